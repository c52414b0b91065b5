"""What a flown vehicle meets besides its scenario (the detection campaign's nominal flights):
the gyroscope's share of the rotors' blade-pass tone, wind and gusts acting on the flown
vehicle, a hard landing on sprung legs, and each case's sensors and wind drawn from its seed."""

import numpy as np
import pytest

from quadest.control.reference import circle_reference, figure_eight_reference
from quadest.control.se3 import thrust_floor
from quadest.evaluation.detection import case_config, disturbances, failure_case, nominal_case
from quadest.flight import FlightParams, fly
from quadest.flight.common import sensors_for
from quadest.models import MultirotorParams, vehicle_preset
from quadest.sim.sensors import rotor_vibration, rotor_vibration_model
from quadest.sim.wind import WindParams, wind_samples


def test_the_gyroscope_has_each_rotors_tone():
    """Rotors at different speeds: the gyroscope holds one tone per rotor at B Ω_i / 2π with
    amplitude ``g/√N (Ω_i/Ω_hover)²`` on each axis given one (least squares), nothing else."""
    V = MultirotorParams(blades=2)
    g = (0.06, 0.05, 0.008)
    offsets = np.random.default_rng(4).uniform(0, 6, (4, 4))
    rv = rotor_vibration_model(V, (0.0, 0.0, 0.0), offsets, (0, 0, 0), g)
    rate = 8000.0
    t = np.arange(int(2.0 * rate)) / rate
    omegas = np.array([380.0, 430.0, 470.0, 520.0])
    acc, gyr = rotor_vibration(rv, t, np.tile(omegas, (len(t), 1)), np.zeros((len(t), 4)))
    assert not acc.any()
    A = np.column_stack([f(V.blades * w * t) for w in omegas for f in (np.sin, np.cos)])
    for axis in range(3):
        coef, *_ = np.linalg.lstsq(A, gyr[:, axis], rcond=None)
        assert np.abs(gyr[:, axis] - A @ coef).max() < 1e-9
        fitted = np.hypot(coef[0::2], coef[1::2])
        np.testing.assert_allclose(fitted, g[axis] / 2.0 * (omegas / V.hover_speed()) ** 2, rtol=1e-9)


def test_a_flown_gyroscope_vibrates_as_drawn():
    """A case's circle: the gyroscope's reading minus the true rate, above 60 Hz, has the RMS of
    the drawn tone (``g/√2`` per axis: four rotors of amplitude ``g/2`` adding in power), the
    drawn white noise taken off, within 1.5× (the rotors' speeds move about hover's). On the
    circle the four rotors turn at different speeds, so their tones add in power; in a level
    hover they turn at nearly one speed and add by their drawn phases (anywhere from 0 to 2×),
    which is why the test flies the circle. Yaw's well below roll's and pitch's, as drawn."""
    case = nominal_case(7, "rotor-speeds", 6.0)
    cfg = case_config(case)
    f = fly("trajectory", seed=7, duration=6.0, vehicle="bebop2", config=cfg)
    rec = f.recording
    processes, _ = sensors_for(cfg, len(rec.t), 7, vehicle_preset("bebop2"))  # the flight's own draws
    ripple = (rec.gyr - rec.true_gyr - processes.gyr_noise)[rec.t > 2.0]
    spectrum = np.fft.rfft(ripple - ripple.mean(axis=0), axis=0)
    freqs = np.fft.rfftfreq(len(ripple), 1.0 / rec.meta["imu_rate_hz"])
    spectrum[freqs < 60.0] = 0.0  # the tone (3 blades × the rotors' turning) is far above the motion
    tone = np.fft.irfft(spectrum, n=len(ripple), axis=0)
    rms = np.sqrt((tone**2).mean(axis=0))
    expected = np.asarray(cfg.gyro.vibration_amp) / np.sqrt(2.0)
    assert expected[0] > 0.02 and expected[2] < expected[0] / 3
    assert (rms > expected / 1.5).all() and (rms < 1.5 * expected).all(), (rms, expected)
    assert rms[2] < 0.5 * min(rms[0], rms[1])


def test_wind_samples_have_the_asked_statistics():
    """The steady wind's speed, the turbulence's standard deviation (half of it vertically) and
    a gust's peak, from a long draw."""
    t = np.arange(0, 2000.0, 0.01)
    w = wind_samples(t, WindParams(mean_m_s=3.0, turbulence_m_s=1.0), np.random.default_rng(1))
    assert abs(np.hypot(*w[:, :2].mean(axis=0)) - 3.0) < 0.2
    np.testing.assert_allclose(w.std(axis=0), [1.0, 1.0, 0.5], rtol=0.15)
    g = wind_samples(t[:1000], WindParams(gusts=1, gust_m_s=5.0, gust_s=(1.0, 1.0)), np.random.default_rng(2))
    assert 0.0 < np.linalg.norm(g, axis=1).max() <= 5.0 * np.sqrt(1 + 1 / 9) + 1e-9


