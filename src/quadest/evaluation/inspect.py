"""What a flight report shows, computed from the whole recording: its sensors and
rates, gaps, clipping, vibration, magnetic disturbance, the events in it, and each estimator's
attitude with its errors where there is a truth (or the autopilot's own estimate, labelled so).
The figures are drawn by :mod:`quadest.plot.report`; every number here comes from all samples,
whatever the figures decimate."""

from __future__ import annotations

import numpy as np

from quadest.conventions import GRAVITY
from quadest.data.checks import runs
from quadest.data.recording import Recording
from quadest.evaluation.metrics import euler_errors
from quadest.evaluation.runner import estimate_all, first_mag_time, score
from quadest.rotation import quat_conj, quat_rotate, quat_to_euler

REST_RATE = 0.05  # rad/s: below this a body is at rest (chosen: gyro noise and bias of a MEMS IMU)
REST_ACC = 0.5  # m/s²: and its specific force within this of g (chosen)
REST_MIN_S = 1.0  # s (chosen: a rest long enough to calibrate on)
FALL_ACC = 3.0  # m/s²: below this the body is falling freely (the recovery paper's β1 order)
FALL_MIN_S = 0.05  # s (chosen: longer than a vibration spike)
SPIN_RATE = 5.0  # rad/s about one axis, sustained: a spin (a rotor loss makes 10-20 rad/s)
SPIN_MIN_S = 1.0  # s (chosen)
MAG_DISTURBED = 0.10  # a field whose norm is more than 10 % off the recording's median is disturbed (chosen)
VIBRATION_WINDOW_S = 0.05  # s: the accelerometer minus its moving average over this is vibration (chosen)
VIBRATION_MIN_SAMPLES = 5  # fewer samples in that window cannot tell vibration from motion


def _runs(mask, t, min_s):
    """Intervals ``(start, end)`` (s) where ``mask`` holds for at least ``min_s``."""
    return [(float(t[a]), float(t[b - 1])) for a, b in runs(mask) if t[b - 1] - t[a] >= min_s]


def _flat_top_share(x) -> float:
    """Share of rows on which an axis sits at the largest magnitude it reaches, held on at
    least 3 samples of that axis (a clipped sensor repeats its limit)."""
    x = np.asarray(x, float)
    ok = np.isfinite(x).all(axis=1)
    if not ok.any():
        return 0.0
    a = np.abs(x[ok])
    top = a.max(axis=0)
    at = np.isclose(a, top, rtol=1e-9, atol=0.0) & (top > 0)
    at &= at.sum(axis=0) >= 3
    return float(at.any(axis=1).mean())


def events(rec: Recording) -> list[dict]:
    """Rests, free falls (a throw or a drop) and sustained spins (a rotor loss) in the recording."""
    t, w, f = rec.t, rec.gyr, rec.acc
    wn, fn = np.linalg.norm(w, axis=1), np.linalg.norm(f, axis=1)
    out = []
    for a, b in _runs((wn < REST_RATE) & (np.abs(fn - GRAVITY) < REST_ACC), t, REST_MIN_S):
        out.append({"kind": "rest", "start_s": a, "end_s": b})
    for a, b in _runs(fn < FALL_ACC, t, FALL_MIN_S):
        out.append({"kind": "free fall (a throw or a drop)", "start_s": a, "end_s": b})
    for axis in range(3):
        for a, b in _runs(np.abs(w[:, axis]) > SPIN_RATE, t, SPIN_MIN_S):
            sel = (t >= a) & (t <= b)
            out.append(
                {
                    "kind": f"sustained spin about body {'xyz'[axis]} (a rotor loss?)",
                    "start_s": a,
                    "end_s": b,
                    "rate_rad_s": float(np.mean(np.abs(w[sel, axis]))),
                }
            )
    return sorted(out, key=lambda e: e["start_s"])


