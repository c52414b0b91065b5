"""The AFCKF paper's experiment on the flying vehicle (issue #14, parts 1 and 2).

The prescribed damaged-rotor scenario (docs/simulator.md) takes its spin rate, tilt and spin-up
as inputs. Here a Bebop 2 (the paper's vehicle, Sun et al.'s parameters) *flies*: it hovers, or
flies a 1 m circle, loses rotor 0, and the fault-tolerant controller keeps it up with the *true*
state in its loop (``quadest.flight``), so the motion is the same whatever the estimators make
of it. The estimators then run over its sensors (the bebop2 preset's), scored from the loss on
as in the paper's Tables I-IV; the spin rate, the tilt and the share of gyroscope samples that
clip are outputs of the flight, printed beside the paper's 15.5 rad/s.

**Ablations.** Because the motion does not depend on the sensors, each ablation samples the same
flights again with one sensor property changed (:func:`quadest.flight.resample`) and runs every
filter over them: one change per row, the rest the baseline's (:data:`ABLATIONS`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from quadest.calibration import calibrate_centrifugal
from quadest.control import Failure
from quadest.evaluation.metrics import AXES
from quadest.evaluation.runner import estimate, score
from quadest.flight import FlightParams, fly, resample
from quadest.records import check, describe, param
from quadest.sim import build_config


@dataclass(frozen=True)
class FlownAfckfParams:
    """What the flown reproduction assumes beyond the vehicle and its sensors."""

    vehicle: str = param("bebop2", "-", "vehicle preset (docs/vehicle.md)",
                         "the AFCKF paper's vehicle, a Parrot Bebop 2 (Sun et al. 2021's simulation parameters)")
    preset: str = param("bebop2", "-", "sensor preset (docs/simulator.md)", "the prescribed reproduction's")
    rotor: int = param(0, "-", "the rotor lost (front right)", "chosen: the paper does not say which",
                       bounds="[0, 3]")
    failure_s: float = param(5.0, "s", "time of the loss", "chosen: as the prescribed scenario; the filters have "
                             "converged in hover by then", bounds="(0, 3600]")
    duration_s: float = param(30.0, "s", "length of each flight", "chosen: 25 s after the loss, mostly the "
                              "settled spin", bounds="(0, 3600]")
    height_m: float = param(10.0, "m", "height of the hover point above the ground",
                            "chosen: room for the Bebop 2's fall after the loss (2.6 m from hover, 5.4 m from the "
                            "circle)", bounds="(0, 1e3]")
    calibration_seed: int = param(1000, "-", "the AFCKF's centrifugal calibration flight (never evaluated)",
                                  "chosen: apart from the evaluated seeds", bounds="[0, 1e9]")
    calibration_after_s: float = param(8.0, "s", "the calibration reads the spin from this long after the loss",
                                       "chosen: the relaxed hover has settled (about 6 s on the Bebop 2)",
                                       bounds="[0, 3600]")

    def __post_init__(self):
        check(self, "flown afckf")

    @classmethod
    def describe(cls) -> list[dict]:
        return describe(cls)


CASES = {
    "damaged-rotor": ("rotor-loss", True),  # hover, then the loss
    "damaged-rotor-trajectory": ("trajectory", True),  # the 1 m circle, then the loss (and hold)
    "nominal": ("trajectory", False),  # the circle, no loss
}
"""The flown cases: the flight (``quadest fly`` scenario) and whether rotor ``rotor`` is lost."""

FILTERS = ["madgwick", "complementary", "kalman", "afckf", "afckf"]
LABELS = ["madgwick", "complementary", "kalman", "afckf", "afckf-nocal"]


def flown_flight(case: str, seed: int, p: FlownAfckfParams | None = None, config=None):
    """One flight of ``case`` (:data:`CASES`) with the truth in the loop."""
    p = p or FlownAfckfParams()
    scenario, lost = CASES[case]
    return fly(scenario, estimator="truth", controller="ftc" if lost else "se3", vehicle=p.vehicle,
               preset=p.preset, config=config, seed=seed, duration=p.duration_s,
               failure=Failure(p.rotor, p.failure_s) if lost else None, params=FlightParams(height_m=p.height_m))


def flight_outputs(flight, t_from: float) -> dict:
    """What physics made of a flight: its end, the settled spin and tilt (a loss), and the share
    of IMU samples after ``t_from`` on which a gyroscope axis sits at its range (clipped)."""
    rec = flight.recording
    rng = rec.meta["config"]["gyro"]["range"]
    after = rec.t >= t_from
    clipped = (np.abs(rec.gyr[after]) >= rng * (1 - 1e-12)).any(axis=1)
    s = flight.summary
    return {"status": s["status"], "spin_rate_rad_s": s.get("spin_rate_rad_s"), "tilt_deg": s.get("tilt_deg"),
            "gyro_clipped_share": float(clipped.mean()) if clipped.size else 0.0,
            "peak_rate_rad_s": float(np.abs(rec.true_gyr[after]).max()) if after.any() else None}


def afckf_calibration_flown(p: FlownAfckfParams | None = None) -> dict:
    """ω1, ω2 of the AFCKF's eq 13 from a separate flown loss (``calibration_seed``) through
    ``quadest calibrate centrifugal`` on its settled spin (:func:`quadest.calibration.calibrate_centrifugal`)."""
    p = p or FlownAfckfParams()
    rec = flown_flight("damaged-rotor", p.calibration_seed, p).recording
    cal = calibrate_centrifugal([rec.between(p.failure_s + p.calibration_after_s, np.inf)])
    return {"omega1": float(cal.values["omega1"]), "omega2": float(cal.values["omega2"]),
            "uncertainty_m": float(cal.uncertainty["omega1"]), "residual_mps2": cal.quality["residual_rms_mps2"],
            "seed": p.calibration_seed, "flown": True}


def score_filters(rec, params: dict, t_from: float) -> dict:
    """Every filter of the reproduction (:data:`LABELS`) over ``rec``, scored from ``t_from``."""
    return {label: score(rec, estimate(rec, name, params.get(label)).q, t_from=t_from)
            for name, label in zip(FILTERS, LABELS)}


def flown_seed(task) -> dict:
    """One seed of one flown case (a picklable task ``(case, seed, params, filter params)``):
    the filters' errors and the flight's outputs."""
    case, seed, p, fparams = task
    flight = flown_flight(case, seed, p)
    t_from = p.failure_s if CASES[case][1] else 0.0
    if flight.summary["status"] != "survived":
        raise ValueError(f"the flown {case} (seed {seed}) did not survive: {flight.summary['reason']}")
    return {"scores": score_filters(flight.recording, fparams, t_from), "flight": flight_outputs(flight, t_from)}


# -- ablations -----------------------------------------------------------------------------------------
ABLATIONS = [
    ("baseline: bebop2 sensors", {}, None),
    ("gyro range ±2000°/s", {"gyro.range": math.radians(2000.0)}, None),
    ("gyro range ±500°/s", {"gyro.range": math.radians(500.0)}, None),
    ("gyro scale error 0", {"gyro.scale": (0.0, 0.0, 0.0)}, None),
    ("gyro scale error +0.3 %", {"gyro.scale": (0.003, 0.003, 0.003)}, None),
    ("magnetometer latency 5 ms", {"mag.latency_s": 0.005}, None),
    ("magnetometer latency 10 ms", {"mag.latency_s": 0.010}, None),
    ("motor-current interference 0", {"mag.motor_coef": (0.0, 0.0, 0.0)}, None),
    ("motor-current interference 3x", {"mag.motor_coef": (2.4, -1.2, 4.5)}, None),
    ("indoor field distortion 10 µT", {"environment.distortion_ut": 10.0}, None),
    ("IMU lever arm 0", {"acc.lever_arm": (0.0, 0.0, 0.0)}, None),
    ("no vibration", {"acc.vibration_amp": (0.0, 0.0, 0.0)}, None),
    ("damaged propeller on rotor 2 (5e-6 kg m)", {}, (0.0, 0.0, 5e-6, 0.0)),
]
"""One row each: a label, the sensor preset's parameters it changes (``--set`` names), and a
propeller imbalance per rotor from the loss on (or None). The baseline's values: gyroscope range
±1000°/s, scale error drawn per run (σ 0.3 %), no magnetometer latency (5 ms rounds to 4 ms at
the 500 Hz IMU rate, the loop's and the batch model's step), motor-current interference
(0.8, −0.4, 1.5) µT at full current, the earth's field alone, lever arm (15, −10, 5) mm,
blade-pass vibration 0.25 m/s² per axis, sound propellers."""


def ablation_seed(task) -> dict:
    """One seed of the ablations (a picklable task ``(seed, params, filter params, rows)``):
    the damaged-rotor flight once, sampled again for every row."""
    seed, p, fparams, rows = task
    flight = flown_flight("damaged-rotor", seed, p)
    if flight.summary["status"] != "survived":
        raise ValueError(f"the flown damaged-rotor (seed {seed}) did not survive: {flight.summary['reason']}")
    base = build_config(p.preset)
    out = {}
    for label, overrides, imbalance in rows:
        rec = resample(flight, base.with_overrides(overrides) if overrides else base, imbalance=imbalance)
        out[label] = score_filters(rec, fparams, p.failure_s)
    return out


def ablation_rows(per_seed: list[dict]) -> list[dict]:
    """Per row and filter: the roll, pitch and yaw RMS (degrees), mean over the seeds."""
    rows = []
    for label in per_seed[0]:
        row = {"change": label}
        for f in LABELS:
            row[f] = {a: float(np.mean([s[label][f]["rms_deg"][a] for s in per_seed])) for a in AXES}
        rows.append(row)
    return rows


def format_ablations(rows: list[dict]) -> str:
    """The ablation table: one line per change, roll / pitch / yaw RMS per filter."""
    names = LABELS
    w = max(len(r["change"]) for r in rows) + 2
    lines = ["roll / pitch / yaw RMS error from the loss on [deg], mean over seeds; each row changes one thing",
             f"{'change':<{w}}" + "".join(f"{n:>22}" for n in names)]
    for r in rows:
        lines.append(f"{r['change']:<{w}}" + "".join(
            f"{r[n]['roll']:>8.1f}{r[n]['pitch']:>7.1f}{r[n]['yaw']:>7.1f}" for n in names))
    return "\n".join(lines)
