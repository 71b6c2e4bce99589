"""The validation study on real measured data (the Armadillo Box, data/armadillo): a data set
is added by config alone, its estimates agree with pySIP's published analysis, and the
reference comparison (railtherm.study.reference) is honest about its inputs."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from chain import checked_fit
from compare_outputs import assert_outputs_agree
from snakemake_run import snakemake

from railtherm import config, structures
from railtherm.data import ingest
from railtherm.errors import ConfigError
from railtherm.records import FitRecord, JudgedEstimate
from railtherm.study import fitsettings, identify, reference

REPO = Path(__file__).resolve().parents[1]
VALIDATION = REPO / "validation"
RAW = REPO / "data" / "armadillo" / "armadillo_data_H2.csv"
PYSIP = VALIDATION / "config" / "published" / "pysip_armadillo.yaml"

# the published pySIP analysis (data/armadillo/README.md)
PYSIP_KA = 51.0  # W/K, 1 / (R_o + R_i)
PYSIP_NRMSE_FIT = 0.843


def validation_copy(tmp_path: Path) -> Path:
    """A scratch copy of the validation study (its config; the data through a link)."""
    study = tmp_path / "validation"
    shutil.copytree(VALIDATION / "config", study / "config")
    (tmp_path / "data").symlink_to(REPO / "data")
    return study


def renamed_copy(folder: Path, **extra: np.ndarray) -> Path:
    """The Armadillo CSV as another logger would write it: own column names and order,
    semicolons and decimal commas, the heating in kW and the indoor air in kelvin."""
    raw = pd.read_csv(RAW)
    renamed = pd.DataFrame(
        {
            "Innen_K": raw["T_int"] + 273.15,
            "Zeit_s": raw["Time"],
            "Heizung_kW": raw["P_hea"] / 1000.0,
            "Aussen_C": raw["T_ext"],
            "Strahlung": raw["I_sol"],
            **extra,
        }
    )
    path = folder / "logger.csv"
    renamed.to_csv(path, sep=";", decimal=",", index=False)
    return path


def renamed_vehicle(folder: Path) -> Path:
    """The Armadillo vehicle config, mapped onto the renamed copy: only config changes."""
    data = yaml.safe_load((VALIDATION / "config" / "vehicles" / "Armadillo.yaml").read_text())
    data["id"] = "Renamed"
    data["raw_files"] = {"h2": "logger.csv"}
    data["format"].update(
        separator=";", decimal=",", time={"column": "Zeit_s", "format": "seconds"}
    )
    data["channels"] = {
        "indoor_air": [{"column": "Innen_K", "unit": "K"}],
        "outdoor_air": [{"column": "Aussen_C"}],
        "heater_power": [{"column": "Heizung_kW", "unit": "kW"}],
    }
    path = folder / "Renamed.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def fit(vehicle_file: Path, model: str = "interior_envelope") -> tuple[dict, dict]:
    """What rules clean, identify and check do for one vehicle file (tests/chain.py): (the
    checked fit, as in fit_<model>.yaml, and the tidy windows)."""
    return checked_fit(vehicle_file, model)


@pytest.fixture(scope="module")
def armadillo_fit():
    """railtherm's interior-envelope fit of the Armadillo data (vehicle, fit, tables)."""
    path = VALIDATION / "config" / "vehicles" / "Armadillo.yaml"
    checked, tables = fit(path)
    return config.load_vehicle(path), checked, tables


def test_interior_envelope_kA_agrees_with_pysip(armadillo_fit):
    _, checked, _ = armadillo_fit
    kA = checked["parameters"]["kA"]
    assert kA["estimated"] == "derived"
    assert abs(kA["value"] / PYSIP_KA - 1) < 0.10
    lo, hi = kA["ci95"]
    assert lo < kA["value"] < hi
    assert checked["k_source"].startswith("joint estimation")
    assert checked["measures"]["T"]["overall"]["r2"] > 0.99


