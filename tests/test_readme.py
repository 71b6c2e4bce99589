"""The README's Python quick-start runs as written and prints what the README shows."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?")


def quick_start() -> tuple[str, str]:
    """The first ```python block of the README's "One vehicle" section and the ```text
    block that follows it."""
    text = (REPO / "README.md").read_text(encoding="utf-8")
    section = text.split("## One vehicle", 1)[1].split("\n## ", 1)[0]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    shown = re.search(r"```text\n(.*?)```", section, re.S).group(1)
    return code, shown


def test_readme_quick_start_prints_what_the_readme_shows():
    code, shown = quick_start()
    run = subprocess.run(
        [sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=False
    )
    assert run.returncode == 0, run.stderr
    got, want = run.stdout.splitlines(), shown.splitlines()
    assert len(got) == len(want), run.stdout
    for g, w in zip(got, want, strict=True):
        # the words exactly; the numbers to the printed digits (another CPU may move the last)
        assert NUMBER.sub("#", g) == NUMBER.sub("#", w), (g, w)
        for a, b in zip(NUMBER.findall(g), NUMBER.findall(w), strict=True):
            assert float(a) == pytest.approx(float(b), rel=2e-3, abs=0.051), (g, w)
