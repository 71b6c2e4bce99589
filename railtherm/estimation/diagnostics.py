"""Residual diagnostics and model selection of a stochastic grey-box fit, as pure functions.

The statistics a stochastic (Kalman-filter, maximum-likelihood) grey-box fit is judged by, as
CTSM-R and pySIP report them, computed from plain arrays and numbers:

* :func:`cumulated_periodogram`: the normalised cumulated periodogram of the one-step
  residuals (innovations) and its Kolmogorov-Smirnov band for white noise (Madsen, *Time
  Series Analysis*, 2008, sec. 6.3; the ``cpgram`` plot of CTSM-R). A frequency-domain
  whiteness test: it sees a slow periodic error that the autocorrelation spreads thinly over
  many lags.
* :func:`residual_tests`: that test beside the Ljung-Box portmanteau test (Ljung & Box 1978),
  which is :func:`railtherm.estimation.metrics.ljung_box` itself (not a second implementation),
  the two combined by Holm's procedure so that the pair rejects white noise at level alpha.
* :func:`holm`: Holm's step-down adjustment of several p-values (Holm 1979, *A simple
  sequentially rejective multiple test procedure*, Scand. J. Statist. 6): a family of tests
  judged by it rejects a true null hypothesis with probability at most alpha, whatever the
  tests' dependence; judged test by test at alpha, a family of m tests would reject up to
  m alpha.
* :func:`likelihood_ratio`: the likelihood-ratio test of two nested models (Wilks 1938), with
  the chi-bar-squared null distribution when parameters of the larger model lie on the
  boundary of the smaller (Self & Liang 1987).
* :func:`forward_selection`: from the smallest model, extend while the extension's
  likelihood-ratio test rejects the smaller model (the forward selection of Bacher & Madsen
  2011, *Identifying suitable models for the heat dynamics of buildings*, Energy and Buildings
  43); :func:`selection_markdown` renders the steps as a table.
* :func:`information_criteria`: AIC (Akaike 1974) and BIC (Schwarz 1978) from a
  log-likelihood. :func:`railtherm.estimation.metrics.aic` /
  :func:`~railtherm.estimation.metrics.bic` are the same
  criteria for output-error fits, from the sum of squared residuals (Gaussian likelihood with
  the variance profiled out, constants dropped); these take the log-likelihood itself, as a
  Kalman-filter fit gives it. Differences between models agree; absolute values do not.

Everything here is numpy at import time; scipy.stats (slow to import) is loaded inside the
functions that need a distribution. Results are frozen dataclasses with ``to_dict()`` (plain
values, stable key order, for YAML).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from railtherm.estimation.metrics import Whiteness, ljung_box

__all__ = [
    "Candidate",
    "CpgTest",
    "LRTest",
    "Nesting",
    "ResidualTests",
    "Selection",
    "Step",
    "cumulated_periodogram",
    "forward_selection",
    "holm",
    "information_criteria",
    "likelihood_ratio",
    "residual_tests",
    "selection_markdown",
]


# --- several tests as one family ----------------------------------------------------------


def holm(p_values: Any) -> np.ndarray:
    """Holm's adjusted p-values of a family of tests (Holm 1979): the i-th smallest p times
    (m - i + 1), made non-decreasing in that order and capped at 1. A test is rejected at
    family-wise level alpha where its adjusted p is below alpha; the family rejects (any test
    does) exactly where the smallest p is below alpha / m (Bonferroni's decision, which Holm's
    refines only in which further tests it names). The family-wise error rate is at most
    alpha for any dependence between the tests. NaN p-values are not tests: they stay NaN
    and do not count in m."""
    p = np.asarray(p_values, dtype=float)
    if p.ndim != 1:
        raise ValueError(f"p_values must be 1-D, got shape {p.shape}")
    if np.any((p < 0.0) | (p > 1.0)):
        raise ValueError(f"p-values must lie in [0, 1], got {p.tolist()}")
    out = np.full(p.shape, np.nan)
    finite = np.flatnonzero(~np.isnan(p))
    m = finite.size
    if m == 0:
        return out
    order = finite[np.argsort(p[finite], kind="stable")]
    scaled = p[order] * (m - np.arange(m))
    out[order] = np.minimum(np.maximum.accumulate(scaled), 1.0)
    return out


# --- the cumulated periodogram ------------------------------------------------------------


@dataclass(frozen=True)
class CpgTest:
    """The cumulated periodogram of a residual series and its white-noise test.

    ``frequencies``: the Fourier frequencies nu_j = j / n, j = 1..q, in cycles per sample
    (q = (n - 1) // 2: the mean's frequency 0 and, for even n, the Nyquist frequency left out).
    ``cumulated``: C(nu_j) = sum_{i <= j} I(nu_i) / sum_{i <= q} I(nu_i), I the periodogram;
    C rises from 0 to 1, along the diagonal :attr:`expected` = j / q for white noise.
    ``half_width``: the band's half-width around the diagonal at level ``alpha``;
    ``max_deviation``: the Kolmogorov-Smirnov statistic; ``white``: the statistic stays
    inside the band (whiteness not rejected at ``alpha``); ``p_value``: P(D >= observed) for
    white noise. ``method``: "exact" or "asymptotic" (see :func:`cumulated_periodogram`).
    ``n``: samples used, ``n_missing``: NaN rows dropped, ``note``: how they were handled."""

    frequencies: np.ndarray
    cumulated: np.ndarray
    half_width: float
    max_deviation: float
    white: bool
    p_value: float
    alpha: float
    method: str
    n: int
    q: int
    n_missing: int = 0
    note: str = ""

    @property
    def expected(self) -> np.ndarray:
        """The white-noise diagonal j / q at :attr:`frequencies` (the band's centre line)."""
        return np.arange(1, self.q + 1) / self.q

    def band(self) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) edges of the band at :attr:`frequencies`, clipped to [0, 1]."""
        centre = self.expected
        return (
            np.clip(centre - self.half_width, 0.0, 1.0),
            np.clip(centre + self.half_width, 0.0, 1.0),
        )

    def to_dict(self) -> dict[str, Any]:
        """The test's numbers (not the arrays), in a stable order."""
        return {
            "cpg_max_deviation": float(self.max_deviation),
            "cpg_half_width": float(self.half_width),
            "cpg_p": float(self.p_value),
            "cpg_white": bool(self.white),
            "cpg_alpha": float(self.alpha),
            "cpg_method": self.method,
            "cpg_n": int(self.n),
            "cpg_q": int(self.q),
            "cpg_missing": int(self.n_missing),
            "cpg_note": self.note,
        }


@functools.lru_cache(maxsize=256)
def _half_width(alpha: float, q: int, method: str) -> float:
    """The band's half-width of :func:`cumulated_periodogram`: the KS quantile of q - 1
    observations (``scipy.stats.kstwo``, a root search of a tenth of a second, so kept per
    (alpha, q)) or Madsen's asymptotic one."""
    from scipy import stats

    if method == "exact":
        return float(stats.kstwo.isf(alpha, q - 1))
    return float(stats.kstwobign.isf(alpha) / math.sqrt(q))


def cumulated_periodogram(
    residuals: Any,
    alpha: float = 0.05,
    *,
    method: Literal["exact", "asymptotic"] = "exact",
    missing: Literal["drop", "raise"] = "drop",
) -> CpgTest:
    """The cumulated periodogram test of whiteness of a (one-step) residual series.

    The periodogram I(nu_j) = |sum_t e_t exp(-i 2 pi nu_j t)|^2 / n of the mean-removed series
    (numpy.fft.rfft, no taper) at the Fourier frequencies nu_j = j / n, j = 1..q,
    q = (n - 1) // 2, is cumulated and normalised to C(nu_j) (Madsen 2008, sec. 6.3.3; the
    ``cpgram`` of CTSM-R, which R's stats package provides). For Gaussian white noise the I(nu_j)
    are independent exponential variables, so C(nu_1)..C(nu_{q-1}) are distributed exactly as
    the order statistics of q - 1 independent U(0, 1) variables (Bartlett 1955; Durbin 1969):
    the test is the one-sample Kolmogorov-Smirnov test of them against U(0, 1).

    ``method="exact"`` (default): the statistic is that KS statistic
    (``scipy.stats.kstest``), the p-value and the band's half-width come from its finite-sample
    distribution (``scipy.stats.kstwo`` with q - 1 observations). The size is alpha for any q.
    ``method="asymptotic"``: Madsen's band as CTSM-R draws it, max_j |C(nu_j) - j/q| against
    K_alpha / sqrt(q), K_alpha the Kolmogorov quantile (``scipy.stats.kstwobign``: 1.36 at
    alpha = 0.05), p from the same limit law. It is conservative in short series (it rejects
    white Gaussian noise at about 2 % instead of 5 % for n = 50, about 3 % for n = 200).
    Either way ``white`` is ``max_deviation <= half_width``, i.e. ``p_value >= alpha``.

    Missing rows (NaN), ``missing="drop"`` (default): dropped, and the remaining samples are
    treated as consecutive (as R's ``cpgram`` does). Under the null hypothesis this is exact: a
    white series with rows removed is white. A coloured series loses its correlation only at
    the seams, so the test's power drops a little with many short gaps. ``missing="raise"``:
    a NaN is a ValueError (for a caller that wants contiguous data). Infinite values are always
    a ValueError. A constant series (zero periodogram) has nothing to test: C is NaN, p = 1.
    """
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha must lie in (0, 1), got {alpha}")
    if method not in ("exact", "asymptotic"):
        raise ValueError(f"method must be 'exact' or 'asymptotic', got {method!r}")
    if missing not in ("drop", "raise"):
        raise ValueError(f"missing must be 'drop' or 'raise', got {missing!r}")
    x = np.asarray(residuals, dtype=float)
    if x.ndim != 1:
        raise ValueError(f"residuals must be a 1-D array, got shape {x.shape}")
    if np.isinf(x).any():
        raise ValueError("residuals must not be infinite")
    gaps = np.isnan(x)
    n_missing = int(gaps.sum())
    if n_missing and missing == "raise":
        raise ValueError(f"{n_missing} residual(s) are NaN; the series must be contiguous")
    x = x[~gaps]
    n = int(x.size)
    q = (n - 1) // 2
    if q < 2:
        raise ValueError(
            f"the cumulated periodogram test needs at least 5 finite residuals, got {n}"
        )
    note = (
        f"{n_missing} missing row(s) dropped; the {n} remaining samples taken as consecutive"
        if n_missing
        else ""
    )
    frequencies = np.arange(1, q + 1) / n
    power = np.abs(np.fft.rfft(x - x.mean())[1 : q + 1]) ** 2 / n
    total = float(power.sum())
    from scipy import stats  # ~2 s to import: only where a test is asked for

    half_width = _half_width(alpha, q, method)
    if not total > 0.0:  # constant residuals
        return CpgTest(
            frequencies=frequencies,
            cumulated=np.full(q, math.nan),
            half_width=half_width,
            max_deviation=0.0,
            white=True,
            p_value=1.0,
            alpha=alpha,
            method=method,
            n=n,
            q=q,
            n_missing=n_missing,
            note="; ".join(s for s in (note, "constant series: nothing to test") if s),
        )
    cumulated = np.cumsum(power) / total
    if method == "exact":
        ks = stats.kstest(cumulated[:-1], "uniform", method="exact")
        deviation, p = float(ks.statistic), float(ks.pvalue)
    else:
        deviation = float(np.max(np.abs(cumulated - np.arange(1, q + 1) / q)))
        p = float(stats.kstwobign.sf(math.sqrt(q) * deviation))
    return CpgTest(
        frequencies=frequencies,
        cumulated=cumulated,
        half_width=half_width,
        max_deviation=deviation,
        white=bool(deviation <= half_width),
        p_value=p,
        alpha=alpha,
        method=method,
        n=n,
        q=q,
        n_missing=n_missing,
        note=note,
    )


@dataclass(frozen=True)
class ResidualTests:
    """The two whiteness tests of one residual series: Ljung-Box (time domain,
    :class:`railtherm.estimation.metrics.Whiteness`) and the cumulated periodogram (frequency
    domain), judged as one family at :attr:`alpha` (:func:`holm`)."""

    ljung_box: Whiteness
    periodogram: CpgTest
    alpha: float

    @property
    def holm_p(self) -> tuple[float, float]:
        """Holm's adjusted p-values (Ljung-Box, cumulated periodogram) of the pair."""
        lb, cpg = holm([self.ljung_box.p_value, self.periodogram.p_value])
        return float(lb), float(cpg)

    @property
    def white(self) -> bool:
        """Whiteness is not rejected by the pair at family level :attr:`alpha`: neither
        Holm-adjusted p is below it (the smaller raw p not below alpha / 2). Either test alone
        at alpha would reject white noise up to twice as often."""
        return min(self.holm_p) >= self.alpha

    def to_dict(self) -> dict[str, Any]:
        """Both tests' numbers in one flat mapping, in a stable order."""
        return {
            **self.ljung_box.to_dict(),
            **self.periodogram.to_dict(),
            "white": bool(self.white),
        }


def residual_tests(
    residuals: Any,
    *,
    lags: int | None = None,
    fitted: int = 0,
    alpha: float = 0.05,
    method: Literal["exact", "asymptotic"] = "exact",
) -> ResidualTests:
    """Ljung-Box (Ljung & Box 1978, :func:`railtherm.estimation.metrics.ljung_box`: ``lags``,
    default min(20, m // 5), and ``fitted`` parameters subtracted from its degrees of freedom) and
    the cumulated periodogram test (:func:`cumulated_periodogram`, ``method``) of one residual
    series, judged together at family level ``alpha`` by Holm's procedure
    (:attr:`ResidualTests.white`).

    Missing rows: Ljung-Box counts them as zero deviations, so its lags stay lags in time; the
    periodogram drops them (see :func:`cumulated_periodogram`). Both are exact under the null
    hypothesis of white noise."""
    return ResidualTests(
        ljung_box=ljung_box(residuals, lags, fitted),
        periodogram=cumulated_periodogram(residuals, alpha, method=method),
        alpha=alpha,
    )


# --- likelihood-ratio tests ----------------------------------------------------------------


@dataclass(frozen=True)
class LRTest:
    """A likelihood-ratio test of a smaller model nested in a larger one.

    ``statistic`` = 2 (l_large - l_small); ``df``: parameters the larger model adds;
    ``boundary``: how many of them lie on the boundary of the parameter space under the smaller
    model; ``distribution``: the null distribution used; ``p_value``; ``reject``: the smaller
    model is rejected at ``alpha`` (the extension is significant); ``conclusion``: one
    sentence."""

    statistic: float
    df: int
    boundary: int
    p_value: float
    alpha: float
    reject: bool
    distribution: str
    conclusion: str
    loglik_small: float
    loglik_large: float

    def to_dict(self) -> dict[str, Any]:
        """Plain values in a stable order."""
        return {
            "lr_statistic": float(self.statistic),
            "df": int(self.df),
            "boundary": int(self.boundary),
            "distribution": self.distribution,
            "p": float(self.p_value),
            "alpha": float(self.alpha),
            "reject": bool(self.reject),
            "loglik_small": float(self.loglik_small),
            "loglik_large": float(self.loglik_large),
            "conclusion": self.conclusion,
        }


def _chi2_name(k: int) -> str:
    return "chi2(0) (mass at 0)" if k == 0 else f"chi2({k})"


def _mixture_name(df: int, boundary: int, weights: Sequence[float]) -> str:
    if boundary == 0:
        return _chi2_name(df)
    parts = [f"{w:g} {_chi2_name(df - boundary + k)}" for k, w in enumerate(weights) if w > 0.0]
    return "chi-bar-squared " + " + ".join(parts)


def likelihood_ratio(
    loglik_small: float,
    loglik_large: float,
    df: int,
    boundary: int = 0,
    alpha: float = 0.05,
) -> LRTest:
    """The likelihood-ratio test of a smaller model nested in a larger one.

    The statistic is 2 (l_large - l_small) from the maximised log-likelihoods. With every
    added parameter interior under the smaller model it is chi2(df) under the smaller model
    (Wilks 1938). When ``boundary`` of the ``df`` added parameters sit on the boundary of the
    parameter space under the smaller model (a variance or a diffusion tested against 0, a
    conductance against 0 or infinity), the null distribution is the chi-bar-squared mixture
    sum_{k=0..b} C(b, k) 2^-b chi2(df - b + k), b = ``boundary``, chi2(0) the point mass at 0
    (Self & Liang 1987, their cases with the boundary parameters' estimates asymptotically
    independent; for b = 1: 0.5 chi2(df - 1) + 0.5 chi2(df), so for df = 1 the p-value is half
    the chi2(1) one). The binomial weights hold when the boundary parameters are orthogonal in
    the Fisher information; otherwise the true weights depend on it and these are an
    approximation. When the smaller model is a limit of the larger one at which other
    parameters of the larger one become unidentified (e.g. a second state whose coupling to the
    first goes to infinity: its capacity then has no effect), no chi2 law holds exactly
    (Davies 1977); the mixture is then a common approximation, and a small p-value still
    means a clear gain.

    A negative statistic (the larger model fits worse than the model nested in it) cannot come
    from two maximised likelihoods: p = 1 and the conclusion says the larger fit did not reach
    its optimum. p-values from ``scipy.stats.chi2.sf`` and weights from ``scipy.stats.binom``.
    """
    df, boundary = int(df), int(boundary)
    if df < 1:
        raise ValueError(f"df must be at least 1, got {df}")
    if not 0 <= boundary <= df:
        raise ValueError(f"boundary must lie in 0..df ({df}), got {boundary}")
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha must lie in (0, 1), got {alpha}")
    small, large = float(loglik_small), float(loglik_large)
    if not (math.isfinite(small) and math.isfinite(large)):
        raise ValueError(f"log-likelihoods must be finite, got {small}, {large}")
    from scipy import stats  # ~2 s to import: only where a test is asked for

    statistic = 2.0 * (large - small)
    ks = np.arange(boundary + 1)
    weights = stats.binom.pmf(ks, boundary, 0.5)
    if statistic > 0.0:
        tails = [
            stats.chi2.sf(statistic, df - boundary + k) if df - boundary + k > 0 else 0.0
            for k in ks
        ]
        p = float(min(1.0, np.dot(weights, tails)))
    else:
        p = 1.0
    reject = p < alpha
    distribution = _mixture_name(df, boundary, weights)
    head = f"LR = {statistic:.4g} on {df} df"
    if boundary:
        head += f" ({boundary} on the boundary)"
    if statistic < 0.0:
        conclusion = (
            f"{head}: the larger model's log-likelihood is below the smaller's, which a "
            "maximised likelihood of a model that contains the smaller one cannot be; its fit "
            "did not reach the optimum (p set to 1)."
        )
    elif reject:
        conclusion = (
            f"{head}, p = {p:.3g} < {alpha:g}: the smaller model is rejected; the extension "
            "is significant."
        )
    else:
        conclusion = (
            f"{head}, p = {p:.3g} >= {alpha:g}: the smaller model is not rejected; the "
            "extension is not significant."
        )
    return LRTest(
        statistic=statistic,
        df=df,
        boundary=boundary,
        p_value=p,
        alpha=alpha,
        reject=reject,
        distribution=distribution,
        conclusion=conclusion,
        loglik_small=small,
        loglik_large=large,
    )


def information_criteria(loglik: float, n_params: int, n_obs: int) -> dict[str, float]:
    """AIC = -2 l + 2 p (Akaike 1974) and BIC = -2 l + p ln(n) (Schwarz 1978) from a maximised
    log-likelihood l with p estimated parameters (every one: physical parameters, noise and
    diffusion terms, estimated initial states) and n scalar observations (the finite
    measurements of every output). Lower is better; compare only models fitted to the same
    data."""
    p, n = int(n_params), int(n_obs)
    if p < 0 or n < 1:
        raise ValueError(f"n_params must be >= 0 and n_obs >= 1, got {p}, {n}")
    return {"aic": -2.0 * float(loglik) + 2.0 * p, "bic": -2.0 * float(loglik) + p * math.log(n)}


# --- forward selection ---------------------------------------------------------------------


@dataclass(frozen=True)
class Candidate:
    """A fitted model: its name, maximised log-likelihood and number of estimated
    parameters."""

    name: str
    loglik: float
    n_params: int

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "loglik": float(self.loglik), "n_params": int(self.n_params)}


