"""Run several estimators on one recording and tabulate their errors and speed."""
from __future__ import annotations

import math
from dataclasses import replace

from quadest.data.recording import Recording
from quadest.evaluation.metrics import AXES, summarize_errors, time_estimator
from quadest.filters import FILTERS, make_filter


def declination_of(rec: Recording) -> float:
    """Declination (rad, east positive) of a recording's magnetic field: from a simulation's
    earth field, or ``meta['declination_rad']``, else 0."""
    B = rec.meta.get("earth_field_ned_ut")
    if B is not None:
        return float(math.atan2(B[1], B[0]))
    return float(rec.meta.get("declination_rad", 0.0))


def parse_filters(spec: str, all_includes_peers: bool = False) -> list[str]:
    """``all`` (quadest's filters, and the installed peers with ``all_includes_peers``),
    ``quadest``, ``peers`` (the installed peers) or a comma-separated list of filters and peers."""
    from quadest.evaluation.peers import PEERS, available_peers

    spec = (spec or "all").strip()
    if spec in ("all", "quadest"):
        return list(FILTERS) + (available_peers() if spec == "all" and all_includes_peers else [])
    if spec == "peers":
        return available_peers()
    names = [s.strip() for s in spec.split(",") if s.strip()]
    bad = [n for n in names if n not in FILTERS and n not in PEERS]
    if bad or not names:
        raise ValueError(f"unknown filter(s) {', '.join(bad) or spec!r}; filters: {', '.join(FILTERS)}; "
                         f"peers: {', '.join(PEERS)}")
    missing = [n for n in names if n in PEERS and n not in available_peers()]
    if missing:
        raise ValueError(f"peer(s) {', '.join(missing)} not installed: pip install 'quadest[peers]'")
    return names


def parse_params(items) -> dict:
    """``["afckf.beta=2", ...]`` -> ``{"afckf": {"beta": 2.0}}`` (values as numbers or booleans)."""
    out: dict = {}
    for item in items or []:
        key, eq, value = item.partition("=")
        name, dot, field = key.strip().partition(".")
        if not eq or not dot or name not in FILTERS:
            raise ValueError(f"--param expects FILTER.NAME=VALUE with a known filter, got {item!r}")
        v = value.strip()
        parsed = {"true": True, "false": False}.get(v.lower())
        if parsed is None:
            try:
                parsed = float(v)
            except ValueError:
                raise ValueError(f"--param {key}: {v!r} is not a number or true/false") from None
        out.setdefault(name, {})[field] = parsed
    return out


def run_filters(rec: Recording, names, params: dict | None = None, label: dict | None = None):
    """Run each estimator (quadest filter or peer) over the recording; ``{label: FilterResult}``."""
    from quadest.evaluation.peers import run_peer
    from quadest.filters.base import FilterResult

    params = params or {}
    decl = declination_of(rec)
    results = {}
    for name in names:
        key = (label or {}).get(name, name)
        if name in FILTERS:
            results[key] = make_filter(name, declination=decl, **params.get(name, {})).run(rec)
        else:
            results[key] = FilterResult(name, rec.t, run_peer(name, rec, use_mag=rec.has_mag), {}, None)
    return results


def truth_of(rec: Recording) -> str:
    """``true_q``, or the log's onboard attitude ``ref_q`` when there is no independent truth."""
    if rec.true_q is not None:
        return "true_q"
    if rec.ref_q is not None:
        return "ref_q"
    raise ValueError("the recording has no attitude truth (true_q) or onboard reference (ref_q) to compare against")


def compare(rec: Recording, names, *, params: dict | None = None, t_from: float | None = None,
            timing: bool = True, source: str = "", align: str | None = None,
            align_body: bool | None = None) -> tuple[dict, dict]:
    """Errors (and speed) of each estimator on ``rec``. Returns ``(report, results)`` where the
    report follows the JSON layout of ``quadest compare --json``. ``align`` (none, heading,
    full) and ``align_body`` remove constant frame rotations before the errors (default: what
    the reader recommends in ``meta['align']``, else none); results then hold the aligned
    estimates."""
    from quadest.evaluation.benchmark import align_estimate, evaluation_mask

    truth = truth_of(rec)
    rec_align = rec.meta.get("align", {})
    nav = align if align is not None else rec_align.get("nav", "none")
    body = align_body if align_body is not None else bool(rec_align.get("body", False))
    params = params or {}
    results = run_filters(rec, names, params)
    mask = evaluation_mask(rec)
    if t_from is not None:
        mask &= rec.t >= t_from
    report = {"recording": source, "from_s": t_from, "against": truth, "alignment": {"nav": nav, "body": body},
              "filters": {}}
    decl = declination_of(rec)
    for name, res in results.items():
        q, al = align_estimate(rec, res.q, truth=truth, nav=nav, body=body, mask=mask)
        results[name] = replace(res, q=q)
        entry = summarize_errors(q, getattr(rec, truth), mask)
        if al is not None:
            entry["alignment"] = al.describe()
        if timing and name in FILTERS:
            tm = time_estimator(lambda n=name: make_filter(n, declination=decl, **params.get(n, {})), rec)
            entry["us_per_sample"] = tm["batch_us"]
            entry["us_per_sample_streaming"] = tm["stream_us"]
        report["filters"][name] = entry
    return report, results


def format_tables(report: dict, metrics=(("rms_deg", "RMS error [deg]"), ("var_deg2", "variance [deg²]"),
                                         ("mae_deg", "mean absolute error [deg]"))) -> str:
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
        lines.append(f"{'stream':<8}" + "".join(
            f"{report['filters'][n]['us_per_sample_streaming']:>{w}.2f}" for n in names))
    return "\n".join(lines).rstrip()
