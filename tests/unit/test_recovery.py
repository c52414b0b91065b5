"""State-estimate recovery: sphere, aerodynamic fit, the bank of EKFs and the recovery logic."""

import numpy as np
import pytest

from quadest.recovery import AeroModel, RecoveryParams, fit_aero, min_angle, recover, spread_points
from quadest.recovery.bank import BankRecord, _aero, bank_step, gravity_body
from quadest.recovery.logic import shortest_arc, true_gravity_dir
from quadest.rotation import quat_conj, quat_from_rotvec, quat_mul, quat_rotate
from quadest.sim import aero_model, build_config, simulate

MODEL = aero_model(build_config("fma"))


# -- hypotheses on the sphere ---------------------------------------------------------------------
@pytest.mark.parametrize(
    "n,angle_deg", [(4, np.degrees(np.arccos(-1 / 3))), (6, 90.0), (12, np.degrees(np.arctan(2.0)))]
)
def test_platonic_arrangements(n, angle_deg):
    """Tetrahedron, octahedron, icosahedron: the known optimal spherical codes."""
    p = spread_points(n)
    np.testing.assert_allclose(np.linalg.norm(p, axis=1), 1.0, atol=1e-12)
    assert abs(np.degrees(min_angle(p)) - angle_deg) < 0.01
    # every point has the same number of nearest neighbours as the solid's vertices
    c = p @ p.T
    np.fill_diagonal(c, -2)
    neighbours = (c > np.cos(np.radians(angle_deg + 0.1))).sum(axis=1)
    assert set(neighbours) == {{4: 3, 6: 4, 12: 5}[n]}


def test_forty_hypotheses_are_well_spread():
    p = spread_points(40)
    assert np.degrees(min_angle(p)) >= 32.5  # Fejes Tóth bound 34.6°
    np.testing.assert_array_equal(p, spread_points(40))  # deterministic
    assert np.linalg.norm(p.mean(axis=0)) < 0.05  # no side preferred
    with pytest.raises(ValueError):
        spread_points(0)


# -- aerodynamic model --------------------------------------------------------------------------------
def test_fit_recovers_simulated_parameters():
    """From noisy throws (accelerometer σ 0.1 m/s², biases, misalignment) within a few percent."""
    recs = [simulate("throw", "fma", seed=s) for s in range(300, 315)]
    m = fit_aero(recs, 0.5)
    for name, idx in (("A", [(0, 0), (1, 1), (2, 2)]), ("B", [(0, 0), (1, 1), (2, 2)]), ("C", [(2, 9)])):
        got, want = getattr(m, name), getattr(MODEL, name)
        for i, j in idx:
            assert abs(got[i, j] - want[i, j]) <= 0.05 * abs(want[i, j]), (name, i, j, got[i, j], want[i, j])
    assert max(m.info["residual_rms_mps2"]) < 0.15  # the accelerometer noise is 0.1 m/s²


def test_model_file_round_trip(tmp_path):
    path = MODEL.save(tmp_path / "aero.json")
    back = AeroModel.load(path)
    np.testing.assert_array_equal(back.Lambda, MODEL.Lambda)
    assert back.mass_kg == MODEL.mass_kg
    (tmp_path / "bad.json").write_text('{"format": "other"}')
    with pytest.raises(ValueError, match="not a quadest aero model"):
        AeroModel.load(tmp_path / "bad.json")
    with pytest.raises(ValueError, match="shape"):
        AeroModel(np.zeros((2, 3)), MODEL.B, MODEL.C)


def test_from_z_up_conversion():
    """A model in the paper's z-up body frame gives the same physical force in FRD."""
    rng = np.random.default_rng(0)
    A, B, C = rng.normal(size=(3, 3)), rng.normal(size=(3, 3)), rng.normal(size=(3, 10))
    up = AeroModel(A, B, C)
    frd = AeroModel.from_z_up(A, B, C)
    P = np.diag([1.0, -1.0, -1.0])
    v, w = rng.normal(size=3), rng.normal(size=3)
    np.testing.assert_allclose(frd.force(v, w), P @ up.force(P @ v, P @ w), atol=1e-12)


