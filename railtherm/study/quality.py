"""The quality of a fit as the study records and judges it: the measures of each compared
output written to fit files (:func:`summary`: R² of eq. 21, NRMSE fit, RMSE, AIC, BIC and the
residuals' whiteness, from :mod:`railtherm.estimation.metrics`), the plain verdict
(:func:`verdict`): "fit acceptable" or "assumptions in doubt", with its reasons, and the check
stage that reaches it for a fit (:func:`check`): each criterion of :data:`CRITERIA` judged
(the measures, the flags, the physical plausibility of :func:`plausibility`, the Kalman
innovations' whiteness, the static test's agreement) with the vehicle's thresholds
(:func:`check_thresholds`)."""

from __future__ import annotations

import copy
import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import pandas as pd

from railtherm import structures
from railtherm.estimation import outliers
from railtherm.estimation.metrics import Whiteness, aic, bic, ljung_box, nrmse_fit, paired, r2, rmse
from railtherm.records import EstimateRecord, FitRecord
from railtherm.study import identifiability
from railtherm.yamlio import packaged_schema, validate_schema

__all__ = [
    "ACCEPTABLE",
    "CRITERIA",
    "DEFAULT_THRESHOLDS",
    "IN_DOUBT",
    "check",
    "check_thresholds",
    "plausibility",
    "summary",
    "verdict",
]

ACCEPTABLE = "fit acceptable"
IN_DOUBT = "assumptions in doubt"

#: Defaults of :func:`verdict`, named and valued as the keys of a vehicle's ``check`` section
#: (railtherm/schemas/vehicle.schema.yaml, where each value's reason is given): the
#: climatic-wind-tunnel values. ``r2_min``: R^2 (eq. 21) below this puts the assumptions in
#: doubt. ``min_effective_samples``: residuals whose autocorrelation time leaves fewer than this
#: many independent samples (m / tau) are *strongly coloured*: the error is a few slow
#: excursions, i.e. dynamics the model does not have. ``require_white``: also count a rejected
#: Ljung-Box test (Holm-adjusted p < ``whiteness_alpha`` over the series judged) as a reason;
#: off by default, since
#: simulation-error residuals of thermal data are practically never white.
DEFAULT_THRESHOLDS: dict[str, Any] = {
    "r2_min": 0.9,
    "min_effective_samples": 10.0,
    "require_white": False,
    "whiteness_alpha": 0.05,
}


def summary(y: Any, yhat: Any, p: int, lags: int | None = None) -> dict[str, float | int]:
    """All measures of one output series (y measured, yhat simulated, p estimated parameters
    including estimated initial states), as plain values in a stable order, for YAML."""
    yy, yh = paired(y, yhat)
    e = yy - yh
    m = int(yy.size)
    ssr = float(e @ e)
    out: dict[str, float | int] = {
        "m": m,
        "p": int(p),
        "r2": r2(yy, yh),
        "nrmse_fit": nrmse_fit(yy, yh),
        "rmse": rmse(yy, yh),
        "ssr": ssr,
        "aic": aic(ssr, m, p) if m and ssr > 0 else math.nan,
        "bic": bic(ssr, m, p) if m and ssr > 0 else math.nan,
    }
    w = ljung_box(e, lags)
    for key, value in w.to_dict().items():
        if key != "m":
            out[key] = value
    return out


def _message(flag: Any) -> str:
    """The plain sentence of an identifiability flag: a str, a mapping with 'message', an
    object with ``.message``, or a (code, message) pair."""
    if isinstance(flag, str):
        return flag
    if isinstance(flag, Mapping):
        return str(flag.get("message", flag.get("code", flag)))
    if hasattr(flag, "message"):
        return str(flag.message)
    if isinstance(flag, tuple) and len(flag) == 2:
        return str(flag[1])
    return str(flag)


def _named(value: Any) -> list[tuple[str, Any]]:
    """A single value as [("", value)], a mapping as its (name, value) items."""
    if value is None:
        return []
    if isinstance(value, Mapping) and not (value and "ljung_box_p" in value):
        return [(str(k), v) for k, v in value.items()]
    return [("", value)]


def _get(w: Any, attr: str, key: str) -> float:
    return float(w[key]) if isinstance(w, Mapping) else float(getattr(w, attr))


