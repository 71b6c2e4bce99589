"""The virtual climatic wind tunnel (CWT): synthetic raw files from declared ground truth.

The paper's measurements are proprietary, so the study ships a SYNTHETIC campaign: a YAML file
(config/campaign/virtual_cwt.yaml) declares, per vehicle, the true parameters (k, C, K_veh,
C_veh from Table 2, masses implied by Table 3 or assumed), the experiment programme (paper
section 3), the instruments and logger, and any declared deviation from the paper's
assumptions (section 4). This module simulates each vehicle and writes the raw CSV files a lab
logger would have written. See docs/virtual-cwt.md.

Physics: the generic balance eq. 1 around the two-capacity model, eqs. 7-8 / 14, states
x = [T, T_veh] (+ T_zone for ``poor_mixing``), inputs T_o and Q_H (eq. 3: heaters + fans (+ the
HVAC during pre-heating)) plus eq. 1's Q_aux when a deviation declares unlogged auxiliaries.
The linear part is simulated EXACTLY by zero-order hold (matrix exponential,
:func:`railtherm.models.discretize_zoh`) on the fine step ``fine_step_s`` with every input held
constant over a fine step; the controllers (tunnel temperature, HVAC pre-heating, heater
thermostat) act once per fine step. The one non-linear deviation (``temperature_dependent_k``)
freezes its extra loss per fine step.

Logger conventions: one sample every ``step_s``; temperatures are instantaneous values at the
sample time; powers are the mean over the preceding logging interval [t - step_s, t) as
integrating power meters report them.
"""

from __future__ import annotations

import copy
import gzip
import io
import json
import math
import posixpath
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.signal import lfilter

from railtherm.errors import ConfigError
from railtherm.models import discretize_zoh, second_order
from railtherm.rawfile import RawLayout
from railtherm.yamlio import deep_merge, read_yaml, validate_schema

__all__ = [
    "DEVIATION_TYPES",
    "SOURCE_PREFIXES",
    "TRUTH_UNITS",
    "columns",
    "ground_truth_sources",
    "ground_truth_table",
    "load_campaign",
    "planned_layouts",
    "raw_file_names",
    "simulate",
    "time_constants",
    "vehicle_config",
    "vehicle_spec",
    "windows",
    "write_raw_file",
]

SOURCE_PREFIXES = ("published:", "implied:", "assumption:")
TRUTH_UNITS = {
    "k": "W/(m^2 K)",
    "C": "J/K",
    "K_veh": "W/K",
    "C_veh": "J/K",
    "mass_kg": "kg",
    "surface_m2": "m^2",
    "volume_m3": "m^3",
}
DEVIATION_TYPES = (
    "body_to_outdoor",
    "poor_mixing",
    "unsteady_start",
    "temperature_dependent_k",
    "unlogged_aux",
    "short_hold",
)
# What each declared deviation does to the standardized static k test (eq. 10): the physics
# behind a k estimate that disagrees with the truth. None: no bias expected at the k test.
DEVIATION_EFFECT_ON_K = {
    "body_to_outdoor": "heat also leaves through the body to T_o, so Q_H / (A (T - T_o)) "
    "counts that path too: static k biased up",
    "poor_mixing": "the indoor sensors may not see the mixed air temperature, so T - T_o and "
    "hence k may be biased",
    "unsteady_start": None,
    "temperature_dependent_k": None,
    "unlogged_aux": "unlogged auxiliary heat enters the interior but not Q_H: static k biased low",
    "short_hold": "the hold ends before steady state: heat still goes into storage, so static k "
    "is biased up and the window drifts",
}
LN20 = math.log(20.0)  # 95 % of a first-order step response is reached after ln(20) tau

