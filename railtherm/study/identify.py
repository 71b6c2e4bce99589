"""One vehicle's identification: tidy windows + the static k stage -> PEM fits (paper section 5).

Stage two of the paper's two-stage approach (section 5.2): with kA = k A fixed from the
standardized static test (eq. 10), the heat capacities are estimated by simulation-error PEM
(eqs. 15-20, railtherm.estimation.pem): C_bar for the first-order model (eq. 19), C, K_veh and
C_veh for the second-order model (eq. 20). When the static k is not usable (its window failed the
steady-state test and was not forced) or the config asks for it (``model.mode: joint``), kA is
estimated with the capacities; every output says which way k was obtained.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from types import SimpleNamespace
from typing import Any

import numpy as np
import pandas as pd

from railtherm.data import plausibility as units_plausibility
from railtherm.errors import ConfigError
from railtherm.estimation import common, metrics, models, pem
from railtherm.estimation.priors import LinearT, bounded, prior_from_config
from railtherm.estimation.profile import kalman_profile, output_error_profile
from railtherm.records import EstimateRecord, JudgedEstimate, ParameterEstimate
from railtherm.study import identifiability
from railtherm.study.budget import combine_uncertainty, systematic_budget
from railtherm.study.fitsettings import (
    CONTRADICTION_Z,
    JOINT,
    SAME_ESTIMATE,
    compared_outputs,
    envelope_tables,
    estimate_parameters,
    experiments,
    hold_flags,
    input_hold,
    input_noise,
    kA_estimated,
    kA_expression,
    model_key,
    model_structure,
    physical_bounds,
    rows_used,
    split_key,
    stage_two_options,
    surface,
    surface_offsets,
)
from railtherm.study.quality import check_thresholds


def _judged_fit(structure, exps, options, vehicle_data, kvalue, storage):
    """One fit of ``structure`` with ``options``: the estimator's result, the
    :class:`~railtherm.records.JudgedEstimate` of it (the combined, statistical and type-B,
    intervals judged for identification) and the type-B budget."""
    result = estimate_parameters(structure, exps, options)
    budget = systematic_budget(structure, exps, options, result, vehicle_data, kvalue, storage)
    content = result.to_dict()
    content["parameters"] = combine_uncertainty(content["parameters"], budget)
    fitted = JudgedEstimate.from_dict(content)
    if "kA" not in fitted.parameters:
        content["parameters"]["kA"] = derived_kA(fitted, structure)
        fitted = JudgedEstimate.from_dict(content)
    fitted = judge_identification(
        fitted,
        {**structure.bounds, **options["bounds"]},
        structure,
        physical={
            p: what
            for p, (floor, what) in physical_bounds(structure, vehicle_data).items()
            if float(options["bounds"][p][0]) == floor
        },
        budget=budget,
    )
    return result, fitted, budget


def _not_identified(fitted: JudgedEstimate, structure: models.Structure) -> list[str]:
    """The estimated parameters of ``fitted`` judged not identified, in the structure's order."""
    params = fitted.parameters
    return [
        p
        for p in structure.parameters
        if p in params and params[p].estimated and not params[p].identified
    ]


