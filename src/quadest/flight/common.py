"""What the flights share: their parameters, the record of a flown run, the position fusion's
gain, the sensors' draws and the error measures of the summaries."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import solve_discrete_are

from quadest.data.recording import Recording
from quadest.records import check, describe, param
from quadest.rotation import quat_conj, quat_mul, quat_rotate
from quadest.sim import sensors as S
from quadest.sim.inloop import sensor_model
from quadest.sim.simulator import draw_processes

SIM_RATE_HZ = 1000.0


@dataclass(frozen=True)
class FlightParams:
    """What a flight assumes beyond the vehicle, its sensors and its controllers."""

    mocap_rate_hz: float = param(100.0, "Hz", "position sensor rate",
                                 "chosen: a motion-capture system (Vicon/OptiTrack class, 100-300 Hz)",
                                 bounds="(0, 1000]")
    mocap_noise_m: float = param(1e-3, "m", "position sensor white noise per axis",
                                 "chosen: motion capture, millimetre noise", bounds="[0, 10]")
    mocap_latency_s: float = param(0.01, "s", "position sensor latency",
                                   "chosen: motion capture over a radio link, about 10 ms", bounds="[0, 1]")
    fusion_acc_std: float = param(0.5, "m/s²", "acceleration noise the position fusion assumes",
                                  "chosen: accelerometer noise plus what a degree of attitude error makes of g",
                                  bounds="(0, 100]")
    height_m: float = param(3.0, "m", "height of the hover point above the ground",
                            "chosen: room for the fall a rotor loss causes before control is regained",
                            bounds="(0, 1e3]")
    detect_delay_s: float = param(0.05, "s", "a rotor loss is known to the controller this long after it "
                                  "happens (known at t + delay, not detected from measurements)",
                                  "chosen: the order of the detection delays reported for rotor failures",
                                  bounds="[0, 10]")
    settle_m: float = param(0.3, "m", "a run has settled once its position error stays below this",
                            "chosen: a relaxed hover circles a few centimetres; a drifting one does not",
                            bounds="(0, 100]")

    def __post_init__(self):
        check(self, "flight")

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


def position_gain(p: FlightParams, imu_rate_hz: float) -> np.ndarray:
    """Steady-state Kalman gain ``[k_p, k_v]`` of a constant-velocity model driven by white
    acceleration (std ``fusion_acc_std`` per IMU sample) and corrected by the position sensor
    (std ``mocap_noise_m``) every ``1/mocap_rate_hz``."""
    T = 1.0 / p.mocap_rate_hz
    Fm = np.array([[1.0, T], [0.0, 1.0]])
    # acceleration noise integrated over T: std per IMU sample, white at that rate
    q = p.fusion_acc_std ** 2 / imu_rate_hz
    Q = q * np.array([[T ** 3 / 3, T ** 2 / 2], [T ** 2 / 2, T]])
    H = np.array([[1.0, 0.0]])
    R = np.array([[max(p.mocap_noise_m, 1e-6) ** 2]])
    P = solve_discrete_are(Fm.T, H.T, Q, R)
    K = P @ H.T / (H @ P @ H.T + R)
    return K[:, 0].copy()


def sensors_for(cfg, n: int, seed: int):
    """One run's sensor draws for ``n`` IMU samples (the generators and order of
    :func:`quadest.sim.flown.flown_recording`) and the compiled sampler's record."""
    rate = cfg.imu.rate_hz
    t = np.arange(n) / rate
    rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(int(seed)).spawn(4)]
    has_mag = S.mag_rows(np.arange(n), rate, cfg.mag.rate_hz)
    processes = draw_processes(cfg, t, has_mag, rngs)
    return processes, sensor_model(cfg, processes, has_mag)


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


def rms(v):
    return float(np.sqrt(np.mean(np.square(v)))) if len(v) else None


