"""Where a finished run's time went, per rule: the start and end times Snakemake records for
every output (``.snakemake/metadata``), one entry per job.

    python benchmarks/job_times.py [WORKDIR]     # after e.g. snakemake --cores 2 --forceall

Prints, per rule, the number of jobs, their mean and largest wall time and their share of the
summed job time, in Markdown, largest share first; then the summed job time and the span from
the first job's start to the last job's end. A job's time runs from its start to its end as
Snakemake saw them: the interpreter's start-up and imports included. Only the latest run of
each output is recorded, so run with every job forced for a whole picture.
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path


def job_spans(workdir: Path) -> dict[tuple, tuple[str, float, float]]:
    """{job: (rule, start, end)}; a job is its rule, log files and input files."""
    jobs: dict[tuple, tuple[str, float, float]] = {}
    for record in sorted((workdir / ".snakemake" / "metadata").iterdir()):
        try:
            m = json.loads(record.read_text())
        except (ValueError, OSError):
            continue
        if m.get("starttime") is None or m.get("endtime") is None:
            continue
        key = (m["rule"], tuple(m.get("log") or ()), tuple(m.get("input") or ()))
        _, start, end = jobs.get(key, (m["rule"], m["starttime"], m["endtime"]))
        jobs[key] = (m["rule"], min(start, m["starttime"]), max(end, m["endtime"]))
    return jobs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("workdir", nargs="?", type=Path, default=Path("."))
    args = parser.parse_args()
    jobs = job_spans(args.workdir)
    if not jobs:
        raise SystemExit(f"{args.workdir}: no job times in .snakemake/metadata")
    per_rule: dict[str, list[float]] = defaultdict(list)
    for rule, start, end in jobs.values():
        per_rule[rule].append(end - start)
    total = sum(sum(times) for times in per_rule.values())
    print("| rule | jobs | mean job time | largest | share of all job time |")
    print("|---|---|---|---|---|")
    for rule, times in sorted(per_rule.items(), key=lambda kv: (-sum(kv[1]), kv[0])):
        print(
            f"| {rule} | {len(times)} | {sum(times) / len(times):.2f} s | {max(times):.2f} s "
            f"| {100 * sum(times) / total:.0f} % |"
        )
    span = max(e for _, _, e in jobs.values()) - min(s for _, s, _ in jobs.values())
    print(
        f"\n{len(jobs)} jobs, {total:.0f} s of job time, {span:.0f} s from first start to last end"
    )


if __name__ == "__main__":
    main()
