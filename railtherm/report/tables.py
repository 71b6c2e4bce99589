"""Result tables as CSV at a fixed number of significant digits.

The study's CSV tables (``results/tables``, ``validation/results/tables``) are written by
:func:`write_csv`, which rounds every float to :data:`SIGNIFICANT_DIGITS` significant digits,
so that they hold numbers another CPU reproduces. The same code with the same package
versions gives different last digits on different CPUs: numpy and OpenBLAS choose their SIMD
kernels (AVX2, AVX-512) by CPU, and these add in different orders. In well-determined fits the
difference is ~1e-9 relative, far below the sixth digit, so those numbers print the same
everywhere; in fits whose parameters the data do not determine it reaches ~5e-5, where the
sixth digit can still differ, which is why the tests compare a fresh table with the committed
one within a tolerance (``tests/compare_outputs.py``) rather than byte for byte. Written with
all 17 digits, every such table would differ on every machine in digits that mean nothing.
Six digits lose nothing the study reports: its narrowest intervals are >= 0.1 % wide, at
least 100 times a unit in the sixth digit.
"""

from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path

import pandas as pd

SIGNIFICANT_DIGITS = 6


def _round(value: float, digits: int) -> float:
    if not math.isfinite(value):
        return value  # NaN and +-inf as they are
    rounded = float(f"{value:.{digits}g}")
    return rounded if math.isfinite(rounded) else value  # not up to inf next to the largest float


def round_significant(df: pd.DataFrame, digits: int = SIGNIFICANT_DIGITS) -> pd.DataFrame:
    """A copy of ``df`` with every float column rounded to ``digits`` significant digits.

    The rounding is the one ``"%.{digits}g"`` prints (round half to even on the binary value),
    so the rounded value prints exactly as the original would. NaN and +-inf stay; integer,
    boolean and text columns, and the index, are not touched.
    """
    if digits < 1:
        raise ValueError(f"digits must be >= 1, not {digits}")
    out = df.copy()
    for i, (_, column) in enumerate(df.items()):
        if pd.api.types.is_float_dtype(column.dtype):
            out.isetitem(i, column.map(lambda v: _round(v, digits), na_action="ignore"))
    return out


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_csv(df: pd.DataFrame, path: str | os.PathLike, digits: int = SIGNIFICANT_DIGITS) -> None:
    """Write ``df`` to ``path`` as CSV, floats at ``digits`` significant digits.

    No index column, "\\n" line endings, UTF-8, empty cells for NaN. The file is written to a
    temporary file in the same directory and moved into place, so ``path`` is never left
    half-written: a reader sees the old table or the new one.
    """
    path = Path(path)
    text = round_significant(df, digits).to_csv(
        index=False, float_format=f"%.{digits}g", lineterminator="\n"
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as stream:
            stream.write(text)
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp's 0600 -> what open() would give
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