def test_a_gust_moves_the_flown_vehicle():
    """The same hover in still air and in a 4 m/s wind with a gust: the wind pushes the vehicle
    off its point (the controller does not know it), still air leaves the flight unchanged."""
    still = fly("hover", seed=3, duration=6.0, vehicle="bebop2")
    same = fly("hover", seed=3, duration=6.0, vehicle="bebop2", params=FlightParams(wind=WindParams()))
    gusty = FlightParams(wind=WindParams(mean_m_s=4.0, gusts=2, gust_m_s=5.0))
    windy = fly("hover", seed=3, duration=6.0, vehicle="bebop2", params=gusty)
    np.testing.assert_array_equal(still.states, same.states)
    late = still.recording.t > 3.0
    err = [np.linalg.norm(f.states[late, :3], axis=1).max() for f in (still, windy)]
    assert err[1] > err[0] + 0.05, err
    assert windy.summary["status"] == "survived"


@pytest.mark.parametrize("speed", [1.0, 2.0])
def test_a_hard_landing_is_an_impact(speed):
    """A hover ending in a descent at 1 and 2 m/s onto the ground 3 m below: the vehicle stands
    on its legs at the end (the centre of mass 5 cm above the ground, level); at the touchdown
    the accelerometer's z reads the legs' push, about ``v √(k/m)`` (63 rad/s for four legs of
    500 N/m on 0.5 kg) above gravity, within a factor 2 (the damping adds, the controller's
    thrust and the sensor's range take off)."""
    f = fly("hover", seed=5, duration=8.0, vehicle="bebop2", params=FlightParams(landing_m_s=speed))
    assert f.summary["status"] == "survived"
    x = f.states
    assert abs(x[-1, 2] - (3.0 - 0.05)) < 0.01 and np.abs(x[-1, 10:13]).max() < 0.1
    acc_z = f.recording.acc[:, 2]
    k = int(np.argmin(acc_z))
    assert 6.0 < f.recording.t[k] < 7.2  # touchdown near 1 s before the end
    peak = -acc_z[k] - 9.81
    expected = speed * np.sqrt(4 * 500.0 / 0.5)
    assert expected / 2 < peak < 2 * expected, (peak, expected)


def test_a_landing_that_does_not_fit_is_a_usage_error():
    """A flight of 2 s cannot stop a circle and descend 3 m by 1 s before its end: one line
    naming the option, not a landing that ends in the air."""
    from quadest.errors import UsageError
    from quadest.flight.landing import landing_reference

    t = np.arange(1000) / 500.0
    with pytest.raises(UsageError, match="landing_m_s"):
        landing_reference(circle_reference(t), t, 1.5, 3.0)
    with pytest.raises(UsageError, match="non-finite"):
        ref = circle_reference(np.arange(5000) / 500.0)
        ref[1][10, 0] = np.nan
        landing_reference(ref, np.arange(5000) / 500.0, 1.5, 3.0)


def test_a_landing_speeds_up_its_descent_as_an_autopilot_does():
    """A 2 m/s landing whose descent speeds up at 3 m/s² (PX4's MPC_ACC_DOWN_MAX) asks for 0.3 g
    less thrust: no rotor's command falls below 60 % of the hover's (√0.7 ≈ 0.84 at the ramp's
    start, less for the pitch and yaw control on top); a step to 2 m/s cuts the collective
    thrust to the controller's floor in the descent (PX4's MPC_THR_MIN, 0.12 of the rotors'
    most). Both touch down at the speed asked, within 5 %, about 1 s before the end."""
    for accel in (3.0, 0.0):
        f = fly(
            "hover",
            seed=5,
            duration=8.0,
            vehicle="bebop2",
            params=FlightParams(landing_m_s=2.0, landing_accel_m_s2=accel),
        )
        t, c, v = f.recording.t, f.commands, f.vehicle
        descent = (t > 3.0) & (t < 6.8)
        share = c[descent].min(axis=0) / np.median(c[(t > 2.0) & (t < 3.0)])
        floor = thrust_floor(v.mass_kg * v.gravity, v.rotors * v.k_f * v.omega_max**2)
        thrust = (v.k_f * c[descent] ** 2).sum(axis=1).min() / floor
        if accel > 0.0:
            assert share.min() > 0.6 and thrust > 1.5, (share, thrust)
        else:
            assert thrust == pytest.approx(1.0, abs=0.01), thrust
        k = int(np.argmin(f.recording.acc[:, 2]))
        assert abs(t[k] - 7.0) < 0.15 and abs(f.states[k - 5, 5] - 2.0) < 0.1


