"""Inputs that once stopped with a traceback after the config checks passed: a weather file
of another kind than declared, a programme whose logger step is longer than its phases, and a
study without an acceptable second-order fit for the energy table. Each now stops with one
line naming the file, the key, the value and the fix, or gives its output with a statement."""

from __future__ import annotations

import shutil
from pathlib import Path
from types import SimpleNamespace

import pandas as pd
import pytest
import yaml

from railtherm.cli import main
from railtherm.errors import ConfigError
from railtherm.study import design, energy, weather

REPO = Path(__file__).resolve().parents[1]
TMY3 = REPO / "config" / "weather" / "723170TYA.csv"
PAPER = REPO / "config" / "programmes" / "paper.yaml"
PROFILE = REPO / "config" / "profiles" / "metro_service.yaml"


def one_line(capsys) -> str:
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.count("\n") == 1, captured
    return captured.err


# ------------------------------------------------------------------ weather of another kind
@pytest.mark.bad_input
@pytest.mark.parametrize("kind", ["epw", "pvgis"])
def test_a_tmy3_file_read_as_another_kind_names_the_kind_to_give(kind):
    with pytest.raises(ConfigError) as caught:
        weather.read_weather(TMY3, kind=kind)
    text = str(caught.value)
    assert str(TMY3) in text and f"'kind' = '{kind}'" in text
    assert "looks like an NREL TMY3 file" in text and "--kind tmy3" in text


@pytest.mark.bad_input
def test_an_epw_file_read_as_tmy3_names_the_kind_to_give(tmp_path):
    epw = tmp_path / "year.epw"
    epw.write_text("LOCATION,Somewhere,XX,YYY,TMY3,1,50.0,10.0,1.0,100.0\nDATA PERIODS,1\n")
    with pytest.raises(ConfigError) as caught:
        weather.read_weather(epw, kind="tmy3")
    text = str(caught.value)
    assert str(epw) in text and "'kind' = 'tmy3'" in text and "--kind epw" in text


@pytest.mark.bad_input
def test_a_csv_that_does_not_parse_is_refused_by_name(tmp_path):
    broken = tmp_path / "year.csv"
    broken.write_text('time,T_o\n"2001-01-01T00:00,1\n' + "x,1,2,3\n" * 3)
    with pytest.raises(ConfigError) as caught:
        weather.read_weather(broken, kind="csv")
    text = str(caught.value)
    assert str(broken) in text and "'kind' = 'csv'" in text and "a plain CSV" in text


@pytest.mark.bad_input
def test_railtherm_energy_with_kind_epw_on_a_tmy3_file_is_one_line(tmp_path, capsys):
    ref = tmp_path / "metro.yaml"
    argv = ["reference", "--class", "metro", "--mass-kg", "40000", "--surface-m2", "330"]
    assert main([*argv, "-d", str(REPO), "--out", str(ref)]) == 0
    capsys.readouterr()
    argv = ["energy", str(ref), "--weather", str(TMY3), "--kind", "epw"]
    assert main([*argv, "--profile", str(PROFILE), "--draws", "0"]) == 1
    err = one_line(capsys)
    assert "723170TYA.csv" in err and "'kind' = 'epw'" in err and "--kind tmy3" in err


# ------------------------------------------------------------- a logger step of a day
def programme_with(tmp_path: Path, **changes) -> Path:
    data = yaml.safe_load(PAPER.read_text(encoding="utf-8"))
    data.update(changes)
    path = tmp_path / "programme.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


@pytest.mark.bad_input
def test_a_logger_step_of_a_day_names_the_phase_and_the_step_to_give(tmp_path):
    path = programme_with(tmp_path, step_s=86400)
    with pytest.raises(ConfigError) as caught:
        design.load_programme(path)
    text = str(caught.value)
    assert str(path) in text and "'step_s' = 86400.0" in text
    assert "phases[1] (step up, 12 h" in text and "at most 4320 s" in text


@pytest.mark.bad_input
def test_a_compared_part_shorter_than_the_step_names_identify(tmp_path):
    data = yaml.safe_load(PAPER.read_text(encoding="utf-8"))
    path = programme_with(tmp_path, step_s=7200, phases=data["phases"])
    with pytest.raises(ConfigError) as caught:
        design.load_programme(path)
    text = str(caught.value)
    assert "'phases[0].identify' = 1" in text and "compare at least 2 h" in text


@pytest.mark.bad_input
def test_railtherm_design_with_a_step_of_a_day_is_one_line(tmp_path, capsys):
    path = programme_with(tmp_path, step_s=86400)
    argv = ["design", str(path), "--class", "metro", "--mass-kg", "40000"]
    assert main([*argv, "--surface-m2", "330", "--draws", "5", "-d", str(REPO)]) == 1
    err = one_line(capsys)
    assert "programme.yaml" in err and "'step_s'" in err and "e.g. 60" in err


