"""Every command that reads a recording or a log (info, estimate, compare, report, diagnose,
calibrate, identify) on every file of ../shared/data (or $QUADEST_DATA) and on small generated files of
every format: each ends in a result (exit code 0) or a one-line refusal (exit code 1 or 2, one
``error:`` line on stderr, no traceback, no internal error), within a time limit. The commands
run in-process (as tests/integration/test_cli.py runs them), on their shortest settings: one
fast estimator, the report's first 20 s."""

from __future__ import annotations

import os
import signal
from dataclasses import replace
from pathlib import Path

import h5py
import numpy as np
import pytest
from logwriters import write_dataflash, write_ulog

from quadest.cli.main import main
from quadest.data import save_recording
from quadest.sim import simulate

DATA = Path(os.environ.get("QUADEST_DATA", Path(__file__).resolve().parents[3] / "shared" / "data"))
REAL = sorted(p for p in DATA.rglob("*") if p.is_file() and p.suffix not in (".md", ".json")) if DATA.is_dir() else []

LIMIT_S = 120
"""A case's time limit: the slowest case on a warm cache takes a few seconds, the first report
(compiling the estimator and loading bokeh) about 40 s on one core."""

MAPPED = ["--format", "csv", "--map", "t=time", "--map", "gyr=gx,gy,gz", "--map", "acc=ax,ay,az"]


def _argv(command: str, path: Path, out: Path, options: list) -> list[str]:
    """The command's shortest run on ``path``, its outputs in ``out``."""
    f = str(path)
    return {
        "info": ["info", f, *options],
        "estimate": ["estimate", f, "--filter", "madgwick", "-o", str(out / "e.csv"), *options],
        "compare": ["compare", "--recording", f, "--filters", "madgwick", "--no-timing", *options],
        "report": ["report", f, "--filters", "madgwick", "--to", "20", "-o", str(out / "r.html"), *options],
        "diagnose": ["diagnose", f],  # logs only: it takes no reader options
        "calibrate": ["calibrate", "gyro", f, "-o", str(out / "c.json"), *options],
        "identify": ["identify", f, "-o", str(out / "v.toml"), *options],
    }[command]


COMMANDS = ("info", "estimate", "compare", "report", "diagnose", "calibrate", "identify")


class Hang(BaseException):
    """A case that ran past its time limit (a BaseException: the command line's own handler,
    which turns every Exception into one line, does not catch it)."""


def _on_alarm(signum, frame):
    raise Hang


def _run(capsys, argv) -> tuple[int, str]:
    previous = signal.signal(signal.SIGALRM, _on_alarm)
    signal.alarm(LIMIT_S)
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse's own refusal
        code = exc.code
    except Hang:
        pytest.fail(f"quadest {' '.join(argv)} ran longer than {LIMIT_S} s")
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    return code, capsys.readouterr().err


def check_result_or_refusal(capsys, argv) -> None:
    code, err = _run(capsys, argv)
    said = f"quadest {' '.join(argv)} -> {code}:\n{err}"
    assert "Traceback" not in err and "internal error" not in err, said
    if code != 0:
        errors = [line for line in err.splitlines() if ": error: " in line]
        assert code in (1, 2) and len(errors) == 1, said
        others = [line for line in err.splitlines() if line not in errors]
        assert all(("note:" in line or "warning:" in line) for line in others), said


def _hover(duration=4.0):
    return simulate(
        "hover", "bebop2", seed=4, duration=duration, overrides={"imu.rate_hz": 100.0, "mag.rate_hz": 100.0}
    )


def _pwm(n, level):
    return np.full((n, 4), float(level))


def _mapped_csv(path, t, rec):
    head = "time,gx,gy,gz,ax,ay,az\n"
    rows = np.column_stack([t, rec.gyr, rec.acc])
    path.write_text(head + "\n".join(",".join(repr(float(v)) for v in row) for row in rows) + "\n")


def _broad(path, n=400, rate=100.0):
    with h5py.File(path, "w") as f:
        f.attrs["sampling_rate"] = rate
        f["imu_gyr"] = np.zeros((n, 3))
        f["imu_acc"] = np.tile([0.0, 0.0, 9.81], (n, 1))
        f["imu_mag"] = np.tile([20.0, 0.0, -40.0], (n, 1))
        f["opt_quat"] = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
        f["movement"] = np.ones(n)


