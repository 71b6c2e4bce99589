"""What a planned programme does to the vehicle, against what the tunnel and the vehicle allow:
the highest cabin-air and body temperatures (simulated for every parameter set of the prior,
read at its upper band), and whether the static k window at the first phase's end is steady.

A programme the design searches propose (:func:`railtherm.study.design.best_of_length`,
:func:`railtherm.study.design.shortest`) keeps the cabin air at most ``limits.max_T_C`` and
the body at most ``limits.max_T_veh_C`` at the prior's upper band (the 97.5 % quantile of the
peak over its draws); an assessed programme beyond them is flagged.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from railtherm.estimation import models
from railtherm.study.programme import (
    Programme,
    initial_state,
    k_window_rows,
    programme_inputs,
)

__all__ = [
    "LIMIT_KEYS",
    "UPPER_BAND",
    "k_window_storage_share",
    "peaks",
    "temperature_limits",
    "violations",
]

UPPER_BAND = 0.975  # the quantile of the peak over the prior's draws a limit is held at
LIMIT_KEYS = {"T": "max_T_C", "T_veh": "max_T_veh_C"}  # state -> its key under limits
WHAT = {"T": "the cabin air", "T_veh": "the car body"}
NOT_STEADY_SHARE = 0.02  # stored share of the k window's heat that flags it as not steady


def temperature_limits(programme: Programme) -> dict[str, float]:
    """{state: the hottest it may get (degC)} as the programme's limits declare."""
    return {s: float(programme.limits[k]) for s, k in LIMIT_KEYS.items() if k in programme.limits}


def _record(structure: models.Structure, theta: Mapping[str, float], programme: Programme):
    u = programme_inputs(programme, structure, theta)
    x0 = initial_state(programme, structure, theta, u[0])
    return u, models.simulate(structure, theta, u, programme.step_s, x0)


def peaks(
    structure: models.Structure,
    thetas: Sequence[Mapping[str, float]],
    programme: Programme,
) -> dict[str, float]:
    """Each state's highest temperature over the programme (degC), at the upper band
    (:data:`UPPER_BAND`) over the parameter sets ``thetas`` (one set: its own peak). A set
    whose simulation is not finite is left out."""
    found: dict[str, list[float]] = {s: [] for s in structure.states}
    for theta in thetas:
        try:
            with np.errstate(all="ignore"):
                _, x = _record(structure, theta, programme)
        except FloatingPointError:  # exp(A dt) overflows: no finite simulation either
            continue
        if not np.all(np.isfinite(x)):
            continue
        for i, s in enumerate(structure.states):
            found[s].append(float(np.max(x[:, i])))
    return {
        s: float(np.quantile(v, UPPER_BAND, method="inverted_cdf")) if v else math.nan
        for s, v in found.items()
    }


def violations(highest: Mapping[str, float], programme: Programme) -> list[str]:
    """Sentences for each temperature limit the peaks ``highest`` (:func:`peaks`) exceed."""
    out = []
    for state, limit in temperature_limits(programme).items():
        peak = highest.get(state, math.nan)
        if not peak <= limit:
            out.append(
                f"{WHAT.get(state, state)} reaches {peak:.1f} degC at the prior's upper band "
                f"({100 * UPPER_BAND:g} % of its draws below), above limits."
                f"{LIMIT_KEYS[state]} {limit:g} degC"
            )
    return out


def k_window_storage_share(
    structure: models.Structure, theta: Mapping[str, float], programme: Programme
) -> float:
    """The share of the heat supplied over the static k window that goes into storage (the
    change of C T + C_veh T_veh; the rest is lost through kA), at ``theta``: 0 for a window
    at steady state; eq. 10 books it as loss."""
    a, b = k_window_rows(programme)
    u, x = _record(structure, theta, programme)
    supplied = float(np.sum(u[a : b - 1, 1])) * programme.step_s
    if "kA" not in theta or not supplied > 0:
        return math.nan
    excess = x[a:b, 0] - u[a:b, 0]
    lost = float(theta["kA"]) * float(np.sum((excess[1:] + excess[:-1]) / 2.0)) * programme.step_s
    return (supplied - lost) / supplied
