"""``quadest fit-aero`` and ``quadest recover``: the state-estimate recovery of a thrown vehicle."""

from __future__ import annotations

from pathlib import Path

from quadest.cli.choices import RECOVERY_DEFAULTS
from quadest.cli.common import (
    CliError,
    add_calibration_arg,
    add_input_args,
    add_report_arg,
    read,
    say,
    write_json,
    write_report_for,
)


def cmd_fit_aero(args):
    import numpy as np

    from quadest.models.aero import fit_aero

    recs = [read(args, p) for p in args.recordings]
    mass = args.mass
    if mass is None:
        masses = {r.meta.get("config", {}).get("vehicle", {}).get("mass_kg") for r in recs}
        if len(masses) != 1 or None in masses:
            raise CliError("give the vehicle mass with --mass KG (the recordings do not state one)")
        mass = masses.pop()
    model = fit_aero(recs, mass)
    model.save(args.output)
    res = model.info["residual_rms_mps2"]
    say(f"fitted eq 14 on {model.info['samples']} samples of {len(recs)} recording(s), mass {mass} kg")
    say(f"residual RMS x/y/z: {res[0]:.3f} / {res[1]:.3f} / {res[2]:.3f} m/s²")
    say(f"constant term (idle thrust) C[:, 9] = {np.array2string(model.C[:, 9], precision=3)} N")
    say(f"wrote {args.output}")
    return 0


def cmd_recover(args):
    from quadest.calibration import apply_calibrations, load_calibration
    from quadest.models.aero import AeroModel
    from quadest.recovery import RecoveryParams, recover

    rec = read(args, args.file)
    cals = [load_calibration(p) for p in args.calibration or []]
    aero = [c.aero_model() for c in cals if c.kind == "aero"]
    rec, _ = apply_calibrations(rec, [c for c in cals if c.kind != "aero"])
    model = aero[-1] if aero else AeroModel.load(args.aero) if args.aero else _simulated_model(rec)
    params = RecoveryParams(n_hypotheses=args.hypotheses, beta1=args.beta1, beta2=args.beta2)
    res = recover(rec, model, params, record_all=bool(args.plot or args.report))
    s = res.summary
    for ev in s["events"]:
        say(f"{ev['t_s']:8.3f} s  {ev['state']}")
    if not s["detected"]:
        say(f"no throw detected (‖acc‖ never below {params.beta1} m/s² for {params.detect_samples} samples)")
    elif not s["converged"]:
        say(f"the bank did not converge (S_g never below {params.beta2})")
    else:
        g = s["gravity_dir_body"]
        v = s["velocity_body_mps"]
        say(
            f"converged {s['t_converge_from_detection_s'] * 1e3:.0f} ms after detection"
            + (f", {s['t_converge_s'] * 1e3:.0f} ms after release" if "t_converge_s" in s else "")
        )
        say(
            f"gravity direction (body) [{g[0]:+.3f}, {g[1]:+.3f}, {g[2]:+.3f}], velocity (body) "
            f"[{v[0]:+.2f}, {v[1]:+.2f}, {v[2]:+.2f}] m/s"
        )
        if "gravity_err_deg" in s:
            say(
                f"errors against truth: gravity direction {s['gravity_err_deg']:.2f}°"
                + (f", velocity {s['vel_err_mps']:.3f} m/s" if "vel_err_mps" in s else "")
            )
    if args.json:
        write_json(args.json, s)
    if args.plot:
        from quadest.plot import plot_recovery  # matplotlib: only when a plot is asked for

        say(f"wrote {plot_recovery(res, rec, args.plot, title=f'recovery: {args.file}')}")
    if args.report:
        write_report_for(
            rec,
            ["madgwick"],
            {},
            args.report,
            f"quadest recover: {args.file}",
            recovery=res,
            recovery_model="the aerodynamic model this recovery used",
        )
    return 0


def _simulated_model(rec):
    from quadest.sim import aero_model_of

    try:
        return aero_model_of(rec)
    except ValueError:
        raise CliError(
            "this recording does not carry a simulation's aerodynamic model: give --aero aero.json (quadest fit-aero)"
        ) from None


def add_parsers(sub):
    fa = sub.add_parser(
        "fit-aero",
        help="fit the recovery paper's aerodynamic model (eq 14)",
        description="Least-squares fit of f_c = A v + B|v|v + C ψ(ω) (recovery paper eqs "
        "9-14) from recordings with true velocity and attitude (simulated "
        "throws: the free flight after release; other recordings: every sample).",
    )
    fa.add_argument("recordings", nargs="+", type=Path, metavar="RECORDING")
    fa.add_argument("-o", "--output", "--out", required=True, metavar="JSON", help="model file to write")
    fa.add_argument("--mass", type=float, default=None, help="vehicle mass, kg (default: from a simulation)")
    add_input_args(fa)
    fa.set_defaults(func=cmd_fit_aero)

    rv = sub.add_parser(
        "recover",
        help="recover attitude and velocity of a thrown vehicle from the IMU",
        description="Run the recovery logic (throw detection, the bank of EKFs, hand-over "
        "to a nominal estimator) on a recording; report detection and "
        "convergence times, gravity direction and velocity, and their errors "
        "when the recording has truth.",
    )
    rv.add_argument("file", type=Path, help="recording: any supported format (docs/readers.md)")
    rv.add_argument("--aero", metavar="JSON", help="aerodynamic model (default: a simulation's own)")
    d = RECOVERY_DEFAULTS  # the parameter record's defaults
    rv.add_argument(
        "--hypotheses", type=int, default=d.n_hypotheses, help=f"hypotheses of the bank (default: {d.n_hypotheses})"
    )
    rv.add_argument("--beta1", type=float, default=d.beta1, help=f"detection threshold, m/s² (default: {d.beta1:g})")
    rv.add_argument("--beta2", type=float, default=d.beta2, help=f"convergence threshold on S_g (default: {d.beta2:g})")
    rv.add_argument("--json", metavar="OUT", help="write the summary as JSON")
    rv.add_argument("--plot", metavar="PNG", help="hypothesis errors, probabilities and velocity over time")
    add_calibration_arg(rv)
    add_input_args(rv)
    add_report_arg(rv)
    rv.set_defaults(func=cmd_recover)
