"""``quadest``: the command line. ``quadest --help`` lists the subcommands; each has ``--help``."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from quadest import __version__


class CliError(Exception):
    """An error to report as one line, without a traceback."""


def _write_json(path, obj):
    """Write ``obj`` as indented JSON and say so."""
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    Path(path).write_text(json.dumps(obj, indent=2))
    _say(f"wrote {path}")


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


# -- reading any supported file ---------------------------------------------------------------
def _add_input_args(p):
    """The options every recording-taking command shares (docs/readers.md)."""
    from quadest.readers import FORMATS

    g = p.add_argument_group("input format (chosen from the file unless --format is given)")
    g.add_argument("--format", choices=FORMATS, default=None,
                   help="reader: " + ", ".join(FORMATS))
    g.add_argument("--map", action="append", metavar="FIELD=COL[,COL..]",
                   help="--format csv: which columns are t, gyr, acc, mag, true_q, true_pos, true_vel "
                        "(e.g. --map gyr=gx,gy,gz; repeatable)")
    g.add_argument("--units", action="append", metavar="FIELD=UNIT",
                   help="--format csv: t=s|ms|us|ns, gyr=rad/s|deg/s, acc=m/s^2|g|mg, mag=uT|nT|T|gauss|mgauss")
    g.add_argument("--frame", choices=["ned-frd", "enu-flu"], default="ned-frd",
                   help="--format csv: the file's navigation/body frames (default: ned-frd)")
    g.add_argument("--quat-order", choices=["wxyz", "xyzw"], default="wxyz", help="--format csv: true_q order")
    g.add_argument("--topic", action="append", metavar="KIND=TOPIC",
                   help="ROS bags: imu=/imu/data, mag=/imu/mag, truth=/vicon/pose when several are present")


def _read(args, path):
    from quadest.readers import read_recording
    from quadest.readers.generic import parse_columns, parse_units

    opts = {}
    fmt = getattr(args, "format", None)
    if fmt == "csv" or getattr(args, "map", None):
        fmt = fmt or "csv"
        opts = {"columns": parse_columns(args.map), "units": parse_units(args.units), "frame": args.frame,
                "quat_order": args.quat_order}
    for item in getattr(args, "topic", None) or []:
        kind, sep, topic = item.partition("=")
        if not sep or kind not in ("imu", "mag", "truth"):
            raise CliError(f"--topic {item!r}: expected imu=TOPIC, mag=TOPIC or truth=TOPIC")
        opts[f"{kind}_topic"] = topic
    return read_recording(path, fmt, **opts)


# -- info ----------------------------------------------------------------------------------
def cmd_info(args):
    from quadest.data import format_summary, summarize

    rec = _read(args, args.file)
    s = summarize(rec)
    if args.json:
        _say(json.dumps(s, indent=2))
    else:
        _say(format_summary(s, str(args.file)))
    return 0


# -- compare -------------------------------------------------------------------------------
def _recording_from_args(args):
    from quadest.sim import build_config, simulate

    if args.recording:
        return _read(args, args.recording), str(args.recording)
    cfg = build_config(args.preset, _parse_sets(args.set))
    rec = simulate(args.scenario, args.preset, seed=args.seed, duration=args.duration, config=cfg,
                   progress=True)
    return rec, f"simulated {args.scenario} / {args.preset} / seed {args.seed}"


def cmd_compare(args):
    from quadest.evaluation.compare import compare, format_tables, parse_filters, parse_params

    from quadest.calibration import apply_calibrations

    names = parse_filters(args.filters)
    params = parse_params(args.param)
    rec, source = _recording_from_args(args)
    rec, cal_params = apply_calibrations(rec, args.calibration)
    for name, kv in cal_params.items():
        params[name] = {**kv, **params.get(name, {})}
    _say(f"comparing {', '.join(names)} on {source} ({len(rec)} samples"
         + (f", errors from t = {args.t_from:g} s)" if args.t_from is not None else ")"))
    report, results = compare(rec, names, params=params, t_from=args.t_from, timing=not args.no_timing,
                              source=source, align=args.align, align_body=args.align_body)
    if report["against"] == "ref_q":
        _say("no independent truth in this recording: errors are against the log's onboard attitude (ref_q)")
    for name, entry in report["filters"].items():
        if "alignment" in entry:
            a = entry["alignment"]
            parts = [f"heading {a['heading_offset_deg']:+.2f}°" if "heading_offset_deg" in a else "",
                     f"navigation rotation {a['nav_rotation_deg']:.2f}°" if "nav_rotation_deg" in a else "",
                     f"body rotation {a['body_rotation_deg']:.2f}°" if "body_rotation_deg" in a else ""]
            _say(f"alignment removed for {name}: " + ", ".join(p for p in parts if p))
    _say(format_tables(report))
    if args.json:
        _write_json(args.json, report)
    if args.plot_dir:
        from quadest.plot import plot_errors

        for p in plot_errors(rec.t, rec.true_q, results, args.plot_dir, title=f"({source})", t_from=args.t_from):
            _say(f"wrote {p}")
    return 0


# -- reproduce -----------------------------------------------------------------------------
def _parse_seeds(text):
    a, dash, b = text.partition("-")
    try:
        seeds = list(range(int(a), int(b) + 1)) if dash else [int(v) for v in text.split(",")]
    except ValueError:
        raise CliError(f"--seeds expects a range like 1-5 or a list like 1,2,3, got {text!r}") from None
    if not seeds:
        raise CliError("--seeds selects no seed")
    return seeds


def cmd_reproduce(args):
    from quadest.evaluation import reproduce as R

    if args.paper == "recovery":
        return _reproduce_recovery(args, R)
    seeds = _parse_seeds(args.seeds)
    if args.paper == "afckf":
        _say("Reproducing Solanki & de Visser 2022 (AFCKF), Tables I-V, on the simulator: a Bebop 2 "
             f"that loses a rotor (errors from the failure on) and in normal flight, seeds {args.seeds}.")
        _say("(first use compiles the estimators: about a minute)")
        result = R.reproduce_afckf(seeds, progress=True, workers=args.workers, scheduler=args.scheduler)
    else:
        _say("Reproducing Liang et al. 2023 (QUKF), Table 1, on the simulator: MPU6050 + HMC5883L at "
             f"20 Hz, 30 s of hover and of motion, seeds {args.seeds}.")
        result = R.reproduce_qukf(seeds, progress=True, workers=args.workers, scheduler=args.scheduler)
    _say(R.format_reproduction(args.paper, result))
    if args.json:
        _write_json(args.json, result)
    if args.plot_dir:
        from quadest.evaluation.compare import run_filters
        from quadest.plot import plot_errors, plot_recording
        from quadest.sim import simulate

        if args.paper == "afckf":
            scen, preset, names, t_from = "damaged-rotor", "bebop2", ["madgwick", "complementary", "kalman", "afckf"], 5.0
            params = {"afckf": {k: result["calibration"][k] for k in ("omega1", "omega2")}}
        else:
            scen, preset, names, t_from, params = "nominal", "lowcost-20hz", ["qukf", "ekf", "complementary"], None, {}
        rec = simulate(scen, preset, seed=seeds[0], duration=None if args.paper == "afckf" else 30.0)
        out = Path(args.plot_dir)
        for p in plot_errors(rec.t, rec.true_q, run_filters(rec, names, params), out / args.paper,
                             title=f"({scen}, seed {seeds[0]})", t_from=t_from):
            _say(f"wrote {p}")
        _say(f"wrote {plot_recording(rec, out / args.paper / 'flight.png', title=f'{scen} / {preset} / seed {seeds[0]}')}")
    return 0


# -- recovery ------------------------------------------------------------------------------
def cmd_fit_aero(args):
    from quadest.recovery import fit_aero

    recs = [_read(args, p) for p in args.recordings]
    mass = args.mass
    if mass is None:
        masses = {r.meta.get("config", {}).get("vehicle", {}).get("mass_kg") for r in recs}
        if len(masses) != 1 or None in masses:
            raise CliError("give the vehicle mass with --mass KG (the recordings do not state one)")
        mass = masses.pop()
    model = fit_aero(recs, mass)
    model.save(args.output)
    res = model.info["residual_rms_mps2"]
    _say(f"fitted eq 14 on {model.info['samples']} samples of {len(recs)} recording(s), mass {mass} kg")
    _say(f"residual RMS x/y/z: {res[0]:.3f} / {res[1]:.3f} / {res[2]:.3f} m/s²")
    _say(f"constant term (idle thrust) C[:, 9] = {np.array2string(model.C[:, 9], precision=3)} N")
    _say(f"wrote {args.output}")
    return 0


def _aero_for(rec, path):
    from quadest.recovery import AeroModel
    from quadest.sim.params import SimConfig

    if path:
        return AeroModel.load(path)
    cfg = rec.meta.get("config")
    if not cfg:
        raise CliError("this recording does not carry a simulation's aerodynamic model: give --aero aero.json "
                       "(quadest fit-aero)")
    base = SimConfig()
    return AeroModel.from_config(base.with_overrides({"aero": cfg["aero"], "vehicle.mass_kg": cfg["vehicle"]["mass_kg"]}))


def cmd_recover(args):
    from quadest.recovery import RecoveryParams, recover

    from quadest.calibration import apply_calibrations, load_calibration
    from quadest.recovery import AeroModel

    rec = _read(args, args.file)
    model = None
    sensor_cals = []
    for path in args.calibration or []:
        cal = load_calibration(path)
        if cal.kind == "aero":
            v = cal.values
            model = AeroModel(v["A"], v["B"], v["C"], v["mass_kg"])
        else:
            sensor_cals.append(path)
    rec, _ = apply_calibrations(rec, sensor_cals)
    if model is None:
        model = _aero_for(rec, args.aero)
    params = RecoveryParams(n_hypotheses=args.hypotheses, beta1=args.beta1, beta2=args.beta2)
    res = recover(rec, model, params, record_all=bool(args.plot))
    s = res.summary
    for ev in s["events"]:
        _say(f"{ev['t_s']:8.3f} s  {ev['state']}")
    if not s["detected"]:
        _say(f"no throw detected (‖acc‖ never below {params.beta1} m/s² for {params.detect_samples} samples)")
    elif not s["converged"]:
        _say(f"the bank did not converge (S_g never below {params.beta2})")
    else:
        g = s["gravity_dir_body"]
        v = s["velocity_body_mps"]
        _say(f"converged {s['t_converge_from_detection_s'] * 1e3:.0f} ms after detection"
             + (f", {s['t_converge_s'] * 1e3:.0f} ms after release" if "t_converge_s" in s else ""))
        _say(f"gravity direction (body) [{g[0]:+.3f}, {g[1]:+.3f}, {g[2]:+.3f}], velocity (body) "
             f"[{v[0]:+.2f}, {v[1]:+.2f}, {v[2]:+.2f}] m/s")
        if "gravity_err_deg" in s:
            _say(f"errors against truth: gravity direction {s['gravity_err_deg']:.2f}°"
                 + (f", velocity {s['vel_err_mps']:.3f} m/s" if "vel_err_mps" in s else ""))
    if args.json:
        _write_json(args.json, s)
    if args.plot:
        from quadest.plot import plot_recovery

        _say(f"wrote {plot_recovery(res, rec, args.plot, title=f'recovery: {args.file}')}")
    return 0


def _reproduce_recovery(args, R):
    _say(f"Reproducing Beffa, Ledergerber & D'Andrea (state estimate recovery) on {args.throws} simulated "
         f"throws (fma preset, seeds {args.seed}..{args.seed + args.throws - 1}), with the simulation's "
         "aerodynamic model, one fitted on 20 separate throws, and one perturbed by ±20 %.")
    result = R.reproduce_recovery(args.throws, args.seed, progress=True, keep_runs=bool(args.json or args.plot_dir),
                                  workers=args.workers, scheduler=args.scheduler)
    _say(R.format_recovery(result))
    if args.plot_dir:
        from quadest.plot import plot_recovery, plot_recovery_histograms
        from quadest.recovery import recover
        from quadest.sim import simulate

        out = Path(args.plot_dir) / "recovery"
        out.mkdir(parents=True, exist_ok=True)
        runs = {n: c["runs"] for n, c in result["cases"].items()}
        _say(f"wrote {plot_recovery_histograms(runs, out / 'errors_histogram.png')}")
        rec = simulate("throw", "fma", seed=args.seed)
        models = R.recovery_models()
        res = recover(rec, models["true"], record_all=True)
        _say(f"wrote {plot_recovery(res, rec, out / 'throw.png', title=f'throw seed {args.seed}, true model')}")
    if args.json:
        _write_json(args.json, result)
    return 0


# -- calibration and estimation ----------------------------------------------------------------------
def cmd_calibrate(args):
    from quadest.calibration import calibrate

    recs = [_read(args, p) for p in args.recordings]
    kw = {"mass_kg": args.mass} if args.kind == "aero" else {}
    cal = calibrate(args.kind, recs, **kw)
    cal.save(args.output)
    _say(f"{args.kind} calibration from {len(recs)} recording(s)")
    for key, val in cal.values.items():
        unc = cal.uncertainty.get(key)
        _say(f"  {key:<22} {np.array2string(np.asarray(val), precision=5, suppress_small=True)}"
             + (f"  ± {np.array2string(np.asarray(unc), formatter={'float_kind': lambda x: f'{x:.1e}'})}"
                if unc is not None else ""))
    for key, val in cal.quality.items():
        if key in ("samples_per_position", "recordings"):
            continue
        _say(f"  {key:<22} {val if not isinstance(val, float) else round(val, 5)}")
    _say(f"wrote {args.output}")
    return 0


def cmd_estimate(args):
    from quadest.calibration import apply_calibrations
    from quadest.evaluation.compare import declination_of, parse_params
    from quadest.filters import FILTERS, make_filter
    from quadest.rotation import quat_to_euler

    rec = _read(args, args.file)
    rec, cal_params = apply_calibrations(rec, args.calibration)
    params = parse_params(args.param)
    kw = {**cal_params.get(args.filter, {}), **params.get(args.filter, {})}
    decl = np.radians(args.declination_deg) if args.declination_deg is not None else declination_of(rec)
    if args.filter in FILTERS:
        q = make_filter(args.filter, declination=decl, **kw).run(rec).q
    else:  # a peer, at its own defaults
        from quadest.evaluation.peers import run_peer

        if kw:
            raise CliError(f"peer {args.filter} runs with its own defaults; it takes no --param")
        q = run_peer(args.filter, rec, use_mag=rec.has_mag, declination=decl)
    e = quat_to_euler(q)
    cols = {"t": rec.t, "q_w": q[:, 0], "q_x": q[:, 1], "q_y": q[:, 2], "q_z": q[:, 3],
            "roll": e[:, 0], "pitch": e[:, 1], "yaw": e[:, 2]}
    _write_table(cols, Path(args.output))
    _say(f"{args.filter}: {len(rec)} samples -> {args.output} (t, q_w, q_x, q_y, q_z, roll, pitch, yaw; rad)")
    return 0


def _write_table(cols: dict, path: Path):
    import pyarrow as pa

    table = pa.table(cols)
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix.lower() == ".csv":
        import pyarrow.csv as pcsv
        with open(path, "wb") as fh:  # pyarrow quotes header names; write a plain header ourselves
            fh.write((",".join(cols) + "\n").encode())
            pcsv.write_csv(table, fh, pcsv.WriteOptions(include_header=False, quoting_style="none"))
    elif path.suffix.lower() in (".parquet", ".pq"):
        import pyarrow.parquet as pq
        pq.write_table(table, path)
    else:
        raise CliError(f"{path}: use .csv or .parquet")


# -- benchmark -----------------------------------------------------------------------------
def cmd_benchmark(args):
    if args.what == "speed":
        return _benchmark_speed(args)
    from quadest.evaluation import benchmark as B

    if not args.data:
        raise CliError(f"benchmark {args.what} needs --data DIR")
    names = _filter_names(args.filters)
    if args.what == "broad":
        _say(f"BROAD on {args.data}: {', '.join(names)}; BROAD's metric over the movement phases")
        res = B.benchmark_broad(args.data, names, trials=args.trials, nav=args.align or "none", progress=True)
        _say(B.format_broad(res))
    else:
        _say(f"quadrotor flights under {args.data}: {', '.join(names)}; 6-axis, roll/pitch/yaw RMS")
        res = B.benchmark_flights(args.data, names, nav=args.align or "heading", progress=True)
        _say(B.format_flights(res))
    if args.json:
        _write_json(args.json, res)
    return 0


def _filter_names(spec):
    """``all`` (quadest's filters and the installed peers), ``quadest``, ``peers`` or a list."""
    from quadest.evaluation.compare import parse_filters

    return parse_filters(spec, all_includes_peers=True)


def _benchmark_speed(args):
    import time

    from quadest.evaluation.metrics import time_estimator
    from quadest.evaluation.peers import run_peer
    from quadest.filters import FILTERS, make_filter
    from quadest.sim import simulate

    names = _filter_names(args.filters)
    rec = simulate("damaged-rotor", "bebop2", seed=1, duration=args.duration)
    _say(f"µs per sample on {len(rec)} samples of a simulated damaged-rotor flight (bebop2), one core; "
         "batch: best of 3 after a warm-up; streaming: update() called from Python. Peers: their "
         "whole-recording call (the same Python loop per sample for imufusion and ahrs)")
    out = {}
    _say(f"{'filter':<15}{'batch':>10}{'streaming':>12}")
    for name in names:
        if name in FILTERS:
            tm = time_estimator(lambda n=name: make_filter(n, declination=0.035), rec)
            out[name] = {"batch_us": tm["batch_us"], "stream_us": tm["stream_us"]}
        else:
            part = rec.select(slice(0, min(len(rec), 10000)))
            run_peer(name, part.select(slice(0, 200)))  # warm-up
            best = np.inf
            for _ in range(2):
                t0 = time.perf_counter()
                run_peer(name, part)
                best = min(best, time.perf_counter() - t0)
            us = best / len(part) * 1e6
            out[name] = {"batch_us": us, "stream_us": _peer_stream_us(name, part) or us}
        _say(f"{name:<15}{out[name]['batch_us']:>10.3f}{out[name]['stream_us']:>12.2f}")
    from quadest.recovery.logic import time_bank

    bank = time_bank(40)
    _say(f"{'recovery bank of 40 EKFs':<27}{bank:>8.2f} µs per IMU sample (whole bank, batch)")
    if args.json:
        _write_json(args.json, {"samples": len(rec), "filters": out, "recovery_bank_40_us": bank})
    return 0


def _peer_stream_us(name, rec):
    """VQF's per-sample update() from Python; None for the peers whose batch is that loop."""
    import time

    if name != "vqf":
        return None
    from vqf import VQF

    from quadest.rotation.frames import vec_frd_to_flu

    g, a = vec_frd_to_flu(rec.gyr), vec_frd_to_flu(rec.acc)
    f = VQF(float(np.median(np.diff(rec.t))))
    n = min(len(rec), 3000)
    t0 = time.perf_counter()
    for k in range(n):
        f.update(g[k], a[k])
    return (time.perf_counter() - t0) / n * 1e6


# -- sweeps and tuning -------------------------------------------------------------------------
def _add_engine_args(p, default_workers=None):
    g = p.add_argument_group("execution (Dask)")
    g.add_argument("--workers", type=int, default=default_workers, metavar="N",
                   help="worker processes of a local Dask cluster; 0 runs in this process "
                        + ("(default: 0)" if default_workers == 0 else "(default: one per core)"))
    g.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="run on an existing Dask cluster instead")


