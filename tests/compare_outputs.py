"""Compare a freshly generated result file with the committed one: the text exactly, the numbers
within a tolerance.

A fresh run on another CPU gives the same tables in every word but not in every digit (numpy and
OpenBLAS pick other SIMD kernels there; see railtherm/report/tables.py), so the tests compare:

- CSV: the same header and the same rows; a cell that is a number in both files agrees
  within ``RTOL`` (relative) or ``ATOL`` (absolute), an empty cell (NaN) only with an empty
  cell, +-inf only with itself; any other cell is text and compared like prose (below).
- Markdown, LaTeX and any other text: every number is replaced by a placeholder and the text
  that is left must be identical, line by line (in Markdown and LaTeX tables cell by cell, as
  the padding that aligns a column follows the width of its numbers); the numbers, in order, agree
  within one unit of their last printed digit plus ``RTOL``: two values that differ by less
  than RTOL can round to neighbouring last digits. A number is what a reader sees as one:
  ``-1,169``, ``0.75``, ``87%`` (the ``%`` is text), ``2.95e7``, ``1.47e+07``, ``3.1×10⁷``,
  ``4.6×10^6``, ``$3.1\\times10^{7}$``, a scale ``]×10⁷`` on its own, ``∞`` and ``\\infty``. Digits
  inside a word (``Tram2``, ``fit_order1``, ``R^2``, ``m²``) are text, so a changed name fails.
  The notation of a number may change (``%g`` prints 999.4 as ``999`` and 999.6 as ``1e+03``).

Lines (rows) are paired by their text (difflib), so a line added or removed is reported once
and the lines after it are still compared with their counterparts. Every message names the
file, the line or row (with its first cells), the column and both values.

Tolerance: RTOL = 1e-4. The tables are written at 6 significant digits (a unit in the sixth
digit is 1e-6 to 1e-5 relative). Across CPUs the well-determined numbers agree to ~1e-9 and
the worst, in fits whose parameters the data do not determine, differ by up to ~5e-5
(benchmarks/cross_cpu.py measures it): RTOL covers that with a margin of two, yet is ten times
finer than the narrowest interval the study reports (0.1 % wide), so no difference that could
change a reported conclusion passes. ATOL = 1e-9 lets a number that is zero up to rounding
noise (a residual correlation, a coefficient thresholded to zero) be 0 in one file and ~1e-12
in the other. A relative error e = x / x_true - 1 (CSV columns ``rel_error``,
``<p>_rel_error``) carries the noise of x as an absolute one: there RTOL applies to 1 + e.
"""

from __future__ import annotations

import csv
import difflib
import io
import math
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

RTOL = 1e-4
ATOL = 1e-9

_SUPERSCRIPT = str.maketrans("⁰¹²³⁴⁵⁶⁷⁸⁹⁻", "0123456789-")
_EXPONENT = r"(?:\^\{[-−]?[0-9]+\}|\^[-−]?[0-9]+|⁻?[⁰¹²³⁴⁵⁶⁷⁸⁹]+)"
_SCALE = rf"(?:×|\\times\s*)10{_EXPONENT}"
_MANTISSA = r"[-−+]?(?:[0-9]{1,3}(?:,[0-9]{3})+(?:\.[0-9]+)?|[0-9]+(?:\.[0-9]+)?|\.[0-9]+)"
NUMBER = re.compile(
    rf"(?<![\w.^{{])"  # not inside a word, a decimal or an exponent
    rf"(?:(?P<mantissa>{_MANTISSA})(?P<exponent>[eE][-+]?[0-9]+|{_SCALE})?"
    rf"|(?P<scale>{_SCALE})"
    rf"|(?P<infinity>[-−+]?(?:∞|\\infty))"
    rf")(?!\w)"
)
PLACEHOLDER = "<#>"
RELATIVE_ERROR = re.compile(r"(^|_)rel_error$")
_CSV_NUMBER = re.compile(r"[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?|[-+]?inf")


@dataclass(frozen=True)
class Number:
    """A number as printed: its value and one unit of its last printed digit."""

    text: str
    value: float
    unit: float = 0.0


