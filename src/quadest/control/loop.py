"""The closed loop: the controller reads the state (for now the true one; the estimators come
into the loop next), commands the rotors, the vehicle model integrates (RK4), every step in
compiled code."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from quadest._jit import njit
from quadest.control.se3 import SE3Params, se3_command
from quadest.errors import UsageError
from quadest.models.multirotor import MultirotorParams, rk4_ws, work


@njit(cache=True)
def _fly(x, eta, V, G, h, p_d, v_d, a_d, yaw_d, fail_rotor, fail_step, fail_eta, out_x, out_cmd, out_eta):
    cmd = np.empty(V.rotor_pos.shape[0])
    W = work(V, x.shape[0])
    for k in range(yaw_d.shape[0]):
        if k == fail_step and fail_rotor >= 0:
            eta[fail_rotor] = fail_eta
        se3_command(x, p_d[k], v_d[k], a_d[k], yaw_d[k], G, V, cmd)
        if fail_rotor >= 0 and k >= fail_step and fail_eta == 0.0:
            cmd[fail_rotor] = 0.0  # a lost rotor: no thrust or torque, and its motor spins down
        rk4_ws(x, cmd, eta, V, h, W)
        for j in range(eta.shape[0]):
            out_eta[k, j] = eta[j]
        for j in range(x.shape[0]):
            out_x[k, j] = x[j]
        for j in range(cmd.shape[0]):
            out_cmd[k, j] = cmd[j]


def hover_reference(steps: int, position=(0.0, 0.0, 0.0), yaw: float = 0.0):
    """A fixed setpoint: ``(p_d, v_d, a_d, yaw_d)`` arrays of ``steps`` rows."""
    p = np.tile(np.asarray(position, float), (steps, 1))
    return p, np.zeros((steps, 3)), np.zeros((steps, 3)), np.full(steps, float(yaw))


def circle_reference(t, radius: float = 1.0, freq_hz: float = 0.2, height: float = 0.0):
    """A horizontal circle about the origin (north-east plane, at ``-height`` down), with its
    exact velocity and acceleration; heading held at 0."""
    t = np.asarray(t, float)
    w = 2 * np.pi * freq_hz
    c, s = np.cos(w * t), np.sin(w * t)
    p = np.column_stack([radius * c, radius * s, np.full(len(t), -height)])
    v = np.column_stack([-radius * w * s, radius * w * c, np.zeros(len(t))])
    a = np.column_stack([-radius * w * w * c, -radius * w * w * s, np.zeros(len(t))])
    return p, v, a, np.zeros(len(t))


@dataclass(frozen=True)
class Failure:
    """A rotor failure as an event: rotor ``rotor`` (0-based, the vehicle's order) keeps
    ``efficiency`` of its thrust and torque from ``time_s`` on. Efficiency 0 is a complete loss:
    no thrust or torque, and its motor spins down; between 0 and 1 a damaged rotor. A damaged
    propeller also has an ``imbalance`` (kg m: the missing mass times its radius; 5e-6 is a
    0.1 g chip at 5 cm), whose once-per-revolution force shakes the sensors
    (:func:`quadest.sim.sensors.rotor_vibration_step`); with an imbalance the efficiency may be 1."""

    rotor: int
    time_s: float
    efficiency: float = 0.0
    imbalance: float = 0.0

    @property
    def complete(self) -> bool:
        """Whether the rotor is lost (no thrust or torque)."""
        return self.efficiency == 0.0

    def check(self, vehicle: MultirotorParams, duration_s: float) -> None:
        if not 0 <= self.rotor < vehicle.rotors:
            raise UsageError(
                f"failure: rotor {self.rotor} does not exist (the vehicle has rotors 0 to {vehicle.rotors - 1})"
            )
        if not 0.0 <= self.time_s < duration_s:
            raise UsageError(f"failure: time {self.time_s} s lies outside the run (0 to {duration_s:g} s)")
        if not (math.isfinite(self.imbalance) and 0.0 <= self.imbalance <= MAX_IMBALANCE):
            raise UsageError(f"failure: imbalance must be between 0 and {MAX_IMBALANCE:g} kg m, got {self.imbalance}")
        if not 0.0 <= self.efficiency <= 1.0 or (self.efficiency == 1.0 and self.imbalance == 0.0):
            raise UsageError(
                f"failure: efficiency must be in [0, 1) (1 only for a propeller with an imbalance), "
                f"got {self.efficiency}"
            )


MAX_IMBALANCE = 1e-3
"""The largest propeller imbalance a failure may have (kg m): 1 g at 1 m, far beyond any
propeller's; what a user meaning grams by millimetres (5 rather than 5e-6) would give."""


def fly_se3(
    x0,
    reference,
    *,
    vehicle: MultirotorParams | None = None,
    gains: SE3Params | None = None,
    rate_hz: float = 1000.0,
    eta=None,
    failure: Failure | None = None,
    return_eta: bool = False,
):
    """Fly the vehicle from state ``x0`` along ``reference`` (``(p_d, v_d, a_d, yaw_d)``, one row
    per step at ``rate_hz``) with the SE(3) controller on the true state, a ``failure`` striking
    when it is due. Returns the states after each step (steps, 13 + N) and the rotor commands
    (steps, N); with ``return_eta`` also the rotor efficiencies per step."""
    vehicle = vehicle or MultirotorParams()
    gains = gains or SE3Params()
    p_d, v_d, a_d, yaw_d = (np.ascontiguousarray(a, dtype=float) for a in reference)
    steps = len(yaw_d)
    x = np.array(x0, dtype=float)
    if x.shape != (13 + vehicle.rotors,):
        raise ValueError(f"x0 must have {13 + vehicle.rotors} values, got {x.shape}")
    eta = np.ones(vehicle.rotors) if eta is None else np.array(eta, float)
    fail_rotor, fail_step, fail_eta = -1, -1, 1.0
    if failure is not None:
        failure.check(vehicle, steps / rate_hz)
        fail_rotor, fail_step, fail_eta = failure.rotor, int(round(failure.time_s * rate_hz)), failure.efficiency
    out_x, out_cmd, out_eta = (
        np.empty((steps, len(x))),
        np.empty((steps, vehicle.rotors)),
        np.empty((steps, vehicle.rotors)),
    )
    _fly(
        x,
        eta,
        vehicle.vehicle(),
        gains.gains(vehicle),
        1.0 / rate_hz,
        p_d,
        v_d,
        a_d,
        yaw_d,
        fail_rotor,
        fail_step,
        float(fail_eta),
        out_x,
        out_cmd,
        out_eta,
    )
    return (out_x, out_cmd, out_eta) if return_eta else (out_x, out_cmd)
