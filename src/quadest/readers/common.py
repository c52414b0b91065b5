"""What every reader shares: unit factors, frame changes, putting magnetometer samples on IMU
rows, resampling a reference attitude, and building the Recording with the file's name in any
error (docs/readers.md)."""

from __future__ import annotations

import numpy as np

from quadest.conventions import GRAVITY
from quadest.data.checks import ACC_LIMIT, GYR_LIMIT, row_abs_max, row_norms
from quadest.data.recording import Recording
from quadest.rotation import quat_continuous, quat_normalize
from quadest.rotation.quaternion import quat_mul

# factors to quadest's units (SI; magnetometer µT)
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
GYR_UNITS = {"rad/s": 1.0, "deg/s": np.pi / 180.0}
ACC_UNITS = {"m/s^2": 1.0, "g": GRAVITY, "mg": 1e-3 * GRAVITY}
MAG_UNITS = {"uT": 1.0, "nT": 1e-3, "T": 1e6, "gauss": 100.0, "mgauss": 0.1, "mG": 0.1, "G": 100.0}

_S = np.sqrt(0.5)
Q_ENU_TO_NED = np.array([0.0, _S, _S, 0.0])


class ReaderError(ValueError):
    """A file that cannot be read; the message names the file and what is wrong."""


def reason(exc: BaseException) -> str:
    """What a library raised, on one line: its kind and its message with every run of
    whitespace (a damaged name's newlines) made one space."""
    return f"{type(exc).__name__}: {' '.join(str(exc).split())}"


def unit_factor(kind: str, unit: str) -> float:
    table = {"t": TIME_UNITS, "gyr": GYR_UNITS, "acc": ACC_UNITS, "mag": MAG_UNITS}[kind]
    if unit not in table:
        raise ReaderError(f"unknown {kind} unit {unit!r}; known: {', '.join(table)}")
    return table[unit]


def z_up_nav_to_ned(q):
    """``q_nb`` with a z-up navigation frame (ENU, or any x/y in the horizontal plane) and the
    body frame left as it is -> NED navigation frame. A horizontal x/y that is not east/north
    leaves a constant heading offset, which evaluation estimates and removes (docs/readers.md)."""
    return quat_mul(Q_ENU_TO_NED, np.asarray(q, float))


def mag_on_imu_rows(t_imu, t_mag, mag):
    """Put each magnetometer sample on the first IMU row at or after its time (the last sample
    wins when several fall on one row); other rows are NaN, meaning "no new sample"."""
    out = np.full((len(t_imu), 3), np.nan)
    if len(t_mag) == 0:
        return out
    idx = np.searchsorted(t_imu, t_mag, side="left")
    ok = idx < len(t_imu)
    out[idx[ok]] = np.asarray(mag, float)[ok]
    return out


def _increasing(t, q):
    """The rows whose time is finite and beyond every earlier row's (a strictly increasing time
    for the interpolation: a repeated, backward or NaN time is left out)."""
    ok = np.isfinite(t)
    t, q = t[ok], q[ok]
    if len(t) == 0:
        return t, q
    before = np.maximum.accumulate(np.concatenate([[-np.inf], t[:-1]]))
    keep = t > before
    return t[keep], q[keep]


def resample_quat(t_src, q_src, t, max_gap: float = 0.1):
    """Quaternions at ``t`` by spherical interpolation of ``(t_src, q_src)``; NaN outside the
    source's time span and inside gaps longer than ``max_gap`` seconds."""
    from scipy.spatial.transform import Rotation, Slerp

    t_src = np.asarray(t_src, float)
    q_src = np.asarray(q_src, float)
    with np.errstate(over="ignore", invalid="ignore"):  # damaged values: inf norms are not > 0.5 usable rows
        ok = np.isfinite(q_src).all(axis=1) & (np.linalg.norm(q_src, axis=1) > 0.5)
    t_src, q_src = t_src[ok], quat_normalize(q_src[ok])
    t_src, q_src = _increasing(t_src, q_src)
    out = np.full((len(t), 4), np.nan)
    if len(t_src) < 2:
        return out
    inside = (t >= t_src[0]) & (t <= t_src[-1])
    slerp = Slerp(t_src, Rotation.from_quat(q_src, scalar_first=True))
    out[inside] = slerp(t[inside]).as_quat(scalar_first=True)
    j = np.clip(np.searchsorted(t_src, t, side="right"), 1, len(t_src) - 1)
    gap = (t_src[j] - t_src[j - 1]) > max_gap
    out[gap & inside] = np.nan
    good = np.isfinite(out[:, 0])
    out[good] = quat_continuous(out[good])
    return out


