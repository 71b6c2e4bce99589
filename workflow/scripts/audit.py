"""Adapter for rule audit: findings.csv and audit.md of the published values."""

from pathlib import Path

from railtherm import logs
from railtherm.report import audit

log = logs.to_file(snakemake.log[0])
estimates = str(Path(snakemake.input.estimates[0]).parent) if snakemake.input.estimates else None
findings = audit.audit(
    snakemake.input.published,
    snakemake.input.ranges,
    estimates,
    Path(snakemake.output.findings).parent,
)
log.info("%s", findings["severity"].value_counts().to_dict())
