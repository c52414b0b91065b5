"""``quadest info``, ``quadest diagnose``, ``quadest calibrate`` and ``quadest estimate``: one recording in, a summary,
a calibration or an attitude out."""

from __future__ import annotations

from pathlib import Path

from quadest.cli.choices import DIAGNOSE_DEFAULTS, ESTIMATORS, filter_name
from quadest.cli.common import (
    CliError,
    add_calibration_arg,
    add_input_args,
    add_report_arg,
    read,
    say,
    say_units_beside,
    write_json,
    write_report_for,
)


def cmd_info(args):
    from quadest.data import files, format_summary, summarize

    rec = read(args, args.file)
    s = summarize(rec)
    if args.json:
        say(files.dumps_json(s))
    else:
        say(format_summary(s, str(args.file)))
    return 0


AUTOPILOT_LOGS = (".bin", ".ulg")
"""Logs whose motor outputs ``diagnose`` reads with a model built from the log (without --vehicle)."""


def cmd_diagnose(args):
    if not args.file.exists():
        raise CliError(f"{args.file}: no such file")
    if args.vehicle is None and args.file.suffix.lower() in AUTOPILOT_LOGS:
        return _diagnose_log(args)
    return _diagnose_speeds(args)


def _diagnose_speeds(args):
    from quadest.evaluation.diagnose_speeds import diagnose_speeds, format_speed_diagnosis
    from quadest.models.multirotor import MultirotorParams
    from quadest.models.vehicle_file import read_vehicle_file

    if args.report:
        raise CliError("--report: the page draws an autopilot log's motor outputs; leave it out with --vehicle")
    drag = ((0.0, 0.0), (0.0, 0.0))
    if args.vehicle is not None:
        vehicle, _, identified = read_vehicle_file(args.vehicle)
        source = str(args.vehicle)
        drag = identified.get("drag_moment", {}).get("value", drag)
    rec = read(args, args.file)
    if rec.rotor_speed is None:
        raise CliError(
            f"{args.file}: no rotor speeds: diagnose reads motor outputs from ArduPilot (.bin) and PX4 (.ulg) logs, "
            "and rotor speeds (with a vehicle file, --vehicle) from other recordings"
        )
    if args.vehicle is None:
        vehicle = MultirotorParams()
        source = "quadest's default vehicle (the recovery paper's), not this one: give --vehicle (quadest identify)"
        say(f"no --vehicle: the model assumed is {source}")
    d = diagnose_speeds(rec, vehicle, file=str(args.file), vehicle_source=source, drag_moment=drag)
    say(format_speed_diagnosis(d))
    if args.json:
        write_json(args.json, d.as_json())
    return 0


def _diagnose_log(args):
    from quadest.evaluation.diagnose import DiagnoseParams, diagnose_log, format_diagnosis

    if not args.moment_gain > 0:
        raise CliError(f"--moment-gain {args.moment_gain}: must be positive (rad/s² per unit thrust)")
    if not 0 < args.excess_threshold < 10:
        raise CliError(f"--excess-threshold {args.excess_threshold}: must be a share between 0 and 10")
    params = DiagnoseParams(moment_gain=args.moment_gain, excess_threshold=args.excess_threshold)
    d = diagnose_log(args.file, params)
    say(format_diagnosis(d))
    if args.json:
        write_json(args.json, d.as_json())
    if args.report:
        rec = read(args, args.file)
        title = f"quadest diagnose: {args.file.name}"
        write_report_for(rec, [], {}, args.report, title, diagnosis=d.for_report())
    return 0


def cmd_calibrate(args):
    import numpy as np

    from quadest.calibration import calibrate

    recs = [read(args, p) for p in args.recordings]
    kw = {"mass_kg": args.mass} if args.kind == "aero" else {}
    cal = calibrate(args.kind, recs, **kw)
    cal.save(args.output)
    say(f"{args.kind} calibration from {len(recs)} recording(s)")
    for key, val in cal.values.items():
        unc = cal.uncertainty.get(key)
        say(
            f"  {key:<22} {np.array2string(np.asarray(val), precision=5, suppress_small=True)}"
            + (
                f"  ± {np.array2string(np.asarray(unc), formatter={'float_kind': lambda x: f'{x:.1e}'})}"
                if unc is not None
                else ""
            )
        )
    for key, val in cal.quality.items():
        if key in ("samples_per_position", "recordings"):
            continue
        say(f"  {key:<22} {val if not isinstance(val, float) else round(val, 5)}")
    say(f"wrote {args.output}")
    return 0


WRITE_ROWS = 1 << 18
"""Rows per block where an estimate is written (its output columns are never held whole)."""


ATTITUDE_UNITS = {
    "t": "s (the file's own time)",
    **{f"q_{c}": "1 (Hamilton, scalar first; body FRD to navigation NED)" for c in "wxyz"},
    **{a: "rad (ZYX Euler angle, body FRD in navigation NED)" for a in ("roll", "pitch", "yaw")},
}
"""The units and frames of an estimate's columns (docs/conventions.md), kept in its Parquet schema."""


