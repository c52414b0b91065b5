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
from dataclasses import fields, replace

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
from quadest.errors import UsageError
from quadest.filters import ESTIMATORS, Estimator, make_filter
from quadest.flight import build, inflight
from quadest.flight.common import (
    SIM_RATE_HZ,
    Flight,
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
from quadest.flight.spec import FlightSpec, Resolved
from quadest.flight.start import converge, rest_readings
from quadest.flight.summary import add_detection, offline_errors, summarize
from quadest.flight.throw import fly_throw
from quadest.recovery import RecoveryParams
from quadest.rotation import euler_to_quat
from quadest.sim.flown import flown_recording
from quadest.sim.params import SimConfig
from quadest.sim.wind import wind_samples

FLIGHT_SCENARIOS = ("hover", "trajectory", "aggressive", "rotor-loss", "throw")


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


def fly(spec: FlightSpec | str = "trajectory", /, **changes) -> Flight:
    """Fly ``spec`` (a :class:`~quadest.flight.spec.FlightSpec`, or a scenario's name) with
    ``changes`` to its fields: ``fly("rotor-loss", estimator="robust", seed=3)``.

    Scenarios: ``hover`` (hold the origin from a disturbed start), ``trajectory`` (a 1 m circle
    at 0.2 Hz), ``aggressive`` (a figure eight drawn from the seed, 1-1.5 m by 0.3-0.45 m at
    0.3-0.35 Hz, the heading swinging ±2.5 rad, grown in over 2 s), ``rotor-loss`` (hover; rotor
    0 lost at 2 s unless ``failure`` says otherwise), ``throw`` (released tumbling; the recovery
    paper's bank of EKFs and logic in the loop, then the recovery controller:
    :mod:`quadest.flight.throw`; estimator ``recovery`` or ``truth``, sensors ``fma`` by default).
    The estimator in the loop is a quadest filter or peer by name (with the preset's declination;
    started converged at the start attitude, ``params.estimator_start_s``: an oracle of the
    start), an :class:`~quadest.filters.Estimator` (it continues from its state), or ``truth`` (an
    oracle: the controller reads the true state). ``controller``: ``se3`` (nominal only) or
    ``ftc`` (SE(3), then the fault-tolerant controller once a complete rotor loss is known,
    holding the point the reference had reached then: a trajectory with a loss ends in a relaxed
    hover). ``detection``: how the fault-tolerant controller learns of a rotor loss: ``oracle``
    (told ``params.detect_delay_s`` after it, the lost rotor's command zeroed from the failure
    on), ``rotor-speeds`` or ``commands`` (found by the detector of :mod:`quadest.detect` with a
    model of the vehicle off by ``params.detector_model_error``), or a
    :class:`~quadest.detect.DetectorParams` (its ``rotor_speeds`` says which).
    ``params.collision`` and ``params.divergence``: a collision and the checks that start a recovery
    in flight (:mod:`quadest.flight.collision`; with the checks the sensors are ``fma`` by default).
    ``params.wind``: the air's motion (:class:`~quadest.sim.wind.WindParams`; its realisation
    drawn from the seed), which the vehicle flies in and nothing in the loop knows.
    ``params.landing_m_s``: the flight ends with a hard landing (:func:`landing_reference`) on
    sprung legs (:func:`~quadest.models.multirotor.with_ground`)."""
    spec = replace(FlightSpec(spec) if isinstance(spec, str) else spec, **changes)
    r = spec.resolved()
    meta = {"scenario": f"flown {spec.scenario}", "preset": r.preset, "vehicle": r.vehicle_name}
    if r.truth_drawn:
        meta["truth_drawn"] = dict(r.truth_drawn)
    if spec.scenario == "throw":
        meta.update(controller="se3 after recovery", estimator=r.estimator)
        return fly_throw(
            estimator=r.estimator, duration=r.duration, seed=spec.seed, cfg=r.cfg, vehicle=r.vehicle,
            params=r.params, se3=spec.se3, throw=spec.throw, recovery=_recovery_params(spec.estimator_params),
            meta=meta,
        )  # fmt: skip
    rate = r.rates[0]
    # the truth flies (its start, its sensors, the plant); the model is what the software knows
    t, rng_mocap, (x0, ref) = _referenced(spec.scenario, r.duration, rate, spec.seed, r.truth, r.params)
    processes, sm = sensors_for(r.cfg, len(t), spec.seed, r.truth)  # the generators and order of flown_recording's
    nav, est = _in_loop(r.estimator, r.cfg, rate, spec.estimator_params)
    if not isinstance(r.estimator, Estimator):  # one given continues from its state
        _start_converged(est, sm, x0[6:10], r.cfg, r.params.estimator_start_s)
    detection = spec.detection
    detection, detector = (detection, None) if isinstance(detection, str) else (detector_mode(detection), detection)
    loop = _loop(spec, r, (t, x0, ref), (sm, rng_mocap), (nav, est), (detection, detector))
    x, t0 = x0.copy(), time.perf_counter()
    (status, flown), loop_s = _run(x, loop, est), time.perf_counter() - t0
    if flown == 0:
        raise ValueError(f"the flight ended before its first sample ({STATUS[status]})")
    out = flown_arrays(loop.record, flown)
    meta.update(controller=r.controller, estimator=est.name, position_sensor=r.params.position_sensor)
    flight = _flight(out, t[:flown], r, spec.seed, meta, (processes, loop_s))
    flight.summary = summarize(flight, spec, r, status, est.name, (loop.control.p_d, loop.control.yaw_d))
    if detection != "oracle":
        add_detection(flight, loop.detection, detection, r.failure, flown)
    flight.summary.update(landing_summary(loop.landing, t[:flown]))
    if r.truth_drawn:
        flight.summary["truth_drawn"] = dict(r.truth_drawn)
    if r.watching is not None or r.event is not None:
        flight.summary.update(inflight.summary(flight, out, loop, r.event, status, rate))
    return flight


def _loop(spec: FlightSpec, r: Resolved, motion, sensing, estimating, detecting):
    """The compiled loop's record of one flight: ``motion`` the sample times, start state and
    reference; ``sensing`` the sensor model and the position sensor's generator; ``estimating``
    what the controller reads and the estimator; ``detecting`` the detection mode and the
    detector's parameters (None: the defaults)."""
    (t, x0, ref), (sm, rng_mocap), (nav, _), (detection, detector) = motion, sensing, estimating, detecting
    (rate, substeps, every), vehicle, params, seed, n = r.rates, r.vehicle, r.params, spec.seed, len(t)
    ftc, gains = spec.ftc or FtcParams(), (spec.se3 or SE3Params()).gains(vehicle)
    oracle = detection == "oracle"
    return build.loop(
        plant=_plant(r.truth, params, r.failure, t, (rate, substeps), oracle, seed, r.event),
        sensing=_position_sensing(sm, params, rate, every, n, x0, rng_mocap, vehicle.rotors, seed),
        nav=build.navigation(
            nav,
            x0,
            position_gain(params, rate),
            clip_rate_model(params, vehicle, r.cfg, seed, n),
            inflight.reset(r.event, estimating[1], rate),
        ),  # fmt: skip
        bank=build.bank() if r.watching is None else inflight.bank(vehicle, r.cfg, gains),
        watch=inflight.watch(r.watching, detector_model(vehicle, params, seed)[0], rate, rate / every),
        control=build.control(
            {**dict(REGISTRY[r.controller].phases), **({} if r.watching is None else {"nominal": "recovery"})},
            gains=gains,
            ftc=ftc_gains(ftc, vehicle, r.controller, r.failure, oracle),
            reference=ref,
            fault=known_fault(r.controller, r.failure, params, rate, n) if oracle else (-1, -1),
            cmd0=x0[13:].copy(),  # what the rotors were doing (a detector reads it before the first command)
            limited_k=(descent := descent_start(ref[1][:, 2], params.landing_m_s)),  # PX4's thrust limits
            **inflight.recovery_control(r.watching),
        ),
        detection=detection_record(detection, detector, vehicle, params, seed, n, r.cfg.acc.lever_arm),
        landing=land_detector(vehicle, rate, descent, params.landing_m_s * params.land_detector),
        n=n,
        rotors=vehicle.rotors,
        phase="flying",
    )


def check_flight(spec: FlightSpec, seeds=(0,)) -> None:
    """Refuse, in one line and before anything is flown or written, what :func:`fly` would refuse
    of ``spec`` for each of ``seeds`` (a collision is drawn from the seed)."""
    for seed in seeds:
        r = spec.resolved(seed)
        if spec.scenario != "throw":
            _referenced(spec.scenario, r.duration, r.rates[0], seed, r.vehicle, r.params)


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
        sampled=(rate, len(t)),
        zero_failed=oracle,
        collision=event,
        wind=wind,
        legs=params.landing_m_s > 0.0,
    )


