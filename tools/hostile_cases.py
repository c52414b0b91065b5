"""Bad input, tried as a careless user and a hostile file would (docs/reliability.md).

Runs every case in a temporary folder through the command line (in this process) and prints a
Markdown table: the case, what quadest did (exit code and the first line of stderr) and whether
that is what docs/reliability.md promises. Exit code 0 when every case behaves.

    python tools/hostile_cases.py            # the table
    python tools/hostile_cases.py --json out.json
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import socket
import stat
import sys
import tempfile
import threading
import time
import traceback
import warnings
from pathlib import Path

import numpy as np

from quadest.cli.main import main
from quadest.data import Recording, save_recording
from quadest.data.files import write_json
from quadest.sim import simulate


def run(*argv) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), warnings.catch_warnings():
        warnings.simplefilter("always")  # every warning on stderr, as in a process of its own (and under pytest) ...
        for quiet in (DeprecationWarning, PendingDeprecationWarning, ResourceWarning):  # ... but these, as there
            warnings.simplefilter("ignore", quiet)
        warnings.showwarning = _on_stderr
        try:
            code = main([str(a) for a in argv])
        except SystemExit as exc:  # argparse's usage errors
            code = exc.code
    return code, out.getvalue(), err.getvalue()


def _on_stderr(message, category, filename, lineno, file=None, line=None):
    sys.stderr.write(warnings.formatwarning(message, category, filename, lineno, line))


def _rows(path: Path):
    """Header lines, column names and the numbers of a quadest CSV."""
    lines = path.read_text().splitlines()
    h = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    body = [line.split(",") for line in lines[h + 1 :] if not line.startswith("#")]
    return lines[:h], lines[h].split(","), np.array([[float(x) if x else np.nan for x in r] for r in body])


def _write(path: Path, head, cols, A, end=True):
    with open(path, "w") as f:  # a plain CSV (head: an earlier version's comment lines, and its end line)
        f.write("".join(line + "\n" for line in head) + ",".join(cols) + "\n")
        for r in A:
            f.write(",".join("" if np.isnan(v) else format(float(v), ".17g") for v in r) + "\n")
        if end and head:
            f.write(f"# end: {len(A)} rows\n")
    return path


def cases(d: Path):
    """``(name, argv or callable, expectation)``; an expectation is a function of
    ``(code, stdout, stderr)`` returning True when quadest behaved."""
    h = d / "h.csv"
    save_recording(simulate("hover", "bebop2", seed=1, duration=3.0), h)
    head, cols, A = _rows(h)
    acc = [cols.index(c) for c in ("acc_x", "acc_y", "acc_z")]
    B = A.copy()
    B[:, acc] *= 1000 / 9.80665
    mg = _write(d / "mg.csv", head, cols, B)
    B = A.copy()
    B[:, 0] *= 1000
    ms = _write(d / "ms.csv", head, cols, B)
    rev = _write(d / "reversed.csv", head, cols, A[::-1])
    data, side = h.read_bytes(), Path(f"{h}-metadata.json").read_bytes()  # a CSV cut, its metadata beside it
    cut = d / "cut.csv"
    cut.write_bytes(data[: len(data) // 2])
    cut_row = d / "cut_row.csv"
    cut_row.write_bytes(data[: data.rstrip().rfind(b"\n") + 1])
    for f in (cut, cut_row):
        Path(f"{f}-metadata.json").write_bytes(side)
    dup = d / "dup.csv"
    dup.write_text("t,gx,gx,gz,ax,ay,az\n0,0,0,0,0,0,-9.8\n")
    copy = d / "f.csv"
    shutil.copy(h, copy)
    rec = simulate("hover", "bebop2", seed=2, duration=3.0)
    notruth = save_recording(Recording(t=rec.t, gyr=rec.gyr, acc=rec.acc, mag=rec.mag, meta=rec.meta), d / "nt.csv")
    other = d / "other.parquet"
    import pyarrow as pa
    import pyarrow.parquet as pq

    pq.write_table(pa.table({"run_id": ["x"], "seed": ["a"]}), other)
    zero_si = d / "zero_soft_iron.json"
    zero_si.write_text(
        json.dumps(
            {
                "format": "quadest calibration v1",
                "kind": "mag",
                "unit": "uT",
                "values": {"hard_iron": [0, 0, 0], "soft_iron_correction": [[0, 0, 0], [0, 0, 0], [0, 0, 0]]},
            }
        )
    )
    import h5py

    huge = d / "huge.hdf5"
    with h5py.File(huge, "w") as f:  # declares 10⁸ rows, stores none
        f.attrs["sampling_rate"] = 100.0
        for k, w in (("imu_gyr", 3), ("imu_acc", 3), ("imu_mag", 3), ("opt_quat", 4), ("movement", 1)):
            f.create_dataset(k, shape=(100_000_000, w), dtype="f8", chunks=(1000, w))
    logs = Path(__file__).resolve().parents[1] / "tests"
    sys.path.insert(0, str(logs))
    from logwriters import write_dataflash, write_ulog  # byte-exact writers of both formats

    short = simulate("hover", "bebop2", seed=4, duration=2.0, overrides={"imu.rate_hz": 100.0, "mag.rate_hz": 100.0})
    ulg, df = d / "cut.ulg", d / "damaged.bin"
    write_ulog(ulg, short)
    ulg.write_bytes(ulg.read_bytes()[: len(ulg.read_bytes()) // 2 + 5])
    write_dataflash(df, short)
    raw = bytearray(df.read_bytes())
    raw[len(raw) // 2 : len(raw) // 2 + 300] = b"\x00" * 300
    df.write_bytes(bytes(raw))
    empty_values = d / "empty_values.json"
    empty_values.write_text(
        json.dumps({"format": "quadest calibration v1", "kind": "gyro", "unit": "rad/s", "values": {}})
    )

    def one_line(code_wanted):
        return lambda c, o, e: (
            c == code_wanted and e.count("\n") == 1 and "Traceback" not in e and "internal error" not in e
        )

    def intact(c, o, e):
        return c == 2 and copy.read_bytes() == data and "is the input file" in e

    yield "estimate -o onto its input", ["estimate", copy, "--filter", "madgwick", "-o", copy], intact
    yield "compare --json onto its input", ["compare", "--recording", copy, "--json", copy, "--no-timing"], intact
    yield "calibrate -o onto its input", ["calibrate", "gyro", copy, "-o", copy], intact
    yield "fit-aero -o onto its input", ["fit-aero", copy, "-o", copy, "--mass", "1"], intact
    yield "recover --json onto its input", ["recover", copy, "--json", copy], intact
    yield "quadest CSV cut in half", ["info", cut], lambda c, o, e: c == 1 and "cut short" in e
    yield "quadest CSV cut at a row boundary", ["info", cut_row], lambda c, o, e: c == 1 and "cut short" in e
    yield "acceleration in mg", ["info", mg], lambda c, o, e: c == 1 and "mg" in e
    yield "time in ms", ["info", ms], lambda c, o, e: c == 1 and "in ms" in e
    yield "reversed rows", ["info", rev], lambda c, o, e: c == 1 and "not strictly increasing" in e
    yield (
        "a duplicated column",
        ["info", dup, "--format", "csv", "--map", "t=t", "--map", "gyr=gx,gx,gz", "--map", "acc=ax,ay,az"],
        one_line(1),
    )
    yield (
        "--param for a parameter that does not exist",
        ["estimate", h, "--filter", "madgwick", "--param", "madgwick.beta=0.1", "-o", d / "e.csv"],
        one_line(2),
    )
    yield (
        "--param with a negative noise",
        ["estimate", h, "--filter", "roetenberg", "--param", "roetenberg.gyro_noise=-1", "-o", d / "e.csv"],
        one_line(2),
    )
    yield (
        "--param k_p=1e300",
        ["estimate", h, "--filter", "mahony", "--param", "mahony.k_p=1e300", "-o", d / "e.csv"],
        one_line(2),
    )
    yield (
        "--declination-deg nan",
        ["estimate", h, "--filter", "madgwick", "--declination-deg", "nan", "-o", d / "e.csv"],
        one_line(2),
    )
    yield "--set of an unknown parameter", ["simulate", "--set", "gyro.nope=1", "-o", d / "x.csv"], one_line(2)
    yield "--set without a value", ["simulate", "--set", "novalue", "-o", d / "x.csv"], one_line(2)
    yield "an unknown filter", ["compare", "--filters", "nope", "--duration", "2"], one_line(2)
    yield (
        "a grid parameter typo",
        [
            "sweep",
            "--filters",
            "madgwick",
            "--grid",
            "madgwick.bta=0.1",
            "--seeds",
            "1",
            "--duration",
            "2",
            "--workers",
            "0",
            "-o",
            d / "s.parquet",
        ],
        one_line(2),
    )
    yield "a missing file", ["info", d / "missing.csv"], one_line(1)
    yield "an HDF5 file that declares 1e8 rows", ["info", huge, "--format", "broad"], one_line(1)
    yield "a ULog cut in half", ["info", ulg], lambda c, o, e: c == 0 and "warning:" in e and "cut short" in e
    yield (
        "a DataFlash log damaged mid-file",
        ["info", df],
        lambda c, o, e: c == 0 and "warning:" in e and "damaged" in e and "bad header" not in e,
    )
    yield (
        "--param for a filter that is not run",
        ["compare", "--recording", h, "--filters", "madgwick", "--param", "roetenberg.lin_acc=1", "--no-timing"],
        one_line(2),
    )
    yield (
        "--workers -1",
        ["sweep", "--filters", "madgwick", "--seeds", "1", "--workers", "-1", "-o", d / "w.parquet"],
        lambda c, o, e: c == 2 and "Traceback" not in e,
    )
    yield (
        "reproduce recovery --throws 0",
        ["reproduce", "recovery", "--throws", "0"],
        lambda c, o, e: c == 2 and "Traceback" not in e,
    )
    yield "simulate --duration inf", ["simulate", "--duration", "inf", "-o", d / "x.csv"], one_line(1)
    yield "simulate --duration 1e5", ["simulate", "--duration", "1e5", "-o", d / "x.csv"], one_line(1)
    yield "--set imu.rate_hz=1e12", ["simulate", "--set", "imu.rate_hz=1e12", "-o", d / "x.csv"], one_line(2)
    yield "--set a negative noise", ["simulate", "--set", "gyro.noise_std=-0.1", "-o", d / "x.csv"], one_line(2)
    yield (
        "an all-zero soft-iron correction",
        ["estimate", h, "--filter", "madgwick", "--calibration", zero_si, "-o", d / "e.csv"],
        one_line(1),
    )
    yield (
        "a calibration with no values",
        ["estimate", h, "--filter", "madgwick", "--calibration", empty_values, "-o", d / "e.csv"],
        one_line(1),
    )
    yield (
        "a sweep in which every run fails",
        ["sweep", "--filters", "madgwick", "--data", notruth, "--workers", "0", "-o", d / "s2.parquet"],
        lambda c, o, e: c == 1 and "none of the 1 runs succeeded" in e and "Traceback" not in e,
    )
    yield (
        "a sweep resumed onto another program's Parquet file",
        ["sweep", "--filters", "madgwick", "--seeds", "1", "--duration", "2", "--workers", "0", "-o", other],
        lambda c, o, e: c == 1 and "not a results file" in e and not (d / "other.parquet.parts").exists(),
    )
    yield "an output with an unknown extension", ["estimate", h, "--filter", "madgwick", "-o", d / "e.txt"], one_line(1)
    yield from cases_bounds(d)
    yield from cases_outputs(d)
    yield from cases_values(d)


def cases_bounds(d: Path):
    """Bounded work and interruptions: too many runs refused before anything runs, inputs that are
    not files or are sparse refused unread, seeds below 0 a usage error, a damaged compiled cache
    mended (downloads, Ctrl-C and the cache's damage need a server, a signal or a child process:
    tests/integration/test_data_fetch.py and test_bounds.py; a killed local Dask worker and the
    report's memory on a long recording take a minute each: test_sweep.py and test_bounds.py)."""
    import os

    def refused(count):
        return lambda c, o, e: (
            c == 2 and f"makes {count} runs, more than --max-runs" in e and e.count("\n") == 1 and "Traceback" not in e
        )

    def one_line(code_wanted, said):
        return lambda c, o, e: c == code_wanted and said in e and e.count("\n") == 1 and "Traceback" not in e

    out = d / "bounds.parquet"
    yield "sweep --seeds 0-100000000", ["sweep", "--seeds", "0-100000000", "-o", out], refused("100,000,001")
    yield (
        "a 3000x3000 grid",
        ["sweep", "--seeds", "1", "--grid", "madgwick.beta_marg=lin:0:1:3000", "--grid",
         "madgwick.beta_imu=lin:0:1:3000", "-o", out],
        refused("9,000,000"),
    )  # fmt: skip
    yield (
        "--grid log:1e-9:1:1000000 over 10 seeds",
        ["sweep", "--seeds", "0-9", "--filters", "madgwick", "--grid", "madgwick.beta_marg=log:1e-9:1:1000000",
         "-o", out],
        refused("10,000,000"),
    )  # fmt: skip
    yield (
        "--grid lin:0:1:1e12",
        ["sweep", "--seeds", "1", "--grid", "madgwick.beta_marg=lin:0:1:1e12", "-o", out],
        refused("1,000,000,000,000"),
    )
    yield (
        "reproduce recovery --throws 10000000",
        ["reproduce", "recovery", "--throws", "10000000"],
        refused("10,000,000"),
    )
    yield "fly --seeds 0-2000000", ["fly", "--seeds", "0-2000000", "-o", d / "fl"], refused("2,000,001")
    yield (
        "simulate --seed -1",
        ["simulate", "--seed", "-1", "-o", d / "x.csv"],
        lambda c, o, e: c == 2 and "0 or more" in e,
    )
    yield "sweep --seeds 3,-2", ["sweep", "--seeds", "3,-2", "-o", out], one_line(2, "0 or more")
    fifo = d / "fifo.csv"
    os.mkfifo(fifo)
    yield "a FIFO as input", ["info", fifo], one_line(1, "a FIFO (named pipe), not a file")
    yield "a FIFO as --config", ["simulate", "--config", fifo, "-o", d / "x.csv"], one_line(1, "a FIFO")
    yield (
        "a device as input",
        ["info", "/dev/zero", "--format", "csv", "--map", "t=t"],
        one_line(1, "a character device"),
    )
    sparse = d / "sparse.csv"
    with open(sparse, "wb") as f:
        f.write(b"t,gx,gy,gz,ax,ay,az\n")
        f.truncate(2 * 1024**3)
    yield (
        "a 2 GB sparse CSV",
        ["info", sparse, "--format", "csv", "--map", "t=t", "--map", "gyr=gx,gy,gz", "--map", "acc=ax,ay,az"],
        one_line(1, "a sparse file"),
    )
    yield "a damaged compiled cache", _damaged_cache_case, lambda c, o, e: c == 0 and e.count("was damaged") == 1


def _damaged_cache_case():
    """A compiled function's cache files cut short, in a child process with its own cache: the
    second run says so once and still computes."""
    import os
    import subprocess

    d = Path(tempfile.mkdtemp(prefix="quadest-cache-"))
    try:
        (d / "jitted.py").write_text(
            "from quadest._jit import njit\n\n@njit(cache=True)\ndef f(x):\n    return x + 1.0\n"
        )
        code = f"import sys; sys.path.insert(0, {str(d)!r}); import jitted; print(jitted.f(1.0))"
        env = {k: v for k, v in os.environ.items() if "NUMBA_CACHE_DIR" not in k}
        env["XDG_CACHE_HOME"] = str(d / "cache")
        env["PYTHONPATH"] = os.pathsep.join(sys.path)
        subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, timeout=300, check=True)
        for f in (d / "cache").rglob("*.nb[ic]"):
            with open(f, "r+b") as fh:
                fh.truncate(10)
        r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
        ok = r.returncode == 0 and r.stdout.strip() == "2.0"
        note = next((line for line in r.stderr.splitlines() if "damaged" in line), "")
        return (0 if ok else 1), r.stdout, (note + "\n" if note else r.stderr)
    finally:
        shutil.rmtree(d, ignore_errors=True)


