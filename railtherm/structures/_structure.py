"""The :class:`Structure` every module of :mod:`railtherm.structures` declares: a grey-box
thermal network dx/dt = A(theta) x + B(theta) u, y = x (eqs. 11-12), with everything the
pipeline needs to know about it in one place."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

CAPACITY_UNIT = "J/K"
CONDUCTANCE_UNIT = "W/K"


@dataclass(frozen=True, kw_only=True)
class Structure:
    """A grey-box structure dx/dt = A(theta) x + B(theta) u, u = ``inputs`` (T_o, Q_H, then
    any irradiance channels of :func:`railtherm.estimation.models.with_irradiance`), y = x.

    ``build(**theta) -> (A, B)`` and ``jacobian(**theta) -> {param: (dA, dB)}`` take the
    parameters by name; ``initial`` holds the start values (the paper's, section 5.3) and
    ``bounds`` loose default bounds (SI units) for parameters the caller does not bound;
    ``air`` names the air node's capacity, the parameter through which heating and any solar
    gain enter the air node (state 0): B[0, 1] = 1 / theta[air]. ``capacities`` (J/K) and
    ``conductances`` (W/K) name the parameters of each kind: the automatic start of
    :func:`railtherm.estimation.pem.fit` scales them to the data (the time constants C / K and the
    overall kA of eq. 10); any other parameter (an aperture, m2) is neither. ``envelope``
    names the envelope node's capacity (state 1: C_veh of T_veh, C_e of T_e), through which
    solar gain declared on the envelope enters, B[1, j] = a_j / theta[envelope]; empty for a
    one-node structure.

    ``coupled`` names the parameters of the dynamic part (the capacities and the internal
    conductance between the nodes) that the data determine only together: when one of them
    is not identified (at a bound of the search, or an interval too wide), none of the group
    is reported as an estimate. ``totals`` names each combination the data do determine
    however the capacity splits between the nodes, as {name: the parameters summed}: the
    total capacity C_total = C + C_veh of eqs. 7-8, the C_bar of eq. 9 (the first-order model
    lumps both nodes into one).

    The rest tells the pipeline how to use the structure:

    - ``name``: the module's file name (set by the registry, :mod:`railtherm.structures`);
    - ``order``: the paper's model order it is (``model.orders``: 1, 2), its model key then
      ``order<n>``; None for a further structure, asked for by ``model.structures: [name]``;
    - ``title``: how figures and tables name it; ``descriptions``: a phrase per parameter;
    - ``sensors``: {state: the tidy column that measures it}; a state not listed is measured
      only where ``model.envelope_sensors`` says so (the envelope state), else estimated;
    - ``loss_path``: without a parameter kA, the conductances in series from the air to the
      outdoors (the overall kA, :meth:`overall_kA`, is their series value; a joint fit starts
      each at len(loss_path) times the record's kA) and ``kA_expression`` how kA follows;
    - ``nests``: {key of a smaller structure: the number of this structure's parameters on
      the boundary of its search where it reduces to that one}: the likelihood-ratio tests
      of the model selection (:func:`railtherm.estimation.diagnostics.forward_selection`).
    """

    parameters: tuple[str, ...]
    states: tuple[str, ...]
    build: Callable[..., tuple[np.ndarray, np.ndarray]] = field(repr=False)
    jacobian: Callable[..., dict] = field(repr=False)
    name: str = ""
    inputs: tuple[str, ...] = ("T_o", "Q_H")
    initial: Mapping[str, float] = field(default_factory=dict)
    bounds: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    equations: str = ""
    air: str = "C"
    capacities: tuple[str, ...] = ()
    conductances: tuple[str, ...] = ()
    envelope: str = ""
    coupled: tuple[str, ...] = ()
    totals: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    order: int | None = None
    title: str = ""
    descriptions: Mapping[str, str] = field(default_factory=dict)
    sensors: Mapping[str, str] = field(default_factory=dict)
    loss_path: tuple[str, ...] = ()
    kA_expression: str = ""
    nests: Mapping[str, int] = field(default_factory=dict)

    @property
    def key(self) -> str:
        """The model key of config files and result names: order<n> for the paper's orders,
        else the structure's name (fit_<key>.yaml, fit_<key>_kalman.yaml)."""
        return f"order{self.order}" if self.order else self.name.split("+")[0]

    def unit(self, parameter: str) -> str:
        """J/K for a capacity, W/K for a conductance, m2 for an aperture a_<name>, else ''."""
        if parameter in self.capacities:
            return CAPACITY_UNIT
        if parameter in self.conductances:
            return CONDUCTANCE_UNIT
        return "m²" if parameter.startswith("a_") else ""

    def _theta(self, theta: Mapping[str, float]) -> dict:
        missing = [p for p in self.parameters if p not in theta]
        if missing:
            raise KeyError(f"structure {self.name!r} needs parameters {missing}")
        return {p: float(theta[p]) for p in self.parameters}

    def matrices(self, theta: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray]:
        """Continuous (A, B) at ``theta`` (a mapping with at least every parameter)."""
        return self.build(**self._theta(theta))

    def derivatives(self, theta: Mapping[str, float]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Analytic {param: (dA/dparam, dB/dparam)} at ``theta``."""
        return self.jacobian(**self._theta(theta))

    def overall_kA(self, theta: Mapping[str, float]) -> float:
        """The overall heat-loss coefficient (W/K) at ``theta``: the parameter kA where the
        structure has one, else from the steady state (:meth:`kA_log_gradient`). NaN when the
        network has no steady state."""
        if "kA" in self.parameters:
            return float(theta["kA"])
        return self.kA_log_gradient(theta)[0]

    def kA_log_gradient(self, theta: Mapping[str, float]) -> tuple[float, dict[str, float]]:
        """(kA, {param: d log kA / d log param}) from the steady state. Eq. 10, Q_H = kA (T -
        T_o), holds at equilibrium, so kA = 1 / g with the gain g = dT/dQ_H = -(A^-1 B)[0, 1]
        (heating enters the air node, state 0); dg = (A^-1 dA A^-1 B - A^-1 dB)[0, 1] from the
        analytic derivatives, exact for any network. kA K_i K_o / (K_i + K_o) for losses in
        series. (NaN, {}) without a steady state."""
        A, B = self.matrices(theta)
        try:
            AiB = np.linalg.solve(A, B)  # the gain from a solve, as the fits' starts have it
            Ai = np.linalg.inv(A)
        except np.linalg.LinAlgError:
            return math.nan, {}
        g = -float(AiB[0, 1])
        if not (g > 0 and math.isfinite(g)):
            return math.nan, {}
        gradient = {}
        for p, (dA, dB) in self.derivatives(theta).items():
            dg = float((Ai @ dA @ AiB - Ai @ dB)[0, 1])
            slope = -float(theta[p]) * dg / g  # d log kA = -d log g
            gradient[p] = slope if abs(slope) > 1e-12 else 0.0  # rounding of an exact zero
        return 1.0 / g, gradient
