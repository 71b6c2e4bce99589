"""Load and validate vehicle configs and the study config.

A vehicle YAML file is checked in two stages, and the first mistake found stops with one
:class:`~railtherm.errors.ConfigError` whose message names the file, the key path (for example
``channels.indoor_air[2].column``) and the value:

1. JSON Schema (Draft 2020-12) against ``railtherm/schemas/vehicle.schema.yaml``; schema
   defaults (sensor weight 1.0, unit degC, empty surface/fan lists, ...) are filled in.
2. Semantic checks against the raw files: every raw file exists (or is planned by the virtual
   wind-tunnel campaign), the time column and every channel column are in each file, no
   column is used twice, windows name a known file, their timestamps match the file's time
   format, start < end, and the windows lie inside the data; model bounds are ordered and
   initial values lie inside them.

Paths: relative ``raw_files`` paths are relative to the vehicle YAML's directory; the loaded
:class:`Vehicle` holds them normalised relative to ``workdir`` (the workflow's working
directory), the form in which the workflow and :func:`railtherm.synth.planned_layouts` name them.
"""

from __future__ import annotations

import copy
import datetime as dt
import difflib
import functools
import importlib.resources
import math
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import jsonschema
import pandas as pd
import yaml
from jsonschema import Draft202012Validator
from jsonschema.exceptions import ValidationError, best_match

from railtherm.errors import ConfigError, DataError
from railtherm.ingest import irradiance_names
from railtherm.rawfile import (
    MAX_ROWS,
    MIN_WINDOW_STEPS,
    RawLayout,
    read_columns,
    read_layout,
    separator_hint,
)

__all__ = [
    "Study",
    "Vehicle",
    "add_vehicle",
    "deep_merge",
    "load_study",
    "load_vehicle",
    "read_yaml",
    "study_context",
    "packaged_schema",
    "vehicle_schema",
]

CHANNEL_GROUPS = (
    "indoor_air",
    "surface",
    "outdoor_air",
    "heater_power",
    "fan_power",
    "heat_flows",
    "irradiance",
)
PARAMETERS = ("C_bar", "C", "K_veh", "C_veh", "K_i", "C_e", "K_o")


@dataclass(frozen=True)
class Vehicle:
    """One validated vehicle config.

    ``raw_files`` maps each raw-file name to its path normalised relative to the working
    directory; ``layouts`` maps the same names to the :class:`RawLayout` the checks used (read
    from the file, or planned by the campaign when the file does not exist yet). ``data`` is
    the whole validated YAML with schema defaults filled in and the study's defaults merged
    under its sections (``data["model"]`` is ``defaults.model`` deep-merged under the vehicle's
    own ``model``); ``format``, ``channels``, ``windows`` and ``model`` read from it.
    """

    id: str
    vehicle_class: str
    path: str
    synthetic: bool
    mass_kg: float
    surface_m2: float
    volume_m3: float
    raw_files: dict[str, str]
    data: dict[str, Any]
    layouts: dict[str, RawLayout] = field(default_factory=dict)

    @property
    def format(self) -> dict[str, Any]:
        return self.data["format"]

    @property
    def channels(self) -> dict[str, list[dict[str, Any]]]:
        return self.data["channels"]

    @property
    def windows(self) -> dict[str, Any]:
        return self.data["windows"]

    @property
    def model(self) -> dict[str, Any]:
        return self.data["model"]


@dataclass(frozen=True)
class Study:
    """The validated study: every vehicle (in config order) and the campaign path, if any.

    ``defaults`` is the study config's validated ``defaults`` section; ``campaign_data`` the
    loaded campaign (railtherm.synth.load_campaign) and ``layouts`` its planned raw-file
    layouts (None and empty without a campaign).
    """

    vehicles: dict[str, Vehicle]
    campaign: str | None
    defaults: dict[str, Any] = field(default_factory=dict)
    layouts: dict[str, RawLayout] = field(default_factory=dict)
    campaign_data: dict[str, Any] | None = None


# ---------------------------------------------------------------------------------------------
# YAML


class _UniqueKeyLoader(yaml.SafeLoader):
    """A safe loader that refuses a mapping with the same key twice (PyYAML keeps the last)."""


