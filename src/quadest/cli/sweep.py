"""``quadest sweep`` and ``quadest tune``: grids of filters and parameters over many flights."""

from __future__ import annotations

import math
import sys
from pathlib import Path

from quadest.cli.choices import (
    CAMPAIGN_FAILURE_MODES,
    CONTROLLERS,
    DETECTIONS,
    FLIGHT_SCENARIOS,
    PRESCRIBED_SCENARIOS,
    PRESETS,
    TRUTH_SPREADS,
    VEHICLE_PRESETS,
    filter_name,
)
from quadest.cli.common import (
    CliError,
    add_engine_args,
    add_max_runs_arg,
    check_runs,
    parse_seeds,
    parse_sets,
    say,
    sim_config,
    write_json,
)
from quadest.cli.flight_options import detector_sets, failure_record, parse_failure
from quadest.extras import need


def _flown_sources(args):
    from quadest.flight import DEFAULT_DURATION
    from quadest.models import vehicle_preset
    from quadest.sweep import flown_sources

    if args.data or args.set:
        raise CliError("--fly flies the vehicle: it takes neither --data nor --set")
    failures = [parse_failure(f) for f in args.failure] if args.failure else [None]
    seeds = parse_seeds(args.seeds)
    check_runs(args, len(seeds) * len(failures), f"--seeds {args.seeds} x {len(failures)} failure(s)")
    vehicle = vehicle_preset(args.vehicle)
    duration = args.duration or DEFAULT_DURATION[args.fly]
    for f in failures:  # refused before any run starts
        if f is not None:
            f.check(vehicle, duration)
    return flown_sources(
        args.fly,
        seeds,
        controller=args.controller,
        failures=[failure_record(f) for f in failures],
        duration=args.duration,
        vehicle=args.vehicle,
        preset=args.preset,
    )


def _sim_sources(args):
    from quadest.sweep import sim_sources

    preset = args.preset or "bebop2"
    sim_config(preset, args.set)  # refuse a wrong --set before any run starts
    seeds = parse_seeds(args.seeds)
    check_runs(args, len(seeds), f"--seeds {args.seeds}")  # before a source is made for each
    return sim_sources(args.scenario, preset, seeds, args.duration, parse_sets(args.set), args.t_from)


def _sweep_runs(args, filters):
    from quadest.readers.catalog import resolve_data
    from quadest.sweep import build_runs, file_sources, parse_grid

    grid = parse_grid(args.grid, args.max_runs)
    if args.fly:
        sources = _flown_sources(args)
    elif args.data:
        sources = file_sources([resolve_data(d) for d in args.data], args.format)
    else:
        sources = _sim_sources(args)
    return build_runs(filters, grid, sources, args.align, args.max_runs)


def _announce(args, runs):
    where = (
        f"on the Dask cluster at {args.scheduler}"
        if args.scheduler
        else "in this process"
        if args.workers == 0
        else f"on a local Dask cluster of {args.workers} worker(s)"
        if args.workers
        else "on a local Dask cluster (one worker per core)"
    )
    say(f"{len(runs)} runs {where}; results in {args.out}")


def _report(args, res):
    say(
        f"executed {res['executed']} (skipped {res['skipped']} already in {args.out}) in {res['wall_s']:.1f} s"
        + (
            f"; {res['runs_per_s']:.2f} runs/s over {res['compute_s']:.1f} s of computing (cluster start-up excluded)"
            if res["executed"]
            else ""
        )
        + f"; results hold {res['ok']} ok, {res['failed']} failed"
    )
    if res["failed"]:
        say("failed runs keep their error in the 'error' column; --retry-failed runs them again")


def _engine(args) -> dict:
    return {"workers": args.workers, "scheduler": args.scheduler, "retry_failed": args.retry_failed, "progress": True}


def cmd_sweep(args):
    from quadest.sweep import run_sweep
    from quadest.sweep.engine import ResultStore
    from quadest.sweep.summary import format_sweep_summary, sweep_summary

    runs = _sweep_runs(args, args.filters)
    _announce(args, runs)
    res = run_sweep(runs, args.out, **_engine(args))
    _report(args, res)
    table = ResultStore(args.out).read()
    if table is not None and table.num_rows:
        res["summary"] = sweep_summary(table)
        say(format_sweep_summary(res["summary"]))
        say(f"every set, and the metrics against each parameter: quadest report {args.out}")
    if args.json:
        write_json(args.json, res)
    if res["executed"] and not res["executed_ok"]:
        print(
            f"quadest sweep: error: none of the {res['executed']} runs succeeded; their errors are in "
            f"{args.out} (column 'error')",
            file=sys.stderr,
        )
        return 1
    return 0


