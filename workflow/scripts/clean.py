"""Adapter for rule clean: one tidy, uniformly sampled table of one window."""

from railtherm import ingest, logs

log = logs.to_file(snakemake.log[0])
table = ingest.clean_window(
    snakemake.input[0], snakemake.params.vehicle, snakemake.wildcards.window
)
ingest.write_tidy(table, snakemake.output[0])
log.info("%s/%s: %d rows, %d filled", *snakemake.wildcards, len(table), table["filled"].sum())
