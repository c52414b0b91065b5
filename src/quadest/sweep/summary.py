"""A sweep's results for a person (``quadest report RESULTS.parquet``): per filter,
each parameter set's mean metrics over the sources it ran on, and the metric against each
swept parameter."""

from __future__ import annotations

import json

from quadest.sweep.runs import METRICS


def is_results(path) -> bool:
    """Whether ``path`` is a sweep's results file (Parquet with a run id, filter and params)."""
    import pyarrow.parquet as pq

    try:
        names = set(pq.read_schema(path).names)
    except Exception:  # noqa: BLE001 (not Parquet, not readable: not a results file)
        return False
    return {"run_id", "filter", "params", "status"} <= names


def _as_missing_where_nan(column):
    """A float column with its NaNs as nulls (a metric a run could not give: left out of means)."""
    import pyarrow.compute as pc

    return pc.if_else(pc.is_nan(column), None, column)


def _set_means(table, metrics: list[str]):
    """Per (filter, parameter set), in order of first appearance, over the successful runs: the
    runs, the mean of each metric (NaN left out) and, for flown runs, how many stayed up. One
    Arrow aggregation, so a results file of a million runs is summarised without a Python row
    each."""
    import pyarrow as pa
    import pyarrow.compute as pc

    ok = table.filter(pc.equal(table["status"], "ok"))
    cols = {"filter": ok["filter"], "params": ok["params"], "one": pa.repeat(1, ok.num_rows)}
    cols |= {m: _as_missing_where_nan(ok[m]) for m in metrics}
    if "flight" in ok.column_names:
        cols["up"] = pc.cast(pc.equal(ok["flight"], "survived"), pa.int64())
    aggs = [("one", "sum")] + [(m, "mean") for m in metrics] + ([("up", "sum")] if "up" in cols else [])
    return pa.table(cols).group_by(["filter", "params"], use_threads=False).aggregate(aggs).to_pylist()


def sweep_summary(table) -> dict:
    """``{"runs", "ok", "failed", "sources", "filters": {name: {"sets": [...], "params": [...]}}}``;
    each set: its parameters, the runs, and the mean of every metric over its successful runs."""
    import pyarrow.compute as pc

    names = table.column_names
    metrics = [m for m in METRICS if m in names]
    extra = [k for k in ("position_rms_m", "time_to_settle_s", "spin_rate_rad_s") if k in names]
    status = table["status"]
    n_ok = pc.sum(pc.equal(status, "ok")).as_py() or 0
    out = {
        "runs": table.num_rows,
        "ok": n_ok,
        "failed": table.num_rows - n_ok,
        "sources": len(pc.unique(table["source"])),
        "metrics": metrics + extra,
        "filters": {},
    }
    failed = table.filter(pc.not_equal(status, "ok"))["filter"].to_pylist()
    groups: dict = {}
    for g in _set_means(table, metrics + extra):
        e = {"params": json.loads(g["params"]), "runs": g["one_sum"]}
        for m in metrics + extra:
            e[m] = None if g[f"{m}_mean"] is None else float(g[f"{m}_mean"])
        if "up_sum" in g:
            e["survived"] = g["up_sum"]
        groups.setdefault(g["filter"], []).append(e)
    for name in sorted(set(table["filter"].to_pylist())):
        entries = groups.get(name, [])
        entries.sort(key=lambda e: (e.get("total_rmse_deg") is None, e.get("total_rmse_deg") or 0.0))
        keys = sorted({k for e in entries for k, v in e["params"].items() if isinstance(v, (int, float))})
        out["filters"][name] = {"sets": entries, "params": keys, "failed": failed.count(name)}
    return out


SHORT = {
    "total_rmse_deg": "total",
    "heading_rmse_deg": "heading",
    "inclination_rmse_deg": "incl.",
    "roll_rms_deg": "roll",
    "pitch_rms_deg": "pitch",
    "yaw_rms_deg": "yaw",
    "position_rms_m": "pos m",
    "time_to_settle_s": "settle s",
    "spin_rate_rad_s": "spin rad/s",
}


def _set_label(params: dict) -> str:
    return (
        ", ".join(f"{k}={v:g}" if isinstance(v, (int, float)) else f"{k}={v}" for k, v in params.items()) or "defaults"
    )


def format_sweep_summary(summ: dict, best: int = 3) -> str:
    """:func:`sweep_summary` for a terminal: per filter its ``best`` parameter sets by mean
    total RMSE (every set when it has no more), each set's runs and mean metrics."""
    cols = [
        m for m in summ["metrics"] if any(e.get(m) is not None for f in summ["filters"].values() for e in f["sets"])
    ]
    flown = any("survived" in e for f in summ["filters"].values() for e in f["sets"])
    head = ["filter", "parameters", "runs"] + [SHORT.get(m, m) for m in cols] + (["survived"] if flown else [])
    rows = []
    for name, f in summ["filters"].items():
        for e in f["sets"][:best]:
            cells = [f"{e[m]:.2f}" if e.get(m) is not None else "-" for m in cols]
            survived = [f"{e.get('survived', 0)}/{e['runs']}"] if flown else []
            rows.append([name, _set_label(e["params"]), str(e["runs"]), *cells, *survived])
        if len(f["sets"]) > best:
            rows.append([name, f"(best {best} of {len(f['sets'])} sets by total)"] + [""] * (len(head) - 2))
        if f["failed"]:
            rows.append([name, f"({f['failed']} failed run(s) left out)"] + [""] * (len(head) - 2))
    widths = [max(len(r[i]) for r in [head, *rows]) for i in range(len(head))]

    def line(r):
        return "  ".join(c.ljust(w) if i < 2 else c.rjust(w) for i, (c, w) in enumerate(zip(r, widths))).rstrip()

    title = (
        f"results: {summ['runs']} runs ({summ['ok']} ok) on {summ['sources']} source(s); per parameter set the mean "
        "over its successful runs (degrees unless named)"
    )
    return "\n".join([title, line(head), *(line(r) for r in rows)])