def cmd_tune(args):
    from quadest.sweep import format_selection, format_split, tune

    runs = _sweep_runs(args, args.filter)
    _announce(args, runs)
    sel, res = tune(runs, args.out, args.filter, args.metric, split=args.split, **_engine(args))
    _report(args, res)
    say(format_split(sel) if args.split else format_selection(sel))
    if args.json:
        write_json(args.json, {**sel, "sweep": res})
    return 0


def _campaign_list(text: str, option: str, unit: str) -> list:
    """A comma-separated list of numbers (``none``: the preset's value) for ``option``."""
    out = []
    for item in str(text).split(","):
        item = item.strip().lower()
        if item in ("none", "preset"):
            out.append(None)
            continue
        try:
            v = float(item)
        except ValueError:
            raise CliError(f"{option}: {item!r} is not a number of {unit} (give e.g. {option} 1000,500)") from None
        if not math.isfinite(v) or v < 0 or (v == 0 and unit == "°/s"):
            raise CliError(f"{option}: {item} is out of range (give a positive number of {unit})")
        out.append(v)
    return out


def _campaign_runs(args):
    from quadest.sweep.campaign import DETECTIONS, HEIGHT_M, campaign_runs
    from quadest.sweep.runs import flown_names

    filters = flown_names(args.filters, "rotor-loss")
    detections = [d.strip() for d in args.detection.split(",") if d.strip()]
    if not detections:
        raise CliError(f"--detection: give one or more of {', '.join(DETECTIONS)}, comma-separated")
    if args.height is not None and not 1.0 <= args.height <= 1000.0:
        raise CliError(f"--height {args.height:g}: give the hover point's height above the ground in m, 1 to 1000")
    seeds = parse_seeds(args.seeds)
    none = args.nominal_seeds.strip().lower() == "none"
    try:
        nominal = [] if none else parse_seeds(args.nominal_seeds, "--nominal-seeds")
    except CliError as exc:
        raise CliError(f"{exc}, or none (no nominal flight)") from None
    if args.height is not None and args.height != HEIGHT_M and nominal:
        raise CliError(
            "--height is for the failures: give --nominal-seeds none with it (a nominal flight lands from the hover "
            "point, so the height would change its landing and the alarms counted)"
        )
    gyro = _campaign_list(args.gyro_range, "--gyro-range", "°/s")
    lat = [v or 0.0 for v in _campaign_list(args.mag_latency, "--mag-latency", "s")]
    detector = detector_sets(args.set, detections, "campaign")
    modes = [m.strip() for m in args.failure_modes.split(",") if m.strip()]
    per_case = len(filters) * len(detections) * len(gyro) * len(lat)
    cases = len(seeds) * len(modes) + len(nominal)  # at most: a partial loss is flown once
    check_runs(args, per_case * cases, f"{cases:,} cases x {per_case} set(s)")
    return campaign_runs(seeds, nominal, filters, detections=detections, gyro_ranges_dps=gyro, mag_latencies_s=lat,
                         duration=args.duration, height_m=args.height, detector=detector,
                         failure_modes=modes, truth_spread=args.truth_spread)  # fmt: skip


def cmd_campaign(args):
    from quadest.sweep import run_sweep
    from quadest.sweep.campaign import campaign_summary, format_campaign
    from quadest.sweep.engine import ResultStore

    runs = _campaign_runs(args)
    if args.report:
        need("bokeh", "the campaign's HTML report")
    _announce(args, runs)
    res = run_sweep(runs, args.out, **_engine(args))
    _report(args, res)
    summary = campaign_summary(ResultStore(args.out).read().to_pylist())
    say(format_campaign(summary))
    if args.json:
        write_json(args.json, {**summary, "sweep": res})
    if args.report:
        from quadest.plot.campaign import write_campaign_report  # bokeh: only when a report is written

        say(f"wrote {write_campaign_report(summary, args.report, f'quadest campaign: {args.out.name}')}")
    return 1 if res["executed"] and not res["executed_ok"] else 0


