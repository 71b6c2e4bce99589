"""The SINDy cross-check (issue 7): exact recovery on noise-free data, the verdicts, the
virtual campaign's acceptance, and that switching it off keeps pysindy out."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from railtherm.data import ingest
from railtherm.estimation import models
from railtherm.records import FitRecord
from railtherm.study import sindy

TRAM2 = {"kA": 979.2, "C": 1.8e7, "K_veh": 974.0, "C_veh": 1.0e7}


def experiment(A, B, step_s=60.0, hours=60.0, seed=1, noise_K=0.0) -> pd.DataFrame:
    """A tidy table of a CWT-like experiment, simulated exactly at the logger step."""
    rng = np.random.default_rng(seed)
    n = int(hours * 3600 / step_s)
    t = np.arange(n) * step_s
    # steps every 4 h (T_o) and 2 h (Q_H), on logger instants: exactly zero-order held
    hold_o, hold_q = int(4 * 3600 / step_s), int(2 * 3600 / step_s)
    T_o = np.repeat(rng.choice([-10.0, 0.0, 10.0], size=n // hold_o + 1), hold_o)[:n]
    Q_H = np.repeat(rng.uniform(0, 20_000, size=n // hold_q + 1), hold_q)[:n]
    Ad, Bd = models.discretize_zoh(A, B, step_s)
    x = np.zeros((n, 2))
    x[0] = [15.0, 10.0]
    u = np.column_stack([T_o, Q_H])
    for k in range(n - 1):
        x[k + 1] = Ad @ x[k] + Bd @ u[k]
    x += rng.normal(0, noise_K, size=x.shape) if noise_K else 0.0
    return pd.DataFrame({"time": t, "T": x[:, 0], "T_veh": x[:, 1], "T_o": T_o, "Q_H": Q_H})


def body_to_outdoor(K_o: float, p=TRAM2):
    A, B = models.second_order(**p)
    A, B = A.copy(), B.copy()
    A[1, 1] -= K_o / p["C_veh"]
    B[1, 0] = K_o / p["C_veh"]
    return A, B


FAST = sindy.Settings(n_bootstrap=50)


def test_noise_free_data_give_the_exact_support_and_coefficients_within_2_percent():
    A, B = models.second_order(**TRAM2)
    truth = sindy.grey_box_coefficients(**TRAM2)
    result = sindy.cross_check([experiment(A, B)], FAST, truth)
    assert result.verdict == sindy.CONFIRMED, result.reasons
    np.testing.assert_array_equal(result.support(), sindy.STRUCTURE)
    np.testing.assert_allclose(
        result.coefficients[sindy.STRUCTURE], truth[sindy.STRUCTURE], rtol=0.02
    )


def test_a_body_to_outdoor_path_contradicts_the_structure_and_is_named():
    K_o = 300.0
    A, B = body_to_outdoor(K_o)
    result = sindy.cross_check([experiment(A, B)], FAST)
    assert result.verdict == sindy.CONTRADICTED
    assert len(result.reasons) == 1 and "dT_veh/dt needs a T_o term" in result.reasons[0]
    expected = np.vstack([np.c_[A * 3600, B[:, :1] * 3600, B[:, 1:] * 3600 * 1000]])
    support = expected != 0
    np.testing.assert_array_equal(result.support(), support)
    np.testing.assert_allclose(result.coefficients[support], expected[support], rtol=0.02)


def test_several_windows_are_fitted_together():
    A, B = models.second_order(**TRAM2)
    windows = [experiment(A, B, hours=30, seed=s) for s in (2, 3)]
    result = sindy.cross_check(windows, FAST)
    assert result.verdict == sindy.CONFIRMED
    assert result.n_samples == sum(len(w) - 2 for w in windows)


def test_gaps_are_left_out_not_differenced_across():
    A, B = models.second_order(**TRAM2)
    w = experiment(A, B)
    w.loc[500:505, "T"] = np.nan
    result = sindy.cross_check([w], FAST)
    assert result.verdict == sindy.CONFIRMED
    assert result.n_samples == len(w) - 2 - 8  # 6 missing rows and their two neighbours


def test_a_fast_mode_below_the_sample_step_is_too_poor_to_judge():
    fast = dict(TRAM2, K_veh=2.0e5)  # air and body equalise in about a minute
    A, B = models.second_order(**fast)
    result = sindy.cross_check([experiment(A, B, step_s=600.0, seed=4, noise_K=0.05)], FAST)
    assert result.verdict == sindy.TOO_POOR
    assert result.reasons


def test_measurement_noise_at_the_campaign_level_keeps_the_verdicts():
    A, B = models.second_order(**TRAM2)
    ok = sindy.cross_check([experiment(A, B, noise_K=0.05, seed=5)], FAST)
    assert ok.verdict == sindy.CONFIRMED, ok.reasons
    A, B = body_to_outdoor(300.0)
    bad = sindy.cross_check([experiment(A, B, noise_K=0.05, seed=5)], FAST)
    assert bad.verdict == sindy.CONTRADICTED and "T_o term" in " ".join(bad.reasons)


def test_grey_box_bounds_from_a_fit_contain_its_coefficients():
    """Interval arithmetic over the parameters' intervals; an entry written without its
    identification is judged by its interval, so an unbounded C_veh implies no coefficient."""
    content = {
        "parameters": {
            "kA": {"value": 979.2},
            "C": {"value": 1.8e7, "ci95": [1.5e7, 2.2e7]},
            "K_veh": {"value": 974.0, "ci95": [800.0, 1200.0]},
            "C_veh": {"value": 1.0e7, "ci95": [0.5e7, 2.0e7]},
        }
    }
    xi, lo, hi = sindy.grey_box_from_fit(FitRecord.from_dict(content))
    assert np.all(lo <= xi) and np.all(xi <= hi)
    assert lo[0, 3] == pytest.approx(1000 / 2.2e7 * 3600)  # 1/C at the largest C
    assert lo[1, 0] == pytest.approx(800.0 / 2.0e7 * 3600)  # K_veh/C_veh at its smallest
    content["parameters"]["C_veh"]["ci95"] = [0.0, float("inf")]
    xi, lo, hi = sindy.grey_box_from_fit(FitRecord.from_dict(content))
    assert np.isnan(xi[1, 0]) and lo[1, 0] == -np.inf and hi[1, 0] == np.inf


def test_the_yaml_says_which_terms_were_kept_and_why():
    A, B = body_to_outdoor(300.0)
    vehicle = {"id": "X", "synthetic": True}
    fit = FitRecord.from_dict({"parameters": {p: {"value": v} for p, v in TRAM2.items()}})
    data = sindy.for_vehicle(vehicle, [experiment(A, B)], fit, FAST)
    assert data["verdict"] == sindy.CONTRADICTED and data["synthetic"] is True
    kept = {(t["equation"], t["term"]) for t in data["terms"] if t["kept"]}
    assert ("dT_veh/dt", "T_o") in kept and ("dT_veh/dt", "Q_H") not in kept
    t_o = next(t for t in data["terms"] if (t["equation"], t["term"]) == ("dT_veh/dt", "T_o"))
    assert not t_o["in_structure"] and t_o["significant"] and t_o["grey_box"] == 0.0
    table = sindy.summary_table({"X": data}, "synthetic")
    assert table.loc[0, "extra_terms"] == "dT_veh/dt T_o"
    assert "structure contradicted" in sindy.summary_markdown(table, "synthetic")


def test_campaign_vehicles_get_the_verdicts_their_declared_deviations_call_for(campaign_study):
    """Deviation-free vehicles confirmed; the body-to-outdoor vehicle contradicted, naming the
    T_o term in dT_veh/dt; nothing judged on data too poor to say."""
    root, campaign, study = campaign_study
    verdicts = {}
    for vid, vehicle in study.vehicles.items():
        windows = []
        for w in vehicle.data["windows"]["identification"]:
            key, _, _ = ingest.window_spec(vehicle.data, w["name"])
            windows.append(
                ingest.clean_window(root / vehicle.raw_files[key], vehicle.data, w["name"])
            )
        result = sindy.cross_check(windows, FAST)
        verdicts[vid] = result
    deviations = {
        vid: [d["type"] for d in spec.get("deviations", [])]
        for vid, spec in campaign["vehicles"].items()
    }
    for vid, result in verdicts.items():
        if not deviations[vid]:
            assert result.verdict == sindy.CONFIRMED, (vid, result.reasons)
        if "body_to_outdoor" in deviations[vid]:
            assert result.verdict == sindy.CONTRADICTED, (vid, result.reasons)
            assert any("dT_veh/dt needs a T_o term" in r for r in result.reasons)
        if result.verdict == sindy.TOO_POOR:
            assert result.reasons  # says why, judges nothing
        if any("complex pair" in r for r in result.reasons):  # Metro3: no time constant
            assert np.isnan(result.tau_fast_h), (vid, result.tau_fast_h)
    assert any("body_to_outdoor" in d for d in deviations.values())
    assert any("complex pair" in r for res in verdicts.values() for r in res.reasons)


def test_without_the_stage_pysindy_is_never_imported():
    code = (
        "import sys, railtherm, railtherm.cli, railtherm.config, railtherm.data.ingest, "
        "railtherm.estimation.kvalue, railtherm.study.identify, railtherm.estimation.pem, "
        "railtherm.study.aggregate, "
        "railtherm.report.plots, railtherm.report.audit, railtherm.synth; "
        "print('pysindy' in sys.modules)"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == "False"


def test_no_coefficient_is_implied_from_a_parameter_the_data_do_not_determine():
    """K_veh at its upper bound: K_veh/C and K_veh/C_veh are not implied (NaN, unbounded), and
    kA/C, 1/C still are."""
    fit = FitRecord.from_dict(
        {
            "parameters": {
                "kA": {"value": 900.0, "estimated": False},
                "C": {"value": 1e7, "ci95": [0.9e7, 1.1e7], "identified": True},
                "K_veh": {"value": 1e7, "ci95": [0.0, float("inf")], "identified": False},
                "C_veh": {"value": 2e7, "ci95": [1.8e7, 2.2e7], "identified": True},
            }
        }
    )
    xi, lo, hi = sindy.grey_box_from_fit(fit)
    assert np.isnan(xi[0, 1]) and np.isnan(xi[1, 0])  # dT/dt: T_veh, dT_veh/dt: T
    assert lo[1, 0] == -np.inf and hi[1, 0] == np.inf
    assert np.isfinite(xi[0, 2]) and np.isfinite(xi[0, 3])  # kA/C and 1/C


def test_an_oscillating_state_matrix_is_named_a_complex_pair():
    """Metro3's unthresholded state matrix (as sindy.csv rounds it) has a complex pair of
    eigenvalues, -0.214 ± 0.0666i 1/h: the reason printed "eigenvalues -0.214, -0.214" (two
    equal real modes) and the yaml a fast time constant of 4.67 h from the real part (none
    now: the campaign test)."""
    A = np.array([[0.819, -0.975], [1.099, -1.247]])
    xi = np.hstack([A, np.zeros((2, 2))])
    ones = np.ones((2, 4))
    (reason, *_) = sindy._physical(xi, ones, ones)
    assert reason.endswith("(eigenvalues a complex pair -0.214 ± 0.0666i 1/h)"), reason
    real = np.array([[-1.0, 0.5], [0.2, -0.3]])
    assert sindy._eigenvalues_text(np.linalg.eigvals(real)) == "-1.12, -0.178"
