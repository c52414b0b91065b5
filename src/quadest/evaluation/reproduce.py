"""Reproduce the papers' experiments on the simulator, with the published figures beside ours.

AFCKF (Solanki & de Visser 2022, Tables I-V): a Bebop 2 with one rotor lost (errors counted from
the failure on) and in normal flight; Madgwick, Valenti's complementary filter, Roetenberg's
Kalman filter and the AFCKF. By default the vehicle *flies* (:mod:`quadest.evaluation.flown`:
the loss from hover and from a circle, and the circle without a loss; spin, tilt and clipping
are outputs), with ablations on request; ``prescribed=True`` runs the prescribed scenarios
(``damaged-rotor``, ``nominal``) instead. The AFCKF's centrifugal constants (eq 13) come from a
separate calibration flight (seed 1000, the spinning segment), never from the evaluated seeds;
it also runs uncalibrated (``afckf-nocal``).

QUKF (Liang et al. 2023, Table 1): the ``lowcost-20hz`` preset, 30 s of hover and 30 s of motion;
QUKF, EKF and a complementary filter (the paper does not say which; quadest uses Valenti's).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from quadest.calibration import calibrate_centrifugal
from quadest.control.ftc import nutation_rates, relaxed_hover
from quadest.evaluation import flown
from quadest.evaluation.flown import FlownAfckfParams
from quadest.evaluation.metrics import AXES
from quadest.evaluation.parallel import execute
from quadest.evaluation.runner import estimate, estimate_all, score_result
from quadest.evaluation.speed import time_estimator
from quadest.filters import make_filter
from quadest.models.multirotor import SPIN_RANGES
from quadest.sim import build_config, simulate

# Published figures (degrees; AFCKF Table V in seconds per step).
PUBLISHED = {
    "afckf": {
        "damaged-rotor": {
            "rms_deg": {
                "madgwick": {"yaw": 143.5094, "pitch": 2.7121, "roll": 3.2761},
                "valenti": {"yaw": 164.8690, "pitch": 2.0417, "roll": 2.7165},
                "roetenberg": {"yaw": 150.4092, "pitch": 2.4125, "roll": 3.0184},
                "afckf": {"yaw": 9.8865, "pitch": 1.5717, "roll": 1.4599},
            },
            "var_deg2": {
                "madgwick": {"yaw": 20591.4895, "pitch": 6.9058, "roll": 6.9263},
                "valenti": {"yaw": 27182.5512, "pitch": 4.0811, "roll": 3.4681},
                "roetenberg": {"yaw": 22415.3247, "pitch": 5.5746, "roll": 5.5789},
                "afckf": {"yaw": 97.7493, "pitch": 1.8775, "roll": 1.7705},
            },
        },
        "nominal": {
            "rms_deg": {
                "madgwick": {"yaw": 1.8073, "pitch": 1.6893, "roll": 1.3670},
                "valenti": {"yaw": 2.6526, "pitch": 8.2690, "roll": 3.0333},
                "roetenberg": {"yaw": 2.6571, "pitch": 1.8590, "roll": 2.9042},
                "afckf": {"yaw": 2.4921, "pitch": 2.0445, "roll": 2.0558},
            },
            "var_deg2": {
                "madgwick": {"yaw": 3.1942, "pitch": 1.4312, "roll": 0.5101},
                "valenti": {"yaw": 3.0433, "pitch": 7.8106, "roll": 0.8680},
                "roetenberg": {"yaw": 3.3033, "pitch": 0.5657, "roll": 0.1548},
                "afckf": {"yaw": 2.2183, "pitch": 1.3689, "roll": 1.1665},
            },
        },
        "time_us": {"madgwick": 70.80, "valenti": 597.3, "roetenberg": 486.2, "afckf": 111.0},
    },
    "qukf": {
        "nominal": {
            "rms_deg": {
                "qukf": {"roll": 0.5288, "pitch": 0.6891, "yaw": 0.5821},
                "ekf": {"roll": 0.8122, "pitch": 0.8934, "yaw": 0.7526},
                "valenti": {"roll": 1.1548, "pitch": 1.0438, "yaw": 1.0745},
            },
            "mae_deg": {
                "qukf": {"roll": 0.3582, "pitch": 0.4224, "yaw": 0.4163},
                "ekf": {"roll": 0.7564, "pitch": 0.6827, "yaw": 0.6135},
                "valenti": {"roll": 1.0652, "pitch": 0.8307, "yaw": 0.8677},
            },
        },
    },
}

CALIBRATION_SEED = 1000


def afckf_calibration(seed: int = CALIBRATION_SEED) -> dict:
    """ω1, ω2 of eq 13 fitted on a separate simulated damaged-rotor flight, through
    ``quadest calibrate centrifugal`` (:func:`quadest.calibration.calibrate_centrifugal`) on its
    steady spin (from five spin-up time constants after the failure; gyroscope below its range)."""
    rec = simulate("damaged-rotor", "bebop2", seed=seed)
    cfg = build_config("bebop2")
    spin = rec.between(cfg.damaged.failure_s + 5 * cfg.damaged.spin_up_tau_s, np.inf)
    cal = calibrate_centrifugal([spin])
    return {
        "omega1": float(cal.values["omega1"]),
        "omega2": float(cal.values["omega2"]),
        "uncertainty_m": float(cal.uncertainty["omega1"]),
        "residual_mps2": cal.quality["residual_rms_mps2"],
        "seed": seed,
    }


def _aggregate(per_seed: list[dict], names) -> dict:
    """Mean over seeds of each metric, per filter and axis; keeps the per-seed values."""
    out = {}
    for n in names:
        out[n] = {}
        for key in ("rms_deg", "var_deg2", "mae_deg"):
            out[n][key] = {a: float(np.mean([s[n][key][a] for s in per_seed])) for a in AXES}
            out[n][key + "_per_seed"] = {a: [s[n][key][a] for s in per_seed] for a in AXES}
        for key in ("total_rmse_deg", "heading_rmse_deg", "inclination_rmse_deg"):
            out[n][key] = float(np.mean([s[n][key] for s in per_seed]))
        if all("nees" in s[n] for s in per_seed):
            out[n]["nees"] = float(np.mean([s[n]["nees"] for s in per_seed]))
            out[n]["nees_per_seed"] = [s[n]["nees"] for s in per_seed]
    return out


def reproduce_afckf(
    seeds=range(1, 6),
    progress: bool = False,
    workers: int = 0,
    scheduler=None,
    *,
    prescribed: bool = False,
    ablations: bool = False,
    params: flown.FlownAfckfParams | None = None,
) -> dict:
    """AFCKF Tables I-V on the simulator: flown (default) or on the prescribed scenarios; with
    ``ablations`` (flown only) the ablation table too. Seeds run through
    :func:`quadest.evaluation.parallel.execute`: in this process (``workers=0``), on a local
    Dask cluster or on ``scheduler``."""
    if prescribed:
        if ablations:
            raise ValueError("the ablations run on the flown rotor loss, not on the prescribed scenario")
        return _reproduce_afckf_prescribed(seeds, progress, workers, scheduler)
    p = params or flown.FlownAfckfParams()
    cal = flown.afckf_calibration_flown(p)
    fparams = {"afckf": {"omega1": cal["omega1"], "omega2": cal["omega2"]}, "afckf-nocal": {}}
    seeds = list(seeds)
    out = {
        "seeds": seeds,
        "mode": "flown",
        "params": {r["name"]: getattr(p, r["name"]) for r in p.describe()},
        "calibration": cal,
        "published": PUBLISHED["afckf"],
        "cases": {},
        "flights": {},
    }
    for case in flown.CASES:
        res = run_tasks(
            flown.flown_seed,
            [(case, s, p, fparams) for s in seeds],
            progress,
            f"AFCKF flown {case}",
            workers,
            scheduler,
        )
        out["cases"][case] = _aggregate([r["scores"] for r in res], flown.LABELS)
        out["flights"][case] = _flight_means([r["flight"] for r in res])
    if ablations:
        per_seed = run_tasks(
            flown.ablation_seed,
            [(s, p, fparams, flown.ABLATIONS) for s in seeds],
            progress,
            "AFCKF ablations",
            workers,
            scheduler,
        )
        out["ablations"] = flown.ablation_rows(per_seed)
    rec = flown.flown_flight("damaged-rotor", seeds[0], p).recording
    out["time_us"] = _times(rec, fparams)
    return out


def afckf_in_loop(
    seeds=range(1, 21),
    progress: bool = False,
    workers: int = 0,
    scheduler=None,
    *,
    params: flown.FlownAfckfParams | None = None,
    estimators=None,
    variants=None,
) -> dict:
    """The flown loss with each estimator in the fault-tolerant controller's loop
    (:func:`quadest.evaluation.flown.in_loop_seed`), per sensor variant and seed."""
    p = params or flown.FlownAfckfParams()
    estimators = list(estimators or flown.IN_LOOP_ESTIMATORS)
    variants = list(variants or flown.IN_LOOP_VARIANTS)
    seeds = list(seeds)
    tasks = [(label, overrides, s, p, estimators) for label, overrides in variants for s in seeds]
    runs = [
        r
        for part in run_tasks(flown.in_loop_seed, tasks, progress, "AFCKF in the loop", workers, scheduler)
        for r in part
    ]
    return {
        "seeds": seeds,
        "mode": "in-loop",
        "params": {r["name"]: getattr(p, r["name"]) for r in p.describe()},
        "after_loss_s": flown.IN_LOOP_AFTER_S,
        "table": flown.in_loop_table(runs),
        "runs": runs,
    }


def afckf_spin_range(
    seeds=range(1, 21),
    progress: bool = False,
    workers: int = 0,
    scheduler=None,
    *,
    ends=flown.RANGE_ENDS,
    params: flown.FlownAfckfParams | None = None,
) -> dict:
    """The flown loss at each end of the vehicle's spin range (:data:`quadest.models.SPIN_RANGES`,
    :func:`quadest.evaluation.flown.range_vehicle`): the controller model's relaxed hover, the
    truth's flights (spin, tilt, clipping share) with every filter's error over those that stayed
    up, and truth, robust and the AFCKF in the loop with a ±1000 and a ±500 °/s gyro."""
    seeds = list(seeds)
    out = {"seeds": seeds, "mode": "spin-range", "ranges": {}, "ends": {}}
    base = params or FlownAfckfParams()
    out["ranges"] = {
        k: [{"value": v, "source": src} for v, src in r] for k, r in SPIN_RANGES.get(base.vehicle, {}).items()
    }
    for end in ends:
        p = replace(base, vehicle_range=end)
        out["ends"][end] = _spin_range_end(p, seeds, progress, workers, scheduler)
    out["params"] = {r["name"]: getattr(base, r["name"]) for r in base.describe()}
    out["after_loss_s"] = flown.IN_LOOP_AFTER_S
    return out


def _spin_range_end(p, seeds, progress, workers, scheduler) -> dict:
    v = flown.range_vehicle(p.vehicle, p.vehicle_range)
    ftc = flown.flown_ftc(p)
    model = ftc.model(v)
    hover = relaxed_hover(model, p.rotor, ftc.rho)
    cal, fparams = _spin_range_calibration(p)
    per_seed = run_tasks(
        flown.surviving_seed,
        [("damaged-rotor", s, p, fparams) for s in seeds],
        progress,
        f"spin range {p.vehicle_range}: truth's flights",
        workers,
        scheduler,
    )
    up = [r for r in per_seed if r["scores"] is not None]
    loop = afckf_in_loop(
        seeds,
        progress,
        workers,
        scheduler,
        params=p,
        estimators=flown.SPIN_RANGE_ESTIMATORS,
        variants=flown.SPIN_RANGE_VARIANTS,
    )
    return {
        "vehicle": {"k_h": v.k_h, "rotor_inertia": v.rotor_inertia},
        "relaxed_hover_model": {
            "spin_rate_rad_s": abs(hover.spin),
            "tilt_deg": hover.tilt_deg,
            "nutation_rates_rad_s": list(nutation_rates(model, hover)),
        },
        "calibration": cal,
        "truth_flights": {
            "survived": len(up),
            "runs": len(per_seed),
            **_means_of_survivors([r["flight"] for r in up]),
            "per_seed": [r["flight"] for r in per_seed],
        },
        "offline": _aggregate([r["scores"] for r in up], flown.LABELS) if up else None,
        "in_loop": loop["table"],
    }


def _spin_range_calibration(p) -> tuple[dict | None, dict]:
    """The AFCKF's centrifugal calibration at an end of the spin range and the filters' parameters
    it gives; none (the AFCKF uncalibrated) where the calibration flight does not stay up or its
    gyroscope is at its range throughout the spin (the high end spins beyond ±1000 °/s)."""
    if flown.flown_flight("damaged-rotor", p.calibration_seed, p).summary["status"] != "survived":
        return None, {}
    try:
        cal = flown.afckf_calibration_flown(p)
    except ValueError:  # no spinning sample within the gyroscope's range: nothing to fit
        return None, {}
    return cal, {"afckf": {"omega1": cal["omega1"], "omega2": cal["omega2"]}, "afckf-nocal": {}}


def format_spin_range(result: dict) -> str:
    """The spin range as text: per end the vehicle, the spin, and who stays up in the loop."""
    lines = []
    for end, r in result["ends"].items():
        t = r["truth_flights"]
        spin = "-" if t["spin_rate_rad_s"] is None else f"{t['spin_rate_rad_s']:.1f} rad/s"
        lines.append(
            f"{end}: k_h {r['vehicle']['k_h']:.3g}, I_p {r['vehicle']['rotor_inertia']:.3g}; model "
            f"{r['relaxed_hover_model']['spin_rate_rad_s']:.1f} rad/s; "
            f"truth up {t['survived']}/{t['runs']}, spin {spin}"
        )
        for row in r["in_loop"]:
            lines.append(f"  {row['variant']}, {row['estimator']} in the loop: {row['survived']}/{row['runs']} up")
    return "\n".join(lines)


def _means_of_survivors(outputs: list[dict]) -> dict:
    keys = ("spin_rate_rad_s", "tilt_deg", "gyro_clipped_share", "peak_rate_rad_s")
    if not outputs:
        return dict.fromkeys(keys)
    return {k: v for k, v in _flight_means(outputs).items() if k != "per_seed"}


def _flight_means(outputs: list[dict]) -> dict:
    """The flights' outputs per seed, and their mean where every seed has one."""
    out = {"per_seed": outputs}
    for k in ("spin_rate_rad_s", "tilt_deg", "gyro_clipped_share", "peak_rate_rad_s"):
        v = [o[k] for o in outputs]
        out[k] = float(np.mean(v)) if all(x is not None for x in v) else None
    return out


