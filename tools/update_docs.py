"""Regenerate the generated tables in README.md and docs/ from the code and from the measured
results in docs/results/*.json (run after changing parameters or re-running a benchmark).

Sections between ``<!-- generated:NAME -->`` and ``<!-- /generated -->`` are replaced:
parameter tables (``simulator-params``, ``estimator-params``, ``recovery-params``) from the
parameter records, and result tables (``results-*``) from the JSON the benchmark commands write
(docs/developing.md says which command writes which file). tests/integration/test_docs.py fails when a table
is out of date.
"""

import json
import math
import re
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def simulator_params() -> str:
    from quadest.sim import build_config, param_table

    rows = ["| parameter | value | unit | meaning | source |", "|---|---|---|---|---|"]
    for r in param_table(build_config("bebop2"), "bebop2"):
        rows.append(
            f"| `{r['key']}` | {json.dumps(r['value'], default=str)} | {r['unit']} | {r['doc']} | {r['source']} |"
        )
    return "\n".join(rows)


def estimator_params() -> str:
    from quadest.filters import FILTERS

    out, seen = [], {}
    for name, cls in FILTERS.items():
        base = next((seen[b] for b in cls.Params.__mro__[1:] if b in seen), None)
        known = {d["name"] for d in base[1].describe()} if base else set()
        if len(known) == len(cls.Params.describe()):  # the same parameters under another name: all shown
            base, known = None, set()
        seen[cls.Params] = (name, cls.Params)
        also = f" (and every parameter of `{base[0]}`)" if base else ""
        out.append(f"**`{name}`**{also}\n\n| parameter | default | unit | bounds | meaning | source |")
        out.append("|---|---|---|---|---|---|")
        for d in (d for d in cls.Params.describe() if d["name"] not in known):
            out.append(
                f"| `{d['name']}` | {json.dumps(d['default'], default=float)} | {d['unit']} | "
                f"{d.get('bounds', '-')} | {d['doc']} | {d['source']} |"
            )
        out.append("")
    return "\n".join(out).rstrip()


def recovery_params() -> str:
    from quadest.recovery import RecoveryParams

    rows = ["| parameter | default | unit | meaning | source |", "|---|---|---|---|---|"]
    for d in RecoveryParams.describe():
        rows.append(f"| `{d['name']}` | {d['default']} | {d['unit']} | {d['doc']} | {d['source']} |")
    return "\n".join(rows)


def vehicle_params() -> str:
    from quadest.models.multirotor import MultirotorParams

    rows = ["| parameter | default | unit | bounds | meaning | source |", "|---|---|---|---|---|---|"]
    for d in MultirotorParams.describe():
        rows.append(
            f"| `{d['name']}` | {json.dumps(d['default'], default=float)} | {d['unit']} | "
            f"{d.get('bounds', '-')} | {d['doc']} | {d['source']} |"
        )
    return "\n".join(rows)


def _param_rows(describe_rows, default_header="default"):
    rows = [f"| parameter | {default_header} | unit | bounds | meaning | source |", "|---|---|---|---|---|---|"]
    for d in describe_rows:
        rows.append(
            f"| `{d['name']}` | {json.dumps(d['default'], default=float)} | {d['unit']} | "
            f"{d.get('bounds', '-')} | {d['doc']} | {d['source']} |"
        )
    return "\n".join(rows)


def vehicle_presets() -> str:
    """The presets' values that differ from the default vehicle, with sources."""
    from quadest.models.multirotor import VEHICLE_PRESETS, preset_rows

    out = []
    for name, (values, _) in VEHICLE_PRESETS.items():
        if not values:
            continue
        rows = ["| parameter | value | unit | source |", "|---|---|---|---|"]
        for d in preset_rows(name):
            if d["name"] in values:
                value = json.dumps(d["default"], default=float)
                rows.append(f"| `{d['name']}` | {value} | {d['unit']} | {d['source']} |")
        out.append(f"**`{name}`**\n\n" + "\n".join(rows) + "\n")
    return "\n".join(out).rstrip()


def ftc_params() -> str:
    from quadest.control import FtcParams

    return _param_rows(FtcParams.describe())


def throw_params() -> str:
    from quadest.flight.throw import ThrowParams

    return _param_rows(ThrowParams.describe())


def flight_params() -> str:
    from quadest.flight import FlightParams

    return _param_rows(FlightParams.describe())


def rate_params() -> str:
    from quadest.detect import RatePredictorParams

    return _param_rows(RatePredictorParams.describe())


def _f(v, fmt="{:.1f}"):
    return "-" if v is None else fmt.format(v)


def results_flight() -> str:
    r = _load("flight")
    rows = [
        [
            t["estimator"],
            f"{t['survived']}/{t['runs']}",
            f"{t['settled']}/{t['runs']}",
            _f(t["tilt_error_in_loop_deg"]),
            _f(t["tilt_error_offline_deg"]),
            _f(t["position_rms_settled_m"], "{:.3f}"),
            _f(t["spin_rate_rad_s"]),
            _f(t["tilt_deg"]),
        ]
        for t in r["table"]
    ]
    seeds = sorted({run["seed"] for run in r["runs"]})
    return (
        _table(
            [
                "in the loop",
                "survived",
                "settled",
                "tilt error in the loop (° RMS)",
                "offline, truth's flight (° RMS)",
                "position RMS settled (m)",
                "spin (rad/s)",
                "tilt (°)",
            ],
            rows,
        )
        + f"\n\nRotor 0 lost at 2 s, 10 s flights, seeds {seeds[0]}-{seeds[-1]}, recovery vehicle, bebop2 sensors "
        "(docs/results/flight.json)."
    )


def results_throw() -> str:
    import numpy as np

    r = _load("throw")
    rows = []
    for t in r["table"]:
        runs = [x for x in r["runs"] if x["estimator"] == t["estimator"]]
        g = [x["gravity_error_at_handover_deg"] for x in runs if x.get("gravity_error_at_handover_deg") is not None]
        v = [x["velocity_error_at_handover_m_s"] for x in runs if x.get("velocity_error_at_handover_m_s") is not None]
        up = [x["upright_s"] for x in runs if x.get("upright_s") is not None]
        low = [x["lowest_point_m"] for x in runs]
        rows.append(
            [
                t["estimator"],
                f"{t['recovered']}/{t['runs']}",
                _f(t["handover_s"], "{:.3f}"),
                f"{np.median(g):.1f} / {np.max(g):.1f}" if g else "-",
                f"{np.median(v):.2f} / {np.max(v):.2f}" if v else "-",
                f"{np.median(up):.2f}" if up else "-",
                f"{np.mean(low):.2f} / {np.max(low):.2f}",
            ]
        )
    seeds = sorted({x["seed"] for x in r["runs"]})
    return (
        _table(
            [
                "in the loop",
                "recovered",
                "handover (s after the release, mean)",
                "gravity error there (°, median / max)",
                "velocity error there (m/s, median / max)",
                "upright (s after the release, median)",
                "fall (m, mean / max)",
            ],
            rows,
        )
        + f"\n\n{len(seeds)} throws (seeds {seeds[0]}-{seeds[-1]}), recovery vehicle, fma sensors "
        "(docs/results/throw.json)."
    )


def results_repoimu() -> str:
    """docs/readers.md: the RepoIMU benchmark, total RMS per trial and the means."""
    r = _load("repoimu")
    names = r["filters"]
    rows = [[t] + [f"{row[n]['total_rmse_deg']:.2f}" for n in names] for t, row in r["trials"].items()]
    rows.append(["mean total"] + [f"{r['mean'][n]['total_rmse_deg']:.2f}" for n in names])
    rows.append(["mean roll / pitch"] + [f"{r['mean'][n]['roll']:.1f} / {r['mean'][n]['pitch']:.1f}" for n in names])
    return (
        _table(["trial"] + names, rows)
        + f"\n\nTotal RMS error in degrees after the reader's alignment (heading and body rotation); "
        f"{', '.join(r['without_truth']) or 'none'} without Vicon truth, not scored "
        "(`quadest benchmark repoimu --data ../shared/data/repoimu --json docs/results/repoimu.json`)."
    )


