"""``-q`` and ``-v`` on every command: quiet leaves results, warnings and errors; verbose adds
the library's debug lines (docs/usage.md)."""

import numpy as np
import pytest

from quadest import progress
from quadest.cli.main import build_parser, main

MAPPED = ["--format", "csv", "--map", "t=t", "--map", "gyr=gx,gy,gz", "--map", "acc=ax,ay,az"]


@pytest.fixture
def repeated_time(tmp_path):
    """A mapped CSV with one repeated time: read, the row dropped and noted."""
    t = np.arange(400) * 0.005
    t[100] = t[99]
    path = tmp_path / "dup.csv"
    path.write_text("t,gx,gy,gz,ax,ay,az\n" + "".join(f"{v:.6f},0.01,0,0,0,0,-9.81\n" for v in t))
    yield path
    progress.QUIET = False


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_every_command_takes_q_and_v():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    missing = [
        name
        for name, command in sub.choices.items()
        if not {"--quiet", "--verbose"} <= {o for a in command._actions for o in a.option_strings}
    ]
    assert not missing, missing


def test_a_note_is_said_by_default_and_not_with_q(capsys, repeated_time):
    code, out, err = run(capsys, "info", repeated_time, *MAPPED)
    assert code == 0 and "note:" in err and "dropped 1 row" in err and "399" in out
    code, out_q, err_q = run(capsys, "info", repeated_time, *MAPPED, "-q")
    assert code == 0 and err_q == "" and out_q == out  # the result unchanged
    assert progress.QUIET


def test_v_adds_what_was_read_before_or_after_the_command(capsys, repeated_time):
    for argv in (["-v", "info", repeated_time, *MAPPED], ["info", repeated_time, *MAPPED, "--verbose"]):
        code, _, err = run(capsys, *argv)
        assert code == 0 and f"{repeated_time}: read as csv: 399 rows, 1.995 s at 200.0 Hz; gyr, acc" in err
    code, _, err = run(capsys, "info", repeated_time, *MAPPED)
    assert "read as" not in err


def test_a_warning_stays_with_q(capsys, tmp_path):
    from quadest.data import Recording, save_recording

    t = np.arange(300) * 0.01
    rec = Recording(t=t, gyr=np.zeros((300, 3)), acc=np.tile([0, 0, -9.81], (300, 1)), meta={"warnings": ["cut"]})
    path = save_recording(rec, tmp_path / "w.csv")  # a reader's warning, kept in the file's metadata
    code, _, err = run(capsys, "info", path, "-q")
    assert code == 0 and err == f"warning: {path}: cut\n"


def test_q_and_v_together_are_one_line_error(capsys, repeated_time):
    code, out, err = run(capsys, "info", repeated_time, *MAPPED, "-q", "-v")
    assert code == 2 and out == "" and err.count("\n") == 1 and "-q (--quiet) and -v (--verbose)" in err


def test_progress_bars_are_off_with_q():
    progress.QUIET = True
    try:
        assert progress.bar(total=3).disable
    finally:
        progress.QUIET = False
    assert not progress.bar(total=3, file=open("/dev/null", "w")).disable  # noqa: SIM115