def parse_number(match: re.Match) -> Number:
    """The value and last-digit unit of one NUMBER match."""
    text = match.group(0)
    if match["infinity"]:
        return Number(text, -math.inf if text[0] in "-−" else math.inf)
    if match["scale"]:
        return Number(text, 10.0 ** _power(match["scale"]))
    mantissa = match["mantissa"].replace(",", "").replace("−", "-")
    decimals = len(mantissa.split(".")[1]) if "." in mantissa else 0
    value, unit = float(mantissa), 10.0**-decimals
    exponent = match["exponent"]
    if exponent:
        power = int(exponent[1:]) if exponent[0] in "eE" else _power(exponent)
        value, unit = value * 10.0**power, unit * 10.0**power
    return Number(text, value, unit)


def _power(scale: str) -> int:
    digits = scale.split("10", 1)[1].translate(_SUPERSCRIPT).strip("^{}").replace("−", "-")
    return int(digits)


def split_numbers(text: str) -> tuple[str, list[Number]]:
    """``text`` with every number replaced by PLACEHOLDER, and the numbers in order."""
    numbers: list[Number] = []

    def replace(match: re.Match) -> str:
        numbers.append(parse_number(match))
        return PLACEHOLDER

    return NUMBER.sub(replace, text), numbers


def agree(committed: Number, fresh: Number, rtol: float = RTOL, atol: float = ATOL) -> bool:
    """Whether two printed numbers can be roundings of values within rtol (or atol)."""
    a, b = committed.value, fresh.value
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    if math.isinf(a) or math.isinf(b):
        return a == b
    slack = (committed.unit + fresh.unit) / 2 + rtol * max(abs(a), abs(b)) + atol
    return abs(a - b) <= slack * (1 + 1e-12)


def relative_difference(committed: Number, fresh: Number) -> float:
    a, b = committed.value, fresh.value
    if a == b or (math.isnan(a) and math.isnan(b)):
        return 0.0
    if not (math.isfinite(a) and math.isfinite(b)):
        return math.inf
    return abs(a - b) / max(abs(a), abs(b))


@dataclass
class Comparison:
    """The outcome of comparing one file: text differences (each a message) and the pairs of
    numbers (where, committed, fresh) to be compared within the tolerance."""

    name: str
    text_differences: list[str] = field(default_factory=list)
    pairs: list[tuple[str, Number, Number]] = field(default_factory=list)

    @property
    def text_identical(self) -> bool:
        return not self.text_differences

    def max_relative_difference(self) -> float:
        return max((relative_difference(c, f) for _, c, f in self.pairs), default=0.0)

    def failures(self, rtol: float = RTOL, atol: float = ATOL) -> list[str]:
        """One message per difference: text, or a number beyond the tolerance."""
        out = [f"{self.name}, {message}" for message in self.text_differences]
        for where, c, f in self.pairs:
            if not agree(c, f, rtol, atol):
                out.append(
                    f"{self.name}, {where}: committed {c.text}, fresh {f.text} "
                    f"(relative difference {relative_difference(c, f):.2g} > rtol {rtol:g}"
                    + (f" + one unit of the last digit {max(c.unit, f.unit):g})" if c.unit else ")")
                )
        return out


# --- CSV -------------------------------------------------------------------------------------


def _csv_cell(cell: str) -> Number | None:
    if cell == "":
        return Number(cell, math.nan)
    if _CSV_NUMBER.fullmatch(cell):
        return Number(cell, float(cell))
    return None


def _csv_template(row: list[str]) -> tuple[str, ...]:
    return tuple(
        ("<empty>" if c == "" else PLACEHOLDER) if _csv_cell(c) else split_numbers(c)[0]
        for c in row
    )


