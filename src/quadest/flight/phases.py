"""The phases of a flight and what the controller reads in each, by value for compiled code.

A flight flies (``flying``) and, once a rotor loss is known, flies fault-tolerant (``fault``). A
throw (Beffa, Ledergerber & D'Andrea, sections IV-V) starts in the hand and goes through the
recovery's phases:

1. ``waiting``: the throw is detected once ``‖z_acc‖ < β1`` has held for ``detect_samples``
   samples (eq 37); the rotors keep their constant speed (section III);
2. ``converging``: the bank of EKFs (:mod:`quadest.recovery.bank`) runs from the detection until
   the spherical variance ``S_g < β2`` (eqs 38-39) and ``dwell_s`` has passed; ``rearm_samples``
   samples with ``‖z_acc‖ ≥ β1`` (a hand still accelerating the vehicle) return to waiting
   with the bank restarted (:mod:`quadest.recovery.logic`, the same functions as over a recording);
3. ``nominal``: the most likely hypothesis's mean and covariance start one EKF of the bank's
   kind with the height added (section V-B, :mod:`quadest.recovery.nominal`), corrected by the
   barometer; the recovery controller (:mod:`quadest.control.upright`) takes over,
   reading that EKF's attitude and velocity and the position sensor's height; the EKF's
   accelerometer update waits while the attitude control error exceeds ``β3``. The bank's
   model was learnt at the throw's constant rotor speed, so its constant force (the last
   column of ``C``, along z) holds that thrust; from the handover it holds the thrust the
   measured rotor speeds give (``k_f Σ Ω²``). With the truth in the loop (an oracle) the
   handover is at the detection and the controller reads the true state.

A flight enters the same phases, at ``waiting``, when a divergence check fires in flight
(:mod:`quadest.flight.collision`): the rotors then go to the throw's speed, and while they spin
down the bank's constant force follows the measured rotor speeds (:func:`measured_thrust`).
"""

from __future__ import annotations

import numpy as np

from quadest._jit import copy_into, njit
from quadest.control.registry import command
from quadest.records import compiled_record
from quadest.recovery.bank import bank_step, summarize
from quadest.recovery.logic import count_samples, handover_due, restart_bank
from quadest.recovery.nominal import nominal_step
from quadest.rotation.kernels import rot_matrix

WAITING, CONVERGING, NOMINAL, FLYING, FAULT = 0, 1, 2, 3, 4
PHASES = ("waiting", "converging", "nominal", "flying", "fault")
"""The phases by value (a flight's phase per sample is ``Flight.modes``)."""

NAV_TRUTH, NAV_TRUE_STATE, NAV_FILTER, NAV_BANK = 0, 1, 2, 3
NAV = {
    "truth": NAV_TRUTH,  # oracle: true attitude, position and velocity; the gyro's rate
    "true-state": NAV_TRUE_STATE,  # oracle: the whole true state, rate included
    "filter": NAV_FILTER,  # an estimator's attitude and the position fusion
    "bank": NAV_BANK,  # a throw's recovery: the bank of EKFs, then its nominal EKF
}
"""What the controller reads, by value."""

PHASE, BELOW, GATE = 0, 1, 2  # the loop's carried state (Loop.state)
YAW, HOLD_Z = 0, 1  # what a recovery holds (Loop.held)

Bank = compiled_record(
    "Bank",
    "A throw's recovery: the bank's parameters, aerodynamic model (A, B, C; Cn its nominal "
    "copy), hypotheses (velocity, attitude, covariance 6x6, log likelihood, height) and their start "
    "(attitude, covariance), their probabilities and gravity directions, the nominal EKF (V1, "
    "Q1, P1 6x6, Z1 its height), the previous gyro reading, the thresholds of eqs 37-39, the "
    "re-arm and dwell of the logic, the barometer variance the nominal EKF assumes (0: not "
    "read) and the thrust of the throw's constant rotor speed.",
    prm="any",
    A="f8[:, :]",
    B="f8[:, :]",
    C="f8[:, :]",
    Cn="f8[:, :]",
    Vb="f8[:, :]",
    Qr="f8[:, :]",
    Pb="f8[:, :, :]",
    Lb="f8[:]",
    Zb="f8[:]",
    Qr0="f8[:, :]",
    Pb0="f8[:, :, :]",
    prob="f8[:]",
    gd="f8[:, :]",
    V1="f8[:, :]",
    Q1="f8[:, :]",
    P1="f8[:, :, :]",
    Z1="f8[:]",
    w_prev="f8[:]",
    beta1="f8",
    detect_samples="i8",
    beta2="f8",
    rearm_samples="i8",
    dwell_s="f8",
    baro_var="f8",
    t_throw="f8",
)


