"""Flights of the rotor-level vehicle with an estimator in the loop (docs/vehicle.md).

``fly(scenario, estimator=..., controller=...)`` flies one run and returns a :class:`Flight`:
the recording (what the sensors gave, as every command reads it), the true states, what the
loop estimated and commanded, and a summary (survived or crashed, why and when, position error
after settling, the attitude error in the loop, the settled spin and tilt after a rotor loss).
"""

from __future__ import annotations

import math
import time
from collections import namedtuple
from collections.abc import Callable, Iterable
from dataclasses import fields

import numpy as np
from numpy.typing import ArrayLike

from quadest.control import (
    FtcParams,
    SE3Params,
    circle_reference,
    figure_eight_reference,
    hover_reference,
)
from quadest.control.registry import CONTROLLERS as REGISTRY
from quadest.data.recording import Recording
from quadest.detect import DetectorParams
from quadest.errors import UsageError
from quadest.filters import ESTIMATORS, Estimator, filter_name, make_filter
from quadest.flight import build, inflight
from quadest.flight.common import (
    SIM_RATE_HZ,
    Flight,
    FlightParams,
    barometer_draws,
    flight_of,
    position_gain,
    sensors_for,
)
from quadest.flight.fault_setup import (
    clip_rate_model,
    detection_record,
    detector_mode,
    detector_model,
    ftc_gains,
    known_fault,
)
from quadest.flight.landing import descent_start, land_detector, landing_reference, landing_summary
from quadest.flight.loop import (
    OK,
    STATUS,
    act_sample,
    closed_loop,
    flown,
    flown_arrays,
    sense_sample,
)
from quadest.flight.start import converge, rest_readings
from quadest.flight.summary import add_detection, offline_errors, summarize
from quadest.flight.throw import ThrowParams, fly_throw
from quadest.models.multirotor import MultirotorParams, vehicle_preset
from quadest.recovery import RecoveryParams
from quadest.recovery.divergence import CHECKS, DivergenceParams
from quadest.rotation import euler_to_quat
from quadest.sim import build_config
from quadest.sim.faults import Failure
from quadest.sim.flown import flown_recording
from quadest.sim.params import SimConfig
from quadest.sim.wind import wind_samples

FLIGHT_SCENARIOS = ("hover", "trajectory", "aggressive", "rotor-loss", "throw")


def in_loop_estimators() -> list[str]:
    """What can fly in the loop (besides truth): quadest's filters and the installed peers with
    a per-sample API."""
    return [name for name in in_loop_names() if ESTIMATORS[name].available()]


CONTROLLERS = tuple(name for name, c in REGISTRY.items() if c.selectable)  # what a user may fly by name
DEFAULT_DURATION = {
    "hover": 10.0,
    "trajectory": 20.0,
    "aggressive": 20.0,
    "rotor-loss": 10.0,
    "throw": 14.0,
}  # a throw: from the release
COLLISION_S = 16.0  # s: a flight with a collision (at 2-4 s), then the 10 s hover it is judged by
IN_FLIGHT_MAG = {"mag.rate_hz": 100.0}
"""A recovery in flight flies the recovery paper's IMU (``fma``) with a magnetometer at the
simulator's default rate: the estimator in the loop needs a heading before the collision."""
DEFAULT_PRESET = {"throw": "fma"}  # the recovery paper's sensors (IMU 1 kHz, no magnetometer); else bebop2


def _reference(scenario, t, rng, vehicle, params):
    """The start and the reference ``(p_d, v_d, a_d, yaw_d)`` of ``scenario`` at ``t``, ending in
    ``params``' landing when it asks for one (:func:`landing_reference`)."""
    x0 = vehicle.hover_state()
    if scenario == "hover":
        ref = hover_reference(len(t))
        x0[0:3] = rng.uniform(-0.5, 0.5, 3)
        x0[6:10] = euler_to_quat(np.concatenate([rng.uniform(-0.2, 0.2, 2), rng.uniform(-np.pi, np.pi, 1)]))
    elif scenario == "trajectory":
        ref = circle_reference(t)
        x0[0], x0[4] = 1.0, 2 * np.pi * 0.2
    elif scenario == "aggressive":
        ref = figure_eight_reference(
            t,
            size=(rng.uniform(1.0, 1.5), rng.uniform(0.3, 0.45)),
            freq_hz=rng.uniform(0.3, 0.35),
            yaw_amplitude=2.5,
            phase=rng.uniform(0, 2 * np.pi),
        )
    else:
        ref = hover_reference(len(t))
    if params.landing_m_s > 0.0:
        ref = landing_reference(ref, t, params.landing_m_s, params.height_m, accel=params.landing_accel_m_s2)
    return x0, ref


