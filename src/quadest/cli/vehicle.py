"""``quadest identify``: a vehicle file from the vehicle's own flights with rotor speeds
(docs/vehicle.md, *Your own vehicle*)."""

from __future__ import annotations

from pathlib import Path

from quadest.cli.choices import IDENTIFY_DEFAULTS
from quadest.cli.common import CliError, add_input_args, read, say


def _read_all(args, paths) -> dict:
    recs = {}
    for p in paths:
        if not Path(p).exists():
            raise CliError(f"{p}: no such file")
        recs[Path(p).name] = read(args, p)
    return recs


def format_identification(ident) -> list[str]:
    """The identified quantities with their uncertainties, and the held-out residuals."""
    lines = [f"identified from {', '.join(ident.files)} (± one standard error over parts of the flights)"]
    for name, (value, sd, unit) in ident.summary().items():
        lines.append(f"  {name:<22} {value:+.4g} ± {sd:.2g}  {unit}")
    spin = " ".join(f"{i}:{'cw' if s > 0 else 'ccw'}" for i, s in enumerate(ident.fit.spin))
    places = " ".join(
        f"{i}:{'front' if q[0] > 0 else 'rear'}-{'right' if q[1] > 0 else 'left'}"
        for i, q in enumerate(ident.geometry.quadrant)
    )
    lines += [f"  rotors                 {places}", f"  senses (from above)    {spin}"]
    if not ident.held_out:
        lines.append("no held-out flight (give two or more flights, or --hold-out): no residuals")
    for name, r in ident.held_out.items():
        lines.append(
            f"held out {name}: specific force z {r['f_z']:.3f} m/s² rms (signal {r['f_z_spread']:.3f}); "
            f"angular acceleration roll {r['alpha_roll']:.2f}/{r['alpha_roll_spread']:.2f}, "
            f"pitch {r['alpha_pitch']:.2f}/{r['alpha_pitch_spread']:.2f}, "
            f"yaw {r['alpha_yaw']:.2f}/{r['alpha_yaw_spread']:.2f} rad/s² rms (residual/signal)"
        )
    return lines


def cmd_identify(args):
    from quadest.calibration.identify import identified_vehicle, identify
    from quadest.models.multirotor import MultirotorParams
    from quadest.models.vehicle_file import write_vehicle

    train = _read_all(args, args.logs)
    held = _read_all(args, args.hold_out or [])
    mass = IDENTIFY_DEFAULTS.mass_kg if args.mass is None else args.mass
    arm = IDENTIFY_DEFAULTS.arm_m if args.arm is None else args.arm
    ident = identify(train, held or None, mass_kg=mass, arm_m=arm)
    for line in format_identification(ident):
        say(line)
    values, sources, uncertainty, identified = identified_vehicle(
        ident, mass_given=args.mass is not None, arm_given=args.arm is not None
    )
    name = Path(args.output).stem
    write_vehicle(args.output, MultirotorParams(**values), sources, name=name, uncertainty=uncertainty,
                  identified=identified)  # fmt: skip
    said = "per mass and per inertia (unit mass and arm)" if args.mass is None else f"at {mass:g} kg"
    say(f"wrote {args.output} (the vehicle {said}; docs/vehicle.md)")
    return 0


def add_parsers(sub):
    p = sub.add_parser(
        "identify",
        help="identify your vehicle from its flights with rotor speeds and write a vehicle file",
        description="Fit a quadrotor's thrust per mass, roll, pitch and yaw moment gains, centre of mass "
        "(from the thrust split), rotor places and senses and the rotors' inertia from nominal flights "
        "with measured rotor speeds (DIDO, PX4 or ArduPilot ESC telemetry, CSV), each with its "
        "uncertainty, and print the residuals on flights it was not fitted on. Mass, inertia and arm "
        "are not identifiable from flight: the vehicle is written at a reference mass and arm "
        "(--mass, --arm; by default unit ones: per-mass and per-inertia quantities). docs/vehicle.md.",
    )
    p.add_argument("logs", nargs="+", type=Path, metavar="LOG", help="recordings with rotor speeds to fit on")
    p.add_argument("-o", "--output", "--out", required=True, type=Path, metavar="VEHICLE.toml", help="vehicle file")
    p.add_argument(
        "--hold-out",
        nargs="+",
        type=Path,
        metavar="LOG",
        default=None,
        help="recordings to check the fit on (default: each LOG left out in turn)",
    )
    p.add_argument(
        "--mass",
        type=float,
        default=None,
        metavar="KG",
        help=f"the vehicle's mass (default: a unit mass, {IDENTIFY_DEFAULTS.mass_kg:g} kg)",
    )
    p.add_argument(
        "--arm",
        type=float,
        default=None,
        metavar="M",
        help=f"distance of each rotor from the rotors' centre (default: a unit arm, {IDENTIFY_DEFAULTS.arm_m:g} m; "
        "the centre of mass is then in arm lengths)",
    )
    add_input_args(p)
    p.set_defaults(func=cmd_identify)
