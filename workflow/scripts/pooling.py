"""Adapter for rule pooling: the study table of each vehicle's maximum likelihood, class
prior and posterior (railtherm.study.pooling)."""

from railtherm import io as rt_io
from railtherm import logs
from railtherm.report import tables
from railtherm.study import aggregate, pooling

log = logs.to_file(snakemake.log[0])
records = [rt_io.read_result(path) for path in snakemake.input.records]
table = pooling.pooling_rows(records)
tables.write_csv(table, snakemake.output.csv, digits=4)
with open(snakemake.output.md, "w", encoding="utf-8") as stream:
    stream.write(pooling.pooling_markdown(table, aggregate.data_source(snakemake.params.vehicles)))
untrusted = sum(not r["diagnostics"]["trusted"] for r in records)
log.info("%d posteriors, %d not trusted", len(records), untrusted)
