"""Adapter for rule fit_table: every fit of the study beside the truth where known."""

from pathlib import Path

import pandas as pd
import yaml

from railtherm import aggregate, logs, tables

log = logs.to_file(snakemake.log[0])
fits = [yaml.safe_load(Path(path).read_text(encoding="utf-8")) for path in snakemake.input.fits]
truth = pd.read_csv(snakemake.input.truth, keep_default_na=False) if snakemake.input.truth else None
tables.write_csv(aggregate.fit_table(fits, truth), snakemake.output[0])
log.info("%d fits", len(fits))
