"""A recorded flight with measured rotor speeds diagnosed against a vehicle model (a vehicle
file from ``quadest identify``, docs/vehicle.md): quadest's detector, with its measured-speed
settings, over each flying span; what it finds lost or damaged, and whether the moment it learns
against the model hit its clamp (a sign the model is off)."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from quadest.calibration.identify import EDGE_S, FLYING_SHARE
from quadest.detect import Detector, DetectorParams
from quadest.evaluation.diagnose import DiagnoseParams
from quadest.models.multirotor import MultirotorParams

SHORTEST_S = 5.0
"""Flying spans shorter than this (s) are not diagnosed."""


@dataclass
class SpeedDiagnosis:
    """What :func:`diagnose_speeds` found: failures and damaged rotors (rotor: the recording's
    column, 0-based; time in the recording's own time), the moment learnt per span, notes."""

    file: str
    vehicle: str
    failures: list[dict]
    damaged: list[dict]
    spans: list[dict]
    notes: list[str] = field(default_factory=list)

    def as_json(self) -> dict:
        return {
            "file": self.file,
            "vehicle": self.vehicle,
            "failures": self.failures,
            "damaged": self.damaged,
            "spans": self.spans,
            "notes": self.notes,
        }


def flying_spans(rec) -> list[tuple[int, int]]:
    """``[start, end)`` rows of each flying span (every rotor's speed above :data:`FLYING_SHARE`
    of the median summed square), :data:`EDGE_S` in from each end, of :data:`SHORTEST_S` or more."""
    speed = np.asarray(rec.rotor_speed, float)
    ok = np.isfinite(speed).all(axis=1)
    total = np.where(ok, (np.nan_to_num(speed) ** 2).sum(axis=1), 0.0)
    flying = ok & (total > FLYING_SHARE * np.median(total[ok])) if ok.any() else ok
    edges = np.flatnonzero(np.diff(np.concatenate([[0], flying.astype(np.int8), [0]])))
    spans = []
    for a, b in zip(edges[::2], edges[1::2]):
        a2 = int(np.searchsorted(rec.t, rec.t[a] + EDGE_S))
        b2 = int(np.searchsorted(rec.t, rec.t[b - 1] - EDGE_S))
        if b2 > a2 and rec.t[b2 - 1] - rec.t[a2] >= SHORTEST_S:
            spans.append((a2, b2))
    return spans


NO_DRAG = ((0.0, 0.0), (0.0, 0.0))
"""No drag moments (the detector's default)."""


def diagnose_speeds(rec, vehicle: MultirotorParams, *, file: str, vehicle_source: str,
                    params: DetectorParams | None = None, drag_moment=NO_DRAG) -> SpeedDiagnosis:  # fmt: skip
    """The detector over each flying span of ``rec`` with ``vehicle`` and ``drag_moment`` (a
    vehicle file's ``identified.drag_moment``) as its model (module doc); ``params`` by default
    its in-flight settings with measured speeds and, after the fact as the log diagnosis, a
    deficit counted only beyond :attr:`DiagnoseParams.deficit_sigmas` standard deviations (without
    it, a yaw step of the circle flight of ../shared/data/dido, rotor speeds read 10 ms after the
    gyroscope's response, made one rotor "damaged" for 40 ms)."""
    params = params or DetectorParams(rotor_speeds=True, deficit_sigmas=DiagnoseParams.deficit_sigmas)
    if rec.rotor_speed is None:
        raise ValueError(f"{file}: no rotor speeds: diagnosing against a vehicle file needs each rotor's speed")
    if rec.rotor_speed.shape[1] != vehicle.rotors:
        raise ValueError(
            f"{file}: {rec.rotor_speed.shape[1]} rotors, the vehicle {vehicle.rotors}: is it this vehicle's file?"
        )
    failures, damaged, spans, notes = [], [], [], []
    for a, b in flying_spans(rec):
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            found = Detector(vehicle, params, drag_moment=drag_moment).run(
                rec.t[a:b], rec.gyr[a:b], rec.acc[a:b], rec.rotor_speed[a:b]
            )
        notes += [str(w.message) for w in said]
        t0 = float(rec.t[a])
        spans.append(
            {
                "from_s": round(t0, 3),
                "to_s": round(float(rec.t[b - 1]), 3),
                "moment_scale": [round(float(v), 3) for v in found.moment_scale],
                "moment_scale_clamped": found.moment_scale_clamped,
            }
        )
        if found.lost is not None:
            failures.append(_finding(found.lost, t0 + found.lost_t, found.lost_effectiveness))
        if found.damaged is not None:
            damaged.append(_finding(found.damaged, t0 + found.damaged_t, found.damaged_effectiveness))
    if not spans:
        notes.append(f"no flying span of {SHORTEST_S:g} s or more: nothing diagnosed")
    return SpeedDiagnosis(file, vehicle_source, failures, damaged, spans, notes)


def _finding(rotor: int, t: float, effectiveness: float) -> dict:
    return {"time_s": round(float(t), 3), "motor": int(rotor), "effectiveness": round(float(effectiveness), 3)}


def format_speed_diagnosis(d: SpeedDiagnosis) -> str:
    """The diagnosis as text: the model, each span's learnt moment, what was found."""
    lines = [f"{d.file}: measured rotor speeds; vehicle model: {d.vehicle}"]
    for s in d.spans:
        clamp = f" (clamped about {', '.join(s['moment_scale_clamped'])})" if s["moment_scale_clamped"] else ""
        scale = ", ".join(f"{v:.2f}" for v in s["moment_scale"])
        lines.append(f"flying {s['from_s']:.1f}-{s['to_s']:.1f} s: moment learnt x, y, z {scale} of the model's{clamp}")
    for f in d.failures:
        lines.append(
            f"FAILURE: rotor {f['motor']} lost at {f['time_s']:.3f} s (effectiveness left {f['effectiveness']:.2f})"
        )
    for f in d.damaged:
        lines.append(f"DAMAGED: rotor {f['motor']} from {f['time_s']:.3f} s (effectiveness {f['effectiveness']:.2f})")
    if not d.failures and not d.damaged:
        lines.append("no rotor failure or damage found")
    lines += [f"note: {n}" for n in d.notes]
    return "\n".join(lines)