def _add_campaign_args(p):
    p.add_argument(
        "--seeds",
        default="0-99",
        help="the failures' seeds: each decides the scenario (hover, "
        "circle, figure eight in turn), the rotor, the time, and for one in four a partial loss (default: 0-99)",
    )
    p.add_argument(
        "--nominal-seeds",
        default="1000-1019",
        help="the nominal flights' seeds (none: no nominal flight; default: 1000-1019)",
    )
    p.add_argument("--duration", type=float, default=60.0, help="seconds of each nominal flight (default: 60)")
    p.add_argument(
        "--height",
        type=float,
        default=None,
        metavar="M",
        help="the hover point's height above the ground in m, 1 to 1000, for the failures (with --nominal-seeds "
        "none); each loss's deepest point is recorded, so the losses that would have stayed up flown lower are "
        "counted too (default: 3)",
    )
    p.add_argument(
        "--filters",
        default="robust",
        help="estimators in the loop, comma-separated (truth: the true state, an oracle; default: robust)",
    )
    p.add_argument(
        "--detection",
        default=",".join(DETECTIONS),
        help="how the controller learns of a loss, "
        "comma-separated: rotor-speeds, commands (the detector), oracle (told 50 ms after) (default: all three)",
    )
    p.add_argument(
        "--failure-modes",
        default=CAMPAIGN_FAILURE_MODES[0],
        metavar="MODE[,MODE...]",
        help=f"how the complete losses happen, comma-separated: {', '.join(CAMPAIGN_FAILURE_MODES)} (the motor "
        "stops and spins down, its propeller on); each complete-loss seed is flown once per mode, the partial losses "
        f"and nominal flights once (default: {CAMPAIGN_FAILURE_MODES[0]})",
    )
    p.add_argument(
        "--truth-spread",
        default="none",
        choices=TRUTH_SPREADS,
        help="the vehicle flown drawn apart from the model its estimator, detector and controllers know, one draw "
        "per flight from its seed: none (the model flies) or default (docs/truth.md's ranges) (default: none)",
    )
    p.add_argument(
        "--gyro-range",
        default="none",
        metavar="DPS[,DPS...]",
        help="gyroscope full-scale ranges in °/s, "
        "comma-separated (none: the Bebop 2 preset's, ±1000 °/s; default: none)",
    )
    p.add_argument(
        "--mag-latency",
        default="0",
        metavar="S[,S...]",
        help="magnetometer latencies in s, comma-separated (default: 0)",
    )
    p.add_argument(
        "--set",
        action="append",
        metavar="detector.KEY=VALUE",
        help="change a parameter of the detector the rotor-speeds and commands runs fly, e.g. --set "
        "detector.lost_threshold=0.008 (repeatable; checked against its bounds; docs/detection.md lists them); "
        "its runs are told apart from the defaults' in the results file and the summary",
    )
    _add_results_args(p, "flight")
    p.add_argument("--report", metavar="PATH", help="write the campaign's HTML page (docs/campaign.md)")
    add_engine_args(p)


def _add_results_args(p, row: str):
    """The results file and what a sweep or a campaign does with it: the same options on both."""
    p.add_argument(
        "-o",
        "--output",
        "--out",
        dest="out",
        required=True,
        type=Path,
        metavar="RESULTS.parquet",
        help=f"results file, one row per {row} (parts go to RESULTS.parquet.parts/ while it runs); "
        "an existing one is resumed",
    )
    p.add_argument("--retry-failed", action="store_true", help="run again the runs recorded as failed")
    add_max_runs_arg(p)
    p.add_argument("--json", metavar="OUT", help="write the summary as JSON")


