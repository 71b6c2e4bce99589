"""Simulation scenarios as data (railtherm.study.scenario): the shipped ones, every kind of profile,
and the bad scenarios, each stopped by one message naming the file, the key and the value."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest
import yaml

from railtherm.errors import ConfigError
from railtherm.study.scenario import (
    CP_AIR_J_KG_K,
    RHO_AIR_KG_M3,
    Controller,
    Initial,
    Scenario,
    load_scenario,
)

REPO = Path(__file__).resolve().parents[1]
SHIPPED = REPO / "config" / "scenarios"


def write(tmp_path: Path, data: dict | str, name: str = "scn.yaml") -> Path:
    path = tmp_path / name
    text = textwrap.dedent(data) if isinstance(data, str) else yaml.safe_dump(data)
    path.write_text(text, encoding="utf-8")
    return path


def base(**over) -> dict:
    """A minimal valid scenario with keys put over it (a value None removes the key)."""
    data = {
        "source": "test",
        "duration_h": 2,
        "step_s": 60,
        "outdoor": {"constant_C": -10},
        "heating": {"power_W": 1000},
    }
    data.update(over)
    return {k: v for k, v in data.items() if v is not None}


# ---------------------------------------------------------------------------------------------
# The shipped scenarios


def test_every_shipped_scenario_loads_and_says_where_its_numbers_come_from():
    files = sorted(SHIPPED.glob("*.yaml"))
    assert {f.stem for f in files} == {"preheat_cold_soak", "winter_day", "cool_down"}
    for path in files:
        scn = load_scenario(path)
        assert isinstance(scn, Scenario)
        assert scn.name == path.stem and scn.file == str(path)
        assert scn.source and "assumption" in scn.source.lower()
        n = round(scn.duration_s / scn.dt_s)
        for array in (scn.t_s, scn.T_o, scn.air_exchange_W_K, scn.gains_W):
            assert array.shape == (n + 1,)
        assert scn.t_s[-1] == scn.duration_s


def test_preheat_cold_soak():
    scn = load_scenario(SHIPPED / "preheat_cold_soak.yaml")
    assert scn.dt_s == 60 and scn.duration_s == 12 * 3600 and scn.t_s.shape == (721,)
    assert np.all(scn.T_o == -20)
    assert scn.heating_W is None
    assert scn.controller == Controller(
        kind="thermostat", setpoint_C=15, power_max_W=60000, power_min_W=0, hysteresis_K=1.0
    )
    assert scn.gains == {} and np.all(scn.gains_W == 0) and np.all(scn.air_exchange_W_K == 0)
    assert scn.initial == Initial("soaked")
    assert scn.heat_up_to_C == 15 and scn.cool_down_to_C is None


def test_winter_day():
    scn = load_scenario(SHIPPED / "winter_day.yaml")
    assert scn.t_s.shape == (24 * 60 + 1,)
    hour = 60  # grid points per hour
    csv = np.loadtxt(SHIPPED / "winter_day_outdoor.csv", delimiter=",", skiprows=1)
    assert np.allclose(scn.T_o[::hour], csv[:, 1])  # the file's rows at whole hours
    assert scn.T_o[5 * hour] == -8 and scn.T_o[14 * hour] == -2
    assert scn.T_o.min() == -8 and scn.T_o.max() == -2
    assert scn.T_o[hour // 2] == pytest.approx((csv[0, 1] + csv[1, 1]) / 2)  # linear
    assert scn.controller.kind == "pi" and scn.controller.setpoint_C == 20
    assert scn.controller.power_max_W == 60000 and scn.heating_W is None
    assert set(scn.gains) == {"passengers", "auxiliaries"}
    assert np.all(scn.gains["passengers"] == 60 * 75)
    assert np.all(scn.gains_W == 60 * 75 + 1500)
    assert scn.initial.kind == "steady" and scn.heat_up_to_C is None
    # doors open 20 s every 3 min: 1/3 of the first minute of every three
    full = RHO_AIR_KG_M3 * CP_AIR_J_KG_K * 3600 / 3600
    air = scn.air_exchange_W_K
    assert air[:6] == pytest.approx([full / 3, 0, 0, full / 3, 0, 0])
    assert air[:-1].mean() == pytest.approx(full * 20 / 180)


def test_cool_down():
    scn = load_scenario(SHIPPED / "cool_down.yaml")
    assert np.all(scn.T_o == -10) and np.all(scn.heating_W == 0) and scn.controller is None
    assert scn.initial == Initial("given", {"T": 20.0, "T_veh": 20.0})
    assert scn.cool_down_to_C == 10 and scn.heat_up_to_C is None


def test_arrays_are_read_only():
    scn = load_scenario(SHIPPED / "cool_down.yaml")
    with pytest.raises(ValueError):
        scn.T_o[0] = 0


# ---------------------------------------------------------------------------------------------
# Profiles


def test_steps_hold_each_value_from_its_time(tmp_path):
    steps = [{"at_h": 0, "C": -20}, {"at_h": 0.5, "C": -10}, {"at_h": 1.5, "C": 0}]
    heat = [{"at_h": 0, "W": 5000}, {"at_h": 1, "W": 0}]
    scn = load_scenario(write(tmp_path, base(outdoor={"steps": steps}, heating={"steps": heat})))
    assert scn.T_o.shape == (121,)
    assert np.all(scn.T_o[:30] == -20) and np.all(scn.T_o[30:90] == -10)
    assert np.all(scn.T_o[90:] == 0)
    assert np.all(scn.heating_W[:60] == 5000) and np.all(scn.heating_W[60:] == 0)


def test_default_name_step_and_initial(tmp_path):
    scn = load_scenario(write(tmp_path, base(step_s=None), "my_case.yaml"), display="shown.yaml")
    assert scn.name == "my_case" and scn.file == "shown.yaml" and scn.dt_s == 60
    assert scn.initial == Initial("soaked") and scn.description == ""
    assert np.all(scn.heating_W == 1000) and scn.irradiance == {}
    named = load_scenario(write(tmp_path, base(name="other")))
    assert named.name == "other"


def _file_spec(path: str, time_column: str, time_format: str, column: str, **fmt) -> dict:
    spec = {"path": path, "time": {"column": time_column, "format": time_format}}
    spec["column"] = column
    if fmt:
        spec["format"] = fmt
    return spec


def test_file_profile_in_hours_is_interpolated_linearly(tmp_path):
    (tmp_path / "profiles").mkdir()
    (tmp_path / "profiles" / "t.csv").write_text("t_h,T_o,other\n0,-10,x\n1,-4,y\n2,-6,z\n")
    spec = _file_spec("profiles/t.csv", "t_h", "hours", "T_o")
    scn = load_scenario(write(tmp_path, base(outdoor={"file": spec})))
    assert scn.T_o[0] == -10 and scn.T_o[60] == -4 and scn.T_o[120] == -6
    assert scn.T_o[30] == pytest.approx(-7) and scn.T_o[90] == pytest.approx(-5)


def test_file_profile_with_iso_times_starts_at_its_first_row(tmp_path):
    rows = ["time,P"] + [f"2024-01-15T{8 + h:02d}:00:00,{1000 * h}" for h in range(4)]
    (tmp_path / "p.csv").write_text("\n".join(rows) + "\n")
    spec = _file_spec("p.csv", "time", "iso", "P")
    scn = load_scenario(write(tmp_path, base(heating={"file": spec})))
    assert scn.heating_W[0] == 0 and scn.heating_W[60] == 1000 and scn.heating_W[120] == 2000
    assert scn.heating_W[15] == pytest.approx(250)


def test_file_profile_with_semicolons_and_decimal_commas(tmp_path):
    text = "Zeit [min];Temperatur\n0;-10,5\n60;-9,5\n120;-8,25\n"
    (tmp_path / "de.csv").write_text(text, encoding="cp1252")
    spec = _file_spec(
        "de.csv",
        "Zeit [min]",
        "minutes",
        "Temperatur",
        separator=";",
        decimal=",",
        encoding="cp1252",
    )
    scn = load_scenario(write(tmp_path, base(outdoor={"file": spec})))
    assert scn.T_o[0] == -10.5 and scn.T_o[60] == -9.5 and scn.T_o[120] == -8.25


def test_irradiance_channels(tmp_path):
    (tmp_path / "sun.csv").write_text("t_s,G\n0,0\n7200,720\n")
    irradiance = {
        "south": 300,
        "roof": {"steps": [{"at_h": 0, "W_m2": 0}, {"at_h": 1, "W_m2": 500}]},
        "north": {"file": _file_spec("sun.csv", "t_s", "seconds", "G")},
    }
    scn = load_scenario(write(tmp_path, base(irradiance=irradiance)))
    assert set(scn.irradiance) == {"south", "roof", "north"}
    assert np.all(scn.irradiance["south"] == 300)
    assert scn.irradiance["roof"][59] == 0 and scn.irradiance["roof"][60] == 500
    assert scn.irradiance["north"][60] == pytest.approx(360)


def test_gains_and_air_exchange(tmp_path):
    gains = {
        "passengers": {
            "steps": [{"at_h": 0, "count": 10}, {"at_h": 1, "count": 100}],
            "sensible_W": 80,
        },
        "auxiliaries_W": 1500,
        "doors": {"every_min": 2, "open_s": 20, "heat_W": -6000},
        "ventilation_m3_h": 1800,
    }
    scn = load_scenario(write(tmp_path, base(gains=gains)))
    assert set(scn.gains) == {"passengers", "auxiliaries", "doors"}
    assert scn.gains["passengers"][0] == 800 and scn.gains["passengers"][60] == 8000
    assert np.all(scn.gains["auxiliaries"] == 1500)
    # doors open 20 s every 120 s: the first step of every two holds -6000 W for 20 s of 60
    assert scn.gains["doors"][:4] == pytest.approx([-2000, 0, -2000, 0])
    assert scn.gains["doors"][:-1].mean() == pytest.approx(-6000 * 20 / 120)
    assert scn.gains_W[0] == pytest.approx(800 + 1500 - 2000)
    assert np.all(scn.air_exchange_W_K == pytest.approx(1.2 * 1005 * 1800 / 3600))


def test_door_openings_shorter_or_longer_than_a_step(tmp_path):
    for step_s, every_min, open_s in ((60, 3, 20), (10, 2, 45), (300, 7, 90)):
        doors = {"every_min": every_min, "open_s": open_s, "air_exchange_m3_h": 3600}
        scn = load_scenario(
            write(tmp_path, base(duration_h=7, step_s=step_s, gains={"doors": doors}))
        )
        full = RHO_AIR_KG_M3 * CP_AIR_J_KG_K
        share = scn.air_exchange_W_K / full
        assert np.all((share >= 0) & (share <= 1 + 1e-12))
        assert share[:-1].mean() == pytest.approx(open_s / (every_min * 60))
        assert len(np.unique(share)) <= 5  # a few distinct values, no float noise


def test_controllers(tmp_path):
    pi = {"type": "pi", "setpoint_C": 20, "power_max_W": 30000, "kp_W_K": 5000, "ti_s": 900}
    scn = load_scenario(write(tmp_path, base(heating={"controller": pi})))
    assert scn.heating_W is None
    assert scn.controller == Controller("pi", 20, 30000, 0, 1.0, 5000, 900)
    thermo = {"type": "thermostat", "setpoint_C": 15, "power_max_W": 9000, "power_min_W": 1000}
    scn = load_scenario(write(tmp_path, base(heating={"controller": thermo})))
    assert scn.controller == Controller("thermostat", 15, 9000, 1000, 1.0)


# ---------------------------------------------------------------------------------------------
# Bad scenarios: one ConfigError naming the file, the key and the value


PROFILE = "t_h,T_o\n0,-10\n1,-8\n"  # covers 1 h
FILE = {"path": "p.csv", "time": {"column": "t_h", "format": "hours"}, "column": "T_o"}
THERMO = {"type": "thermostat", "setpoint_C": 15, "power_max_W": 9000}
BAD = {
    "unknown key": (base(outdor={"constant_C": 0}), "outdor", "did you mean 'outdoor'"),
    "unknown nested key": (
        base(heating={"controller": {**THERMO, "setpoint": 15}}),
        "heating.controller.setpoint",
        "unknown key",
    ),
    "negative duration": (base(duration_h=-1), "duration_h", "must be > 0"),
    "zero step": (base(step_s=0), "step_s", "must be > 0"),
    "duration not a multiple of the step": (
        base(duration_h=1, step_s=70),
        "duration_h",
        "step_s 70",
    ),
    "duration as text": (base(duration_h="12"), "duration_h", "must be a number"),
    "missing source": (base(source=None), "source", "missing required key"),
    "missing heating": (base(heating=None), "heating", "missing required key"),
    "missing profile file": (
        base(outdoor={"file": {**FILE, "path": "nope.csv"}}),
        "outdoor.file.path",
        "file not found: ",
    ),
    "missing profile column": (
        base(duration_h=1, outdoor={"file": {**FILE, "column": "T_out"}}),
        "outdoor.file.column",
        "no such column",
    ),
    "missing time column": (
        base(duration_h=1, outdoor={"file": {**FILE, "time": {"column": "t", "format": "hours"}}}),
        "outdoor.file.time.column",
        "no such column",
    ),
    "unknown time format": (
        base(duration_h=1, outdoor={"file": {**FILE, "time": {"column": "t_h", "format": "h"}}}),
        "outdoor.file.time.format",
        "must be iso",
    ),
    "profile too short": (
        base(duration_h=2, outdoor={"file": FILE}),
        "outdoor.file.path",
        "covers 0 h to 1 h",
    ),
    "steps decreasing": (
        base(outdoor={"steps": [{"at_h": 0, "C": 0}, {"at_h": 1, "C": 1}, {"at_h": 0.5, "C": 2}]}),
        "outdoor.steps[2].at_h",
        "time order",
    ),
    "first step not at 0": (
        base(outdoor={"steps": [{"at_h": 1, "C": 0}]}),
        "outdoor.steps[0].at_h",
        "at 0 h",
    ),
    "step off the grid": (
        base(outdoor={"steps": [{"at_h": 0, "C": 0}, {"at_h": 0.01, "C": 1}]}),
        "outdoor.steps[1].at_h",
        "not on the time grid",
    ),
    "step after the end": (
        base(outdoor={"steps": [{"at_h": 0, "C": 0}, {"at_h": 3, "C": 1}]}),
        "outdoor.steps[1].at_h",
        "after the end",
    ),
    "both constant_C and steps": (
        base(outdoor={"constant_C": 0, "steps": [{"at_h": 0, "C": 0}]}),
        "outdoor",
        "exactly one of constant_C, steps, file",
    ),
    "no outdoor profile": (base(outdoor={}), "outdoor", "given: none"),
    "power and controller": (
        base(heating={"power_W": 0, "controller": THERMO}),
        "heating",
        "exactly one of",
    ),
    "power_max_W <= 0": (
        base(heating={"controller": {**THERMO, "power_max_W": 0}}),
        "heating.controller.power_max_W",
        "must be > 0",
    ),
    "power_min >= power_max": (
        base(heating={"controller": {**THERMO, "power_min_W": 9000}}),
        "heating.controller.power_min_W",
        "must be < power_max_W",
    ),
    "hysteresis <= 0": (
        base(heating={"controller": {**THERMO, "hysteresis_K": 0}}),
        "heating.controller.hysteresis_K",
        "must be > 0",
    ),
    "hysteresis of a pi controller": (
        base(heating={"controller": {**THERMO, "type": "pi", "hysteresis_K": 1}}),
        "heating.controller.hysteresis_K",
        "a setting of a thermostat",
    ),
    "unknown controller type": (
        base(heating={"controller": {**THERMO, "type": "bang-bang"}}),
        "heating.controller.type",
        "must be one of thermostat, pi",
    ),
    "initial unknown word": (base(initial="cold"), "initial", "must be one of soaked, steady"),
    "initial unknown state": (
        base(initial={"T_C": 20, "T_body_C": 10}),
        "initial.T_body_C",
        "unknown key",
    ),
    "door open as long as its interval": (
        base(gains={"doors": {"every_min": 1, "open_s": 60, "heat_W": -1000}}),
        "gains.doors.open_s",
        "shorter than the interval",
    ),
    "door with both air and heat": (
        base(gains={"doors": {"every_min": 2, "open_s": 20, "heat_W": -1, "air_exchange_m3_h": 9}}),
        "gains.doors",
        "exactly one of air_exchange_m3_h, heat_W",
    ),
    "passengers without a count": (
        base(gains={"passengers": {"sensible_W": 80}}),
        "gains.passengers",
        "exactly one of count, steps",
    ),
    "negative irradiance": (base(irradiance={"south": -5}), "irradiance.south", "must be >= 0"),
    "not a number": (base(outdoor={"constant_C": float("nan")}), "outdoor.constant_C", "finite"),
}


@pytest.mark.bad_input
@pytest.mark.parametrize("case", list(BAD), ids=list(BAD))
def test_bad_scenario_is_named_by_file_key_and_value(tmp_path, case):
    data, key, reason = BAD[case]
    (tmp_path / "p.csv").write_text(PROFILE)
    path = write(tmp_path, data)
    with pytest.raises(ConfigError) as info:
        load_scenario(path, display="bad.yaml")
    err = info.value
    message = str(err)
    assert "\n" not in message
    assert err.file == "bad.yaml" and message.startswith("bad.yaml: ")
    assert err.key == key, message
    assert f"'{key}'" in message and repr(err.value) in message
    assert reason in message, message


@pytest.mark.bad_input
def test_bad_values_in_a_profile_file_name_the_line(tmp_path):
    (tmp_path / "p.csv").write_text("t_h,T_o\n0,-10\n1,oops\n2,-8\n")
    with pytest.raises(ConfigError) as info:
        load_scenario(write(tmp_path, base(outdoor={"file": FILE})))
    assert info.value.key == "outdoor.file.column" and "line 3" in str(info.value)
    (tmp_path / "p.csv").write_text("t_h,T_o\n0,-10\n2,-9\n1,-8\n")
    with pytest.raises(ConfigError) as info:
        load_scenario(write(tmp_path, base(outdoor={"file": FILE})))
    assert info.value.key == "outdoor.file.time.column" and "backwards" in str(info.value)
    (tmp_path / "p.csv").write_text("t_h,T_o\n0,-10\n1,\n2,-8\n")
    with pytest.raises(ConfigError) as info:
        load_scenario(write(tmp_path, base(outdoor={"file": FILE})))
    assert info.value.key == "outdoor.file.column" and "empty cell" in str(info.value)


@pytest.mark.bad_input
def test_a_profile_file_that_cannot_be_read_is_named_by_its_path(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.csv").write_text("")
    write(tmp_path, base(outdoor={"file": FILE}))
    with pytest.raises(ConfigError) as info:
        load_scenario("scn.yaml")
    assert str(info.value) == (
        "scn.yaml: key 'outdoor.file.path' = 'p.csv': p.csv: the file is empty (no header line)"
    )
    (tmp_path / "p.csv").write_text(PROFILE)
    write(tmp_path, base(outdoor={"file": {**FILE, "format": {"sheet": 1}}}))
    with pytest.raises(ConfigError, match=r"'outdoor.file.path' = 'p.csv': .*format.sheet"):
        load_scenario("scn.yaml")


@pytest.mark.bad_input
def test_yaml_syntax_error_and_missing_file(tmp_path):
    with pytest.raises(ConfigError, match="YAML syntax error"):
        load_scenario(write(tmp_path, "duration_h: [1\n"))
    with pytest.raises(ConfigError, match="file not found"):
        load_scenario(tmp_path / "absent.yaml")
