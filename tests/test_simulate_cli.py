"""``railtherm simulate``: scenarios through a checked fit or a class reference model
(railtherm.study.simulate), the summaries on stdout and, with --out, each scenario's series and
outcomes; a mistake is one line on stderr, exit 1 and nothing written."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest
import yaml

from railtherm.cli import main

REPO = Path(__file__).resolve().parents[1]
PREHEAT = "config/scenarios/preheat_cold_soak.yaml"
COOL_DOWN = "config/scenarios/cool_down.yaml"


def simulate(*argv: str) -> int:
    return main(["simulate", "-d", str(REPO), "--draws", "40", *argv])


def unreachable_scenario(tmp_path: Path) -> Path:
    """The pre-heating scenario with 5 kW: below the steady load of any metro at -20 degC."""
    data = yaml.safe_load((REPO / PREHEAT).read_text(encoding="utf-8"))
    data["name"] = "weak_heater"
    data["heating"]["controller"]["power_max_W"] = 5000
    path = tmp_path / "weak.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def assert_one_line_error(capsys, *words: str) -> str:
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.count("\n") == 1, captured.err
    for word in words:
        assert word in captured.err, (word, captured.err)
    return captured.err


def test_a_fit_through_two_scenarios(fit_files, tmp_path, capsys):
    fit_path, _ = fit_files("Metro1", "order2")
    out = tmp_path / "out"
    assert (
        simulate(str(fit_path), "--scenario", PREHEAT, "--scenario", COOL_DOWN, "--out", str(out))
        == 0
    )
    printed = capsys.readouterr().out
    assert "Metro1 order2 - scenario preheat_cold_soak" in printed
    assert "Metro1 order2 - scenario cool_down" in printed
    assert "heat-up time:" in printed and "95 % bands from 40 draws" in printed
    assert f"written to {out / 'preheat_cold_soak'}.csv" in printed
    assert sorted(p.name for p in out.iterdir()) == [
        "cool_down.csv",
        "cool_down.yaml",
        "preheat_cold_soak.csv",
        "preheat_cold_soak.yaml",
    ]
    series = pd.read_csv(out / "preheat_cold_soak.csv")
    assert {"time_h", "T_o", "T", "T_veh", "heating_W", "T_lo", "T_hi"} <= set(series.columns)
    assert series["time_h"].iloc[-1] == pytest.approx(12.0)  # the scenario's duration
    assert series["T"].iloc[0] == pytest.approx(-20.0)  # soaked at T_o
    result = yaml.safe_load((out / "preheat_cold_soak.yaml").read_text(encoding="utf-8"))
    assert result["scenario"] == "preheat_cold_soak" and result["scenario_file"] == PREHEAT
    assert result["draws"] == 40
    heat = result["outcomes"]["heat_up_time_s"]
    assert heat["status"] == "ok" and heat["ci95"][0] <= heat["value"] <= heat["ci95"][1]
    # the same seed gives the same numbers
    again = tmp_path / "again"
    assert simulate(str(fit_path), "--scenario", PREHEAT, "--out", str(again)) == 0
    capsys.readouterr()
    assert (again / "preheat_cold_soak.yaml").read_text() == (
        out / "preheat_cold_soak.yaml"
    ).read_text()


def test_a_class_reference_model(tmp_path, capsys):
    """The pooled rail classes (7 vehicles) determine every parameter: a band from the
    spread of the vehicles; the metro class (3, one with a K_veh ten times the others')
    leaves K_veh's prediction interval wider than a factor 1000: its centre, no band."""
    for name, n, band in (("all", 7, True), ("metro", 3, False)):
        ref = tmp_path / f"{name}.yaml"
        argv = ["reference", "--class", name, "--mass-kg", "35000", "--surface-m2", "300"]
        assert main([*argv, "-d", str(REPO), "--out", str(ref)]) == 0
        capsys.readouterr()
        assert simulate(str(ref), "--scenario", PREHEAT) == 0  # without --out: stdout only
        printed = capsys.readouterr().out
        assert f"{name} reference model" in printed and "scenario preheat_cold_soak" in printed
        assert f"class reference model from {n} vehicles" in printed
        assert ("spread of the class's vehicles" in printed) is band
        assert ("leave C, K_veh, C_veh not identified" in printed) is not band
        assert "written to" not in printed


@pytest.mark.bad_input
def test_an_unreachable_set_point_is_refused_and_nothing_is_written(fit_files, tmp_path, capsys):
    fit_path, _ = fit_files("Metro1", "order2")
    weak = unreachable_scenario(tmp_path)
    out = tmp_path / "out"
    # the first scenario runs, the second fails: neither is written
    argv = [str(fit_path), "--scenario", PREHEAT, "--scenario", str(weak), "--out", str(out)]
    assert simulate(*argv) == 1
    assert_one_line_error(capsys, str(weak), "heating.controller.power_max_W", "5000")
    assert not out.exists()
    # allowed: simulated, the heat-up time reported as unreachable
    assert simulate(*argv, "--allow-unreachable") == 0
    printed = capsys.readouterr().out
    assert "unreachable" in printed
    assert (out / "weak_heater.yaml").is_file() and (out / "preheat_cold_soak.csv").is_file()
    result = yaml.safe_load((out / "weak_heater.yaml").read_text(encoding="utf-8"))
    assert result["outcomes"]["heat_up_time_s"]["status"] == "unreachable"


@pytest.mark.bad_input
def test_a_fit_with_a_parameter_not_identified_is_refused(fit_files, tmp_path, capsys):
    fit_path, _ = fit_files("Metro3", "order2")
    out = tmp_path / "out"
    assert simulate(str(fit_path), "--scenario", PREHEAT, "--out", str(out)) == 1
    assert_one_line_error(capsys, str(fit_path), "not identified")
    assert not out.exists()


@pytest.mark.bad_input
@pytest.mark.parametrize(
    "params, words",
    [
        (PREHEAT, [PREHEAT, "not a parameter file"]),  # a scenario is no parameter file
        ("config/vehicles/Metro1.yaml", ["config/vehicles/Metro1.yaml", "not a parameter file"]),
        ("results/tables/table2.csv", ["results/tables/table2.csv", "YAML"]),  # a CSV
        ("nowhere/fit_order2.yaml", ["nowhere/fit_order2.yaml", "file not found"]),
    ],
)
def test_a_file_that_is_no_parameter_set_is_refused(params, words, tmp_path, capsys):
    out = tmp_path / "out"
    assert simulate(params, "--scenario", PREHEAT, "--out", str(out)) == 1
    err = assert_one_line_error(capsys, *words)
    assert str(REPO) not in err  # the path as given, not under -d
    assert not out.exists()


@pytest.mark.bad_input
def test_scenario_mistakes(fit_files, tmp_path, capsys):
    fit_path, _ = fit_files("Metro1", "order2")
    out = tmp_path / "out"
    assert simulate(str(fit_path), "--scenario", "config/scenarios/nope.yaml") == 1
    err = assert_one_line_error(capsys, "config/scenarios/nope.yaml", "file not found")
    assert str(REPO) not in err  # the path as given, not under -d
    argv = [str(fit_path), "--scenario", PREHEAT, "--scenario", PREHEAT, "--out", str(out)]
    assert simulate(*argv) == 1
    assert_one_line_error(capsys, "preheat_cold_soak", "overwrite")
    assert simulate(str(fit_path), "--scenario", PREHEAT, "--draws", "-1") == 1
    assert_one_line_error(capsys, "--draws")
    assert not out.exists()
