"""Sensors sampled from a flown vehicle: the states of the rotor-level model
(:mod:`quadest.models.multirotor`) become a :class:`~quadest.data.Recording` with the same
sensor models as the prescribed scenarios (:func:`quadest.sim.simulator.sample_sensors`), so
every command (estimate, compare, recover, calibrate) reads a flown flight."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from quadest.data.recording import Recording
from quadest.models.multirotor import MultirotorParams
from quadest.sim import sensors
from quadest.sim.params import SimConfig
from quadest.sim.sensors import motor_current
from quadest.sim.simulator import build_config, sample_sensors
from quadest.sim.truth import Truth


def flown_recording(
    t,
    states,
    derivs,
    thrusts,
    vehicle: MultirotorParams,
    *,
    cfg: SimConfig | None = None,
    seed: int = 0,
    eta=None,
    imbalance=None,
    meta: dict | None = None,
    readings=None,
    processes=None,
) -> Recording:
    """A recording of a flight: ``states``, their derivatives and the rotor thrusts at the IMU
    instants ``t`` (one row each, at ``cfg.imu.rate_hz``). ``cfg`` gives the sensors (default:
    the bebop2 preset's); the vehicle's own mass, thrust and rotors set the vibration load and
    the motor current that disturbs the magnetometer. ``eta``: the rotor efficiencies, one row
    per sample or one for all (default: all rotors intact); ``imbalance`` likewise, each
    propeller's imbalance in kg m (default: none). The rotor speeds (the states' last columns)
    and imbalances set each rotor's vibration
    (:func:`quadest.sim.sensors.rotor_vibration_step`). ``readings``: ``(gyr, acc, mag)``
    sampled in a closed loop from the same flight and seed (the same compiled sensors); they
    must agree with what this function samples (else ValueError: the loop's inputs to the
    sensors have parted from the flight's), and they are what the recording holds, as the estimator in
    the loop read them. ``processes``: the sensor draws the loop made (for the rows it
    planned; a run that ended early uses their first rows), instead of drawing them from ``seed``."""
    cfg = (cfg or build_config("bebop2")).validate()
    t = np.asarray(t, float)
    states, derivs, thrusts = (np.asarray(a, float) for a in (states, derivs, thrusts))
    n = len(t)
    if states.shape[0] != n or derivs.shape != states.shape or thrusts.shape != (n, vehicle.rotors):
        raise ValueError("flown_recording: t, states, derivs and thrusts must have one row per IMU sample")
    eta = np.ones(vehicle.rotors) if eta is None else np.asarray(eta, float)
    eta = np.broadcast_to(eta, (n, vehicle.rotors))
    imbalance = np.broadcast_to(
        np.zeros(vehicle.rotors) if imbalance is None else np.asarray(imbalance, float), (n, vehicle.rotors)
    )
    active = np.maximum(1, (eta > 0).sum(axis=1))
    hover_thrust = vehicle.mass_kg * vehicle.gravity / vehicle.rotors
    load = thrusts.sum(axis=1) / active / hover_thrust
    thrust_to_weight = vehicle.rotors * vehicle.k_f * vehicle.omega_max**2 / (vehicle.mass_kg * vehicle.gravity)
    truth = Truth(
        t=t,
        q=states[:, 6:10],
        gyr=states[:, 10:13],
        gyr_dot=derivs[:, 10:13],
        pos=states[:, 0:3],
        vel=states[:, 3:6],
        acc_n=derivs[:, 3:6],
        current=motor_current(load, active, thrust_to_weight),
        rotor_load=load,
        meta={
            "flown": True,
            "rotor_efficiency_end": eta[-1].tolist(),
            "rotor_imbalance_end_kg_m": imbalance[-1].tolist(),
        },
        rotor_speeds=states[:, 13:],
        rotor_imbalance=imbalance,
    )
    rng = [np.random.default_rng(s) for s in np.random.SeedSequence(int(seed)).spawn(4)]
    k = np.round((t - t[0]) * cfg.imu.rate_hz).astype(np.int64)
    has_mag = sensors.mag_rows(k, cfg.imu.rate_hz, cfg.mag.rate_hz)
    info = {"source": "quadest fly", "seed": int(seed), **(meta or {})}
    rec, _, _ = sample_sensors(truth, cfg, np.ones(n, bool), has_mag, rng, info, processes=processes, vehicle=vehicle)
    if readings is not None:
        loop = {}
        for name, got in zip(("gyr", "acc", "mag"), readings):
            ref = getattr(rec, name)
            got = np.asarray(got, float)
            same = np.isnan(ref) == np.isnan(got)
            diff = np.abs(np.nan_to_num(got) - np.nan_to_num(ref))
            if (
                got.shape != ref.shape
                or not same.all()
                or (diff > READINGS_RTOL * (1.0 + np.abs(np.nan_to_num(ref)))).any()
            ):
                raise ValueError(
                    f"flown_recording: the closed loop's {name} readings differ from the sensor model's "
                    f"(largest difference {np.nanmax(diff) if diff.size else 0:.3g})"
                )
            loop[name] = got
        rec = replace(rec, **loop)
    return rec


READINGS_RTOL = 1e-9
"""How far a closed loop's readings may be from the batch sensor model's: rounding only (the
sums are the same, in the same order, except the 3x3 matrix products)."""
