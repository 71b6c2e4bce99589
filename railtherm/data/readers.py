"""Raw files of every kind, read as text: CSV, Excel, MATLAB and R.

:func:`read_table` gives a raw file's cells as text (missing cells NaN), whatever kind of file
it is, and :func:`read_header` its column names; the number and time parsing downstream
(:func:`railtherm.data.rawfile.parse_times`, :mod:`railtherm.data.ingest`) is the one place that
parses values. The kind of file is ``format.reader`` of the vehicle config, or by default its
suffix:

============  ====================================  ===========================================
reader        suffixes                              keys of ``format`` it reads
============  ====================================  ===========================================
``csv``       ``.csv``, ``.txt``, ``.gz``, others   ``separator``, ``encoding`` (utf-8),
                                                    ``comment`` (none), ``header_row`` (0)
``excel``     ``.xlsx``, ``.xlsm``, ``.xls``,       ``sheet`` (the first), ``header_row`` (0)
              ``.xlsb``, ``.ods``
``matlab``    ``.mat`` (v4 to v7; not v7.3)         ``variable`` (the only one), ``columns``
``r``         ``.rda``, ``.rdata``, ``.rds``        ``variable`` (the only data frame),
                                                    ``encoding`` (of strings R did not mark)
============  ====================================  ===========================================

A CSV file is read by ``pandas.read_csv(..., dtype=str)``. The other
kinds hold typed values, which are written as the text a CSV file with the vehicle's
``format.decimal`` would hold: a number as the shortest text that parses back to the same float
(``repr``), an Excel or R date as ISO 8601 text, an Excel duration as seconds. Text that
``pandas.read_csv`` takes for a missing value (``NA``, ``#N/A``, ``NaN``, an empty cell, ...) is
missing in every kind. Every problem is a :class:`~railtherm.errors.DataError` naming the file,
what is wrong and the fix; a reader whose package is missing names the extra to install
(``pip install 'railtherm[formats]'``).
"""

from __future__ import annotations

import codecs
import datetime as dt
import gzip
import hashlib
import importlib
import json
import math
import os
import warnings
import zlib
from collections import OrderedDict
from collections.abc import Hashable, Iterable, Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from railtherm.errors import DataError, first_line

__all__ = [
    "READERS",
    "csv_error",
    "csv_layout",
    "elsewhere_hint",
    "header_rows",
    "line_of",
    "read_header",
    "sheets_with",
    "read_table",
    "reader_kind",
]

READERS = ("csv", "excel", "matlab", "r")
SUFFIXES = {
    ".csv": "csv",
    ".txt": "csv",
    ".gz": "csv",
    ".xlsx": "excel",
    ".xlsm": "excel",
    ".xls": "excel",
    ".xlsb": "excel",
    ".ods": "excel",
    ".mat": "matlab",
    ".rda": "r",
    ".rdata": "r",
    ".rds": "r",
}
# the keys of `format` that only some readers read: a key given for another reader is a mistake
READER_KEYS = {
    "encoding": ("csv", "r"),
    "sheet": ("excel",),
    "header_row": ("excel", "csv"),
    "comment": ("csv",),
    "variable": ("matlab", "r"),
    "columns": ("matlab",),
}
_WHAT = {"csv": "CSV", "excel": "a spreadsheet", "matlab": "a MATLAB file", "r": "R data"}
EXTRA = "formats"
# pandas.read_csv's default missing-value strings (its documented na_values)
NA_TEXT = frozenset(
    {
        "",
        "#N/A",
        "#N/A N/A",
        "#NA",
        "-1.#IND",
        "-1.#QNAN",
        "-NaN",
        "-nan",
        "1.#IND",
        "1.#QNAN",
        "<NA>",
        "N/A",
        "NA",
        "NULL",
        "NaN",
        "None",
        "n/a",
        "nan",
        "null",
    }
)
_TEXT_DTYPE = pd.Series(["x"], dtype=str).dtype  # the dtype read_csv(dtype=str) gives


# ---------------------------------------------------------------------------------------------
# Entry points