# --------------------------------------------------------------------------------------------
# Campaign schema (validated with jsonschema; semantic checks follow in _check_vehicle)
# --------------------------------------------------------------------------------------------
_NUM = {"type": "number"}
_POS = {"type": "number", "exclusiveMinimum": 0}
_NONNEG = {"type": "number", "minimum": 0}
_INT_POS = {"type": "integer", "minimum": 1}
_INT_NONNEG = {"type": "integer", "minimum": 0}
_TRUTH = {
    "type": "object",
    "additionalProperties": False,
    "required": ["value", "unit", "source"],
    "properties": {
        "value": _POS,
        "unit": {"type": "string"},
        "source": {"type": "string", "pattern": "^(published|implied|assumption): .+"},
    },
}
_ENTRY_PROPS: dict[str, Any] = {
    "class": {"enum": ["tram", "metro", "regional", "main-line", "other"]},
    "description": {"type": "string"},
    "start": {"type": "string", "pattern": r"^\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d$"},
    "truth": {
        "type": "object",
        "additionalProperties": False,
        "required": list(TRUTH_UNITS),
        "properties": {q: _TRUTH for q in TRUTH_UNITS},
    },
    "programme": {
        "type": "object",
        "additionalProperties": False,
        "required": ["type", "T_tunnel"],
        "properties": {
            "type": {"enum": ["existing", "special"]},
            "T_tunnel": _NUM,
            # existing
            "soak_h": _POS,
            "preheat_h": _POS,
            "hold_h": _POS,
            "cooldown_h": _POS,
            "T_preheat": _NUM,
            "T_setpoint": _NUM,
            "kvalue_window_h": _POS,
            # special
            "base_h": _POS,
            "base_groups": _INT_NONNEG,
            "step_groups": _INT_POS,
            "up_h": {"oneOf": [_POS, {"const": "auto"}]},
            "down_h": {"oneOf": [_POS, {"const": "auto"}]},
            "overlap_h": _NONNEG,
        },
    },
    "logger": {
        "type": "object",
        "additionalProperties": False,
        "properties": {
            "step_s": {"type": "integer", "minimum": 10, "maximum": 600},
            "time_format": {"enum": ["iso", "seconds"]},
            "time_column": {"type": "string", "minLength": 1},
            "separator": {"enum": [",", ";", "\t"]},
            "decimal": {"enum": [".", ","]},
            "gzip": {"type": "boolean"},
            "power_unit": {"enum": ["W", "kW"]},
            "hvac_unit": {"enum": ["W", "kW"]},
            "temperature_unit": {"enum": ["degC", "K"]},
            "temperature_decimals": {"type": "integer", "minimum": 1, "maximum": 4},
            "naming": {"enum": ["tag", "german", "dotted", "english", "channel"]},
            "heater_channels": {"enum": ["per_group", "total"]},
            "fan_channels": {"enum": ["per_fan", "total"]},
            "extras": {"type": "array", "items": {"enum": ["humidity", "wind"]}},
        },
    },
    "sensors": {
        "type": "object",
        "additionalProperties": False,
        "properties": {
            "indoor": {
                "type": "object",
                "additionalProperties": False,
                "properties": {
                    "heights_m": {"type": "array", "minItems": 1, "items": _NONNEG},
                    "weights": {"type": "array", "items": _POS},
                    "noise_K": _NONNEG,
                    "offset_sd_K": _NONNEG,
                },
            },
            "surface": {
                "type": "object",
                "additionalProperties": False,
                "properties": {"n": _INT_NONNEG, "noise_K": _NONNEG, "offset_sd_K": _NONNEG},
            },
            "outdoor": {
                "type": "object",
                "additionalProperties": False,
                "properties": {"n": _INT_POS, "noise_K": _NONNEG, "offset_sd_K": _NONNEG},
            },
            "reference_height_m": _NONNEG,
            "stratification_K_per_m_kW": _NONNEG,
            "response_s": _POS,
        },
    },
    "tunnel": {
        "type": "object",
        "additionalProperties": False,
        "properties": {"lag_s": _POS, "fluctuation_sd_K": _NONNEG, "correlation_s": _POS},
    },
    "heaters": {
        "type": "object",
        "additionalProperties": False,
        "properties": {
            "groups": _INT_POS,
            "power_W": _POS,
            "tolerance_rel": _NONNEG,
            "hysteresis_K": _POS,
            "dwell_s": _NONNEG,
        },
    },
    "hvac": {
        "type": "object",
        "additionalProperties": False,
        "properties": {
            "power_max_W": _POS,
            "band_K": _POS,
            "airflow_bias_sd": _NONNEG,
            "airflow_noise_rel": _NONNEG,
        },
    },
    "fans": {
        "type": "object",
        "additionalProperties": False,
        "properties": {"n": _INT_NONNEG, "power_W": _NONNEG},
    },
    "power_meter": {
        "type": "object",
        "additionalProperties": False,
        "properties": {"noise_rel": _NONNEG},
    },
    "dropouts": {
        "type": "object",
        "additionalProperties": False,
        "properties": {"missing_rows": _INT_NONNEG, "empty_cells": _INT_NONNEG},
    },
    "deviations": {
        "type": "array",
        "items": {
            "type": "object",
            "required": ["type", "note"],
            "properties": {"type": {"enum": list(DEVIATION_TYPES)}, "note": {"type": "string"}},
        },
    },
}
_ENTRY_REQUIRED = ["class", "start", "truth", "programme", "heaters"]
# Built-in defaults, merged under the campaign's own `defaults` (documented in docs/virtual-cwt.md)
_BUILTIN: dict[str, Any] = {
    "tunnel": {"lag_s": 900.0, "fluctuation_sd_K": 0.12, "correlation_s": 1200.0},
    "heaters": {"tolerance_rel": 0.02, "hysteresis_K": 0.3, "dwell_s": 120.0},
    "hvac": {
        "power_max_W": 30000.0,
        "band_K": 2.0,
        "airflow_bias_sd": 0.08,
        "airflow_noise_rel": 0.04,
    },
    "fans": {"n": 4, "power_W": 250.0},
    "power_meter": {"noise_rel": 0.007},
    "sensors": {
        "indoor": {"heights_m": [0.1, 1.1, 1.7, 1.1], "noise_K": 0.07, "offset_sd_K": 0.15},
        "surface": {"n": 4, "noise_K": 0.08, "offset_sd_K": 0.2},
        "outdoor": {"n": 2, "noise_K": 0.08, "offset_sd_K": 0.1},
        "reference_height_m": 1.1,
        "stratification_K_per_m_kW": 0.008,
        "response_s": 120.0,
    },
    "logger": {
        "step_s": 60,
        "time_format": "iso",
        "time_column": "time",
        "separator": ",",
        "decimal": ".",
        "gzip": False,
        "power_unit": "W",
        "temperature_unit": "degC",
        "temperature_decimals": 2,
        "naming": "tag",
        "heater_channels": "per_group",
        "fan_channels": "per_fan",
        "extras": [],
    },
    "dropouts": {"missing_rows": 4, "empty_cells": 6},
    "deviations": [],
}
_DEVIATION_SCHEMAS = {
    "body_to_outdoor": {"K_o": _POS},
    "poor_mixing": {
        "zone_fraction": {"type": "number", "exclusiveMinimum": 0, "exclusiveMaximum": 1},
        "zone_loss_fraction": {"type": "number", "minimum": 0, "exclusiveMaximum": 1},
        "K_zone": _POS,
        "zone_sensors": {"type": "array", "items": _INT_POS},
        "plume_sensors": {"type": "array", "items": _INT_POS},
        "plume_K_per_kW": _NONNEG,
    },
    "unsteady_start": {"dT_air_K": _NUM, "dT_body_K": _NUM},
    "temperature_dependent_k": {"beta_per_K": _NUM},
    "unlogged_aux": {
        "power_W": _POS,
        "on_h": {
            "type": "array",
            "minItems": 1,
            "items": {"type": "array", "minItems": 2, "maxItems": 2, "items": _NONNEG},
        },
    },
    "short_hold": {"hold_h": _POS},
}
_CAMPAIGN_SCHEMA = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "type": "object",
    "additionalProperties": False,
    "required": ["name", "synthetic", "description", "seed", "fine_step_s", "vehicles"],
    "properties": {
        "name": {"type": "string", "minLength": 1},
        "synthetic": {"const": True},
        "description": {"type": "string"},
        "seed": {"type": "integer", "minimum": 0},
        "fine_step_s": {"type": "integer", "minimum": 1},
        "defaults": {"type": "object", "additionalProperties": False, "properties": _ENTRY_PROPS},
        "vehicles": {
            "type": "object",
            "minProperties": 1,
            "propertyNames": {"pattern": "^[A-Za-z][A-Za-z0-9_-]*$"},
            "additionalProperties": {"type": "object"},
        },
    },
}
_VEHICLE_SCHEMA = {
    "type": "object",
    "additionalProperties": False,
    "required": _ENTRY_REQUIRED,
    "properties": _ENTRY_PROPS,
}


def load_campaign(path) -> dict:
    """Parse and validate a campaign file; returns the dict (vehicles in file order).

    Raises ConfigError naming the campaign file, the key path (e.g.
    ``vehicles.Tram1.logger.step_s``) and the value on any bad entry.
    """
    path = Path(path)
    if not path.is_file():
        raise ConfigError(path, "campaign", str(path), "campaign file not found")
    data = read_yaml(path)
    validate_schema(str(path), data, _CAMPAIGN_SCHEMA)
    defaults = data.get("defaults", {}) or {}
    merged = {}
    base = deep_merge(_BUILTIN, defaults)
    for vid, entry in data["vehicles"].items():
        m = deep_merge(base, entry or {})
        validate_schema(str(path), m, _VEHICLE_SCHEMA, prefix=f"vehicles.{vid}")
        _check_vehicle(path, data, vid, m)
        merged[vid] = m
    data["_merged"] = merged
    data["_path"] = str(path)
    return data


