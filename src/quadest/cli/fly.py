"""``quadest fly``: the vehicle flies with an estimator in the loop."""

from __future__ import annotations

from pathlib import Path

from quadest.cli.choices import (
    CHECKS,
    COLLISIONS,
    CONTROLLERS,
    DETECTION_MODES,
    ESTIMATORS,
    FAILURE_MODES,
    FILTERS,
    FLIGHT_SCENARIOS,
    PRESETS,
    VEHICLE_PRESETS,
)
from quadest.cli.common import (
    CliError,
    add_max_runs_arg,
    check_runs,
    parse_seeds,
    parse_sets,
    say,
    with_sets,
    write_json,
)
from quadest.cli.flight_options import detector_changes, parse_failure

SENSOR_SECTIONS = ("environment", "imu", "gyro", "acc", "mag")
"""The simulator's sections a flight samples its sensors with (``--set gyro.range=8.73``)."""
RECORD_PREFIXES = ("vehicle", "flight", "se3", "ftc", "throw", "detector")
"""``--set PREFIX.FIELD``: the flown vehicle (MultirotorParams), the flight (FlightParams), the
nominal and fault-tolerant controllers (SE3Params, FtcParams), a throw (ThrowParams) and the
rotor-failure detector (DetectorParams)."""
SET_HELP = (
    "override a parameter, e.g. --set gyro.range=8.73 --set acc.lever_arm=[0,0,0.01] --set vehicle.mass_kg=0.6 "
    "(repeatable): the sensors' environment.*, imu.*, gyro.*, acc.*, mag.* (as quadest simulate --set; "
    "quadest simulate --list-params lists them), the flown vehicle's vehicle.* (after --vehicle), the "
    "flight's flight.* (after --position-sensor), the controllers' se3.* (k_p, k_v, k_R, k_w) and ftc.*, "
    "a throw's throw.* (docs/vehicle.md lists the fields), the detector's detector.* with --detection "
    "rotor-speeds or commands (e.g. detector.lost_threshold=0.008; docs/detection.md lists them); each "
    "checked against its bounds, kept in the recording's meta and the summary"
)


def grouped_sets(sets: dict) -> dict[str, dict]:
    """``--set`` overrides by what they change: ``"sensors"`` (``{"gyro.range": "8.73"}``) and
    one group per record prefix (``"vehicle": {"mass_kg": "0.6"}``). Any other key is refused,
    naming the keys fly takes."""
    groups = {}
    for key, text in sets.items():
        prefix, _, name = key.partition(".")
        if prefix in SENSOR_SECTIONS and name:
            groups.setdefault("sensors", {})[key] = text
        elif prefix in RECORD_PREFIXES and name:
            groups.setdefault(prefix, {})[name] = text
        else:
            keys = ", ".join(f"{p}.*" for p in SENSOR_SECTIONS + RECORD_PREFIXES)
            raise CliError(f"--set {key}: fly takes {keys} (quadest fly --help)")
    return groups


def _check_sets_fly(groups: dict, scenario: str, controller: str | None) -> None:
    """Refuse settings of what this flight does not fly (never ignored)."""
    if "throw" in groups and scenario != "throw":
        raise CliError("--set throw.*: a throw's parameters are for --scenario throw")
    if "detector" in groups and scenario == "throw":
        raise CliError("--set detector.*: a throw flies no rotor-failure detector")
    flies_ftc = scenario != "throw" and (controller or ("ftc" if scenario == "rotor-loss" else "se3")) == "ftc"
    if "ftc" in groups and not flies_ftc:
        raise CliError("--set ftc.*: this flight does not fly the fault-tolerant controller (--controller ftc does)")


def _sensor_config(preset: str, texts: dict):
    """The preset's sensors with ``--set``'s overrides, checked as simulate checks them."""
    from quadest.sim import build_config

    return with_sets(build_config(preset), texts)


