"""railtherm.study.identify: a vehicle's windows and k stage -> fits, budget, verdict."""

import numpy as np
import pandas as pd
import pytest

from railtherm.config import section_defaults
from railtherm.errors import DataError
from railtherm.estimation import models
from railtherm.records import EstimateRecord, JudgedEstimate
from railtherm.study import fitsettings, identify, quality

TRUTH = {"kA": 979.2, "C": 1.8e7, "K_veh": 974.0, "C_veh": 1.0e7}
A = 306.0
STEP = 120.0


def window(hours: float, Q0: float, Q1: float, T_o: float = -10.0) -> pd.DataFrame:
    """A noise-free tidy window: steady at Q0, then a heating step to Q1 after 2 h."""
    n = int(hours * 3600 / STEP) + 1
    t = np.arange(n) * STEP
    Q = np.where(t < 7200, Q0, Q1)
    u = np.column_stack([np.full(n, T_o), Q])
    Ac, Bc = models.second_order(**TRUTH)
    x0 = models.steady_state(Ac, Bc, np.array([T_o, Q0]))
    x = models.simulate(models.STRUCTURES["second_order"], TRUTH, u, STEP, x0)
    return pd.DataFrame({"time": t, "T": x[:, 0], "T_veh": x[:, 1], "T_o": T_o, "Q_H": Q})


def vehicle(**model) -> dict:
    return {
        "id": "V",
        "synthetic": True,
        "surface_m2": A,
        "mass_kg": 30_030.0,
        "volume_m3": 120.0,
        "channels": {
            "indoor_air": [{"column": "a"}] * 4,
            "surface": [{"column": "s"}] * 4,
            "outdoor_air": [{"column": "o"}] * 2,
            "heater_power": [{"column": "p", "unit": "W"}],
        },
        "instruments": {"temperature_u_K": 0.0, "power_u_rel": 0.0, "surface_u_rel": 0.0},
        "model": {
            "orders": [2],
            "mode": "static",
            "x0": "measured",
            "covariance": "iid",
            "start": "auto",
            "initial": {"C": 120480, "C_veh": 500000, "K_veh": 20, "C_bar": 620480},
            "bounds": {"C": [1e4, 1e10], "K_veh": [1e-2, 1e7], "C_veh": [1e4, 1e10]},
            **model,
        },
    }


def k_result(usable=True, scatter=0.0, storage=0.0, delta_T=30.0):
    """A static k stage that measured the truth: kA = mean(Q_H) / delta_T (eq. 10), with
    the k window's own standard uncertainties (W/(m^2 K))."""
    k = TRUTH["kA"] / A
    budget = {"scatter": scatter, "storage": storage}
    return {
        "k": k,
        "usable": usable,
        "forced": False,
        "Q_H_mean": TRUTH["kA"] * delta_T,
        "delta_T": delta_T,
        "budget": budget,
    }


TABLES = {"up": window(30, 20_000, 29_000), "down": window(30, 29_000, 20_000)}


def test_two_stage_fit_recovers_the_truth_and_cross_validates():
    estimate, series = identify.identify(TABLES, vehicle(), k_result(), 2)
    params = estimate.content["fit"]["parameters"]
    assert params["kA"] == {"value": pytest.approx(TRUTH["kA"]), "estimated": False}
    for p in ("C", "K_veh", "C_veh"):
        assert params[p]["value"] == pytest.approx(TRUTH[p], rel=1e-5)
    assert estimate.content["k_source"] == "static test (eq. 10)"
    assert {(cv["train"], cv["test"]) for cv in estimate.content["cross_validation"]} == {
        ("up", "down"),
        ("down", "up"),
    }
    assert all(cv["r2_T"] > 0.999999 for cv in estimate.content["cross_validation"])
    assert set(series["window"]) == {"up", "down"}
    assert np.abs(series["T_residual"]).max() < 1e-6
    result = quality.check(estimate, series, section_defaults("check"))
    assert result.content["verdict"] == "fit acceptable" and result.content["R2"] == pytest.approx(
        1.0
    )


