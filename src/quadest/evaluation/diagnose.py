"""A recorded flight's motors diagnosed (docs/diagnose.md): rotor failures found by quadest's
detector run at the log's own rates on a vehicle model built from the log, and each motor's
share of the thrust against the others (a damaged propeller makes its motor work harder)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from quadest.detect import Detector, DetectorParams
from quadest.models.multirotor import MultirotorParams
from quadest.readers.motors import ARDUPILOT_FRAMES, MotorLog, frame_geometry, logged_failure, read_motor_log, runs

OMEGA_REF = 1000.0
"""The equivalent rotor speed of full thrust: a log has outputs, not speeds; the detector is
given ``OMEGA_REF √(thrust fraction)``, whose square is what thrust needs."""


@dataclass(frozen=True)
class DiagnoseParams:
    """What the diagnosis assumes where a log says nothing (docs/diagnose.md has the sources)."""

    moment_gain: float = 10.0
    """Roll and pitch angular acceleration per unit of one motor's thrust fraction on a unit arm
    (rad/s²): not identifiable from outputs logged at 10 Hz; chosen on the two SITL losses
    (in-sample: 2.5-20 work on motor 1's, 10-20 on motor 2's; docs/diagnose.md)."""
    yaw_ratio: float = 0.07
    """Yaw acceleration per unit of reaction torque relative to roll's: k_m/k_f ≈ 0.14 arm and
    I_zz ≈ 2 I_xx, typical of small quadrotors."""
    deficit_sigmas: float = 3.0
    """The detector counts a rotor's deficit only beyond this many standard deviations."""
    eta_walk: float = 3.0
    """The effectiveness's random walk (1/√s): the in-flight detector's 1.5 "finds" the loss of
    motor 2 5.4 s before it happens (docs/diagnose.md; in-sample)."""
    noise_window_s: float = 0.0
    """0: the gyroscope's noise from the whole log (else over this window, as in flight)."""
    weighted_others: bool = False
    """A rotor's deficit against the others' effectiveness weighted by how well each is known (the
    in-flight setting) or their plain mean."""
    contact_margin: float = 0.0
    """The in-flight detector's contact gate (m/s²; 0: none): the log is cut to its flying spans."""
    glr: bool = False
    """The in-flight detector's fast test: off, its model of a window's rate change needs the
    rotors' outputs at the IMU's rate, which logs hold at 10-50 Hz."""
    moment_scale_s: float = 0.0
    """The in-flight detector's moment learnt in flight (its memory, s; 0: off): a log's motor
    outputs at 10-50 Hz, mapped to speeds through a generic motor, leave its model's rate change
    coarse (docs/diagnose.md)."""
    settle_s: float = 2.0
    """Seconds after take-off before the detector starts (leaving the ground)."""
    before_landing_s: float = 1.5
    """Seconds before the landing the autopilot reports at which the detector stops (ground effect)."""
    excess_threshold: float = 0.15
    """A motor whose thrust exceeds the others' mean by more than this share is flagged:
    twice the largest excess of the intact flights in ../shared/data (0.07; in-sample)."""
    min_flight_s: float = 10.0
    """Flight time below which motor shares are not reported."""


@dataclass
class Diagnosis:
    """What :func:`diagnose_log` found: failures (time in the log's own base, motor in the
    autopilot's numbering, effectiveness left), damaged motors, each motor's share, notes."""

    log: MotorLog
    failures: list[dict]
    damaged: list[dict]
    motors: list[dict]
    model: dict
    notes: list[str] = field(default_factory=list)

    def as_json(self) -> dict:
        return {
            "file": self.log.path,
            "autopilot": self.log.autopilot,
            "frame": self.log.frame,
            "imu_rate_hz": round(self.log.imu_rate, 1),
            "output_rate_hz": round(self.log.output_rate, 1),
            "flying": [[a, None if not np.isfinite(b) else b] for a, b in self.log.flying],
            "failures": self.failures,
            "damaged": self.damaged,
            "motors": self.motors,
            "model": self.model,
            "parameter_changes": [{"time_s": t, "name": n, "value": v} for t, n, v in self.log.changes],
            "notes": self.notes,
        }

    def for_report(self) -> dict:
        """What the report page draws: the findings (:meth:`as_json`) and each motor's output
        over time as a fraction of its full thrust, in the log's own time."""
        return {"json": self.as_json(), "t_out": self.log.t_out, "thrust": self.log.thrust, "motors": self.log.motors}


