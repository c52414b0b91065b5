"""Flights with the estimator in the loop: sensors sampled in the loop equal the
batch sensor model, the fault-tolerant controller's relaxed hover (solved here independently),
what the nominal controller does after a rotor loss, and runs that end with a status."""

from dataclasses import replace

import numpy as np
import pytest
from numba import njit
from scipy.optimize import least_squares

from quadest.control import FtcParams, relaxed_hover
from quadest.errors import UsageError
from quadest.evaluation.detection import case_failure, case_flight_kwargs, failure_case
from quadest.filters import Madgwick, make_filter
from quadest.flight import FlightParams, fly
from quadest.flight.common import angle_errors
from quadest.models import MultirotorParams, vehicle_preset
from quadest.sim.faults import Failure
from quadest.sim.flown import flown_recording

V = MultirotorParams()


TILTED = FtcParams(rho=0.25)
"""A relaxed hover with a tilted axis (the default ρ = 0 is level), to check the solver and the flight against."""


@pytest.fixture(scope="module")
def ftc_truth():
    return fly("rotor-loss", estimator="truth", seed=1, duration=12.0, ftc=TILTED)


def _relaxed_hover_independently(model, failed, rho):
    """The relaxed hover written another way: the axis by its tilt θ and azimuth φ, the moments
    as sums of r × F with full 3-vectors, a least-squares solve."""
    pos = np.asarray(model.rotor_pos, float)
    far = int(np.argmax(np.linalg.norm(pos - pos[failed], axis=1)))
    J = np.diag(model.inertia)
    D = np.diag(model.damping)

    def residual(z):
        t_a, theta, phi, w = z
        n = np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), -np.cos(theta)])
        thrusts = np.array([0.0 if i == failed else (rho if i == far else 1.0) * t_a for i in range(4)])
        M = np.zeros(3)
        for i in range(4):
            M += np.cross(pos[i], [0.0, 0.0, -thrusts[i]]) + np.array(
                [0.0, 0.0, -model.spin[i] * model.kappa * thrusts[i]]
            )
        omega = w * n
        M -= D @ omega
        force_up = thrusts.sum() * np.cos(theta) - model.mass * model.gravity
        rotors = model.rotor_inertia * np.dot(model.spin, np.sqrt(thrusts / model.k_f))  # their momentum about z
        return np.concatenate([[force_up], M - np.cross(omega, J @ omega + [0.0, 0.0, rotors])])

    best = None
    for phi0 in np.linspace(-np.pi, np.pi, 8, endpoint=False):
        for w0 in (-15.0, 15.0):
            sol = least_squares(
                residual, [2.0, 0.1, phi0, w0], bounds=([0, 0, -4, -200], [20, 1.2, 4, 200]), xtol=1e-14, ftol=1e-14
            )
            if np.abs(residual(sol.x)).max() < 1e-9 and (best is None or sol.x[1] < best[1]):
                best = sol.x
    return best


def test_the_relaxed_hover_is_the_controllers_model_solved_and_the_flight_reaches_it(ftc_truth):
    """After rotor 0 is lost the fault-tolerant controller (on the true state) settles into a
    spinning relaxed hover. The solver the controller uses agrees with an independent one
    written in the test (1e-6), and the flown vehicle's spin rate and tilt (outputs of the
    rotor-level physics: inflow and rotor drag the controller's model lacks) agree with that
    solution within 10 %."""
    ftc = TILTED
    model = ftc.model(V)
    h = relaxed_hover(model, 0, ftc.rho)
    t_a, theta, phi, w = _relaxed_hover_independently(model, 0, ftc.rho)
    assert np.degrees(theta) == pytest.approx(h.tilt_deg, rel=1e-6)
    assert w == pytest.approx(h.spin, rel=1e-6)
    assert h.thrusts[2] == pytest.approx(t_a, rel=1e-6)
    s = ftc_truth.summary
    assert s["status"] == "survived", s
    spin_model = -w  # ω = ω̄ n with n up: the rate about the navigation frame's z (down) is −ω̄
    assert s["spin_rate_rad_s"] == pytest.approx(spin_model, rel=0.10)
    assert s["tilt_deg"] == pytest.approx(np.degrees(theta), rel=0.10)
    assert s["relaxed_hover_model"]["spin_rate_rad_s"] == pytest.approx(spin_model, rel=1e-6)
    # it holds its place: a settled run circles within the settling bound
    from quadest.flight import FlightParams

    assert s["time_to_settle_s"] is not None and s["position_rms_settled_m"] < FlightParams().settle_m


