"""How well the rotor-failure detector does in the loop (``quadest benchmark detection``;
docs/detection.md): flown failures (a random rotor at a random time, complete or partial, from a
hover, on a circle or on a figure eight) for the detection delay, the isolation and the survival, and flown
nominal flights for the false alarms, each with the detector's model of the vehicle off by
the flight's drawn errors. Every case follows from its seed, so that thresholds are chosen on
one set of seeds and reported on another."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from quadest.detect import DetectorParams
from quadest.evaluation.parallel import execute
from quadest.flight import Flight, FlightParams, fly
from quadest.sim import build_config
from quadest.sim.faults import Failure
from quadest.sim.params import SimConfig
from quadest.sim.wind import WindParams

SCENARIOS = ("hover", "trajectory", "aggressive")


PRESET = "bebop2"
"""The sensors' preset the cases start from; each flight scales its noise, biases and vibration."""


def failure_case(seed: int, mode: str, duration: float = 6.0, *, disturbed: bool = True) -> dict:
    """The failure flown for ``seed``: the scenario in turn (hover from a disturbed start, the
    circle, the figure eight), a random rotor at a random time
    between 2 and 4 s; complete for three seeds in four, else left at 0-70 % effectiveness; with
    ``disturbed`` the flight's wind and sensors drawn from the seed (:func:`disturbances`)."""
    rng = np.random.default_rng([int(seed), 31])
    partial = seed % 4 == 3
    return {
        "seed": int(seed),
        "mode": mode,
        "scenario": SCENARIOS[seed % len(SCENARIOS)],
        "rotor": int(rng.integers(4)),
        "time_s": float(rng.uniform(2.0, 4.0)),
        "efficiency": float(rng.uniform(0.0, 0.7)) if partial else 0.0,
        "duration": duration,
        **(disturbances(seed, duration, landing=False) if disturbed else {}),
    }


def nominal_case(seed: int, mode: str, duration: float, *, disturbed: bool = True) -> dict:
    """The nominal flight flown for ``seed``: the scenarios in turn, no failure; with
    ``disturbed`` its wind and sensors drawn from the seed, and a hard landing at its end
    (:func:`disturbances`)."""
    return {"seed": int(seed), "mode": mode, "scenario": SCENARIOS[seed % len(SCENARIOS)], "rotor": None,
            "duration": duration, **(disturbances(seed, duration, landing=True) if disturbed else {})}  # fmt: skip