@pytest.mark.bad_input
def test_unusable_static_k_falls_back_to_joint_and_says_so():
    estimate, series = identify.identify(TABLES, vehicle(), k_result(usable=False), 2)
    assert estimate.content["k_source"] == "joint estimation (PEM)"
    assert estimate.content["fit"]["parameters"]["kA"]["value"] == pytest.approx(
        TRUTH["kA"], rel=1e-5
    )
    result = quality.check(estimate, series, section_defaults("check"))
    assert result.content["verdict"] == "assumptions in doubt"
    assert any("kA estimated jointly" in r for r in result.content["reasons"])


def test_systematic_uncertainty_widens_the_interval_by_its_budget():
    exact, _ = identify.identify(TABLES, vehicle(), k_result(), 2)
    assert all(
        e == pytest.approx(0.0, abs=1e-9)
        for effects in exact.content["systematic"]["effects_log"].values()
        for e in effects.values()
    )
    data = vehicle()
    data["instruments"] = {"temperature_u_K": 0.1, "power_u_rel": 0.01, "surface_u_rel": 0.02}
    uncertain, _ = identify.identify(TABLES, data, k_result(scatter=0.02, storage=0.01), 2)
    # each physical source once: no kA source beside the instruments it is made of, and the
    # surface, which moves k but not kA = k A, is none
    assert set(uncertain.content["systematic"]["sources"]) == {
        "power_scale",
        "offset_T",
        "offset_T_veh",
        "offset_T_o",
        "k_scatter",
        "k_storage",
    }
    for p in ("C", "K_veh", "C_veh"):
        entry = uncertain.content["fit"]["parameters"][p]
        lo, hi = entry["ci95"]
        slo, shi = entry["ci95_statistical"]
        assert lo < slo and hi > shi  # the combined interval contains the statistical one
        assert lo < TRUTH[p] < hi


@pytest.mark.parametrize("mode", ["static", "joint"])
def test_power_scale_error_moves_every_parameter_by_its_scale(mode):
    """Q_H -> s Q_H in every record, the k window's included, is matched exactly by kA, K_veh,
    C, C_veh -> s times each (eqs. 7-8 and 10 are homogeneous in them), so each log-parameter
    moves by log(s): in the two-stage method too, where kA follows through eq. 10."""
    data = vehicle(mode=mode)
    data["instruments"] = {"temperature_u_K": 0.0, "power_u_rel": 0.01, "surface_u_rel": 0.0}
    estimate, _ = identify.identify(TABLES, data, k_result() if mode == "static" else None, 2)
    effects = estimate.content["systematic"]["effects_log"]
    for p in ("C", "K_veh", "C_veh") + (("kA",) if mode == "joint" else ()):
        assert effects[p]["power_scale"] == pytest.approx(np.log(1.01), rel=1e-4)
        entry = estimate.content["fit"]["parameters"][p]
        assert entry["sd_log_total"] == pytest.approx(np.log(1.01), rel=1e-3)


def test_an_offset_on_both_temperatures_of_the_k_window_is_one_source_each():
    """A calibration offset of the indoor sensors moves mean(T) - mean(T_o) in eq. 10 and the
    fitted T together; its effect on C_veh is that of the joint perturbation, not of kA alone
    or of the records alone."""
    data = vehicle()
    data["instruments"] = {"temperature_u_K": 0.2, "power_u_rel": 0.0, "surface_u_rel": 0.0}
    estimate, _ = identify.identify(TABLES, data, k_result(), 2)
    u = 0.2 / 2.0  # four indoor sensors
    kA = TRUTH["kA"] * 30.0 / (30.0 + u)  # eq. 10 with the offset on T
    shifted = {n: t.assign(T=t["T"] + u) for n, t in TABLES.items()}
    direct, _ = identify.identify(shifted, vehicle(), {**k_result(), "k": kA / A}, 2)
    for p in ("C", "K_veh", "C_veh"):
        expected = np.log(direct.content["fit"]["parameters"][p]["value"] / TRUTH[p])
        assert estimate.content["systematic"]["effects_log"][p]["offset_T"] == pytest.approx(
            expected,
            abs=5e-5,  # two fits, each converged to ~1e-5 in log theta
        )


