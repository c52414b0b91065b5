"""The command line, run in-process and headless."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from quadest import load_recording
from quadest.cli.main import main


def run(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_help_and_version(capsys):
    for argv in (
        ["--help"],
        ["simulate", "--help"],
        ["info", "--help"],
        ["demo", "--help"],
        ["sweep", "--help"],
        ["tune", "--help"],
        ["benchmark", "--help"],
        ["calibrate", "--help"],
        ["estimate", "--help"],
        ["compare", "--help"],
        ["reproduce", "--help"],
        ["recover", "--help"],
        ["fit-aero", "--help"],
        ["fly", "--help"],
        ["data", "--help"],
        ["data", "fetch", "--help"],
        ["report", "--help"],
    ):
        with pytest.raises(SystemExit) as e:
            main(argv)
        assert e.value.code == 0
        assert "usage: quadest" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        main(["--version"])
    assert capsys.readouterr().out.startswith("quadest ")


def test_simulate_info_and_plot(tmp_path, capsys):
    out = tmp_path / "r.parquet"
    png = tmp_path / "r.png"
    code, text, _ = run(
        capsys,
        "simulate",
        "--scenario",
        "damaged-rotor",
        "--preset",
        "bebop2",
        "--seed",
        "2",
        "--duration",
        "8",
        "--set",
        "gyro.noise_std=0.02",
        "-o",
        str(out),
        "--plot",
        str(png),
    )
    assert code == 0 and "gyroscope saturated" in text
    rec = load_recording(out)
    assert rec.meta["config"]["gyro"]["noise_std"] == 0.02 and rec.meta["seed"] == 2
    assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"
    code, text, _ = run(capsys, "info", str(out))
    assert code == 0 and "500.00 Hz" in text and "true_q" in text and "gaps        none" in text
    code, text, _ = run(capsys, "info", "--json", str(out))
    assert code == 0 and '"imu_rate_hz": 500.0' in text


def test_same_seed_same_file(tmp_path, capsys):
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    for p in (a, b):
        assert run(capsys, "simulate", "--scenario", "throw", "--preset", "fma", "--seed", "5", "-o", str(p))[0] == 0
    assert a.read_bytes() == b.read_bytes()


def test_list_params(capsys):
    code, text, _ = run(capsys, "simulate", "--preset", "lowcost-20hz", "--list-params")
    assert code == 0 and "imu.rate_hz" in text and "20.0" in text and "QUKF paper" in text


def test_errors_are_one_line(tmp_path, capsys):
    for argv in (
        ["simulate", "--set", "gyro.nope=1", "-o", str(tmp_path / "x.csv")],
        ["simulate", "--set", "novalue", "-o", str(tmp_path / "x.csv")],
        ["simulate"],
        ["info", str(tmp_path / "missing.csv")],
    ):
        code, _, err = run(capsys, *argv)
        assert code == (1 if argv[0] == "info" else 2)  # 2: an option is wrong; 1: the data is
        assert err.count("\n") == 1 and err.startswith("quadest ") and "Traceback" not in err
    bad = tmp_path / "bad.csv"
    bad.write_text("t,gyr_x,gyr_y\n0,1,2\n")
    code, _, err = run(capsys, "info", str(bad))
    assert code == 1 and "missing column" in err


def test_demo_is_what_make_demo_runs(tmp_path, capsys):
    """`make demo` runs `quadest demo`, which is reproduce afckf with its plots, JSON and report."""
    make = (Path(__file__).resolve().parents[2] / "Makefile").read_text()
    assert "$(BIN)/quadest demo --out $(OUT)" in make
    code, text, _ = run(capsys, "demo", "--out", str(tmp_path), "--seeds", "1")
    assert code == 0 and "quadest demo: quadest reproduce afckf --plot-dir" in text
    assert json.loads((tmp_path / "afckf.json").read_text())["seeds"] == [1]
    assert (tmp_path / "report.html").stat().st_size > 10_000 and list(tmp_path.glob("afckf/*.png"))


def test_console_script_entry_point():
    r = subprocess.run([sys.executable, "-m", "quadest.cli.main", "--version"], capture_output=True, text=True)
    assert r.returncode == 0 and "quadest" in r.stdout


def test_compare_prints_tables_json_and_plots(tmp_path, capsys):
    out = tmp_path / "c.json"
    code, text, _ = run(
        capsys,
        "compare",
        "--scenario",
        "damaged-rotor",
        "--seed",
        "2",
        "--duration",
        "8",
        "--filters",
        "afckf,madgwick",
        "--from",
        "5",
        "--param",
        "afckf.beta=2",
        "--json",
        str(out),
        "--plot-dir",
        str(tmp_path / "plots"),
    )
    assert code == 0
    for title in ("RMS error [deg]", "variance [deg²]", "mean absolute error [deg]", "execution time"):
        assert title in text
    import json

    rep = json.loads(out.read_text())
    assert set(rep["filters"]) == {"afckf", "madgwick"}
    for key in ("rms_deg", "var_deg2", "mae_deg"):
        assert set(rep["filters"]["afckf"][key]) == {"roll", "pitch", "yaw"}
    assert rep["filters"]["afckf"]["us_per_sample"] > 0
    assert (tmp_path / "plots" / "error_yaw.png").is_file()


def test_compare_refuses_bad_arguments(tmp_path, capsys):
    for argv in (
        ["compare", "--filters", "nope"],
        ["compare", "--param", "afckf"],
        ["compare", "--param", "afckf.beta=x"],
    ):
        code, _, err = run(capsys, *argv, "--no-timing", "--duration", "2")
        assert code == 2 and err.count("\n") == 1


def test_reproduce_qukf_and_benchmark(tmp_path, capsys):
    code, text, _ = run(capsys, "reproduce", "qukf", "--seeds", "1-2", "--json", str(tmp_path / "q.json"))
    assert code == 0 and "paper" in text and "0.529" in text  # the published QUKF roll RMSE
    code, text, _ = run(capsys, "benchmark", "speed", "--duration", "2")
    assert code == 0 and "afckf" in text and "roetenberg" in text


def test_recovery_commands(tmp_path, capsys):
    throw = tmp_path / "throw.csv"
    assert run(capsys, "simulate", "--scenario", "throw", "--preset", "fma", "--seed", "5", "-o", str(throw))[0] == 0
    code, text, _ = run(
        capsys, "recover", str(throw), "--json", str(tmp_path / "r.json"), "--plot", str(tmp_path / "r.png")
    )
    assert code == 0 and "nominal" in text and "errors against truth" in text
    assert (tmp_path / "r.png").stat().st_size > 10_000
    aero = tmp_path / "aero.json"
    code, text, _ = run(capsys, "fit-aero", str(throw), "-o", str(aero))
    assert code == 0 and "residual RMS" in text and aero.is_file()
    code, text, _ = run(capsys, "recover", str(throw), "--aero", str(aero))
    assert code == 0 and "converged" in text
    hover = tmp_path / "hover.csv"
    run(capsys, "simulate", "--scenario", "hover", "--preset", "fma", "--duration", "5", "-o", str(hover))
    code, text, _ = run(capsys, "recover", str(hover))
    assert code == 0 and "no throw detected" in text
    code, text, _ = run(
        capsys,
        "reproduce",
        "recovery",
        "--prescribed",
        "--throws",
        "4",
        "--json",
        str(tmp_path / "rr.json"),
        "--plot-dir",
        str(tmp_path / "plots"),
    )
    assert code == 0 and "gravity error median" in text
    import json

    rep = json.loads((tmp_path / "rr.json").read_text())
    for case in ("true", "fitted", "perturbed"):
        for key in ("converged_share", "t_converge_s", "gravity_err_deg", "vel_err_mps"):
            assert key in rep["cases"][case]
    assert (tmp_path / "plots" / "recovery" / "errors_histogram.png").is_file()
    # a recording without a simulation's model needs --aero: one clear line
    from quadest import Recording, save_recording

    plain = tmp_path / "plain.csv"
    save_recording(Recording(t=np.arange(10) * 0.01, gyr=np.zeros((10, 3)), acc=np.tile([0, 0, -9.8], (10, 1))), plain)
    code, _, err = run(capsys, "recover", str(plain))
    assert code == 2 and "--aero" in err and err.count("\n") == 1


def test_fly_writes_runs_that_every_command_reads(tmp_path, capsys):
    """quadest fly: per seed a recording (read back by estimate), the flight table, a summary
    and a plot; summary.json gathers the runs; the nominal controller after a rotor loss crashes
    with its reason, the fault-tolerant one keeps the vehicle (truth in the loop)."""
    import json

    import pyarrow.parquet as pq

    out = tmp_path / "fly"
    code, text, _ = run(
        capsys,
        "fly",
        "--scenario",
        "rotor-loss",
        "--estimator",
        "truth",
        "--seeds",
        "1",
        "--duration",
        "6",
        "-o",
        str(out),
    )
    assert code == 0 and "1 of 1 runs survived" in text and "spin" in text
    summary = json.loads((out / "summary.json").read_text())
    run0 = summary["runs"][0]
    assert run0["status"] == "survived" and run0["controller"] == "ftc"
    rec = load_recording(run0["files"]["recording"])
    assert rec.meta["failure"] == {"rotor": 0, "time_s": 2.0, "efficiency": 0.0} and len(rec) == 3000
    table = pq.read_table(run0["files"]["flight"])
    assert table.num_rows == 3000 and "rotor0_cmd" in table.column_names and "est_qw" in table.column_names
    assert open(run0["files"]["plot"], "rb").read(4) == b"\x89PNG"
    code, text, _ = run(
        capsys,
        "fly",
        "--scenario",
        "rotor-loss",
        "--controller",
        "se3",
        "--estimator",
        "truth",
        "--duration",
        "6",
        "--no-plot",
        "-o",
        str(out),
    )
    assert code == 0 and "crashed" in text and "0 of 1 runs survived" in text
    code, text, _ = run(
        capsys, "estimate", run0["files"]["recording"], "--filter", "madgwick", "-o", str(tmp_path / "q.csv")
    )
    assert code == 0
    # robust's reported covariance comes out with --diagnostics
    code, text, _ = run(
        capsys,
        "estimate",
        run0["files"]["recording"],
        "--filter",
        "robust",
        "--diagnostics",
        "-o",
        str(tmp_path / "r.parquet"),
    )
    cols = pq.read_table(tmp_path / "r.parquet").column_names
    assert code == 0 and {"diag_var_tilt", "diag_var_heading", "diag_bias_z"} <= set(cols) and "diag_var_tilt" in text
    code, _, err = run(
        capsys,
        "estimate",
        run0["files"]["recording"],
        "--filter",
        "vqf",
        "--diagnostics",
        "-o",
        str(tmp_path / "v.csv"),
    )
    assert code == 2 and "reports no per-sample diagnostics" in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize(
    "argv, match",
    [
        (["--failure", "x@2"], "--failure expects"),
        (["--failure", "7@2"], "rotor 7 does not exist"),
        (["--failure", "0@99"], "outside the run"),
        (["--failure", "0@1:0.5:1e-6:2"], "--failure expects"),
        (["--failure", "0@1:1"], "needs an efficiency in [0, 1)"),
        (["--failure", "0@1:0.9:-1e-6"], "imbalance must be between"),
        (["--failure", "0@1:0.9:5"], "imbalance must be between"),
        (["--seeds", "a-b"], "--seeds expects"),
        (["--preset", "lowcost-20hz"], "position sensor"),
        (["--set", "gyro.nope=1"], "--set: gyro has no parameter 'nope'"),
        (["--set", "gyro.range=-1"], "--set: gyro.range must not be negative"),
        (["--set", "vehicle.mass_kg=0"], "--set: vehicle: mass_kg must be in (0, 1e3]"),
        (["--set", "vehicle.inertia=3"], "--set vehicle.inertia: expected a list"),
        (["--set", "se3.k_R=fast"], "--set: se3: k_R must be a finite number"),
        (["--set", "hover.spin=1"], "--set hover.spin: fly takes"),
        (["--set", "throw.speed_max=3"], "--set throw.*"),
        (["--controller", "se3", "--set", "ftc.rho=0.5"], "--set ftc.*"),
        (["--set", "gyro.range"], "--set expects key=value"),
        (["--set", "detector.lost_threshold=0.01"], "the oracle flies no detector"),
        (["--detection", "commands", "--set", "detector.rotor_speeds=1"], "the detection mode decides it"),
        (["--detection", "commands", "--set", "detector.lost_threshold=0"], "lost_threshold must be in (0, 10]"),
        (["--seeds", "0-3,2"], "--seeds 0-3,2: a seed is given twice"),
        (["--seeds", "5-3,7"], "5-3 selects no seed"),
        (["--seeds", "0-99999999999999999999999"], "seeds are at most"),
        (["--scenario", "throw", "--detection", "commands", "--set", "detector.glr=0"], "a throw flies no"),
        (["--estimator", "robust-offline"], "robust-offline is acausal"),
        (["--scenario", "throw", "--failure", "0@1"], "a throw has no rotor failure"),
        (["--duration", "-1"], "duration must be between"),
        (["--set", "flight.landing_m_s=1", "--duration", "1"], "does not fit"),
    ],
)
def test_fly_refuses_bad_options_in_one_line(tmp_path, capsys, argv, match):
    """Refused in one line, before the output folder is made."""
    code, _, err = run(capsys, "fly", "--estimator", "truth", "--duration", "3", "-o", str(tmp_path / "f"), *argv)
    assert code == 2 and match in err and "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "f").exists()


def test_fly_set_reaches_the_sensors_the_vehicle_and_the_controller(tmp_path, capsys, monkeypatch):
    """quadest fly --set: the gyroscope's range clips the recorded rates of a rotor loss (the
    settled spin is above 8.73 rad/s), the vehicle's mass sets the hover the flight starts from,
    the controller's gain reaches fly(); the recording's meta and the summary keep what was set."""
    from dataclasses import replace

    import pyarrow.parquet as pq

    import quadest.flight
    from quadest.models.multirotor import vehicle_preset

    flown = []
    real_fly = quadest.flight.fly
    monkeypatch.setattr(quadest.flight, "fly", lambda *a, **kw: flown.append(kw) or real_fly(*a, **kw))
    sets = {"gyro.range": "8.73", "vehicle.mass_kg": "0.55", "se3.k_R": "2", "ftc.rho": "0.6"}
    argv = [a for k, v in sets.items() for a in ("--set", f"{k}={v}")]
    out = tmp_path / "fly"
    code, text, _ = run(capsys, "fly", "--estimator", "truth", "--duration", "4", "--no-plot", "-o", str(out), *argv)
    assert code == 0, text
    assert flown[0]["se3"].k_R == 2.0 and flown[0]["ftc"].rho == 0.6 and flown[0]["vehicle"].mass_kg == 0.55
    run0 = json.loads((out / "summary.json").read_text())["runs"][0]
    assert run0["set"] == sets
    rec = load_recording(run0["files"]["recording"])
    assert rec.meta["set"] == sets and rec.meta["vehicle"] == "recovery" and rec.meta["config"]["gyro"]["range"] == 8.73
    assert np.abs(rec.true_gyr).max() > 10.0 and np.abs(rec.gyr).max() == pytest.approx(8.73)
    hover = replace(vehicle_preset("recovery"), mass_kg=0.55).hover_speed()
    table = pq.read_table(run0["files"]["flight"])
    assert table.column("rotor0_speed")[0].as_py() == pytest.approx(hover)
    # the controller read the gyroscope within range and the predicted rate, beyond the limit, where it clipped
    rate = np.column_stack([table.column(f"est_w{a}").to_numpy() for a in "xyz"])
    clipped = np.abs(rec.gyr) >= 8.73 * 0.995
    assert clipped.any() and (np.abs(rate[clipped]) >= 8.73 * 0.995).all()
    np.testing.assert_allclose(rate[~clipped], rec.gyr[~clipped], rtol=1e-9, atol=1e-12)
    assert "gyro_clipped_share" in run0 and run0["clip_rate_error_rms_rad_s"][2] < 1.0


def test_fly_set_reaches_the_detector(tmp_path, capsys):
    """quadest fly --set detector.*: with the 'lost' test's threshold beyond reach and the fast
    test off, the loss the default detector finds at once is never found (the controller is never
    switched, and the vehicle falls); the summary keeps what was set."""
    args = ["fly", "--scenario", "rotor-loss", "--estimator", "truth", "--detection", "rotor-speeds",
            "--duration", "3", "--failure", "0@1", "--no-plot"]  # fmt: skip
    code, text, _ = run(capsys, *args, "-o", str(tmp_path / "a"))
    found = json.loads((tmp_path / "a" / "summary.json").read_text())["runs"][0]
    assert code == 0 and found["detection"]["lost_rotor"] == 0 and found["status"] == "survived", text
    sets = ["--set", "detector.lost_threshold=10", "--set", "detector.glr=false"]
    code, text, _ = run(capsys, *args, *sets, "-o", str(tmp_path / "b"))
    blind = json.loads((tmp_path / "b" / "summary.json").read_text())["runs"][0]
    assert code == 0 and blind["detection"]["lost_rotor"] is None and blind["status"] == "crashed", text
    assert blind["set"] == {"detector.lost_threshold": "10", "detector.glr": "false"}


def test_fly_takes_the_failure_modes_and_says_a_damaged_rotor(tmp_path, capsys):
    """quadest fly --failure MODE:...: a gradual fade is flown and kept in the recording as given;
    a stopped motor is a complete loss the fault-tolerant controller flies; a partial loss the
    detector names damaged is said so (it used to print 'nothing found')."""
    base = ["fly", "--estimator", "truth", "--vehicle", "bebop2", "--duration", "5", "--no-plot"]
    code, text, _ = run(capsys, *base, "--scenario", "hover", "--failure", "gradual:0@1:0.7,ramp_s=3",
                        "-o", str(tmp_path / "g"))  # fmt: skip
    run0 = json.loads((tmp_path / "g" / "summary.json").read_text())["runs"][0]
    rec = load_recording(run0["files"]["recording"])
    assert code == 0 and rec.meta["failure"] == {"rotor": 0, "time_s": 1.0, "efficiency": 0.7, "mode": "gradual",
                                                 "ramp_s": 3.0}, text  # fmt: skip
    code, text, _ = run(capsys, *base, "--scenario", "rotor-loss", "--failure", "motor-stop:2@1",
                        "-o", str(tmp_path / "m"))  # fmt: skip
    run0 = json.loads((tmp_path / "m" / "summary.json").read_text())["runs"][0]
    assert code == 0 and run0["controller"] == "ftc" and run0["status"] == "survived", text
    code, text, _ = run(capsys, *base, "--scenario", "hover", "--detection", "rotor-speeds", "--failure", "1@2:0.6",
                        "-o", str(tmp_path / "p"))  # fmt: skip
    det = json.loads((tmp_path / "p" / "summary.json").read_text())["runs"][0]["detection"]
    assert code == 0 and det["damaged_rotor"] == 1 and "rotor 1 found damaged at" in text, text


def test_seeds_take_ranges_and_lists_together():
    from quadest.cli.common import parse_seeds

    assert parse_seeds("3-5") == range(3, 6) and parse_seeds("4") == [4] and parse_seeds("1,2") == [1, 2]
    assert parse_seeds("0-2,10-11,20") == [0, 1, 2, 10, 11, 20]


def test_fly_a_throw_with_the_recovery_and_the_oracle(tmp_path, capsys):
    """quadest fly --scenario throw: the recovery and the truth oracle per seed, the throw table
    (recovered, handover, gravity error), and the flight table's recovery state per sample. 12 s:
    the handover waits the dwell (0.5 s), so the 10 s hover of seed 0 starts 1.3 s after the release."""
    import json

    import pyarrow.parquet as pq

    out = tmp_path / "throws"
    code, text, _ = run(
        capsys,
        "fly",
        "--scenario",
        "throw",
        "--estimator",
        "all",
        "--seeds",
        "0",
        "--duration",
        "12",
        "--no-plot",
        "-o",
        str(out),
    )
    assert code == 0 and "recovered" in text and "gravity err" in text, text
    runs = json.loads((out / "summary.json").read_text())["runs"]
    assert [r["estimator"] for r in runs] == ["truth", "recovery"] and all(r["recovered"] for r in runs)
    modes = pq.read_table(runs[1]["files"]["flight"]).column("recovery_mode").to_pylist()
    assert modes[0] == 0 and modes[-1] == 2  # in the hand, waiting; at the end, nominal
    code, _, err = run(capsys, "fly", "--scenario", "throw", "--estimator", "madgwick", "-o", str(out))
    assert code == 2 and "--estimator" in err


@pytest.mark.parametrize(
    "argv, match",
    [
        (["reproduce", "qukf", "--ablations"], "are for reproduce afckf"),
        (["reproduce", "afckf", "--prescribed", "--ablations"], "leave out --prescribed"),
        (["reproduce", "afckf", "--any-direction"], "--any-direction is for reproduce recovery"),
        (["reproduce", "recovery", "--in-loop"], "are for reproduce afckf"),
        (["reproduce", "afckf", "--clipping"], "add --in-loop"),
        (["reproduce", "recovery", "--clipping"], "add --in-loop"),
        (["reproduce", "recovery", "--prescribed", "--any-direction"], "leave out --prescribed"),
        (["reproduce", "qukf", "--vehicle-range", "high"], "--vehicle-range is for reproduce afckf"),
        (["reproduce", "afckf", "--prescribed", "--vehicle-range", "low"], "--vehicle-range is for reproduce afckf"),
        (["reproduce", "afckf", "--spin-range", "--in-loop"], "--spin-range is its own run"),
        (["reproduce", "afckf", "--spin-range", "--vehicle-range", "high"], "leave out --vehicle-range"),
        (["reproduce", "afckf", "--prescribed", "--ftc", "default"], "--ftc is for reproduce afckf"),
        (["reproduce", "qukf", "--ftc", "default"], "--ftc is for reproduce afckf"),
    ],
)
def test_reproduce_refuses_options_that_do_not_fit(capsys, argv, match):
    code, _, err = run(capsys, *argv)
    assert code == 2 and match in err and len(err.strip().splitlines()) == 1, err


@pytest.mark.parametrize(
    "argv, target",
    [
        (["--in-loop"], "afckf_in_loop"),
        (["--in-loop", "--clipping"], "afckf_in_loop"),
        (["--spin-range"], "afckf_spin_range"),
        ([], "reproduce_afckf"),
    ],
)
def test_reproduce_afckf_flies_the_controller_ftc_names(capsys, monkeypatch, argv, target):
    """--ftc reaches the flown loss's parameters in every flown mode (former unless asked)."""
    from quadest.evaluation import reproduce

    for ftc in ("former", "default"):
        seen = []
        monkeypatch.setattr(reproduce, target, lambda *a, seen=seen, **kw: seen.append(kw["params"]) or {"table": []})
        monkeypatch.setattr(reproduce, "format_spin_range", lambda r: "")
        monkeypatch.setattr(reproduce, "format_reproduction", lambda paper, r: "")
        monkeypatch.setattr("quadest.evaluation.flown.format_in_loop", lambda t: "")
        extra = [] if ftc == "former" else ["--ftc", "default"]
        code, _, err = run(capsys, "reproduce", "afckf", "--seeds", "1-1", *argv, *extra)
        assert code == 0, err
        assert len(seen) == 1 and seen[0].ftc == ftc and seen[0].vehicle_range == "chosen"


