"""Priors and maximum a posteriori estimates (railtherm.estimation.priors): the densities
against scipy.stats, the specification's errors, and each estimator's MAP estimate against
an optimisation of the same criterion built here from scipy.stats' densities and scipy's
optimiser (the likelihood from railtherm's public functions, checked against pySIP in
tests/test_kalman.py)."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import optimize, stats
from test_kalman import sde_experiment

from railtherm.estimation import filtering, kalman, models, pem
from railtherm.estimation.priors import KINDS, LogPrior, Prior, PriorError, prior_from_config

S1 = models.STRUCTURES["first_order"]
S2 = models.STRUCTURES["second_order"]
TRUTH1 = {"kA": 900.0, "C_bar": 2.4e7}


def scipy_density(spec):
    """The same prior by scipy.stats (the normal truncated to theta > 0)."""
    kind = spec["kind"]
    if kind == "lognormal":
        return stats.lognorm(s=spec["sd_log"], scale=spec["median"])
    if kind == "normal":
        a = (0.0 - spec["mean"]) / spec["sd"]
        return stats.truncnorm(a, np.inf, loc=spec["mean"], scale=spec["sd"])
    if kind == "gamma":
        return stats.gamma(spec["shape"], scale=spec["scale"])
    if kind == "half_normal":
        return stats.halfnorm(scale=spec["sd"])
    return stats.uniform(loc=spec["lower"], scale=spec["upper"] - spec["lower"])


SPECS = [
    {"kind": "lognormal", "median": 2.0e7, "sd_log": 0.4},
    {"kind": "normal", "mean": 1.0e3, "sd": 300.0},
    {"kind": "normal", "mean": -50.0, "sd": 300.0},
    {"kind": "gamma", "shape": 3.0, "scale": 5.0e6},
    {"kind": "half_normal", "sd": 2.0e3},
    {"kind": "uniform", "lower": 1.0e6, "upper": 5.0e7},
]


@pytest.mark.parametrize("spec", SPECS, ids=lambda s: s["kind"])
@given(u=st.floats(0.02, 0.98))
@settings(max_examples=25, deadline=None)
def test_each_density_is_scipys_with_its_derivatives(spec, u):
    prior = prior_from_config(spec)
    theta = float(scipy_density(spec).ppf(u))
    assert prior.logpdf(theta) == pytest.approx(scipy_density(spec).logpdf(theta), abs=1e-9)
    # the derivatives in v = log theta (what the estimators use) by central differences
    lp = LogPrior(["p"], {"p": prior})
    v = np.array([math.log(theta)])
    h = 1e-5
    for jac in (False, True):
        f0, g, H = lp.evaluate(v, jacobian=jac)
        up, down = lp.evaluate(v + h, jacobian=jac)[0], lp.evaluate(v - h, jacobian=jac)[0]
        if spec["kind"] == "uniform" and not (
            math.log(spec["lower"]) < v[0] - 1e-3 and v[0] + 1e-3 < math.log(spec["upper"])
        ):
            continue
        assert g[0] == pytest.approx((up - down) / (2 * h), rel=1e-6, abs=1e-8)
        g_up, g_down = lp.evaluate(v + h, jacobian=jac)[1], lp.evaluate(v - h, jacobian=jac)[1]
        assert H[0, 0] == pytest.approx((g_up[0] - g_down[0]) / (2 * h), rel=1e-6, abs=1e-8)


def test_outside_its_support_a_prior_has_no_density():
    lp = LogPrior(["C"], {"C": prior_from_config(SPECS[-1])})
    assert lp.evaluate(np.array([math.log(1.0e5)]))[0] == -math.inf
    lo, hi = lp.bounds(np.array([0.0]), np.array([50.0]))
    assert (math.exp(lo[0]), math.exp(hi[0])) == pytest.approx((1.0e6, 5.0e7))


@pytest.mark.parametrize(
    "spec, message",
    [
        ({"kind": "cauchy", "loc": 1.0}, "priors.C.kind: 'cauchy' is not one of"),
        ({"kind": "lognormal", "median": 2.0e7}, "missing sd_log"),
        ({"kind": "lognormal", "median": 2.0e7, "sd_log": 0.3, "mu": 1}, "unknown mu"),
        ({"kind": "lognormal", "median": -1.0, "sd_log": 0.3}, "priors.C.median: -1.0 must be"),
        ({"kind": "gamma", "shape": "two", "scale": 1.0}, "priors.C.shape: 'two' is not a number"),
        ({"kind": "uniform", "lower": 5.0, "upper": 1.0}, "lower 5 must be < upper 1"),
        ({"kind": "half_normal", "sd": float("nan")}, "priors.C.sd: nan must be"),
        ([1, 2], "a prior is a mapping"),
    ],
)
def test_a_wrong_prior_is_refused_naming_its_key_and_value(spec, message):
    with pytest.raises(PriorError, match=None) as err:
        prior_from_config(spec, "priors.C")
    assert message in str(err.value)


@settings(max_examples=60, deadline=None)
@given(
    spec=st.sampled_from(
        [
            ("gamma", (st.floats(0.05, 50.0), st.floats(1e-3, 1e6))),
            ("normal", (st.floats(-1e3, 1e6), st.floats(1e-2, 1e5))),
            ("half_normal", (st.floats(1e-3, 1e6),)),
        ]
    ).flatmap(lambda k: st.tuples(st.just(k[0]), st.tuples(*k[1])))
)
def test_a_priors_median_is_scipys(spec):
    """The median the config check and the MAP's second start use, by scipy.special's
    quantiles (no scipy.stats import), against scipy.stats."""
    kind, args = spec
    dist = {
        "normal": lambda a: stats.truncnorm(-a[0] / a[1], np.inf, a[0], a[1]),
        "gamma": lambda a: stats.gamma(a[0], scale=a[1]),
        "half_normal": lambda a: stats.halfnorm(scale=a[0]),
    }[kind](args)
    assert Prior(kind, args).median() == pytest.approx(float(dist.median()), rel=1e-9)


def test_every_kind_names_its_parameters():
    for kind, names in KINDS.items():
        spec = {"kind": kind, **{n: float(i + 1) for i, n in enumerate(names)}}
        assert prior_from_config(spec).to_dict() == spec


# ----------------------------------------------------------------------------------------------
# the MAP estimates against scipy's optimisation of the same criterion


def first_order_record(n=900, seed=11):
    return sde_experiment(
        theta=TRUTH1, sigma=(2e-3,), meas_var=(0.02,), n=n, seed=seed, structure=S1
    )


def test_kalman_map_is_the_minimum_of_the_likelihood_minus_the_log_prior():
    """The MAP estimate of the first-order model (C_bar with a lognormal prior, the
    measurement variance with a gamma prior) is where scipy's optimiser, started at the
    maximum-likelihood estimate, finds the minimum of NLL (railtherm's public
    negative_log_likelihood) minus scipy.stats' log densities of theta."""
    e = first_order_record()
    spec_c = {"kind": "lognormal", "median": 3.5e7, "sd_log": 0.1}
    spec_s = {"kind": "gamma", "shape": 4.0, "scale": 0.01}
    fixed = {"kA": TRUTH1["kA"]}
    ml = kalman.fit(S1, [e], fixed=fixed)
    mp = kalman.fit(
        S1,
        [e],
        fixed=fixed,
        priors={"C_bar": prior_from_config(spec_c), "s_T": prior_from_config(spec_s)},
    )

    def criterion(w):
        c, sigma, s, x0 = math.exp(w[0]), math.exp(w[1]), math.exp(w[2]), w[3]
        nll = filtering.negative_log_likelihood(
            S1, [e], {"kA": TRUTH1["kA"], "C_bar": c}, {"T": sigma}, {"T": s}, [[x0]]
        )
        return nll - scipy_density(spec_c).logpdf(c) - scipy_density(spec_s).logpdf(s)

    start = [math.log(ml.theta["C_bar"]), math.log(ml.sigma["T"]), math.log(ml.meas_var["T"])]
    ref = optimize.minimize(
        criterion, start + [ml.x0[0][0]], method="Nelder-Mead",
        options={"xatol": 1e-7, "fatol": 1e-10, "maxiter": 20000},
    )  # fmt: skip
    assert ref.success
    ours = [
        math.log(mp.theta["C_bar"]), math.log(mp.sigma["T"]), math.log(mp.meas_var["T"]),
        mp.x0[0][0],
    ]  # fmt: skip
    assert criterion(ours) <= ref.fun + 1e-6
    assert mp.theta["C_bar"] == pytest.approx(math.exp(ref.x[0]), rel=1e-4)
    assert mp.meas_var["T"] == pytest.approx(math.exp(ref.x[2]), rel=1e-3)
    # the prior moved the estimate towards its median, and the file says it is a MAP estimate
    assert ml.theta["C_bar"] < mp.theta["C_bar"] < spec_c["median"]
    written = mp.to_dict()
    assert written["inference"] == "MAP"
    assert written["priors"] == {"C_bar": spec_c, "s_T": spec_s}
    nll = filtering.negative_log_likelihood(
        S1, [e], mp.theta, mp.sigma, mp.meas_var, [mp.x0[0]]
    )  # the file's cost and log-likelihood are the likelihood's, not the posterior's
    assert written["cost"] == pytest.approx(nll, rel=1e-9)
    assert written["loglik"] == pytest.approx(-nll, rel=1e-9)