def _times(rec, params) -> dict:
    out = {}
    for label, name in flown.RUNS.items():
        out[label] = time_estimator(
            lambda n=name, lb=label: make_filter(n, declination=rec.declination, **params.get(lb, {})), rec
        )
    return out


def _reproduce_afckf_prescribed(seeds, progress, workers, scheduler) -> dict:
    cal = afckf_calibration()
    cfg = build_config("bebop2")
    params = {"afckf": {"omega1": cal["omega1"], "omega2": cal["omega2"]}, "afckf-nocal": {}}
    seeds = list(seeds)
    out = {"seeds": seeds, "mode": "prescribed", "calibration": cal, "published": PUBLISHED["afckf"], "cases": {}}
    for scenario in ("damaged-rotor", "nominal"):
        out["cases"][scenario] = _run_case_labelled(
            scenario,
            "bebop2",
            seeds,
            list(flown.RUNS.values()),
            flown.LABELS,
            params,
            cfg.damaged.failure_s if scenario == "damaged-rotor" else 0.0,
            progress,
            f"AFCKF {scenario}",
            workers,
            scheduler,
        )
    out["time_us"] = _times(simulate("damaged-rotor", "bebop2", seed=seeds[0]), params)
    return out


def _one_seed(task) -> dict:
    """One seed of a reproduction: simulate, run the filters, their errors (a picklable task)."""
    scenario, preset, seed, duration, names, labels_list, params, t_from = task
    rec = simulate(scenario, preset, seed=seed, duration=duration)
    return {
        label: score_result(rec, estimate(rec, name, params.get(label)), t_from=t_from)
        for name, label in zip(names, labels_list)
    }


