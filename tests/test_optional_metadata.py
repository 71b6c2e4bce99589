"""Metadata that means nothing for an object is optional: an object of class other (a building
test cell such as the Armadillo Box) may leave out mass_kg and surface_m2. Then k = kA / A
(eq. 10) and c_veh = C_veh / m_veh (eq. 24) are not given for it - a blank with its reason in
every table, never a crash or a printed NaN - and the checks that read them are skipped with a
note. A rail vehicle must give both."""

from __future__ import annotations

import math
import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from snakemake_run import snakemake
from test_identify import TABLES, TRUTH, vehicle
from test_kvalue import COUNTS, INSTRUMENTS, SETTINGS, window
from test_study_tables import fit, kv

from railtherm.cli import main
from railtherm.config import load_vehicle, metadata_classes, section_defaults
from railtherm.errors import ConfigError
from railtherm.estimation import kvalue
from railtherm.records import EstimateRecord
from railtherm.report import audit, plots, tableformat
from railtherm.study import aggregate, fitsettings, identify, quality
from railtherm.study.fit import read_fit

REPO = Path(__file__).resolve().parents[1]
ARMADILLO = REPO / "validation" / "config" / "vehicles" / "Armadillo.yaml"
METADATA = ("mass_kg", "surface_m2")


def armadillo_copy(root: Path, drop: tuple[str, ...] = METADATA) -> Path:
    """The validation study's Armadillo vehicle (class other) under ``root``, its raw file
    reached by an absolute path, without the metadata keys ``drop``."""
    data = yaml.safe_load(ARMADILLO.read_text(encoding="utf-8"))
    for key in drop:
        data.pop(key)
    data["raw_files"] = {"h2": str(REPO / "data" / "armadillo" / "armadillo_data_H2.csv")}
    path = root / "config" / "vehicles" / "Armadillo.yaml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def no_nan_printed(text: str) -> None:
    assert not re.search(r"\bnan\b", text, re.IGNORECASE), text


# --- the config --------------------------------------------------------------------------------


def test_class_other_may_leave_out_mass_and_surface(tmp_path):
    vehicle_ = load_vehicle(armadillo_copy(tmp_path), workdir=tmp_path)
    assert vehicle_.vehicle_class == "other"
    assert vehicle_.mass_kg is None and vehicle_.surface_m2 is None
    assert "mass_kg" not in vehicle_.data and "surface_m2" not in vehicle_.data
    kept = load_vehicle(armadillo_copy(tmp_path, drop=("surface_m2",)), workdir=tmp_path)
    assert kept.mass_kg == 20000.0 and kept.surface_m2 is None


@pytest.mark.bad_input
@pytest.mark.parametrize("cls", ["tram", "metro", "regional", "main-line"])
@pytest.mark.parametrize("key", METADATA)
def test_a_rail_vehicle_must_give_mass_and_surface(tmp_path, cls, key):
    path = armadillo_copy(tmp_path, drop=(key,))
    data = yaml.safe_load(path.read_text(encoding="utf-8"))
    data["class"] = cls
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        load_vehicle(path, workdir=tmp_path)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith("config/vehicles/Armadillo.yaml: key")
    assert info.value.key == key and f"class '{cls}'" in message
    assert "missing required key" in message and "class 'other'" in message


def test_the_rail_classes_are_the_schemas_classes_but_other():
    schema_classes = aggregate.CLASS_ORDER
    assert set(metadata_classes()) == set(schema_classes) - {"other"}


# --- the static k test (eq. 10) ----------------------------------------------------------------


