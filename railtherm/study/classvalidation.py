"""How good is the class generalisation? A leave-one-out validation of the class reference
model (:mod:`railtherm.study.classmodel`; the paper's c_veh and delta, eqs. 24-25, section 6.3).

For each vehicle with an acceptable fit, the reference model of its class is built without
it (and, as a comparator, the model of every rail class pooled), from its mass and surface
only - with k from the class, and with its own measured k (the static test, eq. 10, is often
run where no heat-up test is). That model then

- predicts the vehicle's identification windows (the measured T_o and Q_H, from the same
  initial state as the vehicle's own fit): the RMSE of T against the measurement, beside
  the RMSE of the vehicle's own fit (eq. 15, K = 0);
- predicts a scenario (:mod:`railtherm.study.scenario`): the heat-up time and the energy with
  their 95 % prediction bands, beside the same scenario through the vehicle's own
  identified model.

A class with too few vehicles left to build a model from is reported as such, with the
minimum (``reference_model.min_vehicles``). A model resting on fewer than
:data:`MIN_BAND_VEHICLES` other vehicles gives its central prediction without a band: the
class spread from two vehicles is a t with one degree of freedom (a Cauchy), whose band
reaches any value (``band_note`` says so). The bands' draws are held to the physical limits
(:mod:`railtherm.study.simulate`: C at least the capacity of the vehicle's air, ρ c_p V); where the
vehicle's data are synthetic, its declared truth (the virtual campaign's parameters) is run
through the same scenario (``heat_up_true_h``) and compared with the reference band.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from railtherm.errors import ConfigError
from railtherm.estimation import models
from railtherm.study import classmodel
from railtherm.study import simulate as sim
from railtherm.study.fit import Fit
from railtherm.study.scenario import Scenario

__all__ = ["leave_one_out", "window_rmse", "summary_lines", "validation_markdown"]

BASES = ("class", "pooled")
COLUMNS = (
    "vehicle",
    "class",
    "basis",
    "k_from",
    "n_basis",
    "basis_vehicles",
    "status",
    "rmse_ref_K",
    "rmse_fit_K",
    "heat_up_ref_h",
    "heat_up_ref_h_lo",
    "heat_up_ref_h_hi",
    "heat_up_fit_h",
    "heat_up_fit_h_lo",
    "heat_up_fit_h_hi",
    "heat_up_ratio",
    "heat_up_inside",
    "heat_up_true_h",
    "heat_up_true_inside",
    "band_note",
    "draws_rejected_pct",
    "energy_ref_kWh",
    "energy_ref_kWh_lo",
    "energy_ref_kWh_hi",
    "energy_fit_kWh",
    "energy_ratio",
    "energy_inside",
)
K_FROM = ("class", "measured")
MIN_BAND_VEHICLES = 3  # a reference band needs the spread of at least this many vehicles


def window_rmse(theta: Mapping[str, float], structure: models.Structure, series: pd.DataFrame):
    """RMSE of T (K) of the model ``theta`` over every identification window of ``series``
    (the fit's series: measured inputs, measured T, the fit's simulated states), from the
    fit's own initial states; and the same for the fit's simulated T."""
    errors, fit_errors = [], []
    for _, w in series.groupby("window", sort=False):
        t = w["time"].to_numpy(float)
        dt = float(np.median(np.diff(t)))
        u = w[list(structure.inputs)].to_numpy(float)
        x0 = [float(w[f"{s}_sim"].iloc[0]) for s in structure.states]
        x = models.simulate(structure, theta, u, dt, x0)
        measured = w["T"].to_numpy(float)
        ok = np.isfinite(measured)
        errors.append(x[ok, 0] - measured[ok])
        fit_errors.append(w["T_sim"].to_numpy(float)[ok] - measured[ok])
    e, f = np.concatenate(errors), np.concatenate(fit_errors)
    return float(np.sqrt(np.mean(e**2))), float(np.sqrt(np.mean(f**2)))


def _band(o: sim.Outcome, scale: float) -> tuple[float, float, float]:
    def v(x: float | None) -> float:
        return math.nan if x is None else x / scale

    value = (
        v(o.value) if o.status == "ok" else (math.inf if o.status != "not requested" else math.nan)
    )
    return value, v(o.lo), v(o.hi)


def _inside(x: float, lo: float, hi: float) -> Any:
    if any(math.isnan(v) for v in (x, lo, hi)):
        return None
    return bool(lo <= x <= hi)


def _compared(stem: str, unit: str, ref: tuple, own: tuple, own_band: bool) -> dict[str, Any]:
    """The columns of one outcome: the reference model's value and band, the vehicle's own,
    their ratio and whether the own value lies inside the reference band."""
    out = {
        f"{stem}_ref_{unit}": ref[0],
        f"{stem}_ref_{unit}_lo": ref[1],
        f"{stem}_ref_{unit}_hi": ref[2],
        f"{stem}_fit_{unit}": own[0],
    }
    if own_band:
        out[f"{stem}_fit_{unit}_lo"], out[f"{stem}_fit_{unit}_hi"] = own[1], own[2]
    out[f"{stem}_ratio"] = ref[0] / own[0] if own[0] else math.nan
    out[f"{stem}_inside"] = _inside(own[0], ref[1], ref[2])
    return out


def true_heat_up_h(truth: Mapping[str, float], scenario: Scenario, vehicle: str) -> float:
    """The heat-up time (h) of ``scenario`` through the second-order model (eqs. 7-8) at the
    declared true parameters ``truth`` (kA, C, K_veh, C_veh: the virtual campaign's,
    :func:`railtherm.synth.ground_truth_table`); inf where the threshold is not reached."""
    structure = models.structure_for(classmodel.STRUCTURE)
    missing = [p for p in structure.parameters if p not in truth]
    if missing:
        raise ConfigError(f"truth of {vehicle}", "parameters", sorted(truth), f"lacks {missing}")
    ps = sim.ParameterSet(
        label=f"{vehicle} (declared truth)",
        source="ground truth of the virtual campaign",
        structure=structure,
        theta={p: float(truth[p]) for p in structure.parameters},
    )
    o = sim.simulate(ps, scenario, draws=0, allow_unreachable=True).outcomes["heat_up_time_s"]
    return _band(o, 3600.0)[0]


def leave_one_out(
    members: Sequence[classmodel.ClassMember],
    fits: Mapping[str, Fit],
    series: Mapping[str, pd.DataFrame],
    scenario: Scenario,
    min_vehicles: int = 2,
    draws: int = sim.DEFAULT_DRAWS,
    seed: int = 0,
    volumes: Mapping[str, float | None] | None = None,
    truth: Mapping[str, Mapping[str, float]] | None = None,
) -> pd.DataFrame:
    """One row per usable vehicle, basis (its class, every rail class pooled) and source of
    k (the class's, its own measured one): the model from the other vehicles, its RMSE over
    the vehicle's windows and its heat-up time and energy in ``scenario`` with 95 % bands,
    beside the vehicle's own fit; or why no model could be built (status).

    A model from fewer than :data:`MIN_BAND_VEHICLES` other vehicles has no band
    (``band_note``). ``volumes``: each vehicle's ``volume_m3``, the floor of the draws' air
    capacity (its own fit's and its reference model's). ``truth``: by vehicle, the declared
    kA, C, K_veh and C_veh of a synthetic vehicle; its heat-up time (``heat_up_true_h``) and
    whether the reference band holds it (``heat_up_true_inside``)."""
    volumes = volumes or {}
    truth = truth or {}
    rows = []
    usable = [m for m in members if m.usable and m.vehicle in fits]
    for i, m in enumerate(usable):
        fit = fits[m.vehicle]
        volume = volumes.get(m.vehicle)
        own = sim.simulate(
            fit,
            scenario,
            draws=draws,
            seed=seed + 100 * i,
            allow_unreachable=True,
            volume_m3=volume,
        )
        own_heat = _band(own.outcomes["heat_up_time_s"], 3600.0)
        own_energy = _band(own.outcomes["energy_kWh"], 1.0)
        true_h = (
            true_heat_up_h(truth[m.vehicle], scenario, m.vehicle)
            if m.vehicle in truth
            else math.nan
        )
        for basis in BASES:
            for k_from in K_FROM:
                row: dict[str, Any] = {
                    "vehicle": m.vehicle,
                    "class": m.vehicle_class,
                    "basis": basis,
                    "k_from": k_from,
                }
                try:
                    ref = classmodel.build(
                        members,
                        m.vehicle_class if basis == "class" else "all",
                        m.mass_kg,
                        m.surface_m2,
                        k=m.k if k_from == "measured" else None,
                        min_vehicles=min_vehicles,
                        exclude=[m.vehicle],
                    )
                except ConfigError as err:
                    n = sum(
                        1
                        for o in members
                        if o.usable
                        and o.vehicle != m.vehicle
                        and (basis == "pooled" or o.vehicle_class == m.vehicle_class)
                    )
                    row["n_basis"] = n
                    if n >= min_vehicles:  # refused for another reason: say it whole
                        row["status"] = f"no model: {err.reason}"
                    else:
                        row["status"] = (
                            f"too few vehicles: {n} other with an acceptable fit, "
                            f"{min_vehicles} needed"
                        )
                    rows.append(row)
                    continue
                ps = sim.parameter_set(ref)
                rmse_ref, rmse_fit = window_rmse(ps.theta, ps.structure, series[m.vehicle])
                few = len(ref.basis) < MIN_BAND_VEHICLES
                pred = sim.simulate(
                    ps,
                    scenario,
                    draws=0 if few else draws,
                    seed=seed + 100 * i + 7,
                    allow_unreachable=True,
                    volume_m3=volume,
                )
                heat = _band(pred.outcomes["heat_up_time_s"], 3600.0)
                energy = _band(pred.outcomes["energy_kWh"], 1.0)
                note = pred.band_withheld
                if few:
                    note = (
                        f"no band: the class statistic rests on {len(ref.basis)} other "
                        f"vehicles, fewer than {MIN_BAND_VEHICLES}"
                    )
                elif pred.rejected:
                    note = pred.limit_note()
                row.update(
                    {
                        "n_basis": len(ref.basis),
                        "basis_vehicles": " ".join(ref.basis),
                        "status": "predicted",
                        "rmse_ref_K": rmse_ref,
                        "rmse_fit_K": rmse_fit,
                        **_compared("heat_up", "h", heat, own_heat, own_band=True),
                        **_compared("energy", "kWh", energy, own_energy, own_band=False),
                        "heat_up_true_h": true_h,
                        "heat_up_true_inside": _inside(true_h, heat[1], heat[2]),
                        "band_note": note,
                        "draws_rejected_pct": (
                            100.0 * pred.rejected_share if pred.draws else math.nan
                        ),
                    }
                )
                rows.append(row)
    return pd.DataFrame(rows, columns=list(COLUMNS))


def summary_lines(table: pd.DataFrame) -> list[str]:
    """Per basis and source of k: how many vehicles were predicted, the median factor
    between the predicted and the identified heat-up time (max(r, 1/r)), how many own
    heat-up times lie inside the 95 % prediction band, and the median RMSE ratio."""
    lines = []
    done = table[table["status"] == "predicted"] if "status" in table else table.iloc[:0]
    for basis in BASES:
        for k_from in K_FROM:
            part = done[(done["basis"] == basis) & (done["k_from"] == k_from)]
            n_total = int(((table["basis"] == basis) & (table["k_from"] == k_from)).sum())
            if part.empty:
                lines.append(
                    f"- {basis}, k from {k_from}: no vehicle could be predicted "
                    f"({n_total} tried; too few vehicles left in the class)"
                )
                continue
            r = part["heat_up_ratio"].astype(float).to_numpy()
            r = r[~np.isnan(r) & (r > 0)]
            with np.errstate(divide="ignore"):
                factor = float(np.median(np.maximum(r, 1 / r))) if len(r) else math.nan
            lo = part["heat_up_ref_h_lo"].astype(float).to_numpy()
            hi = part["heat_up_ref_h_hi"].astype(float).to_numpy()
            banded = ~np.isnan(lo)
            rmse_ratio = float(np.median(part["rmse_ref_K"] / part["rmse_fit_K"]))
            rmse = part["rmse_ref_K"].astype(float)
            text = (
                f"- {basis}, k from {k_from}: {len(part)} of {n_total} vehicles predicted; "
                f"heat-up time off by a median factor {factor:.2f}; "
            )
            if banded.any():
                inside = part["heat_up_inside"][banded].dropna()
                text += (
                    f"the own heat-up time inside the 95 % band for {int(inside.sum())} of "
                    f"{len(inside)}, the band reaching from a median "
                    f"{np.median(lo[banded]):.2g} h to beyond the scenario's end for "
                    f"{int(np.isinf(hi[banded]).sum())} of {int(banded.sum())}; "
                )
                if "heat_up_true_inside" in part:
                    true_inside = part["heat_up_true_inside"][banded].dropna()
                    if len(true_inside):
                        text += (
                            f"the declared truth's heat-up time inside the band for "
                            f"{int(true_inside.astype(bool).sum())} of {len(true_inside)}; "
                        )
            if (~banded).any():
                text += (
                    f"no band for {int((~banded).sum())} (fewer than {MIN_BAND_VEHICLES} other "
                    "vehicles, or none within the physical limits); "
                )
            lines.append(
                text + f"RMSE of T over the measured windows {rmse.min():.2g} to "
                f"{rmse.max():.2g} K, a median {rmse_ratio:.0f}× the vehicle's own fit"
            )
    return lines


def _cell(x: Any, digits: int = 3) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return ""
    if isinstance(x, float) and math.isinf(x):
        return "not reached"
    return f"{x:.{digits}g}"


def validation_markdown(table: pd.DataFrame, scenario: Scenario, source: str) -> str:
    """The leave-one-out table for people, with its summary."""
    lines = [
        "**Leave-one-out validation of the class reference model (c_veh, δ of eqs. 24-25, "
        "κ_veh = K_veh / A, k): each vehicle with an acceptable fit predicted from the other "
        f"vehicles of its class, and of every class pooled.** Data: {source}.",
        "",
        f"Scenario: {scenario.name} (heat-up to {scenario.heat_up_to_C:g} °C). RMSE: T over "
        "the vehicle's own identification windows, from its fit's initial state.",
        "",
        "| Name | class | basis | k from | n | RMSE ref (K) | RMSE fit (K) | heat-up ref (h) "
        "| heat-up fit (h) | inside | heat-up truth (h) | truth inside | energy ref (kWh) "
        "| energy fit (kWh) |",
        "|:--|:--|:--|:--|--:|--:|--:|--:|--:|:--|--:|:--|--:|--:|",
    ]
    notes = []
    for _, r in table.iterrows():
        if r["status"] != "predicted":
            lines.append(
                f"| {r['vehicle']} | {r['class']} | {r['basis']} | {r['k_from']} | "
                f"{int(r['n_basis'])} | {r['status']} | | | | | | | | |"
            )
            continue

        def band(stem: str, r: Any = r) -> str:
            lo, hi = r[stem + "_lo"], r[stem + "_hi"]
            if lo is None or (isinstance(lo, float) and math.isnan(lo)):
                return f"{_cell(r[stem])} ‡"
            return (
                f"{_cell(r[stem])} [{_cell(lo)}, "
                f"{_cell(hi) if math.isfinite(hi) else '> duration'}]"
            )

        yes_no = {True: "yes", False: "no"}
        note = r.get("band_note")
        if isinstance(note, str) and note:
            notes.append(f"- {r['vehicle']}, {r['basis']}, k from {r['k_from']}: {note}")
        lines.append(
            f"| {r['vehicle']} | {r['class']} | {r['basis']} | {r['k_from']} | "
            f"{int(r['n_basis'])} | {_cell(r['rmse_ref_K'])} | {_cell(r['rmse_fit_K'])} | "
            f"{band('heat_up_ref_h')} | {_cell(r['heat_up_fit_h'])} | "
            f"{yes_no.get(r['heat_up_inside'], '')} | {_cell(r.get('heat_up_true_h'))} | "
            f"{yes_no.get(r.get('heat_up_true_inside'), '')} | "
            f"{band('energy_ref_kWh')} | {_cell(r['energy_fit_kWh'])} |"
        )
    lines += ["", *notes] if notes else []
    lines += ["", "Summary:", "", *summary_lines(table), ""]
    lines += [
        "- Bands: 95 % prediction bands of a new vehicle of the class (the spread of the "
        "other vehicles' generalised parameters, Student t), railtherm.study.classmodel.",
        "- inside: the vehicle's own identified heat-up time lies within the reference "
        "model's band; truth inside: the heat-up time of the vehicle's declared true parameters "
        "(synthetic data only) lies within it.",
        f"- ‡: no band, the central prediction only (why: in the notes under the table): the "
        f"class statistic rests on fewer than {MIN_BAND_VEHICLES} other vehicles (a t with one "
        "degree of freedom reaches any value).",
        "- The bands' draws are truncated at the physical limits by rejection sampling: every "
        "capacity and conductance > 0 and C at least the capacity of the vehicle's air, "
        "ρ c_p V, so that no draw heats up faster than the air alone.",
        "- A class whose other vehicles number fewer than reference_model.min_vehicles has no "
        "model; the pooled basis takes every rail class together.",
    ]
    return "\n".join(lines) + "\n"


TRUTH_PARAMETERS = ("kA", "C", "K_veh", "C_veh")


def declared_truth(path: str | None, vehicles: Iterable[str]) -> dict[str, dict[str, float]]:
    """The declared kA, C, K_veh, C_veh of each listed vehicle found in a synthetic
    campaign's ``ground_truth.csv`` (``path`` None or empty: no truth, e.g. measured data)."""
    if not path:
        return {}
    declared = pd.read_csv(path).set_index("vehicle")
    return {
        vid: declared.loc[vid, list(TRUTH_PARAMETERS)].astype(float).to_dict()
        for vid in vehicles
        if vid in declared.index
    }


def study_leave_one_out(
    table2: str,
    vehicles: Mapping[str, Mapping[str, Any]],
    fit_files: Sequence[str],
    series_files: Sequence[str],
    scenario: Scenario,
    truth_file: str | None = None,
    **options: Any,
) -> pd.DataFrame:
    """:func:`leave_one_out` over a study's files: the members from its Table 2
    (:func:`railtherm.study.classmodel.members_from_table2`, each vehicle's config in ``vehicles``),
    each vehicle's second-order fit file and series table (in the order of ``vehicles``), the
    vehicles' volumes and, for a synthetic campaign, the truth of ``truth_file``. ``options``
    go to :func:`leave_one_out` (min_vehicles, draws, seed)."""
    from railtherm.study.fit import read_fit

    members = classmodel.members_from_table2(table2, vehicles)
    fits = {vid: read_fit(path) for vid, path in zip(vehicles, fit_files, strict=True)}
    series = {vid: pd.read_csv(path) for vid, path in zip(vehicles, series_files, strict=True)}
    return leave_one_out(
        members,
        fits,
        series,
        scenario,
        volumes={vid: data.get("volume_m3") for vid, data in vehicles.items()},
        # a campaign's truth is of its synthetic vehicles: a measured one is never set
        # beside it, whatever its id
        truth=declared_truth(truth_file, [v for v, d in vehicles.items() if d.get("synthetic")]),
        **options,
    )


def write_validation(
    table: pd.DataFrame,
    scenario: Scenario,
    vehicles: Mapping[str, Mapping[str, Any]],
    csv: str,
    md: str,
    figure: str,
) -> None:
    """The leave-one-out table of ``vehicles`` (id -> config) as CSV (4 significant digits)
    and Markdown, and its figure (``figure``: the path without suffix; PNG and SVG), whose
    footer names the measured vehicles of a mixed study."""
    from railtherm.report import plots, tables
    from railtherm.study import aggregate

    tables.write_csv(table, csv, digits=4)
    with open(md, "w", encoding="utf-8") as stream:
        stream.write(validation_markdown(table, scenario, aggregate.data_source(vehicles)))
    sources = [aggregate.vehicle_source(vehicles.get(v, {})) for v in table["vehicle"]]
    fig = plots.reference_validation_figure(
        table, note=plots.provenance_note(table.assign(source=sources))
    )
    plots.save_figure(fig, figure)
