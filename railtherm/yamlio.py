"""YAML and JSON Schema for every railtherm config: one reader, one validator.

:func:`read_yaml` parses a file safely (duplicate keys and alias bombs refused, unquoted
timestamps given back as ISO text); :func:`validate_schema` checks data against a JSON Schema
(Draft 2020-12) and fills in its defaults; both raise one-line
:class:`~railtherm.errors.ConfigError` naming the file, the key path and the value. The
schemas live in ``railtherm/schemas/`` (:func:`packaged_schema`).
"""

from __future__ import annotations

import copy
import datetime as dt
import difflib
import functools
import importlib.resources
import math
import os
import re
from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING, Any

import yaml

if TYPE_CHECKING:
    from jsonschema.exceptions import ValidationError

from railtherm.errors import ConfigError, first_line

# ---------------------------------------------------------------------------------------------
# YAML


# PyYAML's safe loader parsing with libyaml where PyYAML has it (its wheels do: a tenth of the
# time of the pure Python parser, which is the fallback); the values are built in Python either way
SafeLoader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


class _UniqueKeyLoader(SafeLoader):
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
        problem = getattr(exc, "problem", None) or first_line(exc)
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


@functools.cache
def _default_filling_validator() -> type:
    """The Draft 2020-12 validator class that fills in ``default`` values of ``properties``
    while validating, built on first use (jsonschema's import is a job's start-up cost).

    The same technique as ``snakemake.utils.validate(..., set_default=True)`` (see the
    jsonschema FAQ); defaults are deep-copied so that no two configs share a list.
    """
    import jsonschema

    validator_class = jsonschema.Draft202012Validator
    validate_properties = validator_class.VALIDATORS["properties"]

    def set_defaults(validator, properties, instance, schema):
        if validator.is_type(instance, "object"):
            for name, subschema in properties.items():
                if isinstance(subschema, dict) and "default" in subschema:
                    instance.setdefault(name, copy.deepcopy(subschema["default"]))
        yield from validate_properties(validator, properties, instance, schema)

    return jsonschema.validators.extend(validator_class, {"properties": set_defaults})


@functools.cache
def packaged_schema(name: str) -> dict[str, Any]:
    """The JSON Schema ``railtherm/schemas/<name>.schema.yaml`` (vehicle, published, audit,
    reference), read once; shared, so treat it as read-only. A subschema ``{x-registry:
    what}`` takes its values from the structure registry (:func:`registry_schema`)."""
    text = importlib.resources.files("railtherm").joinpath(f"schemas/{name}.schema.yaml")
    return _from_registry(yaml.load(text.read_text(encoding="utf-8"), Loader=SafeLoader))


def registry_schema(what: str) -> dict[str, Any]:
    """The subschema of a value the structure registry (:mod:`railtherm.structures`) lists:
    ``orders`` (model.orders: 1, 2), ``structures`` (model.structures: the further
    structures' names), ``states`` (model.outputs: the states a sensor can measure), ``model_keys``
    (a model key, with the suffix _kalman of the Kalman-filter estimator)."""
    from railtherm import structures

    if what == "model_keys":
        keys = "|".join(structures.keys(include_refused=True))
        return {"type": "string", "pattern": f"^({keys})(_kalman)?$"}
    # a refused module's key passes the schema: the config check then says why it is refused
    values = {
        "orders": structures.orders(include_refused=True),
        "structures": structures.further(include_refused=True),
        "states": structures.measurable_states(),
    }
    return {"enum": values[what]}


def _from_registry(schema: Any) -> Any:
    if isinstance(schema, dict):
        if "x-registry" in schema:
            rest = {k: v for k, v in schema.items() if k != "x-registry"}
            return {**rest, **registry_schema(schema["x-registry"])}
        return {k: _from_registry(v) for k, v in schema.items()}
    if isinstance(schema, list):
        return [_from_registry(v) for v in schema]
    return schema


def _key(path: Iterable[Any], prefix: str = "") -> str:
    """Dotted key path with ``[i]`` list indices: ``channels.indoor_air[2].column``."""
    key = prefix
    for part in path:
        if isinstance(part, int):
            key += f"[{part}]"
        else:
            key += f".{part}" if key else str(part)
    return key or "(root)"


def words(values: Iterable[Any]) -> str:
    return ", ".join(str(v) for v in values)


_NAME_PATTERN = "^[A-Za-z][A-Za-z0-9_-]*$"  # ids and names in railtherm's schemas

TYPE_WORDS = {
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
        reason = (
            f"not one of {', '.join(map(str, expected))}"
            if kind == "enum"
            else "invalid name: must start with a letter and contain only letters, digits, _ or -"
        )
        return ConfigError(file, _key([*path, value], prefix), value, reason)
    if kind == "required":
        missing = [name for name in expected if name not in error.instance]
        return ConfigError(file, _key([*path, missing[0]], prefix), None, "missing required key")
    if kind == "additionalProperties" and expected is False:
        allowed = list(error.schema.get("properties", {}))
        patterns = list(error.schema.get("patternProperties", {}))
        unknown = [
            name
            for name in error.instance
            if name not in allowed and not any(re.search(p, str(name)) for p in patterns)
        ]
        name = unknown[0]
        close = difflib.get_close_matches(str(name), allowed, n=1)
        hint = f"did you mean '{close[0]}'? " if close else ""
        names = words(allowed) if allowed else ""
        if patterns:
            names += ("; " if names else "") + "names matching " + " or ".join(patterns)
        return ConfigError(
            file,
            _key([*path, name], prefix),
            error.instance[name],
            f"unknown key ({hint}allowed: {names})",
        )
    if kind == "enum":
        reason = f"must be one of {words(expected)}"
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
        reason = "must be " + " or ".join(TYPE_WORDS.get(t, t) for t in types)
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
    from jsonschema.exceptions import best_match

    validator = _default_filling_validator()(schema)
    error = best_match(validator.iter_errors(data))
    if error is not None:
        raise _schema_error(file, error, prefix)


def deep_merge(base: Mapping[str, Any], override: Mapping[str, Any]) -> dict[str, Any]:
    """``override`` merged over ``base``: mappings merge key by key, anything else is replaced."""
    merged = copy.deepcopy(dict(base))
    for name, value in override.items():
        if isinstance(value, Mapping) and isinstance(merged.get(name), Mapping):
            merged[name] = deep_merge(merged[name], value)
        else:
            merged[name] = copy.deepcopy(value)
    return merged


def check_finite(file: str, data: Any, key: str = "") -> None:
    """Every number in a config is finite: YAML's .nan and .inf pass a JSON Schema's "number"
    and its bounds (NaN > 0 is false either way), then fail deep in a job."""
    if isinstance(data, dict):
        for k, v in data.items():
            check_finite(file, v, f"{key}.{k}" if key else str(k))
    elif isinstance(data, list):
        for i, v in enumerate(data):
            check_finite(file, v, f"{key}[{i}]")
    elif isinstance(data, float) and not math.isfinite(data):
        raise ConfigError(file, key, data, "not a finite number (.nan or .inf)")
