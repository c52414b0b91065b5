"""``quadest reproduce`` and ``quadest demo``: the papers' experiments on the simulator."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from quadest.cli.common import (
    CliError,
    add_engine_args,
    add_max_runs_arg,
    check_runs,
    count,
    parse_seeds,
    positive,
    say,
    write_json,
    write_report_for,
)

if TYPE_CHECKING:  # the library is imported when a command runs
    from quadest.evaluation import flown


def cmd_reproduce(args):
    from quadest.evaluation import reproduce

    if args.clipping and not (args.paper == "afckf" and args.in_loop):
        raise CliError("--clipping is an ablation of reproduce afckf --in-loop: add --in-loop")
    if args.vehicle_range != "chosen" and (args.paper != "afckf" or args.prescribed):
        raise CliError("--vehicle-range is for reproduce afckf on the flown vehicle: leave out --prescribed")
    if args.spin_range and (args.paper != "afckf" or args.prescribed or args.ablations or args.in_loop):
        raise CliError("--spin-range is its own run of reproduce afckf: leave out --prescribed, --ablations, --in-loop")
    if args.spin_range and args.vehicle_range != "chosen":
        raise CliError("--spin-range flies every end of the range: leave out --vehicle-range")
    if args.ftc != "former" and (args.paper != "afckf" or args.prescribed):
        raise CliError("--ftc is for reproduce afckf on the flown vehicle: leave out --prescribed")
    if args.paper == "recovery":
        return _reproduce_recovery(args)
    args.seeds = args.seeds or ("1-20" if args.in_loop or args.spin_range else "1-5")
    seeds = parse_seeds(args.seeds)
    check_runs(args, len(seeds), f"--seeds {args.seeds}")
    if (args.prescribed or args.ablations or args.in_loop) and args.paper == "qukf":
        raise CliError("--prescribed, --ablations and --in-loop are for reproduce afckf")
    if args.any_direction:
        raise CliError("--any-direction is for reproduce recovery")
    if args.prescribed and (args.ablations or args.in_loop):
        raise CliError("--ablations and --in-loop run on the flown rotor loss: leave out --prescribed")
    if args.in_loop:
        return _reproduce_in_loop(args)
    if args.spin_range:
        return _reproduce_spin_range(args)
    if args.paper == "afckf":
        if args.prescribed:
            say(
                "Reproducing Solanki & de Visser 2022 (AFCKF), Tables I-V, on the prescribed scenarios: a "
                f"Bebop 2 that loses a rotor (spin, tilt and spin-up given; errors from the failure on) and in "
                f"normal flight, seeds {args.seeds}."
            )
        else:
            say(
                "Reproducing Solanki & de Visser 2022 (AFCKF), Tables I-V, on the flying vehicle: a Bebop 2 "
                "hovers (and flies a circle) and loses a rotor; a fault-tolerant controller flies it on the true "
                f"state; the estimators run on its sensors (errors from the loss on); seeds {args.seeds}"
                + (", then the ablations (each row one sensor change)." if args.ablations else ".")
            )
        say("(first use compiles the estimators and the closed loop: about a minute)")
        result = reproduce.reproduce_afckf(
            seeds,
            progress=True,
            workers=args.workers,
            scheduler=args.scheduler,
            prescribed=args.prescribed,
            ablations=args.ablations,
            params=None if args.prescribed else _flown_params(args),
        )
    else:
        say(
            "Reproducing Liang et al. 2023 (QUKF), Table 1, on the simulator: MPU6050 + HMC5883L at "
            f"20 Hz, 30 s of hover and of motion, seeds {args.seeds}."
        )
        result = reproduce.reproduce_qukf(seeds, progress=True, workers=args.workers, scheduler=args.scheduler)
    say(reproduce.format_reproduction(args.paper, result))
    if args.json:
        write_json(args.json, result)
    if args.report:
        rec, names, params, _, title = reproduce.first_seed_flight(args.paper, result)
        write_report_for(rec, names, params, args.report, f"quadest reproduce {args.paper}: {title}")
    if args.plot_dir:
        from quadest.plot import plot_errors, plot_recording

        rec, results, t_from, title = reproduce.first_seed_estimates(args.paper, result)
        out = Path(args.plot_dir) / args.paper
        for p in plot_errors(rec.t, rec.true_q, results, out, title=f"({title})", t_from=t_from):
            say(f"wrote {p}")
        say(f"wrote {plot_recording(rec, out / 'flight.png', title=title)}")
    return 0


def _flown_params(args) -> flown.FlownAfckfParams:
    """The flown rotor loss's parameters the command line sets: the vehicle's end of the spin range
    and the fault-tolerant controller."""
    from quadest.evaluation import flown

    return flown.FlownAfckfParams(vehicle_range=args.vehicle_range, ftc=args.ftc)


def _reproduce_in_loop(args):
    from quadest.evaluation import flown, reproduce

    seeds = parse_seeds(args.seeds)
    what = (
        "the clipping ablation (the rate of a clipped gyroscope axis predicted or not, for the controller and "
        "the estimator; truth, robust and afckf)"
        if args.clipping
        else "the baseline sensors and the gyroscope-range and magnetometer-latency ablations"
    )
    say(
        "The AFCKF paper's rotor loss flown with each estimator in the fault-tolerant controller's loop (a Bebop 2 "
        f"loses rotor 0 at 5 s and must stay up 20 s more), seeds {args.seeds}, with {what}."
    )
    say("(each estimator's loop compiles on its first flight: some seconds each)")
    clipping = dict(estimators=flown.CLIP_ESTIMATORS, variants=flown.CLIP_VARIANTS) if args.clipping else {}
    result = reproduce.afckf_in_loop(
        seeds,
        progress=True,
        workers=args.workers,
        scheduler=args.scheduler,
        params=_flown_params(args),
        **clipping,
    )
    say(flown.format_in_loop(result["table"]))
    if args.json:
        write_json(args.json, result)
    return 0


def _reproduce_spin_range(args):
    from quadest.evaluation import reproduce

    seeds = parse_seeds(args.seeds)
    say(
        "The AFCKF paper's rotor loss flown at the low, chosen and high ends of the Bebop 2's spin range "
        f"(rotor drag k_h and rotor inertia I_p, docs/vehicle.md), seeds {args.seeds}."
    )
    result = reproduce.afckf_spin_range(
        seeds, progress=True, workers=args.workers, scheduler=args.scheduler, params=_flown_params(args)
    )
    say(reproduce.format_spin_range(result))
    if args.json:
        write_json(args.json, result)
    return 0


def _reproduce_recovery(args):
    from quadest.evaluation import reproduce_recovery

    check_runs(args, args.throws, f"--throws {args.throws}")
    if args.in_loop:
        raise CliError("--in-loop: the flown rotor loss in the loop; its runs are for reproduce afckf")
    if args.ablations and args.prescribed:
        raise CliError("--ablations of the recovery are for the flown throws: leave out --prescribed")
    if args.any_direction and args.prescribed:
        raise CliError("--any-direction is for the flown throws: leave out --prescribed")
    if not args.prescribed:
        return _reproduce_recovery_flown(args)
    say(
        f"Reproducing Beffa, Ledergerber & D'Andrea (state estimate recovery) on {args.throws} simulated "
        f"throws (fma preset, seeds {args.seed}..{args.seed + args.throws - 1}), with the simulation's "
        "aerodynamic model, one fitted on 20 separate throws, and one perturbed by ±20 %."
    )
    result = reproduce_recovery.reproduce_recovery(
        args.throws,
        args.seed,
        progress=True,
        keep_runs=bool(args.json or args.plot_dir),
        workers=args.workers,
        scheduler=args.scheduler,
    )
    say(reproduce_recovery.format_recovery(result))
    if args.plot_dir:
        from quadest.plot import plot_recovery, plot_recovery_histograms

        out = Path(args.plot_dir) / "recovery"
        out.mkdir(parents=True, exist_ok=True)
        runs = {n: c["runs"] for n, c in result["cases"].items()}
        say(f"wrote {plot_recovery_histograms(runs, out / 'errors_histogram.png')}")
        res, rec = reproduce_recovery.example_throw(args.seed)
        say(f"wrote {plot_recovery(res, rec, out / 'throw.png', title=f'throw seed {args.seed}, true model')}")
    if args.json:
        write_json(args.json, result)
    return 0


def _reproduce_recovery_flown(args):
    from quadest.evaluation import reproduce_recovery
    from quadest.flight import fly
    from quadest.flight.throw import ThrowParams

    say(
        f"Reproducing Beffa, Ledergerber & D'Andrea (state estimate recovery) on {args.throws} flown throws (seeds "
        f"{args.seed}..{args.seed + args.throws - 1}): the rotor-level vehicle thrown "
        + ("in any direction" if args.any_direction else "upward")
        + " by a hand (up to 30 m/s²), released at up to "
        "8 m/s and 20 rad/s; the bank of EKFs (its aerodynamic model fitted on separate flown throws) finds gravity, "
        "the controller rights the vehicle and holds its height."
    )
    say("(the first throw fits the model and compiles the loop: about a minute)")
    result = reproduce_recovery.reproduce_recovery_flown(
        args.throws,
        args.seed,
        progress=True,
        workers=args.workers,
        scheduler=args.scheduler,
        any_direction=args.any_direction,
        keep_runs=bool(args.json),
        ablations=args.ablations,
    )
    say(reproduce_recovery.format_throws(result))
    if args.plot_dir:
        from quadest.plot import plot_flight

        out = Path(args.plot_dir) / "recovery"
        out.mkdir(parents=True, exist_ok=True)
        f = fly("throw", estimator="recovery", seed=args.seed, throw=ThrowParams(any_direction=args.any_direction))
        say(f"wrote {plot_flight(f, out / 'flown-throw.png', title=f'flown throw, seed {args.seed}')}")
    if args.json:
        write_json(args.json, result)
    return 0


def demo_argv(out: str, seeds: str | None) -> list[str]:
    """``quadest demo``'s job as the command it is (``make demo`` runs ``quadest demo``)."""
    argv = ["reproduce", "afckf", "--plot-dir", out, "--json", f"{out}/afckf.json", "--report", f"{out}/report.html"]
    return argv + (["--seeds", seeds] if seeds else [])


