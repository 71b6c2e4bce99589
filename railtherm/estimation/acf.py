"""Sample autocorrelation of a series and its integrated autocorrelation time.

Used for residual whiteness (Ljung-Box, :mod:`railtherm.estimation.metrics`), for the effective
number of independent samples of a fit's residuals, and for the drift and scatter terms of the
static k
test (:mod:`railtherm.estimation.kvalue`). numpy only.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np


def deviations(e: Any) -> tuple[np.ndarray, int]:
    """Residuals minus their mean with NaN rows set to 0, and the number of finite rows."""
    e = np.asarray(e, dtype=float)
    if e.ndim != 1:
        raise ValueError(f"residuals must be a 1-D array, got shape {e.shape}")
    finite = ~np.isnan(e)
    n = int(finite.sum())
    d = np.zeros_like(e)
    if n:
        d[finite] = e[finite] - e[finite].mean()
    return d, n


def autocorrelation(e: Any, max_lag: int | None = None) -> np.ndarray:
    """Sample autocorrelation rho_0..rho_max_lag of a residual series, by FFT.

    rho_k = sum_n d(n) d(n + k) / sum_n d(n)^2 with d = e - mean(e) (the usual biased estimator,
    as in Box-Jenkins and Ljung-Box). NaN rows count as zero deviations. max_lag defaults to
    len(e) - 1 and is clipped to it. rho_0 = 1; all NaN for a constant or empty series."""
    d, n = deviations(e)
    size = d.size
    max_lag = size - 1 if max_lag is None else min(int(max_lag), size - 1)
    if max_lag < 0:
        return np.empty(0)
    var = float(d @ d)
    if n == 0 or not var > 0.0:
        return np.full(max_lag + 1, math.nan)
    nfft = 1 << (2 * size - 1).bit_length()
    f = np.fft.rfft(d, nfft)
    acov = np.fft.irfft(f * np.conj(f), nfft)[: max_lag + 1]
    return acov / var


def autocorrelation_time(x: Sequence[float]) -> float:
    """Integrated autocorrelation time tau = 1 + 2 sum_{j>=1} rho_j (in samples) of a series.

    Geyer's initial positive sequence: rho_0 + rho_1, rho_2 + rho_3, ... are summed while
    positive (so oscillating, e.g. thermostat-cycled, series are truncated at the first
    non-positive pair). Clamped to >= 1: anti-correlation earns no credit. 1 for a constant or
    too short series."""
    x = np.asarray(x, dtype=float)
    n = x.size
    if n < 4 or not np.all(np.isfinite(x)):
        return 1.0
    rho = autocorrelation(x)
    if not math.isfinite(rho[0]):
        return 1.0  # constant
    total = 0.0
    for m in range(0, (n - 1) // 2):
        pair = rho[2 * m] + rho[2 * m + 1]
        if pair <= 0.0:
            break
        total += pair
    return max(1.0, 2.0 * total - 1.0)