def results_recovery_flown() -> str:
    """docs/recovery.md: the recovery paper's experiment flown, upward and in any direction."""
    up, anyd = _load("recovery-flown"), _load("recovery-flown-any")
    cu, ca = up["cases"]["upward"], anyd["cases"]["any direction"]
    pub = up["published"]

    def med(c, k, fmt):
        d = c[k]
        return "-" if d["median"] is None else f"{d['median']:{fmt}} / {d['p90']:{fmt}}"

    rows = [
        ["release detected", f"{cu['detected']}/{cu['throws']}", f"{ca['detected']}/{ca['throws']}", "-"],
        ["bank converged", f"{cu['converged']}/{cu['throws']}", f"{ca['converged']}/{ca['throws']}", "-"],
        [
            "convergence after the detection (s, median / p90)",
            med(cu, "convergence_s", ".3f"),
            med(ca, "convergence_s", ".3f"),
            f"{pub['convergence_s']:.2f} (one throw)",
        ],
        [
            "gravity error there (°, median / p90)",
            med(cu, "gravity_error_deg", ".1f"),
            med(ca, "gravity_error_deg", ".1f"),
            f"about {pub['gravity_error_deg']:g} (one throw)",
        ],
        [
            "velocity error there (m/s, median / p90)",
            med(cu, "velocity_error_m_s", ".2f"),
            med(ca, "velocity_error_m_s", ".2f"),
            "-",
        ],
        [
            "upright within 30° (s after the release, median / p90)",
            med(cu, "upright_s", ".2f"),
            med(ca, "upright_s", ".2f"),
            "-",
        ],
        [
            "recovered to hover (height within 0.5 m for 10 s)",
            f"{cu['recovered']}/{cu['throws']} ({100 * cu['recovered'] / cu['throws']:.0f} %)",
            f"{ca['recovered']}/{ca['throws']} ({100 * ca['recovered'] / ca['throws']:.0f} %)",
            f"{pub['hovered_10s']}/{pub['throws']} hovered 10 s; {pub['recovered']}/{pub['throws']} with brief hovers",
        ],
        ["crashed", f"{cu['crashed']}/{cu['throws']}", f"{ca['crashed']}/{ca['throws']}", "1/32"],
        [
            "detected in the hand / handed over there",
            f"{cu['detected_in_hand']} / {cu['handover_in_hand']}",
            f"{ca['detected_in_hand']} / {ca['handover_in_hand']}",
            "-",
        ],
        [
            "height off the held height, last 5 s (m, median / p90)",
            med(cu, "height_error_end_m", ".2f"),
            med(ca, "height_error_end_m", ".2f"),
            "-",
        ],
        [
            "height held within 0.2 m",
            f"{cu['height_within_0_2_m']}/{cu['throws']}",
            f"{ca['height_within_0_2_m']}/{ca['throws']}",
            "-",
        ],
        ["fall (m, median / p90)", med(cu, "fall_m", ".2f"), med(ca, "fall_m", ".2f"), "-"],
    ]
    t = up["throw"]
    return (
        _table(["", "thrown upward", "in any direction", "paper (real throws)"], rows)
        + f"\n\n{cu['throws']} flown throws each (seeds {up['seeds'][0]}-{up['seeds'][1]}), release up to "
        f"{t['speed_max']:g} m/s and {t['rate_max']:g} rad/s, hand up to {t['hand_acc_max']:g} m/s² "
        "(`quadest reproduce recovery [--any-direction] --ablations --json ...`, docs/results/recovery-flown*.json)."
    )


def results_recovery_ablations() -> str:
    """docs/recovery.md: the flown throws without each addition to the paper's recovery."""
    rows = []
    for name, case in (("recovery-flown", "upward"), ("recovery-flown-any", "any direction")):
        r = _load(name)
        variants = {"all three": r["cases"][case], **r["ablations"]}
        for label, c in variants.items():
            g = c["gravity_error_deg"]
            rows.append(
                [
                    case,
                    label,
                    f"{c['recovered']}/{c['throws']}",
                    str(c["crashed"]),
                    str(c["handover_in_hand"]),
                    f"{g['median']:.1f} / {g['p90']:.1f}",
                    f"{c['height_within_0_2_m']}/{c['throws']}",
                    f"{c['fall_m']['median']:.2f} / {c['fall_m']['p90']:.2f}",
                ]
            )
    return (
        _table(
            [
                "thrown",
                "recovery",
                "recovered",
                "crashed",
                "handed over in the hand",
                "gravity error at the handover (°, median / p90)",
                "height held within 0.2 m",
                "fall (m, median / p90)",
            ],
            rows,
        )
        + "\n\nThe same 100 throws (seeds 1-100) each row (`quadest reproduce recovery [--any-direction] --ablations "
        "--json ...`, docs/results/recovery-flown*.json)."
    )


def results_sim() -> str:
    r = _load("sim")
    c = r["closed_loop"]
    rows = [
        [
            "closed loop: rotor loss, fault-tolerant controller, " + c["estimator"] + " in the loop, sensors at 1 kHz",
            f"{c['loop_us_per_step']:.2f} µs",
            f"{c['loop_x_real_time']:.0f}x real time (whole `fly` call with its "
            f"recording: {c['total_x_real_time']:.0f}x)",
            "≥ 200x",
        ]
    ]
    if "rotorpy" in r:
        p = r["rotorpy"]
        rows.append(
            [
                "SE(3) circle, Hummingbird, 1 kHz: quadest",
                f"{p['ms_per_step']['quadest'] * 1e3:.2f} µs",
                f"{p['speedup']:.0f}x faster than RotorPy",
                "≥ 100x",
            ]
        )
        rows.append(["the same, RotorPy", f"{p['ms_per_step']['rotorpy'] * 1e3:.0f} µs", "-", "-"])
    return _table(["flight", "per step", "measured", "target"], rows) + (
        f"\n\n{c['duration_s']:g} s flown, best of 3 after a warm-up, one core (docs/results/sim.json)."
    )


def results_crosscheck() -> str:
    p = _load("sim")["rotorpy"]
    h, t = p["hover_rotor_speed"], p["tracking_rms_m"]
    rows = [
        [
            "hover rotor speed (rad/s)",
            f"{h['quadest']:.3f}",
            f"{h['rotorpy']:.3f}",
            f"{100 * (h['quadest'] / h['rotorpy'] - 1):+.3f} %",
            "within 1 %",
        ],
        [
            f"tracking RMS after {t['from_s']:g} s (cm)",
            f"{100 * t['quadest']:.2f}",
            f"{100 * t['rotorpy']:.2f}",
            f"{100 * (t['quadest'] / t['rotorpy'] - 1):+.1f} %",
            "within 20 %",
        ],
    ]
    return (
        _table(["", "quadest", "RotorPy", "difference", "required"], rows)
        + f"\n\nAt {p['rate_hz']:g} Hz over {p['duration_s']:g} s (docs/results/sim.json)."
    )


RESULTS = ROOT / "docs" / "results"
SPEED_TARGET_US = {
    "afckf": 0.5,
    "qukf": 2.0,
    "ekf": 2.0,
    "madgwick": 0.2,
    "mahony": 0.2,
    "valenti": 0.2,
    "roetenberg": 5.0,
}  # the batch speed targets (targets, not measurements)
BROAD_GROUPS = (("all_trials", "all"), ("undisturbed", "undisturbed"), ("disturbed", "disturbed"))


