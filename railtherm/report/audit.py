"""Audit of published reference values (the paper's Tables 1-3 and the claims of its text).

The published values are read as printed (``config/published/paper.yaml``): a number printed as
``1.3×10^7`` stands for the interval [1.25, 1.35]×10^7, ``246`` for [245.5, 246.5]. Every
recomputation runs on such intervals (:class:`Interval`), so a value that is consistent within
its printed rounding is never reported as inconsistent.

Check families, each a small function returning :class:`Finding` s (passed checks included,
as severity ``info``, so that the report shows the arithmetic of every check):

- ``consistency``: δ = C_veh / C (eq. 25) recomputed from Table 2; class means, ranges and
  orderings stated in the text recomputed from Table 3; counts across Tables 1-3;
- ``claims``: the claims of the text tested on the printed rows: the metro/regional
  difference of c_veh that "cannot be statistically proven" (§6.3) by Welch's t-test and the
  exact Mann-Whitney U test; "a model with small deviations ... for all vehicles" (§6.2)
  against R^2 (eqs. 21-23); the §6.3 class means, the δ order and the class test again
  without the fits whose R^2 is below that level;
- ``plausibility``: quantities implied by the published values (m_veh = C_veh / c_veh from
  eq. 24, the total specific heat (C + C_veh) / m_veh, the overall heat-loss coefficient
  kA and time constant (C + C_veh) / kA) against limits and ranges of ``config/audit.yaml``;
- ``fitness``: references from fits with R^2 (eq. 21) below a threshold, or whose fast time
  constant τ_fast = 1 / (K_veh/C + K_veh/C_veh) is shorter than any sampling interval the paper
  names (§3.1), so that the second state is not identifiable;
- ``units``: printed units that do not fit their quantity; inconsistent typography;
- ``reproduction``: the published value beside this project's re-estimate and its 95 %
  interval. These are findings about the re-estimation, not about the paper: the report shows
  them in a section of their own and never counts them with the paper's findings.

Every threshold, limit and range of ``config/audit.yaml`` names its source, starting with its
kind (:data:`SOURCE_KINDS`). The severity rule: a finding against an ``assumption:`` is at most
``info`` ("outside the assumed range ... (assumption, not a sourced limit)"); only sourced
thresholds raise warnings; errors are kept for contradictions and physical impossibilities.

The module knows nothing about Snakemake: rule ``audit`` and ``railtherm audit`` call
:func:`run` and :func:`write`. SciPy is imported only by the class test.
"""

from __future__ import annotations

import math
import re
import statistics
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from railtherm.errors import ConfigError
from railtherm.study.smallsample import two_class_test
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


def _sourced_entries(data: Mapping[str, Any]) -> list[tuple[str, Mapping[str, Any]]]:
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
    for key, entry in _sourced_entries(data):
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


def _cap(severity: str, entry: Mapping[str, Any]) -> str:
    """The severity rule: a finding against an ``assumption:`` is at most info."""
    return "info" if source_kind(entry) == "assumption" else severity


def _cite(entry: Mapping[str, Any]) -> str:
    """The kind of a source, and for a published one where in the paper: ``published,
    Section 3.1``."""
    kind = source_kind(entry)
    where = re.search(r"(Section|§|Table|eqs?\.)\s*[\d.]*\d", entry["source"])
    return f"{kind}, {where.group(0)}" if kind == "published" and where else kind


def _threshold(ranges: Mapping[str, Any], name: str) -> Mapping[str, Any]:
    return ranges["thresholds"][name]


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


PARAMETER_QUANTITIES = ("k", "C", "K_veh", "C_veh", "R2")


def _class_rows(
    pub: Published, quantity: str, cls: str, exclude: Collection[str] = ()
) -> list[tuple[str, Printed]]:
    """(vehicle, printed value) of ``quantity`` for the vehicles of class ``cls`` (``all``: every
    vehicle), from Table 2 or Table 3, whichever holds it, in table order; without ``exclude``."""
    classes = pub.classes()
    table = "parameters" if quantity in PARAMETER_QUANTITIES else "generalised"
    return [
        (vid, row[quantity])
        for vid, row in pub.table(table).items()
        if quantity in row and (cls == "all" or classes.get(vid) == cls) and vid not in exclude
    ]


@dataclass(frozen=True)
class Order:
    """Class means of a quantity and whether they increase in the stated order."""

    state: str  # "increase", "overlap" (rounding cannot tell) or "decrease"
    broken: list[tuple[str, str]]  # neighbouring classes whose means decrease
    means: list[tuple[str, Interval, list[tuple[str, Printed]]]]

    def listing(self) -> str:
        return "; ".join(
            f"{cls} mean {_g(sum(p.value for _, p in rows) / len(rows), 3)} "
            f"(n = {len(rows)}, with rounding {m.text(3)})"
            for cls, m, rows in self.means
        )

    def recomputed(self) -> str:
        return " < ".join(f"{_g(m.lo, 3)}..{_g(m.hi, 3)}" for _, m, _ in self.means)


