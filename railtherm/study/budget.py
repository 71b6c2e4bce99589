"""The systematic (type B) part of a fit's uncertainty: each error source of the instruments
(:class:`ErrorSource`: a sensor offset, the power meter's scale, the tunnel air's offset, the
storage correction of kA, the surface sensors' offsets) shifts the records, the fit is
repeated on the shifted records (warm-started), and the parameters' moves, combined in
quadrature, are the systematic budget (:func:`systematic_budget`); the combined interval of
a parameter adds it to the statistical one (:func:`combine_uncertainty`)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from railtherm.estimation import pem
from railtherm.study.fitsettings import estimate_parameters, mean_offset_u, surface_states


def _perturbed(exps, column: Any, u: float) -> list:
    """Copies of the experiments with a systematic error of size u: an offset on a measured
    state (its index) or on T_o, a relative scale error on Q_H, or none (``column`` None). A
    measured initial state is the first row, so it carries the same error."""
    out = []
    for e in exps:
        y, inputs = e.y.copy(), e.u.copy()
        if column == "T_o":
            inputs[:, 0] += u
        elif column == "Q_H":
            inputs[:, 1] *= 1.0 + u
        elif column is not None:
            y[:, column] += u
        x0 = None if e.x0 is None else y[0].copy()
        out.append(replace(e, u=inputs, y=y, x0=x0))
    return out


@dataclass(frozen=True)
class ErrorSource:
    """One physical error source of the type-B budget at one standard uncertainty ``u``.

    ``column``: what it does to the identification windows (a state's index for a sensor
    offset, ``"T_o"``, ``"Q_H"`` for the power meters' scale, None for nothing); ``kA``: the
    static kA that eq. 10 gives on the k window with the same error (None when kA is not
    fixed from the static test); ``meaning``: one line for the reader."""

    name: str
    u: float
    column: Any
    kA: float | None
    meaning: str


def error_sources(structure, options, vehicle_data, kvalue, storage=None) -> list[ErrorSource]:
    """The physical error sources of a fit, each once, with what each does to both stages.

    With kA fixed from the static test, kA = mean(Q_H) / (mean(T) - mean(T_o)) over the k
    window (eq. 10). A scale error of the power meters or a calibration offset of a
    temperature sensor group moves the k window's means and the identification windows
    alike, so it reaches the capacities twice - through kA and through the fitted records -
    and both paths are taken together, as one perturbation (the k stage's u(k) is not added
    on top: its power and temperature components are these very sources). The k window's
    own random error (the scatter of its means) and the heat still going into storage reach
    the capacities through kA only. The surface A does not reach them at all: eq. 10
    measures kA and eqs. 7-8 use kA, so an error of A moves k alone.

    ``storage``: the applied storage-corrected k (:func:`storage_corrected_k`), whose kA is
    the one fixed. A scale error of Q_H scales it as it scales eq. 10's kA (every term of the
    window's energy balance scales with Q_H), and an offset u of T or T_o changes the integral
    of T - T_o alone, by u times the duration, so kA moves by the factor dT / (dT +- u) as
    eq. 10's does (dT the window's mean T - T_o); an offset of the surface sensors cancels
    in the change of T_veh. The correction's own random error (``k_storage``) then replaces
    both the k stage's storage bound and its scatter, which the regression's residuals hold."""
    u_power = float(vehicle_data["instruments"]["power_u_rel"])
    u_in = mean_offset_u(vehicle_data, "indoor")
    u_out = mean_offset_u(vehicle_data, "outdoor")
    static = "kA" in options["fixed"] and kvalue is not None
    kA = float(options["fixed"]["kA"]) if static else math.nan
    dT = float(kvalue["delta_T"]) if static else math.nan

    def k_stage(value: float) -> float | None:
        return float(value) if static else None

    sources = [
        ErrorSource(
            "power_scale",
            u_power,
            "Q_H",
            k_stage(kA * (1.0 + u_power)),
            "scale error of the power meters (instruments.power_u_rel)",
        ),
        ErrorSource(
            "offset_T",
            u_in,
            structure.states.index("T"),
            k_stage(kA * dT / (dT + u_in)),
            "calibration offset of the mean indoor temperature (u_K / sqrt(n_eff))",
        ),
        ErrorSource(
            "offset_T_o",
            u_out,
            "T_o",
            k_stage(kA * dT / (dT - u_out)),
            "calibration offset of the mean outdoor temperature (u_K / sqrt(n_eff))",
        ),
    ]
    for state in surface_states(structure, vehicle_data, options["outputs"]):
        sources.append(
            ErrorSource(
                f"offset_{state}",
                mean_offset_u(vehicle_data, "surface"),
                structure.states.index(state),
                k_stage(kA),
                "calibration offset of the mean surface temperature (u_K / sqrt(n))",
            )
        )
    if static:
        # the budget is in the unit of k, or of kA where no surface is given
        budget = kvalue["budget"]
        k = float(kvalue["kA"]) if kvalue.get("k") is None else float(kvalue["k"])
        if storage is None:
            u_scatter = float(budget["scatter"]) / k
            u_storage = float(budget["storage"]) / k
            sources.append(
                ErrorSource(
                    "k_scatter",
                    u_scatter,
                    None,
                    kA * (1.0 + u_scatter),
                    "random error of eq. 10 on the k window, from its energy balance "
                    "(relative to kA)",
                )
            )
            storage_meaning = "heat still going into storage during the k window (relative to kA)"
        else:
            # the correction's regression residuals hold eq. 10's scatter: one random term
            u_storage = float(storage["u_storage_kA"]) / float(storage["kA_corrected"])
            storage_meaning = (
                "random error of the storage-corrected kA: its energy-balance regression on "
                "eqs. 7-8 (residuals about the modelled storage, which hold eq. 10's scatter) "
                "and the capacities' statistical error, relative to kA"
            )
        sources.append(
            ErrorSource("k_storage", u_storage, None, kA * (1.0 + u_storage), storage_meaning)
        )
    return sources


def systematic_budget(
    structure, exps, options, result, vehicle_data, kvalue, storage=None
) -> dict[str, Any]:
    """Type-B uncertainty of the estimates (GUM): every physical error source
    (:func:`error_sources`) is applied once, at one standard uncertainty, to every record it
    touches - the static k window and the identification windows together - and the
    two-stage estimate is repeated from the estimate; the shift of log(theta) is that
    source's effect (a linearisation of the whole estimator, the GUM's sensitivity
    coefficient times u). The sources are independent, so their effects add in quadrature
    (:func:`combine_uncertainty`); the signed effects are kept for ratios such as delta."""
    warm = {**options, "initial": {p: result.theta[p] for p in result.free}, "start": "initial"}
    if not options.get("priors"):
        # only the point estimate is needed; a MAP estimate keeps its covariance setting,
        # which sets its likelihood's weight against the prior (pem._maximum_a_posteriori)
        warm["covariance"] = "iid"
    effects: dict[str, dict[str, float]] = {p: {} for p in result.free}
    # the same sources' effect on kA where the static test fixes it (eq. 10): with the free
    # parameters' effects, the joint distribution a prediction samples (railtherm.study.simulate)
    fixed_effects: dict[str, dict[str, float]] = {}
    sources = error_sources(structure, options, vehicle_data, kvalue, storage)
    for source in sources:
        if not source.u > 0:
            continue
        fixed = dict(options["fixed"])
        if source.kA is not None:
            fixed["kA"] = source.kA
            kA = float(options["fixed"]["kA"])
            shift = math.log(source.kA / kA) if source.kA > 0 and kA > 0 else math.inf
            fixed_effects.setdefault("kA", {})[source.name] = shift
        try:
            if not all(math.isfinite(v) and v > 0 for v in fixed.values()):
                raise ValueError("the k stage gives no kA under this error")
            perturbed = _perturbed(exps, source.column, source.u)
            refit = estimate_parameters(structure, perturbed, {**warm, "fixed": fixed})
            shifts = {p: float(np.log(refit.theta[p] / result.theta[p])) for p in result.free}
        except (np.linalg.LinAlgError, ValueError, FloatingPointError):
            shifts = {}
        for p in result.free:
            # a refit that fails or leaves the finite range: the estimate does not follow the
            # data smoothly (not identifiable), so its systematic effect is unbounded
            shift = shifts.get(p, math.inf)
            effects[p][source.name] = shift if math.isfinite(shift) else math.inf
    return {
        "method": (
            "GUM type B: each physical error source once, applied to the k window and the "
            "identification windows together, the two-stage estimate repeated"
        ),
        "sources": {s.name: float(s.u) for s in sources},
        "meaning": {s.name: s.meaning for s in sources},
        "effects_log": effects,
        "effects_log_fixed": fixed_effects,
    }


def combine_uncertainty(
    parameters: Mapping[str, Mapping[str, Any]], budget: Mapping[str, Any]
) -> dict[str, dict[str, Any]]:
    """The parameter entries (an estimator's ``parameters``, :meth:`Estimate.to_dict`) with
    each estimated parameter's 95 % interval ``ci95`` the combined one: the statistical sd of
    log(theta) (from the fit) and the effects of the independent error sources added in
    quadrature (``sd_log_total``). The statistical interval is kept as ``ci95_statistical``.
    Returns new entries; ``parameters`` is left as it is."""
    combined = {p: dict(entry) for p, entry in parameters.items()}
    for p, effects in budget["effects_log"].items():
        entry = combined[p]
        sd = float(np.sqrt(entry["sd_log"] ** 2 + sum(e**2 for e in effects.values())))
        log_value = np.log(entry["value"])
        entry["ci95_statistical"] = entry["ci95"]
        entry["sd_log_total"] = sd
        with np.errstate(over="ignore"):  # a non-identifiable parameter: [0, inf) is honest
            entry["ci95"] = [
                float(np.exp(log_value - pem.Z95 * sd)),
                float(np.exp(log_value + pem.Z95 * sd)),
            ]
    return combined