def fly(
    scenario: str = "trajectory",
    *,
    estimator: str | Estimator = "truth",
    controller: str | None = None,
    duration: float | None = None,
    seed: int = 0,
    preset: str | None = None,
    vehicle: MultirotorParams | str | None = None,
    failure: Failure | None = None,
    se3: SE3Params | None = None,
    ftc: FtcParams | None = None,
    params: FlightParams | None = None,
    config: SimConfig | None = None,
    estimator_params: dict | None = None,
    throw: ThrowParams | None = None,
    detection: str | DetectorParams = "oracle",
) -> Flight:
    """Fly ``scenario`` with ``estimator`` in the loop: a quadest filter or peer by name (with the
    preset's declination; started converged at the start attitude, ``params.estimator_start_s``:
    an oracle of the start), an :class:`~quadest.filters.Estimator` (it continues from its
    state), or ``truth`` (an oracle: the controller reads the true state).

    Scenarios: ``hover`` (hold the origin from a disturbed start), ``trajectory`` (a 1 m circle
    at 0.2 Hz), ``aggressive`` (a figure eight drawn from the seed, 1-1.5 m by 0.3-0.45 m at
    0.3-0.35 Hz, the heading swinging ±2.5 rad, grown in over 2 s), ``rotor-loss`` (hover; rotor
    0 lost at 2 s unless ``failure`` says otherwise), ``throw`` (released tumbling; the recovery
    paper's bank of EKFs and logic in the loop, then the recovery controller:
    :mod:`quadest.flight.throw`; estimator ``recovery`` or ``truth``, sensors ``fma`` by default).
    ``controller``: ``se3`` (nominal only) or ``ftc`` (SE(3), then the fault-tolerant controller
    once a complete rotor loss is known, holding the point the reference had reached then: a
    trajectory with a loss ends in a relaxed hover); default ``ftc`` for ``rotor-loss``, else ``se3``.
    The sensors are the ``preset``'s (or ``config``'s), the position sensor and what the loop
    assumes ``params``'; ``vehicle`` a :class:`MultirotorParams` or a preset name
    (:data:`~quadest.models.VEHICLE_PRESETS`, default ``recovery``); ``estimator_params`` the
    named estimator's parameters (``{"beta_marg": 0.05}``; a throw's recovery: RecoveryParams'
    fields); ``throw`` a throw's (:class:`~quadest.flight.throw.ThrowParams`; duration from the release).
    ``detection``: how the fault-tolerant controller learns of a rotor loss: ``oracle`` (told
    ``params.detect_delay_s`` after it, the lost rotor's command zeroed from the failure on),
    ``rotor-speeds`` or ``commands`` (found by the detector of :mod:`quadest.detect` with a model
    of the vehicle off by ``params.detector_model_error``), or a
    :class:`~quadest.detect.DetectorParams` (its ``rotor_speeds`` says which).
    ``params.collision`` and ``params.divergence``: a collision and the checks that start a recovery
    in flight (:mod:`quadest.flight.collision`; with the checks the sensors are ``fma`` by default).
    ``params.wind``: the air's motion (:class:`~quadest.sim.wind.WindParams`; its realisation
    drawn from the seed), which the vehicle flies in and nothing in the loop knows.
    ``params.landing_m_s``: the flight ends with a hard landing (:func:`landing_reference`) on
    sprung legs (:func:`~quadest.models.multirotor.with_ground`)."""
    estimator = filter_name(estimator) if isinstance(estimator, str) else estimator
    params = params or FlightParams()
    controller, duration = _check_request(scenario, estimator, controller, duration, params.collision != "none")
    vehicle_name = vehicle if isinstance(vehicle, str) else ("recovery" if vehicle is None else "custom")
    vehicle = vehicle_preset(vehicle) if isinstance(vehicle, str) else (vehicle or MultirotorParams())
    failure = _checked_failure(scenario, failure, controller, vehicle, duration)
    event, watching = _in_flight_request(scenario, params, seed, duration)
    preset, cfg = _sensors(preset, config, scenario, watching)
    rate, substeps, every = _rates(cfg, params, preset)
    meta = {"scenario": f"flown {scenario}", "preset": preset, "vehicle": vehicle_name}
    if scenario == "throw":
        meta.update(controller="se3 after recovery", estimator=estimator)
        return fly_throw(
            estimator=estimator, duration=duration, seed=seed, cfg=cfg, vehicle=vehicle, params=params, se3=se3,
            throw=throw, recovery=_recovery_params(estimator_params), meta=meta,
        )  # fmt: skip
    t, rng_mocap, (x0, ref) = _referenced(scenario, duration, rate, seed, vehicle, params)
    n = len(t)
    processes, sm = sensors_for(cfg, n, seed, vehicle)  # the generators and order of flown_recording's
    nav, est = _in_loop(estimator, cfg, rate, estimator_params)
    if not isinstance(estimator, Estimator):  # one given continues from its state
        _start_converged(est, sm, x0[6:10], cfg, params.estimator_start_s)
    ftc, gains = ftc or FtcParams(), (se3 or SE3Params()).gains(vehicle)
    detection, detector = (detection, None) if isinstance(detection, str) else (detector_mode(detection), detection)
    oracle = detection == "oracle"
    loop = build.loop(
        plant=_plant(vehicle, params, failure, t, (rate, substeps), oracle, seed, event),
        sensing=_position_sensing(sm, params, rate, every, n, x0, rng_mocap, vehicle.rotors, seed),
        nav=build.navigation(
            nav,
            x0,
            position_gain(params, rate),
            clip_rate_model(params, vehicle, cfg, seed, n),
            inflight.reset(event, est, rate),
        ),  # fmt: skip
        bank=build.bank() if watching is None else inflight.bank(vehicle, cfg, gains),
        watch=inflight.watch(watching, detector_model(vehicle, params, seed)[0], rate, rate / every),
        control=build.control(
            {**dict(REGISTRY[controller].phases), **({} if watching is None else {"nominal": "recovery"})},
            gains=gains,
            ftc=ftc_gains(ftc, vehicle, controller, failure, oracle),
            reference=ref,
            fault=known_fault(controller, failure, params, rate, n) if oracle else (-1, -1),
            cmd0=x0[13:].copy(),  # what the rotors were doing (a detector reads it before the first command)
            limited_k=(descent := descent_start(ref[1][:, 2], params.landing_m_s)),  # PX4's thrust limits
            **inflight.recovery_control(watching),
        ),
        detection=detection_record(detection, detector, vehicle, params, seed, n, cfg.acc.lever_arm),
        landing=land_detector(vehicle, rate, descent, params.landing_m_s * params.land_detector),
        n=n,
        rotors=vehicle.rotors,
        phase="flying",
    )
    x, t0 = x0.copy(), time.perf_counter()
    (status, flown), loop_s = _run(x, loop, est), time.perf_counter() - t0
    if flown == 0:
        raise ValueError(f"the flight ended before its first sample ({STATUS[status]})")
    out = flown_arrays(loop.record, flown)
    meta.update(controller=controller, estimator=est.name, position_sensor=params.position_sensor)
    flight = _flight(out, t[:flown], vehicle, cfg, seed, failure, meta, processes, loop_s, watching is not None)
    flight.summary = summarize(
        flight, scenario=scenario, status=status, duration=duration, failure=failure, controller=controller,
        estimator=est.name, seed=seed, params=params, ftc=ftc, vehicle=vehicle,
        ref=(loop.control.p_d, loop.control.yaw_d), gyro_range=float(cfg.gyro.range),
    )  # fmt: skip
    if detection != "oracle":
        add_detection(flight, loop.detection, detection, failure, flown)
    flight.summary.update(landing_summary(loop.landing, t[:flown]))
    if watching is not None or event is not None:
        flight.summary.update(inflight.summary(flight, out, loop, event, status, rate))
    return flight


