"""Adapter for rule kvalue_table: k and u(k) of every vehicle beside the truth where known."""

import pandas as pd

from railtherm import io as rt_io
from railtherm import logs
from railtherm.report import tables
from railtherm.study import aggregate

log = logs.to_file(snakemake.log[0])
results = {
    vid: rt_io.read_result(path)
    for vid, path in zip(snakemake.params.vehicles, snakemake.input.results, strict=True)
}
truth = pd.read_csv(snakemake.input.truth) if snakemake.input.truth else None
if truth is not None:  # of the synthetic vehicles only
    truth = truth[truth["vehicle"].isin(snakemake.params.synthetic)]
tables.write_csv(aggregate.kvalue_table(results, truth), snakemake.output[0])
log.info("k table of %d vehicles", len(results))
