"""What a flight report shows, computed from the whole recording: its sensors and
rates, gaps, clipping, vibration, magnetic disturbance, the events in it, and each estimator's
attitude with its errors where there is a truth (or the autopilot's own estimate, labelled so).
The figures are drawn by :mod:`quadest.plot.report`; every number here comes from all samples,
whatever the figures decimate. A long recording is gone through in blocks: its estimates, errors
and derived series are never held whole, only their sums and the points drawn."""

from __future__ import annotations

import numpy as np

from quadest.conventions import GRAVITY
from quadest.data.checks import row_norms, runs, timestamp_jitter
from quadest.data.recording import Recording
from quadest.evaluation.metrics import SUM_ROWS, ErrorSums, euler_errors
from quadest.evaluation.runner import (
    align_estimate,
    alignment_of,
    estimate_pieces,
    evaluation_mask,
    first_mag_time,
)
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
DISPLAY_POINTS = 4000  # per drawn line (chosen: smooth to pan in a browser; the extremes are kept)


def bucket_extremes(y, size: int) -> np.ndarray:
    """Indices of each bucket of ``size`` rows' first, smallest and largest sample, in order."""
    keep = []
    for a in range(0, len(y), size):
        seg = y[a : a + size]
        idx = {a}
        if np.isfinite(seg).any():
            idx |= {a + int(np.nanargmin(seg)), a + int(np.nanargmax(seg))}
        keep += sorted(idx)
    return np.asarray(keep, dtype=np.int64)


class Decimator:
    """A series of ``n`` samples decimated for display as its pieces arrive: at most about
    ``max_points`` points, per bucket its first, smallest and largest sample (a spike survives);
    the points of :func:`decimate` on the whole series, whatever the pieces."""

    def __init__(self, n: int, max_points: int = DISPLAY_POINTS):
        self.size = int(np.ceil(3 * n / max_points)) if n > max_points else 1
        self.t, self.y, self.tail = [], [], (np.zeros(0), np.zeros(0))

    def add(self, t, y) -> Decimator:
        t, y = np.asarray(t, float), np.asarray(y, float)
        if len(self.tail[0]):  # the last piece's unfinished bucket
            t, y = np.concatenate([self.tail[0], t]), np.concatenate([self.tail[1], y])
        whole = len(t) // self.size * self.size
        self._keep(t[:whole], y[:whole])
        self.tail = (t[whole:].copy(), y[whole:].copy())
        return self

    def _keep(self, t, y) -> None:
        if len(t):
            idx = bucket_extremes(y, self.size) if self.size > 1 else slice(None)
            self.t.append(t[idx])
            self.y.append(y[idx])

    def points(self) -> tuple[np.ndarray, np.ndarray]:
        """The points drawn ``(t, y)`` (the last bucket may be short)."""
        self._keep(*self.tail)
        self.tail = (np.zeros(0), np.zeros(0))
        return np.concatenate([np.zeros(0), *self.t]), np.concatenate([np.zeros(0), *self.y])


def decimate(t, y, max_points: int = DISPLAY_POINTS):
    """At most about ``max_points`` points of ``(t, y)`` for display (:class:`Decimator`)."""
    t, y = np.asarray(t, float), np.asarray(y, float)
    if len(t) <= max_points:
        return t, y
    return Decimator(len(t), max_points).add(t, y).points()


def row_blocks(n: int, rows: int | None = None):
    """``(start, end)`` of each block of ``rows`` rows (default :data:`SUM_ROWS`) in ``n``."""
    rows = rows or SUM_ROWS
    return [(a, min(a + rows, n)) for a in range(0, n, rows)]


def _runs(mask, t, min_s):
    """Intervals ``(start, end)`` (s) where ``mask`` holds for at least ``min_s``."""
    return [(float(t[a]), float(t[b - 1])) for a, b in runs(mask) if t[b - 1] - t[a] >= min_s]