def _load(name):
    return json.loads((RESULTS / f"{name}.json").read_text())


def _table(header, rows):
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(out)


def _rpy(d, fmt="{:.2f}"):
    return " / ".join(fmt.format(d[a]) for a in ("roll", "pitch", "yaw"))


def _ms(delay):
    if delay is None:
        return "not found"
    if delay < 0:
        return f"{-delay:.2f} s before it happened"
    return f"{1e3 * delay:.0f} ms" if delay < 1 else f"{delay:.2f} s"


def results_diagnose() -> str:
    """docs/diagnose.md: each log diagnosed with the default model."""
    rows = []
    for name, log in _load("diagnose")["logs"].items():
        d, truth = log["variants"]["default"], log["truth"]
        failure = "none" if truth is None else f"motor {truth['motor']} at {truth['time_s']:.3f} s"
        found = ", ".join(f"motor {f['motor']} at {f['time_s']:.3f} s" for f in d["failures"]) or "nothing"
        if truth is not None and d["failures"]:
            found += f" ({_ms(d['delay_s'])} after)"
        top = max(log["motors"], key=lambda r: r["excess"])
        largest = f"motor {top['motor']}: {100 * top['excess']:+.1f} % ({top['output_excess']:+.0f} µs)"
        flagged = ", ".join(f"motor {x['motor']}" for x in d["damaged"]) or "none"
        rate = f"{log['imu_rate_hz']:.0f} / {log['output_rate_hz']:.0f} Hz"
        rows.append((name, rate, failure, found, largest, flagged))
    header = ("log", "IMU / outputs", "failure in the log (truth)", "found", "largest excess", "flagged")
    return _table(header, rows)


def results_diagnose_sweep() -> str:
    """docs/diagnose.md: the model's chosen values across their range, and its ablations."""
    res = _load("diagnose")
    losses = {n: log for n, log in res["logs"].items() if log["truth"] is not None}
    intact = [n for n, log in res["logs"].items() if log["truth"] is None]
    rows = []
    for variant in res["variants"]:
        cells = [variant]
        for log in losses.values():
            v = log["variants"][variant]
            cells.append(_ms(v["delay_s"]) + ("" if v["named"] or v["delay_s"] is None else " (wrong motor)"))
        false = [n for n in intact if res["logs"][n]["variants"][variant]["false_failures"]]
        cells.append(", ".join(false) or "none")
        rows.append(cells)
    header = ("variant", *(f"{n}: found after" for n in losses), "flights without a failure: false losses")
    return _table(header, rows)


def results_diagnose_synthetic() -> str:
    """docs/diagnose.md: the log mode on synthetic losses, with and without its significance test."""
    rows = []
    for r in _load("diagnose")["synthetic"]:
        found = [f for f in r["found"] if f is not None]
        early = [f for f in found if f[1] < 0]
        right = [f[1] for f in found if f[0] == 1 and f[1] >= 0]
        wrong = [f[1] for f in found if f[0] != 1 and f[1] >= 0]
        cells = [f"right motor {len(right)}" + (f" (median {_ms(sorted(right)[len(right) // 2])})" if right else "")]
        cells += [f"wrong motor {len(wrong)}" + (f" (after {_ms(min(wrong))} or more)" if wrong else "")]
        cells += [f"before the loss {len(early)}", f"none {len(r['found']) - len(found)}"]
        rows.append(
            (
                f"{r['gain_factor']:g}×",
                f"{r['gyro_noise']:g}",
                f"{r['deficit_sigmas']:g}",
                f"of {len(r['found'])}: " + ", ".join(cells),
                f"{r['false_losses']} of {r['flights']}",
            )
        )
    header = (
        "vehicle's gain / model's",
        "gyro noise (rad/s)",
        "deficit_sigmas",
        "a loss of motor 1",
        "60 s without a loss: false losses",
    )
    return _table(header, rows)


def results_overview() -> str:
    """README: BROAD groups, flights and speed per filter."""
    broad, flights, speed = _load("broad"), _load("flights"), _load("speed")
    g = broad["groups"]
    header = (
        ["filter"]
        + [f"BROAD {label} ({g[k]['_trials']})" for k, label in BROAD_GROUPS]
        + ["flights: roll / pitch / yaw RMS", "µs/sample batch", "streaming"]
    )
    rows = []
    for n in broad["filters"]:
        sp = speed["filters"].get(n)
        rows.append(
            [n]
            + [f"{g[k][n]['total_rmse_deg']:.2f}" for k, _ in BROAD_GROUPS]
            + [
                _rpy(flights["mean"][n]) if n in flights["mean"] else "-",
                f"{sp['batch_us']:.2f}" if sp else "-",
                f"{sp['stream_us']:.2f}" if sp and sp["stream_us"] is not None else "-",
            ]
        )
    return _table(header, rows)


def results_broad_summary() -> str:
    broad, flights = _load("broad"), _load("flights")
    g = broad["groups"]["all_trials"]
    header = (
        ["filter", f"all {g['_trials']} trials: total", "heading", "inclination"]
        + [f"{label} ({broad['groups'][k]['_trials']})" for k, label in BROAD_GROUPS[1:]]
        + ["flights roll / pitch / yaw"]
    )
    rows = [
        [n, f"{g[n]['total_rmse_deg']:.2f}", f"{g[n]['heading_rmse_deg']:.2f}", f"{g[n]['inclination_rmse_deg']:.2f}"]
        + [f"{broad['groups'][k][n]['total_rmse_deg']:.2f}" for k, _ in BROAD_GROUPS[1:]]
        + [_rpy(flights["mean"][n]) if n in flights["mean"] else "-"]
        for n in broad["filters"]
    ]
    return _table(header, rows)


def results_broad_trials() -> str:
    broad = _load("broad")
    names = broad["filters"]
    return _table(
        ["trial"] + names,
        [[t] + [f"{row[n]['total_rmse_deg']:.2f}" for n in names] for t, row in broad["trials"].items()],
    )


def results_flights() -> str:
    flights = _load("flights")
    names = flights["filters"]
    return _table(
        ["flight"] + names,
        [
            [f"{f} ({row['duration_s']:.0f} s)"] + [_rpy(row[n]["rms_deg"], "{:.1f}") for n in names]
            for f, row in flights["flights"].items()
        ],
    )


def results_speed() -> str:
    speed = _load("speed")
    rows = []
    for n, v in speed["filters"].items():
        target = SPEED_TARGET_US.get(n)
        met = (
            "-"
            if target is None
            else (f"{target:g}" + ("" if v["batch_us"] <= target else f" (missed by {v['batch_us'] - target:.2f})"))
        )
        stream = "-" if v["stream_us"] is None else f"{v['stream_us']:.2f}"
        rows.append([n, f"{v['batch_us']:.2f}", met, stream])
    rows.append(["recovery bank, 40 EKFs", f"{speed['recovery_bank_40_us']:.1f}", "20", "-"])
    if "detector_us" in speed:
        us, v = speed["detector_us"], speed.get("detector_vs_vqf")
        met = "1" + ("" if us <= 1.0 else f" (missed by {us - 1.0:.2f})")
        paired = f" ({v['median']:.3g} × vqf, paired)" if v else ""
        rows.append(["rotor-failure detector", f"{us:.2f}{paired}", met, "-"])
    return (
        _table(["filter", "batch", "batch target", "streaming"], rows)
        + f"\n\n{speed['samples']} simulated samples (docs/results/speed.json)."
    )


