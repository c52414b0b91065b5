"""A long recording gone through in blocks gives what one pass over it gives: the decimated
display points, the error sums, the estimators run piece by piece and the report's numbers."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from quadest.evaluation import inspect, metrics, runner
from quadest.evaluation.inspect import Decimator, decimate, report_data
from quadest.evaluation.metrics import ErrorSums, euler_errors, summarize_errors
from quadest.evaluation.runner import estimate, estimate_pieces
from quadest.rotation import quat_from_rotvec
from quadest.sim import simulate


@settings(max_examples=40, deadline=None)
@given(
    n=st.integers(1, 5000),
    cuts=st.lists(st.integers(0, 5000), max_size=6),
    points=st.integers(30, 400),
    seed=st.integers(0, 2**31 - 1),
)
def test_decimating_piece_by_piece_keeps_the_points_of_one_pass(n, cuts, points, seed):
    rng = np.random.default_rng(seed)
    t, y = np.arange(n) / 100.0, rng.normal(size=n)
    y[rng.random(n) < 0.1] = np.nan  # gaps in the series (a magnetometer between its samples)
    bounds = sorted({0, n, *[c for c in cuts if c < n]})
    d = Decimator(n, points)
    for a, b in zip(bounds[:-1], bounds[1:]):
        d.add(t[a:b], y[a:b])
    td, yd = d.points()
    tw, yw = decimate(t, y, points)
    np.testing.assert_array_equal(td, tw)
    np.testing.assert_array_equal(yd, yw)
    assert len(td) <= max(n, 3 * np.ceil(n / np.ceil(3 * n / points))) and np.all(np.diff(td) > 0)
    finite = np.isfinite(y)
    if finite.any():  # the extremes are drawn
        assert np.nanmax(yd) == y[finite].max() and np.nanmin(yd) == y[finite].min()


@settings(max_examples=30, deadline=None)
@given(n=st.integers(1, 3000), rows=st.integers(1, 1000), seed=st.integers(0, 2**31 - 1))
def test_error_sums_over_blocks_equal_the_sums_over_all_rows(n, rows, seed):
    """Chan's combination of the blocks' variances against numpy's on all rows at once."""
    rng = np.random.default_rng(seed)
    q_true = quat_from_rotvec(rng.normal(scale=1.0, size=(n, 3)))
    q_est = quat_from_rotvec(rng.normal(scale=0.1, size=(n, 3)))
    from quadest.rotation import quat_mul

    q_est = quat_mul(q_est, q_true)
    mask = rng.random(n) < 0.9
    sums = ErrorSums()
    for a in range(0, n, rows):
        sums.add(q_est[a : a + rows], q_true[a : a + rows], mask[a : a + rows])
    if not mask.any():
        with pytest.raises(ValueError):
            sums.summary()
        return
    got = sums.summary()
    e = np.degrees(euler_errors(q_est[mask], q_true[mask]))
    assert got["samples"] == mask.sum()
    for i, a in enumerate(metrics.AXES):
        assert got["rms_deg"][a] == pytest.approx(np.sqrt(np.mean(e[:, i] ** 2)), rel=1e-12)
        assert got["var_deg2"][a] == pytest.approx(np.var(e[:, i]), rel=1e-9, abs=1e-12)
        assert got["mae_deg"][a] == pytest.approx(np.mean(np.abs(e[:, i])), rel=1e-12)
    one = summarize_errors(q_est, q_true, mask)
    assert one["total_rmse_deg"] == pytest.approx(got["total_rmse_deg"], rel=1e-12)


@pytest.fixture(scope="module")
def spin():
    return simulate("damaged-rotor", "bebop2", seed=3, duration=8.0)


@pytest.mark.parametrize("name", ["robust", "afckf", "madgwick"])
def test_an_estimator_run_piece_by_piece_gives_the_run_over_the_whole(spin, name):
    """A quadest filter resumes where it stopped: the pieces join to the whole run to rounding
    (fastmath's vector loops round a sample by where it falls in its piece, 1e-16 a step: a
    stable filter keeps that below 1e-12)."""
    whole = estimate(spin, name).q
    pieces = list(estimate_pieces(spin, name, rows=997))
    assert [a for a, _ in pieces] == list(range(0, len(spin), 997))
    np.testing.assert_allclose(np.concatenate([r.q for _, r in pieces]), whole, rtol=0, atol=1e-12)


def _flat(x):
    if isinstance(x, dict):
        return {k: _flat(v) for k, v in x.items() if k != "recovery"}
    if isinstance(x, (list, tuple)):
        return [_flat(v) for v in x]
    return x


def _assert_close(a, b, path=""):
    if isinstance(a, dict):
        assert set(a) == set(b), path
        for k in a:
            _assert_close(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), path
        for i, (u, v) in enumerate(zip(a, b)):
            _assert_close(u, v, f"{path}[{i}]")
    elif isinstance(a, (np.ndarray, float)):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9, err_msg=path)
    else:
        assert a == b, path


@pytest.mark.parametrize("truth", [True, False])
def test_the_report_in_small_blocks_shows_what_one_pass_shows(spin, monkeypatch, truth):
    """Every number and every drawn point of a report, with blocks of a few hundred rows (as a
    10⁷-row recording goes through its blocks), equal to those of one pass, to rounding."""
    rec = spin if truth else spin.__class__(t=spin.t, gyr=spin.gyr, acc=spin.acc, mag=spin.mag, meta={})
    names = ["robust", "madgwick"]
    whole = _flat(report_data(rec, names))
    monkeypatch.setattr(metrics, "SUM_ROWS", 613)
    monkeypatch.setattr(inspect, "SUM_ROWS", 613)
    monkeypatch.setattr(runner, "ESTIMATE_ROWS", 613)
    blocks = _flat(report_data(rec, names))
    _assert_close(whole, blocks)
    assert bool(whole[1]["scores"]) == truth


def test_an_acausal_estimator_runs_whole(spin):
    """robust-offline's estimate at each sample uses the whole recording: never cut in pieces."""
    pieces = list(estimate_pieces(spin, "robust-offline", rows=997))
    assert len(pieces) == 1
    np.testing.assert_array_equal(pieces[0][1].q, estimate(spin, "robust-offline").q)
