"""railtherm.estimation.models: the paper's structures (eqs. 13, 14) and exact ZOH
discretisation."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from railtherm.estimation import models


def test_zoh_matches_analytic_first_order_step_response():
    """Eq. 9 under a constant input: T(t) = T_inf + (T0 - T_inf) exp(-kA t / C_bar)."""
    kA, C_bar, T_o, Q_H, T0, dt = 900.0, 2.0e7, -10.0, 30_000.0, -10.0, 600.0
    Ad, Bd = models.discretize_zoh(*models.first_order(kA, C_bar), dt)
    T, u = np.array([T0]), np.array([T_o, Q_H])
    T_inf = T_o + Q_H / kA
    for n in range(1, 200):
        T = Ad @ T + Bd @ u
        expected = T_inf + (T0 - T_inf) * np.exp(-kA * n * dt / C_bar)
        assert T[0] == pytest.approx(expected, rel=1e-12, abs=1e-12)


def test_second_order_steady_state_is_static_model():
    """At rest both states settle at T_o + Q_H / kA (eq. 10): the models are consistent."""
    A, B = models.second_order(kA=950.0, C=3.0e7, K_veh=246.0, C_veh=1.7e7)
    x = models.steady_state(A, B, np.array([-5.0, 19_000.0]))
    np.testing.assert_allclose(x, [-5.0 + 19_000.0 / 950.0] * 2, rtol=1e-12)


@given(
    kA=st.floats(100, 2000),
    C=st.floats(1e5, 5e7),
    K_veh=st.floats(1, 1e5),
    C_veh=st.floats(1e6, 5e7),
    dt=st.floats(1, 3600),
)
def test_zoh_composes_over_steps(kA, C, K_veh, C_veh, dt):
    """Two half steps equal one full step under a held input (exactness, not an approximation)."""
    A, B = models.second_order(kA, C, K_veh, C_veh)
    Ad, Bd = models.discretize_zoh(A, B, dt)
    Ah, Bh = models.discretize_zoh(A, B, dt / 2)
    np.testing.assert_allclose(Ah @ Ah, Ad, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(Ah @ Bh + Bh, Bd, rtol=1e-9, atol=1e-12)


def test_second_order_matrices_follow_eq_14():
    A, B = models.second_order(kA=2.0, C=4.0, K_veh=6.0, C_veh=3.0)
    np.testing.assert_array_equal(A, [[-2.0, 1.5], [2.0, -2.0]])
    np.testing.assert_array_equal(B, [[0.5, 0.25], [0.0, 0.0]])


# ---------------------------------------------------------------- structures, simulation


TRAM2 = {"kA": 979.2, "C": 1.8e7, "K_veh": 974.0, "C_veh": 1.0e7}


def _inputs(n: int, dt: float, seed: int = 0) -> np.ndarray:
    """Q_H steps every 4 h, T_o steps every 12 h, plus a little jitter (deterministic)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    q = 4000.0 * rng.integers(0, 9, size=int(t[-1] // 14_400) + 1)[(t // 14_400).astype(int)]
    to = rng.uniform(-20, 10, size=int(t[-1] // 43_200) + 1)[(t // 43_200).astype(int)]
    return np.column_stack([to + 0.05 * rng.standard_normal(n), q])


def _loop(structure, theta, u, dt, x0):
    Ad, Bd = models.discretize_zoh(*structure.matrices(theta), dt)
    x = np.empty((len(u), len(x0)))
    x[0] = x0
    for n in range(len(u) - 1):
        x[n + 1] = Ad @ x[n] + Bd @ u[n]
    return x


def test_structures_are_data():
    s1, s2 = models.STRUCTURES["first_order"], models.STRUCTURES["second_order"]
    assert s1.parameters == ("kA", "C_bar") and s1.states == ("T",)
    assert s2.parameters == ("kA", "C", "K_veh", "C_veh") and s2.states == ("T", "T_veh")
    assert s2.inputs == ("T_o", "Q_H")
    A, B = s2.matrices(TRAM2)
    np.testing.assert_array_equal(A, models.second_order(**TRAM2)[0])
    np.testing.assert_array_equal(B, models.second_order(**TRAM2)[1])


@pytest.mark.parametrize("name", ["first_order", "second_order"])
def test_analytic_derivatives_of_A_and_B(name):
    s = models.STRUCTURES[name]
    theta = TRAM2 if name == "second_order" else {"kA": 979.2, "C_bar": 2.8e7}
    for p, (dA, dB) in s.derivatives(theta).items():
        h = theta[p] * 1e-6
        Ap, Bp = s.matrices({**theta, p: theta[p] + h})
        Am, Bm = s.matrices({**theta, p: theta[p] - h})
        np.testing.assert_allclose(dA, (Ap - Am) / (2 * h), rtol=1e-6, atol=1e-20)
        np.testing.assert_allclose(dB, (Bp - Bm) / (2 * h), rtol=1e-6, atol=1e-20)


@pytest.mark.parametrize("name", ["first_order", "second_order"])
def test_simulate_equals_plain_loop(name):
    s = models.STRUCTURES[name]
    theta = TRAM2 if name == "second_order" else {"kA": 979.2, "C_bar": 2.8e7}
    u = _inputs(3000, 60.0)
    x0 = np.array([3.0, -4.0])[: len(s.states)]
    x = models.simulate(s, theta, u, 60.0, x0)
    np.testing.assert_allclose(x, _loop(s, theta, u, 60.0, x0), rtol=0, atol=1e-10)
    assert x.shape == (3000, len(s.states))
    np.testing.assert_array_equal(x[0], x0)


def test_simulate_analytic_first_order_step_response():
    kA, C_bar, T_o, Q_H, T0, dt = 900.0, 2.0e7, -10.0, 30_000.0, -10.0, 600.0
    s = models.STRUCTURES["first_order"]
    u = np.tile([T_o, Q_H], (200, 1))
    x = models.simulate(s, {"kA": kA, "C_bar": C_bar}, u, dt, [T0])
    t = np.arange(200) * dt
    T_inf = T_o + Q_H / kA
    np.testing.assert_allclose(x[:, 0], T_inf + (T0 - T_inf) * np.exp(-kA * t / C_bar), rtol=1e-12)


def _custom(A_fn, name="custom"):
    """A one-parameter toy structure whose A is given (for the Schur fall-back)."""

    def build(a):
        A = A_fn(a)
        return A, np.column_stack([np.ones(len(A)), np.arange(1, len(A) + 1) * 1e-3])

    def jac(a):
        h = 1e-7
        return {"a": ((A_fn(a + h) - A_fn(a - h)) / (2 * h), np.zeros((len(A_fn(a)), 2)))}

    states = tuple(f"x{i}" for i in range(len(A_fn(1.0))))
    return models.Structure(name=name, parameters=("a",), states=states, build=build, jacobian=jac)


@pytest.mark.parametrize(
    "A_fn",
    [
        lambda a: np.array([[-a, 1e-3], [-1e-3, -a]]) * 1e-3,  # complex pair
        lambda a: np.array([[-a, 1.0], [0.0, -a]]) * 1e-3,  # defective (Jordan block)
    ],
)
def test_simulate_falls_back_when_not_diagonalisable(A_fn):
    s = _custom(A_fn)
    d = models.discretize(s, {"a": 1.0}, 60.0)
    assert not d.diagonal
    u = _inputs(2000, 60.0)
    x = models.simulate(s, {"a": 1.0}, u, 60.0, [1.0, -2.0])
    np.testing.assert_allclose(x, _loop(s, {"a": 1.0}, u, 60.0, [1.0, -2.0]), atol=1e-9)
    F = models.free_response(d, 50)
    np.testing.assert_allclose(F[7], np.linalg.matrix_power(d.Ad, 7), atol=1e-12)


def test_block_expm_derivatives_equal_expm_frechet():
    from scipy.linalg import expm_frechet

    s, dt = models.STRUCTURES["second_order"], 60.0
    d = models.discretize(s, TRAM2, dt, s.parameters)
    A, B = s.matrices(TRAM2)
    M = np.zeros((4, 4))
    M[:2, :2], M[:2, 2:] = A, B
    for p, (dA, dB) in s.derivatives(TRAM2).items():
        E = np.zeros((4, 4))
        E[:2, :2], E[:2, 2:] = dA, dB
        L = expm_frechet(M * dt, E * dt, compute_expm=False)
        np.testing.assert_allclose(d.dAd[p], L[:2, :2], rtol=1e-10, atol=1e-14 * abs(L).max())
        np.testing.assert_allclose(d.dBd[p], L[:2, 2:], rtol=1e-10, atol=1e-14 * abs(L).max())


@pytest.mark.parametrize("name", ["first_order", "second_order"])
def test_sensitivities_match_finite_differences(name):
    s = models.STRUCTURES[name]
    theta = TRAM2 if name == "second_order" else {"kA": 979.2, "C_bar": 2.8e7}
    u, dt = _inputs(2000, 60.0, seed=3), 60.0
    x0 = np.array([2.0, -1.0])[: len(s.states)]
    x, S, F = models.sensitivities(s, theta, u, dt, x0)
    np.testing.assert_allclose(x, models.simulate(s, theta, u, dt, x0), atol=1e-12)
    for p in s.parameters:
        h = theta[p] * 1e-5
        fd = (
            models.simulate(s, {**theta, p: theta[p] + h}, u, dt, x0)
            - models.simulate(s, {**theta, p: theta[p] - h}, u, dt, x0)
        ) / (2 * h)
        scale = np.abs(fd).max()
        assert scale > 0
        np.testing.assert_allclose(S[p], fd, rtol=0, atol=1e-5 * scale)
    for j in range(len(x0)):
        e = np.zeros(len(x0))
        e[j] = 1e-3
        fd = (
            models.simulate(s, theta, u, dt, x0 + e) - models.simulate(s, theta, u, dt, x0 - e)
        ) / 2e-3
        np.testing.assert_allclose(F[:, :, j], fd, rtol=0, atol=1e-8)


def test_free_response_is_cut_not_subnormal():
    """A fast mode decays below 1e-30 within a few steps: the rest is exactly 0 (no subnormals)."""
    s = models.STRUCTURES["second_order"]
    d = models.discretize(s, {"kA": 979.2, "C": 1.0e5, "K_veh": 974.0, "C_veh": 1.0e6}, 600.0)
    head = models.free_response_head(d, 1_000_000)
    assert len(head) < 100_000
    F = models.free_response(d, 5000)
    tiny = np.abs(F[F != 0]).min()
    assert tiny > 1e-40  # far from the subnormal range (< 2.2e-308)
    np.testing.assert_allclose(F[3], np.linalg.matrix_power(d.Ad, 3), rtol=1e-12)


def test_sensitivities_on_the_schur_path_match_finite_differences():
    s = _custom(lambda a: np.array([[-a, 1e-3], [-1e-3, -a]]) * 1e-3)
    u, dt, x0 = _inputs(1500, 60.0, seed=4), 60.0, np.array([1.0, -2.0])
    x, S, F = models.sensitivities(s, {"a": 1.0}, u, dt, x0)
    h = 1e-4
    fd = (
        models.simulate(s, {"a": 1.0 + h}, u, dt, x0)
        - models.simulate(s, {"a": 1.0 - h}, u, dt, x0)
    ) / (2 * h)
    np.testing.assert_allclose(S["a"], fd, rtol=0, atol=1e-5 * np.abs(fd).max())
    np.testing.assert_allclose(
        F[5], np.linalg.matrix_power(models.discretize(s, {"a": 1.0}, dt).Ad, 5)
    )


def test_first_order_hold_is_the_exact_response_to_inputs_linear_between_samples():
    """The first-order-hold recursion equals the continuous system driven by the linear
    interpolation of the samples: the zero-order recursion on a grid 1000x finer (each fine
    step holding its interval's mean of the ramp) converges to it at O(h^2)."""
    s = models.STRUCTURES["second_order"]
    u, dt = _inputs(40, 600.0, seed=5), 600.0
    x0 = np.array([18.0, 15.0])
    x = models.simulate(s, TRAM2, u, dt, x0, hold="first_order")
    errors = []
    for f in (100, 1000):
        t = np.arange((len(u) - 1) * f + 1) / f
        fine = np.column_stack([np.interp(t, np.arange(len(u)), u[:, j]) for j in range(2)])
        held = models.step_means(fine, "first_order")
        errors.append(np.abs(models.simulate(s, TRAM2, held, dt / f, x0)[::f] - x).max())
    assert errors[1] < 1e-6 * np.abs(x).max()
    assert errors[1] < errors[0] / 50  # second order in the fine step: 100x smaller
    # a constant input: both holds are the same model
    const = np.tile([[-5.0, 20_000.0]], (50, 1))
    np.testing.assert_allclose(
        models.simulate(s, TRAM2, const, dt, x0, hold="first_order"),
        models.simulate(s, TRAM2, const, dt, x0),
        rtol=1e-12,
    )


def test_first_order_hold_derivatives_match_finite_differences():
    """dAd, dBd of the first-order hold (one block exponential) and the sensitivities built on
    them agree with central differences of the simulation."""
    s = models.STRUCTURES["second_order"]
    u, dt, x0 = _inputs(500, 300.0, seed=7), 300.0, np.array([2.0, -1.0])
    d = models.discretize(s, TRAM2, dt, s.parameters, "first_order")
    assert d.Bd.shape == (2, 4) and d.hold == "first_order"
    x, S, _ = models.sensitivities(s, TRAM2, u, dt, x0, hold="first_order")
    for p in s.parameters:
        h = TRAM2[p] * 1e-5
        up = models.discretize(s, {**TRAM2, p: TRAM2[p] + h}, dt, hold="first_order")
        dn = models.discretize(s, {**TRAM2, p: TRAM2[p] - h}, dt, hold="first_order")
        fd = (up.Bd - dn.Bd) / (2 * h)
        np.testing.assert_allclose(d.dBd[p], fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())
        sim = (
            models.simulate(s, {**TRAM2, p: TRAM2[p] + h}, u, dt, x0, hold="first_order")
            - models.simulate(s, {**TRAM2, p: TRAM2[p] - h}, u, dt, x0, hold="first_order")
        ) / (2 * h)
        np.testing.assert_allclose(S[p], sim, rtol=0, atol=1e-5 * np.abs(sim).max())


def test_an_unknown_hold_is_refused_by_name():
    with pytest.raises(ValueError, match="hold must be one of zero_order, first_order"):
        models.discretize(models.STRUCTURES["first_order"], {"kA": 1.0, "C_bar": 1.0}, 1.0,
                          hold="linear")  # fmt: skip


@settings(deadline=None)  # the first example imports scipy.signal and loads the compiled loop
@given(
    n=st.integers(1, 400),
    channels=st.integers(1, 3),
    lam_abs=st.floats(0.0, 0.99999),
    lam_angle=st.sampled_from([0.0, 0.3, -2.0]),
    seed=st.integers(0, 2**16),
)
def test_a_mode_recursion_is_scipys_lfilter_to_the_bit(n, channels, lam_abs, lam_angle, seed):
    """z[n + 1] = lam z[n] + w[n] from z0: the same numbers as scipy.signal.lfilter([0, 1],
    [1, -lam], w, zi=z0), real and complex modes alike (one multiply-add per sample, in
    lfilter's order)."""
    from scipy.signal import lfilter

    rng = np.random.default_rng(seed)
    w = rng.normal(size=(channels, n)) * 10.0 ** rng.integers(-3, 4)
    z0 = rng.normal(size=channels)
    lam = lam_abs * np.exp(1j * lam_angle) if lam_angle else lam_abs
    if lam_angle:
        w = w + 1j * rng.normal(size=w.shape)
        z0 = z0 - 1j * rng.normal(size=channels)
    dtype = complex if lam_angle else float
    expected = lfilter(
        np.array([0.0, 1.0], dtype=dtype), np.array([1.0, -lam], dtype=dtype), w, zi=z0[:, None]
    )[0]
    assert np.array_equal(models.recursion(lam, w, z0), expected)
    one = models.recursion(lam, w[0], z0[0])  # one channel: 1-D in, 1-D out
    assert one.shape == (n,) and np.array_equal(one, expected[0])
