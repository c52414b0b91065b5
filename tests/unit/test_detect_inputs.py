"""The detector's public entries check what they are given before the compiled code reads it:
shapes, the model's rotor count, units (rpm or 10⁴ rpm where rad/s is expected), each refused in
one line naming the argument; and the learnt moment's clamp reported."""

import warnings

import numpy as np
import pytest

from quadest.detect import Detector, RatePredictor, detect_run, detect_step, rate_step
from quadest.detect.layout import DIAG as DIAG_SIZE
from quadest.models import vehicle_preset

BEBOP = vehicle_preset("bebop2")
N = 200
HOVER = float(np.sqrt(BEBOP.mass_kg * 9.80665 / (4 * BEBOP.k_f)))  # rad/s, each rotor's in a hover


def _arrays(rotors=4, speed=HOVER):
    t = np.arange(N) * 0.002
    gyr = np.zeros((N, 3))
    acc = np.tile([0.0, 0.0, -9.80665], (N, 1))
    return t, gyr, acc, np.full((N, rotors), speed)


def _one_line(exc_info, *words):
    text = str(exc_info.value)
    assert "\n" not in text, text
    for w in words:
        assert w in text, text


def test_a_plausible_run_is_taken():
    t, gyr, acc, rotors = _arrays()
    res = Detector(BEBOP).run(t, gyr, acc, rotors)
    assert res.lost is None and res.effectiveness.shape == (N, 4) and res.moment_scale_clamped == []


@pytest.mark.parametrize(
    "change, words",
    [
        (
            {"rotors": 3},
            ("rotors has shape (200, 3), expected (200, 4)", "one column per rotor of the model (4 rotors)"),
        ),
        ({"speed": HOVER * 30 / np.pi}, ("rotors reach", "rpm? give rad/s")),
        ({"speed": HOVER * 30 / np.pi / 1e4}, ("rotors stay below", "10⁴ rpm")),
        ({"speed": 0.6}, ("rotors stay below", "normalised to 0..1")),
    ],
)
def test_detector_run_refuses_wrong_rotor_inputs(change, words):
    t, gyr, acc, rotors = _arrays(**change)
    with pytest.raises(ValueError) as e:
        Detector(BEBOP).run(t, gyr, acc, rotors)
    _one_line(e, "detector:", *words)


def test_detector_run_refuses_a_gap_a_negative_speed_and_wrong_shapes():
    t, gyr, acc, rotors = _arrays()
    bad = rotors.copy()
    bad[17, 2] = np.nan
    with pytest.raises(ValueError) as e:
        Detector(BEBOP).run(t, gyr, acc, bad)
    _one_line(e, "rotors has a non-finite value (row 17)", "hold the last reading")
    with pytest.raises(ValueError) as e:
        Detector(BEBOP).run(t, gyr, acc, -rotors)
    _one_line(e, "negative")
    with pytest.raises(ValueError) as e:
        Detector(BEBOP).run(t, gyr[:, :2], acc, rotors)
    _one_line(e, "gyr has shape (200, 2), expected (200, 3)")
    with pytest.raises(ValueError) as e:
        Detector(BEBOP).run(t, gyr, acc, rotors, commands=rotors[:, :3])
    _one_line(e, "commands has shape (200, 3)")


def test_detect_run_checks_its_low_level_arrays():
    det = Detector(BEBOP)
    x, p, c, _ = det.compiled()
    t, gyr, acc, rotors = _arrays()
    dt = np.full(N, 0.002)
    diag = np.zeros((N, DIAG_SIZE))
    detect_run(x, p, c, dt, gyr, acc, rotors, diag, np.zeros((0, 4)))  # as given: taken
    with pytest.raises(ValueError) as e:
        detect_run(x, p, c, dt, gyr, acc, rotors[:, :3], diag, np.zeros((0, 4)))
    _one_line(e, "detect_run: rotors has shape (200, 3), expected (200, 4)")
    with pytest.raises(ValueError) as e:
        detect_run(x, p, c[:-1], dt, gyr, acc, rotors, diag, np.zeros((0, 4)))
    _one_line(e, "detect_run: c is not a detector model")
    with pytest.raises(ValueError) as e:
        detect_run(x, p, c, dt, gyr, acc, rotors, diag[:, :-1], np.zeros((0, 4)))
    _one_line(e, "diag_out")
    with pytest.raises(ValueError) as e:
        detect_run(x[:-1], p, c, dt, gyr, acc, rotors, diag, np.zeros((0, 4)))
    _one_line(e, "detect_run: x must be")


