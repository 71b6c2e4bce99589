"""The storage-corrected k: eq. 10 books the heat a lagging car body takes up as loss; the k
window's energy balance under the identified second-order model (eqs. 7-8) does not."""

import dataclasses

import numpy as np
import pandas as pd
import pytest
from test_identify import TRUTH, A
from test_identify import vehicle as identify_vehicle

from railtherm.config import section_defaults
from railtherm.estimation import kvalue, models, pem
from railtherm.study import fitsettings, identify
from railtherm.study import storage as storage_module
from railtherm.study.storage import storage_corrected_k

STEP = 120.0
T_O = -10.0
NOISE_K = 0.01  # white noise of the measured temperatures


def record(x0, hours, Q=None, T_set=None, seed=0) -> pd.DataFrame:
    """A tidy window of eqs. 7-8 (exact ZOH) from the state x0 = (T, T_veh): the heating
    power Q(t) given, or set at each step so that T stays at ``T_set`` (a controller that
    holds the air). Temperatures measured with white noise NOISE_K (seeded)."""
    n = int(hours * 3600 / STEP) + 1
    Ad, Bd = models.discretize_zoh(*models.second_order(**TRUTH), STEP)
    x = np.empty((n, 2))
    Q_H = np.empty(n)
    x[0] = x0
    for i in range(n):
        if T_set is None:
            Q_H[i] = Q(i * STEP)
        else:  # T[i + 1] = T_set: Ad[0] x + Bd[0, 0] T_o + Bd[0, 1] Q_H = T_set
            Q_H[i] = (T_set - Ad[0] @ x[i] - Bd[0, 0] * T_O) / Bd[0, 1]
        if i + 1 < n:
            x[i + 1] = Ad @ x[i] + Bd @ np.array([T_O, Q_H[i]])
    rng = np.random.default_rng(seed)
    noisy = x + rng.normal(0.0, NOISE_K, x.shape)
    t = np.arange(n) * STEP
    return pd.DataFrame({"time": t, "T": noisy[:, 0], "T_veh": noisy[:, 1], "T_o": T_O, "Q_H": Q_H})


def steady(Q0: float) -> np.ndarray:
    Ac, Bc = models.second_order(**TRUTH)
    return models.steady_state(Ac, Bc, np.array([T_O, Q0]))


def step_window(Q0: float, Q1: float, seed: int) -> pd.DataFrame:
    return record(steady(Q0), 30, Q=lambda t: Q0 if t < 7200 else Q1, seed=seed)


IDENTIFICATION = {"up": step_window(20_000, 29_000, 1), "down": step_window(29_000, 20_000, 2)}


def k_window(lag_K: float, surface_sensors: bool = False) -> pd.DataFrame:
    """8 h with T held at 20 degC and the body lag_K below it at the start; T_veh not measured
    (no surface sensors in the k window) unless ``surface_sensors``."""
    w = record(np.array([20.0, 20.0 - lag_K]), 8, T_set=20.0, seed=3)
    return w if surface_sensors else w.assign(T_veh=np.nan)


def vehicle() -> dict:
    # the vehicle of test_identify with its k stage's settings; the initial states estimated:
    # "measured" takes the first row's noise as exact and biases C by about +0.2 % here,
    # beyond its interval - a question of x0, not of the k stage (the capacities' errors with
    # eq. 10's k are ten times larger)
    return {**identify_vehicle(x0="estimated"), "kvalue": section_defaults("kvalue")}


def k_stage(window: pd.DataFrame, data: dict) -> dict:
    return kvalue.for_vehicle(window, data, source="k window").to_dict()


def two_stages(window: pd.DataFrame, data: dict | None = None):
    data = data or vehicle()
    k = k_stage(window, data)
    storage = storage_corrected_k(IDENTIFICATION, window, data, k)
    estimate, _ = identify.identify(IDENTIFICATION, data, k, 2, storage)
    return k, storage, estimate


@pytest.fixture(scope="module")
def lagging():
    return two_stages(k_window(0.3))


def test_eq10_books_the_lagging_body_as_loss(lagging):
    """The bias of eq. 10 is K_veh mean(T - T_veh) / (A mean(T - T_o)), several u(k)."""
    k, _, _ = lagging
    tau = TRUTH["C_veh"] / TRUTH["K_veh"]
    duration = 8 * 3600.0
    mean_lag = 0.3 * tau / duration * -np.expm1(-duration / tau)
    expected = TRUTH["K_veh"] * mean_lag / (A * 30.0)
    bias = k["k"] - TRUTH["kA"] / A
    assert k["usable"] and k["steady"]
    assert bias == pytest.approx(expected, rel=0.1)
    assert bias > 3 * k["u_k"]


