"""Audit of published reference values (the paper's Tables 1-3 and the numbers in its text).

The published values are read as printed (``config/published/paper.yaml``): a number printed as
``1.3×10^7`` stands for the interval [1.25, 1.35]×10^7, ``246`` for [245.5, 246.5]. Every
recomputation runs on such intervals (:class:`Interval`), so a value that is consistent within
its printed rounding is never reported as inconsistent.

Check families, each a small function returning :class:`Finding` s (passed checks included,
as severity ``info``, so that the report shows the arithmetic of every check):

- ``consistency``: δ = C_veh / C (eq. 25) recomputed from Table 2; class means, ranges and
  orderings stated in the text recomputed from Table 3; counts across Tables 1-3;
- ``plausibility``: quantities implied by the published values (m_veh = C_veh / c_veh from
  eq. 24, the total specific heat (C + C_veh) / m_veh, the overall heat-loss coefficient
  kA and time constant (C + C_veh) / kA) against ranges declared in ``config/audit.yaml``;
- ``fitness``: references from fits with R^2 (eq. 21) below a threshold, or with a coupling
  K_veh so large that the second state is not identifiable;
- ``units``: printed units that do not fit their quantity; inconsistent typography;
- ``reproduction``: the published value beside the pipeline's re-estimate and its 95 %
  interval.

The module knows nothing about Snakemake: rule ``audit`` and ``railtherm audit`` call
:func:`run` and :func:`write`.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from railtherm.config import packaged_schema, read_yaml, validate_schema
from railtherm.errors import ConfigError

SEVERITIES = ("error", "warning", "info")
FAMILIES = ("consistency", "plausibility", "fitness", "units", "reproduction")
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
        return f"[{_g(self.lo, digits)}, {_g(self.hi, digits)}]"


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

    @property
    def has_separator(self) -> bool:
        return "," in self.text


def _g(x: float, digits: int = 4) -> str:
    """A number for the arithmetic shown in messages: ``digits`` significant digits, powers
    of ten written ``e7`` (``1.65e7``)."""
    text = f"{x:.{digits}g}"
    if "e" in text:
        mantissa, exponent = text.split("e")
        text = f"{mantissa}e{int(exponent)}"
    return text


# ---------------------------------------------------------------------------------------------
# Units: dimensions over (kg, m, s, K)

_BASE = {
    "J": (1, 2, -2, 0),
    "W": (1, 2, -3, 0),
    "kg": (1, 0, 0, 0),
    "t": (1, 0, 0, 0),
    "g": (1, 0, 0, 0),
    "m": (0, 1, 0, 0),
    "s": (0, 0, 1, 0),
    "h": (0, 0, 1, 0),
    "K": (0, 0, 0, 1),
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


def _factor(token: str) -> tuple[int, ...]:
    m = re.fullmatch(r"([A-Za-z]+)(?:\^(-?\d+)|([²³]))?", token)
    if m is None or m.group(1) not in _BASE:
        raise ValueError(token)
    power = int(m.group(2)) if m.group(2) else _SUPERSCRIPT.get(m.group(3), 1)
    return tuple(power * d for d in _BASE[m.group(1)])


def _product(text: str) -> tuple[int, ...]:
    dims = (0, 0, 0, 0)
    for token in text.strip().strip("()").replace("·", " ").replace("*", " ").split():
        if token != "1":
            dims = tuple(a + b for a, b in zip(dims, _factor(token), strict=True))
    return dims


def dimension(unit: str) -> tuple[int, ...]:
    """The dimension of a printed unit as exponents of (kg, m, s, K); ``"1"`` is
    dimensionless. :class:`ValueError` for a symbol it does not know."""
    num, _, den = unit.partition("/")
    d_num = _product(num)
    d_den = _product(den) if den else (0, 0, 0, 0)
    return tuple(a - b for a, b in zip(d_num, d_den, strict=True))


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


def _finding(family, check, subject, severity, location, published, recomputed, message):
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
        """Rows of ``parameters`` or ``generalised``: vehicle -> quantity -> Printed."""
        return {
            vid: {
                q: Printed.parse(text, f"{self.file}: {name}.rows.{vid}.{q}")
                for q, text in row.items()
            }
            for vid, row in (self.section(name).get("rows") or {}).items()
        }

    def location(self, name: str) -> str:
        return self.section(name).get("location", name)


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
                try:
                    Printed.parse(text, "")
                except ValueError:
                    raise ConfigError(
                        name, f"{section}.rows.{vid}.{q}", text, "not a number as printed"
                    ) from None
    classes = pub.classes()
    for section in ("parameters", "generalised"):
        for vid in pub.section(section).get("rows") or {}:
            if vid not in classes:
                raise ConfigError(
                    name, "classes.of", vid, f"vehicle of {section} has no class; add it"
                )
    return pub


def load_ranges(path: str | Path, display: str | None = None) -> dict[str, Any]:
    """Read and validate the audit's ranges and thresholds (``config/audit.yaml``)."""
    name = display or str(path)
    data = read_yaml(path, display=name)
    validate_schema(name, data, packaged_schema("audit"))
    for quantity, by_class in data["ranges"].items():
        for cls, entry in by_class.items():
            lo, hi = entry["range"]
            if not lo < hi:
                raise ConfigError(
                    name, f"ranges.{quantity}.{cls}.range", entry["range"], "needs low < high"
                )
    return data


