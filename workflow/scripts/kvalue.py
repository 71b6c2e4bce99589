"""Adapter for rule kvalue: static k (eq. 10), verdict, u(k) and the k-window figure."""

import yaml

from railtherm import ingest, kvalue, logs, plots

log = logs.to_file(snakemake.log[0])
vehicle = snakemake.params.vehicle
window = ingest.read_tidy(snakemake.input.window)
result = kvalue.for_vehicle(window, vehicle, source=snakemake.input.window)
with open(snakemake.output.result, "w", encoding="utf-8") as stream:
    yaml.safe_dump(result.to_dict(), stream, sort_keys=False)
record = ingest.read_tidy(snakemake.input.record)
figure = plots.kvalue_figure(record, window, result, f"{vehicle['id']}: static k test (eq. 10)")
plots.save_figure(figure, snakemake.output.figure[0].removesuffix(".png"))
log.info("k = %.4g +- %.2g W/(m2 K), steady: %s", result.k, result.u_k, result.steady)
