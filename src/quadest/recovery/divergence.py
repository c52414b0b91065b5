"""A lost estimate noticed in flight: the checks that start the recovery from a flying vehicle.

The recovery paper starts its bank of EKFs at a detected free fall after a throw (eq 37). A
vehicle that collides, tumbles or whose estimator diverges in flight is not in free fall: its
rotors still push. Four checks, each per IMU sample, any of them enough:

- ``impact``: the specific force ``‖z_acc‖`` beyond what the rotors can produce
  (``impact_factor`` times the largest thrust over the mass, ``k_f N Ω_max² / m``) for
  ``impact_samples`` samples: something else pushed the vehicle;
- ``rate``: a body rate that changed, over ``rate_window_s``, by more on one axis than the
  rotors' largest moment about it can turn the vehicle (``rate_factor`` times
  ``M_max / J`` times the window), plus the gyroscope's noise margin: the rate was given by
  something else;
- ``innovation``: the position fusion's innovation (motion capture against the position the
  estimator's attitude integrated), low-passed over ``innovation_tau_s``, longer than
  ``innovation_m``: the estimate no longer explains the measured motion;
- ``nonfinite``: the estimator returned a non-finite attitude.

The first two read the IMU alone, the third the estimate; none runs before ``arm_s`` (the
estimator's start). Thresholds: docs/recovery.md (section 7) says where each value comes from.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from quadest._jit import njit
from quadest.models.multirotor import MultirotorParams
from quadest.records import check, describe, field_offsets, layout, pack, param

IMPACT, RATE, INNOVATION, NONFINITE = 1, 2, 4, 8
CHECKS = {"impact": IMPACT, "rate": RATE, "innovation": INNOVATION, "nonfinite": NONFINITE}
"""The checks by bit (``fired`` holds their sum)."""


@dataclass(frozen=True)
class DivergenceParams:
    impact_factor: float = param(
        1.5,
        "-",
        "impact: ‖z_acc‖ above this times the rotors' largest specific force (k_f N Ω_max² / m)",
        "chosen: the rotors cannot push harder (1.5: their model may be off by tens of %); 300 nominal "
        "flights of 60 s (seeds 1000-1299) reach at most 0.30 of it, vibration included (docs/recovery.md)",
        bounds="(0, 100]",
    )
    impact_samples: int = param(
        2, "samples", "consecutive samples beyond the impact threshold", "chosen: one spike is not an impact",
        bounds="[1, 1000]",
    )  # fmt: skip
    rate_factor: float = param(
        2.0,
        "-",
        "rate: a change of body rate over the window above this times what the rotors' largest "
        "moment about the axis gives (M_max / J times the window)",
        "chosen: twice the rotors' reach (the model's inertia and thrust may be off by tens of %)",
        bounds="(0, 100]",
    )
    rate_window_s: float = param(
        0.005,
        "s",
        "rate: the window over which the change of body rate is taken",
        "chosen: a few samples, shorter than an impact's rise, longer than one sample's noise",
        bounds="(0, 1]",
    )
    rate_margin: float = param(
        0.3,
        "rad/s",
        "rate: added to the threshold (gyroscope noise and vibration over the window)",
        "chosen: well above the gyroscope's noise (0.005-0.01 rad/s per sample in the fma and bebop2 "
        "presets) and vibration; nominal flights reach at most 0.30 of the whole rate threshold",
        bounds="[0, 100]",
    )
    innovation_m: float = param(
        0.1,
        "m",
        "innovation: the low-passed position innovation's length above this",
        "chosen before any collision was flown (a few cm of error the fusion cannot explain), kept after "
        "checking it on seeds 1000-1099 (collisions) and 1000-1299 (nominal flights: at most 0.42 of it)",
        bounds="(0, 1e3]",
    )
    innovation_tau_s: float = param(
        0.05,
        "s",
        "innovation: time constant of its low-pass",
        "chosen: a few position readings at 100 Hz",
        bounds="(0, 100]",
    )
    arm_s: float = param(
        0.5,
        "s",
        "no check before this time from the start of the flight",
        "chosen: the estimator's and the position fusion's start",
        bounds="[0, 1e4]",
    )
    checks: str = param(
        "impact,rate,innovation,nonfinite",
        "-",
        "the checks that run (comma-separated; the ablation leaves some out)",
        "all four",
    )

    def __post_init__(self):
        check(self, "divergence")
        unknown = [c for c in self.check_names() if c not in CHECKS]
        if unknown:
            raise ValueError(f"divergence: unknown check {unknown[0]!r}; checks: {', '.join(CHECKS)}")

    def check_names(self) -> list[str]:
        return [c.strip() for c in self.checks.split(",") if c.strip()]

    def mask(self) -> int:
        return sum(CHECKS[c] for c in dict.fromkeys(self.check_names()))

    @classmethod
    def describe(cls) -> list[dict]:
        return describe(cls)


WATCH = field_offsets(
    ["mask", "impact_acc", "impact_samples", "window", "alpha0", "alpha1", "alpha2", "rate_margin",
     "innovation_m", "innovation_a", "arm_k"],
    "Watch",
)  # fmt: skip
"""The offsets of the compiled thresholds (:func:`thresholds`)."""
STATE = layout(("impact", 1), ("lp", 3), ("fired_k", 1), ("fired", 1), ("peak", 3))
"""The checks' carried state: samples beyond the impact threshold, the innovation's low-pass,
the sample of the first detection (−1 none) and the checks that fired there, and the largest
ratio of each statistic (impact, rate, innovation) to its threshold once armed (how close a
flight came)."""


def reach(vehicle: MultirotorParams) -> tuple[float, np.ndarray]:
    """The rotors' reach: the largest specific force ``k_f N Ω_max² / m`` (m/s²) and, per body
    axis, the largest angular acceleration ``M_max / J`` (rad/s²), with the rotors on one side
    of the axis at ``Ω_max`` and the others stopped (yaw: the reaction torques of one pair)."""
    r = np.asarray(vehicle.rotor_pos, float)
    spin = np.asarray(vehicle.spin, float)
    t_max = vehicle.k_f * vehicle.omega_max**2
    force = vehicle.rotors * t_max / vehicle.mass_kg
    m_roll, m_pitch = (t_max * max(r[r[:, j] > 0, j].sum(), -r[r[:, j] < 0, j].sum()) for j in (1, 0))
    m_yaw = vehicle.k_m * vehicle.omega_max**2 * max((spin > 0).sum(), (spin < 0).sum())
    return float(force), np.array([m_roll, m_pitch, m_yaw]) / np.asarray(vehicle.inertia, float)


def thresholds(p: DivergenceParams, vehicle: MultirotorParams, *, rate_hz: float, reading_hz: float) -> np.ndarray:
    """The compiled thresholds (:data:`WATCH`) of ``p`` for ``vehicle`` (its model, as the
    controller knows it) with the IMU at ``rate_hz`` and the position sensor at ``reading_hz``."""
    force, alpha = reach(vehicle)
    window = max(1, int(round(p.rate_window_s * rate_hz)))
    values = {
        "mask": p.mask(),
        "impact_acc": p.impact_factor * force,
        "impact_samples": p.impact_samples,
        "window": window,
        "alpha0": p.rate_factor * alpha[0] * window / rate_hz,
        "alpha1": p.rate_factor * alpha[1] * window / rate_hz,
        "alpha2": p.rate_factor * alpha[2] * window / rate_hz,
        "rate_margin": p.rate_margin,
        "innovation_m": p.innovation_m,
        "innovation_a": 1.0 - math.exp(-1.0 / (reading_hz * p.innovation_tau_s)),
        "arm_k": max(int(round(p.arm_s * rate_hz)), window),
    }
    return pack(values[name] for name in WATCH._fields)


def watch_state(p_array: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The checks' state at the start (:data:`STATE`) and the gyroscope's history (window + 1 rows)."""
    st = np.zeros(STATE.end)
    st[STATE.fired_k] = -1.0
    return st, np.zeros((int(p_array[WATCH.window]) + 1, 3))


