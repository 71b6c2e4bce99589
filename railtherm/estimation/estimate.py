"""What every estimator returns: an :class:`Estimate` of a structure's parameters from a set of
records, with its intervals, identifiability flags and the simulated series. The paper's
simulation-error PEM (:class:`railtherm.estimation.pem.FitResult`) and the Kalman filter's maximum
likelihood (:class:`railtherm.estimation.kalman.KalmanResult`) extend it; ``estimator`` says
which."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

__all__ = ["Estimate", "Flag", "Identification"]


@dataclass(frozen=True)
class Flag:
    """An identifiability warning: a machine ``code``, the parameters concerned, a sentence."""

    code: str
    parameters: tuple[str, ...]
    message: str

    def to_dict(self) -> dict[str, Any]:
        return {"code": self.code, "parameters": list(self.parameters), "message": self.message}


@dataclass(frozen=True, eq=False)
class Identification(Mapping[str, Any]):
    """Whether the data determine a parameter (:func:`railtherm.estimation.pem.identification`):
    ``identified``, and where they do not, the one-sided ``limit`` they give ("upper",
    "lower" or "none") with its ``limit_value``, the side of the search bound the estimate
    sits at (``at_bound``) and the ``reason``. Read as a mapping it holds exactly the keys a
    fit file stores under ``parameters.<p>`` (``{"identified": True}`` alone for an identified
    parameter), and compares equal to that dict."""

    identified: bool
    limit: str | None = None
    limit_value: float | None = None
    at_bound: str | None = None
    reason: str | None = None

    def to_dict(self) -> dict[str, Any]:
        if self.identified:
            return {"identified": True}
        out: dict[str, Any] = {
            "identified": False,
            "limit": self.limit,
            "limit_value": self.limit_value,
        }
        if self.at_bound is not None:
            out["at_bound"] = self.at_bound
        out["reason"] = self.reason
        return out

    def __getitem__(self, key: str) -> Any:
        return self.to_dict()[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self.to_dict())

    def __len__(self) -> int:
        return len(self.to_dict())


@dataclass(kw_only=True)
class Estimate:
    """The estimate of a structure's parameters, whatever the estimator.

    ``theta`` holds every parameter (fixed ones too); ``free`` the estimated ones, in the
    order of ``correlation``; ``sd_log`` the standard deviation of log(theta); ``ci95``
    {param: (lo, hi)}; ``cond`` the conditioning of the problem (:attr:`CONDITION`); ``cost``
    the minimised criterion (e^T e of eq. 17, K^2, or the negative log-likelihood);
    ``n_obs`` the scalar measurements used and ``n_unknowns`` every estimated quantity.
    Per record (lists in the order given): ``names``, ``dt``, ``x0`` (the initial state),
    ``x0_estimated`` (its estimated states), ``simulated`` (N x n_states, the deterministic
    simulation of eq. 15 at the estimate), ``residuals`` (measured - simulated, NaN where not
    compared)."""

    CONDITION: ClassVar[str] = "condition"  # the key of ``cond`` in :meth:`to_dict`

    estimator: str
    structure: str
    theta: dict[str, float]
    free: tuple[str, ...]
    fixed: dict[str, float]
    ci95: dict[str, tuple[float, float]]
    sd_log: dict[str, float]
    correlation: np.ndarray
    cond: float
    flags: list[Flag]
    cost: float
    n_obs: int
    n_unknowns: int
    success: bool
    message: str
    outputs: tuple[str, ...]
    names: list[str]
    x0: list[np.ndarray]
    simulated: list[np.ndarray] = field(repr=False)
    residuals: list[np.ndarray] = field(repr=False)
    x0_estimated: list[tuple[str, ...]] = field(default_factory=list)
    dt: list[float] = field(default_factory=list)
    states: tuple[str, ...] = ()
    nfev: int = 0
    njev: int = 0
    covariance: str = ""
    start_used: str = ""
    start_costs: dict[str, float] = field(default_factory=dict)
    bandwidths: list[int] = field(default_factory=list)
    input_noise_sd: list[dict[str, float]] = field(default_factory=list)
    # a MAP estimate's priors ({param: {kind, ...}}, railtherm.estimation.priors) and its
    # log-prior at the estimate; empty and None for a maximum-likelihood estimate
    priors: dict[str, dict[str, Any]] = field(default_factory=dict)
    log_prior: float | None = None

    def parameter_entries(self) -> dict[str, dict[str, Any]]:
        """{param: {value, estimated[, ci95, sd_log]}} in the structure's order."""
        params = {}
        for p, v in self.theta.items():
            entry: dict[str, Any] = {"value": float(v), "estimated": p in self.free}
            if p in self.free:
                entry["ci95"] = [float(c) for c in self.ci95[p]]
                entry["sd_log"] = float(self.sd_log[p])
            params[p] = entry
        return params

    def experiment_entries(self) -> list[dict[str, Any]]:
        """Per record: its name, step, initial state and which of its states were estimated."""
        return [
            {
                "name": name,
                "dt": float(dt),
                "x0": {s: float(v) for s, v in zip(self.states, x0, strict=True)},
                "x0_estimated": list(est),
            }
            for name, dt, x0, est in zip(
                self.names, self.dt, self.x0, self.x0_estimated, strict=True
            )
        ]

    def to_dict(self) -> dict[str, Any]:
        """Plain floats, lists and strings in a stable order (YAML-ready): the keys every
        estimator writes; an estimator's own follow (:meth:`extra`)."""
        common = {
            "estimator": self.estimator,
            "structure": self.structure,
            "parameters": self.parameter_entries(),
            "free": list(self.free),
            "correlation": [[float(c) for c in row] for row in np.asarray(self.correlation)],
            self.CONDITION: float(self.cond),
            "flags": [fl.to_dict() for fl in self.flags],
            "cost": float(self.cost),
            "n_obs": int(self.n_obs),
            "n_unknowns": int(self.n_unknowns),
            "nfev": int(self.nfev),
            "njev": int(self.njev),
            "success": bool(self.success),
            "message": str(self.message),
            "start_used": self.start_used,
            "start_costs": {k: float(v) for k, v in self.start_costs.items()},
            "covariance": self.covariance,
            "outputs": list(self.outputs),
            "experiments": self.experiment_entries(),
            "hac_bandwidths": [int(b) for b in self.bandwidths],
            "input_noise_sd": [
                {name: float(sd) for name, sd in record.items()} for record in self.input_noise_sd
            ],
        }
        if self.priors:  # a MAP estimate says so; a maximum-likelihood one is written as before
            common["inference"] = "MAP"
            common["priors"] = {p: dict(spec) for p, spec in self.priors.items()}
            common["log_prior"] = float(self.log_prior)
        return {**common, **self.extra()}

    def extra(self) -> dict[str, Any]:
        """The estimator's own keys of :meth:`to_dict` (none here)."""
        return {}
