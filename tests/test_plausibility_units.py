"""A temperature channel declared in the wrong unit: refused at the k window, or put in doubt
by the verdict, with the file, the columns, the declared unit and "check the unit" named.

The record of the main case is simulated here from eqs. 7-8 (the second-order model, its
exact discretisation under held inputs written out with scipy's matrix exponential), not by
railtherm's own synthesizer or model code, then written in degC and declared degF.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import expm

from railtherm.cli import main
from railtherm.config import add_vehicle, load_study, read_yaml, study_context
from railtherm.data import datacheck, plausibility
from railtherm.errors import DataError
from railtherm.estimation import kvalue
from railtherm.study import run

REPO = Path(__file__).resolve().parents[1]

# a metro car of the paper's class (k = 700 / 241.6 = 2.9 W/(m2 K)), eqs. 7-8, SI units
KA, C, K_VEH, C_VEH = 700.0, 9.0e6, 450.0, 1.8e7
AREA = 241.6
STEP = 60.0


def eqs_7_8_record(hours: float = 20.0, seed: int = 7) -> pd.DataFrame:
    """A tunnel record of eqs. 7-8: the cabin held steady at 20 degC against a -15 degC
    tunnel by 24.5 kW for 8 h (the k window), then the heating cut to 10 kW; zero-order held
    inputs, the exact discretisation exp([[A, B], [0, 0]] dt), 0.05 K sensor noise. degC, W."""
    A = np.array([[-(KA + K_VEH) / C, K_VEH / C], [K_VEH / C_VEH, -K_VEH / C_VEH]])
    B = np.array([[KA / C, 1.0 / C], [0.0, 0.0]])
    M = expm(np.block([[A, B], [np.zeros((2, 4))]]) * STEP)
    Ad, Bd = M[:2, :2], M[:2, 2:]
    n = int(hours * 3600 / STEP) + 1
    T_o = np.full(n, -15.0)
    Q = np.where(np.arange(n) * STEP < 8 * 3600, KA * 35.0, 10_000.0)
    x = np.empty((n, 2))
    x[0] = [20.0, 20.0]  # the steady state of 24.5 kW against -15 degC
    for i in range(n - 1):
        x[i + 1] = Ad @ x[i] + Bd @ np.array([T_o[i], Q[i]])
    rng = np.random.default_rng(seed)
    noise = rng.normal(0.0, 0.05, (n, 3))
    return pd.DataFrame(
        {
            "t_s": np.arange(n) * STEP,
            "T_in": np.round(x[:, 0] + noise[:, 0], 3),
            "T_wall": np.round(x[:, 1] + noise[:, 1], 3),
            "T_out": np.round(T_o + noise[:, 2], 3),
            "P_heat": Q,
        }
    )


def vehicle_config(unit: str, kvalue_window: bool = True, outdoor_unit: str | None = None):
    windows = {"identification": [{"name": "run", "start": 0, "end": 72000}]}
    if kvalue_window:
        windows["kvalue"] = {"start": 0, "end": 28800}
    return {
        "id": "Gen",
        "class": "metro",
        "mass_kg": 35000,
        "surface_m2": AREA,
        "volume_m3": 90.0,
        "raw_files": {"cwt": "../../data/gen.csv"},
        "format": {"time": {"column": "t_s", "format": "seconds"}},
        "channels": {
            "indoor_air": [{"column": "T_in", "unit": unit}],
            "surface": [{"column": "T_wall", "unit": unit}],
            "outdoor_air": [{"column": "T_out", "unit": outdoor_unit or unit}],
            "heater_power": [{"column": "P_heat", "unit": "W"}],
        },
        "windows": windows,
        "model": {"orders": [2], "mode": "static" if kvalue_window else "joint"},
    }


def write_generated(root: Path, config: dict) -> str:
    os.makedirs(root / "data", exist_ok=True)
    os.makedirs(root / "config" / "vehicles", exist_ok=True)
    eqs_7_8_record().to_csv(root / "data" / "gen.csv", index=False)
    path = root / "config" / "vehicles" / "Gen.yaml"
    path.write_text(yaml.safe_dump(config, sort_keys=False))
    return "config/vehicles/Gen.yaml"


@pytest.mark.bad_input
def test_the_independent_record_written_in_degC_and_declared_degF_is_refused(
    tmp_path, monkeypatch, capsys
):
    """20 degC read as 20 degF is -6.7 degC: `railtherm validate` stops on the k window, naming
    the raw file, the column, the declared unit and what the numbers are in degC; the same
    file declared degC passes (no false alarm)."""
    monkeypatch.chdir(tmp_path)
    vehicle = write_generated(tmp_path, vehicle_config("degF"))
    assert main(["validate", vehicle]) == 1
    err = capsys.readouterr().err
    for fragment in ("data/gen.csv", "T_in", "declared degF", "check the unit", "20.0 degC"):
        assert fragment in err, (fragment, err)
    assert "check.heated_air_range_degC" in err
    vehicle = write_generated(tmp_path, vehicle_config("degC"))
    assert main(["validate", vehicle]) == 0, capsys.readouterr().err


def fitted(root: Path, vehicle_file: str):
    study = load_study({"vehicles": [vehicle_file]}, workdir=root)
    return run.fit_vehicle(study.vehicles["Gen"], ["order2"], workdir=root).fits["order2"]


@pytest.mark.bad_input
def test_the_independent_record_without_a_k_window_is_put_in_doubt(tmp_path):
    """Without a k window (kA fitted jointly) the degF record fits as well as the truth, with
    kA 1.8 times too large; the verdict is in doubt with the channel, its unit and the check
    of the unit. Declared degC, no unit check fires."""
    wrong = fitted(tmp_path, write_generated(tmp_path, vehicle_config("degF", False)))
    assert wrong.parameters["kA"].value == pytest.approx(1.8 * KA, rel=0.05)
    assert wrong.verdict == "assumptions in doubt"
    said = " ".join(wrong.reasons)
    for fragment in ("gen.csv", "'T_in' declared degF", "check the unit", "below 5 degC"):
        assert fragment in said, (fragment, said)
    right = fitted(tmp_path, write_generated(tmp_path, vehicle_config("degC", False)))
    assert right.parameters["kA"].value == pytest.approx(KA, rel=0.05)
    assert not [r for r in right.reasons if "check the unit" in r], right.reasons


def window(T: float, T_o: float, Q: float, n: int = 50) -> pd.DataFrame:
    return pd.DataFrame(
        {
            "time": np.arange(n) * 60.0,
            "T": np.full(n, T),
            "T_veh": np.full(n, T),
            "T_o": np.full(n, T_o),
            "Q_H": np.full(n, Q),
        }
    )


def config_data(tmp_path, **changes) -> dict:
    """The generated vehicle's validated config (``Vehicle.data``), with ``changes``."""
    write_generated(tmp_path, {**vehicle_config("degC"), **changes})
    return (
        load_study({"vehicles": ["config/vehicles/Gen.yaml"]}, workdir=tmp_path)
        .vehicles["Gen"]
        .data
    )


