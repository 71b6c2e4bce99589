"""The README's main command run for real, from clean, in a temporary directory, once: the
committed tables, every raw file and figure, the report, nothing left to do, the same bytes when
regenerated, and the jobs an edit reruns. A file of its own, so that the test runner's workers
take it and the other workflow runs side by side."""

from __future__ import annotations

import io
import re
import shutil
from pathlib import Path

import pytest
import yaml
from compare_outputs import assert_outputs_agree
from matplotlib.image import imread
from snakemake_run import copy_of, job_counts, make_study, outputs, planned_outputs, snakemake

REPO = Path(__file__).resolve().parents[1]
VEHICLES = [
    Path(p).stem for p in yaml.safe_load((REPO / "config" / "config.yaml").read_text())["vehicles"]
]

pytestmark = pytest.mark.workflow


def png_is_a_picture(data: bytes, min_px: int = 400) -> None:
    """A PNG of a sensible size whose pixels are not all one colour."""
    img = imread(io.BytesIO(data), format="png")
    assert img.shape[0] >= min_px and img.shape[1] >= min_px, img.shape
    grey = img[..., :3].mean(axis=2)
    assert grey.std() > 0.02 and (grey < 0.5).mean() > 0.002  # ink on the page


@pytest.fixture(scope="module")
def full_run(tmp_path_factory) -> Path:
    """The study of the shipped config, run once from clean; tests that edit it work on a copy."""
    study = make_study(tmp_path_factory.mktemp("full"))
    run = snakemake(study)
    assert run.returncode == 0, run.stderr[-3000:]
    return study


@pytest.mark.slow
def test_full_study_reproduces_the_committed_tables(full_run):
    """The same tables and audit as committed under results/tables and results/audit (the
    reader's copy), the text identical and the numbers within the tolerance of compare_outputs
    (another CPU moves the last digits), and every figure a real picture."""
    committed = sorted((REPO / "results" / "tables").glob("*"))
    committed += sorted((REPO / "results" / "audit").glob("*"))
    assert len(committed) >= 17 + 2
    assert_outputs_agree(full_run, REPO, [p.relative_to(REPO) for p in committed])
    figures = sorted((full_run / "results").rglob("*.png"))
    assert len(figures) >= 4 + 13 + 26
    for png in figures:
        png_is_a_picture(png.read_bytes())


@pytest.mark.slow
def test_the_run_writes_raw_files_truth_tables_and_figures(full_run):
    written = outputs(full_run)
    assert "results/campaign/ground_truth.csv" in written
    for vid in VEHICLES:
        assert any(p.startswith(f"resources/campaign/{vid}/") for p in written), vid
        for suffix in ("yaml", "png", "svg"):
            assert f"results/vehicles/{vid}/kvalue.{suffix}" in written
        assert f"results/vehicles/{vid}/sindy.yaml" in written
    for table in ("step_up", "step_down", "kvalue", "record"):
        assert f"results/vehicles/Tram2/clean/{table}.csv" in written
    k_table = written["results/tables/kvalue.csv"].decode().splitlines()
    assert k_table[0].startswith("vehicle,method,k,u_k") and len(k_table) == 1 + len(VEHICLES)
    for name in ("table1", "table2", "table3", "class_summary", "class_test"):
        for ext in ("csv", "md", "tex"):
            assert f"results/tables/{name}.{ext}" in written
    assert "synthetic" in written["results/tables/table2.md"].decode().splitlines()[0]
    sindy_table = written["results/tables/sindy.csv"].decode().splitlines()
    assert sindy_table[0].startswith("vehicle,verdict") and len(sindy_table) == 1 + len(VEHICLES)
    assert "results/figures/sindy.png" in written
    assert "reproduction,reestimate,Tram2 k" in written["results/audit/findings.csv"].decode()
    for stem in ("figure3", "figure4", "figure5a", "figure5b"):
        assert f"results/figures/{stem}.png" in written
    for vid in ("Tram2", "Metro3"):
        for n in (1, 2):
            assert f"results/vehicles/{vid}/fit_order{n}.png" in written
    # predictions: Tram2 simulated, Metro3 (C, K_veh and C_veh, coupled to them, not identified)
    # said so; Tram2's class model needs two other trams with an acceptable fit (there is one)
    scenarios = written["results/tables/scenarios.md"].decode()
    assert "| Metro3 | metro | not simulated: C, K_veh, C_veh not identified" in scenarios
    assert re.search(r"\| Tram2 \| tram \| \d", scenarios)
    loo = written["results/tables/reference_validation.md"].decode()
    assert "| Tram2 | tram | class | class | 1 | too few vehicles" in loo
    for stem in ("scenarios", "reference_validation"):
        assert f"results/figures/{stem}.png" in written


