"""The calibration benchmark's own generator (benchmarks/calibration.py): its files are what
the study reads, its physics is eqs. 7-8, and the library recovers its truth."""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from railtherm.config import load_vehicle
from railtherm.estimation import kvalue
from railtherm.study import identify, run

BENCHMARK = Path(__file__).resolve().parents[1] / "benchmarks" / "calibration.py"


@pytest.fixture(scope="module")
def cb():
    spec = importlib.util.spec_from_file_location("calibration_benchmark", BENCHMARK)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    yield module
    del sys.modules[spec.name]


@pytest.fixture(scope="module")
def ideal(cb, tmp_path_factory):
    """A vehicle without offsets, meter error or body lag: the static k test's assumptions
    hold up to the sensors' white noise."""
    generator = cb.Generator(offsets=False, meter_error=False, steady_start=True)
    truth, errors, csv = cb.write_vehicle(7, 1, tmp_path_factory.mktemp("ideal"), generator)
    return truth, errors, csv


def test_does_not_use_the_campaign_generator():
    text = BENCHMARK.read_text(encoding="utf-8")
    assert "synth" not in text.replace("synthetic", "")


def test_same_seed_same_vehicle_other_index_other_vehicle(cb, tmp_path):
    a = cb.draw_truth(cb.vehicle_rng(3, 0), 0, cb.Generator())
    b = cb.draw_truth(cb.vehicle_rng(3, 0), 0, cb.Generator())
    c = cb.draw_truth(cb.vehicle_rng(3, 1), 1, cb.Generator())
    assert a == b
    assert a.C != c.C
    for name, (lo, hi) in cb.RANGES.items():
        assert lo <= getattr(a, name) <= hi


def test_simulation_follows_eqs_7_8(cb):
    """The stored states obey the ZOH recursion of eqs. 7-8 with the logged power, and the
    thermostat holds T at its set point over the k window while the body lags as drawn."""
    truth = cb.draw_truth(cb.vehicle_rng(11, 0), 0, cb.Generator())
    states, truth = cb.simulate(truth, cb.vehicle_rng(11, 100))
    A, B = cb.state_space(truth)
    # step response: with T_o near constant, a 60 s step of the exact ZOH model
    Ad, Bd = cb.zoh(A, B, cb.STEP_S)
    X = states[["T", "T_veh"]].to_numpy()
    u = np.column_stack([states["T_o"], states["Q_H"]])
    predicted = X[:-1] @ Ad.T + u[:-1] @ Bd.T
    assert np.max(np.abs(predicted - X[1:])) < 0.01  # T_o moves by millikelvin within a minute
    k0 = int((cb.HEATING_H - cb.KWINDOW_H) * 3600 / cb.STEP_S)
    k1 = int(cb.HEATING_H * 3600 / cb.STEP_S)
    assert np.allclose(states["T"].iloc[k0:k1], truth.T_set, atol=0.01)
    assert truth.lag == pytest.approx(truth.lag_drawn, rel=1e-3) or truth.lag < truth.lag_drawn
    assert 0.0 < truth.lag <= 0.4


@pytest.mark.parametrize("setting", ["output_error/static/with", "output_error/joint/without"])
def test_yaml_validates_and_raw_file_is_read(cb, ideal, setting):
    truth, _, csv = ideal
    path = cb.write_yaml_file(truth, csv, setting, "measured")
    vehicle = load_vehicle(path, workdir=path.parent)
    assert vehicle.data["model"]["mode"] == setting.split("/")[1]
    tables = run.tidy_tables(vehicle, workdir=path.parent)
    assert set(tables) == {"kvalue", "step_up", "step_down"}
    measured = tables["step_up"]["T_veh"].notna().any()  # NaN without surface sensors
    assert measured == setting.endswith("/with")
    assert len(tables["step_up"]) == pytest.approx(cb.STEP_H * 60, abs=2)


def test_static_k_and_second_order_fit_recover_the_truth(cb, ideal):
    truth, _, csv = ideal
    path = cb.write_yaml_file(truth, csv, "output_error/static/with", "measured")
    vehicle = load_vehicle(path, workdir=path.parent)
    tables = run.tidy_tables(vehicle, workdir=path.parent)
    k = kvalue.for_vehicle(tables["kvalue"], vehicle.data, source=vehicle.id).to_dict()
    assert k["usable"]
    assert k["k"] == pytest.approx(truth.k, rel=0.01)
    windows = {w["name"]: tables[w["name"]] for w in vehicle.windows["identification"]}
    estimate, _ = identify.identify(windows, vehicle.data, k, "order2")
    for p in ("C", "K_veh", "C_veh"):
        value = estimate.content["fit"]["parameters"][p]["value"]
        assert value == pytest.approx(getattr(truth, p), rel=0.05), p


def test_summary_counts_and_z(cb):
    df = pd.DataFrame(
        {
            "setting": ["s"] * 4,
            "parameter": ["C"] * 4,
            "covered": [True, True, False, True],
            "identified": [True, True, True, False],
            "z": [1.0, -1.0, 3.0, math.nan],
        }
    )
    row = cb.summary(df).iloc[0]
    assert row["n"] == 4 and row["coverage"] == 0.75 and row["not_identified"] == 1
    assert row["mean_z"] == pytest.approx(1.0)
    assert row["rms_z"] == pytest.approx(math.sqrt(11 / 3))
    lo, hi = cb.wilson(3, 4)
    assert lo < 0.75 < hi