def _strict_json(text: str):
    def no_constant(name):
        raise ValueError(f"not strict JSON: {name}")

    return json.loads(text, parse_constant=no_constant)


def _read_fifo(fifo: Path) -> dict:
    """Start a reader of ``fifo``; ``got["data"]`` once the writer closes it."""
    got: dict = {}
    thread = threading.Thread(target=lambda: got.update(data=fifo.read_bytes()), daemon=True)
    thread.start()
    got["thread"] = thread
    return got


def _fifo_read(fifo: Path, got: dict) -> bytes | None:
    got["thread"].join(20)
    if got["thread"].is_alive():  # nothing was written: let the reader end
        with contextlib.suppress(OSError):
            os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
        return None
    return got.get("data")


def _sweep_metrics(path: Path) -> dict:
    from quadest.sweep import ResultStore

    t = ResultStore(path).read()
    return {r["run_id"]: (r["status"], r["total_rmse_deg"]) for r in t.to_pylist()} if t is not None else {}


def _holding_lock(lock: Path, seconds: float) -> None:
    """Hold a results file's lock, as another sweep would, for ``seconds`` (returns once held)."""
    from quadest.data.files import exclusive_lock

    held = threading.Event()

    def hold():
        with exclusive_lock(lock):
            held.set()
            time.sleep(seconds)

    threading.Thread(target=hold, daemon=True).start()
    held.wait(10)


