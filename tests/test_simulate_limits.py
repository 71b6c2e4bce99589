"""The bands' physical limits and when a prediction carries no band (railtherm.study.simulate,
railtherm.study.predictions, railtherm.study.classvalidation): draws truncated at the air's capacity
rho c_p V, no band from a fit in doubt or from a class statistic of two vehicles, the
declared truth against the reference band, and deterministic draws."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml
from test_predictions import T_O, _member, scenario

from railtherm.errors import ConfigError
from railtherm.estimation import models
from railtherm.study import classvalidation, predictions
from railtherm.study import simulate as sim
from railtherm.study.classmodel import ClassMember
from railtherm.study.fit import Fit
from railtherm.study.quality import RHO_CP_AIR
from railtherm.study.scenario import Scenario

TARGET, POWER = 15.0, 60_000.0
VOLUME = 89.4  # m³
THETA = {"kA": 800.0, "C": 2.0e6, "K_veh": 400.0, "C_veh": 1.6e7}


def preheat(hours: float = 6.0) -> Scenario:
    """A soaked vehicle at T_O heated at a constant POWER; the heat-up time to TARGET."""
    return scenario(heat_up_to_C=TARGET, hours=hours, power_W=POWER)


def fit(
    theta: dict = THETA,
    sd_C: float = 0.025,
    verdict: str = "fit acceptable",
    vehicle: str = "W1",
) -> Fit:
    """A second-order fit (eqs. 7-8) with statistical sd_log ``sd_C`` on C, 0.025 on the rest."""
    params = {"kA": {"value": theta["kA"], "estimated": False}}
    for p in ("C", "K_veh", "C_veh"):
        sd = sd_C if p == "C" else 0.025
        params[p] = {
            "value": theta[p],
            "estimated": True,
            "ci95": [theta[p] * math.exp(-1.96 * sd), theta[p] * math.exp(1.96 * sd)],
            "sd_log": sd,
            "identified": True,
        }
    return Fit.from_dict(
        {
            "vehicle": vehicle,
            "model": "order2",
            "structure": "second_order",
            "verdict": verdict,
            "reasons": [] if verdict == "fit acceptable" else ["residuals not white"],
            "parameters": params,
            "free": ["C", "K_veh", "C_veh"],
            "correlation": np.eye(3).tolist(),
        }
    )


def air_alone_s() -> float:
    """The heat-up time of the air in VOLUME alone: rho c_p V Delta T / P."""
    return RHO_CP_AIR * VOLUME * (TARGET - T_O) / POWER


# ------------------------------------------------------------------------ truncated draws
def test_a_wide_C_interval_never_heats_up_faster_than_the_air_alone():
    """C drawn with sd_log 2 (a factor 50 at 95 %) reaches far below the air's capacity:
    without the vehicle's volume the band's lower end is faster than heating the air alone;
    with it, every kept draw holds C >= rho c_p V, the band's lower end is no faster than
    the air alone, and the share rejected is reported and said to set the band's end."""
    wide = fit(sd_C=2.0)
    free = sim.simulate(wide, preheat(), draws=200, seed=3)
    assert free.outcomes["heat_up_time_s"].lo < air_alone_s()  # the limit is what holds it
    assert free.rejected == 0 and "no volume_m3" in free.limits

    held = sim.simulate(wide, preheat(), draws=200, seed=3, volume_m3=VOLUME)
    assert held.draws == 200 and held.rejected > 0
    assert held.outcomes["heat_up_time_s"].lo >= air_alone_s()
    assert held.rejected_share >= sim.LIMIT_DOMINATED
    assert "rests on the limit" in held.limit_note()
    assert held.to_dict()["draws_rejected"] == held.rejected

    d, rejected = sim._physical_draws(
        sim.parameter_set(wide), 500, np.random.default_rng(1), RHO_CP_AIR * VOLUME
    )
    assert rejected > 0 and len(d["C"]) == 500
    assert d["C"].min() >= RHO_CP_AIR * VOLUME
    assert all((v > 0).all() and np.isfinite(v).all() for v in d.values())


