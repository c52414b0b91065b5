"""``quadest simulate`` and ``quadest demo``."""

from __future__ import annotations

import json

from quadest.cli.choices import PRESCRIBED_SCENARIOS, PRESETS
from quadest.cli.common import CliError, count, say, say_units_beside, sim_config


def cmd_simulate(args):
    from quadest.data import save_recording
    from quadest.sim import param_table, simulate

    cfg = sim_config(args.preset, args.set, args.config, args.ideal)
    if args.list_params:
        rows = param_table(cfg, args.preset)
        w = max(len(r["key"]) for r in rows)
        if args.markdown:
            say("| parameter | value | unit | meaning | source |\n|---|---|---|---|---|")
            for r in rows:
                say(
                    f"| `{r['key']}` | {json.dumps(r['value'], default=str)} | {r['unit']} | "
                    f"{r['doc']} | {r['source']} |"
                )
            return 0
        for r in rows:
            say(
                f"{r['key']:<{w}}  {json.dumps(r['value'], default=str):<28} {r['unit']:<12} {r['doc']} [{r['source']}]"
            )
        return 0
    if not args.output:
        raise CliError("simulate needs -o FILE (.csv or .parquet), or --list-params")
    say(
        f"simulating {args.scenario} with preset {args.preset}, seed {args.seed}"
        + (", ideal sensors" if args.ideal else "")
    )
    rec = simulate(args.scenario, args.preset, seed=args.seed, duration=args.duration, config=cfg, progress=True)
    path = save_recording(rec, args.output)
    say(f"wrote {path}: {len(rec)} samples, {rec.duration:.2f} s")
    say_units_beside(path)
    if args.scenario == "damaged-rotor":
        say(f"gyroscope saturated in {100 * rec.meta['gyro_saturated_share']:.1f} % of the samples")
    if args.plot:
        from quadest.plot import plot_recording  # matplotlib: only when a plot is asked for

        plot_recording(rec, args.plot, title=f"{args.scenario} / {args.preset} / seed {args.seed}")
        say(f"wrote {args.plot}")
    return 0


def add_parsers(sub):
    s = sub.add_parser(
        "simulate",
        help="simulate a flight and its sensors into a recording",
        description="Simulate a flight scenario with a sensor preset. Deterministic "
        "for a given seed. Every parameter can be overridden; "
        "--list-params shows them with unit and source.",
    )
    s.add_argument("--scenario", choices=PRESCRIBED_SCENARIOS, default="hover", help="motion (default: hover)")
    s.add_argument("--preset", choices=list(PRESETS), default="bebop2", help="vehicle and sensors (default: bebop2)")
    s.add_argument("--seed", type=count, default=0, help="random seed (default: 0)")
    s.add_argument("--duration", type=float, default=None, help="seconds (default: per scenario)")
    s.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        help="override a parameter, e.g. --set gyro.noise_std=0.02 --set acc.lever_arm=[0,0,0.01] (repeatable)",
    )
    s.add_argument("--config", metavar="TOML", help="TOML file of [section] key = value overrides")
    s.add_argument(
        "--ideal",
        action="store_true",
        help="ideal sensors: no noise, bias, scale error, saturation or disturbance "
        "(--set and --config then add chosen errors back)",
    )
    s.add_argument(
        "-o",
        "--output",
        "--out",
        metavar="FILE",
        help="recording to write (.csv or .parquet; - for CSV on standard output)",
    )
    s.add_argument("--plot", metavar="PNG", help="also draw attitude, rates and sensor signals")
    s.add_argument(
        "--list-params", action="store_true", help="print every parameter (after preset and overrides) and exit"
    )
    s.add_argument("--markdown", action="store_true", help="with --list-params: a Markdown table")
    s.set_defaults(func=cmd_simulate)
