"""Diagnostic figures, deterministic byte for byte (Agg canvas, fixed SVG hash salt, no dates).

Figures are built on :class:`matplotlib.figure.Figure` with an Agg canvas, never through
``pyplot``, so nothing depends on a global figure manager or an interactive backend.

Time axis of :func:`kvalue_figure`: hours from the start of the record (the first row of the
whole-file tidy table). The k window is placed on it either by ``offset_s`` (seconds from the
record start to the window start) or, by default, by finding the window's first ``timestamp``
among the record's ``timestamp`` values (ISO text is compared as time, seconds as numbers).

Study figures (paper section 6): :func:`fit_figure` (one vehicle, one model order),
:func:`figure3` (Tram2, first- vs second-order model), :func:`figure4` (measured vs simulated T
for a few metros) and :func:`figure5` (c_veh and delta by vehicle class). Their time axes lay
the identification windows side by side: each window keeps its own time (hours since the
window start, as in the ``order{n}_series.csv`` files) and starts a small gap after the end of
the previous one; thin vertical lines separate the windows and the window names stand above the
top panel. ``synthetic=True`` (or :func:`synthetic_note`) adds the footer
:data:`SYNTHETIC_NOTE` so figures of virtual-tunnel data cannot pass for measurements.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import matplotlib
import numpy as np
import pandas as pd
from matplotlib import transforms
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.layout_engine import ConstrainedLayoutEngine, PlaceHolderLayoutEngine
from matplotlib.lines import Line2D
from matplotlib.text import Text

from railtherm import io as rt_io
from railtherm import structures
from railtherm.data import ingest
from railtherm.estimation import pem
from railtherm.estimation.acf import autocorrelation
from railtherm.estimation.diagnostics import cumulated_periodogram
from railtherm.estimation.kvalue import KValue
from railtherm.estimation.metrics import ljung_box
from railtherm.study import aggregate
from railtherm.study.quality import ACCEPTABLE, IN_DOUBT

__all__ = [
    "fit_figure",
    "figure3",
    "figure4",
    "figure5",
    "innovation_figure",
    "kvalue_figure",
    "save_figure",
    "synthetic_note",
    "sindy_figure",
    "vehicle_figures",
    "window_offset_s",
]

FIGSIZE_IN = (7.0, 4.8)  # fits a paper column pair / A4 page width with margins
DPI = 200
SVG_HASHSALT = "railtherm"
# no creation date, no software version in the files: bytes depend only on the content
PNG_METADATA = {"Software": None}
SVG_METADATA = {"Date": None, "Creator": None}
_RC = {
    "font.size": 9,
    "axes.titlesize": 10,
    "axes.labelsize": 9,
    "legend.fontsize": 8,
    "svg.hashsalt": SVG_HASHSALT,
    "svg.fonttype": "path",
    "path.simplify": True,
}

COLORS = {"T": "#c0392b", "T_veh": "#8e44ad", "T_o": "#2471a3", "Q_H": "#4d4d4d"}
IRRADIANCE_COLORS = ("#d68910", "#b9770e", "#7d6608")
FIGSIZE_FIG5_IN = (3.5, 3.0)  # each of Figure 5 (a) and (b): one paper column
SYNTHETIC_NOTE = "synthetic data: virtual climatic wind tunnel (not measurements)"
# the models of Figure 3: told apart by line style as well as colour (grey print)
MODEL_LABELS = {1: "first-order model (eq. 9)", 2: "second-order model (eqs. 7-8)"}
MODEL_STYLES = {
    1: {"color": "#1e8449", "ls": (0, (5, 2)), "lw": 1.1},
    2: {"color": "#17202a", "ls": (0, (6, 2, 1, 2)), "lw": 1.1},
}
# measured: wide and light; simulated: thin, dark and dashed, drawn on top
_MEASURED = {"lw": 1.6, "alpha": 0.55}
_SIMULATED = {"ls": (0, (4, 2)), "lw": 0.9}
_SIM_COLORS = {"T": "#641e16", "T_veh": "#4a235a"}
_SEPARATOR = {"color": "0.45", "lw": 0.6, "zorder": 0.5}
# Figure 5 points: filled circle, or hollow square for "assumptions in doubt"
_POINT = {
    False: {"marker": "o", "ms": 3.8, "mew": 0.9, "mec": COLORS["T_veh"], "mfc": COLORS["T_veh"]},
    True: {"marker": "s", "ms": 3.6, "mew": 0.9, "mec": COLORS["T_veh"], "mfc": "none"},
}
# Figure 5, a value the data do not determine: an open triangle at its one-sided limit (up:
# at least, down: at most) with an arrow to the axis edge, or a dotted line over the axis
_OPEN = {
    kind: {"marker": m, "ms": 4.2, "mew": 0.9, "mec": "0.35", "mfc": "white"}
    for kind, m in (("lower", "^"), ("upper", "v"), ("none", "D"))
}
_OPEN_ARROW = {"arrowstyle": "->", "color": "0.45", "lw": 0.7, "shrinkA": 3, "shrinkB": 0}
_OPEN_BAND = {"color": "0.55", "lw": 0.7, "ls": (0, (1, 1.5))}
_TIME_LABEL = "time since window start (h)"
_MAX_TICKS = 12.0  # at most about this many time ticks over the whole axis
_HOUR_STEPS = (0.25, 0.5, 1.0, 2.0, 3.0, 4.0, 6.0, 12.0, 24.0, 48.0, 72.0, 168.0)


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
    with matplotlib.rc_context(_RC):
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


def save_figure(fig: Figure, stem: str | os.PathLike[str]) -> tuple[Path, Path]:
    """Write ``stem.png`` and ``stem.svg`` (byte-deterministic); returns both paths."""
    stem = Path(stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    png, svg = Path(f"{stem}.png"), Path(f"{stem}.svg")  # "a/Tram1.k" -> a/Tram1.k.png
    with matplotlib.rc_context({"svg.hashsalt": SVG_HASHSALT, "svg.fonttype": "path"}):
        fig.savefig(png, format="png", dpi=DPI, metadata=PNG_METADATA)
        fig.savefig(svg, format="svg", metadata=SVG_METADATA)
    return png, svg


def synthetic_note(fig: Figure, text: str = SYNTHETIC_NOTE) -> Text:
    """Add the footer ``text`` (default :data:`SYNTHETIC_NOTE`) at the figure's bottom right.

    For a constrained-layout figure (also one this module already settled) the layout keeps a
    strip at the bottom free for it, so the note covers no tick label, axis label or legend,
    and is then settled (:func:`_settle`: later draws and saves reuse that layout unchanged).
    Returns the text."""
    size = 6.5
    strip = min(0.2, 1.9 * size / 72.0 / fig.get_figheight())  # figure fraction for one line
    engine = fig.get_layout_engine()
    # a placeholder that replaced a constrained layout (adjust_compatible False): ours, settled
    settled = isinstance(engine, PlaceHolderLayoutEngine) and not engine.adjust_compatible
    if settled:
        engine = ConstrainedLayoutEngine()  # the defaults, as layout="constrained" gives
        fig.set_layout_engine(engine)
    if isinstance(engine, ConstrainedLayoutEngine):
        engine.set(rect=(0.0, strip, 1.0, 1.0 - strip))
    with matplotlib.rc_context(_RC):
        note = fig.text(
            0.995,
            0.25 * strip,
            text,
            ha="right",
            va="bottom",
            fontsize=size,
            fontstyle="italic",
            color="0.3",
        )
    if isinstance(engine, ConstrainedLayoutEngine):
        _settle(fig)
    return note


def _settle(fig: Figure, passes: int = 10, tol_px: float = 0.5) -> Figure:
    """Run the constrained layout to its fixed point, then keep that layout for good.

    Twin and secondary axes, titles above top tick labels and legends in small grid cells make
    each constrained-layout pass start from the previous one's result, so a figure drawn twice
    would come out slightly different. Laying out (without rendering) until no axes edge moves
    by more than ``tol_px`` pixels at the figure's resolution (the passes converge
    geometrically: 2 or 3 passes to half a pixel) and then swapping the engine for a
    placeholder makes every later draw, PNG or SVG, first save or second, use the very same
    layout: :func:`save_figure` stays byte for byte."""
    tol = tol_px / (fig.dpi * float(max(fig.get_size_inches())))  # in figure fractions
    with matplotlib.rc_context(_RC):
        before = None
        for _ in range(passes):
            fig.draw_without_rendering()
            now = np.array([ax.get_position().bounds for ax in fig.axes])
            if before is not None and float(np.abs(now - before).max()) < tol:
                break
            before = now
        fig.set_layout_engine("none")
        # the solver's last bits depend on its internal order (they differed from one process
        # to the next with a footer's rect): round them off so the ids in the SVG, hashes of
        # the clip rectangles, are the same in every run
        for ax in fig.axes:
            ax.set_position([round(float(v), 9) for v in ax.get_position().bounds])
    return fig


def _finish(fig: Figure, synthetic: bool, note: str | None = None) -> Figure:
    """The footer when asked (``note``, else :data:`SYNTHETIC_NOTE`); the settled layout
    either way."""
    if synthetic or note:
        synthetic_note(fig, note or SYNTHETIC_NOTE)
        return fig
    return _settle(fig)


def provenance_note(table: pd.DataFrame) -> str | None:
    """The footer that says what a study figure's data are, from a table's ``source`` and
    ``vehicle`` columns: the synthetic note when every row is synthetic, which vehicles are
    measured when the data are mixed, none when every row is measured."""
    synthetic = table["source"].astype(str).str.startswith("synthetic")
    if synthetic.all():
        return SYNTHETIC_NOTE
    if not synthetic.any():
        return None
    measured = ", ".join(table.loc[~synthetic, "vehicle"].astype(str))
    return f"synthetic data (virtual climatic wind tunnel), except measured: {measured}"


# --- windows laid side by side on one time axis -------------------------------------------


@dataclass(frozen=True)
class _Windows:
    """The side-by-side layout of a series' windows (consecutive blocks of ``window``).

    ``x``: hours on the common axis, one NaN between windows so no line joins two of them;
    ``rows``: the series row of each ``x`` (-1 at the NaNs); ``spans``: (name, start, end, local
    start) per window in axis hours; ``gap``: hours between one window's end and the next."""

    x: np.ndarray
    rows: np.ndarray
    spans: tuple[tuple[str, float, float, float], ...]
    gap: float

    def values(self, series: pd.DataFrame, column: str) -> np.ndarray:
        """``column`` on the layout (NaN between windows; all NaN if the column is absent)."""
        if column not in series:
            return np.full(self.x.size, np.nan)
        v = series[column].to_numpy(dtype=float)
        return np.where(self.rows >= 0, v[np.maximum(self.rows, 0)], np.nan)

    def separators(self) -> list[float]:
        """Axis hours of the thin lines between windows (the middle of each gap)."""
        return [(a[2] + b[1]) / 2.0 for a, b in zip(self.spans, self.spans[1:], strict=False)]

    def ticks(self) -> tuple[list[float], list[str]]:
        """Tick positions and labels: each window's own hours (0, step, 2 step ...), with one
        nice step for all windows; a tick too close to the next window's 0 is left out."""
        length = self.spans[-1][2] - self.spans[0][1]
        step = next((s for s in _HOUR_STEPS if length / s <= _MAX_TICKS), None)
        if step is None:
            step = _HOUR_STEPS[-1] * np.ceil(length / _MAX_TICKS / _HOUR_STEPS[-1])
        positions, labels = [], []
        for i, (_, start, end, local0) in enumerate(self.spans):
            limit = end if i + 1 == len(self.spans) else self.spans[i + 1][1] - 0.45 * step
            first = np.ceil(local0 / step - 1e-9) * step
            for local in np.arange(first, local0 + (limit - start) + 1e-9, step):
                positions.append(start + local - local0)
                labels.append(f"{local + 0.0:g}")  # + 0.0: no "-0"
        return positions, labels


