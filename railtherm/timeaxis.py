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
"""

from __future__ import annotations

import datetime as dt
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from railtherm.errors import ConfigError, DataError

ELAPSED_UNITS_S = {"seconds": 1.0, "minutes": 60.0, "hours": 3600.0, "days": 86400.0}
NAMED_ABSOLUTE = ("iso", "epoch", "serial_days")
SERIAL_DAY_ORIGIN = pd.Timestamp("1899-12-30")  # day 0 of the 1900 date system
DST_RULES = ("raise", "infer", "earlier", "later")
_ISO_DATE = re.compile(r"^\s*\d{4}-\d{2}-\d{2}")
_OFFSET = re.compile(r"(?:Z|[+-]\d\d:?\d\d)\s*$")


@dataclass(frozen=True)
class TimeFormat:
    """A declared time notation (see the module docstring)."""

    format: str
    timezone: str | None = None
    dst: str = "raise"

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
    return TimeFormat(format=name, timezone=spec.get("timezone"), dst=spec.get("dst", "raise"))


def _named(tf: TimeFormat) -> str:
    return "" if tf.pattern else f" (time format {tf.format})"


def _numbers(raw: pd.Series, decimal: str) -> pd.Series:
    numbers = raw.astype("string").str.strip()
    if decimal != ".":
        numbers = numbers.str.replace(decimal, ".", regex=False)
    return pd.to_numeric(numbers, errors="coerce").astype(float)


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
                where = f"line {int(hits[0]) + 2}: "
        value = raw.iloc[int(hits[0])] if stamp and hits.size else (stamp.group(0) if stamp else "")
        if kind:
            reason = (
                f"{where}this local time does not exist in {tf.timezone} (the hour skipped when "
                "daylight-saving time starts): is the timezone right, or the clock already on "
                "UTC or standard time?"
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
        times = _numbers(raw, decimal) * ELAPSED_UNITS_S[tf.format]
    elif tf.format in ("epoch", "serial_days"):
        numbers = _numbers(raw, decimal)
        # to whole microseconds (epoch) or milliseconds (a day's float fraction) before the
        # conversion: a float of seconds or days is not an exact count of nanoseconds
        if tf.format == "epoch":
            us = np.round(numbers.to_numpy() * 1e6)
            times = pd.Series(pd.to_datetime(us, unit="us", utc=True, errors="coerce"))
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
            path, column, text.iloc[row], f"line {row + 2}: not {tf.describe()}{_named(tf)}"
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
            f"line {row + 2}: no UTC offset, where other timestamps have one; give every "
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
    if not tf.absolute:
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not math.isfinite(value)
        ):
            raise ConfigError(file, key, value, f"must be a number of {tf.format} (time format)")
        return float(value) * ELAPSED_UNITS_S[tf.format]
    if isinstance(value, int | float) and not isinstance(value, bool):
        if tf.format not in ("epoch", "serial_days"):
            raise ConfigError(file, key, value, f"must be {tf.describe()} or ISO 8601 text")
        return parse(file, pd.Series([str(value)]), key, tf)[0]
    if not isinstance(value, str):
        raise ConfigError(file, key, value, f"must be {tf.describe()} or ISO 8601 text")
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
    elif tf.format == "epoch" and stamp.tzinfo is None:
        stamp = stamp.tz_localize("UTC")  # an epoch file's instants are in UTC
    return stamp
