"""Tables over all vehicles: the k values, every fit, and the study's Tables 1-3 with the class
statistics (paper section 6), each with 95 % intervals and the source of its data.

Formatting for readers (:func:`to_markdown`, :func:`to_latex`) follows the paper's tables:
k with two decimals, C and C_veh as 1.8x10^7, K_veh as an integer with thousands separators,
R^2 with three decimals, c_veh as an integer and delta with two decimals; intervals in
brackets beside the value. The CSV files hold the numbers at six significant digits
(railtherm.report.tables).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from railtherm.estimation import models, pem
from railtherm.records import FitRecord, ParameterEstimate
from railtherm.study import identifiability
from railtherm.study.quality import ACCEPTABLE
from railtherm.study.smallsample import t_interval, two_class_test
from railtherm.yamlio import packaged_schema

COVERAGE_FACTOR = 2.0  # expanded uncertainty U = 2 u: about 95 % for a normal distribution
K_TOLERANCE_REL = 0.03  # agreement floor: within 3 % of the truth counts as agreeing


def kvalue_table(results: Mapping[str, Mapping[str, Any]], truth: pd.DataFrame | None = None):
    """One row per vehicle: the static k (eq. 10), u(k), the verdict, and the truth if known.

    ``results`` maps vehicle id -> the dict of its kvalue.yaml (railtherm.estimation.kvalue);
    ``truth`` is the campaign's ground_truth.csv (synthetic vehicles only). A vehicle agrees with
    its truth
    when |k - k_truth| <= max(u_k, 3 % k_truth) (u_k the standard uncertainty; U_k = 2 u_k, the
    expanded one, is listed too). ``note`` names the declared deviations that bias k, says when
    the window is not usable, and flags a disagreement that nothing declared explains;
    ``plausibility`` says when k lies outside ``check.k_range_W_m2K`` (a unit mistake), as
    the fit's verdict does.

    A vehicle without ``surface_m2`` (class other) has no k: its k, u_k and U_k are blank, and
    the table then gives every vehicle's ``kA``, ``u_kA`` and ``k_status`` ("estimated" or
    "not given: no surface_m2"); such a vehicle is compared with its truth by kA.
    """
    truth_by_id = truth.set_index("vehicle") if truth is not None else None
    without_surface = any(r.get("k") is None for r in results.values())
    rows = []
    for vid, r in results.items():
        given = r.get("k") is not None
        row = {
            "vehicle": vid,
            "method": "static (eq. 10)",
            "k": r["k"] if given else math.nan,
            "u_k": r["u_k"] if given else math.nan,
            "U_k": COVERAGE_FACTOR * r["u_k"] if given else math.nan,
        }
        if without_surface:
            row |= {
                "kA": float(r["kA"]),
                "u_kA": float(r.get("u_kA", r["u_k_rel"] * r["kA"])),
                "k_status": ESTIMATED if given else NOT_GIVEN["surface_m2"],
            }
        row |= {
            "steady": r["steady"],
            "forced": r["forced"],
            "usable": r["usable"],
            "reasons": "; ".join(r["reasons"]),
            "plausibility": "; ".join(r.get("plausibility") or []),
        }
        if truth_by_id is not None and vid in truth_by_id.index:
            t = truth_by_id.loc[vid]
            declared = [d for d in str(t["deviations"] or "").split(";") if d and d != "nan"]
            effects = str(t["k_effects"]) if pd.notna(t["k_effects"]) else ""
            if given:
                error = r["k"] - t["k"]
                agrees = bool(abs(error) <= max(r["u_k"], K_TOLERANCE_REL * t["k"]))
                rel_error = float(error / t["k"])
            else:  # no surface: kA against the truth's kA, relative, as k would be
                rel_error = float(r["kA"] / t["kA"] - 1.0)
                agrees = bool(abs(rel_error) <= max(r["u_k_rel"], K_TOLERANCE_REL))
            notes = []
            if not given:
                notes.append(f"k {NOT_GIVEN['surface_m2']}; kA compared with the truth's kA")
            if not r["usable"]:
                notes.append("window not steady: k not usable")
            if effects:
                notes.append("declared deviation affecting the static test: " + effects)
            elif not agrees:
                notes.append("disagrees with the truth and no declared deviation explains it")
            note = "; ".join(notes)
            row |= {
                "k_truth": float(t["k"]),
                "rel_error": rel_error,
                "agrees": agrees,
                "deviations": ";".join(declared),
                "note": note,
            }
        rows.append(row)
    return pd.DataFrame(rows)


PARAMETERS = ("kA", "C_bar", "C", "K_veh", "C_veh")
# Tolerance of the second-order estimates against the campaign's truth (relative error):
# ``<p>_within_tolerance``; C_total = C + C_veh as its parts.
RECOVERY_TOLERANCE = {"C": 0.05, "K_veh": 0.10, "C_veh": 0.05, "C_total": 0.05}
TOTAL = "C_total"  # C + C_veh (eqs. 7-8), the capacity the first-order C_bar lumps (eq. 9)


def fit_structure(fit: FitRecord) -> models.Structure | None:
    """The structure of a written fit (``structure``, irradiance inputs stripped); a fit
    without the key but with C, K_veh and C_veh is the second-order model (eqs. 7-8)."""
    name = fit.structure_name.split("+")[0]
    if not name and {"C", "K_veh", "C_veh"} <= set(fit.parameters):
        name = "second_order"
    return models.STRUCTURES.get(name)


def judged_parameters(fit: FitRecord) -> dict[str, Mapping[str, Any]]:
    """{param: identification} of a written fit: each estimated parameter as the fit file
    records it (:attr:`railtherm.records.ParameterEstimate.identification`), then the
    structure's coupled parameters together (``Structure.coupled``,
    :func:`railtherm.study.identifiability.coupled_identification`):
    a capacity or the internal conductance coupled to one the data do not determine is not an
    estimate either. A fixed parameter (kA from the static test) is identified."""
    judged: dict[str, Mapping[str, Any]] = {
        p: e.identification if e.estimated else {"identified": True}
        for p, e in fit.parameters.items()
    }
    structure = fit_structure(fit)
    if structure is not None:
        estimated = {p: judged[p] for p in structure.coupled if p in judged}
        judged |= identifiability.coupled_identification(estimated, structure.coupled)
    return judged


def fit_totals(fit: FitRecord) -> dict[str, ParameterEstimate]:
    """The totals of a written fit (``totals``: C_total = C + C_veh with its 95 % interval),
    as recorded, or computed from its parameters, correlation and systematic effects
    (:func:`railtherm.study.identifiability.total_capacity`) for a fit written without them."""
    if fit.totals:
        return fit.totals
    structure = fit_structure(fit)
    params = fit.parameters
    out = {}
    for name, parts in (structure.totals if structure is not None else {}).items():
        if all(p in params and params[p].estimated for p in parts):
            effects = fit.section("systematic").get("effects_log")
            entry = identifiability.total_capacity(fit, parts, effects)
            out[name] = ParameterEstimate.from_entry(name, entry)
    return out


def intervals_overlap(a: Sequence[float], b: Sequence[float]) -> bool:
    """Whether two closed intervals [lo, hi] meet."""
    return bool(float(a[0]) <= float(b[1]) and float(b[0]) <= float(a[1]))


def total_vs_C_bar(total: ParameterEstimate | None, C_bar: ParameterEstimate | None) -> str:
    """C_total = C + C_veh of the second-order fit against C_bar of the first-order fit of the
    same vehicle, the same capacity by eq. 9: "overlap" when their 95 % intervals meet,
    "disjoint" when not, "not comparable: <why>" when either is not an estimate."""
    if total is None:
        return "not comparable: no C_total"
    if C_bar is None:
        return "not comparable: no first-order fit"
    for name, entry in ((TOTAL, total), ("C_bar", C_bar)):
        if not entry.identified:
            return f"not comparable: {name} not identified"
    return "overlap" if intervals_overlap(total.ci95_combined, C_bar.ci95_combined) else "disjoint"


def fit_table(fits: Sequence[FitRecord], truth: pd.DataFrame | None = None) -> pd.DataFrame:
    """One row per vehicle and model order: verdict, R^2 (eq. 21), NRMSE fit, how k was
    obtained, every parameter with its 95 % interval, the flags; the total capacity C_total =
    C + C_veh of a second-order fit (``C_total``, ``_lo``, ``_hi``, ``_status``) and whether
    its interval meets that of the same vehicle's first-order C_bar (``C_total_vs_C_bar``, the
    same capacity by eq. 9: :func:`total_vs_C_bar`). A parameter the data do not determine,
    or coupled to one they do not determine, has no value there (``<p>_status`` says why).

    For second-order fits of campaign vehicles, per C, K_veh, C_veh and C_total: the truth,
    the relative error, ``<p>_inside`` (the truth inside the 95 % interval),
    ``<p>_within_tolerance`` (|relative error| within :data:`RECOVERY_TOLERANCE`) and
    ``<p>_recovered`` (either of the two). Each needs an identified estimate: a value the
    data do not determine is never compared with the truth (all three False)."""
    truth_by_id = truth.set_index("vehicle") if truth is not None else None
    first_order = {
        (f.vehicle, f.estimator): f.parameters["C_bar"]
        for f in fits
        if "C_bar" in f.parameters and f.parameters["C_bar"].estimated
    }
    rows = []
    for fit in fits:
        row: dict[str, Any] = {
            "vehicle": fit.vehicle,
            "order": fit.order,
            "verdict": fit.verdict,
            "judged_by": fit.judged_by,
            "R2": fit.R2,
            "nrmse_fit": fit.nrmse_fit,
            "k_source": fit.k_source,
        }
        judged = judged_parameters(fit)
        params = fit.parameters
        for p in PARAMETERS:
            entry = params.get(p)
            if entry is None:
                row |= {p: math.nan, f"{p}_lo": math.nan, f"{p}_hi": math.nan, f"{p}_status": ""}
            elif not entry.estimated:  # held fixed (kA from the static test)
                value = entry.value
                row |= {p: value, f"{p}_lo": math.nan, f"{p}_hi": math.nan, f"{p}_status": "fixed"}
            else:
                q = quantity(entry.value, entry.ci95_combined, judged[p])
                row |= {f"{p}{suffix}": q[suffix] for suffix in ("", "_lo", "_hi", "_status")}
        total = fit_totals(fit).get(TOTAL)
        if total is None:
            row |= {TOTAL: math.nan, f"{TOTAL}_lo": math.nan, f"{TOTAL}_hi": math.nan}
            row |= {f"{TOTAL}_status": "", f"{TOTAL}_vs_C_bar": ""}
        else:
            q = quantity(total.value, total.ci95_combined, total.identification)
            row |= {f"{TOTAL}{suffix}": q[suffix] for suffix in ("", "_lo", "_hi", "_status")}
            key = (fit.vehicle, fit.estimator)
            row[f"{TOTAL}_vs_C_bar"] = total_vs_C_bar(total, first_order.get(key))
        row["flags"] = ";".join(sorted({f["code"] for f in fit.flags}))
        # the campaign's truth is of its synthetic vehicles, never of a measured one
        known = truth_by_id is not None and fit.synthetic and fit.vehicle in truth_by_id.index
        if known and fit.order == 2:
            t = truth_by_id.loc[fit.vehicle]
            row["deviations"] = "" if pd.isna(t["deviations"]) else t["deviations"]
            for p, tol in RECOVERY_TOLERANCE.items():
                true = float(t["C"] + t["C_veh"]) if p == TOTAL else float(t[p])
                # NaN where not identified: never inside, never within tolerance
                error = row[p] / true - 1.0
                inside = bool(row[f"{p}_lo"] <= true <= row[f"{p}_hi"])
                within = bool(abs(error) <= tol)
                row |= {
                    f"{p}_truth": true,
                    f"{p}_rel_error": float(error),
                    f"{p}_inside": inside,
                    f"{p}_within_tolerance": within,
                    f"{p}_recovered": inside or within,
                }
        rows.append(row)
    table = pd.DataFrame(rows)
    estimators = [fit.estimator for fit in fits]
    if any(e != "output_error" for e in estimators):  # said where it is not the paper's
        table.insert(table.columns.get_loc("order") + 1, "estimator", estimators)
    return table


# the level at which an output-error fit's residuals count as coloured (check.whiteness_alpha's
# default): its AIC / BIC are then indicative only
WHITENESS_ALPHA = packaged_schema("vehicle")["properties"]["check"]["properties"][
    "whiteness_alpha"
]["default"]


def model_table(fits: Sequence[FitRecord]) -> pd.DataFrame:
    """Every fitted model of every vehicle side by side (rule compare_models): the overall
    heat-loss coefficient kA with its 95 % interval and how it was obtained, and the measures of
    the simulated T (the one output every structure shares): R^2 (eq. 21), NRMSE fit, RMSE,
    AIC and BIC (with the model's unknowns, initial states included), the Ljung-Box whiteness
    p-value and the residuals' effective sample count; the verdict with the criteria that
    judged it (``judged_by``) and whether the solver converged. ``best_aic``/``best_bic`` mark
    each vehicle's preferred model per estimator among the fits that are acceptable and
    converged (none where no fit is); ``ic_indicative`` marks an output-error fit whose
    residuals are coloured (Ljung-Box p < :data:`WHITENESS_ALPHA`): its AIC and BIC count
    dependent residuals as independent samples."""
    rows = []
    for fit in fits:
        T = dict(fit.section("measures")["T"]["overall"])
        estimator = fit.estimator
        if estimator == "kalman":  # the criteria of its likelihood, the tests of its innovations
            from railtherm.estimation.diagnostics import information_criteria

            T |= information_criteria(fit.loglik, fit.n_params, fit.n_obs)
            T["p"] = fit.n_params
            T["ljung_box_p"] = fit.section("innovations")["T"]["ljung_box_p"]
        kA = fit.parameters.get("kA")
        if kA is not None and kA.estimated:
            q = quantity(kA.value, kA.ci95_combined, kA.identification)
        else:  # fixed from the static test
            q = {"": math.nan if kA is None else kA.value, "_lo": math.nan, "_hi": math.nan}
            q["_status"] = "fixed" if kA is not None else ""
        rows.append(
            {
                "vehicle": fit.vehicle,
                "model": fit.model,
                "estimator": estimator,
                "structure": fit.structure_name,
                "k_source": fit.k_source,
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
                "verdict": fit.verdict,
                "judged_by": fit.judged_by,
                "converged": converged(fit),
                "source": vehicle_source({"synthetic": fit.synthetic}),
            }
        )
    df = pd.DataFrame(rows)
    for criterion in ("aic", "bic"):
        # the criteria of the two estimators rest on different likelihoods: compared apart;
        # only a selectable fit is a candidate
        score = df[criterion].where(pd.Series([selectable(f) for f in fits], index=df.index))
        best = score.groupby([df["vehicle"], df["estimator"]], sort=False).transform("min")
        df.insert(df.columns.get_loc("ljung_box_p"), f"best_{criterion}", score == best)
    # an output-error AIC / BIC counts the residuals as independent samples: with coloured
    # residuals it is indicative only (the Kalman fit's rest on its innovations' likelihood)
    df.insert(
        df.columns.get_loc("ljung_box_p"),
        "ic_indicative",
        (df["estimator"] != "kalman") & (df["ljung_box_p"] < WHITENESS_ALPHA),
    )
    return df


def converged(fit: FitRecord) -> bool:
    """Whether the fit's solver ended at a clean optimum (no ``not_converged`` flag)."""
    return not any(f["code"] == "not_converged" for f in fit.flags)


def selectable(fit: FitRecord) -> bool:
    """Whether a fit is a candidate of model selection (the lowest AIC / BIC, the forward
    selection): acceptable and converged."""
    return fit.verdict == ACCEPTABLE and converged(fit)


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
# the status of a quantity whose metadata the config does not give (an object of class
# other): k needs the surface, c_veh the mass; blank in every table, left out of every statistic
NOT_GIVEN_PREFIX = "not given"
NOT_GIVEN = {
    "surface_m2": "not given: no surface_m2",
    "mass_kg": "not given: no mass_kg",
}


def vehicle_source(vehicle: Mapping[str, Any]) -> str:
    """Where one vehicle's rows come from: the campaign's synthetic data, or measured."""
    return SYNTHETIC_SOURCE if vehicle.get("synthetic", False) else MEASURED_SOURCE


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
    / "lower" / "none"): the one-sided limit the data do give
    (railtherm.estimation.pem.identification)."""
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


def not_given(key: str) -> dict[str, Any]:
    """The table columns of a quantity the config's metadata cannot give (:data:`NOT_GIVEN`:
    k without ``surface_m2``, c_veh without ``mass_kg``): no value, no interval, no limit."""
    return {
        "": math.nan,
        "_lo": math.nan,
        "_hi": math.nan,
        "_status": NOT_GIVEN[key],
        "_limit": math.nan,
        "_limit_kind": "",
    }


def is_not_given(status: Any) -> bool:
    """Whether a ``<q>_status`` cell says the quantity is not given (no metadata for it)."""
    return isinstance(status, str) and status.startswith(NOT_GIVEN_PREFIX)


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


def _part(entry: ParameterEstimate, judged: Mapping[str, Any]) -> tuple[str, float]:
    if judged.get("identified", True):
        return "point", entry.value
    limit = judged.get("limit_value")
    return judged["limit"], math.nan if limit is None else float(limit)


def table2(
    fits: Mapping[str, FitRecord],
    kvalues: Mapping[str, Mapping[str, Any] | None],
    vehicles: Mapping[str, Mapping[str, Any]],
    first_order: Mapping[str, FitRecord] | None = None,
) -> pd.DataFrame:
    """Table 2: per vehicle k (W/(m^2 K)), C (J/K), K_veh (W/K), C_veh (J/K) and R^2 (eq. 21) of
    the second-order model, each estimate with its 95 % interval and its status, the verdict
    and how k was obtained. Rows by class (tram, metro, regional, main-line, then others),
    within a class in the order of ``vehicles`` (the study config's order).

    ``fits``: vehicle -> its fit_order2.yaml; ``kvalues``: vehicle -> its kvalue.yaml (or None);
    ``vehicles``: vehicle -> its config; ``first_order``: vehicle -> its fit_order1.yaml, where
    fitted. k from the static test carries k +- 2 u(k) (expanded uncertainty, coverage factor
    2, as the k table), storage-corrected where the fit corrected it (the k whose kA the
    capacities were fitted with; the k table keeps eq. 10's); k from joint estimation kA / A
    with kA's interval. C, K_veh, C_veh
    intervals are the combined ones (statistical and systematic); a parameter the data do not
    determine, or coupled to one they do not determine (:func:`judged_parameters`), has no
    value, its status and any one-sided limit the data give (:func:`quantity`).

    Beside them the total capacity C_total = C + C_veh (:func:`fit_totals`), which the data
    determine even where they cannot split it between the nodes, the first-order C_bar of the
    same vehicle (eq. 9: the same capacity lumped into one node) and whether the two 95 %
    intervals meet (``C_total_vs_C_bar``, :func:`total_vs_C_bar`). A vehicle without
    ``surface_m2`` has no k: status "not given: no surface_m2" (:func:`not_given`)."""
    first_order = first_order or {}
    rows = []
    for vid in by_class(vehicles):
        vehicle, fit = vehicles[vid], fits[vid]
        params = fit.parameters
        judged = judged_parameters(fit)
        A = None if vehicle.get("surface_m2") is None else float(vehicle["surface_m2"])
        kv = kvalues.get(vid)
        if A is None:
            k = not_given("surface_m2")
        elif params["kA"].estimated or kv is None:
            entry = params["kA"]
            judged_kA = dict(judged["kA"])
            if judged_kA.get("limit_value") is not None:
                judged_kA["limit_value"] = judged_kA["limit_value"] / A
            ci = [c / A for c in entry.ci95_combined or (math.nan, math.nan)]
            k = quantity(entry.value / A, ci, judged_kA)
        elif fit.k_corrected is not None and fit.u_k_corrected is not None:
            # the storage-corrected k the capacities were fitted with, not eq. 10's
            U = COVERAGE_FACTOR * fit.u_k_corrected
            k = quantity(fit.k_corrected, (fit.k_corrected - U, fit.k_corrected + U), {})
        else:
            U = COVERAGE_FACTOR * float(kv["u_k"])
            k = quantity(float(kv["k"]), (float(kv["k"]) - U, float(kv["k"]) + U), {})
        row: dict[str, Any] = {"vehicle": vid, "class": vehicle["class"]}
        row |= _columns("k", k)
        row["k_source"] = fit.k_source
        for p in ("C", "K_veh", "C_veh"):
            entry = params[p]
            row |= _columns(p, quantity(entry.value, entry.ci95_combined, judged[p]))
        total = fit_totals(fit).get(TOTAL)
        if total is None:
            row |= _columns(TOTAL, quantity(math.nan, (math.nan, math.nan), {}))
        else:
            row |= _columns(TOTAL, quantity(total.value, total.ci95_combined, total.identification))
        lumped = first_order.get(vid)
        C_bar = None if lumped is None else lumped.parameters.get("C_bar")
        if C_bar is None or not C_bar.estimated:
            row |= _columns("C_bar", quantity(math.nan, (math.nan, math.nan), {}))
            C_bar = None
        else:
            row |= _columns(
                "C_bar", quantity(C_bar.value, C_bar.ci95_combined, C_bar.identification)
            )
        row[f"{TOTAL}_vs_C_bar"] = total_vs_C_bar(total, C_bar)
        row |= {
            "R2": fit.R2,
            "verdict": fit.verdict,
            "source": vehicle_source(vehicle),
        }
        rows.append(row)
    return pd.DataFrame(rows)


def _sd_log_ratio(fit: FitRecord, num: str, den: str) -> float:
    """sd of log(num / den): statistical part from the fit's sd_log and correlation, systematic
    part from the signed effects of each type-B source (a source shifts both at once)."""
    params = fit.parameters
    free = list(fit.free)
    corr = fit.correlation
    sd_n, sd_d = float(params[num].sd_log), float(params[den].sd_log)
    rho = corr[free.index(num), free.index(den)]
    rho = 0.0 if not np.isfinite(rho) else float(rho)
    var = sd_n**2 + sd_d**2 - 2.0 * rho * sd_n * sd_d
    effects = fit.section("systematic").get("effects_log", {})
    e_n, e_d = effects.get(num, {}), effects.get(den, {})
    for source in sorted(set(e_n) | set(e_d)):  # fixed order: the same bits every run
        var += (float(e_n.get(source, 0.0)) - float(e_d.get(source, 0.0))) ** 2
    return math.sqrt(max(var, 0.0))


def table3(
    t2: pd.DataFrame,
    fits: Mapping[str, FitRecord],
    vehicles: Mapping[str, Mapping[str, Any]],
) -> pd.DataFrame:
    """Table 3: c_veh = C_veh / m_veh (eq. 24, J/(kg K)) and delta = C_veh / C (eq. 25) with
    95 % intervals, in Table 2's row order. c_veh takes C_veh's interval (the mass is taken as
    exact); delta's interval is exp(log delta +- z_0.975 sd), sd combining the statistical
    variances and the correlation of log C and log C_veh with the systematic effects of each
    source on both. A ratio with a part the data do not determine (or coupled to one they do
    not determine, :func:`judged_parameters`) is not identified either; a one-sided limit
    follows only from parts that are one-sided limits the data give, never from a bound of
    the search.
    A vehicle without ``mass_kg`` has no m_veh and no c_veh: status "not given: no mass_kg"
    (:func:`not_given`); delta needs no mass."""
    rows = []
    for vid, cls, verdict, source in zip(
        t2["vehicle"], t2["class"], t2["verdict"], t2["source"], strict=True
    ):
        fit = fits[vid]
        params = fit.parameters
        judged = judged_parameters(fit)
        mass = vehicles[vid].get("mass_kg")
        m = math.nan if mass is None else float(mass)
        C_veh, C = params["C_veh"], params["C"]
        c_kind, c_value = _ratio_limit(_part(C_veh, judged["C_veh"]), ("point", m))
        if mass is None:
            c_veh = not_given("mass_kg")
        elif c_kind == "point":
            ci = [c / m for c in C_veh.ci95_combined]
            c_veh = quantity(c_value, ci, pem.identification(c_value, ci))
        else:
            reason = f"C_veh {judged['C_veh']['reason']}"
            limit = {"limit": c_kind, "limit_value": c_value, "reason": reason}
            c_veh = quantity(math.nan, (math.nan, math.nan), {"identified": False, **limit})
        d_kind, d_value = _ratio_limit(_part(C_veh, judged["C_veh"]), _part(C, judged["C"]))
        if d_kind == "point":
            sd = _sd_log_ratio(fit, "C_veh", "C")
            with np.errstate(over="ignore"):
                ci = (float(d_value * np.exp(-Z95 * sd)), float(d_value * np.exp(Z95 * sd)))
            delta = quantity(d_value, ci, pem.identification(d_value, ci))
        else:
            why = "; ".join(
                f"{p} {judged[p]['reason']}"
                for p in ("C", "C_veh")
                if not judged[p].get("identified", True)
            )
            limit = {"identified": False, "limit": d_kind, "reason": why}
            limit["limit_value"] = None if d_kind == "none" else d_value
            delta = quantity(math.nan, (math.nan, math.nan), limit)
        row = {"vehicle": vid, "class": cls, "m_veh": m}
        row |= _columns("c_veh", c_veh) | _columns("delta", delta)
        row |= {"verdict": verdict, "source": source}
        rows.append(row)
    return pd.DataFrame(rows)


def table1(
    vehicles: Mapping[str, Mapping[str, Any]],
    kvalues: Mapping[str, Mapping[str, Any] | None],
    fits: Mapping[str, FitRecord],
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
                    judged_parameters(fits[vid])[p].get("identified", True)
                    for p in ("C", "K_veh", "C_veh")
                )
                for vid in ids
            ),
            "vehicles evaluated (fit acceptable)": sum(
                fits[vid].verdict == ACCEPTABLE for vid in ids
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


def geometric_sd(x: Sequence[float]) -> float:
    """The geometric standard deviation exp(sd(log x)) (n - 1 in the sd): the spread of a
    positive quantity on the log scale, a factor (x/÷) about the geometric mean; NaN below
    two values or for a value that is not positive."""
    x = np.asarray(x, dtype=float)
    if x.size < 2 or not np.all(x > 0):
        return math.nan
    return float(np.exp(np.log(x).std(ddof=1)))


def class_summary(t3: pd.DataFrame) -> pd.DataFrame:
    """Per selection (every identified value; only fits judged acceptable), class and quantity
    (c_veh, delta): n, mean with its 95 % t interval, the geometric mean with its t interval on
    the log scale (the natural centre of a ratio such as delta, whose values span decades),
    median, sample sd, the geometric sd (:func:`geometric_sd`, delta's spread on the log
    scale beside its geometric mean), min and max, the vehicles used and those left out
    because the data do not determine their value. A t interval (n - 1 degrees of freedom)
    is exact for normal data and honest at n = 2 (wide); a percentile bootstrap of 3 to 5
    values returns little more than their range and covers far less than 95 %. A value not
    given (no metadata for it, :data:`NOT_GIVEN`) is skipped: neither used nor listed as not
    identified."""
    rows = []
    for selection, pick in SELECTIONS.items():
        sub = pick(t3)
        for c in class_order(sub["class"].tolist()):
            part = sub[sub["class"] == c]
            for q in ("c_veh", "delta"):
                if f"{q}_status" in part:
                    ok = part[f"{q}_status"] == ESTIMATED
                    given = ~part[f"{q}_status"].map(is_not_given).astype(bool)
                else:
                    ok = part[q].notna()
                    given = pd.Series(True, index=part.index)
                x = part.loc[ok, q].to_numpy(dtype=float)
                left_out = part.loc[~ok & given, "vehicle"].tolist()
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
                        "geometric_sd": geometric_sd(x),
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
    columns += ["sd", "geometric_sd", "min", "max", "vehicles", "not_identified"]
    return pd.DataFrame(rows, columns=columns)


def class_test(
    t3: pd.DataFrame,
    quantity: str = "c_veh",
    groups: Sequence[str] = ("metro", "regional"),
    alpha: float = 0.05,
) -> pd.DataFrame:
    """The paper's open question (section 6.3): do metros and regional trains differ in c_veh?
    Per selection of vehicles (values the data do not determine left out): Welch's t-test
    (needs 3 vehicles per group: with 2, one sample sd is a single difference and the test
    has almost no power) and the exact two-sided Mann-Whitney U test, each run only when it
    can reach significance at ``alpha`` - the exact test's smallest attainable p is
    2 / C(n_a + n_b, n_a) (railtherm.study.smallsample: 0.2 at 3 vs 2), so with fewer vehicles
    "no significant difference" would be certain before any data; the conclusion then reads
    "not testable". A plain conclusion from the tests that ran."""
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
            conclusion = f"not testable: too few vehicles ({n}: {'; '.join(test.not_run)})"
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
# the study's tables


def study_tables(
    fits: Mapping[str, FitRecord],
    kvalues: Mapping[str, Mapping[str, Any] | None],
    vehicles: Mapping[str, Mapping[str, Any]],
    class_test_groups: Sequence[str] = ("metro", "regional"),
    first_order: Mapping[str, FitRecord] | None = None,
) -> dict[str, pd.DataFrame]:
    """Tables 1-3, the class summary and the class test from the second-order fits;
    ``first_order``: the vehicles' first-order fits, whose C_bar Table 2 sets beside C_total."""
    t2 = table2(fits, kvalues, vehicles, first_order)
    t3 = table3(t2, fits, vehicles)
    return {
        "table1": table1(vehicles, kvalues, fits),
        "table2": t2,
        "table3": t3,
        "class_summary": class_summary(t3),
        "class_test": class_test(t3, "c_veh", tuple(class_test_groups)),
    }
