"""Whether the data determine the parameters of a written fit: the judgement of each
estimated parameter (as recorded by :func:`railtherm.estimation.pem.identification`, or judged
from its interval), of the parameters a structure couples (``Structure.coupled``), and of the
sums the data determine however the capacity splits between the nodes (``Structure.totals``).
These read the parameter entries of a fit file (fit_<model>.yaml, ``parameters.<p>``) or of
an estimate being judged (:class:`~railtherm.records.JudgedEstimate`)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from railtherm.estimation.common import Z95, identification
from railtherm.records import FitRecord, JudgedEstimate

__all__ = ["coupled_identification", "parameter_identification", "total_capacity"]


def coupled_identification(judged: Mapping[str, Mapping[str, Any]], coupled) -> dict:
    """The identification of each parameter of a coupled group (``Structure.coupled``): the
    capacities and the internal conductance of a structure's dynamic part are determined only
    together, so when one is not identified (``judged[p]``, :func:`identification`) every
    other of the group is not reported as an estimate either: ``{"identified": False, "limit":
    "none", "coupled_to": [...], "reason": "coupled to C, which is not identified"}``.
    Returns {param: judgement} for the parameters of ``coupled`` present in ``judged``."""
    present = [p for p in coupled if p in judged]
    failed = [p for p in present if not judged[p].get("identified", True)]
    out = {}
    for p in present:
        if judged[p].get("identified", True) and failed:
            which = ", ".join(failed)
            verb = "is" if len(failed) == 1 else "are"
            out[p] = {
                "identified": False,
                "limit": "none",
                "limit_value": None,
                "coupled_to": list(failed),
                "reason": f"coupled to {which}, which {verb} not identified",
            }
        else:
            out[p] = dict(judged[p])
    return out


def total_capacity(
    fitted: JudgedEstimate | FitRecord,
    parts: Sequence[str],
    effects_log: Mapping[str, Mapping[str, float]] | None = None,
) -> dict[str, Any]:
    """The sum S = sum of ``parts`` (C_total = C + C_veh: the capacity the data determine
    however it splits between the nodes, the C_bar of eq. 9) with its combined 95 % interval
    by the delta method on the log scale: d log S = sum_i w_i d log theta_i, w_i = theta_i / S,

        var(log S) = w^T Sigma w + sum_sources (sum_i w_i e_i,source)^2,

    Sigma the fit's statistical covariance of the log parameters (``sd_log`` and
    ``correlation`` over ``free``), e the signed systematic effects of each source
    (``effects_log``, railtherm.study.budget.systematic_budget). A part at a bound of the search
    (its entry's ``at_bound``, :func:`identification`) is held there: the sum is conditional
    on it (its variance and effects left out, ``note`` says so); a part at an upper bound, or
    every part at a bound, leaves the sum not identified, and a part with an unbounded
    variance not at a bound leaves it unbounded. Judged by :func:`identification` like a
    parameter."""
    params = fitted.parameters
    at_bounds = {p: params[p].at_bound for p in parts if params[p].at_bound}
    values = np.array([params[p].value for p in parts])
    S = float(values.sum())
    w = values / S
    free = list(fitted.free)
    corr = fitted.correlation
    effects = effects_log or {}
    varying = [i for i, p in enumerate(parts) if params[p].estimated and p not in at_bounds]
    # w^T Sigma w over the varying parts, Sigma = diag(sd) R diag(sd)
    g = np.array([w[i] * float(params[parts[i]].sd_log) for i in varying])
    at = [free.index(parts[i]) for i in varying]
    R = np.nan_to_num(corr[np.ix_(at, at)], nan=0.0) if at else np.zeros((0, 0))
    np.fill_diagonal(R, 1.0)
    var = float(g @ R @ g) if np.all(np.isfinite(g)) else math.inf
    sources = sorted({s for i in varying for s in effects.get(parts[i], {})})
    for source in sources:  # a source shifts every part at once: signed, then squared
        shift = sum(w[i] * float(effects.get(parts[i], {}).get(source, 0.0)) for i in varying)
        var += shift**2 if math.isfinite(shift) else math.inf
    sd = math.sqrt(var) if math.isfinite(var) and var >= 0 else math.inf
    with np.errstate(over="ignore"):
        ci = [float(S * np.exp(-Z95 * sd)), float(S * np.exp(Z95 * sd))]
    if not math.isfinite(sd):
        ci = [0.0, math.inf]
    entry: dict[str, Any] = {
        "value": S,
        "parts": list(parts),
        "ci95": ci,
        "sd_log_total": sd,
        "method": "delta method on log S: the fit's covariance and the signed systematic effects",
    }
    held = [p for p in parts if p in at_bounds]
    if held:
        entry["held_at_bound"] = held
        entry["note"] = (
            f"{', '.join(held)} held at {'its' if len(held) == 1 else 'their'} bound: the "
            "interval is conditional on it"
        )
    entry.update(identification(S, ci))
    upper = [p for p in held if at_bounds[p] == "upper"]
    if upper:  # the sum grows with a part the search stopped: no value the data give
        reason = f"{', '.join(upper)} at the upper bound of the search"
        entry.update(identified=False, limit="none", limit_value=None, reason=reason)
    elif not varying:  # every part held: a sum of bounds, nothing the data give
        reason = f"every part ({', '.join(parts)}) at a bound of the search"
        entry.update(identified=False, limit="none", limit_value=None, reason=reason)
    return entry


def parameter_identification(entry: Mapping[str, Any]) -> Mapping[str, Any]:
    """The :func:`identification` of a parameter entry of a written fit (``parameters.<p>``
    of fit_<model>.yaml): as recorded there, or, for a fit written before it was recorded,
    judged from the entry's interval. A fixed parameter (no interval) is identified."""
    if "identified" in entry:
        return entry
    if "ci95" not in entry:
        return {"identified": True}
    return identification(float(entry["value"]), entry["ci95"])
