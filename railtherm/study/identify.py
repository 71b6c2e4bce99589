"""One vehicle's identification: tidy windows + the static k stage -> PEM fits (paper section 5).

Stage two of the paper's two-stage approach (section 5.2): with kA = k A fixed from the
standardized static test (eq. 10), the heat capacities are estimated by simulation-error PEM
(eqs. 15-20, railtherm.estimation.pem): C_bar for the first-order model (eq. 19), C, K_veh and
C_veh for the second-order model (eq. 20). When the static k is not usable (its window failed the
steady-state test and was not forced) or the config asks for it (``model.mode: joint``), kA is
estimated with the capacities; every output says which way k was obtained.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import pandas as pd

from railtherm import structures
from railtherm.data import ingest
from railtherm.data import plausibility as units_plausibility
from railtherm.errors import ConfigError, DataError
from railtherm.estimation import metrics, models, outliers, pem
from railtherm.estimation.kvalue import COMPONENTS, sensor_counts, sensor_u_K, storage_corrected_kA
from railtherm.study import identifiability, quality
from railtherm.yamlio import packaged_schema, validate_schema

KA_BOUNDS = (1.0, 1.0e5)  # W/K, for joint estimation when the config gives none nor a scale
# the default search range of a conductance estimated jointly: this factor either side of the
# record's own scale (the static kA, 2 W/(m^2 K) on the surface, or the windows' energy
# balance), so a 4 W/K test box and a 2000 W/K coach both start well inside their bounds
CONDUCTANCE_SPAN = 1.0e3


def conductance_bounds(kA_start: float | None) -> tuple[float, float]:
    """The default bounds (W/K) of kA, K_i and K_o estimated jointly: ``CONDUCTANCE_SPAN``
    either side of ``kA_start``, or :data:`KA_BOUNDS` where the record gives no scale."""
    if kA_start is None or not (math.isfinite(kA_start) and kA_start > 0):
        return KA_BOUNDS
    return (kA_start / CONDUCTANCE_SPAN, kA_start * CONDUCTANCE_SPAN)


# the estimators of model.estimator: the paper's simulation-error PEM (K = 0,
# railtherm.estimation.pem)
# and the Kalman-filter maximum-likelihood PEM of the stochastic model (railtherm.estimation.kalman)
ESTIMATORS = ("output_error", "kalman")
KALMAN_SUFFIX = "_kalman"  # the model key of a kalman fit: order2_kalman, fit_order2_kalman.yaml


def estimators(vehicle_data: Mapping[str, Any]) -> list[str]:
    """``model.estimator`` of a vehicle as a list (default: output_error alone)."""
    chosen = (vehicle_data.get("model") or {}).get("estimator", "output_error")
    return [chosen] if isinstance(chosen, str) else list(chosen)


def model_keys(vehicle_data: Mapping[str, Any]) -> list[str]:
    """The models a vehicle's config asks for: its orders (order1, order2), then any further
    structures (``model.structures``, :mod:`railtherm.structures`), each once per estimator
    (``model.estimator``): the key itself for output_error, with the suffix ``_kalman`` for
    kalman."""
    model = vehicle_data["model"]
    keys = [f"order{int(n)}" for n in model["orders"]] + list(model.get("structures") or [])
    suffix = {"output_error": "", "kalman": KALMAN_SUFFIX}
    return [key + suffix[e] for key in keys for e in estimators(vehicle_data)]


def split_key(key: int | str) -> tuple[str, str]:
    """A model key -> (the structure's key, the estimator): ``"order2_kalman"`` ->
    ``("order2", "kalman")``, ``2`` -> ``("order2", "output_error")``."""
    text = str(key)
    if text.endswith(KALMAN_SUFFIX):
        return model_key(text[: -len(KALMAN_SUFFIX)]), "kalman"
    return model_key(text), "output_error"


def model_key(order: int | str) -> str:
    """``1``, ``"1"`` or ``"order1"`` -> ``"order1"``; a structure key stays as it is."""
    text = str(order)
    return f"order{text}" if text.isdigit() else text


def irradiance_inputs(vehicle_data: Mapping[str, Any]) -> list[str]:
    """The vehicle's irradiance inputs as :func:`railtherm.estimation.models.structure_for` takes
    them:
    I_<name> for a gain into the air node, I_<name>@envelope or I_<name>@both for one declared
    on the envelope node or shared (``channels.irradiance[i].node``, default air)."""
    names = ingest.irradiance_names(vehicle_data)
    channels = list((vehicle_data.get("channels") or {}).get("irradiance") or [])
    nodes = [str(c.get("node") or "air") for c in channels]
    return [n if node == "air" else f"{n}@{node}" for n, node in zip(names, nodes, strict=True)]


def model_structure(order: int | str, vehicle_data: Mapping[str, Any] | None = None):
    """The structure of a model key, with the vehicle's irradiance inputs (eq. 1), each on
    the node its channel declares. A gain declared on the envelope (or both) where the model
    has one node (order1) is a :class:`ConfigError` naming the channel."""
    irradiance = irradiance_inputs(vehicle_data) if vehicle_data else []
    base = structures.by_key(split_key(order)[0])
    name = base.name
    for i, spec in enumerate(irradiance):
        node = models.irradiance_spec(spec)[1]
        if node != "air" and not base.envelope:
            raise ConfigError(
                vehicle_data.get("id", "(vehicle)"),
                f"channels.irradiance[{i}].node",
                node,
                f"model {model_key(order)} ({name}) has one node, no envelope: declare node "
                f"air, or fit only {', '.join(structures.with_envelope())} (model.orders, "
                "model.structures)",
            )
    return models.structure_for(name, irradiance)


# model.envelope_sensors -> the tidy column that measures the envelope state
ENVELOPE_SENSORS = {"surface": "T_veh"}


def envelope_tables(
    structure: models.Structure,
    vehicle_data: Mapping[str, Any],
    tables: Mapping[str, pd.DataFrame],
) -> dict[str, pd.DataFrame]:
    """The windows with the envelope state measured where the config says so:
    ``model.envelope_sensors: surface`` makes the weighted mean of ``channels.surface`` (the
    tidy column T_veh) the measurement of the structure's envelope state (T_e of the
    interior-envelope structure), compared in eq. 17 like T_veh in eqs. 7-8 and, with
    ``model.x0: measured``, its measured initial state. Without the key, or for a structure
    whose sensors measure its envelope state already (T_veh of eqs. 7-8,
    ``Structure.sensors``) or that has none, the windows as they are."""
    group = (vehicle_data.get("model") or {}).get("envelope_sensors")
    state = structure.states[1] if structure.envelope else None
    column = ENVELOPE_SENSORS.get(str(group)) if group else None
    if column is None or state is None or state in structure.sensors:
        return dict(tables)
    return {
        name: table.assign(**{state: table[column]}) if column in table.columns else table
        for name, table in tables.items()
    }


# a first-order hold is flagged where the straight lines between the rows miss an input's
# logged signal by more than this share of the input's rms (:func:`hold_flags`): a meter's
# noise (0.3-1 %) and a few steps per record stay well below it, a heater that switches within
# the steps lies far above it (30-70 %)
HOLD_ERROR_MAX = 0.05


def hold_flags(
    structure: models.Structure,
    vehicle_data: Mapping[str, Any],
    tables: Mapping[str, pd.DataFrame],
) -> list[dict[str, Any]]:
    """The flag ``first_order_hold_on_switching_input`` per input that ``model.input_hold:
    first_order`` misrepresents: an input resampled from a finer logger step
    (``cleaning.step_s``) whose logged signal departs from the straight lines between the
    rows by more than :data:`HOLD_ERROR_MAX` of its rms (the cleaning's
    ``<input>_hold_error``, :func:`railtherm.data.ingest._hold_error`). A heater switching
    within the steps is piecewise constant with jumps inside them: the hold draws a ramp
    through each jump and the fit moves the capacities to follow it. The zero-order hold
    takes each step's exact mean (eq. 15), which is right for such an input."""
    if input_hold(vehicle_data) != "first_order":
        return []
    step = (vehicle_data.get("cleaning") or {}).get("step_s")
    step = f"cleaning.step_s {float(step):g} s" if step else "a step coarser than the logger's"
    flags = []
    for name in structure.inputs:
        column = f"{name}{ingest.HOLD_ERROR_SUFFIX}"
        parts = [t for t in tables.values() if column in t.columns]
        if not parts:
            continue
        error = np.concatenate([t[column].to_numpy(float) for t in parts])
        level = np.concatenate([t[name].to_numpy(float) for t in parts])
        rms = float(np.sqrt(np.nanmean(level**2)))
        share = float(np.sqrt(np.nanmean(error**2))) / rms if rms > 0 else 0.0
        if share > HOLD_ERROR_MAX:
            flags.append(
                pem.Flag(
                    "first_order_hold_on_switching_input",
                    (),
                    f"model.input_hold: first_order on {name} resampled to {step}: the "
                    f"logged {name} departs from the straight lines between the "
                    f"rows by {100 * share:.0f} % of its rms (more than "
                    f"{100 * HOLD_ERROR_MAX:g} %) - it switches within the steps, and a "
                    "first-order hold draws a ramp through each switch, which moves the "
                    "capacities; set model.input_hold: zero_order (the exact mean of each "
                    "step), or cleaning.step_s to the logger's step",
                ).to_dict()
            )
    return flags


