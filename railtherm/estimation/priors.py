"""Prior distributions of a structure's parameters, and the log-prior both estimators add to
their criterion for a maximum a posteriori (MAP) estimate.

A prior is given per parameter in the parameter's own unit (SI: J/K, W/K, m^2), one of

=============  ==========================  ==============================================
kind           parameters                  density of theta > 0 (up to a constant)
=============  ==========================  ==============================================
lognormal      median, sd_log              exp(-(log theta - log median)^2 / (2 sd_log^2)) / theta
normal         mean, sd                    exp(-(theta - mean)^2 / (2 sd^2))
gamma          shape, scale                theta^(shape - 1) exp(-theta / scale)
half_normal    sd                          exp(-theta^2 / (2 sd^2))
uniform        lower, upper                1 on [lower, upper], 0 elsewhere
=============  ==========================  ==============================================

The estimators work in log parameters v = log theta. The MAP estimate is the mode of the
posterior density of theta, p(y | theta) p(theta), as CTSM-R and pySIP define it: the
criterion is NLL(v) - sum_i log p_i(exp(v_i)), and a parameter without a prior adds nothing
(so that with no prior at all the MAP estimate is the maximum-likelihood one). A sampler
that explores v needs the density of v instead, log p_i(exp(v_i)) + v_i (the log Jacobian):
:meth:`LogPrior.evaluate` gives either. A uniform prior is a bound: its interval is
intersected with the parameter's search bounds (:meth:`LogPrior.bounds`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

__all__ = [
    "KINDS",
    "LinearT",
    "LogPrior",
    "PosteriorDensity",
    "Prior",
    "PriorError",
    "prior_from_config",
]

# kind: its parameters, in the order they are written
KINDS: dict[str, tuple[str, ...]] = {
    "lognormal": ("median", "sd_log"),
    "normal": ("mean", "sd"),
    "gamma": ("shape", "scale"),
    "half_normal": ("sd",),
    "uniform": ("lower", "upper"),
}


class PriorError(ValueError):
    """A prior's specification that names no known kind, misses a parameter or gives one
    out of its range; the message names the key and the value."""


HALF_NORMAL_MEDIAN = 0.6744897501960817  # the standard half-normal's median, ndtri(0.75)


@dataclass(frozen=True)
class Prior:
    """One parameter's prior: ``kind`` (a key of :data:`KINDS`) and its ``args`` in the
    order of :data:`KINDS`, in the parameter's unit (``sd_log`` and ``shape`` have none)."""

    kind: str
    args: tuple[float, ...]

    def to_dict(self) -> dict[str, float | str]:
        """{kind, <its parameters>} as written in a vehicle file's ``model.priors``."""
        values = map(float, self.args)
        return {"kind": self.kind, **dict(zip(KINDS[self.kind], values, strict=True))}

    def median(self) -> float:
        """The prior's median in the parameter's unit (a normal one truncated at 0)."""
        a = self.args
        if self.kind == "lognormal":
            return float(a[0])
        if self.kind == "uniform":
            return 0.5 * (a[0] + a[1])
        if self.kind == "half_normal":
            return float(a[0]) * HALF_NORMAL_MEDIAN
        from scipy import special  # the quantile functions, without scipy.stats's import

        if self.kind == "gamma":
            return float(special.gammaincinv(a[0], 0.5)) * a[1]
        mean, sd = a  # normal on theta > 0: Phi((m - mean) / sd) = (1 + Phi(-mean / sd)) / 2
        if mean / sd < -30.0:  # far below 0: the tail is exponential, rate |mean| / sd^2
            return math.log(2.0) * sd * sd / abs(mean)
        return mean + sd * float(special.ndtri(0.5 * (1.0 + special.ndtr(-mean / sd))))

    def support(self) -> tuple[float, float]:
        """The interval of theta outside which the density is zero."""
        if self.kind == "uniform":
            return float(self.args[0]), float(self.args[1])
        return 0.0, math.inf

    def log_density(self, theta: float, positive: bool = True) -> tuple[float, float, float]:
        """(log p(theta), d log p / dtheta, d^2 log p / dtheta^2) up to the constant of the
        kind; -inf (and zero derivatives) outside the support. ``positive=False``: theta is
        a quantity of either sign (an initial temperature), for which a normal prior is not
        truncated at 0 and a uniform one is its interval."""
        lo, hi = self.support()
        signed = not positive and self.kind in ("normal", "uniform")
        if not (lo <= theta <= hi) or (theta <= 0.0 and not signed):
            return -math.inf, 0.0, 0.0
        if self.kind == "lognormal":
            median, s = self.args
            z = (math.log(theta) - math.log(median)) / s
            return (
                -0.5 * z * z - math.log(theta),
                -(z / s + 1.0) / theta,
                (z / s + 1.0 - 1.0 / s**2) / theta**2,
            )
        if self.kind == "normal":
            mean, s = self.args
            return -0.5 * ((theta - mean) / s) ** 2, -(theta - mean) / s**2, -1.0 / s**2
        if self.kind == "gamma":
            shape, scale = self.args
            return (
                (shape - 1.0) * math.log(theta) - theta / scale,
                (shape - 1.0) / theta - 1.0 / scale,
                -(shape - 1.0) / theta**2,
            )
        if self.kind == "half_normal":
            (s,) = self.args
            return -0.5 * (theta / s) ** 2, -theta / s**2, -1.0 / s**2
        return 0.0, 0.0, 0.0  # uniform, inside

    def logpdf(self, theta: float) -> float:
        """The normalised log density of theta (for comparison with other implementations;
        the estimators need only :meth:`log_density`)."""
        lp = self.log_density(theta)[0]
        if not math.isfinite(lp):
            return lp
        if self.kind == "lognormal":
            median, s = self.args
            return lp - math.log(s * math.sqrt(2.0 * math.pi))
        if self.kind == "normal":  # on theta > 0: truncated
            mean, s = self.args
            return lp - math.log(s * math.sqrt(2.0 * math.pi)) - _log_ndtr(mean / s)
        if self.kind == "gamma":
            shape, scale = self.args
            return lp - math.lgamma(shape) - shape * math.log(scale)
        if self.kind == "half_normal":
            (s,) = self.args
            return lp + 0.5 * math.log(2.0 / math.pi) - math.log(s)
        lo, hi = self.args
        return -math.log(hi - lo)


