"""A starter vehicle YAML for a raw logger file: ``railtherm new-vehicle RAW``.

Any file railtherm reads is read whole (:mod:`railtherm.data.readers`: CSV, plain or gzip; a
workbook, whose table - sheet and header row - is the first row naming a time column above
rows of two values or more, on any sheet or on ``--sheet``, unless ``--header-row`` says;
MATLAB and R data), so ranges, gaps and a repeated hour anywhere in the record are seen. The
file format is detected, the rest is guessed or left as an explicit TODO:

- **preamble** of a CSV file: ``comment`` when it opens with lines starting with ``#`` or
  ``%`` (a data-acquisition system's channel list), ``header_row`` when a title or other
  lines stand above the header - the first line as wide as the table's rows;
- **separator** among ``,`` ``;`` and tab: the one that splits the table's rows alike (of
  several, the one whose header comes first), else :class:`csv.Sniffer` on the first lines
  (if it cannot decide: the candidate that splits the header into the most columns);
- **decimal mark** ``.`` or ``,``: the one with which pandas reads more columns as numbers
  (``.`` when both read alike, and always with the separator ``,``);
- **gzip** by the extension ``.gz`` (pandas reads it as :mod:`railtherm.data.rawfile` does);
- **time column**: the first column whose name looks like a time (time, zeit, date, datum,
  stamp), else the first column; its **format** is ``seconds`` if every value is a number
  (with a comment to check the unit: minutes, hours, days, epoch or serial_days read numbers
  too, and no file tells which), ``iso`` if every value is an ISO 8601 timestamp, else the
  first of :data:`railtherm.data.timeaxis.COMMON_PATTERNS` (``%d.%m.%Y %H:%M:%S`` and other
  German, British and US notations) that reads every value, each parsed by
  :func:`railtherm.data.rawfile.read_layout` exactly as the validator will; otherwise a TODO. For
  instants a commented ``timezone``/``dst`` line says how to declare a logger clock on local
  time; where the clock steps back an hour once (the end of summer time) they are declared,
  ``dst: infer`` with the zone the column's name states (``Europe/Berlin``, ``CST/CDT``,
  ``MEZ``) or a TODO;
- **channel groups** from the column names (English and German, case-insensitive), each guess
  marked ``# guessed from the column name: check``; temperatures named in °F (``[°F]``,
  ``(F)``, degF, Fahrenheit) get ``unit: degF``, those named in K or with values above 200
  ``unit: K``, power columns named with ``kW`` get ``unit: kW`` (else ``W``);
- **windows**: one identification window over the whole file, in the file's own notation (its
  first and last time as written); the static k window stays a commented-out TODO, as only
  the engineer can choose the steady part.

What no file can tell (class, mass, outer surface, air volume) is written as the placeholder
``TODO``, which ``railtherm validate`` refuses until it is replaced.
"""

from __future__ import annotations

import argparse
import csv
import gzip
import json
import os
import re
import sys
import zlib
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import pandas as pd
import yaml

from railtherm.data import timeaxis, units
from railtherm.data.ingest import CHANNEL_GROUPS
from railtherm.data.rawfile import (
    RawLayout,
    csv_error,
    parse_times,
    read_columns,
    read_layout,
    separator_hint,
)
from railtherm.data.readers import csv_layout, header_rows, read_table, reader_kind
from railtherm.errors import ConfigError, DataError
from railtherm.yamlio import packaged_schema

TODO = "TODO"
READER_WORDS = {"excel": "a workbook", "matlab": "a MATLAB file", "r": "R data"}
GUESSED = "# guessed from the column name: check"
SEPARATORS = (",", ";", "\t")
TABLE_ROWS = 3  # data rows below a workbook's header that show it heads a table
COMMENT_CHARS = ("#", "%")  # a logger preamble's comment lines (pandas: one character)
SNIFF_CHARS = 64 * 1024  # the text csv.Sniffer looks at
DECIMAL_ROWS = 5000  # rows that decide the decimal mark (the record is then read whole once)
# the zones of common abbreviations of standard and summer time in a time column's name
ZONE_ABBREVIATIONS = {
    **dict.fromkeys(("CET", "CEST", "MEZ", "MESZ"), "Europe/Berlin"),
    **dict.fromkeys(("GMT", "BST"), "Europe/London"),
    **dict.fromkeys(("EST", "EDT"), "America/New_York"),
    **dict.fromkeys(("CST", "CDT"), "America/Chicago"),
    **dict.fromkeys(("MST", "MDT"), "America/Denver"),
    **dict.fromkeys(("PST", "PDT"), "America/Los_Angeles"),
}
NAME_PATTERN = re.compile(r"^[A-Za-z][A-Za-z0-9_-]*$")  # ids and names in the schema
CLASSES = tuple(packaged_schema("vehicle")["properties"]["class"]["enum"])

