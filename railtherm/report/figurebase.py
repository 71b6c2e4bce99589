"""Shared by every figure: sizes, resolution, colours and line styles, the footer that marks
synthetic data, and the byte-deterministic save (Agg canvas, fixed SVG hash salt, no dates; the
constrained layout settled once so that every save reuses it), and the time axis that lays
a record's identification windows side by side.

Figures are built on :class:`matplotlib.figure.Figure` with an Agg canvas, never through
``pyplot``, so nothing depends on a global figure manager or an interactive backend.
"""

from __future__ import annotations

import os
import textwrap
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import matplotlib
import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.layout_engine import ConstrainedLayoutEngine, PlaceHolderLayoutEngine
from matplotlib.text import Text

FIGSIZE_IN = (7.0, 4.8)  # fits a paper column pair / A4 page width with margins
DPI = 200
SVG_HASHSALT = "railtherm"
# no creation date, no software version in the files: bytes depend only on the content
PNG_METADATA = {"Software": None}
SVG_METADATA = {"Date": None, "Creator": None}
RC = {
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
MEASURED = {"lw": 1.6, "alpha": 0.55}
SIMULATED = {"ls": (0, (4, 2)), "lw": 0.9}
SIM_COLORS = {"T": "#641e16", "T_veh": "#4a235a"}
_SEPARATOR = {"color": "0.45", "lw": 0.6, "zorder": 0.5}
# Figure 5 points: filled circle, or hollow square for "assumptions in doubt"
POINT = {
    False: {"marker": "o", "ms": 3.8, "mew": 0.9, "mec": COLORS["T_veh"], "mfc": COLORS["T_veh"]},
    True: {"marker": "s", "ms": 3.6, "mew": 0.9, "mec": COLORS["T_veh"], "mfc": "none"},
}
# Figure 5, a value the data do not determine: an open triangle at its one-sided limit (up:
# at least, down: at most) with an arrow to the axis edge, or a dotted line over the axis
OPEN = {
    kind: {"marker": m, "ms": 4.2, "mew": 0.9, "mec": "0.35", "mfc": "white"}
    for kind, m in (("lower", "^"), ("upper", "v"), ("none", "D"))
}
OPEN_ARROW = {"arrowstyle": "->", "color": "0.45", "lw": 0.7, "shrinkA": 3, "shrinkB": 0}
OPEN_BAND = {"color": "0.55", "lw": 0.7, "ls": (0, (1, 1.5))}
_TIME_LABEL = "time since window start (h)"
_MAX_TICKS = 12.0  # at most about this many time ticks over the whole axis
_HOUR_STEPS = (0.25, 0.5, 1.0, 2.0, 3.0, 4.0, 6.0, 12.0, 24.0, 48.0, 72.0, 168.0)


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
    A note longer than the figure is wide is wrapped onto as many lines as it takes.
    Returns the text."""
    size = 6.5
    # wrapped to the figure's width (an italic character is at most about 0.55 em wide), the
    # strip as high as its lines
    per_line = max(20, int(0.98 * fig.get_figwidth() * 72.0 / (0.55 * size)))
    text = "\n".join(textwrap.wrap(text, per_line, break_on_hyphens=False)) or text
    lines = text.count("\n") + 1
    strip = min(0.45, (1.25 * lines + 0.65) * size / 72.0 / fig.get_figheight())
    engine = fig.get_layout_engine()
    # a placeholder that replaced a constrained layout (adjust_compatible False): ours, settled
    settled = isinstance(engine, PlaceHolderLayoutEngine) and not engine.adjust_compatible
    if settled:
        engine = ConstrainedLayoutEngine()  # the defaults, as layout="constrained" gives
        fig.set_layout_engine(engine)
    if isinstance(engine, ConstrainedLayoutEngine):
        engine.set(rect=(0.0, strip, 1.0, 1.0 - strip))
    with matplotlib.rc_context(RC):
        note = fig.text(
            0.995,
            0.475 * size / 72.0 / fig.get_figheight(),
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
    would come out slightly different. Laying out (the layout engine alone, which costs half of
    a draw without rendering and gives the same positions) until no axes edge moves
    by more than ``tol_px`` pixels at the figure's resolution (the passes converge
    geometrically: 2 or 3 passes to half a pixel) and then swapping the engine for a
    placeholder makes every later draw, PNG or SVG, first save or second, use the very same
    layout: :func:`save_figure` stays byte for byte."""
    tol = tol_px / (fig.dpi * float(max(fig.get_size_inches())))  # in figure fractions
    with matplotlib.rc_context(RC):
        before = None
        engine = fig.get_layout_engine()
        for _ in range(passes):
            if engine is not None:
                engine.execute(fig)  # the layout alone: a draw would also lay out every artist
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


def finish_figure(fig: Figure, synthetic: bool, note: str | None = None) -> Figure:
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
    measured = ", ".join(dict.fromkeys(table.loc[~synthetic, "vehicle"].astype(str)))
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


def lay_windows(series: pd.DataFrame) -> _Windows:
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


def draw_time_axis(axes: Sequence[Any], lay: _Windows, *, names: bool = True) -> None:
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


def legend_row(
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


def has_data(v: np.ndarray) -> bool:
    return bool(np.isfinite(v).any())


T_O_MIN_SPAN_K = 10.0  # the T_o axis spans at least this: a steady tunnel's noise stays small


def inputs_panel(ax: Any, series: pd.DataFrame, lay: _Windows, tunnel: bool = True) -> list[Any]:
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
    if has_data(t_o):  # a steady tunnel's sensor noise must not fill the panel over Q_H
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
    if has_data(q):
        low, high = min(0.0, float(np.nanmin(q))), float(np.nanmax(q))
        axq.set_ylim(low, high + 0.1 * (high - low) if high > low else low + 1.0)
    ax.set_zorder(axq.get_zorder() + 1)  # the temperature over the power trace
    ax.patch.set_visible(False)
    return lines
