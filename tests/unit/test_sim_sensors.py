"""Sensor error models: the generated statistics match their parameters within sampling error.

Each error source is switched on alone on top of ideal sensors, so the difference between the
sample and the truth is that source only. Bounds are 5 standard errors of the estimator
(std of a sample std ≈ σ/√(2N); of a sample mean, σ/√N).
"""

import numpy as np
import pytest

from quadest.sim import build_config, simulate

IDEAL = build_config("bebop2", ideal=True)


def run(overrides, scenario="hover", seed=0, duration=20.0, preset="bebop2"):
    cfg = build_config(preset, ideal=True).with_overrides(overrides)
    return simulate(scenario, seed=seed, duration=duration, config=cfg)


@pytest.mark.parametrize("field,sigma", [("gyro", 0.01), ("acc", 0.3)])
def test_white_noise_std(field, sigma):
    rec = run({f"{field}.noise_std": sigma})
    err = (rec.gyr - rec.true_gyr) if field == "gyro" else (rec.acc - rec.true_acc)
    n = len(err)
    assert np.abs(err.mean(axis=0)).max() < 5 * sigma / np.sqrt(n)
    assert np.abs(err.std(axis=0) - sigma).max() < 5 * sigma / np.sqrt(2 * n)
    # white: lag-1 autocorrelation within sampling error of zero
    r1 = np.array([np.corrcoef(err[1:, j], err[:-1, j])[0, 1] for j in range(3)])
    assert np.abs(r1).max() < 5 / np.sqrt(n)


def test_magnetometer_noise_std():
    rec = run({"mag.noise_std": 0.5})
    from scipy.spatial.transform import Rotation

    from quadest.sim.sensors import earth_field

    ok = np.isfinite(rec.mag[:, 0])
    clean = Rotation.from_quat(rec.true_q[ok], scalar_first=True).inv().apply(earth_field(IDEAL.environment))
    err = rec.mag[ok] - clean
    assert np.abs(err.std(axis=0) - 0.5).max() < 5 * 0.5 / np.sqrt(2 * len(err))


@pytest.mark.parametrize("field", ["gyro", "acc"])
def test_constant_bias_draws(field):
    sigma = 0.02
    draws = np.array(
        [
            run({f"{field}.bias_std": sigma}, seed=s, duration=0.2).meta["sensor_errors"][
                "gyr" if field == "gyro" else "acc"
            ]["bias"]
            for s in range(200)
        ]
    )
    assert abs(draws.std() - sigma) < 5 * sigma / np.sqrt(2 * draws.size)
    assert abs(draws.mean()) < 5 * sigma / np.sqrt(draws.size)
    # and the samples carry exactly the recorded bias
    rec = run({f"{field}.bias_std": sigma}, seed=7, duration=1.0)
    b = rec.meta["sensor_errors"]["gyr" if field == "gyro" else "acc"]["bias"]
    err = (rec.gyr - rec.true_gyr) if field == "gyro" else (rec.acc - rec.true_acc)
    np.testing.assert_allclose(err, np.tile(b, (len(rec), 1)), atol=1e-12)


def test_bias_random_walk_increments():
    q = 0.01  # rad/s/√s
    rec = run({"gyro.bias_rw_std": q}, duration=40.0)
    b = rec.gyr - rec.true_gyr
    inc = np.diff(b, axis=0)
    dt = np.diff(rec.t)[0]
    assert np.abs(inc.std(axis=0) / np.sqrt(dt) - q).max() < 5 * q / np.sqrt(2 * len(inc))
    assert np.allclose(b[0], 0.0)