@njit(cache=True, inline="always")
def impact_check(st, w, acc):
    """``impact``: ``‖z_acc‖`` beyond the threshold for ``impact_samples`` samples; returns
    whether it fired and ``‖z_acc‖`` over the threshold."""
    ratio = math.sqrt(acc[0] * acc[0] + acc[1] * acc[1] + acc[2] * acc[2]) / w[WATCH.impact_acc]
    st[STATE.impact] = st[STATE.impact] + 1.0 if ratio > 1.0 else 0.0
    return st[STATE.impact] >= w[WATCH.impact_samples], ratio


@njit(cache=True, inline="always")
def rate_check(hist, w, k, gyr):
    """``rate``: the change of the gyroscope's reading over the window beyond the rotors' reach
    on an axis (the reading kept for the samples to come); returns the largest change over its
    threshold (above 1: fired)."""
    n = hist.shape[0]
    old = hist[(k + 1) % n]  # the reading ``window`` samples ago (written at k − window)
    ratio = 0.0
    if k >= n - 1:
        for j in range(3):
            ratio = max(ratio, abs(gyr[j] - old[j]) / (w[WATCH.alpha0 + j] + w[WATCH.rate_margin]))
    for j in range(3):
        hist[k % n, j] = gyr[j]
    return ratio


@njit(cache=True, inline="always")
def innovation_check(st, w, innov, reading):
    """``innovation``: at a position reading the innovation ``innov`` (m) low-passed; returns its
    length over ``innovation_m`` (above 1: fired)."""
    if reading:
        a = w[WATCH.innovation_a]
        for j in range(3):
            st[STATE.lp + j] += a * (innov[j] - st[STATE.lp + j])
    lp0, lp1, lp2 = st[STATE.lp], st[STATE.lp + 1], st[STATE.lp + 2]
    return math.sqrt(lp0 * lp0 + lp1 * lp1 + lp2 * lp2) / w[WATCH.innovation_m]


@njit(cache=True)
def watch_step(st, hist, w, k, gyr, acc, innov, reading, finite):
    """The checks at IMU sample ``k`` (module doc): ``gyr``, ``acc`` the readings, ``innov`` the
    position fusion's innovation (read when ``reading``), ``finite`` whether the estimator's
    attitude is finite. Returns the checks that fired (:data:`CHECKS`' bits, 0: none) and
    keeps the first detection in ``st``."""
    mask = int(w[WATCH.mask])
    impact, r_impact = impact_check(st, w, acc)
    r_rate = rate_check(hist, w, k, gyr)
    r_innov = innovation_check(st, w, innov, reading)
    fired = (IMPACT if impact else 0) | (RATE if r_rate > 1.0 else 0) | (INNOVATION if r_innov > 1.0 else 0)
    fired = (fired | (0 if finite else NONFINITE)) & mask
    if k < w[WATCH.arm_k]:
        return 0
    st[STATE.peak] = max(st[STATE.peak], r_impact)
    st[STATE.peak + 1] = max(st[STATE.peak + 1], r_rate)
    st[STATE.peak + 2] = max(st[STATE.peak + 2], r_innov)
    if fired and st[STATE.fired_k] < 0:
        st[STATE.fired_k] = k
        st[STATE.fired] = fired
    return fired


def fired_names(bits: int) -> list[str]:
    """The names of the checks in ``bits``."""
    return [name for name, b in CHECKS.items() if int(bits) & b]