def compare_csv(fresh: str, committed: str, name: str = "csv") -> Comparison:
    result = Comparison(name)
    old = list(csv.reader(io.StringIO(committed)))
    new = list(csv.reader(io.StringIO(fresh)))
    if not old or not new:
        if old != new:
            result.text_differences.append(f"committed {len(old)} lines, fresh {len(new)}")
        return result
    header = old[0]
    if new[0] != header:
        missing = [c for c in header if c not in new[0]]
        extra = [c for c in new[0] if c not in header]
        result.text_differences.append(
            f"header: committed {header}, fresh {new[0]}"
            + (f"; missing {missing}" if missing else "")
            + (f"; extra {extra}" if extra else "")
        )
        return result
    if len(new) != len(old):
        result.text_differences.append(f"committed {len(old) - 1} rows, fresh {len(new) - 1}")

    def label(row: list[str]) -> str:
        return ", ".join(row[:2])

    def compare_rows(i: int, j: int) -> None:
        row_old, row_new = old[i], new[j]
        rows = f"row {i}" + (f" (fresh row {j})" if i != j else "") + f" ({label(row_old)})"
        if len(row_old) != len(header) or len(row_new) != len(header):
            result.text_differences.append(
                f"{rows}: {len(row_old)} cells committed, {len(row_new)} fresh, "
                f"{len(header)} columns"
            )
            return
        for column, c, f in zip(header, row_old, row_new, strict=True):
            where = f"{rows}, column {column}"
            num_c, num_f = _csv_cell(c), _csv_cell(f)
            if num_c is not None and num_f is not None:
                if RELATIVE_ERROR.search(column):  # rtol applies to 1 + e
                    num_c, num_f = (Number(n.text, 1 + n.value) for n in (num_c, num_f))
                result.pairs.append((where, num_c, num_f))
            elif num_c is not None or num_f is not None:
                result.text_differences.append(f"{where}: committed {c!r}, fresh {f!r}")
            else:
                _compare_prose_cell(result, where, c, f)

    def unmatched(i1: int, i2: int, j1: int, j2: int) -> None:
        gone = [label(r) for r in old[i1:i2]]
        added = [label(r) for r in new[j1:j2]]
        result.text_differences.append(_unmatched("row", i1, i2, gone, j1, j2, added))

    _align(
        [_csv_template(r) for r in old], [_csv_template(r) for r in new], compare_rows, unmatched
    )
    return result


def _align(old: list, new: list, pair, unmatched) -> None:
    """Pair the items of two sequences by their templates (difflib), index 0 excluded (a header
    compared apart): equal runs and same-length replaced runs item by item, anything else
    reported as unmatched."""
    matcher = difflib.SequenceMatcher(None, old[1:], new[1:], autojunk=False)
    for tag, i1, i2, j1, j2 in matcher.get_opcodes():
        if tag == "equal" or (tag == "replace" and i2 - i1 == j2 - j1):
            for k in range(i2 - i1):
                pair(i1 + 1 + k, j1 + 1 + k)
        else:
            unmatched(i1 + 1, i2 + 1, j1 + 1, j2 + 1)


def _compare_prose_cell(result: Comparison, where: str, committed: str, fresh: str) -> None:
    template_c, numbers_c = split_numbers(committed)
    template_f, numbers_f = split_numbers(fresh)
    if template_c != template_f or len(numbers_c) != len(numbers_f):
        result.text_differences.append(f"{where}: committed {committed!r}, fresh {fresh!r}")
        return
    for k, (c, f) in enumerate(zip(numbers_c, numbers_f, strict=True), start=1):
        suffix = f", number {k}" if len(numbers_c) > 1 else ""
        result.pairs.append((f"{where}{suffix}", c, f))


# --- text: Markdown, LaTeX, prose ------------------------------------------------------------

_SEPARATOR_CELL = re.compile(r":?-+:?")


def _cells(line: str) -> list[str] | None:
    """The cells of a Markdown or LaTeX table row, else None."""
    stripped = line.strip()
    if stripped.startswith("|") and stripped.endswith("|") and len(stripped) > 1:
        cells = [c.strip() for c in stripped[1:-1].split("|")]
        # a separator row's dashes follow the column width: keep only the alignment
        if all(_SEPARATOR_CELL.fullmatch(c) for c in cells):
            cells = [c[0] * (c[0] == ":") + "-" + ":" * (c[-1] == ":") for c in cells]
        return cells
    if " & " in stripped and stripped.endswith("\\\\"):
        return [c.strip() for c in stripped[:-2].split("&")]
    return None


def _line_template(line: str) -> str:
    cells = _cells(line)
    if cells is not None:
        return " | ".join(split_numbers(c)[0] for c in cells)
    return split_numbers(line)[0]