def test_a_narrow_fit_rejects_nothing_and_its_band_is_unchanged():
    """A fit far from the limit: no draw is rejected, the band is the one drawn without a
    volume (the same generator, the same draws) and no note is added."""
    a = sim.simulate(fit(), preheat(), draws=100, seed=2, volume_m3=VOLUME)
    b = sim.simulate(fit(), preheat(), draws=100, seed=2)
    assert a.rejected == 0 and a.limit_note() == ""
    assert a.outcomes["heat_up_time_s"] == b.outcomes["heat_up_time_s"]


def test_draws_are_deterministic():
    """The same seed gives the same text (outcomes, rejected draws), a different seed other
    numbers: rejection sampling keeps the draws in the generator's order."""

    def text(seed: int) -> str:
        r = sim.simulate(fit(sd_C=2.0), preheat(), draws=120, seed=seed, volume_m3=VOLUME)
        return yaml.safe_dump(r.to_dict(), sort_keys=False)

    assert text(7) == text(7)
    assert text(7) != text(8)


@pytest.mark.parametrize("volume", [-1.0, 0.0, math.inf, "89 m3"])
def test_a_volume_that_is_not_positive_is_refused(volume):
    with pytest.raises(ConfigError, match="volume_m3"):
        sim.simulate(fit(), preheat(), draws=10, volume_m3=volume)


# ------------------------------------------------------------------------ fits in doubt
def test_a_fit_in_doubt_gets_no_band_and_the_mark():
    """A fit whose verdict is "assumptions in doubt" gives its central prediction (the same
    as an acceptable fit with the same parameters) without a band: empty band columns, a
    column saying why, the mark in the Markdown table; the acceptable fit keeps its band."""
    doubt = fit(verdict="assumptions in doubt", vehicle="D1")
    fits = {"W1": fit(), "D1": doubt}
    classes = {"W1": "metro", "D1": "metro"}
    volumes = {"W1": VOLUME, "D1": VOLUME}
    sc = preheat()
    table, runs = predictions.scenario_table(fits, classes, [sc], 50, 0, volumes=volumes)
    w1, d1 = table.set_index("vehicle").loc["W1"], table.set_index("vehicle").loc["D1"]
    assert w1["no_band"] == "" and w1["heat_up_h_lo"] < w1["heat_up_h"] < w1["heat_up_h_hi"]
    assert "assumptions in doubt" in d1["no_band"]
    for stem in ("heat_up_h", "energy_kWh", "peak_kW", "final_T_C"):
        assert math.isnan(d1[f"{stem}_lo"]) and math.isnan(d1[f"{stem}_hi"])
    assert d1["heat_up_h"] == pytest.approx(w1["heat_up_h"], rel=1e-12)
    assert math.isnan(d1["draws_rejected_pct"]) and w1["draws_rejected_pct"] == 0.0
    assert "T_lo" not in runs["preheat", "D1"].series
    md = predictions.scenario_markdown(table, [sc], "synthetic: test", 50, volumes)
    row = next(line for line in md.splitlines() if line.startswith("| D1 |"))
    assert f"{d1['heat_up_h']:.3g} {predictions.DOUBT_MARK}" in row and "[" not in row
    assert f"{predictions.DOUBT_MARK}: assumptions in doubt, no band" in md
    assert "no 95 % band" in runs["preheat", "D1"].summary()


def test_the_share_rejected_is_reported_in_the_scenario_table():
    wide = fit(sd_C=2.0)
    table, _ = predictions.scenario_table(
        {"W1": wide}, {"W1": "metro"}, [preheat()], 100, 0, volumes={"W1": VOLUME}
    )
    share = float(table["draws_rejected_pct"].iloc[0])
    assert share > 0
    md = predictions.scenario_markdown(table, [preheat()], "test", 100, {"W1": VOLUME})
    assert f"W1: {share:.1f} % of the parameter draws lay beyond the physical limits" in md
    md = predictions.scenario_markdown(table, [preheat()], "test", 100, {"W1": None})
    assert "no volume_m3, positivity only: W1" in md


# ------------------------------------------------------------------------ leave-one-out
def _series(theta: dict) -> object:
    import pandas as pd

    structure = models.structure_for("second_order")
    n, dt = 300, 60.0
    u = np.column_stack([np.full(n, -10.0), np.where(np.arange(n) < 150, 30_000.0, 0.0)])
    x = models.simulate(structure, theta, u, dt, [-10.0, -10.0])
    return pd.DataFrame(
        {
            "window": "w",
            "time": np.arange(n) * dt,
            "T": x[:, 0],
            "T_sim": x[:, 0],
            "T_veh": x[:, 1],
            "T_veh_sim": x[:, 1],
            "T_o": u[:, 0],
            "Q_H": u[:, 1],
        }
    )


