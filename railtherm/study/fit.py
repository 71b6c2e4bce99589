"""A checked fit of one grey-box model to one vehicle, as a model.

:class:`Fit` is the :class:`~railtherm.records.FitRecord` of ``fit_<model>.yaml`` (the rule
``check``'s output: the parameters with their 95 % intervals and the explicit "not
identified" state, the flags, the fit measures (R^2 of eq. 21) and the verdict) with the
identified model as a continuous state-space system (:meth:`Fit.to_statespace`, eqs. 7-8 or
9) and a simulator (:meth:`Fit.simulate`, exact zero-order hold as in eq. 15). :func:`read_fit`
and :meth:`Fit.write` read and write the file through :mod:`railtherm.io`.
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
from railtherm.records import FitRecord


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
        """(A_d, B_d) of the exact zero-order-hold discretisation over ``dt`` s (eq. 15).

        Parameters
        ----------
        dt : float
            The sample step (s).

        Returns
        -------
        tuple of ndarray
            (A_d, B_d).
        """
        return models.discretize_zoh(self.A, self.B, dt)


@dataclass(frozen=True, eq=False)
class Fit(FitRecord):
    """A checked fit as a model: its :class:`~railtherm.records.FitRecord` (the content of
    ``fit_<model>.yaml``: parameters, intervals, the verdict) with the identified model as a
    state-space system and a simulator; ``series`` the measured and simulated states per
    window (time, T, T_sim, ..., inputs), when known; ``posterior`` the draws of its
    posterior (:func:`railtherm.study.posterior.read_draws`: every parameter, the systematic
    budget mixed in) where one was sampled and read with it, and ``posterior_file`` where
    they came from, ``posterior_systematic`` whether they carry the systematic budget."""

    series: pd.DataFrame | None = field(default=None, repr=False)
    posterior: Mapping[str, np.ndarray] | None = field(default=None, repr=False)
    posterior_file: str = ""
    posterior_systematic: bool = False

    def posterior_sample(self, n: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
        """Parameter sets drawn (with replacement) from :attr:`posterior`: predictions from
        the posterior itself instead of a Gaussian about the estimate.

        Parameters
        ----------
        n : int
            How many parameter sets.
        rng : numpy.random.Generator
            The draws' generator.

        Returns
        -------
        dict of str to ndarray
            Each parameter's ``n`` values.
        """
        if self.posterior is None:
            raise ValueError(f"{self.vehicle} {self.model}: no posterior draws")
        size = len(next(iter(self.posterior.values())))
        at = rng.integers(0, size, n)
        return {p: np.asarray(v)[at] for p, v in self.posterior.items()}

    @property
    def central(self) -> dict[str, float]:
        """The parameters a prediction's central run takes: the posterior's median of each
        (the draws' centre, so that a band over the draws holds its central value) where a
        posterior is attached, else the estimate (:attr:`theta`)."""
        theta = self.theta
        if self.posterior is None:
            return theta
        return {p: float(np.median(self.posterior[p])) if p in self.posterior else v
                for p, v in theta.items()}  # fmt: skip

    @classmethod
    def from_dict(cls, content: Mapping[str, Any], series: pd.DataFrame | None = None) -> Fit:
        """The fit of a fit file's content (the rule check's output), with its series.

        Parameters
        ----------
        content : mapping
            The content of a ``fit_<model>.yaml``.
        series : DataFrame, optional
            Its measured and simulated series.

        Returns
        -------
        Fit
        """
        return cls(FitRecord.from_dict(content).content, series)

    @classmethod
    def of(cls, record: FitRecord, series: pd.DataFrame | None = None) -> Fit:
        """The fit of a record, with its series.

        Parameters
        ----------
        record : FitRecord
            The fit's record (:func:`railtherm.io.read_fit`).
        series : DataFrame, optional
            Its measured and simulated series.

        Returns
        -------
        Fit
        """
        return cls(record.content, series)

    @property
    def hold(self) -> str:
        """How the inputs ran between samples in the fit ("zero_order": eq. 15, or
        "first_order"); a simulation of the model uses the same discretisation."""
        return self.input_hold

    # --- the model
    @property
    def structure(self) -> models.Structure:
        """The grey-box structure, with the irradiance inputs it was fitted with."""
        base, *irradiance = self.structure_name.split("+")
        return models.structure_for(base, irradiance)

    def to_statespace(self) -> StateSpace:
        """The identified model as (A, B, C, D): eqs. 7-8 (second order), eq. 9 (first order)
        or the interior-envelope structure, inputs T_o, Q_H and any irradiance.

        Returns
        -------
        StateSpace
            A, B, C, D with the names of states, inputs and outputs.
        """
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
        state of the first input row). Returns time and states.

        Parameters
        ----------
        u : DataFrame or ndarray
            The inputs, one row per step.
        dt : float
            The step (s).
        x0 : sequence of float, optional
            The initial states (K or degC, as the fit's).

        Returns
        -------
        DataFrame
            ``time`` (s) and one column per state.
        """
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
        """Write ``fit_<model>.yaml`` (plain YAML, keys in the order of the fit).

        Parameters
        ----------
        path : str or os.PathLike
            The file to write (its directory made if needed).
        """
        results_io.write_fit(self, path)

    def summary(self) -> str:
        """A few lines for people: the model, each parameter, R^2, the verdict with its
        reasons (-), each source's clock as the fit judges it (~; a record of several
        sources) and the record's outlying samples (!).

        Returns
        -------
        str
        """
        # a prior moved the estimate: say which (an output-error fit file holds the keys at
        # its top, a Kalman one in its section fit)
        held = self.content if self.content.get("inference") else self.section("fit")
        inference = ""
        if held.get("inference") == "MAP":
            inference = f", MAP with priors on {', '.join(held.get('priors') or {}) or 'none'}"
        lines = [
            f"{self.vehicle} {self.model} ({self.k_source}{inference}): {self.verdict}, "
            f"R2 = {self.R2:.4f}"
        ]
        lines += [f"  {p}" for p in self.parameters.values()]
        lines += [f"  - {r}" for r in self.reasons]
        if self.has("clocks"):
            from railtherm.study import clocks

            lines += [f"  ~ {n}" for n in clocks.notes(self.section("clocks"))]
        lines += [f"  ! {t}" for t in self.outlying_samples()]
        return "\n".join(lines)

    def outlying_samples(self) -> list[str]:
        """The record's outlying samples (``outliers`` of the fit file,
        :mod:`railtherm.estimation.outliers`), one sentence each.

        Returns
        -------
        list of str
        """
        return [
            text
            for state, found in self.section("outliers").items()
            for text in outliers.OutlyingSamples.from_dict(state, found).texts()
        ]


