"""railtherm.estimation.metrics: R^2 (eq. 21), the NRMSE fit, residual whiteness, AIC/BIC, the
verdict."""

import math

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st
from scipy import stats

from railtherm.estimation import metrics
from railtherm.study import quality

Y = [1.0, 2.0, 3.0, 4.0]
YHAT = [1.0, 2.0, 3.0, 5.0]  # SS_res = 1, SS_tot = 5 (eqs. 22, 23)


def test_hand_computed_values():
    assert metrics.r2(Y, YHAT) == pytest.approx(0.8, abs=1e-15)
    assert metrics.nrmse_fit(Y, YHAT) == pytest.approx(1.0 - math.sqrt(0.2), abs=1e-15)
    assert metrics.rmse(Y, YHAT) == pytest.approx(0.5, abs=1e-15)


def test_r2_of_a_perfect_fit_is_one_and_of_the_mean_is_zero():
    y = np.sin(np.linspace(0.0, 7.0, 101)) + 20.0
    assert metrics.r2(y, y) == 1.0
    assert metrics.r2(y, np.full_like(y, y.mean())) == pytest.approx(0.0, abs=1e-12)
    assert metrics.nrmse_fit(y, y) == 1.0
    assert metrics.nrmse_fit(y, np.full_like(y, y.mean())) == pytest.approx(0.0, abs=1e-12)
    assert metrics.r2(y, y.mean() - (y - y.mean())) == pytest.approx(-3.0)  # worse than mean


def test_nan_rows_are_skipped_in_either_series():
    y = [1.0, 2.0, np.nan, 3.0, 4.0, 9.0]
    yhat = [1.0, 2.0, 7.0, 3.0, 5.0, np.nan]
    assert metrics.r2(y, yhat) == pytest.approx(0.8)
    assert metrics.nrmse_fit(y, yhat) == pytest.approx(1.0 - math.sqrt(0.2))
    assert metrics.rmse(y, yhat) == pytest.approx(0.5)


def test_undefined_cases_give_nan_and_bad_shapes_raise():
    assert math.isnan(metrics.r2([5.0, 5.0, 5.0], [5.0, 5.0, 4.0]))  # SS_tot = 0
    assert math.isnan(metrics.r2([np.nan], [1.0]))
    assert math.isnan(metrics.nrmse_fit([], []))
    assert math.isnan(metrics.rmse([np.nan], [np.nan]))
    with pytest.raises(ValueError, match="equal length"):
        metrics.r2([1.0, 2.0], [1.0])
    with pytest.raises(ValueError, match="1-D"):
        metrics.r2(np.ones((3, 2)), np.ones((3, 2)))


finite = st.floats(-50.0, 50.0, allow_nan=False)


@given(
    y=st.lists(finite, min_size=3, max_size=40),
    noise=st.lists(st.floats(-5.0, 5.0), min_size=40, max_size=40),
    c=st.floats(-1e3, 1e3),
)
def test_r2_is_invariant_to_a_common_offset_and_matches_nrmse_fit(y, noise, c):
    y = np.asarray(y)
    yhat = y + np.asarray(noise[: y.size])
    assume(np.sum((y - y.mean()) ** 2) > 1e-3)
    r = metrics.r2(y, yhat)
    assert metrics.r2(y + c, yhat + c) == pytest.approx(r, rel=1e-9, abs=1e-9)
    fit = metrics.nrmse_fit(y, yhat)
    assert r == pytest.approx(1.0 - (1.0 - fit) ** 2, rel=1e-12, abs=1e-12)
    assert metrics.r2_from_nrmse_fit(fit) == pytest.approx(r, rel=1e-12, abs=1e-12)
    assert r <= 1.0 and fit <= 1.0


