"""Flights of the rotor-level vehicle (issue #13, in progress; docs/vehicle.md): a controller
flies the vehicle model, and its sensors are sampled from the flight into a recording that every
command reads. Layer 2: it joins the controllers and the simulator's sensors."""
from __future__ import annotations

import numpy as np

from quadest.control import Failure, circle_reference, fly_se3, hover_reference
from quadest.data.recording import Recording
from quadest.models.multirotor import MultirotorParams, derivatives
from quadest.rotation import euler_to_quat
from quadest.sim import build_config
from quadest.sim.flown import flown_recording

SIM_RATE_HZ = 1000.0
REFERENCES = ("hover", "circle")


def fly(reference: str = "circle", *, duration: float = 20.0, seed: int = 0, preset: str = "bebop2",
        vehicle: MultirotorParams | None = None, failure: Failure | None = None) -> tuple[Recording, np.ndarray]:
    """Fly ``reference`` (``hover``: hold the origin from a disturbed start; ``circle``: a 1 m
    circle at 0.2 Hz) with the SE(3) controller on the true state at 1 kHz, a rotor ``failure``
    striking when due, and sample the ``preset``'s sensors from the flight. Returns the
    recording and the states at its rows."""
    if reference not in REFERENCES:
        raise ValueError(f"unknown reference {reference!r}; references: {', '.join(REFERENCES)}")
    if not (np.isfinite(duration) and 0 < duration <= 3600):
        raise ValueError(f"duration must be between 0 and 3600 s, got {duration}")
    vehicle = vehicle or MultirotorParams()
    cfg = build_config(preset)
    step = SIM_RATE_HZ / cfg.imu.rate_hz
    if abs(step - round(step)) > 1e-9:
        raise ValueError(f"the IMU rate {cfg.imu.rate_hz} Hz must divide the simulation rate {SIM_RATE_HZ} Hz")
    steps = int(round(duration * SIM_RATE_HZ))
    t = np.arange(1, steps + 1) / SIM_RATE_HZ
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 13]))
    x0 = vehicle.hover_state()
    if reference == "hover":
        ref = hover_reference(steps)
        x0[0:3] = rng.uniform(-0.5, 0.5, 3)
        x0[6:10] = euler_to_quat(np.concatenate([rng.uniform(-0.2, 0.2, 2), rng.uniform(-np.pi, np.pi, 1)]))
    else:
        ref = circle_reference(t)
        x0[0], x0[4] = 1.0, 2 * np.pi * 0.2
    states, cmds, etas = fly_se3(x0, ref, vehicle=vehicle, rate_hz=SIM_RATE_HZ, failure=failure, return_eta=True)
    rows = np.arange(int(round(step)) - 1, steps, int(round(step)))
    eta = np.ascontiguousarray(etas[rows])
    dx, thrust = np.empty_like(states[rows]), np.empty((len(rows), vehicle.rotors))
    derivatives(np.ascontiguousarray(states[rows]), np.ascontiguousarray(cmds[rows]), eta, vehicle.vehicle(), dx,
                thrust)
    meta = {"scenario": f"flown {reference}", "preset": preset, "controller": "se3 (true state)"}
    if failure is not None:
        meta["failure"] = {"rotor": failure.rotor, "time_s": failure.time_s, "efficiency": failure.efficiency}
    rec = flown_recording(t[rows] - t[rows][0], states[rows], dx, thrust, vehicle, cfg=cfg, seed=seed, eta=eta,
                          meta=meta)
    return rec, states[rows]


__all__ = ["REFERENCES", "SIM_RATE_HZ", "fly"]