def _range(ranges: Mapping[str, Any], quantity: str, cls: str) -> tuple[Interval, dict] | None:
    by_class = ranges["ranges"].get(quantity, {})
    entry = by_class.get(cls) or by_class.get("all")
    if entry is None:
        return None
    return Interval(*entry["range"]), entry


# ---------------------------------------------------------------------------------------------
# Consistency


def check_delta_ratio(pub: Published, ranges: Mapping[str, Any] | None = None) -> list[Finding]:
    """δ printed in the generalised table against C_veh / C of the parameter table (eq. 25)."""
    out = []
    params, gen = pub.table("parameters"), pub.table("generalised")
    where = f"{pub.location('generalised')} vs {pub.location('parameters')}"
    for vid, row in gen.items():
        if "delta" not in row or not {"C", "C_veh"} <= set(params.get(vid, {})):
            continue
        C, C_veh, delta = params[vid]["C"], params[vid]["C_veh"], row["delta"]
        ratio = C_veh.interval / C.interval
        point = C_veh.value / C.value
        ok = ratio.overlaps(delta.interval)
        arithmetic = (
            f"C_veh / C = {C_veh.text} / {C.text} = {_g(point)}; within the printed rounding "
            f"{C_veh.interval.text()} / {C.interval.text()} = {ratio.text()}; δ printed "
            f"{delta.text} stands for {delta.interval.text()}"
        )
        out.append(
            _finding(
                "consistency",
                "delta_ratio",
                vid,
                "info" if ok else "error",
                where,
                delta.text,
                ratio.text(),
                ("consistent: " if ok else "inconsistent beyond rounding: ") + arithmetic,
            )
        )
    return out


def _class_rows(pub: Published, quantity: str, cls: str) -> list[tuple[str, Printed]]:
    classes = pub.classes()
    return [
        (vid, row[quantity])
        for vid, row in pub.table("generalised").items()
        if quantity in row and (cls == "all" or classes.get(vid) == cls)
    ]


