"""Adapter for rule energy_table: the vehicles' annual energy (rule energy) as the study's
table and figure (railtherm.study.energy.study_table, write_study_energy)."""

from railtherm import logs
from railtherm.study import aggregate, energy

log = logs.to_file(snakemake.log[0])
table = energy.study_table(
    snakemake.input.tables, snakemake.input.fits, snakemake.params.fit_vehicles
)
energy.write_study_energy(
    table,
    [energy.load_profile(path) for path in snakemake.input.profiles],
    snakemake.params.step_s,
    aggregate.data_source(snakemake.params.vehicles),
    snakemake.output.csv,
    snakemake.output.md,
    snakemake.output.png.removesuffix(".png"),
)
if table.empty:
    log.warning(energy.no_acceptable_fit(table.attrs.get("verdicts", {})))
log.info("%d rows", len(table))
