"""The standardized static k value (paper section 2.4, eq. 10) with a steady-state verdict and a
GUM uncertainty budget.

Eq. 10, 0 = Q_H - k A (T - T_o), holds only at rest (dT/dt = 0). Over a steady window of a tidy
table (columns ``time``, ``T``, ``T_veh``, ``T_o``, ``Q_H``; see :mod:`railtherm.data.ingest`)::

    k = mean(Q_H) / (A (mean(T) - mean(T_o)))          (eq. 10)        kA = k A

Window means are time means over [t_0, t_N] (t_0 the first, t_N the last grid point):
temperatures are point values, averaged by the trapezoidal rule; ``Q_H[n]`` is the mean power
over [t_n, t_n + step) (the zero-order hold of eq. 15), so the rows n = 0..N-1 cover the window
exactly and the last row (which covers time after the window) is left out. The duration is
t_N - t_0.

Steady-state verdict: a least-squares straight line is fitted to T, T_o and Q_H over the
window; the drift of each is its slope times the duration, with a standard uncertainty u(drift)
from the residuals about the line, widened by their integrated autocorrelation time (a
thermostat's on/off cycling makes them strongly correlated). A drift fails the window when it
exceeds its limit by more than 2 u(drift): |drift| - 2 u(drift) > limit, so that a trend which
cycling cannot tell from the limit is not taken as evidence of drift. The window is *steady*
when no drift fails (limits ``max_drift_T_K``, ``max_drift_T_o_K``, ``max_drift_Q_H_rel``
mean(Q_H)), mean(T - T_o) >= ``min_delta_T_K`` and the duration >= ``min_duration_h``.
Each failed test adds one plain sentence with the numbers to ``reasons``.
``force: true`` makes a failed window *usable* (``forced``) without making it steady.

Standard uncertainty u(k) (GUM, first-order propagation, independent components, all in
W/(m^2 K)); k is a product of powers, so each relative uncertainty enters with sensitivity 1:

* ``power``: u_rel(Q_H) = ``power_u_rel``, applied to the total Q_H (the meters are taken as
  fully correlated: one rig, one calibration reference, and the tidy table carries only the
  sum; independent channels would give up to sqrt(n) less, so this is the conservative side).
* ``temperature``: the calibration error of a weighted mean of n sensors is u_T / sqrt(n_eff)
  with n_eff = (sum w)^2 / sum w^2 (Kish; = n for equal weights), u_T the group's sensor
  accuracy (:func:`sensor_u_K`); T and T_o independent:
  u(dT) = sqrt(u_in^2 / n_indoor + u_out^2 / n_outdoor), relative u(dT) / dT.
* ``surface``: ``surface_u_rel``.
* ``scatter``: the random error of eq. 10 itself. To first order,
  k_hat - k = mean(r) / (A mean(T - T_o)) with the energy-balance residual
  r[n] = Q_H[n] - kA (T - T_o)[n] (T - T_o over the step Q_H[n] covers, kA from eq. 10): the
  heat that goes into or comes out of storage. Its mean over the window is the change of the
  stored energy E(t) = integral of r (about its fitted line) between the window's two ends,
  divided by the duration; with the ends independent, u_E = sqrt(2) sd(E) / duration. A
  thermostat's cycling moves heat in and out of storage and so sets sd(E), but its mean
  cancels over the window except for the ends: the standard error of the mean of r treated as
  a noise series (Q_H and T - T_o apart, or together) overstates it several times, since it
  sees the cycling's swings but not that they cancel. White measurement noise on r adds
  u_w = sigma_w / sqrt(n), sigma_w^2 = mean((r[n+1] - r[n])^2) / 2 (von Neumann; the
  cycling's jumps make it conservative); u = sqrt(u_E^2 + u_w^2) / (A mean(T - T_o)).
* ``storage``: heat still going into storage biases eq. 10. It is bounded by
  ``mass_kg`` ``storage_c_J_per_kgK`` |dT_s/dt| (the fitted slope of T_veh if the table has it,
  since the body stores most; else of T), taken as a rectangular half-width:
  u = bound / sqrt(3) / (A dT).

u(k) is the root sum of squares of the components.

Without a surface (``surface_m2`` may be left out for an object of class other, a test cell or
a building) k is not given: the test gives kA = mean(Q_H) / (mean(T) - mean(T_o)) and its
relative uncertainty ``u_k_rel``, the budget is in W/K (that of kA) and has no ``surface``
term. Without a mass (``mass_kg``) the heat still going into storage is not bounded: the
``storage`` term is 0 and a note says so. Both stay usable for the two-stage fit, which needs
kA only.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from railtherm.data import plausibility
from railtherm.errors import DataError
from railtherm.estimation import models
from railtherm.estimation.acf import autocorrelation_time

__all__ = [
    "Budget",
    "KValue",
    "StorageBalance",
    "StorageCorrection",
    "autocorrelation_time",
    "balance_of",
    "effective_count",
    "sensor_counts",
    "sensor_u_K",
    "static_k",
    "storage_balance",
    "storage_corrected_kA",
]

SQRT3 = math.sqrt(3.0)
COMPONENTS = ("power", "temperature", "surface", "scatter", "storage")


@dataclass(frozen=True)
class Budget:
    """Uncertainty budget of k: standard uncertainties in W/(m^2 K) (``COMPONENTS``; their root
    sum of squares is u_k) and the figures behind them.

    ``storage_bound_W`` is the bound on the heat still going into storage, mass c |dT_s/dt|
    (W), ``storage_bound_k`` the same bound expressed in k (W/(m^2 K)), ``storage_rate_K_per_h``
    the slope used and ``storage_from`` its source column (``T_veh`` or ``T``);
    ``n_indoor``/``n_outdoor`` the effective sensor counts used for the calibration term.
    ``unit`` is that of the components: W/(m2 K), that of k, or W/K, that of kA, where no
    surface is given. Without a mass, ``storage_bound_W``/``_k`` are None and ``storage`` is 0.
    """

    power: float
    temperature: float
    surface: float
    scatter: float
    storage: float
    storage_bound_W: float | None
    storage_bound_k: float | None
    storage_rate_K_per_h: float
    storage_from: str
    n_indoor: float
    n_outdoor: float
    power_basis: str = "total"
    unit: str = "W/(m2 K)"

    def components(self) -> dict[str, float]:
        """The standard-uncertainty components (W/(m^2 K)), in ``COMPONENTS`` order."""
        return {name: float(getattr(self, name)) for name in COMPONENTS}

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = self.components()
        out.update(
            storage_bound_W=_optional(self.storage_bound_W),
            storage_bound_k=_optional(self.storage_bound_k),
            storage_rate_K_per_h=float(self.storage_rate_K_per_h),
            storage_from=self.storage_from,
            n_indoor=float(self.n_indoor),
            n_outdoor=float(self.n_outdoor),
            power_basis=self.power_basis,
            unit=self.unit,
        )
        return out


@dataclass(frozen=True)
class KValue:
    """Result of the static k test on one window (eq. 10); SI units, k in W/(m^2 K).

    ``steady`` is the verdict, ``forced`` is true when the config forces a window that failed
    it, ``usable`` = steady or forced; ``reasons`` lists every failed test (empty if steady).
    ``window_start``/``window_end`` are the raw time labels of the first and last grid point.
    ``k``, ``u_k`` and ``A`` are None where no surface is given (kA and ``u_k_rel`` still are);
    ``notes`` says what the test could not give for want of metadata.
    """

    k: float | None
    u_k: float | None
    u_k_rel: float
    kA: float
    A: float | None
    delta_T: float
    Q_H_mean: float
    T_mean: float
    T_o_mean: float
    duration_h: float
    drift_T_K: float
    drift_T_o_K: float
    drift_Q_H_rel: float
    u_drift_T_K: float
    u_drift_T_o_K: float
    u_drift_Q_H_rel: float
    steady: bool
    forced: bool
    usable: bool
    reasons: tuple[str, ...]
    budget: Budget
    window_start: Any = None
    window_end: Any = None
    notes: tuple[str, ...] = ()
    plausibility: tuple[str, ...] = ()  # k outside the physical range: a unit mistake

    @property
    def u_kA(self) -> float:
        """Standard uncertainty of kA, W/K."""
        return float(self.u_k_rel * self.kA)

    def to_dict(self) -> dict[str, Any]:
        """A plain dict for YAML: Python floats/bools/str (None for k, u_k and A without a
        surface), keys in a fixed order.

        Returns
        -------
        dict
            The content of ``kvalue.yaml``.
        """
        return {
            "k": _optional(self.k),
            "u_k": _optional(self.u_k),
            "u_k_rel": float(self.u_k_rel),
            "kA": float(self.kA),
            "A": _optional(self.A),
            "u_kA": self.u_kA,
            "delta_T": float(self.delta_T),
            "Q_H_mean": float(self.Q_H_mean),
            "T_mean": float(self.T_mean),
            "T_o_mean": float(self.T_o_mean),
            "duration_h": float(self.duration_h),
            "drift_T_K": float(self.drift_T_K),
            "drift_T_o_K": float(self.drift_T_o_K),
            "drift_Q_H_rel": float(self.drift_Q_H_rel),
            "u_drift_T_K": float(self.u_drift_T_K),
            "u_drift_T_o_K": float(self.u_drift_T_o_K),
            "u_drift_Q_H_rel": float(self.u_drift_Q_H_rel),
            "steady": bool(self.steady),
            "forced": bool(self.forced),
            "usable": bool(self.usable),
            "notes": list(self.notes),
            "reasons": list(self.reasons),
            "plausibility": list(self.plausibility),
            "budget": self.budget.to_dict(),
            "window": {"start": _plain(self.window_start), "end": _plain(self.window_end)},
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> KValue:
        """The inverse of :meth:`to_dict` (a kvalue.yaml read back).

        Parameters
        ----------
        data : mapping
            The content of a ``kvalue.yaml``.

        Returns
        -------
        KValue
            The static test's result.
        """
        names = {f.name for f in dataclasses.fields(cls)} - {
            "budget",
            "reasons",
            "notes",
            "plausibility",
        }
        window = data.get("window") or {}
        return cls(
            **{k: data[k] for k in names if k in data},
            reasons=tuple(data["reasons"]),
            notes=tuple(data.get("notes") or ()),
            plausibility=tuple(data.get("plausibility") or ()),
            budget=Budget(**data["budget"]),
            window_start=window.get("start"),
            window_end=window.get("end"),
        )


def _optional(value: float | None) -> float | None:
    """A float for YAML, or None for a quantity not given."""
    return None if value is None else float(value)


def _plain(value: Any) -> Any:
    """A YAML-safe scalar: numpy numbers -> Python numbers, timestamps -> ISO text."""
    if value is None:
        return None
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, (int, float, str, bool)):
        return value
    if hasattr(value, "isoformat"):
        return value.isoformat()
    return str(value)


# ---------------------------------------------------------------------------------------------
# Statistics helpers


def effective_count(weights: Sequence[float]) -> float:
    """Kish's effective number of a weighted mean, (sum w)^2 / sum w^2.

    The weighted mean of n sensors with independent errors of equal u has u / sqrt(n_eff)."""
    w = np.asarray(weights, dtype=float)
    if w.size == 0 or np.any(w <= 0):
        raise ValueError(f"weights must be positive and non-empty, got {list(w)}")
    return float(w.sum() ** 2 / np.sum(w**2))


def sensor_u_K(instruments: Mapping[str, Any], group: str) -> float:
    """Standard uncertainty (K) of one calibrated sensor of ``group`` (indoor, surface,
    outdoor): ``instruments.<group>_temperature_u_K`` where declared, else
    ``instruments.temperature_u_K``."""
    return float(instruments.get(f"{group}_temperature_u_K", instruments["temperature_u_K"]))


def sensor_counts(channels: Mapping[str, Sequence[Mapping[str, Any]]]) -> dict[str, float]:
    """Effective sensor counts for :func:`static_k` from a vehicle's ``channels`` section.

    ``indoor``/``outdoor``: Kish effective numbers of the weighted means (weights default 1);
    ``surface`` the number of surface sensors; ``power`` the number of power channels (heater
    plus fan; reported only, see the module docstring on the power term)."""

    def weights(group: str) -> list[float]:
        return [float(c.get("weight", 1.0)) for c in channels.get(group, [])]

    return {
        "indoor": effective_count(weights("indoor_air")),
        "outdoor": effective_count(weights("outdoor_air")),
        "surface": float(len(channels.get("surface", []))),
        "power": float(len(channels.get("heater_power", [])) + len(channels.get("fan_power", []))),
    }


def _line(t: np.ndarray, y: np.ndarray) -> tuple[float, np.ndarray]:
    """Least-squares slope of y(t) and the residuals about the fitted line."""
    tc = t - t.mean()
    slope = float(tc @ (y - y.mean()) / (tc @ tc))
    return slope, y - y.mean() - slope * tc


def _drift(t: np.ndarray, y: np.ndarray, duration: float) -> tuple[float, float]:
    """(drift, its standard uncertainty) of y across the window: the
    least-squares slope times the duration, with the slope's standard error from the residuals
    widened by their integrated autocorrelation time (thermostat cycling correlates them)."""
    slope, residuals = _line(t, y)
    tc = t - t.mean()
    if residuals.size < 3:
        return slope * duration, 0.0
    variance = float(residuals @ residuals) / (residuals.size - 2)
    se_slope = math.sqrt(variance * autocorrelation_time(residuals) / float(tc @ tc))
    return slope * duration, se_slope * duration


def _trapezoid_mean(t: np.ndarray, y: np.ndarray) -> float:
    return float(np.sum((y[1:] + y[:-1]) * np.diff(t)) / 2.0 / (t[-1] - t[0]))


def _zoh_mean(t: np.ndarray, q: np.ndarray) -> float:
    """Time mean over [t_0, t_N] of a signal held at q[n] over [t_n, t_{n+1})."""
    return float(np.sum(q[:-1] * np.diff(t)) / (t[-1] - t[0]))


# ---------------------------------------------------------------------------------------------
# The k value


def _column(window: pd.DataFrame, name: str, source: str, required: bool = True) -> np.ndarray:
    if name not in window.columns:
        if not required:
            return np.full(len(window), np.nan)
        raise DataError(source, name, None, "column missing from the tidy k window")
    values = pd.to_numeric(window[name], errors="coerce").to_numpy(dtype=float)
    if required and not np.all(np.isfinite(values)):
        i = int(np.flatnonzero(~np.isfinite(values))[0])
        raise DataError(
            source, name, _plain(window[name].iloc[i]), f"not a finite number in row {i}"
        )
    return values


def _fmt(x: float) -> str:
    return f"{x:g}"


def static_k(
    window: pd.DataFrame,
    A: float | None,
    mass_kg: float | None,
    settings: Mapping[str, Any],
    instruments: Mapping[str, Any],
    n_sensors: Mapping[str, float],
    *,
    source: str = "k window",
) -> KValue:
    """The static k value of eq. 10 over a tidy k window, its verdict and u(k).

    ``settings`` is the vehicle's ``kvalue`` section, ``instruments`` its ``instruments``
    section (both with schema defaults filled), ``n_sensors`` the effective sensor counts
    ``{"indoor": ..., "outdoor": ...}`` (:func:`sensor_counts`). ``source`` names the table in
    error messages. ``A`` None (no surface): k is not given, the budget is that of kA (W/K);
    ``mass_kg`` None: the storage term is not bounded (0, with a note). Raises
    :class:`~railtherm.errors.DataError` for a missing or non-finite column, fewer than 3
    rows, a non-increasing time, mean(T - T_o) <= 0 or mean(Q_H) <= 0 (no k exists then)."""
    if len(window) < 3:
        raise DataError(source, "time", len(window), "the k window needs at least 3 rows")
    t, T, T_o, Q_H, T_veh = _window_columns(window, source)
    if (A is not None and not A > 0) or (mass_kg is not None and not mass_kg > 0):
        raise ValueError(f"A and mass_kg must be > 0 or None, got A={A}, mass_kg={mass_kg}")
    per = 1.0 if A is None else A  # the budget's unit: that of k, or of kA without a surface

    duration = float(t[-1] - t[0])
    T_mean = _trapezoid_mean(t, T)
    T_o_mean = _trapezoid_mean(t, T_o)
    delta_T = T_mean - T_o_mean
    Q_mean = _zoh_mean(t, Q_H)
    _check_means(source, T_mean, T_o_mean, Q_mean)
    kA = Q_mean / delta_T
    k = kA / per

    # -- verdict --------------------------------------------------------------------------
    t_q = t[:-1] + np.diff(t) / 2.0  # Q_H[n] is the mean over [t_n, t_n+1)
    drift_T, u_drift_T = _drift(t, T, duration)
    drift_T_o, u_drift_T_o = _drift(t, T_o, duration)
    drift_Q, u_drift_Q = _drift(t_q, Q_H[:-1], duration)
    drift_Q_rel, u_drift_Q_rel = drift_Q / Q_mean, u_drift_Q / Q_mean
    duration_h = duration / 3600.0

    lim = {key: float(settings[key]) for key in _LIMITS}
    reasons = _unsteady_reasons(
        lim, (drift_T, u_drift_T), (drift_T_o, u_drift_T_o), (drift_Q_rel, u_drift_Q_rel),
        delta_T, duration_h,
    )  # fmt: skip
    steady = not reasons
    forced = bool(settings.get("force", False)) and not steady
    usable = steady or forced

    # -- uncertainty budget (W/(m^2 K)) ---------------------------------------------------
    u_in_K, u_out_K = sensor_u_K(instruments, "indoor"), sensor_u_K(instruments, "outdoor")
    n_in, n_out = float(n_sensors["indoor"]), float(n_sensors["outdoor"])
    if not (n_in > 0 and n_out > 0):
        raise ValueError(f"sensor counts must be > 0, got {dict(n_sensors)}")
    u_power = k * float(instruments["power_u_rel"])
    u_temp = k * math.sqrt(u_in_K**2 / n_in + u_out_K**2 / n_out) / delta_T
    u_surface = k * float(instruments["surface_u_rel"]) if A is not None else 0.0

    u_scatter = _scatter_W(t, t_q, T, T_o, Q_H, kA) / (per * delta_T)

    rate, storage_from = _storage_rate(t, T_veh, drift_T / duration)
    notes = []
    if A is None:
        notes.append("k = kA / A not given: no surface_m2 (the budget is that of kA, in W/K)")
    bound_W, bound_k, u_storage, storage_from, note = _storage_bound(
        mass_kg, settings, rate, per * delta_T, storage_from
    )
    notes += note
    budget = Budget(
        power=u_power,
        temperature=u_temp,
        surface=u_surface,
        scatter=u_scatter,
        storage=u_storage,
        storage_bound_W=bound_W,
        storage_bound_k=bound_k,
        storage_rate_K_per_h=rate * 3600.0,
        storage_from=storage_from,
        n_indoor=n_in,
        n_outdoor=n_out,
        unit="W/(m2 K)" if A is not None else "W/K",
    )
    u_k = math.sqrt(sum(v * v for v in budget.components().values()))

    stamps = window["timestamp"] if "timestamp" in window.columns else window["time"]
    return KValue(
        k=k if A is not None else None,
        u_k=u_k if A is not None else None,
        u_k_rel=u_k / k,
        kA=kA,
        A=float(A) if A is not None else None,
        delta_T=delta_T,
        Q_H_mean=Q_mean,
        T_mean=T_mean,
        T_o_mean=T_o_mean,
        duration_h=duration_h,
        drift_T_K=drift_T,
        drift_T_o_K=drift_T_o,
        drift_Q_H_rel=drift_Q_rel,
        u_drift_T_K=u_drift_T,
        u_drift_T_o_K=u_drift_T_o,
        u_drift_Q_H_rel=u_drift_Q_rel,
        steady=steady,
        forced=forced,
        usable=usable,
        reasons=tuple(reasons),
        budget=budget,
        window_start=stamps.iloc[0],
        window_end=stamps.iloc[-1],
        notes=tuple(notes),
    )


def _window_columns(window: pd.DataFrame, source: str) -> tuple[np.ndarray, ...]:
    """time (increasing), T, T_o, Q_H and T_veh (NaN where not measured) of a k window
    (:func:`static_k`)."""
    t = _column(window, "time", source)
    if np.any(np.diff(t) <= 0):
        i = int(np.flatnonzero(np.diff(t) <= 0)[0]) + 1
        raise DataError(source, "time", float(t[i]), f"not increasing at row {i}")
    T = _column(window, "T", source)
    T_o = _column(window, "T_o", source)
    Q_H = _column(window, "Q_H", source)
    return t, T, T_o, Q_H, _column(window, "T_veh", source, required=False)


def _check_means(source: str, T_mean: float, T_o_mean: float, Q_mean: float) -> None:
    """Eq. 10 needs mean(T - T_o) > 0 and mean(Q_H) > 0 (:func:`static_k`): else a
    :class:`~railtherm.errors.DataError` that names what to check."""
    delta_T = T_mean - T_o_mean
    if not delta_T > 0:
        raise DataError(
            source,
            "T - T_o",
            round(delta_T, 6),
            f"the mean T - T_o must be > 0 for eq. 10 (mean T {T_mean:.4g} degC, mean T_o "
            f"{T_o_mean:.4g} degC, mean Q_H {Q_mean:.4g} W): are channels.indoor_air and "
            "outdoor_air, or a power and a temperature channel, swapped? Is the k window where "
            "the vehicle is heated?",
        )
    if not Q_mean > 0:
        raise DataError(
            source,
            "Q_H",
            round(Q_mean, 6),
            f"the mean Q_H must be > 0 for eq. 10 (mean T - T_o {delta_T:.4g} K): is a power "
            "channel's sign or column wrong, or the k window outside the heated test?",
        )


def _unsteady_reasons(lim, T, T_o, Q_rel, delta_T: float, duration_h: float) -> list[str]:
    """Why a k window is not steady (:func:`static_k`): each drift (value, standard
    uncertainty) beyond its limit, a small mean T - T_o, a short window."""
    drift_T, u_drift_T = T
    drift_T_o, u_drift_T_o = T_o
    drift_Q_rel, u_drift_Q_rel = Q_rel
    reasons = []
    # A drift fails the window when it exceeds its limit by more than twice its own standard
    # uncertainty: a trend that cycling or noise cannot tell from the limit is no evidence.
    if abs(drift_T) - 2 * u_drift_T > lim["max_drift_T_K"]:
        reasons.append(
            f"T drifts by {drift_T:+.2f} +- {u_drift_T:.2f} K across the window "
            f"(limit {_fmt(lim['max_drift_T_K'])} K)"
        )
    if abs(drift_T_o) - 2 * u_drift_T_o > lim["max_drift_T_o_K"]:
        reasons.append(
            f"T_o drifts by {drift_T_o:+.2f} +- {u_drift_T_o:.2f} K across the window "
            f"(limit {_fmt(lim['max_drift_T_o_K'])} K)"
        )
    if abs(drift_Q_rel) - 2 * u_drift_Q_rel > lim["max_drift_Q_H_rel"]:
        reasons.append(
            f"Q_H drifts by {100 * drift_Q_rel:+.1f} +- {100 * u_drift_Q_rel:.1f} % of its mean "
            f"across the window (limit {_fmt(100 * lim['max_drift_Q_H_rel'])} %)"
        )
    if delta_T < lim["min_delta_T_K"]:
        reasons.append(
            f"the mean T - T_o is {delta_T:.2f} K (minimum {_fmt(lim['min_delta_T_K'])} K)"
        )
    if duration_h < lim["min_duration_h"]:
        reasons.append(
            f"the window lasts {duration_h:.2f} h (minimum {_fmt(lim['min_duration_h'])} h)"
        )
    return reasons


def _scatter_W(t, t_q, T, T_o, Q_H, kA: float) -> float:
    """The scatter of eq. 10's balance (:func:`static_k`), in W: the swing of the heat going
    into storage (E(t), the balance Q_H - kA (T - T_o) about its line, integrated) at the
    window's ends, and the balance's noise, in quadrature."""
    duration = float(t[-1] - t[0])
    dT_step = (T[:-1] - T_o[:-1] + T[1:] - T_o[1:]) / 2.0  # over the step Q_H[n] covers
    _, balance = _line(t_q, Q_H[:-1] - kA * dT_step)
    stored = np.cumsum(balance * np.diff(t))  # E(t): heat into storage since the start, J
    u_stored = math.sqrt(2.0) * float(np.std(stored, ddof=1)) / duration
    u_noise = math.sqrt(float(np.mean(np.diff(balance) ** 2)) / 2.0 / balance.size)
    return math.hypot(u_stored, u_noise)


def _storage_rate(t: np.ndarray, T_veh: np.ndarray, drift_rate: float) -> tuple[float, str]:
    """The rate (K/s) at which heat still goes into storage: T_veh's slope where it is
    measured, else T's drift rate (:func:`static_k`)."""
    finite_veh = np.isfinite(T_veh)
    if np.count_nonzero(finite_veh) >= 2:
        return _line(t[finite_veh], T_veh[finite_veh])[0], "T_veh"
    return drift_rate, "T"


