"""Adapter for rule figure4: the paper's Figure 4 (measurement vs simulation, metros)."""

import pandas as pd

from railtherm import logs
from railtherm.report import plots

log = logs.to_file(snakemake.log[0])
series = {
    vid: pd.read_csv(path)
    for vid, path in zip(snakemake.params.vehicles, snakemake.input.series, strict=True)
}
figure = plots.figure4(series, synthetic=snakemake.params.synthetic)
plots.save_figure(figure, snakemake.output.png.removesuffix(".png"))
log.info("Figure 4 of %s", ", ".join(series))
