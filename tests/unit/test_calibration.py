"""Calibration: each fit against the errors the simulator put in, the refusals, and the
file/apply path. Targets from the issue; bebop2 preset; the motions are the simulator's
calibration scenarios (docs/calibration.md)."""

import json

import numpy as np
import pytest

from quadest import save_recording
from quadest.calibration import (
    Calibration,
    apply_calibrations,
    calibrate,
    calibrate_accel,
    calibrate_centrifugal,
    calibrate_gyro,
    calibrate_mag,
    load_calibration,
    static_segments,
)
from quadest.cli.main import main
from quadest.sim import simulate

ACC_ERRORS = {"acc.bias_std": 0.2, "acc.scale_std": 0.01, "acc.misalignment_std": 0.005}
HARD_IRON = [15.0, -8.0, 20.0]  # µT, about 40 % of the 48 µT field
SOFT_IRON = [[1.05, 0.02, -0.01], [0.02, 0.97, 0.015], [-0.01, 0.015, 1.02]]
MAG_ERRORS = {"mag.hard_iron": HARD_IRON, "mag.soft_iron": SOFT_IRON}


def _segment_mean(series, rec, segs):
    return np.vstack([series[a:b] for a, b in segs]).mean(axis=0)


# -- gyroscope -----------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", [1, 2, 3, 4, 5, 6])
def test_gyro_bias_within_1e3(seed):
    """Target 1e-3 rad/s against the bias the sensor had during the rest (constant part plus the
    random walk, averaged over the rest segments). White noise alone gives 0.01/√15000 ≈ 8e-5."""
    rec, tr = simulate("rest", "bebop2", seed=seed, return_truth=True)
    cal = calibrate_gyro([rec])
    segs = static_segments(rec)
    assert len(segs) == 1 and segs[0][1] - segs[0][0] > 0.9 * len(rec)  # the whole rest is found
    err = np.abs(np.array(cal.values["bias"]) - _segment_mean(tr.gyr_bias, rec, segs))
    assert err.max() < 1e-3
    # the reported 1σ is the white-noise part: the error stays within 5σ of it
    assert np.all(err < 5 * np.array(cal.uncertainty["bias"]))


def test_gyro_bias_without_random_walk_matches_turn_on_bias():
    rec = simulate("rest", "bebop2", seed=7, overrides={"gyro.bias_rw_std": 0.0})
    cal = calibrate_gyro([rec])
    assert np.abs(np.array(cal.values["bias"]) - rec.meta["sensor_errors"]["gyr"]["bias"]).max() < 1e-3


def test_gyro_finds_rest_segments_between_motion():
    """Rest segments inside a six-position run (holds between turns) are found and reported."""
    rec = simulate("six-position", "bebop2", seed=3)
    cal = calibrate_gyro([rec])
    assert len(cal.quality["rest_segments_s"]) == 6
    assert np.abs(np.array(cal.values["bias"]) - rec.meta["sensor_errors"]["gyr"]["bias"]).max() < 1e-3


# -- accelerometer -------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", [1, 2, 3, 4, 5])
def test_accel_six_position_targets(seed):
    """Bias within 0.02 m/s², scale (and misalignment) within 0.2 %: the fitted correction T times
    the sensor's true matrix M is the identity to 2e-3."""
    rec, tr = simulate("six-position", "bebop2", seed=seed, overrides=ACC_ERRORS, return_truth=True)
    cal = calibrate_accel([rec])
    assert cal.quality["method"] == "six-position" and cal.quality["positions"] == 6
    segs = static_segments(rec)
    true_bias = _segment_mean(tr.acc_bias, rec, segs)
    assert np.abs(np.array(cal.values["bias"]) - true_bias).max() < 0.02
    M = np.array(rec.meta["sensor_errors"]["acc"]["matrix"])
    assert np.abs(np.array(cal.values["matrix"]) @ M - np.eye(3)).max() < 2e-3
    assert np.abs(np.array(cal.values["scale"]) - np.diag(M) + 1).max() < 2e-3
    assert cal.quality["norm_residual_rms_mps2"] < 0.05


def test_accel_many_position_targets():
    """Two six-position sets placed 35° off (random axes): twelve positions of varied attitude
    take the norm fit. Norms fix T only up to a rotation, so T·M must be orthogonal: its
    singular values within 0.2 % of 1."""
    over = {**ACC_ERRORS, "calibration.six_tilt_deg": 35.0, "acc.bias_rw_std": 0.0}
    recs = [
        simulate(
            "six-position",
            "bebop2",
            seed=s,
            overrides={
                **over,
                "acc.bias": [0.1, -0.2, 0.15],
                "acc.scale": [0.01, -0.008, 0.012],
                "acc.misalignment": [[0, 0.004, -0.003], [0.002, 0, 0.005], [-0.004, 0.003, 0]],
            },
        )
        for s in (11, 12)
    ]
    cal = calibrate_accel(recs)
    assert cal.quality["method"] == "many-position" and cal.quality["positions"] == 12
    assert np.abs(np.array(cal.values["bias"]) - [0.1, -0.2, 0.15]).max() < 0.02
    M = np.array(recs[0].meta["sensor_errors"]["acc"]["matrix"])
    sv = np.linalg.svd(np.array(cal.values["matrix"]) @ M, compute_uv=False)
    assert np.abs(sv - 1).max() < 2e-3


