"""quadest as a library (quadest.api): read, estimate on arrays or a recording, score; arrays
checked like files; a missing extra named in one line."""

import os
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import quadest
from quadest.cli.main import main
from quadest.data.checks import gyro_scale
from quadest.errors import UsageError
from quadest.extras import MissingExtra, need
from quadest.rotation import angle_between
from quadest.rotation.frames import quat_enu_flu_to_ned_frd, vec_frd_to_flu
from quadest.sim import simulate


@pytest.fixture(scope="module")
def flight():
    """20 s of a simulated figure-eight (turning, magnetometer on), IMU at 200 Hz."""
    return simulate("figure-eight", "bebop2", seed=3, duration=20.0, overrides={"imu.rate_hz": 200.0})


def test_three_lines_on_arrays_given_only_the_rate(flight):
    est = quadest.estimate(flight.gyr, flight.acc, flight.mag, rate=200.0)
    same = quadest.estimate(flight.gyr, flight.acc, flight.mag, t=np.arange(len(flight)) / 200.0)
    assert np.array_equal(est.q, same.q) and est.q.shape == (len(flight), 4) and est.euler.shape == (len(flight), 3)
    assert angle_between(est.q[-500:], flight.true_q[-500:]).max() < np.radians(5)
    assert np.array_equal(quadest.make_filter("robust").run(gyr=flight.gyr, acc=flight.acc, rate=200.0).t, est.t)


def test_a_recording_its_score_and_pandas(flight):
    est = quadest.estimate(flight, method="madgwick")
    s = quadest.score(flight, est)
    assert s["samples"] > 0 and s["total_rmse_deg"] < 10
    df = est.to_pandas()
    assert list(df.columns[:7]) == ["q_w", "q_x", "q_y", "q_z", "roll", "pitch", "yaw"]
    assert df.index.name == "t" and np.array_equal(df.index.to_numpy(), flight.t)
    assert np.array_equal(df["yaw"].to_numpy(), est.euler[:, 2])


def test_time_must_be_given_once(flight):
    with pytest.raises(UsageError, match="give the sample times t"):
        quadest.estimate(flight.gyr, flight.acc)
    with pytest.raises(UsageError, match="give the sample times t"):
        quadest.estimate(flight.gyr, flight.acc, t=flight.t, rate=200.0)
    with pytest.raises(UsageError, match="rate must be a positive"):
        quadest.estimate(flight.gyr, flight.acc, rate=-1.0)
    with pytest.raises(UsageError, match="acc must have shape"):
        quadest.estimate(flight.gyr, flight.acc[:-1], rate=200.0)
    with pytest.raises(UsageError, match="carries its own rate"):
        quadest.estimate(flight, rate=200.0)


def test_a_gyroscope_in_deg_s_at_ordinary_rates_is_named(flight):
    """Below 70 rad/s no magnitude gives deg/s away; the magnetometer's turning does."""
    gentle = simulate("nominal", "bebop2", seed=1, duration=20.0)
    deg = np.degrees(gentle.gyr)
    assert np.abs(deg).max() < 70.0
    s, se = gyro_scale(gentle.t, gentle.gyr, gentle.mag)
    assert abs(s - 1.0) < 4 * se  # rad/s: the scale the field's turning asks for is 1
    with pytest.raises(ValueError, match="the magnetometer's field .* is it in deg/s"):
        quadest.estimate(deg, gentle.acc, gentle.mag, t=gentle.t)
    assert quadest.estimate(deg, gentle.acc, gentle.mag, t=gentle.t, check=False).q.shape == (len(gentle), 4)
    with pytest.raises(ValueError, match="look like g"):
        quadest.estimate(flight.gyr, flight.acc / 9.80665, t=flight.t)


def test_a_z_up_frame_is_named_and_enu_flu_is_taken():
    rest = simulate("nominal", "bebop2", seed=1, duration=5.0)  # hover: level, gravity on −z
    flu = [vec_frd_to_flu(a) for a in (rest.gyr, rest.acc, rest.mag)]
    with pytest.warns(UserWarning, match="frame='enu-flu'"):
        quadest.estimate(*flu, t=rest.t)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        est = quadest.estimate(*flu, t=rest.t, frame="enu-flu")
        ned = quadest.estimate(rest.gyr, rest.acc, rest.mag, t=rest.t)
    assert est.frame == "enu-flu"
    assert angle_between(quat_enu_flu_to_ned_frd(est.q), ned.q).max() < 1e-9
    with pytest.raises(UsageError, match="ENU/FLU"):
        quadest.score(rest, est)


def test_read_is_the_one_reader(tmp_path, flight):
    p = quadest.save_recording(flight, tmp_path / "f.parquet")
    rec = quadest.read(p)
    assert np.array_equal(rec.gyr, flight.gyr) and quadest.load_recording is quadest.read
    assert {"read", "estimate", "score", "Recording", "make_filter", "Robust"} <= set(quadest.__all__)


def test_a_missing_extra_is_one_line(monkeypatch, tmp_path, capsys):
    monkeypatch.setitem(sys.modules, "pyulog", None)  # as if not installed
    with pytest.raises(MissingExtra, match=r"reading x needs pyulog, in quadest's \[logs\] extra: pip install"):
        need("pyulog", "reading x")
    log = tmp_path / "a.ulg"
    log.write_bytes(b"ULog\x01\x12\x35\x01" + bytes(8))
    assert main(["info", str(log)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["quadest info: error: reading a PX4 ULog needs pyulog, in quadest's [logs] extra: "
                   "pip install 'quadest[logs]'"]  # fmt: skip
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    assert main(["simulate", "-o", str(tmp_path / "s.csv"), "--plot", str(tmp_path / "s.png")]) == 1
    assert "--plot needs matplotlib" in capsys.readouterr().err
    assert not (tmp_path / "s.csv").exists()  # said before any work


DATA = Path(os.environ.get("QUADEST_DATA", Path(__file__).resolve().parents[3] / "shared" / "data"))
REAL = ("broad/*.hdf5", "px4_ulog/*.ulg", "ardupilot/*.[bB][iI][nN]", "repoimu/*/*.csv")


def test_the_deg_s_check_on_real_recordings():
    """Every real recording with a magnetometer (in rad/s) reads without a deg/s error; the same
    gyroscope in deg/s is refused wherever the field turns enough to tell, and never fits s ≈ 1
    where it can tell (a static trial cannot)."""
    files = [f for pattern in REAL for f in sorted(DATA.glob(pattern))]
    if not files:
        pytest.skip(f"no real recordings under {DATA} (set QUADEST_DATA; ../shared/data/README.md)")
    told = 0
    for f in files:
        rec = quadest.read(f)  # rad/s: the check passes
        if not rec.has_mag:
            continue
        s, se = gyro_scale(rec.t, np.degrees(rec.gyr), rec.mag)
        assert not (abs(s - 1.0) < 4 * se and se < 0.25), f.name  # where it can tell, never rad/s
        told += bool(np.isfinite(se) and abs(s) + 4 * se < 0.25)
    assert told >= 0.8 * len(files), told
