"""A lab's timestamps read by configuration alone (railtherm.data.timeaxis behind the raw-file
path): one measured recording (the Armadillo Box, data/armadillo), written as an ISO 8601 CSV
original and again in every time notation and file kind - German dates in a cp1252 CSV with
';' and decimal commas (plain and gzip), elapsed hours, Unix epoch seconds, spreadsheet serial
days, local wall-clock time in Europe/Berlin across the end of daylight-saving time (CSV and
.xlsx), elapsed minutes in a .mat file, elapsed days in R data - gives the same tidy table and
the same estimates; only each vehicle YAML differs (format, time column, window bounds in the
file's own notation). A time column declared wrongly stops validate with one line naming the
first bad value, its line, the notation and the fix, or is warned about naming the unit."""

from __future__ import annotations

import gzip
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import scipy.io
import yaml

from railtherm.cli import main
from railtherm.config import load_vehicle
from railtherm.data import ingest
from railtherm.data.starter import starter_vehicle
from railtherm.errors import ConfigError, DataError
from railtherm.study.run import fit_vehicle

rdata = pytest.importorskip("rdata")
pytest.importorskip("python_calamine")
pytest.importorskip("xlsxwriter")

REPO = Path(__file__).resolve().parents[1]
RAW = REPO / "data" / "armadillo" / "armadillo_data_H2.csv"
ARMADILLO = REPO / "validation" / "config" / "vehicles" / "Armadillo.yaml"

# The record's first row, in UTC. Its 233 rows at 30 min run to 2024-10-28 20:00 UTC, across
# the end of daylight-saving time in Europe/Berlin (27 Oct 2024, 03:00 CEST -> 02:00 CET: the
# local hour 02:00-03:00 is written twice).
START = pd.Timestamp("2024-10-24 00:00:00")
WINDOW_S = (7200.0, 410400.0)  # the identification window: 2 h to 114 h after the first row
GERMAN = "%d.%m.%Y %H:%M:%S"
BERLIN = "Europe/Berlin"
OUTSIDE = "Temperatur außen"  # a cp1252 file holds the ß as one byte
SERIAL_ORIGIN = pd.Timestamp("1899-12-30")  # day 0 of a spreadsheet's 1900 date system
MODELS = ["order1", "order2"]


def recording() -> tuple[pd.DataFrame, np.ndarray]:
    """The Armadillo record without its time column, and its times in seconds. The values
    are rounded to 15 significant digits (1e-15 relative, far below any sensor), which every
    writer here keeps exactly: xlsxwriter stores 16 digits where the CSV file has 17, and 16
    digits give back the same float only for a value that 15 digits already name."""
    raw = pd.read_csv(RAW)
    channels = raw.drop(columns="Time").map(lambda v: float(f"{v:.15g}"))
    return channels, raw["Time"].to_numpy(dtype=float)


def utc(seconds) -> pd.DatetimeIndex:
    return START + pd.to_timedelta(np.asarray(seconds, dtype=float), unit="s")


def local(seconds, pattern: str = GERMAN) -> list[str]:
    """Wall-clock times in Europe/Berlin, as a logger on local time writes them (no offset)."""
    return list(utc(seconds).tz_localize("UTC").tz_convert(BERLIN).strftime(pattern))


def with_time(name: str, values) -> pd.DataFrame:
    channels, _ = recording()
    return pd.concat([pd.Series(values, name=name), channels], axis=1)


# ---------------------------------------------------------------------------------------------
# The forms of one recording: (file name, writer, format keys, window bounds, outdoor column)


def iso_text(seconds) -> list[str]:
    return list(utc(seconds).strftime("%Y-%m-%dT%H:%M:%S"))


def write_csv(table: pd.DataFrame, path: Path, **options) -> None:
    table.to_csv(path, index=False, **options)  # .gz: compressed by the extension


def write_xlsx(table: pd.DataFrame, path: Path) -> None:
    """The data on a second sheet below a title and an empty row, as exports often are."""
    with pd.ExcelWriter(path, engine="xlsxwriter") as book:
        pd.DataFrame({"Versuch": ["Armadillo H2"]}).to_excel(book, sheet_name="Info", index=False)
        table.to_excel(book, sheet_name="Messdaten", index=False, startrow=2)
        book.sheets["Messdaten"].write(0, 0, "Klimawindkanal, Lauf H2")


