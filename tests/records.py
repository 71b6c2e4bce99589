"""Records of the second-order model (eqs. 7-8) shared by the estimators' tests and benchmarks."""

import numpy as np

from railtherm.estimation import models

S2 = models.STRUCTURES["second_order"]
# the campaign's Tram2 (W/K, J/K)
TRAM2 = {"kA": 979.2, "C": 1.8e7, "K_veh": 974.0, "C_veh": 1.0e7}


def noisy_power_record(seed: int, sd: float = 1000.0, n: int = 1800):
    """A 30 h step record of Tram2 without process noise at a 60 s step (Q_H 20 -> 29 kW
    after 2 h, T_o -10 degC; T measured with 0.02 K white noise, T_veh not), whose measured
    Q_H carries white noise of ``sd`` W. Returns the true inputs, the measured inputs and
    the outputs (T, T_veh = NaN)."""
    u0 = np.column_stack([np.full(n, -10.0), np.where(np.arange(n) < 120, 20_000.0, 29_000.0)])
    x = models.simulate(S2, TRAM2, u0, 60.0, models.steady_state(*S2.matrices(TRAM2), u0[0]))
    rng = np.random.default_rng(seed)
    y = np.column_stack([x[:, 0] + rng.normal(0.0, 0.02, n), np.full(n, np.nan)])
    u = u0 + np.column_stack([np.zeros(n), rng.normal(0.0, sd, n)])
    return u0, u, y
