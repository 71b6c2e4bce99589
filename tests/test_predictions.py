"""The study's prediction tables: scenarios per vehicle (railtherm.study.predictions) and the
leave-one-out validation of the class reference model (railtherm.study.classvalidation)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from railtherm.estimation import models
from railtherm.study import aggregate, classvalidation, predictions
from railtherm.study.classmodel import ClassMember
from railtherm.study.fit import Fit
from railtherm.study.scenario import Controller, Initial, Scenario

MASS, SURFACE = 40_000.0, 300.0
T_O = -20.0  # degC: the scenarios' outdoor air and soak


def scenario(
    controller: Controller | None = None,
    heat_up_to_C: float | None = 15.0,
    hours: float = 12.0,
    power_W: float = 50_000.0,
):
    """A soaked vehicle at T_O heated for ``hours`` at ``power_W`` (or by
    ``controller``); the heat-up time to ``heat_up_to_C``."""
    t = np.arange(round(hours * 60) + 1) * 60.0
    return Scenario(
        name="preheat",
        file="preheat.yaml",
        description="a test pre-heating",
        source="test",
        dt_s=60.0,
        duration_s=t[-1],
        t_s=t,
        T_o=np.full(t.shape, T_O),
        heating_W=None if controller else np.full(t.shape, power_W),
        controller=controller,
        gains={},
        air_exchange_W_K=np.zeros(t.shape),
        irradiance={},
        initial=Initial("soaked"),
        heat_up_to_C=heat_up_to_C,
        cool_down_to_C=None,
    )


def second_order_fit(vehicle: str, theta: dict, identified: bool = True) -> Fit:
    """A checked second-order fit (eqs. 7-8) with small statistical intervals."""
    params = {"kA": {"value": theta["kA"], "estimated": False}}
    for p in ("C", "K_veh", "C_veh"):
        params[p] = {
            "value": theta[p],
            "estimated": True,
            "ci95": [theta[p] * 0.95, theta[p] * 1.05],
            "sd_log": 0.025,
            "identified": identified or p != "C",
        }
    return Fit.from_dict(
        {
            "vehicle": vehicle,
            "model": "order2",
            "structure": "second_order",
            "verdict": "fit acceptable",
            "parameters": params,
            "free": ["C", "K_veh", "C_veh"],
            "correlation": np.eye(3).tolist(),
        }
    )


def test_scenario_table_rows_and_markdown():
    theta = {"kA": 800.0, "C": 8e6, "K_veh": 400.0, "C_veh": 1.6e7}
    fits = {
        "A1": second_order_fit("A1", theta),
        "A2": second_order_fit("A2", theta, identified=False),
    }
    sc = scenario(Controller("pi", 15.0, 60_000.0))
    table, runs = predictions.scenario_table(fits, {"A1": "metro", "A2": "metro"}, [sc], 30, 1)
    assert list(table["vehicle"]) == ["A1", "A2"]
    a1 = table.iloc[0]
    assert a1["status"] == "simulated" and a1["heat_up_h_status"] == "ok"
    assert a1["heat_up_h_lo"] < a1["heat_up_h"] < a1["heat_up_h_hi"]
    assert a1["peak_kW"] == pytest.approx(60.0)
    assert table.iloc[1]["status"] == "not simulated: C not identified"
    assert set(runs) == {("preheat", "A1")}
    md = predictions.scenario_markdown(table, [sc], "synthetic: test", 30)
    assert "| A2 | metro | not simulated: C not identified" in md
    assert "heat-up to 15 °C (h)" in md and "cool-down" not in md


def test_an_open_band_is_written_as_beyond_the_duration():
    row = {
        "status": "simulated",
        "heat_up_h": 10.0,
        "heat_up_h_lo": 8.0,
        "heat_up_h_hi": math.inf,
        "heat_up_h_status": "ok",
    }
    assert predictions.outcome_text(row, "heat_up_h", "h", 12.0) == "10 [8, > 12]"
    row["heat_up_h_status"] = "unreachable"
    assert predictions.outcome_text(row, "heat_up_h", "h", 12.0).startswith("unreachable")


def _member(vid: str, cls: str, theta: dict, usable: bool = True) -> ClassMember:
    return ClassMember(
        vehicle=vid,
        vehicle_class=cls,
        mass_kg=MASS,
        surface_m2=SURFACE,
        k=theta["kA"] / SURFACE,
        c_veh=theta["C_veh"] / MASS,
        delta=theta["C_veh"] / theta["C"],
        kappa_veh=theta["K_veh"] / SURFACE,
        usable=usable,
        why="" if usable else "fit assumptions in doubt",
    )


def _series(theta: dict, seed: int) -> pd.DataFrame:
    """One identification window: a heating step, the fit's simulation and a 'measurement'
    with 0.05 K of noise."""
    structure = models.structure_for("second_order")
    n, dt = 600, 60.0
    u = np.column_stack([np.full(n, -10.0), np.where(np.arange(n) < 300, 30_000.0, 0.0)])
    x = models.simulate(structure, theta, u, dt, [-10.0, -10.0])
    noise = np.random.default_rng(seed).normal(0, 0.05, n)
    return pd.DataFrame(
        {
            "window": "w",
            "time": np.arange(n) * dt,
            "T": x[:, 0] + noise,
            "T_sim": x[:, 0],
            "T_veh": x[:, 1],
            "T_veh_sim": x[:, 1],
            "T_o": u[:, 0],
            "Q_H": u[:, 1],
        }
    )


def test_leave_one_out_of_identical_vehicles_predicts_each_like_its_own_fit():
    """Three vehicles with the same generalised parameters: the model built from any two
    of them is the third's own model, so its prediction equals its fit's."""
    theta = {"kA": 800.0, "C": 8e6, "K_veh": 400.0, "C_veh": 1.6e7}
    names = ["M1", "M2", "M3"]
    members = [_member(v, "metro", theta) for v in names]
    members.append(_member("M4", "metro", {**theta, "C": 1e5}, usable=False))
    fits = {v: second_order_fit(v, theta) for v in names}
    series = {v: _series(theta, i) for i, v in enumerate(names)}
    table = classvalidation.leave_one_out(members, fits, series, scenario(), 2, draws=20, seed=0)
    assert list(table.columns) == list(classvalidation.COLUMNS)
    assert sorted(table["vehicle"].unique()) == names  # M4 is not usable: never predicted
    done = table[table["status"] == "predicted"]
    assert len(done) == 3 * 4
    assert (done["n_basis"] == 2).all()
    np.testing.assert_allclose(done["rmse_ref_K"], done["rmse_fit_K"], rtol=1e-9)
    np.testing.assert_allclose(done["heat_up_ratio"].astype(float), 1.0, rtol=1e-9)
    md = classvalidation.validation_markdown(table, scenario(), "synthetic: test")
    assert "class, k from class: 3 of 3 vehicles predicted" in md


def test_leave_one_out_says_when_a_class_is_too_small():
    """Two vehicles in a class leave one to build from: below the minimum of two."""
    a = {"kA": 800.0, "C": 8e6, "K_veh": 400.0, "C_veh": 1.6e7}
    b = {"kA": 900.0, "C": 6e6, "K_veh": 500.0, "C_veh": 2.0e7}
    members = [_member("T1", "tram", a), _member("T2", "tram", b), _member("R1", "regional", a)]
    fits = {"T1": second_order_fit("T1", a), "T2": second_order_fit("T2", b)}
    series = {"T1": _series(a, 1), "T2": _series(b, 2)}
    table = classvalidation.leave_one_out(members, fits, series, scenario(), 2, draws=20, seed=0)
    by_class = table[table["basis"] == "class"]
    assert (by_class["status"].str.startswith("too few vehicles")).all()
    assert (by_class["n_basis"] == 1).all()
    pooled = table[table["basis"] == "pooled"]
    assert (pooled["status"] == "predicted").all()  # T2 or T1 plus R1: two vehicles
    md = classvalidation.validation_markdown(table, scenario(), "synthetic: test")
    assert "class, k from class: no vehicle could be predicted" in md


def test_declared_truth_reads_the_campaign_truth_of_the_listed_vehicles(tmp_path):
    path = tmp_path / "ground_truth.csv"
    pd.DataFrame(
        {
            "vehicle": ["M1", "M2"],
            "kA": [800.0, 900.0],
            "C": [8e6, 6e6],
            "K_veh": [400.0, 500.0],
            "C_veh": [1.6e7, 2.0e7],
            "mass_kg": [4e4, 4e4],
        }
    ).to_csv(path, index=False)
    truth = classvalidation.declared_truth(str(path), ["M2", "X"])
    assert truth == {"M2": {"kA": 900.0, "C": 6e6, "K_veh": 500.0, "C_veh": 2.0e7}}
    assert classvalidation.declared_truth(None, ["M2"]) == {}


def test_write_validation_writes_the_table_its_markdown_and_figure(tmp_path, monkeypatch):
    theta = {"kA": 800.0, "C": 8e6, "K_veh": 400.0, "C_veh": 1.6e7}
    names = ["M1", "M2", "M3"]
    members = [_member(v, "metro", theta) for v in names]
    fits = {v: second_order_fit(v, theta) for v in names}
    series = {v: _series(theta, i) for i, v in enumerate(names)}
    table = classvalidation.leave_one_out(members, fits, series, scenario(), 2, draws=20, seed=0)
    out = tmp_path / "out"
    out.mkdir()
    # M2 measured among synthetic vehicles: the figure's footer names it (before, a mixed
    # study's figure carried no footer at all)
    vehicles = {v: {"synthetic": v != "M2"} for v in names}
    from railtherm.report import plots

    drawn, figure = [], plots.reference_validation_figure
    monkeypatch.setattr(
        plots,
        "reference_validation_figure",
        lambda t, note: drawn.append(note) or figure(t, note=note),
    )
    classvalidation.write_validation(
        table, scenario(), vehicles, out / "v.csv", out / "v.md", str(out / "v")
    )
    written = pd.read_csv(out / "v.csv")
    assert list(written.columns) == list(classvalidation.COLUMNS)
    assert len(written) == len(table)
    md = (out / "v.md").read_text(encoding="utf-8")
    source = aggregate.data_source(vehicles)
    assert md == classvalidation.validation_markdown(table, scenario(), source)
    assert (out / "v.png").stat().st_size > 0 and (out / "v.svg").stat().st_size > 0
    assert drawn == ["synthetic data (virtual climatic wind tunnel), except measured: M2"]


def test_study_predictions_write_the_table_its_markdown_and_the_chosen_scenario_s_figure(
    tmp_path, monkeypatch
):
    """Rule simulate's work: the CSV and Markdown of every scenario and vehicle, and the
    chosen scenario's figure, which names the vehicle it could not simulate and marks none as
    in doubt (both fits acceptable)."""
    from railtherm.report import plots

    theta = {"kA": 800.0, "C": 8e6, "K_veh": 400.0, "C_veh": 1.6e7}
    fits = {
        "A1": second_order_fit("A1", theta),
        "A2": second_order_fit("A2", theta, identified=False),
    }
    vehicles = {vid: {"class": "metro", "volume_m3": 90.0, "synthetic": True} for vid in fits}
    drawn = {}
    original = plots.scenario_figure

    def spy(runs, **kwargs):
        drawn.update(runs=list(runs), **kwargs)
        return original(runs, **kwargs)

    monkeypatch.setattr(plots, "scenario_figure", spy)
    out = tmp_path
    table = predictions.write_study_predictions(
        fits,
        vehicles,
        [scenario()],
        "preheat",
        out / "s.csv",
        out / "s.md",
        str(out / "s"),
        draws=20,
        seed=1,
    )
    assert list(pd.read_csv(out / "s.csv")["vehicle"]) == ["A1", "A2"] == list(table["vehicle"])
    assert "| A2 | metro | not simulated" in (out / "s.md").read_text(encoding="utf-8")
    assert (out / "s.png").stat().st_size > 0 and (out / "s.svg").stat().st_size > 0
    assert drawn["runs"] == ["A1"] and "no band" not in drawn["title"]
    assert drawn["note"].startswith("not drawn: A2 (not simulated, see the scenario table)")
    assert drawn["threshold_C"] == 15.0