def _flat_top_share(x) -> float:
    """Share of rows on which an axis sits at the largest magnitude it reaches, held on at
    least 3 samples of that axis (a clipped sensor repeats its limit); block by block."""
    x = np.asarray(x, float)
    top, finite = np.zeros(x.shape[1]), 0
    for blk in _finite_rows(x):
        finite += len(blk)
        if len(blk):
            top = np.maximum(top, np.abs(blk).max(axis=0))
    if not finite:
        return 0.0
    held = sum(_at_top(blk, top).sum(axis=0) for blk in _finite_rows(x)) >= 3
    return float(sum(int(_at_top(blk, top)[:, held].any(axis=1).sum()) for blk in _finite_rows(x)) / finite)


def _finite_rows(x):
    """Each block's rows that are finite on every axis."""
    for a, b in row_blocks(len(x)):
        blk = x[a:b]
        yield blk[np.isfinite(blk).all(axis=1)]


def _at_top(blk, top) -> np.ndarray:
    return np.isclose(np.abs(blk), top, rtol=1e-9, atol=0.0) & (top > 0)


def events(rec: Recording) -> list[dict]:
    """Rests, free falls (a throw or a drop) and sustained spins (a rotor loss) in the recording."""
    t, w = rec.t, rec.gyr
    rest, fall = _rest_and_fall(w, rec.acc)
    out = [{"kind": "rest", "start_s": a, "end_s": b} for a, b in _runs(rest, t, REST_MIN_S)]
    del rest
    out += [{"kind": "free fall (a throw or a drop)", "start_s": a, "end_s": b} for a, b in _runs(fall, t, FALL_MIN_S)]
    del fall
    for axis in range(3):
        for a, b in _runs(_spinning(w[:, axis]), t, SPIN_MIN_S):
            sel = slice(np.searchsorted(t, a, "left"), np.searchsorted(t, b, "right"))
            out.append(
                {
                    "kind": f"sustained spin about body {'xyz'[axis]} (a rotor loss?)",
                    "start_s": a,
                    "end_s": b,
                    "rate_rad_s": float(np.mean(np.abs(w[sel, axis]))),
                }
            )
    return sorted(out, key=lambda e: e["start_s"])


def _rest_and_fall(w, f) -> tuple[np.ndarray, np.ndarray]:
    """Per row: at rest (the gyro and the specific force's norm near g); falling freely."""
    rest, fall = np.empty(len(w), bool), np.empty(len(w), bool)
    for a, b in row_blocks(len(w)):
        wn, fn = row_norms(w[a:b]), row_norms(f[a:b])
        rest[a:b] = (wn < REST_RATE) & (np.abs(fn - GRAVITY) < REST_ACC)
        fall[a:b] = fn < FALL_ACC
    return rest, fall


def _spinning(w_axis) -> np.ndarray:
    spin = np.empty(len(w_axis), bool)
    for a, b in row_blocks(len(w_axis)):
        spin[a:b] = np.abs(w_axis[a:b]) > SPIN_RATE
    return spin


def summary(rec: Recording) -> dict:
    """The recording at a glance (the report's first section)."""
    t = rec.t
    out = {
        "source": rec.meta.get("source") or rec.meta.get("format") or "-",
        "vehicle": rec.meta.get("vehicle") or rec.meta.get("preset") or rec.meta.get("system"),
        "file": rec.meta.get("path") or rec.meta.get("file"),
        "duration_s": float(t[-1] - t[0]) if len(t) > 1 else 0.0,
        "rows": int(len(t)),
        "imu_rate_hz": None,
        "mag_rate_hz": None,
        "dropped_rows": rec.meta.get("dropped_rows") or rec.meta.get("skipped_rows"),
        "gyro_clipped_share": _flat_top_share(rec.gyr),
        "acc_clipped_share": _flat_top_share(rec.acc),
        "truth": "true_q" if rec.true_q is not None else ("ref_q" if rec.ref_q is not None else None),
    }
    intervals, med = _intervals(t)
    out.update(intervals)
    out.update(vibration(rec, med))
    if has_mag(rec):
        out.update(_mag_rate_and_disturbance(t, rec.mag))
    out["events"] = events(rec)
    return out


