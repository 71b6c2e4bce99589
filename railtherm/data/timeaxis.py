"""The time column of a raw file, in whatever notation the logger wrote it.

A vehicle config declares ``format.time.format``:

- ``iso``: ISO 8601 timestamps (``2024-01-15T08:30:00``, with or without a UTC offset);
- a strftime pattern, e.g. ``"%d.%m.%Y %H:%M:%S"`` (any string with a ``%`` directive);
- ``seconds``, ``minutes``, ``hours`` or ``days``: time elapsed since some start;
- ``epoch``: seconds since 1970-01-01 00:00 UTC (Unix time);
- ``serial_days``: a spreadsheet's serial day number (days since 1899-12-30, the 1900 date
  system of Excel and LibreOffice; the fraction is the time of day).

The first four name absolute instants (:attr:`TimeFormat.absolute`), parsed into
``pandas.Timestamp``; elapsed times become float seconds. ``format.time.timezone`` (an IANA name
such as ``Europe/Berlin``) says that wall-clock times without an offset are local time: they
are converted to UTC, so that the hour repeated at the end of daylight-saving time does not
run backwards. That repeated hour is ambiguous and the hour skipped at its start does not
exist; ``format.time.dst`` declares the rule for both (``raise``, the default: an error naming
the time; ``infer``: the repeated hour from the order of the rows, the skipped hour cannot
occur in a real log and stays an error; ``earlier`` / ``later``: take the first or second
occurrence). Parsing is pandas' and zoneinfo's; nothing here reads dates by hand.

:func:`declared` checks a config's ``format.time``; :func:`parse` reads a time column and
:func:`seconds` puts it on the seconds axis of the cleaning (seconds since the first row for
instants); :func:`instant` reads a window bound; :func:`recognise` names the notation values
are written in, and :func:`fix` the likely fix for a value that does not match the declared
notation.
"""

from __future__ import annotations

import datetime as dt
import difflib
import math
import re
import zoneinfo
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from railtherm.data.readers import line_of
from railtherm.errors import ConfigError, DataError

ELAPSED_UNITS_S = {"seconds": 1.0, "minutes": 60.0, "hours": 3600.0, "days": 86400.0}
NAMED_ABSOLUTE = ("iso", "epoch", "epoch_ms", "serial_days")
EPOCHS = {"epoch": 1e6, "epoch_ms": 1e3}  # microseconds per counted unit since 1970 UTC
LAST_YEAR = 2200  # an instant after this year is a unit mistake (epoch milliseconds read as s)
SERIAL_DAY_ORIGIN = pd.Timestamp("1899-12-30")  # day 0 of the 1900 date system
DST_RULES = ("raise", "infer", "earlier", "later")
ACCEPTED = (
    "iso, a strftime pattern such as '%d.%m.%Y %H:%M:%S', seconds, minutes, hours or days "
    "(elapsed time), epoch (Unix seconds) or serial_days (spreadsheet serial days)"
)
# Notations a logger or a spreadsheet export commonly writes, tried in this order to recognise
# a time column (railtherm new-vehicle) or to name the notation of a value that does not match
# the declared one. Day-first before month-first: a European export is the likelier.
COMMON_PATTERNS = (
    "%d.%m.%Y %H:%M:%S",
    "%d.%m.%Y %H:%M",
    "%d.%m.%Y %H:%M:%S.%f",
    "%d.%m.%y %H:%M:%S",
    "%d.%m.%y %H:%M",
    "%d/%m/%Y %H:%M:%S",
    "%d/%m/%Y %H:%M",
    "%m/%d/%Y %I:%M:%S %p",
    "%m/%d/%Y %I:%M %p",
    "%Y/%m/%d %H:%M:%S",
)
_SAMPLE_TIME = dt.datetime(2024, 1, 15, 8, 30, 45)  # a pattern must read back its own date
_ISO_DATE = re.compile(r"^\s*\d{4}-\d{2}-\d{2}")
_OFFSET = re.compile(r"(?:Z|[+-]\d\d:?\d\d)\s*$")