@pytest.mark.parametrize("rotor_inertia", [4.7e-6, 1.1e-5])
def test_the_relaxed_hover_with_the_rotors_inertia_is_solved(rotor_inertia):
    """With the rotors' angular momentum in the controller's model (the Bebop 2 and the high end
    of its range) the controller's solver agrees with the independent one (1e-6), and the
    rotors' momentum tilts the axis and speeds the spin (against I_p = 0)."""
    ftc = TILTED
    model = ftc.model(replace(vehicle_preset("bebop2"), rotor_inertia=rotor_inertia))
    h = relaxed_hover(model, 0, ftc.rho)
    t_a, theta, phi, w = _relaxed_hover_independently(model, 0, ftc.rho)
    assert np.degrees(theta) == pytest.approx(h.tilt_deg, rel=1e-6)
    assert w == pytest.approx(h.spin, rel=1e-6)
    plain = relaxed_hover(replace(model, rotor_inertia=0.0), 0, ftc.rho)
    assert abs(h.spin) > abs(plain.spin) + 1.0 and h.tilt_deg > plain.tilt_deg


def test_the_nominal_controller_loses_the_vehicle_after_a_rotor_loss():
    s = fly("rotor-loss", controller="se3", estimator="truth", seed=1, duration=6.0).summary
    assert s["status"] == "crashed" and s["end_time_s"] < 6.0, s


def test_a_clipped_gyro_axis_gives_the_controller_the_predicted_rate():
    """A Bebop 2 without its rotors' inertia loses a rotor with a ±500 °/s gyroscope (its spin,
    about 11 rad/s, clips the yaw axis): with the predicted rate it stays up, the rate within
    0.5 rad/s RMS of the truth's on the clipped samples (measured: 0.2-0.3 on seeds 100-109),
    the reading itself on every axis within range. (With the clipped reading it used to crash;
    since the controller's allocation keeps the moments' direction it stays up too, seeds 0-5;
    with the rotors' inertia the predicted rate is worse than the reading: docs/vehicle.md,
    Spin range.)"""
    from quadest.sim import build_config

    cfg = build_config("bebop2").with_overrides({"gyro.range": np.radians(500.0)})
    plain = replace(vehicle_preset("bebop2"), rotor_inertia=0.0)
    kw = dict(estimator="truth", vehicle=plain, config=cfg, seed=3, duration=10.0, failure=Failure(0, 2.0))
    f = fly("rotor-loss", **kw)
    assert f.summary["status"] == "survived", f.summary
    clipped = np.abs(f.recording.gyr[:, 2]) >= cfg.gyro.range * 0.995
    assert clipped.mean() > 0.5
    err = f.rate_est[clipped, 2] - f.states[clipped, 12]
    assert np.sqrt(np.mean(err**2)) < 0.5
    within = np.abs(f.recording.gyr) < cfg.gyro.range * 0.995
    assert np.array_equal(f.rate_est[within], f.recording.gyr[within])


@pytest.mark.parametrize("estimator", ["truth", "madgwick"])
def test_a_gyro_within_range_flies_bit_for_bit_as_without_the_predictor(estimator):
    """A rotor loss whose gyroscope never clips flies the same, bit for bit, with the predicted
    rate and without it: the controller and the estimator read the gyroscope itself."""
    from quadest.flight import FlightParams

    kw = dict(estimator=estimator, seed=2, duration=5.0)
    a = fly("rotor-loss", **kw)
    b = fly("rotor-loss", params=FlightParams(clip_rate="off"), **kw)
    c = fly("rotor-loss", params=FlightParams(clip_rate_estimator=True, clip_rate="rotor-speeds"), **kw)
    assert np.abs(a.recording.gyr).max() < np.radians(1000.0) * 0.99  # the bebop2 sensors' range
    assert np.array_equal(a.states, b.states) and np.array_equal(a.states, c.states)
    assert np.array_equal(a.q_est, b.q_est) and np.array_equal(a.rate_est, a.recording.gyr)