def test_adding_a_renamed_copy_needs_config_only(armadillo_fit, tmp_path):
    """Same data, other column names, separators and units, declared in YAML alone: the same
    estimates."""
    _, original, _ = armadillo_fit
    renamed_copy(tmp_path)
    estimate, tables = fit(renamed_vehicle(tmp_path))
    raw = pd.read_csv(RAW)
    window = raw[raw["Time"] <= 415_800]  # pySIP's rows: the window ends before the last
    assert list(tables["h2"]["T"].round(9)) == pytest.approx(list(window["T_int"]), abs=1e-9)
    for p in ("C", "K_i", "C_e", "K_o", "kA"):
        assert estimate["parameters"][p]["value"] == pytest.approx(
            original["parameters"][p]["value"], rel=1e-6
        ), p


def test_irradiance_and_known_heat_flows_are_declared_channels(tmp_path):
    """eq. 1's further terms: a known heat flow is added to Q_H, an irradiance channel
    becomes a model input I_<name> with its own aperture a_I_<name>."""
    occupants = np.where(np.arange(233) % 48 < 20, 0.35, 0.0)  # kW, 10 h a day
    renamed_copy(tmp_path, Personen_kW=occupants)
    data = yaml.safe_load(renamed_vehicle(tmp_path).read_text())
    data["channels"]["heat_flows"] = [{"column": "Personen_kW", "unit": "kW"}]
    data["channels"]["irradiance"] = [{"column": "Strahlung", "unit": "W/m2", "name": "south"}]
    data["format"]["power_timing"] = "mean_following"  # each sample the step's mean
    data["model"]["input_hold"] = "zero_order"  # a mean is held over its step
    data["windows"]["identification"][0]["end"] = 417_600  # every row of the file
    path = tmp_path / "Renamed.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    vehicle = config.load_vehicle(path)
    table = ingest.clean_window(vehicle.raw_files["h2"], vehicle.data, "h2")
    raw = pd.read_csv(RAW)
    assert ingest.irradiance_names(vehicle.data) == ["I_south"]
    # samples are interval means of the following step (power_timing: mean_following)
    np.testing.assert_allclose(table["Q_known"], 1000.0 * occupants)
    np.testing.assert_allclose(table["Q_H"], table["Q_heater"] + 1000.0 * occupants)
    np.testing.assert_allclose(table["I_south"].to_numpy(), raw["I_sol"].to_numpy())
    structure = fitsettings.model_structure("interior_envelope", vehicle.data)
    assert structure.inputs[-1] == "I_south" and "a_I_south" in structure.parameters


def test_solar_input_is_estimated_with_an_interval():
    vehicle_file = VALIDATION / "config" / "vehicles" / "Armadillo_solar.yaml"
    checked, _ = fit(vehicle_file)
    a = checked["parameters"]["a_I_sol"]
    assert a["estimated"] is True and a["value"] > 0
    assert a["ci95"][0] < a["value"] < a["ci95"][1]


def test_reference_comparison_on_the_armadillo_data(armadillo_fit):
    vehicle, checked, tables = armadillo_fit
    ref = reference.load_reference(PYSIP)
    table = reference.compare(ref, FitRecord.from_dict(checked), tables, vehicle.data).set_index(
        "quantity"
    )
    # pySIP's own parameters through railtherm's simulator reproduce pySIP's printed fit:
    # both tools read the same data and the same model
    assert table.loc["nrmse_fit", "published_simulated"] == pytest.approx(PYSIP_NRMSE_FIT, abs=0.01)
    assert table.loc["kA", "published_simulated"] == pytest.approx(1 / (0.01759 + 0.001984))
    # railtherm's fit is within 10 % on kA and at least as good in simulation
    assert abs(table.loc["kA", "ratio"] - 1) < 0.10
    assert table.loc["nrmse_fit", "railtherm"] >= table.loc["nrmse_fit", "published_simulated"]
    md = reference.markdown(table.reset_index(), [ref], "measured")
    assert "NRMSE fit" in md and "R² (eq. 21)" in md and "pySIP" in md
    with pytest.raises(ValueError, match="compared with the fit"):
        reference.compare(
            ref, FitRecord.from_dict({**checked, "model": "order2"}), tables, vehicle.data
        )


