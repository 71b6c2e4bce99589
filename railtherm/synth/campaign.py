"""The campaign file: declared ground truth, programme and instruments of every vehicle.

:func:`load_campaign` validates the file against ``railtherm/schemas/campaign.schema.yaml`` and
the semantic rules the schema cannot express; :func:`vehicle_spec` resolves one vehicle into a
plain JSON-able dict (truth with A and kA, programme phase times in s, raw files, seed) that the
simulation and the logger work from.
"""

from __future__ import annotations

import copy
import json
import math
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from railtherm.errors import ConfigError
from railtherm.estimation.models import second_order
from railtherm.yamlio import deep_merge, packaged_schema, read_yaml, validate_schema

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
    "power_meter": {"noise_rel": 0.007, "scale_u_rel": 0.0},
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


def _schema_def(name: str) -> dict:
    """The definition ``$defs/<name>`` of the campaign schema, as a schema of its own."""
    root = packaged_schema("campaign")
    return {"$schema": root["$schema"], "$defs": root["$defs"], "$ref": f"#/$defs/{name}"}


def load_campaign(path) -> dict:
    """Parse and validate a campaign file; returns the dict (vehicles in file order).

    Raises ConfigError naming the campaign file, the key path (e.g.
    ``vehicles.Tram1.logger.step_s``) and the value on any bad entry.
    """
    path = Path(path)
    if not path.is_file():
        raise ConfigError(path, "campaign", str(path), "campaign file not found")
    data = read_yaml(path)
    validate_schema(str(path), data, packaged_schema("campaign"))
    defaults = data.get("defaults", {}) or {}
    merged = {}
    base = deep_merge(_BUILTIN, defaults)
    vehicle_schema = _schema_def("vehicle")
    for vid, entry in data["vehicles"].items():
        m = deep_merge(base, entry or {})
        validate_schema(str(path), m, vehicle_schema, prefix=f"vehicles.{vid}")
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
        schema = _schema_def(f"deviation/$defs/{t}")
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
    """The declared deviation of type ``kind`` (its dict), or ``default``."""
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