def fly_settings(args, sets: dict) -> dict:
    """The flight's records from the options, then ``--set`` (fly's keyword arguments): the
    sensors, the vehicle, the flight, the controllers' and a throw's parameters."""
    from quadest.control import FtcParams, SE3Params
    from quadest.detect import DetectorParams
    from quadest.flight import FlightParams
    from quadest.flight.spec import DEFAULT_PRESET
    from quadest.flight.throw import ThrowParams
    from quadest.records import with_fields
    from quadest.recovery.divergence import CHECKS

    groups = grouped_sets(sets)
    _check_sets_fly(groups, args.scenario, args.controller)
    checks = [c.strip() for c in args.divergence.split(",")]
    if args.divergence not in ("auto", "off") and not all(c in CHECKS for c in checks):
        raise CliError(f"--divergence expects auto, off or a comma-separated list of {', '.join(CHECKS)}, "
                       f"got {args.divergence!r}")  # fmt: skip
    flight = FlightParams(position_sensor=args.position_sensor, collision=args.collision, divergence=args.divergence)
    out = {"params": with_fields(flight, groups.get("flight", {}), "flight"), "vehicle": _vehicle(args.vehicle)}
    if "sensors" in groups:
        preset = args.preset or DEFAULT_PRESET.get(args.scenario, "bebop2")
        out["config"] = _sensor_config(preset, groups["sensors"])
    if "vehicle" in groups:
        out["vehicle"] = with_fields(_vehicle(args.vehicle, preset=True), groups["vehicle"], "vehicle")
    for prefix, record in (("se3", SE3Params), ("ftc", FtcParams), ("throw", ThrowParams)):
        if prefix in groups:
            out[prefix] = with_fields(record(), groups[prefix], prefix)
    if "detector" in groups:
        changes = detector_changes(groups["detector"], [args.detection])
        out["detection"] = DetectorParams(rotor_speeds=args.detection == "rotor-speeds", **changes)
    return out


def _vehicle(name: str, preset: bool = False):
    """``--vehicle``: a preset's name (as given, or its parameters with ``preset``) or a vehicle file."""
    from quadest.models.multirotor import VEHICLE_PRESETS, vehicle_preset
    from quadest.models.vehicle_file import read_vehicle

    if name in VEHICLE_PRESETS:
        return vehicle_preset(name) if preset else name
    if not Path(name).is_file():
        raise CliError(f"--vehicle {name}: neither a vehicle ({', '.join(VEHICLE_PRESETS)}) nor a vehicle file")
    return read_vehicle(name)


def _noted(flight, vehicle: str, sets: dict):
    """``flight`` with what ``--set`` changed in its recording's meta and its summary (``set``,
    as given; meta ``vehicle`` names the preset they changed), so that the run can be flown again."""
    if sets:
        flight.recording.meta.update(vehicle=vehicle, set=dict(sets))
        flight.summary["set"] = dict(sets)
    return flight


def _fmt(v, unit="", digits=2):
    return "-" if v is None else f"{v:.{digits}f}{unit}"


CAUSAL = [n for n in FILTERS if not ESTIMATORS[n].acausal]
"""quadest's estimators that can fly in the loop (an acausal one uses the whole recording)."""


def parse_estimators(text, scenario: str) -> list[str]:
    """``all`` (truth and every quadest filter; for a throw truth and the recovery) or a
    comma-separated list."""
    from quadest.filters import ESTIMATORS, filter_name
    from quadest.flight import in_loop_estimators

    known = ["truth", "recovery"] if scenario == "throw" else ["truth", *in_loop_estimators()]
    if text is None:
        return ["recovery" if scenario == "throw" else "madgwick"]
    names = known if text.strip() == "all" else [filter_name(n.strip()) for n in text.split(",") if n.strip()]
    bad = [n for n in names if n not in known]
    acausal = [n for n in bad if n in ESTIMATORS and ESTIMATORS[n].acausal]
    if acausal:
        raise CliError(
            f"--estimator (--filters): {', '.join(acausal)} is acausal (each estimate uses the whole recording) and "
            "cannot fly in the loop; run it over the flight afterwards with quadest estimate --offline"
        )
    if bad or not names:
        raise CliError(
            f"--estimator (--filters): unknown {', '.join(bad) or repr(text)} for {scenario}; estimators: "
            f"{', '.join(known)}, or all"
        )
    return names


