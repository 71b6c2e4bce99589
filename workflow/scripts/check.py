"""Adapter for rule check: diagnostics and verdict of one fit."""

import pandas as pd
import yaml

from railtherm import identify, logs
from railtherm.fit import Fit

log = logs.to_file(snakemake.log[0])
with open(snakemake.input.estimate, encoding="utf-8") as stream:
    estimate = yaml.safe_load(stream)
series = pd.read_csv(snakemake.input.series)
fit = Fit(identify.check(estimate, series, snakemake.params.check), series)
fit.write(snakemake.output[0])
log.info("%s: R2 = %.4f; %s", fit.vehicle, fit.R2, fit.verdict)
