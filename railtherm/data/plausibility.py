"""Plausibility of a record's numbers against a unit mistake that leaves every fit measure
perfect.

A temperature channel's unit is an affine map (:mod:`railtherm.data.units`): the same raw
numbers read in the wrong unit still make a smooth record that a model fits perfectly, only
shifted and scaled. 20 degC declared degF becomes (20 - 32) 5/9 = -6.7 degC, -15 degC becomes
-26.1 degC: every difference T - T_o shrinks by 5/9, so kA of eq. 10 comes out 9/5 = 1.8 times
the truth. Read the other way, 68 degF declared degC is a cabin at 68 degC and a difference
1.8 times too large. What such a record cannot hide is its level and its sign:

- **a heated cabin colder than the tunnel**: with heat going in (mean Q_H > 0) over a steady
  window, eq. 10 (0 = Q_H - kA (T - T_o)) needs T > T_o; mean T below mean T_o is no k value
  but a channel in the wrong unit (indoor air declared degF, tunnel degC) or two swapped
  channels;
- **a heated cabin at a temperature no k-value test holds**: the static test holds the cabin
  at a comfort temperature, ``check.heated_air_range_degC`` (default 5-45 degC); a heated
  cabin at -6.7 degC is 20 degC declared degF, one at 68 degC is 68 degF declared degC;
- **an implied k far from its class** (eq. 5, k = kA / A): the paper's Table 2 gives each rail
  class's k (:data:`CLASS_K_W_M2K`); a k more than ``check.k_class_factor`` (default 2)
  beyond that range is a unit mistake (or the wrong ``surface_m2``), not a vehicle of the
  class.

The k window (:func:`check_k_window`) is checked where its static k is computed - by
``railtherm validate`` and rule ``kvalue`` alike - and refused with a
:class:`~railtherm.errors.DataError`; the identification records (:func:`record_reasons`) and
a fitted k (:func:`k_class_reason`) are judged in the fit's verdict. Each message names the raw
file, the columns, their declared unit and what the same numbers read in another unit give.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from railtherm.data import units
from railtherm.errors import DataError

__all__ = [
    "CLASS_K_W_M2K",
    "HEATED_AIR_RANGE_DEGC",
    "K_CLASS_FACTOR",
    "check_k_window",
    "class_k_range",
    "declared",
    "k_class_reason",
    "record_reasons",
]

#: Each rail class's k = kA / A (W/(m^2 K)), the lowest and highest of its vehicles in the
#: paper's Table 2 (published; config/published/paper.yaml holds the table as printed).
CLASS_K_W_M2K: dict[str, tuple[float, float]] = {
    "tram": (2.5, 3.2),
    "metro": (2.4, 3.1),
    "regional": (1.3, 2.0),
    "main-line": (1.4, 1.6),
}
#: Defaults of ``check.heated_air_range_degC`` and ``check.k_class_factor`` (vehicle schema).
HEATED_AIR_RANGE_DEGC = (5.0, 45.0)
K_CLASS_FACTOR = 2.0


def _check(vehicle_data: Mapping[str, Any], key: str, default: Any) -> Any:
    return (vehicle_data.get("check") or {}).get(key, default)


def _channels(vehicle_data: Mapping[str, Any], group: str) -> list[Mapping[str, Any]]:
    return list((vehicle_data.get("channels") or {}).get(group) or [])


def declared(vehicle_data: Mapping[str, Any], group: str) -> str:
    """The channels of ``group`` and their declared units, as a message shows them:
    ``channels.indoor_air 'air.T.1', 'air.T.2' declared degF``."""
    channels = _channels(vehicle_data, group)
    default = "degC" if group in ("indoor_air", "surface", "outdoor_air") else "W"
    by_unit: dict[str, list[str]] = {}
    for c in channels:
        by_unit.setdefault(str(c.get("unit", default)), []).append(repr(str(c["column"])))
    parts = [f"{', '.join(cols)} declared {unit}" for unit, cols in by_unit.items()]
    return f"channels.{group} " + "; ".join(parts) if parts else f"channels.{group} (none)"


def _unit(vehicle_data: Mapping[str, Any], group: str) -> str:
    """The declared unit of a temperature group (its first channel's)."""
    channels = _channels(vehicle_data, group)
    return str(channels[0].get("unit", "degC")) if channels else "degC"


def _read_as(value_degC: float, unit: str) -> str:
    """What the raw numbers behind ``value_degC`` (read in ``unit``) give read in each other
    temperature unit: "the same numbers read as degC give 20 degC"."""
    factor, shift = units.TEMPERATURE_UNITS[unit]
    raw = (value_degC - shift) / factor
    others = []
    for other, (f, s) in units.TEMPERATURE_UNITS.items():
        if other != unit:
            v = f * raw + s
            if -80.0 <= v <= 120.0:
                others.append(f"read as {other} give {v:.1f} degC")
    return "the same numbers " + " and ".join(others) if others else ""


def _fix(vehicle_data: Mapping[str, Any], group: str, value: float) -> str:
    alternative = _read_as(value, _unit(vehicle_data, group))
    return "check the unit" + (f" ({alternative})" if alternative else "")


def _columns(vehicle_data: Mapping[str, Any], group: str) -> str:
    return ", ".join(str(c["column"]) for c in _channels(vehicle_data, group)) or group


def check_k_window(window: pd.DataFrame, vehicle_data: Mapping[str, Any], source: str) -> None:
    """Refuse a k window (tidy table: ``T``, ``T_o``, ``Q_H``) whose heated cabin is colder
    than the tunnel or outside ``check.heated_air_range_degC``: a
    :class:`~railtherm.errors.DataError` naming ``source`` (the raw file and window), the
    indoor-air columns, their declared unit and the check of the unit (module docstring).
    A window without heat going in, or without those columns, is left to eq. 10's own
    check."""
    if not {"T", "T_o", "Q_H"} <= set(window.columns):
        return
    T = window["T"].to_numpy(float)
    T_o = window["T_o"].to_numpy(float)
    Q_H = window["Q_H"].to_numpy(float)
    if not (np.isfinite(T).all() and np.isfinite(T_o).all() and np.isfinite(Q_H).all()):
        return  # eq. 10 names the column that is not finite
    T_mean, T_o_mean, Q_mean = float(T.mean()), float(T_o.mean()), float(Q_H.mean())
    if not Q_mean > 0:
        return
    indoor = _columns(vehicle_data, "indoor_air")
    if T_mean < T_o_mean:
        raise DataError(
            source,
            indoor,
            round(T_mean, 2),
            f"the heated cabin (mean Q_H {Q_mean:.4g} W) is colder than the tunnel over the k "
            f"window: mean T - T_o = {T_mean - T_o_mean:.2f} K, which must be > 0 for eq. 10 "
            "(heat does not flow from a cold cabin into a warm tunnel); mean T "
            f"{T_mean:.2f} degC ({declared(vehicle_data, 'indoor_air')}), mean T_o "
            f"{T_o_mean:.2f} degC ({declared(vehicle_data, 'outdoor_air')}): "
            f"{_fix(vehicle_data, 'indoor_air', T_mean)}; the outdoor air's: "
            f"{_fix(vehicle_data, 'outdoor_air', T_o_mean)}; or are channels.indoor_air and "
            "outdoor_air swapped?",
        )
    lo, hi = (
        float(x) for x in _check(vehicle_data, "heated_air_range_degC", HEATED_AIR_RANGE_DEGC)
    )
    if not lo <= T_mean <= hi:
        raise DataError(
            source,
            indoor,
            round(T_mean, 2),
            f"the heated cabin's mean air temperature over the k window is {T_mean:.2f} degC "
            f"({declared(vehicle_data, 'indoor_air')}), outside {lo:g}-{hi:g} degC, where a "
            "k-value test holds a heated cabin (check.heated_air_range_degC): "
            f"{_fix(vehicle_data, 'indoor_air', T_mean)}; widen "
            "check.heated_air_range_degC only if the test really held the cabin there",
        )


def class_k_range(vehicle_data: Mapping[str, Any]) -> tuple[float, float, float] | None:
    """(low, high, factor): the vehicle class's k range (:data:`CLASS_K_W_M2K`) and
    ``check.k_class_factor``; None for class other (a test cell, a building: no class)."""
    k_range = CLASS_K_W_M2K.get(str(vehicle_data.get("class")))
    if k_range is None:
        return None
    factor = float(_check(vehicle_data, "k_class_factor", K_CLASS_FACTOR))
    return k_range[0], k_range[1], factor


def k_class_reason(k: float | None, vehicle_data: Mapping[str, Any], what: str) -> str | None:
    """A sentence when ``k`` (W/(m^2 K); ``what`` says where it comes from) lies more than
    ``check.k_class_factor`` beyond the class's k range of Table 2, naming the raw files, the
    temperature and power channels with their declared units and the check of the unit; None
    when it does not, or there is no k or no class."""
    found = class_k_range(vehicle_data)
    if k is None or found is None or not math.isfinite(k):
        return None
    lo, hi, factor = found
    if lo / factor <= k <= hi * factor:
        return None
    files = ", ".join(str(f) for f in (vehicle_data.get("raw_files") or {}).values())
    temperatures = "; ".join(declared(vehicle_data, g) for g in ("indoor_air", "outdoor_air"))
    powers = "; ".join(declared(vehicle_data, g) for g in ("heater_power", "fan_power"))
    ratio = k / hi if k > hi else lo / k
    return (
        f"{what} k = {k:.3g} W/(m² K) is {ratio:.2g} times beyond the {vehicle_data['class']} "
        f"class's {lo:g}-{hi:g} W/(m² K) (the paper's Table 2; more than a factor {factor:g}, "
        f"check.k_class_factor): check the unit of the channels in {files} ({temperatures}; "
        f"{powers}; degC data declared degF give 1.8 times the true k) and surface_m2"
    )


def record_reasons(
    tables: Mapping[str, pd.DataFrame], vehicle_data: Mapping[str, Any]
) -> list[str]:
    """Sentences for the verdict on the identification windows' heated rows (heater power
    ``Q_heater`` > 0, or ``Q_H`` > 0 without it): a heated cabin colder on average than the
    tunnel, or whose air stays outside ``check.heated_air_range_degC`` (its 95th percentile
    below the range, or its 5th above it: never, while heated, at a temperature a heated cabin
    has). Each names the raw file, the columns, their declared unit and the check of the
    unit; [] when nothing is heated."""
    frames = []
    for table in tables.values():
        if not {"T", "T_o", "Q_H"} <= set(table.columns):
            continue
        power = table["Q_heater"] if "Q_heater" in table.columns else table["Q_H"]
        heated = table[power.to_numpy(float) > 0]
        frames.append(heated[["T", "T_o"]])
    rows = pd.concat(frames).dropna() if frames else pd.DataFrame()
    if len(rows) < 3:
        return []
    T, T_o = rows["T"].to_numpy(float), rows["T_o"].to_numpy(float)
    files = ", ".join(str(f) for f in (vehicle_data.get("raw_files") or {}).values())
    indoor = declared(vehicle_data, "indoor_air")
    out = []
    if T.mean() < T_o.mean():
        out.append(
            f"the heated cabin is colder than the tunnel: over the {len(T)} heated rows of "
            f"{files}, mean T {T.mean():.2f} degC ({indoor}) is below mean T_o "
            f"{T_o.mean():.2f} degC ({declared(vehicle_data, 'outdoor_air')}): "
            f"{_fix(vehicle_data, 'indoor_air', float(T.mean()))}; or are the indoor and "
            "outdoor channels swapped?"
        )
    lo, hi = (
        float(x) for x in _check(vehicle_data, "heated_air_range_degC", HEATED_AIR_RANGE_DEGC)
    )
    p5, p95 = (float(x) for x in np.percentile(T, [5.0, 95.0]))
    if p95 < lo or p5 > hi:
        low = p95 < lo
        level, side = (p95, f"below {lo:g}") if low else (p5, f"above {hi:g}")
        out.append(
            f"the heated cabin's air stays {side} degC: over the {len(T)} heated rows of "
            f"{files} its {'95th' if low else '5th'} percentile is {level:.2f} degC ({indoor}), "
            f"outside {lo:g}-{hi:g} degC (check.heated_air_range_degC): "
            f"{_fix(vehicle_data, 'indoor_air', level)}"
        )
    return out
