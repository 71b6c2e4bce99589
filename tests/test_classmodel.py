"""The class reference model (railtherm.study.classmodel): a second-order parameter set for an
unmeasured vehicle from its class's generalised parameters c_veh (eq. 24), delta (eq. 25),
kappa_veh = K_veh / A and k, with 95 % prediction intervals for one new vehicle."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import scipy.stats
import yaml

from railtherm.cli import main
from railtherm.errors import ConfigError
from railtherm.study import classmodel, quality
from railtherm.study import simulate as sim
from railtherm.study.aggregate import SYNTHETIC_SOURCE
from railtherm.study.classmodel import (
    ClassMember,
    build,
    member_from_fit,
    member_from_row,
    read_reference_model,
)
from railtherm.study.fit import Fit
from railtherm.study.scenario import load_scenario

REPO = Path(__file__).resolve().parents[1]
MASS, SURFACE = 35_000.0, 300.0


def member(
    vid: str,
    vehicle_class: str = "metro",
    c_veh: float = 400.0,
    delta: float = 2.0,
    kappa_veh: float = 1.5,
    k: float = 2.8,
    usable: bool = True,
    why: str = "",
) -> ClassMember:
    return ClassMember(
        vehicle=vid,
        vehicle_class=vehicle_class,
        mass_kg=40_000.0,
        surface_m2=250.0,
        k=k,
        c_veh=c_veh,
        delta=delta,
        kappa_veh=kappa_veh,
        usable=usable,
        why=why,
    )


# --- members ----------------------------------------------------------------------------------


def fit_data(verdict: str = quality.ACCEPTABLE, **entries) -> dict:
    parameters = {
        "kA": {"value": 700.0, "estimated": False},
        "C": {"value": 1.0e7, "estimated": True, "ci95": [8e6, 1.2e7], "identified": True},
        "K_veh": {"value": 450.0, "estimated": True, "ci95": [400.0, 500.0], "identified": True},
        "C_veh": {"value": 1.8e7, "estimated": True, "ci95": [1.6e7, 2e7], "identified": True},
    }
    for name, entry in entries.items():
        parameters[name] = {**parameters[name], **entry}
    return {
        "vehicle": "V1",
        "model": "order2",
        "structure": "second_order",
        "verdict": verdict,
        "flags": [],
        "parameters": parameters,
    }


VEHICLE = {"id": "V1", "class": "metro", "mass_kg": 36_000, "surface_m2": 250.0}


def test_member_from_fit_gives_eqs_24_and_25():
    m = member_from_fit(Fit.from_dict(fit_data()), VEHICLE)
    assert m.usable and m.why == ""
    assert m.c_veh == pytest.approx(1.8e7 / 36_000)  # eq. 24
    assert m.delta == pytest.approx(1.8)  # eq. 25
    assert m.kappa_veh == pytest.approx(450.0 / 250.0)
    assert m.k == pytest.approx(700.0 / 250.0)


def test_member_not_usable_why():
    bound = {
        "identified": False,
        "limit": "upper",
        "limit_value": 1e4,
        "reason": "at its lower bound 1e+04",
    }
    m = member_from_fit(Fit.from_dict(fit_data(quality.IN_DOUBT, C=bound)), VEHICLE)
    assert not m.usable and m.delta is None
    assert m.why == (
        "C not identified (at a bound); K_veh, C_veh not identified (coupled to a parameter "
        "not identified); fit assumptions in doubt"
    )
    assert m.c_veh is None and m.kappa_veh is None  # C_veh and K_veh are coupled to C
    # an estimate flagged at a bound is never used, even where marked identified
    data = fit_data()
    data["flags"] = [{"code": "at_bound", "parameters": ["K_veh"], "message": "..."}]
    m = member_from_fit(Fit.from_dict(data), VEHICLE)
    assert not m.usable and m.kappa_veh is None and m.c_veh is None
    assert m.why == (
        "K_veh not identified (at a bound); C, C_veh not identified (coupled to a parameter "
        "not identified)"
    )
    m = member_from_fit(Fit.from_dict(fit_data()), {**VEHICLE, "class": "other", "mass_kg": None})
    assert not m.usable and m.why == "no mass_kg" and m.c_veh is None


def row_of(**cells) -> dict:
    """A row of Table 2 as the csv module reads it (strings, "" for an empty cell) for the
    fit of fit_data(): k = kA / A = 700 / 250."""
    row = {
        "vehicle": "V1",
        "class": "metro",
        "k": "2.8",
        "k_status": "estimated",
        "C": "1e+07",
        "C_status": "estimated",
        "K_veh": "450",
        "K_veh_status": "estimated",
        "C_veh": "1.8e+07",
        "C_veh_status": "estimated",
        "verdict": quality.ACCEPTABLE,
        "source": "measured",
    }
    return {**row, **cells}


def test_member_from_row_is_member_from_fit():
    # the same vehicle from its Table 2 row and from its fit: one rule, the same member
    assert member_from_row(row_of(), VEHICLE) == member_from_fit(Fit.from_dict(fit_data()), VEHICLE)
    bound = "not identified: at its lower bound 1e+04"
    m = member_from_row(row_of(verdict=quality.IN_DOUBT, C="", C_status=bound), VEHICLE)
    fit = Fit.from_dict(
        fit_data(
            quality.IN_DOUBT,
            C={"identified": False, "reason": bound.removeprefix("not identified: ")},
        )
    )
    assert m == member_from_fit(fit, VEHICLE)
    assert not m.usable and m.delta is None and m.c_veh is None  # C_veh coupled to C
    assert m.why == (
        "C not identified (at a bound); K_veh, C_veh not identified (coupled to a parameter "
        "not identified); fit assumptions in doubt"
    )
    assert m.c_veh is None and m.kappa_veh is None  # C_veh and K_veh are coupled to C
    # an unbounded interval; pandas' NaN for an empty cell
    unbounded = "not identified: 95 % interval unbounded above (beyond a factor 100 of the value)"
    m = member_from_row(row_of(K_veh=math.nan, K_veh_status=unbounded), VEHICLE)
    assert m.why == (
        "K_veh not identified (interval unbounded); C, C_veh not identified (coupled to a "
        "parameter not identified)"
    )
    assert m.kappa_veh is None
    fit = Fit.from_dict(
        fit_data(K_veh={"identified": False, "reason": unbounded.removeprefix("not identified: ")})
    )
    assert m == member_from_fit(fit, VEHICLE)
    # no surface: k "not given", and the member is not usable for the want of A
    no_surface = {**VEHICLE, "surface_m2": None}
    m = member_from_row(row_of(k="", k_status="not given: no surface_m2"), no_surface)
    assert not m.usable and m.why == "no surface_m2" and m.k is None and m.kappa_veh is None
    assert member_from_row(row_of(source=SYNTHETIC_SOURCE), VEHICLE).synthetic


@pytest.mark.bad_input
@pytest.mark.parametrize(
    "cells, vehicle, words",
    [
        ({"class": "tram"}, {}, ["key 'class' = 'tram'", "older than the config"]),
        ({"vehicle": "V2"}, {}, ["key 'vehicle' = 'V2'", "not the config's vehicle"]),
        ({"k_status": "not given: no surface_m2"}, {}, ["gives surface_m2", "snakemake"]),
        ({"C": ""}, {}, ["key 'C' = ''", "not a positive number"]),
        ({"C_veh": "-3"}, {}, ["key 'C_veh' = '-3'"]),
        ({}, {"mass_kg": "heavy"}, ["key 'mass_kg' = 'heavy'"]),
    ],
)
def test_member_from_row_refuses_a_row_that_disagrees(cells, vehicle, words):
    row = row_of(**cells)
    with pytest.raises(ConfigError) as err:
        member_from_row(row, {**VEHICLE, **vehicle}, table="results/tables/table2.csv")
    text = str(err.value)
    assert "\n" not in text
    for word in words:
        assert word in text


@pytest.mark.bad_input
def test_member_from_row_refuses_a_table_without_a_column():
    row = row_of()
    row.pop("verdict")
    with pytest.raises(ConfigError, match="table2.csv: key 'verdict' = None: column missing"):
        member_from_row(row, VEHICLE)


def test_members_of_the_committed_study():
    # from the committed Table 2 and the vehicle configs: no fit file needed (a fresh clone)
    members = classmodel.members_from_study("config/config.yaml", "results", workdir=REPO)
    by_id = {m.vehicle: m for m in members}
    usable = {
        cls: [m.vehicle for m in members if m.vehicle_class == cls and m.usable]
        for cls in ("tram", "metro", "regional", "main-line")
    }
    assert usable == {
        "tram": ["Tram1", "Tram2"],
        "metro": ["Metro1", "Metro2", "Metro5"],
        "regional": ["Regio2", "Regio4"],
        "main-line": [],
    }
    assert by_id["Metro3"].why == (
        "K_veh not identified (interval unbounded); C_veh not identified (at a bound); C not "
        "identified (coupled to a parameter not identified); fit assumptions in doubt"
    )
    assert by_id["Main1"].why == (
        "C not identified (at a bound); K_veh, C_veh not identified (coupled to a parameter not "
        "identified); fit assumptions in doubt"
    )
    assert by_id["Metro4"].why == "fit assumptions in doubt"
    assert all(m.synthetic for m in members)
    # the numbers: Table 2's (6 significant digits) and the configs' mass and surface
    table = pd.read_csv(REPO / "results" / "tables" / "table2.csv").set_index("vehicle")
    metro1 = by_id["Metro1"]
    row = table.loc["Metro1"]
    assert metro1.k == pytest.approx(row["k"], rel=1e-12)
    assert metro1.c_veh == pytest.approx(row["C_veh"] / metro1.mass_kg, rel=1e-12)  # eq. 24
    assert metro1.delta == pytest.approx(row["C_veh"] / row["C"], rel=1e-12)  # eq. 25
    assert metro1.kappa_veh == pytest.approx(row["K_veh"] / metro1.surface_m2, rel=1e-12)
    # the same as Table 2 says: usable = acceptable and every parameter estimated
    for row in table.reset_index().itertuples():
        statuses = {row.k_status, row.C_status, row.K_veh_status, row.C_veh_status}
        usable = row.verdict == quality.ACCEPTABLE and statuses == {"estimated"}
        assert by_id[row.vehicle].usable == usable, row.vehicle


def study_copy(tmp_path: Path, drop: str | None = None) -> Path:
    """The committed configs and Table 2 in tmp_path, less ``drop``'s row."""
    shutil.copytree(REPO / "config", tmp_path / "config")
    table = tmp_path / "results" / "tables" / "table2.csv"
    table.parent.mkdir(parents=True)
    lines = (REPO / "results" / "tables" / "table2.csv").read_text(encoding="utf-8").splitlines()
    kept = [line for line in lines if drop is None or not line.startswith(f"{drop},")]
    table.write_text("\n".join(kept) + "\n", encoding="utf-8")
    return tmp_path


