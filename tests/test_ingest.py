"""railtherm.data.ingest: raw CWT files -> tidy tables, against hand arithmetic and known
signals."""

from __future__ import annotations

import copy
import gzip
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, assume, event, given, settings
from hypothesis import strategies as st

from railtherm import synth
from railtherm.config import load_vehicle
from railtherm.data import ingest
from railtherm.errors import ConfigError, DataError
from railtherm.synth.physics import meter_scale

ROOT = Path(__file__).resolve().parents[1]
START = pd.Timestamp("2024-01-01T00:00:00")


def _vehicle(channels: dict[str, list], **over: Any) -> dict[str, Any]:
    """A vehicle config as plain data, as Vehicle.data carries it (schema defaults filled)."""
    data: dict[str, Any] = {
        "id": "V1",
        "raw_files": {"cwt": "V1.csv"},
        "format": {
            "separator": ",",
            "decimal": ".",
            "power_timing": "instant",
            "time": {"column": "time", "format": "iso"},
        },
        "channels": {"surface": [], "fan_power": [], **channels},
        "windows": {"identification": [{"name": "all", "start": 0, "end": 0}]},
        "cleaning": {"max_gap_s": 900},
    }
    for key, value in over.items():
        data[key] = value
    return data


def _write(df: pd.DataFrame, path: Path, sep: str = ",", decimal: str = ".") -> Path:
    text = df.to_csv(index=False, sep=sep, decimal=decimal, lineterminator="\n")
    if str(path).endswith(".gz"):
        path.write_bytes(gzip.compress(text.encode()))
    else:
        path.write_text(text)
    return path


def _iso(seconds) -> list[str]:
    return [(START + pd.Timedelta(seconds=float(s))).isoformat() for s in seconds]


def _clean(tmp_path, df, data, window=None, name="raw.csv", **kw) -> pd.DataFrame:
    path = _write(df, tmp_path / name, data["format"]["separator"], data["format"]["decimal"])
    raw = ingest.read_raw(path, data["format"], label=name)
    return ingest.tidy(raw, data, window, name, **kw)


SIMPLE = {
    "indoor_air": [{"column": "Ti1"}],
    "outdoor_air": [{"column": "To1"}],
    "heater_power": [{"column": "P1", "unit": "W"}],
}


def _simple_frame(t, Ti=20.0, To=-10.0, P=1000.0) -> pd.DataFrame:
    n = len(t)
    return pd.DataFrame(
        {
            "time": _iso(t),
            "Ti1": np.broadcast_to(Ti, n),
            "To1": np.broadcast_to(To, n),
            "P1": np.broadcast_to(P, n),
        }
    )


# ---------------------------------------------------------------------------------------------
# Hand arithmetic


def test_weighted_means_units_and_spread_by_hand(tmp_path):
    t = np.arange(5) * 60.0
    df = pd.DataFrame(
        {
            "time": _iso(t),
            "Tin_a": 20.0,
            "Tin_b": 21.0,
            "Tin_c": 24.0 + 273.15,  # logged in K
            "wall_1": 10.0,
            "wall_2": 12.0,
            "tunnel": 263.15,  # K
            "heat_1": 1.5,  # kW
            "heat_2": 500.0,  # W
            "fan": 0.1,  # kW
        }
    )
    channels = {
        "indoor_air": [
            {"column": "Tin_a", "weight": 1.0},
            {"column": "Tin_b", "weight": 2.0},
            {"column": "Tin_c", "weight": 1.0, "unit": "K"},
        ],
        "surface": [{"column": "wall_1"}, {"column": "wall_2"}],
        "outdoor_air": [{"column": "tunnel", "unit": "K"}],
        "heater_power": [{"column": "heat_1", "unit": "kW"}, {"column": "heat_2", "unit": "W"}],
        "fan_power": [{"column": "fan", "unit": "kW"}],
    }
    out = _clean(tmp_path, df, _vehicle(channels))
    assert list(out.columns) == list(ingest.TIDY_COLUMNS)
    assert out["time"].tolist() == [0.0, 60.0, 120.0, 180.0, 240.0]
    assert out["timestamp"].tolist() == _iso(t)
    # T = (1*20 + 2*21 + 1*24) / 4 = 21.5; spread = sqrt((2.25 + 2*0.25 + 6.25) / 4) = 1.5
    assert out["T"].to_numpy() == pytest.approx(21.5)
    assert out["T_spread"].to_numpy() == pytest.approx(1.5)
    assert out["T_veh"].to_numpy() == pytest.approx(11.0)
    assert out["T_o"].to_numpy() == pytest.approx(-10.0)
    assert out["Q_heater"].to_numpy() == pytest.approx(2000.0)
    assert out["Q_fan"].to_numpy() == pytest.approx(100.0)
    assert out["Q_H"].to_numpy() == pytest.approx(2100.0)
    assert out["filled"].tolist() == [0] * 5


def test_no_surface_sensors_gives_empty_T_veh_and_no_fans_zero_Q_fan(tmp_path):
    out = _clean(tmp_path, _simple_frame(np.arange(4) * 60.0), _vehicle(SIMPLE))
    assert out["T_veh"].isna().all()
    assert (out["Q_fan"] == 0).all()
    assert (out["T_spread"] == 0).all()
    path = tmp_path / "tidy.csv"
    ingest.write_tidy(out, path)
    assert path.read_text().splitlines()[1].split(",")[3] == ""  # T_veh written empty