def _sensors(preset, config, scenario, watching):
    """The preset's name and the sensors: ``config``, the ``preset``'s, or by default the
    scenario's (:data:`DEFAULT_PRESET`); with the divergence checks on, ``fma`` with a magnetometer
    (:data:`IN_FLIGHT_MAG`)."""
    if preset is None and config is None and watching is not None:
        return "fma+mag", build_config("fma").with_overrides(IN_FLIGHT_MAG, source="a recovery in flight").validate()
    preset = preset or DEFAULT_PRESET.get(scenario, "bebop2")
    return preset, (config or build_config(preset)).validate()


def _in_flight_request(scenario, params: FlightParams, seed, duration):
    """The flight's collision (``params.collision``, drawn from ``seed``; None: none) and its
    divergence checks (``params.divergence``; None: off), after refusing what cannot fly."""
    if scenario == "throw" and (params.collision != "none" or params.divergence not in ("auto", "off")):
        raise UsageError("a throw starts its recovery at the release: no collision or divergence checks")
    event = inflight.collision_of(params.collision, seed)
    if event is not None and not 0.0 <= event.time_s < duration:
        raise UsageError(
            f"collision: time {event.time_s:g} s lies outside the run (0 to {duration:g} s): a longer --duration"
        )
    checks = params.divergence
    if checks == "auto":
        checks = "off" if event is None or scenario == "throw" else ",".join(CHECKS)
    return event, None if checks == "off" else DivergenceParams(checks=checks)