def _static_kA_check(
    structure, exps, options, vehicle_data, kvalue, storage, static
) -> tuple[dict[str, Any], tuple | None, Any]:
    """Whether the identification records accept the two-stage fit (``static``: its result,
    judged estimate and budget), which holds the static kA fixed.

    The same structure is fitted with kA free (the joint fit, started at the static kA), and
    kA and each coupled parameter are compared between the two (:func:`_differences`: z of
    the log difference). The static kA is measured independently of the records; under the
    two-stage premise both fits estimate the same values and differ within their
    uncertainties. Where a |z| exceeds ``CONTRADICTION_Z`` they do not: either the records
    contradict the static kA, or the capacities follow kA so steeply (several optima of a fit
    of T alone, a factor 3 for 0.4 % of kA) that the linearised type-B effect of kA's
    uncertainty does not describe them - the joint fit, which carries kA's uncertainty in its
    own covariance, is reported then. Where the static kA leaves a parameter not identified,
    likewise. Either only where the joint fit determines every parameter and its kA lies
    within ``CONTRADICTION_Z`` times the static test's own relative uncertainty (the
    storage-corrected kA's where ``storage`` is given, else eq. 10's): two independent
    measurements of kA that disagree beyond that (a heat source or sink the model lacks moves
    the joint kA as far as it likes) leave the two-stage fit in place with a note that says
    so (a verdict reason). Returns the check's record for the fit file (``kA_static``,
    ``kA_joint``, ``z`` per parameter, ``kA_within_static_u``, ``use_joint`` and its
    ``reason``; with ``note`` where the fit is replaced or in conflict), where the joint
    fit replaces the two-stage one its (result, judged estimate, budget, options), else None, and
    the joint fit's result (None where it failed)."""
    _, fitted, budget = static
    kA_static = float(options["fixed"]["kA"])
    if storage:
        u_static_rel = float(storage["u_kA_corrected"]) / float(storage["kA_corrected"])
    else:
        u_static_rel = float(kvalue.get("u_k_rel") or 0.0)
    joint_options = kA_estimated(options, kA_static)
    record: dict[str, Any] = {"kA_static": kA_static, "use_joint": False}
    try:
        joint = _judged_fit(structure, exps, joint_options, vehicle_data, kvalue, None)
    except (np.linalg.LinAlgError, ValueError, FloatingPointError) as err:
        record["reason"] = f"the joint fit failed ({err})"
        return record, None, None
    kA_joint = joint[1].parameters["kA"].value
    z = _differences(structure, (fitted, budget), joint, kA_static)
    undetermined = _not_identified(fitted, structure)
    joint_undetermined = _not_identified(joint[1], structure)
    worst = max(z, key=lambda p: abs(z[p]) if math.isfinite(z[p]) else -1.0)
    contradicted = math.isfinite(z[worst]) and abs(z[worst]) > CONTRADICTION_Z
    d_kA = math.log(kA_joint / kA_static)
    within = abs(d_kA) <= max(CONTRADICTION_Z * u_static_rel, SAME_ESTIMATE)
    record.update(kA_joint=kA_joint, z=z, u_static_rel=u_static_rel, kA_within_static_u=within)
    if not (undetermined or contradicted):
        record["reason"] = "the records accept the two-stage fit"
        return record, None, joint[0]
    if joint_undetermined:
        record["reason"] = (
            f"the joint fit leaves {', '.join(joint_undetermined)} not identified: the "
            "two-stage fit stays"
        )
        return record, None, joint[0]
    if not within:
        # two independent measurements of kA disagree beyond the static test's own
        # uncertainty: the records' kA cannot simply replace it (a heat source the model
        # lacks moves the joint kA as far as it likes), and the two-stage fit stays in doubt
        record["reason"] = STATIC_CONFLICT
        record["note"] = (
            f"the static test and the records disagree: with kA free the records give kA "
            f"{kA_joint:.4g} W/K, {100 * math.expm1(d_kA):+.2f} % from the static "
            f"{kA_static:.4g} W/K, more than {CONTRADICTION_Z:g} times the static test's own "
            f"uncertainty ({100 * u_static_rel:.2g} %): a heat source or sink the model lacks, "
            "or a k window that does not measure the loss; the two-stage fit is kept"
        )
        return record, None, joint[0]
    agreement = _kA_agreement(kA_joint, kA_static, d_kA, u_static_rel, z["kA"])
    if undetermined:
        record["reason"] = STATIC_UNDETERMINED
        note = (
            f"the static kA ({kA_static:.4g} W/K), held fixed, left "
            f"{', '.join(undetermined)} not identified; the joint fit ({agreement}, kA "
            "estimated with the capacities) determines every parameter and is reported"
        )
    else:
        record["reason"] = STATIC_CONTRADICTED
        static_value = kA_static if worst == "kA" else fitted.parameters[worst].value
        joint_value = joint[1].parameters[worst].value
        if worst == "kA":
            what = f"with kA free (the joint fit) {agreement}"
        else:
            what = (
                f"with kA free (the joint fit: {agreement}) {worst} is {joint_value:.4g} "
                f"against {static_value:.4g}, z = {z[worst]:+.1f}, more than "
                f"{CONTRADICTION_Z:g} standard uncertainties of the difference"
            )
        note = (
            f"the records contradict the two-stage fit: {what}; the fit with the static kA "
            "held fixed does not hold against kA's own uncertainty, so the joint fit is "
            "reported"
        )
    own = [f["message"] for f in fitted.flags]
    if own:  # what the two-stage fit showed stays in view (a misfit shows in it first)
        note += "; the two-stage fit's own flags: " + "; ".join(own)
    record["two_stage"] = {p: fitted.parameters[p].value for p in ("kA", *structure.coupled)}
    record.update(use_joint=True, note=note)
    return record, (*joint, joint_options), joint[0]


