"""ROS 1 (.bag) and ROS 2 (folder with metadata.yaml, .db3 or .mcap) bags via rosbags.

ROS follows REP 103 / 145: IMU and magnetometer in the sensor's body frame with z up (FLU),
orientation of a pose relative to an ENU world, magnetic field in tesla. quadest converts to
FRD / NED and µT (docs/readers.md). Topics are found by message type; with several candidates
give ``imu_topic`` / ``mag_topic`` / ``truth_topic``. The rotors' speeds and commands come from a
``mav_msgs/Actuators`` topic (RotorS, Agilicious: ``angular_velocities`` rad/s, ``normalized``),
where the bag has one (a ROS 1 bag carries its definition)."""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path

import numpy as np

from quadest.errors import UsageError
from quadest.extras import need
from quadest.readers.common import ReaderError, mag_on_imu_rows, make_recording, resample_quat
from quadest.readers.rotors import on_rows, rate_hz, rotor_meta
from quadest.rotation.frames import quat_enu_flu_to_ned_frd, vec_enu_to_ned, vec_flu_to_frd

IMU = ("sensor_msgs/msg/Imu", "sensor_msgs/Imu")
ACTUATORS = ("mav_msgs/msg/Actuators", "mav_msgs/Actuators")
PX4_IMU = ("px4_msgs/msg/SensorCombined",)
PX4_MAG = ("px4_msgs/msg/VehicleMagnetometer",)
PX4_ATTITUDE = ("px4_msgs/msg/VehicleAttitude", "px4_msgs/msg/VehicleOdometry")
MAG = ("sensor_msgs/msg/MagneticField", "sensor_msgs/MagneticField")
POSE = (
    "geometry_msgs/msg/PoseStamped",
    "geometry_msgs/PoseStamped",
    "nav_msgs/msg/Odometry",
    "nav_msgs/Odometry",
    "geometry_msgs/msg/TransformStamped",
    "geometry_msgs/TransformStamped",
    "geometry_msgs/msg/PoseWithCovarianceStamped",
    "geometry_msgs/PoseWithCovarianceStamped",
)


def _stamp(msg, t_log):
    """``(header stamp, bag time)`` in s: a message without a header has the bag's time as its
    stamp; a header stamp of 0 is kept as 0 (no time) for :func:`_clocked` to judge."""
    h = getattr(msg, "header", None)
    if h is not None:
        return h.stamp.sec + h.stamp.nanosec * 1e-9, t_log * 1e-9
    return t_log * 1e-9, t_log * 1e-9


def _clocked(rows, keep_missing: bool = False) -> np.ndarray:
    """A topic's rows ``(stamp, bag time, values...)`` as ``(time, values...)`` sorted by time,
    on one clock: the header stamps where the topic has any (a stamp of 0 among them is a
    missing time: NaN, last, and left out unless ``keep_missing``, never the bag's wall-clock
    time, which sorted it after every other message), the bag's times where it has none."""
    a = np.array(rows, float)
    stamped = a[:, 0] > 0
    t = np.where(stamped, a[:, 0], np.nan) if stamped.any() else a[:, 1]
    out = np.column_stack([t, a[:, 2:]])[np.argsort(t, kind="stable")]
    return out if keep_missing else out[np.isfinite(out[:, 0])]


def _pick(conns, types, wanted, what, path, required):
    cands = [c for c in conns if c.msgtype in types]
    if wanted is not None:
        cands = [c for c in conns if c.topic == wanted]
        if not cands:
            raise ReaderError(f"{path}: no topic {wanted!r}; topics: {', '.join(sorted({c.topic for c in conns}))}")
        return cands[0]
    topics = sorted({c.topic for c in cands})
    if len(topics) > 1:
        raise ReaderError(f"{path}: several {what} topics ({', '.join(topics)}); choose one with --topic")
    if not cands:
        if required:
            raise ReaderError(f"{path}: no {what} topic (message types {', '.join(types[:1])})")
        return None
    return cands[0]


def _pose_of(msg):
    if hasattr(msg, "pose") and hasattr(msg.pose, "pose"):  # Odometry, PoseWithCovarianceStamped
        p = msg.pose.pose
    elif hasattr(msg, "pose"):
        p = msg.pose
    else:  # TransformStamped
        tr = msg.transform
        return (tr.translation.x, tr.translation.y, tr.translation.z), tr.rotation
    return (p.position.x, p.position.y, p.position.z), p.orientation


def _imu_orientation(orient, t) -> np.ndarray | None:
    """The IMU messages' own orientation (the driver's or autopilot's estimate, ENU/FLU by
    REP 145) on the IMU's rows in NED/FRD, where it is given and a unit quaternion; else None."""
    if not orient:
        return None
    o = _clocked(orient)
    norm = np.linalg.norm(o[:, 1:5], axis=1)
    o = o[np.abs(norm - 1.0) < 0.01]
    if len(o) < 2:
        return None
    return quat_enu_flu_to_ned_frd(resample_quat(o[:, 0], o[:, 1:5], t))


