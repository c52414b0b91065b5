"""The plant as an interface (quadest.flight.plant): the loop run from Python around a plant
flies quadest's compiled vehicle as the compiled loop does, so another simulator's plant flies
through the same loop."""

import importlib

import numpy as np
import pytest

from quadest.flight import FlightParams, fly
from quadest.flight.plant import CompiledPlant, fly_plant
from quadest.sim.faults import Failure
from quadest.sim.wind import WindParams

fly_module = importlib.import_module("quadest.flight.fly")  # the module (quadest.flight.fly is the function)

CASES = {
    "rotor loss, robust, detector": dict(
        scenario="rotor-loss", estimator="robust", detection="rotor-speeds", failure=Failure(1, 1.5),
        params=FlightParams(wind=WindParams(mean_m_s=3.0, turbulence_m_s=0.5)),
    ),
    "gradual loss, truth": dict(
        scenario="hover", estimator="truth", failure=Failure(2, 1.0, 0.6, mode="gradual", ramp_s=1.0)
    ),
    "motor stop, oracle": dict(scenario="rotor-loss", estimator="truth", failure=Failure(0, 1.5, mode="motor-stop")),
}  # fmt: skip


def _through_the_interface(x, loop, est):
    return fly_plant(CompiledPlant(loop), x, loop, est.args if est.peer is None else est.peer.update)


@pytest.mark.parametrize("case", list(CASES))
def test_the_compiled_vehicle_flies_the_same_through_the_interface(case, monkeypatch):
    kw = dict(CASES[case])
    scenario = kw.pop("scenario")
    direct = fly(scenario, vehicle="bebop2", seed=2, duration=4.0, **kw)
    monkeypatch.setattr(fly_module, "_run", _through_the_interface)
    via = fly(scenario, vehicle="bebop2", seed=2, duration=4.0, **kw)
    assert via.summary["status"] == direct.summary["status"]
    np.testing.assert_array_equal(via.states, direct.states)
    np.testing.assert_array_equal(via.recording.gyr, direct.recording.gyr)
    np.testing.assert_array_equal(via.commands, direct.commands)
    assert via.summary.get("detection") == direct.summary.get("detection")


def test_a_plant_of_its_own_flies_no_throw(monkeypatch):
    """A throw's loop holds the hand: refused before its first sample."""
    import quadest.flight.throw as throw_module

    class Idle:
        def truth(self, k, cmd, out): ...

        def step(self, k, cmd, x): ...

    monkeypatch.setattr(throw_module, "closed_loop", lambda x, loop, est=None: fly_plant(Idle(), x, loop))
    with pytest.raises(ValueError, match="no throw"):
        fly("throw", estimator="truth", seed=0, duration=1.0)