def _plant(vehicle, params, failure, t, rates, oracle, seed, event):
    """The flight's plant: the vehicle in ``params``' wind (drawn from the seed), on legs for a
    landing, the oracle zeroing the lost rotor's command when it is the one that tells, struck
    by the collision ``event`` (None: none); ``rates`` the IMU rate and the simulation substeps
    per sample."""
    rate, substeps = rates
    wind = None if params.wind is None else wind_samples(t, params.wind, np.random.default_rng([int(seed), 37]))
    return build.plant(
        vehicle,
        h=1.0 / SIM_RATE_HZ,
        substeps=substeps,
        ground_z=float(params.height_m if event is None else event.height_m),
        failure=failure,
        rate=rate,
        n=len(t),
        zero_failed=oracle,
        collision=event,
        wind=wind,
        legs=params.landing_m_s > 0.0,
    )


def _check_request(scenario, estimator, controller, duration, collision=False):
    """The controller and duration of a flight (with a ``collision``, 16 s by default: the
    collision at 2-4 s, then the 10 s hover), after refusing what cannot fly (one line each)."""
    if scenario not in FLIGHT_SCENARIOS:
        raise UsageError(f"unknown scenario {scenario!r}; scenarios: {', '.join(FLIGHT_SCENARIOS)}")
    if scenario == "throw":
        if estimator not in ("recovery", "truth"):
            raise UsageError(
                f"a throw is recovered by the recovery paper's bank of EKFs: estimator recovery (or "
                f"truth), not {estimator!r}"
            )
        if controller not in (None, "se3"):
            raise UsageError("after a throw the SE(3) controller holds the vehicle: controller se3 (or none)")
    elif not isinstance(estimator, Estimator) and estimator != "truth" and estimator not in in_loop_names():
        raise UsageError(
            f"unknown estimator {estimator!r}; estimators in the loop: truth, {', '.join(in_loop_names())} "
            "(a peer through its streaming API)"
        )
    controller = controller or ("ftc" if scenario == "rotor-loss" else "se3")
    if controller not in CONTROLLERS:
        raise UsageError(f"unknown controller {controller!r}; controllers: {', '.join(CONTROLLERS)}")
    if duration is None:
        duration = COLLISION_S if collision and scenario != "throw" else DEFAULT_DURATION[scenario]
    duration = float(duration)
    if not (math.isfinite(duration) and 0 < duration <= 3600):
        raise UsageError(f"duration must be between 0 and 3600 s, got {duration}")
    return controller, duration


def check_flight(
    scenario: str,
    *,
    estimator="truth",
    controller=None,
    duration=None,
    vehicle=None,
    failure=None,
    params: FlightParams | None = None,
    preset=None,
    config=None,
    seeds=(0,),
) -> None:
    """Refuse, in one line and before anything is flown or written, what :func:`fly` would refuse
    in its arguments (for each of ``seeds``: a collision is drawn from the seed)."""
    estimator = filter_name(estimator) if isinstance(estimator, str) else estimator
    params = params or FlightParams()
    controller, duration = _check_request(scenario, estimator, controller, duration, params.collision != "none")
    vehicle = vehicle_preset(vehicle) if isinstance(vehicle, str) else (vehicle or MultirotorParams())
    _checked_failure(scenario, failure, controller, vehicle, duration)
    for seed in seeds:
        _, watching = _in_flight_request(scenario, params, seed, duration)
        name, cfg = _sensors(preset, config, scenario, watching)
        rate = _rates(cfg, params, name)[0]
        if scenario != "throw":
            _referenced(scenario, duration, rate, seed, vehicle, params)