@dataclass(frozen=True)
class TimeFormat:
    """A declared time notation (see the module docstring)."""

    format: str
    timezone: str | None = None
    dst: str = "raise"
    start: str | None = None  # elapsed time: the instant of its zero (ISO 8601 with offset)

    @property
    def absolute(self) -> bool:
        """True for instants (Timestamps), False for elapsed time (seconds)."""
        return self.format not in ELAPSED_UNITS_S

    @property
    def pattern(self) -> str | None:
        """The strftime pattern, or None for a named format."""
        return self.format if "%" in self.format else None

    def describe(self) -> str:
        if self.pattern:
            return f"a time of the pattern {self.pattern!r}"
        return {
            "iso": "an ISO 8601 timestamp",
            "epoch": "a number of seconds since 1970-01-01 UTC (epoch)",
            "epoch_ms": "a number of milliseconds since 1970-01-01 UTC (epoch_ms)",
            "serial_days": "a spreadsheet serial day number (serial_days)",
        }.get(self.format, f"a number of {self.format}")


def time_format(spec: Mapping[str, Any] | str) -> TimeFormat:
    """The :class:`TimeFormat` of a config's ``format.time`` mapping (or a format name).
    ValueError for a format that is none of the above."""
    if isinstance(spec, str):
        spec = {"format": spec}
    name = str(spec["format"])
    known = name in ELAPSED_UNITS_S or name in NAMED_ABSOLUTE or "%" in name
    if not known:
        raise ValueError(
            f"unknown time format {name!r}: one of {', '.join([*NAMED_ABSOLUTE, *ELAPSED_UNITS_S])}"
            " or a strftime pattern such as '%d.%m.%Y %H:%M:%S'"
        )
    return TimeFormat(
        format=name,
        timezone=spec.get("timezone"),
        dst=spec.get("dst", "raise"),
        start=spec.get("start"),
    )


def declared(file: str, spec: Mapping[str, Any]) -> TimeFormat:
    """The :class:`TimeFormat` of a vehicle config's ``format.time`` (``format``, optional
    ``timezone`` and ``dst``), checked: :class:`ConfigError` naming the file, the key, the
    value and the accepted forms. A pattern must read back the date it writes (a time of day
    alone cannot order a record over midnight); a timezone is an IANA name and applies to
    wall-clock times only (not to elapsed time, nor to epoch seconds, which count in UTC);
    ``dst`` needs a timezone."""
    name = spec.get("format")
    if not isinstance(name, str) or not (
        name in ELAPSED_UNITS_S or name in NAMED_ABSOLUTE or "%" in name
    ):
        raise ConfigError(file, "format.time.format", name, f"must be {ACCEPTED}")
    if "%" in name:
        sample = _SAMPLE_TIME.replace(tzinfo=dt.UTC)  # so that %z and %Z write something
        try:
            back = dt.datetime.strptime(sample.strftime(name), name)
        except ValueError:
            back = None
        if back is None or back.date() != _SAMPLE_TIME.date():
            example = _SAMPLE_TIME.strftime("%d.%m.%Y %H:%M:%S")
            raise ConfigError(
                file,
                "format.time.format",
                name,
                "not a strftime pattern that reads back a date and time (day %d, month %m, "
                f"year %Y, hour %H, minute %M, second %S: '%d.%m.%Y %H:%M:%S' reads {example})",
            )
    tf = time_format(spec)
    if tf.timezone is not None:
        zone = tf.timezone
        if not tf.absolute or tf.format in EPOCHS:
            what = "elapsed time has" if not tf.absolute else "epoch seconds count in UTC and have"
            raise ConfigError(
                file,
                "format.time.timezone",
                zone,
                f"{what} no wall-clock time to place in a time zone: remove the key",
            )
        if not _known_zone(zone):
            close = difflib.get_close_matches(
                str(zone), sorted(zoneinfo.available_timezones()), n=1
            )
            hint = f"did you mean '{close[0]}'? " if close else ""
            raise ConfigError(
                file,
                "format.time.timezone",
                zone,
                f"not an IANA time zone name ({hint}e.g. Europe/Berlin, UTC)",
            )
    if tf.start is not None:
        if tf.absolute:
            raise ConfigError(
                file,
                "format.time.start",
                tf.start,
                f"only for elapsed time (seconds, minutes, hours, days): {tf.describe()} "
                "carries its own date and time; remove the key",
            )
        start_instant(file, tf)
    if tf.dst not in DST_RULES:
        raise ConfigError(file, "format.time.dst", tf.dst, f"must be one of {', '.join(DST_RULES)}")
    if "dst" in spec and tf.timezone is None:
        raise ConfigError(
            file,
            "format.time.dst",
            tf.dst,
            "applies to local wall-clock times only: declare format.time.timezone too, or "
            "remove the key",
        )
    return tf


