"""Typical-year weather for the annual heating energy: outdoor temperature T_o and, where a
fit has apertures, global horizontal irradiance, from the files weather services publish.

Readers (``kind``, or recognised from the file):

- ``tmy3``: NREL's TMY3 CSV (``pvlib.iotools.read_tmy3``);
- ``epw``: EnergyPlus weather (``pvlib.iotools.read_epw``);
- ``pvgis``: a PVGIS typical meteorological year in its CSV, JSON or EPW output
  (``pvlib.iotools.read_pvgis_tmy``);
- ``csv``: a plain table with a time column (declared as a vehicle's raw files declare
  theirs, :mod:`railtherm.data.timeaxis`), ``T_o`` in degC and optionally ``ghi`` in W/m².

pvlib, the maintained library of the photovoltaic community for exactly these files, is an
optional dependency (``pip install railtherm[weather]``); a plain CSV needs none.

A typical year is a sequence of records of one calendar year's length (8760 or 8784 hours),
hourly or at a finer regular step (a plain CSV), months taken from different years. Each value
is placed on the instant it describes, as seconds from 00:00 of 1 January, local standard
time (the clock of a service profile), whatever year its month was taken from:

- TMY3 (NREL's manual, and pvlib's reader): each record is stamped at the end of its hour,
  in local standard time, 01:00 to 24:00; the dry-bulb temperature is the value at the stamp,
  the irradiance the total of the hour before it. The record stamped 01:00 is placed at 01:00
  (its irradiance at 00:30), and the one stamped 24:00 of 31 December at 00:00.
- EPW (EnergyPlus's weather converter): the same, hour N being the hour ending at N:00 (pvlib
  labels it by the hour's start, N - 1).
- PVGIS: stamped in UTC (``time(UTC)``), each value at its stamp: placed on the local standard
  time of the longitude's zone, UTC + round(longitude / 15) h, as pvlib's ``roll_utc_offset``
  does; a PVGIS year in EPW layout is read as an EPW in UTC.
- a plain CSV: each value at its stamp, in the clock the file is written in.

A year whose values run past the year's end (a UTC year moved to a zone east of Greenwich)
wraps round: the typical year is read as one that repeats. :func:`on_grid` puts it on a
simulation grid: linear between the records (``first_order``, the default: a temperature is a
continuous signal) or each held until the next (``zero_order``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from railtherm.data import units
from railtherm.errors import ConfigError, first_line

__all__ = ["KINDS", "Weather", "load_year", "on_grid", "read_weather", "write_year"]

KINDS = ("tmy3", "epw", "pvgis", "csv")
HOUR_S = 3600.0


@dataclass(frozen=True, eq=False)
class Weather:
    """A typical year: hourly ``T_o`` (degC) and ``ghi`` (W/m², None where the file has
    none) at ``t_s`` (seconds from 00:00 of 1 January, local standard time, each value at
    the instant it describes, in rising order), the file's ``time`` stamps in the same
    order, where the year comes from (``name``, ``source``, ``latitude``, ``longitude``),
    and ``ghi_shift_s``: where the irradiance sits against ``t_s`` (-1800 s for the total of
    the hour before a stamp)."""

    name: str
    source: str
    time: pd.DatetimeIndex
    t_s: np.ndarray
    T_o: np.ndarray
    ghi: np.ndarray | None
    latitude: float = math.nan
    longitude: float = math.nan
    meta: dict = field(default_factory=dict)
    step_s: float = HOUR_S
    ghi_shift_s: float = 0.0

    @property
    def hours(self) -> int:
        """The year's length in hours (8760 or 8784)."""
        return int(round(len(self.t_s) * self.step_s / HOUR_S))


READ_YEAR_SUFFIX = ".year.pickle"


def write_year(year: Weather, path: str | Path) -> None:
    """``year`` as read (:func:`read_weather`), for jobs that would otherwise each import the
    readers again (pvlib's import alone costs a second): the study's rule weather_year."""
    import pickle

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(pickle.dumps(year, protocol=5))


def load_year(path: str | Path) -> Weather:
    """A typical year: one :func:`write_year` wrote (``*.year.pickle``), else the file read
    by :func:`read_weather`."""
    if str(path).endswith(READ_YEAR_SUFFIX):
        import pickle

        year = pickle.loads(Path(path).read_bytes())
        if not isinstance(year, Weather):
            raise ConfigError(str(path), "weather", type(year).__name__, "not a typical year")
        return year
    return read_weather(path)


