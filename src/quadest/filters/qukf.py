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
from quadest.filters.linalg import cholesky, inv_spd, mm, mm_t, mv
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
    return cholesky(M)


@njit(cache=True)
def _sigma(X, L):
    """Eq 20: ``X``, ``X + L_i``, ``X − L_i`` (rows), L the columns of √((n+λ)P)."""
    n = len(X)
    chi = np.empty((2 * n + 1, n))
    for j in range(n):
        chi[0, j] = X[j]
    for i in range(n):
        for j in range(n):
            chi[1 + i, j] = X[j] + L[j, i]
            chi[1 + n + i, j] = X[j] - L[j, i]
    return chi


@njit(cache=True)
def _propagate(F, chi):
    """Each sigma point (row) through the linear process model ``F``."""
    out = np.empty_like(chi)
    for k in range(chi.shape[0]):
        for i in range(4):
            out[k, i] = F[i, 0] * chi[k, 0] + F[i, 1] * chi[k, 1] + F[i, 2] * chi[k, 2] + F[i, 3] * chi[k, 3]
    return out


@njit(cache=True)
def _ut_mean(chi, w0, wi):
    n = chi.shape[1]
    m = np.empty(n)
    for j in range(n):
        s = w0 * chi[0, j]
        for k in range(1, chi.shape[0]):
            s += wi * chi[k, j]
        m[j] = s
    return m


@njit(cache=True)
def _ut_cov(A, ma, B, mb, w0, wi):
    """``Σ w_i (A_i − ma)(B_i − mb)ᵀ`` with w_0 for the central point."""
    n = A.shape[1]
    C = np.zeros((n, n))
    for k in range(A.shape[0]):
        w = w0 if k == 0 else wi
        for i in range(n):
            da = w * (A[k, i] - ma[i])
            for j in range(n):
                C[i, j] += da * (B[k, j] - mb[j])
    return C


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
    # eq 21, corrected: w_m0 = λ/(n+λ), w_c0 = w_m0 + 1 − α² + β, w_i = 1/(2(n+λ))
    wm0 = lam / (n + lam)
    wc0 = wm0 + 1.0 - alpha * alpha + beta
    wi = 1.0 / (2.0 * (n + lam))
    X = x[0:4].copy()
    F = omega_matrix(gyr, dt) if finite3(gyr) else np.eye(4)
    # eq 20: 2n + 1 sigma points; eq 22: through the process model
    chi = _propagate(F, _sigma(X, _sqrt_psd(P, n + lam)))
    # eqs 23-24
    Xp = _ut_mean(chi, wm0, wi)
    Pp = _ut_cov(chi, Xp, chi, Xp, wc0, wi)
    for i in range(4):
        Pp[i, i] += S
    z, ok = measurement_quaternion(acc, mag, Xp, use_mag)
    if ok:
        sig = _sigma(Xp, _sqrt_psd(Pp, n + lam))  # eq 25
        Zs = sig.copy()  # eq 26: Z_i = H X̃_i with H = I
        Zh = _ut_mean(Zs, wm0, wi)  # eq 27
        Pzz = _ut_cov(Zs, Zh, Zs, Zh, wc0, wi)  # eq 28
        for i in range(4):
            Pzz[i, i] += R
        Pxz = _ut_cov(sig, Xp, Zs, Zh, wc0, wi)  # eq 29
        K = mm(Pxz, inv_spd(Pzz))  # eq 30
        Xp = Xp + mv(K, z - Zh)  # eq 31
        Pp = Pp - mm_t(mm(K, Pzz), K)  # eq 32
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
