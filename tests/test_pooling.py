"""Partial pooling (railtherm.study.pooling): a vehicle's class prior is built without it, the
class prior in the sampler is the Student-t density scipy gives, and the study table shows
maximum likelihood, prior and posterior side by side."""

import math

import numpy as np
import pytest
from scipy import stats
from test_profile import record, simulate

from railtherm.estimation import models, sampling
from railtherm.estimation.priors import LinearT
from railtherm.study import pooling
from railtherm.study.classmodel import ClassMember

S1 = models.STRUCTURES["first_order"]


def member(vid, vehicle_class, c_veh):
    return ClassMember(
        vehicle=vid, vehicle_class=vehicle_class, mass_kg=40_000.0, surface_m2=250.0, k=2.5,
        c_veh=c_veh, delta=2.0, kappa_veh=2.0, usable=True, why="",
    )  # fmt: skip


VEHICLE = {"class": "metro", "mass_kg": 40_000.0, "surface_m2": 250.0}


def test_a_vehicles_class_prior_is_built_without_it_and_falls_back_to_all_classes():
    members = [member("M1", "metro", 300.0), member("M2", "metro", 400.0),
               member("M3", "metro", 500.0), member("R1", "regional", 600.0)]  # fmt: skip
    prior = pooling.class_prior(members, "M1", VEHICLE, kA_held=625.0)
    assert prior.basis == "class" and prior.reference.basis == ["M2", "M3"]
    # c_veh's centre: the geometric mean of the others' (400, 500); no k term (kA held)
    assert prior.reference.generalised["c_veh"].centre == pytest.approx(math.sqrt(400 * 500))
    assert {t.name for t in prior.terms} == {"class:c_veh", "class:delta", "class:kappa_veh"}
    assert set(prior.to_dict()["parameters"]) == {"C", "K_veh", "C_veh"}  # kA held
    # a class with one other vehicle: every rail class pooled, still without the vehicle
    prior = pooling.class_prior(members[:2] + members[3:], "M1", VEHICLE, kA_held=None)
    assert prior.basis == "all" and sorted(prior.reference.basis) == ["M2", "R1"]
    assert "class:k" in {t.name for t in prior.terms}
    assert set(prior.to_dict()["parameters"]) == {"kA", "C", "K_veh", "C_veh"}
    # no surface: no class prior, and the reason
    prior = pooling.class_prior(members, "M1", {"class": "metro", "mass_kg": 4e4}, None)
    assert prior.reference is None and "surface_m2" in prior.reason
    assert prior.to_dict() == {"kind": "vehicle", "reason": prior.reason}
    # the vehicle's own prior on C_veh: the class model would give it a second one (before:
    # PriorError's traceback from the fit); its own prior on kA, held by the static test,
    # takes nothing from the class model (no k term) and keeps the class prior
    own = {**VEHICLE, "model": {"priors": {"C_veh": {"kind": "lognormal"}}}}
    prior = pooling.class_prior(members, "M1", own, kA_held=625.0)
    assert prior.reference is None and "own model.priors on C_veh" in prior.reason
    held = {**VEHICLE, "model": {"priors": {"kA": {"kind": "lognormal"}}}}
    assert pooling.class_prior(members, "M1", held, kA_held=625.0).reference is not None


