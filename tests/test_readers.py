"""Raw files of every kind read by configuration alone (railtherm.data.readers): one measured
recording (the Armadillo Box, data/armadillo) written as a cp1252 CSV with ';' and decimal
commas, gzip-compressed, as a spreadsheet, a MATLAB file and R data gives the same tidy table as
the plain CSV original; the vehicle configs differ only in their format and channel keys. Each
reader's mistakes stop with one line naming the file, the problem and the fix."""

from __future__ import annotations

import datetime as dt
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import scipy.io
import yaml

from railtherm.cli import main
from railtherm.config import load_vehicle
from railtherm.data import ingest, readers
from railtherm.data.rawfile import read_columns, read_layout
from railtherm.errors import ConfigError, DataError

python_calamine = pytest.importorskip("python_calamine")
rdata = pytest.importorskip("rdata")
pytest.importorskip("xlsxwriter")

REPO = Path(__file__).resolve().parents[1]
RAW = REPO / "data" / "armadillo" / "armadillo_data_H2.csv"
ARMADILLO = REPO / "validation" / "config" / "vehicles" / "Armadillo.yaml"
OUTSIDE = "Außentemperatur"  # a column name a cp1252 file holds as one byte per letter
START = dt.datetime(2024, 1, 16)  # the ISO forms' first timestamp


def original() -> pd.DataFrame:
    return pd.read_csv(RAW)


def write_vehicle(folder: Path, raw: str, fmt: dict | None = None, **channels: str) -> Path:
    """The Armadillo vehicle config on the raw file ``raw``: only ``format`` (the keys given
    over the original's) and the channel columns given (indoor, outdoor, heater) differ."""
    data = yaml.safe_load(ARMADILLO.read_text(encoding="utf-8"))
    data.pop("model")  # another concern: the fit
    data["raw_files"] = {"h2": raw}
    data["format"].update(fmt or {})
    for group, key in (("indoor_air", "indoor"), ("outdoor_air", "outdoor")):
        if key in channels:
            data["channels"][group] = [{"column": channels[key]}]
    if "heater" in channels:
        data["channels"]["heater_power"] = [{"column": channels["heater"], "unit": "W"}]
    path = folder / f"{Path(raw).name.split('.')[0]}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False, allow_unicode=True), encoding="utf-8")
    return path


def cleaned(vehicle_file: Path) -> pd.DataFrame:
    """What the rule clean writes for the window h2, after the validator's checks."""
    vehicle = load_vehicle(vehicle_file, workdir=vehicle_file.parent)
    raw = vehicle_file.parent / vehicle.raw_files["h2"]
    return ingest.clean_window(raw, vehicle.data, "h2", file_label="raw")


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> pd.DataFrame:
    folder = tmp_path_factory.mktemp("reference")
    return cleaned(write_vehicle(folder, str(RAW)))


# ---------------------------------------------------------------------------------------------
# The forms of one recording


def write_cp1252(folder: Path, name: str = "logger.csv") -> Path:
    path = folder / name  # .gz: compressed by the extension
    raw = original().rename(columns={"T_ext": OUTSIDE})
    raw.to_csv(path, sep=";", decimal=",", index=False, encoding="cp1252")
    return path


CP1252 = {"separator": ";", "decimal": ",", "encoding": "cp1252"}


def write_xlsx(folder: Path) -> Path:
    """The data on the second sheet, below a title and an empty row (header in row 3)."""
    path = folder / "logger.xlsx"
    with pd.ExcelWriter(path, engine="xlsxwriter") as book:
        pd.DataFrame({"Versuch": ["Armadillo H2"]}).to_excel(book, sheet_name="Info", index=False)
        original().to_excel(book, sheet_name="Messdaten", index=False, startrow=2)
        book.sheets["Messdaten"].write(0, 0, "Klimawindkanal, Lauf H2")
    return path