def attitude_blocks(t, q, extra: dict | None = None, rows: int = WRITE_ROWS):
    """``t, q_w ... q_z, roll, pitch, yaw`` and ``extra``'s columns, block by block of ``rows``."""
    import numpy as np

    from quadest.rotation import quat_to_euler

    for s in range(0, len(q), rows):
        qb = q[s : s + rows]
        euler = quat_to_euler(qb)
        yield {
            "t": t[s : s + rows],
            **{f"q_{c}": np.ascontiguousarray(qb[:, j]) for j, c in enumerate("wxyz")},
            **{name: np.ascontiguousarray(euler[:, j]) for j, name in enumerate(("roll", "pitch", "yaw"))},
            **{k: v[s : s + rows] for k, v in (extra or {}).items()},
        }


def estimate_filter(args) -> str:
    """The estimator ``quadest estimate`` runs: ``--filter``, else robust (robust-offline with
    ``--offline``); with ``--offline`` it must be acausal."""
    from quadest.filters import ESTIMATORS

    if not args.offline:
        return args.filter or "robust"
    name = args.filter or "robust-offline"
    if not ESTIMATORS[name].acausal:
        offline = ", ".join(n for n, c in ESTIMATORS.items() if c.acausal)
        raise CliError(f"--offline: {name} is a causal estimator; offline ones: {offline} (or leave out --filter)")
    return name


def cmd_estimate(args):
    import numpy as np

    from quadest.calibration import apply_calibrations
    from quadest.data import write_blocks
    from quadest.data.checks import warn_tilt_disagreement
    from quadest.evaluation.compare import parse_params
    from quadest.evaluation.runner import estimate, filter_notes

    args.filter = estimate_filter(args)
    rec = read(args, args.file)
    if not args.report:  # the truth is for the report alone: a long recording's is not held
        rec = rec.sensors_only()
    rec, cal_params = apply_calibrations(rec, args.calibration)
    params = parse_params(args.param)
    other = sorted(set(params) - {args.filter})
    if other:
        raise CliError(f"--param names {', '.join(other)}, but this runs {args.filter} (--filter)")
    kw = {**cal_params.get(args.filter, {}), **params.get(args.filter, {})}
    if args.declination_deg is not None and not abs(args.declination_deg) <= 180.0:
        raise CliError(f"--declination-deg {args.declination_deg:g}: a declination in degrees lies within ±180")
    decl = np.radians(args.declination_deg) if args.declination_deg is not None else None
    res = estimate(rec, args.filter, kw, declination=decl)
    warn_tilt_disagreement(args.filter, res.q, rec.acc)
    for line in filter_notes(res):
        say(line)
    if args.diagnostics and not res.diag:
        raise CliError(f"--diagnostics: {args.filter} reports no per-sample diagnostics")
    diag = {f"diag_{k}": v for k, v in res.diag.items()} if args.diagnostics else {}
    write_blocks(attitude_blocks(rec.t, res.q, diag), Path(args.output), units=ATTITUDE_UNITS)
    extra = f", diag_{', diag_'.join(res.diag)}" if args.diagnostics else ""
    say(f"{args.filter}: {len(rec)} samples -> {args.output} (t, q_w, q_x, q_y, q_z, roll, pitch, yaw; rad{extra})")
    say_units_beside(args.output)
    decl = np.degrees(rec.declination if decl is None else decl)
    source = "--declination-deg" if args.declination_deg is not None else rec.declination_source
    say(f"  t in the file's own time, from {rec.t[0]:.3f} s; declination {decl:+.2f}° ({source})")
    if args.report:
        write_report_for(
            rec,
            [args.filter],
            {args.filter: kw},
            args.report,
            f"quadest estimate: {args.filter} on {Path(args.file).name}",
        )
    return 0


