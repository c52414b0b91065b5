"""PX4 ULog and ArduPilot DataFlash logs written by hand from their specifications, for the
tests and for the check of the built wheel (tools/check_wheel.py): numpy and struct only."""

import struct
from pathlib import Path

import numpy as np

from quadest.rotation import quat_to_euler


def _ulog_msg(kind, payload):
    return struct.pack("<HB", len(payload), ord(kind)) + payload


def _ulog_param(name: str, value: float) -> bytes:
    key = f"float {name}".encode()
    return _ulog_msg("P", struct.pack("<B", len(key)) + key + struct.pack("<f", value))


FIFO = "uint64_t timestamp;uint64_t timestamp_sample;uint32_t device_id;float dt;float scale;uint8_t samples;"
FIFO += "int16_t[32] x;int16_t[32] y;int16_t[32] z;"
FIFO_SCALE = {"sensor_gyro_fifo": 1e-3, "sensor_accel_fifo": 5e-3}  # rad/s, m/s² per count


def _ulog_fifo(flight, k, us, mid, name, value):
    """One FIFO message holding the ``k``-th group of four samples (PX4's layout: the stamp is
    the last sample's, ``dt`` µs apart, int16 counts times ``scale``)."""
    rows = value[4 * k : 4 * k + 4]
    counts = np.zeros((3, 32), np.int16)
    counts[:, : len(rows)] = np.round(rows.T / FIFO_SCALE[name])
    dt = (flight.t[1] - flight.t[0]) * 1e6
    head = struct.pack("<HQQIffB", mid, us, us, 1, dt, FIFO_SCALE[name], len(rows))
    return _ulog_msg("D", head + counts.astype("<i2").tobytes())