def _outputs(structure: models.Structure, vehicle_data: Mapping[str, Any], tables) -> tuple:
    """The measured states compared in eq. 17: the config's choice, else every state measured."""
    chosen = vehicle_data["model"].get("outputs")
    measured = [
        s
        for s in structure.states
        if all(s in t.columns and t[s].notna().any() for t in tables.values())
    ]
    if chosen:
        return tuple(s for s in chosen if s in structure.states and s in measured)
    return tuple(measured)


input_hold = ingest.input_hold  # the declared hold, as the cleaning read the windows for it


def experiments(
    structure: models.Structure, tables: Mapping[str, pd.DataFrame], hold: str = "zero_order"
) -> list:
    """pem.Experiment per tidy window (inputs T_o, Q_H and any irradiance I_<name>; the
    structure's states as measured, NaN where a state has no sensor; x0 the first row, the
    measured initial state), under the input ``hold`` the tables were cleaned for."""
    return [
        pem.experiment_from_table(
            table, name, states=structure.states, inputs=tuple(structure.inputs), hold=hold
        )
        for name, table in tables.items()
    ]


# initial states of each window: estimated (extra unknowns), not the first measured row, which
# carries a sample's noise and calibration offset that neither the covariance nor the type-B
# budget holds (docs/identification.md, "Initial states")
X0_DEFAULT = "estimated"

MIN_USED_SHARE = 0.95


def rows_used(
    structure: models.Structure,
    tables: Mapping[str, pd.DataFrame],
    outputs: Sequence[str],
    vehicle_data: Mapping[str, Any],
) -> dict[str, dict[str, Any]]:
    """Rows per window and, per compared output, how many the fit uses (a row whose
    measurement is missing is skipped, eq. 17 sums over the rest). An input must be finite in
    every row, since a simulation carries a missing input into every later state; an output
    used in fewer than ``check.min_used_share`` (default 0.95) of a window's rows means the fit
    would rest on a fraction of the data. Both are :class:`DataError` naming the window, the
    column and the row."""
    share = float((vehicle_data.get("check") or {}).get("min_used_share", MIN_USED_SHARE))
    source = f"{vehicle_data.get('id', '(vehicle)')} window"
    out = {}
    for name, table in tables.items():
        n = len(table)
        for column in structure.inputs:
            values = table[column].to_numpy(float)
            bad = ~np.isfinite(values)
            if bad.any():
                i = int(bad.argmax())
                raise DataError(
                    f"{source} {name}",
                    column,
                    float(values[i]),
                    f"row {i} (time {table['time'].iloc[i]:g} s) of {n}: an input must be "
                    f"finite in every row, or the simulation carries it into every later state",
                )
        used = {s: int(np.isfinite(table[s].to_numpy(float)).sum()) for s in outputs}
        for s, k in used.items():
            if k < share * n:
                raise DataError(
                    f"{source} {name}",
                    s,
                    f"{k} of {n} rows",
                    f"the fit would use only {100 * k / n:.1f} % of the rows, less than "
                    f"check.min_used_share = {share:g}: the measurement is missing in the rest",
                )
        out[name] = {"rows": n, "used": used}
    return out


def surface(vehicle_data: Mapping[str, Any]) -> float | None:
    """A, the vehicle's ``surface_m2`` (eq. 5), or None where the config gives none (an
    object of class other): then k = kA / A is not given, kA still is."""
    A = vehicle_data.get("surface_m2")
    return None if A is None else float(A)


def static_kA(kvalue: Mapping[str, Any], A: float | None) -> float:
    """kA of the static test (eq. 10): k A, or the test's own kA where no surface is given."""
    if A is None or kvalue.get("k") is None:
        return float(kvalue["kA"])
    return float(kvalue["k"]) * A


def energy_balance_kA(tables: Mapping[str, pd.DataFrame] | None) -> float | None:
    """A start for kA where neither the static test nor a surface gives one: the mean heat
    input over the mean T - T_o of the identification windows (eq. 10 as if at rest); None
    when that is not a positive number (no heating)."""
    if not tables:
        return None
    frames = [t for t in tables.values() if {"T", "T_o", "Q_H"} <= set(t.columns)]
    if not frames:
        return None
    rows = pd.concat([t[["T", "T_o", "Q_H"]] for t in frames]).dropna()
    dT, Q = float((rows["T"] - rows["T_o"]).mean()), float(rows["Q_H"].mean())
    kA = Q / dT if dT > 0 else math.nan
    return kA if math.isfinite(kA) and kA > 0 else None


# how a jointly estimated kA is labelled (k_source), per estimator
JOINT = {"output_error": "joint estimation (PEM)", "kalman": "joint estimation (Kalman ML)"}


