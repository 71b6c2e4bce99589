"""Adapter for rule ground_truth: the campaign's declared truth as tables (SI units)."""

from railtherm import logs, synth
from railtherm.report import tables

log = logs.to_file(snakemake.log[0])
campaign = synth.load_campaign(snakemake.input[0])
tables.write_csv(synth.ground_truth_table(campaign), snakemake.output.truth)
tables.write_csv(synth.ground_truth_sources(campaign), snakemake.output.sources)
log.info("wrote the ground truth of %d vehicles", len(campaign["vehicles"]))