def _log_ndtr(x: float) -> float:
    """log Phi(x), the log standard normal CDF."""
    return math.log(0.5 * math.erfc(-x / math.sqrt(2.0)))


def prior_from_config(spec: Mapping[str, object], where: str = "priors") -> Prior:
    """The :class:`Prior` of one entry of ``model.priors``: ``{kind: <kind>, <its
    parameters>}``. Raises :class:`PriorError` naming ``where`` (the key) and the value."""
    if not isinstance(spec, Mapping):
        raise PriorError(f"{where}: a prior is a mapping {{kind: ..., ...}}, got {spec!r}")
    kind = spec.get("kind")
    if kind not in KINDS:
        raise PriorError(f"{where}.kind: {kind!r} is not one of {', '.join(KINDS)}")
    names = KINDS[kind]
    extra = sorted(set(spec) - {"kind", *names})
    missing = [n for n in names if n not in spec]
    if extra or missing:
        raise PriorError(
            f"{where}: a {kind} prior takes {', '.join(names)}"
            + (f"; missing {', '.join(missing)}" if missing else "")
            + (f"; unknown {', '.join(extra)}" if extra else "")
        )
    args = []
    for n in names:
        value = spec[n]
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise PriorError(f"{where}.{n}: {value!r} is not a number")
        value = float(value)
        if n == "mean":  # a normal prior's mean may lie anywhere (truncated at theta > 0)
            need, ok = "finite", math.isfinite(value)
        elif kind == "uniform" and n == "lower":
            need, ok = "finite and >= 0", math.isfinite(value) and value >= 0
        else:
            need, ok = "finite and > 0", math.isfinite(value) and value > 0
        if not ok:
            raise PriorError(f"{where}.{n}: {value!r} must be {need}")
        args.append(value)
    if kind == "uniform" and not args[0] < args[1]:
        raise PriorError(f"{where}: lower {args[0]:g} must be < upper {args[1]:g}")
    prior = Prior(kind, tuple(args))
    median = prior.median()
    if not (math.isfinite(median) and median > 0):
        raise PriorError(
            f"{where}: its median {median:g} is no positive number (the mass of the prior "
            "lies below any value a parameter takes): widen it"
        )
    return prior


@dataclass(frozen=True)
class LinearT:
    """A joint prior term: a linear combination of log parameters,
    g = sum_p weights[p] log theta_p + offset, distributed as centre_log + scale T_dof (a
    Student t; dof = inf: a normal). A class reference model's generalised parameters are of
    this kind (railtherm.study.classmodel): log c_veh = log C_veh - log m,
    log delta = log C_veh - log C, log kappa_veh = log K_veh - log A. The term is the density
    of g; a set of such terms that maps the parameters' logs one to one (as those do) is a
    density of the log parameters, and :class:`LogPrior` turns it into theta's."""

    name: str
    weights: tuple[tuple[str, float], ...]
    offset: float
    centre_log: float
    scale: float
    dof: float

    def to_dict(self) -> dict[str, object]:
        return {
            "kind": "student_t_log" if math.isfinite(self.dof) else "normal_log",
            "of": " + ".join(f"{w:g} log {p}" for p, w in self.weights)
            + (f" {self.offset:+.6g}" if self.offset else ""),
            "centre": math.exp(self.centre_log),
            "scale_log": self.scale,
            **({"dof": self.dof} if math.isfinite(self.dof) else {}),
        }

    def log_density(self, g: float) -> tuple[float, float, float]:
        """(log density of g up to a constant, its first and second derivative in g)."""
        z = (g - self.centre_log) / self.scale
        if not math.isfinite(self.dof):
            return -0.5 * z * z, -z / self.scale, -1.0 / self.scale**2
        nu = self.dof
        q = 1.0 + z * z / nu
        return (
            -0.5 * (nu + 1.0) * math.log(q),
            -(nu + 1.0) / nu * z / q / self.scale,
            -(nu + 1.0) / nu * (1.0 - z * z / nu) / q**2 / self.scale**2,
        )


