"""The samples' times and intervals as every estimator reads them: given times or a rate, and
the interval of each sample from the last usable time (a bad time is skipped, never a gap)."""

from __future__ import annotations

import math

import numpy as np

from quadest.errors import UsageError


def nominal_interval(dt) -> float:
    """The median of the usable (positive, finite) intervals; 0 when there is none."""
    ok = dt[np.isfinite(dt) & (dt > 0)]
    return float(np.median(ok)) if len(ok) else 0.0


def sample_times(t, rate, gyr, who: str) -> np.ndarray:
    """``t`` as float64, or ``k / rate`` for the rows of ``gyr``; exactly one must be given."""
    if (t is None) == (rate is None):
        raise UsageError(f"{who}: give the sample times t (s) or the sample rate rate (Hz), one of them")
    if t is not None:
        return np.asarray(t, dtype=np.float64)
    if isinstance(rate, bool) or not (isinstance(rate, (int, float, np.number)) and math.isfinite(rate) and rate > 0):
        raise UsageError(f"{who}: rate must be a positive number of samples per second, got {rate!r}")
    return np.arange(len(np.asarray(gyr))) / float(rate)


def sample_intervals(t) -> np.ndarray:
    """``dt[k] = t[k] − t[j]`` with ``t[j]`` the latest earlier time that was usable (finite, and
    later than every time before it); the first interval is the median of the usable ones (0 for
    one sample). A non-finite time or one that goes backwards gives an unusable interval (NaN or ≤ 0):
    the filters skip that sample, and the next one is measured from the last good time."""
    t = np.asarray(t, dtype=np.float64)
    if len(t) < 2:
        return np.zeros(len(t))
    latest = np.maximum.accumulate(np.where(np.isfinite(t), t, -np.inf))
    prev = np.concatenate([[-np.inf], latest[:-1]])
    with np.errstate(invalid="ignore"):  # inf − inf: NaN, as wanted
        dt = t - prev
        nominal = nominal_interval(np.diff(t))
    dt[~np.isfinite(prev) & np.isfinite(t)] = nominal  # the first usable sample
    dt[~np.isfinite(t)] = np.nan  # a NaN or infinite time: skipped and counted, never a gap
    return dt
