"""Partial pooling across a class, the empirical-Bayes way (docs/bayes.md): each vehicle's
second-order fit with the class reference model of the study's *other* vehicles as its
prior, sampled by NUTS - the study's table of each vehicle's maximum-likelihood estimate,
its class prior and its posterior side by side.

The prior of vehicle v is the predictive distribution of the class reference model
(:mod:`railtherm.study.classmodel`, eqs. 24-25) built from Table 2 without v: the
generalised parameters c_veh, delta and kappa_veh of v's class (every rail class pooled
where v's class has fewer than two other usable vehicles), each a scaled Student t in log
space, as joint terms on log C_veh, log C, log K_veh
(:meth:`railtherm.study.classmodel.ReferenceModel.prior_terms`). kA stays held at its
static value (eq. 10, the two-stage approach), so the class's k is not a term. A vehicle
without class, mass or surface, or whose class cannot be built, keeps the priors of its own
file. A first-order model is sampled with the vehicle's own priors: the class model is one
of the second-order model.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from railtherm.errors import ConfigError
from railtherm.estimation import sampling
from railtherm.study import classmodel

__all__ = [
    "ClassPrior",
    "class_prior",
    "pooling_markdown",
    "pooling_rows",
    "posterior_record",
    "summary_line",
    "study_posterior",
    "TRUST",
]

# what a reader must see before using a posterior (docs/bayes.md)
TRUST = {"r_hat_max": 1.01, "ess_bulk_min": 400.0, "divergences": 0}
SHOWN = ("kA", "C_bar", "C", "K_veh", "C_veh")  # in the study table, in this order


@dataclass
class ClassPrior:
    """The prior a vehicle's fit is given: ``reference`` (the class reference model without
    the vehicle) with ``basis`` ("class": its own class; "all": every rail class pooled), or
    None with ``reason`` (the fit keeps the vehicle's own priors)."""

    reference: classmodel.ReferenceModel | None
    basis: str
    reason: str = ""

    @property
    def terms(self) -> list:
        return [] if self.reference is None else self.reference.prior_terms()

    def to_dict(self) -> dict[str, Any]:
        if self.reference is None:
            return {"kind": "vehicle", "reason": self.reason}
        ref = self.reference
        parameters = ref.parameters
        return {
            "kind": "class",
            "class": ref.vehicle_class,
            "basis": self.basis,
            "vehicles": list(ref.basis),
            "parameters": {  # kA only where the class's k is a term (kA not held)
                p: {"value": float(parameters[p]["value"]), "ci95": list(parameters[p]["ci95"])}
                for p in ("kA", "C", "K_veh", "C_veh")
                if p != "kA" or ref.k_given is None
            },
        }


# the parameters the class model's terms join (kA only where the fit does not hold it)
CLASS_TERMS = ("kA", "C", "K_veh", "C_veh")


def class_prior(
    members: Sequence[classmodel.ClassMember],
    vehicle_id: str,
    vehicle: Mapping[str, Any],
    kA_held: float | None,
    min_vehicles: int = 2,
) -> ClassPrior:
    """The class prior of ``vehicle_id`` (its config ``vehicle``) from the study's
    ``members`` less itself: its class's reference model, else every rail class pooled; k
    given as ``kA_held`` / surface where the fit holds kA (no class term on kA)."""
    missing = [k for k in ("class", "mass_kg", "surface_m2") if vehicle.get(k) is None]
    if missing:
        return ClassPrior(None, "none", f"the vehicle declares no {', '.join(missing)}")
    joined = set(CLASS_TERMS) - ({"kA"} if kA_held is not None else set())
    own = sorted(set((vehicle.get("model") or {}).get("priors") or {}) & joined)
    if own:  # one parameter, one prior: the vehicle's own stands, the class's would add to it
        return ClassPrior(
            None,
            "none",
            f"the vehicle's own model.priors on {', '.join(own)}: a parameter takes one "
            "prior, its own or the class model's",
        )
    mass, surface = float(vehicle["mass_kg"]), float(vehicle["surface_m2"])
    k = None if kA_held is None else kA_held / surface
    exclude = [vehicle_id] if any(m.vehicle == vehicle_id for m in members) else []
    reasons = []
    for basis, name in (("class", vehicle["class"]), ("all", classmodel.POOLED)):
        try:
            reference = classmodel.build(
                members, name, mass, surface, k=k, min_vehicles=min_vehicles, exclude=exclude
            )
        except ConfigError as err:
            reasons.append(err.reason)
            continue
        return ClassPrior(reference, basis)
    return ClassPrior(None, "none", "; ".join(reasons))


def study_posterior(
    vehicle_id: str,
    model: str,
    vehicle: Mapping[str, Any],
    tables,
    kvalue: Mapping[str, Any] | None,
    k_window,
    fit,
    settings: Mapping[str, Any],
    members: Sequence[classmodel.ClassMember] | None = None,
    min_vehicles: int = 2,
) -> tuple[sampling.Posterior, dict[str, Any], ClassPrior | None]:
    """One posterior of the study (rule posterior): ``model`` of ``vehicle`` sampled as its
    fit ``fit`` is set up (its identification ``tables``, static k result and k window),
    with the class prior of ``members`` less the vehicle where given (a second-order model
    with ``posterior.prior: class``), the systematic budget mixed in; ``settings``: the
    study config's ``posterior`` section. Returns the posterior, its file's content
    (:func:`posterior_record`, PSIS-LOO where ``settings["loo"]``) and the prior given."""
    from railtherm.study import posterior  # nutpie and ArviZ on first use

    prior = None
    if members is not None:
        kA = fit.section("parameters").get("kA", {})
        kA_held = None if kA.get("estimated", True) else float(kA["value"])
        prior = class_prior(members, vehicle_id, vehicle, kA_held, min_vehicles)
    post = posterior.sample_model(
        tables, vehicle, kvalue, k_window, model, fit=fit,
        prior_terms=prior.terms if prior is not None else (), chains=settings["chains"],
        draws=settings["draws"], tune=settings["tune"], seed=settings["seed"],
        target_accept=settings.get("target_accept", sampling.TARGET_ACCEPT),
    )  # fmt: skip
    loo = post.loo() if settings.get("loo", True) else None
    return post, posterior_record(vehicle_id, model, post, fit, prior, loo), prior


def _r_hat(value: float, digits: int) -> str:
    """R-hat as printed: none from a single chain (it compares chains), which the verdict
    then does not trust."""
    return f"{value:.{digits}f}" if math.isfinite(value) else "n/a (one chain)"


def summary_line(record: Mapping[str, Any]) -> str:
    """A posterior file's diagnostics in one line (the rule's log)."""
    d = record["diagnostics"]
    verdict = "trusted" if d["trusted"] else "NOT trusted"
    return (
        f"{record['vehicle']} {record['model']}: R-hat <= {_r_hat(d['r_hat_max'], 4)}, bulk ESS >= "
        f"{d['ess_bulk_min']:.0f}, {d['divergences']} divergences, {verdict}"
    )


def _interval(values, prob: float = 0.95) -> list[float]:
    lo, hi = np.quantile(values, [(1 - prob) / 2, (1 + prob) / 2])
    return [float(lo), float(hi)]


def posterior_record(
    vehicle_id: str,
    model: str,
    post: sampling.Posterior,
    fit,
    prior: ClassPrior | None,
    loo: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """The content of a vehicle's posterior file (results/vehicles/<id>/posterior_<model>.
    yaml): the prior it was given, the sampler's settings, the diagnostics a reader must
    check (and whether they pass :data:`TRUST`), and per parameter the posterior's median
    and 95 % interval - the data's (statistical) and with the type-B budget mixed in - beside
    the maximum-likelihood fit's (``fit``); PSIS-LOO's figures where ``loo`` gives them
    (:meth:`railtherm.estimation.sampling.Posterior.loo`)."""
    summary = post.summary()
    params = fit.section("parameters")
    structural = [p for p in summary.index if p in params]
    diagnostics = {
        "r_hat_max": float(summary.loc[structural, "r_hat"].max()),
        "ess_bulk_min": float(summary.loc[structural, "ess_bulk"].min()),
        "divergences": post.divergences(),
    }
    diagnostics["trusted"] = bool(
        diagnostics["r_hat_max"] <= TRUST["r_hat_max"]
        and diagnostics["ess_bulk_min"] >= TRUST["ess_bulk_min"]
        and diagnostics["divergences"] <= TRUST["divergences"]
    )
    groups = post.idata.groups()
    mixed = post.idata.posterior_systematic if "posterior_systematic" in groups else None
    out: dict[str, Any] = {}
    for p in params:
        entry: dict[str, Any] = {"ml": _ml_entry(params[p])}
        if p in post.idata.posterior:
            draws = post.idata.posterior[p].values.ravel()
            entry["median"] = float(np.median(draws))
            entry["ci95_statistical"] = _interval(draws)
        if mixed is not None and p in mixed:
            draws = mixed[p].values.ravel()
            entry.setdefault("median", float(np.median(draws)))
            entry["ci95"] = _interval(draws)
        elif "ci95_statistical" in entry:
            entry["ci95"] = entry["ci95_statistical"]
        entry["sampled"] = p in post.idata.posterior
        out[p] = entry
    return {
        "vehicle": vehicle_id,
        "model": model,
        "inference": "posterior",
        "prior": {"kind": "vehicle"} if prior is None else prior.to_dict(),
        "sampler": {"method": post.idata.attrs.get("sampler", "NUTS"), **post.settings},
        "diagnostics": diagnostics,
        "trust": dict(TRUST),
        **({"loo": dict(loo)} if loo is not None else {}),
        "parameters": out,
        "systematic": (
            "type-B sources mixed in by draws (the fit's budget: log theta + sum_j "
            "effects_log[p][j] xi_j, xi_j ~ N(0, 1))"
            if mixed is not None
            else "none: the fit has no systematic budget"
        ),
    }


def _ml_entry(entry: Mapping[str, Any]) -> dict[str, Any]:
    out = {
        "value": float(entry["value"]),
        "estimated": bool(entry.get("estimated", True)),
        "identified": bool(entry.get("identified", True)),
    }
    if entry.get("ci95") is not None:
        out["ci95"] = [float(x) for x in entry["ci95"]]
    profile = entry.get("profile")
    if isinstance(profile, Mapping):
        out["profile"] = {k: profile.get(k) for k in ("kind", "lower", "upper")}
    return out


def pooling_rows(records: Sequence[Mapping[str, Any]]) -> pd.DataFrame:
    """One row per vehicle, model and parameter of :data:`SHOWN`: the ML estimate and its
    95 % interval (or "not identified"), the class prior's centre and 95 % predictive
    interval, the posterior's median and 95 % interval (type B included), diagnostics."""
    rows = []
    for rec in records:
        prior = rec["prior"]
        diag = rec["diagnostics"]
        for p in SHOWN:
            entry = rec["parameters"].get(p)
            if entry is None:
                continue
            ml = entry["ml"]
            shown = ml["identified"] or not ml["estimated"]
            row = {
                "vehicle": rec["vehicle"],
                "model": rec["model"],
                "parameter": p,
                "ml": ml["value"] if ml["identified"] and ml["estimated"] else math.nan,
                "ml_lo": (ml.get("ci95") or [math.nan] * 2)[0] if shown else math.nan,
                "ml_hi": (ml.get("ci95") or [math.nan] * 2)[1] if shown else math.nan,
                "ml_status": _status(ml),
                "ml_held": ml["value"] if not ml["estimated"] else math.nan,
                "prior_from": _prior_from(prior),
                "prior": math.nan,
                "prior_lo": math.nan,
                "prior_hi": math.nan,
                "posterior": entry.get("median", math.nan),
                "posterior_lo": (entry.get("ci95") or [math.nan] * 2)[0],
                "posterior_hi": (entry.get("ci95") or [math.nan] * 2)[1],
                "sampled": bool(entry.get("sampled", False)),
                "r_hat_max": diag["r_hat_max"],
                "ess_bulk_min": diag["ess_bulk_min"],
                "divergences": diag["divergences"],
                "trusted": diag["trusted"],
            }
            if prior.get("kind") == "class" and p in prior["parameters"]:
                cp = prior["parameters"][p]
                row["prior"], (row["prior_lo"], row["prior_hi"]) = cp["value"], cp["ci95"]
            rows.append(row)
    return pd.DataFrame(rows)


def _status(ml: Mapping[str, Any]) -> str:
    if not ml["estimated"]:
        return "held"
    if ml["identified"]:
        return "estimated"
    profile = ml.get("profile") or {}
    kind, lo, hi = profile.get("kind"), profile.get("lower"), profile.get("upper")
    if kind == "upper" and hi is not None:
        return f"not identified (<= {hi:.3g})"
    if kind == "lower" and lo is not None:
        return f"not identified (>= {lo:.3g})"
    if kind == "two_sided" and lo is not None and hi is not None:
        return f"not identified ({lo:.3g} to {hi:.3g})"
    return "not identified"


def _prior_from(prior: Mapping[str, Any]) -> str:
    if prior.get("kind") != "class":
        return "the vehicle's own"
    where = prior["class"] if prior["basis"] == "class" else "all rail classes"
    return f"{where} without it ({', '.join(prior['vehicles'])})"


def _cell(x: float, lo: float, hi: float) -> str:
    if not math.isfinite(x):
        return ""
    if not (math.isfinite(lo) and math.isfinite(hi)):  # a value without an interval
        return f"{x:.4g}"
    return f"{x:.4g} [{lo:.4g}, {hi:.4g}]"


def pooling_markdown(table: pd.DataFrame, source: str) -> str:
    """The pooling table as Markdown (4 significant digits)."""
    lines = [
        "# Partial pooling: each vehicle's maximum likelihood, its class prior and its posterior",
        "",
        f"Data: {source}. Maximum likelihood: the study's fit (95 % interval, statistical "
        "and systematic). Class prior: the class reference model of the study's other "
        "vehicles (centre and 95 % predictive interval). Posterior: NUTS on the fit's "
        "likelihood times that prior, median and 95 % interval with the systematic budget "
        "mixed in by draws. A posterior is to be used only where R-hat <= "
        f"{TRUST['r_hat_max']}, bulk ESS >= {TRUST['ess_bulk_min']:.0f} and no divergences "
        "(trusted); docs/bayes.md.",
        "",
        "| vehicle | parameter | maximum likelihood [95 %] | class prior [95 %] "
        "| posterior [95 %] | R-hat / bulk ESS / divergences | prior from |",
        "|---|---|---|---|---|---|---|",
    ]
    for _, r in table.iterrows():
        ml = (
            _cell(r["ml"], r["ml_lo"], r["ml_hi"])
            if r["ml_status"] == "estimated"
            else r["ml_status"]
        )
        if r["ml_status"] == "held":
            ml = f"{_cell(r['ml_held'], r['ml_lo'], r['ml_hi'])} (held)"
        post = _cell(r["posterior"], r["posterior_lo"], r["posterior_hi"])
        if not r["trusted"]:
            post += " (not trusted)"
        diag = f"{_r_hat(r['r_hat_max'], 3)} / {r['ess_bulk_min']:.0f} / {int(r['divergences'])}"
        lines.append(
            f"| {r['vehicle']} ({r['model']}) | {r['parameter']} | {ml} "
            f"| {_cell(r['prior'], r['prior_lo'], r['prior_hi'])} | {post} | {diag} "
            f"| {r['prior_from']} |"
        )
    return "\n".join(lines) + "\n"