def run_tasks(fn, tasks, progress, desc, workers, scheduler) -> list:
    results = execute(fn, tasks, workers=workers, scheduler=scheduler, progress=progress, desc=desc)
    for r in results:
        if isinstance(r, BaseException):
            raise ValueError(f"a reproduction run failed: {type(r).__name__}: {r}")
    return results


def _run_case_labelled(
    scenario,
    preset,
    seeds,
    names,
    labels_list,
    params,
    t_from,
    progress,
    desc,
    workers=0,
    scheduler=None,
    duration=None,
):
    tasks = [(scenario, preset, s, duration, list(names), list(labels_list), params, t_from) for s in seeds]
    return _aggregate(run_tasks(_one_seed, tasks, progress, desc, workers, scheduler), labels_list)


def reproduce_qukf(
    seeds=range(1, 6), progress: bool = False, duration: float = 30.0, workers: int = 0, scheduler=None
) -> dict:
    """QUKF Table 1 on the simulator: 30 s of hover and of motion at 20 Hz."""
    names = ["qukf", "ekf", "valenti"]
    seeds = list(seeds)
    out = {"seeds": seeds, "published": PUBLISHED["qukf"], "cases": {}}
    for scenario in ("hover", "nominal"):
        out["cases"][scenario] = _run_case_labelled(
            scenario,
            "lowcost-20hz",
            seeds,
            names,
            names,
            {},
            0.0,
            progress,
            f"QUKF {scenario}",
            workers,
            scheduler,
            duration,
        )
    return out