def test_static_k_without_surface_gives_kA_and_its_relative_uncertainty():
    w = window(hours=8.0, T_veh=16.0)
    with_surface = kvalue.static_k(w, 400.0, 4e4, SETTINGS, INSTRUMENTS, COUNTS)
    without = kvalue.static_k(w, None, 4e4, SETTINGS, INSTRUMENTS, COUNTS)
    assert without.k is None and without.u_k is None and without.A is None
    assert without.kA == pytest.approx(with_surface.kA, rel=1e-12)
    # surface_u_rel is 0 here: kA's relative uncertainty is k's
    assert without.u_k_rel == pytest.approx(with_surface.u_k_rel, rel=1e-9)
    assert without.u_kA == pytest.approx(with_surface.u_k_rel * with_surface.kA, rel=1e-9)
    assert without.budget.unit == "W/K" and with_surface.budget.unit == "W/(m2 K)"
    assert without.budget.scatter == pytest.approx(with_surface.budget.scatter * 400.0)
    assert any("no surface_m2" in n for n in without.notes) and with_surface.notes == ()
    d = without.to_dict()
    assert d["k"] is None and d["u_k"] is None and d["A"] is None
    assert yaml.safe_load(yaml.safe_dump(d, sort_keys=False)) == d
    assert kvalue.KValue.from_dict(d) == without


def test_static_k_without_mass_leaves_the_storage_unbounded_with_a_note():
    w = window(hours=8.0, T_veh=16.0)
    r = kvalue.static_k(w, 400.0, None, SETTINGS, INSTRUMENTS, COUNTS)
    assert r.k is not None and r.budget.storage == 0.0
    assert r.budget.storage_bound_W is None and r.budget.storage_from.endswith("no mass_kg")
    assert any("no mass_kg" in n for n in r.notes)
    assert kvalue.KValue.from_dict(r.to_dict()) == r


def test_the_k_figure_of_an_object_without_surface_gives_kA():
    r = kvalue.static_k(window(hours=8.0, T_veh=16.0), None, None, SETTINGS, INSTRUMENTS, COUNTS)
    text = plots._verdict_text(r)
    assert text.startswith("kA = ") and "k not given: no surface_m2" in text
    no_nan_printed(text)


# --- identification (eqs. 15-20) and its checks -------------------------------------------------


def bare(**model) -> dict:
    """test_identify's vehicle without mass and surface."""
    data = vehicle(**model)
    del data["mass_kg"], data["surface_m2"]
    return data


def test_two_stage_fit_without_surface_takes_kA_from_the_static_test():
    k = {
        "k": None,
        "kA": TRUTH["kA"],
        "usable": True,
        "forced": False,
        "Q_H_mean": TRUTH["kA"] * 30.0,
        "delta_T": 30.0,
        "budget": {"scatter": 0.0, "storage": 0.0, "unit": "W/K"},
    }
    estimate, series = identify.identify(TABLES, bare(), k, 2)
    params = estimate.content["fit"]["parameters"]
    assert params["kA"] == {"value": pytest.approx(TRUTH["kA"]), "estimated": False}
    for p in ("C", "K_veh", "C_veh"):
        assert params[p]["value"] == pytest.approx(TRUTH[p], rel=1e-5)
    assert estimate.content["A"] is None and estimate.content["mass_kg"] is None
    result = quality.check(estimate, series, section_defaults("check"))
    assert result.content["verdict"] == "fit acceptable", result.content["reasons"]
    notes = " ".join(result.content["notes"])
    assert "k_range_W_m2K) not checked: no surface_m2" in notes
    assert "min_capacity_per_kg_J_kgK" in notes and "no mass_kg" in notes


def test_joint_fit_without_surface_starts_from_the_energy_balance():
    start = fitsettings.energy_balance_kA(TABLES)
    rows = pd.concat(TABLES.values())
    assert start == pytest.approx(rows["Q_H"].mean() / (rows["T"] - rows["T_o"]).mean())
    assert fitsettings.energy_balance_kA({"w": TABLES["up"].assign(Q_H=0.0)}) is None
    estimate, _ = identify.identify(TABLES, bare(mode="joint"), None, 2)
    assert estimate.content["fit"]["parameters"]["kA"]["value"] == pytest.approx(
        TRUTH["kA"], rel=1e-5
    )


