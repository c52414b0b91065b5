"""Roetenberg et al.'s Kalman filter with magnetic-disturbance compensation (AFCKF ref [21]).

D. Roetenberg, H. Luinge, C. Baten, P. Veltink, "Compensation of magnetic disturbances improves
inertial and magnetic sensing of human body segment orientation", IEEE TNSRE 13(3), 2005.

An error-state (complementary) Kalman filter: the gyroscope propagates the attitude; the filter
estimates the errors of the orientation (3, body frame), of the gyro bias (3) and of a magnetic
disturbance in the navigation frame (3), modelled as a first-order Gauss-Markov process
``d_k = c_d d_{k−1} + w`` with ``c_d = exp(−dt/τ_d)``. Accelerometer and magnetometer enter as
vector measurements: ``f = −g Rᵀ e_z + (acceleration, treated as noise)`` and
``m/|m_ref| = Rᵀ (m_ref + d) + noise`` with the unit reference field ``m_ref = [cos I, 0, sin I]``
in the magnetic NED frame, its norm and dip I measured on the first magnetometer sample (the dip
from the angle between the field and the accelerometer's down direction, so a wrong initial
attitude does not enter the reference). After each update the error is moved into the nominal state
(``q ← q ⊗ Exp(δθ)``, ``b ← b + δb``, ``d ← d + δd``).

Jacobians (checked against finite differences in the tests), right-multiplied error
``q_true = q ⊗ Exp(δθ)``:
``∂(−g Rᵀ e_z)/∂δθ = −g [Rᵀ e_z]×``, ``∂(Rᵀ u)/∂δθ = [Rᵀ u]×``, ``∂(Rᵀ u)/∂d = Rᵀ``;
propagation ``δθ⁺ = Exp(ω dt)ᵀ δθ − dt δb``.

The paper's numerical noise values are not reproduced here (its text is not among quadest's
sources); the defaults below are stated per sample for the ``bebop2`` sensors and are
documented as assumptions.
"""

from collections import namedtuple
from dataclasses import dataclass

import numpy as np

from quadest._jit import njit
from quadest.conventions import GRAVITY
from quadest.filters.base import Estimator, Params, coefficient_offsets, params_record
from quadest.filters.common import (
    BASE,
    admit,
    admitted_mag,
    finite3,
    layout,
    norm3,
    prepare,
    publish,
    run_and_stream,
)
from quadest.filters.linalg import inv_spd, mm, mm_t, mv
from quadest.records import param
from quadest.rotation.kernels import FASTMATH, qexp, qexp_right, rot_matrix, skew

STATE = layout(
    ("bias", 3),  # gyro bias, rad/s
    ("dist", 3),  # magnetic disturbance, navigation frame, in reference-field units
    ("ref", 3),  # unit reference field, navigation frame
    ("norm", 1),  # reference field norm in the magnetometer's unit (0: not yet set)
    ("P", 81),  # error covariance (orientation, bias, disturbance), row-major
    start=BASE,
)
IB, ID, IREF, INORM, IP = STATE.bias, STATE.dist, STATE.ref, STATE.norm, STATE.P