def write_mat(table: pd.DataFrame, path: Path) -> None:
    scipy.io.savemat(path, {"messung": {c: table[c].to_numpy() for c in table.columns}})


def write_rda(table: pd.DataFrame, path: Path) -> None:
    rdata.write_rda(path, {"logger": table})


def german(t: np.ndarray) -> pd.DataFrame:
    return with_time("Datum/Uhrzeit", list(utc(t).strftime(GERMAN))).rename(
        columns={"T_ext": OUTSIDE}
    )


CP1252 = {"separator": ";", "decimal": ",", "encoding": "cp1252"}
LOCAL = {"timezone": BERLIN, "dst": "infer"}
W0, W1 = WINDOW_S


def forms() -> dict[str, tuple]:
    """name -> (file, write(path), format, (start, end), outdoor column)."""
    _, t = recording()
    serial = [repr(d) for d in (45589.0 + t / 86400.0).tolist()]  # 45589 is 2024-10-24
    return {
        "iso": (
            "iso.csv",
            lambda p: write_csv(with_time("Zeit", iso_text(t)), p),
            {"time": {"column": "Zeit", "format": "iso"}},
            tuple(iso_text(WINDOW_S)),
            "T_ext",
        ),
        "german-cp1252": (
            "messung.csv",
            lambda p: write_csv(german(t), p, sep=";", decimal=",", encoding="cp1252"),
            {**CP1252, "time": {"column": "Datum/Uhrzeit", "format": GERMAN}},
            tuple(utc(WINDOW_S).strftime(GERMAN)),
            OUTSIDE,
        ),
        "german-gzip": (
            "messung.csv.gz",
            lambda p: write_csv(german(t), p, sep=";", decimal=",", encoding="cp1252"),
            {**CP1252, "time": {"column": "Datum/Uhrzeit", "format": GERMAN}},
            tuple(utc(WINDOW_S).strftime(GERMAN)),
            OUTSIDE,
        ),
        "hours": (
            "hours.csv",
            lambda p: write_csv(with_time("t_h", [repr(h) for h in (t / 3600.0).tolist()]), p),
            {"time": {"column": "t_h", "format": "hours"}},
            (W0 / 3600.0, W1 / 3600.0),
            "T_ext",
        ),
        "epoch": (
            "epoch.csv",
            lambda p: write_csv(
                with_time("unix_s", [repr(1729728000.0 + s) for s in t.tolist()]), p
            ),
            {"time": {"column": "unix_s", "format": "epoch"}},
            (int(1729728000 + W0), int(1729728000 + W1)),
            "T_ext",
        ),
        "epoch-ms": (
            "epoch_ms.csv",
            lambda p: write_csv(
                with_time("unix_ms", [repr(1729728000000.0 + 1e3 * s) for s in t.tolist()]), p
            ),
            {"time": {"column": "unix_ms", "format": "epoch_ms"}},
            (int(1729728000000 + 1e3 * W0), int(1729728000000 + 1e3 * W1)),
            "T_ext",
        ),
        "serial-days": (  # window bounds in ISO 8601 where the file writes numbers
            "serial.csv",
            lambda p: write_csv(with_time("Excel-Datum", serial), p),
            {"time": {"column": "Excel-Datum", "format": "serial_days"}},
            tuple(iso_text(WINDOW_S)),
            "T_ext",
        ),
        "berlin-csv": (  # ISO text on a local clock
            "berlin.csv",
            lambda p: write_csv(with_time("Zeit", local(t, "%Y-%m-%dT%H:%M:%S")), p),
            {"time": {"column": "Zeit", "format": "iso", **LOCAL}},
            tuple(local(WINDOW_S, "%Y-%m-%dT%H:%M:%S")),
            "T_ext",
        ),
        "berlin-xlsx": (  # the walk-through of docs/adding-a-vehicle.md
            "export.xlsx",
            lambda p: write_xlsx(german(t).assign(**{"Datum/Uhrzeit": local(t)}), p),
            {
                "sheet": "Messdaten",
                "header_row": 2,
                "time": {"column": "Datum/Uhrzeit", "format": GERMAN, **LOCAL},
            },
            tuple(local(WINDOW_S)),
            OUTSIDE,
        ),
        "mat-minutes": (
            "logger.mat",
            lambda p: write_mat(with_time("t_min", t / 60.0), p),
            {"variable": "messung", "time": {"column": "t_min", "format": "minutes"}},
            (W0 / 60.0, W1 / 60.0),
            "T_ext",
        ),
        "rda-days": (  # steps of 1/48 day, which no float holds exactly
            "logger.rda",
            lambda p: write_rda(with_time("t_d", t / 86400.0), p),
            {"time": {"column": "t_d", "format": "days"}},
            (W0 / 86400.0, W1 / 86400.0),
            "T_ext",
        ),
    }


