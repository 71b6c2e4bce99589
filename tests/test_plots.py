"""railtherm.report.plots: the k-window figure renders, is not blank and is byte-deterministic."""

import io
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from matplotlib.image import imread

from railtherm import io as rt_io
from railtherm.config import section_defaults
from railtherm.estimation import kvalue
from railtherm.records import FitRecord
from railtherm.report import plots

SETTINGS = section_defaults("kvalue")  # the schema defaults
INSTRUMENTS = {"temperature_u_K": 0.1, "power_u_rel": 0.01, "surface_u_rel": 0.0}


def record(iso=True):
    """A 30 h record at 5 min: heat-up, a steady hold from 16 h to 24 h, cool-down."""
    t = np.arange(0.0, 30 * 3600.0 + 1, 300.0)
    h = t / 3600.0
    T = np.where(h < 24, 20 - 30 * np.exp(-h / 4), 20 - 30 * (1 - np.exp(-(h - 24) / 4)))
    T_veh = np.where(h < 24, 19.5 - 29.5 * np.exp(-h / 8), 19.5 - 29 * (1 - np.exp(-(h - 24) / 8)))
    Q = np.where(h < 24, 24_000.0 + 1000.0 * np.sin(h * 7.0), 1000.0)
    stamps = (pd.Timestamp("2024-01-16T02:00:00") + pd.to_timedelta(t, unit="s")).strftime(
        "%Y-%m-%dT%H:%M:%S"
    )
    return pd.DataFrame(
        {
            "time": t,
            "timestamp": list(stamps) if iso else t + 500.0,
            "T": T,
            "T_veh": T_veh,
            "T_o": np.full(t.size, -10.0),
            "Q_H": Q,
        }
    )


def k_window(rec):
    w = rec[(rec["time"] >= 16 * 3600) & (rec["time"] <= 24 * 3600)].copy()
    w["time"] -= w["time"].iloc[0]
    return w.reset_index(drop=True)


def figure(iso=True, **kwargs):
    rec = record(iso)
    win = k_window(rec)
    result = kvalue.static_k(win, 400.0, 4e4, SETTINGS, INSTRUMENTS, {"indoor": 4, "outdoor": 2})
    return plots.kvalue_figure(rec, win, result, "Test vehicle: static k (eq. 10)", **kwargs)


def test_window_offset_from_iso_and_seconds_timestamps():
    for iso in (True, False):
        rec = record(iso)
        assert plots.window_offset_s(rec, k_window(rec)) == pytest.approx(16 * 3600.0)


def test_figure_renders_to_a_png_of_the_expected_size_and_is_not_blank(tmp_path):
    png, svg = plots.save_figure(figure(), tmp_path / "Tram9.kvalue")
    assert png.name == "Tram9.kvalue.png" and svg.name == "Tram9.kvalue.svg"
    image = imread(png)
    w_in, h_in = plots.FIGSIZE_IN
    assert image.shape[:2] == (round(h_in * plots.DPI), round(w_in * plots.DPI))
    assert image[..., :3].std() > 0.05  # not a blank canvas
    assert svg.read_text(encoding="utf-8").lstrip().startswith("<?xml")


def test_two_renders_are_byte_identical(tmp_path):
    a = plots.save_figure(figure(), tmp_path / "a")
    b = plots.save_figure(figure(), tmp_path / "b")
    for x, y in zip(a, b, strict=True):
        assert x.read_bytes() == y.read_bytes()


def test_explicit_offset_places_the_window_like_the_timestamps():
    """Axis text aside, the shaded span must land on the same place either way."""

    def span(fig):
        buf = io.BytesIO()
        fig.savefig(buf, format="png")
        return buf.getvalue()

    assert span(figure(iso=False)) == span(figure(iso=False, offset_s=16 * 3600.0))
    assert span(figure(iso=True)) != span(figure(iso=True, offset_s=10 * 3600.0))


def test_verdict_box_names_the_failed_tests():
    rec = record()
    win = k_window(rec).iloc[:37]  # 3 h
    result = kvalue.static_k(win, 400.0, 4e4, SETTINGS, INSTRUMENTS, {"indoor": 4, "outdoor": 2})
    text = plots._verdict_text(result)
    assert "NOT steady (not used)" in text and "the window lasts 3.00 h" in text
    assert f"{result.k:.3f} ± {result.u_k:.3f}" in text