@pytest.mark.bad_input
def test_residuals_beyond_sensor_accuracy_put_the_fit_in_doubt():
    estimate, series = identify.identify(TABLES, vehicle(), k_result(), 2)
    noisy = series.copy()
    noisy["T"] += 0.5 * np.sin(noisy["time"] / 3600.0)  # a dynamic the model lacks
    noisy["T_residual"] = noisy["T"] - noisy["T_sim"]
    result = quality.check(estimate, noisy, section_defaults("check"))
    assert result.content["verdict"] == "assumptions in doubt"
    assert any("misses the measurement" in r for r in result.content["reasons"])


def test_without_surface_sensors_the_fit_uses_T_and_still_cross_validates():
    tables = {name: t.assign(T_veh=np.nan) for name, t in TABLES.items()}
    estimate, _ = identify.identify(tables, vehicle(), k_result(), 2)
    assert estimate.content["outputs"] == ["T"]
    assert "offset_T_veh" not in estimate.content["systematic"]["sources"]
    assert [cv["r2_T"] for cv in estimate.content["cross_validation"]] == pytest.approx([1.0, 1.0])


@pytest.mark.bad_input
@pytest.mark.parametrize(
    ("factor", "reasons"),
    [
        (1000.0, ("outside the physical range",)),  # W logged, kW declared: C at its bound
        # the reverse: the air node pinned at the air's own capacity (volume_m3's bound)
        (1e-3, ("outside the physical range", "sits at its physical lower bound")),
    ],
)
def test_a_unit_mistake_in_the_power_is_never_fit_acceptable(factor, reasons):
    """Power in W declared kW once gave k = 2003 W/(m^2 K) and C_bar = 5e9 J/K, 'fit
    acceptable': every number scaled, every fit measure perfect. Plausibility says so; the
    stored heat per kg is judged where the capacities are identified (test below)."""
    tables = {n: t.assign(Q_H=t["Q_H"] * factor) for n, t in TABLES.items()}
    k = k_result()
    k["k"], k["Q_H_mean"] = k["k"] * factor, k["Q_H_mean"] * factor
    estimate, series = identify.identify(tables, vehicle(), k, 2)
    result = quality.check(estimate, series, section_defaults("check"))
    assert result.content["verdict"] == "assumptions in doubt"
    for text in reasons:
        assert any(text in r for r in result.content["reasons"]), (text, result.content["reasons"])
    ok, _ = identify.identify(TABLES, vehicle(), k_result(), 2)
    assert quality.plausibility(ok, section_defaults("check")) == []


@pytest.mark.bad_input
def test_capacities_that_store_more_than_water_are_implausible():
    estimate, _ = identify.identify(TABLES, vehicle(), k_result(), 2)
    light = EstimateRecord.from_dict({**estimate.content, "mass_kg": 5_000.0})  # 5600 J/(kg K)
    reasons = quality.plausibility(light, section_defaults("check"))
    assert len(reasons) == 1 and "5600 J/(kg K)" in reasons[0] and "more than water" in reasons[0]


@pytest.mark.bad_input
def test_an_aperture_larger_than_the_whole_surface_is_implausible():
    """An effective solar aperture of 1000 m² on a body of 8.64 m² outer surface is named;
    one of 2 m² is not judged."""
    estimate, _ = identify.identify(TABLES, vehicle(), k_result(), 2)
    par = estimate.content["fit"]["parameters"]

    def with_aperture(a: float) -> dict:
        entry = {"value": a, "ci95": [0.9 * a, 1.1 * a], "estimated": True}
        fit = {**estimate.content["fit"], "parameters": {**par, "a_I_sol": entry}}
        return EstimateRecord.from_dict({**estimate.content, "A": 8.64, "fit": fit})

    thresholds = {**section_defaults("check"), "k_range_W_m2K": [0.01, 1000.0]}
    (reason,) = quality.plausibility(with_aperture(1000.0), thresholds)
    assert "a_I_sol = 1000 m²" in reason and "A = 8.64 m²" in reason
    assert quality.plausibility(with_aperture(2.0), thresholds) == []


