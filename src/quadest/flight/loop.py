"""The closed loop: the one compiled loop every flight flies (a hover, a trajectory, a rotor
loss, a throw), configured by records checked field by field (:func:`quadest.records.compiled_record`).

Per IMU sample ``k`` (time ``k / rate``; the controller runs at the IMU rate, the vehicle at the
simulation rate, ``substeps`` RK4 steps per sample):

1. a failure's profile (:mod:`quadest.sim.faults`) sets the rotors' efficiencies, motor
   drives and imbalances of sample ``k``;
2. the sensors are sampled (:mod:`quadest.sim.sensors`, the model every simulation samples)
   from the true state, or in the hand from the hand's motion; every ``every`` samples the
   position sensor reads (its reading ``delay`` samples old); a clipped gyroscope axis's rate
   is predicted from the vehicle model (:mod:`quadest.flight.rate`);
3. the estimate: an estimator's compiled step (the function its batch run calls) and the
   position fusion, the truth (an oracle, labelled), or a throw's recovery (:mod:`quadest.flight.phases`);
4. the controller of the flight's phase (:data:`PHASES`, :mod:`quadest.control.registry`)
   commands the rotors, after the rotor-failure detector (:mod:`quadest.flight.detection`) and,
   in a landing, the land detector (:mod:`quadest.flight.landing`) have had their say;
5. the vehicle flies to the next sample (in the hand it is carried).

A collision adds its velocity and body rate over its impact (:func:`strike`: the sensors see it);
with the divergence checks on, a check that fires after step 3 turns the flight into a
throw's recovery (:mod:`quadest.flight.collision`).

The loop ends early with a status: ground contact, lost control (body rate or speed beyond
what a flying vehicle has), a non-finite estimate, or a diverged simulation.
"""

from __future__ import annotations

import numpy as np

from quadest._jit import NO_ALLOCATION, copy_into, njit
from quadest.control.registry import command
from quadest.flight.collision import diverged, start_recovery
from quadest.flight.detection import notice_failure
from quadest.flight.landing import detect_landing, idle_when_landed
from quadest.flight.phases import FAULT, FLYING, NAV_FILTER, NAV_TRUE_STATE, PHASE, recovery_phase
from quadest.flight.rate import predict_rate
from quadest.models.multirotor import derivative_ws, rk4_ws
from quadest.records import compiled_record
from quadest.rotation.kernels import qmul_s, rotate_s
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

Plant = compiled_record(
    "Plant",
    "The vehicle and what happens to it: the integration step and substeps per sample, where "
    "a flight ends, the rotor failure (from sample fail_k, -1: none, one row per sample of every "
    "rotor's efficiency, motor drive and imbalance, the last row holding on: sim.faults.Failure.profile; "
    "a lost rotor's command zeroed from sample lost_k on with zero_failed, an oracle; lost_rotor -1: "
    "none), the rotors' efficiencies, drives and imbalances now, the hand's states and derivatives "
    "until the release (none: "
    "zero rows), a collision (from sample hit_k over hit_n samples, the velocity hit_dv, NED, and "
    "body rate hit_dw it adds; hit_n 0: none), the wind per sample (NED, m/s; no rows: still air) "
    "and the work arrays of the dynamics.",
    vehicle="any",
    h="f8",
    substeps="i8",
    ground_z="f8",
    max_rate="f8",
    max_speed="f8",
    tw="f8",
    eta="f8[:]",
    drive="f8[:]",
    imb="f8[:]",
    fail_k="i8",
    fail_eta="f8[:, :]",
    fail_drive="f8[:, :]",
    fail_imb="f8[:, :]",
    lost_rotor="i8",
    lost_k="i8",
    zero_failed="b1",
    hit_k="i8",
    hit_n="i8",
    hit_dv="f8[:]",
    hit_dw="f8[:]",
    hand_x="f8[:, :]",
    hand_dx="f8[:, :]",
    wind="f8[:, :]",
    work="any",
    dx="f8[:]",
    Fb="f8[:]",
    Mb="f8[:]",
    thrusts="f8[:]",
)

