"""Adapter for rule fit_table: every fit of the study beside the truth where known."""

import pandas as pd

from railtherm import io as rt_io
from railtherm import logs
from railtherm.report import tables
from railtherm.study import aggregate

log = logs.to_file(snakemake.log[0])
fits = [rt_io.read_fit(path) for path in snakemake.input.fits]
truth = pd.read_csv(snakemake.input.truth, keep_default_na=False) if snakemake.input.truth else None
tables.write_csv(aggregate.fit_table(fits, truth), snakemake.output[0])
log.info("%d fits", len(fits))
