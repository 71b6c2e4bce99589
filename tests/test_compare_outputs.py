"""The helper that compares fresh outputs with the committed ones (tests/compare_outputs.py):
it passes last-digit rounding noise and fails on any changed word, column or number."""

from __future__ import annotations

import math

import pytest
from compare_outputs import (
    RTOL,
    assert_outputs_agree,
    compare_csv,
    compare_text,
    split_numbers,
)
from hypothesis import given
from hypothesis import strategies as st

CSV = (
    "vehicle,order,verdict,n,C,ljung_box_p,message\n"
    'Tram1,2,fit acceptable,5,3.06484e+07,0,"k = 2.5 [2.40, 2.64]; m = 6.93 t"\n'
    "Metro3,2,assumptions in doubt,4,,1.2e-219,inf\n"
)


def failures_csv(fresh: str, committed: str = CSV) -> list[str]:
    return compare_csv(fresh, committed, "t.csv").failures()


def test_identical_csv_agrees():
    assert failures_csv(CSV) == []


def test_csv_noise_within_rtol_agrees():
    fresh = CSV.replace("3.06484e+07", "3.06499e+07").replace("1.2e-219", "1.20001e-219")
    assert failures_csv(fresh) == []
    assert failures_csv(CSV.replace(",0,", ",1e-12,")) == []  # zero up to rounding noise


def test_csv_number_beyond_rtol_names_file_row_column_and_values():
    (message,) = failures_csv(CSV.replace("3.06484e+07", "3.06584e+07"))
    assert message.startswith("t.csv, row 1 (Tram1, 2), column C: ")
    assert "committed 3.06484e+07, fresh 3.06584e+07" in message
    assert "relative difference 0.00033 > rtol 0.0001" in message


def test_relative_error_columns_compare_one_plus_the_error():
    committed = "vehicle,rel_error,C_rel_error\nTram1,0.0216147,-0.0032\n"
    fresh = committed.replace("0.0216147", "0.0216647").replace("-0.0032", "-0.00325")
    assert compare_csv(fresh, committed).failures() == []  # x moved by 5e-5 relative
    fresh = committed.replace("0.0216147", "0.0218147")
    assert compare_csv(fresh, committed).failures()


@pytest.mark.parametrize(
    "fresh",
    [
        CSV.replace("Metro3,2,", "Metro3,1,"),  # an integer
        CSV.replace(",5,", ",6,"),  # a count
        CSV.replace("Metro3,2,assumptions in doubt,4,,", "Metro3,2,assumptions in doubt,4,1e7,"),
        CSV.replace(",inf\n", ",-inf\n"),
    ],
)
def test_csv_changed_number_or_missing_value_fails(fresh):
    assert len(failures_csv(fresh)) == 1


@pytest.mark.parametrize(
    ("fresh", "where"),
    [
        (CSV.replace("fit acceptable", "fit acceptible"), "row 1 (Tram1, 2), column verdict"),
        (CSV.replace("6.93 t", "6.93 kg"), "row 1 (Tram1, 2), column message"),
        (CSV.replace("Metro3", "Metro4"), "row 2 (Metro3, 2), column vehicle"),
    ],
)
def test_csv_changed_word_fails(fresh, where):
    (message,) = failures_csv(fresh)
    assert message.startswith(f"t.csv, {where}: committed ")


def test_numbers_in_csv_text_cells_agree_within_their_last_digit():
    assert failures_csv(CSV.replace("6.93 t", "6.94 t")) == []
    (message,) = failures_csv(CSV.replace("6.93 t", "6.95 t"))
    assert "column message, number 4: committed 6.93, fresh 6.95" in message


@pytest.mark.parametrize(
    "fresh",
    [
        CSV.replace("ljung_box_p", "ljung_box"),  # renamed column
        CSV.replace("n,C", "C,n"),  # reordered columns
        CSV.replace(",message\n", "\n"),  # dropped column
    ],
)
def test_csv_changed_column_fails(fresh):
    (message,) = failures_csv(fresh)
    assert message.startswith("t.csv, header: committed ['vehicle'")


