"""Failures as profiles (quadest.sim.faults): each mode's profile, the record's one serialised
form, and the flown physics of the modes a motor takes part in."""

import math

import numpy as np
import pytest

from quadest.errors import UsageError
from quadest.models.multirotor import vehicle_preset
from quadest.sim.faults import FAILURE_MODES, Failure

RATE = 500.0

EXAMPLES = [
    Failure(0, 2.0),
    Failure(1, 3.0, 0.6),
    Failure(2, 1.0, 0.9, 5e-6),
    Failure(0, 2.0, mode="motor-stop"),
    Failure(3, 2.0, 0.7, mode="gradual", ramp_s=3.0),
    Failure(0, 1.5, mode="gradual", ramp_s=0.25),
    Failure(1, 2.0, mode="desync", off_s=0.05, period_s=0.5),
]


def test_every_mode_has_an_example():
    assert {f.mode for f in EXAMPLES} | {"partial"} == set(FAILURE_MODES)


def test_the_numbers_imply_the_modes_of_the_first_failures():
    assert [f.mode for f in EXAMPLES[:3]] == ["propeller-off", "partial", "damaged-propeller"]


@pytest.mark.parametrize("failure", EXAMPLES, ids=str)
def test_one_serialised_form_reads_back(failure):
    assert Failure.from_dict(failure.to_dict()) == failure
    assert Failure.parse(str(failure)) == failure


def test_failures_written_before_the_modes_keep_their_keys():
    assert Failure(0, 2.0).to_dict() == {"rotor": 0, "time_s": 2.0, "efficiency": 0.0}
    assert Failure(2, 1.0, 0.9, 5e-6).to_dict() == {"rotor": 2, "time_s": 1.0, "efficiency": 0.9, "imbalance": 5e-6}
    assert Failure.parse("1@3:0.6") == Failure(1, 3.0, 0.6)


@pytest.mark.parametrize(
    "failure, complete, lost_s",
    [(EXAMPLES[0], True, 2.0), (EXAMPLES[1], False, 3.0), (EXAMPLES[3], True, 2.0), (EXAMPLES[4], False, 5.0),
     (EXAMPLES[5], True, 1.75), (EXAMPLES[6], False, 2.0)],
    ids=str,
)  # fmt: skip
def test_a_complete_loss_is_asked_of_the_record(failure, complete, lost_s):
    assert failure.complete is complete and failure.lost_s == lost_s


def test_propeller_off_and_motor_stop_profiles():
    k0, eta, drive, imb = Failure(0, 2.0).profile(RATE, 5000, 4)
    assert k0 == 1000 and eta.tolist() == [[0.0, 1, 1, 1]] and drive.tolist() == [[1.0] * 4] and not imb.any()
    k0, eta, drive, _ = Failure(2, 2.0, mode="motor-stop").profile(RATE, 5000, 4)
    assert eta.tolist() == [[1.0] * 4] and drive.tolist() == [[1.0, 1, 0, 1]]


def test_a_gradual_loss_fades_linearly_then_holds():
    f = Failure(3, 2.0, 0.7, mode="gradual", ramp_s=3.0)
    k0, eta, drive, _ = f.profile(RATE, 10_000, 4)
    t = np.arange(len(eta)) / RATE
    assert len(eta) == 3 * 500 + 1 and eta[-1, 3] == pytest.approx(0.7, abs=1e-15)
    np.testing.assert_allclose(eta[:, 3], 1.0 - 0.3 * t / 3.0, atol=1e-12)
    assert (eta[:, :3] == 1.0).all() and (drive == 1.0).all()


def test_a_desync_drops_the_motor_for_off_s_of_every_period():
    f = Failure(1, 2.0, mode="desync", off_s=0.05, period_s=0.5)
    k0, _, drive, _ = f.profile(RATE, 3000, 4)
    assert len(drive) == 2000  # to the end of the flight
    off = drive[:, 1] == 0.0
    assert off.sum() == 8 * 25  # 25 samples of 2 ms in each of the eight periods of 0.5 s
    assert off[:25].all() and not off[25:250].any() and off[250:275].all()


@pytest.mark.parametrize(
    "text, says",
    [
        ("spin:0@2", "--failure expects"),
        ("0@2,ramp_s=3", "--failure expects"),  # ramp_s is the gradual loss's
        ("motor-stop:0@2:0.5", "no efficiency"),
        ("gradual:0@2:1", "efficiency in [0, 1)"),
        ("gradual:0@2,ramp_s=0", "ramp_s"),
        ("desync:0@2,off_s=0.6", "off_s < period_s"),
        ("damaged-propeller:0@2:0.9", "imbalance > 0"),
        ("4@1", "rotor 4 does not exist"),
        ("0@9", "outside the run"),
    ],
)
def test_refused_in_one_line(text, says):
    with pytest.raises(UsageError, match=None) as err:
        Failure.parse(text).check(vehicle_preset("bebop2"), 8.0)
    assert says in str(err.value) and "\n" not in str(err.value)


def test_an_unknown_field_is_refused():
    with pytest.raises(UsageError, match="unknown field"):
        Failure.from_dict({"rotor": 0, "time_s": 1.0, "efficency": 0.5})


# -- flown: what the motor does ------------------------------------------------------------------------
@pytest.fixture(scope="module")
def flights():
    from quadest.flight import fly

    kw = dict(estimator="truth", vehicle="bebop2", seed=1, duration=4.0)
    return {
        "motor-stop": fly("rotor-loss", failure=Failure(0, 2.0, mode="motor-stop"), **kw),
        "gradual": fly("hover", failure=Failure(0, 2.0, 0.7, mode="gradual", ramp_s=1.0), **kw),
        "desync": fly("hover", failure=Failure(0, 2.0, mode="desync", off_s=0.05, period_s=0.5), **kw),
    }


def test_a_stopped_motor_spins_down_at_the_motor_time_constant(flights):
    """ω̇ = −ω / τ with the drive gone (below the rate limit): ω(t0 + τ) = ω(t0) / e."""
    f, v = flights["motor-stop"], vehicle_preset("bebop2")
    t, w = f.recording.t, f.states[:, 13]
    k0 = int(np.searchsorted(t, 2.0))
    assert w[k0 - 1] / v.motor_tau_s < v.omega_dot_max  # the exponential, not the rate limit
    # the loop applies the failure at sample k0, so the decay starts from the speed at k0
    k1 = k0 + int(round(v.motor_tau_s * RATE))
    assert w[k1] == pytest.approx(w[k0] * math.exp(-(t[k1] - t[k0]) / v.motor_tau_s), rel=1e-3)
    assert w[-1] < 1e-3 * w[k0] and (f.eta[:, 0] == 1.0).all()  # the propeller is on, the motor off


def test_a_gradual_loss_flies_its_profile(flights):
    f = flights["gradual"]
    t = f.recording.t
    expected = np.clip(1.0 - 0.3 * (t - 2.0) / 1.0, 0.7, 1.0)
    np.testing.assert_allclose(f.eta[:, 0], expected, atol=1e-9)


def test_a_desync_lets_the_rotor_sag_and_recover(flights):
    f = flights["desync"]
    t, w = f.recording.t, f.states[:, 13]
    before = w[(t > 1.8) & (t < 2.0)].mean()
    dip = w[(t >= 2.0) & (t < 2.06)].min()
    back = w[(t > 2.3) & (t < 2.5)].mean()
    assert dip < 0.4 * before and back == pytest.approx(before, rel=0.1)
