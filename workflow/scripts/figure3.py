"""Adapter for rule figure3: the paper's Figure 3 (first- vs second-order model)."""

import pandas as pd

from railtherm import logs
from railtherm.report import plots

log = logs.to_file(snakemake.log[0])
figure = plots.figure3(
    pd.read_csv(snakemake.input.order1),
    pd.read_csv(snakemake.input.order2),
    title=f"{snakemake.params.vehicle}: measurement and simulation",
    synthetic=snakemake.params.synthetic,
)
plots.save_figure(figure, snakemake.output.png.removesuffix(".png"))
log.info("Figure 3 of %s", snakemake.params.vehicle)