def _check_vehicle(path, campaign: dict, vid: str, m: dict) -> None:
    """Semantic checks the schema cannot express."""

    def bad(key, value, reason):
        raise ConfigError(path, f"vehicles.{vid}.{key}", value, reason)

    for k in ("groups", "power_W"):
        if k not in m["heaters"]:
            bad(f"heaters.{k}", None, "required key missing")
    for q, unit in TRUTH_UNITS.items():
        if m["truth"][q]["unit"] != unit:
            bad(f"truth.{q}.unit", m["truth"][q]["unit"], f"expected '{unit}'")
    dt = campaign["fine_step_s"]
    step = m["logger"]["step_s"]
    if step % dt:
        bad("logger.step_s", step, f"must be a multiple of fine_step_s = {dt}")
    p = m["programme"]
    need = (
        ["soak_h", "preheat_h", "hold_h", "cooldown_h", "T_preheat", "T_setpoint"]
        if p["type"] == "existing"
        else ["base_h", "base_groups", "step_groups", "up_h", "down_h"]
    )
    for k in need:
        if k not in p:
            bad(f"programme.{k}", None, f"required for a '{p['type']}' programme")
    for k in ("soak_h", "preheat_h", "hold_h", "cooldown_h", "base_h", "up_h", "down_h"):
        v = p.get(k)
        if isinstance(v, int | float) and (v * 3600) % step:
            bad(f"programme.{k}", v, f"must be a whole number of logger steps ({step} s)")
    if p["type"] == "special" and p["base_groups"] + p["step_groups"] > m["heaters"]["groups"]:
        bad("programme.step_groups", p["step_groups"], "base + step groups exceed heaters.groups")
    n_in = len(m["sensors"]["indoor"]["heights_m"])
    w = m["sensors"]["indoor"].get("weights")
    if w is not None and len(w) != n_in:
        bad("sensors.indoor.weights", w, f"need one weight per indoor sensor ({n_in})")
    seen = set()
    for i, d in enumerate(m.get("deviations", [])):
        t = d["type"]
        if t in seen:
            bad(f"deviations[{i}].type", t, "declared twice")
        seen.add(t)
        schema = {
            "type": "object",
            "additionalProperties": False,
            "required": ["type", "note", *_DEVIATION_SCHEMAS[t]],
            "properties": {"type": {}, "note": {}, **_DEVIATION_SCHEMAS[t]},
        }
        validate_schema(str(path), d, schema, prefix=f"vehicles.{vid}.deviations[{i}]")
        for k in ("zone_sensors", "plume_sensors"):
            for j in d.get(k, []):
                if j > n_in:
                    bad(f"deviations[{i}].{k}", j, f"only {n_in} indoor sensors")
        if t == "short_hold" and (d["hold_h"] * 3600) % step:
            bad(f"deviations[{i}].hold_h", d["hold_h"], "must be a whole number of logger steps")
    if p["type"] == "special" and seen & {"short_hold", "temperature_dependent_k"}:
        bad("deviations", sorted(seen), "short_hold/temperature_dependent_k need 'existing'")
    if p["type"] == "existing":
        hold = _deviation(m, "short_hold", {}).get("hold_h", p["hold_h"])
        if p.get("kvalue_window_h", 8) > hold:
            bad("programme.kvalue_window_h", p.get("kvalue_window_h"), "longer than the hold")


def _deviation(spec: dict, kind: str, default=None):
    for d in spec.get("deviations", []):
        if d["type"] == kind:
            return d
    return default


# --------------------------------------------------------------------------------------------
# Spec: everything one vehicle needs, JSON-able
# --------------------------------------------------------------------------------------------
def _truth_values(m: dict) -> dict:
    t = {q: float(m["truth"][q]["value"]) for q in TRUTH_UNITS}
    t["A"] = t.pop("surface_m2")
    t["kA"] = t["k"] * t["A"]
    return t


def time_constants(spec: dict) -> tuple[float, float]:
    """(tau_fast, tau_slow) in s: -1/eigenvalues of eq. 14's A (declared model, no deviation)."""
    tr = spec["truth"]
    A, _ = second_order(tr["kA"], tr["C"], tr["K_veh"], tr["C_veh"])
    lam = np.sort(np.linalg.eigvals(A).real)
    return float(-1.0 / lam[0]), float(-1.0 / lam[1])


def vehicle_spec(campaign: dict, vehicle_id: str) -> dict:
    """Everything needed to synthesise one vehicle's raw files, as a plain JSON-able dict.

    Campaign defaults are merged in; ``seed`` is [campaign seed, crc32(vehicle id)] so one
    vehicle's files do not depend on the others; the programme is resolved to phase times in s.
    """
    if vehicle_id not in campaign["_merged"]:
        raise ConfigError(campaign["_path"], "vehicles", vehicle_id, "no such vehicle")
    m = copy.deepcopy(campaign["_merged"][vehicle_id])
    spec: dict[str, Any] = {
        "id": vehicle_id,
        "class": m["class"],
        "campaign": campaign["name"],
        "seed": [int(campaign["seed"]), zlib.crc32(vehicle_id.encode())],
        "fine_step_s": int(campaign["fine_step_s"]),
        "start": m["start"],
        "truth": _truth_values(m),
    }
    for k in ("logger", "sensors", "tunnel", "heaters", "hvac", "fans", "power_meter"):
        spec[k] = m.get(k, {})
    spec["dropouts"] = m["dropouts"]
    spec["deviations"] = m.get("deviations", [])
    lg = spec["logger"]
    lg.setdefault("hvac_unit", lg.get("power_unit", "W"))
    p = dict(m["programme"])
    step = lg["step_s"]
    h = 3600.0
    if p["type"] == "existing":
        hold_h = _deviation(spec, "short_hold", {}).get("hold_h", p["hold_h"])
        p.setdefault("kvalue_window_h", 8)
        t_pre = p["soak_h"] * h
        t_k = t_pre + p["preheat_h"] * h
        t_cool = t_k + hold_h * h
        t_end = t_cool + p["cooldown_h"] * h
        p["phases_s"] = {"preheat": t_pre, "kvalue": t_k, "cooldown": t_cool, "end": t_end}
        ext = ".csv.gz" if lg["gzip"] else ".csv"
        files = [{"key": "cwt", "name": f"{vehicle_id}_cwt{ext}", "t0": 0.0, "t1": t_end}]
    else:
        _, tau_slow = time_constants(spec)
        auto = math.ceil(LN20 * tau_slow / h)  # 95 % of the step response (section 3.2)
        up_h = auto if p["up_h"] == "auto" else p["up_h"]
        down_h = auto if p["down_h"] == "auto" else p["down_h"]
        p.setdefault("kvalue_window_h", 6)
        p.setdefault("overlap_h", 1)
        t_up = p["base_h"] * h
        t_rev = t_up + up_h * h
        t_end = t_rev + down_h * h
        p["phases_s"] = {"step_up": t_up, "step_down": t_rev, "end": t_end}
        ext = ".csv.gz" if lg["gzip"] else ".csv"
        t_split = t_rev - p["overlap_h"] * h
        files = [
            {"key": "step_up", "name": f"{vehicle_id}_step_up{ext}", "t0": 0.0, "t1": t_rev},
            {
                "key": "step_down",
                "name": f"{vehicle_id}_step_down{ext}",
                "t0": t_split,
                "t1": t_end,
            },
        ]
    for f in files:
        for k in ("t0", "t1"):
            f[k] = float(math.floor(f[k] / step) * step)
    spec["programme"] = p
    spec["files"] = files
    return json.loads(json.dumps(spec))  # plain JSON types only