def _report(flight, out: Path, plot: bool):
    from quadest.data import save_recording, write_table
    from quadest.flight.summary import flight_table

    s = flight.summary
    stem = out / f"{s['scenario']}-{s['controller']}-{s['estimator']}-seed{s['seed']}"
    s["files"] = {
        "recording": str(save_recording(flight.recording, stem.with_suffix(".csv"))),
        "recording_metadata": f"{stem}.csv-metadata.json",
        "flight": str(write_table(flight_table(flight), Path(f"{stem}-flight.parquet"))),
    }
    if plot:
        from quadest.plot import plot_flight  # matplotlib: only when a plot is drawn

        s["files"]["plot"] = str(plot_flight(flight, Path(f"{stem}.png")))
    extra = ""
    if "spin_rate_rad_s" in s:
        extra = f", spin {s['spin_rate_rad_s']:.1f} rad/s, tilt {s['tilt_deg']:.1f}°"
    if s["scenario"] == "throw":
        hand = "-" if s["handover_s"] is None else f"{s['handover_s']:.3f} s"
        say(
            f"{s['estimator']}, seed {s['seed']}: {s['reason']}; {'recovered' if s['recovered'] else 'not recovered'}: "
            f"handover at {hand}, gravity error there {_fmt(s.get('gravity_error_at_handover_deg'), '°')}, "
            f"upright at {_fmt(s.get('upright_s'), ' s')}, lowest {s['lowest_point_m']:.2f} m below the release"
        )
        return
    end = f" at {s['end_time_s']:.2f} s" if s["end_time_s"] is not None else ""
    if s.get("collision") is not None or s.get("recovery_started"):
        extra += "; " + in_flight_line(s)
    det = s.get("detection")
    if det is not None:
        found = (
            "nothing found"
            if det["lost_rotor"] is None
            else f"rotor {det['lost_rotor']} found lost at {det['lost_s']:.3f} s"
        )
        if det["delay_s"] is not None:
            found += (
                f" ({1e3 * det['delay_s']:.0f} ms after the failure{'' if det['isolated'] else ', the wrong rotor'})"
            )
        if det["false_alarm"]:
            found += ": a false alarm"
        if det.get("damaged_rotor") is not None:
            damaged = f"rotor {det['damaged_rotor']} found damaged at {det['damaged_s']:.3f} s"
            damaged += f" ({100 * det['damaged_effectiveness']:.0f} % of its thrust left)"
            found = damaged if det["lost_rotor"] is None else f"{found}; {damaged}"
        extra += f"; detector: {found}"
    say(
        f"{s['estimator']}, seed {s['seed']}: {s['reason']}{end}; settled after {_fmt(s['time_to_settle_s'], ' s')}, "
        f"position RMS {_fmt(s['position_rms_settled_m'], ' m', 3)}, tilt error in the loop "
        f"{_fmt(s['tilt_error_rms_deg'], '°')} RMS{extra}"
    )


def in_flight_line(s: dict) -> str:
    """A flight's collision and recovery in flight, in one line."""
    c = s.get("collision")
    out = "" if c is None else (
        f"collision at {c['time_s']:.2f} s ({c['speed_m_s']:.1f} m/s, {c['rate_rad_s']:.1f} rad/s, the estimator "
        f"{c['estimator']}): "
    )  # fmt: skip
    if not s["recovery_started"]:
        return out + "no recovery started" + ("" if c is None else f"; {'' if s['recovered'] else 'not '}recovered")
    return out + (
        f"recovery started by {', '.join(s['checks'])} at {s['divergence_s']:.3f} s, handover "
        f"{_fmt(s['handover_s'], ' s', 3)} after, gravity error there "
        f"{_fmt(s.get('gravity_error_at_handover_deg'), '°')}, "
        f"fall {_fmt(s['fall_m'], ' m')}" + ("" if c is None else f"; {'' if s['recovered'] else 'not '}recovered")
    )


