"""The one reader and writer of railtherm's result files: ``kvalue.yaml``,
``identify/<model>.yaml``, ``fit_<model>.yaml``, ``sindy.yaml`` and the like.

Every result file is plain YAML, keys in the order they were written (:func:`write_result`),
so that a diff of two runs reads like the results. :func:`read_result` gives its content as
plain data and stops with a :class:`~railtherm.errors.DataError` naming the file when it cannot
be read or holds no mapping. A fit file is read and written as its typed record only
(:func:`read_fit`, :func:`write_fit`: :class:`railtherm.records.FitRecord`); the other typed
views build on :func:`read_result` (:meth:`railtherm.estimation.kvalue.KValue.from_dict`). The
workflow's scripts, the figures and the tables read result files through this module only; it
imports no other part of railtherm but its errors, the YAML loader and the records.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

import yaml

from railtherm.errors import ConfigError, DataError
from railtherm.records import EstimateRecord, FitRecord
from railtherm.yamlio import SafeLoader, read_yaml

__all__ = [
    "read_estimate",
    "read_fit",
    "read_result",
    "write_estimate",
    "write_fit",
    "write_result",
]


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
            data = yaml.load(stream, Loader=SafeLoader)
    except (OSError, yaml.YAMLError) as exc:
        raise DataError(str(path), "", None, f"cannot read the result file: {exc}") from None
    if not isinstance(data, dict):
        raise DataError(str(path), "", None, "not a result file: it holds no mapping of keys")
    return data


def read_fit(path: str | os.PathLike[str], display: str | None = None) -> FitRecord:
    """The :class:`~railtherm.records.FitRecord` of a fit file (``fit_<model>.yaml``): the one
    route from a fit file to the code. The file is read as a user's file is
    (:func:`railtherm.yamlio.read_yaml`: a missing file, bad YAML or a key given twice is a
    :class:`~railtherm.errors.ConfigError` naming ``display``, default the path); one that
    holds no mapping of keys is refused. Whether its content can run a model is the
    command's check (:func:`railtherm.study.fit.check_fit_file`)."""
    name = display or str(path)
    data = read_yaml(path, display=name)
    if not isinstance(data, Mapping):
        raise ConfigError(
            name, "(file)", type(data).__name__, "not a fit file: it holds no mapping of keys"
        )
    return FitRecord.from_dict(data)


def write_fit(record: FitRecord, path: str | os.PathLike[str]) -> None:
    """Write a fit's record as ``fit_<model>.yaml`` (:func:`write_result`: plain YAML, keys in
    the order of the fit)."""
    write_result(record.to_dict(), path)


def read_estimate(path: str | os.PathLike[str]) -> EstimateRecord:
    """The :class:`~railtherm.records.EstimateRecord` of an estimate file
    (``identify/<model>.yaml``, the rule identify's output)."""
    return EstimateRecord.from_dict(read_result(path))


def write_estimate(record: EstimateRecord, path: str | os.PathLike[str]) -> None:
    """Write an estimate's record as ``identify/<model>.yaml`` (:func:`write_result`)."""
    write_result(record.to_dict(), path)