# -- Jacobians (appendix, eqs 40-46) ----------------------------------------------------------------
def test_upsilon_eq45_against_finite_differences():
    """Υ = A + B (v vᵀ + I|v|²)/|v| (the printed eq 45 lacks B)."""
    rng = np.random.default_rng(1)
    v, w = rng.normal(size=3) * 3, rng.normal(size=3) * 5
    f, U = np.empty(3), np.empty((3, 3))
    _aero(v, w, MODEL.A, MODEL.B, MODEL.C, MODEL.mass_kg, f, U)
    np.testing.assert_allclose(f, MODEL.specific_force(v, w), atol=1e-12)
    fd = np.column_stack(
        [(MODEL.specific_force(v + h, w) - MODEL.specific_force(v - h, w)) / 2e-6 for h in np.eye(3) * 1e-6]
    )
    np.testing.assert_allclose(U, fd, atol=1e-7)


def _prior(v, q_ref, delta, w, dt):
    """The exact prior of one hypothesis as a function of the state (v, δx, δy): the true attitude
    q_ref ⊗ Exp(δ) propagated, the new error read against the propagated reference."""
    from quadest.rotation import quat_to_rotvec

    q = quat_mul(q_ref, quat_from_rotvec([delta[0], delta[1], 0.0]))
    g = np.empty(3)
    gravity_body(q, 9.80665, g)
    vn = v + dt * (-np.cross(w, v) + MODEL.specific_force(v, w) + g)
    q_ref_new = quat_mul(q_ref, quat_from_rotvec(w * dt))
    q_new = quat_mul(q, quat_from_rotvec(w * dt))
    d = quat_to_rotvec(quat_mul(quat_conj(q_ref_new), q_new))
    return np.concatenate([vn, d[:2]])


