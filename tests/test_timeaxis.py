"""railtherm.data.timeaxis: every declared time notation names the same instants."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from railtherm.data.timeaxis import declared, fix, instant, parse, recognise, seconds, time_format
from railtherm.errors import ConfigError, DataError

START = pd.Timestamp("2024-01-15 08:00:00")
STEPS_S = np.arange(0, 6 * 3600 + 1, 600.0)  # 6 h at 10 min


def column(values) -> pd.Series:
    return pd.Series([str(v) for v in values], dtype=object)


NOTATIONS = {
    "iso": [(START + pd.Timedelta(seconds=s)).isoformat() for s in STEPS_S],
    "%d.%m.%Y %H:%M:%S": [
        (START + pd.Timedelta(seconds=s)).strftime("%d.%m.%Y %H:%M:%S") for s in STEPS_S
    ],
    "%m/%d/%Y %I:%M %p": [
        (START + pd.Timedelta(seconds=s)).strftime("%m/%d/%Y %I:%M %p") for s in STEPS_S
    ],
    "epoch": [
        repr((START - pd.Timestamp("1970-01-01")).total_seconds() + float(s)) for s in STEPS_S
    ],
    "serial_days": [repr(45306 + 8 / 24 + float(s) / 86400) for s in STEPS_S],  # 2024-01-15
}


@pytest.mark.parametrize("name", list(NOTATIONS))
def test_absolute_notations_give_the_same_instants(name):
    tf = time_format({"format": name})
    times = parse("f.csv", column(NOTATIONS[name]), "t", tf)
    assert tf.absolute
    np.testing.assert_allclose(seconds(times, tf), STEPS_S, rtol=0, atol=1e-3)
    first = times.iloc[0].tz_localize(None) if times.dt.tz is not None else times.iloc[0]
    assert first == START


@pytest.mark.parametrize(("name", "factor"), [("seconds", 1), ("minutes", 60), ("hours", 3600)])
def test_elapsed_units_become_seconds_with_a_decimal_comma(name, factor):
    values = [repr(float(s) / factor).replace(".", ",") for s in STEPS_S]
    tf = time_format({"format": name})
    times = parse("f.csv", column(values), "t", tf, decimal=",")
    np.testing.assert_allclose(seconds(times, tf), STEPS_S, rtol=1e-9, atol=1e-6)
    assert instant("v.yaml", "windows.kvalue.start", 1.5, tf) == 1.5 * factor


def wall_clock(start: str, n: int) -> list[str]:
    """Local wall-clock times every 30 min across a DST change, as a logger on local time
    writes them (naive)."""
    utc = pd.date_range(pd.Timestamp(start, tz="UTC"), periods=n, freq="30min")
    return [t.tz_convert("Europe/Berlin").strftime("%d.%m.%Y %H:%M") for t in utc]


def test_local_time_across_the_autumn_change_is_read_in_utc_by_the_declared_rule():
    values = wall_clock("2024-10-26T22:00", 12)  # 00:00 local .. 03:30 local, 02:xx twice
    spec = {"format": "%d.%m.%Y %H:%M", "timezone": "Europe/Berlin"}
    with pytest.raises(DataError, match="occurs twice in Europe/Berlin.*format.time.dst"):
        parse("f.csv", column(values), "t", time_format(spec))
    times = parse("f.csv", column(values), "t", time_format({**spec, "dst": "infer"}))
    np.testing.assert_allclose(np.diff(seconds(times, time_format(spec))), 1800.0)


def test_a_local_time_in_the_skipped_spring_hour_is_an_error_naming_it():
    values = ["31.03.2024 01:30", "31.03.2024 02:30", "31.03.2024 03:30"]
    spec = {"format": "%d.%m.%Y %H:%M", "timezone": "Europe/Berlin", "dst": "infer"}
    with pytest.raises(DataError, match="does not exist in Europe/Berlin"):
        parse("f.csv", column(values), "t", time_format(spec))


def test_window_bounds_in_the_files_notation_or_iso():
    tf = time_format({"format": "%d.%m.%Y %H:%M:%S"})
    a = instant("v.yaml", "windows.kvalue.start", "15.01.2024 09:00:00", tf)
    b = instant("v.yaml", "windows.kvalue.start", "2024-01-15T09:00:00", tf)
    assert a == b == pd.Timestamp("2024-01-15 09:00")
    epoch = time_format({"format": "epoch"})
    assert instant("v.yaml", "k", 1705309200, epoch) == pd.Timestamp("2024-01-15 09:00", tz="UTC")
    with pytest.raises(ConfigError, match="windows.kvalue.start"):
        instant("v.yaml", "windows.kvalue.start", "yesterday", tf)
    with pytest.raises(ConfigError, match="must be a number of hours"):
        instant("v.yaml", "windows.kvalue.end", "2024-01-15", time_format({"format": "hours"}))


def test_a_value_of_another_notation_names_its_line():
    values = list(NOTATIONS["%d.%m.%Y %H:%M:%S"])
    values[4] = "2024-01-15T08:40:00"
    with pytest.raises(DataError, match=r"line 6: not a time of the pattern '%d.%m.%Y %H:%M:%S'"):
        parse("f.csv", column(values), "t", time_format({"format": "%d.%m.%Y %H:%M:%S"}))
    with pytest.raises(ValueError, match="unknown time format 'dd.mm.yyyy'"):
        time_format({"format": "dd.mm.yyyy"})


def test_converted_units_name_whole_microseconds():
    """0.1 h is 360 s: the float product 0.1 * 3600 = 360.00000000000006 is rounded to whole
    microseconds; seconds stay the file's own numbers."""
    tenths = column([f"{k / 10:.1f}" for k in range(200)])
    times = parse("f.csv", tenths, "t", time_format("hours"))
    np.testing.assert_array_equal(times.to_numpy(), np.arange(200) * 360.0)
    assert instant("v.yaml", "k", 0.1, time_format("hours")) == 360.0
    raw = column(["0.1", "0.30000000000000004"])
    assert parse("f.csv", raw, "t", time_format("seconds")).tolist() == [0.1, 0.30000000000000004]