@pytest.mark.parametrize("ratio", [1, 2, 3, 5])
def test_ramp_resampled_to_its_value_at_the_grid_points(tmp_path, ratio):
    t = np.arange(61) * 60.0
    data = _vehicle(SIMPLE, cleaning={"max_gap_s": 900, "step_s": 60.0 * ratio})
    out = _clean(tmp_path, _simple_frame(t, Ti=5.0 + 0.01 * t, To=-3.0 - 0.002 * t), data)
    grid = np.arange(0, 3600.0 + 1, 60.0 * ratio)
    assert out["time"].to_numpy() == pytest.approx(grid)
    # centred bin means (half weight on the bin edges), shrunk symmetrically at the ends
    assert out["T"].to_numpy() == pytest.approx(5.0 + 0.01 * grid, abs=1e-9)
    assert out["T_o"].to_numpy() == pytest.approx(-3.0 - 0.002 * grid, abs=1e-9)


def test_bin_mean_of_a_noisy_signal_by_hand(tmp_path):
    t = np.arange(7) * 60.0
    Ti = np.array([1.0, 4.0, 2.0, 8.0, 5.0, 7.0, 3.0])
    data = _vehicle(SIMPLE, cleaning={"max_gap_s": 900, "step_s": 120.0})
    out = _clean(tmp_path, _simple_frame(t, Ti=Ti), data)
    # grid 0, 120, 240, 360 s; bins [t-60, t+60] with the edge samples at half weight
    assert out["T"].tolist() == pytest.approx(
        [1.0, (0.5 * 4 + 2 + 0.5 * 8) / 2, (0.5 * 8 + 5 + 0.5 * 7) / 2, 3.0]
    )


def test_step_finer_than_the_logger_interpolates(tmp_path):
    t = np.arange(4) * 60.0
    data = _vehicle(SIMPLE, cleaning={"max_gap_s": 900, "step_s": 20.0})
    out = _clean(tmp_path, _simple_frame(t, Ti=np.array([0.0, 6.0, 3.0, 3.0])), data)
    assert out["T"].to_numpy()[:4] == pytest.approx([0.0, 2.0, 4.0, 6.0])
    assert out["filled"].sum() == 0


def _power_samples(timing: str, t: np.ndarray, dt: float, switch: float, lo: float, hi: float):
    """Logged samples of a power that steps from lo to hi at ``switch``."""

    def mean(a, b):  # exact mean of the step signal over [a, b)
        return lo + (hi - lo) * np.clip(b - np.maximum(a, switch), 0, None) / (b - a)

    if timing == "mean_preceding":
        return mean(t - dt, t)
    if timing == "mean_following":
        return mean(t, t + dt)
    return np.where(t >= switch, hi, lo)


@pytest.mark.parametrize("timing", ["mean_preceding", "mean_following", "instant"])
@pytest.mark.parametrize("ratio", [1, 2, 3])
def test_power_step_gives_exact_interval_means(tmp_path, timing, ratio):
    dt, step = 60.0, 60.0 * ratio
    t = np.arange(31) * dt
    switch = 630.0  # midway between two samples (the instant samples' linear reading is exact)
    P = _power_samples(timing, t, dt, switch, 1000.0, 3000.0)
    data = _vehicle(SIMPLE, cleaning={"max_gap_s": 900, "step_s": step})
    data["format"]["power_timing"] = timing
    window = {"start": _iso([0])[0], "end": _iso([1500])[0]}  # data run on to 1800 s
    out = _clean(tmp_path, _simple_frame(t, P=P), data, window)
    a = out["time"].to_numpy()
    expected = 1000.0 + 2000.0 * np.clip(a + step - switch, 0, step) / step
    assert out["Q_H"].to_numpy() == pytest.approx(expected)
    assert out["Q_heater"].to_numpy() == pytest.approx(expected)


@pytest.mark.parametrize("ratio", [1, 2])
def test_first_order_hold_takes_the_power_at_each_time(tmp_path, ratio):
    """model.input_hold first_order: a power column holds the value at t_n (binned like a
    temperature), not the mean over the step that follows."""
    t = np.arange(11) * 60.0
    P = 100.0 * np.arange(11) ** 2
    data = _vehicle(SIMPLE, cleaning={"max_gap_s": 900, "step_s": 60.0 * ratio})
    data["model"] = {"input_hold": "first_order"}
    out = _clean(tmp_path, _simple_frame(t, P=P), data)
    n = np.arange(0, 11, ratio)
    expected = 100.0 * n**2.0
    if ratio == 2:  # centred bins [t_n - 60, t_n + 60]: the ends count half
        inner = (100.0 * (n - 1) ** 2 / 2 + 100.0 * n**2 + 100.0 * (n + 1) ** 2 / 2) / 2
        expected[1:-1] = inner[1:-1]
    assert out["Q_H"].to_numpy() == pytest.approx(expected)
    assert out.attrs["input_hold"] == "first_order"


def test_mean_preceding_at_the_logger_step_is_the_next_sample(tmp_path):
    t = np.arange(6) * 60.0
    P = np.array([100.0, 200.0, 300.0, 400.0, 500.0, 600.0])
    data = _vehicle(SIMPLE)
    data["format"]["power_timing"] = "mean_preceding"
    out = _clean(tmp_path, _simple_frame(t, P=P), data)
    # Q_H[n] = mean over [t_n, t_n + 60) = the sample logged at t_n + 60; the last row (no data
    # after the end) keeps the last sample
    assert out["Q_H"].tolist() == pytest.approx([200.0, 300.0, 400.0, 500.0, 600.0, 600.0])