def verdict(
    r2: float | Mapping[str, float],
    flags: Iterable[Any] = (),
    whiteness: Whiteness | Mapping[str, Any] | None = None,
    thresholds: Mapping[str, Any] | None = None,
) -> tuple[str, list[str]]:
    """("fit acceptable" | "assumptions in doubt", reasons): a small pure function.

    r2: R^2 (eq. 21), or a mapping {name: R^2} (e.g. per experiment or per cross-validation
    fold); a NaN R^2 is a reason. flags: the fit's identifiability flags (sentences, or objects
    / mappings carrying a ``message``); each one is a reason. whiteness: a :class:`Whiteness`
    (or its ``to_dict()``), or a mapping {name: Whiteness}; with ``require_white`` their
    Ljung-Box tests are one family, judged by Holm's procedure at ``whiteness_alpha``
    (:func:`railtherm.estimation.diagnostics.holm`: white residuals put the fit in doubt with
    probability at most that level, however many series). thresholds: overrides of
    :data:`DEFAULT_THRESHOLDS` (an unknown name is a ValueError naming the known ones).
    Reasons are plain sentences with the numbers; the label is "fit acceptable" exactly when
    there are none."""
    t = {**DEFAULT_THRESHOLDS, **(thresholds or {})}
    unknown = set(t) - set(DEFAULT_THRESHOLDS)
    if unknown:
        raise ValueError(
            f"unknown verdict thresholds: {sorted(unknown)} (known: {sorted(DEFAULT_THRESHOLDS)})"
        )
    reasons: list[str] = []
    for name, value in _named(r2):
        where = f" ({name})" if name else ""
        value = float(value)
        if math.isnan(value):
            reasons.append(f"R^2{where} is undefined (no usable rows or a constant measurement).")
        elif value < t["r2_min"]:
            reasons.append(f"R^2{where} = {value:.4f} is below {t['r2_min']:g}.")
    reasons.extend(_message(f) for f in flags)
    named = _named(whiteness)
    if t["require_white"] and named:
        from railtherm.estimation.diagnostics import holm

        adjusted = holm([_get(w, "p_value", "ljung_box_p") for _, w in named])
    family = f"Holm over {len(named)} series, " if len(named) > 1 else ""
    for i, (name, w) in enumerate(named):
        where = f" ({name})" if name else ""
        n_eff = _get(w, "effective_samples", "effective_samples")
        tau = _get(w, "tau", "autocorrelation_time")
        if n_eff < t["min_effective_samples"]:
            reasons.append(
                f"The residuals{where} are strongly coloured: autocorrelation time {tau:.4g} "
                f"samples leaves {n_eff:.3g} independent samples (< "
                f"{t['min_effective_samples']:g}); the model misses a slow dynamic."
            )
        p = _get(w, "p_value", "ljung_box_p")
        if t["require_white"] and adjusted[i] < t["whiteness_alpha"]:
            shown = f"p = {p:.3g}, {family}adjusted {adjusted[i]:.3g}" if family else f"p = {p:.3g}"
            reasons.append(
                f"The residuals{where} are not white (Ljung-Box {shown} < "
                f"{t['whiteness_alpha']:g})."
            )
    return (IN_DOUBT if reasons else ACCEPTABLE), reasons


# ---------------------------------------------------------------------------------------------
# The check stage: a fit judged by every criterion


K_STAGE_FIELDS = (
    "kA_fixed",
    "k_eq10",
    "u_k_eq10",
    "k_corrected",
    "u_k_corrected",
    "storage_correction",
)


def outlying_samples(
    estimate: EstimateRecord, series: pd.DataFrame, thresholds: Mapping[str, Any]
) -> dict[str, Any]:
    """Each compared output's outlying samples
    (:class:`railtherm.estimation.outliers.OutlyingSamples`): a Kalman fit's standardised
    one-step innovations, an output-error fit's simulation residuals over their RMSE, beyond
    the Bonferroni threshold at ``check.outlier_alpha`` over the record's samples. Reported
    in the fit's notes and ``outliers``; they do not judge the verdict."""
    estimator = estimate.estimator
    alpha = float(thresholds["outlier_alpha"])
    # a series without times (a hand-built one) names its samples by their row
    times = series["time"] if "time" in series else pd.Series(range(len(series)))
    return {
        state: outliers.outlying_samples(
            state,
            outliers.standardized(series, state, estimator),
            times.to_numpy(float),
            series["window"].astype(str).to_numpy(),
            estimator,
            alpha,
        )
        for state in estimate.outputs
        if outliers.has_columns(series, state, estimator)
    }


