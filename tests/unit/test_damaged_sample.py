"""Autopilot logs read as they are: one implausible value or time is skipped and counted as a
NaN is, only a log whose values are implausible throughout is refused, naming the unit
(readers.common.make_recording); a ULog's second IMU is that IMU's; a missing value or time
is missing, not zeros nor the bag's clock (docs/reliability.md)."""

import struct
from types import SimpleNamespace

import h5py
import numpy as np
import pytest
from logwriters import _ulog_msg, write_dataflash, write_ulog

from quadest.readers import ReaderError, read_recording
from quadest.rotation.frames import vec_frd_to_flu
from quadest.sim import simulate

K = 150  # the damaged row


@pytest.fixture(scope="module")
def hover():
    return simulate("hover", "bebop2", seed=4, duration=3.0, overrides={"imu.rate_hz": 100.0, "mag.rate_hz": 100.0})


class _Flight(SimpleNamespace):
    def __len__(self):
        return len(self.t)


def _flight(rec, field=None, value=None):
    arrays = {k: np.array(getattr(rec, k)) for k in ("t", "gyr", "acc", "mag", "true_q")}
    if field == "t":
        arrays["t"][K] += value
    elif field is not None:
        arrays[field][K, 1] = value
    return _Flight(**arrays)


@pytest.mark.parametrize("writer, ext", [(write_dataflash, "bin"), (write_ulog, "ulg")])
@pytest.mark.parametrize(
    "field, value", [("gyr", 80.0), ("acc", 2000.0), ("t", 1000.0), ("gyr", np.nan)], ids=["gyr", "acc", "time", "nan"]
)
def test_one_implausible_sample_is_dropped_like_a_nan(hover, tmp_path, writer, ext, field, value):
    """Before: one gyroscope value of 80 rad/s refused the whole log ("is the gyroscope in
    deg/s?"), one of 2000 m/s² too, and one time jump ("is the file sorted by time?": every
    later row was behind it)."""
    path = tmp_path / f"log.{ext}"
    writer(path, _flight(hover, field, value))
    rec = read_recording(path)
    assert rec.meta["dropped_rows"] == 1 and len(rec) == len(hover) - 1
    assert np.allclose(rec.t - rec.t[0], np.delete(hover.t, K), atol=2e-6)
    assert np.allclose(rec.gyr, np.delete(hover.gyr, K, axis=0), atol=1e-5)


def test_a_log_implausible_throughout_is_refused_naming_the_unit(hover, tmp_path):
    flight = _flight(hover)
    flight.gyr = flight.gyr + 100.0  # every row beyond any gyroscope: a unit, not damage
    write_dataflash(tmp_path / "log.bin", flight)
    with pytest.raises(ReaderError, match="is the gyroscope in deg/s"):
        read_recording(tmp_path / "log.bin")


def _two_gyroscopes_ulog(path, rec):
    """sensor_combined (PX4's primary IMU, instance 0 only) and sensor_gyro / sensor_accel of
    instances 0 and 1; instance 1 reads twice the rates of instance 0."""
    vec = "uint64_t timestamp;float x;float y;float z;"
    formats = {"sensor_combined": "uint64_t timestamp;float[3] gyro_rad;float[3] accelerometer_m_s2;"}
    formats.update({"sensor_gyro": vec, "sensor_accel": vec})
    out = b"ULog\x01\x12\x35\x01" + struct.pack("<Q", 0) + _ulog_msg("B", bytes(16) + struct.pack("<3Q", 0, 0, 0))
    for name, fmt in formats.items():
        out += _ulog_msg("F", f"{name}:{fmt}".encode())
    subs = [("sensor_combined", 0), ("sensor_gyro", 0), ("sensor_gyro", 1), ("sensor_accel", 0), ("sensor_accel", 1)]
    for mid, (name, multi) in enumerate(subs):
        out += _ulog_msg("A", struct.pack("<BH", multi, mid) + name.encode())
    for k in range(len(rec)):
        us = 1_000_000 + int(round(rec.t[k] * 1e6))
        out += _ulog_msg("D", struct.pack("<HQ6f", 0, us, *rec.gyr[k], *rec.acc[k]))
        for mid, (name, multi) in enumerate(subs[1:], start=1):
            value = (rec.gyr[k] if name == "sensor_gyro" else rec.acc[k]) * (1 + multi)
            out += _ulog_msg("D", struct.pack("<HQ3f", mid, us, *value))
    path.write_bytes(out)


def test_a_ulogs_second_imu_is_that_instance(hover, tmp_path):
    """Before: instance=1 returned sensor_combined, instance 0's data, silently."""
    path = tmp_path / "two.ulg"
    rec = _flight(hover)
    rec.acc = rec.acc * 0.5  # instance 1's accelerometer (twice this) stays gravity-sized
    _two_gyroscopes_ulog(path, rec)
    first, second = read_recording(path), read_recording(path, instance=1)
    assert np.allclose(first.gyr, rec.gyr, atol=1e-5)
    assert np.allclose(second.gyr, 2 * rec.gyr, atol=1e-5) and np.allclose(second.acc, 2 * rec.acc, atol=1e-4)


def test_an_hdf5_dataset_never_written_is_missing_not_zeros(tmp_path):
    """Before: a BROAD file whose imu_gyr was declared but never written read as a gyroscope at
    rest (h5py's fill value)."""
    n, path = 200, tmp_path / "b.hdf5"
    with h5py.File(path, "w") as f:
        f.attrs["sampling_rate"] = 100.0
        f.create_dataset("imu_gyr", shape=(n, 3), dtype="f8")  # declared, never written
        f["imu_acc"] = np.tile([0.0, 0.0, 9.81], (n, 1))
        f["imu_mag"] = np.tile([20.0, 0.0, -40.0], (n, 1))
        f["opt_quat"] = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
        f["movement"] = np.ones(n)
    with pytest.raises(ReaderError, match="'imu_gyr' declares .* but none was ever written"):
        read_recording(path)


def test_a_ros2_imu_message_stamped_0_is_a_missing_time(hover, tmp_path):
    """Before: an IMU message whose header stamp is 0 took the bag's wall-clock time and was
    sorted after every other sample (a jump of decades); now it is dropped and counted."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    T, path = ts.types, tmp_path / "bag"
    V = T["geometry_msgs/msg/Vector3"]
    with Writer(path, version=8) as w:
        conn = w.add_connection("/imu", "sensor_msgs/msg/Imu", typestore=ts)
        for k in range(len(hover)):
            ns = 0 if k == K else int(1e9 * (100 + hover.t[k]))
            stamp = T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
            imu = T["sensor_msgs/msg/Imu"](
                header=T["std_msgs/msg/Header"](stamp=stamp, frame_id="imu"),
                orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                orientation_covariance=np.full(9, -1.0),
                angular_velocity=V(*vec_frd_to_flu(hover.gyr[k])),
                angular_velocity_covariance=np.zeros(9),
                linear_acceleration=V(*vec_frd_to_flu(hover.acc[k])),
                linear_acceleration_covariance=np.zeros(9),
            )
            w.write(
                conn, 1_700_000_000_000_000_000 + int(1e9 * hover.t[k]), ts.serialize_cdr(imu, "sensor_msgs/msg/Imu")
            )
    rec = read_recording(path)
    assert rec.meta["dropped_rows"] == 1 and len(rec) == len(hover) - 1
    assert np.allclose(rec.t, 100 + np.delete(hover.t, K), atol=1e-6)
