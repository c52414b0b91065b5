"""Autopilot logs: PX4 ULog (pyulog) and ArduPilot DataFlash .bin (pymavlink). Both
autopilots already use NED / FRD, so only units change (docs/readers.md)."""

from __future__ import annotations

import functools
import struct
from contextlib import contextmanager

import numpy as np

from quadest.errors import UsageError
from quadest.extras import need
from quadest.readers.common import ReaderError, mag_on_imu_rows, make_recording, reason, resample_quat
from quadest.readers.rotors import PX4_ROTOR_TOPICS, ardupilot_rotors, px4_rotors
from quadest.records import number
from quadest.rotation import euler_to_quat

# -- PX4 ----------------------------------------------------------------------------------------------
LOG_DAMAGE = (KeyError, IndexError, TypeError, AttributeError, OverflowError, struct.error, UnicodeDecodeError)
"""What a damaged log makes the readers' field access raise."""


def _gauss_to_ut(g):
    """Gauss to µT in float64 (PX4 logs float32: a damaged value times 100 would overflow it)."""
    return np.asarray(g, dtype=np.float64) * 100.0


IMU_SOURCES = ("logged", "fifo")
"""Which IMU samples a log's reader takes: the ones logged at the IMU topic's rate, or the
high-rate samples of the sensor's FIFO where the log has them."""


def _imu_source(imu, path) -> str:
    imu = imu or "logged"
    if imu not in IMU_SOURCES:
        raise ReaderError(f"{path}: unknown IMU source {imu!r}; one of {', '.join(IMU_SOURCES)}")
    return imu


ULOG_IMU_TOPICS = ("sensor_combined", "sensor_gyro", "sensor_accel", "sensor_gyro_fifo", "sensor_accel_fifo")


def _instance(instance) -> int:
    return number(instance, "instance (the IMU's)", "int", "[0, 255]")


def _refuse_missing_instance(path, instance: int, present) -> None:
    """Refuse an IMU instance the log does not hold (never another one taken instead)."""
    if present and instance not in present:
        have = ", ".join(str(i) for i in sorted(present))
        raise UsageError(f"{path}: instance={instance}, but the log holds IMU instance(s) {have}; choose one of them")


def read_ulog(path, *, instance: int = 0, imu: str | None = None):
    """See :func:`_read_ulog`; a log whose topics lack the fields they should have is refused
    naming the file."""
    imu, instance = _imu_source(imu, path), _instance(instance)
    try:
        return _read_ulog(path, instance=instance, imu=imu)
    except LOG_DAMAGE as exc:
        raise ReaderError(f"{path}: the ULog is damaged or not from PX4 ({reason(exc)})") from None


def read_dataflash(path, *, instance: int = 0, imu: str | None = None):
    """See :func:`_read_dataflash`; a log whose messages lack the fields they should have is
    refused naming the file."""
    imu, instance = _imu_source(imu, path), _instance(instance)
    try:
        return _read_dataflash(path, instance=instance, imu=imu)
    except LOG_DAMAGE as exc:
        raise ReaderError(f"{path}: the DataFlash log is damaged ({reason(exc)})") from None


PX4_FIFO = ("sensor_gyro_fifo", "sensor_accel_fifo")


def _fifo_samples(d) -> tuple[np.ndarray, np.ndarray]:
    """``(t, xyz)`` of every sample of a PX4 FIFO topic: ``samples`` int16 values per axis and
    message, times ``timestamp_sample − (samples − 1 − i)·dt`` (the stamp is the last sample's;
    µs), values times ``scale``."""
    n = d["samples"].astype(np.int64)
    i = np.arange(32)
    keep = i[None, :] < n[:, None]
    t = d["timestamp_sample"][:, None] - (n[:, None] - 1 - i[None, :]) * d["dt"][:, None].astype(np.float64)
    axes = [np.column_stack([d[f"{a}[{k}]"] for k in range(32)]) * d["scale"][:, None] for a in "xyz"]
    return t[keep] * 1e-6, np.column_stack([ax[keep] for ax in axes])


