"""The first-order model of the paper, eq. 9: one node, the air with everything in
equilibrium with it, C_bar dT/dt = Q_H - kA (T - T_o); (A, B) of eq. 13."""

import numpy as np

from railtherm.structures._structure import Structure


def matrices(kA: float, C_bar: float) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) of eq. 13, state x = [T], inputs u = [T_o, Q_H]."""
    A = np.array([[-kA / C_bar]])
    B = np.array([[kA / C_bar, 1.0 / C_bar]])
    return A, B


def derivatives(kA: float, C_bar: float) -> dict:
    """d(A, B)/d(kA, C_bar) of eq. 13."""
    return {
        "kA": (np.array([[-1.0 / C_bar]]), np.array([[1.0 / C_bar, 0.0]])),
        "C_bar": (
            np.array([[kA / C_bar**2]]),
            np.array([[-kA / C_bar**2, -1.0 / C_bar**2]]),
        ),
    }


STRUCTURE = Structure(
    order=1,
    title="first-order model (eq. 9)",
    parameters=("kA", "C_bar"),
    states=("T",),
    build=matrices,
    jacobian=derivatives,
    # the paper's start (section 5.3): C_bar = C + C_veh of its second-order start
    initial={"kA": 1000.0, "C_bar": 120_480.0 + 500_000.0},
    bounds={"kA": (1.0, 1.0e6), "C_bar": (1.0e4, 1.0e10)},
    equations="eq. 9, eq. 13",
    air="C_bar",
    capacities=("C_bar",),
    conductances=("kA",),
    descriptions={
        "kA": "overall heat-loss coefficient (eq. 10)",
        "C_bar": "heat capacity of the one node, air and vehicle together",
    },
    sensors={"T": "T"},
)
