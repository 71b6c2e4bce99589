"""The interior-envelope model: the air node (with the interior, capacity C) is linked through
K_i to an envelope node (C_e), which alone is linked through K_o to the outdoor air; heating
enters the air node. The building literature's TiTe model and pySIP's TwTi_RoRi (R_i = 1/K_i,
R_o = 1/K_o).

    C dT/dt = K_i (T_e - T) + Q_H,   C_e dT_e/dt = K_i (T - T_e) + K_o (T_o - T_e)

Unlike eq. 14 every loss passes the envelope; the paper's overall kA is K_i K_o / (K_i + K_o).
"""

import numpy as np

from railtherm.structures._structure import Structure


def matrices(C: float, K_i: float, C_e: float, K_o: float) -> tuple[np.ndarray, np.ndarray]:
    """(A, B), states x = [T, T_e], inputs u = [T_o, Q_H]."""
    A = np.array([[-K_i / C, K_i / C], [K_i / C_e, -(K_i + K_o) / C_e]])
    B = np.array([[0.0, 1.0 / C], [K_o / C_e, 0.0]])
    return A, B


def derivatives(C: float, K_i: float, C_e: float, K_o: float) -> dict:
    """Analytic d(A, B)/d(C, K_i, C_e, K_o) of :func:`matrices`."""
    z = np.zeros((2, 2))
    return {
        "C": (
            np.array([[K_i / C**2, -K_i / C**2], [0.0, 0.0]]),
            np.array([[0.0, -1 / C**2], [0, 0]]),
        ),
        "K_i": (np.array([[-1 / C, 1 / C], [1 / C_e, -1 / C_e]]), z.copy()),
        "C_e": (
            np.array([[0.0, 0.0], [-K_i / C_e**2, (K_i + K_o) / C_e**2]]),
            np.array([[0.0, 0.0], [-K_o / C_e**2, 0.0]]),
        ),
        "K_o": (np.array([[0.0, 0.0], [0.0, -1 / C_e]]), np.array([[0.0, 0.0], [1 / C_e, 0.0]])),
    }


STRUCTURE = Structure(
    title="interior-envelope model",
    parameters=("C", "K_i", "C_e", "K_o"),
    states=("T", "T_e"),
    build=matrices,
    jacobian=derivatives,
    # start: the paper's capacities (section 5.3), an envelope 10 times tighter to the air
    # than to the outdoors is not assumed: both conductances start equal
    initial={"C": 120_480.0, "K_i": 1000.0, "C_e": 500_000.0, "K_o": 1000.0},
    bounds={
        "C": (1.0e4, 1.0e10),
        "K_i": (1.0e-1, 1.0e7),
        "C_e": (1.0e4, 1.0e10),
        "K_o": (1.0e-1, 1.0e6),
    },
    equations="interior-envelope (TiTe, pySIP TwTi_RoRi)",
    capacities=("C", "C_e"),
    conductances=("K_i", "K_o"),
    envelope="C_e",
    coupled=("C", "K_i", "C_e", "K_o"),
    totals={"C_total": ("C", "C_e")},
    descriptions={
        "C": "heat capacity of the air node with the interior",
        "K_i": "conductance between the air and the envelope",
        "C_e": "heat capacity of the envelope",
        "K_o": "conductance between the envelope and the outdoor air",
    },
    # T_e is measured only where model.envelope_sensors names its sensors
    sensors={"T": "T"},
    loss_path=("K_i", "K_o"),
    kA_expression="K_i K_o / (K_i + K_o)",
    # K_i -> infinity makes air and envelope one node: the first-order model
    nests={"order1": 1},
)