def reader_kind(path: str | os.PathLike[str], fmt: Mapping[str, Any] | None = None) -> str:
    """``format.reader``, or the reader the file's suffix names (``csv`` for any other)."""
    fmt = fmt or {}
    kind = fmt.get("reader")
    if kind is not None:
        if kind not in READERS:
            raise DataError(
                str(path),
                "",
                None,
                f"format.reader '{kind}' is no reader; use one of {', '.join(READERS)}",
            )
        return str(kind)
    return SUFFIXES.get(os.path.splitext(str(path))[1].lower(), "csv")


# The last few files read: a fleet whose vehicles share a raw file (copies of one test, one
# record cut into several vehicles) has it parsed once per process, not once per vehicle and
# check. Kept by the file's content, so a file rewritten in place is parsed again whatever its
# times; files larger than _MEMO_BYTES are not kept (the memory is not worth it).
_MEMO: OrderedDict[Hashable, Any] = OrderedDict()
_MEMO_SIZE = 4
_MEMO_BYTES = 32 << 20


def _memo_key(what: str, path: str, fmt: Mapping[str, Any], extra: Any = None) -> Hashable | None:
    """What tells that a read would give the same result: the file (its path and the sha256 of
    its bytes), the format read with and the columns asked for; None for a file that cannot be
    read or is too large to keep (read it, and let any failure be reported as usual)."""
    try:
        if os.path.getsize(path) > _MEMO_BYTES:
            return None
        with open(path, "rb") as stream:
            digest = hashlib.file_digest(stream, "sha256").hexdigest()
    except OSError:
        return None
    options = json.dumps(fmt, sort_keys=True, default=repr)
    return (what, path, os.path.abspath(path), digest, options, extra)


def _memo(key: Hashable | None, read: Any) -> Any:
    """``read()``, or its result kept under ``key`` (the last :data:`_MEMO_SIZE` kept)."""
    if key is None:
        return read()
    if key in _MEMO:
        _MEMO.move_to_end(key)
        return _MEMO[key]
    value = _MEMO[key] = read()
    while len(_MEMO) > _MEMO_SIZE:
        _MEMO.popitem(last=False)
    return value


def read_header(
    path: str | os.PathLike[str], fmt: Mapping[str, Any] | None = None
) -> tuple[str, ...]:
    """The column names of a raw file, in file order (an empty name for an unnamed CSV column)."""
    path = str(path)
    fmt = fmt or {}
    return _memo(_memo_key("header", path, fmt), lambda: _read_header(path, fmt))


def _read_header(path: str, fmt: Mapping[str, Any]) -> tuple[str, ...]:
    kind = _kind(path, fmt)
    if kind == "csv":
        return _csv_header(path, fmt)
    if kind == "excel":
        names, _ = _excel(path, fmt, header_only=True)
        return names
    if kind == "matlab":
        return tuple(_matlab(path, fmt))
    return tuple(_r(path, fmt))


def read_table(
    path: str | os.PathLike[str],
    fmt: Mapping[str, Any] | None = None,
    columns: Iterable[str] | None = None,
) -> pd.DataFrame:
    """The cells of a raw file as text (NaN where empty), one column per column of the file in
    file order; ``columns`` reads only those (a CSV file parses no other column). A file read
    before in this process with the same format and columns, and unchanged since, is not read
    again: the caller gets a copy of the table read then."""
    path = str(path)
    fmt = fmt or {}
    wanted = None if columns is None else list(columns)
    key = _memo_key("table", path, fmt, None if wanted is None else tuple(wanted))
    return _memo(key, lambda: _read_table(path, fmt, wanted)).copy()


def _read_table(path: str, fmt: Mapping[str, Any], wanted: list[str] | None) -> pd.DataFrame:
    kind = _kind(path, fmt)
    if kind == "csv":
        return _csv_table(path, fmt, wanted)
    where: dict[str, Any] = {}
    if kind == "excel":
        names, rows = _excel(path, fmt)
        where = {"sheet": rows.sheet, "lines": rows.lines}  # the sheet's own row numbers
        data = {
            name: [row[i] if i < len(row) else None for row in rows] for i, name in names.items()
        }
    elif kind == "matlab":
        data = _matlab(path, fmt)
    else:
        data = _r(path, fmt)
    if wanted is not None:
        _check_wanted(path, wanted, tuple(data))
        data = {name: values for name, values in data.items() if name in wanted}
    decimal = fmt.get("decimal", ".")
    table = pd.DataFrame({name: _text(values, decimal) for name, values in data.items()})
    table.attrs.update(where)
    return table


