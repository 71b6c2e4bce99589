"""Vehicle and study config validation: every bad config stops with file, key and value named."""

from __future__ import annotations

import copy
import gzip
import os
from collections.abc import Callable
from typing import Any

import numpy as np
import pandas as pd
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from railtherm.config import Vehicle, load_study, load_vehicle, read_yaml
from railtherm.data.rawfile import DigestCache, RawLayout, read_layout
from railtherm.errors import ConfigError, DataError

VEHICLE_FILE = "config/vehicles/V1.yaml"
RAW_FILE = "data/V1.csv"
START = pd.Timestamp("2024-01-01T00:00:00")
STEP_S = 60.0
ROWS = 10  # 00:00 .. 00:09

COLUMNS = ["time", "T_in_1", "T_in_2", "T_surf", "T_out", "P_heat_1", "P_heat_2", "P_fan"]

VEHICLE: dict[str, Any] = {
    "id": "V1",
    "class": "tram",
    "mass_kg": 30000,
    "surface_m2": 250.0,
    "volume_m3": 120.0,
    "raw_files": {"cwt": "../../data/V1.csv"},
    "format": {"time": {"column": "time", "format": "iso"}},
    "channels": {
        "indoor_air": [{"column": "T_in_1"}, {"column": "T_in_2", "weight": 2.0}],
        "surface": [{"column": "T_surf"}],
        "outdoor_air": [{"column": "T_out"}],
        "heater_power": [
            {"column": "P_heat_1", "unit": "kW"},
            {"column": "P_heat_2", "unit": "kW"},
        ],
        "fan_power": [{"column": "P_fan", "unit": "W"}],
    },
    "windows": {
        "kvalue": {"start": "2024-01-01T00:00:00", "end": "2024-01-01T00:04:00"},
        "identification": [
            {"name": "run1", "start": "2024-01-01T00:02:00", "end": "2024-01-01T00:09:00"}
        ],
    },
    "model": {"initial": {"C": 2.0e5}, "bounds": {"C": [1.0e4, 1.0e10]}},
}

DEFAULTS: dict[str, Any] = {
    "model": {
        "orders": [1, 2],
        "initial": {"C_bar": 620480, "C": 120480, "C_veh": 500000, "K_veh": 20},
        "bounds": {"C_bar": [1.0e4, 1.0e10], "K_veh": [1.0e-2, 1.0e7]},
    }
}


def csv_text(time_format: str = "iso", columns: list[str] | None = None, sep: str = ",") -> str:
    """A small raw file: ROWS samples STEP_S apart, one column per channel."""
    columns = columns or COLUMNS
    lines = [sep.join(columns)]
    for i in range(ROWS):
        if time_format == "iso":
            time = (START + pd.Timedelta(seconds=i * STEP_S)).isoformat()
        else:
            time = f"{i * STEP_S:g}"
        # indoor near 21-22 degC, the tunnel 30 K colder: a k window eq. 10 can use
        values = {
            c: f"{20 + i * 0.1 + j - (30 if c.startswith('T_out') else 0):.2f}"
            for j, c in enumerate(columns)
        }
        values["time"] = time
        lines.append(sep.join(values[c] for c in columns))
    return "\n".join(lines) + "\n"


def write_vehicle(data: Any, path: str = VEHICLE_FILE) -> str:
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w", encoding="utf-8") as stream:
        if isinstance(data, str):
            stream.write(data)
        else:
            yaml.safe_dump(data, stream, sort_keys=False)
    return path


def write_raw(text: str, path: str = RAW_FILE) -> str:
    os.makedirs(os.path.dirname(path), exist_ok=True)
    opener = gzip.open if path.endswith(".gz") else open
    with opener(path, "wt", encoding="utf-8") as stream:
        stream.write(text)
    return path


@pytest.fixture
def repo(tmp_path, monkeypatch):
    """A working directory with one valid vehicle file and its raw file."""
    monkeypatch.chdir(tmp_path)
    write_raw(csv_text())
    write_vehicle(VEHICLE)
    return tmp_path


def mutated(change: Callable[[dict[str, Any]], Any]) -> dict[str, Any]:
    data = copy.deepcopy(VEHICLE)
    change(data)
    return data


def to_seconds(data: dict[str, Any]) -> None:
    data["format"]["time"]["format"] = "seconds"
    data["windows"]["kvalue"] = {"start": 0, "end": 240}
    data["windows"]["identification"][0].update(start="2024-01-01T00:02:00", end=540)


def two_files(data: dict[str, Any]) -> None:
    data["raw_files"]["cwt2"] = "../../data/V1.csv"


