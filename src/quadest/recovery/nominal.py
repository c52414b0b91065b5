"""The nominal estimator after the handover (the recovery paper's section V-B): one EKF of the
bank's kind (:mod:`quadest.recovery.bank`: body velocity, a two-component error rotation and
the height, the aerodynamic model, the accelerometer update) that always reads the barometer
(the bank only with ``bank_baro``), so that a reading corrects the velocity it integrates. The
paper's nominal estimator has a barometer too; without it the velocity's error (the aerodynamic
model's, fitted at the throw's rotor speed) goes uncorrected and a height loop that reads it
settles off its height.

State ``x = (v_b, δx, δy, z)``: the bank's, ``z`` the height (NED, m down). With ``ĝ`` the
gravity direction in the body (row 2 of ``R_nb``) and ``R_nb = R_ref (I + [δ]×)``:

    ż = e_zᵀ R_nb v_b = ĝᵀ v + δ · (v × ĝ)      so   ∂ż/∂v = ĝᵀ,  ∂ż/∂(δx, δy) = (v × ĝ)_{x, y}

and the transition matrix is the bank's, which carries the same height (no process noise on z:
its error comes from the velocity's). The accelerometer does not see z
(``H = [Υ/m, 0, 0]``). A barometer reading ``b`` (m up) is ``−z`` plus white noise of variance
``baro_var``: ``y = b + z``, ``H = [0 0 0 0 0 −1]``, ``S = P_zz + baro_var``,
``K = −P[:, z]/S``, ``P ← P − P[:, z] P[z, :]/S``. The estimator models neither the sensor's
lag nor its noise as the simulator draws them (:func:`quadest.flight.common.barometer_draws`):
``baro_var`` covers both.
"""

from __future__ import annotations

import numpy as np

from quadest._jit import njit
from quadest.recovery.bank import _aero, gravity_body, inverse_3x3, transition_matrix
from quadest.rotation.kernels import FASTMATH, qexp_right

NS = 6
"""The nominal EKF's state size: body velocity (3), error rotation (2), height (1)."""


@njit(cache=True, fastmath=FASTMATH)
def nominal_step(v, q, P, z, w_prev, sample, prm, model, baro, baro_var):
    """Advance the nominal EKF by one IMU sample, in place: ``v`` body velocity (3), ``q`` its
    ``q_nb`` (4), ``P`` (6, 6), ``z`` the height (1, NED); ``sample`` ``(gyr, acc, dt, update)``
    (``update=False``: the accelerometer update waits, the gate of section V-B); ``prm`` a
    :data:`~quadest.recovery.bank.BankRecord`; ``model`` ``(A, B, C)``; ``baro`` a barometer
    reading (m up; NaN: none this sample, or none fused when ``baro_var`` is 0)."""
    gyr, acc, dt, update = sample
    A, B, C = model
    g, m = prm.gravity, prm.mass
    f, U, gb = np.empty(3), np.empty((3, 3)), np.empty(3)
    F, T = np.empty((NS, NS)), np.empty((NS, NS))
    w = w_prev
    # -- prior: the bank's (eqs 22-25), and ż = ĝᵀ v ---------------------------------------------
    gravity_body(q, g, gb)
    _aero(v, w, A, B, C, m, f, U)
    transition_matrix(F, U, w, v, gb, g, dt)  # the bank's, height row included
    z[0] += dt * (gb[0] * v[0] + gb[1] * v[1] + gb[2] * v[2]) / g
    v0 = v[0] + dt * (-(w[1] * v[2] - w[2] * v[1]) + f[0] + gb[0])
    v1 = v[1] + dt * (-(w[2] * v[0] - w[0] * v[2]) + f[1] + gb[1])
    v2 = v[2] + dt * (-(w[0] * v[1] - w[1] * v[0]) + f[2] + gb[2])
    v[0], v[1], v[2] = v0, v1, v2
    qexp_right(q, w[0] * dt, w[1] * dt, w[2] * dt)  # eq 23
    # P̄ = F P Fᵀ + Q
    for r in range(NS):
        for c in range(NS):
            s = 0.0
            for k in range(NS):
                s += F[r, k] * P[k, c]
            T[r, c] = s
    for r in range(NS):
        for c in range(r, NS):
            s = 0.0
            for k in range(NS):
                s += T[r, k] * F[c, k]
            P[r, c] = s
            P[c, r] = s
    for r in range(3):
        P[r, r] += prm.q_vel * dt
    P[3, 3] += prm.q_att * dt
    P[4, 4] += prm.q_att * dt
    if update:
        accelerometer_update(v, q, P, z, gyr, acc, prm, model)
    if baro_var > 0.0 and np.isfinite(baro):
        barometer_update(v, q, P, z, baro, baro_var)
    w_prev[0], w_prev[1], w_prev[2] = gyr[0], gyr[1], gyr[2]


