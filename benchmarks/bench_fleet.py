"""What a fleet costs the workflow before any job runs: ``snakemake --dry-run`` of studies of N
copies of a measured vehicle, side by side with bare Snakefiles planning the same jobs.

The fleet is N copies of the validation study's Armadillo Box (validation/config/vehicles/
Armadillo.yaml: measured data, three structures by two estimators, six fits a vehicle), of two
kinds (``--fleets``):

- ``own``: each copy reads its own copy of the real raw file (data/armadillo/
  armadillo_data_H2.csv), so that the parse-time checks read N files as they would a real
  fleet's;
- ``shared``: every copy reads the one raw file, as copies of a vehicle config made to try a
  fleet do.

Per vehicle the workflow plans one clean job, one identify and one check job (each over the six
fits) and one figure job.

Each study is dry-run twice: first with no ``.snakemake/`` (cold: railtherm's parse caches
empty, every vehicle validated and its raw file read), then again (warm: the caches under
``.snakemake/railtherm/`` filled by the first parse; the best of two runs). Beside it, best of
two runs each:

- the bare one-rule Snakefile: rule ``job`` writing ``out/{i}.txt`` and the target rule
  ``all``, as many jobs as railtherm plans, the job a ``script:`` (as railtherm's jobs are;
  Snakemake reads a script's source per job) and, in the next column, a ``shell:`` command;
- the bare Snakefile of the same DAG: rules clean, identify, check, figures, fit_table,
  compare_models and all with railtherm's inputs and outputs per job, ``script:`` jobs, but
  no railtherm code, no params, logs, resources or conda environment. What Snakemake itself
  spends on a DAG of this shape (railtherm's jobs have several input files each, the one-rule
  jobs one).

Wall time, CPU time (user + sys) and peak memory (max RSS of the process and its children)
come from ``os.wait4``; the table is printed in Markdown. On a machine other work loads, the
ratio of CPU times (of the runs with the best wall time) is the steadier comparison.

    python benchmarks/bench_fleet.py [--sizes 10 100 1000] [--fleets own shared] [--keep DIR]
    python benchmarks/bench_fleet.py --full 100      # run a 100-vehicle study on 2 cores

``--full N`` runs the whole study of N vehicles from clean (``--cores 2``, or ``--cores``) and
reports wall time and the CPU seconds of snakemake and all its jobs (user + sys), in total and
per vehicle: the marginal cost of one more vehicle. ``--figures off`` sets ``study.figures:
false`` (no per-vehicle figures) in either mode.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]
VEHICLE = REPO / "validation" / "config" / "vehicles" / "Armadillo.yaml"
RAW = REPO / "data" / "armadillo" / "armadillo_data_H2.csv"

BARE_ONE_RULE = """\
# A bare workflow: one rule, as many jobs as config["jobs"] (plus the target rule all).
rule all:
    input:
        expand("out/{{i}}.txt", i=range(config["jobs"])),


rule job:
    output:
        "out/{{i}}.txt",
    {job}
"""

BARE_SAME_DAG = """\
# A bare workflow with the DAG of railtherm's for a fleet of Armadillo copies: the same jobs,
# with the same input and output files, but script jobs without params, logs or resources.
V = config["vehicles"]
KEYS = config["keys"]
ORDERS = [key for key in KEYS if key in ("order1", "order2")]
FIGURES = [f"fit_{{key}}" for key in KEYS]
FIGURES += [f"innovations_{{key}}" for key in KEYS if key.endswith("_kalman")]
FIG = expand("results/vehicles/{{{{vehicle}}}}/{{f}}.{{e}}", f=FIGURES, e=("png", "svg"))
FITS = expand("results/vehicles/{{{{vehicle}}}}/identify/{{k}}.yaml", k=KEYS)
FITS += expand("results/vehicles/{{{{vehicle}}}}/identify/{{k}}_series.csv", k=KEYS)


