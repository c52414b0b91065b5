"""SIGTERM (``kill``, a scheduler stopping a job) ends a command as Ctrl-C does: the output
being written is removed, one line, exit code 130 (docs/reliability.md)."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from quadest.conventions import GRAVITY
from quadest.data import Recording, save_recording

PROGRAM = "import sys; from quadest.cli.main import main; sys.exit(main())"
SRC = Path(__file__).resolve().parents[2] / "src"


def _env() -> dict:
    return {**os.environ, "PYTHONPATH": f"{SRC}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}


def _temporary(folder: Path) -> list[Path]:
    return [p for p in folder.iterdir() if p.name.endswith(".tmp")]


def _long_recording(path: Path, n: int = 300_000) -> Path:
    """A recording at rest, long enough that its estimate is written for about a second."""
    rng = np.random.default_rng(0)
    acc = np.array([0.0, 0.0, -GRAVITY]) + rng.normal(0.0, 0.05, (n, 3))
    return save_recording(Recording(t=np.arange(n) / 500.0, gyr=rng.normal(0.0, 0.01, (n, 3)), acc=acc), path)


def test_sigterm_while_writing_removes_the_temporary_file(tmp_path):
    """Before: the hidden temporary file (``.e.csv.XXXX.csv.tmp``) stayed and nothing was said."""
    (tmp_path / "in").mkdir()
    source = _long_recording(tmp_path / "in" / "rest.parquet")
    out = tmp_path / "e.csv"
    p = subprocess.Popen(
        [sys.executable, "-c", PROGRAM, "estimate", str(source), "--filter", "madgwick", "-o", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=_env(),
        text=True,
    )
    deadline = time.monotonic() + 300
    while not _temporary(tmp_path) and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    assert _temporary(tmp_path), "the command wrote no temporary file"
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 130 and err.strip().splitlines()[-1] == "quadest: interrupted", (p.returncode, err)
    assert "Traceback" not in err
    assert not _temporary(tmp_path) and not out.exists()