def test_accel_refuses_too_few_positions():
    rec = simulate("rest", "bebop2", seed=1)
    with pytest.raises(ValueError, match="found 1 static position"):
        calibrate_accel([rec])


# -- magnetometer --------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_mag_hard_and_soft_iron_targets(seed):
    """Hard iron within 1 % of the field strength; soft iron within 2 %: the correction W times the
    true distortion S is a multiple of the identity (the sphere's radius is free), so W·S scaled
    to unit determinant must be the identity to 2e-2."""
    rec = simulate("figure-eight", "bebop2", seed=seed, overrides=MAG_ERRORS)
    cal = calibrate_mag([rec])
    field = np.linalg.norm(rec.meta["earth_field_ned_ut"])
    assert np.abs(np.array(cal.values["hard_iron"]) - HARD_IRON).max() < 0.01 * field
    WS = np.array(cal.values["soft_iron_correction"]) @ np.array(SOFT_IRON)
    WS /= np.cbrt(np.linalg.det(WS))
    assert np.abs(WS - np.eye(3)).max() < 0.02
    # the fitted field strength is the true one seen through the distortion's volume scale
    assert cal.values["field_strength"] == pytest.approx(field * np.cbrt(np.linalg.det(SOFT_IRON)), rel=0.01)
    corrected = cal.apply(rec)
    r = np.linalg.norm(corrected.mag[np.isfinite(corrected.mag[:, 0])], axis=1)
    assert np.std(r) / np.mean(r) < 0.02  # on a sphere up to noise (0.5 µT of 48 µT)


def test_mag_refuses_rotation_about_one_axis():
    rec = simulate("figure-eight", "bebop2", seed=1, overrides={**MAG_ERRORS, "calibration.tilt_amp_deg": 0.0})
    with pytest.raises(ValueError, match="one plane only.*other axes"):
        calibrate_mag([rec])


def test_mag_refuses_too_few_samples():
    rec = simulate("figure-eight", "bebop2", seed=1, duration=0.5, overrides=MAG_ERRORS)
    with pytest.raises(ValueError, match="magnetometer samples.*at least 100"):
        calibrate_mag([rec])


# -- centrifugal and aero ------------------------------------------------------------------------------
def test_centrifugal_constants_within_5_percent():
    """ω1, ω2 from the noisy bebop2 sensors (gyro partly saturated) against the same flight with
    ideal sensors, where eq 13's fit sees the vehicle's own geometry."""
    noisy = calibrate_centrifugal([simulate("damaged-rotor", "bebop2", seed=1000)])
    ideal = calibrate_centrifugal([simulate("damaged-rotor", "bebop2", seed=1000, ideal=True)])
    for k in ("omega1", "omega2"):
        assert noisy.values[k] == pytest.approx(ideal.values[k], rel=0.05)
    assert noisy.filter_params() == {"afckf": {"omega1": noisy.values["omega1"], "omega2": noisy.values["omega2"]}}


def test_centrifugal_refuses_no_spin():
    with pytest.raises(ValueError, match="spinning segment"):
        calibrate_centrifugal([simulate("hover", "bebop2", seed=1, duration=5.0)])


def test_aero_is_fit_aero():
    from quadest.models.aero import fit_aero

    recs = [simulate("throw", "fma", seed=s, duration=4.0) for s in (1, 2)]
    cal = calibrate("aero", recs)
    model = fit_aero(recs, recs[0].meta["config"]["vehicle"]["mass_kg"])
    assert np.array_equal(np.array(cal.values["A"]), model.A)
    assert np.array_equal(np.array(cal.values["B"]), model.B)


# -- the file, applying, refusing a mismatch -------------------------------------------------------------
def test_file_round_trip_and_apply(tmp_path):
    rec = simulate("rest", "bebop2", seed=2)
    cal = calibrate("gyro", [rec])
    path = cal.save(tmp_path / "g.json")
    d = json.loads(path.read_text())
    assert d["kind"] == "gyro" and d["sensor"] == "gyr" and d["unit"] == "rad/s"
    back = load_calibration(path)
    assert back.values == cal.values
    out, params = apply_calibrations(rec, [path])
    assert params == {} and out.meta["calibrations"] == ["gyro"]
    assert np.allclose(out.gyr, rec.gyr - np.array(cal.values["bias"]))
    assert np.array_equal(out.acc, rec.acc)


