"""Adapter for rule innovation_figure: the one-step innovations of a kalman fit, their
autocorrelation and cumulated periodogram, per compared temperature."""

from pathlib import Path

import pandas as pd
import yaml

from railtherm import logs, plots

log = logs.to_file(snakemake.log[0])
fit = yaml.safe_load(Path(snakemake.input.fit).read_text(encoding="utf-8"))
series = pd.read_csv(snakemake.input.series)
outputs = list(fit["outputs"])
times = series["time"].to_numpy(float)
plots.innovation_figure(
    times,
    series[[f"{s}_innovation" for s in outputs]].to_numpy(float),
    series[[f"{s}_innovation_sd" for s in outputs]].to_numpy(float),
    title=f"{fit['vehicle']}: {fit['structure']}, Kalman-filter estimator",
    path=snakemake.output.png,
    names=outputs,
    synthetic=bool(fit.get("synthetic", False)),
)
log.info("innovation figure of %s, %s", fit["vehicle"], fit["structure"])