FORMS = list(forms())


def write_vehicle(folder: Path, form: str) -> Path:
    """The Armadillo vehicle config on the form's raw file: only ``format`` (and the time
    column in it), the window bounds and the outdoor column name differ from the original's."""
    name, write, fmt, (start, end), outdoor = forms()[form]
    write(folder / name)
    data = yaml.safe_load(ARMADILLO.read_text(encoding="utf-8"))
    data["id"] = f"Box_{form.replace('-', '_')}"
    data["raw_files"] = {"h2": name}
    data["format"] = {"power_timing": data["format"]["power_timing"], **fmt}
    data["channels"]["outdoor_air"] = [{"column": outdoor}]
    data["windows"]["identification"] = [{"name": "h2", "start": start, "end": end}]
    data["model"].update(orders=[1, 2], structures=[])
    path = folder / f"{data['id']}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False, allow_unicode=True), encoding="utf-8")
    return path


def fit_record(folder: Path, form: str):
    vehicle = load_vehicle(write_vehicle(folder, form), workdir=folder)
    return fit_vehicle(vehicle, models=MODELS, workdir=folder)


@pytest.fixture(scope="module")
def original(tmp_path_factory):
    return fit_record(tmp_path_factory.mktemp("iso"), "iso")


def test_the_record_spans_the_end_of_daylight_saving_time():
    """The premise of the local-time forms: local 02:00-03:00 is written twice, in order."""
    _, t = recording()
    written = local(t)
    assert written.count("27.10.2024 02:30:00") == 2
    assert written.index("27.10.2024 02:30:00") < written.index("27.10.2024 03:00:00")
    start, end = local(WINDOW_S)
    assert start.endswith("04:00:00") and end.endswith("19:00:00")  # CEST, then CET


@pytest.mark.parametrize("form", [f for f in FORMS if f != "iso"])
def test_every_notation_gives_the_tidy_table_and_estimates_of_the_iso_original(
    tmp_path, form, original
):
    """Every number of the tidy table is bit for bit the original's, so exact equality is
    asserted: German, epoch and local times name whole seconds; serial days, hours and days are
    written in full (repr), so that they name the logger's second to far below a millisecond
    (a serial day's float is off by about 1e-6 ms and is read to the millisecond; elapsed
    minutes, hours and days are converted to seconds and rounded to whole microseconds). The
    estimates then agree far inside the 1e-9 asked for."""
    result = fit_record(tmp_path, form)
    table, reference = result.tables["h2"], original.tables["h2"]
    numbers = [c for c in reference.columns if c != "timestamp"]
    pd.testing.assert_frame_equal(table[numbers], reference[numbers], check_exact=True)

    labels = reference["timestamp"]
    kind = forms()[form][2]["time"]["format"]
    if kind in ("hours", "minutes", "days"):  # elapsed seconds since the file's zero
        expected = (pd.to_datetime(labels) - START).dt.total_seconds()
        np.testing.assert_array_equal(table["timestamp"].to_numpy(float), expected.to_numpy())
    elif kind in ("epoch", "epoch_ms") or "timezone" in forms()[form][2]["time"]:  # in UTC
        assert list(table["timestamp"]) == [f"{s}+00:00" for s in labels]
    else:
        assert list(table["timestamp"]) == list(labels)

    for model in MODELS:
        got, want = result.fits[model].parameters, original.fits[model].parameters
        assert list(got) == list(want)
        for name in want:
            assert got[name].value == pytest.approx(want[name].value, rel=1e-9, abs=0), name
            assert got[name].ci95_combined == pytest.approx(
                want[name].ci95_combined, rel=1e-9, abs=0
            ), name


