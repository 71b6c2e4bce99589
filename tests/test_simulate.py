"""Predictions from identified models (railtherm.study.simulate): consistency with the fits' own
simulations, the energy balance, the analytic first-order heat-up, the controllers, the
unreachable set point and the bands."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from railtherm.study import simulate as sim
from railtherm.study.fit import Fit, read_fit
from railtherm.study.scenario import Controller, Initial, Scenario

ROOT = Path(__file__).resolve().parents[1]


def scenario(
    duration_s: float,
    dt_s: float,
    T_o: float | np.ndarray,
    heating_W: float | np.ndarray | None = None,
    controller: Controller | None = None,
    initial: Initial | None = None,
    gains: dict | None = None,
    air_exchange_W_K: float | np.ndarray = 0.0,
    heat_up_to_C: float | None = None,
    cool_down_to_C: float | None = None,
    input_hold: str = "zero_order",
) -> Scenario:
    """A scenario built in code (the YAML form is tested in test_scenario.py)."""
    t = np.arange(round(duration_s / dt_s) + 1) * dt_s

    def series(v):
        return np.broadcast_to(np.asarray(v, dtype=float), t.shape).copy()

    return Scenario(
        name="test",
        file="test.yaml",
        description="",
        source="test",
        dt_s=dt_s,
        duration_s=duration_s,
        t_s=t,
        T_o=series(T_o),
        heating_W=None if heating_W is None else series(heating_W),
        controller=controller,
        gains={k: series(v) for k, v in (gains or {}).items()},
        air_exchange_W_K=series(air_exchange_W_K),
        irradiance={},
        initial=initial or Initial(kind="soaked"),
        heat_up_to_C=heat_up_to_C,
        cool_down_to_C=cool_down_to_C,
        input_hold=input_hold,
    )


def first_order_fit(kA: float = 800.0, C_bar: float = 3.0e7) -> Fit:
    """A first-order fit (eq. 9) with exact parameters and no uncertainty."""
    return Fit.from_dict(
        {
            "vehicle": "Box",
            "model": "order1",
            "structure": "first_order",
            "verdict": "fit acceptable",
            "parameters": {
                "kA": {"value": kA, "estimated": False},
                "C_bar": {"value": C_bar, "estimated": True, "identified": True},
            },
            "free": [],
        }
    )


# ------------------------------------------------------------------------ consistency
@pytest.mark.parametrize(
    ("vehicle", "model"),
    [
        ("Metro1", "order2"),
        ("Tram2", "order1"),
        ("Tram2", "order2"),
        ("Armadillo", "order2"),
        ("Armadillo", "interior_envelope_kalman"),
    ],
)
def test_fitted_window_reproduces_the_fits_own_simulation(fit_files, vehicle: str, model: str):
    """A fit_files model run over its own identification window with the measured inputs (the
    held T_o and Q_H, or their samples under the fit's first-order hold) from the fit's
    initial state reproduces the fit's simulated series."""
    path, series_path = fit_files(vehicle, model)
    fit = read_fit(path)
    series = pd.read_csv(series_path)
    name = series["window"].iloc[-1]
    w = series[series["window"] == name].reset_index(drop=True)
    dt = float(w["time"].iloc[1] - w["time"].iloc[0])
    assert np.allclose(np.diff(w["time"]), dt)
    states = fit.structure.states
    x0 = {s: float(w[f"{s}_sim"].iloc[0]) for s in states}
    sc = scenario(
        duration_s=float(w["time"].iloc[-1] - w["time"].iloc[0]),
        dt_s=dt,
        T_o=w["T_o"].to_numpy(),
        heating_W=w["Q_H"].to_numpy(),
        initial=Initial(kind="given", states_C=x0),
        input_hold=fit.hold,
    )
    out = sim.simulate(fit, sc, draws=0)
    for s in states:
        np.testing.assert_allclose(out.series[s], w[f"{s}_sim"], rtol=0, atol=1e-9)


def test_energy_is_the_integral_of_the_power_and_closes_the_heat_balance():
    """Energy (kWh) is the integral of the held heating power; for a first-order model it also
    equals what the air stored plus what it lost, kA * integral(T - T_o) dt, each step's
    integral of the exponential taken exactly - an independent check of the simulation."""
    kA, C_bar, dt = 800.0, 3.0e7, 300.0
    rng = np.random.default_rng(3)
    n = 96
    power = np.repeat(rng.uniform(0, 40_000, n // 8), 8)
    power = np.append(power, power[-1])
    T_o = np.linspace(-15, -5, n + 1)
    sc = scenario(n * dt, dt, T_o, heating_W=power, initial=Initial("given", {"T": 5.0}))
    out = sim.simulate(first_order_fit(kA, C_bar), sc, draws=0)
    s = out.series
    held = np.sum(s["heating_W"].to_numpy()[:-1] * dt) / 3.6e6
    assert out.outcomes["energy_kWh"].value == pytest.approx(held, rel=1e-12)
    tau = C_bar / kA
    T = s["T"].to_numpy()
    T_star = T_o[:-1] + power[:-1] / kA  # each step's equilibrium
    integral = T_star * dt + (T[:-1] - T_star) * tau * (1 - math.exp(-dt / tau))
    lost = kA * np.sum(integral - T_o[:-1] * dt)
    stored = C_bar * (T[-1] - T[0])
    assert (stored + lost) / 3.6e6 == pytest.approx(held, rel=1e-9)


def test_first_order_hold_follows_an_outdoor_ramp_exactly():
    """input_hold first_order: T_o linear between grid points. For eq. 9 under a ramp
    T_o = a + b t and a fixed power P the solution is T = T_p + (T_0 - T_p(0)) e^(-t/tau),
    T_p = a + b t + P / kA - b tau: matched to rounding at an hourly step, where the
    zero-order hold of the same grid lags by about b dt / 2."""
    kA, C_bar, P, a, b, dt = 800.0, 3.0e7, 20_000.0, -20.0, 10.0 / 86_400, 3600.0
    t = np.arange(25) * dt
    sc = scenario(24 * dt, dt, a + b * t, heating_W=P, initial=Initial("given", {"T": 5.0}))
    tau = C_bar / kA
    T_p = a + b * t + P / kA - b * tau
    exact = T_p + (5.0 - T_p[0]) * np.exp(-t / tau)
    linear = sim.simulate(first_order_fit(kA, C_bar), replace(sc, input_hold="first_order"))
    held = sim.simulate(first_order_fit(kA, C_bar), sc, draws=0)
    np.testing.assert_allclose(linear.series["T"].to_numpy(), exact, rtol=0, atol=1e-9)
    assert np.abs(held.series["T"].to_numpy() - exact).max() > 0.1 * b * dt / 2


@pytest.mark.parametrize("dt", [60.0, 600.0, 3600.0])
def test_first_order_heat_up_time_is_the_analytic_one(dt: float):
    """T(t) = T_inf + (T_0 - T_inf) exp(-t / tau), tau = C_bar / kA, T_inf = T_o + P / kA:
    the time to reach T_1 is tau ln((T_0 - T_inf) / (T_1 - T_inf)), whatever the step."""
    kA, C_bar, P, T_o = 800.0, 3.0e7, 40_000.0, -20.0
    sc = scenario(24 * 3600.0, dt, T_o, heating_W=P, heat_up_to_C=15.0)
    out = sim.simulate(first_order_fit(kA, C_bar), sc, draws=0)
    tau, T_inf = C_bar / kA, T_o + P / kA
    expected = tau * math.log((T_o - T_inf) / (15.0 - T_inf))
    assert out.outcomes["heat_up_time_s"].value == pytest.approx(expected, rel=1e-9)
    assert out.outcomes["heat_up_time_s"].status == "ok"


def test_cool_down_time_is_the_analytic_one():
    kA, C_bar = 800.0, 3.0e7
    sc = scenario(
        24 * 3600.0,
        600.0,
        -10.0,
        heating_W=0.0,
        initial=Initial("given", {"T": 20.0}),
        cool_down_to_C=10.0,
    )
    out = sim.simulate(first_order_fit(kA, C_bar), sc, draws=0)
    expected = C_bar / kA * math.log(30.0 / 20.0)
    assert out.outcomes["cool_down_time_s"].value == pytest.approx(expected, rel=1e-9)
    assert out.outcomes["heat_up_time_s"].status == "not requested"


def test_a_threshold_not_reached_within_the_duration_says_so():
    sc = scenario(3600.0, 60.0, -20.0, heating_W=40_000.0, heat_up_to_C=15.0)
    heat = sim.simulate(first_order_fit(), sc, draws=0).outcomes["heat_up_time_s"]
    assert heat.status == "not reached"
    assert heat.value == math.inf


# ------------------------------------------------------------------------ controllers
def test_pi_controller_holds_the_set_point_within_its_power_limit():
    ctl = Controller(kind="pi", setpoint_C=15.0, power_max_W=60_000.0)
    sc = scenario(48 * 3600.0, 60.0, -20.0, controller=ctl, heat_up_to_C=15.0)
    out = sim.simulate(first_order_fit(), sc, draws=0)
    s = out.series
    assert s["heating_W"].between(0, 60_000).all()
    assert s["heating_W"].iloc[0] == 60_000.0
    assert out.outcomes["peak_power_W"].value == 60_000.0
    assert abs(s["T"].iloc[-1] - 15.0) < 0.01
    # at the end the power is the steady load kA (T - T_o)
    assert s["heating_W"].iloc[-1] == pytest.approx(800.0 * 35.0, rel=1e-3)


def test_thermostat_cycles_within_its_hysteresis():
    ctl = Controller(kind="thermostat", setpoint_C=15.0, power_max_W=60_000.0, hysteresis_K=1.0)
    sc = scenario(48 * 3600.0, 60.0, -20.0, controller=ctl, heat_up_to_C=15.0)
    out = sim.simulate(first_order_fit(), sc, draws=0)
    s = out.series
    reached = out.outcomes["heat_up_time_s"].value
    after = s[s["time_h"] * 3600 > reached + 3600]
    assert set(after["heating_W"].unique()) == {0.0, 60_000.0}
    assert after["T"].between(14.4, 15.6).all()


@pytest.mark.bad_input
def test_unreachable_set_point_is_an_error_naming_file_key_and_value():
    ctl = Controller(kind="pi", setpoint_C=15.0, power_max_W=20_000.0)
    sc = scenario(12 * 3600.0, 60.0, -20.0, controller=ctl, heat_up_to_C=15.0)
    with pytest.raises(sim.UnreachableSetpoint) as err:
        sim.simulate(first_order_fit(), sc, draws=0)
    message = str(err.value)
    assert "\n" not in message
    assert "test.yaml" in message and "heating.controller.power_max_W" in message
    assert "20000" in message and "28,000 W" in message and "unreachable" in message


def test_unreachable_set_point_allowed_is_reported_not_nan():
    ctl = Controller(kind="pi", setpoint_C=15.0, power_max_W=20_000.0)
    sc = scenario(12 * 3600.0, 60.0, -20.0, controller=ctl, heat_up_to_C=15.0)
    out = sim.simulate(first_order_fit(), sc, draws=0, allow_unreachable=True)
    heat = out.outcomes["heat_up_time_s"]
    assert heat.status == "unreachable"
    assert "unreachable" in heat.text(3600.0, "h")
    assert not out.series.isna().any().any()
    assert any("unreachable" in n for n in out.notes)


# ------------------------------------------------------------------------ further heat flows
def test_air_exchange_adds_its_conductance_to_the_losses():
    """A constant air exchange G = rho c_p V' is a conductance in parallel with kA."""
    G, kA, P = 400.0, 800.0, 30_000.0
    sc = scenario(
        400 * 3600.0, 3600.0, -10.0, heating_W=P, air_exchange_W_K=G, gains={"passengers": 2000}
    )
    out = sim.simulate(first_order_fit(kA), sc, draws=0)
    assert out.series["T"].iloc[-1] == pytest.approx(-10.0 + (P + 2000) / (kA + G), abs=1e-6)


# ------------------------------------------------------------------------ bands
def test_bands_of_a_fit_contain_the_prediction_and_are_reproducible(fit_files):
    fit = read_fit(fit_files("Metro1", "order2")[0])
    ctl = Controller(kind="pi", setpoint_C=15.0, power_max_W=60_000.0)
    sc = scenario(24 * 3600.0, 120.0, -20.0, controller=ctl, heat_up_to_C=15.0)
    a = sim.simulate(fit, sc, draws=100, seed=1)
    b = sim.simulate(fit, sc, draws=100, seed=1)
    heat, energy = a.outcomes["heat_up_time_s"], a.outcomes["energy_kWh"]
    assert heat.lo < heat.value < heat.hi
    assert energy.lo < energy.value < energy.hi
    assert heat.to_dict() == b.outcomes["heat_up_time_s"].to_dict()
    assert (a.series["T_lo"] <= a.series["T_hi"]).all()
    assert "systematic error sources (type B)" in a.band_sources


def test_band_follows_the_fits_uncertainty(fit_files):
    """The band of the heat-up time is the fit's: it narrows with the fit's uncertainty."""
    fit = read_fit(fit_files("Metro1", "order2")[0])
    sc = scenario(24 * 3600.0, 120.0, -20.0, heating_W=50_000.0, heat_up_to_C=10.0)
    wide = sim.simulate(fit, sc, draws=400, seed=2).outcomes["heat_up_time_s"]
    tight_data = {**fit.to_dict()}
    tight_data["parameters"] = {
        p: {**e, **({"sd_log": e["sd_log"] / 10} if "sd_log" in e else {})}
        for p, e in fit.content["parameters"].items()
    }
    tight_data["systematic"] = {"effects_log": {}, "effects_log_fixed": {}}
    tight = sim.simulate(Fit.from_dict(tight_data), sc, draws=400, seed=2).outcomes[
        "heat_up_time_s"
    ]
    assert (tight.hi - tight.lo) < 0.3 * (wide.hi - wide.lo)
    assert tight.lo < tight.value < tight.hi


def test_a_fit_with_a_parameter_not_identified_is_not_predicted(fit_files):
    fit = read_fit(fit_files("Metro3", "order2")[0])
    sc = scenario(3600.0, 60.0, -20.0, heating_W=40_000.0)
    with pytest.raises(sim.NotPredictable, match="not identified"):
        sim.simulate(fit, sc, draws=0)


def test_kalman_process_noise_widens_the_band(fit_files):
    """The identified process noise widens the band. The fit's verdict is taken as
    acceptable: a fit in doubt carries no band (test_simulate_limits.py), and it is the
    noise's contribution that is tested here, not this fit's verdict."""
    fit = read_fit(fit_files("Armadillo", "order2_kalman")[0])
    fit = Fit.from_dict({**fit.to_dict(), "verdict": "fit acceptable"})
    sc = scenario(48 * 3600.0, 1800.0, 5.0, heating_W=300.0, heat_up_to_C=12.0)
    with_noise = sim.simulate(fit, sc, draws=300, seed=4)
    data = {k: v for k, v in fit.content.items() if k != "noise"}
    without = sim.simulate(Fit.from_dict(data), sc, draws=300, seed=4)
    assert "process noise (kalman estimator)" in with_noise.band_sources
    w = with_noise.series["T_hi"] - with_noise.series["T_lo"]
    wo = without.series["T_hi"] - without.series["T_lo"]
    assert (w.iloc[-10:] > wo.iloc[-10:]).all()


@pytest.mark.parametrize("vehicle", ["Tram2", "Metro1"])
def test_band_of_a_campaign_fit_holds_the_prediction_of_the_truth(fit_files, vehicle):
    """The virtual campaign's declared truth, run through the same pre-heating, lands inside
    the band of the fit made from its synthetic data - and the band is narrow (a few per cent),
    so it holds the truth by being right, not by being wide."""
    from railtherm import synth

    campaign = synth.load_campaign(ROOT / "config" / "campaign" / "virtual_cwt.yaml")
    truth = synth.ground_truth_table(campaign).set_index("vehicle").loc[vehicle]
    assert not truth["deviations"], "a vehicle without a declared deviation"
    fit = read_fit(fit_files(vehicle, "order2")[0])
    true_data = {**fit.to_dict(), "parameters": {}}
    true_data["parameters"] = {
        p: {"value": float(truth[p]), "estimated": False} for p in ("kA", "C", "K_veh", "C_veh")
    }
    sc = scenario(24 * 3600.0, 60.0, -20.0, heating_W=50_000.0, heat_up_to_C=10.0)
    band = sim.simulate(fit, sc, draws=300, seed=5).outcomes["heat_up_time_s"]
    true = sim.simulate(Fit.from_dict(true_data), sc, draws=0).outcomes["heat_up_time_s"].value
    assert band.lo <= true <= band.hi
    assert (band.hi - band.lo) / band.value < 0.25


def test_irradiance_enters_through_the_fitted_aperture():
    """A first-order model fit_files with an irradiance input I_sol (aperture a_I_sol, m²):
    the scenario's irradiance adds a_I_sol * I to the heat balance; one the model lacks is
    refused, and one the scenario leaves out is said to be taken as 0."""
    kA, a = 800.0, 3.0
    fit = Fit.from_dict(
        {
            "vehicle": "Box",
            "model": "order1",
            "structure": "first_order+I_sol",
            "verdict": "fit acceptable",
            "parameters": {
                "kA": {"value": kA, "estimated": False},
                "C_bar": {"value": 3.0e7, "estimated": False},
                "a_I_sol": {"value": a, "estimated": False},
            },
            "free": [],
        }
    )
    base = scenario(400 * 3600.0, 3600.0, -10.0, heating_W=20_000.0)
    sunny = Scenario(**{**base.__dict__, "irradiance": {"I_sol": np.full(base.t_s.shape, 500.0)}})
    out = sim.simulate(fit, sunny, draws=0)
    assert out.series["T"].iloc[-1] == pytest.approx(-10.0 + (20_000.0 + a * 500.0) / kA, abs=1e-6)
    dark = sim.simulate(fit, base, draws=0)
    assert any("I_sol" in n and "taken as 0" in n for n in dark.notes)
    wrong = Scenario(**{**base.__dict__, "irradiance": {"I_roof": base.T_o * 0}})
    with pytest.raises(sim.ConfigError, match="irradiance.I_roof"):
        sim.simulate(fit, wrong, draws=0)


def test_pi_controller_taking_over_a_steady_state_holds_it_without_a_dip():
    """From `initial: steady` under constant conditions the PI controller starts at the
    steady power (bumpless), so T stays at the set point and the power at kA (T - T_o)."""
    ctl = Controller(kind="pi", setpoint_C=20.0, power_max_W=60_000.0)
    sc = scenario(
        6 * 3600.0, 60.0, -5.0, controller=ctl, initial=Initial("steady"), gains={"p": 3000.0}
    )
    out = sim.simulate(first_order_fit(), sc, draws=0)
    np.testing.assert_allclose(out.series["T"], 20.0, atol=1e-9)
    np.testing.assert_allclose(out.series["heating_W"], 800.0 * 25.0 - 3000.0, rtol=1e-9)


def test_an_implausible_prediction_says_what_to_check():
    """1e12 W of heating (a unit slip) runs the air to ~1e9 °C: the result says so and names
    the inputs to check, instead of printing the number alone."""
    sc = scenario(24 * 3600.0, 600.0, -10.0, heating_W=1.0e12)
    out = sim.simulate(first_order_fit(), sc, draws=0)
    assert out.outcomes["final_T_C"].value > 1e6
    assert any("beyond what a vehicle's interior reaches" in n and "in W" in n for n in out.notes)
    ordinary = sim.simulate(first_order_fit(), scenario(24 * 3600.0, 600.0, -10.0, 20_000.0))
    assert not any("beyond what" in n for n in ordinary.notes)


def test_no_load_means_no_heating_not_rounding_noise(fit_files):
    """Outdoor air at the set point from a steady start: nothing to heat. The PI law's
    difference of near-equal terms left about 1e-12 W in some draws, printed as an energy of
    0 [0, 3.65e-12] kWh; a power below the controller's resolution is none."""
    fit = read_fit(fit_files("Metro1", "order2")[0])
    ctl = Controller(kind="pi", setpoint_C=20.0, power_max_W=60_000.0)
    sc = scenario(6 * 3600.0, 60.0, 20.0, controller=ctl, initial=Initial("steady"))
    out = sim.simulate(fit, sc, draws=40, seed=1)
    for name in ("energy_kWh", "peak_power_W"):
        o = out.outcomes[name]
        assert (o.value, o.lo, o.hi) == (0.0, 0.0, 0.0), o
    assert out.outcomes["energy_kWh"].text() == "0 [0, 0] kWh"
    assert (out.series["heating_W"] == 0.0).all()
