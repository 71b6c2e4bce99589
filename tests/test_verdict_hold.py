"""A first-order hold on an input resampled from a finer logger step that switches within the
steps (a heater's on/off) is flagged, and the verdict names the fix; a smooth input, or the
zero-order hold, is not flagged."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from railtherm.config import load_vehicle
from railtherm.data import ingest
from railtherm.study import identify, quality, run

START = pd.Timestamp("2026-01-05T00:00:00")
LOGGER_S = 60.0
STEP_S = 1800.0
HOURS = 36
KA, C = 500.0, 2.0e7  # W/K, J/K: eq. 9's first-order model, tau about 11 h


def record(switching: bool, seed: int = 3) -> pd.DataFrame:
    """A 1-min logger record of eq. 9 (exact zero-order hold per minute): the heater either
    switches on/off each minute as a thermostat asks (20 kW or nothing, set point 15 then
    20 degC) or follows a smooth ramp of the same mean."""
    rng = np.random.default_rng(seed)
    n = int(HOURS * 3600 / LOGGER_S) + 1
    a = np.exp(-KA / C * LOGGER_S)
    T_o = -5.0 + 0.5 * np.sin(np.arange(n) * 2 * np.pi / (n / 3))
    T = np.empty(n)
    Q = np.empty(n)
    x = 15.0
    for i in range(n):
        T[i] = x
        if switching:
            target = 15.0 if i < n // 3 else 20.0
            Q[i] = 20_000.0 if x < target else 0.0
        else:
            Q[i] = 10_000.0 + 6_000.0 * np.sin(i * 2 * np.pi / n)
        x = a * x + (1.0 - a) * (T_o[i] + Q[i] / KA)
    stamps = START + pd.to_timedelta(np.arange(n) * LOGGER_S, unit="s")
    return pd.DataFrame(
        {
            "timestamp": stamps.strftime("%Y-%m-%dT%H:%M:%S"),
            "indoor": np.round(T + rng.normal(0.0, 0.02, n), 4),
            "tunnel": np.round(T_o + rng.normal(0.0, 0.02, n), 4),
            "heater": np.round(Q / 1000.0, 5),
        }
    )


def vehicle_file(directory: Path, hold: str) -> Path:
    end = (START + pd.Timedelta(hours=HOURS)).strftime("%Y-%m-%dT%H:%M:%S")
    data = {
        "id": "Box",
        "class": "other",
        "description": "A heated box whose heater switches (tests/test_verdict_hold.py).",
        "synthetic": True,
        "raw_files": {"run": "run.csv"},
        "format": {
            "separator": ",",
            "power_timing": "instant",
            "time": {"column": "timestamp", "format": "iso"},
        },
        "channels": {
            "indoor_air": [{"column": "indoor"}],
            "outdoor_air": [{"column": "tunnel"}],
            "heater_power": [{"column": "heater", "unit": "kW"}],
        },
        "instruments": {"temperature_u_K": 0.1, "power_u_rel": 0.003},
        "cleaning": {"step_s": STEP_S},
        "windows": {
            "identification": [
                {"name": "all", "file": "run", "start": START.isoformat(), "end": end}
            ]
        },
        "model": {"orders": [1], "mode": "joint", "input_hold": hold},
    }
    path = directory / f"box_{hold}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def fit(tmp_path: Path, switching: bool, hold: str) -> tuple[dict, dict]:
    record(switching).to_csv(tmp_path / "run.csv", index=False)
    vehicle = load_vehicle(vehicle_file(tmp_path, hold), workdir=tmp_path)
    tables = run.tidy_tables(vehicle, workdir=tmp_path)
    windows = {"all": tables["all"]}
    estimate, series = identify.identify(windows, vehicle.data, None, 1, None)
    return estimate, quality.check(estimate, series, vehicle.data.get("check"))


def codes(estimate: dict) -> set[str]:
    return {f["code"] for f in estimate.content["fit"]["flags"]}


def test_first_order_hold_on_a_switching_heater_resampled_is_flagged_with_the_fix(tmp_path):
    estimate, checked = fit(tmp_path, switching=True, hold="first_order")
    assert "first_order_hold_on_switching_input" in codes(estimate)
    assert checked.verdict == "assumptions in doubt"
    reason = next(r for r in checked.reasons if "first_order" in r)
    assert "Q_H" in reason and "cleaning.step_s 1800" in reason
    assert "model.input_hold: zero_order" in reason  # the fix is named


def test_zero_order_hold_on_the_same_record_is_not_flagged(tmp_path):
    estimate, _ = fit(tmp_path, switching=True, hold="zero_order")
    assert "first_order_hold_on_switching_input" not in codes(estimate)


def test_first_order_hold_on_a_smooth_input_resampled_is_not_flagged(tmp_path):
    estimate, _ = fit(tmp_path, switching=False, hold="first_order")
    assert "first_order_hold_on_switching_input" not in codes(estimate)


def test_the_hold_error_column_measures_the_ramps_miss(tmp_path):
    """The cleaning's Q_H_hold_error: on a switching heater of the order of its jumps, on a
    smooth one a small fraction of its level; absent under the zero-order hold and at the
    logger's own step (nothing is resampled)."""
    record(True).to_csv(tmp_path / "run.csv", index=False)
    column = f"Q_H{ingest.HOLD_ERROR_SUFFIX}"
    switching = run.tidy_tables(
        load_vehicle(vehicle_file(tmp_path, "first_order"), workdir=tmp_path), workdir=tmp_path
    )["all"]
    assert switching[column].iloc[:-1].mean() > 0.2 * switching["Q_H"].abs().mean()
    assert switching[column].iloc[-1] == 0.0  # no step follows the last row
    zoh = run.tidy_tables(
        load_vehicle(vehicle_file(tmp_path, "zero_order"), workdir=tmp_path), workdir=tmp_path
    )["all"]
    assert column not in zoh.columns
    record(False).to_csv(tmp_path / "run.csv", index=False)
    smooth = run.tidy_tables(
        load_vehicle(vehicle_file(tmp_path, "first_order"), workdir=tmp_path), workdir=tmp_path
    )["all"]
    assert smooth[column].max() < 0.01 * smooth["Q_H"].mean()
    assert pytest.approx(smooth["Q_H"].mean(), rel=0.05) == 10_000.0
