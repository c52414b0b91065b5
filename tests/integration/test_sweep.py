"""Sweeps and tuning on Dask: results independent of where runs execute, a real
scheduler and two workers on loopback, a worker killed mid-sweep, an interrupted sweep resumed."""

import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from quadest.cli.main import main
from quadest.sweep import (
    ResultStore,
    build_runs,
    halves,
    parse_grid,
    run_id,
    run_one,
    run_sweep,
    select,
    sim_sources,
    split_select,
)
from quadest.sweep.runs import parse_values

BIN = Path(sys.executable).parent
COMPARE = (
    "total_rmse_deg",
    "heading_rmse_deg",
    "inclination_rmse_deg",
    "roll_rms_deg",
    "pitch_rms_deg",
    "yaw_rms_deg",
    "samples",
    "status",
    "source",
    "params",
    "filter",
)


def _runs(seeds=range(1, 4), duration=6.0, betas="0.02,0.1"):
    return build_runs(
        "madgwick,mahony", parse_grid([f"madgwick.beta_marg={betas}"]), sim_sources("hover", "bebop2", seeds, duration)
    )


def _rows(path):
    t = ResultStore(path).read()
    return {r["run_id"]: {k: r[k] for k in COMPARE} for r in t.to_pylist()}


def _raw_ids(path):
    """Every run_id written, in the results file and in parts a killed sweep left."""
    t = ResultStore(path).raw()
    return t.column("run_id").to_pylist() if t is not None else []


def _parts(path):
    return list(Path(str(path) + ".parts").glob("part-*.parquet"))


# -- pieces -----------------------------------------------------------------------------------------------------
def test_grid_values_and_run_ids():
    assert parse_values("0.1,0.2") == [0.1, 0.2]
    assert parse_values("lin:0:1:3") == [0.0, 0.5, 1.0]
    v = parse_values("log:0.001:1:4")
    assert v[0] == pytest.approx(0.001) and v[-1] == pytest.approx(1.0) and len(v) == 4
    with pytest.raises(ValueError, match="lin:A:B:N"):
        parse_values("log:0:1:3")
    runs = _runs()
    assert len(runs) == (2 + 1) * 3  # madgwick x 2 gains + mahony, x 3 seeds
    assert len({run_id(r) for r in runs}) == len(runs)
    assert run_id(json.loads(json.dumps(runs[0]))) == run_id(runs[0])  # stable through JSON
    with pytest.raises(ValueError, match="does not run"):
        build_runs("madgwick", parse_grid(["mahony.k_p=1"]), sim_sources("hover", "bebop2", [1]))


def test_a_misspelt_grid_parameter_is_refused_before_any_run():
    with pytest.raises(ValueError, match="no parameter no_such_gain"):
        build_runs("madgwick", parse_grid(["madgwick.no_such_gain=1,2"]), sim_sources("hover", "bebop2", [1], 3.0))


def test_a_failing_run_is_recorded_and_the_sweep_goes_on(tmp_path):
    gone = {"kind": "file", "path": str(tmp_path / "deleted.csv"), "format": None}  # removed after planning
    runs = [{"filter": f, "params": {}, "source": gone, "align": None} for f in ("madgwick", "mahony")]
    runs += _runs(seeds=[1], duration=3.0)
    res = run_sweep(runs, tmp_path / "r", workers=0, progress=False)
    assert res["failed"] == 2 and res["ok"] == len(runs) - 2
    bad = [r for r in ResultStore(tmp_path / "r").read().to_pylist() if r["status"] == "failed"]
    assert all("deleted.csv" in r["error"] for r in bad)
    again = run_sweep(runs, tmp_path / "r", workers=0, progress=False)
    assert again["executed"] == 0  # failed runs are finished runs, unless --retry-failed
    again = run_sweep(runs, tmp_path / "r", workers=0, progress=False, retry_failed=True)
    assert again["executed"] == 2 and len(ResultStore(tmp_path / "r").read()) == len(runs)
    assert len(ResultStore(tmp_path / "r").raw()) == len(runs)  # the superseded failed rows are dropped


def test_serial_equals_local_cluster_and_resume_skips(tmp_path):
    runs = _runs()
    serial = run_sweep(runs, tmp_path / "serial", workers=0, progress=False)
    assert serial["executed"] == len(runs) and serial["ok"] == len(runs)
    assert run_sweep(runs, tmp_path / "serial", workers=0, progress=False)["executed"] == 0
    local = run_sweep(runs, tmp_path / "local", workers=2, progress=False)
    assert local["executed"] == len(runs)
    assert _rows(tmp_path / "serial") == _rows(tmp_path / "local")


