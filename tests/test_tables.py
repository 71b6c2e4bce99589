"""railtherm.report.tables: CSV tables at a fixed number of significant digits, written
atomically."""

from __future__ import annotations

import math
import os

import numpy as np
import pandas as pd
import pytest
from hypothesis import given
from hypothesis import strategies as st

from railtherm.report import tables

finite = st.floats(-1e300, 1e300)  # rounding 1.5e308 to 2e308 would overflow
any_float = st.floats(allow_nan=True, allow_infinity=True)


@given(finite, st.integers(1, 17))
def test_rounding_keeps_the_printed_digits_and_is_within_half_a_unit(x, digits):
    (r,) = tables.round_significant(pd.DataFrame({"x": [x]}), digits)["x"]
    assert f"{r:.{digits}g}" == f"{x:.{digits}g}"
    if x != 0:
        unit = 10.0 ** (math.floor(math.log10(abs(x))) - digits + 1)
        assert abs(r - x) <= 0.5 * unit * (1 + 1e-9) + 2 * math.ulp(x)  # + back to binary
    again = tables.round_significant(pd.DataFrame({"x": [r]}), digits)["x"].iloc[0]
    assert again == r  # idempotent


def test_rounding_examples():
    df = pd.DataFrame({"x": [30648441.779328328, 0.999897857004911, -1.2345649e-7, 0.0]})
    r = tables.round_significant(df)["x"].tolist()
    assert r == [30648400.0, 0.999898, -1.23456e-7, 0.0]
    assert tables.round_significant(df, 2)["x"].tolist() == [31000000.0, 1.0, -1.2e-7, 0.0]


@given(st.lists(any_float, min_size=1, max_size=20))
def test_nan_and_inf_stay_and_other_columns_are_untouched(values):
    n = len(values)
    df = pd.DataFrame(
        {
            "f": values,
            "i": np.arange(n, dtype="int64") * 123456789,
            "b": [True] * n,
            "s": ["3.14159265358979"] * n,
        },
        index=pd.Index(np.arange(n) + 0.123456789),
    )
    out = tables.round_significant(df)
    assert list(out.dtypes) == list(df.dtypes)
    pd.testing.assert_frame_equal(out[["i", "b", "s"]], df[["i", "b", "s"]])
    pd.testing.assert_index_equal(out.index, df.index)
    got, want = out["f"].to_numpy(), df["f"].to_numpy()
    assert (np.isnan(got) == np.isnan(want)).all()
    inf = np.isinf(want)
    assert (got[inf] == want[inf]).all()
    pd.testing.assert_series_equal(df["f"], pd.Series(values, index=df.index, name="f"))


def test_nullable_float_column_keeps_missing_values():
    df = pd.DataFrame({"x": pd.array([1.23456789, None], dtype="Float64")})
    out = tables.round_significant(df)
    assert out["x"].dtype == "Float64"
    assert out["x"].iloc[0] == 1.23457 and out["x"].isna().iloc[1]


def test_digits_must_be_positive():
    with pytest.raises(ValueError, match="digits"):
        tables.round_significant(pd.DataFrame({"x": [1.0]}), 0)


@given(st.lists(any_float, min_size=1, max_size=10))
def test_written_csv_reads_back_as_the_rounded_values(tmp_path_factory, values):
    path = tmp_path_factory.mktemp("csv") / "t.csv"
    df = pd.DataFrame({"name": [f"v{i}" for i in range(len(values))], "x": values})
    tables.write_csv(df, path)
    back = pd.read_csv(path)
    want = tables.round_significant(df)["x"].to_numpy()
    np.testing.assert_array_equal(back["x"].to_numpy(dtype=float), want)
    assert back["name"].tolist() == df["name"].tolist()


def test_csv_format_line_endings_and_no_index(tmp_path):
    path = tmp_path / "sub" / "t.csv"
    df = pd.DataFrame(
        {"vehicle": ["Tram1", "Tram2"], "n": [2, 3], "C": [30648441.779328328, math.nan]}
    )
    tables.write_csv(df, path)
    assert path.read_bytes() == b"vehicle,n,C\nTram1,2,3.06484e+07\nTram2,3,\n"
    assert not [p for p in path.parent.iterdir() if p.name != "t.csv"]  # no temporary file left
    assert os.stat(path).st_mode & 0o777 == 0o666 & ~_umask()


def test_a_failed_write_leaves_the_old_table_and_no_temporary_file(tmp_path, monkeypatch):
    path = tmp_path / "t.csv"
    path.write_text("old\n")

    def broken_replace(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(tables.os, "replace", broken_replace)
    with pytest.raises(OSError, match="disk full"):
        tables.write_csv(pd.DataFrame({"x": [1.0]}), path)
    assert path.read_text() == "old\n"
    assert [p.name for p in tmp_path.iterdir()] == ["t.csv"]


def test_noise_below_the_sixth_digit_prints_the_same(tmp_path):
    """What another CPU gives in a well-determined fit (~1e-9 relative) does not show."""
    values = np.array([30648441.779328328, 0.999897857004911, 231.11789471280943, 2.5227271898924])
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    tables.write_csv(pd.DataFrame({"x": values}), a)
    tables.write_csv(pd.DataFrame({"x": values * (1 + 1e-9)}), b)
    assert a.read_bytes() == b.read_bytes()


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
