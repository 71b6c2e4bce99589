"""The study's design table: for every vehicle with a second-order fit, the interval widths its
own records were predicted to give, against those its fit realised, and the shortest
programme of the paper's shape that reaches a target (rule ``design``,
``results/tables/design.{csv,md}`` and ``results/figures/design.*``).

Per vehicle and parameter (C, K_veh, C_veh):

- **realised**: the relative 95 % half-width of the fit's combined interval;
- **predicted from its fit**: :func:`railtherm.study.design.predict_runs` on the vehicle's
  own records (each identification window a record with its measured inputs, from the fit's
  simulated state at its start), the fit's estimates, its residual noise and colour less its
  systematic errors' shapes (:func:`~railtherm.study.design.residual_noise`), and the
  standard uncertainties of its systematic sources (its budget);
- **predicted before the tunnel**: the same records, from the class reference model built
  without the vehicle (its class, mass and surface; median and 5-95 % range over the model's
  draws, and the share of draws that identify the parameter) with the residual level of the
  class's other acceptable fits; none where fewer than two other vehicles of the class are
  usable.

Then the shortest programme of the paper's shape for the vehicle (its k window's steady
state held 10 h, the heating raised by half for the step and reversed, the step's two
phases scaled together, :func:`~railtherm.study.design.shortest`) whose prediction from its
fit reaches the target.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from railtherm.study import design
from railtherm.study.fit import Fit

__all__ = [
    "BUDGET_SOURCES",
    "study_design",
    "CHECKED",
    "design_markdown",
    "paper_programme",
    "systematic_of",
    "vehicle_rows",
    "write_design",
]

CHECKED = ("C", "K_veh", "C_veh")
# the fit's budget sources (fit file ``systematic.sources``) as a programme's systematic keys
BUDGET_SOURCES = {
    "offset_T": "T",
    "offset_T_veh": "T_veh",
    "offset_T_o": "T_o",
    "power_scale": "power_rel",
    "k_storage": "kA_rel",
}
STEADY_H = 10.0  # the paper-shaped programme's steady start (its k window at the end)
STEP_RISE = 0.5  # the step raises the heating by this share of the steady power
STEP_H = 24.0  # each step phase before scaling


def systematic_of(fit) -> dict[str, float]:
    """The standard uncertainties of the fit's systematic sources, as a programme names them
    (:data:`BUDGET_SOURCES`); sources of other kinds are left out."""
    sources = fit.section("systematic").get("sources") or {}
    return {BUDGET_SOURCES[k]: float(v) for k, v in sources.items() if k in BUDGET_SOURCES}


def paper_programme(
    fit, kvalue: Mapping[str, Any], step_s: float, noise_K: Mapping[str, float] | None = None
) -> design.Programme:
    """The paper's special experiment for the vehicle (section 3.2): its k window's power and
    tunnel temperature held :data:`STEADY_H` (the fit compares the last hour), the heating
    raised by :data:`STEP_RISE` of it for :data:`STEP_H`, then reversed for as long; the two
    steps fitted as two records. Noise (``noise_K``, default the fit's separated residual
    noise) and systematic uncertainties as in the fit."""
    base, T_o = float(kvalue["Q_H_mean"]), float(kvalue["T_o_mean"])
    up = base * (1.0 + STEP_RISE)
    phases = (
        design.Phase("steady", STEADY_H, T_o, ((0.0, base),), None, 1.0, "step up"),
        design.Phase("step up", STEP_H, T_o, ((0.0, up),), window="step up"),
        design.Phase("step down", STEP_H, T_o, ((0.0, base),), window="step down"),
    )
    noise = design.prior_from_fit(fit).noise_K if noise_K is None else noise_K
    limits = {"max_power_W": up}
    return design.Programme(
        f"paper-shaped, {fit.vehicle}",
        phases,
        step_s,
        dict(noise),
        systematic_of(fit),
        limits,
        "steady",
    )


def _class_prior(members, vehicle: Mapping[str, Any], vid: str, fits, draws: int, seed: int):
    """The class reference model of ``vid`` from the other members (None where it cannot be
    built, with the reason)."""
    from railtherm.errors import ConfigError
    from railtherm.study import classmodel

    missing = [k for k in ("class", "mass_kg", "surface_m2") if vehicle.get(k) is None]
    if missing:
        return None, f"the vehicle declares no {', '.join(missing)}"
    try:
        model = classmodel.build(
            members,
            vehicle["class"],
            float(vehicle["mass_kg"]),
            float(vehicle["surface_m2"]),
            exclude=[vid] if any(m.vehicle == vid for m in members) else [],
        )
    except ConfigError as err:
        return None, err.reason
    others = [fits[v] for v in model.basis if v in fits]
    return design.prior_from_reference(model, draws, seed, others), ""


def vehicle_rows(
    fits: Mapping[str, Fit],
    kvalues: Mapping[str, Mapping[str, Any] | None],
    vehicles: Mapping[str, Mapping[str, Any]],
    members: Sequence[Any],
    target: tuple[str, float],
    draws: int = 100,
    seed: int = 0,
) -> pd.DataFrame:
    """One row per vehicle and parameter of :data:`CHECKED`: the realised and predicted
    relative 95 % half-widths (fractions; NaN where not identified or not predicted, with the
    status saying which), and per vehicle the shortest paper-shaped programme to ``target``
    (hours, and its predicted half-width of the target's parameter)."""
    rows = []
    name, goal = target
    for i, (vid, fit) in enumerate(fits.items()):
        records = design.record_runs(fit)
        kvalue = kvalues.get(vid)
        static = fit.k_source.startswith("static test")
        dT_k = float(kvalue["delta_T"]) if (kvalue and static) else 0.0
        prior = design.prior_from_fit(fit)
        # a fit that does not determine a parameter gives no parameter set to predict from
        undetermined = [p for p in prior.free if not fit.parameters[p].identified]
        own = None
        if records is not None and not undetermined:
            runs, step_s = records
            own = prior.predict_runs(runs, step_s, systematic_of(fit), dT_k)
        cls, why = _class_prior(members, vehicles[vid], vid, fits, draws, seed + i)
        spread: dict[str, tuple] = {}
        if cls is not None and records is not None:
            free = tuple(p for p in cls.free if p in prior.free)
            cls = design.Prior(
                cls.structure,
                cls.theta,
                free,
                cls.source,
                cls.draws,
                cls.noise_K or prior.noise_K,
                *(
                    (cls.tau_samples, cls.tau_step_s)
                    if cls.tau_samples
                    else (prior.tau_samples, prior.tau_step_s)
                ),
            )
            preds = [
                cls.predict_runs(runs, step_s, systematic_of(fit), dT_k, theta)
                for theta in cls.thetas()
            ]
            widths, shares = design.spread(preds, CHECKED)
            spread = {p: (*widths[p], shares[p]) for p in CHECKED}
        shortest_h = shortest_w = math.nan
        if kvalue and own is not None and name in prior.free:
            programme = paper_programme(fit, kvalue, records[1], prior.noise_K)
            found = design.shortest(
                prior,
                programme,
                target,
                0.5,
                tuple(np.round(np.geomspace(0.05, 4.0, 65), 4)),
                keep_first=True,
            )
            if found is not None:
                shortest_h = found[1].programme.hours
                shortest_w = found[1].central.half_width[name]
        hours = sum(len(r.u) for r in records[0]) * records[1] / 3600.0 if records else math.nan
        for p in CHECKED:
            par = fit.parameters.get(p)
            ci = None if par is None else par.ci95_combined
            identified = par is not None and par.identified and ci is not None
            realised = (
                math.sqrt(ci[1] / ci[0]) - 1.0 if identified else math.nan
            )  # exp of the combined interval's log half-width, less 1
            predicted = own.half_width[p] if own is not None and own.identifiable[p] else math.nan
            lo, med, hi, share = spread.get(p, (math.nan,) * 4)
            rows.append(
                {
                    "vehicle": vid,
                    "class": vehicles[vid].get("class", ""),
                    "records_h": hours,
                    "parameter": p,
                    "realised": realised,
                    "realised_status": "estimated" if identified else "not identified",
                    "predicted": predicted,
                    "predicted_status": (
                        f"not predicted ({', '.join(undetermined)} not identified by the fit)"
                        if undetermined
                        else "not predicted (no series)"
                        if own is None
                        else ("predicted" if own.identifiable[p] else "not identifiable")
                    ),
                    "class_median": med,
                    "class_q05": lo,
                    "class_q95": hi,
                    "class_identifiable_share": share,
                    "class_note": why if cls is None else "",
                    "target": f"{name}={100 * goal:g}%",
                    "shortest_h": shortest_h,
                    "shortest_predicted": shortest_w,
                }
            )
    return pd.DataFrame(rows)


def _pct(x: float) -> str:
    """A relative half-width in percent, 3 significant digits; above 1000 % only so."""
    if math.isnan(x):
        return "—"
    if not math.isfinite(x):
        return "not identifiable"
    return "> 1000 %" if x > 10.0 else f"{100 * x:.3g} %"


def design_markdown(table: pd.DataFrame, source: str) -> str:
    """The design table for readers."""
    target = table["target"].iloc[0] if len(table) else ""
    lines = [
        "# Design: the intervals each vehicle's records were predicted to give, and the",
        "# shortest paper-shaped programme to the target",
        "",
        f"Data: {source}. Relative 95 % half-widths. Predicted from the vehicle's fit: its own "
        "records, its estimates, its residual noise less its systematic errors' shapes, its "
        "systematic budget. Before the tunnel: the class reference model without the "
        "vehicle, median [5 %, 95 %] over its draws and the share of draws that identify the "
        "parameter. Shortest programme: the paper's shape (k window's steady state 10 h, "
        f"heating +50 % and reversed, the two steps scaled together) predicted to reach {target}"
        " (railtherm.study.designstudy).",
        "",
        "| vehicle | parameter | realised ± | predicted from its fit | before the tunnel "
        "(class model) | shortest programme |",
        "|---|---|---|---|---|---|",
    ]
    for _, r in table.iterrows():
        realised = _pct(r["realised"]) if r["realised_status"] == "estimated" else "not identified"
        predicted = (
            _pct(r["predicted"]) if r["predicted_status"] == "predicted" else r["predicted_status"]
        )
        if math.isfinite(r["class_median"]):
            before = (
                f"{_pct(r['class_median'])} [{_pct(r['class_q05'])}, {_pct(r['class_q95'])}], "
                f"{100 * r['class_identifiable_share']:.0f} % of draws identify it"
            )
        else:
            note = str(r["class_note"])
            few = "usable vehicle" in note or "no vehicle among" in note
            before = f"no class model ({'fewer than 2 other usable vehicles' if few else note})"
        short = ""
        if r["parameter"] == target.partition("=")[0]:
            if math.isfinite(r["shortest_h"]):
                short = f"{r['shortest_h']:.3g} h (± {_pct(r['shortest_predicted'])})"
            elif r["predicted_status"].startswith("not predicted"):
                short = "not predicted"
            else:
                short = "none up to 4 times the shape"
        lines.append(
            f"| {r['vehicle']} | {r['parameter']} | {realised} | {predicted} | {before} | {short} |"
        )
    return "\n".join(lines) + "\n"


def write_design(table: pd.DataFrame, source: str, csv: str, md: str, figure: str) -> None:
    """The design table as CSV (4 significant digits) and Markdown, and its figure
    (``figure``: the path without suffix; PNG and SVG)."""
    from railtherm.report import plots, tables

    tables.write_csv(table, csv, digits=4)
    with open(md, "w", encoding="utf-8") as stream:
        stream.write(design_markdown(table, source))
    plots.save_figure(plots.design_figure(table, note=source), figure)


def study_design(
    table2: str,
    vehicles: Mapping[str, Mapping[str, Any]],
    fit_files: Sequence[str],
    series_files: Sequence[str],
    kvalue_files: Mapping[str, str],
    target: str,
    draws: int = 100,
    seed: int = 0,
) -> pd.DataFrame:
    """:func:`vehicle_rows` over a study's files: each vehicle's second-order fit file and
    its series (in the order of ``vehicles``, {id: config}), its static k result where it has
    one (``kvalue_files``: {id: path}), the class members from its Table 2
    (:func:`railtherm.study.classmodel.members_from_table2`) and ``target`` as the config
    writes it (``C_veh=10%``)."""
    from railtherm.io import read_result
    from railtherm.study import classmodel
    from railtherm.study.fit import read_fit

    fits = {
        vid: read_fit(path, series)
        for vid, path, series in zip(vehicles, fit_files, series_files, strict=True)
    }
    kvalues = {vid: read_result(path) for vid, path in kvalue_files.items()}
    members = classmodel.members_from_table2(table2, vehicles)
    parsed = design.parse_target(target)
    return vehicle_rows(fits, kvalues, vehicles, members, parsed, draws=draws, seed=seed)
