"""Run several estimators on one recording and tabulate their errors and speed (``quadest
compare``), through the one runner (:mod:`quadest.evaluation.runner`)."""

from __future__ import annotations

from dataclasses import replace

from quadest.data.recording import Recording
from quadest.errors import UsageError
from quadest.evaluation.metrics import AXES
from quadest.evaluation.runner import alignment_of, check_params, estimate_all, evaluation_mask, score, truth_of
from quadest.evaluation.speed import time_estimator
from quadest.filters import ESTIMATORS, filter_name, make_filter


def parse_params(items) -> dict:
    """``["afckf.beta=2", ...]`` -> ``{"afckf": {"beta": 2.0}}`` (values as numbers or booleans)."""
    out: dict = {}
    for item in items or []:
        key, eq, value = item.partition("=")
        name, dot, field = key.strip().partition(".")
        name = filter_name(name)
        if not eq or not dot or name not in ESTIMATORS:
            raise UsageError(f"--param expects FILTER.NAME=VALUE with a known filter, got {item!r}")
        check_params(name, {field: None})  # the name before its value
        v = value.strip()
        parsed = {"true": True, "false": False}.get(v.lower())
        if parsed is None:
            try:
                parsed = float(v)
            except ValueError:
                raise UsageError(f"--param {key}: {v!r} is not a number or true/false") from None
        out.setdefault(name, {})[field] = parsed
    return out


def compare(
    rec: Recording,
    names,
    *,
    params: dict | None = None,
    t_from: float | None = None,
    timing: bool = True,
    source: str = "",
    align: str | None = None,
    align_body: bool | None = None,
) -> tuple[dict, dict]:
    """Errors (and speed) of each estimator on ``rec``. Returns ``(report, results)`` where the
    report follows the JSON layout of ``quadest compare --json``. ``align`` (none, heading,
    full) and ``align_body`` remove constant frame rotations before the errors (default: what
    the reader recommends in ``meta['align']``, else none); results then hold the aligned
    estimates."""
    truth = truth_of(rec)
    nav, body = alignment_of(rec, align, align_body)
    params = params or {}
    results = estimate_all(rec, names, params)
    mask = evaluation_mask(rec, t_from)
    report = {
        "recording": source,
        "from_s": t_from,
        "against": truth,
        "alignment": {"nav": nav, "body": body},
        "filters": {},
    }
    for name, res in results.items():
        aligned: list = []
        entry = score(rec, res.q, truth=truth, nav=nav, body=body, mask=mask, aligned=aligned)
        results[name] = replace(res, q=aligned[0])
        entry["skipped_samples"] = res.skipped
        entry["restarts_s"] = list(res.restarts)
        if timing and name in ESTIMATORS and not ESTIMATORS[name].peer:
            tm = time_estimator(lambda n=name: make_filter(n, declination=rec.declination, **params.get(n, {})), rec)
            entry["us_per_sample"] = tm["batch_us"]
            entry["us_per_sample_streaming"] = tm["stream_us"]
        report["filters"][name] = entry
    return report, results


def _cell(v, w) -> str:
    """A figure in a column ``w`` wide, ``-`` for none (an acausal estimator does not stream)."""
    return f"{'-':>{w}}" if v is None else f"{v:>{w}.2f}"


def format_tables(
    report: dict,
    metrics=(("rms_deg", "RMS error [deg]"), ("var_deg2", "variance [deg²]"), ("mae_deg", "mean absolute error [deg]")),
) -> str:
    """One table per metric: filters as columns, roll/pitch/yaw as rows (like the papers)."""
    names = list(report["filters"])
    w = max(12, *(len(n) + 2 for n in names))
    lines = []
    for key, title in metrics:
        lines.append(title)
        lines.append(" " * 8 + "".join(f"{n:>{w}}" for n in names))
        for a in AXES:
            lines.append(f"{a:<8}" + "".join(f"{report['filters'][n][key][a]:>{w}.3f}" for n in names))
        lines.append("")
    if all("us_per_sample" in report["filters"][n] for n in names):
        lines.append("execution time [µs/sample]")
        lines.append(f"{'batch':<8}" + "".join(f"{report['filters'][n]['us_per_sample']:>{w}.3f}" for n in names))
        lines.append(
            f"{'stream':<8}" + "".join(_cell(report["filters"][n]["us_per_sample_streaming"], w) for n in names)
        )
    return "\n".join(lines).rstrip()
