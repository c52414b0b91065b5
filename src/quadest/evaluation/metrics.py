"""Attitude errors and their statistics (quadest conventions: ``q_nb``, NED, ZYX).

- Per-axis Euler error: ``euler(q_est) − euler(q_true)``, each wrapped to ±180°, as the AFCKF
  and QUKF papers tabulate (roll, pitch, yaw).
- Total, heading and inclination error as the BROAD benchmark defines them (Laidig et al. 2021):
  the error rotation in the navigation frame ``e = q_est ⊗ q_true⁻¹`` split into a rotation about
  the vertical (heading, ``2 atan2(|e_z|, |e_w|)``) and the rest (inclination,
  ``2 acos(√(e_w² + e_z²))``); the total is its angle ``2 atan2(|e_xyz|, |e_w|)``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from quadest.rotation import quat_conj, quat_mul, quat_to_euler

AXES = ("roll", "pitch", "yaw")


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def euler_errors(q_est: ArrayLike, q_true: ArrayLike) -> np.ndarray:
    """Per-axis ZYX Euler error (rad) wrapped to ±π, shape (N, 3): roll, pitch, yaw."""
    return _wrap(quat_to_euler(q_est) - quat_to_euler(q_true))


def error_angles(q_est: ArrayLike, q_true: ArrayLike) -> dict:
    """Total, heading and inclination error angles (rad) per sample (BROAD's definitions)."""
    e = quat_mul(q_est, quat_conj(q_true))
    w, z = np.abs(e[:, 0]), np.abs(e[:, 3])
    total = 2 * np.arctan2(np.linalg.norm(e[:, 1:], axis=1), w)
    heading = 2 * np.arctan2(z, w)
    inclination = 2 * np.arccos(np.clip(np.sqrt(e[:, 0] ** 2 + e[:, 3] ** 2), 0.0, 1.0))
    return {"total": total, "heading": heading, "inclination": inclination}


def _rms(x):
    return float(np.sqrt(np.mean(np.square(x)))) if len(x) else float("nan")


def summarize_errors(q_est: ArrayLike, q_true: ArrayLike, mask: ArrayLike | None = None) -> dict:
    """RMS, variance and mean absolute value of the per-axis errors (degrees, degrees²) and the
    RMS of total, heading and inclination errors, over the rows in ``mask`` with truth."""
    q_est, q_true = np.asarray(q_est, float), np.asarray(q_true, float)
    ok = np.isfinite(q_true).all(axis=1) & np.isfinite(q_est).all(axis=1)
    if mask is not None:
        ok &= np.asarray(mask, bool)
    if not ok.any():
        raise ValueError("no samples with truth to evaluate")
    e = np.degrees(euler_errors(q_est[ok], q_true[ok]))
    ang = {k: np.degrees(v) for k, v in error_angles(q_est[ok], q_true[ok]).items()}
    return {
        "samples": int(ok.sum()),
        "rms_deg": {a: _rms(e[:, i]) for i, a in enumerate(AXES)},
        "var_deg2": {a: float(np.var(e[:, i])) for i, a in enumerate(AXES)},
        "mae_deg": {a: float(np.mean(np.abs(e[:, i]))) for i, a in enumerate(AXES)},
        "total_rmse_deg": _rms(ang["total"]),
        "heading_rmse_deg": _rms(ang["heading"]),
        "inclination_rmse_deg": _rms(ang["inclination"]),
    }


def nees(q_est, q_true, var_tilt, var_heading, mask=None) -> float:
    """Mean normalised estimation error squared of an estimator's reported attitude covariance
    (diagonal in the navigation frame: ``var_tilt`` about north and about east, ``var_heading``
    about down, rad²): ``e = Log(q_true ⊗ q_est⁻¹)``, ``NEES = (e_N² + e_E²)/var_tilt +
    e_D²/var_heading``, 3 degrees of freedom (a consistent covariance gives 3 on average)."""
    from scipy.spatial.transform import Rotation

    q_est, q_true = np.asarray(q_est, float), np.asarray(q_true, float)
    ok = np.isfinite(q_true).all(axis=1) & np.isfinite(q_est).all(axis=1) & (var_tilt > 0) & (var_heading > 0)
    if mask is not None:
        ok &= np.asarray(mask, bool)
    if not ok.any():
        return float("nan")
    err = quat_mul(q_true[ok], quat_conj(q_est[ok]))
    e = Rotation.from_quat(err[:, [1, 2, 3, 0]]).as_rotvec()
    return float(np.mean((e[:, 0] ** 2 + e[:, 1] ** 2) / var_tilt[ok] + e[:, 2] ** 2 / var_heading[ok]))