def test_a_reference_of_any_published_subset_compares_with_blanks(armadillo_fit, tmp_path):
    """A published analysis that printed kA alone, or an aperture railtherm's model lacks:
    the comparison shows what there is and leaves the rest blank, never a crash."""
    vehicle, checked, tables = armadillo_fit
    data = yaml.safe_load(PYSIP.read_text())
    data["parameters"] = {"kA": 51.0, "a_I_sol": 2.5}
    path = tmp_path / "ref.yaml"
    path.write_text(yaml.safe_dump(data))
    table = reference.compare(
        reference.load_reference(path), FitRecord.from_dict(checked), tables, vehicle.data
    )
    table = table.set_index("quantity")
    assert table.loc["kA", "published"] == 51.0
    assert abs(table.loc["kA", "ratio"] - 1) < 0.10
    assert np.isnan(table.loc["a_I_sol", "railtherm"]) and table.loc["a_I_sol", "unit"] == "m²"
    assert np.isnan(table.loc["nrmse_fit", "published_simulated"])  # nothing to simulate
    assert "–" in reference.markdown(table.reset_index(), [data], "measured")


@pytest.mark.bad_input
@pytest.mark.parametrize(
    ("edit", "key"),
    [
        (lambda d: d["parameters"].update(K_veh=3.0), "parameters"),
        (lambda d: d["parameters"].update(R_veh=3.0), "parameters.R_veh"),
        (lambda d: d["parameters"].update(C=-1.0), "parameters.C"),
        (lambda d: d.update(model="order3"), "model"),
    ],
)
def test_bad_reference_file_names_the_key(tmp_path, edit, key):
    data = yaml.safe_load(PYSIP.read_text())
    edit(data)
    path = tmp_path / "ref.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError) as err:
        reference.load_reference(path)
    assert str(path) in str(err.value) and key in str(err.value)


@pytest.mark.slow
@pytest.mark.workflow
def test_validation_study_reproduces_its_committed_results(tmp_path):
    """The README's validation command, from clean, in a scratch copy: the tables committed
    under validation/results (the text identical, the numbers within the tolerance of
    compare_outputs), the interior-envelope figures, and none of the paper's rail-vehicle
    tables; a second run does nothing."""
    study = validation_copy(tmp_path)
    run = snakemake(study)
    assert run.returncode == 0, run.stderr[-3000:]
    tables = sorted((VALIDATION / "results" / "tables").glob("*"))
    assert {p.name for p in tables} == {
        "identification.csv",
        "models.csv",
        "models.md",
        "reference.csv",
        "reference.md",
    }
    assert {p.name for p in (study / "results" / "tables").glob("*")} == {p.name for p in tables}
    assert_outputs_agree(study, VALIDATION, [p.relative_to(VALIDATION) for p in tables])
    for vid in ("Armadillo", "Armadillo_solar"):
        for key in ("order1", "order2", "interior_envelope"):
            assert (study / "results" / "vehicles" / vid / f"fit_{key}.png").is_file()
    assert not (study / "results" / "figures").exists()  # no Figure 3-5 of rail vehicles
    again = snakemake(study)
    assert "Nothing to be done" in again.stdout + again.stderr


@pytest.mark.parametrize("rho", [-0.8, 0.0, 0.6])
def test_derived_kA_interval_matches_monte_carlo(rho):
    """kA = K_i K_o / (K_i + K_o) of losses in series: its delta-method sd (log) against
    sampling log K_i, log K_o from the fit's normal approximation."""
    sd = {"K_i": 0.04, "K_o": 0.02}
    fitted = {
        "parameters": {
            "C": {"value": 2.0e5, "sd_log": 0.1},
            "K_i": {"value": 320.0, "sd_log": sd["K_i"]},
            "C_e": {"value": 4.0e6, "fixed": True},
            "K_o": {"value": 65.0, "sd_log_total": sd["K_o"]},
        },
        "free": ["C", "K_i", "K_o"],
        "correlation": [[1.0, 0.0, 0.0], [0.0, 1.0, rho], [0.0, rho, 1.0]],
    }
    kA = identify.derived_kA(
        JudgedEstimate.from_dict(fitted), structures.STRUCTURES["interior_envelope"]
    )
    assert kA["value"] == pytest.approx(320.0 * 65.0 / 385.0)
    cov = np.array([[sd["K_i"] ** 2, rho * 0.04 * 0.02], [rho * 0.04 * 0.02, sd["K_o"] ** 2]])
    draws = np.random.default_rng(8).multivariate_normal([np.log(320.0), np.log(65.0)], cov, 50_000)
    K_i, K_o = np.exp(draws).T
    assert np.std(np.log(K_i * K_o / (K_i + K_o))) == pytest.approx(kA["sd_log_total"], rel=0.03)
    lo, hi = kA["ci95"]
    assert lo < kA["value"] < hi