def test_without_priors_both_estimators_write_a_maximum_likelihood_estimate_as_before():
    e = first_order_record(n=400)
    for fit in (kalman.fit, pem.fit):
        plain = fit(S1, [e], fixed={"kA": TRUTH1["kA"]})
        empty = fit(S1, [e], fixed={"kA": TRUTH1["kA"]}, priors={})
        assert plain.to_dict() == empty.to_dict()
        assert "inference" not in plain.to_dict() and "priors" not in plain.to_dict()


def test_output_error_map_is_the_minimum_of_its_profiled_likelihood_minus_the_log_prior():
    """The output-error MAP estimate (iid covariance: the likelihood's weight is m) is where
    scipy's optimiser finds the minimum of (m/2) log(e^T e) (the residuals from railtherm's
    least-squares problem at given parameters) minus scipy.stats' log density of theta."""
    e = first_order_record(n=600, seed=4)
    spec = {"kind": "normal", "mean": 1.5e7, "sd": 2.0e6}
    fixed = {"kA": TRUTH1["kA"]}
    ml = pem.fit(S1, [e], fixed=fixed, covariance="iid")
    mp = pem.fit(S1, [e], fixed=fixed, covariance="iid", priors={"C_bar": prior_from_config(spec)})
    m = int(np.isfinite(e.y).sum())

    def criterion(w):
        c = math.exp(w[0])
        ssr = pem.fit(S1, [e], fixed={**fixed, "C_bar": c}, covariance="iid").cost
        return 0.5 * m * math.log(ssr) - scipy_density(spec).logpdf(c)

    ref = optimize.minimize_scalar(
        lambda x: criterion([x]), bracket=(math.log(1.2e7), math.log(3e7)), tol=1e-10
    )
    assert mp.theta["C_bar"] == pytest.approx(math.exp(ref.x), rel=1e-4)
    assert criterion([math.log(mp.theta["C_bar"])]) <= ref.fun + 1e-6
    assert spec["mean"] < mp.theta["C_bar"] < ml.theta["C_bar"]
    # the posterior is narrower than the likelihood alone: the prior adds information
    assert mp.sd_log["C_bar"] < ml.sd_log["C_bar"]
    assert mp.to_dict()["inference"] == "MAP"


