"""Cleaning raw climatic-wind-tunnel recordings into tidy, uniformly sampled tables.

A raw file (CSV, plain or ``.gz``, or any kind :mod:`railtherm.data.readers` reads) is read by
:func:`read_raw`; :func:`tidy` cuts one window out of it and returns the tidy table every later
stage consumes; :func:`clean_window` does both for a window named in the vehicle config, and
:func:`write_tidy` writes the table.

Tidy table (columns in this order)
----------------------------------
``time``       s since the window start: 0, step, 2 step, ...
``timestamp``  the time of the grid point: ISO 8601 text for a file of instants (``iso``, a
               strftime pattern, ``epoch``, ``serial_days``; in UTC, ``+00:00``, when the
               file's times carry offsets or a declared ``format.time.timezone``, and for
               ``epoch``), elapsed seconds for a file of elapsed time (whatever its unit)
``T``          weighted mean of the indoor air sensors, degC
``T_veh``      weighted mean of the interior surface sensors, degC (empty if there are none)
``T_o``        weighted mean of the outdoor (tunnel) air sensors, degC
``Q_H``        heater plus fan power, W (eq. 3): ``Q_heater + Q_fan``
``Q_heater``   heater power, W
``Q_fan``      fan power, W (0 without fan channels)
``T_spread``   weighted standard deviation of the indoor sensors, K:
               ``sqrt(sum w_i (T_i - T)^2 / sum w_i)`` (0 with one sensor)
``filled``     1 if any value used for this row was interpolated across a gap, else 0

Only when the vehicle declares them (the further terms of the general balance, eq. 1):

``Q_known``    known heat flows (``channels.heat_flows``: passengers, auxiliaries, ...), W,
               already included in ``Q_H`` (which is then ``Q_heater + Q_fan + Q_known``)
``I_<name>``   each irradiance channel (``channels.irradiance``), W/m2, a mean over the step
               like the powers; a further model input with an estimated effective aperture

Grid
----
``t_n = window start + n step`` for ``n = 0..N`` with ``t_N <= window end``; ``step`` is
``cleaning.step_s`` or, by default, the raw file's median logger step ``dt_log``.

Temperatures at ``t_n`` are the mean of the samples in the bin ``[t_n - step/2, t_n + step/2]``;
a sample lying exactly on the boundary of two bins counts half in each (so every sample has
weight 1 in total and the bin mean is centred on ``t_n`` for any whole number of logger steps
per step; when step = ``dt_log`` the value is the sample at ``t_n`` itself). Near the ends of the
data the bin shrinks symmetrically to ``[t_n - h, t_n + h]`` with ``h`` the distance to the
first/last sample (h = 0: the sample at ``t_n``). A bin without any sample (step finer than the
logger) takes the linear interpolation at ``t_n``.

Powers: ``Q_H[n]`` is the mean power over ``[t_n, t_n + step)``, the input held over the step
that follows ``t_n`` (the zero-order hold of eq. 15 used by the simulation). It is the exact
integral of the power signal the samples describe, by ``format.power_timing``:

* ``mean_preceding``: a sample at ``t_k`` is the mean over ``(t_{k-1}, t_k]`` (the first sample
  covers ``(t_0 - dt_log, t_0]``); the signal is piecewise constant;
* ``mean_following``: a sample at ``t_k`` is the mean over ``[t_k, t_{k+1})`` (the last covers
  ``[t_last, t_last + dt_log)``); piecewise constant;
* ``instant``: a sample is the power at ``t_k``; the signal is the linear interpolation between
  samples (so a switch between two samples counts half of the interval on either side, the
  unbiased guess when the switching time is unknown).

With ``model.input_hold: first_order`` (inputs linear between samples, which needs
``power_timing: instant``) every power and irradiance column is instead the value at ``t_n``,
binned like a temperature (the sample itself when step = ``dt_log``). On a step coarser than
the logger's, a column ``<input>_hold_error`` per input (Q_H, each irradiance) gives, per row,
the rms of the logged signal's departure from the straight line between the rows over
``[t_n, t_n+1)``: large where the input switches within a step (a heater's on/off), which
the fit flags (``railtherm.study.fitsettings.hold_flags``).

Data after the window end are used when the file has them. Where the power signal ends before
``t_N + step`` (the last row of a window that reaches the end of the data), the last row's
power is the mean over the part of ``[t_N, t_N + step)`` that the data cover, and where they
cover none of it (``instant`` or ``mean_preceding`` with ``t_N`` = the last sample), the power
just before ``t_N`` (the last sample's value).

Gaps
----
Each channel is cleaned on its own BEFORE the sensors are combined, so a missing sensor does not
shift a mean by its offset. The raw time axis is first completed: an interval of about ``m``
logger steps between two rows holds ``m - 1`` missing rows, inserted evenly. Missing rows and
empty cells are then linearly interpolated per channel (values before a channel's first or after
its last value are held) and the rows they touch are flagged in ``filled``. A gap lasts
(number of missing samples) x ``dt_log``; a gap longer than ``cleaning.max_gap_s`` that reaches
into the rows of the window is a :class:`~railtherm.errors.DataError` naming the file, the
column and the time of the gap. Gaps elsewhere in the file do not matter.

Units: each channel's ``scale * raw + offset`` (when declared) in its declared unit, converted
to degC (from K or degF), W (from kW) or W/m2 (from kW/m2) by :func:`railtherm.data.units.to_si`.
Raw-data problems raise :class:`~railtherm.errors.DataError`; a window that does not fit the
data (outside it, empty, unknown name) raises :class:`~railtherm.errors.ConfigError` naming the
raw file and the window's key.
"""

from __future__ import annotations

import gzip
import os
import re
from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from railtherm.data import sources as sources_
from railtherm.data import timeaxis, units
from railtherm.data.rawfile import parse_times, read_columns, separator_hint
from railtherm.data.readers import elsewhere_hint, line_of, read_table, reader_kind
from railtherm.errors import ConfigError, DataError

