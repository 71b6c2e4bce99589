"""Energy settings that contradict each other or a weather year in the wrong unit: refused
with the key, the value and the fix, by ``railtherm energy`` and by the study config alike."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from test_cli import setup_repo, write_study
from test_config import VEHICLE_FILE

from railtherm.cli import main
from railtherm.errors import ConfigError
from railtherm.study import energy, weather

REPO = Path(__file__).resolve().parents[1]
SAND_POINT = REPO / "config" / "weather" / "703165TY.csv"
PROFILE = REPO / "config" / "profiles" / "metro_service.yaml"


def write_profile(path: Path, **changes) -> Path:
    data = {**yaml.safe_load(PROFILE.read_text()), **changes}
    path.write_text(yaml.safe_dump(data))
    return path


def csv_year(path: Path, T_o: np.ndarray) -> Path:
    time = pd.date_range("2001-01-01 01:00", periods=len(T_o), freq="h")
    pd.DataFrame({"time": time.strftime("%Y-%m-%dT%H:%M:%S"), "T_o": T_o}).to_csv(path, index=False)
    return path


def sand_point_in(unit: str) -> np.ndarray:
    """Sand Point's typical year (degC) written in ``unit``."""
    T = weather.read_weather(SAND_POINT).T_o
    return {"degF": T * 9 / 5 + 32, "K": T + 273.15, "degC": T}[unit]


@pytest.mark.bad_input
@pytest.mark.parametrize("unit, hint", [("degF", "read as degF"), ("K", "read as K")])
def test_a_weather_year_in_another_unit_is_refused_with_its_mean_and_extremes(tmp_path, unit, hint):
    """Sand Point's year written in degF (mean 39 degF, read as degC: a hot year of 0 kWh)
    or in kelvin: refused naming the file, the column, degC, the observed mean and extremes,
    and what they are in the unit the numbers are in; the same year in degC is read."""
    path = csv_year(tmp_path / f"year_{unit}.csv", sand_point_in(unit))
    with pytest.raises(ConfigError) as err:
        weather.read_weather(path)
    text = str(err.value)
    true = sand_point_in("degC")
    for fragment in (
        str(path),
        "'T_o'",
        "read in degC",
        "mean ",
        "min ",
        "max ",
        hint,
        f"mean {true.mean():.1f}",
        "check the unit",
    ):
        assert fragment in text, (fragment, text)
    year = weather.read_weather(csv_year(tmp_path / "year_degC.csv", true))
    assert year.T_o.mean() == pytest.approx(true.mean())


@pytest.mark.bad_input
def test_a_year_too_hot_for_earth_is_refused_even_without_a_guess(tmp_path):
    """A year at 40 degC throughout: no climate has that annual mean."""
    path = csv_year(tmp_path / "hot.csv", np.full(8760, 40.0))
    with pytest.raises(ConfigError, match=r"mean 40\.0.*annual mean -30 to 35 degC"):
        weather.read_weather(path)


@pytest.mark.bad_input
def test_the_energy_command_refuses_a_degF_year(tmp_path, capsys):
    path = csv_year(tmp_path / "year.csv", sand_point_in("degF"))
    code = main(["energy", "fit.yaml", "--weather", str(path), "--profile", str(PROFILE)])
    err = capsys.readouterr().err
    assert code == 1 and "read as degF" in err and "check the unit" in err, err


@pytest.mark.bad_input
def test_a_set_back_above_the_set_point_is_refused_in_the_profile(tmp_path):
    with pytest.raises(ConfigError) as err:
        energy.load_profile(write_profile(tmp_path / "p.yaml", set_point_C=18, set_back_C=22))
    text = str(err.value)
    for fragment in ("'set_back_C' = 22", "set_point_C = 18", "at most set_point_C", "null"):
        assert fragment in text, (fragment, text)