def raw_file_names(spec: dict) -> list[str]:
    """File names written for a vehicle (e.g. ``Tram1_cwt.csv.gz``), in file order."""
    return [f["name"] for f in spec["files"]]


# --------------------------------------------------------------------------------------------
# Columns
# --------------------------------------------------------------------------------------------
_SCHEMES = {
    "tag": {
        "indoor": "TI{:02d}",
        "surface": "TW{:02d}",
        "outdoor": "TA{:02d}",
        "hvac": "QKL01",
        "heater": "PH{:02d}",
        "heater_total": "PH_SUM",
        "fan": "PV{:02d}",
        "fan_total": "PV_SUM",
        "humidity": "RF01",
        "wind": "VW01",
    },
    "german": {
        "indoor": "T_Innen_{}",
        "surface": "T_Wand_{}",
        "outdoor": "T_Aussen_{}",
        "hvac": "Q_Klima_Luftstrom",
        "heater": "P_Heizung_{}",
        "heater_total": "P_Heizung_ges",
        "fan": "P_Luefter_{}",
        "fan_total": "P_Luefter_ges",
        "humidity": "rF_Innen",
        "wind": "v_Wind",
    },
    "dotted": {
        "indoor": "air.T.{}",
        "surface": "wall.T.{}",
        "outdoor": "tunnel.T.{}",
        "hvac": "hvac.Q",
        "heater": "heater.P.{}",
        "heater_total": "heater.P.total",
        "fan": "fan.P.{}",
        "fan_total": "fan.P.total",
        "humidity": "air.RH",
        "wind": "tunnel.v",
    },
    "english": {
        "indoor": "indoor_air_{}",
        "surface": "surface_{}",
        "outdoor": "tunnel_air_{}",
        "hvac": "hvac_heat_airflow",
        "heater": "heater_group_{}",
        "heater_total": "heater_total",
        "fan": "fan_{}",
        "fan_total": "fans_total",
        "humidity": "rel_humidity",
        "wind": "wind_speed",
    },
}


def columns(spec: dict) -> list[tuple[str, str, int]]:
    """(column name, kind, index) of every column of the vehicle's raw files, in file order.

    kind is one of time, indoor, surface, outdoor, hvac, heater, heater_total, fan, fan_total,
    humidity, wind; index counts from 1 within the kind (0 for single columns).
    """
    lg, se = spec["logger"], spec["sensors"]
    items: list[tuple[str, int]] = []
    items += [("indoor", i + 1) for i in range(len(se["indoor"]["heights_m"]))]
    items += [("surface", i + 1) for i in range(se["surface"]["n"])]
    items += [("outdoor", i + 1) for i in range(se["outdoor"]["n"])]
    if spec["programme"]["type"] == "existing":
        items.append(("hvac", 0))
    if lg["heater_channels"] == "per_group":
        items += [("heater", i + 1) for i in range(spec["heaters"]["groups"])]
    else:
        items.append(("heater_total", 0))
    if spec["fans"]["n"] > 0:
        if lg["fan_channels"] == "per_fan":
            items += [("fan", i + 1) for i in range(spec["fans"]["n"])]
        else:
            items.append(("fan_total", 0))
    items += [(x, 0) for x in lg.get("extras", [])]
    out = [(lg["time_column"], "time", 0)]
    if lg["naming"] == "channel":
        out += [(f"CH{j + 1:02d}", kind, i) for j, (kind, i) in enumerate(items)]
    else:
        fmt = _SCHEMES[lg["naming"]]
        out += [(fmt[kind].format(i), kind, i) for kind, i in items]
    return out


def _time_values(spec: dict, t_s: np.ndarray):
    if spec["logger"]["time_format"] == "seconds":
        return t_s.astype(float)
    base = np.datetime64(spec["start"], "s")
    return base + t_s.astype(np.int64).astype("timedelta64[s]")


def planned_layouts(campaign: dict, root: str = "resources/campaign") -> dict[str, RawLayout]:
    """Columns and first/last time of every raw file the campaign writes, WITHOUT simulating.

    Keyed by the normalised relative path ``{root}/{vehicle}/{name}``. The first and the last row
    of a file are never dropped, so the span is exact.
    """
    out = {}
    for vid in campaign["_merged"]:
        spec = vehicle_spec(campaign, vid)
        cols = tuple(c for c, _, _ in columns(spec))
        lg = spec["logger"]
        for f in spec["files"]:
            path = posixpath.normpath(f"{root}/{vid}/{f['name']}")
            t = _time_values(spec, np.array([f["t0"], f["t1"]]))
            if lg["time_format"] == "iso":
                t0, t1 = pd.Timestamp(t[0]), pd.Timestamp(t[1])
            else:
                t0, t1 = float(t[0]), float(t[1])
            out[path] = RawLayout(
                path, cols, lg["time_column"], lg["time_format"], t0, t1, float(lg["step_s"])
            )
    return out


# --------------------------------------------------------------------------------------------
# Simulation
# --------------------------------------------------------------------------------------------
def _rngs(spec: dict):
    """Independent streams: instruments, tunnel, noise, dropouts."""
    return [np.random.default_rng(s) for s in np.random.SeedSequence(spec["seed"]).spawn(4)]