_TIME_NAME = re.compile(r"time|zeit|date|datum|stamp")
# the notations tried for the time column, in this order (numbers are read as seconds)
TIME_FORMATS = ("seconds", "iso", *timeaxis.COMMON_PATTERNS)
UNIX_TIME_S = (1e8, 1e10)  # numbers in this range look like Unix time (1973 to 2286)
SERIAL_DAYS = (2e4, 8e4)  # and these, with a step below a day, like spreadsheet dates
# Channel groups in the order a name is tried: the more specific words first (a wall
# temperature is not the indoor air, a fan power is not the heater's, the cabin's air is not
# the tunnel's: "Innenluft" is indoor, "T_Luft" alone the tunnel's). A thermocouple numbered
# alone (TC01) is taken for the cabin air. Names are lowercased
# and German umlauts spelt out (Außen -> aussen, Lüfter -> luefter) before matching; short
# symbols such as T_in must stand alone ("Zeit_in" is not T_in).
_ALONE_BEFORE, _ALONE_AFTER = r"(?<![a-z])", r"(?![a-z])"
CHANNEL_WORDS: tuple[tuple[str, re.Pattern[str]], ...] = (
    (
        "irradiance",
        re.compile(rf"{_ALONE_BEFORE}i_?sol|solar|strahlung|irradian|pyrano|global_?rad"),
    ),
    ("surface", re.compile(r"surf|wall|wand|oberfl")),
    ("fan_power", re.compile(r"fan|luefter|geblaese")),
    ("heater_power", re.compile(rf"{_ALONE_BEFORE}p_?hea|heat|heiz|power|leistung")),
    (
        "indoor_air",
        re.compile(
            rf"{_ALONE_BEFORE}t_?(int|in|i){_ALONE_AFTER}|innen|cabin|kabine|indoor|inside"
            rf"|interior|raum|fahrgast|{_ALONE_BEFORE}tc_?\d"
        ),
    ),
    (
        "outdoor_air",
        re.compile(
            rf"{_ALONE_BEFORE}t_?(ext|out|amb|o){_ALONE_AFTER}|aussen|outdoor|outside|ambient"
            r"|umgebung|kanal|tunnel|chamber|kammer|luft"
        ),
    ),
)
TEMPERATURE_GROUPS = ("indoor_air", "surface", "outdoor_air")
POWER_GROUPS = ("heater_power", "fan_power", "heat_flows")
# the schema's order of the channel groups; the first, third and fourth are required
GROUP_ORDER = CHANNEL_GROUPS
REQUIRED_GROUPS = {
    "indoor_air": "the indoor air temperature sensor(s), their weighted mean is T",
    "outdoor_air": "the outdoor (tunnel) air temperature sensor(s), their weighted mean is T_o",
    "heater_power": "the heater power channel(s) in W or kW, summed into Q_H",
}
_KW = re.compile(rf"{_ALONE_BEFORE}kw{_ALONE_AFTER}")
_UMLAUTS = str.maketrans({"ä": "ae", "ö": "oe", "ü": "ue", "ß": "ss"})


@dataclass
class Detected:
    """What :func:`detect` found in a raw file.

    ``layout`` is None when no time column could be read in any notation of
    :data:`TIME_FORMATS`; ``time_problem`` then says why, and ``time_column_known`` whether
    the column or only its format is in doubt. ``sample`` holds every row, read with the
    detected separator and decimal mark.
    """

    path: str
    columns: tuple[str, ...]
    separator: str
    decimal: str
    time_column: str
    time_by_name: bool
    layout: RawLayout | None
    time_problem: str = ""
    time_column_known: bool = True  # False: the guessed column is no time (it does not increase)
    sample: pd.DataFrame = field(default_factory=pd.DataFrame)  # the whole record
    kind: str = "csv"  # the reader (railtherm.data.readers)
    given: dict[str, Any] = field(default_factory=dict)  # sheet, header_row, encoding
    repeated_hour: str | None = None  # a time the clock steps back an hour to (DST's end)
    zone: str | None = None  # the time zone the time column's name states


@dataclass
class Channel:
    """One guessed channel: its column, unit (None: the schema's default) and a comment."""

    column: str
    unit: str | None = None
    note: str = ""
    source: str | None = None  # of several sources: the one whose file holds the column


# ---------------------------------------------------------------------------------------------
# Detection


def _head_text(path: str) -> str:
    """The first lines of a plain or gzip-compressed text file (whole lines only)."""
    opener = gzip.open if path.endswith(".gz") else open
    try:
        with opener(path, "rt", encoding="utf-8", errors="replace", newline="") as stream:
            text = stream.read(SNIFF_CHARS)
    except (OSError, EOFError, zlib.error) as exc:
        raise csv_error(path, exc) from None
    if len(text) == SNIFF_CHARS and "\n" in text:
        text = text[: text.rindex("\n") + 1]
    return text


def _header_width(text: str, separator: str) -> int:
    first = text.splitlines()[0] if text.strip() else ""
    return len(next(csv.reader([first], delimiter=separator), []))


def _content(text: str, comment: str | None) -> list[tuple[int, str]]:
    """(line index from 0, line) of the lines that are neither blank nor a comment."""
    return [
        (i, line)
        for i, line in enumerate(text.splitlines())
        if line.strip() and not (comment and line.lstrip().startswith(comment))
    ]


def csv_preamble(path: str) -> dict[str, Any]:
    """What stands above a CSV file's table, as ``format`` keys: ``comment`` when the file
    opens with lines starting with one of :data:`COMMENT_CHARS` (a logger's preamble), and
    ``header_row`` when title or other lines (fewer fields than the table) stand above the
    header (its line, counted from 0 over every line), and the ``separator`` that splits the
    table's rows alike (none found: left to :func:`detect_separator`). The header is the
    first line as wide as the rows."""
    text = _head_text(path)
    lines = text.splitlines()
    comment = None
    for line in lines:
        if not line.strip():
            continue
        head = line.lstrip()[:1]
        comment = head if head in COMMENT_CHARS else None
        break
    content = _content(text, comment)
    found: dict[str, Any] = {} if comment is None else {"comment": comment}
    if len(content) < 3:
        return found
    rows = [line for _, line in content[-min(len(content) - 1, 20) :]]
    # the separator that splits the rows alike into 2 or more fields; of several, the one
    # whose header (the first line as wide) comes first: under a wrong one it is a data row
    best = None
    for separator in SEPARATORS:
        widths = {_header_width(line, separator) for line in rows}
        if len(widths) != 1 or min(widths) < 2:
            continue
        width = widths.pop()
        index = next(i for i, line in content if _header_width(line, separator) == width)
        if best is None or index < best[1]:
            best = (separator, index)
    if best is not None:
        found["separator"] = best[0]
        if best[1] != content[0][0]:
            found["header_row"] = best[1]
    return found


