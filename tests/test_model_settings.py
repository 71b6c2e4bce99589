"""model.initial and model.bounds of a vehicle file: every estimated parameter, kA and the
solar apertures a_I_<name> included, reaches the fit; a name the vehicle does not have is
one ConfigError naming the file, the key and the accepted names."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from railtherm import structures
from railtherm.config import load_vehicle
from railtherm.errors import ConfigError
from railtherm.study import identify
from railtherm.study.run import tidy_tables

REPO = Path(__file__).resolve().parents[1]
SOLAR = REPO / "validation" / "config" / "vehicles" / "Armadillo_solar.yaml"
RAW = REPO / "data" / "armadillo" / "armadillo_data_H2.csv"


def vehicle_file(tmp_path: Path, model: dict, defaults: dict | None = None):
    """The Armadillo vehicle with the solar input (a_I_sol), its model section updated by
    ``model``, written to tmp_path and loaded (under study defaults ``defaults``)."""
    data = yaml.safe_load(SOLAR.read_text(encoding="utf-8"))
    data["raw_files"] = {"h2": str(RAW)}
    data["model"] = {**data["model"], **model}
    path = tmp_path / "Box.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return load_vehicle(path, defaults=defaults, workdir=tmp_path)


def fit_of(tmp_path: Path, vehicle, order: int) -> dict:
    windows = {w["name"]: w["name"] for w in vehicle.windows["identification"]}
    tables = tidy_tables(vehicle, tmp_path)
    estimate, _ = identify.identify(
        {name: tables[name] for name in windows}, vehicle.data, None, order
    )
    return estimate.content["fit"]


def test_kA_and_aperture_bounds_reach_the_fit(tmp_path):
    """Unbounded (the defaults) the second-order fit puts kA near 31 W/K and the aperture at
    its lower default bound, 1e-3 m2; bounded here, both sit at the bounds given."""
    model = {
        "orders": [2],
        "structures": [],
        "initial": {"kA": 80.0, "a_I_sol": 2.0},
        "bounds": {"kA": [60.0, 1.0e3], "a_I_sol": [0.5, 50.0]},
    }
    vehicle = vehicle_file(tmp_path, model)
    assert vehicle.model["initial"] == {"kA": 80.0, "a_I_sol": 2.0}
    fit = fit_of(tmp_path, vehicle, 2)
    assert fit["parameters"]["kA"]["value"] == pytest.approx(60.0, rel=1e-4)
    assert fit["parameters"]["a_I_sol"]["value"] == pytest.approx(0.5, rel=1e-4)
    pinned = {p for f in fit["flags"] if f["code"] == "at_bound" for p in f["parameters"]}
    assert {"kA", "a_I_sol"} <= pinned


def test_initial_values_start_the_fit(tmp_path):
    """start: initial begins at model.initial. Given the optimum of a first fit (kA and the
    aperture included), the second starts where the first ended."""
    model = {"orders": [2], "structures": [], "start": "initial"}
    first = fit_of(tmp_path, vehicle_file(tmp_path, model), 2)
    optimum = {p: first["parameters"][p]["value"] for p in first["free"]}
    assert set(optimum) == {"kA", "C", "K_veh", "C_veh", "a_I_sol"}
    second = fit_of(tmp_path, vehicle_file(tmp_path, {**model, "initial": optimum}), 2)
    assert second["start_costs"]["initial"] < 0.1 * first["start_costs"]["initial"]
    assert second["nfev"] < first["nfev"]
    assert second["cost"] == pytest.approx(first["cost"], rel=1e-6)


@pytest.mark.bad_input
@pytest.mark.parametrize(
    "section, name, value",
    [
        ("initial", "a_I_sun", 2.0),  # no input I_sun
        ("bounds", "a_I_sun", [0.1, 10.0]),
        ("initial", "f_I_sol", 0.5),  # I_sol heats the air node alone: no share
    ],
)
def test_a_solar_parameter_of_no_input_is_refused_naming_the_accepted(
    tmp_path, section, name, value
):
    with pytest.raises(ConfigError) as caught:
        vehicle_file(tmp_path, {section: {name: value}})
    message = str(caught.value)
    assert "Box.yaml" in message and f"'model.{section}.{name}'" in message
    every = ", ".join(structures.parameters())  # every registered structure's parameters
    assert every.startswith("kA, C_bar, C, K_veh, C_veh, K_i, C_e, K_o")
    assert f"accepted: {every}, a_I_sol)" in message
    assert len(message.splitlines()) == 1


@pytest.mark.bad_input
def test_an_unknown_parameter_name_is_refused_by_the_schema(tmp_path):
    with pytest.raises(ConfigError) as caught:
        vehicle_file(tmp_path, {"initial": {"k_A": 50.0}})
    message = str(caught.value)
    assert "'model.initial.k_A'" in message and "did you mean 'kA'" in message
    assert "K_veh" in message and "^a_I_" in message  # the accepted names and patterns


@pytest.mark.bad_input
@pytest.mark.parametrize(
    "model, key, reason",
    [
        ({"bounds": {"kA": [100.0, 10.0]}}, "model.bounds.kA", "lower bound must be <"),
        (
            {"initial": {"a_I_sol": 0.01}, "bounds": {"a_I_sol": [0.1, 10.0]}},
            "model.initial.a_I_sol",
            "outside model.bounds.a_I_sol = [0.1, 10]",
        ),
        (
            {"initial": {"kA": 5.0}, "bounds": {"kA": [10.0, 1.0e3]}},
            "model.initial.kA",
            "outside model.bounds.kA = [10, 1000]",
        ),
    ],
)
def test_kA_and_aperture_bounds_are_checked_like_the_others(tmp_path, model, key, reason):
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")) as caught:
        vehicle_file(tmp_path, model)
    assert reason in str(caught.value)


def test_a_study_default_aperture_is_ignored_where_no_input_has_it(tmp_path):
    """defaults.model names a_I_sol for every vehicle; one without that input loads, and the
    fit ignores the name (the structure has no such parameter)."""
    data = yaml.safe_load(SOLAR.read_text(encoding="utf-8"))
    data["channels"].pop("irradiance")
    data["raw_files"] = {"h2": str(RAW)}
    path = tmp_path / "Plain.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    defaults = {"model": {"initial": {"a_I_sol": 3.0}}}
    vehicle = load_vehicle(path, defaults=defaults, workdir=tmp_path)
    assert vehicle.model["initial"]["a_I_sol"] == 3.0
    fit = fit_of(tmp_path, vehicle, 1)
    assert "a_I_sol" not in fit["parameters"]


def test_a_share_is_accepted_for_a_gain_on_both_nodes(tmp_path):
    data = yaml.safe_load(SOLAR.read_text(encoding="utf-8"))
    data["channels"]["irradiance"][0]["node"] = "both"
    data["raw_files"] = {"h2": str(RAW)}
    data["model"] |= {"orders": [2], "initial": {"f_I_sol": 0.3}, "bounds": {"f_I_sol": [0.1, 1]}}
    path = tmp_path / "Both.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    vehicle = load_vehicle(path, workdir=tmp_path)
    assert vehicle.model["initial"] == {"f_I_sol": 0.3}