def start_instant(file: str, tf: TimeFormat) -> pd.Timestamp:
    """The instant (UTC) that the zero of an elapsed time stands for (``format.time.start``):
    :class:`ConfigError` naming the key when it is missing, no ISO 8601 timestamp, or without
    a UTC offset (an elapsed time has no zone of its own to read it in)."""
    value = tf.start
    example = "e.g. 2026-03-02T08:57:43+01:00 or 2026-03-02T07:57:43Z"
    if value is None:
        raise ConfigError(
            file,
            "format.time.start",
            None,
            f"missing: the instant the elapsed time's zero stands for ({example}), so that "
            "this record can be placed on UTC beside the others",
        )
    try:
        stamp = pd.Timestamp(dt.datetime.fromisoformat(str(value).strip()))
    except ValueError:
        raise ConfigError(
            file, "format.time.start", value, f"not an ISO 8601 timestamp ({example})"
        ) from None
    if stamp.tzinfo is None:
        raise ConfigError(
            file,
            "format.time.start",
            value,
            f"has no UTC offset: write the offset of the clock that started ({example})",
        )
    return stamp.tz_convert("UTC")


def _known_zone(name: Any) -> bool:
    if not isinstance(name, str):
        return False
    try:
        zoneinfo.ZoneInfo(name)
    except (zoneinfo.ZoneInfoNotFoundError, ValueError):
        return False
    return True


def _named(tf: TimeFormat) -> str:
    return "" if tf.pattern else f" (time format {tf.format})"


def _numbers(raw: pd.Series, decimal: str) -> pd.Series:
    numbers = raw.astype("string").str.strip()
    if decimal != ".":
        numbers = numbers.str.replace(decimal, ".", regex=False)
    return pd.to_numeric(numbers, errors="coerce").astype(float)


def elapsed_seconds(values: Any, unit: str) -> Any:
    """Elapsed time in ``unit`` (seconds, minutes, hours, days) as float seconds. Seconds are
    the file's own numbers; a converted unit is rounded to whole microseconds, far below any
    logger's resolution, so that 0.1 h is 360 s and not the float product 360.00000000000006 s
    (a step of 0.1 h would otherwise differ from row to row in its last digits)."""
    if unit == "seconds":
        return values
    return np.round(values * ELAPSED_UNITS_S[unit], 6)


def _localize(path: str, column: str, raw: pd.Series, times: pd.Series, tf: TimeFormat):
    """Naive wall-clock times in ``tf.timezone`` as UTC instants, by the declared DST rule."""
    rule = {"raise": "raise", "infer": "infer", "earlier": True, "later": False}[tf.dst]
    try:
        return times.dt.tz_localize(tf.timezone, ambiguous=rule, nonexistent="raise").dt.tz_convert(
            "UTC"
        )
    except Exception as exc:  # pytz/zoneinfo errors differ across pandas versions
        text = str(exc)
        kind = "NonExistent" in type(exc).__name__ or "nonexistent" in text.lower()
        stamp = re.search(r"\d{4}-\d\d-\d\d[ T]\d\d:\d\d(?::\d\d)?", text)
        where = ""
        if stamp:
            hits = np.flatnonzero(
                times.astype(str).str.startswith(stamp.group(0).replace("T", " "))
            )
            if hits.size:
                where = f"{line_of(raw, int(hits[0]))}: "
        value = raw.iloc[int(hits[0])] if stamp and hits.size else (stamp.group(0) if stamp else "")
        if len(times) == 1:  # one time (a window's bound), not a column: no line to cite
            where = ""
        if kind:
            reason = (
                f"{where}this local time does not exist in {tf.timezone} (the hour skipped when "
                "daylight-saving time starts): is the timezone right, or the clock already on "
                "UTC or standard time?"
            )
        elif len(times) == 1:  # a window's bound: no rule orders one time
            passes = [
                times.dt.tz_localize(tf.timezone, ambiguous=np.array([first])).iloc[0].isoformat()
                for first in (True, False)
            ]
            reason = (
                f"this local time occurs twice in {tf.timezone} (the hour repeated when "
                f"daylight-saving time ends; format.time.dst {tf.dst} orders the rows of a "
                "column, not one time): write the bound with its UTC offset, "
                f"{passes[0]} (the first pass) or {passes[1]} (the second), or move it out of "
                "the repeated hour"
            )
        else:
            reason = (
                f"{where}this local time occurs twice in {tf.timezone} (the hour repeated when "
                "daylight-saving time ends): declare format.time.dst: infer (rows in time "
                "order), earlier or later"
            )
        raise DataError(path, column, value, reason) from None


