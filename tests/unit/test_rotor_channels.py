"""The rotors' channels of a Recording (rotor speeds, rad/s; motor commands, 0 to 1): their checks
and their files, each reader's on a small file written here (DIDO in both of its layouts, PX4
ULog, ArduPilot DataFlash, a ROS 1 bag, a CSV) against the values written, converted
independently; the real files of ../shared/data read when present; ``quadest info`` shows them."""

import contextlib
import io
import json
import math
import os
from pathlib import Path

import numpy as np
import pytest
from logwriters import write_dataflash, write_ulog

from quadest.cli.main import main
from quadest.data import Recording, load_recording, save_recording
from quadest.readers import read_recording

DATA = Path(os.environ.get("QUADEST_DATA", Path(__file__).resolve().parents[3] / "shared" / "data"))
RAD_S_PER_RPM = 2.0 * math.pi / 60.0  # one revolution a minute
N = 400
RATE = 200.0


@pytest.fixture(scope="module")
def flight():
    """2 s of a level vehicle turning slowly about each axis at 200 Hz (what the readers convert;
    no simulator needed), its magnetometer on every sample."""
    t = np.arange(N) / RATE
    gyr = 0.2 * np.column_stack([np.sin(t), np.cos(2 * t), np.sin(3 * t)])
    acc = np.tile([0.0, 0.0, -9.80665], (N, 1)) + 0.01 * gyr
    mag = np.tile([20.0, 1.0, 40.0], (N, 1))
    q = np.tile([1.0, 0.0, 0.0, 0.0], (N, 1))
    return Recording(t, gyr, acc, mag, true_q=q, meta={"units": {"mag": "uT"}})


def _speeds_rpm(n=N):
    """Four rotors' rpm, each its own slow wave about a hover's 14 000 rpm."""
    t = np.arange(n) / RATE
    return 14000.0 + 500.0 * np.sin(t[:, None] * np.array([1.0, 2.0, 3.0, 4.0]))


def _rec(**kw):
    t = np.arange(50) * 0.01
    return Recording(t, np.zeros((50, 3)), np.tile([0.0, 0.0, -9.81], (50, 1)), **kw)


# -- the Recording ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("ext", ["csv", "parquet"])
def test_rotor_channels_round_trip_through_files(tmp_path, ext):
    speed = np.full((50, 4), 1500.0) + np.arange(4)
    speed[7, 2] = np.nan  # one rotor without a reading at one row
    command = np.linspace(0.0, 1.0, 200).reshape(50, 4)
    meta = {"rotors": {"count": 4, "motors": [1, 2, 3, 4], "spin": [-1, -1, 1, 1]}}
    rec = _rec(rotor_speed=speed, motor_command=command, meta=meta)
    back = load_recording(save_recording(rec, tmp_path / f"r.{ext}"))
    assert np.array_equal(back.rotor_speed, speed, equal_nan=True)
    assert np.array_equal(back.motor_command, command)
    assert back.meta["rotors"] == meta["rotors"] and back.rotors == 4
    assert back.rotor_channels == ["rotor_speed", "motor_command"]
    part = back.select(slice(5, 10))
    assert np.array_equal(part.rotor_speed, speed[5:10], equal_nan=True)


@pytest.mark.parametrize(
    "kw, message",
    [
        ({"rotor_speed": np.full((50, 4), 15000.0)}, "rpm or another unit"),
        ({"rotor_speed": np.full((50, 4), -10.0)}, "rotor_speed: row 0 holds a negative speed"),
        ({"motor_command": np.full((50, 4), 1.5)}, "motor_command: row 0 holds a value outside [0, 1]"),
        ({"rotor_speed": np.ones((50, 4)), "motor_command": np.ones((50, 3))}, "different rotor counts (3 and 4)"),
        ({"rotor_speed": np.ones((49, 4))}, "rotor_speed: has 49 rows but t has 50"),
        ({"rotor_speed": np.ones((50, 4)), "meta": {"rotors": {"count": 6}}}, "states 6 rotors"),
        ({"rotor_speed": np.ones((50, 4)), "meta": {"rotors": {"spin": [1, -1]}}}, "rotors.spin must be a list of 4"),
    ],
)
def test_rotor_channels_refuse_what_cannot_be(kw, message):
    with pytest.raises(ValueError) as e:
        _rec(**kw)
    assert message in str(e.value) and "\n" not in str(e.value)