def test_corrected_k_recovers_the_truth_and_feeds_stage_two(lagging):
    k, storage, estimate = lagging
    k_true = TRUTH["kA"] / A
    assert storage["applied"] and storage["converged"]
    assert 1 <= storage["iterations"] <= 4
    assert storage["window"]["T_veh_from"] == "model (eq. 8)"
    assert storage["window"]["D0"] == pytest.approx(0.3, abs=0.05)
    assert estimate.content["k_eq10"] == pytest.approx(k["k"])
    assert abs(estimate.content["k_corrected"] - k_true) < estimate.content["u_k_corrected"]
    assert abs(estimate.content["k_corrected"] - k_true) < 0.2 * abs(k["k"] - k_true)
    assert estimate.content["kA_fixed"] == pytest.approx(storage["kA_corrected"])
    assert estimate.content["fit"]["parameters"]["kA"]["value"] == pytest.approx(
        storage["kA_corrected"]
    )
    assert estimate.content["k_source"] == "static test (eq. 10), storage-corrected"
    # the storage term of the budget is the correction's, not eq. 10's bound
    systematic = estimate.content["systematic"]
    assert systematic["sources"]["k_storage"] == pytest.approx(
        storage["u_storage_kA"] / storage["kA_corrected"]
    )
    for p in ("C", "K_veh", "C_veh"):
        lo, hi = estimate.content["fit"]["parameters"][p]["ci95"]
        assert lo <= TRUTH[p] <= hi, p


def test_records_disagree_with_eq10s_biased_kA_not_with_the_corrected_one(lagging):
    """eq. 10's kA, biased by the lagging body by many of its own u(k), and the records'
    kA disagree: the two-stage fit stays, in doubt, with the disagreement as a reason; the
    storage-corrected kA the records accept."""
    _, _, corrected = lagging
    data = vehicle()
    data["kvalue"] = {**data["kvalue"], "storage_correction": False}
    k, storage, eq10 = two_stages(k_window(0.3), data)
    assert storage is None and eq10.content["storage_correction"] is None
    assert eq10.content["k_source"] == "static test (eq. 10)"
    check = eq10.content["fit"]["static_kA_check"]
    assert check["kA_static"] == pytest.approx(k["kA"])
    assert check["z"]["kA"] < -fitsettings.CONTRADICTION_Z  # eq. 10 too high
    assert check["reason"] == identify.STATIC_CONFLICT and not check["kA_within_static_u"]
    assert any("the static test and the records disagree" in n for n in eq10.content["notes"])
    check = corrected.content["fit"]["static_kA_check"]
    assert check["use_joint"] is False
    assert all(abs(z) < fitsettings.CONTRADICTION_Z for z in check["z"].values())
    assert corrected.content["k_source"] == "static test (eq. 10), storage-corrected"
    assert not corrected.content["notes"]


def test_measured_body_temperature_is_used_where_the_window_has_it():
    window = k_window(0.3, surface_sensors=True)
    k, storage, estimate = two_stages(window)
    assert storage["window"]["T_veh_from"] == "T_veh"
    assert storage["window"]["D0"] is None
    assert (
        abs(estimate.content["k_corrected"] - TRUTH["kA"] / A) < estimate.content["u_k_corrected"]
    )


def test_steady_body_leaves_eq10_as_it_is():
    k, storage, estimate = two_stages(k_window(0.0))
    assert storage["iterations"] <= 2
    assert abs(estimate.content["k_corrected"] - k["k"]) < 0.5 * estimate.content["u_k_corrected"]
    assert abs(k["k"] - TRUTH["kA"] / A) < 2 * k["u_k"]


def test_regression_uncertainty_grows_when_the_body_is_slow_against_the_window():
    """tau_veh long against the window: D0's column approaches kA's, the two are confounded."""
    window = k_window(0.3)
    fast = kvalue.storage_corrected_kA(window, TRUTH["C"], TRUTH["K_veh"], TRUTH["C_veh"])
    slow = kvalue.storage_corrected_kA(window, TRUTH["C"], TRUTH["K_veh"] / 20, TRUTH["C_veh"])
    assert abs(slow.corr_kA_D0) > abs(fast.corr_kA_D0)
    assert slow.u_kA > 3 * fast.u_kA


