"""What one run of a sweep is, how a grid becomes runs, and how a run is evaluated
(docs/sweeps.md).

A run is a JSON-able dict: the filter, its parameters, the source of the data (a simulated
scenario with its seed, or a recording file) and how to evaluate. Its ``run_id`` is a hash of
that dict, so the same run has the same id in every sweep, which is what resuming relies on,
and the result depends on nothing else: the seed travels with the task.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import time
from collections.abc import Iterable, Sequence
from functools import lru_cache
from pathlib import Path

import numpy as np

from quadest.errors import MAX_RUNS, UsageError, check_run_count
from quadest.evaluation.runner import check_params, estimate, estimator_names, score
from quadest.filters import filter_name
from quadest.flight import fly, in_loop_estimators
from quadest.readers import read_recording
from quadest.sim import simulate
from quadest.sim.faults import Failure
from quadest.sweep.campaign import CAMPAIGN_ROW_TYPES, RUN_COLUMNS, campaign_label, fly_campaign

METRICS = ("total_rmse_deg", "heading_rmse_deg", "inclination_rmse_deg", "roll_rms_deg", "pitch_rms_deg", "yaw_rms_deg")


ROW_TYPES = {
    **RUN_COLUMNS,
    **{k: "double" for k in METRICS},
    "samples": "int64",
    "seconds": "double",
}
"""The columns of a results row and their Arrow types (a results file must hold these)."""


FLOWN_ROW_TYPES = {
    **ROW_TYPES,
    "flight": "string",
    "reason": "string",
    "end_time_s": "double",
    "time_to_settle_s": "double",
    "position_rms_m": "double",
    "spin_rate_rad_s": "double",
    "tilt_deg": "double",
    "recovered": "int64",
    "handover_s": "double",
    "gravity_error_at_handover_deg": "double",
}
"""A flown run's row: the estimation columns (``total_rmse_deg``: the attitude error the
controller flew with, ``inclination_rmse_deg``: its tilt error; the others NaN) and the
flight's outcome (``flight``: survived, crashed or stopped; ``recovered`` 1/0 for a throw, −1
otherwise)."""
FLOWN_FIELDS = {
    "end_time_s": "end_time_s",
    "time_to_settle_s": "time_to_settle_s",
    "position_rms_m": "position_rms_settled_m",
    "spin_rate_rad_s": "spin_rate_rad_s",
    "tilt_deg": "tilt_deg",
    "handover_s": "handover_s",
    "gravity_error_at_handover_deg": "gravity_error_at_handover_deg",
}


def row_types(runs) -> dict:
    """The layout of a sweep's results: flown runs have their own (a sweep is one or the other)."""
    kinds = {r["source"]["kind"] for r in runs} or {"sim"}
    layouts = {id(_layout(k)) for k in kinds}
    if len(layouts) > 1:
        raise UsageError("a sweep runs either flown flights, a campaign or estimation runs, not a mix")
    return _layout(kinds.pop())


def _layout(kind: str) -> dict:
    """A run kind's row layout."""
    return {"flown": FLOWN_ROW_TYPES, "campaign": CAMPAIGN_ROW_TYPES}.get(kind, ROW_TYPES)


def empty_row(spec: dict, error: str = "") -> dict:
    """A run's row before (or without) its results: NaN metrics, status failed when ``error``."""
    layout = _layout(spec["source"]["kind"])
    row = {
        "run_id": run_id(spec),
        "filter": spec["filter"],
        "params": json.dumps(spec["params"], sort_keys=True),
        "source": source_label(spec["source"]),
        "seed": spec["source"].get("seed", spec["source"].get("case", {}).get("seed", -1)),
        "spec": json.dumps(spec, sort_keys=True),
        "status": "failed" if error else "ok",
        "error": error,
    }
    for k, t in layout.items():
        if k not in row:
            row[k] = {"double": math.nan, "int64": 0 if k == "samples" else -1, "string": ""}[t]
    return row


def run_id(spec: dict) -> str:
    return hashlib.sha1(json.dumps(spec, sort_keys=True).encode()).hexdigest()[:16]