# --- study figures: fit_figure, figure3, figure4, figure5 ------------------------------------


def series(windows=("step_up", "step_down"), n=120, dt=900.0, veh=True, sim_offset=0.05):
    """An ``order{n}_series.csv``-like table: per window a step response, time restarting at 0."""
    parts = []
    for k, name in enumerate(windows):
        t = np.arange(n) * dt
        h = t / 3600.0
        up = k % 2 == 0
        T = (22.0 - 11.0 * np.exp(-h / 6.0)) if up else (11.0 + 11.0 * np.exp(-h / 5.0))
        T_veh = (21.5 - 10.5 * np.exp(-h / 10.0)) if up else (11.5 + 10.0 * np.exp(-h / 9.0))
        wiggle = 0.05 * np.sin(h * 3.0)
        part = pd.DataFrame(
            {
                "window": name,
                "time": t,
                "T": T + wiggle,
                "T_sim": T + sim_offset,
                "T_veh": T_veh + wiggle if veh else np.nan,
                "T_veh_sim": T_veh - sim_offset,
                "T_o": -10.0 + 0.2 * np.cos(h),
                "Q_H": np.where(up, 24_000.0, 1000.0) + 100.0 * np.sin(h),
            }
        )
        part["T_residual"] = part["T"] - part["T_sim"]
        part["T_veh_residual"] = part["T_veh"] - part["T_veh_sim"]
        parts.append(part)
    return pd.concat(parts, ignore_index=True)


def order1(s):
    """The first-order series has no T_veh columns at all."""
    out = s[["window", "time", "T", "T_sim", "T_residual", "T_o", "Q_H"]].copy()
    out["T_sim"] += 0.2
    out["T_residual"] = out["T"] - out["T_sim"]
    return out


FIT_CONTENT = {
    "vehicle": "Tram9",
    "order": 2,
    "verdict": "fit acceptable",
    "R2": 0.99912,
    "nrmse_fit": 0.9703,
    "outputs": ["T", "T_veh"],
    "parameters": {"C": {"value": 1.8e7, "estimated": True, "ci95": [1.7e7, 1.9e7]}},
    "synthetic": True,
}
FIT = FitRecord.from_dict(FIT_CONTENT)


def table3():
    """Table 3 rows in a shuffled class order; two verdicts 'assumptions in doubt'."""
    rows = [
        ("Main1", "main-line", 562, 5.47, "fit acceptable"),
        ("Tram1", "tram", 270, 0.56, "assumptions in doubt"),
        ("Metro1", "metro", 533, 2.05, "fit acceptable"),
        ("Regio1", "regional", 664, 0.11, "assumptions in doubt"),
        ("Metro2", "metro", 304, 1.04, "fit acceptable"),
        ("Tram2", "tram", 333, 0.55, "fit acceptable"),
        ("Regio2", "regional", 577, 4.88, "fit acceptable"),
        ("Metro3", "metro", 175, 0.71, "fit acceptable"),
        ("Main2", "main-line", 433, 9.35, "fit acceptable"),
    ]
    df = pd.DataFrame(rows, columns=["vehicle", "class", "c_veh", "delta", "verdict"])
    df["c_veh_lo"], df["c_veh_hi"] = 0.85 * df["c_veh"], 1.2 * df["c_veh"]
    df["delta_lo"], df["delta_hi"] = 0.7 * df["delta"], 1.4 * df["delta"]
    df.loc[df["vehicle"] == "Metro2", "delta_hi"] = np.inf  # an open interval: no bar, no error
    columns = "vehicle class c_veh c_veh_lo c_veh_hi delta delta_lo delta_hi verdict"
    return df[columns.split()]


STUDY_FIGURES = {
    "fit": lambda: plots.fit_figure(series(), FIT, "Tram9: second-order fit"),
    "figure3": lambda: plots.figure3(order1(series()), series()),
    "figure4": lambda: plots.figure4({"MetroA": series(("sequence",)), "MetroB": series()}),
    "figure5a": lambda: plots.figure5(table3())[0],
    "figure5b": lambda: plots.figure5(table3())[1],
}
SIZES = {"figure5a": plots.FIGSIZE_FIG5_IN, "figure5b": plots.FIGSIZE_FIG5_IN}