def innovation_reasons(estimate: EstimateRecord, thresholds: Mapping[str, Any]) -> list[str]:
    """The verdict's reasons of a kalman fit: an output whose one-step innovations are not
    white (:func:`innovation_tests`) - the stochastic model misses a dynamic or an input.

    The Ljung-Box and cumulated-periodogram tests of every compared output are one family,
    judged by Holm's procedure (:func:`railtherm.estimation.diagnostics.holm`) at
    ``whiteness_alpha``: with white innovations the fit is put in doubt with probability at
    most that level, however many outputs and tests there are (each test alone at that level
    would do so up to 2 x outputs times as often). A two-stage fit's tests are those of its
    check's joint fit (``innovations_of``, :func:`railtherm.study.identify.identify`), named
    in the reason."""
    from railtherm.estimation import diagnostics

    tests = estimate.section("innovations")
    alpha = float(thresholds["whiteness_alpha"])
    names = [(state, key) for state in tests for key in ("ljung_box_p", "cpg_p")]
    adjusted = diagnostics.holm([float(tests[state][key]) for state, key in names])
    held = dict(zip(names, adjusted, strict=True))
    family = f"Holm over {len(names)} tests" if len(names) > 1 else "one test"
    of = f" of {estimate.innovations_of}" if estimate.innovations_of else ""
    reasons = []
    for state, t in tests.items():
        lb, cpg = held[(state, "ljung_box_p")], held[(state, "cpg_p")]
        if min(lb, cpg) < alpha:
            reasons.append(
                f"The one-step innovations of {state}{of} are not white (Ljung-Box p = "
                f"{t['ljung_box_p']:.3g}, cumulated periodogram p = {t['cpg_p']:.3g}; "
                f"adjusted {lb:.3g} and {cpg:.3g} by {family}, below the family's level "
                f"{alpha:g}): the stochastic model misses a dynamic or an input."
            )
    return reasons


RHO_CP_AIR = 1.2 * 1005.0  # J/(m^3 K): air at about 20 degC


C_WATER = 4186.0  # J/(kg K): the highest specific heat of any common material


def check_thresholds(thresholds: Mapping[str, Any] | None) -> dict[str, Any]:
    """Every threshold of the verdict: a vehicle's ``check`` section (the study's
    ``defaults.check`` merged under it) with the schema's defaults, the climatic-wind-tunnel
    values, filled in for what it leaves out. An unknown key or a value of the wrong type is a
    :class:`~railtherm.errors.ConfigError` naming the key (with a did-you-mean)."""
    schema = packaged_schema("vehicle")
    data = copy.deepcopy(dict(thresholds or {}))
    section = {**schema["properties"]["check"], "$defs": schema["$defs"]}
    validate_schema("thresholds", data, section, prefix="check")
    return data


def skipped_checks(estimate: EstimateRecord) -> list[str]:
    """The plausibility checks a fit could not make, each a note: an object of class other
    may give no ``surface_m2`` (then k = kA / A and ``check.k_range_W_m2K``) or no ``mass_kg``
    (then c_veh and the stored heat per kg) - nothing is wrong, there is nothing to judge."""
    out = []
    if estimate.A is None:
        out.append(
            "k = kA / A not given, and its range (check.k_range_W_m2K) not checked: no surface_m2"
        )
    if estimate.mass_kg is None:
        out.append(
            "c_veh = C_veh / m_veh not given, and the heat stored per kg "
            "(check.min_capacity_per_kg_J_kgK, max_capacity_per_kg_J_kgK) not checked: no mass_kg"
        )
    return out


