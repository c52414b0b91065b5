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


def test_time_must_be_given_and_agree(flight):
    with pytest.raises(UsageError, match="give the sample times t"):
        quadest.estimate(flight.gyr, flight.acc)
    with pytest.raises(UsageError, match="rate=2000 Hz, but the times t step .* they disagree"):
        quadest.estimate(flight.gyr, flight.acc, t=flight.t, rate=2000.0)
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


def test_without_a_magnetometer_the_rests_warn_of_deg_s():
    """Six rests in six positions, no magnetometer: read as deg/s the gyroscope turns one rest's
    gravity into the next's, read as rad/s it does not; a warning (the rests are weaker evidence
    than the magnetometer's field), and none for the same data in rad/s."""
    six = simulate("six-position", "bebop2", seed=2)
    t, gyr = 2.0 * six.t, 0.5 * six.gyr  # turned half as fast: below 70 °/s, so no magnitude tells
    assert np.degrees(np.abs(gyr)).max() < 70.0
    with pytest.warns(UserWarning) as said:
        quadest.estimate(np.degrees(gyr), six.acc, t=t)
    said = [str(w.message) for w in said]
    assert any("only if it is read as deg/s" in m for m in said)  # before the estimate
    assert any("the estimate's tilt is" in m for m in said)  # and after it
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        quadest.estimate(gyr, six.acc, t=t)


def test_a_hover_in_deg_s_is_caught_by_the_estimates_tilt():
    """A hover barely turns the field and has no rests: the rates where the accelerometer holds
    still say deg/s beforehand, and the estimate's tilt, 86° from the gravity the accelerometer
    reads (rad/s: 3°), says it after: two warnings."""
    from quadest.data.checks import TILT_WARN_DEG, tilt_disagreement

    hover = simulate("hover", "bebop2", seed=1, duration=30.0)
    with pytest.warns(UserWarning) as caught:
        est = quadest.estimate(np.degrees(hover.gyr), hover.acc, hover.mag, t=hover.t)
    said = [str(w.message) for w in caught]
    assert any("is it in deg/s" in m for m in said) and any("from the gravity" in m for m in said), said
    assert tilt_disagreement(est.q, hover.acc) > 2 * TILT_WARN_DEG - 10
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        est = quadest.estimate(hover)
    assert tilt_disagreement(est.q, hover.acc) < 5.0


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
                   "pip install 'quadest[logs]' (from a clone: pip install '.[logs]')"]  # fmt: skip
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


def test_the_tilt_check_on_real_recordings():
    """robust's tilt stays within the warning's angle of the accelerometer's gravity on every real
    recording (BROAD, DIDO, RepoIMU, the PX4 and ArduPilot logs): the check never fires there."""
    from quadest.data.checks import TILT_WARN_DEG, tilt_disagreement

    files = [f for pattern in REAL for f in sorted(DATA.glob(pattern))] + sorted(DATA.glob("dido/*.hdf5"))
    if not files:
        pytest.skip(f"no real recordings under {DATA} (set QUADEST_DATA; ../shared/data/README.md)")
    worst = max(tilt_disagreement(quadest.estimate(rec).q, rec.acc) for rec in map(quadest.read, files))
    assert worst < TILT_WARN_DEG / 2, worst


def test_the_rests_check_on_real_recordings():
    """No real recording in rad/s draws the rests' warning; where the rests tell, the same data in
    deg/s fits them far better (BROAD, RepoIMU)."""
    from quadest.data.checks import DEG_S_RATIO, rest_misfits

    files = [f for pattern in REAL for f in sorted(DATA.glob(pattern))] + sorted(DATA.glob("dido/*.hdf5"))
    if not files:
        pytest.skip(f"no real recordings under {DATA} (set QUADEST_DATA; ../shared/data/README.md)")
    told = 0
    for f in files:
        rec = quadest.read(f)
        rad, deg = rest_misfits(rec.t, rec.gyr, rec.acc), rest_misfits(rec.t, np.degrees(rec.gyr), rec.acc)
        if len(rad):
            assert not rad[:, 1].sum() < DEG_S_RATIO * rad[:, 0].sum(), f.name
            told += bool(deg[:, 1].sum() < DEG_S_RATIO * deg[:, 0].sum())
    assert told >= 5, told


