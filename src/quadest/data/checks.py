"""Unit and frame mistakes found from the samples themselves (docs/recordings.md, checks).

Magnitudes give away a gyroscope far beyond any sensor's range or an accelerometer in g or mg.
A gyroscope in deg/s at ordinary rates does not: its values look like fast rad/s. What gives it
away is kinematics: the magnetic field, fixed in the navigation frame and measured in the body,
turns as ``dm/dt = −ω × m``, so the gyroscope's rates scaled by ``s`` must explain its turning
with ``s ≈ 1``. ``s`` is fitted by least squares (with the magnetometer's constant offset, hard
iron, beside it); a gyroscope in deg/s gives ``s ≈ π/180``. Without a magnetometer only the
magnitudes and, as a warning, the rests are checked: between two rests the gyroscope's
rotation must turn the first rest's gravity into the second's. A body frame that is z-up (FLU)
reads ``+g`` on z at rest.
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy.spatial.transform import Rotation

from quadest.conventions import GRAVITY
from quadest.rotation import quat_conj, quat_rotate

REST_RATE = 0.2  # rad/s: the gyroscope below this on every axis counts as rest
MIN_REST_SAMPLES = 20
GYR_LIMIT = 70.0  # rad/s: ±4000 °/s, beyond any MEMS gyroscope's range
ACC_LIMIT = 1600.0  # m/s²: about 160 g, beyond the range of a flight IMU

GAP_FACTOR = 10.0
"""The estimators' rule (batch): an interval longer than this many nominal intervals is a gap..."""
GAP_MIN_S = 0.1
"""...and longer than this many seconds (a brief hiccup of a fast sensor is integrated over)."""
SCALE_BAND = 0.25
"""The gyroscope is called too fast (deg/s) when ``s`` ± 4 standard errors lies within ±this:
nowhere near 1, and near π/180 ≈ 0.017 (on every real recording quadest has, rad/s gave a band
around 1 or a wide one; docs/recordings.md)."""


BLOCK = 1 << 16
"""Rows per block where a check goes through a whole recording (its memory stays a few MB
whatever the recording's length)."""


JITTER_NOTED = 1.01
"""Timestamps whose intervals give ``mean(Δt²) / mean(Δt)²`` above this are called jittered."""


def timestamp_jitter(dt, median: float) -> dict:
    """How the intervals ``dt`` (their median ``median``) spread about their mean, the
    estimators' gaps (:data:`GAP_FACTOR`, :data:`GAP_MIN_S`) left out: the mean and the standard
    deviation (s), and ``mean(Δt²) / mean(Δt)²``, the factor by which a low-pass whose
    coefficients followed each interval would pass a fast motion (docs/estimators.md, robust,
    item 12). An IMU that samples on its own clock and is stamped by a host on arrival shows a
    large spread (DIDO's flights: 1.4 ms about 2.5 ms, the factor 1.28-1.35)."""
    limit = max(GAP_FACTOR * median, GAP_MIN_S)
    n = s1 = s2 = 0.0
    for a in range(0, len(dt), BLOCK):  # a few MB at a time, whatever the recording's length
        d = dt[a : a + BLOCK]
        d = d[(d > 0) & (d <= limit)]
        n, s1, s2 = n + len(d), s1 + float(d.sum()), s2 + float((d * d).sum())
    if n == 0:
        return {"interval_mean_s": None, "jitter_s": None, "jitter_gain": None}
    mean = s1 / n
    return {"interval_mean_s": mean, "jitter_s": max(0.0, s2 / n - mean**2) ** 0.5, "jitter_gain": s2 / n / mean**2}


def jitter_note(stats: dict) -> str | None:
    """What :func:`timestamp_jitter`'s ``stats`` say to a user when the stamps jitter (None when
    they do not)."""
    if (stats.get("jitter_gain") or 1.0) <= JITTER_NOTED:
        return None
    mean = stats["interval_mean_s"]
    return (
        f"the intervals spread {stats['jitter_s'] * 1e3:.3f} ms about their mean {mean * 1e3:.3f} ms "
        f"({1.0 / mean:.2f} Hz; mean(dt²)/mean(dt)² {stats['jitter_gain']:.3f}): stamps a host gave on arrival? "
        "robust's low-passes run at the mean interval (docs/estimators.md, robust, item 12)"
    )


