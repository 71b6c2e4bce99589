"""The heteroskedasticity- and autocorrelation-consistent (HAC) covariance of the
simulation-error PEM's estimate: the Newey-West sandwich (J^T J)^-1 S (J^T J)^-1 with a
Bartlett kernel, its bandwidth by Andrews' AR(1) plug-in rule (docs/identification.md)."""

from __future__ import annotations

import math

import numpy as np

from railtherm.estimation.solver import gram

__all__ = ["andrews_bandwidth", "bartlett", "sandwich"]


def bartlett(gT: np.ndarray, L: int) -> np.ndarray:
    """sum_{|l| <= L} (1 - |l| / (L + 1)) Gamma_l for the score series g (given transposed,
    gT p x T), computed as (1 / (L + 1)) sum_t G_t G_t^T with G_t the sum of L + 1 consecutive
    g (zero-padded): every pair at lag l falls in L + 1 - l windows, which is the Bartlett
    weight exactly. O(T p^2), whatever L."""
    if L <= 0:
        return gram(gT)
    p, T = gT.shape
    c = np.empty((p, T + 2 * L + 1))  # c[:, j]: sum of the zero-padded g before position j
    c[:, : L + 1] = 0.0
    np.cumsum(gT, axis=1, out=c[:, L + 1 : L + 1 + T])
    c[:, L + 1 + T :] = c[:, L + T : L + T + 1]
    return gram(c[:, L + 1 :] - c[:, : T + L]) / (L + 1)


def sandwich(Vt: np.ndarray, inv_s: np.ndarray, meat: np.ndarray) -> np.ndarray:
    """The HAC covariance (J^T J)^+ meat (J^T J)^+ with (J^T J)^+ = V diag(inv_s^2) V^T,
    formed as F F^T with F = (J^T J)^+ meat^(1/2): positive semi-definite by construction, so
    no variance comes out negative (or is clipped to zero) and no correlation exceeds 1 when
    J is ill-conditioned and the plain triple product loses everything to cancellation."""
    lam, Q = np.linalg.eigh(meat)
    root = Q * np.sqrt(np.clip(lam, 0.0, None))
    F = Vt.T @ (inv_s[:, None] ** 2 * (Vt @ root))
    return F @ F.T


def andrews_bandwidth(e: np.ndarray) -> int:
    """Andrews (1991) AR(1) plug-in bandwidth for the Bartlett kernel."""
    T = len(e)
    if T < 3:
        return 0
    e = e - e.mean()
    den = float(e @ e)
    if den <= 0:
        return 0
    rho = float(e[1:] @ e[:-1]) / den
    rho = min(max(rho, -0.999), 0.999)
    alpha = 4 * rho**2 / ((1 - rho) ** 2 * (1 + rho) ** 2)
    L = int(math.ceil(1.1447 * (alpha * T) ** (1.0 / 3.0)))
    return max(0, min(L, T // 2))
