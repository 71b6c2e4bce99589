"""Adapter for rule energy: every vehicle with an acceptable fit (its second-order one where
acceptable, else its first-order one) through the study's typical years under its operating
profile, with the what-ifs paired (railtherm.study.energy)."""

from railtherm import logs
from railtherm.study import aggregate, energy

log = logs.to_file(snakemake.log[0])
vehicles = snakemake.params.vehicles
table, profile = energy.study_energy(
    vehicles,
    snakemake.input.fits,
    snakemake.input.weather,
    snakemake.input.profile,
    snakemake.params.what_if,
    dt_s=snakemake.params.step_s,
    draws=snakemake.params.draws,
    seed=snakemake.params.seed,
    hold=snakemake.params.hold,
    fit_vehicles=snakemake.params.fit_vehicles,
)
energy.write_study_energy(
    table,
    profile,
    snakemake.params.step_s,
    aggregate.data_source(vehicles),
    snakemake.output.csv,
    snakemake.output.md,
    snakemake.output.png.removesuffix(".png"),
)
if table.empty:
    log.warning(energy.no_acceptable_fit(table.attrs.get("verdicts", {})))
log.info("%d rows", len(table))