def check_statements(pub: Published, ranges: Mapping[str, Any] | None = None) -> list[Finding]:
    """Class means, ranges and orderings stated in the text, recomputed from the table rows."""
    out = []
    for st in pub.data.get("statements") or []:
        kind, q = st["statistic"], st["quantity"]
        subject = st["id"]
        if kind == "mean":
            rows = _class_rows(pub, q, st["class"])
            if not rows:
                continue
            stated = Printed.parse(st["printed"], subject)
            m = mean([p.interval for _, p in rows])
            point = sum(p.value for _, p in rows) / len(rows)
            ok = m.overlaps(stated.interval)
            sum_text = " + ".join(p.text for _, p in rows)
            message = (
                f"mean of {q} over the {len(rows)} {st['class']} rows "
                f"({', '.join(v for v, _ in rows)}) = ({sum_text}) / {len(rows)} = {_g(point)}; "
                f"with each row's rounding {m.text()}; stated {stated.text} "
                f"stands for {stated.interval.text()}"
            )
            out.append(
                _finding(
                    "consistency",
                    "stated_mean",
                    subject,
                    "info" if ok else "error",
                    st["location"],
                    stated.text,
                    _g(point),
                    ("consistent: " if ok else "inconsistent: ") + message,
                )
            )
        elif kind == "range":
            rows = _class_rows(pub, q, st["class"])
            if not rows:
                continue
            lo_s, hi_s = (Printed.parse(t, subject) for t in st["printed"])
            low = min(rows, key=lambda r: r[1].value)
            high = max(rows, key=lambda r: r[1].value)
            ok = low[1].interval.overlaps(lo_s.interval) and high[1].interval.overlaps(
                hi_s.interval
            )
            message = (
                f"smallest {q} in the table: {low[1].text} ({low[0]}), largest: {high[1].text} "
                f"({high[0]}); stated range {lo_s.text} to {hi_s.text}"
            )
            out.append(
                _finding(
                    "consistency",
                    "stated_range",
                    subject,
                    "info" if ok else "error",
                    st["location"],
                    f"{lo_s.text} - {hi_s.text}",
                    f"{low[1].text} - {high[1].text}",
                    ("consistent: " if ok else "inconsistent: ") + message,
                )
            )
        elif kind == "increasing":
            means = []
            for cls in st["classes"]:
                rows = _class_rows(pub, q, cls)
                if rows:
                    means.append((cls, mean([p.interval for _, p in rows]), rows))
            steps = list(zip(means, means[1:], strict=False))
            certain = all(a[1].below(b[1]) for a, b in steps)
            broken = [(a, b) for a, b in steps if b[1].hi < a[1].lo]
            listing = "; ".join(
                f"{cls} mean {_g(sum(p.value for _, p in rows) / len(rows), 3)} "
                f"(n = {len(rows)}, with rounding {m.text(3)})"
                for cls, m, rows in means
            )
            if broken:
                severity, verdict = (
                    "error",
                    "contradicted: the class means decrease at "
                    + (", ".join(f"{a[0]} -> {b[0]}" for a, b in broken)),
                )
            elif certain:
                severity, verdict = "info", "consistent: the class means increase"
            else:
                severity, verdict = (
                    "warning",
                    "not shown by the table: neighbouring class means overlap within rounding",
                )
            out.append(
                _finding(
                    "consistency",
                    "stated_order",
                    subject,
                    severity,
                    st["location"],
                    " < ".join(st["classes"]),
                    " < ".join(f"{_g(m.lo, 3)}..{_g(m.hi, 3)}" for _, m, _ in means),
                    f"{verdict}; {listing}",
                )
            )
    return out


def check_counts(pub: Published, ranges: Mapping[str, Any] | None = None) -> list[Finding]:
    """Table 1's sums, and its evaluated experiments against the rows of Tables 2 and 3."""
    out = []
    counts = pub.section("counts")
    where = counts.get("location", "counts")
    columns = counts.get("columns") or []
    rows = counts.get("rows") or {}
    for label, values in rows.items():
        numbers = [int(Printed.parse(v, f"counts.rows.{label}").value) for v in values]
        if "sum" in columns:
            i = columns.index("sum")
            parts = [n for j, n in enumerate(numbers) if j != i]
            ok = sum(parts) == numbers[i]
            out.append(
                _finding(
                    "consistency",
                    "count_sum",
                    label,
                    "info" if ok else "error",
                    where,
                    str(numbers[i]),
                    str(sum(parts)),
                    f"{'consistent' if ok else 'inconsistent'}: "
                    f"{' + '.join(map(str, parts))} = {sum(parts)}; printed sum {numbers[i]}",
                )
            )
    evaluated = counts.get("evaluated_row")
    classes = pub.classes()
    params = pub.table("parameters")
    if evaluated in rows and params:
        numbers = dict(zip(columns, rows[evaluated], strict=True))
        for cls, text in numbers.items():
            if cls == "sum":
                n_table = len(params)
                names = "all rows"
            else:
                members = [v for v in params if classes.get(v) == cls]
                n_table, names = len(members), ", ".join(members) or "none"
            n = int(Printed.parse(text, f"counts.rows.{evaluated}").value)
            ok = n == n_table
            out.append(
                _finding(
                    "consistency",
                    "count_rows",
                    cls,
                    "info" if ok else "error",
                    f"{where} vs {pub.location('parameters')}",
                    str(n),
                    str(n_table),
                    f"{'consistent' if ok else 'inconsistent'}: '{evaluated}' = {n}; "
                    f"{pub.location('parameters')} has {n_table} ({names})",
                )
            )
    gen = pub.table("generalised")
    if params and gen:
        only_p = sorted(set(params) - set(gen))
        only_g = sorted(set(gen) - set(params))
        ok = not only_p and not only_g
        out.append(
            _finding(
                "consistency",
                "same_vehicles",
                "all",
                "info" if ok else "error",
                f"{pub.location('parameters')} vs {pub.location('generalised')}",
                str(len(params)),
                str(len(gen)),
                "consistent: both tables list the same vehicles"
                if ok
                else f"inconsistent: only in {pub.location('parameters')}: {only_p or 'none'}; "
                f"only in {pub.location('generalised')}: {only_g or 'none'}",
            )
        )
    return out