@pytest.mark.parametrize("tau_h", [0.05, 2.0, 40.0])
def test_the_modelled_body_follows_the_cabin_as_scipys_lsim_does(tau_h):
    """T_veh^0 of eq. 8 driven by the measured T, linear between samples: the same as
    scipy.signal.lsim with its first-order hold (interp=True), for a body fast, moderate and
    slow against the 60 s step."""
    from scipy import signal

    rng = np.random.default_rng(3)
    s = np.arange(0.0, 6 * 3600.0, 60.0)
    T = 20.0 + 5.0 * np.tanh(s / 5000.0) + rng.normal(0.0, 0.05, s.size)
    tau = tau_h * 3600.0
    lag = signal.StateSpace([[-1.0 / tau]], [[1.0 / tau]], [[1.0]], [[0.0]])
    _, expected, _ = signal.lsim(lag, T, s, X0=[T[0]], interp=True)
    assert np.allclose(kvalue._body_response(T, s, tau), expected, rtol=1e-12, atol=0.0)


def test_exact_balance_without_noise():
    """Noise-free: the regression returns kA and D0 of the simulation to solver precision."""
    global NOISE_K
    saved, NOISE_K = NOISE_K, 0.0
    try:
        window = k_window(0.3)
    finally:
        NOISE_K = saved
    result = kvalue.storage_corrected_kA(window, TRUTH["C"], TRUTH["K_veh"], TRUTH["C_veh"])
    assert result.kA == pytest.approx(TRUTH["kA"], rel=1e-6)
    assert result.D0 == pytest.approx(0.3, rel=1e-4)


def test_undetermined_capacities_leave_eq10_and_say_why(monkeypatch):
    """Where the second-order fit does not determine the capacities (statistical sd infinite),
    the correction is not made: eq. 10's kA is the static one, and the record says why."""
    monkeypatch.setattr(storage_module, "_storage_model_u", lambda *args: float("inf"))
    k, storage, estimate = two_stages(k_window(0.3))
    assert storage["applied"] is False and "does not determine" in storage["reason"]
    # stage two holds eq. 10's kA (here biased by the lag, which the records then reject)
    assert estimate.content["fit"]["static_kA_check"]["kA_static"] == pytest.approx(k["kA"])
    assert estimate.content["k_corrected"] is None
    assert estimate.content["storage_correction"]["reason"] == storage["reason"]


# -- the static kA against the records' own -----------------------------------------------
WITHOUT_SURFACE = {n: w.assign(T_veh=np.nan) for n, w in IDENTIFICATION.items()}


def static_stage(scale: float, u_k_rel: float = 0.005) -> tuple[dict, dict]:
    """Stage two on records without surface sensors, with the steady k window's eq. 10 kA
    scaled by ``scale`` (an error of the static test the records can see) and its relative
    uncertainty ``u_k_rel`` (0.5 %: a power meter's)."""
    data = vehicle()
    data["kvalue"] = {**data["kvalue"], "storage_correction": False}
    k = k_stage(k_window(0.0), data)
    k = {**k, "kA": k["kA"] * scale, "k": k["k"] * scale, "u_k_rel": u_k_rel}
    estimate, _ = identify.identify(WITHOUT_SURFACE, data, k, 2, None)
    return k, estimate


def test_records_that_accept_the_static_kA_keep_the_two_stage_fit():
    k, estimate = static_stage(1.0)
    check = estimate.content["fit"]["static_kA_check"]
    assert estimate.content["k_source"] == "static test (eq. 10)"
    assert estimate.content["kA_fixed"] == pytest.approx(k["kA"])
    assert check["use_joint"] is False
    assert all(abs(z) < fitsettings.CONTRADICTION_Z for z in check["z"].values())
    assert check["kA_joint"] == pytest.approx(TRUTH["kA"], rel=0.002)


def test_records_that_contradict_the_static_kA_get_the_joint_fit():
    """1 % off in kA, held fixed, doubles C and C_veh on these records (the capacities
    absorb the mismatch); the records determine kA far better than that, so the check
    rejects it and the joint fit, which recovers every parameter, is reported."""
    k, estimate = static_stage(1.01)
    check = estimate.content["fit"]["static_kA_check"]
    assert check["use_joint"] is True and check["z"]["kA"] < -fitsettings.CONTRADICTION_Z
    assert estimate.content["k_source"] == f"joint estimation (PEM): {identify.STATIC_CONTRADICTED}"
    assert estimate.content["kA_fixed"] is None
    assert estimate.content["k_eq10"] == pytest.approx(k["k"])  # the static test is still reported
    # the reported joint fit's kA agrees with the static test: a note, not a verdict reason
    assert "contradict the two-stage fit" in estimate.content["method_notes"][-1]
    assert not any("contradict the two-stage fit" in n for n in estimate.content["notes"])
    parameters = estimate.content["fit"]["parameters"]
    for p in ("kA", "C", "K_veh", "C_veh"):
        lo, hi = parameters[p]["ci95"]
        assert parameters[p]["identified"] and lo <= TRUTH[p] <= hi, p