def plausibility(estimate: EstimateRecord, thresholds: Mapping[str, Any]) -> list[str]:
    """Physical plausibility of a fit's numbers, each failure a sentence for the verdict
    (a unit mistake in a channel leaves every other check silent):

    - k = kA / A inside ``k_range_W_m2K`` (default 0.1-10 W/(m^2 K): from a well-insulated
      envelope to bare single glazing in wind); W logged as kW puts it 1000 times too high;
    - the stored heat per kg, (sum of the capacities) / mass, at most
      ``max_capacity_per_kg_J_kgK`` (default that of water, 4186 J/(kg K)): no vehicle stores
      more;
    - the stored heat per kg at least ``min_capacity_per_kg_J_kgK`` (default 50 J/(kg K), a
      tenth of the vehicle's mass in steel at 477 J/(kg K)): time logged in minutes but
      declared seconds divides every capacity by 60;
    - the air node's capacity (C, or C_bar) at least ``min_air_capacity_ratio`` (default half)
      that of the air in ``volume_m3`` (rho c_p = 1206 J/(m^3 K)): the node holds the air and
      what is in equilibrium with it;
    - an effective solar aperture a_<name> at most the whole outer surface A;
    - the records and the fitted k against a temperature channel's unit (``unit_checks``
      of the estimate, :func:`unit_checks`): a heated cabin colder than the tunnel or never
      at a heated cabin's temperature (``heated_air_range_degC``), k far from the vehicle
      class's (``k_class_factor``);
    - a conductance between two nodes (K_veh, K_i, K_o) at most
      ``max_conductance_per_area_W_m2K`` (default 200 W/(m^2 K)) of the outer surface A:
      more than forced convection in the tunnel's wind carries over the whole surface. (kA
      is judged by k; in the interior-envelope structure K_i and K_o are at least kA by
      construction, kA = K_i K_o / (K_i + K_o).)

    ``thresholds``: the ``check`` section (defaults filled in by :func:`check_thresholds`).
    A check whose quantity the config does not give (no surface, mass or volume) is skipped
    (:func:`skipped_checks` says so). A parameter the data do not determine is not judged here
    (its flag already is); where the data determine only the total capacity C_total = C +
    C_veh (``fit.totals``), the sum stands for the capacities, and for the air node's as an
    upper bound (C <= C_total)."""
    thresholds = check_thresholds(thresholds)
    par = estimate.section("fit")["parameters"]

    def value(p):
        entry = par.get(p)
        if entry is None or not identifiability.parameter_identification(entry)["identified"]:
            return None
        return float(entry["value"])

    total = (estimate.section("fit").get("totals") or {}).get("C_total")
    if total is not None and not identifiability.parameter_identification(total)["identified"]:
        total = None
    return [
        *_against_surface(value, par, estimate.A, thresholds),
        *_against_mass(value, par, total, estimate.mass_kg, thresholds),
        *_against_air(value, par, total, estimate.volume_m3, thresholds),
        *estimate.unit_checks,
    ]


def _against_surface(value, par, A, thresholds) -> list[str]:
    """k = kA / A in its range, each solar aperture within A, each conductance per area below
    the ceiling (:func:`plausibility`)."""
    out = []
    kA = value("kA")
    lo, hi = (float(x) for x in thresholds["k_range_W_m2K"])
    if kA is not None and A is not None and not lo <= kA / A <= hi:
        out.append(
            f"k = kA / A = {kA / A:.4g} W/(m² K) lies outside the physical range "
            f"{lo:g}-{hi:g} W/(m² K) (check.k_range_W_m2K): are the units of the power and "
            "temperature channels right (W or kW, degC or K), and A the whole surface?"
        )
    for p in sorted(par):  # an effective solar aperture cannot exceed the whole surface
        a = value(p) if p.startswith("a_") else None
        if a is not None and A is not None and a > A:
            out.append(
                f"the effective aperture {p} = {a:.4g} m² exceeds the whole outer surface "
                f"A = {A:g} m²: the irradiance channel's unit (W/m² or kW/m²), or a gain the "
                "model lacks taken for sunshine"
            )
    ceiling = float(thresholds["max_conductance_per_area_W_m2K"])
    for p in structures.of_kind("conductances"):  # kA itself is judged by k, above
        if p == "kA":
            continue
        K = value(p) if p in par else None
        if K is not None and A is not None and K / A > ceiling:
            out.append(
                f"the conductance {p} = {K:.4g} W/K is {K / A:.4g} W/(m² K) of the outer surface "
                f"A = {A:g} m², more than {ceiling:g} W/(m² K) "
                "(check.max_conductance_per_area_W_m2K, forced convection over the whole "
                "surface): a unit mistake, or a fast dynamic the logger step cannot resolve "
                "taken up by the conductance"
            )
    return out