def _referenced(scenario, duration, rate, seed, vehicle, params):
    """The flight's sample times, the motion capture's generator, and the start state and
    reference (:func:`_reference`, a landing included), from the seed."""
    t = np.arange(int(round(duration * rate))) / rate
    rng_ref, rng_mocap = (np.random.default_rng(s) for s in np.random.SeedSequence([int(seed), 13]).spawn(2))
    return t, rng_mocap, _reference(scenario, t, rng_ref, vehicle, params)


def in_loop_names() -> list[str]:
    """The names an estimator in the loop may have (installed or not): those with a per-sample
    ``update``."""
    return [name for name, cls in ESTIMATORS.items() if cls.streaming]


def _checked_failure(scenario, failure, controller, vehicle, duration):
    """The failure the flight has (rotor 0 at 2 s for ``rotor-loss`` unless given), checked."""
    if scenario == "throw":
        if failure is not None:
            raise UsageError("a throw has no rotor failure")
        return None
    if scenario == "rotor-loss" and failure is None:
        failure = Failure(rotor=0, time_s=min(2.0, duration / 2))
    if failure is not None:
        failure.check(vehicle, duration)
    if controller == "ftc" and (failure is None or not failure.complete):
        raise UsageError(
            "the fault-tolerant controller is for a complete rotor loss: give a failure with "
            "efficiency 0 (scenario rotor-loss)"
        )
    return failure


def _rates(cfg, params, preset):
    """The IMU rate, the simulation substeps per IMU sample and the IMU samples per position
    reading, which must divide each other."""
    rate = cfg.imu.rate_hz
    substeps = SIM_RATE_HZ / rate
    if abs(substeps - round(substeps)) > 1e-9 or substeps < 1:
        raise UsageError(
            f"preset {preset!r}: its IMU rate {rate:g} Hz must divide the simulation rate {SIM_RATE_HZ:g} Hz"
        )
    pos_rate = params.position()[0]
    every = rate / pos_rate
    if abs(every - round(every)) > 1e-9 or every < 1:
        raise UsageError(f"the position sensor's rate {pos_rate:g} Hz must divide the IMU rate {rate:g} Hz")
    return rate, int(round(substeps)), int(round(every))


def _recovery_params(values: dict | None) -> RecoveryParams:
    """A throw's recovery parameters from ``estimator_params`` (names of :class:`RecoveryParams`)."""
    unknown = sorted(set(values or {}) - {f.name for f in fields(RecoveryParams)})
    if unknown:
        raise UsageError(f"unknown recovery parameter(s) {', '.join(unknown)}; see quadest.recovery.RecoveryParams")
    return RecoveryParams(**(values or {}))


def _position_sensing(sm, params, rate, every, n, x0, rng, rotors, seed):
    """The loop's sensing with the position sensor ``params`` names (its noise from ``rng``)
    and the barometer (its noise from the ``seed``'s own generator)."""
    _, noise, latency, _ = params.position()
    n_read = (n - 1) // every + 1
    return build.sensing(
        sm,
        dt=1.0 / rate,
        rotors=rotors,
        position0=x0[0:3],
        every=every,
        delay=int(round(latency * rate)),
        noise=rng.normal(0.0, 1.0, (n_read, 3)) * noise,
        n=n,
        baro=barometer_draws(np.arange(n) / rate, params, seed),
    )


InLoop = namedtuple("InLoop", ["name", "args", "peer", "instance"])
"""An estimator in the loop: its name, the compiled loop's estimator arguments (None: no
estimator), or a peer; the estimator (None: the truth)."""


def _in_loop(estimator, cfg, rate, estimator_params):
    """What the controller reads (a :data:`~quadest.flight.phases.NAV` name) and the estimator."""
    declination = math.radians(cfg.environment.declination_deg)
    if isinstance(estimator, str) and estimator == "truth":
        return "truth", InLoop("truth", None, None, None)
    if isinstance(estimator, Estimator):
        est = estimator
    elif ESTIMATORS[estimator].peer:
        est = make_filter(estimator, declination=declination, use_mag=cfg.mag.rate_hz > 0)
    else:
        est = make_filter(estimator, declination=declination, **(estimator_params or {}))
    return "filter", InLoop(est.name, None if est.peer else tuple(est.compiled()), est if est.peer else None, est)


def _start_converged(est: InLoop, sm, q0, cfg, seconds: float) -> None:
    """The estimator in the loop fed ``seconds`` of its sensors' readings at rest at the start
    attitude ``q0`` (:func:`~quadest.flight.start.rest_readings`): started as a flying vehicle's
    is, converged (an oracle of the start; none for the truth)."""
    if est.instance is None or seconds <= 0.0:
        return
    rate = cfg.imu.rate_hz
    readings = rest_readings(sm, q0, int(round(seconds * rate)), rate, cfg.mag.rate_hz)
    converge(est.instance, est.peer is not None, readings, rate)


