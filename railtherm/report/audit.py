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

The checks live in :mod:`railtherm.report.auditclaims` (consistency, claims) and
:mod:`railtherm.report.auditvalues` (plausibility, fitness, units), on the vocabulary of
:mod:`railtherm.report.auditbase`; this module holds the reproduction family, runs them all and
writes the report, and is the audit's one entry point (it names every check).

The module knows nothing about Snakemake: rule ``audit`` and ``railtherm audit`` call
:func:`run` and :func:`write`. SciPy is imported only by the class test.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import asdict
from pathlib import Path
from typing import Any

import pandas as pd

from railtherm.errors import ConfigError
from railtherm.report.auditbase import (
    COLUMNS,
    FAMILIES,
    PAPER_FAMILIES,
    SEVERITIES,
    SOURCE_KINDS,
    SYNTHETIC_CAVEAT,
    Finding,
    Interval,
    Printed,
    Published,
    dimension,
    finding,
    fmt_g,
    load_published,
    load_ranges,
    source_kind,
    sourced_entries,
)
from railtherm.report.auditclaims import (
    CONTRADICTED,
    NOT_CONTRADICTED,
    TOO_FEW,
    check_class_test,
    check_counts,
    check_delta_ratio,
    check_small_deviations,
    check_statements,
    check_without_poor_fits,
    class_test,
)
from railtherm.report.auditvalues import (
    check_coupling,
    check_implied_mass,
    check_published_in_range,
    check_r2,
    check_separators,
    check_time_constant,
    check_total_specific_heat,
    check_units,
)

__all__ = [
    "CHECKS",
    "COLUMNS",
    "CONTRADICTED",
    "FAMILIES",
    "Finding",
    "Interval",
    "NOT_CONTRADICTED",
    "PAPER_FAMILIES",
    "Printed",
    "Published",
    "SEVERITIES",
    "SOURCE_KINDS",
    "SYNTHETIC_CAVEAT",
    "TOO_FEW",
    "audit",
    "check_class_test",
    "check_counts",
    "check_coupling",
    "check_delta_ratio",
    "check_implied_mass",
    "check_published_in_range",
    "check_r2",
    "check_reproduction",
    "check_separators",
    "check_small_deviations",
    "check_statements",
    "check_time_constant",
    "check_total_specific_heat",
    "check_units",
    "check_without_poor_fits",
    "class_test",
    "compare_reestimate",
    "dimension",
    "estimates_note",
    "load_published",
    "load_ranges",
    "read_estimates",
    "report",
    "run",
    "source_kind",
    "sourced_entries",
    "write",
]

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
        return f"{NOT_COMPARABLE}: the re-estimate {fmt_g(x)} is not positive", None
    if not (lo > 0 and hi / lo <= UNBOUNDED):
        return (
            f"{NOT_COMPARABLE}: the 95 % interval spans more than a factor {fmt_g(UNBOUNDED)} in "
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
                shown = f"{fmt_g(_number(x), 4)} with 95 % interval {interval.text()}"
                recomputed = f"{fmt_g(_number(x), 3)} {interval.text(3)}"
            else:
                shown = (
                    f"{fmt_g(_number(x), 4)} with 95 % interval "
                    f"[{fmt_g(_number(lo), 4)}, {fmt_g(_number(hi), 4)}]"
                )
                recomputed = "-"
            severity = "warning" if verdict == DIFFERS and not synthetic else "info"
            out.append(
                finding(
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
            first_order = _first_order_finding(vid, line, source)
            if first_order is not None:
                out.append(first_order)
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
    shown = "-" if interval is None else f"{fmt_g(_number(x), 3)} {interval.text(3)}"
    severity = "warning" if verdict == DIFFERS and not synthetic else "info"
    return finding(
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
        return f"{fmt_g(x, 3)} [{fmt_g(lo, 3)}, {fmt_g(hi, 3)}]"

    recomputed = f"C_total {shown(TOTAL)}; C_bar {shown('C_bar')}"
    return finding(
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
    df = _estimate_table(t2)
    if t3.is_file():
        extra = _estimate_table(t3)
        keep = ["vehicle"] + [c for c in extra.columns if c not in df.columns]
        df = df.merge(extra[keep], on="vehicle", how="left")
    return df


def _estimate_table(path: Path) -> pd.DataFrame:
    """A table of re-estimates, one row per vehicle; a :class:`ConfigError` naming the file
    for an empty one, one without a ``vehicle`` column or with a vehicle twice."""
    try:
        table = pd.read_csv(path)
    except pd.errors.EmptyDataError:
        raise ConfigError(str(path), "(file)", None, "empty: a table of re-estimates") from None
    if "vehicle" not in table.columns:
        raise ConfigError(str(path), "vehicle", None, "missing column: one row per vehicle")
    twice = sorted(set(table.loc[table["vehicle"].duplicated(), "vehicle"].astype(str)))
    if twice:
        raise ConfigError(str(path), "vehicle", twice[0], "a vehicle in two rows")
    return table


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
    for key, entry in sourced_entries(ranges):
        if "range" in entry:
            lo, hi = entry["range"]
            value = f"{fmt_g(lo)}-{fmt_g(hi)}"
        else:
            value = fmt_g(entry["value"])
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
