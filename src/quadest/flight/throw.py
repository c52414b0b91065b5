"""A thrown vehicle recovered with the recovery paper's method in the loop (issue #13, part 4:
recovery after a throw; Beffa, Ledergerber & D'Andrea, sections IV-V).

The vehicle is released at t = 0 with a random attitude, velocity and tumble, its rotors at a
constant predefined speed (section III: "the motors are commanded to spin at a constant,
predefined speed" while the aerodynamic model is learnt and during recovery). Per IMU sample:

1. ``waiting``: the throw is detected once ``‖z_acc‖ < β1`` has held for ``detect_samples``
   samples (eq 37);
2. ``converging``: the bank of EKFs (:mod:`quadest.recovery.bank`) runs from the detection until
   the spherical variance ``S_g < β2`` (eqs 38-39); the rotors stay at their constant speed;
3. ``nominal``: the most likely hypothesis's mean and covariance start one EKF of the bank's kind
   (section V-B), and the controller takes over, reading that EKF's attitude and velocity and
   the position sensor's height: while the thrust axis is more than 30° from where the
   velocity and altitude loop wants it, a reduced-attitude controller (angle and axis, as the
   paper's ref [19]) brings it up (:func:`upright`; SE(3)'s attitude error vanishes towards
   180°); then SE(3) holds zero velocity and the height of the handover (the paper's velocity
   and altitude loop). The EKF's accelerometer update is disabled while
   the attitude control error (desired against estimated thrust axis) exceeds ``β3 = 15°``
   (section V-B). The bank's aerodynamic model was learnt at the throw's constant rotor speed, so
   its constant force (the last column of ``C``, along z) holds that thrust; from the handover
   it holds the thrust the measured rotor speeds give (``k_f Σ Ω²``), in the prior and the
   update. (The paper's nominal estimator has a near-hover model and a barometer instead.)

The bank's aerodynamic model is the estimator's: fitted (eq 14, :func:`quadest.models.fit_aero`)
from throws this simulator flies open loop at the constant rotor speed
(:func:`fit_throw_model`, seeds not evaluated), never the simulator's own model.
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass

import numpy as np

from quadest._jit import njit
from quadest.control import SE3Params
from quadest.control.se3 import mix, se3_command
from quadest.flight.common import SIM_RATE_HZ, Flight, FlightParams, angle_errors, barometer, sensors_for
from quadest.flight.loop import OK, STATUS, record_and_fly, sample, sense
from quadest.models import fit_aero
from quadest.models.multirotor import MultirotorParams, derivative_ws, derivatives, fly_open_loop, work
from quadest.records import check, describe, param
from quadest.recovery import RecoveryParams
from quadest.recovery.bank import bank_step, summarize
from quadest.recovery.logic import initial_bank
from quadest.recovery.sphere import spread_points
from quadest.rotation import quat_conj, quat_from_rotvec, quat_mul, quat_rotate
from quadest.rotation.kernels import rot_matrix
from quadest.sim.flown import flown_recording

WAITING, CONVERGING, NOMINAL = 0, 1, 2
MODES = ("waiting", "converging", "nominal")


@dataclass(frozen=True)
class ThrowParams:
    rotor_speed: float = param(
        240.0,
        "rad/s",
        "every rotor's constant speed from release to handover",
        "chosen: 1.5 N of thrust on the recovery vehicle, the prescribed throw's idle "
        "thrust (3 m/s² along the body); the paper gives none",
        bounds="[0, 1e4]",
    )
    speed_max: float = param(
        8.0,
        "m/s",
        "release speed drawn uniformly in [0, speed_max]",
        "issue #14: harder throws, up to 8 m/s",
        bounds="[0, 30]",
    )
    rate_max: float = param(
        20.0,
        "rad/s",
        "release body-rate magnitude drawn in [0, rate_max]",
        "issue #14: harder throws, tumbling up to 20 rad/s",
        bounds="[0, 50]",
    )
    any_direction: bool = param(
        False,
        "-",
        "release velocity in any direction (else upward or level)",
        "chosen: thrown upward by default, as the paper's; downward as a flagged case",
    )
    hand_acc_min: float = param(
        10.0,
        "m/s²",
        "the hand's peak acceleration is drawn in [hand_acc_min, hand_acc_max]",
        "chosen: a brisk throw",
        bounds="(0, 100]",
    )
    hand_acc_max: float = param(
        30.0, "m/s²", "largest peak hand acceleration", "issue #14: up to 30 m/s²", bounds="(0, 100]"
    )
    hand_min_s: float = param(
        0.15,
        "s",
        "shortest hand motion (a slow release takes this long)",
        "chosen: a hand does not move in less",
        bounds="(0, 10]",
    )
    beta3_deg: float = param(
        15.0,
        "deg",
        "the nominal estimator's accelerometer update waits until the attitude control error is below this",
        "recovery paper, section V-B",
        bounds="(0, 180]",
    )
    fit_throws: int = param(
        20,
        "-",
        "throws flown open loop to fit the bank's aerodynamic model",
        "chosen: 30 s of tumbling flight, a few thousand samples per parameter",
        bounds="[1, 1000]",
    )
    fit_seed: int = param(
        5000, "-", "first seed of the fitting throws", "chosen: seeds no evaluation uses", bounds="[0, 1e9]"
    )
    fit_duration_s: float = param(
        1.5, "s", "duration of each fitting throw", "chosen: a throw's free flight", bounds="(0, 60]"
    )
    upright_switch_deg: float = param(
        30.0,
        "deg",
        "above this attitude control error the vehicle is first "
        "brought upright (reduced attitude), below it SE(3) holds it",
        "chosen: ArduPilot's throw mode uprights to 30° before holding height",
        bounds="(0, 180]",
    )
    drop_m: float = param(
        10.0,
        "m",
        "height of the release point above the ground",
        "chosen: a throw high in a flight arena (the paper's is about 10 m tall)",
        bounds="(0, 1e3]",
    )
    recovered_tilt_deg: float = param(
        30.0,
        "deg",
        "recovered: upright within this tilt, then the height held",
        "issue #14: upright within 30°",
        bounds="(0, 180]",
    )
    hover_tol_m: float = param(
        0.5,
        "m",
        "recovered: the height held within this of the held height",
        "issue #14: within 0.5 m",
        bounds="(0, 100]",
    )
    hover_s: float = param(
        10.0,
        "s",
        "recovered: for this long",
        "recovery paper, section VI (hover for at least 10 s)",
        bounds="(0, 3600]",
    )

    def __post_init__(self):
        check(self, "throw")
        if self.hand_acc_min > self.hand_acc_max:
            raise ValueError("throw: hand_acc_min must not exceed hand_acc_max")

    @classmethod
    def describe(cls) -> list[dict]:
        return describe(cls)


def random_quaternion(rng) -> np.ndarray:
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    return q if q[0] >= 0 else -q


def release_state(vehicle: MultirotorParams, rng, p: ThrowParams) -> np.ndarray:
    """A release: at the origin, any attitude, a speed in [0, speed_max] upward or level (any
    direction with ``any_direction``), a tumble in [0, rate_max], rotors at the throw's
    constant speed."""
    x = vehicle.hover_state()
    d = rng.normal(size=3)
    d /= np.linalg.norm(d)
    if not p.any_direction:
        d[2] = -abs(d[2])  # NED: up or level
    x[3:6] = rng.uniform(0.0, p.speed_max) * d
    x[6:10] = random_quaternion(rng)
    w = rng.normal(size=3)
    x[10:13] = rng.uniform(0.0, p.rate_max) * w / np.linalg.norm(w)
    x[13:] = p.rotor_speed
    return x


def hand_motion(x_rel, a_peak: float, rate: float, min_s: float):
    """The hand's throw that ends in the release ``x_rel``: from rest, the acceleration
    ``a_peak sin²(πt/T)`` along the release velocity and the body rate ``ω_rel s(t)``,
    ``s = t/T − sin(2πt/T)/(2π)`` (so ``ω̇ = ω_rel 2 sin²(πt/T)/T``), about the release rate's
    body-fixed axis; ``T = max(2|v_rel|/a_peak, min_s)`` rounded up to whole samples (the peak
    then at most ``a_peak``). Closed form: ``v = a (t/2 − T sin(2πt/T)/(4π))``,
    ``p = a (t²/4 − T² (1 − cos(2πt/T))/(8π²))``, rotation angle
    ``θ = |ω_rel| (t²/(2T) + T (cos(2πt/T) − 1)/(4π²))``. Returns the states at the samples
    before the release and at it (n + 1 rows; the rotors as at the release) and their
    derivatives (n rows)."""
    v_rel, w_rel = x_rel[3:6], x_rel[10:13]
    speed, wn = np.linalg.norm(v_rel), np.linalg.norm(w_rel)
    n = int(np.ceil(max(2 * speed / a_peak, min_s) * rate - 1e-9))
    T = n / rate
    a = 2 * speed / T  # the peak acceleration that reaches the release speed in T
    d = v_rel / speed if speed > 0 else np.zeros(3)
    axis = w_rel / wn if wn > 0 else np.array([0.0, 0.0, 1.0])
    t = np.arange(n + 1) / rate
    c, sn, s2 = np.cos(2 * np.pi * t / T), np.sin(2 * np.pi * t / T), np.sin(np.pi * t / T) ** 2
    P = a * (t**2 / 4 - T**2 * (1 - c) / (8 * np.pi**2))
    theta = wn * (t**2 / (2 * T) + T * (c - 1) / (4 * np.pi**2))
    x = np.tile(x_rel, (n + 1, 1))
    x[:, 0:3] = x_rel[0:3] + np.outer(P - P[-1], d)
    x[:, 3:6] = np.outer(a * (t / 2 - T * sn / (4 * np.pi)), d)
    # q(t) ⊗ exp(axis (θ_T − θ(t))) = q_rel: the rest of the turn is about the body-fixed axis
    x[:, 6:10] = quat_mul(
        np.tile(x_rel[6:10], (n + 1, 1)), quat_conj(quat_from_rotvec(np.outer(theta[-1] - theta, axis)))
    )
    x[:, 10:13] = np.outer(t / T - sn / (2 * np.pi), w_rel)
    x[-1] = x_rel
    dx = np.zeros((n, x.shape[1]))
    dx[:, 0:3] = x[:n, 3:6]
    dx[:, 3:6] = np.outer(a * s2[:n], d)
    dx[:, 6:10] = 0.5 * quat_mul(x[:n, 6:10], np.column_stack([np.zeros(n), x[:n, 10:13]]))
    dx[:, 10:13] = np.outer(2 * s2[:n] / T, w_rel)
    return x, dx


def fit_throw_model(vehicle: MultirotorParams, cfg, p: ThrowParams):
    """The bank's aerodynamic model (eq 9) fitted by least squares (eq 14) to ``p.fit_throws``
    throws flown open loop at the constant rotor speed, with ``cfg``'s sensors."""
    return _fit_cached(vehicle, cfg, p)


