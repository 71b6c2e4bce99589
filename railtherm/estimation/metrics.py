"""Fit measures and residual diagnostics of an identified model (the verdict built on them:
:mod:`railtherm.study.quality`).

Notation as in the paper (section 6): y(n) is the measured and yhat(n) the simulated indoor air
temperature T, n = 1..m, and e(n) = y(n) - yhat(n) the (simulation-error) residual.

* :func:`r2` is the paper's coefficient of determination, eqs. 21-23::

      R^2 = 1 - SS_res / SS_tot,   SS_res = sum e(n)^2,   SS_tot = sum (y(n) - mean(y))^2

* :func:`nrmse_fit` is the *NRMSE fit* that MATLAB's ``compare`` and pySIP report,
  ``1 - ||y - yhat|| / ||y - mean(y)||``. It is **not** R^2: R^2 = 1 - (1 - nrmse_fit)^2, so an
  NRMSE fit of 0.9 is an R^2 of 0.99. Every output key says which one it is (``"r2"`` and
  ``"nrmse_fit"``, never ``"fit"`` alone).
* :func:`rmse`, the root mean square residual in the unit of y (K).
* :func:`autocorrelation` of the residuals (FFT) and :func:`ljung_box`, a whiteness test.
  Simulation-error residuals of slow thermal data are almost never white (any small model error
  leaves a slow, smooth residual), so the Ljung-Box p-value is nearly always ~0 on real data and
  is reported for information; the *autocorrelation time* tau (``railtherm.estimation.kvalue``'s
  :func:`~railtherm.estimation.acf.autocorrelation_time`, Geyer's initial positive sequence) says
  how coloured they are: the residuals carry about m / tau independent samples.
* :func:`aic` and :func:`bic` from SSR, m, p under a Gaussian likelihood, to compare the first
  and the second order on the same data (lower is better; only differences matter).

Missing values: rows where y or yhat is NaN are skipped by every measure (for the
autocorrelation the skipped rows count as zero deviations, so lags stay lags in time).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from railtherm.estimation.acf import autocorrelation, autocorrelation_time, deviations

__all__ = [
    "Whiteness",
    "aic",
    "autocorrelation",
    "bic",
    "ljung_box",
    "nrmse_fit",
    "paired",
    "r2",
    "r2_from_nrmse_fit",
    "rmse",
]


def paired(y: Any, yhat: Any) -> tuple[np.ndarray, np.ndarray]:
    """y and yhat as float 1-D arrays of equal length, rows with a NaN in either removed."""
    y = np.asarray(y, dtype=float)
    yhat = np.asarray(yhat, dtype=float)
    if y.shape != yhat.shape or y.ndim != 1:
        raise ValueError(
            f"y and yhat must be 1-D arrays of equal length, got shapes {y.shape}, {yhat.shape}"
        )
    keep = ~(np.isnan(y) | np.isnan(yhat))
    return y[keep], yhat[keep]


def _sums(y: Any, yhat: Any) -> tuple[float, float]:
    """(SS_res, SS_tot) of eqs. 22 and 23 over the rows where both are finite."""
    y, yhat = paired(y, yhat)
    if y.size == 0:
        return math.nan, math.nan
    e = y - yhat
    d = y - y.mean()
    if np.ptp(y) <= 1e-12 * max(1.0, float(np.max(np.abs(y)))):
        # constant y: SS_tot is the rounding of its mean alone, and 1 - SS_res / SS_tot
        # would print as a huge negative R^2 (a stuck sensor gave -9e29)
        return float(e @ e), 0.0
    return float(e @ e), float(d @ d)


def r2(y: Any, yhat: Any) -> float:
    """Coefficient of determination, eq. 21: 1 - SS_res / SS_tot (eqs. 22, 23).

    1 for a perfect fit, 0 when yhat is the mean of y, negative when worse than the mean. NaN
    when fewer than two rows are usable or y is constant (SS_tot = 0)."""
    ss_res, ss_tot = _sums(y, yhat)
    if not ss_tot > 0.0:
        return math.nan
    return 1.0 - ss_res / ss_tot


def nrmse_fit(y: Any, yhat: Any) -> float:
    """The NRMSE fit of MATLAB's ``compare`` and pySIP: 1 - ||y - yhat|| / ||y - mean(y)||.

    Not R^2 (eq. 21): :func:`r2` = 1 - (1 - nrmse_fit)^2. NaN as for :func:`r2`."""
    ss_res, ss_tot = _sums(y, yhat)
    if not ss_tot > 0.0:
        return math.nan
    return 1.0 - math.sqrt(ss_res / ss_tot)


def r2_from_nrmse_fit(fit: float) -> float:
    """R^2 (eq. 21) from an NRMSE fit: 1 - (1 - fit)^2 (for comparing with MATLAB/pySIP)."""
    return 1.0 - (1.0 - fit) ** 2


def rmse(y: Any, yhat: Any) -> float:
    """Root mean square residual sqrt(SS_res / m), in the unit of y; NaN rows skipped."""
    y, yhat = paired(y, yhat)
    if y.size == 0:
        return math.nan
    e = y - yhat
    return math.sqrt(float(e @ e) / y.size)


@dataclass(frozen=True)
class Whiteness:
    """Ljung-Box test of residual whiteness, and how coloured the residuals are.

    ``q``: Ljung-Box Q = m (m + 2) sum_{k=1..lags} rho_k^2 / (m - k); ``dof`` = lags -
    ``fitted``; ``p_value``: P(chi2(dof) >= Q) (small = not white). ``tau``: integrated
    autocorrelation time (samples; 1 for white noise); ``effective_samples`` = m / tau."""

    q: float
    p_value: float
    lags: int
    dof: int
    m: int
    tau: float
    effective_samples: float

    def white(self, alpha: float = 0.05) -> bool:
        """True unless the test rejects whiteness at level alpha."""
        return not self.p_value < alpha

    def to_dict(self) -> dict[str, float | int]:
        """Plain values for YAML, in a stable order."""
        return {
            "ljung_box_q": float(self.q),
            "ljung_box_p": float(self.p_value),
            "ljung_box_lags": int(self.lags),
            "ljung_box_dof": int(self.dof),
            "m": int(self.m),
            "autocorrelation_time": float(self.tau),
            "effective_samples": float(self.effective_samples),
        }


def ljung_box(e: Any, lags: int | None = None, fitted: int = 0) -> Whiteness:
    """Ljung-Box whiteness test of residuals e (NaN rows skipped, see :func:`autocorrelation`).

    lags defaults to min(20, m // 5) (at least 1); ``fitted`` is subtracted from the degrees of
    freedom (the ARMA convention; 0 for simulation-error residuals, whose parameters do not
    whiten them). The p-value is the chi-square survival function at Q with dof degrees of
    freedom (``scipy.special.chdtrc``, what ``scipy.stats.chi2.sf`` evaluates, without the
    second it takes to import scipy.stats)."""
    d, m = deviations(e)
    if m < 3:
        raise ValueError(f"the Ljung-Box test needs at least 3 finite residuals, got {m}")
    if lags is None:
        lags = max(1, min(20, m // 5))
    lags = int(lags)
    if not 1 <= lags < m:
        raise ValueError(f"lags must lie in 1..{m - 1}, got {lags}")
    dof = lags - int(fitted)
    if dof < 1:
        raise ValueError(f"lags ({lags}) must exceed the fitted parameter count ({fitted})")
    rho = autocorrelation(e, lags)
    k = np.arange(1, lags + 1)
    if np.isnan(rho[0]):  # constant residuals: nothing to test
        q, p = 0.0, 1.0
    else:
        q = float(m * (m + 2) * np.sum(rho[1:] ** 2 / (m - k)))
        from scipy.special import chdtrc  # imported where a p-value is asked for

        p = float(chdtrc(dof, q))
    tau = float(autocorrelation_time(d[~np.isnan(np.asarray(e, dtype=float))]))
    return Whiteness(q=q, p_value=p, lags=lags, dof=dof, m=m, tau=tau, effective_samples=m / tau)


def aic(ssr: float, m: int, p: int) -> float:
    """Akaike's criterion under a Gaussian likelihood: m ln(SSR / m) + 2 p (constants dropped,
    so compare only models fitted to the same m rows; lower is better)."""
    return m * math.log(ssr / m) + 2 * p


def bic(ssr: float, m: int, p: int) -> float:
    """Bayesian (Schwarz) criterion: m ln(SSR / m) + p ln(m); same conventions as :func:`aic`."""
    return m * math.log(ssr / m) + p * math.log(m)