def _storage_bound(mass_kg, settings, rate: float, per_delta_T: float, storage_from: str):
    """The storage term of u(k) (:func:`static_k`): the bound m c |rate| in W and in k's
    unit (``per_delta_T``: A mean(T - T_o)), its standard uncertainty (uniform), where the
    rate comes from, and a note where no mass bounds it."""
    if mass_kg is None:
        return (
            None,
            None,
            0.0,
            "not bounded: no mass_kg",
            [
                "the heat still going into storage is not bounded: no mass_kg (u(k) has no "
                "storage term)"
            ],
        )
    bound_W = mass_kg * float(settings["storage_c_J_per_kgK"]) * abs(rate)
    bound_k = bound_W / per_delta_T
    return bound_W, bound_k, bound_k / SQRT3, storage_from, []


_LIMITS = (
    "max_drift_T_K",
    "max_drift_T_o_K",
    "max_drift_Q_H_rel",
    "min_delta_T_K",
    "min_duration_h",
)


K_RANGE = (0.1, 10.0)  # W/(m2 K): the default of check.k_range_W_m2K


def for_vehicle(window: pd.DataFrame, vehicle_data: Mapping[str, Any], source: str) -> KValue:
    """:func:`static_k` with A, mass, settings, instruments and sensor counts from a vehicle's
    validated config (``Vehicle.data``); a surface or mass the config does not give is None.
    A heated cabin colder than the tunnel or at a temperature no k-value test holds is refused
    first, and a k far from the vehicle class's is a plausibility note
    (:mod:`railtherm.data.plausibility`: a temperature channel's unit)."""
    A, mass = vehicle_data.get("surface_m2"), vehicle_data.get("mass_kg")
    plausibility.check_k_window(window, vehicle_data, source)
    result = static_k(
        window,
        A=None if A is None else float(A),
        mass_kg=None if mass is None else float(mass),
        settings=vehicle_data["kvalue"],
        instruments=vehicle_data["instruments"],
        n_sensors=sensor_counts(vehicle_data["channels"]),
        source=source,
    )
    lo, hi = (float(x) for x in (vehicle_data.get("check") or {}).get("k_range_W_m2K", K_RANGE))
    if result.k is not None and not lo <= result.k <= hi:
        why = (
            f"k = {result.k:.4g} W/(m² K) lies outside the physical range {lo:g}-{hi:g} "
            "W/(m² K) (check.k_range_W_m2K): are the units of the power and temperature "
            "channels right (W or kW, degC, K or degF), and A the whole surface?"
        )
        result = dataclasses.replace(result, plausibility=(why,))
    far = plausibility.k_class_reason(result.k, vehicle_data, "the static test's (eq. 10)")
    if far is not None:
        result = dataclasses.replace(result, plausibility=(*result.plausibility, far))
    return result