def cmd_fly(args):
    from quadest.flight import campaign_table, fly, fly_many
    from quadest.flight.fly import check_flight
    from quadest.flight.spec import FlightSpec

    seeds = parse_seeds(args.seeds)
    failure = parse_failure(args.failure)
    estimators = parse_estimators(args.estimator, args.scenario)
    sets = parse_sets(args.set)
    settings = fly_settings(args, sets)
    check_runs(args, len(seeds) * len(estimators), f"--seeds {args.seeds} x {len(estimators)} estimator(s)")
    for name in estimators:
        spec = FlightSpec(
            args.scenario, estimator=name, controller=args.controller, duration=args.duration,
            vehicle=settings["vehicle"], failure=failure, params=settings["params"], preset=args.preset,
            config=settings.get("config"),
        )  # fmt: skip
        check_flight(spec, seeds)
    out = Path(args.output)
    if out.exists() and not out.is_dir():
        raise CliError(f"{out}: -o names a folder for the runs' files, and this is a file")
    out.mkdir(parents=True, exist_ok=True)
    say(
        f"flying {args.scenario} ({args.vehicle} vehicle, {args.preset or 'default'} sensors) with the "
        f"{args.controller or 'default'} controller and {', '.join(estimators)} in the loop, seeds {args.seeds}"
        + "".join(f", --set {k}={v}" for k, v in sets.items())
        + " (the first flight with each estimator compiles the loop: some seconds)"
    )
    kwargs = dict(
        controller=args.controller,
        duration=args.duration,
        preset=args.preset,
        failure=failure,
        **{"detection": args.detection, **settings},
    )
    runs = []
    if len(estimators) == 1:
        for seed in seeds:
            flight = _noted(fly(args.scenario, estimator=estimators[0], seed=seed, **kwargs), args.vehicle, sets)
            _report(flight, out, not args.no_plot)
            runs.append(flight.summary)
        table = campaign_table(runs)
    else:
        runs = fly_many(
            args.scenario,
            estimators,
            seeds,
            on_flight=lambda f: _report(_noted(f, args.vehicle, sets), out, not args.no_plot),
            **kwargs,
        )
        table = campaign_table(runs)
    if args.scenario == "throw":
        say(f"\n{'estimator':<12}{'recovered':>10}{'handover':>10}{'gravity err':>12}{'velocity err':>13}{'lowest':>9}")
        for r in table:
            say(
                f"{r['estimator']:<12}{r['recovered']:>6}/{r['runs']:<3}{_fmt(r['handover_s'], ' s', 3):>10}"
                f"{_fmt(r['gravity_error_at_handover_deg'], '°'):>12}"
                f"{_fmt(r['velocity_error_at_handover_m_s'], ' m/s'):>13}{_fmt(r['lowest_point_m'], ' m'):>9}"
            )
    elif len(estimators) > 1:
        say("\nper estimator (tilt error offline: the same estimator over the flight with truth in the loop)")
        say(
            f"{'estimator':<14}{'survived':>9}{'settled':>8}{'tilt err loop':>14}{'offline':>9}{'pos RMS':>9}"
            f"{'spin':>7}{'tilt':>7}"
        )
        for r in table:
            say(
                f"{r['estimator']:<14}{r['survived']:>5}/{r['runs']:<3}{r['settled']:>4}/{r['runs']:<3}"
                f"{_fmt(r['tilt_error_in_loop_deg'], '°'):>14}{_fmt(r['tilt_error_offline_deg'], '°'):>9}"
                f"{_fmt(r['position_rms_settled_m'], ' m'):>9}{_fmt(r['spin_rate_rad_s'], '', 1):>7}"
                f"{_fmt(r['tilt_deg'], '°', 1):>7}"
            )
    survived = sum(r["status"] == "survived" for r in runs)
    say(f"{survived} of {len(runs)} runs survived")
    write_json(out / "summary.json", {"runs": runs, "table": table, "survived": survived, "runs_flown": len(runs)})
    return 0


def add_parsers(sub):
    s = sub.add_parser(
        "fly",
        help="fly the vehicle with an estimator in the loop (hover, trajectory, rotor loss)",
        description="Fly the rotor-level vehicle model with a controller that reads an estimator's attitude "
        "(and position from a motion-capture sensor) at the IMU rate. Per seed, writes the "
        "recording (.csv, readable by every command), the flight (.parquet: true state, rotor "
        "speeds and commands, what the controller read), a summary and a plot; summary.json "
        "gathers the runs. A run that crashes or whose estimator fails ends with a status and "
        "reason. docs/vehicle.md has the models.",
    )
    s.add_argument(
        "--scenario",
        choices=FLIGHT_SCENARIOS,
        default="rotor-loss",
        help="hover: hold the origin from a disturbed start; trajectory: a 1 m circle at 0.2 Hz; "
        "aggressive: a figure eight of 7-12 m/s² and 5-8 rad/s with the heading swinging ±2.5 rad; "
        "rotor-loss: hover, rotor 0 lost at 2 s (default); throw: released tumbling, recovered by the "
        "recovery paper's bank of EKFs, then held",
    )
    s.add_argument(
        "--controller",
        choices=CONTROLLERS,
        default=None,
        help="se3: the nominal controller only; ftc: SE(3), then the fault-tolerant controller once a "
        "rotor loss is known (default: ftc for rotor-loss, else se3)",
    )
    s.add_argument(
        "--estimator",
        "--filters",
        dest="estimator",
        default=None,
        help=f"the attitude estimator in the loop: truth, {', '.join(CAUSAL)}, the peers "
        f"{' and '.join(n for n, c in ESTIMATORS.items() if c.peer and c.streaming)} "
        "(their streaming API, when installed); for a throw recovery (the "
        "bank of EKFs, then its nominal EKF) or truth. Several (comma-separated) or all fly each, with "
        "the flight with truth in the loop first and each estimator also run over that flight "
        "afterwards (default: madgwick; recovery for a throw)",
    )
    _add_runs(s)
    _add_preset_and_vehicle(s)
    _add_sensing_and_detection(s)
    s.add_argument("--set", action="append", metavar="KEY=VALUE", help=SET_HELP)
    s.add_argument("-o", "--output", "--out", required=True, metavar="DIR", help="folder for the runs' files")
    s.add_argument("--no-plot", action="store_true", help="skip the figures")
    s.set_defaults(func=cmd_fly)