def data_axes(fig):
    """The first axes that shows data (legend rows and info cells have no visible axis)."""
    return next(ax for ax in fig.axes if ax.axison and ax.lines)


@pytest.mark.parametrize("name", list(STUDY_FIGURES))
def test_study_figure_renders_at_paper_size_and_is_not_blank(name, tmp_path):
    fig = STUDY_FIGURES[name]()
    png, svg = plots.save_figure(fig, tmp_path / name)
    assert png.exists() and svg.read_text(encoding="utf-8").lstrip().startswith("<?xml")
    image = imread(png)
    w_in, h_in = SIZES.get(name, plots.FIGSIZE_IN)
    assert image.shape[:2] == (round(h_in * plots.DPI), round(w_in * plots.DPI))
    assert image[..., :3].std() > 0.05
    # the plot area itself is not one colour: crop the first data panel inside its spines
    box = data_axes(fig).get_window_extent()
    height = image.shape[0]
    rows = slice(int(height - box.y1) + 4, int(height - box.y0) - 4)
    cols = slice(int(box.x0) + 4, int(box.x1) - 4)
    area = image[rows, cols, :3]
    assert area.size > 0 and area.std() > 0.02
    assert len(np.unique(area.reshape(-1, 3), axis=0)) > 10


@pytest.mark.parametrize("name", list(STUDY_FIGURES))
def test_study_figure_is_byte_deterministic(name, tmp_path):
    fig = STUDY_FIGURES[name]()
    a = plots.save_figure(fig, tmp_path / "a")
    b = plots.save_figure(fig, tmp_path / "b")  # the same figure saved twice
    c = plots.save_figure(STUDY_FIGURES[name](), tmp_path / "c")  # built again
    for x, y, z in zip(a, b, c, strict=True):
        assert x.read_bytes() == y.read_bytes() == z.read_bytes()


def labels_of(fig):
    return [line.get_label() for ax in fig.axes for line in ax.lines]


def test_fit_figure_without_surface_sensors_draws_no_t_veh_line():
    s = series(veh=False)  # T_veh all NaN, T_veh_sim still there
    fig = plots.fit_figure(
        s, FitRecord.from_dict(FIT_CONTENT | {"outputs": ["T"]}), "no surface sensors"
    )
    labels = labels_of(fig)
    assert "T measured" in labels and "T simulated" in labels and "T residual" in labels
    assert not [x for x in labels if "T_veh" in x]
    # a first-order series has no T_veh columns at all
    labels = labels_of(
        plots.fit_figure(
            order1(series()), FitRecord.from_dict(FIT_CONTENT | {"outputs": ["T"]}), "order 1"
        )
    )
    assert not [x for x in labels if "T_veh" in x]


def test_fit_figure_draws_t_veh_when_compared_or_measured():
    labels = labels_of(plots.fit_figure(series(), FIT, "compared"))
    assert {"T_veh measured", "T_veh simulated", "T_veh residual"} <= set(labels)
    # measured but not compared: drawn, yet no residual
    labels = labels_of(
        plots.fit_figure(
            series(), FitRecord.from_dict(FIT_CONTENT | {"outputs": ["T"]}), "measured"
        )
    )
    assert {"T_veh measured", "T_veh simulated"} <= set(labels)
    assert "T_veh residual" not in labels


def test_fit_figure_lays_two_windows_side_by_side():
    s = series(("step_up", "step_down"), n=50, dt=1800.0)
    fig = plots.fit_figure(s, FIT, "two windows")
    ax = fig.axes[0]
    line = next(ln for ln in ax.lines if ln.get_label() == "T measured")
    x = np.asarray(line.get_xdata(), dtype=float)
    assert x.size == len(s) + 1 and np.isnan(x[50])  # one break: no line joins the windows
    first, second = x[:50], x[51:]
    end = 49 * 1800.0 / 3600.0
    assert first[0] == 0.0 and first[-1] == pytest.approx(end)
    assert second[0] > first[-1]  # after the first window plus a gap
    assert np.allclose(second - second[0], first)  # each window keeps its own time
    # a thin vertical line in the gap, the window names above the top panel
    vertical = [
        ln for ln in ax.lines if ln.get_label().startswith("_") and len(set(ln.get_xdata())) == 1
    ]
    assert len(vertical) == 1 and first[-1] < vertical[0].get_xdata()[0] < second[0]
    names = [t.get_text() for sec in ax.child_axes for t in sec.get_xticklabels()]
    assert names == ["step_up", "step_down"]
    # tick labels: each window's own hours, never "-0"
    bottom = fig.axes[2]
    ticks = [t.get_text() for t in bottom.get_xticklabels()]
    assert ticks.count("0") == 2 and "-0" not in ticks
    assert bottom.get_xlabel() == "time since window start (h)"


