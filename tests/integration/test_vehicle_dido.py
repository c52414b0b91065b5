"""docs/vehicle.md's three commands on the DIDO flights of ../shared/data: a vehicle identified on
two flights (``quadest identify``), the third diagnosed against it (``quadest diagnose
--vehicle``), all three ways: no failure, no damaged rotor, and the moment the detector learns
against the identified model stays within its clamp (no warning). Without ``--vehicle`` the
command says in one line which model it assumed."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from quadest.cli.main import main
from quadest.models.vehicle_file import read_vehicle_file

DATA = Path(os.environ.get("QUADEST_DATA", Path(__file__).resolve().parents[3] / "shared" / "data"))
DIDO = sorted((DATA / "dido").glob("*.hdf5"))

pytestmark = pytest.mark.skipif(
    len(DIDO) < 3, reason=f"the three DIDO flights are not in {DATA / 'dido'} (../shared/data, or QUADEST_DATA)"
)


@pytest.mark.parametrize("held", range(3), ids=lambda k: DIDO[k].stem if len(DIDO) == 3 else str(k))
def test_a_flight_the_vehicle_was_not_fitted_on_is_diagnosed_intact(tmp_path, capsys, held):
    train = [str(p) for k, p in enumerate(DIDO) if k != held]
    vehicle, found = tmp_path / "vehicle.toml", tmp_path / "diagnosis.json"
    assert main(["identify", *train, "--hold-out", str(DIDO[held]), "-o", str(vehicle)]) == 0
    said = capsys.readouterr().out
    assert f"held out {DIDO[held].name}" in said
    _, sources, identified = read_vehicle_file(vehicle)
    assert "unit reference mass" in sources["mass_kg"] and "held_out_alpha_roll" in identified
    assert main(["diagnose", str(DIDO[held]), "--vehicle", str(vehicle), "--json", str(found)]) == 0
    result = json.loads(found.read_text())
    assert result["failures"] == [] and result["damaged"] == []
    assert result["spans"] and all(span["moment_scale_clamped"] == [] for span in result["spans"])
    assert not any("clamp" in note for note in result["notes"])  # the detector's warning, kept as a note


def test_without_a_vehicle_the_assumed_model_is_said(capsys):
    assert main(["diagnose", str(DIDO[0])]) == 0
    lines = [line for line in capsys.readouterr().out.splitlines() if line.startswith("no --vehicle")]
    assert len(lines) == 1 and "default vehicle" in lines[0]