def test_a_file_with_a_gap_in_its_rotor_columns_is_refused(tmp_path):
    p = save_recording(_rec(rotor_speed=np.ones((50, 3))), tmp_path / "r.csv")
    text = p.read_text().replace("rotor_speed_1", "rotor_speed_7")
    p.write_text(text)
    with pytest.raises(ValueError, match="numbered from 0"):
        load_recording(p)


# -- DIDO ---------------------------------------------------------------------------------------------------
def _dido(path, flight, rpm_layout):
    import h5py

    from quadest.rotation.frames import vec_frd_to_flu

    speeds = _speeds_rpm() / 1e4  # DIDO's unit: 10⁴ rpm
    with h5py.File(path, "w") as f:
        f["ts"] = 1.6e9 + flight.t
        f["gyr"] = vec_frd_to_flu(flight.gyr)
        f["acc"] = vec_frd_to_flu(flight.acc)
        f["gt_q"] = np.tile([1.0, 0.0, 0.0, 0.0], (N, 1))
        f["dynamic_params"] = np.arange(9.0)
        if rpm_layout == 5:
            f["meas_rpm"] = np.column_stack([1.6e11 + 100 * flight.t, speeds])  # the dataset's time column
        elif rpm_layout == 4:
            f["meas_rpm"] = speeds


@pytest.mark.parametrize("layout", [4, 5])
def test_dido_rotor_speeds_in_both_layouts(tmp_path, flight, layout):
    p = tmp_path / "flight.hdf5"
    _dido(p, flight, layout)
    rec = read_recording(p)
    expected = _speeds_rpm() * RAD_S_PER_RPM
    assert np.allclose(rec.rotor_speed, expected, rtol=1e-12)
    assert rec.motor_command is None and rec.meta["rotors"]["count"] == 4
    assert f"N×{layout}" in rec.meta["rotors"]["sources"]["rotor_speed"]
    assert "spin" not in rec.meta["rotors"]  # DIDO does not state them: never guessed
    assert rec.meta["dido_dynamic_params"] == list(np.arange(9.0))


def test_dido_without_or_with_mismatched_rotor_speeds(tmp_path, flight):
    p = tmp_path / "none.hdf5"
    _dido(p, flight, None)
    assert read_recording(p).rotor_speed is None
    import h5py

    q = tmp_path / "short.hdf5"
    _dido(q, flight, 4)
    with h5py.File(q, "a") as f:
        del f["meas_rpm"]
        f["meas_rpm"] = np.ones((N - 3, 4))
    rec = read_recording(q)
    assert rec.rotor_speed is None and any("meas_rpm" in w for w in rec.meta["warnings"])


# -- autopilot logs -----------------------------------------------------------------------------------------
def test_ulog_motor_commands_and_esc_rpm(tmp_path, flight):
    p = tmp_path / "log.ulg"
    commands = np.clip(0.5 + 0.1 * np.sin(np.arange(N)[:, None] * [0.01, 0.02, 0.03, 0.04]), 0, 1)
    rpm = np.round(_speeds_rpm())
    write_ulog(p, flight, rotors=(commands, rpm))
    rec = read_recording(p)
    # logged every second sample, held on the rows between
    held = np.repeat(np.arange(0, N, 2), 2)[:N]
    assert np.allclose(rec.motor_command, commands.astype(np.float32)[held], atol=0)
    assert np.allclose(rec.rotor_speed, rpm[held] * RAD_S_PER_RPM, rtol=1e-12)
    r = rec.meta["rotors"]
    assert r["spin"] == [-1, -1, 1, 1] and r["motors"] == [1, 2, 3, 4] and "assumed" in r["frame"]
    assert r["rates_hz"]["rotor_speed"] == pytest.approx(RATE / 2, rel=1e-3)


def test_ulog_pwm_outputs_as_commands(tmp_path, flight):
    p = tmp_path / "log.ulg"
    pwm = np.tile([1000.0, 1250.0, 1500.0, 2100.0], (N, 1))
    write_ulog(p, flight, outputs=pwm, params={"PWM_MIN": 1000.0, "PWM_MAX": 2000.0})
    rec = read_recording(p)
    assert np.allclose(rec.motor_command, [0.0, 0.25, 0.5, 1.0])  # clipped at full
    assert rec.rotor_speed is None