@functools.lru_cache(maxsize=8)
def _fit_cached(vehicle, cfg, p):  # the records are frozen: their values are the key
    V = vehicle.vehicle()
    rate = cfg.imu.rate_hz
    every = int(round(SIM_RATE_HZ / rate))
    steps = int(round(p.fit_duration_s * SIM_RATE_HZ))
    recs = []
    for seed in range(p.fit_seed, p.fit_seed + p.fit_throws):
        rng = np.random.default_rng(np.random.SeedSequence([seed, 14]))
        x = release_state(vehicle, rng, p)
        cmd = np.full(vehicle.rotors, p.rotor_speed)
        out = np.empty((steps, len(x)))
        fly_open_loop(x, cmd, np.ones(vehicle.rotors), V, 1.0 / SIM_RATE_HZ, steps, out)
        states = np.ascontiguousarray(out[every - 1 :: every])
        n = len(states)
        dx, thrust = np.empty_like(states), np.empty((n, vehicle.rotors))
        derivatives(states, np.tile(cmd, (n, 1)), np.ones((n, vehicle.rotors)), V, dx, thrust)
        recs.append(
            flown_recording(
                np.arange(n) / rate,
                states,
                dx,
                thrust,
                vehicle,
                cfg=cfg,
                seed=seed,
                meta={"scenario": "flown throw (fit)"},
            )
        )
    return fit_aero(recs, vehicle.mass_kg)


