"""What an output's name means (docs/reliability.md, "Output targets and concurrent writers"):
a file is replaced atomically, a link's target is written and the link kept, a FIFO or a
device is written as a stream, a read-only file, a missing folder, a folder, a socket are
refused in one line; JSON is strict."""

import json
import os
import socket
import stat
import threading

import numpy as np
import pytest

from quadest.cli.main import main
from quadest.data.files import (
    atomic_output,
    dumps_json,
    output_target,
    replacing_read_only,
    write_bytes,
    write_json,
)


def _no_constants(name):
    raise ValueError(f"not strict JSON: {name}")


def strict_load(text: str):
    return json.loads(text, parse_constant=_no_constants)


def test_a_regular_file_is_replaced_atomically_and_keeps_its_mode(tmp_path):
    p = tmp_path / "out.json"
    p.write_text("old")
    os.chmod(p, 0o640)
    write_json(p, {"a": 1})
    assert strict_load(p.read_text()) == {"a": 1}
    assert stat.S_IMODE(p.stat().st_mode) == 0o640
    assert sorted(tmp_path.iterdir()) == [p]


def test_a_symlink_is_kept_and_its_target_written(tmp_path):
    (tmp_path / "real").mkdir()
    target = tmp_path / "real" / "t.json"
    target.write_text("old")
    link = tmp_path / "link.json"
    link.symlink_to(target)
    write_json(link, {"a": 2})
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert strict_load(target.read_text()) == {"a": 2}
    assert sorted(p.name for p in (tmp_path / "real").iterdir()) == ["t.json"]  # no temporary file left


def test_a_dangling_symlink_creates_its_target(tmp_path):
    link = tmp_path / "link.json"
    link.symlink_to("made.json")
    write_json(link, [1])
    assert link.is_symlink() and strict_load((tmp_path / "made.json").read_text()) == [1]


def test_a_fifo_is_written_as_a_stream(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    got = []
    reader = threading.Thread(target=lambda: got.append(fifo.read_bytes()))
    reader.start()
    write_bytes(fifo, b"hello\n")
    reader.join(30)
    assert got == [b"hello\n"] and stat.S_ISFIFO(os.lstat(fifo).st_mode)
    assert sorted(tmp_path.iterdir()) == [fifo]


def test_a_fifo_nobody_reads_is_refused_not_waited_for_forever(tmp_path, monkeypatch):
    from quadest.data import files

    monkeypatch.setattr(files, "FIFO_WAIT_S", 0.2)
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    with pytest.raises(ValueError, match="no process read from this FIFO"):
        with atomic_output(fifo) as tmp:
            tmp.write_bytes(b"x")
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)


def test_a_character_device_is_written_not_replaced():
    """/dev/null is a stream: it is written to, never renamed over (as root, replacing it would
    break the system). The classification is checked before anything is written."""
    assert output_target("/dev/null").stream  # guard: nothing below runs if /dev/null would be replaced
    before = os.stat("/dev/null")
    write_json("/dev/null", {"x": float("nan")})
    after = os.stat("/dev/null")
    assert stat.S_ISCHR(after.st_mode) and after.st_ino == before.st_ino and after.st_rdev == before.st_rdev


def test_a_read_only_file_is_refused_unless_forced(tmp_path):
    p = tmp_path / "ro.json"
    p.write_text("keep")
    os.chmod(p, 0o444)
    with pytest.raises(ValueError, match="is read-only; give --force"):
        write_json(p, {})
    assert p.read_text() == "keep"
    with replacing_read_only():
        write_json(p, {"b": 1})
    assert strict_load(p.read_text()) == {"b": 1} and stat.S_IMODE(p.stat().st_mode) == 0o444


@pytest.mark.parametrize("kind", ["missing folder", "folder", "socket", "link loop"])
def test_targets_that_cannot_be_written_are_refused_in_one_line(tmp_path, kind):
    p = tmp_path / "x"
    if kind == "missing folder":
        p = tmp_path / "nope" / "x.json"
    elif kind == "folder":
        p.mkdir()
    elif kind == "socket":
        s = socket.socket(socket.AF_UNIX)
        s.bind(str(p))
    else:
        p.symlink_to(p)
    with pytest.raises(ValueError) as err:
        write_json(p, {})
    assert str(p) in str(err.value) and "\n" not in str(err.value)
    assert not (tmp_path / "nope").exists()
    assert sorted(q.name for q in tmp_path.iterdir()) == ([] if kind == "missing folder" else ["x"])


def _run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_the_command_line_refuses_before_any_work_and_force_replaces(tmp_path, capsys):
    ro = tmp_path / "ro.csv"
    ro.write_text("keep")
    os.chmod(ro, 0o444)
    code, out, err = _run(capsys, "simulate", "--duration", "1", "-o", ro)
    assert code == 2 and err.count("\n") == 1 and "read-only" in err and "simulating" not in out
    assert ro.read_text() == "keep"
    code, out, err = _run(capsys, "simulate", "--duration", "1", "-o", ro, "--force")
    assert code == 0 and ro.read_text().startswith("t,gyr_x,")
    code, out, err = _run(capsys, "simulate", "--duration", "1", "-o", tmp_path / "nope" / "x.csv")
    assert code == 2 and "the folder" in err and "does not exist" in err and not (tmp_path / "nope").exists()


def test_a_csvs_metadata_is_an_output_checked_before_any_work(tmp_path, capsys):
    """Found by a hostile run: the metadata file beside a CSV output, linked to the input, was
    written onto the input; a read-only one refused only after the CSV had been replaced."""
    rec = tmp_path / "r.csv"
    assert _run(capsys, "simulate", "--duration", "1", "-o", rec)[0] == 0
    before = rec.read_bytes()
    (tmp_path / "e.csv-metadata.json").symlink_to(rec)
    code, out, err = _run(capsys, "estimate", rec, "--filter", "madgwick", "-o", tmp_path / "e.csv")
    assert code == 2 and err.count("\n") == 1 and "e.csv-metadata.json is the input file" in err
    assert rec.read_bytes() == before and not (tmp_path / "e.csv").exists()
    os.chmod(tmp_path / "r.csv-metadata.json", 0o444)
    code, out, err = _run(capsys, "simulate", "--duration", "1", "--seed", "5", "-o", rec)
    assert code == 2 and "r.csv-metadata.json is read-only" in err and rec.read_bytes() == before


def test_every_command_that_writes_takes_force():
    from quadest.cli.main import build_parser

    sub = next(a for a in build_parser()._actions if a.dest == "command")
    writers = {"simulate", "estimate", "calibrate", "fit-aero", "recover", "compare", "report", "sweep", "tune", "fly"}
    for name in writers:
        assert any(a.dest == "force" for a in sub.choices[name]._actions), name
    assert not any(a.dest == "force" for a in sub.choices["info"]._actions)


def test_json_is_strict_everywhere(tmp_path, capsys):
    obj = {
        "nan": float("nan"),
        "inf": [float("inf"), -np.inf],
        "f32": np.float32("nan"),
        "arr": np.array([1.0, np.nan]),
    }
    assert strict_load(dumps_json(obj)) == {"nan": None, "inf": [None, None], "f32": None, "arr": [1.0, None]}
    one = tmp_path / "one.csv"
    one.write_text("t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z,mag_x,mag_y,mag_z\n0,0,0,0,0,0,-9.8,20,0,40\n")
    code, out, err = _run(capsys, "info", one, "--json")
    assert code == 0 and strict_load(out)["samples"] == 1