@pytest.mark.bad_input
def test_a_programme_scaled_below_its_step_is_not_identified_not_a_traceback(tmp_path):
    """--optimise scales a programme's phases; scaled below the logger step they hold no
    compared sample: the prediction is 'not identified' (infinite sd), not an error."""
    programme = design.load_programme(programme_with(tmp_path, step_s=3600))
    tiny = design.scaled(programme, 0.01)
    theta = {"kA": 700.0, "C": 9.0e6, "K_veh": 450.0, "C_veh": 1.8e7}
    structure = design.models.STRUCTURES["second_order"]
    found = design.predict(structure, theta, tiny)
    assert all(v == float("inf") for v in found.sd_log.values())
    assert not any(found.identifiable.values())


# ------------------------------------------------- the energy table without acceptable fits
@pytest.mark.bad_input
def test_energy_table_without_an_acceptable_fit_says_so(tmp_path, monkeypatch):
    """Rule energy when every second-order fit is in doubt: the CSV has its columns and no
    row, the Markdown names each vehicle's verdict and what gives a row, the figure is drawn."""
    from railtherm.study import fit as fit_module

    doubtful = SimpleNamespace(verdict="fit assumptions in doubt")
    monkeypatch.setattr(fit_module, "read_fit", lambda path, **_: doubtful)
    weather_file = tmp_path / "year.csv"
    shutil.copy(TMY3, weather_file)
    parts = []
    for vid, fit_file in (("Metro3", "a.yaml"), ("Metro4", "b.yaml")):
        part = energy.vehicle_energy(
            vid, {"class": "metro"}, [fit_file], [str(weather_file)], str(PROFILE), draws=0
        )
        part.to_csv(tmp_path / f"{vid}.csv", index=False)
        parts.append(str(tmp_path / f"{vid}.csv"))
    table = energy.study_table(parts, ["a.yaml", "b.yaml"], ["Metro3", "Metro4"])
    profile = energy.load_profile(PROFILE)
    csv, md = tmp_path / "energy.csv", tmp_path / "energy.md"
    energy.write_study_energy(table, [profile], 60.0, "test", csv, md, str(tmp_path / "fig"))
    assert table.empty and list(table.columns) == energy.study_columns()
    assert list(pd.read_csv(csv).columns) == energy.study_columns()
    text = md.read_text(encoding="utf-8")
    assert "No vehicle has an acceptable fit" in text
    assert "Metro3: fit assumptions in doubt" in text and "fit_<model>.yaml" in text
    assert (tmp_path / "fig.png").stat().st_size > 0


# -------------------------------------------------- an energy step longer than the hour
@pytest.mark.bad_input
@pytest.mark.parametrize("step", ["86400", "4e7"])
def test_railtherm_energy_with_a_step_of_a_day_or_more_is_refused(tmp_path, capsys, step):
    """A step of a day, or of more than the year, once gave a year of 0 kWh and rc 0."""
    argv = ["energy", "params.yaml", "--weather", str(TMY3), "--profile", str(PROFILE)]
    assert main([*argv, "--step-s", step, "-d", str(tmp_path)]) == 1
    err = one_line(capsys)
    assert "--step-s: key 'step_s'" in err and "at most 3600 s" in err


@pytest.mark.bad_input
def test_a_study_energy_step_of_a_day_names_the_config_key():
    from railtherm.config import check_study_plans

    config = {"energy": {"enabled": True, "step_s": 86400}}
    with pytest.raises(ConfigError) as caught:
        check_study_plans(config, REPO, "config/config.yaml")
    text = str(caught.value)
    assert "config/config.yaml: key 'energy.step_s' = 86400" in text and "at most 3600 s" in text


# ------------------------------------------- the energy command's output and heater settings
@pytest.mark.bad_input
def test_railtherm_energy_out_onto_a_file_is_refused_before_the_run(tmp_path, capsys):
    """--out naming an existing file (not a directory) stops at once, naming the option."""
    (tmp_path / "taken").write_text("x")
    argv = ["energy", "params.yaml", "--weather", str(TMY3), "--profile", str(PROFILE)]
    assert main([*argv, "--out", "taken", "-d", str(tmp_path)]) == 1
    err = one_line(capsys)
    assert "--out: key 'out' = 'taken'" in err and "give a directory" in err


@pytest.mark.bad_input
@pytest.mark.parametrize(
    "limits", [{}, {"heating_limit_W": 1000, "heating_limit_W_per_m2": 100}], ids=["none", "both"]
)
def test_a_profile_gives_its_heater_one_way(tmp_path, limits):
    """A profile names its heater's power as exactly one of heating_limit_W and
    heating_limit_W_per_m2: neither or both is refused, naming the keys."""
    path = tmp_path / "profile.yaml"
    path.write_text(
        yaml.safe_dump({"service": {"weekdays": [[0, 24]]}, "set_point_C": 20, **limits})
    )
    with pytest.raises(ConfigError, match="exactly one of heating_limit_W") as err:
        energy.load_profile(path)
    assert str(path) in str(err.value)
