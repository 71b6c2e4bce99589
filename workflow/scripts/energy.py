"""Adapter for rule energy: one vehicle with an acceptable fit (its second-order one where
acceptable, else its first-order one) through the study's typical years under its class's
operating profile, with the what-ifs paired (railtherm.study.energy.vehicle_energy)."""

from railtherm import logs
from railtherm.report import tables
from railtherm.study import energy

log = logs.to_file(snakemake.log[0])
table = energy.vehicle_energy(
    snakemake.wildcards.vehicle,
    snakemake.params.vehicle,
    snakemake.input.fits,
    snakemake.input.weather,
    snakemake.input.profile,
    snakemake.params.what_if,
    index=snakemake.params.index,
    dt_s=snakemake.params.step_s,
    draws=snakemake.params.draws,
    seed=snakemake.params.seed,
    hold=snakemake.params.hold,
    posteriors=snakemake.input.posteriors,
)
tables.write_csv(table, snakemake.output[0], digits=10)
log.info("%d rows", len(table))
