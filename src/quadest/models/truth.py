"""A truth drawn apart from the model: the vehicle that flies differs from the one its software
knows by what a maker cannot measure well (docs/truth.md).

:data:`DEFAULT_SPREAD` states, for each quantity, the range a vehicle's truth may lie in around
its model and the sources of that range; :func:`draw_truth` draws one truth from a generator.
Ratios multiply the model's value; offsets (m, rad) and levels (the rotor speed readings'
relative noise) replace or add to it. Every range is drawn uniformly, a ratio's on a log scale
(a factor and its inverse equally likely where the range is symmetric in them).

The draw depends only on the generator and the spread, never on the model: the same seed gives
the same numbers for every vehicle (each then applied to that vehicle's own values).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from quadest.errors import UsageError
from quadest.models.multirotor import MultirotorParams


class Range(NamedTuple):
    """A quantity's range: ``low`` to ``high`` (a ratio, or in the quantity's unit), drawn once per
    body axis of ``axes`` (``"xyz"``, ``"xy"``; "": once); ``log``: uniform in the logarithm;
    ``source`` where the bounds come from."""

    low: float
    high: float
    source: str
    log: bool = False
    axes: str = ""


_SPIN = "docs/vehicle.md, Spin range (models.multirotor.SPIN_RANGES)"

DEFAULT_RANGES = {
    "rotor_inertia_ratio": Range(
        0.5,
        2.3,
        "Bebop 2: Paparazzi's INDI airframe gives 4.7e-6 kg m² (the preset's), LADAC's model 1.1e-5 (ratio 2.3; "
        f"{_SPIN}); below: half, the lowest the campaign was measured at (a bare propeller without its bell)",
        log=True,
    ),
    "top_speed_ratio": Range(
        0.83,
        1.0,
        "a 3S LiPo (the Bebop 2's) from 4.2 V a cell full to 3.5 V a cell loaded near the end of a flight (a common "
        "low-voltage warning): a brushless motor's top speed follows the voltage (K_v V), 3.5/4.2 = 0.83. The plant "
        "cannot change its top speed during a flight: the whole flight flies the sagged value drawn",
    ),
    "motor_tau_ratio": Range(
        0.5,
        2.0,
        "small brushless motors have 15-40 ms (MultirotorParams.motor_tau_s); the Bebop 2 preset's 33 ms is Sun et "
        "al. 2021's simulation value, not a measurement of the vehicle flown",
        log=True,
    ),
    "thrust_coefficient_ratio": Range(
        0.9,
        1.1,
        "propellers measured within 10 % (FlightParams.detector_model_error); a worn or nicked propeller loses more",
    ),
    "torque_coefficient_ratio": Range(
        0.8,
        1.2,
        "k_m/k_f of small propellers spans 0.01-0.02 m (MultirotorParams.k_m's doc); the preset's is Sun et al.'s "
        "simulation value: ±20 %",
    ),
    "rotor_drag_ratio": Range(
        0.5,
        1.5,
        f"Bebop 2: none (Sun et al.'s simple model) to 6.1e-5 (RotorPy's Hummingbird scaled), preset 4.05e-5 ({_SPIN})",
    ),
    "body_drag_ratio": Range(0.5, 2.0, "chosen values in every preset (0.16 N at 4 m/s): a factor of two", log=True),
    "inflow_ratio": Range(
        0.5,
        2.0,
        "chosen values (10 % less thrust climbing at 4 m/s); RotorPy's Hummingbird has 2.4 times the Bebop 2's k_z/k_f",
        log=True,
    ),
    "com_offset_m": Range(
        -0.005,
        0.005,
        "the centre of mass found by balancing the vehicle within a few millimetres (FlightParams.detector_imu_error); "
        "horizontal axes (x, y): the rotors move by minus the offset",
        axes="xy",
    ),
    "imu_misalignment_rad": Range(
        -math.radians(1.0) / math.sqrt(3.0),
        math.radians(1.0) / math.sqrt(3.0),
        "the IMU board mounted within 1° of the body axes (a rotation vector drawn per axis within ±1°/√3); "
        "replaces the sensors' drawn non-orthogonality",
        axes="xyz",
    ),
    "gyro_scale": Range(
        -0.03,
        0.03,
        "MPU-6050 (the Bebop 2's IMU) datasheet: gyroscope sensitivity scale factor tolerance ±3 % at 25 °C; "
        "replaces the sensors' drawn scale error",
        axes="xyz",
    ),
    "speed_noise": Range(
        0.005,
        0.03,
        "ESC eRPM telemetry: about 1 % at hover speed (FlightParams.speed_noise); a coarser ESC or a noisier "
        "commutation up to 3 %",
    ),
}
"""The default spread: each quantity's range and its sources (docs/truth.md renders this table)."""


@dataclass(frozen=True)
class TruthSpread:
    """The ranges a truth is drawn from (``{name: Range}``, the names of :data:`DEFAULT_RANGES`)."""

    ranges: dict

    def __post_init__(self):
        unknown = sorted(set(self.ranges) - set(DEFAULT_RANGES))
        if unknown:
            known = ", ".join(DEFAULT_RANGES)
            raise ValueError(f"truth spread: unknown quantities {', '.join(unknown)}; known: {known}")
        for name, r in self.ranges.items():
            if not (math.isfinite(r.low) and math.isfinite(r.high) and r.low <= r.high) or (r.log and r.low <= 0):
                raise ValueError(f"truth spread: {name} needs low <= high (positive if log), got {r.low}, {r.high}")

    def __hash__(self):
        return hash(tuple(sorted(self.ranges.items())))


