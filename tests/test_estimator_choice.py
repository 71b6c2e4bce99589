"""model.estimator: output_error (the paper's K = 0) and kalman (eq. 16 with K from a Kalman
filter) side by side for one vehicle, each fit its own output and every table naming its
estimator; every fit is judged by one policy (the simulation's R^2 and RMSE, the whiteness of
its residuals or one-step innovations, flags, plausibility), and only acceptable, converged
fits are candidates for model selection."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from railtherm.config import load_vehicle
from railtherm.errors import ConfigError
from railtherm.records import EstimateRecord, FitRecord
from railtherm.report import tableformat
from railtherm.study import aggregate, fitsettings, quality
from railtherm.study.run import fit_vehicle

REPO = Path(__file__).resolve().parents[1]
ARMADILLO = REPO / "validation" / "config" / "vehicles" / "Armadillo.yaml"


def armadillo_vehicle_file(tmp_path: Path, **model) -> Path:
    data = yaml.safe_load(ARMADILLO.read_text(encoding="utf-8"))
    data["model"] |= model
    data["raw_files"] = {"h2": str(REPO / "data" / "armadillo" / "armadillo_data_H2.csv")}
    path = tmp_path / "Armadillo.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def test_model_keys_name_each_estimator_once():
    data = {"model": {"orders": [1, 2], "structures": ["interior_envelope"]}}
    assert fitsettings.model_keys(data) == ["order1", "order2", "interior_envelope"]
    data["model"]["estimator"] = ["output_error", "kalman"]
    assert fitsettings.model_keys(data) == [
        "order1",
        "order1_kalman",
        "order2",
        "order2_kalman",
        "interior_envelope",
        "interior_envelope_kalman",
    ]
    data["model"]["estimator"] = "kalman"
    assert fitsettings.model_keys(data)[0] == "order1_kalman"
    assert fitsettings.split_key("order2_kalman") == ("order2", "kalman")
    assert fitsettings.split_key(2) == ("order2", "output_error")


@pytest.mark.bad_input
def test_an_unknown_estimator_is_refused(tmp_path):
    with pytest.raises(ConfigError, match="estimator"):
        load_vehicle(armadillo_vehicle_file(tmp_path, estimator="ekf"), workdir=tmp_path)


@pytest.fixture(scope="module")
def both(tmp_path_factory):
    root = tmp_path_factory.mktemp("estimators")
    vehicle = load_vehicle(
        armadillo_vehicle_file(root, orders=[1], estimator=["output_error", "kalman"]), workdir=root
    )
    return fit_vehicle(vehicle, out=root / "out", workdir=root), root


def test_both_estimators_fit_and_write_their_own_files(both):
    result, root = both
    assert set(result.fits) == {
        "order1",
        "order1_kalman",
        "interior_envelope",
        "interior_envelope_kalman",
    }
    for key in result.fits:
        assert (root / "out" / "vehicles" / "Armadillo" / f"fit_{key}.yaml").is_file()
    kalman = result.fits["interior_envelope_kalman"].to_dict()
    assert kalman["estimator"] == "kalman"
    assert result.fits["interior_envelope"].content["estimator"] == "output_error"
    assert math.isfinite(kalman["loglik"]) and kalman["n_params"] > len(kalman["free"])
    assert set(kalman["innovations"]) == {"T"}


def test_both_estimators_are_judged_by_the_simulation_and_say_by_what(both):
    """The same criteria judge both fits (the whiteness of the Kalman fit's innovations in
    place of the output-error residuals'); a Kalman fit whose simulation misses the record by
    more than max_rmse_K is in doubt, white innovations or not."""
    result, _ = both
    for key in ("interior_envelope", "interior_envelope_kalman"):
        fit = result.fits[key].to_dict()
        rmse = fit["measures"]["T"]["overall"]["rmse"]
        judged = {c["criterion"]: c for c in fit["criteria"]}
        assert judged["rmse"]["applies"] and judged["rmse"]["passed"] == (rmse <= 0.2), key
        assert any("RMSE" in r for r in fit["reasons"]) == (rmse > 0.2), key
        kalman = key.endswith("_kalman")
        assert judged["innovations_white"]["applies"] == kalman
        assert judged["residuals_white"]["applies"] is False  # require_white is off
        assert fit["judged_by"].startswith("R²")
        assert ("RMSE ✗" in fit["judged_by"]) == (rmse > 0.2)
    kf = result.fits["interior_envelope_kalman"].to_dict()
    white = kf["innovations"]["T"]["white"]
    assert white == (not any("innovations of T are not white" in r for r in kf["reasons"]))


def kalman_estimate(offset_K: float, white: bool = True) -> tuple[EstimateRecord, pd.DataFrame]:
    """A hand-built Kalman estimate of one 10 h window whose simulated T lies ``offset_K``
    off the measurement (plus 0.01 K white noise), with innovations declared white."""
    n = 600
    rng = np.random.default_rng(0)
    T = 20.0 + 20.0 * np.sin(np.linspace(0.0, 3.0, n))  # R^2 stays high at a 1 K offset
    series = pd.DataFrame({"window": "w", "T": T, "T_sim": T + offset_K + rng.normal(0.0, 0.01, n)})
    parameters = {
        p: {"value": v, "ci95": [0.9 * v, 1.1 * v], "estimated": True}
        for p, v in (("kA", 400.0), ("C_bar", 2.0e7))
    }
    estimate = {
        "vehicle": "X",
        "synthetic": False,
        "order": 1,
        "model": "order1_kalman",
        "estimator": "kalman",
        "structure": "first_order",
        "k_source": "joint estimation",
        "outputs": ["T"],
        "cross_validation": [],
        "notes": [],
        "systematic": {},
        "windows": ["w"],
        "rows": n,
        "A": None,
        "mass_kg": None,
        "innovations": {"T": {"white": white, "ljung_box_p": 0.5, "cpg_p": 0.5}},
        "fit": {
            "n_params": 4,
            "n_unknowns": 4,
            "n_obs": n,
            "loglik": -100.0,
            "flags": [],
            "parameters": parameters,
            "free": ["kA", "C_bar"],
            "correlation": [[1.0, 0.0], [0.0, 1.0]],
        },
    }
    return EstimateRecord.from_dict(estimate), series


def test_white_innovations_do_not_excuse_a_simulation_that_misses_the_record():
    """A Kalman fit with white innovations and a simulated T 1 K off: in doubt, failed on the
    RMSE criterion alone; 0.05 K off: acceptable."""
    far = quality.check(*kalman_estimate(1.0), {})
    assert far.content["verdict"] == "assumptions in doubt"
    failed = [c["criterion"] for c in far.content["criteria"] if c["applies"] and not c["passed"]]
    assert failed == ["rmse"]
    assert far.content["judged_by"] == (
        "R², RMSE ✗, innovations white, flags, plausibility, k method"
    )
    near = quality.check(*kalman_estimate(0.05), {})
    assert near.content["verdict"] == "fit acceptable" and "✗" not in near.content["judged_by"]


def test_model_selection_considers_only_acceptable_converged_fits():
    """Of two nested Kalman fits of a vehicle, the larger in doubt (its simulation 1 K off):
    the forward selection has a single candidate and is not shown, and the AIC mark goes to
    the acceptable fit whatever the in-doubt one scores; an unconverged fit is no candidate
    either."""
    small = quality.check(*kalman_estimate(0.05), {})
    large = quality.check(*kalman_estimate(1.0), {})
    large = FitRecord.from_dict(
        large.to_dict() | {"model": "order2_kalman", "order": 2, "loglik": 500.0, "n_params": 6}
    )
    assert tableformat.model_selection_markdown([small, large]) == ""
    table = aggregate.model_table([small, large])
    assert table["best_aic"].tolist() == [True, False]
    assert table["best_bic"].tolist() == [True, False]
    unconverged = FitRecord.from_dict(
        {**small.to_dict(), "flags": [{"code": "not_converged", "message": "stopped"}]}
    )
    table = aggregate.model_table([unconverged, large])
    assert not table["best_aic"].any() and not table["converged"].iloc[0]
    text = tableformat.model_markdown(table, "hand-built")
    assert "(not converged)" in text and "RMSE ✗" in text


def test_models_table_names_the_estimator_and_marks_indicative_criteria(both):
    result, _ = both
    fits = list(result.fits.values())
    table = aggregate.model_table(fits)
    assert sorted(table["estimator"]) == ["kalman", "kalman", "output_error", "output_error"]
    # the information criteria are compared within an estimator, never across, and only
    # among acceptable, converged fits
    eligible = (table["verdict"] == "fit acceptable") & table["converged"]
    for estimator, part in table.groupby("estimator"):
        assert part["best_aic"].sum() == int(eligible[part.index].any()), estimator
    assert not table.loc[~eligible, "best_aic"].any()
    # an output-error AIC with coloured residuals is marked indicative
    oe = table["estimator"] == "output_error"
    assert (table.loc[oe, "ic_indicative"] == (table.loc[oe, "ljung_box_p"] < 0.05)).all()
    assert not table.loc[~oe, "ic_indicative"].any()
    text = tableformat.model_markdown(table, "measured")
    assert "Kalman ML" in text and "output error" in text and "judged by" in text


def test_the_fit_table_names_the_estimator_only_where_a_fit_is_not_the_papers(both):
    result, _ = both
    oe = [result.fits[k] for k in ("order1", "interior_envelope")]
    kf = [result.fits[k] for k in ("order1_kalman", "interior_envelope_kalman")]
    assert "estimator" not in aggregate.fit_table(oe).columns
    table = aggregate.fit_table(oe + kf)
    assert list(table.columns[:3]) == ["vehicle", "order", "estimator"]
    assert table["estimator"].tolist() == ["output_error"] * 2 + ["kalman"] * 2
