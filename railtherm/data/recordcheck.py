"""A vehicle's record against the layout its configuration declares, as
:func:`railtherm.config.load_vehicle` checks it before any job: each source's ``format``
(:func:`check_format`), each raw file's columns read once and every declared column found in
it (:func:`source_layout`, with the nearest names and the separator or decimal a file seems to
use where one is missing), the ``sources`` of a record from several systems with their files
and channels (:func:`check_sources`), and each channel's group, unit and source
(:func:`check_channels`). Errors are :class:`~railtherm.errors.ConfigError` naming the vehicle
file, the key and the value."""

from __future__ import annotations

import difflib
import os
from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any

import pandas as pd

from railtherm.data import sources, timeaxis, units
from railtherm.data.ingest import CHANNEL_GROUPS, irradiance_names
from railtherm.data.rawfile import (
    RawLayout,
    read_columns,
    read_layout,
    separator_hint,
)
from railtherm.data.readers import elsewhere_hint, reader_kind
from railtherm.errors import ConfigError, DataError
from railtherm.yamlio import words

__all__ = [
    "UNIT_KINDS",
    "check_channels",
    "check_format",
    "check_sources",
    "fmt_time",
    "normalise_path",
    "source_layout",
]


def normalise_path(path: str, workdir: str) -> str:
    return os.path.relpath(os.path.normpath(path), workdir)


def fmt_time(value: Any) -> str:
    if isinstance(value, pd.Timestamp):
        return value.isoformat()
    return f"{value:g}"


def source_layout(
    file: str,
    name: str,
    raw: str,
    local: str,
    normalised: str,
    fmt: dict[str, Any],
    layouts: Mapping[str, RawLayout],
) -> RawLayout:
    """Layout of one raw file: the campaign's planned layout if the campaign writes it, else read.

    Planned layouts win even over a file on disk: that file may be stale (from an earlier
    campaign) and the workflow is about to rewrite it, so the plan is what the data will be.
    """
    key = f"raw_files.{name}"
    time = fmt["time"]
    planned = layouts.get(normalised)
    if planned is not None or not os.path.exists(local):
        if planned is None:
            planned_too = "; the campaign does not plan it either" if layouts else ""
            raise ConfigError(
                file, key, raw, f"raw file not found (looked for {normalised}{planned_too})"
            )
        if time["column"] not in planned.columns:
            raise _missing_column(file, "format.time.column", time["column"], normalised, planned)
        if planned.time_format != time["format"]:
            raise ConfigError(
                file,
                "format.time.format",
                time["format"],
                f"the campaign writes {normalised} with time format {planned.time_format}",
            )
        return planned
    try:
        columns = read_columns(local, fmt=fmt)
    except DataError as exc:
        raise ConfigError(file, key, raw, f"{normalised}: {exc.reason}") from None
    if time["column"] not in columns:
        hint = separator_hint(columns, fmt["separator"])
        hint = elsewhere_hint(local, time["column"]) or hint  # a workbook's other sheet/row
        raise ConfigError(
            file,
            "format.time.column",
            time["column"],
            f"not a column of {normalised} ({hint}columns: {words(columns)})",
        )
    try:
        layout = read_layout(local, fmt=fmt)
    except DataError as exc:
        if exc.value is None:  # about the file, not one of its values
            raise ConfigError(file, key, raw, f"{normalised}: {exc.reason}") from None
        tf = timeaxis.time_format(time)
        which = ("format.time.format", time["format"])  # the key whose value is in doubt
        if tf.timezone and "daylight-saving" in exc.reason:
            which = ("format.time.dst", tf.dst)
        elif tf.timezone and "format.time.timezone" in exc.reason:
            which = ("format.time.timezone", tf.timezone)
        fix = timeaxis.fix(exc.value, tf, fmt["decimal"])
        raise ConfigError(
            file, *which, f"{normalised} column '{exc.key}' {exc.reason}: {exc.value!r}{fix}"
        ) from None
    return replace(layout, path=normalised)  # the path as the config names it


def _missing_column(
    file: str, key: str, column: str, raw: str, layout: RawLayout, local: str | None = None
) -> ConfigError:
    close = difflib.get_close_matches(column, layout.columns, n=1)
    hint = f"did you mean '{close[0]}'? " if close else ""
    hint = separator_hint(layout.columns, "") or hint
    hint = elsewhere_hint(local, column) or hint  # a workbook: on another sheet or row?
    return ConfigError(
        file, key, column, f"not a column of {raw} ({hint}columns: {words(layout.columns)})"
    )


UNIT_KINDS = {
    **dict.fromkeys(("indoor_air", "surface", "outdoor_air"), ("temperature", "degC")),
    **dict.fromkeys(("heater_power", "fan_power", "heat_flows"), ("power", None)),
    "irradiance": ("irradiance", None),
}


