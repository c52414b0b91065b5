"""``quadest identify`` on quadest's own simulated vehicle, whose truth is known: 60 s of the
aggressive flight (a figure eight with the heading swinging), the rotors' speeds read at 100 Hz
(held on the IMU's rows, as ESC telemetry), a centre of mass 3 mm forward and 2 mm left of the
rotors' centre and rotors with inertia. Targets: thrust per mass and the roll, pitch and yaw gains
within 5 %, the centre of mass within 2 mm, the rotors' places and senses right."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from quadest.calibration.identify import identify
from quadest.flight import fly
from quadest.models.multirotor import MultirotorParams, quad_x

ARM = 0.17
COM = np.array([0.003, -0.002, 0.0])  # the centre of mass from the rotors' centre (m, body FRD)
TRUTH = MultirotorParams(rotor_pos=tuple(tuple(np.array(p) - COM) for p in quad_x(ARM)), rotor_inertia=4e-6)
TELEMETRY_HZ = 100.0


def _with_telemetry(flight):
    """The flight's recording with each rotor's true speed read every 1/TELEMETRY_HZ s and held."""
    t = flight.recording.t
    k = np.searchsorted(t, np.floor(t * TELEMETRY_HZ) / TELEMETRY_HZ, side="left")
    return replace(flight.recording, rotor_speed=flight.states[k, 13:])


@pytest.fixture(scope="module")
def identified():
    flight = fly("aggressive", vehicle=TRUTH, duration=60.0, seed=1)
    return identify({"aggressive": _with_telemetry(flight)}, mass_kg=TRUTH.mass_kg, arm_m=ARM)


def test_gains_centre_of_mass_places_and_senses(identified):
    s = identified.summary()
    v = TRUTH
    assert s["thrust_per_mass"][0] == pytest.approx(v.k_f / v.mass_kg, rel=0.05)
    assert s["roll_gain"][0] == pytest.approx(v.k_f * ARM / v.inertia[0], rel=0.05)
    assert s["pitch_gain"][0] == pytest.approx(v.k_f * ARM / v.inertia[1], rel=0.05)
    assert s["yaw_gain"][0] == pytest.approx(v.k_m / v.inertia[2], rel=0.05)
    assert abs(s["com_x"][0] - COM[0]) < 0.002 and abs(s["com_y"][0] - COM[1]) < 0.002
    quadrants = np.sign(np.asarray(quad_x(ARM))[:, :2])
    assert (identified.geometry.quadrant == quadrants).all()
    assert (identified.fit.spin == np.asarray(v.spin)).all()