def _add_sweep_args(p):
    p.add_argument(
        "--grid",
        action="append",
        metavar="FILTER.PARAM=VALUES",
        help="parameter values: a list 0.01,0.1, lin:A:B:N or log:A:B:N (repeatable; several "
        "parameters of one filter make their Cartesian product)",
    )
    src = p.add_argument_group("data: simulated flights (default) or recordings")
    src.add_argument(
        "--data",
        nargs="+",
        metavar="PATH",
        help="recordings or folders of them (e.g. ../shared/data/broad), any supported format, or a "
        "dataset fetched with quadest data fetch (broad)",
    )
    src.add_argument("--format", default=None, help="with --data: reader (default: chosen from each file)")
    src.add_argument(
        "--scenario", choices=PRESCRIBED_SCENARIOS, default="nominal", help="simulated scenario (default: nominal)"
    )
    src.add_argument(
        "--preset",
        choices=list(PRESETS),
        default=None,
        help="simulator preset (default: bebop2; fma for a flown throw)",
    )
    src.add_argument("--seeds", default="1-10", help="seed range or list (default: 1-10)")
    src.add_argument("--duration", type=float, default=None, help="seconds per simulated flight")
    src.add_argument("--set", action="append", metavar="KEY=VALUE", help="simulator parameter")
    src.add_argument(
        "--from", dest="t_from", type=float, default=None, metavar="SECONDS", help="count errors from this time on"
    )
    fl = p.add_argument_group("flown flights: the vehicle flies with each estimator in the loop (docs/vehicle.md)")
    fl.add_argument(
        "--fly",
        choices=FLIGHT_SCENARIOS,
        default=None,
        metavar="SCENARIO",
        help=f"fly this scenario ({', '.join(FLIGHT_SCENARIOS)}) instead of simulating a prescribed one; "
        "--filters then names the estimators in the loop (truth too; recovery for a throw)",
    )
    fl.add_argument("--controller", choices=CONTROLLERS, default=None, help="with --fly (default: per scenario)")
    fl.add_argument(
        "--failure",
        action="append",
        metavar="ROTOR@TIME[:EFF[:IMB]]",
        help="with --fly: a rotor failure (repeatable: every failure with every seed)",
    )
    fl.add_argument(
        "--vehicle",
        choices=list(VEHICLE_PRESETS),
        default="recovery",
        help="with --fly: the vehicle (default: recovery)",
    )
    p.add_argument(
        "--align",
        choices=["none", "heading", "full"],
        default=None,
        help="constant navigation-frame rotation removed (default: the reader's recommendation)",
    )
    _add_results_args(p, "run")
    add_engine_args(p)


def add_parsers(sub):
    sw = sub.add_parser(
        "sweep",
        help="run a grid of filters and parameters over many flights, on Dask",
        description="Run every (filter x parameter set x flight) and write one row per run "
        "(parameters, metrics, status, error) to a Parquet file as runs finish. "
        "Runs carry their seeds, so results do not depend on the number of workers; "
        "an interrupted sweep resumes. docs/sweeps.md",
    )
    sw.add_argument("--filters", default="quadest", help="quadest (default), all, peers, or a comma-separated list")
    _add_sweep_args(sw)
    sw.set_defaults(func=cmd_sweep)

    tu = sub.add_parser(
        "tune",
        help="choose a filter's parameters that minimise a metric over a set",
        description="Sweep one filter's parameter grid over flights or recordings and report "
        "the best set for all trials together (the lowest mean: BROAD's "
        "trial-agnostic choice) and per trial. docs/sweeps.md",
    )
    tu.add_argument("filter", type=filter_name, help="the filter to tune (quadest's or a peer's name)")
    tu.add_argument(
        "--metric",
        default="total_rmse_deg",
        choices=[
            "total_rmse_deg",
            "heading_rmse_deg",
            "inclination_rmse_deg",
            "roll_rms_deg",
            "pitch_rms_deg",
            "yaw_rms_deg",
        ],
        help="metric to minimise (default: total_rmse_deg)",
    )
    tu.add_argument(
        "--split",
        action="store_true",
        help="cross-validate: choose on one half of the trials (sorted, alternately), report the mean "
        "on the other half it never saw, and the reverse",
    )
    _add_sweep_args(tu)
    tu.set_defaults(func=cmd_tune)

    ca = sub.add_parser(
        "campaign",
        help="rotor failures and nominal flights with detection in the loop: survival, delay, false alarms",
        description="Fly rotor failures (complete and partial, from a hover, on a circle and on a figure eight) "
        "and nominal flights with each estimator, detection mode, gyroscope range and magnetometer latency in "
        "the loop, on Dask, into one resumable results file; print survival, detection delay and isolation "
        "and the false alarms per group. quadest report RESULTS draws its page. docs/campaign.md",
    )
    _add_campaign_args(ca)
    ca.set_defaults(func=cmd_campaign)
