"""Grey-box state-space structures of the paper (section 5.1) and their exact discretisation.

Inputs are always u = [T_o, Q_H] (degC, W); outputs y = x (C = I, D = 0, eqs. 11-12).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm


def first_order(kA: float, C_bar: float) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) of the first-order model, eq. 13: C_bar dT/dt = Q_H - kA (T - T_o) (eq. 9)."""
    A = np.array([[-kA / C_bar]])
    B = np.array([[kA / C_bar, 1.0 / C_bar]])
    return A, B


def second_order(kA: float, C: float, K_veh: float, C_veh: float) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) of the second-order model, eq. 14, with states x = [T, T_veh] (eqs. 7-8)."""
    A = np.array(
        [
            [-(kA + K_veh) / C, K_veh / C],
            [K_veh / C_veh, -K_veh / C_veh],
        ]
    )
    B = np.array([[kA / C, 1.0 / C], [0.0, 0.0]])
    return A, B


def discretize_zoh(A: np.ndarray, B: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretisation: expm([[A, B], [0, 0]] dt) = [[Ad, Bd], [0, I]]."""
    A = np.atleast_2d(np.asarray(A, dtype=float))
    B = np.atleast_2d(np.asarray(B, dtype=float))
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n] = A
    M[:n, n:] = B
    E = expm(M * dt)
    return E[:n, :n], E[:n, n:]


def steady_state(A: np.ndarray, B: np.ndarray, u: np.ndarray) -> np.ndarray:
    """The equilibrium x* = -A^-1 B u for a constant input u."""
    return -np.linalg.solve(np.atleast_2d(A), np.atleast_2d(B) @ np.asarray(u, dtype=float))