def _add_runs(s) -> None:
    """The seeds, the duration and the failure."""
    s.add_argument("--seeds", default="0", help="seeds: 0-4, 0,3,7 or both, 0-4,10-14 (default: 0)")
    add_max_runs_arg(s)
    s.add_argument(
        "--duration",
        type=float,
        default=None,
        help="seconds (default: per scenario; a throw's count from the release, 14 s)",
    )
    s.add_argument(
        "--failure",
        default=None,
        metavar="[MODE:]ROTOR@TIME[:EFF[:IMB]][,KEY=VALUE]",
        help="a rotor failure: 0@2 loses rotor 0's propeller at 2 s, 1@3:0.6 leaves rotor 1 60 %% from 3 s, "
        "2@1:0.9:5e-6 damages rotor 2's propeller at 1 s (90 %% thrust, imbalance 5e-6 kg m: a "
        "0.1 g chip at 5 cm, which shakes the IMU once per revolution); a MODE first for the others: "
        "motor-stop:0@2 (the motor spins down to rest), gradual:0@2:0.7,ramp_s=3 (fades to 70 %% over 3 s), "
        "desync:0@2,off_s=0.05,period_s=0.5 (the ESC drops the motor for 50 ms every 0.5 s); modes: "
        f"{', '.join(FAILURE_MODES)} (docs/simulator.md) (default for rotor-loss: 0@2)",
    )


def _add_preset_and_vehicle(s) -> None:
    """The sensors' preset and the vehicle."""
    s.add_argument("--preset", choices=list(PRESETS), default=None, help="sensors (default: bebop2; fma for a throw)")
    s.add_argument(
        "--vehicle",
        default="recovery",
        metavar="{" + ",".join(VEHICLE_PRESETS) + "} or VEHICLE.toml",
        help="vehicle: recovery (the recovery paper's), bebop2 (Sun et al. 2021), hummingbird (RotorPy's), or a "
        "vehicle file (quadest identify) (default: recovery; docs/vehicle.md)",
    )


def _add_sensing_and_detection(s) -> None:
    """The position sensor, how a rotor loss is learnt, a collision and the divergence checks."""
    s.add_argument(
        "--position-sensor",
        choices=["mocap", "gnss"],
        default="mocap",
        help="the position sensor the loop reads: mocap (100 Hz, 1 mm, 10 ms) or gnss (5 Hz, 0.5 m "
        "horizontal, 1 m vertical, 100 ms) (default: mocap)",
    )
    s.add_argument(
        "--detection",
        choices=DETECTION_MODES,
        default="oracle",
        help="how the fault-tolerant controller learns of a rotor loss: oracle (told 50 ms after it, the "
        "lost rotor's command zeroed from the failure on), rotor-speeds or commands (found by the "
        "detector from the measured rotor speeds or from the commands; docs/detection.md) (default: oracle)",
    )
    s.add_argument(
        "--collision",
        choices=COLLISIONS,
        default="none",
        help="a collision in flight, drawn from the seed (at 2-4 s, up to 5 m/s and 20 rad/s; 16 s flights by "
        "default): drawn (the estimator's state reset to nonsense or left to diverge, as drawn), reset or left; "
        "the divergence checks then start the recovery paper's bank of EKFs in flight (docs/recovery.md) "
        "(default: none)",
    )
    s.add_argument(
        "--divergence",
        default="auto",
        metavar="CHECKS",
        help="the checks that start a recovery in flight: auto (all with a collision, none without), off, or "
        f"a comma-separated list of {', '.join(CHECKS)}; with them on, the sensors are fma with a magnetometer "
        "unless --preset says otherwise (default: auto)",
    )


__all__ = ["add_parsers", "cmd_fly", "fly_settings", "grouped_sets"]