def test_autocorrelation_by_hand_and_against_a_direct_sum():
    rho = metrics.autocorrelation([1.0, -1.0, 1.0, -1.0])
    np.testing.assert_allclose(rho, [1.0, -0.75, 0.5, -0.25], atol=1e-15)
    e = np.random.default_rng(1).normal(size=57)
    d = e - e.mean()
    direct = [d[: d.size - k] @ d[k:] / (d @ d) for k in range(11)]
    np.testing.assert_allclose(metrics.autocorrelation(e, 10), direct, atol=1e-12)
    assert metrics.autocorrelation(e, 1000).size == e.size  # clipped
    assert np.isnan(metrics.autocorrelation([2.0, 2.0, 2.0])).all()


def test_ljung_box_by_hand():
    e = np.array([0.3, -1.2, 0.8, 0.1, -0.4, 1.5, -0.9, 0.2, 0.6, -1.0])
    d = e - e.mean()
    m = e.size
    rho = [d[: m - k] @ d[k:] / (d @ d) for k in (1, 2)]
    q = m * (m + 2) * (rho[0] ** 2 / (m - 1) + rho[1] ** 2 / (m - 2))
    w = metrics.ljung_box(e)  # default lags: min(20, 10 // 5) = 2
    assert (w.lags, w.dof, w.m) == (2, 2, 10)
    assert w.q == pytest.approx(q, rel=1e-12)
    assert w.p_value == pytest.approx(stats.chi2.sf(q, 2), rel=1e-12)
    assert metrics.ljung_box(e, lags=3, fitted=1).dof == 2
    with pytest.raises(ValueError, match="lags"):
        metrics.ljung_box(e, lags=10)
    with pytest.raises(ValueError, match="fitted"):
        metrics.ljung_box(e, lags=2, fitted=2)


def test_ljung_box_p_is_uniformish_on_white_noise_and_tiny_on_coloured_noise():
    rng = np.random.default_rng(20240)
    p = np.array([metrics.ljung_box(rng.normal(size=400)).p_value for _ in range(300)])
    assert stats.kstest(p, "uniform").pvalue > 0.01
    assert 0.02 < np.mean(p < 0.05) < 0.09
    # AR(1), phi = 0.9: tau = (1 + phi) / (1 - phi) = 19
    e = np.zeros(20_000)
    x = rng.normal(size=e.size)
    for n in range(1, e.size):
        e[n] = 0.9 * e[n - 1] + x[n]
    w = metrics.ljung_box(e)
    assert w.p_value < 1e-12 and not w.white()
    assert w.tau == pytest.approx(19.0, rel=0.2)
    assert w.effective_samples == pytest.approx(e.size / w.tau)
    white = metrics.ljung_box(rng.normal(size=20_000))
    assert white.tau < 1.3 and white.white()


def test_ljung_box_skips_nan_rows():
    e = np.random.default_rng(3).normal(size=200)
    gappy = e.copy()
    gappy[[5, 50, 120]] = np.nan
    w = metrics.ljung_box(gappy)
    assert w.m == 197 and math.isfinite(w.q) and 0.0 <= w.p_value <= 1.0


def test_aic_and_bic_by_hand_and_they_prefer_the_true_order():
    assert metrics.aic(2.0, 10, 3) == pytest.approx(10 * math.log(0.2) + 6)
    assert metrics.bic(2.0, 10, 3) == pytest.approx(10 * math.log(0.2) + 3 * math.log(10))
    # a 4-parameter model whose SSR is barely lower than a 2-parameter one loses
    assert metrics.aic(99.9, 1000, 4) > metrics.aic(100.0, 1000, 2)
    assert metrics.bic(50.0, 1000, 4) < metrics.bic(100.0, 1000, 2)


def test_summary_labels_r2_and_nrmse_fit_apart():
    rng = np.random.default_rng(7)
    y = np.cumsum(rng.normal(size=500))
    yhat = y + rng.normal(scale=0.3, size=500)
    s = quality.summary(y, yhat, p=3)
    assert "fit" not in s
    assert s["r2"] == pytest.approx(metrics.r2(y, yhat))
    assert s["nrmse_fit"] == pytest.approx(metrics.nrmse_fit(y, yhat))
    assert s["m"] == 500 and s["p"] == 3
    assert s["aic"] == pytest.approx(metrics.aic(s["ssr"], 500, 3))
    assert s["ljung_box_lags"] == 20
    assert all(isinstance(v, int | float) for v in s.values())


