"""The one chain the tests run a vehicle through, as the workflow's rules do: clean, static k,
identify, check (:func:`railtherm.study.run.fit_vehicle`, which ``railtherm fit`` runs too)."""

from __future__ import annotations

import os
from pathlib import Path

from railtherm.config import Vehicle, load_vehicle
from railtherm.study.run import VehicleResult, fit_vehicle


def checked_fits(
    vehicle: Vehicle | str | os.PathLike[str],
    models: list[str] | None = None,
    workdir: str | os.PathLike[str] = ".",
) -> VehicleResult:
    """A vehicle (or its file) through the chain: its tidy tables, static k and checked fits
    of ``models`` (default: every model its config asks for)."""
    if not isinstance(vehicle, Vehicle):
        vehicle = load_vehicle(Path(vehicle), workdir=workdir)
    return fit_vehicle(vehicle, models=models, workdir=workdir)


def checked_fit(
    vehicle: Vehicle | str | os.PathLike[str], model: str, workdir: str | os.PathLike[str] = "."
) -> tuple[dict, dict]:
    """(the checked fit of ``model`` as fit_<model>.yaml holds it, the tidy tables)."""
    result = checked_fits(vehicle, [model], workdir)
    return result.fits[model].to_dict(), result.tables
