"""Adapter for rule compare_models: every fitted model of every vehicle side by side."""

from pathlib import Path

from railtherm import io as rt_io
from railtherm import logs
from railtherm.report import tableformat, tables
from railtherm.study import aggregate

log = logs.to_file(snakemake.log[0])
fits = [rt_io.read_fit(p) for p in snakemake.input.fits]
source = aggregate.data_source(snakemake.params.data)
table = aggregate.model_table(fits)  # each row its own source
tables.write_csv(table, snakemake.output.csv)
selection = tableformat.model_selection_markdown(fits)
Path(snakemake.output.md).write_text(
    tableformat.model_markdown(table, source, selection), encoding="utf-8"
)
log.info("%d fits", len(fits))
