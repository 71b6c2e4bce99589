"""Adapter for rule aggregate: Tables 1-3, class statistics and the class test (CSV, MD, TeX)."""

from railtherm import io as rt_io
from railtherm import logs
from railtherm.report import tableformat
from railtherm.study import aggregate

log = logs.to_file(snakemake.log[0])
vehicles = snakemake.params.vehicles
fits = {vid: rt_io.read_fit(path) for vid, path in zip(vehicles, snakemake.input.fits, strict=True)}
kvalues = {vid: None for vid in vehicles} | {
    vid: rt_io.read_result(path)
    for vid, path in zip(snakemake.params.with_kvalue, snakemake.input.kvalues, strict=True)
}
first_order = {
    vid: rt_io.read_fit(path)
    for vid, path in zip(
        snakemake.params.with_first_order, snakemake.input.first_order, strict=True
    )
}
tables = aggregate.study_tables(fits, kvalues, vehicles, snakemake.params.class_test, first_order)
source = aggregate.data_source(vehicles)
if any(fit.estimator == "kalman" for fit in fits.values()):
    source += "; heat capacities by the Kalman-filter estimator (study.estimator: kalman)"
tableformat.write_study_tables(
    tables, source, dict(snakemake.output), left_out=snakemake.params.left_out
)
log.info("tables of %d vehicles", len(vehicles))
