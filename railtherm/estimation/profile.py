"""Profile-likelihood limits of a parameter the data do not determine (Brastein et al.,
Energy & Buildings 2020; Raue et al., Bioinformatics 2009).

The profile of a parameter p is the fit's criterion with p held at each value in turn and
every other unknown re-estimated: a log-likelihood, up to a constant, of p alone. Where it
rises by more than half the chi-square quantile of one degree of freedom above its minimum
(1.92 for 95 %), the data exclude p at that level. Walking from the estimate outwards to each
search bound in log p gives

- two crossings: a two-sided interval (the data determine p after all, in the likelihood's
  sense, though the curvature at the optimum did not say so);
- a crossing below and none up to the upper bound: a lower limit ("p is at least ..."), the
  data's own, not a search bound;
- a crossing above only: an upper limit ("at most ...");
- none: the records do not limit p within the physical range ("not identified" alone).

The walk is in log p on a grid of ``points`` steps between the bounds, each fit warm-started
from the previous one (a profile follows its valley), and a crossing is refined by bisection
to ``tol`` of its distance from the estimate in log p. The criterion is the estimator's:
for the simulation error the Gaussian log-likelihood with its variance profiled out,
(w / 2) log(e^T e) with w the samples the residuals count as
(:func:`output_error_profile`); for the Kalman filter its negative log-likelihood.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from railtherm.estimation import models, pem

__all__ = [
    "CHI2_1_95",
    "ProfileLimit",
    "kalman_profile",
    "output_error_profile",
    "profile_limit",
]

CHI2_1_95 = 3.841458820694124  # the 95 % quantile of chi-square with one degree of freedom


@dataclass
class ProfileLimit:
    """What the profile of ``parameter`` says: ``kind`` "two_sided", "lower" (at least
    ``lower``), "upper" (at most ``upper``) or "none"; ``points``: (value, rise of the
    criterion above its minimum) in the order evaluated; ``level`` the confidence level."""

    parameter: str
    kind: str
    lower: float | None
    upper: float | None
    level: float
    points: list[tuple[float, float]] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return {
            "method": "profile likelihood (the other unknowns re-estimated at each value)",
            "level": self.level,
            "kind": self.kind,
            "lower": self.lower,
            "upper": self.upper,
            "points": [[float(v), float(d)] for v, d in sorted(self.points)],
        }

    def phrase(self) -> str:
        """How a table or a reason says it."""
        if self.kind == "lower":
            return f"profile likelihood: at least {self.lower:.3g} ({self.level:.0%})"
        if self.kind == "upper":
            return f"profile likelihood: at most {self.upper:.3g} ({self.level:.0%})"
        if self.kind == "two_sided":
            return f"profile likelihood: {self.lower:.3g} to {self.upper:.3g} ({self.level:.0%})"
        return "profile likelihood: no limit within the search bounds"


BISECTIONS = 40  # at most this many refits to place one crossing


def profile_limit(
    parameter: str,
    estimate: float,
    bounds: tuple[float, float],
    criterion: Callable[[float, Any], tuple[float, Any]],
    *,
    minimum: float,
    points: int = 16,
    tol: float = 0.01,
) -> ProfileLimit:
    """The profile-likelihood limits of ``parameter`` at 95 %.

    ``criterion(value, warm)``: the fit's criterion (a negative log-likelihood up to a
    constant) with the parameter held at ``value``, re-estimating the rest from ``warm``
    (None, or what an earlier call returned), and what the next call may start from;
    ``minimum``: the criterion at the estimate ``estimate``; ``bounds``: the search bounds.
    A value the model cannot be evaluated at (criterion inf or raising ValueError) counts as
    excluded."""
    threshold = CHI2_1_95 / 2.0
    lo_b, hi_b = (math.log(float(b)) for b in bounds)
    v_hat = min(max(math.log(float(estimate)), lo_b), hi_b)
    step = (hi_b - lo_b) / max(points, 2)
    seen: list[tuple[float, float]] = []
    best = [float(minimum)]

    def rise(v: float, warm):
        try:
            value, warm = criterion(math.exp(v), warm)
        except (ValueError, ArithmeticError):
            value = math.inf
        if math.isfinite(value):
            best[0] = min(best[0], value)
        seen.append((math.exp(v), value))
        return value, warm

    def walk(direction: int) -> float | None:
        """The crossing in ``direction`` (log p), or None when the bound is reached."""
        inside, warm = v_hat, None
        while True:
            edge = hi_b if direction > 0 else lo_b
            v = inside + direction * step
            v = min(v, edge) if direction > 0 else max(v, edge)
            if v == inside:
                return None
            value, warm_v = rise(v, warm)
            if not value - best[0] <= threshold:
                break
            inside, warm = v, warm_v
        outside = v
        # bisection between inside and outside, to ``tol`` of the distance from the estimate
        # (and no finer than a thousandth of a step: a profile that rises beyond the
        # threshold right beside the estimate, as a prior that contradicts the record makes
        # it, has its crossing there, not ever closer to it)
        for _ in range(BISECTIONS):
            if abs(outside - inside) <= max(
                tol * max(abs(inside - v_hat), abs(outside - v_hat) / 2), 1e-3 * step
            ):
                break
            mid = 0.5 * (inside + outside)
            value, warm_m = rise(mid, warm)
            if value - best[0] <= threshold:
                inside, warm = mid, warm_m
            else:
                outside = mid
        return math.exp(0.5 * (inside + outside))

    upper = walk(+1)
    lower = walk(-1)
    kind = {
        (True, True): "two_sided",
        (True, False): "lower",
        (False, True): "upper",
        (False, False): "none",
    }[(lower is not None, upper is not None)]
    rises = [(v, c - best[0]) for v, c in seen]
    return ProfileLimit(parameter, kind, lower, upper, 0.95, rises)


def output_error_profile(
    structure: models.Structure,
    experiments: Sequence[pem.Experiment],
    parameter: str,
    estimate: pem.FitResult,
    *,
    weight: float | None = None,
    points: int = 16,
    **options: Any,
) -> ProfileLimit:
    """The profile-likelihood limits of ``parameter`` (:func:`profile_limit`) around
    ``estimate``, the fit of :func:`railtherm.estimation.pem.fit` with ``options`` (fixed,
    bounds, outputs, x0, input_noise, priors ...): at each value the parameter is fixed and
    the rest re-fitted (warm-started, the iid covariance: only the point is needed). The
    criterion is (weight / 2) log(e^T e), ``weight`` the samples the residuals count as
    (default: the estimate's ``samples_weight``, fewer than the compared samples where the
    HAC covariance finds the residuals coloured). Within the parameter's search bounds."""
    default = estimate.samples_weight if estimate.samples_weight else estimate.n_obs
    w = float(default if weight is None else weight)
    bounds = dict(structure.bounds)
    bounds.update({p: (float(b[0]), float(b[1])) for p, b in (options.get("bounds") or {}).items()})
    fixed = dict(options.get("fixed") or {})
    base = {**options, "start": "initial", "covariance": "iid"}
    others = {p: estimate.theta[p] for p in estimate.free if p != parameter}

    def criterion(value: float, warm):
        r = pem.fit(
            structure, experiments, **{**base, "fixed": {**fixed, parameter: value},
            "initial": warm or others},
        )  # fmt: skip
        return 0.5 * w * math.log(r.cost), {p: r.theta[p] for p in r.free}

    minimum = 0.5 * w * math.log(estimate.cost)
    return profile_limit(
        parameter, estimate.theta[parameter], bounds[parameter], criterion,
        minimum=minimum, points=points,
    )  # fmt: skip


