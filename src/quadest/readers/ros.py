"""ROS 1 (.bag) and ROS 2 (folder with metadata.yaml, .db3 or .mcap) bags via rosbags.

ROS follows REP 103 / 145: IMU and magnetometer in the sensor's body frame with z up (FLU),
orientation of a pose relative to an ENU world, magnetic field in tesla. quadest converts to
FRD / NED and µT (docs/readers.md). Topics are found by message type; with several candidates
give ``imu_topic`` / ``mag_topic`` / ``truth_topic``."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from quadest.extras import need
from quadest.readers.common import ReaderError, mag_on_imu_rows, make_recording, resample_quat
from quadest.rotation.frames import quat_enu_flu_to_ned_frd, vec_enu_to_ned, vec_flu_to_frd

IMU = ("sensor_msgs/msg/Imu", "sensor_msgs/Imu")
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
    h = getattr(msg, "header", None)
    if h is not None:
        s = h.stamp.sec + h.stamp.nanosec * 1e-9
        if s > 0:
            return s
    return t_log * 1e-9


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


def read_rosbag(path, *, imu_topic=None, mag_topic=None, truth_topic=None, **_):
    AnyReader = need("rosbags.highlevel", "reading a ROS bag").AnyReader
    typesys = need("rosbags.typesys", "reading a ROS bag")
    Stores, get_typestore = typesys.Stores, typesys.get_typestore

    p = Path(path)
    try:
        reader = AnyReader([p], default_typestore=get_typestore(Stores.LATEST))
        reader.open()
    except Exception as exc:  # rosbags raises its own error types per format
        raise ReaderError(f"{path}: not a readable ROS bag ({type(exc).__name__}: {exc})") from None
    try:
        conns = reader.connections
        ci = _pick(conns, IMU, imu_topic, "sensor_msgs/Imu", path, True)
        cm = _pick(conns, MAG, mag_topic, "sensor_msgs/MagneticField", path, False)
        ct = _pick(conns, POSE, truth_topic, "pose or odometry", path, False)
        imu, mag, pose = [], [], []
        chosen = [c for c in (ci, cm, ct) if c is not None]
        for conn, t_log, raw in reader.messages(connections=chosen):
            msg = reader.deserialize(raw, conn.msgtype)
            ts = _stamp(msg, t_log)
            if conn is ci or conn.topic == ci.topic:
                w, a = msg.angular_velocity, msg.linear_acceleration
                imu.append((ts, w.x, w.y, w.z, a.x, a.y, a.z))
            elif cm is not None and conn.topic == cm.topic:
                f = msg.magnetic_field
                mag.append((ts, f.x, f.y, f.z))
            else:
                pos, o = _pose_of(msg)
                pose.append((ts, o.w, o.x, o.y, o.z, *pos))
    except ReaderError:
        raise
    except Exception as exc:
        raise ReaderError(f"{path}: ROS bag broken ({type(exc).__name__}: {exc})") from None
    finally:
        reader.close()
    if not imu:
        raise ReaderError(f"{path}: the IMU topic {ci.topic} has no messages")
    imu = np.array(sorted(imu), float)
    t = imu[:, 0]
    magv = None
    if mag:
        mag = np.array(sorted(mag), float)
        magv = mag_on_imu_rows(t, mag[:, 0], vec_flu_to_frd(mag[:, 1:4] * 1e6))
    truth = {}
    if pose:
        pose = np.array(sorted(pose), float)
        truth["true_q"] = quat_enu_flu_to_ned_frd(resample_quat(pose[:, 0], pose[:, 1:5], t))
        inside = np.isfinite(truth["true_q"][:, 0])
        pos = np.full((len(t), 3), np.nan)
        pos[inside] = vec_enu_to_ned(
            np.column_stack([np.interp(t[inside], pose[:, 0], pose[:, 5 + i]) for i in range(3)])
        )
        truth["true_pos"] = pos
    meta = {
        "source_format": "ROS bag",
        "units": {"gyr": "rad/s", "acc": "m/s^2", "mag": "uT"},
        "frames": "REP 103: ENU world, FLU body -> NED/FRD; tesla -> µT",
        "topics": {"imu": ci.topic, "mag": cm.topic if cm else None, "truth": ct.topic if ct else None},
    }
    return make_recording(
        path, "rosbag", t, vec_flu_to_frd(imu[:, 1:4]), vec_flu_to_frd(imu[:, 4:7]), magv, meta, **truth
    )