def _ulog_fifo(data, path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The gyroscope's FIFO samples with the accelerometer's interpolated onto their times."""
    missing = [name for name in PX4_FIFO if name not in data]
    if missing:
        raise ReaderError(
            f"{path}: --imu fifo, but the log has no {' / '.join(missing)} (PX4 logs them with "
            "SDLOG_PROFILE's high-rate IMU bit); leave out --imu fifo for the logged IMU"
        )
    t, gyr = _fifo_samples(data["sensor_gyro_fifo"])
    ta, acc = _fifo_samples(data["sensor_accel_fifo"])
    order = np.argsort(ta, kind="stable")
    acc = np.column_stack([np.interp(t, ta[order], acc[order, k]) for k in range(3)])
    return t, gyr, acc


def _read_ulog(path, *, instance: int = 0, imu: str = "logged"):
    """Raw IMU from ``sensor_combined`` (or ``vehicle_imu``-less logs' ``sensor_accel`` /
    ``sensor_gyro``), magnetometer from ``vehicle_magnetometer``, ``sensor_mag`` or the
    ``magnetometer_ga`` fields of old ``sensor_combined`` (gauss -> µT), the onboard EKF2
    attitude ``vehicle_attitude.q`` as ``ref_q``, and the rotors' commands and speeds
    (:func:`~quadest.readers.rotors.px4_rotors`)."""
    ULog = need("pyulog", "reading a PX4 ULog").ULog

    topics = [
        "sensor_combined",
        "sensor_gyro",
        "sensor_accel",
        "vehicle_magnetometer",
        "sensor_mag",
        "vehicle_attitude",
        *PX4_ROTOR_TOPICS,
    ] + (list(PX4_FIFO) if imu == "fifo" else [])
    try:
        ulog = ULog(str(path), topics)
    except Exception as exc:  # pyulog raises plain Exceptions and struct errors on bad files
        raise ReaderError(f"{path}: not a readable ULog file ({reason(exc)})") from None
    data = {}
    for d in ulog.data_list:  # the IMU's topics of that instance only; others' first where it has none
        if d.multi_id == instance or (d.name not in data and d.name not in ULOG_IMU_TOPICS):
            data[d.name] = d.data
    _refuse_missing_instance(path, instance, {d.multi_id for d in ulog.data_list if d.name in ULOG_IMU_TOPICS})
    if imu == "fifo":
        t, gyr, acc = _ulog_fifo(data, path)
    elif "sensor_combined" in data:
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
        raise ReaderError(
            f"{path}: the ULog has no raw IMU topic (sensor_combined or sensor_gyro/"
            f"sensor_accel) of instance {instance}; log it with SDLOG_PROFILE including sensor data"
            + (" (sensor_combined holds instance 0 only)" if instance else "")
        )
    mag = None
    if "vehicle_magnetometer" in data:
        m = data["vehicle_magnetometer"]
        mag = mag_on_imu_rows(
            t, m["timestamp"] * 1e-6, _gauss_to_ut(np.column_stack([m[f"magnetometer_ga[{i}]"] for i in range(3)]))
        )
    elif "sensor_mag" in data:
        m = data["sensor_mag"]
        mag = mag_on_imu_rows(t, m["timestamp"] * 1e-6, _gauss_to_ut(np.column_stack([m[a] for a in "xyz"])))
    elif "sensor_combined" in data and "magnetometer_ga[0]" in data["sensor_combined"]:
        sc = data["sensor_combined"]
        rel = sc["magnetometer_timestamp_relative"].astype(np.int64)
        fresh = rel != np.iinfo(np.int32).max  # PX4's "no new sample" marker
        tm = (sc["timestamp"] + rel) * 1e-6
        vals = _gauss_to_ut(np.column_stack([sc[f"magnetometer_ga[{i}]"] for i in range(3)]))
        # a new sample is one whose values or timestamp changed
        new = fresh & np.concatenate([[True], (np.diff(tm) != 0) | (np.diff(vals, axis=0) != 0).any(axis=1)])
        mag = mag_on_imu_rows(t, tm[new], vals[new])
    truth = {}
    if "vehicle_attitude" in data:
        va = data["vehicle_attitude"]
        truth["ref_q"] = resample_quat(va["timestamp"] * 1e-6, np.column_stack([va[f"q[{i}]"] for i in range(4)]), t)
    rotor_channels, rotors = px4_rotors(data, ulog.initial_parameters, t)
    truth.update(rotor_channels)
    corrupt = bool(getattr(ulog, "file_corruption", False)) or _ulog_cut(path)
    meta = {
        "source_format": "PX4 ULog",
        "units": {"gyr": "rad/s", "acc": "m/s^2", "mag": "uT"},
        "frames": "NED/FRD (PX4's own)",
        "reference": "vehicle_attitude (EKF2) as ref_q",
        "ulog_corrupt": corrupt,
        "imu_source": "sensor_gyro_fifo / sensor_accel_fifo" if imu == "fifo" else "the logged IMU topic",
        "imu_sources": ["logged"] + (["fifo"] if all(n in ulog.message_formats for n in PX4_FIFO) else []),
        **_ulog_declination(ulog),
        **({"rotors": rotors} if rotors else {}),
    }
    if corrupt:
        meta["warnings"] = [
            f"the log is damaged or cut short inside a message: what could be read ends at "
            f"t = {t[-1] - t[0]:.3f} s (a log cut exactly between two messages cannot be told "
            "from a complete one)"
        ]
    return make_recording(path, "ulog", t, gyr, acc, mag, meta, **truth)


PX4_DECLINATION = ("EKF2_MAG_DECL", "ATT_MAG_DECL")
"""PX4's declination parameters (degrees, east positive): EKF2's, and the older attitude
estimator's; the log's last value is the one the autopilot used last."""


def _ulog_declination(ulog) -> dict:
    """``{"declination_rad", "declination_source"}`` from the log's parameters, or nothing."""
    for name in PX4_DECLINATION:
        values = [v for _, n, v in getattr(ulog, "changed_parameters", []) if n == name]
        value = values[-1] if values else ulog.initial_parameters.get(name)
        if value is not None and np.isfinite(value):
            return {"declination_rad": float(np.radians(value)), "declination_source": f"the log's {name}"}
    return {}


def _ulog_cut(path) -> bool:
    """Whether a ULog file ends inside a message: the file is a 16-byte header and then messages
    of (uint16 size, uint8 type, size bytes); pyulog reads a file cut inside its last message
    without saying so."""
    import struct

    with open(path, "rb") as f:
        data = f.read()
    pos, n = 16, len(data)
    while pos + 3 <= n:
        (size,) = struct.unpack_from("<H", data, pos)
        pos += 3 + size
    return pos != n


# -- ArduPilot ------------------------------------------------------------------------------------------
def _read_dataflash(path, *, instance: int = 0, imu: str = "logged"):
    """IMU (GyrX.. rad/s, AccX.. m/s²; or with ``imu="fifo"`` the batch sampler's GYR / ACC at
    their ``SampleUS``), MAG (MagX.. milligauss -> µT), the EKF's attitude as ``ref_q``
    (:func:`_dataflash_reference`), the declination ``COMPASS_DEC`` and the rotors' commands and
    speeds (:func:`~quadest.readers.rotors.ardupilot_rotors`); instance ``I`` 0 unless chosen."""
    DFReader = need("pymavlink.DFReader", "reading an ArduPilot DataFlash log")
    fifo = imu == "fifo"
    imu, mag, att, xkq, vibe, params, present = [], [], [], [], [], {}, set()
    batch = {"GYR": [], "ACC": []} if fifo else None
    motors = {"RCOU": [], "ESC": [], "PARM": {}}  # PARM: each parameter's first value (the motors' outputs)
    with _printed() as said:  # pymavlink prints what it skips; quadest counts it and says it once
        log = open_dataflash(DFReader, path)
        try:
            _read_dataflash_messages(log, instance, (imu, mag, att, xkq, vibe), params, batch, present, motors)
        except ReaderError:
            raise
        except Exception as exc:
            raise ReaderError(f"{path}: DataFlash log broken after {len(imu)} IMU messages ({reason(exc)})") from None
    warnings = _dataflash_damage(said)
    _refuse_missing_instance(path, instance, present)
    if fifo:
        imu = _dataflash_batch(batch, path)
    if not len(imu):
        raise ReaderError(f"{path}: no IMU messages (instance {instance}) in the DataFlash log")
    imu = np.array(imu, float)
    t = imu[:, 0] * 1e-6
    magv = None
    if mag:
        mag = np.array(mag, float)
        magv = mag_on_imu_rows(t, mag[:, 0] * 1e-6, mag[:, 1:4] * 0.1)
    truth, reference = _dataflash_reference(t, att, xkq)
    rotor_channels, rotors = ardupilot_rotors(motors, motors["PARM"], t)
    truth.update(rotor_channels)
    meta = {
        "source_format": "ArduPilot DataFlash",
        "units": {"gyr": "rad/s", "acc": "m/s^2", "mag": "uT"},
        "frames": "NED/FRD (ArduPilot's own)",
        "reference": reference,
        "imu_source": "the batch sampler's GYR / ACC" if fifo else "IMU",
        "imu_sources": ["logged"] + (["fifo"] if _has_messages(log, ("GYR", "ACC")) else []),
        **({"rotors": rotors} if rotors else {}),
    }
    if vibe:
        meta["vibration"] = _vibration(np.array(vibe, float))
    if np.isfinite(params.get("COMPASS_DEC", np.nan)):  # radians, east positive; its last value
        meta.update(declination_rad=float(params["COMPASS_DEC"]), declination_source="the log's COMPASS_DEC")
    if _dataflash_cut(path):
        warnings.append(
            f"the log is cut short inside a message: what could be read ends at t = {t[-1] - t[0]:.3f} s (a "
            "log cut exactly between two messages, or on a 512-byte block as ArduPilot ends its own, cannot "
            "be told from a complete one)"
        )
    if warnings:
        meta["warnings"] = warnings
    return make_recording(path, "dataflash", t, imu[:, 1:4], imu[:, 4:7], magv, meta, **truth)


DF_HEAD = b"\xa3\x95"
DF_FMT = 128  # the FMT message's type: it defines every type's length (its own: 89 bytes)
DF_BLOCK = 512


def _dataflash_cut(path) -> bool:
    """Whether a DataFlash log ends inside a message that does not end at a 512-byte block:
    messages are ``A3 95 type`` and a body whose length the type's FMT message states. ArduPilot's
    own writer ends its logs on a block boundary, often inside the last message, so such an
    ending is taken as complete. Damaged bytes are stepped over to the next header (pymavlink does
    the same, quadest counts them elsewhere); an undeclared type ends the walk (cannot tell)."""
    with open(path, "rb") as f:
        data = f.read()
    lengths, pos, n = {DF_FMT: 89}, 0, len(data)
    while pos + 3 <= n:
        if not data.startswith(DF_HEAD, pos):
            pos = data.find(DF_HEAD, pos + 1)
            if pos < 0:
                return False
            continue
        size = lengths.get(data[pos + 2])
        if size is None or size < 3:
            return False
        if pos + size > n:
            break
        if data[pos + 2] == DF_FMT:
            lengths[data[pos + 3]] = data[pos + 4]
        pos += size
    return pos < n and n % DF_BLOCK != 0


def _dataflash_reference(t, att, xkq) -> tuple[dict, str]:
    """The EKF's quaternion (XKQ, core 0) on the IMU's rows as ``ref_q``, else ATT's Euler
    angles (rounded to 0.01°, logged more slowly), else none."""
    if xkq:
        xkq = np.array(xkq, float)
        return {"ref_q": resample_quat(xkq[:, 0] * 1e-6, xkq[:, 1:5], t, max_gap=0.5)}, "XKQ (EKF quaternion) as ref_q"
    if att:
        att = np.array(att, float)
        q = euler_to_quat(np.radians(att[:, 1:4]))
        return {"ref_q": resample_quat(att[:, 0] * 1e-6, q, t, max_gap=0.5)}, "ATT (EKF attitude) as ref_q"
    return {}, "none"


def _vibration(vibe: np.ndarray) -> dict:
    """ArduPilot's own vibration figures (VIBE: the accelerometer's high-passed RMS per axis,
    m/s², and the clipping count)."""
    return {
        "source": "the log's VIBE messages",
        "rms_m_s2": np.median(vibe[:, 1:4], axis=0).tolist(),
        "max_m_s2": vibe[:, 1:4].max(axis=0).tolist(),
        "clips": int(vibe[:, 4].max()),
    }


def _has_messages(log, kinds) -> bool:
    """Whether the log holds messages of every one of ``kinds`` (pymavlink counts each type when
    it opens a log; a format defined is not a message logged)."""
    ids = [log.name_to_id.get(k) for k in kinds]
    counts = getattr(log, "counts", None)
    return counts is not None and all(i is not None and counts[i] > 0 for i in ids)


def _dataflash_batch(batch, path) -> np.ndarray:
    """Rows ``(t_us, gyr xyz, acc xyz)`` of the batch sampler: GYR's samples, ACC's interpolated
    onto their times."""
    if not batch["GYR"] or not batch["ACC"]:
        raise ReaderError(
            f"{path}: --imu fifo, but the log has no GYR / ACC batch samples (ArduPilot logs them with "
            "INS_LOG_BAT_MASK); leave out --imu fifo for the logged IMU"
        )
    g, a = (np.array(sorted(batch[k]), float) for k in ("GYR", "ACC"))
    acc = np.column_stack([np.interp(g[:, 0], a[:, 0], a[:, k]) for k in (1, 2, 3)])
    return np.column_stack([g, acc])


def open_dataflash(DFReader, path):
    """pymavlink's reader of the DataFlash log ``path``, refusing a log it cannot open or that
    would keep it in one place (:func:`_moving_reader`) in one line naming the file."""
    try:
        return _moving_reader(DFReader)(path)
    except ReaderError:
        raise
    except Exception as exc:  # pymavlink raises many kinds on bad files
        raise ReaderError(f"{path}: not a readable DataFlash log ({reason(exc)})") from None


@functools.cache
def _moving_reader(DFReader):
    """pymavlink's binary DataFlash reader that refuses a message which does not move it on: a
    damaged format message declaring a length below the 3-byte header, with an empty format,
    made pymavlink read the same place for ever."""

    class MovingReader(DFReader.DFReader_binary):
        def __init__(self, path):
            self.quadest_path = path
            super().__init__(str(path), zero_time_base=True)

        def _parse_next(self):
            start = self.offset
            m = super()._parse_next()
            if m is not None and self.offset <= start:
                raise ReaderError(
                    f"{self.quadest_path}: the DataFlash log is damaged: a message at byte {start} has a "
                    f"format of length {m.fmt.len}, shorter than its header, so the log cannot be read past it"
                )
            return m

    return MovingReader


def _read_dataflash_messages(log, instance, lists, params, batch=None, present=None, motors=None):
    """Collect the messages quadest reads into ``lists`` (instance ``instance``), the parameters,
    the batch sampler's (``batch``), the IMU instances ``present``, and the motors' (``motors``:
    RCOU and ESC rows, each parameter's first value)."""
    imu, mag, att, xkq, vibe = lists
    kinds = ["IMU", "MAG", "ATT", "XKQ", "PARM", "VIBE"] + (list(batch) if batch is not None else [])
    kinds += ["RCOU", "ESC"] if motors is not None else []
    while True:
        m = log.recv_match(type=kinds)
        if m is None:
            return
        kind = m.get_type()
        inst = getattr(m, "I", getattr(m, "Instance", 0))
        if batch is not None and kind in batch:
            if inst == instance:
                axes = ("GyrX", "GyrY", "GyrZ") if kind == "GYR" else ("AccX", "AccY", "AccZ")
                batch[kind].append((m.SampleUS, *(getattr(m, a) for a in axes)))
        elif kind == "IMU":
            if present is not None:
                present.add(inst)
            if inst == instance:
                imu.append((m.TimeUS, m.GyrX, m.GyrY, m.GyrZ, m.AccX, m.AccY, m.AccZ))
        elif kind == "MAG" and inst == instance:
            mag.append((m.TimeUS, m.MagX, m.MagY, m.MagZ))
        elif kind == "ATT":
            att.append((m.TimeUS, m.Roll, m.Pitch, m.Yaw))
        elif kind == "XKQ" and getattr(m, "C", 0) == 0:
            xkq.append((m.TimeUS, m.Q1, m.Q2, m.Q3, m.Q4))
        elif kind == "PARM":
            params[m.Name] = m.Value
            if motors is not None:
                motors["PARM"].setdefault(m.Name, m.Value)
        elif kind == "RCOU":
            motors["RCOU"].append([m.TimeUS] + [getattr(m, f"C{i}", 0) for i in range(1, 15)])
        elif kind == "ESC":
            motors["ESC"].append((m.TimeUS, getattr(m, "Instance", 0), getattr(m, "RPM", np.nan)))
        elif kind == "VIBE" and getattr(m, "IMU", 0) == instance:
            vibe.append((m.TimeUS, m.VibeX, m.VibeY, m.VibeZ, getattr(m, "Clip", getattr(m, "Clip0", 0))))


@contextmanager
def _printed():
    """Capture what is written to the process's stdout and stderr (file descriptors 1 and 2:
    pymavlink writes there directly) into a list of lines, filled when the block ends."""
    import os
    import sys
    import tempfile

    lines: list[str] = []
    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        os.dup2(tmp.fileno(), 1)
        os.dup2(tmp.fileno(), 2)
        try:
            yield lines
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])
            tmp.seek(0)
            lines.extend(tmp.read().decode("utf-8", "replace").splitlines())


def _dataflash_damage(printed: list[str]) -> list[str]:
    """What pymavlink skipped: it prints a "bad header" line per damaged byte (a log cut short is
    found by :func:`_dataflash_cut`)."""
    bad = sum(1 for line in printed if line.startswith(("bad header", "Skipped", "Failed to parse")))
    if bad:
        return [
            f"the log is damaged: pymavlink skipped {bad} byte(s) or message(s) it could not read; what "
            "lies there is missing"
        ]
    return []