def _settings(
    structure,
    vehicle_data,
    kvalue: Mapping[str, Any] | None,
    tables: Mapping[str, pd.DataFrame] | None = None,
    estimator: str = "output_error",
):
    """fixed, initial, bounds and the provenance of kA from the config and the k stage (a
    joint estimate labelled by its ``estimator``, :data:`JOINT`)."""
    model = vehicle_data["model"]
    A = surface(vehicle_data)
    usable = bool(kvalue and kvalue["usable"])
    mode = model.get("mode", "static")
    notes = []
    initial = {p: float(v) for p, v in model.get("initial", {}).items()}
    bounds = {p: tuple(map(float, b)) for p, b in model.get("bounds", {}).items()}
    fixed = {}
    if kvalue:
        kA_start = static_kA(kvalue, A)
    else:  # k = 2 W/(m2 K) on the surface; without one, the windows' energy balance
        kA_start = 2.0 * A if A is not None else energy_balance_kA(tables)
    if "kA" not in structure.parameters:  # losses in series: kA derived (loss_path)
        path = structure.loss_path
        for p in path:  # n conductances of n kA in series give kA
            if kA_start is not None:
                initial.setdefault(p, len(path) * kA_start)
                bounds.setdefault(p, conductance_bounds(kA_start))
        k_source = f"{JOINT[estimator]}, kA = {kA_expression(structure)}"
        if mode == "static":
            notes.append(
                f"{structure.name}: the static k cannot be imposed (kA is derived, "
                f"{kA_expression(structure)}); it is estimated with the capacities"
            )
    elif mode == "static" and usable:
        fixed["kA"] = static_kA(kvalue, A)
        k_source = "static test (eq. 10), forced" if kvalue["forced"] else "static test (eq. 10)"
    else:
        if mode == "static":
            why = "no k window" if kvalue is None else "its window failed the steady-state test"
            notes.append(f"static k not usable ({why}): kA estimated jointly")
        k_source = JOINT[estimator]
        if kA_start is not None:
            initial.setdefault("kA", kA_start)
        bounds.setdefault("kA", conductance_bounds(kA_start))
    for p, (floor, _) in physical_bounds(structure, vehicle_data).items():
        # physics over an arbitrary lower bound: a configured one below the air's is raised
        lo, hi = bounds.get(p, structure.bounds[p])
        bounds[p] = (max(float(lo), floor), float(hi))
    initial = {p: v for p, v in initial.items() if p in structure.parameters and p not in fixed}
    bounds = {p: b for p, b in bounds.items() if p in structure.parameters and p not in fixed}
    return fixed, initial, bounds, k_source, notes


AIR_CAPACITY = "the air's capacity ρ c_p V"


def physical_bounds(
    structure: models.Structure, vehicle_data: Mapping[str, Any]
) -> dict[str, tuple[float, str]]:
    """The lower search bounds the vehicle's metadata make physical, {param: (bound, what it
    is)}: the air node's capacity (C of eqs. 7-8, C_bar of eq. 9, ``structure.air``) holds
    at least the air in ``volume_m3``, ρ c_p V (:data:`RHO_CP_AIR`). Without a volume, none:
    the structure's loose default (1e4 J/K) stays. A volume that is not a positive number is
    a :class:`ConfigError` naming the key."""
    if vehicle_data.get("volume_m3") is None or structure.air not in structure.parameters:
        return {}
    floor = air_capacity(vehicle_data["volume_m3"], vehicle_data.get("id", "(vehicle)"))
    return {structure.air: (floor, AIR_CAPACITY)}


def air_capacity(volume_m3: Any, source: str = "volume_m3") -> float | None:
    """rho c_p V (J/K, :data:`RHO_CP_AIR`): the capacity of the air in ``volume_m3``, the
    least the air node's capacity can be (None without a volume). A volume that is not a
    positive number is a :class:`ConfigError` naming ``source`` and the key."""
    if volume_m3 is None:
        return None
    number = isinstance(volume_m3, int | float | np.floating) and not isinstance(volume_m3, bool)
    if not (number and math.isfinite(volume_m3) and volume_m3 > 0):
        raise ConfigError(source, "volume_m3", volume_m3, "expected a volume > 0 (m³)")
    return RHO_CP_AIR * float(volume_m3)


def input_noise(structure, vehicle_data, exps) -> dict[str, list[float]]:
    """The declared white noise of the measured inputs per record, as
    :func:`railtherm.estimation.pem.fit` takes it (``input_noise``): T_o, the mean of the
    outdoor-air sensors, ``instruments.outdoor_noise_K`` / sqrt(n_eff); Q_H, the sum of the power
    channels, ``instruments.power_noise_rel`` times the record's rms Q_H / sqrt(n) (each
    meter's noise relative to its own reading, the channels taken as equal shares). Empty
    where nothing is declared."""
    instruments = vehicle_data.get("instruments") or {}
    counts = sensor_counts(vehicle_data.get("channels") or {})
    out: dict[str, list[float]] = {}
    s_T_o = float(instruments.get("outdoor_noise_K", 0.0) or 0.0)
    if s_T_o > 0 and "T_o" in structure.inputs and counts["outdoor"] > 0:
        out["T_o"] = [s_T_o / math.sqrt(counts["outdoor"])] * len(exps)
    r = float(instruments.get("power_noise_rel", 0.0) or 0.0)
    if r > 0 and "Q_H" in structure.inputs and counts["power"] > 0:
        k = structure.inputs.index("Q_H")
        out["Q_H"] = [
            r * math.sqrt(float(np.mean(np.square(e.u[:, k])))) / math.sqrt(counts["power"])
            for e in exps
        ]
    return out


def surface_offsets(structure, vehicle_data, outputs) -> dict[str, float]:
    """For a Kalman-filter fit: the compared body temperature's constant offset relative to
    the air sensors, estimated with the prior sd of the difference of the two groups' mean
    calibration offsets, sqrt(u_in^2 / n_in + u_surface^2 / n_surface) (:func:`kalman.fit`'s
    ``offsets``). A constant difference between the air and the surface readings contradicts
    eqs. 7-8 (the body settles at the air's temperature); the filter would explain it by
    diffusions, which move the capacities in proportion to its square. Empty without
    surface sensors."""
    states = surface_states(structure, vehicle_data, outputs)
    if not states:
        return {}
    u = math.hypot(mean_offset_u(vehicle_data, "indoor"), mean_offset_u(vehicle_data, "surface"))
    return {states[0]: u}


def surface_states(structure, vehicle_data, outputs) -> list[str]:
    """The compared states the surface sensors measure: every one but the air's, where the
    vehicle has surface sensors."""
    if sensor_counts(vehicle_data["channels"])["surface"] <= 0:
        return []
    return [s for s in structure.states if s != "T" and s in outputs]


def mean_offset_u(vehicle_data, group: str) -> float:
    """Standard uncertainty (K) of the mean calibration offset of a sensor group (indoor,
    outdoor, surface): one sensor's u_K / sqrt(n_eff)."""
    counts = sensor_counts(vehicle_data["channels"])
    return sensor_u_K(vehicle_data["instruments"], group) / math.sqrt(counts[group])


def stage_two_options(
    structure, vehicle_data, kvalue, tables, estimator: str = "output_error"
) -> tuple[dict, str, list]:
    """The options of the stage-two fit (:func:`estimate_parameters`: fixed, initial, bounds,
    outputs, x0, covariance, start) from the config and the k stage, with the provenance of
    kA and the notes of :func:`_settings`. ``tables``: the windows as the fit sees them."""
    fixed, initial, bounds, k_source, notes = _settings(
        structure, vehicle_data, kvalue, tables, estimator
    )
    model = vehicle_data["model"]
    options = {
        "fixed": fixed,
        "initial": initial,
        "bounds": bounds,
        "outputs": _outputs(structure, vehicle_data, tables),
        "x0": model.get("x0", X0_DEFAULT),
        "covariance": model.get("covariance", "hac"),
        "start": model.get("start", "auto"),
    }
    return options, k_source, notes


