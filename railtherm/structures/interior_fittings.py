"""The second-order model with a third node for the interior fittings (seats, panels, floor
covering): the air node T exchanges K_f with the fittings T_f (capacity C_f), which touch
nothing else; the air and the body are as in eqs. 7-8.

    C dT/dt = Q_H - kA (T - T_o) - K_veh (T - T_veh) - K_f (T - T_f)
    C_veh dT_veh/dt = K_veh (T - T_veh)
    C_f dT_f/dt = K_f (T - T_f)

The fittings are seldom instrumented: T_f is estimated, never compared. With K_f -> 0 the
fittings decouple and the structure is the second-order model.
"""

import numpy as np

from railtherm.structures._structure import Structure


def matrices(
    kA: float, C: float, K_veh: float, C_veh: float, K_f: float, C_f: float
) -> tuple[np.ndarray, np.ndarray]:
    """(A, B), states x = [T, T_veh, T_f], inputs u = [T_o, Q_H]."""
    A = np.array(
        [
            [-(kA + K_veh + K_f) / C, K_veh / C, K_f / C],
            [K_veh / C_veh, -K_veh / C_veh, 0.0],
            [K_f / C_f, 0.0, -K_f / C_f],
        ]
    )
    B = np.array([[kA / C, 1.0 / C], [0.0, 0.0], [0.0, 0.0]])
    return A, B


def derivatives(kA: float, C: float, K_veh: float, C_veh: float, K_f: float, C_f: float) -> dict:
    """Analytic d(A, B)/d(theta) of :func:`matrices`."""
    zA, zB = np.zeros((3, 3)), np.zeros((3, 2))

    def dA(entries):
        out = zA.copy()
        for (i, j), v in entries.items():
            out[i, j] = v
        return out

    return {
        "kA": (dA({(0, 0): -1.0 / C}), np.array([[1.0 / C, 0.0], [0, 0], [0, 0]])),
        "C": (
            dA({(0, 0): (kA + K_veh + K_f) / C**2, (0, 1): -K_veh / C**2, (0, 2): -K_f / C**2}),
            np.array([[-kA / C**2, -1.0 / C**2], [0, 0], [0, 0]]),
        ),
        "K_veh": (
            dA({(0, 0): -1 / C, (0, 1): 1 / C, (1, 0): 1 / C_veh, (1, 1): -1 / C_veh}),
            zB.copy(),
        ),
        "C_veh": (dA({(1, 0): -K_veh / C_veh**2, (1, 1): K_veh / C_veh**2}), zB.copy()),
        "K_f": (dA({(0, 0): -1 / C, (0, 2): 1 / C, (2, 0): 1 / C_f, (2, 2): -1 / C_f}), zB.copy()),
        "C_f": (dA({(2, 0): -K_f / C_f**2, (2, 2): K_f / C_f**2}), zB.copy()),
    }


STRUCTURE = Structure(
    title="second-order model with interior fittings",
    parameters=("kA", "C", "K_veh", "C_veh", "K_f", "C_f"),
    states=("T", "T_veh", "T_f"),
    build=matrices,
    jacobian=derivatives,
    # the paper's start (section 5.3) for the first four; fittings a fifth of the body's
    initial={
        "kA": 1000.0,
        "C": 120_480.0,
        "K_veh": 20.0,
        "C_veh": 500_000.0,
        "K_f": 200.0,
        "C_f": 100_000.0,
    },
    bounds={
        "kA": (1.0, 1.0e6),
        "C": (1.0e4, 1.0e10),
        "K_veh": (1.0e-2, 1.0e7),
        "C_veh": (1.0e4, 1.0e10),
        "K_f": (1.0e-2, 1.0e7),
        "C_f": (1.0e4, 1.0e10),
    },
    equations="eqs. 7-8 with a fittings node",
    capacities=("C", "C_veh", "C_f"),
    conductances=("kA", "K_veh", "K_f"),
    envelope="C_veh",
    coupled=("C", "K_veh", "C_veh", "K_f", "C_f"),
    totals={"C_total": ("C", "C_veh", "C_f")},
    descriptions={
        "kA": "overall heat-loss coefficient (eq. 10)",
        "C": "heat capacity of the air node",
        "K_veh": "conductance between the air and the vehicle's body",
        "C_veh": "heat capacity of the vehicle's body",
        "K_f": "conductance between the air and the interior fittings",
        "C_f": "heat capacity of the interior fittings",
    },
    sensors={"T": "T", "T_veh": "T_veh"},
    # K_f -> 0 decouples the fittings: the second-order model
    nests={"order2": 1},
)
