"""Adapter for rule posterior: one of a vehicle's models sampled by NUTS, a second-order
model with its class prior (railtherm.study.pooling.study_posterior)."""

from railtherm import io as rt_io
from railtherm import logs
from railtherm.study import classmodel, pooling, posterior
from railtherm.study.fit import read_fit
from railtherm.study.run import read_stage_inputs

log = logs.to_file(snakemake.log[0])
inputs = snakemake.input
tables, kvalue, k_window = read_stage_inputs(
    snakemake.params.windows, inputs.windows, inputs.kvalue or None, inputs.k_window or None
)
members = None
if inputs.table2:
    members = classmodel.members_from_table2(inputs.table2, snakemake.params.vehicles)
post, record, prior = pooling.study_posterior(
    snakemake.wildcards.vehicle,
    snakemake.wildcards.model,
    snakemake.params.vehicle,
    tables,
    kvalue,
    k_window,
    read_fit(inputs.fit),
    snakemake.params.settings,
    members,
    snakemake.params.min_vehicles,
)
if prior is not None and prior.reference is None:
    log.info("no class prior (%s); the vehicle's own priors", prior.reason)
posterior.write(post, snakemake.output.nc)
posterior.pair_plot(post, snakemake.output.png)
rt_io.write_result(record, snakemake.output.record)
log.info("%s", pooling.summary_line(record))
