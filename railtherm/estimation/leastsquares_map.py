"""The maximum a posteriori estimate of a least-squares estimator (the simulation error of
:mod:`railtherm.estimation.pem`, eq. 17) and its Laplace covariance (docs/bayes.md).

The residuals e(v) are read as Gaussian with an unknown variance; integrated out under the
scale-free prior p(sigma) ~ 1/sigma (or profiled out: the same mode), they leave the
likelihood (w / 2) log(e^T e) to minimise, w the number of independent samples the
residuals count as (m for white residuals; :func:`railtherm.estimation.pem.fit` gives fewer
for coloured ones). The MAP estimate minimises

    (w / 2) log(e^T e) - log p(theta)

with the log-prior of :class:`railtherm.estimation.priors.LogPrior`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from railtherm.estimation.priors import LogPrior, PosteriorDensity

__all__ = ["INFO_NULL", "Density", "laplace_covariance", "search"]

INFO_NULL = 1e-14  # eigenvalues of the posterior's information below this (relative) are null


@dataclass
class Density(PosteriorDensity):
    """The log posterior density a sampler explores (:mod:`railtherm.estimation.sampling`)
    over the least-squares fit's unknowns ``names`` (the first ``n_log`` held as logarithms:
    the free parameters; then the estimated initial states, K), within ``lo``, ``hi``; ``v``
    the fit's estimate. :meth:`log_density` is -(weight / 2) log(e^T e) (the Gaussian
    likelihood with its variance integrated out under p(sigma) ~ 1/sigma) plus each prior's
    log density of the log parameter; an unknown without a prior is flat as held."""

    residuals: Callable[[np.ndarray], np.ndarray] = field(kw_only=True)
    jacobian: Callable[[np.ndarray], np.ndarray] = field(kw_only=True)
    weight: float = field(kw_only=True)

    def log_density(self, v: np.ndarray) -> tuple[float, np.ndarray]:
        """(log density up to a constant, its gradient); -inf outside the bounds."""
        if self.outside(v):
            return -math.inf, np.zeros(len(v))
        r = self.residuals(v)
        ssr = float(r @ r)
        lp, gp, _ = self.prior.evaluate(v, jacobian=True)
        if not (math.isfinite(ssr) and ssr > 0 and math.isfinite(lp)):
            return -math.inf, np.zeros(len(v))
        grad = gp - self.weight * (self.jacobian(v).T @ r) / ssr
        return -0.5 * self.weight * math.log(ssr) + lp, grad

    def pointwise(self, v: np.ndarray) -> np.ndarray:
        """Each residual's Gaussian log density at v with the variance it implies,
        s^2 = e^T e / m, counted as weight / m of a sample (coloured residuals are worth
        fewer than m): (weight / m) (-(ln(2 pi s^2) + e_i^2 / s^2) / 2); they add up to
        the profiled likelihood -(weight / 2) (ln(2 pi e^T e / m) + 1)."""
        r = np.asarray(self.residuals(np.asarray(v, dtype=float)), dtype=float)
        m = len(r)
        s2 = float(r @ r) / m
        return (self.weight / m) * -0.5 * (np.log(2.0 * math.pi * s2) + r**2 / s2)


def search(
    residuals: Callable[[np.ndarray], np.ndarray],
    jacobian: Callable[[np.ndarray], np.ndarray],
    sol,
    prior: LogPrior,
    weight: float,
    lo: np.ndarray,
    hi: np.ndarray,
) -> SimpleNamespace:
    """The MAP estimate from the least-squares solution ``sol`` (its ``x``, ``nfev``,
    ``njev``): L-BFGS-B within [lo, hi] on (weight / 2) log(e^T e) - log p(theta), with the
    gradient weight J^T e / e^T e - d log p / dv, from the least-squares optimum and from
    the prior's centre (:meth:`LogPrior.centre`), the better of the two. A solution in the
    form of the least-squares solver's (``x``, ``fun`` the residuals, ``success``,
    ``active_mask``, ``nfev``, ``njev``, ``message``)."""
    from scipy.optimize import minimize  # on first use: a job's start-up

    v_ls = np.clip(sol.x, lo, hi)
    counts = {"nfev": 0}

    def criterion(w):
        counts["nfev"] += 1
        r = residuals(w)
        ssr = float(r @ r)
        lp, gp, _ = prior.evaluate(w)
        if not (math.isfinite(ssr) and math.isfinite(lp)) or ssr <= 0:
            return math.inf, np.zeros(len(w))
        return 0.5 * weight * math.log(ssr) - lp, weight * (jacobian(w).T @ r) / ssr - gp

    # the posterior's mode may lie far from the likelihood's (the records alone leave a
    # parameter at a bound or on a ridge): a second start at the prior's centre
    res = None
    for start in (v_ls, np.clip(prior.centre(v_ls), lo, hi)):
        if not math.isfinite(criterion(start)[0]):
            continue
        trial = minimize(
            criterion,
            start,
            jac=True,
            method="L-BFGS-B",
            bounds=list(zip(lo, hi, strict=True)),
            options={"maxiter": 2000, "ftol": 1e-15, "gtol": 1e-10 * max(weight, 1.0)},
        )
        if res is None or trial.fun < res.fun:
            res = trial
    if res is None:
        raise ValueError("the posterior cannot be evaluated at the least-squares optimum")
    # L-BFGS-B may end its line search at the optimum, where the criterion's rounding stalls
    # it: converged as well when the gradient left (within the bounds) is negligible, a
    # Newton step of at most 1e-6 in every log parameter (the criterion's curvature is at
    # least the likelihood's weight times the squared relative sensitivities)
    g = np.array(res.jac, dtype=float)
    g[(res.x <= lo) & (g > 0)] = 0.0
    g[(res.x >= hi) & (g < 0)] = 0.0
    converged = bool(res.success) or float(np.max(np.abs(g), initial=0.0)) <= 1e-6 * weight
    return SimpleNamespace(
        x=res.x,
        fun=residuals(res.x),
        success=converged,
        status=1 if converged else 0,
        nfev=int(sol.nfev) + counts["nfev"],
        njev=int(sol.njev or 0) + counts["nfev"],
        active_mask=np.where(res.x <= lo, -1, np.where(res.x >= hi, 1, 0)),
        message=f"maximum a posteriori (L-BFGS-B, the better of two starts): {res.message}",
    )


def laplace_covariance(cov: np.ndarray, null: np.ndarray, Vt: np.ndarray, prior: LogPrior, v):
    """The estimator's covariance ``cov`` with the prior's information at ``v`` added to its
    own (the Laplace approximation of the posterior), with the null directions of that sum
    and its eigenvectors (rows), as the estimator's SVD gives them. The estimator's
    information is the inverse of ``cov`` on the directions its data determine (``Vt``'s
    rows off ``null``); a direction of the sum whose eigenvalue is below INFO_NULL of the
    largest is determined by neither."""
    seen = Vt[~null]
    info = seen.T @ np.linalg.pinv(seen @ cov @ seen.T, hermitian=True) @ seen
    info = info + prior.information(v)
    ev, vec = np.linalg.eigh((info + info.T) / 2.0)
    top = float(ev.max()) if ev.size else 0.0
    null = ev <= INFO_NULL * top if top > 0 else np.ones(ev.shape, bool)
    inv = np.where(null, 0.0, 1.0 / np.where(null, 1.0, ev))
    return (vec * inv) @ vec.T, null, vec.T
