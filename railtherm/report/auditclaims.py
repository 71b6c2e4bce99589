"""The audit's checks of the published tables against each other and of the claims of the
text (families ``consistency`` and ``claims`` of :mod:`railtherm.report.audit`): δ = C_veh / C
(eq. 25), class means, ranges and orderings, counts, the class test (§6.3), R^2 (eqs. 21-23)
and the same without the poor fits.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from railtherm.report.auditbase import (
    Finding,
    Interval,
    Printed,
    Published,
    capped,
    cite,
    finding,
    fmt_g,
    mean,
    source_kind,
    threshold,
)
from railtherm.study.smallsample import two_class_test

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
            f"C_veh / C = {C_veh.text} / {C.text} = {fmt_g(point)}; within the printed rounding "
            f"{C_veh.interval.text()} / {C.interval.text()} = {ratio.text()}; δ printed "
            f"{delta.text} stands for {delta.interval.text()}"
        )
        out.append(
            finding(
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
            f"{cls} mean {fmt_g(sum(p.value for _, p in rows) / len(rows), 3)} "
            f"(n = {len(rows)}, with rounding {m.text(3)})"
            for cls, m, rows in self.means
        )

    def recomputed(self) -> str:
        return " < ".join(f"{fmt_g(m.lo, 3)}..{fmt_g(m.hi, 3)}" for _, m, _ in self.means)


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
                f"({', '.join(v for v, _ in rows)}) = ({sum_text}) / {len(rows)} = {fmt_g(point)}; "
                f"with each row's rounding {m.text()}; stated {stated.text} "
                f"stands for {stated.interval.text()}"
            )
            out.append(
                finding(
                    "consistency",
                    "stated_mean",
                    subject,
                    "info" if ok else "error",
                    st["location"],
                    stated.text,
                    fmt_g(point),
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
                finding(
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
                finding(
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
                finding(
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
                finding(
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
            finding(
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
            return "not run" if x is None else fmt_g(x, 3)

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
            f"Welch: t = ({fmt_g(ma)} - {fmt_g(mb)}) / √({fmt_g(sa)}²/{na} + {fmt_g(sb)}²/{nb}) "
            f"= {fmt_g(test.welch_t)} with ν = {fmt_g(test.welch_df, 3)} degrees of "
            f"freedom, two-sided p = {fmt_g(test.welch_p, 3)}"
        )
    splits = math.comb(na + nb, na)
    floor_text = f"2 / C({na + nb}, {na}) = 2/{splits} = {fmt_g(test.mwu_min_p, 3)}"
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
            ordering = f"{name_a} above {name_b} in {fmt_g(u)} of the {na * nb} pairs"
        exact = test.mwu_method == "exact"
        p_text = floor_text if u in (0, na * nb) and exact else fmt_g(test.mwu_p, 3)
        parts.append(
            f"Mann-Whitney ({test.mwu_method}): U = {fmt_g(u)} of n_a n_b = {na} × {nb} = "
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
    level = f"α = {alpha['value']} ({cite(alpha)})"
    if test.verdict == CONTRADICTED:
        worst = max(test.welch_p, test.mwu_p)
        return (
            f"both p below {level}: the difference is significant at any level above "
            f"{fmt_g(worst, 3)}, where the text says it cannot be statistically proven"
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
    above = [f"{name} p = {fmt_g(p, 3)}" for name, p in ran.items() if p >= alpha["value"]]
    return f"{', '.join(above)} not below {level}"


def check_class_test(pub: Published, ranges: Mapping[str, Any]) -> list[Finding]:
    """A difference between two classes the text calls not significant (§6.3), tested on the
    printed rows by Welch's t-test and the exact two-sided Mann-Whitney U test."""
    out = []
    alpha = threshold(ranges, "alpha")
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
            finding(
                "claims",
                "class_test",
                st["id"],
                capped("warning", alpha) if test.verdict == CONTRADICTED else "info",
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
    r2_min = threshold(ranges, "r2_min")["value"]
    return {vid: p for vid, p in _class_rows(pub, "R2", "all") if p.interval.hi < r2_min}


def r2_arithmetic(r2: Printed) -> str:
    return f"SS_res = (1 - R^2) SS_tot = {fmt_g(1 - r2.value, 3)} SS_tot"


def check_small_deviations(pub: Published, ranges: Mapping[str, Any]) -> list[Finding]:
    """The claim of §6.2, "a model with small deviations ... for all vehicles", against R^2
    (eq. 21): by eqs. 21-23, R^2 < 0.5 means SS_res > SS_tot / 2, the residual sum of squares
    exceeds the part of the total the model reproduces (SS_tot - SS_res). R^2 is relative to
    the variance of each test's indoor temperature, so the finding says what R^2 shows and
    no more: a test with a narrow temperature range can have a low R^2 with deviations small
    in kelvin, which the published numbers do not give."""
    out = []
    entry = threshold(ranges, "r2_min")
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
            f"below {r2_min} SS_res > {fmt_g(1 - r2_min)} SS_tot, more than the part SS_tot - "
            "SS_res the model reproduces)"
        )
        if below:
            listing = "; ".join(
                f"{v} R^2 = {p.text}: SS_res = {fmt_g(1 - p.value, 3)} SS_tot, {1 - p.value:.1%} "
                "of the variance of the indoor temperature left unexplained"
                for v, p in below
            )
            severity = capped("warning", entry)
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
            finding(
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
    entry = threshold(ranges, "r2_min")
    if not _class_rows(pub, "R2", "all"):
        return []
    poor = _poor_fits(pub, ranges)
    out = []
    where = f"without R^2 < {entry['value']}"
    for st in pub.data.get("statements") or []:
        recompute = _WITHOUT_POOR_FITS.get(st["statistic"])
        found = recompute(pub, ranges, st, poor) if recompute else None
        if found is not None:  # (severity, published, recomputed, message)
            severity, published, recomputed, message = found
            location = f"{st['location']} {where}"
            out.append(
                finding(
                    "claims",
                    "without_poor_fits",
                    st["id"],
                    severity,
                    location,
                    published,
                    recomputed,
                    message,
                )
            )
    return out


def _mean_without(
    pub: Published, ranges: Mapping[str, Any], st: Mapping[str, Any], poor
) -> tuple[str, str, str, str] | None:
    """A stated class mean without the poor fits (:func:`check_without_poor_fits`)."""
    q, subject = st["quantity"], st["id"]
    entry = threshold(ranges, "r2_min")
    full = _class_rows(pub, q, st["class"])
    reduced = _class_rows(pub, q, st["class"], poor)
    if not full:
        return None
    dropped = [f"{v} (R^2 = {poor[v].text})" for v, _ in full if v in poor]
    m_full = statistics.fmean(p.value for _, p in full)
    stated = Printed.parse(st["printed"], subject)
    unit = f" {st['unit']}" if st.get("unit", "1") != "1" else ""
    if not dropped:
        message = f"unchanged: no {st['class']} fit below R^2 = {entry['value']}"
        recomputed = fmt_g(m_full)
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
            f"{len(reduced)} = {fmt_g(m_red)}; with all {len(full)} rows {fmt_g(m_full)}, "
            f"stated {stated.text}; shift {shift:+.4g}{unit} ({shift / m_full:+.0%})"
        )
        if len(values) >= 2:
            s = statistics.stdev(values)
            se = s / math.sqrt(len(values))
            message += (
                f", beside the standard error of the reduced mean s / √n = "
                f"{fmt_g(s)} / √{len(values)} = {fmt_g(se)}"
            )
        recomputed = fmt_g(m_red)
    return "info", stated.text, recomputed, message