def test_transition_matrix_eqs40_44_against_finite_differences():
    """F = I + ΔT [[−[ω]× + Υ/m, Γ2], [0, Γ4]], with Γ4 = [[0, ω_z], [−ω_z, 0]] (no ½, eq 44)."""
    rng = np.random.default_rng(2)
    v, w, dt = rng.normal(size=3) * 2, rng.normal(size=3) * 4, 1e-3
    q_ref = quat_from_rotvec(rng.normal(size=3))
    x0 = np.zeros(5)
    x0[:3] = v
    fd = np.column_stack(
        [
            (_prior(x0[:3] + h[:3], q_ref, h[3:], w, dt) - _prior(x0[:3] - h[:3], q_ref, -h[3:], w, dt)) / 2e-6
            for h in np.eye(5) * 1e-6
        ]
    )
    # the compiled step builds F; recover it from one step of a single hypothesis without update
    f, U = np.empty(3), np.empty((3, 3))
    _aero(v, w, MODEL.A, MODEL.B, MODEL.C, MODEL.mass_kg, f, U)
    g = np.empty(3)
    gravity_body(q_ref, 9.80665, g)
    F = np.eye(5)
    F[:3, :3] += dt * (-np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) + U)
    F[:3, 3:] = dt * np.array([[0, -g[2]], [g[2], 0], [-g[1], g[0]]])
    F[3:, 3:] += dt * np.array([[0, w[2]], [-w[2], 0]])
    # F is the first-order transition; the exact discrete map differs by O((|ω|ΔT)²)
    np.testing.assert_allclose(F, fd, atol=2 * (np.linalg.norm(w) * dt) ** 2 + 1e-9)
    # and the compiled propagation of P agrees with F P Fᵀ + Q (no measurement: infinite noise)
    P0 = np.diag([1.0, 2.0, 3.0, 0.1, 0.2, 0.5])
    V, Qr, P, L = v[None].copy(), q_ref[None].copy(), P0[None].copy(), np.zeros(1)
    prm = BankRecord(gravity=9.80665, mass=MODEL.mass_kg, acc_var=1e30, q_vel=0.0, q_att=0.0, baro_var=0.0)
    bank_step(
        (V, Qr, P, L, np.zeros(1), w.copy()), (w, np.zeros(3), dt, True, np.nan), prm, (MODEL.A, MODEL.B, MODEL.C)
    )
    np.testing.assert_allclose(P[0, :5, :5], F @ P0[:5, :5] @ F.T, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(V[0], _prior(v, q_ref, np.zeros(2), w, dt)[:3], atol=1e-12)


def _height_prior_case(seed: int):
    """A random (v, ω, q_ref) and the finite-difference Jacobian of the exact prior of
    (v, δx, δy, z) at δ = 0, z = 1.5 (the height row ż = the body velocity's down component), and
    the exact prior's height."""
    rng = np.random.default_rng(seed)
    v, w, dt = rng.normal(size=3) * 2, rng.normal(size=3) * 4, 1e-3
    q_ref = quat_from_rotvec(rng.normal(size=3))

    def prior(x):
        q = quat_mul(q_ref, quat_from_rotvec([x[3], x[4], 0.0]))
        z = x[5] + dt * quat_rotate(q, x[:3])[2]  # NED down: the body velocity in the navigation frame
        return np.concatenate([_prior(x[:3], q_ref, x[3:5], w, dt), [z]])

    x0 = np.concatenate([v, [0.0, 0.0, 1.5]])
    fd = np.column_stack([(prior(x0 + h) - prior(x0 - h)) / 2e-6 for h in np.eye(6) * 1e-6])
    return v, w, dt, q_ref, fd, prior(x0)[5]


def test_bank_height_row_against_finite_differences():
    """The bank's height row ż = ĝᵀ v + δ · (v × ĝ) against finite differences of the exact prior,
    and its propagation of the whole 6x6 P is F P Fᵀ (no noise, no update)."""
    v, w, dt, q_ref, fd, z1 = _height_prior_case(6)
    P0 = np.diag([1.0, 2.0, 3.0, 0.1, 0.2, 0.5])
    V, Qr, P, L, Z = v[None].copy(), q_ref[None].copy(), P0[None].copy(), np.zeros(1), np.array([1.5])
    prm = BankRecord(gravity=9.80665, mass=MODEL.mass_kg, acc_var=1.0, q_vel=0.0, q_att=0.0, baro_var=0.09)
    bank_step((V, Qr, P, L, Z, w.copy()), (w, np.zeros(3), dt, False, np.nan), prm, (MODEL.A, MODEL.B, MODEL.C))
    tol = 2 * (np.linalg.norm(w) * dt) ** 2 + 1e-9
    np.testing.assert_allclose(P[0], fd @ P0 @ fd.T, atol=10 * tol)
    assert Z[0] == pytest.approx(z1, abs=1e-12)


def _level_fall(baro_var, ms=1000):
    """Two hypotheses of a level vehicle falling from rest under its rotors' constant thrust: the
    true attitude and upside down (which predicts a fall faster by twice the thrust per mass).
    The accelerometer made uninformative (its variance 1e30): only the barometer, read every
    20 ms from the true height, can tell them apart. Returns the log-likelihoods."""
    dt, g = 1e-3, 9.80665
    prm = BankRecord(gravity=g, mass=MODEL.mass_kg, acc_var=1e30, q_vel=0.0, q_att=0.0, baro_var=baro_var)
    V, L, Z = np.zeros((2, 3)), np.zeros(2), np.full(2, np.nan)
    Qr = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
    P = np.repeat(np.diag([9.0, 9, 9, 1, 1, 0.09])[None], 2, axis=0)
    v, z, w = np.zeros(3), -10.0, np.zeros(3)
    for k in range(ms):
        acc = MODEL.specific_force(v, w)
        v = v + dt * (acc + [0.0, 0.0, g])
        z += dt * v[2]
        baro = -z if k % 20 == 0 else np.nan
        bank_step((V, Qr, P, L, Z, w.copy()), (w, acc, dt, True, baro), prm, (MODEL.A, MODEL.B, MODEL.C))
    return L


def test_the_barometer_rules_out_a_hypothesis_that_falls_wrong():
    """With the barometer in the likelihood the upside-down hypothesis loses (its probability
    below 1e-3 after 1 s: 2 × 3 m/s² of thrust is 3 m of height by then, a tenth of that at 0.3
    s, when the readings hardly tell them apart); without it the two stay alike."""
    thrust = -MODEL.specific_force(np.zeros(3), np.zeros(3))[2]
    assert thrust > 1.0  # m/s², the rotors' constant thrust per mass along body −z
    with_baro, without = _level_fall(0.09), _level_fall(0.0)
    assert with_baro[0] == 0.0 and with_baro[1] < np.log(1e-3)
    assert abs(without[1] - without[0]) < 1e-6


# -- the bank --------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def ideal_throw():
    return simulate("throw", "fma", seed=21, ideal=True)


def _truth_dir(rec, k):
    return true_gravity_dir(rec.true_q[k])


def test_true_hypothesis_wins_on_noise_free_data(ideal_throw):
    rec = ideal_throw
    from quadest.recovery.logic import detect_throw

    k = detect_throw(rec.acc, 7.0, 3)
    others = spread_points(12)
    dirs = np.vstack([_truth_dir(rec, k), others])
    res = recover(rec, MODEL, RecoveryParams(beta2=0.0), dirs=dirs, record_all=True)
    # from 150 ms on the true hypothesis is the most likely (neighbours whose filters turn
    # towards it share the probability, so it need not hold most of it)
    for ms in (150, 250, 400):
        assert res.best[k + ms] == 0
        assert res.probabilities[k + ms, 0] > 2.0 / len(dirs)


def test_antipodal_hypothesis_is_ruled_out_quickly(ideal_throw):
    rec = ideal_throw
    from quadest.recovery.logic import detect_throw

    k = detect_throw(rec.acc, 7.0, 3)
    g = _truth_dir(rec, k)
    res = recover(rec, MODEL, RecoveryParams(beta2=0.0), dirs=np.vstack([g, -g]), record_all=True)
    # out within 300 ms (the bank converges in about 250 ms); it was below 1e-3 after 200 ms on
    # seeds 21-24
    assert res.probabilities[k + 300, 1] < 1e-6


def test_probabilities_stay_normalised_and_finite_over_a_million_steps():
    from numba import njit

    from quadest.recovery.bank import summarize

    @njit
    def run(V, Qr, P, L, Z, w, steps, prm, A, B, C, seed):
        np.random.seed(seed)
        prob = np.empty(V.shape[0])
        gd = np.empty((V.shape[0], 3))
        worst = 0.0
        gyr = np.empty(3)
        acc = np.empty(3)
        for k in range(steps):
            for j in range(3):
                gyr[j] = 0.5 + 0.01 * np.random.randn()
                acc[j] = 0.1 * np.random.randn()
            acc[2] -= 3.0
            bank_step((V, Qr, P, L, Z, w), (gyr, acc, 1e-3, True, np.nan), prm, (A, B, C))
            if k % 1000 == 0:
                summarize(Qr, L, prm.gravity, prob, gd)
                worst = max(worst, abs(prob.sum() - 1.0))
        return worst

    H = 12
    dirs = spread_points(H)
    V = np.zeros((H, 3))
    Qr = np.array([shortest_arc(d) for d in dirs])
    P = np.repeat(np.diag([9.0, 9, 9, 1, 1, 0.09])[None], H, axis=0)
    L = np.zeros(H)
    prm = RecoveryParams().bank_record(0.5)
    worst = run(V, Qr, P, L, np.zeros(H), np.zeros(3), 1_000_000, prm, MODEL.A, MODEL.B, MODEL.C, 3)
    assert worst < 1e-12
    assert np.isfinite(L).all() and L.max() == 0.0 and np.isfinite(P).all() and np.isfinite(V).all()


def test_shortest_arc_puts_the_hypothesis_on_gravity():
    rng = np.random.default_rng(4)
    for d in list(rng.normal(size=(20, 3))) + [np.array([0, 0, -1.0]), np.array([0, 0, 1.0])]:
        q = shortest_arc(d)
        np.testing.assert_allclose(quat_rotate(q, d / np.linalg.norm(d)), [0, 0, 1], atol=1e-12)


# -- the recovery logic -------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "scenario,preset", [("hover", "fma"), ("nominal", "fma"), ("hover", "bebop2"), ("nominal", "bebop2")]
)
def test_never_leaves_waiting_at_rest_or_in_normal_flight(scenario, preset):
    rec = simulate(scenario, preset, seed=3, duration=30)
    res = recover(rec, MODEL)
    assert res.detect_index is None and [e[0] for e in res.events] == ["waiting"]
    assert res.state_at(len(rec) - 1) == "waiting"
    still = simulate("hover", preset, seed=3, duration=10, overrides={"hover.gust_acc_rms": 0.0})
    assert recover(still, MODEL).detect_index is None


