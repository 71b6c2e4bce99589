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

A study parsed again (every ``snakemake`` call parses it) need not validate again what has not
changed: :func:`load_study` with a ``cache`` file (:class:`VehicleCache`) reuses each vehicle
validated before while its file, the study's defaults, its raw files (size, mtime, ctime,
inode) and the railtherm code are unchanged.
"""

from __future__ import annotations

import copy
import functools
import hashlib
import importlib.metadata
import json
import os
import pickle
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from railtherm import codedigest, structures
from railtherm.data import sources, timeaxis
from railtherm.data.ingest import irradiance_names
from railtherm.data.rawfile import (
    MAX_RAW_ROWS,
    MAX_ROWS,
    MIN_WINDOW_STEPS,
    TYPO_GAP_S,
    RawLayout,
)
from railtherm.data.recordcheck import (
    check_channels,
    check_format,
    check_sources,
    fmt_time,
    normalise_path,
    source_layout,
)
from railtherm.errors import ConfigError
from railtherm.estimation.priors import PriorError, outside_bounds, prior_from_config
from railtherm.yamlio import (
    TYPE_WORDS,
    check_finite,
    deep_merge,
    packaged_schema,
    read_yaml,
    validate_schema,
    words,
)

__all__ = [
    "Study",
    "Vehicle",
    "VehicleCache",
    "add_vehicle",
    "deep_merge",
    "load_study",
    "load_vehicle",
    "read_yaml",
    "study_context",
    "packaged_schema",
    "vehicle_schema",
]

DEFAULT_ORDERS = (1, 2)  # the paper's two models, when model.orders is not given
# Parameters model.initial and model.bounds name, besides the solar ones of the vehicle's
# irradiance inputs I_<name>: a_I_<name> and, for a gain on both nodes, f_I_<name>.
PARAMETERS = tuple(structures.parameters())  # every registered structure's


@dataclass(frozen=True)
class Vehicle:
    """One validated vehicle config.

    ``raw_files`` maps each raw-file name to its path normalised relative to the working
    directory (with ``sources``: to its files joined by ' + ', a label; ``source_files``
    then maps each name to {source: path}, ``source_layouts`` each source to its layouts by
    name); ``layouts`` maps the same names to the
    :class:`RawLayout` the checks used (read from the file, or planned by the campaign when
    the file does not exist yet). ``data`` is
    the whole validated YAML with schema defaults filled in and the study's defaults merged
    under its sections (``data["model"]`` is ``defaults.model`` deep-merged under the vehicle's
    own ``model``); ``format``, ``channels``, ``windows`` and ``model`` read from it.
    ``mass_kg`` and ``surface_m2`` are None where an object of class other leaves them out
    (:data:`METADATA`).
    """

    id: str
    vehicle_class: str
    path: str
    synthetic: bool
    mass_kg: float | None
    surface_m2: float | None
    volume_m3: float | None
    raw_files: dict[str, str]
    data: dict[str, Any]
    layouts: dict[str, RawLayout] = field(default_factory=dict)
    source_files: dict[str, dict[str, str]] = field(default_factory=dict)
    source_layouts: dict[str, dict[str, RawLayout]] = field(default_factory=dict)

    def record(self, name: str) -> str | dict[str, str]:
        """The file of one part of the record (a key of ``raw_files``), or with sources the
        file of each source ({source: path}), relative to the working directory: what
        :func:`railtherm.data.ingest.clean_windows` reads.

        Parameters
        ----------
        name : str
            A key of the vehicle's ``raw_files``.

        Returns
        -------
        str or dict of str
            The file's path, or with sources {source: path}.
        """
        return self.source_files.get(name) or self.raw_files[name]

    def files(self) -> list[str]:
        """Every raw file of the vehicle (each source's), relative to the working directory.

        Returns
        -------
        list of str
            The paths, in the config's order.
        """
        if self.source_files:
            return [p for part in self.source_files.values() for p in part.values()]
        return list(self.raw_files.values())

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
# Schemas


def vehicle_schema() -> dict[str, Any]:
    """The vehicle JSON Schema (a fresh copy), read from the package's schemas directory,
    with ``model.initial`` and ``model.bounds`` taking every registered structure's
    parameters (:data:`PARAMETERS`): a structure added as one file is started and bounded
    like the shipped ones, as docs/structures.md says."""
    schema = copy.deepcopy(packaged_schema("vehicle"))
    initial = schema["$defs"]["parameters"]["properties"]
    bounds = schema["properties"]["model"]["properties"]["bounds"]["properties"]
    priors = schema["properties"]["model"]["properties"]["priors"]["properties"]
    for p in PARAMETERS:
        initial.setdefault(p, {"type": "number", "exclusiveMinimum": 0})
        bounds.setdefault(p, {"$ref": "#/$defs/interval"})
        priors.setdefault(p, {"$ref": "#/$defs/prior"})
    return schema


# Tidy-table names the workflow uses itself: the k window and the whole recording.
RESERVED_WINDOW_NAMES = ("kvalue", "record")

# Sections of a vehicle file that the study config's ``defaults`` may preset.
DEFAULTABLE = ("model", "cleaning", "instruments", "kvalue", "check")

# Metadata a rail vehicle must give, with what needs it. An object of another class (a test
# cell, a building) may leave out what means nothing for it: the quantity that needs it is
# then not given (railtherm.study.aggregate), and the checks that read it are skipped with a note.
METADATA = {
    "mass_kg": "the mass m_veh gives c_veh = C_veh / m_veh (eq. 24)",
    "surface_m2": "the surface A gives k = kA / A (eq. 10)",
}


def metadata_classes() -> tuple[str, ...]:
    """The vehicle classes that must give every key of :data:`METADATA`: the rail classes of
    the vehicle schema (its ``if``/``then``)."""
    return tuple(packaged_schema("vehicle")["if"]["properties"]["class"]["enum"])


def _check_metadata(file: str, data: dict[str, Any]) -> None:
    """A rail vehicle gives ``mass_kg`` and ``surface_m2``; the message names the class."""
    vehicle_class = data.get("class")
    if not isinstance(vehicle_class, str) or vehicle_class not in metadata_classes():
        return
    for key, why in METADATA.items():
        if key not in data:
            raise ConfigError(
                file,
                key,
                None,
                f"missing required key for class '{vehicle_class}': {why}; only class 'other' "
                "(a test cell, a building) may leave it out",
            )


def _section_schema(section: str) -> dict[str, Any]:
    schema = vehicle_schema()
    return {**schema["properties"][section], "$defs": schema["$defs"]}


def section_defaults(section: str) -> dict[str, Any]:
    """The schema defaults of one vehicle section (e.g. ``kvalue``), as a vehicle without that
    section gets them: for library callers that have no vehicle file."""
    data: dict[str, Any] = {}
    validate_schema("(defaults)", data, _section_schema(section), prefix=section)
    return data


def _display(path: str, workdir: str) -> str:
    """The path as messages show it: relative to ``workdir`` unless that climbs out of it."""
    rel = os.path.relpath(os.path.normpath(path), workdir)
    return str(path) if rel.startswith("..") else rel


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


# ---------------------------------------------------------------------------------------------
# Vehicle


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

    Parameters
    ----------
    path : str or os.PathLike
        The vehicle YAML file.
    defaults : mapping, optional
        The study config's ``defaults`` section, merged under the vehicle's own.
    layouts : mapping, optional
        Planned raw-file layouts by normalised path (a campaign's files not yet written).
    workdir : str or os.PathLike
        The directory the vehicle's paths are relative to.

    Returns
    -------
    Vehicle
        The validated vehicle config.

    Raises
    ------
    ConfigError
        On the first problem, naming the file, the key path and the value.
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
            f"expected a mapping of keys (id, class, ...), got {TYPE_WORDS.get(_json_type(data))}",
        )
    check_finite(file, data)
    for section in DEFAULTABLE[1:]:  # model is merged after validation (see _check_model)
        if section in (defaults or {}) and isinstance(data.get(section, {}), dict):
            data[section] = deep_merge(defaults[section], data.get(section) or {})
    _check_metadata(file, data)
    validate_schema(file, data, vehicle_schema())

    _check_ranges(file, data)

    yaml_dir = os.path.dirname(path)
    raw_files: dict[str, str] = {}
    source_files: dict[str, dict[str, str]] = {}
    source_layouts: dict[str, dict[str, RawLayout]] = {}
    if sources.declared(data):
        raw_files, source_files, found, source_layouts = check_sources(
            file, data, yaml_dir, workdir, layouts
        )
    else:
        for key in ("raw_files", "format"):
            if key not in data:
                raise ConfigError(
                    file,
                    key,
                    None,
                    "missing required key (or declare the record's data-acquisition systems "
                    "under sources, each with its files and format)",
                )
        fmt = data["format"]
        check_format(file, fmt, "format", list(data["raw_files"].values()))
        locals_: dict[str, str] = {}  # the raw files as this process finds them
        found = {}
        for name, raw in data["raw_files"].items():
            local = os.path.normpath(os.path.join(yaml_dir, raw))
            raw_files[name] = normalise_path(local, workdir)
            locals_[name] = local
            found[name] = source_layout(file, name, raw, local, raw_files[name], fmt, layouts or {})
        check_channels(file, data, found, locals_)
    _check_windows(file, data, found)
    model = deep_merge((defaults or {}).get("model") or {}, data.get("model") or {})
    if "priors" in model:  # a vehicle's prior replaces the default's for its parameter whole
        default_priors = ((defaults or {}).get("model") or {}).get("priors") or {}
        model["priors"] = {**default_priors, **((data.get("model") or {}).get("priors") or {})}
    model.setdefault("orders", list(DEFAULT_ORDERS))
    if not model["orders"] and not model.get("structures"):
        raise ConfigError(
            file,
            "model.orders",
            [],
            "nothing to fit: list an order (1: eq. 9, 2: eqs. 7-8) or a model.structures entry",
        )
    _check_structures(file, model, data)
    _check_model(file, model, data.get("model") or {}, solar=_solar_parameters(data))
    _check_envelope(file, data, model)
    data["model"] = model  # data is self-contained: the workflow passes it as params

    return Vehicle(
        id=data["id"],
        vehicle_class=data["class"],
        path=normalise_path(path, workdir),
        synthetic=data["synthetic"],
        mass_kg=float(data["mass_kg"]) if "mass_kg" in data else None,
        surface_m2=float(data["surface_m2"]) if "surface_m2" in data else None,
        volume_m3=float(data["volume_m3"]) if "volume_m3" in data else None,
        raw_files=raw_files,
        data=data,
        layouts=found,
        source_files=source_files,
        source_layouts=source_layouts,
    )


def _check_ranges(file: str, data: Mapping[str, Any]) -> None:
    """Each [lower, upper] range of a vehicle's cleaning and check sections with lower <
    upper, and the capacity per kg's minimum below its maximum."""
    for section, key in (
        ("cleaning", "temperature_range_degC"),
        ("check", "k_range_W_m2K"),
        ("check", "heated_air_range_degC"),
    ):
        lo, hi = data[section][key]
        if not lo < hi:
            raise ConfigError(
                file, f"{section}.{key}", [lo, hi], "must be [lower, upper] with lower < upper"
            )
    check = data["check"]
    if not check["min_capacity_per_kg_J_kgK"] < check["max_capacity_per_kg_J_kgK"]:
        raise ConfigError(
            file,
            "check.max_capacity_per_kg_J_kgK",
            check["max_capacity_per_kg_J_kgK"],
            "must be above check.min_capacity_per_kg_J_kgK = "
            f"{check['min_capacity_per_kg_J_kgK']:g}",
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


def _check_structures(file: str, model: dict[str, Any], data: dict[str, Any] | None = None) -> None:
    """Every structure the vehicle asks for (``model.orders``, ``model.structures``) loaded
    and passed the registry's checks: a refused module (:data:`railtherm.structures.REFUSED`:
    it fails to import, leaves out or repeats an entry, or its derivatives disagree with
    central differences) refuses the vehicles that ask for it, and only those. The storage
    correction of eq. 10's kA (a k window, ``kvalue.storage_correction``, static mode) fits
    the second-order model whatever the orders: it asks for order 2 as well."""
    asked = [(f"model.orders[{i}]", n, f"order{n}") for i, n in enumerate(model["orders"])]
    asked += [
        (f"model.structures[{i}]", name, name)
        for i, name in enumerate(model.get("structures") or [])
    ]
    for key, value, model_key in asked:
        for refused in structures.refused(model_key):
            raise ConfigError(
                file,
                key,
                value,
                f"the structure module is refused: {refused}. Fix the module, or drop "
                f"{value} from {key.split('[')[0]}; vehicles that do not ask for it are "
                "unaffected",
            )
    kvalue = (data or {}).get("kvalue") or {}
    if (
        "kvalue" in ((data or {}).get("windows") or {})
        and kvalue.get("storage_correction", True)
        and model.get("mode", "static") != "joint"
    ):
        for refused in structures.refused("order2"):
            raise ConfigError(
                file,
                "kvalue.storage_correction",
                True,
                "the storage correction of eq. 10's kA fits the second-order model (eqs. "
                f"7-8), whose structure module is refused: {refused}. Fix the module, or set "
                "kvalue.storage_correction: false (or model.mode: joint)",
            )


def _check_envelope(file: str, data: dict[str, Any], model: dict[str, Any]) -> None:
    """What the channels say about the envelope node fits the models asked for: a solar gain
    declared on the envelope (``channels.irradiance[i].node`` envelope or both) needs a
    second node, which a one-node structure (the first-order model) lacks;
    ``model.envelope_sensors: surface`` needs surface sensors; ``model.outputs`` compares a
    state no structure's sensors measure (T_e) only when envelope sensors measure it."""
    asked = [structures.by_key(f"order{n}") for n in model.get("orders") or []]
    asked += [structures.STRUCTURES[name] for name in model.get("structures") or []]
    one_node = [s for s in asked if not s.envelope]
    for i, channel in enumerate(data["channels"].get("irradiance") or []):
        node = channel.get("node", "air")
        if node != "air" and one_node:
            raise ConfigError(
                file,
                f"channels.irradiance[{i}].node",
                node,
                f"the {one_node[0].title} ({one_node[0].key}) has one node, no envelope: "
                f"declare node air, or fit only {', '.join(structures.with_envelope())}",
            )
    formats = (
        [s["format"] for s in data[sources.SOURCES].values()]
        if sources.declared(data)
        else [data["format"]]
    )
    timing = next(
        (
            f.get("power_timing", "instant")
            for f in formats
            if f.get("power_timing", "instant") != "instant"
        ),
        "instant",
    )
    if model.get("input_hold") == "first_order" and timing != "instant":
        raise ConfigError(
            file,
            "model.input_hold",
            "first_order",
            f"the first-order hold takes each power sample as the power at its time, linear "
            f"to the next; format.power_timing {timing} says a sample is the mean over a "
            "logger interval (a piecewise-constant power): use input_hold zero_order, or "
            "power_timing instant if the samples are instantaneous",
        )
    instruments = data.get("instruments") or {}
    noisy = [k for k in ("outdoor_noise_K", "power_noise_rel") if instruments.get(k)]
    if model.get("input_hold") == "first_order" and noisy:
        raise ConfigError(
            file,
            f"instruments.{noisy[0]}",
            instruments[noisy[0]],
            "the input noise is modelled for the zero-order hold (white noise on each held "
            "step); under model.input_hold first_order a noisy sample drives two steps: "
            "remove the key or use input_hold zero_order",
        )
    sensors = model.get("envelope_sensors")
    if sensors and not data["channels"].get(sensors):
        raise ConfigError(
            file,
            "model.envelope_sensors",
            sensors,
            f"no channels.{sensors} sensors are declared: add them, or remove the key (the "
            "envelope then stays unmeasured)",
        )
    unmeasured = [
        x
        for x in model.get("outputs") or []
        if not any(x in s.sensors for s in structures.STRUCTURES.values())
    ]
    if unmeasured and not sensors:
        raise ConfigError(
            file,
            "model.outputs",
            model["outputs"],
            f"{unmeasured[0]} is compared only when measured: set model.envelope_sensors: "
            f"surface, or drop {unmeasured[0]} from the list",
        )


def _windows(data: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
    windows = data["windows"]
    found = []
    if "kvalue" in windows:
        found.append(("windows.kvalue", windows["kvalue"]))
    found += [(f"windows.identification[{i}]", w) for i, w in enumerate(windows["identification"])]
    return found


def _check_windows(file: str, data: dict[str, Any], layouts: dict[str, RawLayout]) -> None:
    """File keys, time format, start < end and windows inside the data."""
    if sources.declared(data):
        time_format = sources.RECORD_TIME  # ISO 8601 instants; without an offset UTC
    else:
        time_format = timeaxis.time_format(data["format"]["time"])
    names: dict[str, str] = {}
    for key, window in _windows(data):
        if "name" in window and key.startswith("windows.identification"):
            if window["name"] in RESERVED_WINDOW_NAMES:
                raise ConfigError(
                    file,
                    f"{key}.name",
                    window["name"],
                    f"reserved for the workflow's own tables ({words(RESERVED_WINDOW_NAMES)})",
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
                    f"not a key of raw_files (known: {words(layouts)})",
                )
            layout = layouts[window["file"]]
        elif len(layouts) > 1:
            raise ConfigError(
                file,
                f"{key}.file",
                None,
                f"required when there is more than one raw file (one of: {words(layouts)})",
            )
        else:
            layout = next(iter(layouts.values()))
        start = _window_time(file, f"{key}.start", window["start"], time_format, layout)
        end = _window_time(file, f"{key}.end", window["end"], time_format, layout)
        if not start < end:
            raise ConfigError(
                file, f"{key}.end", window["end"], f"must be after start ({window['start']!r})"
            )
        span = f"the data of {layout.path} run from {fmt_time(layout.t_first)} to "
        span += fmt_time(layout.t_last)
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
    if step and duration < MIN_WINDOW_STEPS * float(step):
        raise ConfigError(
            file,
            "cleaning.step_s",
            step,
            f"{key} lasts {duration:g} s, fewer than {MIN_WINDOW_STEPS} tidy steps of "
            f"{float(step):g} s: give a step of at most {duration / MIN_WINDOW_STEPS:.4g} s "
            f"(the logger's step in {layout.path} is {layout.step_s:g} s)",
        )
    if not layout.step_s or layout.step_s <= 0:
        return
    if not step and duration / layout.step_s > MAX_ROWS:
        raise ConfigError(
            file,
            "cleaning.step_s",
            None,
            f"{key} spans {duration / layout.step_s:,.0f} logger steps of {layout.step_s:g} s "
            f"in {layout.path}, more than the {MAX_ROWS:,} rows a tidy table may hold: set "
            f"cleaning.step_s to resample it (at least {duration / MAX_ROWS:.3g} s; 60 s keeps "
            "a thermal test's dynamics)",
        )
    if duration < MIN_WINDOW_STEPS * layout.step_s:
        raise ConfigError(
            file,
            f"{key}.end",
            window["end"],
            f"the window lasts {duration:g} s, fewer than {MIN_WINDOW_STEPS} logger steps of "
            f"{layout.step_s:g} s in {layout.path}: too short to fit or test anything",
        )


def _check_record_size(file: str, layout: RawLayout) -> None:
    """The raw record completed to its logger step: beyond MAX_ROWS rows a jump between two
    rows longer than TYPO_GAP_S is a typo in a timestamp (a span of years at a step of
    seconds), and no record may exceed MAX_RAW_ROWS; both refused before they are allocated."""
    if not layout.step_s or layout.step_s <= 0:
        return
    span = layout.seconds(layout.t_last)
    rows = span / layout.step_s
    jump = layout.gap_s is not None and layout.gap_s > TYPO_GAP_S
    if rows > MAX_ROWS and (jump or layout.gap_s is None):
        raise ConfigError(
            file,
            "raw_files",
            layout.path,
            f"its rows run from {fmt_time(layout.t_first)} to {fmt_time(layout.t_last)} at a "
            f"step of {layout.step_s:g} s: {rows:,.0f} rows to complete, more than "
            f"{MAX_ROWS:,}; a typo in a timestamp (the year?) or the wrong time format "
            "(format.time.format)?",
        )
    if rows > MAX_RAW_ROWS:
        raise ConfigError(
            file,
            "raw_files",
            layout.path,
            f"{rows:,.0f} rows at its step of {layout.step_s:g} s, more than {MAX_RAW_ROWS:,} "
            "that one raw file may hold: split the record into several raw_files (one per "
            "test), each listed with its windows",
        )


def _window_time(
    file: str, key: str, value: Any, tf: timeaxis.TimeFormat, layout: RawLayout
) -> Any:
    """A window bound as the file's time type (:func:`railtherm.data.timeaxis.instant`): a
    ``pandas.Timestamp`` for a file of instants, written in the file's notation or ISO 8601;
    float seconds for elapsed time, written as a number in the file's unit."""
    stamp = timeaxis.instant(file, key, value, tf)
    if not tf.absolute:
        return stamp
    file_tz = getattr(layout.t_first, "tzinfo", None)
    if (stamp.tzinfo is None) != (file_tz is None):
        if file_tz is None:
            reason = f"has a time zone but the timestamps of {layout.path} have none"
        else:
            reason = f"has no time zone but the timestamps of {layout.path} have one"
        raise ConfigError(file, key, value, reason)
    return stamp


def _solar_parameters(data: dict[str, Any]) -> tuple[str, ...]:
    """The solar parameters of a vehicle's irradiance inputs I_<name>: the effective aperture
    a_I_<name> of each, and the envelope share f_I_<name> of a gain declared on both nodes."""
    channels = data["channels"].get("irradiance") or []
    names = irradiance_names(data)
    shares = [f"f_{n}" for n, c in zip(names, channels, strict=True) if c.get("node") == "both"]
    return tuple(f"a_{n}" for n in names) + tuple(shares)


def _check_model(
    file: str,
    model: dict[str, Any],
    own: dict[str, Any],
    prefix: str = "model",
    solar: tuple[str, ...] | None = None,
) -> None:
    """Bounds lo < hi; initial values inside their bounds (after merging the defaults); each
    prior a known kind with its parameters in range (:func:`railtherm.estimation.priors.
    prior_from_config`). With ``solar`` (a vehicle's solar parameters,
    :func:`_solar_parameters`), a solar parameter that the vehicle's own initial, bounds or
    priors name must be one of them (one the study's defaults name is ignored where it does
    not apply)."""
    bounds = model.get("bounds") or {}
    initial = model.get("initial") or {}

    def origin(section: str, name: str) -> str:
        mine = name in (own.get(section) or {})
        return "" if mine else f" (model.{section}.{name} from the study's defaults.model)"

    for name, spec in (model.get("priors") or {}).items():
        try:
            prior = prior_from_config(spec, f"{prefix}.priors.{name}")
        except PriorError as err:
            key, _, message = str(err).partition(": ")
            value = spec.get(key.rsplit(".", 1)[-1], spec) if isinstance(spec, dict) else spec
            raise ConfigError(file, key, value, message + origin("priors", name)) from None
        search = (model.get("bounds") or {}).get(name) or structures.search_bounds(name)
        problem = outside_bounds(prior, name, search)
        if problem:
            key = f"{prefix}.priors.{name}"
            raise ConfigError(file, key, spec, problem + origin("priors", name))
    if solar is not None:
        for section in ("initial", "bounds", "priors"):
            for name in own.get(section) or {}:
                if section == "priors" and name.startswith(("sigma_", "s_")):
                    # the Kalman estimator's noise parameters
                    if name not in structures.noise_parameters():
                        raise ConfigError(
                            file,
                            f"{prefix}.priors.{name}",
                            (own.get(section) or {})[name],
                            "no such noise parameter: sigma_<state> (a state's diffusion) or "
                            "s_<output> (an output's measurement variance), of "
                            f"{', '.join(structures.noise_parameters())}",
                        )
                    continue
                if name not in PARAMETERS and name not in solar:
                    accepted = ", ".join(PARAMETERS + solar)
                    raise ConfigError(
                        file,
                        f"{prefix}.{section}.{name}",
                        (own.get(section) or {})[name],
                        f"no such parameter for this vehicle's inputs (accepted: {accepted}); a "
                        "solar parameter names an input of channels.irradiance, f_ one on "
                        "node both",
                    )
    for name, (lo, hi) in bounds.items():
        if not lo < hi:
            raise ConfigError(
                file,
                f"{prefix}.bounds.{name}",
                bounds[name],
                f"lower bound must be < upper bound{origin('bounds', name)}",
            )
    for name, value in initial.items():
        if name in bounds:
            lo, hi = bounds[name]
            if not lo <= value <= hi:
                raise ConfigError(
                    file,
                    f"{prefix}.initial.{name}",
                    value,
                    f"outside {prefix}.bounds.{name} = [{lo:g}, {hi:g}]"
                    f"{origin('initial', name)}{origin('bounds', name)}",
                )


# ---------------------------------------------------------------------------------------------
# Study


def load_study(
    config: Mapping[str, Any],
    workdir: str | os.PathLike[str] = ".",
    config_file: str = "config/config.yaml",
    cache: str | os.PathLike[str] | None = None,
) -> Study:
    """Load every vehicle of the study config (paths relative to ``workdir``).

    If the config names a ``campaign``, its planned raw-file layouts are used for raw files the
    virtual wind tunnel has not written yet. Checks that listed vehicle files exist, vehicle
    ids are unique and ``defaults.model`` is valid; messages name ``config_file`` for mistakes
    in the study config and the vehicle file for mistakes there.

    ``cache`` is a file (e.g. ``.snakemake/railtherm/vehicles.pickle``) keeping the validated
    vehicles for the next load (:class:`VehicleCache`): a vehicle whose file, raw files and
    context are unchanged is taken from it, neither its YAML nor its raw files read again.

    Parameters
    ----------
    config : mapping
        The study config (``config/config.yaml`` as read).
    workdir : str or os.PathLike
        The directory the config's paths are relative to.
    config_file : str
        The study config's name, for messages.
    cache : str or os.PathLike, optional
        A file keeping the validated vehicles for the next load.

    Returns
    -------
    Study
        The study: its vehicles by id, in the config's order, and its settings.

    Raises
    ------
    ConfigError
        Naming the study config or the vehicle file and the key at fault.
    """
    workdir = str(workdir)
    study = study_context(config, workdir, config_file)
    check_study_plans(config, workdir, config_file)
    vehicle_cache = VehicleCache(cache) if cache is not None else None
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
        add_vehicle(study, local, workdir, cache=vehicle_cache)
    if vehicle_cache is not None:
        vehicle_cache.save()
    check_energy_classes(study, config, config_file, workdir)
    return study


def check_study_plans(
    config: Mapping[str, Any], workdir: str | os.PathLike[str] = ".", config_file: str = ""
) -> None:
    """The study config's settings of the design table and the annual energy, as the
    workflow and ``railtherm validate`` alike read them: ``design.target`` a parameter the
    second-order fit estimates, each ``energy.what_if`` readable, the ``energy`` weather and
    profile files given (when enabled), present and the profile valid, and no what-if
    contradicting the profile (:func:`railtherm.study.energy.check_what_ifs`, which
    ``railtherm energy`` runs on its ``--what-if`` too). A mistake is a :class:`ConfigError` naming
    ``config_file`` and the key."""
    from railtherm import structures
    from railtherm.study.design import parse_target
    from railtherm.study.energy import check_what_ifs, load_profile, parse_what_if, step_problem

    config_file = config_file or "config/config.yaml"
    target = (config.get("design") or {}).get("target")
    energy = config.get("energy") or {}
    texts = [("design.target", parse_target, target)] if target is not None else []
    texts += [
        (f"energy.what_if[{i}]", parse_what_if, t)
        for i, t in enumerate(energy.get("what_if") or [])
    ]
    what_ifs = []
    for key, parse, text in texts:
        try:
            parsed = parse(text)
        except ConfigError as err:
            raise ConfigError(config_file, key, text, err.reason) from None
        if parse is parse_target and "order2" in structures.keys():  # else none fits order 2
            allowed = [p for p in structures.by_key("order2").parameters if p != "kA"]
            if parsed[0] not in allowed:
                raise ConfigError(config_file, key, text, f"a parameter of {allowed}")
        if parse is parse_what_if:
            what_ifs.append(parsed)
    if not energy.get("enabled", False):
        return
    step = step_problem(float(energy.get("step_s", 300)))
    if step:
        raise ConfigError(config_file, "energy.step_s", energy.get("step_s"), step)
    weather = energy.get("weather") or []
    names: dict[str, str] = {}
    for i, path in enumerate(weather):
        if not os.path.isfile(os.path.join(str(workdir), path)):
            raise ConfigError(config_file, f"energy.weather[{i}]", path, "weather file not found")
        name = os.path.basename(path).split(".")[0]  # the year's name in results/weather/
        if name in names:
            raise ConfigError(
                config_file,
                f"energy.weather[{i}]",
                path,
                f"the same file name as {names[name]}: the study names each typical year by "
                "its file name, so give the copies different names",
            )
        names[name] = path
    files = {"energy.profile": energy.get("profile")} if energy.get("profile") else {}
    files.update({f"energy.profiles.{c}": p for c, p in (energy.get("profiles") or {}).items()})
    if not files:
        raise ConfigError(
            config_file,
            "energy.profile",
            energy.get("profile"),
            "energy.enabled is true but no operating profile is given: name one per class "
            "(profiles: {tram: config/profiles/tram_service.yaml, ...}) or one for all, e.g. "
            "profile: config/profiles/metro_service.yaml (docs/energy.md), or set "
            "energy.enabled: false",
        )
    loaded = {}
    for key, path in files.items():
        local = os.path.join(str(workdir), path)
        if not os.path.isfile(local):
            raise ConfigError(config_file, key, path, "profile file not found")
        loaded[key] = load_profile(local)
    if not weather:
        raise ConfigError(
            config_file,
            "energy.weather",
            weather,
            "energy.enabled is true but no typical year is given: list one or more weather "
            "files (TMY3, EPW, PVGIS or CSV), e.g. weather: [config/weather/703165TY.csv], or "
            "set energy.enabled: false",
        )
    what_if_keys = [f"energy.what_if[{i}]" for i in range(len(what_ifs))]
    for profile in loaded.values():
        check_what_ifs(profile, what_ifs, energy.get("what_if") or [], config_file, what_if_keys)


def energy_profile(config: Mapping[str, Any], vehicle_class: str) -> str | None:
    """The operating profile (path) of a vehicle of ``vehicle_class`` in the annual energy:
    its class's in ``energy.profiles``, else ``energy.profile``, else None."""
    energy = config.get("energy") or {}
    return (energy.get("profiles") or {}).get(vehicle_class) or energy.get("profile") or None


def check_energy_classes(
    study: Study, config: Mapping[str, Any], config_file: str, workdir: str = "."
) -> None:
    """With the annual energy enabled, every vehicle's class has an operating profile
    (:func:`energy_profile`), and a vehicle whose profile sizes the heater per m² gives its
    surface: a :class:`ConfigError` naming the first class without a profile, or the
    vehicle file without its surface."""
    from railtherm.study.energy import load_profile

    energy = config.get("energy") or {}
    if not energy.get("enabled", False):
        return
    sized: dict[str, bool] = {}  # profile path: its heater is per m² of surface
    for vid, vehicle in study.vehicles.items():
        vehicle_class = str(vehicle.data.get("class", ""))
        path = energy_profile(config, vehicle_class)
        if path is None:
            raise ConfigError(
                config_file,
                f"energy.profiles.{vehicle_class}",
                None,
                f"vehicle {vid} is of class {vehicle_class!r}, which has no operating profile: "
                f"add one to energy.profiles (or a default energy.profile)",
            )
        if path not in sized:
            profile = load_profile(os.path.join(str(workdir), path))
            sized[path] = profile.heating_limit_W_per_m2 is not None
        if sized[path] and vehicle.data.get("surface_m2") is None:
            raise ConfigError(
                vehicle.path,
                "surface_m2",
                None,
                f"its class's profile {path} sizes the heater per m² of outer surface: give "
                "the vehicle's surface_m2, or a profile with heating_limit_W",
            )


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
    check_finite(config_file, dict(config))
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


def add_vehicle(
    study: Study,
    path: str | os.PathLike[str],
    workdir: str = ".",
    cache: VehicleCache | None = None,
) -> Vehicle:
    """Load one vehicle file under the study's defaults and layouts and add it to the study
    (from ``cache`` when it holds the vehicle validated under the same conditions).

    :class:`ConfigError` naming the vehicle file when its id is already taken.
    """
    vehicle = cache.get(path, study, workdir) if cache is not None else None
    if vehicle is None:
        vehicle = load_vehicle(
            path, defaults=study.defaults, layouts=study.layouts, workdir=workdir
        )
        if cache is not None:
            cache.put(path, study, workdir, vehicle)
    if vehicle.id in study.vehicles:
        raise ConfigError(
            _display(str(path), workdir),
            "id",
            vehicle.id,
            f"duplicate vehicle id (also in {study.vehicles[vehicle.id].path})",
        )
    study.vehicles[vehicle.id] = vehicle
    return vehicle


# ---------------------------------------------------------------------------------------------
# Parse cache


@functools.cache
def _code_version() -> str:
    """Digest of the railtherm code validation can run and read (this module's imports in
    turn, with the schemas: :func:`railtherm.codedigest.code_digest`) and of the libraries that
    parse files: any change invalidates the cache."""
    h = hashlib.sha256(sys.version.encode())
    for dist in ("pandas", "numpy", "PyYAML", "jsonschema"):
        try:
            h.update(f"{dist} {importlib.metadata.version(dist)}".encode())
        except importlib.metadata.PackageNotFoundError:
            h.update(f"{dist} ?".encode())
    h.update(codedigest.code_digest(__file__).encode())
    return h.hexdigest()


def _stat_key(path: str) -> list[int] | None:
    """What tells a file changed: size, mtime, ctime (which no user sets back) and inode; None
    for a file that does not exist."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return [st.st_size, st.st_mtime_ns, st.st_ctime_ns, st.st_ino]


class VehicleCache:
    """Vehicles validated by :func:`load_vehicle`, kept in a pickle file for the next load.

    An entry is reused while everything its validation read is unchanged: the bytes of the
    vehicle file, its path and the working directory, the study's ``defaults`` and planned
    raw-file layouts (a campaign's), the size, mtime, ctime and inode of each raw file (or its
    absence), and the railtherm code and parsing libraries (:func:`_code_version`). A vehicle
    whose validation failed is not kept, so its error is raised again on every load. The file
    holds the vehicles of the last load only; a missing, broken or other-version file is only
    a cache (nothing is reused), and one that cannot be written costs time, not correctness.
    ``hits`` and ``misses`` count the lookups of this load.
    """

    def __init__(self, path: str | os.PathLike[str] | None = None):
        self.path = None if path is None else os.path.abspath(path)
        self.entries: dict[str, tuple[str, list, Vehicle]] = {}
        self.used: dict[str, tuple[str, list, Vehicle]] = {}
        self.hits = self.misses = 0
        self._dirty = False
        self._context: tuple[int, str] | None = None
        if self.path and os.path.isfile(self.path):
            try:
                with open(self.path, "rb") as stream:
                    if pickle.load(stream) == _code_version():
                        self.entries = pickle.load(stream)
            except Exception:  # a broken or foreign cache is only a cache
                self.entries = {}

    def _study_digest(self, study: Study, workdir: str) -> str:
        """Digest of what every vehicle of ``study`` is validated under (computed once)."""
        if self._context is None or self._context[0] != id(study):
            h = hashlib.sha256(os.path.abspath(workdir).encode())
            h.update(json.dumps(study.defaults, sort_keys=True, default=repr).encode())
            h.update(repr(sorted(study.layouts.items())).encode())
            self._context = (id(study), h.hexdigest())
        return self._context[1]

    def _key(self, path: str | os.PathLike[str], study: Study, workdir: str) -> tuple[str, str]:
        name = os.path.abspath(path)
        h = hashlib.sha256(_code_version().encode())
        h.update(self._study_digest(study, workdir).encode())
        h.update(name.encode())
        try:
            with open(name, "rb") as stream:
                h.update(stream.read())
        except OSError:
            h.update(b"(unreadable)")
        return name, h.hexdigest()

    def get(self, path: str | os.PathLike[str], study: Study, workdir: str) -> Vehicle | None:
        """The vehicle of ``path`` as validated before under the same conditions, or None."""
        name, key = self._key(path, study, workdir)
        entry = self.entries.get(name)
        if entry is not None and entry[0] == key:
            if all(_stat_key(file) == stat for file, stat in entry[1]):
                self.hits += 1
                self.used[name] = entry
                return entry[2]
        self.misses += 1
        return None

    def put(self, path: str | os.PathLike[str], study: Study, workdir: str, vehicle: Vehicle):
        """Keep ``vehicle``, just validated from ``path``, with the state of its raw files."""
        name, key = self._key(path, study, workdir)
        yaml_dir = os.path.dirname(name)
        files = [
            os.path.abspath(os.path.normpath(os.path.join(yaml_dir, raw)))
            for raw in (
                vehicle.data["raw_files"].values()
                if "raw_files" in vehicle.data
                else [
                    r
                    for src in vehicle.data[sources.SOURCES].values()
                    for r in src["files"].values()
                ]
            )
        ]
        self.used[name] = (key, [(f, _stat_key(f)) for f in files], vehicle)
        self._dirty = True

    def save(self) -> None:
        """Write the vehicles of this load (when any was validated anew, or one left)."""
        if not self.path or not (self._dirty or self.used.keys() != self.entries.keys()):
            return
        try:
            os.makedirs(os.path.dirname(self.path), exist_ok=True)
            tmp = f"{self.path}.{os.getpid()}.tmp"
            with open(tmp, "wb") as stream:
                pickle.dump(_code_version(), stream)
                pickle.dump(self.used, stream, protocol=pickle.HIGHEST_PROTOCOL)
            os.replace(tmp, self.path)
        except OSError:
            pass  # an unwritable cache costs time, not correctness
        self.entries, self._dirty = dict(self.used), False
