"""Predictions from an identified model: a scenario run through eqs. 7-8 (or 9, or any further
structure), with 95 % bands.

A scenario (:mod:`railtherm.study.scenario`) gives the outdoor temperature T_o, the heating (a fixed
power series, or a thermostat or PI controller to a set point with a power limit), the further
heat flows of eq. 1 (passengers, auxiliaries, door openings as heat or as air exchange),
irradiance, the initial state and the duration. :func:`simulate` runs it through a parameter
set - a checked fit (:class:`railtherm.study.fit.Fit`) or a class reference model
(:class:`railtherm.study.classmodel.ReferenceModel`) - and reports T(t), every further state
(T_veh), the heating power, its energy (kWh) and peak, and the heat-up and cool-down times to
the scenario's thresholds.

**Time.** Every input is held over a step (zero-order hold, as in eq. 15); the step's exact
discretisation is used, so the result does not depend on the step except through the inputs
and the controller, which samples T at the start of each step and holds its power over it.
Energy is the sum of the held powers times the step (the exact integral of the power). A
threshold time is the exact instant within the step at which the continuous solution crosses
the threshold (the state within a step is x(s) = x* + V exp(Lambda s) V^-1 (x_n - x*), x* the
step's equilibrium), not an interpolation.

**Air exchange.** Air exchanged with the outside (an open door, ventilation) at a volume flow
V' adds the conductance G = rho c_p V' between T and T_o to the air node (eq. 1's E_sup -
E_exh): dT/dt gains -G (T - T_o) / C. The model stays linear in the state; its matrices change
with G, so each distinct G has its own discretisation.

**Bands.** The 95 % bands are the 2.5 and 97.5 % quantiles of the same scenario run with
parameter sets drawn from what the identification says about them: for a fit, the log
parameters are drawn jointly normal with the fit's statistical covariance (sd_log and
correlation) plus each systematic error source of the type-B budget as one common normal shift
of every parameter it moves (kA of the static test included); for the stochastic (kalman)
estimator, each draw also carries the identified process noise (the diffusion Sigma of the
state equation, discretised exactly). For a class reference model, the draws come from the
spread of the class's vehicles (:meth:`railtherm.study.classmodel.ReferenceModel.draws`). A result
some draws do not reach within the duration has an open upper band ("> duration").

**Physical limits of the draws.** A drawn parameter set is a vehicle only if every capacity
and conductance is finite and positive and the air node's capacity (C of eqs. 7-8, C_bar of
eq. 9) is at least that of the air it holds, rho c_p V (V the vehicle's ``volume_m3``,
rho c_p = :data:`railtherm.study.quality.RHO_CP_AIR`). With C >= rho c_p V no draw heats up
faster than the air alone would: C dT/dt <= Q_H while T lies above T_o and T_veh, so a rise
by Delta T at power P takes at least rho c_p V Delta T / P. Draws beyond the limits are
rejected and replaced by further draws from the same generator (rejection sampling: the
distribution truncated at the limits, deterministic for a seed); the share rejected is
reported. Where it reaches 2.5 % the untruncated band's end would lie beyond the limit: the
band's end rests on the limit, not on the data. Without a volume only positivity is
enforced, and the result says so.

**No band from a fit in doubt.** A fit whose verdict is not "fit acceptable" gives the central
prediction only: its intervals hold where its assumptions do, and they are in doubt.

A fit with a parameter the data do not determine is not simulated (:class:`NotPredictable`):
its prediction would rest on a value set by the search's bound. A class reference model with
a parameter whose 95 % prediction interval spans more than a factor 1000 (or coupled to one)
gives its central prediction without a band: the class's centre is still its estimate, but
the spread of its vehicles does not bound the prediction.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from railtherm.errors import ConfigError
from railtherm.estimation import models
from railtherm.study.scenario import Scenario

__all__ = [
    "NotPredictable",
    "Outcome",
    "ParameterSet",
    "SimulationResult",
    "UnreachableSetpoint",
    "band_draws_problem",
    "load_parameters",
    "parameter_draws",
    "parameter_set",
    "prepare_steps",
    "rejected_note",
    "simulate",
]

Z95 = 1.959963984540054
DEFAULT_DRAWS = 200
PI_KP_PER_W = 0.5  # default PI gain: full power at a 2 K error (kp = power_max / 2 K)
PI_TI_S = 1800.0  # default PI integral time (s)
# a controller's power below this is rounding, not heating: where the load is nil (outdoor air
# at the set point) the PI law's difference of near-equal terms leaves about 1e-12 W, which a
# heater does not resolve and a printed energy must not show as 3.65e-12 kWh
POWER_RESOLUTION_W = 1e-6
DRAW_FACTOR = 1e8  # a class model's draws are held within this factor of its centre
MAX_DRAW_ROUNDS = 50  # rejection sampling: at most this many batches of draws per band
LIMIT_DOMINATED = 0.025  # a rejected share from which a band's end rests on the limit
# A 95 % band from fewer draws is not one: the range of n draws holds a further draw with
# probability (n - 1) / (n + 1), below 0.95 for n < 39
MIN_BAND_DRAWS = 40


def band_draws_problem(draws: int) -> str | None:
    """Why ``draws`` parameter draws cannot give a 95 % band (None when they can, or for 0:
    the central run only)."""
    if draws == 0 or draws >= MIN_BAND_DRAWS:
        return None
    return (
        f"a 95 % band needs at least {MIN_BAND_DRAWS} parameter draws (the range of n draws "
        "holds a further draw with probability (n - 1) / (n + 1)); give 0 for the central "
        "run alone"
    )


def replaced_note(rejected: int, kept: int) -> str:
    """:func:`rejected_note` of ``rejected`` draws replaced for ``kept`` ones, with the
    counts ("" when none was replaced)."""
    if not rejected:
        return ""
    return rejected_note(rejected / (rejected + kept), f" ({rejected} of {rejected + kept})")


def rejected_note(share: float, counts: str = "") -> str:
    """The sentence on a ``share`` of parameter draws rejected at the physical limits, with
    ``counts`` in words after "draws" where known; from :data:`LIMIT_DOMINATED` on it says
    the band's end rests on the limit."""
    text = (
        f"{100 * share:.1f} % of the parameter draws{counts} lay beyond the physical limits and "
        "were replaced"
    )
    if share >= LIMIT_DOMINATED:
        text += ": the band reaches the limit, an end of it rests on the limit, not on the data"
    return text


