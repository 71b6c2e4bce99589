"""railtherm: heat capacities and heat-transfer coefficients of rail vehicles.

A plain Python library (no workflow engine inside) implementing the two-capacity thermal
model of Hofstaedter et al. (first order eq. 9, second order eqs. 7-8), the virtual climatic
wind tunnel that synthesises campaigns from declared ground truth, and the estimation stages.
"""

from railtherm.errors import ConfigError, DataError, RailthermError

__version__ = "0.1.0"
__all__ = ["ConfigError", "DataError", "RailthermError", "__version__"]