# the records contradict the two-stage fit when an estimate of the joint fit differs from it
# by more than this many standard uncertainties of the difference (two-sided p about 0.003);
# relative differences up to SAME_ESTIMATE are the optimiser's resolution (z = 0)
CONTRADICTION_Z = 3.0
SAME_ESTIMATE = 1e-6


def kA_estimated(options: Mapping[str, Any], kA_start: float) -> dict[str, Any]:
    """The options of a two-stage fit with kA estimated instead of fixed (the joint fit):
    started at ``kA_start``, within ``KA_BOUNDS`` unless the options bound it already."""
    return {
        **options,
        "fixed": {p: v for p, v in options["fixed"].items() if p != "kA"},
        "initial": {**options["initial"], "kA": float(kA_start)},
        "bounds": {"kA": KA_BOUNDS, **options["bounds"]},
    }


def _judged_fit(structure, exps, options, vehicle_data, kvalue, storage):
    """One fit of ``structure`` with ``options``: the estimate, its dict with the combined
    (statistical and type-B) intervals judged for identification, and the type-B budget."""
    result = estimate_parameters(structure, exps, options)
    fitted = result.to_dict()
    budget = systematic_budget(structure, exps, options, result, vehicle_data, kvalue, storage)
    combine_uncertainty(fitted["parameters"], budget)
    if "kA" not in fitted["parameters"]:
        fitted["parameters"]["kA"] = derived_kA(fitted, structure)
    judge_identification(
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


def _not_identified(fitted: Mapping[str, Any], structure: models.Structure) -> list[str]:
    """The estimated parameters of ``fitted`` judged not identified, in the structure's order."""
    params = fitted["parameters"]
    return [
        p
        for p in structure.parameters
        if params.get(p, {}).get("estimated") and not params[p].get("identified", True)
    ]


def _static_kA_check(
    structure, exps, options, vehicle_data, kvalue, storage, static
) -> tuple[dict[str, Any], tuple | None]:
    """Whether the identification records accept the two-stage fit (``static``: its result,
    judged dict and budget), which holds the static kA fixed.

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
    ``reason``; with ``note`` where the fit is replaced or in conflict) and, where the joint
    fit replaces the two-stage one, its (result, judged dict, budget, options), else None."""
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
        return record, None
    kA_joint = float(joint[1]["parameters"]["kA"]["value"])
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
        return record, None
    if joint_undetermined:
        record["reason"] = (
            f"the joint fit leaves {', '.join(joint_undetermined)} not identified: the "
            "two-stage fit stays"
        )
        return record, None
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
        return record, None
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
        static_value = kA_static if worst == "kA" else fitted["parameters"][worst]["value"]
        joint_value = joint[1]["parameters"][worst]["value"]
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
    own = [f["message"] for f in fitted["flags"]]
    if own:  # what the two-stage fit showed stays in view (a misfit shows in it first)
        note += "; the two-stage fit's own flags: " + "; ".join(own)
    record["two_stage"] = {
        p: float(fitted["parameters"][p]["value"]) for p in ("kA", *structure.coupled)
    }
    record.update(use_joint=True, note=note)
    return record, (*joint, joint_options)


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
            value = float(fitted["parameters"][p]["value"])
            sd = float(fitted["parameters"][p]["sd_log"])
            effects = budget["effects_log"].get(p, {})
        entry = joint_fitted["parameters"][p]
        joint_effects = joint_budget["effects_log"].get(p, {})
        variance = sd**2 + float(entry["sd_log"]) ** 2
        variance += sum(
            (joint_effects.get(s, 0.0) - effects.get(s, 0.0)) ** 2
            for s in sorted(set(effects) | set(joint_effects))
        )
        d = math.log(float(entry["value"]) / value)
        finite = variance > 0 and math.isfinite(variance)
        if abs(d) <= SAME_ESTIMATE:  # one estimate, as far as the optimiser resolves it
            z[p] = 0.0
        else:
            z[p] = d / math.sqrt(variance) if finite else math.nan
    return z


STATIC_UNDETERMINED = "the static kA left the capacities not identified"
STATIC_CONTRADICTED = "the records contradict the two-stage fit"
STATIC_CONFLICT = "the static test and the records disagree"


def identify(
    tables: Mapping[str, pd.DataFrame],
    vehicle_data: Mapping[str, Any],
    kvalue: Mapping[str, Any] | None,
    order: int,
    storage: Mapping[str, Any] | None = None,
) -> tuple[dict[str, Any], pd.DataFrame]:
    """Fit the model of ``order`` to all identification windows jointly (one parameter set,
    own initial states); cross-validate when there are two or more windows.

    ``storage``: the storage-corrected k of the vehicle (:func:`storage_corrected_k`); where
    it is applied, its kA is the one held fixed (first- and second-order fits alike) and its
    uncertainty replaces the k stage's storage bound in the type-B budget. Without it (or not
    applied) kA is that of eq. 10.

    Returns the estimate (a plain dict for YAML) and the series table (per window: time,
    measured and simulated states, residuals and inputs).
    """
    structure = model_structure(order, vehicle_data)
    tables = envelope_tables(structure, vehicle_data, tables)
    outputs = _outputs(structure, vehicle_data, tables)
    estimator = split_key(order)[1]
    options, k_source, notes = stage_two_options(structure, vehicle_data, kvalue, tables, estimator)
    fixed = options["fixed"]
    applied = bool(storage and storage.get("applied")) and "kA" in fixed
    if applied:
        fixed["kA"] = float(storage["kA_corrected"])
        k_source += ", storage-corrected"
    if estimator == "kalman":
        options["estimator"] = "kalman"
        options["offsets"] = surface_offsets(structure, vehicle_data, options["outputs"])
    rows = rows_used(structure, tables, outputs, vehicle_data)
    exps = experiments(structure, tables, input_hold(vehicle_data))
    options["input_noise"] = input_noise(structure, vehicle_data, exps)
    storage_used = storage if applied else None
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
    if checked and "kA" in fixed and kvalue is not None and structure.coupled:
        check, joint = _static_kA_check(
            structure, exps, options, vehicle_data, kvalue, storage_used, (result, fitted, budget)
        )
        if joint is not None:
            result, fitted, budget, options = joint
            fixed = options["fixed"]
            k_source = f"{JOINT[estimator]}: {check['reason']}"
        if check.get("note"):
            # a conflict of the two kA measurements is a reason of the verdict; the joint
            # fit's replacing a two-stage fit whose kA agrees with it is a note: nothing in
            # the reported fit's assumptions is in doubt (the joint fit is judged itself)
            (method_notes if check["use_joint"] else notes).append(check["note"])
        fitted["static_kA_check"] = check
    fitted["flags"] = [*fitted["flags"], *hold_flags(structure, vehicle_data, tables)]
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
        "fit": fitted,
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
        estimate["innovations"] = innovation_tests(series, outputs, alpha)
        estimate["fit"]["loglik"] = float(result.loglik)
        estimate["fit"]["n_params"] = int(result.n_params)
    return estimate, series


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
    fitted: Mapping[str, Any], vehicle_data: Mapping[str, Any], tables: Mapping[str, pd.DataFrame]
) -> list[str]:
    """The plausibility of the records and of the fitted k against a temperature channel's
    unit (:mod:`railtherm.data.plausibility`): a heated cabin colder than the tunnel or never
    at a heated cabin's temperature, and k = kA / A far from the vehicle class's; sentences
    naming the raw files, the channels and their declared units, for the verdict."""
    out = units_plausibility.record_reasons(tables, vehicle_data)
    entry = fitted["parameters"].get("kA")
    A = surface(vehicle_data)
    if entry is not None and A and identifiability.parameter_identification(entry)["identified"]:
        far = units_plausibility.k_class_reason(
            float(entry["value"]) / A, vehicle_data, "the fit's"
        )
        if far is not None:
            out.append(far)
    return out