def test_a_throw_goes_through_every_state(ideal_throw):
    res = recover(simulate("throw", "fma", seed=5), MODEL)
    states = [e[0] for e in res.events]
    assert states == ["waiting", "thrown", "converging", "nominal"]
    t_rel = 1.0
    assert t_rel <= res.summary["t_detect_s"] < t_rel + 0.01
    assert 0.0 < res.summary["t_converge_s"] < 1.5
    assert res.summary["gravity_err_deg"] < 15.0 and res.summary["vel_err_mps"] < 0.5
    # after the hand-over the nominal estimator keeps the gravity direction
    tail = slice(-500, None)
    err = np.degrees(
        np.arccos(
            np.clip(
                np.sum(res.gravity_dir[tail] * true_gravity_dir(simulate("throw", "fma", seed=5).true_q[tail]), axis=1),
                -1,
                1,
            )
        )
    )
    assert err.max() < 10.0


# -- the nominal EKF with the height (after the handover) ------------------------------------------
def test_nominal_ekf_height_row_against_finite_differences():
    """The nominal EKF's transition (quadest.recovery.nominal): the bank's (v, δ) block and the
    height row ż = ĝᵀ v + δ · (v × ĝ), both against finite differences of the exact prior; its
    propagation of P is F P Fᵀ (no noise, no update)."""
    from quadest.recovery.nominal import nominal_step

    v, w, dt, q_ref, fd, z1 = _height_prior_case(5)
    P0 = np.diag([1.0, 2.0, 3.0, 0.1, 0.2, 0.5])
    V, Q, P, Z = v.copy(), q_ref.copy(), P0.copy(), np.array([1.5])
    prm = BankRecord(gravity=9.80665, mass=MODEL.mass_kg, acc_var=1.0, q_vel=0.0, q_att=0.0, baro_var=0.0)
    sample = (w, np.zeros(3), dt, False)
    nominal_step(V, Q, P, Z, w.copy(), sample, prm, (MODEL.A, MODEL.B, MODEL.C), np.nan, 0.0)
    # P = F P0 Fᵀ with F the finite differences (the first-order F is O((|ω|ΔT)²) off the exact map)
    tol = 2 * (np.linalg.norm(w) * dt) ** 2 + 1e-9
    np.testing.assert_allclose(P, fd @ P0 @ fd.T, atol=10 * tol)
    assert Z[0] == pytest.approx(z1, abs=1e-12)


