"""Posterior sampling (railtherm.estimation.sampling): NUTS draws against the posterior
computed on a grid from railtherm's public likelihood and scipy.stats' prior density, and
the InferenceData written and read back."""

import math

import arviz as az
import numpy as np
import pytest
from scipy import stats
from test_kalman import sde_experiment

from railtherm.estimation import filtering, models, sampling
from railtherm.estimation.priors import Prior

S1 = models.STRUCTURES["first_order"]
TRUTH = {"kA": 900.0, "C_bar": 2.4e7}
NOISE = {"sigma": {"T": 2e-3}, "meas_var": {"T": 0.02}}


@pytest.fixture(scope="module")
def record():
    return sde_experiment(theta=TRUTH, sigma=(2e-3,), meas_var=(0.02,), n=300, seed=8, structure=S1)


@pytest.fixture(scope="module")
def posterior(record):
    """kA and C_bar free (C_bar with a lognormal prior, kA without: flat in log kA), the
    noise given, the initial state from the first reading: a two-dimensional posterior."""
    return sampling.sample(
        S1,
        [record],
        x0="measured",
        fixed={"sigma_T": NOISE["sigma"]["T"], "s_T": NOISE["meas_var"]["T"]},
        priors={"C_bar": Prior("lognormal", (2.0e7, 0.3))},
        chains=2,
        draws=1000,
        tune=600,
        seed=3,
    )


def grid_posterior(record, n=101, half_width=7.0, centre=None, sd=None):
    """The posterior density of (log kA, log C_bar) on a grid of +- half_width sd: the
    filter's likelihood (railtherm.estimation.filtering.negative_log_likelihood, public)
    times scipy.stats' lognormal density of C_bar times C_bar (the density of log C_bar);
    flat in log kA."""
    axes = [
        np.linspace(c - half_width * s, c + half_width * s, n)
        for c, s in zip(centre, sd, strict=True)
    ]
    prior = stats.lognorm(s=0.3, scale=2.0e7)
    logp = np.empty((n, n))
    for i, a in enumerate(axes[0]):
        for j, b in enumerate(axes[1]):
            theta = {"kA": math.exp(a), "C_bar": math.exp(b)}
            nll = filtering.negative_log_likelihood(
                S1, [record], theta, NOISE["sigma"], NOISE["meas_var"], [[math.nan]],
                x0_mode="measured",
            )  # fmt: skip
            logp[i, j] = -nll + prior.logpdf(theta["C_bar"]) + b
    w = np.exp(logp - logp.max())
    return axes, w / w.sum()


def marginal_quantiles(axis, weights, q):
    cdf = np.cumsum(weights) - weights / 2.0  # each node's mass centred on it
    return np.interp(q, cdf, axis)


def test_nuts_draws_are_the_posterior_computed_on_a_grid(record, posterior):
    summary = posterior.summary()
    assert (summary["r_hat"] < 1.01).all(), summary
    assert (summary["ess_bulk"] > 400).all(), summary
    assert posterior.divergences() == 0
    draws = {p: np.log(posterior.idata.posterior[p].values.ravel()) for p in ("kA", "C_bar")}
    centre = [float(np.mean(draws[p])) for p in ("kA", "C_bar")]
    sd = [float(np.std(draws[p])) for p in ("kA", "C_bar")]
    axes, w = grid_posterior(record, centre=centre, sd=sd)
    marginals = {"kA": w.sum(axis=1), "C_bar": w.sum(axis=0)}
    for k, p in enumerate(("kA", "C_bar")):
        grid_mean = float(axes[k] @ marginals[p])
        grid_sd = math.sqrt(float((axes[k] - grid_mean) ** 2 @ marginals[p]))
        assert np.mean(draws[p]) == pytest.approx(grid_mean, abs=0.1 * grid_sd), p
        assert np.std(draws[p]) == pytest.approx(grid_sd, rel=0.1), p
        q = [0.025, 0.5, 0.975]
        ours = np.quantile(draws[p], q)
        theirs = marginal_quantiles(axes[k], marginals[p], q)
        np.testing.assert_allclose(ours, theirs, atol=0.2 * grid_sd, err_msg=p)
    # the chains started at the fit's MAP estimate, which lies inside the posterior's bulk
    lo, hi = np.quantile(draws["C_bar"], [0.025, 0.975])
    assert lo < math.log(posterior.estimate.theta["C_bar"]) < hi