def outside_bounds(prior: Prior, name: str, search: Sequence[float] | None) -> str | None:
    """Why ``prior`` leaves nothing to estimate within the search bounds ``search`` of the
    parameter ``name`` (None where it does, or no bounds are known): a uniform range outside
    them, or a median outside them (the estimate would rest on a bound: a unit mistake)."""
    if search is None:
        return None
    lo, hi = float(search[0]), float(search[1])
    if prior.kind == "uniform":
        if max(prior.args[0], lo) < min(prior.args[1], hi):
            return None
        return (
            f"a uniform prior outside the search bounds [{lo:g}, {hi:g}] of {name}: no value "
            "is left to estimate (its unit: SI, J/K or W/K)"
        )
    median = prior.median()
    if lo < median < hi:
        return None
    return (
        f"its median {median:.4g} lies outside the search bounds [{lo:g}, {hi:g}] of {name}: "
        "the estimate would rest on a bound (a unit mistake? SI units: J/K, W/K)"
    )


def bounded(bounds: Mapping[str, tuple[float, float]], priors: Mapping[str, Prior] | None):
    """``bounds`` ({parameter: (lo, hi)}) narrowed by each uniform prior: the search's
    bounds, so that an estimate at a uniform prior's end is flagged as at a bound."""
    out = dict(bounds)
    for name, prior in (priors or {}).items():
        if prior.kind == "uniform" and name in out:
            lo, hi = out[name]
            out[name] = (max(float(lo), prior.args[0]), min(float(hi), prior.args[1]))
    return out