def _kind_of(path: Path) -> str:
    suffix = path.suffix.lower()
    if suffix == ".epw":
        return "epw"
    if suffix == ".json":
        return "pvgis"
    head = path.read_text(encoding="utf-8", errors="replace")[:400]
    if head.startswith("Latitude") or "PVGIS" in head[:200]:
        return "pvgis"
    first = head.splitlines()[0] if head else ""
    if first.count(",") == 6 and first.split(",")[0].strip().isdigit():
        return "tmy3"  # the TMY3 header: USAF, name, state, TZ, lat, lon, elevation
    return "csv"


_KIND_NAMES = {"tmy3": "an NREL TMY3", "epw": "an EnergyPlus EPW", "pvgis": "a PVGIS TMY"}


def _misread(path: Path, kind: str, err: BaseException) -> str:
    """Why ``path`` does not read as ``kind`` and the fix: the kind the file looks like."""
    looks = _kind_of(path)
    what = _KIND_NAMES.get(kind, "a plain CSV")
    cause = f"{type(err).__name__}: {first_line(err)}" if str(err).strip() else type(err).__name__
    if looks != kind:
        fix = (
            f"it looks like {_KIND_NAMES.get(looks, 'a plain CSV')} file: give kind "
            f"{looks} (railtherm energy --kind {looks}) or leave the kind out to recognise it"
        )
    else:
        fix = f"check that it is {what} file as its service publishes it"
    return f"does not read as {what} file ({cause}); {fix}"


def _pvlib(file: str):
    try:
        from pvlib import iotools
    except ImportError as err:  # pragma: no cover - the test environment has it
        raise ConfigError(
            file,
            "weather",
            "pvlib",
            "reading TMY3, EPW or PVGIS files needs pip install railtherm[weather] (pvlib)",
        ) from err
    return iotools


def _numbers(file: str, table: pd.DataFrame, column: str) -> np.ndarray:
    """A plain CSV's column as floats, empty cells NaN; text that is no number (a logger's
    "ERR") is a :class:`ConfigError` naming the file, the column, the value and its line."""
    text = table[column]
    values = pd.to_numeric(text, errors="coerce").to_numpy(dtype=float, na_value=np.nan)
    bad = np.isnan(values) & text.notna().to_numpy()
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ConfigError(
            file,
            column,
            str(text.iloc[i]),
            f"line {i + 2}: not a number: give "
            + ("the dry-bulb temperature in degC" if column == "T_o" else "the irradiance in W/m2"),
        )
    return values