# the storage correction's iteration kA <-> stage two: stop when kA moves less than this share
# of u(kA), or after this many stage-two fits
STORAGE_TOLERANCE = 0.1
MAX_STORAGE_ITERATIONS = 10
STORAGE_METHOD = (
    "kA of the k window's energy balance under eqs. 7-8 (heat stored by C and C_veh of the "
    "second-order fit), iterated with the stage-two fit"
)


def storage_corrected_k(
    tables: Mapping[str, pd.DataFrame],
    k_window: pd.DataFrame | None,
    vehicle_data: Mapping[str, Any],
    kvalue: Mapping[str, Any] | None,
) -> dict[str, Any] | None:
    """The storage-corrected k of a vehicle: kA with the heat the structure takes up during the
    k window, estimated from the identified second-order model, and the count of iterations.

    Eq. 10 books every watt that goes into storage as loss: where the air is held steady but
    the car body still lags behind it, K_veh (T - T_veh) > 0 and eq. 10's kA is too high by
    K_veh mean(T - T_veh) / mean(T - T_o). The first balance takes C, K_veh, C_veh from the
    joint fit (kA free, started at eq. 10's); then the second-order model (eqs. 7-8) is fitted
    with the corrected kA fixed (stage two, warm-started), the k window's energy balance under
    that model gives a new kA (:func:`railtherm.estimation.kvalue.storage_corrected_kA`), and the
    two steps alternate until kA moves by less than ``STORAGE_TOLERANCE`` u(kA)
    (at most ``MAX_STORAGE_ITERATIONS`` fits). u(kA) is eq. 10's budget with its storage bound
    replaced by the correction's own standard uncertainty: the regression's (T_veh's start D0
    and its correlation with kA included) and that of the capacities' statistical errors
    carried through the balance (finite differences in log theta with the fit's covariance),
    in quadrature. This one term replaces both eq. 10's storage bound and its scatter: the
    scatter is the stored energy's swing at the window's ends and the balance's noise, which
    the regression's residuals (about the modelled storage, with their autocorrelation time)
    already hold, so counting it again would count the same heat twice. The power,
    temperature and surface components stay as eq. 10 has them (relative to k).

    None where there is nothing to correct: no k window or no usable static k, ``model.mode``
    joint, or ``kvalue.storage_correction: false``. Otherwise a dict for the fit files; with
    ``applied`` false and a ``reason`` where the correction cannot be made (solar gains in the
    k window, a fit that fails or leaves C, K_veh, C_veh undetermined, a kA that is not
    positive) - eq. 10's kA is fixed then.
    """
    if k_window is None or not kvalue or not kvalue.get("usable"):
        return None
    if not (vehicle_data.get("kvalue") or {}).get("storage_correction", True):
        return None
    structure = model_structure("order2", vehicle_data)
    tables = envelope_tables(structure, vehicle_data, tables)
    options, _, _ = stage_two_options(structure, vehicle_data, kvalue, tables)
    if "kA" not in options["fixed"]:
        return None
    A = surface(vehicle_data)
    per = 1.0 if A is None else A
    kA_eq10 = float(options["fixed"]["kA"])
    k_eq10 = kA_eq10 / per
    budget = {c: float(kvalue["budget"].get(c, 0.0)) for c in COMPONENTS}
    # the components that stay: relative to k (power, temperature, surface), or absolute
    relative = {c: budget[c] / k_eq10 for c in ("power", "temperature", "surface")}
    record: dict[str, Any] = {
        "applied": False,
        "method": STORAGE_METHOD,
        "kA_eq10": kA_eq10,
        "u_kA_eq10": float(kvalue.get("u_k_rel") or 0.0) * kA_eq10,
    }
    solar = [
        n
        for n in ingest.irradiance_names(vehicle_data)
        if n in k_window.columns and np.any(np.abs(k_window[n].to_numpy(float)) > 0)
    ]
    if solar:
        record["reason"] = (
            f"the k window has solar gains ({', '.join(solar)}): its energy balance would need "
            "the apertures; eq. 10's kA is fixed"
        )
        return record
    exps = experiments(structure, tables, input_hold(vehicle_data))
    options["input_noise"] = input_noise(structure, vehicle_data, exps)
    fit_options = {**options, "fixed": dict(options["fixed"])}

    def balance(kA: float, initial: Mapping[str, float] | None) -> _StorageStep:
        """Stage two with kA fixed (warm-started from ``initial``), then the k window's
        balance under its C, K_veh, C_veh."""
        fit_options["fixed"]["kA"] = kA
        if initial:
            fit_options["initial"] = dict(initial)
            fit_options["start"] = "initial"
        result = pem.fit(structure, exps, **fit_options)
        theta = {p: float(result.theta[p]) for p in ("C", "K_veh", "C_veh")}
        bounded = sorted(
            {q for f in result.flags if f.code == "at_bound" for q in f.parameters} & set(theta)
        )
        if bounded:  # a balance under a capacity the search bound holds means nothing
            raise ValueError(
                f"stage two at kA = {kA:.4g} W/K leaves {', '.join(bounded)} at a search bound"
            )
        correction = storage_corrected_kA(k_window, **theta)
        u_model = _storage_model_u(k_window, theta, result)
        u_storage = math.hypot(correction.u_kA, u_model)
        if not (math.isfinite(correction.kA) and correction.kA > 0):
            raise ValueError(f"the k window's balance gives kA = {correction.kA:.4g} W/K")
        if not math.isfinite(u_storage):
            raise ValueError("the second-order fit does not determine C, K_veh and C_veh")
        other = sum((r * correction.kA) ** 2 for r in relative.values())
        return _StorageStep(
            kA=kA,
            kA_balance=float(correction.kA),
            u_kA=math.sqrt(other + u_storage**2),
            u_storage=u_storage,
            u_model=u_model,
            correction=correction,
            theta=theta,
            warm={p: float(result.theta[p]) for p in result.free},
        )

    history: list[float] = []
    method = "alternation"
    try:
        # the capacities of the first balance come from the joint fit (kA free, started at
        # eq. 10's): with kA held at eq. 10's biased value, a fit of T alone can settle in a
        # far optimum of C, K_veh, C_veh whose balance then moves kA away from the truth;
        # the joint fit's optimum does not depend on that bias
        joint = pem.fit(structure, exps, **kA_estimated(options, kA_eq10))
        joint_theta = {p: float(joint.theta[p]) for p in ("C", "K_veh", "C_veh")}
        kA, initial = kA_eq10, None
        if all(math.isfinite(v) and v > 0 for v in joint_theta.values()):
            start = storage_corrected_kA(k_window, **joint_theta).kA
            if math.isfinite(start) and start > 0:
                kA, initial = start, joint_theta
        unusable = None  # why the alternation's step could not be used, if it could not
        try:
            step = _storage_alternation(balance, kA, initial, history)
        except ValueError as err:
            step, unusable = None, err
        if step is None and initial is not None:
            # the alternation runs away where stage two's capacities follow kA steeply (the
            # balance's kA moves more than the kA it was given): solve kA = balance(kA) by
            # the secant method from the joint fit instead, each fit warm-started there
            method = "secant"
            step = _storage_secant(balance, float(joint.theta["kA"]), kA, joint_theta, history)
        if step is None:
            raise ValueError(_unsettled(history, kA, unusable))
    except (np.linalg.LinAlgError, ValueError, FloatingPointError) as err:
        record["reason"] = f"the correction failed ({err}); eq. 10's kA is fixed"
        return record
    kA, u_storage = step.kA_balance, step.u_storage
    corrected = {
        "power": relative["power"] * kA / per,
        "temperature": relative["temperature"] * kA / per,
        "surface": relative["surface"] * kA / per,
        # held by the regression's residuals (its u is the storage term)
        "scatter": 0.0,
        "storage": u_storage / per,
    }
    record.update(
        applied=True,
        kA_corrected=float(kA),
        u_kA_corrected=float(step.u_kA),
        u_storage_kA=float(u_storage),
        u_storage_regression_kA=float(step.correction.u_kA),
        u_storage_model_kA=float(step.u_model),
        budget=corrected,
        budget_unit="W/(m2 K)" if A is not None else "W/K",
        window=step.correction.to_dict(),
        theta=step.theta,
        iterations=len(history),
        converged=True,  # a step that did not settle ends the correction above
        solver=method,
        history_kA=[float(v) for v in history],
    )
    return record