# ---------------------------------------------------------------------------------------------
# The storage-corrected k (eqs. 7-8 over the k window)


@dataclass(frozen=True)
class StorageCorrection:
    """kA of the k window's energy balance under the second-order model (eqs. 7-8), given the
    capacities: see :func:`storage_corrected_kA`. SI units; ``D0`` (K) is the body's lag
    T(t_0) - T_veh(t_0) at the window's start (None where T_veh is measured), ``u_kA`` the
    standard uncertainty of kA from the regression, ``corr_kA_D0`` the correlation of the two
    estimates (0 without D0), ``storage_W`` the mean heat taken up by the structure over the
    window (Q_H - kA (T - T_o), averaged), ``tau_veh_h`` = C_veh / K_veh in hours."""

    kA: float
    u_kA: float
    D0: float | None
    u_D0: float | None
    corr_kA_D0: float
    storage_W: float
    T_veh_from: str
    tau_veh_h: float
    duration_h: float
    n_eff: float

    def to_dict(self) -> dict[str, Any]:
        return {f.name: _plain(getattr(self, f.name)) for f in dataclasses.fields(self)}


def _body_response(T: np.ndarray, s: np.ndarray, tau_veh: float) -> np.ndarray:
    """T_veh^0 of :func:`storage_corrected_kA`: eq. 8's lag tau_veh dT_veh/dt = T - T_veh from
    T_veh(0) = T(0), driven by T linear between grid points (first-order hold) on the uniform
    grid s: T_veh[n+1] = a T_veh[n] + (G0 - G1) T[n] + G1 T[n+1] with (a, G0, G1) the exact
    ramp discretisation of :func:`railtherm.estimation.models.discretize_ramp`."""
    if s.size < 2:
        raise ValueError("the k window has fewer than two rows")
    step = float(s[1] - s[0])
    if not np.allclose(np.diff(s), step):
        raise ValueError("the k window's time steps are not equally spaced")
    a, G0, G1 = (float(M[0, 0]) for M in models.discretize_ramp([[-1.0]], [[1.0]], step / tau_veh))
    forcing = (G0 - G1) * T[:-1] + G1 * T[1:]
    return models.recursion(a, np.append(forcing, 0.0), T[0])


