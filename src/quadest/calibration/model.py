"""The calibration file and how a calibration is applied to a recording.

Models (quadest conventions; the accelerometer's is the QUKF paper's eq 4, ``a = R_a (a' − a_e)``):

- gyro: ``ω = ω' − b``
- accel: ``a = T (a' − b)`` with T the full 3x3 matrix that undoes scale and misalignment
- mag: ``m = W (m' − h)``: hard iron h and the soft-iron correction W (symmetric)
- centrifugal: the AFCKF's ``ω1, ω2`` (eq 13), applied as estimator parameters
- aero: the recovery paper's model (eq 9), used by ``quadest recover``

A calibration states the sensor and the unit of the data it was fitted from (``unit``; for
centrifugal and aero, the accelerometer's); applying it to a recording whose unit differs is
refused. The parameters' own units: biases and hard iron in the sensor's unit, ω1 and ω2 in m,
A, B, C in N s/m, N s²/m², N.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from quadest.conventions import GRAVITY
from quadest.data.checks import rests
from quadest.data.files import write_json
from quadest.data.recording import Recording
from quadest.data.tagged import read_tagged_json
from quadest.models.aero import AeroModel

FORMAT_TAG = "quadest calibration v1"
KINDS = ("gyro", "accel", "mag", "centrifugal", "aero")
VALUE_SHAPES = {
    "gyro": {"bias": (3,)},
    "accel": {"bias": (3,), "matrix": (3, 3)},
    "mag": {"hard_iron": (3,), "soft_iron_correction": (3, 3)},
    "centrifugal": {"omega1": (), "omega2": ()},
    "aero": {"A": (3, 3), "B": (3, 3), "C": (3, 10), "mass_kg": ()},
}
"""The values each kind of calibration must hold, and their shapes."""
SENSOR = {"gyro": "gyr", "accel": "acc", "mag": "mag", "centrifugal": "acc", "aero": "acc"}


@dataclass
class Calibration:
    """One calibration: ``values`` (model parameters), ``uncertainty`` (1σ of the same keys),
    ``quality`` (fit figures) and where it came from."""

    kind: str
    unit: str
    values: dict
    uncertainty: dict = field(default_factory=dict)
    quality: dict = field(default_factory=dict)
    source: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"unknown calibration kind {self.kind!r}; kinds: {', '.join(KINDS)}")
        if not isinstance(self.values, dict):
            raise ValueError(f"calibration {self.kind}: values must be a mapping of names to numbers")
        for key, shape in VALUE_SHAPES[self.kind].items():
            if key not in self.values:
                raise ValueError(f"calibration {self.kind} lacks the value {key!r}")
            try:
                a = np.asarray(self.values[key], dtype=float)
            except (TypeError, ValueError):
                raise ValueError(f"calibration {self.kind}: {key} is not numeric") from None
            if a.shape != shape or not np.isfinite(a).all():
                raise ValueError(
                    f"calibration {self.kind}: {key} must be {shape or 'a number'} of finite numbers, "
                    f"got {self.values[key]!r}"
                )
            if key in ("matrix", "soft_iron_correction") and abs(np.linalg.det(a)) < 1e-6:
                raise ValueError(
                    f"calibration {self.kind}: the matrix {key} is singular; applying it would "
                    "erase the sensor's signal"
                )

    @property
    def sensor(self) -> str:
        return SENSOR[self.kind]

    def to_dict(self) -> dict:
        return {
            "format": FORMAT_TAG,
            "kind": self.kind,
            "sensor": self.sensor,
            "unit": self.unit,
            "values": self.values,
            "uncertainty": self.uncertainty,
            "quality": self.quality,
            "source": self.source,
        }

    def save(self, path: str | Path) -> Path:
        """Write the JSON file, atomically (nothing half-written is left on a failure)."""
        return write_json(path, self.to_dict())

    def check(self, rec: Recording) -> None:
        """Refuse a recording whose sensor unit differs from the calibration's."""
        units = rec.meta.get("units", {})
        have = units.get(self.sensor)
        if have is not None and have != "unknown" and have != self.unit:
            raise ValueError(
                f"calibration {self.kind} was made for {self.sensor} in {self.unit}, but the "
                f"recording's {self.sensor} is in {have}"
            )
        if self.kind == "mag" and not rec.has_mag:
            raise ValueError("a magnetometer calibration needs a recording with magnetometer samples")

    def apply(self, rec: Recording) -> Recording:
        """A new recording with this calibration applied (gyro, accel, mag kinds)."""
        self.check(rec)
        kw = {k: getattr(rec, k) for k in ("t", "gyr", "acc", "mag", *rec.truth, *rec.rotor_channels)}
        v = self.values
        if self.kind == "gyro":
            kw["gyr"] = rec.gyr - np.asarray(v["bias"])
        elif self.kind == "accel":
            kw["acc"] = (rec.acc - np.asarray(v["bias"])) @ np.asarray(v["matrix"]).T
        elif self.kind == "mag":
            kw["mag"] = (rec.mag - np.asarray(v["hard_iron"])) @ np.asarray(v["soft_iron_correction"]).T
        else:
            return rec
        warn_if_unfit(self, rec, kw[self.sensor])
        meta = dict(rec.meta)
        meta["calibrations"] = list(meta.get("calibrations", [])) + [self.kind]
        return Recording(**kw, meta=meta, check_units=False)

    def aero_model(self) -> AeroModel:
        """The aerodynamic model of an ``aero`` calibration (recovery paper eq 9)."""
        if self.kind != "aero":
            raise ValueError(f"a {self.kind} calibration holds no aerodynamic model")
        v = self.values
        return AeroModel(v["A"], v["B"], v["C"], v["mass_kg"])

    def filter_params(self) -> dict:
        """Estimator parameters this calibration sets (``{"afckf": {"omega1": ..}}``)."""
        if self.kind == "centrifugal":
            return {"afckf": {"omega1": self.values["omega1"], "omega2": self.values["omega2"]}}
        return {}


