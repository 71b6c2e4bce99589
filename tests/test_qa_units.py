"""A temperature channel in degC declared as kelvin: every value of the window lies far below
the physical range. The message says the unit, not "a spike or a faulty sensor? (empty the
cell)", which is the fix for one bad value, not for a column."""

from __future__ import annotations

import copy

import pytest
from test_cli import setup_repo
from test_config import VEHICLE, VEHICLE_FILE, write_vehicle

from railtherm.cli import main


@pytest.mark.bad_input
def test_degC_data_declared_kelvin_is_refused_naming_the_unit(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    setup_repo(tmp_path)
    vehicle = copy.deepcopy(VEHICLE)
    vehicle["channels"]["outdoor_air"] = [{"column": "T_out", "unit": "K"}]
    write_vehicle(vehicle)
    assert main(["validate", VEHICLE_FILE]) == 1
    err = capsys.readouterr().err
    for fragment in (
        "column 'T_out'",
        "degC declared as kelvin?",
        "read as degC",
        "check the unit",
    ):
        assert fragment in err, (fragment, err)
    assert "empty the cell" not in err