@dataclass(frozen=True)
class Nesting:
    """``large`` extends ``small`` (``small`` is ``large`` with some parameters fixed);
    ``boundary``: how many of the added parameters are on the boundary there (see
    :func:`likelihood_ratio`)."""

    small: str
    large: str
    boundary: int = 0

    def to_dict(self) -> dict[str, Any]:
        return {"small": self.small, "large": self.large, "boundary": int(self.boundary)}


@dataclass(frozen=True)
class Step:
    """One tested extension: ``stage`` (1 for the extensions of the starting model, ...),
    ``from_model`` -> ``to_model``, the likelihood-ratio ``test``, whether it was
    ``accepted`` (the selection moved on to ``to_model``) and the ``decision`` in words."""

    stage: int
    from_model: str
    to_model: str
    test: LRTest
    accepted: bool
    decision: str

    def to_dict(self) -> dict[str, Any]:
        return {
            "stage": int(self.stage),
            "from": self.from_model,
            "to": self.to_model,
            **self.test.to_dict(),
            "accepted": bool(self.accepted),
            "decision": self.decision,
        }


@dataclass(frozen=True)
class Selection:
    """The outcome of :func:`forward_selection`: the ``steps`` in order, the ``start`` and
    ``selected`` models, and the level ``alpha``. Iterating over it yields the steps."""

    steps: tuple[Step, ...]
    start: str
    selected: str
    alpha: float

    def __iter__(self):
        return iter(self.steps)

    def __len__(self) -> int:
        return len(self.steps)

    def __getitem__(self, i: int) -> Step:
        return self.steps[i]

    def to_dict(self) -> dict[str, Any]:
        return {
            "start": self.start,
            "selected": self.selected,
            "alpha": float(self.alpha),
            "steps": [s.to_dict() for s in self.steps],
        }


