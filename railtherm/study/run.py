"""One vehicle through the study's chain, without the workflow engine.

:func:`fit_vehicle` does for one validated :class:`~railtherm.config.Vehicle` what the rules
``clean`` -> ``kvalue`` -> ``identify`` -> ``check`` do: tidy tables of its windows, the
static k (eq. 10) when it has a k window, its storage correction (the k window's energy
balance under the second-order model, iterated with stage two), then each model fitted by
simulation-error PEM (eqs. 15-20) with the corrected kA fixed, and the verdict. With ``out``
it writes the same files under ``out/vehicles/<id>/`` as the workflow does under
``results/vehicles/<id>/``.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import pandas as pd

from railtherm import io as rt_io
from railtherm import structures
from railtherm.config import Vehicle
from railtherm.data import ingest
from railtherm.errors import ConfigError
from railtherm.estimation import kvalue
from railtherm.study import fitsettings, identify, quality
from railtherm.study.fit import Fit, write_yaml
from railtherm.study.storage import storage_corrected_k


@dataclass
class VehicleResult:
    """What :func:`fit_vehicle` produced: the tidy tables by window name, the static k test
    (None without a k window) and the checked fits by model key (order1, order2, ...)."""

    vehicle: Vehicle
    tables: dict[str, pd.DataFrame]
    kvalue: kvalue.KValue | None
    fits: dict[str, Fit] = field(default_factory=dict)


def read_stage_inputs(
    names: Sequence[str],
    windows: Sequence[str],
    kvalue_file: str | None = None,
    k_window_file: str | None = None,
) -> tuple[dict[str, pd.DataFrame], dict[str, Any] | None, pd.DataFrame | None]:
    """What a vehicle's fit stage reads from the rules' files (rules identify and
    posterior): its identification windows ``{name: tidy table}`` (``names`` and their
    files ``windows``, in order), its static k result and its k window (None where the
    vehicle has no k window)."""
    tables = {name: ingest.read_tidy(path) for name, path in zip(names, windows, strict=True)}
    if not kvalue_file:
        return tables, None, None
    return tables, rt_io.read_result(kvalue_file), ingest.read_tidy(k_window_file)


def tidy_tables(vehicle: Vehicle, workdir: str | os.PathLike[str] = ".") -> dict[str, pd.DataFrame]:
    """Every window of ``vehicle`` cleaned (rule ``clean``): the k window and the
    identification windows, each raw file read once."""
    sources = {
        name: vehicle.record(ingest.window_spec(vehicle.data, name)[0])
        for name in ingest.window_names(vehicle.data)
    }
    return ingest.clean_windows(vehicle.data, sources, workdir)


def fit_vehicle(
    vehicle: Vehicle,
    models: Sequence[str] | None = None,
    out: str | os.PathLike[str] | None = None,
    workdir: str | os.PathLike[str] = ".",
    prior_terms: Sequence[Any] = (),
) -> VehicleResult:
    """Clean, static k, fit and check ``models`` (default: every model the config asks for,
    :func:`railtherm.study.fitsettings.model_keys`). ``out``: a results directory to write the
    rules' files into (``vehicles/<id>/clean/<window>.csv``, ``kvalue.yaml``,
    ``identify/<model>.yaml`` and ``_series.csv``, ``fit_<model>.yaml``).

    Parameters
    ----------
    vehicle : Vehicle
        The vehicle config (:func:`railtherm.load_vehicle`).
    models : sequence of str, optional
        Model keys (``order1``, ``order2``, ``order2_kalman``, ...).
    out : str or os.PathLike, optional
        A results directory to write into.
    workdir : str or os.PathLike
        The directory the vehicle's raw files are relative to.
    prior_terms : sequence of LinearT, optional
        Joint prior terms for the second-order models (the class's:
        :func:`railtherm.study.pooling.class_prior`): their fits are then MAP fits.

    Returns
    -------
    VehicleResult
        The tidy tables, the static k and each model's :class:`Fit`.
    """
    keys = list(models) if models else fitsettings.model_keys(vehicle.data)
    for key in keys:  # a refused structure module stops here, naming its file and the fix
        for refused in structures.refused(fitsettings.split_key(key)[0]):
            raise refused.error()
    unknown = [k for k in keys if fitsettings.split_key(k)[0] not in structures.keys()]
    if unknown:
        raise ValueError(
            f"unknown model {unknown[0]!r}; known: {', '.join(structures.keys())}, each "
            f"also with the suffix {fitsettings.KALMAN_SUFFIX} (the Kalman-filter estimator)"
        )
    tables = tidy_tables(vehicle, workdir)
    base = None if out is None else os.path.join(str(out), "vehicles", vehicle.id)
    if base is not None:
        for name, table in tables.items():
            ingest.write_tidy(table, os.path.join(base, "clean", f"{name}.csv"))
    k = None
    if "kvalue" in tables:
        raw_name, _, key = ingest.window_spec(vehicle.data, "kvalue")
        source = f"{vehicle.raw_files[raw_name]} ({key})"
        k = kvalue.for_vehicle(tables["kvalue"], vehicle.data, source=source)
        if base is not None:
            write_yaml(k.to_dict(), os.path.join(base, "kvalue.yaml"))
    windows = {w["name"]: tables[w["name"]] for w in vehicle.windows["identification"]}
    result = VehicleResult(vehicle=vehicle, tables=tables, kvalue=k)
    k_stage = None if k is None else k.to_dict()
    storage = storage_corrected_k(windows, tables.get("kvalue"), vehicle.data, k_stage)
    for key in keys:
        model = fitsettings.model_key(key)
        try:
            terms = prior_terms if fitsettings.split_key(model)[0] == "order2" else ()
            estimate, series = identify.identify(
                windows, vehicle.data, k_stage, model, storage, prior_terms=terms
            )
        except ConfigError as err:
            if err.file != f"vehicle {vehicle.id}":
                raise
            raise ConfigError(vehicle.path, err.key, err.value, err.reason) from None
        fit = Fit.of(quality.check(estimate, series, vehicle.data["check"]), series)
        if base is not None:
            rt_io.write_estimate(estimate, os.path.join(base, "identify", f"{model}.yaml"))
            ingest.write_tidy(series, os.path.join(base, "identify", f"{model}_series.csv"))
            fit.write(os.path.join(base, f"fit_{model}.yaml"))
        result.fits[model] = fit
    return result
