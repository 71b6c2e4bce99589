"""Adapter for rule design: predicted against realised interval widths, and the shortest
paper-shaped programme to the target, per vehicle (railtherm.study.designstudy)."""

from railtherm import logs
from railtherm.study import aggregate, designstudy

log = logs.to_file(snakemake.log[0])
vehicles = snakemake.params.vehicles
table = designstudy.study_design(
    snakemake.input.table2,
    vehicles,
    snakemake.input.fits,
    snakemake.input.series,
    dict(zip(snakemake.params.with_kvalue, snakemake.input.kvalues, strict=True)),
    snakemake.params.target,
    draws=snakemake.params.draws,
    seed=snakemake.params.seed,
)
designstudy.write_design(
    table,
    aggregate.data_source(vehicles),
    snakemake.output.csv,
    snakemake.output.md,
    snakemake.output.png.removesuffix(".png"),
)
log.info("%d vehicles", table["vehicle"].nunique())
