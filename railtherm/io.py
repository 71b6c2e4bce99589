"""The one reader and writer of railtherm's result files: ``kvalue.yaml``,
``identify/<model>.yaml``, ``fit_<model>.yaml``, ``sindy.yaml`` and the like.

Every result file is plain YAML, keys in the order they were written (:func:`write_result`),
so that a diff of two runs reads like the results. :func:`read_result` gives its content as
plain data and stops with a :class:`~railtherm.errors.DataError` naming the file when it cannot
be read or holds no mapping; the typed views build on it (:func:`railtherm.study.fit.read_fit`,
:meth:`railtherm.estimation.kvalue.KValue.from_dict`). The workflow's scripts, the figures and the
tables read result files through this module only; it imports no other part of railtherm but its
errors and the YAML loader.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

import yaml

from railtherm.errors import DataError
from railtherm.yamlio import SafeLoader

__all__ = ["read_result", "write_result"]


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
