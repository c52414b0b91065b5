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
import shutil
import sys
import tempfile
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
    with open(path, "w") as f:
        f.write("\n".join(head) + "\n" + ",".join(cols) + "\n")
        for r in A:
            f.write(",".join("" if np.isnan(v) else format(float(v), ".17g") for v in r) + "\n")
        if end:
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
    data = h.read_bytes()
    cut = d / "cut.csv"
    cut.write_bytes(data[: len(data) // 2])
    cut_row = d / "cut_row.csv"
    cut_row.write_bytes(data[: data.rfind(b"\n", 0, data.rfind(b"# end")) + 1])
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
    yield from cases_values(d)


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
    text = csv.read_text()
    units = d / "v_units.csv"
    units.write_text(text.replace('"gyr": "rad/s"', '"gyr": "deg/s"').replace('"acc": "m/s^2"', '"acc": "g"'))
    yield "a units line saying deg/s and g", ["info", units], lambda c, o, e: c == 1 and "is stated to be in" in e
    crlf, blank = d / "v_crlf.csv", d / "v_blank.csv"
    crlf.write_bytes(csv.read_bytes().replace(b"\n", b"\r\n"))
    blank.write_bytes(csv.read_bytes() + b"\n")
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