def parse(path: str, raw: pd.Series, column: str, tf: TimeFormat, decimal: str = ".") -> pd.Series:
    """Parse a time column: Timestamps for an absolute format (tz-aware in UTC when a timezone
    or offsets are given), float seconds for elapsed time. :class:`DataError` naming the first
    value that does not parse, with its line."""
    text = raw.astype(object).where(raw.notna(), None)
    if not tf.absolute:
        times = elapsed_seconds(_numbers(raw, decimal), tf.format)
    elif tf.format in ("serial_days", *EPOCHS):
        numbers = _numbers(raw, decimal)
        # to whole microseconds (epoch) or milliseconds (a day's float fraction) before the
        # conversion: a float of seconds or days is not an exact count of nanoseconds
        if tf.format in EPOCHS:
            us = np.round(numbers.to_numpy() * EPOCHS[tf.format])
            times = pd.Series(pd.to_datetime(us, unit="us", utc=True, errors="coerce"))
            late = np.flatnonzero(times.dt.year.to_numpy(dtype=float, na_value=0) > LAST_YEAR)
            if late.size:
                row = int(late[0])
                as_ms = pd.to_datetime(np.round(numbers.iloc[row] * 1e3), unit="us", utc=True)
                raise DataError(
                    path,
                    column,
                    text.iloc[row],
                    f"{line_of(raw, row)}: read as {tf.describe()} this is the year "
                    f"{times.iloc[row].year}; as milliseconds it is {as_ms.isoformat()}: "
                    "declare format.time.format: epoch_ms",
                )
        else:
            ms = np.round(numbers.to_numpy() * 86_400_000.0)
            times = pd.Series(SERIAL_DAY_ORIGIN + pd.to_timedelta(ms, unit="ms", errors="coerce"))
    elif tf.pattern:
        times = pd.to_datetime(raw, format=tf.pattern, errors="coerce")
    else:
        times = _iso(path, raw, column, text)
    bad = times.isna().to_numpy()
    if bad.any():
        row = int(bad.argmax())
        raise DataError(
            path, column, text.iloc[row], f"{line_of(raw, row)}: not {tf.describe()}{_named(tf)}"
        )
    if tf.absolute and tf.timezone:
        if times.dt.tz is not None:
            raise DataError(
                path,
                column,
                text.iloc[0],
                "the timestamps carry a UTC offset, so format.time.timezone must not be given",
            )
        times = _localize(path, column, raw, times, tf)
    return times


def _iso(path: str, raw: pd.Series, column: str, text: pd.Series) -> pd.Series:
    looks_iso = raw.astype("string").str.match(_ISO_DATE).fillna(False).astype(bool)
    try:
        return pd.to_datetime(raw.where(looks_iso), format="ISO8601", errors="coerce")
    except ValueError:
        pass
    except TypeError as exc:
        raise DataError(
            path, column, text.iloc[0], f"timestamps cannot be parsed together: {exc}"
        ) from None
    # mixed UTC offsets (a daylight-saving change): every stamp names its instant, so they are
    # compared in UTC; stamps with and without an offset cannot be
    try:
        times = pd.to_datetime(raw.where(looks_iso), format="ISO8601", errors="coerce", utc=True)
    except (ValueError, TypeError) as exc:
        raise DataError(
            path, column, text.iloc[0], f"timestamps cannot be parsed together: {exc}"
        ) from None
    offset = raw.astype("string").str.contains(_OFFSET).fillna(False).astype(bool)
    naive = looks_iso & ~offset
    if naive.any():
        row = int(naive.to_numpy(dtype=bool).argmax())
        raise DataError(
            path,
            column,
            text.iloc[row],
            f"{line_of(raw, row)}: no UTC offset, where other timestamps have one; give every "
            "timestamp its offset, or none",
        )
    return times


def seconds(times: pd.Series, tf: TimeFormat) -> np.ndarray:
    """The parsed times as float seconds: since the first row for instants, as they are for
    elapsed time."""
    if tf.absolute:
        return (times - times.iloc[0]).dt.total_seconds().to_numpy(dtype=float)
    return times.to_numpy(dtype=float)


