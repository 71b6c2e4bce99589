"""The storage-corrected k: eq. 10's kA on a k window that is not quite steady, corrected for
the heat the capacities still take up or give off (eqs. 7-8 over the window), with the
capacities of stage two. kA and the capacities depend on each other, so the correction is
iterated to a fixed point: kA -> stage two's capacities -> eqs. 7-8's balance over the k window
-> kA, by alternation, or by the secant method where the alternation runs away; its
uncertainty replaces eq. 10's storage bound by the correction's own. The balance itself is
:func:`railtherm.estimation.kvalue.storage_corrected_kA`."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np
import pandas as pd

from railtherm.data import ingest
from railtherm.estimation import pem
from railtherm.estimation.kvalue import COMPONENTS, storage_corrected_kA
from railtherm.study.fitsettings import (
    envelope_tables,
    experiments,
    input_hold,
    input_noise,
    kA_estimated,
    model_structure,
    stage_two_options,
    surface,
)

__all__ = ["STORAGE_METHOD", "storage_corrected_k"]


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
    try:
        step, method, history = solve_storage_kA(
            structure, exps, options, kA_eq10, k_window, relative
        )
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


def solve_storage_kA(
    structure: Any,
    exps: Sequence[Any],
    options: Mapping[str, Any],
    kA_eq10: float,
    k_window: pd.DataFrame,
    relative: Mapping[str, float] | None = None,
) -> tuple[_StorageStep, str, list[float]]:
    """The storage-corrected kA of :func:`storage_corrected_k` from its parts: stage two's
    ``structure``, experiments ``exps`` and fit ``options`` (``options["fixed"]["kA"]`` eq.
    10's ``kA_eq10``), the k window (columns time, T, T_o, Q_H, T_veh where measured) and the
    components of u(kA) that stay (``relative``, relative to kA). Returns the settled step,
    the solver ("alternation" or "secant") and the balances' kA on the way; raises
    ValueError (or LinAlgError, FloatingPointError) where they do not settle, a capacity
    sits at a search bound or the balance gives no positive kA. One solver for the study
    and the design's virtual tunnel runs."""
    fit_options = {**options, "fixed": dict(options["fixed"])}
    balance = partial(
        _balance,
        structure=structure,
        exps=exps,
        fit_options=fit_options,
        k_window=k_window,
        relative=relative or {},
    )
    history: list[float] = []
    step, method = _solve(balance, structure, exps, options, kA_eq10, k_window, history)
    return step, method, history


def _balance(
    kA: float,
    initial: Mapping[str, float] | None,
    *,
    structure: Any,
    exps: Any,
    fit_options: dict[str, Any],
    k_window: pd.DataFrame,
    relative: Mapping[str, float],
) -> _StorageStep:
    """Stage two with kA fixed (warm-started from ``initial``), then the k window's balance
    under its C, K_veh, C_veh (:func:`storage_corrected_k`; ``relative``: the components of
    u(kA) that stay, relative to kA)."""
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


def _solve(balance, structure, exps, options, kA_eq10, k_window, history) -> tuple:
    """The storage-corrected kA, kA = balance(kA) (:func:`storage_corrected_k`): alternation
    from the joint fit's balance, else the secant method; the step found and the method. A
    step that does not settle raises ValueError."""
    method = "alternation"
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
    return step, method


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
