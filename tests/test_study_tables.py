"""railtherm.study.aggregate: the study's Tables 1-3, class statistics and class test (section
6)."""

import math

import numpy as np
import pandas as pd
import pytest

from railtherm.estimation import pem
from railtherm.records import FitRecord
from railtherm.report import tableformat
from railtherm.study import aggregate, smallsample


def fit_content(
    C,
    K_veh,
    C_veh,
    *,
    sd=(0.1, 0.2, 0.1),
    corr=-0.5,
    effects=None,
    verdict=None,
    kA=None,
    r2=0.99,
    pinned=None,
):
    """The content of a fit_order2.yaml; sd_log for (C, K_veh, C_veh), corr of C and C_veh;
    ``pinned``: {parameter: ("lower" | "upper", bound)} for estimates at a bound."""
    free = ["C", "K_veh", "C_veh"]
    R = np.eye(3)
    R[0, 2] = R[2, 0] = corr
    params = {"kA": {"value": 1000.0 if kA is None else kA, "estimated": kA is not None}}
    if kA is not None:
        params["kA"]["ci95"] = [0.9 * kA, 1.1 * kA]
        free = ["kA", *free]
        R = np.pad(R, ((1, 0), (1, 0)))
        R[0, 0] = 1.0
    for p, v, s in zip(("C", "K_veh", "C_veh"), (C, K_veh, C_veh), sd, strict=True):
        params[p] = {
            "value": v,
            "estimated": True,
            "sd_log": s,
            "ci95": [v * math.exp(-1.96 * s), v * math.exp(1.96 * s)],
        }
        params[p] |= pem.identification(v, params[p]["ci95"], (pinned or {}).get(p))
    return {
        "vehicle": "x",
        "order": 2,
        "k_source": "joint estimation (PEM)" if kA is not None else "static test (eq. 10)",
        "verdict": verdict or aggregate.ACCEPTABLE,
        "R2": r2,
        "parameters": params,
        "free": free,
        "correlation": R.tolist(),
        "systematic": {"effects_log": effects or {}},
    }


def fit(*args, **kwargs) -> FitRecord:
    """The record of :func:`fit_content`'s fit file."""
    return FitRecord.from_dict(fit_content(*args, **kwargs))


def vehicle(cls, mass=30_000.0, A=300.0, windows=1, synthetic=True):
    return {
        "class": cls,
        "mass_kg": mass,
        "surface_m2": A,
        "synthetic": synthetic,
        "windows": {"identification": [{"name": f"w{i}"} for i in range(windows)]},
    }


def kv(k, u_k=0.05, usable=True):
    return {"k": k, "u_k": u_k, "usable": usable}


def test_table2_k_from_static_test_or_joint_estimate_and_rows_by_class():
    vehicles = {"B": vehicle("metro"), "A": vehicle("tram", A=250.0), "D": vehicle("metro")}
    fits = {"A": fit(1e7, 500, 2e7, kA=750.0), "B": fit(9e6, 200, 1e7), "D": fit(9e6, 200, 1e7)}
    t2 = aggregate.table2(fits, {"A": None, "B": kv(2.8, 0.05), "D": kv(2.8)}, vehicles)
    # by class in the paper's order, the config's order within a class: a vehicle added at
    # the end of the config (D) lands among its class
    assert list(t2["vehicle"]) == ["A", "B", "D"]
    a, b = t2.iloc[0], t2.iloc[1]
    assert (b["k"], b["k_lo"], b["k_hi"]) == pytest.approx((2.8, 2.7, 2.9))  # k +- 2 u(k)
    assert (a["k"], a["k_lo"], a["k_hi"]) == pytest.approx((3.0, 2.7, 3.3))  # kA / A
    assert a["k_source"] == "joint estimation (PEM)"
    assert b["source"] == aggregate.SYNTHETIC_SOURCE


def test_table3_eq_24_and_25_with_correlated_interval_of_delta():
    f = fit(1e7, 500, 2e7, sd=(0.1, 0.2, 0.1), corr=-0.5)
    vehicles = {"A": vehicle("metro", mass=40_000.0)}
    t2 = aggregate.table2({"A": f}, {"A": kv(2.0)}, vehicles)
    r = aggregate.table3(t2, {"A": f}, vehicles).iloc[0]
    assert r["c_veh"] == pytest.approx(2e7 / 40_000.0)
    assert r["c_veh_lo"] == pytest.approx(2e7 * math.exp(-1.96 * 0.1) / 40_000.0)
    assert r["delta"] == pytest.approx(2.0)
    sd = math.sqrt(0.1**2 + 0.1**2 + 2 * 0.5 * 0.1 * 0.1)  # var(a - b) with corr -0.5
    assert r["delta_hi"] == pytest.approx(2.0 * math.exp(aggregate.Z95 * sd))
    assert r["delta_lo"] == pytest.approx(2.0 * math.exp(-aggregate.Z95 * sd))


