"""Exceptions for user mistakes: each names the file, the key (or column) and the value."""

from __future__ import annotations

from typing import Any


def first_line(exc: BaseException) -> str:
    """The first line of an exception's message, or its type's name where the message is
    empty (a message for the user is never built from nothing)."""
    lines = str(exc).strip().splitlines()
    return lines[0] if lines else type(exc).__name__


class RailthermError(Exception):
    """Base class of every error railtherm raises for bad input."""


class _Located(RailthermError):
    """An error located by file, key and value; ``str()`` gives one line naming all three."""

    what = "key"

    def __init__(self, file: Any, key: str, value: Any, reason: str):
        self.file = str(file)
        self.key = key
        self.value = value
        self.reason = reason
        super().__init__(f"{self.file}: {self.what} '{key}' = {value!r}: {reason}")


class ConfigError(_Located):
    """A vehicle, study or campaign config that is malformed or inconsistent with its data."""


class DataError(_Located):
    """Raw measurement data that cannot be used as configured (missing channel, bad time, gap)."""

    what = "column"