def _check_stated_unit(file: str, key: str, group: str, channel: Mapping[str, Any]) -> None:
    """A column whose name states a unit (``T [°F]``, ``P_kW``) declared in another one is
    refused, naming both; a channel with its own scale or offset is taken as declared."""
    if "scale" in channel or "offset" in channel:
        return
    kind, default = UNIT_KINDS[group]
    stated = units.stated_unit(channel["column"], kind)
    declared = channel.get("unit", default)
    if stated is None or stated == declared:
        return
    raise ConfigError(
        file,
        f"{key}.unit",
        declared,
        f"the column '{channel['column']}' says {units.WORDS.get(stated, stated)}: declare "
        f"unit: {stated} (a value read in the wrong unit moves every parameter), or give the "
        "channel's scale and offset if its name is wrong",
    )


def check_format(file: str, fmt: dict[str, Any], prefix: str, paths: Sequence[str] = ()) -> None:
    """A ``format`` section (``prefix``: its key, e.g. ``sources.power.format``) of the raw
    files ``paths``: separator and decimal mark differ where a text reader splits the lines
    (a workbook has cells, no separator: a decimal comma in its text cells is its own); the
    time column's notation, zone, dst rule and start are valid."""
    workbook = bool(paths) and all(reader_kind(p, fmt) == "excel" for p in paths)
    if fmt["separator"] == fmt["decimal"] and not workbook:
        raise ConfigError(
            file, f"{prefix}.decimal", fmt["decimal"], f"must differ from {prefix}.separator"
        )
    try:
        timeaxis.declared(file, fmt["time"])  # format, timezone and dst rule of the time column
    except ConfigError as exc:
        raise _prefixed(exc, "format", prefix) from None


def _prefixed(exc: ConfigError, old: str, new: str) -> ConfigError:
    """``exc`` with a key that starts with ``old`` moved under ``new``."""
    key = exc.key
    if key == old or key.startswith(f"{old}."):
        key = new + key[len(old) :]
    return ConfigError(exc.file, key, exc.value, exc.reason)


def check_sources(
    file: str,
    data: dict[str, Any],
    yaml_dir: str,
    workdir: str,
    layouts: Mapping[str, RawLayout] | None,
) -> tuple[
    dict[str, str], dict[str, dict[str, str]], dict[str, RawLayout], dict[str, dict[str, RawLayout]]
]:
    """The record's sources (:mod:`railtherm.data.sources`) against their files: each
    source's format and files, the same parts in every source, every source placed on UTC
    (a zone for instants, a start for elapsed time), their spans overlapping, every channel
    naming a source whose files hold its column. Returns ``(raw_files, source_files,
    layouts, source_layouts)``: each part's label, its files by source, the part's span on
    UTC as one layout (ISO 8601, from the latest first time to the earliest last) for the
    windows' checks, and each source's own layouts by part."""
    declared_sources = data[sources.SOURCES]
    for key in ("raw_files", "format"):
        if key in data:
            raise ConfigError(
                file,
                key,
                data[key] if key == "raw_files" else None,
                "a record declared as sources gives its files and format per source "
                f"(sources.<name>.files, sources.<name>.format): remove {key}",
            )
    parts: list[str] | None = None
    first_source = ""
    source_files: dict[str, dict[str, str]] = {}
    per_source: dict[str, dict[str, RawLayout]] = {}
    spans: dict[str, dict[str, tuple[pd.Timestamp, pd.Timestamp, float | None, str]]] = {}
    for name, source in declared_sources.items():
        prefix = f"{sources.SOURCES}.{name}"
        fmt = source["format"]
        check_format(file, fmt, f"{prefix}.format", list((source.get("files") or {}).values()))
        tf = timeaxis.time_format(fmt["time"])
        if not tf.absolute:
            try:
                timeaxis.start_instant(file, tf)
            except ConfigError as exc:
                raise _prefixed(exc, "format", f"{prefix}.format") from None
        if parts is None:
            parts, first_source = list(source["files"]), name
        elif set(source["files"]) != set(parts):
            raise ConfigError(
                file,
                f"{prefix}.files",
                sorted(source["files"]),
                f"must name the same parts of the record as {sources.SOURCES}.{first_source}"
                f".files ({words(parts)}): every source has a file for every part",
            )
        per_source[name] = {}
        for part, raw in source["files"].items():
            local = os.path.normpath(os.path.join(yaml_dir, raw))
            normalised = normalise_path(local, workdir)
            source_files.setdefault(part, {})[name] = normalised
            try:
                layout = source_layout(file, part, raw, local, normalised, fmt, layouts or {})
            except ConfigError as exc:
                exc = _prefixed(exc, f"raw_files.{part}", f"{prefix}.files.{part}")
                raise _prefixed(exc, "format", f"{prefix}.format") from None
            per_source[name][part] = layout
            t0 = sources.source_utc0(name, source, layout.t_first, file)
            t1 = sources.source_utc0(name, source, layout.t_last, file)
            spans.setdefault(part, {})[name] = (t0, t1, layout.step_s, normalised)
    _check_source_channels(file, data, per_source)

    raw_files: dict[str, str] = {}
    found: dict[str, RawLayout] = {}
    for part, by_source in spans.items():
        raw_files[part] = sources.label(source_files[part])
        t_first = max(t0 for t0, _, _, _ in by_source.values())
        t_last = min(t1 for _, t1, _, _ in by_source.values())
        if not t_last > t_first:
            listed = "; ".join(
                f"sources.{n} ({path}) from {fmt_time(t0)} to {fmt_time(t1)}"
                for n, (t0, t1, _, path) in by_source.items()
            )
            raise ConfigError(
                file,
                sources.SOURCES,
                None,
                f"the sources' times do not overlap ({listed}): check each source's "
                "format.time (zone, start) and clock_offset_s",
            )
        steps = [step for _, _, step, _ in by_source.values() if step]
        found[part] = RawLayout(
            path=raw_files[part],
            columns=tuple(c for layout in per_source.values() for c in layout[part].columns),
            time_column="time",
            time_format="iso",
            t_first=t_first,
            t_last=t_last,
            step_s=max(steps) if steps else None,
            gap_s=max((layout[part].gap_s or 0.0) for layout in per_source.values()) or None,
        )
    return raw_files, source_files, found, per_source