BISECTION_STEPS = 60  # bisection of a threshold crossing within one step: dt / 2^60


class UnreachableSetpoint(ConfigError):
    """The controller's power limit is below the steady-state load of the vehicle: the set
    point cannot be held (one line naming the scenario file, the key and the value)."""


class NotPredictable(ConfigError):
    """A parameter set that does not determine every parameter of its model."""


@dataclass(frozen=True)
class ParameterSet:
    """What a prediction needs of an identified model: the structure, the point parameters
    and a way to draw parameter sets (and, for the kalman estimator, the process noise).

    ``draw(n, rng)`` returns {parameter: (n,) array}; ``sigma`` the diffusion of each state
    (K/sqrt(s)) or None; ``band_sources`` says in words what the bands carry;
    ``band_withheld`` why the prediction carries no band ("" when it may: a fit whose
    verdict is not "fit acceptable" carries none)."""

    label: str
    source: str
    structure: models.Structure
    theta: Mapping[str, float]
    draw: Callable[[int, np.random.Generator], dict[str, np.ndarray]] | None = None
    sigma: np.ndarray | None = None
    band_sources: tuple[str, ...] = ()
    not_identified: tuple[str, ...] = ()
    band_withheld: str = ""
    vehicle_class: str = ""  # a class reference model's class; a fit file does not name one
    surface_m2: float | None = None  # the outer surface a class reference model was built for


@dataclass(frozen=True)
class Outcome:
    """One reported result with its 95 % band. ``status``: "ok", "not reached" (within the
    duration), "unreachable" (the set point exceeds what the power limit can hold) or
    "not requested" (the scenario names no such threshold). ``lo``/``hi`` are None without
    a band; ``hi`` is inf where some draws do not reach the threshold within the duration."""

    name: str
    unit: str
    value: float | None
    lo: float | None = None
    hi: float | None = None
    status: str = "ok"
    note: str = ""

    def to_dict(self) -> dict[str, Any]:
        def plain(v: float | None) -> float | str | None:
            if v is None:
                return None
            return float(v) if math.isfinite(v) else ("inf" if v > 0 else "-inf")

        out: dict[str, Any] = {"value": plain(self.value), "unit": self.unit}
        if self.lo is not None or self.hi is not None:
            out["ci95"] = [plain(self.lo), plain(self.hi)]
        out["status"] = self.status
        if self.note:
            out["note"] = self.note
        return out

    def text(self, scale: float = 1.0, unit: str | None = None, digits: int = 3) -> str:
        """``value [lo, hi] unit`` for people (an open bound as "> duration")."""
        unit = self.unit if unit is None else unit
        if self.status in ("not requested",):
            return self.status
        if self.value is None or not math.isfinite(self.value):
            return f"{self.status}" + (f" ({self.note})" if self.note else "")

        def fmt(v: float | None) -> str:
            if v is None:
                return "?"
            if not math.isfinite(v):
                return "not reached"
            return f"{v / scale:.{digits}g}"

        band = "" if self.lo is None else f" [{fmt(self.lo)}, {fmt(self.hi)}]"
        return f"{fmt(self.value)}{band} {unit}".rstrip()


@dataclass
class SimulationResult:
    """A scenario's prediction: ``series`` (time_h, T_o, each state, heating_W, gains_W and
    the 95 % bands <column>_lo/_hi) and the ``outcomes`` (heat_up_time_s, cool_down_time_s,
    energy_kWh, peak_power_W, final_T_C)."""

    scenario: Scenario
    label: str
    source: str
    series: pd.DataFrame
    outcomes: dict[str, Outcome]
    draws: int
    band_sources: tuple[str, ...] = ()
    notes: list[str] = field(default_factory=list)
    band_withheld: str = ""
    rejected: int = 0
    limits: str = ""

    @property
    def rejected_share(self) -> float:
        """The share of the parameter draws rejected at the physical limits (0 without
        draws)."""
        tried = self.draws + self.rejected
        return self.rejected / tried if tried else 0.0

    def limit_note(self) -> str:
        """A sentence on the draws rejected at the physical limits ("" when none was)."""
        return replaced_note(self.rejected, self.draws)

    def to_dict(self) -> dict[str, Any]:
        out = {
            "scenario": self.scenario.name,
            "scenario_file": self.scenario.file,
            "parameters": self.label,
            "source": self.source,
            "draws": self.draws,
            "band": list(self.band_sources),
        }
        if self.band_withheld:
            out["no_band"] = self.band_withheld
        if self.draws:
            out["limits"] = self.limits
            out["draws_rejected"] = self.rejected
        out["outcomes"] = {k: o.to_dict() for k, o in self.outcomes.items()}
        out["notes"] = list(self.notes)
        return out

    def summary(self) -> str:
        o = self.outcomes
        lines = [f"{self.label} - scenario {self.scenario.name} ({self.source})"]
        lines.append(f"  heat-up time:   {o['heat_up_time_s'].text(3600.0, 'h')}")
        lines.append(f"  cool-down time: {o['cool_down_time_s'].text(3600.0, 'h')}")
        hours = f"{self.scenario.duration_s / 3600.0:g} h"
        lines.append(f"  energy:         {o['energy_kWh'].text()} (over the scenario's {hours})")
        lines.append(f"  peak power:     {o['peak_power_W'].text(1000.0, 'kW')}")
        lines.append(f"  final T:        {o['final_T_C'].text(digits=3)}")
        if self.draws:
            lines.append(f"  95 % bands from {self.draws} draws: {', '.join(self.band_sources)}")
            lines.append(f"  draws held to {self.limits}")
        if self.band_withheld:
            lines.append(f"  no 95 % band: {self.band_withheld}")
        lines += [f"  - {n}" for n in [self.limit_note(), *self.notes] if n]
        return "\n".join(lines)