def first_seed_flight(paper: str, result: dict):
    """The first seed's flight of a reproduction and what runs on it:
    ``(rec, names, params, t_from, title)``."""
    seed = result["seeds"][0]
    if paper == "afckf":
        names = ["madgwick", "valenti", "roetenberg", "afckf"]
        params = {"afckf": {k: result["calibration"][k] for k in ("omega1", "omega2")}}
        if result.get("mode") == "flown":
            p = flown.FlownAfckfParams(**result["params"])
            return (
                flown.flown_flight("damaged-rotor", seed, p).recording,
                names,
                params,
                p.failure_s,
                f"flown rotor loss / {p.vehicle} / seed {seed}",
            )
        scen, preset, t_from, duration = "damaged-rotor", "bebop2", build_config("bebop2").damaged.failure_s, None
    elif paper == "qukf":
        scen, preset, t_from, duration = "nominal", "lowcost-20hz", None, 30.0
        names, params = ["qukf", "ekf", "valenti"], {}
    else:
        raise ValueError(f"no error plots for {paper!r}")
    return (
        simulate(scen, preset, seed=seed, duration=duration),
        names,
        params,
        t_from,
        f"{scen} / {preset} / seed {seed}",
    )


def first_seed_estimates(paper: str, result: dict):
    """The first seed's flight of a reproduction and every filter's estimate on it, for the
    error plots: ``(rec, {label: FilterResult}, t_from, title)``."""
    rec, names, params, t_from, title = first_seed_flight(paper, result)
    return rec, estimate_all(rec, names, params), t_from, title


