"""Readers: every format is written here from a simulated flight in that format's own
frames and units, read back, and compared with the simulation (which is in quadest's); broken
files give one clear line; the real samples in ../shared/data are read when present."""

import os
from pathlib import Path

import numpy as np
import pytest
from logwriters import write_dataflash, write_ulog

from quadest.cli.main import main
from quadest.readers import ReaderError, detect_format, read_recording
from quadest.readers.common import reason
from quadest.rotation import angle_between, quat_mul, quat_rotate
from quadest.rotation.frames import quat_ned_frd_to_enu_flu, vec_frd_to_flu, vec_ned_to_enu
from quadest.sim import simulate

DATA = Path(os.environ.get("QUADEST_DATA", Path(__file__).resolve().parents[3] / "shared" / "data"))
needs_data = pytest.mark.skipif(
    not DATA.is_dir(), reason=f"real recordings not found at {DATA} (set QUADEST_DATA to their folder)"
)
FLOAT32 = 2e-6  # relative precision of formats that store float32


@pytest.fixture(scope="module")
def flight():
    """10 s of simulated flight, magnetometer on every IMU sample, at 200 Hz."""
    return simulate("nominal", "bebop2", seed=11, duration=10.0, overrides={"imu.rate_hz": 200.0, "mag.rate_hz": 200.0})


def _cli_error(argv) -> tuple[int, str]:
    """The exit code and stderr of a command."""
    import contextlib
    import io

    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main(argv)
    return code, err.getvalue()


def _same(rec, ref, tol=1e-9, q_tol=1e-9, fields=("gyr", "acc")):
    """The same samples at the same intervals (a file's own time may start anywhere: it is kept)."""
    assert len(rec) == len(ref)
    assert np.allclose(rec.t - rec.t[0], ref.t - ref.t[0], atol=1e-6)
    for f in fields:
        assert np.allclose(getattr(rec, f), getattr(ref, f), atol=tol * 20, rtol=tol), f
    if rec.true_q is not None:
        ok = np.isfinite(rec.true_q[:, 0])
        assert angle_between(rec.true_q[ok], ref.true_q[ok]).max() < q_tol


# -- generic CSV -------------------------------------------------------------------------------------------
def test_generic_csv_with_units_frames_and_order(tmp_path, flight):
    p = tmp_path / "log.csv"
    g = np.degrees(vec_frd_to_flu(flight.gyr))
    a = vec_frd_to_flu(flight.acc) / 9.80665
    m = vec_frd_to_flu(flight.mag) / 100.0  # gauss
    q = quat_ned_frd_to_enu_flu(flight.true_q)[:, [1, 2, 3, 0]]  # x y z w
    cols = np.column_stack([(flight.t + 100.0) * 1000.0, g, a, m, q])
    header = "time_ms,gx,gy,gz,ax,ay,az,mx,my,mz,qx,qy,qz,qw"
    np.savetxt(p, cols, delimiter=",", header=header, comments="", fmt="%.17g")
    opts = [
        "--format",
        "csv",
        "--map",
        "t=time_ms",
        "--map",
        "gyr=gx,gy,gz",
        "--map",
        "acc=ax,ay,az",
        "--map",
        "mag=mx,my,mz",
        "--map",
        "true_q=qx,qy,qz,qw",
        "--units",
        "t=ms",
        "--units",
        "gyr=deg/s",
        "--units",
        "acc=g",
        "--units",
        "mag=gauss",
        "--frame",
        "enu-flu",
        "--quat-order",
        "xyzw",
    ]
    from quadest.cli.common import read
    from quadest.cli.main import build_parser

    args = build_parser().parse_args(["info", str(p), *opts])
    rec = read(args, p)
    _same(rec, flight, tol=1e-9)
    assert np.allclose(rec.mag, flight.mag, atol=1e-9)
    assert rec.meta["t0_s"] == pytest.approx(100.0) and rec.t[0] == pytest.approx(100.0)  # the file's own time
    out = tmp_path / "att.csv"
    assert main(["estimate", str(p), "--filter", "madgwick", "-o", str(out), *opts]) == 0
    assert out.read_text().splitlines()[0] == "t,q_w,q_x,q_y,q_z,roll,pitch,yaw"


def test_generic_csv_errors(tmp_path, capsys):
    p = tmp_path / "x.csv"
    p.write_text("a,b\n1,2\n")
    with pytest.raises(ReaderError, match="quadest's own; say which columns"):
        read_recording(p)
    with pytest.raises(ReaderError, match="needs the column mapping for t, gyr, acc"):
        read_recording(p, "csv")
    with pytest.raises(ReaderError, match="no column 'gx'"):
        read_recording(p, "csv", columns={"t": "a", "gyr": ["gx", "gy", "gz"], "acc": ["a", "b", "a"]})
    code = main(["info", str(p), "--format", "csv", "--map", "gyr=a,b", "--map", "t=a"])
    err = capsys.readouterr().err
    assert code == 2 and "gyr needs 3 column(s)" in err and len(err.strip().splitlines()) == 1
    code = main(["info", str(p), "--format", "csv", "--map", "t=a", "--units", "gyr=rpm"])
    assert code == 2 and "unknown gyr unit 'rpm'" in capsys.readouterr().err