# ----------------------------------------------------------------------------------------------
# model.priors in a vehicle file


def test_a_vehicle_files_priors_reach_its_fit_which_says_it_is_a_map_estimate(tmp_path):
    """Armadillo (the box of validation/) with a tight lognormal prior on C_veh: the fit
    file names the prior and the MAP inference, its C_veh lies between the
    maximum-likelihood value and the prior's median, and the interval is narrower."""
    from test_model_settings import fit_of, vehicle_file

    model = {"orders": [2], "structures": []}
    ml = fit_of(tmp_path, vehicle_file(tmp_path, model), 2)
    c_ml = ml["parameters"]["C_veh"]["value"]
    spec = {"kind": "lognormal", "median": 3.0 * c_ml, "sd_log": 0.2}
    mp = fit_of(tmp_path, vehicle_file(tmp_path, {**model, "priors": {"C_veh": spec}}), 2)
    assert "inference" not in ml
    assert mp["inference"] == "MAP" and mp["priors"] == {"C_veh": spec}
    c_map = mp["parameters"]["C_veh"]["value"]
    assert c_ml < c_map < 3.0 * c_ml

    def width(fit):
        lo, hi = fit["parameters"]["C_veh"]["ci95"]
        return math.log(hi / lo)

    assert width(mp) < width(ml)