def _construct_unique_mapping(loader: _UniqueKeyLoader, node: yaml.MappingNode) -> dict:
    seen: dict[Any, yaml.Mark] = {}
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=True)
        if key in seen:
            raise yaml.constructor.ConstructorError(
                None,
                None,
                f"duplicate key {key!r} (first at line {seen[key].line + 1})",
                key_node.start_mark,
            )
        seen[key] = key_node.start_mark
    return loader.construct_mapping(node, deep=True)


_UniqueKeyLoader.add_constructor(
    yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_unique_mapping
)


MAX_YAML_VALUES = 100_000  # a vehicle config has a few hundred; checked before expansion


def _expanded_size(node: yaml.Node | None, memo: dict[int, int]) -> int:
    """How many values a YAML node stands for once every alias is expanded, counted on the
    composed node graph (an alias is the same node object, so each node is visited once):
    a document of nested aliases ("billion laughs") is refused in milliseconds, before it is
    built."""
    if node is None:
        return 0
    key = id(node)
    if key in memo:
        return memo[key]
    memo[key] = 1  # a recursive alias counts once
    if isinstance(node, yaml.MappingNode):
        size = 1 + sum(_expanded_size(k, memo) + _expanded_size(v, memo) for k, v in node.value)
    elif isinstance(node, yaml.SequenceNode):
        size = 1 + sum(_expanded_size(v, memo) for v in node.value)
    else:
        size = 1
    memo[key] = size
    return size


