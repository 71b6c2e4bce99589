"""Published analyses of the same data beside railtherm's own fit (a validation on real data).

A reference file (``railtherm/schemas/reference.schema.yaml``) holds the parameters and fit
figures another tool printed for one vehicle's data, e.g. pySIP's TwTi_RoRi fit of the
Armadillo Box. :func:`compare` sets beside them

- railtherm's fit of the same structure (simulation-error PEM, eqs. 17-18), with its 95 %
  intervals, and
- the published parameters run through railtherm's own simulator (eq. 15) on the same cleaned
  data, with only the initial states estimated: this checks that both tools see the same data
  and the same model, whatever their estimators.

Fit quality is given both as the NRMSE fit that pySIP and MATLAB report and as R^2 of eq. 21.
Where the reference gives a published standard uncertainty ({value, sd}), the comparison gives
z of the difference of the logarithms over both standard uncertainties in quadrature
(:func:`z_difference`); the markdown names the rows railtherm's fit used and the record's
outlying samples (:mod:`railtherm.estimation.outliers`).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from railtherm import structures
from railtherm.errors import ConfigError
from railtherm.estimation import pem
from railtherm.records import FitRecord, ParameterEstimate
from railtherm.study import fitsettings, quality
from railtherm.yamlio import check_finite, packaged_schema, read_yaml, validate_schema

__all__ = [
    "compare",
    "load_reference",
    "markdown",
    "published_parameters",
    "published_sd_log",
    "simulate_published",
    "z_difference",
]

UNITS = {
    **{p: structures.unit(p) for p in structures.parameters()},
    "kA": "W/K",
    "nrmse_fit": "1",
    "r2": "1",
    "rmse": "K",
}
METRIC_LABELS = {"nrmse_fit": "NRMSE fit", "r2": "R² (eq. 21)", "rmse": "RMSE of T"}


def unit(quantity: str) -> str:
    """The SI unit of a compared quantity (an aperture a_<channel> is an area, m²)."""
    return "m²" if quantity.startswith("a_") else UNITS[quantity]


def load_reference(path: str | Path, display: str | None = None) -> dict[str, Any]:
    """Read and validate a reference file; :class:`ConfigError` naming the file, key and
    value on any problem."""
    name = display or str(path)
    data = read_yaml(path, display=name)
    validate_schema(name, data, packaged_schema("reference"))
    check_finite(name, data)
    structure = fitsettings.model_structure(data["model"])
    params = published_parameters(data)
    known = {*structure.parameters, "kA"}
    unknown = sorted(p for p in params if p not in known and not p.startswith("a_"))
    if unknown:
        raise ConfigError(
            name,
            "parameters",
            unknown[0],
            f"not a quantity of {structure.name} (its parameters: "
            f"{', '.join(structure.parameters)}; kA; apertures a_<irradiance channel>)",
        )
    return data


def study_references(
    paths: Sequence[str], fits: Iterable[tuple[str, str]], workdir: str | Path = "."
) -> list[tuple[str, dict[str, Any]]]:
    """Every reference file of a study (``study.references``), loaded and checked against the
    study's fits ``(vehicle, model key)``: [(path, reference)]. :class:`ConfigError` naming
    the file when a reference is malformed or names a fit the study does not make."""
    fits = set(fits)
    out = []
    for path in paths:
        ref = load_reference(Path(workdir) / path, display=path)
        if (ref["vehicle"], ref["model"]) not in fits:
            raise ConfigError(
                path,
                "model",
                ref["model"],
                f"of vehicle '{ref['vehicle']}': no such fit in the study (list the vehicle in "
                "the study config and the model in its model.orders or model.structures)",
            )
        out.append((path, ref))
    return out


def _printed(entry: Any) -> tuple[float, float | None]:
    """A published parameter as the reference gives it: (value, sd or None)."""
    if isinstance(entry, Mapping):
        return float(entry["value"]), float(entry["sd"])
    return float(entry), None


def _railtherm_name(name: str) -> str:
    return "K_" + name[2:] if name.startswith("R_") else name


def published_parameters(reference: Mapping[str, Any]) -> dict[str, float]:
    """The published parameters in railtherm's names: R_x (K/W) becomes K_x = 1 / R_x."""
    out = {}
    for name, entry in reference["parameters"].items():
        value, _ = _printed(entry)
        out[_railtherm_name(name)] = 1.0 / value if name.startswith("R_") else value
    return out


