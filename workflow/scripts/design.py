"""Adapter for rule design: predicted against realised interval widths, and the shortest
paper-shaped programme to the target, per vehicle."""

import pandas as pd

from railtherm import logs
from railtherm.io import read_result
from railtherm.study import aggregate, classmodel, design, designstudy
from railtherm.study.fit import read_fit

log = logs.to_file(snakemake.log[0])
vehicles = snakemake.params.vehicles
fits = {
    vid: read_fit(path, series)
    for vid, path, series in zip(
        vehicles, snakemake.input.fits, snakemake.input.series, strict=True
    )
}
kvalues = {
    vid: read_result(path)
    for vid, path in zip(snakemake.params.with_kvalue, snakemake.input.kvalues, strict=True)
}
members = [
    classmodel.member_from_row(row, vehicles[row["vehicle"]])
    for row in pd.read_csv(snakemake.input.table2).to_dict("records")
    if row["vehicle"] in vehicles
]
table = designstudy.vehicle_rows(
    fits,
    kvalues,
    vehicles,
    members,
    design.parse_target(snakemake.params.target),
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
