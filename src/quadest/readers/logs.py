"""Autopilot logs: PX4 ULog (pyulog) and ArduPilot DataFlash .bin (pymavlink). Both
autopilots already use NED / FRD, so only units change (docs/readers.md)."""
from __future__ import annotations

import numpy as np

from quadest.readers.common import ReaderError, make_recording, mag_on_imu_rows, resample_quat
from quadest.rotation import euler_to_quat


# -- PX4 ----------------------------------------------------------------------------------------------
def read_ulog(path, *, instance: int = 0, **_):
    """Raw IMU from ``sensor_combined`` (or ``vehicle_imu``-less logs' ``sensor_accel`` /
    ``sensor_gyro``), magnetometer from ``vehicle_magnetometer``, ``sensor_mag`` or the
    ``magnetometer_ga`` fields of old ``sensor_combined`` (gauss -> µT), and the onboard EKF2
    attitude ``vehicle_attitude.q`` as ``ref_q``."""
    from pyulog import ULog

    topics = ["sensor_combined", "sensor_gyro", "sensor_accel", "vehicle_magnetometer", "sensor_mag",
              "vehicle_attitude"]
    try:
        ulog = ULog(str(path), topics)
    except Exception as exc:  # pyulog raises plain Exceptions and struct errors on bad files
        raise ReaderError(f"{path}: not a readable ULog file ({type(exc).__name__}: {exc})") from None
    data = {}
    for d in ulog.data_list:
        if d.multi_id == instance or d.name not in data:
            data[d.name] = d.data
    if "sensor_combined" in data:
        sc = data["sensor_combined"]
        t = sc["timestamp"] * 1e-6
        gyr = np.column_stack([sc[f"gyro_rad[{i}]"] for i in range(3)])
        acc = np.column_stack([sc[f"accelerometer_m_s2[{i}]"] for i in range(3)])
    elif "sensor_gyro" in data and "sensor_accel" in data:
        sg, sa = data["sensor_gyro"], data["sensor_accel"]
        t = sg["timestamp"] * 1e-6
        gyr = np.column_stack([sg[a] for a in "xyz"])
        acc = np.column_stack([np.interp(t, sa["timestamp"] * 1e-6, sa[a]) for a in "xyz"])
    else:
        raise ReaderError(f"{path}: the ULog has no raw IMU topic (sensor_combined or sensor_gyro/"
                          "sensor_accel); log it with SDLOG_PROFILE including sensor data")
    mag = None
    if "vehicle_magnetometer" in data:
        m = data["vehicle_magnetometer"]
        mag = mag_on_imu_rows(t, m["timestamp"] * 1e-6,
                              np.column_stack([m[f"magnetometer_ga[{i}]"] for i in range(3)]) * 100.0)
    elif "sensor_mag" in data:
        m = data["sensor_mag"]
        mag = mag_on_imu_rows(t, m["timestamp"] * 1e-6, np.column_stack([m[a] for a in "xyz"]) * 100.0)
    elif "sensor_combined" in data and "magnetometer_ga[0]" in data["sensor_combined"]:
        sc = data["sensor_combined"]
        rel = sc["magnetometer_timestamp_relative"].astype(np.int64)
        fresh = rel != np.iinfo(np.int32).max  # PX4's "no new sample" marker
        tm = (sc["timestamp"] + rel) * 1e-6
        vals = np.column_stack([sc[f"magnetometer_ga[{i}]"] for i in range(3)]) * 100.0
        # a new sample is one whose values or timestamp changed
        new = fresh & np.concatenate([[True], (np.diff(tm) != 0) | (np.diff(vals, axis=0) != 0).any(axis=1)])
        mag = mag_on_imu_rows(t, tm[new], vals[new])
    truth = {}
    if "vehicle_attitude" in data:
        va = data["vehicle_attitude"]
        truth["ref_q"] = resample_quat(va["timestamp"] * 1e-6, np.column_stack([va[f"q[{i}]"] for i in range(4)]), t)
    meta = {"source_format": "PX4 ULog", "units": {"gyr": "rad/s", "acc": "m/s^2", "mag": "uT"},
            "frames": "NED/FRD (PX4's own)", "reference": "vehicle_attitude (EKF2) as ref_q",
            "ulog_corrupt": bool(getattr(ulog, "file_corruption", False))}
    return make_recording(path, "ulog", t, gyr, acc, mag, meta, **truth)


# -- ArduPilot ------------------------------------------------------------------------------------------
def read_dataflash(path, *, instance: int = 0, **_):
    """IMU (GyrX.. rad/s, AccX.. m/s²), MAG (MagX.. milligauss -> µT) and ATT (Roll, Pitch, Yaw
    in degrees, the EKF's attitude) as ``ref_q``; instance ``I`` 0 unless chosen."""
    from pymavlink import DFReader

    try:
        log = DFReader.DFReader_binary(str(path), zero_time_base=True)
    except Exception as exc:  # pymavlink raises many kinds on bad files
        raise ReaderError(f"{path}: not a readable DataFlash log ({type(exc).__name__}: {exc})") from None
    imu, mag, att = [], [], []
    try:
        while True:
            m = log.recv_match(type=["IMU", "MAG", "ATT"])
            if m is None:
                break
            kind = m.get_type()
            inst = getattr(m, "I", getattr(m, "Instance", 0))
            if kind == "IMU" and inst == instance:
                imu.append((m.TimeUS, m.GyrX, m.GyrY, m.GyrZ, m.AccX, m.AccY, m.AccZ))
            elif kind == "MAG" and inst == instance:
                mag.append((m.TimeUS, m.MagX, m.MagY, m.MagZ))
            elif kind == "ATT":
                att.append((m.TimeUS, m.Roll, m.Pitch, m.Yaw))
    except Exception as exc:
        raise ReaderError(f"{path}: DataFlash log broken after {len(imu)} IMU messages "
                          f"({type(exc).__name__}: {exc})") from None
    if not imu:
        raise ReaderError(f"{path}: no IMU messages (instance {instance}) in the DataFlash log")
    imu = np.array(imu, float)
    t = imu[:, 0] * 1e-6
    magv = None
    if mag:
        mag = np.array(mag, float)
        magv = mag_on_imu_rows(t, mag[:, 0] * 1e-6, mag[:, 1:4] * 0.1)
    truth = {}
    if att:
        att = np.array(att, float)
        truth["ref_q"] = resample_quat(att[:, 0] * 1e-6, euler_to_quat(np.radians(att[:, 1:4])), t, max_gap=0.5)
    meta = {"source_format": "ArduPilot DataFlash", "units": {"gyr": "rad/s", "acc": "m/s^2", "mag": "uT"},
            "frames": "NED/FRD (ArduPilot's own)", "reference": "ATT (EKF attitude) as ref_q"}
    return make_recording(path, "dataflash", t, imu[:, 1:4], imu[:, 4:7], magv, meta, **truth)