def test_joint_conductance_bounds_follow_the_records_scale():
    """A 4 W/K test box and a 2000 W/K coach both start well inside their default bounds."""
    for kA in (4.0, 2000.0):
        lo, hi = fitsettings.conductance_bounds(kA)
        assert lo <= kA / 100 and hi >= kA * 100
    assert fitsettings.conductance_bounds(None) == fitsettings.KA_BOUNDS


@pytest.mark.bad_input
def test_time_in_minutes_declared_seconds_is_never_fit_acceptable():
    """Minutes read as seconds compress every window 60-fold: the fit is as good as ever and
    every capacity is 60 times too small (k, from means, is unchanged)."""
    tables = {n: t.assign(time=t["time"] / 60.0) for n, t in TABLES.items()}
    estimate, series = identify.identify(tables, vehicle(), k_result(), 2)
    result = quality.check(estimate, series, section_defaults("check"))
    assert result.content["verdict"] == "assumptions in doubt"
    assert any("time column's unit" in r for r in result.content["reasons"]), result.content[
        "reasons"
    ]


@pytest.mark.bad_input
def test_a_fit_says_how_many_rows_it_used_and_refuses_too_few():
    """A fit once used 280 of 1609 rows without a word: the rows used are in the estimate,
    a missing input stops the fit, and so does a measurement missing in too many rows."""
    estimate, _ = identify.identify(TABLES, vehicle(), k_result(), 2)
    name, table = next(iter(TABLES.items()))
    assert estimate.content["rows"][name] == {
        "rows": len(table),
        "used": {"T": len(table), "T_veh": len(table)},
    }
    holes = {n: t.copy() for n, t in TABLES.items()}
    holes[name].loc[holes[name].index[5:], "T"] = np.nan
    with pytest.raises(DataError, match=rf"V window {name}: column 'T' = '5 of \d+ rows'"):
        identify.identify(holes, vehicle(), k_result(), 2)
    gap = {n: t.copy() for n, t in TABLES.items()}
    gap[name]["Q_H"] = gap[name]["Q_H"].astype(float)
    gap[name].loc[gap[name].index[7], "Q_H"] = np.inf
    with pytest.raises(DataError, match=r"column 'Q_H' = inf: row 7 "):
        identify.identify(gap, vehicle(), k_result(), 2)
    few = {n: t.copy() for n, t in TABLES.items()}
    few[name].loc[few[name].index[:3], "T"] = np.nan  # a few missing rows are skipped
    estimate, _ = identify.identify(few, vehicle(), k_result(), 2)
    assert estimate.content["rows"][name]["used"]["T"] == len(table) - 3


@pytest.mark.parametrize("order, air", [(2, "C"), (1, "C_bar")])
def test_the_air_in_the_volume_is_the_lower_bound_of_the_air_node(order, air):
    data = vehicle(bounds={})
    structure = fitsettings.model_structure(order, data)
    _, _, bounds, _, _ = fitsettings._settings(structure, data, k_result(), TABLES)
    assert bounds[air] == pytest.approx((quality.RHO_CP_AIR * 120.0, 1e10))
    without = {k: v for k, v in data.items() if k != "volume_m3"}
    _, _, bounds, _, _ = fitsettings._settings(structure, without, k_result(), TABLES)
    assert air not in bounds  # the structure's loose 1e4 J/K stays
    assert structure.bounds[air][0] == 1e4
    # a configured lower bound below the air's capacity (1.45e5 J/K) is raised to it ...
    given = vehicle(bounds={air: [2e4, 1e9]})
    _, _, bounds, _, _ = fitsettings._settings(structure, given, k_result(), TABLES)
    assert bounds[air] == pytest.approx((quality.RHO_CP_AIR * 120.0, 1e9))
    # ... one above it is kept
    given = vehicle(bounds={air: [1e6, 1e9]})
    _, _, bounds, _, _ = fitsettings._settings(structure, given, k_result(), TABLES)
    assert bounds[air] == (1e6, 1e9)