def test_dataflash_rcou_and_esc_by_servo_function(tmp_path, flight):
    d = tmp_path / "log.bin"
    pwm = np.tile([1100.0, 1300.0, 1500.0, 1900.0], (N, 1))
    rpm = _speeds_rpm()
    # outputs 1 and 2 swapped: motor 1 on output 2, motor 2 on output 1
    params = {"SERVO1_FUNCTION": 34, "SERVO2_FUNCTION": 33, "SERVO3_FUNCTION": 35, "SERVO4_FUNCTION": 36}
    params.update(MOT_PWM_MIN=1100.0, MOT_PWM_MAX=1900.0, FRAME_CLASS=1, FRAME_TYPE=1)
    write_dataflash(d, flight, params=params, outputs=pwm, esc_rpm=rpm)
    rec = read_recording(d)
    assert np.allclose(rec.motor_command[10], [0.25, 0.0, 0.5, 1.0])
    held = np.repeat(np.arange(0, N, 2), 2)[:N]
    assert np.allclose(rec.rotor_speed[2:], (rpm[held][:, [1, 0, 2, 3]] * RAD_S_PER_RPM)[2:], rtol=1e-6)
    r = rec.meta["rotors"]
    assert r["frame"] == "quad X" and r["spin"] == [-1, -1, 1, 1]
    assert np.allclose(r["positions"][0], [math.sqrt(0.5), math.sqrt(0.5)])  # motor 1 front right


def test_dataflash_without_esc_telemetry_has_no_speeds(tmp_path, flight):
    d = tmp_path / "log.bin"
    write_dataflash(d, flight, outputs=np.full((N, 4), 1500.0), esc_rpm=np.zeros((N, 4)))
    rec = read_recording(d)
    assert rec.rotor_speed is None and rec.motor_command is not None


