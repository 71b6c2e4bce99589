"""Adapter for rule synthesize: one raw file of the virtual climatic wind tunnel."""

from railtherm import logs, synth

log = logs.to_file(snakemake.log[0])
log.info("synthesising %s for %s", snakemake.wildcards.filename, snakemake.wildcards.vehicle)
synth.write_raw_file(snakemake.params.spec, snakemake.wildcards.filename, snakemake.output[0])
