"""What the commands share: one-line errors, output, and the options several commands take."""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Sequence
from pathlib import Path

from quadest.cli.choices import FORMATS, IMU_SOURCES
from quadest.errors import MAX_RUNS, UsageError, check_run_count
from quadest.extras import need


class CliError(UsageError):
    """A wrong or missing option, reported as one line (exit code 2)."""


_DATA_ON_STDOUT = [False]


def say(msg):
    """A line for the user: on stdout, or on stderr when stdout carries the data (``-o -``)."""
    print(msg, file=sys.stderr if _DATA_ON_STDOUT[0] else sys.stdout, flush=True)


STDOUT_TABLES = {("estimate", "output"), ("simulate", "output")}
"""The outputs that may be standard output (``-o -``): a table, written as CSV."""


def data_on_stdout(args) -> None:
    """Refuse ``-`` for an output that is not a table; with ``-o -`` what the command says goes
    to stderr, so that stdout holds the CSV alone."""
    to_stdout = [name for name in OUTPUT_NAMES if str(getattr(args, name, None)) == "-"]
    for name in to_stdout:
        opt = OUTPUT_NAMES[name]
        if (args.command, name) not in STDOUT_TABLES:
            raise CliError(
                f"{opt} -: standard output takes a table (quadest estimate -o -, quadest simulate -o -); "
                f"give {opt} a file name"
            )
    _DATA_ON_STDOUT[0] = bool(to_stdout)


OUTPUT_NAMES = {"output": "-o", "out": "-o", "json": "--json", "plot": "--plot", "report": "--report"}
"""Each option naming a file a command writes, by its destination, and how it is spelt."""


LOG = logging.getLogger("quadest")
"""The library's diagnostics: notes (info), warnings, and with ``-v`` its debug lines; each
message carries its own ``quadest:`` or ``note:`` / ``warning:`` prefix."""


class _Stderr(logging.Handler):
    """Writes each record as its message alone to the ``sys.stderr`` of the moment (a command
    run in-process, under a test's capture, writes where that test reads)."""

    def emit(self, record: logging.LogRecord) -> None:
        try:
            sys.stderr.write(self.format(record) + "\n")
            sys.stderr.flush()
        except (OSError, ValueError):  # a closed stream, a reader that stopped
            pass


_HANDLER = _Stderr()


def add_verbosity(parser, *, top: bool = False) -> None:
    """``-q`` / ``-v``, the same on every command (and before it)."""
    default = False if top else argparse.SUPPRESS  # a command's own would otherwise reset the top's
    parser.add_argument(
        "-q", "--quiet", action="store_true", default=default,
        help="no progress bars, library notes or compile notices (results, a command's own lines, warnings and "
        "errors stay)",
    )  # fmt: skip
    parser.add_argument(
        "-v", "--verbose", action="store_true", default=default,
        help="also say the library's debug lines (what was read and how, which model was assumed)",
    )  # fmt: skip


def set_verbosity(args) -> None:
    """Route the library's log to stderr at the level ``-q`` / ``-v`` ask for, and the progress
    bars off with ``-q``."""
    from quadest import progress

    quiet, verbose = getattr(args, "quiet", False), getattr(args, "verbose", False)
    if quiet and verbose:
        raise CliError("-q (--quiet) and -v (--verbose) ask for opposite things: give one")
    if _HANDLER not in LOG.handlers:
        LOG.addHandler(_HANDLER)
    LOG.setLevel(logging.DEBUG if verbose else logging.WARNING if quiet else logging.INFO)
    logging.getLogger("quadest.compiling").setLevel(logging.ERROR if quiet else logging.NOTSET)
    progress.QUIET = quiet


def say_units_beside(path) -> None:
    """Name a CSV's metadata file (its columns' units and frames) when one was written beside it."""
    from quadest.data.tables import csv_metadata_path

    side = csv_metadata_path(path)
    if str(path).lower().endswith(".csv") and side.is_file():
        say(f"  each column's unit and frame: {side}")