def test_the_posterior_is_written_as_netcdf_and_read_back(posterior, tmp_path):
    path = tmp_path / "posterior.nc"
    posterior.write(str(path))
    back = az.from_netcdf(path)
    for p in ("kA", "C_bar"):
        np.testing.assert_array_equal(back.posterior[p].values, posterior.idata.posterior[p].values)
    assert back.attrs["structure"] == "first_order"
    assert back.attrs["target"].startswith("railtherm's Kalman-filter likelihood")


def test_output_error_draws_are_its_posterior_computed_on_a_grid():
    """The simulation error's posterior (iid residuals: the likelihood's weight is m) of kA
    and C_bar, C_bar with a lognormal prior: NUTS draws against the grid of
    -(m/2) ln(e^T e) + ln p(C_bar) + ln C_bar, e^T e by an independent recursion
    (tests/test_profile.py)."""
    from test_profile import record as oe_record
    from test_profile import simulate

    e = oe_record(1.6e7, n=120, seed=4, sd=0.2)
    prior = stats.lognorm(s=0.3, scale=2.0e7)
    post = sampling.sample(
        S1, [e], estimator="output_error", covariance="iid", x0="measured",
        priors={"C_bar": Prior("lognormal", (2.0e7, 0.3))}, chains=2, draws=1000, tune=600,
        seed=5,
    )  # fmt: skip
    assert (post.summary()["r_hat"] < 1.01).all() and post.divergences() == 0
    assert post.idata.attrs["target"].startswith("railtherm's simulation-error likelihood")
    draws = {p: np.log(post.idata.posterior[p].values.ravel()) for p in ("kA", "C_bar")}
    y = e.y[:, 0]
    m = len(y) - 1
    n = 121
    axes = [np.linspace(np.mean(d) - 7 * np.std(d), np.mean(d) + 7 * np.std(d), n)
            for d in draws.values()]  # fmt: skip
    logp = np.empty((n, n))
    for i, a in enumerate(axes[0]):
        for j, b in enumerate(axes[1]):
            sse = float(np.sum((simulate(math.exp(a), math.exp(b), e.u, y[0])[1:] - y[1:]) ** 2))
            logp[i, j] = -0.5 * m * math.log(sse) + prior.logpdf(math.exp(b)) + b
    w = np.exp(logp - logp.max())
    w /= w.sum()
    for k, (p, marginal) in enumerate(zip(("kA", "C_bar"), (w.sum(1), w.sum(0)), strict=True)):
        mean = float(axes[k] @ marginal)
        sd = math.sqrt(float((axes[k] - mean) ** 2 @ marginal))
        assert np.mean(draws[p]) == pytest.approx(mean, abs=0.1 * sd), p
        assert np.std(draws[p]) == pytest.approx(sd, rel=0.1), p


def test_railtherm_fit_posterior_prints_its_summary_and_writes_the_inference_data(
    tmp_path, monkeypatch, capsys
):
    """`railtherm fit VEHICLE --posterior` on the Armadillo box (its Kalman fit): the summary
    with R-hat and bulk ESS per unknown, the InferenceData beside the fit file."""
    from pathlib import Path

    from railtherm.cli import main

    repo = Path(__file__).resolve().parents[1]
    monkeypatch.chdir(repo / "validation")
    code = main(
        ["fit", "config/vehicles/Armadillo.yaml", "--model", "interior_envelope_kalman",
         "--posterior", "--chains", "2", "--draws", "200", "--tune", "200", "--seed", "2",
         "--target-accept", "0.9", "--loo", "--out", str(tmp_path)]
    )  # fmt: skip
    assert code == 0
    out = capsys.readouterr().out
    assert "(2 chains x 200 draws after 200 tuning, seed 2, target acceptance 0.9;" in out
    for name in ("C ", "K_i", "C_e", "K_o", "r_hat", "ess_bulk", "PSIS-LOO: ", "elpd_loo "):
        assert name in out
    path = tmp_path / "vehicles" / "Armadillo" / "fit_interior_envelope_kalman.posterior.nc"
    assert f"written to {path}" in out
    back = az.from_netcdf(path)
    assert back.posterior["K_o"].shape == (2, 200)
    assert (tmp_path / "vehicles" / "Armadillo" / "fit_interior_envelope_kalman.yaml").is_file()
    png = path.with_suffix(".png")
    assert f"pair plot: {png}" in out and png.stat().st_size > 10_000