def published_sd_log(reference: Mapping[str, Any]) -> dict[str, float]:
    """The published standard uncertainties as sds of the logarithm, in railtherm's names
    (only the parameters published with one): sd / value, which K = 1 / R shares with R
    (d log K = -d log R)."""
    out = {}
    for name, entry in reference["parameters"].items():
        value, sd = _printed(entry)
        if sd is not None:
            out[_railtherm_name(name)] = sd / value
    return out


def z_difference(value: float, sd_log: float, published: float, published_sd_log: float) -> float:
    """z of railtherm's estimate against a published one: the difference of the logarithms
    over both standard uncertainties (sds of the logarithm) in quadrature,
    ln(value / published) / sqrt(sd_log^2 + published_sd_log^2). Both analyses fit the same
    record, so their errors are correlated and this z is on the small side of the truth's:
    |z| > 2 is a difference the two uncertainties do not explain. NaN where either is
    missing."""
    variance = sd_log**2 + published_sd_log**2
    if not (np.isfinite(variance) and variance > 0 and value > 0 and published > 0):
        return np.nan
    return float(np.log(value / published) / np.sqrt(variance))


def simulate_published(
    reference: Mapping[str, Any],
    tables: Mapping[str, pd.DataFrame],
    vehicle_data: Mapping[str, Any],
) -> dict[str, float] | None:
    """The published parameters simulated by railtherm (eq. 15) on the cleaned windows that
    railtherm's own fit used, every initial state estimated, nothing else: the fit figures
    (quality.summary) of the simulated T, and the overall kA of those parameters. None when
    the reference does not publish every parameter of the vehicle's structure (e.g. kA alone,
    or a model without the vehicle's irradiance inputs): there is nothing to simulate."""
    structure = fitsettings.model_structure(reference["model"], vehicle_data)
    theta = published_parameters(reference)
    if any(p not in theta for p in structure.parameters):
        return None
    theta = {p: theta[p] for p in structure.parameters}
    exps = fitsettings.experiments(structure, tables, fitsettings.input_hold(vehicle_data))
    result = pem.fit(structure, exps, fixed=theta, outputs=("T",), x0="estimated")
    y = np.concatenate([e.y[:, 0] for e in exps])
    yhat = np.concatenate([x[:, 0] for x in result.simulated])
    p = int(sum(np.count_nonzero(est) for est in result.x0_estimated))
    out = quality.summary(y, yhat, p=p)
    out["kA"] = structure.overall_kA(theta)
    return out


def _row(
    quantity, label, published, fit_entry, simulated=None, judged=None, published_sd_log=None
) -> dict[str, Any]:
    """One quantity; a fitted value the data do not determine
    (railtherm.estimation.pem.identification),
    or coupled to one they do not determine (``judged``: the fit's judgement with its
    structure's coupling, railtherm.study.aggregate.judged_parameters), has no value, no interval
    and is within nothing: its ``status`` says why. ``published_sd_log``: the published
    standard uncertainty (sd of the logarithm), when given: then ``published_sd`` (in the
    quantity's unit) and ``z`` (:func:`z_difference`, railtherm's statistical sd, as a
    published fit's own sd is)."""
    value = np.nan if fit_entry is None else fit_entry.value
    lo, hi = (np.nan, np.nan)
    status = "estimated"
    if fit_entry is not None and fit_entry.ci95_combined is not None:
        lo, hi = fit_entry.ci95_combined
        judged = judged or fit_entry.identification
        if not judged["identified"]:
            value, lo, hi = np.nan, np.nan, np.nan
            status = f"not identified: {judged['reason']}"
    published = np.nan if published is None else float(published)
    z = np.nan
    if published_sd_log is not None and fit_entry is not None and np.isfinite(value):
        sd_log = fit_entry.sd_log if fit_entry.sd_log is not None else fit_entry.sd_log_total
        if sd_log is not None:
            z = z_difference(value, float(sd_log), published, published_sd_log)
    return {
        "quantity": quantity,
        "label": label,
        "unit": unit(quantity),
        "published": published,
        "published_sd": np.nan if published_sd_log is None else published * published_sd_log,
        "railtherm": value,
        "railtherm_lo": lo,
        "railtherm_hi": hi,
        "ratio": value / published if np.isfinite(published) and published else np.nan,
        "within_ci": bool(lo <= published <= hi) if np.isfinite(lo) else None,
        "z": z,
        "published_simulated": np.nan if simulated is None else float(simulated),
        "status": status,
    }