def test_a_systematic_error_moving_both_capacities_alike_does_not_widen_delta():
    same = {"C": {"scale_Q_H": 0.3}, "C_veh": {"scale_Q_H": 0.3}}
    opposite = {"C": {"scale_Q_H": 0.3}, "C_veh": {"scale_Q_H": -0.3}}
    vehicles = {"A": vehicle("metro")}
    widths = []
    for effects in (None, same, opposite):
        f = fit(1e7, 500, 2e7, corr=0.0, effects=effects)
        t2 = aggregate.table2({"A": f}, {"A": kv(2.0)}, vehicles)
        r = aggregate.table3(t2, {"A": f}, vehicles).iloc[0]
        widths.append(math.log(r["delta_hi"] / r["delta_lo"]))
    assert widths[1] == pytest.approx(widths[0])
    assert widths[2] > 2 * widths[0]


def test_table1_counts_per_class_and_sum():
    vehicles = {
        "T1": vehicle("tram", windows=2),
        "M1": vehicle("metro"),
        "M2": vehicle("metro"),
    }
    fits = {
        "T1": fit(1e7, 500, 2e7),
        "M1": fit(1e7, 500, 2e7, verdict="assumptions in doubt"),
        "M2": fit(1e7, 500, 2e7),
    }
    kvalues = {"T1": kv(3.0), "M1": kv(2.0, usable=False), "M2": None}
    t1 = aggregate.table1(vehicles, kvalues, fits).set_index("quantity")
    assert list(t1.columns) == ["Tram", "Metro", "Sum"]
    assert t1.loc["vehicles with a k value measured"].tolist() == [1, 1, 2]
    assert t1.loc["k value usable (steady window)"].tolist() == [1, 0, 1]
    assert t1.loc["identification windows fitted"].tolist() == [2, 2, 4]
    assert t1.loc["vehicles with C, K_veh, C_veh identified"].tolist() == [1, 2, 3]
    assert t1.loc["vehicles evaluated (fit acceptable)"].tolist() == [1, 1, 2]


def table3_frame(values):
    rows = []
    for cls, xs in values.items():
        for i, x in enumerate(xs):
            rows.append(
                {
                    "vehicle": f"{cls}{i}",
                    "class": cls,
                    "c_veh": x,
                    "c_veh_status": aggregate.ESTIMATED,
                    "delta": x / 100.0,
                    "delta_status": aggregate.ESTIMATED,
                    "verdict": aggregate.ACCEPTABLE if i < 3 else "assumptions in doubt",
                }
            )
    return pd.DataFrame(rows)


def test_class_summary_t_intervals_and_geometric_mean_of_delta():
    t3 = table3_frame({"tram": [270.0, 330.0], "metro": [300.0, 350.0, 400.0, 700.0]})
    cs = aggregate.class_summary(t3)
    allv = cs[cs["selection"] == "every identified value"].set_index(["class", "quantity"])
    metro = allv.loc[("metro", "c_veh")]
    assert metro["n"] == 4 and metro["mean"] == pytest.approx(437.5)
    assert metro["median"] == pytest.approx(375.0)
    # t interval, 3 degrees of freedom: 437.5 +- 3.182 * sd / 2
    half = 3.182446305284263 * np.std([300, 350, 400, 700], ddof=1) / 2.0
    assert (metro["mean_ci_lo"], metro["mean_ci_hi"]) == pytest.approx((437.5 - half, 437.5 + half))
    tram = allv.loc[("tram", "c_veh")]  # n = 2: a t interval with 1 degree of freedom, wide
    half = 12.706204736174698 * np.std([270.0, 330.0], ddof=1) / math.sqrt(2)
    assert tram["mean_ci_hi"] == pytest.approx(300.0 + half)
    delta = allv.loc[("metro", "delta")]
    logs = np.log([3.0, 3.5, 4.0, 7.0])
    assert delta["geometric_mean"] == pytest.approx(math.exp(logs.mean()))
    assert delta["geometric_mean_ci_lo"] < delta["geometric_mean"] < delta["geometric_mean_ci_hi"]
    acceptable = cs[cs["selection"] == "fit acceptable only"].set_index(["class", "quantity"])
    assert acceptable.loc[("metro", "c_veh")]["n"] == 3  # the fourth is in doubt