def flying_mask(t, spans, settle=0.0, before_landing=0.0) -> np.ndarray:
    """Samples inside the flying spans, ``settle`` s after each take-off and ``before_landing`` s
    before each landing."""
    mask = np.zeros(len(t), bool)
    for a, b in spans:
        mask |= (t >= a + settle) & (t <= b - before_landing)
    return mask


def held(t, t_out, values) -> tuple[np.ndarray, np.ndarray]:
    """Each output as last logged at the times ``t`` (the log's zero-order hold: nothing from
    the future), and whether one had been logged yet."""
    k = np.searchsorted(t_out, t, side="right") - 1
    return values[np.clip(k, 0, None)], k >= 0


def motor_shares(log: MotorLog, params: DiagnoseParams = DiagnoseParams()) -> list[dict]:
    """Each motor's median output and thrust over the flight against the mean of the others."""
    fly = flying_mask(log.t_out, log.flying, params.settle_s, params.before_landing_s)
    if not fly.any():
        return [{"motor": m, "output": None, "output_excess": None, "excess": None} for m in log.motors]
    out, thrust = log.outputs[fly], log.thrust[fly]
    rows = []
    for k, motor in enumerate(log.motors):
        others = np.delete(np.arange(len(log.motors)), k)
        ratio = thrust[:, k] / np.maximum(thrust[:, others].mean(axis=1), 1e-6)
        rows.append(
            {
                "motor": motor,
                "output": float(np.median(out[:, k])),
                "output_excess": float(np.median(out[:, k] - out[:, others].mean(axis=1))),
                "excess": float(np.median(ratio) - 1.0),
            }
        )
    return rows


def thrust_per_mass(log: MotorLog, mask_out) -> float:
    """Full thrust of one motor over the mass (m/s²): the accelerometer's z against the summed
    thrust fractions in flight, ``f_z = −(T/m) Σ thrust_i``, as a median ratio."""
    az = np.interp(log.t_out[mask_out], log.t, log.acc[:, 2])
    total = log.thrust[mask_out].sum(axis=1)
    ok = total > 0.05
    return float(np.median(-az[ok] / total[ok])) if ok.any() else float("nan")


def log_vehicle(log: MotorLog, t_over_m: float, params: DiagnoseParams) -> MultirotorParams:
    """The detector's model of a logged vehicle: unit mass and arm, the log's frame and senses,
    full thrust ``t_over_m`` per motor, inertias from the moment gains (docs/diagnose.md)."""
    k_f = t_over_m / OMEGA_REF**2
    i_xy = t_over_m / params.moment_gain
    return MultirotorParams(
        mass_kg=1.0,
        inertia=(i_xy, i_xy, t_over_m / (params.moment_gain * params.yaw_ratio)),
        rotor_pos=tuple((float(x), float(y), 0.0) for x, y in log.positions),
        spin=tuple(float(s) for s in log.spin),
        k_f=k_f,
        k_m=k_f,
        k_z=0.0,
        k_h=0.0,
        omega_min=0.0,
        omega_max=OMEGA_REF,
        rot_drag=(0.0, 0.0, 0.0),
    )


def robust_sd(x) -> float:
    """Standard deviation from the median absolute deviation (what outliers leave alone)."""
    x = np.asarray(x, float)
    return float(1.4826 * np.median(np.abs(x - np.median(x, axis=0))))


