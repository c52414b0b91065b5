"""The SE(3) controller flying the vehicle model on the true state."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from quadest.control import SE3Params, allocation, circle_reference, hover_reference
from quadest.control.se3 import TILT_MAX, limited_thrust
from quadest.flight.truth import fly_se3
from quadest.models.multirotor import MultirotorParams
from quadest.rotation import angle_between, euler_to_quat

P = MultirotorParams()


def test_allocation_inverts_the_rotor_moments():
    Ainv = allocation(P)
    pos, spin = np.asarray(P.rotor_pos), np.asarray(P.spin)
    A = np.vstack([np.ones(4), -pos[:, 1], pos[:, 0], -spin * P.k_m / P.k_f])
    np.testing.assert_allclose(A @ Ainv, np.eye(4), atol=1e-12)
    t = Ainv @ [0.0, 0.0, 0.0, 0.01]  # a pure yaw moment: the counter-clockwise pair speeds up
    assert (t[spin < 0] > 0).all() and (t[spin > 0] < 0).all() and abs(t.sum()) < 1e-12


def test_it_brings_a_thrown_off_vehicle_back_to_the_setpoint():
    """From 1 m away, tilted 25°, moving at 2 m/s and turning: within 5 s the vehicle holds the
    setpoint (position within 1 cm, level within 0.5°, rotors at the hover speed within 1 %)."""
    x0 = P.hover_state()
    x0[0:3] = [1.0, -0.5, 0.3]
    x0[3:6] = [2.0, 0.0, -1.0]
    x0[6:10] = euler_to_quat([0.3, -0.25, 1.0])
    x0[10:13] = [1.0, -2.0, 0.5]
    states, cmd = fly_se3(x0, hover_reference(5000))
    end = states[-1]
    assert np.linalg.norm(end[0:3]) < 0.01
    assert np.degrees(angle_between(end[6:10], np.array([1.0, 0, 0, 0]))) < 0.5
    np.testing.assert_allclose(end[13:], P.hover_speed(), rtol=0.01)


def test_it_tracks_a_circle_up_to_the_drag_it_does_not_know():
    """A 1 m circle at 0.2 Hz. The controller has no integral term and no drag model, so the
    rotors' H-drag and the body drag (about 0.23 N at 1.26 m/s) leave a steady lag: the
    error of a spring-damper driven by that force, |D/m| / |k_p − w² + i k_v w| ≈ 7 cm, bounds
    it. Without drag the lag shrinks; what remains (about 2.6 cm) is the attitude rate the
    circle needs, which this controller does not feed forward (e_ω = ω, module doc of se3), and
    the motors' 20 ms lag."""
    from dataclasses import replace

    rate = 1000.0
    t = np.arange(10_000) / rate
    ref = circle_reference(t)
    w = 2 * np.pi * 0.2
    x0 = P.hover_state()
    x0[0] = 1.0
    x0[4] = w  # on the circle, at its speed
    k_p, k_v = SE3Params().k_p[0], SE3Params().k_v[0]
    drag = (4 * P.k_h * P.hover_speed() + P.body_drag[0] * w) * w / P.mass_kg
    bound = drag / abs(complex(k_p - w * w, k_v * w))
    states, _ = fly_se3(x0, ref, rate_hz=rate)
    err = np.linalg.norm(states[:, 0:3] - ref[0], axis=1)[t > 5.0]
    assert err.max() < bound and err.max() - err.min() < 0.002  # a steady lag
    clean = replace(P, k_h=0.0, body_drag=(0.0, 0.0, 0.0))
    states, _ = fly_se3(x0, ref, vehicle=clean, rate_hz=rate)
    err_clean = np.linalg.norm(states[:, 0:3] - ref[0], axis=1)[t > 5.0]
    assert err_clean.max() < 0.03 and err_clean.max() < 0.8 * err.max()


def test_bad_gains_are_refused():
    with pytest.raises(ValueError, match="k_p must be three non-negative"):
        SE3Params(k_p=(1.0, -1.0, 1.0))
    with pytest.raises(ValueError, match="needs 4 rotors"):
        allocation(MultirotorParams(rotor_pos=((0.1, 0, 0), (-0.1, 0, 0)), spin=(1.0, -1.0)))


def test_a_flown_recording_is_read_by_every_estimator(tmp_path):
    """Sensors sampled from the flown circle (bebop2 sensors, noise and all): the recording
    passes quadest's checks, survives a file round trip, and the estimators follow its attitude
    as they follow a prescribed flight's (roll and pitch within 3°)."""
    from quadest.data import load_recording, save_recording
    from quadest.evaluation.metrics import summarize_errors
    from quadest.filters import make_filter
    from quadest.flight import fly

    flight = fly("trajectory", duration=20.0, seed=3)
    rec, states = flight.recording, flight.states
    assert rec.meta["source"] == "quadest fly" and rec.imu_rate_hz() == pytest.approx(500.0)
    np.testing.assert_allclose(rec.true_q, states[:, 6:10])
    back = load_recording(save_recording(rec, tmp_path / "flown.csv"))  # with the unit checks
    assert len(back) == len(rec)
    for name in ("madgwick", "roetenberg", "afckf"):
        r = summarize_errors(make_filter(name, declination=rec.declination).run(rec).q, rec.true_q, rec.t > 5.0)[
            "rms_deg"
        ]
        assert r["roll"] < 3.0 and r["pitch"] < 3.0, (name, r)


