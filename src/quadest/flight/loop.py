"""The closed loop with the estimator in it (issue #13, part 5), every step in compiled code.

Per IMU sample ``k`` (time ``k / rate``; the controller runs at the IMU rate, the vehicle at the
simulation rate, ``substeps`` RK4 steps per sample):

1. a failure due at ``k`` strikes (the rotor's efficiency changes);
2. the sensors are sampled from the true state (:mod:`quadest.sim.sensors`, the model every
   simulation samples): IMU, magnetometer,
   and every ``mocap_every`` samples the position sensor, motion capture or GNSS-like (its
   reading ``delay`` samples old);
3. the estimator takes one step (its compiled ``step``, the same function its batch run calls);
   its attitude goes through the declination into the geographic frame;
4. position and velocity: predicted with the accelerometer rotated by the estimated attitude,
   corrected at each position reading with a constant (steady-state Kalman) gain;
5. the controller (SE(3) before the failure is known, the fault-tolerant one after) commands
   the rotors from the estimated state and the measured body rate;
6. the vehicle flies to the next sample.

The loop ends early with a status: ground contact, lost control (body rate or speed beyond
what a flying vehicle has), a non-finite estimate, or a diverged simulation.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from quadest._jit import njit
from quadest.control.ftc import ftc_command
from quadest.control.se3 import se3_command
from quadest.models.multirotor import derivative_ws, rk4_ws
from quadest.rotation.kernels import rotate_s
from quadest.sim.sensors import motor_current, rotor_vibration_step, sample_imu, sample_mag

OK, GROUND, LOST_CONTROL, ESTIMATE_NAN, DIVERGED = 0, 1, 2, 3, 4
STATUS = {
    OK: "survived",
    GROUND: "crashed: ground contact",
    LOST_CONTROL: "crashed: lost control",
    ESTIMATE_NAN: "stopped: the estimator returned a non-finite attitude",
    DIVERGED: "stopped: the simulation diverged",
}
MAX_RATE = 100.0  # rad/s: beyond this the vehicle is tumbling out of control (RotorPy stops at the same)
MAX_SPEED = 20.0  # m/s: beyond this it is falling or flying away (RotorPy stops at the same)


@njit(cache=True)
def _true_estimate(x, p, c, gyr, acc, mag, dt, diag):
    """The 'truth' estimator: nothing to do (the loop reads the true state)."""


def no_estimator():
    return _true_estimate


@njit(cache=True, inline="always")
def sense(x, cmd, eta, imb, V, sm, k, dt, tw, dx, Fb, Mb, T, vib, gyr, acc, mag):
    """IMU and magnetometer sample ``k`` (at ``k dt``) from the true state ``x``: the state's
    derivative (into ``dx``) gives the acceleration and angular acceleration, the rotors'
    thrusts (into ``T``) their load and the motor current, their speeds and imbalances ``imb``
    (kg m) the vibration."""
    derivative_ws(x, cmd, eta, V, dx, Fb, Mb, T)  # also the force, moment and rotor thrusts
    sample(x, dx, eta, imb, V, sm, k, dt, tw, T, vib, gyr, acc, mag)


@njit(cache=True, inline="always")
def sample(x, dx, eta, imb, V, sm, k, dt, tw, T, vib, gyr, acc, mag):
    """The sensors of sample ``k`` from the state ``x``, its derivative ``dx`` (the dynamics' or,
    in a hand that carries the vehicle, the hand's) and the rotors' thrusts ``T``."""
    n_rot = eta.shape[0]
    active = 0
    total = 0.0
    for i in range(n_rot):
        total += T[i]
        if eta[i] > 0.0:
            active += 1
    active = max(active, 1)
    load = total / active / (V.mass * V.gravity / n_rot)
    rotor_vibration_step(sm.rv, k * dt, x[13:], imb, vib, sm.vib_acc, sm.vib_gyr)
    sample_imu(sm, k, x[6:10], dx[3:6], x[10:13], dx[10:13], sm.vib_acc, sm.vib_gyr, gyr, acc)
    sample_mag(sm, k, x[6:10], x[0:3], motor_current(load, active, tw), mag)


@njit(cache=True, inline="always")
def ended(x, ground_z):
    """Whether a flight ends after this step, and why (module doc)."""
    for j in range(x.shape[0]):
        if not np.isfinite(x[j]):
            return DIVERGED
    if x[2] > ground_z:
        return GROUND
    if (
        x[10] * x[10] + x[11] * x[11] + x[12] * x[12] > MAX_RATE * MAX_RATE
        or x[3] * x[3] + x[4] * x[4] + x[5] * x[5] > MAX_SPEED * MAX_SPEED
    ):
        return LOST_CONTROL
    return OK


@njit(cache=True, inline="always")
def record_and_fly(
    k,
    x,
    dx,
    T,
    cmd,
    gyr,
    acc,
    mag,
    eta,
    V,
    h,
    substeps,
    ground_z,
    out_x,
    out_dx,
    out_thrust,
    out_cmd,
    out_gyr,
    out_acc,
    out_mag,
    W,
):
    """Record sample ``k`` (state, derivative, thrusts, commands, readings), fly ``substeps``
    RK4 steps to the next sample, and say whether the flight ends there (:func:`ended`)."""
    out_x[k] = x
    out_dx[k] = dx
    out_thrust[k] = T
    out_cmd[k] = cmd
    out_gyr[k] = gyr
    out_acc[k] = acc
    out_mag[k] = mag
    for _ in range(substeps):
        rk4_ws(x, cmd, eta, V, h, W)
    return ended(x, ground_z)


Loop = namedtuple(
    "Loop",
    [
        # the flight: vehicle, controllers, sensors, reference, failure, position sensor, ground
        "V",
        "G",
        "F",
        "sm",
        "use_truth",
        "h",
        "substeps",
        "dt",
        "p_d",
        "v_d",
        "a_d",
        "yaw_d",
        "fail_rotor",
        "fail_k",
        "fail_eta",
        "fail_imb",
        "ftc_k",
        "tw",
        "mocap_every",
        "mocap_delay",
        "mocap_noise",
        "pos_gain",
        "ground_z",
        # what the loop carries from sample to sample
        "cmd",
        "dx",
        "Fb",
        "Mb",
        "T",
        "gyr",
        "acc",
        "mag",
        "vib",
        "imb",
        "xh",
        "integral",
        "ph",
        "vh",
        "hist",
        # what it records per sample
        "out_x",
        "out_dx",
        "out_thrust",
        "out_eta",
        "out_cmd",
        "out_gyr",
        "out_acc",
        "out_mag",
        "out_q",
        "out_pv",
        # the integrator's work arrays (multirotor.work)
        "W",
    ],
)
"""Everything a closed loop reads and writes (built by :func:`quadest.flight.fly`)."""


@njit(cache=True, inline="always")
def step_sense(k, x, eta, L):
    """Sample ``k``, first half: a failure due now strikes; the sensors are sampled into
    ``L.gyr``, ``L.acc``, ``L.mag``."""
    if k == L.fail_k and L.fail_rotor >= 0:
        eta[L.fail_rotor] = L.fail_eta
        L.imb[L.fail_rotor] = L.fail_imb
    sense(x, L.cmd, eta, L.imb, L.V, L.sm, k, L.dt, L.tw, L.dx, L.Fb, L.Mb, L.T, L.vib, L.gyr, L.acc, L.mag)


@njit(cache=True, inline="always")
def step_act(k, x, eta, L, q_est):
    """Sample ``k``, second half, with the estimator's attitude ``q_est`` (geographic ``q_nb``;
    ignored with truth in the loop): position and velocity, control, record, fly to the next
    sample. Returns the status (:data:`OK` to go on)."""
    V, xh, ph, vh, hist, acc, gyr = L.V, L.xh, L.ph, L.vh, L.hist, L.acc, L.gyr
    dt = L.dt
    if L.use_truth:
        for j in range(4):
            xh[6 + j] = x[6 + j]
    else:
        for j in range(4):
            xh[6 + j] = q_est[j]
    if not (np.isfinite(xh[6]) and np.isfinite(xh[7]) and np.isfinite(xh[8]) and np.isfinite(xh[9])):
        return ESTIMATE_NAN
    # position and velocity
    if L.use_truth:
        for j in range(3):
            ph[j], vh[j] = x[j], x[3 + j]
    else:
        a0, a1, a2 = rotate_s(xh[6], xh[7], xh[8], xh[9], acc[0], acc[1], acc[2])
        an = (a0, a1, a2 + V.gravity)
        for j in range(3):
            ph[j] += vh[j] * dt + 0.5 * an[j] * dt * dt
            vh[j] += an[j] * dt
        for j in range(L.mocap_delay, 0, -1):
            hist[j] = hist[j - 1]
        hist[0] = x[0:3]
        if k % L.mocap_every == 0:
            m = k // L.mocap_every
            for j in range(3):
                e = hist[L.mocap_delay, j] + L.mocap_noise[m, j] - ph[j]
                ph[j] += L.pos_gain[j, 0] * e
                vh[j] += L.pos_gain[j, 1] * e
    for j in range(3):
        xh[j], xh[3 + j], xh[10 + j] = ph[j], vh[j], gyr[j]
    # control
    if L.ftc_k >= 0 and k >= L.ftc_k:
        ftc_command(xh, L.p_d[k], L.v_d[k], L.a_d[k], L.F, V, dt, L.integral, L.cmd)
    else:
        se3_command(xh, L.p_d[k], L.v_d[k], L.a_d[k], L.yaw_d[k], L.G, V, L.cmd)
    if L.fail_rotor >= 0 and k >= L.fail_k and L.fail_eta == 0.0:
        L.cmd[L.fail_rotor] = 0.0  # a lost rotor: its motor spins down
    # record, then fly to the next sample
    L.out_eta[k] = eta
    L.out_q[k] = xh[6:10]
    L.out_pv[k, 0:3] = ph
    L.out_pv[k, 3:6] = vh
    return record_and_fly(
        k,
        x,
        L.dx,
        L.T,
        L.cmd,
        gyr,
        acc,
        L.mag,
        eta,
        V,
        L.h,
        L.substeps,
        L.ground_z,
        L.out_x,
        L.out_dx,
        L.out_thrust,
        L.out_cmd,
        L.out_gyr,
        L.out_acc,
        L.out_mag,
        L.W,
    )


@njit
def closed_loop(x, eta, L, est_step, ex, ep, ec, ediag, dq):
    """Fly ``len(L.yaw_d)`` IMU samples (module doc) with a quadest estimator in the loop:
    ``est_step`` its compiled step, with its state ``ex``, records ``ep``, ``ec`` and
    diagnostics ``ediag``; ``dq`` the declination quaternion. Returns ``(status, samples flown)``.
    (Not cached: numba compiles it once per estimator and process, a few seconds.)"""
    q = np.empty(4)
    for k in range(L.yaw_d.shape[0]):
        step_sense(k, x, eta, L)
        est_step(ex, ep, ec, L.gyr, L.acc, L.mag, L.dt, ediag)
        # q = dq ⊗ q_est (the declination turns the magnetic frame into the geographic one)
        q[0] = dq[0] * ex[0] - dq[1] * ex[1] - dq[2] * ex[2] - dq[3] * ex[3]
        q[1] = dq[0] * ex[1] + dq[1] * ex[0] + dq[2] * ex[3] - dq[3] * ex[2]
        q[2] = dq[0] * ex[2] - dq[1] * ex[3] + dq[2] * ex[0] + dq[3] * ex[1]
        q[3] = dq[0] * ex[3] + dq[1] * ex[2] - dq[2] * ex[1] + dq[3] * ex[0]
        status = step_act(k, x, eta, L, q)
        if status == ESTIMATE_NAN:
            return status, k
        if status != OK:
            return status, k + 1
    return OK, L.yaw_d.shape[0]
