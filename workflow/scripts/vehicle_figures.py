"""Adapter for rule vehicle_figures: every figure of one vehicle - the record with the k window
and the k-test verdict, measured vs simulated temperatures with residuals and inputs per fit,
and the one-step innovations of each Kalman-filter fit (their autocorrelation and cumulated
periodogram, per compared temperature)."""

from pathlib import Path

import pandas as pd
import yaml

from railtherm import ingest, logs, plots
from railtherm.kvalue import KValue

MODELS = {
    "first_order": "first-order model (eq. 9)",
    "second_order": "second-order model (eqs. 7-8)",
    "interior_envelope": "interior-envelope model",
}

log = logs.to_file(snakemake.log[0])
vehicle = snakemake.wildcards.vehicle
inputs, outputs = snakemake.input, snakemake.output


if snakemake.params.kvalue:
    result = KValue.from_dict(
        yaml.safe_load(Path(inputs.kvalue_result).read_text(encoding="utf-8"))
    )
    figure = plots.kvalue_figure(
        ingest.read_tidy(inputs.kvalue_record),
        ingest.read_tidy(inputs.kvalue_window),
        result,
        f"{vehicle}: static k test (eq. 10)",
        synthetic=bool(snakemake.params.synthetic),
    )
    plots.save_figure(figure, outputs.kvalue_png.removesuffix(".png"))
    log.info("k figure of %s", vehicle)

for key in snakemake.params.models:
    fit = yaml.safe_load(Path(inputs[f"fit_{key}"]).read_text(encoding="utf-8"))
    series = pd.read_csv(inputs[f"series_{key}"])
    synthetic = bool(fit.get("synthetic", False))
    model = MODELS[fit["structure"].split("+")[0]]
    if fit.get("estimator") == "kalman":
        model += ", Kalman-filter estimator"
    figure = plots.fit_figure(series, fit, f"{fit['vehicle']}: {model}", synthetic=synthetic)
    plots.save_figure(figure, outputs[f"fit_{key}_png"].removesuffix(".png"))
    log.info("fit figure of %s, %s", fit["vehicle"], fit["structure"])
    if f"innovations_{key}_png" in outputs.keys():
        names = list(fit["outputs"])
        plots.innovation_figure(
            series["time"].to_numpy(float),
            series[[f"{s}_innovation" for s in names]].to_numpy(float),
            series[[f"{s}_innovation_sd" for s in names]].to_numpy(float),
            title=f"{fit['vehicle']}: {fit['structure']}, Kalman-filter estimator",
            path=outputs[f"innovations_{key}_png"],
            names=names,
            synthetic=synthetic,
        )
        log.info("innovation figure of %s, %s", fit["vehicle"], fit["structure"])
