"""``quadest report``: one self-contained HTML page of a recording, a log's diagnosis, a sweep's
or a campaign's results."""

from __future__ import annotations

from pathlib import Path

from quadest.cli.common import (
    LOG,
    CliError,
    add_calibration_arg,
    add_input_args,
    add_span_args,
    cropped,
    read,
    say,
    write_json,
    write_report_for,
)
from quadest.extras import need


def cmd_report(args):
    from quadest.calibration import apply_calibrations
    from quadest.evaluation.compare import parse_params
    from quadest.evaluation.inspect import events
    from quadest.evaluation.runner import estimator_names
    from quadest.models.aero import AeroModel
    from quadest.recovery import recover
    from quadest.sim import aero_model_of
    from quadest.sweep.summary import is_results

    if Path(args.file).suffix.lower() == ".parquet" and is_results(args.file):
        return _sweep_report(args)
    rec = cropped(read(args, args.file), args.t_from, args.t_to)
    rec, cal_params = apply_calibrations(rec, args.calibration)
    names = estimator_names(args.filters, all_includes_peers=False)
    params = parse_params(args.param)
    other = sorted(set(params) - set(names))
    if other:
        raise CliError(f"--param names {', '.join(other)}, which this report does not run (--filters)")
    kw = {n: {**cal_params.get(n, {}), **params.get(n, {})} for n in names}
    recovery, source = None, ""
    if any(e["kind"].startswith("free fall") for e in events(rec)):
        model = AeroModel.load(args.aero) if args.aero else None
        source = f"the aerodynamic model of {args.aero}"
        if model is None:
            try:
                model = aero_model_of(rec)  # a simulated recording carries its configuration's model
                source = "the aerodynamic model of the recording's simulation configuration"
            except ValueError:
                say("a free fall was found; give --aero aero.json (quadest fit-aero) to see the recovery's bank")
        if model is not None:
            recovery = recover(rec, model, record_all=True)
    rotors = _rotor_speeds(
        args.rotors or Path(args.file).with_name(Path(args.file).stem + "-flight.parquet"), explicit=bool(args.rotors)
    )
    write_report_for(
        rec,
        names,
        kw,
        args.output,
        args.title or f"quadest report: {Path(args.file).name}",
        args.json,
        recovery=recovery,
        recovery_model=source,
        rotors=rotors,
        diagnosis=_log_diagnosis(args.file),
    )
    return 0


def _log_diagnosis(path) -> dict | None:
    """An autopilot log's diagnosis for its report page (quadest diagnose), or None for a file
    that is not one or has no motor outputs (said in one line)."""
    from quadest.evaluation.diagnose import DiagnoseParams, diagnose_log
    from quadest.readers import ReaderError
    from quadest.readers.motors import MOTOR_LOG_SUFFIXES

    if Path(path).suffix.lower() not in MOTOR_LOG_SUFFIXES:
        return None
    try:
        return diagnose_log(path, DiagnoseParams()).for_report()
    except ReaderError as exc:
        say(f"no motor diagnosis on the page: {exc}")
        return None


def _rotor_speeds(path, explicit: bool):
    """A flown recording's rotor speeds and commands (its ``-flight.parquet`` from quadest fly):
    ``(t, {column: values})``, or None when there is no such file (an error when it was named)."""
    import pyarrow.parquet as pq

    path = Path(path)
    if not path.is_file():
        if explicit:
            raise CliError(f"--rotors {path}: no such file (quadest fly writes NAME-flight.parquet beside NAME.csv)")
        return None
    with open(path, "rb") as fh:
        table = pq.read_table(fh)
    cols = [c for c in table.column_names if c.startswith("rotor") and c.endswith("_speed")]
    if "t" not in table.column_names or not cols:
        if explicit:
            raise CliError(f"--rotors {path}: no t and rotorN_speed columns (a quadest fly flight table)")
        return None
    return table.column("t").to_numpy(), {c: table.column(c).to_numpy() for c in cols}


def _campaign_report(args, table):
    from quadest.plot.campaign import write_campaign_report  # bokeh: only when a report is written
    from quadest.sweep.campaign import campaign_summary

    summ = campaign_summary(table.to_pylist())
    out = write_campaign_report(summ, args.output, args.title or f"quadest campaign: {Path(args.file).name}")
    if args.json:
        write_json(args.json, summ)
    say(f"{summ['runs']} flights of a survival campaign; wrote {out} (open it in a browser)")
    return 0


def _sweep_report(args):
    from quadest.sweep.campaign import is_campaign
    from quadest.sweep.engine import ResultStore
    from quadest.sweep.summary import sweep_summary

    need("bokeh", "the HTML report")
    from quadest.plot.report import write_sweep_report  # bokeh: only when a report is written

    store = ResultStore(args.file)
    table = store.read()
    if store.damaged:
        LOG.warning(
            f"quadest report: warning: {args.file}: {store.damaged} damaged row(s) left out (a sweep on it runs them "
            "again)"
        )
    if table is None:
        raise CliError(f"{args.file}: no results left to report")
    if is_campaign(table.column_names):
        return _campaign_report(args, table)
    summ = sweep_summary(table)
    out = write_sweep_report(summ, args.output, args.title or f"quadest sweep results: {Path(args.file).name}")
    if args.json:
        write_json(args.json, summ)
    say(f"{summ['runs']} runs of {', '.join(summ['filters'])}; wrote {out} (open it in a browser)")
    return 0


def add_parsers(sub):
    r = sub.add_parser(
        "report",
        help="an HTML report of a recording, to open in a browser",
        description="One self-contained HTML page (opens offline) for any recording quadest reads: "
        "a summary (rates, gaps, clipping, vibration, magnetic disturbance, events such "
        "as rests, free falls and spins), each estimator's attitude beside the truth "
        "or the autopilot's own estimate (labelled so) with error plots and an RMS "
        "table, the raw sensors, the magnetometer's norm and dip and the "
        "accelerometer's spectrogram; linked zoom. Numbers from all samples; plots "
        "decimated for display.",
    )
    r.add_argument(
        "file",
        type=Path,
        help="recording: any supported format (docs/readers.md), or a sweep's "
        "results (.parquet from quadest sweep or tune)",
    )
    r.add_argument(
        "--filters",
        default="robust,madgwick,afckf",
        help="estimators to run: comma-separated, quadest (all of quadest's), or peers (default: "
        "robust,madgwick,afckf)",
    )
    add_span_args(r)
    r.add_argument("--param", action="append", metavar="FILTER.NAME=VALUE", help="a filter parameter (repeatable)")
    r.add_argument("--title", default=None, help="the page's title (default: from the file name)")
    r.add_argument("-o", "--output", "--out", type=Path, required=True, help="the HTML file to write")
    r.add_argument("--json", type=Path, default=None, help="also write the report's tables as JSON")
    r.add_argument(
        "--rotors",
        type=Path,
        default=None,
        metavar="FLIGHT.parquet",
        help="rotor speeds to show (default: NAME-flight.parquet beside the recording, as quadest fly writes it)",
    )
    r.add_argument(
        "--aero",
        metavar="JSON",
        default=None,
        help="with a throw in the recording: the aerodynamic model for the recovery's bank (default: a "
        "simulation's own; quadest fit-aero)",
    )
    add_calibration_arg(r)
    add_input_args(r)
    r.set_defaults(func=cmd_report)