@dataclass(frozen=True)
class StorageBalance:
    """The k window's energy balance of :func:`storage_corrected_kA` as a linear regression
    y = X beta, beta = (kA, [D0 C_veh,] c): the time from the window's start ``s`` (s), the
    heat supplied ``E`` (J) and the integral of T - T_o (K s, trapezoidal) from the start,
    the stored-heat-corrected energy ``y`` (J) and the regressors ``X``; ``T_veh_from`` says
    whether T_veh was measured ("T_veh") or follows eq. 8 ("model (eq. 8)")."""

    s: np.ndarray
    E: np.ndarray
    integral: np.ndarray
    y: np.ndarray
    X: np.ndarray
    T_veh_from: str


def storage_balance(
    window: pd.DataFrame, C: float, K_veh: float, C_veh: float, *, source: str = "k window"
) -> StorageBalance:
    """The regression of :func:`storage_corrected_kA` for the k window ``window`` (columns
    time, T, T_o, Q_H and, where measured, T_veh) given the capacities (SI).

    Parameters
    ----------
    window : DataFrame
        The k window's rows.
    C, K_veh, C_veh : float
        The second-order model's capacities and body conductance (eqs. 7-8), all > 0.
    source : str
        The window's name in errors.

    Returns
    -------
    StorageBalance
    """
    t = _column(window, "time", source)
    T = _column(window, "T", source)
    T_o = _column(window, "T_o", source)
    Q_H = _column(window, "Q_H", source)
    T_veh = _column(window, "T_veh", source, required=False)
    return balance_of(t, T, T_o, Q_H, T_veh, C, K_veh, C_veh)