def _instruments(spec: dict, rng) -> dict:
    """Per-vehicle realisation of the instruments (drawn in a fixed order)."""
    se = spec["sensors"]
    n_in = len(se["indoor"]["heights_m"])
    return {
        "indoor_offset": rng.normal(0, se["indoor"]["offset_sd_K"], n_in),
        "surface_offset": rng.normal(0, se["surface"]["offset_sd_K"], se["surface"]["n"]),
        "outdoor_offset": rng.normal(0, se["outdoor"]["offset_sd_K"], se["outdoor"]["n"]),
        "group_factor": 1 + rng.normal(0, spec["heaters"].get("tolerance_rel", 0.02), 64),
        "fan_factor": 1 + rng.normal(0, 0.03, 64),
        "hvac_bias": 1 + spec["hvac"].get("airflow_bias_sd", 0.08) * rng.normal(),
    }


def _system(spec: dict):
    """Continuous (A, B) with states [T, T_veh, T_zone] and inputs [T_o, Q into the air node].

    Without poor_mixing the zone state is absent (n = 2). body_to_outdoor adds K_o between
    T_veh and T_o; poor_mixing splits the air into a mixed part (1 - f) C and a zone f C coupled
    by K_zone, the zone losing a share g of kA.
    """
    tr = spec["truth"]
    kA, C, K, Cv = tr["kA"], tr["C"], tr["K_veh"], tr["C_veh"]
    A, B = second_order(kA, C, K, Cv)
    bo = _deviation(spec, "body_to_outdoor")
    if bo:
        A[1, 1] -= bo["K_o"] / Cv
        B[1, 0] += bo["K_o"] / Cv
    pm = _deviation(spec, "poor_mixing")
    if pm:
        f, g, Kz = pm["zone_fraction"], pm["zone_loss_fraction"], pm["K_zone"]
        Cm, Cz = (1 - f) * C, f * C
        A = np.array(
            [
                [-((1 - g) * kA + K + Kz) / Cm, K / Cm, Kz / Cm],
                [K / Cv, A[1, 1], 0.0],
                [Kz / Cz, 0.0, -(g * kA + Kz) / Cz],
            ]
        )
        B = np.array([[(1 - g) * kA / Cm, 1 / Cm], [B[1, 0], 0.0], [g * kA / Cz, 0.0]])
    return A, B


def _schedules(spec: dict, n_steps: int, dt: float):
    """Per fine step: mode (0 fixed, 1 HVAC pre-heating, 2 thermostat), fixed heater power,
    fan power, unlogged auxiliary power, tunnel setpoint."""
    p = spec["programme"]
    ph = p["phases_s"]
    t = np.arange(n_steps) * dt
    mode = np.zeros(n_steps, dtype=np.int8)
    q_fix = np.zeros(n_steps)
    fan_on = np.zeros(n_steps, dtype=bool)
    inst = spec["_inst"]
    groups = spec["heaters"]["power_W"] * inst["group_factor"][: spec["heaters"]["groups"]]
    if p["type"] == "existing":
        mode[(t >= ph["preheat"]) & (t < ph["kvalue"])] = 1
        mode[(t >= ph["kvalue"]) & (t < ph["cooldown"])] = 2
        fan_on[t >= ph["kvalue"]] = True
    else:
        base = groups[: p["base_groups"]].sum()
        up = groups[: p["base_groups"] + p["step_groups"]].sum()
        q_fix[:] = base
        q_fix[(t >= ph["step_up"]) & (t < ph["step_down"])] = up
        fan_on[:] = True
    fans = spec["fans"]["power_W"] * inst["fan_factor"][: spec["fans"]["n"]]
    q_fan = np.where(fan_on, fans.sum(), 0.0)
    q_aux = np.zeros(n_steps)
    ua = _deviation(spec, "unlogged_aux")
    if ua:
        for a, b in ua["on_h"]:
            q_aux[(t >= a * 3600) & (t < b * 3600)] += ua["power_W"]
    return mode, q_fix, q_fan, q_aux, groups, fans


def _tunnel(spec: dict, n: int, dt: float, rng) -> np.ndarray:
    """Tunnel air T_o per fine step: the tunnel controller's first-order lag to the setpoint
    plus an AR(1) fluctuation (the control loop's residual), starting settled."""
    tu = spec["tunnel"]
    sp = np.full(n, float(spec["programme"]["T_tunnel"]))
    a = math.exp(-dt / tu["lag_s"])
    lag, _ = lfilter([1 - a], [1, -a], sp, zi=[a * sp[0]])
    phi = math.exp(-dt / tu["correlation_s"])
    w = rng.normal(0, tu["fluctuation_sd_K"] * math.sqrt(1 - phi**2), n)
    w[0] = rng.normal(0, tu["fluctuation_sd_K"])
    ar = lfilter([1.0], [1, -phi], w)
    return lag + ar