def test_fit_figure_text_box_and_axis_units():
    fig = plots.fit_figure(
        series(), FitRecord.from_dict(FIT_CONTENT | {"verdict": "assumptions in doubt"}), "box"
    )
    texts = [t.get_text() for ax in fig.axes for t in ax.texts]
    box = next(t for t in texts if "NRMSE fit" in t)
    lines = box.splitlines()
    assert any("R²" in x and "eq. 21" in x and "0.9991" in x for x in lines)
    nrmse = next(x for x in lines if "NRMSE fit" in x)
    assert "R²" not in nrmse and "R^2" not in nrmse and "0.970" in nrmse
    assert "verdict: assumptions in doubt" in lines
    ylabels = [ax.get_ylabel() for ax in fig.axes if ax.get_ylabel()]
    assert ylabels and all("(" in y and y.endswith(")") for y in ylabels)
    assert {"temperature (°C)", "T_o (°C)", "Q_H (kW)"} <= set(ylabels)
    assert any("(K)" in y for y in ylabels)  # residuals in kelvin


def test_fit_figure_computes_residuals_when_the_column_is_missing():
    s = series().drop(columns=["T_residual", "T_veh_residual"])
    fig = plots.fit_figure(s, FIT, "no residual columns")
    residual = next(ln for ax in fig.axes for ln in ax.lines if ln.get_label() == "T residual")
    y = np.asarray(residual.get_ydata(), dtype=float)
    h = np.r_[np.arange(120), np.nan, np.arange(120)] * 0.25  # 900 s steps, a break between
    expected = 0.05 * np.sin(3.0 * h) - 0.05  # measured (T + wiggle) - simulated (T + 0.05)
    assert np.isnan(y[120]) and np.nanmax(np.abs(y - expected)) < 1e-9


def test_q_h_is_a_post_step_in_kw():
    fig = plots.fit_figure(series(), FIT, "inputs")
    q = next(ln for ax in fig.axes for ln in ax.lines if ln.get_label() == "Q_H (heat input)")
    assert q.get_drawstyle() == "steps-post"
    assert np.nanmax(np.asarray(q.get_ydata(), dtype=float)) == pytest.approx(24.1, abs=0.01)


def test_irradiance_inputs_are_drawn_in_kw_per_m2_and_t_o_says_where_it_was_measured():
    s = series().assign(I_sol=lambda d: 800.0 * (d["time"] % 7200 < 3600))
    fig = plots.fit_figure(s, FIT, "sunshine", synthetic=False)
    labels = labels_of(fig)
    assert "T_o (outdoor air)" in labels and "T_o (tunnel air)" not in labels
    line = next(ln for ax in fig.axes for ln in ax.lines if ln.get_label().startswith("I_sol"))
    assert line.get_drawstyle() == "steps-post"
    assert np.nanmax(np.asarray(line.get_ydata(), dtype=float)) == pytest.approx(0.8)
    assert any("kW/m²" in ax.get_ylabel() for ax in fig.axes)
    assert "T_o (tunnel air)" in labels_of(plots.fit_figure(series(), FIT, "CWT", synthetic=True))


def test_figure3_names_the_models_and_checks_the_windows():
    fig = plots.figure3(order1(series()), series())
    legend = [t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().texts]
    assert "first-order model (eq. 9)" in legend and "second-order model (eqs. 7-8)" in legend
    # told apart in grey print: measured solid, the two models dashed in different patterns
    styles = {ln.get_label(): ln.get_linestyle() for ln in fig.axes[0].lines}
    assert styles["measured T"] == "-"
    assert styles["first-order model (eq. 9)"] == styles["second-order model (eqs. 7-8)"] == "--"
    assert plots.MODEL_STYLES[1]["ls"] != plots.MODEL_STYLES[2]["ls"]
    with pytest.raises(ValueError, match="same windows"):
        plots.figure3(order1(series(n=100)), series())


