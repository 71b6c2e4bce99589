"""Posterior sampling: the No-U-Turn sampler (NUTS) of nutpie on either estimator's
likelihood with its exact gradient - the Kalman filter's of :mod:`railtherm.estimation.
filtering`, or the simulation error's (:class:`railtherm.estimation.leastsquares_map.Density`)
- times the priors of :mod:`railtherm.estimation.priors`.

The sampler explores the estimator's unknowns as the fit holds them: the logarithms of the
structure's free parameters and of the noise parameters, the output offsets and the
estimated initial states (K). Its target is the log density of those unknowns,

    log p(v | y) = -NLL(v) + sum_i [log p_i(exp v_i) + v_i] + const,

the likelihood times each prior's density of theta carried to v = log theta
(the log Jacobian v_i). An unknown without a prior is flat in v: a log-uniform prior on a
positive parameter, a uniform one on an initial state or offset; within the fit's bounds,
outside which the density is zero. nutpie (the PyMC project's NUTS in Rust, with its
mass-matrix adaptation) calls the target as a Python function that returns the value and
the gradient together (``Density.log_density``): each leapfrog step costs one pass of the
filter with its forward sensitivities, or one simulation with its sensitivities.

nutpie and ArviZ are the optional extra ``railtherm[bayes]``; they are imported on first use
only.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from railtherm.estimation import kalman, pem
from railtherm.estimation.common import Experiment
from railtherm.estimation.models import Structure

__all__ = ["Posterior", "sample"]

EXTRA = "railtherm[bayes]"  # what to install for sampling
JITTER = 0.1  # chains start at the estimate moved by this many of its standard deviations
TARGET_ACCEPT = 0.8  # NUTS's default mean acceptance rate (nutpie's, PyMC's, Stan's)
LOO_DRAWS = 400  # the draws PSIS-LOO evaluates every observation's likelihood at


def _nutpie():
    try:
        import arviz
        import nutpie
        from nutpie import compiled_pyfunc
    except ImportError as err:
        raise ImportError(
            f"posterior sampling needs nutpie and ArviZ ({err.name} is missing): "
            f"pip install '{EXTRA}'"
        ) from None
    return nutpie, compiled_pyfunc, arviz


@dataclass
class Posterior:
    """Draws of a posterior and what a reader must check before using them.

    ``idata``: ArviZ InferenceData (nutpie's); its ``posterior`` group holds every unknown
    under its name (a parameter or noise parameter in its own unit, an offset or initial
    state in K),
    ``sample_stats`` the sampler's statistics (divergences, tree depth, step size).
    ``names``: the unknowns; ``estimate``: the MAP (or maximum-likelihood, without priors)
    fit the chains started from; ``seconds``: wall time of the sampling (tuning included);
    ``settings``: chains, draws, tune, target_accept, seed."""

    idata: Any
    names: tuple[str, ...]
    estimate: kalman.KalmanResult | pem.FitResult
    seconds: float
    settings: dict[str, Any] = field(default_factory=dict)
    density: Any = field(default=None, repr=False)  # the target, for :meth:`loo`

    def summary(self):
        """ArviZ's summary (mean, sd, 2.5 % and 97.5 % quantiles, R-hat, bulk and tail ESS)
        of every unknown, as a pandas DataFrame."""
        _, _, az = _nutpie()
        return az.summary(self.idata, hdi_prob=0.95, stat_focus="mean", round_to="none", kind="all")

    def quantiles(self, name: str, q: Sequence[float] = (0.025, 0.5, 0.975)) -> np.ndarray:
        """Quantiles of one unknown over all chains and draws."""
        return np.quantile(self.idata.posterior[name].values.ravel(), q)

    def divergences(self) -> int:
        return int(self.idata.sample_stats["diverging"].values.sum())

    def write(self, path: str) -> None:
        """The InferenceData as NetCDF (the ecosystem's format: ``arviz.from_netcdf``)."""
        self.idata.to_netcdf(path)

    def loo(self, max_draws: int = LOO_DRAWS) -> dict[str, Any]:
        """PSIS-LOO (Vehtari, Gelman & Gabry 2017) by ArviZ: the expected log predictive
        density of each observation left out, estimated from the posterior's draws by
        Pareto-smoothed importance sampling, over at most ``max_draws`` draws taken evenly
        from every chain. Each observation's log-likelihood is the estimator's own term
        (:meth:`railtherm.estimation.priors.PosteriorDensity.pointwise`): a row's
        one-step-ahead term for the Kalman filter, a residual's for the simulation error.
        Returns elpd_loo, its standard error, p_loo (the effective number of parameters),
        the number of observations and draws, the largest Pareto k and how many exceed 0.7
        (where the estimate of that observation's term is unreliable)."""
        if self.density is None:
            raise ValueError("PSIS-LOO needs the posterior's density (sampling.sample's)")
        _, _, az = _nutpie()
        post = self.idata.posterior
        chains, draws = post.sizes["chain"], post.sizes["draw"]
        keep = max(1, min(draws, max_draws // chains))
        at = np.unique(np.linspace(0, draws - 1, keep).round().astype(int))
        values = {name: post[name].values[:, at] for name in self.names}
        v = np.stack([values[name] for name in self.names], axis=-1)  # (chains, draws, P)
        v[..., : self.density.n_log] = np.log(v[..., : self.density.n_log])
        ll = np.array([[self.density.pointwise(row) for row in chain] for chain in v])
        data = az.from_dict(posterior=values, log_likelihood={"y": ll})
        with warnings.catch_warnings():  # the Pareto k are reported, not warned about
            warnings.simplefilter("ignore")
            result = az.loo(data, pointwise=True)
        k = np.asarray(result.pareto_k).ravel()
        m = int(ll.shape[2])
        weight = getattr(self.density, "weight", None)  # the simulation error's w
        return {
            "elpd_loo": float(result.elpd_loo),
            "se": float(result.se),
            "p_loo": float(result.p_loo),
            "observations": m,
            "draws": int(chains * len(at)),
            "pareto_k_max": float(np.max(k)) if k.size else math.nan,
            "pareto_k_above_0.7": int(np.sum(k > 0.7)),
            "effective_samples": float(m if weight is None else weight),
            "compare": LOO_COMPARE["kalman" if weight is None else "output_error"],
        }

    def add_systematic(
        self,
        effects_log: Mapping[str, Mapping[str, float]],
        values: Mapping[str, float] | None = None,
        seed: int = 0,
    ) -> None:
        """Mix the systematic (GUM type B) budget into the draws: the InferenceData's group
        ``posterior_systematic`` holds, for each parameter p of ``effects_log`` (p's signed
        change of log theta per standard uncertainty of each source j, as the ML fit's
        budget gives it), per chain and draw

            log theta_p = log theta_p(draw) + sum_j effects_log[p][j] xi_j,  xi_j ~ N(0, 1),

        one xi per source and draw, shared by every parameter (a source moves them
        together). A parameter the posterior does not sample (held by the fit, as kA from
        eq. 10 in the two-stage approach) enters at ``values[p]``. The posterior itself
        stays the data's: the statistical part."""
        post = self.idata.posterior
        chains, draws = post.sizes["chain"], post.sizes["draw"]
        sources = sorted({s for effects in effects_log.values() for s in effects})
        rng = np.random.default_rng([seed, 0x7B])  # apart from the sampler's own stream
        xi = rng.standard_normal((chains, draws, len(sources)))
        out = {}
        for p, effects in effects_log.items():
            if p in post:
                log_theta = np.log(post[p].values)
            elif values is not None and p in values:
                log_theta = np.full((chains, draws), math.log(float(values[p])))
            else:
                continue
            shift = xi @ np.array([float(effects.get(s, 0.0)) for s in sources])
            out[p] = (("chain", "draw"), np.exp(log_theta + shift))
        if not out:
            return
        import xarray as xr  # ArviZ's own dependency

        group = xr.Dataset(out, coords={"chain": post["chain"], "draw": post["draw"]})
        group.attrs["method"] = (
            "type-B sources mixed in by draws: log theta + sum_j effects_log[p][j] xi_j, "
            "xi_j ~ N(0, 1) per source and draw"
        )
        group.attrs["sources"] = ", ".join(sources)
        if "posterior_systematic" in self.idata.groups():
            del self.idata["posterior_systematic"]
        self.idata.add_groups({"posterior_systematic": group})

    def intervals(self, prob: float = 0.95):
        """Per parameter: the equal-tailed ``prob`` interval and median of the posterior
        (``statistical``) and, where :meth:`add_systematic` added it, of the posterior with
        the type-B budget mixed in (``with_systematic``); a pandas DataFrame."""
        import pandas as pd

        q = ((1.0 - prob) / 2.0, 0.5, (1.0 + prob) / 2.0)
        rows = {}
        groups = [("statistical", self.idata.posterior)]
        if "posterior_systematic" in self.idata.groups():
            groups.append(("with_systematic", self.idata.posterior_systematic))
        for label, group in groups:
            for p in group.data_vars:
                lo, med, hi = np.quantile(group[p].values.ravel(), q)
                rows.setdefault(p, {}).update(
                    {f"{label}_lo": lo, f"{label}_median": med, f"{label}_hi": hi}
                )
        return pd.DataFrame.from_dict(rows, orient="index")


# What a posterior's elpd_loo may be compared with (docs/bayes.md)
LOO_COMPARE = {
    "kalman": "Kalman-filter models of the same records and outputs",
    "output_error": (
        "none: each residual counts as effective_samples / observations of a sample, the "
        "model's own weight (its residuals' colour), so two models' elpd_loo are on "
        "different scales"
    ),
}


def sample(
    structure: Structure,
    experiments: Sequence[Experiment],
    *,
    chains: int = 4,
    draws: int = 1000,
    tune: int = 1000,
    seed: int = 0,
    target_accept: float = TARGET_ACCEPT,
    estimator: str = "kalman",
    mass_matrix: str = "low_rank",
    **fit_options: Any,
) -> Posterior:
    """Draws of the posterior of the model of ``structure`` given ``experiments`` under
    ``estimator``'s likelihood: ``kalman`` (the stochastic model's filter) or
    ``output_error`` (the simulation error, Gaussian with its variance integrated out, its
    residuals counted as the HAC covariance counts them:
    :class:`railtherm.estimation.leastsquares_map.Density`). First the fit
    (:func:`railtherm.estimation.kalman.fit` or :func:`railtherm.estimation.pem.fit` with
    ``fit_options``: fixed, initial, bounds, outputs, x0, priors, prior_terms, ...), then
    ``chains`` chains of NUTS, one after the other in this process (one thread), each
    ``tune`` tuning steps (discarded) and ``draws`` draws, each chain started at the fit's
    estimate moved by JITTER of its standard deviations, seeded by ``seed``.
    ``mass_matrix``: nutpie's adaptation of the metric, ``"low_rank"`` (the diagonal
    modified along the directions where the draws' covariance departs from it most: the
    correlated capacities and couplings of a grey-box model take 6-10x fewer leapfrog steps
    per draw) or ``"diagonal"``."""
    if mass_matrix not in ("low_rank", "diagonal"):
        raise ValueError(f"mass_matrix must be 'low_rank' or 'diagonal', got {mass_matrix!r}")
    if chains < 1 or draws < 1 or tune < 0:
        raise ValueError(
            f"chains and draws must be >= 1 and tune >= 0, got {chains}, {draws}, {tune}"
        )
    nutpie, compiled_pyfunc, az = _nutpie()
    if estimator not in ("kalman", "output_error"):
        raise ValueError(f"estimator must be 'kalman' or 'output_error', got {estimator!r}")
    fitter = kalman if estimator == "kalman" else pem
    estimate, density = fitter.fit_with_density(structure, experiments, **fit_options)
    held = getattr(estimate, "noise_at_bound", ())
    if held:  # as the fit holds them: a diffusion the records do not show stays at its bound
        fixed = {**(fit_options.get("fixed") or {})}
        for name in held:
            kind, of = name.split("_", 1)
            fixed[name] = (estimate.sigma if kind == "sigma" else estimate.meas_var)[of]
        estimate, density = fitter.fit_with_density(
            structure, experiments, **{**fit_options, "fixed": fixed}
        )
    names, n_log = density.names, density.n_log
    spread = _spread(estimate, density)

    def make_logp():
        def logp(v):
            lp, g = density.log_density(np.asarray(v, dtype=float))
            return float(lp), np.ascontiguousarray(g, dtype=float)

        return logp

    def make_expand(seed1, seed2, chain):
        def expand(v):
            v = np.asarray(v, dtype=float)
            return {
                name: np.asarray(math.exp(v[i]) if i < n_log else v[i])
                for i, name in enumerate(names)
            }

        return expand

    def initial_point(seed):  # the estimate, moved a little (its gradient there is ~0)
        rng = np.random.default_rng(seed)
        v = density.v + JITTER * spread * rng.standard_normal(len(density.v))
        return np.clip(v, density.lo, density.hi)

    model = compiled_pyfunc.from_pyfunc(
        len(names),
        make_logp,
        make_expand,
        [np.dtype("float64")] * len(names),
        [()] * len(names),
        list(names),
        make_initial_point_fn=initial_point,
    )
    start = time.perf_counter()
    idata = nutpie.sample(
        model,
        draws=draws,
        tune=tune,
        chains=chains,
        seed=seed,
        cores=1,
        target_accept=target_accept,
        progress_bar=False,
        low_rank_modified_mass_matrix=mass_matrix == "low_rank",
    )
    seconds = time.perf_counter() - start
    idata.attrs.update(
        {
            "sampler": f"nutpie {nutpie.__version__} (NUTS)",
            "target": (
                "railtherm's Kalman-filter likelihood with its exact gradient"
                if estimator == "kalman"
                else "railtherm's simulation-error likelihood (eq. 17, its variance "
                "integrated out) with its exact gradient"
            ),
            "structure": structure.name,
        }
    )
    settings = {
        "chains": chains,
        "draws": draws,
        "tune": tune,
        "seed": seed,
        "target_accept": target_accept,
        "mass_matrix": mass_matrix,
        "cores": 1,
    }
    return Posterior(idata, tuple(names), estimate, seconds, settings, density)


def _spread(estimate, density) -> np.ndarray:
    """The estimate's standard deviation of each unknown (the Kalman fit's covariance; the
    output-error fit's sd of the log parameters); 0.01 where none is known or finite."""
    cov = np.asarray(getattr(estimate, "covariance_log", np.zeros((0, 0))), dtype=float)
    if cov.shape == (len(density.v), len(density.v)):
        sd = np.sqrt(np.abs(np.diag(cov)))
    else:
        sd = np.array([estimate.sd_log.get(name, np.nan) for name in density.names])
    return np.where(np.isfinite(sd) & (sd > 0), sd, 0.01)
