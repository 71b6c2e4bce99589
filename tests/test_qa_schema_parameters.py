"""model.initial and model.bounds take every registered structure's parameters, as
config/README.md and docs/structures.md say: the vehicle schema listed only those of the
first three structures, and K_f, C_f of interior_fittings were refused as unknown keys."""

from __future__ import annotations

import copy

import pytest
from test_cli import setup_repo
from test_config import VEHICLE, VEHICLE_FILE, write_vehicle

from railtherm import structures
from railtherm.cli import main


@pytest.mark.parametrize("parameter", structures.parameters())
def test_every_structure_parameter_can_be_started_and_bounded(
    tmp_path, monkeypatch, capsys, parameter
):
    monkeypatch.chdir(tmp_path)
    setup_repo(tmp_path)
    vehicle = copy.deepcopy(VEHICLE)
    vehicle["model"] = {
        "structures": ["interior_envelope", "interior_fittings"],
        "initial": {parameter: 1.0e5},
        "bounds": {parameter: [1.0, 1.0e9]},
    }
    write_vehicle(vehicle)
    assert main(["validate", "--headers-only", VEHICLE_FILE]) == 0, capsys.readouterr().err


@pytest.mark.bad_input
def test_an_unknown_parameter_is_still_refused_naming_the_known_ones(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    setup_repo(tmp_path)
    vehicle = copy.deepcopy(VEHICLE)
    vehicle["model"] = {"bounds": {"K_x": [1.0, 2.0]}}
    write_vehicle(vehicle)
    assert main(["validate", "--headers-only", VEHICLE_FILE]) == 1
    err = capsys.readouterr().err
    assert "key 'model.bounds.K_x'" in err and "unknown key" in err
    assert "K_f, C_f" in err, err
