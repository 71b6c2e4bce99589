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


def test_readme_prediction_commands_print_what_the_readme_shows(tmp_path):
    """The README's `railtherm reference` and `railtherm simulate` commands, run on the
    committed configs and tables in a scratch directory, print its text block."""
    import shutil

    text = (REPO / "README.md").read_text(encoding="utf-8")
    section = text.split("## Predictions", 1)[1].split("\n## ", 1)[0]
    commands = re.search(r"```bash\n(.*?)```", section, re.S).group(1).splitlines()
    shown = re.search(r"```text\n(.*?)```", section, re.S).group(1)
    shutil.copytree(REPO / "config", tmp_path / "config")
    shutil.copytree(REPO / "results" / "tables", tmp_path / "results" / "tables")
    got = ""
    for command in commands:
        args = command.split()
        assert args[0] == ".venv/bin/railtherm"
        run = subprocess.run(
            [sys.executable, "-m", "railtherm", *args[1:]],
            cwd=tmp_path,
            capture_output=True,
            text=True,
            check=False,
        )
        assert run.returncode == 0, run.stderr
        got += run.stdout
    got_lines, want = got.splitlines(), shown.splitlines()
    assert len(got_lines) == len(want), got
    for g, w in zip(got_lines, want, strict=True):
        assert NUMBER.sub("#", g) == NUMBER.sub("#", w), (g, w)
        for a, b in zip(NUMBER.findall(g), NUMBER.findall(w), strict=True):
            assert float(a) == pytest.approx(float(b), rel=2e-3, abs=0.051), (g, w)