def test_tune_picks_trial_agnostic_and_per_trial(tmp_path):
    runs = _runs(betas="0.005,0.05,0.5")
    run_sweep(runs, tmp_path / "r", workers=0, progress=False)
    sel = select(ResultStore(tmp_path / "r").read(), "madgwick")
    rows = [run_one(r) for r in runs if r["filter"] == "madgwick"]
    means = {}
    for r in rows:
        means.setdefault(r["params"], []).append(r["total_rmse_deg"])
    best = min(means, key=lambda p: np.mean(means[p]))
    assert sel["trial_agnostic"]["params"] == json.loads(best)
    assert sel["trial_agnostic"]["total_rmse_deg"] == pytest.approx(np.mean(means[best]))
    for src, v in sel["per_trial"].items():
        assert v["total_rmse_deg"] == min(r["total_rmse_deg"] for r in rows if r["source"] == src)
    assert sel["per_trial_mean"] <= sel["trial_agnostic"]["total_rmse_deg"] + 1e-12


def test_split_selection_never_sees_the_half_it_reports():
    """--split: each fold's parameters are the best on its own half, and its reported mean is
    over the other half only. A table built so that the halves disagree shows both: set a is
    best on the even trials, set b on the odd ones; each fold reports the other set's worse
    score on the half it did not choose on."""
    import pyarrow as pa

    trials = [f"t{k:02d}" for k in range(6)]
    even, odd = halves(trials)
    assert even == ["t00", "t02", "t04"] and odd == ["t01", "t03", "t05"]
    score = {('{"k": 1}', t): (1.0 if t in even else 3.0) for t in trials}
    score.update({('{"k": 2}', t): (2.0 if t in even else 2.5) for t in trials})
    rows = [
        {"filter": "f", "status": "ok", "params": p, "source": t, "total_rmse_deg": v} for (p, t), v in score.items()
    ]
    sel = split_select(pa.Table.from_pylist(rows), "f")
    a, b = sel["folds"]
    assert a["params"] == {"k": 1} and a["tuned_mean"] == 1.0 and a["held_out_mean"] == 3.0
    assert b["params"] == {"k": 2} and b["tuned_mean"] == 2.5 and b["held_out_mean"] == 2.0
    assert a["held_out_trials"] == odd and b["held_out_trials"] == even
    assert {tuple(r["params"].values()): (r["mean_A"], r["mean_B"]) for r in sel["sets"]} == {
        (1,): (1.0, 3.0),
        (2,): (2.0, 2.5),
    }


def test_sweep_defaults_to_a_local_cluster(tmp_path, capsys):
    assert (
        main(
            [
                "sweep",
                "--filters",
                "madgwick",
                "--scenario",
                "hover",
                "--seeds",
                "1",
                "--duration",
                "3",
                "-o",
                str(tmp_path / "r"),
            ]
        )
        == 0
    )
    assert "on a local Dask cluster (one worker per core)" in capsys.readouterr().out
    assert ResultStore(tmp_path / "r").read().column("status").to_pylist() == ["ok"]


def test_sweep_prints_each_sets_mean(tmp_path, capsys):
    """After the runs, each filter's parameter sets with the mean of their runs' metrics, the
    figures those of the results file's rows; the JSON carries the same summary."""
    import pyarrow.parquet as pq

    out, js = tmp_path / "r.parquet", tmp_path / "s.json"
    argv = "sweep --filters madgwick,roetenberg --grid madgwick.beta_marg=0.01,0.1 --scenario hover".split()
    argv += ["--seeds", "1-2", "--duration", "3", "--workers", "0", "-o", str(out), "--json", str(js)]
    assert main(argv) == 0
    text = capsys.readouterr().out
    rows = pq.read_table(out).to_pylist()
    for name, beta, label in (
        ("madgwick", 0.01, "beta_marg=0.01"),
        ("madgwick", 0.1, "beta_marg=0.1"),
        ("roetenberg", None, "defaults"),
    ):
        mine = [
            r for r in rows if r["filter"] == name and (beta is None or json.loads(r["params"])["beta_marg"] == beta)
        ]
        assert len(mine) == 2
        total, yaw = (np.mean([r[k] for r in mine]) for k in ("total_rmse_deg", "yaw_rms_deg"))
        line = next(ln for ln in text.splitlines() if ln.startswith(name) and f" {label} " in ln)
        cells = line.split()
        assert cells[2] == "2" and cells[3] == f"{total:.2f}" and cells[-1] == f"{yaw:.2f}", line
    summ = json.loads(js.read_text())["summary"]
    assert summ["runs"] == 6 and [e["params"] for e in summ["filters"]["roetenberg"]["sets"]] == [{}]


