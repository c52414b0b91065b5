"""The accuracy targets on the prescribed flights, measured as `quadest reproduce afckf --prescribed` measures them.

Deterministic (simulated seeds), so they guard against regressions; speed targets are measured
by `quadest benchmark speed`, never here.
"""

import pytest

from quadest.evaluation.reproduce import reproduce_afckf


@pytest.fixture(scope="module")
def afckf():
    return reproduce_afckf(range(1, 6), prescribed=True)


def test_afckf_damaged_rotor_targets(afckf):
    r = afckf["cases"]["damaged-rotor"]["afckf"]["rms_deg"]
    assert r["roll"] <= 1.5 and r["pitch"] <= 1.5 and r["yaw"] <= 8.0


# Measured (seeds 1-5, mean roll / pitch RMS): afckf 1.54/1.41, madgwick 2.25/2.11, roetenberg
# 1.24/1.15 meet 3°; mahony 3.45/3.54, qukf and ekf 4.62/4.80, complementary 5.11/5.36 do not:
# with their papers' gains they follow the manoeuvre accelerations (time constants of 0.2-1 s).
# docs/estimators.md reports this. The target is one-sided: a filter that improves past 3° is
# welcome, so only the filters that meet it are held to it.
MEETS_3DEG = {"afckf", "madgwick", "roetenberg"}


def test_nominal_flight_roll_pitch():
    import numpy as np

    from quadest.evaluation.metrics import summarize_errors
    from quadest.evaluation.runner import estimate_all
    from quadest.sim import simulate

    worst = {n: [] for n in MEETS_3DEG}
    for seed in range(1, 6):
        rec = simulate("nominal", "bebop2", seed=seed)
        for name, res in estimate_all(rec, sorted(MEETS_3DEG)).items():
            r = summarize_errors(res.q, rec.true_q)["rms_deg"]
            worst[name].append((r["roll"], r["pitch"]))
    for name, v in worst.items():
        assert np.mean(v, axis=0).max() <= 3.0, (name, np.mean(v, axis=0))


def test_recovery_targets():
    """The recovery paper's targets: with the simulation's model >= 95 % of throws converge within 1.5 s of release,
    gravity error at convergence median <= 5°, p90 <= 15°; the fitted model at most 5 points
    worse. 100 throws, seeds 1-100 (the filter's noise values were chosen on throws 5000-5079)."""
    from quadest.evaluation.reproduce_recovery import reproduce_recovery

    r = reproduce_recovery(100, 1)["cases"]
    true, fitted = r["true"], r["fitted"]
    assert true["converged_within_share"] >= 0.95
    assert true["gravity_err_deg"]["median"] <= 5.0
    assert true["gravity_err_deg"]["p90"] <= 15.0
    assert fitted["converged_within_share"] >= true["converged_within_share"] - 0.05
