"""The rotor-level vehicle model, held to physics: a free rigid body keeps
its energy and angular momentum, rotors at the hover speed hold the vehicle still, a lost rotor
removes exactly its force and moment, inflow and motors behave as stated."""

from dataclasses import replace

import numpy as np
import pytest

from quadest.models.multirotor import MultirotorParams, derivative, fly_open_loop, rk4, rotor_forces
from quadest.rotation import euler_to_quat, quat_rotate

P = MultirotorParams()


def _energy_momentum(states, p):
    J = np.asarray(p.inertia)
    v, q, w = states[:, 3:6], states[:, 6:10], states[:, 10:13]
    energy = 0.5 * p.mass_kg * (v**2).sum(axis=1) + 0.5 * (J * w**2).sum(axis=1) - p.mass_kg * p.gravity * states[:, 2]
    momentum = quat_rotate(q, J * w)
    return energy, momentum


def test_a_free_rigid_body_keeps_energy_and_angular_momentum():
    """Rotors stopped, no drag or damping, gravity on: a tumbling body with three different
    moments of inertia (the intermediate axis is unstable: a demanding case) over 10 s at 1 kHz
    keeps its mechanical energy and its angular momentum in the navigation frame to 1e-6."""
    p = replace(
        P,
        inertia=(0.0023, 0.0031, 0.0046),
        body_drag=(0.0, 0.0, 0.0),
        damping=(0.0, 0.0, 0.0),
        rot_drag=(0.0, 0.0, 0.0),
    )
    V = p.vehicle()
    x = np.zeros(13 + p.rotors)
    x[3:6] = [1.0, 2.0, -3.0]
    x[6:10] = euler_to_quat([0.3, -0.2, 1.0])
    x[10:13] = [3.0, 0.05, 7.0]  # mostly about the intermediate axis's neighbours
    steps = 10_000
    out = np.empty((steps, len(x)))
    e0, h0 = _energy_momentum(x[None], p)
    fly_open_loop(x, np.zeros(p.rotors), np.ones(p.rotors), V, 1e-3, steps, out)
    e, h = _energy_momentum(out, p)
    assert np.abs(e - e0).max() / abs(e0) < 1e-6
    assert np.abs(h - h0).max() / np.linalg.norm(h0) < 1e-6
    assert np.abs(out[:, 10:13]).max() > 5.0  # it did tumble


def test_rotors_at_the_hover_speed_hold_the_vehicle_still():
    """Ω = √(m g / (4 k_f)): no acceleration, no angular acceleration, steady motors."""
    V = P.vehicle()
    x = P.hover_state()
    assert x[13] == pytest.approx(np.sqrt(P.mass_kg * P.gravity / (4 * P.k_f)))
    dx = np.empty_like(x)
    derivative(x, x[13:].copy(), np.ones(4), V, dx)
    assert np.abs(dx[3:6]).max() < 1e-12 and np.abs(dx[10:13]).max() < 1e-9 and np.abs(dx[13:]).max() < 1e-9
    out = np.empty((1000, len(x)))
    fly_open_loop(x, x[13:].copy(), np.ones(4), V, 1e-3, 1000, out)
    assert np.abs(out[-1, 0:6]).max() < 1e-9  # one second later, still at the origin


def test_a_lost_rotor_removes_exactly_its_force_and_moment():
    V = P.vehicle()
    x = P.hover_state()
    x[10:13] = [0.4, -0.3, 2.0]
    x[3:6] = [1.0, -0.5, 0.3]
    F, M = np.empty(3), np.empty(3)
    rotor_forces(x, np.ones(4), V, F, M, np.empty(4))
    for k in range(4):
        eta = np.ones(4)
        eta[k] = 0.0
        Fk, Mk = np.empty(3), np.empty(3)
        rotor_forces(x, eta, V, Fk, Mk, np.empty(4))
        only = np.zeros(4)
        only[k] = 1.0
        F1, M1 = np.empty(3), np.empty(3)
        rotor_forces(x, only, V, F1, M1, np.empty(4))
        body = np.empty(3), np.empty(3)
        rotor_forces(x, np.zeros(4), V, *body, np.empty(4))
        np.testing.assert_allclose(F - Fk, F1 - body[0], atol=1e-12)
        np.testing.assert_allclose(M - Mk, M1 - body[1], atol=1e-12)
    # losing the front-right rotor (clockwise) drops the front-right corner: the body rolls
    # right (+x) and pitches nose down (−y); the three others' reactions yaw it clockwise (+z)
    eta = np.array([0.0, 1.0, 1.0, 1.0])
    x = P.hover_state()
    rotor_forces(x, eta, V, F, M, np.empty(4))
    assert M[0] > 0 and M[1] < 0 and M[2] > 0


def test_thrust_depends_on_inflow_and_motors_are_first_order():
    V = P.vehicle()
    F, M = np.empty(3), np.empty(3)
    x = P.hover_state()
    rotor_forces(x, np.ones(4), V, F, M, np.empty(4))
    hover = -F[2]
    x[5] = 3.0  # falling at 3 m/s: the air comes from below, more thrust
    rotor_forces(x, np.ones(4), V, F, M, np.empty(4))
    assert -F[2] > hover
    x[5] = -3.0  # climbing: less
    rotor_forces(x, np.ones(4), V, F, M, np.empty(4))
    assert -F[2] < hover
    # a small speed step follows exp(−t/τ); a large one is limited by the rate
    p = replace(P, omega_dot_max=1e9)
    x = p.hover_state()
    start = x[13]
    out = np.empty((int(p.motor_tau_s / 1e-4), len(x)))
    fly_open_loop(x, np.full(4, start + 10.0), np.ones(4), p.vehicle(), 1e-4, len(out), out)
    assert out[-1, 13] - start == pytest.approx(10.0 * (1 - np.exp(-1.0)), rel=1e-3)
    p = replace(P, omega_dot_max=5e3)  # below (Ω_max − Ω_hover)/τ: the limit binds
    x = p.hover_state()
    rk4(x, np.full(4, p.omega_max), np.ones(4), p.vehicle(), 1e-3)
    assert x[13] - p.hover_speed() == pytest.approx(p.omega_dot_max * 1e-3, rel=1e-9)