@pytest.mark.bad_input
@pytest.mark.workflow
def test_reference_to_a_fit_not_in_the_study_stops_the_run(tmp_path):
    study = validation_copy(tmp_path)
    vehicle = study / "config" / "vehicles" / "Armadillo.yaml"
    data = yaml.safe_load(vehicle.read_text())
    del data["model"]["structures"]
    vehicle.write_text(yaml.safe_dump(data, sort_keys=False))
    run = snakemake(study, "--dry-run")
    assert run.returncode != 0
    err = run.stdout + run.stderr
    assert "config/published/pysip_armadillo.yaml" in err and "'interior_envelope'" in err
    assert "Armadillo" in err and not (study / "results").exists()


@pytest.mark.bad_input
@pytest.mark.workflow
def test_new_raw_content_with_the_old_mtime_reruns_its_jobs(tmp_path):
    """A measured raw file replaced by other content with the same size class and the old
    mtime (cp -p, a restored backup): the content digest of the file reruns its clean job,
    where file times alone would say "Nothing to be done"."""
    study = tmp_path / "validation"
    shutil.copytree(VALIDATION / "config", study / "config")
    shutil.copytree(REPO / "data", tmp_path / "data")
    raw = tmp_path / "data" / "armadillo" / "armadillo_data_H2.csv"
    target = "results/vehicles/Armadillo/clean/h2.csv"
    assert snakemake(study, target).returncode == 0
    assert "Nothing to be done" in (r := snakemake(study, target, "-n")).stdout + r.stderr
    before = raw.stat()
    lines = raw.read_text().splitlines(keepends=True)
    # the same bytes in another order: other measurements at the same times
    (t5, v5), (t6, v6) = (line.split(",", 1) for line in lines[5:7])
    lines[5], lines[6] = f"{t5},{v6}", f"{t6},{v5}"
    raw.write_text("".join(lines))
    os.utime(raw, ns=(before.st_atime_ns, before.st_mtime_ns))
    assert raw.stat().st_mtime_ns == before.st_mtime_ns and raw.stat().st_size == before.st_size
    again = snakemake(study, target, "-n")
    assert again.returncode == 0
    assert "rule clean:" in again.stdout and "Nothing to be done" not in again.stdout


@pytest.mark.bad_input
@pytest.mark.workflow
def test_a_bad_value_in_a_measured_file_stops_the_run_before_any_job(tmp_path):
    """The values of the study's own raw files are read at parse time, as clean reads them."""
    study = tmp_path / "validation"
    shutil.copytree(VALIDATION / "config", study / "config")
    shutil.copytree(REPO / "data", tmp_path / "data")
    raw = tmp_path / "data" / "armadillo" / "armadillo_data_H2.csv"
    lines = raw.read_text().splitlines(keepends=True)
    header = lines[0].strip().split(",")
    cells = lines[100].rstrip("\n").split(",")
    cells[header.index("T_int")] = "inf"
    lines[100] = ",".join(cells) + "\n"
    raw.write_text("".join(lines))
    run = snakemake(study, "--dry-run")
    assert run.returncode != 0
    err = run.stdout + run.stderr
    assert "invalid raw data" in err and "column 'T_int' = 'inf': line 101" in err, err
    assert not (study / "results").exists()


@pytest.mark.bad_input
def test_validate_checks_the_reference_files_as_the_run_would(tmp_path, capsys):
    """Once a reference naming a fit the study does not make passed validate and stopped the
    run at parse time."""
    from railtherm.cli import main

    study = validation_copy(tmp_path)
    assert main(["validate", "-d", str(study)]) == 0
    assert "4 reference files" in capsys.readouterr().out
    vehicle = study / "config" / "vehicles" / "Armadillo.yaml"
    data = yaml.safe_load(vehicle.read_text())
    del data["model"]["structures"]
    vehicle.write_text(yaml.safe_dump(data, sort_keys=False))
    assert main(["validate", "-d", str(study)]) == 1
    err = capsys.readouterr().err
    assert err.startswith(
        "config/published/pysip_armadillo.yaml: key 'model' = 'interior_envelope'"
    )
    assert "no such fit in the study" in err


