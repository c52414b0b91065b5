"""The plant as an interface: the closed loop flying a vehicle it does not own.

The one closed loop (:mod:`quadest.flight.loop`) flies quadest's compiled vehicle inside
compiled code. Another simulator can be the truth instead through :class:`Plant`: rotor speed
commands in; the true state, its derivative, each rotor's thrust, the share of its thrust it
delivers and its propeller's imbalance out. :func:`fly_plant` runs the same loop from Python,
sample by sample, calling the plant between the loop's compiled halves: the sensors read the
plant's truth, the estimator and the detector read the sensors, the controller commands the
rotors, the plant flies to the next sample. :class:`CompiledPlant` is quadest's own vehicle
behind the same interface, which flies every flight bit for bit as the compiled loop does
(``tests/unit/test_plant.py``).
"""

from __future__ import annotations

from typing import NamedTuple, Protocol

import numpy as np

from quadest.flight.loop import (
    OK,
    advance_sample,
    command_sample,
    ended_sample,
    estimate_sample,
    flown,
    plant_truth_sample,
    read_sensors_sample,
)


class Truth(NamedTuple):
    """The arrays a plant writes a sample's truth into (the loop's own: nothing is copied):

    - ``x`` (13 + N): NED position (m), NED velocity (m/s), ``q_nb`` ``[w, x, y, z]``, FRD body
      rate (rad/s), rotor speeds (rad/s);
    - ``dx`` (13 + N): the time derivative of ``x`` (the accelerometer reads ``dx[3:6]``);
    - ``thrusts`` (N): each rotor's thrust, N;
    - ``eta`` (N): the share of its thrust and torque each rotor delivers (1 intact);
    - ``imb`` (N): each propeller's imbalance, kg m (0 balanced).
    """

    x: np.ndarray
    dx: np.ndarray
    thrusts: np.ndarray
    eta: np.ndarray
    imb: np.ndarray


class Plant(Protocol):
    """A vehicle the closed loop flies as the truth (conventions: docs/conventions.md)."""

    def truth(self, k: int, cmd: np.ndarray, out: Truth) -> None:
        """Write the truth of sample ``k`` into ``out``, the rotors last commanded ``cmd`` (rad/s)."""

    def step(self, k: int, cmd: np.ndarray, x: np.ndarray) -> None:
        """Fly from sample ``k`` to the next with the rotor speed commands ``cmd`` (rad/s) and
        write the state reached into ``x``."""


class CompiledPlant:
    """quadest's compiled vehicle (the loop's ``Plant`` record, its failure profile, wind and
    collision included) as a :class:`Plant`."""

    def __init__(self, loop):
        self.loop = loop

    def truth(self, k: int, cmd: np.ndarray, out: Truth) -> None:
        plant_truth_sample(k, out.x, self.loop)  # reads the loop's commands, which ``cmd`` is

    def step(self, k: int, cmd: np.ndarray, x: np.ndarray) -> None:
        advance_sample(k, x, self.loop)


def fly_plant(plant: Plant, x: np.ndarray, loop, estimator=None) -> tuple[int, int]:
    """Fly ``loop`` (built by :mod:`quadest.flight.build`) with ``plant`` as the truth from the
    state ``x``: per sample the plant's truth, the sensors, the estimator (``estimator``: a
    compiled step's arguments as :func:`~quadest.flight.loop.closed_loop` takes them, a peer's
    ``update`` as ``peer.update``, or None: the loop's own navigation), the rotor commands, the
    plant's step. A throw, a hand or a recovery in flight are the compiled loop's alone.
    Returns ``(status, samples flown)`` as :func:`~quadest.flight.loop.closed_loop` does."""
    if loop.plant.hand_dx.shape[0] or loop.watch.on:
        raise ValueError("a plant of its own flies no throw and no recovery in flight")
    truth = Truth(x, loop.plant.dx, loop.plant.thrusts, loop.plant.eta, loop.plant.imb)
    cmd = loop.control.cmd
    n = len(loop.record.phase)
    for k in range(n):
        plant.truth(k, cmd, truth)
        read_sensors_sample(k, x, loop)
        status = command_sample(k, x, loop, _attitude(k, loop, estimator))
        if status != OK:
            return status, flown(status, k)
        plant.step(k, cmd, x)
        status = ended_sample(x, loop)
        if status != OK:
            return status, k + 1
    return OK, n


def _attitude(k: int, loop, estimator):
    """The attitude the controller reads at sample ``k`` (geographic ``q_nb``)."""
    if estimator is None:
        return loop.nav.q_est
    if callable(estimator):  # a peer's streaming update
        sensing = loop.sensing
        return estimator(loop.nav.clip.gyr, sensing.acc, sensing.mag, dt=sensing.dt)
    estimate_sample(k, loop, *estimator)
    return loop.nav.q_est