def test_class_test_runs_a_test_only_when_it_can_reach_significance():
    assert smallsample.smallest_mann_whitney_p(3, 2) == pytest.approx(0.2)
    assert smallsample.smallest_mann_whitney_p(5, 4) == pytest.approx(2 / 126)
    clear = table3_frame({"metro": [300.0, 310.0, 305.0], "regional": [600.0, 610.0, 605.0]})
    r = aggregate.class_test(clear).iloc[0]
    # exact Mann-Whitney with 3 vs 3 cannot go below p = 0.1: not run, and said so
    assert math.isnan(r["mannwhitney_p"]) and r["mannwhitney_min_p"] == pytest.approx(0.1)
    assert r["welch_p"] < 0.01 and r["conclusion"].startswith("differ: Welch significant")
    assert "Mann-Whitney cannot go below p = 2 / C(6, 3) = 0.1" in r["conclusion"]
    noisy = table3_frame({"metro": [300.0, 600.0, 450.0], "regional": [350.0, 650.0, 500.0]})
    r = aggregate.class_test(noisy).iloc[0]
    assert r["welch_p"] > 0.05 and r["conclusion"].startswith("no significant difference")
    big = table3_frame({"metro": [300.0, 310, 305, 299, 302, 311], "regional": [600.0] * 5})
    big.loc[big["class"] == "regional", "c_veh"] += np.arange(5.0)
    big["verdict"] = aggregate.ACCEPTABLE
    r = aggregate.class_test(big).iloc[0]
    assert r["mannwhitney_p"] == pytest.approx(2 / math.comb(11, 5))
    assert r["conclusion"].startswith("differ: Welch and Mann-Whitney")
    lonely = table3_frame({"metro": [300.0, 310.0], "regional": [600.0]})
    r = aggregate.class_test(lonely).iloc[0]
    assert r["conclusion"].startswith("not testable")


def test_a_value_at_a_bound_and_those_coupled_to_it_are_never_printed_averaged_or_tested():
    """Metro3-like: C at its lower bound, K_veh at its upper bound. Table 2 has no value for
    them, nor for C_veh, coupled to them (it is the whole capacity C + C_veh in disguise); a
    search bound is no limit the data give, so none is printed. C_total = C + C_veh is
    reported with its interval; delta and c_veh are not identified, and the class statistics
    and test leave the vehicle out, by name."""
    vehicles = {f"M{i}": vehicle("metro", mass=30_000.0) for i in range(3)}
    vehicles |= {f"R{i}": vehicle("regional", mass=50_000.0) for i in range(3)}
    fits = {vid: fit(1e7, 500, 1.2e7 + 1e6 * i) for i, vid in enumerate(vehicles)}
    fits["M0"] = fit(1e4, 1e7, 1.4e7, pinned={"C": ("lower", 1e4), "K_veh": ("upper", 1e7)})
    tables = aggregate.study_tables(fits, {vid: kv(2.0) for vid in vehicles}, vehicles)
    t2, t3 = tables["table2"].set_index("vehicle"), tables["table3"].set_index("vehicle")
    m0 = t2.loc["M0"]
    assert math.isnan(m0["C"]) and math.isnan(m0["C_lo"]) and math.isnan(m0["K_veh"])
    assert m0["C_status"].startswith("not identified: at its lower search bound")
    assert math.isnan(m0["C_limit"]) and m0["C_limit_kind"] == "none"
    assert math.isnan(m0["K_veh_limit"]) and m0["K_veh_limit_kind"] == "none"
    assert math.isnan(m0["C_veh"]) and m0["C_veh_status"].startswith(
        "not identified: coupled to C, K_veh"
    )
    # the sum the data determine: C held at its bound, C_veh's interval carried over
    assert m0["C_total"] == pytest.approx(1.4e7 + 1e4)
    assert m0["C_total_status"] == aggregate.ESTIMATED
    assert m0["C_total_lo"] < 1.4e7 < m0["C_total_hi"] < 3e7
    d = t3.loc["M0"]
    assert math.isnan(d["delta"]) and d["delta_status"].startswith("not identified")
    assert math.isnan(d["c_veh"]) and d["c_veh_status"].startswith("not identified")
    cs = tables["class_summary"].set_index(["selection", "class", "quantity"])
    for q in ("delta", "c_veh"):
        metro = cs.loc[("every identified value", "metro", q)]
        assert metro["n"] == 2 and metro["not_identified"] == "M0"
    test = tables["class_test"].iloc[0]
    assert test["n_a"] == 2  # M0 is not in the test either
    md = tableformat.to_markdown("table2", tables["table2"], "T2.", "synthetic", [])
    assert "≤" not in md and "≥" not in md and "1.00×10⁴" not in md and "10\u202f000" not in md
    assert "1.40×10⁷" in md  # C_total, not C_veh
    md3 = tableformat.to_markdown("table3", t3.reset_index(), "T3.", "s", [])
    (m0_line,) = [line for line in md3.splitlines() if line.startswith("| M0 ")]
    assert m0_line.count("not identified") == 2  # neither c_veh nor delta of M0


