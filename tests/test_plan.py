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


def test_the_tables_name_the_vehicles_they_leave_out(campaign_plan, validation_plan):
    """Tables 1-3 are of second-order fits: a vehicle without one is named in their notes
    (rule aggregate's left_out), none in the shipped study; in the validation study the
    Armadillo variants fitting order 1 alone are."""
    assert campaign_plan.without_second_order() == {}
    left_out = validation_plan.without_second_order()
    assert left_out and all(2 not in orders for orders in left_out.values())
    assert set(left_out) | set(validation_plan.second_order_vehicles()) == set(
        validation_plan.vehicles
    )


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
@pytest.mark.parametrize(
    ("section", "key"),
    [
        ({"design": {"target": "kA=5%"}}, "design.target"),
        ({"energy": {"enabled": True, "what_if": ["k=-10", "x"]}}, "energy.what_if[0]"),
        ({"energy": {"enabled": True, "weather": ["nowhere.epw"]}}, "energy.weather[0]"),
        ({"energy": {"enabled": True, "profile": "config/config.yaml"}}, "campaign"),
    ],
)
def test_plan_settings_are_refused_by_validate_as_by_the_workflow(tmp_path, section, key):
    """A design target that is no estimated parameter, an unreadable what-if, a missing
    weather file or a profile that is none: ``railtherm validate`` and the workflow's parse
    (both through load_study) refuse it, naming the key."""
    from railtherm.cli import main

    config = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
    for name, values in section.items():
        config[name] = {**config.get(name, {}), **values}
    config_path = tmp_path / "config.yaml"
    config_path.write_text(yaml.safe_dump(config))
    with pytest.raises(ConfigError, match=re.escape(f"'{key}'")):
        load_study(config, workdir=REPO)
    args = ["validate", "-d", str(REPO), "--config", str(config_path), "--headers-only"]
    assert main(args) != 0