@njit(cache=True, fastmath=FASTMATH)
def accelerometer_update(v, q, P, z, gyr, acc, prm, model):
    """The bank's posterior (eqs 26-30) on the six states: ``r = z_acc − f_c(v̄, ω)/m``,
    ``H = [Υ/m, 0, 0]``, ``K = P Hᵀ W⁻¹``, the error rotation reset into ``q``."""
    A, B, C = model
    f, U = np.empty(3), np.empty((3, 3))
    PH, Wm, Wi, K, dx = np.empty((NS, 3)), np.empty((3, 3)), np.empty((3, 3)), np.empty((NS, 3)), np.empty(NS)
    _aero(v, gyr, A, B, C, prm.mass, f, U)
    r0, r1, r2 = acc[0] - f[0], acc[1] - f[1], acc[2] - f[2]
    for r in range(NS):  # P Hᵀ = P[:, 0:3] Uᵀ
        for c in range(3):
            PH[r, c] = P[r, 0] * U[c, 0] + P[r, 1] * U[c, 1] + P[r, 2] * U[c, 2]
    for r in range(3):  # W = H P Hᵀ + Σ_acc
        for c in range(3):
            Wm[r, c] = U[r, 0] * PH[0, c] + U[r, 1] * PH[1, c] + U[r, 2] * PH[2, c]
        Wm[r, r] += prm.acc_var
    inverse_3x3(Wm, Wi)
    for r in range(NS):
        for c in range(3):
            K[r, c] = PH[r, 0] * Wi[0, c] + PH[r, 1] * Wi[1, c] + PH[r, 2] * Wi[2, c]
        dx[r] = K[r, 0] * r0 + K[r, 1] * r1 + K[r, 2] * r2
    # P = P̄ − K (P Hᵀ)ᵀ, symmetrised
    T = np.empty((NS, NS))
    for r in range(NS):
        for c in range(NS):
            T[r, c] = P[r, c] - (K[r, 0] * PH[c, 0] + K[r, 1] * PH[c, 1] + K[r, 2] * PH[c, 2])
    for r in range(NS):
        for c in range(NS):
            P[r, c] = 0.5 * (T[r, c] + T[c, r])
    v[0], v[1], v[2] = v[0] + dx[0], v[1] + dx[1], v[2] + dx[2]
    z[0] += dx[5]
    qexp_right(q, dx[3], dx[4], 0.0)  # eq 30; δ back to zero


@njit(cache=True, fastmath=FASTMATH)
def barometer_update(v, q, P, z, baro, baro_var):
    """A barometer reading ``baro`` (m up) of the height ``−z``: ``y = baro + z``,
    ``S = P_zz + baro_var``, ``K = −P[:, z]/S``, ``P ← P − P[:, z] P[z, :]/S``."""
    y = baro + z[0]
    S = P[5, 5] + baro_var
    K = np.empty(NS)
    for r in range(NS):
        K[r] = -P[r, 5] / S
    for r in range(NS):
        for c in range(NS):
            P[r, c] += K[r] * P[5, c] if r <= c else 0.0
    for r in range(NS):
        for c in range(r):
            P[r, c] = P[c, r]
    v[0], v[1], v[2] = v[0] + K[0] * y, v[1] + K[1] * y, v[2] + K[2] * y
    z[0] += K[5] * y
    qexp_right(q, K[3] * y, K[4] * y, 0.0)  # the error rotation reset, as the bank's eq 30
