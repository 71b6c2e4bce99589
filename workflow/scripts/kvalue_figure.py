"""Adapter for rule kvalue_figure: the record with the k window and the k-test verdict."""

from pathlib import Path

import yaml

from railtherm import ingest, logs, plots
from railtherm.kvalue import KValue

log = logs.to_file(snakemake.log[0])
result = KValue.from_dict(yaml.safe_load(Path(snakemake.input.result).read_text(encoding="utf-8")))
window = ingest.read_tidy(snakemake.input.window)
record = ingest.read_tidy(snakemake.input.record)
vehicle = snakemake.wildcards.vehicle
figure = plots.kvalue_figure(
    record,
    window,
    result,
    f"{vehicle}: static k test (eq. 10)",
    synthetic=bool(snakemake.params.synthetic),
)
plots.save_figure(figure, snakemake.output.png.removesuffix(".png"))
log.info("k figure of %s", vehicle)