def _unsettled(history: Sequence[float], kA: float, unusable: Exception | None) -> str:
    """Why the storage correction found no kA: the balances it reached (``history``, empty
    where the first stage-two fit at ``kA`` could not be used, for the reason ``unusable``)."""
    if history:
        last = f"last kA {history[-1]:.4g} W/K after {len(history)} fits"
    else:
        last = f"no usable stage-two fit from kA = {kA:.4g} W/K"
    if unusable is not None:
        last += f"; {unusable}"
    return f"the k window's balance and stage two do not settle on one kA ({last})"


@dataclass(frozen=True)
class _StorageStep:
    """One stage-two fit at a fixed kA and the k window's balance under it."""

    kA: float
    kA_balance: float
    u_kA: float
    u_storage: float
    u_model: float
    correction: Any
    theta: dict[str, float]
    warm: dict[str, float]

    @property
    def settled(self) -> bool:
        return abs(self.kA_balance - self.kA) < STORAGE_TOLERANCE * self.u_kA


def _storage_alternation(balance, kA: float, initial, history: list[float]):
    """kA <- balance(kA), each fit warm-started from the previous one, until kA moves by less
    than ``STORAGE_TOLERANCE`` u(kA); None where it does not settle within
    ``MAX_STORAGE_ITERATIONS`` fits. ``balance`` raises ValueError where a step cannot be
    used (a capacity at a search bound, a balance that is not a positive kA)."""
    for _ in range(MAX_STORAGE_ITERATIONS):
        step = balance(kA, initial)
        history.append(step.kA_balance)
        if step.settled:
            return step
        kA, initial = step.kA_balance, step.warm
    return None


def _storage_secant(balance, kA_0: float, kA_1: float, initial, history: list[float]):
    """The root of h(kA) = balance(kA) - kA by the secant method from kA_0 and kA_1, every fit
    warm-started from ``initial``; None where it does not settle within
    ``MAX_STORAGE_ITERATIONS`` fits or leaves positive kA (ValueError from ``balance``
    where a step cannot be used)."""
    previous = balance(kA_0, initial)
    history.append(previous.kA_balance)
    if previous.settled:
        return previous
    kA = kA_1
    for _ in range(MAX_STORAGE_ITERATIONS - 1):
        if not (math.isfinite(kA) and kA > 0):
            return None
        step = balance(kA, initial)
        history.append(step.kA_balance)
        if step.settled:
            return step
        h_0, h_1 = previous.kA_balance - previous.kA, step.kA_balance - step.kA
        if h_1 == h_0:
            return None
        kA, previous = step.kA - h_1 * (step.kA - previous.kA) / (h_1 - h_0), step
    return None


def _storage_model_u(k_window: pd.DataFrame, theta: Mapping[str, float], result) -> float:
    """Standard uncertainty (W/K) of the storage-corrected kA from the statistical errors of
    C, K_veh, C_veh: the sensitivities d kA / d log theta by central differences, with the
    fit's covariance of log theta (sd_log and correlation over its free parameters)."""
    free = list(result.free)
    names = [p for p in ("C", "K_veh", "C_veh") if p in free]
    if not names:
        return 0.0
    sd = np.array([float(result.sd_log[p]) for p in names])
    if not np.all(np.isfinite(sd)):
        return math.inf
    h = 1.0e-4
    gradient = []
    for p in names:
        shifted = [
            storage_corrected_kA(k_window, **{**theta, p: theta[p] * math.exp(sign * h)}).kA
            for sign in (1.0, -1.0)
        ]
        gradient.append((shifted[0] - shifted[1]) / (2.0 * h))
    index = [free.index(p) for p in names]
    correlation = np.asarray(result.correlation, dtype=float)[np.ix_(index, index)]
    g = np.asarray(gradient) * sd
    return float(math.sqrt(max(float(g @ correlation @ g), 0.0)))


K_STAGE_FIELDS = (
    "kA_fixed",
    "k_eq10",
    "u_k_eq10",
    "k_corrected",
    "u_k_corrected",
    "storage_correction",
)


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


def outlying_samples(
    estimate: Mapping[str, Any], series: pd.DataFrame, thresholds: Mapping[str, Any]
) -> dict[str, Any]:
    """Each compared output's outlying samples
    (:class:`railtherm.estimation.outliers.OutlyingSamples`): a Kalman fit's standardised
    one-step innovations, an output-error fit's simulation residuals over their RMSE, beyond
    the Bonferroni threshold at ``check.outlier_alpha`` over the record's samples. Reported
    in the fit's notes and ``outliers``; they do not judge the verdict."""
    estimator = estimate.get("estimator", "output_error")
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
        for state in estimate["outputs"]
        if outliers.has_columns(series, state, estimator)
    }


def innovation_reasons(estimate: Mapping[str, Any], thresholds: Mapping[str, Any]) -> list[str]:
    """The verdict's reasons of a kalman fit: an output whose one-step innovations are not
    white (:func:`innovation_tests`) - the stochastic model misses a dynamic or an input.

    The Ljung-Box and cumulated-periodogram tests of every compared output are one family,
    judged by Holm's procedure (:func:`railtherm.estimation.diagnostics.holm`) at
    ``whiteness_alpha``: with white innovations the fit is put in doubt with probability at
    most that level, however many outputs and tests there are (each test alone at that level
    would do so up to 2 x outputs times as often)."""
    from railtherm.estimation import diagnostics

    tests = estimate.get("innovations", {})
    alpha = float(thresholds["whiteness_alpha"])
    names = [(state, key) for state in tests for key in ("ljung_box_p", "cpg_p")]
    adjusted = diagnostics.holm([float(tests[state][key]) for state, key in names])
    held = dict(zip(names, adjusted, strict=True))
    family = f"Holm over {len(names)} tests" if len(names) > 1 else "one test"
    reasons = []
    for state, t in tests.items():
        lb, cpg = held[(state, "ljung_box_p")], held[(state, "cpg_p")]
        if min(lb, cpg) < alpha:
            reasons.append(
                f"The one-step innovations of {state} are not white (Ljung-Box p = "
                f"{t['ljung_box_p']:.3g}, cumulated periodogram p = {t['cpg_p']:.3g}; "
                f"adjusted {lb:.3g} and {cpg:.3g} by {family}, below the family's level "
                f"{alpha:g}): the stochastic model misses a dynamic or an input."
            )
    return reasons