def _against_mass(value, par, total, mass_kg, thresholds) -> list[str]:
    """The stored heat per kg between its floor and ceiling (:func:`plausibility`)."""
    out = []
    capacities = [value(p) for p in structures.of_kind("capacities") if p in par]
    if None in capacities and total is not None:  # the split unknown, the sum determined
        capacities = [float(total["value"])]
    if capacities and None not in capacities and mass_kg:
        per_kg = sum(capacities) / mass_kg
        ceiling = float(thresholds["max_capacity_per_kg_J_kgK"])
        if per_kg > ceiling:
            than = (
                f"water ({C_WATER:g} J/(kg K))"
                if ceiling == C_WATER
                else f"{ceiling:g} J/(kg K) (check.max_capacity_per_kg_J_kgK)"
            )
            out.append(
                f"the capacities store {per_kg:.4g} J/(kg K) of the mass {mass_kg:g} "
                f"kg, more than {than}: a unit mistake (power in W declared kW?) or the wrong mass"
            )
        floor = float(thresholds["min_capacity_per_kg_J_kgK"])
        if per_kg < floor:
            out.append(
                f"the capacities store only {per_kg:.4g} J/(kg K) of the mass "
                f"{mass_kg:g} kg, below {floor:g} J/(kg K) "
                "(check.min_capacity_per_kg_J_kgK): is the time column's unit right (minutes "
                "declared seconds divides every capacity by 60), or the mass?"
            )
    return out


def _against_air(value, par, total, volume_m3, thresholds) -> list[str]:
    """The air node's capacity (or the total, an upper bound of it) against the air of the
    volume (:func:`plausibility`)."""
    out = []
    air_name = "C" if "C" in par else "C_bar"
    reason = str((par.get(air_name) or {}).get("reason", ""))
    if reason.startswith("at its physical lower bound") and volume_m3:
        out.append(
            f"the air node's capacity {air_name} sits {reason}: the data "
            f"ask for less than the air in {volume_m3:g} m³ holds - a unit mistake "
            "(power in kW declared W, time in minutes declared seconds?), the wrong volume, or "
            "a dynamic the model lacks"
        )
    air = value(air_name)
    what = "the air node's capacity"
    if air is None and total is not None:  # C <= C + C_veh: a total below the air's is too
        air, what = float(total["value"]), "the total capacity C_total (at least the air node's)"
    if air is not None and volume_m3:
        ratio = float(thresholds["min_air_capacity_ratio"])
        floor = ratio * RHO_CP_AIR * volume_m3
        if air < floor:
            share = "half" if ratio == 0.5 else f"{ratio:g} times (check.min_air_capacity_ratio)"
            out.append(
                f"{what} {air:.4g} J/K is below {share} that of the air in "
                f"{volume_m3:g} m³ ({floor:.4g} J/K): a unit mistake (power in kW "
                "declared W, time in minutes declared seconds?) or the wrong volume"
            )
    return out


# check.max_rmse_K's default, 0.2 K: twice a calibrated sensor's 0.1 K
RMSE_DEFAULT_K = packaged_schema("vehicle")["properties"]["check"]["properties"]["max_rmse_K"][
    "default"
]


# Flags that describe the data's information but do not invalidate the fit: the combined
# intervals already carry them (a parameter whose interval spans more than a factor 1000 is
# printed "not identified" in every table). Every other flag puts the model's assumptions in
# doubt. A wide interval is common on correctly specified records (a two-node fit of T alone:
# 40 % of benchmarks/false_alarms.py's records without surface sensors), so as a reason it
# would cry wolf.
NOTE_ONLY_FLAGS = ("high_correlation", "wide_interval")


# the verdict's criteria, in the order they are checked and shown (check.criteria; the
# "judged by" column of models.md and identification.csv)
CRITERIA = {
    "r2": "R²",
    "rmse": "RMSE",
    "innovations_white": "innovations white",
    "residuals_white": "residuals white",
    "flags": "flags",
    "plausibility": "plausibility",
    "k_stage": "k method",
    "clocks": "clocks",
}


def judged_by(criteria: Sequence[Mapping[str, Any]]) -> str:
    """The criteria that judged a fit, those it failed marked: "R², RMSE ✗, flags, ..."."""
    return ", ".join(
        CRITERIA[c["criterion"]] + ("" if c["passed"] else " ✗") for c in criteria if c["applies"]
    )


