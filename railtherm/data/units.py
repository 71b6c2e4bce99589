"""Units of the measured channels: the conversion of a raw column to SI (degC, W, W/m2) and the
unit a column's name states.

A channel's value is ``scale * raw + offset`` in the channel's declared ``unit`` (scale 1 and
offset 0 unless declared: a logger writing mV, a sensor's calibration line), then converted::

    degC: T            K: T - 273.15            degF: (T - 32) * 5 / 9
    W: P               kW: 1000 P
    W/m2: I            kW/m2: 1000 I

A column name that states a unit (``T_int [°F]``, ``P_hea_kW``, ``Strahlung (W/m²)``) is
read by :func:`stated_unit`; a declared unit that contradicts it is a configuration error
(:mod:`railtherm.config`), unless the channel declares its own ``scale`` or ``offset``.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import Any

import numpy as np

__all__ = ["TEMPERATURE_UNITS", "POWER_UNITS", "IRRADIANCE_UNITS", "stated_unit", "to_si"]

KELVIN = 273.15
# SI value = factor * value + shift, per declared unit
TEMPERATURE_UNITS = {"degC": (1.0, 0.0), "K": (1.0, -KELVIN), "degF": (5.0 / 9.0, -32.0 * 5 / 9)}
POWER_UNITS = {"W": (1.0, 0.0), "kW": (1000.0, 0.0)}
IRRADIANCE_UNITS = {"W/m2": (1.0, 0.0), "kW/m2": (1000.0, 0.0)}
_ALL = {**TEMPERATURE_UNITS, **POWER_UNITS, **IRRADIANCE_UNITS}
WORDS = {"degC": "°C", "K": "K", "degF": "°F", "W": "W", "kW": "kW"}

_B = r"(?<![A-Za-z])"  # not inside a word
_A = r"(?![A-Za-z])"
_STATED = {
    "temperature": (
        ("degF", re.compile(rf"°\s*F{_A}|{_B}deg\s*F{_A}|fahrenheit|[\[(]\s*F\s*[\])]", re.I)),
        ("degC", re.compile(rf"°\s*C{_A}|{_B}deg\s*C{_A}|celsius|[\[(]\s*C\s*[\])]", re.I)),
        ("K", re.compile(r"kelvin|\[\s*K\s*\]|\(\s*K\s*\)", re.I)),
    ),
    "power": (
        ("kW", re.compile(rf"{_B}kW{_A}(?!\s*/\s*m)", re.I)),
        ("W", re.compile(r"\[\s*W\s*\]|\(\s*W\s*\)|(?<![A-Za-z])W$")),
    ),
    "irradiance": (
        ("kW/m2", re.compile(r"kW\s*/\s*m", re.I)),
        ("W/m2", re.compile(r"(?<![kK])W\s*/\s*m")),
    ),
}


def stated_unit(column: str, kind: str) -> str | None:
    """The unit that the column name ``column`` states for a ``kind`` ("temperature", "power"
    or "irradiance") channel, or None when it states none (or two that disagree)."""
    found = {unit for unit, pattern in _STATED[kind] if pattern.search(str(column))}
    return found.pop() if len(found) == 1 else None


def to_si(values: np.ndarray, channel: Mapping[str, Any], default_unit: str) -> np.ndarray:
    """The channel's values in SI units (degC, W or W/m2): ``scale * raw + offset`` in its
    declared unit, converted (module docstring)."""
    unit = str(channel.get("unit", default_unit))
    factor, shift = _ALL[unit]
    scale, offset = float(channel.get("scale", 1.0)), float(channel.get("offset", 0.0))
    if scale != 1.0 or offset != 0.0:
        values = values * scale + offset
    if factor != 1.0:
        values = values * factor
    if shift != 0.0:
        values = values + shift
    return values
