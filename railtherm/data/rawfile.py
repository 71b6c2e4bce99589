"""What the validator needs to know of a raw file: its columns and the time span it covers.

A layout comes either from reading an existing file (:func:`read_layout`, in railtherm.config's
checks) or, for files the virtual climatic wind tunnel has not written yet, from the campaign
(:func:`railtherm.synth.planned_layouts`). Both give the same answer for the same file.
Files of every kind the vehicle's ``format`` declares (CSV, Excel, MATLAB, R) are read by
:mod:`railtherm.data.readers`.
"""

from __future__ import annotations

import atexit
import hashlib
import json
import os
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from railtherm.data import timeaxis

# csv_error stays importable from here, where it was before railtherm.data.readers
from railtherm.data.readers import csv_error as csv_error
from railtherm.data.readers import elsewhere_hint, read_header, read_table
from railtherm.errors import DataError


@dataclass(frozen=True)
class RawLayout:
    """Columns and time span of one raw file.

    ``time_format`` is the declared ``format.time.format`` (:mod:`railtherm.data.timeaxis`).
    ``t_first``/``t_last`` are ``pandas.Timestamp`` for a format of instants (iso, a strftime
    pattern, epoch, serial_days; in UTC when the file's times carry an offset or a declared
    ``format.time.timezone``) and float seconds for elapsed time (seconds, minutes, hours,
    days: converted to seconds); ``step_s`` the logger's median step in seconds (None where
    unknown).
    """

    path: str
    columns: tuple[str, ...]
    time_column: str
    time_format: str
    t_first: pd.Timestamp | float
    t_last: pd.Timestamp | float
    step_s: float | None = None
    gap_s: float | None = None  # the longest time between two rows (a typo makes it years)

    @property
    def absolute(self) -> bool:
        """True when the file's times are instants (``pandas.Timestamp``)."""
        return timeaxis.time_format(self.time_format).absolute

    def seconds(self, t: pd.Timestamp | float) -> float:
        """A time of this file as seconds since its first row."""
        if self.absolute:
            return float((t - self.t_first).total_seconds())
        return float(t) - float(self.t_first)


# Rows of a tidy table (or of a raw record completed to its logger step) beyond which a window
# or a file is taken for a mistake (a step of 0.01 s, a year typo in a timestamp) and refused
# before anything is allocated: a year at one second is 3e7 rows.
MAX_ROWS = 5_000_000
# A raw record completed to its logger step may hold more (a long record at 1 Hz, resampled by
# cleaning.step_s), unless one jump between two rows explains its span: a typo
MAX_RAW_ROWS = 40_000_000  # 15 months at 1 s
TYPO_GAP_S = 30 * 86_400.0  # a jump between two rows longer than any pause of a test
MIN_WINDOW_STEPS = 3  # a window needs at least this many logger steps: a fit and its tests


def _format(fmt: Mapping[str, Any] | None, **given: Any) -> dict[str, Any]:
    """``fmt`` (a vehicle's ``format`` section) with the keys given as arguments (not None)
    put over it, and the defaults of separator and decimal."""
    out = {"separator": ",", "decimal": ".", **(fmt or {})}
    out.update({key: value for key, value in given.items() if value is not None})
    return out


def read_columns(
    path: str | os.PathLike[str],
    separator: str | None = None,
    *,
    fmt: Mapping[str, Any] | None = None,
) -> tuple[str, ...]:
    """Column names of a raw file: the header line of a plain or gzip-compressed CSV file
    (``separator``, default ``,``), or of a file of any kind ``fmt`` (a vehicle's ``format``
    section: ``reader``, ``encoding``, ``sheet``, ... see :mod:`railtherm.data.readers`) declares.

    Raises :class:`DataError` naming the file when it cannot be read, is empty, or has a
    column name twice (a channel map could not tell the two apart).
    """
    path = str(path)
    columns = read_header(path, _format(fmt, separator=separator))
    seen: set[str] = set()
    for column in columns:
        if column in seen:
            raise DataError(path, column, column, "the header names this column twice")
        seen.add(column)
    return columns


def separator_hint(columns: tuple[str, ...], separator: str) -> str:
    """A hint when a header read with ``separator`` came out as one column that another
    common separator would split: "the header reads as one column; is format.separator ';'?"
    (empty when there is nothing to suggest)."""
    if len(columns) != 1:
        return ""
    for other in (";", "\t", ",", "|"):
        if other != separator and other in columns[0]:
            shown = "\\t" if other == "\t" else other
            return f"the header reads as one column; is format.separator '{shown}'? "
    return ""


