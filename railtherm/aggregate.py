"""Tables over all vehicles: the k values, every fit, and the study's Tables 1-3 with the class
statistics (paper section 6), each with 95 % intervals and the source of its data.

Formatting for readers (:func:`to_markdown`, :func:`to_latex`) follows the paper's tables:
k with one decimal, C and C_veh as 1.8x10^7, K_veh as an integer with thousands separators,
R^2 with three decimals, c_veh as an integer and delta with two decimals; intervals in
brackets beside the value. The CSV files keep full precision.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd
from scipy import stats

from railtherm.synth import DEVIATION_EFFECT_ON_K

COVERAGE_FACTOR = 2.0  # expanded uncertainty U = 2 u: about 95 % for a normal distribution
K_TOLERANCE_REL = 0.03  # agreement floor: within 3 % of the truth counts as agreeing


def kvalue_table(results: Mapping[str, Mapping[str, Any]], truth: pd.DataFrame | None = None):
    """One row per vehicle: the static k (eq. 10), u(k), the verdict, and the truth if known.

    ``results`` maps vehicle id -> the dict of its kvalue.yaml (railtherm.kvalue); ``truth`` is
    the campaign's ground_truth.csv (synthetic vehicles only). A vehicle agrees with its truth
    when |k - k_truth| <= max(u_k, 3 % k_truth) (u_k the standard uncertainty; U_k = 2 u_k, the
    expanded one, is listed too). ``note`` names the declared deviations that bias k, says when
    the window is not usable, and flags a disagreement that nothing declared explains.
    """
    truth_by_id = truth.set_index("vehicle") if truth is not None else None
    rows = []
    for vid, r in results.items():
        row = {
            "vehicle": vid,
            "method": "static (eq. 10)",
            "k": r["k"],
            "u_k": r["u_k"],
            "U_k": COVERAGE_FACTOR * r["u_k"],
            "steady": r["steady"],
            "forced": r["forced"],
            "usable": r["usable"],
            "reasons": "; ".join(r["reasons"]),
        }
        if truth_by_id is not None and vid in truth_by_id.index:
            t = truth_by_id.loc[vid]
            declared = [d for d in str(t["deviations"] or "").split(";") if d and d != "nan"]
            effects = [
                f"{d}: {DEVIATION_EFFECT_ON_K[d]}" for d in declared if DEVIATION_EFFECT_ON_K.get(d)
            ]
            error = r["k"] - t["k"]
            agrees = bool(abs(error) <= max(r["u_k"], K_TOLERANCE_REL * t["k"]))
            notes = []
            if not r["usable"]:
                notes.append("window not steady: k not usable")
            if effects:
                notes.append("declared deviation affecting the static test: " + " | ".join(effects))
            elif not agrees:
                notes.append("disagrees with the truth and no declared deviation explains it")
            note = "; ".join(notes)
            row |= {
                "k_truth": float(t["k"]),
                "rel_error": float(error / t["k"]),
                "agrees": agrees,
                "deviations": ";".join(declared),
                "note": note,
            }
        rows.append(row)
    return pd.DataFrame(rows)


PARAMETERS = ("kA", "C_bar", "C", "K_veh", "C_veh")
# Recovery tolerance of the second-order estimates against the campaign's truth (issue 4).
RECOVERY_TOLERANCE = {"C": 0.05, "K_veh": 0.10, "C_veh": 0.05}


def fit_table(fits: list[Mapping[str, Any]], truth: pd.DataFrame | None = None) -> pd.DataFrame:
    """One row per vehicle and model order: verdict, R^2 (eq. 21), NRMSE fit, how k was
    obtained, every parameter with its 95 % interval, the flags; and, for second-order fits of
    campaign vehicles, the truth, the relative error and whether the estimate is recovered
    (within 5 % for C and C_veh, 10 % for K_veh, or the truth inside the 95 % interval)."""
    truth_by_id = truth.set_index("vehicle") if truth is not None else None
    rows = []
    for fit in fits:
        row: dict[str, Any] = {
            "vehicle": fit["vehicle"],
            "order": fit["order"],
            "verdict": fit["verdict"],
            "R2": fit["R2"],
            "nrmse_fit": fit["nrmse_fit"],
            "k_source": fit["k_source"],
        }
        for p in PARAMETERS:
            entry = fit["parameters"].get(p, {})
            lo, hi = entry.get("ci95", (None, None))
            row |= {p: entry.get("value"), f"{p}_lo": lo, f"{p}_hi": hi}
        row["flags"] = ";".join(sorted({f["code"] for f in fit["flags"]}))
        known = truth_by_id is not None and fit["vehicle"] in truth_by_id.index
        if known and fit["order"] == 2:
            t = truth_by_id.loc[fit["vehicle"]]
            row["deviations"] = "" if pd.isna(t["deviations"]) else t["deviations"]
            for p, tol in RECOVERY_TOLERANCE.items():
                error = row[p] / t[p] - 1.0
                inside = row[f"{p}_lo"] is not None and row[f"{p}_lo"] <= t[p] <= row[f"{p}_hi"]
                row |= {
                    f"{p}_truth": float(t[p]),
                    f"{p}_rel_error": float(error),
                    f"{p}_recovered": bool(abs(error) <= tol or inside),
                }
        rows.append(row)
    return pd.DataFrame(rows)


def model_table(fits: list[Mapping[str, Any]], source: str) -> pd.DataFrame:
    """Every fitted model of every vehicle side by side (rule compare_models): the overall
    heat-loss coefficient kA with its 95 % interval and how it was obtained, and the measures of
    the simulated T (the one output every structure shares): R^2 (eq. 21), NRMSE fit, RMSE,
    AIC and BIC (with the model's unknowns, initial states included), the Ljung-Box whiteness
    p-value and the residuals' effective sample count; ``best_aic``/``best_bic`` mark each
    vehicle's preferred model."""
    rows = []
    for fit in fits:
        T = fit["measures"]["T"]["overall"]
        kA = fit["parameters"].get("kA", {})
        lo, hi = kA.get("ci95", (None, None))
        rows.append(
            {
                "vehicle": fit["vehicle"],
                "model": fit["model"],
                "structure": fit["structure"],
                "k_source": fit["k_source"],
                "kA": kA.get("value"),
                "kA_lo": lo,
                "kA_hi": hi,
                "unknowns": T["p"],
                "R2": T["r2"],
                "nrmse_fit": T["nrmse_fit"],
                "rmse_K": T["rmse"],
                "aic": T["aic"],
                "bic": T["bic"],
                "ljung_box_p": T["ljung_box_p"],
                "effective_samples": T["effective_samples"],
                "verdict": fit["verdict"],
                "source": source,
            }
        )
    df = pd.DataFrame(rows)
    for criterion in ("aic", "bic"):
        best = df.groupby("vehicle", sort=False)[criterion].transform("min")
        df.insert(df.columns.get_loc("ljung_box_p"), f"best_{criterion}", df[criterion] == best)
    return df


def model_markdown(df: pd.DataFrame, source: str) -> str:
    """The model comparison for readers."""

    def ka(r) -> str:
        if r.kA is None or not math.isfinite(r.kA):
            return "–"
        if r.kA_lo is None or not math.isfinite(r.kA_lo):
            return f"{r.kA:.1f}"
        return f"{r.kA:.1f} [{r.kA_lo:.1f}, {r.kA_hi:.1f}]"

    view = pd.DataFrame(
        {
            "vehicle": df["vehicle"],
            "model": df["structure"],
            "kA (W/K)": [ka(r) for r in df.itertuples()],
            "k from": df["k_source"],
            "R² (1)": [f"{x:.3f}" for x in df["R2"]],
            "NRMSE fit (1)": [f"{x:.3f}" for x in df["nrmse_fit"]],
            "RMSE (K)": [f"{x:.3f}" for x in df["rmse_K"]],
            "AIC": [
                f"{x:.1f}" + (" ◀" if b else "")
                for x, b in zip(df["aic"], df["best_aic"], strict=True)
            ],
            "BIC": [
                f"{x:.1f}" + (" ◀" if b else "")
                for x, b in zip(df["bic"], df["best_bic"], strict=True)
            ],
            "Ljung-Box p": [f"{x:.3g}" for x in df["ljung_box_p"]],
            "verdict": df["verdict"],
        }
    )
    return "\n".join(
        [
            f"**Models compared per vehicle (simulated T).** Data: {source}.",
            "",
            view.to_markdown(index=False, disable_numparse=True),
            "",
            "- ◀: the vehicle's lowest AIC / BIC. NRMSE fit = 1 - ||y - ŷ|| / ||y - mean(y)|| "
            "(MATLAB's compare, pySIP), not R^2 (eq. 21). kA of the interior-envelope model is "
            "K_i K_o / (K_i + K_o), its interval by the delta method.",
            "",
        ]
    )


# ----------------------------------------------------------------------------------------------
# the study's tables (paper section 6)

CLASS_ORDER = ("tram", "metro", "regional", "main-line", "other")
CLASS_LABEL = {
    "tram": "Tram",
    "metro": "Metro",
    "regional": "Regional",
    "main-line": "Main-line",
    "other": "Other",
}
Z95 = 1.959963984540054
SYNTHETIC_SOURCE = "synthetic: virtual climatic wind tunnel campaign (not measurements)"
MEASURED_SOURCE = "measured"
ACCEPTABLE = "fit acceptable"
BOOTSTRAP_RESAMPLES = 10_000
BOOTSTRAP_SEED = 20_150_302


def data_source(vehicles: Mapping[str, Mapping[str, Any]]) -> str:
    """One line naming where a table's rows come from: synthetic, measured or both."""
    synthetic = {bool(v.get("synthetic", False)) for v in vehicles.values()}
    if synthetic == {True}:
        return SYNTHETIC_SOURCE
    if synthetic == {False}:
        return MEASURED_SOURCE
    names = sorted(vid for vid, v in vehicles.items() if v.get("synthetic", False))
    return f"mixed: {', '.join(names)} synthetic (virtual climatic wind tunnel), the rest measured"


def _interval(entry: Mapping[str, Any]) -> tuple[float, float]:
    lo, hi = entry.get("ci95", (math.nan, math.nan))
    return float(lo), float(hi)


def table2(
    fits: Mapping[str, Mapping[str, Any]],
    kvalues: Mapping[str, Mapping[str, Any] | None],
    vehicles: Mapping[str, Mapping[str, Any]],
) -> pd.DataFrame:
    """Table 2: per vehicle k (W/(m^2 K)), C (J/K), K_veh (W/K), C_veh (J/K) and R^2 (eq. 21) of
    the second-order model, each estimate with its 95 % interval, the verdict and how k was
    obtained. Rows in the order of ``vehicles`` (the study config's order).

    ``fits``: vehicle -> its fit_order2.yaml; ``kvalues``: vehicle -> its kvalue.yaml (or None);
    ``vehicles``: vehicle -> its config. k from the static test carries k +- 2 u(k) (expanded
    uncertainty, coverage factor 2, as the k table); k from joint estimation kA / A with kA's
    interval. C, K_veh, C_veh intervals are the combined ones (statistical and systematic)."""
    rows = []
    for vid, vehicle in vehicles.items():
        fit = fits[vid]
        params = fit["parameters"]
        A = float(vehicle["surface_m2"])
        kv = kvalues.get(vid)
        if params["kA"]["estimated"] or kv is None:
            lo, hi = _interval(params["kA"])
            k, k_lo, k_hi = params["kA"]["value"] / A, lo / A, hi / A
        else:
            k = float(kv["k"])
            k_lo, k_hi = k - COVERAGE_FACTOR * kv["u_k"], k + COVERAGE_FACTOR * kv["u_k"]
        row: dict[str, Any] = {
            "vehicle": vid,
            "class": vehicle["class"],
            "k": k,
            "k_lo": k_lo,
            "k_hi": k_hi,
            "k_source": fit["k_source"],
        }
        for p in ("C", "K_veh", "C_veh"):
            lo, hi = _interval(params[p])
            row |= {p: float(params[p]["value"]), f"{p}_lo": lo, f"{p}_hi": hi}
        row |= {
            "R2": float(fit["R2"]),
            "verdict": fit["verdict"],
            "source": SYNTHETIC_SOURCE if vehicle.get("synthetic", False) else MEASURED_SOURCE,
        }
        rows.append(row)
    return pd.DataFrame(rows)


def _sd_log_ratio(fit: Mapping[str, Any], num: str, den: str) -> float:
    """sd of log(num / den): statistical part from the fit's sd_log and correlation, systematic
    part from the signed effects of each type-B source (a source shifts both at once)."""
    params = fit["parameters"]
    free = list(fit["free"])
    corr = np.asarray(fit["correlation"], dtype=float)
    sd_n, sd_d = float(params[num]["sd_log"]), float(params[den]["sd_log"])
    rho = corr[free.index(num), free.index(den)]
    rho = 0.0 if not np.isfinite(rho) else float(rho)
    var = sd_n**2 + sd_d**2 - 2.0 * rho * sd_n * sd_d
    effects = fit.get("systematic", {}).get("effects_log", {})
    e_n, e_d = effects.get(num, {}), effects.get(den, {})
    for source in sorted(set(e_n) | set(e_d)):  # fixed order: the same bits every run
        var += (float(e_n.get(source, 0.0)) - float(e_d.get(source, 0.0))) ** 2
    return math.sqrt(max(var, 0.0))


def table3(
    t2: pd.DataFrame,
    fits: Mapping[str, Mapping[str, Any]],
    vehicles: Mapping[str, Mapping[str, Any]],
) -> pd.DataFrame:
    """Table 3: c_veh = C_veh / m_veh (eq. 24, J/(kg K)) and delta = C_veh / C (eq. 25) with
    95 % intervals. c_veh takes C_veh's interval (the mass is taken as exact); delta's
    interval is exp(log delta +- 1.96 sd), sd combining the statistical variances and the
    correlation of log C and log C_veh with the systematic effects of each source on both."""
    rows = []
    for _, r in t2.iterrows():
        vid = r["vehicle"]
        m = float(vehicles[vid]["mass_kg"])
        delta = r["C_veh"] / r["C"]
        sd = _sd_log_ratio(fits[vid], "C_veh", "C")
        with np.errstate(over="ignore"):
            d_lo, d_hi = float(delta * np.exp(-Z95 * sd)), float(delta * np.exp(Z95 * sd))
        rows.append(
            {
                "vehicle": vid,
                "class": r["class"],
                "m_veh": m,
                "c_veh": r["C_veh"] / m,
                "c_veh_lo": r["C_veh_lo"] / m,
                "c_veh_hi": r["C_veh_hi"] / m,
                "delta": delta,
                "delta_lo": d_lo,
                "delta_hi": d_hi,
                "verdict": r["verdict"],
                "source": r["source"],
            }
        )
    return pd.DataFrame(rows)


def table1(
    vehicles: Mapping[str, Mapping[str, Any]],
    kvalues: Mapping[str, Mapping[str, Any] | None],
    fits: Mapping[str, Mapping[str, Any]],
) -> pd.DataFrame:
    """Table 1: per class, how many vehicles had a static k test, how many of those were
    steady (usable), how many identification experiments (windows) were available, and how
    many vehicles' second-order fits could be evaluated (verdict "fit acceptable"); a Sum
    column. Counted from the configs and the verdicts."""
    classes = [c for c in CLASS_ORDER if any(v["class"] == c for v in vehicles.values())]
    counts: dict[str, dict[str, int]] = {}
    for c in classes:
        ids = [vid for vid, v in vehicles.items() if v["class"] == c]
        counts[c] = {
            "k value measured": sum(kvalues.get(vid) is not None for vid in ids),
            "k value usable (steady window)": sum(
                bool(kvalues.get(vid) and kvalues[vid]["usable"]) for vid in ids
            ),
            "experiments available": sum(
                len(vehicles[vid]["windows"]["identification"]) for vid in ids
            ),
            "vehicles evaluated (fit acceptable)": sum(
                fits[vid]["verdict"] == ACCEPTABLE for vid in ids
            ),
        }
    rows = []
    for quantity in next(iter(counts.values())) if counts else []:
        row = {"quantity": quantity}
        row |= {CLASS_LABEL[c]: counts[c][quantity] for c in classes}
        row["Sum"] = sum(counts[c][quantity] for c in classes)
        rows.append(row)
    return pd.DataFrame(rows)


def _bootstrap_mean_ci(values: np.ndarray, seed: int) -> tuple[float, float]:
    if len(values) < 3:  # two points resample to three distinct means: no interval
        return math.nan, math.nan
    res = stats.bootstrap(
        (values,),
        np.mean,
        n_resamples=BOOTSTRAP_RESAMPLES,
        confidence_level=0.95,
        method="percentile",
        rng=np.random.default_rng(seed),
    )
    return float(res.confidence_interval.low), float(res.confidence_interval.high)


SELECTIONS = {
    "all vehicles (as the paper)": lambda t3: t3,
    "fit acceptable only": lambda t3: t3[t3["verdict"] == ACCEPTABLE],
}


def class_summary(t3: pd.DataFrame) -> pd.DataFrame:
    """Per selection (every vehicle, as the paper; only fits judged acceptable), class and
    quantity (c_veh, delta): n, mean, median, sample sd, min, max and a percentile bootstrap
    95 % interval of the mean (10,000 resamples, fixed seed; none for n < 3)."""
    rows = []
    for selection, pick in SELECTIONS.items():
        sub = pick(t3)
        for c in CLASS_ORDER:
            part = sub[sub["class"] == c]
            if part.empty:
                continue
            for q in ("c_veh", "delta"):
                x = part[q].to_numpy(dtype=float)
                lo, hi = _bootstrap_mean_ci(x, BOOTSTRAP_SEED)
                rows.append(
                    {
                        "selection": selection,
                        "class": c,
                        "quantity": q,
                        "n": len(x),
                        "mean": float(x.mean()),
                        "median": float(np.median(x)),
                        "sd": float(x.std(ddof=1)) if len(x) > 1 else math.nan,
                        "min": float(x.min()),
                        "max": float(x.max()),
                        "mean_ci_lo": lo,
                        "mean_ci_hi": hi,
                        "vehicles": ";".join(part["vehicle"]),
                    }
                )
    return pd.DataFrame(rows)


def class_test(
    t3: pd.DataFrame,
    quantity: str = "c_veh",
    groups: Sequence[str] = ("metro", "regional"),
    alpha: float = 0.05,
) -> pd.DataFrame:
    """The paper's open question (section 6.3): do metros and regional trains differ in c_veh?
    Welch's t-test and the Mann-Whitney U test (two-sided, exact for small samples), per
    selection of vehicles, with the p-values and a plain conclusion at level ``alpha``."""
    a_name, b_name = groups
    rows = []
    for selection, pick in SELECTIONS.items():
        sub = pick(t3)
        a = sub.loc[sub["class"] == a_name, quantity].to_numpy(dtype=float)
        b = sub.loc[sub["class"] == b_name, quantity].to_numpy(dtype=float)
        row: dict[str, Any] = {
            "selection": selection,
            "quantity": quantity,
            "group_a": a_name,
            "group_b": b_name,
            "n_a": len(a),
            "n_b": len(b),
            "mean_a": float(a.mean()) if len(a) else math.nan,
            "mean_b": float(b.mean()) if len(b) else math.nan,
        }
        if len(a) >= 2 and len(b) >= 2:
            welch = stats.ttest_ind(a, b, equal_var=False)
            mwu = stats.mannwhitneyu(a, b, alternative="two-sided", method="exact")
            p_w, p_u = float(welch.pvalue), float(mwu.pvalue)
            significant = [n for n, p in (("Welch", p_w), ("Mann-Whitney", p_u)) if p < alpha]
            if len(significant) == 2:
                conclusion = f"differ: both tests significant at {alpha:g}"
            elif significant:
                conclusion = (
                    f"inconclusive: only {significant[0]} significant at {alpha:g} "
                    f"(n = {len(a)} and {len(b)})"
                )
            else:
                conclusion = (
                    f"no significant difference at {alpha:g} (n = {len(a)} and {len(b)}): "
                    "the data cannot show that the classes differ"
                )
            row |= {
                "welch_t": float(welch.statistic),
                "welch_p": p_w,
                "mannwhitney_U": float(mwu.statistic),
                "mannwhitney_p": p_u,
                "conclusion": conclusion,
            }
        else:
            row |= {
                "welch_t": math.nan,
                "welch_p": math.nan,
                "mannwhitney_U": math.nan,
                "mannwhitney_p": math.nan,
                "conclusion": "too few vehicles in a group (fewer than 2) to test",
            }
        rows.append(row)
    return pd.DataFrame(rows)


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


def _plain(x: float, decimals: int, thousands: bool = False) -> str:
    if not math.isfinite(x):
        return "∞"
    return f"{x:,.{decimals}f}" if thousands else f"{x:.{decimals}f}"


UNBOUNDED_FACTOR = 1e3  # an interval limit this far from the value prints as 0 or ∞


def _delta(x: float, decimals: int = 2) -> str:
    """delta as the paper prints it: two decimals, three significant digits from 10 up."""
    if not math.isfinite(x):
        return "∞"
    return f"{x:.{decimals}f}" if abs(x) < 10 else f"{x:.3g}" if abs(x) < 1000 else f"{x:,.0f}"


def _limits(x: float, lo: float, hi: float) -> tuple[float, float]:
    """Interval limits beyond a factor 1e3 of the value become 0 and ∞: the data do not bound
    the parameter there (printing 6e45 would suggest otherwise)."""
    lo = 0.0 if not (math.isfinite(lo) and lo > x / UNBOUNDED_FACTOR) else lo
    hi = math.inf if not (math.isfinite(hi) and hi < x * UNBOUNDED_FACTOR) else hi
    return lo, hi


def _value_interval(kind: str, x: float, lo: float, hi: float, tex: bool) -> str:
    """A value as the paper prints it, its 95 % interval in brackets (one digit more; an
    interval in the value's power of ten for the 1.8x10^7 kind; 0 and ∞ for limits the data
    do not set)."""
    lo, hi = _limits(x, lo, hi)
    if kind == "sci":
        text, e = _sci(x, tex)
        inner = ", ".join("0" if lim == 0 else _plain(lim / 10.0**e, 2) for lim in (lo, hi))
        text = f"{text} [{inner}]{_power(e, tex)}"
        return f"${text}$".replace("∞", "\\infty") if tex else text
    if kind == "delta":
        return f"{_delta(x)} [{'0' if lo == 0 else _delta(lo, 3)}, {_delta(hi, 3)}]"
    decimals, thousands = {"k": (1, False), "int": (0, True)}[kind]
    more = decimals + 1 if kind == "k" else decimals
    return (
        f"{_plain(x, decimals, thousands)} "
        f"[{'0' if lo == 0 else _plain(lo, more, thousands)}, {_plain(hi, more, thousands)}]"
    )


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


def _intervals(df: pd.DataFrame, q: str, kind: str, tex: bool) -> list[str]:
    """Column ``q`` with its 95 % interval (columns ``q_lo``, ``q_hi``), printed as ``kind``."""
    return [
        _value_interval(kind, x, lo, hi, tex)
        for x, lo, hi in zip(df[q], df[f"{q}_lo"], df[f"{q}_hi"], strict=True)
    ]


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
                "R² (1)": [f"{x:.3f}" for x in df["R2"]],
                "verdict": df["verdict"].map(esc),
                "k from": df["k_source"].map(esc),
            }
        )
    if name == "table3":
        return pd.DataFrame(
            {
                "Name": df["vehicle"].map(esc),
                "class": df["class"].map(esc),
                "m_veh (t)": [f"{m / 1000:.1f}" for m in df["m_veh"]],
                "c_veh (J/(kg K))": _intervals(df, "c_veh", "int", tex),
                "δ (1)": _intervals(df, "delta", "delta", tex),
                "verdict": df["verdict"].map(esc),
            }
        )
    if name == "class_summary":

        def num(q, x):
            return _plain(x, 0, True) if q == "c_veh" else _delta(x)

        return pd.DataFrame(
            {
                "selection": df["selection"].map(esc),
                "class": df["class"].map(esc),
                "quantity": df["quantity"].map(esc),
                "n": df["n"].astype(str),
                "mean": [num(r.quantity, r.mean) for r in df.itertuples()],
                "95 % CI of the mean (bootstrap)": [
                    "–"
                    if not math.isfinite(r.mean_ci_lo)
                    else f"[{num(r.quantity, r.mean_ci_lo)}, {num(r.quantity, r.mean_ci_hi)}]"
                    for r in df.itertuples()
                ],
                "median": [num(r.quantity, r.median) for r in df.itertuples()],
                "sd": [
                    "–" if not math.isfinite(r.sd) else num(r.quantity, r.sd)
                    for r in df.itertuples()
                ],
                "range": [
                    f"{num(r.quantity, r.min)} – {num(r.quantity, r.max)}" for r in df.itertuples()
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
                "means": [f"{r.mean_a:.0f} vs {r.mean_b:.0f}" for r in df.itertuples()],
                "Welch p": [f"{p:.3f}" if math.isfinite(p) else "–" for p in df["welch_p"]],
                "Mann-Whitney p": [
                    f"{p:.3f}" if math.isfinite(p) else "–" for p in df["mannwhitney_p"]
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
    "table1": "Table 1. Available and evaluated experiments per vehicle class.",
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
NOTES = {
    "table1": [
        "k value measured: vehicles with a static k window; usable: the window passed the "
        "steady-state test; experiments available: identification windows in the configs; "
        "evaluated: second-order fits with the verdict 'fit acceptable' (results/vehicles/"
        "<id>/fit_order2.yaml gives the reasons for the others).",
    ],
    "table2": [
        "k: the static test (eq. 10) with k ± 2 u(k), or kA / A estimated jointly when the "
        "static k was not usable ('k from').",
        "C, K_veh, C_veh: simulation-error PEM (eqs. 15-20); intervals combine the statistical "
        "(HAC) and the systematic (GUM type B) uncertainty; a limit shown as 0 or ∞ lies beyond "
        "a factor 1000 of the estimate (the data do not bound it). R²: eq. 21 for T.",
        "Verdict: results/vehicles/<id>/fit_order2.yaml lists the reasons.",
    ],
    "table3": [
        "c_veh takes C_veh's interval (the mass m_veh is taken as exact); δ's interval "
        "accounts for the correlation of C and C_veh and for systematic errors that move both.",
    ],
    "class_summary": [
        "Bootstrap: percentile interval of the class mean, 10,000 resamples, fixed seed; none "
        "for fewer than 3 vehicles. 'all vehicles' includes fits in doubt, as the paper's "
        "Figure 5 does.",
    ],
    "class_test": [
        "Welch's t-test and the exact two-sided Mann-Whitney U test at the 5 % level.",
    ],
}
SYNTHETIC_NOTE = (
    "These re-estimates come from the synthetic campaign, whose ground truth was set from the "
    "paper's published values: they test the method and reproduce the published pattern; "
    "they are not evidence about real vehicles."
)


def study_tables(
    fits: Mapping[str, Mapping[str, Any]],
    kvalues: Mapping[str, Mapping[str, Any] | None],
    vehicles: Mapping[str, Mapping[str, Any]],
    class_test_groups: Sequence[str] = ("metro", "regional"),
) -> dict[str, pd.DataFrame]:
    """Tables 1-3, the class summary and the class test from the second-order fits."""
    t2 = table2(fits, kvalues, vehicles)
    t3 = table3(t2, fits, vehicles)
    return {
        "table1": table1(vehicles, kvalues, fits),
        "table2": t2,
        "table3": t3,
        "class_summary": class_summary(t3),
        "class_test": class_test(t3, "c_veh", tuple(class_test_groups)),
    }


def write_study_tables(
    tables: Mapping[str, pd.DataFrame], source: str, paths: Mapping[str, str]
) -> None:
    """Each table as CSV (full precision, a ``source`` column), Markdown and LaTeX (formatted
    as the paper, the source in the caption); ``paths`` maps "<name>_<csv|md|tex>" to files."""
    for name, df in tables.items():
        df = df.copy()
        if "source" not in df.columns:
            df["source"] = source
        df.to_csv(paths[f"{name}_csv"], index=False)
        notes = NOTES[name] + ([SYNTHETIC_NOTE] if source == SYNTHETIC_SOURCE else [])
        with open(paths[f"{name}_md"], "w", encoding="utf-8") as stream:
            stream.write(to_markdown(name, df, CAPTIONS[name], source, notes))
        with open(paths[f"{name}_tex"], "w", encoding="utf-8") as stream:
            stream.write(to_latex(name, df, CAPTIONS[name], source, f"tab:{name}"))