@pytest.mark.parametrize(
    "text, fragments",
    [
        ("k=-150%", ["k=-150%", "kA -0.5 times", "above -100 %", "k=-10%"]),
        ("k=-100%", ["k=-100%", "not positive", "above -100 %"]),
        # before: 1e308 % overflowed kA to inf (numpy's LinAlgError); 1e20 % broke the balance
        ("k=1e308%", ["k=1e308%", "within 10 times", "at most k=+900%"]),
        ("k=+901%", ["k=+901%", "kA 10.01 times", "at most k=+900%"]),
        ("set_back=nan", ["set_back=nan", "not a finite number", "set_back=8"]),
        ("set_back=inf", ["set_back=inf", "not a finite number"]),
        ("k=nan%", ["k=nan%", "not a finite number", "k=-10%"]),
        ("preheat_h=-2", ["preheat_h=-2", "0 h or more", "preheat_h=3"]),
    ],
)
@pytest.mark.bad_input
def test_a_what_if_that_cannot_hold_is_refused_by_the_command(tmp_path, capsys, text, fragments):
    """`railtherm energy --what-if`: a change that makes kA not positive, a value that is no
    finite number, a negative pre-heating - one line naming --what-if, the text and the fix,
    before anything is simulated."""
    code = main(
        ["energy", "fit.yaml", "--weather", str(SAND_POINT), "--profile", str(PROFILE)]
        + ["--what-if", text]
    )
    err = capsys.readouterr().err
    assert code == 1 and err.count("\n") == 1 and "--what-if" in err, err
    for fragment in fragments:
        assert fragment in err, (fragment, err)


@pytest.mark.bad_input
def test_a_set_back_what_if_above_the_set_point_is_refused_by_the_command(tmp_path, capsys):
    """metro_service holds 20 degC in service: a what-if set-back of 24 contradicts it."""
    args = ["energy", "fit.yaml", "--weather", str(SAND_POINT), "--profile", str(PROFILE)]
    assert main([*args, "--what-if", "set_back=24"]) == 1
    err = capsys.readouterr().err
    for fragment in ("--what-if", "set_back=24", "above the profile's set point 20", "set_back=20"):
        assert fragment in err, (fragment, err)


@pytest.mark.parametrize(
    "option, value", [("--step-s", "inf"), ("--volume-m3", "nan"), ("--volume-m3", "-5")]
)
@pytest.mark.bad_input
def test_a_non_finite_or_negative_number_option_is_refused(capsys, option, value):
    args = ["energy", "fit.yaml", "--weather", str(SAND_POINT), "--profile", str(PROFILE)]
    assert main([*args, option, value]) == 1
    err = capsys.readouterr().err
    assert option in err and value in err, err


@pytest.mark.bad_input
def test_a_contradicting_what_if_built_in_code_is_refused_by_the_engine(tmp_path):
    """The engine itself refuses a what-if the parser would not give (a library caller)."""
    from railtherm.estimation import models
    from railtherm.study import simulate

    ps = simulate.ParameterSet(
        "car",
        "declared",
        models.STRUCTURES["second_order"],
        {"kA": 700.0, "C": 9.0e6, "K_veh": 450.0, "C_veh": 1.8e7},
    )
    prof = energy.load_profile(PROFILE)
    year = weather.read_weather(SAND_POINT)
    with pytest.raises(ConfigError, match="above the profile's set point"):
        energy.annual_energy(
            ps, year, prof, what_ifs=[energy.WhatIf("hot", profile={"set_back_C": 30.0})]
        )
    with pytest.raises(ConfigError, match="not positive"):
        energy.annual_energy(ps, year, prof, what_ifs=[energy.WhatIf("neg", k_rel=-1.5)], draws=0)


def energy_study(**section) -> None:
    write_study(
        [VEHICLE_FILE, "config/vehicles/V2.yaml"],
        energy={"enabled": True, **section},
    )


