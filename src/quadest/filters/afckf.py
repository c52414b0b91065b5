"""Adaptive Fuzzy Complementary Kalman Filter (Solanki & de Visser, AIAA SciTech 2022), §III.

The attitude of a quadcopter that spins at ~15 rad/s after losing a rotor, from MARG sensors:

A. centrifugal compensation ``a_cor = (a − ω_z² [ω1, ω2, 0]) / g`` (eqs 13-15);
B. one gradient-descent step per sample from ``a_cor`` with adaptive step
   ``μ_t = β |q̇_ω| Δt`` (eqs 16-24);
C. an additive Kalman filter fusing the gyro prediction (process model eqs 25-31) with the
   gradient-descent attitude (measurement eq 32, noise eq 33); the measurement noise is switched
   off (R = ∞, prediction only) while |‖a_cor‖ − 1| > λ_a (eqs 35-38);
D. gyro bias by integral feedback (eqs 39-42);
E. a separate yaw channel: gyro yaw integration (eq 43), tilt-compensated magnetometer heading
   plus declination (eqs 44-45), a fuzzy complementary gain κ (eqs 46-51: two exponential
   memberships, minimum inference, centre-of-gravity defuzzification over four extreme-case
   gains) and an adaptive-window moving average (eqs 52-53) taken on the circle.
Roll and pitch come from the Kalman channel, yaw from the yaw channel.

Corrections of the printed equations (each pinned by a test):

- eq 23: the gradient step starts from the gyro prediction ``q_ω,t`` (eq 26), not from
  ``q_{t−1}``: ``q_∇,t = q_ω,t − μ_t ∇f/‖∇f‖`` with ``∇f`` evaluated at ``q_ω,t``. J_g cannot see
  rotations about gravity, so R of eq 33 is singular in that direction and the Kalman gain there
  is one; a measurement started from ``q_{t−1}`` would then undo the gyro's rotation about the
  vertical at every step, and a vehicle spinning at 15 rad/s would be estimated as not
  spinning, its tilt collapsing onto the accelerometer's body z. Eq 24's own argument (the step
  must keep up with the physical rate of change) describes a measurement of the attitude at t.
- eq 31: ``Q_t = Δt²/4 · Ξ(q) Σ_ω² Ξ(q)ᵀ`` with ``q ⊗ [0, e] = Ξ(q) e`` — the process noise
  ``e_q = ½ q ⊗ [0, e_ω] Δt`` of eq 30 has this covariance; the printed product of a quaternion, a
  diagonal matrix and a transposed quaternion is not a 4x4 covariance.
- eq 33: ``R_t = μ_t²/‖∇f‖² · J_gᵀ Σ_acc² J_g`` with ``Σ_acc`` in units of g (``a_cor`` is
  normalised by g, eq 15); J_g is the 3x4 Jacobian of eq 22.
- eq 38: the threshold on ``|ξ| = |‖a_cor‖ − 1|`` is ``λ_a = α ‖[1 1 1] Σ_a‖ / g``; the printed
  ``‖g/‖g‖‖ + …`` is the upper end of the spread of ‖a_cor‖ (eq 37), not a bound on ξ.
- eq 40: ``b_t = b_{t−1} − ρ (a_cor × v̂) Δt`` with ``v̂ = q* ⊗ ĝ ⊗ q`` the predicted gravity
  direction: the sign of Mahony's integral feedback (eq 48c of ref [12], which the paper follows).
  The printed ``+ρ Σ ω_e Δt`` together with eq 39 (``ω_cor = ω − b``) integrates the error the
  wrong way and drives the bias away.
- eq 44: tilt compensation ``m_h = Ry(θ) Rx(φ) m``: ``m_h,x = m_x cos θ + (m_y sin φ + m_z cos φ)
  sin θ``, ``m_h,y = m_y cos φ − m_z sin φ``; the printed form mixes sin/cos and has a stray ψ.
  Eq 45 in NED/FRD: ``ψ_m = atan2(−m_h,y, m_h,x) + ν``.
- eq 46 blends angles: ``ψ = ψ_ω + κ wrap(ψ_m − ψ_ω)``, on the circle.
- eq 50: ``ρ_|m| = |‖m_t‖ − ‖b_e‖|`` as the text defines it (the printed ``‖m_t − b_e‖`` would need
  the attitude); clipped at λ_m.
- eq 53: the window ``i = ι e^{−|ψ̇|}`` shrinks with the yaw rate, as the formula says (the text
  says it grows): averaging the last i headings lags by (i − 1)/2 samples times the rate, and
  e^{+|ψ̇|} would ask for millions of samples at 15 rad/s.

The gradient step and the Kalman channel work in the paper's z-up earth frame (eq 19:
``ĝ = [0, 0, 0, 1]``) on ``q' = q_F ⊗ q_nb``, as Madgwick's filter does (:mod:`.madgwick`).
The paper publishes no values for β, ρ, ϑ, κ_i, ι, α; quadest's defaults below are chosen from
the sensors' noise and the vehicle's rates and documented; none was fitted to the checked seeds.
"""

