"""The survival campaign: its runs, its rows against the detection benchmark's own flights, its
summary against counts made by hand, resuming, its page, and its refusals."""

import json
import math

import pytest

from quadest.cli.main import main
from quadest.errors import UsageError
from quadest.evaluation.detection import failure_case, fly_case, fly_case_flight
from quadest.sweep import ResultStore
from quadest.sweep.campaign import campaign_runs, campaign_summary, survival_curves, up_by_height
from quadest.sweep.runs import run_id
from quadest.sweep.truth_summary import truth_survival


def _row(**kw):
    row = {
        "status": "ok", "filter": "robust", "detection": "rotor-speeds", "gyro_range_dps": 1000.0,
        "mag_latency_s": 0.0, "kind": "loss", "scenario": "hover", "rotor": 1, "failure_s": 2.0,
        "efficiency": 0.0, "flight": "survived", "flown_s": 6.0, "lost_rotor": 1, "lost_s": 2.02,
        "delay_s": 0.02, "isolated": 1, "false_alarm": 0, "damaged_rotor": -1, "damaged_s": math.nan,
        "damaged_effectiveness": math.nan, "spin_rate_rad_s": 11.0, "gyro_clipped_share": math.nan,
    }  # fmt: skip
    row.update(kw)
    return row


def test_the_summary_counts_what_happened():
    rows = [
        _row(),
        _row(flight="crashed", scenario="aggressive", delay_s=0.2, spin_rate_rad_s=8.0),
        _row(kind="nominal", rotor=-1, failure_s=math.nan, efficiency=math.nan, lost_rotor=2, flown_s=3600.0),
        _row(kind="nominal", rotor=-1, failure_s=math.nan, efficiency=math.nan, lost_rotor=-1, flown_s=1800.0),
        _row(detection="oracle", delay_s=0.05),
        _row(status="failed"),
    ]
    s = campaign_summary(rows)
    assert (s["runs"], s["ok"], s["failed"]) == (6, 5, 1)
    mine, oracle = s["groups"]  # the detector before the oracle
    assert mine["detection"] == "rotor-speeds" and oracle["detection"] == "oracle"
    assert (mine["failures"]["complete"], mine["failures"]["survived"]) == (2, 1)
    assert mine["failures"]["delay_ms"]["median"] == pytest.approx(110.0)
    assert mine["survival_by_scenario"] == {"hover": [1, 1], "aggressive": [0, 1]}
    assert mine["nominal"] == {"flights": 2, "hours": 1.5, "lost_alarms": 1, "damaged_alarms": 0, "crashed": 0}
    spin = s["curves"]["spin_rate_rad_s"]["lines"]["robust / rotor-speeds"]
    assert sum(spin["flights"]) == 2 and sum(spin["survived"]) == 1
    assert "gyro_clipped_share" not in s["curves"]  # no range clipped: nothing to draw against


def test_the_curves_bin_every_flight_once():
    rows = [_row(spin_rate_rad_s=float(k), flight="survived" if k % 3 else "crashed") for k in range(40)]
    line = survival_curves(rows)["spin_rate_rad_s"]["lines"]["robust / rotor-speeds"]
    assert sum(line["flights"]) == 40 and sum(line["survived"]) == sum(1 for k in range(40) if k % 3)
    assert line["x"] == sorted(line["x"])


def test_a_loss_flown_lower_stays_up_where_its_drop_says():
    """A figure eight's loss (seed 302, the truth and the detector in the loop; lost from 3 m)
    flown 30 m up falls ``drop_m`` below the hover point and recovers; flown 0.3 m higher than
    that it stays up, 0.3 m lower it hits the ground: the flight is the same up to the contact."""
    case = failure_case(302, "rotor-speeds")
    high = fly_case_flight({**case, "height_m": 30.0}).summary
    drop = high["drop_m"]
    assert high["status"] == "survived" and 3.0 < drop < 30.0, high
    assert fly_case_flight({**case, "height_m": drop + 0.3}).summary["status"] == "survived"
    low = fly_case_flight({**case, "height_m": drop - 0.3}).summary
    assert low["status"] == "crashed" and low["reason"] == "crashed: ground contact"


