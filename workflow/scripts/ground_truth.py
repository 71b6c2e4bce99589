"""Adapter for rule ground_truth: the campaign's declared truth as tables (SI units)."""

from railtherm import logs, synth

log = logs.to_file(snakemake.log[0])
campaign = synth.load_campaign(snakemake.input[0])
synth.ground_truth_table(campaign).to_csv(snakemake.output.truth, index=False)
synth.ground_truth_sources(campaign).to_csv(snakemake.output.sources, index=False)
log.info("wrote the ground truth of %d vehicles", len(campaign["vehicles"]))