@pytest.mark.parametrize("timing", ["mean_preceding", "instant", "mean_following"])
def test_last_row_uses_the_data_available(tmp_path, timing):
    t = np.arange(6) * 60.0  # ends at 300 s
    P = np.array([100.0, 200.0, 300.0, 400.0, 500.0, 600.0])
    data = _vehicle(SIMPLE, cleaning={"max_gap_s": 900, "step_s": 120.0})
    data["format"]["power_timing"] = timing
    out = _clean(tmp_path, _simple_frame(t, P=P), data)
    assert out["time"].tolist() == [0.0, 120.0, 240.0]
    # the last row's [240, 360) reaches past the data: the covered part only
    covered = {"mean_preceding": 600.0, "instant": 550.0, "mean_following": 550.0}[timing]
    assert out["Q_H"].iloc[-1] == pytest.approx(covered)


def test_instant_power_is_read_as_linear_between_samples(tmp_path):
    t = np.arange(5) * 60.0
    data = _vehicle(SIMPLE, cleaning={"max_gap_s": 900, "step_s": 120.0})
    out = _clean(tmp_path, _simple_frame(t, P=np.array([0.0, 60.0, 120.0, 180.0, 240.0])), data)
    # P(t) = t W: mean over [0, 120) = 60, over [120, 240) = 180, last row holds P(240) = 240
    assert out["Q_H"].tolist() == pytest.approx([60.0, 180.0, 240.0])


# ---------------------------------------------------------------------------------------------
# Gaps


def test_short_gaps_are_interpolated_per_channel_and_flagged(tmp_path):
    t = np.arange(21) * 60.0
    channels = {**SIMPLE, "indoor_air": [{"column": "Ti1"}, {"column": "Ti2"}]}
    df = _simple_frame(t, Ti=10.0 + 0.01 * t)
    df.insert(2, "Ti2", 30.0 + 0.01 * t)  # a sensor reading 20 K higher
    df.loc[5, "Ti2"] = np.nan  # an empty cell
    df = df.drop(index=[12, 13])  # two missing rows
    out = _clean(tmp_path, df, _vehicle(channels))
    # interpolated per channel: the missing sensor does not pull the mean down by 10 K
    assert out["T"].to_numpy() == pytest.approx(20.0 + 0.01 * t, abs=1e-9)
    assert len(out) == 21
    flagged = set(np.flatnonzero(out["filled"].to_numpy()))
    # instant power: row n uses samples n and n + 1
    assert flagged == {5, 11, 12, 13}


@pytest.mark.bad_input
def test_long_gap_is_an_error_naming_file_column_and_time(tmp_path):
    t = np.arange(60) * 60.0
    df = _simple_frame(t)
    df.loc[20:35, "To1"] = np.nan  # 16 samples = 960 s > 900 s
    with pytest.raises(DataError) as err:
        _clean(tmp_path, df, _vehicle(SIMPLE))
    msg = str(err.value)
    assert "raw.csv" in msg and "'To1'" in msg and "2024-01-01T00:20:00" in msg
    assert "960 s" in msg and "max_gap_s = 900" in msg


@pytest.mark.bad_input
def test_long_gap_of_missing_rows_and_limit_from_config(tmp_path):
    t = np.arange(60) * 60.0
    df = _simple_frame(t).drop(index=range(10, 13))  # 3 missing rows = 180 s
    data = _vehicle(SIMPLE, cleaning={"max_gap_s": 180})
    assert len(_clean(tmp_path, df, data)) == 60
    data["cleaning"]["max_gap_s"] = 179
    with pytest.raises(DataError, match=r"'Ti1' = '2024-01-01T00:10:00': gap of 180 s"):
        _clean(tmp_path, df, data)


def test_long_gap_outside_the_window_does_not_matter(tmp_path):
    t = np.arange(120) * 60.0
    df = _simple_frame(t)
    df.loc[80:110, "P1"] = np.nan
    window = {"start": _iso([600])[0], "end": _iso([3600])[0]}
    out = _clean(tmp_path, df, _vehicle(SIMPLE), window)
    assert len(out) == 51 and out["filled"].sum() == 0
    with pytest.raises(DataError, match="'P1'"):
        _clean(tmp_path, df, _vehicle(SIMPLE))


def test_empty_cell_at_the_start_is_held_and_flagged(tmp_path):
    t = np.arange(5) * 60.0
    df = _simple_frame(t, To=np.array([np.nan, -5.0, -6.0, -7.0, -8.0]))
    out = _clean(tmp_path, df, _vehicle(SIMPLE))
    assert out["T_o"].tolist() == pytest.approx([-5.0, -5.0, -6.0, -7.0, -8.0])
    assert out["filled"].tolist() == [1, 0, 0, 0, 0]


# ---------------------------------------------------------------------------------------------
# Errors


@pytest.mark.bad_input
def test_time_going_backwards_is_an_error(tmp_path):
    df = _simple_frame(np.array([0.0, 60.0, 180.0, 120.0, 240.0]))
    with pytest.raises(DataError) as err:
        _clean(tmp_path, df, _vehicle(SIMPLE))
    msg = str(err.value)
    assert msg.startswith("raw.csv: column 'time' = '2024-01-01T00:02:00': time goes backwards")
    assert "data row 4 (line 5)" in msg