# ---------------------------------------------------------------------------------------------
# Plausibility


def _implied_mass(pub: Published, vid: str) -> tuple[Interval, str, float] | None:
    """m_veh = C_veh / c_veh (eq. 24) with the printed rounding, and its arithmetic."""
    p, g = pub.table("parameters").get(vid, {}), pub.table("generalised").get(vid, {})
    if "C_veh" not in p or "c_veh" not in g:
        return None
    m = p["C_veh"].interval / g["c_veh"].interval
    point = p["C_veh"].value / g["c_veh"].value
    text = (
        f"m_veh = C_veh / c_veh = {p['C_veh'].text} / {g['c_veh'].text} = "
        f"{_g(point / 1000, 3)} t "
        f"(with rounding {_g(m.lo / 1000, 3)}-{_g(m.hi / 1000, 3)} t)"
    )
    return m, text, point


def _outside(
    value: Interval, bounds: Interval, entry: Mapping[str, Any], quantity: str, arithmetic: str
) -> tuple[str, str]:
    ok = value.overlaps(bounds)
    verb = "plausible" if ok else "implausible"
    message = (
        f"{verb}: {arithmetic}; typical {quantity} {_g(bounds.lo)}-{_g(bounds.hi)} "
        f"{entry['unit']} (config: ranges)"
    )
    return ("info" if ok else "warning"), message


def check_implied_mass(pub: Published, ranges: Mapping[str, Any]) -> list[Finding]:
    """The vehicle mass the tables imply, m_veh = C_veh / c_veh, against its class."""
    out = []
    classes = pub.classes()
    for vid in pub.table("generalised"):
        implied = _implied_mass(pub, vid)
        bounds = _range(ranges, "m_veh", classes.get(vid, ""))
        if implied is None or bounds is None:
            continue
        m, arithmetic, point = implied
        tonnes = {**bounds[1], "unit": "t"}
        severity, message = _outside(
            m.scale(1e-3), bounds[0].scale(1e-3), tonnes, "mass", arithmetic
        )
        out.append(
            _finding(
                "plausibility",
                "implied_mass",
                vid,
                severity,
                f"{pub.location('parameters')} and {pub.location('generalised')}",
                "-",
                f"{_g(point / 1000, 3)} t",
                message,
            )
        )
    return out


def check_total_specific_heat(pub: Published, ranges: Mapping[str, Any]) -> list[Finding]:
    """(C + C_veh) / m_veh: the whole vehicle cannot store more heat per kg than water."""
    out = []
    limit = ranges["limits"]["total_specific_heat_max"]
    params = pub.table("parameters")
    for vid in pub.table("generalised"):
        implied = _implied_mass(pub, vid)
        if implied is None or "C" not in params.get(vid, {}):
            continue
        m, mass_text, m_point = implied
        C, C_veh = params[vid]["C"], params[vid]["C_veh"]
        total = (C.interval + C_veh.interval) / m
        point = (C.value + C_veh.value) / m_point
        ok = total.lo <= limit["value"]
        message = (
            f"{'possible' if ok else 'impossible'}: {mass_text}; (C + C_veh) / m_veh = "
            f"({C.text} + {C_veh.text}) / m_veh = {_g(point, 4)} J/(kg K) "
            f"(with rounding {total.text()}); limit {limit['value']} {limit['unit']} "
            "(config: limits)"
        )
        out.append(
            _finding(
                "plausibility",
                "total_specific_heat",
                vid,
                "info" if ok else "error",
                f"{pub.location('parameters')} and {pub.location('generalised')}",
                "-",
                f"{_g(point, 4)} J/(kg K)",
                message,
            )
        )
    return out