def _dido(path, rec):
    with h5py.File(path, "w") as f:
        f["ts"] = rec.t
        f["gyr"] = rec.gyr
        f["acc"] = rec.acc
        f["gt_q"] = rec.true_q


def _asl(folder, rec):
    imu = folder / "mav0" / "imu0"
    imu.mkdir(parents=True)
    rows = np.column_stack([np.round(rec.t * 1e9), rec.gyr, rec.acc])
    np.savetxt(imu / "data.csv", rows, delimiter=",", fmt=["%d"] + ["%.9g"] * 6)
    return folder


def generated(d: Path) -> dict[str, tuple[Path, list]]:
    """Small files of every format quadest reads, with and without a flight, motors and a
    magnetometer, and a few edge cases: name → (path, reader options)."""
    rec = _hover()
    n = len(rec)
    files = {
        "quadest.csv": (save_recording(rec, d / "r.csv"), []),
        "quadest.parquet": (save_recording(rec, d / "r.parquet"), []),
        "no-mag.parquet": (save_recording(replace(rec, mag=None), d / "s.parquet"), []),
        "one-row.csv": (save_recording(rec.select(slice(0, 1)), d / "one.csv"), []),
        "two-rows.csv": (save_recording(rec.select(slice(0, 2)), d / "two.csv"), []),
    }
    _mapped_csv(d / "mapped.csv", rec.t, rec)
    files["mapped.csv"] = (d / "mapped.csv", MAPPED)
    _mapped_csv(d / "tiny-intervals.csv", np.arange(n) * 2e-300, rec)
    files["tiny-intervals.csv"] = (d / "tiny-intervals.csv", MAPPED)
    for name, kw in {
        "motorless": {},
        "no-mag": {"mag": False},
        "grounded": {"outputs": _pwm(n, 1000)},
        "flying": {"outputs": _pwm(n, 1600)},
    }.items():
        write_ulog(d / f"{name}.ulg", rec, **kw)
        write_dataflash(d / f"{name}.bin", rec, **kw)
        files[f"{name}.ulg"] = (d / f"{name}.ulg", [])
        files[f"{name}.bin"] = (d / f"{name}.bin", [])
    write_ulog(d / "cut.ulg", rec, truncate_at=(d / "motorless.ulg").stat().st_size // 3)
    files["cut.ulg"] = (d / "cut.ulg", [])
    _broad(d / "broad.hdf5")
    files["broad.hdf5"] = (d / "broad.hdf5", [])
    _dido(d / "dido.hdf5", rec)
    files["dido.hdf5"] = (d / "dido.hdf5", [])
    files["asl"] = (_asl(d / "asl", rec), [])
    return files


_GENERATED: dict = {}


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    if not _GENERATED:
        _GENERATED.update(generated(tmp_path_factory.mktemp("every-format")))
    return _GENERATED


GENERATED_NAMES = [
    "quadest.csv",
    "quadest.parquet",
    "no-mag.parquet",
    "one-row.csv",
    "two-rows.csv",
    "mapped.csv",
    "tiny-intervals.csv",
    *(f"{name}.{ext}" for name in ("motorless", "no-mag", "grounded", "flying") for ext in ("ulg", "bin")),
    "cut.ulg",
    "broad.hdf5",
    "dido.hdf5",
    "asl",
]


@pytest.mark.parametrize("command", COMMANDS)
@pytest.mark.parametrize("name", GENERATED_NAMES)
def test_every_command_on_every_generated_format(name, command, made, tmp_path, capsys):
    path, options = made[name]
    check_result_or_refusal(capsys, _argv(command, path, tmp_path, options))


@pytest.mark.parametrize("command", COMMANDS)
@pytest.mark.parametrize("path", REAL, ids=[str(p.relative_to(DATA)) for p in REAL])
def test_every_command_on_every_shared_file(path, command, tmp_path, capsys):
    check_result_or_refusal(capsys, _argv(command, path, tmp_path, []))


def test_the_shared_data_is_there():
    if not REAL:
        pytest.skip(f"no shared data under {DATA} (set QUADEST_DATA; ../shared/data/README.md): only generated files")
