"""Adapter for rule identify: PEM fit of each of a vehicle's models to its windows."""

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
for model in snakemake.params.models:
    estimate, series = identify.identify(tables, snakemake.params.vehicle, kvalue, model)
    write_yaml(estimate, snakemake.output[f"estimate_{model}"])
    ingest.write_tidy(series, snakemake.output[f"series_{model}"])
    fit = estimate["fit"]
    criterion = (
        f"log-likelihood {fit['loglik']:.6g}" if "loglik" in fit else f"cost {fit['cost']:.6g}"
    )
    log.info("%s: %s, %s", model, estimate["k_source"], criterion)
