"""Outlying samples of a fit: the samples whose standardised one-step innovation (a Kalman-
filter fit, eq. 16 with K from the filter) or simulation residual (an output-error fit, eqs.
17-18 with K = 0) lies beyond a threshold set for the whole record.

Under the fitted model a standardised innovation z_t = e_t / sqrt(R_t) is N(0, 1); a
simulation residual divided by the residuals' RMSE is N(0, 1) as well, only not independent
of its neighbours. Testing each of N samples at level alpha would name about alpha N samples
of any record; the threshold is therefore the two-sided normal quantile at the Bonferroni-
adjusted level alpha / N,

    z* = Phi^-1(1 - alpha / (2 N)),

so that a record the model describes shows any outlying sample with a probability of at most
alpha (the family-wise error rate; Bonferroni's bound holds whatever the dependence between
the samples, so it holds for the coloured simulation residuals too). A sample beyond z* is a
sensor glitch or a moment the model does not describe (a door opened, a heater switched
faster than the hold assumes): it is reported, never removed - which rows a fit uses is the
vehicle config's ``windows`` (the raw data are never modified).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "OutlyingSamples",
    "bonferroni_threshold",
    "columns",
    "has_columns",
    "outlying_samples",
    "standardized",
]

# what the standardised quantity is, by estimator (the fit files' ``estimator``)
STATISTIC = {
    "kalman": "standardized innovation",
    "output_error": "standardized residual",
}


def bonferroni_threshold(n: int, alpha: float) -> float:
    """The two-sided standard normal quantile at the Bonferroni-adjusted level ``alpha / n``:
    |z| beyond it in any of ``n`` samples has probability at most ``alpha`` under the model.
    ``scipy.special.ndtri`` (the quantile ``scipy.stats.norm.isf`` evaluates) without the second
    scipy.stats takes to import in every check job."""
    from scipy.special import ndtri

    if n < 1:
        raise ValueError(f"no samples to test (n = {n})")
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha = {alpha} is not a probability in (0, 1)")
    return float(-ndtri(alpha / (2.0 * n)))


@dataclass(frozen=True)
class OutlyingSamples:
    """The outlying samples of one output of one fit.

    ``statistic``: what z is (standardized innovation or residual); ``n``: the samples tested
    (those measured); ``threshold``: z* of :func:`bonferroni_threshold`; ``samples``: one
    dict per sample beyond it, ``window``, ``time`` (s) and ``z``, in time order."""

    output: str
    statistic: str
    alpha: float
    n: int
    threshold: float
    samples: tuple[dict[str, Any], ...]

    def to_dict(self) -> dict[str, Any]:
        return {
            "statistic": self.statistic,
            "alpha": float(self.alpha),
            "n": int(self.n),
            "threshold": float(self.threshold),
            "samples": [dict(s) for s in self.samples],
        }

    @classmethod
    def from_dict(cls, output: str, data: dict[str, Any]) -> OutlyingSamples:
        """Back from :meth:`to_dict` (a fit file's ``outliers`` entry of ``output``)."""
        return cls(
            output,
            str(data["statistic"]),
            float(data["alpha"]),
            int(data["n"]),
            float(data["threshold"]),
            tuple(dict(s) for s in data["samples"]),
        )

    def texts(self) -> list[str]:
        """One sentence per outlying sample, for a fit's notes."""
        return [
            f"{self.output} sample at t = {s['time']:g} s (window {s['window']}): "
            f"{self.statistic} {s['z']:+.1f}, beyond the {self.threshold:.2f} threshold "
            f"(Bonferroni over {self.n} samples, alpha {self.alpha:g}): a sensor glitch or a "
            "moment the model does not describe"
            for s in self.samples
        ]


def outlying_samples(
    output: str,
    z: Sequence[float],
    times: Sequence[float],
    windows: Sequence[str],
    estimator: str,
    alpha: float = 0.05,
) -> OutlyingSamples:
    """The samples of ``z`` (standardised: N(0, 1) under the model) beyond the Bonferroni
    threshold at family-wise level ``alpha`` over the measured samples (NaN: not measured, not
    tested). ``times`` and ``windows`` name each sample."""
    z = np.asarray(z, dtype=float)
    measured = np.isfinite(z)
    n = int(measured.sum())
    threshold = bonferroni_threshold(max(n, 1), alpha)
    beyond = np.flatnonzero(measured & (np.abs(np.where(measured, z, 0.0)) > threshold))
    samples = tuple(
        {"window": str(windows[i]), "time": float(times[i]), "z": float(z[i])} for i in beyond
    )
    return OutlyingSamples(output, STATISTIC[estimator], float(alpha), n, threshold, samples)


def columns(output: str, estimator: str) -> tuple[str, str]:
    """The series table's columns :func:`standardized` reads for one output."""
    if estimator == "kalman":
        return f"{output}_innovation", f"{output}_innovation_sd"
    return output, f"{output}_sim"


def has_columns(series, output: str, estimator: str) -> bool:
    """Whether a series table holds what :func:`standardized` reads for ``output``."""
    return all(c in series for c in columns(output, estimator))


def standardized(series, output: str, estimator: str) -> np.ndarray:
    """The standardised quantity of one output of a fit's series table (rule identify's
    ``_series.csv``): a Kalman fit's innovations over their filter sd sqrt(R_t); an output-
    error fit's simulation residuals over their root mean square (the RMSE)."""
    first, second = (series[c].to_numpy(float) for c in columns(output, estimator))
    if estimator == "kalman":
        return first / second
    e = first - second
    rms = float(np.sqrt(np.nanmean(e**2))) if np.any(np.isfinite(e)) else np.nan
    return e / rms if rms > 0 else np.full_like(e, np.nan)