# -- benchmark formats --------------------------------------------------------------------------------------
def _broad_arrays(flight):
    q = quat_ned_frd_to_enu_flu(flight.true_q)
    q[:20] = np.nan  # BROAD marks missing optical samples with NaN
    move = (flight.t > 2.0) & (flight.t < 8.0)
    return {
        "imu_gyr": vec_frd_to_flu(flight.gyr),
        "imu_acc": vec_frd_to_flu(flight.acc),
        "imu_mag": vec_frd_to_flu(flight.mag),
        "opt_quat": q,
        "movement": move,
        "opt_pos": np.zeros((len(flight), 3)),
    }


def write_broad(path, flight):
    import h5py

    with h5py.File(path, "w") as f:
        for k, v in _broad_arrays(flight).items():
            f[k] = v
        f.attrs["sampling_rate"] = 200.0
        f.attrs["info"] = "BROAD\n\nTrial: test\nundisturbed, test movements"


def test_broad_hdf5_and_mat(tmp_path, flight):
    from scipy.io import savemat

    h5, mat = tmp_path / "01_test.hdf5", tmp_path / "01_test.mat"
    write_broad(h5, flight)
    savemat(mat, {**_broad_arrays(flight), "sampling_rate": 200.0})
    for p in (h5, mat):
        assert detect_format(p) == "broad"
        rec = read_recording(p)
        _same(rec, flight, tol=1e-9)
        assert np.isnan(rec.true_q[:20]).all()
        assert rec.meta["evaluate_intervals_s"] == [[pytest.approx(2.005), pytest.approx(7.995)]]


def test_dido_and_blackbird(tmp_path, flight):
    import h5py

    dido = tmp_path / "circle.hdf5"
    with h5py.File(dido, "w") as f:
        f["ts"] = flight.t + 1.6e9
        f["gyr"] = vec_frd_to_flu(flight.gyr)
        f["acc"] = vec_frd_to_flu(flight.acc)
        f["gt_q"] = quat_ned_frd_to_enu_flu(flight.true_q)
        f["gt_p"] = vec_ned_to_enu(flight.true_pos)
        f["gt_v"] = vec_ned_to_enu(flight.true_vel)
        f["gt_gyr"] = vec_frd_to_flu(flight.true_gyr)
    assert detect_format(dido) == "dido"
    rec = read_recording(dido)
    _same(rec, flight, tol=1e-9)
    assert np.allclose(rec.true_vel, flight.true_vel) and rec.mag_rate_hz() == 0
    # Blackbird keeps the IMU's own axes as body; its world is z-up (here ENU)
    bb = tmp_path / "clover"
    bb.mkdir()
    with h5py.File(bb / "data.hdf5", "w") as f:
        f["ts"] = flight.t + 1.5e9
        f["gyro_raw"] = f["gyro_calib"] = flight.gyr
        f["accel_raw"] = f["accel_calib"] = flight.acc
    from quadest.rotation.frames import quat_mul

    S = np.sqrt(0.5)
    q_enu_frd = quat_mul(np.array([0.0, S, S, 0.0]), flight.true_q)
    gt = np.column_stack(
        [flight.t + 1.5e9, vec_ned_to_enu(flight.true_pos), q_enu_frd[:, [1, 2, 3, 0]], vec_ned_to_enu(flight.true_vel)]
    )
    np.savetxt(bb / "stamped_groundtruth_imu.txt", gt, header="ts x y z qx qy qz qw", fmt="%.12f")
    assert detect_format(bb) == "blackbird"
    rec = read_recording(bb)
    _same(rec, flight, tol=1e-9, q_tol=1e-6)
    assert np.allclose(rec.true_pos, flight.true_pos, atol=1e-6)


def test_repoimu_zero_quaternions_have_no_truth(tmp_path, flight):
    p = tmp_path / "TStick_Test99.csv"
    q = quat_ned_frd_to_enu_flu(flight.true_q)
    q[5:9] = 0.0
    rows = np.column_stack(
        [flight.t + 0.08, q, vec_frd_to_flu(flight.acc), vec_frd_to_flu(flight.gyr), vec_frd_to_flu(flight.mag) / 48.0]
    )
    with open(p, "w") as f:
        f.write("Time (s);Vicon Orientation;;;;IMU Acceleration;;;IMU Gyroscope;;;IMU Magnetometer;;;\n")
        f.write(";W;X;Y;Z;X;Y;Z;X;Y;Z;X;Y;Z;\n")
        for r in rows:
            f.write(";".join(f"{v:.10g}" for v in r) + ";\n")
    assert detect_format(p) == "repoimu"
    rec = read_recording(p)
    _same(rec, flight, tol=1e-8, q_tol=1e-8)
    assert np.isnan(rec.true_q[5:9]).all() and rec.meta["rows_without_truth"] == 4
    assert rec.meta["units"]["mag"] == "normalised" and rec.meta["align"] == {"nav": "heading", "body": True}