def _windows(series: pd.DataFrame) -> _Windows:
    """Lay the windows of an ``order{n}_series.csv`` table side by side (file order kept)."""
    missing = [c for c in ("window", "time") if c not in series]
    if missing:
        raise ValueError(f"the series lacks the column(s) {', '.join(missing)}")
    if len(series) == 0:
        raise ValueError("the series is empty")
    names = series["window"].astype(str).to_numpy()
    hours = series["time"].to_numpy(dtype=float) / 3600.0
    starts = np.flatnonzero(np.r_[True, names[1:] != names[:-1]])
    stops = np.r_[starts[1:], names.size]
    total = float(sum(hours[b - 1] - hours[a] for a, b in zip(starts, stops, strict=True)))
    gap = 0.03 * total if starts.size > 1 else 0.0
    if starts.size > 1 and gap <= 0.0:
        gap = 1.0 / 60.0
    xs, rows, spans = [], [], []
    offset = 0.0
    for a, b in zip(starts, stops, strict=True):
        if xs:
            xs.append(np.array([np.nan]))
            rows.append(np.array([-1]))
        local = hours[a:b]
        x = offset + (local - local[0])
        xs.append(x)
        rows.append(np.arange(a, b))
        spans.append((str(names[a]), float(x[0]), float(x[-1]), float(local[0])))
        offset = float(x[-1]) + gap
    return _Windows(np.concatenate(xs), np.concatenate(rows), tuple(spans), gap)


def _time_axis(axes: Sequence[Any], lay: _Windows, *, names: bool = True) -> None:
    """Ticks, limits, separators and window names for panels sharing the layout ``lay``.

    ``axes`` share their x axis, top panel first; the last one carries the tick labels and the
    axis label, the first one the window names above it (a secondary axis, so the layout
    makes room for them)."""
    positions, labels = lay.ticks()
    bottom = axes[-1]
    bottom.set_xticks(positions, labels)
    bottom.set_xlim(lay.spans[0][1], lay.spans[-1][2])
    bottom.set_xlabel(_TIME_LABEL)
    for ax in axes:
        for x in lay.separators():
            ax.axvline(x, **_SEPARATOR)
        ax.grid(True, lw=0.4, alpha=0.5)
        if ax is not bottom:
            ax.tick_params(labelbottom=False)
    if names:
        top = axes[0].secondary_xaxis("top")
        top.set_xticks([(s[1] + s[2]) / 2.0 for s in lay.spans], [s[0] for s in lay.spans])
        top.tick_params(length=0, pad=1.5, labelsize=8)


def _legend_row(
    fig: Figure, cell: Any, handles: list[Any], ncols: int, handlelength: float = 2.4
) -> None:
    """The legend in its own (axis-free) grid cell below the panels, so it hides no data and
    the layout keeps it clear of the tick labels and of a footer."""
    row = fig.add_subplot(cell)
    row.set_axis_off()
    row.legend(
        handles=handles,
        loc="upper center",
        ncols=ncols,
        frameon=False,
        borderaxespad=0,
        handlelength=handlelength,
        columnspacing=1.2,
    )


def _has_data(v: np.ndarray) -> bool:
    return bool(np.isfinite(v).any())


T_O_MIN_SPAN_K = 10.0  # the T_o axis spans at least this: a steady tunnel's noise stays small