def write_yaml(data: Mapping[str, Any], path: str | os.PathLike[str]) -> None:
    """A result as plain YAML (:func:`railtherm.io.write_result`)."""
    results_io.write_result(data, path)


def posterior_file(path: str | os.PathLike[str]) -> str:
    """Where a fit file's posterior is written: ``fit_<model>.posterior.nc`` beside it."""
    text = str(path)
    return (text[: -len(".yaml")] if text.endswith(".yaml") else text) + ".posterior.nc"


def read_fit(
    path: str | os.PathLike[str],
    series: str | os.PathLike[str] | None = None,
    posterior: str | os.PathLike[str] | None = None,
) -> Fit:
    """A :class:`Fit` from ``fit_<model>.yaml`` (read by :func:`railtherm.io.read_fit`)
    and its series CSV, if given.

    Parameters
    ----------
    path : str or os.PathLike
        The ``fit_<model>.yaml``.
    series : str or os.PathLike, optional
        Its ``identify/<model>_series.csv``.
    posterior : str or os.PathLike, optional
        Its posterior (``fit_<model>.posterior.nc``, :func:`posterior_file`), whose draws
        the predictions then take (:attr:`Fit.posterior`); ``"auto"``: the one beside the
        fit file where it exists.

    Returns
    -------
    Fit

    Raises
    ------
    ConfigError
        A missing file, bad YAML or one that holds no mapping, naming the file.
    """
    fit = Fit.of(results_io.read_fit(path), None if series is None else pd.read_csv(series))
    if posterior == "auto":
        posterior = posterior_file(path) if os.path.isfile(posterior_file(path)) else None
    if posterior is None:
        return fit
    from railtherm.study.posterior import read_draws  # ArviZ only where a posterior is read

    draws, systematic = read_draws(posterior, fit)
    return Fit(fit.content, fit.series, draws, str(posterior), systematic)


def check_fit_file(file: str | os.PathLike[str], fit: FitRecord) -> None:
    """A ``fit_<model>.yaml`` given to a command (energy, simulate, design) as it must be for
    its model to run: a structure of the registry, a value for exactly its parameters, each
    a finite number > 0 (capacities and conductances, drawn in log), and ``free`` and
    ``correlation`` that agree. A file edited by hand, cut short or written for another
    structure is a :class:`~railtherm.errors.ConfigError` naming the file, the key, the value
    and the fix, not an error deep in the simulation."""
    from railtherm.errors import ConfigError

    file = str(file)
    data = fit.content
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