@pytest.mark.bad_input
def test_duplicated_time_is_an_error(tmp_path):
    df = _simple_frame(np.array([0.0, 60.0, 60.0, 120.0]))
    with pytest.raises(
        DataError, match=r"'time' = '2024-01-01T00:01:00': duplicated time: data row 3"
    ):
        _clean(tmp_path, df, _vehicle(SIMPLE))


@pytest.mark.bad_input
def test_unparseable_time_is_an_error_naming_the_value(tmp_path):
    df = _simple_frame(np.arange(3) * 60.0)
    df.loc[1, "time"] = "yesterday"
    with pytest.raises(DataError, match=r"column 'time' = 'yesterday': line 3"):
        _clean(tmp_path, df, _vehicle(SIMPLE))


@pytest.mark.bad_input
def test_missing_time_column_and_unreadable_file(tmp_path):
    data = _vehicle(SIMPLE)
    data["format"]["time"]["column"] = "Zeit"
    path = _write(_simple_frame(np.arange(3) * 60.0), tmp_path / "raw.csv")
    with pytest.raises(DataError, match=r"raw.csv: column 'Zeit' = None: time column not found"):
        ingest.read_raw(path, data["format"])
    with pytest.raises(DataError, match="nope.csv"):
        ingest.read_raw(tmp_path / "nope.csv", data["format"])


@pytest.mark.bad_input
def test_missing_channel_is_an_error_naming_file_and_column(tmp_path):
    channels = {**SIMPLE, "fan_power": [{"column": "fan_9", "unit": "W"}]}
    with pytest.raises(DataError) as err:
        _clean(tmp_path, _simple_frame(np.arange(3) * 60.0), _vehicle(channels))
    msg = str(err.value)
    assert msg.startswith("raw.csv: column 'fan_9' = None: channel channels.fan_power[0] not found")
    assert "Ti1, To1, P1" in msg


@pytest.mark.bad_input
def test_text_in_a_channel_is_an_error(tmp_path):
    df = _simple_frame(np.arange(4) * 60.0).astype({"P1": object})
    df.loc[2, "P1"] = "ERR"
    with pytest.raises(DataError, match=r"column 'P1' = 'ERR': line 4: not a number"):
        _clean(tmp_path, df, _vehicle(SIMPLE))


@pytest.mark.bad_input
@pytest.mark.parametrize(
    ("column", "value", "shown"),
    [("Ti1", "inf", "inf"), ("P1", "-inf", "-inf"), ("To1", "Infinity", "inf")],
)
def test_an_infinite_value_is_an_error_naming_its_line(tmp_path, column, value, shown):
    """A single inf in an indoor channel once spread through the mean and left a fit on a
    sixth of its rows; -inf power became empty Q_H. Now it stops the cleaning, named."""
    df = _simple_frame(np.arange(4) * 60.0).astype({column: object})
    df.loc[2, column] = value
    with pytest.raises(DataError, match=rf"column '{column}' = '{shown}': line 4: not a finite"):
        _clean(tmp_path, df, _vehicle(SIMPLE))


@pytest.mark.bad_input
@pytest.mark.parametrize(
    ("column", "value", "cause"),
    [
        ("Ti1", 293.4, "kelvin declared as degC"),
        ("To1", -999.0, "fault code"),
        ("Ti1", 850.0, "a spike or a faulty sensor"),
    ],
)
def test_a_temperature_outside_the_physical_range_is_named_with_its_likely_cause(
    tmp_path, column, value, cause
):
    """Spikes of 850 degC, a sensor stuck at -999 or kelvin declared as degC were fitted
    ("in doubt" at best, k = 0.198 "usable" for kelvin) without a word about the values."""
    df = _simple_frame(np.arange(4) * 60.0)
    df.loc[2, column] = value
    with pytest.raises(DataError, match=rf"column '{column}' = {value!r}: at .*{cause}"):
        _clean(tmp_path, df, _vehicle(SIMPLE))


def test_the_temperature_range_is_checked_only_where_the_window_reads(tmp_path):
    df = _simple_frame(np.arange(10) * 60.0)
    df.loc[9, "Ti1"] = -999.0  # after the window: not the window's business
    window = {"start": "2024-01-01T00:00:00", "end": "2024-01-01T00:05:00"}
    table = _clean(tmp_path, df, _vehicle(SIMPLE), window=window)
    assert table["T"].between(-80, 120).all()


@pytest.mark.bad_input
@pytest.mark.parametrize(
    ("start", "end", "key"),
    [
        ("2023-12-31T23:59:00", "2024-01-01T00:03:00", "start"),
        ("2024-01-01T00:01:00", "2024-01-01T00:05:00", "end"),
    ],
)
def test_window_outside_the_data_is_an_error(tmp_path, start, end, key):
    data = _vehicle(SIMPLE)
    data["windows"]["kvalue"] = {"start": start, "end": end}
    with pytest.raises(ConfigError) as err:
        _clean(tmp_path, _simple_frame(np.arange(5) * 60.0), data, data["windows"]["kvalue"])
    msg = str(err.value)
    assert msg.startswith(f"raw.csv: key 'windows.kvalue.{key}' = ")
    assert "outside the data: the data of raw.csv run from 2024-01-01T00:00:00 to " in msg
    assert msg.endswith("2024-01-01T00:04:00")


