"""Adapter for rule figure5: the paper's Figure 5 (c_veh and delta by vehicle class)."""

import pandas as pd

from railtherm import logs
from railtherm.report import plots

log = logs.to_file(snakemake.log[0])
table3 = pd.read_csv(snakemake.input.table3)
fig_a, fig_b = plots.figure5(table3, note=plots.provenance_note(table3))
plots.save_figure(fig_a, snakemake.output.a_png.removesuffix(".png"))
plots.save_figure(fig_b, snakemake.output.b_png.removesuffix(".png"))
log.info("Figure 5 of %d vehicles", len(table3))
