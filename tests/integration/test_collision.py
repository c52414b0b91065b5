"""A lost estimate in flight recovered: a collision flown with the divergence checks and the
recovery paper's bank of EKFs in the loop, a nominal flight that never starts a recovery, and the
checks changing nothing until they fire."""

import json

import numpy as np
import pytest

from quadest.cli.main import main
from quadest.errors import UsageError
from quadest.flight import FlightParams, fly
from quadest.flight.phases import PHASES
from quadest.recovery.divergence import CHECKS

ALL = ",".join(CHECKS)


def test_a_collision_is_recovered_to_a_hover_by_the_bank_started_in_flight():
    """Seed 1002 (a training seed): in hover, 4.6 m/s and 19.4 rad/s at 2.6 s with the estimator
    reset to a random attitude. The impact is seen on the next sample (its specific force beyond
    the rotors' reach), the logic waits for the free fall as the rotors spin down, the bank hands
    over 0.5 s (the dwell) after it with the gravity direction within 15° (the throws' worst is
    about 10°), and the vehicle is upright and holds its height within 0.5 m for 10 s."""
    f = fly("hover", estimator="robust", seed=1002, duration=16.0, params=FlightParams(collision="drawn"))
    s = f.summary
    c = s["collision"]
    assert c["estimator"] == "reset" and c["rate_rad_s"] > 15.0 and c["speed_m_s"] > 4.0, c
    assert s["recovery_started"] and "impact" in s["checks"] and 0.0 < s["divergence_delay_s"] <= 0.002, s
    assert 0.5 <= s["handover_s"] < 1.0 and s["gravity_error_at_handover_deg"] < 15.0, s
    assert s["status"] == "survived" and s["recovered"] and s["fall_m"] < 10.0, s
    seen = [PHASES[m] for m in dict.fromkeys(f.modes.tolist())]
    assert seen == ["flying", "waiting", "converging", "nominal"], seen


def test_a_nominal_figure_eight_never_starts_a_recovery_and_the_checks_change_nothing():
    """The figure eight (7-12 m/s², 5-8 rad/s) for 20 s with every check on: none fires, each
    statistic stays below half its threshold, and the flight equals the one without the checks
    bit for bit (they only watch until they fire)."""
    kw = dict(estimator="robust", seed=5, duration=20.0, preset="fma")
    on = fly("aggressive", params=FlightParams(divergence=ALL), **kw)
    off = fly("aggressive", params=FlightParams(divergence="off"), **kw)
    assert on.summary["recovery_started"] is False and on.summary["status"] == "survived"
    assert max(on.summary["check_peaks"].values()) < 0.5, on.summary["check_peaks"]
    assert np.array_equal(on.states, off.states) and np.array_equal(on.q_est, off.q_est)


def test_the_same_collision_without_the_checks_crashes_and_a_throw_takes_none():
    """Seed 1002's collision with the checks off: the nominal loop (robust restarted mid-tumble,
    SE(3)) loses the vehicle, which the recovery above brought back."""
    f = fly(
        "hover", estimator="robust", seed=1002, duration=16.0, params=FlightParams(collision="drawn", divergence="off")
    )
    assert f.summary["recovery_started"] is False and f.summary["recovered"] is False
    assert f.summary["status"] == "crashed" and f.modes is None, f.summary
    with pytest.raises(UsageError, match="throw"):
        fly("throw", estimator="recovery", params=FlightParams(collision="drawn"))
    with pytest.raises(ValueError, match="divergence"):
        FlightParams(divergence="impact,wobble")


def test_the_command_line_flies_a_collision_and_refuses_a_bad_check_in_one_line(tmp_path, capsys):
    assert main(["fly", "--scenario", "hover", "--estimator", "robust", "--collision", "drawn", "--seeds", "1002",
                 "--no-plot", "-o", str(tmp_path)]) == 0  # fmt: skip
    out = capsys.readouterr()
    assert "recovery started by impact" in out.out + out.err and "; recovered" in out.out + out.err
    assert main(["fly", "--divergence", "impact,wobble", "-o", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--divergence" in err[0] and "Traceback" not in err[0]


def test_the_benchmark_flies_each_ablation_on_the_same_collision_and_writes_json(tmp_path, capsys):
    out = tmp_path / "c.json"
    argv = ["benchmark", "collisions", "--seeds", "1002", "--nominal-seeds", "1", "--duration", "3", "--json", str(out)]
    assert main(argv) == 0
    res = json.loads(out.read_text())
    cases = res["cases"]
    assert list(cases) == ["all checks", "impact only", "rate only", "innovation only", "no checks"]
    assert cases["all checks"]["recovered"] == 1 and cases["no checks"]["recovered"] == 0  # as flown above
    assert cases["no checks"]["detected"] == 0 and cases["impact only"]["first_by_check"]["impact"] == 1
    assert res["nominal"]["flights"] == 1 and res["nominal"]["recovery_started"] == 0
    assert "recovered 1/1" in capsys.readouterr().out
