"""The rate of a clipped gyroscope axis (quadest.detect.rate): the Euler equations integrated
against their analytic solution, an axis within range returns the reading itself, a clipped
axis never reads below its limit, the magnetometer (eq R4) corrects a model that is wrong, and
bad input is refused."""

from dataclasses import replace

import numpy as np
import pytest

from quadest.detect import RatePredictor, RatePredictorParams
from quadest.models import vehicle_preset

BEBOP = vehicle_preset("bebop2")
# no drag, damping, inflow or rotor drag: the rotors' moments and ω × Jω alone
RIGID = replace(BEBOP, k_z=0.0, k_h=0.0, rot_drag=(0.0, 0.0, 0.0), damping=(0.0, 0.0, 0.0))
DT = 1.0 / 500.0
HOVER = np.sqrt(BEBOP.mass_kg * BEBOP.gravity / (4 * BEBOP.k_f))


def _run(vehicle, gyro_range, gyr, speeds, params=None, mag=None):
    n = len(gyr)
    pr = RatePredictor(vehicle, gyro_range, params or RatePredictorParams(rotor_speeds=True, use_mag=False))
    return pr.run(np.full(n, DT), gyr, speeds, None, mag)


def test_balanced_rotors_keep_a_still_vehicle_still():
    """Equal rotor speeds on the symmetric X layout (two rotors of each sense) give no moment;
    every axis clipped at a range of 1e-9 rad/s, the rate stays at the limit it started from
    (the drag at 1e-9 rad/s is 1e-22 N m) to 1e-15 rad/s over 2 s."""
    n = 1000
    lim = 1e-9
    params = RatePredictorParams(rotor_speeds=True, use_mag=False, clip_margin=0.0)
    out = _run(BEBOP, lim, np.full((n, 3), lim), np.full((n, 4), HOVER), params)
    assert np.abs(out - lim).max() < 1e-15


def test_a_constant_roll_moment_integrates_to_the_analytic_rate():
    """Rotors 0 and 3 (both at +y, opposite senses) faster by the same amount give a pure roll
    moment ``M_x = −2 b δT`` (no pitch: their arms cancel; no yaw: their reaction torques
    cancel). With the roll axis clipped (its reading at the limit, negative) and the others
    reading zero, the roll rate is ``ω_x(t) = −limit + M_x t / J_x``: Heun's method is exact for
    a constant derivative, so to rounding; pitch and yaw stay zero."""
    n = 500
    lim = 0.05
    speeds = np.full((n, 4), HOVER)
    speeds[:, [0, 3]] *= 1.05
    d_thrust = RIGID.k_f * (speeds[0, 0] ** 2 - HOVER**2)
    m_x = -2 * RIGID.rotor_pos[0][1] * d_thrust
    gyr = np.zeros((n, 3))
    gyr[:, 0] = -lim
    out = _run(RIGID, lim, gyr, speeds)
    expected = -lim + m_x / RIGID.inertia[0] * DT * np.arange(n)
    assert m_x < 0 and expected[-1] < -5.0  # a real test: 5 rad/s in a second
    np.testing.assert_allclose(out[:, 0], expected, rtol=1e-12, atol=1e-12)
    assert np.abs(out[:, 1:]).max() == 0.0


def test_an_axis_within_range_returns_the_gyroscope_bit_for_bit():
    """Readings within range, whatever the rotors do, come back unchanged; a clipped axis reads
    the model's rate, never below its limit."""
    rng = np.random.default_rng(3)
    n = 2000
    lim = 8.0
    gyr = rng.uniform(-7.9, 7.9, (n, 3))
    speeds = HOVER * rng.uniform(0.5, 1.5, (n, 4))
    out = _run(BEBOP, lim, gyr, speeds)
    assert np.array_equal(out, gyr)
    gyr[1000:, 2] = lim  # yaw clipped from the middle on, the rotors decelerating it
    speeds[1000:] = HOVER * np.array([0.7, 0.7, 1.2, 1.2])
    out = _run(BEBOP, lim, gyr, speeds)
    assert np.array_equal(out[:, :2], gyr[:, :2]) and np.array_equal(out[:1000, 2], gyr[:1000, 2])
    assert out[1000:, 2].min() >= lim
    assert np.array_equal(_run(BEBOP, np.inf, gyr, speeds), gyr)  # a gyroscope without a range never clips


