"""Time units both ways and calibrations checked (docs/reliability.md): a stated rate or time
unit that the timestamps or the sensors' kinematics contradict is a one-line error; a
magnetometer fit without rotation is refused; a calibration that does not fit the recording it
is applied to is warned about. Synthetic turning recordings (no simulator: nothing compiled)."""

import warnings

import h5py
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import quadest
from quadest.calibration import Calibration, calibrate_mag
from quadest.cli.main import main
from quadest.conventions import GRAVITY
from quadest.data import Recording, save_recording
from quadest.errors import UsageError
from quadest.readers import read_recording

FIELD = np.array([20.0, 2.0, 45.0])  # µT, north-east-down


def turning(rate=500.0, seconds=20.0, seed=0, still=False, hard_iron=(0.0, 0.0, 0.0)):
    """``t, gyr, acc, mag``: a body turning through many orientations (or at rest), FRD, SI; the
    magnetometer at 100 Hz at most (NaN rows between its samples), as real ones sample."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(rate * seconds)) / rate
    angles = np.column_stack([1.2 * np.sin(0.5 * t), 0.8 * np.sin(0.7 * t + 1), 1.5 * np.sin(0.3 * t)])
    rot = Rotation.from_euler("ZYX", 0.0 * angles if still else angles)
    step = rot[:-1].inv() * rot[1:]  # the body's turn over each interval
    gyr = np.vstack([step.as_rotvec() * rate, [[0.0, 0.0, 0.0]]]) + rng.normal(0, 0.005, (len(t), 3))
    acc = rot.inv().apply([0.0, 0.0, -GRAVITY]) + rng.normal(0, 0.05, (len(t), 3))
    mag = rot.inv().apply(FIELD) + np.asarray(hard_iron) + rng.normal(0, 0.5, (len(t), 3))
    mag[np.arange(len(t)) % max(1, round(rate / 100.0)) != 0] = np.nan  # a magnetometer's 100 Hz
    return t, gyr, acc, mag


# -- time units both ways ----------------------------------------------------------------------------
def test_a_rate_given_with_times_must_agree_with_them():
    """Before: t and rate together were refused whatever they said; now they are checked."""
    t, gyr, acc, mag = turning(seconds=2.0)
    with pytest.raises(UsageError, match=r"rate=5000 Hz, but the times t step 0.002 s .* 500 Hz"):
        quadest.estimate(gyr, acc, mag, t=t, rate=5000)
    with pytest.raises(UsageError, match="give the sample times t"):
        quadest.estimate(gyr, acc, mag)


def test_a_rate_ten_times_too_high_is_refused_by_the_kinematics():
    """Before: ``quadest.estimate(..., rate=5000)`` on 500 Hz data ran (87.5° against 3.6°)."""
    t, gyr, acc, mag = turning()
    with pytest.raises(ValueError, match=r"^t: the magnetometer's field turns \S+ times as far") as err:
        quadest.estimate(gyr, acc, mag, rate=5000)
    assert "\n" not in str(err.value)


def _csv(path, t, gyr, acc, mag):
    np.savetxt(
        path, np.column_stack([t, gyr, acc, mag]), delimiter=",", comments="", header="time,gx,gy,gz,ax,ay,az,mx,my,mz"
    )
    return path


MAPPED = {"t": "time", "gyr": ["gx", "gy", "gz"], "acc": ["ax", "ay", "az"], "mag": ["mx", "my", "mz"]}


@pytest.mark.parametrize("rate", [500.0, 20.0])
def test_seconds_stated_as_ms_are_refused(tmp_path, rate):
    """Before: ``--units t=ms`` on a column in seconds gave 115° yaw RMS without a word. At 500 Hz
    the intervals (2 µs) are faster than any IMU; at 20 Hz (50 µs, possible) the magnetometer's
    field turns 1000 times as far as the gyroscope's rates say."""
    p = _csv(tmp_path / "s.csv", *turning(rate=rate, seconds=40.0 if rate < 100 else 10.0))
    assert len(read_recording(p, "csv", columns=MAPPED)) > 0  # read right: accepted
    with pytest.raises(ValueError, match=r"faster than any IMU|times as far") as err:
        read_recording(p, "csv", columns=MAPPED, units={"t": "ms"})
    assert "\n" not in str(err.value) and str(p) in str(err.value)


def _broad(path, sampling_rate, rate=100.0):
    t, gyr, acc, mag = turning(rate=rate, seconds=20.0)
    with h5py.File(path, "w") as f:  # BROAD's ENU/FLU: the FRD arrays turned into it
        f.attrs["sampling_rate"] = sampling_rate
        flu = np.array([1.0, -1.0, -1.0])
        f["imu_gyr"], f["imu_acc"], f["imu_mag"] = gyr * flu, acc * flu, mag * flu
        f["opt_quat"] = np.tile([1.0, 0.0, 0.0, 0.0], (len(t), 1))
    return path


@pytest.mark.parametrize("sampling_rate", [1e12, 1000.0])
def test_a_broad_sampling_rate_the_data_contradict_is_refused(tmp_path, sampling_rate):
    """Before: an HDF5 ``sampling_rate`` of 1e12 was accepted; ten times the true 100 Hz too."""
    assert len(read_recording(_broad(tmp_path / "ok.hdf5", 100.0), "broad")) == 2000
    with pytest.raises(ValueError, match=r"faster than any IMU|times as far"):
        read_recording(_broad(tmp_path / "b.hdf5", sampling_rate), "broad")


# -- calibrations checked ----------------------------------------------------------------------------
def _recording(still=False, hard_iron=(0.0, 0.0, 0.0)):
    t, gyr, acc, mag = turning(rate=100.0, seconds=60.0, still=still, hard_iron=hard_iron)
    return Recording(t=t, gyr=gyr, acc=acc, mag=mag, meta={"units": {"mag": "uT"}})


def test_a_magnetometer_fit_at_rest_is_refused(tmp_path, capsys):
    """Before: ``calibrate mag REST.csv`` wrote a field strength of 558.7 µT. The criterion: the
    field's directions must spread at least 10° (RMS about their mean); a rest spreads 0.6°."""
    rest = _recording(still=True)
    with pytest.raises(ValueError, match=r"spreads 0\.\d° \(RMS about its mean\).*\(at least 10°"):
        calibrate_mag([rest])
    p = save_recording(rest, tmp_path / "rest.csv")
    assert main(["calibrate", "mag", str(p), "-o", str(tmp_path / "m.json")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("quadest calibrate: error: mag: the field's direction spreads") and err.count("\n") == 1
    assert not (tmp_path / "m.json").exists()


def test_a_calibration_that_does_not_fit_is_warned_about():
    """A fitting calibration turns the field onto a sphere silently; one made on another sensor
    (here: a hard iron of 60 µT that this one lacks, and a soft iron squashing an axis) leaves
    the field strength spreading more than the raw data did: warned, in one line."""
    rec = _recording(hard_iron=(15.0, -8.0, 20.0))
    fitting = calibrate_mag([rec])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fitting.apply(rec)
    other = Calibration(
        "mag",
        "uT",
        {
            "hard_iron": [60.0, 0.0, 0.0],
            "soft_iron_correction": np.diag([1.0, 1.0, 0.3]).tolist(),
            "field_strength": 50.0,
        },
    )
    with pytest.warns(UserWarning, match=r"calibration mag does not fit .*field strength spreads") as w:
        other.apply(rec)
    assert "\n" not in str(w[0].message)