@pytest.mark.bad_input
def test_window_without_data_rows_is_an_error(tmp_path):
    df = _simple_frame(np.arange(10) * 60.0).drop(index=[4, 5, 6])
    window = {"name": "w", "start": _iso([250])[0], "end": _iso([350])[0]}
    with pytest.raises(ConfigError, match="no data row in the window"):
        _clean(tmp_path, df, _vehicle(SIMPLE), window, window_key="windows.identification[0]")


# ---------------------------------------------------------------------------------------------
# Formats


@pytest.mark.parametrize("name", ["raw.csv", "raw.csv.gz"])
def test_plain_gz_and_semicolon_comma_give_the_same_table(tmp_path, name):
    t = np.arange(10) * 60.0
    df = _simple_frame(t, Ti=20.25 + 0.5 * np.sin(t), P=1234.5)
    reference = _clean(tmp_path, df, _vehicle(SIMPLE), name="ref.csv")
    data = _vehicle(SIMPLE)
    data["format"].update(separator=";", decimal=",")
    out = _clean(tmp_path, df, data, name=name)
    assert (tmp_path / name).read_bytes()[:2] == (b"\x1f\x8b" if name.endswith(".gz") else b"ti")
    pd.testing.assert_frame_equal(out, reference)
    assert out["T"].iloc[0] == 20.25 and out["Q_H"].iloc[0] == 1234.5


def test_seconds_files_keep_their_seconds(tmp_path):
    t = 1000.0 + np.arange(8) * 30.0
    df = _simple_frame(t, Ti=t / 100.0)
    df["time"] = [f"{s:g}" for s in t]
    data = _vehicle(SIMPLE, cleaning={"max_gap_s": 900, "step_s": 60.0})
    data["format"]["time"]["format"] = "seconds"
    out = _clean(tmp_path, df, data, {"start": 1030, "end": 1200})
    assert out["time"].tolist() == [0.0, 60.0, 120.0]
    assert out["timestamp"].tolist() == [1030.0, 1090.0, 1150.0]
    assert out["T"].to_numpy() == pytest.approx([10.3, 10.9, 11.5])


def test_iso_time_zone_is_kept_in_the_labels(tmp_path):
    df = _simple_frame(np.arange(4) * 60.0)
    df["time"] = [f"2024-06-01T12:0{i}:00+02:00" for i in range(4)]
    out = _clean(
        tmp_path,
        df,
        _vehicle(SIMPLE),
        {"start": "2024-06-01T12:01:00+02:00", "end": "2024-06-01T12:03:00+02:00"},
    )
    assert out["timestamp"].tolist() == [
        "2024-06-01T12:01:00+02:00",
        "2024-06-01T12:02:00+02:00",
        "2024-06-01T12:03:00+02:00",
    ]


def test_write_tidy_is_deterministic_and_reads_back(tmp_path):
    t = np.arange(30) * 60.0
    df = _simple_frame(t, Ti=20.0 + np.sqrt(t) / 7.0)
    out = _clean(tmp_path, df.drop(index=[7]), _vehicle(SIMPLE))
    a, b = tmp_path / "a" / "tidy.csv", tmp_path / "b.csv"
    ingest.write_tidy(out, a)
    ingest.write_tidy(out.copy(), b)
    assert a.read_bytes() == b.read_bytes()
    assert a.read_text().splitlines()[0] == ",".join(ingest.TIDY_COLUMNS)
    back = ingest.read_tidy(a)
    pd.testing.assert_frame_equal(back, out, check_dtype=False)
    ingest.write_tidy(out, tmp_path / "c.csv.gz")
    ingest.write_tidy(out, tmp_path / "d.csv.gz")
    assert (tmp_path / "c.csv.gz").read_bytes() == (tmp_path / "d.csv.gz").read_bytes()


def test_clean_window_by_name(tmp_path):
    t = np.arange(61) * 60.0
    path = _write(_simple_frame(t, Ti=t / 60.0), tmp_path / "raw.csv")
    data = _vehicle(SIMPLE)
    data["windows"] = {
        "kvalue": {"start": _iso([600])[0], "end": _iso([1200])[0]},
        "identification": [{"name": "cool", "start": _iso([1800])[0], "end": _iso([3000])[0]}],
    }
    assert ingest.window_names(data) == ["kvalue", "cool"]
    assert ingest.window_spec(data, "cool") == (
        "cwt",
        data["windows"]["identification"][0],
        "windows.identification[0]",
    )
    k = ingest.clean_window(path, data, "kvalue", "data/raw.csv")
    assert k["T"].iloc[0] == pytest.approx(10.0) and len(k) == 11
    cool = ingest.clean_window(path, data, "cool")
    assert cool["T"].iloc[0] == pytest.approx(30.0) and len(cool) == 21
    assert len(ingest.clean_window(path, data, "record")) == 61
    with pytest.raises(ConfigError, match="no such window"):
        ingest.clean_window(path, data, "warmup")
    data["windows"]["kvalue"]["end"] = _iso([4000])[0]
    with pytest.raises(ConfigError, match=r"^data/raw.csv: key 'windows.kvalue.end'"):
        ingest.clean_window(path, data, "kvalue", "data/raw.csv")