def _kA_agreement(kA_joint, kA_static, d_kA, u_static_rel, z_kA) -> str:
    """How the joint kA stands to the static one, in words that hold for both yardsticks at
    once: the static test's own relative uncertainty (``within`` of :func:`_static_kA_check`)
    and z of their difference (:func:`_differences`), whose standard uncertainty leaves out
    the errors both estimates share and so can be the smaller."""
    text = (
        f"kA {kA_joint:.4g} W/K, {100 * math.expm1(d_kA):+.2f} % from the static "
        f"{kA_static:.4g} W/K, within {CONTRADICTION_Z:g} times the static test's own "
        f"uncertainty ({100 * u_static_rel:.2g} %)"
    )
    if not math.isfinite(z_kA):
        return text
    if abs(z_kA) <= CONTRADICTION_Z:
        return f"{text}, z = {z_kA:+.1f} of their difference"
    sd = abs(d_kA / z_kA)
    return (
        f"{text}, but z = {z_kA:+.1f} of their difference, more than {CONTRADICTION_Z:g}: "
        f"the difference's standard uncertainty ({100 * sd:.2g} %) leaves out the errors both "
        "estimates share (the power meters' scale, the sensors' offsets), so the records "
        "determine kA more closely than the static test does"
    )


def _differences(structure, static, joint, kA_static: float) -> dict[str, float]:
    """z of ln(joint / two-stage) for kA and each coupled parameter: the difference over its
    standard uncertainty, the two fits' statistical sds in quadrature (the same records make
    them correlated, so this is on the wide side) and, per error source, the difference of
    the source's effects on the two estimates (a source moving both alike cancels; the k
    window's own random error moves the static kA alone). NaN where an sd is not finite; 0
    where the two agree within ``SAME_ESTIMATE`` (noise-free records give sds near 0)."""
    (fitted, budget), (_, joint_fitted, joint_budget) = static, joint
    z = {}
    for p in ("kA", *structure.coupled):
        if p == "kA":
            value, sd = kA_static, 0.0
            effects = budget.get("effects_log_fixed", {}).get("kA", {})
        else:
            value = fitted.parameters[p].value
            sd = float(fitted.parameters[p].sd_log)
            effects = budget["effects_log"].get(p, {})
        entry = joint_fitted.parameters[p]
        joint_effects = joint_budget["effects_log"].get(p, {})
        variance = sd**2 + float(entry.sd_log) ** 2
        variance += sum(
            (joint_effects.get(s, 0.0) - effects.get(s, 0.0)) ** 2
            for s in sorted(set(effects) | set(joint_effects))
        )
        d = math.log(entry.value / value)
        finite = variance > 0 and math.isfinite(variance)
        if abs(d) <= SAME_ESTIMATE:  # one estimate, as far as the optimiser resolves it
            z[p] = 0.0
        else:
            z[p] = d / math.sqrt(variance) if finite else math.nan
    return z


STATIC_UNDETERMINED = "the static kA left the capacities not identified"
STATIC_CONTRADICTED = "the records contradict the two-stage fit"
STATIC_CONFLICT = "the static test and the records disagree"
# a two-stage Kalman fit's whiteness is judged on the joint fit of its check: the static kA,
# held fixed, errs within its own uncertainty, and that error alone colours the innovations
# of a long record; its agreement with the records is the k method's criterion
WHITENESS_OF_JOINT = "the fit with kA free (the two-stage check's joint fit)"


