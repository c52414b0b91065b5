"""The closed loop: the controller reads the state (for now the true one; the estimators come
into the loop next), commands the rotors, the vehicle model integrates (RK4), every step in
compiled code."""
from __future__ import annotations

import numpy as np
from numba import njit

from quadest.control.se3 import SE3Params, se3_command
from quadest.models.multirotor import MultirotorParams, rk4


@njit(cache=True)
def _fly(x, eta, V, G, h, p_d, v_d, a_d, yaw_d, out_x, out_cmd):
    cmd = np.empty(V.rotor_pos.shape[0])
    for k in range(yaw_d.shape[0]):
        se3_command(x, p_d[k], v_d[k], a_d[k], yaw_d[k], G, V, cmd)
        rk4(x, cmd, eta, V, h)
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


def fly_se3(x0, reference, *, vehicle: MultirotorParams | None = None, gains: SE3Params | None = None,
            rate_hz: float = 1000.0, eta=None):
    """Fly the vehicle from state ``x0`` along ``reference`` (``(p_d, v_d, a_d, yaw_d)``, one row
    per step at ``rate_hz``) with the SE(3) controller on the true state. Returns the states
    after each step (steps, 13 + N) and the rotor commands (steps, N)."""
    vehicle = vehicle or MultirotorParams()
    gains = gains or SE3Params()
    p_d, v_d, a_d, yaw_d = (np.ascontiguousarray(a, dtype=float) for a in reference)
    steps = len(yaw_d)
    x = np.array(x0, dtype=float)
    if x.shape != (13 + vehicle.rotors,):
        raise ValueError(f"x0 must have {13 + vehicle.rotors} values, got {x.shape}")
    eta = np.ones(vehicle.rotors) if eta is None else np.asarray(eta, float)
    out_x, out_cmd = np.empty((steps, len(x))), np.empty((steps, vehicle.rotors))
    _fly(x, eta, vehicle.vehicle(), gains.gains(vehicle), 1.0 / rate_hz, p_d, v_d, a_d, yaw_d, out_x, out_cmd)
    return out_x, out_cmd