def test_figure4_has_one_panel_per_vehicle():
    fig = plots.figure4({"Metro1": series(("sequence",)), "Metro2": series(("sequence",), n=80)})
    panels = [ax for ax in fig.axes if ax.axison]
    assert [ax.get_title(loc="left") for ax in panels] == ["Metro1", "Metro2"]
    for ax in panels:
        assert ax.get_ylabel() == "T (°C)" and ax.get_xlabel().endswith("(h)")
        assert {"measured T"} <= {ln.get_label() for ln in ax.lines}


def xticks(fig):
    return [t.get_text() for t in data_axes(fig).get_xticklabels()]


def test_figure5_classes_in_paper_order_with_counts():
    a, b = plots.figure5(table3())
    labels = [" ".join(x.split()) for x in xticks(a)]
    assert labels == ["tram (n=2)", "metro (n=3)", "regional (n=2)", "main-line (n=2)"]
    # Metro2's delta interval is open to infinity: not an estimate, counted apart
    assert " ".join(xticks(b)[1].split()) == "metro (n=2+1)"
    assert data_axes(a).get_ylabel() == "c_veh (J/(kg K))"
    # only the classes present
    a, _ = plots.figure5(table3()[lambda d: d["class"] != "tram"])
    assert [x.split()[0] for x in xticks(a)] == ["metro", "regional", "main-line"]


def test_figure5_hollow_markers_for_assumptions_in_doubt():
    t3 = table3()
    for fig in plots.figure5(t3):
        ax = data_axes(fig)
        points = {ln.get_gid(): ln for ln in ax.lines if (ln.get_gid() or "").startswith("vehicle")}
        assert len(points) == len(t3)
        for row in t3.itertuples():
            point = points[f"vehicle-{row.vehicle}"]
            hollow = point.get_markerfacecolor() == "none"
            assert hollow == (row.verdict == "assumptions in doubt")
        shapes = {ln.get_marker() for ln in points.values() if ln.get_markerfacecolor() != "white"}
        assert len(shapes) == 2  # a different marker, not only a different fill
        names = {t.get_text() for t in ax.texts}
        assert set(t3["vehicle"]) <= names
        legend = [t.get_text() for x in fig.axes if x.get_legend() for t in x.get_legend().texts]
        assert "assumptions in doubt" in legend and "fit acceptable" in legend


def test_figure5_draws_a_value_the_data_do_not_determine_apart():
    """Metro3's delta not identified, at least 1,362 (C at its lower bound): no box, no axis
    range and no filled point rest on it; an open triangle at the axis edge with an arrow, and
    the count says so. An interval open to infinity is no estimate either."""
    t3 = table3()
    for q in ("c_veh", "delta"):
        t3[f"{q}_status"], t3[f"{q}_limit"], t3[f"{q}_limit_kind"] = "estimated", np.nan, ""
    metro3 = t3["vehicle"] == "Metro3"
    t3.loc[metro3, ["delta", "delta_lo", "delta_hi"]] = np.nan
    t3.loc[metro3, "delta_status"] = "not identified: C at its lower bound 1e+04"
    t3.loc[metro3, ["delta_limit", "delta_limit_kind"]] = [1362.0, "lower"]
    b = plots.figure5(t3)[1]
    ax = data_axes(b)
    assert ax.get_ylim()[1] < 100  # 1,362 does not stretch the axis
    point = next(ln for ln in ax.lines if ln.get_gid() == "vehicle-Metro3")
    assert point.get_marker() == "^" and point.get_markerfacecolor() == "white"
    lo, hi = np.log10(ax.get_ylim())
    assert np.log10(point.get_ydata()[0]) == pytest.approx(lo + 0.9 * (hi - lo))  # near the top
    assert any(t.arrow_patch is not None for t in ax.texts if hasattr(t, "arrow_patch"))
    assert "metro (n=2+1)" in [" ".join(x.split()) for x in xticks(b)]
    assert "Metro3 (≥ 1.36e+03)" in {t.get_text() for t in ax.texts}  # the limit, by name
    legend = [t.get_text() for x in b.axes if x.get_legend() for t in x.get_legend().texts]
    assert "not identified: limit" in legend