Sensing = compiled_record(
    "Sensing",
    "The sensor model and its readings; the position sensor (every, delay in samples, its "
    "noise per reading, the true positions it has yet to report, its latest reading); the "
    "barometer (per sample its lag's coefficient and the noise of a reading, NaN between "
    "readings; its lagged height and latest reading, m up).",
    sm="any",
    on="b1",
    dt="f8",
    gyr="f8[:]",
    acc="f8[:]",
    mag="f8[:]",
    vib="f8[:]",
    every="i8",
    delay="i8",
    noise="f8[:, :]",
    hist="f8[:, :]",
    reading="f8[:]",
    baro_a="f8[:]",
    baro_noise="f8[:]",
    baro_lag="f8[:]",
    baro="f8[:]",
)

Navigation = compiled_record(
    "Navigation",
    "What the controller reads and how it is made: the source (flight.phases.NAV), the "
    "estimated state xh (position, velocity, q_nb, body rate), the position fusion's position, "
    "velocity and steady-state gain, the estimator's latest attitude (geographic q_nb), and the "
    "rate of a clipped gyroscope axis (flight.rate.ClipRate); the position fusion's latest "
    "innovation; the estimator's state swapped in at sample reset_k (-1: never), a collision's "
    "reset to nonsense.",
    kind="i8",
    xh="f8[:]",
    q_est="f8[:]",
    ph="f8[:]",
    vh="f8[:]",
    gain="f8[:, :]",
    clip="any",
    innov="f8[:]",
    reset_k="i8",
    reset_x="f8[:]",
)

Record = compiled_record(
    "Record",
    "What the loop records per sample: true state, its derivative, rotor thrusts, "
    "efficiencies and commands, the readings (the barometer's NaN between readings), what the "
    "controller read (attitude, position and velocity, body rate), the phase, a recovery's "
    "spherical variance and gravity direction, and its "
    "events (detection, handover, detections, first detection).",
    x="f8[:, :]",
    dx="f8[:, :]",
    thrust="f8[:, :]",
    eta="f8[:, :]",
    cmd="f8[:, :]",
    gyr="f8[:, :]",
    acc="f8[:, :]",
    mag="f8[:, :]",
    baro="f8[:]",
    q="f8[:, :]",
    pv="f8[:, :]",
    rate="f8[:, :]",
    phase="i8[:]",
    sg="f8[:]",
    gdir="f8[:, :]",
    events="i8[:]",
)

Loop = compiled_record(
    "Loop",
    "One flight: its plant, sensing, navigation, recovery bank, control, rotor-failure detection, "
    "land detector (flight.landing.LandDetector) and record, the divergence checks that start a "
    "recovery in flight (flight.collision.Watch), "
    "and what it carries from sample to sample (state: phase, samples below the throw threshold, the "
    "accelerometer gate; held: the yaw and height a recovery holds).",
    plant="any",
    sensing="any",
    nav="any",
    bank="any",
    control="any",
    detection="any",
    landing="any",
    watch="any",
    record="any",
    state="i8[:]",
    held="f8[:]",
)


def record_arrays(n: int, rotors: int) -> dict:
    """Empty arrays for a :data:`Record` of ``n`` samples (the events not yet happened)."""
    nx = 13 + rotors
    shapes = dict(x=nx, dx=nx, thrust=rotors, eta=rotors, cmd=rotors, gyr=3, acc=3, mag=3, q=4, pv=6, rate=3, gdir=3)
    out = {k: np.full((n, m), np.nan) for k, m in shapes.items()}
    out.update(
        baro=np.full(n, np.nan), phase=np.zeros(n, np.int64), sg=np.full(n, np.nan), events=np.full(4, -1, np.int64)
    )
    return out


def flown_arrays(record, flown: int) -> dict:
    """The per-sample arrays of a :data:`Record` up to the samples ``flown``."""
    return {k: v[:flown] for k, v in record._asdict().items() if k != "events"}


@njit(cache=True, inline="always")
def sample(x, dx, plant, sensing, k):
    """The sensors of sample ``k`` from the state ``x``, its derivative ``dx`` (the dynamics' or,
    in a hand that carries the vehicle, the hand's) and the rotors' thrusts ``plant.thrusts``."""
    eta, thrusts = plant.eta, plant.thrusts
    n_rot = eta.shape[0]
    active = 0
    total = 0.0
    for i in range(n_rot):
        total += thrusts[i]
        if eta[i] > 0.0:
            active += 1
    active = max(active, 1)
    load = total / active / (plant.vehicle.mass * plant.vehicle.gravity / n_rot)
    sm = sensing.sm
    rotor_vibration_step(sm.rv, k * sensing.dt, x[13:], plant.imb, sensing.vib, sm.vib_acc, sm.vib_gyr)
    sample_imu(sm, k, x[6:10], dx[3:6], x[10:13], dx[10:13], sm.vib_acc, sm.vib_gyr, sensing.gyr, sensing.acc)
    sample_mag(sm, k, x[6:10], x[0:3], motor_current(load, active, plant.tw), sensing.mag)


