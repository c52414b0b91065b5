"""Generated and damaged files: every reader and configuration loader either reads a
file or refuses it with a ValueError (ReaderError is one) naming it; never another exception, a
hang, or a recording with NaN where a value must be. Through the command line: one line, no
internal error."""

import json
import signal
from contextlib import contextmanager

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from quadest.calibration import load_calibration
from quadest.data import save_recording
from quadest.models.aero import AeroModel
from quadest.readers import read_recording
from quadest.readers.motors import read_motor_log
from quadest.rotation.frames import vec_frd_to_flu
from quadest.sim import build_config, simulate

FUZZ = settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow]
)


_ORIGINALS: dict = {}


def _originals():
    """Valid files to damage (made once; a module-level cache, so that hypothesis does not print
    them with every failing example)."""
    if _ORIGINALS:
        return _ORIGINALS
    import tempfile
    from pathlib import Path

    d = Path(tempfile.mkdtemp(prefix="quadest-fuzz-"))
    rec = simulate("hover", "bebop2", seed=3, duration=0.5)
    out = {
        "csv": save_recording(rec, d / "r.csv").read_bytes(),
        "parquet": save_recording(rec, d / "r.parquet").read_bytes(),
    }
    with h5py.File(d / "b.hdf5", "w") as f:  # a small BROAD-like file
        f.attrs["sampling_rate"] = 100.0
        n = 200
        f["imu_gyr"] = np.zeros((n, 3))
        f["imu_acc"] = np.tile([0.0, 0.0, 9.81], (n, 1))
        f["imu_mag"] = np.tile([20.0, 0.0, -40.0], (n, 1))
        f["opt_quat"] = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
        f["movement"] = np.ones(n)
    out["hdf5"] = (d / "b.hdf5").read_bytes()
    from scipy.io import savemat

    n = 200
    savemat(
        d / "b.mat",
        {
            "sampling_rate": 100.0,
            "imu_gyr": np.zeros((n, 3)),
            "imu_acc": np.tile([0.0, 0.0, 9.81], (n, 1)),
            "imu_mag": np.tile([20.0, 0.0, -40.0], (n, 1)),
            "opt_quat": np.tile([1.0, 0, 0, 0], (n, 1)),
            "movement": np.ones((n, 1)),
        },
    )
    out["mat"] = (d / "b.mat").read_bytes()
    # autopilot logs, written byte by byte as tests/unit/test_readers.py does
    from logwriters import write_dataflash, write_ulog

    short = simulate("hover", "bebop2", seed=4, duration=1.0, overrides={"imu.rate_hz": 100.0, "mag.rate_hz": 100.0})
    write_ulog(d / "l.ulg", short)
    write_dataflash(d / "l.bin", short)
    out["ulg"], out["bin"] = (d / "l.ulg").read_bytes(), (d / "l.bin").read_bytes()
    out["bag"] = _ros1_bag(d / "r.bag", short)
    _ORIGINALS.update(out)
    return out