@pytest.mark.bad_input
@pytest.mark.parametrize(
    "priors, key, says",
    [
        ({"C_veh": {"kind": "lognormal", "median": 1e6}}, "model.priors.C_veh", "missing sd_log"),
        ({"C_veh": {"kind": "beta", "a": 1.0}}, "model.priors.C_veh", "kind"),
        ({"C": {"kind": "normal", "mean": 1e6, "sd": -2.0}}, "model.priors.C.sd", "> 0"),
        ({"C_vehicle": {"kind": "half_normal", "sd": 1e6}}, "model.priors", "C_vehicle"),
        (  # a misspelt noise parameter was accepted, and its prior never used
            {"sigma_Foo": {"kind": "half_normal", "sd": 0.01}},
            "model.priors.sigma_Foo",
            "no such noise parameter: sigma_<state> (a state's diffusion)",
        ),
        # before, each passed validate and then crashed or never ended in the fit: a uniform
        # range below the search bounds (least_squares: lower bound not below upper), a gamma
        # whose median underflows (math domain error), a normal and a half-normal whose mass
        # lies far below the bounds (the profile-likelihood limits walked on for minutes)
        (
            {"C": {"kind": "uniform", "lower": 1.0e3, "upper": 2.0e3}},
            "model.priors.C",
            "outside the search bounds [10000, 1e+10]",
        ),
        (
            {"K_veh": {"kind": "gamma", "shape": 1e-9, "scale": 1e-9}},
            "model.priors.K_veh",
            "median 0 is no positive number",
        ),
        (
            {"C_veh": {"kind": "normal", "mean": -1.0e7, "sd": 1.0e3}},
            "model.priors.C_veh",
            "median 0.06931 lies outside the search bounds",
        ),
        (
            {"C": {"kind": "half_normal", "sd": 1.0e-30}},
            "model.priors.C",
            "lies outside the search bounds",
        ),
    ],
)
def test_a_wrong_prior_in_a_vehicle_file_is_refused_by_load_and_validate(
    tmp_path, priors, key, says
):
    from test_model_settings import vehicle_file

    from railtherm.errors import ConfigError

    with pytest.raises(ConfigError) as err:
        vehicle_file(tmp_path, {"orders": [2], "structures": [], "priors": priors})
    assert key in str(err.value) and says in str(err.value)


def test_a_vehicles_prior_replaces_the_study_defaults_prior_of_its_parameter(tmp_path):
    from test_model_settings import vehicle_file

    defaults = {
        "model": {
            "priors": {
                "C_veh": {"kind": "lognormal", "median": 2.0e7, "sd_log": 0.5},
                "C": {"kind": "half_normal", "sd": 1.0e7},
            }
        }
    }
    own = {"C_veh": {"kind": "normal", "mean": 1.0e7, "sd": 3.0e6}}
    vehicle = vehicle_file(tmp_path, {"priors": own}, defaults=defaults)
    assert vehicle.model["priors"] == {**defaults["model"]["priors"], **own}


