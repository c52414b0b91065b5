"""One writer per results file, and damage found (docs/sweeps.md, docs/reliability.md): two
sweeps started together on one file neither lose nor duplicate a row (the second waits for the
first); a row or part damaged on disk is found on resume and its run is run again, never
counted as done."""

import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from quadest.sweep import ResultStore, build_runs, run_sweep, sim_sources

METRICS = ("total_rmse_deg", "heading_rmse_deg", "roll_rms_deg")
OUTCOMES: dict = {}


def _cmd(out, seeds, duration="10"):
    return [
        sys.executable,
        "-m",
        "quadest.cli.main",
        "sweep",
        "--filters",
        "madgwick,mahony",
        "--seeds",
        seeds,
        "--duration",
        duration,
        "--workers",
        "0",
        "-o",
        str(out),
    ]


def _ids(path):
    t = ResultStore(path).raw()
    return t.column("run_id").to_pylist() if t is not None else []


def test_two_sweeps_on_one_results_file_lose_and_duplicate_nothing(tmp_path):
    """The second waits for the first (saying so), then runs only what is not yet recorded: the
    union of both grids, each run once, and no part, lock or temporary file left."""
    out = tmp_path / "r.parquet"
    first = subprocess.Popen(_cmd(out, "1-30"), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    lock = Path(str(out) + ".lock")
    while time.time() < deadline and not lock.exists():
        time.sleep(0.02)
    second = subprocess.Popen(_cmd(out, "21-40"), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    o1, e1 = first.communicate(timeout=600)
    o2, e2 = second.communicate(timeout=600)
    assert first.returncode == 0 and second.returncode == 0, (e1, e2)
    assert "waiting for it to end" in e2 and "Traceback" not in e1 + e2
    ids = _ids(out)
    assert len(ids) == 80 and len(set(ids)) == 80  # 40 seeds x 2 filters, each once
    assert "skipped 20 already" in o2  # the 10 shared seeds ran once, in the first
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.parquet"]


def test_the_same_sweep_twice_at_once_runs_each_run_once(tmp_path):
    out = tmp_path / "r.parquet"
    procs = [subprocess.Popen(_cmd(out, "1-8", "4"), stdout=subprocess.PIPE, stderr=subprocess.PIPE) for _ in range(2)]
    assert [p.wait(600) for p in procs] == [0, 0]
    ids = _ids(out)
    assert len(ids) == 16 and len(set(ids)) == 16


def _runs():
    return build_runs("madgwick,mahony", {}, sim_sources("hover", "bebop2", range(1, 5), 3.0))


def _metrics(path):
    return {r["run_id"]: [r[m] for m in METRICS] for r in ResultStore(path).read().to_pylist()}


SWEEP = ["sweep", "--filters", "madgwick,mahony", "--seeds", "1-4", "--duration", "3", "--workers", "0"]


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    """A finished sweep's results and their metrics."""
    from quadest.cli.main import main

    out = tmp_path_factory.mktemp("clean") / "r.parquet"
    assert main([*SWEEP, "-o", str(out)]) == 0
    return out.read_bytes(), _metrics(out)


def _flip(data: bytes, rng, n=8) -> bytes:
    raw = bytearray(data)
    for k in rng.choice(len(raw), n, replace=False):
        raw[k] ^= 0xFF
    return bytes(raw)


def _resume(out, clean_metrics, capsys):
    """Resume on a damaged file: it is refused in one line (its footer cannot be read), or every
    run ends recorded once with the clean sweep's metrics (a damaged row run again, never taken
    as done). Returns the outcome and stderr."""
    from quadest.cli.main import main

    code = main([*SWEEP, "-o", str(out)])
    err = capsys.readouterr().err
    if code == 1 and err.count("\n") == 1 and "not a readable results file" in err:
        return "refused", err
    assert code == 0, err
    got = _metrics(out)
    assert set(got) == set(clean_metrics)
    for rid, vals in got.items():
        assert not any(math.isnan(v) for v in vals), (rid, vals)
        assert vals == clean_metrics[rid]
    assert len(_ids(out)) == len(clean_metrics)
    return "resumed", err


def test_a_damaged_row_is_run_again(tmp_path, clean, capsys):
    """A value changed on disk (the page still decodes; NaN where a number was): its checksum
    no longer matches, so the run is not done, and it is run again."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    data, metrics = clean
    out = tmp_path / "r.parquet"
    out.write_bytes(data)
    table = pq.read_table(out)
    rows = table.to_pylist()
    rows[3]["total_rmse_deg"] = float("nan")
    pq.write_table(pa.Table.from_pylist(rows, schema=table.schema), out)
    store = ResultStore(out)
    assert len(store.read()) == len(metrics) - 1 and store.damaged == 1
    outcome, err = _resume(out, metrics, capsys)
    assert outcome == "resumed" and "1 damaged row(s)" in err


@pytest.mark.parametrize("seed", range(12))
def test_eight_flipped_bytes_in_a_results_file_never_resume_as_done(tmp_path, clean, capsys, seed):
    data, metrics = clean
    out = tmp_path / "r.parquet"
    out.write_bytes(_flip(data, np.random.default_rng(seed)))
    outcome, _ = _resume(out, metrics, capsys)
    OUTCOMES[seed] = outcome


def test_most_flipped_results_files_resume():
    """A results file damaged beyond reading is moved aside and its runs run again: every case resumes."""
    assert len(OUTCOMES) == 12 and list(OUTCOMES.values()).count("resumed") == 12, OUTCOMES


@pytest.mark.parametrize("seed", range(12))
def test_eight_flipped_bytes_in_a_killed_sweeps_part_never_resume_as_done(tmp_path, clean, capsys, seed):
    """A killed sweep's part, damaged: left out (or its damaged rows), its runs run again."""
    data, metrics = clean
    out = tmp_path / "r.parquet"
    parts = tmp_path / "r.parquet.parts"
    parts.mkdir()
    (parts / f"part-20260101T000000-{2**22 + 1}-deadbeef-00000.parquet").write_bytes(
        _flip(data, np.random.default_rng(100 + seed))
    )
    assert _resume(out, metrics, capsys)[0] == "resumed"
    assert not parts.exists()


def test_a_part_of_another_live_writer_is_not_deleted(tmp_path):
    """Compaction removes the parts it folded in and leftovers of ended processes, never a part
    another live process is writing."""
    out = tmp_path / "r.parquet"
    parts = tmp_path / "r.parquet.parts"
    parts.mkdir()
    live = parts / f"part-20260101T000000-{os.getppid()}-cafecafe-00000.tmp"
    gone = parts / f"part-20260101T000000-{2**22 + 3}-cafecafe-00000.tmp"
    live.write_bytes(b"being written")
    gone.write_bytes(b"a killed writer's")
    run_sweep(_runs()[:2], out, workers=0, progress=False)
    assert live.exists() and not gone.exists() and len(_ids(out)) == 2