def results_speed_paired() -> str:
    """Each quadest filter against VQF, robust against every peer, robust-offline against robust
    and offline VQF: the paired ratios."""
    speed = _load("speed")

    def cell(r):
        return "-" if r is None else f"{r['median']:.3g} ({r['p10']:.3g}-{r['p90']:.3g})"

    rows = [
        [key, cell(r["batch"]), cell(r["stream"])]
        for key, r in speed["paired"].items()
        if key.endswith("/vqf")
        or key.startswith("robust/")
        or key in ("robust-offline/robust", "robust-offline/vqf-offline")
    ]
    pairs = next(iter(speed["paired"].values()))["batch"]["pairs"]
    return (
        _table(["filter / peer", "batch time ratio", "streaming time ratio"], rows)
        + f"\n\nMedian (10th-90th percentile) of {pairs} interleaved pairs on {speed['pair_samples']} samples;"
        " below 1 the quadest filter is faster (docs/results/speed.json)."
    )


AFCKF_NAMES = ["madgwick", "valenti", "roetenberg", "afckf"]


def _afckf_table(r, cases) -> str:
    """Our RMS per filter with the paper's in parentheses, one row per case and axis."""
    pub = r["published"]
    rows = []
    for case, label in cases:
        for a in ("roll", "pitch", "yaw"):
            p = pub.get(case, {}).get("rms_deg", {})
            rows.append(
                [f"{label}, {a}"]
                + [
                    f"{r['cases'][case][n]['rms_deg'][a]:.2f}" + (f" ({p[n][a]:.2f})" if n in p else "")
                    for n in AFCKF_NAMES
                ]
                + [f"{r['cases'][case][n]['rms_deg'][a]:.2f}" for n in _extra(r["cases"][case])]
            )
    return _table([""] + AFCKF_NAMES + [EXTRA_LABELS[n] for n in _extra(r["cases"][cases[0][0]])], rows)


EXTRA_LABELS = {"afckf-nocal": "afckf uncalibrated", "robust": "robust (quadest's own)"}


def _extra(results: dict) -> list:
    """The columns beyond the paper's filters a result has: the uncalibrated AFCKF, quadest's own."""
    return [n for n in EXTRA_LABELS if n in results]


def results_afckf() -> str:
    """README and docs/estimators.md: the flown reproduction, ours (paper's)."""
    r = _load("afckf")
    seeds = r["seeds"]
    return (
        _afckf_table(
            r,
            [
                ("damaged-rotor", "rotor loss from hover"),
                ("damaged-rotor-trajectory", "rotor loss on the circle"),
                ("nominal", "normal flight"),
            ],
        )
        + f"\n\nRMS error in degrees, the paper's in parentheses; from the loss on; mean over seeds "
        f"{seeds[0]}-{seeds[-1]} (`quadest reproduce afckf`, docs/results/afckf.json)."
    )


def results_afckf_flights() -> str:
    """docs/estimators.md: what the flown reproduction's flights made of the loss."""
    r = _load("afckf")
    rows = []
    for case, f in r["flights"].items():
        spin = "-" if f["spin_rate_rad_s"] is None else f"{f['spin_rate_rad_s']:.1f}"
        tilt = "-" if f["tilt_deg"] is None else f"{f['tilt_deg']:.1f}"
        rows.append([case, spin, tilt, f"{f['peak_rate_rad_s']:.1f}", f"{100 * f['gyro_clipped_share']:.2f} %"])
    p = r["params"]
    return (
        _table(
            ["case", "settled spin (rad/s)", "tilt (°)", "peak body rate (rad/s)", "gyro samples clipped (±1000°/s)"],
            rows,
        )
        + f"\n\nThe paper: 15.5 rad/s. A {p['vehicle']} loses rotor {p['rotor']} at {p['failure_s']:g} s "
        f"(docs/results/afckf.json)."
    )


def results_afckf_ablations() -> str:
    """README and docs/estimators.md: the ablation table."""
    r = _load("afckf")
    names = AFCKF_NAMES + _extra(r["ablations"][0])
    rows = [
        [row["change"]] + [" / ".join(f"{row[n][a]:.1f}" for a in ("roll", "pitch", "yaw")) for n in names]
        for row in r["ablations"]
    ]
    seeds = r["seeds"]
    return (
        _table(["one change", *AFCKF_NAMES, *(EXTRA_LABELS[n] for n in names[len(AFCKF_NAMES) :])], rows)
        + f"\n\nRoll / pitch / yaw RMS error in degrees from the loss on, the flown rotor loss from hover, mean "
        f"over seeds {seeds[0]}-{seeds[-1]} (`quadest reproduce afckf --ablations`, docs/results/afckf.json)."
    )


def results_afckf_in_loop() -> str:
    """docs/estimators.md: each estimator in the fault-tolerant controller's loop."""
    r = _load("afckf-in-loop")

    def f(v, fmt="{:.1f}"):
        return "-" if v is None else fmt.format(v)

    rows = [
        [
            row["variant"],
            row["estimator"],
            f"{row['survived']}/{row['runs']}",
            f"{row['settled']}/{row['runs']}",
            f(row["position_rms_settled_m"], "{:.2f}"),
            f(row["attitude_error_after_loss_deg"]),
            f(row["tilt_error_after_loss_deg"]),
            f(row["tilt_error_offline_deg"]),
        ]
        for row in r["table"]
    ]
    seeds = r["seeds"]
    return (
        _table(
            [
                "sensors",
                "in the loop",
                "stayed up",
                "settled",
                "position RMS settled (m)",
                "attitude error in the loop (°)",
                "tilt error in the loop (°)",
                "tilt error offline (°)",
            ],
            rows,
        )
        + f"\n\nA {r['params']['vehicle']} loses rotor {r['params']['rotor']} at {r['params']['failure_s']:g} s; "
        f"a run must stay up {r['after_loss_s']:g} s more; errors RMS after the loss, mean over the runs that "
        f"stayed up; offline: the same estimator over the truth's flight. Seeds {seeds[0]}-{seeds[-1]} "
        f"(`quadest reproduce afckf --in-loop`, docs/results/afckf-in-loop.json)."
    )


def _in_loop_cells(row: dict) -> list[str]:
    """An in-loop row's estimator, survival, tilt error, clipping share and clipped-rate error."""
    share, err = row.get("gyro_clipped_share"), row.get("clip_rate_error_rms_rad_s")
    return [
        row["estimator"],
        f"{row['survived']}/{row['runs']}",
        _f(row["tilt_error_after_loss_deg"]),
        "-" if share is None else f"{100 * share:.0f} %",
        "-" if err is None else " / ".join(_f(e, "{:.2f}") for e in err),
    ]


def _ftc_option(r: dict) -> str:
    """The reproduce command's ``--ftc`` option for a result flown with the default controller."""
    return " --ftc default" if r["params"].get("ftc") == "default" else ""


def _controller_text(r: dict) -> str:
    """Which fault-tolerant controller a reproduce result was flown with."""
    if r["params"].get("ftc") == "default":
        return "the default fault-tolerant controller (the level relaxed hover)"
    return "the former fault-tolerant controller (the tilted relaxed hover of the AFCKF reproduction)"


def results_clip_rate(name: str = "clip-rate") -> str:
    """docs/vehicle.md: the rate of a clipped gyroscope axis, flown in the loop (the ablation)."""
    r = _load(name)
    rows = []
    for row in r["table"]:
        cells = _in_loop_cells(row)
        rows.append([row["variant"], *cells[:2], f"{row['settled']}/{row['runs']}", *cells[2:]])
    seeds = r["seeds"]
    return (
        _table(
            [
                "gyroscope, rate of a clipped axis",
                "in the loop",
                "stayed up",
                "settled",
                "tilt error in the loop (°)",
                "samples clipped after the loss",
                "rate error on clipped samples, x / y / z (rad/s RMS)",
            ],
            rows,
        )
        + f"\n\nA {r['params']['vehicle']} loses rotor {r['params']['rotor']} at {r['params']['failure_s']:g} s "
        f"and must stay up {r['after_loss_s']:g} s more, flown by {_controller_text(r)}; errors after the loss, "
        f"mean over the runs that stayed up. Seeds {seeds[0]}-{seeds[-1]}; the predictor's values were chosen on "
        f"seeds 100-109 (`quadest reproduce afckf --in-loop --clipping{_ftc_option(r)} --seeds "
        f"{seeds[0]}-{seeds[-1]}`, docs/results/{name}.json)."
    )


