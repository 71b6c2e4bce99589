"""A k window that fails the standardized steady-state test (eq. 10) - here one shorter than
kvalue.min_duration_h - is reported before any fit by `railtherm validate`, and says why
wherever its verdict is printed: `railtherm fit` and the rule kvalue's log."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from railtherm.cli import main

HOURS = 30.0


def steady_record(path: Path) -> None:
    """An own record (not the synthesizer's): 30 h at 60 s, a steady state for the first
    12 h (T 20 degC, T_o -10 degC, 1 kW per 33.3 W/K), then a heating step."""
    t = np.arange(0.0, HOURS * 3600.0 + 1.0, 60.0)
    step = t >= 12 * 3600.0
    T = np.where(step, 20.0 + 5.0 * (1.0 - np.exp(-(t - 12 * 3600.0) / 20000.0)), 20.0)
    pd.DataFrame(
        {
            "t": t,
            "T_int": T,
            "T_ext": np.full(t.size, -10.0),
            "P_hea": np.where(step, 1166.7, 1000.0),
        }
    ).to_csv(path, index=False)


def vehicle(folder: Path, k_window_h: float, **kvalue) -> Path:
    steady_record(folder / "run.csv")
    data = {
        "id": "Box",
        "class": "tram",
        "mass_kg": 30000,
        "surface_m2": 20.0,
        "raw_files": {"run": "run.csv"},
        "format": {"time": {"column": "t", "format": "seconds"}},
        "channels": {
            "indoor_air": [{"column": "T_int"}],
            "outdoor_air": [{"column": "T_ext"}],
            "heater_power": [{"column": "P_hea", "unit": "W"}],
        },
        "windows": {
            "kvalue": {"start": 3600, "end": 3600 + k_window_h * 3600},
            "identification": [{"name": "all", "start": 0, "end": HOURS * 3600}],
        },
        "model": {"orders": [1]},
        **({"kvalue": kvalue} if kvalue else {}),
    }
    path = folder / "Box.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


@pytest.mark.bad_input
def test_validate_reports_a_k_window_shorter_than_the_minimum(tmp_path, capsys):
    """The window is read and tested as the rule kvalue will: validate passes the file (the
    fit can run: kA is then estimated jointly) but warns with the numbers and the keys."""
    path = vehicle(tmp_path, 5.0)
    assert main(["validate", str(path), "-d", str(tmp_path)]) == 0
    err = capsys.readouterr().err
    assert "warning:" in err and "Box.yaml" in err and "windows.kvalue" in err
    assert "the window lasts 5.00 h (minimum 6 h)" in err
    assert "kvalue.min_duration_h" in err and "estimate kA jointly" in err


def test_a_lower_minimum_or_a_longer_window_passes_without_warning(tmp_path, capsys):
    for path in (vehicle(tmp_path, 5.0, min_duration_h=5), vehicle(tmp_path, 6.5)):
        assert main(["validate", str(path), "-d", str(tmp_path)]) == 0
        assert "windows.kvalue" not in capsys.readouterr().err


def test_a_forced_window_is_reported_as_used_anyway(tmp_path, capsys):
    path = vehicle(tmp_path, 5.0, force=True)
    assert main(["validate", str(path), "-d", str(tmp_path)]) == 0
    assert "the fit uses it anyway (kvalue.force), flagged" in capsys.readouterr().err


def test_fit_prints_why_a_forced_window_is_not_steady(tmp_path, capsys):
    path = vehicle(tmp_path, 5.0, force=True)
    assert main(["fit", str(path), "--model", "order1", "-d", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "not steady, forced" in out
    assert "  - the window lasts 5.00 h (minimum 6 h)" in out