def check_published_in_range(pub: Published, ranges: Mapping[str, Any]) -> list[Finding]:
    """Printed k (Table 2) and c_veh (Table 3) against their class-typical ranges."""
    out = []
    classes = pub.classes()
    for table, q in (("parameters", "k"), ("generalised", "c_veh")):
        for vid, row in pub.table(table).items():
            bounds = _range(ranges, q, classes.get(vid, ""))
            if q not in row or bounds is None:
                continue
            arithmetic = f"{q} printed {row[q].text} ({row[q].interval.text()})"
            severity, message = _outside(row[q].interval, bounds[0], bounds[1], q, arithmetic)
            out.append(
                _finding(
                    "plausibility",
                    f"{q}_range",
                    vid,
                    severity,
                    pub.location(table),
                    row[q].text,
                    "-",
                    message,
                )
            )
    return out


def _kA(pub: Published, ranges: Mapping[str, Any], vid: str) -> tuple[Interval, str] | None:
    """kA over the class-typical surface range (A is not published)."""
    row = pub.table("parameters").get(vid, {})
    bounds = _range(ranges, "surface", pub.classes().get(vid, ""))
    if "k" not in row or bounds is None:
        return None
    A, entry = bounds
    kA = row["k"].interval * A
    text = (
        f"kA = k A = {row['k'].text} W/(m² K) × {_g(A.lo)}-{_g(A.hi)} m² (A is not published: "
        f"class-typical range) = {_g(kA.lo, 3)}-{_g(kA.hi, 3)} W/K"
    )
    return kA, text


def check_time_constant(pub: Published, ranges: Mapping[str, Any]) -> list[Finding]:
    """The overall time constant (C + C_veh) / kA against a class-typical range."""
    out = []
    for vid, row in pub.table("parameters").items():
        kA = _kA(pub, ranges, vid)
        bounds = _range(ranges, "time_constant", pub.classes().get(vid, ""))
        if kA is None or bounds is None or not {"C", "C_veh"} <= set(row):
            continue
        tau = ((row["C"].interval + row["C_veh"].interval) / kA[0]).scale(1 / 3600)
        arithmetic = (
            f"{kA[1]}; τ = (C + C_veh) / kA = ({row['C'].text} + {row['C_veh'].text}) / kA "
            f"= {_g(tau.lo, 3)}-{_g(tau.hi, 3)} h"
        )
        severity, message = _outside(tau, bounds[0], bounds[1], "τ", arithmetic)
        out.append(
            _finding(
                "plausibility",
                "time_constant",
                vid,
                severity,
                pub.location("parameters"),
                "-",
                f"{_g(tau.lo, 3)}-{_g(tau.hi, 3)} h",
                message,
            )
        )
    return out


# ---------------------------------------------------------------------------------------------
# Fitness as a reference


def check_r2(pub: Published, ranges: Mapping[str, Any]) -> list[Finding]:
    """Values from fits with R^2 (eq. 21) below ``r2_min`` should not serve as references."""
    out = []
    r2_min = ranges["r2_min"]
    for vid, row in pub.table("parameters").items():
        if "R2" not in row:
            continue
        ok = row["R2"].value >= r2_min
        message = f"R^2 = {row['R2'].text} {'>=' if ok else '<'} r2_min = {r2_min}"
        if not ok:
            unexplained = 1 - row["R2"].value
            message += (
                f"; the model leaves {unexplained:.0%} of the variance of the indoor "
                "temperature unexplained, yet its parameters are offered as reference values"
            )
        out.append(
            _finding(
                "fitness",
                "r2",
                vid,
                "info" if ok else "warning",
                pub.location("parameters"),
                row["R2"].text,
                "-",
                ("fit usable: " if ok else "fit too poor for a reference: ") + message,
            )
        )
    return out