def test_figure5_footer_names_the_measured_vehicles():
    t3 = table3().assign(source="synthetic: virtual climatic wind tunnel campaign")
    assert plots.provenance_note(t3) == plots.SYNTHETIC_NOTE
    t3.loc[t3["vehicle"] == "Regio2", "source"] = "measured"
    note = plots.provenance_note(t3)
    assert note.endswith("except measured: Regio2")
    a, _ = plots.figure5(t3, note=note)
    assert note in [" ".join(f.split()) for f in footers(a)]  # wrapped to the column's width
    assert plots.provenance_note(t3.assign(source="measured")) is None


def test_a_footer_naming_thirteen_measured_vehicles_fits_inside_its_figure(tmp_path):
    """A study of measured vehicles names them all in the footer: on Figure 5 (a) (a paper
    column) and the annual energy figure (a page width) the note wraps onto lines within
    the figure, and the axes keep clear of it."""
    names = [f"Measured{i:02d}" for i in range(13)]
    t3 = pd.concat([table3()] * 2, ignore_index=True).iloc[:13]
    t3 = t3.assign(vehicle=names, source="measured")
    t3.loc[0, "source"] = "synthetic: virtual climatic wind tunnel campaign"
    note = plots.provenance_note(t3)
    assert all(name in note for name in names[1:])
    energy_rows = pd.DataFrame(
        {"vehicle": names, "variant": "base", "climate": "Sand Point", "Jan_kWh": 1.0,
         "Jan_lo": 0.9, "Jan_hi": 1.1}
    )  # fmt: skip
    for fig in (
        plots.figure5(t3, note=note)[0],
        plots.annual_energy_figure(energy_rows, note=note),
    ):
        plots.save_figure(fig, tmp_path / "f")
        renderer = fig.canvas.get_renderer()
        text = next(t for t in fig.texts if "except measured" in t.get_text())
        box = text.get_window_extent(renderer)
        assert text.get_text().count("\n") >= 1
        assert box.x0 >= 0 and box.x1 <= fig.bbox.width + 0.5 and box.y0 >= 0
        for ax in fig.axes:
            if ax.axison:
                assert ax.get_tightbbox(renderer).y0 >= box.y1 - 1.0


def test_figure5_labels_moved_off_their_point_have_a_leader_line():
    """Where names crowd, a label moved away from its point's height is tied to its point
    by a leader line (its xy the point); a label at its point's height needs none."""
    a, _ = plots.figure5(table3())
    ax = data_axes(a)
    points = {ln.get_gid().removeprefix("vehicle-"): ln for ln in ax.lines if ln.get_gid()}
    leaders = [t for t in ax.texts if (t.get_gid() or "").startswith("label-")]
    for label in leaders:
        vid = label.get_gid().removeprefix("label-")
        assert label.arrow_patch is not None and label.get_text().startswith(vid)
        assert label.xy == (points[vid].get_xdata()[0], points[vid].get_ydata()[0])


def test_figure5_points_are_spread_deterministically_inside_their_class():
    t3 = table3()
    ax = data_axes(plots.figure5(t3)[0])
    x = {ln.get_gid(): ln.get_xdata()[0] for ln in ax.lines if ln.get_gid()}
    metro = sorted(x[f"vehicle-{v}"] for v in ("Metro1", "Metro2", "Metro3"))
    assert np.allclose(np.diff(metro), np.diff(metro)[0]) and metro[0] < 2 < metro[-1]
    assert x["vehicle-Metro3"] < x["vehicle-Metro2"] < x["vehicle-Metro1"]  # sorted by value


def test_figure5_log_axis_for_delta_only_over_a_factor_20():
    a, b = plots.figure5(table3())  # delta 0.11 .. 9.35: a factor 85
    assert data_axes(b).get_yscale() == "log" and "log scale" in data_axes(b).get_ylabel()
    assert data_axes(a).get_yscale() == "linear"
    narrow = table3()[lambda d: d["vehicle"] != "Regio1"]  # 0.55 .. 9.35: a factor 17
    b = plots.figure5(narrow)[1]
    assert data_axes(b).get_yscale() == "linear"
    assert data_axes(b).get_ylabel() == "δ = C_veh / C (1)"