def _nutation_cell(model: dict) -> str:
    """The relaxed hover's gyroscopic coupling of roll and pitch (results written before it: -)."""
    rates = model.get("nutation_rates_rad_s")
    return "-" if rates is None else " / ".join(f"{v:.1f}" for v in rates)


def results_spin_range(name: str = "spin-range") -> str:
    """docs/vehicle.md: the flown rotor loss at the ends of the Bebop 2's spin range."""
    r = _load(name)
    rows, loop = [], []
    for end, e in r["ends"].items():
        t, m, off = e["truth_flights"], e["relaxed_hover_model"], e["offline"]
        share = t["gyro_clipped_share"]
        rows.append(
            [
                end,
                f"{e['vehicle']['k_h']:.3g}",
                f"{e['vehicle']['rotor_inertia']:.3g}",
                f"{m['spin_rate_rad_s']:.1f} / {m['tilt_deg']:.1f}",
                _nutation_cell(m),
                f"{t['survived']}/{t['runs']}",
                "-" if t["spin_rate_rad_s"] is None else f"{t['spin_rate_rad_s']:.1f} / {t['tilt_deg']:.1f}",
                "-" if share is None else f"{100 * share:.0f} %",
                "-" if t["peak_rate_rad_s"] is None else f"{t['peak_rate_rad_s']:.1f}",
                *("-" if off is None else _rpy(off[n]["rms_deg"], "{:.1f}") for n in ("robust", "afckf", "madgwick")),
            ]
        )
        for row in e["in_loop"]:
            loop.append([end, row["variant"], *_in_loop_cells(row)])
    seeds = r["seeds"]
    cmd = (
        f"`quadest reproduce afckf --spin-range{_ftc_option(r)} --seeds {seeds[0]}-{seeds[-1]}`, "
        f"docs/results/{name}.json"
    )
    head = [
        "end",
        "k_h (N s²/m)",
        "I_p (kg m²)",
        "model: spin (rad/s) / tilt (°)",
        "model: coupling Λ_x / Λ_y (rad/s)",
        "truth up",
        "flown: spin / tilt",
        "clipped (±1000 °/s)",
        "peak rate (rad/s)",
        "robust, roll / pitch / yaw (° RMS)",
        "afckf",
        "madgwick",
    ]
    return (
        _table(head, rows)
        + "\n\n"
        + _table(
            [
                "end",
                "gyroscope (predicted rate on a clipped axis)",
                "in the loop",
                "stayed up",
                "tilt error in the loop (°)",
                "samples clipped after the loss",
                "rate error on clipped samples, x / y / z (rad/s RMS)",
            ],
            loop,
        )
        + f"\n\nA {r['params']['vehicle']} loses rotor {r['params']['rotor']} at {r['params']['failure_s']:g} s; "
        f"flown values are means over the truth's flights that stayed up (errors offline over them, from the loss "
        f"on); in the loop it must stay up {r['after_loss_s']:g} s more; flown by {_controller_text(r)}. "
        f"Seeds {seeds[0]}-{seeds[-1]} ({cmd})."
    )


def results_afckf_prescribed() -> str:
    """docs/estimators.md: the prescribed reproduction."""
    r = _load("afckf-prescribed")
    seeds = r["seeds"]
    return (
        _afckf_table(r, [("damaged-rotor", "damaged rotor"), ("nominal", "normal flight")])
        + f"\n\nRMS error in degrees, the paper's in parentheses; damaged rotor from the failure on; mean over "
        f"seeds {seeds[0]}-{seeds[-1]} (`quadest reproduce afckf --prescribed`, "
        f"docs/results/afckf-prescribed.json)."
    )


def results_split() -> str:
    """docs/estimators.md: BROAD split in halves, tuned on one and reported on the other."""
    rows = []
    for name in ("robust", "roetenberg", "vqf"):
        sp = _load(f"split-{name}")
        by = {f["held_out"]: f for f in sp["folds"]}
        grid = "its defaults (not tuned)" if sp["parameter_sets"] == 1 else f"{sp['parameter_sets']} sets"
        rows.append(
            [name, grid]
            + [
                f"{by[h]['held_out_mean']:.2f} (tuned on {by[h]['tuned_on']}: "
                f"{_params(by[h]['params'])}; {by[h]['tuned_mean']:.2f} there)"
                for h in "AB"
            ]
        )
    sp = _load("split-robust")
    from quadest.filters.robust import RobustParams

    d = RobustParams()
    row = next(
        r for r in sp["sets"] if all(math.isclose(getattr(d, k), v, rel_tol=1e-3) for k, v in r["params"].items())
    )
    rows.append(["robust, defaults", _params(row["params"]), f"{row['mean_A']:.2f}", f"{row['mean_B']:.2f}"])
    h = sp["halves"]
    return (
        _table(["filter", "grid", "held-out half A", "held-out half B"], rows)
        + f"\n\nBROAD total RMSE (°), mean over a half. A: {', '.join(t[:2] for t in h['A'])}; "
        f"B: {', '.join(t[:2] for t in h['B'])} (trial numbers). `quadest tune NAME --data ../shared/data/broad "
        "--split --grid ...` (docs/results/split-*.json; robust's grid: tau_mag 5-40 s x bias_motion_std "
        "0.05-0.8 °/s, tau_acc 4 s; the Kalman filter's: lin_acc x mag_noise x dist_tau_s)."
    )


def _params(p: dict) -> str:
    if not p:
        return "defaults"
    deg = {"bias_motion_std"}
    return ", ".join(f"{k} {math.degrees(v):.2g} °/s" if k in deg else f"{k} {v:g}" for k, v in p.items())


def _flights_ahead(flights: dict, ours: str, theirs: str) -> int:
    """Flights on which ``ours`` is at or below ``theirs`` in roll, pitch and heading alike."""
    return sum(
        all(f[ours]["rms_deg"][a] <= f[theirs]["rms_deg"][a] for a in ("roll", "pitch", "yaw"))
        for f in flights["flights"].values()
    )


def _at_most(ours: dict, theirs: dict, keys) -> bool:
    return all(ours[k] <= theirs[k] for k in keys)


def _against(res: dict, case: str, other: str) -> tuple:
    """robust's roll / pitch / yaw in a reproduction's ``case`` against ``other``'s: the two cells,
    and whether robust is at most ``other`` in all three."""
    ours, theirs = res["cases"][case]["robust"]["rms_deg"], res["cases"][case][other]["rms_deg"]
    return _rpy(ours), f"{other} {_rpy(theirs)}", _at_most(ours, theirs, ours)


