"""The figures of one vehicle, deterministic byte for byte (:mod:`railtherm.report.figurebase`):
its record with the k window (:func:`kvalue_figure`), measured vs simulated temperatures per
fit (:func:`fit_figure`), a Kalman fit's one-step innovations (:func:`innovation_figure`), and
all of them from their files (:func:`vehicle_figures`, rule ``vehicle_figures``). The study's
figures are in :mod:`railtherm.report.studyfigures`; this module names them too.

Time axis of :func:`kvalue_figure`: hours from the start of the record (the first row of the
whole-file tidy table). The k window is placed on it either by ``offset_s`` (seconds from the
record start to the window start) or, by default, by finding the window's first ``timestamp``
among the record's ``timestamp`` values (ISO text is compared as time, seconds as numbers).

The fit figures lay the identification windows side by side on one time axis: each window keeps
its own time (hours since the window start, as in the ``order{n}_series.csv`` files) and starts
a small gap after the end of the previous one; thin vertical lines separate the windows and the
window names stand above the top panel. ``synthetic=True`` (or
:func:`railtherm.report.figurebase.synthetic_note`) adds the footer :data:`SYNTHETIC_NOTE` so
figures of virtual-tunnel data cannot pass for measurements.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import matplotlib
import numpy as np
import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from railtherm import io as rt_io
from railtherm import structures
from railtherm.data import ingest
from railtherm.estimation.acf import autocorrelation
from railtherm.estimation.diagnostics import cumulated_periodogram
from railtherm.estimation.kvalue import KValue
from railtherm.estimation.metrics import ljung_box
from railtherm.records import FitRecord
from railtherm.report.figurebase import (
    COLORS,
    DPI,
    FIGSIZE_FIG5_IN,
    FIGSIZE_IN,
    MEASURED,
    MODEL_STYLES,
    RC,
    SIM_COLORS,
    SIMULATED,
    SYNTHETIC_NOTE,
    T_O_MIN_SPAN_K,
    draw_time_axis,
    finish_figure,
    has_data,
    inputs_panel,
    lay_windows,
    provenance_note,
    save_figure,
    synthetic_note,
)
from railtherm.report.studyfigures import (
    annual_energy_figure,
    design_figure,
    figure3,
    figure4,
    figure5,
    reference_validation_figure,
    scenario_figure,
    sindy_figure,
)

__all__ = [
    "DPI",
    "FIGSIZE_FIG5_IN",
    "FIGSIZE_IN",
    "MODEL_STYLES",
    "SYNTHETIC_NOTE",
    "T_O_MIN_SPAN_K",
    "annual_energy_figure",
    "design_figure",
    "figure3",
    "figure4",
    "figure5",
    "fit_figure",
    "innovation_figure",
    "kvalue_figure",
    "provenance_note",
    "reference_validation_figure",
    "save_figure",
    "scenario_figure",
    "sindy_figure",
    "synthetic_note",
    "vehicle_figures",
    "window_offset_s",
]


def _seconds(stamps: pd.Series) -> np.ndarray:
    """Time labels as seconds on a common scale (epoch seconds for ISO text)."""
    numeric = pd.to_numeric(stamps, errors="coerce")
    if numeric.notna().all():
        return numeric.to_numpy(dtype=float)
    parsed = pd.to_datetime(stamps.astype(str), format="ISO8601")
    return (parsed - pd.Timestamp(0, tz=parsed.dt.tz)).dt.total_seconds().to_numpy(dtype=float)


def window_offset_s(record: pd.DataFrame, window: pd.DataFrame) -> float:
    """Seconds from the record's first row to the window's first row, from ``timestamp``."""
    rec = _seconds(record["timestamp"])
    win = _seconds(window["timestamp"].iloc[:1])
    return float(win[0] - rec[0])


def kvalue_figure(
    record: pd.DataFrame,
    window: pd.DataFrame,
    result: KValue,
    title: str,
    *,
    offset_s: float | None = None,
    synthetic: bool = False,
) -> Figure:
    """T, T_veh, T_o (left axis, degC) and Q_H (right axis, kW) over the whole record with the
    k window shaded and a box with k +- u(k) and the steady-state verdict.

    Without a surface (``result.k`` None) the box gives kA +- u(kA) and says k is not given.
    ``record`` and ``window`` are tidy tables (the whole file and the k window);
    ``offset_s`` places the window on the record's time axis (default: from ``timestamp``);
    ``synthetic`` adds the :data:`SYNTHETIC_NOTE` footer."""
    if offset_s is None:
        offset_s = window_offset_s(record, window)
    with matplotlib.rc_context(RC):
        fig = Figure(figsize=FIGSIZE_IN, dpi=DPI, layout="constrained")
        FigureCanvasAgg(fig)
        grid = fig.add_gridspec(2, 1, height_ratios=[3.7, 1.0])
        ax = fig.add_subplot(grid[0])
        info = fig.add_subplot(grid[1])  # legend and verdict: below the data, hiding none
        info.set_axis_off()
        axq = ax.twinx()
        h = record["time"].to_numpy(dtype=float) / 3600.0
        lines = []
        lines += ax.plot(h, record["T"], color=COLORS["T"], lw=1.0, label="T (indoor air)")
        if "T_veh" in record and record["T_veh"].notna().any():
            lines += ax.plot(
                h, record["T_veh"], color=COLORS["T_veh"], lw=1.0, label="T_veh (surface)"
            )
        lines += ax.plot(h, record["T_o"], color=COLORS["T_o"], lw=1.0, label="T_o (tunnel air)")
        # Q_H[n] is held over [t_n, t_n+1): draw it as a step after each grid point
        lines += axq.step(
            h,
            record["Q_H"].to_numpy(dtype=float) / 1000.0,
            where="post",
            color=COLORS["Q_H"],
            lw=0.6,
            alpha=0.75,
            label="Q_H (heat input)",
        )
        w0 = offset_s / 3600.0
        w1 = w0 + float(window["time"].iloc[-1]) / 3600.0
        ax.axvspan(w0, w1, color="#f5b041", alpha=0.25, lw=0, zorder=0)
        ax.text(
            (w0 + w1) / 2,
            1.0,
            "k window",
            transform=ax.get_xaxis_transform(),
            ha="center",
            va="bottom",
            fontsize=8,
        )
        ax.set_xlim(h[0], h[-1])
        ax.set_xlabel("time since record start (h)")
        ax.set_ylabel("temperature (°C)")
        axq.set_ylabel("Q_H (kW)")
        axq.set_ylim(bottom=min(0.0, float(np.nanmin(record["Q_H"])) / 1000.0))
        ax.set_zorder(axq.get_zorder() + 1)  # temperatures drawn over the power trace
        ax.patch.set_visible(False)
        ax.grid(True, lw=0.4, alpha=0.5)
        ax.set_title(title, loc="left")
        info.legend(handles=lines, loc="upper left", ncols=1, frameon=False, borderaxespad=0)
        info.text(
            1.0,
            1.0,
            _verdict_text(result),
            transform=info.transAxes,
            ha="right",
            va="top",
            multialignment="left",
            fontsize=8,
            bbox={"boxstyle": "round", "facecolor": "white", "lw": 0.5},
        )
    if synthetic:
        synthetic_note(fig)
    return fig


def _verdict_text(r: KValue) -> str:
    if r.k is None:  # no surface: kA is what the test gives
        first = f"kA = {r.kA:.1f} ± {r.u_kA:.1f} W/K  (u, {100 * r.u_k_rel:.1f} %)"
        second = "k not given: no surface_m2"
    else:
        first = f"k = {r.k:.3f} ± {r.u_k:.3f} W/(m² K)  (u, {100 * r.u_k_rel:.1f} %)"
        second = f"kA = {r.kA:.0f} W/K"
    lines = [
        first,
        f"{second},  ΔT = {r.delta_T:.1f} K,  Q_H = {r.Q_H_mean / 1000:.2f} kW",
    ]
    if r.steady:
        lines.append("steady: all tests passed")
    else:
        lines.append("NOT steady" + (" (forced: used anyway)" if r.forced else " (not used)"))
        lines += [f"– {reason}" for reason in r.reasons]
    return "\n".join(lines)


def _fmt(x: Any, digits: int) -> str:
    try:
        value = float(x)
    except (TypeError, ValueError):
        return "n/a"
    return f"{value:.{digits}f}" if np.isfinite(value) else "n/a"


def _fit_text(fit: FitRecord) -> str:
    """R^2 (eq. 21) and NRMSE fit of T (as in the fit file) and the verdict."""
    return "\n".join(
        [
            f"R² of T (eq. 21) = {_fmt(fit.content.get('R2'), 4)}",
            f"NRMSE fit of T = {_fmt(fit.nrmse_fit, 3)}",
            f"verdict: {fit.content.get('verdict', 'n/a')}",
        ]
    )


def fit_figure(
    series: pd.DataFrame,
    fit: FitRecord,
    title: str,
    *,
    synthetic: bool = False,
) -> Figure:
    """One vehicle, one model order: measured vs simulated temperatures (top), the residuals of
    the compared outputs (middle, measured - simulated, K) and the inputs T_o and Q_H (bottom),
    on one side-by-side time axis; legends and a box with R^2 (eq. 21), the NRMSE fit and the
    verdict stand right of the panels.

    ``series`` is an ``order{n}_series.csv`` table, ``fit`` the record of ``fit_order{n}.yaml``.
    T_veh is drawn when it was compared (``"T_veh" in fit.outputs``) or measured."""
    lay = lay_windows(series)
    outputs = [str(o) for o in (fit.outputs or ("T",))]
    with matplotlib.rc_context(RC):
        fig = Figure(figsize=FIGSIZE_IN, dpi=DPI, layout="constrained")
        FigureCanvasAgg(fig)
        grid = fig.add_gridspec(3, 2, height_ratios=[2.3, 1.0, 1.1], width_ratios=[4.7, 1.3])
        ax = fig.add_subplot(grid[0, 0])
        axr = fig.add_subplot(grid[1, 0], sharex=ax)
        axi = fig.add_subplot(grid[2, 0], sharex=ax)
        infos = [fig.add_subplot(grid[i, 1]) for i in range(3)]
        for info in infos:
            info.set_axis_off()

        lines = []
        for state in ("T", "T_veh"):
            measured = lay.values(series, state)
            simulated = lay.values(series, f"{state}_sim")
            if state == "T_veh" and not (has_data(measured) or state in outputs):
                continue
            if has_data(measured):
                lines += ax.plot(
                    lay.x, measured, color=COLORS[state], label=f"{state} measured", **MEASURED
                )
            if has_data(simulated):
                lines += ax.plot(
                    lay.x,
                    simulated,
                    color=SIM_COLORS[state],
                    label=f"{state} simulated",
                    **SIMULATED,
                )
        ax.set_ylabel("temperature (°C)")
        ax.set_title(title, loc="left")

        residuals = []
        axr.axhline(0.0, color="0.2", lw=0.6)
        for state in outputs:
            e = lay.values(series, f"{state}_residual")
            if not has_data(e):  # no residual column: measured - simulated
                e = lay.values(series, state) - lay.values(series, f"{state}_sim")
            if has_data(e):
                residuals += axr.plot(
                    lay.x, e, color=COLORS.get(state, "0.3"), lw=0.5, label=f"{state} residual"
                )
        axr.set_ylabel("meas. − sim. (K)")

        inputs = inputs_panel(axi, series, lay, tunnel=synthetic)
        draw_time_axis([ax, axr, axi], lay)

        legend = {"loc": "upper left", "frameon": False, "borderaxespad": 0, "handlelength": 2.4}
        infos[0].legend(handles=lines, **legend)
        infos[0].text(
            0.0,
            0.0,
            _fit_text(fit),
            transform=infos[0].transAxes,
            ha="left",
            va="bottom",
            fontsize=8,
            bbox={"boxstyle": "round", "facecolor": "white", "lw": 0.5},
        )
        if residuals:
            infos[1].legend(handles=residuals, **legend)
        infos[2].legend(handles=inputs, **legend)
    return finish_figure(fig, synthetic)


# --- one-step residuals of a stochastic fit -----------------------------------------------

_INNOVATION_COLOR = "#17202a"
_BAND = {"color": "#2471a3", "lw": 0.8, "ls": (0, (4, 2))}


def _per_output(values: Any, names: Sequence[str] | None, n: int) -> dict[str, np.ndarray]:
    """Innovations (or their standard deviations) as {output name: 1-D array of length n}:
    from a mapping, a 1-D array (one output) or a 2-D array (rows x outputs)."""
    if isinstance(values, Mapping):
        out = {str(k): np.asarray(v, dtype=float) for k, v in values.items()}
    else:
        a = np.asarray(values, dtype=float)
        if a.ndim == 1:
            a = a[:, None]
        if a.ndim != 2:
            raise ValueError(f"expected one series or rows x outputs, got shape {a.shape}")
        labels = (
            list(names)
            if names is not None
            else (["y"] if a.shape[1] == 1 else [f"y{i + 1}" for i in range(a.shape[1])])
        )
        if len(labels) != a.shape[1]:
            raise ValueError(f"{len(labels)} names for {a.shape[1]} outputs")
        out = {str(k): a[:, i] for i, k in enumerate(labels)}
    for name, v in out.items():
        if v.shape != (n,):
            raise ValueError(f"{name}: {v.shape[0] if v.ndim else 0} values for {n} times")
    return out


def innovation_figure(
    times: Any,
    innovations: Any,
    innovation_sd: Any = None,
    *,
    title: str = "one-step residuals",
    path: str | os.PathLike[str] | None = None,
    names: Sequence[str] | None = None,
    max_lag: int | None = None,
    alpha: float = 0.05,
    synthetic: bool = False,
) -> Figure:
    """The residual diagnostics of a stochastic grey-box fit, one row of three panels per output.

    Left: the standardised one-step residuals (innovations) e_t / sd_t over time (hours since
    ``times[0]``, ``times`` in seconds) with the +-z_(1-alpha/2) lines; ``innovation_sd`` is
    the filter's predicted standard deviation of each innovation (same shapes as
    ``innovations``, or a scalar per output), and without it the residuals are scaled by
    their sample standard deviation around their mean. Middle: their autocorrelation
    (:func:`railtherm.estimation.acf.autocorrelation`) at lags 1..``max_lag`` samples (default
    min(40, m // 4)) with the white-noise band +-z_(1-alpha/2) / sqrt(m) (95 % at the default
    alpha) and the Ljung-Box p-value (Ljung & Box 1978,
    :func:`railtherm.estimation.metrics.ljung_box`).
    Right: the cumulated periodogram against frequency (cycles per sample) with its
    Kolmogorov-Smirnov band and p-value
    (:func:`railtherm.estimation.diagnostics.cumulated_periodogram`,
    exact method; NaN rows dropped there, while the autocorrelation counts them as zero
    deviations so that lags stay lags in time).

    ``innovations``: a 1-D array (one output), rows x outputs, or a mapping {output: series};
    ``names`` labels the columns of an array. NaN marks a missing row. ``path``: when given,
    the figure is also written there as PNG and SVG (:func:`save_figure`; a ``.png`` or ``.svg``
    suffix is taken as the stem's). ``synthetic`` adds the :data:`SYNTHETIC_NOTE` footer.
    Returns the figure, laid out for byte-identical files."""
    from scipy.stats import norm  # ~2 s to import: only when this figure is drawn

    t = np.asarray(times, dtype=float)
    if t.ndim != 1 or t.size == 0:
        raise ValueError(f"times must be a non-empty 1-D array, got shape {t.shape}")
    series = _per_output(innovations, names, t.size)
    if innovation_sd is None:
        sds = None
    elif isinstance(innovation_sd, Mapping):
        sds = {k: np.broadcast_to(np.asarray(v, float), t.shape) for k, v in innovation_sd.items()}
    else:
        sd = np.asarray(innovation_sd, dtype=float)
        if sd.ndim == 0 or (sd.ndim == 1 and sd.size == len(series) != t.size):
            sd = np.broadcast_to(sd, (t.size, len(series)))  # a constant per output
        sds = dict(zip(series, _per_output(sd, list(series), t.size).values(), strict=True))
    z = float(norm.isf(alpha / 2.0))
    hours = (t - t[0]) / 3600.0
    rows = len(series)
    with matplotlib.rc_context(RC):
        fig = Figure(figsize=(7.0, 0.6 + 2.0 * rows), dpi=DPI, layout="constrained")
        FigureCanvasAgg(fig)
        grid = fig.add_gridspec(rows, 3, width_ratios=[1.9, 1.0, 1.0])
        for r, (name, e) in enumerate(series.items()):
            if sds is None:
                scale = np.nanstd(e, ddof=1) if np.isfinite(e).sum() > 1 else math.nan
                eps = (e - np.nanmean(e)) / scale
                ylabel = f"{name}: e / s (1)"
            else:
                if name not in sds:
                    raise ValueError(f"no innovation standard deviation for {name}")
                eps = e / sds[name]
                ylabel = f"{name}: e / σ (1)"
            m = int(np.isfinite(eps).sum())
            ax_t, ax_a, ax_c = (fig.add_subplot(grid[r, c]) for c in range(3))

            ax_t.plot(hours, eps, color=_INNOVATION_COLOR, lw=0.5)
            for y in (z, -z):
                ax_t.axhline(y, **_BAND)
            ax_t.axhline(0.0, color="0.5", lw=0.5)
            ax_t.set_xlim(hours[0], hours[-1] if hours[-1] > hours[0] else hours[0] + 1.0)
            ax_t.set_ylabel(ylabel)

            _acf_panel(ax_a, eps, z, m, max_lag)
            _periodogram_panel(ax_c, eps, alpha, m)
            ax_c.set_xlim(0.0, 0.5)
            ax_c.set_ylim(0.0, 1.0)
            for ax in (ax_t, ax_a, ax_c):
                ax.grid(True, lw=0.4, alpha=0.5)
            if r == 0:
                fig.suptitle(title, x=0.02, ha="left")
                ax_t.set_title("standardised innovations", loc="left")
                ax_a.set_title(f"ACF ({100 * (1 - alpha):g} % band)")
                ax_c.set_title("cumul. periodogram")
            if r == rows - 1:
                ax_t.set_xlabel("time (h)")
                ax_a.set_xlabel("lag (samples)")
                ax_c.set_xlabel("frequency (1/sample)")
    fig = finish_figure(fig, synthetic)
    if path is not None:
        stem = Path(path)
        save_figure(fig, stem.with_suffix("") if stem.suffix in (".png", ".svg") else stem)
    return fig


def _acf_panel(ax: Any, eps: np.ndarray, z: float, m: int, max_lag: int | None) -> None:
    """The middle panel of :func:`innovation_figure`: autocorrelation, white-noise band and
    the Ljung-Box p-value."""
    lags = max(1, min(40, m // 4) if max_lag is None else int(max_lag))
    rho = autocorrelation(eps, lags)[1:]
    k = np.arange(1, rho.size + 1)
    ax.vlines(k, 0.0, rho, color=_INNOVATION_COLOR, lw=0.8)
    ax.plot(k, rho, ls="none", marker="o", ms=2.0, color=_INNOVATION_COLOR)
    if m > 0:
        for y in (z / math.sqrt(m), -z / math.sqrt(m)):
            ax.axhline(y, **_BAND)
    ax.axhline(0.0, color="0.5", lw=0.5)
    ax.set_xlim(0.0, lags + 0.5)
    if m >= 3:  # the lags of the verdict's test (metrics.ljung_box's default)
        lb = ljung_box(eps)
        ax.text(
            0.97,
            0.95,
            f"Ljung-Box p = {lb.p_value:.2g}",
            transform=ax.transAxes,
            ha="right",
            va="top",
            fontsize=7,
        )


def _periodogram_panel(ax: Any, eps: np.ndarray, alpha: float, m: int) -> None:
    """The right panel of :func:`innovation_figure`: the cumulated periodogram with its
    Kolmogorov-Smirnov band and p-value."""
    if m >= 5:
        cpg = cumulated_periodogram(eps, alpha)
        nu = np.r_[0.0, cpg.frequencies]
        lo, hi = cpg.band()
        ax.plot(nu, np.r_[0.0, cpg.expected], color="0.6", lw=0.5)
        ax.plot(nu, np.r_[0.0, lo], **_BAND)
        ax.plot(nu, np.r_[min(cpg.half_width, 1.0), hi], **_BAND)
        ax.plot(nu, np.r_[0.0, cpg.cumulated], color=_INNOVATION_COLOR, lw=0.9)
        ax.text(
            0.97,
            0.05,
            f"KS p = {cpg.p_value:.2g}",
            transform=ax.transAxes,
            ha="right",
            va="bottom",
            fontsize=7,
        )


# ---------------------------------------------------------------------------------------------
# Every figure of one vehicle (rule vehicle_figures)


def vehicle_figures(
    vehicle: str,
    *,
    kvalue: Mapping[str, str] | None = None,
    fit_files: Mapping[str, Mapping[str, str]] | None = None,
    synthetic: bool = False,
) -> list[str]:
    """Draw every figure of one vehicle from its result files, as PNG and SVG: the record with
    the k window and the k-test verdict (:func:`kvalue_figure`), and per fit the measured vs
    simulated temperatures (:func:`fit_figure`) and, for a Kalman-filter fit, its one-step
    innovations (:func:`innovation_figure`).

    ``kvalue``: the files ``record`` and ``window`` (tidy tables), ``result`` (kvalue.yaml) and
    ``png`` (the figure's PNG path; the SVG beside it), or None. ``fit_files``: per model key the
    files ``fit`` (fit_<key>.yaml), ``series`` (its measured vs simulated series), ``png`` and,
    for a Kalman-filter fit, ``innovations_png``. Returns what was drawn, a line per figure.
    """
    drawn = []
    if kvalue is not None:
        result = KValue.from_dict(rt_io.read_result(kvalue["result"]))
        figure = kvalue_figure(
            ingest.read_tidy(kvalue["record"]),
            ingest.read_tidy(kvalue["window"]),
            result,
            f"{vehicle}: static k test (eq. 10)",
            synthetic=synthetic,
        )
        save_figure(figure, kvalue["png"].removesuffix(".png"))
        drawn.append(f"k figure of {vehicle}")
    for files in (fit_files or {}).values():
        fit = rt_io.read_fit(files["fit"])
        series = pd.read_csv(files["series"])
        fit_synthetic = fit.synthetic
        model = structures.of_fit(fit.structure_name).title
        if fit.estimator == "kalman":
            model += ", Kalman-filter estimator"
        figure = fit_figure(series, fit, f"{fit.vehicle}: {model}", synthetic=fit_synthetic)
        save_figure(figure, files["png"].removesuffix(".png"))
        drawn.append(f"fit figure of {fit.vehicle}, {fit.structure_name}")
        if "innovations_png" in files:
            names = list(fit.outputs)
            innovation_figure(
                series["time"].to_numpy(float),
                series[[f"{s}_innovation" for s in names]].to_numpy(float),
                series[[f"{s}_innovation_sd" for s in names]].to_numpy(float),
                title=f"{fit.vehicle}: {fit.structure_name}, Kalman-filter estimator",
                path=files["innovations_png"],
                names=names,
                synthetic=fit_synthetic,
            )
            drawn.append(f"innovation figure of {fit.vehicle}, {fit.structure_name}")
    return drawn
