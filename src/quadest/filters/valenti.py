"""Valenti, Dryanovski & Xiao's quaternion complementary filter (AFCKF ref [20]).

R. G. Valenti, I. Dryanovski, J. Xiao, "Keeping a good attitude: a quaternion-based orientation
filter for IMUs and MARGs", Sensors 15(8), 2015.

Prediction by the gyroscope (eq 42), then two algebraic corrections applied as small
rotations of the navigation frame: the accelerometer's delta quaternion (eq 47) rotates the
predicted gravity onto the vertical, the magnetometer's (eq 58) rotates the predicted horizontal
field onto north; each is scaled by LERP/SLERP against the identity (eqs 50-52, threshold
0.9) with the gains α (accelerometer) and β (magnetometer). The accelerometer gain adapts to the
acceleration magnitude error ``e_m = |‖a‖ − g|/g`` (eq 60): unchanged below ``t1``, falling
linearly to zero at ``t2``. The gyro bias is estimated while the sensor is in steady state
(section 5.1), as in the authors' reference implementation.

quadest's form: the paper writes ``q = ^L_G q`` (global to local, ``q̇ = −½ ω ⊗ q``); we carry
its conjugate ``q_nb`` and apply the delta quaternions as ``q_nb ← Δq* ⊗ q_nb``. In NED the
normalised, negated accelerometer points along +z (down), which is the paper's "gravity along
+z" in a z-down frame. ahrs's AQUA (the paper's Python implementation) gives the same attitude in
NWU (``q_nwu = q_F ⊗ q_ned``, tested); ahrs has no bias estimation and uses g = 9.809196 in its
adaptive gain.
"""

from dataclasses import dataclass

import numpy as np

from quadest._jit import njit
from quadest.conventions import GRAVITY
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
from quadest.rotation.kernels import normalize_s, qdot_s, rotate_s

STATE = layout(("bias", 3), ("gyr_prev", 3), ("have_prev", 1), start=BASE)
BIAS, GP, HP = STATE.bias, STATE.gyr_prev, STATE.have_prev


@dataclass(frozen=True)
class ValentiParams(Params):
    use_mag: bool = param(
        True, "-", "use the magnetometer when samples are present", "quadest: 9-axis when samples are present"
    )
    gain_acc: float = param(
        0.01,
        "-",
        "accelerometer gain α (static)",
        "Valenti et al. 2015; authors' ROS implementation default",
        bounds="[0, 1]",
    )
    gain_mag: float = param(0.01, "-", "magnetometer gain β", "Valenti et al. 2015; ROS default", bounds="[0, 1]")
    adaptive: bool = param(True, "-", "adapt α to the acceleration magnitude error (eq 60)", "ROS default")
    t1: float = param(
        0.1, "-", "magnitude error below which α is unchanged", "Valenti et al. 2015, section 5.2", bounds="[0, 10]"
    )
    t2: float = param(
        0.2, "-", "magnitude error at which α reaches zero", "Valenti et al. 2015, section 5.2", bounds="(0, 10]"
    )
    threshold: float = param(
        0.9, "-", "LERP above this scalar part, SLERP below (eq 50-52)", "Valenti et al. 2015", bounds="[0, 1]"
    )
    bias_estimation: bool = param(True, "-", "estimate the gyro bias in steady state", "ROS default")
    bias_alpha: float = param(0.01, "-", "low-pass gain of the bias estimate", "ROS default", bounds="[0, 1]")
    steady_acc: float = param(
        0.1, "m/s²", "steady state: |‖a‖ − g| below this", "ROS implementation", bounds="[0, 100]"
    )
    steady_rate: float = param(
        0.2, "rad/s", "steady state: |ω − b| below this per axis", "ROS implementation", bounds="[0, 100]"
    )
    steady_delta: float = param(
        0.01, "rad/s", "steady state: change of ω below this per axis", "ROS implementation", bounds="[0, 100]"
    )
    gravity: float = param(
        GRAVITY, "m/s²", "gravity used for the magnitude error", "standard gravity", bounds="(0, 100]"
    )


PARAM = Record = params_record(ValentiParams)


@njit(cache=True)
def _scaled_delta(d0, d1, d2, d3, gain, threshold):
    """LERP (eq 50) or SLERP (eq 52) between identity and ``d`` by ``gain``, normalised."""
    if d0 > threshold:
        s0, s1, s2, s3 = (1.0 - gain) + gain * d0, gain * d1, gain * d2, gain * d3
    else:
        ang = np.arccos(d0)
        sn = np.sin(ang)
        a, b = np.sin((1.0 - gain) * ang) / sn, np.sin(gain * ang) / sn
        s0, s1, s2, s3 = a + b * d0, b * d1, b * d2, b * d3
    n = np.sqrt(s0 * s0 + s1 * s1 + s2 * s2 + s3 * s3)
    return s0 / n, s1 / n, s2 / n, s3 / n


@njit(cache=True)
def _conj_mul(d0, d1, d2, d3, q0, q1, q2, q3):
    """``d* ⊗ q``."""
    w, a, b, c = d0, -d1, -d2, -d3
    return (
        w * q0 - a * q1 - b * q2 - c * q3,
        w * q1 + a * q0 + b * q3 - c * q2,
        w * q2 - a * q3 + b * q0 + c * q1,
        w * q3 + a * q2 - b * q1 + c * q0,
    )