def test_rosbag_actuators(tmp_path, flight):
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    definition = "std_msgs/Header header\nfloat64[] angles\nfloat64[] angular_velocities\nfloat64[] normalized"
    ts.register(get_types_from_msg(definition, "mav_msgs/msg/Actuators"))
    Imu, Actuators = ts.types["sensor_msgs/msg/Imu"], ts.types["mav_msgs/msg/Actuators"]
    Header, Time = ts.types["std_msgs/msg/Header"], ts.types["builtin_interfaces/msg/Time"]
    V3, Q = ts.types["geometry_msgs/msg/Vector3"], ts.types["geometry_msgs/msg/Quaternion"]
    speeds = _speeds_rpm() * RAD_S_PER_RPM
    path = tmp_path / "flight.bag"
    with Writer(path) as w:
        ci = w.add_connection("/imu", "sensor_msgs/msg/Imu", typestore=ts)
        ca = w.add_connection("/motor_speed", "mav_msgs/msg/Actuators", typestore=ts)
        for k in range(N):
            t_ns = int(1e9 + k * 5e6)
            h = Header(seq=k, stamp=Time(sec=t_ns // 10**9, nanosec=t_ns % 10**9), frame_id="base")
            g, a = flight.gyr[k], flight.acc[k]
            imu = Imu(h, Q(0.0, 0.0, 0.0, 1.0), np.zeros(9), V3(g[0], -g[1], -g[2]), np.zeros(9),
                      V3(a[0], -a[1], -a[2]), np.zeros(9))  # fmt: skip
            w.write(ci, t_ns, ts.serialize_ros1(imu, "sensor_msgs/msg/Imu"))
            act = Actuators(h, np.zeros(0), speeds[k], np.full(4, 0.5))
            w.write(ca, t_ns, ts.serialize_ros1(act, "mav_msgs/msg/Actuators"))
    rec = read_recording(path)
    assert np.allclose(rec.rotor_speed, speeds, rtol=1e-12)
    assert np.allclose(rec.motor_command, 0.5)
    assert "/motor_speed" in rec.meta["rotors"]["sources"]["rotor_speed"]


def test_csv_rotor_columns_with_units(tmp_path, flight):
    p = tmp_path / "log.csv"
    rpm = _speeds_rpm()
    cols = {"time": flight.t, "gx": flight.gyr[:, 0], "gy": flight.gyr[:, 1], "gz": flight.gyr[:, 2]}
    cols.update({"ax": flight.acc[:, 0], "ay": flight.acc[:, 1], "az": flight.acc[:, 2]})
    cols.update({f"rpm{i}": rpm[:, i] for i in range(4)} | {f"pct{i}": np.full(N, 40.0) for i in range(4)})
    with open(p, "w") as f:
        f.write(",".join(cols) + "\n")
        np.savetxt(f, np.column_stack(list(cols.values())), delimiter=",")
    argv = ["info", str(p), "--json", "--format", "csv", "--map", "t=time", "--map", "gyr=gx,gy,gz"]
    argv += ["--map", "acc=ax,ay,az", "--map", "rotor_speed=rpm0,rpm1,rpm2,rpm3"]
    argv += ["--map", "motor_command=pct0,pct1,pct2,pct3", "--units", "rotor_speed=rpm", "--units", "motor_command=%"]
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(argv) == 0
    r = json.loads(out.getvalue())["rotors"]
    assert r["count"] == 4
    assert np.allclose(r["channels"]["rotor_speed"]["max"], rpm.max(axis=0) * RAD_S_PER_RPM, rtol=1e-9)
    assert r["channels"]["motor_command"]["median"] == pytest.approx([0.4] * 4)


def test_info_shows_the_rotors(tmp_path):
    rec = _rec(rotor_speed=np.full((50, 4), 1500.0), meta={"rotors": {"count": 4, "spin": [1, -1, 1, -1]}})
    p = save_recording(rec, tmp_path / "r.csv")
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["info", str(p)]) == 0
    text = out.getvalue()
    assert "rotors      4 (spin [1, -1, 1, -1])" in text
    assert "rotor_speed   50 rows; median [1500, 1500, 1500, 1500]" in text


# -- the shared real files ----------------------------------------------------------------------------------
def _real(folder):
    path = DATA / folder
    if not path.is_dir():
        pytest.skip(f"real recordings not found at {path} (set QUADEST_DATA to the shared data folder)")
    return path


def test_real_dido_flights_have_their_rotor_speeds():
    """The shared DIDO flights: four speeds, held between readings at about 100 Hz, whose hover
    (median) lies between 1300 and 1800 rad/s (12 400-17 200 rpm: a 1.1 kg quadrotor's); the
    thrust per mass from the accelerometer's z against Σ Ω² agrees within 5 % between flights."""
    flights = sorted(_real("dido").glob("*.hdf5"))
    ratios = []
    for f in flights:
        rec = read_recording(f)
        assert rec.rotor_speed.shape == (len(rec), 4) and np.isfinite(rec.rotor_speed).all()
        assert 90.0 < rec.meta["rotors"]["rates_hz"]["rotor_speed"] < 110.0
        med = np.median(rec.rotor_speed, axis=0)
        assert np.all((med > 1300) & (med < 1800)), med
        ratios.append(np.median(-rec.acc[:, 2] / (rec.rotor_speed**2).sum(axis=1)))
    assert len(flights) == 3 and np.ptp(ratios) < 0.05 * np.mean(ratios), ratios


def test_real_px4_log_motor_outputs():
    rec = read_recording(_real("px4_ulog") / "sample.ulg")
    assert rec.motor_command.shape == (len(rec), 4) and rec.rotor_speed is None
    assert "actuator_outputs" in rec.meta["rotors"]["sources"]["motor_command"]
    assert np.nanmax(rec.motor_command) <= 1.0 and np.nanmin(rec.motor_command) >= 0.0


def test_real_ardupilot_logs_commands_and_a_stopped_motor():
    """The SITL loss of motor 1: its command falls to 0 after the logged failure while the
    others' stay; the real hover's commands all between 0.3 and 0.8 in flight."""
    folder = _real("ardupilot")
    rec = read_recording(folder / "sitl_quadx_motor1_loss.bin")
    assert rec.meta["rotors"]["frame"] == "quad X" and rec.rotor_speed is None  # the SITL ESCs report 0 rpm
    cmd = rec.motor_command
    last = cmd[np.isfinite(cmd).all(axis=1)][-20:]
    assert np.all(last[:, 0] == 0.0) and np.all(last[:, 2] > 0.3)
    hover = read_recording(folder / "good_hover1.BIN").motor_command
    flying = hover[np.nanmean(hover, axis=1) > 0.3]
    assert len(flying) > 1000 and np.all((np.median(flying, axis=0) > 0.3) & (np.median(flying, axis=0) < 0.8))
