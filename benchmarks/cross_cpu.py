"""How far the committed tables move on another CPU: the study run natively and as on a CPU
without AVX-512, compared file by file.

    python benchmarks/cross_cpu.py [--cores 2] [--studies campaign validation] [--keep DIR]

Each study runs from clean in two scratch copies (``config/`` copied, the repo's Snakefile,
as in bench_regenerate.py; the validation study's data through a link): once natively, once
with numpy's AVX-512 kernels disabled (``NPY_DISABLE_CPU_FEATURES``) and OpenBLAS forced to
its Haswell (AVX2) kernels (``OPENBLAS_CORETYPE``), which is what a machine without AVX-512
runs. For every committed table file (``results/tables``, ``results/audit``,
``validation/results/tables``) it prints whether the text of the two runs is identical with
every number replaced by a placeholder, the largest relative difference of their numbers,
and whether each run agrees with the committed file within the tests' tolerance
(tests/compare_outputs.py). Takes about twice a full study (~5-6 min with --cores 2). A
failed job is reported, and the files it would have written show as missing.
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
sys.path.insert(0, str(REPO / "tests"))

from compare_outputs import RTOL, compare_files  # noqa: E402

OTHER_CPU = {
    "NPY_DISABLE_CPU_FEATURES": "AVX512F AVX512CD AVX512_SKX AVX512_CLX AVX512_CNL "
    "AVX512_ICL AVX512_SPR",
    "OPENBLAS_CORETYPE": "Haswell",
}
STUDIES = {
    # study: (folder holding config/ and the committed results, committed table folders)
    "campaign": (REPO, ("results/tables", "results/audit")),
    "validation": (REPO / "validation", ("results/tables",)),
}


def scratch_copy(study: str, root: Path) -> Path:
    source, _ = STUDIES[study]
    work = root / study
    shutil.copytree(source / "config", work / "config")
    if study == "validation":
        (root / "data").symlink_to(REPO / "data")  # its config reads ../data
    return work


def run(work: Path, cores: int, env: dict[str, str]) -> float:
    start = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "snakemake", "--snakefile", str(REPO / "Snakefile")]
        + ["--directory", str(work), "--cores", str(cores), "--quiet", "--keep-going"],
        capture_output=True,
        text=True,
        env={**os.environ, **env},
    )
    if proc.returncode != 0:  # compare what was written; the failed job's files show as missing
        errors = [line for line in proc.stderr.splitlines() if "Error" in line]
        print(f"warning: snakemake failed in {work}:\n  " + "\n  ".join(errors[-5:]))
    return time.perf_counter() - start


def report(study: str, native: Path, other: Path) -> int:
    """Print one line per committed file; the number of files whose text differs."""
    source, folders = STUDIES[study]
    files = sorted(p for f in folders for p in (source / f).iterdir() if p.is_file())
    print(f"\n{study}: {len(files)} committed files")
    print(f"{'file':<42} {'text':<10} {'max rel. diff.':>14}   {'native':<10} {'other CPU':<10}")
    text_differs = 0
    for committed in files:
        rel = committed.relative_to(source)
        if not ((native / rel).is_file() and (other / rel).is_file()):
            print(f"{str(rel):<42} missing (a job failed)")
            text_differs += 1
            continue
        between = compare_files(other / rel, native / rel, str(rel))
        verdicts = [
            "agrees" if not compare_files(run_dir / rel, committed).failures() else "DIFFERS"
            for run_dir in (native, other)
        ]
        text_differs += not between.text_identical
        print(
            f"{str(rel):<42} {'identical' if between.text_identical else 'DIFFERS':<10} "
            f"{between.max_relative_difference():>14.2e}   {verdicts[0]:<10} {verdicts[1]:<10}"
        )
        for message in between.text_differences[:3]:
            print(f"    {message}")
    return text_differs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cores", type=int, default=2)
    parser.add_argument("--studies", nargs="+", choices=list(STUDIES), default=list(STUDIES))
    parser.add_argument("--keep", type=Path, help="run in this directory and keep the runs")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = args.keep or Path(tmp)
        print(f"tolerance of the tests: rtol {RTOL:g}; other CPU: {OTHER_CPU}")
        text_differs = 0
        for study in args.studies:
            dirs = {}
            for label, env in (("native", {}), ("other-cpu", OTHER_CPU)):
                work = scratch_copy(study, root / label)
                print(f"{study}, {label}: {run(work, args.cores, env):.0f} s")
                dirs[label] = work
            text_differs += report(study, dirs["native"], dirs["other-cpu"])
        print(f"\n{text_differs} file(s) whose text differs between the two CPUs")


if __name__ == "__main__":
    main()
