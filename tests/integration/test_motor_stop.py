"""A motor that stops in flight (its propeller on, spinning down), the detector in the loop:
found by the speed test from the measured rotor speeds and the commands, named, within the time
its own sum takes for a first-order spin-down (docs/detection.md, The motor's speed)."""

import numpy as np
import pytest
from scipy.optimize import brentq

from quadest.detect import DetectorParams
from quadest.flight import FlightParams, fly
from quadest.models import vehicle_preset
from quadest.sim.faults import Failure

BEBOP = vehicle_preset("bebop2")


def _spin_down_bound(omega0: float, params: DetectorParams) -> float:
    """The oracle: when the speed test's sum passes its threshold for a motor spinning down from
    ``omega0`` at the model's time constant ``τ`` under a command held at ``omega0`` (the floor
    stays there). The shortfall ``a (1 − e^{−t/τ})``, ``a = Ω0 / Ω_max``, passes the drift ``ν``
    at ``t1 = −τ ln(1 − ν/a)``; from there the sum is ``(a − ν)(t − t1) − a τ (e^{−t1/τ} −
    e^{−t/τ})``. A controller that raises the stopped rotor's command as the vehicle tilts lifts
    the floor and only shortens it."""
    tau, a, nu = BEBOP.motor_tau_s, omega0 / BEBOP.omega_max, params.speed_drift
    t1 = -tau * np.log(1.0 - nu / a)

    def excess(t):
        return (a - nu) * (t - t1) - a * tau * (np.exp(-t1 / tau) - np.exp(-t / tau)) - params.speed_threshold

    return brentq(excess, t1, t1 + 1.0)


@pytest.mark.parametrize("rotor", [0, 1, 2, 3])
def test_a_stopped_motor_is_found_named_and_survived_in_the_loop(rotor):
    """Each rotor's motor stopped in hover (10 m up; `robust` in the loop, as the campaign flies),
    rotor speeds read with 1 % noise and the
    detector's model off by the campaign's ±10 %: the speed test names the rotor no later than two
    samples after the bound for its speed at the stop (about 25 ms at the hover's 695 rad/s; the
    loop's first sample after the stop is up to one late), the fault-tolerant controller takes
    over and the vehicle stays up. Without the speed test the same stop goes unfound for 0.5 s:
    the propeller still pushes at the speed it turns, and a stopped rotor is one expected to push
    nothing."""
    fail = Failure(rotor=rotor, time_s=2.0, mode="motor-stop")
    high = FlightParams(height_m=10.0)
    f = fly("rotor-loss", seed=rotor, duration=5.0, vehicle="bebop2", failure=fail, detection="rotor-speeds",
            params=high, estimator="robust")  # fmt: skip
    det = f.summary["detection"]
    omega0 = f.states[np.searchsorted(f.recording.t, fail.time_s), 13 + rotor]
    bound = _spin_down_bound(omega0, DetectorParams()) + 2.0 / 500.0
    assert det["lost_rotor"] == rotor and det["isolated"] and not det["false_alarm"], det
    assert 0.0 <= det["delay_s"] <= bound, (det["delay_s"], bound, omega0)
    assert f.summary["status"] == "survived", f.summary
    off = DetectorParams(speed_test=False)
    s = fly("rotor-loss", seed=rotor, duration=2.5, vehicle="bebop2", failure=fail, detection=off, params=high,
            estimator="robust").summary  # fmt: skip
    assert s["detection"]["lost_rotor"] is None, s["detection"]
