"""A lab's files as data-acquisition systems write them, generated here (not by the
synthesizer): a power analyser's tab-separated text with `#` comment lines above its header,
a tunnel controller's `;`-separated export with a decimal comma under a title and a blank
line, and a US lab's workbook that opens with a sheet of run information and has a title and
an empty row above its table. `railtherm new-vehicle` proposes the right header, separator
and columns for each (never a comment line as a column), and the reader settings it proposes
(`format.comment`, `format.header_row`) read the file, with messages that name a data row's
own line."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import numpy as np
import pytest
import yaml

from railtherm.cli import main
from railtherm.config import load_vehicle
from railtherm.data import ingest
from railtherm.data.readers import read_header
from railtherm.errors import DataError

PREAMBLE = [
    "# Power analyser PA-3000, serial 0417",
    "# channel 1: cabin heater (3~400 V)",
    "# channel 2: cabin fan",
    "# started 2024-03-05 09:57:43",
]


def cabin_record(hours: float = 12.0, step_s: float = 60.0) -> dict[str, np.ndarray]:
    """A first-order heat-up of a cabin (kA 500 W/K, C 2e7 J/K) at 12 kW in a -10 degC
    tunnel, from 14 degC: own closed form, not railtherm.synth."""
    t = np.arange(0.0, hours * 3600.0 + 1.0, step_s)
    kA, C, Q, T_o = 500.0, 2.0e7, 12000.0, -10.0
    T = T_o + Q / kA + (14.0 - T_o - Q / kA) * np.exp(-t * kA / C)
    return {"t": t, "T": T, "T_o": np.full(t.size, T_o), "Q_kW": np.full(t.size, Q / 1000.0)}


def power_meter_file(folder: Path, bad_row: int | None = None) -> Path:
    """The whole record in the analyser's layout: comment lines, a tab-separated header,
    time in seconds since its start, powers in kW."""
    r = cabin_record()
    lines = [*PREAMBLE, "t_s\tT_cabin\tT_tunnel\tP_heater_kW"]
    for i in range(r["t"].size):
        cabin = "n/a?" if i == bad_row else f"{r['T'][i]:.4f}"
        lines.append(f"{r['t'][i]:.0f}\t{cabin}\t{r['T_o'][i]:.2f}\t{r['Q_kW'][i]:.3f}")
    path = folder / "power_meter.txt"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def tunnel_file(folder: Path) -> Path:
    """A controller's export: a title, a blank line, then a `;` table with decimal commas."""
    r = cabin_record(step_s=600.0)
    start = dt.datetime(2024, 3, 5, 9, 0)
    rows = ["Climatic tunnel 2 - controller log", "", "time;T_tunnel_1;T_tunnel_2;T_Innen"]
    for i, t in enumerate(r["t"]):
        stamp = (start + dt.timedelta(seconds=float(t))).isoformat()
        values = [r["T_o"][i], r["T_o"][i] - 0.1, r["T"][i]]
        rows.append(";".join([stamp, *(f"{v:.2f}".replace(".", ",") for v in values)]))
    path = folder / "tunnel.csv"
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return path


def workbook(folder: Path) -> Path:
    """A metadata sheet first; on the data sheet a title row, an empty row, then the header
    in English with Fahrenheit and kW in the names."""
    xlsxwriter = pytest.importorskip("xlsxwriter")
    pytest.importorskip("python_calamine")
    path = folder / "us_lab.xlsx"
    book = xlsxwriter.Workbook(str(path))
    meta = book.add_worksheet("Run info")
    for i, (key, value) in enumerate(
        [("Test", "Chamber run 17"), ("Start time", "2024-03-05 09:00"), ("Operator", "J. Doe")]
    ):
        meta.write(i, 0, key)
        meta.write(i, 1, value)
    data = book.add_worksheet("Data")
    data.write(0, 0, "LRV 4 heat-up test, chamber 2")
    header = ["Date/Time", "Cabin Temp (F)", "Chamber Temp (F)", "Heater Power (kW)"]
    for c, name in enumerate(header):
        data.write(2, c, name)
    stamp = book.add_format({"num_format": "yyyy-mm-dd hh:mm:ss"})
    r = cabin_record(step_s=300.0)
    start = dt.datetime(2024, 3, 5, 9, 0)
    for i, t in enumerate(r["t"]):
        data.write_datetime(3 + i, 0, start + dt.timedelta(seconds=float(t)), stamp)
        data.write_number(3 + i, 1, r["T"][i] * 9 / 5 + 32)
        data.write_number(3 + i, 2, r["T_o"][i] * 9 / 5 + 32)
        data.write_number(3 + i, 3, r["Q_kW"][i])
    book.close()
    return path


def starter(raw: Path, out: Path, *extra: str) -> dict:
    assert main(["new-vehicle", str(raw), "--out", str(out), "--id", "Lab", *extra]) == 0
    text = out.read_text(encoding="utf-8")
    for line in PREAMBLE:  # no comment line proposed as a column or a channel
        assert line.lstrip("# ") not in text.split("raw_files:", 1)[1]
    return yaml.safe_load(text.replace("TODO", "null"))