@njit(cache=True, inline="always")
def sense(k, x, loop):
    """Sample ``k``, first half: the vehicle's truth of sample ``k`` (:func:`plant_truth`), then
    its sensors (:func:`read_sensors`)."""
    plant_truth(k, x, loop)
    read_sensors(k, x, loop)


@njit(cache=True, inline="always")
def plant_truth(k, x, loop):
    """The compiled vehicle's truth of sample ``k`` (the plant's side of the loop, what
    :class:`quadest.flight.plant.Plant` stands for): the failure's profile sets the rotors; the
    wind of the sample; in the hand the vehicle is where the hand has it; with the sensors on, the
    state's derivative and the rotor thrusts (``plant.dx``, ``plant.thrusts``), a collision's share."""
    plant, sensing = loop.plant, loop.sensing
    strike_failure(k, plant)
    if k < plant.wind.shape[0]:
        copy_into(plant.vehicle.wind, plant.wind[k])
    in_hand = k < plant.hand_dx.shape[0]
    if in_hand:
        copy_into(x, plant.hand_x[k])
    if sensing.on:
        derivative_ws(
            x, loop.control.cmd, plant.eta, plant.drive, plant.vehicle, plant.dx, plant.Fb, plant.Mb, plant.thrusts
        )  # also the rotor thrusts
        if in_hand:
            copy_into(plant.dx, plant.hand_dx[k])
        if hitting(k, plant):
            strike(plant.dx, plant, 1.0 / (plant.hit_n * sensing.dt))


@njit(cache=True, inline="always")
def read_sensors(k, x, loop):
    """The sensors of sample ``k`` from the truth (the state ``x``, ``plant.dx``,
    ``plant.thrusts``, ``plant.eta``, ``plant.imb``) into ``loop.sensing``: the IMU and
    magnetometer, a clipped axis's predicted rate, the position sensor and the barometer."""
    plant, sensing = loop.plant, loop.sensing
    if sensing.on:
        sample(x, plant.dx, plant, sensing, k)
        predict_rate(k, x, loop)
    for j in range(sensing.delay, 0, -1):
        copy_into(sensing.hist[j], sensing.hist[j - 1])
    copy_into(sensing.hist[0], x[0:3])
    if k % sensing.every == 0:
        m = k // sensing.every
        for j in range(3):
            sensing.reading[j] = sensing.hist[sensing.delay, j] + sensing.noise[m, j]
    if k < sensing.baro_a.shape[0]:
        sample_baro(k, -x[2], sensing)


@njit(cache=True, inline="always")
def strike_failure(k, plant):
    """The failure's row for sample ``k`` (while its profile changes; its last row then holds)."""
    j = k - plant.fail_k
    if plant.fail_k >= 0 and 0 <= j < plant.fail_eta.shape[0]:
        copy_into(plant.eta, plant.fail_eta[j])
        copy_into(plant.drive, plant.fail_drive[j])
        copy_into(plant.imb, plant.fail_imb[j])


@njit(cache=True, inline="always")
def hitting(k, plant):
    """Whether a collision acts over sample ``k``."""
    return plant.hit_n > 0 and plant.hit_k <= k < plant.hit_k + plant.hit_n


@njit(cache=True, inline="always")
def strike(x, plant, scale):
    """Add ``scale`` times the collision's velocity and body rate to ``x``'s (a state: its share
    of one sample; a derivative: its acceleration over the impact)."""
    for j in range(3):
        x[3 + j] += scale * plant.hit_dv[j]
        x[10 + j] += scale * plant.hit_dw[j]


@njit(cache=True, inline="always")
def sample_baro(k, alt, sensing):
    """The barometer at sample ``k`` from the true height ``alt`` (m up): its first-order lag
    ``h ← a h + (1 − a) alt`` (from ``alt`` at the first sample), read with the noise drawn for
    the sample (NaN: no reading, the latest is kept)."""
    a = sensing.baro_a[k]
    lag = sensing.baro_lag
    lag[0] = alt if k == 0 else a * lag[0] + (1.0 - a) * alt
    if np.isfinite(sensing.baro_noise[k]):
        sensing.baro[0] = lag[0] + sensing.baro_noise[k]


