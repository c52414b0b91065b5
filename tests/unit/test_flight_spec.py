"""A flight as one record (quadest.flight.spec.FlightSpec): fly() takes the record or a
scenario with changes to its fields, and both fly the same; what cannot fly is refused before
anything flies, by the record's own check."""

import dataclasses

import numpy as np
import pytest

from quadest.errors import UsageError
from quadest.flight import FlightParams, FlightSpec, fly
from quadest.flight.fly import check_flight
from quadest.sim.faults import Failure


def test_a_spec_and_its_fields_as_keywords_fly_the_same_flight():
    spec = FlightSpec("rotor-loss", vehicle="bebop2", seed=4, duration=3.0, failure=Failure(2, 1.0))
    by_record = fly(spec)
    by_keywords = fly("rotor-loss", vehicle="bebop2", seed=4, duration=3.0, failure=Failure(2, 1.0))
    by_change = fly(dataclasses.replace(spec, seed=5), seed=4)  # a change given to fly() wins
    for other in (by_keywords, by_change):
        np.testing.assert_array_equal(other.states, by_record.states)
        np.testing.assert_array_equal(other.recording.gyr, by_record.recording.gyr)
    assert by_record.summary["seed"] == 4 and by_record.recording.meta["failure"]["rotor"] == 2


def test_the_spec_is_completed_with_the_scenarios_defaults():
    r = FlightSpec("rotor-loss").resolved()
    assert (r.controller, r.duration, r.failure, r.vehicle_name) == ("ftc", 10.0, Failure(0, 2.0), "recovery")
    assert r.rates[0] == r.cfg.imu.rate_hz and r.rates[1] * r.rates[0] == pytest.approx(1000.0)
    assert FlightSpec("hover", params=FlightParams(collision="drawn")).resolved().duration == 16.0


@pytest.mark.parametrize(
    "spec, match",
    [
        (FlightSpec("cartwheel"), "unknown scenario"),
        (FlightSpec("hover", estimator="no-such-filter"), "unknown estimator"),
        (FlightSpec("hover", controller="ftc"), "complete rotor loss"),
        (FlightSpec("throw", estimator="robust"), "bank of EKFs"),
        (FlightSpec("hover", duration=-1.0), "duration"),
        (FlightSpec("hover", failure=Failure(7, 1.0), vehicle="bebop2"), "rotor"),
    ],
)
def test_what_cannot_fly_is_refused_by_the_spec_before_flying(spec, match):
    with pytest.raises(UsageError, match=match):
        check_flight(spec, seeds=(0, 1))
    with pytest.raises(UsageError, match=match):
        fly(spec)


def test_an_unknown_field_is_refused():
    with pytest.raises(TypeError, match="speed"):
        fly("hover", speed=3.0)