def test_the_loop_reads_the_sensor_model_and_the_check_can_fail():
    """The readings the estimator got in the loop equal what the batch sensor model makes of
    the same flight (flown_recording checks it on every flight); disturbed readings are caught."""
    f = fly("hover", estimator="madgwick", seed=2, duration=2.0)
    rec, x = f.recording, f.states
    assert rec.meta["estimator"] == "madgwick" and len(rec) == 1000
    from quadest.models.multirotor import derivatives

    n = len(rec)
    dx, thrust = np.empty_like(x), np.empty((n, 4))
    derivatives(x, f.commands, np.ones((n, 4)), V.vehicle(), dx, thrust)
    gyr = rec.gyr.copy()
    gyr[500, 1] += 1e-6
    with pytest.raises(ValueError, match="gyr readings differ"):
        flown_recording(rec.t, x, dx, thrust, V, seed=2, readings=(gyr, rec.acc, rec.mag))


def test_estimators_in_the_loop_hold_a_hover():
    """Madgwick's filter and the Kalman filter in the loop hold the hover from a disturbed start
    (settled within 0.3 m and near the setpoint after; the tilt error the controller flew with
    below 5° RMS)."""
    for name in ("madgwick", "roetenberg"):
        s = fly("hover", estimator=name, seed=4).summary
        assert s["status"] == "survived" and s["time_to_settle_s"] is not None, s
        assert s["tilt_error_rms_deg"] < 5.0, s
        # a tilt error δ leaves the position loop pushing g tan δ sideways against k_p (SE(3)
        # gains): the offset it holds, plus 5 cm for the position sensor and the settling
        offset = 9.80665 * np.tan(np.radians(s["tilt_error_rms_deg"])) / 6.5
        assert s["position_rms_settled_m"] < offset + 0.05, s


def _hover_loss(seed, **params):
    """The campaign's hover loss of ``seed`` (a training seed) with robust in the loop."""
    case = failure_case(seed, "oracle")
    kw = case_flight_kwargs(case)
    kw["params"] = replace(kw["params"], **params)
    return fly("hover", estimator="robust", seed=seed, duration=case["duration"], vehicle="bebop2",
               failure=case_failure(case), controller="ftc", **kw)  # fmt: skip


def test_the_estimator_in_the_loop_starts_converged_at_the_start_attitude():
    """A start in flight, tilted 11.6° in a wind: the accelerometer reads the thrust and the
    drag, not gravity. Started from the flight's first samples robust takes them for gravity
    (7° of tilt error at the first sample, 48° within 2 s: the field's heading through the wrong
    tilt) and the vehicle crashes before the rotor goes (the truth keeps it up); started
    converged at the start attitude (``FlightParams.estimator_start_s``, the default) it is
    within its sensors' biases from the first sample and the loss is flown."""
    cold = _hover_loss(180, estimator_start_s=0.0)
    _, tilt = angle_errors(cold.states[:, 6:10], cold.q_est)
    assert cold.summary["status"] == "crashed" and tilt[0] > 5.0 and tilt.max() > 30.0, cold.summary
    assert FlightParams().estimator_start_s > 0.0
    f = _hover_loss(180)
    _, tilt = angle_errors(f.states[:, 6:10], f.q_est)
    assert f.summary["status"] == "survived" and tilt[0] < 1.0 and tilt.max() < 3.0, f.summary


@njit
def _step_that_diverges(x, p, c, gyr, acc, mag, dt, diag):
    x[5] += 1.0  # a counter in a spare slot
    if x[5] > 300:
        x[0] = np.nan


