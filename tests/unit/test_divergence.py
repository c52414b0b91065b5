"""The divergence checks that start a recovery in flight (quadest.recovery.divergence), each on
its own: thresholds from the vehicle model, what fires and what does not."""

import math

import numpy as np
import pytest

from quadest.models.multirotor import vehicle_preset
from quadest.recovery.divergence import (
    CHECKS,
    IMPACT,
    INNOVATION,
    NONFINITE,
    RATE,
    STATE,
    WATCH,
    DivergenceParams,
    fired_names,
    reach,
    thresholds,
    watch_state,
    watch_step,
)

RATE_HZ, READING_HZ = 1000.0, 100.0
G = np.array([0.0, 0.0, -9.80665])  # level, at rest or in hover: the accelerometer reads −g along z


def test_the_rotors_reach_follows_from_the_vehicle():
    """The recovery vehicle (quad X, arm 0.17 m, k_f 6.5e-6, Ω_max 900 rad/s, 0.5 kg): the largest
    specific force 4 k_f Ω² / m; about x and y two rotors at Ω_max on one side, each 0.17/√2 m
    from the axis, over J; about z two rotors' reaction torque k_m Ω² over J_z."""
    v = vehicle_preset("recovery")
    t_max = 6.5e-6 * 900.0**2
    force, alpha = reach(v)
    assert force == pytest.approx(4 * t_max / 0.5)
    arm = 0.17 / math.sqrt(2.0)
    np.testing.assert_allclose(
        alpha, [2 * t_max * arm / 0.0023, 2 * t_max * arm / 0.0023, 2 * 1.1e-7 * 900.0**2 / 0.0046]
    )


def _watch(**changes):
    w = thresholds(DivergenceParams(arm_s=0.0, **changes), vehicle_preset("recovery"), rate_hz=RATE_HZ,
                   reading_hz=READING_HZ)  # fmt: skip
    st, hist = watch_state(w)
    return w, st, hist


def _run(w, st, hist, gyr, acc, innov=None, finite=None, every=10):
    """The checks over rows of readings; the bits fired at each sample."""
    n = len(gyr)
    innov = np.zeros((n, 3)) if innov is None else innov
    finite = np.ones(n, bool) if finite is None else finite
    return np.array(
        [watch_step(st, hist, w, k, gyr[k], acc[k], innov[k], k % every == 0, bool(finite[k])) for k in range(n)]
    )


def test_hover_and_the_rotors_strongest_manoeuvre_fire_nothing():
    """At rest, and turning at the rotors' largest angular acceleration on every axis with their
    largest thrust (exactly what the model can reach), no check fires."""
    w, st, hist = _watch()
    n = 300
    _, alpha = reach(vehicle_preset("recovery"))
    t = np.arange(n) / RATE_HZ
    gyr = np.outer(np.minimum(t, 0.05), alpha)  # ramps at the largest angular acceleration, then held
    force, _ = reach(vehicle_preset("recovery"))
    acc = np.tile([0.0, 0.0, -force], (n, 1))
    assert not _run(w, st, hist, gyr, acc).any()
    assert st[STATE.fired_k] == -1.0 and 0.9 < st[STATE.peak] / (1 / 1.5) < 1.1  # impact: at 1/1.5 of its threshold


def test_an_impact_fires_on_its_second_sample_beyond_the_rotors_reach():
    w, st, hist = _watch()
    n = 20
    acc = np.tile(G, (n, 1))
    acc[5] = [0.0, 0.0, -1.01 * w[WATCH.impact_acc]]  # one spike: not an impact
    acc[10:12] = [1.01 * w[WATCH.impact_acc], 0.0, 0.0]
    fired = _run(w, st, hist, np.zeros((n, 3)), acc)
    assert np.flatnonzero(fired).tolist() == [11] and fired[11] == IMPACT
    assert st[STATE.fired_k] == 11 and fired_names(st[STATE.fired]) == ["impact"]


def test_a_rate_change_beyond_the_rotors_reach_fires_on_its_axis():
    """A step of the yaw rate larger than twice the rotors' reach over the 5 ms window plus the
    margin fires; one just below does not (yaw has the smallest reach: 39 rad/s²)."""
    for factor, expect in ((1.05, True), (0.95, False)):
        w, st, hist = _watch()
        step = factor * (w[WATCH.alpha2] + w[WATCH.rate_margin])
        gyr = np.zeros((40, 3))
        gyr[20:, 2] = step
        fired = _run(w, st, hist, gyr, np.tile(G, (40, 1)))
        assert bool(fired.any()) is expect
        if expect:
            assert np.flatnonzero(fired)[0] == 20 and fired[20] == RATE


def test_a_lasting_innovation_fires_after_its_low_pass_and_a_small_one_never():
    """A constant innovation of twice the threshold: the low-pass crosses the threshold at the
    reading where 1 − (1 − a)^m ≥ 1/2; one of half the threshold never fires."""
    n = 1000
    for size, expect in ((2.0, True), (0.5, False)):
        w, st, hist = _watch()
        innov = np.tile([size * w[WATCH.innovation_m], 0.0, 0.0], (n, 1))
        fired = _run(w, st, hist, np.zeros((n, 3)), np.tile(G, (n, 1)), innov)
        assert bool(fired.any()) is expect
        if expect:
            a = w[WATCH.innovation_a]
            m = math.ceil(math.log(0.5) / math.log(1.0 - a))  # readings needed
            assert np.flatnonzero(fired)[0] == 10 * (m - 1) and fired[10 * (m - 1)] == INNOVATION


def test_a_nonfinite_estimate_fires_and_checks_left_out_or_not_yet_armed_do_not():
    n = 20
    finite = np.ones(n, bool)
    finite[7] = False
    w, st, hist = _watch()
    assert _run(w, st, hist, np.zeros((n, 3)), np.tile(G, (n, 1)), finite=finite)[7] == NONFINITE
    w, st, hist = _watch(checks="impact,rate,innovation")
    assert not _run(w, st, hist, np.zeros((n, 3)), np.tile(G, (n, 1)), finite=finite).any()
    w = thresholds(DivergenceParams(arm_s=0.01), vehicle_preset("recovery"), rate_hz=RATE_HZ, reading_hz=READING_HZ)
    st, hist = watch_state(w)
    assert not _run(w, st, hist, np.zeros((n, 3)), np.tile(G, (n, 1)), finite=finite).any()  # armed at 10 samples


def test_unknown_checks_are_refused():
    with pytest.raises(ValueError, match="unknown check"):
        DivergenceParams(checks="impact,wobble")
    assert DivergenceParams().mask() == sum(CHECKS.values())
