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

from collections import namedtuple
from dataclasses import dataclass

import numpy as np

from quadest._jit import njit
from quadest.filters.base import Estimator, Params, coefficient_offsets, params_record
from quadest.filters.common import (
    BASE,
    admit,
    admitted_mag,
    finite3,
    layout,
    omega_matrix,
    prepare,
    publish,
    run_and_stream,
)
from quadest.filters.linalg import inv_spd_into
from quadest.filters.quatmeas import measurement_quaternion
from quadest.records import param
from quadest.rotation.kernels import FASTMATH

STATE = layout(("P", 16), start=BASE)  # covariance P, row-major
PB = STATE.P


@dataclass(frozen=True)
class QukfParams(Params):
    use_mag: bool = param(
        True, "-", "use the magnetometer heading in the measurement", "quadest: 9-axis when samples are present"
    )
    lam: float = param(-1.0, "-", "sigma-point scaling λ", "Liang et al. 2023, section IV", bounds="(-4, 1e3]")
    alpha: float = param(1.0, "-", "spread α", "Liang et al. 2023, section IV", bounds="(0, 10]")
    beta: float = param(2.0, "-", "prior-distribution parameter β", "Liang et al. 2023, section IV", bounds="[0, 100]")
    s: float = param(
        0.001, "-", "process noise S = s·I per reference step", "Liang et al. 2023, section IV", bounds="(0, 1e6]"
    )
    r: float = param(
        0.05, "-", "measurement noise R = r·I per reference step", "Liang et al. 2023, section IV", bounds="(0, 1e6]"
    )
    p0: float = param(
        1.0,
        "-",
        "initial covariance P0 = p0·I",
        "chosen: large against a unit quaternion's components (the paper gives none)",
        bounds="(0, 1e6]",
    )
    rate_ref_hz: float = param(
        20.0, "Hz", "rate at which s and r are given", "Liang et al. 2023 (20 Hz)", bounds="(0, 1e6]"
    )
    scale_with_rate: bool = param(
        True, "-", "scale s by dt/T and r by T/dt", "quadest: keeps the paper's time constants at any rate (module doc)"
    )


PARAM = Record = params_record(QukfParams)
Coefficients = namedtuple("Coefficients", ["wm0", "wc0", "wi", "T"])
COEF = coefficient_offsets(Coefficients)


def coefficients(p: QukfParams) -> Coefficients:
    """Eq 21, corrected: the unscented weights ``w_m0 = λ/(n+λ)``, ``w_c0 = w_m0 + 1 − α² + β``,
    ``w_i = 1/(2(n+λ))`` (n = 4); and the reference step ``T = 1/rate_ref_hz``."""
    n = 4
    wm0 = p.lam / (n + p.lam)
    return Coefficients(
        wm0=wm0, wc0=wm0 + 1.0 - p.alpha * p.alpha + p.beta, wi=1.0 / (2.0 * (n + p.lam)), T=1.0 / p.rate_ref_hz
    )


@njit(cache=True, fastmath=FASTMATH)
def noise(p, c, dt):
    """Per-step process and measurement noise (the paper's S and R; Q and R here) at interval
    dt (module doc)."""
    if p[PARAM.scale_with_rate] != 0.0 and dt > 0.0:
        return p[PARAM.s] * dt / c[COEF.T], p[PARAM.r] * c[COEF.T] / dt
    return p[PARAM.s], p[PARAM.r]


@njit(cache=True, fastmath=FASTMATH)
def _chol_scaled(P, scale, L):
    """Lower Cholesky factor of ``scale·(P + Pᵀ)/2`` into ``L`` (clamped at 0; a 1e-15 jitter on
    the diagonal keeps it positive definite)."""
    n = P.shape[0]
    for j in range(n):
        for i in range(n):
            L[i, j] = 0.0
    for j in range(n):
        s = scale * P[j, j] + 1e-15
        for k in range(j):
            s -= L[j, k] * L[j, k]
        d = np.sqrt(s) if s > 0.0 else 0.0
        L[j, j] = d
        for i in range(j + 1, n):
            s = scale * 0.5 * (P[i, j] + P[j, i])
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / d if d > 0.0 else 0.0


@njit(cache=True, fastmath=FASTMATH)
def _sigma(X, L, chi):
    """Eq 20: ``X``, ``X + L_i``, ``X − L_i`` (rows of ``chi``), L the columns of √((n+λ)P)."""
    n = len(X)
    for j in range(n):
        chi[0, j] = X[j]
    for i in range(n):
        for j in range(n):
            chi[1 + i, j] = X[j] + L[j, i]
            chi[1 + n + i, j] = X[j] - L[j, i]


@njit(cache=True, fastmath=FASTMATH)
def _ut_mean(chi, w0, wi, m):
    n = chi.shape[1]
    for j in range(n):
        s = w0 * chi[0, j]
        for k in range(1, chi.shape[0]):
            s += wi * chi[k, j]
        m[j] = s


@njit(cache=True, fastmath=FASTMATH)
def _ut_cov(A, ma, B, mb, w0, wi, C):
    """``C = Σ w_i (A_i − ma)(B_i − mb)ᵀ`` with w_0 for the central point."""
    n = A.shape[1]
    for i in range(n):
        for j in range(n):
            C[i, j] = 0.0
    for k in range(A.shape[0]):
        w = w0 if k == 0 else wi
        for i in range(n):
            da = w * (A[k, i] - ma[i])
            for j in range(n):
                C[i, j] += da * (B[k, j] - mb[j])