def results_robust_everywhere() -> str:
    """docs/estimators.md: robust on every axis and robust-offline, the targets measured."""
    broad, flights, speed = _load("broad"), _load("flights"), _load("speed")
    pres, flown = _load("afckf-prescribed-seeds-21-40"), _load("afckf-seeds-21-40")
    rows = []

    def row(what, ours, theirs, met):
        rows.append([what, ours, theirs, "yes" if met else "**no**"])

    cols, rpy = ("all_trials", "undisturbed", "disturbed"), ("roll", "pitch", "yaw")
    g = broad["groups"]
    for ours, theirs in (("robust", "vqf"), ("robust-offline", "vqf-offline")):
        o, t = ({c: g[c][n]["total_rmse_deg"] for c in cols} for n in (ours, theirs))
        row(
            f"BROAD, 12 trials, all / undisturbed / disturbed: {ours}",
            " / ".join(f"{o[c]:.3f}" for c in cols),
            f"{theirs} " + " / ".join(f"{t[c]:.3f}" for c in cols),
            _at_most(o, t, cols),
        )
    sr, sv = _load("split-robust"), _load("split-vqf")
    held = {f["held_out"]: f["held_out_mean"] for f in sr["folds"]}
    vheld = {f["held_out"]: f["held_out_mean"] for f in sv["folds"]}
    row(
        "BROAD split, held-out halves A / B: robust",
        " / ".join(f"{held[h]:.2f}" for h in sorted(held)),
        "vqf " + " / ".join(f"{vheld[h]:.2f}" for h in sorted(held)),
        _at_most(held, vheld, held),
    )
    fm = flights["mean"]
    for ours, theirs in (("robust", "vqf"), ("robust-offline", "vqf-offline")):
        row(
            f"flights, mean roll / pitch / 6-axis heading: {ours}",
            _rpy(fm[ours]),
            f"{theirs} {_rpy(fm[theirs])}",
            _at_most(fm[ours], fm[theirs], rpy),
        )
    ahead = _flights_ahead(flights, "robust", "vqf")
    row(
        "flights, flight by flight ≤ VQF in roll, pitch and heading: robust",
        f"{ahead} of {len(flights['flights'])}",
        "target 4 of 5",
        ahead >= 4,
    )
    for what, ours, theirs, band in (
        ("BROAD (3 dof)", g["all_trials"]["robust-offline"]["nees"], g["all_trials"]["robust"]["nees"], (1.5, 4.5)),
        # without a magnetometer the heading's part is nil: the tilt's 2 dof, the band scaled to them
        ("flights, the tilt's part (2 dof)", fm["robust-offline"]["nees_tilt"], fm["robust"]["nees_tilt"], (1.0, 3.0)),
    ):
        row(
            f"mean NEES of robust-offline's covariance, {what}",
            f"{ours:.2f}",
            f"{band[0]:g}-{band[1]:g} (robust's {theirs:.2f})",
            band[0] <= ours <= band[1],
        )
    for label, res, case, other in (
        ("simulator seeds 21-40, normal flight, prescribed", pres, "nominal", "roetenberg"),
        ("simulator seeds 21-40, normal flight (the circle), flown", flown, "nominal", "roetenberg"),
        ("simulator seeds 21-40, the rotor loss, flown", flown, "damaged-rotor", "afckf"),
    ):
        row(f"{label}: robust", *_against(res, case, other))
    pair = speed["paired"]
    for key, mode, limit in (
        ("robust/vqf", "batch", 1.0),
        ("robust/vqf", "stream", 1.0),
        ("robust-offline/robust", "batch", 3.0),
    ):
        r = pair[key][mode]
        row(
            f"time, {key}, {'streaming' if mode == 'stream' else mode} (median of paired ratios)",
            f"{r['median']:.2f} ({r['p10']:.2f}-{r['p90']:.2f})",
            f"≤ {limit:g}",
            r["median"] <= limit,
        )
    return (
        _table(["target", "ours", "against", "met"], rows)
        + "\n\nBROAD and the flights from one run beside the peers (docs/results/broad.json, flights.json; "
        "BROAD's own metric, the flights 6-axis with the heading offset removed; the NEES on the estimate "
        "as scored); the halves from split-*.json; the simulator from seeds no default was chosen on "
        "(afckf-prescribed-seeds-21-40.json; afckf-seeds-21-40.json, the loss scored from the loss on), "
        "against the filters the targets name; the time ratios from interleaved pairs (speed.json). "
        "Roll / pitch / yaw RMS (°)."
    )


def results_robust_targets() -> str:
    """docs/estimators.md and README: robust's targets, measured."""
    broad, flights, repo, speed = _load("broad"), _load("flights"), _load("repoimu"), _load("speed")
    pres, flown, loop = _load("afckf-prescribed"), _load("afckf"), _load("afckf-in-loop")
    rows = []

    def row(what, ours, theirs, met):
        rows.append([what, ours, theirs, "yes" if met else "**no**"])

    b = broad["groups"]["all_trials"]
    row(
        "BROAD, 12 trials, total RMSE (in-sample for two parameters)",
        f"{b['robust']['total_rmse_deg']:.2f}",
        f"VQF {b['vqf']['total_rmse_deg']:.2f}",
        b["robust"]["total_rmse_deg"] <= b["vqf"]["total_rmse_deg"],
    )
    sr, sv = _load("split-robust"), _load("split-vqf")
    for f in sr["folds"]:
        v = next(g for g in sv["folds"] if g["held_out"] == f["held_out"])
        row(
            f"BROAD split, held-out half {f['held_out']}",
            f"{f['held_out_mean']:.2f}",
            f"VQF {v['held_out_mean']:.2f}",
            f["held_out_mean"] <= v["held_out_mean"],
        )
    fm = flights["mean"]
    row(
        "flights (DIDO, Blackbird), roll / pitch RMS",
        f"{fm['robust']['roll']:.2f} / {fm['robust']['pitch']:.2f}",
        f"VQF {fm['vqf']['roll']:.2f} / {fm['vqf']['pitch']:.2f}",
        _at_most(fm["robust"], fm["vqf"], ("roll", "pitch")),
    )
    ahead = _flights_ahead(flights, "robust", "vqf")
    row(
        "flights, flight by flight ≤ VQF in roll, pitch and 6-axis heading",
        f"{ahead} of {len(flights['flights'])}",
        "target 4 of 5",
        ahead >= 4,
    )
    rm = repo["mean"]
    row(
        "RepoIMU, roll / pitch / yaw, total",
        f"{_rpy(rm['robust'])}, {rm['robust']['total_rmse_deg']:.2f}",
        f"VQF {_rpy(rm['vqf'])}, {rm['vqf']['total_rmse_deg']:.2f}",
        _at_most(rm["robust"], rm["vqf"], ("roll", "pitch", "yaw", "total_rmse_deg")),
    )

    def sim_row(label, res, case, other):
        row(label, *_against(res, case, other))

    sim_row("damaged rotor, prescribed (gyro clips at ±1000 °/s in the spin)", pres, "damaged-rotor", "afckf")
    sim_row("damaged rotor, flown", flown, "damaged-rotor", "afckf")
    clip = next(r for r in flown["ablations"] if r["change"].startswith("gyro range ±500"))
    row(
        "damaged rotor, flown, gyro ±500 °/s (clipping)",
        _rpy(clip["robust"]),
        f"afckf {_rpy(clip['afckf'])}",
        _at_most(clip["robust"], clip["afckf"], ("roll", "pitch", "yaw")),
    )
    sim_row("nominal flight, prescribed", pres, "nominal", "roetenberg")
    sim_row("nominal flight (the circle), flown", flown, "nominal", "roetenberg")
    for variant in dict.fromkeys(r["variant"] for r in loop["table"]):
        up = {r["estimator"]: r for r in loop["table"] if r["variant"] == variant}
        if "robust" in up:
            row(
                f"in the loop, {variant}: stayed up",
                f"{up['robust']['survived']}/{up['robust']['runs']}",
                f"afckf {up['afckf']['survived']}/{up['afckf']['runs']}",
                up["robust"]["survived"] >= up["afckf"]["survived"],
            )
    ne = [pres["cases"][c]["robust"]["nees"] for c in ("damaged-rotor", "nominal")]
    row(
        "mean NEES, prescribed damaged rotor / nominal (3 dof)",
        " / ".join(f"{v:.2f}" for v in ne),
        "1.5-4.5",
        all(1.5 <= v <= 4.5 for v in ne),
    )
    sp = speed["filters"]
    row(
        "batch µs/sample",
        f"{sp['robust']['batch_us']:.2f}",
        f"VQF {sp['vqf']['batch_us']:.2f}",
        sp["robust"]["batch_us"] <= sp["vqf"]["batch_us"],
    )
    row("streaming µs/call", f"{sp['robust']['stream_us']:.2f}", "1.5", sp["robust"]["stream_us"] <= 1.5)
    return (
        _table(["target", "robust", "against", "met"], rows)
        + "\n\nSimulator figures: roll / pitch / yaw RMS (°), seeds 1-5, from the loss on (docs/results/"
        "afckf*.json); real data: docs/results/broad.json, flights.json, repoimu.json, split-*.json; speed "
        "in one run, docs/results/speed.json."
    )


