"""Wall time of the whole study regenerated from clean: ``snakemake --cores N`` in a scratch copy.

    python benchmarks/bench_regenerate.py [--cores 2] [--rounds 1]

The scratch directory holds only ``config/`` (the Snakefile is the repo's), so nothing is
reused: synthesis, cleaning, k values, every fit, check, table and figure run. The figure is
set beside 3 minutes with ``--cores 2``; the script also prints
the time of one ``snakemake --dry-run`` (DAG building and config validation alone) in the same
process, as the fixed cost inside that figure.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def snakemake(study: Path, cores: int, *args: str) -> float:
    start = time.perf_counter()
    run = subprocess.run(
        [sys.executable, "-m", "snakemake", "--snakefile", str(REPO / "Snakefile")]
        + ["--directory", str(study), "--cores", str(cores), "--quiet", *args],
        capture_output=True,
        text=True,
    )
    elapsed = time.perf_counter() - start
    if run.returncode != 0:
        sys.exit(f"snakemake failed in {study}:\n{run.stderr[-3000:]}")
    return elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cores", type=int, default=2)
    parser.add_argument("--rounds", type=int, default=1)
    args = parser.parse_args()
    for r in range(args.rounds):
        with tempfile.TemporaryDirectory() as tmp:
            study = Path(tmp) / "study"
            shutil.copytree(REPO / "config", study / "config")
            dry = snakemake(study, args.cores, "--dry-run")
            full = snakemake(study, args.cores)
            n_png = len(list((study / "results").rglob("*.png")))
            n_tables = len(list((study / "results" / "tables").glob("*")))
            print(
                f"round {r + 1}: full regeneration {full:6.1f} s with --cores {args.cores} "
                f"({full / 180:.2f} of 3 minutes); dry run {dry:4.1f} s; "
                f"{n_tables} table files, {n_png} PNG figures"
            )


if __name__ == "__main__":
    main()