def detect_separator(path: str, preamble: Mapping[str, Any] | None = None) -> str:
    """``,``, ``;`` or tab, by :class:`csv.Sniffer` on the lines from the header on (the
    ``preamble`` of :func:`csv_preamble` left out); if it cannot decide, or its choice leaves
    the header one column wide, the candidate that splits the header into the most columns."""
    preamble = preamble or {}
    text = _head_text(path)
    if not text.strip():
        raise DataError(path, "", None, "the file is empty (no header line)")
    content = _content(text, preamble.get("comment"))
    skip = int(preamble.get("header_row") or 0)
    text = "\n".join(line for i, line in content if i >= skip) + "\n"
    try:
        separator = csv.Sniffer().sniff(text, delimiters="".join(SEPARATORS)).delimiter
    except csv.Error:
        separator = ""
    if separator not in SEPARATORS or _header_width(text, separator) < 2:
        separator = max(SEPARATORS, key=lambda s: _header_width(text, s))  # "," on a tie
    return separator


def _read_sample(
    path: str,
    separator: str,
    decimal: str,
    encoding: str = "utf-8",
    rows: int | None = None,
    preamble: Mapping[str, Any] | None = None,
) -> pd.DataFrame:
    """The first ``rows`` rows, or the whole record (every row: ranges, gaps and a repeated
    hour anywhere are seen), below the ``preamble`` (:func:`csv_preamble`)."""
    layout = csv_layout(preamble or {})
    try:
        return pd.read_csv(
            path,
            sep=separator,
            decimal=decimal,
            index_col=False,
            encoding=encoding,
            nrows=rows,
            **layout,
        )
    except (OSError, ValueError, EOFError, zlib.error, pd.errors.ParserError) as exc:
        raise csv_error(path, exc) from None


def _numeric_columns(sample: pd.DataFrame) -> int:
    return sum(pd.api.types.is_numeric_dtype(sample[c]) for c in sample.columns)


def detect_decimal(
    path: str,
    separator: str,
    encoding: str = "utf-8",
    preamble: Mapping[str, Any] | None = None,
) -> tuple[str, pd.DataFrame]:
    """The decimal mark with which pandas reads more columns as numbers in the first
    DECIMAL_ROWS rows (``,`` only when it reads more, ``21,5``, and the separator is not
    ``,``), and the whole record read once with it."""
    decimal = "."
    if separator != ",":
        dot, comma = (
            _read_sample(path, separator, d, encoding, DECIMAL_ROWS, preamble) for d in ".,"
        )
        decimal = "," if _numeric_columns(comma) > _numeric_columns(dot) else "."
    return decimal, _read_sample(path, separator, decimal, encoding, preamble=preamble)


def _table_sheet(path: str, sheet: str | int | None = None) -> dict[str, Any]:
    """For a workbook: the sheet (``sheet`` when given) and header row of its first table: a
    row naming a time column and another, above rows of two values or more (a workbook often
    opens with a sheet of run information, a table under a title and a blank row); empty
    when none is found (the first sheet's first row, the defaults)."""
    found = header_rows(
        path,
        lambda names: (
            sum(bool(n) for n in names) >= 2
            and any(_TIME_NAME.search(str(n).lower()) for n in names)
        ),
        sheet=sheet,
        below=TABLE_ROWS,
    )
    if not found:
        return {}
    name, row = found[0]
    return {"sheet": name if sheet is None else sheet, "header_row": row}


def _zone_from_name(column: str) -> str | None:
    """The IANA time zone a column name states: as such (``Europe/Berlin``) or by the
    abbreviations of a zone's standard and summer time (``CST/CDT``, ``MEZ``)."""
    named = re.search(
        r"(Africa|America|Antarctica|Asia|Atlantic|Australia|Europe|Indian|Pacific)/[A-Za-z_/]+",
        column,
    )
    if named:
        return named.group(0)
    for word in re.findall(r"[A-Z]{3,4}", column):
        if word in ZONE_ABBREVIATIONS:
            return ZONE_ABBREVIATIONS[word]
    return None


def _time_order(
    path: str, sample: pd.DataFrame, layout: RawLayout, decimal: str
) -> tuple[bool, str | None]:
    """Whether the time column increases strictly over the record (a channel taken for the
    time column does not), and where it does not: the time a clock on local time steps back an
    hour to (the end of summer time), as written, when that single step is the only decrease;
    else None. The column is parsed once."""
    column = layout.time_column
    tf = timeaxis.time_format(layout.time_format)
    try:
        times = parse_times(path, sample[column].astype(str), column, layout.time_format, decimal)
    except DataError:
        return False, None
    if times.is_monotonic_increasing and times.is_unique and len(times) > 1:
        return True, None
    if not tf.absolute or getattr(layout.t_first, "tzinfo", None) is not None:
        return False, None
    steps = np.diff(timeaxis.seconds(times, tf))
    back = np.flatnonzero(steps <= 0)
    step = float(np.median(steps[steps > 0])) if np.any(steps > 0) else 0.0
    if len(back) == 1 and abs(steps[back[0]] + 3600.0) <= max(2.0 * step, 1.0):
        return False, str(sample[column].iloc[back[0] + 1])
    return False, None


