"""Adapter for rule sindy_summary: the table and the figure over all vehicles."""

from pathlib import Path

import pandas as pd

from railtherm import io as rt_io
from railtherm import logs
from railtherm.report import plots, tables
from railtherm.study import aggregate, sindy

log = logs.to_file(snakemake.log[0])
results = {
    vid: rt_io.read_result(path)
    for vid, path in zip(snakemake.params.vehicles, snakemake.input.results, strict=True)
}
source = aggregate.data_source(snakemake.params.data)
sources = {vid: aggregate.vehicle_source(v) for vid, v in snakemake.params.data.items()}
table = sindy.summary_table(results, sources)  # each row its own source
tables.write_csv(table, snakemake.output.csv)
Path(snakemake.output.md).write_text(sindy.summary_markdown(table, source), encoding="utf-8")
# the footer says which vehicles are measured where some are (a figure of every vehicle)
note = plots.provenance_note(
    pd.DataFrame({"vehicle": list(results), "source": [sources[v] for v in results]})
)
figure = plots.sindy_figure(results, note=note)
plots.save_figure(figure, snakemake.output.png.removesuffix(".png"))
log.info("%d vehicles", len(results))