def _inputs_panel(ax: Any, series: pd.DataFrame, lay: _Windows, tunnel: bool = True) -> list[Any]:
    """T_o (left, degC) and Q_H (right, kW, held over each sample: step "post"); T_o is the
    tunnel air of a climatic wind tunnel (``tunnel``), else the outdoor air."""
    axq = ax.twinx()
    where = "tunnel air" if tunnel else "outdoor air"
    lines = ax.plot(
        lay.x, lay.values(series, "T_o"), color=COLORS["T_o"], lw=1.0, label=f"T_o ({where})"
    )
    q = lay.values(series, "Q_H") / 1000.0
    lines += axq.step(lay.x, q, where="post", color=COLORS["Q_H"], lw=1.0, label="Q_H (heat input)")
    ax.set_ylabel("T_o (°C)")
    t_o = np.asarray(lay.values(series, "T_o"), dtype=float)
    if _has_data(t_o):  # a steady tunnel's sensor noise must not fill the panel over Q_H
        low, high = float(np.nanmin(t_o)), float(np.nanmax(t_o))
        if high - low < T_O_MIN_SPAN_K:
            middle = (low + high) / 2.0
            ax.set_ylim(middle - T_O_MIN_SPAN_K / 2.0, middle + T_O_MIN_SPAN_K / 2.0)
    # irradiance inputs (eq. 1), means over the step like Q_H, on the same axis in kW/m2
    irradiance = {c: lay.values(series, c) / 1000.0 for c in series.columns if c.startswith("I_")}
    for i, (name, values) in enumerate(irradiance.items()):
        lines += axq.step(
            lay.x,
            values,
            where="post",
            color=IRRADIANCE_COLORS[i % len(IRRADIANCE_COLORS)],
            lw=0.7,
            label=f"{name} (irradiance, kW/m²)",
        )
    axq.set_ylabel("Q_H (kW), I (kW/m²)" if irradiance else "Q_H (kW)")
    q = np.concatenate([q, *irradiance.values()])  # the right axis's range covers every trace
    if _has_data(q):
        low, high = min(0.0, float(np.nanmin(q))), float(np.nanmax(q))
        axq.set_ylim(low, high + 0.1 * (high - low) if high > low else low + 1.0)
    ax.set_zorder(axq.get_zorder() + 1)  # the temperature over the power trace
    ax.patch.set_visible(False)
    return lines


def _fmt(x: Any, digits: int) -> str:
    try:
        value = float(x)
    except (TypeError, ValueError):
        return "n/a"
    return f"{value:.{digits}f}" if np.isfinite(value) else "n/a"


def _fit_text(fit: Mapping[str, Any]) -> str:
    """R^2 (eq. 21) and NRMSE fit of T (as in the fit file) and the verdict."""
    return "\n".join(
        [
            f"R² of T (eq. 21) = {_fmt(fit.get('R2'), 4)}",
            f"NRMSE fit of T = {_fmt(fit.get('nrmse_fit'), 3)}",
            f"verdict: {fit.get('verdict', 'n/a')}",
        ]
    )


def fit_figure(
    series: pd.DataFrame,
    fit: Mapping[str, Any],
    title: str,
    *,
    synthetic: bool = False,
) -> Figure:
    """One vehicle, one model order: measured vs simulated temperatures (top), the residuals of
    the compared outputs (middle, measured - simulated, K) and the inputs T_o and Q_H (bottom),
    on one side-by-side time axis; legends and a box with R^2 (eq. 21), the NRMSE fit and the
    verdict stand right of the panels.

    ``series`` is an ``order{n}_series.csv`` table, ``fit`` the ``fit_order{n}.yaml`` mapping.
    T_veh is drawn when it was compared (``"T_veh" in fit["outputs"]``) or measured."""
    lay = _windows(series)
    outputs = [str(o) for o in (fit.get("outputs") or ["T"])]
    with matplotlib.rc_context(_RC):
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
            if state == "T_veh" and not (_has_data(measured) or state in outputs):
                continue
            if _has_data(measured):
                lines += ax.plot(
                    lay.x, measured, color=COLORS[state], label=f"{state} measured", **_MEASURED
                )
            if _has_data(simulated):
                lines += ax.plot(
                    lay.x,
                    simulated,
                    color=_SIM_COLORS[state],
                    label=f"{state} simulated",
                    **_SIMULATED,
                )
        ax.set_ylabel("temperature (°C)")
        ax.set_title(title, loc="left")

        residuals = []
        axr.axhline(0.0, color="0.2", lw=0.6)
        for state in outputs:
            e = lay.values(series, f"{state}_residual")
            if not _has_data(e):  # no residual column: measured - simulated
                e = lay.values(series, state) - lay.values(series, f"{state}_sim")
            if _has_data(e):
                residuals += axr.plot(
                    lay.x, e, color=COLORS.get(state, "0.3"), lw=0.5, label=f"{state} residual"
                )
        axr.set_ylabel("meas. − sim. (K)")

        inputs = _inputs_panel(axi, series, lay, tunnel=synthetic)
        _time_axis([ax, axr, axi], lay)

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
    return _finish(fig, synthetic)


def _same_windows(a: pd.DataFrame, b: pd.DataFrame) -> bool:
    return (
        len(a) == len(b)
        and bool((a["window"].astype(str).to_numpy() == b["window"].astype(str).to_numpy()).all())
        and bool(np.allclose(a["time"].to_numpy(dtype=float), b["time"].to_numpy(dtype=float)))
    )


def figure3(
    series1: pd.DataFrame,
    series2: pd.DataFrame,
    title: str = "Tram2: first- and second-order model vs measurement (Figure 3)",
    *,
    synthetic: bool = False,
) -> Figure:
    """The paper's Figure 3: measured T and the simulations of the first-order (``series1``,
    eq. 9) and second-order model (``series2``, eqs. 7-8) over the identification windows laid
    side by side, with a small panel of the inputs Q_H (kW) and T_o (degC, from ``series2``).

    Both series must cover the same windows and times (ValueError otherwise)."""
    lay = _windows(series2)
    if not {"window", "time"} <= set(series1) or not _same_windows(series1, series2):
        raise ValueError("figure3: the two series must cover the same windows and times")
    with matplotlib.rc_context(_RC):
        fig = Figure(figsize=FIGSIZE_IN, dpi=DPI, layout="constrained")
        FigureCanvasAgg(fig)
        grid = fig.add_gridspec(3, 1, height_ratios=[3.0, 1.0, 0.3])
        ax = fig.add_subplot(grid[0])
        axi = fig.add_subplot(grid[1], sharex=ax)
        lines = ax.plot(
            lay.x, lay.values(series2, "T"), color=COLORS["T"], label="measured T", **_MEASURED
        )
        for order, series in ((1, series1), (2, series2)):
            lines += ax.plot(
                lay.x, lay.values(series, "T_sim"), label=MODEL_LABELS[order], **MODEL_STYLES[order]
            )
        ax.set_ylabel("T, indoor air (°C)")
        ax.set_title(title, loc="left")
        lines += _inputs_panel(axi, series2, lay)
        _time_axis([ax, axi], lay)
        _legend_row(fig, grid[2], lines, ncols=3)
    return _finish(fig, synthetic)


def figure4(
    series: Mapping[str, pd.DataFrame],
    title: str = "Measured and simulated indoor air temperature (Figure 4)",
    *,
    synthetic: bool = False,
) -> Figure:
    """The paper's Figure 4: one panel per vehicle (``series`` maps the vehicle name to its
    order-2 series, in panel order) with measured and simulated indoor air temperature T over
    its windows (hours since the window start)."""
    if not series:
        raise ValueError("figure4 needs at least one vehicle")
    layouts = {name: _windows(s) for name, s in series.items()}
    with matplotlib.rc_context(_RC):
        fig = Figure(figsize=FIGSIZE_IN, dpi=DPI, layout="constrained")
        FigureCanvasAgg(fig)
        grid = fig.add_gridspec(len(series) + 1, 1, height_ratios=[1.0] * len(series) + [0.1])
        axes = [fig.add_subplot(grid[i]) for i in range(len(series))]
        lines: list[Any] = []
        for ax, (name, s) in zip(axes, series.items(), strict=True):
            lay = layouts[name]
            measured = ax.plot(
                lay.x, lay.values(s, "T"), color=COLORS["T"], label="measured T", **_MEASURED
            )
            simulated = ax.plot(
                lay.x,
                lay.values(s, "T_sim"),
                label="simulated T, " + MODEL_LABELS[2],
                **MODEL_STYLES[2],
            )
            lines = lines or measured + simulated
            ax.set_ylabel("T (°C)")
            ax.set_title(name, loc="left", fontsize=9)
            _time_axis([ax], lay, names=len(lay.spans) > 1)
        fig.suptitle(title, x=0.01, ha="left", fontsize=10)
        _legend_row(fig, grid[-1], lines, ncols=2)
    return _finish(fig, synthetic)


