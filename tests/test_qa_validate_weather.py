"""`railtherm validate` reads the study's typical years (energy.weather) as the rule energy
will: a year in degF or K, or of another length, stops there, not after every fit."""

from __future__ import annotations

import pytest
from test_cli import setup_repo
from test_plausibility_energy import csv_year, energy_study, sand_point_in, write_profile

from railtherm.cli import main


@pytest.mark.bad_input
@pytest.mark.parametrize(
    "unit, fragments",
    [
        ("degF", ["year.csv", "'T_o'", "read as degF", "check the unit"]),
        ("K", ["year.csv", "'T_o'", "read as K", "check the unit"]),
    ],
)
def test_validate_refuses_a_weather_year_in_another_unit(
    tmp_path, monkeypatch, capsys, unit, fragments
):
    """Before: `railtherm validate` said ok (it checked only that the file exists); the rule
    energy stopped on the year after the study's fits."""
    monkeypatch.chdir(tmp_path)
    setup_repo(tmp_path)
    write_profile(tmp_path / "profile.yaml")
    csv_year(tmp_path / "year.csv", sand_point_in(unit))
    energy_study(weather=["year.csv"], profile="profile.yaml")
    assert main(["validate"]) == 1
    err = capsys.readouterr().err
    for fragment in fragments:
        assert fragment in err, (fragment, err)


@pytest.mark.bad_input
def test_validate_refuses_a_weather_file_that_is_not_a_year(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    setup_repo(tmp_path)
    write_profile(tmp_path / "profile.yaml")
    csv_year(tmp_path / "year.csv", sand_point_in("degC")[:-24])
    energy_study(weather=["year.csv"], profile="profile.yaml")
    assert main(["validate"]) == 1
    err = capsys.readouterr().err
    assert "year.csv: key 'records' = 8736" in err and "8760 (or 8784)" in err, err


def test_validate_reads_a_sound_year_and_says_so(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    setup_repo(tmp_path)
    write_profile(tmp_path / "profile.yaml")
    csv_year(tmp_path / "year.csv", sand_point_in("degC"))
    energy_study(weather=["year.csv"], profile="profile.yaml")
    assert main(["validate"]) == 0, capsys.readouterr().err
    assert capsys.readouterr().out.endswith(", 1 weather year read\n")