import math
from collections import namedtuple
from dataclasses import dataclass

import numpy as np

from quadest._jit import njit
from quadest.conventions import GRAVITY
from quadest.filters.base import Estimator, Params, coefficient_offsets, params_record
from quadest.filters.common import (
    BASE,
    YAW_PENDING,
    admit,
    admitted_mag,
    finite3,
    gravity_objective,
    layout,
    mag_heading,
    norm3,
    prepare,
    publish,
    q_to_euler,
    run_and_stream,
    wrap_angle,
)
from quadest.filters.linalg import inv_spd_into
from quadest.records import param
from quadest.rotation.kernels import FASTMATH, normalize_s, qdot_s

WMAX = 256  # longest averaging window of eq 53, samples
STATE = layout(
    ("q_up", 4),  # Kalman-channel quaternion q' (paper's z-up frame)
    ("P", 16),  # its covariance, row-major
    ("bias", 3),  # gyro bias, rad/s
    ("psi", 1),  # fused yaw (before the moving average), rad
    ("mag_ref", 1),  # local field norm ‖b_e‖ (0: from the first sample)
    ("started", 1),  # 1 once the channels are initialised
    ("head", 1),  # ring buffer position
    ("buf", 2 * WMAX),  # ring buffers of sin and cos of the fused yaw, WMAX values each
    start=BASE,
)
IQ, IP, IB, IPSI, IMREF, ISTART, IHEAD, IBUF = (
    STATE.q_up,
    STATE.P,
    STATE.bias,
    STATE.psi,
    STATE.mag_ref,
    STATE.started,
    STATE.head,
    STATE.buf,
)