@pytest.mark.bad_input
def test_an_implausible_fit_of_a_rail_vehicle_is_still_caught():
    """The skipped checks skip only where the metadata is absent."""
    estimate, _ = identify.identify(TABLES, vehicle(), None, 2)
    light = {**estimate.content, "mass_kg": 5_000.0}
    assert any(
        "more than water" in r for r in quality.plausibility(EstimateRecord.from_dict(light), {})
    )
    assert quality.skipped_checks(estimate) == []
    assert quality.plausibility(EstimateRecord.from_dict({**light, "mass_kg": None}), {}) == []
    assert len(quality.skipped_checks(EstimateRecord.from_dict({**light, "mass_kg": None}))) == 1


# --- the tables --------------------------------------------------------------------------------


def study_vehicle(cls: str, **metadata) -> dict:
    return {
        "class": cls,
        "synthetic": False,
        "windows": {"identification": [{"name": "w0"}]},
        **metadata,
    }


@pytest.fixture
def mixed_tables() -> dict[str, pd.DataFrame]:
    """Two metros with every key; a test cell without either; one with a mass only."""
    vehicles = {
        "M1": study_vehicle("metro", mass_kg=40_000.0, surface_m2=300.0),
        "M2": study_vehicle("metro", mass_kg=35_000.0, surface_m2=280.0),
        "Cell": study_vehicle("other"),
        "Box": study_vehicle("other", mass_kg=20_000.0),
    }
    fits = {
        "M1": fit(1e7, 500, 2e7),
        "M2": fit(9e6, 400, 1.6e7),
        "Cell": fit(2.5e6, 300, 1.5e7, kA=54.0),
        "Box": fit(3e6, 250, 1.2e7, kA=60.0),
    }
    kvalues = {"M1": kv(2.8), "M2": kv(2.6), "Cell": None, "Box": None}
    return aggregate.study_tables(fits, kvalues, vehicles, ("metro", "other"))


def test_table2_and_3_leave_k_and_c_veh_blank_with_the_reason(mixed_tables):
    t2 = mixed_tables["table2"].set_index("vehicle")
    for vid in ("Cell", "Box"):
        assert t2.loc[vid, "k_status"] == "not given: no surface_m2"
        assert all(math.isnan(t2.loc[vid, c]) for c in ("k", "k_lo", "k_hi", "k_limit"))
        assert t2.loc[vid, "C_status"] == "estimated"  # the capacities are there
    assert t2.loc["M1", "k_status"] == "estimated"
    t3 = mixed_tables["table3"].set_index("vehicle")
    assert t3.loc["Cell", "c_veh_status"] == "not given: no mass_kg"
    assert math.isnan(t3.loc["Cell", "c_veh"]) and math.isnan(t3.loc["Cell", "m_veh"])
    assert t3.loc["Box", "c_veh"] == pytest.approx(1.2e7 / 20_000.0)
    assert t3.loc["Cell", "delta"] == pytest.approx(1.5e7 / 2.5e6)  # needs no mass


def test_class_statistics_skip_a_value_not_given(mixed_tables):
    summary = mixed_tables["class_summary"]
    every = summary[summary["selection"] == "every identified value"].set_index(
        ["class", "quantity"]
    )
    assert every.loc[("other", "c_veh"), "n"] == 1
    assert every.loc[("other", "c_veh"), "vehicles"] == "Box"
    assert every.loc[("other", "c_veh"), "not_identified"] == ""  # not given is no failure
    assert every.loc[("other", "delta"), "n"] == 2
    test = mixed_tables["class_test"].iloc[0]
    assert (test["n_a"], test["n_b"]) == (2, 1)


