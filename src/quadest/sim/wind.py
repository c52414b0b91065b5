"""Wind on a flown vehicle: a steady wind, turbulence and discrete gusts, as the air's velocity
(NED, m/s) per sample. The vehicle's dynamics take it (:mod:`quadest.models.multirotor`: the
hub and body speeds are relative to the air, so the wind acts through the rotors' drag and
inflow and the body's drag); nothing in the loop knows it.

- steady: ``mean_m_s`` from a direction drawn uniformly in the horizontal plane;
- turbulence: first-order Gauss-Markov per axis (the Dryden spectrum's shape at low altitude,
  MIL-F-8785C, with a correlation time for the length scale over the speed), standard
  deviation ``turbulence_m_s`` horizontally and half of it vertically;
- gusts: ``gusts`` discrete "1 − cos" gusts (the MIL-F-8785C discrete gust's shape) at times
  drawn uniformly over the flight, each of a peak drawn up to ``gust_m_s`` in a random
  horizontal direction (a third of it vertical) and a duration drawn within ``gust_s``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

from quadest.records import check, param


@dataclass(frozen=True)
class WindParams:
    """The wind of a flown vehicle (module doc); one flight's realisation is drawn from its seed."""

    mean_m_s: float = param(0.0, "m/s", "steady horizontal wind", "chosen", bounds="[0, 30]")
    turbulence_m_s: float = param(0.0, "m/s", "turbulence standard deviation (horizontal)", "chosen", bounds="[0, 10]")
    correlation_s: float = param(
        1.0, "s", "turbulence correlation time", "chosen: a few metres' length scale, slow flight", bounds="(0, 100]"
    )
    gusts: int = param(0, "-", "discrete gusts per flight", "chosen", bounds="[0, 1000]")
    gust_m_s: float = param(0.0, "m/s", "largest peak of a discrete gust", "chosen", bounds="[0, 30]")
    gust_s: tuple = param((0.5, 2.0), "s", "range of a discrete gust's duration", "chosen")

    def __post_init__(self):
        check(self, "wind")
        lo, hi = self.gust_s
        if not 0 < lo <= hi:
            raise ValueError(f"wind: gust_s must be two increasing positive durations, got {self.gust_s!r}")


def wind_samples(t: np.ndarray, wind: WindParams, rng: np.random.Generator) -> np.ndarray:
    """One realisation of ``wind`` at the instants ``t`` (s): the air's velocity, (n, 3) NED."""
    t = np.asarray(t, float)
    n = len(t)
    out = np.zeros((n, 3))
    heading = rng.uniform(-np.pi, np.pi)
    out[:, 0], out[:, 1] = wind.mean_m_s * np.cos(heading), wind.mean_m_s * np.sin(heading)
    out += _turbulence(t, wind, rng)
    for _ in range(wind.gusts):
        out += _gust(t, wind, rng)
    return out


def _turbulence(t, wind, rng):
    """First-order Gauss-Markov per axis at the instants' median interval, stationary from the
    first sample."""
    sd = wind.turbulence_m_s * np.array([1.0, 1.0, 0.5])
    white = rng.standard_normal((len(t), 3))
    if wind.turbulence_m_s == 0.0 or len(t) < 2:
        return np.zeros((len(t), 3))
    a = np.exp(-np.median(np.diff(t)) / wind.correlation_s)
    white[1:] *= np.sqrt(1.0 - a * a)
    return lfilter([1.0], [1.0, -a], white, axis=0) * sd


def _gust(t, wind, rng):
    """One "1 − cos" gust at a random time, peak and direction."""
    start = rng.uniform(t[0], t[-1]) if len(t) else 0.0
    length = rng.uniform(*wind.gust_s)
    peak = rng.uniform(0.0, wind.gust_m_s)
    heading = rng.uniform(-np.pi, np.pi)
    direction = np.array([np.cos(heading), np.sin(heading), rng.uniform(-1.0, 1.0) / 3.0])
    s = (t - start) / length
    shape = np.where((s >= 0) & (s <= 1), 0.5 * (1.0 - np.cos(2 * np.pi * s)), 0.0)
    return peak * shape[:, None] * direction
