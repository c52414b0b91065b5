"""The survival campaign (``quadest campaign``; docs/campaign.md): rotor failures and nominal
flights flown with each estimator, each detection mode and each gyroscope range in the loop, on
the sweep engine (Dask, one resumable results file), and what they show: survival, detection
delay and isolation, false alarms per hour of nominal flight, survival against the spin, the
clipping share, the detection delay, the magnetometer's latency and the hover point's height
(from each loss's deepest point: :func:`up_by_height`).

A run is a case of :mod:`quadest.evaluation.detection` (its seed decides the scenario, the rotor,
the time and how much effectiveness is left) with the detection mode, the estimator in the
loop, the gyroscope's range and the magnetometer's latency; its row is one flight."""

from __future__ import annotations

import math

import numpy as np

from quadest.detect import DetectorParams
from quadest.errors import UsageError
from quadest.evaluation.detection import (
    case_config,
    case_failure,
    complete_loss,
    failure_case,
    fly_case_flight,
    nominal_case,
    summarize_failures,
)
from quadest.flight import FlightParams
from quadest.models.truth import TRUTH_SPREADS, drawn_names
from quadest.sweep.truth_summary import truth_lines, truth_survival

HEIGHT_M = FlightParams().height_m
"""m: the hover point's height above the ground a campaign flies at unless told otherwise."""

DETECTIONS = ("rotor-speeds", "commands", "oracle")
"""The ways the fault-tolerant controller learns of a loss: the detector from measured rotor
speeds or from the commands, or the oracle (told 50 ms after the loss: not what a vehicle knows)."""

FAILURE_MODES = ("propeller-off", "motor-stop")
"""How a campaign's complete losses happen (:data:`quadest.sim.faults.FAILURE_MODES`): the
propeller comes off (its motor spins on at its command), or the motor stops (it spins down, its
propeller still on). Each complete-loss seed is flown once per mode asked; the partial losses
and the nominal flights once."""

RUN_COLUMNS = {
    "run_id": "string",
    "filter": "string",
    "params": "string",
    "source": "string",
    "seed": "int64",
    "spec": "string",
    "status": "string",
    "error": "string",
}
"""The columns every results row starts with (a sweep's and a campaign's): the run, its status."""

CAMPAIGN_ROW_TYPES = {
    **RUN_COLUMNS,
    "samples": "int64",
    "seconds": "double",
    "scenario": "string",
    "kind": "string",
    "detection": "string",
    "detector": "string",
    "gyro_range_dps": "double",
    "mag_latency_s": "double",
    "rotor": "int64",
    "failure_s": "double",
    "efficiency": "double",
    "failure_mode": "string",
    "flight": "string",
    "reason": "string",
    "flown_s": "double",
    "lost_rotor": "int64",
    "lost_s": "double",
    "delay_s": "double",
    "isolated": "int64",
    "false_alarm": "int64",
    "damaged_rotor": "int64",
    "damaged_s": "double",
    "damaged_effectiveness": "double",
    "spin_rate_rad_s": "double",
    "peak_rate_rad_s": "double",
    "gyro_clipped_share": "double",
    "tilt_error_rms_deg": "double",
    "height_m": "double",
    "drop_m": "double",
    "truth_spread": "string",
    **{f"truth_{name}": "double" for name in drawn_names()},
}
"""A campaign run's row: the run (as a sweep's), the case, and what happened. Integers are −1
where they do not apply (no rotor failed, none found); numbers NaN."""


