"""quadest diagnose: autopilot logs' motors read and diagnosed (docs/diagnose.md).

The log checks run on every ArduPilot log in ../shared/data/ardupilot (or $QUADEST_DATA) whose
name says what it holds: ``*motorN*loss*`` a loss of motor N at the logged SERVOn_FUNCTION
change, ``good_*`` intact propellers, ``cut25mm*`` one propeller cut short by 25 mm."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import numpy as np
import pytest

from quadest.cli.main import main
from quadest.detect import DetectorParams
from quadest.evaluation.diagnose import (
    DiagnoseParams,
    diagnose,
    diagnose_log,
    flying_mask,
    held,
    motor_shares,
    synthetic_loss_log,
)
from quadest.readers.motors import (
    ARDUPILOT_FRAMES,
    MotorLog,
    frame_geometry,
    logged_failure,
    pwm_thrust,
    read_motor_log,
    runs,
)

DATA = Path(os.environ.get("QUADEST_DATA", Path(__file__).resolve().parents[3] / "shared" / "data"))
LOGS = sorted(p for p in (DATA / "ardupilot").glob("*") if p.suffix.lower() == ".bin") if DATA.is_dir() else []
needs_logs = pytest.mark.skipif(not LOGS, reason=f"ArduPilot logs not found at {DATA / 'ardupilot'} (set QUADEST_DATA)")


def ardupilot_actuator(thrust, expo):
    """ArduPilot's forward linearisation (thrust_to_actuator): the output for a thrust fraction."""
    return ((expo - 1.0) + np.sqrt((1.0 - expo) ** 2 + 4.0 * expo * thrust)) / (2.0 * expo)


@pytest.mark.parametrize("expo", [0.3, 0.65, 0.9])
def test_pwm_thrust_inverts_ardupilots_thrust_curve(expo):
    thrust = np.linspace(0.0, 1.0, 21)
    lo, hi, smin, smax = 1000.0, 2000.0, 0.15, 0.95
    pwm = lo + (smin + (smax - smin) * ardupilot_actuator(thrust, expo)) * (hi - lo)
    np.testing.assert_allclose(pwm_thrust(pwm, lo, hi, smin, smax, expo), thrust, atol=1e-12)


def test_quad_x_numbering_is_ardupilots():
    """Motor 1 front right counter-clockwise, 2 rear left counter-clockwise, 3 front left and 4
    rear right clockwise (ArduPilot's QUAD/X)."""
    pos, spin = frame_geometry(ARDUPILOT_FRAMES[(1, 1)][1])
    np.testing.assert_allclose(np.sign(pos), [[1, 1], [-1, -1], [1, -1], [-1, 1]])
    np.testing.assert_array_equal(spin, [-1, -1, 1, 1])
    for _, table in ARDUPILOT_FRAMES.values():  # every frame's reaction torques cancel
        assert sum(s for _, s in table) == 0


def test_outputs_are_held_never_read_ahead():
    t_out, values = np.array([1.0, 2.0]), np.array([[10.0], [20.0]])
    got, logged = held(np.array([0.5, 1.0, 1.99, 2.0, 3.0]), t_out, values)
    np.testing.assert_array_equal(logged, [False, True, True, True, True])
    np.testing.assert_array_equal(got[1:, 0], [10.0, 10.0, 20.0, 20.0])


def test_runs_are_the_masks_stretches():
    mask = np.array([0, 1, 1, 0, 1, 0, 1, 1, 1], bool)
    assert runs(mask) == [(1, 3), (4, 5), (6, 9)]
    assert runs(mask, shortest=2) == [(1, 3), (6, 9)]


def test_the_logged_failure_is_a_motor_channel_handed_away():
    """SERVO3_FUNCTION 35 is motor 3's; set to 1 (RC pass-through) at 12 s it fails motor 3;
    changes of other parameters or channels are not failures."""
    log = synthetic_log([1.0] * 4)
    log.channels = [1, 2, 3, 4]
    log.changes = [(5.0, "MOT_THST_HOVER", 0.4), (8.0, "SERVO9_FUNCTION", 1.0), (12.0, "SERVO3_FUNCTION", 1.0)]
    assert logged_failure(log) == (12.0, 3)
    log.changes = log.changes[:2]
    assert logged_failure(log) is None


def test_flying_mask_leaves_out_take_off_and_landing():
    t = np.arange(0.0, 20.0, 0.5)
    mask = flying_mask(t, [(2.0, 12.0)], settle=2.0, before_landing=1.5)
    assert t[mask].min() == 4.0 and t[mask].max() == 10.5


def synthetic_log(thrust_scale) -> MotorLog:
    """A hovering quad X whose motors need ``thrust_scale`` times the nominal output."""
    pos, spin = frame_geometry(ARDUPILOT_FRAMES[(1, 1)][1])
    t_out = np.arange(0.0, 30.0, 0.1)
    rng = np.random.default_rng(0)
    thrust = 0.4 * np.asarray(thrust_scale) * (1.0 + 0.02 * rng.standard_normal((len(t_out), 4)))
    t = np.arange(0.0, 30.0, 0.02)
    acc = np.tile([0.0, 0.0, -9.81], (len(t), 1))
    return MotorLog(
        "synthetic", "ArduPilot", t, np.zeros((len(t), 3)), acc, t_out, 1000 + 1000 * thrust, [1, 2, 3, 4], "quad X",
        pos, spin, thrust, [(0.0, 30.0)],
    )  # fmt: skip


