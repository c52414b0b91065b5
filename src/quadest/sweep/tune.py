"""Choosing parameters from a sweep's results (docs/sweeps.md): one set for all trials, the
one with the lowest mean metric over the trials (BROAD's "trial-agnostic" choice), and the best
set per trial."""

from __future__ import annotations

import json
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from quadest.sweep.engine import ResultStore, run_sweep
from quadest.sweep.runs import run_id


def select(table: pa.Table, filter_name: str, metric: str = "total_rmse_deg") -> dict:
    """``{"trial_agnostic": {...}, "per_trial": {source: {...}}}`` from a results table. A
    parameter set counts for the trial-agnostic choice only if it ran on every trial."""
    rows = [r for r in table.to_pylist() if r["filter"] == filter_name and r["status"] == "ok"]
    if not rows:
        raise ValueError(f"no successful runs of {filter_name} in the results")
    if metric not in rows[0]:
        raise ValueError(f"unknown metric {metric!r}")
    sources = sorted({r["source"] for r in rows})
    by_params: dict = {}
    for r in rows:
        by_params.setdefault(r["params"], {})[r["source"]] = r[metric]
    complete = {p: v for p, v in by_params.items() if len(v) == len(sources)}
    if not complete:
        raise ValueError("no parameter set ran on every trial")
    means = {p: float(np.mean(list(v.values()))) for p, v in complete.items()}
    best = min(means, key=means.get)
    per_trial = {}
    for s in sources:
        cand = [(r[metric], r["params"]) for r in rows if r["source"] == s]
        m, p = min(cand)
        per_trial[s] = {"params": json.loads(p), metric: m, "with_agnostic": by_params[best].get(s)}
    return {
        "filter": filter_name,
        "metric": metric,
        "trials": len(sources),
        "parameter_sets": len(by_params),
        "trial_agnostic": {"params": json.loads(best), metric: means[best], "per_trial": by_params[best]},
        "per_trial": per_trial,
        "per_trial_mean": float(np.mean([v[metric] for v in per_trial.values()])),
    }


def halves(sources: Iterable[str]) -> tuple[list[str], list[str]]:
    """The two halves of a split: the trials in sorted order, alternately (BROAD's trials are
    numbered by kind, so each half gets one of every kind: with and without rest breaks, each
    disturbance)."""
    s = sorted(sources)
    return s[0::2], s[1::2]


def split_select(table: pa.Table, filter_name: str, metric: str = "total_rmse_deg") -> dict:
    """Cross-validation by halves: the parameter set with the lowest mean over one half,
    scored on the other half it never saw, and the reverse. A parameter set counts only if it
    ran on every trial of both halves."""
    rows = [r for r in table.to_pylist() if r["filter"] == filter_name and r["status"] == "ok"]
    if not rows:
        raise ValueError(f"no successful runs of {filter_name} in the results")
    by_params: dict = {}
    for r in rows:
        by_params.setdefault(r["params"], {})[r["source"]] = r[metric]
    a, b = halves({r["source"] for r in rows})
    if not a or not b:
        raise ValueError("a split needs at least two trials")
    complete = {p: v for p, v in by_params.items() if all(s in v for s in a + b)}
    if not complete:
        raise ValueError("no parameter set ran on every trial")
    folds = []
    for name, tune_on, held in (("A", a, b), ("B", b, a)):
        mean = {p: float(np.mean([v[s] for s in tune_on])) for p, v in complete.items()}
        best = min(mean, key=mean.get)
        folds.append(
            {
                "tuned_on": name,
                "tuned_on_trials": tune_on,
                "params": json.loads(best),
                "tuned_mean": mean[best],
                "held_out": "B" if name == "A" else "A",
                "held_out_trials": held,
                "held_out_mean": float(np.mean([complete[best][s] for s in held])),
            }
        )
    sets = sorted(
        (
            {
                "params": json.loads(p),
                "mean_A": float(np.mean([v[s] for s in a])),
                "mean_B": float(np.mean([v[s] for s in b])),
                "mean": float(np.mean([v[s] for s in a + b])),
            }
            for p, v in complete.items()
        ),
        key=lambda r: r["mean"],
    )
    return {
        "filter": filter_name,
        "metric": metric,
        "parameter_sets": len(complete),
        "folds": folds,
        "halves": {"A": a, "B": b},
        "sets": sets,
    }


def format_split(sel: dict) -> str:
    m = sel["metric"]
    lines = [
        f"{sel['filter']}: {sel['parameter_sets']} parameter set(s), metric {m}, split into halves "
        "(sorted trials, alternately)"
    ]
    for f in sel["folds"]:
        lines.append(
            f"tuned on {f['tuned_on']} ({', '.join(t[:12] for t in f['tuned_on_trials'])}): "
            f"{f['params']}  mean {f['tuned_mean']:.3f} (in-sample)"
        )
        lines.append(
            f"  held-out {f['held_out']} ({', '.join(t[:12] for t in f['held_out_trials'])}): "
            f"mean {f['held_out_mean']:.3f}"
        )
    return "\n".join(lines)


def _tuning_table(runs, out, **engine):
    """Run (or resume) a tuning sweep; its results restricted to exactly these runs (the results
    file may hold others) and the sweep's summary."""
    res = run_sweep(runs, out, **engine)
    table = ResultStore(out).read()
    wanted = pa.array(sorted({run_id(r) for r in runs}))
    return table.filter(pc.is_in(table.column("run_id"), value_set=wanted)), res


def tune(
    runs: Sequence[dict],
    out: str | Path,
    filter_name: str,
    metric: str = "total_rmse_deg",
    *,
    split: bool = False,
    **engine,
) -> tuple[dict, dict]:
    """Run (or resume) a tuning sweep and choose parameters over exactly these runs: one set for
    all (:func:`select`) or, with ``split``, by halves (:func:`split_select`). Returns
    ``(selection, sweep summary)``; ``engine``: the keyword arguments of
    :func:`quadest.sweep.engine.run_sweep`."""
    table, res = _tuning_table(runs, out, **engine)
    return (split_select if split else select)(table, filter_name, metric), res


def format_selection(sel: dict) -> str:
    m = sel["metric"]
    ta = sel["trial_agnostic"]
    lines = [
        f"{sel['filter']}: {sel['parameter_sets']} parameter set(s) on {sel['trials']} trial(s), metric {m}",
        f"trial-agnostic best: {ta['params']}  mean {ta[m]:.3f}",
        f"per-trial best: mean {sel['per_trial_mean']:.3f}",
        f"{'trial':<40}{'per-trial best':>16}{'agnostic':>10}  parameters",
    ]
    for s, v in sel["per_trial"].items():
        lines.append(f"{s[:39]:<40}{v[m]:>16.3f}{v['with_agnostic']:>10.3f}  {v['params']}")
    return "\n".join(lines)