def test_scale_and_misalignment_matrix():
    rec = run({"gyro.scale_std": 0.01, "gyro.misalignment_std": 0.005}, scenario="nominal", seed=3)
    M = np.array(rec.meta["sensor_errors"]["gyr"]["matrix"])
    # least squares recovers the applied matrix from noise-free data
    X, *_ = np.linalg.lstsq(rec.true_gyr, rec.gyr, rcond=None)
    np.testing.assert_allclose(X.T, M, atol=1e-9)
    scale = np.array(rec.meta["sensor_errors"]["gyr"]["scale"])
    mis = np.array(rec.meta["sensor_errors"]["gyr"]["misalignment"])
    np.testing.assert_allclose(M, (np.eye(3) + np.diag(scale)) @ (np.eye(3) + mis))
    assert np.all(np.diag(mis) == 0)
    fixed = run({"acc.scale": [0.01, -0.02, 0.003], "acc.bias": [0.1, 0.2, 0.3]}, duration=1.0)
    np.testing.assert_allclose(fixed.meta["sensor_errors"]["acc"]["scale"], [0.01, -0.02, 0.003])


def test_saturation_in_damaged_rotor():
    """The ±1000 °/s gyroscope saturates whenever the spin exceeds 17.45 rad/s; docs/simulator.md
    documents the share (0 to about 17 % of the post-failure samples for seeds 1 to 20)."""
    shares = []
    for seed in (1, 3, 4):
        rec = simulate("damaged-rotor", "bebop2", seed=seed)
        rng = np.radians(1000.0)
        sat = np.abs(rec.gyr) >= rng
        # saturated samples read exactly the range
        assert np.all(np.abs(rec.gyr[sat]) == rng)
        M = np.array(rec.meta["sensor_errors"]["gyr"]["matrix"])
        clean_mag = np.abs(rec.true_gyr @ M.T)
        # saturation happens where the (scaled) true rate is beyond the range, up to noise
        margin = 5 * 0.01 + 0.02
        assert np.all(sat[clean_mag > rng + margin])
        assert not np.any(sat[clean_mag < rng - margin])
        post = rec.t >= 5.0
        share = sat.any(axis=1)[post].mean()
        shares.append(share)
        assert rec.meta["gyro_saturated_share"] == pytest.approx(sat.any(axis=1).mean(), abs=0.01)
    assert all(0.05 < s < 0.2 for s in shares)


def test_vibration_tone_follows_rotor_load():
    rec = run({"acc.vibration_amp": [0.3, 0.3, 0.3]}, scenario="damaged-rotor", duration=12.0)
    vib = rec.acc - rec.true_acc
    before, after = vib[(rec.t > 1) & (rec.t < 4.5)], vib[rec.t > 8]
    # a sinusoid of amplitude A has RMS A/√2; the load rises after the failure (3 rotors)
    assert np.sqrt((before**2).mean()) == pytest.approx(0.3 / np.sqrt(2), rel=0.15)
    assert np.sqrt((after**2).mean()) > 1.2 * np.sqrt((before**2).mean())


def test_motor_disturbance_grows_with_current():
    rec = run({"mag.motor_coef": [10.0, 0.0, 0.0]}, scenario="damaged-rotor", duration=12.0)
    from scipy.spatial.transform import Rotation

    from quadest.sim.sensors import earth_field

    ok = np.isfinite(rec.mag[:, 0])
    clean = Rotation.from_quat(rec.true_q[ok], scalar_first=True).inv().apply(earth_field(IDEAL.environment))
    d = (rec.mag[ok] - clean)[:, 0]
    t = rec.t[ok]
    # hover current (1/TW)^1.5 with TW = 2; after the loss √(4/3) more at equal thrust
    assert d[t < 4.5].mean() == pytest.approx(10.0 * 0.5**1.5, rel=0.02)
    assert d[t > 8].mean() == pytest.approx(10.0 * 0.5**1.5 * np.sqrt(4 / 3), rel=0.05)
    np.testing.assert_allclose((rec.mag[ok] - clean)[:, 1:], 0, atol=1e-9)