def estimate_parameters(structure: models.Structure, exps: Sequence, options: Mapping[str, Any]):
    """The fit of ``structure`` to ``exps`` by the estimator ``options["estimator"]``:
    output_error (default; the paper's simulation-error PEM, eqs. 17-18 with K = 0,
    :func:`railtherm.estimation.pem.fit`) or kalman (the Kalman-filter PEM of the stochastic model,
    eq. 16 with K from the filter, maximum likelihood, :func:`railtherm.estimation.kalman.fit`)."""
    options = dict(options)
    if options.pop("estimator", "output_error") == "kalman":
        from railtherm.estimation import kalman

        options.pop("covariance", None)  # the observed information gives the covariance
        return kalman.fit(structure, exps, **options)
    return pem.fit(structure, exps, **options)


def kA_expression(structure: models.Structure) -> str:
    """How the structure's overall kA follows from its parameters, as its module says (or
    "from the steady state")."""
    return structure.kA_expression or "the steady state's 1 / (dT/dQ_H)"


def derived_kA(fitted: Mapping[str, Any], structure: models.Structure) -> dict[str, Any]:
    """The overall heat-loss coefficient of a structure without a parameter kA (e.g. losses
    in series, kA = K_i K_o / (K_i + K_o)), from its steady state
    (:meth:`~railtherm.structures.Structure.kA_log_gradient`), with a 95 % interval by the
    delta method on the log parameters (their combined sds and the fit's correlation):
    d log kA = sum_p (d log kA / d log p) d log p."""
    par = fitted["parameters"]
    theta = {p: par[p]["value"] for p in structure.parameters}
    value, gradient = structure.kA_log_gradient(theta)
    free = list(fitted["free"])
    corr = np.asarray(fitted["correlation"], dtype=float)
    moving = [p for p in free if gradient.get(p, 0.0) != 0.0]
    g = np.array([gradient[p] for p in moving])
    sd = np.array([par[p].get("sd_log_total", par[p].get("sd_log", 0.0)) for p in moving])
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


def combine_uncertainty(parameters: dict[str, Any], budget: Mapping[str, Any]) -> None:
    """Replace each estimated parameter's 95 % interval by the combined one: the statistical
    sd of log(theta) (from the fit) and the effects of the independent error sources added in
    quadrature. The statistical interval is kept as ``ci95_statistical``."""
    for p, effects in budget["effects_log"].items():
        entry = parameters[p]
        sd = float(np.sqrt(entry["sd_log"] ** 2 + sum(e**2 for e in effects.values())))
        log_value = np.log(entry["value"])
        entry["ci95_statistical"] = entry["ci95"]
        entry["sd_log_total"] = sd
        with np.errstate(over="ignore"):  # a non-identifiable parameter: [0, inf) is honest
            entry["ci95"] = [
                float(np.exp(log_value - pem.Z95 * sd)),
                float(np.exp(log_value + pem.Z95 * sd)),
            ]


def judge_identification(
    fitted: dict[str, Any],
    bounds: Mapping[str, tuple],
    structure: models.Structure | None = None,
    physical: Mapping[str, str] | None = None,
    budget: Mapping[str, Any] | None = None,
) -> None:
    """Mark every estimated parameter of ``fitted`` (a ``FitResult.to_dict()`` with combined
    intervals) with :func:`railtherm.estimation.pem.identification`, and judge the width of the
    interval a reader sees - the combined one - rather than the fit's statistical one: the
    ``wide_interval`` flags are replaced by flags on the combined intervals.

    With the ``structure``: its coupled parameters (``Structure.coupled``, the dynamic part)
    are judged together (:func:`railtherm.study.identifiability.coupled_identification`), and each
    of its totals (``Structure.totals``: C_total = C + C_veh, the capacity eq. 9 lumps into C_bar)
    is written under ``fitted["totals"]`` with its 95 % interval
    (:func:`railtherm.study.identifiability.total_capacity`, ``budget`` the systematic budget).
    ``physical``:
    {param: what its lower bound is} for a bound the metadata make physical
    (:func:`physical_bounds`), named in the reason."""
    physical = dict(physical or {})
    pinned = {p for f in fitted["flags"] if f["code"] == "at_bound" for p in f["parameters"]}
    flags = [f for f in fitted["flags"] if f["code"] != "wide_interval"]
    for p, entry in fitted["parameters"].items():
        if not entry.get("estimated"):
            continue
        at_bound = None
        if p in pinned:
            lo_b, hi_b = (float(b) for b in bounds[p])
            lower = abs(math.log(entry["value"] / lo_b)) <= abs(math.log(hi_b / entry["value"]))
            at_bound = ("lower", lo_b) if lower else ("upper", hi_b)
            if lower and p in physical:
                at_bound = ("lower", lo_b, physical[p])
        entry.update(pem.identification(entry["value"], entry["ci95"], at_bound))
        lo, hi = entry["ci95"]
        if not (lo > 0 and hi / lo <= pem.WIDE_RATIO) and p in fitted["free"]:
            flags.append(
                pem.Flag(
                    "wide_interval",
                    (p,),
                    f"the combined 95 % interval of {p} spans more than a decade ({lo:.3g} to "
                    f"{hi:.3g}): the data hardly determine it",
                ).to_dict()
            )
    fitted["flags"] = flags
    if structure is None:
        return
    params = fitted["parameters"]
    estimated = {p: params[p] for p in structure.coupled if params.get(p, {}).get("estimated")}
    for p, judged in identifiability.coupled_identification(estimated, structure.coupled).items():
        params[p].update(judged)
    totals = {}
    for name, parts in structure.totals.items():
        if all(p in params for p in parts):
            totals[name] = identifiability.total_capacity(
                fitted, parts, (budget or {}).get("effects_log")
            )
    if totals:
        fitted["totals"] = totals


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


def skipped_checks(estimate: Mapping[str, Any]) -> list[str]:
    """The plausibility checks a fit could not make, each a note: an object of class other
    may give no ``surface_m2`` (then k = kA / A and ``check.k_range_W_m2K``) or no ``mass_kg``
    (then c_veh and the stored heat per kg) - nothing is wrong, there is nothing to judge."""
    out = []
    if estimate.get("A") is None:
        out.append(
            "k = kA / A not given, and its range (check.k_range_W_m2K) not checked: no surface_m2"
        )
    if estimate.get("mass_kg") is None:
        out.append(
            "c_veh = C_veh / m_veh not given, and the heat stored per kg "
            "(check.min_capacity_per_kg_J_kgK, max_capacity_per_kg_J_kgK) not checked: no mass_kg"
        )
    return out