@njit(cache=True, inline="always")
def navigate(k, x, loop, q_est):
    """Position, velocity, attitude and rate for the controller of a flight (not a throw's
    recovery): the truth's (rate: the gyro's, on a clipped axis the predicted one,
    :mod:`quadest.flight.rate`; the whole true state with ``true-state``), or the estimator's
    attitude ``q_est`` with the position fusion (the accelerometer rotated by it, corrected at
    each position reading with a constant gain) and the same rate. Returns
    :data:`ESTIMATE_NAN` for a non-finite attitude, else :data:`OK`."""
    nav, sensing, dt = loop.nav, loop.sensing, loop.sensing.dt
    xh, ph, vh, acc = nav.xh, nav.ph, nav.vh, sensing.acc
    truth = nav.kind != NAV_FILTER
    for j in range(4):
        xh[6 + j] = x[6 + j] if truth else q_est[j]
    if not (np.isfinite(xh[6]) and np.isfinite(xh[7]) and np.isfinite(xh[8]) and np.isfinite(xh[9])):
        return ESTIMATE_NAN
    if truth:
        for j in range(3):
            ph[j], vh[j] = x[j], x[3 + j]
    else:
        a0, a1, a2 = rotate_s(xh[6], xh[7], xh[8], xh[9], acc[0], acc[1], acc[2])
        an = (a0, a1, a2 + loop.plant.vehicle.gravity)
        for j in range(3):
            ph[j] += vh[j] * dt + 0.5 * an[j] * dt * dt
            vh[j] += an[j] * dt
        if k % sensing.every == 0:
            for j in range(3):
                e = sensing.reading[j] - ph[j]
                nav.innov[j] = e
                ph[j] += nav.gain[j, 0] * e
                vh[j] += nav.gain[j, 1] * e
    for j in range(3):
        xh[j], xh[3 + j] = ph[j], vh[j]
        xh[10 + j] = x[10 + j] if nav.kind == NAV_TRUE_STATE else nav.clip.rate[j]
    return OK


@njit(cache=True, inline="always")
def control_flight(k, loop):
    """The controller of a flight's phase: nominal, or fault-tolerant once the loss is known
    (holding the point the reference had reached: a spinning vehicle does not track a path, and
    giving the lost rotor up); the lost rotor's command zeroed from the failure on when the
    plant says so (an oracle)."""
    plant, control = loop.plant, loop.control
    fault = control.fault
    if k == fault[0]:
        hold_reference(control, k)
    phase = FAULT if fault[0] >= 0 and k >= fault[0] else FLYING
    loop.state[PHASE] = phase
    command(control.by_phase[phase], k, loop.nav.xh, control, plant.vehicle, loop.sensing.dt)
    if phase == FAULT:
        control.cmd[fault[1]] = 0.0
    if plant.zero_failed and plant.lost_rotor >= 0 and k >= plant.lost_k:
        control.cmd[plant.lost_rotor] = 0.0


@njit(cache=True, inline="always")
def hold_reference(control, k):
    """From sample ``k`` on, the reference holds the point it had reached."""
    for i in range(k, control.p_d.shape[0]):
        for j in range(3):
            control.p_d[i, j] = control.p_d[k, j]
            control.v_d[i, j] = 0.0
            control.a_d[i, j] = 0.0


@njit(cache=True, inline="always")
def ended(x, plant):
    """Whether a flight ends after this step, and why (module doc)."""
    for j in range(x.shape[0]):
        if not np.isfinite(x[j]):
            return DIVERGED
    if x[2] > plant.ground_z:
        return GROUND
    if (
        x[10] * x[10] + x[11] * x[11] + x[12] * x[12] > plant.max_rate * plant.max_rate
        or x[3] * x[3] + x[4] * x[4] + x[5] * x[5] > plant.max_speed * plant.max_speed
    ):
        return LOST_CONTROL
    return OK


@njit(cache=True, inline="always")
def record_and_fly(k, x, loop):
    """Record sample ``k`` (:func:`record_sample`), fly to the next (:func:`advance`) and say
    whether the flight ends there (:func:`ended`)."""
    record_sample(k, x, loop)
    return advance(k, x, loop)


