"""railtherm: heat capacities and heat-transfer coefficients of rail vehicles.

A plain Python library (no workflow engine inside) implementing the two-capacity thermal
model of Hofstaedter et al. (first order eq. 9, second order eqs. 7-8), the virtual climatic
wind tunnel that synthesises campaigns from declared ground truth, and the estimation stages.

The entry points, importable from here (loaded on first use, so that ``import railtherm``
stays cheap): :func:`load_vehicle` (a validated vehicle config), :func:`fit_vehicle` (one
vehicle through clean, static k, fit and check), :class:`Fit` and :func:`read_fit` (a
checked fit: parameters, verdict, ``to_statespace()``, ``simulate()``), and the typed record
of a fit file it builds on (:class:`FitRecord`, :class:`ParameterEstimate`).
"""

from importlib import import_module
from typing import Any

from railtherm.errors import ConfigError, DataError, RailthermError

__version__ = "0.1.0"
_LAZY = {
    "load_vehicle": "railtherm.config",
    "load_study": "railtherm.config",
    "Vehicle": "railtherm.config",
    "Study": "railtherm.config",
    "KValue": "railtherm.estimation.kvalue",
    "Fit": "railtherm.study.fit",
    "read_fit": "railtherm.study.fit",
    "StateSpace": "railtherm.study.fit",
    "FitRecord": "railtherm.records",
    "ParameterEstimate": "railtherm.records",
    "fit_vehicle": "railtherm.study.run",
}
__all__ = ["ConfigError", "DataError", "RailthermError", "__version__", *_LAZY]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'railtherm' has no attribute {name!r}")