@dataclass(frozen=True)
class RoetenbergParams(Params):
    use_mag: bool = param(
        True, "-", "use the magnetometer when samples are present", "quadest: 9-axis when samples are present"
    )
    gyro_noise: float = param(
        0.01, "rad/s", "gyroscope white noise std per sample", "chosen: the bebop2 preset's gyro", bounds="(0, 10]"
    )
    bias_rw: float = param(
        2e-4, "rad/s/√s", "gyro bias random walk", "chosen: the bebop2 preset's gyro", bounds="[0, 1]"
    )
    acc_noise: float = param(
        0.3,
        "m/s²",
        "accelerometer white noise std per sample",
        "chosen: the bebop2 preset's accelerometer",
        bounds="(0, 100]",
    )
    lin_acc: float = param(
        3.0,
        "m/s²",
        "std of the unmodelled acceleration, added to the accelerometer noise",
        "chosen on simulator seed 11 (not a checked seed); Roetenberg's values are not among quadest's sources",
        bounds="[0, 100]",
    )
    mag_noise: float = param(
        0.02,
        "-",
        "magnetometer noise std, in units of the reference field",
        "chosen: about 1 µT of a 49 µT field",
        bounds="(0, 10]",
    )
    dist_std: float = param(
        0.02,
        "-",
        "steady-state std of the magnetic disturbance (reference-field units)",
        "chosen on simulator seed 11",
        bounds="[0, 10]",
    )
    dist_tau_s: float = param(
        0.2, "s", "correlation time τ_d of the magnetic disturbance", "chosen on simulator seed 11", bounds="[0, 1e6]"
    )
    gravity: float = param(GRAVITY, "m/s²", "gravity", "standard gravity", bounds="(0, 100]")
    p0_att: float = param(
        0.01,
        "rad²",
        "initial orientation error variance",
        "chosen: about 6° (the first sample's attitude is close)",
        bounds="(0, 10]",
    )
    p0_bias: float = param(
        1e-4,
        "(rad/s)²",
        "initial gyro bias variance",
        "chosen: 0.01 rad/s, a turn-on bias of a MEMS gyro",
        bounds="[0, 1]",
    )


PARAM = Record = params_record(RoetenbergParams)
Coefficients = namedtuple("Coefficients", ["r_acc", "r_mag"])
COEF = coefficient_offsets(Coefficients)


def coefficients(p: RoetenbergParams) -> Coefficients:
    """Measurement noise variances: accelerometer (white noise plus unmodelled acceleration)
    and magnetometer."""
    return Coefficients(r_acc=p.acc_noise * p.acc_noise + p.lin_acc * p.lin_acc, r_mag=p.mag_noise * p.mag_noise)


@njit(cache=True, fastmath=FASTMATH)
def _update(x, P, r, H, Rm, v_free, constrain):
    """Kalman update with residual r, Jacobian H (m x 9), noise Rm; injects the error.
    With ``constrain``, neither the orientation nor the gyro bias is corrected along the unit
    body vector ``v_free`` (the vertical); the Joseph form keeps P consistent for this
    constrained gain."""
    PHt = mm_t(P, H)
    S = mm(H, PHt) + Rm
    K = mm(PHt, inv_spd(S))
    if constrain:
        Pv = np.eye(3) - np.outer(v_free, v_free)
        K[0:3, :] = mm(Pv, K[0:3, :].copy())
        K[3:6, :] = mm(Pv, K[3:6, :].copy())
    dx = mv(K, r)
    IKH = np.eye(9) - mm(K, H)
    P[:, :] = mm_t(mm(IKH, P), IKH) + mm_t(mm(K, Rm), K)  # Joseph form: keeps P symmetric positive definite
    qexp_right(x[0:4], dx[0], dx[1], dx[2])
    x[IB : IB + 3] += dx[3:6]
    x[ID : ID + 3] += dx[6:9]
    return dx


