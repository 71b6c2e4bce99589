"""The verdict's whiteness criteria are judged as families at their stated level (Holm): on
white residuals the share put in doubt stays at or below whiteness_alpha however many outputs
and tests there are, where judging each test alone at that level cried wolf up to
2 x outputs times as often."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy.stats import binomtest

from railtherm.estimation import diagnostics, metrics
from railtherm.records import EstimateRecord
from railtherm.study import identify, quality

ALPHA = 0.05


def test_holm_adjusts_by_hand():
    # sorted 0.01, 0.02, 0.04, 0.30 times 4, 3, 2, 1 -> 0.04, 0.06, 0.08, 0.30 (monotone)
    adjusted = diagnostics.holm([0.04, 0.30, 0.01, 0.02])
    np.testing.assert_allclose(adjusted, [0.08, 0.30, 0.04, 0.06])
    # the step-down keeps the adjusted p non-decreasing (0.03 x 1 < 0.024 x 2) and caps it at 1
    np.testing.assert_allclose(diagnostics.holm([0.03, 0.01, 0.024]), [0.048, 0.03, 0.048])
    np.testing.assert_allclose(diagnostics.holm([0.6, 0.7]), [1.0, 1.0])
    # a NaN is no test: it stays NaN and does not count
    np.testing.assert_allclose(diagnostics.holm([0.02, np.nan]), [0.02, np.nan])
    assert diagnostics.holm([]).size == 0


@pytest.mark.bad_input
def test_holm_refuses_what_is_no_p_value():
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        diagnostics.holm([0.5, 1.5])
    with pytest.raises(ValueError, match="1-D"):
        diagnostics.holm([[0.1, 0.2]])


def test_holm_holds_the_family_level_that_single_tests_exceed():
    """4 independent tests of true null hypotheses, 4000 times: any test alone at 5 % rejects
    in about 1 - 0.95^4 = 18.5 % of the families, Holm in at most 5 %."""
    p = np.random.default_rng(7).uniform(size=(4000, 4))
    single = np.mean((p < ALPHA).any(axis=1))
    family = np.mean([(diagnostics.holm(row) < ALPHA).any() for row in p])
    assert single > 0.17
    assert family <= ALPHA + 3 * np.sqrt(ALPHA * (1 - ALPHA) / 4000)


def test_two_whiteness_tests_of_white_noise_reject_at_most_at_their_level():
    """Ljung-Box and the cumulated periodogram on the same white series: judged as one family
    (ResidualTests.white) they reject white noise at most at alpha; either alone at alpha,
    more often than alpha."""
    rng = np.random.default_rng(11)
    n, k_family, k_union = 300, 0, 0
    for _ in range(n):
        tests = diagnostics.residual_tests(rng.standard_normal(240), alpha=ALPHA)
        k_family += not tests.white
        k_union += not (tests.ljung_box.white(ALPHA) and tests.periodogram.white)
    assert k_union > k_family
    # the family's rate is at most alpha: its 95 % interval's lower end stays below it
    assert binomtest(k_family, n).proportion_ci(0.95).low <= ALPHA
    assert k_family / n <= ALPHA + 0.02


def innovations_estimate(series: pd.DataFrame, outputs: list[str]) -> EstimateRecord:
    return EstimateRecord.from_dict(
        {"innovations": identify.innovation_tests(series, outputs, ALPHA)}
    )


def test_kalman_innovations_of_two_white_outputs_put_a_fit_in_doubt_at_most_at_alpha():
    """The four tests of a Kalman fit with surface sensors (Ljung-Box and periodogram of T and
    T_veh) on white standardised innovations, 200 fits: the criterion fails in at most 5 %
    (each test alone at 5 % would fail up to about 4 times as often)."""
    rng = np.random.default_rng(5)
    m, runs, failed, union = 240, 200, 0, 0
    for _ in range(runs):
        series = pd.DataFrame(
            {
                "T_innovation": rng.standard_normal(m),
                "T_innovation_sd": np.ones(m),
                "T_veh_innovation": rng.standard_normal(m),
                "T_veh_innovation_sd": np.ones(m),
            }
        )
        estimate = innovations_estimate(series, ["T", "T_veh"])
        failed += bool(quality.innovation_reasons(estimate, {"whiteness_alpha": ALPHA}))
        union += any(
            min(t["ljung_box_p"], t["cpg_p"]) < ALPHA
            for t in estimate.section("innovations").values()
        )
    assert union > 2 * failed
    assert failed / runs <= ALPHA + 0.02


def test_a_single_test_below_alpha_is_no_reason_unless_holm_rejects_it():
    """T's Ljung-Box p = 0.03 among four tests: not white at 0.05 on its own, but Holm's
    adjusted p is 0.12 - no reason; p = 0.004 (adjusted 0.016): the reason names T, both raw
    p-values, the adjusted ones and the family."""

    def reasons(p_lb: float) -> list[str]:
        estimate = {
            "innovations": {
                "T": {"ljung_box_p": p_lb, "cpg_p": 0.5, "white": p_lb >= ALPHA},
                "T_veh": {"ljung_box_p": 0.6, "cpg_p": 0.7, "white": True},
            }
        }
        record = EstimateRecord.from_dict(estimate)
        return quality.innovation_reasons(record, {"whiteness_alpha": ALPHA})

    assert reasons(0.03) == []
    (reason,) = reasons(0.004)
    assert "innovations of T are not white" in reason
    assert "Ljung-Box p = 0.004" in reason and "adjusted 0.016" in reason
    assert "Holm over 4 tests" in reason and "0.05" in reason


def test_a_clearly_coloured_output_is_still_found():
    """Holm costs little power against a real misfit: AR(1) innovations at 0.5 are rejected."""
    rng = np.random.default_rng(2)
    e = rng.standard_normal(400)
    ar = np.empty_like(e)
    ar[0] = e[0]
    for i in range(1, e.size):
        ar[i] = 0.5 * ar[i - 1] + e[i]
    series = pd.DataFrame(
        {
            "T_innovation": ar,
            "T_innovation_sd": np.ones(e.size),
            "T_veh_innovation": rng.standard_normal(e.size),
            "T_veh_innovation_sd": np.ones(e.size),
        }
    )
    (reason,) = quality.innovation_reasons(
        innovations_estimate(series, ["T", "T_veh"]), {"whiteness_alpha": ALPHA}
    )
    assert "innovations of T are not white" in reason


def whiteness(p: float) -> metrics.Whiteness:
    return metrics.Whiteness(
        q=1.0, p_value=p, lags=10, dof=10, m=500, tau=1.0, effective_samples=500.0
    )


def test_require_white_judges_the_outputs_as_one_family():
    """With require_white, the simulation residuals of T and T_veh are one family: p = 0.03
    and 0.5 is no reason (Holm-adjusted 0.06); p = 0.01 is (adjusted 0.02), naming it."""
    thresholds = {"require_white": True, "whiteness_alpha": ALPHA}
    label, reasons = quality.verdict(
        1.0, whiteness={"T": whiteness(0.03), "T_veh": whiteness(0.5)}, thresholds=thresholds
    )
    assert label == quality.ACCEPTABLE and reasons == []
    label, reasons = quality.verdict(
        1.0, whiteness={"T": whiteness(0.01), "T_veh": whiteness(0.5)}, thresholds=thresholds
    )
    assert label == quality.IN_DOUBT
    (reason,) = reasons
    assert "(T) are not white" in reason and "adjusted 0.02" in reason
    # one series alone: its own p at alpha, as before
    _, reasons = quality.verdict(1.0, whiteness=whiteness(0.03), thresholds=thresholds)
    assert len(reasons) == 1 and "p = 0.03 < 0.05" in reasons[0]
