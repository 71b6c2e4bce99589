"""Adapter for rule check: diagnostics and verdict of each of a vehicle's fits."""

import pandas as pd

from railtherm import io as rt_io
from railtherm import logs
from railtherm.study import quality
from railtherm.study.fit import Fit

log = logs.to_file(snakemake.log[0])
for model in snakemake.params.models:
    estimate = rt_io.read_estimate(snakemake.input[f"estimate_{model}"])
    series = pd.read_csv(snakemake.input[f"series_{model}"])
    fit = Fit.of(quality.check(estimate, series, snakemake.params.check), series)
    fit.write(snakemake.output[f"fit_{model}"])
    log.info("%s, %s: R2 = %.4f; %s", fit.vehicle, model, fit.R2, fit.verdict)