def test_the_systematic_budget_is_mixed_into_the_draws_as_the_gum_adds_it():
    """Two parameters with independent log-normal posteriors (sd 0.02, 0.01) and two type-B
    sources moving them (effects 0.03 and -0.01 on a, 0.04 on b) plus a held parameter c:
    the mixed draws' log sd is the root sum of squares (GUM), their correlation the shared
    sources' (0.03 * 0.04 / (sd_a sd_b)), their medians the posterior's; the posterior itself
    is left as it was."""
    rng = np.random.default_rng(1)
    log_a = math.log(5.0) + 0.02 * rng.standard_normal((4, 5000))
    log_b = math.log(2e6) + 0.01 * rng.standard_normal((4, 5000))
    idata = az.from_dict(posterior={"a": np.exp(log_a), "b": np.exp(log_b)})
    post = sampling.Posterior(idata, ("a", "b"), estimate=None, seconds=0.0)
    effects = {
        "a": {"power": 0.03, "offset": -0.01},
        "b": {"power": 0.04},
        "c": {"offset": 0.05},
    }
    post.add_systematic(effects, {"c": 700.0}, seed=3)
    mixed = post.idata.posterior_systematic
    sd_a, sd_b = math.hypot(0.02, 0.03, 0.01), math.hypot(0.01, 0.04)
    la, lb, lc = (np.log(mixed[p].values.ravel()) for p in ("a", "b", "c"))
    assert np.std(la) == pytest.approx(sd_a, rel=0.03)
    assert np.std(lb) == pytest.approx(sd_b, rel=0.03)
    assert np.std(lc) == pytest.approx(0.05, rel=0.03)
    assert np.median(lc) == pytest.approx(math.log(700.0), abs=0.003)
    assert np.corrcoef(la, lb)[0, 1] == pytest.approx(0.03 * 0.04 / (sd_a * sd_b), abs=0.03)
    np.testing.assert_array_equal(post.idata.posterior["a"].values, np.exp(log_a))
    table = post.intervals()
    assert table.loc["a", "with_systematic_hi"] > table.loc["a", "statistical_hi"]
    assert math.isnan(table.loc["c", "statistical_lo"])


def test_psis_loo_is_the_leave_one_out_density_by_quadrature(record, posterior):
    """ArviZ's PSIS-LOO over railtherm's pointwise terms (each row's one-step-ahead term of
    the filter, which add up to the public likelihood) against the exact leave-one-out
    predictive density by quadrature on a grid: sum_i log [int p(y|t) p(t) dt /
    int p(y|t) p(t) / p(y_i|t) dt]."""
    from scipy.special import logsumexp

    loo = posterior.loo(max_draws=200)
    assert loo["observations"] == len(record.y) - 1 and loo["pareto_k_above_0.7"] == 0
    assert loo["effective_samples"] == loo["observations"]  # a filter's rows count fully
    assert loo["compare"] == sampling.LOO_COMPARE["kalman"]
    density = posterior.density
    nll = filtering.negative_log_likelihood(
        S1, [record], {"kA": 900.0, "C_bar": 2.4e7}, NOISE["sigma"], NOISE["meas_var"],
        [[math.nan]], x0_mode="measured",
    )  # fmt: skip
    assert density.pointwise(np.log([900.0, 2.4e7])).sum() == pytest.approx(-nll, rel=1e-10)
    draws = {p: np.log(posterior.idata.posterior[p].values.ravel()) for p in ("kA", "C_bar")}
    axes = [np.linspace(d.mean() - 6 * d.std(), d.mean() + 6 * d.std(), 21) for d in draws.values()]
    prior = stats.lognorm(s=0.3, scale=2.0e7)
    terms, log_w = [], []
    for a in axes[0]:
        for b in axes[1]:
            pw = density.pointwise(np.array([a, b]))
            terms.append(pw)
            log_w.append(pw.sum() + prior.logpdf(math.exp(b)) + b)
    terms, log_w = np.array(terms), np.array(log_w)
    exact = float(np.sum(logsumexp(log_w) - logsumexp(log_w[:, None] - terms, axis=0)))
    assert loo["elpd_loo"] == pytest.approx(exact, abs=0.2)


