"""A cleaning.step_s that leaves a window fewer than three tidy steps: refused by validate
naming cleaning.step_s and the largest step that fits, where it said "column 'time' = 1: the
k window needs at least 3 rows" (a step of 1e5 s) or went on to a fit of three rows (4 h)."""

from __future__ import annotations

import copy

import pytest
from test_cli import setup_repo
from test_config import VEHICLE, VEHICLE_FILE, write_vehicle

from railtherm.cli import main


@pytest.mark.bad_input
@pytest.mark.parametrize("step", [1.0e5, 150.0])
def test_a_step_longer_than_a_third_of_a_window_names_cleaning_step_s(
    tmp_path, monkeypatch, capsys, step
):
    monkeypatch.chdir(tmp_path)
    setup_repo(tmp_path)
    vehicle = copy.deepcopy(VEHICLE)  # its k window lasts 4 min
    vehicle["cleaning"] = {"step_s": step}
    write_vehicle(vehicle)
    assert main(["validate", "--headers-only", VEHICLE_FILE]) == 1
    err = capsys.readouterr().err
    for fragment in (
        f"{VEHICLE_FILE}: key 'cleaning.step_s' = {step}",
        "windows.kvalue lasts 240 s, fewer than 3 tidy steps",
        "give a step of at most 80 s",
    ):
        assert fragment in err, (fragment, err)


def test_a_step_of_a_third_of_the_window_is_accepted(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    setup_repo(tmp_path)
    vehicle = copy.deepcopy(VEHICLE)
    vehicle["cleaning"] = {"step_s": 60.0}
    write_vehicle(vehicle)
    assert main(["validate", "--headers-only", VEHICLE_FILE]) == 0, capsys.readouterr().err