# (case id, change to the vehicle dict, raw CSV text or None, key, value, reason fragment)
BAD_VEHICLES = [
    ("missing-required", lambda d: d.pop("mass_kg"), None, "mass_kg", None, "missing required key"),
    ("negative-mass", lambda d: d.update(mass_kg=-5), None, "mass_kg", -5, "must be > 0"),
    (
        "yaml-1.1-exponent",
        lambda d: d.update(mass_kg="3.0e4"),
        None,
        "mass_kg",
        "3.0e4",
        "must be a number (YAML reads 3.0e4 as text; write 3.0e+4)",
    ),
    ("zero-surface", lambda d: d.update(surface_m2=0), None, "surface_m2", 0, "must be > 0"),
    (
        "unknown-class",
        lambda d: d.update({"class": "bus"}),
        None,
        "class",
        "bus",
        "must be one of tram, metro, regional, main-line, other",
    ),
    (
        "typo-key",
        lambda d: d["channels"]["indoor_air"][1].update(wieght=2.0),
        None,
        "channels.indoor_air[1].wieght",
        2.0,
        "unknown key (did you mean 'weight'? allowed: column, weight, unit, scale, offset, source)",
    ),
    (
        "typo-top-level",
        lambda d: d.update(volume_m=3.0),
        None,
        "volume_m",
        3.0,
        "unknown key (did you mean 'volume_m3'?",
    ),
    (
        "sensor-unit",
        lambda d: d["channels"]["outdoor_air"][0].update(unit="F"),
        None,
        "channels.outdoor_air[0].unit",
        "F",
        "must be one of degC, K",
    ),
    (
        "weight-zero",
        lambda d: d["channels"]["indoor_air"][0].update(weight=0),
        None,
        "channels.indoor_air[0].weight",
        0,
        "must be > 0",
    ),
    (
        "power-unit-missing",
        lambda d: d["channels"]["heater_power"][1].pop("unit"),
        None,
        "channels.heater_power[1].unit",
        None,
        "missing required key",
    ),
    (
        "sensor-not-in-file",
        lambda d: d["channels"]["indoor_air"][1].update(column="t_in_1"),
        None,
        "channels.indoor_air[1].column",
        "t_in_1",
        "not a column of data/V1.csv (did you mean 'T_in_1'?",
    ),
    (
        "irradiance-unit",
        lambda d: d["channels"].update(irradiance=[{"column": "I_a", "unit": "W"}]),
        csv_text(columns=[*COLUMNS, "I_a"]),
        "channels.irradiance[0].unit",
        "W",
        "must be one of W/m2, kW/m2",
    ),
    (
        "irradiance-names-clash",
        lambda d: d["channels"].update(
            irradiance=[
                {"column": "I_a", "unit": "W/m2", "name": "south"},
                {"column": "I_b", "unit": "W/m2", "name": "south"},
            ]
        ),
        csv_text(columns=[*COLUMNS, "I_a", "I_b"]),
        "channels.irradiance[1].name",
        "south",
        "input I_south already named by channels.irradiance[0].name",
    ),
    (
        "heat-flow-not-in-file",
        lambda d: d["channels"].update(heat_flows=[{"column": "P_pax", "unit": "W"}]),
        None,
        "channels.heat_flows[0].column",
        "P_pax",
        "not a column of data/V1.csv",
    ),
    (
        "column-used-twice",
        lambda d: d["channels"]["surface"][0].update(column="T_in_2"),
        None,
        "channels.surface[0].column",
        "T_in_2",
        "column already used by channels.indoor_air[1].column",
    ),
    (
        "time-column-as-channel",
        lambda d: d["channels"]["outdoor_air"][0].update(column="time"),
        None,
        "channels.outdoor_air[0].column",
        "time",
        "is the time column",
    ),
    (
        "time-column-missing",
        lambda d: d["format"]["time"].update(column="timestamp"),
        None,
        "format.time.column",
        "timestamp",
        "not a column of data/V1.csv",
    ),
    (
        "time-not-parseable",
        lambda d: None,
        csv_text().replace("2024-01-01T00:03:00", "01/01/2024 00:03"),
        "format.time.format",
        "iso",
        "line 5: not an ISO 8601 timestamp (time format iso): '01/01/2024 00:03'",
    ),
    (
        "iso-file-declared-seconds",
        to_seconds,
        None,
        "format.time.format",
        "seconds",
        "line 2: not a number of seconds (time format seconds): '2024-01-01T00:00:00'",
    ),
    (
        "window-after-data",
        lambda d: d["windows"]["identification"][0].update(end="2024-01-01T00:10:00"),
        None,
        "windows.identification[0].end",
        "2024-01-01T00:10:00",
        "outside the data: the data of data/V1.csv run from 2024-01-01T00:00:00 to "
        "2024-01-01T00:09:00",
    ),
    (
        "window-before-data",
        lambda d: d["windows"]["kvalue"].update(start="2023-12-31T23:00:00"),
        None,
        "windows.kvalue.start",
        "2023-12-31T23:00:00",
        "outside the data",
    ),
    (
        "window-start-after-end",
        lambda d: d["windows"]["kvalue"].update(end="2024-01-01T00:00:00"),
        None,
        "windows.kvalue.end",
        "2024-01-01T00:00:00",
        "must be after start ('2024-01-01T00:00:00')",
    ),
    (
        "window-file-unknown",
        lambda d: d["windows"]["identification"][0].update(file="cwt_2"),
        None,
        "windows.identification[0].file",
        "cwt_2",
        "not a key of raw_files (known: cwt)",
    ),
    (
        "window-file-required",
        two_files,
        None,
        "windows.kvalue.file",
        None,
        "required when there is more than one raw file (one of: cwt, cwt2)",
    ),
    (
        "window-not-iso",
        lambda d: d["windows"]["kvalue"].update(start="yesterday"),
        None,
        "windows.kvalue.start",
        "yesterday",
        "not an ISO 8601 timestamp",
    ),
    (
        "window-number-on-iso-file",
        lambda d: d["windows"]["kvalue"].update(start=0),
        None,
        "windows.kvalue.start",
        0,
        "must be an ISO 8601 timestamp string (format.time.format is iso)",
    ),
    (
        "window-time-zone",
        lambda d: d["windows"]["kvalue"].update(start="2024-01-01T00:00:00+01:00"),
        None,
        "windows.kvalue.start",
        "2024-01-01T00:00:00+01:00",
        "has a time zone but the timestamps of data/V1.csv have none",
    ),
    (
        "window-name-twice",
        lambda d: d["windows"]["identification"].append(dict(d["windows"]["identification"][0])),
        None,
        "windows.identification[1].name",
        "run1",
        "name already used by windows.identification[0]",
    ),
    (
        "window-name-reserved",
        lambda d: d["windows"]["identification"][0].update(name="record"),
        None,
        "windows.identification[0].name",
        "record",
        "reserved for the workflow's own tables",
    ),
    (
        "window-name-missing",
        lambda d: d["windows"]["identification"][0].pop("name"),
        None,
        "windows.identification[0].name",
        None,
        "missing required key",
    ),
    (
        "raw-file-missing",
        lambda d: d["raw_files"].update(cwt="../../data/V2.csv"),
        None,
        "raw_files.cwt",
        "../../data/V2.csv",
        "raw file not found (looked for data/V2.csv",
    ),
    (
        "bounds-reversed",
        lambda d: d["model"]["bounds"].update(C=[1.0e6, 1.0e5]),
        None,
        "model.bounds.C",
        [1.0e6, 1.0e5],
        "lower bound must be < upper bound",
    ),
    (
        "initial-outside-bounds",
        lambda d: d["model"]["initial"].update(C=10.0),
        None,
        "model.initial.C",
        10.0,
        "outside model.bounds.C = [10000, 1e+10]",
    ),
    (
        "initial-outside-default-bounds",
        lambda d: d["model"]["initial"].update(K_veh=1.0e9),
        None,
        "model.initial.K_veh",
        1.0e9,
        "outside model.bounds.K_veh = [0.01, 1e+07] (model.bounds.K_veh from the study's "
        "defaults.model)",
    ),
    (
        "order-three",
        lambda d: d["model"].update(orders=[1, 3]),
        None,
        "model.orders[1]",
        3,
        "must be one of 1, 2",
    ),
    (
        "separator-equals-decimal",
        lambda d: d["format"].update(decimal=","),
        None,
        "format.decimal",
        ",",
        "must differ from format.separator",
    ),
    (
        "bad-raw-file-name",
        lambda d: d["raw_files"].update({"1st": "../../data/V1.csv"}),
        None,
        "raw_files.1st",
        "1st",
        "invalid name",
    ),
    (  # once ZeroDivisionError or "cannot be simulated from any start" in a job
        "nan-surface",
        lambda d: d.update(surface_m2=float("nan")),
        None,
        "surface_m2",
        float("nan"),
        "not a finite number",
    ),
    ("inf-mass", lambda d: d.update(mass_kg=float("inf")), None, "mass_kg", float("inf"), "finite"),
    (
        "nan-weight",
        lambda d: d["channels"]["indoor_air"][1].update(weight=float("nan")),
        None,
        "channels.indoor_air[1].weight",
        float("nan"),
        "not a finite number",
    ),
    (
        "inf-initial-value",
        lambda d: d["model"]["initial"].update(C=float("inf")),
        None,
        "model.initial.C",
        float("inf"),
        "not a finite number",
    ),
    (  # once "dt must be > 0, got nan" in the fit, or Ljung-Box short of residuals
        "window-of-one-step",
        lambda d: d["windows"]["identification"][0].update(end="2024-01-01T00:03:00"),
        None,
        "windows.identification[0].end",
        "2024-01-01T00:03:00",
        "fewer than 3 logger steps of 60 s",
    ),
    (  # once 126 s, then a 368 MiB allocation error
        "tidy-step-far-below-the-logger",
        lambda d: d.update(cleaning={"step_s": 0.00001}),
        None,
        "cleaning.step_s",
        0.00001,
        "rows at this step, more than 5,000,000",
    ),
    (
        "first-order-hold-of-interval-means",
        lambda d: (
            d["format"].update(power_timing="mean_preceding"),
            d.setdefault("model", {}).update(input_hold="first_order"),
        ),
        None,
        "model.input_hold",
        "first_order",
        "power_timing mean_preceding says a sample is the mean over a logger interval",
    ),
    (
        "first-order-hold-with-input-noise",
        lambda d: (
            d.setdefault("model", {}).update(input_hold="first_order"),
            d.update(instruments={"power_noise_rel": 0.01}),
        ),
        None,
        "instruments.power_noise_rel",
        0.01,
        "a noisy sample drives two steps",
    ),
    (
        "nothing-to-fit",
        lambda d: d["model"].update(orders=[], structures=[]),
        None,
        "model.orders",
        [],
        "nothing to fit: list an order (1: eq. 9, 2: eqs. 7-8) or a model.structures entry",
    ),
    (  # °F data declared °C gives k -44 % and every parameter x 5/9, with a good fit
        "fahrenheit-column-read-as-celsius",
        lambda d: d["channels"]["indoor_air"][0].update(column="T_in_1 [°F]"),
        csv_text(columns=[c.replace("T_in_1", "T_in_1 [°F]") for c in COLUMNS]),
        "channels.indoor_air[0].unit",
        "degC",
        "the column 'T_in_1 [°F]' says °F: declare unit: degF",
    ),
    (
        "watt-column-declared-kilowatt",
        lambda d: d["channels"]["heater_power"][1].update(column="P_heat_2 [W]"),
        csv_text(columns=[c.replace("P_heat_2", "P_heat_2 [W]") for c in COLUMNS]),
        "channels.heater_power[1].unit",
        "kW",
        "the column 'P_heat_2 [W]' says W: declare unit: W",
    ),
    (
        "kelvin-column-declared-fahrenheit",
        lambda d: d["channels"]["outdoor_air"][0].update(column="T_out_Kelvin", unit="degF"),
        csv_text(columns=[c.replace("T_out", "T_out_Kelvin") for c in COLUMNS]),
        "channels.outdoor_air[0].unit",
        "degF",
        "says K: declare unit: K",
    ),
    (  # once a 16.5 GiB allocation: the last row's year mistyped
        "year-typo-in-the-last-row",
        lambda d: None,
        csv_text().replace("2024-01-01T00:09:00", "2042-01-01T00:09:00"),
        "raw_files",
        "data/V1.csv",
        "a typo in a timestamp (the year?)",
    ),
]


