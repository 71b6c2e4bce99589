"""What a newcomer's lab gets wrong, and the message that names the fix: a clock on local time,
a workbook's table on another sheet or below a title row, a window bound in the repeated hour,
units a column's name contradicts, a study config read twice differently. Every case is a
bad input whose message names the key or setting to change."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from snakemake_run import make_study, snakemake

from railtherm.config import load_vehicle
from railtherm.data import ingest
from railtherm.errors import ConfigError, DataError

pytestmark = pytest.mark.bad_input

START = pd.Timestamp("2024-10-26 12:00:00")  # local time; summer time ends 27 Oct, 03:00
COLUMNS = {"indoor": "T_int", "outdoor": "T_ext", "heater": "P_hea", "surface": "T_wall"}


def frame(step_s: float = 600.0, hours: float = 30.0) -> pd.DataFrame:
    """A local-time (Europe/Berlin) record through the end of summer time."""
    utc = (START - pd.Timedelta(hours=2)).tz_localize("UTC")
    times = utc + pd.to_timedelta(np.arange(0, hours * 3600 + 1, step_s), unit="s")
    local = times.tz_convert("Europe/Berlin").tz_localize(None)
    n = len(local)
    return pd.DataFrame(
        {
            "Zeit": local,
            "T_int": np.linspace(18.0, 22.0, n),
            "T_ext": np.full(n, -5.0),
            "P_hea": np.full(n, 2000.0),
            "T_wall": np.linspace(15.0, 19.0, n),
        }
    )


def vehicle(folder: Path, raw: str, fmt: dict, window=None, **units) -> Path:
    data = {
        "id": "Lab",
        "class": "tram",
        "mass_kg": 30000,
        "surface_m2": 250.0,
        "raw_files": {"run": raw},
        "format": {"separator": ",", "decimal": ".", **fmt},
        "channels": {
            "indoor_air": [{"column": COLUMNS["indoor"], **units.get("indoor", {})}],
            "surface": [{"column": COLUMNS["surface"], **units.get("surface", {})}],
            "outdoor_air": [{"column": COLUMNS["outdoor"], **units.get("outdoor", {})}],
            "heater_power": [{"column": COLUMNS["heater"], "unit": "W", **units.get("heater", {})}],
        },
        "windows": {
            "identification": [{"name": "all", **(window or bounds(frame(), "%Y-%m-%dT%H:%M:%S"))}]
        },
        "model": {"orders": [1], "mode": "joint"},
    }
    path = folder / "Lab.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False, allow_unicode=True), encoding="utf-8")
    return path


def csv(folder: Path, df: pd.DataFrame, pattern: str, name: str = "run.csv") -> str:
    out = df.copy()
    out["Zeit"] = out["Zeit"].dt.strftime(pattern)
    out.to_csv(folder / name, index=False)
    return name


def refused(path: Path, folder: Path) -> str:
    with pytest.raises((ConfigError, DataError)) as caught:
        load_vehicle(path, workdir=folder)
    text = str(caught.value)
    assert "\n" not in text
    return text


def read_refused(path: Path, time: dict) -> str:
    """The cleaning's reading of the raw file (what validate's value check runs)."""
    with pytest.raises(DataError) as caught:
        ingest.read_raw(path, {"separator": ",", "decimal": ".", "time": time})
    return str(caught.value)


def bounds(df: pd.DataFrame, pattern: str) -> dict:
    return {
        "start": df["Zeit"].iloc[0].strftime(pattern),
        "end": df["Zeit"].iloc[-1].strftime(pattern),
    }


# ---------------------------------------------------------------------------------------------
# a clock on local time: back by an hour at the end of summer time


@pytest.mark.parametrize(
    ("pattern", "step"),
    [
        ("%Y-%m-%dT%H:%M:%S", 600.0),
        ("%d.%m.%Y %H:%M:%S", 600.0),
        ("%m/%d/%Y %I:%M:%S %p", 600.0),
        ("%Y-%m-%dT%H:%M:%S", 10.0),
    ],
    ids=["iso", "german", "us-am-pm", "iso-10s-logger"],
)
def test_a_clock_back_by_an_hour_names_the_time_zone_settings(tmp_path, pattern, step):
    df = frame(step, hours=30.0 if step > 60 else 16.0)
    fmt = "iso" if pattern.startswith("%Y-%m-%dT") else pattern
    raw = csv(tmp_path, df, pattern)
    text = read_refused(tmp_path / raw, {"column": "Zeit", "format": fmt})
    assert "steps back by an hour" in text and "format.time.timezone" in text, text
    assert "format.time.dst: infer" in text, text


def test_a_clock_back_by_two_hours_is_no_summer_time(tmp_path):
    df = frame()
    df.loc[10:, "Zeit"] -= pd.Timedelta(hours=2)
    raw = csv(tmp_path, df, "%Y-%m-%dT%H:%M:%S")
    text = read_refused(tmp_path / raw, {"column": "Zeit", "format": "iso"})
    assert "time goes backwards" in text and "summer time" not in text, text


# ---------------------------------------------------------------------------------------------
# a window bound inside the repeated hour


@pytest.mark.parametrize("rule", ["raise", "infer"])
def test_a_bound_in_the_repeated_hour_gives_its_two_offsets(tmp_path, rule):
    df = frame()
    raw = csv(tmp_path, df, "%Y-%m-%dT%H:%M:%S")
    window = {"start": "2024-10-27T02:30:00", "end": df["Zeit"].iloc[-1].isoformat()}
    time = {"column": "Zeit", "format": "iso", "timezone": "Europe/Berlin", "dst": "infer"}
    path = vehicle(tmp_path, raw, {"time": time}, window)
    data = yaml.safe_load(path.read_text())
    data["format"]["time"]["dst"] = rule
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    text = refused(path, tmp_path)
    if rule == "infer":
        assert "key 'windows.identification[0].start'" in text, text
        assert "2024-10-27T02:30:00+02:00 (the first pass)" in text, text
        assert "line 2" not in text, text
    else:  # the column itself runs through the hour twice: its rule is named
        assert "format.time.dst" in text and "infer" in text, text


# ---------------------------------------------------------------------------------------------
# a workbook's table on another sheet, below a title row


@pytest.fixture
def workbook(tmp_path):
    pytest.importorskip("python_calamine")
    pytest.importorskip("xlsxwriter")
    df = frame()
    df["Zeit"] = df["Zeit"].dt.strftime("%Y-%m-%dT%H:%M:%S")
    path = tmp_path / "run.xlsx"
    with pd.ExcelWriter(path, engine="xlsxwriter") as book:
        pd.DataFrame({"Item": ["Vehicle"], "Value": ["Tram 7"]}).to_excel(
            book, sheet_name="Run Info", index=False
        )
        df.to_excel(book, sheet_name="Log", index=False, startrow=2)
        book.sheets["Log"].write(0, 0, "Climatic wind tunnel, run 12")
    return path


@pytest.mark.parametrize(
    ("fmt", "expected"),
    [
        ({}, "it is on sheet 'Log', row 3: set format.sheet: 'Log' and format.header_row: 2"),
        ({"sheet": "Log"}, "format.header_row: 2"),
        ({"sheet": 1}, "format.header_row: 2"),
        ({"sheet": "Log", "header_row": 1}, "format.header_row: 2"),
        ({"sheet": "Run Info", "header_row": 0}, "set format.sheet: 'Log'"),
    ],
    ids=[
        "nothing-declared",
        "sheet-by-name",
        "sheet-by-position",
        "header-row-off-by-one",
        "wrong-sheet",
    ],
)
def test_a_table_elsewhere_in_the_workbook_is_found_and_named(tmp_path, workbook, fmt, expected):
    path = vehicle(tmp_path, workbook.name, {"time": {"column": "Zeit", "format": "iso"}, **fmt})
    data = yaml.safe_load(path.read_text())
    del data["format"]["separator"], data["format"]["decimal"]
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    text = refused(path, tmp_path)
    assert expected in text, text


@pytest.mark.parametrize("group", ["indoor", "outdoor", "heater", "surface"])
def test_a_channel_on_another_sheet_names_where_it_is(tmp_path, workbook, group):
    """The time column found on the declared sheet, a channel only on another one."""
    df = frame()
    df["Zeit"] = df["Zeit"].dt.strftime("%Y-%m-%dT%H:%M:%S")
    path = tmp_path / "split.xlsx"
    with pd.ExcelWriter(path, engine="xlsxwriter") as book:
        df.drop(columns=[COLUMNS[group]]).to_excel(book, sheet_name="Main", index=False)
        df[["Zeit", COLUMNS[group]]].to_excel(book, sheet_name="Extra", index=False)
    vehicle_path = vehicle(tmp_path, path.name, {"time": {"column": "Zeit", "format": "iso"}})
    data = yaml.safe_load(vehicle_path.read_text())
    del data["format"]["separator"], data["format"]["decimal"]
    vehicle_path.write_text(yaml.safe_dump(data, sort_keys=False))
    text = refused(vehicle_path, tmp_path)
    assert f"'{COLUMNS[group]}'" in text and "it is on sheet 'Extra', row 1" in text, text


# ---------------------------------------------------------------------------------------------
# units a column's name contradicts


@pytest.mark.parametrize(
    ("group", "column", "declared", "stated"),
    [
        ("indoor", "T_int [°F]", {}, "degF"),
        ("surface", "T_wall degF", {}, "degF"),
        ("outdoor", "T_ext (Fahrenheit)", {}, "degF"),
        ("indoor", "T_int [K]", {"unit": "degC"}, "K"),
        ("outdoor", "T_ext [°C]", {"unit": "degF"}, "degC"),
        ("heater", "P_hea_kW", {"unit": "W"}, "kW"),
        ("heater", "P_hea [W]", {"unit": "kW"}, "W"),
    ],
    ids=["indoor-F", "surface-degF", "outdoor-Fahrenheit", "indoor-K", "outdoor-C", "kW", "W"],
)
def test_a_unit_the_column_name_contradicts_is_refused(tmp_path, group, column, declared, stated):
    df = frame().rename(columns={COLUMNS[group]: column})
    raw = csv(tmp_path, df, "%Y-%m-%dT%H:%M:%S")
    window = bounds(frame(), "%Y-%m-%dT%H:%M:%S")
    time = {"column": "Zeit", "format": "iso", "timezone": "Europe/Berlin", "dst": "infer"}
    COLUMNS_BACKUP = dict(COLUMNS)
    try:
        COLUMNS[group] = column
        path = vehicle(tmp_path, raw, {"time": time}, window, **{group: declared})
    finally:
        COLUMNS.clear()
        COLUMNS.update(COLUMNS_BACKUP)
    text = refused(path, tmp_path)
    assert f"declare unit: {stated}" in text and f"the column '{column}' says" in text, text
    # the same channel with its own scale is taken as declared
    data = yaml.safe_load(path.read_text())
    group_key = {"indoor": "indoor_air", "surface": "surface", "outdoor": "outdoor_air"}
    data["channels"][group_key.get(group, "heater_power")][0]["scale"] = 1.0
    path.write_text(yaml.safe_dump(data, sort_keys=False, allow_unicode=True), encoding="utf-8")
    assert load_vehicle(path, workdir=tmp_path).id == "Lab"


# ---------------------------------------------------------------------------------------------
# the study config: what validate refuses, snakemake refuses the same way


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        ("study:\n  figure3: Tram2\n", "duplicate key 'study'"),
        ("defaults:\n  model: {orders: [1]}\n", "duplicate key 'defaults'"),
        ("campaign: config/campaign.yaml\n", "duplicate key 'campaign'"),
    ],
    ids=["study-twice", "defaults-twice", "campaign-twice"],
)
def test_a_section_given_twice_stops_the_workflow_as_validate_does(tmp_path, text, reason):
    study = make_study(tmp_path)
    cfg = study / "config" / "config.yaml"
    if reason.split("'")[1] + ":" not in cfg.read_text():
        pytest.skip("the shipped config has no such section")
    cfg.write_text(cfg.read_text() + text)
    run = snakemake(study, "-n")
    said = run.stdout + run.stderr
    assert run.returncode != 0 and reason in said, said[-2000:]


# ---------------------------------------------------------------------------------------------
# numbers of the wrong unit in the time column


def test_epoch_milliseconds_declared_epoch_name_the_format(tmp_path):
    df = frame()
    seconds = (df["Zeit"] - pd.Timestamp("1970-01-01")).dt.total_seconds()
    df["Zeit"] = (seconds * 1000).astype("int64")
    df.to_csv(tmp_path / "ms.csv", index=False)
    text = read_refused(tmp_path / "ms.csv", {"column": "Zeit", "format": "epoch"})
    assert "declare format.time.format: epoch_ms" in text and "as milliseconds it is 2024" in text


def test_a_workbooks_bad_cell_is_named_by_its_row_in_the_sheet(tmp_path):
    """A text cell in a workbook below a title row and a blank row: the message gives the row
    as the spreadsheet numbers it, not a line of a CSV file."""
    pytest.importorskip("python_calamine")
    pytest.importorskip("xlsxwriter")
    df = frame()
    df["Zeit"] = df["Zeit"].dt.strftime("%Y-%m-%dT%H:%M:%S")
    df = df.astype(object)
    df.loc[3, :] = None  # a blank row: left out of the table, counted in the sheet
    df.loc[6, "T_int"] = "21,5 C"
    path = tmp_path / "run.xlsx"
    with pd.ExcelWriter(path, engine="xlsxwriter") as book:
        df.to_excel(book, sheet_name="Log", index=False, startrow=2)
    time = {"column": "Zeit", "format": "iso", "timezone": "Europe/Berlin", "dst": "infer"}
    vehicle_path = vehicle(tmp_path, path.name, {"time": time, "sheet": "Log", "header_row": 2})
    data = yaml.safe_load(vehicle_path.read_text())
    del data["format"]["separator"], data["format"]["decimal"]
    vehicle_path.write_text(yaml.safe_dump(data, sort_keys=False))
    loaded = load_vehicle(vehicle_path, workdir=tmp_path)
    with pytest.raises(DataError) as caught:
        ingest.clean_window(path, loaded.data, "all")
    # header in sheet row 3, data from row 4: the seventh data row is row 10
    assert "row 10 of sheet 'Log': not a number" in str(caught.value), str(caught.value)
