"""Every parameter of the simulator: a frozen record per part, with unit, meaning and source.

``SimConfig`` gathers the records; presets (``bebop2``, ``lowcost-20hz``, ``fma``) are sets of
overrides on the defaults; ``--set section.field=value`` and TOML files override further.
``param_table(config)`` lists every value with its unit and source (``quadest simulate
--list-params``); docs/simulator.md shows the same table.
"""

from __future__ import annotations

import json
import math
import sys
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path

import numpy as np

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10
    import tomli as tomllib

from quadest.conventions import GRAVITY
from quadest.data.inputs import check_regular
from quadest.records import param, parse_text


@dataclass(frozen=True)
class Environment:
    gravity: float = param(GRAVITY, "m/s²", "gravitational acceleration along +z (down)", "standard gravity")
    field_ut: float = param(49.0, "µT", "earth magnetic field intensity", "WMM, Delft (52.0°N 4.4°E), 2022")
    inclination_deg: float = param(67.0, "deg", "field inclination, positive down", "WMM, Delft, 2022")
    declination_deg: float = param(2.0, "deg", "field declination, positive east", "WMM, Delft, 2022")
    distortion_ut: float = param(
        0.0,
        "µT",
        "indoor field distortion: the field of magnetised steel below the "
        "flight, its magnitude at the origin (0: none)",
        "chosen per case: near steel structures indoor fields deviate by several µT to tens of µT",
        bounds="[0, 1000]",
    )
    distortion_depth_m: float = param(
        3.0,
        "m",
        "depth of the distortion's sources below the origin",
        "chosen: steel in the floor under a vehicle hovering at 3 m",
        bounds="(0, 100]",
    )
    distortion_spacing_m: float = param(
        1.5,
        "m",
        "spacing of the distortion's sources (3 x 3 dipoles in a horizontal plane)",
        "chosen: the spacing of beams or rebar mats",
        bounds="(0, 100]",
    )
    distortion_seed: int = param(
        0, "-", "which room: the dipoles' directions are drawn from this seed", "chosen", bounds="[0, 1e9]"
    )


@dataclass(frozen=True)
class Vehicle:
    mass_kg: float = param(0.5, "kg", "vehicle mass")
    inertia: tuple = param((0.0023, 0.0023, 0.0046), "kg m²", "principal moments of inertia (x, y, z)")
    arm_m: float = param(0.17, "m", "distance from centre to rotor axis")
    thrust_to_weight: float = param(2.0, "-", "maximum collective thrust over weight (motor-current scale)")
    rotor_drag: float = param(0.3, "1/s", "linear rotor drag: body x/y specific force -d·v (Faessler 2018)")
    rotor_hz_hover: float = param(110.0, "Hz", "rotor rotation frequency at hover (vibration tone)")


@dataclass(frozen=True)
class ImuTiming:
    rate_hz: float = param(500.0, "Hz", "gyroscope and accelerometer sample rate")
    jitter_std_s: float = param(0.0, "s", "std of the sampling-instant error (clipped to ±0.3 period)")
    drop_prob: float = param(0.0, "-", "probability that an IMU sample (row) is lost")


@dataclass(frozen=True)
class Gyroscope:
    noise_std: float = param(0.01, "rad/s", "white noise std per sample")
    bias_std: float = param(0.005, "rad/s", "std of the constant (turn-on) bias drawn per run, per axis")
    bias: tuple | None = param(None, "rad/s", "fixed constant bias (overrides the draw)")
    bias_rw_std: float = param(2e-4, "rad/s/√s", "bias random walk intensity")
    scale_std: float = param(0.003, "-", "std of the scale-factor error drawn per run, per axis")
    scale: tuple | None = param(None, "-", "fixed scale-factor errors (overrides the draw)")
    misalignment_std: float = param(0.002, "rad", "std of each off-diagonal misalignment term")
    misalignment: tuple | None = param(None, "-", "fixed 3x3 misalignment matrix, zero diagonal")
    range: float = param(math.radians(1000.0), "rad/s", "saturation limit per axis")
    dlpf_hz: float = param(0.0, "Hz", "anti-alias low-pass (first order) cut-off before saturation (0: none)")
    vibration_amp: tuple = param(
        (0.0, 0.0, 0.0),
        "rad/s",
        "rotor blade-pass tone amplitude per axis at hover in the gyroscope (a flown vehicle only; grows with "
        "the rotor speed squared); real flights show about 0.25 rad/s per m/s² of the accelerometer's tone on "
        "roll and pitch, 0.03 on yaw (docs/simulator.md)",
    )