@pytest.mark.bad_input
@pytest.mark.parametrize(
    ("change", "raw", "key", "value", "reason"),
    [pytest.param(*case[1:], id=case[0]) for case in BAD_VEHICLES],
)
def test_bad_vehicle_names_file_key_and_value(repo, change, raw, key, value, reason):
    write_vehicle(mutated(change))
    if raw is not None:
        write_raw(raw)
    with pytest.raises(ConfigError) as caught:
        load_vehicle(VEHICLE_FILE, defaults=DEFAULTS)
    error = caught.value
    message = str(error)
    print(message)
    assert (error.file, error.key) == (VEHICLE_FILE, key)
    nan = isinstance(value, float) and value != value
    assert (error.value != error.value) if nan else error.value == value
    assert message.startswith(f"{VEHICLE_FILE}: key '{key}' = {value!r}: ")
    assert reason in message
    assert "\n" not in message


@pytest.mark.bad_input
@pytest.mark.parametrize(
    ("text", "key", "value", "reason"),
    [
        pytest.param(
            "id: V1\nclass: tram\nmass_kg 30000\nsurface_m2: 1\n",
            "line 3",
            "mass_kg 30000",
            "YAML syntax error: while scanning a simple key, could not find expected ':' "
            "(at line 4, column 1)",
            id="yaml-syntax",
        ),
        pytest.param(
            "id: V1\nmass_kg: 1\nclass: tram\nmass_kg: 2\n",
            "line 4",
            "mass_kg: 2",
            "duplicate key 'mass_kg' (first at line 2)",
            id="yaml-duplicate-key",
        ),
        pytest.param(
            "- id: V1\n- class: tram\n",
            "(root)",
            [{"id": "V1"}, {"class": "tram"}],
            "expected a mapping of keys (id, class, ...), got a list",
            id="not-a-mapping",
        ),
        pytest.param("", "(root)", None, "the file is empty", id="empty-file"),
    ],
)
def test_unreadable_vehicle_file(repo, text, key, value, reason):
    write_vehicle(text)
    with pytest.raises(ConfigError) as caught:
        load_vehicle(VEHICLE_FILE)
    print(caught.value)
    assert (caught.value.file, caught.value.key, caught.value.value) == (VEHICLE_FILE, key, value)
    assert reason in str(caught.value)