UNFIT = {"mag": 0.1, "gyro": 0.02, "accel": 0.2}
"""How far a calibrated recording may miss what its calibration promises before a warning, when
the calibration made it miss further than the raw data did (twice as far for the rests, which
may hold a level yaw): the field strength's spread as a
share of its median (mag: a fitting one leaves about 0.02), the gyroscope's mean rate over the
rests (rad/s), the rests' accelerometer norm from g (m/s²)."""


def _miss(kind: str, t, acc, values) -> float:
    """How far ``values`` (a sensor's, raw or calibrated) miss what a calibration promises; NaN
    where the recording cannot tell (a gyroscope or accelerometer without rests)."""
    values = values[np.isfinite(values).all(axis=1)] if kind == "mag" else values
    if kind == "mag":
        norm = np.linalg.norm(values, axis=1)
        return float(np.std(norm) / np.median(norm)) if len(norm) >= 10 and np.median(norm) > 0 else float("nan")
    spans = rests(t, acc)
    if not spans:
        return float("nan")
    rows = np.concatenate([np.arange(a, b) for a, b in spans])
    if kind == "gyro":
        return float(np.linalg.norm(np.nanmean(values[rows], axis=0)))
    return float(abs(np.nanmedian(np.linalg.norm(values[rows], axis=1)) - GRAVITY))


def warn_if_unfit(cal: Calibration, rec: Recording, calibrated) -> None:
    """Warn when a calibration leaves a recording further from what it promises than the raw
    data were (:data:`UNFIT`): a calibration made on another sensor, or from data that could
    not determine it."""
    import warnings

    raw = getattr(rec, cal.sensor)
    acc = rec.acc if cal.kind != "accel" else calibrated
    before, after = _miss(cal.kind, rec.t, rec.acc, raw), _miss(cal.kind, rec.t, acc, calibrated)
    # a rest's gyroscope and accelerometer may hold real motion (a level yaw): only a calibration
    # that at least doubles the miss is called unfit there; the field's spread is motion-free
    if after > UNFIT[cal.kind] and after > (before if cal.kind == "mag" else 2.0 * before):
        what = {
            "mag": "the field strength spreads",
            "gyro": "the rests' mean rate is",
            "accel": "the rests read g off by",
        }
        warnings.warn(
            f"calibration {cal.kind} does not fit {rec.meta.get('source', 'this recording')}: calibrated, "
            f"{what[cal.kind]} {after:.3g} ({before:.3g} raw, at most {UNFIT[cal.kind]} expected): made on "
            "another sensor, or from data that could not determine it?",
            stacklevel=3,
        )


def load_calibration(path: str | Path) -> Calibration:
    d = read_tagged_json(path, FORMAT_TAG, "calibration")
    try:
        return Calibration(
            d["kind"], d["unit"], d["values"], d.get("uncertainty", {}), d.get("quality", {}), d.get("source", {})
        )
    except KeyError as exc:
        raise ValueError(f"{path}: calibration lacks {exc}") from None


def apply_calibrations(
    rec: Recording, calibrations: Iterable[Calibration | str | Path] | None
) -> tuple[Recording, dict]:
    """Apply calibrations (files or :class:`Calibration` records) in order; returns the
    recording and the estimator parameters they set."""
    params: dict = {}
    for p in calibrations or []:
        cal = p if isinstance(p, Calibration) else load_calibration(p)
        rec = cal.apply(rec)
        for name, kv in cal.filter_params().items():
            params.setdefault(name, {}).update(kv)
    return rec, params