def detect(raw_path: str | os.PathLike[str], given: Mapping[str, Any] | None = None) -> Detected:
    """Separator, decimal mark (a CSV file), time column and format, and the time span of a
    raw file of any reader's kind (:mod:`railtherm.data.readers`). ``given``: the reader's
    settings the user knows (``sheet``, ``header_row``, ``encoding``); a workbook's sheet and
    header row are otherwise found (:func:`_table_sheet`). Every row is read.

    :class:`DataError` naming the file when it is empty, cannot be read, or has fewer than
    two columns.
    """
    path = str(raw_path)
    given = {k: v for k, v in (given or {}).items() if v is not None}
    kind = reader_kind(path, given)
    if kind == "excel" and "header_row" not in given:
        given = {**_table_sheet(path, given.get("sheet")), **given}
    if kind == "csv":
        preamble = csv_preamble(path)
        separator = preamble.pop("separator", None)
        given = {**preamble, **given}
        separator = separator or detect_separator(path, given)
        columns = read_columns(path, fmt={"separator": separator, **given})
    else:
        separator = ","
        columns = read_columns(path, fmt=given)
    if len(columns) < 2:
        reason = "the header reads as one column with each of the separators ',', ';' and tab"
        if kind != "csv":
            reason = "the table has one column: a raw file needs a time column and a channel"
        elif separator_hint(columns, separator):  # none of those, so '|' would split it
            reason += "; for a file separated by '|', write format.separator '|' by hand"
        else:
            reason += ": a raw file needs a time column and at least one channel"
        raise DataError(path, "(header)", columns[0] if columns else "", reason)
    if kind == "csv":
        decimal, sample = detect_decimal(path, separator, given.get("encoding", "utf-8"), given)
    else:
        decimal, sample = ".", read_table(path, given)
    named = [c for c in columns if _TIME_NAME.search(c.lower())]
    time_column = named[0] if named else columns[0]
    layout, problems = None, []
    for time_format in TIME_FORMATS:
        try:
            layout = read_layout(path, separator, decimal, time_column, time_format, fmt=given)
            break
        except DataError as exc:
            if exc.value is None:  # about the file (no data rows), not a time value
                raise
            problems.append(exc.value)
    problem, column_known, repeated = "", True, None
    if layout is None:
        problem = (
            f"the time column '{time_column}' holds neither numbers, ISO 8601 timestamps nor "
            f"a common date notation such as dd.mm.yyyy HH:MM:SS (for example {problems[0]!r})"
        )
    else:
        increasing, repeated = _time_order(path, sample, layout, decimal)
        if not increasing and repeated is None:
            problem = f"the column '{time_column}' does not increase from row to row"
            layout, column_known = None, False
    return Detected(
        path=path,
        columns=columns,
        separator=separator,
        decimal=decimal,
        time_column=time_column,
        time_by_name=bool(named),
        layout=layout,
        time_problem=problem,
        time_column_known=column_known,
        sample=sample,
        kind=kind,
        given=given,
        repeated_hour=repeated,
        zone=_zone_from_name(time_column),
    )


def _normalised_name(column: str) -> str:
    return column.lower().translate(_UMLAUTS)


def channel_group(column: str) -> str | None:
    """The channel group a column name suggests (None: no guess)."""
    name = _normalised_name(column)
    for group, pattern in CHANNEL_WORDS:
        if pattern.search(name):
            return group
    return None


def _values(sample: pd.DataFrame, column: str) -> pd.Series:
    if column not in sample.columns:
        return pd.Series(dtype=float)
    return pd.to_numeric(sample[column], errors="coerce").dropna()


def _range(values: pd.Series) -> str:
    if values.empty:
        return "no numeric values in the record"
    if values.min() == values.max():
        return f"value {values.min():.4g} throughout the record"
    return f"values {values.min():.4g} to {values.max():.4g}"


def guess_channels(found: Detected) -> tuple[dict[str, list[Channel]], list[str]]:
    """Channels by group from the column names, with units from the names and the values; and
    the columns left unmapped (the time column excluded)."""
    groups: dict[str, list[Channel]] = {g: [] for g in GROUP_ORDER}
    unmapped = []
    for column in found.columns:
        if column == found.time_column and found.time_column_known:
            continue
        group = channel_group(column)
        if group is None:
            unmapped.append(column)
            continue
        values = _values(found.sample, column)
        kw = bool(_KW.search(column.lower()))
        if group in TEMPERATURE_GROUPS:
            stated = units.stated_unit(column, "temperature")
            if stated == "degF":
                channel = Channel(column, "degF", f"{_range(values)} °F, as the name says")
            elif stated == "K" or (not values.empty and values.median() > 200):
                channel = Channel(column, "K", f"{_range(values)}, above 200 or named: kelvin")
            else:
                channel = Channel(column, None, f"{_range(values)} °C")
        elif group in POWER_GROUPS:
            why = "kW in the name" if kw else "no kW in the name: W"
            channel = Channel(column, "kW" if kw else "W", f"{_range(values)}, {why}")
        else:  # irradiance
            channel = Channel(column, "kW/m2" if kw else "W/m2", _range(values))
        groups[group].append(channel)
    return groups, unmapped


# ---------------------------------------------------------------------------------------------
# The YAML text