@pytest.mark.parametrize("form", ["german-gzip", "epoch", "berlin-xlsx", "rda-days"])
def test_validate_accepts_the_form(tmp_path, monkeypatch, capsys, form):
    vehicle = write_vehicle(tmp_path, form)
    monkeypatch.chdir(tmp_path)
    assert main(["validate", vehicle.name]) == 0, capsys.readouterr().err
    captured = capsys.readouterr()
    assert captured.out == "ok: 1 vehicle, values of 1 window checked\n"
    assert "warning" not in captured.err


def test_the_fit_command_on_the_local_time_spreadsheet(tmp_path, monkeypatch, capsys, original):
    vehicle = write_vehicle(tmp_path, "berlin-xlsx")
    monkeypatch.chdir(tmp_path)
    assert main(["fit", vehicle.name, "--model", "order2", "--out", "out"]) == 0
    printed = capsys.readouterr().out
    kA = original.fits["order2"].parameters["kA"].value
    assert f"kA = {kA:.4g}" in printed, printed
    clean = pd.read_csv(tmp_path / "out/vehicles/Box_berlin_xlsx/clean/h2.csv")
    assert clean["timestamp"].iloc[0] == "2024-10-24T02:00:00+00:00"


# ---------------------------------------------------------------------------------------------
# Mistakes: one line naming the file, the key or column, the value, its line and the fix