def px4_types(folder) -> dict:
    """The message types of a px4_msgs ``msg/`` folder (``*.msg``), as rosbags registers them:
    for a bag that does not carry its definitions (ROS 2 Humble), from the PX4 version that
    recorded it (the layouts change between versions: quadest never guesses them)."""
    get_types_from_msg = need("rosbags.typesys", "reading a ROS bag").get_types_from_msg
    files = sorted(Path(folder).glob("*.msg"))
    if not files:
        raise ReaderError(f"{folder}: no .msg files (give px4_msgs's msg/ folder of the PX4 that recorded the bag)")
    types = {}
    for f in files:
        types.update(get_types_from_msg(f.read_text(), f"px4_msgs/msg/{f.stem}"))
    return types


def _typestore(msgs):
    typesys = need("rosbags.typesys", "reading a ROS bag")
    store = typesys.get_typestore(typesys.Stores.LATEST)
    if msgs is not None:
        store.register(px4_types(msgs))
    return store


def read_rosbag(path, *, imu_topic=None, mag_topic=None, truth_topic=None, msgs=None):
    AnyReader = need("rosbags.highlevel", "reading a ROS bag").AnyReader
    p = Path(path)
    try:
        reader = AnyReader([p], default_typestore=_typestore(msgs))
        reader.open()
    except ReaderError:
        raise
    except Exception as exc:  # rosbags raises its own error types per format
        said = " ".join(str(exc).split())  # rosbags quotes a damaged message definition, newlines and all
        raise ReaderError(f"{path}: not a readable ROS bag ({type(exc).__name__}: {said[:300]})") from None
    if msgs is not None and not any(c.msgtype.startswith("px4_msgs/") for c in reader.connections):
        reader.close()
        raise UsageError(f"{path}: --msgs gives px4_msgs definitions, but the bag has no px4_msgs topic; leave it out")
    if not any(c.msgtype in IMU for c in reader.connections) and any(c.msgtype in PX4_IMU for c in reader.connections):
        with _closing(reader):
            return _read_px4_bag(reader, path, imu_topic, mag_topic, truth_topic)
    try:
        conns = reader.connections
        ci = _pick(conns, IMU, imu_topic, "sensor_msgs/Imu", path, True)
        cm = _pick(conns, MAG, mag_topic, "sensor_msgs/MagneticField", path, False)
        ct = _pick(conns, POSE, truth_topic, "pose or odometry", path, False)
        ca = _pick(conns, ACTUATORS, None, "mav_msgs/Actuators", path, False)
        imu, mag, pose, orient, act = [], [], [], [], []
        chosen = [c for c in (ci, cm, ct, ca) if c is not None]
        for conn, t_log, raw in reader.messages(connections=chosen):
            msg = reader.deserialize(raw, conn.msgtype)
            ts = _stamp(msg, t_log)  # a pair: header, bag
            if conn is ci or conn.topic == ci.topic:
                w, a, o = msg.angular_velocity, msg.linear_acceleration, msg.orientation
                imu.append((*ts, w.x, w.y, w.z, a.x, a.y, a.z))
                if msg.orientation_covariance[0] != -1.0:  # REP 145: -1, no orientation given
                    orient.append((*ts, o.w, o.x, o.y, o.z))
            elif cm is not None and conn.topic == cm.topic:
                f = msg.magnetic_field
                mag.append((*ts, f.x, f.y, f.z))
            elif ca is not None and conn.topic == ca.topic:
                act.append((ts[0] if ts[0] > 0 else ts[1], msg.angular_velocities, msg.normalized))
            else:
                pos, o = _pose_of(msg)
                pose.append((*ts, o.w, o.x, o.y, o.z, *pos))
    except ReaderError:
        raise
    except Exception as exc:
        raise ReaderError(f"{path}: ROS bag broken ({type(exc).__name__}: {exc})") from None
    finally:
        reader.close()
    if not imu:
        raise ReaderError(f"{path}: the IMU topic {ci.topic} has no messages")
    imu = _clocked(imu, keep_missing=True)  # a missing time: dropped and counted with the rows
    t = imu[:, 0]
    magv = None
    if mag:
        mag = _clocked(mag)
        magv = mag_on_imu_rows(t, mag[:, 0], vec_flu_to_frd(mag[:, 1:4] * 1e6))
    truth = {}
    if pose:
        pose = _clocked(pose)
        truth["true_q"] = quat_enu_flu_to_ned_frd(resample_quat(pose[:, 0], pose[:, 1:5], t))
        inside = np.isfinite(truth["true_q"][:, 0])
        pos = np.full((len(t), 3), np.nan)
        pos[inside] = vec_enu_to_ned(
            np.column_stack([np.interp(t[inside], pose[:, 0], pose[:, 5 + i]) for i in range(3)])
        )
        truth["true_pos"] = pos
    ref = _imu_orientation(orient, t)
    if ref is not None:
        truth["ref_q"] = ref
    rotor_channels, rotors = _actuators(act, t, ca)
    truth.update(rotor_channels)
    meta = {
        "source_format": "ROS bag",
        "reference": f"{ci.topic}'s own orientation (the driver's estimate) as ref_q" if ref is not None else "none",
        "units": {"gyr": "rad/s", "acc": "m/s^2", "mag": "uT"},
        "frames": "REP 103: ENU world, FLU body -> NED/FRD; tesla -> µT",
        "topics": {"imu": ci.topic, "mag": cm.topic if cm else None, "truth": ct.topic if ct else None},
        **({"rotors": rotors} if rotors else {}),
    }
    return make_recording(
        path, "rosbag", t, vec_flu_to_frd(imu[:, 1:4]), vec_flu_to_frd(imu[:, 4:7]), magv, meta, **truth
    )