def _scalar(value: Any) -> str:
    """``value`` as a YAML scalar: plain where that reads back the same, else double-quoted
    (a JSON string is a valid YAML double-quoted scalar)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        number = float(value)
        return str(int(number)) if number.is_integer() else repr(number)
    text = str(value)
    plain = re.fullmatch(r"[A-Za-z_][A-Za-z0-9_./\-]*", text) is not None
    if plain and yaml.safe_load(text) == text:
        return text
    return json.dumps(text, ensure_ascii=False)


def _stem(path: str) -> str:
    name = os.path.basename(path)
    for ext in (".gz", ".csv", ".txt", ".dat", ".tsv"):
        if name.lower().endswith(ext):
            name = name[: -len(ext)]
    return name


def _name_from(text: str, fallback: str) -> str:
    """A name the schema accepts (letter first, then letters, digits, _ or -)."""
    name = re.sub(r"[^A-Za-z0-9_-]+", "_", text).strip("_-")
    if not name:
        return fallback
    return name if name[0].isalpha() else f"{fallback}_{name}"


def _raw_path(path: str, yaml_dir: str) -> str:
    """The raw file's path relative to the YAML's directory, as load_vehicle reads it; absolute
    when the two share no directory but the root (a relative path would only climb to it)."""
    absolute = os.path.abspath(path)
    try:
        shared = os.path.commonpath([absolute, yaml_dir])
        relative = os.path.relpath(absolute, yaml_dir)
    except ValueError:  # another drive
        return absolute
    if os.path.dirname(shared) == shared:  # only the root (or drive) in common
        return absolute
    return relative.replace(os.sep, "/")


def _time_text(value: pd.Timestamp | float, time_format: str = "iso") -> str:
    """A time of the file as a YAML scalar in the file's notation (ISO 8601 for ``iso``)."""
    if isinstance(value, pd.Timestamp):
        pattern = timeaxis.time_format(time_format).pattern
        return _scalar(value.strftime(pattern) if pattern else value.isoformat())
    return _scalar(value)


def _comment_line(key_text: str, comment: str, width: int = 30) -> str:
    return f"{key_text.ljust(width)} {comment}" if comment else key_text


class _Todos(list):
    """The TODO list: ``add`` records ``key: meaning`` and returns the YAML comment."""

    def add(self, key: str, meaning: str) -> str:
        self.append(f"{key}: {meaning}")
        return f"# TODO: {meaning}"


def _header(found: Detected) -> list[str]:
    layout = found.layout
    rows = f"{len(found.columns)} columns, all {len(found.sample):,} rows read"
    if found.kind == "csv":
        shown_sep = "\\t" if found.separator == "\t" else found.separator
        compressed = ", gzip-compressed" if found.path.endswith(".gz") else ""
        what = f"separator '{shown_sep}', decimal mark '{found.decimal}'{compressed}"
    else:
        where = ", ".join(f"{k} {v!r}" for k, v in found.given.items() if k != "encoding")
        what = f"{READER_WORDS.get(found.kind, found.kind)}" + (f" ({where})" if where else "")
    lines = [
        "# Starter vehicle file written by `railtherm new-vehicle` from",
        f"#   {found.path}",
        f"# Detected: {what}, {rows}.",
    ]
    if layout is not None:
        tf = timeaxis.time_format(layout.time_format)
        what = {"seconds": "numbers, read as elapsed seconds", "iso": "ISO 8601 timestamps"}
        what = what.get(tf.format) or f"times of the pattern {tf.pattern!r}"
        unit = " s" if tf.format == "seconds" else ""
        first, last = (_time_text(t, tf.format) for t in (layout.t_first, layout.t_last))
        lines.append(
            f"# Time: column '{found.time_column}' in {what}, from {first}{unit} to {last}{unit}."
        )
    else:
        lines.append(f"# Time: not understood: {found.time_problem}.")
    return [
        *lines,
        "# Fill in every TODO and check every line marked 'guessed', then run",
        "#   railtherm validate <this file>",
        "# Every key is explained in config/README.md.",
        "",
    ]


def _metadata(vid: str, from_file_name: bool, todos: _Todos) -> list[str]:
    origin = "from the file name; " if from_file_name else ""
    classes = f"the vehicle class, one of {', '.join(CLASSES)}"
    lines = [
        _comment_line(f"id: {_scalar(vid)}", f"# {origin}used in every output path"),
        _comment_line(f"class: {TODO}", todos.add("class", classes)),
        "# description: free text (optional)",
    ]
    for key, meaning in (
        (
            "mass_kg",
            "the vehicle mass m_veh in kg (> 0), for c_veh = C_veh / m_veh; an object of "
            "class other without a meaningful mass may delete the line",
        ),
        (
            "surface_m2",
            "A, the overall uncoiled outer surface in m2 (> 0), for k = kA / A; an object of "
            "class other may delete the line (then only kA is given)",
        ),
    ):
        lines.append(_comment_line(f"{key}: {TODO}", todos.add(key, meaning)))
    lines.append(
        "# volume_m3: the interior air volume in m3 (optional: with it, an air-node capacity "
        "below that of its air is flagged)"
    )
    return [*lines, ""]


def _format(found: Detected, todos: _Todos, prefix: str = "", multi: bool = False) -> list[str]:
    """The ``format`` section of one file; ``prefix`` goes before the keys of its TODOs (a
    source's ``sources.<name>.``), ``multi``: the file is one of several sources (its time
    must be placed on UTC)."""
    layout = found.layout
    lines = ["format:"]
    if found.kind == "csv":
        lines += [
            _comment_line(f"  separator: {json.dumps(found.separator)}", "# detected"),
            _comment_line(f'  decimal: "{found.decimal}"', "# detected"),
        ]
    for key in ("encoding", "comment", "sheet", "header_row"):
        if key in found.given:
            why = {"encoding": "# given", "comment": "# the preamble's comment lines"}.get(
                key, "# the table found (or given)"
            )
            lines.append(_comment_line(f"  {key}: {_scalar(found.given[key])}", why))
    lines += [
        "  # power_timing: instant      # optional: what a logged power value stands for:",
        "  #   instant | mean_preceding | mean_following (energy meters); see the logger's manual",
        "  time:",
    ]
    if layout is not None:
        first = "# the first column (no name looks like time): check"
        why = GUESSED if found.time_by_name else first
        lines.append(_comment_line(f"    column: {_scalar(found.time_column)}", why))
        lines += _time_format_lines(layout, found, todos, prefix, multi)
        if layout.step_s:
            lines.append(f"    # logger step: {layout.step_s:g} s (the median time difference)")
    elif not found.time_column_known:
        column = todos.add(
            f"{prefix}format.time.column", f"name the time column ({found.time_problem})"
        )
        form = todos.add(
            f"{prefix}format.time.format",
            "the notation of that column: iso, a strftime pattern, seconds, minutes, hours, "
            "days, epoch or serial_days",
        )
        lines.append(_comment_line(f"    column: {TODO}", column))
        lines.append(_comment_line(f"    format: {TODO}", form))
    else:
        meaning = (
            f"{found.time_problem}; declare its notation: iso, a strftime pattern such as "
            "'%d.%m.%Y %H:%M:%S', or a unit of numbers (seconds, minutes, hours, days, epoch, "
            "serial_days)"
        )
        lines.append(_comment_line(f"    column: {_scalar(found.time_column)}", GUESSED))
        lines.append(
            _comment_line(f"    format: {TODO}", todos.add(f"{prefix}format.time.format", meaning))
        )
    return [*lines, ""]