def summary(rec: Recording) -> dict:
    """The recording at a glance (the report's first section)."""
    t = rec.t
    dt = np.diff(t)
    med = float(np.median(dt)) if len(dt) else float("nan")
    gaps = dt > 1.5 * med if len(dt) else np.zeros(0, bool)
    out = {
        "source": rec.meta.get("source") or rec.meta.get("format") or "-",
        "vehicle": rec.meta.get("vehicle") or rec.meta.get("preset") or rec.meta.get("system"),
        "file": rec.meta.get("path") or rec.meta.get("file"),
        "duration_s": float(t[-1] - t[0]) if len(t) > 1 else 0.0,
        "rows": int(len(t)),
        "imu_rate_hz": 1.0 / med if med > 0 else None,
        "mag_rate_hz": None,
        "gaps": int(gaps.sum()),
        "gap_time_s": float(dt[gaps].sum() - med * gaps.sum()),
        "longest_gap_s": float(dt[gaps].max()) if gaps.any() else 0.0,
        "dropped_rows": rec.meta.get("dropped_rows") or rec.meta.get("skipped_rows"),
        "gyro_clipped_share": _flat_top_share(rec.gyr),
        "acc_clipped_share": _flat_top_share(rec.acc),
        "truth": "true_q" if rec.true_q is not None else ("ref_q" if rec.ref_q is not None else None),
    }
    out.update(vibration(rec, med))
    if rec.mag is not None and np.isfinite(rec.mag).any():
        rows = np.isfinite(rec.mag).all(axis=1)
        mt = t[rows]
        out["mag_rate_hz"] = float(1.0 / np.median(np.diff(mt))) if rows.sum() > 1 else None
        norm = np.linalg.norm(rec.mag[rows], axis=1)
        out["mag_disturbed_share"] = float(np.mean(np.abs(norm / np.median(norm) - 1.0) > MAG_DISTURBED))
    out["events"] = events(rec)
    return out


def vibration(rec: Recording, med: float) -> dict:
    """``vibration_rms_m_s2`` and where it comes from: the log's own figures where it has them
    (ArduPilot's VIBE), else the accelerometer minus its moving average over
    :data:`VIBRATION_WINDOW_S`, or None (with the reason) when the IMU is too slow for that window
    to hold :data:`VIBRATION_MIN_SAMPLES` samples."""
    own = rec.meta.get("vibration")
    if own:
        return {"vibration_rms_m_s2": own["rms_m_s2"], "vibration_source": own["source"]}
    n = int(round(VIBRATION_WINDOW_S / med)) if med > 0 else 0
    if n < VIBRATION_MIN_SAMPLES:
        rate = f"{1 / med:.0f} Hz" if med > 0 else "an unknown rate"
        return {"vibration_rms_m_s2": None, "vibration_source": f"n/a: the IMU at {rate} is too slow to tell"}
    k = np.ones(n) / n
    smooth = np.column_stack([np.convolve(rec.acc[:, i], k, mode="same") for i in range(3)])
    edge = slice(n, len(rec.t) - n) if len(rec.t) > 2 * n else slice(None)
    rms = np.sqrt(np.mean((rec.acc - smooth)[edge] ** 2, axis=0))
    return {"vibration_rms_m_s2": [float(v) for v in rms], "vibration_source": "the accelerometer"}


def attitude(rec: Recording, names, params: dict | None = None) -> dict:
    """Each estimator's attitude (ZYX Euler, degrees) and, against the truth (or the autopilot's
    own estimate), its per-axis error over time and its error figures (:func:`score`)."""
    results = estimate_all(rec, names, params)
    truth = "true_q" if rec.true_q is not None else ("ref_q" if rec.ref_q is not None else None)
    out = {"truth": truth, "euler_deg": {}, "error_deg": {}, "scores": {}, "q": {n: r.q for n, r in results.items()}}
    if truth:
        out["euler_deg"][truth] = np.degrees(quat_to_euler(getattr(rec, truth)))
    # without a magnetometer the heading is arbitrary: its constant offset is removed (as the
    # benchmarks do), unless the reader asked for more
    nav = "heading" if not has_mag(rec) and rec.meta.get("align", {}).get("nav", "none") == "none" else None
    out["heading_offset_removed"] = nav == "heading"
    first = first_mag_time(rec)
    out["scored_from_s"] = first if first > rec.t[0] and truth else None
    for name, res in results.items():
        out["euler_deg"][name] = np.degrees(quat_to_euler(res.q))
        if truth:
            aligned = []
            s = score(rec, res.q, truth=truth, nav=nav, aligned=aligned)
            out["scores"][name] = s
            out["error_deg"][name] = np.degrees(euler_errors(aligned[0], getattr(rec, truth)))
    return out