def test_bad_values_are_one_clear_error_and_bad_samples_are_counted(flight, tmp_path):
    """What a hostile user tried: bad samples skipped and counted by quadest's filters and the
    peers alike (vqf once aborted the process on a NaN time); nothing usable, or a score of
    something else, is an error; a value in the wrong unit is named."""
    t, g, a, m = flight.t.copy(), flight.gyr.copy(), flight.acc.copy(), flight.mag.copy()
    t[1000], g[1500], a[1700], m[200] = np.nan, np.nan, np.inf, np.inf
    for method in ("robust", "vqf", "imufusion", "ahrs-madgwick"):
        est = quadest.estimate(g, a, m, t=t, method=method)
        assert np.isfinite(est.q).all() and est.skipped >= 3, method
    with pytest.raises(ValueError, match="none of the .* samples could be used"):
        quadest.estimate(g, a, t=t[::-1].copy())
    with pytest.warns(UserWarning, match="skipped .* of .* samples"):
        quadest.estimate(g, a, t=np.where(np.arange(len(t)) % 10 == 0, np.nan, t))
    with pytest.raises(ValueError, match="exactly zero on every row"):
        quadest.estimate(np.zeros((1000, 3)), np.zeros((1000, 3)), rate=200.0)
    with pytest.raises(ValueError, match="is the time in ns"):
        quadest.estimate(flight.gyr, flight.acc, t=flight.t * 1e9)
    for bad in ({"declination": "0.1"}, {"declination": 10.0}, {"rate": True}):
        with pytest.raises(UsageError):
            quadest.estimate(flight.gyr, flight.acc, **{"rate": 200.0, **bad})
    with pytest.raises(UsageError, match="carries its own frame"):
        quadest.estimate(flight, frame="enu-flu")
    est = quadest.estimate(flight, method="madgwick")
    part = flight.select(slice(0, 1000))
    with pytest.raises(UsageError, match="not the recording's"):
        quadest.score(part, est)
    for q in (est.q[:, :3], 2.0 * est.q):
        with pytest.raises(UsageError, match="quadest.score"):
            quadest.score(flight, q)
    empty = tmp_path / "empty.ulg"
    empty.write_bytes(b"")
    with pytest.raises(ValueError, match="the file is empty"):
        quadest.read(empty)


def test_offline_vqf_with_a_magnetometer_slower_than_the_imu():
    """The Bebop 2's magnetometer samples at a fifth of the IMU's rate: offline VQF is given the
    held sample between them (zeros, which online VQF skips, turned its heading 91° away)."""
    nominal = simulate("nominal", "bebop2", seed=1, duration=20.0)
    assert np.isnan(nominal.mag[:, 0]).mean() > 0.7
    for method in ("vqf", "vqf-offline"):
        assert quadest.score(nominal, quadest.estimate(nominal, method=method))["rms_deg"]["yaw"] < 5.0, method


def test_a_magnetometer_in_another_frame_is_not_called_deg_s():
    """A negative scale (the magnetometer's axes flipped against the gyroscope's) is another
    disagreement, not a gyroscope in deg/s: no deg/s error that would ruin a correct gyroscope."""
    fig = simulate("figure-eight", "bebop2", seed=1, duration=20.0)
    s, se = gyro_scale(fig.t, fig.gyr, fig.mag * [1.0, -1.0, -1.0])
    assert s < 0.0 and s + 4 * se < 0.25
    quadest.estimate(fig.gyr, fig.acc, fig.mag * [1.0, -1.0, -1.0], t=fig.t)  # no deg/s error