def test_figure5_puts_other_classes_last_and_rejects_missing_columns():
    t3 = table3()
    t3.loc[0, "class"] = "other"
    a, _ = plots.figure5(t3)
    assert xticks(a)[-1].split()[0] == "other"
    with pytest.raises(ValueError, match="delta_hi"):
        plots.figure5(table3().drop(columns="delta_hi"))


def footers(fig):
    return [t.get_text() for t in fig.texts]


@pytest.mark.parametrize("name", ["fit", "figure3", "figure4", "figure5"])
def test_synthetic_footer_only_when_asked(name):
    build = {
        "fit": lambda **k: [plots.fit_figure(series(), FIT, "x", **k)],
        "figure3": lambda **k: [plots.figure3(order1(series()), series(), **k)],
        "figure4": lambda **k: [plots.figure4({"A": series()}, **k)],
        "figure5": lambda **k: list(plots.figure5(table3(), **k)),
    }[name]
    for fig in build():
        assert plots.SYNTHETIC_NOTE not in footers(fig)
    for fig in build(synthetic=True):
        assert footers(fig).count(plots.SYNTHETIC_NOTE) == 1
        assert plots.SYNTHETIC_NOTE == (
            "synthetic data: virtual climatic wind tunnel (not measurements)"
        )


def test_synthetic_note_on_the_k_figure_and_its_default_unchanged(tmp_path):
    plain = plots.save_figure(figure(), tmp_path / "plain")
    default = plots.save_figure(figure(synthetic=False), tmp_path / "default")
    for x, y in zip(plain, default, strict=True):
        assert x.read_bytes() == y.read_bytes()
    fig = figure(synthetic=True)
    assert footers(fig) == [plots.SYNTHETIC_NOTE]
    marked = plots.save_figure(fig, tmp_path / "marked")
    assert marked[0].read_bytes() != plain[0].read_bytes()
    # the helper works on any figure and returns the text
    other = figure()
    assert plots.synthetic_note(other).get_text() == plots.SYNTHETIC_NOTE


def test_footer_figures_are_byte_identical_across_processes(tmp_path):
    """With the footer's layout rect the solver's last bits varied from run to run (and with
    them the SVG clip-path ids); the settled layout is rounded, so every process agrees."""
    script = (
        "import sys; sys.path.insert(0, sys.argv[1]); import test_plots as t; "
        "from railtherm.report import plots; "
        "plots.save_figure(plots.fit_figure(t.series(), t.FIT, 'x', synthetic=True), sys.argv[2])"
    )
    here = str(Path(__file__).resolve().parent)
    outputs = []
    for seed in ("1", "2"):
        stem = tmp_path / f"run{seed}"
        env = os.environ | {"PYTHONHASHSEED": seed}
        subprocess.run([sys.executable, "-c", script, here, str(stem)], check=True, env=env)
        outputs.append([Path(f"{stem}.{ext}").read_bytes() for ext in ("png", "svg")])
    local = plots.save_figure(plots.fit_figure(series(), FIT, "x", synthetic=True), tmp_path / "x")
    outputs.append([path.read_bytes() for path in local])
    assert outputs[0] == outputs[1] == outputs[2]


