"""Adapter for rule sindy: the SINDy cross-check of each vehicle of a batch (sindy.yaml)."""

import yaml

from railtherm import ingest, logs, sindy

log = logs.to_file(snakemake.log[0])
p = snakemake.params.settings
settings = sindy.Settings(
    threshold=p["threshold"], n_bootstrap=p["bootstrap"], block_h=p["block_h"]
)
for vid, vehicle in snakemake.params.vehicles.items():
    windows = [ingest.read_tidy(path) for path in snakemake.input[f"windows_{vid}"]]
    fit = None
    if f"fit_{vid}" in snakemake.input.keys():
        with open(snakemake.input[f"fit_{vid}"], encoding="utf-8") as stream:
            fit = yaml.safe_load(stream)
    result = sindy.for_vehicle(vehicle, windows, fit, settings)
    with open(snakemake.output[f"sindy_{vid}"], "w", encoding="utf-8") as stream:
        yaml.safe_dump(result, stream, sort_keys=False)
    log.info("%s: %s", result["vehicle"], result["verdict"])
