"""Bounded work and interruptions (docs/reliability.md): the size of what a command would run is
refused before anything runs; inputs that are not files, are sparse or exceed memory are refused
before they are read; Ctrl-C at any moment is one line; a damaged compiled cache mends itself."""

import os
import resource
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from quadest.cli.main import main
from quadest.data import inputs
from quadest.errors import MAX_RUNS, UsageError
from quadest.readers import ReaderError, read_recording
from quadest.sweep.runs import build_runs, count_values, parse_grid, parse_values, sim_sources

SRC = Path(__file__).resolve().parents[2] / "src"


def run(capsys, *argv):
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code
    out = capsys.readouterr()
    return code, out.out, out.err


def _peak_kb() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss


@pytest.mark.parametrize(
    "argv, count",
    [
        (["sweep", "--seeds", "0-100000000", "-o", "{d}/s.parquet"], "100,000,001"),
        (
            [
                "sweep",
                "--seeds",
                "1",
                "--grid",
                "madgwick.beta_marg=lin:0:1:3000",
                "--grid",
                "madgwick.beta_imu=lin:0:1:3000",
                "-o",
                "{d}/s.parquet",
            ],
            "9,000,000",
        ),
        (
            ["sweep", "--seeds", "1", "--grid", "madgwick.beta_marg=lin:0:1:1e12", "-o", "{d}/s.parquet"],
            "1,000,000,000,000",
        ),
        (
            [
                "sweep",
                "--seeds",
                "0-9",
                "--filters",
                "madgwick",
                "--grid",
                "madgwick.beta_marg=log:1e-9:1:1000000",
                "-o",
                "{d}/s.parquet",
            ],
            "10,000,000",
        ),
        (["tune", "madgwick", "--seeds", "0-100000000", "-o", "{d}/s.parquet"], "100,000,001"),
        (
            ["sweep", "--fly", "hover", "--filters", "truth", "--seeds", "0-10000000", "-o", "{d}/s.parquet"],
            "10,000,001",
        ),
        (["reproduce", "recovery", "--throws", "10000000"], "10,000,000"),
        (["reproduce", "afckf", "--seeds", "0-2000000"], "2,000,001"),
        (["fly", "--seeds", "0-2000000", "-o", "{d}/fl"], "2,000,001"),
        (["benchmark", "detection", "--seeds", "0-2000000"], "2,000,021"),
    ],
)
def test_too_many_runs_are_refused_before_anything_runs(tmp_path, capsys, argv, count):
    """Refused in one line with the count, exit code 2, with nothing written and no list of the
    runs made (the peak memory grows by less than 50 MB: 10⁸ seeds as a list would take GBs)."""
    before = _peak_kb()
    code, _, err = run(capsys, *[a.format(d=tmp_path) for a in argv])
    assert code == 2 and f"makes {count} runs, more than --max-runs 1,000,000" in err, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert _peak_kb() - before < 50_000
    assert list(tmp_path.iterdir()) == []


def test_max_runs_is_one_option_with_one_default(capsys):
    for argv in (["sweep"], ["tune", "madgwick"], ["fly"], ["reproduce", "afckf"], ["benchmark", "detection"]):
        with pytest.raises(SystemExit):
            main([*argv, "--help"])
        assert "--max-runs N" in capsys.readouterr().out, argv
    assert MAX_RUNS == 10**6


def test_max_runs_can_be_lowered_and_raised(tmp_path, capsys):
    code, _, err = run(capsys, "sweep", "--seeds", "1-3", "--max-runs", "2", "-o", tmp_path / "s.parquet")
    assert code == 2 and "makes 3 runs, more than --max-runs 2" in err
    code, _, err = run(capsys, "sweep", "--seeds", "1-3", "--max-runs", "0", "-o", tmp_path / "s.parquet")
    assert code == 2 and "--max-runs" in err
    runs = build_runs("madgwick,mahony", {}, sim_sources("hover", "bebop2", range(10)), max_runs=20)
    assert len(runs) == 20
    with pytest.raises(UsageError, match="makes 20 runs, more than --max-runs 19"):
        build_runs("madgwick,mahony", {}, sim_sources("hover", "bebop2", range(10)), max_runs=19)


