"""The one reader and writer of railtherm's result files: ``kvalue.yaml``,
``identify/<model>.yaml``, ``fit_<model>.yaml``, ``sindy.yaml`` and the like.

Every result file is plain YAML, keys in the order they were written (:func:`write_result`),
so that a diff of two runs reads like the results. :func:`read_result` gives its content as
plain data and stops with a :class:`~railtherm.errors.DataError` naming the file when it cannot
be read or holds no mapping; :func:`read_fit` and :func:`read_kvalue` give the typed views.
The workflow's scripts, the figures and the tables read result files through this module
only.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import pandas as pd
import yaml

from railtherm.errors import DataError

if TYPE_CHECKING:  # the typed views import their classes when called
    from railtherm.fit import Fit
    from railtherm.kvalue import KValue

__all__ = ["read_fit", "read_kvalue", "read_result", "write_result"]


def write_result(data: Mapping[str, Any], path: str | os.PathLike[str]) -> None:
    """A result as plain YAML (keys in insertion order), its directory made if needed."""
    directory = os.path.dirname(str(path))
    if directory:
        os.makedirs(directory, exist_ok=True)
    with open(path, "w", encoding="utf-8") as stream:
        yaml.safe_dump(dict(data), stream, sort_keys=False)


def read_result(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The content of a result file as plain data."""
    try:
        with open(path, encoding="utf-8") as stream:
            data = yaml.safe_load(stream)
    except (OSError, yaml.YAMLError) as exc:
        raise DataError(str(path), "", None, f"cannot read the result file: {exc}") from None
    if not isinstance(data, dict):
        raise DataError(str(path), "", None, "not a result file: it holds no mapping of keys")
    return data


def read_fit(path: str | os.PathLike[str], series: str | os.PathLike[str] | None = None) -> Fit:
    """A :class:`~railtherm.fit.Fit` from ``fit_<model>.yaml`` (and its series CSV, if
    given)."""
    from railtherm.fit import Fit

    return Fit(read_result(path), None if series is None else pd.read_csv(series))


def read_kvalue(path: str | os.PathLike[str]) -> KValue:
    """The static k test (:class:`~railtherm.kvalue.KValue`) from ``kvalue.yaml``."""
    from railtherm.kvalue import KValue

    return KValue.from_dict(read_result(path))