def read_weather(path: str | Path, kind: str | None = None, time: dict | None = None) -> Weather:
    """The typical year in ``path`` (``kind``: one of :data:`KINDS`, default recognised from
    the file). ``time``: a plain CSV's time column as a vehicle config's ``format.time``
    declares it (default ``{column: time, format: iso}``). A file that is not a year of
    hourly records, or whose temperatures are missing or whose mean or extremes no climate
    has in degC (a file in degF or K: :func:`_check_climate`), is a :class:`ConfigError`
    naming the file and the column."""
    path = Path(path)
    file = str(path)
    if not path.is_file():
        raise ConfigError(file, "weather", file, "no such file")
    kind = kind or _kind_of(path)
    if kind not in KINDS:
        raise ConfigError(file, "kind", kind, f"expected one of {list(KINDS)}")
    ghi = None
    lat = lon = math.nan
    meta: dict = {}
    if kind == "csv":
        from railtherm.data import timeaxis

        spec = time or {"column": "time", "format": "iso"}
        try:
            table = pd.read_csv(path)
        except (pd.errors.ParserError, UnicodeDecodeError, ValueError) as err:
            raise ConfigError(file, "kind", kind, _misread(path, kind, err)) from err
        column = spec.get("column", "time")
        for needed in (column, "T_o"):
            if needed not in table.columns:
                raise ConfigError(file, "columns", list(table.columns), f"needs {needed!r}")
        tf = timeaxis.declared(file, spec)
        stamps = timeaxis.parse(file, table[column].astype(str), column, tf)
        index = pd.DatetimeIndex(stamps)
        T_o = _numbers(file, table, "T_o")
        if "ghi" in table.columns:
            ghi = _numbers(file, table, "ghi")
        name, source = path.stem, f"CSV {path.name}"
    else:
        iotools = _pvlib(file)
        # pvlib's readers fail on a file of another kind with whatever their parsing meets
        # (a missing header key, an index out of range, a bad number): every such failure is
        # the file's kind, said with the kind the file looks like
        try:
            if kind == "tmy3":
                data, meta = iotools.read_tmy3(file, map_variables=True)
                name = str(meta.get("Name", path.stem)).strip('"').title()
                state = meta.get("State", "")
                source = f"NREL TMY3 station {meta.get('USAF', '')} ({name}, {state})"
            elif kind == "epw":
                data, meta = iotools.read_epw(file)
                name = str(meta.get("city", path.stem))
                source = f"EPW {path.name} ({name}, {meta.get('country', '')})"
            else:
                out = iotools.read_pvgis_tmy(file, map_variables=True)
                data, meta = out[0], out[-1]
                name = path.stem
                source = f"PVGIS TMY {path.name}"
            where = {**meta.get("location", {}), **meta.get("inputs", {}), **meta}
            lat = float(where.get("latitude", math.nan))
            lon = float(where.get("longitude", math.nan))
            index = pd.DatetimeIndex(data.index)
            T_o = data["temp_air"].to_numpy(float)
        except Exception as err:  # noqa: BLE001 - a third-party parser's any failure
            raise ConfigError(file, "kind", kind, _misread(path, kind, err)) from err
        if "ghi" in data.columns:
            ghi = data["ghi"].to_numpy(float)
    n = len(T_o)
    step = HOUR_S
    if kind == "csv" and n > 1:  # hourly or finer, at a regular step
        gaps = np.asarray((index[1:] - index[:-1]).total_seconds(), dtype=float)
        step = float(np.median(gaps))
        if not (0 < step <= HOUR_S and HOUR_S % step == 0 and np.allclose(gaps, step)):
            raise ConfigError(file, "time", step, "a regular step of an hour or a divisor of it")
        first = index[0]
        if (first.month, first.day) != (1, 1):
            # the engine reads record 0 as 1 January: a year from July would book July's
            # heating as January's
            raise ConfigError(
                file,
                "time",
                str(table[column].iloc[0]),
                "the typical year starts here, not on 1 January: the months and the profile's "
                "weekdays count from the first record; reorder the rows so that the year "
                "runs from 1 January to 31 December",
            )
    if round(n * step / HOUR_S) not in (8760, 8784) or not math.isclose(
        n * step / HOUR_S, round(n * step / HOUR_S)
    ):
        raise ConfigError(
            file, "records", n, "a typical year spans 8760 (or 8784) hours of records"
        )
    missing = ~np.isfinite(T_o)
    if kind == "epw":  # EPW writes 99.9 for a dry-bulb temperature it does not have
        missing |= T_o >= EPW_MISSING_T
    if missing.any():
        i = int(np.flatnonzero(missing)[0])
        marker = f" (EPW's marker {EPW_MISSING_T:g})" if np.isfinite(T_o[i]) else ""
        raise ConfigError(
            file,
            f"{COLUMNS[kind]}[{i}]",
            float(T_o[i]),
            f"missing{marker}: a typical year has none",
        )
    _check_climate(file, kind, T_o)
    if ghi is not None:
        ghi = np.clip(np.nan_to_num(ghi, nan=0.0), 0.0, None)
    epw_layout = kind == "epw" or (kind == "pvgis" and path.suffix.lower() == ".epw")
    t_s = _instants(file, kind, index, lon, n * step, epw_layout)
    order = np.argsort(t_s, kind="stable")
    shift = -HOUR_S / 2.0 if kind in ("tmy3", "epw") else 0.0
    ghi = None if ghi is None else ghi[order]
    return Weather(
        name, source, index[order], t_s[order], T_o[order], ghi, lat, lon, dict(meta), step, shift
    )


EPW_MISSING_T = 99.9  # EnergyPlus weather format: a missing dry-bulb temperature


# how each kind of file stamps its values (module docstring)
STAMPS = {
    "tmy3": "the end of each hour, local standard time",
    "epw": "the end of each hour (hour N ends at N:00), local standard time",
    "pvgis": "UTC, each value at its stamp",
    "csv": "each value at its stamp",
}


def _instants(
    file: str, kind: str, index: pd.DatetimeIndex, lon: float, period_s: float, epw: bool
) -> np.ndarray:
    """Each value's instant in seconds from 00:00 of 1 January, local standard time, within
    the year (the module docstring); the month, day and clock of each stamp count, not the
    year its month came from."""
    stamps = pd.DatetimeIndex(index)
    if kind == "pvgis":
        utc = stamps.tz_convert("UTC").tz_localize(None) if stamps.tz is not None else stamps
        zone = round(lon / 15.0) if math.isfinite(lon) else 0
        stamps = utc + pd.Timedelta(hours=zone)
    elif stamps.tz is not None:
        stamps = stamps.tz_localize(None)  # as written: the file's local standard time
    if epw:  # pvlib labels hour N by its start; its values are at its end
        stamps = stamps + pd.Timedelta(hours=1)
    reference = 2000 if round(period_s / HOUR_S) == 8784 else 2001  # a leap year or not
    try:
        on_year = pd.to_datetime(
            {
                "year": reference,
                "month": stamps.month,
                "day": stamps.day,
                "hour": stamps.hour,
                "minute": stamps.minute,
                "second": stamps.second,
            }
        )
    except ValueError as err:  # 29 February in a year of 8760 hours
        raise ConfigError(
            file,
            "time",
            str(err),
            "29 February in a year of 8760 hours: give a leap year 8784 hourly records, or "
            "drop the day",
        ) from err
    seconds = (on_year - pd.Timestamp(reference, 1, 1)).dt.total_seconds().to_numpy(float)
    seconds = np.mod(seconds, period_s)
    if len(np.unique(seconds)) != len(seconds):
        order = np.argsort(seconds, kind="stable")
        i = int(np.flatnonzero(np.diff(seconds[order]) == 0)[0])
        first, second = (str(pd.DatetimeIndex(index)[order[k]]) for k in (i, i + 1))
        raise ConfigError(
            file,
            "time",
            f"{first} and {second}",
            "two records describe the same instant of the year: give each hour once",
        )
    return seconds