MAX_DROPPED_SHARE = 0.05
"""A reader refuses a file in which more than this share of the rows must be dropped."""


def _isolated_implausible(t, gyr, acc) -> np.ndarray:
    """Rows a damaged sample made implausible, to drop as a NaN is: a gyroscope or accelerometer
    value beyond any sensor (:data:`~quadest.data.checks.GYR_LIMIT`, ``ACC_LIMIT``), and a time
    ahead of the next while the ones around it are in order (one ``TimeUS`` jump). Values beyond
    any sensor on more than ``MAX_DROPPED_SHARE`` of the rows are a unit, not damage: they are
    kept, for the unit checks to name."""
    with np.errstate(invalid="ignore", over="ignore"):
        beyond = (row_abs_max(np.asarray(gyr, float)) > GYR_LIMIT) | (row_norms(np.asarray(acc, float)) > ACC_LIMIT)
    if beyond.sum() > MAX_DROPPED_SHARE * len(t):
        beyond[:] = False
    ahead = np.zeros(len(t), bool)
    if len(t) >= 3:
        ahead[1:-1] = (t[1:-1] > t[2:]) & (t[:-2] < t[2:])
        ahead[0] = t[0] > t[1] and t[1] < t[2]
    return beyond | ahead


def make_recording(path, fmt: str, t, gyr, acc, mag=None, meta=None, **truth) -> Recording:
    """A Recording from a reader's converted arrays, in the file's own time (so an output joins
    the file's other data; where it starts is also ``meta['t0_s']``); rows with repeated or
    decreasing timestamps, non-finite IMU values or an isolated implausible value or time
    (:func:`_isolated_implausible`) are dropped (and counted in
    ``meta['dropped_rows']``; every command reports them), more than ``MAX_DROPPED_SHARE`` of
    them is refused, and any validation error names the file."""
    t = np.asarray(t, float)
    if len(t) == 0:
        raise ReaderError(f"{path}: no IMU samples")
    good = np.isfinite(t) & np.isfinite(gyr).all(axis=1) & np.isfinite(acc).all(axis=1)
    good &= ~_isolated_implausible(t, gyr, acc)
    t_run = np.maximum.accumulate(np.where(good, t, -np.inf))
    good &= np.concatenate([[True], t[1:] > t_run[:-1]])
    meta = dict(meta or {})
    meta.setdefault("source", str(path))
    meta["format"] = fmt
    meta["t0_s"] = float(t[good][0]) if good.any() else float("nan")
    if (~good).any():
        meta["dropped_rows"] = int((~good).sum())
    if not good.any():
        raise ReaderError(f"{path}: no valid IMU sample")
    if (~good).sum() > MAX_DROPPED_SHARE * len(t):
        raise ReaderError(
            f"{path}: {int((~good).sum())} of {len(t)} rows have a repeated or decreasing time or a "
            "non-finite or implausible IMU value (more than {:.0f} %): is the file sorted by time, and are the "
            "columns the right ones?".format(100 * MAX_DROPPED_SHARE)
        )
    kw = {k: (np.asarray(v, float)[good] if v is not None else None) for k, v in truth.items()}
    try:
        return Recording(
            t=t[good],
            gyr=np.asarray(gyr, float)[good],
            acc=np.asarray(acc, float)[good],
            mag=None if mag is None else np.asarray(mag, float)[good],
            meta=meta,
            **kw,
        )
    except ValueError as exc:
        raise ReaderError(f"{path}: {exc}") from None
