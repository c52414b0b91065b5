"""What the flights share: their parameters, the record of a flown run, the position fusion's
gain, the sensors' draws and the error measures of the summaries."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import solve_discrete_are

from quadest.data.recording import Recording
from quadest.flight.rate import CLIP_RATE_MODES
from quadest.records import check, check_triples, describe, param
from quadest.recovery.divergence import CHECKS
from quadest.rotation import quat_conj, quat_mul, quat_rotate
from quadest.sim import sensors
from quadest.sim.flown import flown_recording
from quadest.sim.sensors import sensor_model
from quadest.sim.simulator import draw_processes
from quadest.sim.wind import WindParams

SIM_RATE_HZ = 1000.0
COLLISIONS = ("none", "drawn", "reset", "left")
"""A flight's collision (FlightParams.collision)."""


@dataclass(frozen=True)
class FlightParams:
    """What a flight assumes beyond the vehicle, its sensors and its controllers."""

    mocap_rate_hz: float = param(
        100.0,
        "Hz",
        "position sensor rate",
        "chosen: a motion-capture system (Vicon/OptiTrack class, 100-300 Hz)",
        bounds="(0, 1000]",
    )
    mocap_noise_m: float = param(
        1e-3, "m", "position sensor white noise per axis", "chosen: motion capture, millimetre noise", bounds="[0, 10]"
    )
    mocap_latency_s: float = param(
        0.01, "s", "position sensor latency", "chosen: motion capture over a radio link, about 10 ms", bounds="[0, 1]"
    )
    position_sensor: str = param("mocap", "-", "the position sensor the loop reads: mocap or gnss", "chosen")
    gnss_rate_hz: float = param(
        5.0, "Hz", "GNSS-like position sensor rate", "chosen: a u-blox M8-class receiver", bounds="(0, 1000]"
    )
    gnss_noise_m: tuple = param(
        (0.5, 0.5, 1.0),
        "m",
        "GNSS-like position white noise (north, east, down)",
        "chosen: a single receiver without corrections, vertical worse than horizontal",
    )
    gnss_latency_s: float = param(
        0.1, "s", "GNSS-like position latency", "chosen: a receiver's fix delay", bounds="[0, 1]"
    )
    gnss_fusion_acc_std: float = param(
        5.0,
        "m/s²",
        "acceleration noise the position fusion assumes with the GNSS-like sensor",
        "tuned in simulation (hover, seed 4; 0.5, 2, 5, 10 tried): "
        "over 0.2 s between fixes the accelerometer's error is mostly bias and "
        "attitude error, which a white model underrates; at 0.5 the estimate "
        "drifts 3 m RMS",
        bounds="(0, 100]",
    )
    baro_rate_hz: float = param(
        50.0,
        "Hz",
        "barometer rate (sampled in the loop; a throw's nominal EKF reads it)",
        "chosen: an MS5611-class sensor",
        bounds="(0, 1000]",
    )
    baro_noise_m: float = param(
        0.1, "m", "barometer altitude white noise", "chosen: an MS5611-class sensor, about 10 cm RMS", bounds="[0, 100]"
    )
    baro_tau_s: float = param(
        0.05, "s", "barometer lag (first order)", "chosen: the sensor's and its filter's", bounds="[0, 10]"
    )
    fusion_acc_std: float = param(
        0.5,
        "m/s²",
        "acceleration noise the position fusion assumes (motion capture)",
        "chosen: accelerometer noise plus what a degree of attitude error makes of g",
        bounds="(0, 100]",
    )
    height_m: float = param(
        3.0,
        "m",
        "height of the hover point above the ground",
        "chosen: room for the fall a rotor loss causes before control is regained",
        bounds="(0, 1e3]",
    )
    detect_delay_s: float = param(
        0.05,
        "s",
        "detection oracle: a rotor loss is known to the controller this long after it "
        "happens (known at t + delay, not detected from measurements)",
        "chosen: the order of the detection delays reported for rotor failures",
        bounds="[0, 10]",
    )
    speed_noise: float = param(
        0.01,
        "-",
        "relative noise of each rotor speed reading (ESC telemetry) the detector reads",
        "chosen: eRPM telemetry resolves about 1 % at hover speed",
        bounds="[0, 1]",
    )
    detector_model_error: float = param(
        0.1,
        "-",
        "the detector's model of the vehicle: mass, each moment of inertia and the thrust "
        "coefficient each off by a factor drawn uniformly within ±this per flight",
        "chosen: a vehicle weighed and its propellers measured within 10 %",
        bounds="[0, 0.9]",
    )
    detector_imu_error: float = param(
        0.005,
        "m",
        "the IMU's position from the centre of mass the detector is given (an autopilot's INS_POS / "
        "EKF2_IMU_POS): the sensors' lever arm, each axis off by a distance drawn uniformly within ±this per flight",
        "chosen: the centre of mass found by balancing the vehicle and the IMU's place on the board each within "
        "a few millimetres; flown at 0-20 mm (robust in the loop, rotor speeds): no alarm within 10 mm, 2 in 1,000 "
        "disturbed starts at 20 mm (docs/detection.md)",
        bounds="[0, 0.1]",
    )
    clip_rate: str = param(
        "commands",
        "-",
        "the rate the controller reads on a clipped gyroscope axis: predicted by the vehicle model "
        "(quadest.detect.rate) with the rotor commands through its motor (commands) or with the "
        "measured rotor speeds (rotor-speeds), or the clipped reading (off); axes within range "
        "read the gyroscope",
        "chosen: a clipped reading is no rate; the commands are known on every vehicle",
    )
    clip_rate_estimator: bool = param(
        True,
        "-",
        "the estimator in the loop reads the predicted rate on a clipped axis too (else the clipped reading)",
        "measured on rotor losses with a ±500 °/s gyro, seeds 100-104: robust stayed up in 5 of 5 with it, "
        "0 of 5 without (docs/vehicle.md, A clipped gyroscope)",
    )
    estimator_start_s: float = param(
        5.0,
        "s",
        "the estimator in the loop (one made by name) starts as a flying vehicle's is: fed this long of "
        "its sensors' readings at rest at the vehicle's start attitude (their biases, scale and "
        "misalignment; no noise) before the first sample, an oracle of the start; 0: from the "
        "flight's first samples, which in flight take thrust and drag for gravity",
        "measured on training seeds: from the first samples robust kept 709 of 750 hover losses up, "
        "converged 750 as the truth (docs/campaign.md, The estimator's start); 5 s outlasts robust's initial "
        "averaging (tau_acc, 4 s)",
        bounds="[0, 60]",
    )
    collision: str = param(
        "none",
        "-",
        "a collision in flight (quadest.flight.collision), drawn from the seed: none, drawn (the "
        "estimator's state reset to nonsense or left to diverge, as drawn), reset or left",
        "chosen: none by default",
    )
    divergence: str = param(
        "auto",
        "-",
        "the divergence checks that start a recovery in flight (quadest.recovery.divergence): auto "
        "(all with a collision, none without), off, or those that run, comma-separated (impact, "
        "rate, innovation, nonfinite)",
        "chosen: on where a collision is flown",
    )
    wind: WindParams | None = param(
        None,
        "-",
        "the wind the flown vehicle meets (quadest.sim.wind.WindParams; none: still air), unknown to the loop",
        "chosen: still air unless asked",
    )
    landing_m_s: float = param(
        0.0,
        "m/s",
        "the flight ends with a hard landing: the reference stops and descends at this speed onto the ground "
        "height_m below and on, touching down about 1 s before the end, the vehicle on sprung legs (0: none)",
        "chosen: none unless asked; 1-2 m/s is a hard landing",
        bounds="[0, 10]",
    )
    landing_accel_m_s2: float = param(
        3.0,
        "m/s²",
        "the landing's reference first stops, then speeds its descent up to landing_m_s, changing its "
        "speed at most this fast and its acceleration at most 4 m/s³, or as fast as unwinds the flight's "
        "own acceleration within 0.5 s when that is more (0: at once, steps in speed that cut the thrust, in "
        "the descent to the controller's least)",
        "PX4's defaults: MPC_ACC_DOWN_MAX and MPC_ACC_HOR 3 m/s², MPC_JERK_AUTO 4 m/s³ (its trajectory "
        "generator's limits); the 0.5 s chosen (flight.landing.UNWIND_S)",
        bounds="[0, 100]",
    )
    land_detector: bool = param(
        True,
        "-",
        "after a landing's touchdown the autopilot's land detector turns the thrust off: horizontal once "
        "a ground contact holds 0.35 s, all of it once maybe landed 0.25 s later (false: the controller "
        "flies the descending reference to the end)",
        "PX4's multicopter land detector and position controller, their defaults (flight.landing)",
    )
    settle_m: float = param(
        0.3,
        "m",
        "a run has settled once its position error stays below this",
        "chosen: a relaxed hover circles a few centimetres; a drifting one does not",
        bounds="(0, 100]",
    )

    def __post_init__(self):
        check(self, "flight")
        if self.collision not in COLLISIONS:
            raise ValueError(f"flight: collision must be one of {', '.join(COLLISIONS)}, got {self.collision!r}")
        checks = [c.strip() for c in self.divergence.split(",")]
        if self.divergence not in ("auto", "off") and not all(c in CHECKS for c in checks):
            raise ValueError(
                f"flight: divergence must be auto, off or checks of {', '.join(CHECKS)}, got {self.divergence!r}"
            )
        if self.position_sensor not in ("mocap", "gnss"):
            raise ValueError(f"flight: position_sensor must be mocap or gnss, got {self.position_sensor!r}")
        check_triples(self, "flight", "gnss_noise_m")
        if self.clip_rate not in CLIP_RATE_MODES:
            raise ValueError(f"flight: clip_rate must be one of {', '.join(CLIP_RATE_MODES)}, got {self.clip_rate!r}")

    def position(self) -> tuple[float, np.ndarray, float, float]:
        """The position sensor the loop reads: rate (Hz), white noise per axis (m), latency (s),
        and the acceleration noise the fusion assumes with it (m/s²)."""
        if self.position_sensor == "gnss":
            return (
                self.gnss_rate_hz,
                np.asarray(self.gnss_noise_m, float),
                self.gnss_latency_s,
                self.gnss_fusion_acc_std,
            )
        return self.mocap_rate_hz, np.full(3, self.mocap_noise_m), self.mocap_latency_s, self.fusion_acc_std

    @classmethod
    def describe(cls) -> list[dict]:
        return describe(cls)