def write_xlsx_text(folder: Path) -> Path:
    """The data as text cells with decimal commas, as a German workbook export holds them."""
    path = folder / "logger_text.xlsx"
    text = original().apply(lambda c: c.map(lambda v: repr(float(v)).replace(".", ",")))
    with pd.ExcelWriter(path, engine="xlsxwriter") as book:
        text.to_excel(book, sheet_name="Messdaten", index=False)
    return path


def write_mat(folder: Path) -> Path:
    raw = original()
    path = folder / "logger.mat"
    columns = {c: raw[c].to_numpy() for c in raw.columns}
    scipy.io.savemat(path, {"messung": columns, "M": raw.to_numpy(), "note": "H2"})
    return path


def write_rda(folder: Path) -> Path:
    path = folder / "logger.rda"
    rdata.write_rda(path, {"logger": original(), "note": ["Armadillo H2"]})
    return path


def write_rds(folder: Path) -> Path:
    path = folder / "logger.rds"
    rdata.write_rds(path, original())
    return path


FORMS = {
    "cp1252": (lambda f: write_cp1252(f), CP1252, {"outdoor": OUTSIDE}),
    "gzip": (lambda f: write_cp1252(f, "logger.csv.gz"), CP1252, {"outdoor": OUTSIDE}),
    "xlsx": (write_xlsx, {"sheet": "Messdaten", "header_row": 2}, {}),
    "xlsx-index": (write_xlsx, {"sheet": 1, "header_row": 2}, {}),
    # decimal "," alone: a workbook has no separator to clash with (it was refused as the
    # default separator's twin)
    "xlsx-text-comma": (write_xlsx_text, {"sheet": "Messdaten", "decimal": ","}, {}),
    "mat-struct": (write_mat, {"variable": "messung"}, {}),
    "mat-matrix": (write_mat, {"variable": "M", "columns": list(original().columns)}, {}),
    "rda": (write_rda, {}, {}),
    "rda-named": (write_rda, {"reader": "r", "variable": "logger"}, {}),
    "rds": (write_rds, {}, {}),
}


@pytest.mark.parametrize("form", list(FORMS))
def test_every_form_gives_the_tidy_table_of_the_csv_original(tmp_path, form, reference):
    write, fmt, channels = FORMS[form]
    raw = write(tmp_path)
    table = cleaned(write_vehicle(tmp_path, raw.name, fmt, **channels))
    pd.testing.assert_frame_equal(table, reference, check_exact=False, rtol=1e-9, atol=0)


@pytest.mark.parametrize("form", ["cp1252", "gzip", "mat-struct", "mat-matrix", "rda", "rds"])
def test_binary_and_text_forms_give_the_csv_cells_exactly(tmp_path, form):
    """The cells as text: the CSV original's text for every value, so the numbers parse to
    the same floats bit for bit (a MATLAB or R double written as its repr)."""
    write, fmt, _ = FORMS[form]
    path = write(tmp_path)
    text = readers.read_table(path, fmt).rename(columns={OUTSIDE: "T_ext"})
    if fmt.get("decimal") == ",":
        text = text.apply(lambda c: c.str.replace(",", ".", regex=False))
    expected = readers.read_table(RAW, {})
    assert text.dtypes.tolist() == expected.dtypes.tolist()  # the dtype read_csv(dtype=str) gives
    pd.testing.assert_frame_equal(text, expected)


def test_spreadsheet_numbers_come_back_bit_for_bit(tmp_path):
    """Every number calamine reads from a workbook parses back from its text to the same
    float (the writer, xlsxwriter, keeps 16 digits: the file holds what it holds)."""
    rng = np.random.default_rng(7)
    values = rng.standard_normal(2000) * 10.0 ** rng.integers(-9, 9, 2000)
    path = tmp_path / "numbers.xlsx"
    pd.DataFrame({"x": values}).to_excel(path, index=False, engine="xlsxwriter")
    held = [row[0] for row in read_sheet(path)[1:]]
    text = readers.read_table(path, {})["x"]
    got = pd.to_numeric(text).to_numpy()
    assert np.array_equal(got.view(np.int64), np.array(held, dtype=float).view(np.int64))