def test_rotor_failures_are_events_whose_outcome_is_physics():
    """A damaged rotor (70 % efficiency) at t = 2 s: the nominal controller makes up for it and
    holds the vehicle near the setpoint, with the steady offset a controller without integral
    action keeps (within twice the offset its gains give for the missing thrust and moment). A
    lost rotor: its motor spins down, and the nominal controller, which
    allocates to four rotors, loses the vehicle (it tumbles and falls): the outcome is
    a consequence of thrust, torque and control, not an input. (The fault-tolerant controller
    that keeps it up comes next.)"""
    from quadest.sim.faults import Failure

    x0 = P.hover_state()
    states, _, eta = fly_se3(
        x0, hover_reference(6000), failure=Failure(rotor=0, time_s=2.0, efficiency=0.7), return_eta=True
    )
    assert eta[1999, 0] == 1.0 and eta[2000, 0] == 0.7
    g = SE3Params()
    dT = 0.3 * P.mass_kg * P.gravity / 4  # the thrust the damaged rotor no longer gives
    arm = np.abs(np.asarray(P.rotor_pos)[0, 0])
    lateral = P.gravity * (dT * arm / (P.inertia[0] * g.k_R)) / g.k_p[0]  # tilt needed for the moment
    offset = np.sqrt(2 * lateral**2 + (dT / (P.mass_kg * g.k_p[2])) ** 2)
    assert np.linalg.norm(states[-1, 0:3]) < 2 * offset
    assert np.degrees(angle_between(states[-1, 6:10], np.array([1.0, 0, 0, 0]))) < 5.0
    states, cmd = fly_se3(x0, hover_reference(4000), failure=Failure(rotor=0, time_s=1.0))
    assert cmd[-1, 0] == 0.0 and states[-1, 13] < 0.01 * P.hover_speed()  # spun down
    assert np.abs(states[2000:, 10:13]).max() > 10.0 and states[-1, 2] > 2.0  # tumbling, fallen over 2 m


@pytest.mark.parametrize(
    "failure, match",
    [
        (dict(rotor=4, time_s=1.0), "rotor 4 does not exist"),
        (dict(rotor=0, time_s=9.0), "outside the run"),
        (dict(rotor=0, time_s=0.5, efficiency=1.5), "needs an efficiency in"),
    ],
)
def test_impossible_failures_are_refused(failure, match):
    from quadest.sim.faults import Failure

    with pytest.raises(ValueError, match=match):
        fly_se3(P.hover_state(), hover_reference(1000), failure=Failure(**failure))


def test_a_flight_with_a_damaged_rotor_is_recorded():
    from quadest.flight import fly
    from quadest.sim.faults import Failure

    rec = fly("hover", duration=4.0, seed=1, failure=Failure(rotor=2, time_s=2.0, efficiency=0.6)).recording
    assert rec.meta["failure"] == {"rotor": 2, "time_s": 2.0, "efficiency": 0.6}
    assert np.isfinite(rec.acc).all() and len(rec) == 2000


def test_figure_eight_reference_is_consistent():
    """The figure eight's velocity and acceleration are its position's derivatives (central
    differences at 1 ms: error of order h² times the third derivative, below 1e-3), through
    the smooth start, which begins at rest at the origin."""
    from quadest.control import figure_eight_reference

    t = np.arange(0.0, 6.0, 1e-3)
    p, v, a, yaw = figure_eight_reference(t, phase=0.7)
    np.testing.assert_allclose(np.gradient(p, t, axis=0)[1:-1], v[1:-1], atol=1e-3)
    np.testing.assert_allclose(np.gradient(v, t, axis=0)[1:-1], a[1:-1], atol=1e-2)
    assert np.abs(p[0]).max() == 0 and np.abs(v[0]).max() == 0 and yaw[0] == 0


@settings(max_examples=300, deadline=None)
@given(
    st.floats(-40.0, 40.0),
    st.floats(-40.0, 40.0),
    st.floats(-40.0, 40.0),
)
def test_the_limited_thrust_is_never_upside_down(f0, f1, f2):
    """PX4's thrust limits (a landing's descent): for any desired force the axis leans at most
    45° from the vertical, never up, and the thrust is at least the floor; where the vertical
    force is the weight and the lean within 45° it is the SE(3) controller's own (``−F/‖F‖``,
    ``‖F‖``)."""
    weight, floor = 3.7, 1.3
    thrust, zd = limited_thrust((f0, f1, f2), weight, floor)
    assert np.isclose(np.linalg.norm(zd), 1.0) and zd[2] >= np.cos(TILT_MAX) - 1e-12
    assert thrust >= floor
    level = limited_thrust((f0, f1, -weight), weight, floor)
    if np.hypot(f0, f1) < weight * 0.999:
        f = np.array([f0, f1, -weight])
        np.testing.assert_allclose(level[1], -f / np.linalg.norm(f), atol=1e-12)
        assert level[0] == pytest.approx(np.linalg.norm(f))