# ----------------------------------------------------------------------------------------------
# the class as a prior


def metro_class(mass=35_000.0, surface=240.0):
    """A class reference model of four made-up metro vehicles (ClassMember values)."""
    from railtherm.study.classmodel import ClassMember, build

    values = {  # k, c_veh, delta, kappa_veh
        "A": (2.6, 300.0, 1.1, 1.0),
        "B": (3.0, 420.0, 1.6, 1.8),
        "C": (2.8, 360.0, 0.9, 1.3),
        "D": (3.3, 510.0, 1.9, 2.4),
    }
    members = [
        ClassMember(vid, "metro", 30_000.0, 230.0, k, c, d, kap, True, "")
        for vid, (k, c, d, kap) in values.items()
    ]
    return build(members, "metro", mass, surface)


def test_the_class_terms_are_the_distribution_the_class_model_draws():
    """Each term of the class prior is the predictive t of its generalised parameter: the
    reference model's own draws of log C_veh - log m, log C_veh - log C and log K_veh - log A
    follow scipy's t with the term's centre, scale and degrees of freedom (Kolmogorov-Smirnov),
    and the terms' summed log density differs from scipy's t log densities by a constant."""
    reference = metro_class()
    terms = {t.name: t for t in reference.prior_terms()}
    assert set(terms) == {"class:c_veh", "class:delta", "class:kappa_veh", "class:k"}
    draws = reference.draws(20_000, seed=3)
    logs = {p: np.log(v) for p, v in draws.items()}
    m, A = math.log(reference.mass_kg), math.log(reference.surface_m2)
    combos = {
        "class:c_veh": logs["C_veh"] - m,
        "class:delta": logs["C_veh"] - logs["C"],
        "class:kappa_veh": logs["K_veh"] - A,
        "class:k": logs["kA"] - A,
    }
    for name, g in combos.items():
        t = terms[name]
        assert stats.kstest(g, stats.t(t.dof, t.centre_log, t.scale).cdf).pvalue > 1e-3, name
    free = ("kA", "C", "K_veh", "C_veh")
    prior = LogPrior(free, {}, reference.prior_terms())
    rng = np.random.default_rng(0)
    points = np.log([[reference.theta[p] for p in free]]) + 0.5 * rng.standard_normal((5, 4))
    ours = [prior.evaluate(v, jacobian=True)[0] for v in points]
    theirs = []
    for v in points:
        g = {"class:c_veh": v[3] - m, "class:delta": v[3] - v[1],
             "class:kappa_veh": v[2] - A, "class:k": v[0] - A}  # fmt: skip
        theirs.append(
            sum(stats.t(t.dof, t.centre_log, t.scale).logpdf(g[n]) for n, t in terms.items())
        )
    assert np.ptp(np.array(ours) - np.array(theirs)) < 1e-9
    # the gradient and Hessian by central differences
    v = points[1]
    f, grad, H = prior.evaluate(v)
    h = 1e-6
    for i in range(4):
        e = np.zeros(4)
        e[i] = h
        up, down = prior.evaluate(v + e), prior.evaluate(v - e)
        assert grad[i] == pytest.approx((up[0] - down[0]) / (2 * h), rel=1e-6, abs=1e-7)
        np.testing.assert_allclose(H[:, i], (up[1] - down[1]) / (2 * h), rtol=1e-5, atol=1e-6)
    # the prior's centre is the class model's point values
    centre = prior.centre(np.zeros(4))
    np.testing.assert_allclose(np.exp(centre), [reference.theta[p] for p in free], rtol=1e-12)