@njit(cache=True)
def valenti_step(x, p, c, gyr, acc, mag, dt, diag):
    if not admit(x, gyr, acc, mag, dt):  # skipped and counted; the state stays as it was
        return
    mag = admitted_mag(x)  # NaN where its value was unusable (counted): the rest is used
    use_mag = p[PARAM.use_mag] != 0.0
    g_acc, g_mag, adaptive = p[PARAM.gain_acc], p[PARAM.gain_mag], p[PARAM.adaptive] != 0.0
    t1, t2, thr = p[PARAM.t1], p[PARAM.t2], p[PARAM.threshold]
    bias_on, b_alpha, s_acc = p[PARAM.bias_estimation] != 0.0, p[PARAM.bias_alpha], p[PARAM.steady_acc]
    s_rate, s_delta, grav = p[PARAM.steady_rate], p[PARAM.steady_delta], p[PARAM.gravity]
    diag[0], diag[1], diag[2], diag[3] = 0.0, x[BIAS], x[BIAS + 1], x[BIAS + 2]
    if not prepare(x, acc, mag, use_mag):
        return
    gyr_ok = finite3(gyr)
    an = norm3(acc) if finite3(acc) else 0.0
    # steady-state gyro bias estimate (section 5.1)
    if bias_on and gyr_ok and an > 0.0:
        steady = abs(an - grav) < s_acc and x[HP] > 0.0
        if steady:
            for i in range(3):
                if abs(gyr[i] - x[GP + i]) > s_delta or abs(gyr[i] - x[BIAS + i]) > s_rate:
                    steady = False
        if steady:
            for i in range(3):
                x[BIAS + i] += b_alpha * (gyr[i] - x[BIAS + i])
    if gyr_ok:
        for i in range(3):
            x[GP + i] = gyr[i]
        x[HP] = 1.0
    qw, qx, qy, qz = x[0], x[1], x[2], x[3]
    # eq 42: prediction, q_nb + ½ q_nb ⊗ [0, ω − b] Δt
    if gyr_ok:
        w0, w1, w2 = gyr[0] - x[BIAS], gyr[1] - x[BIAS + 1], gyr[2] - x[BIAS + 2]
        d0, d1, d2, d3 = qdot_s(qw, qx, qy, qz, w0, w1, w2)
        qw, qx, qy, qz = normalize_s(qw + dt * d0, qx + dt * d1, qy + dt * d2, qz + dt * d3)
    if an > 0.0:
        # eq 44: predicted gravity direction (down, NED) from the negated accelerometer
        gx, gy, gz = rotate_s(qw, qx, qy, qz, -acc[0] / an, -acc[1] / an, -acc[2] / an)
        if gz > -1.0 + 1e-12:
            s = np.sqrt(2.0 * (gz + 1.0))
            alpha = g_acc
            if adaptive:  # eq 60
                em = abs(an - grav) / grav
                f = 1.0 if em <= t1 else (0.0 if em >= t2 else (t2 - em) / (t2 - t1))
                alpha = g_acc * f
            diag[0] = alpha
            # eq 47, scaled (eqs 50-52), applied as Δq* ⊗ q_nb
            d0, d1, d2, d3 = _scaled_delta(np.sqrt((gz + 1.0) / 2.0), -gy / s, gx / s, 0.0, alpha, thr)
            qw, qx, qy, qz = _conj_mul(d0, d1, d2, d3, qw, qx, qy, qz)
        mn = norm3(mag) if (use_mag and finite3(mag)) else 0.0
        if mn > 0.0:
            lx, ly, _ = rotate_s(qw, qx, qy, qz, mag[0] / mn, mag[1] / mn, mag[2] / mn)  # eq 54
            G = lx * lx + ly * ly  # eq 28
            if G > 0.0:
                r = np.sqrt(G + lx * np.sqrt(G))
                if r > 1e-12:
                    m0, m3 = r / np.sqrt(2.0 * G), ly / (np.sqrt(2.0) * r)  # eq 58
                else:  # field pointing exactly south: a half turn about z
                    m0, m3 = 0.0, 1.0
                d0, d1, d2, d3 = _scaled_delta(m0, 0.0, 0.0, m3, g_mag, thr)
                qw, qx, qy, qz = _conj_mul(d0, d1, d2, d3, qw, qx, qy, qz)
    x[0], x[1], x[2], x[3] = normalize_s(qw, qx, qy, qz)
    diag[1], diag[2], diag[3] = x[BIAS], x[BIAS + 1], x[BIAS + 2]
    publish(x)


valenti_run, valenti_stream = run_and_stream(valenti_step)


class Valenti(Estimator):
    """Valenti's complementary filter. Diagnostics: the accelerometer gain used (``alpha``, 0
    when no correction) and the bias estimate ``bias_x/y/z`` (rad/s)."""

    name = "valenti"
    Params = ValentiParams
    Record = Record
    state_size = STATE.end
    diag_names = ("alpha", "bias_x", "bias_y", "bias_z")
    step = staticmethod(valenti_step)
    batch = staticmethod(valenti_run)
    stream = staticmethod(valenti_stream)