class _Diverging(Madgwick):
    name = "diverging"
    step = staticmethod(_step_that_diverges)


def test_runs_end_with_a_status_not_a_traceback():
    s = fly("hover", estimator=_Diverging(), seed=0, duration=2.0).summary
    assert (
        s["status"] == "stopped" and "non-finite" in s["reason"] and s["end_time_s"] == pytest.approx(0.6, abs=0.005)
    ), s


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(scenario="rotor-loss", failure=Failure(rotor=4, time_s=1.0)), "rotor 4 does not exist"),
        (dict(scenario="rotor-loss", failure=Failure(rotor=0, time_s=20.0)), "outside the run"),
        (dict(scenario="rotor-loss", failure=Failure(rotor=0, time_s=1.0, efficiency=0.5)), "complete rotor loss"),
        (dict(scenario="throw-me"), "unknown scenario"),
        (dict(scenario="hover", estimator="vqf9"), "unknown estimator"),
        (dict(scenario="hover", controller="pid"), "unknown controller"),
        (dict(scenario="hover", duration=-1.0), "duration"),
    ],
)
def test_impossible_flights_are_refused(kwargs, match):
    with pytest.raises((UsageError, ValueError), match=match):
        fly(**kwargs)


@pytest.fixture(scope="module")
def throws():
    return [fly("throw", estimator="recovery", seed=s, duration=11.5) for s in range(3)]


def test_thrown_vehicles_are_recovered_by_the_bank_in_the_loop(throws):
    """Thrown by a hand (up to 30 m/s²), released at up to 8 m/s and 20 rad/s in any attitude, the
    vehicle is recovered with the recovery paper's method in the loop: detection (eq 37) within
    the first samples after the release, the bank converges (S_g < β2) within 1 s with the
    gravity direction within 20° and the velocity within 1 m/s (over 100 throws the largest were
    about 18° and 0.6 m/s: docs/vehicle.md), then upright within 30° and its height held within
    0.5 m for 10 s, having fallen less than the 10 m to the ground."""
    for f in throws:
        s = f.summary
        assert s["status"] == "survived" and s["recovered"], s
        assert 0.0 <= s["detected_s"] <= 0.01 and s["handover_s"] < 1.0, s
        assert s["gravity_error_at_handover_deg"] < 20.0 and s["velocity_error_at_handover_m_s"] < 1.0, s
        assert s["upright_s"] is not None and s["lowest_point_m"] < 10.0, s
        assert s["hover_from_s"] + 10.0 <= 11.5 + 1e-9, s
        assert list(np.unique(f.modes)) == [0, 1, 2], np.unique(f.modes)


def test_the_hand_throws_continuously_into_the_release():
    """The hand's motion (closed form) ends exactly in the release state; its velocities and
    body rates are the integrals of its accelerations (trapezoid, to the step's accuracy); its
    peak acceleration stays within the drawn one; the rotation is about the release rate's axis."""
    from quadest.flight.throw import ThrowParams, hand_motion, release_state

    rate = 1000.0
    x_rel = release_state(V, np.random.default_rng(3), ThrowParams())
    x, dx = hand_motion(x_rel, 25.0, rate, 0.15)
    assert np.array_equal(x[-1], x_rel) and np.allclose(x[0, 3:6], 0.0) and np.allclose(x[0, 10:13], 0.0)
    n = len(dx)
    acc = np.vstack([dx[:, 3:6], np.zeros((1, 3))])  # the acceleration ends at zero at the release
    wdot = np.vstack([dx[:, 10:13], np.zeros((1, 3))])
    dv = np.cumsum(0.5 * (acc[1:] + acc[:-1]) / rate, axis=0)
    dw = np.cumsum(0.5 * (wdot[1:] + wdot[:-1]) / rate, axis=0)
    np.testing.assert_allclose(dv, x[1:, 3:6], atol=1e-3 * np.linalg.norm(x_rel[3:6]) + 1e-9)
    np.testing.assert_allclose(dw, x[1:, 10:13], atol=1e-3 * np.linalg.norm(x_rel[10:13]) + 1e-9)
    dp = np.cumsum(0.5 * (x[1:, 3:6] + x[:-1, 3:6]) / rate, axis=0)
    np.testing.assert_allclose(x[0, 0:3] + dp, x[1:, 0:3], atol=1e-5)
    assert np.linalg.norm(dx[:, 3:6], axis=1).max() <= 25.0 + 1e-9 and n >= 150
    # the attitude turns about the body-fixed axis of the release rate: the relative rotation
    # from the first sample to the release is along it
    from quadest.rotation import quat_conj, quat_mul, quat_to_rotvec

    rv = quat_to_rotvec(quat_mul(quat_conj(x[0, 6:10]), x[-1, 6:10]))
    axis = x_rel[10:13] / np.linalg.norm(x_rel[10:13])
    assert np.linalg.norm(np.cross(rv, axis)) < 1e-9 * max(1.0, np.linalg.norm(rv))