def _add_diagnose(sub):
    d = sub.add_parser(
        "diagnose",
        help="find rotor failures and damaged propellers in an autopilot log",
        description="Run quadest's rotor-failure detector on a recorded flight (ArduPilot DataFlash "
        ".bin or PX4 ULog .ulg) at the log's own rates, with a vehicle model built from the log "
        "(frame, motor numbering and thrust curve from its parameters, thrust over mass from its "
        "accelerometer), and compare each motor's share of the thrust with the others' (a "
        "damaged propeller makes its motor work harder). Times in the log's own time base, motors "
        "in the autopilot's numbering (docs/diagnose.md). With --vehicle (a vehicle file from quadest "
        "identify), a recording with measured rotor speeds in any format (DIDO, CSV, ...) is diagnosed "
        "against that vehicle: rotors lost or damaged, in the recording's column order (docs/vehicle.md).",
    )
    d.add_argument("file", type=Path, help="ArduPilot (.bin) or PX4 (.ulg) log, or with --vehicle any recording")
    d.add_argument(
        "--vehicle",
        type=Path,
        default=None,
        metavar="VEHICLE.toml",
        help="the vehicle file (quadest identify) to diagnose a recording with rotor speeds against",
    )
    d.add_argument(
        "--json",
        type=Path,
        default=None,
        help='also write {"failures": [{time_s, motor, effectiveness}], "damaged": [{motor, excess}], "motors": [...]}',
    )
    d.add_argument(
        "--report",
        type=Path,
        metavar="PATH",
        default=None,
        help="also write the HTML page of the log with the diagnosis: the failures, the motors' shares and "
        "their outputs over time (quadest report LOG shows the same beside the estimators; docs/report.md)",
    )
    d.add_argument(
        "--moment-gain",
        type=float,
        default=DIAGNOSE_DEFAULTS.moment_gain,
        metavar="RAD_S2",
        help="roll/pitch angular acceleration per unit of one motor's thrust on a unit arm "
        f"(default {DIAGNOSE_DEFAULTS.moment_gain:g}; docs/diagnose.md shows the range that works)",
    )
    d.add_argument(
        "--excess-threshold",
        type=float,
        default=DIAGNOSE_DEFAULTS.excess_threshold,
        metavar="SHARE",
        help="flag a motor whose thrust exceeds the others' mean by more than this share "
        f"(default {DIAGNOSE_DEFAULTS.excess_threshold:g})",
    )
    add_input_args(d)
    d.set_defaults(func=cmd_diagnose)


def add_parsers(sub):
    i = sub.add_parser(
        "info",
        help="summarise a recording",
        description="Print duration, rates, ranges, gaps and which truth a "
        "recording holds; any supported format (docs/readers.md).",
    )
    i.add_argument("file", type=Path, help="recording: any supported format (docs/readers.md)")
    i.add_argument("--json", action="store_true", help="print JSON instead of text")
    add_input_args(i)
    i.set_defaults(func=cmd_info)

    _add_diagnose(sub)

    _add_calibrate(sub)
    _add_estimate(sub)


def _add_calibrate(sub):
    cb = sub.add_parser(
        "calibrate",
        help="calibrate a sensor from recordings",
        description="Fit a calibration and write it with its uncertainty and quality "
        "figures. gyro: bias from rest segments (found automatically); accel: "
        "bias, scale and misalignment from a six-position or many-position "
        "static set; mag: hard and soft iron by ellipsoid fit from a rotation "
        "sequence; centrifugal: the AFCKF's ω1, ω2 from a spinning segment; "
        "aero: the recovery paper's model (as fit-aero). docs/calibration.md "
        "gives the procedures.",
    )
    cb.add_argument("kind", choices=["gyro", "accel", "mag", "centrifugal", "aero"])
    cb.add_argument("recordings", nargs="+", type=Path, metavar="RECORDING")
    cb.add_argument("-o", "--output", "--out", required=True, metavar="CALIB.json")
    cb.add_argument("--mass", type=float, default=None, help="aero: vehicle mass, kg")
    add_input_args(cb)
    cb.set_defaults(func=cmd_calibrate)


def _add_estimate(sub):
    es = sub.add_parser(
        "estimate",
        help="run one estimator on a recording and write its attitude",
        description="Run an estimator over a recording (any supported format) and write t, q_w, "
        "q_x, q_y, q_z, roll, pitch, yaw (radians) to .csv or .parquet.",
    )
    es.add_argument("file", type=Path, help="recording: any supported format (docs/readers.md)")
    es.add_argument(
        "--filter",
        default=None,
        type=filter_name,
        choices=list(ESTIMATORS),
        help="estimator: quadest's, or a peer with quadest[peers] installed (default: robust, "
        "quadest's own, or robust-offline with --offline; docs/estimators.md)",
    )
    es.add_argument(
        "--offline",
        action="store_true",
        help="an acausal estimate for a log analysed after the fact: each sample's attitude from the whole "
        "recording, before and after it (robust-offline, or the offline estimator --filter names: "
        "robust-offline, vqf-offline)",
    )
    es.add_argument(
        "-o", "--output", "--out", required=True, metavar="OUT", help=".csv or .parquet; - for CSV on standard output"
    )
    es.add_argument("--param", action="append", metavar="FILTER.NAME=VALUE", help="estimator parameter")
    es.add_argument(
        "--diagnostics",
        action="store_true",
        help="also write the estimator's per-sample diagnostics as diag_* columns (robust: its reported "
        "error variances var_tilt and var_heading in rad², the bias, rest, disturbance, clipping)",
    )
    es.add_argument(
        "--declination-deg",
        type=float,
        default=None,
        help="magnetic declination, east positive (default: the log's own, PX4 EKF2_MAG_DECL or ArduPilot "
        "COMPASS_DEC, or a simulation's; else 0; `quadest info` shows which)",
    )
    add_calibration_arg(es)
    add_input_args(es)
    add_report_arg(es)
    es.set_defaults(func=cmd_estimate)
