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
from numba import njit

from quadest.filters.base import Estimator, P, Params
from quadest.filters.common import BASE, finite3, norm3, prepare

B = BASE  # gyro bias x[B:B+3], previous gyro sample x[B+3:B+6], have-previous flag x[B+6]


@dataclass(frozen=True)
class ComplementaryParams(Params):
    use_mag: bool = P(True, "-", "use the magnetometer when samples are present", "-")
    gain_acc: float = P(0.01, "-", "accelerometer gain α (static)",
                        "Valenti et al. 2015; authors' ROS implementation default")
    gain_mag: float = P(0.01, "-", "magnetometer gain β", "Valenti et al. 2015; ROS default")
    adaptive: bool = P(True, "-", "adapt α to the acceleration magnitude error (eq 60)", "ROS default")
    t1: float = P(0.1, "-", "magnitude error below which α is unchanged", "Valenti et al. 2015, section 5.2")
    t2: float = P(0.2, "-", "magnitude error at which α reaches zero", "Valenti et al. 2015, section 5.2")
    threshold: float = P(0.9, "-", "LERP above this scalar part, SLERP below (eq 50-52)",
                         "Valenti et al. 2015")
    bias_estimation: bool = P(True, "-", "estimate the gyro bias in steady state", "ROS default")
    bias_alpha: float = P(0.01, "-", "low-pass gain of the bias estimate", "ROS default")
    steady_acc: float = P(0.1, "m/s²", "steady state: |‖a‖ − g| below this", "ROS implementation")
    steady_rate: float = P(0.2, "rad/s", "steady state: |ω − b| below this per axis", "ROS implementation")
    steady_delta: float = P(0.01, "rad/s", "steady state: change of ω below this per axis",
                            "ROS implementation")
    gravity: float = P(9.80665, "m/s²", "gravity used for the magnitude error", "standard gravity")


@njit(cache=True)
def _scale(q, gain, threshold):
    """LERP (eq 50) or SLERP (eq 52) between identity and ``q`` by ``gain``, normalised."""
    out = np.empty(4)
    if q[0] > threshold:
        out[0] = (1.0 - gain) + gain * q[0]
        out[1], out[2], out[3] = gain * q[1], gain * q[2], gain * q[3]
    else:
        ang = np.arccos(q[0])
        s = np.sin(ang)
        a, b = np.sin((1.0 - gain) * ang) / s, np.sin(gain * ang) / s
        out[0] = a + b * q[0]
        out[1], out[2], out[3] = b * q[1], b * q[2], b * q[3]
    n = np.sqrt(out[0] ** 2 + out[1] ** 2 + out[2] ** 2 + out[3] ** 2)
    return out / n


@njit(cache=True)
def _apply_conj(dq, q):
    """``dq* ⊗ q``."""
    w, a, b, c = dq[0], -dq[1], -dq[2], -dq[3]
    out = np.empty(4)
    out[0] = w * q[0] - a * q[1] - b * q[2] - c * q[3]
    out[1] = w * q[1] + a * q[0] + b * q[3] - c * q[2]
    out[2] = w * q[2] - a * q[3] + b * q[0] + c * q[1]
    out[3] = w * q[3] + a * q[2] - b * q[1] + c * q[0]
    return out


