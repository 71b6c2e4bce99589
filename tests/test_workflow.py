"""The Snakemake workflow, run for real in temporary directories (one directory per run)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml
from snakemake_run import job_counts, make_study, snakemake

REPO = Path(__file__).resolve().parents[1]
SMALL = ["Tram2", "Metro3"]

pytestmark = pytest.mark.workflow


def test_lint_reports_nothing(tmp_path):
    run = snakemake(make_study(tmp_path), "--lint")
    assert run.returncode == 0, run.stderr
    assert "Congratulations, your workflow is in a good condition!" in run.stdout + run.stderr


def test_dry_run_plans_the_whole_campaign(tmp_path):
    study = make_study(tmp_path)
    run = snakemake(study, "--dry-run")
    assert run.returncode == 0, run.stderr
    counts = job_counts(run.stdout + run.stderr)
    assert counts["ground_truth"] == 1
    assert counts["synthesize"] >= 13  # at least one raw file per vehicle
    assert counts["sindy"] == 1 and counts["sindy_summary"] == 1  # on in the shipped config
    assert not (study / "resources").exists()


def test_switched_off_the_sindy_stage_plans_no_job(tmp_path):
    study = make_study(tmp_path, SMALL)
    cfg_path = study / "config" / "config.yaml"
    cfg = yaml.safe_load(cfg_path.read_text())
    cfg["sindy"]["enabled"] = False
    cfg_path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    run = snakemake(study, "--dry-run")
    assert run.returncode == 0, run.stderr
    counts = job_counts(run.stdout + run.stderr)
    assert "sindy" not in counts and "sindy_summary" not in counts
    assert counts["identify"] == 2  # one job per vehicle, both models


def test_sindy_fits_share_a_job_up_to_vehicles_per_job(tmp_path):
    """pysindy's import outweighs a fit: the SINDy vehicles go to jobs in batches, in study
    order; one vehicle to a job gives a rule per vehicle, each writing only its vehicle's file."""
    study = make_study(tmp_path, SMALL)
    cfg_path = study / "config" / "config.yaml"
    cfg = yaml.safe_load(cfg_path.read_text())
    cfg["sindy"]["vehicles_per_job"] = 1
    cfg_path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    run = snakemake(study, "--dry-run")
    assert run.returncode == 0, run.stderr
    counts = job_counts(run.stdout + run.stderr)
    assert counts["sindy"] == 1 and counts["sindy_2"] == 1
    for rule, vehicle in (("sindy", "Tram2"), ("sindy_2", "Metro3")):
        planned = re.findall(rf"^rule {rule}:\n\s+input: .*\n\s+output: (.+)$", run.stdout, re.M)
        assert planned == [f"results/vehicles/{vehicle}/sindy.yaml"]


@pytest.mark.bad_input
def test_bad_vehicle_config_stops_before_any_job(tmp_path):
    study = make_study(tmp_path, SMALL)
    path = study / "config" / "vehicles" / "Metro3.yaml"
    vehicle = yaml.safe_load(path.read_text())
    vehicle["mass_kg"] = -1
    path.write_text(yaml.safe_dump(vehicle, sort_keys=False))
    run = snakemake(study)
    assert run.returncode != 0
    message = run.stdout + run.stderr
    assert "config/vehicles/Metro3.yaml" in message
    assert "mass_kg" in message and "-1" in message
    assert not (study / "resources").exists() and not (study / "results").exists()


@pytest.mark.bad_input
@pytest.mark.parametrize(
    ("text", "reason"),
    [
        ("vehicles:\n  - config/vehicles/Tram2.yaml\n", "duplicate key 'vehicles'"),
        (
            "bomb: &a [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]\n"
            + "".join(
                f"b{i}: &b{i} [*{'a' if i == 0 else f'b{i - 1}'}"
                + f", *{'a' if i == 0 else f'b{i - 1}'}" * 9
                + "]\n"
                for i in range(7)
            ),
            "alias bomb",
        ),
    ],
    ids=["vehicles-twice", "alias-bomb"],
)
def test_the_workflow_reads_the_study_config_as_validate_does(tmp_path, text, reason):
    """A config.yaml that `railtherm validate` refuses stops the workflow's parse with the same
    message, before Snakemake's own loader would run the second `vehicles:` list silently or
    build an alias bomb for minutes."""
    study = make_study(tmp_path)
    cfg = study / "config" / "config.yaml"
    cfg.write_text(cfg.read_text() + text)
    run = snakemake(study, "-n")
    assert run.returncode != 0
    said = run.stdout + run.stderr
    assert "invalid configuration: config/config.yaml" in said
    assert reason in said


def test_the_reports_introduction_says_synthetic_only_with_a_virtual_campaign():
    """The report's introduction (workflow/report/workflow.rst, rendered by Snakemake with
    Jinja2 and the study config) said the records were synthetic in a study of measured
    vehicles alone (campaign: null) too."""
    import jinja2

    text = (REPO / "workflow" / "report" / "workflow.rst").read_text(encoding="utf-8")

    def intro(campaign):
        snakemake_ = type("Snakemake", (), {"config": {"campaign": campaign}})
        return (
            jinja2.Environment(undefined=jinja2.StrictUndefined)
            .from_string(text)
            .render(snakemake=snakemake_, categories={}, files={})
        )

    assert "the records are **synthetic**" in intro("config/campaign/virtual_cwt.yaml")
    measured = intro(None)
    assert "synthetic**" not in measured and "no virtual campaign in this study" in measured
