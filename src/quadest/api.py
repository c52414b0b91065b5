"""quadest as a library, in three lines (README, Python)::

    import quadest
    est = quadest.estimate(gyr, acc, mag, rate=200.0)  # rad/s, m/s², any unit; FRD body frame
    est.q, est.euler, est.to_pandas()

    rec = quadest.read("flight.ulg")  # every format quadest reads (docs/readers.md)
    print(quadest.score(rec, quadest.estimate(rec)))

Arrays are checked like files are (:mod:`quadest.data.checks`): a gyroscope in deg/s, an
accelerometer in g or mg, a time in ms, a z-up body frame are each named in one error or warning
with the fix. A sample that cannot be used (NaN, an interval that is not positive) is skipped and
counted (``est.skipped``), never refused.
"""

from __future__ import annotations

import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from quadest.data.checks import check_units, warn_tilt_disagreement
from quadest.data.recording import Recording
from quadest.errors import UsageError
from quadest.evaluation import runner
from quadest.filters import FilterResult, estimator_class
from quadest.filters.timing import sample_intervals, sample_times
from quadest.readers import read_recording
from quadest.rotation.frames import quat_ned_frd_to_enu_flu, vec_flu_to_frd

FRAMES = ("ned-frd", "enu-flu")
"""``ned-frd``: quadest's (north-east-down, forward-right-down); ``enu-flu``: ROS's (REP 103)."""


def read(path: str | Path, format: str | None = None, **options) -> Recording:
    """Any file or folder quadest reads, as a :class:`Recording` in quadest's conventions:
    ULog, DataFlash, ROS bags, BROAD / DIDO / RepoIMU / Blackbird, CSV or Parquet (generic with
    ``columns=``, or quadest's own). ``format`` overrides the detection; ``options`` go to the
    format's reader (docs/readers.md). What the command line says on stderr about the file (a
    log cut short or damaged, rows dropped) is said here as a ``UserWarning``, one line naming
    the file; it is also kept in ``meta['warnings']`` and ``meta['dropped_rows']``."""
    rec = read_recording(path, format, **options)
    dropped = rec.meta.get("dropped_rows")
    if dropped:
        warnings.warn(
            f"{path}: dropped {dropped} row(s) with a repeated or decreasing time or a bad IMU value", stacklevel=2
        )
    for warning in rec.meta.get("warnings", []):
        warnings.warn(f"{path}: {warning}", stacklevel=2)
    return rec


def _vectors(name: str, a, n: int | None) -> np.ndarray:
    try:
        v = np.array(a, dtype=np.float64)
    except (TypeError, ValueError):
        raise UsageError(f"quadest.estimate: {name} must be a numeric array of shape (N, 3)") from None
    if v.ndim != 2 or v.shape[1] != 3 or (n is not None and len(v) != n):
        want = f"({n}, 3)" if n is not None else "(N, 3)"
        raise UsageError(f"quadest.estimate: {name} must have shape {want}, got {v.shape}")
    return v


def _checked(t, gyr, acc, mag) -> None:
    """The unit and frame checks of a file, on the rows an estimator would use."""
    rows = np.isfinite(t) & (sample_intervals(t) > 0) & np.isfinite(gyr).all(1) & np.isfinite(acc).all(1)
    if rows.sum() >= 10 and not acc[rows].any():
        raise ValueError(
            "quadest.estimate: acc is exactly zero on every row: a dead sensor or the wrong array? (even "
            "in free fall an accelerometer's noise is not zero)"
        )
    if rows.all():  # the usual case: no copies
        check_units(t, gyr, acc, mag)
    elif rows.sum() >= 2:
        check_units(t[rows], gyr[rows], acc[rows], None if mag is None else mag[rows])


def _from_recording(rec: Recording, method: str, declination: float | None, others: dict, params: dict):
    given = sorted(k for k, v in others.items() if v is not None and not (k == "frame" and v == "ned-frd"))
    if given:
        raise UsageError(f"quadest.estimate: a Recording carries its own {', '.join(given)}; give those with arrays")
    return runner.estimate(rec, method, params, declination=declination)