@pytest.mark.bad_input
def test_a_heated_cabin_colder_than_the_tunnel_is_refused_naming_both_units(tmp_path):
    """Indoor air declared degF, the tunnel degC: 20 degC reads -6.7 degC, colder than a 0 degC
    tunnel under 20 kW of heating - no k exists; the message names both groups' units."""
    data = config_data(
        tmp_path,
        channels={
            **vehicle_config("degC")["channels"],
            "indoor_air": [{"column": "T_in", "unit": "degF"}],
        },
    )
    with pytest.raises(DataError) as err:
        kvalue.for_vehicle(window(-6.7, 0.0, 20_000.0), data, "data/gen.csv (windows.kvalue)")
    text = str(err.value)
    for fragment in (
        "data/gen.csv (windows.kvalue)",
        "column 'T_in'",
        "colder than the tunnel",
        "'T_in' declared degF",
        "'T_out' declared degC",
        "check the unit",
        "read as degC give 19.9 degC",
    ):
        assert fragment in text, (fragment, text)


@pytest.mark.bad_input
def test_degF_data_declared_degC_is_refused_above_the_heated_range(tmp_path):
    """68 degF read as 68 degC: a cabin no k-value test holds; the message says the numbers
    read as degF give 20 degC."""
    with pytest.raises(DataError) as err:
        kvalue.for_vehicle(window(68.0, 5.0, 20_000.0), config_data(tmp_path), "gen (kvalue)")
    text = str(err.value)
    for fragment in ("'T_in' declared degC", "outside 5-45 degC", "read as degF give 20.0 degC"):
        assert fragment in text, (fragment, text)


def test_the_heated_range_is_a_setting(tmp_path):
    """A test that really held its cabin at 2 degC widens check.heated_air_range_degC."""
    data = config_data(tmp_path, check={"heated_air_range_degC": [0, 45]})
    k = kvalue.for_vehicle(window(2.0, -28.0, 20_000.0), data, "gen (kvalue)")
    assert k.k == pytest.approx(20_000.0 / (30.0 * AREA))


@pytest.mark.bad_input
def test_a_k_far_from_its_class_is_a_plausibility_note_naming_units(tmp_path):
    """k = 8 W/(m2 K) for a metro (Table 2: 2.4-3.1): inside the physical range, more than
    twice the class's highest: noted with the class, the factor and every channel's unit; a
    metro's own k is not noted, nor a k of an object of class other."""
    data = config_data(tmp_path)
    far = kvalue.for_vehicle(window(20.0, -15.0, 8.0 * 35.0 * AREA), data, "gen (kvalue)")
    text = " ".join(far.plausibility)
    for fragment in (
        "metro class's 2.4-3.1",
        "check.k_class_factor",
        "'T_in' declared degC",
        "'P_heat' declared W",
        "check the unit",
        "gen.csv",
    ):
        assert fragment in text, (fragment, text)
    near = kvalue.for_vehicle(window(20.0, -15.0, 2.9 * 35.0 * AREA), data, "gen (kvalue)")
    assert near.plausibility == ()
    other = {**data, "class": "other"}
    assert plausibility.k_class_reason(8.0, other, "the fit's") is None