rule all:
    input:
        {raw_all}
        expand("results/vehicles/{{v}}/clean/h2.csv", v=V),
        expand("results/vehicles/{{v}}/fit_{{k}}.yaml", v=V, k=KEYS),
        "results/tables/identification.csv",
        {figures}
        expand("results/tables/models.{{e}}", e=("csv", "md")),


rule clean:
    input:
        {raw},
    output:
        "results/vehicles/{{vehicle}}/clean/h2.csv",
    script:
        "job.py"


rule identify:
    input:
        "results/vehicles/{{vehicle}}/clean/h2.csv",
    output:
        FITS,
    script:
        "job.py"


rule check:
    input:
        FITS,
    output:
        expand("results/vehicles/{{{{vehicle}}}}/fit_{{k}}.yaml", k=KEYS),
    script:
        "job.py"


rule figures:
    input:
        expand("results/vehicles/{{{{vehicle}}}}/identify/{{k}}_series.csv", k=KEYS),
        expand("results/vehicles/{{{{vehicle}}}}/fit_{{k}}.yaml", k=KEYS),
    output:
        FIG,
    script:
        "job.py"


rule fit_table:
    input:
        expand("results/vehicles/{{v}}/fit_{{k}}.yaml", v=V, k=ORDERS),
    output:
        "results/tables/identification.csv",
    script:
        "job.py"


rule compare_models:
    input:
        expand("results/vehicles/{{v}}/fit_{{k}}.yaml", v=V, k=KEYS),
    output:
        expand("results/tables/models.{{e}}", e=("csv", "md")),
    script:
        "job.py"
"""


@dataclass
class Run:
    """One measured process: wall time (s), peak RSS (MB), user + sys CPU time (s)."""

    wall: float
    rss_mb: float
    cpu: float
    output: str


def measured(cmd: list[str], cwd: Path, env: dict[str, str] | None = None) -> Run:
    """Run ``cmd`` and take its resource use from ``os.wait4``: the peak RSS and CPU times
    cover the process and every descendant it waited for (the jobs of snakemake)."""
    with tempfile.TemporaryFile(mode="w+") as log:
        start = time.perf_counter()
        proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=log, stderr=subprocess.STDOUT)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - start
        proc.returncode = os.waitstatus_to_exitcode(status)
        log.seek(0)
        output = log.read()
    if proc.returncode != 0:
        sys.exit(f"failed in {cwd}: {' '.join(cmd)}\n{output[-3000:]}")
    return Run(wall, usage.ru_maxrss / 1024, usage.ru_utime + usage.ru_stime, output)


def best(runs: list[Run]) -> Run:
    return min(runs, key=lambda run: run.wall)


def vehicle_ids(n: int) -> list[str]:
    return [f"Armadillo{i:04d}" for i in range(1, n + 1)]


def raw_path(fleet: str, vid: str) -> str:
    """A vehicle's raw file in the study directory: its own copy, or the one file all share."""
    return f"data/{vid}/{RAW.name}" if fleet == "own" else f"data/armadillo/{RAW.name}"


def make_fleet(root: Path, n: int, figures: bool = True, fleet: str = "own") -> Path:
    """A study directory of ``n`` copies of the Armadillo Box, each reading its own copy of the
    measured raw file (``fleet`` "own") or all reading the one file (``fleet`` "shared");
    returns the study directory (the working directory of snakemake)."""
    study = root / "study"
    vehicles_dir = study / "config" / "vehicles"
    vehicles_dir.mkdir(parents=True)
    template = yaml.safe_load(VEHICLE.read_text(encoding="utf-8"))
    paths = []
    for vid in vehicle_ids(n):
        raw = study / raw_path(fleet, vid)
        if not raw.exists():
            raw.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(RAW, raw)
        vehicle = dict(template, id=vid)
        vehicle["raw_files"] = {"h2": f"../../{raw_path(fleet, vid)}"}
        (vehicles_dir / f"{vid}.yaml").write_text(
            yaml.safe_dump(vehicle, sort_keys=False), encoding="utf-8"
        )
        paths.append(f"config/vehicles/{vid}.yaml")
    config = {
        "campaign": None,
        "vehicles": paths,
        "study": {
            "figure3": None,
            "figure4": [],
            "paper_tables": False,  # Tables 1-3 are about rail vehicle classes
        },
        "sindy": {"enabled": False},  # no surface sensors
        "audit": {"published": None},
    }
    if not figures:
        config["study"]["figures"] = False
    (study / "config" / "config.yaml").write_text(
        yaml.safe_dump(config, sort_keys=False), encoding="utf-8"
    )
    return study


