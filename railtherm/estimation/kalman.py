"""Stochastic grey-box estimator: the prediction error method with a Kalman gain (paper
eqs. 15-18 with K estimated through a noise model, not fixed to 0), by maximum likelihood.

Model (continuous-discrete, any :class:`railtherm.estimation.models.Structure`)::

    dx = (A(theta) x + B(theta) u) dt + Sigma dw,   Sigma = diag(sigma_i)   (one per state)
    y_k = C x_k + v_k,                              v_k ~ N(0, S), S = diag(s_j)

C selects the compared outputs (states). The input is held over each step (zero-order hold,
as :mod:`railtherm.estimation.pem`) or linear between samples (first-order hold: u_k below is then
[u_k; u_{k+1}], :func:`railtherm.estimation.models.forcing`), so the exact discrete model is
x_{k+1} = Ad x_k + Bd u_k + w_k with (Ad, Bd) of :func:`railtherm.estimation.models.discretize` and
w_k ~ N(0, Qd), Qd by Van Loan's method (:func:`railtherm.estimation.models.discretize_noise`).

The likelihood, its exact gradient and Fisher information come from the Kalman filter of
:mod:`railtherm.estimation.filtering`. The Fisher information is the Hessian of a
trust-region scoring step (``scipy.optimize.minimize``, trust-exact); L-BFGS-B finishes with
bounds when the optimum lies on one. Covariance: the inverse of the observed information
(forward differences of the analytic gradient) at the optimum; 95 % intervals in log
parameters as in :mod:`railtherm.estimation.pem`, whose flags are reused.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any, ClassVar

import numpy as np
from scipy.optimize import minimize

from railtherm.estimation import common, filtering, models, pem
from railtherm.estimation.common import Experiment
from railtherm.estimation.estimate import Estimate, Identification
from railtherm.estimation.filtering import (
    LOG_2PI,
    Likelihood,
    NotEvaluable,
    negative_log_likelihood,
)
from railtherm.estimation.models import Structure
from railtherm.estimation.priors import LinearT, LogPrior, PosteriorDensity, Prior, bounded

__all__ = [
    "KalmanResult",
    "LOG_2PI",
    "fit",
    "negative_log_likelihood",
    "noise_names",
]

SIGMA_BOUNDS = (1e-9, 1.0)  # K / sqrt(s): diffusion of a state (1 K/sqrt(s): 60 K per hour)
MEAS_VAR_BOUNDS = (1e-10, 1e4)  # K^2: measurement variance of an output
OFFSET_BOUNDS = (-5.0, 5.0)  # K: an output's constant offset
HESSIAN_STEP = 1e-5  # forward-difference step of the observed information (log units, K)
SIGMA_START = 0.1  # default start: sigma_i^2 dt = SIGMA_START^2 x the output-error variance
# a noise parameter this close (log) to its bound is held there for the covariance
_AT_BOUND_LOG = 1e-3
KKT_TOL = 1e-3  # NLL per log unit: an unknown held at a bound with a smaller pull inside stays
SNAP_LOG = math.log(1e4)  # a noise parameter within this (log) of its lower bound may snap to it


def noise_names(structure: Structure, outputs: Sequence[str]) -> tuple[str, ...]:
    """The names of the noise parameters: ``sigma_<state>`` (diffusion, K/sqrt(s)) for every
    state, then ``s_<output>`` (measurement variance, K^2) for every compared output. They
    may be given in ``fixed``, ``initial`` and ``bounds`` of :func:`fit` like the structure's
    parameters (a diffusion may be fixed at 0)."""
    return tuple(f"sigma_{s}" for s in structure.states) + tuple(f"s_{o}" for o in outputs)


# ----------------------------------------------------------------------------------------------
# the estimate


@dataclass(kw_only=True)
class KalmanResult(Estimate):
    """The maximum-likelihood estimate of the stochastic grey-box model, an
    :class:`~railtherm.estimation.estimate.Estimate` with ``estimator`` kalman.

    As every estimate for the structure's parameters: ``theta`` (all, fixed
    ones too), ``free`` (estimated, in the order of ``correlation``), ``fixed``, ``ci95``,
    ``sd_log``, ``correlation``, ``cond`` (square root of the condition number of the observed
    information of the log parameters, the analogue of cond(J)), ``flags``, ``identified``
    ({param: :func:`railtherm.estimation.pem.identification`}). ``cost`` is the minimised negative
    log-likelihood and ``loglik`` = -cost; ``n_obs`` the scalar measurements used,
    ``n_unknowns`` = ``n_params`` every estimated quantity (parameters, noise parameters,
    initial states: the count of AIC = 2 cost + 2 n_params and BIC).

    Noise: ``sigma`` {state: sigma, K/sqrt(s)}, ``meas_var`` {output: s, K^2}, with
    ``noise_ci95`` and ``noise_sd_log`` for the estimated ones (a noise parameter at its bound
    is held there: no interval, listed in ``noise_at_bound``).

    Per experiment (lists in the order given): ``names``, ``dt``, ``x0`` (the initial state:
    the prior mean of the filter), ``x0_estimated`` (its estimated states), ``simulated`` (the
    deterministic simulation x[n+1] = Ad x[n] + Bd u[n] from x0 with the estimated theta,
    N x n_states), ``residuals`` (measured - simulated, NaN where not compared), ``one_step``
    (the filter's predictions x_{k|k-1}, N x n_states), ``innovations`` (y - C x_{k|k-1},
    N x n_outputs, NaN where not measured), ``innovation_var`` (the diagonal of R_k, N x
    n_outputs, NaN where not measured). These three are the maximum-likelihood predictor's:
    with declared input noise, at the point the compensation starts from (:func:`fit`) - the
    compensated parameters remove the input noise's bias from the estimate but are not the
    best one-step predictor, so their innovations carry the input noise's coloured share and
    are no test of the stochastic model's whiteness.

    ``unknowns`` names every estimated quantity in the order of ``covariance_log`` (the
    inverse observed information: log parameters, log noise parameters, initial states in K).
    """

    CONDITION: ClassVar[str] = "information_condition"

    estimator: str = "kalman"
    covariance: str = "observed information"
    start_used: str = "output_error"
    sigma: dict[str, float] = field(default_factory=dict)
    meas_var: dict[str, float] = field(default_factory=dict)
    noise_ci95: dict[str, tuple[float, float]] = field(default_factory=dict)
    noise_sd_log: dict[str, float] = field(default_factory=dict)
    noise_at_bound: tuple[str, ...] = ()
    loglik: float = math.nan
    n_params: int = 0
    innovations: list[np.ndarray] = field(default_factory=list, repr=False)
    innovation_var: list[np.ndarray] = field(default_factory=list, repr=False)
    one_step: list[np.ndarray] = field(default_factory=list, repr=False)
    identified: dict[str, Identification] = field(default_factory=dict)
    unknowns: tuple[str, ...] = ()
    covariance_log: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)), repr=False)
    x0_mode: str = "estimated"
    start_theta: dict[str, float] = field(default_factory=dict)
    start_cost: float = math.nan
    offsets: dict[str, dict[str, float]] = field(default_factory=dict)

    @property
    def aic(self) -> float:
        """Akaike's criterion 2 NLL + 2 n_params."""
        return 2.0 * self.cost + 2.0 * self.n_params

    @property
    def bic(self) -> float:
        """Schwarz's criterion 2 NLL + n_params log n_obs."""
        return 2.0 * self.cost + self.n_params * math.log(max(self.n_obs, 1))

    def extra(self) -> dict[str, Any]:
        """The noise parameters (sigma_<state>, s_<output>) with their intervals, the
        measurement offsets, the likelihood and its criteria, the count of AIC and BIC and
        how the initial states were taken."""

        def f(v):
            return float(v)

        noise = {}
        for name, v in [(f"sigma_{s}", x) for s, x in self.sigma.items()] + [
            (f"s_{o}", x) for o, x in self.meas_var.items()
        ]:
            entry = {"value": f(v), "estimated": name in self.noise_ci95}
            if name in self.noise_ci95:
                entry["ci95"] = [f(c) for c in self.noise_ci95[name]]
                entry["sd_log"] = f(self.noise_sd_log[name])
            noise[name] = entry
        return {
            "noise": noise,
            "noise_at_bound": list(self.noise_at_bound),
            "offsets": {
                o: {k: f(x) for k, x in entry.items()} for o, entry in self.offsets.items()
            },
            "negative_log_likelihood": f(self.cost),
            "loglik": f(self.loglik),
            "aic": f(self.aic),
            "bic": f(self.bic),
            "n_params": int(self.n_params),
            "x0_mode": self.x0_mode,
        }


