"""What the loop knows of a rotor failure, set up for :func:`quadest.flight.fly`: the detector
in the loop and its own model of the vehicle (drawn off the flight's), the oracle's known fault,
the fault-tolerant controller's gains for each rotor it may give up, and the model that predicts
a clipped gyroscope axis's rate."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from quadest.detect import DetectorParams
from quadest.errors import UsageError
from quadest.flight import build
from quadest.flight.detection import DETECTION_MODES


def detector_mode(detector: DetectorParams) -> str:
    return "rotor-speeds" if detector.rotor_speeds else "commands"


def known_fault(controller, failure, params, rate, n):
    """The oracle's fault: the fault-tolerant controller flies ``detect_delay_s`` after a complete
    loss, giving the lost rotor up (known, not detected); ``(-1, -1)`` for none."""
    if controller != "ftc":
        return -1, -1
    return min(n, int(round(failure.lost_s * rate)) + int(round(params.detect_delay_s * rate))), failure.rotor


def ftc_gains(ftc, vehicle, controller, failure, oracle):
    """The fault-tolerant gains for each rotor that may be lost: with the oracle only the known
    rotor's are needed (every entry), with a detector each rotor's."""
    if controller == "ftc" and not oracle:
        return ftc.all_gains(vehicle)
    return (ftc.gains(vehicle, failure.rotor if controller == "ftc" else 0),) * vehicle.rotors


def detection_record(mode, detector, vehicle, params, seed, n, imu_position):
    """The detector in the loop, with its own model of the vehicle (the flight's, each of mass,
    inertia and thrust coefficient off by a factor drawn per flight), the sensors' lever arm
    ``imu_position`` off by a distance drawn per flight, and the rotor speed readings' noise,
    all from the flight's seed."""
    if mode not in DETECTION_MODES:
        raise UsageError(f"unknown detection {mode!r}; detection: {', '.join(DETECTION_MODES)}")
    if mode == "oracle":
        return build.detection()
    model, rng_speed, imu_error = detector_model(vehicle, params, seed)
    noise = rng_speed.standard_normal((n, vehicle.rotors)) * params.speed_noise
    imu = np.asarray(imu_position, float) + imu_error
    return build.detection(mode, vehicle=model, params=detector, n=n, noise=noise, imu_position=imu)


def detector_model(vehicle, params, seed):
    """The detector's model of the vehicle (the flight's, each of mass, inertia and thrust
    coefficient off by a factor within ``params.detector_model_error`` drawn per flight), the
    generator of its rotor speed readings' noise and the error of the IMU's position it is given
    (within ``params.detector_imu_error`` per axis), all from the flight's seed."""
    rng_model, rng_speed = (np.random.default_rng(s) for s in np.random.SeedSequence([int(seed), 29]).spawn(2))
    e = params.detector_model_error
    model = replace(
        vehicle,
        mass_kg=vehicle.mass_kg * (1 + rng_model.uniform(-e, e)),
        inertia=tuple(np.asarray(vehicle.inertia) * (1 + rng_model.uniform(-e, e, 3))),
        k_f=vehicle.k_f * (1 + rng_model.uniform(-e, e)),
    )
    return model, rng_speed, rng_model.uniform(-1.0, 1.0, 3) * params.detector_imu_error


def clip_rate_model(params, vehicle, cfg, seed, n):
    """The rate of a clipped gyroscope axis (:mod:`quadest.flight.rate`) with the detector's
    model of the vehicle (:func:`detector_model`) and the gyroscope's range (the sensor's
    configuration, as an autopilot knows it); its rotor speed readings' noise from a generator
    of its own."""
    model = detector_model(vehicle, params, seed)[0]
    noise = None
    if params.clip_rate == "rotor-speeds":
        rng = np.random.default_rng(np.random.SeedSequence([int(seed), 31]))
        noise = rng.standard_normal((n, vehicle.rotors)) * params.speed_noise
    return build.clip_rate(
        params.clip_rate,
        vehicle=model,
        gyro_range=float(cfg.gyro.range),
        n=n,
        noise=noise,
        to_estimator=params.clip_rate_estimator,
    )