# the dry-bulb temperature's column as each kind of file names it, and its unit (degC in all)
COLUMNS = {"tmy3": "Dry-bulb (C)", "epw": "Dry Bulb Temperature", "pvgis": "T2m", "csv": "T_o"}
# Earth's climate: the extremes ever measured (-89.2 degC, Vostok 1983; 56.7 degC, Death
# Valley 1913) and the annual means of inhabited places (about -20 degC at Oymyakon to 35
# degC at Dallol), with a margin; a typical year of any place lies within
T_O_EXTREMES = (-90.0, 57.0)
T_O_ANNUAL_MEAN = (-30.0, 35.0)


def _check_climate(file: str, kind: str, T_o: np.ndarray) -> None:
    """Refuse a year whose mean or extremes no climate on Earth has in degC - a file in degF
    or K read as degC (a degF year read as degC is a hot year: 0 kWh of heating): a
    :class:`ConfigError` naming the file, the column, its unit, the observed mean and
    extremes, and what they are in the unit the numbers are more likely in."""
    lo, hi = (float(T_o.min()), float(T_o.max()))
    mean = float(T_o.mean())
    (x_lo, x_hi), (m_lo, m_hi) = T_O_EXTREMES, T_O_ANNUAL_MEAN
    if x_lo <= lo and hi <= x_hi and m_lo <= mean <= m_hi:
        return
    seen = f"mean {mean:.1f}, min {lo:.1f}, max {hi:.1f}"
    guesses = []
    for unit, (factor, shift) in units.TEMPERATURE_UNITS.items():
        if unit == "degC":
            continue
        c_lo, c_hi, c_mean = (factor * v + shift for v in (lo, hi, mean))
        if x_lo <= c_lo and c_hi <= x_hi and m_lo <= c_mean <= m_hi:
            guesses.append(
                f"read as {unit} they are mean {c_mean:.1f}, min {c_lo:.1f}, max {c_hi:.1f} degC"
            )
    why = "; ".join(guesses) + "; " if guesses else ""
    raise ConfigError(
        file,
        COLUMNS[kind],
        seen,
        f"the year's temperatures read in degC (the unit of a {kind} file's {COLUMNS[kind]}) "
        f"have no climate on Earth (extremes {x_lo:g} to {x_hi:g} degC, an annual mean "
        f"{m_lo:g} to {m_hi:g} degC): {why}check the unit: the file must give degC",
    )


def on_grid(
    weather: Weather, dt_s: float, hold: str = "first_order"
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(t_s, T_o, ghi) on the grid 0, dt, ... (seconds from 00:00 of 1 January, local
    standard time) up to one year (the weather's length) less a step: ``first_order``
    linear between the records' instants, ``zero_order`` each held until the next; the year
    closed over its end (the last record runs into the first: the typical year repeats)."""
    if hold not in ("first_order", "zero_order"):
        raise ValueError(f"hold: first_order or zero_order, got {hold!r}")
    period = len(weather.t_s) * weather.step_s
    t = np.arange(0.0, period, float(dt_s))

    def resample(values: np.ndarray, shift: float = 0.0) -> np.ndarray:
        at = np.mod(weather.t_s + shift, period)
        order = np.argsort(at, kind="stable")
        at, values = at[order], values[order]
        knots = np.concatenate([at[-1:] - period, at, at[:1] + period])
        closed = np.concatenate([values[-1:], values, values[:1]])
        if hold == "first_order":
            return np.interp(t, knots, closed)
        return closed[np.searchsorted(knots, t, side="right") - 1]

    ghi = None if weather.ghi is None else resample(weather.ghi, weather.ghi_shift_s)
    return t, resample(weather.T_o), ghi
