"""R^2 (eq. 21) of a constant measurement (a stuck sensor) is undefined, not the huge negative
number the rounding of its mean gave (R^2 = -9.2e29 printed as the fit's R^2)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from railtherm.estimation import metrics


@pytest.mark.bad_input
@given(
    level=st.floats(-80.0, 120.0, allow_nan=False),
    n=st.integers(2, 500),
    miss=st.floats(0.01, 5.0),
)
def test_r2_of_a_constant_measurement_is_nan(level, n, miss):
    y = np.full(n, level)
    yhat = y + miss * np.sin(np.arange(n))
    assert math.isnan(metrics.r2(y, yhat))
    assert math.isnan(metrics.nrmse_fit(y, yhat))


def test_r2_of_a_measurement_that_varies_is_unchanged():
    y = 18.6 + 0.05 * np.cos(np.arange(100))
    yhat = y + 0.01
    ss_res = float(np.sum((y - yhat) ** 2))
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    assert metrics.r2(y, yhat) == pytest.approx(1 - ss_res / ss_tot, rel=1e-12)
