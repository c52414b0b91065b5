"""Each scenario moves as docs/simulator.md describes, measured on the truth it produces."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from quadest.rotation import quat_to_euler
from quadest.sim import build_config, simulate

G = 9.80665


def test_hover_gusts_and_yaw():
    rec, tr = simulate("hover", "bebop2", seed=2, return_truth=True, ideal=True)
    horiz = np.sqrt(np.mean(np.sum(tr.acc_n[:, :2] ** 2, axis=1)))
    assert horiz == pytest.approx(0.3, rel=0.05)
    yaw = np.unwrap(quat_to_euler(rec.true_q)[:, 2])
    assert np.degrees(np.ptp(yaw)) < 2 * 5.0 + 0.5
    # body z follows the thrust: tilt of a few degrees at most
    tilt = np.degrees(np.arccos(Rotation.from_quat(rec.true_q, scalar_first=True).apply([0, 0, 1])[:, 2]))
    assert tilt.max() < 5.0


def test_nominal_path_limits():
    rec, tr = simulate("nominal", "bebop2", seed=2, return_truth=True, ideal=True)
    a = np.linalg.norm(tr.acc_n, axis=1)
    assert 2.7 < a.max() <= 3.0 * 1.001  # scaled on a 10 ms grid
    yaw = np.unwrap(quat_to_euler(rec.true_q)[:, 2])
    yaw_rate = np.gradient(yaw, rec.t)
    assert 0.9 < np.abs(yaw_rate).max() < 1.05
    # rotor drag shows in the accelerometer's x/y: −d v_b (d = 0.3 1/s)
    vb = Rotation.from_quat(rec.true_q, scalar_first=True).inv().apply(rec.true_vel)
    np.testing.assert_allclose(rec.true_acc[:, :2] - _lever_terms(rec, tr)[:, :2], -0.3 * vb[:, :2], atol=1e-9)


def _lever_terms(rec, tr):
    r = np.array(build_config("bebop2").acc.lever_arm)
    return np.cross(tr.gyr_dot, r) + np.cross(tr.gyr, np.cross(tr.gyr, r))


def test_damaged_rotor_spin():
    rec, tr = simulate("damaged-rotor", "bebop2", seed=1, return_truth=True, ideal=True)
    cfg = build_config("bebop2").damaged
    t = rec.t
    w = rec.true_gyr
    spin = np.linalg.norm(w, axis=1)
    assert np.all(spin[t < cfg.failure_s] < 1.0)
    late = t > cfg.failure_s + 5 * cfg.spin_up_tau_s
    assert spin[late].mean() == pytest.approx(15.5, abs=1.5)
    assert spin[late].max() < 15.5 + 3.0 + 0.5 and spin[late].min() > 15.5 - 3.0 - 0.5
    # spin-up: after one time constant about 1 − 1/e of the rate
    i = np.searchsorted(t, cfg.failure_s + cfg.spin_up_tau_s)
    j = np.searchsorted(t, cfg.failure_s + 5 * cfg.spin_up_tau_s)
    assert spin[i] / spin[j] == pytest.approx(1 - np.exp(-1), abs=0.1)
    # the body spins about an axis tilted from body z by tilt_deg · (rate/15.5)²
    tilt = np.degrees(np.arccos(np.abs(w[late, 2]) / spin[late]))
    want = cfg.tilt_deg * (spin[late] / 15.5) ** 2
    assert np.median(np.abs(tilt - want)) < 0.5
    # roll and pitch oscillate at the spin frequency with about the tilt amplitude
    e = np.degrees(quat_to_euler(rec.true_q[late]))
    assert 0.5 * cfg.tilt_deg < np.std(e[:, 0]) * np.sqrt(2) < 3 * cfg.tilt_deg
    # the spin-centre manoeuvres: accelerations up to about 1 m/s² besides the small circle
    assert np.linalg.norm(tr.acc_n[late], axis=1).max() < 2.5


def test_damaged_rotor_thrust_along_body_z():
    """Without rotor drag the centre of mass accelerates only by thrust along −z_b and gravity:
    the coning body z and the small circle of the centre of mass are consistent."""
    rec, tr = simulate(
        "damaged-rotor", "bebop2", seed=1, return_truth=True, ideal=True, overrides={"vehicle.rotor_drag": 0.0}
    )
    late = rec.t > 7.5
    f_com = Rotation.from_quat(rec.true_q, scalar_first=True).inv().apply(tr.acc_n - [0, 0, G])
    off = np.degrees(np.arctan2(np.linalg.norm(f_com[late, :2], axis=1), -f_com[late, 2]))
    assert off.max() < 0.25  # the circle's radius is taken at the mean tilt/rate² ratio


def test_spin_sign_and_rotor_count():
    rec = simulate("damaged-rotor", "bebop2", seed=1, ideal=True, duration=8.0, overrides={"damaged.spin_sign": -1})
    assert rec.true_gyr[-1, 2] < -10


def test_overrides_and_toml(tmp_path):
    cfg = build_config("bebop2", {"gyro.noise_std": "0.02", "acc.lever_arm": "[0, 0, 0.01]"})
    assert cfg.gyro.noise_std == 0.02 and cfg.acc.lever_arm == (0.0, 0.0, 0.01)
    toml = tmp_path / "p.toml"
    toml.write_text("[damaged]\nspin_rate_mean = 12.0\n[environment]\nfield_ut = 50.0\n")
    cfg = build_config("bebop2", toml=toml)
    assert cfg.damaged.spin_rate_mean == 12.0 and cfg.environment.field_ut == 50.0
    for bad, msg in (
        ({"gyro.nosie_std": 1}, "has no parameter 'nosie_std'"),
        ({"foo.bar": 1}, "unknown section"),
        ({"acc.lever_arm": "[1, 2]"}, "expected shape"),
        ({"gyro.noise_std": "abc"}, "cannot read"),
    ):
        with pytest.raises(ValueError, match=msg):
            build_config("bebop2", bad)
    with pytest.raises(ValueError, match="unknown preset"):
        build_config("nope")
    with pytest.raises(ValueError, match="unknown scenario"):
        simulate("loop", "bebop2")


def test_presets_rates():
    assert len(simulate("hover", "lowcost-20hz", seed=0, duration=30.0)) == 601
    rec = simulate("throw", "fma", seed=0, duration=2.0)
    assert rec.imu_rate_hz() == pytest.approx(1000.0) and not rec.has_mag
    rec = simulate("hover", "bebop2", seed=0, duration=2.0)
    assert rec.mag_rate_hz() == pytest.approx(100.0)
