"""A sweep's results for a person (``quadest report RESULTS.parquet``): per filter,
each parameter set's mean metrics over the sources it ran on, and the metric against each
swept parameter."""

from __future__ import annotations

import json
import math

import numpy as np

from quadest.sweep.runs import METRICS


def is_results(path) -> bool:
    """Whether ``path`` is a sweep's results file (Parquet with a run id, filter and params)."""
    import pyarrow.parquet as pq

    try:
        names = set(pq.read_schema(path).names)
    except Exception:  # noqa: BLE001 (not Parquet, not readable: not a results file)
        return False
    return {"run_id", "filter", "params", "status"} <= names


def sweep_summary(table) -> dict:
    """``{"runs", "ok", "failed", "sources", "filters": {name: {"sets": [...], "params": [...]}}}``;
    each set: its parameters, the runs, and the mean of every metric over its successful runs."""
    rows = table.to_pylist()
    ok = [r for r in rows if r["status"] == "ok"]
    metrics = [m for m in METRICS if m in (rows[0] if rows else {})]
    extra = [k for k in ("position_rms_m", "time_to_settle_s", "spin_rate_rad_s") if rows and k in rows[0]]
    out = {
        "runs": len(rows),
        "ok": len(ok),
        "failed": len(rows) - len(ok),
        "sources": len({r["source"] for r in rows}),
        "metrics": metrics + extra,
        "filters": {},
    }
    for name in sorted({r["filter"] for r in rows}):
        mine = [r for r in ok if r["filter"] == name]
        sets: dict = {}
        for r in mine:
            sets.setdefault(r["params"], []).append(r)
        entries = []
        for p, rs in sets.items():
            e = {"params": json.loads(p), "runs": len(rs)}
            for m in metrics + extra:
                v = [r[m] for r in rs if r.get(m) is not None and not math.isnan(r[m])]
                e[m] = float(np.mean(v)) if v else None
            if "flight" in rs[0]:
                e["survived"] = sum(r["flight"] == "survived" for r in rs)
            entries.append(e)
        entries.sort(key=lambda e: (e.get("total_rmse_deg") is None, e.get("total_rmse_deg") or 0.0))
        keys = sorted({k for e in entries for k, v in e["params"].items() if isinstance(v, (int, float))})
        out["filters"][name] = {
            "sets": entries,
            "params": keys,
            "failed": sum(1 for r in rows if r["filter"] == name and r["status"] != "ok"),
        }
    return out