def row_norms(a: np.ndarray) -> np.ndarray:
    """Each row's Euclidean norm, with no temporary the size of ``a`` (a damaged file's 1e300
    gives inf)."""
    with np.errstate(over="ignore"):
        return np.sqrt(np.einsum("ij,ij->i", a, a))


def row_abs_max(a: np.ndarray) -> np.ndarray:
    """Each row's largest magnitude, block by block."""
    out = np.empty(len(a))
    for s in range(0, len(a), BLOCK):
        out[s : s + BLOCK] = np.abs(a[s : s + BLOCK]).max(axis=1)
    return out


def turn_scale(t, gyr, v, *, offset: bool) -> tuple[float, float]:
    """``(s, standard error)`` of the least-squares fit ``dv/dt = −s ω × (v − b)`` over the rows
    where ``v`` is finite (``b`` a constant offset, fitted when ``offset``), ω the gyroscope's
    mean rate over each interval between such rows; ``(nan, inf)`` with too few rows. A long
    recording is fitted on :func:`sampled_spans` (the scale is one for the whole recording), in
    closed form from the intervals' vectors (:func:`_turn_normal`)."""
    rows, w, c, y = _turn_intervals(t, gyr, v)
    if rows < 50:
        return float("nan"), float("inf")
    m = 4 if offset else 1
    normal, aty = (a[:m, :m] if a.ndim == 2 else a[:m] for a in _turn_normal(w, c, y))
    count = y.size
    if count <= m or np.linalg.cond(normal) > 1e12:
        return float("nan"), float("inf")
    x = np.linalg.solve(normal, aty)
    r = y - x[0] * c - (np.cross(w, x[1:]) if offset else 0.0)  # the residuals
    cov = np.linalg.inv(normal) * float(np.einsum("ij,ij->", r, r)) / (count - m)
    return float(x[0]), float(np.sqrt(cov[0, 0]))


def _turn_intervals(t, gyr, v):
    """:func:`turn_scale`'s rows where ``v`` is finite (their count) and the intervals between
    consecutive ones within each span: the mean rates ω, the column of ``s`` (``c = −ω × v_mid``)
    and the observations ``y = Δv/Δt`` (intervals with a value that is not finite left out)."""
    rows, w, v0, v1, dt = 0, [], [], [], []
    for a, b in sampled_spans(len(v)):
        r = a + np.flatnonzero(np.isfinite(v[a:b]).all(axis=1))
        rows += len(r)
        if len(r) >= 2:
            w.append(_mean_rates(t, gyr, r))
            v0.append(v[r[:-1]])
            v1.append(v[r[1:]])
            dt.append(np.diff(t[r]))
    if not w:
        return rows, *(np.empty((0, 3)),) * 3
    w, v0, v1, dt = (np.concatenate(x) for x in (w, v0, v1, dt))
    y = (v1 - v0) / dt[:, None]
    c = -np.cross(w, 0.5 * (v0 + v1))
    keep = np.isfinite(w).all(axis=1) & np.isfinite(y).all(axis=1) & np.isfinite(c).all(axis=1)
    return rows, w[keep], c[keep], y[keep]


SAMPLED_ROWS = 8192
"""The most rows a statistical check (the gyroscope's scale, the tilt's median) looks at: a
longer recording is looked at in :data:`SAMPLED_SPANS` stretches of consecutive rows spread evenly
over it, so that checking costs the same whatever its length. A unit or a frame is one for the
whole recording; the fit's standard error grows as the square root of the rows left out (BROAD's
trials: 0.004 → 0.010 for rad/s, where a gyroscope in deg/s fits 0.017 ± 0.0002)."""
SAMPLED_SPANS = 16


