"""Mahony's explicit complementary filter with integral gyro-bias feedback.

R. Mahony, T. Hamel, J.-M. Pflimlin, "Nonlinear complementary filters on the special orthogonal
group", IEEE TAC 53(5), 2008 (AFCKF ref [12]), eqs 32 and 48:

    ω_mes = Σ_i v_i × v̂_i,   ḃ = −k_I ω_mes,   q̇ = ½ q ⊗ [0, ω − b + k_P ω_mes]

with the measured directions ``v_i`` (normalised accelerometer, normalised magnetometer) and
their predictions ``v̂_i`` from the estimate. On quadest's NED frame the accelerometer's
prediction is the up direction ``−Rᵀ e_z``; the magnetic prediction is ``Rᵀ [|h_xy|, 0, h_z]``
with ``h = R m``. ahrs's Mahony builds the same predictions in ENU (its magnetic reference has
north along y), so its output equals ours after ``q_ned = q_T ⊗ q_enu`` (tested to 1e-9).
"""

from dataclasses import dataclass

import numpy as np

from quadest._jit import njit
from quadest.filters.base import Estimator, Params, params_record
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
from quadest.records import param
from quadest.rotation.kernels import normalize_s, qdot_s, rotate_inv_s, rotate_s

STATE = layout(("bias", 3), start=BASE)  # gyro bias estimate
BIAS = STATE.bias


@dataclass(frozen=True)
class MahonyParams(Params):
    use_mag: bool = param(
        True, "-", "use the magnetometer when samples are present", "quadest: 9-axis when samples are present"
    )
    k_p: float = param(
        1.0, "rad/s", "proportional gain k_P", "Mahony et al. 2008, experiments (k_P = 1)", bounds="[0, 1e3]"
    )
    k_i: float = param(
        0.3,
        "rad/s²",
        "integral gain k_I of the bias feedback",
        "Mahony et al. 2008, experiments (k_I = 0.3)",
        bounds="[0, 1e3]",
    )


PARAM = Record = params_record(MahonyParams)


@njit(cache=True)
def mahony_step(x, p, c, gyr, acc, mag, dt, diag):
    if not admit(x, gyr, acc, mag, dt):  # skipped and counted; the state stays as it was
        return
    mag = admitted_mag(x)  # NaN where its value was unusable (counted): the rest is used
    use_mag = p[PARAM.use_mag] != 0.0
    kp, ki = p[PARAM.k_p], p[PARAM.k_i]
    diag[0], diag[1], diag[2], diag[3] = x[BIAS], x[BIAS + 1], x[BIAS + 2], 0.0
    if not prepare(x, acc, mag, use_mag):
        return
    qw, qx, qy, qz = x[0], x[1], x[2], x[3]
    e0 = e1 = e2 = 0.0
    an = norm3(acc) if finite3(acc) else 0.0
    if an > 0.0:
        ax, ay, az = acc[0] / an, acc[1] / an, acc[2] / an
        # predicted up direction in the body: −Rᵀ e_z
        vx, vy, vz = rotate_inv_s(qw, qx, qy, qz, 0.0, 0.0, -1.0)
        e0 += ay * vz - az * vy
        e1 += az * vx - ax * vz
        e2 += ax * vy - ay * vx
        diag[3] = 1.0
        mn = norm3(mag) if (use_mag and finite3(mag)) else 0.0
        if mn > 0.0:
            mx, my, mz = mag[0] / mn, mag[1] / mn, mag[2] / mn
            hx, hy, hz = rotate_s(qw, qx, qy, qz, mx, my, mz)
            bx = np.sqrt(hx * hx + hy * hy)
            # v̂_m = Rᵀ [bx, 0, hz], normalised
            wx, wy, wz = rotate_inv_s(qw, qx, qy, qz, bx, 0.0, hz)
            wn = np.sqrt(wx * wx + wy * wy + wz * wz)
            if wn > 0.0:
                wx, wy, wz = wx / wn, wy / wn, wz / wn
                e0 += my * wz - mz * wy
                e1 += mz * wx - mx * wz
                e2 += mx * wy - my * wx
                diag[3] = 2.0
        # eq 48c: ḃ = −k_I ω_mes
        x[BIAS] -= ki * e0 * dt
        x[BIAS + 1] -= ki * e1 * dt
        x[BIAS + 2] -= ki * e2 * dt
    g0, g1, g2 = (gyr[0], gyr[1], gyr[2]) if finite3(gyr) else (0.0, 0.0, 0.0)
    # eq 48b: ω − b + k_P ω_mes
    w0 = g0 - x[BIAS] + kp * e0
    w1 = g1 - x[BIAS + 1] + kp * e1
    w2 = g2 - x[BIAS + 2] + kp * e2
    d0, d1, d2, d3 = qdot_s(qw, qx, qy, qz, w0, w1, w2)
    x[0], x[1], x[2], x[3] = normalize_s(qw + dt * d0, qx + dt * d1, qy + dt * d2, qz + dt * d3)
    diag[0], diag[1], diag[2] = x[BIAS], x[BIAS + 1], x[BIAS + 2]
    publish(x)


mahony_run, mahony_stream = run_and_stream(mahony_step)


class Mahony(Estimator):
    """Mahony's explicit complementary filter. Diagnostics: the bias estimate ``bias_x/y/z``
    (rad/s) and ``correction`` (0 none, 1 accelerometer, 2 with magnetometer)."""

    name = "mahony"
    Params = MahonyParams
    Record = Record
    state_size = STATE.end
    diag_names = ("bias_x", "bias_y", "bias_z", "correction")
    step = staticmethod(mahony_step)
    batch = staticmethod(mahony_run)
    stream = staticmethod(mahony_stream)