__all__ = [
    "TIDY_COLUMNS",
    "irradiance_names",
    "clean_window",
    "read_raw",
    "read_tidy",
    "tidy",
    "window_names",
    "window_spec",
    "write_tidy",
]

TIDY_COLUMNS = (
    "time",
    "timestamp",
    "T",
    "T_veh",
    "T_o",
    "Q_H",
    "Q_heater",
    "Q_fan",
    "T_spread",
    "filled",
)
TEMPERATURE_GROUPS = ("indoor_air", "surface", "outdoor_air")
POWER_GROUPS = ("heater_power", "fan_power")
#: with ``model.input_hold: first_order`` on a step coarser than the logger's: per input (Q_H,
#: each irradiance), the column ``<input>_hold_error``, the rms per row of the logged signal's
#: departure from the straight line between the rows (:func:`_hold_error`)
HOLD_ERROR_SUFFIX = "_hold_error"
KNOWN_HEAT = "heat_flows"  # eq. 1's known heat flows (W), summed into Q_H
IRRADIANCE = "irradiance"  # W/m2, one model input per channel
# every channel group of a vehicle config, in the schema's order
CHANNEL_GROUPS = (*TEMPERATURE_GROUPS, *POWER_GROUPS, KNOWN_HEAT, IRRADIANCE)


def input_hold(vehicle_data: Mapping[str, Any]) -> str:
    """The declared input hold (``model.input_hold``; the paper's zero-order hold by default)."""
    return str((vehicle_data.get("model") or {}).get("input_hold", "zero_order"))


def irradiance_names(vehicle_data: Mapping[str, Any]) -> list[str]:
    """The tidy column (and model input) of each irradiance channel, in config order:
    ``I_<name>``, by default ``I_sol`` (then ``I_sol2``, ...)."""
    return [
        f"I_{c.get('name') or ('sol' if i == 0 else f'sol{i + 1}')}"
        for i, c in enumerate(_channels(vehicle_data, IRRADIANCE))
    ]


RESERVED_WINDOWS = ("kvalue", "record")


# ---------------------------------------------------------------------------------------------
# Reading