def test_markdown_and_latex_show_not_given_once_never_nan(mixed_tables, tmp_path):
    source = aggregate.data_source({"x": {"synthetic": False}})
    paths = {
        f"{name}_{ext}": str(tmp_path / f"{name}.{ext}")
        for name in mixed_tables
        for ext in ("csv", "md", "tex")
    }
    tableformat.write_study_tables(mixed_tables, source, paths)
    t2 = (tmp_path / "table2.md").read_text(encoding="utf-8")
    t3 = (tmp_path / "table3.md").read_text(encoding="utf-8")
    for text in (t2, t3, (tmp_path / "class_summary.md").read_text(encoding="utf-8")):
        no_nan_printed(text)
    for name in mixed_tables:
        no_nan_printed((tmp_path / f"{name}.tex").read_text(encoding="utf-8"))
    cell_row = next(line for line in t2.splitlines() if line.startswith("| Cell"))
    assert "not given" in cell_row.split("|")[3]
    assert t2.count("not given: no surface_m2 (Cell, Box)") == 1
    assert t3.count("not given: no mass_kg (Cell)") == 1
    assert "no mass_kg" not in t2 and "no surface_m2" not in t3
    csv = pd.read_csv(tmp_path / "table2.csv").set_index("vehicle")
    assert pd.isna(csv.loc["Cell", "k"]) and csv.loc["Cell", "k_status"].startswith("not given")
    assert "left out of the statistics" in (tmp_path / "class_summary.md").read_text()


def test_rail_only_tables_get_no_note_about_missing_metadata():
    vehicles = {"M1": study_vehicle("metro", mass_kg=4e4, surface_m2=300.0)}
    tables = aggregate.study_tables({"M1": fit(1e7, 500, 2e7)}, {"M1": kv(2.8)}, vehicles)
    assert all(tableformat.not_given_notes(name, tables) == [] for name in tables)


def test_kvalue_table_blank_k_and_kA_against_the_truth():
    cell = kvalue.static_k(window(hours=8.0), None, None, SETTINGS, INSTRUMENTS, COUNTS)
    tram = kvalue.static_k(window(hours=8.0), 400.0, 4e4, SETTINGS, INSTRUMENTS, COUNTS)
    results = {"Tram": tram.to_dict(), "Cell": cell.to_dict()}
    truth = pd.DataFrame(
        {
            "vehicle": ["Tram", "Cell"],
            "k": [tram.k, tram.k],
            "kA": [tram.kA, tram.kA * 1.2],
            "deviations": ["", ""],
            "k_effects": [np.nan, np.nan],
        }
    )
    table = aggregate.kvalue_table(results, truth).set_index("vehicle")
    assert pd.isna(table.loc["Cell", "k"]) and pd.isna(table.loc["Cell", "U_k"])
    assert table.loc["Cell", "k_status"] == "not given: no surface_m2"
    assert table.loc["Tram", "k_status"] == "estimated"
    assert table.loc["Cell", "kA"] == pytest.approx(cell.kA)
    assert table.loc["Cell", "rel_error"] == pytest.approx(1 / 1.2 - 1)
    assert not table.loc["Cell", "agrees"] and "kA compared" in table.loc["Cell", "note"]
    # a study of rail vehicles alone keeps its columns
    alone = aggregate.kvalue_table({"Tram": tram.to_dict()})
    assert "k_status" not in alone and "kA" not in alone


# --- figures and the audit ----------------------------------------------------------------------


def test_figure5_leaves_out_a_value_not_given_and_says_so(mixed_tables, tmp_path):
    t3 = mixed_tables["table3"]
    fig_a, fig_b = plots.figure5(t3)
    labels = [t.get_text() for ax in fig_a.axes for t in ax.texts]
    assert "Cell" not in labels and "Box" in labels
    legend = [t.get_text() for ax in fig_a.axes if ax.get_legend() for t in ax.get_legend().texts]
    assert "not shown: Cell (not given: no mass_kg)" in legend
    assert "Cell" in [t.get_text() for ax in fig_b.axes for t in ax.texts]  # delta is there
    only_cells = t3[t3["vehicle"] == "Cell"]
    empty, _ = plots.figure5(only_cells)
    message = " ".join(t.get_text() for ax in empty.axes for t in ax.texts)
    assert "no vehicle to show" in message and "no mass_kg" in message
    plots.save_figure(empty, tmp_path / "empty")
    assert (tmp_path / "empty.png").stat().st_size > 0


