"""The Snakemake workflow, run for real in temporary directories (one directory per run)."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest
import yaml
from snakemake_run import job_counts, make_study, snakemake

REPO = Path(__file__).resolve().parents[1]
SMALL = ["Tram2", "Metro3"]

pytestmark = pytest.mark.workflow


def planned_outputs(output: str, rule: str) -> list[str]:
    """The output files of the jobs of one rule in a dry run's job listing."""
    return re.findall(rf"^rule {rule}:\n\s+output: (\S+)", output, re.MULTILINE)


def outputs(study: Path) -> dict[str, bytes]:
    files = sorted(
        p for d in ("resources", "results") for p in (study / d).rglob("*") if p.is_file()
    )
    return {str(p.relative_to(study)): p.read_bytes() for p in files}


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


@pytest.fixture(scope="module")
def small_run(tmp_path_factory) -> Path:
    """One finished run of the small study, shared: tests that edit it work on a copy."""
    study = make_study(tmp_path_factory.mktemp("small"), SMALL)
    run = snakemake(study)
    assert run.returncode == 0, run.stderr
    return study


def copy_of(study: Path, tmp_path: Path) -> Path:
    """A copy of a finished study with its timestamps and Snakemake's records."""
    target = tmp_path / "study"
    shutil.copytree(study, target, symlinks=True)  # copy2: modification times kept
    return target


@pytest.mark.slow
def test_run_writes_raw_files_and_truth_deterministically(small_run, tmp_path):
    first = copy_of(small_run, tmp_path / "a")
    written = outputs(first)
    assert "results/campaign/ground_truth.csv" in written
    for vid in SMALL:
        assert any(p.startswith(f"resources/campaign/{vid}/") for p in written)
    assert not any("Metro1" in p for p in written if p.startswith("resources"))
    for table in ("step_up", "step_down", "kvalue", "record"):
        assert f"results/vehicles/Tram2/clean/{table}.csv" in written
    for vid in SMALL:
        for suffix in ("yaml", "png", "svg"):
            assert f"results/vehicles/{vid}/kvalue.{suffix}" in written
    k_table = written["results/tables/kvalue.csv"].decode().splitlines()
    assert k_table[0].startswith("vehicle,method,k,u_k") and len(k_table) == 1 + len(SMALL)
    for name in ("table1", "table2", "table3", "class_summary", "class_test"):
        for ext in ("csv", "md", "tex"):
            assert f"results/tables/{name}.{ext}" in written
    assert "synthetic" in written["results/tables/table2.md"].decode().splitlines()[0]
    for vid in SMALL:
        assert f"results/vehicles/{vid}/sindy.yaml" in written
    sindy_table = written["results/tables/sindy.csv"].decode().splitlines()
    assert sindy_table[0].startswith("vehicle,verdict") and len(sindy_table) == 1 + len(SMALL)
    assert "results/figures/sindy.png" in written
    findings = written["results/audit/findings.csv"].decode()
    assert "reproduction,reestimate,Tram2 k" in findings and "Metro1 k" not in findings
    # Figure 3 (Tram2 has both orders) and Figure 5; no Figure 4 without Metro1 or Metro2
    for stem in ("figure3", "figure5a", "figure5b"):
        assert f"results/figures/{stem}.png" in written
    assert "results/figures/figure4.png" not in written
    for vid in SMALL:
        for n in (1, 2):
            assert f"results/vehicles/{vid}/fit_order{n}.png" in written
    # predictions: Tram2 simulated, Metro3 (C, K_veh and C_veh, coupled to them, not identified)
    # said so; a class model needs two other vehicles with an acceptable fit, which this study
    # does not have
    scenarios = written["results/tables/scenarios.md"].decode()
    assert "| Metro3 | metro | not simulated: C, K_veh, C_veh not identified" in scenarios
    assert re.search(r"\| Tram2 \| tram \| \d", scenarios)
    loo = written["results/tables/reference_validation.md"].decode()
    assert "| Tram2 | tram | class | class | 0 | too few vehicles" in loo
    for stem in ("scenarios", "reference_validation"):
        assert f"results/figures/{stem}.png" in written

    again = snakemake(first)
    assert again.returncode == 0, again.stderr
    assert "Nothing to be done" in again.stdout + again.stderr

    report = snakemake(first, "--report", "report.html")
    assert report.returncode == 0, report.stderr
    html = (first / "report.html").read_text(encoding="utf-8")
    for caption in (
        "Table 2 (paper Table 2)",
        "Figure 5 (a) (paper Figure 5a)",
        "Figure 3",
        "Audit of the paper's published reference values",
    ):
        assert caption in html
    (first / "report.html").unlink()

    second = make_study(tmp_path / "b", SMALL)
    assert snakemake(second).returncode == 0
    assert outputs(second) == written


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


def test_editing_one_campaign_vehicle_reruns_only_that_vehicle(small_run, tmp_path):
    study = copy_of(small_run, tmp_path)
    campaign_path = study / "config" / "campaign" / "virtual_cwt.yaml"
    campaign = yaml.safe_load(campaign_path.read_text())
    campaign["vehicles"]["Metro3"]["truth"]["C"]["value"] *= 1.1
    campaign_path.write_text(yaml.safe_dump(campaign, sort_keys=False))
    run = snakemake(study, "--dry-run")
    assert run.returncode == 0, run.stderr
    assert planned_outputs(run.stdout, "synthesize") == [
        "resources/campaign/Metro3/Metro3_cwt.csv.gz"
    ]
    assert job_counts(run.stdout + run.stderr)["ground_truth"] == 1


def test_editing_one_vehicle_config_reruns_only_its_jobs_and_the_aggregates(small_run, tmp_path):
    study = copy_of(small_run, tmp_path)
    path = study / "config" / "vehicles" / "Metro3.yaml"
    vehicle = yaml.safe_load(path.read_text())
    vehicle.setdefault("check", {})["r2_min"] = 0.95  # a verdict threshold
    path.write_text(yaml.safe_dump(vehicle, sort_keys=False))
    run = snakemake(study, "--dry-run")
    assert run.returncode == 0, run.stderr
    counts = job_counts(run.stdout + run.stderr)
    assert counts["check"] == 1  # Metro3, orders 1 and 2 in one job
    for rule in ("aggregate", "fit_table", "figure5"):
        assert counts[rule] == 1
    assert "synthesize" not in counts and "ground_truth" not in counts  # raw data untouched
    planned = re.findall(r"^rule (\w+):\n(?:\s+input: .*\n)?\s+output: (.+)$", run.stdout, re.M)
    assert planned
    # the other vehicle rests, but for the SINDy job the two share (sindy.vehicles_per_job)
    assert [rule for rule, line in planned if "Tram2" in line] == ["sindy"]
    assert "figure3" not in counts  # Tram2's figure


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
