"""Adapter for rule simulate: the study's scenarios through every vehicle's identified model."""

from railtherm import logs
from railtherm.study import predictions
from railtherm.study.fit import read_fit
from railtherm.study.scenario import load_scenario

log = logs.to_file(snakemake.log[0])
vehicles = snakemake.params.vehicles
posteriors = snakemake.input.posteriors or [None] * len(snakemake.input.fits)
fits = {
    vid: read_fit(path, posterior=nc)
    for vid, path, nc in zip(vehicles, snakemake.input.fits, posteriors, strict=True)
}
scenarios = [load_scenario(path) for path in snakemake.params.scenarios]
predictions.write_study_predictions(
    fits,
    vehicles,
    scenarios,
    snakemake.params.figure,
    snakemake.output.csv,
    snakemake.output.md,
    snakemake.output.png.removesuffix(".png"),
    draws=snakemake.params.draws,
    seed=snakemake.params.seed,
)
log.info("%d scenarios x %d vehicles", len(scenarios), len(fits))