def write_json(path, obj):
    """Write ``obj`` as indented JSON (atomically) and say so."""
    from quadest.data import files

    files.write_json(path, obj)
    say(f"wrote {path}")


def parse_sets(items) -> dict:
    """``["gyro.noise_std=0.02", ...]`` -> ``{"gyro.noise_std": "0.02"}`` (simulator overrides)."""
    out = {}
    for item in items or []:
        key, eq, value = item.partition("=")
        if not eq or not key.strip():
            raise CliError(f"--set expects key=value (for example gyro.noise_std=0.02), got {item!r}")
        out[key.strip()] = value
    return out


def sim_config(preset, sets, toml=None, ideal: bool = False):
    """A simulator configuration: a preset, a TOML file's overrides (errors there are the file's),
    then ``--set`` overrides (errors there are usage errors)."""
    from quadest.sim import build_config

    cfg = build_config(preset, None, toml, ideal)
    overrides = parse_sets(sets)
    return with_sets(cfg, overrides) if overrides else cfg


def with_sets(cfg, overrides: dict):
    """``cfg`` with ``--set``'s ``{"gyro.range": "8.73"}`` applied and checked; a bad key or
    value is a usage error naming ``--set``."""
    try:
        return cfg.with_overrides(overrides).validate()
    except ValueError as exc:
        raise CliError(str(exc) if str(exc).startswith("--set") else f"--set: {exc}") from None


def parse_seeds(text, option: str = "--seeds") -> Sequence[int]:
    """``1-5`` (a ``range``, never made into a list: its size is known at once), ``1,2,3`` or
    ranges and seeds together, ``0-119,6000-6599`` (at most :data:`LISTED_SEEDS`, none twice);
    seeds are whole numbers from 0 to :data:`MAX_SEED`."""
    text = str(text).strip()
    try:
        parts = [_seed_range(item) for item in text.split(",")]
    except ValueError:
        raise CliError(
            f"{option} expects a range like 1-5, a list like 1,2,3 or both like 0-9,20-29 of seeds 0 or more, "
            f"got {text!r}"
        ) from None
    for item, part in zip(text.split(","), parts):
        if part.stop <= part.start:
            raise CliError(f"{option} {text}: {item.strip()} selects no seed (give ranges as low-high)")
        if part.stop - 1 > MAX_SEED:
            raise CliError(f"{option} {text}: seeds are at most {MAX_SEED}")
    if len(parts) == 1:
        return parts[0] if "-" in text else list(parts[0])
    total = sum(p.stop - p.start for p in parts)
    if total > LISTED_SEEDS:
        raise CliError(f"{option} {text}: {total:,} seeds in a list; give at most {LISTED_SEEDS:,} (or one range)")
    ordered = sorted(parts, key=lambda p: p.start)
    if any(b.start < a.stop for a, b in zip(ordered, ordered[1:])):
        raise CliError(f"{option} {text}: a seed is given twice; give each once")
    return [s for p in parts for s in p]


LISTED_SEEDS = 1_000_000
"""The most seeds a list of ranges may hold (one range may hold any number)."""
MAX_SEED = 2**62
"""The largest seed (a results file keeps seeds as 64-bit integers)."""


def _seed_range(item: str) -> range:
    """``5`` or ``3-7`` as a range of seeds 0 or more (ValueError for anything else: a sign, a
    space inside a number, digits other than 0-9)."""
    a, dash, b = item.strip().partition("-")
    a, b = a.strip(), b.strip()
    if not (a.isascii() and a.isdigit()) or (dash and not (b.isascii() and b.isdigit())):
        raise ValueError(item)
    return range(int(a), int(b) + 1) if dash else range(int(a), int(a) + 1)


def add_max_runs_arg(p):
    """``--max-runs``: the same option, with the same default, on every command that runs many."""
    p.add_argument(
        "--max-runs",
        type=positive,
        default=MAX_RUNS,
        metavar="N",
        help=f"refuse, before anything runs, to start more than N runs (default: {MAX_RUNS:,})",
    )


def check_runs(args, count: int, what: str) -> int:
    """Refuse more runs than ``--max-runs``, in one line with the count."""
    return check_run_count(count, getattr(args, "max_runs", MAX_RUNS), what)