def test_vehicle_figures_draws_the_k_figure_and_each_fit_from_their_files(tmp_path):
    """The files of one vehicle's k test and of two fits (one by the Kalman-filter estimator)
    in, their figures out: the same PNG and SVG bytes as the figure functions drawing the same
    data, the title naming the model and estimator, and innovations only for the Kalman fit."""
    import yaml

    from railtherm.data import ingest

    rec = record()
    win = k_window(rec)
    result = kvalue.static_k(win, 400.0, 4e4, SETTINGS, INSTRUMENTS, {"indoor": 4, "outdoor": 2})
    ingest.write_tidy(rec, tmp_path / "record.csv")
    ingest.write_tidy(win, tmp_path / "kvalue.csv")
    (tmp_path / "kvalue.yaml").write_text(yaml.safe_dump(result.to_dict()))
    s = series()
    for name in ("T", "T_veh"):
        s[f"{name}_innovation"] = 0.01 * np.sin(np.arange(len(s)) * 1.3 + len(name))
        s[f"{name}_innovation_sd"] = 0.02
    s.to_csv(tmp_path / "series.csv", index=False)
    fits = {}
    for key, estimator in (("order2", "output_error"), ("order2_kalman", "kalman")):
        fit = FIT_CONTENT | {"structure": "second_order", "estimator": estimator}
        (tmp_path / f"fit_{key}.yaml").write_text(yaml.safe_dump(fit))
        fits[key] = {
            "fit": str(tmp_path / f"fit_{key}.yaml"),
            "series": str(tmp_path / "series.csv"),
            "png": str(tmp_path / "out" / f"fit_{key}.png"),
        }
    fits["order2_kalman"]["innovations_png"] = str(tmp_path / "out" / "innovations.png")
    kfiles = {
        "record": str(tmp_path / "record.csv"),
        "window": str(tmp_path / "kvalue.csv"),
        "result": str(tmp_path / "kvalue.yaml"),
        "png": str(tmp_path / "out" / "kvalue.png"),
    }
    drawn = plots.vehicle_figures("Tram9", kvalue=kfiles, fit_files=fits, synthetic=True)
    assert drawn == [
        "k figure of Tram9",
        "fit figure of Tram9, second_order",
        "fit figure of Tram9, second_order",
        "innovation figure of Tram9, second_order",
    ]
    out = tmp_path / "out"
    assert sorted(p.name for p in out.iterdir()) == [
        "fit_order2.png",
        "fit_order2.svg",
        "fit_order2_kalman.png",
        "fit_order2_kalman.svg",
        "innovations.png",
        "innovations.svg",
        "kvalue.png",
        "kvalue.svg",
    ]
    direct = tmp_path / "direct"
    read = pd.read_csv(tmp_path / "series.csv")
    for key, title in (
        ("order2", "Tram9: second-order model (eqs. 7-8)"),
        ("order2_kalman", "Tram9: second-order model (eqs. 7-8), Kalman-filter estimator"),
    ):
        fit = rt_io.read_fit(tmp_path / f"fit_{key}.yaml")
        plots.save_figure(plots.fit_figure(read, fit, title, synthetic=True), direct / key)
        for ext in ("png", "svg"):
            assert (out / f"fit_{key}.{ext}").read_bytes() == (direct / f"{key}.{ext}").read_bytes()


def test_figure5_draws_no_box_for_a_class_of_fewer_than_three_values():
    a, b = plots.figure5(table3())  # c_veh: tram 2, metro 3, regional 2, main-line 2
    medians = [ln for ln in data_axes(a).lines if ln.get_color() == "0.1"]
    assert len(medians) == 1 and np.mean(medians[0].get_xdata()) == pytest.approx(2.0)
    # delta: Metro2 open to infinity leaves the metros two values: no box at all
    assert not [ln for ln in data_axes(b).lines if ln.get_color() == "0.1"]
    points = [ln for ln in data_axes(b).lines if (ln.get_gid() or "").startswith("vehicle")]
    assert len(points) == len(table3())  # every vehicle still drawn


def test_figure5_names_a_value_without_a_limit_in_the_legend():
    t3 = table3()
    for q in ("c_veh", "delta"):
        t3[f"{q}_status"], t3[f"{q}_limit"], t3[f"{q}_limit_kind"] = "estimated", np.nan, ""
    metro3 = t3["vehicle"] == "Metro3"
    t3.loc[metro3, ["delta", "delta_lo", "delta_hi"]] = np.nan
    t3.loc[metro3, "delta_status"] = "not identified: C_veh coupled to C, which is not identified"
    t3.loc[metro3, "delta_limit_kind"] = "none"
    b = plots.figure5(t3)[1]
    legend = [t.get_text() for x in b.axes if x.get_legend() for t in x.get_legend().texts]
    assert "not identified" in legend and "not identified: limit" not in legend


def test_a_steady_tunnels_sensor_noise_does_not_fill_the_input_panel():
    """T_o within 0.4 K (a steady tunnel and its sensor's noise): its axis spans at least
    T_O_MIN_SPAN_K, so the noise stays a thin line and the Q_H steps show."""
    fig = plots.fit_figure(series(), FIT, "steady tunnel")
    (axis,) = [ax for ax in fig.axes if ax.get_ylabel() == "T_o (°C)"]
    low, high = axis.get_ylim()
    assert high - low >= plots.T_O_MIN_SPAN_K - 1e-9
    assert low < -10.0 < high