@dataclass
class Flight:
    """One flown run."""

    recording: Recording  # the rows flown
    states: np.ndarray  # true state at each row (13 + rotors)
    commands: np.ndarray  # rotor speed commands (rad/s)
    q_est: np.ndarray  # the attitude the controller read (geographic NED)
    pv_est: np.ndarray  # the position and velocity it read
    summary: dict = field(default_factory=dict)
    timing: dict = field(default_factory=dict)  # wall time of the compiled loop (its first call compiles)
    baro: np.ndarray | None = None  # barometric altitude (m, up), NaN between samples
    modes: np.ndarray | None = None  # a throw's recovery state per sample (flight.throw.MODES)
    derivs: np.ndarray | None = None  # the true state's derivative at each row (its accelerations)
    thrusts: np.ndarray | None = None  # each rotor's thrust at each row (N)
    eta: np.ndarray | None = None  # each rotor's efficiency at each row
    imbalance: np.ndarray | None = None  # each propeller's imbalance at each row (kg m)
    vehicle: object = None  # the MultirotorParams flown
    effectiveness: np.ndarray | None = None  # with a detector in the loop: each rotor's effectiveness it estimates
    detector_statistics: np.ndarray | None = None  # and its tests' statistics (detect.layout.DIAGNOSTICS)
    rate_est: np.ndarray | None = None  # the body rate the controller read (rad/s; NaN where none did)


