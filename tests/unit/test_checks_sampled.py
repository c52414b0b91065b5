"""A long recording's statistical checks look at evenly spread spans of it
(quadest.data.checks.sampled_spans), so that checking costs the same whatever its length: the
verdicts are those of the whole recording."""

import numpy as np
import pytest

import quadest
import quadest.data.checks as checks
from quadest.sim import simulate


@pytest.fixture(scope="module")
def long():
    """40 s of a simulated flight at 500 Hz: 20,001 rows, beyond what a check looks at."""
    return simulate("nominal", "bebop2", seed=1, duration=40.0)


def test_the_spans_are_spread_over_the_whole_recording(long):
    spans = checks.sampled_spans(len(long))
    assert len(long) > 2 * checks.SAMPLED_ROWS and len(spans) == checks.SAMPLED_SPANS
    assert sum(b - a for a, b in spans) == checks.SAMPLED_ROWS
    assert spans[0][0] == 0 and spans[-1][1] == len(long)
    assert checks.sampled_spans(100) == [(0, 100)]


def _verdicts(s: float, se: float) -> tuple[bool, bool]:
    """(rad/s confirmed by the field, refused as deg/s), as data.checks decides them."""
    band = checks.SCALE_BAND
    return abs(s - 1.0) + 4 * se < band, 0.0 < s and s + 4 * se < band and -band < s - 4 * se


def test_a_sampled_fit_tells_deg_s_from_rad_s_as_the_whole_does(long, monkeypatch):
    """The gyroscope's scale fitted on the spans agrees with the fit on every row (within the
    spans' standard error) and gives the same verdicts: deg/s refused, rad/s never."""
    gyros = (long.gyr, np.degrees(long.gyr))
    sampled = [checks.gyro_scale(long.t, g, long.mag) for g in gyros]
    monkeypatch.setattr(checks, "SAMPLED_ROWS", len(long))
    whole = [checks.gyro_scale(long.t, g, long.mag) for g in gyros]
    for (s, se), (s_all, se_all) in zip(sampled, whole, strict=True):
        assert se_all < se < 10 * se_all and abs(s - s_all) < 4 * se
        assert _verdicts(s, se) == _verdicts(s_all, se_all)
    assert not _verdicts(*sampled[0])[1] and _verdicts(*sampled[1])[1]


def test_a_long_recording_in_deg_s_is_still_refused(long):
    with pytest.raises(ValueError, match="the magnetometer's field .* is it in deg/s"):
        quadest.estimate(np.degrees(long.gyr), long.acc, long.mag, t=long.t)
    quadest.estimate(long.gyr, long.acc, long.mag, t=long.t)  # rad/s: no error


def test_the_sampled_tilt_is_the_whole_recording_s(long, monkeypatch):
    """The tilt check's median, on every few rows, within a degree of the median on all rows."""
    sampled = checks.tilt_disagreement(long.true_q, long.acc)
    monkeypatch.setattr(checks, "SAMPLED_ROWS", len(long))
    assert abs(sampled - checks.tilt_disagreement(long.true_q, long.acc)) < 1.0