@dataclass(frozen=True)
class AfckfParams(Params):
    use_mag: bool = param(True, "-", "use the magnetometer yaw channel", "quadest: 9-axis when samples are present")
    omega1: float = param(
        0.0,
        "m",
        "centrifugal constant ω1 of eq 13 (m/s² per (rad/s)²)",
        "calibration (eq 13): quadest calibrate centrifugal on a spinning segment",
    )
    omega2: float = param(0.0, "m", "centrifugal constant ω2 of eq 13", "calibration (eq 13)")
    beta: float = param(
        1.5,
        "-",
        "step scale β > 1 of eq 24",
        "chosen: eq 24 requires β > 1; the paper gives no value",
        bounds="(0, 100]",
    )
    gyro_std: float = param(0.01, "rad/s", "gyro noise σ_ω per sample (eq 27)", "bebop2 gyro noise", bounds="(0, 10]")
    acc_std: float = param(
        0.3, "m/s²", "accelerometer noise σ_acc per sample (eq 34)", "bebop2 accelerometer", bounds="(0, 100]"
    )
    alpha_a: float = param(3.0, "-", "spread multiple α of eqs 37-38", "chosen: 3σ", bounds="(0, 100]")
    omega_d: float = param(
        0.005,
        "rad/s²",
        "bias drift rate ω_d; ρ = √(3/4) ω_d (eq 42)",
        "chosen: slow MEMS bias drift; the paper gives no value",
        bounds="[0, 10]",
    )
    mag_std: float = param(
        0.5, "mag unit", "magnetometer noise σ_m per sample (eq 49)", "bebop2 magnetometer", bounds="(0, 1e9]"
    )
    alpha_m: float = param(3.0, "-", "spread multiple α of eq 49", "chosen: 3σ", bounds="(0, 100]")
    mag_norm: float = param(
        0.0,
        "mag unit",
        "local field norm ‖b_e‖ (0: the first sample's norm)",
        "quadest: measured on the first sample unless given",
        bounds="[0, 1e9]",
    )
    omega_sat: float = param(
        np.radians(1000.0), "rad/s", "gyro yaw-rate saturation ω_ψ,sat (eq 48)", "bebop2 gyro range", bounds="(0, 1e3]"
    )
    theta_m: float = param(
        10.0,
        "-",
        "membership curvature ϑ_m of eq 47",
        "chosen: a convex membership; the paper gives no value",
        bounds="(1, 1e6]",
    )
    theta_w: float = param(10.0, "-", "membership curvature ϑ_ω of eq 48", "chosen: as ϑ_m", bounds="(1, 1e6]")
    kappa_1: float = param(
        0.01,
        "-",
        "κ when the field is clean and the rate low (per magnetometer sample)",
        "chosen: trust the gyro's yaw, a slow magnetometer pull",
        bounds="[0, 1]",
    )
    kappa_2: float = param(
        0.2,
        "-",
        "κ when the field is clean and the gyro near saturation",
        "chosen: lean on the magnetometer when the gyro clips",
        bounds="[0, 1]",
    )
    kappa_3: float = param(
        0.001, "-", "κ when the field is disturbed and the rate low", "chosen: ten times less than κ₁", bounds="[0, 1]"
    )
    kappa_4: float = param(
        0.02,
        "-",
        "κ when the field is disturbed and the gyro near saturation",
        "chosen: ten times less than κ₂",
        bounds="[0, 1]",
    )
    iota: float = param(
        20.0,
        "samples",
        "window scale ι of eq 53 (at most 256)",
        "chosen: 40 ms of averaging at 500 Hz when not rotating",
        bounds="[1, 256]",
    )
    p0: float = param(
        1.0,
        "-",
        "initial covariance P0 = p0·I ('large', §III AEKF)",
        "chosen: large against a unit quaternion's components",
        bounds="(0, 1e6]",
    )
    gravity: float = param(GRAVITY, "m/s²", "|g| of eq 15", "standard gravity", bounds="(0, 100]")


PARAM = Record = params_record(AfckfParams)
Coefficients = namedtuple("Coefficients", ["lam_a", "sa_g", "rho", "lam_m"])
COEF = coefficient_offsets(Coefficients)


def coefficients(p: AfckfParams) -> Coefficients:
    """Constants of eqs 33, 38, 42 and 49, from the parameters."""
    return Coefficients(
        lam_a=p.alpha_a * math.sqrt(3.0) * p.acc_std / p.gravity,  # eq 38, corrected: λ_a
        sa_g=p.acc_std / p.gravity,  # eq 33: Σ_acc in units of g
        rho=math.sqrt(0.75) * p.omega_d,  # eq 42: ρ = √(3/4) ω_d
        lam_m=p.alpha_m * math.sqrt(3.0) * p.mag_std,  # eq 49: λ_m
    )


@njit(cache=True)
def _to_up(q):
    """q' = q_F ⊗ q_nb = [−x, w, −z, y] (NED -> the paper's z-up frame)."""
    out = np.empty(4)
    out[0], out[1], out[2], out[3] = -q[1], q[0], -q[3], q[2]
    return out


@njit(cache=True, inline="always")
def xi_rows(qw, qx, qy, qz):
    """The rows of ``Ξ(q)`` (4x3) with ``q ⊗ [0, e] = Ξ(q) e``."""
    return (-qx, -qy, -qz), (qw, -qz, qy), (qz, qw, -qx), (-qy, qx, qw)


