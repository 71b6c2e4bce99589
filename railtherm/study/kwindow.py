"""The static k window of a planned programme, as the prediction of
:mod:`railtherm.study.design` needs it: how far the kA the two-stage fit holds fixed errs, and
how the capacities the fit gives move that kA in turn.

The paper's two-stage fit holds kA at the static test's value (eq. 10, on the k window at the
end of the programme's first phase). The study corrects eq. 10 for the heat the body still
stores (:mod:`railtherm.study.storage`): the k window's energy balance under the second-order
model (:func:`railtherm.estimation.kvalue.storage_corrected_kA`) gives kA from the capacities,
the fit gives the capacities from kA, and the two settle where they agree. Linearised about
the truth, with F the fit's error of the log parameters at the true kA, b the balance's own
error of log kA, S = d log theta / d log kA of the fit and g = d log kA / d log theta of the
balance::

    d log kA = g . d log theta + b,  d log theta = F + S d log kA
    =>  d log theta = M F + S b / (1 - g . S),  M = I + S g^T / (1 - g . S)

A slow body (C_veh / K_veh of tens of hours) makes S large (the capacities follow kA with a
slope of ten and more) and the balance's noise b - the surface sensors' noise times C_veh in
the stored heat - carries into C_veh at that slope: the prediction that leaves b out is several
times too narrow for heavy and slow vehicles.

b is linear in the records' noise (white, as the programme declares it per logged sample):
the heat supplied E = sum Q_H dt, the stored heat C (T - T(t_0)) + C_veh (T_veh - T_veh(t_0))
and the integral of T - T_o are each sums of samples; the regression's weights
(``kvalue.storage_balance``) give each sample's weight in kA, and the variance is their
squares times the samples' variances. Eq. 10 (no correction) is the same with the ratio of
means. T_veh filtered through eq. 8 from a noisy T (no surface sensors) is left out: over a
window of hours a body of time constant tau_veh averages the noise to a small fraction of
what C (T - T(t_0)) carries.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from railtherm.estimation import kvalue, models

__all__ = ["K_WINDOW_H", "StaticK", "static_k", "storage_parameters", "window_frame"]

K_WINDOW_H = 6.0  # the k window's default length: the vehicle file's kvalue.min_duration_h
STORAGE_PARAMETERS = ("C", "K_veh", "C_veh")  # the balance's capacities (eqs. 7-8)
LOG_STEP = 1e-4  # the central difference in log theta for the balance's gradient


@dataclass(frozen=True)
class StaticK:
    """How the static kA of a planned programme errs: ``dT`` the mean T - T_o over its window
    (K), ``sd_log_random`` the standard deviation of log kA its records' noise gives,
    ``gradient`` d log kA / d log theta_p of the storage-corrected balance for C, K_veh and
    C_veh (empty for eq. 10: kA does not depend on the capacities); ``method`` names which.
    ``rows`` the window's samples [a, b) and ``weights`` per measured state (T, T_veh) d log kA
    / d y_n of each of them (K^-1), for a window the fit compares too (the same noise moves
    both), whose sensors' white noise is ``noise_K``; ``sd_log_inputs`` the share of
    ``sd_log_random`` the logged inputs' noise gives.
    A window without a temperature difference (or a balance without a positive kA) gives no
    kA: ``sd_log_random`` is infinite."""

    dT: float
    sd_log_random: float
    gradient: dict[str, float] = field(default_factory=dict)
    method: str = "eq. 10"
    rows: tuple[int, int] = (0, 0)
    weights: dict[str, np.ndarray] = field(default_factory=dict)
    sd_log_inputs: float = 0.0
    noise_K: dict[str, float] = field(default_factory=dict)

    @property
    def power_share(self) -> float:
        """d log kA / d log (power scale) of the static test, the capacities held: 1 for eq.
        10; for the balance 1 - sum of its gradient, since scaling the power and every
        capacity alike scales its kA alike (eqs. 7-8 are homogeneous in them)."""
        return 1.0 - sum(self.gradient.values())


def storage_parameters(structure: models.Structure) -> bool:
    """Whether the storage-corrected balance applies: the second-order model's states and
    parameters (eqs. 7-8), as the study corrects it."""
    return tuple(structure.states) == ("T", "T_veh") and set(STORAGE_PARAMETERS) <= set(
        structure.parameters
    )


def window_frame(u: np.ndarray, x: np.ndarray, step_s: float, measured_T_veh: bool) -> pd.DataFrame:
    """The k window's rows as :func:`railtherm.estimation.kvalue.storage_balance` reads them
    (time from 0, T, T_o, Q_H, and T_veh where ``measured_T_veh``, else NaN)."""
    names = ("time", "T", "T_o", "Q_H", "T_veh")
    return pd.DataFrame(dict(zip(names, _columns(u, x, step_s, measured_T_veh), strict=True)))


def _columns(u: np.ndarray, x: np.ndarray, step_s: float, measured_T_veh: bool) -> tuple:
    """The k window's columns as :func:`railtherm.estimation.kvalue.balance_of` takes them
    (time from 0, T, T_o, Q_H, T_veh or NaN)."""
    T_veh = x[:, 1] if measured_T_veh else np.full(len(u), math.nan)
    return np.arange(len(u)) * step_s, x[:, 0], u[:, 0], u[:, 1], T_veh


def _balance_weights(
    columns: tuple, theta: Mapping[str, float], step_s: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """Each sample's weight in the balance's kA (W/K per unit of the sample): of Q_H (per
    W), T, T_o and T_veh (per K), and kA itself."""
    C, K_veh, C_veh = (float(theta[p]) for p in STORAGE_PARAMETERS)
    balance = kvalue.balance_of(*columns, C, K_veh, C_veh)
    w = np.linalg.pinv(balance.X)[0]  # kA = w . y
    kA = float(w @ balance.y)
    after = np.append(np.cumsum(w[::-1])[::-1][1:], 0.0)  # sum over n > m of w_n
    from_m = np.cumsum(w[::-1])[::-1]  # sum over n >= m
    # d(w . integral) / d(T - T_o)_m of the trapezoidal rule
    on_excess = step_s / 2.0 * (after + np.where(np.arange(len(w)) >= 1, from_m, 0.0))
    weight_Q = step_s * after
    weight_excess = -kA * on_excess  # the integral is kA's regressor
    weight_T = -C * w + weight_excess
    weight_T_o = -weight_excess
    measured = balance.T_veh_from == "T_veh"
    weight_T_veh = -C_veh * w if measured else np.zeros_like(w)
    return weight_Q, weight_T, weight_T_o, weight_T_veh, kA


def static_k(
    structure: models.Structure,
    theta: Mapping[str, float],
    u: np.ndarray,
    x: np.ndarray,
    step_s: float,
    rows: tuple[int, int],
    noise_K: Mapping[str, float],
    input_noise: Mapping[str, float],
    *,
    storage_correction: bool = True,
    free: Sequence[str] = STORAGE_PARAMETERS,
) -> StaticK:
    """The static kA's error for the k window ``rows`` [a, b) of a planned record (inputs
    ``u`` = [T_o, Q_H], states ``x``, logged every ``step_s``) at ``theta``: the random sd of
    log kA from the white noise of the indoor air's and (where compared) the surface's
    sensor groups (``noise_K``: T, T_veh) and of the logged inputs (``input_noise``: T_o in K,
    ``power_rel`` relative), and, where ``storage_correction`` applies
    (:func:`storage_parameters`), the balance's gradient in the ``free`` parameters.

    Parameters
    ----------
    structure : Structure
        The model the programme is predicted with.
    theta : mapping
        Its parameters (SI).
    u, x : ndarray
        The planned record's inputs (N x 2) and simulated states (N x states).
    step_s : float
        The logger step (s).
    rows : tuple of int
        The k window's first and end sample.
    noise_K : mapping
        The compared states' sensor noise (K, one logged sample).
    input_noise : mapping
        The logged inputs' noise: ``T_o`` (K), ``power_rel`` (relative to Q_H).
    storage_correction : bool
        Whether kA is the storage-corrected balance's (else eq. 10's).
    free : sequence of str
        Unused; kept for callers that name the fit's parameters (the balance's gradient is
        taken in C, K_veh and C_veh alike).

    Returns
    -------
    StaticK
    """
    a, b = rows
    uk, xk = u[a:b], x[a:b]
    excess = xk[:, 0] - uk[:, 0]
    dT = float(np.mean(excess))
    if not (math.isfinite(dT) and abs(dT) > 1e-9):  # no difference to divide by: no kA
        return StaticK(dT, math.inf)
    s_T = float(noise_K.get("T", 0.0))
    s_T_veh = float(noise_K.get("T_veh", 0.0))
    s_T_o = float(input_noise.get("T_o", 0.0))
    s_Q = float(input_noise.get("power_rel", 0.0)) * uk[:, 1]
    if not (storage_correction and storage_parameters(structure)):
        # eq. 10: kA = sum Q_H / sum (T - T_o), d log kA = sum dQ / sum Q - sum d(T - T_o) / ...
        inputs = float(np.sum(s_Q**2)) / float(np.sum(uk[:, 1])) ** 2
        inputs += s_T_o**2 * len(excess) / float(np.sum(excess)) ** 2
        on_T = np.full(len(excess), -1.0 / float(np.sum(excess)))
        var = inputs + float(np.sum(on_T**2)) * s_T**2
        sensors = {"T": s_T}
        return StaticK(
            dT, math.sqrt(var), {}, "eq. 10", rows, {"T": on_T}, math.sqrt(inputs), sensors
        )
    measured = "T_veh" in noise_K
    columns = _columns(uk, xk, step_s, measured)
    w_Q, w_T, w_T_o, w_T_veh, kA = _balance_weights(columns, theta, step_s)
    if not kA > 0:
        return StaticK(dT, math.inf)
    inputs = float(np.sum((w_Q * s_Q) ** 2) + np.sum(w_T_o**2) * s_T_o**2)
    var = inputs + float(np.sum(w_T**2) * s_T**2 + np.sum(w_T_veh**2) * s_T_veh**2)
    weights = {"T": w_T / kA, **({"T_veh": w_T_veh / kA} if measured else {})}
    gradient = {}
    for p in STORAGE_PARAMETERS:  # the balance's kA (its regression's first coefficient)
        moved = []
        for sign in (1.0, -1.0):
            at = {**theta, p: float(theta[p]) * math.exp(sign * LOG_STEP)}
            balance = kvalue.balance_of(*columns, *(at[q] for q in STORAGE_PARAMETERS))
            kA_at = np.linalg.lstsq(balance.X, balance.y, rcond=None)[0][0]
            if not kA_at > 0:  # the capacities moved a little leave no loss: undetermined
                return StaticK(dT, math.inf)
            moved.append(math.log(kA_at))
        gradient[p] = (moved[0] - moved[1]) / (2.0 * LOG_STEP)
    method = "storage-corrected balance"
    sensors = {"T": s_T, "T_veh": s_T_veh}
    sd_inputs = math.sqrt(inputs) / kA
    return StaticK(dT, math.sqrt(var) / kA, gradient, method, rows, weights, sd_inputs, sensors)