def check_coupling(pub: Published, ranges: Mapping[str, Any]) -> list[Finding]:
    """K_veh / kA above ``coupling_ratio_max`` even for the largest plausible kA: T and T_veh
    move as one node and C, C_veh cannot be told apart from T."""
    out = []
    limit = ranges["coupling_ratio_max"]
    for vid, row in pub.table("parameters").items():
        kA = _kA(pub, ranges, vid)
        if kA is None or not {"K_veh", "C", "C_veh"} <= set(row):
            continue
        K = row["K_veh"]
        ratio = K.interval / kA[0]
        tau_fast = 1 / (K.value / row["C"].value + K.value / row["C_veh"].value)
        if ratio.lo > limit:
            severity, verdict = "warning", "second state not identifiable"
        elif ratio.hi > limit:
            severity, verdict = "info", "second state identifiable unless A is near its largest"
        else:
            severity, verdict = "info", "second state identifiable"
        message = (
            f"{kA[1]}; K_veh / kA = {K.text} / kA = {_g(ratio.lo, 3)}-{_g(ratio.hi, 3)} "
            f"(limit {limit}); air and body equalise with τ_fast = 1 / (K_veh/C + K_veh/C_veh) "
            f"= {_g(tau_fast / 60, 3)} min"
        )
        out.append(
            _finding(
                "fitness",
                "coupling",
                vid,
                severity,
                pub.location("parameters"),
                K.text,
                f"{_g(ratio.lo, 3)}-{_g(ratio.hi, 3)}",
                f"{verdict}: {message}",
            )
        )
    return out


# ---------------------------------------------------------------------------------------------
# Units and typography


def _unit_finding(subject: str, quantity: str, unit: str, location: str) -> Finding:
    expected = EXPECTED_UNIT[quantity]
    name = QUANTITY_NAME.get(quantity, quantity)
    try:
        ok = dimension(unit) == dimension(expected)
        reason = f"is not a unit of the {name}, which is in {expected}"
    except ValueError as exc:
        ok, reason = False, f"has a symbol the audit does not know ({exc}); expected {expected}"
    return _finding(
        "units",
        "unit",
        subject,
        "info" if ok else "warning",
        location,
        unit,
        expected,
        f"printed unit '{unit}' fits the {name}" if ok else f"printed unit '{unit}' {reason}",
    )


def check_units(pub: Published, ranges: Mapping[str, Any] | None = None) -> list[Finding]:
    """Every printed unit against the dimension of its quantity."""
    out = []
    for table in ("parameters", "generalised"):
        for q, unit in (pub.section(table).get("units") or {}).items():
            if q in EXPECTED_UNIT:
                out.append(_unit_finding(f"{q} column", q, unit, pub.location(table)))
    for st in pub.data.get("statements") or []:
        if "unit" in st and st["quantity"] in EXPECTED_UNIT:
            out.append(_unit_finding(st["id"], st["quantity"], st["unit"], st["location"]))
    init = pub.section("initial_values")
    for q, entry in (init.get("values") or {}).items():
        if q in EXPECTED_UNIT:
            out.append(
                _unit_finding(
                    f"initial {q} = {entry['printed']}", q, entry["unit"], init["location"]
                )
            )
    mats = pub.section("materials")
    for name, entry in (mats.get("values") or {}).items():
        out.append(
            _unit_finding(f"{name} c = {entry['printed']}", "c", entry["unit"], mats["location"])
        )
    return out


def check_separators(pub: Published, ranges: Mapping[str, Any] | None = None) -> list[Finding]:
    """Thousands separators used for some numbers of a column and not for others."""
    out = []
    for table in ("parameters", "generalised"):
        columns: dict[str, list[tuple[str, Printed]]] = {}
        for vid, row in pub.table(table).items():
            for q, p in row.items():
                if "×" not in p.text and abs(p.value) >= 1000:
                    columns.setdefault(q, []).append((vid, p))
        for q, cells in columns.items():
            with_sep = [f"{v} {p.text}" for v, p in cells if p.has_separator]
            without = [f"{v} {p.text}" for v, p in cells if not p.has_separator]
            if with_sep and without:
                out.append(
                    _finding(
                        "units",
                        "thousands_separator",
                        f"{q} column",
                        "info",
                        pub.location(table),
                        f"{len(with_sep)} with, {len(without)} without",
                        "-",
                        "typography: thousands separator used for "
                        f"{', '.join(with_sep)} but not for {', '.join(without)}",
                    )
                )
    return out


# ---------------------------------------------------------------------------------------------
# Reproduction


