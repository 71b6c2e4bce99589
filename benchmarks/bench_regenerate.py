"""Wall time of the whole study regenerated from clean, and of a no-op rerun, side by side
with a baseline checkout.

    python benchmarks/bench_regenerate.py [--cores 2] [--rounds 1] [--baseline DIR]

Each round copies ``config/`` of a checkout into a scratch directory (nothing is reused:
synthesis, cleaning, k values, every fit, check, table and figure run) and runs that checkout's
Snakefile there with ``snakemake --cores N``; then ``snakemake`` once more in the finished study
(the no-op rerun: nothing to be done) and a ``--dry-run`` of the finished study. With
``--baseline DIR`` (another checkout, e.g. ``git worktree add /tmp/base <commit>``) each round
runs the baseline and this checkout one after the other, so that both see the same load; each
run imports railtherm from its own checkout (``PYTHONPATH``). Every run's jobs and CPU seconds
(user + sys of snakemake and all its jobs, from ``os.wait4``) are printed beside the wall time.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def snakemake(checkout: Path, study: Path, cores: int, *args: str) -> tuple[float, float]:
    """(wall seconds, CPU seconds) of one snakemake call with ``checkout``'s Snakefile."""
    env = {**os.environ, "PYTHONPATH": str(checkout), "MPLBACKEND": "Agg"}
    start = time.perf_counter()
    proc = subprocess.Popen(
        [sys.executable, "-m", "snakemake", "--snakefile", str(checkout / "Snakefile")]
        + ["--directory", str(study), "--cores", str(cores), "--quiet", "all", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        env=env,
    )
    output = proc.stdout.read()
    _, status, usage = os.wait4(proc.pid, 0)
    elapsed = time.perf_counter() - start
    if os.waitstatus_to_exitcode(status) != 0:
        sys.exit(f"snakemake failed in {study}:\n{output.decode()[-3000:]}")
    return elapsed, usage.ru_utime + usage.ru_stime


def jobs(checkout: Path, study: Path) -> int:
    """The number of jobs of the study (a dry run with every job forced)."""
    run = subprocess.run(
        [sys.executable, "-m", "snakemake", "--snakefile", str(checkout / "Snakefile")]
        + ["--directory", str(study), "-n", "--forceall", "--quiet", "rules"],
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": str(checkout)},
    )
    totals = [line.split()[-1] for line in run.stdout.splitlines() if line.startswith("total")]
    return int(totals[-1]) if totals else -1


def round_of(checkout: Path, cores: int) -> dict[str, float]:
    with tempfile.TemporaryDirectory() as tmp:
        study = Path(tmp) / "study"
        shutil.copytree(checkout / "config", study / "config")
        full, cpu = snakemake(checkout, study, cores)
        noop, _ = snakemake(checkout, study, cores)
        dry, _ = snakemake(checkout, study, cores, "--dry-run")
        return {"full": full, "cpu": cpu, "noop": noop, "dry": dry, "jobs": jobs(checkout, study)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cores", type=int, default=2)
    parser.add_argument("--rounds", type=int, default=1)
    parser.add_argument("--baseline", type=Path, help="another checkout to run side by side")
    args = parser.parse_args()
    checkouts = [("this checkout", REPO)]
    if args.baseline:
        checkouts.insert(0, ("baseline", args.baseline.resolve()))
    print(
        f"| round | checkout | jobs | full regeneration, --cores {args.cores} | CPU s "
        "| no-op rerun | dry run, finished study |"
    )
    print("|---|---|---|---|---|---|---|")
    for r in range(args.rounds):
        for name, checkout in checkouts:
            t = round_of(checkout, args.cores)
            print(
                f"| {r + 1} | {name} | {t['jobs']} | {t['full']:.1f} s | {t['cpu']:.0f} "
                f"| {t['noop']:.1f} s | {t['dry']:.1f} s |",
                flush=True,
            )


if __name__ == "__main__":
    main()