def find_failures(log: MotorLog, vehicle: MultirotorParams, params: DiagnoseParams) -> tuple[list[dict], dict]:
    """The detector over each flying span of the log (module doc); its noise levels from the
    log's own gyroscope and accelerometer."""
    mask = flying_mask(log.t, log.flying, params.settle_s, params.before_landing_s)
    rotors, logged = held(log.t, log.t_out, log.thrust)
    mask &= logged
    if mask.sum() < 10:
        return [], {}
    dt = np.diff(log.t[mask])
    gyro_noise = max(robust_sd(np.diff(log.gyr[mask], axis=0)) / np.sqrt(2.0), 1e-3)
    noise = {
        "gyro_noise": float(gyro_noise),
        "acc_noise": float(max(robust_sd(np.diff(log.acc[mask, 2])) / np.sqrt(2.0), 0.01)),
        "moment_noise": max(robust_sd(np.diff(log.gyr[mask], axis=0) / dt[:, None]), 0.1),
    }
    detector_params = DetectorParams(
        deficit_sigmas=params.deficit_sigmas,
        eta_walk=params.eta_walk,
        noise_window_s=params.noise_window_s,
        weighted_others=params.weighted_others,
        contact_margin=params.contact_margin,
        glr=params.glr,
        moment_scale_s=params.moment_scale_s,
        **noise,
    )
    failures = []
    for start, end in runs(mask, shortest=11):
        det = Detector(vehicle, detector_params, imu_position=log.imu_position)
        sl = slice(start, end)
        found = det.run(log.t[sl], log.gyr[sl], log.acc[sl], OMEGA_REF * np.sqrt(rotors[sl]))
        if found.lost is not None:
            failures.append(
                {
                    "time_s": round(float(log.t[start] + found.lost_t), 4),
                    "motor": log.motors[found.lost],
                    "effectiveness": round(float(np.clip(found.lost_effectiveness, 0.0, 1.0)), 3),
                }
            )
    return failures, noise


def diagnose_log(path, params: DiagnoseParams | None = None) -> Diagnosis:
    """Read a log (ArduPilot DataFlash or PX4 ULog) and diagnose its motors (module doc)."""
    return diagnose(read_motor_log(path), params)


def diagnose(log: MotorLog, params: DiagnoseParams | None = None) -> Diagnosis:
    """A log already read (:func:`~quadest.readers.motors.read_motor_log`) diagnosed."""
    params = params or DiagnoseParams()
    notes = list(log.notes)
    fly_out = flying_mask(log.t_out, log.flying, params.settle_s, params.before_landing_s)
    if fly_out.sum() < 3:
        notes.append("the vehicle did not fly in this log (no take-off, or too short): nothing to diagnose")
        return Diagnosis(log, [], [], motor_shares(log, params), {}, notes)
    t_over_m = thrust_per_mass(log, fly_out)
    if not (np.isfinite(t_over_m) and t_over_m > 0):  # the model's k_f from it would be refused
        raise ValueError(
            f"{log.path}: in flight the motors' outputs give no thrust that lifts the vehicle against "
            f"its accelerometer (thrust over mass {t_over_m:g}): are the log's motor and thrust parameters "
            "(SERVOn_FUNCTION, MOT_*; PX4: CA_*, PWM_*) those of the vehicle?"
        )
    vehicle = log_vehicle(log, t_over_m, params)
    failures, noise = find_failures(log, vehicle, params)
    shares = motor_shares(log, params)
    flown = float(np.ptp(log.t_out[fly_out]))
    damaged = []
    if flown < params.min_flight_s:
        notes.append(f"{flown:.0f} s of flight: too short for motor shares (at least {params.min_flight_s:.0f} s)")
    elif not failures:
        damaged = [
            {"motor": r["motor"], "excess": round(r["excess"], 3)}
            for r in shares
            if r["excess"] > params.excess_threshold
        ]
    notes += _rate_notes(log)
    model = {"thrust_per_mass": round(t_over_m, 3), "moment_gain": params.moment_gain, "yaw_ratio": params.yaw_ratio}
    model.update({k: round(v, 4) for k, v in noise.items()})
    return Diagnosis(log, failures, damaged, shares, model, notes)