# -- grids ------------------------------------------------------------------------------------------
GRID_HELP = "give a list (0.1,0.2) or lin:A:B:N or log:A:B:N"


def _spaced(text: str) -> tuple[str, float, float, int]:
    """``lin:A:B:N`` / ``log:A:B:N`` as its parts; N may be written 1e3 but must be whole."""
    kind, a, b, n = text.split(":")
    a, b, count = float(a), float(b), float(n)
    if not (math.isfinite(a) and math.isfinite(b) and math.isfinite(count)) or count != int(count) or count < 1:
        raise ValueError
    if kind == "log" and (a <= 0 or b <= 0):
        raise ValueError
    return kind, a, b, int(count)


def count_values(text: str) -> int:
    """How many values ``text`` (a list, ``lin:A:B:N`` or ``log:A:B:N``) gives, from the text
    alone: nothing is allocated."""
    text = text.strip()
    try:
        if text.startswith(("lin:", "log:")):
            return _spaced(text)[3]
        return sum(1 for v in text.split(",") if v.strip())
    except ValueError:
        raise UsageError(f"grid values {text!r}: {GRID_HELP}") from None


def parse_values(text: str, max_runs: int | None = MAX_RUNS) -> list[float]:
    """``0.1,0.2,0.5``; ``lin:A:B:N`` (N values from A to B); ``log:A:B:N`` (N log-spaced); N
    within ``max_runs``, checked before the values are made."""
    text = text.strip()
    check_run_count(count_values(text), max_runs, f"--grid {text}")
    try:
        if text.startswith(("lin:", "log:")):
            kind, a, b, n = _spaced(text)
            vals = np.linspace(a, b, n) if kind == "lin" else np.geomspace(a, b, n)
            return [float(f"{v:.6g}") for v in vals]
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise UsageError(f"grid values {text!r}: {GRID_HELP}") from None
    if not values:
        raise UsageError(f"grid values {text!r}: {GRID_HELP}")
    return values


def parse_grid(items: Iterable[str] | None, max_runs: int | None = MAX_RUNS) -> dict:
    """``["madgwick.beta_marg=log:0.001:0.5:30", "mahony.k_p=0.5,1,2"]`` ->
    ``{"madgwick": {"beta_marg": [...]}, "mahony": {"k_p": [...]}}``. Each filter's product of
    value counts is checked against ``max_runs`` before its values are made."""
    items = list(items or [])
    counts: dict = {}
    for item in items:
        name, field, vals = _grid_item(item)
        counts.setdefault(name, {})[field] = count_values(vals)
    for name, fields in counts.items():
        check_run_count(math.prod(fields.values()), max_runs, f"the grid of {name}")
    out: dict = {}
    for item in items:
        name, field, vals = _grid_item(item)
        out.setdefault(name, {})[field] = parse_values(vals, max_runs)
    return out


def _grid_item(item: str) -> tuple[str, str, str]:
    key, eq, vals = item.partition("=")
    name, dot, field = key.strip().partition(".")
    name = filter_name(name)
    if not eq or not dot:
        raise UsageError(f"--grid expects FILTER.PARAM=VALUES, got {item!r}")
    return name, field, vals


def param_sets(grid: dict) -> list[dict]:
    """Cartesian product of one filter's grid (``[{}]`` when it has none)."""
    if not grid:
        return [{}]
    keys = sorted(grid)
    return [dict(zip(keys, combo)) for combo in itertools.product(*(grid[k] for k in keys))]


def count_param_sets(grid: dict) -> int:
    """``len(param_sets(grid))``, computed."""
    return math.prod(len(v) for v in grid.values())


def sim_sources(
    scenario: str,
    preset: str,
    seeds: Iterable[int],
    duration: float | None = None,
    overrides: dict | None = None,
    t_from: float | None = None,
) -> list[dict]:
    return [
        {
            "kind": "sim",
            "scenario": scenario,
            "preset": preset,
            "seed": int(s),
            "duration": duration,
            "set": dict(overrides or {}),
            "from_s": t_from,
        }
        for s in seeds
    ]