def _check_source_channels(
    file: str, data: dict[str, Any], per_source: dict[str, dict[str, RawLayout]]
) -> None:
    """Every channel names a declared source (the one source by default), whose every file
    holds its column; no column used twice within a source, nor its time column."""
    names = list(per_source)
    used: dict[tuple[str, str], str] = {}
    for group in CHANNEL_GROUPS:
        for i, channel in enumerate(data["channels"].get(group, [])):
            key = f"channels.{group}[{i}]"
            name = channel.get("source")
            if name is None:
                if len(names) > 1:
                    raise ConfigError(
                        file,
                        f"{key}.source",
                        None,
                        f"missing: with several sources every channel names its source "
                        f"(one of {words(names)})",
                    )
                name = channel["source"] = names[0]
            if name not in per_source:
                close = difflib.get_close_matches(str(name), names, n=1)
                hint = f"did you mean '{close[0]}'? " if close else ""
                raise ConfigError(
                    file,
                    f"{key}.source",
                    name,
                    f"not a declared source ({hint}known: {words(names)})",
                )
            column = channel["column"]
            time_column = data[sources.SOURCES][name]["format"]["time"]["column"]
            if column == time_column:
                raise ConfigError(
                    file,
                    f"{key}.column",
                    column,
                    f"is the time column of sources.{name} (sources.{name}.format.time.column)",
                )
            if (name, column) in used:
                raise ConfigError(
                    file,
                    f"{key}.column",
                    column,
                    f"column of sources.{name} already used by {used[name, column]}",
                )
            used[name, column] = f"{key}.column"
            for part, layout in per_source[name].items():
                if column not in layout.columns:
                    raise _missing_column(
                        file,
                        f"{key}.column",
                        column,
                        f"{layout.path or part} (sources.{name})",
                        layout,
                    )
            _check_stated_unit(file, key, group, channel)
    idle = [
        n
        for n in names
        if not any(
            channel.get("source") == n
            for group in CHANNEL_GROUPS
            for channel in data["channels"].get(group, [])
        )
    ]
    if idle:
        raise ConfigError(
            file,
            f"{sources.SOURCES}.{idle[0]}",
            None,
            "no channel names this source: name it in a channel's source, or remove it",
        )


def check_channels(
    file: str,
    data: dict[str, Any],
    layouts: dict[str, RawLayout],
    local: Mapping[str, str] | None = None,
) -> None:
    """Every channel column is in every raw file; no column (nor the time column) used twice."""
    time_column = data["format"]["time"]["column"]
    used: dict[str, str] = {}
    for group in CHANNEL_GROUPS:
        for i, channel in enumerate(data["channels"].get(group, [])):
            key = f"channels.{group}[{i}].column"
            column = channel["column"]
            if column == time_column:
                raise ConfigError(file, key, column, "is the time column (format.time.column)")
            if column in used:
                raise ConfigError(file, key, column, f"column already used by {used[column]}")
            used[column] = key
            if "source" in channel:
                raise ConfigError(
                    file,
                    f"channels.{group}[{i}].source",
                    channel["source"],
                    "names a source, but the record is declared as raw_files and format: "
                    "declare it under sources, or remove the key",
                )
            for name, layout in layouts.items():
                if column not in layout.columns:
                    where = (local or {}).get(name)
                    raise _missing_column(file, key, column, layout.path or name, layout, where)
            _check_stated_unit(file, f"channels.{group}[{i}]", group, channel)
    inputs: dict[str, str] = {}
    for i, name in enumerate(irradiance_names(data)):
        key = f"channels.irradiance[{i}].name"
        if name in inputs:
            raise ConfigError(file, key, name[2:], f"input {name} already named by {inputs[name]}")
        inputs[name] = key
