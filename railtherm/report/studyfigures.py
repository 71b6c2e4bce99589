"""The study's figures (paper section 6 and what is built on the fits): :func:`figure3` (Tram2,
first- vs second-order model), :func:`figure4` (measured vs simulated T for a few metros),
:func:`figure5` (c_veh and delta by vehicle class), the SINDy cross-check
(:func:`sindy_figure`), predictions (:func:`scenario_figure`,
:func:`reference_validation_figure`), the test plan (:func:`design_figure`) and annual energy
(:func:`annual_energy_figure`); deterministic byte for byte as every figure
(:mod:`railtherm.report.figurebase`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import matplotlib
import numpy as np
import pandas as pd
from matplotlib import transforms
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from railtherm.estimation import pem
from railtherm.report.figurebase import (
    COLORS,
    DPI,
    FIGSIZE_FIG5_IN,
    FIGSIZE_IN,
    MEASURED,
    MODEL_LABELS,
    MODEL_STYLES,
    OPEN,
    OPEN_ARROW,
    OPEN_BAND,
    POINT,
    RC,
    draw_time_axis,
    finish_figure,
    inputs_panel,
    lay_windows,
    legend_row,
)
from railtherm.study import aggregate
from railtherm.study.quality import ACCEPTABLE, IN_DOUBT


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
    lay = lay_windows(series2)
    if not {"window", "time"} <= set(series1) or not _same_windows(series1, series2):
        raise ValueError("figure3: the two series must cover the same windows and times")
    with matplotlib.rc_context(RC):
        fig = Figure(figsize=FIGSIZE_IN, dpi=DPI, layout="constrained")
        FigureCanvasAgg(fig)
        grid = fig.add_gridspec(3, 1, height_ratios=[3.0, 1.0, 0.3])
        ax = fig.add_subplot(grid[0])
        axi = fig.add_subplot(grid[1], sharex=ax)
        lines = ax.plot(
            lay.x, lay.values(series2, "T"), color=COLORS["T"], label="measured T", **MEASURED
        )
        for order, series in ((1, series1), (2, series2)):
            lines += ax.plot(
                lay.x, lay.values(series, "T_sim"), label=MODEL_LABELS[order], **MODEL_STYLES[order]
            )
        ax.set_ylabel("T, indoor air (°C)")
        ax.set_title(title, loc="left")
        lines += inputs_panel(axi, series2, lay)
        draw_time_axis([ax, axi], lay)
        legend_row(fig, grid[2], lines, ncols=3)
    return finish_figure(fig, synthetic)


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
    layouts = {name: lay_windows(s) for name, s in series.items()}
    with matplotlib.rc_context(RC):
        fig = Figure(figsize=FIGSIZE_IN, dpi=DPI, layout="constrained")
        FigureCanvasAgg(fig)
        grid = fig.add_gridspec(len(series) + 1, 1, height_ratios=[1.0] * len(series) + [0.1])
        axes = [fig.add_subplot(grid[i]) for i in range(len(series))]
        lines: list[Any] = []
        for ax, (name, s) in zip(axes, series.items(), strict=True):
            lay = layouts[name]
            measured = ax.plot(
                lay.x, lay.values(s, "T"), color=COLORS["T"], label="measured T", **MEASURED
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
            draw_time_axis([ax], lay, names=len(lay.spans) > 1)
        fig.suptitle(title, x=0.01, ha="left", fontsize=10)
        legend_row(fig, grid[-1], lines, ncols=2)
    return finish_figure(fig, synthetic)


def _spread(n: int, half_width: float = 0.22) -> np.ndarray:
    """Deterministic horizontal offsets of n points inside a box, evenly spread."""
    return np.linspace(-half_width, half_width, n) if n > 1 else np.zeros(n)


def _name_label(ax, name: str, xy, h: float, name_at, moved: bool, vid: str) -> None:
    """A point's name beside it at height ``h`` (axes fraction, :func:`_declutter`); a name
    ``moved`` off its point's height gets a leader line to the point ``xy``."""
    style = {
        "ha": "left",
        "va": "center",
        "fontsize": 5.5,
        "color": "0.2",
        "zorder": 4,
        # a faint white ground keeps the name legible over bars and box lines
        "bbox": {"boxstyle": "square,pad=0.1", "fc": "white", "ec": "none", "alpha": 0.7},
    }
    if not moved:
        ax.text(xy[0], h, name, transform=name_at, **style)
        return
    leader = {"arrowstyle": "-", "color": "0.55", "lw": 0.4, "shrinkA": 0, "shrinkB": 2.5}
    label = ax.annotate(
        name, xy=xy, xycoords="data", xytext=(xy[0], h), textcoords=name_at,
        arrowprops=leader, **style,
    )  # fmt: skip
    label.set_gid(f"label-{vid}")


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
    with matplotlib.rc_context(RC):
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
    with matplotlib.rc_context(RC):
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
                    (point,) = ax.plot([x], [y], ls="none", zorder=5, **POINT[doubt])
                else:
                    kind = str(kinds[in_class].iloc[i])
                    open_kinds.add("limit" if kind in ("upper", "lower") else "none")
                    lim = float(limits[in_class].iloc[i])
                    point, name = _not_identified(ax, x, y, kind, lim, ylim, name)
                vid = str(row["vehicle"])
                point.set_gid(f"vehicle-{vid}")
                _name_label(ax, name, (x, y), h, name_at, abs(h - frac(y)) > 0.25 * sep, vid)
        positions = list(range(1, len(classes) + 1))
        _boxes(ax, positions, boxes)
        ax.set_xticks(positions, labels)
        ax.set_xlim(0.45, len(classes) + 0.75)
        ax.set_ylabel(ylabel)
        ax.set_title(title, loc="left")
        ax.grid(True, axis="y", lw=0.4, alpha=0.5)
        handles = _class_legend(table3.loc[ok, "verdict"].astype(str), open_kinds, skipped)
        legend_row(fig, grid[1], handles, ncols=1 if skipped else 2, handlelength=1.2)
    return fig