def plausibility(estimate: Mapping[str, Any], thresholds: Mapping[str, Any]) -> list[str]:
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
    par = estimate["fit"]["parameters"]
    out = []

    def value(p):
        entry = par.get(p)
        if entry is None or not identifiability.parameter_identification(entry)["identified"]:
            return None
        return float(entry["value"])

    kA = value("kA")
    A = estimate.get("A")
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
    total = (estimate["fit"].get("totals") or {}).get("C_total")
    if total is not None and not identifiability.parameter_identification(total)["identified"]:
        total = None
    capacities = [value(p) for p in structures.of_kind("capacities") if p in par]
    if None in capacities and total is not None:  # the split unknown, the sum determined
        capacities = [float(total["value"])]
    if capacities and None not in capacities and estimate.get("mass_kg"):
        per_kg = sum(capacities) / estimate["mass_kg"]
        ceiling = float(thresholds["max_capacity_per_kg_J_kgK"])
        if per_kg > ceiling:
            than = (
                f"water ({C_WATER:g} J/(kg K))"
                if ceiling == C_WATER
                else f"{ceiling:g} J/(kg K) (check.max_capacity_per_kg_J_kgK)"
            )
            out.append(
                f"the capacities store {per_kg:.4g} J/(kg K) of the mass {estimate['mass_kg']:g} "
                f"kg, more than {than}: a unit mistake (power in W declared kW?) or the wrong mass"
            )
        floor = float(thresholds["min_capacity_per_kg_J_kgK"])
        if per_kg < floor:
            out.append(
                f"the capacities store only {per_kg:.4g} J/(kg K) of the mass "
                f"{estimate['mass_kg']:g} kg, below {floor:g} J/(kg K) "
                "(check.min_capacity_per_kg_J_kgK): is the time column's unit right (minutes "
                "declared seconds divides every capacity by 60), or the mass?"
            )
    air_name = "C" if "C" in par else "C_bar"
    reason = str((par.get(air_name) or {}).get("reason", ""))
    if reason.startswith("at its physical lower bound") and estimate.get("volume_m3"):
        out.append(
            f"the air node's capacity {air_name} sits {reason}: the data "
            f"ask for less than the air in {estimate['volume_m3']:g} m³ holds - a unit mistake "
            "(power in kW declared W, time in minutes declared seconds?), the wrong volume, or "
            "a dynamic the model lacks"
        )
    air = value(air_name)
    what = "the air node's capacity"
    if air is None and total is not None:  # C <= C + C_veh: a total below the air's is too
        air, what = float(total["value"]), "the total capacity C_total (at least the air node's)"
    if air is not None and estimate.get("volume_m3"):
        ratio = float(thresholds["min_air_capacity_ratio"])
        floor = ratio * RHO_CP_AIR * estimate["volume_m3"]
        if air < floor:
            share = "half" if ratio == 0.5 else f"{ratio:g} times (check.min_air_capacity_ratio)"
            out.append(
                f"{what} {air:.4g} J/K is below {share} that of the air in "
                f"{estimate['volume_m3']:g} m³ ({floor:.4g} J/K): a unit mistake (power in kW "
                "declared W, time in minutes declared seconds?) or the wrong volume"
            )
    out.extend(estimate.get("unit_checks") or ())
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
    estimate: Mapping[str, Any], series: pd.DataFrame, thresholds: Mapping[str, Any]
) -> dict[str, Any]:
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
    record's outlying samples (:func:`outlying_samples`, also in ``outliers``).
    """
    thresholds = check_thresholds(thresholds)
    fit = estimate["fit"]
    p = int(fit["n_unknowns"])  # every estimated quantity, whatever the estimator
    measures: dict[str, Any] = {}
    for state in estimate["outputs"]:
        overall = quality.summary(series[state], series[f"{state}_sim"], p)
        windows = {
            name: quality.summary(w[state], w[f"{state}_sim"], p)
            for name, w in series.groupby("window", sort=False)
        }
        measures[state] = {"overall": overall, "windows": windows}
    kalman = estimate.get("estimator") == "kalman"
    criteria: list[dict[str, Any]] = []
    reasons: list[str] = []

    def judge(name: str, failed: list[str], applies: bool = True) -> None:
        criteria.append({"criterion": name, "applies": applies, "passed": not failed})
        reasons.extend(failed)

    r2 = {"T": measures["T"]["overall"]["r2"]}
    r2 |= {f"{cv['train']} -> {cv['test']}": cv["r2_T"] for cv in estimate["cross_validation"]}
    judge("r2", quality.verdict(r2, thresholds={"r2_min": thresholds["r2_min"]})[1])
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
            missed += quality.verdict(
                1.0,
                whiteness={f"{state}, {w}": v for w, v in m["windows"].items()},
                thresholds={"min_effective_samples": thresholds["min_effective_samples"]},
            )[1]
    judge("rmse", missed)
    judge("innovations_white", innovation_reasons(estimate, thresholds) if kalman else [], kalman)
    white = not kalman and bool(thresholds["require_white"])
    not_white = []
    if white:  # the colour alone, not the effective samples
        not_white = quality.verdict(
            1.0,
            whiteness={state: m["overall"] for state, m in measures.items()},
            thresholds={
                "require_white": True,
                "whiteness_alpha": thresholds["whiteness_alpha"],
                "min_effective_samples": 0.0,
            },
        )[1]
    judge("residuals_white", not_white, white)
    severe = [f for f in fit["flags"] if f["code"] not in NOTE_ONLY_FLAGS]
    judge("flags", quality.verdict(1.0, severe)[1])
    judge("plausibility", plausibility(estimate, thresholds))
    judge("k_stage", list(estimate["notes"]))
    clock_notes: list[str] = []
    if "clocks" in estimate:  # a record of several sources: their clocks checked
        from railtherm.study import clocks

        judge("clocks", clocks.reasons(estimate["clocks"]))
        clock_notes = clocks.notes(estimate["clocks"])
    notes = [f["message"] for f in fit["flags"] if f["code"] in NOTE_ONLY_FLAGS]
    notes += clock_notes
    notes += estimate.get("method_notes", [])
    notes += skipped_checks(estimate)
    outlying = outlying_samples(estimate, series, thresholds)
    for found in outlying.values():
        notes += found.texts()
    return {
        "vehicle": estimate["vehicle"],
        "synthetic": estimate["synthetic"],
        "order": estimate["order"],
        "model": estimate["model"],
        "estimator": estimate.get("estimator", "output_error"),
        "structure": estimate["structure"],
        "input_hold": estimate.get("input_hold", "zero_order"),
        "k_source": estimate["k_source"],
        **{key: estimate.get(key) for key in K_STAGE_FIELDS},
        "verdict": quality.IN_DOUBT if reasons else quality.ACCEPTABLE,
        "reasons": reasons,
        "criteria": criteria,
        "judged_by": judged_by(criteria),
        "notes": notes,
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
        "cross_validation": estimate["cross_validation"],
        "flags": fit["flags"],
        "systematic": estimate["systematic"],
        "windows": estimate["windows"],
        "rows": estimate["rows"],
        "outputs": estimate["outputs"],
        **({key: fit[key] for key in ("loglik", "n_params", "n_obs")} if kalman else {}),
        **({"innovations": estimate["innovations"]} if kalman else {}),
        **({"noise": fit["noise"]} if kalman and "noise" in fit else {}),
        "outliers": {state: found.to_dict() for state, found in outlying.items()},
        **({"clocks": estimate["clocks"]} if "clocks" in estimate else {}),
    }