def test_a_flown_throw_is_read_by_recover_and_its_model_is_fitted(throws):
    """The bank in the loop and `recover` over the flown recording afterwards find the same
    handover (the same IMU samples, the same model); the model is fitted from open-loop throws
    of this simulator (eq 14), not taken from it."""
    from quadest.flight.throw import ThrowParams, fit_throw_model
    from quadest.recovery import recover
    from quadest.sim import build_config

    model = fit_throw_model(V, build_config("fma"), ThrowParams())
    assert model.info["samples"] > 20_000 and max(model.info["residual_rms_mps2"]) < 1.0
    f = throws[0]
    res = recover(f.recording.select(slice(0, int(np.argmax(f.modes == 2)) + 5)), model)
    assert res.converge_index is not None
    assert f.recording.t[res.converge_index] == pytest.approx(
        f.summary["handover_s"] + f.summary["release_s"], abs=1e-9
    )


def test_a_throw_detected_in_the_hand_is_rearmed_not_handed_over_there():
    """Seed 24 thrown downward (any direction): the hand's downward acceleration takes ‖z_acc‖
    below β1 0.59 s before the release. The recovery logic re-arms when the hand's acceleration
    falls again (‖z_acc‖ back above β1) and the throw is detected again at the release; the
    handover follows the dwell, after the release, and the vehicle recovers. With the paper's
    logic (no re-arm, no dwell) the bank started in the hand is handed over there, on a gravity
    direction far off, and the vehicle crashes."""
    from quadest.flight.throw import ThrowParams

    down = ThrowParams(any_direction=True)
    s = fly("throw", estimator="recovery", seed=24, throw=down).summary
    assert s["first_detected_s"] < -0.3 and s["detections"] >= 2 and 0.0 <= s["detected_s"] <= 0.01, s
    assert not s["handover_in_hand"] and s["handover_s"] >= 0.5 - 1e-9 and s["recovered"], s
    assert s["gravity_error_at_handover_deg"] < 10.0, s
    paper = {"rearm_samples": 0, "dwell_s": 0.0}
    p = fly("throw", estimator="recovery", seed=24, throw=down, estimator_params=paper).summary
    assert p["handover_in_hand"] and p["gravity_error_at_handover_deg"] > 60.0 and not p["recovered"], p


def test_the_barometer_holds_the_height_after_the_handover():
    """Seed 31 thrown upward: without the barometer the nominal EKF's vertical velocity is biased
    (its aerodynamic model was fitted at the throw's rotor speed) and the height loop settles
    about half a metre off the held height; with the loop's barometer in the nominal EKF the
    height holds within 0.2 m. The barometer the loop read is the true height through its 50 ms
    lag plus its own noise (flight.common.barometer_draws), not the estimator's model."""
    from quadest.flight import FlightParams
    from quadest.flight.common import barometer_draws

    f = fly("throw", estimator="recovery", seed=31, duration=14.0)
    s = f.summary
    assert s["recovered"] and s["height_error_end_m"] < 0.2, s
    off = fly("throw", estimator="recovery", seed=31, duration=14.0, estimator_params={"baro_std": 0.0}).summary
    assert off["height_error_end_m"] > 0.3, off
    a, noise = barometer_draws(f.recording.t, FlightParams(), 31)
    alt = -f.states[:, 2]
    lag = np.empty_like(alt)
    lag[0] = alt[0]
    for k in range(1, len(alt)):
        lag[k] = a[k] * lag[k - 1] + (1.0 - a[k]) * alt[k]
    ok = np.isfinite(noise)
    np.testing.assert_array_equal(np.isfinite(f.baro), ok)
    np.testing.assert_allclose(f.baro[ok], lag[ok] + noise[ok], atol=1e-12)