def _ros1_bag(path, rec) -> bytes:
    """A small ROS 1 bag (rosbags' writer) of ``rec``'s IMU and field as sensor_msgs, in ROS's
    frames (FLU) and units (T): valid messages to damage."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    T = ts.types
    V, zeros = T["geometry_msgs/msg/Vector3"], np.zeros(9)
    with Writer(path) as w:
        ci = w.add_connection("/imu/data", "sensor_msgs/msg/Imu", typestore=ts)
        cm = w.add_connection("/imu/mag", "sensor_msgs/msg/MagneticField", typestore=ts)
        for k in range(0, len(rec), 2):
            ns = int(1e9 * (1000 + rec.t[k]))
            stamp = T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
            hdr = T["std_msgs/msg/Header"](seq=k, stamp=stamp, frame_id="imu")
            imu = T["sensor_msgs/msg/Imu"](
                header=hdr,
                orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                orientation_covariance=np.full(9, -1.0),
                angular_velocity=V(*vec_frd_to_flu(rec.gyr[k])),
                angular_velocity_covariance=zeros,
                linear_acceleration=V(*vec_frd_to_flu(rec.acc[k])),
                linear_acceleration_covariance=zeros,
            )
            mag = T["sensor_msgs/msg/MagneticField"](
                header=hdr, magnetic_field=V(*(vec_frd_to_flu(rec.mag[k]) * 1e-6)), magnetic_field_covariance=zeros
            )
            w.write(ci, ns, ts.serialize_ros1(imu, "sensor_msgs/msg/Imu"))
            w.write(cm, ns, ts.serialize_ros1(mag, "sensor_msgs/msg/MagneticField"))
    return path.read_bytes()


def _mutate(data: bytes, edits) -> bytes:
    b = bytearray(data)
    for kind, where, value in edits:
        if not b:
            break
        i = where % len(b)
        if kind == "flip":
            b[i] ^= value or 1
        elif kind == "cut":
            del b[i:]
        elif kind == "insert":
            b[i:i] = bytes([value]) * (1 + value % 7)
        elif kind == "delete":
            del b[i : i + 1 + value % 50]
    return bytes(b)


EDITS = st.lists(
    st.tuples(st.sampled_from(["flip", "cut", "insert", "delete"]), st.integers(0, 10**9), st.integers(0, 255)),
    min_size=1,
    max_size=4,
)


def _read_or_refuse(path, fmt=None):
    try:
        rec = read_recording(path, fmt)
    except ValueError as exc:
        assert str(exc).strip() and "\n" not in str(exc).strip(), repr(exc)
        return None
    assert np.isfinite(rec.t).all() and np.isfinite(rec.gyr).all() and np.isfinite(rec.acc).all()
    return rec


@contextmanager
def _ends_within(seconds):
    """A read that would never end fails the test instead of holding the suite (a guard, not a
    timing: these reads take milliseconds)."""

    def stop(*_):
        raise AssertionError(f"the read did not end within {seconds} s")

    old = signal.signal(signal.SIGALRM, stop)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


@pytest.mark.parametrize(
    ("edits", "said"),
    [
        ([("insert", 1517, 176), ("delete", 171308, 26), ("insert", 42556, 128), ("insert", 93, 0)], "header"),
        ([("flip", 128, 95), ("flip", 607, 59), ("insert", 5, 10), ("cut", 331373982, 163)], "format char"),
    ],
)
def test_damaged_dataflash_logs_the_fuzz_test_found(edits, said, tmp_path):
    """Two damaged logs this test once generated: in the first a format message declares a
    message of length 0 with no fields, and pymavlink read that one place of the log for ever;
    the second's error carried the damaged format name's newlines. Both are refused in one line
    naming the file, as recordings and as motor logs."""
    p = tmp_path / "x.bin"
    p.write_bytes(_mutate(_originals()["bin"], edits))
    for read in (lambda q: read_recording(q, "dataflash"), read_motor_log):
        with _ends_within(60), pytest.raises(ValueError) as exc:
            read(p)
        msg = str(exc.value)
        assert msg.startswith(str(p)) and said in msg and "\n" not in msg, msg


def test_a_bag_with_a_damaged_message_definition_is_refused_in_one_line(tmp_path):
    """Found by the test below: rosbags' error quotes the damaged definition, newlines and all."""
    data = _originals()["bag"]
    assert b"string frame_id" in data
    p = tmp_path / "x.bag"
    p.write_bytes(data.replace(b"string frame_id", b"strin\x7f frame_id"))
    with pytest.raises(ValueError) as exc:
        read_recording(p)
    msg = str(exc.value)
    assert msg.startswith(f"{p}: not a readable ROS bag") and "\n" not in msg and len(msg) < 500, msg