def campaign_runs(
    seeds, nominal_seeds, filters, *, detections=DETECTIONS, gyro_ranges_dps=(None,), mag_latencies_s=(0.0,),
    duration: float = 60.0, failure_duration: float = 6.0, height_m: float | None = None,
    detector: dict | None = None, failure_modes=FAILURE_MODES[:1], truth_spread: str = "none",
) -> list[dict]:  # fmt: skip
    """Every (failure seed or nominal seed, estimator, detection mode, gyroscope range,
    magnetometer latency) as a run spec, the hover point ``height_m`` above the ground (None:
    ``FlightParams``'), the detector's parameters changed by ``detector`` (``{name: value}``;
    the oracle flies none), each complete loss once per mode of ``failure_modes``
    (:data:`FAILURE_MODES`), the vehicle flown drawn apart from the model within ``truth_spread``
    (:data:`~quadest.models.truth.TRUTH_SPREADS`; ``none``: the model flies); the oracle flies
    only the complete losses (it knows nothing of a partial one, and has nothing to alarm on in
    nominal flight)."""
    if truth_spread not in TRUTH_SPREADS:
        raise UsageError(f"--truth-spread: unknown spread {truth_spread!r}; spreads: {', '.join(TRUTH_SPREADS)}")
    bad = [d for d in detections if d not in DETECTIONS]
    if bad:
        raise UsageError(f"--detection: unknown mode(s) {', '.join(bad)}; known: {', '.join(DETECTIONS)}")
    cases = _failure_cases(seeds, failure_modes, failure_duration)
    cases += [nominal_case(s, "x", duration) for s in nominal_seeds]
    if height_m is not None and height_m != HEIGHT_M:  # the default's runs keep their ids
        cases = [{**c, "height_m": float(height_m)} for c in cases]
    runs = []
    for case in cases:
        for mode in detections:
            if mode == "oracle" and not complete_loss(case):
                continue
            for g in gyro_ranges_dps:
                for lat in mag_latencies_s:
                    src = {"kind": "campaign", "case": {**case, "mode": mode}, "gyro_range_dps": g,
                           "mag_latency_s": float(lat)}  # fmt: skip
                    if detector and mode != "oracle":  # the defaults' runs keep their ids
                        src["detector"] = dict(detector)
                    if truth_spread != "none":  # so do the model's
                        src["truth_spread"] = truth_spread
                    runs += [{"filter": f, "params": {}, "source": src, "align": None} for f in filters]
    return runs


def _failure_cases(seeds, failure_modes, duration: float) -> list[dict]:
    """The failures of ``seeds``: a complete loss once per mode of ``failure_modes`` (a propeller
    off as its case always was, so that its runs keep their ids), a partial loss once."""
    modes = list(dict.fromkeys(failure_modes))
    bad = [m for m in modes if m not in FAILURE_MODES]
    if bad or not modes:
        raise UsageError(
            f"--failure-modes: unknown or no mode(s) {', '.join(bad)}; a campaign flies {', '.join(FAILURE_MODES)}"
        )
    cases = []
    for s in seeds:
        case = failure_case(s, "x", duration)
        if not complete_loss(case):
            cases.append(case)
            continue
        cases += [case if m == "propeller-off" else {**case, "failure_mode": m} for m in modes]
    return cases


def campaign_label(src: dict) -> str:
    c = src["case"]
    what = "nominal" if c["rotor"] is None else f"rotor{c['rotor']}@{c['time_s']:.3f}:{c['efficiency']:.2f}"
    if c.get("failure_mode"):
        what = f"{c['failure_mode']}:{what}"
    g = "" if src["gyro_range_dps"] is None else f"/gyro{src['gyro_range_dps']:g}"
    lat = f"/maglat{src['mag_latency_s']:g}" if src["mag_latency_s"] else ""
    det = f"/{detector_label(src.get('detector'))}" if src.get("detector") else ""
    truth = f"/truth-{src['truth_spread']}" if src.get("truth_spread") else ""
    return f"campaign {c['scenario']}/{what}/{c['mode']}{det}{truth}{g}{lat}/seed{c['seed']}"


def detector_label(changes: dict | None) -> str:
    """The detector's parameters a run changed, ``lost_threshold=0.008,glr=False`` ("" for none)."""
    return ",".join(f"{k}={str(v).lower() if isinstance(v, bool) else v}" for k, v in sorted((changes or {}).items()))


def _overrides(src: dict) -> dict:
    """The run's gyroscope range and magnetometer latency, as sensor parameters."""
    over = {"mag.latency_s": src["mag_latency_s"]}
    if src["gyro_range_dps"] is not None:
        over["gyro.range"] = math.radians(src["gyro_range_dps"])
    return over


