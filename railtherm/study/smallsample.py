"""Statistics for a handful of vehicles (paper section 6.3: two to five per class).

- :func:`t_interval`: the 95 % t interval of a mean (n - 1 degrees of freedom): exact for
  normal data at any n >= 2, honest (wide) at n = 2. A percentile bootstrap of 3 to 5 values
  returns little more than their range and covers far less than 95 %.
- :func:`two_class_test`: Welch's t-test and the exact two-sided Mann-Whitney U test of two
  classes, each run only when it can reach significance: Welch needs three values per class;
  the exact Mann-Whitney test cannot give a p below 2 / C(n_a + n_b, n_a)
  (:func:`smallest_mann_whitney_p`: 0.2 at 3 against 2), so with fewer values "no significant
  difference" would be certain before any data.

scipy.stats is imported inside the functions: it costs seconds, and most callers of the
modules that use this one never test anything.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["TwoClassTest", "smallest_mann_whitney_p", "t_interval", "two_class_test"]

# Welch's test needs this many values per class: with two, a class's sd is one difference,
# its Welch-Satterthwaite degrees of freedom fall towards 1 and "no significant difference"
# is all but certain whatever the classes are
WELCH_MIN = 3


def t_interval(x: Sequence[float], positive: bool = False) -> tuple[float, float]:
    """95 % t interval of the mean of ``x`` (n - 1 degrees of freedom); (nan, nan) below
    n = 2. For a ``positive`` quantity the lower end is clipped at 0 (coverage is kept)."""
    x = np.asarray(x, dtype=float)
    if x.size < 2:
        return math.nan, math.nan
    from scipy import stats

    half = float(stats.t.ppf(0.975, x.size - 1)) * float(x.std(ddof=1)) / math.sqrt(x.size)
    lo = float(x.mean()) - half
    return (max(lo, 0.0) if positive else lo), float(x.mean()) + half


def smallest_mann_whitney_p(n_a: int, n_b: int) -> float:
    """The smallest two-sided p-value the exact Mann-Whitney U test can give for n_a against
    n_b values without ties: every value of one class above every value of the other (U = 0
    or U = n_a n_b), 2 of the C(n_a + n_b, n_a) equally likely splits; at most 1."""
    if n_a < 1 or n_b < 1:
        return 1.0
    return min(1.0, 2.0 / math.comb(n_a + n_b, n_a))


@dataclass(frozen=True)
class TwoClassTest:
    """The tests of two classes a and b at level ``alpha``; a test that did not run has
    ``None`` for its p-value and says why (``welch_why``, ``mwu_why``)."""

    n_a: int
    n_b: int
    alpha: float
    welch_t: float | None
    welch_df: float | None
    welch_p: float | None
    welch_why: str
    mwu_u: float | None
    mwu_p: float | None
    mwu_method: str
    mwu_min_p: float
    mwu_why: str

    @property
    def ran(self) -> dict[str, float]:
        """{test name: p} of the tests that ran."""
        out = {}
        if self.welch_p is not None:
            out["Welch"] = self.welch_p
        if self.mwu_p is not None:
            out["Mann-Whitney"] = self.mwu_p
        return out

    @property
    def not_run(self) -> list[str]:
        return [why for why in (self.welch_why, self.mwu_why) if why]


def two_class_test(a: Sequence[float], b: Sequence[float], alpha: float = 0.05) -> TwoClassTest:
    """Welch's t-test (unequal variances, Welch-Satterthwaite degrees of freedom) and the
    two-sided Mann-Whitney U test of ``a`` against ``b``, each run only when it can reach
    ``alpha``. Mann-Whitney is exact: scipy's exact distribution without ties, a permutation
    over all splits with ties at midranks (up to 1e6 splits), else the normal approximation
    (``mwu_method`` says which)."""
    from scipy import stats

    a, b = [float(v) for v in a], [float(v) for v in b]
    na, nb = len(a), len(b)
    welch_t = welch_df = welch_p = None
    welch_why = ""
    if na < WELCH_MIN or nb < WELCH_MIN:
        welch_why = (
            f"Welch not testable with fewer than {WELCH_MIN} vehicles in a class "
            f"(n = {na} and {nb})"
        )
    elif np.std(a) == 0 and np.std(b) == 0:
        welch_why = "Welch: no variance within either class"
    else:
        with warnings.catch_warnings():  # a class of equal values: var 0, no precision lost
            warnings.simplefilter("ignore", RuntimeWarning)
            res = stats.ttest_ind(a, b, equal_var=False)
        welch_t, welch_p, welch_df = float(res.statistic), float(res.pvalue), float(res.df)
    floor = smallest_mann_whitney_p(na, nb)
    mwu_u = mwu_p = None
    mwu_method, mwu_why = "", ""
    splits = math.comb(na + nb, na) if na and nb else 1
    if floor >= alpha:
        mwu_why = (
            f"Mann-Whitney cannot go below p = 2 / C({na + nb}, {na}) = {floor:.3g} "
            f"with {na} against {nb}"
        )
    elif len(set(a) | set(b)) == na + nb:
        res = stats.mannwhitneyu(a, b, alternative="two-sided", method="exact")
        mwu_u, mwu_p, mwu_method = float(res.statistic), float(res.pvalue), "exact"
    elif splits <= 10**6:

        def statistic(x, y):
            return stats.mannwhitneyu(x, y, method="asymptotic").statistic

        res = stats.permutation_test(
            (a, b), statistic, n_resamples=math.inf, alternative="two-sided"
        )
        mwu_u, mwu_p = float(statistic(a, b)), float(res.pvalue)
        mwu_method = f"exact over all {splits} splits, ties at midranks"
    else:
        res = stats.mannwhitneyu(a, b, alternative="two-sided", method="asymptotic")
        mwu_u, mwu_p = float(res.statistic), float(res.pvalue)
        mwu_method = "normal approximation: ties, and too many splits to enumerate"
    return TwoClassTest(
        na,
        nb,
        alpha,
        welch_t,
        welch_df,
        welch_p,
        welch_why,
        mwu_u,
        mwu_p,
        mwu_method,
        floor,
        mwu_why,
    )
