"""railtherm.io: the one reader and writer of result files."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from railtherm import io
from railtherm.errors import DataError

REPO = Path(__file__).resolve().parents[1]


def test_a_result_reads_back_as_written_in_its_key_order(tmp_path):
    data = {"vehicle": "Tram9", "k": 2.5, "reasons": [], "budget": {"u": 0.1}}
    io.write_result(data, tmp_path / "out" / "kvalue.yaml")
    back = io.read_result(tmp_path / "out" / "kvalue.yaml")
    assert back == data and list(back) == list(data)


@pytest.mark.bad_input
@pytest.mark.parametrize(
    ("text", "reason"),
    [("- a\n- b\n", "holds no mapping"), ("k: [1, 2\n", "cannot read the result file")],
    ids=["a-list", "broken-yaml"],
)
def test_a_file_that_is_no_result_is_named(tmp_path, text, reason):
    path = tmp_path / "fit_order2.yaml"
    path.write_text(text)
    with pytest.raises(DataError) as caught:
        io.read_result(path)
    assert str(caught.value).startswith(str(path)) and reason in str(caught.value)


def test_the_workflow_scripts_and_the_figures_read_results_through_io_only():
    """No other YAML reader of result files: one place decides what a result file is."""
    sources = [
        *sorted((REPO / "workflow" / "scripts").glob("*.py")),
        REPO / "railtherm" / "report" / "plots.py",
    ]
    for source in sources:
        text = source.read_text(encoding="utf-8")
        assert not re.search(r"yaml\.(safe_)?load|yaml\.safe_dump", text), source.name