@njit(cache=True, fastmath=FASTMATH)
def roetenberg_step(x, p, c, gyr, acc, mag, dt, diag):
    if not admit(x, gyr, acc, mag, dt):  # skipped and counted; the state stays as it was
        return
    mag = admitted_mag(x)  # NaN where its value was unusable (counted): the rest is used
    use_mag = p[PARAM.use_mag] != 0.0
    sg, sb, sd, tau, grav = (
        p[PARAM.gyro_noise],
        p[PARAM.bias_rw],
        p[PARAM.dist_std],
        p[PARAM.dist_tau_s],
        p[PARAM.gravity],
    )
    diag[0] = diag[4] = 0.0
    if not prepare(x, acc, mag, use_mag):
        return
    P = x[IP : IP + 81].copy().reshape((9, 9))
    # -- propagation ----------------------------------------------------------------------
    w = np.zeros(3)
    if finite3(gyr):
        w[:] = gyr - x[IB : IB + 3]
    else:
        w[:] = -x[IB : IB + 3]
    qexp_right(x[0:4], w[0] * dt, w[1] * dt, w[2] * dt)
    cd = np.exp(-dt / tau) if tau > 0 else 0.0
    x[ID : ID + 3] *= cd
    F = np.eye(9)
    F[0:3, 0:3] = rot_matrix(qexp(w * dt)).T
    F[0:3, 3:6] = -dt * np.eye(3)
    F[6:9, 6:9] = cd * np.eye(3)
    Q = np.zeros((9, 9))
    for i in range(3):
        Q[i, i] = (sg * dt) ** 2
        Q[3 + i, 3 + i] = sb * sb * dt
        Q[6 + i, 6 + i] = sd * sd * (1.0 - cd * cd)
    P = mm_t(mm(F, P), F) + Q
    # -- accelerometer: f = −g Rᵀ e_z ---------------------------------------------------------
    if finite3(acc) and norm3(acc) > 0.0:
        R = rot_matrix(x[0:4])
        v = R[2, :].copy()  # Rᵀ e_z
        r = acc + grav * v
        H = np.zeros((3, 9))
        H[:, 0:3] = -grav * skew(v)
        # quadest's extension for 6-axis use (docs/estimators.md): without a magnetometer the
        # heading and the bias about the vertical are unobservable, and the accelerometer must
        # not correct them through their correlation with tilt (it drove the heading away)
        _update(x, P, r, H, np.eye(3) * c[COEF.r_acc], v, not use_mag or x[INORM] == 0.0)
        diag[0] = 1.0
    # -- magnetometer: m/|m_ref| = Rᵀ (m_ref + d) ----------------------------------------------
    if use_mag and finite3(mag) and norm3(mag) > 0.0:
        if x[INORM] == 0.0:
            # reference field from the first sample: norm, and dip from the angle between the
            # field and the accelerometer's down direction, independent of the attitude estimate
            mn = norm3(mag)
            x[INORM] = mn
            an = norm3(acc) if finite3(acc) else 0.0
            if an > 0.0:
                s_dip = -(acc[0] * mag[0] + acc[1] * mag[1] + acc[2] * mag[2]) / (an * mn)
                s_dip = min(1.0, max(-1.0, s_dip))
                x[IREF], x[IREF + 1], x[IREF + 2] = np.sqrt(1.0 - s_dip * s_dip), 0.0, s_dip
            else:
                x[IREF : IREF + 3] = mv(rot_matrix(x[0:4]), mag / mn)
                x[IREF + 1] = 0.0  # magnetic frame: no east component
                x[IREF : IREF + 3] /= norm3(x[IREF : IREF + 3])
        else:
            R = rot_matrix(x[0:4])
            u = x[IREF : IREF + 3] + x[ID : ID + 3]
            h = mv(R.T.copy(), u)
            r = mag / x[INORM] - h
            H = np.zeros((3, 9))
            H[:, 0:3] = skew(h)
            H[:, 6:9] = R.T
            _update(x, P, r, H, np.eye(3) * c[COEF.r_mag], h, False)
            diag[4] = 1.0
    x[IP : IP + 81] = (0.5 * (P + P.T)).ravel()
    diag[1], diag[2], diag[3] = x[IB], x[IB + 1], x[IB + 2]
    diag[5] = norm3(x[ID : ID + 3])
    publish(x)


roetenberg_run, roetenberg_stream = run_and_stream(roetenberg_step, fastmath=FASTMATH)


class Roetenberg(Estimator):
    """Roetenberg's filter. Diagnostics: ``acc_update``, the bias ``bias_x/y/z`` (rad/s),
    ``mag_update`` and the disturbance magnitude ``disturbance`` (reference-field units)."""

    name = "roetenberg"
    Params = RoetenbergParams
    Record = Record
    coefficients = staticmethod(coefficients)
    state_size = STATE.end
    diag_names = ("acc_update", "bias_x", "bias_y", "bias_z", "mag_update", "disturbance")
    step = staticmethod(roetenberg_step)
    batch = staticmethod(roetenberg_run)
    stream = staticmethod(roetenberg_stream)

    def _init_state(self, x):
        p = self.params
        P0 = np.diag([p.p0_att] * 3 + [p.p0_bias] * 3 + [p.dist_std**2] * 3)
        x[IP : IP + 81] = P0.ravel()