def test_a_hand_built_fit_at_a_bound_is_judged_with_its_coupling():
    f = fit(1e4, 18_466, 5.7e6, sd=(0.1, 1.5, 0.3), pinned={"C": ("lower", 1e4)})
    judged = aggregate.judged_parameters(f)
    assert not judged["C"]["identified"] and judged["C"]["limit"] == "none"
    for p in ("K_veh", "C_veh"):
        assert not judged[p]["identified"] and judged[p]["coupled_to"] == ["C"]
    assert judged["kA"]["identified"]  # fixed from the static test, not coupled
    total = aggregate.fit_totals(f)["C_total"]
    assert total.identified and total.held_at_bound == ("C",)
    # C held at its bound: the sum's spread is C_veh's, weighted by its share of the sum
    w = 5.7e6 / (5.7e6 + 1e4)
    assert total.sd_log_total == pytest.approx(w * 0.3)
    # every part at a bound: a sum of bounds is nothing the data give
    both = fit(1e4, 500, 1e4, pinned={"C": ("lower", 1e4), "C_veh": ("lower", 1e4)})
    assert not aggregate.fit_totals(both)["C_total"].identified
    upper = fit(1e7, 500, 1e10, pinned={"C_veh": ("upper", 1e10)})
    assert not aggregate.fit_totals(upper)["C_total"].identified


def test_the_total_capacity_follows_the_covariance_and_the_systematic_effects():
    independent = fit(1e7, 500, 1e7, sd=(0.2, 0.1, 0.2), corr=0.0)
    anti = fit(1e7, 500, 1e7, sd=(0.2, 0.1, 0.2), corr=-0.9)
    sd0 = aggregate.fit_totals(independent)["C_total"].sd_log_total
    sd1 = aggregate.fit_totals(anti)["C_total"].sd_log_total
    assert sd0 == pytest.approx(math.sqrt(0.25 * 0.04 * 2))
    assert sd1 == pytest.approx(math.sqrt(0.25 * 0.04 * 2 * (1 - 0.9)))  # C + C_veh is firmer
    moved = fit(
        1e7,
        500,
        1e7,
        sd=(0.2, 0.1, 0.2),
        corr=0.0,
        effects={"C": {"scale_Q_H": 0.1}, "C_veh": {"scale_Q_H": 0.3}},
    )
    sd2 = aggregate.fit_totals(moved)["C_total"].sd_log_total
    assert sd2 == pytest.approx(math.sqrt(sd0**2 + (0.5 * 0.1 + 0.5 * 0.3) ** 2))


def test_the_total_capacity_is_checked_against_the_first_order_C_bar():
    vehicles = {"A": vehicle("metro"), "B": vehicle("metro")}
    fits = {"A": fit(1e7, 500, 2e7), "B": fit(1e7, 500, 2e7)}

    def order1(C_bar):
        ci = [C_bar * math.exp(-0.2), C_bar * math.exp(0.2)]
        return FitRecord.from_dict(
            {"parameters": {"C_bar": {"value": C_bar, "estimated": True, "ci95": ci}}}
        )

    first = {"A": order1(3.1e7), "B": order1(9e7)}
    t2 = aggregate.table2(fits, {v: kv(2.0) for v in vehicles}, vehicles, first).set_index(
        "vehicle"
    )
    assert t2.loc["A", "C_total_vs_C_bar"] == "overlap"
    assert t2.loc["B", "C_total_vs_C_bar"] == "disjoint"
    assert t2.loc["A", "C_bar"] == 3.1e7
    md = tableformat.to_markdown("table2", t2.reset_index(), "T2.", "s", [])
    assert "C_total = C + C_veh" in md and "disjoint" in md