def format_reproduction(paper: str, result: dict) -> str:
    """Our figures next to the published ones, one table per case and metric."""
    lines = []
    pub = result["published"]
    if paper == "afckf":
        cal = result["calibration"]
        if result.get("mode") == "flown":
            lines += _flown_lines(result)
        lines.append(
            f"AFCKF centrifugal calibration (eq 13) from {'flown ' if cal.get('flown') else ''}calibration "
            f"flight seed {cal['seed']}: "
            f"ω1 = {cal['omega1']:.4f} m, ω2 = {cal['omega2']:.4f} m (± {cal['uncertainty_m']:.1e} m, residual "
            f"{cal['residual_mps2']:.2f} m/s²; quadest calibrate centrifugal)"
        )
    lines.append(f"seeds {result['seeds'][0]}..{result['seeds'][-1]} (mean over seeds); 'paper' = published value")
    for case, res in result["cases"].items():
        for key, title in (("rms_deg", "RMS error [deg]"), ("var_deg2", "variance [deg²]"), ("mae_deg", "MAE [deg]")):
            pubc = pub.get(case, {}).get(key)
            if key != "rms_deg" and pubc is None:
                continue
            lines.append("")
            lines.append(f"{case}: {title}")
            names = list(res)
            header = f"{'':8}" + "".join(f"{n:>15}" + (f"{'paper':>10}" if pubc and n in pubc else "") for n in names)
            lines.append(header)
            for a in AXES:
                row = f"{a:<8}"
                for n in names:
                    row += f"{res[n][key][a]:>15.3f}"
                    if pubc and n in pubc:
                        row += f"{pubc[n][a]:>10.3f}"
                lines.append(row)
    if "time_us" in result:
        lines.append("")
        lines.append("execution time [µs/sample]: ours batch / streaming from Python; paper per step (Table V)")
        for n, tm in result["time_us"].items():
            p = pub.get("time_us", {}).get(n)
            lines.append(f"{n:<15}{tm['batch_us']:>10.3f}{tm['stream_us']:>10.2f}" + (f"{p:>12.1f}" if p else ""))
    if result.get("ablations"):
        lines += ["", flown.format_ablations(result["ablations"])]
    return "\n".join(lines)