# ---------------------------------------------------------------------------------------------
# Study config


def study(vehicles=(VEHICLE_FILE,), **extra) -> dict[str, Any]:
    return {"vehicles": list(vehicles), "defaults": copy.deepcopy(DEFAULTS), **extra}


def test_study_loads_vehicles_in_config_order(repo):
    second = mutated(lambda d: d.update(id="A2"))
    write_vehicle(second, "config/vehicles/A2.yaml")
    loaded = load_study(study([VEHICLE_FILE, "config/vehicles/A2.yaml"]))
    assert list(loaded.vehicles) == ["V1", "A2"]
    assert loaded.campaign is None
    assert loaded.vehicles["A2"].path == "config/vehicles/A2.yaml"


@pytest.mark.bad_input
@pytest.mark.parametrize(
    ("config", "file", "key", "value", "reason"),
    [
        pytest.param(
            study([VEHICLE_FILE, "config/vehicles/V1_copy.yaml"]),
            "config/vehicles/V1_copy.yaml",
            "id",
            "V1",
            "duplicate vehicle id (also in config/vehicles/V1.yaml)",
            id="duplicate-id",
        ),
        pytest.param(
            study([VEHICLE_FILE, "config/vehicles/Tram9.yaml"]),
            "config/config.yaml",
            "vehicles[1]",
            "config/vehicles/Tram9.yaml",
            "vehicle file not found",
            id="vehicle-file-missing",
        ),
        pytest.param(
            {**study(), "defaults": {"model": {"bounds": {"C": [1.0e4]}}}},
            "config/config.yaml",
            "defaults.model.bounds.C",
            [1.0e4],
            "must have at least 2 items",
            id="defaults-bad-schema",
        ),
        pytest.param(
            {**study(), "defaults": {"model": {"inital": {"C": 1.0}}}},
            "config/config.yaml",
            "defaults.model.inital",
            {"C": 1.0},
            "unknown key (did you mean 'initial'?",
            id="defaults-typo",
        ),
        pytest.param(
            {**study(), "defaults": {"model": {"bounds": {"K_veh": [5.0, 1.0]}}}},
            "config/config.yaml",
            "defaults.model.bounds.K_veh",
            [5.0, 1.0],
            "lower bound must be < upper bound",
            id="defaults-bounds-reversed",
        ),
        pytest.param(
            study(campaign="config/campaign/none.yaml"),
            "config/config.yaml",
            "campaign",
            "config/campaign/none.yaml",
            "campaign file not found",
            id="campaign-missing",
        ),
        pytest.param(
            {"vehicles": []},
            "config/config.yaml",
            "vehicles",
            [],
            "must have at least 1 item",  # the study schema, as Snakemake's check says
            id="no-vehicles",
        ),
    ],
)
def test_bad_study(repo, config, file, key, value, reason):
    write_vehicle(VEHICLE, "config/vehicles/V1_copy.yaml")
    with pytest.raises(ConfigError) as caught:
        load_study(config)
    print(caught.value)
    assert (caught.value.file, caught.value.key, caught.value.value) == (file, key, value)
    assert reason in str(caught.value)


