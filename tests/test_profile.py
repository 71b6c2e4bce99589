"""Profile-likelihood limits (railtherm.estimation.profile) on hand-built
records whose limit is known: computed here with an independent first-order recursion
(numpy) and scipy's scalar minimiser, not railtherm's model code."""

import math

import numpy as np
import pytest
from scipy import optimize

from railtherm.estimation import models, pem
from railtherm.estimation.profile import CHI2_1_95, output_error_profile

S1 = models.STRUCTURES["first_order"]
DT = 600.0
KA = 900.0


def programme(n, rng):
    """Heater steps every 6 h (0-30 kW), outdoor air at -10 degC."""
    q = 3000.0 * rng.integers(0, 11, size=n // 36 + 1)[np.arange(n) // 36]
    return np.column_stack([np.full(n, -10.0), q])


def simulate(kA, C_bar, u, x0):
    """T_{k+1} = a T_k + (1 - a)(T_o + Q_k / kA), a = exp(-kA dt / C_bar): eq. 9 held over
    each step (independent of railtherm.estimation.models)."""
    a = math.exp(-kA * DT / C_bar)
    x = np.empty(len(u))
    x[0] = x0
    steady = u[:, 0] + u[:, 1] / kA
    for k in range(len(u) - 1):
        x[k + 1] = a * x[k] + (1.0 - a) * steady[k]
    return x


def record(C_bar, n=300, seed=0, sd=0.05):
    rng = np.random.default_rng(seed)
    u = programme(n, rng)
    x = simulate(KA, C_bar, u, -10.0)
    y = (x + rng.normal(0.0, sd, n))[:, None]
    return pem.Experiment("r", DT, u, y, x0=y[0].copy())


def reference_profile(e, grid):
    """(m / 2) log(e^T e) with C_bar held at each value of ``grid`` and kA re-estimated by
    scipy's bounded scalar minimiser; the initial state is the first reading."""
    y = e.y[:, 0]
    m = len(y) - 1  # the first row is the initial state itself

    def sse(C_bar, log_kA):
        return float(np.sum((simulate(math.exp(log_kA), C_bar, e.u, y[0])[1:] - y[1:]) ** 2))

    out = []
    for C_bar in grid:
        res = optimize.minimize_scalar(
            lambda z, c=C_bar: sse(c, z), bounds=(math.log(300), math.log(3000)),
            method="bounded", options={"xatol": 1e-9},
        )  # fmt: skip
        out.append(0.5 * m * math.log(res.fun))
    return np.array(out)


def crossing(grid, values, threshold):
    """The value of ``grid`` where ``values`` first rises above threshold going from their
    minimum along the grid's order, interpolated in log grid."""
    start = int(np.argmin(values))
    j = start + int(np.nonzero(values[start:] > threshold)[0][0])
    t = (threshold - values[j - 1]) / (values[j] - values[j - 1])
    return math.exp(math.log(grid[j - 1]) + t * (math.log(grid[j]) - math.log(grid[j - 1])))


def test_a_body_faster_than_the_step_has_an_upper_limit_the_data_give():
    """C_bar of 3e4 J/K against kA 900 W/K: a time constant of 33 s in 600 s steps, so the
    response is complete within a step and any smaller C_bar fits as well: the data set an
    upper limit only. railtherm's fit leaves C_bar not identified; its profile finds the
    upper limit where the independent reference's profile crosses 1.92, within 5 %, and no
    lower limit."""
    e = record(3.0e4)
    fit = pem.fit(S1, [e], covariance="iid", x0="measured")
    lo, hi = fit.ci95["C_bar"]
    assert not (lo > 0 and hi / lo <= 1000.0) or fit.flags  # the fit cannot say
    limit = output_error_profile(S1, [e], "C_bar", fit, x0="measured")
    assert limit.kind == "upper", limit
    grid = np.geomspace(1e3, 3e6, 400)
    ref = reference_profile(e, grid)
    threshold = ref.min() + CHI2_1_95 / 2.0
    assert ref[0] - ref.min() < 0.5  # flat below: no lower limit
    expected = crossing(grid, ref, threshold)
    assert limit.upper == pytest.approx(expected, rel=0.05)
    assert limit.lower is None


def test_a_determined_parameter_gets_its_two_sided_interval():
    """A time constant of 5 h in 10-minute steps: C_bar is determined, and the profile's
    two-sided interval matches the reference's crossings within 5 % of its half-width (and
    the Wald interval of the fit's iid covariance, the problem being nearly linear)."""
    e = record(1.6e7)
    fit = pem.fit(S1, [e], covariance="iid", x0="measured")
    limit = output_error_profile(S1, [e], "C_bar", fit, x0="measured")
    assert limit.kind == "two_sided"
    c = fit.theta["C_bar"]
    grid = np.geomspace(c * 0.99, c * 1.01, 401)
    ref = reference_profile(e, grid)
    threshold = ref.min() + CHI2_1_95 / 2.0
    upper = crossing(grid, ref, threshold)
    lower = crossing(grid[::-1], ref[::-1], threshold)
    half = math.log(upper / lower) / 2.0
    assert abs(math.log(limit.upper / upper)) < 0.05 * half
    assert abs(math.log(limit.lower / lower)) < 0.05 * half
    assert half == pytest.approx(1.959964 * fit.sd_log["C_bar"], rel=0.05)


def test_a_kalman_fits_profile_gives_the_same_upper_limit():
    """The same fast body by the Kalman filter's likelihood with the diffusion held at 0:
    its measurement variance re-estimated at each C_bar makes the profile (m / 2) log(e^T e)
    up to a constant, so its upper limit is the independent reference's, within 5 %."""
    from railtherm.estimation import kalman
    from railtherm.estimation.profile import kalman_profile

    e = record(3.0e4)
    fit = kalman.fit(S1, [e], x0="measured", fixed={"sigma_T": 0.0})
    limit = kalman_profile(S1, [e], "C_bar", fit, x0="measured", fixed={"sigma_T": 0.0})
    assert limit.kind == "upper", limit
    grid = np.geomspace(1e3, 3e6, 400)
    ref = reference_profile(e, grid)
    expected = crossing(grid, ref, ref.min() + CHI2_1_95 / 2.0)
    assert limit.upper == pytest.approx(expected, rel=0.05)
    assert limit.lower is None


def test_a_profile_that_rises_right_beside_its_estimate_places_its_crossing_there():
    """A prior that contradicts the record (a units mistake: kJ/K for J/K) leaves a criterion
    beyond the threshold at every value but the estimate. Before, the bisection drew ever
    closer to the estimate, a refit each time (a fit of a minute ran past 5 minutes); now a
    crossing takes at most BISECTIONS refits and sits at the estimate."""
    from railtherm.estimation import profile

    calls = []

    def criterion(value, warm):
        calls.append(value)
        return (0.0 if value == 2.0e6 else 10.0), warm

    limit = profile.profile_limit("C", 2.0e6, (1.0e4, 1.0e9), criterion, minimum=0.0)
    assert limit.kind == "two_sided"
    assert limit.lower == pytest.approx(2.0e6, rel=1e-3) and limit.upper == pytest.approx(
        2.0e6, rel=1e-3
    )
    assert len(calls) <= 2 * (1 + profile.BISECTIONS)