def test_csv_missing_or_added_row_is_reported_once():
    assert failures_csv(CSV.rsplit("Metro3", 1)[0]) == [
        "t.csv, committed 2 rows, fresh 1",
        "t.csv, committed row 2 ('Metro3, 2') not in the fresh file",
    ]
    tram2 = "Tram2,2,fit acceptable,5,1.2e7,0,\n"
    fresh = CSV.replace("Metro3", tram2 + "Metro3").replace("3.06484e+07", "4e7")
    assert failures_csv(fresh) == [
        "t.csv, committed 2 rows, fresh 3",
        "t.csv, fresh row 2 ('Tram2, 2') not in the committed file",
        "t.csv, row 1 (Tram1, 2), column C: committed 3.06484e+07, fresh 4e7 "
        "(relative difference 0.23 > rtol 0.0001)",
    ]


MD = """\
**Table 2. k with 95 % intervals (eqs. 7-8).** Data: synthetic.

| Name   | k (W/(m² K))     | C (J/K)                  | K_veh (W/K)       | R² (1)   |
|:-------|:-----------------|:-------------------------|:------------------|---------:|
| Tram1  | 2.5 [2.40, 2.64] | 3.1×10⁷ [2.43, 3.87]×10⁷ | 231 [73, 732]     | 1.000    |
| Metro3 | 2.9 [2.78, 3.01] | 1.0×10⁴ [0, ∞]×10⁴       | 999 [0, ∞]        | 0.999    |

- the model leaves 87% of the variance; R^2 = 0.132 < 0.9; m = 4.6×10^6 / 664 = 6.93 t.
"""


def failures_md(fresh: str, committed: str = MD) -> list[str]:
    return compare_text(fresh, committed, "t.md").failures()


def test_identical_text_agrees():
    assert failures_md(MD) == []


def test_last_digit_rounding_noise_agrees_even_where_it_changes_the_padding():
    fresh = (
        MD.replace("[2.40, 2.64]", "[2.41, 2.63]")
        .replace("3.1×10⁷", "3.2×10⁷")
        .replace("999 [0, ∞]   ", "1,000 [0, ∞]")
        .replace("87%", "86%")
        .replace("6.93 t", "6.94 t")
        .replace("|:-------|", "|:--------|")
    )
    assert failures_md(fresh) == []


@pytest.mark.parametrize(
    ("old", "new", "where", "values"),
    [
        ("2.5 [2.40", "2.5 [2.42", "line 5 (Tram1), column 'k (W/(m² K))', number 2", "2.40, 2.42"),
        ("3.1×10⁷", "3.1×10⁶", "line 5 (Tram1), column 'C (J/K)', number 1", "3.1×10⁷, 3.1×10⁶"),
        ("[0, ∞]×10⁴", "[0, 9]×10⁴", "line 6 (Metro3), column 'C (J/K)', number 3", "∞, 9"),
        ("87%", "89%", "line 8, number 1", "87, 89"),
        ("< 0.9", "< 1.9", "line 8, number 3", "0.9, 1.9"),
    ],
)
def test_text_number_beyond_its_last_digit_fails(old, new, where, values):
    (message,) = failures_md(MD.replace(old, new, 1))
    committed, fresh = values.split(", ")
    assert message.startswith(f"t.md, {where}: committed {committed}, fresh {fresh} (")


@pytest.mark.parametrize(
    ("old", "new"),
    [
        ("synthetic", "measured"),  # a word
        ("Tram1 ", "Tram2 "),  # digits inside a name are text
        ("R^2 = ", "R^3 = "),
        ("87%", "87 %"),
        ("| R² (1)   |", "| R2 (1)   |"),  # a column header
        ("|---------:|", "|:---------|"),  # a column's alignment
        ("(eqs. 7-8).**", "(eqs. 7-8)**"),  # punctuation
        ("eqs. 7-8", "eqs. 7-10"),  # an integer is a number: it may move by one unit only
    ],
)
def test_text_changed_word_or_column_fails(old, new):
    assert MD.count(old) >= 1
    assert len(failures_md(MD.replace(old, new, 1))) >= 1