def check(
    estimate: EstimateRecord, series: pd.DataFrame, thresholds: Mapping[str, Any]
) -> FitRecord:
    """Diagnostics and verdict of one fit (rule check): R^2 (eq. 21), NRMSE fit, RMSE, residual
    whiteness and AIC/BIC per compared output, overall and per window; cross-validation R^2;
    the identifiability flags.

    One verdict policy for every estimator (:data:`CRITERIA`, each recorded in ``criteria``
    with whether it applied and passed): "assumptions in doubt" when

    - ``r2``: R^2 of the simulated T (or a cross-validation R^2) is below ``r2_min``;
    - ``rmse``: a simulated temperature misses its measurement by more than ``max_rmse_K``
      (then also naming strongly coloured residuals, fewer than ``min_effective_samples``
      independent samples: a missing slow dynamic). A Kalman fit is judged by the simulation
      of its parameters as well: white one-step innovations show that the stochastic model
      explains the record one step ahead, not that the deterministic model - what a
      prediction uses - reproduces it;
    - ``innovations_white`` (Kalman fits): a compared output's one-step innovations are not
      white (:func:`innovation_reasons`);
    - ``residuals_white`` (output-error fits, only with ``require_white``): a compared
      temperature's simulation residuals fail the Ljung-Box test at ``whiteness_alpha``;
      residuals within the sensors' accuracy are not judged by their colour otherwise:
      constant calibration offsets colour them by nature;
    - ``flags``: a flag other than a high correlation or a wide interval (a solver exit that
      is not a clean optimum is one: ``not_converged``);
    - ``plausibility``: a number physically implausible (:func:`plausibility`);
    - ``k_stage``: k not obtained by the two-stage approach.

    ``thresholds``: the vehicle's ``check`` section; what it leaves out takes the schema's
    default (:func:`check_thresholds`). The notes list what does not put the fit in doubt:
    high correlations, the checks skipped for metadata the config does not give, and the
    record's outlying samples (:func:`outlying_samples`, also in ``outliers``). Returns the
    checked fit's record (the content of ``fit_<model>.yaml``).
    """
    thresholds = check_thresholds(thresholds)
    fit = estimate.section("fit")
    p = int(fit["n_unknowns"])  # every estimated quantity, whatever the estimator
    measures = _measures(estimate, series, p)
    kalman = estimate.estimator == "kalman"
    criteria: list[dict[str, Any]] = []
    reasons: list[str] = []

    def judge(name: str, failed: list[str], applies: bool = True) -> None:
        criteria.append({"criterion": name, "applies": applies, "passed": not failed})
        reasons.extend(failed)

    r2 = {"T": measures["T"]["overall"]["r2"]}
    r2 |= {f"{cv['train']} -> {cv['test']}": cv["r2_T"] for cv in estimate.cross_validation}
    judge("r2", verdict(r2, thresholds={"r2_min": thresholds["r2_min"]})[1])
    judge("rmse", _rmse_reasons(measures, thresholds))
    judge("innovations_white", innovation_reasons(estimate, thresholds) if kalman else [], kalman)
    white = not kalman and bool(thresholds["require_white"])
    judge("residuals_white", _colour_reasons(measures, thresholds) if white else [], white)
    severe = [f for f in fit["flags"] if f["code"] not in NOTE_ONLY_FLAGS]
    judge("flags", verdict(1.0, severe)[1])
    judge("plausibility", plausibility(estimate, thresholds))
    judge("k_stage", list(estimate.notes))
    clock_notes: list[str] = []
    if "clocks" in estimate.content:  # a record of several sources: their clocks checked
        from railtherm.study import clocks

        judge("clocks", clocks.reasons(estimate.section("clocks")))
        clock_notes = clocks.notes(estimate.section("clocks"))
    notes = [f["message"] for f in fit["flags"] if f["code"] in NOTE_ONLY_FLAGS]
    notes += clock_notes
    notes += estimate.method_notes
    notes += skipped_checks(estimate)
    outlying = outlying_samples(estimate, series, thresholds)
    for found in outlying.values():
        notes += found.texts()
    head, tail = _record(estimate, measures, kalman)
    content = {
        **head,
        "verdict": IN_DOUBT if reasons else ACCEPTABLE,
        "reasons": reasons,
        "criteria": criteria,
        "judged_by": judged_by(criteria),
        "notes": notes,
        **tail,
        "outliers": {state: found.to_dict() for state, found in outlying.items()},
        **({"clocks": estimate.content["clocks"]} if "clocks" in estimate.content else {}),
    }
    return FitRecord.from_dict(content)


