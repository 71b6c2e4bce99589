"""Bad inputs as a new user makes them, through `railtherm validate`.

One small study (two vehicles on one raw file, see test_cli.setup_repo) is broken one way per
case: in a raw file, a vehicle config, the study config. Each case must exit 1 before any job
with one line on stderr naming the file, the key or column, and the value (the fragments
listed), and nothing on stdout. The values of the raw files are read as the jobs `clean` and
`kvalue` read them, so whatever those jobs stop on, validate stops on first. Numerical faults
that only a fit reveals are at the end: each must leave a flag or a reason in the verdict,
never "fit acceptable" beside a wrong number.
"""

from __future__ import annotations

import copy
import gzip
import os
from collections.abc import Callable

import pytest
import yaml
from test_cli import setup_repo, write_study
from test_config import COLUMNS, RAW_FILE, VEHICLE, VEHICLE_FILE, csv_text, write_raw

from railtherm.cli import main

pytestmark = pytest.mark.bad_input

V2_FILE = "config/vehicles/V2.yaml"


# ---------------------------------------------------------------------------------------------
# editing the study


def rows() -> list[list[str]]:
    """The cells of the raw file as it is now (edits compose)."""
    with open(RAW_FILE, encoding="utf-8") as stream:
        return [line.split(",") for line in stream.read().splitlines()]


def write_rows(table: list[list[str]], path: str = RAW_FILE, sep: str = ",") -> None:
    write_raw("\n".join(sep.join(r) for r in table) + "\n", path)


def cell(row: int, column: str, value: str) -> Callable[[], None]:
    """Data row ``row`` (0-based; file line row + 2) of ``column`` set to ``value``."""

    def edit():
        table = rows()
        table[row + 1][COLUMNS.index(column)] = value
        write_rows(table)

    return edit


def column_values(column: str, f: Callable[[float], str]) -> Callable[[], None]:
    def edit():
        table = rows()
        j = COLUMNS.index(column)
        for r in table[1:]:
            r[j] = f(float(r[j]))
        write_rows(table)

    return edit


def vehicle(edit: Callable[[dict], None], path: str = VEHICLE_FILE) -> Callable[[], None]:
    def apply():
        data = copy.deepcopy(VEHICLE)
        if path == V2_FILE:
            data["id"] = "V2"
        edit(data)
        with open(path, "w", encoding="utf-8") as stream:
            yaml.safe_dump(data, stream, sort_keys=False)

    return apply


def vehicle_text(text: str) -> Callable[[], None]:
    def apply():
        with open(VEHICLE_FILE, "w", encoding="utf-8") as stream:
            stream.write(text)

    return apply


def study(**extra) -> Callable[[], None]:
    return lambda: write_study([VEHICLE_FILE, V2_FILE], **extra)


def study_text(text: str) -> Callable[[], None]:
    def apply():
        with open("config/config.yaml", "w", encoding="utf-8") as stream:
            stream.write(text)

    return apply


def setting(path: str, value) -> Callable[[dict], None]:
    """Set a dotted key of a vehicle config (list items as [i])."""

    def edit(data):
        keys = path.replace("[", ".").replace("]", "").split(".")
        node = data
        for k in keys[:-1]:
            node = node[int(k)] if k.isdigit() else node.setdefault(k, {})
        last = keys[-1]
        if last.isdigit():
            node[int(last)] = value
        else:
            node[last] = value

    return edit


def both(*edits: Callable[[], None]) -> Callable[[], None]:
    def apply():
        for e in edits:
            e()

    return apply


def swap_columns(a: str, b: str) -> Callable[[], None]:
    def edit():
        table = rows()
        i, j = COLUMNS.index(a), COLUMNS.index(b)
        for r in table[1:]:
            r[i], r[j] = r[j], r[i]
        write_rows(table)

    return edit