def _class(n: int) -> tuple[dict, list[ClassMember]]:
    """``n`` metro vehicles whose parameters scatter by a few per cent."""
    thetas = {
        f"M{i + 1}": {
            p: v * (1.0 + 0.04 * ((i * (j + 2)) % 5 - 2)) for j, (p, v) in enumerate(THETA.items())
        }
        for i in range(n)
    }
    return thetas, [_member(vid, "metro", th) for vid, th in thetas.items()]


def test_leave_one_out_with_two_other_vehicles_gives_no_band():
    """Three vehicles: each one's class model rests on the two others, a Cauchy spread - no
    band, the row says why; four vehicles leave three, and the band is drawn."""
    sc = preheat()
    for n, banded in ((3, False), (4, True)):
        thetas, members = _class(n)
        fits = {vid: fit(th, vehicle=vid) for vid, th in thetas.items()}
        series = {vid: _series(th) for vid, th in thetas.items()}
        volumes = dict.fromkeys(thetas, VOLUME)
        table = classvalidation.leave_one_out(
            members, fits, series, sc, 2, draws=40, seed=0, volumes=volumes
        )
        done = table[(table["status"] == "predicted") & (table["basis"] == "class")]
        assert len(done) == 2 * n and (done["n_basis"] == n - 1).all()
        lo = done["heat_up_ref_h_lo"].astype(float)
        if banded:
            assert lo.notna().all() and (lo >= air_alone_s() / 3600.0).all()
        else:
            assert lo.isna().all() and done["energy_ref_kWh_lo"].astype(float).isna().all()
            assert done["heat_up_inside"].isna().all()
            assert done["band_note"].str.contains("rests on 2 other vehicles, fewer than 3").all()
            md = classvalidation.validation_markdown(table, sc, "synthetic: test")
            assert "‡" in md and "no band for 3" in md


def test_leave_one_out_compares_the_band_with_the_declared_truth():
    """Where a vehicle's true parameters are known, its heat-up time from them is reported
    and checked against the reference band; a truth far off lies outside."""
    sc = preheat()
    thetas, members = _class(4)
    fits = {vid: fit(th, vehicle=vid) for vid, th in thetas.items()}
    series = {vid: _series(th) for vid, th in thetas.items()}
    truth = {"M1": thetas["M1"], "M2": {**thetas["M2"], "C": 40 * thetas["M2"]["C"]}}
    table = classvalidation.leave_one_out(
        members, fits, series, sc, 2, draws=40, seed=0, truth=truth
    )
    done = table[table["status"] == "predicted"].set_index(["vehicle", "basis", "k_from"])
    m1 = done.loc["M1", "class", "class"]
    assert m1["heat_up_true_h"] == pytest.approx(m1["heat_up_fit_h"], rel=1e-9)
    assert m1["heat_up_true_inside"] == m1["heat_up_inside"]
    m2 = done.loc["M2", "class", "class"]
    assert m2["heat_up_true_h"] > m2["heat_up_ref_h_hi"] and m2["heat_up_true_inside"] is False
    assert done.loc["M3", "class", "class"]["heat_up_true_inside"] is None
    md = classvalidation.validation_markdown(table.reset_index(drop=True), sc, "test")
    assert "the declared truth's heat-up time inside the band for" in md


def test_a_fit_below_the_air_capacity_has_no_band_and_says_so():
    """A fit whose C is far below the air's capacity (a unit mistake): no draw is a vehicle,
    so no band is drawn, and the result says why and that the central C is below the air's."""
    small = fit({**THETA, "C": 1.0e4})
    r = sim.simulate(small, preheat(), draws=20, seed=0, volume_m3=VOLUME)
    assert r.draws == 0 and r.outcomes["heat_up_time_s"].lo is None
    assert "physical limits" in r.band_withheld and "dominated by the limit" in r.band_withheld
    assert any("below the capacity of the air" in n for n in r.notes)