@njit(cache=True, inline="always")
def add_process_noise(P, qw, qx, qy, qz, c):
    """Eq 31, corrected: ``P += c Ξ(q) Ξ(q)ᵀ`` (``c = Δt²/4 σ_ω²``) in place: the covariance of
    ``e_q = ½ q ⊗ [0, e_ω] Δt`` (eq 30)."""
    X = xi_rows(qw, qx, qy, qz)
    for i in range(4):
        for j in range(4):
            P[i, j] += c * (X[i][0] * X[j][0] + X[i][1] * X[j][1] + X[i][2] * X[j][2])


@njit(cache=True, inline="always")
def membership(v, vmax, theta):
    """Eqs 47-48: ``y = (e^{ln(ϑ) v/v_max} − 1)/(ϑ − 1)`` for v in [0, v_max]."""
    v = min(max(v, 0.0), vmax)
    if vmax <= 0.0:
        return 1.0
    return (np.exp(np.log(theta) * v / vmax) - 1.0) / (theta - 1.0)


@njit(cache=True, inline="always")
def fuzzy_gain(rho, lam_m, w_abs, w_sat, th_m, th_w, k1, k2, k3, k4):
    """Eqs 47-51: minimum inference over the four extreme cases, centre-of-gravity output."""
    ym = membership(rho, lam_m, th_m)  # "field disturbed"
    yw = membership(w_abs, w_sat, th_w)  # "gyro near saturation"
    w1 = min(1.0 - ym, 1.0 - yw)
    w2 = min(1.0 - ym, yw)
    w3 = min(ym, 1.0 - yw)
    w4 = min(ym, yw)
    s = w1 + w2 + w3 + w4
    return (w1 * k1 + w2 * k2 + w3 * k3 + w4 * k4) / s


@njit(cache=True, inline="always")
def start_channels(x, p):
    """The channels start from the initial attitude (or the heading just set by the
    magnetometer): the Kalman channel's q' and P, the yaw and its averaging buffer."""
    x[IQ : IQ + 4] = _to_up(x[0:4])
    P0 = np.eye(4) * p[PARAM.p0]
    x[IP : IP + 16] = P0.ravel()
    x[IPSI] = q_to_euler(x[0:4])[2]
    s0, c0 = np.sin(x[IPSI]), np.cos(x[IPSI])
    for i in range(WMAX):
        x[IBUF + i] = s0
        x[IBUF + WMAX + i] = c0
    x[ISTART] = 1.0


@njit(cache=True, inline="always")
def kalman_update(P, J0, J1, J2, cr, q, e):
    """Eq 33, corrected: ``M = P⁻ + R`` with ``R = cr J_gᵀ J_g``; ``K = P⁻ M⁻¹``, the attitude
    ``q + K e`` (``e`` the innovation ``q_∇ − q_ω``) and ``P = (I − K) P⁻`` in place."""
    W = np.empty(48)  # scratch: M, its inverse, K
    M = W[0:16].reshape((4, 4))
    for i in range(4):
        for j in range(4):
            M[i, j] = P[i, j] + cr * (J0[i] * J0[j] + J1[i] * J1[j] + J2[i] * J2[j])
    Minv = W[16:32].reshape((4, 4))
    inv_spd_into(M, Minv)
    K = W[32:48].reshape((4, 4))  # K = P⁻ M⁻¹
    for i in range(4):
        for j in range(4):
            K[i, j] = P[i, 0] * Minv[0, j] + P[i, 1] * Minv[1, j] + P[i, 2] * Minv[2, j] + P[i, 3] * Minv[3, j]
    e0, e1, e2, e3 = e
    nw = q[0] + K[0, 0] * e0 + K[0, 1] * e1 + K[0, 2] * e2 + K[0, 3] * e3
    nx = q[1] + K[1, 0] * e0 + K[1, 1] * e1 + K[1, 2] * e2 + K[1, 3] * e3
    ny = q[2] + K[2, 0] * e0 + K[2, 1] * e1 + K[2, 2] * e2 + K[2, 3] * e3
    nz = q[3] + K[3, 0] * e0 + K[3, 1] * e1 + K[3, 2] * e2 + K[3, 3] * e3
    # P = (I − K) P⁻, in place through M as a copy of P⁻
    for i in range(4):
        for j in range(4):
            M[i, j] = P[i, j]
    for i in range(4):
        for j in range(4):
            P[i, j] = M[i, j] - (K[i, 0] * M[0, j] + K[i, 1] * M[1, j] + K[i, 2] * M[2, j] + K[i, 3] * M[3, j])
    return nw, nx, ny, nz