def _tradeoff_rows(mode: dict, label: str) -> list[list[str]]:
    rows = []
    for r in mode[label]:
        d = r["delay_ms"]
        marks = [m for m, h in (("default", _default(mode)), ("the rule's", mode["chosen"])) if r["threshold"] == h]
        h = f"**{r['threshold']:g}** ({', '.join(marks)})" if marks else f"{r['threshold']:g}"
        rows.append(
            [label, h, f"{r['found']}/{r['complete']}", str(r["isolated"])]
            + [_f(d[k], "{:.0f} ms" if k == "median" else "{:.0f}") for k in ("median", "p90", "p99", "max")]
            + [f"{r['nominal_alarms']} in {r['nominal_hours']:.1f} h", str(r["alarms_before_failure"])]
        )
    return rows


def _default(mode: dict) -> float:
    """The detector's default threshold when the run was made (files before it was written: the rule's)."""
    return mode.get("default", mode["chosen"])


def _smallest_quiet(rows: list[dict]) -> float | None:
    """The rule's choice on one set: the smallest threshold without an alarm, nominal or early."""
    quiet = [r["threshold"] for r in rows if r["nominal_alarms"] == 0 and r["alarms_before_failure"] == 0]
    return min(quiet) if quiet else None


def results_detection_tradeoff() -> str:
    """The 'lost' test's threshold against delay and false alarms, with rotor speeds, both sets,
    and the rule applied the other way round (docs/results/detection-tradeoff.json)."""
    modes = _load("detection-tradeoff")["modes"]
    m = modes["rotor-speeds"]
    rows = _tradeoff_rows(m, "train") + _tradeoff_rows(m, "test")
    header = ["set", "threshold h (deficit-s)", "complete losses found", "named", "median", "p90", "p99", "max",
              "alarms in nominal flight", "alarms before a failure"]  # fmt: skip
    lines = [_table(header, rows), ""]
    for name, mode in modes.items():
        back = _smallest_quiet(mode["test"])
        at = next((r for r in mode["train"] if r["threshold"] == back), None)
        lines.append(
            f"- {name}: chosen on the training seeds {mode['chosen']:g}; chosen the other way round (on the "
            f"test seeds) {back:g}, which on the training seeds finds {at['found']}/{at['complete']}, median "
            f"{_f(at['delay_ms']['median'], '{:.0f}')} ms, p99 {_f(at['delay_ms']['p99'], '{:.0f}')} ms, "
            f"{at['nominal_alarms']} nominal alarms."
        )
    return "\n".join(lines)


SCENARIO_LABELS = {"hover": "hover (disturbed start)", "trajectory": "1 m circle",
                   "aggressive": "figure eight (7-12 m/s², 5-8 rad/s)"}  # fmt: skip


def _delays_ms(runs: list[dict], key: str) -> list[float]:
    """The delays of the complete losses found at threshold ``key`` (ms)."""
    hits = [r["first"][key] for r in runs if r["rotor"] is not None and r["efficiency"] == 0.0]
    times = [r["time_s"] for r in runs if r["rotor"] is not None and r["efficiency"] == 0.0]
    return [1e3 * (h[0] - t) for h, t in zip(hits, times) if h and h[0] >= t]


def results_detection_scenarios() -> str:
    """The default threshold's delays by scenario on the test seeds, rotor speeds."""
    m = _load("detection-tradeoff")["modes"]["rotor-speeds"]
    rows = []
    for name, label in SCENARIO_LABELS.items():
        runs = [r for r in m["test_runs"] if r["scenario"] == name]
        complete = sum(r["rotor"] is not None and r["efficiency"] == 0.0 for r in runs)
        d = _delays_ms(runs, str(_default(m)))
        q = np.percentile(d, [50, 99]) if d else [None, None]
        cells = [_f(v, "{:.0f} ms") for v in (q[0], q[1], max(d, default=None))]
        rows.append([label, f"{len(d)}/{complete}", *cells])
    return _table(["scenario", "found", "median", "p99", "max"], rows)


def results_spin_summary() -> str:
    """README: the flown spin after the loss and where it sits in the range from sources
    (docs/results/afckf.json, spin-range.json)."""
    flown = _load("afckf")
    f, seeds = flown["flights"]["damaged-rotor"], flown["seeds"]
    ends = _load("spin-range")["ends"]

    def end_text(name: str) -> str:
        e, t = ends[name], ends[name]["truth_flights"]
        v = f"k_h {e['vehicle']['k_h']:.3g}, I_p {e['vehicle']['rotor_inertia']:.3g}"
        up = f"{t['survived']}/{t['runs']} up with the true state in the loop"
        if t["spin_rate_rad_s"] is None:
            return (
                f"the {name} end ({v}) is not held by the former fault-tolerant controller, the reproduction's ({up})"
            )
        return f"the {name} end ({v}) spins at {t['spin_rate_rad_s']:.1f} rad/s ({up})"

    return (
        f"The flown Bebop 2 (seeds {seeds[0]}-{seeds[-1]}, the chosen values of its spin range) settles into a spin of "
        f"{f['spin_rate_rad_s']:.1f} rad/s (the paper's: 15.5 rad/s) with its thrust axis {f['tilt_deg']:.0f}° off the "
        f"vertical; the loss's transient peaks at {f['peak_rate_rad_s']:.0f} rad/s, so its ±1000°/s gyroscope clips on "
        f"{100 * f['gyro_clipped_share']:.1f} % of the samples after the loss. Across the range from sources "
        f"([docs/vehicle.md](vehicle.md#spin-range), `quadest reproduce afckf --spin-range`): "
        f"{end_text('low')}; {end_text('high')}. {_default_ftc_ends()}"
    )


def _default_ftc_ends() -> str:
    """README: what the default fault-tolerant controller keeps up at each end of the spin range
    with ``robust`` in the loop (docs/results/spin-range-default.json)."""
    ends = _load("spin-range-default")["ends"]

    def up(e, variant):
        (row,) = [r for r in e["in_loop"] if r["variant"] == variant and r["estimator"] == "robust"]
        return f"{row['survived']}/{row['runs']}"

    cells = [f"{name} {up(e, 'gyro ±1000°/s')} (±500 °/s: {up(e, 'gyro ±500°/s')})" for name, e in ends.items()]
    return (
        "The default fault-tolerant controller (the level relaxed hover) with `robust` in the loop and a "
        f"±1000 °/s gyroscope keeps up {', '.join(cells)} (`quadest reproduce afckf --spin-range --ftc default`)."
    )


