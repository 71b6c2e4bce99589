"""Adapter for rule simulate: the study's scenarios through every vehicle's identified model."""

from railtherm import logs
from railtherm.report import plots, tables
from railtherm.study import aggregate, predictions
from railtherm.study.fit import read_fit
from railtherm.study.scenario import load_scenario

log = logs.to_file(snakemake.log[0])
vehicles = snakemake.params.vehicles
fits = {vid: read_fit(path) for vid, path in zip(vehicles, snakemake.input.fits, strict=True)}
classes = {vid: str(data["class"]) for vid, data in vehicles.items()}
scenarios = [load_scenario(path) for path in snakemake.params.scenarios]
volumes = {vid: data.get("volume_m3") for vid, data in vehicles.items()}
draws, seed = snakemake.params.draws, snakemake.params.seed
table, runs = predictions.scenario_table(
    fits, classes, scenarios, draws=draws, seed=seed, volumes=volumes
)
source = aggregate.data_source(vehicles)
tables.write_csv(table, snakemake.output.csv, digits=predictions.DIGITS)
with open(snakemake.output.md, "w", encoding="utf-8") as stream:
    stream.write(predictions.scenario_markdown(table, scenarios, source, draws, volumes))
chosen = next(sc for sc in scenarios if sc.name == snakemake.params.figure)
mark = predictions.DOUBT_MARK
shown = {
    vid + (f" {mark}" if run.band_withheld else ""): run
    for (name, vid), run in runs.items()
    if name == chosen.name
}
doubt = f" ({mark}: assumptions in doubt, no band)" if any(mark in v for v in shown) else ""
note = plots.provenance_note(table.assign(source=source))
left = [vid for vid in fits if (chosen.name, vid) not in runs]  # the table says why
if left:
    note = f"not drawn: {', '.join(left)} (not simulated, see the scenario table)" + (
        f"; {note}" if note else ""
    )
fig = plots.scenario_figure(
    shown,
    title=f"{chosen.name}: identified second-order models, 95 % bands{doubt}",
    threshold_C=chosen.heat_up_to_C,
    note=note,
)
plots.save_figure(fig, snakemake.output.png.removesuffix(".png"))
log.info("%d scenarios x %d vehicles", len(scenarios), len(fits))
