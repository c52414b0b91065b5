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


SUM_ROWS = 1 << 18
"""Rows per block where errors are summed: a long recording's errors are never held whole (a
recording up to this length gives the figures of one pass, bit for bit)."""


class ErrorSums:
    """The sums behind :func:`summarize_errors`, fed block by block: per axis the count, mean and
    squared deviations (combined as Chan et al. combine variances), the sum of squares and of
    absolute values; the squares of total, heading and inclination errors."""

    def __init__(self):
        self.blocks = []  # (n, mean, var, sum of squares, sum of |e|) per block, per axis
        self.angle_squares = {"total": 0.0, "heading": 0.0, "inclination": 0.0}

    def add(self, q_est: ArrayLike, q_true: ArrayLike, mask: ArrayLike | None = None) -> None:
        """Add the rows of ``mask`` (all when None) where both quaternions are finite."""
        q_est, q_true = np.asarray(q_est, float), np.asarray(q_true, float)
        ok = np.isfinite(q_true).all(axis=1) & np.isfinite(q_est).all(axis=1)
        if mask is not None:
            ok &= np.asarray(mask, bool)
        if not ok.any():
            return
        e = np.degrees(euler_errors(q_est[ok], q_true[ok]))
        self.blocks.append((int(ok.sum()), [_axis_sums(e[:, i]) for i in range(3)]))
        for k, v in error_angles(q_est[ok], q_true[ok]).items():
            self.angle_squares[k] += float(np.sum(np.square(np.degrees(v))))

    def summary(self) -> dict:
        """What :func:`summarize_errors` returns."""
        n = sum(b[0] for b in self.blocks)
        if not n:
            raise ValueError("no samples with truth to evaluate")
        axes = [self._axis([(b[0], *b[1][i]) for b in self.blocks], n) for i in range(3)]
        return {
            "samples": n,
            "rms_deg": {a: float(np.sqrt(axes[i][1] / n)) for i, a in enumerate(AXES)},
            "var_deg2": {a: axes[i][0] for i, a in enumerate(AXES)},
            "mae_deg": {a: float(axes[i][2] / n) for i, a in enumerate(AXES)},
            **{f"{k}_rmse_deg": float(np.sqrt(v / n)) for k, v in self.angle_squares.items()},
        }

    @staticmethod
    def _axis(blocks, n) -> tuple[float, float, float]:
        """One axis's variance, sum of squares and sum of magnitudes over its blocks."""
        if len(blocks) == 1:
            _, _, var, sq, ab = blocks[0]
            return float(var), float(sq), float(ab)
        mean = sum(b * m for b, m, *_ in blocks) / n
        m2 = sum(b * v + b * (m - mean) ** 2 for b, m, v, *_ in blocks)
        return float(m2 / n), float(sum(b[3] for b in blocks)), float(sum(b[4] for b in blocks))


def _axis_sums(e) -> tuple:
    """One axis's mean, variance, sum of squares and sum of magnitudes."""
    return np.mean(e), np.var(e), np.sum(np.square(e)), np.sum(np.abs(e))


def summarize_errors(q_est: ArrayLike, q_true: ArrayLike, mask: ArrayLike | None = None) -> dict:
    """RMS, variance and mean absolute value of the per-axis errors (degrees, degrees²) and the
    RMS of total, heading and inclination errors, over the rows in ``mask`` with truth (summed
    by blocks of :data:`SUM_ROWS`: :class:`ErrorSums`)."""
    q_est, q_true = np.asarray(q_est, float), np.asarray(q_true, float)
    mask = None if mask is None else np.asarray(mask, bool)
    sums = ErrorSums()
    for a in range(0, max(len(q_est), 1), SUM_ROWS):
        sums.add(q_est[a : a + SUM_ROWS], q_true[a : a + SUM_ROWS], None if mask is None else mask[a : a + SUM_ROWS])
    return sums.summary()


def nees_terms(q_est, q_true, var_tilt, var_heading, mask=None) -> tuple[float, float]:
    """The two parts of :func:`nees`, each a mean over the rows: the tilt's ``(e_N² + e_E²) /
    var_tilt`` (2 degrees of freedom) and the heading's ``e_D² / var_heading`` (1); nan where no
    row has a finite estimate, truth and positive variances."""
    from scipy.spatial.transform import Rotation

    q_est, q_true = np.asarray(q_est, float), np.asarray(q_true, float)
    ok = np.isfinite(q_true).all(axis=1) & np.isfinite(q_est).all(axis=1) & (var_tilt > 0) & (var_heading > 0)
    if mask is not None:
        ok &= np.asarray(mask, bool)
    if not ok.any():
        return float("nan"), float("nan")
    err = quat_mul(q_true[ok], quat_conj(q_est[ok]))
    e = Rotation.from_quat(err[:, [1, 2, 3, 0]]).as_rotvec()
    return float(np.mean((e[:, 0] ** 2 + e[:, 1] ** 2) / var_tilt[ok])), float(np.mean(e[:, 2] ** 2 / var_heading[ok]))


def nees(q_est, q_true, var_tilt, var_heading, mask=None) -> float:
    """Mean normalised estimation error squared of an estimator's reported attitude covariance
    (diagonal in the navigation frame: ``var_tilt`` about north and about east, ``var_heading``
    about down, rad²): ``e = Log(q_true ⊗ q_est⁻¹)``, ``NEES = (e_N² + e_E²)/var_tilt +
    e_D²/var_heading``, 3 degrees of freedom (a consistent covariance gives 3 on average)."""
    return float(sum(nees_terms(q_est, q_true, var_tilt, var_heading, mask)))