@dataclass(frozen=True)
class Accelerometer:
    noise_std: float = param(0.25, "m/s²", "white noise std per sample")
    bias_std: float = param(0.05, "m/s²", "std of the constant bias drawn per run, per axis")
    bias: tuple | None = param(None, "m/s²", "fixed constant bias (overrides the draw)")
    bias_rw_std: float = param(1e-3, "m/s²/√s", "bias random walk intensity")
    scale_std: float = param(0.005, "-", "std of the scale-factor error drawn per run, per axis")
    scale: tuple | None = param(None, "-", "fixed scale-factor errors (overrides the draw)")
    misalignment_std: float = param(0.002, "rad", "std of each off-diagonal misalignment term")
    misalignment: tuple | None = param(None, "-", "fixed 3x3 misalignment matrix, zero diagonal")
    range: float = param(8 * GRAVITY, "m/s²", "saturation limit per axis")
    lever_arm: tuple = param((0.0, 0.0, 0.0), "m", "IMU position from the centre of mass, body frame")
    dlpf_hz: float = param(0.0, "Hz", "anti-alias low-pass (first order) cut-off before saturation (0: none)")
    vibration_amp: tuple = param(
        (0.0, 0.0, 0.0), "m/s²", "rotor vibration tone amplitude per axis at hover (grows with rotor load)"
    )


@dataclass(frozen=True)
class Magnetometer:
    rate_hz: float = param(100.0, "Hz", "sample rate (0: no magnetometer)")
    noise_std: float = param(0.5, "µT", "white noise std per sample")
    hard_iron: tuple = param((0.0, 0.0, 0.0), "µT", "hard-iron offset, body frame")
    soft_iron: tuple = param(
        ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
        "-",
        "soft-iron matrix applied to the earth field in the body frame",
    )
    motor_coef: tuple = param(
        (0.0, 0.0, 0.0), "µT", "disturbance at maximum motor current (all rotors at full thrust), body frame"
    )
    range: float = param(4900.0, "µT", "saturation limit per axis")
    latency_s: float = param(0.0, "s", "age of the field a sample reads (rounded to IMU samples; 0: none)")


@dataclass(frozen=True)
class Hover:
    duration_s: float = param(30.0, "s", "default duration of the hover scenario")
    gust_acc_rms: float = param(
        0.3,
        "m/s²",
        "RMS horizontal acceleration from gusts",
        "chosen: light air; a few tenths of m/s² of position-hold residual",
    )
    gust_band_hz: tuple = param((0.1, 1.5), "Hz", "frequency band of the gust motion")
    vertical_ratio: float = param(0.5, "-", "vertical over horizontal gust amplitude")
    yaw_amp_deg: float = param(5.0, "deg", "peak slow yaw change")
    yaw_band_hz: tuple = param((0.02, 0.1), "Hz", "frequency band of the yaw changes")
    components: int = param(6, "-", "sinusoids per axis")


@dataclass(frozen=True)
class Nominal:
    duration_s: float = param(60.0, "s", "default duration of the nominal scenario")
    acc_max: float = param(
        3.0,
        "m/s²",
        "peak acceleration of the path",
        "chosen: brisk manual flight (the AFCKF paper's normal flight is not published)",
    )
    band_hz: tuple = param((0.1, 0.5), "Hz", "frequency band of the path's accelerations (periods 2-10 s)")
    ramp_s: float = param(1.0, "s", "time constant with which the manoeuvres start from hover")
    vertical_ratio: float = param(0.3, "-", "vertical over horizontal path amplitude")
    yaw_rate_max: float = param(1.0, "rad/s", "peak yaw rate", "chosen: moderate manual yaw")
    yaw_band_hz: tuple = param((0.02, 0.15), "Hz", "frequency band of the yaw motion")
    components: int = param(5, "-", "sinusoids per axis")