def has_mag(rec: Recording) -> bool:
    return rec.mag is not None and bool(np.isfinite(rec.mag).any())


def mag_norm_and_dip(rec: Recording, q) -> tuple[np.ndarray, np.ndarray] | None:
    """The magnetometer's norm and its dip below the horizontal (deg) with the attitude ``q``
    (the truth or an estimate); None without a magnetometer."""
    if not has_mag(rec):
        return None
    m_n = quat_rotate(q, rec.mag)
    norm = np.linalg.norm(rec.mag, axis=1)
    return norm, np.degrees(np.arcsin(np.clip(m_n[:, 2] / np.where(norm > 0, norm, np.nan), -1, 1)))


def spin_and_tilt(rec: Recording, q) -> tuple[np.ndarray, np.ndarray]:
    """The body rate about the vertical (rad/s, positive about down) and the tilt of the body's
    z axis from the vertical (deg), with the attitude ``q``: what a rotor loss settles into."""
    w_n = quat_rotate(q, rec.gyr)
    down = quat_rotate(q, np.tile([0.0, 0.0, 1.0], (len(q), 1)))
    return w_n[:, 2], np.degrees(np.arccos(np.clip(down[:, 2], -1.0, 1.0)))


def throw_errors(rec: Recording, res) -> np.ndarray | None:
    """The angle (deg) between a recovery's gravity estimate and the true gravity in the body,
    per sample (NaN where it has none); None without truth."""
    if rec.true_q is None:
        return None
    g_true = quat_rotate(quat_conj(rec.true_q), np.tile([0.0, 0.0, 1.0], (len(rec), 1)))
    return np.degrees(np.arccos(np.clip(np.sum(res.gravity_dir * g_true, axis=1), -1.0, 1.0)))


def report_data(rec: Recording, names, params: dict | None = None, recovery=None) -> tuple[dict, dict]:
    """The report's numbers: :func:`summary` and :func:`attitude`, with the magnetometer's norm
    and dip and, after a sustained spin, the spin and tilt (with the truth's attitude, else the
    first estimator's); a throw's ``recovery`` (a :class:`~quadest.recovery.RecoveryResult` with
    every hypothesis recorded) and its gravity error."""
    summ = summary(rec)
    att = attitude(rec, names, params)
    q = getattr(rec, att["truth"]) if att["truth"] else (next(iter(att["q"].values())) if att["q"] else None)
    att["reference"] = (
        "truth"
        if att["truth"] == "true_q"
        else "the autopilot's estimate"
        if att["truth"]
        else (next(iter(att["q"])) if att["q"] else None)
    )
    att["mag"] = mag_norm_and_dip(rec, q) if q is not None else None
    att["spin"] = spin_and_tilt(rec, q) if q is not None and any("spin" in e["kind"] for e in summ["events"]) else None
    att["recovery"] = recovery
    att["throw_error"] = throw_errors(rec, recovery) if recovery is not None else None
    return summ, att


def report_json(summ: dict, att: dict) -> dict:
    """What a report's tables show, as JSON (``--json``)."""
    return {
        "summary": summ,
        "truth": att["truth"],
        "rms_deg": {n: s["rms_deg"] for n, s in att["scores"].items()},
        "total_rmse_deg": {n: s["total_rmse_deg"] for n, s in att["scores"].items()},
    }