def _run(x, loop, est: InLoop):
    """Fly ``loop`` from ``x``: compiled with a compiled estimator, or sample by sample
    with a peer's streaming update. Returns ``(status, samples flown)``."""
    if est.peer is None:
        return closed_loop(x, loop, est.args)
    sensing = loop.sensing
    for k in range(len(loop.record.phase)):
        sense_sample(k, x, loop)
        status = act_sample(k, x, loop, est.peer.update(loop.nav.clip.gyr, sensing.acc, sensing.mag, dt=sensing.dt))
        if status != OK:
            return status, flown(status, k)
    return OK, len(loop.record.phase)


def _flight(out, t, vehicle, cfg, seed, failure, meta, processes, loop_s, phases=False) -> Flight:
    """The :class:`Flight` of the loop's record ``out`` (its recording sampled as every
    simulation samples, with the loop's readings; the ``failure`` in its ``meta``; the phase of
    each sample with ``phases``: a flight that may recover in flight)."""
    imbalance = np.zeros((len(t), vehicle.rotors))
    if failure is not None:
        meta["failure"] = failure.to_dict()  # imbalance in kg m
        k0, _, _, imb = failure.profile(cfg.imu.rate_hz, len(t), vehicle.rotors)
        imbalance[k0:] = imb[-1]
        imbalance[k0 : k0 + len(imb)] = imb[: len(t) - k0]
    return flight_of(
        out, t, vehicle, cfg=cfg, seed=seed, meta=meta, processes=processes, loop_s=loop_s, imbalance=imbalance,
        modes=out["phase"] if phases else None,
    )  # fmt: skip


def resample(
    flight: Flight, config: SimConfig, *, imbalance: ArrayLike | None = None, seed: int | None = None
) -> Recording:
    """The recording a flight would have given with other sensors (``config``) or another
    propeller ``imbalance`` (kg m, one per rotor from the failure on, or one row per sample):
    the same motion sampled again (:func:`quadest.sim.flown.flown_recording`). The motion does
    not change: with the truth in the loop it does not depend on the sensors (the imbalance's
    response is not fed back either). Seed: the flight's unless given."""
    rec = flight.recording
    imb = flight.imbalance
    if imbalance is not None:
        imbalance = np.asarray(imbalance, float)
        if imbalance.ndim == 1:
            fail = rec.meta.get("failure")
            start = 0 if fail is None else int(np.searchsorted(rec.t, fail["time_s"] - 1e-9))
            imb = np.zeros((len(rec), len(imbalance)))
            imb[start:] = imbalance
        else:
            imb = imbalance
    meta = {
        k: rec.meta[k]
        for k in ("scenario", "preset", "vehicle", "controller", "estimator", "position_sensor", "failure")
        if k in rec.meta
    }
    return flown_recording(
        rec.t,
        flight.states,
        flight.derivs,
        flight.thrusts,
        flight.vehicle,
        cfg=config,
        seed=rec.meta["seed"] if seed is None else seed,
        eta=flight.eta,
        imbalance=imb,
        meta={**meta, "resampled": True},
    )


def fly_many(
    scenario: str,
    estimators: Iterable[str],
    seeds: Iterable[int],
    *,
    on_flight: Callable[[Flight], None] | None = None,
    **kwargs,
) -> list[dict]:
    """Fly ``scenario`` with each of ``estimators`` in the loop for each seed. For every seed the
    flight with ``truth`` in the loop comes first, and each estimator is also run over that
    flight's recording afterwards (``offline``: the same estimator, the motion not its own), so
    that what the loop changes shows. ``on_flight(flight)`` sees every flight as it ends.
    Returns the summaries."""
    estimators = [e for e in estimators if e != "truth"]
    out = []
    for seed in seeds:
        base = fly(scenario, estimator="truth", seed=seed, **kwargs)
        out.append(base.summary)
        if on_flight:
            on_flight(base)
        for name in estimators:
            f = fly(scenario, estimator=name, seed=seed, **kwargs)
            if name in ESTIMATORS:
                f.summary["offline_on_truth_flight"] = offline_errors(base, name)
            out.append(f.summary)
            if on_flight:
                on_flight(f)
    return out