@dataclass(frozen=True)
class DamagedRotor:
    duration_s: float = param(30.0, "s", "default duration of the damaged-rotor scenario")
    failure_s: float = param(
        5.0, "s", "time of the rotor loss (hover before it)", "chosen: the filters have converged in hover by then"
    )
    spin_rate_mean: float = param(15.5, "rad/s", "mean spin rate after the failure", "AFCKF paper, section IV.B.1")
    spin_rate_var: float = param(
        3.0,
        "rad/s",
        "peak slow deviation of the spin rate",
        "chosen, not from the paper: a wandering spin; with the ±1000 °/s gyro it makes the gyro clip",
    )
    spin_band_hz: tuple = param((0.03, 0.15), "Hz", "frequency band of the spin-rate variation")
    spin_up_tau_s: float = param(
        0.5, "s", "time constant of the spin-up", "chosen: the spin settles within about 2 s of the loss"
    )
    spin_sign: float = param(1.0, "-", "+1: positive yaw rate (clockwise seen from above), -1: negative")
    tilt_deg: float = param(
        4.0,
        "deg",
        "angle between body z and the spin axis at the mean spin rate (grows with rate²)",
        "relaxed hover, Mueller & D'Andrea 2014; value assumed",
    )
    tilt_azimuth_deg: float = param(45.0, "deg", "direction in the body x-y plane the spin axis leans to")
    manoeuvre_acc_max: float = param(
        1.0,
        "m/s²",
        "peak acceleration of the spin centre after the failure",
        "chosen: a damaged vehicle drifting slowly around its position",
    )
    manoeuvre_band_hz: tuple = param((0.02, 0.2), "Hz", "frequency band of the spin-centre manoeuvres")
    active_rotors: int = param(3, "-", "rotors producing thrust after the failure (vibration, motor current)")


@dataclass(frozen=True)
class Throw:
    duration_s: float = param(3.0, "s", "default duration of the throw scenario")
    hold_s: float = param(0.75, "s", "time held still in the hand before the throwing motion")
    throw_s: float = param(0.25, "s", "duration of the throwing motion before release")
    speed_max: float = param(
        5.0, "m/s", "release speed drawn uniformly in [0, speed_max]", "chosen: a gentle hand throw"
    )
    any_direction: bool = param(
        False,
        "-",
        "release velocity of any direction (default: upward or horizontal only; a "
        "downward throw makes the hand's own acceleration trigger eq 37 before release)",
    )
    rate_max: float = param(
        10.0, "rad/s", "release body-rate magnitude drawn in [0, rate_max]", "chosen: a throw with some tumble"
    )
    tremor_acc: float = param(0.2, "m/s²", "hand tremor acceleration amplitude while held")
    release_height_m: float = param(1.5, "m", "height of the release point above the origin")
    max_step_s: float = param(2.5e-4, "s", "largest RK4 step of the free flight (>= 4 kHz)")


@dataclass(frozen=True)
class Calibration:
    """Motions a user performs to calibrate, hand-held with the motors off."""

    rest_s: float = param(30.0, "s", "default duration of the rest scenario")
    hold_s: float = param(6.0, "s", "six-position: time held in each orientation")
    turn_s: float = param(2.0, "s", "six-position: time of each turn between orientations")
    figure8_s: float = param(60.0, "s", "default duration of the figure-eight rotation")
    figure8_period_s: float = param(12.0, "s", "figure-eight: period of the heading sweep")
    tilt_amp_deg: float = param(75.0, "deg", "figure-eight: roll and pitch amplitude")
    six_tilt_deg: float = param(0.0, "deg", "six-position: error of each placement (random axis)")