def fit_setup(
    tables: Mapping[str, pd.DataFrame],
    vehicle_data: Mapping[str, Any],
    kvalue: Mapping[str, Any] | None,
    order: int | str,
    storage: Mapping[str, Any] | None = None,
    prior_terms: Sequence[LinearT] = (),
) -> SimpleNamespace:
    """What the stage-two fit of the model ``order`` (a model key) runs on, as
    :func:`identify` sets it up: ``structure``, ``tables`` (with the envelope's),
    ``exps`` (the experiments), ``options`` (the estimator's, kA held at the static or the
    storage-corrected value), ``outputs``, ``estimator``, ``k_source``, ``notes`` and
    ``storage`` (the storage correction where applied, else None)."""
    structure = model_structure(order, vehicle_data)
    tables = envelope_tables(structure, vehicle_data, tables)
    outputs = compared_outputs(structure, vehicle_data, tables)
    estimator = split_key(order)[1]
    options, k_source, notes = stage_two_options(structure, vehicle_data, kvalue, tables, estimator)
    if prior_terms:
        options["prior_terms"] = list(prior_terms)
    applied = bool(storage and storage.get("applied")) and "kA" in options["fixed"]
    if applied:
        options["fixed"]["kA"] = float(storage["kA_corrected"])
        k_source += ", storage-corrected"
    if estimator == "kalman":
        options["estimator"] = "kalman"
        options["offsets"] = surface_offsets(structure, vehicle_data, options["outputs"])
    exps = experiments(structure, tables, input_hold(vehicle_data))
    options["input_noise"] = input_noise(structure, vehicle_data, exps)
    return SimpleNamespace(
        structure=structure, tables=tables, exps=exps, options=options, outputs=outputs,
        estimator=estimator, k_source=k_source, notes=notes,
        storage=storage if applied else None,
    )  # fmt: skip


