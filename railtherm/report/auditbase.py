"""The audit's vocabulary: published values read as printed (:class:`Printed`, the interval
its rounding stands for: :class:`Interval`), their units and dimensions, the published file
and the ranges file (:func:`load_published`, :func:`load_ranges`), and a :class:`Finding`.
The checks are in :mod:`railtherm.report.auditclaims` and :mod:`railtherm.report.auditvalues`,
the run and the report in :mod:`railtherm.report.audit`.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from railtherm.errors import ConfigError
from railtherm.yamlio import packaged_schema, read_yaml, validate_schema

SEVERITIES = ("error", "warning", "info")
FAMILIES = ("consistency", "claims", "plausibility", "fitness", "units", "reproduction")
PAPER_FAMILIES = FAMILIES[:-1]  # findings about the published values; "reproduction" is not
SOURCE_KINDS = ("published", "physics", "definition", "datasheet", "assumption")
COLUMNS = (
    "severity",
    "family",
    "check",
    "subject",
    "location",
    "published",
    "recomputed",
    "message",
)
SYNTHETIC_CAVEAT = (
    "The re-estimates come from the synthetic virtual campaign, whose ground truth was set from "
    "these published values: agreement tests the method (that railtherm recovers what the data "
    "were made from), not the published measurements, which are proprietary."
)

# ---------------------------------------------------------------------------------------------
# Printed numbers and interval arithmetic


@dataclass(frozen=True)
class Interval:
    """A closed interval [lo, hi] of positive or signed reals, with the arithmetic the checks
    need (sums, products and quotients of intervals; quotients of positive intervals only)."""

    lo: float
    hi: float

    def __post_init__(self):
        if not self.lo <= self.hi:
            raise ValueError(f"empty interval [{self.lo}, {self.hi}]")

    @classmethod
    def point(cls, x: float) -> Interval:
        return cls(x, x)

    def __add__(self, other: Interval) -> Interval:
        return Interval(self.lo + other.lo, self.hi + other.hi)

    def __mul__(self, other: Interval) -> Interval:
        p = (self.lo * other.lo, self.lo * other.hi, self.hi * other.lo, self.hi * other.hi)
        return Interval(min(p), max(p))

    def __truediv__(self, other: Interval) -> Interval:
        if other.lo <= 0:
            raise ZeroDivisionError(f"division by an interval containing 0 or less: {other}")
        return self * Interval(1 / other.hi, 1 / other.lo)

    def scale(self, factor: float) -> Interval:
        return Interval(*sorted((self.lo * factor, self.hi * factor)))

    def overlaps(self, other: Interval) -> bool:
        return self.lo <= other.hi and other.lo <= self.hi

    def below(self, other: Interval) -> bool:
        """Every point of self lies below every point of other."""
        return self.hi < other.lo

    def text(self, digits: int = 4) -> str:
        return f"[{fmt_g(self.lo, digits)}, {fmt_g(self.hi, digits)}]"


def mean(intervals: Sequence[Interval]) -> Interval:
    """The interval of the mean of values each known to lie in its interval."""
    total = Interval.point(0.0)
    for i in intervals:
        total = total + i
    return total.scale(1 / len(intervals))


_NUMBER = re.compile(
    r"^\s*(?P<mant>[-+]?(\d{1,3}(,\d{3})+|\d+)(\.(?P<frac>\d+))?)"
    r"\s*(?:(?:×|x|\*)\s*10\s*\^\s*(?P<exp>[-+]?\d+)|[eE](?P<eexp>[-+]?\d+))?\s*$"
)


@dataclass(frozen=True)
class Printed:
    """A number as printed: its text, its value and the interval its rounding stands for
    (half a unit of the last printed digit either side)."""

    text: str
    value: float
    interval: Interval

    @classmethod
    def parse(cls, text: Any, where: str = "") -> Printed:
        """``"2.5"``, ``"47,831"``, ``"3.0×10^7"`` (also ``x10^7``, ``*10^7``, ``e7``).

        Raises :class:`ValueError` naming ``where`` and the text if it is no number."""
        if not isinstance(text, str):
            raise ValueError(f"{where}: {text!r} is not quoted; write it as printed, in quotes")
        m = _NUMBER.match(text)
        if m is None:
            raise ValueError(f"{where}: {text!r} is not a number as printed")
        mant = m.group("mant").replace(",", "")
        exp = int(m.group("exp") or m.group("eexp") or 0)
        decimals = len(m.group("frac") or "")
        value = float(mant) * 10.0**exp
        half = 0.5 * 10.0 ** (exp - decimals)
        return cls(text, value, Interval(value - half, value + half))

    def scaled(self, factor: float, unit: str = "") -> Printed:
        """The same printed number in ``unit``, read in SI: its value ``factor`` times the
        printed one, its text saying both."""
        if factor == 1.0:
            return self
        value = self.value * factor
        text = f"{self.text} {unit} (= {fmt_g(value)} in SI)".replace("  ", " ")
        return Printed(text, value, self.interval.scale(factor))

    @property
    def has_separator(self) -> bool:
        return "," in self.text


def fmt_g(x: float, digits: int = 4) -> str:
    """A number for the arithmetic shown in messages: ``digits`` significant digits, powers
    of ten written ``e7`` (``1.65e7``)."""
    text = f"{x:.{digits}g}"
    if "e" in text:
        mantissa, exponent = text.split("e")
        text = f"{mantissa}e{int(exponent)}"
    return text


# ---------------------------------------------------------------------------------------------
# Units: dimensions over (kg, m, s, K)

_MASS, _LENGTH, _TIME, _TEMPERATURE = (1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1)
_ENERGY, _POWER = (1, 2, -2, 0), (1, 2, -3, 0)
# each symbol the audit reads: its factor to SI and its dimension as exponents of (kg, m, s, K)
_BASE = {
    "J": (1.0, _ENERGY),
    "kJ": (1e3, _ENERGY),
    "MJ": (1e6, _ENERGY),
    "W": (1.0, _POWER),
    "kW": (1e3, _POWER),
    "MW": (1e6, _POWER),
    "kg": (1.0, _MASS),
    "t": (1e3, _MASS),
    "g": (1e-3, _MASS),
    "m": (1.0, _LENGTH),
    "s": (1.0, _TIME),
    "min": (60.0, _TIME),
    "h": (3600.0, _TIME),
    "K": (1.0, _TEMPERATURE),
}
_SUPERSCRIPT = {"²": 2, "³": 3}
EXPECTED_UNIT = {
    "k": "W/(m² K)",
    "C": "J/K",
    "K_veh": "W/K",
    "C_veh": "J/K",
    "C_bar": "J/K",
    "R2": "1",
    "c_veh": "J/(kg K)",
    "delta": "1",
    "c": "J/(kg K)",
}
QUANTITY_NAME = {
    "k": "heat-transfer coefficient k",
    "C": "heat capacity C",
    "K_veh": "conductance K_veh",
    "C_veh": "heat capacity C_veh",
    "R2": "R^2",
    "c_veh": "specific heat capacity c_veh",
    "delta": "ratio δ",
    "c": "specific heat capacity",
}


def _factor(token: str) -> tuple[float, tuple[int, ...]]:
    m = re.fullmatch(r"([A-Za-z]+)(?:\^(-?\d+)|([²³]))?", token)
    if m is None or m.group(1) not in _BASE:
        raise ValueError(token)
    power = int(m.group(2)) if m.group(2) else _SUPERSCRIPT.get(m.group(3), 1)
    scale, dims = _BASE[m.group(1)]
    return scale**power, tuple(power * d for d in dims)


def _product(text: str) -> tuple[float, tuple[int, ...]]:
    scale, dims = 1.0, (0, 0, 0, 0)
    for token in text.strip().strip("()").replace("·", " ").replace("*", " ").split():
        if token != "1":
            f, d = _factor(token)
            scale, dims = scale * f, tuple(a + b for a, b in zip(dims, d, strict=True))
    return scale, dims


def _unit(unit: str) -> tuple[float, tuple[int, ...]]:
    num, _, den = unit.partition("/")
    s_num, d_num = _product(num)
    s_den, d_den = _product(den) if den else (1.0, (0, 0, 0, 0))
    return s_num / s_den, tuple(a - b for a, b in zip(d_num, d_den, strict=True))


def dimension(unit: str) -> tuple[int, ...]:
    """The dimension of a printed unit as exponents of (kg, m, s, K); ``"1"`` is
    dimensionless. :class:`ValueError` for a symbol it does not know."""
    return _unit(unit)[1]


def si_factor(unit: str | None, quantity: str) -> float:
    """What a value printed in ``unit`` is multiplied by to be in the SI unit of ``quantity``
    (:data:`EXPECTED_UNIT`): 1000 for C in kJ/K; 1 where the unit is missing, unknown or of
    another dimension (a finding of check_units; the value is then read as SI)."""
    expected = EXPECTED_UNIT.get(quantity)
    if not unit or expected is None:
        return 1.0
    try:
        scale, dims = _unit(unit)
        return scale / _unit(expected)[0] if dims == dimension(expected) else 1.0
    except ValueError:
        return 1.0


# ---------------------------------------------------------------------------------------------
# Findings


@dataclass(frozen=True)
class Finding:
    """One result of one check on one subject; ``message`` shows the arithmetic."""

    family: str
    check: str
    subject: str
    severity: str
    location: str
    published: str
    recomputed: str
    message: str

    def __post_init__(self):
        if self.severity not in SEVERITIES or self.family not in FAMILIES:
            raise ValueError(f"bad finding {self.family}/{self.severity}")


def finding(family, check, subject, severity, location, published, recomputed, message):
    return Finding(family, check, subject, severity, location, published, recomputed, message)


# ---------------------------------------------------------------------------------------------
# The published document


@dataclass
class Published:
    """A set of published values (the format of ``config/published/paper.yaml``)."""

    file: str
    data: dict[str, Any]

    @property
    def document(self) -> str:
        return self.data.get("document", self.file)

    def section(self, name: str) -> dict[str, Any]:
        return self.data.get(name) or {}

    def classes(self) -> dict[str, str]:
        return dict(self.section("classes").get("of", {}))

    def table(self, name: str) -> dict[str, dict[str, Printed]]:
        """Rows of ``parameters`` or ``generalised``: vehicle -> quantity -> Printed, each
        value and its rounding in SI (a column printed in kJ/K read as J/K)."""
        units = self.section(name).get("units") or {}
        return {
            vid: {
                q: Printed.parse(text, f"{self.file}: {name}.rows.{vid}.{q}").scaled(
                    si_factor(units.get(q), q), units.get(q, "")
                )
                for q, text in row.items()
            }
            for vid, row in (self.section(name).get("rows") or {}).items()
        }

    def location(self, name: str) -> str:
        return self.section(name).get("location", name)


def _printed(file: str, key: str, text: str) -> Printed:
    """``text`` read as printed, else a :class:`ConfigError` naming ``file`` and ``key``."""
    try:
        return Printed.parse(text, "")
    except ValueError:
        raise ConfigError(file, key, text, "not a number as printed") from None


def load_published(path: str | Path, display: str | None = None) -> Published:
    """Read and validate a published-values file; :class:`ConfigError` naming the file, key
    and value on any problem (including a number that is not a number as printed)."""
    name = display or str(path)
    data = read_yaml(path, display=name)
    validate_schema(name, data, packaged_schema("published"))
    pub = Published(name, data)
    for section in ("parameters", "generalised"):
        for vid, row in (pub.section(section).get("rows") or {}).items():
            for q, text in row.items():
                value = _printed(name, f"{section}.rows.{vid}.{q}", text).value
                if q == "R2" and not value <= 1.0:  # eq. 21: 1 - SSE / SST
                    raise ConfigError(name, f"{section}.rows.{vid}.{q}", text, "R² is at most 1")
                if q != "R2" and not value > 0:  # capacities, conductances and their ratios
                    raise ConfigError(
                        name, f"{section}.rows.{vid}.{q}", text, f"{q} is a positive quantity"
                    )
    for i, statement in enumerate(data.get("statements") or []):
        printed = statement.get("printed")
        for j, text in enumerate(printed if isinstance(printed, list) else [printed]):
            if text is not None:
                _printed(name, f"statements[{i}].printed" + (f"[{j}]" if j else ""), text)
    counts = pub.section("counts")
    for row, texts in (counts.get("rows") or {}).items():
        if len(texts) != len(counts.get("columns") or []):
            raise ConfigError(
                name, f"counts.rows.{row}", texts, f"one count per column of {counts['columns']}"
            )
        for j, text in enumerate(texts):
            count = _printed(name, f"counts.rows.{row}[{j}]", text).value
            if not (count >= 0 and float(count).is_integer()):
                raise ConfigError(name, f"counts.rows.{row}[{j}]", text, "a count: 0, 1, 2, ...")
    classes = pub.classes()
    for section in ("parameters", "generalised"):
        for vid in pub.section(section).get("rows") or {}:
            if vid not in classes:
                raise ConfigError(
                    name, "classes.of", vid, f"vehicle of {section} has no class; add it"
                )
    return pub


def sourced_entries(data: Mapping[str, Any]) -> list[tuple[str, Mapping[str, Any]]]:
    """Every threshold, limit and range of ``config/audit.yaml`` with its dotted key."""
    entries = [(f"thresholds.{n}", e) for n, e in data["thresholds"].items()]
    entries += [(f"limits.{n}", e) for n, e in data["limits"].items()]
    for quantity, by_class in data["ranges"].items():
        entries += [(f"ranges.{quantity}.{cls}", e) for cls, e in by_class.items()]
    return entries


def load_ranges(path: str | Path, display: str | None = None) -> dict[str, Any]:
    """Read and validate the audit's thresholds, limits and ranges (``config/audit.yaml``).

    Every entry needs a ``source`` starting with its kind (the schema's pattern); a
    ``published:`` source must also name where in the paper (Section, §, Table or eq.)."""
    name = display or str(path)
    data = read_yaml(path, display=name)
    validate_schema(name, data, packaged_schema("audit"))
    for key, entry in sourced_entries(data):
        if "range" in entry and not entry["range"][0] < entry["range"][1]:
            raise ConfigError(name, f"{key}.range", entry["range"], "needs low < high")
        source = entry["source"]
        if source_kind(entry) == "published" and not re.search(r"Section|§|Table|eq\.", source):
            raise ConfigError(
                name, f"{key}.source", source, "a published source names its section or table"
            )
    return data


def source_kind(entry: Mapping[str, Any]) -> str:
    """The kind a source starts with: one of :data:`SOURCE_KINDS`."""
    return entry["source"].split(":", 1)[0].strip()


def capped(severity: str, entry: Mapping[str, Any]) -> str:
    """The severity rule: a finding against an ``assumption:`` is at most info."""
    return "info" if source_kind(entry) == "assumption" else severity


def cite(entry: Mapping[str, Any]) -> str:
    """The kind of a source, and for a published one where in the paper: ``published,
    Section 3.1``."""
    kind = source_kind(entry)
    where = re.search(r"(Section|§|Table|eqs?\.)\s*[\d.]*\d", entry["source"])
    return f"{kind}, {where.group(0)}" if kind == "published" and where else kind


def threshold(ranges: Mapping[str, Any], name: str) -> Mapping[str, Any]:
    return ranges["thresholds"][name]


def class_range(ranges: Mapping[str, Any], quantity: str, cls: str) -> tuple[Interval, dict] | None:
    by_class = ranges["ranges"].get(quantity, {})
    entry = by_class.get(cls) or by_class.get("all")
    if entry is None:
        return None
    return Interval(*entry["range"]), entry