# -- ROS bags --------------------------------------------------------------------------------------------
def _ros_msgs(ts, flight, ros1, orientation=True):
    """Imu (with the true orientation as the driver's own when ``orientation``; REP 145's −1
    covariance when not), MagneticField and PoseStamped messages of ``flight``."""
    T = ts.types
    out = []
    for k in range(len(flight)):
        sec = 1000 + flight.t[k]
        stamp = T["builtin_interfaces/msg/Time"](sec=int(sec), nanosec=int(round((sec % 1) * 1e9)))
        hdr = (
            T["std_msgs/msg/Header"](seq=k, stamp=stamp, frame_id="imu")
            if ros1
            else T["std_msgs/msg/Header"](stamp=stamp, frame_id="imu")
        )
        V = T["geometry_msgs/msg/Vector3"]
        w, a, m = vec_frd_to_flu(flight.gyr[k]), vec_frd_to_flu(flight.acc[k]), vec_frd_to_flu(flight.mag[k]) * 1e-6
        q = quat_ned_frd_to_enu_flu(flight.true_q[k])
        Q = T["geometry_msgs/msg/Quaternion"](x=q[1], y=q[2], z=q[3], w=q[0])
        imu = T["sensor_msgs/msg/Imu"](
            header=hdr,
            orientation=Q if orientation else T["geometry_msgs/msg/Quaternion"](x=0, y=0, z=0, w=1),
            orientation_covariance=np.zeros(9) if orientation else np.full(9, -1.0),
            angular_velocity=V(x=w[0], y=w[1], z=w[2]),
            angular_velocity_covariance=np.zeros(9),
            linear_acceleration=V(x=a[0], y=a[1], z=a[2]),
            linear_acceleration_covariance=np.zeros(9),
        )
        mag = T["sensor_msgs/msg/MagneticField"](
            header=hdr, magnetic_field=V(x=m[0], y=m[1], z=m[2]), magnetic_field_covariance=np.zeros(9)
        )
        pose = T["geometry_msgs/msg/PoseStamped"](
            header=hdr,
            pose=T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=1.0), orientation=Q),
        )
        out.append((int(sec * 1e9), imu, mag, pose))
    return out


@pytest.mark.parametrize("ros1", [True, False])
def test_rosbag_round_trip(tmp_path, flight, ros1):
    from rosbags.typesys import Stores, get_typestore

    short = flight.select(slice(0, 400))
    if ros1:
        from rosbags.rosbag1 import Writer

        ts = get_typestore(Stores.ROS1_NOETIC)
        path = tmp_path / "flight.bag"
        ser = ts.serialize_ros1
        w = Writer(path)
    else:
        from rosbags.rosbag2 import Writer

        ts = get_typestore(Stores.ROS2_HUMBLE)
        path = tmp_path / "flight_bag"
        ser = ts.serialize_cdr
        w = Writer(path, version=8)
    with w:
        ci = w.add_connection("/imu/data", "sensor_msgs/msg/Imu", typestore=ts)
        cm = w.add_connection("/imu/mag", "sensor_msgs/msg/MagneticField", typestore=ts)
        cp = w.add_connection("/vicon/pose", "geometry_msgs/msg/PoseStamped", typestore=ts)
        for t_ns, imu, mag, pose in _ros_msgs(ts, short, ros1):
            w.write(ci, t_ns, ser(imu, "sensor_msgs/msg/Imu"))
            w.write(cm, t_ns, ser(mag, "sensor_msgs/msg/MagneticField"))
            w.write(cp, t_ns, ser(pose, "geometry_msgs/msg/PoseStamped"))
    assert detect_format(path) == "rosbag"
    rec = read_recording(path)
    assert rec.meta["topics"] == {"imu": "/imu/data", "mag": "/imu/mag", "truth": "/vicon/pose"}
    ref = short
    assert len(rec) == len(ref)
    assert np.allclose(rec.gyr, ref.gyr, atol=1e-12) and np.allclose(rec.acc, ref.acc, atol=1e-12)
    assert np.allclose(rec.t, 1000.0 + ref.t - ref.t[0], atol=2e-9)  # the bag's own time, kept
    assert np.allclose(rec.mag, ref.mag, atol=1e-9)
    assert angle_between(rec.true_q, ref.true_q).max() < 1e-6
    msgs = tmp_path / "msg"
    msgs.mkdir()
    (msgs / "SensorCombined.msg").write_text("uint64 timestamp\n")
    for argv, said in (
        (["--imu", "fifo"], "--imu does not apply to a rosbag file"),
        (["--msgs", str(msgs)], "--msgs gives px4_msgs definitions, but the bag has no px4_msgs topic"),
        (["--units", "gyr=deg/s"], "--units does not apply to a rosbag file"),
    ):
        code, err = _cli_error(["info", str(path), *argv])
        assert code == 2 and said in err and err.count("\n") == 1, err
    assert angle_between(rec.ref_q, ref.true_q).max() < 1e-6  # the Imu message's own orientation
    assert np.allclose(rec.true_pos, [0.0, 0.0, -1.0])