def _spread(n: int, half_width: float = 0.22) -> np.ndarray:
    """Deterministic horizontal offsets of n points inside a box, evenly spread."""
    return np.linspace(-half_width, half_width, n) if n > 1 else np.zeros(n)


def _declutter(y: np.ndarray, sep: float) -> np.ndarray:
    """Label heights (axes fraction) at least ``sep`` apart and inside [0, 1], each as close to
    its point's height as that allows; ``y`` sorted ascending."""
    out = np.array(y, dtype=float)
    for i in range(1, out.size):
        out[i] = max(out[i], out[i - 1] + sep)
    if out.size:
        out[-1] = min(out[-1], 1.0 - sep / 2)
    for i in range(out.size - 2, -1, -1):
        out[i] = min(out[i], out[i + 1] - sep)
    return out


def _limits(values: np.ndarray, log: bool, pad: float = 0.07) -> tuple[float, float]:
    """Axis limits around the finite ``values`` (a fraction ``pad`` of the span each side)."""
    v = values[np.isfinite(values) & ((values > 0) if log else True)]
    lo, hi = (np.log10(v.min()), np.log10(v.max())) if log else (v.min(), v.max())
    span = hi - lo if hi > lo else (abs(hi) if hi else 1.0)
    lo, hi = lo - pad * span, hi + pad * span
    return (10.0**lo, 10.0**hi) if log else (float(lo), float(hi))


def _identified(table3: pd.DataFrame, quantity: str) -> np.ndarray:
    """Rows whose ``quantity`` the data determine: Table 3's ``<q>_status``, or for a table
    without it a finite value with a bounded interval (railtherm.estimation.pem.identification)."""
    values = table3[quantity].to_numpy(dtype=float)
    ok = np.isfinite(values)
    if f"{quantity}_status" in table3:
        return ok & (table3[f"{quantity}_status"].astype(str) == "estimated").to_numpy()
    intervals = table3[[f"{quantity}_lo", f"{quantity}_hi"]].to_numpy(dtype=float)
    for i in np.flatnonzero(ok):
        ok[i] = pem.identification(values[i], intervals[i])["identified"]
    return ok


def _without_not_given(table3: pd.DataFrame, quantity: str) -> tuple[pd.DataFrame, str | None]:
    """Table 3 without the rows whose ``quantity`` is not given (no metadata for it, e.g.
    c_veh without mass_kg: ``<q>_status`` "not given: ..."), and one line naming them and why
    (None when there are none)."""
    status = f"{quantity}_status"
    if status not in table3:
        return table3, None
    mask = table3[status].map(aggregate.is_not_given).astype(bool).to_numpy()
    if not mask.any():
        return table3, None
    why = "; ".join(dict.fromkeys(table3.loc[mask, status].astype(str)))
    names = ", ".join(table3.loc[mask, "vehicle"].astype(str))
    return table3[~mask].reset_index(drop=True), f"{names} ({why})"


def _empty_class_figure(title: str, ylabel: str, message: str) -> Figure:
    """A Figure 5 panel with nothing to show, saying why (``message``)."""
    with matplotlib.rc_context(_RC):
        fig = Figure(figsize=FIGSIZE_FIG5_IN, dpi=DPI, layout="constrained")
        FigureCanvasAgg(fig)
        ax = fig.add_subplot()
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_ylabel(ylabel)
        ax.set_title(title, loc="left")
        ax.text(0.5, 0.5, message, transform=ax.transAxes, ha="center", va="center", wrap=True)
    return fig


BOX_MIN = 3  # a class's box needs this many values the data determine; fewer: points only


