"""A thrown vehicle recovered with the recovery paper's method in the loop (Beffa, Ledergerber
& D'Andrea, sections IV-V): a throw is a phase of the one closed loop.

The vehicle is released at t = 0 with a random attitude, velocity and tumble (:func:`release_state`),
its rotors at a constant predefined speed (section III: "the motors are commanded to spin at a
constant, predefined speed" while the aerodynamic model is learnt and during recovery), after a
hand's throw that ends in the release (:func:`hand_motion`). The loop then goes through the
recovery's phases (:mod:`quadest.flight.phases`: waiting, converging, nominal) and the recovery
controller (:mod:`quadest.control.upright`) takes over. (The paper's nominal estimator has a
near-hover model and a barometer; ours holds the thrust the measured rotor speeds give and reads
the loop's barometer, :mod:`quadest.recovery.nominal`.)

The bank's aerodynamic model is the estimator's: fitted (eq 14, :func:`quadest.models.fit_aero`)
from throws this simulator flies open loop at the constant rotor speed
(:func:`fit_throw_model`, seeds not evaluated), never the simulator's own model.
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass

import numpy as np

from quadest.control import SE3Params, hover_reference
from quadest.flight import build
from quadest.flight.common import (
    SIM_RATE_HZ,
    Flight,
    FlightParams,
    angle_errors,
    barometer_draws,
    flight_of,
    sensors_for,
)
from quadest.flight.loop import OK, STATUS, closed_loop, flown_arrays
from quadest.flight.phases import HOLD_Z, PHASES
from quadest.models import fit_aero
from quadest.models.multirotor import MultirotorParams, derivatives, fly_open_loop
from quadest.records import check, describe, param
from quadest.recovery import RecoveryParams
from quadest.rotation import quat_conj, quat_from_rotvec, quat_mul, quat_rotate
from quadest.sim.flown import flown_recording

MODES = PHASES[:3]  # a throw's phases (waiting, converging, nominal)
HEIGHT_HELD_S = 5.0  # s: the height held is measured over a flight's last seconds (chosen: half the 10 s hover)


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
        "chosen: harder throws than the paper's, up to 8 m/s",
        bounds="[0, 30]",
    )
    rate_max: float = param(
        20.0,
        "rad/s",
        "release body-rate magnitude drawn in [0, rate_max]",
        "chosen: harder throws than the paper's, tumbling up to 20 rad/s",
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
        30.0, "m/s²", "largest peak hand acceleration", "chosen: a hard throw, up to 30 m/s²", bounds="(0, 100]"
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
        "chosen: upright within 30°",
        bounds="(0, 180]",
    )
    hover_tol_m: float = param(
        0.5,
        "m",
        "recovered: the height held within this of the held height",
        "chosen: within 0.5 m",
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
    pos_rate, pos_noise, pos_latency, _ = params.position()
    every = int(round(rate / pos_rate))
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
    gains = (se3 or SE3Params()).gains(vehicle)
    loop = build.loop(
        plant=build.plant(
            vehicle,
            h=1.0 / SIM_RATE_HZ,
            substeps=int(round(SIM_RATE_HZ / rate)),
            ground_z=throw.drop_m,
            hand=(hand_x, hand_dx),
        ),
        sensing=build.sensing(
            sm,
            dt=1.0 / rate,
            rotors=vehicle.rotors,
            position0=hand_x[0, 0:3],
            every=every,
            delay=int(round(pos_latency * rate)),
            noise=rng_mocap.normal(0.0, 1.0, ((n - 1) // every + 1, 3)) * pos_noise,
            n=n,
            baro=barometer_draws(t, params, seed),
        ),
        nav=build.navigation("true-state" if estimator == "truth" else "bank", hand_x[0]),
        detection=build.detection(),
        bank=build.bank(
            model, rp, mass=vehicle.mass_kg, t_throw=vehicle.rotors * gains.k_f * throw.rotor_speed * throw.rotor_speed
        ),
        control=build.control(
            {"nominal": "recovery"},
            gains=gains,
            ftc=build.unused_ftc_gains(vehicle),
            reference=hover_reference(n),
            cmd0=np.full(vehicle.rotors, throw.rotor_speed),
            beta3=np.radians(throw.beta3_deg),
            upright_rad=np.radians(throw.upright_switch_deg),
        ),
        n=n,
        rotors=vehicle.rotors,
        phase="waiting",
    )
    x = hand_x[0].copy()
    t0 = time.perf_counter()
    status, flown = closed_loop(x, loop)
    loop_s = time.perf_counter() - t0
    out = flown_arrays(loop.record, flown)
    events = loop.record.events
    meta = {
        **meta,
        "aero_model_fitted": model.info.get("residual_rms_mps2"),
        "release_s": float(n_hand / rate),
        "hand_acc_peak_m_s2": float(2 * np.linalg.norm(x_rel[3:6]) * rate / n_hand),
    }
    imbalance = np.zeros((flown, vehicle.rotors))
    flight = flight_of(
        out,
        t[:flown],
        vehicle,
        cfg=cfg,
        seed=seed,
        meta=meta,
        processes=processes,
        loop_s=loop_s,
        imbalance=imbalance,
        modes=out["phase"],
    )
    flight.summary = summarize_throw(
        flight, out, events, status, duration, throw, estimator, seed, n_hand, float(loop.held[HOLD_Z])
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
    (the paper's "hover for at least 10 s")."""
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
        "first_detected_s": float(t[events[3]] - t_rel) if events[3] >= 0 else None,
        "detections": int(max(events[2], 0)),
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
    s["handover_in_hand"] = bool(k_conv >= 0 and k_conv < r)
    last = t >= t[-1] - HEIGHT_HELD_S
    s["height_error_end_m"] = float(np.abs(x[last, 2] - hold_z).max()) if np.isfinite(hold_z) and status == OK else None
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