GOOD = metrics.Whiteness(
    q=5.0, p_value=0.5, lags=20, dof=20, m=1000, tau=1.0, effective_samples=1e3
)
COLOURED = metrics.Whiteness(
    q=9e3, p_value=0.0, lags=20, dof=20, m=1000, tau=250.0, effective_samples=4.0
)


def test_verdict_acceptable_only_without_reasons():
    assert quality.verdict(0.99, [], GOOD) == ("fit acceptable", [])
    assert quality.verdict(0.99) == ("fit acceptable", [])


def test_verdict_reasons_name_the_numbers():
    label, reasons = quality.verdict(0.85, [], GOOD)
    assert label == "assumptions in doubt"
    assert reasons == ["R^2 = 0.8500 is below 0.9."]
    assert quality.verdict(0.85, thresholds={"r2_min": 0.8})[0] == "fit acceptable"
    label, reasons = quality.verdict(0.99, [], COLOURED)
    assert label == "assumptions in doubt" and "strongly coloured" in reasons[0]
    assert "250" in reasons[0]
    label, reasons = quality.verdict({"step_up": 0.99, "step_down": float("nan")})
    assert reasons == ["R^2 (step_down) is undefined (no usable rows or a constant measurement)."]


def test_verdict_passes_identifiability_flags_through_in_any_form():
    class Flag:
        code = "wide_interval"
        message = "C_veh: 95 % interval spans more than a decade."

    flags = [
        "K_veh is at its lower bound.",
        {"code": "correlated", "message": "C and C_veh correlate (0.97)."},
        Flag(),
        ("ill_conditioned", "The Jacobian is ill-conditioned (cond 3e9)."),
    ]
    label, reasons = quality.verdict(0.995, flags, GOOD)
    assert label == "assumptions in doubt"
    assert reasons == [
        "K_veh is at its lower bound.",
        "C and C_veh correlate (0.97).",
        "C_veh: 95 % interval spans more than a decade.",
        "The Jacobian is ill-conditioned (cond 3e9).",
    ]


def test_verdict_whiteness_options():
    not_white = metrics.Whiteness(
        q=80.0, p_value=1e-6, lags=20, dof=20, m=1000, tau=1.5, effective_samples=667.0
    )
    assert quality.verdict(0.99, [], not_white)[0] == "fit acceptable"  # informative only
    label, reasons = quality.verdict(0.99, [], not_white, {"require_white": True})
    assert label == "assumptions in doubt" and "Ljung-Box p = 1e-06" in reasons[0]
    # the YAML form and per-experiment mappings are accepted too
    assert quality.verdict(0.99, [], COLOURED.to_dict())[0] == "assumptions in doubt"
    _, reasons = quality.verdict(0.99, [], {"a": GOOD, "b": COLOURED})
    assert len(reasons) == 1 and "(b)" in reasons[0]
    with pytest.raises(ValueError, match="unknown"):
        quality.verdict(0.99, thresholds={"r2": 0.5})


def test_verdict_takes_per_window_summaries_as_whiteness():
    """The form the check rule passes: {window: summary(...)} and flags as dicts."""
    import pandas as pd

    rng = np.random.default_rng(11)
    t = np.arange(600.0)
    y = pd.Series(np.sin(t / 50.0))
    good = quality.summary(y, y + rng.normal(scale=0.05, size=600), p=3)
    drifting = quality.summary(y, y + 0.2 * np.sin(t / 150.0), p=3)  # a slow, missed dynamic
    label, reasons = quality.verdict(
        {"T": good["r2"]},
        [{"code": "at_bound", "parameters": ["K_veh"], "message": "K_veh is at a bound."}],
        whiteness={"step_up": good, "step_down": drifting},
    )
    assert label == "assumptions in doubt"
    assert reasons[0] == "K_veh is at a bound."
    assert len(reasons) == 2 and "(step_down)" in reasons[1] and "strongly coloured" in reasons[1]
