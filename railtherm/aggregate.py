"""Tables over all vehicles: the k values, every fit, and the study's Tables 1-3 with the class
statistics (paper section 6), each with 95 % intervals and the source of its data.

Formatting for readers (:func:`to_markdown`, :func:`to_latex`) follows the paper's tables:
k with two decimals, C and C_veh as 1.8x10^7, K_veh as an integer with thousands separators,
R^2 with three decimals, c_veh as an integer and delta with two decimals; intervals in
brackets beside the value. The CSV files hold the numbers at six significant digits
(railtherm.tables).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from railtherm import pem
from railtherm.metrics import ACCEPTABLE
from railtherm.smallsample import t_interval, two_class_test
from railtherm.tables import round_significant, write_csv
from railtherm.yamlio import packaged_schema

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
            effects = str(t["k_effects"]) if pd.notna(t["k_effects"]) else ""
            error = r["k"] - t["k"]
            agrees = bool(abs(error) <= max(r["u_k"], K_TOLERANCE_REL * t["k"]))
            notes = []
            if not r["usable"]:
                notes.append("window not steady: k not usable")
            if effects:
                notes.append("declared deviation affecting the static test: " + effects)
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
# Recovery tolerance of the second-order estimates against the campaign's truth.
RECOVERY_TOLERANCE = {"C": 0.05, "K_veh": 0.10, "C_veh": 0.05}


def fit_table(fits: list[Mapping[str, Any]], truth: pd.DataFrame | None = None) -> pd.DataFrame:
    """One row per vehicle and model order: verdict, R^2 (eq. 21), NRMSE fit, how k was
    obtained, every parameter with its 95 % interval, the flags; and, for second-order fits of
    campaign vehicles, the truth, the relative error and whether the estimate is recovered
    (within 5 % for C and C_veh, 10 % for K_veh, or the truth inside the 95 % interval). A
    parameter the data do not determine has no value there (``<p>_status`` says why) and is
    never recovered: a comparison with the truth needs a bounded interval."""
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
            entry = fit["parameters"].get(p)
            if entry is None:
                row |= {p: math.nan, f"{p}_lo": math.nan, f"{p}_hi": math.nan, f"{p}_status": ""}
            elif not entry.get("estimated"):  # held fixed (kA from the static test)
                value = float(entry["value"])
                row |= {p: value, f"{p}_lo": math.nan, f"{p}_hi": math.nan, f"{p}_status": "fixed"}
            else:
                judged = pem.parameter_identification(entry)
                q = quantity(entry["value"], entry["ci95"], judged)
                row |= {f"{p}{suffix}": q[suffix] for suffix in ("", "_lo", "_hi", "_status")}
        row["flags"] = ";".join(sorted({f["code"] for f in fit["flags"]}))
        known = truth_by_id is not None and fit["vehicle"] in truth_by_id.index
        if known and fit["order"] == 2:
            t = truth_by_id.loc[fit["vehicle"]]
            row["deviations"] = "" if pd.isna(t["deviations"]) else t["deviations"]
            for p, tol in RECOVERY_TOLERANCE.items():
                # only an identified estimate can be recovered: a bounded interval is needed
                error = row[p] / t[p] - 1.0
                inside = row[f"{p}_lo"] <= t[p] <= row[f"{p}_hi"]
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
        if kA.get("estimated"):
            q = quantity(kA["value"], kA["ci95"], pem.parameter_identification(kA))
        else:  # fixed from the static test
            q = {"": kA.get("value", math.nan), "_lo": math.nan, "_hi": math.nan}
            q["_status"] = "fixed" if kA else ""
        rows.append(
            {
                "vehicle": fit["vehicle"],
                "model": fit["model"],
                "structure": fit["structure"],
                "k_source": fit["k_source"],
                "kA": q[""],
                "kA_lo": q["_lo"],
                "kA_hi": q["_hi"],
                "kA_status": q["_status"],
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

# the vehicle classes in the order of the paper's tables: the vehicle schema's list
CLASS_ORDER = tuple(packaged_schema("vehicle")["properties"]["class"]["enum"])
CLASS_LABEL = {
    "tram": "Tram",
    "metro": "Metro",
    "regional": "Regional",
    "main-line": "Main-line",
    "other": "Other",
}
Z95 = pem.Z95
SYNTHETIC_SOURCE = "synthetic: virtual climatic wind tunnel campaign (not measurements)"
MEASURED_SOURCE = "measured"
ESTIMATED = "estimated"


def data_source(vehicles: Mapping[str, Mapping[str, Any]]) -> str:
    """One line naming where a table's rows come from: synthetic, measured or both."""
    synthetic = {bool(v.get("synthetic", False)) for v in vehicles.values()}
    if synthetic == {True}:
        return SYNTHETIC_SOURCE
    if synthetic == {False}:
        return MEASURED_SOURCE
    names = sorted(vid for vid, v in vehicles.items() if v.get("synthetic", False))
    return f"mixed: {', '.join(names)} synthetic (virtual climatic wind tunnel), the rest measured"