PAPER_SPIN_RATE = 15.5  # rad/s, the AFCKF paper's damaged-rotor flights


def _flown_lines(result: dict) -> list[str]:
    """What the flights made of the loss, beside the paper's spin rate."""
    p = result["params"]
    lines = [
        f"flown: a {p['vehicle']} loses rotor {p['rotor']} at {p['failure_s']:g} s of {p['duration_s']:g} s; the "
        "fault-tolerant controller flies it on the true state; the estimators run on its sensors "
        f"({p['preset']} preset); the damaged-rotor cases are scored from the loss on."
    ]
    for case, f in result["flights"].items():
        if f["spin_rate_rad_s"] is None:
            lines.append(
                f"  {case}: no loss; peak body rate {f['peak_rate_rad_s']:.1f} rad/s, "
                f"gyro clipped on {100 * f['gyro_clipped_share']:.1f} % of the samples"
            )
            continue
        lines.append(
            f"  {case}: settled spin {f['spin_rate_rad_s']:.1f} rad/s (paper: {PAPER_SPIN_RATE} rad/s), "
            f"tilt {f['tilt_deg']:.1f}°, peak body rate {f['peak_rate_rad_s']:.1f} rad/s, gyro clipped on "
            f"{100 * f['gyro_clipped_share']:.1f} % of the samples after the loss"
        )
    return lines


# -- recovery ------------------------------------------------------------------------------