def test_tune_command(tmp_path, capsys):
    out = tmp_path / "res"
    assert (
        main(
            [
                "tune",
                "madgwick",
                "--grid",
                "madgwick.beta_marg=0.01,0.1",
                "--scenario",
                "hover",
                "--seeds",
                "1-2",
                "--duration",
                "4",
                "-o",
                str(out),
                "--workers",
                "0",
                "--json",
                str(tmp_path / "t.json"),
            ]
        )
        == 0
    )
    text = capsys.readouterr().out
    assert "trial-agnostic best" in text and "hover/bebop2/seed2" in text
    d = json.loads((tmp_path / "t.json").read_text())
    assert d["parameter_sets"] == 2 and d["trials"] == 2 and d["sweep"]["executed"] == 4


# -- a real scheduler and workers on loopback -----------------------------------------------------------------------
def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_workers(address, n, timeout=60):
    from dask.distributed import Client

    with Client(address, timeout="30s") as c:
        c.wait_for_workers(n, timeout=timeout)


@pytest.fixture
def cluster():
    """``dask scheduler`` and two ``dask worker`` processes (no nanny, one thread each) on 127.0.0.1."""
    dask = str(BIN / "dask")
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    procs = [
        subprocess.Popen(
            [dask, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            env=env,
        )
    ]
    time.sleep(1.0)
    for _ in range(2):
        procs.append(
            subprocess.Popen(
                [dask, "worker", address, "--nthreads", "1", "--no-nanny", "--no-dashboard", "--host", "127.0.0.1"],
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
                env=env,
            )
        )
    try:
        _wait_workers(address, 2)
        yield address, procs
    finally:
        for p in procs[::-1]:
            if p.poll() is None:
                p.terminate()
        for p in procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()


def test_scheduler_and_two_workers_equal_serial(cluster, tmp_path, capsys):
    address, _ = cluster
    args = ["--grid", "madgwick.beta_marg=0.02,0.1", "--scenario", "hover", "--seeds", "1-3", "--duration", "6"]
    assert (
        main(["sweep", "--filters", "madgwick,mahony", *args, "-o", str(tmp_path / "dask"), "--scheduler", address])
        == 0
    )
    assert "on the Dask cluster at" in capsys.readouterr().out
    assert main(["sweep", "--filters", "madgwick,mahony", *args, "-o", str(tmp_path / "serial"), "--workers", "0"]) == 0
    assert _rows(tmp_path / "dask") == _rows(tmp_path / "serial")
    assert len(_raw_ids(tmp_path / "dask")) == 9


def test_worker_killed_mid_sweep_loses_and_duplicates_nothing(cluster, tmp_path):
    address, procs = cluster
    runs = _runs(seeds=range(1, 25), duration=30.0)  # 72 runs on 24 flights, about 6 s on two workers
    out = tmp_path / "r"
    result = {}
    t = threading.Thread(target=lambda: result.update(run_sweep(runs, out, scheduler=address, progress=False)))
    t.start()
    deadline = time.time() + 60
    while time.time() < deadline and not _parts(out):
        time.sleep(0.05)
    procs[1].send_signal(signal.SIGKILL)  # one worker dies mid-sweep
    assert t.is_alive(), "the sweep finished before the worker was killed"
    t.join(timeout=240)
    assert not t.is_alive()
    assert result["ok"] == len(runs) and result["failed"] == 0
    ids = _raw_ids(out)
    assert sorted(ids) == sorted(run_id(r) for r in runs)  # every run once: none lost, none twice
    run_sweep(runs, tmp_path / "serial", workers=0, progress=False)
    assert _rows(out) == _rows(tmp_path / "serial")


def test_interrupted_sweep_resumes_each_run_once(tmp_path):
    out = tmp_path / "r"
    cmd = [
        str(BIN / "quadest"),
        "sweep",
        "--filters",
        "madgwick,mahony,afckf",
        "--scenario",
        "hover",
        "--seeds",
        "1-30",
        "--duration",
        "30",
        "-o",
        str(out),
        "--workers",
        "0",
    ]  # 90 runs, ~15 s
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 120
    while time.time() < deadline and not _parts(out):
        time.sleep(0.05)
    p.send_signal(signal.SIGKILL)  # no chance to flush: what was buffered is lost and redone
    p.wait()
    first = _raw_ids(out)
    assert 0 < len(first) < 90 and not out.exists()  # only parts: the killed sweep never folded them
    assert subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL).returncode == 0
    ids = _raw_ids(out)
    assert len(ids) == 90 and len(set(ids)) == 90  # each run exactly once across both sessions
    assert out.is_file() and not _parts(out)  # one Parquet file in the end
    import pyarrow.parquet as pq

    assert pq.read_table(out).num_rows == 90