def check_reproduction(
    pub: Published, ranges: Mapping[str, Any], estimates: pd.DataFrame | None
) -> list[Finding]:
    """Published values beside the pipeline's re-estimates (columns ``vehicle``, ``q``,
    ``q_lo``, ``q_hi``, ``source``): agreement when the printed interval meets the 95 %
    interval."""
    if estimates is None or estimates.empty:
        return []
    out = []
    est = estimates.set_index("vehicle")
    params = pub.table("parameters")
    published = {vid: dict(row) for vid, row in params.items()}
    for vid, row in pub.table("generalised").items():
        published.setdefault(vid, {}).update(row)
    for vid, row in published.items():
        if vid not in est.index:
            continue
        source = str(est.loc[vid].get("source", "re-estimate"))
        verdict = str(est.loc[vid].get("verdict", "-"))
        for q in ("k", "C", "K_veh", "C_veh", "c_veh", "delta"):
            if q not in row or f"{q}_lo" not in est.columns or pd.isna(est.loc[vid, q]):
                continue
            x, lo, hi = (float(est.loc[vid, c]) for c in (q, f"{q}_lo", f"{q}_hi"))
            interval = Interval(min(lo, x), max(hi, x))
            ok = interval.overlaps(row[q].interval)
            out.append(
                _finding(
                    "reproduction",
                    "reestimate",
                    f"{vid} {q}",
                    "info" if ok else "warning",
                    pub.location(
                        "parameters" if q in pub.table("parameters").get(vid, {}) else "generalised"
                    ),
                    row[q].text,
                    f"{_g(x, 3)} {interval.text(3)}",
                    f"{'agrees' if ok else 'differs'}: published {row[q].text} "
                    f"({row[q].interval.text()}); re-estimate {_g(x, 4)} with 95 % interval "
                    f"{interval.text()}; re-estimate's verdict: {verdict} ({source})",
                )
            )
    return out


def read_estimates(tables: str | Path) -> pd.DataFrame | None:
    """The pipeline's Table 2 and Table 3 (``table2.csv``, ``table3.csv`` in ``tables``)
    joined per vehicle; None if there are none."""
    tables = Path(tables)
    t2, t3 = tables / "table2.csv", tables / "table3.csv"
    if not t2.is_file():
        return None
    df = pd.read_csv(t2)
    if t3.is_file():
        extra = pd.read_csv(t3)
        keep = ["vehicle"] + [c for c in extra.columns if c not in df.columns]
        df = df.merge(extra[keep], on="vehicle", how="left")
    return df


# ---------------------------------------------------------------------------------------------
# Running and writing

CHECKS: tuple[Callable[[Published, Mapping[str, Any]], list[Finding]], ...] = (
    check_delta_ratio,
    check_statements,
    check_counts,
    check_implied_mass,
    check_total_specific_heat,
    check_published_in_range,
    check_time_constant,
    check_r2,
    check_coupling,
    check_units,
    check_separators,
)


def run(
    pub: Published, ranges: Mapping[str, Any], estimates: pd.DataFrame | None = None
) -> pd.DataFrame:
    """Every check on ``pub``; one row per finding, errors first, then warnings, then info
    (within a severity in the order of the families and of the document)."""
    findings: list[Finding] = []
    for check in CHECKS:
        findings += check(pub, ranges)
    findings += check_reproduction(pub, ranges, estimates)
    df = pd.DataFrame([asdict(f) for f in findings], columns=list(COLUMNS))
    rank = {s: i for i, s in enumerate(SEVERITIES)}
    fam = {f: i for i, f in enumerate(FAMILIES)}
    order = sorted(
        range(len(df)),
        key=lambda i: (rank[df.at[i, "severity"]], fam[df.at[i, "family"]], i),
    )
    return df.iloc[order].reset_index(drop=True)


def _ranges_section(ranges: Mapping[str, Any], file: str) -> list[str]:
    lines = [
        f"## Ranges and thresholds used (`{file}`)",
        "",
        f"- r2_min = {ranges['r2_min']}: {ranges['r2_min_source'].strip()}",
        f"- coupling_ratio_max = {ranges['coupling_ratio_max']}: "
        f"{ranges['coupling_source'].strip()}",
    ]
    for name, entry in ranges["limits"].items():
        lines.append(
            f"- limit {name} = {entry['value']} {entry['unit']}: {entry['source'].strip()}"
        )
    for quantity, by_class in ranges["ranges"].items():
        for cls, entry in by_class.items():
            lo, hi = entry["range"]
            lines.append(
                f"- {quantity} ({cls}): {_g(lo)}-{_g(hi)} {entry['unit']}: "
                f"{entry['source'].strip()}"
            )
    return lines + [""]


