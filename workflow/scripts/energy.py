"""Adapter for rule energy: every acceptable second-order fit through the study's typical
years under its operating profile, with the what-ifs paired."""

from railtherm import logs
from railtherm.study import aggregate, energy
from railtherm.study.fit import read_fit
from railtherm.study.weather import read_weather

log = logs.to_file(snakemake.log[0])
vehicles = snakemake.params.vehicles
fits = {vid: read_fit(path) for vid, path in zip(vehicles, snakemake.input.fits, strict=True)}
weathers = [read_weather(path) for path in snakemake.input.weather]
profile = energy.load_profile(snakemake.input.profile)
rows = energy.study_rows(
    fits,
    vehicles,
    weathers,
    profile,
    [energy.parse_what_if(w) for w in snakemake.params.what_if],
    dt_s=snakemake.params.step_s,
    draws=snakemake.params.draws,
    seed=snakemake.params.seed,
    hold=snakemake.params.hold,
)
energy.write_study_energy(
    rows,
    profile,
    snakemake.params.step_s,
    aggregate.data_source(vehicles),
    snakemake.output.csv,
    snakemake.output.md,
    snakemake.output.png.removesuffix(".png"),
)
log.info("%d rows", len(rows))