def read_sheet(path: Path) -> list[list]:
    book = python_calamine.CalamineWorkbook.from_path(str(path))
    try:
        return book.get_sheet_by_index(0).to_python()
    finally:
        book.close()


def test_spreadsheet_dates_are_iso_timestamps(tmp_path, reference):
    """Date cells as ISO 8601 text: an iso vehicle on a spreadsheet cleans like one on the
    CSV file of the same timestamps as text."""
    raw = original()
    stamps = [START + dt.timedelta(seconds=float(s)) for s in raw["Time"]]
    iso = {"time": {"column": "Zeit", "format": "iso"}}
    csv = raw.drop(columns="Time").assign(Zeit=[s.isoformat() for s in stamps])
    csv.to_csv(tmp_path / "iso.csv", index=False)
    book = raw.drop(columns="Time").assign(Zeit=stamps)
    book.to_excel(tmp_path / "iso.xlsx", index=False, engine="xlsxwriter")
    tables = []
    for name in ("iso.csv", "iso.xlsx"):
        vehicle = write_vehicle(tmp_path, name, iso)
        data = yaml.safe_load(vehicle.read_text(encoding="utf-8"))
        end = START + dt.timedelta(seconds=data["windows"]["identification"][0]["end"])
        data["windows"]["identification"][0].update(start=START.isoformat(), end=end.isoformat())
        vehicle.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
        tables.append(cleaned(vehicle))
    assert readers.read_table(tmp_path / "iso.xlsx", {})["Zeit"].iloc[1] == "2024-01-16T00:30:00"
    pd.testing.assert_frame_equal(tables[1], tables[0])
    numbers = [c for c in reference.columns if c != "timestamp"]
    pd.testing.assert_frame_equal(tables[1][numbers], reference[numbers], rtol=1e-9)


def test_headers_and_layouts_agree_across_forms(tmp_path):
    names = tuple(original().columns)
    layout = read_layout(RAW, time_column="Time", time_format="seconds")
    for form in ("xlsx", "mat-struct", "rds"):
        write, fmt, _ = FORMS[form]
        path = write(tmp_path)
        full = {**fmt, "time": {"column": "Time", "format": "seconds"}}
        assert readers.read_header(path, fmt) == names
        assert read_columns(path, fmt=fmt) == names
        got = read_layout(path, fmt=full)
        assert (got.columns, got.t_first, got.t_last, got.step_s) == (
            layout.columns,
            layout.t_first,
            layout.t_last,
            layout.step_s,
        )
        only = readers.read_table(path, fmt, columns=["T_int"])
        assert list(only.columns) == ["T_int"] and len(only) == len(original())


def test_the_reader_follows_the_suffix_unless_declared():
    assert readers.reader_kind("a/b.CSV.gz") == "csv"
    assert readers.reader_kind("b.dat") == "csv"
    assert readers.reader_kind("b.xlsm") == "excel"
    assert readers.reader_kind("b.RData") == "r"
    assert readers.reader_kind("b.mat") == "matlab"
    assert readers.reader_kind("b.bin", {"reader": "matlab"}) == "matlab"


@pytest.mark.parametrize("form", ["cp1252", "gzip", "xlsx", "mat-struct", "rda", "rds"])
def test_validate_accepts_each_form(tmp_path, monkeypatch, capsys, form):
    write, fmt, channels = FORMS[form]
    raw = write(tmp_path)
    vehicle = write_vehicle(tmp_path, raw.name, fmt, **channels)
    monkeypatch.chdir(tmp_path)
    assert main(["validate", vehicle.name]) == 0, capsys.readouterr().err
    assert capsys.readouterr().out == "ok: 1 vehicle, values of 1 window checked\n"