def _candidate(c: Candidate | Mapping[str, Any] | Sequence[Any]) -> Candidate:
    if isinstance(c, Candidate):
        return c
    if isinstance(c, Mapping):
        return Candidate(str(c["name"]), float(c["loglik"]), int(c["n_params"]))
    name, loglik, n_params = c
    return Candidate(str(name), float(loglik), int(n_params))


def _nesting(n: Nesting | Mapping[str, Any] | Sequence[Any]) -> Nesting:
    if isinstance(n, Nesting):
        return n
    if isinstance(n, Mapping):
        return Nesting(str(n["small"]), str(n["large"]), int(n.get("boundary", 0)))
    small, large, *rest = n
    return Nesting(str(small), str(large), int(rest[0]) if rest else 0)


def forward_selection(
    candidates: Iterable[Candidate | Mapping[str, Any] | Sequence[Any]],
    nesting: Iterable[Nesting | Mapping[str, Any] | Sequence[Any]],
    alpha: float = 0.05,
) -> Selection:
    """Forward selection of nested models by likelihood-ratio tests (Bacher & Madsen 2011).

    ``candidates``: the fitted models, as :class:`Candidate` or mappings / tuples
    (name, loglik, n_params). ``nesting``: which model extends which, as :class:`Nesting` or
    mappings / tuples (small, large[, boundary]). The selection starts from the candidate with
    the fewest parameters. At each stage every declared extension of the current model is
    tested against it (:func:`likelihood_ratio`, df = the difference in parameter counts,
    with the declared boundary parameters); among the extensions that reject the current model
    at ``alpha`` the one with the highest log-likelihood is accepted and becomes the current
    model. The selection stops when no extension is significant or none is declared.

    Pure data in, pure data out: a :class:`Selection` (iterable over its steps) with every
    tested extension, accepted or not, and the selected model. A ValueError for duplicate or
    unknown names, an extension with no more parameters than the model it extends, or two
    smallest models."""
    models: dict[str, Candidate] = {}
    for c in map(_candidate, candidates):
        if c.name in models:
            raise ValueError(f"model {c.name!r} is listed twice")
        models[c.name] = c
    if not models:
        raise ValueError("no candidate models")
    links = [_nesting(n) for n in nesting]
    for link in links:
        for name in (link.small, link.large):
            if name not in models:
                raise ValueError(f"the nesting names {name!r}, which is not a candidate")
        if models[link.large].n_params <= models[link.small].n_params:
            raise ValueError(
                f"{link.large!r} ({models[link.large].n_params} parameters) cannot extend "
                f"{link.small!r} ({models[link.small].n_params} parameters)"
            )
    fewest = min(c.n_params for c in models.values())
    smallest = [c.name for c in models.values() if c.n_params == fewest]
    if len(smallest) > 1:
        raise ValueError(f"no single smallest model to start from: {', '.join(smallest)}")
    start = current = smallest[0]
    steps: list[Step] = []
    stage = 0
    while True:  # ends: the parameter count grows strictly with every accepted step
        extensions = [link for link in links if link.small == current]
        if not extensions:
            break
        stage += 1
        tests = [
            (
                link,
                likelihood_ratio(
                    models[current].loglik,
                    models[link.large].loglik,
                    models[link.large].n_params - models[current].n_params,
                    link.boundary,
                    alpha,
                ),
            )
            for link in extensions
        ]
        significant = [(link, t) for link, t in tests if t.reject]
        chosen = (
            max(significant, key=lambda lt: (models[lt[0].large].loglik, -lt[1].p_value))[0]
            if significant
            else None
        )
        for link, t in tests:
            if link is chosen:
                decision = "accepted"
            elif t.reject:
                decision = f"significant, but {chosen.large} fits better"
            elif t.statistic < 0.0:
                decision = "rejected: the larger fit did not reach its optimum"
            else:
                decision = "rejected: not significant"
            steps.append(Step(stage, current, link.large, t, link is chosen, decision))
        if chosen is None:
            break
        current = chosen.large
    return Selection(steps=tuple(steps), start=start, selected=current, alpha=alpha)