def test_shipped_study_config_validates(monkeypatch, tmp_path):
    """config/config.yaml and the 13 shipped vehicles, against the campaign's planned layouts."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    monkeypatch.chdir(tmp_path)  # the working directory is passed explicitly
    config = read_yaml(os.path.join(root, "config", "config.yaml"))
    loaded = load_study(config, workdir=root)
    assert list(loaded.vehicles) == [
        os.path.basename(p)[: -len(".yaml")] for p in config["vehicles"]
    ]
    for vehicle in loaded.vehicles.values():
        assert vehicle.synthetic
        assert all(
            p.startswith(f"resources/campaign/{vehicle.id}/") for p in vehicle.raw_files.values()
        )
        assert set(vehicle.model["initial"]) == {"C_bar", "C", "K_veh", "C_veh"}


def test_study_with_workdir_elsewhere(repo, monkeypatch, tmp_path_factory):
    monkeypatch.chdir(tmp_path_factory.mktemp("elsewhere"))
    loaded = load_study(study(), workdir=str(repo))
    assert loaded.vehicles["V1"].raw_files == {"cwt": "data/V1.csv"}
    assert loaded.vehicles["V1"].path == "config/vehicles/V1.yaml"


# ---------------------------------------------------------------------------------------------
# Good configs


def test_schema_defaults_are_filled(repo):
    data = mutated(lambda d: [d["channels"].pop("surface"), d["channels"].pop("fan_power")])
    write_vehicle(data)
    vehicle = load_vehicle(VEHICLE_FILE)
    assert isinstance(vehicle, Vehicle)
    assert vehicle.channels["indoor_air"][0] == {"column": "T_in_1", "weight": 1.0, "unit": "degC"}
    assert vehicle.channels["indoor_air"][1]["weight"] == 2.0
    assert vehicle.channels["surface"] == [] and vehicle.channels["fan_power"] == []
    assert vehicle.format == {
        "time": {"column": "time", "format": "iso"},
        "separator": ",",
        "decimal": ".",
        "power_timing": "instant",
    }
    assert vehicle.data["cleaning"] == {"max_gap_s": 900, "temperature_range_degC": [-80, 120]}
    assert vehicle.data["kvalue"]["force"] is False
    assert vehicle.synthetic is False
    assert (
        vehicle.data["channels"] is vehicle.channels or vehicle.data["channels"] == vehicle.channels
    )
    assert (vehicle.id, vehicle.vehicle_class, vehicle.mass_kg) == ("V1", "tram", 30000.0)


def test_defaults_model_merged_under_vehicle_model(repo):
    vehicle = load_vehicle(VEHICLE_FILE, defaults=DEFAULTS)
    assert vehicle.model == {
        "orders": [1, 2],
        "initial": {"C_bar": 620480, "C": 2.0e5, "C_veh": 500000, "K_veh": 20},
        "bounds": {"C_bar": [1.0e4, 1.0e10], "K_veh": [1.0e-2, 1.0e7], "C": [1.0e4, 1.0e10]},
    }
    assert DEFAULTS["model"]["initial"]["C"] == 120480  # the defaults are not modified
    # without the study's defaults: the vehicle's own model, and the paper's two orders
    assert load_vehicle(VEHICLE_FILE).model == {**VEHICLE["model"], "orders": [1, 2]}


def test_raw_paths_relative_to_vehicle_file_and_normalised_to_workdir(repo):
    write_raw(csv_text(), "data/deep/V1.csv")
    write_vehicle(mutated(lambda d: d["raw_files"].update(cwt="./../../data/x/../deep/V1.csv")))
    vehicle = load_vehicle(VEHICLE_FILE)
    assert vehicle.raw_files == {"cwt": os.path.join("data", "deep", "V1.csv")}
    assert vehicle.layouts["cwt"].path == vehicle.raw_files["cwt"]
    assert vehicle.path == VEHICLE_FILE


def test_planned_layout_used_when_raw_file_not_written_yet(repo):
    planned_path = "resources/campaign/V1/V1_cwt.csv.gz"
    write_vehicle(mutated(lambda d: d["raw_files"].update(cwt=f"../../{planned_path}")))
    planned = RawLayout(
        path=planned_path,
        columns=tuple(COLUMNS),
        time_column="time",
        time_format="iso",
        t_first=START,
        t_last=START + pd.Timedelta(minutes=9),
    )
    vehicle = load_vehicle(VEHICLE_FILE, layouts={planned_path: planned})
    assert vehicle.raw_files == {"cwt": planned_path}
    assert vehicle.layouts == {"cwt": planned}
    with pytest.raises(ConfigError, match="raw file not found"):
        load_vehicle(VEHICLE_FILE, layouts={"resources/campaign/V1/other.csv.gz": planned})
    short = RawLayout(planned_path, tuple(COLUMNS), "time", "iso", START, START)
    with pytest.raises(ConfigError, match=r"windows.kvalue.end.*outside the data"):
        load_vehicle(VEHICLE_FILE, layouts={planned_path: short})


def test_gz_raw_file_and_seconds_with_decimal_comma(repo):
    write_raw(csv_text("seconds", sep=";").replace(".", ","), "data/V1.csv.gz")

    def change(d):
        d["raw_files"]["cwt"] = "../../data/V1.csv.gz"
        d["format"].update(separator=";", decimal=",")
        to_seconds(d)
        d["windows"]["identification"][0]["start"] = 120

    write_vehicle(mutated(change))
    vehicle = load_vehicle(VEHICLE_FILE)
    layout = vehicle.layouts["cwt"]
    assert (layout.t_first, layout.t_last, layout.time_format) == (0.0, 540.0, "seconds")
    assert layout.columns == tuple(COLUMNS)


def test_unquoted_yaml_timestamps_are_accepted(repo):
    text = yaml.safe_dump(VEHICLE, sort_keys=False).replace(
        "'2024-01-01T00:02:00'", "2024-01-01 00:02:00"
    )
    assert "start: 2024-01-01 00:02:00" in text
    write_vehicle(text)
    vehicle = load_vehicle(VEHICLE_FILE)
    assert vehicle.windows["identification"][0]["start"] == "2024-01-01T00:02:00"


# ---------------------------------------------------------------------------------------------
# read_layout


def test_read_layout_plain_and_gz_agree(repo):
    write_raw(csv_text(), "data/V1.csv.gz")
    plain = read_layout("data/V1.csv", time_column="time", time_format="iso")
    packed = read_layout("data/V1.csv.gz", ",", ".", "time", "iso")
    assert plain.columns == packed.columns == tuple(COLUMNS)
    assert plain.t_first == packed.t_first == START
    assert plain.t_last == packed.t_last == START + pd.Timedelta(minutes=9)


@pytest.mark.bad_input
@pytest.mark.parametrize(
    ("text", "column", "value", "reason"),
    [
        pytest.param("", "", None, "the file is empty", id="empty"),
        pytest.param("a,b\n1,2\n", "time", None, "no such column (columns: a, b)", id="no-time"),
        pytest.param("time,a\n", "time", None, "no data rows", id="header-only"),
        pytest.param("time,a,a\n0,1,2\n", "a", "a", "names this column twice", id="dup-column"),
        pytest.param("time,a\n0,1\n60,2\n,3\n", "time", None, "line 4: not a number", id="empty"),
        pytest.param("time,a\n0,1\n1 min,2\n", "time", "1 min", "line 3: not a number", id="text"),
    ],
)
def test_read_layout_errors_name_file_column_value(repo, text, column, value, reason):
    write_raw(text, "data/bad.csv")
    with pytest.raises(DataError) as caught:
        read_layout("data/bad.csv", time_column="time", time_format="seconds")
    assert (caught.value.file, caught.value.key, caught.value.value) == (
        "data/bad.csv",
        column,
        value,
    )
    assert reason in str(caught.value)


@pytest.mark.bad_input
def test_read_layout_number_is_not_an_iso_timestamp(repo):
    write_raw("time,a\n3600,1\n", "data/bad.csv")
    with pytest.raises(DataError, match="line 2: not an ISO 8601 timestamp"):
        read_layout("data/bad.csv", time_column="time", time_format="iso")


@pytest.mark.bad_input
def test_read_layout_missing_file():
    with pytest.raises(DataError, match="cannot read the file"):
        read_layout("no/such/file.csv", time_column="time", time_format="iso")


@settings(max_examples=25, deadline=None)
@given(order=st.permutations(COLUMNS))
def test_column_order_does_not_matter(tmp_path_factory, order):
    workdir = tmp_path_factory.mktemp("perm")
    cwd = os.getcwd()
    os.chdir(workdir)
    try:
        write_raw(csv_text(columns=list(order)))
        write_vehicle(VEHICLE)
        vehicle = load_vehicle(VEHICLE_FILE)
    finally:
        os.chdir(cwd)
    layout = vehicle.layouts["cwt"]
    assert layout.columns == tuple(order)
    assert (layout.t_first, layout.t_last) == (START, START + pd.Timedelta(minutes=9))


def test_study_defaults_merge_under_vehicle_sections(repo):
    """defaults.kvalue / instruments / cleaning preset every vehicle; the vehicle's own key wins."""
    write_vehicle(mutated(lambda d: d.update(kvalue={"min_duration_h": 2})))
    config = {
        "vehicles": [VEHICLE_FILE],
        "defaults": {"kvalue": {"min_duration_h": 4, "max_drift_T_K": 0.2}},
    }
    settings = load_study(config).vehicles["V1"].data["kvalue"]
    assert settings["min_duration_h"] == 2  # the vehicle wins
    assert settings["max_drift_T_K"] == 0.2  # from the study's defaults
    assert settings["min_delta_T_K"] == 15  # schema default