def cases_outputs(d: Path):
    """Output targets by kind, concurrent sweeps on one results file, damaged results, strict JSON
    (docs/reliability.md, "Output targets and concurrent writers")."""
    from quadest.data.files import output_target

    h = d / "ot.csv"
    save_recording(simulate("hover", "bebop2", seed=5, duration=2.0), h)
    compare = ["compare", "--recording", h, "--filters", "madgwick", "--no-timing", "--json"]
    (d / "real").mkdir()
    target = d / "real" / "t.json"
    target.write_text("old")
    link = d / "link.json"
    link.symlink_to(target)
    yield (
        "--json onto a symbolic link",
        [*compare, link],
        lambda c, o, e: c == 0 and link.is_symlink() and "rms_deg" in target.read_text(),
    )
    fifo = d / "fifo"
    os.mkfifo(fifo)
    got = _read_fifo(fifo)
    yield (
        "--json onto a FIFO",
        [*compare, fifo],
        lambda c, o, e: (
            c == 0 and b"rms_deg" in (_fifo_read(fifo, got) or b"") and stat.S_ISFIFO(os.lstat(fifo).st_mode)
        ),
    )
    null = "/dev/null" if output_target("/dev/null").stream else d / "guard"  # never rename over /dev/null
    yield (
        "--json /dev/null (a character device)",
        [*compare, null],
        lambda c, o, e: c == 0 and null == "/dev/null" and stat.S_ISCHR(os.stat("/dev/null").st_mode),
    )
    ro = d / "ro.csv"
    ro.write_text("keep")
    os.chmod(ro, 0o444)
    yield (
        "-o onto a read-only file",
        ["simulate", "--duration", "1", "-o", ro],
        lambda c, o, e: c == 2 and e.count("\n") == 1 and "--force" in e and ro.read_text() == "keep",
    )
    yield (
        "-o onto a read-only file with --force",
        ["simulate", "--duration", "1", "-o", ro, "--force"],
        lambda c, o, e: c == 0 and ro.read_text().startswith("t,gyr_x,"),
    )
    yield (
        "-o into a folder that does not exist",
        ["simulate", "--duration", "1", "-o", d / "nope" / "x.csv"],
        lambda c, o, e: c == 2 and "does not exist" in e and not (d / "nope").exists(),
    )
    sock = socket.socket(socket.AF_UNIX)
    sock.bind(str(d / "sock"))
    yield "--json onto a socket", [*compare, d / "sock"], lambda c, o, e: c == 2 and "socket" in e
    one = d / "one.csv"
    one.write_text("t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z,mag_x,mag_y,mag_z\n0,0,0,0,0,0,-9.8,20,0,40\n")
    yield "info --json on a one-row CSV", ["info", one, "--json"], lambda c, o, e: c == 0 and _strict_json(o)
    sweep = ["sweep", "--filters", "madgwick,mahony", "--seeds", "1-2", "--duration", "2", "--workers", "0", "-o"]
    clean = d / "clean.parquet"
    run(*sweep, clean)
    want = _sweep_metrics(clean)
    flipped, part = d / "flipped.parquet", d / "part.parquet"
    raw = bytearray(clean.read_bytes())
    for k in np.random.default_rng(8).choice(len(raw), 8, replace=False):
        raw[k] ^= 0xFF
    flipped.write_bytes(bytes(raw))
    yield (
        "a sweep resumed on a results file with 8 flipped bytes",
        [*sweep, flipped],
        lambda c, o, e: c == 0 and _sweep_metrics(flipped) == want,
    )
    (d / "part.parquet.parts").mkdir()
    (d / "part.parquet.parts" / "part-20260101T000000-4194305-deadbeef-00000.parquet").write_bytes(bytes(raw))
    yield (
        "a sweep resumed on a killed sweep's part with 8 flipped bytes",
        [*sweep, part],
        lambda c, o, e: c == 0 and _sweep_metrics(part) == want,
    )
    busy = d / "busy.parquet"
    _holding_lock(d / "busy.parquet.lock", 1.5)
    yield (
        "a sweep on a results file another sweep is writing",
        [*sweep, busy],
        lambda c, o, e: c == 0 and "waiting for it to end" in e and _sweep_metrics(busy) == want,
    )