# -- PX4 ULog and ArduPilot DataFlash, written by hand from their specifications (tests/logwriters.py) -----
def test_logs_keep_their_own_time_and_declination(tmp_path, flight, capsys):
    """A log is read in its own time (an output joins its other topics) with the declination it
    stores; ArduPilot's reference is the EKF's quaternion (XKQ) where the log has it."""
    p = tmp_path / "log.ulg"
    write_ulog(p, flight, params={"EKF2_MAG_DECL": 10.5}, t0_us=20_330_000)
    rec = read_recording(p)
    assert rec.t[0] == pytest.approx(20.33, abs=1e-9) and rec.meta["t0_s"] == rec.t[0]
    assert rec.declination == pytest.approx(np.radians(10.5), rel=1e-6)
    assert main(["info", str(p)]) == 0
    assert "declination +10.50° (the log's EKF2_MAG_DECL)" in capsys.readouterr().out
    out = tmp_path / "att.csv"
    assert main(["estimate", str(p), "--filter", "madgwick", "-o", str(out)]) == 0
    assert "from 20.330 s; declination +10.50°" in capsys.readouterr().out
    t_out = np.loadtxt(out, delimiter=",", skiprows=1, usecols=0)
    assert np.allclose(t_out, rec.t)
    d = tmp_path / "log.bin"
    write_dataflash(d, flight, params={"COMPASS_DEC": 0.2}, xkq=True)
    rec = read_recording(d)
    assert rec.declination == pytest.approx(0.2, rel=1e-6) and rec.t[0] == pytest.approx(0.5)
    assert rec.meta["reference"].startswith("XKQ")
    ok = np.isfinite(rec.ref_q[:, 0])
    assert ok.mean() > 0.99 and angle_between(rec.ref_q[ok], flight.true_q[ok]).max() < 1e-3
    write_dataflash(d, flight)  # no XKQ, no COMPASS_DEC: ATT, and no declination
    rec = read_recording(d)
    assert rec.meta["reference"].startswith("ATT") and rec.declination == 0.0


def test_ulog_round_trip(tmp_path, flight):
    p = tmp_path / "log.ulg"
    write_ulog(p, flight)
    assert detect_format(p) == "ulog"
    rec = read_recording(p)
    assert len(rec) == len(flight)
    assert np.allclose(rec.gyr, flight.gyr, rtol=FLOAT32, atol=1e-6)
    assert np.allclose(rec.acc, flight.acc, rtol=FLOAT32, atol=1e-5)
    assert np.allclose(rec.mag, flight.mag, rtol=FLOAT32, atol=1e-4)  # gauss -> µT
    ok = np.isfinite(rec.ref_q[:, 0])
    assert ok.mean() > 0.99 and rec.true_q is None  # the onboard estimate is a reference, not truth
    assert angle_between(rec.ref_q[ok], flight.true_q[ok]).max() < 1e-3  # slerp between 50 Hz samples


def test_dataflash_round_trip(tmp_path, flight):
    p = tmp_path / "00000001.BIN"
    write_dataflash(p, flight)
    assert detect_format(p) == "dataflash"
    rec = read_recording(p)
    assert len(rec) == len(flight)
    assert np.allclose(rec.gyr, flight.gyr, rtol=FLOAT32, atol=1e-6)
    assert np.allclose(rec.mag, flight.mag, rtol=FLOAT32, atol=1e-4)  # milligauss -> µT
    assert angle_between(rec.ref_q, flight.true_q).max() < 1e-5
    assert "warnings" not in rec.meta


def test_a_damaged_dataflash_log_is_reported(tmp_path, flight):
    """Bytes overwritten in the middle of a log: pymavlink skips them (printing a line per
    byte); quadest reads the rest, prints nothing of pymavlink's, and says the log is damaged."""
    p = tmp_path / "00000002.BIN"
    write_dataflash(p, flight)
    data = bytearray(p.read_bytes())
    mid = len(data) // 2
    data[mid : mid + 300] = b"\x00" * 300
    p.write_bytes(bytes(data))
    rec = read_recording(p)
    assert 0 < len(rec) < len(flight)
    assert "the log is damaged" in rec.meta["warnings"][0]


def test_a_library_error_is_told_on_one_line():
    """A damaged log's names reach pymavlink's errors (a format named by four newlines): the
    reason quadest gives keeps the error's kind and words on one line."""
    assert reason(Exception("Unsupported format char: 'F' in message \n\n\n\n")) == (
        "Exception: Unsupported format char: 'F' in message"
    )