def _headers(lines: list[str]) -> list[list[str] | None]:
    """For each line, the first row of the table it belongs to (its column names), or None."""
    headers: list[list[str] | None] = []
    header: list[str] | None = None
    for line in lines:
        cells = _cells(line)
        if cells is None:
            if not line.strip() or line.lstrip().startswith("\\begin{tabular"):
                header = None  # a new table follows (LaTeX rules in between keep the header)
        elif header is None or len(header) != len(cells):
            header = cells  # the first row of a table names its columns
        headers.append(header if cells is not None else None)
    return headers


def compare_text(fresh: str, committed: str, name: str = "text") -> Comparison:
    result = Comparison(name)
    old, new = committed.splitlines(), fresh.splitlines()
    if len(old) != len(new):
        result.text_differences.append(f"committed {len(old)} lines, fresh {len(new)}")
    headers = _headers(old)

    def compare_lines(i: int, j: int) -> None:
        line_c, line_f = old[i], new[j]
        at = f"line {i + 1}" + (f" (fresh line {j + 1})" if i != j else "")
        cells_c, cells_f = _cells(line_c), _cells(line_f)
        header = headers[i]
        if cells_c is None or cells_f is None or len(cells_c) != len(cells_f) or not header:
            _compare_prose_cell(result, at, line_c, line_f)
            return
        for column, c, f in zip(header, cells_c, cells_f, strict=True):
            _compare_prose_cell(result, f"{at} ({cells_c[0]}), column {column!r}", c, f)

    def unmatched(i1: int, i2: int, j1: int, j2: int) -> None:
        gone, added = old[i1 - 1 : i2 - 1], new[j1 - 1 : j2 - 1]
        result.text_differences.append(_unmatched("line", i1, i2, gone, j1, j2, added))

    # a dummy first item: _align leaves index 0 out (for the CSV header)
    _align(
        [None] + [_line_template(line) for line in old],
        [None] + [_line_template(line) for line in new],
        lambda i, j: compare_lines(i - 1, j - 1),
        unmatched,
    )
    return result


def _unmatched(
    kind: str, i1: int, i2: int, gone: list[str], j1: int, j2: int, added: list[str]
) -> str:
    """A message on a run of lines (rows) of one file that has no counterpart in the other."""

    def span(a: int, b: int, items: list[str]) -> str:
        first = items[0] if len(items[0]) <= 100 else items[0][:97] + "..."
        where = f"{kind} {a}" if b - a == 1 else f"{kind}s {a}-{b - 1}"
        return f"{where} ({first!r}" + (f" and {len(items) - 1} more)" if len(items) > 1 else ")")

    if gone and added:
        return f"committed {span(i1, i2, gone)} became fresh {span(j1, j2, added)}"
    if gone:
        return f"committed {span(i1, i2, gone)} not in the fresh file"
    return f"fresh {span(j1, j2, added)} not in the committed file"


# --- files -----------------------------------------------------------------------------------


def compare_files(fresh: Path, committed: Path, name: str | None = None) -> Comparison:
    """Compare two files by the committed one's suffix (.csv as CSV, anything else as text)."""
    name = name or str(committed)
    if not fresh.is_file():
        return Comparison(name, [f"no fresh file {fresh}"])
    new = fresh.read_text(encoding="utf-8")
    old = committed.read_text(encoding="utf-8")
    if committed.suffix == ".csv":
        return compare_csv(new, old, name)
    return compare_text(new, old, name)


def assert_outputs_agree(
    fresh_root: Path,
    committed_root: Path,
    relpaths: Iterable[str | Path],
    rtol: float = RTOL,
    atol: float = ATOL,
    limit: int = 40,
) -> None:
    """Every file of ``relpaths`` under ``fresh_root`` agrees with the one under
    ``committed_root``; else an AssertionError naming every file, row, column and value that
    differs (the first ``limit``)."""
    failures: list[str] = []
    for rel in relpaths:
        comparison = compare_files(fresh_root / rel, committed_root / rel, str(rel))
        failures += comparison.failures(rtol, atol)
    if failures:
        shown = failures[:limit]
        more = f"\n... and {len(failures) - limit} more" if len(failures) > limit else ""
        raise AssertionError(
            f"{len(failures)} differences from the committed files "
            f"(rtol {rtol:g}, atol {atol:g}):\n" + "\n".join(shown) + more
        )