def api(fn):
    """A case through the Python API: ``fn()`` run as a command would be, its ValueError one line
    with exit code 2 (1 for a data error), its warnings on stderr; ``fn`` may return stdout."""
    from quadest.errors import UsageError

    def call():
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            try:
                out = fn() or ""
            except ValueError as exc:
                return (2 if isinstance(exc, UsageError) else 1), "", f"error: {exc}\n"
        return 0, str(out), "".join(f"warning: {w.message}\n" for w in said)

    return call


def cases_values(d: Path):
    """Values of any type, damaged and mislabelled input, reader options that do not apply
    (docs/reliability.md, "Values and damaged input")."""
    from quadest.filters import make_filter
    from quadest.readers import read_recording

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from logwriters import write_dataflash, write_ulog

    def refused(*words):
        return lambda c, o, e: c == 2 and e.count("\n") == 1 and all(w in e for w in words)

    for value in ("nan", np.float32("nan"), "-1", np.int64(-5), "1e300", True):
        yield (
            f"make_filter('mahony', k_p={value!r})",
            api(lambda v=value: make_filter("mahony", k_p=v)),
            refused("k_p must be", "[0, 1e3]"),
        )
    for q0 in ([0, 0, 0, 0], [np.nan, 1, 0, 0], [1, 0, 0]):
        yield f"q0={q0}", api(lambda q=q0: make_filter("madgwick", q0=q)), refused("q0 must be a quaternion")

    def huge_counter():
        f = make_filter("mahony")
        x = f.get_state()
        x[7] = 1e308
        f.set_state(x)

    yield "set_state with 1e308 samples skipped", api(huge_counter), refused("not a state of this estimator")
    yield (
        "declination set to 'east'",
        api(lambda: setattr(make_filter("madgwick"), "declination", "east")),
        refused("declination must be a finite number"),
    )
    rec = simulate("hover", "bebop2", seed=1, duration=3.0)

    def inf_time():
        t = rec.t.copy()
        t[500] = np.inf
        res = make_filter("madgwick").run(t=t, gyr=rec.gyr, acc=rec.acc, mag=rec.mag)
        return f"skipped {res.skipped} restarts {len(res.restarts)}"

    yield "a time of inf in a batch run", api(inf_time), lambda c, o, e: c == 0 and o == "skipped 1 restarts 0"

    def bad_mag():
        mag, nan = rec.mag.copy(), rec.mag.copy()
        mag[500], nan[500] = [np.inf, 0.0, 1e300], np.nan
        res = make_filter("madgwick").run(t=rec.t, gyr=rec.gyr, acc=rec.acc, mag=mag)
        ref = make_filter("madgwick").run(t=rec.t, gyr=rec.gyr, acc=rec.acc, mag=nan)
        same = np.array_equal(res.q, ref.q)
        return f"skipped {res.skipped} mag_skipped {res.mag_skipped} as without it {same}"

    yield (
        "an infinite magnetometer value",
        api(bad_mag),
        lambda c, o, e: c == 0 and o == "skipped 0 mag_skipped 1 as without it True",
    )
    short = simulate("hover", "bebop2", seed=4, duration=2.0, overrides={"imu.rate_hz": 100.0, "mag.rate_hz": 100.0})
    df, cut, ulg = d / "v.bin", d / "v_cut.bin", d / "v.ulg"
    write_dataflash(df, short)
    write_ulog(ulg, short)
    raw = df.read_bytes()
    at = len(raw) // 2 + 5
    cut.write_bytes(raw[: at + (at % 512 == 0)])  # not on a 512-byte block, where ArduPilot ends its own
    yield (
        "a DataFlash log cut inside a message",
        ["info", cut],
        lambda c, o, e: c == 0 and "warning:" in e and "cut short inside a message" in e,
    )
    yield "--units on a ULog", ["info", ulg, "--units", "gyr=deg/s"], refused("--units does not apply to a ulog")
    yield "--units on a DataFlash log", ["info", df, "--units", "gyr=deg/s"], refused("--units does not apply")
    yield (
        "instance=5 on a log with one IMU",
        api(lambda: read_recording(ulg, instance=5)),
        refused("instance=5, but the log holds IMU instance(s) 0"),
    )
    import pyarrow as pa
    import pyarrow.parquet as pq

    pqf = save_recording(rec, d / "v.parquet")
    table = pq.read_table(pqf)
    meta = table.schema.metadata
    table = table.set_column(1, "gyr_x", pa.array(np.ones(len(rec), bool))).replace_schema_metadata(meta)
    pq.write_table(table, pqf)
    yield "a Parquet gyr_x stored as bool", ["info", pqf], lambda c, o, e: c == 1 and "holds bool values" in e
    csv = save_recording(rec, d / "v.csv")
    side = Path(f"{csv}-metadata.json").read_text()
    units = d / "v_units.csv"
    shutil.copy(csv, units)
    Path(f"{units}-metadata.json").write_text(
        side.replace('"gyr": "rad/s"', '"gyr": "deg/s"').replace('"acc": "m/s^2"', '"acc": "g"')
    )
    yield "a units line saying deg/s and g", ["info", units], lambda c, o, e: c == 1 and "is stated to be in" in e
    crlf, blank = d / "v_crlf.csv", d / "v_blank.csv"
    crlf.write_bytes(csv.read_bytes().replace(b"\n", b"\r\n"))
    blank.write_bytes(csv.read_bytes() + b"\n")
    for f in (crlf, blank):  # an editor's line ends and blank end, the metadata beside: the same values
        Path(f"{f}-metadata.json").write_text(side)
    yield "a quadest CSV with CRLF line ends", ["info", crlf], lambda c, o, e: c == 0 and "error" not in e
    yield "a quadest CSV with a trailing blank line", ["info", blank], lambda c, o, e: c == 0 and "error" not in e
    head, cols, A = _rows(csv)
    B = A.copy()
    B[:, [cols.index(c) for c in ("gyr_x", "gyr_y", "gyr_z")]] *= 180 / np.pi
    degs = _write(d / "v_deg_s.csv", head, cols, B)
    yield (
        "a 3 s hover recorded in deg/s",
        ["info", degs],
        lambda c, o, e: "holds still" in e and "is it in deg/s" in e,
    )
    yield from _names_and_rates(d)


