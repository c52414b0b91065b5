"""quadest's vehicle and SE(3) controller against RotorPy, a simulator no one here wrote (issue
#13, part 6): RotorPy's Hummingbird and its SE(3) gains, the same circle, flown by both."""

import pytest

from quadest.flight.crosscheck import crosscheck, rotorpy_available

pytestmark = pytest.mark.skipif(not rotorpy_available(), reason="RotorPy is not installed (pip install rotorpy)")


def test_quadest_flies_the_hummingbird_as_rotorpy_does():
    """Hover rotor speeds within 1 % of RotorPy's (after settling from 0.5 m off), and the
    tracking RMS on a 1 m circle at 0.2 Hz within 20 % of RotorPy's. At 200 Hz to keep RotorPy's
    share of the test short (about 3 ms per step); `quadest benchmark sim` flies both at 1 kHz."""
    r = crosscheck(duration=6.0, rate_hz=200.0)
    hover = r["hover_rotor_speed"]
    assert hover["quadest"] == pytest.approx(hover["rotorpy"], rel=0.01)
    assert hover["quadest"] == pytest.approx(hover["model"], rel=0.01)
    track = r["tracking_rms_m"]
    assert track["quadest"] == pytest.approx(track["rotorpy"], rel=0.20), track