def _class_figure(
    table3: pd.DataFrame, quantity: str, title: str, ylabel: str, log_if_span: float | None
) -> Figure:
    """Box plot of ``quantity`` per class with each vehicle's point, 95 % interval and name;
    a class with fewer than :data:`BOX_MIN` values the data determine has its points only
    (the quartiles of two values are no statistic).

    Boxes, axis range and points come from the values the data determine only. A value they
    do not determine (``<q>_status`` "not identified") is drawn apart: an open triangle at the
    one-sided limit the data give (clipped to the axis) with an arrow to the axis edge where
    the value may lie, or a dotted line over the whole axis where they give no limit. A value
    not given (``<q>_status`` "not given", no metadata for it) is not drawn: the legend names
    it, and a panel left with no vehicle says so."""
    table3, skipped = _without_not_given(table3, quantity)
    if len(table3) == 0:
        return _empty_class_figure(title, ylabel, f"no vehicle to show:\n{skipped}")
    ok = _identified(table3, quantity)
    values = table3[quantity].to_numpy(dtype=float)
    finite = values[ok]
    if finite.size == 0:
        raise ValueError(f"table3 has no identified {quantity}")
    log = bool(
        log_if_span is not None and finite.min() > 0 and finite.max() / finite.min() > log_if_span
    )
    if log:
        ylabel += ", log scale"
    lo_hi = table3.loc[ok, [f"{quantity}_lo", f"{quantity}_hi"]].to_numpy(dtype=float).ravel()
    ylim = _limits(np.r_[finite, lo_hi], log)

    def frac(y: float) -> float:  # height as a fraction of the axes
        f = np.log10 if log else (lambda z: z)
        return float((f(y) - f(ylim[0])) / (f(ylim[1]) - f(ylim[0])))

    def at(h: float) -> float:  # the data value at a height fraction of the axes
        if log:
            return float(10.0 ** (np.log10(ylim[0]) + h * np.log10(ylim[1] / ylim[0])))
        return float(ylim[0] + h * (ylim[1] - ylim[0]))

    limits = table3.get(f"{quantity}_limit", pd.Series(np.nan, index=table3.index))
    kinds = table3.get(f"{quantity}_limit_kind", pd.Series("", index=table3.index))
    with matplotlib.rc_context(_RC):
        fig = Figure(figsize=FIGSIZE_FIG5_IN, dpi=DPI, layout="constrained")
        FigureCanvasAgg(fig)
        grid = fig.add_gridspec(2, 1, height_ratios=[1.0, 0.12])
        ax = fig.add_subplot(grid[0])
        if log:
            ax.set_yscale("log")
        ax.set_ylim(*ylim)
        # a label is about 6 pt high, with its white ground and a gap 8.5; the axes about 0.55
        # of the figure height
        sep = 8.5 / (0.55 * 72.0 * fig.get_figheight())
        name_at = transforms.offset_copy(ax.get_xaxis_transform(), fig=fig, x=3.0, units="points")
        classes = aggregate.class_order(table3["class"].tolist())
        boxes, labels, open_kinds = [], [], set()
        for pos, cls in enumerate(classes, start=1):
            in_class = (table3["class"].astype(str) == cls).to_numpy()
            part = table3[in_class]
            v, good = values[in_class], ok[in_class]
            boxes.append(v[good])
            extra = int((~good).sum())
            labels.append(f"{cls}\n(n={int(good.sum())}" + (f"+{extra})" if extra else ")"))
            # every vehicle of the class, identified or not, gets a slot and a name
            shown = np.where(good, v, np.nan)
            for i in np.flatnonzero(~good):  # at the limit, kept inside so the arrow shows
                lim = float(limits[in_class].iloc[i])
                shown[i] = at(min(max(frac(lim), 0.1), 0.9)) if math.isfinite(lim) else at(0.5)
            order = np.argsort(shown, kind="stable")
            heights = _declutter(np.array([frac(shown[i]) for i in order]), sep)
            for dx, i, h in zip(_spread(order.size), order, heights, strict=True):
                row = part.iloc[i]
                x, y = pos + dx, float(shown[i])
                name = str(row["vehicle"])
                if good[i]:
                    lo, hi = float(row[f"{quantity}_lo"]), float(row[f"{quantity}_hi"])
                    if np.isfinite(lo) and np.isfinite(hi):
                        ax.vlines(x, lo, hi, color=COLORS["T_veh"], lw=0.6, alpha=0.8, zorder=2)
                    doubt = str(row["verdict"]) == IN_DOUBT
                    (point,) = ax.plot([x], [y], ls="none", zorder=5, **_POINT[doubt])
                else:
                    kind = str(kinds[in_class].iloc[i])
                    open_kinds.add("limit" if kind in ("upper", "lower") else "none")
                    if kind in ("upper", "lower"):
                        edge = ylim[1] if kind == "lower" else ylim[0]
                        ax.annotate(
                            "",
                            xy=(x, edge),
                            xytext=(x, y),
                            arrowprops={**_OPEN_ARROW},
                            zorder=3,
                        )
                        marker = _OPEN[kind]
                        lim = float(limits[in_class].iloc[i])
                        name += f" ({'≥' if kind == 'lower' else '≤'} {lim:.3g})"
                    else:
                        ax.vlines(x, *ylim, zorder=2, **_OPEN_BAND)
                        marker = _OPEN["none"]
                    (point,) = ax.plot([x], [y], ls="none", zorder=5, **marker)
                point.set_gid(f"vehicle-{row['vehicle']}")
                ax.text(
                    x,
                    h,
                    name,
                    transform=name_at,
                    ha="left",
                    va="center",
                    fontsize=5.5,
                    color="0.2",
                    zorder=4,
                    # a faint white ground keeps the name legible over bars and box lines
                    bbox={"boxstyle": "square,pad=0.1", "fc": "white", "ec": "none", "alpha": 0.7},
                )
        positions = list(range(1, len(classes) + 1))
        grey = {"color": "0.35", "lw": 0.8}
        # a box of fewer than BOX_MIN values would draw quartiles that are not there
        boxed = [
            (pos, box) for pos, box in zip(positions, boxes, strict=True) if box.size >= BOX_MIN
        ]
        for pos, box in boxed:  # one call per class: a list of equal-length arrays is 2-D
            ax.boxplot(
                [box],
                positions=[pos],
                widths=0.62,
                showfliers=False,
                manage_ticks=False,
                boxprops=grey,
                whiskerprops=grey,
                capprops=grey,
                medianprops={"color": "0.1", "lw": 1.2},
                zorder=1,
            )
        ax.set_xticks(positions, labels)
        ax.set_xlim(0.45, len(classes) + 0.75)
        ax.set_ylabel(ylabel)
        ax.set_title(title, loc="left")
        ax.grid(True, axis="y", lw=0.4, alpha=0.5)
        verdicts = table3.loc[ok, "verdict"].astype(str)
        handles = [
            Line2D([], [], ls="none", label=label, **_POINT[doubt])
            for doubt, label in ((False, ACCEPTABLE), (True, IN_DOUBT))
            if ((verdicts == IN_DOUBT) == doubt).any()
        ]
        bar = {"marker": "|", "ms": 9, "mew": 0.6, "color": COLORS["T_veh"]}
        handles.append(Line2D([], [], ls="none", label="95 % interval", **bar))
        if "limit" in open_kinds:
            handles.append(
                Line2D([], [], ls="none", label="not identified: limit", **_OPEN["lower"])
            )
        if "none" in open_kinds:  # no limit the data give: anywhere on the axis
            handles.append(Line2D([], [], ls="none", label="not identified", **_OPEN["none"]))
        if skipped:  # its own line: the names may be long
            handles.append(Line2D([], [], ls="none", label=f"not shown: {skipped}"))
        _legend_row(fig, grid[1], handles, ncols=1 if skipped else 2, handlelength=1.2)
    return fig


def figure5(
    table3: pd.DataFrame, *, synthetic: bool = False, note: str | None = None
) -> tuple[Figure, Figure]:
    """The paper's Figure 5: (a) c_veh and (b) delta by vehicle class (Table 3).

    Box plots per class in the order tram, metro, regional, main-line (then any other class),
    only classes present, a box only for a class with at least 3 values the data determine
    (:data:`BOX_MIN`; fewer: the points alone); every vehicle's value as a point (evenly
    spread inside its box, sorted by value), its 95 % interval as a thin bar (left out when
    a bound is not finite) and its name (nudged up or down where names would overlap).
    Vehicles whose verdict is "assumptions in doubt" have a hollow square, the others a
    filled circle. Tick labels give
    the class and, below it, the number of vehicles with a value the data determine and of
    those without ("metro\n(n=4+1)"); the latter are drawn apart, never in a box
    (:func:`_class_figure`). delta gets a log axis when its values span more than a factor 20
    (said in the axis label). The footer: ``note`` (e.g. :func:`provenance_note`), or the
    synthetic note when ``synthetic``."""
    need = ["vehicle", "class", "verdict"]
    need += [f"{q}{s}" for q in ("c_veh", "delta") for s in ("", "_lo", "_hi")]
    missing = [c for c in need if c not in table3]
    if missing:
        raise ValueError(f"table3 lacks the column(s) {', '.join(missing)}")
    if len(table3) == 0:
        raise ValueError("table3 is empty")
    a = _class_figure(table3, "c_veh", "(a) c_veh by vehicle class", "c_veh (J/(kg K))", None)
    b = _class_figure(table3, "delta", "(b) δ by vehicle class", "δ = C_veh / C (1)", 20.0)
    return _finish(a, synthetic, note), _finish(b, synthetic, note)


# --- the SINDy cross-check ------------------------------------------------------------------

_EQ14_TERMS = (
    ("dT/dt", "T", "(kA+K_veh)/C"),
    ("dT/dt", "T_veh", "K_veh/C"),
    ("dT/dt", "T_o", "kA/C"),
    ("dT/dt", "Q_H", "1/C"),
    ("dT_veh/dt", "T", "K_veh/C_veh"),
    ("dT_veh/dt", "T_veh", "K_veh/C_veh"),
)
_EXTRA_TERMS = (("dT_veh/dt", "T_o"), ("dT_veh/dt", "Q_H"))
_TERM_COLORS = ("#c0392b", "#e67e22", "#2471a3", "#4d4d4d", "#8e44ad", "#1e8449")
_RATIO_LIMITS = (-0.5, 2.5)