def balance_of(
    t: np.ndarray,
    T: np.ndarray,
    T_o: np.ndarray,
    Q_H: np.ndarray,
    T_veh: np.ndarray,
    C: float,
    K_veh: float,
    C_veh: float,
) -> StorageBalance:
    """:func:`storage_balance` of the window's columns as arrays (time in s; T_veh all NaN
    where it is not measured).

    Parameters
    ----------
    t, T, T_o, Q_H, T_veh : ndarray
        The k window's rows.
    C, K_veh, C_veh : float
        The capacities and body conductance (eqs. 7-8), all > 0.

    Returns
    -------
    StorageBalance
    """
    if not (C > 0 and K_veh > 0 and C_veh > 0):
        raise ValueError(f"C, K_veh and C_veh must be > 0, got {C}, {K_veh}, {C_veh}")
    s = t - t[0]
    E = np.concatenate([[0.0], np.cumsum(Q_H[:-1] * np.diff(t))])
    # the trapezoidal rule cumulated, as scipy.integrate.cumulative_trapezoid(T - T_o, t,
    # initial=0) evaluates it (the same operations), without scipy.integrate's 0.2-0.4 s import
    excess = T - T_o
    integral = np.concatenate([[0.0], np.cumsum(np.diff(t) * (excess[1:] + excess[:-1]) / 2.0)])
    tau_veh = C_veh / K_veh
    y = E - C * (T - T[0])
    if np.all(np.isfinite(T_veh)):
        T_veh_from = "T_veh"
        y -= C_veh * (T_veh - T_veh[0])
        X = np.column_stack([integral, np.ones_like(s)])
    else:
        T_veh_from = "model (eq. 8)"
        y -= C_veh * (_body_response(T, s, tau_veh) - T[0])
        X = np.column_stack([integral, C_veh * -np.expm1(-s / tau_veh), np.ones_like(s)])
    return StorageBalance(s, E, integral, y, X, T_veh_from)