def _split(mapping: Mapping[str, Any] | None, structure: Structure, noise: tuple[str, ...]):
    """(structure's entries, noise entries) of a fixed / initial / bounds mapping."""
    mapping = dict(mapping or {})
    unknown = [k for k in mapping if k not in structure.parameters and k not in noise]
    if unknown:
        raise ValueError(
            f"unknown parameters {unknown}: {structure.name!r} has {structure.parameters} and "
            f"the noise parameters {noise}"
        )
    return (
        {k: v for k, v in mapping.items() if k in structure.parameters},
        {k: v for k, v in mapping.items() if k in noise},
    )


def _hessian(lik: Likelihood, v: np.ndarray, g0: np.ndarray, h: float = HESSIAN_STEP) -> np.ndarray:
    """The observed information: forward differences of the analytic gradient (g0 at v),
    symmetrised. With h = 1e-5 the standard deviations it gives agree with central differences
    to about 1e-5 (relative), at half their cost."""
    U = len(v)
    H = np.zeros((U, U))
    for i in range(U):
        step = np.zeros(U)
        step[i] = h
        H[:, i] = (_gradient(lik, v + step) - g0) / h
    return (H + H.T) / 2.0


def _gradient(lik: Likelihood, v: np.ndarray) -> np.ndarray:
    """The NLL's gradient at v; NaN where it cannot be evaluated (the information built from
    it then leaves the unknowns it touches unresolved, :func:`_finite_information`)."""
    nll, g, _ = lik.evaluate(v, 1)
    if g is None or not math.isfinite(nll):
        return np.full(len(v), np.nan)
    return np.asarray(g, dtype=float)


def _information(lik: Likelihood, v: np.ndarray) -> np.ndarray:
    """The Fisher information at v; where the filter's second-order pass cannot give it
    (evaluate returns None), the observed information from the gradient (:func:`_hessian`)."""
    nll, _, F = lik.evaluate(v, 2)
    if F is not None and math.isfinite(nll):
        return F
    return _hessian(lik, v, _gradient(lik, v))