def identify(
    tables: Mapping[str, pd.DataFrame],
    vehicle_data: Mapping[str, Any],
    kvalue: Mapping[str, Any] | None,
    order: int,
    storage: Mapping[str, Any] | None = None,
    prior_terms: Sequence[LinearT] = (),
) -> tuple[EstimateRecord, pd.DataFrame]:
    """Fit the model of ``order`` to all identification windows jointly (one parameter set,
    own initial states); cross-validate when there are two or more windows.

    ``storage``: the storage-corrected k of the vehicle (:func:`storage_corrected_k`); where
    it is applied, its kA is the one held fixed (first- and second-order fits alike) and its
    uncertainty replaces the k stage's storage bound in the type-B budget. Without it (or not
    applied) kA is that of eq. 10. ``prior_terms``: joint prior terms on the model's log
    parameters (the class as a prior,
    :meth:`railtherm.study.classmodel.ReferenceModel.prior_terms`): a MAP fit (docs/bayes.md).

    Returns the estimate (:class:`~railtherm.records.EstimateRecord`, the content of
    identify/<model>.yaml) and the series table (per window: time,
    measured and simulated states, residuals and inputs).
    """
    setup = fit_setup(tables, vehicle_data, kvalue, order, storage, prior_terms)
    structure, tables, exps, options = setup.structure, setup.tables, setup.exps, setup.options
    outputs, estimator, k_source, notes = (
        setup.outputs,
        setup.estimator,
        setup.k_source,
        setup.notes,
    )
    fixed = options["fixed"]
    rows = rows_used(structure, tables, outputs, vehicle_data)
    storage_used = setup.storage
    from railtherm.estimation.kalman import NotEvaluable

    try:
        result, fitted, budget = _judged_fit(
            structure, exps, options, vehicle_data, kvalue, storage_used
        )
    except NotEvaluable as err:  # the fit itself; a joint check's failure is only recorded
        raise ConfigError(
            f"vehicle {vehicle_data.get('id')}",
            "model.estimator",
            "kalman",
            f"{err}: the data do not determine this model by the Kalman filter; fit "
            f"{structure.key} by output error only (model.estimator: output_error), or "
            "bound the parameters named in model.bounds",
        ) from None
    method_notes: list[str] = []
    checked = bool(vehicle_data["model"].get("two_stage_check", True))
    whiteness_fit = None  # a two-stage fit's whiteness: its check's joint fit (kA free)
    static_check = None
    if checked and "kA" in fixed and kvalue is not None and structure.coupled:
        check, joint, joint_result = _static_kA_check(
            structure, exps, options, vehicle_data, kvalue, storage_used, (result, fitted, budget)
        )
        if joint is None:
            whiteness_fit = joint_result
        if joint is not None:
            result, fitted, budget, options = joint
            fixed = options["fixed"]
            k_source = f"{JOINT[estimator]}: {check['reason']}"
        if check.get("note"):
            # a conflict of the two kA measurements is a reason of the verdict; the joint
            # fit's replacing a two-stage fit whose kA agrees with it is a note: nothing in
            # the reported fit's assumptions is in doubt (the joint fit is judged itself)
            (method_notes if check["use_joint"] else notes).append(check["note"])
        static_check = check
    fitted = profile_limits(structure, exps, options, result, fitted)
    fit_section = fitted.to_dict()
    if static_check is not None:
        fit_section["static_kA_check"] = static_check
    fit_section["flags"] = [*fit_section["flags"], *hold_flags(structure, vehicle_data, tables)]
    estimate = {
        "vehicle": vehicle_data["id"],
        "synthetic": bool(vehicle_data.get("synthetic", False)),
        "order": len(structure.states),
        "model": model_key(order),
        "estimator": estimator,
        "structure": structure.name,
        "input_hold": input_hold(vehicle_data),
        "k_source": k_source,
        **k_stage_fields(fixed.get("kA"), kvalue, storage, vehicle_data),
        "A": surface(vehicle_data),
        "mass_kg": float(vehicle_data["mass_kg"]) if "mass_kg" in vehicle_data else None,
        "volume_m3": float(vehicle_data["volume_m3"]) if "volume_m3" in vehicle_data else None,
        "outputs": list(outputs),
        "windows": list(tables),
        "rows": rows,
        "notes": notes,
        "method_notes": method_notes,
        "fit": fit_section,
        "systematic": budget,
        "cross_validation": _cross_validate(structure, exps, options) if len(exps) > 1 else [],
        "unit_checks": unit_checks(fitted, vehicle_data, tables),
    }
    if len(vehicle_data.get("sources") or {}) > 1:
        estimate["clocks"] = _clocks(structure, tables, vehicle_data, options, result)
    series = _series(structure, exps, result)
    if estimator == "kalman":
        series = _innovation_series(structure, series, result)
        alpha = float(check_thresholds(vehicle_data.get("check"))["whiteness_alpha"])
        tested = series
        if whiteness_fit is not None:  # the joint fit's innovations, beside the reported rows
            tested = _innovation_series(structure, series.iloc[:, :0], whiteness_fit)
            estimate["innovations_of"] = WHITENESS_OF_JOINT
        estimate["innovations"] = innovation_tests(tested, outputs, alpha)
        estimate["fit"]["loglik"] = float(result.loglik)
        estimate["fit"]["n_params"] = int(result.n_params)
    return EstimateRecord.from_dict(estimate), series


def _clocks(structure, tables, vehicle_data, options, result) -> dict[str, Any]:
    """Each source's clock against the indoor air's, by the profile of this fit's criterion
    over shifts of the source (:mod:`railtherm.study.clocks`), every refit started at this
    fit's values."""
    from railtherm.study import clocks

    warm = dict(options)
    warm["initial"] = {p: v for p, v in result.theta.items() if p not in options["fixed"]}
    warm["start"] = "initial"
    if warm.get("estimator", "output_error") != "kalman":
        warm["covariance"] = "iid"  # the criterion only: no interval needed
    hold = input_hold(vehicle_data)

    def refit(moved: Mapping[str, pd.DataFrame]):
        moved = envelope_tables(structure, vehicle_data, moved)
        return estimate_parameters(structure, experiments(structure, moved, hold), warm)

    return clocks.clock_offsets(refit, result, tables, vehicle_data)