def _referenced(scenario, duration, rate, seed, vehicle, params):
    """The flight's sample times, the motion capture's generator, and the start state and
    reference (:func:`_reference`, a landing included), from the seed."""
    t = np.arange(int(round(duration * rate))) / rate
    rng_ref, rng_mocap = (np.random.default_rng(s) for s in np.random.SeedSequence([int(seed), 13]).spawn(2))
    return t, rng_mocap, _reference(scenario, t, rng_ref, vehicle, params)


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


def _flight(out, t, r: Resolved, seed, meta, run) -> Flight:
    """The :class:`Flight` of the loop's record ``out`` (its recording sampled as every
    simulation samples, with the loop's readings; the failure in its ``meta``; the phase of each
    sample when the flight may recover in flight); ``run``: the sensors' processes and the
    loop's wall time (s)."""
    (processes, loop_s), vehicle, failure = run, r.truth, r.failure
    imbalance = np.zeros((len(t), vehicle.rotors))
    if failure is not None:
        meta["failure"] = failure.to_dict()  # imbalance in kg m
        k0, _, _, imb = failure.profile(r.cfg.imu.rate_hz, len(t), vehicle.rotors)
        imbalance[k0:] = imb[-1]
        imbalance[k0 : k0 + len(imb)] = imb[: len(t) - k0]
    return flight_of(
        out, t, vehicle, cfg=r.cfg, seed=seed, meta=meta, processes=processes, loop_s=loop_s, imbalance=imbalance,
        modes=out["phase"] if r.watching is not None else None,
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
