"""Run the repository's Snakefile in a temporary study directory (shared by workflow tests)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def snakemake(study: Path, *args: str) -> subprocess.CompletedProcess:
    """``snakemake --directory study --cores 2 *args`` with this repository's Snakefile."""
    return subprocess.run(
        [sys.executable, "-m", "snakemake", "--snakefile", str(REPO / "Snakefile")]
        + ["--directory", str(study), "--cores", "2", *args],
        capture_output=True,
        text=True,
        timeout=600,
    )