# -- broken files ---------------------------------------------------------------------------------------------
def test_broken_files_give_one_line(tmp_path, flight, capsys):
    good_h5 = tmp_path / "02_t.hdf5"
    write_broad(good_h5, flight)
    cases = {}
    cut = tmp_path / "cut.hdf5"
    cut.write_bytes(good_h5.read_bytes()[:5000])
    cases[cut] = "not a readable HDF5 file"
    junk = tmp_path / "junk.ulg"
    noise = np.random.default_rng(3).bytes  # fixed junk: random bytes could by chance begin a valid record
    junk.write_bytes(b"ULog\x01\x12\x35\x01" + noise(64))
    cases[junk] = "ULog"
    junk_bin = tmp_path / "junk.bin"
    junk_bin.write_bytes(noise(100))
    cases[junk_bin] = "DataFlash"
    bag = tmp_path / "junk.bag"
    bag.write_bytes(b"#ROSBAG V2.0\n" + noise(50))
    cases[bag] = "ROS bag"
    other = tmp_path / "x.hdf5"
    import h5py

    with h5py.File(other, "w") as f:
        f["foo"] = np.zeros(3)
    cases[other] = "unknown layout"
    cases[tmp_path / "missing.bin"] = "no such file"
    cases[tmp_path / "x.xyz"] = "no such file"
    for path, msg in cases.items():
        code = main(["info", str(path)])
        err = capsys.readouterr().err
        assert code == 1, path
        assert msg in err and len(err.strip().splitlines()) == 1, (path, err)


def test_truncated_ulog_keeps_what_was_written(tmp_path, flight):
    """A log cut mid-message (power lost in flight): pyulog reads up to the cut without an
    error, and quadest keeps the complete samples before it (docs/readers.md) and says that the
    log was cut (pyulog does not: quadest walks the message framing itself)."""
    p = tmp_path / "cut.ulg"
    write_ulog(p, flight, truncate_at=20_000)
    rec = read_recording(p)
    assert 0 < len(rec) < len(flight)
    assert np.allclose(rec.gyr, flight.gyr[: len(rec)], rtol=FLOAT32, atol=1e-6)
    assert rec.meta["ulog_corrupt"] and "cut short" in rec.meta["warnings"][0]
    whole = tmp_path / "whole.ulg"
    write_ulog(whole, flight)
    assert "warnings" not in read_recording(whole).meta


# -- the real samples ----------------------------------------------------------------------------------------
def _specific_force_down(rec, q):
    """Mean specific force rotated into the navigation frame: -g along z when frames are right."""
    ok = np.isfinite(q[:, 0])
    return quat_rotate(q[ok], rec.acc[ok]).mean(axis=0)


REAL = [
    ("broad/02_undisturbed_slow_rotation_B.hdf5", "broad", "true_q", 0.1),
    ("dido/circle_a_1.5_v_2.5_r_1.5.hdf5", "dido", "true_q", 0.15),
    ("blackbird_clover/val", "blackbird", "true_q", 0.3),
    ("repoimu/TStick/TStick_Test02_Trial1.csv", "repoimu", "true_q", 0.3),
    ("px4_ulog/sample.ulg", "ulog", "ref_q", 0.2),
    ("ardupilot/good_hover1.BIN", "dataflash", "ref_q", 0.3),
]


@needs_data
@pytest.mark.parametrize("rel,fmt,truth,tol", REAL)
def test_real_files_are_in_quadest_conventions(rel, fmt, truth, tol, capsys):
    """The frames check: the measured specific force, rotated by the truth (or onboard
    reference) into the navigation frame, averages to [0, 0, −g] (NED, within ``tol`` m/s² per
    axis plus the files' own accelerometer bias and motion)."""
    path = DATA / rel
    assert detect_format(path) == fmt
    rec = read_recording(path)
    f = _specific_force_down(rec, getattr(rec, truth))
    assert np.abs(f[:2]).max() < tol + 0.1 and abs(f[2] + 9.81) < tol + 0.1, f
    assert main(["info", str(path)]) == 0
    assert "samples" in capsys.readouterr().out


@needs_data
def test_real_repoimu_rows_without_truth():
    rec = read_recording(DATA / "repoimu/TStick/TStick_Test01_Static.csv")
    raw = np.genfromtxt(
        DATA / "repoimu/TStick/TStick_Test01_Static.csv", delimiter=";", skip_header=2, usecols=range(1, 5)
    )
    zero = np.abs(raw).sum(axis=1) == 0
    assert np.isnan(rec.true_q[:, 0]).sum() == zero.sum()


@needs_data
def test_real_broad_movement_phases():
    rec = read_recording(DATA / "broad/05_undisturbed_slow_rotation_with_breaks_B.hdf5")
    import h5py

    with h5py.File(DATA / "broad/05_undisturbed_slow_rotation_with_breaks_B.hdf5") as f:
        move = f["movement"][()]
    from quadest.evaluation.runner import evaluation_mask

    assert np.array_equal(evaluation_mask(rec), move)
    assert len(rec.meta["evaluate_intervals_s"]) > 1  # breaks split the movement


@needs_data
def test_real_px4_our_filter_agrees_with_ekf2():
    """On PX4's own log, quadest's Madgwick stays within 1° roll/pitch RMS of the onboard EKF2."""
    from quadest.evaluation.compare import compare

    rec = read_recording(DATA / "px4_ulog/sample.ulg")
    report, _ = compare(rec, ["madgwick"], timing=False, t_from=5.0)
    assert report["against"] == "ref_q"
    rms = report["filters"]["madgwick"]["rms_deg"]
    assert rms["roll"] < 1.0 and rms["pitch"] < 1.0


