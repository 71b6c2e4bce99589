"""model.estimator: output_error (the paper's K = 0) and kalman (eq. 16 with K from a Kalman
filter) side by side for one vehicle, each fit its own output and every table naming its
estimator; a kalman fit is judged by the whiteness of its one-step innovations."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest
import yaml

from railtherm import aggregate, identify, tableformat
from railtherm.config import load_vehicle
from railtherm.errors import ConfigError
from railtherm.run import fit_vehicle

REPO = Path(__file__).resolve().parents[1]
ARMADILLO = REPO / "validation" / "config" / "vehicles" / "Armadillo.yaml"


def armadillo(tmp_path: Path, **model) -> Path:
    data = yaml.safe_load(ARMADILLO.read_text(encoding="utf-8"))
    data["model"] |= model
    data["raw_files"] = {"h2": str(REPO / "data" / "armadillo" / "armadillo_data_H2.csv")}
    path = tmp_path / "Armadillo.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def test_model_keys_name_each_estimator_once():
    data = {"model": {"orders": [1, 2], "structures": ["interior_envelope"]}}
    assert identify.model_keys(data) == ["order1", "order2", "interior_envelope"]
    data["model"]["estimator"] = ["output_error", "kalman"]
    assert identify.model_keys(data) == [
        "order1",
        "order1_kalman",
        "order2",
        "order2_kalman",
        "interior_envelope",
        "interior_envelope_kalman",
    ]
    data["model"]["estimator"] = "kalman"
    assert identify.model_keys(data)[0] == "order1_kalman"
    assert identify.split_key("order2_kalman") == ("order2", "kalman")
    assert identify.split_key(2) == ("order2", "output_error")


@pytest.mark.bad_input
def test_an_unknown_estimator_is_refused(tmp_path):
    with pytest.raises(ConfigError, match="estimator"):
        load_vehicle(armadillo(tmp_path, estimator="ekf"), workdir=tmp_path)


@pytest.fixture(scope="module")
def both(tmp_path_factory):
    root = tmp_path_factory.mktemp("estimators")
    vehicle = load_vehicle(
        armadillo(root, orders=[1], estimator=["output_error", "kalman"]), workdir=root
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
    kalman = result.fits["interior_envelope_kalman"].data
    assert kalman["estimator"] == "kalman"
    assert result.fits["interior_envelope"].data["estimator"] == "output_error"
    assert math.isfinite(kalman["loglik"]) and kalman["n_params"] > len(kalman["free"])
    assert set(kalman["innovations"]) == {"T"}


def test_a_kalman_fit_is_judged_by_its_innovations_not_by_the_rmse_limit(both):
    result, _ = both
    oe = result.fits["interior_envelope"]
    kf = result.fits["interior_envelope_kalman"]
    assert any("RMSE" in r for r in oe.reasons)
    assert not any("RMSE" in r for r in kf.reasons)
    white = kf.data["innovations"]["T"]["white"]
    assert white == (not any("innovations of T are not white" in r for r in kf.reasons))


def test_models_table_names_the_estimator_and_selects_by_likelihood_ratio(both):
    result, _ = both
    fits = [f.data for f in result.fits.values()]
    table = aggregate.model_table(fits, "measured")
    assert sorted(table["estimator"]) == ["kalman", "kalman", "output_error", "output_error"]
    # the information criteria are compared within an estimator, never across
    assert table.groupby("estimator")["best_aic"].sum().tolist() == [1, 1]
    selection = tableformat.model_selection_markdown(fits)
    assert "Forward selection, Armadillo" in selection
    assert re.search(r"\|\s*order1\s*\|\s*interior_envelope\s*\|", selection), selection
    text = tableformat.model_markdown(table, "measured", selection)
    assert "Kalman ML" in text and "output error" in text


def test_the_fit_table_names_the_estimator_only_where_a_fit_is_not_the_papers(both):
    result, _ = both
    oe = [result.fits[k].data for k in ("order1", "interior_envelope")]
    kf = [result.fits[k].data for k in ("order1_kalman", "interior_envelope_kalman")]
    assert "estimator" not in aggregate.fit_table(oe).columns
    table = aggregate.fit_table(oe + kf)
    assert list(table.columns[:3]) == ["vehicle", "order", "estimator"]
    assert table["estimator"].tolist() == ["output_error"] * 2 + ["kalman"] * 2
