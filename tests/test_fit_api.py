"""railtherm as a library and a one-vehicle command: `railtherm fit`, Fit, StateSpace."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from railtherm.cli import main
from railtherm.estimation import models
from railtherm.study.fit import read_fit

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def tram2(tmp_path_factory):
    """`railtherm fit config/vehicles/Tram2.yaml` in a fresh copy of the study's configs:
    the raw file is not there yet, so the virtual wind tunnel writes it first."""
    root = tmp_path_factory.mktemp("clone")
    shutil.copytree(REPO / "config", root / "config")
    assert main(["fit", "config/vehicles/Tram2.yaml", "--out", "out", "-d", str(root)]) == 0
    assert (root / "resources/campaign/Tram2").is_dir()
    return root


def test_fit_command_reproduces_the_workflow_numbers(tram2, capsys):
    """The committed identification table, written by the workflow at 6 significant digits."""
    table = pd.read_csv(REPO / "results/tables/identification.csv")
    for order in (1, 2):
        row = table[(table.vehicle == "Tram2") & (table.order == order)].iloc[0]
        fit = read_fit(tram2 / f"out/vehicles/Tram2/fit_order{order}.yaml")
        assert fit.verdict == row["verdict"]
        assert fit.R2 == pytest.approx(row["R2"], rel=1e-5)
        for name, p in fit.parameters.items():
            if p.ci95_combined is None or name not in table.columns:
                continue
            assert p.value == pytest.approx(row[name], rel=1e-5), name
            assert p.ci95_combined == pytest.approx(
                (row[f"{name}_lo"], row[f"{name}_hi"]), rel=1e-5
            )
    for name in ("clean/step_up.csv", "kvalue.yaml", "identify/order2.yaml"):
        assert (tram2 / "out/vehicles/Tram2" / name).is_file(), name


def test_statespace_is_eqs_7_8_and_simulates_like_the_fit(tram2):
    fit = read_fit(
        tram2 / "out/vehicles/Tram2/fit_order2.yaml",
        tram2 / "out/vehicles/Tram2/identify/order2_series.csv",
    )
    ss = fit.to_statespace()
    th = fit.theta
    C, K_veh, C_veh, kA = th["C"], th["K_veh"], th["C_veh"], th["kA"]
    # eq. 7: C dT/dt = -(kA + K_veh) T + K_veh T_veh + kA T_o + Q_H; eq. 8: C_veh dT_veh/dt
    np.testing.assert_allclose(
        ss.A, [[-(kA + K_veh) / C, K_veh / C], [K_veh / C_veh, -K_veh / C_veh]], rtol=1e-12
    )
    np.testing.assert_allclose(ss.B, [[kA / C, 1 / C], [0.0, 0.0]], rtol=1e-12)
    assert ss.states == ("T", "T_veh") and ss.inputs == ("T_o", "Q_H")
    assert ss.C.shape == (2, 2) and not ss.D.any()
    # the simulator reproduces the fit's own simulated series of the first window
    series = fit.series[fit.series["window"] == fit.series["window"].iloc[0]]
    dt = float(np.median(np.diff(series["time"])))
    first = series.iloc[0]
    # the series holds the inputs as the fit held them over each step (eq. 15)
    sim = fit.simulate(series[["T_o", "Q_H"]], dt, x0=[first["T_sim"], first["T_veh_sim"]])
    np.testing.assert_allclose(sim["T"], series["T_sim"], atol=1e-6)
    Ad, Bd = ss.discretize(dt)
    assert np.allclose(Ad, models.discretize_zoh(ss.A, ss.B, dt)[0])


def test_unknown_model_and_missing_vehicle_are_one_line_errors(tram2, capsys):
    assert main(["fit", "config/vehicles/Tram9.yaml", "-d", str(tram2)]) == 1
    assert "Tram9.yaml" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["fit", "config/vehicles/Tram2.yaml", "--model", "order3"])
