"""What a campaign flown with a truth apart from the model shows (``quadest campaign
--truth-spread``; docs/truth.md): survival of the complete losses in quarters of each drawn
quantity (one truth is drawn per flight, so the rows are a distribution over draws), and in the
worst quarter of the quantities that decide a loss (the heaviest rotors, the lowest top speed,
the least thrust at top speed)."""

from __future__ import annotations

import math

import numpy as np

VARIABLES = {
    "truth_rotor_inertia_ratio": ("rotor inertia ratio", "high"),
    "truth_top_speed_ratio": ("top speed ratio", "low"),
    "truth_max_thrust_ratio": ("headroom (thrust at top speed ratio)", "low"),
    "truth_motor_tau_ratio": ("motor time constant ratio", "high"),
    "truth_torque_coefficient_ratio": ("torque coefficient ratio", "low"),
}
"""The drawn quantities survival is reported against: their label and which end is the worst
for a vehicle that lost a rotor (heavy rotors: more gyroscopic torque; less top speed or thrust:
less headroom for the three rotors left; a slow motor: late thrust; less reaction torque: less
yaw authority)."""

QUARTERS = 4


def truth_survival(rows: list[dict]) -> dict:
    """``{"flights", "survived", "by": {variable: {"label", "x", "low", "high", "survived",
    "flights"}}, "worst": {variable: {"end", "bound", "survived", "flights"}}}`` over the complete
    losses ``rows``: survival per quarter of each variable (``x`` the median, ``low``/``high`` the
    quarter's bounds), and in its worst quarter (above the upper quartile or below the lower)."""
    up = np.array([r["flight"] == "survived" for r in rows], bool)
    out = {"flights": len(rows), "survived": int(up.sum()), "by": {}, "worst": {}}
    for var, (label, end) in VARIABLES.items():
        x = np.array([r.get(var, math.nan) for r in rows], float)
        ok = np.isfinite(x)
        if ok.sum() < QUARTERS:
            continue
        x, u = x[ok], up[ok]
        edges = np.quantile(x, np.linspace(0.0, 1.0, QUARTERS + 1))
        idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, QUARTERS - 1)
        cells = [k for k in range(QUARTERS) if (idx == k).any()]
        out["by"][var] = {
            "label": label,
            "x": [float(np.median(x[idx == k])) for k in cells],
            "low": [float(x[idx == k].min()) for k in cells],
            "high": [float(x[idx == k].max()) for k in cells],
            "survived": [int(u[idx == k].sum()) for k in cells],
            "flights": [int((idx == k).sum()) for k in cells],
        }
        worst = idx == (QUARTERS - 1 if end == "high" else 0)
        bound = float(edges[QUARTERS - 1] if end == "high" else edges[1])
        out["worst"][var] = {"end": end, "bound": bound, "survived": int(u[worst].sum()), "flights": int(worst.sum())}
    return out


def truth_lines(group: dict) -> list[str]:
    """A person's lines for a group's :func:`truth_survival` (none for a group flown as the model)."""
    t = group.get("truth")
    if not t or not t["flights"]:
        return []
    lines = [f"truth drawn per flight ({group['truth_spread']}): {t['survived']}/{t['flights']} complete losses up"]
    for var, b in t["by"].items():
        cells = ", ".join(
            f"{lo:.3g}-{hi:.3g}: {s}/{n}" for lo, hi, s, n in zip(b["low"], b["high"], b["survived"], b["flights"])
        )
        w = t["worst"][var]
        side = ">=" if w["end"] == "high" else "<="
        lines.append(f"  {b['label']}: {cells}; worst quarter ({side} {w['bound']:.3g}) {w['survived']}/{w['flights']}")
    return lines
