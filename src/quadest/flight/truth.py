"""The SE(3) controller flying on the true state (no sensors, no estimator): the vehicle model
and controller on their own, as RotorPy flies them (:mod:`quadest.flight.crosscheck`), through
the one closed loop."""

from __future__ import annotations

import numpy as np

from quadest.control import SE3Params
from quadest.flight import build
from quadest.flight.common import sensors_for
from quadest.flight.loop import closed_loop
from quadest.models.multirotor import MultirotorParams
from quadest.sim import build_config
from quadest.sim.faults import Failure


def fly_se3(
    x0,
    reference,
    *,
    vehicle: MultirotorParams | None = None,
    gains: SE3Params | None = None,
    rate_hz: float = 1000.0,
    failure: Failure | None = None,
    return_eta: bool = False,
):
    """Fly the vehicle from state ``x0`` along ``reference`` (``(p_d, v_d, a_d, yaw_d)``, one row
    per step at ``rate_hz``) with the SE(3) controller on the true state (an oracle), a
    ``failure`` striking when it is due; nothing ends the flight. Returns the states after each
    step (steps, 13 + N) and the rotor commands (steps, N); with ``return_eta`` also the rotor
    efficiencies per step."""
    vehicle = vehicle or MultirotorParams()
    reference = [np.ascontiguousarray(a, dtype=float) for a in reference]
    steps = len(reference[3])
    x = np.array(x0, dtype=float)
    if x.shape != (13 + vehicle.rotors,):
        raise ValueError(f"x0 must have {13 + vehicle.rotors} values, got {x.shape}")
    if failure is not None:
        failure.check(vehicle, steps / rate_hz)
    _, sm = sensors_for(build_config("bebop2"), 1, 0, vehicle)  # of the record's type; not sampled
    loop = build.loop(
        plant=build.plant(
            vehicle,
            h=1.0 / rate_hz,
            substeps=1,
            ground_z=np.inf,
            failure=failure,
            sampled=(rate_hz, steps),
            limits=False,
        ),
        sensing=build.sensing(sm, dt=1.0 / rate_hz, rotors=vehicle.rotors, position0=x[0:3], n=steps, on=False),
        nav=build.navigation("true-state", x),
        detection=build.detection(),
        bank=build.bank(),
        control=build.control(
            {"flying": "se3"},
            gains=(gains or SE3Params()).gains(vehicle),
            ftc=build.unused_ftc_gains(vehicle),
            reference=reference,
            cmd0=np.zeros(vehicle.rotors),
        ),
        n=steps,
        rotors=vehicle.rotors,
        phase="flying",
    )
    closed_loop(x, loop)
    record = loop.record
    states = np.vstack([record.x[1:], x[None]])  # after each step
    return (states, record.cmd, record.eta) if return_eta else (states, record.cmd)
