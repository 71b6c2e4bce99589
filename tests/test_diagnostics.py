"""railtherm.estimation.diagnostics: cumulated periodogram, likelihood-ratio tests, forward
selection, and the innovation figure of railtherm.report.plots."""

import math

import numpy as np
import pytest
from scipy import stats

from railtherm.estimation import diagnostics
from railtherm.estimation.diagnostics import (
    cumulated_periodogram,
    forward_selection,
    information_criteria,
    likelihood_ratio,
    residual_tests,
    selection_markdown,
)
from railtherm.report import plots

SEEDS = 200


def ar1(n: int, phi: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    w = rng.standard_normal(n)
    x = np.empty(n)
    x[0] = w[0] / math.sqrt(1.0 - phi**2)
    for t in range(1, n):
        x[t] = phi * x[t - 1] + w[t]
    return x


def binomial_bounds(n: int, p: float, tail: float = 1e-4) -> tuple[int, int]:
    """Counts outside which a Binomial(n, p) count falls with probability < 2 * tail."""
    return int(stats.binom.ppf(tail, n, p)), int(stats.binom.isf(tail, n, p))


# --- cumulated periodogram -----------------------------------------------------------------


@pytest.mark.parametrize("n", [60, 301])
def test_white_noise_is_rejected_at_about_the_nominal_rate(n):
    rejected = sum(
        not cumulated_periodogram(np.random.default_rng(seed).standard_normal(n)).white
        for seed in range(SEEDS)
    )
    lo, hi = binomial_bounds(SEEDS, 0.05)
    assert lo <= rejected <= hi, rejected


def test_white_noise_p_values_follow_the_exact_law_and_not_the_limit_law():
    """Exact: p ~ U(0, 1) for white Gaussian noise. Madsen's asymptotic band (K_alpha /
    sqrt(q)) is conservative at q = 29: its p-values lean towards 1, detectably."""
    series = [np.random.default_rng(seed).standard_normal(60) for seed in range(SEEDS)]
    exact = [cumulated_periodogram(e).p_value for e in series]
    asymptotic = [cumulated_periodogram(e, method="asymptotic").p_value for e in series]
    assert stats.kstest(exact, "uniform").pvalue > 1e-3
    assert stats.kstest(asymptotic, "uniform").pvalue < 1e-3
    assert np.mean(asymptotic) > np.mean(exact)


def test_ar1_residuals_are_rejected():
    for seed in range(5):
        for method in ("exact", "asymptotic"):
            test = cumulated_periodogram(ar1(300, 0.7, seed), method=method)
            assert not test.white and test.p_value < 1e-6
            assert test.max_deviation > test.half_width


def test_white_and_p_value_agree_and_the_band_matches_its_law():
    e = np.random.default_rng(3).standard_normal(201)
    exact = cumulated_periodogram(e, alpha=0.1)
    assert exact.q == 100 and exact.frequencies[0] == pytest.approx(1 / 201)
    assert exact.half_width == pytest.approx(stats.kstwo.isf(0.1, 99))
    assert exact.white == (exact.p_value >= 0.1)
    asym = cumulated_periodogram(e, alpha=0.05, method="asymptotic")
    assert asym.half_width == pytest.approx(1.3581 / 10.0, rel=1e-4)  # K_0.05 / sqrt(q)
    assert asym.white == (asym.p_value >= 0.05)
    assert exact.cumulated[-1] == pytest.approx(1.0)
    assert np.all(np.diff(exact.cumulated) >= 0.0)


def test_a_sinusoid_jumps_at_its_frequency():
    n = 240
    t = np.arange(n)
    e = np.random.default_rng(0).standard_normal(n) * 0.3 + np.sin(2 * np.pi * 30 * t / n)
    test = cumulated_periodogram(e)
    jump = np.argmax(np.diff(np.r_[0.0, test.cumulated]))
    assert test.frequencies[jump] == pytest.approx(30 / n)
    assert not test.white


def test_missing_rows_are_dropped_with_a_note_or_refused():
    e = np.random.default_rng(1).standard_normal(100)
    gappy = e.copy()
    gappy[[5, 40, 41, 77]] = np.nan
    test = cumulated_periodogram(gappy)
    kept = cumulated_periodogram(e[~np.isnan(gappy)])
    assert test.n == 96 and test.n_missing == 4 and "4 missing" in test.note
    np.testing.assert_array_equal(test.cumulated, kept.cumulated)
    assert test.p_value == kept.p_value
    with pytest.raises(ValueError, match="contiguous"):
        cumulated_periodogram(gappy, missing="raise")
    with pytest.raises(ValueError, match="at least 5"):
        cumulated_periodogram([1.0, 2.0, np.nan, 3.0])


def test_constant_residuals_have_nothing_to_test():
    test = cumulated_periodogram(np.full(50, 0.2))
    assert test.white and test.p_value == 1.0 and "constant" in test.note


def test_residual_tests_reuse_the_metrics_ljung_box():
    from railtherm.estimation.metrics import ljung_box

    e = ar1(400, 0.7, 2)
    both = residual_tests(e, lags=10)
    assert both.ljung_box == ljung_box(e, 10)
    assert not both.white
    d = both.to_dict()
    assert d["ljung_box_lags"] == 10 and d["cpg_p"] == both.periodogram.p_value
    assert residual_tests(np.random.default_rng(5).standard_normal(400)).white


# --- likelihood-ratio tests ----------------------------------------------------------------


def gaussian_loglik(y: np.ndarray, X: np.ndarray) -> float:
    """The maximised log-likelihood of y = X b + e, e ~ N(0, s^2) (b, s^2 at their MLE)."""
    beta, *_ = np.linalg.lstsq(X, y, rcond=None)
    r = y - X @ beta
    n = y.size
    return -0.5 * n * (math.log(2 * math.pi * float(r @ r) / n) + 1.0)


def test_lr_of_nested_gaussian_regressions_by_hand():
    rng = np.random.default_rng(11)
    n = 50
    x1, x2 = rng.standard_normal(n), rng.standard_normal(n)
    y = 1.0 + 0.3 * x2 + rng.standard_normal(n)
    small = np.column_stack([np.ones(n), x1])
    large = np.column_stack([np.ones(n), x1, x2])
    ssr = [
        float(np.sum((y - X @ np.linalg.lstsq(X, y, rcond=None)[0]) ** 2)) for X in (small, large)
    ]
    by_hand = n * math.log(ssr[0] / ssr[1])  # 2 (l1 - l0) with the variances profiled out
    test = likelihood_ratio(gaussian_loglik(y, small), gaussian_loglik(y, large), df=1)
    assert test.statistic == pytest.approx(by_hand, rel=1e-10)
    assert test.p_value == pytest.approx(stats.chi2.sf(by_hand, 1), rel=1e-10)
    assert test.reject == (test.p_value < 0.05)
    assert test.distribution == "chi2(1)"


def test_a_known_statistic_and_its_p():
    test = likelihood_ratio(-100.0, -100.0 + 3.841458820694124 / 2, df=1)
    assert test.statistic == pytest.approx(3.841458820694124)
    assert test.p_value == pytest.approx(0.05, rel=1e-9)
    assert likelihood_ratio(0.0, 5.0, df=2).p_value == pytest.approx(math.exp(-5.0))


def test_one_boundary_parameter_halves_the_chi2_1_p_value():
    for stat in (0.5, 2.0, 3.84, 9.0):
        plain = likelihood_ratio(0.0, stat / 2, df=1)
        bound = likelihood_ratio(0.0, stat / 2, df=1, boundary=1)
        assert bound.p_value == pytest.approx(0.5 * plain.p_value, rel=1e-12)
    assert "0.5 chi2(0)" in bound.distribution and "0.5 chi2(1)" in bound.distribution


def test_the_boundary_mixture_for_more_parameters():
    stat = 6.0
    one = likelihood_ratio(0.0, stat / 2, df=3, boundary=1).p_value
    assert one == pytest.approx(0.5 * stats.chi2.sf(stat, 2) + 0.5 * stats.chi2.sf(stat, 3))
    two = likelihood_ratio(0.0, stat / 2, df=2, boundary=2).p_value
    assert two == pytest.approx(0.5 * stats.chi2.sf(stat, 1) + 0.25 * stats.chi2.sf(stat, 2))


def test_a_worse_larger_fit_is_named_not_tested():
    test = likelihood_ratio(-10.0, -11.0, df=1)
    assert test.statistic == -2.0 and test.p_value == 1.0 and not test.reject
    assert "did not reach the optimum" in test.conclusion


@pytest.mark.parametrize(
    "kwargs",
    [{"df": 0}, {"df": 1, "boundary": 2}, {"df": 1, "boundary": -1}, {"df": 1, "alpha": 1.0}],
)
def test_lr_arguments_are_checked(kwargs):
    with pytest.raises(ValueError):
        likelihood_ratio(0.0, 1.0, **kwargs)


def test_information_criteria():
    ic = information_criteria(-120.0, 4, 100)
    assert ic == pytest.approx({"aic": 248.0, "bic": 240.0 + 4 * math.log(100)})


# --- forward selection ---------------------------------------------------------------------


def polynomial_candidates(seed: int, degree_true: int = 2, n: int = 120, top: int = 4):
    """Polynomial regressions of degree 0..top fitted by least squares to data from a
    polynomial of degree ``degree_true``: (name, Gaussian log-likelihood, parameters incl. s^2)."""
    rng = np.random.default_rng(seed)
    x = np.linspace(-1.0, 1.0, n)
    coef = [0.5, 1.0, -1.5, 0.8, 0.6][: degree_true + 1]
    y = np.polynomial.polynomial.polyval(x, coef) + 0.3 * rng.standard_normal(n)
    return [
        (f"poly{d}", gaussian_loglik(y, np.vander(x, d + 1, increasing=True)), d + 2)
        for d in range(top + 1)
    ]


CHAIN = [(f"poly{d}", f"poly{d + 1}") for d in range(4)]


def test_forward_selection_picks_the_true_polynomial_and_stops():
    selection = forward_selection(polynomial_candidates(seed=4), CHAIN)
    assert selection.start == "poly0" and selection.selected == "poly2"
    assert [(s.from_model, s.to_model, s.accepted) for s in selection] == [
        ("poly0", "poly1", True),
        ("poly1", "poly2", True),
        ("poly2", "poly3", False),
    ]
    assert selection[-1].decision == "rejected: not significant"
    assert selection[-1].test.p_value >= 0.05


def test_forward_selection_finds_the_true_degree_in_most_samples():
    chosen = [forward_selection(polynomial_candidates(s, 3), CHAIN).selected for s in range(40)]
    assert chosen.count("poly3") >= 32  # the level is 5 % per step; the effects are large


def test_forward_selection_chooses_the_best_significant_branch():
    candidates = [("m1", -200.0, 3), ("m2a", -190.0, 4), ("m2b", -180.0, 4), ("m3", -179.9, 5)]
    nesting = [("m1", "m2a"), ("m1", "m2b", 1), ("m2b", "m3"), ("m2a", "m3")]
    selection = forward_selection(candidates, nesting, alpha=0.05)
    assert selection.selected == "m2b"
    first = {s.to_model: s for s in selection if s.stage == 1}
    assert first["m2b"].accepted and first["m2b"].test.boundary == 1
    assert not first["m2a"].accepted and "m2b fits better" in first["m2a"].decision
    assert [s.to_model for s in selection if s.stage == 2] == ["m3"]
    d = selection.to_dict()
    assert d["selected"] == "m2b" and d["steps"][0]["from"] == "m1"


def test_forward_selection_with_nothing_to_extend():
    selection = forward_selection([{"name": "only", "loglik": -1.0, "n_params": 2}], [])
    assert selection.selected == "only" and len(selection) == 0


@pytest.mark.parametrize(
    "candidates, nesting, message",
    [
        ([("a", 0.0, 2), ("a", 1.0, 3)], [], "twice"),
        ([("a", 0.0, 2), ("b", 1.0, 3)], [("a", "c")], "not a candidate"),
        ([("a", 0.0, 2), ("b", 1.0, 2), ("c", 2.0, 3)], [("a", "c")], "cannot extend|smallest"),
        ([("a", 0.0, 2), ("b", 1.0, 2)], [], "single smallest"),
    ],
)
def test_forward_selection_refuses_bad_declarations(candidates, nesting, message):
    with pytest.raises(ValueError, match=message):
        forward_selection(candidates, nesting)


def test_selection_markdown_table():
    selection = forward_selection(polynomial_candidates(seed=4), CHAIN)
    text = selection_markdown("Tram2", selection)
    lines = text.splitlines()
    assert lines[0].startswith("**Forward selection, Tram2**") and "selected poly2" in lines[0]
    header = [c.strip() for c in lines[2].strip("|").split("|")]
    assert header == ["from", "to", "LR statistic", "df", "p", "decision"]
    assert len(lines) == 2 + 2 + 3  # caption, blank, header, rule, three steps
    assert f"{selection[0].test.statistic:.3f}" in lines[4]
    assert selection_markdown("Tram2", list(selection)).splitlines()[0] == lines[0]
    assert "No nested extension" in selection_markdown("X", [])


def test_module_imports_without_scipy_stats():
    import subprocess
    import sys

    code = "import sys, railtherm.estimation.diagnostics; print('scipy.stats' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


# --- the innovation figure -----------------------------------------------------------------


def innovations():
    n = 300
    t = np.arange(n) * 600.0
    e = np.column_stack([ar1(n, 0.6, 7) * 0.05, np.random.default_rng(8).standard_normal(n)])
    e[100:104, 0] = np.nan
    return t, e


def test_innovation_figure_is_byte_identical_in_two_runs(tmp_path):
    t, e = innovations()
    sd = np.column_stack([np.full(t.size, 0.06), np.full(t.size, 1.0)])
    for stem in ("a", "b"):
        fig = plots.innovation_figure(
            t, e, sd, title="Tram2 order2", path=tmp_path / f"{stem}.png", names=["T", "T_veh"]
        )
    assert len(fig.axes) == 6
    a, b = (tmp_path / "a.png").read_bytes(), (tmp_path / "b.png").read_bytes()
    assert a == b and len(a) > 10_000
    assert (tmp_path / "a.svg").read_bytes() == (tmp_path / "b.svg").read_bytes()


def test_innovation_figure_shows_the_tests_of_each_output():
    t, e = innovations()
    fig = plots.innovation_figure(t, {"T": e[:, 0]}, title="one output")
    texts = [x.get_text() for ax in fig.axes for x in ax.texts]
    p = diagnostics.cumulated_periodogram(
        (e[:, 0] - np.nanmean(e[:, 0])) / np.nanstd(e[:, 0], ddof=1)
    ).p_value
    assert f"KS p = {p:.2g}" in texts and any(s.startswith("Ljung-Box p") for s in texts)
    with pytest.raises(ValueError, match="values for"):
        plots.innovation_figure(t[:-1], e)