def _add_sweep_args(p):
    from quadest.sim import PRESETS, SCENARIOS

    p.add_argument("--grid", action="append", metavar="FILTER.PARAM=VALUES",
                   help="parameter values: a list 0.01,0.1, lin:A:B:N or log:A:B:N (repeatable; several "
                        "parameters of one filter make their Cartesian product)")
    src = p.add_argument_group("data: simulated flights (default) or recordings")
    src.add_argument("--data", nargs="+", type=Path, metavar="PATH",
                     help="recordings or folders of them (e.g. ../shared/data/broad), any supported format")
    src.add_argument("--format", default=None, help="with --data: reader (default: chosen from each file)")
    src.add_argument("--scenario", choices=SCENARIOS, default="nominal", help="simulated scenario (default: nominal)")
    src.add_argument("--preset", choices=list(PRESETS), default="bebop2", help="simulator preset (default: bebop2)")
    src.add_argument("--seeds", default="1-10", help="seed range or list (default: 1-10)")
    src.add_argument("--duration", type=float, default=None, help="seconds per simulated flight")
    src.add_argument("--set", action="append", metavar="KEY=VALUE", help="simulator parameter")
    src.add_argument("--from", dest="t_from", type=float, default=None, metavar="SECONDS",
                     help="count errors from this time on")
    p.add_argument("--align", choices=["none", "heading", "full"], default=None,
                   help="constant navigation-frame rotation removed (default: the reader's recommendation)")
    p.add_argument("-o", "--out", required=True, type=Path, metavar="RESULTS.parquet",
                   help="results file, one row per run (parts go to RESULTS.parquet.parts/ while it runs); "
                        "an existing one is resumed")
    p.add_argument("--retry-failed", action="store_true", help="run again the runs recorded as failed")
    p.add_argument("--json", metavar="OUT", help="write the summary as JSON")
    _add_engine_args(p)