@pytest.mark.bad_input
def test_bad_study_default_names_config_file(repo):
    config = {"vehicles": [VEHICLE_FILE], "defaults": {"instruments": {"power_u_rel": -0.1}}}
    with pytest.raises(ConfigError) as exc:
        load_study(config)
    assert "config/config.yaml" in str(exc.value)
    assert exc.value.key == "defaults.instruments.power_u_rel" and exc.value.value == -0.1


BILLION_LAUGHS = "\n".join(
    ["a: &a [lol, lol, lol, lol, lol, lol, lol, lol, lol]"]
    + [f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join([f'*{chr(97 + i)}'] * 9)}]" for i in range(8)]
    + ["bomb: *i"]
)


@pytest.mark.bad_input
def test_an_alias_bomb_is_refused_before_it_is_built(tmp_path):
    """Nine levels of nine aliases stand for 9^9 = 387 million values: refused with the file
    named, without expanding them (it takes milliseconds, not minutes and all memory)."""
    path = tmp_path / "bomb.yaml"
    path.write_text(BILLION_LAUGHS, encoding="utf-8")
    with pytest.raises(ConfigError, match="aliases .* expand to more than 100,000 values") as err:
        read_yaml(path, display="config/vehicles/bomb.yaml")
    assert err.value.file == "config/vehicles/bomb.yaml"


