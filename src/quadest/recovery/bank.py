"""The bank of EKFs of the recovery paper (Beffa, Ledergerber & D'Andrea), section IV, eqs 15-36
and the appendix (eqs 40-46), on quadest's conventions.

Each hypothesis i carries a reference attitude ``q_ref`` (``q_nb``, body to NED) and a stochastic
state ``x = (v_b, δ_x, δ_y, z)``: the body-frame velocity, two components of an error rotation,
``q = q_ref ⊗ Exp(δ)`` with ``δ_z = 0`` (eqs 17, 19; the heading about gravity is unobservable),
and the height z (NED, m down; not the paper's). The paper's ``R = exp(−[δ]×) R_ref`` (inertial
to body) is this same right-multiplied error.

Prior (eqs 22-25), with ω the previous gyroscope sample and ``g_b = R_bn g_n`` (g_n = [0, 0, g]):

    v̄ = v + ΔT (−ω × v + f_c(v, ω)/m + g_b),   q_ref ← q_ref ⊗ Exp(ω ΔT),   P̄ = F P Fᵀ + Q

with ``F = I + ΔT [[−[ω]× + Υ/m, Γ2, 0], [0, Γ4, 0], [ĝᵀ, (v × ĝ)_{x, y}, 0]]``, ``Γ2 = ∂g_b/∂(δx,
δy)`` = the first two columns of ``[g_b]×`` (eq 42), ``Γ4 = [[0, ω_z], [−ω_z, 0]]`` and the height
row from ``ż = ĝᵀ v`` (``ĝ = g_b/g``; docs/recovery.md derives it); no process noise on z.

Posterior (eqs 26-30): ``r = z_acc − f_c(v̄, ω)/m``, ``H = [Υ/m, 0, 0]``, ``W = H P̄ Hᵀ + Σ_acc``,
``K = P̄ Hᵀ W⁻¹``, ``x = x̄ + K r``, ``P = (I − K H) P̄``, then ``q_ref ← q_ref ⊗ Exp((δx, δy, 0))``
and δ back to zero. The covariance reset of the paper's ref [18] multiplies the δ block by
``I − ½[δ]×``; restricted to (δx, δy) with δ_z = 0 that block is the identity, so P is kept.

Likelihood (eqs 31-34) in the log domain: ``ℓ_i += −½ rᵀ W⁻¹ r − ½ log det(2π W)`` and the
probabilities ``p_i ∝ exp(ℓ_i)`` are normalised by log-sum-exp, so they never underflow.

A barometer reading ``b`` (m up; ``baro_var`` > 0 in the record, else not read) updates each
hypothesis as the nominal EKF does (:mod:`quadest.recovery.nominal`): ``y = b + z``,
``S = P_zz + baro_var``, ``K = −P[:, z]/S``, and adds its scalar eq 33, ``−½ y²/S − ½ log(2π S)``,
to ``ℓ_i``. A hypothesis's z is NaN until set (at the detection, or by its first reading).

Corrections of the printed appendix (pinned by finite-difference tests):

- eq 44 prints ``Γ4 = ½ [[0, ω_z], [−ω_z, 0]]``. Both q and q_ref turn with ω, so
  ``Exp(δ⁺) = Exp(−ω ΔT) Exp(δ) Exp(ω ΔT)``: ``δ̇ = −ω × δ``, whose (x, y) block has no ½.
- eq 45 prints ``Υ = A + (v vᵀ + I ‖v‖²)/‖v‖``; the derivative of ``B ‖v‖ v`` is
  ``B (v vᵀ + I ‖v‖²)/‖v‖``: the B is missing.
- eq 33 prints the normaliser ``1/√(2π|W|)``; for the 3-D accelerometer residual it is
  ``(2π)^{−3/2} |W|^{−1/2}`` (the constant cancels between hypotheses, |W| does not).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from quadest._jit import NO_ALLOCATION, njit
from quadest.rotation.kernels import FASTMATH, qexp_right

BankRecord = namedtuple("BankRecord", ["gravity", "mass", "acc_var", "q_vel", "q_att", "baro_var"])
"""The bank's parameters in compiled code: gravity (m/s²), mass (kg), accelerometer noise
variance per axis ((m/s²)², eq 27), process noise intensities of velocity ((m/s²)²·s) and of
the error rotation (rad²/s), the barometer's noise variance (m²; 0: the bank does not read it).
Built by :meth:`quadest.recovery.RecoveryParams.bank_record`."""

NX = 6
"""A hypothesis's state size: body velocity (3), error rotation (2), height (1)."""

