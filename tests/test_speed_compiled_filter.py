"""The compiled row recursions (railtherm.estimation.loops) against the numpy implementations
they replace in a Kalman fit: the filter's likelihood, gradient, Fisher information and series
(against the numpy filter run row by row, time-varying, in filtering._filter), and the
output-error start's cost with its best initial states (against the numpy one and a direct
solve from models.simulate)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_kalman import SIE, likelihood, random_point, sde_experiment

from railtherm.estimation import common, filtering, models, pem


def _numpy_reference(lik, v, order, monkeypatch):
    with monkeypatch.context() as m:
        m.setattr(filtering, "COMPILED", False)
        return lik.evaluate(np.asarray(v) + 0.0, order, steady=False)


@pytest.mark.parametrize(
    ("x0", "outputs", "hold", "gap"),
    [
        ("measured", (0, 1), "zero_order", True),
        ("estimated", (0, 1), "first_order", True),
        ("measured", (0,), "first_order", False),
        ("estimated", (0,), "zero_order", False),
    ],
)
def test_compiled_filter_equals_the_numpy_filter(x0, outputs, hold, gap, monkeypatch):
    """NLL, gradient and Fisher information of the compiled filter (with its held gain once
    converged, and without) equal the numpy filter's on every row: both outputs or T alone,
    a gap in the record, a second output missing on some rows, both holds."""
    e = sde_experiment(n=900, seed=11)
    e = pem.Experiment("e", e.dt, e.u, e.y.copy(), hold=hold)
    if gap:
        e.y[300:340] = np.nan
        e.y[500:520, 1] = np.nan
    if outputs == (0,):
        e.y[:, 1] = np.nan
    lik = likelihood([e], x0=x0, outputs=outputs)
    v = random_point(lik, [e])
    nll, grad, fisher = _numpy_reference(lik, v, 2, monkeypatch)
    for steady in (True, False):
        lik._cache = {}
        got = lik.evaluate(v, 2, steady=steady)
        assert got[0] == pytest.approx(nll, rel=1e-12, abs=1e-8)
        np.testing.assert_allclose(got[1], grad, rtol=1e-8, atol=1e-8 * np.abs(grad).max())
        np.testing.assert_allclose(got[2], fisher, rtol=1e-7, atol=1e-8 * np.abs(fisher).max())
    if outputs == (0, 1):  # both states measured: the gain converges within the record
        assert lik.passes(v, 0)[0].steady_from


def test_compiled_filter_series_equal_the_numpy_filter(monkeypatch):
    """The one-step predictions, innovations and their variances a fit reports."""
    e = sde_experiment(n=400, seed=12)
    e.y[100:110, 0] = np.nan
    lik = likelihood([e], x0="measured")
    v = random_point(lik, [e])
    got = lik.passes(v, 0, series=True)[0]
    with monkeypatch.context() as m:
        m.setattr(filtering, "COMPILED", False)
        ref = lik.passes(v, 0, steady=False, series=True)[0]
    for a, b in ((got.xp, ref.xp), (got.eps, ref.eps), (got.rvar, ref.rvar)):
        np.testing.assert_array_equal(np.isnan(a), np.isnan(b))
        np.testing.assert_allclose(a[~np.isnan(a)], b[~np.isnan(b)], rtol=1e-9, atol=1e-12)


def test_compiled_filter_refuses_a_covariance_that_is_not_positive():
    """A negative measurement variance: the likelihood cannot be evaluated (inf), as the
    numpy filter reports it."""
    e = sde_experiment(n=50, seed=13)
    lik = likelihood([e], x0="measured")
    v = random_point(lik, [e])
    lik.meas_var0 = np.array([-1.0, -1.0])
    lik.meas_var_free = ()
    lik.Qn = lik.Qg = lik.P + len(lik.sigma_free)
    assert lik.evaluate(v[: lik.Qg].copy(), 1)[0] == np.inf


@pytest.mark.parametrize("hold", ["zero_order", "first_order"])
def test_start_cost_with_best_initial_states_equals_a_direct_solve(hold):
    """The output-error start's cost at given parameters with the unmeasured initial state at
    its least-squares best within the measured range (pem._Problem.cost_x0_projected), by the
    compiled simulation and by numpy, equals the one computed here from two simulations (the
    output is affine in the initial state), with rows missing."""
    rng = np.random.default_rng(4)
    n = 300
    u = np.column_stack([rng.uniform(-5, 10, n), rng.uniform(0, 2000, n)])
    theta = {"C": 1.6e6, "K_i": 500.0, "C_e": 1.5e7, "K_o": 57.0}
    x = models.simulate(SIE, theta, u, 1800.0, [21.0, 18.0], hold)
    y = np.column_stack([x[:, 0] + 0.05 * rng.standard_normal(n), np.full(n, np.nan)])
    y[40:60, 0] = np.nan
    e = pem.Experiment("e", 1800.0, u, y, hold=hold)
    trial = {"C": 2.0e6, "K_i": 400.0, "C_e": 1.0e7, "K_o": 70.0}
    v = np.concatenate([np.log([trial[p] for p in SIE.parameters]), [15.0]])
    ok = np.isfinite(y[:, 0])
    a = models.simulate(SIE, trial, u, 1800.0, [y[0, 0], 0.0], hold)[ok, 0]
    b = models.simulate(SIE, trial, u, 1800.0, [y[0, 0], 1.0], hold)[ok, 0] - a
    best = float(np.clip(np.dot(b, y[ok, 0] - a) / np.dot(b, b), *common.measured_range(e)))
    for compiled in (True, False):
        prob = pem._Problem(SIE, [e], {}, SIE.parameters, (0,), "measured", compiled)
        cost, w = prob.cost_x0_projected(v)
        assert w[-1] == pytest.approx(best, rel=1e-9)
        assert cost == pytest.approx(float(np.sum((a + best * b - y[ok, 0]) ** 2)), rel=1e-9)


@settings(max_examples=60, deadline=None)  # the first example compiles or loads the loop
@given(
    n=st.integers(1, 4),
    outputs=st.integers(1, 3),
    seed=st.integers(0, 2**16),
    slow=st.floats(0.0, 0.99999),
)
def test_the_stationary_covariance_is_scipys_riccati_solution(n, outputs, seed, slow):
    """The doubling solution of the filter's Riccati equation equals scipy's QZ solution
    (solve_discrete_are) within 1e-8 of the largest entry, and solves the equation to 1e-9
    (QZ's own residual reached 7e-10 over 2000 such systems), on random stable networks with
    one slow mode, noise from 1e-8 to 1 and some outputs measured."""
    from scipy.linalg import solve_discrete_are

    rng = np.random.default_rng(seed)
    V = rng.normal(size=(n, n)) + 3.0 * np.eye(n)
    lam = rng.uniform(0.0, 0.95, n)
    lam[0] = slow
    Ad = V @ np.diag(lam) @ np.linalg.inv(V)
    B = rng.normal(size=(n, n))
    Qd = B @ B.T * 10.0 ** rng.uniform(-8, 0) + 1e-12 * np.eye(n)
    C = rng.normal(size=(min(outputs, n), n))
    S = 10.0 ** rng.uniform(-6, 0, len(C))
    expected = solve_discrete_are(Ad.T, C.T, Qd, np.diag(S))
    P = filtering.stationary_covariance(Ad, C, Qd, S)
    scale = np.abs(expected).max()
    assert np.abs(P - expected).max() <= 1e-8 * scale
    R = C @ P @ C.T + np.diag(S)
    residual = Ad @ P @ Ad.T + Qd - Ad @ P @ C.T @ np.linalg.solve(R, C @ P @ Ad.T) - P
    assert np.abs(residual).max() <= 1e-9 * scale


def test_a_zero_measurement_variance_leaves_the_riccati_equation_to_qz():
    """A measurement without noise (S = 0 for one output: G = C^T S^-1 C does not exist) is
    solved by scipy's QZ method, whose solution the filter then uses unchanged."""
    from scipy.linalg import solve_discrete_are

    Ad = np.array([[0.9, 0.05], [0.02, 0.95]])
    C, Qd, S = np.eye(2), np.diag([1e-3, 2e-3]), np.array([0.0, 1e-2])
    P = filtering.stationary_covariance(Ad, C, Qd, S)
    np.testing.assert_array_equal(P, solve_discrete_are(Ad.T, C.T, Qd, np.diag(S)))
    assert P[0, 0] == pytest.approx(Qd[0, 0], rel=0.01)  # the measured state known but for Qd
