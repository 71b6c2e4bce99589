"""railtherm.plots: the k-window figure renders, is not blank and is byte-deterministic."""

import io

import numpy as np
import pandas as pd
import pytest
from matplotlib.image import imread

from railtherm import kvalue, plots
from railtherm.config import section_defaults

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
