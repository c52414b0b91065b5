"""Motor outputs from autopilot logs, for diagnosing the motors (docs/diagnose.md): the IMU, each
motor's output with the autopilot's numbering, the frame's geometry, the thrust curve, when the
vehicle flew, and the logged parameter changes. Times stay in the log's own time base."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from quadest.data.checks import runs
from quadest.extras import need
from quadest.readers.common import ReaderError, reason
from quadest.readers.logs import DF_HEAD, LOG_DAMAGE, _printed, open_dataflash
from quadest.readers.rotors import (
    ARDUPILOT_FRAMES,
    ardupilot_pwm_range,
    frame_geometry,
    motor_channels,
    pwm_share,
    px4_geometry,
    px4_pwm_range,
)

# ArduPilot's event ids (AP_Logger LogEvent): taken off, landing (maybe / complete), disarmed
EV_TAKEOFF, EV_LANDING = 28, (17, 18, 11)
STATISTICS = ("STAT_",)  # parameters ArduPilot updates itself (flight time): not changes of setting


@dataclass
class MotorLog:
    """What :func:`read_motor_log` reads: arrays in the log's own time (s), the outputs as the
    autopilot logged them (µs of PWM, or the normalised thrust PX4 logs in ``actuator_motors``)."""

    path: str
    autopilot: str
    t: np.ndarray
    gyr: np.ndarray
    acc: np.ndarray
    t_out: np.ndarray
    outputs: np.ndarray
    motors: list[int]
    frame: str
    positions: np.ndarray  # unit arm, body FRD (x forward, y right)
    spin: np.ndarray
    thrust: np.ndarray  # each output as a fraction of the motor's full thrust
    flying: list[tuple[float, float]]
    changes: list[tuple[float, str, float]] = field(default_factory=list)
    output_unit: str = "us"
    notes: list[str] = field(default_factory=list)
    channels: list[int] = field(default_factory=list)  # each motor's output channel (1-based)
    imu_position: tuple = (0.0, 0.0, 0.0)  # the IMU from the centre of mass, body FRD (m), as the log's parameters say

    @property
    def imu_rate(self) -> float:
        return _rate(self.t)

    @property
    def output_rate(self) -> float:
        return _rate(self.t_out)


def _rate(t) -> float:
    return float(1.0 / np.median(np.diff(t))) if len(t) > 2 else 0.0


def logged_failure(log: MotorLog) -> tuple[float, int] | None:
    """The first motor whose output was handed to something else in flight (ArduPilot: its
    ``SERVOn_FUNCTION`` changed away from the motor's), and when: how a failure is made in
    ArduPilot's simulator. *Truth for scoring a diagnosis*; the diagnosis never reads it."""
    for t, name, value in log.changes:
        m = re.fullmatch(r"SERVO(\d+)_FUNCTION", name)
        if m and int(m.group(1)) in log.channels and int(value) != 32 + log.channels.index(int(m.group(1))) + 1:
            return t, log.motors[log.channels.index(int(m.group(1)))]
    return None


def pwm_thrust(pwm, pwm_min, pwm_max, spin_min, spin_max, expo) -> np.ndarray:
    """ArduPilot's thrust curve inverted (AP_Motors_Thrust_Linearization): the output's fraction
    of the motor's full thrust, ``(1 − e) x + e x²`` with ``x`` the output between the spin
    limits (battery compensation left out)."""
    x = np.clip((pwm_share(pwm, pwm_min, pwm_max) - spin_min) / (spin_max - spin_min), 0.0, 1.0)
    return (1.0 - expo) * x + expo * x * x


MOTOR_LOG_SUFFIXES = (".bin", ".ulg")
"""The logs whose motors quadest reads: ArduPilot DataFlash and PX4 ULog."""


def read_motor_log(path: str | Path) -> MotorLog:
    """An ArduPilot DataFlash (.bin) or PX4 ULog (.ulg) log's motors (module doc)."""
    p = Path(path)
    if not p.exists():
        raise ReaderError(f"{path}: no such file")
    reader = _log_reader(p)
    try:
        return reader(p)
    except LOG_DAMAGE as exc:
        raise ReaderError(f"{path}: the log is damaged ({reason(exc)})") from None


def _log_reader(path: Path):
    """The reader of a log from its first bytes (a ULog's ``ULog``, a DataFlash log's ``A3 95``):
    any other file is refused at once, not walked byte by byte as a damaged DataFlash log."""
    try:
        with open(path, "rb") as f:
            head = f.read(4)
    except OSError as exc:
        raise ReaderError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    if head.startswith(b"ULog"):
        return _read_px4
    if head.startswith(DF_HEAD):
        return _read_ardupilot
    raise ReaderError(f"{path}: not an ArduPilot DataFlash (.bin) or PX4 ULog (.ulg) log; diagnose reads only those")


# -- ArduPilot ------------------------------------------------------------------------------------------
def _read_motor_messages(log, imu, rcou, events, params, changes) -> None:
    """The IMU (instance 0), motor output, event and parameter messages of a DataFlash log into
    the lists (``changes``: a parameter's later values, the statistics' apart)."""
    last = {}  # each parameter's latest value: a value logged again is not a change again
    while (m := log.recv_match(type=["IMU", "RCOU", "PARM", "EV"])) is not None:
        kind = m.get_type()
        if kind == "IMU" and getattr(m, "I", 0) == 0:
            imu.append((m.TimeUS, m.GyrX, m.GyrY, m.GyrZ, m.AccX, m.AccY, m.AccZ))
        elif kind == "RCOU":
            rcou.append([m.TimeUS] + [getattr(m, f"C{i}", 0) for i in range(1, 15)])
        elif kind == "EV":
            events.append((m.TimeUS * 1e-6, m.Id))
        elif kind == "PARM":
            if m.Name in last and last[m.Name] != m.Value and not m.Name.startswith(STATISTICS):
                changes.append((m.TimeUS * 1e-6, m.Name, float(m.Value)))
            params.setdefault(m.Name, float(m.Value))
            last[m.Name] = m.Value


def _read_ardupilot(path: Path) -> MotorLog:
    DFReader = need("pymavlink.DFReader", "reading an ArduPilot DataFlash log")

    imu, rcou, events, params, changes = [], [], [], {}, []
    with _printed():
        log = open_dataflash(DFReader, path)
        try:
            _read_motor_messages(log, imu, rcou, events, params, changes)
        except (ReaderError, *LOG_DAMAGE):
            raise
        except Exception as exc:  # pymavlink raises many kinds on bad files
            raise ReaderError(f"{path}: DataFlash log broken after {len(imu)} IMU messages ({reason(exc)})") from None
    if not imu or len(rcou) < 2:
        raise ReaderError(f"{path}: the log has no IMU or no RCOU (motor output) messages to diagnose")
    imu, rcou = np.array(imu, float), np.array(rcou, float)
    notes = []
    key = (int(params.get("FRAME_CLASS", 1)), int(params.get("FRAME_TYPE", 1)))
    if key not in ARDUPILOT_FRAMES:
        raise ReaderError(
            f"{path}: frame FRAME_CLASS={key[0]} FRAME_TYPE={key[1]} is not one quadest knows "
            f"(quad and hexa, plus and X)"
        )
    name, table = ARDUPILOT_FRAMES[key]
    channels = motor_channels(params, len(table), notes)
    pwm_min, pwm_max = ardupilot_pwm_range(params)
    outputs = rcou[:, [c for c in channels]]
    thrust = pwm_thrust(outputs, pwm_min, pwm_max, *_thrust_curve(params, path))
    t_out = rcou[:, 0] * 1e-6
    hover = params.get("MOT_THST_HOVER", 0.35)
    flying = _flying_from_events(events) or _flying_from_thrust(t_out, thrust, 0.5 * hover)
    if not _flying_from_events(events):
        notes.append("no take-off event in the log: flight taken as where the mean thrust exceeds half the hover's")
    positions, spin = frame_geometry(table)
    return MotorLog(
        str(path),
        "ArduPilot",
        imu[:, 0] * 1e-6,
        imu[:, 1:4],
        imu[:, 4:7],
        t_out,
        outputs,
        list(range(1, len(table) + 1)),
        name,
        positions,
        spin,
        thrust,
        flying,
        changes,
        "us",
        notes,
        channels,
        _imu_position(params, "INS_POS1_"),
    )


def _thrust_curve(params, path) -> tuple[float, float, float]:
    """``MOT_SPIN_MIN``, ``MOT_SPIN_MAX`` and ``MOT_THST_EXPO`` (ArduPilot's defaults where the
    log has none); ReaderError, in the log's terms, where they make no thrust curve."""
    spin_min, spin_max = params.get("MOT_SPIN_MIN", 0.15), params.get("MOT_SPIN_MAX", 0.95)
    expo = params.get("MOT_THST_EXPO", 0.65)
    if not -1.0 <= expo <= 1.0:
        raise ReaderError(
            f"{path}: the log's MOT_THST_EXPO = {expo:g} is outside ArduPilot's range [-1, 1]: its motors' "
            "thrust cannot be read from their outputs"
        )
    if not 0.0 <= spin_min < spin_max <= 1.0:
        raise ReaderError(
            f"{path}: the log's MOT_SPIN_MIN = {spin_min:g} and MOT_SPIN_MAX = {spin_max:g} are not "
            "0 <= MIN < MAX <= 1: its motors' thrust cannot be read from their outputs"
        )
    return spin_min, spin_max, expo


def _imu_position(params, prefix) -> tuple:
    """The IMU's position from the centre of mass the autopilot was given (m, body FRD; 0 where
    the log has none): ArduPilot's ``INS_POS1_X/Y/Z``, PX4's ``EKF2_IMU_POS_X/Y/Z``."""
    return tuple(float(params.get(f"{prefix}{a}", 0.0)) for a in "XYZ")


def _flying_from_events(events) -> list[tuple[float, float]]:
    spans, start = [], None
    for t, ev in events:
        if ev == EV_TAKEOFF and start is None:
            start = t
        elif ev in EV_LANDING and start is not None:
            spans.append((start, t))
            start = None
    if start is not None:
        spans.append((start, np.inf))
    return spans


def _flying_from_thrust(t, thrust, level) -> list[tuple[float, float]]:
    return [(float(t[a]), float(t[b - 1])) for a, b in runs(thrust.mean(axis=1) > level, shortest=2)]


# -- PX4 ------------------------------------------------------------------------------------------------
def _read_px4(path: Path) -> MotorLog:
    ULog = need("pyulog", "reading a PX4 ULog").ULog

    topics = ["sensor_combined", "actuator_motors", "actuator_outputs", "vehicle_land_detected"]
    try:
        ulog = ULog(str(path), topics)
    except Exception as exc:  # pyulog raises plain Exceptions on bad files
        raise ReaderError(f"{path}: not a readable ULog file ({reason(exc)})") from None
    data = {d.name: d.data for d in ulog.data_list if d.multi_id == 0}
    params = ulog.initial_parameters
    if "sensor_combined" not in data:
        raise ReaderError(f"{path}: the ULog has no sensor_combined (IMU) topic")
    sc = data["sensor_combined"]
    notes = []
    table, frame = px4_geometry(params, notes)
    n = len(table)
    if "actuator_motors" in data:
        am = data["actuator_motors"]
        t_out = am["timestamp"] * 1e-6
        outputs = np.column_stack([am[f"control[{i}]"] for i in range(n)])
        thrust, unit = np.clip(outputs, 0.0, 1.0), "thrust"
    elif "actuator_outputs" in data:
        ao = data["actuator_outputs"]
        t_out = ao["timestamp"] * 1e-6
        outputs = np.column_stack([ao[f"output[{i}]"] for i in range(n)])
        fac = float(params.get("THR_MDL_FAC", 0.0))
        x = pwm_share(outputs, *px4_pwm_range(params))
        thrust, unit = (1.0 - fac) * x + fac * x * x, "us"
    else:
        raise ReaderError(f"{path}: the ULog has no actuator_motors or actuator_outputs topic to diagnose")
    flying = []
    if "vehicle_land_detected" in data:
        ld = data["vehicle_land_detected"]
        flying = _flying_from_landed(ld["timestamp"] * 1e-6, ld["landed"] == 0)
    if not flying:
        flying = _flying_from_thrust(t_out, thrust, 0.2)
        notes.append("no land detector in the log: flight taken as where the mean thrust exceeds 20 %")
    positions, spin = frame_geometry(table)
    return MotorLog(
        str(path),
        "PX4",
        sc["timestamp"] * 1e-6,
        np.column_stack([sc[f"gyro_rad[{i}]"] for i in range(3)]),
        np.column_stack([sc[f"accelerometer_m_s2[{i}]"] for i in range(3)]),
        t_out,
        outputs,
        list(range(1, n + 1)),
        frame,
        positions,
        spin,
        thrust,
        flying,
        [],
        unit,
        notes,
        list(range(1, n + 1)),
        _imu_position(params, "EKF2_IMU_POS_"),
    )


def _flying_from_landed(t, airborne) -> list[tuple[float, float]]:
    """From the first airborne sample to the first landed one after it (open when none)."""
    return [(float(t[a]), float(t[b]) if b < len(t) else np.inf) for a, b in runs(airborne)]