def kalman_profile(
    structure: models.Structure,
    experiments: Sequence[pem.Experiment],
    parameter: str,
    estimate,
    *,
    points: int = 16,
    **options: Any,
) -> ProfileLimit:
    """The profile-likelihood limits of ``parameter`` (:func:`profile_limit`) around
    ``estimate``, the fit of :func:`railtherm.estimation.kalman.fit` with ``options`` (fixed,
    bounds, outputs, x0, offsets, input_noise, ...): at each value the parameter is fixed and
    every other unknown - the structure's parameters and the noise parameters - re-fitted
    from the previous value's (warm start). The criterion is the filter's negative
    log-likelihood (the estimate's ``cost``). Within the parameter's search bounds."""
    from railtherm.estimation import kalman  # the filter's fit, on first use

    bounds = dict(structure.bounds)
    bounds.update({p: (float(b[0]), float(b[1])) for p, b in (options.get("bounds") or {}).items()})
    fixed = dict(options.get("fixed") or {})
    held = {  # a noise parameter the fit holds at its bound stays held
        name: (estimate.sigma if name.startswith("sigma_") else estimate.meas_var)[
            name.split("_", 1)[1]
        ]
        for name in getattr(estimate, "noise_at_bound", ())
    }

    def start_of(r) -> dict[str, float]:
        out = {p: r.theta[p] for p in r.free if p != parameter}
        out.update({f"sigma_{k}": v for k, v in r.sigma.items() if v > 0})
        out.update({f"s_{k}": v for k, v in r.meas_var.items() if v > 0})
        return {k: v for k, v in out.items() if k not in fixed and k not in held}

    def criterion(value: float, warm):
        r = kalman.fit(
            structure, experiments, **{**options, "start": "initial",
            "fixed": {**fixed, **held, parameter: value},
            "initial": {**(options.get("initial") or {}), **(warm or start_of(estimate))}},
        )  # fmt: skip
        return float(r.cost), start_of(r)

    return profile_limit(
        parameter, estimate.theta[parameter], bounds[parameter], criterion,
        minimum=float(estimate.cost), points=points,
    )  # fmt: skip