# ---------------------------------------------------------------------------------------------
# Mistakes: one line naming the file, what is wrong and the fix


def one_line(err: pytest.ExceptionInfo, path: Path | str, *parts: str) -> str:
    text = str(err.value)
    assert "\n" not in text and str(path) in text, text
    for part in parts:
        assert part in text, text
    return text


def test_a_wrong_sheet_is_named_with_the_sheets_there(tmp_path):
    path = write_xlsx(tmp_path)
    with pytest.raises(DataError) as err:
        readers.read_table(path, {"sheet": "Daten"})
    one_line(err, path, "no sheet 'Daten'", "'Info', 'Messdaten'", "set format.sheet")
    with pytest.raises(DataError) as err:
        readers.read_header(path, {"sheet": 2})
    one_line(err, path, "no sheet 2", "counts from 0")
    with pytest.raises(DataError) as err:  # the title row is no header with the channels
        ingest.read_raw(path, {"sheet": 1, "time": {"column": "Time", "format": "seconds"}})
    one_line(err, path, "time column not found", "Klimawindkanal")


@pytest.mark.bad_input
def test_a_column_on_another_sheet_or_row_names_where_it_is(tmp_path):
    """A workbook whose data sheet is not the first and has a title row: the messages say
    on which sheet and row the column is, and which settings read it there."""
    write_xlsx(tmp_path)
    vehicle = write_vehicle(tmp_path, "logger.xlsx")  # neither sheet nor header_row declared
    with pytest.raises(ConfigError) as err:
        load_vehicle(vehicle, workdir=tmp_path)
    one_line(err, "logger.yaml", "it is on sheet 'Messdaten', row 3", "format.header_row: 2")
    path = tmp_path / "logger.xlsx"
    with pytest.raises(DataError) as err:
        ingest.read_raw(path, {"sheet": 1, "time": {"column": "Time", "format": "seconds"}})
    one_line(err, path, "time column not found", "set format.sheet: 'Messdaten'")


def test_a_wrong_sheet_stops_the_validator_naming_config_and_file(tmp_path):
    write_xlsx(tmp_path)
    vehicle = write_vehicle(tmp_path, "logger.xlsx", {"sheet": "Daten"})
    with pytest.raises(ConfigError) as err:
        load_vehicle(vehicle, workdir=tmp_path)
    text = one_line(err, "logger.yaml", "no sheet 'Daten'", "set format.sheet")
    assert text.startswith("logger.yaml: key 'raw_files.h2' = 'logger.xlsx': logger.xlsx: ")


def test_a_header_row_past_the_end_is_named(tmp_path):
    path = write_xlsx(tmp_path)
    with pytest.raises(DataError) as err:
        readers.read_header(path, {"sheet": "Info", "header_row": 5})
    one_line(err, path, "sheet 'Info' has 2 rows", "format.header_row")


@pytest.mark.parametrize(
    ("write", "fmt", "parts"),
    [
        (write_mat, {"variable": "messdaten"}, ("no variable 'messdaten'", "messung, M, note")),
        (write_mat, {}, ("holds 3 variables", "set format.variable")),
        (write_mat, {"variable": "M"}, ("without column names", "format.columns (5 names")),
        (write_mat, {"variable": "M", "columns": ["a", "b"]}, ("names 2 columns", "has 5")),
        (write_rda, {"variable": "log"}, ("no object 'log'", "logger, note")),
        (write_rda, {"variable": "note"}, ("'note' is a list, not a data frame",)),
        (write_rds, {"variable": "logger"}, ("holds one object", "remove format.variable")),
    ],
    ids=[
        "mat-unknown",
        "mat-several",
        "mat-no-names",
        "mat-names",
        "rda-unknown",
        "rda-no-frame",
        "rds-variable",
    ],
)
def test_an_unknown_or_unfit_variable_is_named(tmp_path, write, fmt, parts):
    path = write(tmp_path)
    with pytest.raises(DataError) as err:
        readers.read_table(path, fmt)
    one_line(err, path, *parts)