# -- options -------------------------------------------------------------------------------------
def add_span_args(p):
    """``--from`` / ``--to``: a span of the recording, in seconds after its first sample."""
    p.add_argument("--from", dest="t_from", type=float, default=None, metavar="SECONDS", help=SPAN_HELP.format("start"))
    p.add_argument("--to", dest="t_to", type=float, default=None, metavar="SECONDS", help=SPAN_HELP.format("end"))


SPAN_HELP = "the {} of the span shown and scored, in seconds after the recording's first sample"


def cropped(rec, t_from: float | None, t_to: float | None):
    """The rows of ``rec`` within ``--from`` / ``--to`` (seconds after its first sample)."""
    import numpy as np

    if t_from is None and t_to is None:
        return rec
    t0 = float(rec.t[0])
    a, b = t0 + (t_from or 0.0), t0 + (t_to if t_to is not None else np.inf)
    inside = (rec.t >= a) & (rec.t <= b)
    out = rec.select(inside) if inside.sum() >= 2 else None
    if out is None:
        raise CliError(
            f"--from/--to: the span {t_from or 0:g} to {t_to if t_to is not None else 'the end'} s holds fewer "
            f"than two samples of this {rec.duration:.2f} s recording"
        )
    return out


def add_input_args(p):
    """The options every recording-taking command shares (docs/readers.md)."""
    g = p.add_argument_group("input format (chosen from the file unless --format is given)")
    g.add_argument("--format", choices=FORMATS, default=None, help="reader: " + ", ".join(FORMATS))
    g.add_argument(
        "--map",
        action="append",
        metavar="FIELD=COL[,COL..]",
        help="--format csv: which columns are t, gyr, acc, mag, true_q, true_pos, true_vel, and "
        "rotor_speed / motor_command (one column per rotor) (e.g. --map gyr=gx,gy,gz; repeatable)",
    )
    g.add_argument(
        "--units",
        action="append",
        metavar="FIELD=UNIT",
        help="--format csv: t=s|ms|us|ns, gyr=rad/s|deg/s, acc=m/s^2|g|mg, mag=uT|nT|T|gauss|mgauss, "
        "rotor_speed=rad/s|rpm, motor_command=1|%%",
    )
    g.add_argument(
        "--frame",
        choices=["ned-frd", "enu-flu"],
        default="ned-frd",
        help="--format csv: the file's navigation/body frames (default: ned-frd)",
    )
    g.add_argument("--quat-order", choices=["wxyz", "xyzw"], default="wxyz", help="--format csv: true_q order")
    g.add_argument(
        "--topic",
        action="append",
        metavar="KIND=TOPIC",
        help="ROS bags: imu=/imu/data, mag=/imu/mag, truth=/vicon/pose when several are present",
    )
    g.add_argument(
        "--msgs",
        metavar="DIR",
        default=None,
        help="ROS 2 bags of PX4 topics that do not carry their message definitions (Humble): the "
        "px4_msgs msg/ folder of the PX4 that recorded them",
    )
    g.add_argument(
        "--imu",
        choices=IMU_SOURCES,
        default=None,
        help="autopilot logs: the IMU at its logged rate (default) or its high-rate samples, where the "
        "log has them (fifo: PX4 sensor_gyro_fifo / sensor_accel_fifo, ArduPilot's GYR / ACC batch "
        "sampler; `quadest info` lists what a log has)",
    )


def add_calibration_arg(p):
    p.add_argument(
        "--calibration",
        action="append",
        metavar="CALIB.json",
        help="apply a calibration from quadest calibrate before any filter (repeatable)",
    )


def count(text) -> int:
    """An argparse type: a whole number, 0 or more."""
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if n < 0:
        raise argparse.ArgumentTypeError(f"expected 0 or more, got {n}")
    return n


def positive(text) -> int:
    """An argparse type: a whole number, 1 or more."""
    n = count(text)
    if n < 1:
        raise argparse.ArgumentTypeError(f"expected 1 or more, got {n}")
    return n


