"""The audit's checks of the quantities the published values imply, their fitness and units
(families ``plausibility``, ``fitness`` and ``units`` of :mod:`railtherm.report.audit`): the
implied mass (eq. 24), total specific heat, overall loss and time constant against the ranges of
``config/audit.yaml``; R^2 and the fast time constant; printed units and typography.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from railtherm.report.auditbase import (
    EXPECTED_UNIT,
    QUANTITY_NAME,
    Finding,
    Interval,
    Printed,
    Published,
    capped,
    cite,
    class_range,
    dimension,
    finding,
    fmt_g,
    si_factor,
    source_kind,
    threshold,
)
from railtherm.report.auditclaims import r2_arithmetic

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
        f"{fmt_g(point / 1000, 3)} t "
        f"(with rounding {fmt_g(m.lo / 1000, 3)}-{fmt_g(m.hi / 1000, 3)} t)"
    )
    return m, text, point


def _outside(
    value: Interval, bounds: Interval, entry: Mapping[str, Any], quantity: str, arithmetic: str
) -> tuple[str, str]:
    """Severity and message of ``value`` against a range; by the severity rule, outside an
    ``assumption:`` range is info, outside a sourced range a warning."""
    ok = value.overlaps(bounds)
    kind = source_kind(entry)
    span = f"{quantity} {fmt_g(bounds.lo)}-{fmt_g(bounds.hi)} {entry['unit']}"
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
        bounds = class_range(ranges, "m_veh", classes.get(vid, ""))
        if implied is None or bounds is None:
            continue
        m, arithmetic, point = implied
        tonnes = {**bounds[1], "unit": "t"}
        severity, message = _outside(
            m.scale(1e-3), bounds[0].scale(1e-3), tonnes, "mass", arithmetic
        )
        out.append(
            finding(
                "plausibility",
                "implied_mass",
                vid,
                severity,
                f"{pub.location('parameters')} and {pub.location('generalised')}",
                "-",
                f"{fmt_g(point / 1000, 3)} t",
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
            f"({C.text} + {C_veh.text}) / m_veh = {fmt_g(point, 4)} J/(kg K) "
            f"(with rounding {total.text()}); limit {limit['value']} {limit['unit']} "
            f"({source_kind(limit)}: config limits)"
        )
        out.append(
            finding(
                "plausibility",
                "total_specific_heat",
                vid,
                "info" if ok else capped("error", limit),
                f"{pub.location('parameters')} and {pub.location('generalised')}",
                "-",
                f"{fmt_g(point, 4)} J/(kg K)",
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
            bounds = class_range(ranges, q, classes.get(vid, ""))
            if q not in row or bounds is None:
                continue
            arithmetic = f"{q} printed {row[q].text} ({row[q].interval.text()})"
            severity, message = _outside(row[q].interval, bounds[0], bounds[1], q, arithmetic)
            out.append(
                finding(
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
    bounds = class_range(ranges, "surface", pub.classes().get(vid, ""))
    if "k" not in row or bounds is None:
        return None
    A, entry = bounds
    kA = row["k"].interval * A
    text = (
        f"kA = k A = {row['k'].text} W/(m² K) × {fmt_g(A.lo)}-{fmt_g(A.hi)} m² "
        f"(A is not published: class-typical range) = {fmt_g(kA.lo, 3)}-{fmt_g(kA.hi, 3)} W/K"
    )
    return kA, text


def check_time_constant(pub: Published, ranges: Mapping[str, Any]) -> list[Finding]:
    """The overall time constant (C + C_veh) / kA against a class-typical range."""
    out = []
    for vid, row in pub.table("parameters").items():
        kA = _kA(pub, ranges, vid)
        bounds = class_range(ranges, "time_constant", pub.classes().get(vid, ""))
        if kA is None or bounds is None or not {"C", "C_veh"} <= set(row):
            continue
        tau = ((row["C"].interval + row["C_veh"].interval) / kA[0]).scale(1 / 3600)
        arithmetic = (
            f"{kA[1]}; τ = (C + C_veh) / kA = ({row['C'].text} + {row['C_veh'].text}) / kA "
            f"= {fmt_g(tau.lo, 3)}-{fmt_g(tau.hi, 3)} h"
        )
        severity, message = _outside(tau, bounds[0], bounds[1], "τ", arithmetic)
        out.append(
            finding(
                "plausibility",
                "time_constant",
                vid,
                severity,
                pub.location("parameters"),
                "-",
                f"{fmt_g(tau.lo, 3)}-{fmt_g(tau.hi, 3)} h",
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
    entry = threshold(ranges, "r2_min")
    note = ranges["thresholds"].get("r2_note")
    r2_min = entry["value"]
    for vid, row in pub.table("parameters").items():
        if "R2" not in row:
            continue
        r2 = row["R2"]
        unexplained = (
            f"{r2_arithmetic(r2)}: the model leaves {1 - r2.value:.0%} of the variance of the "
            "indoor temperature unexplained"
        )
        if r2.interval.hi < r2_min:
            severity = capped("warning", entry)
            message = (
                f"fit too poor for a reference: R^2 = {r2.text} < r2_min = {r2_min} "
                f"({source_kind(entry)}); {unexplained}, more than the part it reproduces, "
                "yet its parameters are offered as reference values"
            )
        elif note is not None and r2.interval.hi < note["value"]:
            severity = capped("warning", note)
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
            finding(
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
    entry = threshold(ranges, "sampling_interval")
    finest, coarsest = entry["range"]  # min
    for vid, row in pub.table("parameters").items():
        if not {"K_veh", "C", "C_veh"} <= set(row):
            continue
        K, C, C_veh = row["K_veh"], row["C"], row["C_veh"]
        rate = K.interval / C.interval + K.interval / C_veh.interval  # 1/s
        tau = Interval(1 / rate.hi, 1 / rate.lo).scale(1 / 60)  # min
        point = 1 / (K.value / C.value + K.value / C_veh.value) / 60
        if tau.hi < finest:
            severity = capped("warning", entry)
            verdict = (
                f"second state not identifiable: τ_fast is shorter than the finest sampling "
                f"interval the paper names ({fmt_g(finest)} min), so no sample resolves it"
            )
        elif tau.lo < coarsest:
            severity = "info"
            verdict = (
                "second state identifiable only with sampling intervals shorter than τ_fast, at "
                f"the fine end of the {fmt_g(finest)}-{fmt_g(coarsest)} min the paper names (which "
                "interval was used is not stated)"
            )
        else:
            severity = "info"
            verdict = "second state identifiable at every sampling interval the paper names"
        message = (
            f"{verdict}; τ_fast = 1 / (K_veh/C + K_veh/C_veh) = 1 / ({K.text}/{C.text} + "
            f"{K.text}/{C_veh.text}) = {fmt_g(point * 60, 3)} s = {fmt_g(point, 3)} min (with "
            f"rounding {fmt_g(tau.lo, 3)}-{fmt_g(tau.hi, 3)} min); sampling {fmt_g(finest)}-"
            f"{fmt_g(coarsest)} min ({cite(entry)})"
        )
        kA = _kA(pub, ranges, vid)
        if kA is not None:
            ratio = K.interval / kA[0]
            message += (
                f"; for information, {kA[1]}; K_veh / kA = {K.text} / kA = "
                f"{fmt_g(ratio.lo, 3)}-{fmt_g(ratio.hi, 3)}"
            )
        out.append(
            finding(
                "fitness",
                "coupling",
                vid,
                severity,
                pub.location("parameters"),
                K.text,
                f"τ_fast {fmt_g(point, 3)} min",
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
    fits = f"printed unit '{unit}' fits the {name}"
    factor = si_factor(unit, quantity) if ok else 1.0
    if factor != 1.0:  # the tables' values are read in SI (Published.table)
        fits += f"; its values read as {factor:g} {expected} each"
    return finding(
        "units",
        "unit",
        subject,
        "info" if ok else "warning",
        location,
        unit,
        expected,
        fits if ok else f"printed unit '{unit}' {reason}",
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
                    finding(
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
