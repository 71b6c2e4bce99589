"""The second-order model of the paper, eqs. 7-8: the air node T (capacity C) loses kA to the
outdoors and exchanges K_veh with the vehicle's body T_veh (capacity C_veh); (A, B) of eq. 14.

    C dT/dt = Q_H - kA (T - T_o) - K_veh (T - T_veh),   C_veh dT_veh/dt = K_veh (T - T_veh)
"""

import numpy as np

from railtherm.structures._structure import Structure


def matrices(kA: float, C: float, K_veh: float, C_veh: float) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) of eq. 14, states x = [T, T_veh] (eqs. 7-8), inputs u = [T_o, Q_H]."""
    A = np.array(
        [
            [-(kA + K_veh) / C, K_veh / C],
            [K_veh / C_veh, -K_veh / C_veh],
        ]
    )
    B = np.array([[kA / C, 1.0 / C], [0.0, 0.0]])
    return A, B


def derivatives(kA: float, C: float, K_veh: float, C_veh: float) -> dict:
    """d(A, B)/d(kA, C, K_veh, C_veh) of eq. 14."""
    z = np.zeros((2, 2))
    return {
        "kA": (np.array([[-1.0 / C, 0.0], [0.0, 0.0]]), np.array([[1.0 / C, 0.0], [0.0, 0.0]])),
        "C": (
            np.array([[(kA + K_veh) / C**2, -K_veh / C**2], [0.0, 0.0]]),
            np.array([[-kA / C**2, -1.0 / C**2], [0.0, 0.0]]),
        ),
        "K_veh": (
            np.array([[-1.0 / C, 1.0 / C], [1.0 / C_veh, -1.0 / C_veh]]),
            z.copy(),
        ),
        "C_veh": (
            np.array([[0.0, 0.0], [-K_veh / C_veh**2, K_veh / C_veh**2]]),
            z.copy(),
        ),
    }


STRUCTURE = Structure(
    order=2,
    title="second-order model (eqs. 7-8)",
    parameters=("kA", "C", "K_veh", "C_veh"),
    states=("T", "T_veh"),
    build=matrices,
    jacobian=derivatives,
    # the paper's start (section 5.3; K_veh printed as "20 J/K", a conductance in W/K)
    initial={"kA": 1000.0, "C": 120_480.0, "K_veh": 20.0, "C_veh": 500_000.0},
    # C bounded below: C -> 0 is a false optimum (the air node reacting instantly)
    bounds={
        "kA": (1.0, 1.0e6),
        "C": (1.0e4, 1.0e10),
        "K_veh": (1.0e-2, 1.0e7),
        "C_veh": (1.0e4, 1.0e10),
    },
    equations="eqs. 7-8, eq. 14",
    capacities=("C", "C_veh"),
    conductances=("kA", "K_veh"),
    envelope="C_veh",
    coupled=("C", "K_veh", "C_veh"),
    totals={"C_total": ("C", "C_veh")},
    descriptions={
        "kA": "overall heat-loss coefficient (eq. 10)",
        "C": "heat capacity of the air node",
        "K_veh": "conductance between the air and the vehicle's body",
        "C_veh": "heat capacity of the vehicle's body",
    },
    sensors={"T": "T", "T_veh": "T_veh"},
    # K_veh -> 0 decouples the body: the first-order model with C_bar = C
    nests={"order1": 1},
)