def _order(
    pub: Published, quantity: str, classes: Sequence[str], exclude: Collection[str] = ()
) -> Order:
    """The class means of ``quantity`` (over the printed rounding) in the order ``classes``."""
    means = []
    for cls in classes:
        rows = _class_rows(pub, quantity, cls, exclude)
        if rows:
            means.append((cls, mean([p.interval for _, p in rows]), rows))
    steps = list(zip(means, means[1:], strict=False))
    broken = [(a[0], b[0]) for a, b in steps if b[1].hi < a[1].lo]
    if broken:
        state = "decrease"
    elif all(a[1].below(b[1]) for a, b in steps):
        state = "increase"
    else:
        state = "overlap"
    return Order(state, broken, means)


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
            order = _order(pub, q, st["classes"])
            if order.state == "decrease":
                severity, verdict = (
                    "error",
                    "contradicted: the class means decrease at "
                    + ", ".join(f"{a} -> {b}" for a, b in order.broken),
                )
            elif order.state == "increase":
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
                    order.recomputed(),
                    f"{verdict}; {order.listing()}",
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
# Claims of the text

CONTRADICTED, NOT_CONTRADICTED, TOO_FEW = (
    "contradicted",
    "not contradicted",
    "not testable: too few vehicles",
)


@dataclass(frozen=True)
class ClassTest:
    """Welch's t-test and the exact two-sided Mann-Whitney U test of two classes.

    A test runs only when it can say something at α (Welch: at least three values per class,
    railtherm.study.smallsample.WELCH_MIN; Mann-Whitney: its smallest attainable p-value below α,
    railtherm.study.smallsample.smallest_mann_whitney_p). ``verdict`` on a claim that the
    difference is not significant: ``contradicted`` when both tests ran and both give p < α,
    ``not testable: too few vehicles`` when neither could run, else ``not contradicted``."""

    verdict: str
    welch_p: float | None  # None: not run
    mwu_p: float | None
    u: float | None
    text: str  # the arithmetic

    def recomputed(self) -> str:
        def p(x):
            return "not run" if x is None else _g(x, 3)

        return f"Welch p = {p(self.welch_p)}; Mann-Whitney p = {p(self.mwu_p)}"


def class_test(
    a: Sequence[float], b: Sequence[float], names: tuple[str, str], alpha: float
) -> ClassTest:
    """Welch's t-test (unequal variances) and the exact two-sided Mann-Whitney U test of the
    values ``a`` of class ``names[0]`` against ``b`` of ``names[1]`` at level ``alpha``
    (railtherm.study.smallsample.two_class_test), with their arithmetic."""
    test = two_class_test(a, b, alpha)
    na, nb = len(a), len(b)
    name_a, name_b = names
    parts = []
    if test.welch_p is None:
        parts.append(f"Welch: not testable ({test.welch_why})")
    else:
        ma, mb = statistics.fmean(a), statistics.fmean(b)
        sa, sb = statistics.stdev(a), statistics.stdev(b)
        parts.append(
            f"Welch: t = ({_g(ma)} - {_g(mb)}) / √({_g(sa)}²/{na} + {_g(sb)}²/{nb}) "
            f"= {_g(test.welch_t)} with ν = {_g(test.welch_df, 3)} degrees of "
            f"freedom, two-sided p = {_g(test.welch_p, 3)}"
        )
    splits = math.comb(na + nb, na)
    floor_text = f"2 / C({na + nb}, {na}) = 2/{splits} = {_g(test.mwu_min_p, 3)}"
    if test.mwu_p is None:
        parts.append(
            f"Mann-Whitney: not testable (the smallest two-sided p it can give for "
            f"{na} against {nb} is {floor_text} ≥ α = {alpha})"
        )
    else:
        u = test.mwu_u
        if u == 0:
            ordering = f"all {nb} {name_b} above all {na} {name_a}"
        elif u == na * nb:
            ordering = f"all {na} {name_a} above all {nb} {name_b}"
        else:
            ordering = f"{name_a} above {name_b} in {_g(u)} of the {na * nb} pairs"
        exact = test.mwu_method == "exact"
        p_text = floor_text if u in (0, na * nb) and exact else _g(test.mwu_p, 3)
        parts.append(
            f"Mann-Whitney ({test.mwu_method}): U = {_g(u)} of n_a n_b = {na} × {nb} = "
            f"{na * nb} ({ordering}), two-sided p = {p_text}"
        )
    ran = list(test.ran.values())
    if not ran:
        verdict = TOO_FEW
    elif len(ran) == 2 and all(p < alpha for p in ran):
        verdict = CONTRADICTED
    else:
        verdict = NOT_CONTRADICTED
    return ClassTest(verdict, test.welch_p, test.mwu_p, test.mwu_u, "; ".join(parts))


def _groups(
    pub: Published, st: Mapping[str, Any], exclude: Collection[str] = ()
) -> tuple[list[tuple[str, Printed]], list[tuple[str, Printed]]]:
    cls_a, cls_b = st["classes"]
    return (
        _class_rows(pub, st["quantity"], cls_a, exclude),
        _class_rows(pub, st["quantity"], cls_b, exclude),
    )


def _describe(cls: str, rows: Sequence[tuple[str, Printed]]) -> str:
    return f"{cls} (n = {len(rows)}: {', '.join(p.text for _, p in rows)})"