def test_a_vehicle_without_a_row_is_not_usable(tmp_path):
    root = study_copy(tmp_path, drop="Metro2")
    members = classmodel.members_from_study("config/config.yaml", workdir=root)
    by_id = {m.vehicle: m for m in members}
    assert [m.vehicle for m in members][:4] == ["Tram1", "Tram2", "Metro1", "Metro2"]
    assert not by_id["Metro2"].usable and by_id["Metro2"].why == "not in table2.csv"
    assert by_id["Metro2"].mass_kg == 31_579.0  # from its config
    assert by_id["Metro1"].usable


@pytest.mark.bad_input
def test_a_missing_table2_is_one_line_naming_it_and_snakemake(tmp_path):
    root = study_copy(tmp_path)
    with pytest.raises(ConfigError) as err:
        classmodel.members_from_study("config/config.yaml", "elsewhere", workdir=root)
    text = str(err.value)
    assert "\n" not in text
    assert text.startswith("elsewhere/tables/table2.csv: ")
    assert "snakemake" in text and "not found" in text
    # a vehicle listed twice in the table
    table = root / "results" / "tables" / "table2.csv"
    lines = table.read_text(encoding="utf-8").splitlines()
    table.write_text("\n".join([*lines, lines[1]]) + "\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="key 'vehicle' = 'Tram1': listed twice"):
        classmodel.members_from_study("config/config.yaml", workdir=root)


# --- refusals ---------------------------------------------------------------------------------


def test_refuses_a_class_with_too_few_usable_vehicles():
    members = [
        member("M1"),
        member("M2", usable=False, why="fit assumptions in doubt"),
        member("M3", usable=False, why="C not identified (at a bound)"),
        member("T1", "tram"),
        member("T2", "tram"),
    ]
    with pytest.raises(ConfigError) as err:
        build(members, "metro", MASS, SURFACE)
    text = str(err.value)
    assert "\n" not in text
    assert text.startswith("--class: key 'class' = 'metro': class metro has 1 usable vehicle (M1)")
    assert "M2 (fit assumptions in doubt)" in text
    assert "M3 (C not identified (at a bound))" in text
    assert "at least 2" in text
    # enough for 2, not for 3
    assert build(members, "tram", MASS, SURFACE).basis == ["T1", "T2"]
    with pytest.raises(ConfigError, match="tram has 2 usable vehicles .* at least 3"):
        build(members, "tram", MASS, SURFACE, min_vehicles=3)
    with pytest.raises(ConfigError, match="excluded: T2"):
        build(members, "tram", MASS, SURFACE, exclude=["T2"])
    with pytest.raises(ConfigError, match="main-line has no vehicle"):
        build(members, "main-line", MASS, SURFACE)


def test_an_excluded_vehicle_of_another_class_is_refused():
    """`railtherm reference --class metro --exclude Tram1` was accepted and changed nothing:
    a misplaced id looked like a model built without it."""
    members = [member("M1"), member("M2", c_veh=500.0), member("M3", c_veh=450.0)]
    members.append(member("T1", vehicle_class="tram"))
    with pytest.raises(ConfigError, match=r"'T1': a vehicle of class tram, not of metro"):
        build(members, "metro", MASS, SURFACE, exclude=["T1"], exclude_in_class=True)
    # a study leaving a vehicle out of the class it is predicted by, whatever the basis
    assert build(members, "metro", MASS, SURFACE, exclude=["T1"]).basis == ["M1", "M2", "M3"]


@pytest.mark.parametrize(
    "kwargs, start",
    [
        (
            {"min_vehicles": 1},
            "--min-vehicles: key 'min_vehicles' = 1: must be an integer of at least 2",
        ),
        ({"vehicle_class": "metros"}, "--class: key 'class' = 'metros': unknown vehicle class"),
        ({"vehicle_class": "other"}, "--class: key 'class' = 'other': class other holds"),
        ({"mass_kg": 0.0}, "--mass-kg: key 'mass_kg' = 0.0: expected a positive number"),
        ({"surface_m2": -3.0}, "--surface-m2: key 'surface_m2' = -3.0"),
        ({"k": float("nan")}, "--k: key 'k' = nan"),
        ({"exclude": ["X9"]}, "--exclude: key 'exclude' = 'X9'"),
    ],
)
def test_refuses_bad_arguments(kwargs, start):
    args = {"vehicle_class": "metro", "mass_kg": MASS, "surface_m2": SURFACE, **kwargs}
    with pytest.raises(ConfigError) as err:
        build([member("M1"), member("M2", c_veh=500.0)], **args)
    assert str(err.value).startswith(start)


# --- the intervals ----------------------------------------------------------------------------


def constant_sd_sequence(n: int) -> np.ndarray:
    """n numbers whose every leading subset of 2 or more has sample sd (ddof 1) exactly 1:
    adding x to j numbers of mean m leaves s^2 unchanged iff (x - m)^2 = s^2 (j + 1) / j
    (Welford's update of the sum of squares), so each new number sits that far from the mean."""
    z = [-math.sqrt(0.5), math.sqrt(0.5)]
    for j in range(2, n):
        z.append(float(np.mean(z)) + (-1) ** j * math.sqrt((j + 1) / j))
    return np.array(z)


def test_intervals_widen_as_vehicles_are_removed():
    # Every subset below has the same sample sd of the logs, by construction (checked), so the
    # interval's width exp(+-t_{0.975, n-1} sd_log sqrt(1 + 1/n)) depends on n alone: both
    # the t quantile (fewer degrees of freedom, heavier tails) and sqrt(1 + 1/n) (the class
    # mean known less well) grow as n falls. Neither sample noise nor luck enter: the removed
    # vehicles do not change the spread. The derived parameters' intervals (quantiles of draws
    # with a fixed seed) follow, with margins far beyond the Monte-Carlo error (~17 % wider
    # from n = 5 to 4, ~40 % from 4 to 3 on the log scale).
    z = constant_sd_sequence(5)
    sds = {"c_veh": 0.3, "delta": 0.5, "kappa_veh": 0.8, "k": 0.1}
    centres = {"c_veh": 400.0, "delta": 2.0, "kappa_veh": 1.5, "k": 2.5}
    members = [
        member(f"M{i + 1}", **{p: centres[p] * math.exp(sds[p] * zi) for p in sds})
        for i, zi in enumerate(z)
    ]
    widths: dict[int, dict[str, float]] = {}
    for n in (5, 4, 3):
        model = build(members, "metro", MASS, SURFACE, exclude=[m.vehicle for m in members[n:]])
        assert len(model.basis) == n
        params = model.parameters
        widths[n] = {}
        for name in (*sds, "kA", "C", "K_veh", "C_veh"):
            lo, hi = params[name]["ci95"]
            widths[n][name] = math.log(hi / lo)
        for name, sd in sds.items():
            g = model.generalised[name]
            assert g.sd_log == pytest.approx(sd, rel=1e-12)  # the construction holds
            t = scipy.stats.t.ppf(0.975, n - 1)
            assert widths[n][name] == pytest.approx(2 * t * sd * math.sqrt(1 + 1 / n))
    for name in widths[5]:
        assert widths[5][name] < widths[4][name] < widths[3][name], name


def test_prediction_interval_is_wider_than_the_class_means():
    values = {"A": 300.0, "B": 400.0, "C": 500.0, "D": 350.0}
    g = classmodel.Generalised.from_values("c_veh", "J/(kg K)", values)
    logs = np.log(list(values.values()))
    assert g.centre == pytest.approx(math.exp(logs.mean()))
    assert g.sd_log == pytest.approx(logs.std(ddof=1))
    assert g.dof == 3 and g.n == 4
    t = scipy.stats.t.ppf(0.975, 3)
    mean_half = t * g.sd_log / math.sqrt(4)  # a confidence interval of the class mean
    assert math.log(g.pi95[1] / g.centre) == pytest.approx(t * g.sd_log * math.sqrt(1.25))
    assert math.log(g.pi95[1] / g.centre) > 2 * mean_half


# --- the model --------------------------------------------------------------------------------


def two_members() -> list[ClassMember]:
    # geometric means: c_veh 400, delta 2, kappa_veh 2, k 4
    return [
        member("M1", c_veh=200.0, delta=1.0, kappa_veh=1.0, k=2.0),
        member("M2", c_veh=800.0, delta=4.0, kappa_veh=4.0, k=8.0),
    ]


def test_theta_arithmetic():
    model = build(two_members(), "metro", MASS, SURFACE)
    theta = model.theta
    assert theta["C_veh"] == pytest.approx(400.0 * MASS)  # eq. 24
    assert theta["C"] == pytest.approx(400.0 * MASS / 2.0)  # eq. 25
    assert theta["K_veh"] == pytest.approx(2.0 * SURFACE)
    assert theta["kA"] == pytest.approx(4.0 * SURFACE)
    assert model.structure == "second_order"
    params = model.parameters
    assert [params[p]["value"] for p in ("kA", "C", "K_veh", "C_veh")] == pytest.approx(
        [theta[p] for p in ("kA", "C", "K_veh", "C_veh")]
    )


def test_a_given_k_overrides_the_class_k():
    model = build(two_members(), "metro", MASS, SURFACE, k=2.5)
    assert model.theta["kA"] == pytest.approx(2.5 * SURFACE)
    assert model.generalised["k"].centre == pytest.approx(4.0)  # still there, unused
    params = model.parameters
    assert params["k"] == {
        "value": 2.5,
        "ci95": [2.5, 2.5],
        "unit": "W/(m2 K)",
        "given": True,
        "identified": True,
    }
    assert params["kA"]["ci95"] == [2.5 * SURFACE] * 2
    assert np.allclose(model.draws(100)["kA"], 2.5 * SURFACE)
    # the other parameters are drawn as without k
    free = build(two_members(), "metro", MASS, SURFACE)
    for p in ("C", "K_veh", "C_veh"):
        assert np.array_equal(model.draws(100)[p], free.draws(100)[p])


def test_draws_are_deterministic_with_medians_at_theta():
    members = [
        member(f"M{i}", c_veh=c, delta=d, kappa_veh=q, k=k)
        for i, (c, d, q, k) in enumerate(
            [(300, 1.0, 1.0, 2.5), (400, 2.5, 2.0, 3.0), (500, 2.0, 1.5, 2.7), (350, 1.5, 3.0, 2.9)]
        )
    ]
    model = build(members, "metro", MASS, SURFACE)
    a, b = model.draws(50_001, seed=3), model.draws(50_001, seed=3)
    assert all(np.array_equal(a[p], b[p]) for p in a)
    assert not np.array_equal(a["C"], model.draws(50_001, seed=4)["C"])
    for p, value in model.theta.items():
        assert np.median(a[p]) == pytest.approx(value, rel=0.03), p


def test_round_trip(tmp_path):
    members = [*two_members(), member("M3", c_veh=500.0), member("M4", usable=False, why="x")]
    model = build(members, "metro", MASS, SURFACE, k=2.9, exclude=["M3"])
    path = tmp_path / "sub" / "reference.yaml"
    model.write(path)
    again = read_reference_model(path)
    assert again == model
    assert again.to_dict() == model.to_dict()
    data = yaml.safe_load(path.read_text())
    assert list(data)[:3] == ["kind", "model", "structure"]
    assert data["kind"] == "class_reference_model" and data["excluded"] == ["M3"]
    assert data["not_used"] == {"M4": "x"}
    assert "95 % prediction intervals" in data["note"] and "independent" in data["note"]
    # a file edited by hand is refused
    data["generalised"]["c_veh"]["centre"] = 1.0
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    with pytest.raises(ConfigError, match="generalised.c_veh.centre"):
        read_reference_model(path)


def test_pooled_classes():
    members = [*two_members(), member("T1", "tram"), member("O1", "other")]
    model = build(members, "all", MASS, SURFACE)
    assert model.basis == ["M1", "M2", "T1"]  # class other is no rail class


# --- the command line -------------------------------------------------------------------------


def test_cli_end_to_end(tmp_path, capsys):
    out = tmp_path / "metro.yaml"
    argv = ["reference", "--class", "metro", "--mass-kg", "35000", "--surface-m2", "300"]
    assert main([*argv, "-d", str(REPO), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "rests on 3 vehicles: Metro1, Metro2, Metro5" in printed
    assert "k from class" in printed
    assert "Metro3 (K_veh not identified (interval unbounded)" in printed
    model = read_reference_model(out)
    assert model.basis == ["Metro1", "Metro2", "Metro5"] and model.k_given is None
    # without --out: the YAML on stdout, the summary on stderr
    assert main([*argv, "--k", "2.8", "-d", str(REPO)]) == 0
    captured = capsys.readouterr()
    data = yaml.safe_load(captured.out)
    assert data["k_given"] == 2.8 and data["parameters"]["kA"]["value"] == pytest.approx(840.0)
    assert "k given" in captured.err


@pytest.mark.parametrize(
    "extra, words",
    [
        (["--class", "main-line"], ["main-line has 0 usable vehicles", "Main1", "Main2"]),
        (["--class", "metros"], ["unknown vehicle class"]),
        (["--class", "metro", "--min-vehicles", "4"], ["3 usable vehicles", "at least 4"]),
        (
            ["--class", "metro", "--results", "nowhere"],
            ["nowhere/tables/table2.csv", "not found", "snakemake"],
        ),
    ],
)
def test_cli_error_is_one_line_and_exit_1(capsys, extra, words):
    argv = ["reference", "--mass-kg", "35000", "--surface-m2", "300", "-d", str(REPO), *extra]
    assert main(argv) == 1
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.count("\n") == 1
    for word in words:
        assert word in captured.err


def test_a_class_parameter_with_an_interval_over_a_factor_1000_is_not_an_estimate():
    tight = [
        member("M1", c_veh=400.0, delta=2.0, kappa_veh=2.0, k=2.0),
        member("M2", c_veh=420.0, delta=2.1, kappa_veh=2.2, k=2.1),
        member("M3", c_veh=380.0, delta=1.9, kappa_veh=1.8, k=1.9),
    ]
    params = build(tight, "metro", MASS, SURFACE).parameters
    assert all(p["identified"] for p in params.values())
    # kappa_veh over four decades: K_veh's prediction interval spans far more than 1000
    wide = [
        member("M1", c_veh=400.0, delta=2.0, kappa_veh=0.01, k=2.0),
        member("M2", c_veh=420.0, delta=2.1, kappa_veh=1.0, k=2.1),
        member("M3", c_veh=380.0, delta=1.9, kappa_veh=100.0, k=1.9),
    ]
    model = build(wide, "metro", MASS, SURFACE)
    params = model.parameters
    lo, hi = params["K_veh"]["ci95"]
    assert hi / lo > 1000 and not params["K_veh"]["identified"]
    for p in ("C", "C_veh"):  # coupled to K_veh
        assert not params[p]["identified"] and "coupled to K_veh" in params[p]["reason"]
    assert params["kA"]["identified"] and params["c_veh"]["identified"]
    summary = model.summary()
    (line,) = [x for x in summary.splitlines() if x.strip().startswith("K_veh ")]
    assert "not identified" in line and "[" not in line
    # its centre is predicted, with no band
    scenario = load_scenario(Path(__file__).parents[1] / "config/scenarios/preheat_cold_soak.yaml")
    result = sim.simulate(model, scenario, draws=10)
    assert result.draws == 0 and "K_veh" in result.band_withheld
    assert sim.parameter_set(build(tight, "metro", MASS, SURFACE)).band_withheld == ""