def validate_error(folder: Path, monkeypatch, capsys, vehicle: Path) -> str:
    monkeypatch.chdir(folder)
    assert main(["validate", vehicle.name]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    return err


def edit(vehicle: Path, change) -> None:
    data = yaml.safe_load(vehicle.read_text(encoding="utf-8"))
    change(data)
    vehicle.write_text(yaml.safe_dump(data, sort_keys=False, allow_unicode=True), "utf-8")


@pytest.mark.parametrize(
    ("form", "declared", "parts"),
    [
        (
            "german-cp1252",
            "%d.%m.%Y %H:%M",
            (
                "line 2: not a time of the pattern '%d.%m.%Y %H:%M': '24.10.2024 00:00:00'",
                "it reads as a time of the pattern '%d.%m.%Y %H:%M:%S': declare "
                "format.time.format: '%d.%m.%Y %H:%M:%S'",
            ),
        ),
        (
            "iso",
            GERMAN,
            (
                "line 2: not a time of the pattern '%d.%m.%Y %H:%M:%S': '2024-10-24T00:00:00'",
                "declare format.time.format: iso",
            ),
        ),
        (
            "german-cp1252",
            "%m.%d.%Y %H:%M:%S",  # the month first: 24 is no month
            ("line 2: not a time of the pattern '%m.%d.%Y %H:%M:%S'", "'%d.%m.%Y %H:%M:%S'"),
        ),
        ("hours", GERMAN, ("line 2: not a time of the pattern", "'0.0'", "it is a number")),
        ("epoch", "iso", ("line 2: not an ISO 8601 timestamp", "serial_days")),
        ("epoch-ms", "epoch", ("this is the year 56", "as milliseconds it is 2024-10-24")),
    ],
    ids=[
        "pattern-without-seconds",
        "iso-declared-german",
        "month-first",
        "numbers",
        "epoch",
        "epoch-ms-as-seconds",
    ],
)
def test_a_notation_that_does_not_match_names_value_line_notation_and_fix(
    tmp_path, monkeypatch, capsys, form, declared, parts
):
    vehicle = write_vehicle(tmp_path, form)
    edit(vehicle, lambda d: d["format"]["time"].update(format=declared))
    err = validate_error(tmp_path, monkeypatch, capsys, vehicle)
    assert err.startswith(f"{vehicle.name}: key 'format.time.format' = {declared!r}: "), err
    for part in parts:
        assert part in err, err


def test_one_bad_time_is_named_by_its_line_in_validate_and_in_the_job(
    tmp_path, monkeypatch, capsys
):
    """A single corrupt row (the 31 February) in a German file: validate and the cleaning
    both name it, its line and that the rest of the file reads."""
    vehicle = write_vehicle(tmp_path, "german-cp1252")
    path = tmp_path / "messung.csv"
    lines = path.read_text(encoding="cp1252").splitlines(keepends=True)
    date, rest = lines[49].split(";", 1)
    assert date == "25.10.2024 00:00:00"  # line 50: data row 49, 24 h after the first
    lines[49] = f"31.02.2024 00:00:00;{rest}"
    path.write_text("".join(lines), encoding="cp1252")
    err = validate_error(tmp_path, monkeypatch, capsys, vehicle)
    assert "column 'Datum/Uhrzeit' line 50: not a time of the pattern" in err, err
    assert "'31.02.2024 00:00:00'" in err and "else correct this line" in err, err

    data = yaml.safe_load(vehicle.read_text(encoding="utf-8"))
    with pytest.raises(DataError) as caught:
        ingest.read_raw(path, data["format"], label="messung.csv")
    assert (caught.value.key, caught.value.value) == ("Datum/Uhrzeit", "31.02.2024 00:00:00")
    assert "line 50:" in caught.value.reason and "correct this line" in caught.value.reason


def test_local_time_without_a_dst_rule_names_the_repeated_hour(tmp_path, monkeypatch, capsys):
    vehicle = write_vehicle(tmp_path, "berlin-csv")
    edit(vehicle, lambda d: d["format"]["time"].pop("dst"))
    err = validate_error(tmp_path, monkeypatch, capsys, vehicle)
    assert err.startswith(f"{vehicle.name}: key 'format.time.dst' = 'raise': berlin.csv "), err
    assert "line 146: this local time occurs twice in Europe/Berlin" in err, err  # row 144
    assert "'2024-10-27T02:00:00'" in err and "declare format.time.dst: infer" in err, err


@pytest.mark.bad_input
def test_a_clock_stepping_back_an_hour_without_a_timezone_names_the_settings(
    tmp_path, monkeypatch, capsys
):
    """A local-time log read as if it had no time zone goes back by an hour when summer time
    ends: the message says so and names format.time.timezone and format.time.dst."""
    vehicle = write_vehicle(tmp_path, "berlin-csv")
    edit(vehicle, lambda d: (d["format"]["time"].pop("dst"), d["format"]["time"].pop("timezone")))
    err = validate_error(tmp_path, monkeypatch, capsys, vehicle)
    assert "time goes backwards" in err, err
    assert "steps back by an hour" in err and "declare format.time.timezone" in err, err
    assert "format.time.dst: infer" in err, err


def test_an_earlier_or_later_rule_on_a_log_through_the_repeated_hour_names_infer(
    tmp_path, monkeypatch, capsys
):
    """``earlier`` takes both passes of 02:00-03:00 as summer time: the times repeat."""
    vehicle = write_vehicle(tmp_path, "berlin-csv")
    edit(vehicle, lambda d: d["format"]["time"].update(dst="earlier"))
    err = validate_error(tmp_path, monkeypatch, capsys, vehicle)
    assert err.startswith("berlin.csv: column 'Zeit' = '2024-10-27T02:00:00': time goes backwards")
    assert "line 148" in err and "format.time.dst: earlier takes every repeated" in err, err


@pytest.mark.parametrize(
    ("time", "key", "parts"),
    [
        (
            {"format": "dd.mm.yyyy HH:MM"},
            "format.time.format",
            ("must be iso, a strftime pattern such as '%d.%m.%Y %H:%M:%S', seconds, minutes",),
        ),
        ({"format": "%H:%M:%S"}, "format.time.format", ("reads back a date and time",)),
        ({"format": "hours", "timezone": BERLIN}, "format.time.timezone", ("elapsed time",)),
        ({"format": "epoch", "timezone": BERLIN}, "format.time.timezone", ("count in UTC",)),
        (
            {"format": GERMAN, "timezone": "Europe/Berln"},
            "format.time.timezone",
            ("not an IANA time zone name (did you mean 'Europe/Berlin'?",),
        ),
        ({"format": GERMAN, "dst": "infer"}, "format.time.dst", ("declare format.time.timezone",)),
        ({"format": GERMAN, "timezone": BERLIN, "dst": "guess"}, "format.time.dst", ("raise",)),
    ],
    ids=[
        "no-notation",
        "no-date",
        "zone-on-hours",
        "zone-on-epoch",
        "zone-typo",
        "dst-alone",
        "dst",
    ],
)
def test_a_wrong_time_declaration_is_one_line_naming_key_value_and_accepted_forms(
    tmp_path, time, key, parts
):
    vehicle = write_vehicle(tmp_path, "german-cp1252")
    edit(vehicle, lambda d: d["format"]["time"].update(time))
    with pytest.raises(ConfigError) as caught:
        load_vehicle(vehicle, workdir=tmp_path)
    text = str(caught.value)
    assert "\n" not in text and text.startswith(f"{vehicle.name}: key '{key}' = "), text
    for part in parts:
        assert part in text, text


@pytest.mark.parametrize(
    ("form", "bound", "reason"),
    [
        ("german-cp1252", 7200, "must be text: a time of the pattern '%d.%m.%Y %H:%M:%S' or an"),
        ("hours", "2024-10-24T02:00:00", "must be a number of hours (format.time.format is hours)"),
        ("german-cp1252", "24.10.2024 02:00", "not a time of the pattern"),
        ("berlin-csv", "2024-10-27T02:30:00", "occurs twice in Europe/Berlin"),
        ("berlin-csv", "2024-10-27T02:30:00", "2024-10-27T02:30:00+02:00 (the first pass)"),
        ("berlin-csv", "2024-10-27T02:30:00", "or 2024-10-27T02:30:00+01:00 (the second)"),
    ],
    ids=[
        "number-on-pattern",
        "text-on-hours",
        "other-pattern",
        "ambiguous-local-bound",
        "ambiguous-bound-first-pass",
        "ambiguous-bound-second-pass",
    ],
)
def test_a_window_bound_in_another_notation_is_named(tmp_path, form, bound, reason):
    vehicle = write_vehicle(tmp_path, form)
    edit(vehicle, lambda d: d["windows"]["identification"][0].update(start=bound))
    with pytest.raises(ConfigError) as caught:
        load_vehicle(vehicle, workdir=tmp_path)
    assert caught.value.key == "windows.identification[0].start" and reason in str(caught.value)
    assert "line 2" not in str(caught.value)  # one time, not a row of the file


def test_a_bound_with_its_offset_settles_the_repeated_hour(tmp_path):
    """A window may start inside the repeated hour when its bound carries the UTC offset."""
    vehicle = write_vehicle(tmp_path, "berlin-csv")
    edit(
        vehicle,
        lambda d: d["windows"]["identification"][0].update(start="2024-10-27T02:30:00+01:00"),
    )
    loaded = load_vehicle(vehicle, workdir=tmp_path)
    table = ingest.clean_window(tmp_path / "berlin.csv", loaded.data, "h2")
    assert table["timestamp"].iloc[0] == "2024-10-27T01:30:00+00:00"


@pytest.mark.parametrize(
    ("written", "declared", "other"),
    [
        ("hours", "seconds", "1800 s in hours"),
        ("minutes", "hours", "1800 s in minutes"),
        ("days", "seconds", "1800 s in days"),
        ("seconds", "minutes", "1800 s in seconds"),
        ("minutes", "days", "1800 s in minutes"),
    ],
)
def test_a_time_unit_declared_wrongly_is_warned_naming_the_unit(
    tmp_path, monkeypatch, capsys, written, declared, other
):
    """The same numbers in another unit give a logger step outside 1 s to 3 h: validate
    passes (the file reads) but warns, naming the declared unit and what the step would be
    in the others."""
    _, t = recording()
    factor = {"seconds": 1.0, "minutes": 60.0, "hours": 3600.0, "days": 86400.0}[written]
    numbers = t / factor
    data = yaml.safe_load(ARMADILLO.read_text(encoding="utf-8"))
    data["raw_files"] = {"h2": "logger.csv"}
    write_csv(with_time("t", [repr(x) for x in numbers.tolist()]), tmp_path / "logger.csv")
    data["format"]["time"] = {"column": "t", "format": declared}
    data["windows"]["identification"] = [
        {"name": "h2", "start": float(numbers[0]), "end": float(numbers[-1])}
    ]
    data.pop("model")
    (tmp_path / "V.yaml").write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    assert main(["validate", "V.yaml"]) == 0
    err = capsys.readouterr().err
    assert f"read as format.time.format '{declared}'" in err, err
    assert "is the time unit right?" in err and other in err, err


# ---------------------------------------------------------------------------------------------
# railtherm new-vehicle


def test_new_vehicle_detects_german_dates_and_writes_windows_in_them(tmp_path, monkeypatch):
    _, t = recording()
    raw = tmp_path / "messung.csv"
    write_csv(german(t), raw, sep=";", decimal=",")  # utf-8
    text, todos = starter_vehicle(raw, yaml_dir=tmp_path)
    data = yaml.safe_load(text)
    assert data["format"] == {
        "separator": ";",
        "decimal": ",",
        "time": {"column": "Datum/Uhrzeit", "format": GERMAN},
    }
    assert data["windows"]["identification"] == [
        {"name": "whole", "start": "24.10.2024 00:00:00", "end": "28.10.2024 20:00:00"}
    ]
    assert "# timezone: Europe/Berlin" in text and "# logger step: 1800 s" in text
    assert [todo.split(":")[0] for todo in todos] == ["class", "mass_kg", "surface_m2"]
    filled = text.replace("class: TODO", "class: other")
    filled = filled.replace("mass_kg: TODO", "mass_kg: 20000").replace(
        "surface_m2: TODO", "surface_m2: 162"
    )
    (tmp_path / "V.yaml").write_text(filled, encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    assert main(["validate", "V.yaml"]) == 0


@pytest.mark.parametrize(
    ("numbers", "note"),
    [
        (lambda t: t / 3600.0, "check the unit: seconds, minutes, hours or days elapsed"),
        (lambda t: 1729728000.0 + t, "looks like Unix time: then epoch"),
        (lambda t: 45589.0 + t / 86400.0, "looks like a spreadsheet date: then serial_days"),
    ],
    ids=["hours", "unix", "serial-days"],
)
def test_new_vehicle_reads_numbers_as_seconds_and_asks_for_the_unit(tmp_path, numbers, note):
    _, t = recording()
    raw = tmp_path / "run.csv"
    write_csv(with_time("Zeit", [repr(x) for x in numbers(t).tolist()]), raw)
    text, _ = starter_vehicle(raw, yaml_dir=tmp_path)
    line = next(line for line in text.splitlines() if line.strip().startswith("format: "))
    assert line.split("#")[0].strip() == "format: seconds" and note in line, line
    assert "# timezone" not in text  # elapsed numbers have no wall clock


def test_gzip_and_plain_german_files_hold_the_same_text(tmp_path):
    """The premise of the gzip form: the same cp1252 bytes, compressed."""
    write = forms()["german-cp1252"][1]
    write(tmp_path / "a.csv")
    write(tmp_path / "b.csv.gz")
    with gzip.open(tmp_path / "b.csv.gz", "rb") as stream:
        assert stream.read() == (tmp_path / "a.csv").read_bytes()
    assert "Temperatur au\xdfen".encode("cp1252") in (tmp_path / "a.csv").read_bytes()


# ---------------------------------------------------------------------------------------------
# docs/adding-a-vehicle.md, section 7: the spreadsheet walk-through says what validate says


def test_the_walk_through_shows_what_validate_says(tmp_path, monkeypatch, capsys):
    doc = (REPO / "docs" / "adding-a-vehicle.md").read_text(encoding="utf-8")
    section = doc[doc.index("## 7.") :]
    snippet = re.search(r"```python\n# my/make_export.py\n(.*?)```", section, re.S).group(1)
    vehicle = re.search(r"```yaml\n(id: Box_xlsx\n.*?)```", section, re.S).group(1)
    shown = re.findall(r"\$ \.venv/bin/railtherm validate my/Box_xlsx.yaml\n(.*?)\n", section)
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "armadillo").symlink_to(RAW.parent)
    (tmp_path / "my").mkdir()
    (tmp_path / "my" / "make_export.py").write_text(snippet, encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    subprocess.run([sys.executable, "my/make_export.py"], check=True)
    edits = [
        lambda text: text,
        lambda text: re.sub(r"\n    dst: infer[^\n]*", "", text),
        lambda text: text.replace('"%d.%m.%Y %H:%M:%S"', '"%d.%m.%Y %H:%M"'),
    ]
    assert len(shown) == len(edits)
    for edit_text, line in zip(edits, shown, strict=True):
        Path("my/Box_xlsx.yaml").write_text(edit_text(vehicle), encoding="utf-8")
        main(["validate", "my/Box_xlsx.yaml"])
        captured = capsys.readouterr()
        assert (captured.out + captured.err).strip() == line
