"""``quadest info``, ``quadest calibrate`` and ``quadest estimate``: one recording in, a summary,
a calibration or an attitude out."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from quadest.calibration import apply_calibrations, calibrate
from quadest.cli.common import CliError, add_calibration_arg, add_input_args, read, say
from quadest.data import format_summary, summarize, write_table
from quadest.evaluation.compare import parse_params
from quadest.filters.peers import PEERS
from quadest.evaluation.runner import estimate, filter_notes
from quadest.filters import FILTERS
from quadest.rotation import quat_to_euler


def cmd_info(args):
    rec = read(args, args.file)
    s = summarize(rec)
    if args.json:
        say(json.dumps(s, indent=2))
    else:
        say(format_summary(s, str(args.file)))
    return 0


def cmd_calibrate(args):
    recs = [read(args, p) for p in args.recordings]
    kw = {"mass_kg": args.mass} if args.kind == "aero" else {}
    cal = calibrate(args.kind, recs, **kw)
    cal.save(args.output)
    say(f"{args.kind} calibration from {len(recs)} recording(s)")
    for key, val in cal.values.items():
        unc = cal.uncertainty.get(key)
        say(f"  {key:<22} {np.array2string(np.asarray(val), precision=5, suppress_small=True)}"
            + (f"  ± {np.array2string(np.asarray(unc), formatter={'float_kind': lambda x: f'{x:.1e}'})}"
               if unc is not None else ""))
    for key, val in cal.quality.items():
        if key in ("samples_per_position", "recordings"):
            continue
        say(f"  {key:<22} {val if not isinstance(val, float) else round(val, 5)}")
    say(f"wrote {args.output}")
    return 0


def cmd_estimate(args):
    rec = read(args, args.file)
    rec, cal_params = apply_calibrations(rec, args.calibration)
    params = parse_params(args.param)
    other = sorted(set(params) - {args.filter})
    if other:
        raise CliError(f"--param names {', '.join(other)}, but this runs {args.filter} (--filter)")
    kw = {**cal_params.get(args.filter, {}), **params.get(args.filter, {})}
    decl = np.radians(args.declination_deg) if args.declination_deg is not None else None
    res = estimate(rec, args.filter, kw, declination=decl)
    q = res.q
    for line in filter_notes(res):
        say(line)
    e = quat_to_euler(q)
    cols = {"t": rec.t, "q_w": q[:, 0], "q_x": q[:, 1], "q_y": q[:, 2], "q_z": q[:, 3],
            "roll": e[:, 0], "pitch": e[:, 1], "yaw": e[:, 2]}
    write_table(cols, Path(args.output))
    say(f"{args.filter}: {len(rec)} samples -> {args.output} (t, q_w, q_x, q_y, q_z, roll, pitch, yaw; rad)")
    return 0


def add_parsers(sub):
    i = sub.add_parser("info", help="summarise a recording",
                       description="Print duration, rates, ranges, gaps and which truth a "
                                   "recording holds; any supported format (docs/readers.md).")
    i.add_argument("file", type=Path, help="recording: any supported format (docs/readers.md)")
    i.add_argument("--json", action="store_true", help="print JSON instead of text")
    add_input_args(i)
    i.set_defaults(func=cmd_info)

    cb = sub.add_parser("calibrate", help="calibrate a sensor from recordings",
                        description="Fit a calibration and write it with its uncertainty and quality "
                                    "figures. gyro: bias from rest segments (found automatically); accel: "
                                    "bias, scale and misalignment from a six-position or many-position "
                                    "static set; mag: hard and soft iron by ellipsoid fit from a rotation "
                                    "sequence; centrifugal: the AFCKF's ω1, ω2 from a spinning segment; "
                                    "aero: the recovery paper's model (as fit-aero). docs/calibration.md "
                                    "gives the procedures.")
    cb.add_argument("kind", choices=["gyro", "accel", "mag", "centrifugal", "aero"])
    cb.add_argument("recordings", nargs="+", type=Path, metavar="RECORDING")
    cb.add_argument("-o", "--output", required=True, metavar="CALIB.json")
    cb.add_argument("--mass", type=float, default=None, help="aero: vehicle mass, kg")
    add_input_args(cb)
    cb.set_defaults(func=cmd_calibrate)

    es = sub.add_parser("estimate", help="run one estimator on a recording and write its attitude",
                        description="Run an estimator over a recording (any supported format) and write t, q_w, "
                                    "q_x, q_y, q_z, roll, pitch, yaw (radians) to .csv or .parquet.")
    es.add_argument("file", type=Path, help="recording: any supported format (docs/readers.md)")
    es.add_argument("--filter", required=True, choices=list(FILTERS) + list(PEERS),
                    help="estimator: quadest's, or a peer with quadest[peers] installed")
    es.add_argument("-o", "--output", required=True, metavar="OUT", help=".csv or .parquet")
    es.add_argument("--param", action="append", metavar="FILTER.NAME=VALUE", help="estimator parameter")
    es.add_argument("--declination-deg", type=float, default=None,
                    help="magnetic declination (default: from a simulation's metadata, else 0)")
    add_calibration_arg(es)
    add_input_args(es)
    es.set_defaults(func=cmd_estimate)