def _rate_notes(log: MotorLog) -> list[str]:
    notes = []
    if log.output_rate < 50.0:
        notes.append(
            f"motor outputs logged at {log.output_rate:.0f} Hz: a failure's time is known to within "
            f"{1e3 / max(log.imu_rate, 1e-9):.0f} ms (the IMU's interval), its effectiveness only roughly"
        )
    if log.imu_rate < 100.0:
        notes.append(f"IMU logged at {log.imu_rate:.0f} Hz: too low for the in-flight detection-delay figures")
    return notes


def format_diagnosis(d: Diagnosis) -> str:
    """The diagnosis as text: the log's rates, failures, motors and notes."""
    log = d.log
    lines = [
        f"{log.path}: {log.autopilot}, {log.frame}, IMU {log.imu_rate:.0f} Hz, motor outputs {log.output_rate:.0f} Hz",
        "flying: " + ", ".join(_span(a, b) for a, b in log.flying) if log.flying else "flying: never",
    ]
    for t, name, value in log.changes:
        lines.append(f"parameter change at {t:.3f} s: {name} = {value:g}")
    if d.failures:
        for f in d.failures:
            lines.append(
                f"FAILURE: motor {f['motor']} lost at {f['time_s']:.3f} s (effectiveness left {f['effectiveness']:.2f})"
            )
    else:
        lines.append("no rotor failure found")
    unit = "us" if log.output_unit == "us" else ""
    shown = [r for r in d.motors if r["output"] is not None]  # None: no flight to take shares from
    if shown:
        lines.append("motor  output  vs others  thrust vs others")
    for r in shown:
        flag = (
            "  <- works harder than intact vehicles spread" if any(x["motor"] == r["motor"] for x in d.damaged) else ""
        )
        lines.append(
            f"{r['motor']:5d}  {r['output']:6.0f}  {r['output_excess']:+7.1f}{unit}  {100 * r['excess']:+6.1f} %{flag}"
        )
    lines += [f"note: {n}" for n in d.notes]
    return "\n".join(lines)


def _span(start: float, end: float) -> str:
    """A flying span as text; a span with no landing logged runs to the log's end."""
    if np.isfinite(end):
        return f"{start:.1f}-{end:.1f} s"
    return f"from {start:.1f} s to the end of the log (no landing logged)"


IN_FLIGHT = {
    "eta_walk": "effectiveness walk",
    "noise_window_s": "gyroscope noise window",
    "weighted_others": "deficit against the better-known rotors",
    "contact_margin": "contact gate",
    "glr": "fast test",
    "moment_scale_s": "learnt moment",
}
"""The detector's settings the log mode sets apart from the in-flight detector's defaults."""

SWEEP = {
    "default": {},
    **{f"moment gain {g:g}": {"moment_gain": g} for g in (2.5, 5.0, 20.0, 40.0)},
    **{f"yaw ratio {r:g}": {"yaw_ratio": r} for r in (0.035, 0.14)},
    "no significance test": {"deficit_sigmas": 0.0},
    **{f"in flight's {label}": {k: getattr(DetectorParams(), k)} for k, label in IN_FLIGHT.items()},
    "the in-flight detector": {k: getattr(DetectorParams(), k) for k in IN_FLIGHT},
}
"""The variants :func:`benchmark_diagnose` runs: the default, the chosen values across their
range, the log mode's significance test taken away, and each setting the log mode keeps apart from
the in-flight detector set to the in-flight value, then all of them (docs/diagnose.md)."""


def score(d: Diagnosis, truth: tuple[float, int] | None) -> dict:
    """A diagnosis against the log's failure (time, motor; None for a flight without one)."""
    out = {"failures": d.failures, "damaged": d.damaged}
    if truth is None:
        return out | {"false_failures": len(d.failures)}
    first = d.failures[0] if d.failures else None
    return out | {
        "delay_s": None if first is None else round(first["time_s"] - truth[0], 4),
        "named": first is not None and first["motor"] == truth[1],
    }