def test_the_imus_place_is_the_autopilots_parameter():
    """ArduPilot's INS_POS1_X/Y/Z and PX4's EKF2_IMU_POS_X/Y/Z, in metres and body FRD as the
    detector takes them; 0 where the log has none."""
    from quadest.readers.motors import _imu_position

    assert _imu_position({"INS_POS1_X": 0.02, "INS_POS1_Z": -0.01}, "INS_POS1_") == (0.02, 0.0, -0.01)
    assert _imu_position({"EKF2_IMU_POS_Y": 0.015}, "EKF2_IMU_POS_") == (0.0, 0.015, 0.0)
    assert _imu_position({}, "INS_POS1_") == (0.0, 0.0, 0.0)


def test_a_motor_working_harder_is_its_excess():
    shares = motor_shares(synthetic_log([1.0, 1.25, 1.0, 1.0]))
    excess = [r["excess"] for r in shares]
    assert excess[1] == pytest.approx(0.25, abs=0.02)
    assert max(abs(excess[k]) for k in (0, 2, 3)) < 0.1


def test_the_log_modes_significance_test_is_off_in_flight():
    """In flight the test is off (the in-flight figures stand); for logs it is on."""
    assert DetectorParams().deficit_sigmas == 0.0 < DiagnoseParams().deficit_sigmas


def test_a_large_loss_is_found_at_log_rates_and_noise_alone_is_not():
    """Synthetic logs at 25 Hz / 10 Hz with the real flights' gyro noise: a loss of motor 1 on a
    vehicle whose gain is 8 times the model's is found within two samples, naming motor 1, and
    60 s without a loss raise nothing; without the significance test the noise alone does."""
    for seed in range(3):
        found = diagnose(synthetic_loss_log(0.05, 20.0, seed, gain_factor=8.0)).failures
        assert found and found[0]["motor"] == 1 and 0.0 <= found[0]["time_s"] - 20.0 <= 0.08
        assert diagnose(synthetic_loss_log(0.05, None, seed, 60.0, 8.0)).failures == []
    no_test = DiagnoseParams(deficit_sigmas=0.0)
    assert any(diagnose(synthetic_loss_log(0.05, None, s, 60.0, 8.0), no_test).failures for s in range(3))


def _expected(path: Path):
    name = path.name.lower()
    if m := re.search(r"motor(\d)", name):
        return "loss", int(m.group(1))
    if name.startswith("good"):
        return "intact", None
    if name.startswith("cut25mm"):
        return "cut", None
    return "other", None


@needs_logs
@pytest.mark.parametrize("path", LOGS, ids=lambda p: p.name)
def test_logs_diagnosed(path):
    kind, motor = _expected(path)
    d = diagnose_log(path)
    if kind == "loss":
        change = min(t for t, name, value in d.log.changes if name.endswith("_FUNCTION") and value < 33)
        assert [f["motor"] for f in d.failures] == [motor], d.failures
        delay = d.failures[0]["time_s"] - change
        assert 0.0 <= delay <= 0.15, f"found {delay * 1e3:.0f} ms after the parameter change"
    elif kind == "intact":
        assert d.failures == [] and d.damaged == []
        assert max(abs(r["excess"]) for r in d.motors) < DiagnoseParams().excess_threshold
    elif kind == "cut":
        assert d.failures == [] and len(d.damaged) == 1
    else:
        assert d.failures == []


@needs_logs
def test_the_failure_signature_has_the_frames_signs():
    """The log's gyroscope after the loss of motor 1 (front right) turns right and nose down:
    the opposite of the moment that motor's thrust made, ``(−y, x) T``."""
    path = next((p for p in LOGS if "motor1" in p.name), None)
    if path is None:
        pytest.skip("no log of a loss of motor 1")
    log = read_motor_log(path)
    change = min(t for t, name, value in log.changes if name == "SERVO1_FUNCTION")
    after = (log.t > change) & (log.t < change + 0.1)
    rate = log.gyr[after][-1] - log.gyr[log.t <= change][-1]
    x, y = log.positions[0]
    assert np.sign(rate[0]) == np.sign(y) and np.sign(rate[1]) == -np.sign(x)


@needs_logs
def test_diagnose_writes_json_in_the_logs_own_terms(tmp_path, capsys):
    path = next((p for p in LOGS if "motor" in p.name), LOGS[0])
    out = tmp_path / "d.json"
    assert main(["diagnose", str(path), "--json", str(out)]) == 0
    d = json.loads(out.read_text())
    assert {"failures", "damaged", "motors"} <= set(d)
    assert all(set(f) == {"time_s", "motor", "effectiveness"} for f in d["failures"])
    assert [m["motor"] for m in d["motors"]] == [1, 2, 3, 4]
    t = read_motor_log(path).t
    assert all(t[0] <= f["time_s"] <= t[-1] for f in d["failures"])  # the log's own time base


def test_diagnose_refuses_bad_input_in_one_line(tmp_path, capsys):
    assert main(["diagnose", str(tmp_path / "none.bin")]) == 2
    assert "none.bin: no such file" in capsys.readouterr().err
    junk = tmp_path / "junk.bin"
    junk.write_bytes(b"\x00" * 100)
    assert main(["diagnose", str(junk)]) == 1  # a bad file: exit 1, a bad option: 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "junk.bin" in err[0]
    assert main(["diagnose", str(junk), "--moment-gain", "-1"]) == 2
    assert main(["diagnose", str(junk), "--json", str(junk)]) == 2  # never onto its input
    assert junk.read_bytes() == b"\x00" * 100