@njit(cache=True, fastmath=FASTMATH)
def qukf_step(x, p, c, gyr, acc, mag, dt, diag):
    if not admit(x, gyr, acc, mag, dt):  # skipped and counted; the state stays as it was
        return
    mag = admitted_mag(x)  # NaN where its value was unusable (counted): the rest is used
    use_mag = p[PARAM.use_mag] != 0.0
    diag[0] = 0.0
    if not prepare(x, acc, mag, use_mag):
        return
    n = 4
    Q, R = noise(p, c, dt)
    P = x[PB : PB + 16].reshape((4, 4))  # a view: updated in place
    W = np.empty(2 * 36 + 7 * 16 + 8)  # one scratch buffer for every intermediate
    chi = W[0:36].reshape((9, 4))
    sig = W[36:72].reshape((9, 4))
    L = W[72:88].reshape((4, 4))
    Pp = W[88:104].reshape((4, 4))
    Pzz = W[104:120].reshape((4, 4))
    Pxz = W[120:136].reshape((4, 4))
    K = W[136:152].reshape((4, 4))
    M = W[152:168].reshape((4, 4))
    Minv = W[168:184].reshape((4, 4))
    Xp = W[184:188]
    Zh = W[188:192]
    wm0, wc0, wi = c[COEF.wm0], c[COEF.wc0], c[COEF.wi]  # eq 21, corrected (coefficients)
    # eq 20: 2n + 1 sigma points; eq 22: through the process model F = I + T/2 Ω(ω)
    _chol_scaled(P, n + p[PARAM.lam], L)
    _sigma(x[0:4], L, sig)
    if finite3(gyr):
        F = omega_matrix(gyr, dt)
        for k in range(9):
            for i in range(4):
                chi[k, i] = F[i, 0] * sig[k, 0] + F[i, 1] * sig[k, 1] + F[i, 2] * sig[k, 2] + F[i, 3] * sig[k, 3]
    else:
        chi[:, :] = sig
    # eqs 23-24
    _ut_mean(chi, wm0, wi, Xp)
    _ut_cov(chi, Xp, chi, Xp, wc0, wi, Pp)
    for i in range(4):
        Pp[i, i] += Q
    z, ok = measurement_quaternion(acc, mag, Xp, use_mag)
    if ok:
        _chol_scaled(Pp, n + p[PARAM.lam], L)
        _sigma(Xp, L, sig)  # eq 25; eq 26: Z_i = H X̃_i = X̃_i
        _ut_mean(sig, wm0, wi, Zh)  # eq 27
        _ut_cov(sig, Zh, sig, Zh, wc0, wi, Pzz)  # eq 28
        for i in range(4):
            Pzz[i, i] += R
        _ut_cov(sig, Xp, sig, Zh, wc0, wi, Pxz)  # eq 29
        for i in range(4):
            for j in range(4):
                M[i, j] = Pzz[i, j]
        inv_spd_into(M, Minv)
        for i in range(4):  # eq 30: K = P_xz P_zz⁻¹
            for j in range(4):
                K[i, j] = (
                    Pxz[i, 0] * Minv[0, j] + Pxz[i, 1] * Minv[1, j] + Pxz[i, 2] * Minv[2, j] + Pxz[i, 3] * Minv[3, j]
                )
        d0, d1, d2, d3 = z[0] - Zh[0], z[1] - Zh[1], z[2] - Zh[2], z[3] - Zh[3]
        for i in range(4):  # eq 31
            Xp[i] += K[i, 0] * d0 + K[i, 1] * d1 + K[i, 2] * d2 + K[i, 3] * d3
        # eq 32: P = P⁻ − K P_zz Kᵀ  (M = K P_zz)
        for i in range(4):
            for j in range(4):
                M[i, j] = K[i, 0] * Pzz[0, j] + K[i, 1] * Pzz[1, j] + K[i, 2] * Pzz[2, j] + K[i, 3] * Pzz[3, j]
        for i in range(4):
            for j in range(4):
                Pp[i, j] -= M[i, 0] * K[j, 0] + M[i, 1] * K[j, 1] + M[i, 2] * K[j, 2] + M[i, 3] * K[j, 3]
        diag[0] = 1.0
    tr = 0.0
    for i in range(4):
        for j in range(4):
            P[i, j] = 0.5 * (Pp[i, j] + Pp[j, i])
        tr += P[i, i]
    nq = np.sqrt(Xp[0] * Xp[0] + Xp[1] * Xp[1] + Xp[2] * Xp[2] + Xp[3] * Xp[3])
    for i in range(4):
        x[i] = Xp[i] / nq
    diag[1] = tr
    publish(x)


qukf_run, qukf_stream = run_and_stream(qukf_step, fastmath=FASTMATH)


class Qukf(Estimator):
    """QUKF. Diagnostics: ``updated`` (1 when a measurement was fused) and ``trace_p``."""

    name = "qukf"
    Params = QukfParams
    Record = Record
    coefficients = staticmethod(coefficients)
    state_size = STATE.end
    diag_names = ("updated", "trace_p")
    step = staticmethod(qukf_step)
    batch = staticmethod(qukf_run)
    stream = staticmethod(qukf_stream)

    def _init_state(self, x):
        x[PB : PB + 16] = (np.eye(4) * self.params.p0).ravel()
