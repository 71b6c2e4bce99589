"""A vehicle's fit settings, read from its configuration: the model keys (an order or
structure, and the estimator: ``order2``, ``order2_kalman``), the structure of each, the
experiments a fit is given (the identification windows, the input hold, the outputs
compared, the surface sensors' channels), the start values and bounds of the parameters
(kA from eq. 10 or the energy balance, the conductances' span, the air's capacity as a
lower bound of C), the noise of the measured inputs and the options of stage two (kA fixed)
and of the joint fit; and the fit itself by the vehicle's estimator
(:func:`estimate_parameters`). :mod:`railtherm.study.identify` runs the stages with them."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from railtherm import structures
from railtherm.data import ingest
from railtherm.errors import ConfigError, DataError
from railtherm.estimation import models, pem
from railtherm.estimation.kvalue import sensor_counts, sensor_u_K
from railtherm.estimation.priors import prior_from_config
from railtherm.study.quality import RHO_CP_AIR

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


def compared_outputs(structure: models.Structure, vehicle_data: Mapping[str, Any], tables) -> tuple:
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
        "outputs": compared_outputs(structure, vehicle_data, tables),
        "x0": model.get("x0", X0_DEFAULT),
        "covariance": model.get("covariance", "hac"),
        "start": model.get("start", "auto"),
    }
    priors = model_priors(structure, model, estimator)
    if priors:  # with none the options are the maximum-likelihood fit's, as before
        options["priors"] = priors
    return options, k_source, notes


def model_priors(structure, model: Mapping[str, Any], estimator: str) -> dict[str, Any]:
    """The priors of ``model.priors`` (:class:`railtherm.estimation.priors.Prior`) that the
    fit of ``structure`` by ``estimator`` can use: its parameters, and for the kalman
    estimator its noise parameters (``sigma_<state>``, ``s_<output>``)."""
    names = set(structure.parameters)
    if estimator == "kalman":
        names |= {f"sigma_{s}" for s in structure.states} | {f"s_{s}" for s in structure.states}
    return {
        name: prior_from_config(spec, f"model.priors.{name}")
        for name, spec in (model.get("priors") or {}).items()
        if name in names
    }


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
