"""Constant rotations between an estimate's frames and the truth's (docs/readers.md, alignment).

Real truth often lives in other frames than the estimate: a motion-capture world whose x axis
is not north, a marker body that is not the IMU's axes. Evaluation then compares

    q_true ≈ q_nav ⊗ q_est ⊗ q_body

with ``q_nav`` a constant rotation of the navigation frame (``"heading"``: about the vertical
only, which keeps inclination errors untouched; ``"full"``: any rotation, for 6-axis data whose
reference is not gravity-aligned) and ``q_body`` a constant rotation of the body frame (IMU to
marker body). Both are least-squares (chordal) means; with both unknown, ``q_body`` starts
from the rotation that best maps the estimate's body rotation increments onto the truth's
(Kabsch on rotation vectors over 0.5 s) and the two are refined alternately.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from quadest.rotation import quat_conj, quat_mul, quat_to_rotvec
from quadest.rotation.quaternion import angle_between, matrix_to_quat

NAV_MODES = ("none", "heading", "full")


def mean_quat(q) -> np.ndarray:
    """Chordal L2 mean of unit quaternions (sign-invariant): the principal eigenvector of Σ q qᵀ."""
    q = np.asarray(q, float)
    w, v = np.linalg.eigh(q.T @ q)
    m = v[:, -1]
    return m if m[0] >= 0 else -m


def _heading_only(q):
    h = np.array([q[0], 0.0, 0.0, q[3]])
    n = np.linalg.norm(h)
    return h / n if n > 0 else np.array([1.0, 0, 0, 0])


@dataclass(frozen=True)
class Alignment:
    """``q_true ≈ q_nav ⊗ q_est ⊗ q_body``; :meth:`apply` maps an estimate into the truth's frames."""

    q_nav: np.ndarray
    q_body: np.ndarray
    nav: str = "none"
    body: bool = False

    def apply(self, q_est):
        return quat_mul(quat_mul(self.q_nav, np.asarray(q_est, float)), self.q_body)

    def describe(self) -> dict:
        """What was removed, in degrees (for reports)."""
        out = {"nav": self.nav, "body": self.body}
        ident = np.array([1.0, 0, 0, 0])
        if self.nav == "heading":
            out["heading_offset_deg"] = float(np.degrees(2 * np.arctan2(self.q_nav[3], self.q_nav[0])))
        elif self.nav == "full":
            out["nav_rotation_deg"] = float(np.degrees(angle_between(ident, self.q_nav)))
            out["nav_rotvec_deg"] = np.degrees(quat_to_rotvec(self.q_nav)).tolist()
        if self.body:
            out["body_rotation_deg"] = float(np.degrees(angle_between(ident, self.q_body)))
            out["body_rotvec_deg"] = np.degrees(quat_to_rotvec(self.q_body)).tolist()
        return out


def _body_init(q_est, q_true, lag):
    """Rotation R_B (IMU body -> marker body) from rotation increments: the truth's increment
    in its body frame is R_Bᵀ times the estimate's (Kabsch / Wahba)."""
    a = quat_to_rotvec(quat_mul(quat_conj(q_est[:-lag]), q_est[lag:]))
    b = quat_to_rotvec(quat_mul(quat_conj(q_true[:-lag]), q_true[lag:]))
    H = b.T @ a  # maps a onto b: b ≈ R a with R = R_Bᵀ
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(U @ Vt))
    R = U @ np.diag([1.0, 1.0, d]) @ Vt
    return matrix_to_quat(R.T)


def fit_alignment(
    q_est,
    q_true,
    *,
    nav: str = "heading",
    body: bool = False,
    mask=None,
    rate_hz: float | None = None,
    iterations: int = 30,
) -> Alignment:
    """Fit the constant rotations over the rows with truth (and ``mask``)."""
    if nav not in NAV_MODES:
        raise ValueError(f"unknown alignment {nav!r}; one of {', '.join(NAV_MODES)}")
    q_est, q_true = np.asarray(q_est, float), np.asarray(q_true, float)
    ok = np.isfinite(q_est).all(axis=1) & np.isfinite(q_true).all(axis=1)
    if mask is not None:
        ok &= np.asarray(mask, bool)
    if ok.sum() < 2:
        raise ValueError("alignment: fewer than two samples with truth")
    qe, qt = q_est[ok], q_true[ok]
    qn, qb = np.array([1.0, 0, 0, 0]), np.array([1.0, 0, 0, 0])
    if body:
        lag = max(1, int(0.5 * rate_hz)) if rate_hz else max(1, len(qe) // 200)
        lag = min(lag, len(qe) - 1)
        qb = _body_init(qe, qt, lag)
    for _ in range(iterations if body else 1):
        if nav != "none":
            m = mean_quat(quat_mul(qt, quat_conj(quat_mul(qe, qb))))
            qn = _heading_only(m) if nav == "heading" else m
        if body:
            qb_new = mean_quat(quat_mul(quat_conj(quat_mul(qn, qe)), qt))
            step = angle_between(qb, qb_new)
            qb = qb_new
            if step < 1e-10:
                break
    return Alignment(qn, qb, nav, body)
