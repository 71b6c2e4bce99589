"""Adapter for rule sindy_summary: the table and the figure over all vehicles."""

from pathlib import Path

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
table = sindy.summary_table(results, source)
tables.write_csv(table, snakemake.output.csv)
Path(snakemake.output.md).write_text(sindy.summary_markdown(table, source), encoding="utf-8")
synthetic = any(v.get("synthetic", False) for v in snakemake.params.data.values())
figure = plots.sindy_figure(results, synthetic=synthetic)
plots.save_figure(figure, snakemake.output.png.removesuffix(".png"))
log.info("%d vehicles", len(results))
