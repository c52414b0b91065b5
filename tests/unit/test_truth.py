"""A truth drawn apart from the model (quadest.models.truth): every draw within the table's stated
ranges (the oracle: the table itself), applied to the model as it says, none for the ``none``
spread, the same for a seed and for every model; a flight's plant flies the truth while the
software keeps the model."""

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from quadest.errors import UsageError
from quadest.flight.spec import FlightSpec
from quadest.models.multirotor import MultirotorParams, vehicle_preset
from quadest.models.truth import (
    DEFAULT_RANGES,
    DEFAULT_SPREAD,
    TruthSpread,
    draw_truth,
    drawn_names,
    truth_spread,
)

SEEDS = st.integers(min_value=0, max_value=2**32 - 1)
MODELS = ("bebop2", "recovery", "hummingbird")


def _range_of(key: str):
    """The table's range a drawn number's name belongs to (``gyro_scale_y``: ``gyro_scale``)."""
    if key in DEFAULT_RANGES:
        return DEFAULT_RANGES[key]
    base, _, axis = key.rpartition("_")
    assert axis in DEFAULT_RANGES[base].axes
    return DEFAULT_RANGES[base]


@settings(max_examples=200, deadline=None)
@given(seed=SEEDS, model=st.sampled_from(MODELS))
def test_every_draw_lies_within_its_stated_range_and_is_applied_as_said(seed, model):
    m = vehicle_preset(model)
    t = draw_truth(m, np.random.default_rng(seed))
    assert set(t.drawn) == set(drawn_names())
    for key, v in t.drawn.items():
        if key == "max_thrust_ratio":
            continue
        r = _range_of(key)
        assert r.low <= v <= r.high, (key, v)
    d, v = t.drawn, t.vehicle
    assert v.rotor_inertia == pytest.approx(m.rotor_inertia * d["rotor_inertia_ratio"], rel=1e-12, abs=0)
    assert v.omega_max == pytest.approx(m.omega_max * d["top_speed_ratio"], rel=1e-12)
    assert v.motor_tau_s == pytest.approx(m.motor_tau_s * d["motor_tau_ratio"], rel=1e-12)
    assert v.k_f == pytest.approx(m.k_f * d["thrust_coefficient_ratio"], rel=1e-12)
    assert v.k_m == pytest.approx(m.k_m * d["torque_coefficient_ratio"], rel=1e-12)
    assert v.k_h == pytest.approx(m.k_h * d["rotor_drag_ratio"], rel=1e-12)
    assert v.k_z == pytest.approx(m.k_z * d["inflow_ratio"], rel=1e-12)
    assert np.allclose(v.body_drag, np.asarray(m.body_drag) * d["body_drag_ratio"], rtol=1e-12, atol=0)
    # the centre of mass moved by the offset: every rotor moved by minus it, horizontally only
    shift = np.asarray(v.rotor_pos) - np.asarray(m.rotor_pos)
    assert np.allclose(shift, [[-d["com_offset_m_x"], -d["com_offset_m_y"], 0.0]] * m.rotors, rtol=0, atol=1e-15)
    # max thrust at top speed: k_f Ω_max², computed from the vehicle, not from the ratios
    assert v.k_f * v.omega_max**2 / (m.k_f * m.omega_max**2) == pytest.approx(d["max_thrust_ratio"], rel=1e-12)
    # the IMU's mounting: a rotation by the drawn vector (to first order), I + [w]×
    w = np.array([d[f"imu_misalignment_rad_{a}"] for a in "xyz"])
    mis = np.asarray(t.sensors["gyro.misalignment"])
    assert np.allclose(mis @ np.array([1.0, 2.0, 3.0]), np.cross(w, [1.0, 2.0, 3.0]), rtol=0, atol=1e-15)
    assert np.degrees(np.linalg.norm(w)) <= 1.0 + 1e-12  # within 1° of the body axes
    assert t.sensors["gyro.scale"] == tuple(d[f"gyro_scale_{a}"] for a in "xyz")
    assert t.speed_noise == d["speed_noise"]


@settings(max_examples=50, deadline=None)
@given(seed=SEEDS)
def test_the_same_seed_draws_the_same_numbers_for_every_model(seed):
    a = draw_truth(vehicle_preset("bebop2"), np.random.default_rng(seed))
    b = draw_truth(vehicle_preset("bebop2"), np.random.default_rng(seed))
    c = draw_truth(vehicle_preset("hummingbird"), np.random.default_rng(seed))
    assert a == b
    assert {k: v for k, v in a.drawn.items()} == c.drawn


@settings(max_examples=50, deadline=None)
@given(seed=SEEDS, model=st.sampled_from(MODELS))
def test_no_spread_is_the_model(seed, model):
    m = vehicle_preset(model)
    rng = np.random.default_rng(seed)
    t = draw_truth(m, rng, None)
    assert t.vehicle is m and t.sensors == {} and t.speed_noise is None and t.drawn == {}
    assert rng.uniform() == np.random.default_rng(seed).uniform()  # nothing drawn