def _actuators(act, t, conn) -> tuple[dict, dict | None]:
    """``mav_msgs/Actuators`` messages ``(time, angular_velocities, normalized)`` as the rotor
    channels on the IMU's rows ``t``: the speeds' magnitudes (rad/s) and the commands (its
    ``normalized``, clipped to [0, 1]), each where every message has one value per rotor."""
    out, sources, rates = {}, {}, {}
    if not act:
        return {}, None
    times = np.array([a[0] for a in act], float)
    for k, (name, what) in enumerate((("rotor_speed", "angular_velocities"), ("motor_command", "normalized"))):
        counts = {len(a[1 + k]) for a in act}
        if len(counts) == 1 and counts != {0}:
            values = np.array([np.asarray(a[1 + k], float) for a in act])
            values = np.abs(values) if name == "rotor_speed" else np.clip(values, 0.0, 1.0)
            out[name] = on_rows(t, times, values)
            sources[name], rates[name] = f"{conn.topic} ({what})", rate_hz(times)
    counts = {v.shape[1] for v in out.values()}
    if not out or len(counts) > 1:
        return {}, None
    meta = rotor_meta(counts.pop(), numbering="the Actuators message's order", sources=sources, rates=rates)
    return out, meta


@contextmanager
def _closing(reader):
    try:
        yield reader
    finally:
        reader.close()


def _px4_messages(reader, conn, path):
    """Every message of ``conn``, deserialised; a type the bag does not define is one line."""
    try:
        for c, _, raw in reader.messages(connections=[conn]):
            yield reader.deserialize(raw, c.msgtype)
    except Exception as exc:
        why = str(exc).splitlines()[0] if str(exc) else ""
        raise ReaderError(
            f"{path}: cannot read {conn.msgtype} ({type(exc).__name__}: {why}); a bag without its message "
            "definitions (ROS 2 Humble) needs the px4_msgs msg/ folder of the PX4 that recorded it: --msgs PATH"
        ) from None


def _read_px4_bag(reader, path, imu_topic, mag_topic, truth_topic):
    """A ROS 2 bag of PX4's uXRCE-DDS topics: SensorCombined as the IMU, VehicleMagnetometer
    (gauss), VehicleAttitude's (else VehicleOdometry's) quaternion as ``ref_q``. PX4 keeps its own
    NED / FRD frames and its own time (``timestamp``, µs since boot) on the bridge: no conversion."""
    conns = reader.connections
    ci = _pick(conns, PX4_IMU, imu_topic, "px4_msgs SensorCombined", path, True)
    cm = _pick(conns, PX4_MAG, mag_topic, "px4_msgs VehicleMagnetometer", path, False)
    attitude = [c for c in conns if c.msgtype == PX4_ATTITUDE[0]] or conns  # VehicleAttitude first
    ca = _pick(attitude, PX4_ATTITUDE, truth_topic, "PX4 attitude", path, False)
    imu = np.array(
        sorted((m.timestamp, *m.gyro_rad, *m.accelerometer_m_s2) for m in _px4_messages(reader, ci, path)), float
    )
    if not len(imu):
        raise ReaderError(f"{path}: the IMU topic {ci.topic} has no messages")
    t = imu[:, 0] * 1e-6
    magv, truth = None, {}
    if cm is not None:
        m = np.array(sorted((m.timestamp, *m.magnetometer_ga) for m in _px4_messages(reader, cm, path)), float)
        magv = mag_on_imu_rows(t, m[:, 0] * 1e-6, m[:, 1:4] * 100.0) if len(m) else None
    if ca is not None:
        q = np.array(sorted((m.timestamp, *m.q) for m in _px4_messages(reader, ca, path)), float)
        if len(q) > 1:
            truth["ref_q"] = resample_quat(q[:, 0] * 1e-6, q[:, 1:5], t)
    meta = {
        "source_format": "ROS 2 bag of PX4 topics (px4_msgs)",
        "units": {"gyr": "rad/s", "acc": "m/s^2", "mag": "uT"},
        "frames": "NED/FRD (PX4's own, kept on the ROS 2 bridge)",
        "reference": f"{ca.topic} ({ca.msgtype.split('/')[-1]}, PX4's EKF2) as ref_q" if ca else "none",
        "topics": {"imu": ci.topic, "mag": cm.topic if cm else None, "truth": ca.topic if ca else None},
    }
    return make_recording(path, "rosbag", t, imu[:, 1:4], imu[:, 4:7], magv, meta, **truth)