@pytest.mark.parametrize(
    ("spec", "key", "reason"),
    [
        ({"format": "dd.mm.yyyy"}, "format.time.format", "iso, a strftime pattern such as"),
        ({"format": "%H:%M"}, "format.time.format", "reads back a date and time"),
        ({"format": "minutes", "timezone": "UTC"}, "format.time.timezone", "elapsed time"),
        ({"format": "epoch", "timezone": "UTC"}, "format.time.timezone", "count in UTC"),
        ({"format": "iso", "timezone": "Europe/Berln"}, "format.time.timezone", "Europe/Berlin"),
        ({"format": "iso", "dst": "infer"}, "format.time.dst", "format.time.timezone too"),
        ({"format": "iso", "timezone": "UTC", "dst": "no"}, "format.time.dst", "raise, infer"),
    ],
)
def test_a_declaration_is_checked_naming_key_value_and_accepted_forms(spec, key, reason):
    with pytest.raises(ConfigError) as caught:
        declared("v.yaml", spec)
    assert caught.value.key == key and reason in str(caught.value)
    assert str(caught.value).startswith(f"v.yaml: key '{key}' = ")


def test_the_common_notations_are_recognised():
    for name in ("iso", "%d.%m.%Y %H:%M:%S", "%m/%d/%Y %I:%M %p"):
        assert recognise(column(NOTATIONS[name])) == name
    assert recognise(column(NOTATIONS["epoch"])) == "seconds"  # a number does not tell its unit
    assert recognise(column(["15.01.2024 08:00", "gestern"])) is None


@pytest.mark.parametrize(
    ("value", "declared_as", "clause"),
    [
        ("2024-01-15T08:00:00", "%d.%m.%Y %H:%M:%S", "declare format.time.format: iso"),
        ("15.01.2024 08:00", "%d.%m.%Y %H:%M:%S", "declare format.time.format: '%d.%m.%Y %H:%M'"),
        ("3600", "iso", "it is a number: declare format.time.format seconds"),
        ("31.02.2024 08:00:00", "%d.%m.%Y %H:%M:%S", "else correct this line"),
        (None, "iso", "every row needs its time"),
        ("15.01.2024 08:00:00", "%d.%m.%Y %H:%M:%S", ""),  # of the notation: no fix to give
    ],
)
def test_the_fix_names_the_notation_a_value_is_written_in(value, declared_as, clause):
    got = fix(value, time_format(declared_as))
    assert (clause in got) if clause else got == ""


def test_serial_day_and_epoch_bounds_may_be_text_of_numbers():
    serial = time_format("serial_days")
    noon = pd.Timestamp("2024-01-15 12:00")
    assert instant("v.yaml", "k", "45306.5", serial) == noon
    assert instant("v.yaml", "k", "45306,5", serial, decimal=",") == noon
    assert instant("v.yaml", "k", 45306.5, serial) == noon
    assert instant("v.yaml", "k", "2024-01-15T12:00:00", serial) == noon
