"""One type for a time series of IMU / magnetometer data with optional ground truth.

Conventions: :mod:`quadest.conventions` (NED / FRD, ``q_nb`` scalar first, SI units). Its files
(CSV or Parquet, a lossless round trip): :mod:`quadest.data.recording_files`.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from quadest.data.checks import BLOCK, check_units, row_norms

# name -> (columns suffixes, width, description)
TRUTH_FIELDS = {
    "true_q": (("w", "x", "y", "z"), "attitude q_nb, [w, x, y, z]"),
    "true_gyr": (("x", "y", "z"), "body angular rate, rad/s, body frame"),
    "true_pos": (("n", "e", "d"), "position, m, navigation frame"),
    "true_vel": (("n", "e", "d"), "velocity, m/s, navigation frame"),
    "true_acc": (("x", "y", "z"), "specific force at the IMU, m/s², body frame"),
    "ref_q": (
        ("w", "x", "y", "z"),
        "reference attitude q_nb from the vehicle's own estimator (PX4 EKF2, ArduPilot EKF): not independent truth",
    ),
}
SENSOR_FIELDS = ("gyr", "acc", "mag")
ROTOR_FIELDS = {
    "rotor_speed": "each rotor's speed, rad/s",
    "motor_command": "each motor's command, normalised: 0 off, 1 full",
}
"""The rotors' channels: one column per rotor, numbered from 0 in quadest's order (the detector's and a
failure's rotor index); ``meta['rotors']`` says which of the source's motors each one is. NaN: no reading
of that rotor at that row."""
MAX_ROTOR_CHANNELS = 12
ROTOR_SPEED_LIMIT = 1.0e4
"""rad/s (about 95 000 rpm): no propeller turns faster; a larger value is rpm or another unit."""


def columns_of(name: str, rotors: int = 0) -> list[str]:
    """CSV / Parquet column names of a field (``'gyr'`` -> ``['gyr_x', 'gyr_y', 'gyr_z']``; a rotor
    field's with its ``rotors`` count: ``rotor_speed_0`` ...)."""
    if name in ROTOR_FIELDS:
        return [f"{name}_{i}" for i in range(rotors)]
    if name in SENSOR_FIELDS:
        return [f"{name}_{a}" for a in "xyz"]
    return [f"{name}_{a}" for a in TRUTH_FIELDS[name][0]]


def _first_row(mask) -> int:
    return int(np.flatnonzero(mask)[0])


SI_UNITS = {"gyr": ("rad/s",), "acc": ("m/s^2", "m/s²", "m/s2")}
"""What a Recording's ``meta['units']`` may say of the gyroscope and the accelerometer: the
values are in these units, whatever a file's units line claims."""
_TO_SI = {"gyr": "multiply deg/s by pi/180", "acc": "multiply g by 9.80665"}


def _check_si(units: dict) -> None:
    """Refuse units that contradict SI: a units line saying deg/s or g over values that would
    be taken as rad/s and m/s² (never ignored)."""
    for name, allowed in SI_UNITS.items():
        if units.get(name) not in allowed:
            raise ValueError(
                f"units: {name} is stated to be in {units.get(name)!r}, but a recording holds {allowed[0]} and "
                f"its values would be taken as such: convert them ({_TO_SI[name]}) and state {allowed[0]}, or "
                "read the file as a CSV with its units (--format csv --map ... --units "
                f"{name}={units.get(name)})"
            )


FLOAT_EXACT = 2**53
"""Integers beyond this cannot be held exactly in a float64: no sensor value is that large."""


def numeric_column(source, name: str, col, *, exact: bool = True) -> np.ndarray:
    """A pyarrow column as float64: floats, integers (with ``exact``, none beyond
    :data:`FLOAT_EXACT` in magnitude: a damaged or mislabelled value), or a column of nulls (NaN).
    Anything else (bool, string, date, decimal ...) is refused in one line naming the column."""
    import pyarrow as pa

    kind = col.type
    if pa.types.is_null(kind):
        return np.full(len(col), np.nan)
    if not (pa.types.is_floating(kind) or pa.types.is_integer(kind)):
        raise ValueError(f"{source}: column {name} holds {kind} values, not numbers")
    a = col.to_numpy(zero_copy_only=False)
    if exact and pa.types.is_integer(kind) and a.dtype.kind in "iu" and len(a):
        big = np.abs(a.astype(np.float64)) > FLOAT_EXACT
        if big.any():
            i = _first_row(big)
            raise ValueError(
                f"{source}: column {name} holds the integer {a[i]} at row {i}, beyond what a float holds "
                "exactly (2^53): the file is damaged or the column is not a measurement"
            )
    return a.astype(np.float64, copy=False)


def _check_unit_rows(name: str, q) -> None:
    """Refuse a finite row of ``q`` that is not a unit quaternion (block by block)."""
    for s in range(0, len(q), BLOCK):
        norm = row_norms(q[s : s + BLOCK])  # a damaged file's 1e300 gives inf: refused elsewhere
        bad = np.isfinite(norm) & (np.abs(norm - 1.0) > 1e-6)
        if bad.any():
            i = _first_row(bad)
            raise ValueError(f"{name}: row {s + i} is not a unit quaternion (norm {norm[i]:.6g})")


@dataclass(frozen=True, eq=False)
class Recording:
    """IMU and magnetometer samples with optional ground truth, on quadest's conventions.

    Parameters
    ----------
    t : (N,) timestamps, s; finite and strictly increasing.
    gyr : (N, 3) gyroscope, rad/s, body frame (FRD); finite.
    acc : (N, 3) accelerometer specific force, m/s², body frame; finite.
    mag : (N, 3) magnetometer in any unit (stated in ``meta['units']['mag']``), body frame;
        a row of NaN means "no new magnetometer sample". ``None`` means no magnetometer.
    true_q, true_gyr, true_pos, true_vel, true_acc : optional ground truth (see
        ``TRUTH_FIELDS``); a row of NaN means "no truth at this sample".
    ref_q : optional reference attitude from the vehicle's own estimator (a log's onboard
        attitude), kept apart from truth.
    rotor_speed : optional (N, n) speed of each of n rotors, rad/s, ≥ 0 (``ROTOR_FIELDS``).
    motor_command : optional (N, n) command of each motor, normalised to [0, 1]. In both, NaN is
        "no reading of that rotor at that row"; ``meta['rotors']`` holds the count, the source's
        numbering (``motors``), the spin directions (``spin``, +1 clockwise seen from above) and
        the arms' directions (``positions``, body FRD) where the source states them.
    meta : JSON-serialisable metadata: ``preset``, ``imu_rate_hz``, ``mag_rate_hz``,
        ``source``, ``units`` and anything else.
    check_units : if true (default), refuse magnitudes that show a unit mistake (gyroscope in
        deg/s, acceleration in g or in mg).

    Raises ValueError naming the field and the first bad row.
    """

    t: np.ndarray
    gyr: np.ndarray
    acc: np.ndarray
    mag: np.ndarray | None = None
    true_q: np.ndarray | None = None
    true_gyr: np.ndarray | None = None
    true_pos: np.ndarray | None = None
    true_vel: np.ndarray | None = None
    true_acc: np.ndarray | None = None
    ref_q: np.ndarray | None = None
    rotor_speed: np.ndarray | None = None
    motor_command: np.ndarray | None = None
    meta: dict = field(default_factory=dict)
    check_units: bool = field(default=True, repr=False)
    _adopt: bool = field(default=False, repr=False, compare=False)  # a reader's own arrays: not copied

    def __post_init__(self):
        copy = not self._adopt
        t = self._array("t", self.t, ndim=1, copy=copy)
        n = len(t)
        if n == 0:
            raise ValueError("t: a recording needs at least one sample")
        bad = ~np.isfinite(t)
        if bad.any():
            raise ValueError(f"t: non-finite value at row {_first_row(bad)}")
        step = np.diff(t) <= 0
        if step.any():
            i = _first_row(step) + 1
            raise ValueError(
                f"t: not strictly increasing at row {i} (t[{i}] = {float(t[i])!r} <= t[{i - 1}] = {float(t[i - 1])!r})"
            )
        object.__setattr__(self, "t", t)
        for name in ("gyr", "acc"):
            a = self._array(name, getattr(self, name), width=3, n=n, copy=copy)
            bad = ~np.isfinite(a).all(axis=1)
            if bad.any():
                raise ValueError(f"{name}: non-finite value at row {_first_row(bad)}")
            object.__setattr__(self, name, a)
        mag = self.mag if self.mag is not None else np.full((n, 3), np.nan)
        mag = self._array("mag", mag, width=3, n=n, copy=copy)
        self._check_nan_rows("mag", mag)
        object.__setattr__(self, "mag", mag)
        for name, (axes, _) in TRUTH_FIELDS.items():
            value = getattr(self, name)
            if value is None:
                continue
            a = self._array(name, value, width=len(axes), n=n, copy=copy)
            self._check_nan_rows(name, a)
            if name in ("true_q", "ref_q"):
                _check_unit_rows(name, a)
            object.__setattr__(self, name, a)
        self._set_rotor_channels(n, copy)
        if not isinstance(self.meta, dict):
            raise ValueError("meta: must be a dict")
        try:
            meta = json.loads(json.dumps(self.meta))
        except (TypeError, ValueError) as exc:
            raise ValueError(f"meta: must be JSON-serialisable ({exc})") from None
        meta.setdefault("units", {})
        if not isinstance(meta["units"], dict):
            raise ValueError(f'meta: units must be a mapping like {{"mag": "uT"}}, got {meta["units"]!r}')
        meta["units"] = {"gyr": "rad/s", "acc": "m/s^2", "mag": "unknown", **meta["units"]}
        _check_si(meta["units"])
        _check_rotor_meta(meta, self.rotors)
        _check_declination_meta(meta)
        object.__setattr__(self, "meta", meta)
        if self.check_units:
            self._check_units()

    # -- validation helpers -------------------------------------------------------------
    def _set_rotor_channels(self, n, copy):
        """The rotors' channels checked: one width for both, NaN allowed per value (a rotor without a
        reading), never an infinite value, a negative speed or a command outside [0, 1]."""
        widths = set()
        for name in ROTOR_FIELDS:
            value = getattr(self, name)
            if value is None:
                continue
            a = self._array(name, value, n=n, copy=copy)
            if not 1 <= a.shape[1] <= MAX_ROTOR_CHANNELS:
                raise ValueError(f"{name}: expected 1 to {MAX_ROTOR_CHANNELS} rotors (columns), got {a.shape[1]}")
            widths.add(a.shape[1])
            inf = np.isinf(a).any(axis=1)
            if inf.any():
                raise ValueError(f"{name}: infinite value at row {_first_row(inf)}")
            with np.errstate(invalid="ignore"):
                low = (a < 0.0).any(axis=1) if name == "rotor_speed" else ((a < 0.0) | (a > 1.0)).any(axis=1)
            if low.any():
                i = _first_row(low)
                what = "a negative speed (a magnitude, rad/s)" if name == "rotor_speed" else "a value outside [0, 1]"
                raise ValueError(f"{name}: row {i} holds {what}: {a[i].tolist()}")
            object.__setattr__(self, name, a)
        if len(widths) > 1:
            counts = " and ".join(map(str, sorted(widths)))
            raise ValueError(f"rotor_speed and motor_command: different rotor counts ({counts})")

    @staticmethod
    def _array(name, value, ndim=2, width=None, n=None, copy=True):  # width None: any (a rotor field)
        try:
            a = np.array(value, dtype=np.float64) if copy else np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"{name}: not a numeric array") from None
        shape = "(N,)" if ndim == 1 else f"(N, {width or 'rotors'})"
        if a.ndim != ndim or (width is not None and a.shape[1] != width):
            raise ValueError(f"{name}: expected shape {shape}, got {a.shape}")
        if n is not None and len(a) != n:
            raise ValueError(f"{name}: has {len(a)} rows but t has {n}")
        return a

    @staticmethod
    def _check_nan_rows(name, a):
        nan = np.isnan(a)
        partial = nan.any(axis=1) & ~nan.all(axis=1)
        if partial.any():
            raise ValueError(
                f"{name}: row {_first_row(partial)} is partly NaN; a row without a sample must be NaN in every column"
            )
        inf = np.isinf(a).any(axis=1)
        if inf.any():
            raise ValueError(f"{name}: infinite value at row {_first_row(inf)}")

    def _check_units(self):
        check_units(self.t, self.gyr, self.acc, self.mag if self.has_mag else None)
        if self.rotor_speed is not None:
            with np.errstate(invalid="ignore"):
                fast = (self.rotor_speed > ROTOR_SPEED_LIMIT).any(axis=1)
            if fast.any():
                i = _first_row(fast)
                raise ValueError(
                    f"rotor_speed: row {i} holds {np.nanmax(self.rotor_speed[i]):.6g}, beyond any propeller's "
                    f"{ROTOR_SPEED_LIMIT:g} rad/s: the speeds are in rpm or another unit (rpm times pi/30 is rad/s)"
                )

    # -- properties ---------------------------------------------------------------------
    def __len__(self):
        return len(self.t)

    def __repr__(self) -> str:
        """A line, not the arrays: samples, duration, rate, channels and the source."""
        n = len(self.t)
        channels = ["gyr", "acc", *(["mag"] if self.has_mag else []), *self.truth, *self.rotor_channels]
        span = f", {self.duration:.3f} s at {self.imu_rate_hz():.1f} Hz" if n > 1 else ""
        source = self.meta.get("source")
        return (
            f"Recording({n} sample{'s' if n != 1 else ''}{span}; {', '.join(channels)}"
            + (f"; from {source}" if source else "")
            + ")"
        )

    @property
    def duration(self) -> float:
        """Time from the first to the last sample, s."""
        return float(self.t[-1] - self.t[0])

    @property
    def has_mag(self) -> bool:
        """True when at least one magnetometer sample is present."""
        return bool(np.isfinite(self.mag[:, 0]).any())

    @property
    def truth(self) -> list[str]:
        """Names of the truth fields present."""
        return [k for k in TRUTH_FIELDS if getattr(self, k) is not None]

    @property
    def rotor_channels(self) -> list[str]:
        """Names of the rotors' channels present (``ROTOR_FIELDS``)."""
        return [k for k in ROTOR_FIELDS if getattr(self, k) is not None]

    @property
    def rotors(self) -> int:
        """How many rotors the rotor channels hold (0: none)."""
        return next((getattr(self, k).shape[1] for k in self.rotor_channels), 0)

    @property
    def declination(self) -> float:
        """Magnetic declination (rad, east positive) of the recording's field: from a
        simulation's earth field (``meta['earth_field_ned_ut']``), else
        ``meta['declination_rad']``, else 0. Estimators reference magnetic north; this turns
        their heading to true north."""
        B = self.meta.get("earth_field_ned_ut")
        if B is not None:
            return float(math.atan2(B[1], B[0]))
        return float(self.meta.get("declination_rad", 0.0))

    @property
    def declination_source(self) -> str:
        """Where :attr:`declination` comes from, in words."""
        if self.meta.get("earth_field_ned_ut") is not None:
            return "the simulation's earth field"
        if "declination_source" in self.meta:
            return str(self.meta["declination_source"])
        if "declination_rad" in self.meta:
            return "the recording's declination_rad"
        return "none stated: 0 (give --declination-deg)"

    def imu_rate_hz(self) -> float:
        """Nominal IMU rate from the median sample interval, Hz."""
        if len(self.t) < 2:
            return float(self.meta.get("imu_rate_hz", float("nan")))
        return float(1.0 / np.median(np.diff(self.t)))

    def mag_rate_hz(self) -> float:
        """Mean magnetometer rate, Hz (0 without magnetometer)."""
        tm = self.t[np.isfinite(self.mag[:, 0])]
        if len(tm) < 2:
            return 0.0
        return float((len(tm) - 1) / (tm[-1] - tm[0]))

    def select(self, index: slice | ArrayLike) -> Recording:
        """A new recording with the rows ``index`` (slice, boolean mask or integer array)."""
        kw = {k: getattr(self, k)[index] for k in ("t", "gyr", "acc", "mag", *self.truth, *self.rotor_channels)}
        return Recording(**kw, meta=self.meta, check_units=False)

    def sensors_only(self) -> Recording:
        """The same samples (not copied) without truth or onboard reference: what a command that
        estimates needs, so that a long recording's truth is not held."""
        return Recording(self.t, self.gyr, self.acc, self.mag, meta=self.meta, check_units=False, _adopt=True)

    def between(self, t0: float, t1: float) -> Recording:
        """Rows with ``t0 <= t <= t1``."""
        return self.select((self.t >= t0) & (self.t <= t1))

    def columns(self) -> dict[str, np.ndarray]:
        """Every column by its file name, in file order."""
        cols = {"t": self.t}
        for name in ("gyr", "acc", "mag", *self.truth, *self.rotor_channels):
            a = getattr(self, name)
            for j, c in enumerate(columns_of(name, self.rotors)):
                cols[c] = a[:, j]
        return cols


def _check_declination_meta(meta: dict) -> None:
    """What :attr:`Recording.declination` reads, where present: an earth field of 3 finite numbers
    (µT, NED) and a finite declination (rad)."""
    field_ned = meta.get("earth_field_ned_ut")
    if field_ned is not None and not (
        isinstance(field_ned, (list, tuple))
        and len(field_ned) == 3
        and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in field_ned)
    ):
        raise ValueError(f"meta: earth_field_ned_ut must be 3 finite numbers (µT, NED), got {field_ned!r}")
    decl = meta.get("declination_rad", 0.0)
    if not (isinstance(decl, (int, float)) and not isinstance(decl, bool) and math.isfinite(decl)):
        raise ValueError(f"meta: declination_rad must be a finite number (rad), got {decl!r}")


def _check_rotor_meta(meta: dict, rotors: int) -> None:
    """``meta['rotors']``, where present: a mapping whose ``count`` and per-rotor lists (``motors``,
    ``spin``, ``positions``) agree with the channels' rotor count."""
    info = meta.get("rotors")
    if info is None:
        return
    if not isinstance(info, dict):
        raise ValueError(f'meta: rotors must be a mapping like {{"count": 4, "spin": [...]}}, got {info!r}')
    count = info.get("count", rotors)
    if rotors and count != rotors:
        raise ValueError(f"meta: rotors states {count} rotors but the rotor channels hold {rotors}")
    for key in ("motors", "spin", "positions"):
        if key in info and (not isinstance(info[key], list) or len(info[key]) != count):
            raise ValueError(f"meta: rotors.{key} must be a list of {count} (one per rotor), got {info[key]!r}")
