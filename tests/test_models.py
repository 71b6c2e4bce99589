"""railtherm.models: the paper's structures (eqs. 13, 14) and exact ZOH discretisation."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from railtherm import models


def test_zoh_matches_analytic_first_order_step_response():
    """Eq. 9 under a constant input: T(t) = T_inf + (T0 - T_inf) exp(-kA t / C_bar)."""
    kA, C_bar, T_o, Q_H, T0, dt = 900.0, 2.0e7, -10.0, 30_000.0, -10.0, 600.0
    Ad, Bd = models.discretize_zoh(*models.first_order(kA, C_bar), dt)
    T, u = np.array([T0]), np.array([T_o, Q_H])
    T_inf = T_o + Q_H / kA
    for n in range(1, 200):
        T = Ad @ T + Bd @ u
        expected = T_inf + (T0 - T_inf) * np.exp(-kA * n * dt / C_bar)
        assert T[0] == pytest.approx(expected, rel=1e-12, abs=1e-12)


def test_second_order_steady_state_is_static_model():
    """At rest both states settle at T_o + Q_H / kA (eq. 10): the models are consistent."""
    A, B = models.second_order(kA=950.0, C=3.0e7, K_veh=246.0, C_veh=1.7e7)
    x = models.steady_state(A, B, np.array([-5.0, 19_000.0]))
    np.testing.assert_allclose(x, [-5.0 + 19_000.0 / 950.0] * 2, rtol=1e-12)


@given(
    kA=st.floats(100, 2000),
    C=st.floats(1e5, 5e7),
    K_veh=st.floats(1, 1e5),
    C_veh=st.floats(1e6, 5e7),
    dt=st.floats(1, 3600),
)
def test_zoh_composes_over_steps(kA, C, K_veh, C_veh, dt):
    """Two half steps equal one full step under a held input (exactness, not an approximation)."""
    A, B = models.second_order(kA, C, K_veh, C_veh)
    Ad, Bd = models.discretize_zoh(A, B, dt)
    Ah, Bh = models.discretize_zoh(A, B, dt / 2)
    np.testing.assert_allclose(Ah @ Ah, Ad, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(Ah @ Bh + Bh, Bd, rtol=1e-9, atol=1e-12)


def test_second_order_matrices_follow_eq_14():
    A, B = models.second_order(kA=2.0, C=4.0, K_veh=6.0, C_veh=3.0)
    np.testing.assert_array_equal(A, [[-2.0, 1.5], [2.0, -2.0]])
    np.testing.assert_array_equal(B, [[0.5, 0.25], [0.0, 0.0]])