@pytest.mark.parametrize(
    "section, fragments",
    [
        ({"weather": [], "profile": "profile.yaml"}, ["energy.weather", "no typical year"]),
        ({"weather": ["year.csv"]}, ["energy.profile", "no operating profile", "metro_service"]),
        (
            {"weather": ["year.csv"], "profiles": {"metro": "profile.yaml"}},
            ["energy.profiles.tram", "class 'tram', which has no operating profile"],
        ),
        (
            {"weather": ["year.csv", "sub/year.csv"], "profile": "profile.yaml"},
            ["energy.weather[1]", "sub/year.csv", "the same file name as year.csv"],
        ),
        (
            {"weather": ["year.csv"], "profiles": {"tram": "tram.yaml"}},
            ["energy.profiles.tram", "tram.yaml", "profile file not found"],
        ),
        (
            {"weather": ["year.csv"], "profile": "profile.yaml", "what_if": ["set_back=25"]},
            ["energy.what_if[0]", "set_back=25", "above the profile's set point 20"],
        ),
        (
            {"weather": ["year.csv"], "profile": "profile.yaml", "what_if": ["k=-150%"]},
            ["energy.what_if[0]", "k=-150%", "above -100 %"],
        ),
        (
            {"weather": ["year.csv"], "profile": "profile.yaml", "what_if": ["set_back=nan"]},
            ["energy.what_if[0]", "set_back=nan", "not a finite number"],
        ),
    ],
)
@pytest.mark.bad_input
def test_the_study_config_refuses_the_same_settings(
    tmp_path, monkeypatch, capsys, section, fragments
):
    """`energy: {enabled: true}` without a weather year or a profile, and the what-ifs the
    command refuses: `railtherm validate` (the workflow's parse) stops on the key, before any
    job, with the value and the fix."""
    monkeypatch.chdir(tmp_path)
    setup_repo(tmp_path)
    write_profile(tmp_path / "profile.yaml")
    csv_year(tmp_path / "year.csv", sand_point_in("degC"))
    (tmp_path / "sub").mkdir()
    csv_year(tmp_path / "sub" / "year.csv", sand_point_in("degC"))
    energy_study(**section)
    assert main(["validate", "--headers-only"]) == 1
    err = capsys.readouterr().err
    assert "config/config.yaml" in err, err
    for fragment in fragments:
        assert fragment in err, (fragment, err)
    os.remove("config/config.yaml")


@pytest.mark.bad_input
def test_a_heater_per_square_metre_needs_each_vehicles_surface(tmp_path, monkeypatch, capsys):
    """An object of class other may leave its surface out; under a profile that sizes the
    heater per m² of surface, `railtherm validate` (the workflow's parse) names its file and
    the key, before any job."""
    monkeypatch.chdir(tmp_path)
    setup_repo(tmp_path)
    second = yaml.safe_load(open("config/vehicles/V2.yaml").read())
    second.update({"class": "other"})
    second.pop("surface_m2")
    second.pop("mass_kg", None)
    with open("config/vehicles/V2.yaml", "w") as stream:
        yaml.safe_dump(second, stream)
    write_profile(tmp_path / "profile.yaml")
    per_m2 = {
        k: v for k, v in yaml.safe_load(PROFILE.read_text()).items() if k != "heating_limit_W"
    }
    (tmp_path / "per_m2.yaml").write_text(yaml.safe_dump({**per_m2, "heating_limit_W_per_m2": 130}))
    csv_year(tmp_path / "year.csv", sand_point_in("degC"))
    energy_study(weather=["year.csv"], profile="per_m2.yaml", profiles={"tram": "profile.yaml"})
    assert main(["validate", "--headers-only"]) == 1
    err = capsys.readouterr().err
    assert "config/vehicles/V2.yaml" in err and "'surface_m2'" in err, err
    assert "per_m2.yaml sizes the heater per m²" in err, err


def test_a_complete_energy_section_passes(tmp_path, monkeypatch, capsys):
    """No false alarm: the shipped profile and a degC year with a sound what-if."""
    monkeypatch.chdir(tmp_path)
    setup_repo(tmp_path)
    write_profile(tmp_path / "profile.yaml")
    csv_year(tmp_path / "year.csv", sand_point_in("degC"))
    energy_study(weather=["year.csv"], profile="profile.yaml", what_if=["set_back=8", "k=-10%"])
    assert main(["validate", "--headers-only"]) == 0, capsys.readouterr().err


@settings(max_examples=80, deadline=None)
@given(change=st.floats(-300.0, 1e12, allow_nan=False))
def test_a_k_what_if_is_accepted_exactly_when_kA_stays_positive_and_within_ten_times(change):
    """k=<change>% parses to a factor 1 + change/100 on kA when that factor is positive and
    at most 10, and is refused naming the bound it crosses otherwise."""
    text = f"k={change!r}%"
    if -100.0 < change <= 900.0:
        assert 0.0 < 1.0 + energy.parse_what_if(text).k_rel <= 10.0
    else:
        bound = "above -100 %" if change <= -100.0 else "at most k=\\+900%"
        with pytest.raises(ConfigError, match=bound):
            energy.parse_what_if(text)