@njit(cache=True, inline="always")
def reads_truth(kind):
    """Whether the controller reads the truth (an oracle) rather than the recovery's estimate."""
    return kind == NAV_TRUTH or kind == NAV_TRUE_STATE


@njit(cache=True)
def quat_yaw(q):
    """ZYX yaw of ``q_nb``."""
    return np.arctan2(2.0 * (q[1] * q[2] + q[0] * q[3]), 1.0 - 2.0 * (q[2] * q[2] + q[3] * q[3]))


@njit(cache=True)
def hold(k, yaw, z, loop):
    """Hand over at sample ``k``: the controller holds ``yaw``, the height ``z`` and zero
    velocity from now on (a flight's path given up)."""
    control = loop.control
    loop.state[PHASE] = NOMINAL
    loop.record.events[1] = k
    loop.held[YAW], loop.held[HOLD_Z] = yaw, z
    for i in range(k, control.yaw_d.shape[0]):
        control.p_d[i, 2] = z
        control.yaw_d[i] = yaw
        for j in range(3):
            control.v_d[i, j] = 0.0
            control.a_d[i, j] = 0.0
        control.p_d[i, 0], control.p_d[i, 1] = 0.0, 0.0


@njit(cache=True)
def wait_for_throw(k, x, loop):
    """``waiting``: count the samples below β1 (eq 37); at the detection start converging, the
    bank's heights from the latest barometer reading (NaN: none yet), or with the truth hand over
    at once, holding the true yaw and height. Events: the latest detection, the detections so
    far, the first."""
    bank, sensing, events = loop.bank, loop.sensing, loop.record.events
    gyr = sensing.gyr
    loop.state[BELOW] = count_samples(loop.state[BELOW], sensing.acc, bank.beta1, True)
    if loop.state[BELOW] >= bank.detect_samples:
        loop.state[PHASE] = CONVERGING
        loop.state[BELOW] = 0  # from now on: the samples at or above β1 (the re-arm)
        events[0] = k
        events[2] = max(events[2], 0) + 1
        if events[3] < 0:
            events[3] = k
        for i in range(bank.Zb.shape[0]):
            bank.Zb[i] = -sensing.baro[0]
        if reads_truth(loop.nav.kind):
            hold(k, quat_yaw(x[6:10]), x[2], loop)
    else:
        bank.w_prev[0], bank.w_prev[1], bank.w_prev[2] = gyr[0], gyr[1], gyr[2]


@njit(cache=True)
def rearmed(loop):
    """``converging``: ``rearm_samples`` samples at or above β1 (the hand still accelerates the
    vehicle) return to waiting with the bank restarted; returns whether they did."""
    bank, sensing = loop.bank, loop.sensing
    if bank.rearm_samples <= 0:
        return False
    loop.state[BELOW] = count_samples(loop.state[BELOW], sensing.acc, bank.beta1, False)
    if loop.state[BELOW] < bank.rearm_samples:
        return False
    loop.state[PHASE] = WAITING
    loop.state[BELOW] = 0
    restart_bank(bank.Vb, bank.Qr, bank.Pb, bank.Lb, bank.Zb, bank.Qr0, bank.Pb0)
    gyr = sensing.gyr
    bank.w_prev[0], bank.w_prev[1], bank.w_prev[2] = gyr[0], gyr[1], gyr[2]
    return True


