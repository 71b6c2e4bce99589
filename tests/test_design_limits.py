"""A programme a tunnel can run: the design's searches keep within the declared cabin
temperature, write what they propose as a programme file (and a set-point schedule) that
``railtherm design`` reads back to the same prediction, and keep the static k window."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
import yaml

from railtherm.errors import ConfigError
from railtherm.estimation import models
from railtherm.study import design

REPO_ROOT = Path(__file__).resolve().parents[1]
LIMITED = {
    "name": "limited",
    "step_s": 120,
    "noise_K": {"T": 0.05, "T_veh": 0.05},
    "systematic": {"T": 0.075, "T_veh": 0.1, "T_o": 0.07, "power_rel": 0.01},
    "start": "steady",
    "limits": {"max_power_W": 60000, "max_T_C": 30},
    "phases": [
        {
            "name": "steady",
            "hours": 12,
            "T_o_C": -10,
            "power_W": 20000,
            "identify": 1,
            "window": "step up",
        },
        {"name": "step up", "hours": 12, "T_o_C": -10, "power_W": 30000, "window": "step up"},
        {"name": "step down", "hours": 12, "T_o_C": -10, "power_W": 20000, "window": "step down"},
    ],
}
CLASS = ["--class", "metro", "--mass-kg", "40000", "--surface-m2", "330", "--draws", "40"]


def write(tmp_path: Path, data: dict, name: str = "programme.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def hottest_cabin(programme: design.Programme, thetas) -> float:
    """The cabin air's highest temperature over the programme, at the 97.5 % quantile over
    the parameter sets: each record simulated from the programme's start."""
    structure = models.STRUCTURES["second_order"]
    peaks = []
    for theta in thetas:
        u = design.programme_inputs(programme, structure, theta)
        x0 = design.initial_state(programme, structure, theta, u[0])
        peaks.append(
            float(np.max(models.simulate(structure, theta, u, programme.step_s, x0)[:, 0]))
        )
    return float(np.quantile(peaks, 0.975, method="inverted_cdf"))


