"""A damaged sample is a sample: one implausible value or time in an autopilot log is skipped
and counted as a NaN is; only a log whose values are implausible throughout is refused, naming
the unit (readers.common.make_recording; docs/reliability.md)."""

from types import SimpleNamespace

import numpy as np
import pytest
from logwriters import write_dataflash, write_ulog

from quadest.readers import ReaderError, read_recording
from quadest.sim import simulate

K = 150  # the damaged row


@pytest.fixture(scope="module")
def hover():
    return simulate("hover", "bebop2", seed=4, duration=3.0, overrides={"imu.rate_hz": 100.0, "mag.rate_hz": 100.0})


class _Flight(SimpleNamespace):
    def __len__(self):
        return len(self.t)


def _flight(rec, field=None, value=None):
    arrays = {k: np.array(getattr(rec, k)) for k in ("t", "gyr", "acc", "mag", "true_q")}
    if field == "t":
        arrays["t"][K] += value
    elif field is not None:
        arrays[field][K, 1] = value
    return _Flight(**arrays)


@pytest.mark.parametrize("writer, ext", [(write_dataflash, "bin"), (write_ulog, "ulg")])
@pytest.mark.parametrize(
    "field, value", [("gyr", 80.0), ("acc", 2000.0), ("t", 1000.0), ("gyr", np.nan)], ids=["gyr", "acc", "time", "nan"]
)
def test_one_implausible_sample_is_dropped_like_a_nan(hover, tmp_path, writer, ext, field, value):
    """Before: one gyroscope value of 80 rad/s refused the whole log ("is the gyroscope in
    deg/s?"), one of 2000 m/s² too, and one time jump ("is the file sorted by time?": every
    later row was behind it)."""
    path = tmp_path / f"log.{ext}"
    writer(path, _flight(hover, field, value))
    rec = read_recording(path)
    assert rec.meta["dropped_rows"] == 1 and len(rec) == len(hover) - 1
    assert np.allclose(rec.t - rec.t[0], np.delete(hover.t, K), atol=2e-6)
    assert np.allclose(rec.gyr, np.delete(hover.gyr, K, axis=0), atol=1e-5)


def test_a_log_implausible_throughout_is_refused_naming_the_unit(hover, tmp_path):
    flight = _flight(hover)
    flight.gyr = flight.gyr + 100.0  # every row beyond any gyroscope: a unit, not damage
    write_dataflash(tmp_path / "log.bin", flight)
    with pytest.raises(ReaderError, match="is the gyroscope in deg/s"):
        read_recording(tmp_path / "log.bin")