def fly_campaign(spec: dict, row: dict) -> None:
    """Fly one campaign run and put what happened into ``row``."""
    src = spec["source"]
    case = src["case"]
    over = _overrides(src)
    cfg = case_config(case, over)
    detector = DetectorParams(**src["detector"]) if src.get("detector") else None
    f = fly_case_flight(case, detector, estimator=spec["filter"], overrides=over, truth=src.get("truth_spread"))
    s, det = f.summary, f.summary.get("detection", {})
    row.update(_case_columns(src, cfg))
    drawn = s.get("truth_drawn", {})
    row.update({f"truth_{name}": _num(drawn.get(name)) for name in drawn_names()})
    row.update(
        {
            "samples": len(f.recording),
            "flight": s["status"],
            "reason": s["reason"],
            "flown_s": s["flown_s"],
            "lost_rotor": _int(det.get("lost_rotor")),
            "lost_s": _num(det.get("lost_s")),
            "delay_s": _num(det.get("delay_s")),
            "isolated": -1 if "isolated" not in det else int(bool(det["isolated"])),
            "false_alarm": int(bool(det.get("false_alarm", False))),
            "damaged_rotor": _int(det.get("damaged_rotor")),
            "damaged_s": _num(det.get("damaged_s")),
            "damaged_effectiveness": _num(det.get("damaged_effectiveness")),
            "tilt_error_rms_deg": _num(s.get("tilt_error_after_failure_rms_deg", s.get("tilt_error_rms_deg"))),
            "drop_m": _num(s.get("drop_m")),
        }
    )
    if case["mode"] == "oracle":
        row.update(_told(case))
    row.update(_spin_columns(f, case, s, np.isfinite(cfg.gyro.range)))


def _told(case: dict) -> dict:
    """The oracle's detection: the failed rotor, ``FlightParams.detect_delay_s`` after the
    failure (what it is told, not what it found)."""
    delay = FlightParams().detect_delay_s
    return {"lost_rotor": case["rotor"], "lost_s": case["time_s"] + delay, "delay_s": delay, "isolated": 1}


def _case_columns(src: dict, cfg) -> dict:
    c = src["case"]
    kind = "nominal" if c["rotor"] is None else ("loss" if complete_loss(c) else "partial")
    return {
        "scenario": c["scenario"],
        "kind": kind,
        "detection": c["mode"],
        "detector": detector_label(src.get("detector")),
        "gyro_range_dps": round(math.degrees(cfg.gyro.range), 6) if np.isfinite(cfg.gyro.range) else math.inf,
        "mag_latency_s": src["mag_latency_s"],
        "rotor": _int(c["rotor"]),
        "failure_s": _num(c.get("time_s")),
        "efficiency": _num(c.get("efficiency")),
        "failure_mode": "" if c["rotor"] is None else case_failure(c).mode,
        "height_m": float(c.get("height_m", HEIGHT_M)),
        "truth_spread": src.get("truth_spread", "none"),
    }


def _spin_columns(flight, case: dict, summary: dict, clips: bool) -> dict:
    """The true body rate after the failure (or over a nominal flight): the mean yaw rate's
    magnitude from 0.5 s after the failure on (the spin the vehicle reached), its peak rate, and
    the share of samples with a gyroscope axis clipped."""
    t, w = flight.recording.t, flight.states[:, 10:13]
    start = case.get("time_s") or 0.0
    after = t >= start
    late = t >= start + 0.5
    return {
        "spin_rate_rad_s": float(np.mean(np.abs(w[late, 2]))) if late.any() else math.nan,
        "peak_rate_rad_s": float(np.linalg.norm(w[after], axis=1).max()) if after.any() else math.nan,
        "gyro_clipped_share": float(summary.get("gyro_clipped_share", 0.0)) if clips else math.nan,
    }


def _int(v) -> int:
    return -1 if v is None else int(v)


def _num(v) -> float:
    return math.nan if v is None else float(v)


# -- the summary ----------------------------------------------------------------------------------------
def is_campaign(names) -> bool:
    """Whether a results file with these column names is a campaign's."""
    return {"detection", "kind", "lost_rotor", "flight"} <= set(names)