@pytest.mark.parametrize("kind", ["csv", "parquet", "hdf5", "ulg", "bin", "bag"])
@FUZZ
@given(edits=EDITS)
def test_damaged_recordings_are_read_or_refused(kind, edits, tmp_path):
    p = tmp_path / f"x.{kind}"
    p.write_bytes(_mutate(_originals()[kind], edits))
    _read_or_refuse(p, {"hdf5": "broad", "mat": "broad", "ulg": "ulog", "bin": "dataflash"}.get(kind))


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(edits=EDITS)
def test_damaged_mat_files_are_read_or_refused(edits, tmp_path):
    """MAT files are read in a child process: scipy's loadmat crashes the process on some
    damaged ones (a segmentation fault); quadest refuses them instead."""
    p = tmp_path / "x.mat"
    p.write_bytes(_mutate(_originals()["mat"], edits))
    _read_or_refuse(p, "broad")


@FUZZ
@given(text=st.text(st.characters(codec="utf-8"), max_size=400))
def test_generated_csv_text_is_read_or_refused(text, tmp_path):
    p = tmp_path / "g.csv"
    p.write_text("# quadest recording v2\n" + text)
    _read_or_refuse(p)
    q = tmp_path / "h.csv"
    q.write_text(text)
    try:
        read_recording(q, "csv", columns={"t": "t", "gyr": ["a", "b", "c"], "acc": ["d", "e", "f"]})
    except ValueError:
        pass


JSON = st.recursive(
    st.none() | st.booleans() | st.floats() | st.integers() | st.text(max_size=10),
    lambda c: st.lists(c, max_size=4) | st.dictionaries(st.text(max_size=12), c, max_size=5),
    max_leaves=25,
)


@FUZZ
@given(values=JSON, kind=st.sampled_from(["gyro", "accel", "mag", "centrifugal", "aero", "nope", 3]), unit=JSON)
def test_calibration_files_are_read_or_refused(values, kind, unit, tmp_path):
    p = tmp_path / "c.json"
    p.write_text(json.dumps({"format": "quadest calibration v1", "kind": kind, "unit": unit, "values": values}))
    try:
        load_calibration(p)
    except ValueError:
        pass
    p.write_text(json.dumps(values))
    with pytest.raises(ValueError):
        load_calibration(p)


@FUZZ
@given(doc=JSON)
def test_aero_model_files_are_read_or_refused(doc, tmp_path):
    p = tmp_path / "a.json"
    good = {
        "format": "quadest aero model v1",
        "A": np.eye(3).tolist(),
        "B": np.zeros((3, 3)).tolist(),
        "C": np.zeros((3, 10)).tolist(),
        "mass_kg": 0.5,
    }
    for d in (doc, {**good, "A": doc}, {**good, "mass_kg": doc}):
        p.write_text(json.dumps(d))
        try:
            AeroModel.load(p)
        except ValueError:
            pass


TOML_VALUE = st.one_of(
    st.integers(-(10**6), 10**6),
    st.floats(allow_nan=False),
    st.booleans(),
    st.text(st.characters(codec="ascii", exclude_characters='"\\\n'), max_size=8).map(json.dumps),
    st.lists(st.floats(-10, 10), max_size=4).map(lambda v: json.dumps(v)),
)


@FUZZ
@given(
    section=st.sampled_from(["gyro", "acc", "mag", "imu", "vehicle", "nope", "hover"]),
    key=st.sampled_from(["noise_std", "rate_hz", "range", "bias", "soft_iron", "mass_kg", "nope"]),
    value=TOML_VALUE,
    junk=st.text(max_size=30),
)
def test_simulator_toml_is_read_or_refused(section, key, value, junk, tmp_path):
    p = tmp_path / "c.toml"
    v = value if isinstance(value, str) else json.dumps(value)
    for text in (f"[{section}]\n{key} = {v}\n", f"[{section}]\n{key} = {v}\n{junk}"):
        p.write_text(text)
        try:
            build_config("bebop2", toml=p).validate()
        except ValueError:
            pass