@settings(max_examples=30, deadline=None)
@given(seed=SEEDS)
def test_a_quantity_left_out_keeps_the_model_and_the_others_their_draws(seed):
    fewer = TruthSpread({k: v for k, v in DEFAULT_RANGES.items() if k != "rotor_inertia_ratio"})
    m = vehicle_preset("bebop2")
    full, part = (draw_truth(m, np.random.default_rng(seed), s) for s in (DEFAULT_SPREAD, fewer))
    assert part.vehicle.rotor_inertia == m.rotor_inertia and "rotor_inertia_ratio" not in part.drawn
    assert {k: v for k, v in full.drawn.items() if k != "rotor_inertia_ratio"} == part.drawn


def test_a_spread_is_refused_in_one_line():
    with pytest.raises(UsageError, match="unknown truth spread 'wide'; spreads: none, default"):
        truth_spread("wide")
    with pytest.raises(ValueError, match="unknown quantities mass"):
        TruthSpread({"mass": DEFAULT_RANGES["body_drag_ratio"]})
    with pytest.raises(ValueError, match="low <= high"):
        TruthSpread({"body_drag_ratio": DEFAULT_RANGES["body_drag_ratio"]._replace(low=3.0)})


def test_a_flight_flies_the_truth_and_its_software_the_model():
    """Resolved: the model is ``vehicle``; the truth the plant's, its sensors' fixed errors in the
    configuration, its rotor speed readings' noise in the flight's parameters."""
    model = FlightSpec("rotor-loss", vehicle="bebop2", seed=7).resolved()
    assert model.truth is model.vehicle and model.truth_drawn == {}
    r = FlightSpec("rotor-loss", vehicle="bebop2", seed=7, truth="default").resolved()
    assert r.vehicle == model.vehicle and r.truth != r.vehicle
    assert r.truth == draw_truth(r.vehicle, np.random.default_rng(np.random.SeedSequence([7, 41]))).vehicle
    assert r.cfg.gyro.scale == tuple(r.truth_drawn[f"gyro_scale_{a}"] for a in "xyz")
    assert r.params.speed_noise == r.truth_drawn["speed_noise"]
    assert FlightSpec("rotor-loss", vehicle="bebop2", seed=8, truth="default").resolved().truth != r.truth
    other = replace(vehicle_preset("bebop2"), rotor_inertia=1e-5)
    assert FlightSpec("rotor-loss", vehicle="bebop2", truth=other).resolved().truth is other


def test_what_cannot_fly_a_truth_is_refused_in_one_line():
    with pytest.raises(UsageError, match="a throw flies its model"):
        FlightSpec("throw", estimator="recovery", truth="default").resolved()
    with pytest.raises(UsageError, match="truth: 6 rotors, the model has 4"):
        six = MultirotorParams(rotor_pos=((0.1, 0.0, 0.0),) * 6, spin=(1.0, -1.0) * 3)
        FlightSpec("hover", truth=six).resolved()


def test_the_plant_hovers_on_the_truths_thrust():
    """A truth whose propellers give 10 % more thrust than the model's: the rotors settle at the
    truth's hover speed √(m g / (4 k_f)) (physics; 4.7 % below the model's), the model's
    controller finding it by feedback; the flight records the truth as its vehicle."""
    from quadest.flight import fly

    model = vehicle_preset("bebop2")
    truth = replace(model, k_f=model.k_f * 1.1)
    f = fly("hover", estimator="truth", vehicle="bebop2", truth=truth, duration=4.0, seed=1)
    assert f.summary["status"] == "survived" and f.vehicle is truth
    late = f.recording.t >= f.recording.t[-1] - 0.5
    speed = f.states[late, 13:].mean()
    assert speed == pytest.approx(truth.hover_speed(), rel=0.01)
    assert abs(speed / model.hover_speed() - 1) > 0.03


def test_the_docs_table_is_the_default_spread():
    """docs/truth.md's table of ranges states DEFAULT_RANGES: each quantity once, its bounds, how
    it is drawn, on which axes, and its source."""
    from pathlib import Path

    from quadest.models.truth import DEFAULT_RANGES

    text = (Path(__file__).resolve().parents[2] / "docs" / "truth.md").read_text()
    rows = {}
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 5 and cells[0].startswith("`") and cells[0].strip("`") in DEFAULT_RANGES:
            rows[cells[0].strip("`")] = cells
    assert set(rows) == set(DEFAULT_RANGES)
    for name, r in DEFAULT_RANGES.items():
        _, low, high, drawn, source = rows[name]
        assert (float(low), float(high)) == pytest.approx((r.low, r.high), abs=5e-6), name
        assert drawn.startswith("log-uniform" if r.log else "uniform"), name
        assert (f"per axis {', '.join(r.axes)}" in drawn) == bool(r.axes), name
        assert source == r.source, name
