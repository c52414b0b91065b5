"""Diagnosing a recording with rotor speeds against a vehicle (quadest.evaluation.diagnose_speeds):
what it refuses, and the drag's moments packed into the detector's model where its compiled step
reads them."""

import numpy as np
import pytest

from quadest.data import Recording
from quadest.detect.layout import MODEL
from quadest.detect.model import model_coefficients
from quadest.evaluation.diagnose_speeds import diagnose_speeds
from quadest.models.multirotor import MultirotorParams


def _rec(rotors=4, speeds=True):
    t = np.arange(200) / 100.0
    acc = np.tile([0.0, 0.0, -9.81], (200, 1))
    speed = np.full((200, rotors), 430.0) if speeds else None
    return Recording(t, np.zeros((200, 3)), acc, None, rotor_speed=speed)


def test_the_drag_moments_are_packed_by_name():
    c = model_coefficients(MultirotorParams(), drag_moment=((0.1, 2.0), (-3.0, 0.4)))
    np.testing.assert_array_equal(c[MODEL.drag_moment : MODEL.drag_moment + 4], [0.1, 2.0, -3.0, 0.4])
    assert (model_coefficients(MultirotorParams())[MODEL.drag_moment : MODEL.drag_moment + 4] == 0).all()


def test_a_malformed_drag_moment_is_refused_in_one_line():
    with pytest.raises(ValueError, match="drag_moment must be 2 rows") as err:
        model_coefficients(MultirotorParams(), drag_moment=(1.0, 2.0, 3.0))
    assert "\n" not in str(err.value)


@pytest.mark.parametrize(
    "rec, message", [(_rec(speeds=False), "no rotor speeds"), (_rec(rotors=6), "6 rotors, the vehicle 4")]
)
def test_a_recording_that_does_not_fit_the_vehicle_is_refused(rec, message):
    with pytest.raises(ValueError, match=message):
        diagnose_speeds(rec, MultirotorParams(), file="f.csv", vehicle_source="v.toml")


def test_a_recording_that_never_flies_long_enough_says_so():
    d = diagnose_speeds(_rec(), MultirotorParams(), file="f.csv", vehicle_source="v.toml")
    assert d.failures == [] and d.damaged == [] and d.spans == []
    assert any("nothing diagnosed" in n for n in d.notes)