@njit(cache=True, inline="always")
def record_sample(k, x, loop):
    """Record sample ``k``: the truth, the readings, the commands and the phase."""
    plant, sensing, record, control = loop.plant, loop.sensing, loop.record, loop.control
    copy_into(record.x[k], x)
    copy_into(record.dx[k], plant.dx)
    copy_into(record.thrust[k], plant.thrusts)
    copy_into(record.eta[k], plant.eta)
    copy_into(record.cmd[k], control.cmd)
    copy_into(record.gyr[k], sensing.gyr)
    copy_into(record.acc[k], sensing.acc)
    copy_into(record.mag[k], sensing.mag)
    if k < sensing.baro_noise.shape[0] and np.isfinite(sensing.baro_noise[k]):
        record.baro[k] = sensing.baro[0]
    record.phase[k] = loop.state[PHASE]


@njit(cache=True, inline="always")
def advance(k, x, loop):
    """The compiled vehicle from sample ``k`` to the next: ``substeps`` RK4 steps with the
    commands (in the hand: carried to the hand's next state), a collision's share; whether the
    flight ends there (:func:`ended`)."""
    plant, control = loop.plant, loop.control
    if k < plant.hand_dx.shape[0]:
        status = ended(x, plant)
        copy_into(x, plant.hand_x[k + 1])
        return status
    for _ in range(plant.substeps):
        rk4_ws(x, control.cmd, plant.eta, plant.drive, plant.vehicle, plant.h, plant.work)
    if hitting(k, plant):
        strike(x, plant, 1.0 / plant.hit_n)
    return ended(x, plant)


@njit(cache=True, inline="always")
def fly_sample(k, x, loop, q_est):
    """Sample ``k``, second half, of a flight (not a throw's recovery) with an estimator's
    attitude ``q_est`` (geographic ``q_nb``; read only with an estimator in the loop): the
    estimate, control, record, fly to the next sample. Returns the status (:data:`OK` to go on)."""
    status = navigate(k, x, loop, q_est)
    if diverged(k, loop, status == OK):
        start_recovery(loop)
        return recover_sample(k, x, loop)
    if status != OK:
        return status
    command_rotors(k, x, loop)
    return record_and_fly(k, x, loop)


@njit(cache=True, inline="always")
def command_rotors(k, x, loop):
    """The rotor commands of sample ``k`` once the controller has its state: the detector, the
    land detector, the controller of the phase; what the controller read recorded."""
    notice_failure(k, x, loop)
    detect_landing(k, loop)
    control_flight(k, loop)
    idle_when_landed(loop)
    record, nav = loop.record, loop.nav
    copy_into(record.q[k], nav.xh[6:10])
    copy_into(record.pv[k, 0:3], nav.ph)
    copy_into(record.pv[k, 3:6], nav.vh)
    copy_into(record.rate[k], nav.xh[10:13])


@njit(cache=True, **NO_ALLOCATION)
def read_sensors_sample(k, x, loop):
    """:func:`read_sensors`, compiled on its own: a plant of another simulator has set the truth
    of sample ``k`` (:mod:`quadest.flight.plant`)."""
    read_sensors(k, x, loop)


@njit(cache=True, **NO_ALLOCATION)
def command_sample(k, x, loop, q_est):
    """Sample ``k``, second half, of a flight whose plant is another simulator's
    (:mod:`quadest.flight.plant`): navigate, command and record, but not fly (the plant does).
    Returns the status (:data:`OK` to go on)."""
    status = navigate(k, x, loop, q_est)
    if status != OK:
        return status
    command_rotors(k, x, loop)
    record_sample(k, x, loop)
    return OK


@njit(cache=True)
def recover_sample(k, x, loop):
    """Sample ``k``, second half, of a throw before it flies (:func:`recovery_phase`)."""
    recovery_phase(k, x, loop)
    return record_and_fly(k, x, loop)


@njit(cache=True, **NO_ALLOCATION)
def sense_sample(k, x, loop):
    """:func:`sense`, compiled on its own (called by :func:`closed_loop` and from Python for an
    estimator without a compiled step)."""
    sense(k, x, loop)


@njit(cache=True, inline="always")
def act(k, x, loop, q_est):
    """Sample ``k``, second half: :func:`fly_sample` or, before a throw flies, :func:`recover_sample`."""
    if loop.state[PHASE] >= FLYING:
        return fly_sample(k, x, loop, q_est)
    return recover_sample(k, x, loop)


