"""Adapter for rule reference_validation: the class reference model, leave-one-out."""

from railtherm import logs
from railtherm.study import classvalidation
from railtherm.study.scenario import load_scenario

log = logs.to_file(snakemake.log[0])
vehicles = snakemake.params.vehicles
scenario = load_scenario(snakemake.input.scenario)
table = classvalidation.study_leave_one_out(
    snakemake.input.table2,
    vehicles,
    snakemake.input.fits,
    snakemake.input.series,
    scenario,
    truth_file=snakemake.input.truth or None,
    min_vehicles=snakemake.params.min_vehicles,
    draws=snakemake.params.draws,
    seed=snakemake.params.seed,
)
classvalidation.write_validation(
    table,
    scenario,
    vehicles,
    snakemake.output.csv,
    snakemake.output.md,
    snakemake.output.png.removesuffix(".png"),
)
for line in classvalidation.summary_lines(table):
    log.info("%s", line)
