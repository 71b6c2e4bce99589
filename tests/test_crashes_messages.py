"""Error messages are never built from nothing: an exception with an empty message (a bare
KeyError from a reader, say) still gives a message naming the file and what was read, not an
IndexError from the first line of an empty text."""

from __future__ import annotations

import pytest

from railtherm.data import readers
from railtherm.errors import DataError, first_line


@pytest.mark.bad_input
@pytest.mark.parametrize("exc", [KeyError(), StopIteration(), ValueError("  ")])
def test_a_reader_failing_without_a_message_is_named_by_its_type(exc):
    error = readers._read_error("log.xlsx", "excel", exc)
    assert isinstance(error, DataError)
    text = str(error)
    assert "log.xlsx" in text and "cannot read the file as a spreadsheet" in text
    assert type(exc).__name__ in text and "is format.reader right?" in text


def test_first_line_takes_the_message_where_there_is_one():
    assert first_line(ValueError("bad value\nsecond line")) == "bad value"
    assert first_line(KeyError()) == "KeyError"
