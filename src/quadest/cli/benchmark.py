"""``quadest benchmark``: estimators and the flying vehicle on data and in the loop."""

from __future__ import annotations

from pathlib import Path

from quadest.cli.common import (
    CliError,
    add_max_runs_arg,
    check_runs,
    parse_seeds,
    say,
    write_json,
)
from quadest.cli.flight_options import detector_sets


def _us(v) -> str:
    """A streaming time, ``-`` for an estimator that does not stream (acausal)."""
    return "-" if v is None else f"{v:.2f}"


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


def add_parsers(sub):
    _add_benchmark(sub)


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