def test_an_interval_spanning_more_than_a_factor_1000_in_total_is_not_an_estimate():
    assert pem.identification(1.0, (0.1, 99.9))["identified"]  # 999
    wide = pem.identification(1.0, (0.1, 100.1))  # 1001
    assert not wide["identified"] and wide["limit"] == "none"
    assert "1001" in wide["reason"]
    # judged on the total, not per side: a factor 1424 with each side within 1000 of the value
    assert not pem.identification(18_466.0, (489.0, 696_797.0))["identified"]
    f = fit(1e7, 500, 2e7, sd=(0.1, 4.0, 0.1))  # K_veh: exp(2 * 1.96 * 4) > 1000
    assert f.parameters["K_veh"].identified is False
    t2 = aggregate.table2({"A": f}, {"A": kv(2.0)}, {"A": vehicle("metro")})
    assert math.isnan(t2.iloc[0]["K_veh"]) and t2.iloc[0]["K_veh_status"].startswith(
        "not identified: 95 % interval spans a factor"
    )
    assert math.isnan(t2.iloc[0]["C"])  # coupled to K_veh
    one_sided = pem.identification(10.0, (5.0, math.inf))
    assert one_sided["limit"] == "lower" and one_sided["limit_value"] == 5.0
    at_bound = pem.identification(1e4, (1e3, 1e5), ("lower", 1e4))
    assert at_bound["limit"] == "none" and at_bound["limit_value"] is None
    physical = pem.identification(2e5, (1e5, 4e5), ("lower", 2e5, "the air's capacity ρ c_p V"))
    assert "physical lower bound (the air's capacity ρ c_p V = 2e+05)" in physical["reason"]


def test_truth_comparison_splits_inside_the_interval_from_within_tolerance():
    truth = pd.DataFrame(
        {"vehicle": ["x"], "C": [1e7], "K_veh": [500.0], "C_veh": [2e7], "deviations": [""]}
    )
    content = fit_content(1.08e7, 500, 2e7, sd=(0.1, 0.2, 0.01)) | {"nrmse_fit": 0.9, "flags": []}
    good = FitRecord.from_dict(content | {"synthetic": True})
    # a measured vehicle whose id a campaign vehicle has too: never set beside that truth
    # (before, a measured Metro3 was judged against the campaign's Metro3)
    measured = aggregate.fit_table([FitRecord.from_dict(content)], truth)
    assert not any(c.endswith(("_truth", "_recovered")) for c in measured.columns), measured
    row = aggregate.fit_table([good], truth).iloc[0]
    assert row["C_inside"] and not row["C_within_tolerance"]  # 8 % off, inside +-20 %
    assert row["C_veh_inside"] and row["C_veh_within_tolerance"]
    assert row["C_total_truth"] == 3e7 and row["C_total_inside"]
    assert row["C_recovered"] and row["K_veh_recovered"] and row["C_veh_recovered"]
    wide = FitRecord.from_dict(
        fit_content(1e7, 5e4, 2e7, sd=(0.1, 5.0, 0.1))
        | {"nrmse_fit": 0.9, "flags": [], "synthetic": True}
    )
    row = aggregate.fit_table([wide], truth).iloc[0]
    # K_veh not identified, C and C_veh coupled to it: none compared with the truth
    for p in ("C", "K_veh", "C_veh"):
        assert not row[f"{p}_inside"] and not row[f"{p}_within_tolerance"]
        assert not row[f"{p}_recovered"] and math.isnan(row[p])
    assert row["K_veh_status"].startswith("not identified")
    assert row["C_total_inside"] and row["C_total_within_tolerance"]  # the sum is determined