def estimate(
    gyr: ArrayLike | Recording,
    acc: ArrayLike | None = None,
    mag: ArrayLike | None = None,
    *,
    rate: float | None = None,
    t: ArrayLike | None = None,
    method: str = "robust",
    frame: str = "ned-frd",
    declination: float | None = None,
    check: bool = True,
    **params,
) -> FilterResult:
    """The attitude over a whole recording, or over arrays: ``gyr`` (rad/s) and ``acc`` (m/s²)
    of shape (N, 3), ``mag`` optional (any unit; a NaN row: no new sample), timed by ``t`` (s) or
    ``rate`` (Hz). ``method``: an estimator's name (``quadest.ESTIMATORS``); ``params`` its
    parameters. ``frame``: the body and navigation frames of the arrays and of the result's
    ``q`` (:data:`FRAMES`). ``declination`` (rad, east positive) turns the magnetic heading
    into the geographic one (a recording's own by default). ``check=False`` skips the unit checks.

    Returns a :class:`~quadest.filters.FilterResult`: ``.t``, ``.q`` (``[w, x, y, z]``, body to
    navigation), ``.euler`` (rad), ``.diagnostics``, ``.skipped``, ``.to_pandas()``."""
    _check_declination(declination)
    if isinstance(gyr, Recording):
        others = {"acc": acc, "mag": mag, "rate": rate, "t": t, "frame": frame}
        res = _said_if_skipped(_from_recording(gyr, method, declination, others, params))
        if check:
            warn_tilt_disagreement(res.name, res.q, gyr.acc)
        return res
    if frame not in FRAMES:
        raise UsageError(f"quadest.estimate: frame must be one of {', '.join(FRAMES)}, got {frame!r}")
    if acc is None:
        raise UsageError("quadest.estimate: give the accelerometer acc (m/s², shape (N, 3)) beside gyr")
    gyr = _vectors("gyr", gyr, None)
    acc = _vectors("acc", acc, len(gyr))
    mag = None if mag is None else _vectors("mag", mag, len(gyr))
    t = sample_times(t, rate, gyr, "quadest.estimate")
    if t.shape != (len(gyr),):
        raise UsageError(f"quadest.estimate: t must have shape ({len(gyr)},), got {t.shape}")
    if frame == "enu-flu":
        gyr, acc = vec_flu_to_frd(gyr), vec_flu_to_frd(acc)
        mag = None if mag is None else vec_flu_to_frd(mag)
    if check:
        _checked(t, gyr, acc, mag)
    cls = estimator_class(method)
    runner.check_params(cls.name, params)
    res = cls(declination=0.0 if declination is None else declination, **params).run(t=t, gyr=gyr, acc=acc, mag=mag)
    res = _said_if_skipped(res)
    if check:
        warn_tilt_disagreement(res.name, res.q, acc)
    return replace(res, q=quat_ned_frd_to_enu_flu(res.q), frame=frame) if frame == "enu-flu" else res


SKIPPED_WARN = 0.01
"""Skipping more than this share of the samples is said (a warning); skipping all is an error."""


def _said_if_skipped(res: FilterResult) -> FilterResult:
    n = len(res.t)
    if n >= 2 and res.skipped == n:
        raise ValueError(
            f"quadest.estimate: none of the {n} samples could be used (times not increasing, or not "
            "finite, or sensor values not finite): check t (float32 seconds since the epoch lose "
            "their fraction: use float64) and the arrays"
        )
    if n and res.skipped > SKIPPED_WARN * n:
        warnings.warn(
            f"{res.name}: skipped {res.skipped} of {n} samples (a time not after the one before, or "
            "a value that is not finite); the attitude is held over them",
            stacklevel=3,
        )
    return res


def _check_declination(declination) -> None:
    if declination is None:
        return
    if isinstance(declination, bool) or not isinstance(declination, (int, float, np.number)):
        raise UsageError(f"quadest.estimate: declination must be a number in rad, got {declination!r}")
    if not abs(float(declination)) <= np.pi:
        raise UsageError(
            f"quadest.estimate: declination {float(declination):.4g} is not an angle in rad within ±pi "
            "(degrees? multiply by pi/180)"
        )


def score(rec: Recording, est: FilterResult | ArrayLike, **options) -> dict:
    """Error figures (degrees) of an estimate against the recording's truth (``true_q``, or a
    log's onboard attitude ``ref_q``): RMS and percentiles of roll, pitch, yaw and the total
    angle, after removing the constant rotations the recording's reader names (docs/metrics).
    ``options`` go to :func:`quadest.evaluation.runner.score` (``t_from``, ``nav``, ``body``)."""
    if not isinstance(rec, Recording):
        raise UsageError(f"quadest.score: the first argument is the Recording, got {type(rec).__name__}")
    if isinstance(est, FilterResult):
        if est.frame != "ned-frd":
            raise UsageError("quadest.score: the estimate is in ENU/FLU; a Recording is in NED/FRD")
        if len(est.t) != len(rec) or not np.allclose(est.t, rec.t, equal_nan=True):
            raise UsageError(
                f"quadest.score: the estimate's {len(est.t)} times are not the recording's {len(rec)}: "
                "score an estimate of this recording"
            )
        if not options:
            return runner.score_result(rec, est)
        est = est.q
    return runner.score(rec, _unit_quaternions(est, len(rec)), **options)


def _unit_quaternions(q, n: int) -> np.ndarray:
    q = np.asarray(q, dtype=np.float64)
    if q.shape != (n, 4):
        raise UsageError(f"quadest.score: the estimate must be quaternions of shape ({n}, 4), got {q.shape}")
    norm = np.linalg.norm(q, axis=1)
    ok = np.isfinite(norm)
    if ok.any() and np.abs(norm[ok] - 1.0).max() > 1e-3:
        raise UsageError("quadest.score: the estimate's quaternions are not unit quaternions ([w, x, y, z])")
    return q
