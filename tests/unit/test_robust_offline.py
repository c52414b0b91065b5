"""``robust-offline``: the forward and the time-reversed pass of robust fused, the tilt made
again without delay (docs/estimators.md, robust-offline)."""

import math

import numpy as np
import pytest

from quadest.evaluation.metrics import nees
from quadest.filters import make_filter
from quadest.filters.robust.offline import reversed_recording
from quadest.rotation import quat_conj, quat_mul
from quadest.sim import simulate

BIAS = (0.010, -0.008, 0.012)  # rad/s: as tests/unit/test_robust.py


def _rotvec_error(true_q, q):
    from scipy.spatial.transform import Rotation

    return Rotation.from_quat(quat_mul(true_q, quat_conj(q))[:, [1, 2, 3, 0]]).as_rotvec()


def test_reversing_twice_gives_the_recording_back():
    """Played backwards twice, a recording is itself (the gyro's first row, which spans a nominal
    interval, aside): the one-row shift of the reversed gyro is its own inverse."""
    rng = np.random.default_rng(1)
    t = np.cumsum(0.002 + 0.001 * rng.random(50))
    gyr, acc, mag = rng.standard_normal((3, 50, 3))
    t2, g2, a2, m2 = reversed_recording(*reversed_recording(t, gyr, acc, mag))
    np.testing.assert_array_equal(t2, t)
    np.testing.assert_array_equal(g2[1:], gyr[1:])
    np.testing.assert_array_equal(a2, acc)
    np.testing.assert_array_equal(m2, mag)


def test_the_backward_pass_is_robust_on_the_reversed_recording():
    """The backward pass is robust's forward pass over the reversed recording, bit for bit; on
    noise-free sensors it follows the truth as the forward pass does (the gyro's interval
    matched: unshifted, each sample's rate would be applied one interval late)."""
    rec = simulate("nominal", "bebop2", seed=3, duration=20.0, ideal=True)
    off = make_filter("robust-offline", declination=rec.declination)
    f, b = off.passes(rec.t, rec.gyr, rec.acc, rec.mag)
    tr, gr, ar, mr = reversed_recording(rec.t, rec.gyr, rec.acc, rec.mag)
    ref = make_filter("robust", declination=rec.declination).run(t=tr, gyr=gr, acc=ar, mag=mr)
    np.testing.assert_array_equal(b.q, ref.q)
    mid = (rec.t > 5.0) & (rec.t < 15.0)  # both passes past their start
    ef = np.degrees(np.linalg.norm(_rotvec_error(rec.true_q, f.q)[mid], axis=1)).mean()
    eb = np.degrees(np.linalg.norm(_rotvec_error(rec.true_q, b.q[::-1])[mid], axis=1)).mean()
    assert eb < 1.5 * ef + 0.05, (eb, ef)


_RUNS: dict = {}


def _runs(scenario):
    """Seeds 21-25 of a prescribed flight (no default was chosen on them): the recording,
    robust's run and robust-offline's."""
    if scenario not in _RUNS:
        out = []
        for seed in range(21, 26):
            rec = simulate(scenario, "bebop2", seed=seed)
            on = make_filter("robust", declination=rec.declination).run(rec)
            off = make_filter("robust-offline", declination=rec.declination).run(rec)
            out.append((rec, on, off))
        _RUNS[scenario] = out
    return _RUNS[scenario]


@pytest.fixture(scope="module")
def nominal_runs():
    return _runs("nominal")


def test_offline_tilt_is_below_the_online_one(nominal_runs):
    """The online low-pass's delay takes a manoeuvre's acceleration, out of phase, for gravity;
    the zero-phase one does not (and attenuates it twice): roll and pitch RMS below robust's on
    every seed, and their mean below half of it."""
    on_rms, off_rms = [], []
    for rec, on, off in nominal_runs:
        sel = rec.t > 5.0
        on_rms.append(np.sqrt(np.mean(_rotvec_error(rec.true_q, on.q)[sel, :2] ** 2, axis=0)))
        off_rms.append(np.sqrt(np.mean(_rotvec_error(rec.true_q, off.q)[sel, :2] ** 2, axis=0)))
    on_rms, off_rms = np.array(on_rms), np.array(off_rms)
    assert (off_rms < on_rms).all(), np.degrees([on_rms, off_rms])
    assert off_rms.mean() < 0.5 * on_rms.mean(), np.degrees([on_rms.mean(), off_rms.mean()])