def line_of(table: pd.DataFrame | pd.Series, position: int) -> str:
    """Where the data row at ``position`` is, for a message: ``line N`` of a text file (its
    header line 1), or ``row N of sheet 'S'`` of a workbook (``attrs`` of
    :func:`read_table`; blank rows left out of the table are counted)."""
    lines = table.attrs.get("lines")
    if lines is not None and 0 <= position < len(lines):
        if table.attrs.get("sheet") is None:  # a text file with comments or skipped lines
            return f"line {lines[position]}"
        return f"row {lines[position]} of sheet '{table.attrs.get('sheet')}'"
    return f"line {position + 2}"


class _Rows(list):
    """A sheet's data rows, with the sheet's name and each row's number in it (from 1)."""

    sheet: str = ""
    lines: list[int]


def csv_error(path: str, exc: Exception) -> DataError:
    """The :class:`DataError` for a file pandas cannot read as CSV (a damaged compressed file
    named as such)."""
    return _read_error(path, "csv", exc)


# ---------------------------------------------------------------------------------------------
# Shared


def _kind(path: str, fmt: Mapping[str, Any]) -> str:
    kind = reader_kind(path, fmt)
    for key, kinds in READER_KEYS.items():
        if fmt.get(key) is not None and kind not in kinds:
            readers = " or ".join(kinds)
            raise DataError(
                path,
                "",
                None,
                f"format.{key} is read by the {readers} reader only, and this file is read as "
                f"{kind} ({_why(path, fmt)}); remove format.{key} or set format.reader",
            )
    return kind


def _why(path: str, fmt: Mapping[str, Any]) -> str:
    if fmt.get("reader") is not None:
        return "format.reader"
    suffix = os.path.splitext(path)[1].lower()
    return f"by its suffix {suffix}" if suffix in SUFFIXES else "the default"


def _read_error(path: str, kind: str, exc: BaseException) -> DataError:
    if isinstance(exc, EOFError | zlib.error | gzip.BadGzipFile):
        reason = f"the compressed file is truncated or damaged ({exc}); copy it again"
    elif isinstance(exc, FileNotFoundError) and kind != "csv":
        reason = "no such file"
    else:
        reason = f"cannot read the file as {_WHAT[kind]}: {first_line(exc)}"
        if kind != "csv":
            reason += "; is format.reader right?"
        elif "Expected" in str(exc) and "fields" in str(exc):
            reason += _SHIFT_HINT
    return DataError(path, "", None, reason.splitlines()[0])


# a CSV row with more fields than its header
_SHIFT_HINT = (
    ": a decimal comma in a file separated by ',' (20,5 read as two values)? Declare the "
    "logger's format.separator (';' or tab) and format.decimal ',', or export the values quoted"
)


