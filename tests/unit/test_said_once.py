"""What quadest says, once and in the user's terms: diagnose's parameter changes, an open
flying span, a file that is no log, thrust parameters out of range; quadest.read()'s warnings;
a recording's repr; a report of one row (docs/reliability.md)."""

from types import SimpleNamespace

import numpy as np
import pytest
from logwriters import write_dataflash, write_ulog

import quadest
from quadest.cli.main import main
from quadest.data import save_recording
from quadest.evaluation.diagnose import format_diagnosis
from quadest.readers import ReaderError
from quadest.readers.motors import _read_motor_messages, read_motor_log
from quadest.sim import simulate


class _Messages:
    """A DataFlash reader's ``recv_match`` over a list of messages."""

    def __init__(self, messages):
        self.messages = iter(messages)

    def recv_match(self, type):
        return next(self.messages, None)


def _parm(t_s, name, value):
    return SimpleNamespace(get_type=lambda: "PARM", TimeUS=int(t_s * 1e6), Name=name, Value=value)


def test_a_parameter_logged_again_is_one_change():
    """ArduPilot logs a changed parameter twice (the SITL losses: SERVO1_FUNCTION = 1 at 70.768
    and 70.769 s): one change, at its first time; a later change back is a second one."""
    log = _Messages(
        [
            _parm(1.0, "SERVO1_FUNCTION", 33.0),
            _parm(70.768, "SERVO1_FUNCTION", 1.0),
            _parm(70.769, "SERVO1_FUNCTION", 1.0),
            _parm(80.0, "SERVO1_FUNCTION", 33.0),
        ]
    )
    params, changes = {}, []
    _read_motor_messages(log, [], [], [], params, changes)
    assert changes == [(70.768, "SERVO1_FUNCTION", 1.0), (80.0, "SERVO1_FUNCTION", 33.0)]
    assert params == {"SERVO1_FUNCTION": 33.0}  # the log's first values: the vehicle's setting


def test_a_flight_without_a_landing_is_said_in_words():
    log = SimpleNamespace(
        path="x.bin", autopilot="ArduPilot", frame="quad X", imu_rate=25.0, output_rate=10.0,
        flying=[(56.2, np.inf)], changes=[], output_unit="us",
    )  # fmt: skip
    d = SimpleNamespace(log=log, failures=[], damaged=[], motors=[], notes=[])
    text = format_diagnosis(d)
    assert "inf" not in text and "flying: from 56.2 s to the end of the log (no landing logged)" in text


def test_a_file_that_is_no_log_is_refused_at_once(tmp_path):
    """Before: any file was walked by pymavlink as a damaged DataFlash log (11 s on a 4 MB
    HDF5 file, its "Skipped N bad bytes" printed) and refused for lacking RCOU messages."""
    path = tmp_path / "r.parquet"
    path.write_bytes(b"PAR1" + bytes(100_000))
    with pytest.raises(ReaderError, match="not an ArduPilot DataFlash .* or PX4 ULog"):
        read_motor_log(path)


def _hover(duration=2.0):
    return simulate("hover", "bebop2", seed=4, duration=duration, overrides={"imu.rate_hz": 100.0})


def test_thrust_parameters_outside_ardupilots_range_are_named(tmp_path):
    """Before: MOT_THST_EXPO 5 was refused as "vehicle: k_f must be a finite number" (a name
    of quadest's model), or a flight read as none."""
    rec = _hover(4.0)
    path = tmp_path / "expo.bin"
    write_dataflash(path, rec, params={"MOT_THST_EXPO": 5.0}, outputs=np.full((len(rec), 4), 1600.0))
    with pytest.raises(ReaderError, match=r"MOT_THST_EXPO = 5 is outside ArduPilot's range \[-1, 1\]"):
        read_motor_log(path)


def test_read_warns_where_the_command_line_does(tmp_path):
    """Before: quadest.read() of a log cut short returned what it could read and said nothing
    (the note only in meta['warnings'])."""
    path = tmp_path / "cut.ulg"
    write_ulog(path, _hover())
    write_ulog(path, _hover(), truncate_at=path.stat().st_size // 2 + 7)  # inside a message
    with pytest.warns(UserWarning) as said:
        rec = quadest.read(path)
    messages = [str(w.message) for w in said]
    assert any(str(path) in m and "cut short" in m and "\n" not in m for m in messages), messages
    assert rec.meta["warnings"]


def test_a_recordings_repr_is_one_line():
    """Before: print(rec) printed every array."""
    text = repr(_hover())
    assert "\n" not in text and len(text) < 300, text
    assert text.startswith("Recording(201 samples, 2.000 s at 100.0 Hz; gyr, acc, mag, true_q"), text


def test_a_report_of_one_row(tmp_path, capsys):
    """Before: "need at least one array to stack" (the spectrogram of no segment)."""
    path = save_recording(_hover().select(slice(0, 1)), tmp_path / "one.csv")
    assert main(["report", str(path), "--filters", "madgwick", "-o", str(tmp_path / "r.html")]) == 0
    assert "No spectrogram: 1 sample(s)" in (tmp_path / "r.html").read_text()