def test_reproduce_runs_on_the_same_engine():
    """A reproduction's seeds give the same tables in this process and on two local workers."""
    from quadest.evaluation.reproduce import reproduce_qukf

    a = reproduce_qukf([1, 2], duration=8.0, workers=0)
    b = reproduce_qukf([1, 2], duration=8.0, workers=2)
    assert a == b


def test_flown_runs_sweep_resume_and_tune(tmp_path, capsys):
    """Flown flights in a sweep: estimator x failure x seed, one row per run with
    the flight's outcome; the same run twice is skipped (resume); tuning reads the tilt error
    the controller flew with; a sweep that mixes flown and estimation runs is refused."""
    import pyarrow.parquet as pq

    from quadest.errors import UsageError
    from quadest.sweep import flown_sources

    out = tmp_path / "flown.parquet"
    argv = [
        "sweep",
        "--fly",
        "rotor-loss",
        "--filters",
        "truth,madgwick",
        "--failure",
        "0@1",
        "--failure",
        "2@1",
        "--seeds",
        "0-1",
        "--duration",
        "3",
        "--workers",
        "0",
        "-o",
        str(out),
    ]
    assert main(argv) == 0
    t = pq.read_table(out).to_pylist()
    assert len(t) == 8 and all(r["status"] == "ok" and r["flight"] == "survived" for r in t)
    assert {r["source"] for r in t} == {f"flown rotor-loss/rotor{k}@1/seed{s}" for k in (0, 2) for s in (0, 1)}
    truth = [r for r in t if r["filter"] == "truth"]
    assert all(r["inclination_rmse_deg"] < 1e-5 and r["recovered"] == -1 for r in truth)
    assert all(
        abs(r["spin_rate_rad_s"]) > 5.0 for r in t
    )  # the rotor-loss spin, an output (its sign: the lost rotor's sense)
    capsys.readouterr()
    assert main(argv) == 0 and "executed 0 (skipped 8" in capsys.readouterr().out
    assert (
        main(
            [
                "tune",
                "madgwick",
                "--fly",
                "rotor-loss",
                "--grid",
                "madgwick.beta_marg=0.05",
                "--seeds",
                "0",
                "--duration",
                "3",
                "--metric",
                "inclination_rmse_deg",
                "--workers",
                "0",
                "-o",
                str(tmp_path / "t.parquet"),
            ]
        )
        == 0
    )
    assert "trial-agnostic best" in capsys.readouterr().out
    mixed = flown_sources("hover", [0]) + sim_sources("hover", "bebop2", [0], 2.0)
    with pytest.raises(UsageError, match="either flown"):
        run_sweep(build_runs("madgwick", {}, mixed), tmp_path / "m.parquet", workers=0, progress=False)
    code = main(
        ["sweep", "--fly", "rotor-loss", "--failure", "9@1", "--filters", "madgwick", "-o", str(tmp_path / "x.parquet")]
    )
    assert code == 2 and "rotor 9 does not exist" in capsys.readouterr().err


def test_a_local_worker_killed_leaves_no_leaked_semaphore_warning(tmp_path):
    """`quadest sweep --workers 2` with one worker process killed (kill -9) mid-sweep: every run
    is in the results, and multiprocessing's resource tracker, which removes the dead worker's
    semaphore, does not print its "leaked semaphore" warning (docs/reliability.md)."""
    out = tmp_path / "r"
    cmd = [str(BIN / "quadest"), "sweep", "--filters", "madgwick,mahony", "--scenario", "hover"]
    cmd += ["--seeds", "1-60", "--duration", "30", "-o", str(out), "--workers", "2"]
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 180
    while time.time() < deadline and not _parts(out) and p.poll() is None:
        time.sleep(0.1)
    workers = subprocess.run(["pgrep", "-P", str(p.pid), "-f", "spawn_main"], capture_output=True, text=True)
    pids = [int(w) for w in workers.stdout.split()]
    assert pids and p.poll() is None, "no worker process to kill, or the sweep already ended"
    os.kill(pids[-1], signal.SIGKILL)
    _, err = p.communicate(timeout=600)
    assert p.returncode == 0, err
    assert "leaked semaphore" not in err and "resource_tracker" not in err, err
    assert len(set(_raw_ids(out))) == 120