def _timestamps_to_text(value: Any) -> Any:
    """YAML turns unquoted timestamps into datetime objects; give them back as ISO strings."""
    if isinstance(value, dict):
        return {k: _timestamps_to_text(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_timestamps_to_text(v) for v in value]
    if isinstance(value, dt.datetime | dt.date):
        return value.isoformat()
    return value


def read_yaml(path: str | os.PathLike[str], display: str | None = None) -> Any:
    """Parse a YAML file; :class:`ConfigError` naming the file (and line) on any problem.

    Unquoted YAML timestamps come back as ISO 8601 strings; a key given twice in one mapping is
    an error. ``display`` is the file name used in messages (default: ``path``).
    """
    name = display or str(path)
    try:
        with open(path, encoding="utf-8") as stream:
            text = stream.read()
    except FileNotFoundError:
        raise ConfigError(name, "(file)", str(path), "file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(name, "(file)", str(path), f"cannot read the file: {exc}") from None
    try:
        loader = _UniqueKeyLoader(text)
        try:
            node = loader.get_single_node()
            size = _expanded_size(node, {})
            if size > MAX_YAML_VALUES:
                raise ConfigError(
                    name,
                    "(file)",
                    f"{size:,} values",
                    f"its aliases (*name) expand to more than {MAX_YAML_VALUES:,} values, far "
                    "beyond any config (an alias bomb?); write the values out",
                )
            data = loader.construct_document(node) if node is not None else None
        finally:
            loader.dispose()
    except yaml.YAMLError as exc:
        problem_mark = getattr(exc, "problem_mark", None)
        context_mark = getattr(exc, "context_mark", None)
        mark = context_mark or problem_mark
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        context = getattr(exc, "context", None)
        if context:
            problem = f"{context}, {problem}"
        if problem_mark is not None:
            problem += f" (at line {problem_mark.line + 1}, column {problem_mark.column + 1})"
        if mark is None:
            raise ConfigError(name, "(file)", None, f"YAML syntax error: {problem}") from None
        lines = text.splitlines()
        source = lines[mark.line].strip() if mark.line < len(lines) else ""
        raise ConfigError(
            name, f"line {mark.line + 1}", source, f"YAML syntax error: {problem}"
        ) from None
    return _timestamps_to_text(data)


# ---------------------------------------------------------------------------------------------
# JSON Schema with default filling


def _extend_with_default(validator_class: type) -> type:
    """A validator class that fills in ``default`` values of ``properties`` while validating.

    The same technique as ``snakemake.utils.validate(..., set_default=True)`` (see the
    jsonschema FAQ); defaults are deep-copied so that no two configs share a list.
    """
    validate_properties = validator_class.VALIDATORS["properties"]

    def set_defaults(validator, properties, instance, schema):
        if validator.is_type(instance, "object"):
            for name, subschema in properties.items():
                if isinstance(subschema, dict) and "default" in subschema:
                    instance.setdefault(name, copy.deepcopy(subschema["default"]))
        yield from validate_properties(validator, properties, instance, schema)

    return jsonschema.validators.extend(validator_class, {"properties": set_defaults})


_DefaultFillingValidator = _extend_with_default(Draft202012Validator)


@functools.cache
def packaged_schema(name: str) -> dict[str, Any]:
    """The JSON Schema ``railtherm/schemas/<name>.schema.yaml`` (vehicle, published, audit,
    reference), read once; shared, so treat it as read-only."""
    text = importlib.resources.files("railtherm").joinpath(f"schemas/{name}.schema.yaml")
    return yaml.safe_load(text.read_text(encoding="utf-8"))


def vehicle_schema() -> dict[str, Any]:
    """The vehicle JSON Schema (a fresh copy), read from the package's schemas directory."""
    return copy.deepcopy(packaged_schema("vehicle"))


# Tidy-table names the workflow uses itself: the k window and the whole recording.
RESERVED_WINDOW_NAMES = ("kvalue", "record")

# Sections of a vehicle file that the study config's ``defaults`` may preset.
DEFAULTABLE = ("model", "cleaning", "instruments", "kvalue", "check")


def _section_schema(section: str) -> dict[str, Any]:
    schema = vehicle_schema()
    return {**schema["properties"][section], "$defs": schema["$defs"]}


def section_defaults(section: str) -> dict[str, Any]:
    """The schema defaults of one vehicle section (e.g. ``kvalue``), as a vehicle without that
    section gets them: for library callers that have no vehicle file."""
    data: dict[str, Any] = {}
    validate_schema("(defaults)", data, _section_schema(section), prefix=section)
    return data


def _model_schema() -> dict[str, Any]:
    return _section_schema("model")


def _key(path: Iterable[Any], prefix: str = "") -> str:
    """Dotted key path with ``[i]`` list indices: ``channels.indoor_air[2].column``."""
    key = prefix
    for part in path:
        if isinstance(part, int):
            key += f"[{part}]"
        else:
            key += f".{part}" if key else str(part)
    return key or "(root)"


def _words(values: Iterable[Any]) -> str:
    return ", ".join(str(v) for v in values)


_NAME_PATTERN = "^[A-Za-z][A-Za-z0-9_-]*$"  # ids and names in railtherm's schemas

_TYPE_WORDS = {
    "object": "a mapping (key: value)",
    "array": "a list",
    "string": "a string",
    "number": "a number",
    "integer": "an integer",
    "boolean": "true or false",
    "null": "empty",
}


def _schema_error(file: str, error: ValidationError, prefix: str = "") -> ConfigError:
    """Turn the most relevant jsonschema error into a one-line :class:`ConfigError`."""
    path = list(error.absolute_path)
    kind = error.validator
    expected = error.validator_value
    value = error.instance
    if "propertyNames" in error.schema_path:
        return ConfigError(
            file,
            _key([*path, value], prefix),
            value,
            "invalid name: must start with a letter and contain only letters, digits, _ or -",
        )
    if kind == "required":
        missing = [name for name in expected if name not in error.instance]
        return ConfigError(file, _key([*path, missing[0]], prefix), None, "missing required key")
    if kind == "additionalProperties" and expected is False:
        allowed = list(error.schema.get("properties", {}))
        unknown = [name for name in error.instance if name not in allowed]
        name = unknown[0]
        close = difflib.get_close_matches(str(name), allowed, n=1)
        hint = f"did you mean '{close[0]}'? " if close else ""
        return ConfigError(
            file,
            _key([*path, name], prefix),
            error.instance[name],
            f"unknown key ({hint}allowed: {_words(allowed)})",
        )
    if kind == "enum":
        reason = f"must be one of {_words(expected)}"
    elif kind == "exclusiveMinimum":
        reason = f"must be > {expected:g}"
    elif kind == "minimum":
        reason = f"must be >= {expected:g}"
    elif kind == "exclusiveMaximum":
        reason = f"must be < {expected:g}"
    elif kind == "maximum":
        reason = f"must be <= {expected:g}"
    elif kind == "type":
        types = [expected] if isinstance(expected, str) else list(expected)
        reason = "must be " + " or ".join(_TYPE_WORDS.get(t, t) for t in types)
        if "number" in types and isinstance(value, str) and _looks_like_number(value):
            reason += f" (YAML reads {value} as text; write {_yaml_number_hint(value)})"
    elif kind == "minItems":
        reason = f"must have at least {expected} item{'s' if expected != 1 else ''}"
    elif kind == "maxItems":
        reason = f"must have at most {expected} item{'s' if expected != 1 else ''}"
    elif kind == "minLength":
        reason = "must not be empty" if expected == 1 else f"must have >= {expected} characters"
    elif kind == "minProperties":
        reason = f"must have at least {expected} entr{'ies' if expected != 1 else 'y'}"
    elif kind == "pattern" and expected == _NAME_PATTERN:
        reason = "must start with a letter and contain only letters, digits, _ or -"
    elif kind == "pattern":
        reason = f"must match the pattern {expected}"
    elif kind == "uniqueItems":
        reason = "must not list an item twice"
    elif kind in ("oneOf", "anyOf") and path and path[-1] in ("start", "end"):
        reason = "must be an ISO 8601 timestamp string or a number of seconds"
    else:
        reason = error.message
    return ConfigError(file, _key(path, prefix), value, reason)


def _looks_like_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _yaml_number_hint(text: str) -> str:
    """``1.0e7`` -> ``1.0e+7``: the spelling YAML 1.1 (PyYAML, Snakemake) reads as a number."""
    mantissa, _, exponent = text.lower().partition("e")
    if "." not in mantissa:
        mantissa += ".0"
    if exponent and exponent[0] not in "+-":
        exponent = "+" + exponent
    return f"{mantissa}e{exponent}" if exponent else mantissa


def validate_schema(file: str, data: Any, schema: dict[str, Any], prefix: str = "") -> None:
    """Validate ``data`` (filling schema defaults in place); one-line :class:`ConfigError` if bad.

    ``prefix`` is the key path of ``data`` inside ``file`` (e.g. ``vehicles.Tram1``).
    """
    validator = _DefaultFillingValidator(schema)
    error = best_match(validator.iter_errors(data))
    if error is not None:
        raise _schema_error(file, error, prefix)


# ---------------------------------------------------------------------------------------------
# Helpers


def deep_merge(base: Mapping[str, Any], override: Mapping[str, Any]) -> dict[str, Any]:
    """``override`` merged over ``base``: mappings merge key by key, anything else is replaced."""
    merged = copy.deepcopy(dict(base))
    for name, value in override.items():
        if isinstance(value, Mapping) and isinstance(merged.get(name), Mapping):
            merged[name] = deep_merge(merged[name], value)
        else:
            merged[name] = copy.deepcopy(value)
    return merged


def _display(path: str, workdir: str) -> str:
    """The path as messages show it: relative to ``workdir`` unless that climbs out of it."""
    rel = os.path.relpath(os.path.normpath(path), workdir)
    return str(path) if rel.startswith("..") else rel


def _normalise(path: str, workdir: str) -> str:
    return os.path.relpath(os.path.normpath(path), workdir)


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _fmt_time(value: Any) -> str:
    if isinstance(value, pd.Timestamp):
        return value.isoformat()
    return f"{value:g}"


# ---------------------------------------------------------------------------------------------
# Vehicle


def _check_finite(file: str, data: Any, key: str = "") -> None:
    """Every number in a config is finite: YAML's .nan and .inf pass a JSON Schema's "number"
    and its bounds (NaN > 0 is false either way), then fail deep in a job."""
    if isinstance(data, dict):
        for k, v in data.items():
            _check_finite(file, v, f"{key}.{k}" if key else str(k))
    elif isinstance(data, list):
        for i, v in enumerate(data):
            _check_finite(file, v, f"{key}[{i}]")
    elif isinstance(data, float) and not math.isfinite(data):
        raise ConfigError(file, key, data, "not a finite number (.nan or .inf)")


def load_vehicle(
    path: str | os.PathLike[str],
    defaults: Mapping[str, Any] | None = None,
    layouts: Mapping[str, RawLayout] | None = None,
    workdir: str | os.PathLike[str] = ".",
) -> Vehicle:
    """Load, validate and check one vehicle YAML file.

    ``defaults`` is the study config's ``defaults`` section; each of its sections (model,
    cleaning, instruments, kvalue) is deep-merged under the vehicle's own (the vehicle wins).
    ``layouts`` maps normalised raw-file paths (relative to ``workdir``) to planned layouts,
    used for raw files that do not exist yet.
    Raises :class:`ConfigError` naming this file, the key path and the value on the first
    problem found.
    """
    path = str(path)
    workdir = str(workdir)
    file = _display(path, workdir)
    data = read_yaml(path, display=file)
    if data is None:
        raise ConfigError(file, "(root)", None, "the file is empty; expected a vehicle mapping")
    if not isinstance(data, dict):
        raise ConfigError(
            file,
            "(root)",
            data,
            f"expected a mapping of keys (id, class, ...), got {_TYPE_WORDS.get(_json_type(data))}",
        )
    _check_finite(file, data)
    for section in DEFAULTABLE[1:]:  # model is merged after validation (see _check_model)
        if section in (defaults or {}) and isinstance(data.get(section, {}), dict):
            data[section] = deep_merge(defaults[section], data.get(section) or {})
    validate_schema(file, data, vehicle_schema())

    for section, key in (("cleaning", "temperature_range_degC"), ("check", "k_range_W_m2K")):
        lo, hi = data[section][key]
        if not lo < hi:
            raise ConfigError(
                file, f"{section}.{key}", [lo, hi], "must be [lower, upper] with lower < upper"
            )

    fmt = data["format"]
    if fmt["separator"] == fmt["decimal"]:
        raise ConfigError(
            file, "format.decimal", fmt["decimal"], "must differ from format.separator"
        )

    yaml_dir = os.path.dirname(path)
    raw_files: dict[str, str] = {}
    found: dict[str, RawLayout] = {}
    for name, raw in data["raw_files"].items():
        local = os.path.normpath(os.path.join(yaml_dir, raw))
        raw_files[name] = _normalise(local, workdir)
        found[name] = _layout(file, name, raw, local, raw_files[name], fmt, layouts or {})

    _check_channels(file, data, found)
    _check_windows(file, data, found)
    model = deep_merge((defaults or {}).get("model") or {}, data.get("model") or {})
    _check_model(file, model, data.get("model") or {})
    data["model"] = model  # data is self-contained: the workflow passes it as params

    return Vehicle(
        id=data["id"],
        vehicle_class=data["class"],
        path=_normalise(path, workdir),
        synthetic=data["synthetic"],
        mass_kg=float(data["mass_kg"]),
        surface_m2=float(data["surface_m2"]),
        volume_m3=float(data["volume_m3"]),
        raw_files=raw_files,
        data=data,
        layouts=found,
    )


def _json_type(value: Any) -> str:
    if isinstance(value, list):
        return "array"
    if isinstance(value, str):
        return "string"
    if isinstance(value, bool):
        return "boolean"
    if _is_number(value):
        return "number"
    return "object" if isinstance(value, dict) else "null"


def _layout(
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
        columns = read_columns(local, fmt["separator"])
    except DataError as exc:
        raise ConfigError(file, key, raw, f"{normalised}: {exc.reason}") from None
    if time["column"] not in columns:
        hint = separator_hint(columns, fmt["separator"])
        raise ConfigError(
            file,
            "format.time.column",
            time["column"],
            f"not a column of {normalised} ({hint}columns: {_words(columns)})",
        )
    try:
        layout = read_layout(
            local, fmt["separator"], fmt["decimal"], time["column"], time["format"]
        )
    except DataError as exc:
        if exc.value is None:  # about the file, not one of its values
            raise ConfigError(file, key, raw, f"{normalised}: {exc.reason}") from None
        raise ConfigError(
            file,
            "format.time.format",
            time["format"],
            f"{normalised} column '{exc.key}' {exc.reason}: {exc.value!r}",
        ) from None
    return RawLayout(
        path=normalised,
        columns=layout.columns,
        time_column=layout.time_column,
        time_format=layout.time_format,
        t_first=layout.t_first,
        t_last=layout.t_last,
        step_s=layout.step_s,
    )


def _missing_column(file: str, key: str, column: str, raw: str, layout: RawLayout) -> ConfigError:
    close = difflib.get_close_matches(column, layout.columns, n=1)
    hint = f"did you mean '{close[0]}'? " if close else ""
    hint = separator_hint(layout.columns, "") or hint
    return ConfigError(
        file, key, column, f"not a column of {raw} ({hint}columns: {_words(layout.columns)})"
    )


def _check_channels(file: str, data: dict[str, Any], layouts: dict[str, RawLayout]) -> None:
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
            for name, layout in layouts.items():
                if column not in layout.columns:
                    raise _missing_column(file, key, column, layout.path or name, layout)
    inputs: dict[str, str] = {}
    for i, name in enumerate(irradiance_names(data)):
        key = f"channels.irradiance[{i}].name"
        if name in inputs:
            raise ConfigError(file, key, name[2:], f"input {name} already named by {inputs[name]}")
        inputs[name] = key


def _windows(data: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
    windows = data["windows"]
    found = []
    if "kvalue" in windows:
        found.append(("windows.kvalue", windows["kvalue"]))
    found += [(f"windows.identification[{i}]", w) for i, w in enumerate(windows["identification"])]
    return found


def _check_windows(file: str, data: dict[str, Any], layouts: dict[str, RawLayout]) -> None:
    """File keys, time format, start < end and windows inside the data."""
    time_format = data["format"]["time"]["format"]
    names: dict[str, str] = {}
    for key, window in _windows(data):
        if "name" in window and key.startswith("windows.identification"):
            if window["name"] in RESERVED_WINDOW_NAMES:
                raise ConfigError(
                    file,
                    f"{key}.name",
                    window["name"],
                    f"reserved for the workflow's own tables ({_words(RESERVED_WINDOW_NAMES)})",
                )
            if window["name"] in names:
                raise ConfigError(
                    file,
                    f"{key}.name",
                    window["name"],
                    f"name already used by {names[window['name']]}",
                )
            names[window["name"]] = key
        if "file" in window:
            if window["file"] not in layouts:
                raise ConfigError(
                    file,
                    f"{key}.file",
                    window["file"],
                    f"not a key of raw_files (known: {_words(layouts)})",
                )
            layout = layouts[window["file"]]
        elif len(layouts) > 1:
            raise ConfigError(
                file,
                f"{key}.file",
                None,
                f"required when there is more than one raw file (one of: {_words(layouts)})",
            )
        else:
            layout = next(iter(layouts.values()))
        start = _window_time(file, f"{key}.start", window["start"], time_format, layout)
        end = _window_time(file, f"{key}.end", window["end"], time_format, layout)
        if not start < end:
            raise ConfigError(
                file, f"{key}.end", window["end"], f"must be after start ({window['start']!r})"
            )
        span = f"the data of {layout.path} run from {_fmt_time(layout.t_first)} to "
        span += _fmt_time(layout.t_last)
        if start < layout.t_first or start > layout.t_last:
            raise ConfigError(file, f"{key}.start", window["start"], f"outside the data: {span}")
        if end > layout.t_last:
            raise ConfigError(file, f"{key}.end", window["end"], f"outside the data: {span}")
        duration = layout.seconds(end) - layout.seconds(start)
        _check_window_size(file, key, window, layout, duration, data.get("cleaning") or {})
        _check_record_size(file, layout)
        if key == "windows.kvalue":  # its figure shows the whole record at the tidy step
            record = layout.seconds(layout.t_last) - layout.seconds(layout.t_first)
            _check_window_size(file, "the whole record", window, layout, record, data["cleaning"])


def _check_window_size(
    file: str, key: str, window, layout: RawLayout, duration: float, cleaning: dict
) -> None:
    """A window spans at least MIN_WINDOW_STEPS logger steps, and its tidy table (at
    ``cleaning.step_s``, else the logger's step) at most MAX_ROWS rows."""
    step = cleaning.get("step_s")
    if step and duration / float(step) > MAX_ROWS:
        raise ConfigError(
            file,
            "cleaning.step_s",
            step,
            f"{key} would become {duration / float(step):,.0f} rows at this step, more than "
            f"{MAX_ROWS:,}; the logger's step in {layout.path} is {layout.step_s:g} s",
        )
    if not layout.step_s or layout.step_s <= 0:
        return
    if duration < MIN_WINDOW_STEPS * layout.step_s:
        raise ConfigError(
            file,
            f"{key}.end",
            window["end"],
            f"the window lasts {duration:g} s, fewer than {MIN_WINDOW_STEPS} logger steps of "
            f"{layout.step_s:g} s in {layout.path}: too short to fit or test anything",
        )


def _check_record_size(file: str, layout: RawLayout) -> None:
    """The raw record completed to its logger step holds at most MAX_ROWS rows: a span of
    years at a step of seconds is a typo in a timestamp, refused before it is allocated."""
    if not layout.step_s or layout.step_s <= 0:
        return
    span = layout.seconds(layout.t_last)
    if span / layout.step_s > MAX_ROWS:
        raise ConfigError(
            file,
            "raw_files",
            layout.path,
            f"its rows run from {_fmt_time(layout.t_first)} to {_fmt_time(layout.t_last)} at a "
            f"step of {layout.step_s:g} s: {span / layout.step_s:,.0f} rows to complete, more "
            f"than {MAX_ROWS:,}; a typo in a timestamp (the year?) or the wrong time format?",
        )


def _window_time(file: str, key: str, value: Any, time_format: str, layout: RawLayout) -> Any:
    """A window bound as the file's time type: ``pandas.Timestamp`` (iso) or float (seconds)."""
    if time_format == "seconds":
        if not _is_number(value) or not math.isfinite(value):
            raise ConfigError(
                file, key, value, "must be a number of seconds (format.time.format is seconds)"
            )
        return float(value)
    if not isinstance(value, str):
        raise ConfigError(
            file, key, value, "must be an ISO 8601 timestamp string (format.time.format is iso)"
        )
    try:
        stamp = pd.Timestamp(dt.datetime.fromisoformat(value.strip()))
    except ValueError:
        raise ConfigError(
            file, key, value, "not an ISO 8601 timestamp (e.g. 2024-01-15T08:30:00)"
        ) from None
    file_tz = getattr(layout.t_first, "tzinfo", None)
    if (stamp.tzinfo is None) != (file_tz is None):
        if file_tz is None:
            reason = f"has a time zone but the timestamps of {layout.path} have none"
        else:
            reason = f"has no time zone but the timestamps of {layout.path} have one"
        raise ConfigError(file, key, value, reason)
    return stamp


def _check_model(
    file: str, model: dict[str, Any], own: dict[str, Any], prefix: str = "model"
) -> None:
    """Bounds lo < hi; initial values inside their bounds (after merging the defaults)."""
    bounds = model.get("bounds") or {}
    initial = model.get("initial") or {}

    def origin(section: str, name: str) -> str:
        mine = name in (own.get(section) or {})
        return "" if mine else f" (model.{section}.{name} from the study's defaults.model)"

    for name in PARAMETERS:
        if name in bounds:
            lo, hi = bounds[name]
            if not lo < hi:
                raise ConfigError(
                    file,
                    f"{prefix}.bounds.{name}",
                    bounds[name],
                    f"lower bound must be < upper bound{origin('bounds', name)}",
                )
    for name in PARAMETERS:
        if name in initial and name in bounds:
            lo, hi = bounds[name]
            if not lo <= initial[name] <= hi:
                raise ConfigError(
                    file,
                    f"{prefix}.initial.{name}",
                    initial[name],
                    f"outside {prefix}.bounds.{name} = [{lo:g}, {hi:g}]"
                    f"{origin('initial', name)}{origin('bounds', name)}",
                )


# ---------------------------------------------------------------------------------------------
# Study


def load_study(
    config: Mapping[str, Any],
    workdir: str | os.PathLike[str] = ".",
    config_file: str = "config/config.yaml",
) -> Study:
    """Load every vehicle of the study config (paths relative to ``workdir``).

    If the config names a ``campaign``, its planned raw-file layouts are used for raw files the
    virtual wind tunnel has not written yet. Checks that listed vehicle files exist, vehicle
    ids are unique and ``defaults.model`` is valid; messages name ``config_file`` for mistakes
    in the study config and the vehicle file for mistakes there.
    """
    workdir = str(workdir)
    study = study_context(config, workdir, config_file)
    vehicle_paths = config.get("vehicles")
    if not isinstance(vehicle_paths, list) or not vehicle_paths:
        raise ConfigError(
            config_file, "vehicles", vehicle_paths, "must be a non-empty list of vehicle YAML paths"
        )
    for i, vehicle_path in enumerate(vehicle_paths):
        if not isinstance(vehicle_path, str) or not vehicle_path:
            raise ConfigError(config_file, f"vehicles[{i}]", vehicle_path, "must be a path")
        local = os.path.normpath(os.path.join(workdir, vehicle_path))
        if not os.path.isfile(local):
            raise ConfigError(config_file, f"vehicles[{i}]", vehicle_path, "vehicle file not found")
        add_vehicle(study, local, workdir)
    return study


def study_context(
    config: Mapping[str, Any],
    workdir: str | os.PathLike[str] = ".",
    config_file: str = "config/config.yaml",
) -> Study:
    """A :class:`Study` with no vehicles yet: validated defaults and the campaign's layouts.

    For checking vehicle files one by one (``railtherm validate VEHICLE.yaml``) under the
    study's defaults; :func:`load_study` starts from it.
    """
    workdir = str(workdir)
    if not isinstance(config, Mapping):
        raise ConfigError(config_file, "(root)", config, "expected a mapping (vehicles, ...)")
    # the schema Snakemake validates the study config with: an unknown key stops here too
    validate_schema(config_file, copy.deepcopy(dict(config)), packaged_schema("study"))
    _check_finite(config_file, dict(config))
    defaults = config.get("defaults") or {}
    if not isinstance(defaults, Mapping):
        raise ConfigError(config_file, "defaults", defaults, "must be a mapping (key: value)")
    defaults = copy.deepcopy(dict(defaults))
    for section in DEFAULTABLE:
        if section in defaults:
            # validate a copy: schema defaults must not be filled into the study's defaults
            section_data = copy.deepcopy(defaults[section])
            validate_schema(
                config_file, section_data, _section_schema(section), prefix=f"defaults.{section}"
            )
    if "model" in defaults:
        _check_model(config_file, defaults["model"], defaults["model"], "defaults.model")

    layouts: dict[str, RawLayout] = {}
    campaign_data = None
    campaign = config.get("campaign")
    if campaign is not None:
        if not isinstance(campaign, str) or not campaign:
            raise ConfigError(config_file, "campaign", campaign, "must be a path to a YAML file")
        campaign_path = os.path.normpath(os.path.join(workdir, campaign))
        if not os.path.isfile(campaign_path):
            raise ConfigError(config_file, "campaign", campaign, "campaign file not found")
        from railtherm import synth  # lazy: only studies with a campaign need the generator

        campaign_data = synth.load_campaign(campaign_path)
        planned = synth.planned_layouts(campaign_data)
        layouts = {os.path.normpath(k): v for k, v in planned.items()}
    return Study(
        vehicles={},
        campaign=campaign,
        defaults=defaults,
        layouts=layouts,
        campaign_data=campaign_data,
    )


def add_vehicle(study: Study, path: str | os.PathLike[str], workdir: str = ".") -> Vehicle:
    """Load one vehicle file under the study's defaults and layouts and add it to the study.

    :class:`ConfigError` naming the vehicle file when its id is already taken.
    """
    vehicle = load_vehicle(path, defaults=study.defaults, layouts=study.layouts, workdir=workdir)
    if vehicle.id in study.vehicles:
        raise ConfigError(
            _display(str(path), workdir),
            "id",
            vehicle.id,
            f"duplicate vehicle id (also in {study.vehicles[vehicle.id].path})",
        )
    study.vehicles[vehicle.id] = vehicle
    return vehicle
