"""What one workflow job costs before it computes anything: the imports of each rule's script,
measured in fresh interpreters, side by side with another checkout of railtherm (a baseline).

For every script under workflow/scripts/ the top-level import statements are read (AST) and run
in a new ``python -c`` process, ``--rounds`` times alternating between this checkout and the
baseline (``--baseline DIR``: a checkout whose ``railtherm`` package is imported instead of
this one's, e.g. ``git worktree add /tmp/base <commit>``; a script the baseline does not have
is not timed there); the best time of each is reported,
with the interpreter's own start-up (``python -c pass``) and the scripts that draw
(matplotlib) marked. ``--snakemake`` also times a one-rule workflow whose job runs an empty
``script:``, against the same rule running ``python -c pass`` as a shell command: the cost
Snakemake adds to a script job.

    python benchmarks/bench_jobs.py [--rounds 5] [--baseline /tmp/base] [--snakemake]

prints Markdown tables; docs/performance.md quotes them.
"""

from __future__ import annotations

import argparse
import ast
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SCRIPTS = REPO / "workflow" / "scripts"


def script_imports(path: Path) -> str:
    """The top-level import statements of a script, as code."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    lines = [
        ast.unparse(node) for node in tree.body if isinstance(node, ast.Import | ast.ImportFrom)
    ]
    return "\n".join(lines) or "pass"


def _prefix(railtherm_root: Path) -> str:
    """Code that makes ``import railtherm`` find the checkout at ``railtherm_root``: an editable
    install's finder comes before PYTHONPATH on sys.meta_path, so it is taken out."""
    return (
        "import sys\n"
        "sys.meta_path[:] = [f for f in sys.meta_path "
        "if 'editable' not in getattr(f, '__module__', type(f).__module__)]\n"
        f"sys.path.insert(0, {str(railtherm_root)!r})\n"
    )


def run_once(code: str, railtherm_root: Path) -> float:
    env = dict(os.environ, MPLBACKEND="Agg")
    t0 = time.perf_counter()
    subprocess.run(
        [sys.executable, "-c", _prefix(railtherm_root) + code],
        check=True,
        env=env,
        cwd=tempfile.gettempdir(),
    )
    return time.perf_counter() - t0


def railtherm_file(railtherm_root: Path) -> str:
    """Where ``import railtherm`` resolves with :func:`_prefix` (a check of the set-up)."""
    code = _prefix(railtherm_root) + "import railtherm; print(railtherm.__file__)"
    run = subprocess.run(
        [sys.executable, "-c", code],
        check=True,
        capture_output=True,
        text=True,
        cwd=tempfile.gettempdir(),
    )
    return run.stdout.strip()


def snakemake_overhead(rounds: int) -> tuple[float, float]:
    """Best wall time (s) of `snakemake --cores 1 -F` on a one-job workflow: the job as an
    empty script, and as the shell command `python -c pass`."""
    best = {"script": float("inf"), "shell": float("inf")}
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        (root / "empty.py").write_text("pass\n")
        (root / "Snakefile").write_text(
            "rule script_job:\n    output: 'a'\n    script: 'empty.py'\n\n"
            "rule shell_job:\n    output: 'b'\n"
            f"    shell: '{sys.executable} -c pass; touch {{output}}'\n"
        )
        (root / "empty.py").write_text("open(snakemake.output[0], 'w').close()\n")
        for _ in range(rounds):
            for kind, target in (("script", "a"), ("shell", "b")):
                t0 = time.perf_counter()
                subprocess.run(
                    [sys.executable, "-m", "snakemake", "--cores", "1", "-F", target],
                    cwd=root,
                    check=True,
                    capture_output=True,
                )
                best[kind] = min(best[kind], time.perf_counter() - t0)
    return best["script"], best["shell"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--baseline", type=Path, help="a checkout of railtherm to compare with")
    parser.add_argument("--snakemake", action="store_true")
    args = parser.parse_args()
    scripts = sorted(SCRIPTS.glob("*.py"))
    codes = {"(python -c pass)": "pass"} | {p.stem: script_imports(p) for p in scripts}
    sides = {"this checkout": REPO}
    if args.baseline is not None:
        sides["baseline"] = args.baseline.resolve()
    for side, root in sides.items():
        found = railtherm_file(root)
        assert found.startswith(str(root)), (side, found)
    scripts_of = {
        side: {p.stem for p in (root / "workflow" / "scripts").glob("*.py")}
        for side, root in sides.items()
    }
    best = {(name, side): float("inf") for name in codes for side in sides}
    for _ in range(args.rounds):
        for name, code in codes.items():
            for side, root in sides.items():
                if name.startswith("(") or name in scripts_of[side]:
                    best[name, side] = min(best[name, side], run_once(code, root))
    head = "| script | draws |" + "".join(f" imports, {s} |" for s in sides)
    print(head)
    print("|---|---|" + "---|" * len(sides))
    for name, code in codes.items():
        draws = "yes" if "plots" in code or "matplotlib" in code else ""
        cells = "".join(
            f" {best[name, side]:.2f} s |" if best[name, side] < float("inf") else " (none) |"
            for side in sides
        )
        print(f"| {name} | {draws} |{cells}")
    if args.snakemake:
        script, shell = snakemake_overhead(args.rounds)
        print()
        print("| one-job workflow (`snakemake --cores 1 -F`) | wall time |")
        print("|---|---|")
        print(f"| empty `script:` job | {script:.2f} s |")
        print(f"| `shell:` job running `python -c pass` | {shell:.2f} s |")


if __name__ == "__main__":
    main()
