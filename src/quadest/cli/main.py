"""``quadest``: the command line. ``quadest --help`` lists the subcommands; each has ``--help``."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from quadest import __version__


class CliError(Exception):
    """An error to report as one line, without a traceback."""


def _say(msg):
    print(msg, flush=True)


# -- simulate ------------------------------------------------------------------------------
def _parse_sets(items):
    out = {}
    for item in items or []:
        key, eq, value = item.partition("=")
        if not eq or not key.strip():
            raise CliError(f"--set expects key=value (for example gyro.noise_std=0.02), got {item!r}")
        out[key.strip()] = value
    return out


def cmd_simulate(args):
    from quadest.data import save_recording
    from quadest.sim import build_config, param_table, simulate

    cfg = build_config(args.preset, _parse_sets(args.set), args.config, args.ideal)
    if args.list_params:
        rows = param_table(cfg, args.preset)
        w = max(len(r["key"]) for r in rows)
        if args.markdown:
            _say("| parameter | value | unit | meaning | source |\n|---|---|---|---|---|")
            for r in rows:
                _say(f"| `{r['key']}` | {json.dumps(r['value'], default=str)} | {r['unit']} | "
                     f"{r['doc']} | {r['source']} |")
            return 0
        for r in rows:
            _say(f"{r['key']:<{w}}  {json.dumps(r['value'], default=str):<28} {r['unit']:<12} "
                 f"{r['doc']} [{r['source']}]")
        return 0
    if not args.output:
        raise CliError("simulate needs -o FILE (.csv or .parquet), or --list-params")
    _say(f"simulating {args.scenario} with preset {args.preset}, seed {args.seed}"
         + (", ideal sensors" if args.ideal else ""))
    rec = simulate(args.scenario, args.preset, seed=args.seed, duration=args.duration, config=cfg,
                   progress=True)
    path = save_recording(rec, args.output)
    _say(f"wrote {path}: {len(rec)} samples, {rec.duration:.2f} s")
    if args.scenario == "damaged-rotor":
        _say(f"gyroscope saturated in {100 * rec.meta['gyro_saturated_share']:.1f} % of the samples")
    if args.plot:
        from quadest.plot import plot_recording

        plot_recording(rec, args.plot, title=f"{args.scenario} / {args.preset} / seed {args.seed}")
        _say(f"wrote {args.plot}")
    return 0


# -- info ----------------------------------------------------------------------------------
def cmd_info(args):
    from quadest.data import format_summary, load_recording, summarize

    rec = load_recording(args.file)
    s = summarize(rec)
    if args.json:
        _say(json.dumps(s, indent=2))
    else:
        _say(format_summary(s, str(args.file)))
    return 0


# -- demo ----------------------------------------------------------------------------------
def cmd_demo(args):
    """The main job on a fresh machine; grows with the project."""
    from quadest.data import format_summary, save_recording, summarize
    from quadest.plot import plot_recording
    from quadest.sim import simulate

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    _say("quadest demo: a Bebop 2 loses a rotor after 5 s of hover and spins at about 15.5 rad/s.")
    _say("step 1/3  simulating the flight and its MARG sensors (compiling on first use)...")
    rec = simulate("damaged-rotor", "bebop2", seed=1, progress=True)
    path = save_recording(rec, out / "damaged-rotor.csv")
    _say(f"          wrote {path} ({len(rec)} samples)")
    _say("step 2/3  what the recording holds:")
    for line in format_summary(summarize(rec), str(path)).splitlines():
        _say("          " + line)
    sat = 100 * rec.meta["gyro_saturated_share"]
    _say(f"          the ±1000 °/s gyroscope saturates in {sat:.1f} % of the samples")
    _say("step 3/3  drawing attitude, rates and sensor signals...")
    png = plot_recording(rec, out / "damaged-rotor.png", title="damaged-rotor / bebop2 / seed 1")
    _say(f"          wrote {png}")
    _say("done. Next: `quadest simulate --help`, `quadest info FILE`, docs/ for the details.")
    return 0


# -- parser --------------------------------------------------------------------------------
def build_parser():
    from quadest.sim import PRESETS, SCENARIOS

    p = argparse.ArgumentParser(
        prog="quadest",
        description="Quadcopter attitude and state estimation that keeps working when things go "
                    "wrong. Conventions: NED/FRD, q_nb = [w, x, y, z], SI units (docs/conventions.md).")
    p.add_argument("--version", action="version", version=f"quadest {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")

    s = sub.add_parser("simulate", help="simulate a flight and its sensors into a recording",
                       description="Simulate a flight scenario with a sensor preset. Deterministic "
                                   "for a given seed. Every parameter can be overridden; "
                                   "--list-params shows them with unit and source.")
    s.add_argument("--scenario", choices=SCENARIOS, default="hover", help="motion (default: hover)")
    s.add_argument("--preset", choices=list(PRESETS), default="bebop2",
                   help="vehicle and sensors (default: bebop2)")
    s.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    s.add_argument("--duration", type=float, default=None, help="seconds (default: per scenario)")
    s.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="override a parameter, e.g. --set gyro.noise_std=0.02 --set "
                        "acc.lever_arm=[0,0,0.01] (repeatable)")
    s.add_argument("--config", metavar="TOML", help="TOML file of [section] key = value overrides")
    s.add_argument("--ideal", action="store_true",
                   help="ideal sensors: no noise, bias, scale error, saturation or disturbance")
    s.add_argument("-o", "--output", metavar="FILE", help="recording to write (.csv or .parquet)")
    s.add_argument("--plot", metavar="PNG", help="also draw attitude, rates and sensor signals")
    s.add_argument("--list-params", action="store_true",
                   help="print every parameter (after preset and overrides) and exit")
    s.add_argument("--markdown", action="store_true", help="with --list-params: a Markdown table")
    s.set_defaults(func=cmd_simulate)

    i = sub.add_parser("info", help="summarise a recording",
                       description="Print duration, rates, ranges, gaps and which truth a "
                                   "recording (.csv or .parquet) holds.")
    i.add_argument("file", type=Path, help="recording (.csv or .parquet)")
    i.add_argument("--json", action="store_true", help="print JSON instead of text")
    i.set_defaults(func=cmd_info)

    d = sub.add_parser("demo", help="the main job, as `make demo` runs it",
                       description="Simulate a rotor failure on a Bebop 2, summarise and plot it.")
    d.add_argument("--out", default="demo-output", help="output folder (default: demo-output)")
    d.set_defaults(func=cmd_demo)
    return p


def main(argv=None):
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return args.func(args)
    except (CliError, ValueError, OSError) as exc:
        print(f"quadest {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
