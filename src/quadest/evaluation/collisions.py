"""Collisions in flight recovered (``quadest benchmark collisions``; docs/recovery.md section 7):
flown collisions for the share recovered to a hover, nominal flights with the divergence checks
on for the recoveries started where nothing happened, and the ablation: each check alone, and
none (no recovery), on the same collisions. Every case follows from its seed, so that the
thresholds are chosen on one set of seeds and reported on another."""

from __future__ import annotations

from dataclasses import asdict

import numpy as np

from quadest.evaluation.parallel import execute
from quadest.flight import FlightParams, fly
from quadest.flight.collision import CollisionParams
from quadest.flight.spec import COLLISION_S
from quadest.recovery.divergence import CHECKS, DivergenceParams

SCENARIOS = ("hover", "trajectory", "aggressive")
ABLATIONS = {"impact only": "impact", "rate only": "rate", "innovation only": "innovation", "no checks": "off"}
"""The ablation's rows: the checks that run (FlightParams.divergence)."""
PEAKS = ("impact", "rate", "innovation")
"""The checks whose statistic a nominal flight reports (the largest ratio to the threshold)."""


def fly_collision(task) -> dict:
    """One collision (``(seed, estimator, checks)``): the scenarios in turn, the collision drawn
    from the seed; the summary's figures."""
    seed, estimator, checks = task
    params = FlightParams(collision="drawn", divergence=checks)
    f = fly(SCENARIOS[seed % 3], estimator=estimator, seed=seed, duration=COLLISION_S, params=params)
    return _row(f.summary, seed, checks)


def fly_nominal(task) -> dict:
    """One nominal flight (``(seed, estimator, seconds)``) with every check on."""
    seed, estimator, duration = task
    params = FlightParams(divergence=",".join(CHECKS))
    f = fly(SCENARIOS[seed % 3], estimator=estimator, seed=seed, duration=duration, params=params)
    return _row(f.summary, seed, "all")


def _row(s: dict, seed: int, checks: str) -> dict:
    keys = (
        "scenario", "status", "reason", "flown_s", "collision", "recovery_started", "divergence_delay_s", "checks",
        "check_peaks", "free_fall_s", "handover_s", "gravity_error_at_handover_deg", "fall_m", "recovered",
    )  # fmt: skip
    return {"seed": seed, "with": checks, **{k: s.get(k) for k in keys}}


def _stats(v) -> dict:
    v = [x for x in v if x is not None]
    if not v:
        return {"median": None, "p90": None, "max": None}
    return {"median": float(np.median(v)), "p90": float(np.percentile(v, 90)), "max": float(np.max(v))}


def collision_stats(rows: list[dict]) -> dict:
    """Over flown collisions: recovered, crashed, detected (and by which checks first), the
    delays, the handover and the gravity error there, the fall; by the estimator's fate
    (reset or left); the ones not recovered."""
    n = len(rows)
    fired = [r for r in rows if r["recovery_started"]]
    by_fate = {}
    for fate in ("reset", "left"):
        mine = [r for r in rows if r["collision"]["estimator"] == fate]
        by_fate[fate] = {"collisions": len(mine), "recovered": sum(bool(r["recovered"]) for r in mine)}
    return {
        "collisions": n,
        "recovered": sum(bool(r["recovered"]) for r in rows),
        "crashed": sum(r["status"] == "crashed" for r in rows),
        "detected": len(fired),
        "first_by_check": {c: sum(c in r["checks"] for r in fired) for c in CHECKS},
        "divergence_delay_s": _stats([r["divergence_delay_s"] for r in fired]),
        "handover_s": _stats([r["handover_s"] for r in rows]),
        "gravity_error_deg": _stats([r["gravity_error_at_handover_deg"] for r in rows]),
        "fall_m": _stats([r["fall_m"] for r in rows]),
        "by_estimator": by_fate,
        "not_recovered": [
            {k: r[k] for k in ("seed", "scenario", "reason", "checks", "gravity_error_at_handover_deg", "fall_m")}
            | {
                "speed_m_s": r["collision"]["speed_m_s"],
                "rate_rad_s": r["collision"]["rate_rad_s"],
                "estimator": r["collision"]["estimator"],
            }  # fmt: skip
            for r in rows
            if not r["recovered"]
        ],
    }