@njit(cache=True, inline="always")
def accelerometer_update(x, P, p, c, acc, q, w2, qdot_norm, dt):
    """A-D: the centrifugally compensated accelerometer (eqs 13-15), one gradient step from the
    gyro prediction ``q`` (eqs 21-24), fused when ``|ξ| ≤ λ_a`` (eqs 33, 36, 38), and the bias
    by integral feedback (eqs 40-42). Returns the attitude, μ and whether R was off (1.0)."""
    pw, px, py, pz = q
    mu = 0.0
    an = norm3(acc) if finite3(acc) else 0.0
    if an <= 0.0:
        return pw, px, py, pz, mu, 1.0
    grav, om1, om2 = p[PARAM.gravity], p[PARAM.omega1], p[PARAM.omega2]
    # A. eqs 13-15: centrifugal compensation about body z, normalised by g
    wz2 = w2 * w2
    a0 = (acc[0] - wz2 * om1) / grav
    a1 = (acc[1] - wz2 * om2) / grav
    a2 = acc[2] / grav
    xi_a = np.sqrt(a0 * a0 + a1 * a1 + a2 * a2) - 1.0  # eq 36
    # B. eqs 21-24: one gradient-descent step, from the gyro prediction q_ω,t (eq 23
    # corrected, see the module doc); f_g of eq 21 and J_g of eq 22 at q_ω
    f0, f1, f2, J0, J1, J2 = gravity_objective(pw, px, py, pz, a0, a1, a2)
    g0 = J0[0] * f0 + J1[0] * f1 + J2[0] * f2
    g1 = J0[1] * f0 + J1[1] * f1 + J2[1] * f2
    g2 = J0[2] * f0 + J1[2] * f1 + J2[2] * f2
    g3 = J0[3] * f0 + J1[3] * f1 + J2[3] * f2
    gn = np.sqrt(g0 * g0 + g1 * g1 + g2 * g2 + g3 * g3)
    mu = p[PARAM.beta] * qdot_norm * dt  # eq 24
    if not (abs(xi_a) <= c[COEF.lam_a] and gn > 0.0 and mu > 0.0):  # eq 38, corrected
        return pw, px, py, pz, mu, 1.0
    # eq 33, corrected: R = μ²/‖∇f‖² J_gᵀ (Σ_acc/g)² J_g; the innovation −μ ∇f/‖∇f‖ (eq 23)
    sa_g = c[COEF.sa_g]
    s_ = -mu / gn
    nw, nx, ny, nz = kalman_update(
        P, J0, J1, J2, mu * mu / (gn * gn) * sa_g * sa_g, (pw, px, py, pz), (s_ * g0, s_ * g1, s_ * g2, s_ * g3)
    )
    # D. eqs 40-42: bias by integral feedback (sign corrected), from the measured and
    # predicted up directions a_cor and v̂ = Rᵀ ĝ (v̂ = f_g + a_cor)
    rho = c[COEF.rho]
    vx, vy, vz = f0 + a0, f1 + a1, f2 + a2
    x[IB] -= rho * (a1 * vz - a2 * vy) * dt
    x[IB + 1] -= rho * (a2 * vx - a0 * vz) * dt
    x[IB + 2] -= rho * (a0 * vy - a1 * vx) * dt
    return nw, nx, ny, nz, mu, 0.0