def benchmark_diagnose(paths, variants: dict | None = None, on_log=None) -> dict:
    """Every log diagnosed with every variant (:data:`SWEEP`), scored against the failure the
    log itself records (:func:`~quadest.readers.motors.logged_failure`: truth, never read by the
    diagnosis)."""
    variants = SWEEP if variants is None else variants
    logs = {}
    for path in paths:
        log = read_motor_log(path)
        truth = logged_failure(log)
        runs_ = {name: score(diagnose(log, DiagnoseParams(**kw)), truth) for name, kw in variants.items()}
        logs[log.path.rsplit("/", 1)[-1]] = {
            "truth": None if truth is None else {"time_s": truth[0], "motor": truth[1]},
            "imu_rate_hz": round(log.imu_rate, 1),
            "output_rate_hz": round(log.output_rate, 1),
            "motors": diagnose(log).motors,
            "variants": runs_,
        }
        if on_log:
            on_log(path, logs[log.path.rsplit("/", 1)[-1]])
    return {"variants": dict(variants), "logs": logs, "synthetic": synthetic_losses()}


def synthetic_loss_log(
    gyro_noise: float, loss_at: float | None = 20.0, seed: int = 0, duration: float = 30.0, gain_factor: float = 1.0
):
    """A hovering ArduPilot quad X logged at 25 Hz (IMU) and 10 Hz (outputs) that loses motor 1 at
    ``loss_at`` s (None: never), with white gyroscope noise. Its moment gains are the
    diagnosis's default times ``gain_factor``; its yaw ratio and thrust curve are the
    diagnosis's own. Rigid body, no controller: only the first instants after a loss mean anything."""
    p = DiagnoseParams()
    pos, spin = frame_geometry(ARDUPILOT_FRAMES[(1, 1)][1])
    hover, t_over_m, dt = 0.4, 9.81 / (4 * 0.4), 0.04
    gain = gain_factor * p.moment_gain * np.array([1.0, 1.0, p.yaw_ratio])
    t = np.arange(0.0, duration, dt)
    eta = np.ones((len(t), 4))
    if loss_at is not None:
        eta[t >= loss_at, 0] = 0.0
    g = np.column_stack([-pos[:, 1], pos[:, 0], -spin])
    w = np.cumsum((eta * hover) @ g * gain, axis=0) * dt
    rng = np.random.default_rng(seed)
    acc = np.zeros((len(t), 3))
    acc[:, 2] = -t_over_m * (eta * hover).sum(axis=1) + 0.05 * rng.standard_normal(len(t))
    t_out = np.arange(0.0, duration, 0.1)
    thrust = np.full((len(t_out), 4), hover)
    return MotorLog(
        "synthetic", "ArduPilot", t, w + gyro_noise * rng.standard_normal(w.shape), acc, t_out, 1000 + 1000 * thrust,
        [1, 2, 3, 4], "quad X", pos, spin, thrust, [(0.0, duration)], channels=[1, 2, 3, 4],
    )  # fmt: skip


def synthetic_losses(noises=(0.001, 0.05), gain_factors=(1.0, 8.0), seeds=range(5)) -> list[dict]:
    """The log mode on :func:`synthetic_loss_log`, with and without the deficit's significance
    test: what it finds (motor, seconds after the loss) in 5 flights with a loss of motor 1,
    and how many of 5 flights of 60 s without one raise a loss."""
    rows = []
    for factor in gain_factors:
        for noise in noises:
            for sigmas in (DiagnoseParams().deficit_sigmas, 0.0):
                params = DiagnoseParams(deficit_sigmas=sigmas)
                found = [
                    diagnose(synthetic_loss_log(noise, 20.0, s, gain_factor=factor), params).failures for s in seeds
                ]
                quiet = [diagnose(synthetic_loss_log(noise, None, s, 60.0, factor), params).failures for s in seeds]
                rows.append(
                    {
                        "gain_factor": factor,
                        "gyro_noise": noise,
                        "deficit_sigmas": sigmas,
                        "found": [[f[0]["motor"], round(f[0]["time_s"] - 20.0, 3)] if f else None for f in found],
                        "false_losses": sum(bool(q) for q in quiet),
                        "flights": len(quiet),
                    }
                )
    return rows