@pytest.mark.parametrize("scenario", ["nominal", "damaged-rotor"])
def test_reported_covariance_is_consistent(scenario):
    """Mean NEES of the fused covariance (3 dof: ideal 3) within 1.5-4.5 after the first 5 s, in
    normal flight and after a rotor loss."""
    values = [
        nees(off.q, rec.true_q, off.diag["var_tilt"], off.diag["var_heading"], rec.t > 5.0)
        for rec, _, off in _runs(scenario)
    ]
    assert 1.5 <= np.mean(values) <= 4.5, values


def test_smoothed_bias_is_known_from_the_start():
    """A constant bias: the forward pass learns it over the first seconds of a vibrating hover,
    the backward pass has learnt it by the time it reaches them; the smoothed bias over the
    first 2 s is within a third of the forward one's error."""
    rec = simulate("hover", "bebop2", seed=3, duration=60.0, overrides={"gyro.bias": BIAS, "gyro.bias_rw_std": 0.0})
    off = make_filter("robust-offline", declination=rec.declination)
    f, _ = off.passes(rec.t, rec.gyr, rec.acc, rec.mag)
    res = off.run(rec)
    start = rec.t < 2.0
    err_f = np.column_stack([f.diag[f"bias_{a}"][start] - BIAS[i] for i, a in enumerate("xyz")])
    err_s = np.column_stack([res.diag[f"bias_{a}"][start] - BIAS[i] for i, a in enumerate("xyz")])
    assert np.sqrt(np.mean(err_s**2)) < np.sqrt(np.mean(err_f**2)) / 3.0, np.degrees([err_f.mean(0), err_s.mean(0)])
    assert np.abs(err_s).max() < math.radians(0.3)


def test_streaming_is_refused_in_one_line():
    f = make_filter("robust-offline")
    with pytest.raises(ValueError, match="acausal") as e:
        f.update(np.zeros(3), np.array([0.0, 0.0, -9.81]), dt=0.01)
    assert "\n" not in str(e.value)
    for call in (f.compiled, f.get_state, lambda: f.set_state(np.zeros(3))):
        with pytest.raises(ValueError, match="acausal"):
            call()


def test_estimate_offline_writes_robust_offline_and_refuses_a_causal_filter(tmp_path, capsys):
    """``quadest estimate FILE --offline`` runs robust-offline (the library's result, written
    exactly by Parquet); ``--offline --filter madgwick`` is refused in one line, exit 2;
    ``quadest.estimate(..., method="robust-offline")`` is the same estimate."""
    import pyarrow.parquet as pq

    import quadest
    from quadest import save_recording
    from quadest.cli.main import main

    rec = simulate("hover", "bebop2", seed=5, duration=3.0)
    src, out = tmp_path / "f.parquet", tmp_path / "att.parquet"
    save_recording(rec, src)
    assert main(["estimate", str(src), "--offline", "-o", str(out)]) == 0
    t = pq.read_table(out)
    q = np.column_stack([t.column(c).to_numpy() for c in ("q_w", "q_x", "q_y", "q_z")])
    ref = make_filter("robust-offline", declination=rec.declination).run(rec).q
    np.testing.assert_array_equal(q, ref)
    np.testing.assert_array_equal(quadest.estimate(rec, method="robust-offline").q, ref)
    capsys.readouterr()
    assert main(["estimate", str(src), "--offline", "--filter", "madgwick", "-o", str(tmp_path / "x.csv")]) == 2
    err = capsys.readouterr().err.strip()
    assert "--offline" in err and "madgwick" in err and "\n" not in err
    assert not (tmp_path / "x.csv").exists()


def test_quaternion_exponential_and_logarithm_are_exact_across_their_series_bound():
    """The fusion's and the strapdown's ``Exp`` and ``Log`` switch to their series below 0.05 rad
    and 3°: equal to scipy's rotation vectors within 1e-11 on both sides of the bound."""
    from numba import njit
    from scipy.spatial.transform import Rotation

    from quadest.filters.robust import offline

    exp_s, log_s = njit(lambda a, b, c: offline._exp_s(a, b, c)), njit(lambda w, x, y, z: offline._log_s(w, x, y, z))
    rng = np.random.default_rng(2)
    for th in np.geomspace(1e-9, 1.0, 300):
        v = rng.standard_normal(3)
        v *= th / np.linalg.norm(v)
        q = np.array(exp_s(*v))
        ref = Rotation.from_rotvec(v).as_quat()[[3, 0, 1, 2]]
        np.testing.assert_allclose(q, ref, rtol=0, atol=1e-11)
        np.testing.assert_allclose(log_s(*ref), v, rtol=0, atol=1e-11)
