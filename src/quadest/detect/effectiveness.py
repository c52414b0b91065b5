"""Rotor-failure detection and isolation: a Kalman filter on each rotor's effectiveness, and a
sequential test on what it finds (docs/detection.md).

The filter's state is the body rate ``ω`` and each rotor's effectiveness ``η_i`` (1 intact, 0
lost). Between samples the rate follows the detector's model of the vehicle (docs/detection.md
has the inflow and rotor-drag terms)::

    J ω̇ = Σ_i η_i k_f Ω_i² g_i − ω × J ω − D ω − C_r |ω| ω,   g_i = (−r_iy, r_ix, −s_i k_m/k_f)

with ``Ω_i`` the rotor speeds (measured, or from the commands through the detector's motor
model), and the effectiveness walks randomly. The gyroscope measures ``ω``; the
accelerometer's z measures ``−Σ η_i k_f Ω_i² / m``. Both are linear in the state given the
rotor speeds and the measured rate, so the filter is a linear Kalman filter, updated one scalar
at a time. The accelerometer is read at the centre of mass: what its lever arm adds is taken out
first (``lever_arm``, the IMU's position given).

The yaw moment of the rotors' drag as the vehicle moves through the air is read from the
accelerometer's x and y (``air_drag``). The rotors' moment about each axis is scaled by what
the flight shows of it against the model (``moment_scale_s``: inertia, mass and thrust
coefficient are never known exactly). Each rotor's deficit ``d_i`` is the mean effectiveness
of the others minus its own, relative to theirs (a common error of ``k_f`` or of the mass
moves every ``η`` alike and cancels). Two CUSUM tests
(Page 1954) accumulate it: ``S_i ← max(0, S_i + Δt (d_i − ν))``; the rotor whose sum first
passes its threshold ``h`` is the one that failed. The test with the larger drift answers
"lost" (the fault-tolerant controller takes over), the one with the smaller drift "damaged".
Beside them a fast test (``glr``) reads a loss's first samples directly: a generalised
likelihood ratio of each rotor lost at the start of each of the last few samples' windows.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from quadest._jit import NO_ALLOCATION, njit
from quadest.conventions import GRAVITY
from quadest.records import Params, check, layout, pack, param, params_record

if TYPE_CHECKING:
    from quadest.models.multirotor import MultirotorParams

MAX_ROTORS = 8
H_TAU = 0.004  # s: the low-pass of the rotors' momentum whose change the model reads (chosen: two samples at 500 Hz)
F_TAU = 0.02  # s: the low-pass of the accelerometer's x and y for the rotors' drag (chosen: above vibration)
NS = 3 + MAX_ROTORS  # the filter's largest state: rate and effectiveness
GLR_MAX = 32  # samples: the longest window of the fast test
ROW = layout(  # one sample in the fast test's ring
    ("gyr", 3),
    ("base", 3),  # the rate change without the rotors
    ("b", 3 * MAX_ROTORS),  # the rate change per unit effectiveness, ``b + j·MAX_ROTORS + i``
    ("thrust", MAX_ROTORS),  # thrust per mass per unit effectiveness (right after ``b``: its fourth row)
    ("eta", MAX_ROTORS),
    ("acc_z", 1),
)
GLR_ROW = ROW.end
STATE = layout(
    ("w", 3),
    ("eta", MAX_ROTORS),
    ("P", NS * NS),
    ("omega", MAX_ROTORS),  # the rotor speeds over the last interval (root mean square)
    ("omega_end", MAX_ROTORS),  # at its end
    ("s_lost", MAX_ROTORS),
    ("s_damaged", MAX_ROTORS),
    ("init", 1),
    ("time", 1),
    ("lost", 1),  # the rotor found lost (-1: none), the time, the effectiveness left
    ("lost_t", 1),
    ("lost_eta", 1),
    ("damaged", 1),
    ("damaged_t", 1),
    ("damaged_eta", 1),
    ("gyr_prev", 6),  # the last two gyroscope readings, then the estimate of its noise's variance per axis
    ("gyr_var", 3),
    ("samples", 1),
    ("contact_t", 1),  # when the accelerometer last read a push the rotors cannot make (-inf: never)
    ("landed", 1),  # 1 from a contact until the rotors carry the weight again
    ("cut_t", 1),  # when rotors were last commanded at their lowest speed together (-inf: never)
    ("h_lp", MAX_ROTORS),  # each rotor's angular momentum I_p s_i Ω_i, low-passed over H_TAU
    ("f_lp", 2),  # the accelerometer's x and y less the yaw rate's rotor drag, low-passed over F_TAU
    ("glr", GLR_MAX * GLR_ROW),  # the fast test's ring of the last samples
    ("glr_n", 1),  # samples in it
    ("glr_head", 1),  # the slot of the next one
    ("glr_r", 4),  # scratch of the fast test: sums over its window (below)
    ("glr_sig", 4 * MAX_ROTORS),
    ("B", 3 * MAX_ROTORS),  # scratch of one step: the input matrix, F P's rows, P h, h
    ("FP", 3 * NS),
    ("ph", NS),
    ("h", NS),
    ("scale", 3),  # the rotors' moment per axis against the model's, learnt in flight (1: the model's)
    ("scale_y", 6),  # per axis, the measured rate change less the model's without the rotors, low-passed
    ("scale_u", 6),  # over SCALE_LP and that over SCALE_HP; the rotors' modelled rate change, the same
    ("scale_sums", 6),  # Σ y u, then Σ u u, per axis, over the scale's memory
    ("alpha", 3),  # scratch of one step: the model's angular acceleration over the interval
    ("acc_cg", 3),  # and the accelerometer's reading moved to the centre of mass
    ("thrust", MAX_ROTORS),  # and each intact rotor's thrust at its speed over the interval (N)
)
SCALE_LP = 0.02  # s: above the gyroscope's noise and the rotors' tone (chosen)
SCALE_HP = 1.0  # s: below the manoeuvres; what the model misses steadily (wind, trim) is left out (chosen)
SCALE_RANGE = 0.3  # the learnt scale stays within 1 ± this: the model within 30 %
SCALE_RATE = 0.03  # 1/s: the fastest it moves (a loss's moments before it is found move it 0.3 % in 0.1 s)
MODEL = layout(
    ("rotors", 1),
    ("mass", 1),
    ("inertia", 3),
    ("k_f", 1),
    ("k_z", 1),
    ("k_h", 1),
    ("tau", 1),
    ("omega_min", 1),
    ("omega_max", 1),
    ("omega_dot_max", 1),
    ("damping", 3),
    ("rot_drag", 3),
    ("g", 3 * MAX_ROTORS),  # per rotor: the moment per unit thrust
    ("ip_s", MAX_ROTORS),  # per rotor: its inertia times its sense, I_p s_i (the rotors' momentum per speed)
    ("body_drag", 2),  # the body's quadratic drag along x and y
    ("imu", 3),  # the accelerometer's position from the centre of mass (body, m)
)


@dataclass(frozen=True)
class DetectorParams(Params):
    rotor_speeds: bool = param(
        True,
        "-",
        "the rotor speeds are measured (ESC telemetry); otherwise they follow from the commands "
        "through the detector's motor model",
    )
    gyro_noise: float = param(
        0.02,
        "rad/s",
        "gyroscope noise with vibration, per sample",
        "chosen: the presets' noise and vibration",
        "(0, 10]",
    )
    noise_window_s: float = param(
        0.2,
        "s",
        "the gyroscope's noise (with the rotors' vibration) is estimated over about this window from its "
        "second difference, and used when larger than gyro_noise (0: gyro_noise only)",
        "chosen: vibration changes with the rotor speeds within a second",
        "[0, 100]",
    )
    acc_noise: float = param(
        1.0, "m/s²", "accelerometer z noise with vibration, per sample", "chosen: the presets' vibration", "(0, 100]"
    )
    moment_noise: float = param(
        8.0,
        "rad/s²",
        "angular acceleration the model misses (inertia and thrust errors, aerodynamics)",
        "chosen: 10 % of the 80 rad/s² of aggressive flight",
        "(0, 1e4]",
    )
    model_error: float = param(
        0.15,
        "-",
        "relative error of the modelled roll and pitch moments (inertia, thrust coefficient)",
        "chosen: the ±10 % model errors the campaign draws, with margin",
        "[0, 10]",
    )
    yaw_model_error: float = param(
        0.3,
        "-",
        "relative error of the modelled yaw moment (drag torque coefficient, rotor drag)",
        "chosen: the yaw moment is the least known",
        "[0, 10]",
    )
    eta_walk: float = param(
        1.5,
        "1/√s",
        "random walk of a rotor's effectiveness",
        "chosen on training seeds 0-35 (3.0 before the disturbed flights)",
        "(0, 1e3]",
    )
    deficit_sd_ratio: float = param(
        2.0,
        "-",
        "a rotor's deficit counts only while the deviation of its effectiveness is below this "
        "many times the best-known rotor's (a rotor turning slowly shows little of its effectiveness)",
        "chosen",
        "[1, 100]",
    )
    weighted_others: bool = param(
        True,
        "-",
        "a rotor's deficit is against the others' effectiveness weighted by how well each is known (else "
        "their plain mean)",
        "measured: near-idle rotors' wandering effectiveness made the false alarms of saturated manoeuvres",
    )
    deficit_sigmas: float = param(
        0.0,
        "-",
        "a rotor's deficit counts only beyond this many of its standard deviations (0: always); "
        "for logs, whose rates and noise leave the effectiveness uncertain",
        "chosen: 0 in flight (the fast sensors make it certain), 3 for logs",
        "[0, 100]",
    )
    contact_margin: float = param(
        5.0,
        "m/s²",
        "a contact (the ground, an impact) is a specific force along −z beyond 1.3 times what the intact "
        "rotors make plus this; the tests hold during it, contact_hold_s after, and until the intact rotors "
        "make 0.9 g again (a vehicle standing on the ground: landed) (0: never)",
        "chosen: above the model's ±10 % thrust and mass error, the accelerometer's tone and a lost rotor's drop",
        "[0, 1000]",
    )
    contact_hold_s: float = param(
        0.5,
        "s",
        "the tests hold this long after a contact",
        "chosen: a touchdown's bounce settles within it",
        "[0, 100]",
    )
    cut_rotors: float = param(
        2.0,
        "-",
        "a thrust cut: the tests hold while at least this many rotors are commanded at their lowest speed, "
        "and cut_hold_s after (0: never)",
        "measured on training seeds: each alarm where a landing started (nominal 6000-6599) came within 50 ms "
        "of two or three rotors commanded to idle; the hold moved no alarm of a complete loss (0-399) "
        "(docs/detection.md)",
        "[0, 8]",
    )
    cut_hold_s: float = param(
        0.1,
        "s",
        "the tests hold this long after a thrust cut",
        "chosen on training seeds: of 0.05 and 0.1, the shorter without an alarm where a landing starts "
        "(at the edge for one flight: docs/detection.md)",
        "[0, 100]",
    )
    air_drag: bool = param(
        True,
        "-",
        "the yaw moment of each rotor's drag as the vehicle moves through the air, read from the "
        "accelerometer's x and y (their specific force is the rotors' and the body's drag: docs/detection.md)",
        "measured on training seeds, beside relative_deficit: alarms 2 / 1 against 3 / 5 in 12 h (rotor speeds / "
        "commands), 288 against 287 of 300 losses up, p99 delay 56 against 64 ms; alone, 283 up (docs/detection.md)",
    )
    relative_deficit: bool = param(
        True,
        "-",
        "a rotor's deficit is relative to the others' effectiveness, (η̄ − η_i) / max(η̄, 0.5), so that an error "
        "common to every rotor (thrust coefficient, mass, the vehicle's own inflow), which scales every η alike, "
        "leaves a lost rotor's deficit at 1; else the plain difference η̄ − η_i, which that error scales",
        "measured on training seeds: alone, losses found sooner (p90 41 against 61 ms) and more alarms with the "
        "commands (5 against 2 in 12 h); with air_drag, fewer alarms and sooner (docs/detection.md)",
    )
    glr: bool = param(
        True,
        "-",
        "a fast test beside the 'lost' CUSUM: over the last samples, the gyroscope's change and the "
        "accelerometer's z against the model with the effectiveness before them, a generalised likelihood "
        "ratio for each rotor lost when they began (docs/detection.md, The fast test)",
        "measured on training seeds: losses found in 17 against 24 ms (median), 292 against 288 of 300 up, "
        "no alarm added in 12 h (docs/detection.md)",
    )
    glr_window_s: float = param(
        0.02, "s", "the fast test's longest window (each shorter one down to 3 samples is tried too; at most "
        "31 samples, the ring's: 15.5 ms at 2 kHz)",
        "chosen: a loss's rate change passes the model's unmodelled acceleration within 10-20 ms", "(0, 0.06]",
    )  # fmt: skip
    glr_threshold: float = param(
        150.0,
        "-",
        "the fast test's threshold on twice its log-likelihood ratio",
        "chosen on training seeds: about 1.5 times the largest in 12 h of nominal flight in either mode (103; "
        "docs/detection.md)",
        "(0, 1e12]",
    )
    glr_min_loss: float = param(
        0.7, "-", "the share of the rotor's contribution the fast test must find gone to name it",
        "chosen: above the 'lost' test's drift (0.6)", "(0, 10]",
    )  # fmt: skip
    glr_margin: float = param(
        4.0,
        "-",
        "the fast test names a rotor only when its ratio is this many times the next rotor's",
        "chosen",
        "[1, 1e12]",
    )
    moment_scale_s: float = param(
        10.0,
        "s",
        "memory of the rotors' moment per axis learnt in flight against the detector's model (inertia, mass, "
        "thrust coefficient off), by least squares on the band-passed rate change (0: the model as given)",
        "chosen on training seeds: alarms in 12 h of nominal flight 1 / 0 (rotor speeds / commands) against 2 / 1 "
        "without, the losses' delays alike (docs/detection.md, The moment learnt in flight)",
        "[0, 1e4]",
    )
    moment_scale_prior: float = param(
        5.0,
        "rad/s²",
        "the learnt moment stays near the model's until the modelled angular acceleration, band-passed, passes "
        "about this RMS over the memory (a hover's corrections of its own disturbances would bias it low)",
        "chosen on five training flights: 2 biased the hovers' scale 3-9 % lower",
        "(0, 1e4]",
    )
    lever_arm: bool = param(
        True,
        "-",
        "remove from the accelerometer's reading what its place off the centre of mass adds (the IMU's position "
        "given to the detector; off: the reading taken as the centre of mass's)",
        "measured: docs/detection.md, The accelerometer's place",
    )
    lost_drift: float = param(0.6, "-", "deficit the 'lost' test ignores (ν)", "chosen: above a 50 % loss", "(0, 1]")
    lost_threshold: float = param(
        0.004,
        "s",
        "the 'lost' test's threshold (h, deficit-seconds)",
        "chosen on training seeds 0-399 and nominal 0-119 (the smallest without an alarm in either mode, with the "
        "thrust-cut hold; 0.008 before it; docs/detection.md)",
        "(0, 10]",
    )
    damaged_drift: float = param(
        0.15,
        "-",
        "deficit the 'damaged' test ignores (ν)",
        "chosen: half the smallest loss looked for (30 %)",
        "(0, 1]",
    )
    damaged_threshold: float = param(
        0.02, "s", "the 'damaged' test's threshold (h)", "chosen: tuned on training seeds", "(0, 100]"
    )


PARAM = Record = params_record(DetectorParams)
DIAG = MAX_ROTORS + 4
"""A step's diagnostics: each rotor's effectiveness (``MAX_ROTORS`` slots), then the largest
'lost' sum and its rotor, the largest 'damaged' sum and its rotor (the tests' statistics)."""
STAT = MAX_ROTORS


def model_coefficients(vehicle, imu_position=(0.0, 0.0, 0.0)) -> np.ndarray:
    """The detector's model of a vehicle (a :class:`~quadest.models.multirotor.MultirotorParams`:
    the detector's own, never the simulated truth's) and of where its accelerometer sits
    (``imu_position``, m from the centre of mass, body axes) packed for the compiled step."""
    pos, spin = np.asarray(vehicle.rotor_pos, float), np.asarray(vehicle.spin, float)
    n = len(pos)
    if not 2 <= n <= MAX_ROTORS:
        raise ValueError(f"detector: {n} rotors; it handles 2 to {MAX_ROTORS}")
    g = np.zeros((MAX_ROTORS, 3))
    g[:n] = np.column_stack([-pos[:, 1], pos[:, 0], -spin * vehicle.k_m / vehicle.k_f])
    values = [n, vehicle.mass_kg, *vehicle.inertia, vehicle.k_f, vehicle.k_z, vehicle.k_h, vehicle.motor_tau_s]
    values += [vehicle.omega_min]
    values += [vehicle.omega_max, vehicle.omega_dot_max, *vehicle.damping, *vehicle.rot_drag, *g.ravel()]
    ip_s = np.zeros(MAX_ROTORS)
    ip_s[:n] = vehicle.rotor_inertia * spin
    imu = np.asarray(imu_position, float)
    if imu.shape != (3,) or not np.isfinite(imu).all():
        raise ValueError(f"detector: imu_position must be three finite values (m), got {imu_position!r}")
    return pack(values + list(ip_s) + list(vehicle.body_drag[:2]) + list(imu))


@njit(cache=True, inline="always")
def motor_step(omega, cmd, c, dt):
    """The detector's motor model: first order with its time constant, speed and rate limits."""
    target = min(max(cmd, c[MODEL.omega_min]), c[MODEL.omega_max])
    rate = (target - omega) / c[MODEL.tau]
    lim = c[MODEL.omega_dot_max]
    return omega + dt * min(max(rate, -lim), lim)


@njit(cache=True, inline="always")
def _thrust(c, om, w0, w1, gx, gy):
    """An intact rotor's thrust at speed ``om`` on a body turning at ``(w0, w1)``: ``k_f Ω² + k_z Ω
    u_z`` with the hub's axial speed from the rotation, ``u_z = ω_x r_y − ω_y r_x`` (the
    vehicle's own velocity is not known here: it moves every rotor alike)."""
    return c[MODEL.k_f] * om * om + c[MODEL.k_z] * om * (-w0 * gx - w1 * gy)


@njit(cache=True, inline="always")
def body_moments(c, w0, w1, w2):
    """The moments on the body turning at ``ω`` other than the rotors': the gyroscopic
    ``−ω × J ω`` and the quadratic drag ``−C_r |ω| ω`` (the linear damping ``D ω`` is applied by
    the caller)."""
    J0, J1, J2 = c[MODEL.inertia], c[MODEL.inertia + 1], c[MODEL.inertia + 2]
    m0 = -(w1 * J2 * w2 - w2 * J1 * w1) - c[MODEL.rot_drag] * abs(w0) * w0
    m1 = -(w2 * J0 * w0 - w0 * J2 * w2) - c[MODEL.rot_drag + 1] * abs(w1) * w1
    m2 = -(w0 * J1 * w1 - w1 * J0 * w0) - c[MODEL.rot_drag + 2] * abs(w2) * w2
    return m0, m1, m2


@njit(cache=True, inline="always")
def rotor_thrust_yaw(c, i, om, w0, w1, w2):
    """Intact rotor ``i`` at speed ``om`` on a body turning at ``ω``: its thrust (:func:`_thrust`;
    its roll and pitch moments are ``thrust · (g_x, g_y)``) and its yaw moment, the reaction
    torque and the rotor drag of the hub's in-plane speed ``ω_z × r_i``."""
    gx, gy, gz = c[MODEL.g + 3 * i], c[MODEL.g + 3 * i + 1], c[MODEL.g + 3 * i + 2]
    thrust = _thrust(c, om, w0, w1, gx, gy)
    yaw = c[MODEL.k_f] * om * om * gz - c[MODEL.k_h] * om * w2 * (gx * gx + gy * gy)  # reaction, rotor drag
    return thrust, yaw


@njit(cache=True, inline="always")
def _start(x, p, c, gyr, rotors):
    """The first sample: the rate from the gyroscope, every rotor intact, the speeds read."""
    n = int(c[MODEL.rotors])
    ns = 3 + n
    for i in range(NS * NS):
        x[STATE.P + i] = 0.0
    for j in range(3):
        x[STATE.w + j] = gyr[j]
        x[STATE.P + j * ns + j] = p[PARAM.gyro_noise] ** 2
    for i in range(n):
        x[STATE.eta + i] = 1.0
        x[STATE.P + (3 + i) * ns + 3 + i] = 0.01  # intact within ±10 % at the start
        x[STATE.omega + i] = x[STATE.omega_end + i] = rotors[i]
        x[STATE.h_lp + i] = c[MODEL.ip_s + i] * rotors[i]
        x[STATE.s_lost + i] = 0.0
        x[STATE.s_damaged + i] = 0.0
    x[STATE.lost] = x[STATE.damaged] = -1.0
    x[STATE.contact_t] = -np.inf
    for j in range(3):
        x[STATE.scale + j] = 1.0


@njit(cache=True, inline="always")
def _air_drag_per_speed(x, p, c, n):
    """The rotors' drag as the vehicle moves through the air (docs/detection.md): rotor ``i``'s
    yaw moment is ``−k_h η_i Ω_i (r_x u_y − r_y u_x)`` with ``u`` the body's velocity in the
    air, and the accelerometer reads the rotors' drag with the body's, ``m f_xy = −(k_h Σ_j η_j
    Ω_j + c |u|) u_xy``. So the moment is ``s m Ω_i (g_x f_x + g_y f_y) / Σ_j η_j Ω_j`` with ``s``
    the rotors' share of the drag at that speed. Returns ``f_x, f_y`` and ``s m / Σ_j η_j Ω_j``
    (zero when off, or without rotor drag in the model)."""
    if p[PARAM.air_drag] == 0.0:
        return 0.0, 0.0, 0.0
    total = 0.0
    for j in range(n):
        total += max(x[STATE.eta + j], 0.0) * x[STATE.omega + j]
    fx, fy = x[STATE.f_lp], x[STATE.f_lp + 1]
    rotors = c[MODEL.k_h] * total  # the rotors' drag per unit speed
    if rotors <= 0.0:
        return 0.0, 0.0, 0.0
    body = 0.5 * (c[MODEL.body_drag] + c[MODEL.body_drag + 1])
    force = c[MODEL.mass] * np.sqrt(fx * fx + fy * fy)
    speed = force / rotors if body <= 0.0 else (np.sqrt(rotors * rotors + 4.0 * body * force) - rotors) / (2.0 * body)
    share = rotors / (rotors + body * speed)
    return fx, fy, share * c[MODEL.mass] / total


@njit(cache=True, inline="always")
def _predict(x, p, c, gyr, dt):
    """``ω`` over the interval with the mean squared speed over it (``STATE.omega`` holds
    ``√(½(Ω²_begin + Ω²_end))``); ``P ← F P Fᵀ + Q``."""
    n = int(c[MODEL.rotors])
    B, FP = STATE.B, STATE.FP  # offsets into x
    w0, w1, w2 = gyr[0], gyr[1], gyr[2]  # the measured rate for the gyroscopic and drag terms
    J0, J1, J2 = c[MODEL.inertia], c[MODEL.inertia + 1], c[MODEL.inertia + 2]
    m0, m1, m2 = body_moments(c, w0, w1, w2)
    fx, fy, spread = _air_drag_per_speed(x, p, c, n)
    # B[j, i]: the rate change over dt per unit effectiveness of rotor i
    for i in range(n):
        om = x[STATE.omega + i]
        gx, gy = c[MODEL.g + 3 * i], c[MODEL.g + 3 * i + 1]  # gx = −r_y, gy = r_x
        thrust, yaw = rotor_thrust_yaw(c, i, om, w0, w1, w2)
        x[STATE.thrust + i] = thrust
        yaw += spread * om * (gx * fx + gy * fy)
        # the rotor's inertia: its gyroscopic moment −ω × (I_p s_i Ω_i e_z) and the reaction to its
        # acceleration, from its speed low-passed over H_TAU (speed readings with 1 % noise,
        # differentiated per sample, would give noise larger than the yaw moment)
        h = c[MODEL.ip_s + i] * x[STATE.omega_end + i]
        h_before = x[STATE.h_lp + i]
        x[STATE.h_lp + i] = h_before + min(dt / H_TAU, 1.0) * (h - h_before)
        x[B + i] = dt * thrust * gx / J0 - dt * w1 * h / J0
        x[B + MAX_ROTORS + i] = dt * thrust * gy / J1 + dt * w0 * h / J1
        x[B + 2 * MAX_ROTORS + i] = dt * yaw / J2 - (x[STATE.h_lp + i] - h_before) / J2
    a = (1.0 - dt * c[MODEL.damping] / J0, 1.0 - dt * c[MODEL.damping + 1] / J1, 1.0 - dt * c[MODEL.damping + 2] / J2)
    base = (dt * m0 / J0, dt * m1 / J1, dt * m2 / J2)
    if p[PARAM.moment_scale_s] > 0.0:
        _learn_moment_scale(x, p, c, gyr, a, base, dt)
    rel = (p[PARAM.model_error], p[PARAM.model_error], p[PARAM.yaw_model_error])
    floor = (p[PARAM.moment_noise] * dt) ** 2
    for j in range(3):
        rotors_part = 0.0
        for i in range(n):
            rotors_part += x[B + j * MAX_ROTORS + i] * x[STATE.eta + i]
        change = (a[j] - 1.0) * x[STATE.w + j] + base[j] + rotors_part
        x[STATE.w + j] += change
        x[STATE.alpha + j] = change / dt
        x[FP + j] = floor + (rel[j] * rotors_part) ** 2  # the model's error grows with the moment
    _propagate_covariance(x, p, n, a, dt)


@njit(cache=True, inline="always")
def _propagate_covariance(x, p, n, a, dt):
    """``P ← F P Fᵀ + Q`` with ``F = [[diag(a), B], [0, I]]`` (``B`` and the rate's process
    noise, ``FP``'s first three values, as :func:`_predict` left them): rows 0-2 of ``F P``,
    then ``(F P) Fᵀ``, the rate's three rows summed together (three independent sums in flight)."""
    ns = 3 + n
    P, B, FP = STATE.P, STATE.B, STATE.FP
    q0, q1, q2 = x[FP], x[FP + 1], x[FP + 2]
    for col in range(ns):
        s0, s1, s2 = a[0] * x[P + col], a[1] * x[P + ns + col], a[2] * x[P + 2 * ns + col]
        for i in range(n):
            pc = x[P + (3 + i) * ns + col]
            s0 += x[B + i] * pc
            s1 += x[B + MAX_ROTORS + i] * pc
            s2 += x[B + 2 * MAX_ROTORS + i] * pc
        x[FP + col], x[FP + NS + col], x[FP + 2 * NS + col] = s0, s1, s2
    for r in range(ns):  # (F P Fᵀ)[j, r] = (F P)[j, :] · F[r, :]
        if r < 3:
            s0, s1, s2 = a[r] * x[FP + r], a[r] * x[FP + NS + r], a[r] * x[FP + 2 * NS + r]
            for i in range(n):
                br = x[B + r * MAX_ROTORS + i]
                s0 += x[FP + 3 + i] * br
                s1 += x[FP + NS + 3 + i] * br
                s2 += x[FP + 2 * NS + 3 + i] * br
        else:
            s0, s1, s2 = x[FP + r], x[FP + NS + r], x[FP + 2 * NS + r]
        for j, v in ((0, s0), (1, s1), (2, s2)):
            # within the rate's block both (j, r) and (r, j) are computed and differ by rounding:
            # the one from the larger row is kept, as the row-by-row loop before left it
            if r >= 3 or j >= r:
                x[P + j * ns + r] = v
                x[P + r * ns + j] = v
    qe = p[PARAM.eta_walk] ** 2 * dt
    x[P] += q0
    x[P + ns + 1] += q1
    x[P + 2 * ns + 2] += q2
    for i in range(n):
        x[P + (3 + i) * ns + 3 + i] += qe


@njit(cache=True, inline="always")
def _learn_moment_scale(x, p, c, gyr, a, base, dt):
    """The rotors' moment per axis against the model's (docs/detection.md, The moment learnt in
    flight): the measured rate change less the model's without the rotors against the rotors'
    modelled change at their common effectiveness, both band-passed, by least squares with a
    fading memory and a prior at 1; the rows of ``B`` (unscaled on entry) scaled by it."""
    n = int(c[MODEL.rotors])
    common = 0.0
    for i in range(n):
        common += x[STATE.eta + i]
    common = min(max(common / n, 0.5), 1.5)
    fast, slow = min(dt / SCALE_LP, 1.0), min(dt / SCALE_HP, 1.0)
    keep = 1.0 - min(dt / p[PARAM.moment_scale_s], 1.0)
    prior = (p[PARAM.moment_scale_prior] * dt) ** 2 * p[PARAM.moment_scale_s] / dt
    step = SCALE_RATE * dt  # the most it moves in a sample: a model's error is steady, a loss is sudden
    valid = x[STATE.samples] >= 2.0  # the last reading is there
    learn = valid and x[STATE.lost] < 0.0 and not _holding(x, p)
    for i in range(n):  # a deficit past the 'lost' drift: maybe a loss, whose moments are not the model's
        learn = learn and x[STATE.s_lost + i] == 0.0
    Y, U, S = STATE.scale_y, STATE.scale_u, STATE.scale_sums
    for j in range(3):
        if valid:
            before = x[STATE.gyr_prev + 3 + j]
            y = gyr[j] - before - (a[j] - 1.0) * before - base[j]
            u = 0.0
            for i in range(n):
                u += x[STATE.B + j * MAX_ROTORS + i]
            x[Y + j] += fast * (y - x[Y + j])
            x[Y + 3 + j] += slow * (x[Y + j] - x[Y + 3 + j])
            x[U + j] += fast * (common * u - x[U + j])
            x[U + 3 + j] += slow * (x[U + j] - x[U + 3 + j])
        if learn:
            yb, ub = x[Y + j] - x[Y + 3 + j], x[U + j] - x[U + 3 + j]
            x[S + j] = keep * x[S + j] + yb * ub
            x[S + 3 + j] = keep * x[S + 3 + j] + ub * ub
            slope = (x[S + j] + prior) / (x[S + 3 + j] + prior)
            paced = min(max(slope, x[STATE.scale + j] - step), x[STATE.scale + j] + step)
            x[STATE.scale + j] = min(max(paced, 1.0 - SCALE_RANGE), 1.0 + SCALE_RANGE)
        scale = x[STATE.scale + j]
        for i in range(n):
            x[STATE.B + j * MAX_ROTORS + i] *= scale


@njit(cache=True, inline="always")
def _holding(x, p):
    """The tests hold: on the ground, within ``contact_hold_s`` of a contact or ``cut_hold_s``
    of a thrust cut."""
    if x[STATE.landed] != 0.0 or x[STATE.time] - x[STATE.contact_t] <= p[PARAM.contact_hold_s]:
        return True
    return x[STATE.time] - x[STATE.cut_t] <= p[PARAM.cut_hold_s]


@njit(cache=True, inline="always")
def _update_thrust(x, ns, z, r):
    """Scalar Kalman update with the measurement row ``x[STATE.h:]`` (``ns`` values, zero on the
    rate: the accelerometer's z reads the effectiveness only), value ``z``, variance ``r``. The
    state's rate and effectiveness are contiguous (``STATE.w``)."""
    P, h, ph, w = STATE.P, STATE.h, STATE.ph, STATE.w
    for a in range(ns):
        v = 0.0
        for b in range(3, ns):
            v += x[P + a * ns + b] * x[h + b]
        x[ph + a] = v
    s = r
    pred = 0.0
    for a in range(3, ns):
        s += x[h + a] * x[ph + a]
        pred += x[h + a] * x[w + a]
    _apply_gain(x, ns, (z - pred) / s, s)


@njit(cache=True, inline="always")
def _update_rate(x, ns, j, z, r):
    """Scalar Kalman update with the gyroscope's axis ``j``, value ``z``, variance ``r``: the
    row is the unit vector, so ``P h`` is ``P``'s column ``j``."""
    P, ph = STATE.P, STATE.ph
    for a in range(ns):
        x[ph + a] = x[P + a * ns + j]
    s = x[P + j * ns + j] + r
    _apply_gain(x, ns, (z - x[STATE.w + j]) / s, s)


@njit(cache=True, inline="always")
def _apply_gain(x, ns, innovation_per_s, s):
    """The state moved by ``P h`` times the innovation over its variance ``s``, and ``P ← P −
    (P h)(P h)ᵀ / s`` on and above the diagonal, mirrored (``P`` is exactly symmetric on entry and
    stays so)."""
    P, ph, w = STATE.P, STATE.ph, STATE.w
    for a in range(ns):
        x[w + a] += x[ph + a] * innovation_per_s
    for a in range(ns):
        pa = x[ph + a]
        for b in range(a, ns):
            v = x[P + a * ns + b] - pa * x[ph + b] / s
            x[P + a * ns + b] = v
            x[P + b * ns + a] = v


@njit(cache=True, inline="always")
def _correct(x, p, c, gyr, acc):
    """The gyroscope's three rates and the accelerometer's z, moved to the centre of mass."""
    n = int(c[MODEL.rotors])
    ns = 3 + n
    h = STATE.h
    acc = _at_centre_of_mass(x, p, c, acc)
    rg = p[PARAM.gyro_noise] ** 2
    for j in range(3):
        _update_rate(x, ns, j, gyr[j], max(rg, x[STATE.gyr_var + j]))
    if np.isfinite(acc[2]):
        intact = 0.0
        for i in range(n):
            x[h + 3 + i] = -x[STATE.thrust + i] / c[MODEL.mass]
            intact -= x[h + 3 + i]
        margin = p[PARAM.contact_margin]
        if margin > 0.0 and -acc[2] > 1.3 * intact + margin:  # the ground pushes: the rotors cannot
            x[STATE.contact_t] = x[STATE.time]
            x[STATE.landed] = 1.0
        elif intact > 0.9 * GRAVITY:  # the rotors carry the weight again (lifted off)
            x[STATE.landed] = 0.0
        _update_thrust(x, ns, acc[2], p[PARAM.acc_noise] ** 2)


@njit(cache=True, inline="always")
def _at_centre_of_mass(x, p, c, acc):
    """The accelerometer's reading less what its place ``r`` off the centre of mass adds,
    ``α × r + ω × (ω × r)``, with the model's rate and angular acceleration over the interval
    (a gyroscope's difference would carry its rotors' tone, tens of rad/s² at a sample's
    spacing). Kept in ``STATE.acc_cg``: every later use reads it."""
    out = STATE.acc_cg
    if p[PARAM.lever_arm] == 0.0:
        for j in range(3):
            x[out + j] = acc[j]
        return x[out : out + 3]
    w0, w1, w2 = x[STATE.w], x[STATE.w + 1], x[STATE.w + 2]
    a0, a1, a2 = x[STATE.alpha], x[STATE.alpha + 1], x[STATE.alpha + 2]
    r0, r1, r2 = c[MODEL.imu], c[MODEL.imu + 1], c[MODEL.imu + 2]
    v0, v1, v2 = w1 * r2 - w2 * r1, w2 * r0 - w0 * r2, w0 * r1 - w1 * r0  # ω × r
    x[out] = acc[0] - (a1 * r2 - a2 * r1) - (w1 * v2 - w2 * v1)
    x[out + 1] = acc[1] - (a2 * r0 - a0 * r2) - (w2 * v0 - w0 * v2)
    x[out + 2] = acc[2] - (a0 * r1 - a1 * r0) - (w0 * v1 - w1 * v0)
    return x[out : out + 3]


@njit(cache=True, inline="always")
def gyro_noise_estimate(x, p, gyr, dt):
    """The gyroscope's noise variance per axis from its second difference, ``(g_k − 2 g_{k−1} +
    g_{k−2})² / 6`` (white noise's; the motion's share is its jerk times dt², negligible at IMU
    rates), averaged over ``noise_window_s`` (a running mean over the first window)."""
    x[STATE.samples] += 1.0
    k = x[STATE.samples]
    if p[PARAM.noise_window_s] > 0.0 and k >= 3.0:
        a = max(dt / p[PARAM.noise_window_s], 1.0 / (k - 2.0))
        for j in range(3):
            d2 = gyr[j] - 2.0 * x[STATE.gyr_prev + j] + x[STATE.gyr_prev + 3 + j]
            x[STATE.gyr_var + j] += a * (d2 * d2 / 6.0 - x[STATE.gyr_var + j])
    for j in range(3):
        x[STATE.gyr_prev + 3 + j] = x[STATE.gyr_prev + j]
        x[STATE.gyr_prev + j] = gyr[j]


@njit(cache=True, inline="always")
def _test(x, p, c, dt):
    """The two CUSUM tests on each rotor's deficit; the first alarm of each is kept."""
    n = int(c[MODEL.rotors])
    total = 0.0
    for i in range(n):
        total += x[STATE.eta + i]
    var_total = 0.0
    var_min = np.inf
    for i in range(n):
        var_total += x[STATE.P + (3 + i) * (3 + n) + 3 + i]
        var_min = min(var_min, x[STATE.P + (3 + i) * (3 + n) + 3 + i])
    sd_max = p[PARAM.deficit_sd_ratio] * np.sqrt(var_min)
    touching = _holding(x, p)
    for i in range(n):
        if touching:  # forces the rotor model has not, or a thrust cut: no evidence either way
            x[STATE.s_lost + i] = 0.0
            x[STATE.s_damaged + i] = 0.0
            continue
        others = _others(x, i, n) if p[PARAM.weighted_others] != 0.0 else (total - x[STATE.eta + i]) / (n - 1)
        var_i = x[STATE.P + (3 + i) * (3 + n) + 3 + i]
        scale = max(others, 0.5) if p[PARAM.relative_deficit] != 0.0 else 1.0
        d = (others - x[STATE.eta + i]) / scale if np.sqrt(var_i) < sd_max else 0.0  # too uncertain: no evidence
        k = p[PARAM.deficit_sigmas]
        if k > 0.0 and d * d * scale * scale < k * k * _deficit_variance(x, i, n):  # within its noise
            d = 0.0
        left = x[STATE.eta + i] / others if others > 0.0 else 0.0
        sl = max(0.0, x[STATE.s_lost + i] + dt * (d - p[PARAM.lost_drift]))
        sd = max(0.0, x[STATE.s_damaged + i] + dt * (d - p[PARAM.damaged_drift]))
        x[STATE.s_lost + i], x[STATE.s_damaged + i] = sl, sd
        if x[STATE.lost] < 0.0 and sl > p[PARAM.lost_threshold]:
            x[STATE.lost], x[STATE.lost_t], x[STATE.lost_eta] = i, x[STATE.time], left
        if x[STATE.damaged] < 0.0 and sd > p[PARAM.damaged_threshold]:
            x[STATE.damaged], x[STATE.damaged_t], x[STATE.damaged_eta] = i, x[STATE.time], left


@njit(cache=True, inline="always")
def _others(x, i, n):
    """The other rotors' effectiveness, each weighted by how well it is known (``1/P_jj``): a
    rotor turning slowly, whose effectiveness wanders, does not set the reference."""
    num = 0.0
    den = 0.0
    for j in range(n):
        if j != i:
            w = 1.0 / x[STATE.P + (3 + j) * (3 + n) + 3 + j]
            num += w * x[STATE.eta + j]
            den += w
    return num / den


@njit(cache=True, inline="always")
def _deficit_variance(x, i, n):
    """The variance of rotor ``i``'s deficit ``d_i = aᵀη``, ``a_j = 1/(n−1)`` for the others and
    −1 for itself: ``aᵀ P a`` (the effectivenesses are correlated: their differences are known
    far better than each one)."""
    ns = 3 + n
    total = 0.0
    for j in range(n):
        aj = -1.0 if j == i else 1.0 / (n - 1)
        for k in range(n):
            ak = -1.0 if k == i else 1.0 / (n - 1)
            total += aj * ak * x[STATE.P + (3 + j) * ns + 3 + k]
    return total


@njit(cache=True, inline="always")
def note_commands(x, p, c, cmd):
    """The speeds commanded over the interval that ends at the next step (rad/s): a thrust cut,
    ``cut_rotors`` or more at the lowest speed, holds the tests (the rotors are then far from the
    regime the model holds in: near idle, decelerating, in the inflow of the vehicle's own motion)."""
    need = p[PARAM.cut_rotors]
    if need <= 0.0:
        return
    at_min = 0
    for i in range(int(c[MODEL.rotors])):
        if cmd[i] <= c[MODEL.omega_min]:
            at_min += 1
    if at_min >= need:
        x[STATE.cut_t] = x[STATE.time]


@njit(cache=True, inline="always")
def _air_lowpass(x, c, acc, w2, dt):
    """The accelerometer's x and y without the rotors' drag from the body's yaw rate ``w2`` (the
    hubs' in-plane speed ``ω_z (g_x, g_y)``: ``m f_rot = −k_h ω_z Σ_j η_j Ω_j (g_x, g_y)_j``),
    low-passed over ``F_TAU``: the drag of the body's motion through the air. A missing reading
    keeps the last."""
    if not (np.isfinite(acc[0]) and np.isfinite(acc[1])):
        return
    rx = ry = 0.0
    for j in range(int(c[MODEL.rotors])):
        k = c[MODEL.k_h] * w2 * max(x[STATE.eta + j], 0.0) * x[STATE.omega + j] / c[MODEL.mass]
        rx += k * c[MODEL.g + 3 * j]
        ry += k * c[MODEL.g + 3 * j + 1]
    a = min(dt / F_TAU, 1.0)
    x[STATE.f_lp] += a * (acc[0] + rx - x[STATE.f_lp])
    x[STATE.f_lp + 1] += a * (acc[1] + ry - x[STATE.f_lp + 1])


@njit(cache=True, inline="always")
def _glr_store(x, p, c, gyr, acc, dt):
    """This sample into the fast test's ring: what :func:`_predict` made of it, per rotor, and η."""
    n = int(c[MODEL.rotors])
    row = STATE.glr + int(x[STATE.glr_head]) * GLR_ROW
    J = (c[MODEL.inertia], c[MODEL.inertia + 1], c[MODEL.inertia + 2])
    m = body_moments(c, gyr[0], gyr[1], gyr[2])
    for j in range(3):
        x[row + ROW.gyr + j] = gyr[j]
        x[row + ROW.base + j] = dt * (m[j] - c[MODEL.damping + j] * gyr[j]) / J[j]
        for i in range(n):
            x[row + ROW.b + j * MAX_ROTORS + i] = x[STATE.B + j * MAX_ROTORS + i]
    for i in range(n):
        x[row + ROW.thrust + i] = x[STATE.thrust + i] / c[MODEL.mass]
        x[row + ROW.eta + i] = x[STATE.eta + i]
    x[row + ROW.acc_z] = acc[2] if np.isfinite(acc[2]) else np.nan
    x[STATE.glr_head] = (x[STATE.glr_head] + 1.0) % GLR_MAX
    x[STATE.glr_n] = min(x[STATE.glr_n] + 1.0, GLR_MAX)


@njit(cache=True, inline="always")
def _glr_test(x, p, c, dt):
    """The fast test: for each window of the last 3 to ``glr_window_s`` of samples (each a time
    the loss may have begun), the gyroscope's change and the accelerometer's z against the model
    with every rotor at its effectiveness before the window; for each rotor the least-squares
    share ``μ`` of its contribution gone and twice the log-likelihood ratio ``(sᵀΣ⁻¹r)² / sᵀΣ⁻¹s``
    of that against none (Willsky & Jones 1976), the largest over windows and rotors."""
    n = int(c[MODEL.rotors])
    w_max = min(int(round(p[PARAM.glr_window_s] / dt)), GLR_MAX - 1, int(x[STATE.glr_n]) - 1)
    if w_max < 3 or x[STATE.lost] >= 0.0:
        return
    if _holding(x, p):
        return
    head = int(x[STATE.glr_head])  # the slot of the next sample: the last is head − 1, wrapped
    last = STATE.glr + _ring(head - 1) * GLR_ROW
    R, S = STATE.glr_r, STATE.glr_sig  # sums over the window: see below
    for j in range(4):
        x[R + j] = 0.0  # the rate change without the rotors (3), the accelerometer's z (1)
    for k in range(4 * MAX_ROTORS):  # per unit η of each rotor: its rate change (3), its thrust per mass
        x[S + k] = 0.0  # (as the ring's rows: ``S + j·MAX_ROTORS + i``)
    count = 0
    rel = (p[PARAM.model_error], p[PARAM.model_error], p[PARAM.yaw_model_error])
    g2 = p[PARAM.gyro_noise] ** 2
    g = (2.0 * max(g2, x[STATE.gyr_var]), 2.0 * max(g2, x[STATE.gyr_var + 1]), 2.0 * max(g2, x[STATE.gyr_var + 2]))
    best, who, share = 0.0, -1, 0.0
    for w in range(1, w_max + 1):  # the window of the last w samples
        row = STATE.glr + _ring(head - w) * GLR_ROW
        first = STATE.glr + _ring(head - w - 1) * GLR_ROW  # the sample before it
        eta0 = first + ROW.eta
        for j in range(3):
            x[R + j] += x[row + ROW.base + j]
        for k in range(3 * MAX_ROTORS):  # every slot, the absent rotors' zeros too: a fixed-length loop
            x[S + k] += x[row + ROW.b + k]  # the compiler vectorises (docs/detection.md, the fast test's cost)
        a = x[row + ROW.acc_z]
        if np.isfinite(a):
            count += 1
            x[R + 3] += a
            for k in range(3 * MAX_ROTORS, 4 * MAX_ROTORS):
                x[S + k] += x[row + ROW.b + k]  # ROW.thrust
        if w < 3:
            continue
        stat, rotor, runner_up, mu = _glr_rotors(x, p, n, w, dt, count, last, first, eta0, rel, g)
        if stat > best and mu > p[PARAM.glr_min_loss] and stat > p[PARAM.glr_margin] * runner_up:
            best, who, share = stat, rotor, mu
    if who >= 0 and best > p[PARAM.glr_threshold]:
        x[STATE.lost], x[STATE.lost_t] = who, x[STATE.time]
        x[STATE.lost_eta] = max(0.0, 1.0 - share)


@njit(cache=True, inline="always")
def _ring(k):
    """The ring's slot of sample index ``k`` (``k`` ≥ −GLR_MAX)."""
    return k + GLR_MAX if k < 0 else k


@njit(cache=True, inline="always")
def _glr_rotors(x, p, n, w, dt, count, last, first, eta0, rel, g):
    """One window of the fast test (:func:`_glr_test`'s sums; ``g`` twice the gyroscope's noise
    variance per axis): the largest ratio over the rotors, its rotor, the next rotor's ratio and
    the share ``μ`` of the best. A window whose residual ``rᵀΣ⁻¹r``, which bounds every rotor's
    ratio (Cauchy-Schwarz), stays below the threshold cannot fire: it returns no rotor, and the
    decision is the same."""
    R, S = STATE.glr_r, STATE.glr_sig
    # the rotors' rate change and thrust over the window at the effectiveness before it
    p0 = p1 = p2 = pred = 0.0
    for i in range(n):
        e = x[eta0 + i]
        p0 += x[S + i] * e
        p1 += x[S + MAX_ROTORS + i] * e
        p2 += x[S + 2 * MAX_ROTORS + i] * e
        pred += x[S + 3 * MAX_ROTORS + i] * e
    best, second, who, mu = 0.0, 0.0, -1, 0.0
    r0 = x[last + ROW.gyr] - x[first + ROW.gyr] - x[R] - p0
    r1 = x[last + ROW.gyr + 1] - x[first + ROW.gyr + 1] - x[R + 1] - p1
    r2 = x[last + ROW.gyr + 2] - x[first + ROW.gyr + 2] - x[R + 2] - p2
    m2 = (p[PARAM.moment_noise] * w * dt) ** 2
    i0 = 1.0 / (g[0] + m2 + (rel[0] * p0) ** 2)  # one over each residual's variance
    i1 = 1.0 / (g[1] + m2 + (rel[1] * p1) ** 2)
    i2 = 1.0 / (g[2] + m2 + (rel[2] * p2) ** 2)
    r3 = i3 = 0.0
    if count > 0:
        r3 = (x[R + 3] + pred) / count
        i3 = count / p[PARAM.acc_noise] ** 2
    bound = r0 * r0 * i0 + r1 * r1 * i1 + r2 * r2 * i2 + r3 * r3 * i3
    if bound < 0.99 * p[PARAM.glr_threshold]:
        return 0.0, -1, 0.0, 0.0
    per = 1.0 / max(count, 1)
    for i in range(n):
        e = x[eta0 + i]
        s0, s1, s2 = -x[S + i] * e, -x[S + MAX_ROTORS + i] * e, -x[S + 2 * MAX_ROTORS + i] * e
        s3 = x[S + 3 * MAX_ROTORS + i] * e * per
        a0, a1, a2, a3 = s0 * i0, s1 * i1, s2 * i2, s3 * i3
        num = a0 * r0 + a1 * r1 + a2 * r2 + a3 * r3
        den = a0 * s0 + a1 * s1 + a2 * s2 + a3 * s3
        if den <= 0.0 or num <= 0.0:
            continue
        llr = num * num / den
        if llr > best:
            best, second, who, mu = llr, best, i, num / den
        elif llr > second:
            second = llr
    return best, who, second, mu


@njit(cache=True, **NO_ALLOCATION)
def detect_step(x, p, c, gyr, acc, rotors, dt, diag):
    """One sample: gyroscope (rad/s), accelerometer (m/s²), each rotor's measured speed or the
    command it was given over the interval that ends here (rad/s, ``p.rotor_speeds``), the
    interval (s). ``diag``: each rotor's effectiveness.
    Returns the rotor found lost (-1: none yet)."""
    if not (dt > 0.0 and np.isfinite(gyr[0]) and np.isfinite(gyr[1]) and np.isfinite(gyr[2])):
        return int(x[STATE.lost])
    n = int(c[MODEL.rotors])
    if x[STATE.init] == 0.0:
        _start(x, p, c, gyr, rotors)
        _air_lowpass(x, c, acc, gyr[2], 1.0)  # from the first reading
        x[STATE.init] = 1.0
        for i in range(n):
            diag[i] = 1.0
        for j in range(4):
            diag[STAT + j] = 0.0
        return -1
    measured = p[PARAM.rotor_speeds] != 0.0
    if not measured:
        note_commands(x, p, c, rotors)
    for i in range(n):  # the speeds over the interval: √(½(Ω²_begin + Ω²_end)), Ω² being what thrust needs
        begin = x[STATE.omega_end + i]
        end = rotors[i] if measured else motor_step(begin, rotors[i], c, dt)
        x[STATE.omega + i] = np.sqrt(0.5 * (begin * begin + end * end))
        x[STATE.omega_end + i] = end
    gyro_noise_estimate(x, p, gyr, dt)
    _predict(x, p, c, gyr, dt)
    _correct(x, p, c, gyr, acc)
    acc = x[STATE.acc_cg : STATE.acc_cg + 3]
    _air_lowpass(x, c, acc, gyr[2], dt)
    x[STATE.time] += dt
    _test(x, p, c, dt)
    if p[PARAM.glr] != 0.0:
        _glr_store(x, p, c, gyr, acc, dt)
        _glr_test(x, p, c, dt)
    for j in range(4):
        diag[STAT + j] = 0.0
    for i in range(n):
        diag[i] = x[STATE.eta + i]
        if x[STATE.s_lost + i] > diag[STAT]:
            diag[STAT], diag[STAT + 1] = x[STATE.s_lost + i], i
        if x[STATE.s_damaged + i] > diag[STAT + 2]:
            diag[STAT + 2], diag[STAT + 3] = x[STATE.s_damaged + i], i
    return int(x[STATE.lost])


@njit(cache=True, **NO_ALLOCATION)
def detect_run(x, p, c, dt, gyr, acc, rotors, diag_out, commands):
    """Batch: the same step over every sample; ``commands`` the speeds commanded over each
    interval (:func:`note_commands`), or no rows."""
    noted = commands.shape[0] == len(dt)
    for k in range(len(dt)):
        if noted:
            note_commands(x, p, c, commands[k])
        detect_step(x, p, c, gyr[k], acc[k], rotors[k], dt[k], diag_out[k])


@dataclass
class Detection:
    """What the detector found over a run: each rotor's effectiveness per sample, and the rotor
    found lost and the one found damaged (0-based; None when none), with when (s from the
    start) and the effectiveness left (relative to the other rotors)."""

    t: np.ndarray
    effectiveness: np.ndarray
    lost: int | None
    lost_t: float | None
    lost_effectiveness: float | None
    damaged: int | None
    damaged_t: float | None
    damaged_effectiveness: float | None
    statistics: np.ndarray | None = None
    """Per sample: the largest 'lost' sum and its rotor, the largest 'damaged' sum and its rotor."""


class Detector:
    """Rotor-failure detection and isolation for one vehicle (module doc): ``vehicle`` is the
    detector's model (a :class:`~quadest.models.multirotor.MultirotorParams`), ``params`` a
    :class:`DetectorParams` (or keyword overrides), ``imu_position`` the accelerometer's place
    from the centre of mass (m, body FRD; an autopilot's ``INS_POS`` / ``EKF2_IMU_POS``).
    Streaming :meth:`update` and batch :meth:`run` call one compiled step."""

    def __init__(
        self,
        vehicle: MultirotorParams,
        params: DetectorParams | None = None,
        *,
        imu_position: ArrayLike = (0.0, 0.0, 0.0),
        **overrides,
    ):
        params = params if params is not None else DetectorParams()
        if overrides:
            params = replace(params, **overrides)
        check(params, "detector")
        self.params, self.vehicle = params, vehicle
        self._values = pack(params.values()[f] for f in PARAM._fields)
        self._model = model_coefficients(vehicle, imu_position)
        self.rotors = vehicle.rotors
        self.reset()

    def reset(self) -> None:
        """Back to the start: every rotor intact, nothing found."""
        self._state = np.zeros(STATE.end)
        self._state[STATE.cut_t] = -np.inf
        self._state[STATE.scale : STATE.scale + 3] = 1.0
        self._out = np.zeros(DIAG)

    def compiled(self) -> tuple:
        """The live arrays of the compiled step ``detect_step(x, p, c, ...)`` for a compiled loop."""
        return self._state, self._values, self._model, self._out

    def update(
        self, gyr: ArrayLike, acc: ArrayLike, rotors: ArrayLike, *, dt: float, commands: ArrayLike | None = None
    ) -> int | None:
        """One sample (rotor speeds or commands, rad/s, one per rotor; with measured speeds, the
        ``commands`` over the interval too, for the thrust cut's hold): the rotor found lost, or None."""
        if commands is not None:
            note_commands(self._state, self._values, self._model, _vec(commands, self.rotors))
        lost = detect_step(
            self._state,
            self._values,
            self._model,
            _vec(gyr, 3),
            _vec(acc, 3),
            _vec(rotors, self.rotors),
            float(dt),
            self._out,
        )
        return None if lost < 0 else lost

    @property
    def effectiveness(self) -> np.ndarray:
        return self._state[STATE.eta : STATE.eta + self.rotors].copy()

    @property
    def moment_scale(self) -> np.ndarray:
        """The rotors' moment about x, y and z against the model's, learnt so far (1: the model's)."""
        return self._state[STATE.scale : STATE.scale + 3].copy()

    def result(self, t: ArrayLike | None = None, effectiveness: ArrayLike | None = None) -> Detection:
        """What was found so far (with the per-sample times and effectiveness given, if any)."""
        x = self._state

        def found(key):
            return None if x[key] < 0 else int(x[key])

        lost, damaged = found(STATE.lost), found(STATE.damaged)
        return Detection(
            np.asarray(t if t is not None else []),
            np.asarray(effectiveness if effectiveness is not None else np.empty((0, self.rotors))),
            lost,
            None if lost is None else float(x[STATE.lost_t]),
            None if lost is None else float(x[STATE.lost_eta]),
            damaged,
            None if damaged is None else float(x[STATE.damaged_t]),
            None if damaged is None else float(x[STATE.damaged_eta]),
        )

    def run(
        self, t: ArrayLike, gyr: ArrayLike, acc: ArrayLike, rotors: ArrayLike, commands: ArrayLike | None = None
    ) -> Detection:
        """Over whole arrays (rows of samples; ``commands`` as in :meth:`update`), from the current
        state. Times in the result are seconds from the first sample the detector saw."""
        t = np.asarray(t, float)
        n = len(t)
        gyr, acc = (np.ascontiguousarray(a, dtype=float) for a in (gyr, acc))
        rotors = np.ascontiguousarray(rotors, dtype=float)
        cmds = np.ascontiguousarray(np.zeros((0, self.rotors)) if commands is None else commands, dtype=float)
        if gyr.shape != (n, 3) or acc.shape != (n, 3) or rotors.shape != (n, self.rotors):
            raise ValueError(f"detector: gyr and acc must be ({n}, 3) and rotors ({n}, {self.rotors})")
        if commands is not None and cmds.shape != (n, self.rotors):
            raise ValueError(f"detector: commands must be ({n}, {self.rotors})")
        dt = np.diff(t, prepend=t[0] - (np.median(np.diff(t)) if n > 1 else 0.0))
        diag = np.zeros((n, DIAG))
        detect_run(self._state, self._values, self._model, dt, gyr, acc, rotors, diag, cmds)
        res = self.result(t, diag[:, : self.rotors])
        res.statistics = diag[:, STAT : STAT + 4]
        return res


def _vec(v, n):
    a = np.ascontiguousarray(v, dtype=np.float64)
    if a.shape != (n,):
        raise ValueError(f"detector: expected {n} values, got shape {a.shape}")
    return a