def write_ulog(
    path, flight, truncate_at=None, params=None, t0_us=1_000_000, fifo=False, mag=True, outputs=None, rotors=None
):
    """A minimal ULog (format version 1): header, flag bits, formats, ``params`` (name → float),
    subscriptions, data; the IMU's first timestamp ``t0_us``. With ``fifo`` every sample goes
    into sensor_gyro_fifo / sensor_accel_fifo (four a message) and sensor_combined logs every
    fourth. ``mag`` False leaves the magnetometer out; ``outputs`` (N, 4) PWM µs, one row per
    sample, logs actuator_outputs every fourth sample; ``rotors`` ((N, 4) normalised commands,
    (N, 4) rpm) logs actuator_motors and esc_status (a nested esc_report) every second sample."""
    topics = {
        "sensor_combined": ("uint64_t timestamp;float[3] gyro_rad;float[3] accelerometer_m_s2;", 0),
        "vehicle_magnetometer": ("uint64_t timestamp;float[3] magnetometer_ga;", 1),
        "vehicle_attitude": ("uint64_t timestamp;float[4] q;", 2),
    }
    if not mag:
        del topics["vehicle_magnetometer"]
    if fifo:
        topics.update({"sensor_gyro_fifo": (FIFO, 3), "sensor_accel_fifo": (FIFO, 4)})
    if outputs is not None:
        topics["actuator_outputs"] = ("uint64_t timestamp;float[16] output;", 5)
    if rotors is not None:
        topics["actuator_motors"] = ("uint64_t timestamp;float[12] control;", 6)
        topics["esc_status"] = ("uint64_t timestamp;uint8_t esc_count;esc_report[4] esc;", 7)
    out = b"ULog\x01\x12\x35\x01" + struct.pack("<Q", 0)
    out += _ulog_msg("B", bytes(16) + struct.pack("<3Q", 0, 0, 0))
    if rotors is not None:
        out += _ulog_msg("F", b"esc_report:int32_t esc_rpm;float esc_voltage;")
    for name, (fmt, _) in topics.items():
        out += _ulog_msg("F", f"{name}:{fmt}".encode())
    for name, value in (params or {}).items():
        out += _ulog_param(name, value)
    for name, (_, mid) in topics.items():
        out += _ulog_msg("A", struct.pack("<BH", 0, mid) + name.encode())
    for k in range(len(flight)):
        us = int(round(flight.t[k] * 1e6)) + t0_us
        if fifo and k % 4 == 3:
            out += _ulog_fifo(flight, k // 4, us, 3, "sensor_gyro_fifo", flight.gyr)
            out += _ulog_fifo(flight, k // 4, us, 4, "sensor_accel_fifo", flight.acc)
        if fifo and k % 4:
            continue
        out += _ulog_msg("D", struct.pack("<HQ6f", 0, us, *flight.gyr[k], *flight.acc[k]))
        if mag:
            out += _ulog_msg("D", struct.pack("<HQ3f", 1, us, *(flight.mag[k] / 100.0)))
        if k % 4 == 0:
            out += _ulog_msg("D", struct.pack("<HQ4f", 2, us, *flight.true_q[k]))
        if k % 4 == 0 and outputs is not None:
            out += _ulog_msg("D", struct.pack("<HQ16f", 5, us, *outputs[k], *[0.0] * 12))
        if k % 2 == 0 and rotors is not None:
            out += _ulog_msg("D", struct.pack("<HQ12f", 6, us, *rotors[0][k], *[np.nan] * 8))
            esc = b"".join(struct.pack("<if", int(r), 16.0) for r in rotors[1][k])
            out += _ulog_msg("D", struct.pack("<HQB", 7, us, 4) + esc)
    Path(path).write_bytes(out[:truncate_at] if truncate_at else out)


def _df_fmt(mid, name, fmt, cols):
    sizes = {"Q": 8, "B": 1, "f": 4, "n": 4, "N": 16, "Z": 64}
    length = 3 + sum(sizes[c] for c in fmt)
    return (
        b"\xa3\x95\x80"
        + struct.pack("<BB", mid, length)
        + name.encode().ljust(4, b"\0")
        + fmt.encode().ljust(16, b"\0")
        + cols.encode().ljust(64, b"\0")
    )


def write_dataflash(path, flight, params=None, xkq=False, batch=False, mag=True, outputs=None, esc_rpm=None):
    """A DataFlash log: IMU, MAG, ATT (and XKQ when ``xkq``; every sample as the batch sampler's
    GYR / ACC, and IMU every fourth, when ``batch``), PARM for ``params``. ``mag`` False leaves
    MAG out; ``outputs`` (N, 4) PWM µs, one row per sample, logs RCOU every fourth sample;
    ``esc_rpm`` (N, 4) rpm: one ESC message per instance (output channel − 1) every second sample."""
    out = _df_fmt(128, "FMT", "BBnNZ", "Type,Length,Name,Format,Columns")
    out += _df_fmt(129, "IMU", "QBffffff", "TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ")
    out += _df_fmt(130, "MAG", "QBfff", "TimeUS,I,MagX,MagY,MagZ")
    out += _df_fmt(131, "ATT", "Qfff", "TimeUS,Roll,Pitch,Yaw")
    out += _df_fmt(132, "PARM", "QNf", "TimeUS,Name,Value")
    out += _df_fmt(133, "XKQ", "QBffff", "TimeUS,C,Q1,Q2,Q3,Q4")
    out += _df_fmt(134, "GYR", "QBQfff", "TimeUS,I,SampleUS,GyrX,GyrY,GyrZ")
    out += _df_fmt(135, "ACC", "QBQfff", "TimeUS,I,SampleUS,AccX,AccY,AccZ")
    out += _df_fmt(136, "RCOU", "Qffff", "TimeUS,C1,C2,C3,C4")
    out += _df_fmt(137, "ESC", "QBf", "TimeUS,Instance,RPM")
    for name, value in (params or {}).items():
        out += b"\xa3\x95\x84" + struct.pack("<Q16sf", 400_000, name.encode(), value)
    eul = np.degrees(quat_to_euler(flight.true_q))
    for k in range(len(flight)):
        us = int(round(flight.t[k] * 1e6)) + 500_000
        if batch:
            out += b"\xa3\x95\x86" + struct.pack("<QBQ3f", us + 50, 0, us, *flight.gyr[k])
            out += b"\xa3\x95\x87" + struct.pack("<QBQ3f", us + 50, 0, us, *flight.acc[k])
        if not batch or k % 4 == 0:
            out += b"\xa3\x95\x81" + struct.pack("<QB6f", us, 0, *flight.gyr[k], *flight.acc[k])
        if mag:
            out += b"\xa3\x95\x82" + struct.pack("<QB3f", us, 0, *(flight.mag[k] * 10.0))
        if k % 4 == 0 and outputs is not None:
            out += b"\xa3\x95\x88" + struct.pack("<Q4f", us, *outputs[k])
        if k % 2 == 0 and esc_rpm is not None:
            for i, rpm in enumerate(esc_rpm[k]):
                out += b"\xa3\x95\x89" + struct.pack("<QBf", us, i, rpm)
        out += b"\xa3\x95\x83" + struct.pack("<Q3f", us, *eul[k])
        if xkq and k % 2 == 0:
            out += b"\xa3\x95\x85" + struct.pack("<QB4f", us, 0, *flight.true_q[k])
    Path(path).write_bytes(out)
