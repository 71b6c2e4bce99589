"""railtherm.study.designstudy: the study's design table, on fits of the virtual campaign."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from railtherm.io import read_result
from railtherm.study import classmodel, design, designstudy
from railtherm.study.fit import read_fit

REPO = Path(__file__).resolve().parents[1]


def rows(campaign_study, fit_files, vids, members=(), draws=20):
    _, _, study = campaign_study
    fits, kvalues = {}, {}
    for vid in vids:
        path, series = fit_files(vid, "order2")
        fits[vid] = read_fit(path, series)
        kvalues[vid] = read_result(path.parent / "kvalue.yaml")
    vehicles = {vid: study.vehicles[vid].data for vid in vids}
    target = ("C_veh", 0.10)
    return designstudy.vehicle_rows(fits, kvalues, vehicles, list(members), target, draws=draws)


def test_own_records_are_predicted_as_the_fit_realises_them(campaign_study, fit_files):
    """Acceptable fits of a special programme (Metro2) and of a commissioning record with a
    thermostat hold (Regio2): the widths predicted for their own records, from the fit's
    estimates, its separated noise and its budget, are those the fits report (within 15 %);
    no class model from an empty basis."""
    table = rows(campaign_study, fit_files, ["Metro2", "Regio2"])
    assert list(table["vehicle"]) == ["Metro2"] * 3 + ["Regio2"] * 3
    for _, r in table.iterrows():
        assert r["realised_status"] == "estimated" and r["predicted_status"] == "predicted"
        assert r["predicted"] == pytest.approx(r["realised"], rel=0.15), (
            r["vehicle"],
            r["parameter"],
        )
        assert math.isnan(r["class_median"]) and "at least 2" in r["class_note"]


def test_the_shortest_paper_programme_reaches_the_target_and_a_shorter_one_does_not(
    campaign_study, fit_files
):
    """The shortest paper-shaped programme for Metro2 is predicted to give C_veh within
    ±10 %; the next shorter factor of the grid (its steady start kept) is not."""
    table = rows(campaign_study, fit_files, ["Metro2"])
    row = table[table["parameter"] == "C_veh"].iloc[0]
    assert row["shortest_predicted"] <= 0.10
    path, series = fit_files("Metro2", "order2")
    fit = read_fit(path, series)
    step_s = design.record_runs(fit)[1]  # the vehicle's logger step
    programme = designstudy.paper_programme(fit, read_result(path.parent / "kvalue.yaml"), step_s)
    steps_h = programme.hours - programme.phases[0].hours
    factor = (row["shortest_h"] - programme.phases[0].hours) / steps_h
    grid = np.round(np.geomspace(0.05, 4.0, 65), 4)
    assert np.min(np.abs(grid - factor)) < 1e-6
    shorter = float(grid[grid < factor - 1e-6].max())
    prior = design.prior_from_fit(fit)
    assessed = design.assess(prior, design.scaled(programme, shorter, keep_first=True))
    assert assessed.central.half_width["C_veh"] > 0.10


def test_a_fit_that_leaves_parameters_undetermined_predicts_nothing(campaign_study, fit_files):
    """Metro3's fit determines none of C, K_veh, C_veh: no prediction from it and no shortest
    programme, said in words; the table prints no number for them."""
    table = rows(campaign_study, fit_files, ["Metro3"])
    assert set(table["realised_status"]) == {"not identified"}
    assert all(s.startswith("not predicted (C, K_veh, C_veh") for s in table["predicted_status"])
    assert table["predicted"].isna().all() and table["shortest_h"].isna().all()
    md = designstudy.design_markdown(table, "test")
    assert "| Metro3 | C_veh | not identified | not predicted (C, K_veh, C_veh" in md
    assert md.count("| Metro3 | C_veh |") == 1 and "| not predicted |" in md


def test_before_the_tunnel_the_class_model_without_the_vehicle_predicts(campaign_study, fit_files):
    """Metro2 from the metro class model built of the committed Table 2 without it: a median
    width and a 5-95 % range over the draws, and the share of draws that identify each
    parameter."""
    _, _, study = campaign_study
    table2 = pd.read_csv(REPO / "results" / "tables" / "table2.csv").to_dict("records")
    members = [
        classmodel.member_from_row(r, study.vehicles[r["vehicle"]].data)
        for r in table2
        if r["vehicle"] in study.vehicles
    ]
    table = rows(campaign_study, fit_files, ["Metro2"], members)
    for _, r in table.iterrows():
        assert r["class_q05"] <= r["class_median"] <= r["class_q95"]
        assert 0.0 < r["class_identifiable_share"] <= 1.0 and r["class_note"] == ""


def test_the_study_files_give_the_same_table_as_the_objects(campaign_study, fit_files):
    """study_design reads what rule design gives it (fit files, series, static k files,
    the committed Table 2, the target as the config writes it) into the table that
    vehicle_rows makes of the objects; a vehicle without a static k has no shortest
    programme."""
    _, _, study = campaign_study
    vids = ["Metro1", "Metro2"]
    vehicles = {vid: study.vehicles[vid].data for vid in vids}
    paths = {vid: fit_files(vid, "order2") for vid in vids}
    table2 = REPO / "results" / "tables" / "table2.csv"
    kvalues = {vid: str(paths[vid][0].parent / "kvalue.yaml") for vid in vids}
    files = [str(paths[vid][0]) for vid in vids], [str(paths[vid][1]) for vid in vids]
    table = designstudy.study_design(str(table2), vehicles, *files, kvalues, "C_veh=10%", draws=5)
    members = classmodel.members_from_table2(table2, vehicles)
    assert sorted(m.vehicle for m in members) == vids
    expected = rows(campaign_study, fit_files, vids, members, draws=5)
    pd.testing.assert_frame_equal(table, expected)
    without_k = designstudy.study_design(
        str(table2), vehicles, *files, {"Metro1": kvalues["Metro1"]}, "C_veh=10%", draws=0
    )
    assert without_k.loc[without_k["vehicle"] == "Metro2", "shortest_h"].isna().all()
    assert without_k.loc[without_k["vehicle"] == "Metro1", "shortest_h"].notna().all()