def _needs(module: str, package: str, path: str, kind: str) -> Any:
    """Import an optional reader's package; :class:`DataError` naming the extra without it."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise DataError(
            path,
            "",
            None,
            f"reading {_WHAT[kind]} needs the package {package}: pip install 'railtherm[{EXTRA}]'",
        ) from None


def _check_wanted(path: str, wanted: Sequence[str], names: Sequence[str]) -> None:
    for name in wanted:
        if name not in names:
            raise DataError(path, name, None, f"no such column (columns: {', '.join(names)})")


def _number(value: float, decimal: str) -> str:
    text = repr(float(value))
    return text.replace(".", decimal) if decimal != "." else text


def _cell(value: Any, decimal: str) -> str | None:
    """One typed value as the text a CSV file would hold (None: missing)."""
    if value is None or value is pd.NA or value is pd.NaT:
        return None
    if isinstance(value, str):
        return None if value in NA_TEXT else value
    if isinstance(value, bool | np.bool_):
        return str(bool(value))
    if isinstance(value, int | np.integer):
        return str(int(value))
    if isinstance(value, float | np.floating):
        return None if math.isnan(value) else _number(value, decimal)
    if isinstance(value, dt.datetime):  # before date: a datetime is a date
        return value.isoformat()
    if isinstance(value, dt.date):  # a spreadsheet's date or midnight timestamp
        return f"{value.isoformat()}T00:00:00"
    if isinstance(value, dt.time):
        return value.isoformat()
    if isinstance(value, dt.timedelta):  # a spreadsheet's duration: seconds
        return _number(value.total_seconds(), decimal)
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    return str(value)


def _text(values: Any, decimal: str) -> pd.Series:
    """A column of typed values as a text Series (the dtype ``read_csv(dtype=str)`` gives)."""
    if isinstance(values, pd.Series):
        numeric = values.dtype.kind in "fiu" and isinstance(values.dtype, np.dtype)
        values = values.to_numpy() if numeric else values.to_numpy(dtype=object, na_value=None)
    if isinstance(values, np.ndarray) and values.dtype.kind == "f":
        cells = [None if v != v else _number(v, decimal) for v in values.tolist()]
    elif isinstance(values, np.ndarray) and values.dtype.kind in "iu":
        cells = [str(v) for v in values.tolist()]
    else:
        cells = [_cell(v, decimal) for v in values]
    return pd.Series(np.array(cells, dtype=object), dtype=object).astype(_TEXT_DTYPE)


# ---------------------------------------------------------------------------------------------
# CSV


def _encoding(path: str, fmt: Mapping[str, Any]) -> str:
    encoding = fmt.get("encoding") or "utf-8"
    try:
        codecs.lookup(encoding)
    except LookupError:
        raise DataError(
            path,
            "",
            None,
            f"format.encoding '{encoding}' is no known text encoding; use for example utf-8, "
            "cp1252 or latin-1",
        ) from None
    return encoding


def _decode_error(path: str, encoding: str, exc: UnicodeDecodeError) -> DataError:
    byte = exc.object[exc.start : exc.start + 1].hex() if exc.object else "?"
    return DataError(
        path,
        "",
        None,
        f"the file is not {encoding} text (byte 0x{byte} at position {exc.start}); set "
        "format.encoding to its encoding (cp1252 or latin-1 for many Windows exports)",
    )


_CSV_ERRORS = (OSError, ValueError, EOFError, zlib.error, pd.errors.ParserError)


def csv_layout(fmt: Mapping[str, Any]) -> dict[str, Any]:
    """read_csv's arguments for ``format.comment`` (a line starting with it is skipped, text
    after it ignored) and ``format.header_row`` (the line of the column names, counted from
    0 over every line of the file: the lines above it are skipped, comment or not)."""
    kwargs: dict[str, Any] = {}
    if fmt.get("comment") is not None:
        kwargs["comment"] = fmt["comment"]
    if fmt.get("header_row"):
        kwargs["skiprows"] = int(fmt["header_row"])
    return kwargs


def _csv_header(path: str, fmt: Mapping[str, Any]) -> tuple[str, ...]:
    encoding = _encoding(path, fmt)
    sep = fmt.get("separator", ",")
    try:
        header = pd.read_csv(
            path, sep=sep, header=None, nrows=1, dtype=str, encoding=encoding, **csv_layout(fmt)
        )
    except pd.errors.EmptyDataError:
        if fmt.get("header_row") or fmt.get("comment"):
            row = int(fmt.get("header_row") or 0)
            comment = fmt.get("comment")
            what = "blank" if comment is None else f"blank or a comment ('{comment}')"
            raise DataError(
                path,
                "format.header_row",
                row,
                f"no line at or after line {row + 1} (counted from 0: {row}) that is not "
                f"{what}: set format.header_row to the line of the column names",
            ) from None
        raise DataError(path, "", None, "the file is empty (no header line)") from None
    except UnicodeDecodeError as exc:
        raise _decode_error(path, encoding, exc) from None
    except _CSV_ERRORS as exc:
        raise csv_error(path, exc) from None
    return tuple("" if pd.isna(c) else str(c) for c in header.iloc[0])


def _csv_lines(path: str, fmt: Mapping[str, Any], encoding: str, rows: int) -> list[int]:
    """The line number (from 1) of each data row of a CSV file read with ``format.comment``
    or ``format.header_row``: the lines after the header that are neither blank nor a
    comment, as read_csv keeps them."""
    comment = fmt.get("comment")
    header = int(fmt.get("header_row") or 0)
    opener = gzip.open if path.endswith(".gz") else open
    numbers: list[int] = []
    seen_header = False
    with opener(path, "rt", encoding=encoding, newline="") as stream:
        for number, line in enumerate(stream, start=1):
            if number <= header:
                continue
            text = line.split(comment, 1)[0] if comment else line
            if not text.strip():
                continue
            if not seen_header:
                seen_header = True
                continue
            numbers.append(number)
            if len(numbers) == rows:
                break
    return numbers


def _csv_table(path: str, fmt: Mapping[str, Any], columns: list[str] | None) -> pd.DataFrame:
    encoding = _encoding(path, fmt)
    sep = fmt.get("separator", ",")
    # index_col=False: a separator at the end of every row must not shift the columns
    kwargs: dict[str, Any] = {"sep": sep, "dtype": str, "index_col": False, "encoding": encoding}
    layout = csv_layout(fmt)
    kwargs.update(layout)
    if columns is not None:
        kwargs["usecols"] = columns
    try:
        with warnings.catch_warnings():  # a row longer than the header: values lost, refused
            warnings.simplefilter("error", pd.errors.ParserWarning)
            table = pd.read_csv(path, **kwargs)
        if layout:  # data rows below comments or skipped lines: their own numbers
            table.attrs["lines"] = _csv_lines(path, fmt, encoding, len(table))
        return table
    except pd.errors.ParserWarning:
        raise DataError(
            path, "", None, f"a data row has more fields than the header{_SHIFT_HINT}"
        ) from None
    except pd.errors.EmptyDataError:
        raise DataError(path, "", None, "the file is empty (no header line)") from None
    except UnicodeDecodeError as exc:
        raise _decode_error(path, encoding, exc) from None
    except ValueError as exc:
        if columns is not None and str(exc).startswith("Usecols do not match"):
            _check_wanted(path, columns, _csv_header(path, fmt))
        raise csv_error(path, exc) from None
    except _CSV_ERRORS as exc:
        raise csv_error(path, exc) from None


# ---------------------------------------------------------------------------------------------
# Excel (python-calamine: the Rust calamine reader)


def _empty(value: Any) -> bool:
    return value is None or (isinstance(value, str) and value == "")


def _header_name(value: Any) -> str:
    """A header cell as a column name: a whole number without ``.0`` (a column named 101)."""
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    return _cell(value, ".") or ""


def _excel(
    path: str, fmt: Mapping[str, Any], header_only: bool = False
) -> tuple[Any, list[list[Any]]]:
    """``(names, rows)``: with ``header_only`` the tuple of column names, else a mapping of
    each named column's position to its name and the data rows below the header (blank rows
    left out, as read_csv leaves out blank lines). Columns without a name are left out."""
    calamine = _needs("python_calamine", "python-calamine", path, "excel")
    sheet = fmt.get("sheet", 0)
    header_row = int(fmt.get("header_row", 0))
    try:
        book = calamine.CalamineWorkbook.from_path(path)
    except Exception as exc:  # calamine's own errors: not a workbook, damaged, encrypted
        raise _read_error(path, "excel", exc) from None
    try:
        sheets = [s.name for s in book.sheets_metadata if s.typ == calamine.SheetTypeEnum.WorkSheet]
        listed = ", ".join(f"'{s}'" for s in sheets)
        if isinstance(sheet, int):
            if not 0 <= sheet < len(sheets):
                raise DataError(
                    path,
                    "",
                    None,
                    f"no sheet {sheet} (format.sheet counts from 0; the workbook has "
                    f"{len(sheets)}: {listed}); set format.sheet to one of them",
                )
            name = sheets[sheet]
        else:
            name = str(sheet)
            if name not in sheets:
                raise DataError(
                    path,
                    "",
                    None,
                    f"no sheet '{name}' (sheets: {listed}); set format.sheet to one of them",
                )
        try:
            rows = book.get_sheet_by_name(name).to_python(
                skip_empty_area=False, nrows=header_row + 1 if header_only else None
            )
        except Exception as exc:
            raise _read_error(path, "excel", exc) from None
    finally:
        book.close()
    if len(rows) <= header_row:
        where = "is empty" if not rows else f"has {len(rows)} rows"
        raise DataError(
            path,
            "",
            None,
            f"sheet '{name}' {where}, no header in row {header_row + 1} (format.header_row "
            f"{header_row}, counted from 0); set format.header_row to the row of the names",
        )
    names = {i: _header_name(v) for i, v in enumerate(rows[header_row])}
    names = {i: n for i, n in names.items() if n != ""}
    if header_only:
        return tuple(names.values()), []
    data = _Rows()
    data.sheet, data.lines = name, []
    for number, row in enumerate(rows[header_row + 1 :], start=header_row + 2):
        if not all(_empty(v) for v in row):
            data.append(row)
            data.lines.append(number)
    return names, data


def sheets_with(path: str | os.PathLike[str], column: str, rows: int = 30) -> list[tuple[str, int]]:
    """The worksheets of a workbook whose first ``rows`` rows hold a cell named ``column``,
    each with that row (counted from 0, as ``format.header_row``): where a column missing
    from the declared sheet is. Empty for any other file, or a workbook that cannot be read."""
    return header_rows(path, lambda names: column in names, rows)


def _is_value(cell: Any) -> bool:
    """A cell a data row holds: a number, a date or a duration (not text, not empty)."""
    return isinstance(cell, int | float | dt.date | dt.time | dt.timedelta) and not isinstance(
        cell, bool
    )


def _table_below(head: list[list[Any]], row: int, below: int) -> bool:
    """Whether the ``below`` non-empty rows under ``row`` each hold two values or more (a
    table's data rows, not a sheet of run information with a value per line)."""
    found = 0
    for cells in head[row + 1 :]:
        if all(_empty(v) for v in cells):
            continue
        if sum(_is_value(v) for v in cells) < 2:
            return False
        found += 1
        if found == below:
            return True
    return False


def header_rows(
    path: str | os.PathLike[str],
    test: Any,
    rows: int = 30,
    sheet: str | int | None = None,
    below: int = 0,
) -> list[tuple[str, int]]:
    """Per worksheet of a workbook (only ``sheet``, a name or position, when given), the first
    of its first ``rows`` rows whose cells, read as column names, pass ``test`` (a callable on
    the list of names) and, with ``below``, stand above that many data rows of two values or
    more: (sheet, row counted from 0). Empty for any other file, or a workbook that cannot be
    read."""
    path = str(path)
    if reader_kind(path) != "excel":
        return []
    try:
        calamine = importlib.import_module("python_calamine")
        book = calamine.CalamineWorkbook.from_path(path)
    except Exception:  # no reader or no workbook: the caller's own message stands
        return []
    found = []
    try:
        sheets = [m.name for m in book.sheets_metadata if m.typ == calamine.SheetTypeEnum.WorkSheet]
        if sheet is not None:
            sheets = [
                name
                for i, name in enumerate(sheets)
                if sheet == name or (isinstance(sheet, int) and sheet == i)
            ]
        for name in sheets:
            head = book.get_sheet_by_name(name).to_python(
                skip_empty_area=False, nrows=rows + (below + 5 if below else 0)
            )
            for r, row in enumerate(head[:rows]):
                if test([_header_name(v) for v in row]) and (
                    not below or _table_below(head, r, below)
                ):
                    found.append((name, r))
                    break
    except Exception:
        return found
    finally:
        book.close()
    return found


def elsewhere_hint(path: str | os.PathLike[str] | None, column: str) -> str:
    """For a column missing from the declared sheet of a workbook, where it is and the settings
    to read it there ("it is on sheet 'Data', row 2: set format.sheet ..."); else ""."""
    found = sheets_with(path, column) if path else []
    if not found:
        return ""
    sheet, row = found[0]
    return (
        f"it is on sheet '{sheet}', row {row + 1}: set format.sheet: {sheet!r} and "
        f"format.header_row: {row} (counted from 0); "
    )


# ---------------------------------------------------------------------------------------------
# MATLAB (scipy.io.loadmat: level 4 and 5 files, which MATLAB writes up to -v7)

_NAME_FIELDS = ("colheaders", "VariableNames", "names", "columns")


def _matlab(path: str, fmt: Mapping[str, Any]) -> dict[str, Any]:
    """The columns of ``format.variable`` of a .mat file: name -> values."""
    from scipy.io import loadmat, whosmat
    from scipy.io.matlab import matfile_version

    try:
        major, _ = matfile_version(path)
    except Exception as exc:  # not a .mat file, truncated, missing
        raise _read_error(path, "matlab", exc) from None
    if major == 2:
        raise DataError(
            path,
            "",
            None,
            "a MATLAB v7.3 (HDF5) file, which railtherm does not read; save it again as a "
            "v7 file: save(file, 'name', '-v7')",
        )
    try:
        found = {name: (shape, cls) for name, shape, cls in whosmat(path)}
    except Exception as exc:
        raise _read_error(path, "matlab", exc) from None
    variable = fmt.get("variable")
    listed = ", ".join(found) or "none"
    if variable is None:
        if len(found) != 1:
            raise DataError(
                path,
                "",
                None,
                f"the file holds {len(found)} variables ({listed}); set format.variable to "
                "the one with the data",
            )
        variable = next(iter(found))
    elif variable not in found:
        raise DataError(
            path,
            "",
            None,
            f"no variable '{variable}' (variables: {listed}); set format.variable to one of them",
        )
    try:
        value = loadmat(path, variable_names=[variable], simplify_cells=True)[variable]
    except Exception as exc:
        raise _read_error(path, "matlab", exc) from None
    shape, cls = found[variable]
    names = fmt.get("columns")
    if isinstance(value, dict):
        if "data" in value and (names or any(f in value for f in _NAME_FIELDS)):
            label = next((value[f] for f in _NAME_FIELDS if f in value), None)
            return _matrix(path, variable, np.asarray(value["data"]), names or _strings(label))
        if names:
            raise DataError(
                path,
                "",
                None,
                f"'{variable}' is a struct whose fields are the columns; remove format.columns "
                "(it names the columns of a matrix)",
            )
        return _struct_columns(path, variable, value)
    if isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
        return _struct_rows(path, variable, value)  # a struct array: one element per row
    if isinstance(value, np.ndarray) and value.dtype.kind in "biuf":
        return _matrix(path, variable, value.reshape(shape), names)
    raise DataError(
        path,
        "",
        None,
        f"'{variable}' is a MATLAB {cls}, not a struct of columns nor a numeric matrix; in "
        "MATLAB, save a table T as s = table2struct(T, 'ToScalar', true) with datetimes as "
        "text (string(t, 'yyyy-MM-dd''T''HH:mm:ss')) or seconds",
    )


def _strings(value: Any) -> list[str] | None:
    if value is None:
        return None
    if isinstance(value, str):
        return [value]
    return [str(v) for v in np.asarray(value, dtype=object).ravel()]


def _matrix(path: str, variable: str, value: np.ndarray, names: Sequence[str] | None) -> dict:
    if value.ndim == 1:
        value = value.reshape(-1, 1)
    if value.ndim != 2 or value.dtype.kind not in "biuf":
        raise DataError(path, "", None, f"'{variable}' is no 2-D numeric matrix")
    rows, width = value.shape
    if not names:
        raise DataError(
            path,
            "",
            None,
            f"'{variable}' is a matrix of {rows} rows and {width} columns without column "
            f"names; name them in format.columns ({width} names, in order)",
        )
    if len(names) != width:
        transposed = " (is it transposed? one row per sample)" if len(names) == rows else ""
        raise DataError(
            path,
            "",
            None,
            f"format.columns names {len(names)} columns, '{variable}' has {width}{transposed}; "
            "give one name per matrix column",
        )
    return {str(name): value[:, i] for i, name in enumerate(names)}


def _column(path: str, variable: str, field: str, value: Any) -> Any:
    """One struct field as a column: a numeric vector or a list of texts."""
    if isinstance(value, str):
        return [value]
    if isinstance(value, list):
        return value
    if isinstance(value, int | float | bool | np.generic):
        return np.asarray([value])
    if isinstance(value, np.ndarray) and (value.ndim <= 1 or max(value.shape) == value.size):
        if value.dtype.kind in "biufOU":
            return value.ravel()
    raise DataError(
        path,
        field,
        None,
        f"field of '{variable}' is no column (a vector of numbers or texts; got "
        f"{type(value).__name__} {getattr(value, 'shape', '')}); a struct's fields must "
        "each be one column",
    )


def _struct_columns(path: str, variable: str, value: dict[str, Any]) -> dict[str, Any]:
    columns = {field: _column(path, variable, field, v) for field, v in value.items()}
    lengths = {field: len(v) for field, v in columns.items()}
    if len(set(lengths.values())) > 1:
        first = next(iter(lengths))
        odd = next(f for f, n in lengths.items() if n != lengths[first])
        raise DataError(
            path,
            odd,
            None,
            f"field of '{variable}' has {lengths[odd]} values where '{first}' has "
            f"{lengths[first]}; every field must be one column of the same length",
        )
    return columns


def _struct_rows(path: str, variable: str, value: list[dict[str, Any]]) -> dict[str, Any]:
    names = list(value[0])
    for row in value:
        if list(row) != names:
            raise DataError(path, "", None, f"the elements of '{variable}' differ in fields")
    columns = {}
    for name in names:
        cells = [row[name] for row in value]
        if any(isinstance(c, np.ndarray) and c.size != 1 for c in cells):
            raise DataError(
                path, name, None, f"field of '{variable}' holds more than one value per element"
            )
        columns[name] = [c.item() if isinstance(c, np.ndarray) else c for c in cells]
    return columns


# ---------------------------------------------------------------------------------------------
# R (rdata: .rda/.RData workspaces and .rds single objects)


def _posixct(obj: Any, attrs: Mapping[str, Any]) -> np.ndarray:
    """R's date-time (seconds since 1970 UTC) as ISO text: in its time zone with the UTC
    offset when it has one, else the UTC wall time without an offset."""
    tz = attrs.get("tzone")
    tz = str(np.asarray(tz, dtype=object).ravel()[0]) if tz is not None and len(tz) else ""
    seconds = np.asarray(obj, dtype=float)
    stamps = pd.to_datetime(seconds, unit="s", utc=True).round("us")
    if tz:
        stamps = stamps.tz_convert(tz)
    else:
        stamps = stamps.tz_localize(None)
    return np.array([None if pd.isna(s) else s.isoformat() for s in stamps], dtype=object)


def _rdate(obj: Any, attrs: Mapping[str, Any]) -> np.ndarray:
    """R's date (days since 1970-01-01) as ISO text."""
    days = np.asarray(obj, dtype=float)
    stamps = pd.to_datetime(days, unit="D")
    return np.array([None if pd.isna(s) else s.date().isoformat() for s in stamps], dtype=object)


def _r(path: str, fmt: Mapping[str, Any]) -> dict[str, Any]:
    """The columns of the data frame of an .rds file, or of ``format.variable`` (by default
    the only data frame) of an .rda file: name -> values."""
    rdata = _needs("rdata", "rdata", path, "r")
    constructors = {**rdata.conversion.DEFAULT_CLASS_MAP, "POSIXct": _posixct, "Date": _rdate}
    rds = os.path.splitext(path)[1].lower() == ".rds"
    read = rdata.read_rds if rds else rdata.read_rda
    kwargs: dict[str, Any] = {"constructor_dict": constructors}
    if fmt.get("encoding"):
        kwargs["default_encoding"] = _encoding(path, fmt)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # classes without a constructor: their values
            found = read(path, **kwargs)
    except Exception as exc:  # rdata's own errors: not R data, damaged, unknown object
        raise _read_error(path, "r", exc) from None
    variable = fmt.get("variable")
    if not isinstance(found, dict):  # an .rds file: one object
        if variable is not None:
            raise DataError(
                path,
                "",
                None,
                "an .rds file holds one object, no variables; remove format.variable",
            )
        frame, what = found, "the object"
    else:
        listed = ", ".join(found) or "none"
        frames = [name for name, v in found.items() if isinstance(v, pd.DataFrame)]
        if variable is None:
            if len(frames) != 1:
                raise DataError(
                    path,
                    "",
                    None,
                    f"the file holds {len(frames)} data frames ({', '.join(frames) or 'none'}; "
                    f"objects: {listed}); set format.variable to the one with the data",
                )
            variable = frames[0]
        elif variable not in found:
            raise DataError(
                path,
                "",
                None,
                f"no object '{variable}' (objects: {listed}); set format.variable to one of them",
            )
        frame, what = found[variable], f"'{variable}'"
    if not isinstance(frame, pd.DataFrame):
        raise DataError(
            path,
            "",
            None,
            f"{what} is a {type(frame).__name__}, not a data frame; save a data.frame "
            "(as.data.frame(x)) with one column per channel",
        )
    return {str(name): frame[name] for name in frame.columns}
