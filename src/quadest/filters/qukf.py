"""Quaternion unscented Kalman filter of Liang et al. 2023 (IEEE Access), eqs 16-32.

State ``X = q`` (n = 4); process ``X_t = (I + T/2 Ω(ω)) X_{t−1}`` (eqs 9, 18) with noise S;
measurement ``Z = H X``, ``H = I`` (eq 19), with ``Z`` the quaternion from the accelerometer and
magnetometer (:mod:`quadest.filters.quatmeas`) and noise R; 2n + 1 sigma points (eq 20) with
scaling λ, α, β. Corrections of printed typos:

- eq 21 prints the weights ``ξ^i = λ/(2(n + λ))`` for i ≥ 1; with λ = −1 they would not sum to
  one. The unscented transform's weights are ``1/(2(n + λ))`` (and ``ξ_m^0 = λ/(n + λ)``,
  ``ξ_c^0 = λ/(n + λ) + 1 − α² + β``).
- eq 28 is the innovation covariance ``P_zz`` (printed as ``P_xz``), eq 29 the cross covariance
  ``Σ ξ_c (X̃ − X̂)(Z − Ẑ)ᵀ`` (printed with ``Ẑ`` for ``X̂``); eq 30 is ``K = P_xz P_zz⁻¹``.

The paper's S = 0.001 I and R = 0.05 I are per step of its 20 Hz filter. At another sampling
interval ``dt`` quadest uses ``S·dt/T`` and ``R·T/dt`` with ``T = 1/rate_ref_hz``, so the filter
keeps the paper's time constants at any rate (``scale_with_rate=False`` takes them as they are).
The state is renormalised after each update (section IV).
"""
from dataclasses import dataclass

import numpy as np
from numba import njit

from quadest.filters.base import Estimator, P, Params
from quadest.filters.common import BASE, finite3, omega_matrix, prepare
from quadest.filters.quatmeas import measurement_quaternion

PB = BASE  # covariance P, 16 values, row-major


@dataclass(frozen=True)
class QukfParams(Params):
    use_mag: bool = P(True, "-", "use the magnetometer heading in the measurement", "-")
    lam: float = P(-1.0, "-", "sigma-point scaling λ", "Liang et al. 2023, section IV")
    alpha: float = P(1.0, "-", "spread α", "Liang et al. 2023, section IV")
    beta: float = P(2.0, "-", "prior-distribution parameter β", "Liang et al. 2023, section IV")
    s: float = P(0.001, "-", "process noise S = s·I per reference step", "Liang et al. 2023, section IV")
    r: float = P(0.05, "-", "measurement noise R = r·I per reference step", "Liang et al. 2023, section IV")
    p0: float = P(1.0, "-", "initial covariance P0 = p0·I (not given in the paper)", "assumption")
    rate_ref_hz: float = P(20.0, "Hz", "rate at which s and r are given", "Liang et al. 2023 (20 Hz)")
    scale_with_rate: bool = P(True, "-", "scale s by dt/T and r by T/dt", "quadest (see module doc)")


@njit(cache=True)
def noise(p, dt):
    """Per-step S and R at interval dt (module doc)."""
    if p[8] > 0.0 and dt > 0.0:
        T = 1.0 / p[7]
        return p[4] * dt / T, p[5] * T / dt
    return p[4], p[5]


@njit(cache=True)
def _sym(P):
    return 0.5 * (P + P.T)


@njit(cache=True)
def _sqrt_psd(P, scale):
    """Cholesky factor of ``scale·P`` (a small jitter keeps it positive definite)."""
    M = _sym(P) * scale
    for i in range(4):
        M[i, i] += 1e-15
    return np.linalg.cholesky(M)


@njit(cache=True)
def qukf_step(x, p, gyr, acc, mag, dt, diag):
    use_mag = p[0] > 0.0
    diag[0] = 0.0
    if not prepare(x, acc, mag, use_mag):
        return
    n = 4
    lam, alpha, beta = p[1], p[2], p[3]
    S, R = noise(p, dt)
    P = x[PB:PB + 16].copy().reshape((4, 4))
    wm0 = lam / (n + lam)
    wc0 = wm0 + 1.0 - alpha * alpha + beta
    wi = 1.0 / (2.0 * (n + lam))  # eq 21, corrected
    X = x[0:4].copy()
    F = omega_matrix(gyr, dt) if finite3(gyr) else np.eye(4)
    # eqs 20, 22-24: sigma points through the process model
    L = _sqrt_psd(P, n + lam)
    chi = np.empty((2 * n + 1, 4))
    chi[0] = F @ X
    for i in range(n):
        chi[1 + i] = F @ (X + L[:, i])
        chi[1 + n + i] = F @ (X - L[:, i])
    Xp = wm0 * chi[0]
    for i in range(1, 2 * n + 1):
        Xp = Xp + wi * chi[i]
    Pp = np.eye(4) * S
    d = chi[0] - Xp
    Pp += wc0 * np.outer(d, d)
    for i in range(1, 2 * n + 1):
        d = chi[i] - Xp
        Pp += wi * np.outer(d, d)
    z, ok = measurement_quaternion(acc, mag, Xp, use_mag)
    if ok:
        # eq 25: new sigma points; eq 26: Z_i = H X̃_i = X̃_i
        L = _sqrt_psd(Pp, n + lam)
        sig = np.empty((2 * n + 1, 4))
        sig[0] = Xp
        for i in range(n):
            sig[1 + i] = Xp + L[:, i]
            sig[1 + n + i] = Xp - L[:, i]
        Zh = wm0 * sig[0]
        for i in range(1, 2 * n + 1):
            Zh = Zh + wi * sig[i]
        Pzz = np.eye(4) * R  # eq 28
        Pxz = np.zeros((4, 4))  # eq 29
        for i in range(2 * n + 1):
            w = wc0 if i == 0 else wi
            dz = sig[i] - Zh
            Pzz += w * np.outer(dz, dz)
            Pxz += w * np.outer(sig[i] - Xp, dz)
        K = Pxz @ np.linalg.inv(Pzz)  # eq 30
        Xp = Xp + K @ (z - Zh)  # eq 31
        Pp = Pp - K @ Pzz @ K.T  # eq 32
        diag[0] = 1.0
    Pp = _sym(Pp)
    nq = np.sqrt(np.sum(Xp * Xp))
    x[0:4] = Xp / nq
    x[PB:PB + 16] = Pp.ravel()
    diag[1] = np.trace(Pp)


@njit(cache=True)
def qukf_run(x, p, dt, gyr, acc, mag, q_out, diag_out):
    """Batch: the same step over every sample, in compiled code."""
    for k in range(len(dt)):
        qukf_step(x, p, gyr[k], acc[k], mag[k], dt[k], diag_out[k])
        q_out[k] = x[0:4]


class Qukf(Estimator):
    """QUKF. Diagnostics: ``updated`` (1 when a measurement was fused) and ``trace_p``."""

    name = "qukf"
    Params = QukfParams
    state_size = BASE + 16
    diag_names = ("updated", "trace_p")
    step = staticmethod(qukf_step)
    batch = staticmethod(qukf_run)

    def _init_state(self, x):
        x[PB:PB + 16] = (np.eye(4) * self.params.p0).ravel()