def test_nuts_with_a_class_term_samples_the_likelihood_times_scipys_student_t():
    """A first-order record (kA held), C_bar with a class-like term: log C_bar ~ log centre +
    scale T_3. NUTS draws of log C_bar against the grid of -(m/2) ln(e^T e) + ln t_3 density
    (scipy.stats.t), e^T e by an independent recursion (tests/test_profile.py)."""
    e = record(1.6e7, n=60, seed=11, sd=0.4)
    kA = 800.0  # the record's truth (tests/test_profile.py KA)
    term = LinearT("class:C_bar", (("C_bar", 1.0),), 0.0, math.log(2.2e7), 0.25, 3.0)
    post = sampling.sample(
        S1, [e], estimator="output_error", covariance="iid", x0="measured", fixed={"kA": kA},
        prior_terms=[term], chains=2, draws=1500, tune=600, seed=4,
    )  # fmt: skip
    assert (post.summary()["r_hat"] < 1.01).all() and post.divergences() == 0
    draws = np.log(post.idata.posterior["C_bar"].values.ravel())
    y = e.y[:, 0]
    m = len(y) - 1
    grid = np.linspace(draws.mean() - 8 * draws.std(), draws.mean() + 8 * draws.std(), 801)
    sse = np.array([np.sum((simulate(kA, math.exp(g), e.u, y[0])[1:] - y[1:]) ** 2) for g in grid])
    logp = -0.5 * m * np.log(sse) + stats.t(3.0, loc=math.log(2.2e7), scale=0.25).logpdf(grid)
    w = np.exp(logp - logp.max())
    w /= w.sum()
    mean = float(grid @ w)
    sd = math.sqrt(float((grid - mean) ** 2 @ w))
    assert np.mean(draws) == pytest.approx(mean, abs=0.1 * sd)
    assert np.std(draws) == pytest.approx(sd, rel=0.1)
    cdf = np.cumsum(w)
    for q in (0.025, 0.975):
        assert np.quantile(draws, q) == pytest.approx(np.interp(q, cdf, grid), abs=0.2 * sd)


def record_file(ml_identified=True):
    ml = {"value": 5e6, "estimated": True, "identified": ml_identified, "ci95": [4e6, 6e6]}
    if not ml_identified:
        ml["profile"] = {"kind": "upper", "lower": None, "upper": 7.04e6}
    return {
        "vehicle": "Metro3", "model": "order2",
        "prior": {"kind": "class", "class": "metro", "basis": "class",
                  "vehicles": ["Metro1", "Metro2"],
                  "parameters": {"C_veh": {"value": 6e6, "ci95": [2e6, 1.8e7]}}},
        "diagnostics": {"r_hat_max": 1.002, "ess_bulk_min": 1500.0, "divergences": 0,
                        "trusted": True},
        "parameters": {
            "kA": {"ml": {"value": 700.0, "estimated": False, "identified": True,
                          "ci95": [680.0, 720.0]},
                   "median": 700.0, "ci95": [681.0, 719.0], "sampled": False},
            "C_veh": {"ml": ml, "median": 5.6e6, "ci95": [4.1e6, 7.9e6], "sampled": True},
        },
    }  # fmt: skip


def test_the_pooling_table_puts_ml_prior_and_posterior_side_by_side():
    table = pooling.pooling_rows([record_file(False)])
    assert list(table["parameter"]) == ["kA", "C_veh"]
    row = table.set_index("parameter").loc["C_veh"]
    assert math.isnan(row["ml"]) and row["ml_status"] == "not identified (<= 7.04e+06)"
    assert (row["prior"], row["prior_lo"], row["prior_hi"]) == (6e6, 2e6, 1.8e7)
    assert (row["posterior"], row["posterior_lo"]) == (5.6e6, 4.1e6)
    md = pooling.pooling_markdown(table, "synthetic")
    row = (
        "| Metro3 (order2) | C_veh | not identified (<= 7.04e+06) | 6e+06 [2e+06, 1.8e+07] "
        "| 5.6e+06 [4.1e+06, 7.9e+06] | 1.002 / 1500 / 0 | metro without it (Metro1, Metro2) |"
    )
    assert row in md
    assert "| Metro3 (order2) | kA | 700 [680, 720] (held) |" in md
    untrusted = record_file(True)
    untrusted["diagnostics"].update(r_hat_max=1.05, trusted=False)
    md = pooling.pooling_markdown(pooling.pooling_rows([untrusted]), "synthetic")
    assert "5e+06 [4e+06, 6e+06]" in md and "(not trusted)" in md
    # one chain has no R-hat: said so, never "nan" (before: "| nan / 87 / 1 |")
    one_chain = record_file(True)
    one_chain["diagnostics"].update(r_hat_max=float("nan"), trusted=False)
    md = pooling.pooling_markdown(pooling.pooling_rows([one_chain]), "synthetic")
    assert "nan" not in md and "n/a (one chain) / 1500 / 0" in md
    assert "R-hat <= n/a (one chain)" in pooling.summary_line(one_chain)