def _time_format_lines(
    layout: RawLayout, found: Detected, todos: _Todos, prefix: str = "", multi: bool = False
) -> list[str]:
    """``format:`` of the time column with what to check, and for instants written without a
    UTC offset the ``timezone``/``dst`` lines of a logger clock on local time: declared when
    the record repeats an hour (the end of summer time), with the zone its column's name
    states or a TODO; else commented, with that zone or an example. One of several sources
    (``multi``) must be placed on UTC: its elapsed time gets a TODO for its ``start``, its
    instants without an offset the zone its name states or UTC, guessed."""
    tf = timeaxis.time_format(layout.time_format)
    note = "# detected: every value parses"
    if tf.format == "seconds":
        first = float(layout.t_first)
        note = (
            "# detected: numbers; check the unit: seconds, minutes, hours or days elapsed, "
            "epoch (Unix seconds) or serial_days (spreadsheet dates)"
        )
        if UNIX_TIME_S[0] <= abs(first) < UNIX_TIME_S[1]:
            note += f"; {first:.10g} looks like Unix time: then epoch"
        elif SERIAL_DAYS[0] <= first < SERIAL_DAYS[1] and (layout.step_s or 1.0) < 1.0:
            note += f"; {first:.10g} looks like a spreadsheet date: then serial_days"
    elif tf.pattern and "/" in tf.pattern:
        note += "; check the order of day and month"
    lines = [_comment_line(f"    format: {_scalar(tf.format)}", note)]
    offset = getattr(layout.t_first, "tzinfo", None) is not None
    if tf.absolute and not offset and found.repeated_hour is not None:
        said = f"# the clock steps back an hour to {found.repeated_hour}: local time"
        if found.zone:
            zone = _comment_line(f"    timezone: {found.zone}", f"{said}, zone from the name")
        else:
            meaning = f"the logger clock's IANA time zone ({said[2:]})"
            zone = _comment_line(
                f"    timezone: {TODO}", todos.add(f"{prefix}format.time.timezone", meaning)
            )
        lines += [
            zone,
            _comment_line(
                "    dst: infer", "# the repeated hour read in order: first summer, then winter"
            ),
        ]
    elif tf.absolute and not offset and multi:
        said = "the zone the name states" if found.zone else "no UTC offset written: UTC"
        lines.append(
            _comment_line(
                f"    timezone: {found.zone or 'UTC'}",
                f"# guessed ({said}); this system's clock must be placed on UTC: check",
            )
        )
    elif not tf.absolute and multi:
        meaning = (
            "the instant this elapsed time's zero stands for (the system's start), ISO 8601 "
            "with its UTC offset, e.g. 2026-03-02T08:57:43+01:00"
        )
        lines.append(
            _comment_line(f"    start: {TODO}", todos.add(f"{prefix}format.time.start", meaning))
        )
    elif tf.absolute and not offset:
        example = found.zone or "Europe/Berlin"
        lines += [
            _comment_line(
                f"    # timezone: {example}", "# if the logger clock ran on local time: its zone"
            ),
            _comment_line(
                "    # dst: infer",
                "# and the rule for its hour repeated in autumn: raise | infer | earlier | later",
            ),
        ]
    return lines


def _channels(found: Detected | Mapping[str, Detected], todos: _Todos) -> list[str]:
    """The ``channels`` section guessed from the column names: of one file, or of several
    sources ({source name: what was found}), each entry then naming its source."""
    if isinstance(found, Detected):
        groups, unmapped = guess_channels(found)
    else:
        groups = {g: [] for g in GROUP_ORDER}
        unmapped = []
        for name, one in found.items():
            guessed, left = guess_channels(one)
            for group, channels in guessed.items():
                groups[group] += [replace(c, source=name) for c in channels]
            unmapped += [f"{column} ({name})" for column in left]
    block: list[tuple[str, str]] = []  # (entry, comment), the comments aligned
    for group in GROUP_ORDER:
        channels = groups[group]
        if not channels and group not in REQUIRED_GROUPS:
            continue
        block.append((f"  {group}:", ""))
        if not channels:
            meaning = f"{REQUIRED_GROUPS[group]}; no column name says so"
            block.append((f"    - {{column: {TODO}}}", todos.add(f"channels.{group}", meaning)))
        for channel in channels:
            entry = f"column: {_scalar(channel.column)}"
            if channel.unit is not None:
                entry += f", unit: {_scalar(channel.unit)}"
            if channel.source is not None:
                entry += f", source: {_scalar(channel.source)}"
            block.append((f"    - {{{entry}}}", f"{GUESSED} ({channel.note})"))
    width = max(30, *(len(entry) for entry, comment in block if comment))
    lines = ["channels:", *(_comment_line(entry, comment, width) for entry, comment in block)]
    if unmapped:
        lines.append(f"  # not mapped: {', '.join(unmapped)}")
        lines.append(
            "  # (add each that is a channel; known heat flows in W or kW go under heat_flows)"
        )
    return [*lines, ""]