def test_audit_finds_a_value_not_given_not_comparable():
    published = audit.Printed("2.50", 2.5, audit.Interval(2.495, 2.505))
    verdict, interval = audit.compare_reestimate(
        published, math.nan, math.nan, math.nan, "not given: no surface_m2"
    )
    assert verdict == "not comparable: not given: no surface_m2" and interval is None


# --- end to end ---------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def cli_fit(tmp_path_factory) -> Path:
    """`railtherm fit VEHICLE.yaml --out DIR` on the Armadillo without mass and surface."""
    root = tmp_path_factory.mktemp("fit")
    armadillo_copy(root)
    status = main(["fit", "config/vehicles/Armadillo.yaml", "--out", "out", "-d", str(root)])
    assert status == 0
    return root / "out" / "vehicles" / "Armadillo"


def test_railtherm_fit_runs_an_object_without_mass_and_surface(cli_fit, capsys):
    for model in ("order1", "order2", "interior_envelope"):
        result = read_fit(cli_fit / f"fit_{model}.yaml")
        assert result.parameters["kA"].value > 0
        notes = " ".join(result.content["notes"])
        assert "no surface_m2" in notes and "no mass_kg" in notes
        assert not any("k = kA / A" in r for r in result.reasons)
        estimate = yaml.safe_load((cli_fit / "identify" / f"{model}.yaml").read_text())
        assert estimate["A"] is None and estimate["mass_kg"] is None


def test_railtherm_new_vehicle_starter_validates_as_class_other_without_the_two_keys(tmp_path):
    """The starter writes mass_kg and surface_m2 as TODOs; for an object of class other both
    lines may be deleted."""
    raw = tmp_path / "cell.csv"
    shutil.copy(REPO / "data" / "armadillo" / "armadillo_data_H2.csv", raw)
    out = tmp_path / "Cell.yaml"
    assert main(["new-vehicle", str(raw), "--out", str(out), "--id", "Cell"]) == 0
    text = out.read_text(encoding="utf-8")
    assert re.search(r"^mass_kg: TODO", text, re.M) and re.search(r"^surface_m2: TODO", text, re.M)
    text = re.sub(r"^(mass_kg|surface_m2): TODO.*\n", "", text, flags=re.M)
    text = re.sub(r"^class: TODO.*$", "class: other", text, flags=re.M)
    out.write_text(text, encoding="utf-8")
    vehicle_ = load_vehicle(out, workdir=tmp_path)
    assert vehicle_.mass_kg is None and vehicle_.surface_m2 is None


def metadata_study(root: Path) -> Path:
    """A small study: Tram2 of the virtual campaign declared class other without mass and
    surface (so its static k test gives kA only), Metro3 as shipped, and the Armadillo test
    cell with its mass but no surface, beside its published pySIP analysis."""
    study = root / "study"
    shutil.copytree(REPO / "config", study / "config")
    tram = study / "config" / "vehicles" / "Tram2.yaml"
    data = yaml.safe_load(tram.read_text(encoding="utf-8"))
    data["class"] = "other"
    for key in METADATA:
        data.pop(key)
    tram.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    armadillo_copy(study, drop=("surface_m2",))
    shutil.copy(
        REPO / "validation" / "config" / "published" / "pysip_armadillo.yaml",
        study / "config" / "published" / "pysip_armadillo.yaml",
    )
    cfg_path = study / "config" / "config.yaml"
    cfg = yaml.safe_load(cfg_path.read_text(encoding="utf-8"))
    cfg["vehicles"] = [f"config/vehicles/{v}.yaml" for v in ("Tram2", "Metro3", "Armadillo")]
    cfg["sindy"]["enabled"] = False
    cfg["study"]["references"] = ["config/published/pysip_armadillo.yaml"]
    cfg["study"]["class_test"] = ["metro", "other"]
    cfg_path.write_text(yaml.safe_dump(cfg, sort_keys=False), encoding="utf-8")
    return study