def sindy_figure(results: Mapping[str, Mapping[str, Any]], *, synthetic: bool = False) -> Figure:
    """The SINDy cross-check of every vehicle (results: vehicle -> sindy.yaml contents).

    (a) Each term of eq. 14 as SINDy's least-squares coefficient divided by the PEM-implied
    one (1 = agreement), with SINDy's 95 % bootstrap interval over the same divisor; values
    outside the axis are drawn at its edge as triangles. (b) The terms eq. 14 lacks in
    dT_veh/dt (T_o: a body-to-outdoor path; Q_H: heating of the body), relative to the
    equation's largest coefficient, with the STLSQ threshold as dashed lines. Vehicles whose
    data are too poor to say are drawn hollow and grey; the verdict is printed under each."""
    names = list(results)
    if not names:
        raise ValueError("no SINDy results to draw")
    with matplotlib.rc_context(_RC):
        fig = Figure(figsize=(7.0, 5.2), dpi=DPI, layout="constrained")
        FigureCanvasAgg(fig)
        grid = fig.add_gridspec(3, 1, height_ratios=[1.0, 0.8, 0.13])
        ax_a, ax_b = fig.add_subplot(grid[0]), fig.add_subplot(grid[1])
        x = np.arange(len(names), dtype=float)
        lo_lim, hi_lim = _RATIO_LIMITS
        handles = []
        for k, (eq, feat, label) in enumerate(_EQ14_TERMS):
            dx = (k - 2.5) * 0.11
            for n, vid in enumerate(names):
                data = results[vid]
                term = _term(data, eq, feat)
                gb = term.get("grey_box")
                if gb is None or gb == 0:
                    continue
                poor = data["verdict"] == "data too poor to say"
                r = term["least_squares"] / gb
                lo, hi = sorted(np.array(term["ci95"]) / gb)
                ax_a.vlines(
                    x[n] + dx,
                    max(lo, lo_lim),
                    min(hi, hi_lim),
                    color=_TERM_COLORS[k],
                    lw=0.7,
                    alpha=0.4 if poor else 0.9,
                )
                clipped = r < lo_lim or r > hi_lim
                marker = ("v" if r < lo_lim else "^") if clipped else "o"
                ax_a.plot(
                    [x[n] + dx],
                    [min(max(r, lo_lim), hi_lim)],
                    ls="none",
                    marker=marker,
                    ms=3.2,
                    mew=0.8,
                    mec="0.55" if poor else _TERM_COLORS[k],
                    mfc="none" if poor else _TERM_COLORS[k],
                )
            handles.append(
                Line2D(
                    [],
                    [],
                    ls="none",
                    marker="o",
                    ms=3.2,
                    color=_TERM_COLORS[k],
                    label=f"{eq}, {feat}: {label}",
                )
            )
        ax_a.axhline(1.0, color="0.3", lw=0.6, ls=(0, (4, 2)))
        ax_a.set_ylim(lo_lim - 0.1, hi_lim + 0.1)
        ax_a.set_ylabel("SINDy / PEM-implied (1)")
        ax_a.set_title("(a) terms of eq. 14: SINDy against the grey box", loc="left")
        for k, (eq, feat) in enumerate(_EXTRA_TERMS):
            dx = (k - 0.5) * 0.2
            color = (COLORS["T_o"], COLORS["Q_H"])[k]
            for n, vid in enumerate(names):
                data = results[vid]
                term = _term(data, eq, feat)
                row = [t["least_squares"] for t in data["terms"] if t["equation"] == eq]
                scale = max(abs(v) for v in row) or 1.0
                poor = data["verdict"] == "data too poor to say"
                lo, hi = np.array(term["ci95"]) / scale
                ax_b.vlines(x[n] + dx, lo, hi, color=color, lw=0.7, alpha=0.4 if poor else 0.9)
                ax_b.plot(
                    [x[n] + dx],
                    [term["least_squares"] / scale],
                    ls="none",
                    marker="s",
                    ms=3.4,
                    mew=0.8,
                    mec="0.55" if poor else color,
                    mfc=color if term["kept"] and not poor else "none",
                )
            handles.append(
                Line2D(
                    [],
                    [],
                    ls="none",
                    marker="s",
                    ms=3.4,
                    color=color,
                    label=f"{eq}, {feat} (not in eq. 14; filled: kept by STLSQ)",
                )
            )
        threshold = results[names[0]]["method"]["threshold"]
        for y in (threshold, -threshold):
            ax_b.axhline(y, color="0.3", lw=0.6, ls=(0, (4, 2)))
        ax_b.axhline(0.0, color="0.6", lw=0.4)
        ax_b.set_ylabel("coefficient / largest\nin dT_veh/dt (1)")
        ax_b.set_title(
            f"(b) terms eq. 14 lacks (dashed: STLSQ threshold ±{threshold:g})", loc="left"
        )
        short = {
            "structure confirmed": "confirmed",
            "structure contradicted": "contradicted",
            "data too poor to say": "too poor",
        }
        for ax in (ax_a, ax_b):
            ax.set_xlim(-0.6, len(names) - 0.4)
            ax.grid(True, axis="y", lw=0.4, alpha=0.5)
        ax_a.set_xticks(x, names, fontsize=7)
        ax_b.set_xticks(
            x,
            [f"{vid}: {short.get(results[vid]['verdict'], '?')}" for vid in names],
            fontsize=7,
            rotation=30,
            ha="right",
            rotation_mode="anchor",
        )
        _legend_row(fig, grid[2], handles, ncols=2, handlelength=1.0)
    return _finish(fig, synthetic)