def flown_sources(
    scenario: str,
    seeds: Sequence[int],
    *,
    controller: str | None = None,
    failures: Iterable[dict | None] = (None,),
    duration: float | None = None,
    vehicle: str = "recovery",
    preset: str | None = None,
) -> list[dict]:
    """Flown flights (:func:`quadest.flight.fly`): one per (failure, seed); a failure as
    :meth:`~quadest.sim.faults.Failure.to_dict` writes it, or None."""
    return [
        {
            "kind": "flown",
            "scenario": scenario,
            "controller": controller,
            "failure": f,
            "seed": int(s),
            "duration": duration,
            "vehicle": vehicle,
            "preset": preset,
        }
        for f in failures
        for s in seeds
    ]


def file_sources(paths: Sequence[str | Path], fmt: str | None = None) -> list[dict]:
    out = []
    for p in paths:
        p = Path(p)
        if p.is_dir() and not (p / "metadata.yaml").is_file() and not (p / "data.hdf5").is_file():
            out += [
                {"kind": "file", "path": str(f.resolve()), "format": fmt}
                for f in sorted(p.iterdir())
                if f.suffix.lower() in (".hdf5", ".h5", ".mat", ".csv", ".parquet", ".ulg", ".bin", ".bag")
            ]
        else:
            out.append({"kind": "file", "path": str(p.resolve()), "format": fmt})
    if not out:
        raise ValueError("no recording found among " + ", ".join(map(str, paths)))
    return out


def flown_names(filters, scenario: str) -> list[str]:
    """The estimators a flown sweep puts in the loop: quadest's filters, the installed streaming
    peers, truth, and for a throw the recovery; ``all`` is all of these."""
    spec = (filters if isinstance(filters, str) else ",".join(filters)).strip()
    known = ["truth", "recovery"] if scenario == "throw" else ["truth", *in_loop_estimators()]
    names = known if spec in ("all", "quadest") else [n.strip() for n in spec.split(",") if n.strip()]
    bad = [n for n in names if n not in known]
    if bad or not names:
        raise UsageError(
            f"unknown estimator(s) in the loop for {scenario}: {', '.join(bad) or spec!r}; known: {', '.join(known)}"
        )
    return names


def build_runs(
    filters: str | Iterable[str],
    grid: dict,
    sources: Sequence[dict],
    align: str | None = None,
    max_runs: int | None = MAX_RUNS,
) -> list[dict]:
    """Every (filter, parameter set, source) as a run spec; their number is checked against
    ``max_runs`` before any is made."""
    flown = [s for s in sources if s["kind"] == "flown"]
    if flown:
        names = flown_names(filters, flown[0]["scenario"])
    else:
        names = estimator_names(filters if isinstance(filters, str) else ",".join(filters), all_includes_peers=True)
    unknown = [n for n in grid if n not in names]
    if unknown:
        raise UsageError(f"--grid names filter(s) {', '.join(unknown)} that the sweep does not run")
    for name, fields in grid.items():  # a misspelt parameter is refused before any run starts
        check_params(name, fields)
    per_source = sum(count_param_sets(grid.get(name, {})) for name in names)
    check_run_count(
        per_source * len(sources),
        max_runs,
        f"{len(sources):,} flight(s) x {per_source:,} filter and parameter set(s)",
    )
    # source-major order: the runs on one flight follow each other, so a worker's cache of
    # recent flights (simulated or read) serves them without simulating or reading again
    runs = []
    for src in sources:
        for name in names:
            for params in param_sets(grid.get(name, {})):
                runs.append({"filter": name, "params": params, "source": src, "align": align})
    return runs


def source_label(src: dict) -> str:
    if src["kind"] == "flown":
        f = src.get("failure")
        return f"flown {src['scenario']}{failure_label(f)}/seed{src['seed']}"
    if src["kind"] == "sim":
        return f"{src['scenario']}/{src['preset']}/seed{src['seed']}"
    if src["kind"] == "campaign":
        return campaign_label(src)
    return Path(src["path"]).stem if Path(src["path"]).is_file() else Path(src["path"]).name