def position_gain(p: FlightParams, imu_rate_hz: float) -> np.ndarray:
    """Per axis, the steady-state Kalman gain ``[k_p, k_v]`` (a 3x2 array) of a constant-velocity
    model driven by white acceleration (std per IMU sample) and corrected by the position sensor
    (:meth:`FlightParams.position`) at its rate."""
    rate, noise, _, acc_std = p.position()
    T = 1.0 / rate
    Fm = np.array([[1.0, T], [0.0, 1.0]])
    # acceleration noise integrated over T: std per IMU sample, white at that rate
    q = acc_std**2 / imu_rate_hz
    Q = q * np.array([[T**3 / 3, T**2 / 2], [T**2 / 2, T]])
    H = np.array([[1.0, 0.0]])
    gains = np.empty((3, 2))
    for axis in range(3):
        R = np.array([[max(noise[axis], 1e-6) ** 2]])
        P = solve_discrete_are(Fm.T, H.T, Q, R)
        gains[axis] = (P @ H.T / (H @ P @ H.T + R))[:, 0]
    return gains


def barometer_draws(t, p: FlightParams, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """The barometer the loop samples (:func:`quadest.flight.loop.sense`) at the times ``t``:
    per sample the first-order lag's coefficient ``exp(−Δt/baro_tau_s)`` (1 at the first
    sample) and the white noise of a reading at ``p.baro_rate_hz`` (NaN between readings),
    from its own generator. The loop reads the true height through the lag plus that noise."""
    t = np.asarray(t, float)
    out = np.full(len(t), np.nan)
    dt = np.diff(t, prepend=t[0]) if len(t) else np.zeros(0)
    a = np.exp(-dt / p.baro_tau_s) if p.baro_tau_s > 0 else np.zeros(len(t))
    rows = np.flatnonzero(np.diff(np.floor((t - t[0]) * p.baro_rate_hz + 1e-9), prepend=-1.0) > 0) if len(t) else []
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 16]))
    out[rows] = rng.normal(0.0, p.baro_noise_m, len(rows))
    return a, out


