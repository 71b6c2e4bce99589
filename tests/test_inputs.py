"""Extra inputs: irradiance channels entering the air node with an effective aperture
(models.with_irradiance, structure_for) and their use in the PEM (eq. 1's solar gains)."""

import pickle

import numpy as np
import pandas as pd
import pytest

from railtherm.estimation import models, pem

IE = models.STRUCTURES["interior_envelope"]
TRUTH = {"C": 2.0e5, "K_i": 1500.0, "C_e": 1.5e6, "K_o": 600.0, "a_I_sol": 3.0}
BASE_THETA = {
    "first_order": {"kA": 900.0, "C_bar": 7.0e5},
    "second_order": {"kA": 900.0, "C": 1.5e5, "K_veh": 300.0, "C_veh": 6.0e5},
    "interior_envelope": {"C": 2.0e5, "K_i": 1500.0, "C_e": 1.5e6, "K_o": 600.0},
}


def data(n_days: int = 5, dt: float = 1800.0):
    """u N x 3 = [T_o, Q_H, I_sol]: a daily sine of T_o, Q_H steps, irradiance a daily
    half-sine 0..800 W/m2."""
    t = np.arange(int(n_days * 86_400 / dt)) * dt
    day = 2.0 * np.pi * t / 86_400.0
    T_o = 5.0 + 6.0 * np.sin(day - 2.0)
    Q_H = np.array([2000.0, 8000.0, 4000.0, 6000.0, 0.0])[(t // 36_000).astype(int) % 5]
    I_sol = 800.0 * np.maximum(np.sin(day), 0.0)
    return np.column_stack([T_o, Q_H, I_sol]), dt


@pytest.mark.parametrize("base", sorted(models.STRUCTURES))
@pytest.mark.parametrize("names", [["I_sol"], ["I_roof", "I_side"]])
def test_jacobian_matches_central_differences(base, names):
    s = models.structure_for(base, names)
    theta = dict(BASE_THETA.get(base, models.STRUCTURES[base].initial))  # any registered
    theta.update({f"a_{n}": 2.0 + i for i, n in enumerate(names)})
    A0, B0 = s.matrices(theta)
    assert B0.shape == (A0.shape[0], 2 + len(names))
    assert_jacobian_matches_central_differences(s, theta, 1e-5)


def assert_jacobian_matches_central_differences(
    s: models.Structure, theta: dict[str, float], h_rel: float
) -> None:
    """Each parameter's analytic (dA/dp, dB/dp) equals central differences of the matrices
    with the step h_rel * p, to 1e-6 of the larger of the difference and the matrix / p."""
    A0, B0 = s.matrices(theta)
    der = s.derivatives(theta)
    assert tuple(der) == s.parameters
    for p in s.parameters:
        h = h_rel * theta[p]
        up, down = dict(theta), dict(theta)
        up[p] += h
        down[p] -= h
        (Au, Bu), (Ad, Bd) = s.matrices(up), s.matrices(down)
        for analytic, fd, full in (
            (der[p][0], (Au - Ad) / (2 * h), A0),
            (der[p][1], (Bu - Bd) / (2 * h), B0),
        ):
            assert analytic.shape == full.shape
            scale = max(np.abs(fd).max(), np.abs(full).max() / theta[p], 1e-300)
            assert np.abs(analytic - fd).max() <= 1e-6 * scale, (s.name, p, analytic, fd)


def test_with_irradiance_structure():
    assert models.with_irradiance(IE, []) is IE
    assert models.structure_for("second_order") is models.STRUCTURES["second_order"]
    s = models.structure_for("interior_envelope", ["I_sol"])
    assert s.name == "interior_envelope+I_sol"
    assert s.inputs == ("T_o", "Q_H", "I_sol")
    assert s.parameters == IE.parameters + ("a_I_sol",)
    assert s.states == IE.states
    assert s.initial["a_I_sol"] == 1.0 and s.bounds["a_I_sol"] == (1e-3, 1e3)
    assert {p: s.initial[p] for p in IE.parameters} == dict(IE.initial)
    # the base columns are the base structure's, exactly; the aperture enters the air node
    A, B = s.matrices(TRUTH)
    A0, B0 = IE.matrices(TRUTH)
    assert np.array_equal(A, A0) and np.array_equal(B[:, :2], B0)
    np.testing.assert_array_equal(B[:, 2], [TRUTH["a_I_sol"] / TRUTH["C"], 0.0])
    f = models.structure_for("first_order", ["I_sol"])
    assert f.matrices({"kA": 1.0, "C_bar": 4.0, "a_I_sol": 2.0})[1][0, 2] == 0.5
    # alike structures compare equal and survive pickling (data, not closures)
    assert models.structure_for("interior_envelope", ["I_sol"]) == s
    assert pickle.loads(pickle.dumps(s)) == s
    with pytest.raises(ValueError, match="clash"):
        models.with_irradiance(IE, ["I_sol", "I_sol"])
    with pytest.raises(ValueError, match="clash"):
        models.with_irradiance(IE, ["Q_H"])
    with pytest.raises(ValueError, match="N x 3"):
        models.simulate(s, TRUTH, np.zeros((10, 2)), 60.0, [0.0, 0.0])


@pytest.fixture(scope="module")
def solar():
    """Noise-free air temperature of interior_envelope+I_sol (5 days at 30 min)."""
    s = models.structure_for("interior_envelope", ["I_sol"])
    u, dt = data()
    x = models.simulate(s, TRUTH, u, dt, [15.0, 10.0])
    y = x.copy()
    y[:, 1] = np.nan  # the envelope is not measured
    return s, u, dt, y


def test_fit_recovers_aperture_and_beats_the_model_without_irradiance(solar):
    s, u, dt, y = solar
    e = pem.Experiment(name="sun", dt=dt, u=u, y=y)
    r = pem.fit(s, [e], outputs=("T",), x0="estimated", covariance="iid")
    assert r.success, r.message
    assert r.structure == "interior_envelope+I_sol"
    for p, v in TRUTH.items():
        assert abs(r.theta[p] / v - 1.0) < 0.01, (p, r.theta[p], v)
    np.testing.assert_allclose(r.x0[0], [15.0, 10.0], atol=0.05)

    plain = pem.Experiment(name="sun", dt=dt, u=u[:, :2], y=y)
    r0 = pem.fit(IE, [plain], outputs=("T",), x0="estimated", covariance="iid")
    rms0 = np.sqrt(r0.cost / r0.n_obs)
    assert r0.cost >= 10.0 * r.cost
    assert rms0 > 0.1, rms0  # the sun's gains (2.4 kW at noon) are visibly missing


def test_fit_refuses_a_wrong_input_width(solar):
    s, u, dt, y = solar
    narrow = pem.Experiment(name="narrow", dt=dt, u=u[:, :2], y=y)
    with pytest.raises(ValueError, match=r"3 inputs.*'narrow' \(2\)"):
        pem.fit(s, [narrow], outputs=("T",))
    wide = pem.Experiment(name="wide", dt=dt, u=u, y=y)
    with pytest.raises(ValueError, match=r"2 inputs.*'wide' \(3\)"):
        pem.fit(IE, [wide], outputs=("T",))
    with pytest.raises(ValueError, match="m >= 2"):
        pem.Experiment(name="one", dt=dt, u=u[:, :1], y=y)


def test_block_average_and_equation_error_start_take_any_width(solar):
    s, u, dt, y = solar
    e = pem.Experiment(name="sun", dt=dt, u=u, y=y)
    coarse = pem._block_average(e, 4)
    assert coarse.u.shape == (len(u) // 4, 3)
    np.testing.assert_allclose(coarse.u[0], u[:4].mean(axis=0))
    # every state measured: the equation-error start is computed with k = n + 3 regressors
    x = models.simulate(s, TRUTH, u, dt / 10, [15.0, 10.0])
    full = pem.Experiment(name="full", dt=dt / 10, u=u, y=x)
    lb = np.log([s.bounds[p][0] for p in s.parameters])
    ub = np.log([s.bounds[p][1] for p in s.parameters])
    start = pem.equation_error_start(s, [full], {}, s.initial, (lb, ub), s.parameters)
    assert start is not None and set(start) == set(s.parameters)
    assert abs(start["a_I_sol"] / TRUTH["a_I_sol"] - 1.0) < 0.1


def test_experiment_from_table_takes_further_inputs():
    t = np.arange(5) * 60.0
    table = pd.DataFrame(
        {
            "time": t,
            "T": 1.0,
            "T_e": 2.0,
            "T_o": [0.0, 2.0, 4.0, 6.0, 8.0],
            "Q_H": 100.0,
            "I_sol": [0.0, 10.0, 20.0, 30.0, 40.0],
        }
    )
    s = models.structure_for("interior_envelope", ["I_sol"])
    e = pem.experiment_from_table(table, "w", states=s.states, inputs=s.inputs)
    np.testing.assert_allclose(e.u[:, 0], [1.0, 3.0, 5.0, 7.0, 8.0])  # T_o: trapezoidal
    np.testing.assert_allclose(e.u[:, 1], 100.0)
    np.testing.assert_allclose(e.u[:, 2], table["I_sol"])  # as it is (a step mean)
    plain = pem.experiment_from_table(table, "w", states=s.states)
    assert plain.u.shape == (5, 2)
    assert np.array_equal(plain.u, e.u[:, :2])
    with pytest.raises(ValueError, match="I_roof"):
        pem.experiment_from_table(table, "w", inputs=("T_o", "Q_H", "I_roof"))