def add_engine_args(p, default_workers=None):
    g = p.add_argument_group("execution (Dask)")
    g.add_argument(
        "--workers",
        type=count,
        default=default_workers,
        metavar="N",
        help="worker processes of a local Dask cluster; 0 runs in this process "
        + ("(default: 0)" if default_workers == 0 else "(default: one per core)"),
    )
    g.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="run on an existing Dask cluster instead")


def add_align_args(
    p, *, body: bool = True, default_text: str = "what the reader recommends, e.g. heading for DIDO/Blackbird"
):
    p.add_argument(
        "--align",
        choices=["none", "heading", "full"],
        default=None,
        help="remove a constant rotation between the estimate's and the truth's navigation "
        f"frames (default: {default_text})",
    )
    if body:
        p.add_argument(
            "--align-body",
            action=argparse.BooleanOptionalAction,
            default=None,
            help="also remove a constant rotation between IMU and truth body (default: on for RepoIMU)",
        )


def read(args, path):
    """A recording in any supported format, with the reader options of :func:`add_input_args`."""
    from quadest.readers import read_recording
    from quadest.readers.generic import parse_columns, parse_units

    opts = {}
    fmt = getattr(args, "format", None)
    if fmt == "csv" or getattr(args, "map", None):
        fmt = fmt or "csv"
        try:
            opts = {
                "columns": parse_columns(args.map),
                "units": parse_units(args.units),
                "frame": args.frame,
                "quat_order": args.quat_order,
            }
        except ValueError as exc:  # --map and --units are options: a usage error
            raise CliError(str(exc)) from None
    else:  # given for another format: passed on, so that its reader refuses them (never ignored)
        if getattr(args, "units", None):
            opts["units"] = args.units
        for name, default in (("frame", "ned-frd"), ("quat_order", "wxyz")):
            if getattr(args, name, default) != default:
                opts[name] = getattr(args, name)
    for item in getattr(args, "topic", None) or []:
        kind, sep, topic = item.partition("=")
        if not sep or kind not in ("imu", "mag", "truth"):
            raise CliError(f"--topic {item!r}: expected imu=TOPIC, mag=TOPIC or truth=TOPIC")
        opts[f"{kind}_topic"] = topic
    if getattr(args, "imu", None):
        opts["imu"] = args.imu
    if getattr(args, "msgs", None):
        opts["msgs"] = args.msgs
    rec = read_recording(path, fmt, **opts)
    dropped = rec.meta.get("dropped_rows")
    if dropped:  # said on stderr, so that JSON on stdout stays clean
        LOG.info(
            f"note: {path}: dropped {dropped} row(s) with a repeated or decreasing time or a non-finite or implausible "
            "IMU value"
        )
    for warning in rec.meta.get("warnings", []):
        LOG.warning(f"warning: {path}: {warning}")
    return rec


def write_report_for(
    rec, names, params, path, title, json_path=None, recovery=None, recovery_model="", rotors=None, diagnosis=None
):
    """``quadest report`` and every ``--report PATH``: the HTML page for ``rec`` with the
    estimators ``names``, a throw's ``recovery`` and a log's ``diagnosis``
    (:meth:`~quadest.evaluation.diagnose.Diagnosis.for_report`; docs/report.md)."""
    from quadest.evaluation.inspect import report_data, report_json

    need("bokeh", "the HTML report")
    from quadest.plot.report import write_report  # bokeh: only when a report is written

    summ, att = report_data(rec, names, params, recovery)
    att["recovery_model"] = recovery_model
    att["rotors"] = rotors
    att["diagnosis"] = diagnosis
    out = write_report(rec, summ, att, path, title)
    if json_path:
        table = report_json(summ, att)
        if diagnosis is not None:
            table["diagnosis"] = diagnosis["json"]
        write_json(json_path, table)
    say(f"wrote {out} (open it in a browser)")
    return out


def add_report_arg(p):
    p.add_argument(
        "--report",
        type=Path,
        metavar="PATH",
        default=None,
        help="also write an HTML report of the recording and the estimators (quadest report; docs/report.md)",
    )
