"""A flight as one record: :class:`FlightSpec` says what flies (scenario, vehicle, failure),
with what (estimator, controller, detection, sensors) and in what (the flight's parameters:
position sensing, wind, collision, landing); :meth:`FlightSpec.resolved` checks it and works out
what the loop needs (defaults, the rates, the in-flight recovery), refusing in one line what
cannot fly. :func:`~quadest.flight.fly.fly` flies one."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np

from quadest.control import FtcParams, SE3Params
from quadest.control.registry import CONTROLLERS as REGISTRY
from quadest.detect import DetectorParams
from quadest.errors import UsageError
from quadest.filters import ESTIMATORS, Estimator, filter_name
from quadest.flight import inflight
from quadest.flight.common import SIM_RATE_HZ, FlightParams
from quadest.flight.throw import ThrowParams
from quadest.models.multirotor import MultirotorParams, vehicle_preset
from quadest.models.truth import Truth, TruthSpread, draw_truth, truth_spread
from quadest.recovery.divergence import CHECKS, DivergenceParams
from quadest.sim import build_config
from quadest.sim.faults import Failure
from quadest.sim.params import SimConfig

FLIGHT_SCENARIOS = ("hover", "trajectory", "aggressive", "rotor-loss", "throw")


@dataclass(frozen=True)
class FlightSpec:
    """One flight. ``scenario``: ``hover``, ``trajectory``, ``aggressive``, ``rotor-loss`` or
    ``throw`` (:func:`~quadest.flight.fly.fly` says what each flies); ``estimator``: a name, an
    :class:`~quadest.filters.Estimator` (it continues from its state) or ``truth``;
    ``controller``: ``se3`` or ``ftc`` (default ``ftc`` for ``rotor-loss``, else ``se3``);
    ``duration`` in s (default per scenario); ``preset`` or ``config``: the sensors; ``vehicle``:
    a :class:`~quadest.models.multirotor.MultirotorParams` or a preset's name (default
    ``recovery``); ``failure``: a :class:`~quadest.sim.faults.Failure` (default for
    ``rotor-loss``: rotor 0 at 2 s); ``se3``, ``ftc``: the controllers' gains; ``params``: the
    flight's :class:`~quadest.flight.common.FlightParams`; ``estimator_params``: the named
    estimator's parameters; ``throw``: a throw's; ``detection``: ``oracle``, ``rotor-speeds``,
    ``commands`` or a :class:`~quadest.detect.DetectorParams`; ``truth``: the vehicle that
    flies when it is not the model (``vehicle``) that the estimator, the detector and the
    controllers know (:mod:`quadest.models.truth`): a
    :class:`~quadest.models.multirotor.MultirotorParams`, a
    :class:`~quadest.models.truth.TruthSpread` or a spread's name (``none``, ``default``) drawn
    from the seed; None: the model flies."""

    scenario: str = "trajectory"
    estimator: str | Estimator = "truth"
    controller: str | None = None
    duration: float | None = None
    seed: int = 0
    preset: str | None = None
    vehicle: MultirotorParams | str | None = None
    failure: Failure | None = None
    se3: SE3Params | None = None
    ftc: FtcParams | None = None
    params: FlightParams | None = None
    config: SimConfig | None = None
    estimator_params: dict | None = field(default=None, hash=False)
    throw: ThrowParams | None = None
    detection: str | DetectorParams = "oracle"
    truth: MultirotorParams | TruthSpread | str | None = None

    def resolved(self, seed: int | None = None) -> Resolved:
        """The flight checked and completed (:class:`Resolved`), for ``seed`` (default the
        spec's): a collision is drawn from the seed."""
        seed = self.seed if seed is None else seed
        estimator = filter_name(self.estimator) if isinstance(self.estimator, str) else self.estimator
        params = self.params or FlightParams()
        controller, duration = _check_request(self.scenario, estimator, self.controller, self.duration, params)
        vehicle = self.vehicle
        vehicle_name = vehicle if isinstance(vehicle, str) else ("recovery" if vehicle is None else "custom")
        vehicle = vehicle_preset(vehicle) if isinstance(vehicle, str) else (vehicle or MultirotorParams())
        failure = _checked_failure(self.scenario, self.failure, controller, vehicle, duration)
        event, watching = _in_flight_request(self.scenario, params, seed, duration)
        preset, cfg = _sensors(self.preset, self.config, self.scenario, watching)
        rate, substeps, every = _rates(cfg, params, preset)
        truth = _truth(self.truth, vehicle, seed, self.scenario)
        if truth.sensors:
            cfg = sensors_of(cfg, truth.sensors)
        if truth.speed_noise is not None:
            params = replace(params, speed_noise=truth.speed_noise)
        return Resolved(
            estimator, controller, duration, vehicle, vehicle_name, failure, params, event, watching, preset, cfg,
            (rate, substeps, every), truth.vehicle, truth.drawn,
        )  # fmt: skip


class Resolved(NamedTuple):
    """A :class:`FlightSpec` checked and completed: the estimator's canonical name (or the
    instance), the controller, the duration (s), the vehicle and its name, the failure (with the
    scenario's default), the flight's parameters, the collision (None: none) and the divergence
    checks (None: off), the sensors' preset name and configuration, and ``rates``: the IMU rate
    (Hz), the simulation substeps per IMU sample and the IMU samples per position reading."""

    estimator: str | Estimator
    controller: str
    duration: float
    vehicle: MultirotorParams
    vehicle_name: str
    failure: Failure | None
    params: FlightParams
    event: object
    watching: DivergenceParams | None
    preset: str
    cfg: SimConfig
    rates: tuple
    truth: MultirotorParams
    truth_drawn: dict


def _truth(truth, model: MultirotorParams, seed: int, scenario: str) -> Truth:
    """The vehicle that flies (:class:`~quadest.models.truth.Truth`): ``model`` for None or
    ``none``, a spread drawn from the seed's own generator, or the one given."""
    if truth is None or (isinstance(truth, str) and truth == "none"):
        return Truth(model, {}, None, {})
    if scenario == "throw":
        raise UsageError("a throw flies its model: no truth apart from it")
    if isinstance(truth, MultirotorParams):
        if truth.rotors != model.rotors:
            raise UsageError(f"truth: {truth.rotors} rotors, the model has {model.rotors}")
        return Truth(truth, {}, None, {})
    spread = truth_spread(truth) if isinstance(truth, str) else truth
    if not isinstance(spread, TruthSpread):
        raise UsageError(f"truth: a MultirotorParams, a TruthSpread or a spread's name, not {type(truth).__name__}")
    return draw_truth(model, np.random.default_rng(np.random.SeedSequence([int(seed), 41])), spread)


def sensors_of(cfg: SimConfig, changes: dict) -> SimConfig:
    """``cfg`` with a truth's sensors (``{"section.field": value}``, fixed values that replace the
    configuration's draws)."""
    for key, value in changes.items():
        section, _, name = key.partition(".")
        cfg = replace(cfg, **{section: replace(getattr(cfg, section), **{name: value})})
    return cfg.validate()


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


def _check_request(scenario, estimator, controller, duration, params: FlightParams):
    """The controller and duration of a flight (with a collision in ``params``, 16 s by default: the
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
        duration = COLLISION_S if params.collision != "none" and scenario != "throw" else DEFAULT_DURATION[scenario]
    duration = float(duration)
    if not (math.isfinite(duration) and 0 < duration <= 3600):
        raise UsageError(f"duration must be between 0 and 3600 s, got {duration}")
    return controller, duration


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