def test_up_by_height_counts_the_losses_each_height_keeps_up():
    rows = [_row(height_m=30.0, drop_m=d) for d in (0.5, 3.0, 4.0)]  # 3.0 at 3 m: the ground is touched beyond it
    rows += [_row(height_m=30.0, drop_m=31.0, flight="crashed"), _row(height_m=30.0, drop_m=0.1, flight="false alarm")]
    up = up_by_height(rows)
    assert up["x"] == [1.0, 2.0, 3.0, 5.0, 10.0, 20.0, 30.0] and up["flights"] == [5] * 7
    assert up["survived"] == [1, 1, 2, 3, 3, 3, 3]
    two = campaign_summary(rows + [_row(height_m=10.0, drop_m=1.5)])
    assert set(two["curves"]["height_m"]["lines"]) == {
        "robust / rotor-speeds / 30 m up",
        "robust / rotor-speeds / 10 m up",
    }
    s = campaign_summary(rows)
    assert s["groups"][0]["up_by_height"] == up
    assert s["curves"]["height_m"]["lines"]["robust / rotor-speeds"]["survived"] == up["survived"]
    before = campaign_summary([{k: v for k, v in r.items() if k not in ("height_m", "drop_m")} for r in rows])
    assert before["groups"][0]["up_by_height"] == {"x": [3.0], "survived": [3], "flights": [5]}  # a file of before


def test_the_oracle_flies_only_complete_losses():
    runs = campaign_runs(range(4), range(100, 102), ["truth"], gyro_ranges_dps=(None, 500.0))
    kinds = [(r["source"]["case"]["mode"], r["source"]["case"]["rotor"] is None) for r in runs]
    assert ("oracle", True) not in kinds
    oracle = [r for r in runs if r["source"]["case"]["mode"] == "oracle"]
    assert len(oracle) == 2 * 3  # seeds 0-2 complete, seed 3 partial; two gyroscope ranges
    assert len(runs) == 2 * (4 * 2 + 3 + 2 * 2)


def test_a_campaign_flies_resumes_and_draws(tmp_path, capsys):
    out, page, js = tmp_path / "c.parquet", tmp_path / "c.html", tmp_path / "c.json"
    args = ["campaign", "--seeds", "0-1", "--nominal-seeds", "1000", "--duration", "3", "--filters", "truth",
            "--detection", "rotor-speeds,oracle", "--gyro-range", "none,500", "-o", str(out),
            "--workers", "0"]  # fmt: skip
    assert main([*args, "--report", str(page), "--json", str(js)]) == 0
    rows = ResultStore(out).read().to_pylist()
    assert len(rows) == 2 * (2 * 2 + 1)
    assert all(r["status"] == "ok" for r in rows)
    # the campaign's flight is the detection benchmark's: the same detection, to the sample
    loss = next(r for r in rows if r["seed"] == 0 and r["detection"] == "rotor-speeds" and r["gyro_range_dps"] == 1000)
    direct = fly_case(failure_case(0, "rotor-speeds"))
    assert loss["lost_s"] == pytest.approx(direct["lost_s"]) and loss["flight"] == direct["status"]
    clipped = [r for r in rows if r["gyro_range_dps"] == 500 and r["kind"] == "loss"]
    assert all(r["gyro_clipped_share"] > 0.1 for r in clipped)  # spinning at ~11 rad/s > 8.7 rad/s
    told = [r for r in rows if r["detection"] == "oracle"]
    assert all(r["delay_s"] == pytest.approx(0.05) for r in told)
    summary = json.loads(js.read_text())
    assert summary["sweep"]["executed"] == len(rows)
    assert "campaign-table" in page.read_text() and "oracle (told)" in page.read_text()
    capsys.readouterr()
    assert main(args) == 0  # resumed: nothing flown again
    assert "executed 0 (skipped 10" in capsys.readouterr().out
    assert main(["report", str(out), "-o", str(tmp_path / "r.html")]) == 0
    assert "campaign-scenarios" in (tmp_path / "r.html").read_text()
    high = tmp_path / "h.parquet"
    assert main(["campaign", "--seeds", "0", "--nominal-seeds", "none", "--height", "10", "--filters", "truth",
                 "--detection", "rotor-speeds", "-o", str(high), "--workers", "0"]) == 0  # fmt: skip
    (row,) = ResultStore(high).read().to_pylist()
    assert row["height_m"] == 10.0 and 0.0 < row["drop_m"] < 10.0 and row["flight"] == "survived"


