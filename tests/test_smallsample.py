"""railtherm.study.smallsample: statistics for two to five vehicles per class."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from railtherm.study import smallsample


def test_t_interval_by_hand():
    # n = 4, mean 437.5, sd 180.28; t(0.975, 3) = 3.1824463
    lo, hi = smallsample.t_interval([300.0, 350.0, 400.0, 700.0])
    half = 3.182446305284263 * np.std([300.0, 350.0, 400.0, 700.0], ddof=1) / 2.0
    assert (lo, hi) == pytest.approx((437.5 - half, 437.5 + half))
    lo, hi = smallsample.t_interval([270.0, 330.0], positive=True)  # t(0.975, 1) = 12.706
    assert lo == 0.0 and hi == pytest.approx(300.0 + 12.706204736174698 * 30.0)
    assert all(math.isnan(v) for v in smallsample.t_interval([5.0]))


def test_t_interval_covers_95_percent_at_n_3():
    """The property a percentile bootstrap of three values lacks (about 75 % there)."""
    rng = np.random.default_rng(7)
    hits = 0
    for _ in range(4000):
        lo, hi = smallsample.t_interval(rng.normal(10.0, 2.0, 3))
        hits += lo <= 10.0 <= hi
    assert 0.935 < hits / 4000 < 0.965


def test_smallest_attainable_mann_whitney_p():
    assert smallsample.smallest_mann_whitney_p(3, 2) == pytest.approx(2 / 10)
    assert smallsample.smallest_mann_whitney_p(4, 3) == pytest.approx(2 / 35)
    assert smallsample.smallest_mann_whitney_p(5, 4) == pytest.approx(2 / 126)
    assert smallsample.smallest_mann_whitney_p(1, 1) == 1.0
    assert smallsample.smallest_mann_whitney_p(0, 3) == 1.0


def test_the_published_table_3_classes_differ():
    """The paper's Table 3: every regional c_veh above every metro one."""
    test = smallsample.two_class_test([533, 304, 175, 487, 360], [664, 577, 595, 703])
    assert test.mwu_u == 0 and test.mwu_p == pytest.approx(2 / 126)
    assert test.welch_p == pytest.approx(0.0115, abs=5e-4) and test.mwu_method == "exact"
    assert test.ran == {"Welch": test.welch_p, "Mann-Whitney": test.mwu_p}


def test_a_test_that_cannot_reach_alpha_is_not_run_and_says_why():
    test = smallsample.two_class_test([1.0, 2.0, 3.0], [10.0, 11.0])
    assert test.mwu_p is None and "cannot go below p = 2 / C(5, 3) = 0.2" in test.mwu_why
    # Welch needs 3 per class: with 2 a class's sd is one difference; not testable
    assert test.welch_p is None and "Welch not testable" in test.welch_why
    assert test.ran == {}
    three = smallsample.two_class_test([1.0, 2.0, 3.0], [10.0, 11.0, 12.5])
    assert three.welch_p is not None
    lonely = smallsample.two_class_test([1.0], [10.0, 11.0])
    assert lonely.ran == {} and len(lonely.not_run) == 2


def test_ties_are_handled_by_an_exact_permutation():
    test = smallsample.two_class_test([1.0, 1.0, 2.0, 3.0], [3.0, 4.0, 5.0, 6.0])
    assert test.mwu_method.startswith("exact over all 70 splits")
    assert 0 < test.mwu_p < 1


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.integers(0, 1000).map(float), min_size=1, max_size=6),
    st.lists(st.integers(0, 1000).map(float), min_size=1, max_size=6),
)
def test_a_p_value_is_never_below_what_its_test_can_attain(a, b):
    test = smallsample.two_class_test(a, b)
    if test.mwu_p is not None:
        assert test.mwu_p >= test.mwu_min_p * (1 - 1e-9)
        assert test.mwu_min_p < 0.05
    else:
        assert test.mwu_min_p >= 0.05