@njit(cache=True)
def throw_loop(
    x,
    eta,
    V,
    G,
    sm,
    prm,
    A,
    B,
    C,
    Vb,
    Qr,
    Pb,
    Lb,
    prob,
    gd,
    V1,
    Q1,
    P1,
    L1,
    w_prev,
    h,
    substeps,
    rate,
    tw,
    beta1,
    detect_samples,
    beta2,
    beta3,
    upright_rad,
    rotor_speed,
    use_truth,
    mocap_every,
    mocap_delay,
    mocap_noise,
    ground_z,
    hand_x,
    hand_dx,
    out_x,
    out_dx,
    out_thrust,
    out_cmd,
    out_gyr,
    out_acc,
    out_mag,
    out_q,
    out_pv,
    out_mode,
    out_sg,
    out_gdir,
    events,
    hold,
):
    """Fly a throw (module doc): the hand carries the vehicle through ``hand_x`` (its states
    until the release, and the release) with the derivatives ``hand_dx``, then it flies.
    ``events`` receives the samples of detection and handover, ``hold`` the height the
    controller then holds. Returns ``(status, samples flown)``."""
    n_hand = hand_dx.shape[0]
    n_rot = eta.shape[0]
    cmd = np.full(n_rot, rotor_speed)
    dx = np.empty(x.shape[0])
    Fb, Mb, T = np.empty(3), np.empty(3), np.empty(n_rot)
    gyr, acc, mag = np.empty(3), np.empty(3), np.empty(3)
    Cn = C.copy()
    W = work(V, x.shape[0])
    vib = np.zeros(2 * n_rot + 1)  # quadest.sim.sensors.vibration_state
    vib[n_rot:] = np.nan
    imb = np.zeros(n_rot)  # sound propellers
    xh = np.zeros(13)
    zero3 = np.zeros(3)
    p_d = np.zeros(3)
    hist = np.empty((mocap_delay + 1, 3))
    for j in range(mocap_delay + 1):
        hist[j] = x[0:3]
    z_meas = x[2]
    dt = 1.0 / rate
    mode = WAITING
    below = 0
    gate = False
    yaw_hold = 0.0
    t_throw = n_rot * G.k_f * rotor_speed * rotor_speed
    for k in range(out_mode.shape[0]):
        if k < n_hand:  # in the hand: the rotors turn (their thrust and vibration), the hand moves it
            x[:] = hand_x[k]
            derivative_ws(x, cmd, eta, V, dx, Fb, Mb, T)
            dx[:] = hand_dx[k]
            sample(x, dx, eta, imb, V, sm, k, dt, tw, T, vib, gyr, acc, mag)
        else:
            sense(x, cmd, eta, imb, V, sm, k, dt, tw, dx, Fb, Mb, T, vib, gyr, acc, mag)
        for j in range(mocap_delay, 0, -1):
            hist[j] = hist[j - 1]
        hist[0] = x[0:3]
        if k % mocap_every == 0:
            z_meas = hist[mocap_delay, 2] + mocap_noise[k // mocap_every, 2]
        out_sg[k] = np.nan
        for j in range(3):
            out_gdir[k, j] = np.nan
        for j in range(4):
            out_q[k, j] = np.nan
        if mode == WAITING:
            below = below + 1 if np.sqrt(acc[0] ** 2 + acc[1] ** 2 + acc[2] ** 2) < beta1 else 0
            if below >= detect_samples:
                mode = CONVERGING
                events[0] = k
                if use_truth:  # the oracle: hand over at detection, the controller reads the truth
                    mode = NOMINAL
                    events[1] = k
                    yaw_hold = quat_yaw(x[6:10])
                    p_d[2] = x[2]
                    hold[0] = p_d[2]
            else:
                w_prev[0], w_prev[1], w_prev[2] = gyr[0], gyr[1], gyr[2]
        if mode == CONVERGING:
            bank_step(Vb, Qr, Pb, Lb, w_prev, gyr, acc, dt, prm, A, B, C, True)
            best, sg = summarize(Qr, Lb, prm.gravity, prob, gd)
            out_sg[k] = sg
            for j in range(3):
                out_gdir[k, j] = gd[best, j]
            for j in range(4):
                out_q[k, j] = Qr[best, j]
            if sg < beta2:
                mode = NOMINAL
                events[1] = k
                for j in range(3):
                    V1[0, j] = Vb[best, j]
                for j in range(4):
                    Q1[0, j] = Qr[best, j]
                for r in range(5):
                    for c in range(5):
                        P1[0, r, c] = Pb[best, r, c]
                L1[0] = 0.0
                yaw_hold = quat_yaw(Q1[0])
                p_d[2] = z_meas
                hold[0] = p_d[2]
                gate = False
        elif mode == NOMINAL:
            if use_truth:
                for j in range(13):
                    xh[j] = x[j]
            else:
                # the model's constant force holds the throw's thrust; now the rotors give what their
                # measured speeds say (k_f Σ Ω², along −z), in the prior and the update alike
                t_est = 0.0
                for i in range(n_rot):
                    t_est += G.k_f * x[13 + i] * x[13 + i]
                Cn[2, 9] = C[2, 9] - (t_est - t_throw)
                bank_step(V1, Q1, P1, L1, w_prev, gyr, acc, dt, prm, A, B, Cn, gate)
                R = rot_matrix(Q1[0])
                for j in range(3):
                    xh[3 + j] = R[j, 0] * V1[0, 0] + R[j, 1] * V1[0, 1] + R[j, 2] * V1[0, 2]
                    xh[10 + j] = gyr[j]
                for j in range(4):
                    xh[6 + j] = Q1[0, j]
                xh[0], xh[1], xh[2] = 0.0, 0.0, z_meas  # velocity and height hold: no horizontal position
            for j in range(4):
                out_q[k, j] = xh[6 + j]
            # the attitude control error: desired against estimated thrust axis
            R = rot_matrix(xh[6:10])
            f0 = -G.k_v[0] * xh[3]
            f1 = -G.k_v[1] * xh[4]
            f2 = -G.k_p[2] * (xh[2] - p_d[2]) - G.k_v[2] * xh[5] - V.gravity
            nf = np.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
            cosang = -(f0 * R[0, 2] + f1 * R[1, 2] + f2 * R[2, 2]) / max(nf, 1e-9)
            gate = cosang > np.cos(beta3)
            if cosang > np.cos(upright_rad):
                se3_command(xh, p_d, zero3, zero3, yaw_hold, G, V, cmd)
            else:
                upright(xh, R, -f0 / nf, -f1 / nf, -f2 / nf, nf, cosang, G, V, cmd)
        for j in range(3):  # what the controller read (nothing before the handover)
            out_pv[k, j] = xh[j] if mode == NOMINAL else np.nan
            out_pv[k, 3 + j] = xh[3 + j] if mode == NOMINAL else np.nan
        out_mode[k] = mode
        held = k < n_hand
        status = record_and_fly(
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
            0 if held else substeps,
            ground_z,
            out_x,
            out_dx,
            out_thrust,
            out_cmd,
            out_gyr,
            out_acc,
            out_mag,
            W,
        )
        if held:
            x[:] = hand_x[k + 1]
        if status != OK:
            return status, k + 1
    return OK, out_mode.shape[0]


UPRIGHT_RATE_GAIN = 8.0  # 1/s: rate commanded per radian of tilt error (chosen: turns 180° in well under 0.5 s)
UPRIGHT_RATE_MAX = 20.0  # rad/s (chosen: within the gyroscope's range and the motors' authority)
UPRIGHT_THRUST_MIN = 0.2  # of the weight: kept for the moments while the thrust axis points away (chosen)


@njit(cache=True)
def upright(xh, R, zd0, zd1, zd2, f_norm, cosang, G, V, cmd):
    """Bring the thrust axis up from any attitude (the SE(3) controller's attitude error vanishes
    towards 180°): reduced-attitude control by angle and axis. The desired body z (down) axis
    ``z_d`` (navigation frame, opposite the desired thrust), in the body ``z_b = Rᵀ z_d``; the
    rate ``ω_d = min(k α, ω_max) (e_z × z_b)/‖e_z × z_b‖`` (``ż_b = z_b × ω`` then turns ``z_b``
    towards ``e_z``) with the tilt error ``α`` (any
    horizontal axis when upside down), no yaw rate; the moment ``J k_ω (ω_d − ω) + ω × J ω``;
    thrust the desired force along the thrust axis, at least a fifth of the weight."""
    zb0 = R[0, 0] * zd0 + R[1, 0] * zd1 + R[2, 0] * zd2
    zb1 = R[0, 1] * zd0 + R[1, 1] * zd1 + R[2, 1] * zd2
    alpha = np.arccos(min(1.0, max(-1.0, cosang)))
    a0, a1 = -zb1, zb0  # e_z × z_b (its z part is 0)
    na = np.sqrt(a0 * a0 + a1 * a1)
    if na < 1e-6:
        a0, a1, na = 1.0, 0.0, 1.0
    rate = min(UPRIGHT_RATE_GAIN * alpha, UPRIGHT_RATE_MAX)
    wd0, wd1 = rate * a0 / na, rate * a1 / na
    w0, w1, w2 = xh[10], xh[11], xh[12]
    J0, J1, J2 = V.inertia[0], V.inertia[1], V.inertia[2]
    M0 = J0 * G.k_w * (wd0 - w0) + (w1 * J2 * w2 - w2 * J1 * w1)
    M1 = J1 * G.k_w * (wd1 - w1) + (w2 * J0 * w0 - w0 * J2 * w2)
    M2 = J2 * G.k_w * (0.0 - w2) + (w0 * J1 * w1 - w1 * J0 * w0)
    thrust = max(V.mass * f_norm * cosang, UPRIGHT_THRUST_MIN * V.mass * V.gravity)
    mix(thrust, M0, M1, M2, G, cmd)


@njit(cache=True)
def quat_yaw(q):
    """ZYX yaw of ``q_nb``."""
    return np.arctan2(2.0 * (q[1] * q[2] + q[0] * q[3]), 1.0 - 2.0 * (q[2] * q[2] + q[3] * q[3]))


def fly_throw(
    *,
    estimator: str = "recovery",
    duration: float = 14.0,
    seed: int = 0,
    cfg=None,
    vehicle: MultirotorParams,
    params: FlightParams,
    throw: ThrowParams | None = None,
    recovery: RecoveryParams | None = None,
    se3: SE3Params | None = None,
    meta: dict,
) -> Flight:
    """One throw (module doc): the hand's throw (:func:`hand_motion`), then ``duration`` seconds
    from the release. ``estimator``: ``recovery`` (the bank, then its nominal EKF) or ``truth``
    (the controller takes over at the detection and reads the true state)."""
    throw = throw or ThrowParams()
    rp = recovery or RecoveryParams()
    rate = cfg.imu.rate_hz
    substeps = int(round(SIM_RATE_HZ / rate))
    pos_rate, pos_noise, pos_latency, _ = params.position()
    mocap_every = int(round(rate / pos_rate))
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 13]))
    rng_mocap = np.random.default_rng(np.random.SeedSequence([int(seed), 15]))
    x_rel = release_state(vehicle, rng, throw)
    a_peak = rng.uniform(throw.hand_acc_min, throw.hand_acc_max)
    hand_x, hand_dx = hand_motion(x_rel, a_peak, rate, throw.hand_min_s)
    n_hand = len(hand_dx)
    n = n_hand + int(round(duration * rate))
    t = np.arange(n) / rate
    model = fit_throw_model(vehicle, cfg, throw)
    processes, sm = sensors_for(cfg, n, seed, vehicle)
    H = rp.n_hypotheses
    Vb, Qr, Pb, Lb = initial_bank(rp, spread_points(H))
    V1, Q1, P1, L1 = np.zeros((1, 3)), np.zeros((1, 4)), np.zeros((1, 5, 5)), np.zeros(1)
    G = (se3 or SE3Params()).gains(vehicle)
    tw = vehicle.rotors * vehicle.k_f * vehicle.omega_max**2 / (vehicle.mass_kg * vehicle.gravity)
    N = vehicle.rotors
    out = dict(
        x=np.empty((n, 13 + N)),
        dx=np.empty((n, 13 + N)),
        thrust=np.empty((n, N)),
        cmd=np.empty((n, N)),
        gyr=np.empty((n, 3)),
        acc=np.empty((n, 3)),
        mag=np.empty((n, 3)),
        q=np.empty((n, 4)),
        pv=np.empty((n, 6)),
        mode=np.zeros(n, np.int64),
        sg=np.empty(n),
        gdir=np.empty((n, 3)),
    )
    events = np.full(2, -1, np.int64)
    hold = np.full(1, np.nan)
    w_prev = np.zeros(3)  # the gyro before the first sample: at rest in the hand
    x = hand_x[0].copy()
    t0 = time.perf_counter()
    status, flown = throw_loop(
        x,
        np.ones(N),
        vehicle.vehicle(),
        G,
        sm,
        rp.bank_record(vehicle.mass_kg),
        model.A,
        model.B,
        model.C,
        Vb,
        Qr,
        Pb,
        Lb,
        np.empty(H),
        np.empty((H, 3)),
        V1,
        Q1,
        P1,
        L1,
        w_prev,
        1.0 / SIM_RATE_HZ,
        substeps,
        float(rate),
        tw,
        rp.beta1,
        rp.detect_samples,
        rp.beta2,
        np.radians(throw.beta3_deg),
        np.radians(throw.upright_switch_deg),
        throw.rotor_speed,
        estimator == "truth",
        mocap_every,
        int(round(pos_latency * rate)),
        rng_mocap.normal(0.0, 1.0, ((n - 1) // mocap_every + 1, 3)) * pos_noise,
        throw.drop_m,
        hand_x,
        hand_dx,
        out["x"],
        out["dx"],
        out["thrust"],
        out["cmd"],
        out["gyr"],
        out["acc"],
        out["mag"],
        out["q"],
        out["pv"],
        out["mode"],
        out["sg"],
        out["gdir"],
        events,
        hold,
    )
    loop_s = time.perf_counter() - t0
    out = {k: v[:flown] for k, v in out.items()}
    rec = flown_recording(
        t[:flown],
        out["x"],
        out["dx"],
        out["thrust"],
        vehicle,
        cfg=cfg,
        seed=seed,
        meta={
            **meta,
            "aero_model_fitted": model.info.get("residual_rms_mps2"),
            "release_s": float(n_hand / rate),
            "hand_acc_peak_m_s2": float(2 * np.linalg.norm(x_rel[3:6]) * rate / n_hand),
        },
        readings=(out["gyr"], out["acc"], out["mag"]),
        processes=processes,
    )
    flight = Flight(
        rec,
        out["x"],
        out["cmd"],
        out["q"],
        out["pv"],
        timing={"loop_s": loop_s},
        baro=barometer(rec.t, out["x"], params, seed),
        modes=out["mode"],
        derivs=out["dx"],
        thrusts=out["thrust"],
        eta=np.ones((flown, N)),
        imbalance=np.zeros((flown, N)),
        vehicle=vehicle,
    )
    flight.summary = summarize_throw(
        flight, out, events, status, duration, throw, estimator, seed, n_hand, float(hold[0])
    )
    return flight


def _tilt_deg(q):
    down = quat_rotate(q, np.tile([0.0, 0.0, 1.0], (len(q), 1)))
    return np.degrees(np.arccos(np.clip(down[:, 2], -1.0, 1.0)))


def summarize_throw(flight, out, events, status, duration, throw, estimator, seed, n_hand=0, hold_z=np.nan) -> dict:
    """The release (sample ``n_hand``), the detection and the handover (times from the release;
    the convergence time from the detection to the handover, as the paper's 570 ms), the bank's
    gravity and velocity errors at the handover, the time to upright, the height lost, and
    whether the vehicle recovered: upright within ``recovered_tilt_deg`` after the handover,
    then its height within ``hover_tol_m`` of the held height ``hold_z`` for ``hover_s``
    (issue #14; the paper's "hover for at least 10 s")."""
    t, x = flight.recording.t, flight.states
    r = min(n_hand, len(t) - 1)
    t_rel = t[r]
    k_det, k_conv = int(events[0]), int(events[1])
    s = {
        "scenario": "throw",
        "controller": "recovery",
        "estimator": estimator,
        "seed": int(seed),
        "duration_s": float(duration),
        "status": "survived" if status == OK else "crashed" if status in (1, 2) else "stopped",
        "reason": STATUS[status],
        "end_time_s": None if status == OK else float(t[-1] - t_rel),
        "release_s": float(t_rel),
        "hand_acc_peak_m_s2": flight.recording.meta.get("hand_acc_peak_m_s2"),
        "release_speed_m_s": float(np.linalg.norm(x[r, 3:6])),
        "release_rate_rad_s": float(np.linalg.norm(x[r, 10:13])),
        "detected_s": float(t[k_det] - t_rel) if k_det >= 0 else None,
        "handover_s": float(t[k_conv] - t_rel) if k_conv >= 0 else None,
        "convergence_s": float(t[k_conv] - t[k_det]) if k_conv >= 0 and k_det >= 0 else None,
    }
    if k_conv >= 0 and estimator != "truth":
        q = x[k_conv, 6:10]
        g_true = quat_rotate(quat_conj(q[None]), np.array([[0.0, 0.0, 1.0]]))[0]
        s["gravity_error_at_handover_deg"] = float(np.degrees(np.arccos(np.clip(out["gdir"][k_conv] @ g_true, -1, 1))))
        v_true = quat_rotate(quat_conj(q[None]), x[k_conv : k_conv + 1, 3:6])[0]
        k1 = min(k_conv + 1, len(t) - 1)
        v_est = quat_rotate(quat_conj(out["q"][k1 : k1 + 1]), out["pv"][k1 : k1 + 1, 3:6])[0]
        s["velocity_error_at_handover_m_s"] = float(np.linalg.norm(v_est - v_true))
    tilt = _tilt_deg(x[:, 6:10])
    s["lowest_point_m"] = float(x[r:, 2].max())  # NED: metres below the release point
    s["upright_s"] = s["hover_from_s"] = None
    if k_conv >= 0:
        up = np.flatnonzero((t >= t[k_conv]) & (tilt < throw.recovered_tilt_deg))
        if len(up):
            s["upright_s"] = float(t[up[0]] - t_rel)
            s["hover_from_s"] = _held_from(t, x[:, 2], up[0], hold_z, throw.hover_tol_m, throw.hover_s, t_rel)
        after = t >= t[k_conv]
        ok = after & np.isfinite(out["q"]).all(axis=1)
        if ok.any():
            total, tilt_err = angle_errors(x[ok, 6:10], out["q"][ok])
            s["tilt_error_after_handover_rms_deg"] = float(np.sqrt(np.mean(tilt_err**2)))
    s["held_height_m"] = None if not np.isfinite(hold_z) else float(-hold_z)
    s["final_tilt_deg"] = float(tilt[-1])
    s["final_speed_m_s"] = float(np.linalg.norm(x[-1, 3:6]))
    s["recovered"] = bool(s["hover_from_s"] is not None)
    s["time_to_settle_s"] = None
    s["position_rms_settled_m"] = None
    total, tilt_err = angle_errors(x[:, 6:10], np.where(np.isfinite(out["q"]), out["q"], x[:, 6:10]))
    s["tilt_error_rms_deg"] = float(np.sqrt(np.mean(tilt_err**2)))
    return s


def _held_from(t, z, k0, hold_z, tol, span, t_rel):
    """The first time from sample ``k0`` on (from the release) after which the height ``z``
    stays within ``tol`` of ``hold_z`` for ``span`` seconds; None if it never does."""
    if not np.isfinite(hold_z):
        return None
    start = None
    for k in range(k0, len(t)):
        if abs(z[k] - hold_z) >= tol:
            start = None
            continue
        if start is None:
            start = k
        if t[k] - t[start] >= span - 1e-9:
            return float(t[start] - t_rel)
    return None


__all__ = ["MODES", "ThrowParams", "fit_throw_model", "fly_throw", "hand_motion", "release_state"]