def disturbances(seed: int, duration: float, *, landing: bool) -> dict:
    """What a flight meets besides its scenario, drawn from its seed (docs/detection.md):

    - ``wind``: steady 0-5 m/s, turbulence 0-1.5 m/s, one discrete gust per 20 s (at least one)
      of up to 6 m/s (:class:`~quadest.sim.wind.WindParams`);
    - ``sensors``: the preset's gyroscope and accelerometer noise, each scaled by 0.5-2, their
      constant biases' spread by 0.5-3, the accelerometer's rotor tone by 0.5-2, and a gyroscope
      tone of 0.15-0.3 rad/s per m/s² of it on roll and pitch, 0.02-0.04 on yaw (real flights of
      the DIDO dataset show 0.16-0.30 and 0.03: docs/detection.md);
    - ``landing_m_s``: with ``landing``, the flight ends with a touchdown at 1-2 m/s (a flight
      shorter than :data:`LANDING_ROOM_S` without one: no room to stop and descend)."""
    rng = np.random.default_rng([int(seed), 41])
    acc_tone = float(rng.uniform(0.5, 2.0))
    out = {
        "wind": {
            "mean_m_s": float(rng.uniform(0.0, 5.0)),
            "turbulence_m_s": float(rng.uniform(0.0, 1.5)),
            "gusts": max(1, int(duration // 20)),
            "gust_m_s": 6.0,
        },
        "sensors": {
            "gyro_noise": float(rng.uniform(0.5, 2.0)),
            "acc_noise": float(rng.uniform(0.5, 2.0)),
            "gyro_bias": float(rng.uniform(0.5, 3.0)),
            "acc_bias": float(rng.uniform(0.5, 3.0)),
            "acc_tone": acc_tone,
            "gyro_tone_rad_s_per_m_s2": [
                float(rng.uniform(0.15, 0.3)),
                float(rng.uniform(0.15, 0.3)),
                float(rng.uniform(0.02, 0.04)),
            ],  # fmt: skip
        },
    }
    speed = float(rng.uniform(1.0, 2.0)) if landing else None
    if speed is not None and duration >= LANDING_ROOM_S:
        out["landing_m_s"] = speed
    return out


LANDING_ROOM_S = 8.0
"""s: the shortest nominal flight that ends in a landing (a stop of 1-2 s, 3 m down at 1 m/s
and the second on the ground; shorter ones would be a usage error of the landing)."""


def case_config(case: dict, overrides: dict | None = None) -> SimConfig:
    """The sensors of a case: the preset's (with ``overrides``), scaled as the case's ``sensors`` say."""
    cfg = build_config(PRESET, overrides)
    f = case.get("sensors")
    if f is None:
        return cfg
    acc_tone = tuple(v * f["acc_tone"] for v in cfg.acc.vibration_amp)
    gyro_tone = tuple(a * r for a, r in zip(acc_tone, f["gyro_tone_rad_s_per_m_s2"]))
    g, a = cfg.gyro, cfg.acc
    gyro = replace(g, noise_std=g.noise_std * f["gyro_noise"], bias_std=g.bias_std * f["gyro_bias"])
    acc = replace(a, noise_std=a.noise_std * f["acc_noise"], bias_std=a.bias_std * f["acc_bias"])
    gyro, acc = replace(gyro, vibration_amp=gyro_tone), replace(acc, vibration_amp=acc_tone)
    return replace(cfg, gyro=gyro, acc=acc)


def case_flight_kwargs(case: dict, overrides: dict | None = None) -> dict:
    """What :func:`~quadest.flight.fly` takes for a case's disturbances (its sensors' parameters
    changed by ``overrides`` first)."""
    wind = case.get("wind")
    given = {k: case[k] for k in ("landing_m_s", "landing_accel_m_s2", "land_detector", "height_m") if k in case}
    params = FlightParams(wind=None if wind is None else WindParams(**wind), **given)
    return {"config": case_config(case, overrides), "params": params}


def case_failure(case: dict) -> Failure | None:
    """The case's rotor failure (None for a nominal flight); its mode, when not the one its
    numbers imply, under ``failure_mode`` (a case's ``mode`` is how the loss is learnt)."""
    if case.get("rotor") is None:
        return None
    return Failure(
        rotor=case["rotor"],
        time_s=case["time_s"],
        efficiency=case["efficiency"],
        imbalance=case.get("imbalance") or 0.0,
        mode=case.get("failure_mode"),
    )


def complete_loss(case: dict) -> bool:
    """Whether a case (or a row of one) is a complete rotor loss, asked of its failure."""
    failure = case_failure(case)
    return failure is not None and failure.complete


def fly_case(case: dict, detector: DetectorParams | None = None, estimator: str = "truth") -> dict:
    """Fly one failure (``efficiency`` > 0: the SE(3) controller flies on) or one nominal flight
    (``rotor`` None) with the detector and ``estimator`` in the loop; the flight's summary with
    the case."""
    f = fly_case_flight(case, detector, estimator)
    return {**case, "status": f.summary["status"], **f.summary.get("detection", {}), "flown_s": f.summary["flown_s"]}


def fly_case_flight(
    case: dict, detector: DetectorParams | None = None, estimator: str = "truth", overrides: dict | None = None,
    truth: str | None = None,
) -> Flight:  # fmt: skip
    """The flight of :func:`fly_case`, its sensors' parameters changed by ``overrides``
    (``{"gyro.range": 8.73}``) before the case's own draws; ``truth``: the vehicle that flies
    apart from the model (:attr:`~quadest.flight.spec.FlightSpec.truth`; None: the model)."""
    failure = case_failure(case)
    controller = "ftc" if failure is not None and failure.complete else "se3"
    return fly(
        case["scenario"],
        seed=case["seed"],
        duration=case["duration"],
        vehicle="bebop2",
        failure=failure,
        controller=controller,
        estimator=estimator,
        detection=_detection(case["mode"], detector),
        truth=truth,
        **case_flight_kwargs(case, overrides),
    )


def _detection(mode: str, detector: DetectorParams | None):
    """What :func:`~quadest.flight.fly` takes: the mode, or the parameters with that mode."""
    if mode == "oracle" or detector is None:
        return mode
    return replace(detector, rotor_speeds=mode == "rotor-speeds")


def survival_by_scenario(rows: list[dict]) -> dict:
    """``{mode: {scenario: [survived, flights]}}`` over the complete losses."""
    out: dict = {}
    for r in rows:
        if complete_loss(r):
            cell = out.setdefault(r["mode"], {}).setdefault(r["scenario"], [0, 0])
            cell[0] += r["status"] == "survived"
            cell[1] += 1
    return out


def percentile(values, q: float) -> float | None:
    v = np.asarray([x for x in values if x is not None], float)
    return float(np.percentile(v, q)) if len(v) else None


def summarize_failures(rows: list[dict]) -> dict:
    """Detection delay (median, p90, p99, max), isolation, misses and survival over complete
    losses; delay, isolation and the effectiveness found over partial ones."""
    complete = [r for r in rows if complete_loss(r)]
    partial = [r for r in rows if not complete_loss(r)]
    delays = [r["delay_s"] for r in complete if r["delay_s"] is not None]
    out = {
        "complete": len(complete),
        "found": len(delays),
        "isolated": sum(bool(r["isolated"]) for r in complete),
        "false_alarms": sum(bool(r["false_alarm"]) for r in rows),
        "survived": sum(r["status"] == "survived" for r in complete),
        "delay_ms": {q: _ms(percentile(delays, p)) for q, p in (("median", 50), ("p90", 90), ("p99", 99))},
    }
    out["delay_ms"]["max"] = _ms(max(delays)) if delays else None
    found = [r for r in partial if r["damaged_rotor"] is not None or r["lost_rotor"] is not None]
    damaged = [r for r in partial if r["damaged_rotor"] == r["rotor"] and r["damaged_s"] is not None]
    out["partial"] = {
        "flights": len(partial),
        "found": len(found),
        "isolated": len(damaged),
        "delay_ms_median": _ms(percentile([r["damaged_s"] - r["time_s"] for r in damaged], 50)),
        "effectiveness_error_median": percentile(
            [abs(r["damaged_effectiveness"] - r["efficiency"]) for r in damaged], 50
        ),
    }
    return out


def summarize_nominal(rows: list[dict]) -> dict:
    hours = sum(r["flown_s"] for r in rows) / 3600.0
    alarms = sum(r["lost_rotor"] is not None for r in rows)
    damaged = sum(r["damaged_rotor"] is not None for r in rows)
    return {"flights": len(rows), "hours": hours, "lost_alarms": alarms, "damaged_alarms": damaged}


def benchmark_detection(
    seeds, nominal_seeds, *, modes=("rotor-speeds", "commands"), nominal_s: float = 60.0,
    detector: DetectorParams | None = None, estimator: str = "truth", workers: int | None = 0,
    progress: bool = False,
) -> dict:  # fmt: skip
    """Failures for ``seeds`` and nominal flights of ``nominal_s`` for ``nominal_seeds``, in each
    detection mode, with ``estimator`` in the loop (``truth``: an oracle, the true state); per
    mode the summaries of :func:`summarize_failures` and :func:`summarize_nominal`, the complete
    losses' survival (by scenario) with the oracle (told 50 ms after the loss) beside, and every
    run's row."""
    cases = [failure_case(s, m) for m in modes for s in seeds]
    oracle = [c for c in (failure_case(s, "oracle") for s in seeds) if complete_loss(c)]
    cases += oracle
    cases += [nominal_case(s, m, nominal_s) for m in modes for s in nominal_seeds]
    rows = execute(
        lambda c: fly_case(c, detector, estimator), cases, workers=workers, progress=progress, desc="flights"
    )
    bad = [r for r in rows if isinstance(r, BaseException)]
    if bad:
        raise RuntimeError(f"{len(bad)} flight(s) failed; the first: {bad[0]!r}")
    told = [r for r in rows if r["mode"] == "oracle"]
    out = {"estimator": estimator, "modes": {}, "oracle_flights": len(told)}
    out["oracle_survived"] = sum(r["status"] == "survived" for r in told)
    out["survival_by_scenario"] = survival_by_scenario(rows)
    out["runs"] = rows
    for m in modes:
        mine = [r for r in rows if r["mode"] == m]
        out["modes"][m] = {
            "failures": summarize_failures([r for r in mine if r["rotor"] is not None]),
            "nominal": summarize_nominal([r for r in mine if r["rotor"] is None]),
        }
    return out


THRESHOLDS = (0.002, 0.003, 0.004, 0.006, 0.008, 0.012, 0.016, 0.024)
"""The 'lost' test's thresholds (deficit-seconds) the trade-off looks at."""


def crossings(case: dict, thresholds=THRESHOLDS, detector: DetectorParams | None = None) -> dict:
    """One case flown with the SE(3) controller, the 'lost' test unable to fire and the fast test
    off (the trade-off is the 'lost' test's): the detector then changes nothing, and the first
    sample at which its largest 'lost' sum passes each threshold (time, rotor; None if never) is
    what a detector with that threshold would say, up to its alarm."""
    det = replace(detector or DetectorParams(), lost_threshold=10.0, glr=False)
    failure = case_failure(case)
    f = fly(case["scenario"], seed=case["seed"], duration=case["duration"], vehicle="bebop2", failure=failure,
            controller="se3", detection=_detection(case["mode"], det), **case_flight_kwargs(case))  # fmt: skip
    t, stat = f.recording.t, f.detector_statistics
    first = {}
    for h in thresholds:
        k = np.flatnonzero(stat[:, 0] > h)
        first[str(h)] = None if len(k) == 0 else (float(t[k[0]]), int(stat[k[0], 1]))
    return {**case, "first": first, "flown_s": f.summary["flown_s"]}


def tradeoff(rows: list[dict], thresholds=THRESHOLDS) -> list[dict]:
    """Per threshold: the complete losses found, named and their delays; the alarms in nominal
    flight (per hour) and before a failure."""
    out = []
    nominal = [r for r in rows if r["rotor"] is None]
    hours = sum(r["flown_s"] for r in nominal) / 3600.0
    complete = [r for r in rows if complete_loss(r)]
    for h in thresholds:
        key = str(h)
        early = [r for r in rows if r["rotor"] is not None and r["first"][key] and r["first"][key][0] < r["time_s"]]
        found = [r for r in complete if r["first"][key] and r["first"][key][0] >= r["time_s"]]
        delays = [r["first"][key][0] - r["time_s"] for r in found]
        alarms = sum(r["first"][key] is not None for r in nominal)
        out.append(
            {
                "threshold": h,
                "complete": len(complete),
                "found": len(found),
                "isolated": sum(r["first"][key][1] == r["rotor"] for r in found),
                "delay_ms": {q: _ms(percentile(delays, p)) for q, p in (("median", 50), ("p90", 90), ("p99", 99))}
                | {"max": _ms(max(delays)) if delays else None},
                "nominal_hours": hours,
                "nominal_alarms": alarms,
                "alarms_before_failure": len(early),
            }
        )
    return out


def choose_threshold(table: list[dict]) -> float:
    """The smallest threshold without any alarm in nominal flight or before a failure (the
    training seeds' table); the largest looked at when every one alarms."""
    quiet = [r["threshold"] for r in table if r["nominal_alarms"] == 0 and r["alarms_before_failure"] == 0]
    return min(quiet) if quiet else max(r["threshold"] for r in table)


def benchmark_tradeoff(
    train, test, train_nominal, test_nominal, *, modes=("rotor-speeds", "commands"), nominal_s: float = 60.0,
    workers: int | None = 0, progress: bool = False, detector: DetectorParams | None = None,
) -> dict:  # fmt: skip
    """The trade-off of the 'lost' test's threshold (the detector's other parameters ``detector``'s,
    the defaults' when None): per mode, the table on the training seeds, the threshold chosen
    there (:func:`choose_threshold`) and the table on the test seeds."""
    out = {"modes": {}}
    for m in modes:
        tables = {}
        for name, seeds, nominal in (("train", train, train_nominal), ("test", test, test_nominal)):
            cases = [failure_case(s, m) for s in seeds]
            cases += [nominal_case(s, m, nominal_s) for s in nominal]
            rows = execute(
                lambda c: crossings(c, detector=detector), cases, workers=workers, progress=progress, desc=f"{m} {name}"
            )
            bad = [r for r in rows if isinstance(r, BaseException)]
            if bad:
                raise RuntimeError(f"{len(bad)} flight(s) failed; the first: {bad[0]!r}")
            tables[name] = tradeoff(rows)
            tables[f"{name}_runs"] = rows
        out["modes"][m] = {
            **tables,
            "chosen": choose_threshold(tables["train"]),
            "default": DetectorParams().lost_threshold,
        }
    return out


def format_tradeoff(result: dict) -> str:
    lines = []
    for m, r in result["modes"].items():
        lines.append(f"{m}: threshold chosen on the training seeds: {r['chosen']} deficit-seconds")
        lines.append(f"{'set':<6}{'h':>7}{'found':>9}{'named':>7}{'median':>8}{'p90':>7}{'p99':>7}{'max':>7}"
                     f"{'nominal alarms':>16}{'before':>8}")  # fmt: skip
        for name in ("train", "test"):
            for row in r[name]:
                d = row["delay_ms"]
                mark = (" <" if row["threshold"] == r["chosen"] else "") + (
                    " default" if row["threshold"] == r["default"] else ""
                )
                lines.append(
                    f"{name:<6}{row['threshold']:>7}{row['found']:>5}/{row['complete']:<3}{row['isolated']:>7}"
                    f"{_fmt_ms(d['median']):>8}{_fmt_ms(d['p90']):>7}{_fmt_ms(d['p99']):>7}{_fmt_ms(d['max']):>7}"
                    f"{row['nominal_alarms']:>6} in {row['nominal_hours']:.1f} h{row['alarms_before_failure']:>8}{mark}"
                )
    return "\n".join(lines)


def _fmt_ms(v):
    return "-" if v is None else f"{v:.0f}"


def _ms(v):
    return None if v is None else round(1e3 * v, 1)


def format_detection(result: dict) -> str:
    lines = []
    for mode, r in result["modes"].items():
        f, n, p = r["failures"], r["nominal"], r["failures"]["partial"]
        d = f["delay_ms"]
        lines += [
            f"{mode}: {f['complete']} complete losses: found {f['found']}, isolated {f['isolated']}, "
            f"survived {f['survived']}; delay median {d['median']} ms, p90 {d['p90']}, p99 {d['p99']}, "
            f"max {d['max']} ms; false alarms before a failure {f['false_alarms']}",
            f"  {p['flights']} partial losses: found {p['found']}, isolated as damaged {p['isolated']}, "
            f"delay median {p['delay_ms_median']} ms, effectiveness error median {p['effectiveness_error_median']}",
            f"  nominal: {n['flights']} flights, {n['hours']:.2f} h: {n['lost_alarms']} 'lost' and "
            f"{n['damaged_alarms']} 'damaged' alarms",
        ]
    lines.append(
        f"the oracle (told 50 ms after each complete loss): survived {result['oracle_survived']} of "
        f"{result['oracle_flights']}"
    )
    for mode, cells in result["survival_by_scenario"].items():
        lines.append(f"  survived, {mode}: " + ", ".join(f"{sc} {a}/{b}" for sc, (a, b) in cells.items()))
    return "\n".join(lines)