def test_nominal_ekf_barometer_corrects_height_and_velocity():
    """A barometer reading 1 m above the EKF's height pulls the height up and, through the
    covariance the prior built between them, the vertical velocity up too; without a
    barometer (variance 0 or no reading) nothing is fused."""
    from quadest.recovery.nominal import barometer_update, nominal_step

    q = np.array([1.0, 0.0, 0.0, 0.0])  # level: body z is down
    P = np.diag([0.5, 0.5, 0.5, 0.01, 0.01, 0.04])
    P[2, 5] = P[5, 2] = 0.1  # height and vertical velocity correlated (as after a prior)
    v, z = np.zeros(3), np.array([-2.0])
    barometer_update(v, q, P, z, 3.0, 0.09)  # 3 m up, the EKF says 2 m up
    assert -3.0 < z[0] < -2.0 and v[2] < 0.0  # NED: higher and climbing
    np.testing.assert_allclose(P, P.T, atol=1e-15)
    assert np.all(np.linalg.eigvalsh(P) > 0) and P[5, 5] < 0.04
    prm = BankRecord(gravity=9.80665, mass=MODEL.mass_kg, acc_var=1.0, q_vel=0.0, q_att=0.0, baro_var=0.0)
    sample = (np.zeros(3), np.zeros(3), 1e-3, False)
    for baro, var in ((np.nan, 0.09), (3.0, 0.0)):
        v1, z1 = np.zeros(3), np.array([-2.0])
        model = (MODEL.A, MODEL.B, MODEL.C)
        nominal_step(v1, q.copy(), np.eye(6) * 0.1, z1, np.zeros(3), sample, prm, model, baro, var)
        assert z1[0] == pytest.approx(-2.0, abs=1e-6)