def read_layout(
    path: str | os.PathLike[str],
    separator: str | None = None,
    decimal: str | None = None,
    time_column: str | None = None,
    time_format: str | None = None,
    *,
    fmt: Mapping[str, Any] | None = None,
) -> RawLayout:
    """Columns and time span of a raw file, reading its header and only its time column.

    ``fmt`` is a vehicle's ``format`` section (the kind of file and how to read it, see
    :mod:`railtherm.data.readers`; its ``time`` gives the time column, format, timezone and DST
    rule); the arguments given put their value over it (CSV: ``separator`` default ``,``,
    ``decimal`` default ``.``). ``time_format`` is any notation of :mod:`railtherm.data.timeaxis`:
    ``"iso"`` or a strftime pattern, ``"epoch"``, ``"epoch_ms"`` or ``"serial_days"``
    (instants, returned as ``pandas.Timestamp``), or ``"seconds"``, ``"minutes"``,
    ``"hours"``, ``"days"`` (elapsed time, returned as float seconds); ``decimal`` is
    honoured. Plain and ``.gz`` CSV files are
    read alike. Raises :class:`DataError` naming the file when it cannot be read, the time
    column is missing, or a time value cannot be parsed (naming the first bad value and its
    line); ValueError for a time format that is none of these.
    """
    fmt = _format(fmt, separator=separator, decimal=decimal)
    time = dict(fmt.get("time") or {})
    time_column = time_column if time_column is not None else time.get("column")
    time_format = time_format if time_format is not None else time.get("format")
    if time_column is None or time_format is None:
        raise TypeError("read_layout() needs time_column and time_format")
    tf = timeaxis.time_format({**time, "format": time_format})
    decimal = fmt["decimal"]
    path = str(path)
    columns = read_columns(path, fmt=fmt)
    if time_column not in columns:
        hint = elsewhere_hint(path, time_column)
        raise DataError(
            path, time_column, None, f"no such column ({hint}columns: {', '.join(columns)})"
        )
    raw = read_table(path, fmt, columns=[time_column])[time_column]
    if raw.empty:
        raise DataError(path, time_column, None, "the file has a header but no data rows")
    times = parse_times(path, raw, time_column, tf, decimal)
    steps = np.diff(timeaxis.seconds(times, tf))
    first, last = times.iloc[0], times.iloc[-1]
    return RawLayout(
        path=path,
        columns=columns,
        time_column=time_column,
        time_format=tf.format,
        t_first=first if tf.absolute else float(first),
        t_last=last if tf.absolute else float(last),
        step_s=float(np.median(steps)) if steps.size else None,
        gap_s=float(np.max(steps)) if steps.size else None,
    )


def parse_times(
    path: str,
    raw: pd.Series,
    time_column: str,
    time_format: str | Mapping[str, Any] | timeaxis.TimeFormat,
    decimal: str,
) -> pd.Series:
    """Parse a time column by :func:`railtherm.data.timeaxis.parse`: ``pandas.Timestamp`` for
    instants, float seconds for elapsed time. ``time_format`` is a format name, a config's
    ``format.time`` mapping or a :class:`~railtherm.data.timeaxis.TimeFormat`. :class:`DataError`
    naming the first value that does not parse and its line."""
    if not isinstance(time_format, timeaxis.TimeFormat):
        time_format = timeaxis.time_format(time_format)
    return timeaxis.parse(path, raw, time_column, time_format, decimal)


class DigestCache:
    """Content digests of raw files (sha256 of the bytes), kept in a JSON file and reused while
    a file's size, mtime, ctime and inode are unchanged.

    A workflow that reruns on file times alone misses a raw file replaced by other content
    with the same mtime (a copy with ``cp -p``, a restored backup); the digest does not. The
    ctime cannot be set back by a user, so a replaced file is hashed again even when its size
    and mtime are the old ones."""

    def __init__(self, path: str | os.PathLike[str] | None = None):
        self.path = None if path is None else os.path.abspath(path)  # cwd may change by exit
        self.entries: dict[str, list] = {}
        self._dirty = False
        if self.path and os.path.isfile(self.path):
            try:
                with open(self.path, encoding="utf-8") as stream:
                    self.entries = json.load(stream)
            except (OSError, ValueError):
                self.entries = {}  # a broken cache is only a cache

    def digest(self, file: str | os.PathLike[str]) -> str:
        """``sha256:<hex>`` of the file's bytes; ``missing`` for a file that does not exist."""
        name = os.path.abspath(file)
        try:
            st = os.stat(name)
        except FileNotFoundError:
            return "missing"
        key = [st.st_size, st.st_mtime_ns, st.st_ctime_ns, st.st_ino]
        cached = self.entries.get(name)
        if cached and cached[:4] == key:
            return cached[4]
        h = hashlib.sha256()
        with open(name, "rb") as stream:
            for block in iter(lambda: stream.read(1 << 20), b""):
                h.update(block)
        value = f"sha256:{h.hexdigest()}"
        self.entries[name] = [*key, value]
        if self.path and not self._dirty:  # written once, when the process ends
            atexit.register(self.save)
        self._dirty = True
        return value

    def save(self) -> None:
        """Write the cache (done at exit after new digests; a failure costs only time)."""
        if not self.path or not self._dirty:
            return
        self._dirty = False
        try:
            os.makedirs(os.path.dirname(self.path) or ".", exist_ok=True)
            tmp = f"{self.path}.{os.getpid()}.tmp"
            with open(tmp, "w", encoding="utf-8") as stream:
                json.dump(self.entries, stream)
            os.replace(tmp, self.path)
        except OSError:
            pass  # an unwritable cache costs time, not correctness