DEFAULT_SPREAD = TruthSpread(DEFAULT_RANGES)
TRUTH_SPREADS = ("none", "default")
"""The spreads by name: ``none`` (the truth is the model) and ``default`` (:data:`DEFAULT_SPREAD`)."""


def truth_spread(name: str) -> TruthSpread | None:
    """A spread by name (:data:`TRUTH_SPREADS`); None for ``none``."""
    if name not in TRUTH_SPREADS:
        raise UsageError(f"unknown truth spread {name!r}; spreads: {', '.join(TRUTH_SPREADS)}")
    return None if name == "none" else DEFAULT_SPREAD


class Truth(NamedTuple):
    """One truth: the ``vehicle`` that flies, the ``sensors`` it carries as changes to the model's
    (``{"gyro.scale": ..., "gyro.misalignment": ..., "acc.misalignment": ...}``, the names of
    :meth:`~quadest.sim.params.SimConfig.with_overrides`), the rotor speed readings'
    ``speed_noise`` (None: the flight's own) and ``drawn``: every drawn number by name (one per
    axis as ``name_x``, ``name_y``, ...) and the ``max_thrust_ratio`` they give (the truth's
    thrust at top speed over the model's)."""

    vehicle: MultirotorParams
    sensors: dict
    speed_noise: float | None
    drawn: dict


def draw_truth(model: MultirotorParams, rng: np.random.Generator, spread: TruthSpread | None = DEFAULT_SPREAD) -> Truth:
    """A truth around ``model`` drawn from ``rng`` within ``spread`` (None: the model itself,
    nothing drawn). The numbers drawn, and how many, depend on ``spread`` only; a quantity the
    spread leaves out stays the model's (and its draw is skipped, the others keep theirs)."""
    if spread is None:
        return Truth(model, {}, None, {})
    u = rng.uniform(0.0, 1.0, (len(DEFAULT_RANGES), 3))  # one row per known quantity, in the table's order
    drawn = {}
    for row, name in enumerate(DEFAULT_RANGES):
        r = spread.ranges.get(name)
        if r is None:
            continue
        lo, hi = (math.log(r.low), math.log(r.high)) if r.log else (r.low, r.high)
        v = lo + (hi - lo) * u[row]
        v = np.exp(v) if r.log else v
        if r.axes:
            drawn.update({f"{name}_{axis}": float(v[i]) for i, axis in enumerate(r.axes)})
        else:
            drawn[name] = float(v[0])
    return _applied(model, drawn)


def _applied(model: MultirotorParams, drawn: dict) -> Truth:
    """The truth the numbers ``drawn`` make of ``model``."""
    one = drawn.get
    vehicle = replace(
        model,
        rotor_inertia=model.rotor_inertia * one("rotor_inertia_ratio", 1.0),
        omega_max=model.omega_max * one("top_speed_ratio", 1.0),
        motor_tau_s=model.motor_tau_s * one("motor_tau_ratio", 1.0),
        k_f=model.k_f * one("thrust_coefficient_ratio", 1.0),
        k_m=model.k_m * one("torque_coefficient_ratio", 1.0),
        k_h=model.k_h * one("rotor_drag_ratio", 1.0),
        body_drag=tuple(float(c) * one("body_drag_ratio", 1.0) for c in model.body_drag),
        k_z=model.k_z * one("inflow_ratio", 1.0),
        rotor_pos=tuple(
            (x - one("com_offset_m_x", 0.0), y - one("com_offset_m_y", 0.0), z) for x, y, z in model.rotor_pos
        ),
    )
    sensors = {}
    if "imu_misalignment_rad_x" in drawn:
        wx, wy, wz = (drawn[f"imu_misalignment_rad_{a}"] for a in "xyz")
        skew = ((0.0, -wz, wy), (wz, 0.0, -wx), (-wy, wx, 0.0))  # a small rotation: I + [w]×
        sensors["gyro.misalignment"] = sensors["acc.misalignment"] = skew
    if "gyro_scale_x" in drawn:
        sensors["gyro.scale"] = tuple(drawn[f"gyro_scale_{a}"] for a in "xyz")
    drawn = {**drawn, "max_thrust_ratio": one("thrust_coefficient_ratio", 1.0) * one("top_speed_ratio", 1.0) ** 2}
    return Truth(vehicle, sensors, drawn.get("speed_noise"), drawn)


def drawn_names(spread: TruthSpread | None = DEFAULT_SPREAD) -> list[str]:
    """The names of :attr:`Truth.drawn` for ``spread`` (a per-axis quantity once per axis), in the
    table's order, then ``max_thrust_ratio``."""
    if spread is None:
        return []
    names = []
    for name, r in DEFAULT_RANGES.items():
        if name in spread.ranges:
            names += [f"{name}_{a}" for a in r.axes] if r.axes else [name]
    return names + ["max_thrust_ratio"]