def test_unit_mismatch_is_refused():
    rec = simulate("figure-eight", "bebop2", seed=1, duration=20.0)
    cal = calibrate_mag([rec])
    rec.meta["units"] = {**rec.meta["units"], "mag": "gauss"}
    with pytest.raises(ValueError, match="mag in uT, but the recording's mag is in gauss"):
        cal.apply(rec)
    with pytest.raises(ValueError, match="unknown calibration kind"):
        Calibration("baro", "Pa", {})


def test_bad_calibration_file(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"hello": 1}')
    with pytest.raises(ValueError, match="not a quadest calibration"):
        load_calibration(bad)
    bad.write_text("{not json")
    with pytest.raises(ValueError, match="not a readable calibration"):
        load_calibration(bad)


# -- the commands --------------------------------------------------------------------------------------
def test_calibrate_and_use_from_the_command_line(tmp_path, capsys):
    rest, six, fig8, flight = (tmp_path / f"{n}.parquet" for n in ("rest", "six", "fig8", "flight"))
    save_recording(simulate("rest", "bebop2", seed=4, duration=10.0), rest)
    save_recording(simulate("six-position", "bebop2", seed=4, overrides=ACC_ERRORS), six)
    save_recording(simulate("figure-eight", "bebop2", seed=4, duration=30.0, overrides=MAG_ERRORS), fig8)
    save_recording(simulate("nominal", "bebop2", seed=4, duration=10.0, overrides={**ACC_ERRORS, **MAG_ERRORS}), flight)
    for kind, src in (("gyro", rest), ("accel", six), ("mag", fig8)):
        assert main(["calibrate", kind, str(src), "-o", str(tmp_path / f"{kind}.json")]) == 0
        out = capsys.readouterr().out
        assert f"{kind} calibration from 1 recording" in out and "±" in out
    cals = [x for k in ("gyro", "accel", "mag") for x in ("--calibration", str(tmp_path / f"{k}.json"))]
    est = tmp_path / "est.csv"
    assert main(["estimate", str(flight), "--filter", "madgwick", "-o", str(est), *cals]) == 0
    header = est.read_text().splitlines()[0]
    assert header == "t,q_w,q_x,q_y,q_z,roll,pitch,yaw"
    assert (
        main(
            ["compare", "--recording", str(flight), "--filters", "madgwick", "--json", str(tmp_path / "c.json"), *cals]
        )
        == 0
    )
    with_cal = json.loads((tmp_path / "c.json").read_text())
    assert (
        main(["compare", "--recording", str(flight), "--filters", "madgwick", "--json", str(tmp_path / "n.json")]) == 0
    )
    without = json.loads((tmp_path / "n.json").read_text())
    # 40 % hard iron ruins the heading unless the calibration removes it
    yaw = lambda d: d["filters"]["madgwick"]["rms_deg"]["yaw"]  # noqa: E731
    assert yaw(with_cal) < 5.0 < yaw(without)


def test_command_refuses_mismatched_calibration(tmp_path, capsys):
    fig8 = tmp_path / "fig8.csv"
    rec = simulate("figure-eight", "bebop2", seed=5, duration=20.0)
    save_recording(rec, fig8)
    assert main(["calibrate", "mag", str(fig8), "-o", str(tmp_path / "m.json")]) == 0
    d = json.loads((tmp_path / "m.json").read_text())
    d["unit"] = "gauss"
    (tmp_path / "m.json").write_text(json.dumps(d))
    capsys.readouterr()
    code = main(
        [
            "estimate",
            str(fig8),
            "--filter",
            "afckf",
            "-o",
            str(tmp_path / "o.csv"),
            "--calibration",
            str(tmp_path / "m.json"),
        ]
    )
    err = capsys.readouterr().err
    assert code != 0 and "made for mag in gauss" in err and len(err.strip().splitlines()) == 1
    code = main(["calibrate", "accel", str(fig8), "-o", str(tmp_path / "a.json")])
    err = capsys.readouterr().err
    assert code != 0 and "static position" in err and not (tmp_path / "a.json").exists()


def test_recover_takes_calibration(tmp_path, capsys):
    throw = tmp_path / "throw.parquet"
    save_recording(simulate("throw", "fma", seed=3, duration=3.0, overrides={"gyro.bias": [0.02, -0.01, 0.015]}), throw)
    cal = Calibration("gyro", "rad/s", {"bias": [0.02, -0.01, 0.015]})
    cal.save(tmp_path / "g.json")
    assert main(["recover", str(throw), "--calibration", str(tmp_path / "g.json")]) == 0
    out = capsys.readouterr().out
    assert "nominal" in out
    # the calibration really goes through: one made for another unit is refused
    Calibration("gyro", "deg/s", {"bias": [1.0, 0.0, 0.0]}).save(tmp_path / "d.json")
    assert main(["recover", str(throw), "--calibration", str(tmp_path / "d.json")]) == 1
    assert "made for gyr in deg/s" in capsys.readouterr().err