def _names_and_rates(d: Path):
    """Any bytes in a file name; a BROAD file whose sampling_rate is a string."""
    import h5py

    odd = os.path.join(str(d), os.fsdecode(b"v\xff.parquet"))
    yield "a Parquet output named by bytes that are not UTF-8", ["simulate", "--duration", "1", "-o", odd], _ok
    yield "estimate from a file named by bytes that are not UTF-8", ["estimate", odd, "-o", odd + ".csv"], _ok
    broad = d / "v_broad.hdf5"
    with h5py.File(broad, "w") as f:
        for k in ("imu_gyr", "imu_acc", "imu_mag", "opt_pos"):
            f[k] = np.zeros((10, 3))
        f["opt_quat"], f["movement"] = np.tile([1.0, 0, 0, 0], (10, 1)), np.zeros(10)
        f.attrs["sampling_rate"] = "fast"
    yield (
        "a BROAD file whose sampling_rate is a string",
        ["info", broad],
        lambda c, o, e: c == 1 and "v_broad.hdf5: sampling_rate must be one positive number" in e,
    )


def _ok(c, o, e):
    return c == 0 and "error" not in e


def main_(argv=None) -> int:
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", help="also write the outcomes as JSON")
    args = ap.parse_args(argv)
    d = Path(tempfile.mkdtemp(prefix="quadest-hostile-"))
    results = []
    try:
        for name, argv_, ok in cases(d):
            try:
                code, out, err = argv_() if callable(argv_) else run(*argv_)
                good = bool(ok(code, out, err))
            except Exception:  # noqa: BLE001 (a case that crashes the harness is a failed case)
                code, err, good = "crash", traceback.format_exc().splitlines()[-1], False
            lines = err.strip().splitlines() or [""]
            first = next((line for line in reversed(lines) if "error" in line or "warning" in line), lines[0])
            results.append({"case": name, "exit": code, "stderr": first, "as promised": good})
    finally:
        shutil.rmtree(d, ignore_errors=True)
    print("| case | exit | what quadest said | as promised |\n|---|---|---|---|")
    for r in results:
        msg = r["stderr"].replace("|", "\\|").replace(str(d), "DIR")
        print(f"| {r['case']} | {r['exit']} | {msg[:140]} | {'yes' if r['as promised'] else '**no**'} |")
    bad = sum(not r["as promised"] for r in results)
    print(f"\n{len(results) - bad} of {len(results)} cases as promised")
    if args.json:
        write_json(args.json, results)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main_())