def _run(spec: dict) -> dict:
    """Simulate on the fine grid; returns fine-step arrays (states at n dt, inputs over [n dt,
    (n+1) dt))."""
    dt = float(spec["fine_step_s"])
    t_end = spec["programme"]["phases_s"]["end"]
    N = int(round(t_end / dt))
    r_inst, r_tun, _, _ = _rngs(spec)
    spec = dict(spec, _inst=_instruments(spec, r_inst))
    A, B = _system(spec)
    ns = A.shape[0]
    Ad, Bd = discretize_zoh(A, B, dt)
    Ad3, Bd3 = np.zeros((3, 3)), np.zeros((3, 2))
    Ad3[:ns, :ns], Bd3[:ns] = Ad, Bd
    To = _tunnel(spec, N + 1, dt, r_tun)
    mode, q_fix, q_fan, q_aux, groups, _ = _schedules(spec, N + 1, dt)
    tr, p = spec["truth"], spec["programme"]
    tdk = _deviation(spec, "temperature_dependent_k")
    beta = tdk["beta_per_K"] if tdk else 0.0
    dT_ref = (p.get("T_setpoint", 0.0) - p["T_tunnel"]) if tdk else 0.0
    kA = tr["kA"]

    def q_nl(T, to):  # extra loss of k = k0 (1 + beta (T - T_o - dT_ref))
        return -kA * beta * (T - to - dT_ref) * (T - to)

    # initial state: steady at the initial inputs (fixed point for the non-linear loss)
    q0 = q_fix[0] + q_fan[0] + q_aux[0]
    x = np.linalg.solve(A, -B @ np.array([To[0], q0]))
    for _ in range(50 if beta else 0):
        x = np.linalg.solve(A, -B @ np.array([To[0], q0 + q_nl(x[0], To[0])]))
    us = _deviation(spec, "unsteady_start")
    if us:
        x[0] += us["dT_air_K"]
        x[1] += us["dT_body_K"]
        if ns == 3:
            x[2] += us["dT_air_K"]
    x0, x1, x2 = (float(v) for v in (*x, 0.0, 0.0)[:3])
    (a00, a01, a02), (a10, a11, a12), (a20, a21, a22) = Ad3.tolist()
    (b00, b01), (b10, b11), (b20, b21) = Bd3.tolist()
    cum = np.concatenate([[0.0], np.cumsum(groups)]).tolist()
    G = len(groups)
    he = spec["heaters"]
    Tset = p.get("T_setpoint", 0.0)
    lo, hi = Tset - he.get("hysteresis_K", 0.3), Tset + he.get("hysteresis_K", 0.3)
    dwell = he.get("dwell_s", 120.0)
    hv = spec["hvac"]
    hv_max, band, Tpre = hv.get("power_max_W", 0.0), hv.get("band_K", 2.0), p.get("T_preheat", 0)
    To_l, mode_l = To.tolist(), mode.tolist()
    qfix_l = q_fix.tolist()
    qext_l = (q_fan + q_aux).tolist()
    X0, X1, X2 = [x0] * (N + 1), [x1] * (N + 1), [x2] * (N + 1)
    QH, QV = [0.0] * (N + 1), [0.0] * (N + 1)
    n_on, since = 0, dwell
    for n in range(N):
        m = mode_l[n]
        if m == 2:  # staged thermostat: one group more/less per dwell time outside the band
            if since >= dwell:
                if x0 < lo and n_on < G:
                    n_on += 1
                    since = 0.0
                elif x0 > hi and n_on > 0:
                    n_on -= 1
                    since = 0.0
            since += dt
            qh, qv = cum[n_on], 0.0
        elif m == 1:  # HVAC pre-heating, proportional control towards T_preheat
            qv = hv_max * (Tpre - x0) / band
            qv = hv_max if qv > hv_max else (0.0 if qv < 0.0 else qv)
            qh = 0.0
        else:
            qh, qv = qfix_l[n], 0.0
        to = To_l[n]
        q = qh + qv + qext_l[n]
        if beta:
            q += q_nl(x0, to)
        x0, x1, x2 = (
            a00 * x0 + a01 * x1 + a02 * x2 + b00 * to + b01 * q,
            a10 * x0 + a11 * x1 + a12 * x2 + b10 * to + b11 * q,
            a20 * x0 + a21 * x1 + a22 * x2 + b20 * to + b21 * q,
        )
        X0[n + 1], X1[n + 1], X2[n + 1] = x0, x1, x2
        QH[n], QV[n] = qh, qv
    # inputs after the end (never used in the balance) repeat the last step
    QH[N], QV[N] = QH[N - 1], QV[N - 1]
    return {
        "spec": spec,
        "N": N,
        "dt": dt,
        "T": np.array(X0),
        "T_veh": np.array(X1),
        "T_zone": np.array(X2) if ns == 3 else None,
        "T_o": To,
        "Q_heat": np.array(QH),
        "Q_hvac": np.array(QV),
        "Q_fan": q_fan,
        "Q_aux": q_aux,
        "groups": groups,
    }


def _interval_mean(q: np.ndarray, m: int, n_samples: int) -> np.ndarray:
    """Mean over the logging interval [t - step, t) for each sample; before t = 0 the input is
    the initial one (the record starts in a held state)."""
    qp = np.concatenate([np.full(m, q[0]), q[: (n_samples - 1) * m]])
    return qp.reshape(n_samples, m).mean(axis=1)


_CACHE: dict[str, Any] = {}


def _run_cached(spec: dict) -> dict:
    key = json.dumps(spec, sort_keys=True)
    if key not in _CACHE:
        _CACHE.clear()
        _CACHE[key] = _run(spec)
    return _CACHE[key]


def simulate(spec: dict, ideal: bool = False) -> pd.DataFrame:
    """Simulate one vehicle on its logger grid.

    ideal=True: the TRUE states and inputs, no instruments: time_s, T, T_veh, T_o (at the sample
    time), Q_H (heaters + HVAC + fans, eq. 3, mean over the preceding interval), Q_aux (unlogged
    auxiliaries), n_groups_on-equivalent heater power Q_heaters, Q_hvac (true), and T_zone when
    ``poor_mixing`` is declared.
    ideal=False: the full logged record (all files' rows, before splitting into files) with the
    raw column names, numeric values in the logged units, NaN for empty cells, dropped rows
    removed; the time column holds seconds (float) or numpy datetimes.
    """
    r = _run_cached(spec)
    step = spec["logger"]["step_s"]
    m = int(round(step / r["dt"]))
    K = r["N"] // m + 1
    idx = np.arange(K) * m
    t_s = idx * r["dt"]
    heat = r["Q_heat"] + r["Q_hvac"]
    if ideal:
        out = pd.DataFrame(
            {
                "time_s": t_s,
                "T": r["T"][idx],
                "T_veh": r["T_veh"][idx],
                "T_o": r["T_o"][idx],
                "Q_H": _interval_mean(heat + r["Q_fan"], m, K),
                "Q_heaters": _interval_mean(r["Q_heat"], m, K),
                "Q_hvac": _interval_mean(r["Q_hvac"], m, K),
                "Q_aux": _interval_mean(r["Q_aux"], m, K),
            }
        )
        if r["T_zone"] is not None:
            out["T_zone"] = r["T_zone"][idx]
        return out
    return _logged(spec, r, idx, t_s, m, K)