def model_keys() -> list[str]:
    """The fits of the Armadillo Box (railtherm.study.fitsettings.model_keys of its config)."""
    sys.path.insert(0, str(REPO))
    from railtherm.study.fitsettings import model_keys as keys

    return keys(yaml.safe_load(VEHICLE.read_text(encoding="utf-8")))


def railtherm_env() -> dict[str, str]:
    """The environment of a run: this checkout's railtherm first on the path."""
    env = dict(os.environ)
    env["PYTHONPATH"] = f"{REPO}{os.pathsep}{env.get('PYTHONPATH', '')}"
    env["MPLBACKEND"] = "Agg"
    return env


def railtherm_snakemake(study: Path, *args: str, cores: int = 2) -> list[str]:
    return [sys.executable, "-m", "snakemake", "--snakefile", str(REPO / "Snakefile")] + [
        "--directory",
        str(study),
        "--cores",
        str(cores),
        *args,
    ]


def bare_snakemake(*args: str) -> list[str]:
    return [sys.executable, "-m", "snakemake", "--cores", "2", "--dry-run", "--quiet", *args]


def job_total(output: str) -> int:
    """The total of the 'Job stats' table of a dry run."""
    found = re.search(r"^total\s+(\d+)\s*$", output, re.MULTILINE)
    if not found:
        sys.exit(f"no job stats in:\n{output[-2000:]}")
    return int(found.group(1))


def dry_runs(root: Path, n: int, figures: bool, fleet: str = "own") -> dict[str, Run | int]:
    """Cold and warm dry runs of a fleet of ``n``, and of the bare workflows of as many jobs:
    ``snakemake --dry-run --quiet``, planning without listing the jobs or summing up their
    reasons (the job counts come from one more, untimed run with the job stats)."""
    study = make_fleet(root / "fleet", n, figures, fleet)
    env = railtherm_env()
    quiet = ("--dry-run", "--quiet")
    out: dict[str, Run | int] = {}
    out["cold"] = measured(railtherm_snakemake(study, *quiet), study, env)
    out["warm"] = best([measured(railtherm_snakemake(study, *quiet), study, env) for _ in "ab"])
    stats = measured(railtherm_snakemake(study, "--dry-run", "--quiet", "rules"), study, env)
    out["jobs"] = jobs = job_total(stats.output)
    for kind, job in (
        ("script", 'script:\n        "job.py"'),
        ("shell", 'shell:\n        "touch {output}"'),
    ):
        bare = root / f"bare_{kind}"
        bare.mkdir()
        (bare / "Snakefile").write_text(BARE_ONE_RULE.format(job=job), encoding="utf-8")
        (bare / "job.py").write_text("open(snakemake.output[0], 'w').close()\n")
        cmd = bare_snakemake("--config", f"jobs={jobs - 1}")
        out[kind] = best([measured(cmd, bare, env) for _ in "ab"])
    same = root / "bare_same_dag"
    same.mkdir()
    fig = 'expand("results/vehicles/{v}/{f}.{e}", v=V, f=FIGURES, e=("png", "svg")),'
    if fleet == "own":
        raw, raw_all = f'"data/{{vehicle}}/{RAW.name}"', f'expand("data/{{v}}/{RAW.name}", v=V),'
    else:
        raw = f'"{raw_path(fleet, "")}"'
        raw_all = f"{raw},"
    text = BARE_SAME_DAG.format(figures=fig if figures else "", raw=raw, raw_all=raw_all)
    if not figures:
        text = text[: text.index("rule figures:")] + text[text.index("rule fit_table:") :]
    (same / "Snakefile").write_text(text, encoding="utf-8")
    (same / "job.py").write_text("pass\n")
    for vid in vehicle_ids(n):
        (same / raw_path(fleet, vid)).parent.mkdir(parents=True, exist_ok=True)
        (same / raw_path(fleet, vid)).touch()
    (same / "config.yaml").write_text(
        yaml.safe_dump({"vehicles": vehicle_ids(n), "keys": model_keys()}), encoding="utf-8"
    )
    cmd = bare_snakemake("--configfile", "config.yaml")
    out["same"] = best([measured(cmd, same, env) for _ in "ab"])
    stats = measured(bare_snakemake("--configfile", "config.yaml", "--quiet", "rules"), same, env)
    assert job_total(stats.output) == jobs, ("same DAG", job_total(stats.output), jobs)
    return out


