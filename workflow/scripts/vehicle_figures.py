"""Adapter for rule vehicle_figures: every figure of one vehicle
(railtherm.report.plots.vehicle_figures)
- the record with the k window and the k-test verdict, measured vs simulated temperatures with
residuals and inputs per fit, and the one-step innovations of each Kalman-filter fit."""

from railtherm import logs
from railtherm.report import plots

log = logs.to_file(snakemake.log[0])
inputs, outputs = snakemake.input, snakemake.output
kvalue = None
if snakemake.params.kvalue:
    kvalue = {
        "record": inputs.kvalue_record,
        "window": inputs.kvalue_window,
        "result": inputs.kvalue_result,
        "png": outputs.kvalue_png,
    }
fits = {}
for key in snakemake.params.models:
    fits[key] = {"fit": inputs[f"fit_{key}"], "series": inputs[f"series_{key}"]}
    fits[key]["png"] = outputs[f"fit_{key}_png"]
    if f"innovations_{key}_png" in outputs.keys():
        fits[key]["innovations_png"] = outputs[f"innovations_{key}_png"]
drawn = plots.vehicle_figures(
    snakemake.wildcards.vehicle,
    kvalue=kvalue,
    fit_files=fits,
    synthetic=bool(snakemake.params.synthetic),
)
for line in drawn:
    log.info(line)