def _logged(spec, r, idx, t_s, m, K) -> pd.DataFrame:
    _, _, rng, rng_drop = _rngs(spec)
    inst = r["spec"]["_inst"]
    lg, se = spec["logger"], spec["sensors"]
    dt = r["dt"]
    heat = r["Q_heat"] + r["Q_hvac"]
    # heat-driven stratification and plume respond within response_s (first-order lag)
    a = math.exp(-dt / se.get("response_s", 120.0))
    q_f, _ = lfilter([1 - a], [1, -a], heat, zi=[a * heat[0]])
    qf_kw = q_f[idx] / 1000.0
    T, Tv, To = r["T"][idx], r["T_veh"][idx], r["T_o"][idx]
    Tz = r["T_zone"][idx] if r["T_zone"] is not None else T
    pm = _deviation(spec, "poor_mixing") or {}
    zone, plume = set(pm.get("zone_sensors", [])), set(pm.get("plume_sensors", []))
    h_ref, s_str = se.get("reference_height_m", 1.1), se.get("stratification_K_per_m_kW", 0.0)
    kelvin = 273.15 if lg["temperature_unit"] == "K" else 0.0
    pn = spec["power_meter"]["noise_rel"]
    hv = spec["hvac"]
    data: dict[str, np.ndarray] = {}
    for name, kind, i in columns(spec):
        if kind == "time":
            continue
        if kind == "indoor":
            h = se["indoor"]["heights_m"][i - 1]
            v = (Tz if i in zone else T) + inst["indoor_offset"][i - 1]
            v = v + s_str * (h - h_ref) * qf_kw
            if i in plume:
                v = v + pm["plume_K_per_kW"] * qf_kw
            v = v + rng.normal(0, se["indoor"]["noise_K"], K) + kelvin
        elif kind == "surface":
            v = Tv + inst["surface_offset"][i - 1]
            v = v + rng.normal(0, se["surface"]["noise_K"], K) + kelvin
        elif kind == "outdoor":
            v = To + inst["outdoor_offset"][i - 1]
            v = v + rng.normal(0, se["outdoor"]["noise_K"], K) + kelvin
        elif kind == "hvac":  # from the air flow: biased and noisier (section 3.3)
            q = _interval_mean(r["Q_hvac"], m, K) * inst["hvac_bias"]
            v = q * (1 + rng.normal(0, hv.get("airflow_noise_rel", 0.04), K))
        elif kind in ("heater", "heater_total"):
            if kind == "heater":  # the staged thermostat switches groups 1..n in order
                g = r["groups"][i - 1]
                on = np.clip(
                    r["Q_heat"] - np.concatenate([[0], np.cumsum(r["groups"])])[i - 1], 0, g
                )
                q = _interval_mean(on, m, K)
            else:
                q = _interval_mean(r["Q_heat"], m, K)
            v = q * (1 + rng.normal(0, pn, K))
        elif kind in ("fan", "fan_total"):
            q = _interval_mean(r["Q_fan"], m, K)
            if kind == "fan":
                q = q * inst["fan_factor"][i - 1] / inst["fan_factor"][: spec["fans"]["n"]].sum()
            v = q * (1 + rng.normal(0, pn, K))
        elif kind == "humidity":
            v = np.clip(40.0 - 0.8 * (T - To) + rng.normal(0, 1.0, K), 5, 95)
        else:  # wind
            v = np.abs(1.5 + rng.normal(0, 0.2, K))
        if (
            kind in ("hvac",)
            and lg["hvac_unit"] == "kW"
            or (kind in ("heater", "heater_total", "fan", "fan_total") and lg["power_unit"] == "kW")
        ):
            v = v / 1000.0
        data[name] = np.asarray(v, dtype=float)
    df = pd.DataFrame(data)
    # Short dropouts: a few missing rows and a few empty cells, each an isolated single sample
    # (never next to another gap of the same channel, never a file's first/last row), so no
    # channel ever misses more than one logger step.
    cols = list(df.columns)
    dr = spec["dropouts"]
    keep_ends = {0, K - 1}
    step = spec["logger"]["step_s"]
    for f in spec["files"]:
        keep_ends |= {int(f["t0"] // step), int(f["t1"] // step)}
    drop: set[int] = set()
    while len(drop) < dr["missing_rows"]:
        j = int(rng_drop.integers(1, K - 1))
        if j not in keep_ends and not drop & {j - 1, j, j + 1}:
            drop.add(j)
    empty: set[tuple[int, int]] = set()
    while len(empty) < dr["empty_cells"]:
        j, c = int(rng_drop.integers(1, K - 1)), int(rng_drop.integers(0, len(cols)))
        if not drop & {j - 1, j, j + 1} and not empty & {(j - 1, c), (j, c), (j + 1, c)}:
            empty.add((j, c))
            df.iat[j, c] = np.nan
    df.insert(0, lg["time_column"], _time_values(spec, t_s))
    df.insert(0, "_t_s", t_s)
    return df.drop(index=sorted(drop)).reset_index(drop=True)


def _fmt(values: np.ndarray, decimals: int, dec: str) -> list[str]:
    f = f"{{:.{decimals}f}}"
    out = ["" if v != v else f.format(v) for v in values.tolist()]
    if dec == ",":
        out = [s.replace(".", ",") for s in out]
    return out


def write_raw_file(spec: dict, name: str, out_path) -> None:
    """Simulate the vehicle and write the raw file ``name`` (one header row, no comments;
    byte-deterministic, gzip with mtime=0 for ``.gz``)."""
    files = {f["name"]: f for f in spec["files"]}
    if name not in files:
        raise ConfigError(spec["id"], "name", name, f"not one of {sorted(files)}")
    f = files[name]
    df = simulate(spec)
    df = df[(df["_t_s"] >= f["t0"]) & (df["_t_s"] <= f["t1"])]
    lg = spec["logger"]
    dec, sep = lg.get("decimal", "."), lg["separator"]
    cols_out = []
    for col, kind, _ in columns(spec):
        v = df[col].to_numpy()
        if kind == "time":
            if lg["time_format"] == "iso":
                s = list(np.datetime_as_string(v.astype("datetime64[s]"), unit="s"))
            else:
                s = [str(int(x)) for x in v]
        elif kind in ("indoor", "surface", "outdoor"):
            s = _fmt(v, lg.get("temperature_decimals", 2), dec)
        elif kind in ("humidity", "wind"):
            s = _fmt(v, 1, dec)
        else:
            unit = lg["hvac_unit"] if kind == "hvac" else lg["power_unit"]
            s = _fmt(v, 4 if unit == "kW" else 1, dec)
        cols_out.append(s)
    header = sep.join(c for c, _, _ in columns(spec))
    text = header + "\n" + "".join(sep.join(row) + "\n" for row in zip(*cols_out, strict=True))
    raw = text.encode("utf-8")
    out_path = Path(out_path)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    if name.endswith(".gz"):
        buf = io.BytesIO()
        with gzip.GzipFile(filename="", mode="wb", fileobj=buf, mtime=0, compresslevel=6) as gz:
            gz.write(raw)
        raw = buf.getvalue()
    out_path.write_bytes(raw)


# --------------------------------------------------------------------------------------------
# Vehicle-config helpers (the shipped config/vehicles/*.yaml must agree with these)
# --------------------------------------------------------------------------------------------
def _stamp(spec: dict, t_s: float):
    if spec["logger"]["time_format"] == "seconds":
        return int(t_s) if float(t_s).is_integer() else float(t_s)
    return str(np.datetime_as_string(np.datetime64(spec["start"], "s") + int(t_s), unit="s"))


def windows(spec: dict) -> dict:
    """The vehicle-config ``windows`` for the programme (times in the file's time format).

    existing: kvalue = the last ``kvalue_window_h`` (>= 8 h) of the k-test hold; one
    identification window ``sequence`` from the start of the k-test hold to the end of the
    cool-down. The pre-heating is left out: its heat is only known from the air flow (biased and
    noisy, paper section 3.3), and a test engineer would not identify on it.
    special: kvalue = the last ``kvalue_window_h`` of the steady start; ``step_up``
    from 1 h before the step to the reversal (file step_up) and ``step_down`` over the second
    file.
    """
    p, ph = spec["programme"], spec["programme"]["phases_s"]
    w = p["kvalue_window_h"] * 3600.0
    if p["type"] == "existing":
        return {
            "kvalue": {
                "start": _stamp(spec, ph["cooldown"] - w),
                "end": _stamp(spec, ph["cooldown"]),
            },
            "identification": [
                {
                    "name": "sequence",
                    "start": _stamp(spec, ph["kvalue"]),
                    "end": _stamp(spec, spec["files"][0]["t1"]),
                }
            ],
        }
    f_up, f_down = spec["files"]
    return {
        "kvalue": {
            "file": "step_up",
            "start": _stamp(spec, ph["step_up"] - w),
            "end": _stamp(spec, ph["step_up"]),
        },
        "identification": [
            {
                "name": "step_up",
                "file": "step_up",
                "start": _stamp(spec, max(0.0, ph["step_up"] - 3600.0)),
                "end": _stamp(spec, f_up["t1"]),
            },
            {
                "name": "step_down",
                "file": "step_down",
                "start": _stamp(spec, f_down["t0"]),
                "end": _stamp(spec, f_down["t1"]),
            },
        ],
    }


def vehicle_config(campaign: dict, vehicle_id: str, raw_dir: str = "../../resources/campaign"):
    """The vehicle-config content (schema keys) matching what the campaign writes for a vehicle;
    raw file paths are ``{raw_dir}/{id}/{name}`` (relative to the vehicle YAML's directory)."""
    spec = vehicle_spec(campaign, vehicle_id)
    m = campaign["_merged"][vehicle_id]
    lg = spec["logger"]
    cols = columns(spec)
    tunit = lg["temperature_unit"]
    weights = m["sensors"]["indoor"].get("weights")

    def temp(kind):
        out = []
        for c, k, i in cols:
            if k == kind:
                d = {"column": c}
                if kind == "indoor" and weights is not None:
                    d["weight"] = weights[i - 1]
                if tunit != "degC":
                    d["unit"] = tunit
                out.append(d)
        return out

    heater = [
        {"column": c, "unit": lg["hvac_unit"] if k == "hvac" else lg["power_unit"]}
        for c, k, _ in cols
        if k in ("hvac", "heater", "heater_total")
    ]
    fan = [{"column": c, "unit": lg["power_unit"]} for c, k, _ in cols if k in ("fan", "fan_total")]
    channels = {"indoor_air": temp("indoor"), "surface": temp("surface")}
    channels["outdoor_air"] = temp("outdoor")
    channels["heater_power"] = heater
    if fan:
        channels["fan_power"] = fan
    return {
        "id": vehicle_id,
        "class": spec["class"],
        "synthetic": True,
        "mass_kg": m["truth"]["mass_kg"]["value"],
        "surface_m2": m["truth"]["surface_m2"]["value"],
        "volume_m3": m["truth"]["volume_m3"]["value"],
        "raw_files": {f["key"]: f"{raw_dir}/{vehicle_id}/{f['name']}" for f in spec["files"]},
        "format": {
            "separator": lg["separator"],
            "decimal": lg.get("decimal", "."),
            # the logger's power meters report the mean over the interval ending at each stamp
            "power_timing": "mean_preceding",
            "time": {"column": lg["time_column"], "format": lg["time_format"]},
        },
        "channels": channels,
        # the campaign's sensors, as a lab declares its calibration: one sensor's offset sd
        "instruments": {
            f"{group}_temperature_u_K": float(m["sensors"][group]["offset_sd_K"])
            for group in ("indoor", "surface", "outdoor")
        },
        "windows": windows(spec),
    }


# --------------------------------------------------------------------------------------------
# Ground truth
# --------------------------------------------------------------------------------------------
def ground_truth_table(campaign: dict) -> pd.DataFrame:
    """One row per vehicle (campaign order): the declared truth in SI units, the derived c_veh
    (eq. 24) and delta (eq. 25), time constants of eq. 14, programme and logger step, and the
    declared deviations (";"-joined types, "" if none) with what each does to the static k
    test (``k_effects``, "type: effect" joined by " | ", "" if none does anything)."""
    rows = []
    for vid in campaign["_merged"]:
        spec = vehicle_spec(campaign, vid)
        tr = spec["truth"]
        tf, ts = time_constants(spec)
        inst = _instruments(spec, _rngs(spec)[0])
        devs = spec["deviations"]
        rows.append(
            {
                "vehicle": vid,
                "class": spec["class"],
                "k": tr["k"],
                "A": tr["A"],
                "kA": tr["kA"],
                "C": tr["C"],
                "K_veh": tr["K_veh"],
                "C_veh": tr["C_veh"],
                "mass_kg": tr["mass_kg"],
                "volume_m3": tr["volume_m3"],
                "c_veh": tr["C_veh"] / tr["mass_kg"],
                "delta": tr["C_veh"] / tr["C"],
                "tau_fast_s": tf,
                "tau_slow_s": ts,
                "programme": spec["programme"]["type"],
                "step_s": spec["logger"]["step_s"],
                "duration_s": spec["programme"]["phases_s"]["end"],
                "hvac_airflow_bias": inst["hvac_bias"]
                if spec["programme"]["type"] == "existing"
                else 1.0,
                "deviations": ";".join(d["type"] for d in devs),
                "k_effects": " | ".join(
                    f"{d['type']}: {DEVIATION_EFFECT_ON_K[d['type']]}"
                    for d in devs
                    if DEVIATION_EFFECT_ON_K[d["type"]]
                ),
                "synthetic": True,
            }
        )
    return pd.DataFrame(rows)


def ground_truth_sources(campaign: dict) -> pd.DataFrame:
    """Every truth value with its unit and source (vehicle, quantity, value, unit, source)."""
    rows = []
    for vid, m in campaign["_merged"].items():
        for q in TRUTH_UNITS:
            e = m["truth"][q]
            rows.append(
                {
                    "vehicle": vid,
                    "quantity": q,
                    "value": float(e["value"]),
                    "unit": e["unit"],
                    "source": e["source"],
                }
            )
    return pd.DataFrame(rows)