LOG_2PI = np.log(2.0 * np.pi)


@njit(cache=True, fastmath=FASTMATH)
def _aero(v, w, A, B, C, m, f, U):
    """f = f_c(v, ω)/m (eq 9) and U = Υ/m = (∂f_c/∂v)/m (eq 45, corrected), in place."""
    sp = np.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    ps0, ps1, ps2 = w[0], w[1], w[2]
    ps3, ps4, ps5 = w[0] * w[0], w[1] * w[1], w[2] * w[2]
    ps6, ps7, ps8 = w[0] * w[1], w[1] * w[2], w[2] * w[0]
    for i in range(3):
        s = C[i, 0] * ps0 + C[i, 1] * ps1 + C[i, 2] * ps2 + C[i, 3] * ps3 + C[i, 4] * ps4
        s += C[i, 5] * ps5 + C[i, 6] * ps6 + C[i, 7] * ps7 + C[i, 8] * ps8 + C[i, 9]
        for j in range(3):
            s += (A[i, j] + B[i, j] * sp) * v[j]
        f[i] = s / m
    for i in range(3):
        for j in range(3):
            u = A[i, j]
            if sp > 0.0:
                # B (v vᵀ + I |v|²)/|v|: column j of B v vᵀ/|v| plus B[i, j] |v|
                u += (B[i, 0] * v[0] + B[i, 1] * v[1] + B[i, 2] * v[2]) * v[j] / sp + B[i, j] * sp
            U[i, j] = u / m


