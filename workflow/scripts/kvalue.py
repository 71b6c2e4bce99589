"""Adapter for rule kvalue: static k (eq. 10), its steady-state verdict and u(k)."""

from railtherm import io as rt_io
from railtherm import logs
from railtherm.data import ingest
from railtherm.estimation import kvalue

log = logs.to_file(snakemake.log[0])
vehicle = snakemake.params.vehicle
window = ingest.read_tidy(snakemake.input.window)
result = kvalue.for_vehicle(window, vehicle, source=snakemake.input.window)
rt_io.write_result(result.to_dict(), snakemake.output[0])
if result.k is None:  # no surface_m2: kA only
    log.info("kA = %.4g +- %.2g W/K, steady: %s", result.kA, result.u_kA, result.steady)
else:
    log.info("k = %.4g +- %.2g W/(m2 K), steady: %s", result.k, result.u_k, result.steady)
for reason in result.reasons:  # why the window failed the steady-state test
    log.warning("k window not steady: %s", reason)