def sampled_spans(n: int) -> list[tuple[int, int]]:
    """The ``[start, end)`` row ranges a statistical check looks at in ``n`` rows: all of them,
    or :data:`SAMPLED_SPANS` evenly spread stretches of :data:`SAMPLED_ROWS` in all."""
    if n <= SAMPLED_ROWS:
        return [(0, n)]
    length = SAMPLED_ROWS // SAMPLED_SPANS
    return [(int(a), int(a) + length) for a in np.linspace(0, n - length, SAMPLED_SPANS)]


def _turn_normal(w, c, y) -> tuple[np.ndarray, np.ndarray]:
    """``AᵀA`` and ``Aᵀy`` of the design ``A_i = [c_i | S(ω_i)]`` (three rows per interval;
    ``S(ω) b = ω × b``, the offset's columns: ω × (s b) is linear in ``s b``), summed over the
    intervals without forming ``A``: ``Sᵀc = −ω × c``, ``SᵀS = |ω|² I − ω ωᵀ``."""
    ww = np.einsum("ij,ik->jk", w, w)
    normal = np.empty((4, 4))
    normal[0, 0] = np.einsum("ij,ij->", c, c)
    normal[0, 1:] = normal[1:, 0] = -np.cross(w, c).sum(axis=0)
    normal[1:, 1:] = np.trace(ww) * np.eye(3) - ww
    aty = np.empty(4)
    aty[0] = np.einsum("ij,ij->", c, y)
    aty[1:] = -np.cross(w, y).sum(axis=0)
    return normal, aty


def _mean_rates(t, gyr, r) -> np.ndarray:
    """The gyroscope's mean rate over each interval between the rows ``r`` (its integral from
    ``r[0]`` taken at each row, differenced)."""
    angle = np.zeros((r[-1] - r[0] + 1, 3))
    np.cumsum(gyr[r[0] : r[-1]] * np.diff(t[r[0] : r[-1] + 1])[:, None], axis=0, out=angle[1:])
    return np.diff(angle[r - r[0]], axis=0) / np.diff(t[r])[:, None]


def gyro_scale(t, gyr, mag) -> tuple[float, float]:
    """``(s, standard error)`` against the magnetometer's field (free of accelerations, unlike
    gravity in the accelerometer, which on a multirotor in flight reads the thrust's direction
    and does not turn with the body); ``(nan, inf)`` without enough magnetometer samples."""
    if mag is None or np.isfinite(mag).all(axis=1).sum() < 50:
        return float("nan"), float("inf")
    return turn_scale(t, gyr, mag, offset=True)


STILL_S = 0.25  # a rest: the accelerometer this long within STILL_SPREAD of its mean and ...
STILL_SPREAD = 0.05 * GRAVITY
STILL_NORM = 0.03 * GRAVITY  # ... its mean's norm this close to g
TURN_MIN_DEG = 15.0  # only rests whose gravity directions differ by more count
DEG_S_RATIO = 0.25  # deg/s warned of when its summed misfit is below this share of rad/s's


def runs(mask, shortest: int = 1) -> list[tuple[int, int]]:
    """The index ranges ``[start, end)`` where ``mask`` holds, each at least ``shortest`` long."""
    held = np.concatenate([[False], np.asarray(mask, dtype=bool), [False]])
    edges = np.flatnonzero(held[1:] != held[:-1])
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True) if b - a >= shortest]


