"""What Snakemake's own process costs in a whole-study run, beside its jobs.

    python benchmarks/scheduler_overhead.py [--cores 2] [--max-jobs-per-timespan 100/1s]

Copies ``config/`` into a scratch directory and runs this checkout's Snakefile there from
clean, with Snakemake in a child process that counts its scheduling rounds (each refreshes
the input sizes of every ready job: ``JobScheduler.update_input_sizes``) and the input files
they look at, and reports at its end its own CPU seconds (RUSAGE_SELF) and its jobs' (RUSAGE
_CHILDREN). Prints the wall time, the jobs' and Snakemake's CPU seconds, the rounds and the
files looked at.
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

# run in the child: Snakemake's CLI with the scheduler's refresh counted
CHILD = r"""
import atexit, resource, sys
from snakemake.scheduling import job_scheduler

counts = {"rounds": 0, "files": 0}
refresh = job_scheduler.JobScheduler.update_input_sizes

async def counted(self, jobs):
    jobs = list(jobs)
    counts["rounds"] += 1
    counts["files"] += len({path for job in jobs for path in job.input})
    return await refresh(self, jobs)

job_scheduler.JobScheduler.update_input_sizes = counted

def report():
    own = resource.getrusage(resource.RUSAGE_SELF)
    jobs = resource.getrusage(resource.RUSAGE_CHILDREN)
    print(
        f"OVERHEAD {own.ru_utime + own.ru_stime:.1f} {jobs.ru_utime + jobs.ru_stime:.1f} "
        f"{counts['rounds']} {counts['files']}",
        file=sys.stderr,
    )

atexit.register(report)
from snakemake.cli import main
sys.argv = ["snakemake", *sys.argv[1:]]
main()
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cores", type=int, default=2)
    parser.add_argument(
        "--max-jobs-per-timespan",
        default=None,
        help="passed on to snakemake (its default: 100/1s)",
    )
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="railtherm-overhead-") as tmp:
        study = Path(tmp) / "study"
        shutil.copytree(REPO / "config", study / "config")
        extra = []
        if args.max_jobs_per_timespan:
            extra = ["--max-jobs-per-timespan", args.max_jobs_per_timespan]
        env = {**os.environ, "PYTHONPATH": str(REPO), "MPLBACKEND": "Agg"}
        start = time.perf_counter()
        run = subprocess.run(
            [sys.executable, "-c", CHILD, "--snakefile", str(REPO / "Snakefile")]
            + ["--directory", str(study), "--cores", str(args.cores), "--quiet", *extra, "all"],
            capture_output=True,
            text=True,
            env=env,
        )
        wall = time.perf_counter() - start
        if run.returncode != 0:
            sys.exit(f"snakemake failed:\n{run.stderr[-3000:]}")
    line = next(x for x in run.stderr.splitlines() if x.startswith("OVERHEAD "))
    own, jobs, rounds, files = line.split()[1:]
    print(f"--cores {args.cores}, --max-jobs-per-timespan {args.max_jobs_per_timespan or '100/1s'}")
    print(f"wall {wall:.1f} s; jobs' CPU {jobs} s; Snakemake's own CPU {own} s")
    print(f"scheduling rounds {rounds}; input files looked at {files}")


if __name__ == "__main__":
    main()