def _p_text(p: float) -> str:
    return "< 1e-16" if p < 1e-16 else f"{p:.3g}"


def selection_markdown(vehicle: str, steps: Selection | Sequence[Step]) -> str:
    """A vehicle's forward selection as a Markdown table (columns from, to, LR statistic, df,
    p, decision) under a one-line caption naming the selected model; for
    ``results/tables/models.md``. ``steps``: a :class:`Selection`, or its steps (the selected
    model is then the last accepted one)."""
    import pandas as pd  # only the renderer needs it

    if isinstance(steps, Selection):
        rows, selected, alpha = list(steps.steps), steps.selected, steps.alpha
    else:
        rows = list(steps)
        accepted = [s for s in rows if s.accepted]
        selected = (accepted[-1].to_model if accepted else rows[0].from_model) if rows else None
        alpha = rows[0].test.alpha if rows else None
    caption = f"**Forward selection, {vehicle}**"
    if alpha is not None:
        caption += f" (likelihood-ratio tests at alpha = {alpha:g})"
    caption += f": selected {selected}." if selected else "."
    if not rows:
        return f"{caption}\n\nNo nested extension was tested.\n"
    view = pd.DataFrame(
        {
            "from": [s.from_model for s in rows],
            "to": [s.to_model for s in rows],
            "LR statistic": [f"{s.test.statistic:.3f}" for s in rows],
            "df": [
                f"{s.test.df}" + (f" ({s.test.boundary} on boundary)" if s.test.boundary else "")
                for s in rows
            ],
            "p": [_p_text(s.test.p_value) for s in rows],
            "decision": [s.decision for s in rows],
        }
    )
    return f"{caption}\n\n{view.to_markdown(index=False, disable_numparse=True)}\n"