@pytest.mark.parametrize(
    "kind, x, lo, hi, text",
    [
        # the value with its interval's decimals; thousands grouped by a narrow space, not
        # by commas that would read as the interval's separator
        ("sci", 1.8e7, 1.7e7, 2.06e7, "1.80×10⁷ [1.70, 2.06]×10⁷"),
        ("sci", 9.96e6, 9.0e6, 1.1e7, "1.00×10⁷ [0.90, 1.10]×10⁷"),
        ("int", 47_831.0, 40_000.0, 50_000.0, "47\u202f831 [40\u202f000, 50\u202f000]"),
        ("k", 3.2353, 3.17, 3.30, "3.24 [3.17, 3.30]"),
        ("delta", 0.554, 0.5, 0.61, "0.55 [0.500, 0.610]"),
        ("int", 1e7, 1e-3, math.inf, "10\u202f000\u202f000 [0, ∞]"),
        ("sci", 1e4, 1e-20, 1e40, "1.00×10⁴ [0, ∞]×10⁴"),
    ],
)
def test_numbers_are_printed_as_the_paper_does(kind, x, lo, hi, text):
    assert tableformat._value_interval(kind, x, lo, hi, tex=False) == text


def test_study_tables_are_written_with_their_source(tmp_path):
    vehicles = {"T1": vehicle("tram"), "M1": vehicle("metro"), "M2": vehicle("metro")}
    fits = {vid: fit(1e7, 500, 2e7) for vid in vehicles}
    tables = aggregate.study_tables(fits, {vid: kv(2.0) for vid in vehicles}, vehicles)
    paths = {
        f"{name}_{ext}": str(tmp_path / f"{name}.{ext}")
        for name in tables
        for ext in ("csv", "md", "tex")
    }
    source = aggregate.data_source(vehicles)
    tableformat.write_study_tables(tables, source, paths)
    for name in tables:
        csv = pd.read_csv(paths[f"{name}_csv"])
        assert (csv["source"] == aggregate.SYNTHETIC_SOURCE).all()
        md = (tmp_path / f"{name}.md").read_text(encoding="utf-8")
        assert md.splitlines()[0].endswith(f"Data: {aggregate.SYNTHETIC_SOURCE}.")
        assert "not evidence about real vehicles" in md
        assert "reproduce the published pattern" not in md
        tex = (tmp_path / f"{name}.tex").read_text(encoding="utf-8")
        assert "\\caption{" in tex and "synthetic" in tex and "\\begin{tabular}" in tex
    measured = {vid: {**v, "synthetic": False} for vid, v in vehicles.items()}
    assert aggregate.data_source(measured) == aggregate.MEASURED_SOURCE
    mixed = aggregate.data_source({**measured, "X": vehicle("tram")})
    assert "mixed" in mixed
    # a mixed study's caption speaks of its synthetic rows only
    tableformat.write_study_tables(tables, mixed, paths)
    md = (tmp_path / "table2.md").read_text(encoding="utf-8")
    assert "The synthetic rows' estimates come from" in md and "These re-estimates" not in md
    assert "no second-order fit" not in md
    # a vehicle with a first-order fit alone is named, not silently missing
    tableformat.write_study_tables(tables, source, paths, left_out={"R1": [1], "Box": []})
    for name in tables:
        md = (tmp_path / f"{name}.md").read_text(encoding="utf-8")
        assert (
            "Not in Tables 1-3 nor the class statistics (no second-order fit): "
            "R1 (model.orders [1]), Box (model.orders [])" in md
        ), name


def test_welch_with_fewer_than_three_vehicles_in_a_class_is_not_testable():
    three_two = table3_frame({"metro": [300.0, 310.0, 305.0], "regional": [600.0, 640.0]})
    r = aggregate.class_test(three_two).iloc[0]
    assert math.isnan(r["welch_p"]) and math.isnan(r["mannwhitney_p"])
    assert r["conclusion"].startswith("not testable")
    assert "no significant difference" not in r["conclusion"]
    md = tableformat.to_markdown("class_test", aggregate.class_test(three_two), "T.", "s", [])
    assert "not testable" in md


def test_the_spread_of_delta_is_its_geometric_sd():
    t3 = table3_frame({"metro": [300.0, 350.0, 400.0, 700.0]})
    cs = aggregate.class_summary(t3)
    delta = cs[cs["selection"] == "every identified value"].set_index("quantity").loc["delta"]
    logs = np.log([3.0, 3.5, 4.0, 7.0])
    assert delta["geometric_sd"] == pytest.approx(math.exp(logs.std(ddof=1)))
    md = tableformat.to_markdown("class_summary", cs, "S.", "s", [])
    assert f"×/÷ {math.exp(logs.std(ddof=1)):.2f}" in md