def _not_identified(ax: Any, x: float, y: float, kind: str, lim: float, ylim, name: str):
    """A value the data do not determine (:func:`_class_figure`): an open triangle at its
    one-sided limit with an arrow to the axis edge, or a dotted line over the axis where the
    data give no limit. Returns the point and the name with its limit."""
    if kind in ("upper", "lower"):
        edge = ylim[1] if kind == "lower" else ylim[0]
        ax.annotate("", xy=(x, edge), xytext=(x, y), arrowprops={**OPEN_ARROW}, zorder=3)
        marker = OPEN[kind]
        name += f" ({'≥' if kind == 'lower' else '≤'} {lim:.3g})"
    else:
        ax.vlines(x, *ylim, zorder=2, **OPEN_BAND)
        marker = OPEN["none"]
    (point,) = ax.plot([x], [y], ls="none", zorder=5, **marker)
    return point, name


def _boxes(ax: Any, positions: list[int], boxes: list[np.ndarray]) -> None:
    """A box per class of at least BOX_MIN values (:func:`_class_figure`)."""
    grey = {"color": "0.35", "lw": 0.8}
    # a box of fewer than BOX_MIN values would draw quartiles that are not there
    boxed = [(pos, box) for pos, box in zip(positions, boxes, strict=True) if box.size >= BOX_MIN]
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


def _class_legend(verdicts: pd.Series, open_kinds: set[str], skipped: str | None) -> list:
    """The legend of :func:`_class_figure`: the verdicts shown, the interval, the values not
    identified and those not given."""
    handles = [
        Line2D([], [], ls="none", label=label, **POINT[doubt])
        for doubt, label in ((False, ACCEPTABLE), (True, IN_DOUBT))
        if ((verdicts == IN_DOUBT) == doubt).any()
    ]
    bar = {"marker": "|", "ms": 9, "mew": 0.6, "color": COLORS["T_veh"]}
    handles.append(Line2D([], [], ls="none", label="95 % interval", **bar))
    if "limit" in open_kinds:
        handles.append(Line2D([], [], ls="none", label="not identified: limit", **OPEN["lower"]))
    if "none" in open_kinds:  # no limit the data give: anywhere on the axis
        handles.append(Line2D([], [], ls="none", label="not identified", **OPEN["none"]))
    if skipped:  # its own line: the names may be long
        handles.append(Line2D([], [], ls="none", label=f"not shown: {skipped}"))
    return handles


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
    return finish_figure(a, synthetic, note), finish_figure(b, synthetic, note)


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


def sindy_figure(
    results: Mapping[str, Mapping[str, Any]],
    *,
    synthetic: bool = False,
    note: str | None = None,
) -> Figure:
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
    with matplotlib.rc_context(RC):
        fig = Figure(figsize=(7.0, 5.2), dpi=DPI, layout="constrained")
        FigureCanvasAgg(fig)
        grid = fig.add_gridspec(3, 1, height_ratios=[1.0, 0.8, 0.13])
        ax_a, ax_b = fig.add_subplot(grid[0]), fig.add_subplot(grid[1])
        x = np.arange(len(names), dtype=float)
        handles = _eq14_terms(ax_a, results, names, x)
        handles += _extra_terms(ax_b, results, names, x)
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
        legend_row(fig, grid[2], handles, ncols=2, handlelength=1.0)
    return finish_figure(fig, synthetic, note)