def test_grid_values_are_counted_before_they_are_made():
    assert count_values("lin:0:1:1e12") == 10**12
    assert count_values("log:1e-9:1:1000000") == 10**6
    assert count_values("0.1, 0.2,0.3") == 3
    with pytest.raises(UsageError, match="makes 1,000,000,000,000 runs"):
        parse_values("lin:0:1:1e12")
    with pytest.raises(UsageError, match="lin:A:B:N"):
        parse_values("lin:0:1:2.5")
    with pytest.raises(UsageError, match="lin:A:B:N"):
        parse_values("lin:0:nan:3")
    with pytest.raises(UsageError, match="the grid of madgwick makes 9,000,000 runs"):
        parse_grid(["madgwick.beta_marg=lin:0:1:3000", "madgwick.beta_imu=lin:0:1:3000"])
    assert parse_values("lin:0:1:3") == [0.0, 0.5, 1.0]


@pytest.mark.parametrize(
    "argv", [["simulate", "--seed", "-1"], ["sweep", "--seeds", "-1"], ["sweep", "--seeds", "3,-2"]]
)
def test_a_negative_seed_is_a_usage_error(tmp_path, capsys, argv):
    code, _, err = run(capsys, *argv, "-o", tmp_path / "x.csv")
    assert code == 2 and "Traceback" not in err and ("0 or more" in err)


# -- inputs ----------------------------------------------------------------------------------------------
def test_a_fifo_or_a_device_is_refused_before_it_is_opened(tmp_path, capsys):
    fifo = tmp_path / "f.csv"
    os.mkfifo(fifo)
    for path, kind in ((fifo, "a FIFO (named pipe)"), (Path("/dev/zero"), "a character device")):
        t0 = time.monotonic()
        code, _, err = run(capsys, "info", path, "--format", "csv", "--map", "t=t")
        assert code == 1 and f"{path}: {kind}, not a file" in err and len(err.strip().splitlines()) == 1
        assert time.monotonic() - t0 < 5
    toml, cal = tmp_path / "c.toml", tmp_path / "cal.json"
    os.mkfifo(toml)
    os.mkfifo(cal)
    code, _, err = run(capsys, "simulate", "--config", toml, "-o", tmp_path / "x.csv")
    assert code == 1 and "a FIFO" in err
    with pytest.raises(ValueError, match="a FIFO"):
        from quadest.calibration import load_calibration

        load_calibration(cal)


def test_a_sparse_csv_is_refused_unread(tmp_path, capsys):
    """2 GB of holes: refused at once, the peak memory barely moves."""
    sparse = tmp_path / "sparse.csv"
    with open(sparse, "wb") as f:
        f.write(b"t,gx,gy,gz,ax,ay,az\n")
        f.truncate(2 * 1024**3)
    if inputs.first_hole(sparse) is None:
        pytest.skip("this file system does not report holes")
    before = _peak_kb()
    for argv in (
        ["info", sparse],
        ["info", sparse, "--format", "csv", "--map", "t=t", "--map", "gyr=gx,gy,gz", "--map", "acc=ax,ay,az"],
    ):
        code, _, err = run(capsys, *argv)
        assert code == 1 and "a sparse file (a hole of NUL bytes from byte" in err, err
    assert _peak_kb() - before < 100_000


def test_a_file_larger_than_the_memory_available_is_refused_with_the_figures(tmp_path, monkeypatch):
    from quadest.data import save_recording
    from quadest.sim import simulate

    rec = simulate("hover", "bebop2", seed=1, duration=2.0)
    csv, pq = save_recording(rec, tmp_path / "h.csv"), save_recording(rec, tmp_path / "h.parquet")
    need_csv = inputs.memory_needed(csv)
    assert need_csv == int(inputs.TEXT_FACTOR * csv.stat().st_size)
    import pyarrow.parquet

    columns = pyarrow.parquet.ParquetFile(pq).metadata.num_columns
    assert inputs.memory_needed(pq) == int(inputs.PARQUET_FACTOR * len(rec) * columns * 8)
    monkeypatch.setattr(inputs, "available_memory", lambda: need_csv - 1)
    with pytest.raises(ReaderError, match=r"needs about .* of memory and .* is available"):
        read_recording(csv)
    monkeypatch.setattr(inputs, "available_memory", lambda: need_csv + 1)
    assert len(read_recording(csv)) == len(rec)