def _spin(n, rates, field_noise, rng):
    """A spin about body z at ``rates`` (rad/s, per sample) with the field seen turning in the
    body (inclined 67°, a sample every 5 IMU samples, white noise), the attitude level."""
    angle = np.concatenate([[0.0], np.cumsum(rates[1:] * DT)])
    h, v = 49.0 * np.cos(np.radians(67.0)), 49.0 * np.sin(np.radians(67.0))
    mag = np.column_stack([h * np.cos(-angle), h * np.sin(-angle), np.full(n, v)])
    mag += field_noise * rng.standard_normal((n, 3))
    mag[np.arange(n) % 5 != 0] = np.nan
    return mag


def test_the_magnetometer_corrects_a_wrong_model_on_a_clipped_axis():
    """The model's yaw moment is wrong (its rotors balanced, no drag: it holds whatever rate it
    had) while the vehicle spins up from 0.5 to 3 rad/s past a 1 rad/s range. With the field's
    rate (eq R4, its noise learnt over the first 2 s within range; the field's rate 3.7 rad/s
    noisy per sample) the clipped yaw rate follows the spin-up, lags, overshoots by its bias
    state and settles within a few seconds: 0.4 rad/s RMS over the 5 s after the spin-up, 0.1
    over the last second; without it the model carries on with the angular acceleration its
    bias state learnt as the axis clipped, over 1 rad/s off in the last second."""
    rng = np.random.default_rng(5)
    n = 4000
    t = np.arange(n) * DT
    rates = np.clip(0.5 + 2.5 * (t - 2.0), 0.5, 3.0)
    mag = _spin(n, rates, 0.5, rng)
    gyr = np.zeros((n, 3))
    gyr[:, 2] = np.minimum(rates + 0.01 * rng.standard_normal(n), 1.0)
    speeds = np.full((n, 4), HOVER)
    with_mag = _run(RIGID, 1.0, gyr, speeds, RatePredictorParams(rotor_speeds=True), mag)
    without = _run(RIGID, 1.0, gyr, speeds, RatePredictorParams(rotor_speeds=True, use_mag=False), mag)
    after, last = t > 3.0, t > 7.0
    assert np.sqrt(np.mean((with_mag[after, 2] - rates[after]) ** 2)) < 0.4
    assert np.sqrt(np.mean((with_mag[last, 2] - rates[last]) ** 2)) < 0.1
    assert np.sqrt(np.mean((without[last, 2] - rates[last]) ** 2)) > 1.0


def test_a_bad_reading_does_not_poison_the_state():
    """A NaN gyroscope sample is returned as it is and leaves the state alone: the samples after
    it are, bit for bit, those of a run without it."""
    rng = np.random.default_rng(4)
    n = 400
    gyr = np.clip(rng.normal(0.0, 1.5, (n, 3)), -1.0, 1.0)
    speeds = HOVER * rng.uniform(0.8, 1.2, (n, 4))
    bad = gyr.copy()
    bad[200, 1] = np.nan
    out = _run(BEBOP, 1.0, bad, speeds)
    keep = np.arange(n) != 200
    ref = _run(BEBOP, 1.0, gyr[keep], speeds[keep])
    assert np.array_equal(out[200], bad[200], equal_nan=True)
    assert np.array_equal(out[keep], ref)


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="rate predictor"):
        RatePredictor(BEBOP, 8.0).run(np.full(3, DT), np.zeros((3, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="clip_margin"):
        RatePredictor(BEBOP, 8.0, RatePredictorParams(clip_margin=2.0))
