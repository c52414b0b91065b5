"""What quadest diagnose says about a log: each parameter change once, an open flying span in
words, a file that is no log refused at once (docs/reliability.md)."""

from types import SimpleNamespace

import numpy as np
import pytest

from quadest.evaluation.diagnose import format_diagnosis
from quadest.readers import ReaderError
from quadest.readers.motors import _read_motor_messages, read_motor_log


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
