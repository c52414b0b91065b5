"""``quadest compare``, ``quadest reproduce`` and ``quadest benchmark``: estimators side by side."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from quadest.cli.choices import FILTERS, PEERS, PRESCRIBED_SCENARIOS, PRESETS
from quadest.cli.common import (
    CliError,
    add_align_args,
    add_calibration_arg,
    add_engine_args,
    add_input_args,
    add_max_runs_arg,
    add_report_arg,
    check_runs,
    count,
    parse_seeds,
    positive,
    read,
    say,
    sim_config,
    write_json,
    write_report_for,
)
from quadest.cli.fly import detector_sets

if TYPE_CHECKING:  # the library is imported when a command runs
    from quadest.evaluation import flown


def _recording_from_args(args):
    from quadest.sim import simulate

    if args.recording:
        return read(args, args.recording), str(args.recording)
    cfg = sim_config(args.preset, args.set)
    rec = simulate(args.scenario, args.preset, seed=args.seed, duration=args.duration, config=cfg, progress=True)
    return rec, f"simulated {args.scenario} / {args.preset} / seed {args.seed}"


def _us(v) -> str:
    """A streaming time, ``-`` for an estimator that does not stream (acausal)."""
    return "-" if v is None else f"{v:.2f}"


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


def _benchmark_sim(args):
    from quadest.filters import FILTERS
    from quadest.flight.crosscheck import rotorpy_available
    from quadest.flight.speed import benchmark_sim

    est = args.filters if args.filters in ("truth", *FILTERS) else "afckf"
    rp = min(args.duration, 10.0)
    say(
        f"the flying vehicle on one core at 1 kHz: {args.duration:g} s of rotor loss with the fault-tolerant "
        f"controller and {est} in the loop (sensors at 1 kHz), best of 3 after a warm-up"
        + (
            f"; then {rp:g} s of the SE(3) circle flown by quadest and by RotorPy (RotorPy's "
            "Hummingbird, its SE(3) gains)"
            if rotorpy_available()
            else "; RotorPy is not installed: pip install rotorpy for the comparison"
        )
    )
    res = benchmark_sim(args.duration, rp, est)
    c = res["closed_loop"]
    say(
        f"closed loop ({c['estimator']}, ftc): {c['loop_us_per_step']:.2f} µs per step, "
        f"{c['loop_x_real_time']:.0f}x real time; the whole fly() call with its recording "
        f"{c['total_x_real_time']:.0f}x real time (run {c['status']})"
    )
    if "rotorpy" in res:
        r = res["rotorpy"]
        say(
            f"SE(3) circle at 1 kHz: quadest {r['ms_per_step']['quadest'] * 1e3:.2f} µs per step, RotorPy "
            f"{r['ms_per_step']['rotorpy']:.2f} ms per step: quadest {r['speedup']:.0f}x faster"
        )
        say(
            f"  hover rotor speed: quadest {r['hover_rotor_speed']['quadest']:.2f}, RotorPy "
            f"{r['hover_rotor_speed']['rotorpy']:.2f} rad/s; tracking RMS after the first lap: quadest "
            f"{100 * r['tracking_rms_m']['quadest']:.2f} cm, RotorPy {100 * r['tracking_rms_m']['rotorpy']:.2f} cm"
        )
    return res


BOTH_MODES = " (both modes are flown)"


def _benchmark_detection(args):
    from quadest.detect import DetectorParams
    from quadest.evaluation import detection
    from quadest.filters import FILTERS

    seeds, nominal = parse_seeds(args.seeds), parse_seeds(args.nominal_seeds, "--nominal-seeds")
    check_runs(args, len(seeds) + len(nominal), f"--seeds {args.seeds} and --nominal-seeds {args.nominal_seeds}")
    changes = detector_sets(args.set, ("rotor-speeds",), "benchmark detection", BOTH_MODES)
    say(
        f"the rotor-failure detector in the loop (bebop2): {len(seeds)} failures (a random rotor at a random "
        "time, complete or partial, from a hover, on a circle or on a figure eight) and "
        f"{len(nominal)} nominal flights of {args.duration:g} s, with rotor speeds and with commands; the "
        "detector's model off by each flight's drawn ±10 %"
    )
    est = args.filters if args.filters in ("truth", *FILTERS) else "truth"
    say(
        f"the estimator in the loop: {est}"
        + (" (an oracle: the controller reads the true state)" if est == "truth" else "")
        + "".join(f", detector.{k}={v}" for k, v in changes.items())
    )
    res = detection.benchmark_detection(
        seeds, nominal, nominal_s=args.duration, estimator=est, workers=args.workers, progress=True,
        detector=DetectorParams(**changes) if changes else None,
    )  # fmt: skip
    res["detector"] = changes
    say(detection.format_detection(res))
    return res


def _benchmark_collisions(args):
    from quadest.evaluation import collisions
    from quadest.filters import FILTERS

    seeds, nominal = parse_seeds(args.seeds), parse_seeds(args.nominal_seeds, "--nominal-seeds")
    ablate = 1 + len(collisions.ABLATIONS)
    check_runs(
        args, ablate * len(seeds) + len(nominal), f"--seeds {args.seeds} and --nominal-seeds {args.nominal_seeds}"
    )
    est = args.filters if args.filters in ("truth", *FILTERS) else "robust"
    say(
        f"collisions in flight recovered, {est} in the loop, fma sensors with a magnetometer, recovery vehicle: "
        f"{len(seeds)} collisions (up to 5 m/s and 20 rad/s at 2-4 s, the estimator reset or left as drawn; "
        f"hover, circle, figure eight in turn), flown with every divergence check, each alone and none; "
        f"{len(nominal)} nominal flights of {args.duration:g} s with every check on"
    )
    res = collisions.benchmark_collisions(seeds, nominal, nominal_s=args.duration, estimator=est, workers=args.workers,
                                          progress=True)  # fmt: skip
    say(collisions.format_collisions(res))
    return res


def _benchmark_tradeoff(args):
    from quadest.detect import DetectorParams
    from quadest.evaluation import detection

    train, test = parse_seeds(args.train_seeds, "--train-seeds"), parse_seeds(args.seeds)
    train_nominal = parse_seeds(args.train_nominal_seeds, "--train-nominal-seeds")
    test_nominal = parse_seeds(args.nominal_seeds, "--nominal-seeds")
    check_runs(args, len(train) + len(test) + len(train_nominal) + len(test_nominal), "the seeds")
    changes = detector_sets(args.set, ("rotor-speeds",), "benchmark detection-tradeoff", BOTH_MODES)
    swept = [k for k in changes if k == "lost_threshold" or k.startswith("glr")]
    if swept:
        raise CliError(f"--set detector.{swept[0]}: the trade-off reads the 'lost' test's statistic at every "
                       "threshold, with the fast test off; set the detector's other parameters")  # fmt: skip
    say(
        "the 'lost' test's threshold against delay and false alarms: every case flown once with the "
        "SE(3) controller and the test unable to fire (the detector then changes nothing), each "
        "threshold's first alarm read from its statistic; the threshold chosen on the training seeds "
        f"({len(train)} failures, {len(train_nominal)} nominal flights of {args.duration:g} s), reported on "
        f"the test seeds ({len(test)}, {len(test_nominal)})"
    )
    res = detection.benchmark_tradeoff(
        train, test, train_nominal, test_nominal, nominal_s=args.duration, workers=args.workers, progress=True,
        detector=DetectorParams(**changes) if changes else None,
    )  # fmt: skip
    res["detector"] = changes
    say(detection.format_tradeoff(res))
    return res


def _benchmark_diagnose(args):
    from quadest.evaluation import diagnose

    folder = Path(args.data) if args.data else None
    if folder is None or not folder.is_dir():
        raise CliError("benchmark diagnose: --data must name a folder of ArduPilot (.bin) or PX4 (.ulg) logs")
    paths = sorted(p for p in folder.iterdir() if p.suffix.lower() in (".bin", ".ulg"))
    if not paths:
        raise CliError(f"{folder}: no .bin or .ulg logs in it")
    say(
        f"quadest diagnose on {len(paths)} logs in {folder}, with each variant of its model; a failure "
        "scored against the one the log itself records (ArduPilot: the SERVOn_FUNCTION change; truth, "
        "never read by the diagnosis)"
    )

    def progress(path, r):
        d = r["variants"]["default"]
        found = ", ".join(f"motor {f['motor']} at {f['time_s']:.3f} s" for f in d["failures"]) or "no failure"
        flagged = ", ".join(f"motor {x['motor']} +{100 * x['excess']:.0f} %" for x in d["damaged"]) or "none flagged"
        say(f"  {path.name}: {found}; {flagged}")

    return diagnose.benchmark_diagnose(paths, on_log=progress)


def cmd_benchmark(args):
    from quadest.evaluation import benchmark
    from quadest.evaluation.runner import estimator_names
    from quadest.evaluation.speed import benchmark_speed, format_paired
    from quadest.filters.base import STREAM_C
    from quadest.readers.catalog import resolve_data

    if args.set and args.what not in ("detection", "detection-tradeoff"):
        raise CliError(f"--set: benchmark {args.what} takes none (it is for detection and detection-tradeoff)")
    if args.what == "diagnose":
        res = _benchmark_diagnose(args)
        if args.json:
            write_json(args.json, res)
        return 0
    if args.what in ("detection", "detection-tradeoff", "collisions"):
        bench = {"detection": _benchmark_detection, "detection-tradeoff": _benchmark_tradeoff}
        res = bench.get(args.what, _benchmark_collisions)(args)
        if args.json:
            write_json(args.json, res)
        return 0
    if args.what == "sim":
        res = _benchmark_sim(args)
        if args.json:
            write_json(args.json, res)
        return 0
    names = estimator_names(args.filters, all_includes_peers=True)
    if args.what == "speed":
        say(
            f"µs per sample on {args.duration:g} s of a simulated damaged-rotor flight (bebop2), one core; "
            "batch: best of 3 after a warm-up; streaming: update() called from Python ("
            + (
                "in C: the extension _stream"
                if STREAM_C
                else "through Python: the C extension _stream is not built here, reinstall with a C compiler"
            )
            + "). Peers: their whole-recording call (the same Python loop per sample for imufusion and ahrs)"
        )
        say(f"{'filter':<15}{'batch':>10}{'streaming':>12}")
        res = benchmark_speed(
            names, args.duration, on_result=lambda n, r: say(f"{n:<15}{r['batch_us']:>10.3f}{_us(r['stream_us']):>12}")
        )
        for line in format_paired(res["paired"], res["pair_samples"]):
            say(line)
        say(f"{'recovery bank of 40 EKFs':<27}{res['recovery_bank_40_us']:>8.2f} µs per IMU sample (whole bank, batch)")
        v = res["detector_vs_vqf"]
        against = (
            f"; against VQF's batch, interleaved over {v['pairs']} pairs: "
            f"{v['median']:.3g} [{v['p10']:.3g}-{v['p90']:.3g}]"
            if v
            else ""
        )
        say(
            f"{'rotor-failure detector':<27}{res['detector_us']:>8.2f} µs per IMU sample (batch, rotor speeds{against})"
        )
    else:
        if not args.data:
            raise CliError(
                f"benchmark {args.what} needs --data DIR or a dataset name ("
                + ({"broad": "broad", "repoimu": "repoimu"}.get(args.what, "all"))
                + "; quadest data list)"
            )
        args.data = resolve_data(args.data)
        if args.what == "broad":
            say(f"BROAD on {args.data}: {', '.join(names)}; BROAD's metric over the movement phases")
            res = benchmark.benchmark_broad(
                args.data, names, trials=args.trials, nav=args.align or "none", progress=True
            )
            say(benchmark.format_broad(res))
        elif args.what == "repoimu":
            say(
                f"RepoIMU trials under {args.data}: {', '.join(names)}; 9-axis, roll/pitch/yaw and total RMS after "
                "the reader's alignment"
            )
            res = benchmark.benchmark_repoimu(args.data, names, progress=True)
            say(benchmark.format_repoimu(res))
        else:
            say(f"quadrotor flights under {args.data}: {', '.join(names)}; 6-axis, roll/pitch/yaw RMS")
            res = benchmark.benchmark_flights(args.data, names, nav=args.align or "heading", progress=True)
            say(benchmark.format_flights(res))
    if args.json:
        write_json(args.json, res)
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
    _add_compare(sub)
    _add_reproduce(sub)
    _add_benchmark(sub)
    _add_demo(sub)


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


def _add_benchmark(sub):
    b = sub.add_parser(
        "benchmark",
        help="benchmarks: BROAD, quadrotor flights, speed, the flying vehicle",
        description="broad: every filter on every BROAD trial in --data with the benchmark's "
        "metric (total, heading, inclination RMSE over the movement phases), per "
        "trial and per group of trials.json. flights: roll/pitch/yaw RMS on the "
        "DIDO and Blackbird flights under --data (6-axis; heading offset removed). "
        "repoimu: roll/pitch/yaw and total RMS on the RepoIMU T-stick and pendulum "
        "trials under --data (9-axis; the IMU-to-Vicon body rotation and heading removed). "
        "With broad, flights and repoimu, an estimator that reports its covariance (robust, "
        "robust-offline) also gets the mean NEES of it (3 dof, ideal 3; its tilt's part, ideal 2). "
        "speed: microseconds per sample of every filter, batch and streaming (an acausal one, "
        "robust-offline, batch only), and each quadest filter's time against VQF's, offline VQF's and "
        "imufusion's (robust-offline's also against robust's), timed in interleaved pairs (the median "
        "ratio and its spread). "
        "sim: the flying vehicle's closed loop (rotor loss, fault-tolerant "
        "controller, --filters names the estimator in the loop, default afckf) "
        "and the SE(3) circle flown by quadest and RotorPy (when installed). "
        "detection: the rotor-failure detector in the loop: failures flown for --seeds, nominal "
        "flights of --duration s for --nominal-seeds, --filters naming the estimator in the loop "
        "(default truth) (docs/detection.md). detection-tradeoff: the "
        "'lost' test's threshold against delay and false alarms, chosen on --train-seeds and "
        "--train-nominal-seeds, reported on --seeds and --nominal-seeds. diagnose: quadest diagnose "
        "on every log in --data with its model's chosen values across their range (docs/diagnose.md). "
        "collisions: collisions in flight (up to 5 m/s and 20 rad/s, the estimator reset or left) "
        "for --seeds, recovered by the divergence checks and the bank of EKFs, again with each check "
        "alone and with none, and nominal flights of --duration s for --nominal-seeds with the checks on "
        "(--filters names the estimator in the loop, default robust; docs/recovery.md). "
        "quadest's filters and the installed peers (pip install 'quadest[peers]': "
        "vqf, imufusion, ahrs) run side by side.",
    )
    b.add_argument(
        "what",
        choices=[
            "broad",
            "flights",
            "repoimu",
            "speed",
            "sim",
            "detection",
            "detection-tradeoff",
            "diagnose",
            "collisions",
        ],  # fmt: skip
        help="what to benchmark",
    )
    b.add_argument(
        "--data",
        metavar="DIR|NAME",
        help="broad, flights, repoimu: folder with the data, or a dataset "
        "in the cache (broad, repoimu; all: every dataset there); diagnose: a folder of logs",
    )
    b.add_argument(
        "--filters", default="all", help="all (quadest and installed peers), quadest, peers, or a comma-separated list"
    )
    b.add_argument("--trials", default="*", metavar="GLOB", help="broad: trial files to run (default: all)")
    b.add_argument(
        "--align",
        choices=["none", "heading", "full"],
        default=None,
        help="constant navigation-frame rotation removed before the errors (default: none "
        "for broad, heading for flights)",
    )
    b.add_argument(
        "--duration",
        type=float,
        default=60.0,
        help="speed: seconds of simulated data; sim: seconds flown (RotorPy: at most 10); detection, collisions: "
        "each nominal flight's seconds (default: 60)",
    )
    b.add_argument(
        "--seeds", default="0-99", help="detection: the failures' seeds; collisions: the collisions' (default: 0-99)"
    )
    b.add_argument(
        "--nominal-seeds",
        default="1000-1019",
        help="detection, collisions: the nominal flights' seeds (default: 1000-1019)",
    )
    b.add_argument("--train-seeds", default="0-99", help="detection-tradeoff: the training failures' seeds")
    b.add_argument(
        "--train-nominal-seeds", default="0-19", help="detection-tradeoff: the training nominal flights' seeds"
    )
    b.add_argument(
        "--workers", type=int, default=0, help="detection, collisions: Dask workers (0: this process; default: 0)"
    )
    b.add_argument(
        "--set",
        action="append",
        metavar="detector.KEY=VALUE",
        help="detection, detection-tradeoff: change a parameter of the detector, e.g. --set "
        "detector.relative_deficit=false (repeatable; checked against its bounds; docs/detection.md); the "
        "trade-off sweeps lost_threshold with the fast test off, so it takes neither",
    )
    add_max_runs_arg(b)
    b.add_argument("--json", metavar="OUT", help="write the figures as JSON")
    b.set_defaults(func=cmd_benchmark)