def _sweep_runs(args, filters):
    from quadest.sweep import build_runs, file_sources, parse_grid, sim_sources

    grid = parse_grid(args.grid)
    if args.data:
        sources = file_sources(args.data, args.format)
    else:
        sources = sim_sources(args.scenario, args.preset, _parse_seeds(args.seeds), args.duration,
                              _parse_sets(args.set), args.t_from)
    return build_runs(filters, grid, sources, args.align)


def _run_sweep(args, runs):
    from quadest.sweep import run_sweep

    where = (f"on the Dask cluster at {args.scheduler}" if args.scheduler else
             "in this process" if args.workers == 0 else
             f"on a local Dask cluster of {args.workers} worker(s)" if args.workers else
             "on a local Dask cluster (one worker per core)")
    _say(f"{len(runs)} runs {where}; results in {args.out}")
    res = run_sweep(runs, args.out, workers=args.workers, scheduler=args.scheduler,
                    retry_failed=args.retry_failed, progress=True)
    _say(f"executed {res['executed']} (skipped {res['skipped']} already in {args.out}) in {res['wall_s']:.1f} s"
         + (f"; {res['runs_per_s']:.2f} runs/s over {res['compute_s']:.1f} s of computing (cluster start-up "
            "excluded)" if res["executed"] else "")
         + f"; results hold {res['ok']} ok, {res['failed']} failed")
    if res["failed"]:
        _say("failed runs keep their error in the 'error' column; --retry-failed runs them again")
    return res


