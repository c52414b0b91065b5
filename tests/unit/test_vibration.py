"""A flown vehicle's vibration: each rotor's blade-pass tone follows its own
speed, and a damaged propeller's imbalance shakes the IMU as the rigid body answers its
rotating force (checked against the Euler equations integrated here), in the closed loop as
in the batch sensor model."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from quadest.flight import fly
from quadest.models import MultirotorParams
from quadest.models.multirotor import quad_x
from quadest.sim.faults import Failure
from quadest.sim.sensors import rotor_vibration, rotor_vibration_model

# rotors 3 cm above the centre of mass, so that the imbalance rolls and pitches the body too
RAISED = MultirotorParams(rotor_pos=tuple((x, y, -0.03) for x, y, _ in quad_x(0.17)))
LEVER = (0.02, -0.01, 0.015)


@pytest.mark.parametrize("rotor", [0, 2])  # one of each sense
def test_the_imbalance_response_is_the_rigid_bodys(rotor):
    """A propeller's missing mass ``u`` at the angle ``θ = s ψ`` pulls with ``u Ω² [cos θ,
    sin θ, 0]`` at the rotor; the Euler equations ``J ω̇ = r × F − ω × J ω`` integrated with
    scipy (the gyroscopic term included, which the model neglects) give the gyroscope's
    ripple, and ``F/m + ω̇ × r_imu + ω × (ω × r_imu)`` the accelerometer's. The model agrees to
    2 % of the ripple's amplitude (the neglected terms are of order ``|ω|/Ω``)."""
    u, omega, rate = 5e-6, 450.0, 20000.0
    V = RAISED
    offsets = np.zeros((4, 4))
    offsets[:, 3] = 0.7  # the rotors' angle at the start
    rv = rotor_vibration_model(V, (0.0, 0.0, 0.0), offsets, LEVER)
    t = np.arange(int(0.1 * rate)) / rate  # 7 revolutions
    speeds = np.full((len(t), 4), omega)
    imb = np.zeros((len(t), 4))
    imb[:, rotor] = u
    acc, gyr = rotor_vibration(rv, t, speeds, imb)

    r, s, J = np.asarray(V.rotor_pos[rotor]), V.spin[rotor], np.asarray(V.inertia)

    def force(tt):
        theta = s * (0.7 + omega * tt)
        return u * omega**2 * np.array([np.cos(theta), np.sin(theta), 0.0])

    def rhs(tt, w):
        return (np.cross(r, force(tt)) - np.cross(w, J * w)) / J

    sol = solve_ivp(rhs, (0.0, t[-1]), gyr[0], t_eval=t, rtol=1e-10, atol=1e-12, method="DOP853")
    w_ode = sol.y.T
    amp_g = np.abs(w_ode).max()
    assert amp_g > 0.05  # the ripple is there: 0.1 rad/s about z for these numbers
    assert np.abs(gyr - w_ode).max() < 0.02 * amp_g
    wdot = np.array([rhs(tt, w) for tt, w in zip(t, w_ode)])
    lever = np.asarray(LEVER)
    f_ode = (
        np.array([force(tt) for tt in t]) / V.mass_kg + np.cross(wdot, lever) + np.cross(w_ode, np.cross(w_ode, lever))
    )
    amp_a = np.abs(f_ode).max()
    assert amp_a > u * omega**2 / V.mass_kg  # the centre's 2 m/s² and the lever arm's share
    assert np.abs(acc - f_ode).max() < 0.02 * amp_a


def test_each_rotor_has_its_blade_pass_tone():
    """Rotors at different speeds, one stopped: the accelerometer holds one tone per turning
    rotor at B Ω_i / 2π with amplitude ``a/√N (Ω_i/Ω_hover)²`` (fitted by least squares), and
    nothing at the stopped rotor's."""
    V = MultirotorParams(blades=3)
    amp = 0.4
    rv = rotor_vibration_model(V, (amp, 0.0, 0.0), np.random.default_rng(3).uniform(0, 6, (4, 4)), (0, 0, 0))
    rate = 8000.0
    t = np.arange(int(2.0 * rate)) / rate
    omegas = np.array([380.0, 430.0, 470.0, 0.0])
    acc, gyr = rotor_vibration(rv, t, np.tile(omegas, (len(t), 1)), np.zeros((len(t), 4)))
    assert not gyr.any() and not acc[:, 1:].any()
    cols = []
    for w in omegas[:3]:
        cols += [np.sin(V.blades * w * t), np.cos(V.blades * w * t)]
    A = np.column_stack(cols)
    coef, *_ = np.linalg.lstsq(A, acc[:, 0], rcond=None)
    assert np.abs(acc[:, 0] - A @ coef).max() < 1e-9  # nothing else in the signal
    fitted = np.hypot(coef[0::2], coef[1::2])
    expected = amp / 2.0 * (omegas[:3] / V.hover_speed()) ** 2
    np.testing.assert_allclose(fitted, expected, rtol=1e-9)


def test_a_damaged_propeller_shakes_the_flown_vehicle():
    """A hover whose rotor 2 loses a chip of its propeller at 1 s (90 % thrust, 5e-6 kg m):
    the vehicle flies on; the accelerometer's largest tone after the damage sits at rotor 2's
    turning frequency and the gyroscope's yaw ripple appears with it (the closed loop's
    readings equal the batch model's: ``flown_recording`` checks every flight)."""
    f = fly("hover", estimator="truth", seed=3, duration=3.0, failure=Failure(2, 1.0, 0.9, 5e-6))
    assert f.summary["status"] == "survived"
    rec = f.recording
    assert rec.meta["failure"]["imbalance"] == 5e-6
    before, after = (rec.t > 0.2) & (rec.t < 1.0), rec.t > 1.5
    ripple = rec.gyr[:, 2] - rec.true_gyr[:, 2]
    assert ripple[after].std() > 3 * ripple[before].std()
    x = rec.acc[after, 0] - rec.true_acc[after, 0]
    spectrum = np.abs(np.fft.rfft(x - x.mean()))
    freqs = np.fft.rfftfreq(len(x), 1.0 / rec.meta["imu_rate_hz"])
    peak = freqs[np.argmax(spectrum)]
    turning = f.states[after, 13 + 2].mean() / (2 * np.pi)
    assert peak == pytest.approx(turning, abs=2.0)
