"""The study's predictions: every declared scenario run through every vehicle's identified
second-order model (eqs. 7-8), tabulated with 95 % bands (rule ``simulate``).

A fit whose parameters the data do not all determine is not simulated: its row says which
parameter is not identified. A fit whose verdict is not "fit acceptable" gives its central
prediction without a band (column ``no_band`` says why; marked :data:`DOUBT_MARK` in the
Markdown table). The bands' parameter draws are held to the physical limits (C at least the
capacity of the air in the vehicle's ``volume_m3``, :mod:`railtherm.study.simulate`); column
``draws_rejected_pct`` gives the share of draws rejected there. A set point the heating
cannot hold is reported as "unreachable", with the load it would need. Times are written in
hours, energy in kWh and power in kW, at 4 significant digits in the CSV
(:func:`railtherm.report.tables.write_csv`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import pandas as pd

from railtherm.report import tableformat
from railtherm.study import simulate as sim
from railtherm.study.fit import Fit
from railtherm.study.scenario import Scenario

__all__ = ["DOUBT_MARK", "OUTCOMES", "outcome_text", "scenario_markdown", "scenario_table"]

# (outcome key, column stem, scale to the column's unit, unit)
OUTCOMES = (
    ("heat_up_time_s", "heat_up_h", 3600.0, "h"),
    ("cool_down_time_s", "cool_down_h", 3600.0, "h"),
    ("energy_kWh", "energy_kWh", 1.0, "kWh"),
    ("peak_power_W", "peak_kW", 1000.0, "kW"),
    ("final_T_C", "final_T_C", 1.0, "°C"),
)
DIGITS = 4  # significant digits of the CSV
DOUBT_MARK = "†"  # a prediction without a band: the fit's assumptions are in doubt


def _row_outcomes(result: sim.SimulationResult) -> dict[str, Any]:
    row: dict[str, Any] = {}
    for key, stem, scale, _ in OUTCOMES:
        o = result.outcomes[key]

        def scaled(v: float | None, scale: float = scale) -> float:
            return math.nan if v is None else v / scale

        row[stem] = scaled(o.value) if o.status == "ok" else math.nan
        row[f"{stem}_lo"] = scaled(o.lo)
        row[f"{stem}_hi"] = scaled(o.hi)
        row[f"{stem}_status"] = o.status
    return row


def scenario_table(
    fits: Mapping[str, Fit],
    classes: Mapping[str, str],
    scenarios: Sequence[Scenario],
    draws: int = sim.DEFAULT_DRAWS,
    seed: int = 0,
    volumes: Mapping[str, float | None] | None = None,
) -> tuple[pd.DataFrame, dict[tuple[str, str], sim.SimulationResult]]:
    """One row per scenario and vehicle (in the given orders): the outcomes with their 95 %
    bands, or why the vehicle was not simulated; and the simulation results by (scenario,
    vehicle). Each run draws from its own seed (``seed`` + its position), so a row does not
    depend on which other vehicles the study holds. ``volumes``: each vehicle's
    ``volume_m3``, the floor of its draws' air capacity (a vehicle without one has its draws
    held to positive values only)."""
    volumes = volumes or {}
    rows, results = [], {}
    for i, sc in enumerate(scenarios):
        for j, (vid, fit) in enumerate(fits.items()):
            row: dict[str, Any] = {
                "scenario": sc.name,
                "vehicle": vid,
                "class": classes.get(vid, ""),
                "model": fit.model,
                "verdict": fit.verdict,
            }
            try:
                result = sim.simulate(
                    fit,
                    sc,
                    draws=draws,
                    seed=seed + 1000 * i + j,
                    allow_unreachable=True,
                    volume_m3=volumes.get(vid),
                )
            except sim.NotPredictable as err:
                names = ", ".join(err.value)
                row["status"] = f"not simulated: {names} not identified"
                rows.append(row)
                continue
            results[sc.name, vid] = result
            row["status"] = "; ".join(result.notes) if result.notes else "simulated"
            row["no_band"] = result.band_withheld
            row["draws_rejected_pct"] = 100.0 * result.rejected_share if result.draws else math.nan
            row.update(_row_outcomes(result))
            rows.append(row)
    return pd.DataFrame(rows), results


def outcome_text(row: Mapping[str, Any], stem: str, unit: str, duration_h: float) -> str:
    """``value [lo, hi]`` at 3 significant digits; an open band as "> duration"; the status
    where there is no value; a value whose band is withheld (``no_band``) marked
    :data:`DOUBT_MARK`."""
    mark = f" {DOUBT_MARK}" if isinstance(row.get("no_band"), str) and row["no_band"] else ""
    status = row.get(f"{stem}_status")
    if not isinstance(status, str):
        return str(row.get("status", ""))
    if status == "not requested":
        return ""

    def fmt(v: Any) -> str:
        if v is None or (isinstance(v, float) and math.isnan(v)):
            return "?"
        if math.isinf(v):
            return f"> {duration_h:g}" if unit == "h" else "∞"
        return f"{v:.3g}" if abs(v) < 1000 else tableformat.grouped(v)

    band = ""
    if not pd.isna(row.get(f"{stem}_lo")):
        band = f" [{fmt(row[f'{stem}_lo'])}, {fmt(row[f'{stem}_hi'])}]"
    if status == "ok":
        return f"{fmt(row[stem])}{band}{mark}"
    if status == "not reached":
        return f"not reached (> {duration_h:g} h){band}{mark}"
    return f"{status}{band}{mark}"


def scenario_markdown(
    table: pd.DataFrame,
    scenarios: Sequence[Scenario],
    source: str,
    draws: int,
    volumes: Mapping[str, float | None] | None = None,
) -> str:
    """The scenario table for people: one section per scenario, only the outcomes it asks
    for, with its description and source; the share of draws rejected at the physical limits
    where it is not 0; ``volumes`` (by vehicle) to name the vehicles without a volume."""
    parts = [
        "**Predictions of the identified second-order models (eqs. 7-8) for the study's "
        f"scenarios, with 95 % bands.** Data: {source}.",
        "",
    ]
    for sc in scenarios:
        part = table[table["scenario"] == sc.name]
        no_heating = sc.controller is None and not (sc.heating_W > 0).any()
        wanted = [
            (stem, unit)
            for _, stem, _, unit in OUTCOMES
            if f"{stem}_status" in part
            and part[f"{stem}_status"].dropna().ne("not requested").any()
            and not (no_heating and stem in ("energy_kWh", "peak_kW"))
        ]
        labels = {
            "heat_up_h": f"heat-up to {sc.heat_up_to_C or 0:g} °C (h)",
            "cool_down_h": f"cool-down to {sc.cool_down_to_C or 0:g} °C (h)",
            "energy_kWh": f"energy over the {sc.duration_s / 3600.0:g} h (kWh)",
            "peak_kW": f"peak power over the {sc.duration_s / 3600.0:g} h (kW)",
            "final_T_C": "T at the end (°C)",
        }
        lines = [
            f"### {sc.name}",
            "",
            " ".join(sc.description.split()),
            "",
            "| Name | class | " + " | ".join(labels[s] for s, _ in wanted) + " | verdict |",
            "|:--|:--|" + "--:|" * len(wanted) + ":--|",
        ]
        notes = []
        for _, row in part.iterrows():
            if str(row["status"]).startswith("not simulated"):
                cells = [row["status"]] + [""] * (len(wanted) - 1)
            else:
                cells = [outcome_text(row, s, u, sc.duration_s / 3600.0) for s, u in wanted]
                if row["status"] != "simulated":
                    notes.append(f"- {row['vehicle']}: {row['status']}")
                rejected = row.get("draws_rejected_pct")
                if isinstance(rejected, float) and rejected > 0:
                    notes.append(f"- {row['vehicle']}: {sim.rejected_note(rejected / 100.0)}")
            lines.append(
                f"| {row['vehicle']} | {row['class']} | "
                + " | ".join(cells)
                + f" | {row['verdict']} |"
            )
        lines += ["", *notes, "", f"Source of the scenario: {' '.join(sc.source.split())}", ""]
        parts += lines
    no_volume = [v for v in table["vehicle"].unique() if volumes is not None and not volumes.get(v)]
    parts += [
        f"- Bands: 2.5 and 97.5 % quantiles of {draws} runs with parameter sets drawn from each "
        "fit's statistical covariance and its systematic (type B) error sources, kA of the "
        "static test included (railtherm.study.simulate). The draws are truncated at the physical "
        "limits by rejection sampling: every capacity and conductance > 0, and C at least the "
        "capacity of the vehicle's air, ρ c_p V, so that no draw heats up faster than the air "
        "alone would"
        + (f" (no volume_m3, positivity only: {', '.join(no_volume)})" if no_volume else "")
        + ".",
        f"- {DOUBT_MARK}: assumptions in doubt, no band: the fit's verdict is not \"fit "
        'acceptable", and its intervals hold only where its assumptions do; the central '
        "prediction is given.",
        "- not simulated: a parameter the data do not determine would set the prediction "
        "(results/vehicles/<id>/fit_order2.yaml).",
        "- Scenario keys and the controller: docs/simulation.md.",
    ]
    return "\n".join(parts) + "\n"


def scenario_runs_figure(
    table: pd.DataFrame,
    runs: Mapping[tuple[str, str], sim.SimulationResult],
    scenario: Scenario,
    vehicles: Sequence[str],
    source: str,
):
    """The figure of one ``scenario`` through every vehicle's model: a vehicle whose band is
    withheld (assumptions in doubt) marked :data:`DOUBT_MARK`, a vehicle not simulated named
    in the note (the table says why), the data's provenance beside it."""
    from railtherm.report import plots

    shown = {
        vid + (f" {DOUBT_MARK}" if run.band_withheld else ""): run
        for (name, vid), run in runs.items()
        if name == scenario.name
    }
    doubt = (
        f" ({DOUBT_MARK}: assumptions in doubt, no band)"
        if any(DOUBT_MARK in v for v in shown)
        else ""
    )
    notes = []
    left = [vid for vid in vehicles if (scenario.name, vid) not in runs]
    if left:
        notes.append(f"not drawn: {', '.join(left)} (not simulated, see the scenario table)")
    provenance = plots.provenance_note(table.assign(source=source))
    if provenance:
        notes.append(provenance)
    return plots.scenario_figure(
        shown,
        title=f"{scenario.name}: identified second-order models, 95 % bands{doubt}",
        threshold_C=scenario.heat_up_to_C,
        note="; ".join(notes) or None,
    )