def _finite_information(Hk: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``Hk`` with the rows and columns of unknowns whose information is not finite set to
    zero, and a mask of those unknowns (their variance is then unbounded: not identified)."""
    bad = ~np.all(np.isfinite(Hk), axis=0) | ~np.all(np.isfinite(Hk), axis=1)
    if not bad.any():
        return Hk, bad
    Hk = np.array(Hk, dtype=float)
    Hk[bad, :] = 0.0
    Hk[:, bad] = 0.0
    return Hk, bad


@common.single_threaded_blas
def fit(structure: Structure, experiments: Sequence[Experiment], **options: Any) -> KalmanResult:
    """Maximum-likelihood (or, with priors, maximum a posteriori) fit of the stochastic model
    of ``structure`` to ``experiments`` jointly: :func:`fit_with_density`'s estimate, whose
    options it takes."""
    return fit_with_density(structure, experiments, **options)[0]


@dataclass
class Density(PosteriorDensity):
    """The log density a posterior sampler explores (:mod:`railtherm.estimation.sampling`):
    over the fit's unknowns ``names`` (the first ``n_log`` held as logarithms: the free
    parameters and noise parameters; then offsets and initial states in K), within the
    bounds ``lo``, ``hi``; ``v`` the fit's estimate. :meth:`log_density` is -NLL plus each
    prior's log density of theta carried to the log parameter (the log Jacobian added);
    an unknown without a prior is flat in the way the fit holds it."""

    lik: Likelihood = field(kw_only=True)

    def log_density(self, v: np.ndarray) -> tuple[float, np.ndarray]:
        """(log density up to a constant, its gradient); -inf outside the bounds or where
        the model cannot be evaluated."""
        if self.outside(v):
            return -math.inf, np.zeros(len(v))
        nll, g, _ = self.lik.evaluate(v, 1)
        lp, gp, _ = self.prior.evaluate(v, jacobian=True)
        if not (math.isfinite(nll) and math.isfinite(lp)) or g is None:
            return -math.inf, np.zeros(len(v))
        return -nll + lp, gp - g

    def pointwise(self, v: np.ndarray) -> np.ndarray:
        """Each measured row's term of the filter's log-likelihood at v (its innovation e
        with covariance R over the outputs read at that row): -(ln det(2 pi R) +
        e^T R^-1 e) / 2, by the filter's row loop (no stationary shortcut); they add up to
        -NLL (less the output offsets' prior)."""
        runs = self.lik.passes(
            np.asarray(v, dtype=float), 0, steady=False, series=True, compiled=False
        )
        parts = [run.ll[np.isfinite(run.ll)] for run in runs]
        return np.concatenate(parts) if parts else np.zeros(0)


def fit_with_density(
    structure: Structure,
    experiments: Sequence[Experiment],
    *,
    fixed: Mapping[str, float] | None = None,
    initial: Mapping[str, float] | None = None,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    outputs: Sequence[str] | None = None,
    x0: str = "estimated",
    start: str = "auto",
    sigma_initial: float | Mapping[str, float] | None = None,
    input_noise: Mapping[str, float | Sequence[float]] | None = None,
    offsets: Mapping[str, float] | None = None,
    priors: Mapping[str, Prior] | None = None,
    prior_terms: Sequence[LinearT] = (),
) -> tuple[KalmanResult, Density]:
    """The fit and the posterior's :class:`Density` at it: the maximum-likelihood fit of the
    stochastic model of ``structure`` to ``experiments`` jointly (shared parameters, each
    experiment its own initial state).

    fixed / initial / bounds: as :func:`railtherm.estimation.pem.fit` for the structure's
    parameters, and may also name the noise parameters of :func:`noise_names` (``sigma_<state>`` in
    K/sqrt(s), ``s_<output>`` in K^2; ``fixed={"sigma_T": 0.0}`` removes the diffusion of T).
    outputs: the compared states (default: every state with a measurement). x0:
    ``"estimated"`` (every initial state estimated, prior covariance the stationary P of the
    filter) or ``"measured"`` (the first measurement with its variance s_j as prior; a state
    without one is estimated). start: passed to the output-error fit
    (:func:`railtherm.estimation.pem.fit`, ``"auto"`` or ``"initial"``) whose optimum starts theta
    and the initial states; the measurement variances start at the output-error residual variance,
    the diffusions at sigma_initial (K/sqrt(s), one value or {state: value}), by default
    sigma_i^2 dt = SIGMA_START^2 times the mean of those variances. input_noise: {input name:
    the standard deviation of its white measurement noise, one value or one per experiment},
    as :func:`railtherm.estimation.pem.fit` takes it: compensated in the estimate and added to the
    covariance (:func:`_input_noise_terms`). offsets: {compared output: sd (K)} - a constant
    offset of that output's readings (y = x + b + v, one output at most), estimated with the
    Gaussian prior b ~ N(0, sd^2): the calibration offset of a sensor group relative to the
    others, which the filter would otherwise explain by diffusions (``b_<output>``).
    priors: {parameter: :class:`railtherm.estimation.priors.Prior`} of the structure's free
    parameters, the noise parameters (``sigma_<state>``, ``s_<output>``, in their units
    K/sqrt(s) and K^2) or the estimated initial states (``x0_<state>``, K, normal or
    uniform; in every record): the maximum a posteriori estimate instead (NLL minus the
    log-prior, :class:`_Posterior`, searched from the start and from the prior's centre),
    its covariance the inverse Hessian of that criterion (the Laplace approximation of the
    posterior); without priors the maximum-likelihood estimate.
    prior_terms: joint prior terms on the log parameters (a class reference model's,
    :meth:`railtherm.study.classmodel.ReferenceModel.prior_terms`), MAP alike.
    """
    if x0 not in ("estimated", "measured"):
        raise ValueError(f"x0 must be 'estimated' or 'measured', got {x0!r}")
    if start not in ("auto", "initial"):
        raise ValueError(f"start must be 'auto' or 'initial', got {start!r}")
    experiments = list(experiments)
    if not experiments:
        raise ValueError("fit needs at least one experiment")
    outputs = common.compared_outputs(structure, experiments, outputs)
    noise = noise_names(structure, outputs)
    offsets = _checked_offsets(offsets, outputs)
    fixed_p, fixed_n = _split(fixed, structure, noise)
    initial_p, initial_n = _split(initial, structure, noise)
    bounds_p, bounds_n = _split(bounds, structure, noise)
    noise_n = (fixed_n, initial_n)
    if any(v < 0 or not math.isfinite(v) for v in fixed_n.values()):
        raise ValueError(f"fixed noise parameters must be finite and >= 0, got {fixed_n}")

    # the start: the output-error fit of the same structure, data and initial states
    oe = pem.fit(
        structure,
        experiments,
        fixed=fixed_p,
        initial=initial_p,
        bounds=bounds_p,
        outputs=outputs,
        x0=x0,
        covariance="iid",
        start=start,
        compiled=filtering.COMPILED,
    )
    free = oe.free
    bnds = dict(structure.bounds)
    bnds.update({p: (float(b[0]), float(b[1])) for p, b in bounds_p.items()})
    lik = _likelihood(structure, experiments, oe, outputs, x0, offsets, sigma_initial, noise_n)
    names, lo, hi = _unknowns(structure, outputs, experiments, lik, free, bnds, bounds_n)
    # on the log parameters and log noise; an initial state's prior (x0_<state>) on its
    # value in every record
    raw = [(i, name.split("[")[0]) for i, name in enumerate(names) if i >= lik.Qg]
    prior = LogPrior(names[: lik.Qn], priors or {}, prior_terms, raw)
    target: Likelihood | _Posterior = lik
    if prior:
        lo, hi = prior.bounds(lo, hi)
        bnds = bounded(bnds, priors)  # an estimate at its end sits at a bound
        target = _Posterior(lik, prior)
    span = hi - lo
    margin = np.where(np.isfinite(span), 1e-6 * span, 0.0)

    def clip(v: np.ndarray) -> np.ndarray:
        return np.clip(v, lo + margin, hi - margin)

    v0 = clip(_start_vector(lik, oe))
    start_cost = lik.evaluate(v0, 0)[0]
    if not math.isfinite(start_cost):
        raise NotEvaluable(structure, oe.theta, float(np.median([e.dt for e in experiments])))
    sol = _search(target, prior, v0, lo, hi, clip)
    v = sol.x
    H = _hessian(target, v, _gradient(target, v))
    levels = common.noise_levels(structure, input_noise or {}, experiments)
    meat, v_ml = None, v
    if any(levels):
        v, sol, H, meat = _compensated(target, v, sol, levels, lo, hi)
    result = _result(
        structure, target, sol, v, H, names, lo, hi, bnds, outputs, oe, start_cost, meat
    )  # fmt: skip
    _one_step_series(result, lik, v_ml)  # the one-step predictor is the estimate's
    result.input_noise_sd = [dict(level) for level in levels] if any(levels) else []
    if prior:
        _posterior_terms(result, lik, prior, v)
    density = Density(prior, tuple(names), lik.Qn, lo, hi, np.array(v, dtype=float), lik=lik)
    return result, density


def _likelihood(structure, experiments, oe, outputs, x0, offsets, sigma_initial, noise_n):
    """The filter's :class:`Likelihood` with the noise parameters started from the
    output-error fit ``oe`` (:func:`_noise_start`); ``noise_n``: the fixed and initial
    noise parameters given (:func:`fit_with_density`)."""
    fixed_n, initial_n = noise_n
    out_idx = tuple(structure.states.index(s) for s in outputs)
    dt = float(np.median([e.dt for e in experiments]))
    sigma, meas_var = _noise_start(
        structure, outputs, oe, out_idx, dt, sigma_initial, fixed_n, initial_n
    )
    return Likelihood(
        structure,
        experiments,
        oe.fixed,
        oe.free,
        sigma,
        tuple(i for i, s in enumerate(structure.states) if f"sigma_{s}" not in fixed_n),
        meas_var,
        tuple(j for j, o in enumerate(outputs) if f"s_{o}" not in fixed_n),
        out_idx,
        x0,
        {outputs.index(o): float(sd) for o, sd in offsets.items()},
    )


def _start_vector(lik: Likelihood, oe) -> np.ndarray:
    """The unknowns at the start: the output-error estimate, the noise start, zero
    offsets and the output-error fit's initial states."""
    return np.concatenate(
        [
            np.log([oe.theta[p] for p in lik.free]),
            np.log(lik.sigma0[list(lik.sigma_free)]),
            np.log(lik.meas_var0[list(lik.meas_var_free)]),
            np.zeros(len(lik.offset_out)),
        ]
        + [x[d.x0_free] for x, d in zip(oe.x0, lik.data, strict=True)]
    )


def _search(target, prior: LogPrior, v0: np.ndarray, lo, hi, clip) -> SimpleNamespace:
    """:func:`_optimise` from ``v0``; with a prior also from the prior's centre (the
    posterior's mode may lie far from the likelihood's), the better of the two."""
    sol = _optimise(target, v0, lo, hi, clip)
    if prior:
        other = _optimise(target, clip(prior.centre(v0)), lo, hi, clip)
        if other.fun < sol.fun:
            sol = other
    return sol


def _posterior_terms(result: KalmanResult, lik: Likelihood, prior: LogPrior, v) -> None:
    """A MAP result's likelihood (its criterion was the posterior's), priors and log-prior."""
    nll = float(lik.evaluate(v, 0)[0])
    result.cost, result.loglik = nll, -nll
    result.priors = prior.to_dict()
    result.log_prior = float(prior.evaluate(v)[0])


class _Posterior:
    """The negative log-posterior of theta as the optimiser sees a :class:`Likelihood`:
    ``evaluate`` gives NLL - log p(theta) (:class:`railtherm.estimation.priors.LogPrior`), its
    gradient, and the Fisher information plus the prior's curvature where that is positive
    (a scoring Hessian stays positive semi-definite); every other attribute is the
    likelihood's."""

    def __init__(self, lik: Likelihood, prior: LogPrior):
        self.lik, self.prior = lik, prior

    def __getattr__(self, name: str):
        return getattr(self.lik, name)

    def evaluate(self, v: np.ndarray, order: int, steady: bool = True):
        nll, g, F = self.lik.evaluate(v, order, steady)
        lp, gp, _ = self.prior.evaluate(v)
        if not math.isfinite(nll) or not math.isfinite(lp):
            return math.inf, g, F
        g = None if g is None else g - gp
        F = None if F is None else F + self.prior.information(v)
        return nll - lp, g, F


def _checked_offsets(offsets, outputs) -> dict[str, float]:
    """``offsets`` of :func:`fit`: at most one compared output, with a prior sd > 0."""
    offsets = dict(offsets or {})
    if len(offsets) > 1 or any(o not in outputs for o in offsets):
        raise ValueError(f"offsets: at most one of the compared outputs {outputs}, got {offsets}")
    if any(not (float(sd) > 0) for sd in offsets.values()):
        raise ValueError(f"offsets: the prior sd must be > 0, got {offsets}")
    return offsets


def _noise_start(structure, outputs, oe, out_idx, dt: float, sigma_initial, fixed_n, initial_n):
    """The noise parameters' start (:func:`fit`): measurement variances from the output-error
    residuals, diffusions SIGMA_START times their scale per step unless given; a fixed or
    initial value wins. Returns (sigma per state, measurement variance per output)."""
    n, n_out = len(structure.states), len(outputs)
    resid = np.concatenate([r[:, out_idx] for r in oe.residuals])
    s_start = np.array([float(np.nanmean(resid[:, j] ** 2)) for j in range(n_out)])
    s_start = np.where(np.isfinite(s_start) & (s_start > 0), s_start, 1e-2)
    if sigma_initial is None:
        sig_start = np.full(n, SIGMA_START * math.sqrt(float(s_start.mean()) / dt))
    elif isinstance(sigma_initial, Mapping):
        default = SIGMA_START * math.sqrt(float(s_start.mean()) / dt)
        sig_start = np.array([float(sigma_initial.get(s, default)) for s in structure.states])
    else:
        sig_start = np.full(n, float(sigma_initial))
    sigma = np.array(
        [
            float(fixed_n.get(f"sigma_{s}", initial_n.get(f"sigma_{s}", sig_start[i])))
            for i, s in enumerate(structure.states)
        ]
    )
    meas_var = np.array(
        [
            float(fixed_n.get(f"s_{o}", initial_n.get(f"s_{o}", s_start[j])))
            for j, o in enumerate(outputs)
        ]
    )
    return sigma, meas_var


def _unknowns(structure, outputs, experiments, lik, free, bnds, bounds_n):
    """The unknowns' names (log parameters, log noise, offsets, initial states in K) and
    their bounds (:func:`fit`)."""
    names = (
        list(free)
        + [f"sigma_{structure.states[i]}" for i in lik.sigma_free]
        + [f"s_{outputs[j]}" for j in lik.meas_var_free]
        + [f"b_{outputs[j]}" for j in lik.offset_out]
    )
    for d, e in zip(lik.data, experiments, strict=True):
        names += [f"x0_{structure.states[i]}[{e.name}]" for i in d.x0_free]
    # bounds of the unknowns (log parameters, log noise, initial states in K)
    noise_bounds = {f"sigma_{s}": SIGMA_BOUNDS for s in structure.states}
    noise_bounds |= {f"s_{o}": MEAS_VAR_BOUNDS for o in outputs}
    noise_bounds |= {k: (float(b[0]), float(b[1])) for k, b in bounds_n.items()}
    lo, hi = [], []
    for name in names[: lik.Qn]:
        b = bnds[name] if name in bnds else noise_bounds[name]
        lo.append(math.log(b[0]) if b[0] > 0 else -np.inf)
        hi.append(math.log(b[1]) if np.isfinite(b[1]) else np.inf)
    lo += [OFFSET_BOUNDS[0]] * len(lik.offset_out)
    hi += [OFFSET_BOUNDS[1]] * len(lik.offset_out)
    for d in lik.data:
        lo += [d.x0_range[0]] * len(d.x0_free)
        hi += [d.x0_range[1]] * len(d.x0_free)
    return names, np.array(lo), np.array(hi)


def _compensated(lik, v, sol, levels, lo, hi):
    """The input-noise compensation of an optimum (:func:`fit`): the moved point, the
    solution there, its Fisher information and the sandwich's meat."""
    v = _input_noise_terms(lik, v, levels, lo, hi)
    sol = SimpleNamespace(
        **{
            **vars(sol),
            "x": v,
            "fun": float(lik.evaluate(v, 0)[0]),
            "active_mask": _active_mask(v, lo, hi),
        }
    )
    # the Fisher information: the compensated point is no stationary point of the NLL, so
    # its observed information holds the residuals' second-order terms
    H = _information(lik, v)
    meat = _input_noise_meat(lik, v, _kept(lik, sol, v, lo, hi), levels)
    return v, sol, H, meat


def _optimise(lik: Likelihood, v0: np.ndarray, lo, hi, clip) -> SimpleNamespace:
    """Fisher scoring in a trust region (scipy trust-exact, the Fisher information as its
    Hessian) with an active set for the bounds: an unknown that leaves its bounds is held at
    the bound and the rest re-solved; a held one is released when the gradient points inside
    (the KKT condition fails by more than KKT_TOL). A diffusion the data do not show runs to
    its lower bound this way in a few steps, where a bounded quasi-Newton method crawls along
    the flat likelihood. When the scoring fails, L-BFGS-B with the bounds from the best point.
    """
    counts = {"nfev": 0}
    U = len(v0)
    scale = max(1.0, abs(lik.evaluate(v0, 0)[0]))
    v = v0.copy()
    held: dict[int, float] = {}
    message, success = "", False
    for _ in range(2 * U + 2):
        idx = np.array([i for i in range(U) if i not in held], dtype=int)
        if len(idx):
            v, message = _scoring(lik, v, idx, lo, hi, scale, counts)
        outside = [i for i in idx if v[i] < lo[i] or v[i] > hi[i]]
        if outside:
            for i in outside:
                held[i] = lo[i] if v[i] < lo[i] else hi[i]
                v[i] = held[i]
            continue
        nll, g, F = lik.evaluate(v, 2)
        if g is None or F is None or not math.isfinite(nll):
            # the information cannot be evaluated at the point reached (a derivative's
            # Lyapunov or discretisation solve fails where the likelihood itself does not):
            # no scoring step to judge convergence by; the quasi-Newton solve below goes on
            message = f"the Fisher information cannot be evaluated at the point reached ({message})"
            break
        release = [i for i, b in held.items() if _pull(lik, i, b, v, v0, g, lo, hi) > KKT_TOL]
        if release:
            for i in release:
                del held[i]
                v[i] = float(
                    np.clip(v0[i] if lik.P <= i < lik.Qn else v[i], lo[i] + 1e-3, hi[i] - 1e-3)
                )
            continue
        # a noise parameter left in the flat region near zero (its effect below the solver's
        # resolution) is taken at its bound when that changes the NLL by nothing
        v, nll, snapped = _snap(lik, v, nll, idx, held, v0, lo, hi, scale)
        if snapped:
            continue
        # converged when the scoring step left is negligible: the Newton decrement
        # g^T F^-1 g (on the unknowns not held) below 1e-8 per unknown
        gi, Fi = g[idx], F[np.ix_(idx, idx)]
        try:
            decrement = float(gi @ np.linalg.lstsq(Fi, gi, rcond=1e-12)[0]) if len(idx) else 0.0
        except np.linalg.LinAlgError:
            decrement = math.inf
        success = decrement <= 1e-8 * max(len(idx), 1)
        # scipy's own exit message may read as a failure ("A bad approximation caused
        # failure to predict improvement") at a point whose scoring step is negligible: the
        # message says what decided
        message = (
            f"{'converged' if success else 'not converged'}: Newton decrement "
            f"{decrement:.3g} (tolerance {1e-8 * max(len(idx), 1):.3g}; trust-exact: {message})"
            + (f"; {len(held)} unknowns at a bound" if held else "")
        )
        break
    if not success:  # the bounded quasi-Newton solve from the best point reached
        v, success, message = _quasi_newton(lik, v, held, lo, hi, clip, scale, counts)
    return SimpleNamespace(
        x=v,
        fun=float(lik.evaluate(v, 0)[0]),
        success=success,
        status=1 if success else 0,
        message=message,
        active_mask=_active_mask(v, lo, hi),
        nfev=counts["nfev"],
        njev=counts["nfev"],
    )


def _scoring(lik, v, idx, lo, hi, scale: float, counts: dict):
    """One trust-exact Fisher-scoring solve over the unknowns ``idx`` (the others held),
    stopped when a step leaves the bounds (:func:`_optimise`): the better of the point
    reached and ``v``, and scipy's message."""
    base = v.copy()

    def full(w, base=base, idx=idx):
        x = base.copy()
        x[idx] = w
        return x

    def fun(w, full=full, idx=idx):
        counts["nfev"] += 1
        nll, g, _ = lik.evaluate(full(w), 2)
        return nll, g[idx]

    def hess(w, full=full, idx=idx):
        F = lik.evaluate(full(w), 2)[2]
        if F is None:  # a point the model cannot be evaluated at: a stiff stand-in
            return np.eye(len(idx)) * scale
        return F[np.ix_(idx, idx)]

    def leave(w, idx=idx):
        if np.any(w < lo[idx]) or np.any(w > hi[idx]):
            raise StopIteration

    res = minimize(
        fun,
        v[idx],
        jac=True,
        hess=hess,
        method="trust-exact",
        callback=leave,
        options={"gtol": 1e-7 * scale, "maxiter": 200},
    )
    w = full(res.x)
    if lik.evaluate(w, 0)[0] <= lik.evaluate(v, 0)[0]:
        v = w
    message = str(res.message)
    return v, message


def _snap(lik, v, nll, idx, held, v0, lo, hi, scale: float):
    """A noise parameter left in the flat region near zero (its effect below the solver's
    resolution) taken at its bound when that changes the NLL by nothing (:func:`_optimise`;
    ``held`` gains it). Returns the point, its NLL and whether one snapped."""
    snapped = False
    for i in idx:
        if lik.P <= i < lik.Qn and v[i] - lo[i] < SNAP_LOG:
            w = v.copy()
            w[i] = lo[i]
            nll_w, g_w, _ = lik.evaluate(w, 1)
            if nll_w <= nll + 1e-8 * scale and _pull(lik, i, lo[i], w, v0, g_w, lo, hi) <= KKT_TOL:
                v, nll, held[i], snapped = w, nll_w, lo[i], True
    return v, nll, snapped


def _quasi_newton(lik, v, held, lo, hi, clip, scale: float, counts: dict):
    """L-BFGS-B with the bounds from the best point reached (:func:`_optimise`): the point,
    whether it converged and the message."""

    def fun1(w):
        counts["nfev"] += 1
        nll, g, _ = lik.evaluate(w, 1)
        return nll, g

    res = minimize(
        fun1,
        clip(v) if not held else np.clip(v, lo, hi),
        jac=True,
        method="L-BFGS-B",
        bounds=list(zip(lo, hi, strict=True)),
        options={"maxiter": 2000, "ftol": 1e-14, "gtol": 1e-9 * scale},
    )
    if res.fun <= lik.evaluate(v, 0)[0]:
        v = res.x
    success = bool(res.success)
    message = f"trust-exact did not converge, then L-BFGS-B: {res.message}"
    return v, success, message


def _active_mask(v: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """-1 / +1 for the unknowns at their lower / upper bound, 0 elsewhere."""
    active = np.zeros(len(v), int)
    active[v <= lo + 1e-9] = -1
    active[v >= hi - 1e-9] = 1
    return active


def _pull(lik: Likelihood, i: int, b: float, v, v0, g, lo, hi) -> float:
    """How much the NLL falls per unit step from the bound b of unknown i into the inside
    (the KKT condition holds when it is not positive). For a noise parameter at its lower
    bound the log scale is blind (dNLL/dlog s = s dNLL/ds vanishes as s -> 0 whether or not
    the likelihood wants s > 0): the step is measured in the natural variable instead, s_j
    or sigma_i^2, in units of its start value."""
    inward = 1.0 if b == lo[i] else -1.0
    if lik.P <= i < lik.Qn and b == lo[i]:
        power = 2.0 if i < lik.P + len(lik.sigma_free) else 1.0
        return -g[i] * math.exp(power * (v0[i] - v[i])) / power
    return -inward * g[i]


def _kept(lik: Likelihood, sol, v: np.ndarray, lo, hi) -> np.ndarray:
    """The unknowns the covariance is computed for: every one but the noise parameters at a
    bound, which are held there (the likelihood is flat beyond: a diffusion the data do not
    show), so they carry no curvature to invert."""
    held = {
        i
        for i in range(lik.P, lik.Qn)
        if v[i] - lo[i] < _AT_BOUND_LOG or hi[i] - v[i] < _AT_BOUND_LOG or sol.active_mask[i]
    }
    return np.array([i for i in range(len(v)) if i not in held], dtype=int)


def _pinv_sym(Hk: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pseudo-inverse of a symmetric information matrix (directions below common.NULL_REL of
    the largest eigenvalue dropped) and a mask of the unknowns loading on a dropped one."""
    lam, V = np.linalg.eigh(Hk)
    top = float(np.max(np.abs(lam))) if lam.size else 0.0
    null = lam <= common.NULL_REL * top if top > 0 else np.ones_like(lam, dtype=bool)
    inv = np.where(null, 0.0, 1.0 / np.where(null, 1.0, lam))
    unresolved = np.abs(V[:, null]).max(axis=1) > 1e-8 if null.any() else np.zeros(len(lam), bool)
    return (V * inv) @ V.T, unresolved


def _lag_sums(z: np.ndarray, N: int) -> np.ndarray:
    """S(z) = sum_{l=0}^{N-2} (N - 1 - l) z^l elementwise (complex z, |z| <= 1): the number of
    row pairs at lag l of a record of N rows, weighting z^l."""
    z = np.asarray(z, dtype=complex)
    one = np.abs(1.0 - z) < 1e-9
    zz = np.where(one, 0.5, z)
    with np.errstate(over="ignore", invalid="ignore"):
        out = ((N - 1) - zz * (1.0 - zz ** (N - 1)) / (1.0 - zz)) / (1.0 - zz)
    return np.where(one, N * (N - 1) / 2.0, out)


def _record_noise_terms(lik: Likelihood, v: np.ndarray, i: int, level: Mapping[str, float]):
    """Experiment i's stationary predictor (F, C_o, R^-1, Bd) and the compensation
    1/2 sum_j sd_j^2 sum_l (N - 1 - l) g_l^T R^-1 g_l, g_l = C_o F^l Bd[:, j]
    (:func:`_input_noise_terms`), in closed form over F's modes. None where the record has no
    stationary filter for all its outputs."""
    d = lik.data[i]
    sysm = lik.system(v, d.e.dt, 0)
    n_out = len(lik.out_idx)
    st = sysm.steady((1 << n_out) - 1, np.arange(n_out))
    if st is None:
        return None
    N = len(d.y)
    lam, V = np.linalg.eig(st.F)
    CV = st.C @ V
    G = CV.T @ st.Rinv @ CV  # (modes, modes): alpha_a^T R^-1 alpha_b per unit amplitudes
    S = _lag_sums(np.outer(lam, lam), N)
    comp = 0.0
    for name, sd in level.items():
        beta = np.linalg.solve(V, sysm.Bd[:, lik.s.inputs.index(name)])
        comp += 0.5 * sd**2 * float(np.real(np.sum(G * np.outer(beta, beta) * S)))
    return SimpleNamespace(F=st.F, C=st.C, Rinv=st.Rinv, Bd=sysm.Bd, comp=comp)


def _compensation(lik: Likelihood, v: np.ndarray, levels) -> float:
    total = 0.0
    for i, level in enumerate(levels):
        if level:
            terms = _record_noise_terms(lik, v, i, level)
            if terms is None:
                raise ValueError("no stationary filter")
            total += terms.comp
    return total


def _input_noise_terms(lik: Likelihood, v, levels, lo, hi):
    """The declared white noise of measured inputs in a Kalman fit: its bias removed from the
    estimate, and its share of the covariance.

    The filter conditions on the measured inputs u = u0 + e. Noise e_t on input j moves the
    one-step predictions of the later rows by g_l e_t (g_l = C F^l Bd[:, j], F the stationary
    predictor's transition), so the innovations are the clean ones minus sum_l g_l e_{t-1-l}.
    That is not process noise - it is correlated with the input the filter is given (errors
    in variables) - but the likelihood takes it for some: its expectation adds to the NLL

        c(v) = 1/2 sum_j sd_j^2 sum_l (N - 1 - l) g_l^T R^-1 g_l

    (per record, summed), which prefers diffusions that let the filter follow the record and
    a small gain from the noisy input (for the air node, a larger C). The estimate is the
    minimiser of the compensated criterion NLL - c from the maximum-likelihood point, with the
    measurement variances held at their maximum-likelihood values: first over the
    structure's parameters, the diffusions and the initial states where a diffusion lies
    above its bound (L-BFGS-B within the bounds), then by Gauss-Newton steps with the Fisher
    information in the parameters and initial states (grad c by forward differences, c in
    closed form over F's modes). Where the declared noise accounts for the apparent process
    noise, the diffusions go to their lower bound and the estimate to the compensated
    output-error one. Returns the compensated v (or v unchanged where c cannot be evaluated)."""
    U = len(v)
    P, a = lik.P, lik.P + len(lik.sigma_free)
    diffusions = range(P, a)
    h = 1e-6

    def criterion(w: np.ndarray, order: int, along: Sequence[int]):
        """NLL - c, its gradient along ``along`` (forward differences of c) and, with
        order 2, the Fisher information; (inf, ...) where either cannot be evaluated."""
        nll, g, F = lik.evaluate(w, order)
        if not math.isfinite(nll):
            return math.inf, None, None
        try:
            c = _compensation(lik, w, levels)
            gc = np.zeros(U)
            for q in along:
                if q < a:
                    e = np.zeros(U)
                    e[q] = h
                    gc[q] = (_compensation(lik, w + e, levels) - c) / h
        except (ValueError, np.linalg.LinAlgError, ArithmeticError):
            return math.inf, None, None
        return nll - c, (None if g is None else g - gc), F

    start = criterion(v, 0, ())[0]
    if not math.isfinite(start):
        return v
    # 1. a diffusion above its bound may have taken up the input noise: the compensated
    # criterion over the parameters, the diffusions and the initial states (the measurement
    # variances held at their maximum-likelihood values: c grows as 1 / s, so NLL - c has no
    # minimum in them)
    if any(v[i] > lo[i] + _AT_BOUND_LOG for i in diffusions):
        free = [i for i in range(U) if not a <= i < lik.Qn]
        res = minimize(
            lambda w: criterion(w, 1, free)[:2],
            v,
            jac=True,
            method="L-BFGS-B",
            bounds=[(v[i], v[i]) if a <= i < lik.Qn else (lo[i], hi[i]) for i in range(U)],
            options={"maxiter": 300},
        )
        if math.isfinite(res.fun) and res.fun <= start:
            v, start = res.x.copy(), float(res.fun)
        # a diffusion left in the flat region near zero is taken at its bound when that
        # costs nothing (as the maximum-likelihood search does)
        for i in diffusions:
            if v[i] > lo[i]:
                w = v.copy()
                w[i] = lo[i]
                value = criterion(w, 0, ())[0]
                if value <= start + 1e-8 * max(1.0, abs(start)):
                    v, start = w, value
    # 2. Gauss-Newton steps with the Fisher information in the parameters and initial states,
    # the noise parameters held, each step halved until the criterion falls
    moved = [i for i in range(U) if i < P or i >= lik.Qn]
    for _ in range(20):
        value, g, F = criterion(v, 2, moved)
        if g is None or F is None:  # the information cannot be evaluated here: no step
            break
        Fm, gm = F[np.ix_(moved, moved)], g[moved]
        step = np.zeros(U)
        step[moved] = -np.linalg.lstsq(Fm, gm, rcond=1e-12)[0]
        if float(-gm @ step[moved]) <= 1e-10 * max(len(moved), 1):
            break
        for _ in range(30):
            w = np.clip(v + step, lo, hi)
            if criterion(w, 0, ())[0] < value:
                v = w
                break
            step = step / 2.0
        else:
            break
    return v


def _input_noise_meat(lik: Likelihood, v: np.ndarray, keep: np.ndarray, levels) -> np.ndarray:
    """The covariance's share of the input noise (:func:`_input_noise_terms`): H^-1 M H^-1
    with M = sum_j sd_j^2 sum_t w_t w_t^T, w_t = -sum_l D_{t+1+l}^T R^-1 g_l the score's
    response to the noise at row t (D_k = d eps_k / d v by forward differences), in the
    order of v. With g_l = C F^l b, w_t = -b^T lambda_{t+1} by the backward recursion
    lambda_k = F^T lambda_{k+1} + C^T R^-1 D_k (one pass per record for every input)."""
    U = len(v)
    h = 1e-6
    base = lik.passes(v, 0, series=True)
    D = [np.zeros((len(r.eps), U, r.eps.shape[1])) for r in base]
    for q in keep:
        e = np.zeros(U)
        e[q] = h
        for k, r in enumerate(lik.passes(v + e, 0, series=True)):
            D[k][:, q, :] = np.nan_to_num((r.eps - base[k].eps) / h)
    M = np.zeros((U, U))
    for i, level in enumerate(levels):
        terms = _record_noise_terms(lik, v, i, level) if level else None
        if terms is None:
            continue
        forcing = (D[i] @ terms.Rinv) @ terms.C  # (N, U, n): (C^T R^-1 D_k)^T
        N = len(forcing)
        lam = np.zeros((N + 1, U, terms.F.shape[0]))  # lambda_k^T, lambda_N = 0
        for k in range(N - 1, 0, -1):
            lam[k] = lam[k + 1] @ terms.F + forcing[k]
        for name, sd in level.items():
            wt = -lam[1:N] @ terms.Bd[:, lik.s.inputs.index(name)]  # (N - 1, U)
            M += sd**2 * (wt.T @ wt)
    return M


def _result(structure, lik, sol, v, H, names, lo, hi, bnds, outputs, oe, start_cost, meat=None):
    P, Qg = lik.P, lik.Qg
    U = len(v)
    keep = _kept(lik, sol, v, lo, hi)
    held = [i for i in range(U) if i not in set(keep.tolist())]
    cov, var = _covariance(H, keep, U, meat)
    sd = np.sqrt(np.maximum(var, 0.0))
    th = lik.theta(v)
    free = lik.free
    with np.errstate(invalid="ignore", divide="ignore"):
        dd = np.sqrt(np.maximum(np.diag(cov)[:P], 0.0))
        corr = cov[:P, :P] / np.outer(dd, dd)
    corr = np.where(np.isfinite(corr), corr, np.nan)
    for i in range(P):
        if np.isfinite(sd[i]) and sd[i] > 0:
            corr[i, i] = 1.0
        else:
            corr[i, :] = corr[:, i] = np.nan
    ci, sd_log = {}, {}
    for i, p in enumerate(free):
        lv = math.log(th[p])
        with np.errstate(over="ignore"):
            ci[p] = (float(np.exp(lv - common.Z95 * sd[i])), float(np.exp(lv + common.Z95 * sd[i])))
        sd_log[p] = float(sd[i])
    HP = H[:P, :P]
    if P and np.all(np.isfinite(HP)):
        ev = np.linalg.eigvalsh(HP)
        cond = float(math.sqrt(ev[-1] / ev[0])) if ev[0] > 0 else math.inf
    elif P:  # an information that cannot be evaluated conditions nothing
        cond = math.inf
    else:
        cond = 1.0
    noise_ci, noise_sd = _noise_intervals(v, sd, names, range(P, lik.Qn), held)
    flags = common.fit_flags(sol, v, th, free, ci, corr, cond, bnds)
    prob = SimpleNamespace(
        P=Qg,
        exps=[d.e for d in lik.data],
        x0_free=[d.x0_free for d in lik.data],
        x0_range=[d.x0_range for d in lik.data],
        s=structure,
    )
    flags += common.x0_flags(prob, sol, v)
    identified = _identified(flags, free, th, ci, v, lo, hi, bnds)
    # the series at the optimum
    x0s = lik.x0s(v)
    simulated, residuals = _simulated(structure, lik, th, v, x0s)
    sigma, svar = lik.sigma(v), lik.meas_var(v)
    nll = float(sol.fun)
    offsets = {
        outputs[j]: {
            "value": float(v[lik.Qn + t]),
            "sd": float(sd[lik.Qn + t]),
            "prior_sd": float(lik.offset_sd[t]),
        }
        for t, j in enumerate(lik.offset_out)
    }
    return KalmanResult(
        structure=structure.name,
        theta={p: float(th[p]) for p in structure.parameters},
        free=free,
        fixed=dict(lik.fixed),
        ci95=ci,
        sd_log=sd_log,
        correlation=corr,
        cond=cond,
        flags=flags,
        cost=nll,
        n_obs=lik.n_obs,
        n_unknowns=U,
        success=bool(sol.success),
        message=str(sol.message),
        outputs=tuple(outputs),
        names=[d.e.name for d in lik.data],
        x0=x0s,
        simulated=simulated,
        residuals=residuals,
        sigma={s: float(sigma[i]) for i, s in enumerate(structure.states)},
        meas_var={o: float(svar[j]) for j, o in enumerate(outputs)},
        noise_ci95=noise_ci,
        noise_sd_log=noise_sd,
        noise_at_bound=tuple(names[i] for i in held),
        offsets=offsets,
        loglik=-nll,
        n_params=U,
        x0_estimated=[tuple(structure.states[i] for i in d.x0_free) for d in lik.data],
        dt=[float(d.e.dt) for d in lik.data],
        states=tuple(structure.states),
        identified=identified,
        unknowns=tuple(names),
        covariance_log=cov,
        x0_mode=lik.x0_mode,
        start_theta={p: float(oe.theta[p]) for p in structure.parameters},
        start_cost=float(start_cost),
        start_costs={"output_error": float(start_cost)},
        nfev=int(sol.nfev),
        njev=int(sol.njev),
    )


def _covariance(H: np.ndarray, keep: np.ndarray, U: int, meat: np.ndarray | None):
    """The covariance of the unknowns kept off their bounds (:func:`_result`): the inverse
    of the information (its unresolved directions with infinite variance), in a sandwich
    with the input-noise ``meat`` when there is one; NaN and infinite variance elsewhere."""
    cov = np.full((U, U), np.nan)
    var = np.full(U, np.inf)
    if len(keep):
        Hk, bad = _finite_information(H[np.ix_(keep, keep)])
        ck, unresolved = _pinv_sym(Hk)
        if meat is not None:
            # an unknown whose input-noise term cannot be evaluated is not resolved either
            Mk = meat[np.ix_(keep, keep)]
            bad = bad | ~np.isfinite(Mk).all(axis=0)
            ck = ck + ck @ np.nan_to_num(Mk) @ ck
        unresolved = unresolved | bad
        vk = np.diag(ck).copy()
        vk[unresolved] = np.inf
        cov[np.ix_(keep, keep)] = ck
        var[keep] = vk
    return cov, var


def _noise_intervals(v, sd, names, indices, held):
    """95 % intervals and log sd of the noise parameters not held at a bound (:func:`_result`)."""
    noise_ci, noise_sd = {}, {}
    for i in indices:
        if i in held:
            continue
        with np.errstate(over="ignore"):
            noise_ci[names[i]] = (
                float(np.exp(v[i] - common.Z95 * sd[i])),
                float(np.exp(v[i] + common.Z95 * sd[i])),
            )
        noise_sd[names[i]] = float(sd[i])
    return noise_ci, noise_sd


def _identified(flags, free, th, ci, v, lo, hi, bnds):
    """Each free parameter's identification, with the bound it sits at (:func:`_result`)."""
    bound_of = {fl.parameters[0]: fl for fl in flags if fl.code == "at_bound"}
    identified = {}
    for i, p in enumerate(free):
        at = None
        if p in bound_of:
            side = "lower" if abs(v[i] - lo[i]) <= abs(hi[i] - v[i]) else "upper"
            at = (side, bnds[p][0] if side == "lower" else bnds[p][1])
        identified[p] = common.identification(th[p], ci[p], at)
    return identified


def _one_step_series(result: KalmanResult, lik: Likelihood, v: np.ndarray) -> KalmanResult:
    """``result``'s one-step predictions, innovations and their variances (the filter's
    series, :class:`KalmanResult`) at the point v: the optimum, or with declared input noise
    the maximum-likelihood point the compensation starts from (:func:`fit`)."""
    runs = lik.passes(v, 0, series=True)
    result.innovations = [r.eps for r in runs]
    result.innovation_var = [r.rvar for r in runs]
    result.one_step = [r.xp for r in runs]
    return result


def _simulated(structure, lik, th, v, x0s):
    """Each record simulated at the optimum and its residuals, offsets removed
    (:func:`_result`)."""
    simulated, residuals = [], []
    b = lik.offsets_of(v)
    for d, x0 in zip(lik.data, x0s, strict=True):
        sim = models.simulate(structure, th, d.e.u, d.e.dt, x0, lik.hold)
        res = np.full_like(sim, np.nan)
        for j, i in enumerate(lik.out_idx):
            res[:, i] = d.e.y[:, i] - b[j] - sim[:, i]
        simulated.append(sim)
        residuals.append(res)
    return simulated, residuals