def _intervals(t) -> tuple[dict, float]:
    """The IMU's rate, its gaps (intervals above 1.5 median) and the timestamps' jitter, and the
    median interval."""
    dt = np.diff(t)
    med = float(np.median(dt)) if len(dt) else float("nan")
    gaps = dt[dt > 1.5 * med] if len(dt) else np.zeros(0)
    return {
        "imu_rate_hz": 1.0 / med if med > 0 else None,
        "gaps": len(gaps),
        "gap_time_s": float(gaps.sum() - med * len(gaps)),
        "longest_gap_s": float(gaps.max()) if len(gaps) else 0.0,
        **timestamp_jitter(dt, med),
    }, med


def _mag_rate_and_disturbance(t, mag) -> dict:
    """The magnetometer's rate and the share of its samples whose norm is more than
    :data:`MAG_DISTURBED` off the median norm."""
    rows = np.isfinite(mag).all(axis=1)
    mt = t[rows]
    rate = float(1.0 / np.median(np.diff(mt))) if len(mt) > 1 else None
    del mt
    norm = row_norms(mag)[rows]
    del rows
    median = np.median(norm)
    off = sum(int(np.count_nonzero(np.abs(norm[a:b] / median - 1.0) > MAG_DISTURBED)) for a, b in row_blocks(len(norm)))
    return {"mag_rate_hz": rate, "mag_disturbed_share": off / len(norm)}


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
    return {"vibration_rms_m_s2": _vibration_rms(rec.acc, n), "vibration_source": "the accelerometer"}


def _vibration_rms(acc, n: int) -> list[float]:
    """RMS per axis of the accelerometer minus its moving average over ``n`` samples, away from
    both ends (the average needs ``n`` samples each side), block by block."""
    k, total = np.ones(n) / n, len(acc)
    lo, hi = (n, total - n) if total > 2 * n else (0, total)
    squares, count = np.zeros(3), 0
    for a, b in row_blocks(hi - lo):
        a, b = a + lo, b + lo
        pad_a, pad_b = max(0, a - n), min(total, b + n)
        rows = slice(a - pad_a, b - pad_a)
        smooth = np.column_stack([np.convolve(acc[pad_a:pad_b, i], k, mode="same")[rows] for i in range(3)])
        squares += np.sum((acc[a:b] - smooth) ** 2, axis=0)
        count += b - a
    return [float(v) for v in np.sqrt(squares / count)]


def attitude(rec: Recording, names, params: dict | None = None) -> dict:
    """Each estimator's attitude (ZYX Euler, degrees) and, against the truth (or the autopilot's
    own estimate), its per-axis error over time, decimated for display (``(t, y)`` per axis), and
    its error figures over all samples (what :func:`~quadest.evaluation.runner.score` gives).
    ``q_reference``: the first estimator's attitude when there is no truth, else None."""
    params = params or {}
    truth = "true_q" if rec.true_q is not None else ("ref_q" if rec.ref_q is not None else None)
    out = {"truth": truth, "euler_deg": {}, "error_deg": {}, "scores": {}, "q_reference": None}
    if truth:
        q_true = getattr(rec, truth)
        out["euler_deg"][truth] = _axes_points(rec.t, ((a, q_true[a:b]) for a, b in row_blocks(len(rec))), _euler_deg)
    # without a magnetometer the heading is arbitrary: its constant offset is removed (as the
    # benchmarks do), unless the reader asked for more
    nav = "heading" if not has_mag(rec) and rec.meta.get("align", {}).get("nav", "none") == "none" else None
    out["heading_offset_removed"] = nav == "heading"
    first = first_mag_time(rec)
    out["scored_from_s"] = first if first > rec.t[0] and truth else None
    for i, name in enumerate(names):
        pieces = estimate_pieces(rec, name, params.get(name))
        if truth is None:
            if i == 0:  # the reference attitude of the magnetometer's and the spin's plots: held whole
                out["q_reference"] = np.concatenate([res.q for _, res in pieces])
                pieces = [(0, out["q_reference"])]
            else:
                pieces = ((a, res.q) for a, res in pieces)
            out["euler_deg"][name] = _axes_points(rec.t, pieces, _euler_deg)
            continue
        shown, out["scores"][name], out["error_deg"][name] = _against_truth(rec, pieces, truth, nav)
        out["euler_deg"][name] = shown
    return out


def _euler_deg(q) -> np.ndarray:
    return np.degrees(quat_to_euler(q))