@njit(cache=True, inline="always")
def symmetrize(P):
    for i in range(4):
        for j in range(i + 1, 4):
            v = 0.5 * (P[i, j] + P[j, i])
            P[i, j] = v
            P[j, i] = v


@njit(cache=True, inline="always")
def yaw_channel(x, p, c, gyr, mag, use_mag, b, w1, w2, dt):
    """E. eq 43: gyro yaw integration with the ZYX Euler rate ``ψ̇ = (ω_y sin φ + ω_z cos φ)/cos θ
    = (R21 ω_y + R22 ω_z)/(1 − R20²)`` from the Kalman channel's ``q_nb`` ``b`` (R20 = −sin θ,
    R21 = sin φ cos θ, R22 = cos φ cos θ: no trigonometry per sample), blended with the
    magnetometer's heading by the fuzzy gain (eqs 44-51). Returns ψ, ψ̇ and κ."""
    bw, bx, by, bz = b
    r20 = 2.0 * (bx * bz - bw * by)
    r21 = 2.0 * (by * bz + bw * bx)
    r22 = 1.0 - 2.0 * (bx * bx + by * by)
    c2 = max(1.0 - r20 * r20, 1e-12)
    psi_dot = (r21 * w1 + r22 * w2) / c2
    psi = x[IPSI] + psi_dot * dt
    kappa = 0.0
    if use_mag and finite3(mag) and norm3(mag) > 0.0:
        mn = norm3(mag)
        if x[IMREF] == 0.0:
            x[IMREF] = p[PARAM.mag_norm] if p[PARAM.mag_norm] > 0.0 else mn
        lam_m = c[COEF.lam_m]  # eq 49
        rho_m = min(abs(mn - x[IMREF]), lam_m)  # eq 50 (text's definition)
        w_abs = min(abs(gyr[2]) if finite3(gyr) else 0.0, p[PARAM.omega_sat])
        kappa = fuzzy_gain(
            rho_m,
            lam_m,
            w_abs,
            p[PARAM.omega_sat],
            p[PARAM.theta_m],
            p[PARAM.theta_w],
            p[PARAM.kappa_1],
            p[PARAM.kappa_2],
            p[PARAM.kappa_3],
            p[PARAM.kappa_4],
        )
        roll = np.arctan2(r21, r22)
        pitch = np.arcsin(min(1.0, max(-1.0, -r20)))
        psi_m = mag_heading(mag, roll, pitch)  # eqs 44-45, corrected (ν: declination of the run)
        psi = psi + kappa * wrap_angle(psi_m - psi)  # eq 46 on the circle
    return wrap_angle(psi), psi_dot, kappa


@njit(cache=True, inline="always")
def averaged_heading(x, p, psi, psi_dot):
    """Eqs 52-53: ``psi`` into the buffer, the mean of the last ``ι e^{−|ψ̇|}`` headings on the
    circle. Returns it and the window."""
    head = int(x[IHEAD])
    x[IBUF + head] = np.sin(psi)
    x[IBUF + WMAX + head] = np.cos(psi)
    x[IHEAD] = (head + 1) % WMAX
    win = int(round(min(p[PARAM.iota], WMAX) * np.exp(-abs(psi_dot))))
    win = max(1, min(win, WMAX))
    ss = 0.0
    cs = 0.0
    for j in range(win):
        k = (head - j) % WMAX
        ss += x[IBUF + k]
        cs += x[IBUF + WMAX + k]
    return np.arctan2(ss, cs), win


