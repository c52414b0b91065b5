"""The detector's speed test (quadest.detect.speed; docs/detection.md, The motor's speed): a
stopped motor and a desync found within the time the test's own sum takes for a first-order
spin-down (the oracle: that sum integrated in closed form), and working motors whose time
constant is half or twice the model's and whose top speed is 15 % low, read at 100 Hz with 1 %
noise under full-range command steps, never named."""

import numpy as np
import pytest

from quadest.detect import DetectorParams
from quadest.detect.layout import STATE
from quadest.detect.model import model_coefficients
from quadest.detect.params import PARAM
from quadest.detect.speed import speed_test
from quadest.models import vehicle_preset
from quadest.records import pack

BEBOP = vehicle_preset("bebop2")
DT = 0.002  # s: the Bebop 2 preset's IMU interval
HOVER = float(np.sqrt(BEBOP.mass_kg * BEBOP.gravity / (4 * BEBOP.k_f)))  # rad/s: 695


def _motor(cmds, drive, tau, top, rng, hold=1, noise=0.01):
    """A first-order motor as the simulator's (``Ω̇ = (drive · clip(u) − Ω) / τ``, its rate
    limit), integrated in ten steps a sample, read every ``hold`` samples with relative noise."""
    w, out = float(cmds[0]), np.empty(len(cmds))
    for k, u in enumerate(cmds):
        for _ in range(10):
            rate = (drive[k] * min(max(u, BEBOP.omega_min), top) - w) / tau
            w += DT / 10 * min(max(rate, -BEBOP.omega_dot_max), BEBOP.omega_dot_max)
        out[k] = w
    out = out[(np.arange(len(out)) // hold) * hold]
    return out * (1.0 + noise * rng.standard_normal(len(out)))


def _run(cmds, speeds, params=None):
    """The speed test over a run of one rotor's commands and readings (the other three rotors
    commanded and read at hover): the sample where it names a rotor (None), that rotor, and
    the largest sum."""
    params = params or DetectorParams()
    p, c = pack(params.values()[f] for f in PARAM._fields), model_coefficients(BEBOP)
    x = np.zeros(STATE.end)
    x[STATE.lost] = -1.0
    x[STATE.cmd_known] = 1.0
    x[STATE.speed_low : STATE.speed_low + 4] = speeds[0], HOVER, HOVER, HOVER
    top = 0.0
    for k in range(1, len(cmds)):
        x[STATE.cmd : STATE.cmd + 4] = cmds[k], HOVER, HOVER, HOVER
        x[STATE.time] += DT
        speed_test(x, p, c, np.array([speeds[k], HOVER, HOVER, HOVER]), DT)
        top = max(top, x[STATE.s_speed : STATE.s_speed + 4].max())
        if x[STATE.lost] >= 0.0:
            return k, int(x[STATE.lost]), top
    return None, None, top


def _time_to_find(omega0, tau, params=None):
    """The oracle: the time the test's sum takes to pass its threshold for a motor spinning down
    from ``omega0`` with its command held there, ``S(t) = ∫ max(0, (Ω0/Ω_max)(1 − e^{−u/τ}) − ν) du``
    (the floor stays at the command), integrated finely."""
    params = params or DetectorParams()
    t = np.arange(0.0, 1.0, 1e-5)
    s = np.maximum(omega0 / BEBOP.omega_max * (1.0 - np.exp(-t / tau)) - params.speed_drift, 0.0)
    return t[np.searchsorted(np.cumsum(s) * 1e-5, params.speed_threshold)]


@pytest.mark.parametrize("tau_ratio", [1.0, 2.0, 0.5])
@pytest.mark.parametrize("omega0", [HOVER, 0.5 * BEBOP.omega_max])
def test_a_stopped_motor_is_found_when_its_shortfall_says(omega0, tau_ratio):
    """Stopped at ``omega0`` with its command held: named within two samples of the closed-form
    time for the true time constant (the model's × 0.5 to × 2); a hover stop with the model's
    own in about 25 ms (6 ms to pass the drift, 18 more to sum the threshold)."""
    rng = np.random.default_rng(1)
    n, k0 = 200, 20
    cmds, drive = np.full(n, omega0), np.ones(n)
    drive[k0:] = 0.0
    speeds = _motor(cmds, drive, BEBOP.motor_tau_s * tau_ratio, BEBOP.omega_max, rng)
    k, rotor, _ = _run(cmds, speeds)
    expected = _time_to_find(omega0, BEBOP.motor_tau_s * tau_ratio)
    assert rotor == 0
    assert (k - k0) * DT == pytest.approx(expected, abs=2 * DT)
    if omega0 == HOVER and tau_ratio == 1.0:
        assert 0.018 < expected < 0.025


def test_a_desync_is_found_in_its_first_stutter():
    """Unpowered for 50 ms of every 500 ms: found within the first 50 ms at hover speed (the
    closed-form time, about 25 ms, with the model's time constant)."""
    rng = np.random.default_rng(2)
    n, k0 = 600, 50
    cmds = HOVER + 20.0 * rng.standard_normal(n)
    t = (np.arange(n) - k0) * DT
    drive = np.where(t < 0, 1.0, (np.mod(t + 1e-12, 0.5) >= 0.05).astype(float))
    k, rotor, _ = _run(cmds, _motor(cmds, drive, BEBOP.motor_tau_s, BEBOP.omega_max, rng))
    assert rotor == 0 and (k - k0) * DT <= _time_to_find(HOVER, BEBOP.motor_tau_s) + 2 * DT < 0.05


@pytest.mark.parametrize(
    ("tau_ratio", "top_share", "hold"),
    [(1.0, 1.0, 1), (2.0, 1.0, 5), (0.5, 1.0, 5), (1.0, 0.85, 5), (0.5, 0.85, 5), (2.0, 0.85, 1)],
)
def test_working_motors_off_the_model_are_never_named(tau_ratio, top_share, hold):
    """Full-range command steps (0-1400 rad/s, held 2-80 ms) for 20 s on a motor whose time
    constant and top speed are off the model's by the errors the test stands (× 0.5 to × 2,
    15 % low), read every sample or held 10 ms (100 Hz telemetry) with 1 % noise: nothing named,
    the largest sum below the threshold (chosen at 1.7 times the largest of these, 0.00115)."""
    rng = np.random.default_rng(3)
    n = 10_000
    cmds = np.repeat(rng.uniform(0.0, 1400.0, n), rng.integers(1, 41, n))[:n]
    speeds = _motor(cmds, np.ones(n), BEBOP.motor_tau_s * tau_ratio, top_share * BEBOP.omega_max, rng, hold)
    k, rotor, top = _run(cmds, speeds)
    assert k is None and top < DetectorParams().speed_threshold


def test_the_speed_test_waits_for_the_commands_and_can_be_turned_off():
    """Without commands (``STATE.cmd_known`` 0) or with ``speed_test`` off, a stopped motor is
    not the speed test's to name."""
    rng = np.random.default_rng(4)
    cmds, drive = np.full(100, HOVER), np.r_[np.ones(10), np.zeros(90)]
    speeds = _motor(cmds, drive, BEBOP.motor_tau_s, BEBOP.omega_max, rng)
    assert _run(cmds, speeds, DetectorParams(speed_test=False))[0] is None
    p, c = pack(DetectorParams().values()[f] for f in PARAM._fields), model_coefficients(BEBOP)
    x = np.zeros(STATE.end)
    x[STATE.lost] = -1.0
    for k in range(100):
        speed_test(x, p, c, np.array([speeds[k], HOVER, HOVER, HOVER]), DT)
    assert x[STATE.lost] == -1.0 and not x[STATE.s_speed : STATE.s_speed + 4].any()
