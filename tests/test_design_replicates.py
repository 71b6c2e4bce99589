"""railtherm design --replicates: virtual tunnel runs of a planned programme, every declared
error drawn anew and each record fitted as the study's two-stage fit, against the
prediction."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml

from railtherm.estimation import models
from railtherm.study import design, replicates

REPO_ROOT = Path(__file__).resolve().parents[1]
SIMPLE = {
    "name": "simple",
    "step_s": 120,
    "noise_K": {"T": 0.05, "T_veh": 0.05},
    "systematic": {"T": 0.05, "T_veh": 0.05, "T_o": 0.05, "power_rel": 0.005},
    "input_noise": {"T_o": 0.03, "power_rel": 0.002},
    "start": "steady",
    "limits": {"max_power_W": 40000},
    "phases": [
        {"name": "steady", "hours": 12, "T_o_C": -10, "power_W": 20000, "identify": False},
        {"name": "step up", "hours": 18, "T_o_C": -10, "power_W": 30000, "window": "up"},
        {"name": "step down", "hours": 18, "T_o_C": -10, "power_W": 20000, "window": "down"},
    ],
}
THETA = {"kA": 700.0, "C": 8.0e6, "K_veh": 900.0, "C_veh": 1.5e7}


def test_virtual_runs_spread_as_predicted(tmp_path):
    """40 runs of a steady-start programme with noise, offsets, a meter scale and noisy
    inputs, each kA from the storage-corrected balance solved with the fit: the spread of
    log theta is the prediction's (0.7-1.35) and no estimate is biased by more than a third
    of its spread."""
    path = tmp_path / "simple.yaml"
    path.write_text(yaml.safe_dump(SIMPLE, sort_keys=False))
    programme = design.load_programme(path)
    structure = models.STRUCTURES["second_order"]
    predicted = design.predict(structure, THETA, programme)
    runs = replicates.run(structure, THETA, programme, predicted.sd_log, 40, seed=5)
    assert runs.n == 40 and runs.failed == 0
    for p in ("C", "K_veh", "C_veh"):
        assert 0.7 < runs.ratio(p) < 1.35, (p, runs.ratio(p))
        assert abs(runs.bias[p]) < runs.realised[p] / 3, p


def test_runs_that_differ_from_the_prediction_are_flagged():
    runs = replicates.Replicates(
        30, {"C": 0.01, "C_veh": 0.02}, {"C": 0.011, "C_veh": 0.03}, {"C": 0.0, "C_veh": 0.0}
    )
    text = replicates.markdown(runs)
    assert "| C | 1.98 % | 2.18 % | 1.10 |" in text
    assert "differ by more than 25 % for C_veh:" in text and "for C," not in text


def test_the_command_runs_the_programme_virtually(tmp_path, capsys):
    from railtherm.cli import main

    path = tmp_path / "simple.yaml"
    path.write_text(yaml.safe_dump(SIMPLE, sort_keys=False))
    args = ["design", str(path), "--class", "metro", "--mass-kg", "40000", "--surface-m2", "330"]
    args += ["--draws", "10", "-d", str(REPO_ROOT)]
    assert main([*args, "--replicates", "8"]) == 0
    out = capsys.readouterr().out
    assert "Virtual tunnel runs: 8 runs of the programme" in out
    assert "| C_veh |" in out.split("Virtual tunnel runs")[1]


@pytest.mark.bad_input
def test_one_replicate_is_refused(tmp_path, capsys):
    from railtherm.cli import main

    path = tmp_path / "simple.yaml"
    path.write_text(yaml.safe_dump(SIMPLE, sort_keys=False))
    args = ["design", str(path), "--class", "metro", "--mass-kg", "4e4", "--surface-m2", "330"]
    assert main([*args, "--replicates", "1", "-d", str(REPO_ROOT)]) != 0
    assert "--replicates" in capsys.readouterr().err


def test_the_replicates_table_prints_a_bias_a_positive_parameter_can_have_and_no_nan():
    """A mean log ratio of -6.9 (estimates at a thousandth of the truth) reads as the
    geometric mean's change, -99.9 %, not -690 %; with no run fitted, no realised spread and
    no comparison (before: "nan" and "+nan %", then "differ by more than 25 %")."""
    from railtherm.study.replicates import Replicates, markdown

    runs = Replicates(8, {"C_veh": 0.08}, {"C_veh": 1e-9}, {"C_veh": -6.9})
    assert "| C_veh | 17 % | 1.96e-07 % | 0.00 | -99.9 % |" in markdown(runs)
    none = markdown(Replicates(0, {"C": 0.01}, {"C": math.nan}, {"C": math.nan}, failed=8))
    assert "nan" not in none and "0 runs fitted: no realised spread" in none
    assert "differ by more than" not in none
