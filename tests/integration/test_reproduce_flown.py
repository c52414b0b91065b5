"""The AFCKF paper's experiment on the flying vehicle: the flights
survive the loss, spin and tilt are outputs, and the ablation table has every row, each
changing what physics says it changes."""

import numpy as np
import pytest

from quadest.evaluation.flown import ABLATIONS, LABELS, FlownAfckfParams
from quadest.evaluation.reproduce import format_reproduction, reproduce_afckf

P = FlownAfckfParams(duration_s=15.0)  # 10 s after the loss, to keep the test short


@pytest.fixture(scope="module")
def flown():
    return reproduce_afckf([1], ablations=True, params=P)


def test_the_flown_loss_settles_and_its_spin_is_an_output(flown):
    f = flown["flights"]["damaged-rotor"]
    assert f["per_seed"][0]["status"] == "survived"
    # the Bebop 2's relaxed hover (docs/vehicle.md): 11.8 rad/s, 26°; below the gyro's ±1000°/s
    assert 10.0 < f["spin_rate_rad_s"] < 14.0 and 20.0 < f["tilt_deg"] < 30.0
    assert f["peak_rate_rad_s"] < np.radians(1000.0) and f["gyro_clipped_share"] == 0.0
    assert flown["flights"]["nominal"]["spin_rate_rad_s"] is None
    for case in ("damaged-rotor", "damaged-rotor-trajectory", "nominal"):
        for label in LABELS:
            assert all(np.isfinite(v) for v in flown["cases"][case][label]["rms_deg"].values())
    text = format_reproduction("afckf", flown)
    assert "paper: 15.5 rad/s" in text and "each row changes one thing" in text


def test_the_ablations_change_what_physics_says(flown):
    rows = {r["change"]: r for r in flown["ablations"]}
    assert list(rows) == [label for label, _, _ in ABLATIONS]
    base = rows["baseline: bebop2 sensors"]
    for label in LABELS:
        # nothing clips at ±1000°/s, so a wider range reads the same samples
        assert rows["gyro range ±2000°/s"][label] == base[label]
        # below the spin rate the gyroscope clips: the heading is lost
        assert rows["gyro range ±500°/s"][label]["yaw"] > 3 * base[label]["yaw"]
    # a 10 ms old field is 7° of heading at 11.8 rad/s: the magnetometer-led filters lose accuracy
    for label in ("valenti", "roetenberg", "afckf"):
        assert rows["magnetometer latency 10 ms"][label]["yaw"] > base[label]["yaw"] + 1.0
    # Madgwick's heading follows the gyroscope: without a scale error it drifts less
    assert rows["gyro scale error 0"]["madgwick"]["yaw"] < base["madgwick"]["yaw"]


def test_estimators_in_the_loop_after_the_loss():
    """Part 3: the loss with an estimator in the fault-tolerant controller's loop. With the
    bebop2 sensors the truth and Madgwick's filter keep the vehicle up and in place; with a
    gyroscope that clips below the spin the truth loses it when the controller damps with the
    clipped reading (the clipping ablation's flight.clip_rate off), and keeps it with the
    predicted rate, whose error on the clipped samples the table carries."""
    from quadest.evaluation.flown import CLIP_VARIANTS, IN_LOOP_VARIANTS, in_loop_seed, in_loop_table

    runs = in_loop_seed((*IN_LOOP_VARIANTS[0], 1, FlownAfckfParams(), ["truth", "madgwick"]))
    for label, overrides in (CLIP_VARIANTS[0], CLIP_VARIANTS[2]):
        runs += in_loop_seed((label, overrides, 1, FlownAfckfParams(), ["truth"]))
    rows = {(r["variant"], r["estimator"]): r for r in in_loop_table(runs)}
    truth, madgwick = rows[("baseline: bebop2 sensors", "truth")], rows[("baseline: bebop2 sensors", "madgwick")]
    assert truth["survived"] == truth["settled"] == 1 and madgwick["survived"] == madgwick["settled"] == 1
    assert madgwick["tilt_error_after_loss_deg"] < 5.0 and madgwick["tilt_error_offline_deg"] < 5.0
    assert "gyro_clipped_share" not in truth  # the bebop2 sensors' ±1000°/s does not clip in this spin
    assert rows[(CLIP_VARIANTS[0][0], "truth")]["survived"] == 0
    predicted = rows[(CLIP_VARIANTS[2][0], "truth")]
    assert predicted["survived"] == 1 and predicted["gyro_clipped_share"] > 0.9
    assert predicted["clip_rate_error_rms_rad_s"][2] < 0.5