def test_the_per_sample_entries_check_too():
    det = Detector(BEBOP)
    with pytest.raises(ValueError) as e:
        det.update([0, 0, 0], [0, 0, -9.8], [HOVER] * 3, dt=0.002)
    _one_line(e, "detector: rotors has shape (3,), expected (4,)", "4 rotors")
    with pytest.raises(ValueError) as e:
        det.update([0, 0, 0], [0, 0, -9.8], [HOVER * 30 / np.pi] * 4, dt=0.002)
    _one_line(e, "rpm?")
    x, p, c, diag = det.compiled()
    assert detect_step(x, p, c, np.zeros(3), np.array([0, 0, -9.8]), np.full(4, HOVER), 0.002, diag) == -1
    with pytest.raises(ValueError) as e:
        detect_step(x, p, c, np.zeros(3), np.array([0, 0, -9.8]), np.full(3, HOVER), 0.002, diag)
    _one_line(e, "detect_step: rotors has shape (3,), expected (4,)")


def test_the_rate_predictor_checks_its_inputs():
    pred = RatePredictor(BEBOP, np.inf)
    t, gyr, _, rotors = _arrays()
    dt = np.full(N, 0.002)
    assert pred.run(dt, gyr, rotors).shape == (N, 3)
    with pytest.raises(ValueError) as e:
        pred.run(dt, gyr, rotors[:, :3])
    _one_line(e, "rate predictor: rotors has shape (200, 3), expected (200, 4)")
    with pytest.raises(ValueError) as e:
        pred.run(dt, gyr, rotors * 30 / np.pi)
    _one_line(e, "rpm?")
    x, p, c = pred.compiled()
    out = np.zeros(3)
    with pytest.raises(ValueError) as e:
        rate_step(x, p, c, np.zeros(3), np.full(3, np.nan), np.full(3, HOVER), np.ones(3), np.inf, 0.002, out)
    _one_line(e, "rate_step: rotors has shape (3,), expected (4,)")


def _roll_driven(gain, duration=40.0, rate=500.0, alpha=40.0):
    """A roll oscillation (1.5 Hz, the model's angular acceleration ``alpha`` in amplitude) made by
    the rotors' thrust differences about the Bebop 2's hover, integrated here with the true moment
    ``gain`` times the model's (and the model's damping): an identification target known exactly."""
    t = np.arange(int(duration * rate)) / rate
    arm = -np.asarray(BEBOP.rotor_pos, float)[:, 1]  # the roll moment per unit thrust
    shares = alpha * BEBOP.inertia[0] * np.sin(2 * np.pi * 1.5 * t)[:, None] * arm / (arm @ arm)
    thrust = BEBOP.k_f * HOVER**2 + shares
    moment = (thrust * arm).sum(axis=1)
    w = np.zeros(len(t))
    for k in range(1, len(t)):
        w[k] = w[k - 1] + (gain * moment[k] - BEBOP.damping[0] * w[k - 1]) / BEBOP.inertia[0] / rate
    zeros = np.zeros_like(w)
    acc = np.column_stack([zeros, zeros, -thrust.sum(axis=1) / BEBOP.mass_kg])
    return t, np.column_stack([w, zeros, zeros]), acc, np.sqrt(thrust / BEBOP.k_f)


def test_the_moment_learnt_at_its_clamp_is_reported():
    """The true roll moment 1.2 times the model's: the moment learnt goes within 3 % of 1.2, no
    clamp. Twice the model's: past the clamp (1.3), which the result names ('x', the scale at
    1.3) and a warning says once; a later run of the same detector does not say it again."""
    t, gyr, acc, speeds = _roll_driven(1.2)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        near = Detector(BEBOP).run(t, gyr, acc, speeds)
    assert abs(near.moment_scale[0] - 1.2) < 0.036 and near.moment_scale_clamped == []
    t, gyr, acc, speeds = _roll_driven(2.0)
    det = Detector(BEBOP)
    with pytest.warns(UserWarning, match="learnt about x reached its clamp") as said:
        off = det.run(t, gyr, acc, speeds)
    assert off.moment_scale_clamped == ["x"] and len(said) == 1
    assert off.moment_scale[0] == pytest.approx(1.3, abs=1e-12)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        det.run(t[-100:] + t[-1] + 1.0, gyr[-100:], acc[-100:], speeds[-100:])