def test_a_matlab_v73_file_says_so(tmp_path):
    """A v7.3 file is HDF5 behind MATLAB's 128-byte header (version 0x0200): the header is all
    the reader looks at before it stops."""
    text = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Tue Jan 16 08:00:00 2024 HDF5"
    header = text.ljust(116, b" ") + b"\0" * 8 + b"\x00\x02" + b"IM"
    path = tmp_path / "logger.mat"
    path.write_bytes(header + b"\x89HDF\r\n\x1a\n" + b"\0" * 504)
    with pytest.raises(DataError) as err:
        readers.read_header(path, {"variable": "messung"})
    one_line(err, path, "v7.3 (HDF5)", "'-v7'")


@pytest.mark.parametrize(
    ("module", "write", "fmt"),
    [("python_calamine", write_xlsx, {}), ("rdata", write_rds, {})],
    ids=["excel", "r"],
)
def test_a_missing_extra_is_named(tmp_path, monkeypatch, module, write, fmt):
    path = write(tmp_path)
    monkeypatch.setitem(sys.modules, module, None)  # import fails as without the package
    with pytest.raises(DataError) as err:
        readers.read_table(path, fmt)
    one_line(err, path, module.replace("_", "-"), "pip install 'railtherm[formats]'")


def test_a_cp1252_file_read_as_utf8_names_the_encoding(tmp_path):
    path = write_cp1252(tmp_path)
    with pytest.raises(DataError) as err:
        readers.read_header(path, {"separator": ";"})
    one_line(err, path, "not utf-8 text (byte 0xdf", "set format.encoding")
    with pytest.raises(DataError) as err:
        readers.read_header(path, {"separator": ";", "encoding": "cp-1252x"})
    one_line(err, path, "no known text encoding")


def test_a_key_of_another_reader_is_a_mistake(tmp_path):
    with pytest.raises(DataError) as err:
        readers.read_header(RAW, {"sheet": "Messdaten"})
    one_line(err, RAW, "format.sheet is read by the excel reader only", "by its suffix .csv")


@pytest.mark.parametrize("name", ["logger.xlsx", "logger.mat", "logger.rds"])
def test_a_file_of_another_kind_is_named(tmp_path, name):
    path = tmp_path / name
    path.write_text("Time,T_int\n0,20\n", encoding="utf-8")
    with pytest.raises(DataError) as err:
        readers.read_header(path, {})
    one_line(err, path, "cannot read the file as", "is format.reader right?")


def test_matlab_struct_fields_must_be_columns_of_one_length(tmp_path):
    path = tmp_path / "logger.mat"
    scipy.io.savemat(path, {"s": {"Time": np.arange(3.0), "T_int": np.arange(4.0)}})
    with pytest.raises(DataError) as err:
        readers.read_table(path, {})
    one_line(err, path, "'T_int'", "has 4 values where 'Time' has 3")


@pytest.mark.bad_input
@pytest.mark.parametrize(
    "rows",
    ["0,20,5,-10.0,1000\n60,20,6,-10.0,1000\n", "0,20.5,-10.0,1000\n60,20,6,-10.0,1000\n"],
    ids=["first-row-longer", "later-row-longer"],
)
def test_a_decimal_comma_in_a_comma_separated_file_is_named_not_shifted(tmp_path, rows):
    """An unquoted 20,5 in a file separated by ',' makes a row longer than the header: pandas
    would drop the first field with a warning and shift every value; refused, naming the
    separator and decimal settings."""
    path = tmp_path / "shifted.csv"
    path.write_text("time,T_in,T_out,P\n" + rows)
    fmt = {"separator": ",", "decimal": ".", "time": {"column": "time", "format": "seconds"}}
    with pytest.raises(DataError) as err:
        ingest.read_raw(path, fmt)
    one_line(err, path, "a decimal comma in a file separated by ','", "format.separator")