def _as_case_row(r: dict) -> dict:
    """A campaign row as :func:`~quadest.evaluation.detection.summarize_failures` reads one."""

    def opt(v):
        return None if v is None or (isinstance(v, float) and math.isnan(v)) or v == -1 else v

    return {
        "rotor": opt(r["rotor"]),
        "time_s": r["failure_s"],
        "efficiency": r["efficiency"],
        "status": r["flight"],
        "delay_s": opt(r["delay_s"]),
        "isolated": r["isolated"] == 1,
        "false_alarm": r["false_alarm"] == 1,
        "lost_rotor": opt(r["lost_rotor"]),
        "damaged_rotor": opt(r["damaged_rotor"]),
        "damaged_s": opt(r["damaged_s"]),
        "damaged_effectiveness": opt(r["damaged_effectiveness"]),
    }


GROUP = ("filter", "detection", "detector", "gyro_range_dps", "mag_latency_s", "height_m", "truth_spread")


def _with_mode(r: dict) -> dict:
    """A row with its failure mode (files of before: a complete loss was a propeller off)."""
    if r.get("failure_mode"):
        return r
    if r["kind"] == "nominal":
        return {**r, "failure_mode": ""}
    return {**r, "failure_mode": "propeller-off" if r["kind"] == "loss" else "partial"}


def _by_failure_mode(rows: list[dict]) -> list[tuple[str | None, list[dict]]]:
    """A group's rows once per failure mode of its complete losses (:data:`FAILURE_MODES`' order),
    each with the partial losses and the nominal flights, which are flown once; ``(None, rows)``
    when it has no complete loss."""
    modes = {r["failure_mode"] for r in rows if r["kind"] == "loss"}
    order = sorted(modes, key=lambda m: (FAILURE_MODES.index(m) if m in FAILURE_MODES else len(FAILURE_MODES), m))
    if not order:
        return [(None, rows)]
    return [(m, [r for r in rows if r["kind"] != "loss" or r["failure_mode"] == m]) for m in order]


def campaign_summary(rows: list[dict]) -> dict:
    """Per (estimator, detection, the detector's changed parameters, gyroscope range, magnetometer
    latency, height) and the complete losses' failure mode: the losses' survival, detection and
    isolation (:func:`summarize_failures`), survival by scenario and at each lower height
    (:func:`up_by_height`), the nominal flights' hours and alarms (the partial losses and nominal
    flights, flown once, in each failure mode's group); and survival against spin, clipping,
    delay, latency and height."""
    before = {"height_m": HEIGHT_M, "detector": "", "truth_spread": "none"}  # files of before lack them
    ok = [_with_mode({**r, **{k: v for k, v in before.items() if r.get(k) is None}}) for r in rows]
    ok = [r for r in ok if r["status"] == "ok"]
    groups: dict = {}
    for r in ok:
        groups.setdefault(tuple(r[k] for k in GROUP), []).append(r)
    out = {"runs": len(rows), "ok": len(ok), "failed": len(rows) - len(ok), "groups": []}
    keys = sorted(groups, key=lambda k: (k[0], DETECTIONS.index(k[1]), k[2], -k[3], k[4], k[5], k[6]))
    for key, mode, mine in ((k, m, rs) for k in keys for m, rs in _by_failure_mode(groups[k])):
        failures = [_as_case_row(r) for r in mine if r["kind"] != "nominal"]
        nominal = [r for r in mine if r["kind"] == "nominal"]
        g = dict(zip(GROUP, key))
        g["failure_mode"] = mode
        g["detection_label"] = detection_cell(g)
        g["failures"] = summarize_failures(failures)
        losses = [r for r in mine if r["kind"] == "loss"]
        g["survival_by_scenario"] = _by_scenario(losses)
        g["up_by_height"] = up_by_height(losses)
        g["truth"] = truth_survival(losses) if g["truth_spread"] != "none" else None
        g["nominal"] = {
            "flights": len(nominal),
            "hours": sum(r["flown_s"] for r in nominal) / 3600.0,
            "lost_alarms": sum(r["lost_rotor"] >= 0 for r in nominal),
            "damaged_alarms": sum(r["damaged_rotor"] >= 0 for r in nominal),
            "crashed": sum(r["flight"] != "survived" for r in nominal),
        }
        out["groups"].append(g)
    out["curves"] = survival_curves([r for r in ok if r["kind"] == "loss"])
    heights = {group_label(g, out["groups"]): g["up_by_height"] for g in out["groups"]}
    heights = {k: v for k, v in heights.items() if len(v["x"]) > 1}
    if heights:
        out["curves"]["height_m"] = {"label": "height of the hover point above the ground (m)", "lines": heights}
    return out