def cmd_demo(args):
    argv = demo_argv(str(args.out), args.seeds)
    say(f"quadest demo: quadest {' '.join(argv)}")
    parser = argparse.ArgumentParser(prog="quadest")
    _add_reproduce(parser.add_subparsers(dest="command"))
    Path(args.out).mkdir(parents=True, exist_ok=True)
    return cmd_reproduce(parser.parse_args(argv))


def _add_demo(sub):
    d = sub.add_parser(
        "demo",
        help="the main job: a Bebop 2 flies, loses a rotor, five estimators judged (what make demo runs)",
        description="Runs `quadest reproduce afckf` with its plots, JSON and HTML report written to -o (--output): "
        "the AFCKF paper's rotor loss flown by the simulated Bebop 2, each estimator's errors beside "
        "the paper's tables. The same job as `make demo`.",
    )
    d.add_argument(
        "-o", "--output", "--out", dest="out", default="demo-output", help="output folder (default: demo-output)"
    )
    d.add_argument("--seeds", default=None, help="seed range or list (default: reproduce afckf's, 1-5)")
    d.set_defaults(func=cmd_demo, plot_dir=None, report=None)


def add_parsers(sub):
    _add_reproduce(sub)
    _add_demo(sub)


def _add_reproduce(sub):
    r = sub.add_parser(
        "reproduce",
        help="reproduce a paper's experiments on the simulator",
        description="Run a paper's experiment on simulated flights over several seeds and "
        "print our figures next to the published ones. afckf: Tables I-V of "
        "Solanki & de Visser 2022 on the flown rotor loss (--prescribed: on the "
        "prescribed scenario; --ablations: what each sensor property does); qukf: Table 1 of Liang et al. 2023; "
        "recovery: throws and the bank of EKFs of Beffa et al.",
    )
    r.add_argument("paper", choices=["afckf", "qukf", "recovery"])
    r.add_argument("--seeds", default=None, help="afckf, qukf: seed range or list (default: 1-5; 1-20 with --in-loop)")
    r.add_argument("--throws", type=positive, default=100, help="recovery: number of throws (default: 100)")
    r.add_argument("--seed", type=count, default=1, help="recovery: first seed (default: 1)")
    add_max_runs_arg(r)
    r.add_argument(
        "--prescribed",
        action="store_true",
        help="afckf: the prescribed scenarios (spin, tilt and spin-up given) instead of the flown vehicle; "
        "recovery: the prescribed throws (the simulation's own aerodynamic model) instead of flown ones",
    )
    r.add_argument(
        "--ablations",
        action="store_true",
        help="afckf: also the ablation table on the flown rotor loss (each row one sensor change: gyro "
        "range and scale, magnetometer latency, motor interference, indoor field, lever arm, "
        "vibration, a damaged propeller; docs/estimators.md); recovery: the same flown throws again "
        "without the re-arm, without the dwell, without the barometer, with none, and with the barometer "
        "in the bank's likelihood (off by default; docs/recovery.md)",
    )
    r.add_argument(
        "--any-direction",
        action="store_true",
        help="recovery: throw in any direction, downward too (the flagged case; default: upward or level)",
    )
    r.add_argument(
        "--in-loop",
        action="store_true",
        help="afckf: instead of the tables, the flown loss with each estimator in the fault-tolerant "
        "controller's loop (default seeds 1-20): which keep the vehicle up and in place, with the "
        "baseline sensors and the gyro-range and magnetometer-latency ablations",
    )
    r.add_argument(
        "--clipping",
        action="store_true",
        help="afckf --in-loop: instead of its sensor variants, the clipping ablation with truth, robust and "
        "afckf in the loop: a ±500°/s gyro with the clipped reading, the predicted rate of a clipped axis "
        "(FlightParams.clip_rate) to the controller only, to the controller and the estimator, the same from "
        "the rotor speeds, a ±1000°/s gyro without and with it, ±300, ±400 and ±600°/s gyros with it, and a "
        "vehicle without rotor drag (a faster spin) at ±1000°/s without and with it (docs/vehicle.md)",
    )
    r.add_argument(
        "--spin-range",
        action="store_true",
        help="afckf: instead of the tables, the flown loss at the low, chosen and high ends of the vehicle's "
        "spin range (default seeds 1-20): the truth's spin, tilt and clipping share, every filter's error over "
        "its flights, and truth, robust and afckf in the loop with a ±1000 and a ±500 °/s gyro (docs/vehicle.md)",
    )
    r.add_argument(
        "--vehicle-range",
        choices=["low", "chosen", "high"],
        default="chosen",
        help="afckf, flown: fly the vehicle at an end of the range of the parameters that decide its spin "
        "(rotor drag k_h and rotor inertia I_p, from sources; docs/vehicle.md, Spin range): low or high, the "
        "corner whose relaxed hover spins slowest or fastest; chosen, the preset (default)",
    )
    r.add_argument(
        "--ftc",
        choices=["former", "default"],
        default="former",
        help="afckf, flown: the fault-tolerant controller after the loss: former (default here: the tilted "
        "relaxed hover, whose spin is the paper's) or default (the level relaxed hover that quadest fly and "
        "quadest campaign fly; docs/vehicle.md, The loss's transient)",
    )
    r.add_argument("--json", metavar="OUT", help="write all figures (per seed too) as JSON")
    r.add_argument(
        "--report",
        type=Path,
        metavar="PATH",
        default=None,
        help="afckf, qukf: also write an HTML report of the first seed's flight (quadest report)",
    )
    r.add_argument("--plot-dir", metavar="DIR", help="draw the errors over time for the first seed")
    add_engine_args(r, default_workers=0)
    r.set_defaults(func=cmd_reproduce)