def _axes_points(t, pieces, of) -> list[tuple[np.ndarray, np.ndarray]]:
    """The display points ``(t, y)`` of each column of ``of(piece)`` over the ``(first row,
    piece)`` pieces of a series as long as ``t``."""
    dec = None
    for a, piece in pieces:
        y = of(piece)
        dec = dec or [Decimator(len(t)) for _ in range(y.shape[1])]
        for j, d in enumerate(dec):
            d.add(t[a : a + len(y)], y[:, j])
    return [d.points() for d in dec or []]


def _against_truth(rec: Recording, pieces, truth: str, nav: str | None) -> tuple[list, dict, list]:
    """An estimate's display points, its error figures against ``truth`` (the constant rotations
    removed as :func:`~quadest.evaluation.runner.score` removes them) and its errors' points."""
    nav, body = alignment_of(rec, nav, None)
    mask, t, q_true = evaluation_mask(rec), rec.t, getattr(rec, truth)
    alignment = None
    if nav != "none" or body:  # a rotation fitted over the whole estimate: held whole
        q = np.concatenate([res.q for _, res in pieces])
        qa, alignment = align_estimate(rec, q, truth=truth, nav=nav, body=body, mask=mask)
        pieces = ((a, q[a:b], qa[a:b]) for a, b in row_blocks(len(q)))
    else:
        pieces = ((a, res.q, res.q) for a, res in pieces)
    sums, shown, errors = ErrorSums(), [Decimator(len(t)) for _ in range(3)], [Decimator(len(t)) for _ in range(3)]
    for a, q, qa in pieces:
        b = a + len(q)
        sums.add(qa, q_true[a:b], mask[a:b])
        for j, (e, err) in enumerate(zip(_euler_deg(q).T, np.degrees(euler_errors(qa, q_true[a:b])).T, strict=True)):
            shown[j].add(t[a:b], e)
            errors[j].add(t[a:b], err)
    figures = sums.summary()
    if alignment is not None:
        figures["alignment"] = alignment.describe()
    return [d.points() for d in shown], figures, [d.points() for d in errors]


def has_mag(rec: Recording) -> bool:
    return rec.mag is not None and bool(np.isfinite(rec.mag).any())


def mag_norm_and_dip(rec: Recording, q) -> list | None:
    """The magnetometer's norm and its dip below the horizontal (deg) with the attitude ``q``
    (the truth or an estimate), over the rows with a magnetometer sample, as display points;
    None without a magnetometer."""
    if not has_mag(rec):
        return None
    rows = np.isfinite(rec.mag).all(axis=1)
    norm, dip = Decimator(int(rows.sum())), Decimator(int(rows.sum()))
    for a, b in row_blocks(len(rec)):
        r = rows[a:b]
        m = rec.mag[a:b][r]
        n = row_norms(m)
        m_n = quat_rotate(q[a:b][r], m)
        norm.add(rec.t[a:b][r], n)
        dip.add(rec.t[a:b][r], np.degrees(np.arcsin(np.clip(m_n[:, 2] / np.where(n > 0, n, np.nan), -1, 1))))
    return [norm.points(), dip.points()]


def spin_and_tilt(rec: Recording, q) -> list:
    """The body rate about the vertical (rad/s, positive about down) and the tilt of the body's
    z axis from the vertical (deg), with the attitude ``q``, as display points: what a rotor loss
    settles into."""
    spin, tilt = Decimator(len(rec)), Decimator(len(rec))
    for a, b in row_blocks(len(rec)):
        w_n = quat_rotate(q[a:b], rec.gyr[a:b])
        down = quat_rotate(q[a:b], np.tile([0.0, 0.0, 1.0], (b - a, 1)))
        spin.add(rec.t[a:b], w_n[:, 2])
        tilt.add(rec.t[a:b], np.degrees(np.arccos(np.clip(down[:, 2], -1.0, 1.0))))
    return [spin.points(), tilt.points()]


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
    q = getattr(rec, att["truth"]) if att["truth"] else att.pop("q_reference")
    att.pop("q_reference", None)
    att["reference"] = (
        "truth"
        if att["truth"] == "true_q"
        else "the autopilot's estimate"
        if att["truth"]
        else (next(iter(names)) if names else None)
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