def test_a_static_kA_far_outside_its_own_uncertainty_is_not_replaced():
    """3 % off with 0.5 % claimed: the static test and the records disagree beyond what
    either explains; the joint kA does not replace the static one (a heat source the model
    lacks would move it as far), the two-stage fit stays with the disagreement as a note."""
    k, estimate = static_stage(1.03)
    check = estimate.content["fit"]["static_kA_check"]
    assert check["use_joint"] is False and check["reason"] == identify.STATIC_CONFLICT
    assert estimate.content["k_source"] == "static test (eq. 10)"
    assert estimate.content["kA_fixed"] == pytest.approx(k["kA"])
    assert "the static test and the records disagree" in estimate.content["notes"][-1]


def test_static_kA_leaving_parameters_undetermined_gets_the_joint_fit(monkeypatch):
    """A two-stage fit judged not identified is replaced by the joint fit where the joint
    fit determines every parameter, whatever the check's z."""
    real = identify._not_identified
    calls = []

    def first_call_undetermined(fitted, structure):
        calls.append(1)
        return ["C_veh"] if len(calls) == 1 else real(fitted, structure)

    monkeypatch.setattr(identify, "_not_identified", first_call_undetermined)
    _, estimate = static_stage(1.0)
    assert estimate.content["k_source"] == f"joint estimation (PEM): {identify.STATIC_UNDETERMINED}"
    assert "left C_veh not identified" in estimate.content["method_notes"][-1]


def test_a_runaway_alternation_is_solved_by_the_secant_method(monkeypatch):
    """Where stage two's capacities follow kA steeply, the balance moves kA further than it
    was moved (the alternation kA <- balance(kA) runs away); the correction then solves
    kA = balance(kA) from the joint fit instead, and ends where the two agree. Here the
    balance's answer is amplified about the truth to make the map steep (on records without
    surface sensors, where the capacities follow kA most)."""
    real = storage_module.storage_corrected_kA
    gain = 40.0

    def steep(window, C, K_veh, C_veh):
        result = real(window, C, K_veh, C_veh)
        return dataclasses.replace(result, kA=TRUTH["kA"] + gain * (result.kA - TRUTH["kA"]))

    monkeypatch.setattr(storage_module, "storage_corrected_kA", steep)
    data, window = vehicle(), k_window(0.3)
    k = k_stage(window, data)
    storage = storage_corrected_k(WITHOUT_SURFACE, window, data, k)
    data["model"] = {**data["model"], "two_stage_check": False}
    estimate, _ = identify.identify(WITHOUT_SURFACE, data, k, 2, storage)
    assert storage["applied"] and storage["solver"] == "secant"
    # the plain alternation ran away first (a settled one takes at most 4 fits here)
    assert storage["iterations"] > 4
    # the end is a fixed point of the steep map: stage two at the corrected kA gives
    # capacities whose balance returns that kA
    assert estimate.content["kA_fixed"] == pytest.approx(storage["kA_corrected"])
    theta = {p: estimate.content["fit"]["parameters"][p]["value"] for p in ("C", "K_veh", "C_veh")}
    again = steep(k_window(0.3), **theta).kA
    assert abs(again - storage["kA_corrected"]) < storage["u_kA_corrected"]


def test_a_balance_under_a_capacity_at_its_search_bound_is_not_used(monkeypatch):
    """Where a stage-two fit leaves a capacity at a search bound, the balance under it means
    nothing (a negative kA with a huge u once ran as "settled"): the correction is not made,
    eq. 10's kA is fixed, and the reason names the parameter."""
    real = identify.pem.fit

    def bounded(structure, exps, **options):
        result = real(structure, exps, **options)
        if "kA" in options.get("fixed", {}):  # stage two
            flag = pem.Flag("at_bound", ("C_veh",), "C_veh at its upper search bound")
            result.flags.append(flag)
        return result

    monkeypatch.setattr(identify.pem, "fit", bounded)
    data, window = vehicle(), k_window(0.3)
    k = k_stage(window, data)
    storage = storage_corrected_k(IDENTIFICATION, window, data, k)
    assert storage["applied"] is False
    assert "leaves C_veh at a search bound" in storage["reason"]
    assert "eq. 10's kA is fixed" in storage["reason"]