@pytest.mark.parametrize(
    "option, value, says",
    [
        ("--gyro-range", "fast", "--gyro-range: 'fast' is not a number"),
        ("--gyro-range", "-5", "--gyro-range: -5 is out of range"),
        ("--detection", "psychic", "--detection: unknown mode(s) psychic"),
        ("--filters", "nobody", "unknown estimator(s) in the loop"),
        ("--height", "-2", "--height -2: give the hover point's height above the ground in m, 1 to 1000"),
        ("--height", "20", "--height is for the failures: give --nominal-seeds none with it"),
        ("--nominal-seeds", "some", "--nominal-seeds expects a range"),
        ("--set", "gyro.range=3", "--set gyro.range: campaign takes detector.*"),
        ("--set", "detector.rotor_speeds=0", "the detection mode decides it"),
        ("--set", "detector.lost_threshold=-1", "lost_threshold must be in (0, 10]"),
        ("--set", "detector.nope=1", "detector has no parameter 'nope'"),
        ("--detection", ",", "--detection: give one or more of"),
    ],
)
def test_a_wrong_option_is_one_line(tmp_path, capsys, option, value, says):
    assert main(["campaign", option, value, "-o", str(tmp_path / "c.parquet"), "--workers", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and says in err[0]
    assert not (tmp_path / "c.parquet").exists()


def test_the_detectors_parameters_are_flown_and_told_apart(tmp_path, capsys):
    """--set detector.*: a loss the default detector finds (seed 0, a hover) is not found with the
    'lost' test's threshold beyond reach and the fast test off; both settings' runs live in one
    results file, each with its own row and group; the defaults' run keeps its id."""
    out = tmp_path / "c.parquet"
    args = ["campaign", "--seeds", "0", "--nominal-seeds", "none", "--filters", "truth", "--detection",
            "rotor-speeds", "-o", str(out), "--workers", "0"]  # fmt: skip
    assert main(args) == 0
    assert main([*args, "--set", "detector.lost_threshold=10", "--set", "detector.glr=false"]) == 0
    rows = {r["detector"]: r for r in ResultStore(out).read().to_pylist()}
    assert set(rows) == {"", "glr=false,lost_threshold=10.0"}
    assert rows[""]["lost_rotor"] == rows[""]["rotor"] and rows["glr=false,lost_threshold=10.0"]["lost_rotor"] == -1
    assert rows[""]["run_id"] == run_id(campaign_runs([0], [], ["truth"], detections=("rotor-speeds",))[0])
    groups = campaign_summary(list(rows.values()))["groups"]
    assert [g["detection_label"] for g in groups] == ["rotor-speeds", "rotor-speeds (glr=false,lost_threshold=10.0)"]
    assert [g["failures"]["found"] for g in groups] == [1, 0]
    text = capsys.readouterr().out
    assert "glr=false,lost_threshold=10.0" in text and "defaults" in text
    assert main([*args, "--set", "detector.lost_threshold=0.004"]) == 0  # the default's value: its run, flown before
    assert "executed 0 (skipped 1" in capsys.readouterr().out


def test_the_oracle_alone_takes_no_detector_parameter(tmp_path, capsys):
    args = ["campaign", "--detection", "oracle", "--set", "detector.lost_threshold=0.01"]
    assert main([*args, "-o", str(tmp_path / "c.parquet"), "--workers", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "the oracle flies no detector" in err[0]
    assert not (tmp_path / "c.parquet").exists()


def test_a_results_file_of_before_is_refused_in_one_line_and_kept(tmp_path, capsys):
    """A campaign's file written before the height's columns: refused, named, left as it was."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from quadest.sweep.campaign import CAMPAIGN_ROW_TYPES
    from quadest.sweep.engine import CHECKSUM

    old = {k: t for k, t in CAMPAIGN_ROW_TYPES.items() if k not in ("height_m", "drop_m")} | {CHECKSUM: "string"}
    out = tmp_path / "c.parquet"
    pq.write_table(pa.table({k: pa.array([], type=t) for k, t in old.items()}), out)
    before = out.read_bytes()
    args = ["campaign", "--seeds", "0", "--nominal-seeds", "none", "--filters", "truth", "--detection", "oracle"]
    assert main([*args, "-o", str(out), "--workers", "0"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "written by an earlier quadest, without height_m, drop_m" in err[0] and str(out) in err[0]
    assert out.read_bytes() == before


def test_two_outputs_on_one_file_are_refused(tmp_path, capsys):
    out = tmp_path / "c.parquet"
    assert main(["campaign", "-o", str(out), "--report", str(out), "--workers", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "give each output its own file" in err[0]
    assert not out.exists()


def test_each_complete_loss_is_flown_once_per_failure_mode():
    """Seeds 0-3 (0-2 complete, 3 partial) with a propeller off and a motor stopped: the complete
    losses twice, the propeller's runs with the ids they always had, the partial loss and the
    nominal flight once; an unknown mode is a one-line refusal."""
    before = campaign_runs(range(4), [100], ["truth"], detections=("rotor-speeds",))
    both = campaign_runs(range(4), [100], ["truth"], detections=("rotor-speeds",),
                         failure_modes=("propeller-off", "motor-stop"))  # fmt: skip
    assert len(both) == len(before) + 3
    assert {run_id(r) for r in before} <= {run_id(r) for r in both}
    stopped = [r["source"]["case"] for r in both if r["source"]["case"].get("failure_mode") == "motor-stop"]
    assert sorted(c["seed"] for c in stopped) == [0, 1, 2]
    with pytest.raises(UsageError, match="--failure-modes: unknown or no mode.*desync"):
        campaign_runs([0], [], ["truth"], failure_modes=("desync",))


def test_the_summary_names_each_groups_failure_mode():
    """A propeller off and a motor stopped in one file: a group each, both with the nominal
    flight and the partial loss flown once; a file of before (no failure_mode column) is all
    propellers off."""
    rows = [
        _row(failure_mode="propeller-off"),
        _row(failure_mode="motor-stop", flight="crashed", lost_rotor=-1, delay_s=math.nan, isolated=0),
        _row(kind="partial", failure_mode="partial", efficiency=0.5, lost_rotor=-1, delay_s=math.nan, isolated=0),
        _row(kind="nominal", failure_mode="", rotor=-1, failure_s=math.nan, efficiency=math.nan, lost_rotor=-1,
             flown_s=3600.0),
    ]  # fmt: skip
    off, stop = campaign_summary(rows)["groups"]
    assert (off["failure_mode"], stop["failure_mode"]) == ("propeller-off", "motor-stop")
    assert (off["failures"]["survived"], stop["failures"]["survived"]) == (1, 0)
    assert (off["failures"]["found"], stop["failures"]["found"]) == (1, 0)
    assert off["nominal"]["hours"] == stop["nominal"]["hours"] == 1.0
    assert off["failures"]["partial"]["flights"] == stop["failures"]["partial"]["flights"] == 1
    assert stop["detection_label"] == "rotor-speeds, motor-stop" and off["detection_label"] == "rotor-speeds"
    old = campaign_summary([{k: v for k, v in r.items() if k != "failure_mode"} for r in rows[:1] + rows[2:]])
    assert [g["failure_mode"] for g in old["groups"]] == ["propeller-off"]


def test_a_truth_spread_is_flown_recorded_and_summarised(tmp_path, capsys):
    """--truth-spread default: seed 0's loss flown with the truth drawn from its seed (the row's
    numbers are draw_truth's for that seed, an independent call), the group named, the text
    saying the losses up against the draw; the model's run beside it keeps its id and NaNs."""
    import numpy as np

    from quadest.models.multirotor import vehicle_preset
    from quadest.models.truth import draw_truth, drawn_names

    out = tmp_path / "c.parquet"
    args = ["campaign", "--seeds", "0", "--nominal-seeds", "none", "--filters", "truth", "--detection", "oracle",
            "-o", str(out), "--workers", "0"]  # fmt: skip
    assert main([*args, "--truth-spread", "default"]) == 0
    assert main(args) == 0
    rows = {r["truth_spread"]: r for r in ResultStore(out).read().to_pylist()}
    drawn = draw_truth(vehicle_preset("bebop2"), np.random.default_rng(np.random.SeedSequence([0, 41]))).drawn
    assert {k: rows["default"][f"truth_{k}"] for k in drawn_names()} == drawn
    assert all(math.isnan(rows["none"][f"truth_{k}"]) for k in drawn_names())
    assert rows["none"]["run_id"] == run_id(campaign_runs([0], [], ["truth"], detections=("oracle",))[0])
    groups = campaign_summary(list(rows.values()))["groups"]
    assert [g["truth_spread"] for g in groups] == ["default", "none"]
    assert groups[0]["truth"]["flights"] == 1 and groups[1]["truth"] is None
    assert "truth drawn per flight (default)" in capsys.readouterr().out


def test_the_campaign_keeps_the_models_runs_ids():
    before = campaign_runs(range(3), [100], ["robust"], detections=("rotor-speeds",))
    none = campaign_runs(range(3), [100], ["robust"], detections=("rotor-speeds",), truth_spread="none")
    drawn = campaign_runs(range(3), [100], ["robust"], detections=("rotor-speeds",), truth_spread="default")
    assert [run_id(r) for r in before] == [run_id(r) for r in none]
    assert not {run_id(r) for r in before} & {run_id(r) for r in drawn} and len(drawn) == len(before)
    assert all(r["source"]["truth_spread"] == "default" for r in drawn)
    with pytest.raises(UsageError, match="--truth-spread: unknown spread 'wide'"):
        campaign_runs([0], [], ["robust"], truth_spread="wide")


def test_survival_is_counted_in_quarters_of_each_draw():
    """Eight losses, the rotor inertia ratios 0.5 to 2.25 in steps of 0.25, the heaviest three
    crashed: quarters of two flights each, hand-counted: 2/2, 2/2, 2/2 and 0/2; the worst (the
    heaviest) quarter is 0/2, from the upper quartile 1.8125 up."""
    rows = [
        {"flight": "crashed" if k >= 5 else "survived", "truth_rotor_inertia_ratio": 0.5 + 0.25 * k} for k in range(8)
    ]
    rows[5]["flight"] = "survived"  # 1.75: below the upper quartile
    t = truth_survival(rows)
    by = t["by"]["truth_rotor_inertia_ratio"]
    assert (by["survived"], by["flights"]) == ([2, 2, 2, 0], [2, 2, 2, 2])
    assert t["worst"]["truth_rotor_inertia_ratio"] == {"end": "high", "bound": 1.8125, "survived": 0, "flights": 2}
    assert (t["flights"], t["survived"]) == (8, 6)
    assert "truth_top_speed_ratio" not in t["by"]  # not drawn: nothing to count against
    assert math.isclose(by["x"][0], 0.625)