def failure_label(f: dict | None) -> str:
    """A flown source's failure in its label: ``/rotor1@3:0.6`` for one whose numbers imply its
    mode (the labels of results written before the modes), else the failure as ``--failure``
    reads it (``/motor-stop:0@2``)."""
    if not f:
        return ""
    failure = Failure.from_dict(f)
    if "mode" in f:
        return f"/{failure}"
    text = f"/rotor{failure.rotor}@{failure.time_s:g}"
    if failure.efficiency or failure.imbalance:
        text += f":{failure.efficiency:g}" + (f":{failure.imbalance:g}" if failure.imbalance else "")
    return text


# -- executing one run --------------------------------------------------------------------------------
@lru_cache(maxsize=8)
def _sim(scenario, preset, seed, duration, overrides_json):
    return simulate(scenario, preset, seed=seed, duration=duration, overrides=json.loads(overrides_json) or None)


@lru_cache(maxsize=16)
def _file(path, fmt):
    return read_recording(path, fmt)


def load_source(src: dict):
    if src["kind"] == "sim":
        return _sim(
            src["scenario"],
            src["preset"],
            src["seed"],
            src.get("duration"),
            json.dumps(src.get("set") or {}, sort_keys=True),
        )
    return _file(src["path"], src.get("format"))


def run_group(specs: list) -> list:
    """Several runs on the same flight, one after the other (one task: the flight is simulated
    or read once, on the worker that runs them)."""
    return [run_one(s) for s in specs]


def group_runs(runs: list, max_runs: int = 32) -> list:
    """Consecutive runs that share a source, in groups of at most ``max_runs``."""
    groups: list = []
    for r in runs:
        if groups and groups[-1][0]["source"] == r["source"] and len(groups[-1]) < max_runs:
            groups[-1].append(r)
        else:
            groups.append([r])
    return groups


def fly_one(spec: dict, row: dict) -> None:
    """A flown run: fly it and put its summary into ``row``."""
    src = spec["source"]
    f = src.get("failure")
    flight = fly(
        src["scenario"],
        estimator=spec["filter"],
        controller=src.get("controller"),
        duration=src.get("duration"),
        seed=src["seed"],
        preset=src.get("preset"),
        vehicle=src.get("vehicle") or "recovery",
        failure=Failure.from_dict(f) if f else None,
        estimator_params=spec["params"] or None,
    )
    s = flight.summary
    row.update(
        {
            "flight": s["status"],
            "reason": s["reason"],
            "samples": len(flight.recording),
            "total_rmse_deg": s.get("attitude_error_rms_deg", math.nan),
            "inclination_rmse_deg": s.get("tilt_error_rms_deg", math.nan),
            "recovered": int(s["recovered"]) if "recovered" in s else -1,
        }
    )
    for col, key in FLOWN_FIELDS.items():
        v = s.get(key)
        row[col] = math.nan if v is None else float(v)


def run_one(spec: dict) -> dict:
    """Evaluate one run; never raises: a failure becomes a row with ``status='failed'``."""
    t0 = time.perf_counter()
    row = empty_row(spec)
    if spec["source"]["kind"] in ("flown", "campaign"):
        try:
            (fly_one if spec["source"]["kind"] == "flown" else fly_campaign)(spec, row)
        except Exception as exc:  # a failing run is recorded and the sweep goes on
            row["status"] = "failed"
            row["error"] = f"{type(exc).__name__}: {exc}"
        row["seconds"] = time.perf_counter() - t0
        return row
    try:
        rec = load_source(spec["source"])
        q = estimate(rec, spec["filter"], spec["params"]).q
        s = score(rec, q, nav=spec.get("align"), t_from=spec["source"].get("from_s"))
        row.update(
            {
                "total_rmse_deg": s["total_rmse_deg"],
                "heading_rmse_deg": s["heading_rmse_deg"],
                "inclination_rmse_deg": s["inclination_rmse_deg"],
                "roll_rms_deg": s["rms_deg"]["roll"],
                "pitch_rms_deg": s["rms_deg"]["pitch"],
                "yaw_rms_deg": s["rms_deg"]["yaw"],
                "samples": s["samples"],
            }
        )
    except Exception as exc:  # a failing run is recorded and the sweep goes on
        row["status"] = "failed"
        row["error"] = f"{type(exc).__name__}: {exc}"
    row["seconds"] = time.perf_counter() - t0
    return row