def unit_checks(
    fitted: JudgedEstimate, vehicle_data: Mapping[str, Any], tables: Mapping[str, pd.DataFrame]
) -> list[str]:
    """The plausibility of the records and of the fitted k against a temperature channel's
    unit (:mod:`railtherm.data.plausibility`): a heated cabin colder than the tunnel or never
    at a heated cabin's temperature, and k = kA / A far from the vehicle class's; sentences
    naming the raw files, the channels and their declared units, for the verdict."""
    out = units_plausibility.record_reasons(tables, vehicle_data)
    entry = fitted.parameters.get("kA")
    A = surface(vehicle_data)
    if entry is not None and A and entry.identified:
        far = units_plausibility.k_class_reason(entry.value / A, vehicle_data, "the fit's")
        if far is not None:
            out.append(far)
    return out


def k_stage_fields(
    kA_fixed: float | None,
    kvalue: Mapping[str, Any] | None,
    storage: Mapping[str, Any] | None,
    vehicle_data: Mapping[str, Any],
) -> dict[str, Any]:
    """The k stage as a fit file gives it: ``kA_fixed`` (the kA held in stage two, None where
    it is estimated), ``k_eq10``/``u_k_eq10`` (the standard's eq. 10, as kvalue.yaml has it),
    ``k_corrected``/``u_k_corrected`` (storage-corrected, None where not applied) and the
    correction's record ``storage_correction`` (:func:`storage_corrected_k`, with ``applied``
    false and its ``reason`` where it was not made); k in W/(m^2 K),
    or kA in W/K where no surface is given (then the k_ fields hold kA)."""
    A = surface(vehicle_data)
    per = 1.0 if A is None else A
    out: dict[str, Any] = {
        "kA_fixed": None if kA_fixed is None else float(kA_fixed),
        "k_eq10": None,
        "u_k_eq10": None,
        "k_corrected": None,
        "u_k_corrected": None,
    }
    if kvalue and kvalue.get("kA") is not None:
        kA = float(kvalue["kA"]) if A is None or kvalue.get("k") is None else kvalue["k"] * A
        out["k_eq10"] = float(kA / per)
        if kvalue.get("u_k_rel") is not None:
            out["u_k_eq10"] = float(kvalue["u_k_rel"]) * kA / per
    if storage and storage.get("applied"):
        out["k_corrected"] = float(storage["kA_corrected"]) / per
        out["u_k_corrected"] = float(storage["u_kA_corrected"]) / per
    out["storage_correction"] = dict(storage) if storage else None
    return out


def _innovation_series(structure, series: pd.DataFrame, result) -> pd.DataFrame:
    """The series table with the kalman fit's one-step predictions ``<state>_one_step``, its
    innovations ``<state>_innovation`` (measured - predicted; empty where not measured) and
    their standard deviations ``<state>_innovation_sd`` (the filter's sqrt(R_k)) per output."""
    extra = {}
    for j, state in enumerate(result.outputs):
        i = structure.states.index(state)
        extra[f"{state}_one_step"] = np.concatenate([x[:, i] for x in result.one_step])
        extra[f"{state}_innovation"] = np.concatenate([e[:, j] for e in result.innovations])
        extra[f"{state}_innovation_sd"] = np.sqrt(
            np.concatenate([r[:, j] for r in result.innovation_var])
        )
    return series.assign(**extra)


def innovation_tests(
    series: pd.DataFrame, outputs: Sequence[str], alpha: float
) -> dict[str, dict[str, Any]]:
    """Whiteness of each output's standardised one-step innovations (innovation / its
    sd), the windows one after the other: Ljung-Box and the cumulated periodogram test of
    CTSM-R (:func:`railtherm.estimation.diagnostics.residual_tests`) at level ``alpha``. A correct
    stochastic model leaves white innovations."""
    from railtherm.estimation import diagnostics

    tests = {}
    for state in outputs:
        z = series[f"{state}_innovation"] / series[f"{state}_innovation_sd"]
        tests[state] = diagnostics.residual_tests(z.to_numpy(float), alpha=alpha).to_dict()
    return tests


