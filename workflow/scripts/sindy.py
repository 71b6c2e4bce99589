"""Adapter for rule sindy: the SINDy cross-check of one vehicle (sindy.yaml)."""

import yaml

from railtherm import ingest, logs, sindy

log = logs.to_file(snakemake.log[0])
windows = [ingest.read_tidy(path) for path in snakemake.input.windows]
fit = None
if snakemake.input.fit:
    with open(snakemake.input.fit, encoding="utf-8") as stream:
        fit = yaml.safe_load(stream)
p = snakemake.params.settings
settings = sindy.Settings(
    threshold=p["threshold"], n_bootstrap=p["bootstrap"], block_h=p["block_h"]
)
result = sindy.for_vehicle(snakemake.params.vehicle, windows, fit, settings)
with open(snakemake.output[0], "w", encoding="utf-8") as stream:
    yaml.safe_dump(result, stream, sort_keys=False)
log.info("%s: %s", result["vehicle"], result["verdict"])