def test_text_added_or_removed_line_is_reported_once():
    assert failures_md(MD + "\nmore\n") == [
        "t.md, committed 8 lines, fresh 10",
        "t.md, fresh lines 9-10 ('' and 1 more) not in the committed file",
    ]
    lines = MD.splitlines(keepends=True)
    fresh = "".join(lines[:4] + lines[5:]).replace("0.999", "0.5")
    assert failures_md(fresh) == [
        "t.md, committed 8 lines, fresh 7",
        "t.md, committed line 5 ('| Tram1  | 2.5 [2.40, 2.64] | 3.1×10⁷ [2.43, 3.87]×10⁷ "
        "| 231 [73, 732]     | 1.000    |') not in the fresh file",
        "t.md, line 6 (fresh line 5) (Metro3), column 'R² (1)': committed 0.999, fresh 0.5 "
        "(relative difference 0.5 > rtol 0.0001 + one unit of the last digit 0.1)",
    ]


LATEX = r"""\begin{tabular}{lll}
\toprule
Name & C (J/K) & verdict \\
\midrule
Tram1 & $3.1\times10^{7} [2.43, 3.87]\times10^{7}$ & fit acceptable \\
Metro3 & $1.0\times10^{4} [0, \infty]\times10^{4}$ & assumptions in doubt \\
\bottomrule
\end{tabular}
"""


def test_latex_rows_are_compared_by_column():
    assert compare_text(LATEX, LATEX).failures() == []
    assert compare_text(LATEX.replace("[2.43", "[2.44"), LATEX).failures() == []
    (message,) = compare_text(LATEX.replace("[2.43", "[2.53"), LATEX, "t.tex").failures()
    assert message.startswith(
        "t.tex, line 5 (Tram1), column 'C (J/K)', number 2: committed 2.43, fresh 2.53"
    )
    assert compare_text(LATEX.replace(r"\infty", "10"), LATEX).failures()


def test_numbers_as_a_reader_sees_them():
    text = "k 2.5, -1,169 W, 87%, 2.95e7, 1.47e+07, 3.1×10⁷, 4.6×10^6, 1.0×10⁻³, −5, ∞, Tram2"
    template, numbers = split_numbers(text)
    assert template == "k <#>, <#> W, <#>%, <#>, <#>, <#>, <#>, <#>, <#>, <#>, Tram2"
    assert [n.value for n in numbers] == pytest.approx(
        [2.5, -1169, 87, 2.95e7, 1.47e7, 3.1e7, 4.6e6, 1e-3, -5, math.inf]
    )
    assert [n.unit for n in numbers[:8]] == pytest.approx([0.1, 1, 1, 1e5, 1e5, 1e6, 1e5, 1e-4])


@given(st.floats(1e-6, 1e12), st.floats(-0.9, 0.9), st.integers(2, 6))
def test_two_values_within_rtol_agree_however_they_round(x, noise, digits):
    """Any two values that differ by less than RTOL, printed at the same precision, pass."""
    y = x * (1 + noise * RTOL)
    row = "| {} | {} |"
    fresh, committed = (f"{row.format(f'{v:.{digits}g}', f'{v:,.{digits}f}')}\n" for v in (y, x))
    assert compare_text(fresh, committed).failures() == []


def test_assert_outputs_agree_lists_every_difference(tmp_path):
    fresh, committed = tmp_path / "fresh", tmp_path / "committed"
    for root in (fresh, committed):
        root.mkdir()
        (root / "t.csv").write_text(CSV)
        (root / "t.md").write_text(MD)
    assert_outputs_agree(fresh, committed, ["t.csv", "t.md"])
    (fresh / "t.csv").write_text(CSV.replace("3.06484e+07", "4e7"))
    (fresh / "t.md").write_text(MD.replace("synthetic", "measured"))
    with pytest.raises(AssertionError) as err:
        assert_outputs_agree(fresh, committed, ["t.csv", "t.md", "gone.csv"])
    message = str(err.value)
    assert message.startswith("3 differences from the committed files (rtol 0.0001, atol 1e-09):")
    assert "t.csv, row 1 (Tram1, 2), column C: committed 3.06484e+07, fresh 4e7" in message
    assert "t.md, line 1: committed '**Table 2." in message
    assert "gone.csv, no fresh file" in message