def nominal_stats(rows: list[dict]) -> dict:
    """Over nominal flights: hours flown, recoveries started (and the flights), and how close each
    check came (the largest ratio of its statistic to its threshold, per scenario)."""
    out = {
        "flights": len(rows),
        "hours": sum(r["flown_s"] for r in rows) / 3600.0,
        "recovery_started": sum(bool(r["recovery_started"]) for r in rows),
        "started_in": [
            {"seed": r["seed"], "scenario": r["scenario"], "checks": r["checks"]} for r in rows if r["recovery_started"]
        ],  # fmt: skip
        "survived": sum(r["status"] == "survived" for r in rows),
        "peak_ratio": {},
    }
    for sc in SCENARIOS:
        mine = [r for r in rows if r["scenario"] == sc]
        if mine:
            out["peak_ratio"][sc] = {
                c: max(r["check_peaks"][c] for r in mine) for c in ("impact", "rate", "innovation")
            }
    return out


def benchmark_collisions(
    seeds, nominal_seeds, *, nominal_s: float = 60.0, estimator: str = "robust", ablations: bool = True,
    workers: int | None = 0, progress: bool = False,
) -> dict:  # fmt: skip
    """Collisions for ``seeds`` and nominal flights of ``nominal_s`` for ``nominal_seeds`` with
    ``estimator`` in the loop and every check on; with ``ablations`` the same collisions again
    for each row of :data:`ABLATIONS`."""
    variants = {"all checks": ",".join(CHECKS), **(ABLATIONS if ablations else {})}
    tasks = [(s, estimator, checks) for checks in variants.values() for s in seeds]
    rows = _run(fly_collision, tasks, workers, progress, "collisions")
    nominal = _run(fly_nominal, [(s, estimator, nominal_s) for s in nominal_seeds], workers, progress, "nominal")
    out = {
        "estimator": estimator,
        "seeds": [min(seeds), max(seeds)] if len(seeds) else None,
        "nominal_seeds": [min(nominal_seeds), max(nominal_seeds)] if len(nominal_seeds) else None,
        "collision": asdict(CollisionParams()),
        "divergence": asdict(DivergenceParams()),
        "collision_s": COLLISION_S,
        "nominal_s": nominal_s,
        "nominal": nominal_stats(nominal),
        "cases": {},
    }
    for name, checks in variants.items():
        out["cases"][name] = collision_stats([r for r in rows if r["with"] == checks])
    return out


def _run(fn, tasks, workers, progress, desc) -> list:
    rows = execute(fn, tasks, workers=workers, progress=progress, desc=desc)
    bad = [r for r in rows if isinstance(r, BaseException)]
    if bad:
        raise RuntimeError(f"{len(bad)} flight(s) failed; the first: {bad[0]!r}")
    return rows


def format_collisions(res: dict) -> str:
    """The benchmark's figures, one line each."""
    lines = []
    for name, st in res["cases"].items():
        n, d, g = st["collisions"], st["divergence_delay_s"], st["gravity_error_deg"]
        lines.append(
            f"{name:<16} recovered {st['recovered']}/{n}, crashed {st['crashed']}, detected {st['detected']} "
            f"(first by {', '.join(f'{c} {k}' for c, k in st['first_by_check'].items() if k) or 'none'}); "
            + ("" if d["median"] is None else f"delay {1e3 * d['median']:.0f} ms median, {1e3 * d['max']:.0f} max; ")
            + ("" if g["median"] is None else f"gravity error at the handover {g['median']:.1f}° / {g['p90']:.1f}°")
        )
    nom = res["nominal"]
    lines.append(
        f"nominal flights: {nom['flights']} ({nom['hours']:.1f} h), recovery started in {nom['recovery_started']}, "
        f"survived {nom['survived']}; largest statistic / threshold: "
        + "; ".join(f"{sc} " + ", ".join(f"{c} {v:.2f}" for c, v in p.items()) for sc, p in nom["peak_ratio"].items())
    )
    return "\n".join(lines)
