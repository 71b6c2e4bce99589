"""A checked fit of one grey-box model to one vehicle, as an object.

:class:`Fit` is what ``fit_<model>.yaml`` holds (the rule ``check``'s output): the parameters
with their 95 % intervals and the explicit "not identified" state, the flags, the fit
measures (R^2 of eq. 21) and the verdict; with the identified model as a continuous
state-space system (:meth:`Fit.to_statespace`, eqs. 7-8 or 9) and a simulator
(:meth:`Fit.simulate`, exact zero-order hold as in eq. 15). :func:`read_fit` and
:meth:`Fit.write` are the one place the file is read and written.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from railtherm import io as results_io
from railtherm.estimation import models, outliers
from railtherm.study import identifiability


@dataclass(frozen=True)
class Parameter:
    """One parameter of a fit (SI units). ``estimated``: True (by PEM), False (fixed, e.g. kA
    from the static test, eq. 10) or "derived" (kA of losses in series). ``ci95`` is the
    combined 95 % interval (statistical and systematic), None for a fixed parameter.
    ``identified`` is False where the data do not determine the value: then ``limit``
    ("upper" | "lower" | "none") and ``limit_value`` say what the data do bound, ``reason``
    why (a bound of the search, an interval too wide, or coupled to such a parameter)."""

    name: str
    value: float
    estimated: bool | str
    ci95: tuple[float, float] | None = None
    identified: bool = True
    limit: str | None = None
    limit_value: float | None = None
    reason: str = ""

    @classmethod
    def from_entry(cls, name: str, entry: Mapping[str, Any]) -> Parameter:
        ident = identifiability.parameter_identification(entry)
        ci = entry.get("ci95")
        return cls(
            name=name,
            value=float(entry["value"]),
            estimated=entry.get("estimated", True),
            ci95=None if ci is None else (float(ci[0]), float(ci[1])),
            identified=bool(ident["identified"]),
            limit=ident.get("limit"),
            limit_value=ident.get("limit_value"),
            reason=str(ident.get("reason", "")),
        )

    def __str__(self) -> str:
        if not self.identified:
            if self.limit in ("upper", "lower") and self.limit_value is not None:
                side = {"upper": "at most", "lower": "at least"}[self.limit]
                return f"{self.name}: not identified ({side} {self.limit_value:.3g})"
            return f"{self.name}: not identified ({self.reason or 'no limit the data give'})"
        if self.ci95 is None:
            return f"{self.name} = {self.value:.4g} (fixed)"
        return f"{self.name} = {self.value:.4g} [{self.ci95[0]:.4g}, {self.ci95[1]:.4g}]"


@dataclass(frozen=True)
class StateSpace:
    """dx/dt = A x + B u, y = C x + D u (continuous time, SI units), with the names of the
    states x, inputs u and outputs y: the identified model for any other tool (python-control,
    MATLAB's ss). Every state is an output (the model's temperatures)."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    states: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]

    def discretize(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """(A_d, B_d) of the exact zero-order-hold discretisation over ``dt`` s (eq. 15)."""
        return models.discretize_zoh(self.A, self.B, dt)


@dataclass
class Fit:
    """A checked fit: ``data`` is the content of ``fit_<model>.yaml``; ``series`` the
    measured and simulated states per window (time, T, T_sim, ..., inputs), when known."""

    data: dict[str, Any]
    series: pd.DataFrame | None = field(default=None, repr=False)

    # --- what the tables print
    @property
    def vehicle(self) -> str:
        return str(self.data["vehicle"])

    @property
    def model(self) -> str:
        return str(self.data["model"])

    @property
    def verdict(self) -> str:
        return str(self.data["verdict"])

    @property
    def reasons(self) -> list[str]:
        return list(self.data.get("reasons", []))

    @property
    def flags(self) -> list[dict[str, Any]]:
        return list(self.data.get("flags", []))

    @property
    def R2(self) -> float:
        """R^2 of the simulated T over every window (eq. 21)."""
        return float(self.data["R2"])

    @property
    def k_source(self) -> str:
        return str(self.data["k_source"])

    @property
    def parameters(self) -> dict[str, Parameter]:
        return {p: Parameter.from_entry(p, e) for p, e in self.data["parameters"].items()}

    @property
    def hold(self) -> str:
        """How the inputs ran between samples in the fit ("zero_order": eq. 15, or
        "first_order"); a simulation of the model uses the same discretisation."""
        return str(self.data.get("input_hold", "zero_order"))

    @property
    def theta(self) -> dict[str, float]:
        """Every parameter's value by name (identified or not: the model as fitted)."""
        return {p: float(e["value"]) for p, e in self.data["parameters"].items()}

    # --- the model
    @property
    def structure(self) -> models.Structure:
        """The grey-box structure, with the irradiance inputs it was fitted with."""
        base, *irradiance = str(self.data["structure"]).split("+")
        return models.structure_for(base, irradiance)

    def to_statespace(self) -> StateSpace:
        """The identified model as (A, B, C, D): eqs. 7-8 (second order), eq. 9 (first order)
        or the interior-envelope structure, inputs T_o, Q_H and any irradiance."""
        s = self.structure
        A, B = s.matrices(self.theta)
        n, m = B.shape
        return StateSpace(
            A=A,
            B=B,
            C=np.eye(n),
            D=np.zeros((n, m)),
            states=tuple(s.states),
            inputs=tuple(s.inputs),
            outputs=tuple(s.states),
        )

    def simulate(
        self,
        u: pd.DataFrame | np.ndarray,
        dt: float,
        x0: Sequence[float] | None = None,
    ) -> pd.DataFrame:
        """The states for inputs ``u`` (rows every ``dt`` s; columns T_o, Q_H and any
        irradiance, by name if a DataFrame) under the fit's input hold (:attr:`hold`: held
        over each step, eq. 15, or linear between rows), from ``x0`` (default: the steady
        state of the first input row). Returns time and states."""
        s = self.structure
        if isinstance(u, pd.DataFrame):
            missing = [c for c in s.inputs if c not in u.columns]
            if missing:
                raise ValueError(
                    f"simulate needs input columns {list(s.inputs)}; missing {missing}"
                )
            u = u[list(s.inputs)].to_numpy(float)
        u = np.atleast_2d(np.asarray(u, dtype=float))
        if u.shape[1] != len(s.inputs):
            raise ValueError(f"u has {u.shape[1]} columns; the model's inputs are {s.inputs}")
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a positive number of seconds, got {dt!r}")
        theta = self.theta
        if x0 is None:
            A, B = s.matrices(theta)
            x0 = models.steady_state(A, B, u[0])
        x = models.simulate(s, theta, u, dt, np.asarray(x0, dtype=float), self.hold)
        out = pd.DataFrame(x, columns=list(s.states))
        out.insert(0, "time", np.arange(len(u)) * dt)
        return out

    # --- on disk
    def write(self, path: str | os.PathLike[str]) -> None:
        """Write ``fit_<model>.yaml`` (plain YAML, keys in the order of the fit)."""
        write_yaml(self.data, path)

    def summary(self) -> str:
        """A few lines for people: the model, each parameter, R^2, the verdict with its
        reasons (-), each source's clock as the fit judges it (~; a record of several
        sources) and the record's outlying samples (!)."""
        lines = [
            f"{self.vehicle} {self.model} ({self.k_source}): {self.verdict}, R2 = {self.R2:.4f}"
        ]
        lines += [f"  {p}" for p in self.parameters.values()]
        lines += [f"  - {r}" for r in self.reasons]
        if self.data.get("clocks"):
            from railtherm.study import clocks

            lines += [f"  ~ {n}" for n in clocks.notes(self.data["clocks"])]
        lines += [f"  ! {t}" for t in self.outlying_samples()]
        return "\n".join(lines)

    def outlying_samples(self) -> list[str]:
        """The record's outlying samples (``outliers`` of the fit file,
        :mod:`railtherm.estimation.outliers`), one sentence each."""
        return [
            text
            for state, found in (self.data.get("outliers") or {}).items()
            for text in outliers.OutlyingSamples.from_dict(state, found).texts()
        ]


def write_yaml(data: Mapping[str, Any], path: str | os.PathLike[str]) -> None:
    """A result as plain YAML (:func:`railtherm.io.write_result`)."""
    results_io.write_result(data, path)


def read_fit(path: str | os.PathLike[str], series: str | os.PathLike[str] | None = None) -> Fit:
    """A :class:`Fit` from ``fit_<model>.yaml`` (read by :func:`railtherm.io.read_result`)
    and its series CSV, if given."""
    return Fit(results_io.read_result(path), None if series is None else pd.read_csv(series))


def check_fit_file(file: str | os.PathLike[str], data: Mapping[str, Any]) -> None:
    """A ``fit_<model>.yaml`` given to a command (energy, simulate, design) as it must be for
    its model to run: a structure of the registry, a value for exactly its parameters, each
    a finite number > 0 (capacities and conductances, drawn in log), and ``free`` and
    ``correlation`` that agree. A file edited by hand, cut short or written for another
    structure is a :class:`~railtherm.errors.ConfigError` naming the file, the key, the value
    and the fix, not an error deep in the simulation."""
    from railtherm.errors import ConfigError

    file = str(file)
    again = "write it again with railtherm fit --out (or the workflow's rule check)"
    name = data.get("structure")
    base, *irradiance = str(name).split("+")
    try:
        s = models.structure_for(base, irradiance)
    except KeyError:
        from railtherm import structures

        raise ConfigError(
            file,
            "structure",
            name,
            f"not a structure of the registry ({', '.join(structures.STRUCTURES)}): {again}",
        ) from None
    params = data.get("parameters")
    if not isinstance(params, Mapping):
        raise ConfigError(
            file, "parameters", params, f"must map each parameter to its entry: {again}"
        )
    missing = [p for p in s.parameters if p not in params]
    extra = [
        p
        for p, e in params.items()
        if p not in s.parameters
        and not (isinstance(e, Mapping) and e.get("estimated") == "derived")
    ]
    if missing or extra:
        raise ConfigError(
            file,
            "parameters",
            sorted(params),
            f"{s.name} has the parameters {', '.join(s.parameters)}"
            + (f"; missing {', '.join(missing)}" if missing else "")
            + (f"; not of it {', '.join(map(str, extra))}" if extra else "")
            + f": {again}",
        )
    for p in s.parameters:
        entry = params[p]
        value = entry.get("value") if isinstance(entry, Mapping) else None
        try:
            number = float(value)
        except (TypeError, ValueError):
            number = math.nan
        if isinstance(value, bool) or not (math.isfinite(number) and number > 0):
            raise ConfigError(
                file,
                f"parameters.{p}.value",
                value,
                f"must be a finite number > 0 (a capacity, conductance or aperture, drawn in "
                f"log): {again}",
            )
    free = data.get("free", [])
    if not isinstance(free, list) or any(p not in s.parameters for p in free):
        raise ConfigError(file, "free", free, f"must list parameters of {s.name}: {again}")
    corr = data.get("correlation")
    if corr is not None:
        try:
            shape = np.asarray(corr, dtype=float).shape
        except (TypeError, ValueError):
            shape = None
        n = len([p for p in free if p in params])
        if shape != (n, n):
            raise ConfigError(
                file,
                "correlation",
                f"shape {shape}",
                f"must be the {n} x {n} correlation of the free parameters "
                f"({', '.join(free)}): {again}",
            )