def report(
    findings: pd.DataFrame,
    pub: Published,
    estimates_note: str | None = None,
    ranges: Mapping[str, Any] | None = None,
    ranges_file: str = "config/audit.yaml",
) -> str:
    """audit.md: a summary, then every finding grouped by severity with its arithmetic."""
    lines = [
        f"# Audit of published reference values: {pub.document}",
        "",
        f"Published values: `{pub.file}` ({pub.data.get('data', 'published values')}). "
        "Each number is read as printed and stands for the interval of its rounding "
        "(2.5 for [2.45, 2.55], 1.3×10^7 for [1.25, 1.35]×10^7); every recomputation is "
        "done on those intervals, so a value consistent within its printed rounding is "
        "never reported as inconsistent.",
        "",
    ]
    if estimates_note:
        lines += [estimates_note, ""]
    counts = findings.groupby(["family", "severity"]).size().unstack(fill_value=0)
    counts = counts.reindex(index=list(FAMILIES), columns=list(SEVERITIES), fill_value=0)
    lines += ["| family | error | warning | info |", "| --- | --- | --- | --- |"]
    for family, row in counts.iterrows():
        lines.append(f"| {family} | {row['error']} | {row['warning']} | {row['info']} |")
    lines.append("")
    titles = {
        "error": "Errors: the published numbers contradict each other or physics",
        "warning": "Warnings: implausible, unfit as a reference, or mislabelled",
        "info": "Info: checks passed (with their arithmetic) and typography",
    }
    for severity in SEVERITIES:
        part = findings[findings["severity"] == severity]
        lines += [f"## {titles[severity]} ({len(part)})", ""]
        if part.empty:
            lines += ["None.", ""]
            continue
        for family in FAMILIES:
            rows = part[part["family"] == family]
            if rows.empty:
                continue
            lines += [f"### {family}", ""]
            for r in rows.itertuples():
                lines.append(f"- **{r.check}**, {r.subject} ({r.location}): {r.message}")
            lines.append("")
    if ranges is not None:
        lines += _ranges_section(ranges, ranges_file)
    return "\n".join(lines)


def write(findings: pd.DataFrame, markdown: str, out_dir: str | Path) -> tuple[Path, Path]:
    """``findings.csv`` and ``audit.md`` in ``out_dir`` (written whole or not at all)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    csv, md = out / "findings.csv", out / "audit.md"
    for path, text in ((csv, findings.to_csv(index=False, lineterminator="\n")), (md, markdown)):
        tmp = path.with_suffix(path.suffix + ".tmp")
        tmp.write_text(text, encoding="utf-8")
        tmp.replace(path)
    return csv, md


def estimates_note(estimates: pd.DataFrame | None, tables: str | None) -> str:
    if estimates is None:
        return (
            "Reproduction: no re-estimates given (`--estimates DIR` with table2.csv and "
            "table3.csv), so the reproduction family did not run."
        )
    sources = sorted(set(estimates.get("source", pd.Series(["re-estimate"])).astype(str)))
    note = f"Reproduction: re-estimates from `{tables}` ({'; '.join(sources)})."
    if any("synthetic" in s for s in sources):
        note += " " + SYNTHETIC_CAVEAT
    return note


def audit(
    published: str | Path,
    ranges: str | Path,
    estimates: str | Path | None,
    out_dir: str | Path,
    display: Mapping[str, str] | None = None,
) -> pd.DataFrame:
    """Load, check and write: the whole of rule ``audit`` and of ``railtherm audit``."""
    display = display or {}
    pub = load_published(published, display.get("published"))
    limits = load_ranges(ranges, display.get("ranges"))
    est = read_estimates(estimates) if estimates is not None else None
    findings = run(pub, limits, est)
    note = estimates_note(
        est, display.get("estimates", str(estimates)) if est is not None else None
    )
    markdown = report(findings, pub, note, limits, display.get("ranges", str(ranges)))
    write(findings, markdown, out_dir)
    return findings
