"""Adapter for rule reference: published analyses of the same data beside railtherm's fits."""

from pathlib import Path

import pandas as pd
import yaml

from railtherm import aggregate, ingest, logs, reference

log = logs.to_file(snakemake.log[0])
vehicles = snakemake.params.vehicles
refs, parts = [], []
for path in snakemake.input.refs:
    ref = reference.load_reference(path)
    vid, key = ref["vehicle"], ref["model"]
    fit_file = Path(f"results/vehicles/{vid}/fit_{key}.yaml")
    fit = yaml.safe_load(fit_file.read_text(encoding="utf-8"))
    tables = {
        w: ingest.read_tidy(f"results/vehicles/{vid}/clean/{w}.csv")
        for w in snakemake.params.windows[vid]
    }
    parts.append(reference.compare(ref, fit, tables, vehicles[vid]))
    refs.append(ref)
    log.info("%s: %s/%s", path, vid, key)
table = pd.concat(parts, ignore_index=True)
source = aggregate.data_source({r["vehicle"]: vehicles[r["vehicle"]] for r in refs})
table.to_csv(snakemake.output.csv, index=False, lineterminator="\n")
Path(snakemake.output.md).write_text(reference.markdown(table, refs, source), encoding="utf-8")