@njit(cache=True, **NO_ALLOCATION)
def act_sample(k, x, loop, q_est):
    """:func:`act`, compiled on its own (called by :func:`closed_loop` with an estimator and from
    Python for an estimator without a compiled step)."""
    return act(k, x, loop, q_est)


@njit(cache=True, inline="always")
def flown(status, k):
    """The samples flown when a flight ends at sample ``k`` with ``status`` (a non-finite
    estimate ends it before sample ``k`` is recorded)."""
    return k if status == ESTIMATE_NAN else k + 1


def closed_loop(x, loop, estimator=None):
    """Fly ``len(loop.record.phase)`` IMU samples (module doc) from the state ``x`` with an
    estimator's compiled step in the loop (``estimator``: the step, its state, records,
    diagnostics and the declination quaternion) or none (the truth, or a throw's recovery,
    makes the estimate). Returns ``(status, samples flown)``."""
    if estimator is None:
        return _fly_without_estimator(x, loop)
    return _fly_with_estimator(x, loop, *estimator)


@njit(cache=True, **NO_ALLOCATION)
def _fly_without_estimator(x, loop):
    """The loop with both halves inlined, compiled once and cached: a call passes the loop's
    records field by field, and the two calls per sample cost more than the flight itself
    (1.0 against 2.9 µs a step of the truth-only SE(3) flight)."""
    n = loop.record.phase.shape[0]
    for k in range(n):
        sense(k, x, loop)
        status = act(k, x, loop, loop.nav.q_est)
        if status != OK:
            return status, flown(status, k)
    return OK, n


@njit(**NO_ALLOCATION)
def _fly_with_estimator(x, loop, est_step, ex, ep, ec, ediag, dq):
    """The loop with the compiled step ``est_step`` of an estimator (its state ``ex``, records
    ``ep``, ``ec``, diagnostics ``ediag``; ``dq`` the declination quaternion). Not cached (it
    takes a function): numba compiles it once per estimator and process, so its halves stay
    calls to their cached compiled code."""
    n = loop.record.phase.shape[0]
    for k in range(n):
        sense_sample(k, x, loop)
        q = estimate(k, loop, est_step, ex, ep, ec, ediag, dq)
        status = act_sample(k, x, loop, q)
        if status != OK:
            return status, flown(status, k)
    return OK, n


@njit(inline="always")
def estimate(k, loop, est_step, ex, ep, ec, ediag, dq):
    """The estimator's step of sample ``k`` (:func:`_fly_with_estimator`'s arguments) and the
    geographic attitude it gives, ``loop.nav.q_est``."""
    q, sensing, gyr = loop.nav.q_est, loop.sensing, loop.nav.clip.gyr
    if k == loop.nav.reset_k:
        copy_into(ex, loop.nav.reset_x)  # a collision's reset to nonsense
    est_step(ex, ep, ec, gyr, sensing.acc, sensing.mag, sensing.dt, ediag)
    # q = dq ⊗ q_est (the declination turns the magnetic frame into the geographic one)
    q[0], q[1], q[2], q[3] = qmul_s(dq[0], dq[1], dq[2], dq[3], ex[0], ex[1], ex[2], ex[3])
    return q


@njit(**NO_ALLOCATION)
def estimate_sample(k, loop, est_step, ex, ep, ec, ediag, dq):
    """:func:`estimate`, compiled on its own for a loop run from Python (:mod:`quadest.flight.plant`):
    the attitude into ``loop.nav.q_est``."""
    estimate(k, loop, est_step, ex, ep, ec, ediag, dq)


@njit(cache=True, **NO_ALLOCATION)
def plant_truth_sample(k, x, loop):
    """:func:`plant_truth`, compiled on its own (the compiled vehicle as a :class:`~quadest.flight.plant.Plant`)."""
    plant_truth(k, x, loop)


@njit(cache=True, **NO_ALLOCATION)
def advance_sample(k, x, loop):
    """:func:`advance`, compiled on its own (the compiled vehicle as a :class:`~quadest.flight.plant.Plant`)."""
    return advance(k, x, loop)


@njit(cache=True, **NO_ALLOCATION)
def ended_sample(x, loop):
    """:func:`ended` of the state ``x``, compiled on its own."""
    return ended(x, loop.plant)
