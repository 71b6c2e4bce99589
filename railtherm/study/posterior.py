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

__all__ = ["pair_plot", "vehicle_posterior", "write"]


def vehicle_posterior(
    vehicle, model: str, result, *, chains: int, draws: int, tune: int, seed: int
) -> sampling.Posterior:
    """The posterior of ``model`` (a model key: order2, order2_kalman, ...) of ``vehicle``
    given its identification windows, from ``result`` (:func:`railtherm.study.run.
    fit_vehicle`'s: its tables and k stage): the two-stage set-up of the study's fit."""
    windows = {w["name"]: result.tables[w["name"]] for w in vehicle.windows["identification"]}
    k_stage = None if result.kvalue is None else result.kvalue.to_dict()
    storage = storage_corrected_k(windows, result.tables.get("kvalue"), vehicle.data, k_stage)
    setup = identify.fit_setup(windows, vehicle.data, k_stage, model, storage)
    options: dict[str, Any] = dict(setup.options)
    estimator = options.pop("estimator", "output_error")
    if estimator == "kalman":
        options.pop("covariance", None)  # the filter's observed information gives it
    return sampling.sample(
        setup.structure, setup.exps, chains=chains, draws=draws, tune=tune, seed=seed,
        estimator=estimator, **options,
    )  # fmt: skip


def write(posterior: sampling.Posterior, path: str) -> str:
    """The posterior's InferenceData as NetCDF at ``path`` (its directory made); returns it."""
    os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
    posterior.write(path)
    return path


def pair_plot(posterior: sampling.Posterior, path: str) -> str:
    """ArviZ's pair plot of the structure's parameters (the draws of every pair, each one's
    marginal on the diagonal, divergent draws marked) as PNG at ``path``; returns it."""
    import arviz as az
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [n for n in posterior.estimate.free if n in posterior.idata.posterior]
    axes = az.plot_pair(
        posterior.idata, var_names=names, kind="scatter", marginals=True, divergences=True,
        scatter_kwargs={"alpha": 0.4, "s": 5, "color": "C0"}, figsize=(8.0, 8.0),
        textsize=9,
    )  # fmt: skip
    figure = np.asarray(axes).ravel()[0].figure
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return path
