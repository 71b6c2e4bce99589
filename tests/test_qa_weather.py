"""A plain CSV weather year with text where a number belongs: refused naming the file, the
column, the value and its line, where it raised ValueError from a float conversion."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest
from test_plausibility_energy import PROFILE, csv_year, sand_point_in

from railtherm.cli import main
from railtherm.errors import ConfigError
from railtherm.study import weather


def _with_text(path: Path, column: str, row: int, text: str) -> Path:
    table = pd.read_csv(path)
    if column not in table:
        table[column] = 0.0
    table[column] = table[column].astype(object)
    table.loc[row, column] = text
    table.to_csv(path, index=False)
    return path


@pytest.mark.bad_input
@pytest.mark.parametrize(
    "column, fix", [("T_o", "dry-bulb temperature in degC"), ("ghi", "irradiance in W/m2")]
)
def test_text_in_a_weather_column_is_refused_with_its_line(tmp_path, column, fix):
    path = _with_text(csv_year(tmp_path / "year.csv", sand_point_in("degC")), column, 5, "ERR")
    with pytest.raises(ConfigError) as err:
        weather.read_weather(path)
    assert str(err.value) == (
        f"{path}: key '{column}' = 'ERR': line 7: not a number: give the {fix}"
    )


@pytest.mark.bad_input
def test_railtherm_energy_on_such_a_year_is_one_line(tmp_path, capsys):
    path = _with_text(csv_year(tmp_path / "year.csv", sand_point_in("degC")), "T_o", 5, "ERR")
    args = ["energy", str(tmp_path / "fit.yaml"), "--weather", str(path), "--profile", str(PROFILE)]
    (tmp_path / "fit.yaml").write_text("kind: class_reference_model\n")
    assert main(args) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err and "'T_o' = 'ERR': line 7" in err, err


@pytest.mark.bad_input
def test_a_csv_year_that_does_not_start_on_1_january_is_refused(tmp_path):
    """Before: a year from 1 July was read as starting on 1 January, its July booked as
    January's heating without a word (the timestamps only checked the step)."""
    T = sand_point_in("degC")
    time = pd.date_range("2021-07-01 00:00", periods=len(T), freq="h")
    path = tmp_path / "july.csv"
    pd.DataFrame({"time": time.strftime("%Y-%m-%dT%H:%M:%S"), "T_o": T}).to_csv(path, index=False)
    with pytest.raises(ConfigError) as err:
        weather.read_weather(path)
    text = str(err.value)
    assert f"{path}: key 'time' = '2021-07-01T00:00:00'" in text
    assert "not on 1 January" in text and "reorder the rows" in text