def full_run(root: Path, n: int, figures: bool, cores: int, fleet: str = "own") -> None:
    """The whole study of ``n`` vehicles from clean; CPU seconds per vehicle."""
    study = make_fleet(root / "fleet", n, figures, fleet)
    env = railtherm_env()
    dry = measured(
        railtherm_snakemake(study, "--dry-run", "--quiet", "rules", cores=cores), study, env
    )
    run = measured(railtherm_snakemake(study, "--quiet", cores=cores), study, env)
    again = measured(railtherm_snakemake(study, cores=cores), study, env)
    assert "Nothing to be done" in again.output, again.output[-2000:]
    print("| vehicles | jobs | cores | wall | CPU (user + sys) | CPU per vehicle | peak RSS |")
    print("|---|---|---|---|---|---|---|")
    print(
        f"| {n} | {job_total(dry.output)} | {cores} | {run.wall:.0f} s | {run.cpu:.0f} s | "
        f"{run.cpu / n:.1f} s | {run.rss_mb:.0f} MB |"
    )
    print(f"\nno-op rerun: {again.wall:.1f} s; dry run before the run: {dry.wall:.1f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10, 100, 1000])
    parser.add_argument("--full", type=int, metavar="N", help="run a whole study of N vehicles")
    parser.add_argument("--cores", type=int, default=2)
    parser.add_argument("--figures", choices=["on", "off"], default="on")
    parser.add_argument("--keep", type=Path, help="build the studies here and keep them")
    parser.add_argument(
        "--fleets",
        nargs="+",
        choices=["own", "shared"],
        default=["own", "shared"],
        help="own: each copy reads its own copy of the raw file; shared: all read the one file",
    )
    args = parser.parse_args()
    figures = args.figures == "on"
    with tempfile.TemporaryDirectory() as tmp:
        base = args.keep or Path(tmp)
        if args.full:
            full_run(base / f"full{args.full}", args.full, figures, args.cores, args.fleets[0])
            return
        print(
            "| fleet | vehicles | jobs | railtherm cold | railtherm warm | bare one-rule, script "
            "| warm / bare | bare one-rule, shell | bare same DAG | warm / same DAG "
            "| CPU warm / same DAG | peak RSS warm | peak RSS bare script |"
        )
        print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
        for fleet in args.fleets:
            for n in args.sizes:
                r = dry_runs(base / f"{fleet}{n}", n, figures, fleet)
                warm, script, shell, same = r["warm"], r["script"], r["shell"], r["same"]
                print(
                    f"| {fleet} | {n} | {r['jobs']} | {r['cold'].wall:.1f} s | {warm.wall:.1f} s "
                    f"| {script.wall:.1f} s | {warm.wall / script.wall:.2f} | {shell.wall:.1f} s "
                    f"| {same.wall:.1f} s | {warm.wall / same.wall:.2f} "
                    f"| {warm.cpu / same.cpu:.2f} | {warm.rss_mb:.0f} MB "
                    f"| {script.rss_mb:.0f} MB |",
                    flush=True,
                )


if __name__ == "__main__":
    main()