def cmd_sweep(args):
    runs = _sweep_runs(args, args.filters)
    res = _run_sweep(args, runs)
    if args.json:
        _write_json(args.json, res)
    return 0


def cmd_tune(args):
    import pyarrow as pa
    import pyarrow.compute as pc

    from quadest.sweep import ResultStore, format_selection, run_id, select

    runs = _sweep_runs(args, args.filter)
    res = _run_sweep(args, runs)
    table = ResultStore(args.out).read()  # only this grid's runs, though the file may hold more
    table = table.filter(pc.is_in(table.column("run_id"), value_set=pa.array(sorted({run_id(r) for r in runs}))))
    sel = select(table, args.filter, args.metric)
    _say(format_selection(sel))
    if args.json:
        _write_json(args.json, {**sel, "sweep": res})
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
                   help="ideal sensors: no noise, bias, scale error, saturation or disturbance "
                        "(--set and --config then add chosen errors back)")
    s.add_argument("-o", "--output", metavar="FILE", help="recording to write (.csv or .parquet)")
    s.add_argument("--plot", metavar="PNG", help="also draw attitude, rates and sensor signals")
    s.add_argument("--list-params", action="store_true",
                   help="print every parameter (after preset and overrides) and exit")
    s.add_argument("--markdown", action="store_true", help="with --list-params: a Markdown table")
    s.set_defaults(func=cmd_simulate)

    i = sub.add_parser("info", help="summarise a recording",
                       description="Print duration, rates, ranges, gaps and which truth a "
                                   "recording holds; any supported format (docs/readers.md).")
    i.add_argument("file", type=Path, help="recording: any supported format (docs/readers.md)")
    i.add_argument("--json", action="store_true", help="print JSON instead of text")
    _add_input_args(i)
    i.set_defaults(func=cmd_info)

    from quadest.filters import FILTERS

    c = sub.add_parser("compare", help="run estimators on one recording and tabulate their errors",
                       description="Run attitude estimators on a simulated flight or a recording with "
                                   "truth; print RMS error, variance and mean absolute error per axis "
                                   "(filters as columns) and the execution time, like the papers' "
                                   "tables. Filters: " + ", ".join(FILTERS) + "; with quadest[peers] "
                                   "also vqf, vqf-offline, imufusion, ahrs-madgwick, ahrs-mahony, ahrs-ekf, "
                                   "ahrs-aqua (--filters peers).")
    src = c.add_mutually_exclusive_group()
    src.add_argument("--recording", type=Path, metavar="FILE", help="recording with true_q, any supported format")
    src.add_argument("--scenario", choices=SCENARIOS, default="damaged-rotor",
                     help="simulate this scenario (default: damaged-rotor)")
    c.add_argument("--preset", choices=list(PRESETS), default="bebop2", help="with --scenario (default: bebop2)")
    c.add_argument("--seed", type=int, default=1, help="with --scenario (default: 1)")
    c.add_argument("--duration", type=float, default=None, help="with --scenario: seconds")
    c.add_argument("--set", action="append", metavar="KEY=VALUE", help="with --scenario: simulator parameter")
    c.add_argument("--filters", default="all", help="all (quadest's seven), peers (installed peers), or a comma-separated list of filters and peers (default: all)")
    c.add_argument("--param", action="append", metavar="FILTER.NAME=VALUE",
                   help="estimator parameter, e.g. --param afckf.omega1=-0.0145 (repeatable)")
    c.add_argument("--from", dest="t_from", type=float, default=None, metavar="SECONDS",
                   help="count errors from this time on (e.g. 5 for the failure in damaged-rotor)")
    c.add_argument("--json", metavar="OUT", help="write the figures as JSON")
    c.add_argument("--plot-dir", metavar="DIR", help="draw the error of every filter over time per axis")
    c.add_argument("--no-timing", action="store_true", help="skip the execution-time measurement")
    c.add_argument("--calibration", action="append", metavar="CALIB.json",
                     help="apply a calibration from quadest calibrate before any filter (repeatable)")
    c.add_argument("--align", choices=["none", "heading", "full"], default=None,
                   help="remove a constant rotation between the estimate's and the truth's navigation "
                        "frames (default: what the reader recommends, e.g. heading for DIDO/Blackbird)")
    c.add_argument("--align-body", action=argparse.BooleanOptionalAction, default=None,
                   help="also remove a constant rotation between IMU and truth body (default: on for RepoIMU)")
    _add_input_args(c)
    c.set_defaults(func=cmd_compare)

    r = sub.add_parser("reproduce", help="reproduce a paper's experiments on the simulator",
                       description="Run a paper's experiment on simulated flights over several seeds and "
                                   "print our figures next to the published ones. afckf: Tables I-V of "
                                   "Solanki & de Visser 2022; qukf: Table 1 of Liang et al. 2023; "
                                   "recovery: throws and the bank of EKFs of Beffa et al.")
    r.add_argument("paper", choices=["afckf", "qukf", "recovery"])
    r.add_argument("--seeds", default="1-5", help="afckf, qukf: seed range or list (default: 1-5)")
    r.add_argument("--throws", type=int, default=100, help="recovery: number of throws (default: 100)")
    r.add_argument("--seed", type=int, default=1, help="recovery: first seed (default: 1)")
    r.add_argument("--json", metavar="OUT", help="write all figures (per seed too) as JSON")
    r.add_argument("--plot-dir", metavar="DIR", help="draw the errors over time for the first seed")
    _add_engine_args(r, default_workers=0)
    r.set_defaults(func=cmd_reproduce)

    fa = sub.add_parser("fit-aero", help="fit the recovery paper's aerodynamic model (eq 14)",
                        description="Least-squares fit of f_c = A v + B|v|v + C ψ(ω) (recovery paper eqs "
                                    "9-14) from recordings with true velocity and attitude (simulated "
                                    "throws: the free flight after release; other recordings: every sample).")
    fa.add_argument("recordings", nargs="+", type=Path, metavar="RECORDING")
    fa.add_argument("-o", "--output", required=True, metavar="JSON", help="model file to write")
    fa.add_argument("--mass", type=float, default=None, help="vehicle mass, kg (default: from a simulation)")
    _add_input_args(fa)
    fa.set_defaults(func=cmd_fit_aero)

    rv = sub.add_parser("recover", help="recover attitude and velocity of a thrown vehicle from the IMU",
                        description="Run the recovery logic (throw detection, the bank of EKFs, hand-over "
                                    "to a nominal estimator) on a recording; report detection and "
                                    "convergence times, gravity direction and velocity, and their errors "
                                    "when the recording has truth.")
    rv.add_argument("file", type=Path, help="recording: any supported format (docs/readers.md)")
    rv.add_argument("--aero", metavar="JSON", help="aerodynamic model (default: a simulation's own)")
    rv.add_argument("--hypotheses", type=int, default=40, help="hypotheses of the bank (default: 40)")
    rv.add_argument("--beta1", type=float, default=7.0, help="detection threshold, m/s² (default: 7)")
    rv.add_argument("--beta2", type=float, default=0.06, help="convergence threshold on S_g (default: 0.06)")
    rv.add_argument("--json", metavar="OUT", help="write the summary as JSON")
    rv.add_argument("--plot", metavar="PNG", help="hypothesis errors, probabilities and velocity over time")
    rv.add_argument("--calibration", action="append", metavar="CALIB.json",
                     help="apply a calibration from quadest calibrate before any filter (repeatable)")
    _add_input_args(rv)
    rv.set_defaults(func=cmd_recover)

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
    _add_input_args(cb)
    cb.set_defaults(func=cmd_calibrate)

    es = sub.add_parser("estimate", help="run one estimator on a recording and write its attitude",
                        description="Run an estimator over a recording (any supported format) and write t, q_w, "
                                    "q_x, q_y, q_z, roll, pitch, yaw (radians) to .csv or .parquet.")
    es.add_argument("file", type=Path, help="recording: any supported format (docs/readers.md)")
    from quadest.evaluation.peers import PEERS

    es.add_argument("--filter", required=True, choices=list(FILTERS) + list(PEERS),
                    help="estimator: quadest's, or a peer with quadest[peers] installed")
    es.add_argument("-o", "--output", required=True, metavar="OUT", help=".csv or .parquet")
    es.add_argument("--param", action="append", metavar="FILTER.NAME=VALUE", help="estimator parameter")
    es.add_argument("--declination-deg", type=float, default=None,
                    help="magnetic declination (default: from a simulation's metadata, else 0)")
    es.add_argument("--calibration", action="append", metavar="CALIB.json",
                     help="apply a calibration from quadest calibrate before any filter (repeatable)")
    _add_input_args(es)
    es.set_defaults(func=cmd_estimate)

    b = sub.add_parser("benchmark", help="benchmarks: BROAD, quadrotor flights, speed",
                       description="broad: every filter on every BROAD trial in --data with the benchmark's "
                                   "metric (total, heading, inclination RMSE over the movement phases), per "
                                   "trial and per group of trials.json. flights: roll/pitch/yaw RMS on the "
                                   "DIDO and Blackbird flights under --data (6-axis; heading offset removed). "
                                   "speed: microseconds per sample of every filter, batch and streaming. "
                                   "quadest's filters and the installed peers (pip install 'quadest[peers]': "
                                   "vqf, imufusion, ahrs) run side by side.")
    b.add_argument("what", choices=["broad", "flights", "speed"], help="what to benchmark")
    b.add_argument("--data", type=Path, metavar="DIR", help="broad, flights: folder with the data")
    b.add_argument("--filters", default="all",
                   help="all (quadest and installed peers), quadest, peers, or a comma-separated list")
    b.add_argument("--trials", default="*", metavar="GLOB", help="broad: trial files to run (default: all)")
    b.add_argument("--align", choices=["none", "heading", "full"], default=None,
                   help="constant navigation-frame rotation removed before the errors (default: none "
                        "for broad, heading for flights)")
    b.add_argument("--duration", type=float, default=60.0, help="speed: seconds of simulated data (default: 60)")
    b.add_argument("--json", metavar="OUT", help="write the figures as JSON")
    b.set_defaults(func=cmd_benchmark)

    sw = sub.add_parser("sweep", help="run a grid of filters and parameters over many flights, on Dask",
                        description="Run every (filter x parameter set x flight) and write one row per run "
                                    "(parameters, metrics, status, error) to a Parquet file as runs finish. "
                                    "Runs carry their seeds, so results do not depend on the number of workers; "
                                    "an interrupted sweep resumes. docs/sweeps.md")
    sw.add_argument("--filters", default="quadest", help="quadest (default), all, peers, or a comma-separated list")
    _add_sweep_args(sw)
    sw.set_defaults(func=cmd_sweep)

    tu = sub.add_parser("tune", help="choose a filter's parameters that minimise a metric over a set",
                        description="Sweep one filter's parameter grid over flights or recordings and report "
                                    "the best set for all trials together (the lowest mean: BROAD's "
                                    "trial-agnostic choice) and per trial. docs/sweeps.md")
    tu.add_argument("filter", help="the filter to tune (quadest's or a peer's name)")
    tu.add_argument("--metric", default="total_rmse_deg",
                    choices=["total_rmse_deg", "heading_rmse_deg", "inclination_rmse_deg", "roll_rms_deg",
                             "pitch_rms_deg", "yaw_rms_deg"], help="metric to minimise (default: total_rmse_deg)")
    _add_sweep_args(tu)
    tu.set_defaults(func=cmd_tune)

    d = sub.add_parser("demo", help="the simulator demo: a rotor failure, summarised and plotted",
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
    except BrokenPipeError:  # output piped into a command that stopped reading (head)
        return 0
    except (CliError, ValueError, OSError) as exc:
        print(f"quadest {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