def test_available_memory_sees_ulimit_v():
    code = textwrap.dedent(
        """
        import resource
        from quadest.data.inputs import available_memory
        before = available_memory()
        resource.setrlimit(resource.RLIMIT_AS, (8 * 1024**3, resource.RLIM_INFINITY))
        after = available_memory()
        print(before is None or after <= before, after < 8 * 1024**3)
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=_env(), timeout=120)
    assert out.stdout.split() == ["True", "True"], out.stderr


# -- Ctrl-C ------------------------------------------------------------------------------------------------
def _env(**extra):
    env = dict(os.environ, PYTHONPATH=str(SRC), **extra)
    env.pop("PYTHONWARNINGS", None)
    return env


PROGRAM = "import sys\nfrom quadest.cli.main import main\nsys.exit(main())\n"  # what the console script runs
STARTED = "print('started', flush=True)\n"
"""Said by the interpreter before it imports quadest: a Ctrl-C before that is Python's own start
(a busy machine's may take longer than the shortest delay), where no program can answer."""


def _as_from_a_terminal() -> None:
    """Ctrl-C's default action in the child, as a terminal's foreground program has it: a test
    run started in the background by a shell without job control inherits SIGINT ignored."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _interrupted_run(tmp_path, delay: float) -> tuple[int, str]:
    """A long simulation sent Ctrl-C ``delay`` s after it starts: its exit code and stderr."""
    for f in tmp_path.glob("x.csv*"):
        f.unlink()
    p = subprocess.Popen(
        [sys.executable, "-c", STARTED + PROGRAM, "simulate", "--duration", "2000", "-o", str(tmp_path / "x.csv")],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=_env(),
        text=True,
        preexec_fn=_as_from_a_terminal,
    )
    p.stdout.readline()  # Python has started: the delay counts from the import of quadest
    time.sleep(delay)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=120)
    return p.returncode, err


@pytest.mark.parametrize("delay", [0.05, 0.15, 0.3, 0.6, 1.2, 2.5])
def test_ctrl_c_at_any_moment_is_one_line(tmp_path, delay):
    """SIGINT while Python starts, while quadest loads, while it simulates: exit code 130 (or the
    signal's own end before Python handles it) and at most one line, never a traceback. (Not at
    0 s: in the few milliseconds in which Python finds quadest's first modules, before any of
    quadest's code runs, a traceback of one frame is still possible. The program is run once
    first so that its code is compiled: a Ctrl-C in llvmlite's callbacks, as numba compiles or
    loads, is the next test's; docs/reliability.md.) While scipy's C extensions load, a Ctrl-C once made
    an ImportError's traceback and once was swallowed by an optional import (exit 0)."""
    warm = [sys.executable, "-c", PROGRAM, "simulate", "--duration", "1", "-o", str(tmp_path / "warm.csv")]
    subprocess.run(warm, capture_output=True, env=_env(), timeout=600, check=True)
    code, err = _interrupted_run(tmp_path, delay)
    assert "Traceback" not in err, err
    assert code in (130, -signal.SIGINT), (code, err)
    lines = [line for line in err.splitlines() if line.strip() and "simulate hover" not in line]
    assert len(lines) <= 1 and (not lines or lines[0] == "quadest: interrupted"), err
    assert not (tmp_path / "x.csv").exists()


CALLBACK = """
import ctypes, sys
from quadest.cli import main as m
def boom():
    raise {error}
def command(argv):
    ctypes.CFUNCTYPE(None)(boom)()  # a C library calling back into Python, as llvmlite does for numba
    print("went on")
    return 0
m.run_command = command
sys.exit(m.main())
"""


def test_ctrl_c_inside_a_c_librarys_callback_is_one_line():
    """A KeyboardInterrupt in a callback from C cannot be raised there (Python prints it as
    "Exception ignored ..." with a traceback and goes on, the Ctrl-C lost: found when a Ctrl-C
    landed while numba loaded its cached code): the program ends in one line, exit code 130.
    Another error there is still Python's own report, and the program goes on."""
    run = subprocess.run([sys.executable, "-c", CALLBACK.format(error="KeyboardInterrupt")],
                         capture_output=True, text=True, env=_env(), timeout=120)  # fmt: skip
    assert (run.returncode, run.stderr, run.stdout) == (130, "quadest: interrupted\n", "")
    run = subprocess.run([sys.executable, "-c", CALLBACK.format(error="ValueError('x')")],
                         capture_output=True, text=True, env=_env(), timeout=120)  # fmt: skip
    assert run.returncode == 0 and "went on" in run.stdout and "ValueError: x" in run.stderr


# -- the compiled cache --------------------------------------------------------------------------------------
MODULE = """
from quadest._jit import njit

@njit(cache=True)
def twice(x):
    return 2.0 * x
"""


def test_a_damaged_compiled_cache_is_rebuilt_once_with_a_note(tmp_path):
    """Every ``.nbi`` / ``.nbc`` file cut to 10 bytes: the next run says so in one line and
    compiles again; the one after is quiet and loads from the cache again."""
    (tmp_path / "mod").mkdir()
    (tmp_path / "mod" / "jitted.py").write_text(MODULE)
    code = (
        "import sys, warnings\nsys.path.insert(0, sys.argv[1])\n"
        "warnings.formatwarning = lambda m, *a, **k: f'note: {m}\\n'\n"
        "import jitted\nprint(jitted.twice(21.0))\n"
    )
    env = _env(XDG_CACHE_HOME=str(tmp_path / "cache"))
    env.pop("NUMBA_CACHE_DIR", None)
    env.pop("QUADEST_NUMBA_CACHE_DIR", None)

    def once():
        out = subprocess.run(
            [sys.executable, "-c", code, str(tmp_path / "mod")], capture_output=True, text=True, env=env, timeout=300
        )
        assert out.returncode == 0 and out.stdout.strip() == "42.0", out.stderr
        return out.stderr

    assert "damaged" not in once()
    files = [f for f in (tmp_path / "cache").rglob("*") if f.suffix in (".nbi", ".nbc")]
    assert any(f.suffix == ".nbc" for f in files)
    for f in files:
        with open(f, "r+b") as fh:
            fh.truncate(10)
    err = once()
    notes = [line for line in err.splitlines() if "damaged" in line]
    assert len(notes) == 1 and "compiled again" in notes[0], err
    assert "damaged" not in once()
    assert all(f.stat().st_size > 10 for f in (tmp_path / "cache").rglob("*.nbi"))


PEAK_PROBE = (
    "import resource, sys\nfrom quadest.cli.main import main\nrc = main(sys.argv[1:])\n"
    "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, file=sys.stderr)\nsys.exit(rc)\n"
)


def _report_peak_kb(path, out) -> int:
    r = subprocess.run(
        [sys.executable, "-c", PEAK_PROBE, "report", str(path), "-o", str(out)],
        capture_output=True,
        text=True,
        env=_env(),
        timeout=600,
    )
    assert r.returncode == 0, r.stderr
    return int(r.stderr.strip().splitlines()[-1])


def test_a_report_holds_the_recording_and_little_more(tmp_path):
    """`quadest report`'s memory grows with the recording's rows by about what the recording
    itself holds (112 bytes a row with its truth), not by its estimates and errors at every
    sample (they are run, summed and decimated in blocks): from 2·10⁵ to 2·10⁶ rows at most
    2.5 times the recording's own growth (before, about 7 times; docs/reliability.md has the
    10⁷-row figures)."""
    import numpy as np

    from quadest.data import Recording, save_recording

    def recording(n):
        rng = np.random.default_rng(0)
        path = tmp_path / f"r{n}.parquet"
        save_recording(
            Recording(
                t=np.arange(n) / 500.0,
                gyr=rng.normal(0, 0.01, (n, 3)),
                acc=np.array([0.0, 0.0, -9.80665]) + rng.normal(0, 0.05, (n, 3)),
                mag=np.array([20.0, 0.0, 40.0]) + rng.normal(0, 0.5, (n, 3)),
                true_q=np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)),
            ),
            path,
        )
        return path

    small, large = recording(200_000), recording(2_000_000)
    _report_peak_kb(small, tmp_path / "warm.html")  # the estimators compiled (or loaded) once
    grown = 1024 * (_report_peak_kb(large, tmp_path / "large.html") - _report_peak_kb(small, tmp_path / "small.html"))
    held = 1_800_000 * 8 * (1 + 3 + 3 + 3 + 4)
    assert grown <= 2.5 * held, f"{grown / 1e6:.0f} MB for {held / 1e6:.0f} MB more of recording"