def _eq14_terms(ax: Any, results: Mapping[str, Mapping[str, Any]], names, x) -> list[Line2D]:
    """Panel (a) of :func:`sindy_figure`: each term of eq. 14, SINDy over the grey box."""
    handles = []
    lo_lim, hi_lim = _RATIO_LIMITS
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
            ax.vlines(
                x[n] + dx,
                max(lo, lo_lim),
                min(hi, hi_lim),
                color=_TERM_COLORS[k],
                lw=0.7,
                alpha=0.4 if poor else 0.9,
            )
            clipped = r < lo_lim or r > hi_lim
            marker = ("v" if r < lo_lim else "^") if clipped else "o"
            ax.plot(
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
    ax.axhline(1.0, color="0.3", lw=0.6, ls=(0, (4, 2)))
    ax.set_ylim(lo_lim - 0.1, hi_lim + 0.1)
    ax.set_ylabel("SINDy / PEM-implied (1)")
    ax.set_title("(a) terms of eq. 14: SINDy against the grey box", loc="left")
    return handles


def _extra_terms(ax: Any, results: Mapping[str, Mapping[str, Any]], names, x) -> list[Line2D]:
    """Panel (b) of :func:`sindy_figure`: the terms eq. 14 lacks, over the equation's largest."""
    handles = []
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
            ax.vlines(x[n] + dx, lo, hi, color=color, lw=0.7, alpha=0.4 if poor else 0.9)
            ax.plot(
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
        ax.axhline(y, color="0.3", lw=0.6, ls=(0, (4, 2)))
    ax.axhline(0.0, color="0.6", lw=0.4)
    ax.set_ylabel("coefficient / largest\nin dT_veh/dt (1)")
    ax.set_title(f"(b) terms eq. 14 lacks (dashed: STLSQ threshold ±{threshold:g})", loc="left")
    return handles


def _term(data: Mapping[str, Any], equation: str, feature: str) -> Mapping[str, Any]:
    for term in data["terms"]:
        if term["equation"] == equation and term["term"] == feature:
            return term
    raise ValueError(f"{data.get('vehicle', '?')}: no term {feature} in {equation}")


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
    with matplotlib.rc_context(RC):
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
    return finish_figure(fig, synthetic, note)


def reference_validation_figure(
    table: pd.DataFrame, *, synthetic: bool = False, note: str | None = None
) -> Figure:
    """The leave-one-out validation of the class reference model (``table``: rows of
    :func:`railtherm.study.classvalidation.leave_one_out`): (a) the heat-up time predicted from the
    other vehicles (with its 95 % prediction band) against the vehicle's own identified
    model's, the 1:1 line, a band open above drawn to the axis top with an arrow; (b) the
    RMSE of T over the vehicle's identification windows: its own fit and the reference models
    (class and pooled)."""
    with matplotlib.rc_context(RC):
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
    return finish_figure(fig, synthetic, note)


def design_figure(table: pd.DataFrame, *, note: str | None = None) -> Figure:
    """The design table (rows of :func:`railtherm.study.designstudy.vehicle_rows`): per
    parameter, each vehicle's realised relative 95 % half-width (bar), the one predicted from
    its fit (cross) and the one predicted before the tunnel from its class reference model
    (circle, with the 5-95 % range over the model's draws); not identified: no bar."""
    parameters = list(dict.fromkeys(table["parameter"]))
    vehicles = list(dict.fromkeys(table["vehicle"]))
    x = np.arange(len(vehicles))
    with matplotlib.rc_context(RC):
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
    return finish_figure(fig, False, note)


def annual_energy_figure(table: pd.DataFrame, *, note: str | None = None) -> Figure:
    """The study's annual energy (rows of :func:`railtherm.study.energy.study_rows`): per
    climate, each vehicle's monthly heating energy of the base variant as bars with their
    95 % bands."""
    months = [  # the month columns (Jan_kWh with Jan_lo, Jan_hi), in the table's order
        c.removesuffix("_kWh")
        for c in table.columns
        if c.endswith("_kWh") and f"{c.removesuffix('_kWh')}_lo" in table.columns
    ]
    base = table[table["variant"] == "base"]
    climates = list(dict.fromkeys(base["climate"]))
    vehicles = list(dict.fromkeys(base["vehicle"]))
    colors = _vehicle_colors(vehicles)
    x = np.arange(len(months))
    width = 0.8 / max(len(vehicles), 1)
    with matplotlib.rc_context(RC):
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
                at = x + (i - (len(vehicles) - 1) / 2) * width
                ax.bar(at, c, width, color=colors[vid], label=vid)
                if not np.isnan(lo).all():  # the band as drawn, wherever the central bar ends
                    ax.vlines(at, lo, hi, colors="0.15", lw=0.6)
            ax.set_ylabel("heating (MWh)", fontsize=8)
            ax.set_title(climate, fontsize=9)
            ax.grid(True, axis="y", lw=0.3, alpha=0.5)
        axes[-1].set_xticks(x, months, fontsize=7)
        if base.empty:  # no vehicle with an acceptable fit: the figure says so
            axes[0].text(
                0.5,
                0.5,
                "no vehicle with an acceptable fit",
                ha="center",
                va="center",
                transform=axes[0].transAxes,
                fontsize=8,
            )
            return finish_figure(fig, False, note)
        handles, labels = axes[0].get_legend_handles_labels()
        fig.legend(
            handles,
            labels,
            fontsize=7,
            frameon=False,
            ncols=min(len(labels), 7),
            loc="outside upper center",
        )
    return finish_figure(fig, False, note)