def class_order(classes: Sequence[str]) -> list[str]:
    """The classes present: the paper's order (tram, metro, regional, main-line) first, then
    any other in order of appearance."""
    present = list(dict.fromkeys(str(c) for c in classes))
    return [c for c in CLASS_ORDER if c in present] + [c for c in present if c not in CLASS_ORDER]


def by_class(vehicles: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """Vehicle ids grouped by class in :func:`class_order`, the config's order within a class:
    a vehicle added at the end of the config lands among its class."""
    order = class_order([v["class"] for v in vehicles.values()])
    return sorted(vehicles, key=lambda vid: order.index(str(vehicles[vid]["class"])))


# --- values the data determine, and those they do not ----------------------------------------


def quantity(value: float, ci95: Sequence[float], judged: Mapping[str, Any]) -> dict[str, Any]:
    """The table columns of one quantity: ``q``, ``q_lo``, ``q_hi`` (NaN when not identified:
    such a value is never printed, averaged or compared as an estimate), ``q_status``
    ("estimated" or "not identified: <reason>"), and ``q_limit`` with ``q_limit_kind`` ("upper"
    / "lower" / "none"): the one-sided limit the data do give (railtherm.pem.identification)."""
    if judged.get("identified", True):
        lo, hi = (float(c) for c in ci95)
        return {"": float(value), "_lo": lo, "_hi": hi, "_status": ESTIMATED}
    limit = judged.get("limit_value")
    return {
        "": math.nan,
        "_lo": math.nan,
        "_hi": math.nan,
        "_status": f"not identified: {judged['reason']}",
        "_limit": math.nan if limit is None else float(limit),
        "_limit_kind": judged["limit"],
    }


def _columns(name: str, q: Mapping[str, Any]) -> dict[str, Any]:
    out = {f"{name}{suffix}": v for suffix, v in q.items()}
    out.setdefault(f"{name}_limit", math.nan)
    out.setdefault(f"{name}_limit_kind", "")
    return out


_FLIP = {"upper": "lower", "lower": "upper", "point": "point", "none": "none"}


def _ratio_limit(num: tuple[str, float], den: tuple[str, float]) -> tuple[str, float]:
    """What num / den is known to be when a part is only a one-sided limit: ("point", x) for
    an estimate, ("upper", b) for "at most b", ("lower", b), ("none", nan). An upper limit of
    the denominator is a lower limit of the ratio; limits of opposite kinds give none."""
    kinds = {num[0], _FLIP[den[0]]} - {"point"}
    if "none" in kinds or len(kinds) > 1:
        return "none", math.nan
    return (kinds.pop() if kinds else "point"), num[1] / den[1]


def _part(entry: Mapping[str, Any]) -> tuple[str, float]:
    judged = pem.parameter_identification(entry)
    if judged.get("identified", True):
        return "point", float(entry["value"])
    limit = judged.get("limit_value")
    return judged["limit"], math.nan if limit is None else float(limit)


def table2(
    fits: Mapping[str, Mapping[str, Any]],
    kvalues: Mapping[str, Mapping[str, Any] | None],
    vehicles: Mapping[str, Mapping[str, Any]],
) -> pd.DataFrame:
    """Table 2: per vehicle k (W/(m^2 K)), C (J/K), K_veh (W/K), C_veh (J/K) and R^2 (eq. 21) of
    the second-order model, each estimate with its 95 % interval and its status, the verdict
    and how k was obtained. Rows by class (tram, metro, regional, main-line, then others),
    within a class in the order of ``vehicles`` (the study config's order).

    ``fits``: vehicle -> its fit_order2.yaml; ``kvalues``: vehicle -> its kvalue.yaml (or None);
    ``vehicles``: vehicle -> its config. k from the static test carries k +- 2 u(k) (expanded
    uncertainty, coverage factor 2, as the k table); k from joint estimation kA / A with kA's
    interval. C, K_veh, C_veh intervals are the combined ones (statistical and systematic); a
    parameter the data do not determine has no value, its status and its one-sided limit
    (:func:`quantity`)."""
    rows = []
    for vid in by_class(vehicles):
        vehicle, fit = vehicles[vid], fits[vid]
        params = fit["parameters"]
        A = float(vehicle["surface_m2"])
        kv = kvalues.get(vid)
        if params["kA"]["estimated"] or kv is None:
            entry = params["kA"]
            judged = dict(pem.parameter_identification(entry))
            if judged.get("limit_value") is not None:
                judged["limit_value"] = judged["limit_value"] / A
            ci = [c / A for c in entry.get("ci95", (math.nan, math.nan))]
            k = quantity(entry["value"] / A, ci, judged)
        else:
            U = COVERAGE_FACTOR * float(kv["u_k"])
            k = quantity(float(kv["k"]), (float(kv["k"]) - U, float(kv["k"]) + U), {})
        row: dict[str, Any] = {"vehicle": vid, "class": vehicle["class"]}
        row |= _columns("k", k)
        row["k_source"] = fit["k_source"]
        for p in ("C", "K_veh", "C_veh"):
            entry = params[p]
            row |= _columns(
                p, quantity(entry["value"], entry["ci95"], pem.parameter_identification(entry))
            )
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
    95 % intervals, in Table 2's row order. c_veh takes C_veh's interval (the mass is taken as
    exact); delta's interval is exp(log delta +- z_0.975 sd), sd combining the statistical
    variances and the correlation of log C and log C_veh with the systematic effects of each
    source on both. A ratio with a part the data do not determine is not identified either;
    its limit follows from the parts' (C at its lower bound: delta at least C_veh / bound)."""
    rows = []
    for vid, cls, verdict, source in zip(
        t2["vehicle"], t2["class"], t2["verdict"], t2["source"], strict=True
    ):
        fit = fits[vid]
        params = fit["parameters"]
        m = float(vehicles[vid]["mass_kg"])
        C_veh, C = params["C_veh"], params["C"]
        c_kind, c_value = _ratio_limit(_part(C_veh), ("point", m))
        if c_kind == "point":
            ci = [c / m for c in C_veh["ci95"]]
            c_veh = quantity(c_value, ci, pem.identification(c_value, ci))
        else:
            reason = f"C_veh {pem.parameter_identification(C_veh)['reason']}"
            judged = {"limit": c_kind, "limit_value": c_value, "reason": reason}
            c_veh = quantity(math.nan, (math.nan, math.nan), {"identified": False, **judged})
        d_kind, d_value = _ratio_limit(_part(C_veh), _part(C))
        if d_kind == "point":
            sd = _sd_log_ratio(fit, "C_veh", "C")
            with np.errstate(over="ignore"):
                ci = (float(d_value * np.exp(-Z95 * sd)), float(d_value * np.exp(Z95 * sd)))
            delta = quantity(d_value, ci, pem.identification(d_value, ci))
        else:
            why = "; ".join(
                f"{p} {pem.parameter_identification(params[p])['reason']}"
                for p in ("C", "C_veh")
                if not pem.parameter_identification(params[p]).get("identified", True)
            )
            judged = {"identified": False, "limit": d_kind, "reason": why}
            judged["limit_value"] = None if d_kind == "none" else d_value
            delta = quantity(math.nan, (math.nan, math.nan), judged)
        row = {"vehicle": vid, "class": cls, "m_veh": m}
        row |= _columns("c_veh", c_veh) | _columns("delta", delta)
        row |= {"verdict": verdict, "source": source}
        rows.append(row)
    return pd.DataFrame(rows)


def table1(
    vehicles: Mapping[str, Mapping[str, Any]],
    kvalues: Mapping[str, Mapping[str, Any] | None],
    fits: Mapping[str, Mapping[str, Any]],
) -> pd.DataFrame:
    """Table 1: per class, how many vehicles had a static k test, how many of those were
    steady (usable), how many identification windows the fits used, how many vehicles' C,
    K_veh and C_veh were all identified, and how many second-order fits could be evaluated
    (verdict "fit acceptable"); a Sum column. Counted from the configs and the fits."""
    classes = class_order([v["class"] for v in vehicles.values()])
    counts: dict[str, dict[str, int]] = {}
    for c in classes:
        ids = [vid for vid, v in vehicles.items() if v["class"] == c]
        counts[c] = {
            "vehicles with a k value measured": sum(kvalues.get(vid) is not None for vid in ids),
            "k value usable (steady window)": sum(
                bool(kvalues.get(vid) and kvalues[vid]["usable"]) for vid in ids
            ),
            "identification windows fitted": sum(
                len(vehicles[vid]["windows"]["identification"]) for vid in ids
            ),
            "vehicles with C, K_veh, C_veh identified": sum(
                all(
                    pem.parameter_identification(fits[vid]["parameters"][p]).get("identified", True)
                    for p in ("C", "K_veh", "C_veh")
                )
                for vid in ids
            ),
            "vehicles evaluated (fit acceptable)": sum(
                fits[vid]["verdict"] == ACCEPTABLE for vid in ids
            ),
        }
    rows = []
    for name in next(iter(counts.values())) if counts else []:
        row = {"quantity": name}
        row |= {CLASS_LABEL.get(c, c): counts[c][name] for c in classes}
        row["Sum"] = sum(counts[c][name] for c in classes)
        rows.append(row)
    return pd.DataFrame(rows)


# --- class statistics for a handful of vehicles ------------------------------------------------

SELECTIONS = {
    "every identified value": lambda t3: t3,
    "fit acceptable only": lambda t3: t3[t3["verdict"] == ACCEPTABLE],
}


def class_summary(t3: pd.DataFrame) -> pd.DataFrame:
    """Per selection (every identified value; only fits judged acceptable), class and quantity
    (c_veh, delta): n, mean with its 95 % t interval, the geometric mean with its t interval on
    the log scale (the natural centre of a ratio such as delta, whose values span decades),
    median, sample sd, min and max, the vehicles used and those left out because the data do
    not determine their value. A t interval (n - 1 degrees of freedom) is exact for normal
    data and honest at n = 2 (wide); a percentile bootstrap of 3 to 5 values returns little
    more than their range and covers far less than 95 %."""
    rows = []
    for selection, pick in SELECTIONS.items():
        sub = pick(t3)
        for c in class_order(sub["class"].tolist()):
            part = sub[sub["class"] == c]
            for q in ("c_veh", "delta"):
                ok = part[f"{q}_status"] == ESTIMATED if f"{q}_status" in part else part[q].notna()
                x = part.loc[ok, q].to_numpy(dtype=float)
                left_out = part.loc[~ok, "vehicle"].tolist()
                row = {"selection": selection, "class": c, "quantity": q, "n": int(x.size)}
                if x.size:
                    lo, hi = t_interval(x, positive=True)
                    glo, ghi = t_interval(np.log(x)) if np.all(x > 0) else (math.nan, math.nan)
                    geo = float(np.exp(np.log(x).mean())) if np.all(x > 0) else math.nan
                    row |= {
                        "mean": float(x.mean()),
                        "mean_ci_lo": lo,
                        "mean_ci_hi": hi,
                        "geometric_mean": geo,
                        "geometric_mean_ci_lo": math.exp(glo) if math.isfinite(glo) else math.nan,
                        "geometric_mean_ci_hi": math.exp(ghi) if math.isfinite(ghi) else math.nan,
                        "median": float(np.median(x)),
                        "sd": float(x.std(ddof=1)) if x.size > 1 else math.nan,
                        "min": float(x.min()),
                        "max": float(x.max()),
                    }
                row |= {
                    "vehicles": ";".join(part.loc[ok, "vehicle"]),
                    "not_identified": ";".join(left_out),
                }
                rows.append(row)
    columns = ["selection", "class", "quantity", "n", "mean", "mean_ci_lo", "mean_ci_hi"]
    columns += ["geometric_mean", "geometric_mean_ci_lo", "geometric_mean_ci_hi", "median"]
    columns += ["sd", "min", "max", "vehicles", "not_identified"]
    return pd.DataFrame(rows, columns=columns)


def class_test(
    t3: pd.DataFrame,
    quantity: str = "c_veh",
    groups: Sequence[str] = ("metro", "regional"),
    alpha: float = 0.05,
) -> pd.DataFrame:
    """The paper's open question (section 6.3): do metros and regional trains differ in c_veh?
    Per selection of vehicles (values the data do not determine left out): Welch's t-test
    (needs 2 vehicles per group) and the exact two-sided Mann-Whitney U test, each run only
    when it can reach significance at ``alpha`` - the exact test's smallest attainable p is
    2 / C(n_a + n_b, n_a) (railtherm.smallsample: 0.2 at 3 vs 2), so with fewer
    vehicles "no significant difference" would be certain before any data; the table says
    "too few vehicles to test" instead. A plain conclusion from the tests that ran."""
    a_name, b_name = groups
    rows = []
    for selection, pick in SELECTIONS.items():
        sub = pick(t3)
        if f"{quantity}_status" in sub:
            sub = sub[sub[f"{quantity}_status"] == ESTIMATED]
        a = sub.loc[sub["class"] == a_name, quantity].to_numpy(dtype=float)
        b = sub.loc[sub["class"] == b_name, quantity].to_numpy(dtype=float)
        test = two_class_test(a, b, alpha)
        nan = math.nan
        row: dict[str, Any] = {
            "selection": selection,
            "quantity": quantity,
            "group_a": a_name,
            "group_b": b_name,
            "n_a": len(a),
            "n_b": len(b),
            "mean_a": float(a.mean()) if len(a) else nan,
            "mean_b": float(b.mean()) if len(b) else nan,
            "welch_t": nan if test.welch_t is None else test.welch_t,
            "welch_p": nan if test.welch_p is None else test.welch_p,
            "mannwhitney_U": nan if test.mwu_u is None else test.mwu_u,
            "mannwhitney_p": nan if test.mwu_p is None else test.mwu_p,
            "mannwhitney_min_p": test.mwu_min_p,
        }
        ran, n = test.ran, f"n = {len(a)} and {len(b)}"
        significant = [name for name, p in ran.items() if p < alpha]
        if not ran:
            conclusion = f"too few vehicles to test ({n}: {'; '.join(test.not_run)})"
        elif len(significant) == len(ran):
            conclusion = f"differ: {' and '.join(ran)} significant at {alpha:g} ({n})"
        elif significant:
            conclusion = f"inconclusive: only {significant[0]} significant at {alpha:g} ({n})"
        else:
            conclusion = f"no significant difference at {alpha:g} ({n})"
        if ran and test.not_run:
            conclusion += f"; not run: {'; '.join(test.not_run)}"
        row["conclusion"] = conclusion
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


UNBOUNDED_FACTOR = pem.UNBOUNDED_FACTOR  # an interval limit this far prints as 0 or ∞


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


def _number(kind: str, x: float, tex: bool) -> str:
    """A single number as the paper prints its kind."""
    if kind == "sci":
        text = _sci(x, tex)[0]
        return f"${text}$" if tex else text
    if kind == "delta":
        return _delta(x)
    decimals, thousands = {"k": (2, False), "int": (0, True)}[kind]
    return _plain(x, decimals, thousands)


def _value_interval(kind: str, x: float, lo: float, hi: float, tex: bool) -> str:
    """A value as the paper prints it, its 95 % interval in brackets (an interval in the
    value's power of ten for the 1.8x10^7 kind; 0 and ∞ for limits the data do not set).
    k is printed with two decimals, as its interval: u(k) is about 1 % of k."""
    lo, hi = _limits(x, lo, hi)
    if kind == "sci":
        text, e = _sci(x, tex)
        inner = ", ".join("0" if lim == 0 else _plain(lim / 10.0**e, 2) for lim in (lo, hi))
        text = f"{text} [{inner}]{_power(e, tex)}"
        return f"${text}$".replace("∞", "\\infty") if tex else text
    if kind == "delta":
        return f"{_delta(x)} [{'0' if lo == 0 else _delta(lo, 3)}, {_delta(hi, 3)}]"
    decimals, thousands = {"k": (2, False), "int": (0, True)}[kind]
    return (
        f"{_plain(x, decimals, thousands)} "
        f"[{'0' if lo == 0 else _plain(lo, decimals, thousands)}, "
        f"{_plain(hi, decimals, thousands)}]"
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


def _intervals(df: pd.DataFrame, q: str, kind: str, tex: bool) -> list[str]:
    """Column ``q`` with its 95 % interval (columns ``q_lo``, ``q_hi``), printed as ``kind``;
    "not identified" with its limit where ``q_status`` says so."""
    out = []
    for _, r in df.iterrows():
        status = r.get(f"{q}_status", ESTIMATED)
        if isinstance(status, str) and status.startswith("not identified"):
            out.append(_not_identified(kind, r[f"{q}_limit"], r[f"{q}_limit_kind"], tex))
        else:
            out.append(_value_interval(kind, r[q], r[f"{q}_lo"], r[f"{q}_hi"], tex))
    return out


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
            if not math.isfinite(x):
                return "–"
            return _plain(x, 0, True) if q == "c_veh" else _delta(x)

        def centre(r):
            """c_veh: the mean (the paper's statistic); delta: the geometric mean."""
            if r.n == 0:
                return "–"
            key = "mean" if r.quantity == "c_veh" else "geometric_mean"
            x, lo, hi = getattr(r, key), getattr(r, f"{key}_ci_lo"), getattr(r, f"{key}_ci_hi")
            ci = f" [{num(r.quantity, lo)}, {num(r.quantity, hi)}]" if math.isfinite(lo) else ""
            return f"{num(r.quantity, x)}{ci}"

        return pd.DataFrame(
            {
                "selection": df["selection"].map(esc),
                "class": df["class"].map(esc),
                "quantity": df["quantity"].map(esc),
                "n": df["n"].astype(str),
                "mean or geometric mean [95 % t interval]": [centre(r) for r in df.itertuples()],
                "median": [num(r.quantity, r.median) for r in df.itertuples()],
                "sd": [num(r.quantity, r.sd) for r in df.itertuples()],
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
    "search, or its 95 % interval reaches beyond a factor 1000 of it; what the data do say is "
    "given as a one-sided limit (≤, ≥). Such a value is left out of every class statistic and "
    "comparison."
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
        "k: the static test (eq. 10) with k ± 2 u(k), or kA / A estimated jointly when the "
        "static k was not usable ('k from').",
        "C, K_veh, C_veh: simulation-error PEM (eqs. 15-20); intervals combine the statistical "
        "(HAC) and the systematic (GUM type B) uncertainty, each physical error source once "
        "through both stages. R²: eq. 21 for T.",
        NOT_IDENTIFIED_NOTE,
        "Verdict: results/vehicles/<id>/fit_order2.yaml lists the reasons.",
    ],
    "table3": [
        "c_veh takes C_veh's interval (the mass m_veh is taken as exact); δ's interval "
        "accounts for the correlation of C and C_veh and for systematic errors that move both. "
        "A ratio with a part the data do not determine is not identified either.",
        NOT_IDENTIFIED_NOTE,
    ],
    "class_summary": [
        "c_veh: the arithmetic mean (the paper's statistic); δ, a ratio whose values span "
        "decades: the geometric mean. Their 95 % intervals are t intervals (n - 1 degrees of "
        "freedom; for δ on the log scale; a lower end below 0 shown as 0), none for a single "
        "vehicle. With 2 to 5 vehicles a class mean is known only roughly: the intervals say "
        "how roughly.",
        "Values the data do not determine are left out and named; 'every identified value' "
        "also includes fits whose assumptions are in doubt, as the paper's Figure 5 does.",
    ],
    "class_test": [
        "Welch's t-test and the exact two-sided Mann-Whitney U test at the 5 % level, each run "
        "only when it can reach significance: the exact test's smallest p is "
        "2 / C(n_a + n_b, n_a) (0.2 at 3 vs 2).",
    ],
}
SYNTHETIC_NOTE = (
    "These re-estimates come from the synthetic campaign, whose ground truth was set from the "
    "paper's published values: they test the method (does railtherm recover what the data "
    "were made from?), and they are not evidence about real vehicles."
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
    """Each table as CSV (at ``tables.SIGNIFICANT_DIGITS`` significant digits, a ``source``
    column), Markdown and LaTeX (formatted as the paper from the same rounded numbers, the
    source in the caption); ``paths`` maps "<name>_<csv|md|tex>" to files."""
    for name, df in tables.items():
        df = round_significant(df)
        if "source" not in df.columns:
            df["source"] = source
        write_csv(df, paths[f"{name}_csv"])
        notes = NOTES[name] + ([SYNTHETIC_NOTE] if "synthetic" in source else [])
        with open(paths[f"{name}_md"], "w", encoding="utf-8") as stream:
            stream.write(to_markdown(name, df, CAPTIONS[name], source, notes))
        with open(paths[f"{name}_tex"], "w", encoding="utf-8") as stream:
            stream.write(to_latex(name, df, CAPTIONS[name], source, f"tab:{name}"))
