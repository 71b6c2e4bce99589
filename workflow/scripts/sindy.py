"""Adapter for rule sindy: the SINDy cross-check of each vehicle of a batch (sindy.yaml)."""

from railtherm import io as rt_io
from railtherm import logs
from railtherm.data import ingest
from railtherm.study import sindy

log = logs.to_file(snakemake.log[0])
p = snakemake.params.settings
settings = sindy.Settings(
    threshold=p["threshold"], n_bootstrap=p["bootstrap"], block_h=p["block_h"]
)
for vid, vehicle in snakemake.params.vehicles.items():
    windows = [ingest.read_tidy(path) for path in snakemake.input[f"windows_{vid}"]]
    fit = None
    if f"fit_{vid}" in snakemake.input.keys():
        fit = rt_io.read_fit(snakemake.input[f"fit_{vid}"])
    result = sindy.for_vehicle(vehicle, windows, fit, settings)
    rt_io.write_result(result, snakemake.output[f"sindy_{vid}"])
    log.info("%s: %s", result["vehicle"], result["verdict"])