@pytest.mark.parametrize("unknowns", [["C_bar", "x0_T[sequence]"], ["C_bar"]])
def test_a_first_order_posterior_with_kA_held_still_gets_its_figure(unknowns, tmp_path):
    """One structural parameter (C_bar; kA held by the static test): the pair plot takes the
    initial states with it, or draws the one marginal - never an error."""
    from types import SimpleNamespace

    from railtherm.study import posterior as study_posterior

    rng = np.random.default_rng(0)
    idata = az.from_dict(posterior={v: rng.lognormal(size=(2, 50)) for v in unknowns})
    post = sampling.Posterior(idata, tuple(unknowns), SimpleNamespace(free=("C_bar",)), 0.0)
    path = study_posterior.pair_plot(post, str(tmp_path / "pair.png"))
    assert (tmp_path / "pair.png").stat().st_size > 5_000 and path.endswith("pair.png")


@pytest.mark.bad_input
@pytest.mark.parametrize(
    ("option", "value", "message"),
    [
        ("--chains", "0", "--chains: key 'chains' = 0: expected 1 or more"),
        ("--draws", "0", "--draws: key 'draws' = 0: expected 1 or more"),
        ("--tune", "-1", "--tune: key 'tune' = -1: expected 0 or more"),
        ("--target-accept", "1.0", "--target-accept: key 'target_accept' = 1.0: expected"),
        # before: nutpie's OverflowError after the fit had run
        ("--seed", "-1", "--seed: key 'seed' = -1: expected 0 to 2^64 - 1"),
        ("--seed", str(2**64), f"--seed: key 'seed' = {2**64}: expected 0 to 2^64 - 1"),
    ],
)
def test_railtherm_fit_refuses_a_bad_sampler_setting_before_fitting(
    tmp_path, monkeypatch, capsys, option, value, message
):
    """A sampler setting out of its range stops `railtherm fit --posterior` at once, naming
    the option and the value, with nothing fitted or written."""
    from pathlib import Path

    from railtherm.cli import main

    monkeypatch.chdir(Path(__file__).resolve().parents[1] / "validation")
    code = main(
        ["fit", "config/vehicles/Armadillo.yaml", "--model", "order1", "--posterior",
         option, value, "--out", str(tmp_path)]
    )  # fmt: skip
    assert code == 1
    captured = capsys.readouterr()
    assert captured.err.startswith(message) and captured.out == ""
    assert not any(tmp_path.iterdir())


def test_the_target_acceptance_defaults_agree_in_the_library_the_cli_and_the_study_schema():
    """One default for NUTS's target acceptance wherever a user can leave it out."""
    from pathlib import Path

    import yaml

    from railtherm.cli import build_parser

    schema = yaml.safe_load(
        (Path(sampling.__file__).parents[1] / "schemas" / "study.schema.yaml").read_text()
    )
    default = schema["properties"]["posterior"]["properties"]["target_accept"]["default"]
    args = build_parser().parse_args(["fit", "vehicle.yaml", "--posterior"])
    assert default == args.target_accept == sampling.TARGET_ACCEPT


def test_the_loo_line_says_first_when_its_estimate_is_unreliable():
    """Every Pareto k above 0.7 (a Kalman model with 20 draws: 6,481 of them) printed the
    elpd as if it held; the line now opens with what is unreliable."""
    from railtherm.cli import loo_line

    loo = {"elpd_loo": 23709.7, "se": 95.0, "p_loo": 12.0, "observations": 6481, "draws": 20}
    loo |= {"pareto_k_max": math.inf, "pareto_k_above_0.7": 6481, "compare": "none"}
    assert loo_line(loo).startswith("PSIS-LOO: unreliable: 6481 of 6481 observations")
    loo |= {"pareto_k_max": 0.4, "pareto_k_above_0.7": 0}
    assert loo_line(loo).startswith("PSIS-LOO: elpd_loo 23709.7 ± 95")
