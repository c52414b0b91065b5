"""``quadest compare``: estimators side by side on one recording."""

from __future__ import annotations

from pathlib import Path

from quadest.cli.choices import FILTERS, PEERS, PRESCRIBED_SCENARIOS, PRESETS
from quadest.cli.common import (
    CliError,
    add_align_args,
    add_calibration_arg,
    add_input_args,
    add_report_arg,
    count,
    read,
    say,
    sim_config,
    write_json,
    write_report_for,
)


def _recording_from_args(args):
    from quadest.sim import simulate

    if args.recording:
        return read(args, args.recording), str(args.recording)
    cfg = sim_config(args.preset, args.set)
    rec = simulate(args.scenario, args.preset, seed=args.seed, duration=args.duration, config=cfg, progress=True)
    return rec, f"simulated {args.scenario} / {args.preset} / seed {args.seed}"


def cmd_compare(args):
    import numpy as np

    from quadest.calibration import apply_calibrations
    from quadest.evaluation.compare import compare, format_tables, parse_params
    from quadest.evaluation.runner import estimator_names, filter_notes

    names = estimator_names(args.filters)
    params = parse_params(args.param)
    not_run = sorted(set(params) - set(names))
    if not_run:
        raise CliError(f"--param names {', '.join(not_run)}, which this comparison does not run (--filters)")
    rec, source = _recording_from_args(args)
    rec, cal_params = apply_calibrations(rec, args.calibration)
    for name, kv in cal_params.items():
        params[name] = {**kv, **params.get(name, {})}
    say(
        f"comparing {', '.join(names)} on {source} ({len(rec)} samples"
        + (f", errors from t = {args.t_from:g} s)" if args.t_from is not None else ")")
    )
    report, results = compare(
        rec,
        names,
        params=params,
        t_from=args.t_from,
        timing=not args.no_timing,
        source=source,
        align=args.align,
        align_body=args.align_body,
    )
    if report["against"] == "ref_q":
        say("no independent truth in this recording: errors are against the log's onboard attitude (ref_q)")
    used = min((e["samples"] for e in report["filters"].values()), default=0)
    if used < 0.5 * len(rec):
        truth = getattr(rec, report["against"])
        ok = np.isfinite(truth[:, 0])
        span = float(rec.t[ok][-1] - rec.t[ok][0]) if ok.any() else 0.0
        say(
            f"note: the errors rest on {used} of {len(rec)} samples: the truth covers {span:.2f} s of the "
            f"{rec.duration:.2f} s recording" + (" (and --from cuts more)" if args.t_from is not None else "")
        )
    for res in results.values():
        for line in filter_notes(res):
            say(line)
    for name, entry in report["filters"].items():
        if "alignment" in entry:
            a = entry["alignment"]
            parts = [
                f"heading {a['heading_offset_deg']:+.2f}°" if "heading_offset_deg" in a else "",
                f"navigation rotation {a['nav_rotation_deg']:.2f}°" if "nav_rotation_deg" in a else "",
                f"body rotation {a['body_rotation_deg']:.2f}°" if "body_rotation_deg" in a else "",
            ]
            say(f"alignment removed for {name}: " + ", ".join(p for p in parts if p))
    say(format_tables(report))
    if args.json:
        write_json(args.json, report)
    if args.report:
        write_report_for(rec, names, params, args.report, f"quadest compare: {source}")
    if args.plot_dir:
        from quadest.plot import plot_errors  # matplotlib: only when a plot is asked for

        for p in plot_errors(rec.t, rec.true_q, results, args.plot_dir, title=f"({source})", t_from=args.t_from):
            say(f"wrote {p}")
    return 0


def add_parsers(sub):
    _add_compare(sub)


def _add_compare(sub):
    c = sub.add_parser(
        "compare",
        help="run estimators on one recording and tabulate their errors",
        description="Run attitude estimators on a simulated flight or a recording with "
        "truth; print RMS error, variance and mean absolute error per axis "
        "(filters as columns) and the execution time, like the papers' "
        "tables. Filters: " + ", ".join(FILTERS) + "; with quadest[peers] "
        "also " + ", ".join(PEERS) + " (--filters peers).",
    )
    src = c.add_mutually_exclusive_group()
    src.add_argument("--recording", type=Path, metavar="FILE", help="recording with true_q, any supported format")
    src.add_argument(
        "--scenario",
        choices=PRESCRIBED_SCENARIOS,
        default="damaged-rotor",
        help="simulate this scenario (default: damaged-rotor)",
    )
    c.add_argument("--preset", choices=list(PRESETS), default="bebop2", help="with --scenario (default: bebop2)")
    c.add_argument("--seed", type=count, default=1, help="with --scenario (default: 1)")
    c.add_argument("--duration", type=float, default=None, help="with --scenario: seconds")
    c.add_argument("--set", action="append", metavar="KEY=VALUE", help="with --scenario: simulator parameter")
    c.add_argument(
        "--filters",
        default="all",
        help=f"all (quadest's {len(FILTERS)}: {', '.join(FILTERS)}), peers (installed peers), or a "
        "comma-separated list of filters and peers (default: all)",
    )
    c.add_argument(
        "--param",
        action="append",
        metavar="FILTER.NAME=VALUE",
        help="estimator parameter, e.g. --param afckf.omega1=-0.0145 (repeatable)",
    )
    c.add_argument(
        "--from",
        dest="t_from",
        type=float,
        default=None,
        metavar="SECONDS",
        help="count errors from this time on (e.g. 5 for the failure in damaged-rotor)",
    )
    c.add_argument("--json", metavar="OUT", help="write the figures as JSON")
    c.add_argument("--plot-dir", metavar="DIR", help="draw the error of every filter over time per axis")
    c.add_argument("--no-timing", action="store_true", help="skip the execution-time measurement")
    add_calibration_arg(c)
    add_align_args(c)
    add_input_args(c)
    add_report_arg(c)
    c.set_defaults(func=cmd_compare)