def test_a_bad_volume_is_refused_naming_the_key():
    data = vehicle(bounds={}) | {"volume_m3": -5}
    with pytest.raises(identify.ConfigError, match="volume_m3"):
        fitsettings.physical_bounds(models.STRUCTURES["second_order"], data)


def test_an_estimate_at_the_physical_bound_says_so_and_takes_its_coupled_parameters_along():
    floor = quality.RHO_CP_AIR * 120.0

    def entry(value, sd):
        ci = [value * np.exp(-1.96 * sd), value * np.exp(1.96 * sd)]
        return {"value": value, "estimated": True, "sd_log": sd, "ci95": ci}

    fitted = {
        "parameters": {
            "kA": {"value": 979.2, "estimated": False},
            "C": entry(floor, 0.5),
            "K_veh": entry(2e4, 1.0),
            "C_veh": entry(1.3e7, 0.2),
        },
        "free": ["C", "K_veh", "C_veh"],
        "correlation": np.eye(3).tolist(),
        "flags": [{"code": "at_bound", "parameters": ["C"], "message": ""}],
    }
    bounds = {"C": (floor, 1e10), "K_veh": (1e-2, 1e7), "C_veh": (1e4, 1e10)}
    judged = identify.judge_identification(
        JudgedEstimate.from_dict(fitted),
        bounds,
        models.STRUCTURES["second_order"],
        physical={"C": fitsettings.AIR_CAPACITY},
        budget={"effects_log": {"C_veh": {"scale_Q_H": 0.05}}},
    )
    assert "identified" not in fitted["parameters"]["C"]  # judged into a new record
    par = judged.content["parameters"]
    assert par["C"]["reason"].startswith("at its physical lower bound (the air's capacity ρ c_p V")
    assert par["C"]["limit"] == "none"
    assert not par["K_veh"]["identified"] and not par["C_veh"]["identified"]
    assert par["C_veh"]["reason"] == "coupled to C, which is not identified"
    total = judged.content["totals"]["C_total"]
    assert total["identified"] and total["value"] == pytest.approx(1.3e7 + floor)
    w = 1.3e7 / (1.3e7 + floor)
    assert total["sd_log_total"] == pytest.approx(w * np.hypot(0.2, 0.05))


def test_combined_intervals_are_new_entries_beside_the_statistical_ones():
    """The combined interval (statistical and systematic sds of log theta in quadrature)
    replaces ``ci95`` in new entries; the statistical one is kept as ``ci95_statistical``
    and the estimator's entries are left as they are."""
    from railtherm.study.budget import combine_uncertainty

    stat = [2.0e5 * np.exp(-1.96 * 0.03), 2.0e5 * np.exp(1.96 * 0.03)]
    parameters = {
        "kA": {"value": 900.0, "estimated": False},
        "C": {"value": 2.0e5, "estimated": True, "sd_log": 0.03, "ci95": stat},
    }
    combined = combine_uncertainty(parameters, {"effects_log": {"C": {"a": 0.04}}})
    assert parameters["C"]["ci95"] == stat and "sd_log_total" not in parameters["C"]
    assert combined["kA"] == parameters["kA"]
    assert combined["C"]["sd_log_total"] == pytest.approx(0.05)
    assert combined["C"]["ci95_statistical"] == stat
    lo, hi = combined["C"]["ci95"]
    z = 1.959964  # the normal's 97.5 % quantile
    assert (lo, hi) == pytest.approx((2.0e5 * np.exp(-z * 0.05), 2.0e5 * np.exp(z * 0.05)))
