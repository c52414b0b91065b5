"""The consistency figures: NEES of a reported attitude covariance, on the estimate as scored."""

from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from quadest.evaluation.benchmark import _nees_means
from quadest.evaluation.metrics import nees, nees_terms
from quadest.evaluation.runner import estimate, score_result
from quadest.rotation import quat_mul
from quadest.sim import simulate


def test_nees_terms_of_a_known_error():
    """An estimate off the truth by a constant rotation Exp(δ) in the navigation frame: the tilt's
    part is (δ_N² + δ_E²) / var_tilt and the heading's δ_D² / var_heading, exactly."""
    rng = np.random.default_rng(0)
    q_true = Rotation.from_rotvec(np.cumsum(rng.normal(0, 0.05, (500, 3)), axis=0)).as_quat(scalar_first=True)
    delta = np.array([0.02, -0.01, 0.03])
    q_est = quat_mul(Rotation.from_rotvec(-delta).as_quat(scalar_first=True), q_true)
    var_t, var_h = np.full(500, 1e-4), np.full(500, 4e-4)
    tilt, heading = nees_terms(q_est, q_true, var_t, var_h)
    assert tilt == pytest.approx(5.0, rel=1e-9) and heading == pytest.approx(2.25, rel=1e-9)
    assert nees(q_est, q_true, var_t, var_h) == pytest.approx(7.25, rel=1e-9)


def test_nees_is_taken_on_the_estimate_as_scored():
    """A heading offset that the alignment removes changes nothing: robust's run turned by 40°
    about down, scored with the heading aligned, has the NEES of the run itself scored the same
    way (unaligned, the turned run's heading part would be about (40°)² / var_heading)."""
    rec = simulate("nominal", "bebop2", seed=3, duration=20.0)
    run = estimate(rec, "robust")
    turn = Rotation.from_euler("z", 40, degrees=True).as_quat(scalar_first=True)
    turned = replace(run, q=quat_mul(np.broadcast_to(turn, run.q.shape), run.q))
    a, b = (score_result(rec, r, nav="heading", body=False) for r in (run, turned))
    assert a["nees"] == pytest.approx(b["nees"], rel=1e-6) and a["nees_tilt"] == pytest.approx(b["nees_tilt"], rel=1e-6)
    assert 0.05 < b["nees"] < 20.0, b


def test_nees_means_are_means_of_the_rows_that_have_them():
    rows = [{"nees": 1.0, "nees_tilt": 0.5}, {"nees": 2.0, "nees_tilt": 0.5}, {"nees": 6.0, "nees_tilt": 2.0}]
    assert _nees_means(rows) == {"nees": 3.0, "nees_tilt": 1.0}
    assert _nees_means(rows + [{}]) == {} and _nees_means([]) == {}
