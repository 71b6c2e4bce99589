"""Adapter for rule reference_validation: the class reference model, leave-one-out."""

import pandas as pd

from railtherm import aggregate, classmodel, classvalidation, logs, plots, tables
from railtherm.fit import read_fit
from railtherm.scenario import load_scenario

log = logs.to_file(snakemake.log[0])
vehicles = snakemake.params.vehicles
table2 = pd.read_csv(snakemake.input.table2)
members = [
    classmodel.member_from_row(row, vehicles[row["vehicle"]])
    for row in table2.to_dict("records")
    if row["vehicle"] in vehicles
]
fits = {vid: read_fit(path) for vid, path in zip(vehicles, snakemake.input.fits, strict=True)}
series = {
    vid: pd.read_csv(path) for vid, path in zip(vehicles, snakemake.input.series, strict=True)
}
scenario = load_scenario(snakemake.input.scenario)
truth = {}
if snakemake.input.truth:  # the virtual campaign's declared parameters (synthetic vehicles)
    declared = pd.read_csv(snakemake.input.truth).set_index("vehicle")
    truth = {
        vid: declared.loc[vid, ["kA", "C", "K_veh", "C_veh"]].astype(float).to_dict()
        for vid in vehicles
        if vid in declared.index
    }
table = classvalidation.leave_one_out(
    members,
    fits,
    series,
    scenario,
    min_vehicles=snakemake.params.min_vehicles,
    draws=snakemake.params.draws,
    seed=snakemake.params.seed,
    volumes={vid: data.get("volume_m3") for vid, data in vehicles.items()},
    truth=truth,
)
source = aggregate.data_source(vehicles)
tables.write_csv(table, snakemake.output.csv, digits=4)
with open(snakemake.output.md, "w", encoding="utf-8") as stream:
    stream.write(classvalidation.validation_markdown(table, scenario, source))
fig = plots.reference_validation_figure(
    table, note=plots.provenance_note(table.assign(source=source))
)
plots.save_figure(fig, snakemake.output.png.removesuffix(".png"))
for line in classvalidation.summary_lines(table):
    log.info("%s", line)