def test_a_class_prior_helps_where_a_record_says_little_and_leaves_a_clear_record_alone():
    """Short records of the air temperature alone (400 one-minute rows, the body
    unmeasured, 0.2 K noise) of vehicles whose parameters lie within the class's spread:
    by maximum likelihood C_veh is known to 10-15 %; with the class as the prior the MAP
    estimate is closer to the truth in the median over eight records. A record that
    determines the parameters (twice as long) keeps its estimate: the prior moves each by
    less than its own standard deviation."""
    reference = metro_class()
    terms = reference.prior_terms()
    fixed = {"kA": reference.theta["kA"]}
    errors = {"ml": [], "map": []}
    for seed in range(8):
        truth = {**fixed, "C": 8.0e6, "K_veh": 800.0, "C_veh": 1.2e7}
        e = sde_experiment(theta=truth, sigma=(0.0, 0.0), meas_var=(0.04, 0.04), n=400, seed=seed)
        ml = pem.fit(S2, [e], fixed=fixed, outputs=("T",))
        mp = pem.fit(S2, [e], fixed=fixed, outputs=("T",), prior_terms=terms)
        assert mp.success and mp.to_dict()["priors"]["class:delta"]["kind"] == "student_t_log"
        errors["ml"].append(abs(math.log(ml.theta["C_veh"] / truth["C_veh"])))
        errors["map"].append(abs(math.log(mp.theta["C_veh"] / truth["C_veh"])))
    assert np.median(errors["map"]) < 0.8 * np.median(errors["ml"])
    e = sde_experiment(theta=truth, sigma=(0.0, 0.0), meas_var=(0.04, 0.04), n=800, seed=2)
    ml = pem.fit(S2, [e], fixed=fixed, outputs=("T",))
    mp = pem.fit(S2, [e], fixed=fixed, outputs=("T",), prior_terms=terms)
    for p in ("C", "K_veh", "C_veh"):
        assert abs(math.log(mp.theta[p] / ml.theta[p])) < ml.sd_log[p], p


def test_a_map_fit_says_so_where_it_is_printed(fit_files):
    """`railtherm fit` prints each fit's summary: a MAP estimate names itself and the
    parameters its priors are on (before, only the fit file said so)."""
    from dataclasses import replace

    from railtherm.study.fit import read_fit

    fit = read_fit(fit_files("Metro2", "order2")[0])
    assert "MAP" not in fit.summary().splitlines()[0]
    priors = {"inference": "MAP", "priors": {"C_veh": {}, "K_veh": {}}}
    first = replace(fit, content={**fit.content, **priors}).summary().splitlines()[0]
    assert "MAP with priors on C_veh, K_veh" in first, first
    kalman = read_fit(fit_files("Metro2", "order2_kalman")[0])  # its keys in section fit
    section = {**kalman.section("fit"), **priors}
    first = replace(kalman, content={**kalman.content, "fit": section}).summary().splitlines()[0]
    assert "MAP with priors on C_veh, K_veh" in first, first


def test_a_map_estimate_at_the_end_of_its_uniform_prior_sits_at_a_bound(tmp_path):
    """A uniform prior that excludes the maximum-likelihood value: the MAP estimate sits at
    the prior's end, which is flagged as a bound (not identified: the optimum may lie
    beyond it); before, it was an estimate with an interval reaching outside the prior."""
    from test_model_settings import fit_of, vehicle_file

    model = {"orders": [2], "structures": []}
    ml = fit_of(tmp_path, vehicle_file(tmp_path, model), 2)
    c_ml = ml["parameters"]["C_veh"]["value"]
    spec = {"kind": "uniform", "lower": 2.0 * c_ml, "upper": 3.0 * c_ml}
    mp = fit_of(tmp_path, vehicle_file(tmp_path, {**model, "priors": {"C_veh": spec}}), 2)
    entry = mp["parameters"]["C_veh"]
    assert entry["value"] == pytest.approx(2.0 * c_ml, rel=1e-3)
    assert entry["identified"] is False and "lower" in entry["reason"], entry