def test_the_class_ranges_are_those_of_the_papers_table_2():
    """The class k ranges are the lowest and highest k of each class in the published Table 2
    as the project holds it (config/published/paper.yaml), not numbers of their own."""
    paper = read_yaml(REPO / "config" / "published" / "paper.yaml")
    by_class: dict[str, list[float]] = {}
    for vid, row in paper["parameters"]["rows"].items():
        by_class.setdefault(paper["classes"]["of"][vid], []).append(float(row["k"]))
    assert {c: (min(v), max(v)) for c, v in by_class.items()} == plausibility.CLASS_K_W_M2K


@pytest.mark.bad_input
def test_a_heated_record_colder_than_the_tunnel_is_a_verdict_reason(tmp_path):
    """On the identification records (no k window to refuse): heated rows with T below T_o
    on average give a reason naming the file, the columns and their units."""
    data = config_data(tmp_path)
    n = 100
    table = pd.DataFrame(
        {
            "T": np.linspace(-10.0, -5.0, n),
            "T_o": np.zeros(n),
            "Q_H": np.full(n, 5000.0),
            "Q_heater": np.full(n, 5000.0),
        }
    )
    reasons = plausibility.record_reasons({"run": table}, data)
    assert any("colder than the tunnel" in r and "declared degC" in r for r in reasons), reasons
    assert all("check the unit" in r and "gen.csv" in r for r in reasons)
    table["Q_heater"] = 0.0  # not heated: nothing to say
    assert plausibility.record_reasons({"run": table}, data) == []


def test_the_campaign_and_armadillo_records_raise_no_unit_alarm(campaign_study):
    """No false alarm: every k window of the 13-vehicle virtual campaign passes (and its k has
    no class note), every identification record raises no reason; nor Armadillo's measured
    record (class other: no class check, a hot box heated at 26-42 degC)."""
    root, _, study = campaign_study
    for vehicle in study.vehicles.values():
        datacheck.check_values(vehicle, workdir=root)  # raises on a refused k window
        tables = run.tidy_tables(vehicle, root)
        k = kvalue.for_vehicle(tables["kvalue"], vehicle.data, vehicle.id)
        assert k.plausibility == (), (vehicle.id, k.plausibility)
        records = {w["name"]: tables[w["name"]] for w in vehicle.windows["identification"]}
        assert plausibility.record_reasons(records, vehicle.data) == [], vehicle.id
    workdir = REPO / "validation"
    context = study_context(read_yaml(workdir / "config" / "config.yaml"), workdir=workdir)
    add_vehicle(context, workdir / "config" / "vehicles" / "Armadillo.yaml", workdir)
    armadillo = context.vehicles["Armadillo"]
    tables = run.tidy_tables(armadillo, workdir)
    assert plausibility.record_reasons(tables, armadillo.data) == []


def test_a_campaign_fit_and_armadillos_carry_no_unit_check(fit_files):
    """The fits' own unit checks (the fitted k against the class, the records) are empty for
    a campaign metro and for Armadillo."""
    for vehicle, model in (("Metro1", "order2"), ("Armadillo", "interior_envelope")):
        path, _ = fit_files(vehicle, model)
        fit = read_yaml(path)
        assert not [r for r in fit["reasons"] if "check the unit" in r], (vehicle, fit["reasons"])


@pytest.mark.bad_input
@settings(max_examples=60, deadline=None)
@given(
    cabin=st.floats(15.0, 35.0),
    tunnel=st.floats(-30.0, 5.0),
    power=st.floats(5_000.0, 60_000.0),
)
def test_any_comfortable_cabin_written_in_degC_and_declared_degF_is_refused(cabin, tunnel, power):
    """Whatever the test's levels (a cabin at 15-35 degC, a tunnel at -30 to 5 degC), the k
    window read in degF stops naming degF; read in degC it passes."""
    data = {
        "class": "metro",
        "raw_files": {"cwt": "gen.csv"},
        "channels": {
            "indoor_air": [{"column": "T_in", "unit": "degF"}],
            "outdoor_air": [{"column": "T_out", "unit": "degF"}],
        },
    }

    def read_as_degF(x: float) -> float:
        return (x - 32.0) * 5.0 / 9.0

    with pytest.raises(DataError, match="declared degF.*check the unit"):
        plausibility.check_k_window(
            window(read_as_degF(cabin), read_as_degF(tunnel), power), data, "gen.csv"
        )
    right = {
        **data,
        "channels": {g: [{**c, "unit": "degC"} for c in v] for g, v in data["channels"].items()},
    }
    plausibility.check_k_window(window(cabin, tunnel, power), right, "gen.csv")