@pytest.mark.parametrize("search", [["--length-h", "48"], ["--optimise", "--probability", "0.5"]])
def test_no_proposed_programme_heats_the_cabin_beyond_its_limit(tmp_path, capsys, search):
    """--length-h (whose best powers would heat the cabin past 30 degC) and --optimise write
    programmes whose cabin air, simulated for each of the prior's 40 draws, stays at most
    limits.max_T_C = 30 degC at the upper band (97.5 %); the printout says which limit binds."""
    from railtherm.cli import main

    given = write(tmp_path, LIMITED)
    out = tmp_path / "proposed.yaml"
    args = ["design", str(given), *CLASS, "--target", "C_veh=10%", "-d", str(REPO_ROOT)]
    assert main([*args, *search, "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    proposed = design.load_programme(out)
    prior = design.prior_for_class("metro", 40000, 330, workdir=REPO_ROOT, n=40, seed=0)
    assert hottest_cabin(proposed, prior.thetas()) <= 30.0 + 1e-6
    if search[0] == "--length-h":
        assert "limits.max_T_C binds" in printed
        assert hottest_cabin(proposed, prior.thetas()) == pytest.approx(30.0, abs=0.05)


def test_a_written_programme_reads_back_to_the_same_prediction(tmp_path, capsys):
    """--optimise --out writes the shortest programme; ``railtherm design`` of that file
    prints the same table of predicted widths; the schedule beside it holds each phase's
    set points, end to end."""
    from railtherm.cli import main

    given = write(tmp_path, {**LIMITED, "limits": {"max_power_W": 60000}})
    out = tmp_path / "shortest.yaml"
    common = [*CLASS, "--target", "C_veh=10%", "-d", str(REPO_ROOT)]
    search = ["--optimise", "--probability", "0.5", "--out", str(out)]
    assert main(["design", str(given), *common, *search]) == 0
    first = capsys.readouterr().out
    assert main(["design", str(out), *common]) == 0
    again = capsys.readouterr().out
    table = again.split("| parameter |")[1].split("\n\n")[0]
    assert table in first.split("Shortest programme of this shape")[1]
    with open(out.with_suffix(".csv"), newline="") as f:
        rows = list(csv.DictReader(f))
    proposed = design.load_programme(out)
    assert [r["phase"] for r in rows] == [ph.name for ph in proposed.phases]
    assert float(rows[-1]["end_h"]) == pytest.approx(proposed.hours, abs=1e-6)
    ends, starts = [float(r["end_h"]) for r in rows[:-1]], [float(r["start_h"]) for r in rows[1:]]
    assert ends == starts


def test_a_programme_file_reads_back_to_the_same_programme(tmp_path):
    """programme_dict and load_programme are inverse: steps, a thermostat, a compared tail,
    windows, noise, inputs' noise, limits and the k window survive the round trip."""
    data = {
        **LIMITED,
        "input_noise": {"T_o": 0.03, "power_rel": 0.002},
        "kvalue": {"hours": 4, "storage_correction": False},
        "phases": [
            {"name": "held", "hours": 10, "T_o_C": -10, "set_point_C": 20, "identify": False},
            {"name": "up", "hours": 6, "T_o_C": -10, "steps": [[0, 30000], [2.5, 35000]]},
            {"name": "down", "hours": 8, "T_o_C": -5, "power_W": 1000, "identify": 3},
        ],
    }
    given = design.load_programme(write(tmp_path, data))
    written, _ = design.write_programme(given, tmp_path / "again.yaml")
    assert design.load_programme(written) == given


def test_scaling_keeps_the_k_window_in_the_first_phase():
    """A programme scaled shorter keeps its first phase at least as long as the static k
    window (kvalue.hours): the k window needs its hours."""
    phases = (
        design.Phase("steady", 10.0, -10.0, ((0.0, 2e4),)),
        design.Phase("step", 10.0, -10.0, ((0.0, 3e4),)),
    )
    programme = design.Programme("p", phases, 60.0, {"T": 0.05}, k_window_h=6.0)
    short = design.scaled(programme, 0.3)
    assert short.phases[0].hours >= 6.0 and short.phases[1].hours == pytest.approx(3.0)


@pytest.mark.bad_input
def test_a_k_window_longer_than_the_first_phase_is_refused(tmp_path):
    with pytest.raises(ConfigError) as caught:
        design.load_programme(write(tmp_path, {**LIMITED, "kvalue": {"hours": 20}}))
    assert "'kvalue.hours'" in str(caught.value) and "20" in str(caught.value)


@pytest.mark.bad_input
def test_out_without_a_search_is_refused(tmp_path, capsys):
    from railtherm.cli import main

    given = write(tmp_path, LIMITED)
    args = ["design", str(given), *CLASS, "--out", str(tmp_path / "x.yaml"), "-d", str(REPO_ROOT)]
    assert main(args) != 0
    assert "--out" in capsys.readouterr().err
    assert not (tmp_path / "x.yaml").exists()


def test_draws_from_a_fit_spread_as_its_combined_intervals(fit_files):
    """A fit's prior carries draws of its own uncertainty: log C_veh spreads as the fit's
    combined sd of log C_veh; the kA the static test fixed is not drawn."""
    from railtherm.study.fit import read_fit

    path, _ = fit_files("Metro2", "order2")
    fit = read_fit(path)
    prior = design.prior_from_fit(fit, n=2000, seed=1)
    draws = prior.draws
    assert np.all(draws["kA"] == fit.parameters["kA"].value)
    sd = float(np.std(np.log(draws["C_veh"]), ddof=1))
    assert sd == pytest.approx(fit.parameters["C_veh"].sd_log_total, rel=0.06)
    assert design.prior_from_fit(fit).draws is None  # no draws asked, none made