def _order_without(
    pub: Published, ranges: Mapping[str, Any], st: Mapping[str, Any], poor
) -> tuple[str, str, str, str] | None:
    """The stated order of class means without the poor fits
    (:func:`check_without_poor_fits`)."""
    q = st["quantity"]
    entry = threshold(ranges, "r2_min")
    full = _order(pub, q, st["classes"])
    reduced = _order(pub, q, st["classes"], poor)
    dropped = sorted(v for v in poor if any(v == r for _, _, rows in full.means for r, _ in rows))
    verdicts = {
        "increase": "the class means still increase",
        "overlap": "neighbouring class means overlap within rounding",
        "decrease": "the class means decrease at "
        + ", ".join(f"{a} -> {b}" for a, b in reduced.broken),
    }
    single = [cls for cls, _, rows in reduced.means if len(rows) == 1]
    severity = (
        capped("warning", entry)
        if reduced.state == "decrease" and full.state != "decrease"
        else "info"
    )
    message = (
        f"without {', '.join(dropped) or 'no fit'}: {verdicts[reduced.state]}; "
        f"{reduced.listing()}; with every row: {full.listing()}"
    )
    if single:
        message += f"; only one vehicle left in {', '.join(single)}"
    return severity, " < ".join(st["classes"]), reduced.recomputed(), message


def _test_without(
    pub: Published, ranges: Mapping[str, Any], st: Mapping[str, Any], poor
) -> tuple[str, str, str, str] | None:
    """The class test of the text without the poor fits
    (:func:`check_without_poor_fits`)."""
    q = st["quantity"]
    alpha = threshold(ranges, "alpha")
    rows_a, rows_b = _groups(pub, st, poor)
    full_a, full_b = _groups(pub, st)
    if not full_a or not full_b:
        return None
    dropped = [v for v, _ in full_a + full_b if v in poor]
    names = tuple(st["classes"])
    test = class_test(
        [p.value for _, p in rows_a], [p.value for _, p in rows_b], names, alpha["value"]
    )
    before = class_test(
        [p.value for _, p in full_a], [p.value for _, p in full_b], names, alpha["value"]
    )
    severity = (
        capped("warning", alpha)
        if test.verdict == CONTRADICTED and before.verdict != CONTRADICTED
        else "info"
    )
    return (
        severity,
        "not significant",
        test.recomputed(),
        f"{test.verdict} without {', '.join(dropped) or 'no fit'}: {q} of "
        f"{_describe(names[0], rows_a)} against {_describe(names[1], rows_b)}; "
        f"{test.text}; {_class_test_message(test, alpha)}; with every row: "
        f"{before.verdict} ({before.recomputed()})",
    )


# a statement of the text by its statistic, recomputed without the poor fits
_WITHOUT_POOR_FITS = {
    "mean": _mean_without,
    "increasing": _order_without,
    "not_significant": _test_without,
}
