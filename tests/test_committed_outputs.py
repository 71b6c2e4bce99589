"""What a reader sees without running anything: the committed tables and figures."""

import csv
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from matplotlib.image import imread

from railtherm.report import tables
from railtherm.study import aggregate

REPO = Path(__file__).resolve().parents[1]
TABLES = REPO / "results" / "tables"
FIGURES = REPO / "results" / "figures"
VALIDATION = REPO / "validation" / "results"
STUDY_TABLES = ("table1", "table2", "table3", "class_summary", "class_test")


VALIDATION_FIGURES = [
    VALIDATION / "vehicles" / vid / "fit_interior_envelope.png"
    for vid in ("Armadillo", "Armadillo_solar")
]


@pytest.mark.parametrize(
    "png",
    [
        FIGURES / f"{stem}.png"
        for stem in (
            "figure3",
            "figure4",
            "figure5a",
            "figure5b",
            "sindy",
            "scenarios",
            "reference_validation",
        )
    ]
    + VALIDATION_FIGURES,
    ids=lambda p: str(p.relative_to(REPO)),
)
def test_committed_figure_is_a_legible_picture(png):
    if png.parent == FIGURES:
        assert png.with_suffix(".svg").is_file()
    img = imread(png)
    assert min(img.shape[:2]) >= 500  # paper size at 200 dpi
    grey = img[..., :3].mean(axis=2)
    assert grey.std() > 0.05, "blank or nearly blank"
    # ink in every quarter of the picture: axes, data and labels, not a lone corner
    h, w = grey.shape
    for part in (
        grey[: h // 2, : w // 2],
        grey[: h // 2, w // 2 :],
        grey[h // 2 :, : w // 2],
        grey[h // 2 :, w // 2 :],
    ):
        assert (part < 0.6).mean() > 0.001


@pytest.mark.parametrize("name", STUDY_TABLES)
def test_committed_table_names_its_data_source(name):
    csv = pd.read_csv(TABLES / f"{name}.csv")
    assert (csv["source"] == aggregate.SYNTHETIC_SOURCE).all()
    first = (TABLES / f"{name}.md").read_text(encoding="utf-8").splitlines()[0]
    assert "synthetic" in first and "not measurements" in first
    assert "synthetic" in (TABLES / f"{name}.tex").read_text(encoding="utf-8")


@pytest.mark.parametrize(
    ("folder", "names", "word"),
    [
        (TABLES, ["models"], "synthetic"),
        (VALIDATION / "tables", ["models", "reference"], "measured"),
    ],
    ids=["campaign", "validation"],
)
def test_committed_comparisons_name_their_data_source(folder, names, word):
    for name in names:
        first = (folder / f"{name}.md").read_text(encoding="utf-8").splitlines()[0]
        assert f"Data: {word}" in first, name
    sources = set(pd.read_csv(folder / "models.csv")["source"])
    assert len(sources) == 1 and word in sources.pop()


def test_adding_a_vehicle_doc_quotes_the_committed_reference_table():
    """docs/adding-a-vehicle.md copies the pySIP comparison: it must be the committed one."""
    doc = (REPO / "docs" / "adding-a-vehicle.md").read_text(encoding="utf-8")
    rows = [
        line
        for line in (VALIDATION / "tables" / "reference.md")
        .read_text(encoding="utf-8")
        .splitlines()
        if line.startswith("|")
    ]
    assert len(rows) >= 8
    for row in rows:
        assert row in doc, row
    # the model comparison is quoted with fewer columns: every quoted cell as committed
    committed = _markdown_rows((VALIDATION / "tables" / "models.md").read_text(encoding="utf-8"))
    quoted = _markdown_rows(doc.split("### Which model?", 1)[1].split("###", 1)[0])
    assert len(quoted) == len(committed) >= 9
    for key, cells in quoted.items():
        for header, cell in cells.items():
            assert committed[key][header] == cell, (key, header)


def _markdown_rows(text: str) -> dict[tuple[str, str, str], dict[str, str]]:
    """{(vehicle, model, estimator): {header: cell}} of the first Markdown table in ``text``."""
    first = text[text.index("\n|") + 1 :].split("\n\n", 1)[0]
    lines = [line for line in first.splitlines() if line.startswith("|")]
    split = [[c.strip() for c in line.strip("|").split("|")] for line in lines]
    header, rows = split[0], split[2:]
    return {(r[0], r[1], r[2]): dict(zip(header, r, strict=True)) for r in rows}


def test_committed_table3_follows_from_table2_and_the_masses():
    t2 = pd.read_csv(TABLES / "table2.csv").set_index("vehicle")
    t3 = pd.read_csv(TABLES / "table3.csv").set_index("vehicle")
    # each number is rounded to SIGNIFICANT_DIGITS, within half a unit of its last digit:
    # a quotient of two rounded numbers, compared with a third, within three such halves
    rtol = 3 * 0.5 * 10.0 ** (1 - tables.SIGNIFICANT_DIGITS)
    np.testing.assert_allclose(t3["c_veh"], t2["C_veh"] / t3["m_veh"], rtol=rtol)
    np.testing.assert_allclose(t3["delta"], t2["C_veh"] / t2["C"], rtol=rtol)
    identified = t3["delta"].notna()  # a delta the data do not determine has no value
    inside = (t3["delta_lo"] <= t3["delta"]) & (t3["delta"] <= t3["delta_hi"])
    assert inside[identified].all()


COMMITTED_CSVS = [
    *sorted(TABLES.glob("*.csv")),
    REPO / "results" / "audit" / "findings.csv",
    *sorted((VALIDATION / "tables").glob("*.csv")),
]


@pytest.mark.parametrize("path", COMMITTED_CSVS, ids=lambda p: str(p.relative_to(REPO)))
def test_committed_csv_holds_numbers_at_the_tables_precision(path):
    """Every committed CSV was written by railtherm.report.tables.write_csv (or holds no float with
    more digits): a float cell has at most SIGNIFICANT_DIGITS significant digits."""
    too_long = []
    with path.open(encoding="utf-8", newline="") as stream:
        for n, row in enumerate(csv.DictReader(stream), start=1):
            for column, cell in row.items():
                if FLOAT_CELL.fullmatch(cell or "") and significant_digits(cell) > (
                    tables.SIGNIFICANT_DIGITS
                ):
                    too_long.append(f"row {n}, {column}: {cell}")
    assert not too_long, (
        f"{len(too_long)} cells with more digits (write the table with "
        f"railtherm.report.tables.write_csv and regenerate it), first: {too_long[:3]}"
    )


FLOAT_CELL = re.compile(r"[-+]?(?:[0-9]+\.[0-9]*|\.[0-9]+|[0-9]+(?=[eE]))(?:[eE][-+]?[0-9]+)?")


def significant_digits(cell: str) -> int:
    mantissa = re.split("[eE]", cell.lstrip("+-"))[0]
    return len(mantissa.replace(".", "").lstrip("0")) or 1


def test_readme_shows_figure_5():
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    assert "](results/figures/figure5a.png)" in readme
    assert "](results/figures/figure5b.png)" in readme


def test_committed_audit_says_where_the_reestimates_come_from():
    text = (REPO / "results" / "audit" / "audit.md").read_text(encoding="utf-8")
    assert "synthetic virtual campaign" in text and "not the published measurements" in text
    findings = pd.read_csv(REPO / "results" / "audit" / "findings.csv")
    reproduction = findings[findings["family"] == "reproduction"]
    assert len(reproduction) > 0 and reproduction["message"].str.contains("synthetic").all()