@njit(cache=True)
def converge(k, x, loop):
    """``converging``: one step of the bank (eqs 38-39, the barometer's reading of sample ``k``
    fused when the bank reads it) unless re-armed; below β2, once the dwell has passed, its most
    likely hypothesis starts the nominal EKF (the height its own, else from the latest barometer
    reading) and the controller holds the measured height."""
    if rearmed(loop):
        return
    bank, sensing, record = loop.bank, loop.sensing, loop.record
    if loop.watch.on:  # started in flight: the rotors still spin down to the throw's speed
        measured_thrust(loop, x)
    bank_step(
        (bank.Vb, bank.Qr, bank.Pb, bank.Lb, bank.Zb, bank.w_prev),
        (sensing.gyr, sensing.acc, sensing.dt, True, baro_reading(k, sensing)),
        bank.prm,
        (bank.A, bank.B, bank.Cn if loop.watch.on else bank.C),
    )
    best, sg = summarize(bank.Qr, bank.Lb, bank.prm.gravity, bank.prob, bank.gd)
    record.sg[k] = sg
    copy_into(record.gdir[k], bank.gd[best])
    copy_into(record.q[k], bank.Qr[best])
    if handover_due(sg, bank.beta2, (k - record.events[0]) * sensing.dt, bank.dwell_s):
        bank.V1[0] = bank.Vb[best]
        bank.Q1[0] = bank.Qr[best]
        own = bank.prm.baro_var > 0.0 and np.isfinite(bank.Zb[best])  # the bank read the barometer
        P1 = bank.P1[0]
        for r in range(P1.shape[0]):
            for c in range(P1.shape[1]):
                P1[r, c] = bank.Pb[best, r, c] if own or (r < 5 and c < 5) else 0.0
        if own:
            bank.Z1[0] = bank.Zb[best]
        else:
            P1[5, 5] = bank.baro_var
            bank.Z1[0] = -sensing.baro[0] if np.isfinite(sensing.baro[0]) else sensing.reading[2]
        hold(k, quat_yaw(bank.Q1[0]), sensing.reading[2], loop)
        loop.state[GATE] = 0


@njit(cache=True, inline="always")
def baro_reading(k, sensing):
    """The barometer's reading of sample ``k`` (m up), NaN when it reads none."""
    noise = sensing.baro_noise
    return sensing.baro[0] if k < noise.shape[0] and np.isfinite(noise[k]) else np.nan


@njit(cache=True)
def measured_thrust(loop, x):
    """The bank's constant force (the last column of ``C``, along z) moved from the thrust of
    the throw's rotor speed to the thrust the measured rotor speeds give (``k_f Σ Ω²``), into ``Cn``."""
    bank = loop.bank
    t_est = 0.0
    for i in range(loop.plant.vehicle.rotor_pos.shape[0]):
        t_est += loop.control.gains.k_f * x[13 + i] * x[13 + i]
    bank.Cn[2, 9] = bank.C[2, 9] - (t_est - bank.t_throw)


@njit(cache=True)
def nominal_estimate(k, x, loop):
    """``nominal``: the state the recovery controller reads: the truth, or the nominal EKF's
    attitude and velocity (:func:`quadest.recovery.nominal.nominal_step`, the barometer's
    reading of sample ``k`` fused when there is one) with the thrust of the measured rotor
    speeds, the gyro's rate and the position sensor's height (no horizontal position: velocity
    and height hold)."""
    bank, sensing, xh = loop.bank, loop.sensing, loop.nav.xh
    if reads_truth(loop.nav.kind):
        for j in range(13):
            xh[j] = x[j]
        return
    measured_thrust(loop, x)
    nominal_step(
        bank.V1[0],
        bank.Q1[0],
        bank.P1[0],
        bank.Z1,
        bank.w_prev,
        (sensing.gyr, sensing.acc, sensing.dt, loop.state[GATE] != 0),
        bank.prm,
        (bank.A, bank.B, bank.Cn),
        baro_reading(k, sensing),
        bank.baro_var,
    )
    rot = rot_matrix(bank.Q1[0])
    for j in range(3):
        xh[3 + j] = rot[j, 0] * bank.V1[0, 0] + rot[j, 1] * bank.V1[0, 1] + rot[j, 2] * bank.V1[0, 2]
        xh[10 + j] = sensing.gyr[j]
    for j in range(4):
        xh[6 + j] = bank.Q1[0, j]
    xh[0], xh[1], xh[2] = 0.0, 0.0, sensing.reading[2]


@njit(cache=True)
def recovery_phase(k, x, loop):
    """A throw's sample ``k`` (module doc): detection, convergence, or the nominal estimate and
    the recovery controller; records what the controller read (nothing before the handover)."""
    if loop.state[PHASE] == WAITING:
        wait_for_throw(k, x, loop)
    if loop.state[PHASE] == CONVERGING:
        converge(k, x, loop)
    elif loop.state[PHASE] == NOMINAL:
        nominal_estimate(k, x, loop)
        xh, control = loop.nav.xh, loop.control
        copy_into(loop.record.q[k], xh[6:10])
        gate = command(control.by_phase[NOMINAL], k, xh, control, loop.plant.vehicle, loop.sensing.dt)
        loop.state[GATE] = 1 if gate else 0
    if loop.state[PHASE] == NOMINAL:
        copy_into(loop.record.pv[k], loop.nav.xh[0:6])