def _class_test_message(test: ClassTest, alpha: Mapping[str, Any]) -> str:
    level = f"α = {alpha['value']} ({_cite(alpha)})"
    if test.verdict == CONTRADICTED:
        worst = max(test.welch_p, test.mwu_p)
        return (
            f"both p below {level}: the difference is significant at any level above "
            f"{_g(worst, 3)}, where the text says it cannot be statistically proven"
        )
    if test.verdict == TOO_FEW:
        return f"neither test can reach {level}"
    ran = {"Welch": test.welch_p, "Mann-Whitney": test.mwu_p}
    missing = [name for name, p in ran.items() if p is None]
    if missing:
        return (
            f"only {' and '.join(n for n, p in ran.items() if p is not None)} could run; a "
            f"contradiction needs both tests below {level}"
        )
    above = [f"{name} p = {_g(p, 3)}" for name, p in ran.items() if p >= alpha["value"]]
    return f"{', '.join(above)} not below {level}"


def check_class_test(pub: Published, ranges: Mapping[str, Any]) -> list[Finding]:
    """A difference between two classes the text calls not significant (§6.3), tested on the
    printed rows by Welch's t-test and the exact two-sided Mann-Whitney U test."""
    out = []
    alpha = _threshold(ranges, "alpha")
    for st in pub.data.get("statements") or []:
        if st["statistic"] != "not_significant":
            continue
        (cls_a, cls_b), q = st["classes"], st["quantity"]
        rows_a, rows_b = _groups(pub, st)
        if not rows_a or not rows_b:
            continue
        test = class_test(
            [p.value for _, p in rows_a],
            [p.value for _, p in rows_b],
            (cls_a, cls_b),
            alpha["value"],
        )
        out.append(
            _finding(
                "claims",
                "class_test",
                st["id"],
                _cap("warning", alpha) if test.verdict == CONTRADICTED else "info",
                st["location"],
                "not significant",
                test.recomputed(),
                f"{test.verdict}: {q} of {_describe(cls_a, rows_a)} against "
                f"{_describe(cls_b, rows_b)}; {test.text}; {_class_test_message(test, alpha)}",
            )
        )
    return out


def _poor_fits(pub: Published, ranges: Mapping[str, Any]) -> dict[str, Printed]:
    """Vehicles whose printed R^2 (its whole rounding interval) lies below ``r2_min``."""
    r2_min = _threshold(ranges, "r2_min")["value"]
    return {vid: p for vid, p in _class_rows(pub, "R2", "all") if p.interval.hi < r2_min}


def _r2_arithmetic(r2: Printed) -> str:
    return f"SS_res = (1 - R^2) SS_tot = {_g(1 - r2.value, 3)} SS_tot"


def check_small_deviations(pub: Published, ranges: Mapping[str, Any]) -> list[Finding]:
    """The claim of §6.2, "a model with small deviations ... for all vehicles", against R^2
    (eq. 21): by eqs. 21-23, R^2 < 0.5 means SS_res > SS_tot / 2, the residual sum of squares
    exceeds the part of the total the model reproduces (SS_tot - SS_res). R^2 is relative to
    the variance of each test's indoor temperature, so the finding says what R^2 shows and
    no more: a test with a narrow temperature range can have a low R^2 with deviations small
    in kelvin, which the published numbers do not give."""
    out = []
    entry = _threshold(ranges, "r2_min")
    r2_min = entry["value"]
    poor = _poor_fits(pub, ranges)
    for st in pub.data.get("statements") or []:
        if st["statistic"] != "small_deviations":
            continue
        rows = _class_rows(pub, "R2", st["class"])
        if not rows:
            continue
        below = sorted(((v, p) for v, p in rows if v in poor), key=lambda r: r[1].value)
        level = (
            f"R^2 = {r2_min} ({source_kind(entry)}: R^2 = 1 - SS_res / SS_tot, eqs. 21-23, so "
            f"below {r2_min} SS_res > {_g(1 - r2_min)} SS_tot, more than the part SS_tot - "
            "SS_res the model reproduces)"
        )
        if below:
            listing = "; ".join(
                f"{v} R^2 = {p.text}: SS_res = {_g(1 - p.value, 3)} SS_tot, {1 - p.value:.1%} "
                "of the variance of the indoor temperature left unexplained"
                for v, p in below
            )
            severity = _cap("warning", entry)
            message = (
                f"not supported by R^2: {len(below)} of {len(rows)} fits lie below {level}, "
                f"the model reproducing less than half of the indoor temperature's variance "
                f"in their own test: {listing}. R^2 is relative to each test's temperature "
                "range; the deviations in kelvin (RMSE) are not published, so whether they "
                "are small in absolute terms is not checked"
            )
        else:
            lowest = min(rows, key=lambda r: r[1].value)
            severity = "info"
            message = (
                f"consistent: all {len(rows)} fits reach {level}; lowest "
                f"{lowest[0]} R^2 = {lowest[1].text}"
            )
        out.append(
            _finding(
                "claims",
                "small_deviations",
                st["id"],
                severity,
                st["location"],
                "all vehicles",
                f"{len(below)} of {len(rows)} below {r2_min}",
                message,
            )
        )
    return out