@njit(cache=True, fastmath=FASTMATH)
def afckf_step(x, p, c, gyr, acc, mag, dt, diag):
    if not admit(x, gyr, acc, mag, dt):  # skipped and counted; the state stays as it was
        return
    mag = admitted_mag(x)  # NaN where its value was unusable (counted): the rest is used
    for i in range(7):
        diag[i] = 0.0
    pending = x[YAW_PENDING] != 0.0
    if not prepare(x, acc, mag, p[PARAM.use_mag] != 0.0):
        return
    if x[ISTART] == 0.0 or (pending and x[YAW_PENDING] == 0.0):
        start_channels(x, p)
    # the Kalman channel works in place on the state: P is a view of x
    P = x[IP : IP + 16].reshape((4, 4))
    qw, qx, qy, qz = x[IQ], x[IQ + 1], x[IQ + 2], x[IQ + 3]
    # D. eq 39: ω_cor = ω − b
    if finite3(gyr):
        w0, w1, w2 = gyr[0] - x[IB], gyr[1] - x[IB + 1], gyr[2] - x[IB + 2]
    else:
        w0, w1, w2 = 0.0, 0.0, 0.0
    # C. eqs 25-26: q̇_ω = ½ q ⊗ [0, ω], q_ω = q + q̇_ω Δt (normalised)
    d0, d1, d2, d3 = qdot_s(qw, qx, qy, qz, w0, w1, w2)
    qdot_norm = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2 + d3 * d3)
    q_w = normalize_s(qw + d0 * dt, qx + d1 * dt, qy + d2 * dt, qz + d3 * dt)
    # eq 31, corrected: P⁻ = P + Δt²/4 σ² Ξ(q) Ξ(q)ᵀ (Φ = Λ = I)
    sg = p[PARAM.gyro_std]
    add_process_noise(P, qw, qx, qy, qz, dt * dt / 4.0 * sg * sg)
    nw, nx, ny, nz, mu, r_off = accelerometer_update(x, P, p, c, acc, q_w, w2, qdot_norm, dt)
    symmetrize(P)
    nq = np.sqrt(nw * nw + nx * nx + ny * ny + nz * nz)
    nw, nx, ny, nz = nw / nq, nx / nq, ny / nq, nz / nq
    x[IQ], x[IQ + 1], x[IQ + 2], x[IQ + 3] = nw, nx, ny, nz
    # the Kalman channel's q_nb = q_F* ⊗ q' = [q'x, −q'w, q'z, −q'y]; its roll and pitch are the estimate's
    bw, bx, by, bz = nx, -nw, nz, -ny
    psi, psi_dot, kappa = yaw_channel(x, p, c, gyr, mag, p[PARAM.use_mag] != 0.0, (bw, bx, by, bz), w1, w2, dt)
    x[IPSI] = psi
    yaw, win = averaged_heading(x, p, psi, psi_dot)
    # output: roll and pitch of the Kalman channel, yaw of the yaw channel — the Kalman
    # channel's q_nb turned about the vertical by (yaw − its own yaw)
    yaw_kf = np.arctan2(2.0 * (bx * by + bw * bz), 1.0 - 2.0 * (by * by + bz * bz))
    h = 0.5 * wrap_angle(yaw - yaw_kf)
    ch, sh = np.cos(h), np.sin(h)
    x[0], x[1], x[2], x[3] = ch * bw - sh * bz, ch * bx - sh * by, ch * by + sh * bx, ch * bz + sh * bw
    diag[0], diag[1], diag[2], diag[3] = kappa, mu, r_off, float(win)
    diag[4], diag[5], diag[6] = x[IB], x[IB + 1], x[IB + 2]
    publish(x)


afckf_run, afckf_stream = run_and_stream(afckf_step)


class Afckf(Estimator):
    """The AFCKF. Diagnostics per sample: the fuzzy gain ``kappa``, the step ``mu``,
    ``r_off`` (1 when the measurement noise was switched off), the averaging ``window`` and the
    bias estimate ``bias_x/y/z`` (rad/s)."""

    name = "afckf"
    Params = AfckfParams
    Record = Record
    coefficients = staticmethod(coefficients)
    state_size = STATE.end
    diag_names = ("kappa", "mu", "r_off", "window", "bias_x", "bias_y", "bias_z")
    step = staticmethod(afckf_step)
    batch = staticmethod(afckf_run)
    stream = staticmethod(afckf_stream)