@pytest.mark.slow
def test_a_finished_study_has_nothing_to_do_and_reports_its_results(full_run, tmp_path):
    again = snakemake(full_run)
    assert again.returncode == 0, again.stderr
    assert "Nothing to be done" in again.stdout + again.stderr
    report = snakemake(full_run, "--report", str(tmp_path / "report.html"))
    assert report.returncode == 0, report.stderr
    html = (tmp_path / "report.html").read_text(encoding="utf-8")
    for caption in (
        "Table 2 (paper Table 2)",
        "Figure 5 (a) (paper Figure 5a)",
        "Figure 3",
        "Figure 4",
        "Audit of the paper's published reference values",
    ):
        assert caption in html


@pytest.mark.slow
def test_a_vehicle_and_every_study_output_regenerated_are_the_same_bytes(full_run, tmp_path):
    """Same inputs, same outputs: Tram2's raw files and results and every table, figure and
    audit file of the study deleted and made again by new processes (its synthesis, cleaning,
    k test, fits, checks and figures, the SINDy job and every study-wide rule) give every file
    of the study byte for byte, raw data, figures and all. Two jobs at a time here, whatever
    the first run took: a parallel run gives the bytes of a serial one (in `pytest -n auto`,
    whose workers take every CPU, the study itself runs one job at a time)."""
    study = copy_of(full_run, tmp_path)
    written = outputs(study)
    for gone in ("resources/campaign/Tram2", "results/vehicles/Tram2", "results/tables"):
        shutil.rmtree(study / gone)
    for gone in ("results/figures", "results/audit"):
        shutil.rmtree(study / gone)
    run = snakemake(study, jobs=2)
    assert run.returncode == 0, run.stderr[-3000:]
    counts = job_counts(run.stdout + run.stderr)
    for rule in ("synthesize", "clean", "kvalue", "identify", "check", "vehicle_figures"):
        assert sum(n for r, n in counts.items() if r == rule or r.startswith(f"{rule}_")) >= 1
    for rule in ("sindy", "aggregate", "figure3", "figure4", "figure5", "audit", "energy"):
        assert counts[rule] == 1, rule
    assert outputs(study) == written


def test_editing_one_campaign_vehicle_reruns_only_that_vehicle(full_run, tmp_path):
    study = copy_of(full_run, tmp_path)
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


def test_editing_one_vehicle_config_reruns_only_its_jobs_and_the_aggregates(full_run, tmp_path):
    study = copy_of(full_run, tmp_path)
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
    # the other vehicles rest, but for the SINDy job they share (sindy.vehicles_per_job)
    assert [rule for rule, line in planned if "Tram2" in line] == ["sindy"]
    assert "figure3" not in counts  # Tram2's figure


def test_inference_posterior_samples_each_vehicle_with_the_class_of_the_others(full_run, tmp_path):
    """`inference: posterior` plans a posterior job per Table 1 and Table 2 fit and the pooling
    table; the posterior of a vehicle (Regio1, the smallest record) runs alone on the finished
    study, its prior the regional class without it, its file the diagnostics and each
    parameter's maximum-likelihood and posterior intervals, its InferenceData readable."""
    import arviz as az

    study = copy_of(full_run, tmp_path)
    cfg_path = study / "config" / "config.yaml"
    cfg = yaml.safe_load(cfg_path.read_text())
    cfg["inference"] = "posterior"
    cfg["posterior"] = {"chains": 2, "draws": 100, "tune": 100, "seed": 3}
    cfg_path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    plan = snakemake(study, "--dry-run")
    assert plan.returncode == 0, plan.stderr[-3000:]
    counts = job_counts(plan.stdout + plan.stderr)
    fits = sum(len(yaml.safe_load((study / v).read_text()).get("model", {}).get("orders", [1, 2]))
               for v in cfg["vehicles"])  # fmt: skip
    assert counts["posterior"] == fits and counts["pooling"] == 1
    assert not {"identify", "check", "aggregate"} & set(counts)  # nothing else reruns
    target = "results/vehicles/Regio1/posterior_order2.yaml"
    run = snakemake(study, target)
    assert run.returncode == 0, run.stderr[-3000:]
    assert job_counts(run.stdout + run.stderr) == {"posterior": 1}
    rec = yaml.safe_load((study / target).read_text())
    assert rec["prior"]["kind"] == "class" and rec["prior"]["class"] == "regional"
    assert "Regio1" not in rec["prior"]["vehicles"] and rec["prior"]["vehicles"]
    assert set(rec["diagnostics"]) == {"r_hat_max", "ess_bulk_min", "divergences", "trusted"}
    assert rec["loo"]["observations"] > 100 and rec["loo"]["draws"] == 200
    for p in ("C", "K_veh", "C_veh"):
        entry = rec["parameters"][p]
        lo, hi = entry["ci95"]
        ml_lo, ml_hi = entry["ml"]["ci95"]
        assert lo < entry["median"] < hi and lo < ml_hi and ml_lo < hi  # intervals meet
    back = az.from_netcdf(study / "results/vehicles/Regio1/fit_order2.posterior.nc")
    assert back.posterior["C_veh"].shape == (2, 100)
    assert "posterior_systematic" in back.groups()