def test_jitter_and_drops():
    rec = run({"imu.jitter_std_s": 2e-4, "imu.drop_prob": 0.05}, duration=20.0)
    dt = np.diff(rec.t)
    assert np.all(dt > 0)
    n_nominal = int(20.0 * 500) + 1
    assert abs((n_nominal - len(rec)) / n_nominal - 0.05) < 5 * np.sqrt(0.05 * 0.95 / n_nominal)
    off = rec.t * 500 - np.round(rec.t * 500)
    assert abs(off.std() / 500 - 2e-4) < 2e-5


def test_determinism_and_seed_dependence():
    a = simulate("nominal", "bebop2", seed=9, duration=5.0)
    b = simulate("nominal", "bebop2", seed=9, duration=5.0)
    c = simulate("nominal", "bebop2", seed=10, duration=5.0)
    for name in ("t", "gyr", "acc", "mag", "true_q", "true_pos"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert not np.allclose(a.gyr, c.gyr)
    # changing one sensor's parameter leaves the motion and the other sensors' draws alone
    d = simulate("nominal", "bebop2", seed=9, duration=5.0, overrides={"mag.noise_std": 2.0})
    np.testing.assert_array_equal(a.true_q, d.true_q)
    np.testing.assert_array_equal(a.gyr, d.gyr)


def test_the_indoor_distortion_is_a_magnetic_field():
    """The distortion is the field of magnetised steel: divergence- and curl-free wherever the
    vehicle flies (central differences, relative to the field's gradient), its magnitude at the
    origin what the parameter says, and a single dipole's field on its axis ``2m/r³``."""
    from quadest.sim.params import Environment
    from quadest.sim.sensors import distortion_at, distortion_sources, field_at

    env = Environment(distortion_ut=12.0, distortion_seed=4)
    src, mom = distortion_sources(env)
    assert np.linalg.norm(
        field_at(env, np.zeros((1, 3)))[0] - field_at(Environment(), np.zeros((1, 3)))[0]
    ) == pytest.approx(12.0, rel=1e-12)
    h = 1e-4
    for p in np.random.default_rng(0).uniform(-1.5, 1.5, (20, 3)):
        jac = np.empty((3, 3))  # jac[i, j] = ∂B_i/∂p_j
        for j in range(3):
            e = np.zeros(3)
            e[j] = h
            jac[:, j] = (np.array(distortion_at(*(p + e), src, mom)) - np.array(distortion_at(*(p - e), src, mom))) / (
                2 * h
            )
        scale = np.abs(jac).max()
        assert abs(np.trace(jac)) < 1e-6 * scale
        assert np.abs(jac - jac.T).max() < 1e-6 * scale
    one = np.array([[0.0, 0.0, 0.0]]), np.array([[0.0, 0.0, 2.0]])
    assert np.array(distortion_at(0.0, 0.0, 1.5, *one)) == pytest.approx([0.0, 0.0, 2 * 2.0 / 1.5**3], rel=1e-12)


def test_the_distortion_follows_the_position():
    """With the distortion on, the magnetometer of a flight that moves reads the field where the
    vehicle is (ideal sensors: the reading is Rᵀ B_n(p) exactly); off, the prescribed outputs are
    those of before (the field is the earth's)."""
    from quadest.rotation import quat_conj, quat_rotate
    from quadest.sim.sensors import field_at

    room = {"environment.distortion_ut": 15.0}  # (the flight is 20 m above the origin, 23 m above the steel)
    rec = run(room, scenario="nominal", duration=10.0)
    cfg = IDEAL.with_overrides(room)
    rows = np.isfinite(rec.mag[:, 0])
    want = quat_rotate(quat_conj(rec.true_q[rows]), field_at(cfg.environment, rec.true_pos[rows]))
    np.testing.assert_allclose(rec.mag[rows], want, atol=1e-9)
    flat = quat_rotate(rec.true_q[rows], rec.mag[rows])  # the field in NED along the flight
    assert np.ptp(flat, axis=0).max() > 1e-3  # it changes as the vehicle moves
    plain = run({}, scenario="nominal", duration=10.0)
    assert np.ptp(quat_rotate(plain.true_q[rows], plain.mag[rows]), axis=0).max() < 1e-9