def read_raw(
    path: str | os.PathLike[str], fmt: dict[str, Any], label: str | None = None
) -> pd.DataFrame:
    """Read a raw file into a DataFrame indexed by its time in seconds.

    ``fmt`` is the vehicle's ``format`` section: the kind of file (CSV, plain or ``.gz``; Excel;
    MATLAB; R) and how to read it (:mod:`railtherm.data.readers`), decimal, and ``time`` (column,
    format, timezone, dst; :mod:`railtherm.data.timeaxis`). The index (``t_s``, float) is the time
    column in seconds: elapsed time in seconds (the numbers themselves for ``seconds``,
    converted from minutes, hours or days), seconds since the first row for instants (iso, a
    strftime pattern, epoch, serial_days). The time column is kept as text (the raw labels);
    every other column is read as numbers where each of its cells is one (``format.decimal``
    honoured), else kept as text with the decimal mark ``.``. ``label`` is the file name used
    in messages (default: ``path``).

    Raises :class:`ConfigError` for a ``format.time`` that declares no known notation;
    :class:`DataError` naming the file when it cannot be read, the time column is missing, a
    time does not parse (naming the value, its line and the likely fix), or the time is not
    strictly increasing (naming the offending time, its data row and line).
    """
    file = label or str(path)
    sep = fmt.get("separator", ",")
    decimal = fmt.get("decimal", ".")
    time_column = fmt["time"]["column"]
    tf = timeaxis.declared(file, fmt["time"])
    try:
        columns = read_columns(path, fmt=fmt)
    except DataError as exc:
        raise DataError(file, exc.key, exc.value, exc.reason) from None
    if time_column not in columns:
        hint = separator_hint(columns, sep) if reader_kind(path, fmt) == "csv" else ""
        hint = elsewhere_hint(path, time_column) or hint
        raise DataError(
            file, time_column, None, f"time column not found ({hint}columns: {', '.join(columns)})"
        )
    try:
        raw = read_table(path, fmt)
    except DataError as exc:
        raise DataError(file, exc.key, exc.value, exc.reason) from None
    if raw.empty:
        raise DataError(file, time_column, None, "the file has a header but no data rows")
    for column in raw.columns.drop(time_column):
        text = raw[column]
        if decimal != ".":  # "21,5" as "21.5"; a cell holding a "." is left as it is
            keep = text.str.contains(".", regex=False).fillna(True).astype(bool)
            text = text.where(keep, text.str.replace(decimal, ".", regex=False))
        # a column of numbers only becomes float (as read_csv's type inference made it); any
        # other stays text, and the cleaning names its first cell that is no number
        values = pd.to_numeric(text, errors="coerce")
        raw[column] = values.astype(float) if (values.notna() | text.isna()).all() else text
    labels = raw[time_column]
    try:
        times = parse_times(file, labels, time_column, tf, decimal)
    except DataError as exc:
        fix = timeaxis.fix(exc.value, tf, decimal)
        raise DataError(file, exc.key, exc.value, exc.reason + fix) from None
    seconds = timeaxis.seconds(times, tf)
    steps = np.diff(seconds)
    bad = np.flatnonzero(steps <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        what = "duplicated time" if steps[i - 1] == 0 else "time goes backwards"
        why = "the time column must increase strictly"
        forward = steps[steps > 0]
        step = float(np.median(forward)) if forward.size else 0.0
        hour_back = abs(steps[i - 1] + 3600.0) <= max(2.0 * step, 1.0)
        if tf.timezone and tf.dst in ("earlier", "later"):  # both passes of the repeated hour
            why += f"; format.time.dst: {tf.dst} takes every repeated local time as one: infer?"
        elif hour_back and tf.absolute and not tf.timezone:
            why += (
                "; it steps back by an hour, as a clock on local time does when summer time "
                "ends: declare format.time.timezone (e.g. Europe/Berlin, America/Chicago) and "
                "format.time.dst: infer"
            )
        raise DataError(
            file,
            time_column,
            labels.iloc[i],
            f"{what}: data row {i + 1} ({line_of(labels, i)}) follows {labels.iloc[i - 1]!s} "
            f"({why})",
        )
    raw.index = pd.Index(seconds, name="t_s")
    origin = times.iloc[0] if tf.absolute else None  # the time at index 0 s
    raw.attrs = {
        **{k: raw.attrs[k] for k in ("sheet", "lines") if k in raw.attrs},  # a workbook's rows
        "file": file,
        "time_column": time_column,
        "time_format": tf.format,
        "origin": origin,
    }
    return raw


# ---------------------------------------------------------------------------------------------
# Windows


def part_names(vehicle_data: Mapping[str, Any]) -> list[str]:
    """The names of a record's parts: the keys of ``raw_files``, or with sources those of each
    source's ``files`` (the same in every source)."""
    if vehicle_data.get("sources"):
        return list(next(iter(vehicle_data["sources"].values()))["files"])
    return list(vehicle_data["raw_files"])


def window_names(vehicle_data: dict[str, Any]) -> list[str]:
    """Names of the windows the vehicle config defines: ``kvalue`` (if any), then the
    identification windows in config order (``record``, the whole file, is always available)."""
    windows = vehicle_data["windows"]
    names = ["kvalue"] if "kvalue" in windows else []
    return names + [w["name"] for w in windows["identification"]]


def window_spec(
    vehicle_data: dict[str, Any], window_name: str
) -> tuple[str, dict[str, Any] | None, str]:
    """``(raw-file name, window or None, config key)`` of a window named in the vehicle config.

    ``kvalue`` is ``windows.kvalue``; ``record`` is the whole file (window ``None``) of the
    kvalue window, or of the first identification window when there is none; any other name is
    the identification window of that name. The raw-file name is a key of ``raw_files``.
    Raises :class:`ConfigError` for an unknown name.
    """
    windows = vehicle_data["windows"]
    ident = windows["identification"]

    def file_of(window: dict[str, Any]) -> str:
        return window.get("file") or part_names(vehicle_data)[0]

    if window_name == "kvalue":
        if "kvalue" not in windows:
            raise ConfigError(
                vehicle_data.get("id", "(vehicle)"), "windows.kvalue", None, "no kvalue window"
            )
        return file_of(windows["kvalue"]), windows["kvalue"], "windows.kvalue"
    if window_name == "record":
        first = windows.get("kvalue") or ident[0]
        return file_of(first), None, "record"
    for i, window in enumerate(ident):
        if window["name"] == window_name:
            return file_of(window), window, f"windows.identification[{i}]"
    raise ConfigError(
        vehicle_data.get("id", "(vehicle)"),
        "windows",
        window_name,
        f"no such window (known: {', '.join([*window_names(vehicle_data), 'record'])})",
    )


def _window_key(vehicle_data: dict[str, Any], window: dict[str, Any] | None) -> str:
    if window is None:
        return "record"
    windows = vehicle_data.get("windows", {})
    if windows.get("kvalue") == window:
        return "windows.kvalue"
    for i, w in enumerate(windows.get("identification", [])):
        if w == window:
            return f"windows.identification[{i}]"
    return "window"


def _bound(file: str, key: str, value: Any, tf: timeaxis.TimeFormat, origin: Any) -> float:
    """A window bound (in the file's notation or ISO 8601, :func:`railtherm.data.timeaxis.instant`)
    in the raw index's seconds."""
    t = timeaxis.instant(file, key, value, tf)
    if not tf.absolute:
        return float(t)
    try:
        return float((t - origin).total_seconds())
    except TypeError:
        raise ConfigError(
            file, key, value, "time zone given on one side only (window vs. the file's timestamps)"
        ) from None


# ---------------------------------------------------------------------------------------------
# Cleaning


def _channels(vehicle_data: Mapping[str, Any], group: str) -> list[dict[str, Any]]:
    return list(vehicle_data["channels"].get(group) or [])


def _number_hint(text: str) -> str:
    """The likely fix for a cell that is no number under the declared format."""
    if re.fullmatch(r"\s*[-+]?\d[\d.]*,\d+\s*", text):
        return (
            " (a decimal comma: declare format.decimal: ',' - with format.separator ';' if "
            "the file separates its columns by semicolons)"
        )
    if re.fullmatch(r"\s*[-+]?\d+\.\d+\s*", text):
        return " (a decimal point where format.decimal is ',': declare format.decimal: '.')"
    return ""


def _numeric(file: str, raw: pd.DataFrame, column: str) -> np.ndarray:
    """A channel column as float, empty cells NaN (gaps); :class:`DataError` naming the first
    value that is no number, or not a finite one: "inf" or "-inf" is a logger's overflow or
    fault, not a measurement, and would otherwise spread through every mean it enters."""
    series = raw[column]
    if pd.api.types.is_numeric_dtype(series.dtype):
        values = series.to_numpy(dtype=float, na_value=np.nan)
    else:
        text = series.astype("string")
        values = pd.to_numeric(text, errors="coerce").to_numpy(dtype=float, na_value=np.nan)
        blank = (text.isna() | text.str.strip().eq("")).to_numpy(dtype=bool, na_value=True)
        bad = np.isnan(values) & ~blank
        if bad.any():
            i = int(bad.argmax())
            value = str(text.iloc[i])
            raise DataError(
                file, column, value, f"{line_of(series, i)}: not a number{_number_hint(value)}"
            )
    infinite = np.isinf(values)
    if infinite.any():
        i = int(infinite.argmax())
        raise DataError(
            file,
            column,
            str(series.iloc[i]),
            f"{line_of(series, i)}: not a finite measurement (a logger's overflow or fault); empty "
            "the cell to mark a gap, which is interpolated up to cleaning.max_gap_s",
        )
    return values


TEMPERATURE_RANGE_DEGC = (-80.0, 120.0)


def _check_temperatures(file, groups, t, region, cleaning, labels) -> None:
    """Every temperature the window uses lies in ``cleaning.temperature_range_degC`` (default
    -80 to 120 degC: beyond the coldest and hottest climatic wind tunnels, and beyond any
    indoor air): a value outside is a sensor's fault code (-999), a spike, or a unit mistake
    (kelvin declared as degC), never a temperature to fit. :class:`DataError` naming the
    file, column, value, time and the likely cause."""
    lo, hi = map(float, cleaning.get("temperature_range_degC") or TEMPERATURE_RANGE_DEGC)
    used = (t >= region[0]) & (t <= region[1])
    for group in TEMPERATURE_GROUPS:
        for column, _, values in groups.get(group, []):
            wrong = used & np.isfinite(values) & ((values < lo) | (values > hi))
            if not wrong.any():
                continue
            i = int(wrong.argmax())
            v = float(values[i])
            share = wrong.sum() / max(int((used & np.isfinite(values)).sum()), 1)
            if 200.0 <= v <= 400.0:
                cause = "kelvin declared as degC? (give the channel unit: K)"
            elif share > 0.5 and lo <= v + 273.15 <= hi:
                # most of the window below absolute zero's neighbourhood: degC read as K
                cause = (
                    f"degC declared as kelvin? {share:.0%} of the window's values lie outside, "
                    f"and read as degC this one is {v + 273.15:.2f} degC: check the unit "
                    "(give the channel unit: degC, or leave unit out)"
                )
            elif v <= -99.0 and float(v).is_integer():
                cause = "a logger's fault code for a missing value? (empty the cell)"
            else:
                cause = "a spike or a faulty sensor? (empty the cell, or drop the channel)"
            raise DataError(
                file,
                column,
                round(v, 6),
                f"at {labels.one(t[i])}: outside the physical range {lo:g} to {hi:g} degC "
                f"(cleaning.temperature_range_degC): {cause}",
            )


def _complete_axis(t: np.ndarray, dt_log: float) -> tuple[np.ndarray, np.ndarray]:
    """The time axis with missing rows inserted: ``(t_full, positions of the raw rows)``.

    An interval of about m logger steps (m = round(interval / dt_log)) gets m - 1 evenly spaced
    points."""
    d = np.diff(t)
    count = np.maximum(np.rint(d / dt_log), 1).astype(np.int64)
    first = np.cumsum(count) - count  # position of each raw row (but the last) in t_full
    owner = np.repeat(np.arange(d.size), count)
    j = np.arange(int(count.sum())) - np.repeat(first, count)
    t_full = np.concatenate([t[owner] + d[owner] * j / count[owner], t[-1:]])
    return t_full, np.concatenate([first, [t_full.size - 1]])


class _Labels:
    """Time labels of arbitrary times (seconds on the raw index): ISO 8601 text for a file of
    instants (``absolute``, with ``origin`` the instant at 0 s), else the seconds."""

    def __init__(self, absolute: bool, origin: Any):
        self.iso = absolute
        self.origin = origin

    def many(self, seconds: np.ndarray) -> np.ndarray:
        seconds = np.asarray(seconds, dtype=float)
        if not self.iso:
            return seconds
        whole = np.allclose(seconds, np.rint(seconds), rtol=0, atol=1e-6)
        unit = "s" if whole else "ms"
        origin = self.origin
        tz = origin.tzinfo is not None
        offset = origin.isoformat()[-6:] if tz else ""
        local = origin.tz_localize(None) if tz else origin
        step = np.rint(seconds * (1 if whole else 1000)).astype(np.int64)
        stamps = np.datetime64(local.to_datetime64(), unit) + step.astype(f"timedelta64[{unit}]")
        text = np.datetime_as_string(stamps, unit=unit)
        return np.char.add(text.astype(str), offset) if offset else text.astype(str)

    def one(self, seconds: float) -> Any:
        value = self.many(np.array([seconds]))[0]
        return str(value) if self.iso else float(value)


def _fill_channels(
    file: str,
    columns: list[str],
    values: list[np.ndarray],
    t_full: np.ndarray,
    rows: np.ndarray,
    dt_log: float,
    max_gap: float,
    region: tuple[float, float],
    labels: _Labels,
) -> tuple[np.ndarray, np.ndarray]:
    """Interpolate each channel across its gaps on ``t_full``; ``(values, filled)`` with one
    column per channel. The earliest gap longer than ``max_gap`` that reaches into ``region``
    is a :class:`DataError` naming its column and time."""
    tol = 1e-6 * dt_log
    out = np.empty((t_full.size, len(columns)))
    filled = np.ones((t_full.size, len(columns)), dtype=bool)
    worst: tuple[float, int, str] | None = None
    for c, (column, raw_values) in enumerate(zip(columns, values, strict=True)):
        full = np.full(t_full.size, np.nan)
        full[rows] = raw_values
        ok = ~np.isnan(full)
        if not ok.any():
            raise DataError(file, column, None, "the channel has no values at all")
        tv = t_full[ok]
        filled[:, c] = ~ok
        out[:, c] = np.interp(t_full, tv, full[ok])
        # gaps as (last time with data or the axis start, next time with data or the axis end)
        lo = np.concatenate([[t_full[0] - dt_log], tv])
        hi = np.concatenate([tv, [t_full[-1] + dt_log]])
        length = hi - lo - dt_log
        long = (length > max_gap + tol) & (lo < region[1]) & (hi > region[0])
        if long.any():
            i = int(np.flatnonzero(long)[0])
            first_missing = t_full[np.searchsorted(t_full, lo[i] + 0.5 * dt_log)]
            if worst is None or first_missing < worst[0]:
                after = "the start of the data" if i == 0 else labels.one(lo[i])
                until = "the end of the data" if i == tv.size else labels.one(hi[i])
                worst = (
                    first_missing,
                    c,
                    f"gap of {length[i]:g} s without data (after {after}, until {until}) is "
                    f"longer than cleaning.max_gap_s = {max_gap:g} s",
                )
    if worst is not None:
        raise DataError(file, columns[worst[1]], labels.one(worst[0]), worst[2])
    return out, filled


def _bin_means(
    t: np.ndarray, values: np.ndarray, flags: np.ndarray, grid: np.ndarray, step: float, tol: float
) -> tuple[np.ndarray, np.ndarray]:
    """Temperatures on the grid: centred bin means (see the module docstring) and, per grid
    point, whether any sample used was filled."""
    half = np.minimum(step / 2.0, np.minimum(grid - t[0], t[-1] - grid))
    half = np.maximum(half, 0.0)
    lo = np.searchsorted(t, grid - half - tol, side="left")
    hi = np.searchsorted(t, grid + half + tol, side="right") - 1
    offset = values[0]
    cum = np.vstack([np.zeros((1, values.shape[1])), np.cumsum(values - offset, axis=0)])
    fcum = np.concatenate([[0], np.cumsum(flags)])
    empty = lo > hi
    lo_c = np.minimum(lo, t.size - 1)
    hi_c = np.maximum(hi, 0)
    total = cum[hi_c + 1] - cum[lo_c]
    count = (hi_c - lo_c + 1).astype(float)
    wide = half > tol
    on_lo = ~empty & wide & (np.abs(t[lo_c] - (grid - half)) <= tol)
    on_hi = ~empty & wide & (np.abs(t[hi_c] - (grid + half)) <= tol)
    total -= 0.5 * (
        on_lo[:, None] * (values[lo_c] - offset) + on_hi[:, None] * (values[hi_c] - offset)
    )
    count -= 0.5 * (on_lo.astype(float) + on_hi.astype(float))
    with np.errstate(invalid="ignore", divide="ignore"):
        means = total / count[:, None] + offset
    if empty.any():
        for c in range(values.shape[1]):
            means[empty, c] = np.interp(grid[empty], t, values[:, c])
    # flags: the samples of the bin, or the two neighbours an empty bin interpolates between
    f_lo = np.where(empty, np.maximum(hi, 0), lo_c)
    f_hi = np.where(empty, np.minimum(lo, t.size - 1), hi_c)
    used_filled = fcum[f_hi + 1] - fcum[f_lo] > 0
    return means, used_filled


def _power_means(
    t: np.ndarray,
    p: np.ndarray,
    flags: np.ndarray,
    grid: np.ndarray,
    step: float,
    dt_log: float,
    timing: str,
    tol: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Mean power over ``[t_n, t_n + step)`` for each grid point (see the module docstring),
    with one column per power sum in ``p``; and whether any sample used was filled."""
    fcum = np.concatenate([[0], np.cumsum(flags)])
    if timing == "instant":
        x = t
        d = np.diff(x)
        energy = np.vstack(
            [np.zeros((1, p.shape[1])), np.cumsum(0.5 * (p[:-1] + p[1:]) * d[:, None], axis=0)]
        )

        def cumulative(s: np.ndarray) -> np.ndarray:
            k = np.clip(np.searchsorted(x, s, side="right") - 1, 0, x.size - 2)
            u = (s - x[k])[:, None]
            slope = (p[k + 1] - p[k]) / d[k][:, None]
            return energy[k] + p[k] * u + 0.5 * slope * u * u

    else:
        if timing == "mean_preceding":
            x = np.concatenate([[t[0] - dt_log], t])
        else:  # mean_following
            x = np.concatenate([t, [t[-1] + dt_log]])
        energy = np.vstack([np.zeros((1, p.shape[1])), np.cumsum(p * np.diff(x)[:, None], axis=0)])

        def cumulative(s: np.ndarray) -> np.ndarray:
            return np.column_stack([np.interp(s, x, energy[:, c]) for c in range(p.shape[1])])

    a = grid
    b = np.minimum(grid + step, x[-1])
    length = b - a
    short = length <= tol
    with np.errstate(invalid="ignore", divide="ignore"):
        means = (cumulative(b) - cumulative(a)) / length[:, None]
    means[short] = p[-1]
    # flags: every sample whose support overlaps (a, b)
    if timing == "instant":  # sample k supports (t_{k-1}, t_{k+1})
        k_lo = np.searchsorted(t, a + tol, side="right") - 1
        k_hi = np.searchsorted(t, b - tol, side="left")
    else:  # sample k is the piece (x_k, x_{k+1})
        k_lo = np.searchsorted(x[1:], a + tol, side="right")
        k_hi = np.searchsorted(x[:-1], b - tol, side="left") - 1
    k_lo = np.clip(k_lo, 0, t.size - 1)
    k_hi = np.clip(k_hi, k_lo, t.size - 1)
    k_lo[short] = k_hi[short] = t.size - 1
    used_filled = fcum[k_hi + 1] - fcum[k_lo] > 0
    return means, used_filled


def _hold_error(t: np.ndarray, fine: np.ndarray, grid: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Per row n, the rms over the logged samples in [t_n, t_n+1) of the logged signal
    ``fine`` (at ``t``) minus the straight line between the rows' values ``rows`` (at
    ``grid``): what a first-order hold misses of an input resampled to a coarser step. Near 0
    for a signal that is smooth over a step; of the order of the jump where it switches
    within a step. The last row (no step follows it) is 0."""
    inside = (t >= grid[0]) & (t < grid[-1])
    tt, e = t[inside], fine[inside] - np.interp(t[inside], grid, rows)
    row = np.searchsorted(grid, tt, side="right") - 1
    count = np.bincount(row, minlength=grid.size).astype(float)
    total = np.bincount(row, weights=e * e, minlength=grid.size)
    return np.sqrt(np.divide(total, count, out=np.zeros(grid.size), where=count > 0))


class _Part:
    """One source of a record on the record's time axis: its raw table (index in seconds on
    that axis), the file that names it in messages, its power timing and its channels by
    group as ``(column, weight, values in SI units)``."""

    def __init__(
        self, file: str, raw: pd.DataFrame, timing: str, groups: dict[str, list], source=None
    ):
        self.file = file
        self.source = source
        self.t = raw.index.to_numpy(dtype=float)
        self.timing = timing
        self.groups = groups
        self.dt_log = float(np.median(np.diff(self.t))) if self.t.size > 1 else 0.0


def _part_groups(
    file: str,
    raw: pd.DataFrame,
    vehicle_data: Mapping[str, Any],
    time_column: str,
    source: str | None,
) -> dict[str, list[tuple[str, float, np.ndarray]]]:
    """The channels of one source (``source`` None: the one raw file) by group, as numbers in
    SI units (degC, W), in config order."""
    groups: dict[str, list[tuple[str, float, np.ndarray]]] = {}
    for group in (*TEMPERATURE_GROUPS, *POWER_GROUPS, KNOWN_HEAT, IRRADIANCE):
        found = []
        for i, channel in enumerate(_channels(vehicle_data, group)):
            if source is not None and channel.get("source") != source:
                continue
            column = channel["column"]
            if column not in raw.columns:
                shown = [c for c in raw.columns if c != time_column]
                where = "the file" if source is None else f"the files of sources.{source}"
                raise DataError(
                    file,
                    column,
                    None,
                    f"channel channels.{group}[{i}] not found in {where} "
                    f"(columns: {', '.join(map(str, shown))})",
                )
            values = _numeric(file, raw, column)
            default = "degC" if group in TEMPERATURE_GROUPS else "W"
            values = units.to_si(values, channel, default)
            found.append((column, float(channel.get("weight", 1.0)), values))
        groups[group] = found
    return groups


def _record(raw: Any, vehicle_data: Mapping[str, Any], file: str) -> tuple:
    """The parts of a record (one raw file, or each source on the record's UTC axis), its
    time notation, the instant of its 0 s, its labels, the span every part covers and that
    span in words: ``(parts, tf, origin, labels, t_lo, t_hi, span)``."""
    if isinstance(raw, pd.DataFrame):
        fmt = vehicle_data["format"]
        time_column = fmt["time"]["column"]
        tf = timeaxis.declared(file, fmt["time"])
        t = raw.index.to_numpy(dtype=float)
        if t.size < 2:
            raise DataError(file, time_column, None, "needs at least two data rows")
        if not np.all(np.diff(t) > 0):
            raise DataError(file, time_column, None, "the time index must increase strictly")
        origin = None
        if tf.absolute:  # the time at index 0 s
            origin = raw.attrs.get("origin")
            if origin is None:
                first = raw[time_column].iloc[:1].astype(str).reset_index(drop=True)
                decimal = fmt.get("decimal", ".")
                origin = timeaxis.parse(file, first, time_column, tf, decimal).iloc[0]
                origin -= pd.Timedelta(seconds=float(t[0]))
        labels = _Labels(tf.absolute, origin)
        groups = _part_groups(file, raw, vehicle_data, time_column, None)
        parts = [_Part(file, raw, fmt.get("power_timing", "instant"), groups)]
        t_lo, t_hi = float(t[0]), float(t[-1])
        span = f"the data of {file} run from {labels.one(t[0])} to {labels.one(t[-1])}"
    else:
        tf = sources_.RECORD_TIME
        origin = sources_.origin(raw)
        labels = _Labels(True, origin)
        parts = []
        for name, part in raw.items():
            src_fmt = vehicle_data["sources"][name]["format"]
            part_file = part.attrs.get("file", name)
            groups = _part_groups(part_file, part, vehicle_data, src_fmt["time"]["column"], name)
            timing = src_fmt.get("power_timing", "instant")
            parts.append(_Part(part_file, part, timing, groups, name))
        t_lo = max(float(p.t[0]) for p in parts)
        t_hi = min(float(p.t[-1]) for p in parts)
        span = f"the sources all hold data from {labels.one(t_lo)} to {labels.one(t_hi)}"
        if not t_hi > t_lo:
            raise ConfigError(file, "sources", None, sources_.no_overlap(raw, labels))

    return parts, tf, origin, labels, t_lo, t_hi, span


def _window_bounds(
    window: dict[str, Any] | None, key: str, file: str, record: tuple, tol: float
) -> tuple[float, float]:
    """A window's start and end in the record's seconds (the whole span every part covers for
    ``None``): :class:`ConfigError` for a bound outside the data, an end before the start, a
    part without a row in it."""
    parts, tf, origin, _, t_lo, t_hi, span = record
    if window is None:
        start, end = t_lo, t_hi
    else:
        start = _bound(file, f"{key}.start", window["start"], tf, origin)
        end = _bound(file, f"{key}.end", window["end"], tf, origin)
        if start < t_lo - tol or start > t_hi + tol:
            raise ConfigError(file, f"{key}.start", window["start"], f"outside the data: {span}")
        if end > t_hi + tol or end < t_lo - tol:
            raise ConfigError(file, f"{key}.end", window["end"], f"outside the data: {span}")
        if not end > start:
            raise ConfigError(
                file, f"{key}.end", window["end"], f"must be after start ({window['start']!r})"
            )
        for p in parts:
            inside = np.count_nonzero((p.t >= start - tol) & (p.t <= end + tol))
            if inside == 0:
                raise ConfigError(
                    p.file,
                    key,
                    f"{window['start']} .. {window['end']}",
                    "no data row in the window",
                )
    return start, end


def _add_part(
    acc: dict[str, Any],
    p: _Part,
    grid: np.ndarray,
    step: float,
    region: tuple[float, float],
    cleaning: Mapping[str, Any],
    labels: _Labels,
    vehicle_data: Mapping[str, Any],
) -> None:
    """One part's contribution to the tidy table in ``acc`` (:func:`tidy`): its channels
    gap-filled on its completed time axis, then averaged over each step (temperatures per
    channel, powers per sum), and its flags."""
    hold, max_gap, resampled = acc["hold"], acc["max_gap"], acc["resampled"]
    names = irradiance_names(vehicle_data)
    channels_irr = _channels(vehicle_data, IRRADIANCE)
    channel_means, power, extra = acc["channel_means"], acc["power"], acc["extra"]
    hold_errors = acc["hold_errors"]
    t_full, rows = _complete_axis(p.t, p.dt_log)
    _check_temperatures(p.file, p.groups, p.t, region, cleaning, labels)
    filled_parts: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for group, found in p.groups.items():
        if found:
            filled_parts[group] = _fill_channels(
                p.file,
                [c for c, _, _ in found],
                [v for _, _, v in found],
                t_full,
                rows,
                p.dt_log,
                max_gap,
                region,
                labels,
            )
    p_tol = 1e-6 * min(p.dt_log, step)
    temps = [g for g in TEMPERATURE_GROUPS if g in filled_parts]
    if temps:
        t_values = np.hstack([filled_parts[g][0] for g in temps])
        t_flags = np.any(np.hstack([filled_parts[g][1] for g in temps]), axis=1)
        t_means, used = _bin_means(t_full, t_values, t_flags, grid, step, p_tol)
        acc["t_filled"] |= used
        col = 0
        for group in temps:
            for c, (_, weight, _) in enumerate(p.groups[group]):
                channel_means[group].append((weight, t_means[:, col + c]))
            col += len(p.groups[group])
    # powers: heater and fan sums (then known heat flows, then each irradiance channel,
    # when declared), integrated over [t_n, t_n + step)
    sums, slots = [], []
    p_flags = np.zeros(t_full.size, dtype=bool)
    for group in (*POWER_GROUPS, KNOWN_HEAT):
        if group in filled_parts:
            values, flags = filled_parts[group]
            sums.append(values.sum(axis=1))
            slots.append(group)
            p_flags |= flags.any(axis=1)
    if IRRADIANCE in filled_parts:
        values, flags = filled_parts[IRRADIANCE]
        mine = [
            n
            for n, c in zip(names, channels_irr, strict=True)
            if p.source is None or c.get("source") == p.source
        ]
        for i, name in enumerate(mine):
            sums.append(values[:, i])
            slots.append(name)
        p_flags |= flags.any(axis=1)
    if not sums:
        return
    if hold == "first_order":  # values at t_n, linear between (config: instant timing)
        q, used = _bin_means(t_full, np.column_stack(sums), p_flags, grid, step, p_tol)
    else:
        q, used = _power_means(
            t_full, np.column_stack(sums), p_flags, grid, step, p.dt_log, p.timing, p_tol
        )
    acc["q_filled"] |= used
    part_Q_H = np.zeros(grid.size)
    fine_Q_H = np.zeros(t_full.size)
    for i, slot in enumerate(slots):
        if slot in POWER_GROUPS:
            power[slot] = power[slot] + q[:, i]
        else:
            extra[{KNOWN_HEAT: "Q_known"}.get(slot, slot)] = q[:, i]
        if slot in (*POWER_GROUPS, KNOWN_HEAT):
            part_Q_H = part_Q_H + q[:, i]
            fine_Q_H = fine_Q_H + sums[i]
    if resampled:
        # how far the straight lines between the rows miss the logged signal (with
        # several sources, the sum of each source's: a bound on the whole)
        if any(slot in (*POWER_GROUPS, KNOWN_HEAT) for slot in slots):
            e = _hold_error(t_full, fine_Q_H, grid, part_Q_H)
            hold_errors["Q_H"] = hold_errors["Q_H"] + e if "Q_H" in hold_errors else e
        for i, slot in enumerate(slots):
            if slot in names:
                hold_errors[slot] = _hold_error(t_full, sums[i], grid, q[:, i])


def tidy(
    raw: pd.DataFrame | Mapping[str, pd.DataFrame],
    vehicle_data: dict[str, Any],
    window: dict[str, Any] | None,
    file: str,
    window_key: str | None = None,
) -> pd.DataFrame:
    """The tidy table (module docstring) of one window of a raw file read by :func:`read_raw`,
    or of a record of several sources read by :func:`read_record_part`
    (``raw`` then maps each source to its table on the record's UTC axis).

    ``vehicle_data`` is the validated vehicle config as plain data (``Vehicle.data``);
    ``window`` is a window of it (``start``/``end`` in the file's time notation, or ISO 8601
    for a file of instants or a record of sources; :func:`railtherm.data.timeaxis.instant`) or
    ``None`` for the whole recording (with sources: the span every source covers); ``file``
    names the raw file (or the record) in messages, ``window_key`` the window (default: found
    in ``vehicle_data``, e.g. ``windows.kvalue``).

    With sources, each source is gap-filled on its own time axis and averaged over each tidy
    step on its own (:func:`_bin_means`, :func:`_power_means`); a group's mean then weights
    every channel of every source, powers add up across sources, and a row is ``filled`` when
    any source's samples in it were. The default step is the coarsest source's logger step.

    Raises :class:`DataError` for a missing channel (file, column), a value that is no number,
    a gap longer than ``cleaning.max_gap_s`` (file, column, time); :class:`ConfigError` for a
    window outside the data (file, the window's start or end, the data's range) or without any
    data row.
    """
    hold = input_hold(vehicle_data)
    cleaning = vehicle_data.get("cleaning") or {}
    max_gap = float(cleaning.get("max_gap_s", 900.0))
    key = window_key or _window_key(vehicle_data, window)

    record = _record(raw, vehicle_data, file)
    parts, labels = record[0], record[3]

    # the window, in the record's seconds
    dt_log = max(p.dt_log for p in parts)
    step = float(cleaning.get("step_s") or dt_log)
    tol = 1e-6 * min(min(p.dt_log for p in parts), step)
    start, end = _window_bounds(window, key, file, record, tol)
    n_steps = int(np.floor((end - start) / step + 1e-9))
    grid = start + np.arange(n_steps + 1) * step
    region = (grid[0] - step / 2.0, grid[-1] + step)

    # per source: per-channel gap filling on its completed time axis, then its means over
    # each step (temperatures per channel, powers per sum)
    channel_means: dict[str, list[tuple[float, np.ndarray]]] = {g: [] for g in TEMPERATURE_GROUPS}
    t_filled = np.zeros(grid.size, dtype=bool)
    q_filled = np.zeros(grid.size, dtype=bool)
    power = {group: np.zeros(grid.size) for group in POWER_GROUPS}
    extra: dict[str, np.ndarray] = {}
    hold_errors: dict[str, np.ndarray] = {}
    resampled = hold == "first_order" and step > dt_log + tol
    acc = {
        "hold": hold,
        "max_gap": max_gap,
        "resampled": resampled,
        "channel_means": channel_means,
        "t_filled": t_filled,
        "q_filled": q_filled,
        "power": power,
        "extra": extra,
        "hold_errors": hold_errors,
    }
    for p in parts:
        _add_part(acc, p, grid, step, region, cleaning, labels, vehicle_data)
    t_filled, q_filled = acc["t_filled"], acc["q_filled"]
    names = irradiance_names(vehicle_data)
    means: dict[str, np.ndarray] = {}
    spread = np.zeros(grid.size)
    for group in TEMPERATURE_GROUPS:
        found = channel_means[group]
        if not found:
            means[group] = np.full(grid.size, np.nan)
            continue
        w = np.array([weight for weight, _ in found])
        x = np.column_stack([m for _, m in found])
        means[group] = x @ w / w.sum()
        if group == "indoor_air":
            dev = x - means[group][:, None]
            spread = np.sqrt(np.maximum((dev * dev) @ w / w.sum(), 0.0))
    Q_H = power["heater_power"] + power["fan_power"]
    if "Q_known" in extra:
        Q_H = Q_H + extra["Q_known"]
    ordered = (["Q_known"] if "Q_known" in extra else []) + [n for n in names if n in extra]
    hold_order = [n for n in ("Q_H", *names) if n in hold_errors]

    out = pd.DataFrame(
        {
            "time": grid - start,
            "timestamp": labels.many(grid),
            "T": means["indoor_air"],
            "T_veh": means["surface"],
            "T_o": means["outdoor_air"],
            "Q_H": Q_H,
            "Q_heater": power["heater_power"],
            "Q_fan": power["fan_power"],
            "T_spread": spread,
            "filled": (t_filled | q_filled).astype(np.int64),
            **{name: extra[name] for name in ordered},
            **{f"{name}{HOLD_ERROR_SUFFIX}": hold_errors[name] for name in hold_order},
        },
        columns=[
            *TIDY_COLUMNS,
            *ordered,
            *(f"{name}{HOLD_ERROR_SUFFIX}" for name in hold_order),
        ],
    )
    out.attrs = {
        "file": file,
        "window": key,
        "step_s": step,
        "logger_step_s": dt_log,
        "power_timing": parts[0].timing,
        "input_hold": hold,
    }
    return out


def clean_window(
    raw_path: str | os.PathLike[str],
    vehicle_data: dict[str, Any],
    window_name: str,
    file_label: str | None = None,
) -> pd.DataFrame:
    """Read ``raw_path`` and return the tidy table of the window ``window_name``.

    ``kvalue`` is ``windows.kvalue``, ``record`` the whole file, any other name the
    identification window of that name (see :func:`window_spec`; ``raw_path`` must be the raw
    file that window names). ``file_label`` names the file in messages (default: ``raw_path``).
    """
    _, window, key = window_spec(vehicle_data, window_name)
    file = file_label or str(raw_path)
    raw = read_raw(raw_path, vehicle_data["format"], label=file)
    return tidy(raw, vehicle_data, window, file, window_key=key)


def clean_windows(
    vehicle_data: dict[str, Any],
    sources: Mapping[str, str | Mapping[str, str]],
    workdir: str | os.PathLike[str] = ".",
) -> dict[str, pd.DataFrame]:
    """The tidy table of each window named in ``sources`` (window name -> the raw file it is
    cut from, relative to ``workdir``, as messages name it, or with sources {source: path};
    names as in :func:`window_spec`),
    in the order of ``sources``, each raw file read once."""
    raws: dict[str, Any] = {}
    tables = {}
    for name, path in sources.items():
        _, window, key = window_spec(vehicle_data, name)
        label = path if isinstance(path, str) else sources_.label(path)
        if label not in raws:
            raws[label] = read_record_part(path, vehicle_data, workdir)
        tables[name] = tidy(raws[label], vehicle_data, window, label, window_key=key)
    return tables


def read_record_part(
    path: str | Mapping[str, str],
    vehicle_data: Mapping[str, Any],
    workdir: str | os.PathLike[str] = ".",
) -> pd.DataFrame | dict[str, pd.DataFrame]:
    """One part of a vehicle's record, relative to ``workdir``: a raw file read by
    :func:`read_raw` with the vehicle's ``format``, or with sources ({source: path}) each
    source's file on the record's UTC axis (:func:`railtherm.data.sources.align`)."""
    if isinstance(path, str):
        local = os.path.join(str(workdir), path)
        return read_raw(local, vehicle_data["format"], label=path)
    raws = {
        name: read_raw(
            os.path.join(str(workdir), file), vehicle_data["sources"][name]["format"], label=file
        )
        for name, file in path.items()
    }
    return sources_.align(raws, vehicle_data)


# ---------------------------------------------------------------------------------------------
# Writing


def write_tidy(df: pd.DataFrame, path: str | os.PathLike[str]) -> None:
    """Write a tidy table as CSV: no index, floats in repr (shortest round-trip) form, NaN as an
    empty field, ``\\n`` line ends; the same table always gives the same bytes (``.gz``: gzip
    with mtime 0)."""
    path = str(path)
    directory = os.path.dirname(path)
    if directory:
        os.makedirs(directory, exist_ok=True)
    text = df.to_csv(index=False, lineterminator="\n", float_format=None)
    data = text.encode("utf-8")
    if path.endswith(".gz"):
        data = gzip.compress(data, compresslevel=6, mtime=0)
    with open(path, "wb") as stream:
        stream.write(data)


def read_tidy(path: str | os.PathLike[str]) -> pd.DataFrame:
    """Read a table written by :func:`write_tidy` (``timestamp`` stays as written: text for ISO
    labels, numbers for seconds)."""
    df = pd.read_csv(path)
    if df["timestamp"].dtype == object or pd.api.types.is_string_dtype(df["timestamp"]):
        df["timestamp"] = df["timestamp"].astype(str)
    return df