@dataclass(frozen=True)
class Aero:
    """Recovery paper eq 9, in quadest's body frame (FRD): f_c = A v + B|v|v + C ψ(ω), N."""

    A: tuple = param(
        ((-0.20, 0.0, 0.0), (0.0, -0.20, 0.0), (0.0, 0.0, -0.30)),
        "N s/m",
        "linear drag matrix (rotor drag and inflow), body frame",
        "assumption, form from Beffa eq 9",
    )
    B: tuple = param(
        ((-0.012, 0.0, 0.0), (0.0, -0.012, 0.0), (0.0, 0.0, -0.030)),
        "N s²/m²",
        "quadratic drag matrix (frame drag)",
        "assumption, form from Beffa eq 9",
    )
    C: tuple = param(
        (
            (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
            (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
            (0.0, 0.0, 0.0, 0.0015, 0.0015, 0.0, 0.0, 0.0, 0.0, -1.5),
        ),
        "N, N s/rad, N s²/rad²",
        "rate terms on ψ(ω) = (ωx, ωy, ωz, ωx², ωy², ωz², ωxωy, ωyωz, ωzωx, 1); the last "
        "column is the idle thrust (-1.5 N: 3 m/s² up the body)",
        "assumption, form from Beffa eq 10",
    )
    rate_damping: tuple = param((0.002, 0.002, 0.001), "N m s/rad", "body-rate damping torque -D ω")


@dataclass(frozen=True)
class SimConfig:
    environment: Environment = field(default_factory=Environment)
    vehicle: Vehicle = field(default_factory=Vehicle)
    imu: ImuTiming = field(default_factory=ImuTiming)
    gyro: Gyroscope = field(default_factory=Gyroscope)
    acc: Accelerometer = field(default_factory=Accelerometer)
    mag: Magnetometer = field(default_factory=Magnetometer)
    hover: Hover = field(default_factory=Hover)
    nominal: Nominal = field(default_factory=Nominal)
    damaged: DamagedRotor = field(default_factory=DamagedRotor)
    throw: Throw = field(default_factory=Throw)
    calibration: Calibration = field(default_factory=Calibration)
    aero: Aero = field(default_factory=Aero)

    def with_overrides(self, overrides: dict, source: str = "--set") -> SimConfig:
        """Apply ``{"section.field": value}`` or ``{"section": {"field": value}}`` overrides."""
        flat = {}
        for k, v in overrides.items():
            if isinstance(v, dict):
                flat.update({f"{k}.{kk}": vv for kk, vv in v.items()})
            else:
                flat[k] = v
        cfg = self
        for key, value in flat.items():
            section, _, name = key.partition(".")
            if section not in SECTIONS:
                raise ValueError(f"{source}: unknown section {section!r} in {key!r}; sections: " + ", ".join(SECTIONS))
            rec = getattr(cfg, section)
            names = [f.name for f in fields(rec)]
            if name not in names:
                raise ValueError(f"{source}: {section} has no parameter {name!r}; it has: " + ", ".join(names))
            rec = replace(rec, **{name: _coerce(key, getattr(rec, name), value)})
            cfg = replace(cfg, **{section: rec})
        return cfg

    def idealized(self) -> SimConfig:
        """Ideal sensors: no noise, bias, scale error, misalignment, saturation, disturbance,
        vibration, jitter or drops; lever arm and sample rates kept."""
        zero3 = (0.0, 0.0, 0.0)
        eye = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
        inertial = dict(
            noise_std=0.0,
            bias_std=0.0,
            bias=None,
            bias_rw_std=0.0,
            scale_std=0.0,
            scale=None,
            misalignment_std=0.0,
            misalignment=None,
            range=math.inf,
        )
        return replace(
            self,
            imu=replace(self.imu, jitter_std_s=0.0, drop_prob=0.0),
            gyro=replace(self.gyro, **inertial, vibration_amp=zero3),
            acc=replace(self.acc, **inertial, vibration_amp=zero3),
            mag=replace(self.mag, noise_std=0.0, hard_iron=zero3, soft_iron=eye, motor_coef=zero3, range=math.inf),
        )

    def to_dict(self) -> dict:
        return json.loads(json.dumps(asdict(self), default=_jsonable))

    def validate(self) -> SimConfig:
        """Refuse values no sensor or flight has (docs/reliability.md): every number finite
        (a range may be inf: no saturation); noise, standard deviations, amplitudes, times and
        probabilities not negative; probabilities at most 1; rates at most 100 kHz; the
        magnetometer's soft-iron matrix invertible. Returns the configuration."""
        for section in SECTIONS:
            rec = getattr(self, section)
            for f in fields(rec):
                key, v = f"{section}.{f.name}", getattr(rec, f.name)
                values = np.ravel(np.asarray(v, dtype=float)) if v is not None and not isinstance(v, bool) else []
                if len(values) and not np.isfinite(values).all() and not (f.name == "range" and values[0] == math.inf):
                    raise ValueError(f"{key} must be finite, got {v!r}")
                negative_forbidden = (
                    f.name.endswith(("_std", "_s", "_prob", "_amp", "_hz", "_max", "_rms")) or f.name in NOT_NEGATIVE
                )
                if negative_forbidden and len(values) and (values < 0).any():
                    raise ValueError(f"{key} must not be negative, got {v!r}")
                if f.name.endswith("_prob") and len(values) and (values > 1).any():
                    raise ValueError(f"{key} is a probability: at most 1, got {v!r}")
                if f.name in AT_MOST and len(values) and (values > AT_MOST[f.name][0]).any():
                    raise ValueError(f"{key} = {v!r}: at most {AT_MOST[f.name][0]:g} {AT_MOST[f.name][1]}")
                if f.name.endswith("rate_hz") and len(values) and (values > MAX_RATE_HZ).any():
                    raise ValueError(f"{key} = {v!r} Hz: beyond any sensor (at most {MAX_RATE_HZ:.0e} Hz)")
        if abs(np.linalg.det(np.asarray(self.mag.soft_iron, float))) < 1e-6:
            raise ValueError(
                f"mag.soft_iron {self.mag.soft_iron!r} is singular: a soft-iron distortion is close to the identity"
            )
        if not self.imu.rate_hz > 0:
            raise ValueError("imu.rate_hz must be positive")
        return self


SECTIONS = [f.name for f in fields(SimConfig)]
MAX_RATE_HZ = 1e5
AT_MOST = {
    "components": (100, "sinusoids per axis: a motion's memory grows with them"),
    "latency_s": (10.0, "s: no sensor reads a field older than that"),
}
"""Upper limits of parameters whose work or memory grows with them."""
NOT_NEGATIVE = {
    "range",
    "mass_kg",
    "inertia",
    "arm_m",
    "field_ut",
    "gravity",
    "thrust_to_weight",
    "rotor_drag",
    "vibration_amp",
    "tremor_acc",
    "spin_rate_var",
    "components",
    "active_rotors",
    "rate_damping",
    "tilt_deg",
    "six_tilt_deg",
    "tilt_amp_deg",
    "yaw_amp_deg",
    "vertical_ratio",
    "release_height_m",
}


def _jsonable(x):
    if isinstance(x, float) and not math.isfinite(x):
        return str(x)
    raise TypeError(f"not JSON-serialisable: {x!r}")


def _coerce(key, current, value):
    """Parse a string from the command line and check the type against the current value."""
    if isinstance(value, str):
        text, value = value, parse_text(value)
        if isinstance(value, str):
            raise ValueError(f"{key}: cannot read {text!r} as a number or list")
    if isinstance(value, list):
        value = _tuples(value)
    if value is None:
        return None
    if isinstance(current, int):  # whole-number parameters (counts)
        if not isinstance(value, (int, float)) or float(value) != int(value):
            raise ValueError(f"{key}: expected a whole number, got {value!r}")
        return int(value)
    if isinstance(current, float):
        if not isinstance(value, (int, float)):
            raise ValueError(f"{key}: expected a number, got {value!r}")
        return float(value)
    if isinstance(current, tuple) or current is None:
        if not isinstance(value, tuple):
            raise ValueError(f"{key}: expected a list such as [1, 2, 3], got {value!r}")
        if isinstance(current, tuple) and _shape(current) != _shape(value):
            raise ValueError(f"{key}: expected shape {_shape(current)}, got {_shape(value)}")
        return value
    return value


def _tuples(v):
    return tuple(_tuples(x) for x in v) if isinstance(v, list) else float(v)


def _shape(t):
    return (len(t),) + (_shape(t[0]) if t and isinstance(t[0], tuple) else ())


# -- presets -------------------------------------------------------------------------------
PRESETS = {
    "bebop2": {
        "description": "Parrot Bebop 2, the AFCKF paper's vehicle: MPU6050 IMU at 500 Hz, AK8963 "
        "magnetometer at 100 Hz, vibration-dominated noise",
        "overrides": {
            "vehicle.mass_kg": 0.5,
            "vehicle.inertia": (0.0015, 0.0015, 0.0026),
            "vehicle.arm_m": 0.085,
            "imu.rate_hz": 500.0,
            "mag.rate_hz": 100.0,
            "gyro.noise_std": 0.01,
            "gyro.range": math.radians(1000.0),
            "acc.noise_std": 0.25,
            "acc.vibration_amp": (0.25, 0.25, 0.25),
            "acc.lever_arm": (0.015, -0.010, 0.005),
            "mag.noise_std": 0.5,
            "mag.hard_iron": (0.5, -0.3, 0.4),
            "mag.soft_iron": ((1.005, 0.002, 0.0), (0.002, 0.997, 0.001), (0.0, 0.001, 1.002)),
            "mag.motor_coef": (0.8, -0.4, 1.5),
        },
        "sources": {
            "imu.rate_hz": "chosen: Bebop 2 IMU logging rate (the AFCKF paper gives none)",
            "mag.rate_hz": "chosen: a typical magnetometer rate (the AFCKF paper gives none)",
            "gyro.noise_std": "chosen: vibration-dominated per-sample noise of a small quadrotor",
            "gyro.range": "chosen: ±1000 °/s, a common MEMS gyro range; the AFCKF's ω_ψ,sat (eq 48) needs one",
            "acc.noise_std": "chosen: total per-sample σ 0.3 m/s² = √(0.25² + 0.25²/2) with the tone",
            "acc.vibration_amp": "chosen: rotor vibration, share of the 0.3 m/s² per-sample σ",
            "acc.lever_arm": "chosen: an IMU a centimetre or two off the centre of mass",
            "mag.noise_std": "chosen: a low-cost magnetometer's per-sample noise",
            "mag.hard_iron": "assumption: residual after the paper's calibration",
            "mag.soft_iron": "assumption: residual after the paper's calibration",
            "vehicle.mass_kg": "Parrot Bebop 2 specification (500 g)",
        },
    },
    "lowcost-20hz": {
        "description": "QUKF paper's low-cost system: MPU6050 + HMC5883L sampled at 20 Hz",
        "overrides": {
            "vehicle.mass_kg": 1.2,
            "vehicle.inertia": (0.012, 0.012, 0.022),
            "vehicle.arm_m": 0.225,
            "vehicle.rotor_hz_hover": 90.0,
            "imu.rate_hz": 20.0,
            "mag.rate_hz": 20.0,
            "gyro.noise_std": 0.005,
            "gyro.bias_std": 0.002,
            "gyro.range": math.radians(2000.0),
            "acc.noise_std": 0.1,
            "acc.bias_std": 0.05,
            "acc.range": 2 * GRAVITY,
            "acc.vibration_amp": (0.0, 0.0, 0.0),
            "mag.noise_std": 0.2,
            "mag.range": 130.0,
            "mag.motor_coef": (0.5, 0.3, 1.0),
        },
        "sources": {
            "imu.rate_hz": "QUKF paper, section IV (20 Hz)",
            "mag.rate_hz": "QUKF paper, section IV",
            "gyro.range": "QUKF paper eq 4: c = 16.4 LSB/(°/s), MPU6050 ±2000 °/s",
            "acc.range": "QUKF paper eq 4: b = 1638.35, MPU6050 ±2 g",
            "gyro.noise_std": "assumption: MPU6050 0.005 °/s/√Hz plus flight vibration behind the DLPF",
            "acc.noise_std": "assumption: MPU6050 400 µg/√Hz plus flight vibration behind the DLPF",
            "mag.noise_std": "HMC5883L datasheet: 2 mG noise floor",
            "mag.range": "HMC5883L ±1.3 G",
        },
    },
    "fma": {
        "description": "Recovery paper's vehicle in the Flying Machine Arena: IMU at 1000 Hz, no "
        "magnetometer, idle propellers",
        "overrides": {
            "vehicle.mass_kg": 0.5,
            "vehicle.inertia": (0.0023, 0.0023, 0.0046),
            "vehicle.arm_m": 0.17,
            "vehicle.rotor_hz_hover": 150.0,
            "imu.rate_hz": 1000.0,
            "mag.rate_hz": 0.0,
            "gyro.noise_std": 0.005,
            "gyro.bias_std": 0.001,
            "gyro.range": math.radians(2000.0),
            "acc.noise_std": 0.1,
            "acc.bias_std": 0.02,
            "acc.range": 16 * GRAVITY,
            "acc.vibration_amp": (0.05, 0.05, 0.05),
        },
        "sources": {
            "imu.rate_hz": "recovery paper, section III.C (1000 Hz)",
            "mag.rate_hz": "recovery paper: IMU only",
            "vehicle.mass_kg": "recovery paper, experimental setup (m = 0.5 kg)",
            "vehicle.inertia": "recovery paper, experimental setup (J = diag(0.0023, 0.0023, 0.0046))",
            "vehicle.arm_m": "recovery paper, experimental setup (L = 0.17 m)",
            "gyro.bias_std": "assumption: the paper assumes calibrated, unbiased sensors (section II.B)",
        },
    },
}
DEFAULT_SOURCES = {
    "environment.field_ut": "chosen: about 49 µT, a mid-latitude field (Netherlands)",
    "environment.inclination_deg": "chosen: 67°, a mid-latitude dip (Netherlands)",
}


def preset_config(name: str) -> SimConfig:
    """The configuration of a named preset."""
    if name not in PRESETS:
        raise ValueError(f"unknown preset {name!r}; presets: {', '.join(PRESETS)}")
    return SimConfig().with_overrides(PRESETS[name]["overrides"], source=f"preset {name}")


def load_toml_overrides(path) -> dict:
    """Read ``[section] field = value`` tables from a TOML file."""
    path = Path(path)
    check_regular(path)
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise ValueError(f"{path}: cannot read TOML ({exc})") from None
    for k, v in data.items():
        if not isinstance(v, dict):
            raise ValueError(f"{path}: top-level key {k!r} must be a [section] table")
    return data


def param_table(cfg: SimConfig, preset: str | None = None) -> list[dict]:
    """Every parameter with value, unit, meaning and source, in declaration order."""
    srcs = dict(DEFAULT_SOURCES)
    if preset:
        srcs.update(PRESETS[preset]["sources"])
    rows = []
    for sec in SECTIONS:
        rec = getattr(cfg, sec)
        for f in fields(rec):
            key = f"{sec}.{f.name}"
            rows.append(
                {
                    "key": key,
                    "value": getattr(rec, f.name),
                    "unit": f.metadata["unit"],
                    "doc": f.metadata["doc"],
                    "source": srcs.get(key, f.metadata["source"]),
                }
            )
    return rows
