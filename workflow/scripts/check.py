"""Adapter for rule check: diagnostics and verdict of one fit."""

import pandas as pd
import yaml

from railtherm import identify, logs

log = logs.to_file(snakemake.log[0])
with open(snakemake.input.estimate, encoding="utf-8") as stream:
    estimate = yaml.safe_load(stream)
series = pd.read_csv(snakemake.input.series)
result = identify.check(estimate, series, snakemake.params.check)
with open(snakemake.output[0], "w", encoding="utf-8") as stream:
    yaml.safe_dump(result, stream, sort_keys=False)
log.info("%s: R2 = %.4f; %s", result["vehicle"], result["R2"], result["verdict"])