def _term(data: Mapping[str, Any], equation: str, feature: str) -> Mapping[str, Any]:
    for term in data["terms"]:
        if term["equation"] == equation and term["term"] == feature:
            return term
    raise ValueError(f"{data.get('vehicle', '?')}: no term {feature} in {equation}")


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
    with matplotlib.rc_context(_RC):
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

            lags = max(1, min(40, m // 4) if max_lag is None else int(max_lag))
            rho = autocorrelation(eps, lags)[1:]
            k = np.arange(1, rho.size + 1)
            ax_a.vlines(k, 0.0, rho, color=_INNOVATION_COLOR, lw=0.8)
            ax_a.plot(k, rho, ls="none", marker="o", ms=2.0, color=_INNOVATION_COLOR)
            if m > 0:
                for y in (z / math.sqrt(m), -z / math.sqrt(m)):
                    ax_a.axhline(y, **_BAND)
            ax_a.axhline(0.0, color="0.5", lw=0.5)
            ax_a.set_xlim(0.0, lags + 0.5)
            if m >= 3:  # the lags of the verdict's test (metrics.ljung_box's default)
                lb = ljung_box(eps)
                ax_a.text(
                    0.97,
                    0.95,
                    f"Ljung-Box p = {lb.p_value:.2g}",
                    transform=ax_a.transAxes,
                    ha="right",
                    va="top",
                    fontsize=7,
                )

            if m >= 5:
                cpg = cumulated_periodogram(eps, alpha)
                nu = np.r_[0.0, cpg.frequencies]
                lo, hi = cpg.band()
                ax_c.plot(nu, np.r_[0.0, cpg.expected], color="0.6", lw=0.5)
                ax_c.plot(nu, np.r_[0.0, lo], **_BAND)
                ax_c.plot(nu, np.r_[min(cpg.half_width, 1.0), hi], **_BAND)
                ax_c.plot(nu, np.r_[0.0, cpg.cumulated], color=_INNOVATION_COLOR, lw=0.9)
                ax_c.text(
                    0.97,
                    0.05,
                    f"KS p = {cpg.p_value:.2g}",
                    transform=ax_c.transAxes,
                    ha="right",
                    va="bottom",
                    fontsize=7,
                )
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
    fig = _finish(fig, synthetic)
    if path is not None:
        stem = Path(path)
        save_figure(fig, stem.with_suffix("") if stem.suffix in (".png", ".svg") else stem)
    return fig


# --- predictions: scenarios and the class reference model -----------------------------------


def _vehicle_colors(names: Sequence[str]) -> dict[str, Any]:
    """A colour per vehicle: tab20's ten strong colours first, its ten light ones only from
    the eleventh vehicle on (light lines are hard to read; neighbours never pair up)."""
    cmap = matplotlib.colormaps["tab20"]
    order = [*range(0, 20, 2), *range(1, 20, 2)]
    return {name: cmap(order[i % 20]) for i, name in enumerate(names)}


def scenario_figure(
    runs: Mapping[str, Any],
    *,
    title: str,
    threshold_C: float | None = None,
    synthetic: bool = False,
    note: str | None = None,
) -> Figure:
    """One scenario through every vehicle's identified model (``runs``: vehicle ->
    :class:`railtherm.study.simulate.SimulationResult`): (a) the indoor air temperature T(t) with
    its 95 % band, the heat-up threshold dashed, each line faint once it reaches the threshold
    (where a thermostat holds it, switching every few steps); (b) the heating energy since the
    start (kWh, the integral of the held power: readable where a thermostat switches)."""
    if not runs:
        raise ValueError("no simulated vehicle to draw")
    colors = _vehicle_colors(list(runs))
    with matplotlib.rc_context(_RC):
        fig = Figure(figsize=(7.0, 5.6), dpi=DPI, layout="constrained")
        FigureCanvasAgg(fig)
        ax_t, ax_p = fig.subplots(2, 1, sharex=True, height_ratios=[1.4, 1.0])
        for vid, run in runs.items():
            s = run.series
            c = colors[vid]
            T = s["T"].to_numpy()
            reached = np.flatnonzero(T >= threshold_C) if threshold_C is not None else np.array([])
            cut = int(reached[0]) + 1 if reached.size else len(T)
            ax_t.plot(s["time_h"][:cut], T[:cut], color=c, lw=1.1, label=vid)
            if cut < len(T):  # held at the set point: a thermostat's chatter, drawn faintly
                ax_t.plot(s["time_h"][cut - 1 :], T[cut - 1 :], color=c, lw=0.4, alpha=0.35)
            if "T_lo" in s:
                ax_t.fill_between(s["time_h"], s["T_lo"], s["T_hi"], color=c, alpha=0.15, lw=0)
            dt_h = float(s["time_h"].iloc[1] - s["time_h"].iloc[0])
            energy = np.r_[0.0, np.cumsum(s["heating_W"].to_numpy()[:-1]) * dt_h / 1000.0]
            ax_p.plot(s["time_h"], energy, color=c, lw=1.1)
        first = next(iter(runs.values())).series
        ax_t.plot(first["time_h"], first["T_o"], color="0.4", lw=1.0, ls=":", label="T_o")
        if threshold_C is not None:
            ax_t.axhline(threshold_C, color="0.3", lw=0.8, ls="--")
        ax_t.set_title(title, fontsize=9)
        ax_t.set_ylabel("T (°C)")
        ax_p.set_ylabel("heating energy (kWh)")
        ax_p.set_xlabel("time (h)")
        ax_t.legend(fontsize=6.5, ncols=4, loc="lower right", frameon=False)
        for ax in (ax_t, ax_p):
            ax.grid(True, lw=0.3, alpha=0.5)
    return _finish(fig, synthetic, note)


def reference_validation_figure(
    table: pd.DataFrame, *, synthetic: bool = False, note: str | None = None
) -> Figure:
    """The leave-one-out validation of the class reference model (``table``: rows of
    :func:`railtherm.study.classvalidation.leave_one_out`): (a) the heat-up time predicted from the
    other vehicles (with its 95 % prediction band) against the vehicle's own identified
    model's, the 1:1 line, a band open above drawn to the axis top with an arrow; (b) the
    RMSE of T over the vehicle's identification windows: its own fit and the reference models
    (class and pooled)."""
    with matplotlib.rc_context(_RC):
        fig = Figure(figsize=(7.0, 3.6), dpi=DPI, layout="constrained")
        FigureCanvasAgg(fig)
        ax_a, ax_b = fig.subplots(1, 2, width_ratios=[1.0, 1.3])
        done = table[table["status"] == "predicted"]
        styles = {
            ("class", "class"): dict(marker="o", mfc=None, label="class, k from class"),
            ("class", "measured"): dict(marker="s", mfc="white", label="class, k measured"),
            ("pooled", "class"): dict(marker="^", mfc=None, label="pooled, k from class"),
            ("pooled", "measured"): dict(marker="v", mfc="white", label="pooled, k measured"),
        }
        colors = _vehicle_colors(sorted(done["vehicle"].unique()))
        finite = done[["heat_up_fit_h", "heat_up_ref_h", "heat_up_ref_h_lo"]].astype(float)
        finite = finite.to_numpy()[np.isfinite(finite.to_numpy())]
        top = 1.25 * float(finite.max()) if finite.size else 1.0
        named: dict[str, tuple[float, float, Any]] = {}  # vehicle: where its name goes
        for (basis, k_from), style in styles.items():
            part = done[(done["basis"] == basis) & (done["k_from"] == k_from)]
            part = part[np.isfinite(part["heat_up_fit_h"].astype(float))]
            for _, r in part.iterrows():
                x = float(r["heat_up_fit_h"])
                y, lo, hi = (
                    float(r[c]) for c in ("heat_up_ref_h", "heat_up_ref_h_lo", "heat_up_ref_h_hi")
                )
                c = colors[r["vehicle"]]
                # the band: to the axis top with an arrow where it is open above (none where
                # the model rests on too few vehicles: lo and hi NaN)
                ax_a.plot([x, x], [lo, min(hi, top)], color=c, lw=0.6, alpha=0.6)
                if math.isinf(hi):
                    ax_a.plot(x, top, marker="^", color=c, ms=3, alpha=0.6)
                if math.isfinite(y):
                    ax_a.plot(
                        x,
                        y,
                        marker=style["marker"],
                        ms=4.5,
                        color=c,
                        mfc=style["mfc"] or c,
                        ls="none",
                    )
                if r["vehicle"] not in named:
                    named[r["vehicle"]] = (x, lo if math.isfinite(lo) else min(y, top), c)
            ax_a.plot(
                [],
                [],
                color="0.3",
                marker=style["marker"],
                ls="none",
                mfc=style["mfc"] or "0.3",
                label=style["label"],
            )
        placed: list[tuple[float, float, int]] = []  # anchor and line of each name
        width = 0.09 * top  # a name of six letters, in hours of the x axis
        for vid, (x, y, c) in sorted(named.items(), key=lambda kv: (kv[1][0], kv[1][1])):
            # the first line below its anchor that no name nearby takes yet
            taken = {
                line for px, py, line in placed if abs(px - x) < width and abs(py - y) < 0.1 * top
            }
            line = next(i for i in range(len(placed) + 1) if i not in taken)
            ax_a.annotate(
                vid,
                (x, y),
                xytext=(2, -8 - 7 * line),
                textcoords="offset points",
                fontsize=5.5,
                color=c,
            )
            placed.append((x, y, line))
        ax_a.plot([0, top], [0, top], color="0.5", lw=0.8, ls="--")
        ax_a.set_xlim(0, top)
        ax_a.set_ylim(0, top * 1.03)
        ax_a.set_xlabel("heat-up time, own fit (h)")
        ax_a.set_ylabel("heat-up time, reference model (h)")
        ax_a.set_title("(a) heat-up time, leave-one-out", fontsize=9)
        ax_a.legend(fontsize=6, loc="upper left", frameon=False)
        rmse = done[done["k_from"] == "class"]
        vehicles = list(dict.fromkeys(rmse["vehicle"]))
        x = np.arange(len(vehicles), dtype=float)
        bars = [
            ("fit", "rmse_fit_K", "0.35"),
            ("class", "rmse_ref_K", "#2471a3"),
            ("pooled", "rmse_ref_K", "#d68910"),
        ]
        width = 0.26
        for i, (label, column, color) in enumerate(bars):
            if label == "fit":
                vals = [float(rmse[rmse["vehicle"] == v][column].iloc[0]) for v in vehicles]
            else:
                vals = [
                    float(rmse[(rmse["vehicle"] == v) & (rmse["basis"] == label)][column].iloc[0])
                    if ((rmse["vehicle"] == v) & (rmse["basis"] == label)).any()
                    else math.nan
                    for v in vehicles
                ]
            name = "own fit" if label == "fit" else f"reference ({label})"
            ax_b.bar(x + (i - 1) * width, vals, width, color=color, label=name)
        ax_b.set_xticks(x, vehicles, rotation=45, ha="right", fontsize=7)
        ax_b.set_yscale("log")
        ax_b.set_ylabel("RMSE of T over the windows (K), log scale")
        ax_b.set_title("(b) prediction of the measured windows", fontsize=9)
        ax_b.legend(fontsize=6, frameon=False)
        for ax in (ax_a, ax_b):
            ax.grid(True, lw=0.3, alpha=0.5)
    return _finish(fig, synthetic, note)


def design_figure(table: pd.DataFrame, *, note: str | None = None) -> Figure:
    """The design table (rows of :func:`railtherm.study.designstudy.vehicle_rows`): per
    parameter, each vehicle's realised relative 95 % half-width (bar), the one predicted from
    its fit (cross) and the one predicted before the tunnel from its class reference model
    (circle, with the 5-95 % range over the model's draws); not identified: no bar."""
    parameters = list(dict.fromkeys(table["parameter"]))
    vehicles = list(dict.fromkeys(table["vehicle"]))
    x = np.arange(len(vehicles))
    with matplotlib.rc_context(_RC):
        fig = Figure(figsize=(7.0, 2.4 * len(parameters)), dpi=DPI, layout="constrained")
        FigureCanvasAgg(fig)
        axes = np.atleast_1d(fig.subplots(len(parameters), 1, sharex=True))
        for ax, p in zip(axes, parameters, strict=True):
            part = table[table["parameter"] == p].set_index("vehicle").reindex(vehicles)
            pct = {
                c: 100 * part[c].astype(float).to_numpy()
                for c in part.columns
                if c in ("realised", "predicted", "class_median", "class_q05", "class_q95")
            }
            ax.bar(x, pct["realised"], 0.6, color="0.75", label="realised (its fit)")
            ax.plot(x, pct["predicted"], "x", color="C3", ms=6, label="predicted from its fit")
            # the class range drawn up to the axis top, an arrow where it goes beyond
            top = 1000.0
            for xi, q05, q95 in zip(x + 0.2, pct["class_q05"], pct["class_q95"], strict=True):
                if np.isfinite(q05):
                    ax.plot([xi, xi], [q05, min(q95, top)], color="C0", lw=0.8)
                    if not q95 <= top:
                        ax.plot(xi, top, marker="^", color="C0", ms=4)
            ax.plot(
                x + 0.2,
                pct["class_median"],
                "o",
                color="C0",
                ms=4,
                label="before the tunnel (class model, 5-95 %)",
            )
            ax.set_yscale("log")
            ax.set_ylim(0.5, 1.5 * top)
            ax.set_ylabel(f"{p}: ± (95 %), %", fontsize=8)
            ax.grid(True, lw=0.3, alpha=0.5)
        handles, labels = axes[0].get_legend_handles_labels()
        fig.legend(handles, labels, fontsize=7, frameon=False, ncols=3, loc="outside upper center")
        axes[-1].set_xticks(x, vehicles, rotation=45, ha="right", fontsize=7)
    return _finish(fig, False, note)


def annual_energy_figure(table: pd.DataFrame, *, note: str | None = None) -> Figure:
    """The study's annual energy (rows of :func:`railtherm.study.energy.study_rows`): per
    climate, each vehicle's monthly heating energy of the base variant as bars with their
    95 % bands."""
    totals = ("energy", "preheat", "difference")
    months = [  # the month columns, in the table's order
        c.removesuffix("_kWh")
        for c in table.columns
        if c.endswith("_kWh") and c.removesuffix("_kWh") not in totals
    ]
    base = table[table["variant"] == "base"]
    climates = list(dict.fromkeys(base["climate"]))
    vehicles = list(dict.fromkeys(base["vehicle"]))
    colors = _vehicle_colors(vehicles)
    x = np.arange(len(months))
    width = 0.8 / max(len(vehicles), 1)
    with matplotlib.rc_context(_RC):
        fig = Figure(figsize=(7.0, 2.6 * max(len(climates), 1)), dpi=DPI, layout="constrained")
        FigureCanvasAgg(fig)
        axes = np.atleast_1d(fig.subplots(max(len(climates), 1), 1, sharex=True))
        for ax, climate in zip(axes, climates, strict=False):
            part = base[base["climate"] == climate]
            for i, vid in enumerate(vehicles):
                r = part[part["vehicle"] == vid]
                if r.empty:
                    continue
                r = r.iloc[0]
                c = np.array([r[f"{m}_kWh"] for m in months], dtype=float) / 1000.0
                lo = np.array([r[f"{m}_lo"] for m in months], dtype=float) / 1000.0
                hi = np.array([r[f"{m}_hi"] for m in months], dtype=float) / 1000.0
                err = None if np.isnan(lo).all() else [c - lo, hi - c]
                ax.bar(
                    x + (i - (len(vehicles) - 1) / 2) * width,
                    c,
                    width,
                    yerr=err,
                    color=colors[vid],
                    error_kw={"lw": 0.6, "capsize": 0},
                    label=vid,
                )
            ax.set_ylabel("heating (MWh)", fontsize=8)
            ax.set_title(climate, fontsize=9)
            ax.grid(True, axis="y", lw=0.3, alpha=0.5)
        axes[-1].set_xticks(x, months, fontsize=7)
        if base.empty:  # no vehicle with an acceptable fit: the figure says so
            axes[0].text(
                0.5,
                0.5,
                "no vehicle with an acceptable second-order fit",
                ha="center",
                va="center",
                transform=axes[0].transAxes,
                fontsize=8,
            )
            return _finish(fig, False, note)
        handles, labels = axes[0].get_legend_handles_labels()
        fig.legend(
            handles,
            labels,
            fontsize=7,
            frameon=False,
            ncols=min(len(labels), 7),
            loc="outside upper center",
        )
    return _finish(fig, False, note)


# ---------------------------------------------------------------------------------------------
# Every figure of one vehicle (rule vehicle_figures)


def vehicle_figures(
    vehicle: str,
    *,
    kvalue: Mapping[str, str] | None = None,
    fits: Mapping[str, Mapping[str, str]] | None = None,
    synthetic: bool = False,
) -> list[str]:
    """Draw every figure of one vehicle from its result files, as PNG and SVG: the record with
    the k window and the k-test verdict (:func:`kvalue_figure`), and per fit the measured vs
    simulated temperatures (:func:`fit_figure`) and, for a Kalman-filter fit, its one-step
    innovations (:func:`innovation_figure`).

    ``kvalue``: the files ``record`` and ``window`` (tidy tables), ``result`` (kvalue.yaml) and
    ``png`` (the figure's PNG path; the SVG beside it), or None. ``fits``: per model key the
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
    for files in (fits or {}).values():
        fit = rt_io.read_result(files["fit"])
        series = pd.read_csv(files["series"])
        fit_synthetic = bool(fit.get("synthetic", False))
        model = structures.of_fit(fit["structure"]).title
        if fit.get("estimator") == "kalman":
            model += ", Kalman-filter estimator"
        figure = fit_figure(series, fit, f"{fit['vehicle']}: {model}", synthetic=fit_synthetic)
        save_figure(figure, files["png"].removesuffix(".png"))
        drawn.append(f"fit figure of {fit['vehicle']}, {fit['structure']}")
        if "innovations_png" in files:
            names = list(fit["outputs"])
            innovation_figure(
                series["time"].to_numpy(float),
                series[[f"{s}_innovation" for s in names]].to_numpy(float),
                series[[f"{s}_innovation_sd" for s in names]].to_numpy(float),
                title=f"{fit['vehicle']}: {fit['structure']}, Kalman-filter estimator",
                path=files["innovations_png"],
                names=names,
                synthetic=fit_synthetic,
            )
            drawn.append(f"innovation figure of {fit['vehicle']}, {fit['structure']}")
    return drawn
