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


RATE_TOLERANCE = 0.05
"""A rate given with the times may differ from their median interval's by this share at most."""


def sample_times(t, rate, gyr, who: str) -> np.ndarray:
    """``t`` as float64, or ``k / rate`` for the rows of ``gyr``; given both, the rate must agree
    with the times' median interval (:data:`RATE_TOLERANCE`) and the times are used."""
    if t is None and rate is None:
        raise UsageError(f"{who}: give the sample times t (s) or the sample rate rate (Hz)")
    if rate is not None and (
        isinstance(rate, bool) or not (isinstance(rate, (int, float, np.number)) and math.isfinite(rate) and rate > 0)
    ):
        raise UsageError(f"{who}: rate must be a positive number of samples per second, got {rate!r}")
    if t is None:
        return np.arange(len(np.asarray(gyr))) / float(rate)
    t = np.asarray(t, dtype=np.float64)
    if rate is not None and t.ndim == 1 and len(t) >= 2:
        _check_rate_against_times(t, float(rate), who)
    return t


def _check_rate_against_times(t, rate: float, who: str) -> None:
    """Refuse a stated rate that the times contradict (their median interval's rate)."""
    with np.errstate(invalid="ignore"):
        dt = np.diff(t)
    dt = dt[np.isfinite(dt) & (dt > 0)]
    if not len(dt):
        return
    of_times = 1.0 / float(np.median(dt))
    if abs(of_times / rate - 1.0) > RATE_TOLERANCE:
        raise UsageError(
            f"{who}: rate={rate:g} Hz, but the times t step {1 / of_times:.3g} s (median), {of_times:.4g} Hz: "
            "they disagree; give the times in seconds and the rate in Hz, or only one of them"
        )


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