@pytest.mark.slow
def test_every_model_combination_that_validates_runs_to_the_end(tmp_path):
    """Model sections a user may write - no model.orders (the paper's two), the Kalman
    estimator alone, order 2 with interior_envelope but no order 1, no order at all beside a
    structure - each validate and run to the tables (a day of the Armadillo record each)."""
    study = validation_copy(tmp_path)
    base = yaml.safe_load((study / "config" / "vehicles" / "Armadillo.yaml").read_text())
    base["windows"]["identification"][0]["end"] = 86_400
    variants = {
        "NoOrders": {"structures": [], "mode": "joint"},
        "KalmanOnly": {"orders": [1], "structures": [], "estimator": "kalman", "mode": "joint"},
        "Order2Envelope": {"orders": [2], "structures": ["interior_envelope"], "mode": "joint"},
        "EnvelopeOnly": {"orders": [], "structures": ["interior_envelope"], "mode": "joint"},
    }
    paths = []
    for name, model in variants.items():
        data = {**base, "id": name, "model": {"x0": "estimated", **model}}
        path = study / "config" / "vehicles" / f"{name}.yaml"
        path.write_text(yaml.safe_dump(data, sort_keys=False))
        paths.append(f"config/vehicles/{name}.yaml")
    cfg_path = study / "config" / "config.yaml"
    cfg = yaml.safe_load(cfg_path.read_text())
    cfg["vehicles"] = paths
    cfg["study"]["references"] = []
    cfg_path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    from railtherm.cli import main

    assert main(["validate", "-d", str(study)]) == 0
    run = snakemake(study)
    assert run.returncode == 0, run.stderr[-3000:]
    models = pd.read_csv(study / "results" / "tables" / "models.csv")
    got = {(r.vehicle, r.model) for r in models.itertuples()}
    assert got == {
        ("NoOrders", "order1"),
        ("NoOrders", "order2"),
        ("KalmanOnly", "order1_kalman"),
        ("Order2Envelope", "order2"),
        ("Order2Envelope", "interior_envelope"),
        ("EnvelopeOnly", "interior_envelope"),
    }
    fits = pd.read_csv(study / "results" / "tables" / "identification.csv")
    assert sorted(fits["vehicle"]) == ["KalmanOnly", "NoOrders", "NoOrders", "Order2Envelope"]


@pytest.mark.bad_input
@pytest.mark.workflow
def test_identification_windows_that_overlap_are_refused_by_validate_and_the_parse(
    tmp_path, capsys
):
    """Two identification windows of one record sharing samples (a window added twice under
    two names): the fit counted those samples twice and narrowed its intervals, without a
    word. `railtherm validate` and the workflow's parse refuse it alike, naming both; windows
    that meet at one instant are no overlap."""
    from railtherm.cli import main

    study = tmp_path / "validation"
    shutil.copytree(VALIDATION / "config", study / "config")
    shutil.copytree(REPO / "data", tmp_path / "data")
    path = study / "config" / "vehicles" / "Armadillo.yaml"
    data = yaml.safe_load(path.read_text())
    (window,) = data["windows"]["identification"]
    cfg_path = study / "config" / "config.yaml"
    cfg = yaml.safe_load(cfg_path.read_text())
    cfg["vehicles"], cfg["study"]["references"] = ["config/vehicles/Armadillo.yaml"], []
    cfg_path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    middle = (window["start"] + window["end"]) // 2
    data["windows"]["identification"] = [
        {**window, "name": "first", "end": middle},
        {**window, "name": "second", "start": middle},
    ]
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    assert main(["validate", "-d", str(study)]) == 0  # meeting at one instant
    capsys.readouterr()
    data["windows"]["identification"] = [window, {**window, "name": "again"}]
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    assert main(["validate", "-d", str(study)]) == 1
    err = capsys.readouterr().err
    assert "key 'windows.identification' = 'h2, again': the windows overlap on" in err, err
    run = snakemake(study, "--dry-run")
    assert run.returncode != 0
    assert "key 'windows.identification' = 'h2, again'" in run.stdout + run.stderr
