"""The study's tables for readers: the paper's number formats, Markdown and LaTeX.

:mod:`railtherm.study.aggregate` builds the tables (numbers, intervals, the "not identified" state
and the class statistics); this module only formats them: values with their 95 % intervals in
the paper's notation, a value the data do not determine as a one-sided limit (≤, ≥), the
captions and notes, and the files (CSV at a stated precision through
:func:`railtherm.report.tables.write_csv`, Markdown, LaTeX).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import pandas as pd

from railtherm import structures
from railtherm.estimation import common
from railtherm.records import FitRecord
from railtherm.report.tables import round_significant, write_csv
from railtherm.study.aggregate import ESTIMATED, NOT_GIVEN, is_not_given, selectable

ESTIMATOR_LABEL = {"output_error": "output error", "kalman": "Kalman ML"}


def model_selection_markdown(fits: Sequence[FitRecord], alpha: float = 0.05) -> str:
    """Per vehicle with two or more kalman fits that are acceptable and converged (a fit in
    doubt or unconverged is no candidate): the forward selection of its nested
    structures by likelihood-ratio tests
    (:func:`railtherm.estimation.diagnostics.forward_selection`,
    :func:`railtherm.structures.nesting`: each structure's ``nests``, e.g. the first-order
    model is the limit of the second-order model as K_veh -> 0 and of the interior-envelope
    model as K_i -> infinity); empty when no vehicle has them."""
    from railtherm.estimation import diagnostics
    from railtherm.study.fitsettings import split_key

    by_vehicle: dict[str, list[FitRecord]] = {}
    for fit in fits:
        if fit.estimator == "kalman" and selectable(fit):
            by_vehicle.setdefault(fit.vehicle, []).append(fit)
    parts = []
    for vehicle, kfits in by_vehicle.items():
        keys = {split_key(f.model)[0]: f for f in kfits}
        if len(keys) < 2:
            continue
        nesting = [
            (small, large, boundary)
            for small, large, boundary in structures.nesting()
            if small in keys and large in keys and keys[large].n_params > keys[small].n_params
        ]
        if not nesting:  # e.g. order2 and interior_envelope without order1: not nested
            continue
        nested = {name for link in nesting for name in link[:2]}
        candidates = [(k, f.loglik, f.n_params) for k, f in keys.items() if k in nested]
        selection = diagnostics.forward_selection(candidates, nesting, alpha)
        parts.append(diagnostics.selection_markdown(vehicle, selection))
    return "\n".join(parts)


def model_markdown(df: pd.DataFrame, source: str, selection: str = "") -> str:
    """The model comparison for readers; ``selection``: the forward selections of the kalman
    fits (:func:`model_selection_markdown`), appended."""

    def ka(r) -> str:
        if str(r.kA_status).startswith("not identified"):
            return "not identified"
        if r.kA is None or not math.isfinite(r.kA):
            return "–"
        if r.kA_lo is None or not math.isfinite(r.kA_lo):
            return f"{r.kA:.1f}"
        return f"{r.kA:.1f} [{r.kA_lo:.1f}, {r.kA_hi:.1f}]"

    view = pd.DataFrame(
        {
            "vehicle": df["vehicle"],
            "model": df["structure"],
            "estimator": df["estimator"].map(ESTIMATOR_LABEL),
            "kA (W/K)": [ka(r) for r in df.itertuples()],
            "k from": df["k_source"],
            "R² (1)": [r2_text(x) for x in df["R2"]],
            "NRMSE fit (1)": [f"{x:.3f}" for x in df["nrmse_fit"]],
            "RMSE (K)": [f"{x:.3f}" for x in df["rmse_K"]],
            "AIC": [
                f"{x:.1f}" + ("*" if c else "") + (" ◀" if b else "")
                for x, c, b in zip(df["aic"], df["ic_indicative"], df["best_aic"], strict=True)
            ],
            "BIC": [
                f"{x:.1f}" + ("*" if c else "") + (" ◀" if b else "")
                for x, c, b in zip(df["bic"], df["ic_indicative"], df["best_bic"], strict=True)
            ],
            "Ljung-Box p": [f"{x:.3g}" for x in df["ljung_box_p"]],
            "verdict": [
                v + ("" if c else " (not converged)")
                for v, c in zip(df["verdict"], df["converged"], strict=True)
            ],
            "judged by": df["judged_by"],
        }
    )
    return "\n".join(
        [
            f"**Models compared per vehicle (simulated T).** Data: {source}.",
            "",
            view.to_markdown(index=False, disable_numparse=True),
            "",
            "- ◀: the vehicle's lowest AIC / BIC (per estimator) among its fits that are "
            "acceptable and converged. *: an output-error fit whose residuals are coloured "
            "(Ljung-Box p below the check's level): its AIC / BIC count dependent residuals as "
            "independent samples and are indicative only. Judged by: the verdict's criteria "
            "(docs/checks.md), ✗ the ones the fit failed. NRMSE fit = 1 - ||y - ŷ|| / "
            "||y - mean(y)|| (MATLAB's compare, pySIP), not R^2 (eq. 21). kA of the "
            "interior-envelope model is K_i K_o / (K_i + K_o), its interval by the delta method.",
            *(
                [
                    "- Kalman ML rows: R², NRMSE fit and RMSE are those of the simulation of the "
                    "same parameters; AIC and BIC are from the likelihood of the one-step "
                    "innovations, Ljung-Box p from the standardised innovations.",
                ]
                if (df["estimator"] == "kalman").any()
                else []
            ),
            "",
            *([selection] if selection else []),
        ]
    )


# ----------------------------------------------------------------------------------------------
# formatting for readers: the paper's number formats, Markdown and LaTeX

_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def _exponent(x: float) -> int:
    return int(math.floor(math.log10(abs(x)))) if x and math.isfinite(x) else 0


def _power(e: int, tex: bool) -> str:
    return f"\\times10^{{{e}}}" if tex else "×10" + str(e).translate(_SUPERSCRIPT)


def _sci(x: float, tex: bool, digits: int = 2) -> tuple[str, int]:
    """1.8x10^7 with ``digits`` significant digits, and the exponent used."""
    e = _exponent(x)
    decimals = max(digits - 1, 0)
    if round(abs(x) / 10.0**e, decimals) >= 10.0:  # 9.96e6 prints as 1.0x10^7
        e += 1
    return f"{x / 10.0**e:.{decimals}f}{_power(e, tex)}", e


THIN = "\u202f"  # groups thousands: "5 554 [5 243, 5 883]", where commas would be ambiguous


def grouped(x: float, decimals: int = 0, tex: bool = False) -> str:
    """``x`` with its thousands grouped by a narrow no-break space (TeX: a thin space)."""
    return f"{x:,.{decimals}f}".replace(",", "\\," if tex else THIN)


def _plain(x: float, decimals: int, thousands: bool = False, tex: bool = False) -> str:
    if not math.isfinite(x):
        return "∞"
    return grouped(x, decimals, tex) if thousands else f"{x:.{decimals}f}"


def r2_text(x: float) -> str:
    """R^2 (eq. 21) with the digits that tell fits apart: three decimals, five from 0.999 up
    (where three would print 1.000 for most fits)."""
    if not math.isfinite(x):
        return "–"
    return f"{x:.5f}" if x >= 0.999 else f"{x:.3f}"


UNBOUNDED_FACTOR = common.UNBOUNDED_FACTOR  # an interval limit this far prints as 0 or ∞


def _delta(x: float, decimals: int = 2) -> str:
    """delta as the paper prints it: two decimals, three significant digits from 10 up."""
    if not math.isfinite(x):
        return "∞"
    return f"{x:.{decimals}f}" if abs(x) < 10 else f"{x:.3g}" if abs(x) < 1000 else grouped(x)


def _limits(x: float, lo: float, hi: float) -> tuple[float, float]:
    """Interval limits beyond a factor 1e3 of the value become 0 and ∞: the data do not bound
    the parameter there (printing 6e45 would suggest otherwise)."""
    lo = 0.0 if not (math.isfinite(lo) and lo > x / UNBOUNDED_FACTOR) else lo
    hi = math.inf if not (math.isfinite(hi) and hi < x * UNBOUNDED_FACTOR) else hi
    return lo, hi


def _number(kind: str, x: float, tex: bool) -> str:
    """A single number as the paper prints its kind."""
    if kind == "sci":
        text = _sci(x, tex)[0]
        return f"${text}$" if tex else text
    if kind == "delta":
        return _delta(x)
    decimals, thousands = {"k": (2, False), "int": (0, True)}[kind]
    return _plain(x, decimals, thousands, tex)


def _value_interval(kind: str, x: float, lo: float, hi: float, tex: bool) -> str:
    """A value as the paper prints it, its 95 % interval in brackets (an interval in the
    value's power of ten for the 1.8x10^7 kind; 0 and ∞ for limits the data do not set).
    k is printed with two decimals, as its interval: u(k) is about 1 % of k."""
    lo, hi = _limits(x, lo, hi)
    if kind == "sci":  # the value with as many decimals as its interval
        e = _sci(x, tex)[1]
        text = f"{x / 10.0**e:.2f}{_power(e, tex)}"
        inner = ", ".join("0" if lim == 0 else _plain(lim / 10.0**e, 2) for lim in (lo, hi))
        text = f"{text} [{inner}]{_power(e, tex)}"
        return f"${text}$".replace("∞", "\\infty") if tex else text
    if kind == "delta":
        return f"{_delta(x)} [{'0' if lo == 0 else _delta(lo, 3)}, {_delta(hi, 3)}]"
    decimals, thousands = {"k": (2, False), "int": (0, True)}[kind]
    return (
        f"{_plain(x, decimals, thousands, tex)} "
        f"[{'0' if lo == 0 else _plain(lo, decimals, thousands, tex)}, "
        f"{_plain(hi, decimals, thousands, tex)}]"
    )


def _not_identified(kind: str, limit: float, limit_kind: str, tex: bool) -> str:
    """'not identified', with the one-sided limit the data give (≤ for an upper limit)."""
    if limit_kind not in ("upper", "lower") or not math.isfinite(limit):
        return "not identified"
    sign = {"upper": "≤", "lower": "≥"}[limit_kind]
    if tex:
        sign = {"upper": "$\\le$", "lower": "$\\ge$"}[limit_kind]
    return f"not identified ({sign} {_number(kind, limit, tex)})"


def _tex_escape(text: str) -> str:
    for a, b in (
        ("\\", "\\textbackslash{}"),
        ("&", "\\&"),
        ("%", "\\%"),
        ("_", "\\_"),
        ("#", "\\#"),
    ):
        text = text.replace(a, b)
    return text.replace("∞", "$\\infty$")


NOT_GIVEN_CELL = "not given"  # the table's note names the missing metadata, once


def _intervals(df: pd.DataFrame, q: str, kind: str, tex: bool) -> list[str]:
    """Column ``q`` with its 95 % interval (columns ``q_lo``, ``q_hi``), printed as ``kind``;
    "not identified" with its limit where ``q_status`` says so; "not given" where the config
    lacks the metadata the quantity needs (the note says which); "–" for any other value
    missing (never "nan")."""
    out = []
    for _, r in df.iterrows():
        status = r.get(f"{q}_status", ESTIMATED)
        if isinstance(status, str) and status.startswith("not identified"):
            out.append(_not_identified(kind, r[f"{q}_limit"], r[f"{q}_limit_kind"], tex))
        elif is_not_given(status):
            out.append(NOT_GIVEN_CELL)
        elif not math.isfinite(float(r[q])):
            out.append("–")
        else:
            out.append(_value_interval(kind, r[q], r[f"{q}_lo"], r[f"{q}_hi"], tex))
    return out


def _total_check(verdict: Any) -> str:
    """The C_total-against-C_bar column: "overlap", "disjoint" or "–" (not comparable)."""
    text = str(verdict) if isinstance(verdict, str) else ""
    return text if text in ("overlap", "disjoint") else "–"


def format_table(name: str, df: pd.DataFrame, tex: bool = False) -> pd.DataFrame:
    """The reader's version of a study table (all cells text): ``name`` one of table1,
    table2, table3, class_summary, class_test."""
    esc = _tex_escape if tex else (lambda t: t)
    if name == "table1":
        df = df.drop(columns=["source"], errors="ignore")
        return df.astype({c: str for c in df.columns}).map(esc)
    if name == "table2":
        return pd.DataFrame(
            {
                "Name": df["vehicle"].map(esc),
                "class": df["class"].map(esc),
                "k (W/(m² K))": _intervals(df, "k", "k", tex),
                "C (J/K)": _intervals(df, "C", "sci", tex),
                "K_veh (W/K)": _intervals(df, "K_veh", "int", tex),
                "C_veh (J/K)": _intervals(df, "C_veh", "sci", tex),
                **(
                    {
                        "C_total = C + C_veh (J/K)": _intervals(df, "C_total", "sci", tex),
                        "C_bar, eq. 9 (J/K)": _intervals(df, "C_bar", "sci", tex),
                        "C_total vs C_bar": [esc(_total_check(v)) for v in df["C_total_vs_C_bar"]],
                    }
                    if "C_total" in df
                    else {}
                ),
                "R² (1)": [r2_text(x) for x in df["R2"]],
                "verdict": df["verdict"].map(esc),
                "k from": df["k_source"].map(esc),
            }
        )
    if name == "table3":
        return pd.DataFrame(
            {
                "Name": df["vehicle"].map(esc),
                "class": df["class"].map(esc),
                "m_veh (t)": [
                    f"{m / 1000:.1f}" if math.isfinite(m) else NOT_GIVEN_CELL for m in df["m_veh"]
                ],
                "c_veh (J/(kg K))": _intervals(df, "c_veh", "int", tex),
                "δ (1)": _intervals(df, "delta", "delta", tex),
                "verdict": df["verdict"].map(esc),
            }
        )
    if name == "class_summary":

        def num(q, x):
            if not math.isfinite(x):
                return "–"
            return _plain(x, 0, True, tex) if q == "c_veh" else _delta(x)

        def centre(r):
            """c_veh: the mean (the paper's statistic); delta: the geometric mean."""
            if r.n == 0:
                return "–"
            key = "mean" if r.quantity == "c_veh" else "geometric_mean"
            x, lo, hi = getattr(r, key), getattr(r, f"{key}_ci_lo"), getattr(r, f"{key}_ci_hi")
            ci = f" [{num(r.quantity, lo)}, {num(r.quantity, hi)}]" if math.isfinite(lo) else ""
            return f"{num(r.quantity, x)}{ci}"

        def spread(r):
            """c_veh: the sample sd; delta: the geometric sd, a factor about its geometric
            mean (its spread on the log scale)."""
            if r.quantity == "c_veh":
                return num(r.quantity, r.sd)
            x = getattr(r, "geometric_sd", math.nan)
            return f"×/÷ {x:.2f}" if math.isfinite(x) else "–"

        return pd.DataFrame(
            {
                "selection": df["selection"].map(esc),
                "class": df["class"].map(esc),
                "quantity": df["quantity"].map(esc),
                "n": df["n"].astype(str),
                "mean or geometric mean [95 % t interval]": [centre(r) for r in df.itertuples()],
                "median": [num(r.quantity, r.median) for r in df.itertuples()],
                "sd (δ: geometric, ×/÷)": [spread(r) for r in df.itertuples()],
                "range": [
                    "–" if r.n == 0 else f"{num(r.quantity, r.min)} – {num(r.quantity, r.max)}"
                    for r in df.itertuples()
                ],
                "not identified (left out)": [
                    esc(str(v)) if isinstance(v, str) and v else "–" for v in df["not_identified"]
                ],
            }
        )
    if name == "class_test":
        return pd.DataFrame(
            {
                "selection": df["selection"].map(esc),
                "quantity": df["quantity"].map(esc),
                "groups": [
                    f"{r.group_a} (n={r.n_a}) vs {r.group_b} (n={r.n_b})" for r in df.itertuples()
                ],
                "means": [
                    f"{r.mean_a:.0f} vs {r.mean_b:.0f}"
                    if math.isfinite(r.mean_a) and math.isfinite(r.mean_b)
                    else "–"
                    for r in df.itertuples()
                ],
                "Welch p": [f"{p:.3f}" if math.isfinite(p) else "not run" for p in df["welch_p"]],
                "Mann-Whitney p": [
                    f"{p:.3f}" if math.isfinite(p) else "not run" for p in df["mannwhitney_p"]
                ],
                "conclusion": df["conclusion"].map(esc),
            }
        )
    raise ValueError(f"unknown table {name!r}")


def to_markdown(name: str, df: pd.DataFrame, caption: str, source: str, notes=()) -> str:
    """A caption line naming the data source, the table (GitHub Markdown), and notes."""
    lines = [f"**{caption}** Data: {source}.", ""]
    lines.append(format_table(name, df).to_markdown(index=False, disable_numparse=True))
    lines += ["", *[f"- {n}" for n in notes]] if notes else []
    return "\n".join(lines).rstrip() + "\n"


_TEX_HEADER = (("²", "$^2$"), ("δ", "$\\delta$"), ("_veh", "$_\\mathrm{veh}$"), ("%", "\\%"))


def to_latex(name: str, df: pd.DataFrame, caption: str, source: str, label: str) -> str:
    """A booktabs table environment; the caption names the data source."""
    table = format_table(name, df, tex=True)
    headers = []
    for h in table.columns:
        for a, b in _TEX_HEADER:
            h = h.replace(a, b)
        headers.append(h.replace("_", "\\_") if "$" not in h else h)
    table.columns = headers
    return table.to_latex(
        index=False,
        escape=False,
        column_format="l" * len(headers),
        caption=_tex_escape(f"{caption} Data: {source}."),
        label=label,
        position="htbp",
    )


# ----------------------------------------------------------------------------------------------
# the study's tables as files

CAPTIONS = {
    "table1": "Table 1. Vehicles, k tests and identification windows evaluated per class.",
    "table2": (
        "Table 2. Heat transfer coefficient k and heat capacities of the second-order model "
        "(eqs. 7-8) with 95 % intervals."
    ),
    "table3": (
        "Table 3. Generalised parameters c_veh = C_veh / m_veh (eq. 24) and "
        "δ = C_veh / C (eq. 25) with 95 % intervals."
    ),
    "class_summary": "Class statistics of c_veh and δ.",
    "class_test": "Do the vehicle classes differ in c_veh? (the paper's open question, §6.3)",
}
NOT_IDENTIFIED_NOTE = (
    "not identified: the data do not determine the value - the estimate sits at a bound of the "
    "search, or its 95 % interval spans more than a factor 1000 in total (hi / lo > 1000), or "
    "it is coupled to such a parameter (C, K_veh and C_veh are determined only together). A "
    "bound of the search is no limit the data give: a one-sided limit (≤, ≥) is printed only "
    "where the interval itself is open on one side. Such a value is left out of every class "
    "statistic, figure and comparison."
)
TOTAL_NOTE = (
    "C_total = C + C_veh: the total capacity, which the data determine even where they cannot "
    "split it between the air node and the vehicle body (interval by the delta method on "
    "log C_total from the fit's covariance and the signed systematic effects; a part at a "
    "bound of the search is held there). It is the capacity the first-order model lumps into "
    "C_bar (eq. 9): 'C_total vs C_bar' says whether the two 95 % intervals overlap."
)
NOTES = {
    "table1": [
        "Vehicles with a k value measured: a static k window in the config; usable: the window "
        "passed the steady-state test; identification windows fitted: windows of the "
        "second-order fits (a vehicle may have several); identified: C, K_veh and C_veh all "
        "determined by the data; evaluated: second-order fits with the verdict 'fit "
        "acceptable' (results/vehicles/<id>/fit_order2.yaml gives the reasons for the others).",
    ],
    "table2": [
        "k: the static test (eq. 10) with k ± 2 u(k), corrected for the heat stored in the k "
        "window where 'k from' says storage-corrected (the k whose kA the capacities were "
        "fitted with; the k table keeps eq. 10's), or kA / A estimated jointly when the "
        "static k was not usable ('k from').",
        "C, K_veh, C_veh: simulation-error PEM (eqs. 15-20); intervals combine the statistical "
        "(HAC) and the systematic (GUM type B) uncertainty, each physical error source once "
        "through both stages. R²: eq. 21 for T.",
        NOT_IDENTIFIED_NOTE,
        TOTAL_NOTE,
        "Verdict: results/vehicles/<id>/fit_order2.yaml lists the reasons.",
    ],
    "table3": [
        "c_veh takes C_veh's interval (the mass m_veh is taken as exact); δ's interval "
        "accounts for the correlation of C and C_veh and for systematic errors that move both. "
        "A ratio with a part the data do not determine is not identified either.",
        NOT_IDENTIFIED_NOTE,
    ],
    "class_summary": [
        "c_veh: the arithmetic mean (the paper's statistic) and the sample sd; δ, a ratio whose "
        "values span decades: the geometric mean and the geometric sd (×/÷ a factor: the "
        "spread of log δ). Their 95 % intervals are t intervals (n - 1 degrees of "
        "freedom; for δ on the log scale; a lower end below 0 shown as 0), none for a single "
        "vehicle. With 2 to 5 vehicles a class mean is known only roughly: the intervals say "
        "how roughly.",
        "Values the data do not determine are left out and named; 'every identified value' "
        "also includes fits whose assumptions are in doubt, as the paper's Figure 5 does.",
    ],
    "class_test": [
        "Welch's t-test and the exact two-sided Mann-Whitney U test at the 5 % level, each run "
        "only when it can reach significance: Welch with at least 3 vehicles per class, the "
        "exact test whose smallest p is 2 / C(n_a + n_b, n_a) (0.2 at 3 vs 2) below the level; "
        "otherwise 'not testable', never 'no significant difference'.",
    ],
}
# what a quantity not given needs, for the note of a table that has one
_NEEDS = {
    "surface_m2": "k = kA / A (eq. 10) needs the surface A",
    "mass_kg": "m_veh and c_veh = C_veh / m_veh (eq. 24) need the mass",
}
_NOT_GIVEN_QUANTITIES = {
    "table2": (("k", "surface_m2"),),
    "table3": (("c_veh", "mass_kg"),),
    "class_summary": (("c_veh", "mass_kg"),),
    "class_test": (("c_veh", "mass_kg"),),
}


def not_given_notes(name: str, tables: Mapping[str, pd.DataFrame]) -> list[str]:
    """One note per quantity of table ``name`` that some vehicles do not have for want of
    metadata (:data:`railtherm.study.aggregate.NOT_GIVEN`): which vehicles, which key, why; none
    when every vehicle gives it. Read from Table 2 (k) and Table 3 (c_veh)."""
    notes = []
    for q, key in _NOT_GIVEN_QUANTITIES.get(name, ()):
        source = tables.get("table2" if q == "k" else "table3")
        if source is None or f"{q}_status" not in source:
            continue
        ids = source.loc[source[f"{q}_status"].map(is_not_given).astype(bool), "vehicle"]
        if len(ids):
            left_out = "" if name.startswith("table") else "; left out of the statistics"
            notes.append(
                f"{NOT_GIVEN[key]} ({', '.join(map(str, ids))}): {_NEEDS[key]}, which the "
                f"vehicle config does not give (allowed for class other: a test cell, a "
                f"building){left_out}."
            )
    return notes


SYNTHETIC_NOTE = (
    "These re-estimates come from the synthetic campaign, whose ground truth was set from the "
    "paper's published values: they test the method (does railtherm recover what the data "
    "were made from?), and they are not evidence about real vehicles."
)


def write_study_tables(
    tables: Mapping[str, pd.DataFrame],
    source: str,
    paths: Mapping[str, str],
    left_out: Mapping[str, Sequence[int]] | None = None,
) -> None:
    """Each table as CSV (at ``tables.SIGNIFICANT_DIGITS`` significant digits, a ``source``
    column), Markdown and LaTeX (formatted as the paper from the same rounded numbers, the
    source in the caption); ``paths`` maps "<name>_<csv|md|tex>" to files. ``left_out``:
    {vehicle: its model orders} of the study's vehicles without a second-order fit, which
    the Markdown names (the tables are of second-order fits)."""
    for name, df in tables.items():
        df = round_significant(df)
        if "source" not in df.columns:
            df["source"] = source
        write_csv(df, paths[f"{name}_csv"])
        notes = NOTES[name] + not_given_notes(name, tables)
        if left_out:
            named = ", ".join(f"{vid} (model.orders {list(o)})" for vid, o in left_out.items())
            notes += [
                f"Not in Tables 1-3 nor the class statistics (no second-order fit): {named}; "
                "their fits are in results/tables/models.md."
            ]
        if source.startswith("mixed:"):  # the note is about the synthetic rows only
            notes += [SYNTHETIC_NOTE.replace("These re-estimates", "The synthetic rows' estimates")]
        elif "synthetic" in source:
            notes += [SYNTHETIC_NOTE]
        with open(paths[f"{name}_md"], "w", encoding="utf-8") as stream:
            stream.write(to_markdown(name, df, CAPTIONS[name], source, notes))
        with open(paths[f"{name}_tex"], "w", encoding="utf-8") as stream:
            stream.write(to_latex(name, df, CAPTIONS[name], source, f"tab:{name}"))