def _windows(found: Detected, todos: _Todos) -> list[str]:
    lines = [
        "windows:",
        "  # kvalue:                    # TODO (optional): the steady part of the test for",
        "  #   start: ...               # the static k test (eq. 10); only you can choose it",
        "  #   end: ...",
        "  identification:              # the whole file: narrow it or split it as needed",
        "    - name: whole",
    ]
    if found.layout is not None:
        notation = found.layout.time_format
        lines.append(f"      start: {_time_text(found.layout.t_first, notation)}")
        lines.append(f"      end: {_time_text(found.layout.t_last, notation)}")
    else:
        meaning = "the window's start and end, once the time column is understood"
        lines.append(
            _comment_line(f"      start: {TODO}", todos.add("windows.identification", meaning))
        )
        lines.append(f"      end: {TODO}")
    return [*lines, ""]


def _check_inputs(paths: list[str], vehicle_id: str | None) -> None:
    """Every raw file exists; an id given is one the schema accepts."""
    for path in paths:
        if not os.path.isfile(path):
            raise ConfigError(path, "(file)", path, "file not found")
    if vehicle_id is not None and not NAME_PATTERN.match(vehicle_id):
        raise ConfigError(
            "--id",
            "id",
            vehicle_id,
            "must start with a letter and contain only letters, digits, _ or -",
        )


def starter_vehicle(
    raw_path: str | os.PathLike[str],
    vehicle_id: str | None = None,
    yaml_dir: str | os.PathLike[str] | None = None,
    given: Mapping[str, Any] | None = None,
) -> tuple[str, list[str]]:
    """The text of a starter vehicle YAML for ``raw_path`` and its TODO list.

    ``yaml_dir`` is the directory the YAML will be saved in (default: the current directory):
    ``raw_files`` gives the raw file's path relative to it, as
    :func:`railtherm.config.load_vehicle` reads it. ``given``: reader settings the user knows
    (``sheet``, ``header_row``, ``encoding``; :func:`detect`). Each TODO starts with the key
    to fill, then ``: `` and what is meant; ``railtherm validate`` refuses the file until
    every TODO is filled. The keys come in the schema's order.
    """
    path = str(raw_path)
    _check_inputs([path], vehicle_id)
    found = detect(path, given)
    stem = _stem(path)
    yaml_dir = os.path.abspath(yaml_dir if yaml_dir is not None else os.getcwd())
    todos = _Todos()
    lines = [
        *_header(found),
        *_metadata(vehicle_id or _name_from(stem, "V"), vehicle_id is None, todos),
        "raw_files:                     # relative to the directory of this file",
        f"  {_name_from(stem, 'raw')}: {_scalar(_raw_path(path, yaml_dir))}",
        "",
        *_format(found, todos),
        *_channels(found, todos),
        *_windows(found, todos),
        "# model:                       # optional; the study's defaults.model applies",
        "#   mode: joint                # kA estimated with the capacities: for a record",
        "#                              # without a steady window (windows.kvalue)",
    ]
    return "\n".join(lines) + "\n", list(todos)


def _utc_span(found: Detected) -> tuple[pd.Timestamp, pd.Timestamp] | None:
    """A file's first and last time in UTC: instants with their offset, or without one in
    the zone its time column's name states, else in UTC (as the starter proposes); None for
    elapsed time (its start is the user's to give) or times not understood."""
    layout = found.layout
    if layout is None or not layout.absolute:
        return None
    span = []
    for t in (layout.t_first, layout.t_last):
        t = pd.Timestamp(t)
        t = t.tz_localize(found.zone or "UTC") if t.tzinfo is None else t
        span.append(t.tz_convert("UTC"))
    return span[0], span[1]