def derived_kA(fitted: JudgedEstimate, structure: models.Structure) -> dict[str, Any]:
    """The overall heat-loss coefficient of a structure without a parameter kA (e.g. losses
    in series, kA = K_i K_o / (K_i + K_o)), from its steady state
    (:meth:`~railtherm.structures.Structure.kA_log_gradient`), with a 95 % interval by the
    delta method on the log parameters (their combined sds and the fit's correlation):
    d log kA = sum_p (d log kA / d log p) d log p. Returns the entry of kA."""
    par = fitted.parameters
    theta = {p: par[p].value for p in structure.parameters}
    value, gradient = structure.kA_log_gradient(theta)
    free = list(fitted.free)
    corr = fitted.correlation
    moving = [p for p in free if gradient.get(p, 0.0) != 0.0]
    g = np.array([gradient[p] for p in moving])
    sd = np.array([_sd_log_total(par[p]) for p in moving])
    idx = [free.index(p) for p in moving]
    gs = g * sd
    var = float(gs @ corr[np.ix_(idx, idx)] @ gs) if moving else 0.0
    sd_log = float(np.sqrt(max(var, 0.0)))
    with np.errstate(over="ignore"):
        ci = [float(value * np.exp(-pem.Z95 * sd_log)), float(value * np.exp(pem.Z95 * sd_log))]
    return {
        "value": float(value),
        "estimated": "derived",
        "derived_from": kA_expression(structure),
        "ci95": ci,
        "sd_log_total": sd_log,
    }


def _sd_log_total(entry: ParameterEstimate) -> float:
    """The combined sd of a parameter's log, its statistical one where no budget combined it."""
    if entry.sd_log_total is not None:
        return entry.sd_log_total
    return 0.0 if entry.sd_log is None else entry.sd_log


def profile_limits(structure, exps, options, result, fitted: JudgedEstimate) -> JudgedEstimate:
    """``fitted`` with each estimated parameter it judges not identified given the limits
    of its profile likelihood (:func:`railtherm.estimation.profile.output_error_profile`: the
    other parameters re-fitted at each value; for the Kalman filter's fit
    :func:`railtherm.estimation.profile.kalman_profile`, by its likelihood): a one-sided limit
    the data give ("lower": at least, "upper": at most) replaces ``limit: none``; the profile
    is kept under ``profile`` and said in the reason. A parameter the profile bounds on both
    sides stays not identified (its interval at the optimum said otherwise), with the
    profile's interval in the reason."""
    kalman = options.get("estimator", "output_error") == "kalman"
    profiler = kalman_profile if kalman else output_error_profile
    content = fitted.to_dict()
    fit_options = {k: v for k, v in options.items() if k != "estimator"}
    if kalman:
        fit_options.pop("covariance", None)  # the filter's observed information gives it
    for p, entry in content["parameters"].items():
        if not entry.get("estimated") or entry.get("identified", True) or p not in result.free:
            continue
        limit = profiler(structure, exps, p, result, **fit_options)
        entry["profile"] = limit.to_dict()
        entry["reason"] = f"{entry.get('reason', 'not identified')}; {limit.phrase()}"
        if limit.kind in ("lower", "upper"):
            entry["limit"] = limit.kind
            entry["limit_value"] = float(limit.lower if limit.kind == "lower" else limit.upper)
    return JudgedEstimate.from_dict(content)