def check_without_poor_fits(pub: Published, ranges: Mapping[str, Any]) -> list[Finding]:
    """The stated class means, the stated order and the class test of the text, recomputed
    without the fits whose R^2 is below ``r2_min``, beside the values from every row.

    Severity info, unless leaving those fits out turns a claim into its contradiction (an
    order that holds on every row decreases, or a class test not contradicted on every row is
    contradicted): then warning, since the claim rests on fits the paper's own R^2 shows to be
    poor. A mean's shift is set beside the standard error of the reduced mean; no sourced
    threshold says how large a shift matters."""
    entry = _threshold(ranges, "r2_min")
    if not _class_rows(pub, "R2", "all"):
        return []
    poor = _poor_fits(pub, ranges)
    out = []
    where = f"without R^2 < {entry['value']}"
    for st in pub.data.get("statements") or []:
        kind, q, subject = st["statistic"], st["quantity"], st["id"]
        location = f"{st['location']} {where}"
        if kind == "mean":
            full = _class_rows(pub, q, st["class"])
            reduced = _class_rows(pub, q, st["class"], poor)
            if not full:
                continue
            dropped = [f"{v} (R^2 = {poor[v].text})" for v, _ in full if v in poor]
            m_full = statistics.fmean(p.value for _, p in full)
            stated = Printed.parse(st["printed"], subject)
            unit = f" {st['unit']}" if st.get("unit", "1") != "1" else ""
            if not dropped:
                message = f"unchanged: no {st['class']} fit below R^2 = {entry['value']}"
                recomputed = _g(m_full)
            elif not reduced:
                message = f"no {st['class']} vehicle left without {', '.join(dropped)}"
                recomputed = "-"
            else:
                values = [p.value for _, p in reduced]
                m_red = statistics.fmean(values)
                shift = m_red - m_full
                message = (
                    f"without {', '.join(dropped)}: mean {q} of the {len(reduced)} remaining "
                    f"{st['class']} rows = ({' + '.join(p.text for _, p in reduced)}) / "
                    f"{len(reduced)} = {_g(m_red)}; with all {len(full)} rows {_g(m_full)}, "
                    f"stated {stated.text}; shift {shift:+.4g}{unit} ({shift / m_full:+.0%})"
                )
                if len(values) >= 2:
                    s = statistics.stdev(values)
                    se = s / math.sqrt(len(values))
                    message += (
                        f", beside the standard error of the reduced mean s / √n = "
                        f"{_g(s)} / √{len(values)} = {_g(se)}"
                    )
                recomputed = _g(m_red)
            out.append(
                _finding(
                    "claims",
                    "without_poor_fits",
                    subject,
                    "info",
                    location,
                    stated.text,
                    recomputed,
                    message,
                )
            )
        elif kind == "increasing":
            full = _order(pub, q, st["classes"])
            reduced = _order(pub, q, st["classes"], poor)
            dropped = sorted(
                v for v in poor if any(v == r for _, _, rows in full.means for r, _ in rows)
            )
            verdicts = {
                "increase": "the class means still increase",
                "overlap": "neighbouring class means overlap within rounding",
                "decrease": "the class means decrease at "
                + ", ".join(f"{a} -> {b}" for a, b in reduced.broken),
            }
            single = [cls for cls, _, rows in reduced.means if len(rows) == 1]
            severity = (
                _cap("warning", entry)
                if reduced.state == "decrease" and full.state != "decrease"
                else "info"
            )
            message = (
                f"without {', '.join(dropped) or 'no fit'}: {verdicts[reduced.state]}; "
                f"{reduced.listing()}; with every row: {full.listing()}"
            )
            if single:
                message += f"; only one vehicle left in {', '.join(single)}"
            out.append(
                _finding(
                    "claims",
                    "without_poor_fits",
                    subject,
                    severity,
                    location,
                    " < ".join(st["classes"]),
                    reduced.recomputed(),
                    message,
                )
            )
        elif kind == "not_significant":
            alpha = _threshold(ranges, "alpha")
            rows_a, rows_b = _groups(pub, st, poor)
            full_a, full_b = _groups(pub, st)
            if not full_a or not full_b:
                continue
            dropped = [v for v, _ in full_a + full_b if v in poor]
            names = tuple(st["classes"])
            test = class_test(
                [p.value for _, p in rows_a], [p.value for _, p in rows_b], names, alpha["value"]
            )
            before = class_test(
                [p.value for _, p in full_a], [p.value for _, p in full_b], names, alpha["value"]
            )
            severity = (
                _cap("warning", alpha)
                if test.verdict == CONTRADICTED and before.verdict != CONTRADICTED
                else "info"
            )
            out.append(
                _finding(
                    "claims",
                    "without_poor_fits",
                    subject,
                    severity,
                    location,
                    "not significant",
                    test.recomputed(),
                    f"{test.verdict} without {', '.join(dropped) or 'no fit'}: {q} of "
                    f"{_describe(names[0], rows_a)} against {_describe(names[1], rows_b)}; "
                    f"{test.text}; {_class_test_message(test, alpha)}; with every row: "
                    f"{before.verdict} ({before.recomputed()})",
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
    """Severity and message of ``value`` against a range; by the severity rule, outside an
    ``assumption:`` range is info, outside a sourced range a warning."""
    ok = value.overlaps(bounds)
    kind = source_kind(entry)
    span = f"{quantity} {_g(bounds.lo)}-{_g(bounds.hi)} {entry['unit']}"
    if ok:
        what = "the assumed range" if kind == "assumption" else f"the range ({kind})"
        return "info", f"within {what} {span}: {arithmetic}"
    if kind == "assumption":
        return (
            "info",
            f"outside the assumed range {span}: {arithmetic} (assumption, not a sourced limit)",
        )
    return "warning", f"implausible: {arithmetic}; outside {span} ({kind} source)"


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
            f"({source_kind(limit)}: config limits)"
        )
        out.append(
            _finding(
                "plausibility",
                "total_specific_heat",
                vid,
                "info" if ok else _cap("error", limit),
                f"{pub.location('parameters')} and {pub.location('generalised')}",
                "-",
                f"{_g(point, 4)} J/(kg K)",
                message,
            )
        )
    return out


def check_published_in_range(pub: Published, ranges: Mapping[str, Any]) -> list[Finding]:
    """Printed k (Table 2) and c_veh (Table 3) against their class-typical ranges, where
    ``config/audit.yaml`` declares one."""
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
    """Fits whose R^2 (eq. 21) lies below ``r2_min`` should not serve as references: by
    eqs. 21-23, R^2 < 0.5 means SS_res > SS_tot / 2, deviations larger than the part of the
    indoor temperature's variation the model reproduces. The optional ``r2_note`` adds a
    stricter level (info when it is an assumption)."""
    out = []
    entry = _threshold(ranges, "r2_min")
    note = ranges["thresholds"].get("r2_note")
    r2_min = entry["value"]
    for vid, row in pub.table("parameters").items():
        if "R2" not in row:
            continue
        r2 = row["R2"]
        unexplained = (
            f"{_r2_arithmetic(r2)}: the model leaves {1 - r2.value:.0%} of the variance of the "
            "indoor temperature unexplained"
        )
        if r2.interval.hi < r2_min:
            severity = _cap("warning", entry)
            message = (
                f"fit too poor for a reference: R^2 = {r2.text} < r2_min = {r2_min} "
                f"({source_kind(entry)}); {unexplained}, more than the part it reproduces, "
                "yet its parameters are offered as reference values"
            )
        elif note is not None and r2.interval.hi < note["value"]:
            severity = _cap("warning", note)
            if source_kind(note) == "assumption":
                message = (
                    f"outside the assumed range R^2 >= {note['value']}: R^2 = {r2.text}; "
                    f"{unexplained} (assumption, not a sourced limit)"
                )
            else:
                message = (
                    f"fit below r2_note: R^2 = {r2.text} < {note['value']} "
                    f"({source_kind(note)}); {unexplained}"
                )
        else:
            message = f"fit usable: R^2 = {r2.text} >= r2_min = {r2_min} ({source_kind(entry)})"
            severity = "info"
        out.append(
            _finding(
                "fitness",
                "r2",
                vid,
                severity,
                pub.location("parameters"),
                r2.text,
                "-",
                message,
            )
        )
    return out


def check_coupling(pub: Published, ranges: Mapping[str, Any]) -> list[Finding]:
    """The fast time constant of eq. 14 against the sampling intervals of §3.1.

    Air and body equalise at the rate K_veh/C + K_veh/C_veh; the fast eigenvalue of A (eq. 14)
    is at least that fast for any kA >= 0, so τ_fast = 1 / (K_veh/C + K_veh/C_veh) bounds the
    fast time constant from above without knowing A. Below the finest sampling interval the
    paper names, no sample sees the fast mode: T then measures C + C_veh, not C and C_veh apart,
    and the second state is not identifiable. K_veh / kA (kA over the class-typical surface,
    an assumption) is shown for information."""
    out = []
    entry = _threshold(ranges, "sampling_interval")
    finest, coarsest = entry["range"]  # min
    for vid, row in pub.table("parameters").items():
        if not {"K_veh", "C", "C_veh"} <= set(row):
            continue
        K, C, C_veh = row["K_veh"], row["C"], row["C_veh"]
        rate = K.interval / C.interval + K.interval / C_veh.interval  # 1/s
        tau = Interval(1 / rate.hi, 1 / rate.lo).scale(1 / 60)  # min
        point = 1 / (K.value / C.value + K.value / C_veh.value) / 60
        if tau.hi < finest:
            severity = _cap("warning", entry)
            verdict = (
                f"second state not identifiable: τ_fast is shorter than the finest sampling "
                f"interval the paper names ({_g(finest)} min), so no sample resolves it"
            )
        elif tau.lo < coarsest:
            severity = "info"
            verdict = (
                "second state identifiable only with sampling intervals shorter than τ_fast, at "
                f"the fine end of the {_g(finest)}-{_g(coarsest)} min the paper names (which "
                "interval was used is not stated)"
            )
        else:
            severity = "info"
            verdict = "second state identifiable at every sampling interval the paper names"
        message = (
            f"{verdict}; τ_fast = 1 / (K_veh/C + K_veh/C_veh) = 1 / ({K.text}/{C.text} + "
            f"{K.text}/{C_veh.text}) = {_g(point * 60, 3)} s = {_g(point, 3)} min (with "
            f"rounding {_g(tau.lo, 3)}-{_g(tau.hi, 3)} min); sampling {_g(finest)}-"
            f"{_g(coarsest)} min ({_cite(entry)})"
        )
        kA = _kA(pub, ranges, vid)
        if kA is not None:
            ratio = K.interval / kA[0]
            message += (
                f"; for information, {kA[1]}; K_veh / kA = {K.text} / kA = "
                f"{_g(ratio.lo, 3)}-{_g(ratio.hi, 3)}"
            )
        out.append(
            _finding(
                "fitness",
                "coupling",
                vid,
                severity,
                pub.location("parameters"),
                K.text,
                f"τ_fast {_g(point, 3)} min",
                message,
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
# Reproduction: findings about this project's re-estimation, not about the paper

REESTIMATED = ("k", "C", "K_veh", "C_veh", "c_veh", "delta")
# An interval spanning more than a factor UNBOUNDED in total (hi / lo) is no estimate
# (railtherm.estimation.pem.identification): the data do not determine the value, and it is not
# compared.
UNBOUNDED = 1000.0
TOTAL = "C_total"  # C + C_veh of the re-estimates' Table 2: the capacity the data determine
AGREES, DIFFERS, NOT_COMPARABLE = "agrees", "differs", "not comparable"
REESTIMATE_VERDICTS = (DIFFERS, NOT_COMPARABLE, AGREES)  # the report's order


def _number(value: Any) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def compare_reestimate(
    published: Printed, x: Any, lo: Any, hi: Any, status: Any = None
) -> tuple[str, Interval | None]:
    """``agrees``, ``differs`` or ``not comparable: <reason>``, and the interval compared.

    ``agrees`` needs an identified re-estimate (``status`` missing or ``estimated``: not
    "not identified", which includes a parameter coupled to one not identified) with a finite
    95 % interval [lo, hi] spanning at most a factor 1000 in total (hi / lo <= 1000) that
    meets the printed interval of the published value. A re-estimate "not given" (its vehicle config
    lacks the metadata it needs: k without surface_m2, c_veh without mass_kg) is not
    comparable, with that reason."""
    status = "" if status is None or pd.isna(status) else str(status).strip()
    x, lo, hi = _number(x), _number(lo), _number(hi)
    if status.startswith(("not identified", "not given")):
        return f"{NOT_COMPARABLE}: {status}", None
    if status not in ("", "estimated"):
        return f"{NOT_COMPARABLE}: status '{status}'", None
    if not math.isfinite(x):
        return f"{NOT_COMPARABLE}: no re-estimate", None
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return f"{NOT_COMPARABLE}: the 95 % interval is not finite", None
    if x <= 0:
        return f"{NOT_COMPARABLE}: the re-estimate {_g(x)} is not positive", None
    if not (lo > 0 and hi / lo <= UNBOUNDED):
        return (
            f"{NOT_COMPARABLE}: the 95 % interval spans more than a factor {_g(UNBOUNDED)} in "
            "total: the data do not determine the value"
        ), None
    interval = Interval(min(lo, x), max(hi, x))
    return (AGREES if interval.overlaps(published.interval) else DIFFERS), interval


def check_reproduction(
    pub: Published, ranges: Mapping[str, Any], estimates: pd.DataFrame | None
) -> list[Finding]:
    """Published values beside this project's re-estimates (columns ``vehicle``, ``q``,
    ``q_lo``, ``q_hi``, optionally ``q_status``, ``verdict``, ``source``), compared by
    :func:`compare_reestimate`. Severity info when the re-estimates are synthetic (their
    ``source`` says so): they test the method, not the paper; otherwise a difference is a
    warning about the re-estimation."""
    if estimates is None or estimates.empty:
        return []
    out = []
    est = estimates.drop_duplicates("vehicle").set_index("vehicle")
    params = pub.table("parameters")
    published = {vid: dict(row) for vid, row in params.items()}
    for vid, row in pub.table("generalised").items():
        published.setdefault(vid, {}).update(row)
    for vid, row in published.items():
        if vid not in est.index:
            continue
        line = est.loc[vid]
        source = str(line.get("source", "re-estimate"))
        synthetic = "synthetic" in source
        verdict_of_fit = str(line.get("verdict", "-"))
        for q in REESTIMATED:
            if q not in row or q not in est.columns:
                continue
            x, lo, hi = (line.get(c) for c in (q, f"{q}_lo", f"{q}_hi"))
            verdict, interval = compare_reestimate(row[q], x, lo, hi, line.get(f"{q}_status"))
            if interval is not None:
                shown = f"{_g(_number(x), 4)} with 95 % interval {interval.text()}"
                recomputed = f"{_g(_number(x), 3)} {interval.text(3)}"
            else:
                shown = (
                    f"{_g(_number(x), 4)} with 95 % interval "
                    f"[{_g(_number(lo), 4)}, {_g(_number(hi), 4)}]"
                )
                recomputed = "-"
            severity = "warning" if verdict == DIFFERS and not synthetic else "info"
            out.append(
                _finding(
                    "reproduction",
                    "reestimate",
                    f"{vid} {q}",
                    severity,
                    pub.location("parameters" if q in params.get(vid, {}) else "generalised"),
                    row[q].text,
                    recomputed,
                    f"{verdict}: published {row[q].text} ({row[q].interval.text()}); "
                    f"re-estimate {shown}; re-estimate's verdict: {verdict_of_fit} ({source})",
                )
            )
        if TOTAL in est.columns and "C" in row and "C_veh" in row:
            out.append(_total_finding(vid, row, line, pub, synthetic, verdict_of_fit, source))
        if f"{TOTAL}_vs_C_bar" in est.columns:
            finding = _first_order_finding(vid, line, source)
            if finding is not None:
                out.append(finding)
    return out


def _total_finding(vid, row, line, pub, synthetic, verdict_of_fit, source) -> Finding:
    """The published C + C_veh (the printed intervals added) beside the re-estimated total
    capacity C_total = C + C_veh: the quantity the data determine even where they cannot
    split it between the nodes (eqs. 7-8), compared like a parameter."""
    total = row["C"].interval + row["C_veh"].interval
    value = row["C"].value + row["C_veh"].value
    printed = Printed(f"{row['C'].text} + {row['C_veh'].text}", value, total)
    x, lo, hi = (line.get(c) for c in (TOTAL, f"{TOTAL}_lo", f"{TOTAL}_hi"))
    verdict, interval = compare_reestimate(printed, x, lo, hi, line.get(f"{TOTAL}_status"))
    shown = "-" if interval is None else f"{_g(_number(x), 3)} {interval.text(3)}"
    severity = "warning" if verdict == DIFFERS and not synthetic else "info"
    return _finding(
        "reproduction",
        "reestimate_total",
        f"{vid} C + C_veh",
        severity,
        pub.location("parameters"),
        printed.text,
        shown,
        f"{verdict}: published C + C_veh = {printed.text} ({total.text()}); re-estimated "
        f"C_total = C + C_veh {shown} (determined even where C and C_veh are not); "
        f"re-estimate's verdict: {verdict_of_fit} ({source})",
    )


def _first_order_finding(vid, line, source) -> Finding | None:
    """The re-estimates' own check of eq. 9: C_total = C + C_veh of the second-order fit
    against C_bar of the first-order fit of the same vehicle, the same capacity lumped into
    one node. Overlapping 95 % intervals agree."""
    check = str(line.get(f"{TOTAL}_vs_C_bar") or "")
    if not check or check == "nan":
        return None
    verdict = {"overlap": AGREES, "disjoint": DIFFERS}.get(check, NOT_COMPARABLE)
    reason = "" if verdict != NOT_COMPARABLE else check.removeprefix("not comparable")

    def shown(q):
        x, lo, hi = (_number(line.get(c)) for c in (q, f"{q}_lo", f"{q}_hi"))
        if not math.isfinite(x):
            return "-"
        return f"{_g(x, 3)} [{_g(lo, 3)}, {_g(hi, 3)}]"

    recomputed = f"C_total {shown(TOTAL)}; C_bar {shown('C_bar')}"
    return _finding(
        "reproduction",
        "total_vs_first_order",
        f"{vid} C_total vs C_bar",
        "info",
        "re-estimates (Table 2)",
        "-",
        recomputed,
        f"{verdict}{reason}: the re-estimated C_total = C + C_veh (eqs. 7-8) and the "
        f"first-order C_bar (eq. 9) of the same vehicle, the same capacity: {recomputed} "
        f"({'95 % intervals overlap' if verdict == AGREES else check}; {source})",
    )


def read_estimates(tables: str | Path) -> pd.DataFrame | None:
    """This project's Table 2 and Table 3 (``table2.csv``, ``table3.csv`` in ``tables``)
    joined per vehicle; None if there are none. The ``{q}_status`` columns ("estimated" or
    "not identified: ...") are kept when present; without them every value present counts as
    estimated."""
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
    check_class_test,
    check_small_deviations,
    check_without_poor_fits,
    check_implied_mass,
    check_total_specific_heat,
    check_published_in_range,
    check_time_constant,
    check_r2,
    check_coupling,
    check_units,
    check_separators,
)


def _verdict(message: str) -> str:
    return next(v for v in REESTIMATE_VERDICTS if message.startswith(v))


def run(
    pub: Published, ranges: Mapping[str, Any], estimates: pd.DataFrame | None = None
) -> pd.DataFrame:
    """Every check on ``pub``; one row per finding. The findings about the published values
    first, errors, then warnings, then info (within a severity in the order of the families
    and of the document); then the re-estimation (family ``reproduction``), by severity and
    verdict (differs, not comparable, agrees)."""
    findings: list[Finding] = []
    for check in CHECKS:
        findings += check(pub, ranges)
    findings += check_reproduction(pub, ranges, estimates)
    df = pd.DataFrame([asdict(f) for f in findings], columns=list(COLUMNS))
    rank = {s: i for i, s in enumerate(SEVERITIES)}
    fam = {f: i for i, f in enumerate(FAMILIES)}
    verdict = {v: i for i, v in enumerate(REESTIMATE_VERDICTS)}

    def key(i: int) -> tuple:
        family = df.at[i, "family"]
        if family == "reproduction":
            return (1, rank[df.at[i, "severity"]], verdict[_verdict(df.at[i, "message"])], i)
        return (0, rank[df.at[i, "severity"]], fam[family], i)

    return df.iloc[sorted(range(len(df)), key=key)].reset_index(drop=True)


def _ranges_section(ranges: Mapping[str, Any], file: str) -> list[str]:
    lines = [
        f"## Thresholds, limits and ranges used (`{file}`)",
        "",
        "Each names its source, starting with its kind (published, physics, definition, "
        "assumption). A finding against an assumption is at most info; only sourced thresholds "
        "raise warnings; errors are kept for contradictions and physical impossibilities.",
        "",
    ]
    for key, entry in _sourced_entries(ranges):
        if "range" in entry:
            lo, hi = entry["range"]
            value = f"{_g(lo)}-{_g(hi)}"
        else:
            value = _g(entry["value"])
        unit = "" if entry["unit"] == "1" else f" {entry['unit']}"
        lines.append(f"- {key} = {value}{unit}: {entry['source'].strip()}")
    return lines + [""]


def _reestimation_section(findings: pd.DataFrame, note: str | None) -> list[str]:
    rows = findings[findings["family"] == "reproduction"]
    lines = ["## Re-estimation (not findings about the published values)", ""]
    lines += [
        "The published values beside this project's re-estimates. These findings are about the "
        "re-estimation and are not counted with the findings about the paper above. A value the "
        "data do not determine (not identified: at a bound of the search, a 95 % interval "
        "spanning more than a factor 1000 in total, or coupled to such a parameter - C, K_veh "
        "and C_veh are determined only together) is not comparable; agreement needs an "
        "identified value whose interval meets the printed one. Where the data cannot split "
        "the capacity between the nodes, the total C_total = C + C_veh is compared with the "
        "published C + C_veh, and checked against the same vehicle's first-order C_bar "
        "(eq. 9, the same capacity).",
        "",
    ]
    if note:
        lines += [note, ""]
    if rows.empty:
        return lines
    verdicts = rows["message"].map(_verdict)
    lines += [
        "| verdict | count |",
        "| --- | --- |",
        *(f"| {v} | {int((verdicts == v).sum())} |" for v in REESTIMATE_VERDICTS),
        "",
    ]
    for v in REESTIMATE_VERDICTS:
        part = rows[verdicts == v]
        if part.empty:
            continue
        lines += [f"### {v} ({len(part)})", ""]
        for r in part.itertuples():
            tag = "" if r.severity == "info" else f" [{r.severity}]"
            lines.append(f"- **{r.subject}** ({r.location}){tag}: {r.message}")
        lines.append("")
    return lines


def report(
    findings: pd.DataFrame,
    pub: Published,
    estimates_note: str | None = None,
    ranges: Mapping[str, Any] | None = None,
    ranges_file: str = "config/audit.yaml",
) -> str:
    """audit.md: a summary of the findings about the published values, every such finding
    grouped by severity with its arithmetic, then the re-estimation in a section of its own
    (never counted in the paper's totals), then the thresholds with their sources."""
    paper = findings[findings["family"] != "reproduction"]
    n_reest = int((findings["family"] == "reproduction").sum())
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
    counts = paper.groupby(["family", "severity"]).size().unstack(fill_value=0)
    counts = counts.reindex(index=list(PAPER_FAMILIES), columns=list(SEVERITIES), fill_value=0)
    lines += ["| family | error | warning | info |", "| --- | --- | --- | --- |"]
    for family, row in counts.iterrows():
        lines.append(f"| {family} | {row['error']} | {row['warning']} | {row['info']} |")
    total = counts.sum()
    lines.append(
        f"| **total (the paper)** | {total['error']} | {total['warning']} | {total['info']} |"
    )
    lines += [
        "",
        f"Re-estimation: {n_reest} comparisons with this project's re-estimates, in their "
        "own section after the findings; they are not findings about the published values "
        "and are not counted above."
        if n_reest
        else "Re-estimation: none (see its section after the findings).",
        "",
    ]
    titles = {
        "error": "Errors: the published numbers contradict each other or physics",
        "warning": "Warnings: claims contradicted, fits unfit as references, or mislabelled "
        "(against sourced thresholds)",
        "info": "Info: checks passed (with their arithmetic), notes against assumed ranges, "
        "and typography",
    }
    for severity in SEVERITIES:
        part = paper[paper["severity"] == severity]
        lines += [f"## {titles[severity]} ({len(part)})", ""]
        if part.empty:
            lines += ["None.", ""]
            continue
        for family in PAPER_FAMILIES:
            rows = part[part["family"] == family]
            if rows.empty:
                continue
            lines += [f"### {family}", ""]
            for r in rows.itertuples():
                lines.append(f"- **{r.check}**, {r.subject} ({r.location}): {r.message}")
            lines.append("")
    lines += _reestimation_section(findings, estimates_note)
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
            "No re-estimates given (`--estimates DIR` with table2.csv and table3.csv), so the "
            "reproduction family did not run."
        )
    sources = sorted(set(estimates.get("source", pd.Series(["re-estimate"])).astype(str)))
    note = f"Re-estimates from `{tables}` ({'; '.join(sources)})."
    if any("synthetic" in s for s in sources):
        note += " " + SYNTHETIC_CAVEAT + " Their findings are therefore info."
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
