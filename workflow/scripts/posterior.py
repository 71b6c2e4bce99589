"""Adapter for rule posterior: one of a vehicle's models sampled by NUTS, a second-order
model with its class prior (railtherm.study.pooling, railtherm.study.posterior)."""

from railtherm import io as rt_io
from railtherm import logs
from railtherm.data import ingest
from railtherm.study import classmodel, pooling, posterior
from railtherm.study.fit import read_fit

log = logs.to_file(snakemake.log[0])
vid, model = snakemake.wildcards.vehicle, snakemake.wildcards.model
vehicle = snakemake.params.vehicle
settings = snakemake.params.settings
tables = {
    name: ingest.read_tidy(path)
    for name, path in zip(snakemake.params.windows, snakemake.input.windows, strict=True)
}
kvalue = k_window = None
if snakemake.input.kvalue:
    kvalue = rt_io.read_result(snakemake.input.kvalue)
    k_window = ingest.read_tidy(snakemake.input.k_window)
fit = read_fit(snakemake.input.fit)
prior = None
if snakemake.input.table2:
    members = classmodel.members_from_table2(snakemake.input.table2, snakemake.params.vehicles)
    kA = fit.section("parameters").get("kA", {})
    kA_held = None if kA.get("estimated", True) else float(kA["value"])
    prior = pooling.class_prior(members, vid, vehicle, kA_held, snakemake.params.min_vehicles)
    if prior.reference is None:
        log.info("%s: no class prior (%s); the vehicle's own priors", vid, prior.reason)
post = posterior.sample_model(
    tables,
    vehicle,
    kvalue,
    k_window,
    model,
    fit=fit,
    prior_terms=prior.terms if prior is not None else (),
    chains=settings["chains"],
    draws=settings["draws"],
    tune=settings["tune"],
    seed=settings["seed"],
)
loo = post.loo() if settings["loo"] else None
record = pooling.posterior_record(vid, model, post, fit, prior, loo)
posterior.write(post, snakemake.output.nc)
posterior.pair_plot(post, snakemake.output.png)
rt_io.write_result(record, snakemake.output.record)
d = record["diagnostics"]
log.info(
    "%s %s: R-hat <= %.4f, bulk ESS >= %.0f, %d divergences, %s",
    vid,
    model,
    d["r_hat_max"],
    d["ess_bulk_min"],
    d["divergences"],
    "trusted" if d["trusted"] else "NOT trusted",
)