def compare(
    reference: Mapping[str, Any],
    fit: FitRecord,
    tables: Mapping[str, pd.DataFrame],
    vehicle_data: Mapping[str, Any],
) -> pd.DataFrame:
    """One row per quantity: the published value, railtherm's fit (``fit``: the check
    output fit_<model>.yaml of the same vehicle and model) with its 95 % interval and the
    ratio to the published value, and, for the fit figures, the published parameters
    simulated by railtherm (:func:`simulate_published`)."""
    if (fit.vehicle, fit.model) != (reference["vehicle"], reference["model"]):
        raise ValueError(
            f"reference {reference['vehicle']}/{reference['model']} compared with the fit of "
            f"{fit.vehicle}/{fit.model}"
        )
    theta = published_parameters(reference)
    sds = published_sd_log(reference)
    printed = reference.get("metrics") or {}
    simulated = simulate_published(reference, tables, vehicle_data) or {}
    fitted = fit.parameters
    from railtherm.study.aggregate import judged_parameters

    judged = judged_parameters(fit)
    # every published parameter (a quantity railtherm does not estimate stays blank), then kA
    rows = [
        _row(q, q, theta[q], fitted.get(q), None, judged.get(q), sds.get(q))
        for q in theta
        if q != "kA"
    ]
    published_kA = theta.get("kA", printed.get("kA"))
    rows.append(
        _row(
            "kA",
            "kA (overall)",
            published_kA,
            fitted.get("kA"),
            simulated.get("kA"),
            judged.get("kA"),
            sds.get("kA"),
        )
    )
    overall = fit.section("measures")["T"]["overall"]
    for q, label in METRIC_LABELS.items():
        measured = ParameterEstimate(q, float(overall[q]), estimated=False)
        rows.append(_row(q, label, printed.get(q), measured, simulated.get(q)))
    table = pd.DataFrame(rows)
    table["k_source"] = fit.k_source
    table["input_hold"] = fit.input_hold
    table["rows"] = int(sum(int(w["rows"]) for w in fit.section("rows").values()))
    table.insert(0, "model", reference["model"])
    table.insert(0, "vehicle", reference["vehicle"])
    return table


HOLD_WORDS = {
    "zero_order": "zero-order hold (each step's mean held, eq. 15)",
    "first_order": "first-order hold (linear between samples)",
}


def _number(value: float, quantity: str) -> str:
    if not np.isfinite(value):
        return "–"
    if unit(quantity) == "J/K":
        return f"{value:.3g}"
    if unit(quantity) == "1":
        return f"{value:.3f}"
    return f"{value:.4g}"


def outlier_text(fit: FitRecord) -> str:
    """The record's outlying samples as a fit file gives them (``outliers``, by
    :func:`railtherm.study.quality.outlying_samples`), one sentence."""
    parts = []
    for state, found in fit.section("outliers").items():
        head = (
            f"{state}, {found['statistic']}s beyond ±{found['threshold']:.2f} (the normal "
            f"quantile at {found['alpha']:g} / {found['n']}, Bonferroni over the "
            f"{found['n']} samples)"
        )
        samples = found["samples"]
        if samples:
            named = "; ".join(f"t = {s['time']:g} s: {s['z']:+.1f}" for s in samples)
            parts.append(f"{head}: {named}")
        else:
            parts.append(f"{head}: none")
    return ". ".join(parts)


