"""A sweep's results summarised per parameter set, from a table written by hand."""

import json
import math

import pyarrow as pa

from quadest.sweep.summary import format_sweep_summary, sweep_summary


def _table():
    nan = math.nan
    rows = [  # filter, params, status, total, heading, flight
        ("a", {"x": 1}, "ok", 1.0, nan, "survived"),
        ("a", {"x": 1}, "ok", nan, nan, "crashed"),
        ("a", {"x": 1}, "ok", 3.0, nan, "survived"),
        ("a", {"x": 1}, "failed", nan, nan, "survived"),
        ("a", {"x": 2}, "ok", 0.5, nan, "crashed"),
        ("b", {}, "failed", nan, nan, "survived"),
    ]
    cols = list(zip(*rows))
    return pa.table(
        {
            "run_id": [str(i) for i in range(len(rows))],
            "filter": list(cols[0]),
            "params": [json.dumps(p) for p in cols[1]],
            "source": ["s1", "s2", "s3", "s1", "s1", "s1"],
            "status": list(cols[2]),
            "total_rmse_deg": list(cols[3]),
            "heading_rmse_deg": list(cols[4]),
            "flight": list(cols[5]),
        }
    )


def test_each_set_is_the_mean_of_its_successful_runs_without_their_nans():
    s = sweep_summary(_table())
    assert (s["runs"], s["ok"], s["failed"], s["sources"]) == (6, 4, 2, 3)
    a = s["filters"]["a"]
    assert [e["params"] for e in a["sets"]] == [{"x": 2}, {"x": 1}]  # by mean total
    x1 = a["sets"][1]
    assert (x1["runs"], x1["total_rmse_deg"], x1["heading_rmse_deg"], x1["survived"]) == (3, 2.0, None, 2)
    assert a["failed"] == 1 and a["params"] == ["x"]
    assert s["filters"]["b"] == {"sets": [], "params": [], "failed": 1}


def test_the_printed_table_shows_the_sets_and_what_was_left_out():
    text = format_sweep_summary(sweep_summary(_table()), best=1)
    lines = text.splitlines()
    assert lines[1].split() == ["filter", "parameters", "runs", "total", "survived"]  # heading: no figure at all
    assert lines[2].split() == ["a", "x=2", "1", "0.50", "0/1"]
    assert "(best 1 of 2 sets by total)" in text and "(1 failed run(s) left out)" in text