def _posterior_file(path, draws):
    import arviz as az

    az.from_dict(posterior={p: v.reshape(2, -1) for p, v in draws.items()}).to_netcdf(str(path))
    return path


def test_predictions_take_the_posteriors_draws_where_a_posterior_is_given(fit_files, tmp_path):
    """simulate and design draw from a fit's posterior when it is read with one: a posterior
    whose every draw has C_veh 1.5 times the fit's collapses the band onto the prediction
    of the fit with that C_veh, and the central run takes the posterior's medians (it stays
    inside its band however far the posterior lies from the estimate); a file without the
    systematic group says its band is statistical only; a posterior of other parameters is
    refused, naming the file."""
    import shutil

    import yaml

    from railtherm.errors import ConfigError
    from railtherm.study import design
    from railtherm.study import simulate as sim
    from railtherm.study.fit import read_fit
    from railtherm.study.scenario import load_scenario

    fit_path, _ = fit_files("Metro2", "order2")
    local = tmp_path / "fit_order2.yaml"
    shutil.copy(fit_path, local)
    fit = read_fit(local)
    theta = {p: float(q.value) for p, q in fit.parameters.items()}
    n = 400
    shifted = {p: np.full(n, theta[p] * (1.5 if p == "C_veh" else 1.0)) for p in theta}
    _posterior_file(tmp_path / "fit_order2.posterior.nc", {p: shifted[p] for p in
                    ("C", "K_veh", "C_veh")})  # fmt: skip
    from pathlib import Path

    repo = Path(__file__).resolve().parents[1]
    scenario = load_scenario(repo / "config" / "scenarios" / "preheat_cold_soak.yaml")
    with_post = sim.simulate(sim.load_parameters(local), scenario, draws=50, seed=1)
    assert "statistical only" in " ".join(sim.load_parameters(local).band_sources)
    edited = yaml.safe_load(local.read_text())
    edited["parameters"]["C_veh"]["value"] = theta["C_veh"] * 1.5
    other = tmp_path / "other" / "fit_order2.yaml"
    other.parent.mkdir()
    other.write_text(yaml.safe_dump(edited, sort_keys=False))
    point = sim.simulate(sim.load_parameters(other), scenario, draws=0).outcomes
    for name in ("heat_up_time_s", "final_T_C"):
        o = with_post.outcomes[name]
        assert o.lo == pytest.approx(point[name].value, rel=1e-9), name
        assert o.hi == pytest.approx(point[name].value, rel=1e-9), name
        assert o.value == pytest.approx(point[name].value, rel=1e-9), name
    prior = design.prior_from_fit(read_fit(local, posterior="auto"), 10, seed=2)
    assert prior.theta["C_veh"] == pytest.approx(1.5 * theta["C_veh"], rel=1e-12)
    assert "draws of its posterior" in prior.source
    draws = design.fit_draws(read_fit(local, posterior="auto"), 30, seed=2)
    np.testing.assert_allclose(draws["C_veh"], theta["C_veh"] * 1.5)
    np.testing.assert_allclose(draws["kA"], theta["kA"])  # held: its value
    _posterior_file(tmp_path / "fit_order2.posterior.nc", {"C_bar": np.ones(n)})
    with pytest.raises(ConfigError, match="fit_order2.posterior.nc"):
        read_fit(local, posterior="auto")
    _posterior_file(tmp_path / "fit_order2.posterior.nc", {"C_veh": np.ones((2, 0))})
    with pytest.raises(ConfigError, match="no draws to predict from.*remove it"):
        read_fit(local, posterior="auto")  # a posterior without draws: no median, no band
    (tmp_path / "fit_order2.posterior.nc").write_text("")  # empty: no traceback, the fix
    with pytest.raises(ConfigError, match="not a posterior InferenceData.*remove it"):
        read_fit(local, posterior="auto")