def _measures(estimate: EstimateRecord, series: pd.DataFrame, p: int) -> dict[str, Any]:
    """:func:`summary` of each compared output, overall and per window (``p`` unknowns)."""
    measures: dict[str, Any] = {}
    for state in estimate.outputs:
        overall = summary(series[state], series[f"{state}_sim"], p)
        windows = {
            name: summary(w[state], w[f"{state}_sim"], p)
            for name, w in series.groupby("window", sort=False)
        }
        measures[state] = {"overall": overall, "windows": windows}
    return measures


def _rmse_reasons(measures: Mapping[str, Any], thresholds: Mapping[str, Any]) -> list[str]:
    """Criterion ``rmse`` of :func:`check`: each simulated temperature that misses its
    measurement by more than ``max_rmse_K``, with its windows' too few effective samples."""
    missed = []
    for state, m in measures.items():
        rmse = m["overall"]["rmse"]
        if rmse > thresholds["max_rmse_K"]:
            limit = thresholds["max_rmse_K"]
            why = "twice a sensor's accuracy" if limit == RMSE_DEFAULT_K else "check.max_rmse_K"
            # as many digits as show the RMSE above its limit (0.2002, not "0.2 ... more than 0.2")
            digits = next((d for d in range(3, 9) if float(f"{rmse:.{d}g}") > limit), 9)
            missed.append(
                f"The simulated {state} misses the measurement by RMSE {rmse:.{digits}g} K "
                f"(more than {limit:g} K, {why}): the model lacks a dynamic or a heat path."
            )
            missed += verdict(
                1.0,
                whiteness={f"{state}, {w}": v for w, v in m["windows"].items()},
                thresholds={"min_effective_samples": thresholds["min_effective_samples"]},
            )[1]
    return missed


def _colour_reasons(measures: Mapping[str, Any], thresholds: Mapping[str, Any]) -> list[str]:
    """Criterion ``residuals_white`` of :func:`check`: the colour alone, not the effective
    samples."""
    return verdict(
        1.0,
        whiteness={state: m["overall"] for state, m in measures.items()},
        thresholds={
            "require_white": True,
            "whiteness_alpha": thresholds["whiteness_alpha"],
            "min_effective_samples": 0.0,
        },
    )[1]


def _record(
    estimate: EstimateRecord, measures: Mapping[str, Any], kalman: bool
) -> tuple[dict[str, Any], dict[str, Any]]:
    """What a fit file records of the estimate and its measures besides the verdict: the
    entries before the verdict's, and those after them (the fit file's order), taken from
    the estimate file's content (the fit's record copies them, :func:`check`)."""
    content = estimate.content
    fit = content["fit"]
    head = {
        "vehicle": content["vehicle"],
        "synthetic": content["synthetic"],
        "order": content["order"],
        "model": content["model"],
        "estimator": content.get("estimator", "output_error"),
        "structure": content["structure"],
        "input_hold": content.get("input_hold", "zero_order"),
        "k_source": content["k_source"],
        **{key: content.get(key) for key in K_STAGE_FIELDS},
        # a MAP fit says so, with its priors (docs/bayes.md); a maximum-likelihood one does not
        **{key: fit[key] for key in ("inference", "priors", "log_prior") if key in fit},
    }
    tail = {
        "parameters": fit["parameters"],
        # combinations the data determine however the capacity splits (C_total = C + C_veh)
        **({"totals": fit["totals"]} if fit.get("totals") else {}),
        # statistical correlation of the free log parameters (order of ``free``): the
        # aggregate propagates it into ratios such as delta = C_veh / C (eq. 25)
        "free": fit["free"],
        "correlation": fit["correlation"],
        "R2": measures["T"]["overall"]["r2"],
        "nrmse_fit": measures["T"]["overall"]["nrmse_fit"],
        "measures": measures,
        "cross_validation": content["cross_validation"],
        "flags": fit["flags"],
        "systematic": content["systematic"],
        "windows": content["windows"],
        "rows": content["rows"],
        "outputs": content["outputs"],
        **({key: fit[key] for key in ("loglik", "n_params", "n_obs")} if kalman else {}),
        **({"innovations": content["innovations"]} if kalman else {}),
        **({"innovations_of": content["innovations_of"]} if "innovations_of" in content else {}),
        **({"noise": fit["noise"]} if kalman and "noise" in fit else {}),
    }
    return head, tail
