"""The README's main command run for real, from clean, in a temporary directory: a file of its
own, so that the test runner's workers take it and the other workflow runs side by side."""

from __future__ import annotations

import io
from pathlib import Path

import pytest
from compare_outputs import assert_outputs_agree
from matplotlib.image import imread
from snakemake_run import make_study, snakemake

REPO = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.workflow


def png_is_a_picture(data: bytes, min_px: int = 400) -> None:
    """A PNG of a sensible size whose pixels are not all one colour."""
    img = imread(io.BytesIO(data), format="png")
    assert img.shape[0] >= min_px and img.shape[1] >= min_px, img.shape
    grey = img[..., :3].mean(axis=2)
    assert grey.std() > 0.02 and (grey < 0.5).mean() > 0.002  # ink on the page


@pytest.mark.slow
def test_full_study_reproduces_the_committed_tables(tmp_path):
    """The README's main command, from clean, in a scratch copy: the same tables and audit as
    committed under results/tables and results/audit (the reader's copy), the text identical
    and the numbers within the tolerance of compare_outputs (another CPU moves the last
    digits), and every figure a real picture."""
    study = make_study(tmp_path)
    run = snakemake(study)
    assert run.returncode == 0, run.stderr[-3000:]
    committed = sorted((REPO / "results" / "tables").glob("*"))
    committed += sorted((REPO / "results" / "audit").glob("*"))
    assert len(committed) >= 17 + 2
    assert_outputs_agree(study, REPO, [p.relative_to(REPO) for p in committed])
    figures = sorted((study / "results").rglob("*.png"))
    assert len(figures) >= 4 + 13 + 26
    for png in figures:
        png_is_a_picture(png.read_bytes())
    again = snakemake(study)
    assert "Nothing to be done" in again.stdout + again.stderr
