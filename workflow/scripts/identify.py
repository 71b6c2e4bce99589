"""Adapter for rule identify: PEM fit of one model to a vehicle's windows."""

import yaml

from railtherm import identify, ingest, logs
from railtherm.fit import write_yaml

log = logs.to_file(snakemake.log[0])
tables = {
    name: ingest.read_tidy(path)
    for name, path in zip(snakemake.params.windows, snakemake.input.windows, strict=True)
}
kvalue = None
if snakemake.input.kvalue:
    with open(snakemake.input.kvalue, encoding="utf-8") as stream:
        kvalue = yaml.safe_load(stream)
estimate, series = identify.identify(
    tables, snakemake.params.vehicle, kvalue, snakemake.wildcards.model
)
write_yaml(estimate, snakemake.output.estimate)
ingest.write_tidy(series, snakemake.output.series)
fit = estimate["fit"]
criterion = f"log-likelihood {fit['loglik']:.6g}" if "loglik" in fit else f"cost {fit['cost']:.6g}"
log.info("%s: %s, %s", snakemake.wildcards.model, estimate["k_source"], criterion)