def test_cases_draw_their_disturbances_from_the_seed():
    """Each case's wind, sensors and landing follow from its seed (the same twice, another
    seed another), failures without a landing; a case's rotor and time are unchanged by them."""
    assert disturbances(3, 60.0, landing=True) == disturbances(3, 60.0, landing=True)
    assert disturbances(3, 60.0, landing=True) != disturbances(4, 60.0, landing=True)
    n = nominal_case(3, "commands", 60.0)
    assert 1.0 <= n["landing_m_s"] <= 2.0 and n["wind"]["gusts"] == 3
    f, plain = failure_case(3, "commands"), failure_case(3, "commands", disturbed=False)
    assert "landing_m_s" not in f and "wind" not in plain
    assert (f["rotor"], f["time_s"]) == (plain["rotor"], plain["time_s"])
    cfg = case_config(n)
    assert cfg.gyro.vibration_amp[0] > 0 and cfg.acc.noise_std != case_config(plain).acc.noise_std


def _landed(ref, t, speed=1.5, height=3.0):
    from quadest.flight.landing import landing_reference

    p, v, a, _ = landing_reference(ref, t, speed, height)
    k = int(np.flatnonzero(np.any(np.abs(p - ref[0]) > 1e-9, axis=1))[0])  # where the landing starts
    return p, v, a, k


@pytest.mark.parametrize(
    "name, ref_of",
    [
        ("circle at 8 m/s²", lambda t: circle_reference(t, radius=8.0, freq_hz=1.0 / (2 * np.pi))),
        ("figure eight at 12 m/s²", lambda t: figure_eight_reference(t, size=(1.5, 0.45), freq_hz=0.35)),
        *(
            (f"figure eight, phase {ph:.1f}", lambda t, ph=ph: figure_eight_reference(t, (1.5, 0.45), 0.35, 2.5, ph))
            for ph in (1.2, 2.6, 4.4)
        ),
    ],
)
def test_a_landing_stops_then_descends_as_an_autopilot_does(name, ref_of):
    """From a fast circle and the campaign's sharpest figure eight: the landing's reference takes
    over from the flight's with no jump in position, speed or acceleration; its speed and
    acceleration are its position's and speed's rates (within a sample's change); its jerk is
    at most ``max(4, |a₀|/0.5 s)``, its acceleration at most ``max(3 m/s², |a₀|)``; it stops
    within what unwinding ``a₀`` in 0.5 s, ramping to 3 m/s² at 4 m/s³ and braking take, and
    touches down vertically (under 5 cm/s sideways) at the speed asked, 1 s before the end
    (within 0.05 s, wherever in the figure eight it starts: the touchdown's time is not
    monotonic in the start), its acceleration steady in the descent, and descends on at that
    speed into the ground (an autopilot's landing does, until its land detector says landed)."""
    rate, speed, height = 500.0, 1.5, 3.0
    t = np.arange(int(30.0 * rate)) / rate
    ref = ref_of(t)
    p, v, a, k = _landed(ref, t, speed, height)
    p0, v0, a0 = ref[0][k], ref[1][k], ref[2][k]
    dt = 1.0 / rate
    assert np.abs(p[k] - p0).max() < 0.02 and np.abs(v[k] - v0).max() < 0.05 and np.abs(a[k] - a0).max() < 0.1
    air = slice(k, int(np.flatnonzero(p[:, 2] >= height)[0]) - 1)
    np.testing.assert_allclose(np.diff(p[air], axis=0) / dt, v[air][1:], atol=0.02)
    np.testing.assert_allclose(np.diff(v[air], axis=0) / dt, a[air][1:], atol=0.05)
    jerk = np.linalg.norm(np.diff(a[air], axis=0), axis=1) / dt
    assert jerk.max() <= max(4.0, np.linalg.norm(a0) / 0.5) * 1.01, name
    still = np.flatnonzero((np.hypot(v[air, 0], v[air, 1]) < 0.05) & (np.linalg.norm(a[air], axis=1) < 0.5))[0]
    assert jerk[still:].max() <= 4.0 * 1.01, name  # the descent's: PX4's
    assert np.linalg.norm(a[air], axis=1).max() <= max(3.0, np.linalg.norm(a0)) + 1e-6, name
    stop = np.linalg.norm(p[air][:, :2] - p0[:2], axis=1).max()
    v1 = np.linalg.norm(v0) + np.linalg.norm(a0) * 0.5 / 2  # the speed once a0 is unwound within 0.5 s
    brake = v1 * (0.5 + 3.0 / 4.0) + v1**2 / (2 * 3.0)  # the unwinding, the jerk's ramp to 3 m/s², the braking
    assert stop < brake, (name, stop, brake)
    down = int(np.flatnonzero(p[:, 2] >= height)[0])
    assert np.hypot(*v[down, :2]) < 0.05 and abs(v[down, 2] - speed) < 0.01, (name, v[down])
    assert abs(t[down] - (t[-1] - 1.0)) < 0.05, (name, t[down])
    assert np.allclose(v[down:, 2], speed) and np.abs(v[down:, :2]).max() < 0.05, name
    descent = slice(down - int(0.5 * rate), down)  # at the landing's speed: no chatter
    assert np.ptp(a[descent], axis=0).max() < 1e-6 and np.allclose(v[descent, 2], speed), name