def instant(
    file: str, key: str, value: Any, tf: TimeFormat, decimal: str = "."
) -> pd.Timestamp | float:
    """A window bound of the config as the file's time: for an absolute format an ISO 8601
    string, or a value in the file's own notation (a string of its pattern, an epoch or serial
    day number), localized like the file's times; for elapsed time a number in the file's unit,
    returned in seconds. :class:`ConfigError` naming file, key and value otherwise."""
    shown = repr(tf.format) if tf.pattern else tf.format
    declared_as = f"(format.time.format is {shown})"
    if not tf.absolute:
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not math.isfinite(value)
        ):
            raise ConfigError(file, key, value, f"must be a number of {tf.format} {declared_as}")
        return float(elapsed_seconds(float(value), tf.format))
    number = isinstance(value, int | float) and not isinstance(value, bool)
    if tf.format in ("serial_days", *EPOCHS):
        if number or (isinstance(value, str) and _numbers(pd.Series([value]), decimal).notna()[0]):
            return parse(file, pd.Series([str(value)]), key, tf, decimal)[0]
        if not isinstance(value, str):
            raise ConfigError(
                file,
                key,
                value,
                f"must be {tf.describe()} or an ISO 8601 timestamp string {declared_as}",
            )
    elif not isinstance(value, str):
        text = f"text: {tf.describe()} or an" if tf.pattern else "an"
        raise ConfigError(
            file, key, value, f"must be {text} ISO 8601 timestamp string {declared_as}"
        )
    stamp = None
    if tf.pattern:
        try:
            stamp = pd.Timestamp(dt.datetime.strptime(value.strip(), tf.pattern))
        except ValueError:
            stamp = None
    if stamp is None:
        try:
            stamp = pd.Timestamp(dt.datetime.fromisoformat(value.strip()))
        except ValueError:
            hint = f"{tf.describe()} or " if tf.pattern else ""
            raise ConfigError(
                file, key, value, f"not {hint}an ISO 8601 timestamp (e.g. 2024-01-15T08:30:00)"
            ) from None
    if tf.timezone and stamp.tzinfo is None:
        try:
            stamp = _localize(file, key, pd.Series([value]), pd.Series([stamp]), tf)[0]
        except DataError as exc:
            raise ConfigError(file, key, value, exc.reason) from None
    elif tf.format in EPOCHS and stamp.tzinfo is None:
        stamp = stamp.tz_localize("UTC")  # an epoch file's instants are in UTC
    return stamp


def recognise(raw: pd.Series, decimal: str = ".") -> str | None:
    """The notation every value of ``raw`` is written in: ``seconds`` for numbers (elapsed,
    or epoch or serial days: a number does not tell its unit), ``iso``, or the first of
    :data:`COMMON_PATTERNS` that reads every value; None when none does."""
    values = raw.dropna()
    if values.empty:
        return None
    for name in ("seconds", "iso", *COMMON_PATTERNS):
        try:
            parse("", values.reset_index(drop=True), "", time_format(name), decimal)
        except DataError:
            continue
        return name
    return None


def fix(value: Any, tf: TimeFormat, decimal: str = ".") -> str:
    """The likely fix when the time ``value`` is not of the declared notation ``tf``, as a
    clause to append to the message ("; it reads as ...: declare format.time.format ...");
    empty when the value is of ``tf`` after all (the trouble is elsewhere, e.g. a DST hour)."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "; every row needs its time: fill in the cell or delete the row"
    one = pd.Series([str(value)], dtype=object)
    try:
        parse("", one, "", tf, decimal)
        return ""
    except DataError:
        pass
    found = recognise(one, decimal)
    if found == tf.format:  # of the declared notation, but not a valid time in its zone
        return ""
    if found == "seconds":
        return (
            "; it is a number: declare format.time.format seconds, minutes, hours or days "
            "(elapsed time), epoch (Unix seconds) or serial_days (spreadsheet serial days)"
        )
    if found is not None:
        shown = found if found == "iso" else repr(found)
        return f"; it reads as {time_format(found).describe()}: declare format.time.format: {shown}"
    example = _SAMPLE_TIME.strftime("%d.%m.%Y %H:%M:%S")
    return (
        "; if every time of the file is written like this one, declare its strftime pattern "
        f"as format.time.format ('%d.%m.%Y %H:%M:%S' reads {example}), else correct this line"
    )
