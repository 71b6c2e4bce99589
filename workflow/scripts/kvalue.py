"""Adapter for rule kvalue: static k (eq. 10), its steady-state verdict and u(k)."""

import yaml

from railtherm import ingest, kvalue, logs

log = logs.to_file(snakemake.log[0])
vehicle = snakemake.params.vehicle
window = ingest.read_tidy(snakemake.input.window)
result = kvalue.for_vehicle(window, vehicle, source=snakemake.input.window)
with open(snakemake.output[0], "w", encoding="utf-8") as stream:
    yaml.safe_dump(result.to_dict(), stream, sort_keys=False)
log.info("k = %.4g +- %.2g W/(m2 K), steady: %s", result.k, result.u_k, result.steady)