@pytest.mark.parametrize("speed", [1.0, 2.0])
def test_the_land_detector_idles_the_rotors_after_a_touchdown(speed):
    """A hover landing at 1 and 2 m/s, the reference descending on into the ground: in the
    descent the SE(3) controller keeps PX4's limits (never upside down, at least 0.12 of the
    rotors' thrust), so on the ground the rotors keep that thrust until the land detector
    (PX4's) finds the ground contact, its conditions (a commanded descent, thrust under 0.3 of
    the way to the hover's, under 0.25 m/s up or down, 1.5 m/s sideways) held 0.35 s after the
    touchdown, never in the air, and the vehicle maybe landed 0.25 s later (under 0.1 of that
    way, rolling and pitching under 20 °/s): from then every rotor is commanded to idle and the
    vehicle stands level on its legs. Without the land detector the thrust stays at the floor."""
    flights = {
        on: fly(
            "hover", seed=5, duration=8.0, vehicle="bebop2", params=FlightParams(landing_m_s=speed, land_detector=on)
        )
        for on in (True, False)
    }
    f = flights[True]
    t, c = f.recording.t, f.commands
    touch = t[int(np.argmin(f.recording.acc[:, 2]))]
    landing = f.summary["landing"]
    assert touch + 0.35 <= landing["ground_contact_s"] < touch + 0.8, (touch, landing)
    assert landing["maybe_landed_s"] == pytest.approx(landing["ground_contact_s"] + 0.25, abs=0.01)
    idle = t >= landing["maybe_landed_s"] - 1e-9
    assert np.all(c[idle] == 0.0) and abs(f.states[-1, 2] - (3.0 - 0.05)) < 0.01
    assert np.abs(f.states[-1, 10:13]).max() < 0.1 and f.summary["status"] == "survived"
    free = flights[False]
    assert "landing" not in free.summary and free.summary["status"] == "survived"
    vehicle = f.vehicle
    floor = thrust_floor(vehicle.mass_kg * vehicle.gravity, vehicle.rotors * vehicle.k_f * vehicle.omega_max**2)
    on_ground = t > touch + 0.05
    assert (vehicle.k_f * free.commands[on_ground] ** 2).sum(axis=1).min() > 0.95 * floor
    assert (vehicle.k_f * c[on_ground & ~idle] ** 2).sum(axis=1).min() > 0.95 * floor


def test_a_vehicle_of_high_thrust_to_weight_lands_too():
    """The Hummingbird (thrust-to-weight 10): the descent's least thrust is half its weight, not
    0.12 of its rotors' most (1.2 times its weight, which would climb away), so it touches down,
    the land detector finds the contact and idles its rotors, and it stands on its legs."""
    f = fly("hover", seed=5, duration=8.0, vehicle="hummingbird", params=FlightParams(landing_m_s=1.0))
    v = f.vehicle
    assert thrust_floor(v.mass_kg * v.gravity, v.rotors * v.k_f * v.omega_max**2) == 0.5 * v.mass_kg * v.gravity
    assert f.summary["status"] == "survived" and f.summary["landing"]["maybe_landed_s"] is not None
    assert abs(f.states[-1, 2] - (3.0 - 0.05)) < 0.02 and np.all(f.commands[-1] == 0.0)
