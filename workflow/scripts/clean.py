"""Adapter for rule clean: every tidy, uniformly sampled table of one vehicle, each raw file
read once."""

from railtherm import ingest, logs

log = logs.to_file(snakemake.log[0])
vehicle = snakemake.params.vehicle
sources = snakemake.params.sources  # table -> the raw file it is cut from
raws = {}
for name, path in zip(snakemake.params.tables, snakemake.output, strict=True):
    raw_path = sources[name]
    if raw_path not in raws:
        raws[raw_path] = ingest.read_raw(raw_path, vehicle["format"], label=raw_path)
    _, window, key = ingest.window_spec(vehicle, name)
    table = ingest.tidy(raws[raw_path], vehicle, window, raw_path, window_key=key)
    ingest.write_tidy(table, path)
    log.info("%s/%s: %d rows, %d filled", vehicle["id"], name, len(table), table["filled"].sum())
