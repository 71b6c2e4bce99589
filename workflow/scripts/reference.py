"""Adapter for rule reference: published analyses of the same data beside railtherm's fits."""

from pathlib import Path

import pandas as pd

from railtherm import io as rt_io
from railtherm import logs
from railtherm.data import ingest
from railtherm.report import tables
from railtherm.study import aggregate, reference

log = logs.to_file(snakemake.log[0])
refs, parts, vehicles, fits = [], [], {}, []
for path, fit_file, vehicle, windows in zip(
    snakemake.input.refs,
    snakemake.input.fits,
    snakemake.params.vehicles,
    snakemake.params.windows,
    strict=True,
):
    ref = reference.load_reference(path)
    fit = rt_io.read_fit(fit_file)
    windows_data = {w: ingest.read_tidy(p) for w, p in windows.items()}
    parts.append(reference.compare(ref, fit, windows_data, vehicle))
    refs.append(ref)
    fits.append(fit)
    vehicles[vehicle["id"]] = vehicle
    log.info("%s: %s/%s", path, ref["vehicle"], ref["model"])
table = pd.concat(parts, ignore_index=True)
source = aggregate.data_source(vehicles)
tables.write_csv(table, snakemake.output.csv)
Path(snakemake.output.md).write_text(
    reference.markdown(table, refs, source, fits), encoding="utf-8"
)