# -- the logic: re-arm and dwell ------------------------------------------------------------------
@pytest.mark.parametrize(
    "kwargs",
    [{"rearm_samples": -1}, {"rearm_samples": 1.5}, {"dwell_s": -0.1}, {"dwell_s": 11.0}, {"baro_std": -1.0}],
)
def test_recovery_parameters_out_of_bounds_are_refused(kwargs):
    from quadest.errors import UsageError

    with pytest.raises(UsageError, match=next(iter(kwargs))):
        RecoveryParams(**kwargs)


def test_a_spell_below_beta1_in_the_hand_is_rearmed(ideal_throw):
    """A hand that takes ‖z_acc‖ below β1 for 100 ms while it still holds the vehicle, then back
    to g: the detection there is re-armed and the throw is detected at its release; the
    handover waits the dwell. With the paper's logic (no re-arm) the detection stays in the hand."""
    from quadest.data.recording import Recording
    from quadest.recovery.logic import detect_throw

    k_rel = detect_throw(ideal_throw.acc, 7.0, 3)
    acc = ideal_throw.acc.copy()
    acc[200:300] = [0.0, 0.0, -3.0]  # the hand accelerating it downward at about g − 3 m/s²
    kw = {k: getattr(ideal_throw, k) for k in ("t", "gyr", "mag", *ideal_throw.truth)}
    rec = Recording(**kw, acc=acc, meta=ideal_throw.meta, check_units=False)
    res = recover(rec, MODEL)
    assert res.summary["detections"] == 2 and res.detect_index == k_rel
    assert res.summary["t_first_detect_s"] == pytest.approx(rec.t[202])
    assert rec.t[res.converge_index] - rec.t[k_rel] >= RecoveryParams().dwell_s - 1e-9
    paper = recover(rec, MODEL, RecoveryParams(rearm_samples=0, dwell_s=0.0))
    assert paper.detect_index == 202 and paper.summary["detections"] == 1
    # with the re-arm the release's own detection starts a fresh bank: the same as the unmodified throw's
    clean = recover(ideal_throw, MODEL)
    assert clean.converge_index == res.converge_index
    np.testing.assert_allclose(res.gravity_dir[res.converge_index], clean.gravity_dir[clean.converge_index], atol=1e-12)
