"""What a controller is asked to fly: references (a fixed setpoint, a circle, a figure eight).
A rotor failure is the simulator's (:mod:`quadest.sim.faults`)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike


def hover_reference(
    steps: int, position: ArrayLike = (0.0, 0.0, 0.0), yaw: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A fixed setpoint: ``(p_d, v_d, a_d, yaw_d)`` arrays of ``steps`` rows."""
    p = np.tile(np.asarray(position, float), (steps, 1))
    return p, np.zeros((steps, 3)), np.zeros((steps, 3)), np.full(steps, float(yaw))


def circle_reference(
    t: ArrayLike, radius: float = 1.0, freq_hz: float = 0.2, height: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A horizontal circle about the origin (north-east plane, at ``-height`` down), with its
    exact velocity and acceleration; heading held at 0."""
    t = np.asarray(t, float)
    w = 2 * np.pi * freq_hz
    c, s = np.cos(w * t), np.sin(w * t)
    p = np.column_stack([radius * c, radius * s, np.full(len(t), -height)])
    v = np.column_stack([-radius * w * s, radius * w * c, np.zeros(len(t))])
    a = np.column_stack([-radius * w * w * c, -radius * w * w * s, np.zeros(len(t))])
    return p, v, a, np.zeros(len(t))


def figure_eight_reference(
    t: ArrayLike,
    size: tuple[float, float] = (2.0, 0.5),
    freq_hz: float = 0.35,
    yaw_amplitude: float = math.pi,
    phase: float = 0.0,
    ramp_s: float = 2.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A figure eight, ``x = A sin(ωt + φ) − A sin φ``, ``y = B sin(2(ωt + φ)) − B sin 2φ``, with
    the heading swinging ``yaw_amplitude (sin(ωt + φ) − sin φ)``, grown in over ``ramp_s`` by a
    smooth step ``e(t)`` (so it starts at rest at the origin, without a jump in acceleration),
    with its exact velocity and acceleration (``e p``, ``e' p + e v``, ``e'' p + 2 e' v + e a``).
    At full size the defaults ask for about 9.7 m/s² along each axis, 4.4 m/s and a yaw rate up
    to 6.9 rad/s."""
    t = np.asarray(t, float)
    w = 2 * np.pi * freq_hz
    a_x, b_y = size
    th = w * t + phase
    zero = np.zeros(len(t))
    p = np.column_stack([a_x * (np.sin(th) - np.sin(phase)), b_y * (np.sin(2 * th) - np.sin(2 * phase)), zero])
    v = np.column_stack([a_x * w * np.cos(th), 2 * b_y * w * np.cos(2 * th), zero])
    a = np.column_stack([-a_x * w * w * np.sin(th), -4 * b_y * w * w * np.sin(2 * th), zero])
    yaw = yaw_amplitude * (np.sin(th) - np.sin(phase))
    e, de, dde = _smooth_step(t, ramp_s)
    return (
        e[:, None] * p,
        de[:, None] * p + e[:, None] * v,
        dde[:, None] * p + 2 * de[:, None] * v + e[:, None] * a,
        e * yaw,
    )


def _smooth_step(t: np.ndarray, width: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``e = 10u³ − 15u⁴ + 6u⁵`` with ``u = t / width`` clipped to [0, 1], and its first two
    derivatives (both zero at either end: the acceleration has no jump)."""
    if width <= 0:
        one = np.ones(len(t))
        return one, 0 * one, 0 * one
    u = np.clip(t / width, 0.0, 1.0)
    return u**3 * (10 - 15 * u + 6 * u**2), 30 * u**2 * (1 - u) ** 2 / width, 60 * u * (1 - u) * (1 - 2 * u) / width**2