def storage_corrected_kA(
    window: pd.DataFrame,
    C: float,
    K_veh: float,
    C_veh: float,
    *,
    source: str = "k window",
) -> StorageCorrection:
    """kA from the k window's energy balance with the heat stored by the second-order model.

    Adding eq. 7 and eq. 8 and integrating from the window's start t_0 gives, at every grid
    point t_n::

        E(t_n) = integral of Q_H = kA integral (T - T_o) dt + C (T(t_n) - T(t_0))
                                 + C_veh (T_veh(t_n) - T_veh(t_0))

    (Q_H held over each step, the integral of T - T_o by the trapezoidal rule). Where the
    window measures T_veh (surface sensors, every row finite) its change is taken as measured
    and kA is the one unknown. Otherwise T_veh follows eq. 8, C_veh dT_veh/dt = K_veh (T -
    T_veh), driven by the measured T (linear between grid points) from an unknown start
    T_veh(t_0) = T(t_0) - D0: T_veh = T_veh^0 - D0 exp(-(t - t_0) / tau_veh), tau_veh = C_veh /
    K_veh, with T_veh^0 the response from T_veh^0(t_0) = T(t_0). Both ways the balance is
    linear in the unknowns::

        E - C (T - T(t_0)) - C_veh (T_veh^0 - T(t_0)) = kA integral (T - T_o) dt
                                                       + D0 C_veh (1 - exp(-(t - t_0) / tau_veh))
                                                       + c

    solved by least squares over t_0..t_N. The constant c is the stored energy's error at the
    anchor: the measured T(t_0) (and T_veh(t_0)) carries the sensor noise of one sample, which
    would otherwise shift every row alike (C times it); with c the noise of each row enters
    once, not through the first. Its covariance is the residuals' variance times
    (X^T X)^-1, widened by their integrated autocorrelation time (the residuals of an
    integrated balance are strongly correlated): when tau_veh is long against the window the
    D0 column approaches the kA column (both grow about linearly in t), the two are confounded
    and u(kA) grows accordingly. With a steady body (D0 = 0, T constant) the balance is eq. 10.
    """
    balance = storage_balance(window, C, K_veh, C_veh, source=source)
    s, E, integral, y, X = balance.s, balance.E, balance.integral, balance.y, balance.X
    T_veh_from, tau_veh = balance.T_veh_from, C_veh / K_veh
    beta, *_ = np.linalg.lstsq(X, y, rcond=None)
    residuals = y - X @ beta
    n, p = X.shape
    tau_int = autocorrelation_time(residuals)
    variance = float(residuals @ residuals) / max(n - p, 1) * tau_int
    cov = variance * np.linalg.pinv(X.T @ X)
    kA = float(beta[0])
    u_kA = math.sqrt(max(float(cov[0, 0]), 0.0))
    if p == 3:
        D0, u_D0 = float(beta[1]), math.sqrt(max(float(cov[1, 1]), 0.0))
        denominator = u_kA * u_D0
        corr = float(cov[0, 1]) / denominator if denominator > 0 else 0.0
    else:
        D0 = u_D0 = None
        corr = 0.0
    duration = float(s[-1])
    storage_W = (E[-1] - kA * integral[-1]) / duration
    return StorageCorrection(
        kA=kA,
        u_kA=u_kA,
        D0=D0,
        u_D0=u_D0,
        corr_kA_D0=corr,
        storage_W=float(storage_W),
        T_veh_from=T_veh_from,
        tau_veh_h=tau_veh / 3600.0,
        duration_h=duration / 3600.0,
        n_eff=n / tau_int,
    )