def results_campaign() -> str:
    """The survival campaign's table (docs/results/campaign.json: quadest campaign --json)."""
    r = _load("campaign")
    rows = []
    for g in r["groups"]:
        f, n, d = g["failures"], g["nominal"], g["failures"]["delay_ms"]
        p = f["partial"]
        oracle = g["detection"] == "oracle"
        gyro = "none" if math.isinf(g["gyro_range_dps"]) else f"±{g['gyro_range_dps']:.0f}"
        share = (
            f"{f['survived']}/{f['complete']} ({100.0 * f['survived'] / f['complete']:.1f} %)" if f["complete"] else "-"
        )
        rows.append(
            [
                g["filter"],
                g["detection"] + (" (told 50 ms after: an oracle)" if oracle else ""),
                gyro,
                share,
                "-" if oracle else f"{f['found']} / {f['isolated']}",
                "-" if oracle else " / ".join(_f(d[k], "{:.0f}") for k in ("median", "p90", "p99", "max")),
                "-"
                if oracle or not p["flights"]
                else f"{p['isolated']}/{p['flights']}, {_f(p['effectiveness_error_median'], '{:.3f}')}",
                "-" if oracle else f"{n['lost_alarms']} in {n['hours']:.1f} h",
            ]
        )
    header = ["estimator", "detection", "gyro (°/s)", "complete losses up", "found / named",
              "delay ms (median / p90 / p99 / max)", "partial: named, effectiveness error",
              "false alarms (nominal)"]  # fmt: skip
    return _table(header, rows)


def divergence_params() -> str:
    from quadest.recovery.divergence import DivergenceParams

    return _param_rows(DivergenceParams.describe())


def collision_params() -> str:
    from quadest.flight.collision import CollisionParams

    return _param_rows(CollisionParams.describe())


def _med(d, fmt="{:.2f}", scale=1.0):
    return "-" if d["median"] is None else f"{fmt.format(scale * d['median'])} / {fmt.format(scale * d['p90'])}"


def results_collisions() -> str:
    """docs/recovery.md: collisions in flight recovered, each check alone and none, and nominal flights."""
    r = _load("collisions")
    rows = []
    for name, st in r["cases"].items():
        n, fates = st["collisions"], st["by_estimator"]
        first = ", ".join(f"{c} {k}" for c, k in st["first_by_check"].items() if k) or "-"
        rows.append(
            [
                name,
                f"{st['recovered']}/{n} ({100 * st['recovered'] / max(n, 1):.0f} %)",
                str(st["crashed"]),
                f"{st['detected']}/{n} ({first})",
                _med(st["divergence_delay_s"], "{:.0f}", 1e3),
                _med(st["handover_s"]),
                _med(st["gravity_error_deg"], "{:.1f}"),
                _med(st["fall_m"]),
                f"{fates['reset']['recovered']}/{fates['reset']['collisions']}",
                f"{fates['left']['recovered']}/{fates['left']['collisions']}",
            ]
        )
    nom = r["nominal"]
    peaks = "; ".join(f"{sc} " + ", ".join(f"{c} {v:.2f}" for c, v in p.items()) for sc, p in nom["peak_ratio"].items())
    return (
        _table(
            [
                "checks",
                "recovered to hover",
                "crashed",
                "recovery started (first by)",
                "delay (ms, median / p90)",
                "handover after the collision (s, median / p90)",
                "gravity error at the handover (°, median / p90)",
                "fall (m, median / p90)",
                "reset: recovered",
                "left: recovered",
            ],
            rows,
        )
        + f"\n\n{r['cases']['all checks']['collisions']} collisions (seeds {r['seeds'][0]}-{r['seeds'][1]}), "
        f"{r['estimator']} in the loop, each row the same collisions. Nominal flights with every check on "
        f"(seeds {r['nominal_seeds'][0]}-{r['nominal_seeds'][1]}, {r['nominal_s']:g} s each, hover, circle and "
        f"figure eight in turn): {nom['flights']} flights, {nom['hours']:.1f} h, recovery started in "
        f"{nom['recovery_started']}, survived {nom['survived']}; the largest statistic over its threshold: {peaks} "
        "(`quadest benchmark collisions --seeds 1-100 --nominal-seeds 1-600 --json ...`, docs/results/collisions.json)."
    )


def results_campaign_height() -> str:
    """The complete losses that would have stayed up at each height of the hover point, from one
    campaign flown high (docs/results/campaign-height.json: quadest campaign --height 30 --json)."""
    r = _load("campaign-height")
    groups = [g for g in r["groups"] if len(g["up_by_height"]["x"]) > 1]
    heights = groups[0]["up_by_height"]["x"]
    assert all(g["up_by_height"]["x"] == heights for g in groups), "campaign-height.json: one flown height"
    rows = []
    for g in groups:
        up = g["up_by_height"]
        n = up["flights"][0]
        oracle = " (told 50 ms after: an oracle)" if g["detection"] == "oracle" else ""
        cells = [f"{k} ({100.0 * k / n:.1f} %)" for k in up["survived"]]
        rows.append([g["filter"], g["detection"] + oracle, n, *cells])
    header = ["estimator", "detection", "complete losses", *(f"up at {h:g} m" for h in heights)]
    return _table(header, rows)


GENERATORS = {
    "results-campaign": results_campaign,
    "results-campaign-height": results_campaign_height,
    "results-detection-tradeoff": results_detection_tradeoff,
    "results-spin-summary": results_spin_summary,
    "results-detection-scenarios": results_detection_scenarios,
    "divergence-params": divergence_params,
    "collision-params": collision_params,
    "results-collisions": results_collisions,
    "results-speed-paired": results_speed_paired,
    "simulator-params": simulator_params,
    "estimator-params": estimator_params,
    "recovery-params": recovery_params,
    "vehicle-params": vehicle_params,
    "vehicle-presets": vehicle_presets,
    "ftc-params": ftc_params,
    "flight-params": flight_params,
    "rate-params": rate_params,
    "throw-params": throw_params,
    "results-flight": results_flight,
    "results-throw": results_throw,
    "results-sim": results_sim,
    "results-crosscheck": results_crosscheck,
    "results-overview": results_overview,
    "results-broad-summary": results_broad_summary,
    "results-broad-trials": results_broad_trials,
    "results-flights": results_flights,
    "results-speed": results_speed,
    "results-afckf": results_afckf,
    "results-afckf-flights": results_afckf_flights,
    "results-afckf-ablations": results_afckf_ablations,
    "results-afckf-prescribed": results_afckf_prescribed,
    "results-afckf-in-loop": results_afckf_in_loop,
    "results-clip-rate": results_clip_rate,
    "results-clip-rate-default": lambda: results_clip_rate("clip-rate-default"),
    "results-spin-range": results_spin_range,
    "results-spin-range-default": lambda: results_spin_range("spin-range-default"),
    "results-recovery-flown": results_recovery_flown,
    "results-recovery-ablations": results_recovery_ablations,
    "results-repoimu": results_repoimu,
    "results-split": results_split,
    "results-robust-targets": results_robust_targets,
    "results-robust-everywhere": results_robust_everywhere,
    "results-diagnose": results_diagnose,
    "results-diagnose-sweep": results_diagnose_sweep,
    "results-diagnose-synthetic": results_diagnose_synthetic,
}
PATTERN = re.compile(r"(<!-- generated:([a-z-]+) -->\n)(.*?)(<!-- /generated -->)", re.S)


def render(text: str) -> str:
    return PATTERN.sub(lambda m: m.group(1) + GENERATORS[m.group(2)]() + "\n" + m.group(4), text)


def main(check: bool = False) -> int:
    stale = []
    for path in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        text = path.read_text()
        new = render(text)
        if new != text:
            stale.append(path.name)
            if not check:
                path.write_text(new)
    if check and stale:
        print("out of date: " + ", ".join(stale) + " (run python tools/update_docs.py)")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(check="--check" in sys.argv))