@pytest.mark.slow
@pytest.mark.workflow
def test_snakemake_study_with_objects_without_metadata(tmp_path):
    study = metadata_study(tmp_path)
    run = snakemake(study)
    assert run.returncode == 0, run.stderr[-3000:]
    tables = study / "results" / "tables"
    for md in sorted(tables.glob("*.md")) + sorted(tables.glob("*.tex")):
        no_nan_printed(md.read_text(encoding="utf-8"))
    k = pd.read_csv(tables / "kvalue.csv").set_index("vehicle")
    assert pd.isna(k.loc["Tram2", "k"]) and k.loc["Tram2", "kA"] > 0
    assert k.loc["Tram2", "k_status"] == "not given: no surface_m2"
    assert k.loc["Metro3", "k"] > 0 and k.loc["Metro3", "k_status"] == "estimated"
    t2 = (tables / "table2.md").read_text(encoding="utf-8")
    assert t2.count("not given: no surface_m2 (Tram2, Armadillo)") == 1
    t3 = pd.read_csv(tables / "table3.csv").set_index("vehicle")
    assert t3.loc["Tram2", "c_veh_status"] == "not given: no mass_kg"
    assert t3.loc["Armadillo", "c_veh_status"] != "not given: no mass_kg"
    assert "not given: no mass_kg (Tram2)" in (tables / "table3.md").read_text()
    summary = pd.read_csv(tables / "class_summary.csv", keep_default_na=False)
    other = summary[(summary["class"] == "other") & (summary["quantity"] == "c_veh")]
    assert "Tram2" not in " ".join(other["vehicles"]) + " ".join(other["not_identified"])
    findings = pd.read_csv(study / "results" / "audit" / "findings.csv")
    # a study of some vehicles synthesises, re-estimates and draws only those: no Metro1
    # (Figure 4 shows Metro1 and Metro2)
    assert not (study / "resources" / "campaign" / "Metro1").exists()
    reestimated = findings.loc[findings["check"] == "reestimate", "subject"]
    assert "Tram2 C" in set(reestimated) and not reestimated.str.startswith("Metro1 ").any()
    assert not (study / "results" / "figures" / "figure4.png").exists()
    tram_k = findings[findings["subject"] == "Tram2 k"]["message"].iloc[0]
    assert tram_k.startswith("not comparable: not given: no surface_m2")
    assert (tables / "reference.md").is_file()
    for png in ("vehicles/Tram2/kvalue.png", "figures/figure5a.png", "figures/figure3.png"):
        assert (study / "results" / png).is_file(), png
    fit2 = read_fit(study / "results" / "vehicles" / "Tram2" / "fit_order2.yaml")
    # kA from the k window (storage-corrected), no surface needed
    assert fit2.k_source == "static test (eq. 10), storage-corrected"
    assert fit2.content["k_eq10"] is not None and fit2.content["kA_fixed"] == fit2.theta["kA"]


def test_railtherm_fit_prints_kA_for_an_object_without_surface_with_a_k_window(tmp_path, capsys):
    """Tram2 of the virtual campaign declared class other without a surface: its static test
    gives kA (W/K), and `railtherm fit` prints kA, not k."""
    shutil.copytree(REPO / "config", tmp_path / "config")
    tram = tmp_path / "config" / "vehicles" / "Tram2.yaml"
    data = yaml.safe_load(tram.read_text(encoding="utf-8"))
    data["class"] = "other"
    data.pop("surface_m2")
    tram.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    status = main(["fit", "config/vehicles/Tram2.yaml", "--model", "order1", "-d", str(tmp_path)])
    assert status == 0
    out = capsys.readouterr().out
    pattern = (
        r"Tram2: kA = [0-9.]+ ± [0-9.]+ W/K \(± one standard uncertainty u; eq. 10; k not given"
    )
    assert re.search(pattern, out), out
    no_nan_printed(out)