def group_label(g: dict, groups: list[dict]) -> str:
    """``estimator / detection``, with the detector's changed parameters (as the curves name
    their lines), and the gyroscope's range, the latency and the height where the groups differ
    in them."""
    parts = [g["filter"], g["detection"]]
    if g["detector"]:
        parts.append(f"detector {g['detector']}")
    if len({h.get("failure_mode") for h in groups}) > 1:
        parts.append(g.get("failure_mode") or "no complete loss")
    for key, fmt in (("gyro_range_dps", "±{:g} °/s"), ("mag_latency_s", "latency {:g} s"), ("height_m", "{:g} m up"),
                     ("truth_spread", "truth {}")):  # fmt: skip
        if len({h[key] for h in groups}) > 1:
            parts.append(fmt.format(g[key]))
    return " / ".join(parts)


def detection_cell(g: dict) -> str:
    """A group's detection mode, with the detector's parameters it changed and its complete
    losses' failure mode when not a propeller off."""
    return g["detection"] + (f" ({g['detector']})" if g.get("detector") else "") + _mode_suffix(g)


HEIGHTS_M = (1.0, 2.0, 3.0, 5.0, 10.0, 20.0, 30.0, 50.0, 100.0)
"""The heights at which :func:`up_by_height` says how many losses would have stayed up."""


def up_by_height(rows: list[dict]) -> dict:
    """How many complete losses would have stayed up had the hover point been each of
    :data:`HEIGHTS_M` (up to the lowest flown) above the ground: those whose deepest point after
    the failure (``drop_m``) stays above it: flown lower, the flight is the same up to the contact
    (no ground effect is modelled). A flight that did not stay up at its own height (the ground,
    lost control, a false alarm) stays up at none. ``{"x", "survived", "flights"}``."""
    if not rows:
        return {"x": [], "survived": [], "flights": []}
    flown = min(r["height_m"] for r in rows)
    up = [r.get("drop_m", math.nan) for r in rows if r["flight"] == "survived"]
    known = np.isfinite(up).all()  # files of before have no drop: their flown height only
    xs = sorted({h for h in HEIGHTS_M if h < flown} | {flown}) if known else [flown]
    kept = [sum(not d > h for d in up) for h in xs]  # the ground is touched at z > h
    return {"x": xs, "survived": kept, "flights": [len(rows)] * len(xs)}


def _by_scenario(rows: list[dict]) -> dict:
    out: dict = {}
    for r in rows:
        cell = out.setdefault(r["scenario"], [0, 0])
        cell[0] += r["flight"] == "survived"
        cell[1] += 1
    return out


CURVES = {
    "spin_rate_rad_s": ("spin rate after the loss (rad/s)", 8),
    "gyro_clipped_share": ("share of samples with a gyro axis clipped", 8),
    "delay_s": ("detection delay (s)", 8),
    "mag_latency_s": ("magnetometer latency (s)", None),
    "truth_rotor_inertia_ratio": ("rotor inertia flown over the model's", 4),
    "truth_max_thrust_ratio": ("thrust at top speed flown over the model's (headroom)", 4),
}
"""What survival is drawn against, with the number of quantile bins (None: each value its own)."""


def survival_curves(rows: list[dict]) -> dict:
    """``{variable: {"label", "lines": {"estimator / detection": {"x", "survived", "flights"}}}}``:
    the share of complete losses that stayed up in bins of the variable (equal counts), per
    estimator and detection mode; a variable with no finite value is left out."""
    out = {}
    several = len({r.get("failure_mode") for r in rows}) > 1
    for var, (label, bins) in CURVES.items():
        lines = {}
        for name in sorted({_curve_key(r, several) for r in rows}):
            mine = [r for r in rows if _curve_key(r, several) == name and np.isfinite(r.get(var, math.nan))]
            if mine:
                lines[" / ".join(n for n in name if n)] = _binned(mine, var, bins)
        if lines:
            out[var] = {"label": label, "lines": lines}
    return out


