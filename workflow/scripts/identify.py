"""Adapter for rule identify: PEM fit of each of a vehicle's models to its windows."""

from railtherm import io as rt_io
from railtherm import logs
from railtherm.data import ingest
from railtherm.study import identify
from railtherm.study.run import read_stage_inputs
from railtherm.study.storage import storage_corrected_k

log = logs.to_file(snakemake.log[0])
tables, kvalue, k_window = read_stage_inputs(
    snakemake.params.windows,
    snakemake.input.windows,
    snakemake.input.kvalue or None,
    snakemake.input.k_window or None,
)
# the storage-corrected kA (eqs. 7-8 over the k window), once for every model of the vehicle
storage = storage_corrected_k(tables, k_window, snakemake.params.vehicle, kvalue)
if storage and storage["applied"]:
    log.info(
        "kA %.6g W/K (eq. 10) -> %.6g +- %.2g W/K storage-corrected, %d iterations",
        storage["kA_eq10"],
        storage["kA_corrected"],
        storage["u_kA_corrected"],
        storage["iterations"],
    )
for model in snakemake.params.models:
    estimate, series = identify.identify(tables, snakemake.params.vehicle, kvalue, model, storage)
    rt_io.write_estimate(estimate, snakemake.output[f"estimate_{model}"])
    ingest.write_tidy(series, snakemake.output[f"series_{model}"])
    fit = estimate.section("fit")
    criterion = (
        f"log-likelihood {fit['loglik']:.6g}"
        if fit["estimator"] == "kalman"
        else f"cost {fit['cost']:.6g}"
    )
    log.info("%s: %s, %s", model, estimate.k_source, criterion)
