"""Adapter for rule clean: every tidy, uniformly sampled table of one vehicle, each raw file
read once (railtherm.data.ingest.clean_windows)."""

from railtherm import logs
from railtherm.data import ingest

log = logs.to_file(snakemake.log[0])
vehicle = snakemake.params.vehicle
sources = snakemake.params.sources  # table -> the raw file it is cut from
tables = ingest.clean_windows(vehicle, {name: sources[name] for name in snakemake.params.tables})
for (name, table), path in zip(tables.items(), snakemake.output, strict=True):
    ingest.write_tidy(table, path)
    log.info("%s/%s: %d rows, %d filled", vehicle["id"], name, len(table), table["filled"].sum())