def rests(t, acc) -> list[tuple[int, int]]:
    """Stretches of at least :data:`STILL_S` in which the accelerometer holds still near g."""
    if len(t) < 3:
        return []
    k = max(2, int(round(STILL_S / max(median_interval(t), 1e-9))))
    if len(acc) <= k:
        return []
    still = np.zeros(len(t), bool)
    windows = len(acc) - k + 1  # a window of k samples starts at each of these
    for s in range(0, windows, BLOCK):
        e = min(s + BLOCK, windows)
        still[k // 2 + s : k // 2 + e] = _still_windows(acc[s : e + k - 1], k)
    return runs(still, k)


def _still_windows(acc, k) -> np.ndarray:
    """For each window of ``k`` samples of ``acc``: whether it holds still near g."""
    c1 = np.cumsum(np.vstack([np.zeros((1, 3)), acc]), axis=0)
    c2 = np.cumsum(np.vstack([np.zeros((1, 3)), acc**2]), axis=0)
    mean = (c1[k:] - c1[:-k]) / k
    spread = np.sqrt(np.maximum((c2[k:] - c2[:-k]) / k - mean**2, 0.0)).max(axis=1)
    return (spread < STILL_SPREAD) & (np.abs(np.linalg.norm(mean, axis=1) - GRAVITY) < STILL_NORM)


def _turned(gyr, dt, scale) -> Rotation:
    """The body's rotation over the samples (the product of each sample's, in order)."""
    r = Rotation.from_rotvec(scale * gyr * dt[:, None])
    while len(r) > 1:
        if len(r) % 2:
            r = Rotation.concatenate([r, Rotation.identity()])
        r = r[0::2] * r[1::2]
    return r[0]


def rest_misfits(t, gyr, acc) -> np.ndarray:
    """Per pair of consecutive rests whose gravity directions differ by more than
    :data:`TURN_MIN_DEG`: the angle (deg) between the second rest's gravity and the first's turned
    by the gyroscope read as rad/s, and as deg/s."""
    out = []
    spans = rests(t, acc)
    for (a0, b0), (a1, b1) in zip(spans[:-1], spans[1:]):
        g0, g1 = (acc[a:b].mean(axis=0) / np.linalg.norm(acc[a:b].mean(axis=0)) for a, b in ((a0, b0), (a1, b1)))
        if np.degrees(np.arccos(np.clip(g0 @ g1, -1.0, 1.0))) <= TURN_MIN_DEG:
            continue
        i, j = (a0 + b0) // 2, (a1 + b1) // 2
        fits = [_turned(gyr[i:j], np.diff(t[i : j + 1]), s).inv().apply(g0) @ g1 for s in (1.0, np.pi / 180.0)]
        out.append(np.degrees(np.arccos(np.clip(fits, -1.0, 1.0))))
    return np.array(out).reshape(-1, 2)


def warn_deg_s_from_rests(t, gyr, acc) -> None:
    """Warn when the rests' gravity turns far better with the gyroscope read as deg/s."""
    misfit = rest_misfits(t, gyr, acc)
    if len(misfit) and misfit[:, 1].sum() < DEG_S_RATIO * misfit[:, 0].sum():
        warnings.warn(
            f"gyr: between {len(misfit) + 1} rests the gravity in the accelerometer turns as the gyroscope "
            f"says only if it is read as deg/s ({misfit[:, 1].sum():.0f}° off in all, against "
            f"{misfit[:, 0].sum():.0f}° as rad/s): is it in deg/s? {RAD_S_FIX}",
            stacklevel=3,
        )


STILL_RATE_WARN = 0.8
"""rad/s: where the accelerometer holds still near g (:func:`rests`), the gyroscope's median rate
about the axes across gravity, which would tilt the body, is at most 0.34 rad/s on every real
recording quadest has (a quadrotor's figure eight; at rest and in a hover a few hundredths), and
1.1 to 8 in a hover recorded in deg/s (57 times as much): above this it is warned of..."""
STILL_SHARE = 0.25
"""...when such stretches make at least this share of the recording (an aggressive flight's few
still moments, yawing fast, do not count)."""


def still_rate_across_gravity(t, gyr, acc) -> tuple[float, float]:
    """``(median rate across gravity, share of the samples)`` over the rests: the gyroscope's
    component perpendicular to the accelerometer's direction (a turn about gravity, a yaw, leaves
    the accelerometer still; a turn across it would not); ``(nan, 0)`` without rests."""
    spans = rests(t, acc)
    if not spans:
        return float("nan"), 0.0
    rate = np.empty(sum(b - a for a, b in spans))
    at = 0
    for a, b in spans:
        for s in range(a, b, BLOCK):
            e = min(s + BLOCK, b)
            up = acc[s:e] / row_norms(acc[s:e])[:, None]
            rate[at : at + e - s] = row_norms(np.cross(gyr[s:e], up))
            at += e - s
    return float(np.median(rate, overwrite_input=True)), len(rate) / len(t)


def warn_deg_s_from_still_rates(t, gyr, acc) -> None:
    """Warn when the gyroscope turns fast where the accelerometer says the body holds still: a
    hover or a rest in deg/s (:data:`STILL_RATE_WARN`)."""
    rate, share = still_rate_across_gravity(t, gyr, acc)
    if share >= STILL_SHARE and rate > STILL_RATE_WARN:
        warnings.warn(
            f"gyr: where the accelerometer holds still ({100 * share:.0f} % of the samples) the gyroscope "
            f"reads {rate:.2f} (median, across gravity), as if the body tilted by {np.degrees(rate):.0f}°/s "
            f"as rad/s, or {rate:.2f}°/s as deg/s: is it in deg/s? {RAD_S_FIX}",
            stacklevel=3,
        )


def check_gyro_scale(t, gyr, mag=None) -> tuple[float, float]:
    """Refuse a gyroscope whose rates are far faster than the turning it should explain (a small
    positive scale: deg/s gives 0.0175; a negative one is another disagreement, not deg/s), and
    times far shorter than that turning took (:data:`TIME_SCALE_LIMIT`).
    Returns the fit ``(s, standard error)`` (:func:`gyro_scale`; an infinite error: the
    magnetometer could not tell at all)."""
    s, se = gyro_scale(t, gyr, mag)
    if np.isfinite(se) and 0.0 < s and s + 4 * se < SCALE_BAND and -SCALE_BAND < s - 4 * se:
        raise ValueError(
            f"gyr: the gyroscope reads about {1 / max(abs(s), 1e-3):.0f} times the rotation that turns "
            f"the magnetometer's field (scale {s:.4f} ± {se:.4f}; deg/s gives 0.0175): is it in deg/s "
            f"(or are the magnetometer's axes or times not the IMU's)? {RAD_S_FIX}"
        )
    if np.isfinite(se) and s - 4 * se > TIME_SCALE_LIMIT:
        raise ValueError(
            f"t: the magnetometer's field turns {s:.3g} times as far as the gyroscope's rates turn the body "
            f"over these times (scale {s:.4g} ± {se:.2g}; right times give 1): are the times shorter than "
            "they should be (a time in seconds stated as ms, a rate stated too high)? quadest takes "
            "seconds (a CSV: --units t=s|ms|us|ns)"
        )
    return s, se


TIME_SCALE_LIMIT = 2.0
"""The times are called too short when the scale ``s`` less 4 standard errors exceeds this: the
field turns at least twice as far as the gyroscope's rates, integrated over the stated times,
say (a time in seconds stated as ms gives 1000, a rate stated ten times too high 10)."""

RAD_S_FIX = "quadest takes rad/s (multiply deg/s by pi/180; a CSV: --units gyr=deg/s)"


TILT_WARN_DEG = 45.0
"""An estimate whose tilt is further than this (median) from the accelerometer's gravity, where
it reads g alone, is warned of: on every simulated and real recording quadest has, a working
estimate stays within 16° (a spinning vehicle after a rotor loss), a hover in deg/s 86°."""


def tilt_disagreement(q, acc) -> float:
    """The median angle (deg) between the estimate's "up" in the body and the accelerometer's
    direction, over the rows where the accelerometer reads g within 5 % (where it reads gravity
    alone, or a multirotor's thrust near the vertical); NaN with fewer than 50 such rows. A long
    recording is looked at every few rows (at most :data:`SAMPLED_ROWS`, evenly spread)."""
    step = -(-len(acc) // SAMPLED_ROWS) if len(acc) > SAMPLED_ROWS else 1
    q, acc = q[::step], acc[::step]
    angles, count = np.empty(len(acc)), 0
    for s in range(0, len(acc), BLOCK):
        block = _tilt_angles(q[s : s + BLOCK], acc[s : s + BLOCK])
        angles[count : count + len(block)] = block
        count += len(block)
    return float(np.median(angles[:count], overwrite_input=True)) if count >= 50 else float("nan")


def _tilt_angles(q, acc) -> np.ndarray:
    """:func:`tilt_disagreement`'s angles (deg) on the rows where the accelerometer reads g."""
    norm = np.linalg.norm(acc, axis=1)
    rows = np.isfinite(norm) & (np.abs(norm - GRAVITY) < 0.05 * GRAVITY) & np.isfinite(q).all(axis=1)
    up = quat_rotate(quat_conj(q[rows]), np.tile([0.0, 0.0, -1.0], (int(rows.sum()), 1)))
    cos = np.sum(up * acc[rows] / norm[rows, None], axis=1)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def warn_tilt_disagreement(name: str, q, acc) -> None:
    """Warn when an estimate's tilt and the accelerometer's gravity disagree (TILT_WARN_DEG)."""
    angle = tilt_disagreement(q, acc)
    if angle > TILT_WARN_DEG:
        warnings.warn(
            f"{name}: the estimate's tilt is {angle:.0f}° (median) from the gravity the accelerometer reads "
            "where it reads g alone: a gyroscope in deg/s, axes in another frame, or a failed estimate?",
            stacklevel=3,
        )


def warn_z_up(gyr, acc) -> None:
    """Warn when, at rest, the accelerometer reads +g along z most of the time: an FRD body
    frame reads −g level, a z-up (FLU) one +g. A long recording is looked at on
    :func:`sampled_spans`."""
    at_rest = z_up = 0
    for start, end in sampled_spans(len(acc)):
        a = acc[start:end]
        norm = row_norms(a)
        rest = (row_abs_max(gyr[start:end]) < REST_RATE) & (np.abs(norm - GRAVITY) < 0.1 * GRAVITY)
        at_rest += int(rest.sum())
        z_up += int((a[rest, 2] > 0.8 * norm[rest]).sum())
    if at_rest >= MIN_REST_SAMPLES and z_up > 0.5 * at_rest:
        warnings.warn(
            "acc: at rest the accelerometer reads +g along z (up): the body frame looks z-up (FLU, "
            "ROS's); quadest takes forward-right-down: give frame='enu-flu' (--frame enu-flu)",
            stacklevel=3,
        )


def _shown(v: float) -> str:
    """A value for a message: one decimal, or three digits when it is huge (a damaged file)."""
    return f"{v:.1f}" if abs(v) < 1e6 else f"{v:.3g}"


def _first_row(mask) -> int:
    return int(np.flatnonzero(mask)[0])


def check_magnitudes(t, gyr, acc) -> None:
    """Refuse magnitudes that show a unit mistake: a gyroscope beyond any sensor, an
    accelerometer in g or mg or scaled, a time in ms or µs."""
    _check_sensor_magnitudes(gyr, acc)
    _check_time_unit(t)


def _check_sensor_magnitudes(gyr, acc) -> None:
    rest = _quiet_gyro(gyr)
    norm = row_norms(acc)  # a damaged file's 1e300 gives inf: refused below
    big = norm > ACC_LIMIT
    if big.any():
        i = _first_row(big)
        raise ValueError(
            f"acc: norm {_shown(norm[i])} at row {i} exceeds {ACC_LIMIT:.0f} m/s²: "
            "is the accelerometer in mg or raw counts? quadest takes m/s²"
        )
    # not rotating (gyroscope quiet), the accelerometer reads gravity (about 9.8 m/s²) or,
    # falling without rotation, less: never much more
    at_rest = int(rest.sum())
    g_rest = float(np.median(norm[rest], overwrite_input=True)) if at_rest >= MIN_REST_SAMPLES else float("nan")
    row0 = norm[0]
    med, p95 = np.percentile(norm, [50, 95], overwrite_input=True)  # norm is reordered: not used after
    if len(acc) >= 10 and 0.5 < med < 1.5 and p95 < 3.0:
        raise ValueError(
            f"acc: norms look like g, not m/s² (median {med:.3f}, row 0 reads "
            f"{row0:.3f}); quadest takes m/s² (multiply g by 9.80665)"
        )
    if 500.0 < g_rest < 2000.0:  # 1 g = 1000 mg
        raise ValueError(
            f"acc: at rest the accelerometer reads {g_rest:.0f} (median norm): that is gravity "
            "in mg (or cm/s²), not m/s²; quadest takes m/s² (multiply mg by 0.00980665)"
        )
    if g_rest > 2.0 * GRAVITY:
        raise ValueError(
            f"acc: at rest (gyroscope below {REST_RATE} rad/s, {at_rest} samples) the "
            f"accelerometer reads {g_rest:.3g} (median norm), not gravity (9.81 m/s²): is "
            "it in another unit (ft/s²?) or scaled? quadest takes m/s²"
        )


def _quiet_gyro(gyr) -> np.ndarray:
    """Refuse a gyroscope beyond any sensor (deg/s); the rows where it reads below
    :data:`REST_RATE`."""
    gyr_max = row_abs_max(gyr)
    big = gyr_max > GYR_LIMIT
    if big.any():
        i = _first_row(big)
        raise ValueError(
            f"gyr: {_shown(np.abs(gyr[i]).max())} at row {i} exceeds {GYR_LIMIT:.0f} rad/s, "
            f"more than any MEMS gyroscope measures: is the gyroscope in deg/s? {RAD_S_FIX}"
        )
    return gyr_max < REST_RATE


def median_interval(t) -> float:
    """The median of ``t``'s intervals (one temporary of ``t``'s size, no second copy)."""
    return float(np.median(np.diff(t), overwrite_input=True))


MIN_INTERVAL_S = 2e-5
"""s: no IMU samples faster than 50 kHz (the fastest, ICM-42688's FIFO, at 32 kHz): times in
seconds stated as ms give 1000 times the rate (500 Hz: 500 kHz)."""


def _check_time_unit(t) -> None:
    """An IMU samples faster than once a second, and slower than :data:`MIN_INTERVAL_S`."""
    if len(t) >= 2 and 0 < (med_dt := median_interval(t)) < MIN_INTERVAL_S:
        raise ValueError(
            f"t: the median interval is {med_dt:g} s ({1 / med_dt:.3g} Hz), faster than any IMU: "
            "are the times in seconds (or the rate in Hz)?"
        )
    if len(t) >= 10:
        med_dt = median_interval(t)
        if med_dt > 1.0:
            unit = "ns" if med_dt > 1e5 else "µs" if med_dt > 200.0 else "ms"
            raise ValueError(
                f"t: the median interval is {med_dt:g} s ({1 / med_dt:.3g} Hz), slower than any "
                f"IMU: is the time in {unit}? quadest takes seconds"
            )


def check_units(t, gyr, acc, mag=None) -> None:
    """Every check of this module on finite samples: errors for unit mistakes, warnings for a
    gyroscope that looks like deg/s by its rests alone (without a magnetometer to tell: how the
    rests' gravity turns, and how fast it reads where the accelerometer holds still) and for a z-up
    body frame."""
    check_magnitudes(t, gyr, acc)
    s, se = check_gyro_scale(t, gyr, mag)
    if not np.isfinite(se):
        warn_deg_s_from_rests(t, gyr, acc)
    if not (np.isfinite(se) and abs(s - 1.0) + 4 * se < SCALE_BAND):  # unless the field confirms rad/s
        warn_deg_s_from_still_rates(t, gyr, acc)
    warn_z_up(gyr, acc)
