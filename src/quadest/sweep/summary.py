"""A sweep's results for a person (``quadest report RESULTS.parquet``): per filter,
each parameter set's mean metrics over the sources it ran on, and the metric against each
swept parameter."""

from __future__ import annotations

import json
import math

import numpy as np

from quadest.sweep.runs import METRICS


def is_results(path) -> bool:
    """Whether ``path`` is a sweep's results file (Parquet with a run id, filter and params)."""
    import pyarrow.parquet as pq

    try:
        names = set(pq.read_schema(path).names)
    except Exception:  # noqa: BLE001 (not Parquet, not readable: not a results file)
        return False
    return {"run_id", "filter", "params", "status"} <= names


def sweep_summary(table) -> dict:
    """``{"runs", "ok", "failed", "sources", "filters": {name: {"sets": [...], "params": [...]}}}``;
    each set: its parameters, the runs, and the mean of every metric over its successful runs."""
    rows = table.to_pylist()
    ok = [r for r in rows if r["status"] == "ok"]
    metrics = [m for m in METRICS if m in (rows[0] if rows else {})]
    extra = [k for k in ("position_rms_m", "time_to_settle_s", "spin_rate_rad_s") if rows and k in rows[0]]
    out = {
        "runs": len(rows),
        "ok": len(ok),
        "failed": len(rows) - len(ok),
        "sources": len({r["source"] for r in rows}),
        "metrics": metrics + extra,
        "filters": {},
    }
    for name in sorted({r["filter"] for r in rows}):
        mine = [r for r in ok if r["filter"] == name]
        sets: dict = {}
        for r in mine:
            sets.setdefault(r["params"], []).append(r)
        entries = []
        for p, rs in sets.items():
            e = {"params": json.loads(p), "runs": len(rs)}
            for m in metrics + extra:
                v = [r[m] for r in rs if r.get(m) is not None and not math.isnan(r[m])]
                e[m] = float(np.mean(v)) if v else None
            if "flight" in rs[0]:
                e["survived"] = sum(r["flight"] == "survived" for r in rs)
            entries.append(e)
        entries.sort(key=lambda e: (e.get("total_rmse_deg") is None, e.get("total_rmse_deg") or 0.0))
        keys = sorted({k for e in entries for k, v in e["params"].items() if isinstance(v, (int, float))})
        out["filters"][name] = {
            "sets": entries,
            "params": keys,
            "failed": sum(1 for r in rows if r["filter"] == name and r["status"] != "ok"),
        }
    return out


SHORT = {
    "total_rmse_deg": "total",
    "heading_rmse_deg": "heading",
    "inclination_rmse_deg": "incl.",
    "roll_rms_deg": "roll",
    "pitch_rms_deg": "pitch",
    "yaw_rms_deg": "yaw",
    "position_rms_m": "pos m",
    "time_to_settle_s": "settle s",
    "spin_rate_rad_s": "spin rad/s",
}


def _set_label(params: dict) -> str:
    return (
        ", ".join(f"{k}={v:g}" if isinstance(v, (int, float)) else f"{k}={v}" for k, v in params.items()) or "defaults"
    )


def format_sweep_summary(summ: dict, best: int = 3) -> str:
    """:func:`sweep_summary` for a terminal: per filter its ``best`` parameter sets by mean
    total RMSE (every set when it has no more), each set's runs and mean metrics."""
    cols = [
        m for m in summ["metrics"] if any(e.get(m) is not None for f in summ["filters"].values() for e in f["sets"])
    ]
    flown = any("survived" in e for f in summ["filters"].values() for e in f["sets"])
    head = ["filter", "parameters", "runs"] + [SHORT.get(m, m) for m in cols] + (["survived"] if flown else [])
    rows = []
    for name, f in summ["filters"].items():
        for e in f["sets"][:best]:
            cells = [f"{e[m]:.2f}" if e.get(m) is not None else "-" for m in cols]
            survived = [f"{e.get('survived', 0)}/{e['runs']}"] if flown else []
            rows.append([name, _set_label(e["params"]), str(e["runs"]), *cells, *survived])
        if len(f["sets"]) > best:
            rows.append([name, f"(best {best} of {len(f['sets'])} sets by total)"] + [""] * (len(head) - 2))
        if f["failed"]:
            rows.append([name, f"({f['failed']} failed run(s) left out)"] + [""] * (len(head) - 2))
    widths = [max(len(r[i]) for r in [head, *rows]) for i in range(len(head))]

    def line(r):
        return "  ".join(c.ljust(w) if i < 2 else c.rjust(w) for i, (c, w) in enumerate(zip(r, widths))).rstrip()

    title = (
        f"results: {summ['runs']} runs ({summ['ok']} ok) on {summ['sources']} source(s); per parameter set the mean "
        "over its successful runs (degrees unless named)"
    )
    return "\n".join([title, line(head), *(line(r) for r in rows)])