# --------------------------------------------------------------------------- parameter sets
def _fit_draws(fit: Any) -> tuple[Callable | None, tuple[str, ...]]:
    """Joint draws of a fit's parameters: log theta = log theta_hat + L z + E xi, with
    L L^T the statistical covariance of the free log parameters (sd_log, correlation) and
    E the signed effect of each type-B source on every parameter (xi ~ N(0, 1) per source).
    A fit read with its posterior (:attr:`railtherm.study.fit.Fit.posterior`) gives the
    posterior's own draws instead, the systematic budget mixed in as the same E xi."""
    if getattr(fit, "posterior", None) is not None:
        what = (f"posterior draws (NUTS, {fit.posterior_file})",)
        if fit.posterior_systematic:
            return fit.posterior_sample, (*what, "systematic error sources (type B)")
        return fit.posterior_sample, (*what, "no systematic budget: statistical only")
    params = fit.section("parameters")
    free = [p for p in fit.free if p in params]
    if not free:
        return None, ()
    sd = np.array([float(params[p].get("sd_log", math.nan)) for p in free])
    corr = np.array(fit.correlation, dtype=float)
    corr = np.where(np.isfinite(corr), corr, 0.0)
    np.fill_diagonal(corr, 1.0)
    if not np.all(np.isfinite(sd)):
        return None, ()
    cov = corr * np.outer(sd, sd)
    w, V = np.linalg.eigh((cov + cov.T) / 2.0)
    L = V * np.sqrt(np.clip(w, 0.0, None))  # PSD square root: L L^T = cov
    systematic = fit.section("systematic")
    effects = {
        **(systematic.get("effects_log") or {}),
        **(systematic.get("effects_log_fixed") or {}),
    }
    moved = sorted(p for p in effects if p in params)
    sources = sorted({s for p in moved for s in effects[p]})
    E = np.array([[float(effects[p].get(s, 0.0)) for s in sources] for p in moved])
    if E.size and not np.all(np.isfinite(E)):
        return None, ()
    names = list(params)
    log_hat = {p: math.log(float(params[p]["value"])) for p in names}

    def draw(n: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
        z = rng.standard_normal((n, len(free))) @ L.T
        xi = rng.standard_normal((n, len(sources))) if sources else np.zeros((n, 0))
        out = {p: np.full(n, log_hat[p]) for p in names}
        for j, p in enumerate(free):
            out[p] = out[p] + z[:, j]
        for i, p in enumerate(moved):
            out[p] = out[p] + xi @ E[i]
        return {p: np.exp(v) for p, v in out.items()}

    what = ["parameter covariance (statistical)"]
    if sources:
        what.append("systematic error sources (type B)")
    return draw, tuple(what)


def _bounded(draws: Mapping[str, np.ndarray], centre: Mapping[str, float]) -> dict:
    """Draws held within a factor :data:`DRAW_FACTOR` of the centre. A class resting on two
    vehicles has a predictive t with one degree of freedom, whose draws reach any magnitude
    (and overflow); every reported outcome saturates long before the factor (a heat-up time
    at 0 or beyond the duration, the power at its limit), so the held draws give the same
    outcomes and quantiles while the simulation stays finite."""
    bound = math.log(DRAW_FACTOR)
    out = {}
    for p, v in draws.items():
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.log(np.asarray(v, dtype=float) / centre[p])
        out[p] = centre[p] * np.exp(np.clip(np.nan_to_num(r, nan=0.0), -bound, bound))
    return out


def parameter_set(params: Any) -> ParameterSet:
    """The :class:`ParameterSet` of a :class:`railtherm.study.fit.Fit` or a class reference model
    (:class:`railtherm.study.classmodel.ReferenceModel`)."""
    from railtherm.study.fit import Fit
    from railtherm.study.quality import ACCEPTABLE

    if isinstance(params, Fit):
        withheld = (
            ""
            if params.verdict == ACCEPTABLE
            else f"fit verdict {params.verdict!r}: its intervals hold only where its assumptions do"
        )
        not_identified = tuple(p for p, q in params.parameters.items() if not q.identified)
        draw, what = _fit_draws(params)
        sigma = None
        noise = params.section("noise")
        s = params.structure
        if noise:
            sigma = np.array(
                [float(noise.get(f"sigma_{state}", {}).get("value", 0.0)) for state in s.states]
            )
            what = (*what, "process noise (kalman estimator)")
        return ParameterSet(
            label=f"{params.vehicle} {params.model}",
            source=f"identified ({params.estimator}; {params.verdict})"
            + ("; central: the posterior's medians" if params.posterior is not None else ""),
            structure=s,
            theta=params.central,
            draw=draw,
            sigma=sigma,
            band_sources=what,
            not_identified=not_identified,
            band_withheld=withheld,
        )
    from railtherm.study import classmodel

    if isinstance(params, classmodel.ReferenceModel):
        structure = models.structure_for(params.structure)
        theta = params.theta
        judged = params.parameters  # the vehicles' rule applied to the class's intervals
        return ParameterSet(
            label=(
                f"{params.vehicle_class} reference model "
                f"({params.mass_kg / 1000:.3g} t, {params.surface_m2:.4g} m²)"
            ),
            source=f"class reference model from {len(params.basis)} vehicles",
            structure=structure,
            theta=params.theta,
            draw=lambda n, rng: _bounded(params.draws(n, seed=int(rng.integers(2**31))), theta),
            band_sources=("spread of the class's vehicles (95 % prediction)",),
            band_withheld=_class_band_withheld(judged, structure),
            vehicle_class=params.vehicle_class,
            surface_m2=params.surface_m2,
        )
    raise TypeError(f"cannot simulate a {type(params).__name__}: give a Fit or a ReferenceModel")


def air_capacity(volume_m3: float | None, label: str = "volume_m3") -> float | None:
    """rho c_p V (J/K) of ``volume_m3``: :func:`railtherm.study.fitsettings.air_capacity`."""
    from railtherm.study.fitsettings import air_capacity as capacity

    return capacity(volume_m3, label)


def central_below_air(ps: ParameterSet, floor: float | None, volume_m3: float | None) -> str:
    """The note that the central parameters' air node holds less than the air of
    ``volume_m3`` (``floor``: its rho c_p V), "" when it holds as much or no volume is given."""
    air = ps.structure.air
    if floor is None or ps.theta[air] >= floor:
        return ""
    return (
        f"the central {air} = {ps.theta[air]:.4g} J/K is below the capacity of the air in "
        f"{volume_m3:g} m³ ({floor:.4g} J/K)"
    )


def _limits(structure: models.Structure, floor: float | None) -> str:
    """The physical limits the draws are held to, in words."""
    text = "every capacity and conductance > 0"
    if floor is None:
        return text + "; no volume_m3 given: the air node's capacity is not held above the air's"
    return text + f", {structure.air} ≥ ρ c_p V = {floor:.4g} J/K (the air alone)"


def _physical(
    draws: Mapping[str, np.ndarray], structure: models.Structure, floor: float | None
) -> np.ndarray:
    """Which draws are vehicles: every parameter finite and > 0 and the air node's capacity
    at least ``floor`` (rho c_p V)."""
    ok = np.ones(len(next(iter(draws.values()))), dtype=bool)
    for v in draws.values():
        v = np.asarray(v, dtype=float)
        ok &= np.isfinite(v) & (v > 0)
    if floor is not None and structure.air in draws:
        ok &= np.asarray(draws[structure.air], dtype=float) >= floor
    return ok


def _physical_draws(
    ps: ParameterSet, n: int, rng: np.random.Generator, floor: float | None
) -> tuple[dict[str, np.ndarray] | None, int]:
    """``n`` parameter draws within the physical limits by rejection sampling: batches of
    ``n`` from ``ps.draw`` with ``rng``, each draw kept in order if it is a vehicle
    (:func:`_physical`), until ``n`` are kept; and how many of those examined were rejected.
    None (and the number examined) when :data:`MAX_DRAW_ROUNDS` batches keep fewer than n."""
    kept: dict[str, list[np.ndarray]] = {}
    count = rejected = 0
    for _ in range(MAX_DRAW_ROUNDS):
        d = ps.draw(n, rng)
        ok = _physical(d, ps.structure, floor)
        idx = np.flatnonzero(ok)[: n - count]
        examined = (int(idx[-1]) + 1) if count + len(idx) == n else len(ok)
        rejected += examined - len(idx)
        for p, v in d.items():
            kept.setdefault(p, []).append(np.asarray(v, dtype=float)[idx])
        count += len(idx)
        if count == n:
            return {p: np.concatenate(v) for p, v in kept.items()}, rejected
    return None, rejected + count


def parameter_draws(
    ps: ParameterSet, draws: int, rng: np.random.Generator, floor: float | None
) -> tuple[list[dict[str, float]], int, str]:
    """The central parameters of ``ps`` and ``draws`` parameter sets within the physical
    limits (:func:`_physical_draws`, the air node at least ``floor``): (the sets, the central
    first; how many draws were rejected; why there are no draws, "" when there are). No
    draws when ``draws`` is 0 or ``ps`` draws none."""
    thetas = [dict(ps.theta)]
    if draws <= 0 or ps.draw is None:
        return thetas, 0, ""
    d, rejected = _physical_draws(ps, draws, rng, floor)
    if d is None:
        limits = _limits(ps.structure, floor)
        why = (
            f"fewer than {draws} of {MAX_DRAW_ROUNDS * draws} parameter draws lie within "
            f"the physical limits ({limits}): the spread is dominated by the limit"
        )
        return thetas, 0, why
    thetas += [
        {p: float(d[p][i]) if p in d else ps.theta[p] for p in ps.theta} for i in range(draws)
    ]
    return thetas, rejected, ""


def load_parameters(path: str | os.PathLike[str]) -> ParameterSet:
    """A parameter file: ``fit_<model>.yaml`` (rule check, ``railtherm fit --out``) or a class
    reference model (``railtherm reference``)."""
    from railtherm import io as rt_io
    from railtherm.yamlio import read_yaml

    name = str(path)
    data = read_yaml(path)  # which kind of parameter file
    if isinstance(data, dict) and data.get("kind") == "class_reference_model":
        from railtherm.study import classmodel

        return parameter_set(classmodel.read_reference_model(path))
    if isinstance(data, dict) and {"vehicle", "parameters", "structure"} <= set(data):
        from railtherm.study.fit import Fit, check_fit_file, read_fit

        fit = Fit.of(rt_io.read_fit(path, display=name))
        check_fit_file(name, fit)
        return parameter_set(read_fit(path, posterior="auto"))
    keys = sorted(data) if isinstance(data, dict) else type(data).__name__
    raise ConfigError(
        name,
        "(file)",
        keys,
        "not a parameter file: expected a fit_<model>.yaml (vehicle, structure, parameters) "
        "or a class reference model (kind: class_reference_model)",
    )


# --------------------------------------------------------------------------- the engine
@dataclass
class _Steps:
    """Per draw (S) and per distinct air-exchange conductance: the continuous matrices of
    the air-exchange-augmented model, their exact discretisation (Bd: an input held over the
    step; Bd1: a ramp over the step, for the scenario's first-order hold, else None) and
    eigen-decomposition."""

    A: np.ndarray  # (G, S, n, n)
    B: np.ndarray  # (G, S, n, m)
    Ad: np.ndarray
    Bd: np.ndarray
    Bd1: np.ndarray | None
    lam: np.ndarray  # (G, S, n) eigenvalues (complex)
    V: np.ndarray  # (G, S, n, n)
    Vinv: np.ndarray
    Qchol: np.ndarray | None  # (G, S, n, n) Cholesky of the step's noise covariance


def _matrices(structure: models.Structure, thetas: Sequence[Mapping[str, float]]):
    AB = [structure.matrices(t) for t in thetas]
    return np.array([a for a, _ in AB]), np.array([b for _, b in AB])


def _with_exchange(
    structure: models.Structure, A: np.ndarray, B: np.ndarray, C_air: np.ndarray, G: float
):
    """A, B with the conductance G (W/K) between the air node (state 0) and T_o (input 0)."""
    A = A.copy()
    B = B.copy()
    A[:, 0, 0] -= G / C_air
    B[:, 0, 0] += G / C_air
    return A, B


PLAUSIBLE_AIR_C = (-60.0, 100.0)  # an interior air temperature outside: the inputs' units


def prepare_steps(
    structure: models.Structure,
    thetas: list[dict[str, float]],
    G_values: np.ndarray,
    dt: float,
    sigma: np.ndarray | None,
    hold: str = "zero_order",
) -> _Steps:
    """Per parameter set of ``thetas`` and per air-exchange conductance of ``G_values``: the
    model's matrices with that conductance, their exact discretisation over ``dt`` under the
    input ``hold``, their eigen-decomposition and, with the diffusion ``sigma``, the
    Cholesky factor of each step's process noise."""
    A0, B0 = _matrices(structure, thetas)
    C_air = np.array([t[structure.air] for t in thetas])
    ramp = models.check_hold(hold) == "first_order"
    As, Bs, Ads, Bds, Bd1s, lams, Vs, Vinvs, Qs = [], [], [], [], [], [], [], [], []
    for G in G_values:
        A, B = _with_exchange(structure, A0, B0, C_air, float(G))
        Ad = np.empty_like(A)
        Bd = np.empty_like(B)
        Bd1 = np.empty_like(B) if ramp else None
        Q = np.empty_like(A) if sigma is not None else None
        for s in range(len(thetas)):
            Ad[s], Bd[s], G1 = models.discretize_ramp(A[s], B[s], dt, ramp)
            if ramp:
                Bd1[s] = G1
            if Q is not None:
                Qd, _ = models.discretize_noise(A[s], np.diag(sigma**2), dt)
                w, v = np.linalg.eigh(Qd)
                Q[s] = v * np.sqrt(np.clip(w, 0.0, None))
        lam, V = np.linalg.eig(A)
        As.append(A)
        Bs.append(B)
        Ads.append(Ad)
        Bds.append(Bd)
        Bd1s.append(Bd1)
        lams.append(lam)
        Vs.append(V)
        Vinvs.append(np.linalg.inv(V))
        Qs.append(Q)
    return _Steps(
        A=np.array(As),
        B=np.array(Bs),
        Ad=np.array(Ads),
        Bd=np.array(Bds),
        Bd1=np.array(Bd1s) if ramp else None,
        lam=np.array(lams),
        V=np.array(Vs),
        Vinv=np.array(Vinvs),
        Qchol=None if sigma is None else np.array(Qs),
    )


def _inputs(structure: models.Structure, scenario: Scenario) -> tuple[np.ndarray, list[str]]:
    """The scenario's exogenous inputs (N+1, m) in the structure's order with Q_H = gains only
    (the heating is added per step); the names of irradiance inputs the scenario leaves at 0."""
    N1 = len(scenario.t_s)
    u = np.zeros((N1, len(structure.inputs)))
    u[:, 0] = scenario.T_o
    u[:, 1] = scenario.gains_W
    unused = sorted(set(scenario.irradiance) - set(structure.inputs[2:]))
    if unused:
        raise ConfigError(
            scenario.file,
            f"irradiance.{unused[0]}",
            unused[0],
            f"the model has no such irradiance input; its irradiance inputs are "
            f"{list(structure.inputs[2:]) or 'none'}",
        )
    zero = []
    for j, name in enumerate(structure.inputs[2:], start=2):
        if name in scenario.irradiance:
            u[:, j] = scenario.irradiance[name]
        else:
            zero.append(name)
    return u, zero


def _steady_T(A: np.ndarray, B: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Air temperature at equilibrium for each draw (A: (S, n, n), B: (S, n, m), u: (m,))."""
    x = -np.linalg.solve(A, (B @ u)[..., None])[..., 0]
    return x[:, 0]


def _loads(
    steps: _Steps, g_index: np.ndarray, u: np.ndarray, setpoint: float
) -> tuple[np.ndarray, np.ndarray]:
    """The steady heating power (W) that holds T at the set point for every input row and
    draw, (S, N+1), and each draw's most demanding row (S,). The equilibrium air temperature
    is linear in the inputs, T* = h u with h the first row of -A^-1 B."""
    S = steps.A.shape[1]
    out = np.empty((S, len(u)))
    for g in np.unique(g_index):
        rows = np.flatnonzero(g_index == g)
        h = -np.linalg.solve(steps.A[g], steps.B[g])[:, 0, :]  # (S, m)
        T0 = h @ u[rows].T  # (S, rows)
        out[:, rows] = (setpoint - T0) / h[:, 1:2]
    return out, np.argmax(out, axis=1)


def _crossing(
    T: np.ndarray,
    X: np.ndarray,
    U: np.ndarray,
    g_index: np.ndarray,
    steps: _Steps,
    t: np.ndarray,
    threshold: float,
    rising: bool,
) -> np.ndarray:
    """The first time (s) T crosses ``threshold`` (rising or falling) for each draw; 0 if it
    starts beyond it, inf if it never crosses. Exact within the step: bisection on
    x(s) = x* + V exp(Lambda s) V^-1 (x_k - x*), every draw at once in the step it crosses
    in (the equilibrium x* and V^-1 (x_k - x*) taken once per draw)."""
    S, N1 = T.shape
    beyond = T >= threshold if rising else T <= threshold
    first = np.where(beyond.any(axis=1), beyond.argmax(axis=1), -1)
    out = np.full(S, math.inf)
    out[first == 0] = 0.0
    rows = np.flatnonzero(first > 0)
    if not len(rows):
        return out
    dt = t[1] - t[0]
    k = first[rows] - 1  # per draw, the step [t_k, t_k+1) in which it crosses
    g = g_index[k]
    A, B = steps.A[g, rows], steps.B[g, rows]
    V, lam = steps.V[g, rows], steps.lam[g, rows]
    xs = -np.linalg.solve(A, np.einsum("sij,sj->si", B, U[rows, k])[..., None])[..., 0]
    z0 = np.einsum("sij,sj->si", steps.Vinv[g, rows], (X[rows, k] - xs).astype(complex))
    lo = np.zeros(len(rows))
    hi = np.full(len(rows), dt)
    for _ in range(BISECTION_STEPS):
        mid = (lo + hi) / 2.0
        Tm = (xs + np.einsum("sij,sj->si", V, z0 * np.exp(lam * mid[:, None])).real)[:, 0]
        past = Tm >= threshold if rising else Tm <= threshold
        hi = np.where(past, mid, hi)
        lo = np.where(past, lo, mid)
        if np.all(hi - lo <= 1e-9 * dt):
            break
    out[rows] = t[k] + (lo + hi) / 2.0
    return out


def _run(
    steps: _Steps,
    scenario: Scenario,
    u: np.ndarray,
    g_index: np.ndarray,
    x0: np.ndarray,
    noise: np.ndarray | None,
    power0: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """States X (S, N+1, n), heating P (S, N+1) and inputs U (S, N+1, m) of S parameter sets
    through the scenario (the controller closing the loop step by step)."""
    S, n = x0.shape
    N1 = len(scenario.t_s)
    X = np.empty((S, N1, n))
    P = np.empty((S, N1))
    U = np.broadcast_to(u, (S, *u.shape)).copy()
    X[:, 0] = x0
    ctl = scenario.controller
    dt = scenario.dt_s
    if ctl is not None:
        on = X[:, 0, 0] < ctl.setpoint_C
        # a PI controller taking over a steady state holds its power from the start (its
        # integral at the steady power: a bumpless start); from any other start it is at 0
        integral = np.zeros(S) if power0 is None else np.asarray(power0, dtype=float).copy()
        kp = ctl.kp_W_K if ctl.kp_W_K is not None else PI_KP_PER_W * ctl.power_max_W
        ti = ctl.ti_s if ctl.ti_s is not None else PI_TI_S
    if steps.Bd1 is not None:  # each step's change of the inputs: T_o, heat flows, irradiance
        slopes = np.diff(u, axis=0)
        if ctl is None:  # a fixed heating power is a profile too; a controller's is held
            slopes[:, 1] += np.diff(scenario.heating_W)
    for k in range(N1):
        T = X[:, k, 0]
        if ctl is None:
            p = np.full(S, scenario.heating_W[k])
        elif ctl.kind == "thermostat":
            half = ctl.hysteresis_K / 2.0
            on = np.where(
                T < ctl.setpoint_C - half, True, np.where(T > ctl.setpoint_C + half, False, on)
            )
            p = np.where(on, ctl.power_max_W, ctl.power_min_W)
        else:  # PI with conditional integration (no wind-up at the limits)
            e = ctl.setpoint_C - T
            raw = kp * e + integral
            p = np.clip(raw, ctl.power_min_W, ctl.power_max_W)
            p = np.where(np.abs(p) < POWER_RESOLUTION_W, 0.0, p)
            saturated = ((raw >= ctl.power_max_W) & (e > 0)) | ((raw <= ctl.power_min_W) & (e < 0))
            integral = integral + np.where(saturated, 0.0, kp * e * dt / ti)
        P[:, k] = p
        U[:, k, 1] += p
        if k == N1 - 1:
            break
        g = int(g_index[k])
        x = np.einsum("sij,sj->si", steps.Ad[g], X[:, k]) + np.einsum(
            "sij,sj->si", steps.Bd[g], U[:, k]
        )
        if steps.Bd1 is not None:  # the scenario's inputs linear to the next grid point
            x += np.einsum("sij,j->si", steps.Bd1[g], slopes[k])
        if noise is not None:
            x = x + np.einsum("sij,sj->si", steps.Qchol[g], noise[:, k])
        X[:, k + 1] = x
    return X, P, U


def _initial(
    structure: models.Structure,
    scenario: Scenario,
    steps: _Steps,
    u: np.ndarray,
    g_index: np.ndarray,
) -> tuple[np.ndarray, np.ndarray | None]:
    """x0 of every draw (S, n) from the scenario's ``initial``, and under a controller from a
    steady start the heating power (S,) that holds it (None otherwise)."""
    S = steps.A.shape[1]
    n = len(structure.states)
    init = scenario.initial
    if init.kind == "soaked":
        return np.full((S, n), float(scenario.T_o[0])), None
    if init.kind == "given":
        values = dict(init.states_C)
        unknown = sorted(set(values) - set(structure.states))
        if unknown:
            raise ConfigError(
                scenario.file,
                "initial",
                unknown[0],
                f"the model's states are {list(structure.states)}",
            )
        T = float(values.get("T", scenario.T_o[0]))
        return np.tile([float(values.get(s, T)) for s in structure.states], (S, 1)), None
    # steady: the equilibrium of the first input row, at the set point under a controller,
    # with the scenario's mean air exchange (door openings come and go within minutes: the
    # vehicle in service is at the steady state of their mean, not of the first step's). A
    # and B are affine in the exchange, so the row-weighted mean of the matrices is theirs.
    u0 = u[0].copy()
    weights = np.bincount(g_index, minlength=steps.A.shape[0]) / len(g_index)
    A = np.einsum("g,gsij->sij", weights, steps.A)
    B = np.einsum("g,gsij->sij", weights, steps.B)
    if scenario.controller is None:
        u0[1] += scenario.heating_W[0]
        return -np.linalg.solve(A, (B @ u0)[..., None])[..., 0], None
    T0 = _steady_T(A, B, u0)
    e = np.zeros_like(u0)
    e[1] = 1.0
    dT_dP = _steady_T(A, B, e)
    power = np.clip(
        (scenario.controller.setpoint_C - T0) / dT_dP,
        scenario.controller.power_min_W,
        scenario.controller.power_max_W,
    )
    power = np.where(np.abs(power) < POWER_RESOLUTION_W, 0.0, power)
    U0 = np.tile(u0, (S, 1))
    U0[:, 1] += power
    return -np.linalg.solve(A, np.einsum("sij,sj->si", B, U0)[..., None])[..., 0], power


def _quantiles(v: np.ndarray) -> tuple[float, float]:
    lo, hi = np.quantile(v, [0.025, 0.975], method="linear")
    return float(lo), float(hi)


def _time_outcome(
    name: str, central: float, draws: np.ndarray | None, threshold: float | None, what: str
) -> Outcome:
    if threshold is None:
        return Outcome(name, "s", None, status="not requested")
    lo = hi = None
    note = ""
    if draws is not None and len(draws):
        finite = np.isfinite(draws)
        if finite.all():
            lo, hi = _quantiles(draws)
        else:
            share = 1.0 - finite.mean()
            # quantiles of a sample with some times at +inf (not reached within the duration):
            # a large stand-in keeps the interpolation finite; a quantile beyond every reached
            # time is an open bound
            reached = draws[finite]
            top = float(reached.max()) if len(reached) else -math.inf
            stand_in = 2.0 * max(top, 1.0) + 1.0
            q = np.quantile(np.where(finite, draws, stand_in), [0.025, 0.975])
            lo, hi = (float(v) if v <= top else math.inf for v in q)
            note = f"{100 * share:.0f} % of the draws do not {what} within the duration"
    if not math.isfinite(central):
        return Outcome(name, "s", math.inf, lo, hi, "not reached", note or f"T does not {what}")
    return Outcome(name, "s", central, lo, hi, "ok", note)


def _class_band_withheld(judged: Mapping[str, Any], structure: models.Structure) -> str:
    """Why a class reference model gives no band: a parameter whose 95 % prediction interval
    spans more than a factor 1000, or coupled to one (the vehicles' rule); "" otherwise. Its
    centre is still the class's estimate; the spread of the class does not bound it."""
    wide = [p for p in structure.parameters if not judged.get(p, {}).get("identified", True)]
    if not wide:
        return ""
    return (
        f"the class's vehicles leave {', '.join(wide)} not identified (a 95 % prediction "
        "interval wider than a factor 1000, or coupled to one)"
    )


def simulate(
    params: Any,
    scenario: Scenario,
    draws: int = DEFAULT_DRAWS,
    seed: int = 0,
    allow_unreachable: bool = False,
    volume_m3: float | None = None,
) -> SimulationResult:
    """Run ``scenario`` through ``params`` (a :class:`ParameterSet`, a Fit or a class
    reference model) and its ``draws`` parameter sets for the 95 % bands (0: no bands).

    The draws are held to the physical limits (module docstring): every capacity and
    conductance > 0 and, given the vehicle's ``volume_m3``, the air node's capacity at least
    rho c_p V; draws beyond them are rejected and replaced. A fit whose verdict is not "fit
    acceptable" gives no band (``band_withheld`` says why).

    Raises :class:`UnreachableSetpoint` when the controller's power limit is below the
    steady-state load under the scenario's most demanding input row (unless
    ``allow_unreachable``: then the heat-up time's status is "unreachable") and
    :class:`NotPredictable` for a fit with a parameter that is not identified (a class
    reference model with one gives its central prediction without a band)."""
    ps = params if isinstance(params, ParameterSet) else parameter_set(params)
    if ps.not_identified:
        raise NotPredictable(
            ps.label,
            "parameters",
            list(ps.not_identified),
            "not identified by the data (an estimate at a bound of the search or with an "
            "unbounded interval): no prediction rests on it",
        )
    structure = ps.structure
    u, zero_irradiance = _inputs(structure, scenario)
    G_values, g_index = np.unique(scenario.air_exchange_W_K, return_inverse=True)
    floor = air_capacity(volume_m3, ps.label)
    limits = _limits(structure, floor)
    notes = [n for n in (central_below_air(ps, floor, volume_m3),) if n]
    withheld = ps.band_withheld
    if withheld:
        draws = 0
    rng = np.random.default_rng(seed)
    thetas, rejected, unbounded = parameter_draws(ps, draws, rng, floor)
    withheld = withheld or unbounded
    noise_on = ps.sigma is not None and len(thetas) > 1 and np.any(ps.sigma > 0)
    sigma = ps.sigma if noise_on else None
    steps = prepare_steps(structure, thetas, G_values, scenario.dt_s, sigma, scenario.input_hold)
    if zero_irradiance:
        notes.append(f"irradiance {zero_irradiance} not in the scenario: taken as 0 W/m²")

    # the controller: is the set point within the power limit?
    status_heat = _controller_status(ps, scenario, steps, u, g_index, allow_unreachable, notes)

    x0, power0 = _initial(structure, scenario, steps, u, g_index)
    noise = None
    if sigma is not None:
        noise = rng.standard_normal((len(thetas), len(scenario.t_s), len(structure.states)))
        noise[0] = 0.0  # the central run is the model's own prediction, without noise
    X, P, U = _run(steps, scenario, u, g_index, x0, noise, power0)
    T = X[:, :, 0]
    t = scenario.t_s
    N = len(t) - 1

    def times(threshold: float | None, rising: bool) -> np.ndarray | None:
        if threshold is None:
            return None
        return _crossing(T, X, U, g_index, steps, t, threshold, rising)

    has_band = len(thetas) > 1

    def threshold_time(name: str, threshold: float | None, rising: bool, what: str) -> Outcome:
        crossed = times(threshold, rising)
        return _time_outcome(
            name,
            crossed[0] if crossed is not None else math.nan,
            crossed[1:] if crossed is not None and has_band else None,
            threshold,
            f"{what} {threshold} °C",
        )

    heat = threshold_time("heat_up_time_s", scenario.heat_up_to_C, True, "reach")
    if status_heat == "unreachable" and scenario.heat_up_to_C is not None:
        if not math.isfinite(heat.value or math.inf):
            heat = Outcome(heat.name, "s", math.inf, heat.lo, heat.hi, "unreachable", heat.note)
    cool = threshold_time("cool_down_time_s", scenario.cool_down_to_C, False, "fall to")
    energy = P[:, :N].sum(axis=1) * scenario.dt_s / 3.6e6
    peak = P[:, :N].max(axis=1)
    final = T[:, -1]

    def scalar(name: str, unit: str, v: np.ndarray) -> Outcome:
        lo, hi = _quantiles(v[1:]) if has_band else (None, None)
        return Outcome(name, unit, float(v[0]), lo, hi)

    outcomes = {
        "heat_up_time_s": heat,
        "cool_down_time_s": cool,
        "energy_kWh": scalar("energy_kWh", "kWh", energy),
        "peak_power_W": scalar("peak_power_W", "W", peak),
        "final_T_C": scalar("final_T_C", "°C", final),
    }
    notes += _air_range_notes(T[0])
    series = _series(scenario, structure, X, P, has_band)
    return SimulationResult(
        scenario=scenario,
        label=ps.label,
        source=ps.source,
        series=series,
        outcomes=outcomes,
        draws=len(thetas) - 1,
        band_sources=ps.band_sources if has_band else (),
        notes=notes,
        band_withheld=withheld,
        rejected=rejected,
        limits=limits,
    )


def _controller_status(ps, scenario, steps, u, g_index, allow_unreachable, notes) -> str:
    """The heating's status, "ok" or "unreachable": the latter when the controller's power
    limit is below the steady-state load at the scenario's most demanding row (with
    ``allow_unreachable``, a note; else :class:`UnreachableSetpoint`) (:func:`simulate`)."""
    status_heat = "ok"
    ctl = scenario.controller
    if ctl is not None:
        load, worst = _loads(steps, g_index, u, ctl.setpoint_C)
        r = int(worst[0])
        if load[0, r] > ctl.power_max_W:
            message = (
                f"below the steady-state load of {ps.label}: {load[0, r]:,.0f} W hold "
                f"{ctl.setpoint_C:g} °C at T_o = {u[r, 0]:g} °C (t = {scenario.t_s[r] / 3600:g} h; "
                f"kA = {models.steady_state_kA(ps.structure, ps.theta):,.0f} W/K): the set point "
                "is unreachable"
            )
            if not allow_unreachable:
                raise UnreachableSetpoint(
                    scenario.file, "heating.controller.power_max_W", ctl.power_max_W, message
                )
            status_heat = "unreachable"
            notes.append(f"heating.controller.power_max_W = {ctl.power_max_W:g} W is {message}")
    return status_heat


def _air_range_notes(T: np.ndarray) -> list[str]:
    """A note when the predicted air temperature ``T`` leaves what a vehicle's interior
    reaches (:data:`PLAUSIBLE_AIR_C`) (:func:`simulate`)."""
    hottest, coldest = float(np.max(T)), float(np.min(T))
    lo_C, hi_C = PLAUSIBLE_AIR_C
    if hottest > hi_C or coldest < lo_C:
        return [
            f"the predicted air temperature runs from {coldest:.4g} to {hottest:.4g} °C, beyond "
            f"what a vehicle's interior reaches ({lo_C:g} to {hi_C:g} °C): is the scenario's "
            "heating power in W (not kW or mW), and its outdoor temperature in °C?"
        ]
    return []


def _series(scenario, structure, X: np.ndarray, P: np.ndarray, has_band: bool) -> pd.DataFrame:
    """The central run's states, heating and inputs over time, with the 95 % bands of the
    draws (:func:`simulate`)."""
    t = scenario.t_s
    series = pd.DataFrame({"time_h": t / 3600.0, "T_o": scenario.T_o})
    for i, state in enumerate(structure.states):
        series[state] = X[0, :, i]
    series["heating_W"] = P[0]
    series["gains_W"] = scenario.gains_W
    series["air_exchange_W_K"] = scenario.air_exchange_W_K
    if has_band:
        for i, state in enumerate(structure.states):
            lo, hi = np.quantile(X[1:, :, i], [0.025, 0.975], axis=0)
            series[f"{state}_lo"], series[f"{state}_hi"] = lo, hi
        lo, hi = np.quantile(P[1:], [0.025, 0.975], axis=0)
        series["heating_W_lo"], series["heating_W_hi"] = lo, hi
    return series
