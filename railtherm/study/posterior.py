"""A vehicle's posterior: the stage-two fit of one of its models, set up as the study sets
it up (:func:`railtherm.study.identify.fit_setup`: kA held at the static or the
storage-corrected value, the vehicle's priors), sampled by NUTS
(:func:`railtherm.estimation.sampling.sample`; docs/bayes.md)."""

from __future__ import annotations

import os
from typing import Any

from railtherm.estimation import sampling
from railtherm.study import identify
from railtherm.study.storage import storage_corrected_k

__all__ = ["vehicle_posterior", "write"]


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