def truncated_gzip():
    data = gzip.compress(csv_text().encode())
    with open("data/V1.csv.gz", "wb") as stream:
        stream.write(data[: len(data) // 2])
    vehicle(setting("raw_files.cwt", "../../data/V1.csv.gz"))()


def alias_bomb():
    lines = ['a0: &a0 ["x", "x", "x", "x", "x", "x", "x", "x", "x", "x"]']
    for i in range(1, 9):
        lines.append(f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]")
    vehicle_text("\n".join(lines) + "\n")()


def remove(path: str) -> Callable[[], None]:
    return lambda: os.remove(path)


def rows_with_gap(first: int, last: int, column: str) -> Callable[[], None]:
    def edit():
        table = rows()
        j = COLUMNS.index(column)
        for r in table[first + 1 : last + 2]:
            r[j] = ""
        write_rows(table)

    return edit


# (case, edit, fragments of the one-line message)
CASES = [
    # --- raw files: reading
    ("raw file missing", remove(RAW_FILE), ["data/V1.csv", "raw_files.cwt", "not found"]),
    ("raw file empty", lambda: write_raw(""), ["data/V1.csv", "empty"]),
    (
        "header only",
        lambda: write_raw(",".join(COLUMNS) + "\n"),
        ["V1.yaml", "raw_files.cwt", "data/V1.csv: the file has a header but no data rows"],
    ),
    (
        "semicolon file read with commas",
        lambda: write_rows(rows(), sep=";"),
        ["data/V1.csv", "format.time.column", "is format.separator ';'"],
    ),
    ("truncated gzip", truncated_gzip, ["data/V1.csv.gz", "truncated"]),
    (
        "decimal comma declared as point",
        both(
            lambda: write_rows([[c.replace(".", ",") for c in r] for r in rows()], sep=";"),
            vehicle(setting("format.separator", ";")),
            vehicle(setting("format.separator", ";"), path=V2_FILE),
        ),
        ["data/V1.csv", "T_in_1", "'21,00'", "line 2", "format.decimal: ','"],
    ),
    (
        "channel column missing",
        vehicle(setting("channels.indoor_air[0].column", "t_in_1")),
        ["V1.yaml", "channels.indoor_air[0].column", "'t_in_1'", "did you mean 'T_in_1'"],
    ),
    (
        "time column missing",
        vehicle(setting("format.time.column", "Time")),
        ["V1.yaml", "format.time.column", "'Time'"],
    ),
    # --- raw files: time
    (
        "local date format declared iso",
        cell(3, "time", "01.01.2024 00:03:00"),
        ["data/V1.csv", "time", "'01.01.2024 00:03:00'", "line 5"],
    ),
    ("time going backwards", cell(5, "time", "2024-01-01T00:01:00"), ["data/V1.csv", "time"]),
    ("duplicated time", cell(5, "time", "2024-01-01T00:04:00"), ["data/V1.csv", "time"]),
    (
        "year typo in the last row",
        cell(9, "time", "2034-01-01T00:09:00"),
        ["data/V1.csv", "5,000,000"],
    ),
    (
        "stamp without offset among offsets",
        lambda: write_rows(
            [rows()[0]] + [[r[0] + "+01:00", *r[1:]] for r in rows()[1:9]] + rows()[9:]
        ),
        ["data/V1.csv", "time", "offset"],
    ),
    # --- raw files: values, as the clean job reads them
    ("text in a channel", cell(2, "T_in_1", "err"), ["data/V1.csv", "T_in_1", "'err'", "line 4"]),
    ("inf in indoor air", cell(6, "T_in_2", "inf"), ["data/V1.csv", "T_in_2", "line 8"]),
    ("-inf in power", cell(1, "P_heat_1", "-inf"), ["data/V1.csv", "P_heat_1", "line 3"]),
    ("Infinity in surface", cell(4, "T_surf", "Infinity"), ["data/V1.csv", "T_surf", "line 6"]),
    ("sensor stuck at -999", cell(3, "T_out", "-999"), ["data/V1.csv", "T_out", "-999"]),
    ("spike of 850 degC", cell(7, "T_in_1", "850"), ["data/V1.csv", "T_in_1", "850"]),
    (
        "kelvin declared degC",
        column_values("T_surf", lambda v: f"{v + 273.15:.2f}"),
        ["data/V1.csv", "T_surf", "kelvin"],
    ),
    (
        "long gap in a channel",
        both(rows_with_gap(2, 6, "T_out"), vehicle(setting("cleaning.max_gap_s", 120))),
        ["data/V1.csv", "T_out", "gap"],
    ),
    (
        "power and outdoor columns swapped",
        swap_columns("T_out", "P_heat_1"),
        ["data/V1.csv", "windows.kvalue", "swapped"],
    ),
    (
        "outdoor warmer than indoor in the k window",
        column_values("T_out", lambda v: f"{v + 40:.2f}"),
        ["data/V1.csv", "windows.kvalue", "T - T_o", "must be > 0"],
    ),
    (
        "no heating in the k window",
        both(*(column_values(c, lambda v: "0") for c in ("P_heat_1", "P_heat_2", "P_fan"))),
        ["data/V1.csv", "windows.kvalue", "Q_H"],
    ),
    # --- vehicle config: YAML
    ("YAML syntax", vehicle_text("id: V1\nclass: [tram\n"), ["V1.yaml", "line"]),
    (
        "duplicate key",
        vehicle_text(yaml.safe_dump(VEHICLE, sort_keys=False) + "mass_kg: 1\n"),
        ["V1.yaml", "mass_kg", "duplicate"],
    ),
    ("alias bomb", alias_bomb, ["V1.yaml", "100,000"]),
    ("not a mapping", vehicle_text("- V1\n"), ["V1.yaml", "mapping"]),
    # --- vehicle config: keys and types
    (
        "unknown key",
        vehicle(setting("colour", "red")),
        ["V1.yaml", "'colour'", "'red'", "unknown key"],
    ),
    ("missing mass", vehicle(lambda d: d.pop("mass_kg")), ["V1.yaml", "mass_kg"]),
    ("text mass", vehicle(setting("mass_kg", "heavy")), ["V1.yaml", "mass_kg", "'heavy'"]),
    ("negative mass", vehicle(setting("mass_kg", -1)), ["V1.yaml", "mass_kg", "-1", "> 0"]),
    ("unknown class", vehicle(setting("class", "bus")), ["V1.yaml", "class", "'bus'"]),
    (
        "misspelt section",
        vehicle(setting("windws", {})),
        ["V1.yaml", "'windws'", "did you mean 'windows'"],
    ),
    (
        "power unit unknown",
        vehicle(setting("channels.heater_power[0].unit", "PS")),
        ["V1.yaml", "channels.heater_power[0].unit", "'PS'"],
    ),
    (
        "duplicate id",
        vehicle(setting("id", "V1"), path=V2_FILE),
        ["V2.yaml", "id", "'V1'", "duplicate"],
    ),
    # --- vehicle config: numbers a schema lets through
    ("nan surface", vehicle(setting("surface_m2", float("nan"))), ["V1.yaml", "surface_m2"]),
    ("inf mass", vehicle(setting("mass_kg", float("inf"))), ["V1.yaml", "mass_kg"]),
    (
        "nan weight",
        vehicle(setting("channels.indoor_air[1].weight", float("nan"))),
        ["V1.yaml", "channels.indoor_air[1].weight"],
    ),
    (
        "inf initial value",
        vehicle(setting("model.initial.C", float("inf"))),
        ["V1.yaml", "model.initial.C"],
    ),
    ("zero weight", vehicle(setting("channels.indoor_air[1].weight", 0)), ["V1.yaml", "weight"]),
    (
        "bounds reversed",
        vehicle(setting("model.bounds.C", [1e10, 1e4])),
        ["V1.yaml", "model.bounds.C"],
    ),
    (
        "initial outside bounds",
        vehicle(setting("model.initial.C", 1.0)),
        ["V1.yaml", "model.initial.C", "1"],
    ),
    # --- vehicle config: windows and sizes
    (
        "window ends before it starts",
        vehicle(setting("windows.identification[0].end", "2024-01-01T00:01:00")),
        ["V1.yaml", "windows.identification[0]"],
    ),
    (
        "window outside the data",
        vehicle(setting("windows.identification[0].end", "2024-01-01T00:10:00")),
        ["V1.yaml", "windows.identification[0].end", "outside the data"],
    ),
    (
        "window shorter than one logger step",
        vehicle(setting("windows.kvalue.end", "2024-01-01T00:00:30")),
        ["V1.yaml", "windows.kvalue", "3 logger steps"],
    ),
    (
        "two-row window",
        vehicle(setting("windows.kvalue.end", "2024-01-01T00:01:00")),
        ["V1.yaml", "windows.kvalue", "3 logger steps"],
    ),
    (
        "window start not a time",
        vehicle(setting("windows.kvalue.start", "yesterday")),
        ["V1.yaml", "windows.kvalue.start", "'yesterday'"],
    ),
    (
        "resampling step far too small",
        vehicle(setting("cleaning.step_s", 0.0001)),
        ["V1.yaml", "cleaning.step_s", "5,000,000"],
    ),
    (
        "unknown window file",
        vehicle(setting("windows.identification[0].file", "other")),
        ["V1.yaml", "windows.identification[0].file", "'other'"],
    ),
    (
        "duplicate window names",
        vehicle(
            setting(
                "windows.identification",
                [
                    {"name": "run1", "start": "2024-01-01T00:00:00", "end": "2024-01-01T00:04:00"},
                    {"name": "run1", "start": "2024-01-01T00:04:00", "end": "2024-01-01T00:09:00"},
                ],
            )
        ),
        ["V1.yaml", "windows.identification", "'run1'"],
    ),
    (
        "temperature range reversed",
        vehicle(setting("cleaning.temperature_range_degC", [120, -80])),
        ["V1.yaml", "cleaning.temperature_range_degC"],
    ),
    # --- study config
    ("study: unknown key", study(default={}), ["config.yaml", "'default'", "'defaults'"]),
    (
        "study: misspelt defaults section",
        study(defaults={"modle": {}}),
        ["config.yaml", "defaults.modle", "did you mean 'model'"],
    ),
    ("study: no vehicles", study_text("vehicles: []\n"), ["config.yaml", "vehicles"]),
    (
        "study: vehicle file missing",
        lambda: write_study([VEHICLE_FILE, "config/vehicles/V3.yaml"]),
        ["config.yaml", "vehicles[1]", "V3.yaml", "not found"],
    ),
    (
        "study: campaign missing",
        study(campaign="config/campaign.yaml"),
        ["config.yaml", "campaign", "not found"],
    ),
    (
        "study: nan in defaults",
        study(defaults={"model": {"initial": {"C": float("nan")}}}),
        ["config.yaml", "defaults.model.initial.C"],
    ),
    (
        "study: bad default order",
        study(defaults={"model": {"orders": [3]}}),
        ["config.yaml", "defaults.model.orders"],
    ),
]


@pytest.mark.parametrize(("edit", "fragments"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_validate_stops_with_one_line_naming_file_key_and_value(
    tmp_path, monkeypatch, capsys, edit, fragments
):
    monkeypatch.chdir(tmp_path)
    setup_repo(tmp_path)
    assert main(["validate"]) == 0, capsys.readouterr().err  # the study is fine
    capsys.readouterr()
    edit()
    assert main(["validate"]) == 1
    out, err = capsys.readouterr()
    assert out == ""
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for fragment in fragments:
        assert fragment in err, (fragment, err)


def test_the_catalogue_is_large_enough():
    assert len(CASES) >= 55 and len({c[0] for c in CASES}) == len(CASES)


def test_trailing_separators_and_mixed_offsets_are_read_not_refused(tmp_path, monkeypatch, capsys):
    """Two look-alikes that are valid: a separator at every line end, and UTC offsets that
    change within the file (a daylight-saving change), compared in UTC."""
    monkeypatch.chdir(tmp_path)
    setup_repo(tmp_path)
    write_raw("\n".join(line + "," for line in csv_text().splitlines()) + "\n")
    assert main(["validate"]) == 0
    table = rows()
    for i, r in enumerate(table[1:]):
        r[0] += "+01:00" if i < 5 else "+02:00"
        # one hour later on the wall clock from row 5 on: the same instants
        if i >= 5:
            r[0] = r[0].replace("T00:", "T01:")
    write_rows(table)
    capsys.readouterr()
    for w in ("V1.yaml", "V2.yaml"):
        data = copy.deepcopy(VEHICLE)
        data["id"] = w[:2]
        data["windows"] = {
            "kvalue": {"start": "2024-01-01T00:00:00+01:00", "end": "2024-01-01T00:04:00+01:00"},
            "identification": [
                {
                    "name": "run1",
                    "start": "2024-01-01T00:02:00+01:00",
                    "end": "2024-01-01T01:09:00+02:00",
                }
            ],
        }
        with open(f"config/vehicles/{w}", "w", encoding="utf-8") as stream:
            yaml.safe_dump(data, stream, sort_keys=False)
    assert main(["validate"]) == 0, capsys.readouterr().err


def test_headers_only_validate_leaves_values_to_the_jobs(tmp_path, monkeypatch, capsys):
    """What Snakemake's parse reads of a campaign file not yet written: headers and times."""
    monkeypatch.chdir(tmp_path)
    setup_repo(tmp_path)
    cell(6, "T_in_2", "inf")()
    assert main(["validate", "--headers-only"]) == 0
    assert main(["validate"]) == 1


def test_value_check_is_cached_by_content(tmp_path, monkeypatch):
    """The parse-time value check re-reads a study only when a config or raw byte changed."""
    from railtherm.config import load_study, read_yaml
    from railtherm.data import datacheck
    from railtherm.data.rawfile import DigestCache
    from railtherm.errors import DataError

    monkeypatch.chdir(tmp_path)
    setup_repo(tmp_path)

    def run():
        s = load_study(read_yaml("config/config.yaml"))
        return datacheck.check_study_values(s, DigestCache(), ".cache/values.json")

    assert run() == ["V1", "V2"]
    assert run() == []
    cell(6, "T_in_2", "inf")()
    with pytest.raises(DataError, match="T_in_2"):
        run()
    write_raw(csv_text())
    assert run() == []  # the same bytes as before: checked then
    skip = datacheck.check_study_values(
        load_study(read_yaml("config/config.yaml")),
        DigestCache(),
        ".cache/other.json",
        skip=lambda path: path.startswith("data"),
    )
    assert skip == []


def test_hours_declared_as_seconds_are_named_as_the_suspect(tmp_path, monkeypatch, capsys):
    """A record in elapsed hours declared seconds: every step is 1/60 "s". Validate warns
    (a 0.0167 s thermal logger is implausible) and names the time unit."""
    monkeypatch.chdir(tmp_path)
    setup_repo(tmp_path)
    table = rows()
    for i, r in enumerate(table[1:]):
        r[0] = repr(i / 60.0)  # hours
    write_rows(table)
    windows = {
        "kvalue": {"start": 0, "end": 4 / 60},
        "identification": [{"name": "run1", "start": 2 / 60, "end": 9 / 60}],
    }

    def edit(data):
        setting("format.time", {"column": "time", "format": "seconds"})(data)
        setting("windows", windows)(data)

    for path in (VEHICLE_FILE, V2_FILE):
        vehicle(edit, path=path)()
    assert main(["validate"]) == 0
    err = capsys.readouterr().err
    assert "warning: config/vehicles/V1.yaml: raw file data/V1.csv" in err
    assert "every 0.0166667 s" in err and "is the time unit right?" in err