def test_ordinary_anchors_and_aliases_still_work(tmp_path):
    path = tmp_path / "ok.yaml"
    path.write_text("base: &b {C: 1.0e+4, K_veh: 20}\nmodel: {initial: *b}\n", encoding="utf-8")
    assert read_yaml(path)["model"]["initial"] == {"C": 1.0e4, "K_veh": 20}


@pytest.mark.bad_input
def test_digest_cache_sees_new_content_behind_an_old_mtime(tmp_path):
    """Raw files rerun their jobs on content (rule clean's param), whatever their mtime."""
    raw, store = tmp_path / "raw.csv", tmp_path / "cache" / "digests.json"
    raw.write_text("time,T\n0,20.0\n")
    cache = DigestCache(store)
    first = cache.digest(raw)
    cache.save()  # (also done at exit)
    assert first.startswith("sha256:") and store.is_file()
    assert DigestCache(store).digest(raw) == first  # from the cache, the file unchanged
    st = raw.stat()
    raw.write_text("time,T\n0,21.0\n")  # same size
    os.utime(raw, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert DigestCache(store).digest(raw) != first
    assert cache.digest(tmp_path / "gone.csv") == "missing"
    store.write_text("not json")
    assert DigestCache(store).digest(raw).startswith("sha256:")  # a broken cache is rebuilt


def test_volume_is_optional(repo):
    data = copy.deepcopy(VEHICLE)
    del data["volume_m3"]
    write_vehicle(data)
    assert load_vehicle(VEHICLE_FILE).volume_m3 is None


def _long_record(tmp_path, days: float, step_s: float, typo: bool = False) -> str:
    """A raw file of ``days`` at ``step_s``, its last row a year typo when ``typo``."""
    n = int(days * 86_400 / step_s) + 1
    t = START + pd.to_timedelta(np.arange(n) * step_s, unit="s")
    if typo:
        t = t[:-1].append(pd.DatetimeIndex([t[-1] + pd.DateOffset(years=18)]))
    frame = pd.DataFrame({c: 20.0 for c in COLUMNS[1:]}, index=range(n))
    frame.insert(0, "time", t.strftime("%Y-%m-%dT%H:%M:%S"))
    frame.to_csv(tmp_path / RAW_FILE, index=False)
    return t[-2 if typo else -1].strftime("%Y-%m-%dT%H:%M:%S")  # the last good row


@pytest.mark.bad_input
@pytest.mark.parametrize(
    ("typo", "step", "key", "reason"),
    [
        (False, None, "cleaning.step_s", "set cleaning.step_s to resample it"),
        (True, 300, "raw_files", "a typo in a timestamp (the year?)"),
    ],
    ids=["long-high-rate-record-without-step", "year-typo-with-step"],
)
def test_a_long_high_rate_record_names_the_setting_and_a_typo_stays_a_typo(
    repo, monkeypatch, typo, step, key, reason
):
    """A record longer than a tidy table may hold (58 days at 1 Hz against 5 million rows;
    here 2 days at 10 s against 10,000) is a real record: read with cleaning.step_s, and
    without it refused naming that setting; a year typo in the last row stays a typo."""
    monkeypatch.setattr("railtherm.config.MAX_ROWS", 10_000)
    end = _long_record(repo, 2.0, 10.0, typo)
    data = copy.deepcopy(VEHICLE)
    data["windows"] = {"identification": [{"name": "all", "start": START.isoformat(), "end": end}]}
    if step:
        data["cleaning"] = {"step_s": step}
    write_vehicle(data)
    with pytest.raises(ConfigError) as caught:
        load_vehicle(VEHICLE_FILE)
    assert caught.value.key == key and reason in str(caught.value), str(caught.value)
    if not typo:  # the same record resampled to 300 s is read
        data["cleaning"] = {"step_s": 300}
        write_vehicle(data)
        assert load_vehicle(VEHICLE_FILE).layouts["cwt"].step_s == 10.0