def test_clean_windows_reads_each_raw_file_once_and_cuts_every_window(tmp_path, monkeypatch):
    t = np.arange(61) * 60.0
    _write(_simple_frame(t, Ti=t / 60.0), tmp_path / "raw.csv")
    data = _vehicle(SIMPLE)
    data["windows"] = {
        "kvalue": {"start": _iso([600])[0], "end": _iso([1200])[0]},
        "identification": [{"name": "cool", "start": _iso([1800])[0], "end": _iso([3000])[0]}],
    }
    reads = []
    read_raw = ingest.read_raw
    monkeypatch.setattr(
        ingest, "read_raw", lambda path, *a, **k: reads.append(path) or read_raw(path, *a, **k)
    )
    names = ["record", "kvalue", "cool"]
    tables = ingest.clean_windows(data, dict.fromkeys(names, "raw.csv"), tmp_path)
    assert len(reads) == 1
    assert list(tables) == names
    for name in names:
        alone = ingest.clean_window(tmp_path / "raw.csv", data, name, "raw.csv")
        pd.testing.assert_frame_equal(tables[name], alone)


# ---------------------------------------------------------------------------------------------
# Property-based: arbitrary layouts, units, steps and dropouts give the right table or an error


@st.composite
def _cases(draw):
    time_format = draw(st.sampled_from(["iso", "seconds"]))
    dt = draw(
        st.sampled_from(
            [1.0, 10.0, 30.0, 60.0, 300.0] + ([2.5] if time_format == "seconds" else [])
        )
    )
    ratio = draw(st.sampled_from([None, 1, 2, 3, 4]))
    n = draw(st.integers(12, 80))
    n_in, n_surf, n_out = draw(st.integers(1, 3)), draw(st.integers(0, 2)), draw(st.integers(1, 2))
    n_heat, n_fan = draw(st.integers(1, 3)), draw(st.integers(0, 2))
    timing = draw(st.sampled_from(["instant", "mean_preceding", "mean_following"]))
    sep, decimal = draw(st.sampled_from([(",", "."), (";", ","), ("\t", "."), (";", ".")]))
    i0 = draw(st.integers(0, n // 3))
    i1 = draw(st.integers(max(i0 + 1, 2 * n // 3), n - 1))
    max_gap_steps = draw(st.integers(1, 4))
    missing_rows = draw(st.lists(st.integers(1, n - 2), max_size=6, unique=True))
    empty = draw(st.lists(st.tuples(st.integers(1, n - 2), st.integers(0, 20)), max_size=8))
    seed = draw(st.integers(0, 2**16))
    return dict(
        time_format=time_format,
        dt=dt,
        ratio=ratio,
        n=n,
        counts=(n_in, n_surf, n_out, n_heat, n_fan),
        timing=timing,
        sep=sep,
        decimal=decimal,
        window=(i0, i1),
        max_gap=max_gap_steps * dt,
        missing_rows=missing_rows,
        empty=empty,
        seed=seed,
    )


@pytest.mark.bad_input
@settings(
    max_examples=120, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(case=_cases())
def test_property_right_table_or_clear_error(tmp_path, case):
    rng = np.random.default_rng(case["seed"])
    dt, n = case["dt"], case["n"]
    t0 = 0.0 if case["time_format"] == "iso" else float(rng.integers(0, 10_000))
    t = t0 + np.arange(n) * dt
    kinds = ["indoor_air", "surface", "outdoor_air", "heater_power", "fan_power"]
    channels: dict[str, list] = {k: [] for k in kinds}
    columns: dict[str, np.ndarray] = {}
    truth: dict[str, tuple] = {}  # column -> (kind, weight, a, b): signal a + b (t - t0) in SI
    for kind, count in zip(kinds, case["counts"], strict=True):
        for i in range(count):
            name = f"{kind[:3]}_{i}"
            if kind.endswith("power"):
                a, b = rng.uniform(100, 5000), rng.uniform(-1, 1)
                unit = str(rng.choice(["W", "kW"]))
                # power samples of a linear signal by the timing convention
                shift = {"instant": 0.0, "mean_preceding": -dt / 2, "mean_following": dt / 2}
                logged = a + b * (t - t0 + shift[case["timing"]])
                columns[name] = logged / (1000.0 if unit == "kW" else 1.0)
                channels[kind].append({"column": name, "unit": unit})
                truth[name] = (kind, 1.0, a, b)
            else:
                a, b = rng.uniform(-20, 30), rng.uniform(-0.01, 0.01)
                unit = str(rng.choice(["degC", "K"]))
                w = float(rng.choice([1.0, 0.5, 2.0]))
                columns[name] = a + b * (t - t0) + (273.15 if unit == "K" else 0.0)
                channels[kind].append({"column": name, "unit": unit, "weight": w})
                truth[name] = (kind, w, a, b)
    columns["humidity"] = rng.uniform(20, 60, n)  # not a channel
    order = list(rng.permutation(list(columns)))
    time_col = "Zeit"
    labels = _iso(t) if case["time_format"] == "iso" else [repr(float(s)) for s in t]
    df = pd.DataFrame({"Zeit": labels, **{c: columns[c] for c in order}})
    df = df[[*order[: len(order) // 2], time_col, *order[len(order) // 2 :]]]
    names = [c for c in order if c != "humidity"]
    missing = {c: set(case["missing_rows"]) for c in names}
    for row, j in case["empty"]:
        column = names[j % len(names)]
        df.loc[row, column] = np.nan
        missing[column].add(row)
    df = df.drop(index=case["missing_rows"])
    if case["time_format"] == "seconds" and case["decimal"] == ",":
        df[time_col] = df[time_col].str.replace(".", ",")
    # linear test signals may leave the physical range of temperatures: not the point here
    cleaning = {"max_gap_s": case["max_gap"], "temperature_range_degC": [-1e4, 1e4]}
    if case["ratio"]:
        cleaning["step_s"] = case["ratio"] * dt
    data = _vehicle(channels, cleaning=cleaning)
    data["format"] = {
        "separator": case["sep"],
        "decimal": case["decimal"],
        "power_timing": case["timing"],
        "time": {"column": time_col, "format": case["time_format"]},
    }
    i0, i1 = case["window"]
    bounds = [t[i0], t[i1]]
    window = {
        "start": _iso([bounds[0]])[0] if case["time_format"] == "iso" else bounds[0],
        "end": _iso([bounds[1]])[0] if case["time_format"] == "iso" else bounds[1],
    }
    step = cleaning.get("step_s", dt)
    grid = np.arange(bounds[0], bounds[1] + 1e-9 * dt, step)
    region = (grid[0] - step / 2, grid[-1] + step)

    # the oracle: which channels have a gap longer than max_gap reaching the window's rows
    long_gap = set()
    for column, rows in missing.items():
        runs = np.split(
            np.array(sorted(rows), dtype=int), np.flatnonzero(np.diff(sorted(rows)) > 1) + 1
        )
        for run in runs:
            if run.size and run.size * dt > case["max_gap"] + 1e-9:
                lo, hi = t[run[0] - 1], t[run[-1] + 1]
                if lo < region[1] and hi > region[0]:
                    long_gap.add(column)
    present = np.setdiff1d(np.arange(n), case["missing_rows"])
    # the median step is the logger step unless rows are missing in bulk
    assume(np.median(np.diff(t[present])) == dt)
    no_rows = not np.any((present >= i0) & (present <= i1))

    path = _write(df, tmp_path / "prop.csv", case["sep"], case["decimal"])
    raw = ingest.read_raw(path, data["format"])
    event("outcome: " + ("empty window" if no_rows else "long gap" if long_gap else "table"))
    if no_rows:
        with pytest.raises(ConfigError, match="no data row"):
            ingest.tidy(raw, data, window, "prop.csv")
        return
    if long_gap:
        with pytest.raises(DataError) as err:
            ingest.tidy(raw, data, window, "prop.csv")
        assert err.value.key in long_gap and "gap of" in str(err.value)
        return
    out = ingest.tidy(raw, data, window, "prop.csv")
    assert list(out.columns) == list(ingest.TIDY_COLUMNS)
    assert out["time"].to_numpy() == pytest.approx(grid - bounds[0], abs=1e-9)

    def expected(kind: str, at: np.ndarray) -> np.ndarray:
        terms = [(w, a + b * (at - t0)) for k, w, a, b in truth.values() if k == kind]
        if not terms:
            return np.full(at.size, np.nan)
        return sum(w * v for w, v in terms) / sum(w for w, _ in terms)

    for column, kind in (("T", "indoor_air"), ("T_veh", "surface"), ("T_o", "outdoor_air")):
        np.testing.assert_allclose(out[column], expected(kind, grid), atol=1e-7)
    # power over [t_n, t_n + step): its value at the interval's midpoint; the last row may reach
    # past the data (checked by hand in test_last_row_uses_the_data_available)
    covered = grid + step <= t[-1] + (dt if case["timing"] == "mean_following" else 0.0) + 1e-9
    mid = grid + step / 2
    heat = sum(a + b * (mid - t0) for k, _, a, b in truth.values() if k == "heater_power")
    fan = sum((a + b * (mid - t0) for k, _, a, b in truth.values() if k == "fan_power"), 0 * mid)
    np.testing.assert_allclose(out["Q_heater"][covered], heat[covered], rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(out["Q_fan"][covered], fan[covered], rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(out["Q_H"], out["Q_heater"] + out["Q_fan"])
    # flags: none without dropouts; rows far from every dropout are never flagged
    dropped = [t[r] for rows in missing.values() for r in rows]
    if not dropped:
        assert out["filled"].sum() == 0
    else:
        far = np.min(np.abs(grid[:, None] - np.array(dropped)[None, :]), axis=1) > 2 * step + dt
        assert out["filled"][far].sum() == 0


# ---------------------------------------------------------------------------------------------
# The shipped campaign against the noise-free truth


@pytest.fixture(scope="module")
def campaign():
    return synth.load_campaign(ROOT / "config" / "campaign" / "virtual_cwt.yaml")


@pytest.mark.parametrize("vid", ["Tram2", "Metro4"])
def test_campaign_windows_match_the_noise_free_truth(tmp_path, campaign, vid):
    spec = synth.vehicle_spec(campaign, vid)
    for name in synth.raw_file_names(spec):
        synth.write_raw_file(spec, name, tmp_path / "resources" / "campaign" / vid / name)
    (tmp_path / "config" / "vehicles").mkdir(parents=True)
    yaml_path = tmp_path / "config" / "vehicles" / f"{vid}.yaml"
    shutil.copy(ROOT / "config" / "vehicles" / f"{vid}.yaml", yaml_path)
    vehicle = load_vehicle(yaml_path, workdir=tmp_path)
    data = copy.deepcopy(vehicle.data)
    ideal = synth.simulate(spec, ideal=True).set_index("time_s")
    step = spec["logger"]["step_s"]
    for window in ingest.window_names(data):
        key, _, _ = ingest.window_spec(data, window)
        out = ingest.clean_window(tmp_path / vehicle.raw_files[key], data, window)
        assert out["time"].diff().iloc[1:].eq(step).all()
        if spec["logger"]["time_format"] == "iso":
            start = pd.Timestamp(spec["start"])
            at = (pd.to_datetime(out["timestamp"]) - start).dt.total_seconds().to_numpy()
        else:
            at = out["timestamp"].to_numpy()
        truth = ideal.loc[at]
        # temperatures: within the sensors' calibration offsets (0.1-0.2 K sd), noise and
        # stratification
        for column in ("T", "T_veh", "T_o"):
            err = out[column].to_numpy() - truth[column].to_numpy()
            assert abs(err.mean()) < 0.25, (window, column, err.mean())
            assert np.abs(err).max() < 0.6, (window, column, np.abs(err).max())
        # Q_H[n] covers [t_n, t_n + step) = the truth's interval ending at t_n + step; rows
        # without HVAC heat (logged from the air flow, biased by design), not interpolated,
        # and whose interval the file covers
        q_true = ideal["Q_H"].reindex(at + step).to_numpy()
        hvac = ideal["Q_hvac"].reindex(at + step).to_numpy()
        use = (out["filled"].to_numpy() == 0) & (hvac == 0) & ~np.isnan(q_true)
        use[-1] = False
        assert use.sum() > 0.5 * len(out)
        off = use & (q_true == 0)
        assert np.all(out["Q_H"].to_numpy()[off] == 0)
        use &= q_true > 0
        # the meters' common calibration error (power_meter.scale_u_rel), then their noise
        scale = meter_scale(spec)
        assert scale != 1.0 and abs(scale - 1.0) < 4 * spec["power_meter"]["scale_u_rel"]
        rel = out["Q_H"].to_numpy()[use] / (scale * q_true[use]) - 1
        assert abs(rel.mean()) < 0.003, (window, rel.mean())
        assert np.abs(rel).max() < 0.03, (window, np.abs(rel).max())


@pytest.mark.bad_input
def test_a_semicolon_file_read_with_commas_gets_a_separator_hint(tmp_path):
    df = _simple_frame(np.arange(3) * 60.0)
    path = _write(df, tmp_path / "raw.csv", ";", ".")
    with pytest.raises(DataError, match="reads as one column; is format.separator ';'"):
        ingest.read_raw(path, _vehicle(SIMPLE)["format"])


def test_trailing_separators_do_not_shift_the_columns(tmp_path):
    path = tmp_path / "raw.csv"
    rows = [f"2024-01-01T00:0{i}:00,20,-10,1000," for i in range(4)]
    path.write_text("time,Ti1,To1,P1\n" + "\n".join(rows) + "\n")
    raw = ingest.read_raw(path, _vehicle(SIMPLE)["format"])
    table = ingest.tidy(raw, _vehicle(SIMPLE), None, "raw.csv")
    assert table["T"].eq(20.0).all() and table["T_o"].eq(-10.0).all()


@pytest.mark.bad_input
def test_a_truncated_gzip_file_is_named(tmp_path):
    path = tmp_path / "raw.csv.gz"
    text = "time,Ti1,To1,P1\n" + "".join(
        f"2024-01-01T{i // 60:02d}:{i % 60:02d}:00,20,-10,1000\n" for i in range(500)
    )
    data = gzip.compress(text.encode())
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(DataError, match=r"raw.csv.gz.*truncated or damaged"):
        ingest.read_raw(path, _vehicle(SIMPLE)["format"])


def test_mixed_utc_offsets_are_compared_in_utc(tmp_path):
    """A daylight-saving change in an offset-stamped log once ended in pandas' 'Pass
    utc=True'; every stamp names its instant, so the record runs on in UTC."""
    path = tmp_path / "raw.csv"
    stamps = ["2024-03-31T01:58:00+01:00", "2024-03-31T01:59:00+01:00"]
    stamps += ["2024-03-31T03:00:00+02:00", "2024-03-31T03:01:00+02:00"]
    path.write_text("time,Ti1,To1,P1\n" + "".join(f"{s},20,-10,1000\n" for s in stamps))
    raw = ingest.read_raw(path, _vehicle(SIMPLE)["format"])
    assert list(raw.index) == [0.0, 60.0, 120.0, 180.0]
    path.write_text(path.read_text().replace("03:01:00+02:00", "03:01:00"))
    with pytest.raises(DataError, match="line 5: no UTC offset"):
        ingest.read_raw(path, _vehicle(SIMPLE)["format"])


def test_fahrenheit_and_a_channels_scale_and_offset_are_converted(tmp_path):
    """°F is a temperature unit; any channel's scale * raw + offset is taken in its unit
    before the conversion: the raw file is read as it is."""
    t = np.arange(5) * 60.0
    frame = _simple_frame(t, Ti=68.0, To=14.0, P=2.5)
    frame["P1"] = [2.5, 2.5, 3.0, 3.0, 3.0]  # logged in volts: 400 W per volt, 100 W offset
    data = _vehicle(
        {
            "indoor_air": [{"column": "Ti1", "unit": "degF"}],
            "outdoor_air": [{"column": "To1", "unit": "degF", "offset": -1.8}],
            "heater_power": [{"column": "P1", "unit": "W", "scale": 400.0, "offset": 100.0}],
        }
    )
    out = _clean(tmp_path, frame, data)
    assert out["T"].to_numpy() == pytest.approx(20.0)
    assert out["T_o"].to_numpy() == pytest.approx(-11.0)  # (14 - 1.8 - 32) * 5 / 9
    assert out["Q_heater"].iloc[0] == pytest.approx(1100.0)  # instant: [0, 60) at 1100 W
