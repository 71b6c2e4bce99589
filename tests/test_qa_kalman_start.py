"""A Kalman fit whose output-error start is stiff beyond what the filter's discretised noise
can hold (a surface sensor that follows the air, so K_veh runs to its upper bound and C_veh
to its lower one): refused naming the vehicle file, model.estimator and the fix, where it
raised ValueError("the likelihood cannot be evaluated at the output-error optimum")."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest
import yaml

from railtherm.cli import main

REPO = Path(__file__).resolve().parents[1]
ARMADILLO = REPO / "data" / "armadillo" / "armadillo_data_H2.csv"


@pytest.mark.bad_input
def test_a_kalman_fit_that_cannot_start_names_the_file_the_key_and_the_fix(tmp_path, capsys):
    data = pd.read_csv(ARMADILLO)
    data["T_surf"] = data["T_int"].rolling(4, min_periods=1).mean()  # follows the air
    data.to_csv(tmp_path / "box.csv", index=False)
    vehicle = {
        "id": "Box",
        "class": "other",
        "mass_kg": 20000,
        "surface_m2": 162,
        "raw_files": {"h2": "box.csv"},
        "format": {"power_timing": "instant", "time": {"column": "Time", "format": "seconds"}},
        "channels": {
            "indoor_air": [{"column": "T_int"}],
            "surface": [{"column": "T_surf"}],
            "outdoor_air": [{"column": "T_ext"}],
            "heater_power": [{"column": "P_hea", "unit": "W"}],
        },
        "windows": {"identification": [{"name": "h2", "start": 0, "end": 415800}]},
        "model": {"orders": [2], "mode": "joint", "x0": "estimated", "estimator": ["kalman"]},
    }
    path = tmp_path / "Box.yaml"
    path.write_text(yaml.safe_dump(vehicle, sort_keys=False))
    assert main(["fit", str(path), "--out", str(tmp_path / "results")]) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err
    for fragment in (
        "Box.yaml: key 'model.estimator' = 'kalman'",
        "cannot be evaluated at the output-error optimum",
        "fastest time constant",
        "against the 1800 s step",
        "K_veh, C_veh at a bound",
        "fit order2 by output error only (model.estimator: output_error)",
        "model.bounds",
    ):
        assert fragment in err, (fragment, err)
    assert not (tmp_path / "results" / "vehicles" / "Box" / "fit_order2_kalman.yaml").exists()
