"""railtherm.study.plan: the files the workflow's rules read and write, from the configs."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml
from snakemake.utils import validate

from railtherm.config import load_study
from railtherm.errors import ConfigError
from railtherm.study.plan import VEHICLE_ID, StudyPlan, group_constraint
from railtherm.study.scenario import load_scenario

REPO = Path(__file__).resolve().parents[1]


def plan_of(study_dir: Path) -> StudyPlan:
    """The plan of a study directory, its config with the schema's defaults as the Snakefile
    fills them in."""
    config = yaml.safe_load((study_dir / "config" / "config.yaml").read_text())
    validate(config, str(REPO / "railtherm" / "schemas" / "study.schema.yaml"))
    study = load_study(config, workdir=study_dir)
    scenarios = [load_scenario(study_dir / p) for p in config["scenarios"]["files"]]
    return StudyPlan(study, config, scenarios)


@pytest.fixture(scope="module")
def campaign_plan() -> StudyPlan:
    return plan_of(REPO)


@pytest.fixture(scope="module")
def validation_plan() -> StudyPlan:
    return plan_of(REPO / "validation")


def test_the_campaign_targets_are_the_committed_outputs(campaign_plan):
    """Every committed table and figure of the study is a target, and each vehicle's fits."""
    targets = set(campaign_plan.all_outputs())
    committed = {
        p.relative_to(REPO).as_posix()
        for folder in ("results/tables", "results/figures")
        for p in (REPO / folder).iterdir()
    }
    assert committed <= targets, sorted(committed - targets)[:5]
    for vid in campaign_plan.second_order_vehicles():
        assert f"results/vehicles/{vid}/fit_order2.yaml" in targets
    assert len(campaign_plan.all_outputs()) == len(targets)  # no target twice


def test_the_validation_study_plans_every_structure_and_estimator(validation_plan):
    """The Armadillo box fits order1 and interior_envelope by both estimators: six fits, a
    figure each, innovations for the Kalman ones; no paper tables (class other)."""
    keys = validation_plan.model_keys("Armadillo")
    assert set(keys) >= {"order1", "order1_kalman", "interior_envelope_kalman"}
    figures = validation_plan.vehicle_figure_files("Armadillo")
    assert "results/vehicles/Armadillo/innovations_interior_envelope_kalman.png" in figures
    assert not validation_plan.paper_tables()
    assert "results/tables/table2.csv" not in validation_plan.all_outputs()


def test_vehicles_with_other_models_get_rules_of_their_own(validation_plan):
    """Per-vehicle rules are grouped by the files they write: each group's constraint matches
    its own vehicles and no other's."""
    groups = validation_plan.rule_groups("identify", validation_plan.model_keys)
    names = [name for name, _, _ in groups]
    assert names[0] == "identify" and all(
        n == f"identify_{i + 1}" for i, n in enumerate(names) if i
    )
    for _, keys, constraint in groups:
        for vid in validation_plan.vehicles:
            mine = validation_plan.model_keys(vid) == keys
            assert bool(re.fullmatch(constraint, vid)) == mine, (vid, constraint)


def test_group_constraints_of_a_fleet_stay_short():
    """The largest group is "any id but the others'": a fleet's constraint does not list it."""
    fleet = [f"V{i}" for i in range(1000)]
    odd = ["V1_x", "Odd"]
    constraint = group_constraint([fleet, odd], fleet)
    assert len(constraint) < 100
    assert all(re.fullmatch(constraint, v) for v in ("V1", "V999", "V1_y"))
    assert not any(re.fullmatch(constraint, v) for v in odd)
    assert group_constraint([fleet], fleet) == VEHICLE_ID
    assert re.fullmatch(group_constraint([fleet, odd], odd), "Odd")


@pytest.mark.bad_input
def test_a_design_target_of_no_estimated_parameter_is_refused_at_parse(campaign_plan):
    """kA is held by the static test in the paper's fit: no design can target it."""
    config = {
        **campaign_plan.config,
        "design": {**campaign_plan.config["design"], "target": "kA=5%"},
    }
    plan = StudyPlan(campaign_plan.study, config, campaign_plan.scenarios)
    with pytest.raises(ConfigError, match=r"design\.target"):
        plan.design_outputs()
