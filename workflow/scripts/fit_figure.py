"""Adapter for rule fit_figure: measured vs simulated temperatures, residuals and inputs."""

from pathlib import Path

import pandas as pd
import yaml

from railtherm import logs, plots

log = logs.to_file(snakemake.log[0])
fit = yaml.safe_load(Path(snakemake.input.fit).read_text(encoding="utf-8"))
series = pd.read_csv(snakemake.input.series)
model = {
    "first_order": "first-order model (eq. 9)",
    "second_order": "second-order model (eqs. 7-8)",
    "interior_envelope": "interior-envelope model",
}[fit["structure"].split("+")[0]]
if fit.get("estimator") == "kalman":
    model += ", Kalman-filter estimator"
figure = plots.fit_figure(
    series, fit, f"{fit['vehicle']}: {model}", synthetic=bool(fit.get("synthetic", False))
)
plots.save_figure(figure, snakemake.output.png.removesuffix(".png"))
log.info("fit figure of %s, %s", fit["vehicle"], fit["structure"])