class LogPrior:
    """The log-prior of the unknowns ``free`` held as logarithms at the head of the
    estimator's unknowns (``v[:len(free)]``): a sum over those with a prior in ``priors``
    ({name: Prior}); the others add nothing. Priors on parameters that are not free are
    ignored by the estimate (a fixed parameter has no distribution to update): :attr:`unused`
    names them."""

    def __init__(
        self,
        free: Sequence[str],
        priors: Mapping[str, Prior],
        terms: Sequence[LinearT] = (),
        raw: Sequence[tuple[int, str]] = (),
    ):
        self.free = tuple(free)
        self.priors = dict(priors)
        self.index = [(i, self.priors[p]) for i, p in enumerate(self.free) if p in self.priors]
        # unknowns held as values, not logarithms (an initial state in K): (position, name)
        self.raw = [(i, name, self.priors[name]) for i, name in raw if name in self.priors]
        named = set(self.free) | {name for _, name in raw}
        self.unused = tuple(p for p in self.priors if p not in named)
        # joint terms over free parameters only (one on a fixed parameter conditions nothing
        # the fit estimates: it is left out, like a prior on a fixed parameter)
        self.terms = [t for t in terms if all(p in self.free for p, _ in t.weights)]
        self.unused_terms = tuple(t.name for t in terms if t not in self.terms)
        overlap = {p for t in self.terms for p, _ in t.weights} & set(self.priors)
        if overlap:
            raise PriorError(
                f"priors: {', '.join(sorted(overlap))} given both a prior of its own and one "
                "from the class model"
            )
        self.jacobian_of_terms = sorted(
            {self.free.index(p) for t in self.terms for p, _ in t.weights}
        )

    def __bool__(self) -> bool:
        return bool(self.index) or bool(self.terms) or bool(self.raw)

    def evaluate(self, v: np.ndarray, jacobian: bool = False):
        """(log-prior, gradient, Hessian) in v = log theta, over ``len(v)`` unknowns (those
        past the free parameters get zeros). ``jacobian``: the density of v (adds sum v_i
        over the parameters with a prior) instead of theta's."""
        U = len(v)
        g, H = np.zeros(U), np.zeros((U, U))
        total = 0.0
        for i, prior in self.index:
            theta = math.exp(float(v[i]))
            lp, d1, d2 = prior.log_density(theta)
            if not math.isfinite(lp):
                return -math.inf, g, H
            # d/dv = theta d/dtheta; d2/dv2 = theta d/dtheta + theta^2 d2/dtheta2
            total += lp + (float(v[i]) if jacobian else 0.0)
            g[i] = theta * d1 + (1.0 if jacobian else 0.0)
            H[i, i] = theta * d1 + theta**2 * d2
        for i, _, prior in self.raw:  # on the value itself: no Jacobian either way
            lp, d1, d2 = prior.log_density(float(v[i]), positive=False)
            if not math.isfinite(lp):
                return -math.inf, g, H
            total += lp
            g[i] += d1
            H[i, i] += d2
        for term in self.terms:  # densities of the log parameters
            w = np.zeros(U)
            for p, weight in term.weights:
                w[self.free.index(p)] = weight
            lp, d1, d2 = term.log_density(float(w @ v) + term.offset)
            total += lp
            g += d1 * w
            H += d2 * np.outer(w, w)
        if self.terms and not jacobian:  # theta's density: d log theta = d theta / theta
            for i in self.jacobian_of_terms:
                total -= float(v[i])
                g[i] -= 1.0
        return total, g, H

    def centre(self, v: np.ndarray) -> np.ndarray:
        """``v`` with the parameters that have a prior moved to the prior's centre: a
        prior's median (the geometric centre of a uniform one), and for the joint terms the
        log parameters that put every term at its centre (least squares over the terms'
        parameters). A second start for a MAP search, where the likelihood alone leaves a
        parameter at a bound or on a ridge."""
        w = np.array(v, dtype=float)
        for i, prior in self.index:
            if prior.kind == "uniform":
                w[i] = 0.5 * (math.log(max(prior.args[0], 1e-300)) + math.log(prior.args[1]))
            else:
                w[i] = math.log(prior.median())
        for i, _, prior in self.raw:
            if prior.kind == "normal":
                w[i] = prior.args[0]
            elif prior.kind == "uniform":
                w[i] = 0.5 * (prior.args[0] + prior.args[1])
        if self.terms:
            cols = self.jacobian_of_terms
            W = np.zeros((len(self.terms), len(cols)))
            rhs = np.zeros(len(self.terms))
            for r, term in enumerate(self.terms):
                for p, weight in term.weights:
                    W[r, cols.index(self.free.index(p))] = weight
                rhs[r] = term.centre_log - term.offset
            w[cols] = np.linalg.lstsq(W, rhs, rcond=None)[0]
        return w

    def information(self, v: np.ndarray) -> np.ndarray:
        """The prior's information at v: minus its Hessian in v, its negative eigenvalues
        set to zero (a Student t's tails curve the other way; a scoring step and a Laplace
        covariance take the part that adds information)."""
        H = self.evaluate(v)[2]
        if not H.any():
            return np.zeros_like(H)
        ev, vec = np.linalg.eigh(-(H + H.T) / 2.0)
        return (vec * np.maximum(ev, 0.0)) @ vec.T

    def bounds(self, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The log bounds ``lo``, ``hi`` of the unknowns narrowed to each prior's support."""
        lo, hi = np.array(lo, dtype=float), np.array(hi, dtype=float)
        for i, prior in self.index:
            a, b = prior.support()
            if a > 0:
                lo[i] = max(lo[i], math.log(a))
            if math.isfinite(b):
                hi[i] = min(hi[i], math.log(b))
        for i, _, prior in self.raw:
            if prior.kind == "uniform":
                lo[i], hi[i] = max(lo[i], prior.args[0]), min(hi[i], prior.args[1])
        return lo, hi

    def to_dict(self) -> dict[str, dict[str, object]]:
        """{parameter: the prior as written} for the free parameters with one, and
        {term name: the term} for the joint terms."""
        return {
            **{self.free[i]: prior.to_dict() for i, prior in self.index},
            **{name: prior.to_dict() for _, name, prior in self.raw},
            **{t.name: t.to_dict() for t in self.terms},
        }


@dataclass
class PosteriorDensity:
    """What a posterior sampler needs of an estimator (:mod:`railtherm.estimation.sampling`):
    the log-prior ``prior``, the unknowns' ``names`` (the first ``n_log`` held as
    logarithms), their bounds ``lo``, ``hi`` and the fit's estimate ``v``; each estimator's
    subclass adds :meth:`log_density`, its likelihood plus ``prior``'s log density of the
    log parameters, -inf outside the bounds (:meth:`outside`)."""

    prior: LogPrior
    names: tuple[str, ...]
    n_log: int
    lo: np.ndarray
    hi: np.ndarray
    v: np.ndarray

    def outside(self, v: np.ndarray) -> bool:
        return bool(np.any(v < self.lo) or np.any(v > self.hi))

    def pointwise(self, v: np.ndarray) -> np.ndarray:
        """The likelihood's log density of each observation at v (one value per compared
        sample), for PSIS-LOO (:meth:`railtherm.estimation.sampling.Posterior.loo`)."""
        raise NotImplementedError
