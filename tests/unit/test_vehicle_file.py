"""The vehicle file: every preset written and read back to the same parameters bit for bit, its
sources kept; a bad file refused in one line naming the file and the key."""

import math

import pytest

from quadest.errors import UsageError
from quadest.models.multirotor import VEHICLE_PRESETS, MultirotorParams, vehicle_preset
from quadest.models.vehicle_file import preset_toml, read_vehicle, read_vehicle_file, vehicle_toml, write_vehicle


@pytest.mark.parametrize("name", list(VEHICLE_PRESETS))
def test_every_preset_round_trips(tmp_path, name):
    path = tmp_path / f"{name}.toml"
    path.write_text(preset_toml(name))
    vehicle, sources, identified = read_vehicle_file(path)
    assert vehicle == vehicle_preset(name)
    assert identified == {}
    for key, source in VEHICLE_PRESETS[name][1].items():
        assert sources[key] == source


def test_written_atomically_with_uncertainty_and_identified(tmp_path):
    path = tmp_path / "v.toml"
    ident = {"thrust_per_mass": {"value": 1.25e-6, "unit": "m/s² per (rad/s)²", "source": "fit", "uncertainty": 1e-9}}
    write_vehicle(path, MultirotorParams(mass_kg=0.7), {"mass_kg": "weighed"}, uncertainty={"mass_kg": 0.01},
                  identified=ident)  # fmt: skip
    vehicle, sources, identified = read_vehicle_file(path)
    assert vehicle.mass_kg == 0.7 and sources["mass_kg"] == "weighed"
    assert identified == ident
    assert "uncertainty = 0.01" in path.read_text()
    assert not [p for p in tmp_path.iterdir() if p.name != "v.toml"]  # no temporary left


def _bad(tmp_path, text: str) -> str:
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(UsageError) as err:
        read_vehicle(path)
    message = str(err.value)
    assert "\n" not in message and str(path) in message
    return message


HEAD = 'format = "quadest vehicle 1"\n'


@pytest.mark.parametrize(
    "text, key",
    [
        (HEAD + '[mass_kg]\nvalue = 500\nunit = "g"\nsource = "scale"\n', "mass_kg"),  # wrong unit
        (HEAD + '[mass]\nvalue = 0.5\nunit = "kg"\nsource = "scale"\n', "mass"),  # unknown key
        (HEAD + '[mass_kg]\nunit = "kg"\nsource = "scale"\n', "mass_kg"),  # no value
        (HEAD + '[k_f]\nvalue = 1e-6\nunit = "N s²"\n', "k_f"),  # no source
        (HEAD + '[mass_kg]\nvalue = -1.0\nunit = "kg"\nsource = "scale"\n', "mass_kg"),  # out of bounds
        (HEAD + '[spin]\nvalue = [1, 1, 1]\nunit = "-"\nsource = "x"\n', "spin"),  # 3 senses for 4 rotors
        (HEAD + '[k_f]\nvalue = 1e-6\nunit = "N s²"\nsource = "x"\nsigma = 1\n', "k_f"),  # unknown entry
        ('[mass_kg]\nvalue = 0.5\nunit = "kg"\nsource = "x"\n', "format"),  # not a vehicle file
        (HEAD + "[mass_kg\n", "TOML"),
    ],
)
def test_a_bad_file_is_refused_in_one_line_naming_the_key(tmp_path, text, key):
    assert key in _bad(tmp_path, text)


def test_units_written_with_carets_are_the_same_units(tmp_path):
    path = tmp_path / "v.toml"
    path.write_text(HEAD + '[inertia]\nvalue = [0.01, 0.01, 0.02]\nunit = "kg m^2"\nsource = "CAD"\n')
    assert read_vehicle(path).inertia == (0.01, 0.01, 0.02)


def test_non_finite_and_numpy_numbers_are_written_as_toml():
    text = vehicle_toml(MultirotorParams(), identified={"x": {"value": math.inf, "unit": "-", "source": "s"}})
    assert "value = inf" in text and "np.float64" not in text
