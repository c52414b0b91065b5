"""``-o -``: a command whose output is a table writes it as CSV to standard output, alone there
(what the command says goes to stderr); any other output refuses ``-`` in one line."""

import io
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from quadest.cli.main import main


def quadest(*argv, timeout=600):
    return subprocess.run(
        [sys.executable, "-m", "quadest.cli.main", *map(str, argv)], capture_output=True, timeout=timeout
    )


def test_simulate_and_estimate_write_csv_to_a_pipe(tmp_path):
    r = quadest("simulate", "--scenario", "hover", "--duration", "1", "--seed", "3", "-o", "-")
    assert r.returncode == 0, r.stderr
    frame = pd.read_csv(io.BytesIO(r.stdout))
    assert list(frame.columns[:4]) == ["t", "gyr_x", "gyr_y", "gyr_z"] and len(frame) > 400
    assert b"wrote -" in r.stderr and not list(tmp_path.iterdir())  # nothing beside a stream
    rec = tmp_path / "h.csv"
    rec.write_bytes(r.stdout)
    r = quadest("estimate", rec, "--filter", "madgwick", "-o", "-")
    assert r.returncode == 0, r.stderr
    est = pd.read_csv(io.BytesIO(r.stdout))
    assert list(est.columns) == ["t", "q_w", "q_x", "q_y", "q_z", "roll", "pitch", "yaw"]
    np.testing.assert_array_equal(est["t"].to_numpy(), frame["t"].to_numpy())
    assert b"madgwick:" in r.stderr


@pytest.mark.parametrize(
    "argv",
    [
        ["fly", "--scenario", "hover", "-o", "-"],
        ["compare", "--recording", "x.csv", "--json", "-"],
        ["calibrate", "gyro", "x.csv", "-o", "-"],
    ],
)
def test_dash_is_refused_for_outputs_that_are_not_tables(capsys, argv):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "standard output takes a table" in err, err


def test_a_closed_standard_output_is_one_line():
    """Found by a hostile run: ``-o -`` with stdout closed (``>&-``) ended in a traceback."""
    r = subprocess.run(
        ["sh", "-c", f"'{sys.executable}' -m quadest.cli.main simulate --duration 1 -o - >&-"],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert r.returncode == 1 and "standard output is closed" in r.stderr and "Traceback" not in r.stderr, r.stderr