def _curve_key(r: dict, mode: bool = False) -> tuple:
    """A curve's line: estimator, detection, the detector's changed parameters (files of before:
    the defaults) and, with ``mode``, the failure mode."""
    return r["filter"], r["detection"], r.get("detector", ""), (r.get("failure_mode") or "") if mode else ""


def _binned(rows: list[dict], var: str, bins: int | None) -> dict:
    x = np.array([r[var] for r in rows], float)
    up = np.array([r["flight"] == "survived" for r in rows])
    if bins is None or len(np.unique(x)) <= bins:
        edges = np.unique(x)
        idx = np.searchsorted(edges, x)
    else:
        edges = np.unique(np.quantile(x, np.linspace(0, 1, bins + 1)))
        idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(edges) - 2)
    keep = [k for k in range(int(idx.max()) + 1) if (idx == k).any()]
    return {
        "x": [float(np.median(x[idx == k])) for k in keep],
        "survived": [int(up[idx == k].sum()) for k in keep],
        "flights": [int((idx == k).sum()) for k in keep],
    }


def format_campaign(summary: dict) -> str:
    """The campaign's table for a person: a line per group."""
    wide = max([13] + [len(_detection_text(g)) + 1 for g in summary["groups"]])
    head = (
        f"{'estimator':<10}{'detection':<{wide}}{'gyro °/s':>9}{'mag lat':>8}{'height':>7}{'losses':>8}{'survived':>10}"
        f"{'found':>7}{'named':>7}{'median':>8}{'p99':>7}{'max':>7}{'partial':>9}{'nominal h':>10}{'alarms':>7}"
    )
    changed = any(g.get("detector") for g in summary["groups"])
    lines = [head + ("  detector" if changed else "")]
    for g in summary["groups"]:
        f, n, d = g["failures"], g["nominal"], g["failures"]["delay_ms"]
        share = f"{f['survived']}/{f['complete']}" if f["complete"] else "-"
        part = f"{f['partial']['isolated']}/{f['partial']['flights']}" if f["partial"]["flights"] else "-"
        alarms = "-" if g["detection"] == "oracle" else f"{n['lost_alarms']}"
        gyro = "none" if math.isinf(g["gyro_range_dps"]) else f"{g['gyro_range_dps']:.0f}"
        lines.append(
            f"{g['filter']:<10}{_detection_text(g):<{wide}}{gyro:>9}{g['mag_latency_s']:>8g}{g['height_m']:>7g}{f['complete']:>8}"
            f"{share:>10}"
            f"{f['found']:>7}{f['isolated']:>7}{_ms(d['median']):>8}{_ms(d['p99']):>7}{_ms(d['max']):>7}{part:>9}"
            f"{n['hours']:>10.2f}{alarms:>7}" + (f"  {_detector_cell(g)}" if changed else "")
        )
    lines.append("delays in ms; the oracle's is what it is told (50 ms), not found; 'partial': named as damaged")
    for g in summary["groups"]:
        up = g.get("up_by_height", {"x": []})
        if len(up["x"]) > 1:
            kept = ", ".join(f"{h:g} m: {n}" for h, n in zip(up["x"], up["survived"]))
            lines.append(f"{group_label(g, summary['groups'])}: of {up['flights'][0]} complete losses, up with the "
                         f"hover point at {kept} above the ground")  # fmt: skip
    lines += [f"{group_label(g, summary['groups'])}: {line}" for g in summary["groups"] for line in truth_lines(g)]
    return "\n".join(lines)


def _detection_text(g: dict) -> str:
    """The table's detection cell: the mode, and the failure mode when not a propeller off."""
    return g["detection"] + _mode_suffix(g)


def _mode_suffix(g: dict) -> str:
    mode = g.get("failure_mode")
    return f", {mode}" if mode and mode != FAILURE_MODES[0] else ""


def _detector_cell(g: dict) -> str:
    return "-" if g["detection"] == "oracle" else (g["detector"] or "defaults")


def _ms(v) -> str:
    return "-" if v is None else f"{v:.0f}"