def markdown(
    table: pd.DataFrame,
    references: list[Mapping[str, Any]],
    source: str,
    fits: Sequence[FitRecord] | None = None,
) -> str:
    """The comparison as Markdown: one table per reference, its source and location, and,
    given ``fits`` (the fit files compared, in the order of ``references``), the record's
    outlying samples."""
    parts = [f"**Published analyses of the same data beside railtherm.** Data: {source}.", ""]
    kalman = False
    for i, ref in enumerate(references):
        rows = table[(table["vehicle"] == ref["vehicle"]) & (table["model"] == ref["model"])]
        estimator = "PEM"
        if str(ref["model"]).endswith("_kalman"):
            estimator, kalman = "Kalman ML", True
        record = (
            f" railtherm's fit used {int(rows['rows'].iloc[0])} rows." if "rows" in rows else ""
        )
        outlying = ""
        if fits is not None and fits[i].section("outliers"):
            outlying = f" Outlying samples: {outlier_text(fits[i])}."
        parts += [
            f"### {ref['vehicle']}, {ref['model']}",
            "",
            f"Published: {' '.join(ref['source'].split())} ({ref['location']}).",
            "",
            f"railtherm's kA: {rows['k_source'].iloc[0]}. Inputs between samples: "
            f"{HOLD_WORDS[rows['input_hold'].iloc[0]]}.{record}{outlying}",
            "",
            f"| quantity | unit | published | railtherm ({estimator}) | 95 % interval | "
            "railtherm / published | z | published parameters, simulated by railtherm |",
            "|:--|:--|--:|--:|:--|--:|--:|--:|",
        ]
        for r in rows.itertuples():
            ci = (
                f"[{_number(r.railtherm_lo, r.quantity)}, {_number(r.railtherm_hi, r.quantity)}]"
                if np.isfinite(r.railtherm_lo)
                else "–"
            )
            ratio = f"{r.ratio:.3f}" if np.isfinite(r.ratio) else "–"
            value = _number(r.railtherm, r.quantity)
            if r.status != "estimated":
                value = "not identified"
            published = _number(r.published, r.quantity)
            sd = getattr(r, "published_sd", np.nan)
            if np.isfinite(sd):
                published += f" ± {_number(sd, r.quantity)}"
            z = getattr(r, "z", np.nan)
            parts.append(
                f"| {r.label} | {r.unit} | {published} | {value} | {ci} | {ratio} | "
                f"{f'{z:+.2f}' if np.isfinite(z) else '–'} | "
                f"{_number(r.published_simulated, r.quantity)} |"
            )
        parts.append("")
    parts += [
        "- published ± sd: the published standard uncertainty, where the publication gives "
        "one (a resistance's carried to the conductance, the same relative sd). z: "
        "ln(railtherm / published) over both standard uncertainties in quadrature "
        "(railtherm's statistical sd, as a published fit's own); both fits read the same "
        "record, so |z| > 2 is a difference their uncertainties do not explain.",
        "- Outlying samples: samples whose standardized innovation (Kalman ML) or simulation "
        "residual over its RMSE (PEM) lies beyond the two-sided normal quantile at alpha / N "
        "(check.outlier_alpha, 0.05 by default; Bonferroni over the N samples: a record the "
        "model describes shows one with probability at most alpha); reported, never removed "
        "- the rows a fit uses are its vehicle config's windows.",
        "- railtherm (PEM): simulation-error PEM (eqs. 17-18, K = 0) of the same structure, "
        "intervals with the systematic budget. Published parameters, simulated by railtherm: "
        "the published values run through railtherm's simulator (eq. 15, the fit's input "
        "hold) on the same cleaned data, only the initial states estimated.",
        *(
            [
                "- railtherm (Kalman ML): the Kalman-filter prediction error method of the "
                "stochastic model (eq. 16 with K from the filter), maximum likelihood on the "
                "one-step innovations, as pySIP and CTSM-R; intervals from the observed "
                "information with the systematic budget. Its NRMSE fit, R² and RMSE are those "
                "of the simulation of its parameters.",
            ]
            if kalman
            else []
        ),
        "- NRMSE fit = 1 - ||y - ŷ|| / ||y - mean(y)|| (MATLAB's compare, pySIP), not R² "
        "(eq. 21) = 1 - ||y - ŷ||² / ||y - mean(y)||².",
        "",
    ]
    return "\n".join(parts)