def write_study_predictions(
    fits: Mapping[str, Fit],
    vehicles: Mapping[str, Mapping[str, Any]],
    scenarios: Sequence[Scenario],
    figure_scenario: str,
    csv: str,
    md: str,
    figure: str,
    draws: int = sim.DEFAULT_DRAWS,
    seed: int = 0,
) -> pd.DataFrame:
    """The study's scenario predictions (rule simulate): every scenario through every
    vehicle's fit (``vehicles``: id -> its validated config, for its class and volume), the
    table as CSV (:data:`DIGITS` significant digits) and Markdown, and the figure of the
    scenario named ``figure_scenario`` (``figure``: the path without suffix; PNG and SVG).
    Returns the table."""
    from railtherm.report import plots, tables
    from railtherm.study.aggregate import data_source

    classes = {vid: str(data["class"]) for vid, data in vehicles.items()}
    volumes = {vid: data.get("volume_m3") for vid, data in vehicles.items()}
    table, runs = scenario_table(fits, classes, scenarios, draws=draws, seed=seed, volumes=volumes)
    source = data_source(vehicles)
    tables.write_csv(table, csv, digits=DIGITS)
    with open(md, "w", encoding="utf-8") as stream:
        stream.write(scenario_markdown(table, scenarios, source, draws, volumes))
    chosen = next(sc for sc in scenarios if sc.name == figure_scenario)
    fig = scenario_runs_figure(table, runs, chosen, list(fits), source)
    plots.save_figure(fig, figure)
    return table
