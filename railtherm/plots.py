"""Diagnostic figures, deterministic byte for byte (Agg canvas, fixed SVG hash salt, no dates).

Figures are built on :class:`matplotlib.figure.Figure` with an Agg canvas, never through
``pyplot``, so nothing depends on a global figure manager or an interactive backend.

Time axis of :func:`kvalue_figure`: hours from the start of the record (the first row of the
whole-file tidy table). The k window is placed on it either by ``offset_s`` (seconds from the
record start to the window start) or, by default, by finding the window's first ``timestamp``
among the record's ``timestamp`` values (ISO text is compared as time, seconds as numbers).
"""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib
import numpy as np
import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from railtherm.kvalue import KValue

__all__ = ["kvalue_figure", "save_figure", "window_offset_s"]

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
) -> Figure:
    """T, T_veh, T_o (left axis, degC) and Q_H (right axis, kW) over the whole record with the
    k window shaded and a box with k +- u(k) and the steady-state verdict.

    ``record`` and ``window`` are tidy tables (the whole file and the k window);
    ``offset_s`` places the window on the record's time axis (default: from ``timestamp``)."""
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
    return fig


def _verdict_text(r: KValue) -> str:
    lines = [
        f"k = {r.k:.3f} ± {r.u_k:.3f} W/(m² K)  (u, {100 * r.u_k_rel:.1f} %)",
        f"kA = {r.kA:.0f} W/K,  ΔT = {r.delta_T:.1f} K,  Q_H = {r.Q_H_mean / 1000:.2f} kW",
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
