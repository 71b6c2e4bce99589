"""`railtherm new-vehicle`: a starter vehicle YAML from a raw logger file, which `railtherm
validate` refuses until its TODOs are filled and accepts afterwards."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from test_validation import renamed_copy

from railtherm.cli import main
from railtherm.data.starter import GUESSED, channel_group, starter_vehicle

REPO = Path(__file__).resolve().parents[1]
RAW = REPO / "data" / "armadillo" / "armadillo_data_H2.csv"
# what a user would write for the Armadillo Box (validation/config/vehicles/Armadillo.yaml)
FILLED = {"class": "other", "mass_kg": "20000", "surface_m2": "162", "volume_m3": "113"}


def armadillo_copy(folder: Path) -> Path:
    path = folder / "armadillo_data_H2.csv"
    shutil.copyfile(RAW, path)
    return path


def armadillo_gz(folder: Path) -> Path:
    path = folder / "armadillo_data_H2.csv.gz"
    pd.read_csv(RAW).to_csv(path, index=False)  # compressed by the extension
    return path


def iso_file(folder: Path, separator: str = ",") -> Path:
    """200 rows at 60 s with ISO timestamps, two indoor sensors and a heater in W."""
    n = np.arange(200)
    table = pd.DataFrame(
        {
            "timestamp": pd.date_range("2024-01-16T02:00:00", periods=200, freq="60s").strftime(
                "%Y-%m-%dT%H:%M:%S"
            ),
            "T_in_1": 20.0 + 0.01 * n,
            "T_in_2": 20.5 + 0.01 * n,
            "T_out": np.full(200, -5.0),
            "P_heat": np.full(200, 3000.0),
        }
    )
    path = folder / "cwt_run.csv"
    table.to_csv(path, sep=separator, index=False)
    return path


def todo_keys(todos: list[str]) -> list[str]:
    return [todo.split(":", 1)[0] for todo in todos]


def fill(path: Path, todos: list[str], values: dict[str, str]) -> None:
    """Replace the placeholder of each listed TODO, as a user would in an editor."""
    text = path.read_text(encoding="utf-8")
    for key in todo_keys(todos):
        text, count = re.subn(rf"^{key}: TODO\b", f"{key}: {values[key]}", text, flags=re.M)
        assert count == 1, key
    assert not re.search(r"^[^#\n]*TODO", text, flags=re.M), "a placeholder is left"
    path.write_text(text, encoding="utf-8")


def new_vehicle(tmp_path: Path, raw: Path, capsys, name: str = "V1") -> tuple[Path, list[str]]:
    """Run the command with --out in config/vehicles/ and return the file and its TODO list."""
    out = Path("config") / "vehicles" / f"{name}.yaml"
    assert main(["new-vehicle", str(raw.relative_to(tmp_path)), "--out", str(out)]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert printed[0] == f"wrote {out}"
    todos = [line.strip() for line in printed[2:] if line.startswith("  ")]
    return tmp_path / out, todos


@pytest.mark.parametrize(
    ("make", "separator", "decimal", "time_column", "channels"),
    [
        (
            armadillo_copy,
            ",",
            ".",
            "Time",
            {
                "indoor_air": [{"column": "T_int"}],
                "outdoor_air": [{"column": "T_ext"}],
                "heater_power": [{"column": "P_hea", "unit": "W"}],
                "irradiance": [{"column": "I_sol", "unit": "W/m2"}],
            },
        ),
        (
            armadillo_gz,
            ",",
            ".",
            "Time",
            {
                "indoor_air": [{"column": "T_int"}],
                "outdoor_air": [{"column": "T_ext"}],
                "heater_power": [{"column": "P_hea", "unit": "W"}],
                "irradiance": [{"column": "I_sol", "unit": "W/m2"}],
            },
        ),
        (
            renamed_copy,
            ";",
            ",",
            "Zeit_s",
            {
                "indoor_air": [{"column": "Innen_K", "unit": "K"}],
                "outdoor_air": [{"column": "Aussen_C"}],
                "heater_power": [{"column": "Heizung_kW", "unit": "kW"}],
                "irradiance": [{"column": "Strahlung", "unit": "W/m2"}],
            },
        ),
    ],
    ids=["armadillo", "armadillo-gz", "semicolon-decimal-comma"],
)
def test_starter_detects_the_format_and_validates_once_filled(
    tmp_path, monkeypatch, capsys, make, separator, decimal, time_column, channels
):
    monkeypatch.chdir(tmp_path)  # no config/config.yaml: the file is checked on its own
    (tmp_path / "data").mkdir()
    raw = make(tmp_path / "data")
    path, todos = new_vehicle(tmp_path, raw, capsys)
    data = yaml.safe_load(path.read_text(encoding="utf-8"))
    assert data["format"] == {
        "separator": separator,
        "decimal": decimal,
        "time": {"column": time_column, "format": "seconds"},
    }
    assert data["channels"] == channels
    assert data["raw_files"] == {data["id"]: f"../../data/{raw.name}"}
    assert data["windows"] == {"identification": [{"name": "whole", "start": 0, "end": 417600}]}
    text = path.read_text(encoding="utf-8")
    assert text.count(GUESSED) == 1 + sum(len(c) for c in channels.values())  # + time column
    assert "# logger step: 1800 s" in text and "# kvalue:" in text

    assert todo_keys(todos) == ["class", "mass_kg", "surface_m2"]
    assert main(["validate", str(path.relative_to(tmp_path))]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "'TODO'" in err
    assert any(f"key '{key}'" in err for key in todo_keys(todos)), err

    fill(path, todos, FILLED)
    assert main(["validate", str(path.relative_to(tmp_path))]) == 0
    assert capsys.readouterr().out.startswith("ok: 1 vehicle, values of 1 window checked")


@pytest.mark.parametrize("separator", [",", "\t"], ids=["comma", "tab"])
def test_iso_timestamps_and_two_indoor_sensors(tmp_path, monkeypatch, capsys, separator):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "data").mkdir()
    path, todos = new_vehicle(tmp_path, iso_file(tmp_path / "data", separator), capsys)
    data = yaml.safe_load(path.read_text(encoding="utf-8"))
    assert data["format"] == {
        "separator": separator,
        "decimal": ".",
        "time": {"column": "timestamp", "format": "iso"},
    }
    assert data["channels"] == {
        "indoor_air": [{"column": "T_in_1"}, {"column": "T_in_2"}],
        "outdoor_air": [{"column": "T_out"}],
        "heater_power": [{"column": "P_heat", "unit": "W"}],
    }
    assert data["windows"]["identification"] == [
        {"name": "whole", "start": "2024-01-16T02:00:00", "end": "2024-01-16T05:19:00"}
    ]
    assert "# logger step: 60 s" in path.read_text(encoding="utf-8")
    fill(path, todos, {**FILLED, "class": "tram"})
    assert main(["validate", str(path.relative_to(tmp_path))]) == 0


def test_an_unsupported_time_format_is_a_todo(tmp_path, monkeypatch):
    """A notation no common pattern reads (hours written 02h00) is said so, not invented."""
    monkeypatch.chdir(tmp_path)
    raw = tmp_path / "messung.csv"
    raw.write_text(
        "Datum;T_innen;T_aussen;P_Heizung_kW\n"
        "16.01.2024 02h00;20,1;-5,0;3,0\n16.01.2024 02h01;20,2;-5,0;3,0\n",
        encoding="utf-8",
    )
    text, todos = starter_vehicle(raw)
    assert "format.time.format" in todo_keys(todos)
    todo = next(t for t in todos if t.startswith("format.time.format"))
    assert "'16.01.2024 02h00'" in todo and "strftime pattern" in todo
    data = yaml.safe_load(text)
    assert data["format"]["time"] == {"column": "Datum", "format": "TODO"}
    assert data["format"]["decimal"] == ","
    assert data["channels"]["heater_power"] == [{"column": "P_Heizung_kW", "unit": "kW"}]
    assert data["windows"]["identification"][0]["start"] == "TODO"
    Path("V.yaml").write_text(text, encoding="utf-8")
    assert main(["validate", "V.yaml"]) == 1


def test_a_missing_channel_group_is_a_todo(tmp_path):
    raw = tmp_path / "run.csv"
    raw.write_text("time,T_cabin,T_ambient,x\n0,20,5,1\n60,20,5,1\n120,20,5,1\n", encoding="utf-8")
    text, todos = starter_vehicle(raw, vehicle_id="Tram7", yaml_dir=tmp_path)
    assert todo_keys(todos)[-1] == "channels.heater_power"
    data = yaml.safe_load(text)
    assert data["id"] == "Tram7" and data["channels"]["heater_power"] == [{"column": "TODO"}]
    assert "# not mapped: x" in text


def test_a_column_that_does_not_increase_is_no_time_column(tmp_path):
    raw = tmp_path / "run.csv"
    raw.write_text("T1,T2\n20,5\n19,5\n21,5\n", encoding="utf-8")
    text, todos = starter_vehicle(raw)
    assert todo_keys(todos)[3:5] == ["format.time.column", "format.time.format"]
    assert "'T1' does not increase" in todos[3] and "# not mapped: T1, T2" in text
    assert yaml.safe_load(text)["format"]["time"] == {"column": "TODO", "format": "TODO"}


def test_refuses_to_overwrite_and_prints_without_out(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    raw = armadillo_copy(tmp_path)
    Path("V1.yaml").write_text("keep me\n", encoding="utf-8")
    assert main(["new-vehicle", raw.name, "--out", "V1.yaml"]) == 1
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.count("\n") == 1
    assert captured.err.startswith("V1.yaml: ") and "exists already" in captured.err
    assert Path("V1.yaml").read_text(encoding="utf-8") == "keep me\n"

    assert main(["new-vehicle", raw.name, "--id", "Box"]) == 0
    captured = capsys.readouterr()
    data = yaml.safe_load(captured.out)  # stdout holds the YAML alone
    assert data["id"] == "Box" and data["raw_files"] == {"armadillo_data_H2": raw.name}
    assert "class: the vehicle class" in captured.err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["V1.yaml", raw.name]


@pytest.mark.parametrize(
    ("content", "reason"),
    [
        ("", "the file is empty"),
        ("Time\n0\n60\n", "one column"),
        ("Time|T_int|T_ext\n0|20|5\n", "format.separator '|' by hand"),
        ("Time,T_int\n", "no data rows"),
    ],
    ids=["empty", "one-column", "pipe", "header-only"],
)
def test_an_unusable_file_gives_one_line_naming_it(tmp_path, monkeypatch, capsys, content, reason):
    monkeypatch.chdir(tmp_path)
    Path("raw.csv").write_text(content, encoding="utf-8")
    assert main(["new-vehicle", "raw.csv", "--out", "V.yaml"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("raw.csv: ") and err.count("\n") == 1 and reason in err, err
    assert not Path("V.yaml").exists()


@pytest.mark.parametrize(
    ("argv", "start"),
    [
        (["new-vehicle", "missing.csv"], "missing.csv: key '(file)'"),
        (["new-vehicle", "raw.csv", "--id", "1st"], "--id: key 'id' = '1st'"),
    ],
)
def test_bad_arguments(tmp_path, monkeypatch, capsys, argv, start):
    monkeypatch.chdir(tmp_path)
    armadillo_copy(tmp_path).rename("raw.csv")
    assert main(argv) == 1
    assert capsys.readouterr().err.startswith(start)


@pytest.mark.parametrize(
    ("column", "group"),
    [
        ("T_int", "indoor_air"),
        ("T_in_3", "indoor_air"),
        ("Innentemperatur", "indoor_air"),
        ("Cabin_air", "indoor_air"),
        ("T_ext", "outdoor_air"),
        ("Außen", "outdoor_air"),
        ("T_ambient", "outdoor_air"),
        ("T_Wand_links", "surface"),
        ("Oberfläche_Boden", "surface"),
        ("P_hea", "heater_power"),
        ("Heizleistung_kW", "heater_power"),
        ("P_Lüfter", "fan_power"),
        ("fan_power_W", "fan_power"),
        ("I_sol", "irradiance"),
        ("Globalstrahlung", "irradiance"),
        ("Zeit_in_s", None),
        ("RH_percent", None),
    ],
)
def test_channel_group_from_the_name(column, group):
    assert channel_group(column) == group
