"""Run the repository's Snakefile in a temporary study directory (shared by workflow tests)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]


def cores() -> int:
    """The cores a test's Snakemake run is given: 1 where the suite's workers already take every
    CPU (``pytest -n auto``), 2 otherwise. A second job at a time then only competes with the
    other workers for the same CPUs: on 2 cores the four test files that run whole studies
    (`pytest -n 2`, one run each, the same commit, 2 first) took 590 CPU-s (313 s) with 2 and
    498 CPU-s (281 s) with 1, the same tests passing."""
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cpus = os.cpu_count() or 1
    return 1 if workers >= cpus else 2


def snakemake(study: Path, *args: str, jobs: int | None = None) -> subprocess.CompletedProcess:
    """``snakemake --directory study --cores N *args`` with this repository's Snakefile, N =
    ``jobs`` or :func:`cores`."""
    return subprocess.run(
        [sys.executable, "-m", "snakemake", "--snakefile", str(REPO / "Snakefile")]
        + ["--directory", str(study), "--cores", str(jobs or cores()), *args],
        capture_output=True,
        text=True,
        timeout=600,
    )


def make_study(tmp_path: Path, vehicles: list[str] | None = None) -> Path:
    """A working directory holding a copy of config/, optionally restricted to some vehicles."""
    study = tmp_path / "study"
    shutil.copytree(REPO / "config", study / "config")
    if vehicles is not None:
        cfg_path = study / "config" / "config.yaml"
        cfg = yaml.safe_load(cfg_path.read_text())
        cfg["vehicles"] = [f"config/vehicles/{v}.yaml" for v in vehicles]
        cfg_path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    return study


def job_counts(output: str) -> dict[str, int]:
    """Rule -> job count from the 'Job stats' table Snakemake prints."""
    table = output.split("Job stats:", 1)[1]
    return {
        m.group(1): int(m.group(2))
        for m in re.finditer(r"^(\w+)\s+(\d+)\s*$", table, re.MULTILINE)
        if m.group(1) != "total"
    }


def planned_outputs(output: str, rule: str) -> list[str]:
    """The output files of the jobs of one rule in a dry run's job listing."""
    return re.findall(rf"^rule {rule}:\n\s+output: (\S+)", output, re.MULTILINE)


def outputs(study: Path) -> dict[str, bytes]:
    """Every file a run wrote (resources/ and results/), by path relative to the study."""
    files = sorted(
        p for d in ("resources", "results") for p in (study / d).rglob("*") if p.is_file()
    )
    return {str(p.relative_to(study)): p.read_bytes() for p in files}


def copy_of(study: Path, tmp_path: Path) -> Path:
    """A copy of a finished study with its timestamps and Snakemake's records."""
    target = tmp_path / "study"
    shutil.copytree(study, target, symlinks=True)  # copy2: modification times kept
    return target