def test_rosbag_odometry_as_truth(tmp_path, flight):
    """nav_msgs/Odometry as the truth topic (pose.pose), ROS 2, no magnetometer topic."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    short = flight.select(slice(0, 200))
    path = tmp_path / "odom_bag"
    with Writer(path, version=8) as w:
        ci = w.add_connection("/imu", "sensor_msgs/msg/Imu", typestore=ts)
        co = w.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=ts)
        for t_ns, imu, _, pose in _ros_msgs(ts, short, ros1=False, orientation=False):
            odom = T["nav_msgs/msg/Odometry"](
                header=pose.header,
                child_frame_id="base_link",
                pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose.pose, covariance=np.zeros(36)),
                twist=T["geometry_msgs/msg/TwistWithCovariance"](
                    twist=T["geometry_msgs/msg/Twist"](
                        linear=T["geometry_msgs/msg/Vector3"](x=0, y=0, z=0),
                        angular=T["geometry_msgs/msg/Vector3"](x=0, y=0, z=0),
                    ),
                    covariance=np.zeros(36),
                ),
            )
            w.write(ci, t_ns, ts.serialize_cdr(imu, "sensor_msgs/msg/Imu"))
            w.write(co, t_ns, ts.serialize_cdr(odom, "nav_msgs/msg/Odometry"))
    rec = read_recording(path)
    assert rec.meta["topics"] == {"imu": "/imu", "mag": None, "truth": "/odom"}
    assert not rec.has_mag
    assert angle_between(rec.true_q, short.true_q).max() < 1e-6
    assert rec.ref_q is None and rec.meta["reference"] == "none"  # covariance −1: no orientation given


def test_both_repoimu_headers_are_read(tmp_path):
    """RepoIMU's files come with two header variants ("Time (s);..." with a trailing ';', and
    "Time;Vicon Orientation;..." with a units row): both are detected and read alike."""
    from quadest.readers import detect_format, read_recording

    rows = [f"{0.01 * k};1;0;0;0;0;0;9.81;0.01;0;0;0.4;0;0.9" for k in range(50)]
    a = tmp_path / "a.csv"
    a.write_text(
        "Time (s);Vicon Orientation;;;;IMU Acceleration;;;IMU Gyroscope;;;IMU Magnetometer;;;\n"
        ";W;X;Y;Z;X;Y;Z;X;Y;Z;X;Y;Z;\n" + "\n".join(r + ";" for r in rows) + "\n"
    )
    b = tmp_path / "b.csv"
    b.write_text(
        "Time;Vicon Orientation;;;;IMU Acceleration;;;IMU Gyroscope;;;IMU Magnetometer;;\n"
        "s;W;X;Y;Z;X;Y;Z;X;Y;Z;X;Y;Z\n" + "\n".join(rows) + "\n"
    )
    ra, rb = (read_recording(p) for p in (a, b))
    assert detect_format(a) == detect_format(b) == "repoimu"
    assert len(ra) == len(rb) == 50 and np.array_equal(ra.gyr, rb.gyr) and np.array_equal(ra.true_q, rb.true_q)


# -- ASL (EuRoC / TUM-VI) ----------------------------------------------------------------------------------
def _write_asl(root: Path, flight, truth: str):
    """A folder in the ASL layout: mav0/imu0/data.csv and the ground truth (``truth``: EuRoC's
    state_groundtruth_estimate0 or TUM-VI's mocap0) at half the IMU's rate, nanosecond stamps
    from 1.4e18, a z-up world."""
    mav = root / "mav0"
    (mav / "imu0").mkdir(parents=True)
    ns = 1_403_636_579_758_555_392 + np.round(flight.t * 1e9).astype(np.int64)
    with open(mav / "imu0" / "data.csv", "w") as f:
        f.write("#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y,w_RS_S_z,a_RS_S_x [m s^-2],a_RS_S_y,a_RS_S_z\n")
        for k in range(len(flight)):
            f.write(f"{ns[k]}," + ",".join(repr(float(v)) for v in (*flight.gyr[k], *flight.acc[k])) + "\n")
    (mav / truth).mkdir()
    q_up = quat_ned_frd_to_enu_flu(flight.true_q)  # a z-up world; the body kept FRD below
    q_up = quat_mul(q_up, np.array([0.0, 1.0, 0.0, 0.0]))  # undo the FLU body: ENU world, FRD body
    pos = vec_ned_to_enu(flight.true_pos)
    with open(mav / truth / "data.csv", "w") as f:
        f.write("#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z []\n")
        for k in range(0, len(flight), 2):
            f.write(f"{ns[k]}," + ",".join(repr(float(v)) for v in (*pos[k], *q_up[k])) + "\n")
    return mav


@pytest.mark.parametrize("truth", ["state_groundtruth_estimate0", "mocap0"])
def test_asl_folder(tmp_path, flight, truth):
    """The folder that holds mav0/ and mav0/ itself are read alike: the IMU in its own axes, the
    z-up truth turned to NED, the stamps in seconds of the file's own time."""
    mav = _write_asl(tmp_path / "seq", flight, truth)
    for path in (tmp_path / "seq", mav):
        assert detect_format(path) == "asl"
        rec = read_recording(path)
        _same(rec, flight, tol=1e-12, q_tol=2e-3)  # the truth at half the rate, slerped
        assert rec.t[0] == pytest.approx(1_403_636_579.758555, abs=1e-6)
        ok = np.isfinite(rec.true_q[:, 0])
        assert ok.sum() >= len(flight) - 1 and angle_between(rec.true_q[ok], flight.true_q[ok]).max() < 2e-3
        assert np.nanmax(np.abs(rec.true_pos - flight.true_pos)) < 0.01
        assert rec.meta["align"] == {"nav": "heading", "body": truth == "mocap0"}
    (mav / "imu0" / "data.csv").write_text("#timestamp\n1,2\n")
    with pytest.raises(ReaderError, match="at least 7 comma-separated columns"):
        read_recording(tmp_path / "seq")


def test_high_rate_imu_samples_of_a_log(tmp_path):
    """--imu fifo: PX4's sensor_gyro_fifo / sensor_accel_fifo and ArduPilot's GYR / ACC batch
    samples at their full rate, where the logged IMU keeps every fourth; info says they are there."""
    fast = simulate("nominal", "bebop2", seed=4, duration=2.0, overrides={"imu.rate_hz": 1000.0}).select(slice(2000))
    p, d = tmp_path / "fifo.ulg", tmp_path / "batch.bin"
    write_ulog(p, fast, fifo=True)
    write_dataflash(d, fast, batch=True)
    for path, quantum in ((p, 5e-3), (d, 1e-5)):
        logged, full = read_recording(path), read_recording(path, imu="fifo")
        assert len(logged) == len(fast) // 4 and len(full) == len(fast), path
        assert np.allclose(full.t - full.t[0], fast.t - fast.t[0], atol=1e-6)
        assert np.abs(full.gyr - fast.gyr).max() <= 1e-3 / 2 + 1e-5 and np.abs(full.acc - fast.acc).max() <= quantum
        assert logged.meta["imu_sources"] == ["logged", "fifo"] and full.meta["imu_source"] != logged.meta["imu_source"]
    assert main(["info", str(p)]) == 0
    with pytest.raises(ReaderError, match="no sensor_gyro_fifo / sensor_accel_fifo"):
        write_ulog(p, fast)
        read_recording(p, imu="fifo")


PX4_MSGS = {
    "SensorCombined": "uint64 timestamp\nfloat32[3] gyro_rad\nuint32 gyro_integral_dt\n"
    "int32 accelerometer_timestamp_relative\nfloat32[3] accelerometer_m_s2\nuint32 accelerometer_integral_dt\n"
    "uint8 accelerometer_clipping\nuint8 gyro_clipping\nuint8 accel_calibration_count\nuint8 gyro_calibration_count\n",
    "VehicleAttitude": "uint64 timestamp\nuint64 timestamp_sample\nfloat32[4] q\nfloat32[4] delta_q_reset\n"
    "uint8 quat_reset_counter\n",
    "VehicleMagnetometer": "uint64 timestamp\nuint64 timestamp_sample\nuint32 device_id\nfloat32[3] magnetometer_ga\n"
    "uint8 calibration_count\n",
}


def test_a_ros2_bag_of_px4_topics(tmp_path, flight):
    """PX4's uXRCE-DDS topics in a ROS 2 bag (px4_msgs): SensorCombined, VehicleMagnetometer and
    VehicleAttitude, read in PX4's own NED / FRD and its own time, with the definitions the bag
    carries or those of a px4_msgs msg/ folder."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    from quadest.readers.ros import px4_types

    msg = tmp_path / "px4_msgs" / "msg"
    msg.mkdir(parents=True)
    for name, text in PX4_MSGS.items():
        (msg / f"{name}.msg").write_text(text)
    ts = get_typestore(Stores.ROS2_HUMBLE)
    ts.register(px4_types(msg))
    T, short, path = ts.types, flight.select(slice(0, 400)), tmp_path / "px4_bag"
    with Writer(path, version=9) as w:
        conns = {n: w.add_connection(f"/fmu/out/{n}", f"px4_msgs/msg/{n}", typestore=ts) for n in PX4_MSGS}
        for k in range(len(short)):
            us = 7_000_000 + int(round(short.t[k] * 1e6))
            t_ns = 1_700_000_000_000_000_000 + 1000 * us  # the bag's receive time: not what is read
            g, a, q = (v[k].astype(np.float32) for v in (short.gyr, short.acc, short.true_q))
            sc = T["px4_msgs/msg/SensorCombined"](us, g, 0, 0, a, 0, 0, 0, 0, 0)
            w.write(conns["SensorCombined"], t_ns, ts.serialize_cdr(sc, "px4_msgs/msg/SensorCombined"))
            if k % 4 == 0:
                va = T["px4_msgs/msg/VehicleAttitude"](us, us, q, np.zeros(4, np.float32), 0)
                w.write(conns["VehicleAttitude"], t_ns, ts.serialize_cdr(va, "px4_msgs/msg/VehicleAttitude"))
                vm = T["px4_msgs/msg/VehicleMagnetometer"](us, us, 1, (short.mag[k] / 100).astype(np.float32), 0)
                w.write(conns["VehicleMagnetometer"], t_ns, ts.serialize_cdr(vm, "px4_msgs/msg/VehicleMagnetometer"))
    for options in ({}, {"msgs": msg}):
        rec = read_recording(path, **options)
        assert rec.t[0] == pytest.approx(7.0) and np.allclose(rec.t - rec.t[0], short.t, atol=1e-6)
        assert np.allclose(rec.gyr, short.gyr, rtol=FLOAT32, atol=1e-6)  # NED / FRD kept
        assert np.allclose(rec.acc, short.acc, rtol=FLOAT32, atol=1e-5)
        assert np.nanmax(np.abs(rec.mag - short.mag)) < 1e-3 and np.isfinite(rec.mag[::4, 0]).all()
        ok = np.isfinite(rec.ref_q[:, 0])
        assert ok.mean() > 0.98 and angle_between(rec.ref_q[ok], short.true_q[ok]).max() < 1e-3
        assert rec.meta["topics"]["imu"] == "/fmu/out/SensorCombined"
    with pytest.raises(ReaderError, match="no .msg files"):
        read_recording(path, msgs=tmp_path)


def test_real_logs_keep_their_time_and_declination():
    """On every autopilot log in the data folder: the time starts where the log's IMU does, the
    declination is the log's own, and where it is large it is what brings an estimate's heading
    onto the autopilot's (ArduPilot's SITL stores 12.65°), over the first 10 s (before a loss)."""
    from quadest.api import estimate, score
    from quadest.evaluation.runner import evaluation_mask

    logs = sorted(DATA.glob("px4_ulog/*.ulg")) + sorted(DATA.glob("ardupilot/*.[bB][iI][nN]"))
    if not logs:
        pytest.skip(f"no PX4 or ArduPilot logs under {DATA} (set QUADEST_DATA)")
    for path in logs:
        rec = read_recording(path)
        assert rec.t[0] > 1.0 and rec.meta["t0_s"] == rec.t[0], path.name  # seconds since boot
        assert rec.meta["declination_source"].startswith("the log's "), path.name
        if abs(rec.declination) > np.radians(5):
            first = evaluation_mask(rec) & (rec.t < rec.t[0] + 10.0)
            yaw = [score(rec, estimate(rec, declination=d), mask=first)["rms_deg"]["yaw"] for d in (None, 0.0)]
            assert yaw[0] < 0.5 * yaw[1], (path.name, yaw)


def test_a_z_up_csv_read_as_frd_draws_one_note(tmp_path):
    """A hover logged z-up (ROS's FLU) and read without --frame enu-flu: the command says, in one
    note on stderr, that the frame looks z-up and which option reads it; with the option, no note."""
    import subprocess
    import sys

    rest = simulate("nominal", "bebop2", seed=1, duration=5.0)
    p = tmp_path / "zup.csv"
    cols = np.column_stack([rest.t, vec_frd_to_flu(rest.gyr), vec_frd_to_flu(rest.acc)])
    np.savetxt(p, cols, delimiter=",", header="t,gx,gy,gz,ax,ay,az", comments="", fmt="%.17g")
    argv = [sys.executable, "-m", "quadest.cli.main", "info", str(p), "--format", "csv", "--map", "t=t"]
    argv += ["--map", "gyr=gx,gy,gz", "--map", "acc=ax,ay,az"]
    for frame, noted in (("ned-frd", True), ("enu-flu", False)):
        done = subprocess.run([*argv, "--frame", frame], capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, done.stderr
        notes = [line for line in done.stderr.splitlines() if "z-up" in line]
        assert len(notes) == noted and all(n.startswith("quadest: note: ") and "--frame enu-flu" in n for n in notes)


@pytest.mark.parametrize("rate", ["200", b"fast", np.array([200.0, 100.0]), -5.0, np.nan])
def test_a_broad_sampling_rate_that_is_not_one_positive_number_names_the_file(tmp_path, flight, rate):
    import h5py

    h5 = tmp_path / "01_test.hdf5"
    write_broad(h5, flight)
    with h5py.File(h5, "a") as f:
        f.attrs["sampling_rate"] = rate
    with pytest.raises(ReaderError, match=r"01_test\.hdf5: sampling_rate must be one positive number"):
        read_recording(h5)


def test_reference_times_out_of_order_are_left_out_not_an_interpolation_error():
    """scipy's Slerp refuses times that do not increase ("Times must be in strictly increasing
    order", no file named): rows whose time is not beyond every earlier one are left out."""
    from quadest.readers.common import resample_quat

    t_src = np.array([0.0, 5.0, 1.0, 2.0, np.nan, 6.0, 6.0, 7.0])
    q = np.tile([1.0, 0.0, 0.0, 0.0], (len(t_src), 1))
    out = resample_quat(t_src, q, np.array([0.5, 5.5, 6.5]), max_gap=10.0)
    assert np.allclose(out, [1.0, 0.0, 0.0, 0.0])