@njit(cache=True, fastmath=FASTMATH)
def gravity_body(q, g, out):
    """g_b = R_bn g_n = g · (row 2 of R_nb)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    out[0] = g * 2.0 * (x * z - w * y)
    out[1] = g * 2.0 * (y * z + w * x)
    out[2] = g * (1.0 - 2.0 * (x * x + y * y))


@njit(cache=True, inline="always")
def transition_matrix(F, U, w, v, gb, g, dt):
    """F = I + ΔT [[−[ω]× + Υ/m, Γ2, 0], [0, Γ4, 0], [ĝᵀ, (v × ĝ)_{x, y}, 0]] (eqs 40-45 and the
    height row), into ``F`` (6, 6)."""
    for r in range(NX):
        for c in range(NX):
            F[r, c] = 0.0
    for r in range(3):
        for c in range(3):
            F[r, c] = dt * U[r, c]
    F[0, 1] += dt * w[2]
    F[0, 2] -= dt * w[1]
    F[1, 0] -= dt * w[2]
    F[1, 2] += dt * w[0]
    F[2, 0] += dt * w[1]
    F[2, 1] -= dt * w[0]
    F[0, 4] = -dt * gb[2]  # Γ2: columns x, y of [g_b]×
    F[1, 3] = dt * gb[2]
    F[2, 3] = -dt * gb[1]
    F[2, 4] = dt * gb[0]
    F[3, 4] = dt * w[2]  # Γ4 (eq 44, corrected)
    F[4, 3] = -dt * w[2]
    F[5, 0], F[5, 1], F[5, 2] = dt * gb[0] / g, dt * gb[1] / g, dt * gb[2] / g  # ∂ż/∂v = ĝᵀ
    F[5, 3] = dt * (v[1] * gb[2] - v[2] * gb[1]) / g  # ∂ż/∂δ = (v × ĝ)_{x, y}
    F[5, 4] = dt * (v[2] * gb[0] - v[0] * gb[2]) / g
    for r in range(NX):
        F[r, r] += 1.0


@njit(cache=True, inline="always")
def predict_covariance(Pi, F, T, q_vel, q_att, dt, nx):
    """P̄ = F P Fᵀ + Q in place (``T`` scratch) on the first ``nx`` states (5: the height's
    row and column left as they are, for a bank that does not read the barometer)."""
    for r in range(nx):
        for c in range(nx):
            s = 0.0
            for k in range(nx):
                s += F[r, k] * Pi[k, c]
            T[r, c] = s
    for r in range(nx):
        for c in range(r, nx):
            s = 0.0
            for k in range(nx):
                s += T[r, k] * F[c, k]
            Pi[r, c] = s
            Pi[c, r] = s
    for r in range(3):
        Pi[r, r] += q_vel * dt
    Pi[3, 3] += q_att * dt
    Pi[4, 4] += q_att * dt


@njit(cache=True, inline="always")
def inverse_3x3(Wm, Wi):
    """``Wi = Wm⁻¹`` by cofactors; returns the determinant."""
    c00 = Wm[1, 1] * Wm[2, 2] - Wm[1, 2] * Wm[2, 1]
    c01 = Wm[1, 2] * Wm[2, 0] - Wm[1, 0] * Wm[2, 2]
    c02 = Wm[1, 0] * Wm[2, 1] - Wm[1, 1] * Wm[2, 0]
    det = Wm[0, 0] * c00 + Wm[0, 1] * c01 + Wm[0, 2] * c02
    Wi[0, 0], Wi[1, 0], Wi[2, 0] = c00 / det, c01 / det, c02 / det
    Wi[0, 1] = (Wm[0, 2] * Wm[2, 1] - Wm[0, 1] * Wm[2, 2]) / det
    Wi[1, 1] = (Wm[0, 0] * Wm[2, 2] - Wm[0, 2] * Wm[2, 0]) / det
    Wi[2, 1] = (Wm[0, 1] * Wm[2, 0] - Wm[0, 0] * Wm[2, 1]) / det
    Wi[0, 2] = (Wm[0, 1] * Wm[1, 2] - Wm[0, 2] * Wm[1, 1]) / det
    Wi[1, 2] = (Wm[0, 2] * Wm[1, 0] - Wm[0, 0] * Wm[1, 2]) / det
    Wi[2, 2] = (Wm[0, 0] * Wm[1, 1] - Wm[0, 1] * Wm[1, 0]) / det
    return det


@njit(cache=True, inline="always")
def update_covariance(Pi, T, K, PH, nx):
    """P = (I − K H) P̄ = P̄ − K (P Hᵀ)ᵀ, symmetrised, in place (``T`` scratch), on the first
    ``nx`` states."""
    for r in range(nx):
        for c in range(nx):
            T[r, c] = Pi[r, c] - (K[r, 0] * PH[c, 0] + K[r, 1] * PH[c, 1] + K[r, 2] * PH[c, 2])
    for r in range(nx):
        for c in range(nx):
            Pi[r, c] = 0.5 * (T[r, c] + T[c, r])


@njit(cache=True, inline="always")
def mahalanobis_3(r0, r1, r2, Wi):
    """``rᵀ W⁻¹ r``."""
    return (
        r0 * (Wi[0, 0] * r0 + Wi[0, 1] * r1 + Wi[0, 2] * r2)
        + r1 * (Wi[1, 0] * r0 + Wi[1, 1] * r1 + Wi[1, 2] * r2)
        + r2 * (Wi[2, 0] * r0 + Wi[2, 1] * r1 + Wi[2, 2] * r2)
    )


@njit(cache=True, inline="always")
def barometer_term(v, q, Pi, Z, i, baro, baro_var, K):
    """A barometer reading ``baro`` (m up) of hypothesis ``i``'s height ``−Z[i]`` (module doc):
    the scalar update in place (``K`` scratch) and its log-likelihood term. A NaN ``Z[i]`` is
    set to the reading, with variance ``baro_var`` and no term."""
    if not np.isfinite(Z[i]):
        Z[i] = -baro
        for r in range(NX):
            Pi[r, 5] = 0.0
            Pi[5, r] = 0.0
        Pi[5, 5] = baro_var
        return 0.0
    y = baro + Z[i]
    S = Pi[5, 5] + baro_var
    for r in range(NX):
        K[r] = -Pi[r, 5] / S
    for r in range(NX):
        for c in range(r, NX):
            Pi[r, c] += K[r] * Pi[5, c]
    for r in range(NX):
        for c in range(r):
            Pi[r, c] = Pi[c, r]
    v[0], v[1], v[2] = v[0] + K[0] * y, v[1] + K[1] * y, v[2] + K[2] * y
    Z[i] += K[5] * y
    qexp_right(q, K[3] * y, K[4] * y, 0.0)  # the error rotation reset, as eq 30
    return -0.5 * y * y / S - 0.5 * (LOG_2PI + np.log(S))


@njit(cache=True, fastmath=FASTMATH)
def bank_step(bank, sample, prm, model):
    """Advance every hypothesis by one IMU sample (in place): ``bank`` is ``(V, Qr, P, L, Z,
    w_prev)``, ``V`` (H, 3), ``Qr`` (H, 4), ``P`` (H, 6, 6), ``L`` (H), ``Z`` (H) the heights (NaN:
    not yet read); ``sample`` is ``(gyr, acc, dt, update, baro)``; ``prm``: a :data:`BankRecord`;
    ``model``: the aerodynamic model's ``(A, B, C)``. ``update`` False skips the accelerometer
    update (prior only; the likelihoods stay): the nominal estimator's gate while the attitude
    control error is large (section V-B). ``baro``: the barometer's reading this sample (m up;
    NaN: none)."""
    work = (
        np.empty(3),  # f: the aerodynamic force per mass
        np.empty((3, 3)),  # U: its Jacobian in v
        np.empty(3),  # g_b
        np.empty((NX, NX)),  # F
        np.empty((NX, NX)),  # scratch
        np.empty((NX, 3)),  # P Hᵀ
        np.empty((3, 3)),  # the innovation covariance
        np.empty((3, 3)),  # its inverse
        np.empty((NX, 3)),  # K
        np.empty(3),  # the prior velocity
        np.empty(NX),  # the correction
    )
    V, Qr, P, L, Z, w_prev = bank
    advance_bank(V, Qr, P, L, Z, w_prev, sample, prm, model, work)


@njit(cache=True, fastmath=FASTMATH, **NO_ALLOCATION)
def advance_bank(V, Qr, P, L, Z, w_prev, sample, prm, model, work):
    """:func:`bank_step` on its scratch arrays ``work``, without reference counting (its phases
    are inlined: counting the arrays they take cost 5-10 % of the bank's time)."""
    g, m = prm.gravity, prm.mass
    gyr, acc, dt, update, baro = sample
    A, B, C = model
    n = V.shape[0]
    f, U, gb, F, T, PH, Wm, Wi, K, vbar, dx = work
    w = w_prev
    nx = NX if prm.baro_var > 0.0 else NX - 1  # the height's covariance only when read
    read = prm.baro_var > 0.0 and np.isfinite(baro)
    for i in range(n):
        v = V[i]
        Pi = P[i]
        # -- prior (eqs 22-25) and ż = ĝᵀ v ------------------------------------------------------
        gravity_body(Qr[i], g, gb)
        _aero(v, w, A, B, C, m, f, U)
        vbar[0] = v[0] + dt * (-(w[1] * v[2] - w[2] * v[1]) + f[0] + gb[0])
        vbar[1] = v[1] + dt * (-(w[2] * v[0] - w[0] * v[2]) + f[1] + gb[1])
        vbar[2] = v[2] + dt * (-(w[0] * v[1] - w[1] * v[0]) + f[2] + gb[2])
        Z[i] += dt * (gb[0] * v[0] + gb[1] * v[1] + gb[2] * v[2]) / g
        qexp_right(Qr[i], w[0] * dt, w[1] * dt, w[2] * dt)  # eq 23
        transition_matrix(F, U, w, v, gb, g, dt)
        predict_covariance(Pi, F, T, prm.q_vel, prm.q_att, dt, nx)
        v[0], v[1], v[2] = vbar[0], vbar[1], vbar[2]
        if update:
            L[i] += accelerometer_term(v, Qr[i], Pi, Z, i, (gyr, acc, nx), prm, model, work)
        if read:
            L[i] += barometer_term(v, Qr[i], Pi, Z, i, baro, prm.baro_var, dx)
    top = L[0]
    for i in range(1, n):
        if L[i] > top:
            top = L[i]
    for i in range(n):
        L[i] -= top
    w_prev[0], w_prev[1], w_prev[2] = gyr[0], gyr[1], gyr[2]


@njit(cache=True, inline="always")
def accelerometer_term(v, q, Pi, Z, i, reading, prm, model, work):
    """The posterior (eqs 26-30) of one hypothesis in place from its prior ``v``, ``q``, ``Pi``,
    ``Z[i]`` and the ``reading`` ``(gyr, acc, nx)`` (the first ``nx`` states updated); returns
    its log-likelihood term (eq 33 in the log domain)."""
    gyr, acc, nx = reading
    A, B, C = model
    f, U, gb, F, T, PH, Wm, Wi, K, vbar, dx = work
    _aero(v, gyr, A, B, C, prm.mass, f, U)
    r0, r1, r2 = acc[0] - f[0], acc[1] - f[1], acc[2] - f[2]
    # PHᵀ = P[:, 0:3] Uᵀ (H = [U, 0, 0])
    for r in range(nx):
        for c in range(3):
            PH[r, c] = Pi[r, 0] * U[c, 0] + Pi[r, 1] * U[c, 1] + Pi[r, 2] * U[c, 2]
    for r in range(3):
        for c in range(3):
            Wm[r, c] = U[r, 0] * PH[0, c] + U[r, 1] * PH[1, c] + U[r, 2] * PH[2, c]
        Wm[r, r] += prm.acc_var
    det = inverse_3x3(Wm, Wi)
    for r in range(nx):
        for c in range(3):
            K[r, c] = PH[r, 0] * Wi[0, c] + PH[r, 1] * Wi[1, c] + PH[r, 2] * Wi[2, c]
    for r in range(nx):
        dx[r] = K[r, 0] * r0 + K[r, 1] * r1 + K[r, 2] * r2
    v[0], v[1], v[2] = v[0] + dx[0], v[1] + dx[1], v[2] + dx[2]
    if nx == NX:
        Z[i] += dx[5]
    update_covariance(Pi, T, K, PH, nx)
    qexp_right(q, dx[3], dx[4], 0.0)  # eq 30; δ back to zero
    maha = mahalanobis_3(r0, r1, r2, Wi)
    return -0.5 * maha - 0.5 * (3.0 * LOG_2PI + np.log(det))


@njit(cache=True, fastmath=FASTMATH)
def summarize(Qr, L, g, prob, gdirs):
    """Probabilities (eq 31, normalised), each hypothesis's gravity direction in the body,
    the most likely index (eq 35) and the spherical variance S_g (eq 39)."""
    n = L.shape[0]
    s = 0.0
    best = 0
    for i in range(n):
        prob[i] = np.exp(L[i])
        s += prob[i]
        if L[i] > L[best]:
            best = i
    mx = my = mz = 0.0
    for i in range(n):
        prob[i] /= s
        gravity_body(Qr[i], 1.0, gdirs[i])
        mx += prob[i] * gdirs[i, 0]
        my += prob[i] * gdirs[i, 1]
        mz += prob[i] * gdirs[i, 2]
    return best, 1.0 - np.sqrt(mx * mx + my * my + mz * mz)