def test_bad_vehicles_are_refused():
    with pytest.raises(ValueError, match="mass_kg must be in"):
        MultirotorParams(mass_kg=-1.0)
    with pytest.raises(ValueError, match="spin must hold"):
        MultirotorParams(spin=(1.0, 1.0, -1.0))
    with pytest.raises(ValueError, match="inertia must be three positive"):
        MultirotorParams(inertia=(0.0, 1.0, 1.0))


def _gyrostat(rotor_inertia=2e-5, inertia=(0.0023, 0.0031, 0.0046)):
    """Rotors at the centre of mass with no thrust, torque or drag: only their inertia acts."""
    return replace(
        P,
        inertia=inertia,
        rotor_pos=((0.0, 0.0, 0.0),) * 4,
        k_f=1e-12,
        k_m=0.0,
        k_z=0.0,
        k_h=0.0,
        body_drag=(0.0, 0.0, 0.0),
        damping=(0.0, 0.0, 0.0),
        rot_drag=(0.0, 0.0, 0.0),
        rotor_inertia=rotor_inertia,
    )


def _total_momentum(states, p):
    """Navigation-frame angular momentum of body and rotors: R (J ω + I_p Σ s_i Ω_i e_z)."""
    body = np.asarray(p.inertia) * states[:, 10:13]
    body[:, 2] += p.rotor_inertia * states[:, 13:] @ np.asarray(p.spin)
    return quat_rotate(states[:, 6:10], body)


def test_a_rotor_spin_up_keeps_the_total_angular_momentum():
    """A tumbling body whose rotors change speed (two speed up, two slow down, unequally) with
    no aerodynamic moment: the navigation-frame angular momentum of body and rotors is kept to
    1e-6 over 5 s; the body's alone is not (the rotors' momentum is 10 % of it)."""
    p = _gyrostat()
    x = np.zeros(13 + p.rotors)
    x[6:10] = euler_to_quat([0.3, -0.2, 1.0])
    x[10:13] = [3.0, 0.5, 4.0]
    x[13:] = [300.0, 300.0, 300.0, 300.0]
    h0 = _total_momentum(x[None], p)
    steps = 5000
    out = np.empty((steps, len(x)))
    fly_open_loop(x, np.array([800.0, 600.0, 100.0, 0.0]), np.ones(4), p.vehicle(), 1e-3, steps, out)
    h = _total_momentum(out, p)
    assert np.abs(h - h0).max() / np.linalg.norm(h0) < 1e-6
    body_only = quat_rotate(out[:, 6:10], np.asarray(p.inertia) * out[:, 10:13])
    assert np.abs(body_only - h0).max() / np.linalg.norm(h0) > 0.05


def test_the_reaction_to_a_rotor_spin_up_is_its_angular_momentum():
    """From rest, the rotors' momentum about z changes by Δh: the body turns the other way at
    ω_z = −Δh / J_z, to 1e-9."""
    p = _gyrostat()
    x = np.zeros(13 + p.rotors)
    x[6] = 1.0
    steps = 300
    out = np.empty((steps, len(x)))
    fly_open_loop(x, np.array([900.0, 900.0, 200.0, 200.0]), np.ones(4), p.vehicle(), 1e-3, steps, out)
    dh = p.rotor_inertia * out[:, 13:] @ np.asarray(p.spin)
    assert np.abs(out[:, 12] + dh / p.inertia[2]).max() < 1e-9
    assert np.abs(out[:, 10:12]).max() < 1e-12 and np.abs(dh).max() > 1e-2


def test_the_rotors_angular_momentum_turns_the_body_rate_at_the_closed_form_rate():
    """An axisymmetric body (J_x = J_y = J) with steady rotors of net momentum h about z and a
    small roll rate w: the Euler equations with the gyroscopic term give ω_x + i ω_y =
    w e^{i λ t}, λ = h / J (the rate vector turns about z); the flown rates agree to 1e-6 rad/s."""
    p = _gyrostat(rotor_inertia=1e-5, inertia=(0.002, 0.002, 0.004))
    x = np.zeros(13 + p.rotors)
    x[6] = 1.0
    x[10] = 0.2
    x[13:] = [700.0, 700.0, 300.0, 300.0]  # spin (+1, +1, −1, −1): h = I_p · 800
    h = p.rotor_inertia * x[13:] @ np.asarray(p.spin)
    steps = 2000
    out = np.empty((steps, len(x)))
    fly_open_loop(x, x[13:].copy(), np.ones(4), p.vehicle(), 1e-3, steps, out)
    t = 1e-3 * np.arange(1, steps + 1)
    lam = h / p.inertia[0]
    assert lam * t[-1] > 2 * np.pi  # more than a turn
    assert np.abs(out[:, 10] - 0.2 * np.cos(lam * t)).max() < 1e-6
    assert np.abs(out[:, 11] - 0.2 * np.sin(lam * t)).max() < 1e-6