def test_railtherm_fit_class_prior_fits_with_the_class_of_the_other_vehicles(
    campaign_study, tmp_path, capsys
):
    """`railtherm fit VEHICLE --class-prior`: the study's Table 2 without the vehicle gives
    its second-order fit a class prior (a MAP fit whose file lists the class terms); a
    vehicle whose class cannot be built is refused, naming the file and the reason."""
    import shutil
    from pathlib import Path

    import yaml

    from railtherm.cli import main

    root, _, _ = campaign_study
    repo = Path(__file__).resolve().parents[1]
    work = tmp_path / "study"
    shutil.copytree(root / "config", work / "config")
    (work / "resources").symlink_to(root / "resources")
    (work / "results" / "tables").mkdir(parents=True)
    shutil.copy(repo / "results" / "tables" / "table2.csv", work / "results" / "tables")
    args = ["fit", "config/vehicles/Regio1.yaml", "--model", "order2", "--class-prior",
            "-d", str(work), "--out", "out"]  # fmt: skip
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "Regio1: class prior from its class without it (Regio2, Regio4;" in out
    fit = yaml.safe_load((work / "out" / "vehicles" / "Regio1" / "fit_order2.yaml").read_text())
    assert fit["inference"] == "MAP"
    assert {"class:c_veh", "class:delta", "class:kappa_veh"} <= set(fit["priors"])
    vehicle = yaml.safe_load((work / "config/vehicles/Regio1.yaml").read_text())
    vehicle.pop("surface_m2")
    (work / "config/vehicles/Regio1.yaml").write_text(yaml.safe_dump(vehicle, sort_keys=False))
    assert main(args) != 0
    err = capsys.readouterr().err
    assert "config/vehicles/Regio1.yaml" in err and "surface_m2" in err


def test_a_study_posterior_is_sampled_with_the_class_of_the_others(fit_files, campaign_study):
    """railtherm.study.pooling.study_posterior, what rule posterior runs: Regio1's fit
    files as the rules write them, the class members from the committed Table 2; the prior
    is the regional class without Regio1, the file carries diagnostics, LOO and per
    parameter the ML and posterior intervals, and its summary line says whether to trust it;
    without members the vehicle keeps its own priors."""
    from pathlib import Path

    from railtherm.study import classmodel
    from railtherm.study.fit import read_fit
    from railtherm.study.run import read_stage_inputs

    _, _, study = campaign_study
    fit_path, _ = fit_files("Regio1", "order2")
    base = Path(fit_path).parent
    names = [w["name"] for w in study.vehicles["Regio1"].windows["identification"]]
    tables, kvalue, k_window = read_stage_inputs(
        names, [base / "clean" / f"{n}.csv" for n in names], base / "kvalue.yaml",
        base / "clean" / "kvalue.csv",
    )  # fmt: skip
    repo = Path(__file__).resolve().parents[1]
    members = classmodel.members_from_table2(
        repo / "results" / "tables" / "table2.csv", {k: v.data for k, v in study.vehicles.items()}
    )
    settings = {"chains": 2, "draws": 60, "tune": 60, "seed": 1, "target_accept": 0.9, "loo": True}
    fit = read_fit(fit_path)
    data = study.vehicles["Regio1"].data
    post, record, prior = pooling.study_posterior(
        "Regio1", "order2", data, tables, kvalue, k_window, fit, settings, members
    )
    assert prior.basis == "class" and "Regio1" not in prior.reference.basis
    assert record["prior"]["vehicles"] == prior.reference.basis
    assert record["sampler"]["target_accept"] == 0.9
    assert record["loo"]["draws"] == 120 and record["loo"]["observations"] > 100
    # the simulation error's residuals count as its weight (their colour) says: no scale
    # shared with another model's elpd_loo, and the file says so
    assert record["loo"]["effective_samples"] < record["loo"]["observations"]
    assert record["loo"]["compare"].startswith("none: each residual counts as")
    for p in ("C", "K_veh", "C_veh"):
        lo, hi = record["parameters"][p]["ci95"]
        assert lo < record["parameters"][p]["median"] < hi
    assert pooling.summary_line(record).startswith("Regio1 order2: R-hat <= ")
    _, own, none = pooling.study_posterior(
        "Regio1", "order2", data, tables, kvalue, k_window, fit, {**settings, "loo": False}
    )
    assert none is None and own["prior"] == {"kind": "vehicle"} and "loo" not in own
