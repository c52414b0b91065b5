"""A lost estimate in flight, and its recovery: a collision flown, the divergence checks in the
loop, and the recovery paper's bank of EKFs started from a flying vehicle.

A collision (:class:`CollisionParams`, :func:`draw_collision`) adds a velocity (up to 5 m/s, any
direction) and a body rate (up to 20 rad/s, any axis) over a short impact (10 ms): the plant
takes them as an acceleration over the impact, so the accelerometer and the gyroscope see it
(:func:`quadest.flight.loop.strike`). Drawn per seed, the estimator's state is either reset to
nonsense at the impact (the state of an estimator of its kind started afresh at a random
attitude: a brown-out, a restart) or left to diverge.

With the checks on (:class:`Watch`, :mod:`quadest.recovery.divergence`), each sample of a
flight runs them after the estimate; once one fires the flight enters the throw's phases
(:mod:`quadest.flight.phases`) as a thrown vehicle does at its release: the rotors are commanded
to the throw's constant speed (the speed the bank's aerodynamic model was fitted at), the
logic waits for the free fall (eq 37; the re-arm waits out an impact still pushing and the
rotors spinning down), the bank converges, hands over to the nominal EKF (with the loop's
barometer) and the recovery controller holds the height. The truth in the loop (an oracle)
hands over at the free-fall detection, as for a throw.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from quadest._jit import njit
from quadest.flight.phases import BELOW, PHASE, WAITING
from quadest.records import check, compiled_record, describe, param
from quadest.recovery.divergence import DivergenceParams, thresholds, watch_state, watch_step

Watch = compiled_record(
    "Watch",
    "The divergence checks in the loop (quadest.recovery.divergence): on, their thresholds, "
    "state and the gyroscope's history, and the rotor speed commanded when one fires (the "
    "throw's, at which the bank's model was fitted).",
    on="b1",
    w="f8[:]",
    st="f8[:]",
    hist="f8[:, :]",
    idle="f8",
)


def watch(params: DivergenceParams | None = None, vehicle=None, *, rate_hz=1.0, reading_hz=1.0, idle=0.0):
    """The loop's :data:`Watch`: the checks of ``params`` for ``vehicle`` (none: off)."""
    if params is None:
        st, hist = np.full(1, -1.0), np.zeros((1, 3))
        return Watch.make(on=False, w=np.zeros(1), st=st, hist=hist, idle=0.0)
    w = thresholds(params, vehicle, rate_hz=rate_hz, reading_hz=reading_hz)
    st, hist = watch_state(w)
    return Watch.make(on=True, w=w, st=st, hist=hist, idle=float(idle))


@njit(cache=True, inline="always")
def diverged(k, loop, finite):
    """Whether a check fires at sample ``k`` (never with the checks off)."""
    wt = loop.watch
    if not wt.on:
        return False
    sensing, nav = loop.sensing, loop.nav
    reading = k % sensing.every == 0
    return watch_step(wt.st, wt.hist, wt.w, k, nav.clip.gyr, sensing.acc, nav.innov, reading, finite) != 0


@njit(cache=True, inline="always")
def start_recovery(loop):
    """Enter the throw's phases: waiting for the free fall, the rotors at the throw's speed."""
    loop.state[PHASE] = WAITING
    loop.state[BELOW] = 0
    cmd = loop.control.cmd
    for i in range(cmd.shape[0]):
        cmd[i] = loop.watch.idle


@dataclass(frozen=True)
class CollisionParams:
    time_min_s: float = param(
        2.0, "s", "the collision's time is drawn in [time_min_s, time_max_s]", "chosen: after the start has settled",
        bounds="[0, 3600]",
    )  # fmt: skip
    time_max_s: float = param(
        4.0, "s", "latest collision time", "chosen: leaves the 10 s hover in a 16 s flight", bounds="[0, 3600]"
    )
    rate_max: float = param(
        20.0,
        "rad/s",
        "body rate added: its size drawn in [0, rate_max], any axis",
        "issue: up to 20 rad/s (as a throw's tumble)",
        bounds="[0, 50]",
    )
    speed_max: float = param(
        5.0, "m/s", "velocity added: its size drawn in [0, speed_max], any direction", "issue: up to 5 m/s",
        bounds="[0, 30]",
    )  # fmt: skip
    impact_s: float = param(
        0.01,
        "s",
        "the impact's duration (the velocity and rate added evenly over it)",
        "chosen: a propeller guard or frame against a wall or another vehicle, a few ms to tens of ms",
        bounds="(0, 1]",
    )
    reset_share: float = param(
        0.5,
        "-",
        "share of the collisions whose estimator state is reset to nonsense (else left to diverge)",
        "issue: both, drawn per seed",
        bounds="[0, 1]",
    )
    height_m: float = param(
        10.0,
        "m",
        "height of the flight above the ground with a collision",
        "chosen: the throws' arena (docs/recovery.md); the bank needs 0.5 s of fall and more",
        bounds="(0, 1e3]",
    )

    def __post_init__(self):
        check(self, "collision")
        if self.time_min_s > self.time_max_s:
            raise ValueError("collision: time_min_s must not exceed time_max_s")

    @classmethod
    def describe(cls) -> list[dict]:
        return describe(cls)


@dataclass(frozen=True)
class Collision:
    """One collision: its time (s), the velocity (NED, m/s) and body rate (rad/s) it adds over
    ``impact_s``, the attitude the estimator is reset to (None: left to diverge), and the
    flight's height above the ground (m)."""

    time_s: float
    dv: tuple
    dw: tuple
    impact_s: float
    reset_q: tuple | None
    height_m: float = 10.0

    def summary(self) -> dict:
        return {
            "time_s": self.time_s,
            "speed_m_s": float(np.linalg.norm(self.dv)),
            "rate_rad_s": float(np.linalg.norm(self.dw)),
            "dv_m_s": list(self.dv),
            "dw_rad_s": list(self.dw),
            "estimator": "reset" if self.reset_q is not None else "left",
        }


def _direction(rng) -> np.ndarray:
    d = rng.normal(size=3)
    return d / np.linalg.norm(d)


def draw_collision(p: CollisionParams, seed: int) -> Collision:
    """The collision of ``seed`` (its own generator): time, velocity and rate uniform in size,
    uniform in direction, the estimator reset (with a random attitude) or left."""
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 37]))
    t = rng.uniform(p.time_min_s, p.time_max_s)
    dv = rng.uniform(0.0, p.speed_max) * _direction(rng)
    dw = rng.uniform(0.0, p.rate_max) * _direction(rng)
    reset = rng.uniform() < p.reset_share
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    q = tuple(map(float, q)) if reset else None
    return Collision(float(t), tuple(map(float, dv)), tuple(map(float, dw)), p.impact_s, q, p.height_m)


__all__ = ["Collision", "CollisionParams", "Watch", "draw_collision", "watch"]