def test_the_bank_without_its_update_keeps_the_prior():
    """`bank_step` with update False (the nominal estimator's gate, section V-B): the likelihoods stay,
    the covariance grows, the velocity follows the prior alone."""
    from quadest.recovery import RecoveryParams
    from quadest.recovery.bank import bank_step
    from quadest.sim import aero_model, build_config

    m = aero_model(build_config("fma"))
    prm = RecoveryParams().bank_record(0.5)
    q = np.array([[1.0, 0.0, 0.0, 0.0]])
    args = lambda: (np.array([[1.0, 0.0, 0.0]]), q.copy(), np.eye(6)[None] * 0.1, np.zeros(1))  # noqa: E731
    w = np.array([0.1, 0.0, 0.0])
    acc = np.array([0.0, 0.0, -3.0])
    Va, Qa, Pa, La = args()
    bank_step((Va, Qa, Pa, La, np.zeros(1), w.copy()), (w, acc, 1e-3, False, np.nan), prm, (m.A, m.B, m.C))
    Vb, Qb, Pb, Lb = args()
    bank_step((Vb, Qb, Pb, Lb, np.zeros(1), w.copy()), (w, acc, 1e-3, True, np.nan), prm, (m.A, m.B, m.C))
    assert La[0] == 0.0 and np.trace(Pa[0]) > np.trace(Pb[0]) and not np.allclose(Va, Vb)
    # the prior by hand: v + dt (−ω × v + f_c(v, ω)/m + g_b), g_b = [0, 0, g] level
    from quadest.models.aero import aero_force

    f = aero_force(np.array([1.0, 0.0, 0.0]), w, m.A, m.B, m.C) / 0.5
    expect = np.array([1.0, 0.0, 0.0]) + 1e-3 * (-np.cross(w, [1.0, 0.0, 0.0]) + f + [0.0, 0.0, prm.gravity])
    np.testing.assert_allclose(Va[0], expect, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("peer", ["vqf", "imufusion"])
def test_peers_fly_in_the_loop_through_their_streaming_api(peer):
    """A peer in the loop (its per-sample API, from Python) gives, sample by sample, what its
    batch adapter gives over the flown recording afterwards (the same frames and declination),
    and holds a hover."""
    pytest.importorskip(peer)
    f = fly("trajectory", estimator=peer, seed=1, duration=4.0, params=FlightParams(estimator_start_s=0.0))
    q = make_filter(peer, declination=f.recording.declination).run(f.recording).q
    assert np.abs(np.abs((q * f.q_est).sum(axis=1)) - 1.0).max() < 1e-6
    s = fly("hover", estimator=peer, seed=4).summary
    assert s["status"] == "survived" and s["time_to_settle_s"] is not None, s


def test_other_sensors_of_a_flight():
    """The GNSS-like position sensor flies a hover: what the loop read stays within 1.5 times
    its noise (0.5-1 m) of the truth, and so does the vehicle after the start; the barometer
    samples at its rate with its noise
    (the lag of 50 ms is small against
    the hover's slow height changes); a magnetometer latency is sampled in the loop as in the
    batch model (flown_recording's check) and reads the attitude of 20 ms before."""
    from quadest.flight import FlightParams
    from quadest.rotation import quat_conj, quat_rotate
    from quadest.sim import build_config
    from quadest.sim.sensors import earth_field

    p = FlightParams(position_sensor="gnss")
    f = fly("hover", estimator="madgwick", seed=4, params=p)
    assert f.summary["status"] == "survived" and f.recording.meta["position_sensor"] == "gnss"
    err = np.linalg.norm(f.pv_est[:, 0:3] - f.states[:, 0:3], axis=1)
    bound = 1.5 * np.linalg.norm(p.gnss_noise_m)
    assert np.sqrt(np.mean(err**2)) < bound and np.abs(f.states[f.recording.t > 5.0, 0:3]).max() < bound
    ok = np.isfinite(f.baro)
    assert ok.sum() == pytest.approx(50 * 10, abs=1)
    resid = f.baro[ok] + f.states[ok, 2]
    assert np.std(resid) == pytest.approx(0.1, rel=0.15) and abs(np.mean(resid)) < 0.03
    cfg = build_config(
        "bebop2",
        {
            "mag.latency_s": 0.02,
            "mag.noise_std": 0.0,
            "mag.motor_coef": [0.0, 0.0, 0.0],
            "mag.hard_iron": [0.0, 0.0, 0.0],
            "mag.soft_iron": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        },
    )
    g = fly("trajectory", estimator="madgwick", seed=1, duration=3.0, config=cfg)
    rows = np.flatnonzero(np.isfinite(g.recording.mag[:, 0]))
    rows = rows[rows >= 10]
    B = earth_field(cfg.environment)
    for lag, close in ((10, True), (0, False)):
        expect = quat_rotate(quat_conj(g.recording.true_q[rows - lag]), np.tile(B, (len(rows), 1)))
        assert np.allclose(g.recording.mag[rows], expect, atol=1e-6) == close


def test_the_anti_alias_filter_in_the_batch_model_and_in_the_loop():
    """The IMU's first-order low-pass (``dlpf_hz``): white gyroscope noise leaves it with the
    variance ``α/(2 − α)`` of its input (the filter's noise gain); a flown recording with the
    filter on passes the loop-against-batch check (flown_recording raises otherwise)."""
    from quadest.sim import build_config, simulate
    from quadest.sim.sensors import dlpf_alpha

    cfg = build_config("bebop2", {"gyro.noise_std": 0.05, "gyro.dlpf_hz": 40.0}, ideal=False)
    sets = {"gyro.bias_std": 0.0, "gyro.bias_rw_std": 0.0, "gyro.scale_std": 0.0, "gyro.misalignment_std": 0.0}
    rec = simulate("hover", config=cfg.with_overrides(sets), duration=60.0, seed=3, return_truth=False)
    resid = rec.gyr - rec.true_gyr  # the noise through the filter (the true rate is slow against 40 Hz)
    a = dlpf_alpha(40.0, 500.0)
    assert np.std(resid[100:], axis=0) == pytest.approx(np.full(3, 0.05 * np.sqrt(a / (2 - a))), rel=0.05)
    f = fly(
        "hover",
        estimator="madgwick",
        seed=1,
        duration=2.0,
        config=build_config("bebop2", {"gyro.dlpf_hz": 40.0, "acc.dlpf_hz": 40.0}),
    )
    assert f.summary["status"] == "survived"


def test_the_loop_reads_an_indoor_field_as_the_batch_model_does():
    """With an indoor distortion and a magnetometer latency the closed loop's magnetometer
    (position and attitude of 10 ms before) equals the batch model's (flown_recording checks
    it), and differs from the earth's field alone by the distortion's size."""
    from quadest.sim import build_config

    room = build_config("bebop2", {"environment.distortion_ut": 10.0, "mag.latency_s": 0.01})
    f = fly("hover", estimator="truth", seed=2, duration=2.0, config=room)
    plain = fly(
        "hover", estimator="truth", seed=2, duration=2.0, config=room.with_overrides({"environment.distortion_ut": 0.0})
    )
    diff = np.linalg.norm(f.recording.mag - plain.recording.mag, axis=1)
    diff = diff[np.isfinite(diff)]
    assert 5.0 < np.median(diff) < 15.0  # 10 µT at the origin; the vehicle starts within 0.5 m of it