def test_reproduce_recovery_flies_the_throws(tmp_path, capsys):
    """reproduce recovery (flown): throws of the rotor-level vehicle, the bank in the loop, then
    a hover; the table beside the paper's and the JSON with every run."""
    code, text, _ = run(
        capsys,
        "reproduce",
        "recovery",
        "--throws",
        "2",
        "--json",
        str(tmp_path / "r.json"),
        "--plot-dir",
        str(tmp_path / "p"),
    )
    assert code == 0 and "recovered to hover" in text and "paper: 16 of 32" in text
    import json

    r = json.loads((tmp_path / "r.json").read_text())
    case = r["cases"]["upward"]
    assert case["throws"] == 2 and len(case["runs"]) == 2 and case["detected"] == 2
    assert (tmp_path / "p" / "recovery" / "flown-throw.png").is_file()


def test_a_span_beyond_the_recording_is_one_usage_error(tmp_path, capsys):
    rec_path = tmp_path / "f.csv"
    assert main(["simulate", "--scenario", "hover", "--duration", "3", "-o", str(rec_path)]) == 0
    capsys.readouterr()
    argv = ["report", str(rec_path), "--filters", "madgwick", "--from", "500", "--to", "600"]
    code = main([*argv, "-o", str(tmp_path / "r.html")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "holds fewer than two samples" in err[0]


def test_estimate_refuses_a_declination_or_parameter_it_cannot_use(tmp_path, capsys):
    """A declination that is no angle, and a parameter the filter does not have (named before its
    value is read), are one-line usage errors; info and estimate say where a simulation's
    declination comes from."""
    rec_path = tmp_path / "f.csv"
    assert main(["simulate", "--scenario", "hover", "--duration", "2", "-o", str(rec_path)]) == 0
    capsys.readouterr()
    out = str(tmp_path / "q.csv")
    for value in ("1e9", "nan"):
        code, _, err = run(capsys, "estimate", str(rec_path), "-o", out, "--declination-deg", value)
        assert code == 2 and "lies within ±180" in err and len(err.strip().splitlines()) == 1, err
    code, _, err = run(
        capsys, "estimate", str(rec_path), "-o", out, "--filter", "madgwick", "--param", "madgwick.beta=abc"
    )
    assert code == 2 and "madgwick has no parameter beta" in err and len(err.strip().splitlines()) == 1, err
    code, text, _ = run(capsys, "info", str(rec_path))
    assert code == 0 and "declination +2.00° (the simulation's earth field)" in text


def test_every_output_option_takes_the_same_names():
    """-o, --output and --out name what a command writes, on every command that writes one."""
    from quadest.cli.main import OUTPUT_OPTIONS, build_parser

    commands = build_parser()._subparsers._group_actions[0].choices
    named = {}
    for name, sub in commands.items():
        for action in sub._actions:
            if action.dest in ("output", "out") and action.option_strings:
                named[name] = set(action.option_strings)
    assert {"estimate", "simulate", "fly", "report", "calibrate", "sweep", "campaign", "tune", "demo"} <= set(named)
    for name, strings in named.items():
        assert strings == {"-o", "--output", "--out"}, (name, strings)
    assert OUTPUT_OPTIONS["output"] == OUTPUT_OPTIONS["out"] == "-o"