def sensors_for(cfg, n: int, seed: int, vehicle):
    """One run's sensor draws for ``n`` IMU samples of the flown ``vehicle`` (the generators
    and order of :func:`quadest.sim.flown.flown_recording`) and the compiled sampler's record."""
    rate = cfg.imu.rate_hz
    t = np.arange(n) / rate
    rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(int(seed)).spawn(4)]
    has_mag = sensors.mag_rows(np.arange(n), rate, cfg.mag.rate_hz)
    processes = draw_processes(cfg, t, has_mag, rngs, rotors=vehicle.rotors)
    return processes, sensor_model(cfg, processes, has_mag, vehicle)


def angle_errors(q_true, q_est):
    """Rotation angle between two attitudes (deg) and the tilt error: the angle between the
    true and the estimated down direction in the body."""
    dq = quat_mul(quat_conj(q_true), q_est)
    total = np.degrees(2 * np.arccos(np.clip(np.abs(dq[:, 0]), 0.0, 1.0)))
    ez = np.array([0.0, 0.0, 1.0])
    g_true = quat_rotate(quat_conj(q_true), ez)
    g_est = quat_rotate(quat_conj(q_est), ez)
    tilt = np.degrees(np.arccos(np.clip((g_true * g_est).sum(axis=1), -1.0, 1.0)))
    return total, tilt


def mean_present(values):
    """The mean of the values that are not None (None when there are none)."""
    values = [v for v in values if v is not None]
    return float(np.mean(values)) if values else None


def rms(v):
    return float(np.sqrt(np.mean(np.square(v)))) if len(v) else None


def flight_of(out: dict, t, vehicle, *, cfg, seed, meta, processes, loop_s, imbalance, modes=None) -> Flight:
    """The :class:`Flight` of a closed loop's record ``out`` (``flight.loop.flown_arrays``) at the
    IMU instants ``t``: its recording sampled as every simulation samples, with the loop's
    readings; ``imbalance`` each propeller's per sample, ``modes`` a throw's phase per sample."""
    rec = flown_recording(
        t,
        out["x"],
        out["dx"],
        out["thrust"],
        vehicle,
        cfg=cfg,
        seed=seed,
        eta=out["eta"],
        imbalance=imbalance,
        meta=meta,
        readings=(out["gyr"], out["acc"], out["mag"]),
        processes=processes,
    )
    return Flight(
        rec,
        out["x"],
        out["cmd"],
        out["q"],
        out["pv"],
        timing={"loop_s": loop_s},
        baro=out["baro"],
        modes=modes,
        derivs=out["dx"],
        thrusts=out["thrust"],
        eta=out["eta"],
        imbalance=imbalance,
        vehicle=vehicle,
        rate_est=out.get("rate"),
    )