@njit(cache=True)
def _to_nav(q, v):
    """``R(q) v``."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    return (v[0] * (1 - 2 * (y * y + z * z)) + v[1] * 2 * (x * y - w * z) + v[2] * 2 * (x * z + w * y),
            v[0] * 2 * (x * y + w * z) + v[1] * (1 - 2 * (x * x + z * z)) + v[2] * 2 * (y * z - w * x),
            v[0] * 2 * (x * z - w * y) + v[1] * 2 * (y * z + w * x) + v[2] * (1 - 2 * (x * x + y * y)))


@njit(cache=True)
def complementary_step(x, p, gyr, acc, mag, dt, diag):
    use_mag = p[0] > 0.0
    g_acc, g_mag, adaptive, t1, t2, thr = p[1], p[2], p[3] > 0, p[4], p[5], p[6]
    bias_on, b_alpha, s_acc, s_rate, s_delta, grav = p[7] > 0, p[8], p[9], p[10], p[11], p[12]
    diag[0], diag[1], diag[2], diag[3] = 0.0, x[B], x[B + 1], x[B + 2]
    if not prepare(x, acc, mag, use_mag):
        return
    gyr_ok = finite3(gyr)
    an = norm3(acc) if finite3(acc) else 0.0
    # steady-state gyro bias estimate (section 5.1)
    if bias_on and gyr_ok and an > 0.0:
        steady = abs(an - grav) < s_acc
        if x[B + 6] > 0.0:
            for i in range(3):
                if abs(gyr[i] - x[B + 3 + i]) > s_delta or abs(gyr[i] - x[B + i]) > s_rate:
                    steady = False
        else:
            steady = False
        if steady:
            for i in range(3):
                x[B + i] += b_alpha * (gyr[i] - x[B + i])
    if gyr_ok:
        for i in range(3):
            x[B + 3 + i] = gyr[i]
        x[B + 6] = 1.0
    q = x[0:4].copy()
    # eq 42: prediction, q_nb + ½ q_nb ⊗ [0, ω − b] Δt
    if gyr_ok:
        w0, w1, w2 = gyr[0] - x[B], gyr[1] - x[B + 1], gyr[2] - x[B + 2]
        h = 0.5 * dt
        qw, qx, qy, qz = q[0], q[1], q[2], q[3]
        q[0] = qw + h * (-qx * w0 - qy * w1 - qz * w2)
        q[1] = qx + h * (qw * w0 + qy * w2 - qz * w1)
        q[2] = qy + h * (qw * w1 - qx * w2 + qz * w0)
        q[3] = qz + h * (qw * w2 + qx * w1 - qy * w0)
        q /= np.sqrt(q[0] ** 2 + q[1] ** 2 + q[2] ** 2 + q[3] ** 2)
    if an > 0.0:
        a = np.empty(3)
        a[0], a[1], a[2] = -acc[0] / an, -acc[1] / an, -acc[2] / an
        gx, gy, gz = _to_nav(q, a)  # eq 44: predicted gravity direction (down, NED)
        if gz > -1.0 + 1e-12:
            s = np.sqrt(2.0 * (gz + 1.0))
            dq = np.empty(4)
            dq[0], dq[1], dq[2], dq[3] = np.sqrt((gz + 1.0) / 2.0), -gy / s, gx / s, 0.0  # eq 47
            alpha = g_acc
            if adaptive:  # eq 60
                em = abs(an - grav) / grav
                f = 1.0 if em <= t1 else (0.0 if em >= t2 else (t2 - em) / (t2 - t1))
                alpha = g_acc * f
            diag[0] = alpha
            q = _apply_conj(_scale(dq, alpha, thr), q)
        mn = norm3(mag) if (use_mag and finite3(mag)) else 0.0
        if mn > 0.0:
            m = np.empty(3)
            m[0], m[1], m[2] = mag[0] / mn, mag[1] / mn, mag[2] / mn
            lx, ly, _ = _to_nav(q, m)  # eq 54
            G = lx * lx + ly * ly  # eq 28
            if G > 0.0:
                r = np.sqrt(G + lx * np.sqrt(G))
                dq = np.empty(4)
                if r > 1e-12:
                    dq[0], dq[1], dq[2], dq[3] = r / np.sqrt(2.0 * G), 0.0, 0.0, ly / (np.sqrt(2.0) * r)  # eq 58
                else:  # field pointing exactly south: a half turn about z
                    dq[0], dq[1], dq[2], dq[3] = 0.0, 0.0, 0.0, 1.0
                q = _apply_conj(_scale(dq, g_mag, thr), q)
    x[0:4] = q / np.sqrt(q[0] ** 2 + q[1] ** 2 + q[2] ** 2 + q[3] ** 2)
    diag[1], diag[2], diag[3] = x[B], x[B + 1], x[B + 2]


@njit(cache=True)
def complementary_run(x, p, dt, gyr, acc, mag, q_out, diag_out):
    """Batch: the same step over every sample, in compiled code."""
    for k in range(len(dt)):
        complementary_step(x, p, gyr[k], acc[k], mag[k], dt[k], diag_out[k])
        q_out[k] = x[0:4]


class Complementary(Estimator):
    """Valenti's complementary filter. Diagnostics: the accelerometer gain used (``alpha``, 0
    when no correction) and the bias estimate ``bias_x/y/z`` (rad/s)."""

    name = "complementary"
    Params = ComplementaryParams
    state_size = BASE + 7
    diag_names = ("alpha", "bias_x", "bias_y", "bias_z")
    step = staticmethod(complementary_step)
    batch = staticmethod(complementary_run)