def starter_sources(
    raw_paths: list[str],
    vehicle_id: str | None = None,
    yaml_dir: str | os.PathLike[str] | None = None,
    given: Mapping[str, Any] | None = None,
) -> tuple[str, list[str]]:
    """The text of a starter vehicle YAML for a record of several files, one source per file
    (:mod:`railtherm.data.sources`), and its TODO list: each file's reader settings and time
    column detected as :func:`starter_vehicle` does, its channels guessed by name and naming
    their source, an elapsed time given a TODO for its start, instants without an offset a
    guessed zone (UTC, or the one the column's name states), and the identification window
    the span every file with dates covers (UTC)."""
    _check_inputs(raw_paths, vehicle_id)
    yaml_dir = os.path.abspath(yaml_dir if yaml_dir is not None else os.getcwd())
    found: dict[str, Detected] = {}
    for i, path in enumerate(raw_paths):
        name = _name_from(_stem(path), f"source{i + 1}")
        while name in found:
            name += "_2"
        found[name] = detect(path, given)
    todos = _Todos()
    lines = [
        "# Starter vehicle file written by `railtherm new-vehicle` from a record of "
        f"{len(found)} systems, one source each:",
    ]
    for name, one in found.items():
        detected = [line for line in _header(one)[1:4] if line.startswith("# ")]
        lines += [f"# sources.{name}:", *(f"#  {line[1:]}" for line in detected)]
    lines += [
        "# Fill in every TODO and check every line marked 'guessed', then run",
        "#   railtherm validate <this file>",
        "# Every key is explained in config/README.md.",
        "",
    ]
    lines += _metadata(vehicle_id or "V", False, todos)
    lines.append("sources:                       # one per data-acquisition system")
    for name, one in found.items():
        section = _format(one, todos, prefix=f"sources.{name}.", multi=True)
        lines += [
            f"  {name}:",
            "    files:                     # relative to the directory of this file",
            f"      record: {_scalar(_raw_path(one.path, yaml_dir))}",
            *(f"    {line}" if line else line for line in section[:-1]),
            "    # clock_offset_s: 0         # how far this system's clock runs ahead of true "
            "time (s)",
        ]
    lines.append("")
    lines += _channels(found, todos)
    # a local clock whose zone is left a TODO places no instant: the window waits for it
    unplaced = [
        name
        for name, f in found.items()
        if f.layout is not None
        and f.layout.absolute
        and getattr(f.layout.t_first, "tzinfo", None) is None
        and f.repeated_hour is not None
        and not f.zone
    ]
    spans = [span for span in map(_utc_span, found.values()) if span is not None]
    if unplaced:
        spans = []
    lines += [
        "windows:                        # instants, ISO 8601 (without an offset: UTC)",
        "  # kvalue:                    # TODO (optional): the steady part of the test for",
        "  #   start: ...               # the static k test (eq. 10); only you can choose it",
        "  #   end: ...",
    ]
    if spans:
        first = max(a for a, _ in spans).strftime("%Y-%m-%dT%H:%M:%SZ")
        last = min(b for _, b in spans).strftime("%Y-%m-%dT%H:%M:%SZ")
        lines += [
            "  identification:              # the span every file with dates covers",
            "    - name: whole",
            f"      start: {_scalar(first)}",
            f"      end: {_scalar(last)}",
        ]
    else:
        meaning = "the window's start and end, as ISO 8601 instants" + (
            f", once sources.{unplaced[0]}.format.time.timezone places its clock on UTC"
            if unplaced
            else ""
        )
        lines += [
            "  identification:",
            "    - name: whole",
            _comment_line(f"      start: {TODO}", todos.add("windows.identification", meaning)),
            f"      end: {TODO}",
        ]
    lines += [
        "",
        "# model:                       # optional; the study's defaults.model applies",
        "#   mode: joint                # kA estimated with the capacities: for a record",
        "#                              # without a steady window (windows.kvalue)",
    ]
    return "\n".join(lines) + "\n", list(todos)


# ---------------------------------------------------------------------------------------------
# The command


def _run(args: argparse.Namespace) -> int:
    out = args.out
    if out is not None and os.path.exists(out):
        raise ConfigError(
            out, "(file)", out, "exists already; new-vehicle does not overwrite a file"
        )
    yaml_dir = os.path.dirname(os.path.abspath(out)) if out is not None else None
    sheet = args.sheet
    if sheet is not None and sheet.isdigit():
        sheet = int(sheet)  # a position, counted from 0, as format.sheet
    given = {"sheet": sheet, "header_row": args.header_row, "encoding": args.encoding}
    if len(args.raw) > 1:
        text, todos = starter_sources(args.raw, args.id, yaml_dir, given)
    else:
        text, todos = starter_vehicle(args.raw[0], args.id, yaml_dir, given)
    listing = [f"  {t}" for t in todos]
    if out is None:
        sys.stdout.write(text)
        # the TODO list goes to stderr so that `> VEHICLE.yaml` keeps only the YAML
        print("TODO:", *listing, sep="\n", file=sys.stderr)
        return 0
    os.makedirs(os.path.dirname(out) or ".", exist_ok=True)
    try:
        with open(out, "x", encoding="utf-8") as stream:
            stream.write(text)
    except FileExistsError:
        raise ConfigError(
            out, "(file)", out, "exists already; new-vehicle does not overwrite a file"
        ) from None
    print(f"wrote {out}")
    print(f"TODO (fill in, then run `railtherm validate {out}`):", *listing, sep="\n")
    print("Check every line marked 'guessed'; windows.kvalue is optional (see the comments).")
    return 0


def register(commands: Any) -> None:
    """Add the ``new-vehicle`` subparser to ``commands`` (an argparse subparsers object)."""
    parser = commands.add_parser(
        "new-vehicle",
        help="write a starter vehicle YAML for a raw logger file",
        description=(
            "Read a raw logger file of any kind railtherm reads (CSV, plain or .gz; a workbook; "
            "a MATLAB or R data file), all of its rows; detect the separator and decimal mark "
            "of a CSV file, a workbook's table (sheet and header row), the time format and a "
            "clock on local time (an hour repeated at the end of summer time); guess which "
            "column feeds which channel group and its unit; and write a vehicle YAML with "
            "explicit TODOs for what the file cannot tell. 'railtherm validate' accepts it "
            "once the TODOs are filled."
        ),
    )
    parser.add_argument(
        "raw",
        metavar="RAW",
        nargs="+",
        help="raw logger file: .csv/.txt (or .gz), .xlsx/.xls, .mat, .rda/.rds; several files "
        "(one per data-acquisition system of one record) give one source each",
    )
    parser.add_argument(
        "--sheet", help="a workbook's sheet: its name or position from 0 (default: found)"
    )
    parser.add_argument(
        "--header-row",
        type=int,
        metavar="N",
        help="the row of a workbook's column names, counted from 0 (default: found)",
    )
    parser.add_argument("--encoding", help="a CSV file's text encoding (default utf-8)")
    parser.add_argument(
        "--out",
        metavar="VEHICLE.yaml",
        help="file to write (never overwritten; default: print the YAML to stdout)",
    )
    parser.add_argument("--id", help="vehicle id (default: from the raw file's name)")
    parser.set_defaults(run=_run)