def filled(out: Path) -> Path:
    """The starter with its TODOs filled as a user would (class, mass, surface)."""
    text = out.read_text(encoding="utf-8")
    for key, value in (("class", "tram"), ("mass_kg", "30000"), ("surface_m2", "250")):
        text = "\n".join(
            f"{key}: {value}" if line.startswith(f"{key}: TODO") else line
            for line in text.splitlines()
        )
    out.write_text(text + "\n", encoding="utf-8")
    return out


def test_comment_lines_above_a_tab_separated_header(tmp_path):
    data = starter(power_meter_file(tmp_path), tmp_path / "Lab.yaml")
    fmt = data["format"]
    assert fmt["separator"] == "\t" and fmt["comment"] == "#" and "header_row" not in fmt
    assert fmt["time"] == {"column": "t_s", "format": "seconds"}
    channels = data["channels"]
    assert channels["indoor_air"] == [{"column": "T_cabin"}]
    assert channels["outdoor_air"] == [{"column": "T_tunnel"}]
    assert channels["heater_power"] == [{"column": "P_heater_kW", "unit": "kW"}]
    vehicle = load_vehicle(filled(tmp_path / "Lab.yaml"), workdir=tmp_path)
    table = ingest.clean_window(tmp_path / "power_meter.txt", vehicle.data, "record")
    r = cabin_record()
    np.testing.assert_allclose(table["T"].to_numpy(), r["T"], atol=1e-4)
    np.testing.assert_allclose(table["Q_H"].to_numpy(), 12000.0)


def test_a_title_and_a_blank_line_above_a_semicolon_table_with_decimal_commas(tmp_path):
    data = starter(tunnel_file(tmp_path), tmp_path / "Lab.yaml")
    fmt = data["format"]
    assert (fmt["separator"], fmt["decimal"], fmt["header_row"]) == (";", ",", 2)
    assert fmt["time"]["column"] == "time" and fmt["time"]["format"] == "iso"
    assert data["channels"]["outdoor_air"] == [{"column": "T_tunnel_1"}, {"column": "T_tunnel_2"}]
    assert data["channels"]["indoor_air"] == [{"column": "T_Innen"}]
    assert read_header(tmp_path / "tunnel.csv", fmt) == (
        "time",
        "T_tunnel_1",
        "T_tunnel_2",
        "T_Innen",
    )


@pytest.mark.parametrize("given", [[], ["--sheet", "Data"]])
def test_a_workbook_with_a_run_sheet_a_title_and_an_empty_row(tmp_path, given):
    data = starter(workbook(tmp_path), tmp_path / "Lab.yaml", *given)
    fmt = data["format"]
    assert fmt["sheet"] == "Data" and fmt["header_row"] == 2
    assert fmt["time"]["column"] == "Date/Time"
    channels = data["channels"]
    assert channels["indoor_air"] == [{"column": "Cabin Temp (F)", "unit": "degF"}]
    assert channels["outdoor_air"] == [{"column": "Chamber Temp (F)", "unit": "degF"}]
    assert channels["heater_power"] == [{"column": "Heater Power (kW)", "unit": "kW"}]
    vehicle = load_vehicle(filled(tmp_path / "Lab.yaml"), workdir=tmp_path)
    table = ingest.clean_window(tmp_path / "us_lab.xlsx", vehicle.data, "record")
    np.testing.assert_allclose(table["T"].to_numpy(), cabin_record(step_s=300.0)["T"], atol=1e-6)


@pytest.mark.bad_input
def test_a_bad_value_below_comment_lines_names_its_own_line(tmp_path):
    starter(power_meter_file(tmp_path), tmp_path / "Lab.yaml")
    vehicle = load_vehicle(filled(tmp_path / "Lab.yaml"), workdir=tmp_path)
    power_meter_file(tmp_path, bad_row=10)  # the 11th data row: line 4 + 1 + 11 = 16
    with pytest.raises(DataError) as err:
        ingest.clean_window(tmp_path / "power_meter.txt", vehicle.data, "record")
    assert "line 16: not a number" in str(err.value) and "T_cabin" in str(err.value)


@pytest.mark.bad_input
def test_a_header_row_past_the_end_names_the_key(tmp_path):
    path = tunnel_file(tmp_path)
    with pytest.raises(DataError) as err:
        read_header(path, {"separator": ";", "header_row": 500})
    assert "format.header_row" in str(err.value) and "500" in str(err.value)


@pytest.mark.bad_input
def test_a_comment_character_on_a_workbook_is_refused(tmp_path):
    path = workbook(tmp_path)
    with pytest.raises(DataError) as err:
        read_header(path, {"comment": "#"})
    assert "format.comment is read by the csv reader only" in str(err.value)
