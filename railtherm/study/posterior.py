"""A vehicle's posterior: the stage-two fit of one of its models, set up as the study sets
it up (:func:`railtherm.study.identify.fit_setup`: kA held at the static or the
storage-corrected value, the vehicle's priors), sampled by NUTS
(:func:`railtherm.estimation.sampling.sample`; docs/bayes.md)."""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from railtherm.estimation import sampling
from railtherm.study import identify
from railtherm.study.storage import storage_corrected_k

__all__ = [
    "add_systematic",
    "pair_plot",
    "read_draws",
    "sample_model",
    "vehicle_posterior",
    "write",
]


def vehicle_posterior(
    vehicle,
    model: str,
    result,
    *,
    chains: int,
    draws: int,
    tune: int,
    seed: int,
    prior_terms=(),
    target_accept: float = sampling.TARGET_ACCEPT,
) -> sampling.Posterior:
    """The posterior of ``model`` (a model key: order2, order2_kalman, ...) of ``vehicle``
    given its identification windows, from ``result`` (:func:`railtherm.study.run.
    fit_vehicle`'s: its tables, k stage and fits): the two-stage set-up of the study's fit,
    the fit's type-B budget mixed into the draws."""
    windows = {w["name"]: result.tables[w["name"]] for w in vehicle.windows["identification"]}
    k_stage = None if result.kvalue is None else result.kvalue.to_dict()
    return sample_model(
        windows, vehicle.data, k_stage, result.tables.get("kvalue"), model,
        fit=result.fits.get(model), prior_terms=prior_terms, chains=chains, draws=draws,
        tune=tune, seed=seed, target_accept=target_accept,
    )  # fmt: skip


def sample_model(
    windows,
    vehicle_data,
    k_stage,
    k_window,
    model: str,
    *,
    fit=None,
    prior_terms=(),
    chains: int,
    draws: int,
    tune: int,
    seed: int,
    target_accept: float = sampling.TARGET_ACCEPT,
) -> sampling.Posterior:
    """The posterior of ``model`` of a vehicle (its config ``vehicle_data``) given its
    identification ``windows``, its static k result ``k_stage`` and k window: kA held at the
    static or storage-corrected value (:func:`railtherm.study.identify.fit_setup`), the
    vehicle's priors and ``prior_terms`` (e.g. the class's:
    :mod:`railtherm.study.pooling`); ``fit``'s type-B budget, where given, mixed into the
    draws (:func:`add_systematic`)."""
    storage = storage_corrected_k(windows, k_window, vehicle_data, k_stage)
    setup = identify.fit_setup(windows, vehicle_data, k_stage, model, storage, prior_terms)
    options: dict[str, Any] = dict(setup.options)
    estimator = options.pop("estimator", "output_error")
    if estimator == "kalman":
        options.pop("covariance", None)  # the filter's observed information gives it
    post = sampling.sample(
        setup.structure, setup.exps, chains=chains, draws=draws, tune=tune, seed=seed,
        target_accept=target_accept, estimator=estimator, **options,
    )  # fmt: skip
    if fit is not None:
        add_systematic(post, fit, seed)
    return post


def add_systematic(post: sampling.Posterior, fit, seed: int) -> None:
    """The fit's type-B budget (its ``systematic`` section: each source's signed effect on
    every log parameter, the held kA's included) mixed into the posterior's draws
    (:meth:`railtherm.estimation.sampling.Posterior.add_systematic`)."""
    systematic = fit.section("systematic")
    effects = {
        **(systematic.get("effects_log") or {}),
        **(systematic.get("effects_log_fixed") or {}),
    }
    values = {p: float(e["value"]) for p, e in fit.section("parameters").items()}
    if effects:
        post.add_systematic(effects, values, seed=seed)


def write(posterior: sampling.Posterior, path: str) -> str:
    """The posterior's InferenceData as NetCDF at ``path`` (its directory made); returns it."""
    os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
    posterior.write(path)
    return path


def pair_plot(posterior: sampling.Posterior, path: str) -> str:
    """ArviZ's pair plot of the structure's parameters (the draws of every pair, each one's
    marginal on the diagonal, divergent draws marked) as PNG at ``path``; returns it. With
    one structural parameter (a first-order model with kA held) the initial states join it;
    a single unknown gets its marginal with the 95 % HDI."""
    import arviz as az
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [n for n in posterior.estimate.free if n in posterior.idata.posterior]
    if len(names) < 2:  # one structural parameter (C_bar, kA held): with the initial states
        names = list(posterior.idata.posterior.data_vars)
    if len(names) < 2:  # a single unknown: its marginal
        ax = az.plot_posterior(posterior.idata, var_names=names, hdi_prob=0.95, figsize=(6, 4))
        figure = np.asarray(ax).ravel()[0].figure
        figure.savefig(path, dpi=110)
        plt.close(figure)
        return path
    axes = az.plot_pair(
        posterior.idata, var_names=names, kind="scatter", marginals=True, divergences=True,
        scatter_kwargs={"alpha": 0.4, "s": 5, "color": "C0"}, figsize=(8.0, 8.0),
        textsize=9,
    )  # fmt: skip
    figure = np.asarray(axes).ravel()[0].figure
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return path


def read_draws(path, fit) -> tuple[dict[str, np.ndarray], bool]:
    """The draws of every parameter of ``fit`` from its posterior file ``path`` (NetCDF, as
    :func:`write` writes it), chains and draws in one axis: a parameter's draws with the
    systematic budget mixed in (group ``posterior_systematic``) where there are such, else
    the posterior's own, else (a parameter neither sampled nor moved by a type-B source) its
    value in the fit file; and whether the file carries the systematic budget. A ConfigError
    names the file when it cannot be read or holds no posterior of the fit's parameters."""
    from railtherm.errors import ConfigError

    try:
        _, _, az = sampling._nutpie()
        idata = az.from_netcdf(str(path))
    except (OSError, ValueError, KeyError, TypeError) as err:
        reason = (
            f"not a posterior InferenceData ({type(err).__name__}: {err or 'unreadable'}); "
            "write it again with `railtherm fit --posterior --out`, or remove it"
        )
        raise ConfigError(str(path), "(file)", str(path), reason) from None
    groups = idata.groups()
    if "posterior" not in groups:
        raise ConfigError(
            str(path), "posterior", list(groups), "no posterior group: not a sampler's output"
        )
    mixed = idata.posterior_systematic if "posterior_systematic" in groups else None
    own = idata.posterior
    params = fit.section("parameters")
    if not any(p in own for p in params):
        raise ConfigError(
            str(path), "posterior", sorted(own.data_vars), f"no parameter of {fit.model}"
        )
    size = own.sizes["chain"] * own.sizes["draw"]
    if size == 0:
        raise ConfigError(
            str(path), "posterior", "0 draws",
            "no draws to predict from: write it again with `railtherm fit --posterior --out`, "
            "or remove it",
        )  # fmt: skip
    out = {}
    for p, entry in params.items():
        if mixed is not None and p in mixed:
            out[p] = mixed[p].values.ravel()
        elif p in own:
            out[p] = own[p].values.ravel()
        else:
            out[p] = np.full(size, float(entry["value"]))
    return out, mixed is not None