def judge_identification(
    fitted: JudgedEstimate,
    bounds: Mapping[str, tuple],
    structure: models.Structure | None = None,
    physical: Mapping[str, str] | None = None,
    budget: Mapping[str, Any] | None = None,
) -> JudgedEstimate:
    """``fitted`` (an estimator's result with combined intervals) with every estimated
    parameter marked with :func:`railtherm.estimation.pem.identification`; the width judged
    is that of the interval a reader sees - the combined one - rather than the fit's
    statistical one: the ``wide_interval`` flags are replaced by flags on the combined
    intervals.

    With the ``structure``: its coupled parameters (``Structure.coupled``, the dynamic part)
    are judged together (:func:`railtherm.study.identifiability.coupled_identification`), and each
    of its totals (``Structure.totals``: C_total = C + C_veh, the capacity eq. 9 lumps into C_bar)
    is written under ``totals`` with its 95 % interval
    (:func:`railtherm.study.identifiability.total_capacity`, ``budget`` the systematic budget).
    ``physical``:
    {param: what its lower bound is} for a bound the metadata make physical
    (:func:`physical_bounds`), named in the reason. Returns the judged estimate; ``fitted``
    is left as it is."""
    physical = dict(physical or {})
    content = fitted.to_dict()
    pinned = {p for f in content["flags"] if f["code"] == "at_bound" for p in f["parameters"]}
    # the search's bounds: a uniform prior narrows them (a class prior's terms do not)
    uniform = {
        p: prior_from_config(spec, p)
        for p, spec in (content.get("priors") or {}).items()
        if spec.get("kind") == "uniform"
    }
    searched = bounded(bounds, uniform)
    flags = [f for f in content["flags"] if f["code"] != "wide_interval"]
    for p, entry in content["parameters"].items():
        if not entry.get("estimated"):
            continue
        at_bound = None
        if p in pinned:
            lo_b, hi_b = (float(b) for b in searched[p])
            lower = abs(math.log(entry["value"] / lo_b)) <= abs(math.log(hi_b / entry["value"]))
            at_bound = ("lower", lo_b) if lower else ("upper", hi_b)
            if lower and p in physical:
                at_bound = ("lower", lo_b, physical[p])
        entry.update(pem.identification(entry["value"], entry["ci95"], at_bound))
        lo, hi = entry["ci95"]
        if not (lo > 0 and hi / lo <= common.WIDE_RATIO) and p in content["free"]:
            flags.append(
                pem.Flag(
                    "wide_interval",
                    (p,),
                    f"the combined 95 % interval of {p} spans more than a decade ({lo:.3g} to "
                    f"{hi:.3g}): the data hardly determine it",
                ).to_dict()
            )
    content["flags"] = flags
    if structure is None:
        return JudgedEstimate.from_dict(content)
    params = content["parameters"]
    estimated = {p: params[p] for p in structure.coupled if params.get(p, {}).get("estimated")}
    for p, judged in identifiability.coupled_identification(estimated, structure.coupled).items():
        params[p].update(judged)
    marked = JudgedEstimate.from_dict(content)
    totals = {}
    for name, parts in structure.totals.items():
        if all(p in params for p in parts):
            totals[name] = identifiability.total_capacity(
                marked, parts, (budget or {}).get("effects_log")
            )
    if totals:
        content["totals"] = totals
    return JudgedEstimate.from_dict(content)


def _series(structure, exps, result) -> pd.DataFrame:
    frames = []
    for exp, sim in zip(exps, result.simulated, strict=True):
        n = len(exp.u)
        frame = {"window": [exp.name] * n, "time": np.arange(n) * exp.dt}
        for i, state in enumerate(structure.states):
            frame[state] = exp.y[:, i]
            frame[f"{state}_sim"] = sim[:, i]
            frame[f"{state}_residual"] = exp.y[:, i] - sim[:, i]
        for j, name in enumerate(structure.inputs):
            frame[name] = exp.u[:, j]
        frames.append(pd.DataFrame(frame))
    return pd.concat(frames, ignore_index=True)


def _cross_validate(structure, exps, options) -> list[dict[str, Any]]:
    """Fit on each window alone; R^2 (eq. 21) of the simulated T on every other window."""
    rows = []
    noise = options.get("input_noise") or {}
    for i, train in enumerate(exps):
        alone = {**options, "input_noise": {n: [v[i]] for n, v in noise.items()}}
        fitted = estimate_parameters(structure, [train], alone)
        for test in exps:
            if test is train:
                continue
            if np.all(np.isfinite(test.x0)):
                sim = models.simulate(structure, fitted.theta, test.u, test.dt, test.x0, test.hold)
            else:  # an unmeasured initial state: estimate only it, theta held
                held = {**options, "fixed": dict(fitted.theta), "initial": {}, "bounds": {}}
                held["input_noise"] = {}
                held.pop("estimator", None)  # the simulation of the same parameters
                held.pop("offsets", None)
                sim = pem.fit(structure, [test], **{**held, "x0": "estimated"}).simulated[0]
            rows.append(
                {
                    "train": train.name,
                    "test": test.name,
                    "r2_T": float(metrics.r2(test.y[:, 0], sim[:, 0])),
                    "theta": {p: float(v) for p, v in fitted.theta.items()},
                }
            )
    return rows
