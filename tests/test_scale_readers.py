"""A raw file shared by many vehicles is parsed once per process, and never served stale."""

import os

import pandas as pd

from railtherm.data import readers

FMT = {"separator": ",", "decimal": ".", "time": {"column": "t", "format": "seconds"}}


def counting_read_csv(monkeypatch) -> list[str]:
    calls: list[str] = []
    real = pd.read_csv

    def read_csv(path, *args, **kwargs):
        calls.append(str(path))
        return real(path, *args, **kwargs)

    monkeypatch.setattr(readers.pd, "read_csv", read_csv)
    return calls


def test_a_shared_file_is_parsed_once_and_each_caller_gets_its_own_copy(tmp_path, monkeypatch):
    raw = tmp_path / "shared.csv"
    raw.write_text("t,T\n0,1.5\n60,2.5\n", encoding="utf-8")
    calls = counting_read_csv(monkeypatch)
    first = readers.read_table(raw, FMT)
    first["T"] = "changed by the first caller"
    for _ in range(5):  # five more vehicles reading the same file
        again = readers.read_table(raw, FMT)
        assert list(again["T"]) == ["1.5", "2.5"]
        assert readers.read_header(raw, FMT) == ("t", "T")
    assert calls.count(str(raw)) == 2  # the table once, the header once


def test_a_file_rewritten_in_place_with_the_same_size_and_times_is_read_anew(tmp_path):
    raw = tmp_path / "record.csv"
    raw.write_text("t,T\n0,1.5\n60,2.5\n", encoding="utf-8")
    stat = os.stat(raw)
    assert list(readers.read_table(raw, FMT)["T"]) == ["1.5", "2.5"]
    with open(raw, "r+", encoding="utf-8") as stream:  # same inode, same size
        stream.write("t,T\n0,9.5\n60,8.5\n")
    os.utime(raw, ns=(stat.st_atime_ns, stat.st_mtime_ns))  # and the old mtime
    assert list(readers.read_table(raw, FMT)["T"]) == ["9.5", "8.5"]
    assert list(readers.read_table(raw, FMT, columns=["T"])["T"]) == ["9.5", "8.5"]


def test_other_options_or_columns_are_other_reads(tmp_path):
    raw = tmp_path / "semi.csv"
    raw.write_text("t;T\n0;1,5\n", encoding="utf-8")
    assert readers.read_header(raw, FMT) == ("t;T",)
    assert readers.read_header(raw, {**FMT, "separator": ";"}) == ("t", "T")
    assert list(readers.read_table(raw, {**FMT, "separator": ";"}, columns=["t"])) == ["t"]
