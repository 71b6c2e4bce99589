"""A record of several data-acquisition systems (a vehicle's ``sources``) on one UTC time axis.

A climatic wind tunnel's record comes from several systems: the cabin's temperature loggers,
the heater's power analyser, the tunnel controller. Each writes its own files, in its own
format, at its own rate, on its own clock. A vehicle config declares them under ``sources``::

    sources:
      cabin:   {files: {record: cabin.csv}, format: {time: {column: time, format: iso}}}
      power:   {files: {record: power.txt},
                format: {separator: "\\t", comment: "#",
                         time: {column: t_s, format: seconds, start: "2026-03-02T08:57:43+01:00"}}}
      tunnel:  {files: {record: tunnel.csv}, clock_offset_s: 40,
                format: {separator: ";", decimal: ",", time: {column: Zeit, format: iso,
                                                               timezone: UTC}}}

and each channel names its source (``channels.indoor_air[0].source: cabin``). Every source is
read by :func:`railtherm.data.ingest.read_raw` with its own format, then placed on UTC:

- instants (iso, a pattern, epoch, serial days) by their UTC offset or declared
  ``format.time.timezone`` (a naive time without either cannot be placed: refused);
- elapsed time (seconds, minutes, hours, days) from ``format.time.start``, the instant its
  zero stands for (with a UTC offset);
- then moved back by ``clock_offset_s``, how far that system's clock runs ahead of true time.

The record's axis counts seconds from the earliest source's first time (whole seconds), and
its timestamps are ISO 8601 in UTC. :func:`railtherm.data.ingest.tidy` averages each source
over each tidy step on its own and combines the groups (module docstring there).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import pandas as pd

from railtherm.data import timeaxis
from railtherm.errors import ConfigError

SOURCES = "sources"

# the record's time notation: ISO 8601 instants in UTC (window bounds without an offset are UTC)
RECORD_TIME = timeaxis.TimeFormat("iso", timezone="UTC")


def declared(vehicle_data: Mapping[str, Any]) -> bool:
    """Whether the vehicle's record is declared as sources (else ``raw_files`` and ``format``)."""
    return bool(vehicle_data.get(SOURCES))


def source_utc0(
    name: str, source: Mapping[str, Any], first: pd.Timestamp | float, file: str
) -> pd.Timestamp:
    """The UTC instant of a source's time ``first`` (a Timestamp for instants, seconds for
    elapsed time), its clock offset removed. :class:`ConfigError` naming
    ``sources.<name>.format.time.timezone`` for instants without a zone, and
    ``sources.<name>.format.time.start`` for elapsed time without its start."""
    fmt = source["format"]
    tf = timeaxis.time_format(fmt["time"])
    key = f"{SOURCES}.{name}.format.time"
    if tf.absolute:
        if getattr(first, "tzinfo", None) is None:
            raise ConfigError(
                file,
                f"{key}.timezone",
                None,
                "the times carry no UTC offset: declare the zone of this system's clock "
                "(e.g. UTC, Europe/Berlin), so that it can be aligned with the other sources",
            )
        utc = pd.Timestamp(first).tz_convert("UTC")
    else:
        try:
            start = timeaxis.start_instant(file, tf)
        except ConfigError as exc:
            raise ConfigError(
                exc.file, f"{SOURCES}.{name}.{exc.key}", exc.value, exc.reason
            ) from None
        utc = start + pd.Timedelta(seconds=float(first))
    return utc - pd.Timedelta(seconds=float(source.get("clock_offset_s", 0.0)))


def align(
    raws: Mapping[str, pd.DataFrame], vehicle_data: Mapping[str, Any]
) -> dict[str, pd.DataFrame]:
    """Each source's raw table of one part of the record (as
    :func:`railtherm.data.ingest.read_raw` reads it with the source's format) placed on the
    record's axis: the index counts seconds from the earliest source's start (whole seconds,
    UTC); ``attrs["utc_origin"]`` is that instant, ``attrs["source"]`` the source."""
    starts: dict[str, pd.Timestamp] = {}
    for name, raw in raws.items():
        source = vehicle_data[SOURCES][name]
        origin = raw.attrs.get("origin")
        first = origin if origin is not None else 0.0
        starts[name] = source_utc0(name, source, first, raw.attrs.get("file", name))
    origin = min(starts.values()).floor("s")
    out = {}
    for name, raw in raws.items():
        shift = (starts[name] - origin).total_seconds()
        table = raw.copy()
        table.index = pd.Index(raw.index.to_numpy(dtype=float) + shift, name="t_s")
        table.attrs = {**raw.attrs, "utc_origin": origin, "source": name}
        out[name] = table
    return out


def origin(record: Mapping[str, pd.DataFrame]) -> pd.Timestamp:
    """The UTC instant of a record's 0 s (:func:`align`)."""
    return next(iter(record.values())).attrs["utc_origin"]


def no_overlap(record: Mapping[str, pd.DataFrame], labels: Any) -> str:
    """The message for sources whose times do not overlap, naming each source's span."""
    spans = "; ".join(
        f"sources.{name} ({table.attrs.get('file', name)}) from {labels.one(table.index[0])} "
        f"to {labels.one(table.index[-1])}"
        for name, table in record.items()
    )
    return (
        f"the sources' times do not overlap ({spans}): check each source's time zone, "
        "format.time.start and clock_offset_s"
    )


def label(files: Mapping[str, str]) -> str:
    """How messages name a part of the record: its files joined by ' + '."""
    return " + ".join(files.values())
