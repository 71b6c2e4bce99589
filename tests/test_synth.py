"""The virtual climatic wind tunnel: physics against closed forms, logger, determinism, layouts."""

from __future__ import annotations

import copy
import gzip
import math

import numpy as np
import pandas as pd
import pytest
import yaml
from scipy.linalg import expm

from railtherm import synth
from railtherm.errors import ConfigError
from railtherm.estimation.models import second_order
from railtherm.synth import physics

TRUTH = {
    "k": {"value": 2.0, "unit": "W/(m^2 K)", "source": "assumption: test"},
    "C": {"value": 2.0e6, "unit": "J/K", "source": "assumption: test"},
    "K_veh": {"value": 800.0, "unit": "W/K", "source": "assumption: test"},
    "C_veh": {"value": 4.0e6, "unit": "J/K", "source": "assumption: test"},
    "mass_kg": {"value": 30000, "unit": "kg", "source": "assumption: test"},
    "surface_m2": {"value": 250.0, "unit": "m^2", "source": "assumption: test"},
    "volume_m3": {"value": 90.0, "unit": "m^3", "source": "assumption: test"},
}
SPECIAL = {
    "type": "special",
    "T_tunnel": -5.0,
    "base_h": 2,
    "base_groups": 2,
    "step_groups": 2,
    "up_h": 10,
    "down_h": 4,
}
EXISTING = {
    "type": "existing",
    "T_tunnel": -10.0,
    "soak_h": 1,
    "preheat_h": 2,
    "hold_h": 10,
    "cooldown_h": 3,
    "T_preheat": 18.0,
    "T_setpoint": 20.0,
}


def _campaign(tmp_path, vehicles: dict, seed=7, name="c.yaml") -> dict:
    doc = {
        "name": "test",
        "synthetic": True,
        "description": "test campaign",
        "seed": seed,
        "fine_step_s": 5,
        "vehicles": vehicles,
    }
    path = tmp_path / name
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return synth.load_campaign(path)


def _vehicle(programme=SPECIAL, **over) -> dict:
    v = {
        "class": "metro",
        "start": "2020-01-06T08:00:00",
        "truth": copy.deepcopy(TRUTH),
        "programme": dict(programme),
        "heaters": {"groups": 4, "power_W": 3000.0},
        "logger": {"step_s": 60},
    }
    for k, val in over.items():
        v[k] = val
    return v


def _noise_free(v: dict) -> dict:
    """Exact inputs: constant tunnel air, nominal heater power, no fans."""
    v["tunnel"] = {"fluctuation_sd_K": 0.0}
    v["heaters"]["tolerance_rel"] = 0.0
    v["fans"] = {"n": 0, "power_W": 0.0}
    return v


# ---------------------------------------------------------------------------------- physics
def test_first_order_step_response_matches_closed_form(tmp_path):
    """With K_veh -> 0 the air node is eq. 9: T = T_o + Q/kA + dQ/kA (1 - exp(-t kA / C))."""
    v = _noise_free(_vehicle())
    v["truth"]["K_veh"]["value"] = 1e-12
    c = _campaign(tmp_path, {"V": v})
    spec = synth.vehicle_spec(c, "V")
    d = synth.simulate(spec, ideal=True)
    kA, C = 2.0 * 250.0, 2.0e6
    Q0, dQ, T_o = 2 * 3000.0, 2 * 3000.0, -5.0
    t_up = 2 * 3600.0
    up = d[(d.time_s >= t_up) & (d.time_s <= t_up + 10 * 3600)]
    t = up.time_s.to_numpy() - t_up
    expected = T_o + Q0 / kA + dQ / kA * (1 - np.exp(-t * kA / C))
    np.testing.assert_allclose(up["T"].to_numpy(), expected, rtol=1e-9, atol=0)
    assert np.all(d.T_o == T_o)


def test_second_order_steady_state_is_To_plus_Q_over_kA(tmp_path):
    """Initial state is exactly steady (both states = T_o + Q/kA) and stays there; after a long
    step both states approach T_o + Q1/kA."""
    v = _noise_free(_vehicle())
    v["programme"]["up_h"] = 80  # ~ 19 slow time constants (4.2 h)
    c = _campaign(tmp_path, {"V": v})
    spec = synth.vehicle_spec(c, "V")
    d = synth.simulate(spec, ideal=True)
    kA = 500.0
    base = d[d.time_s < 2 * 3600]
    for col in ("T", "T_veh"):
        np.testing.assert_allclose(base[col], -5.0 + 6000.0 / kA, rtol=1e-12)
    end_up = d[d.time_s == (2 + 80) * 3600].iloc[0]
    assert end_up["T"] == pytest.approx(-5.0 + 12000.0 / kA, abs=1e-6)
    assert end_up["T_veh"] == pytest.approx(-5.0 + 12000.0 / kA, abs=1e-6)


def test_step_response_is_exact_matrix_exponential(tmp_path):
    """Every logged state equals x_ss1 + expm(A t) (x0 - x_ss1) (exact ZOH, no integration error),
    including the stiff, almost rigidly coupled Main1-like case (fast mode of seconds)."""
    for K_veh, C in ((800.0, 2.0e6), (93627.0, 7.2e5)):
        v = _noise_free(_vehicle())
        v["truth"]["K_veh"]["value"] = K_veh
        v["truth"]["C"]["value"] = C
        c = _campaign(tmp_path, {"V": v}, name=f"c{K_veh}.yaml")
        spec = synth.vehicle_spec(c, "V")
        d = synth.simulate(spec, ideal=True)
        A, B = second_order(500.0, C, K_veh, 4.0e6)
        x0 = np.linalg.solve(A, -B @ [-5.0, 6000.0])
        x1 = np.linalg.solve(A, -B @ [-5.0, 12000.0])
        t_up = 7200.0
        up = d[(d.time_s >= t_up) & (d.time_s <= t_up + 10 * 3600)]
        for _, row in up.iloc[::37].iterrows():
            x = x1 + expm(A * (row.time_s - t_up)) @ (x0 - x1)
            np.testing.assert_allclose([row["T"], row["T_veh"]], x, rtol=1e-9)


def test_power_is_mean_over_preceding_interval(tmp_path):
    v = _noise_free(_vehicle())
    c = _campaign(tmp_path, {"V": v})
    d = synth.simulate(synth.vehicle_spec(c, "V"), ideal=True).set_index("time_s")
    assert d.loc[7200.0, "Q_H"] == pytest.approx(6000.0)  # interval (7140, 7200] before the step
    assert d.loc[7260.0, "Q_H"] == pytest.approx(12000.0)


def test_body_to_outdoor_biases_static_k_upwards(tmp_path):
    v = _noise_free(_vehicle())
    v["programme"]["up_h"] = 40
    v["deviations"] = [{"type": "body_to_outdoor", "K_o": 200.0, "note": "x"}]
    c = _campaign(tmp_path, {"V": v})
    d = synth.simulate(synth.vehicle_spec(c, "V"), ideal=True)
    s = d[d.time_s < 7200]
    k_static = (s.Q_H / (s["T"] - s.T_o)).mean() / 250.0
    series = 200.0 * 800.0 / (200.0 + 800.0)  # K_o in series with K_veh
    assert k_static == pytest.approx(2.0 + series / 250.0, rel=1e-9)


def test_unlogged_aux_heats_but_is_not_in_Q_H(tmp_path):
    v = _noise_free(_vehicle())
    v["programme"]["up_h"] = 40
    v["deviations"] = [{"type": "unlogged_aux", "power_W": 1000.0, "on_h": [[0, 100]], "note": "x"}]
    c = _campaign(tmp_path, {"V": v})
    d = synth.simulate(synth.vehicle_spec(c, "V"), ideal=True)
    s = d[d.time_s < 7200]
    np.testing.assert_allclose(s["T"] - s.T_o, (6000.0 + 1000.0) / 500.0, rtol=1e-9)
    np.testing.assert_allclose(s.Q_H, 6000.0)
    np.testing.assert_allclose(s.Q_aux, 1000.0)


def test_existing_programme_thermostat_holds_setpoint(tmp_path):
    v = _vehicle(EXISTING, heaters={"groups": 6, "power_W": 3000.0})  # 18 kW > 500 W/K x 30 K
    c = _campaign(tmp_path, {"V": v})
    spec = synth.vehicle_spec(c, "V")
    d = synth.simulate(spec, ideal=True)
    ph = spec["programme"]["phases_s"]
    soak = d[d.time_s < ph["preheat"]]
    assert (soak.Q_H == 0).all()
    np.testing.assert_allclose(soak["T"], soak.T_veh, atol=0.05)  # soaked (tunnel fluctuates)
    assert soak["T"].iloc[0] == pytest.approx(soak.T_o.iloc[0], abs=1e-12)
    assert soak["T_veh"].iloc[0] == pytest.approx(soak.T_o.iloc[0], abs=1e-12)
    assert (d[(d.time_s > ph["preheat"]) & (d.time_s <= ph["kvalue"])].Q_hvac > 0).all()
    hold = d[(d.time_s > ph["cooldown"] - 4 * 3600) & (d.time_s <= ph["cooldown"])]
    assert hold["T"].between(20.0 - 0.6, 20.0 + 0.6).all()
    assert hold.Q_heaters.nunique() > 1  # groups switching
    cool = d[d.time_s > ph["cooldown"] + 60]
    assert (cool.Q_heaters == 0).all() and cool["T"].is_monotonic_decreasing


# ---------------------------------------------------------------------------------- logger
def _read(path, spec):
    lg = spec["logger"]
    return pd.read_csv(path, sep=lg["separator"], decimal=lg["decimal"])


def test_written_file_has_one_header_row_units_and_dropouts(tmp_path):
    v = _vehicle(
        EXISTING,
        logger={"step_s": 120, "power_unit": "kW", "separator": ";", "decimal": ","},
        dropouts={"missing_rows": 5, "empty_cells": 4},
    )
    c = _campaign(tmp_path, {"V": v})
    spec = synth.vehicle_spec(c, "V")
    (name,) = synth.raw_file_names(spec)
    synth.write_raw_file(spec, name, tmp_path / name)
    df = _read(tmp_path / name, spec)
    assert list(df.columns) == [col for col, _, _ in synth.columns(spec)]
    n_all = int(spec["programme"]["phases_s"]["end"] // 120) + 1
    assert len(df) == n_all - 5
    assert 1 <= df.isna().sum().sum() <= 4
    ideal = synth.simulate(spec, ideal=True).set_index("time_s")
    t = pd.to_datetime(df["time"])
    df["time_s"] = (t - t.iloc[0]).dt.total_seconds()
    heat = df.filter(like="PH").sum(axis=1, min_count=4).to_numpy() * 1000  # NaN if a cell is empty
    q_true = ideal.loc[df.time_s, "Q_heaters"].to_numpy()
    ok = (q_true > 0) & ~np.isnan(heat)
    np.testing.assert_allclose(heat[ok], q_true[ok], rtol=0.05)
    T_logged = df.filter(like="TI").mean(axis=1).to_numpy()
    assert np.nanmax(np.abs(T_logged - ideal.loc[df.time_s, "T"].to_numpy())) < 1.5


def test_dropouts_are_short_no_channel_misses_more_than_one_logger_step(tmp_path):
    """Even with dense dropouts, every gap is a single sample: missing rows and empty cells
    never touch another gap of the same channel (the default cleaning.max_gap_s then bridges
    every dropout of every logger step the campaign allows)."""
    v = _vehicle(
        EXISTING, logger={"step_s": 120}, dropouts={"missing_rows": 40, "empty_cells": 120}
    )
    c = _campaign(tmp_path, {"V": v})
    spec = synth.vehicle_spec(c, "V")
    (name,) = synth.raw_file_names(spec)
    synth.write_raw_file(spec, name, tmp_path / name)
    df = _read(tmp_path / name, spec)
    t = pd.to_datetime(df["time"])
    seconds = (t - t.iloc[0]).dt.total_seconds().to_numpy()
    assert df.drop(columns="time").isna().sum().sum() == 120
    for column in df.columns.drop("time"):
        valid = seconds[df[column].notna().to_numpy()]
        assert np.diff(valid).max() <= 2 * 120, column


def test_write_is_byte_deterministic_and_seed_dependent(tmp_path):
    v = _vehicle(EXISTING, logger={"step_s": 60, "gzip": True})
    c1 = _campaign(tmp_path, {"V": v}, seed=1, name="a.yaml")
    c2 = _campaign(tmp_path, {"V": v}, seed=2, name="b.yaml")
    s1, s2 = synth.vehicle_spec(c1, "V"), synth.vehicle_spec(c2, "V")
    (name,) = synth.raw_file_names(s1)
    assert name.endswith(".csv.gz")
    synth.write_raw_file(s1, name, tmp_path / "1" / name)
    physics._CACHE.clear()
    synth.write_raw_file(s1, name, tmp_path / "2" / name)
    synth.write_raw_file(s2, name, tmp_path / "3" / name)
    b1, b2, b3 = ((tmp_path / d / name).read_bytes() for d in "123")
    assert b1 == b2
    assert b1 != b3
    assert b1[4:8] == b"\x00\x00\x00\x00"  # gzip mtime = 0
    assert gzip.decompress(b1).count(b"\n") > 100


def test_vehicle_spec_does_not_depend_on_other_vehicles(tmp_path):
    a = _vehicle()
    b = _vehicle(EXISTING)
    c1 = _campaign(tmp_path, {"A": a, "B": b}, name="a.yaml")
    b2 = _vehicle(EXISTING, logger={"step_s": 30})
    c2 = _campaign(tmp_path, {"B": b2, "A": a}, name="b.yaml")
    s1, s2 = synth.vehicle_spec(c1, "A"), synth.vehicle_spec(c2, "A")
    assert s1 == s2
    assert s1["seed"] != synth.vehicle_spec(c1, "B")["seed"]


def test_special_programme_writes_two_overlapping_files(tmp_path):
    c = _campaign(tmp_path, {"V": _vehicle(dropouts={"missing_rows": 0, "empty_cells": 0})})
    spec = synth.vehicle_spec(c, "V")
    names = synth.raw_file_names(spec)
    assert names == ["V_step_up.csv", "V_step_down.csv"]
    for n in names:
        synth.write_raw_file(spec, n, tmp_path / n)
    up, down = (_read(tmp_path / n, spec) for n in names)
    overlap = set(up["time"]) & set(down["time"])
    assert len(overlap) == 61  # 1 h overlap at 60 s, both ends included
    w = synth.windows(spec)
    assert [x["name"] for x in w["identification"]] == ["step_up", "step_down"]
    assert w["kvalue"]["file"] == "step_up"


def test_auto_hold_reaches_95_percent_of_the_step(tmp_path):
    v = _noise_free(_vehicle())
    v["programme"].update(up_h="auto", down_h="auto")
    c = _campaign(tmp_path, {"V": v})
    spec = synth.vehicle_spec(c, "V")
    ph = spec["programme"]["phases_s"]
    _, tau_slow = synth.time_constants(spec)
    assert ph["step_down"] - ph["step_up"] == math.ceil(math.log(20) * tau_slow / 3600) * 3600
    d = synth.simulate(spec, ideal=True).set_index("time_s")
    T0, T1 = d.loc[0.0, "T"], -5.0 + 12000.0 / 500.0
    assert (d.loc[ph["step_down"], "T"] - T0) / (T1 - T0) >= 0.95


# ---------------------------------------------------------------------------------- layouts
def _read_layout(path, spec):
    lg = spec["logger"]
    try:
        from railtherm.data.rawfile import read_layout
    except ImportError:
        read_layout = None
    if read_layout is not None:
        return read_layout(
            path, lg["separator"], lg["decimal"], lg["time_column"], lg["time_format"]
        )
    df = pd.read_csv(path, sep=lg["separator"], decimal=lg["decimal"])
    t = df[lg["time_column"]]
    t = pd.to_datetime(t) if lg["time_format"] == "iso" else t.astype(float)
    return tuple(df.columns), t.iloc[0], t.iloc[-1]


def test_planned_layouts_equal_written_files(tmp_path):
    vehicles = {
        "Iso": _vehicle(EXISTING, logger={"step_s": 120, "gzip": True, "naming": "german"}),
        "Sec": _vehicle(logger={"step_s": 300, "time_format": "seconds", "time_column": "t_s"}),
        "Chan": _vehicle(EXISTING, logger={"step_s": 600, "naming": "channel", "extras": ["wind"]}),
    }
    c = _campaign(tmp_path, vehicles)
    root = str(tmp_path / "res")
    plan = synth.planned_layouts(c, root=root + "/./")
    assert len(plan) == 4
    for vid in vehicles:
        spec = synth.vehicle_spec(c, vid)
        for name in synth.raw_file_names(spec):
            key = f"{root}/{vid}/{name}"
            synth.write_raw_file(spec, name, key)
            got = _read_layout(key, spec)
            want = plan[key]
            if isinstance(got, tuple):
                assert (want.columns, want.t_first, want.t_last) == got
            else:
                assert (got.columns, got.t_first, got.t_last, got.time_format) == (
                    want.columns,
                    want.t_first,
                    want.t_last,
                    want.time_format,
                )


# ---------------------------------------------------------------------------------- errors
@pytest.mark.parametrize(
    ("mutate", "key", "reason"),
    [
        (lambda v: v["logger"].update(step_s=62), "vehicles.V.logger.step_s", "multiple"),
        (lambda v: v["logger"].update(step_s=5), "vehicles.V.logger.step_s", "must be >= 10"),
        (
            lambda v: v["truth"]["k"].update(source="Table 2"),
            "vehicles.V.truth.k.source",
            "must match the pattern",
        ),
        (lambda v: v["truth"]["C"].update(unit="kJ/K"), "vehicles.V.truth.C.unit", "J/K"),
        (
            lambda v: v.update(deviations=[{"type": "gremlins", "note": "x"}]),
            "vehicles.V.deviations[0].type",
            "gremlins",
        ),
        (
            lambda v: v.update(deviations=[{"type": "body_to_outdoor", "note": "x"}]),
            "vehicles.V.deviations[0].K_o",
            "required",
        ),
        (lambda v: v["programme"].pop("base_h"), "vehicles.V.programme.base_h", "required"),
        (lambda v: v["programme"].update(step_groups=9), "vehicles.V.programme.step_groups", ""),
        (lambda v: v.pop("truth"), "vehicles.V.truth", "required"),
    ],
)
def test_bad_campaign_entries_name_file_key_and_value(tmp_path, mutate, key, reason):
    v = _vehicle()
    mutate(v)
    with pytest.raises(ConfigError) as exc:
        _campaign(tmp_path, {"V": v})
    assert exc.value.key == key
    assert str(tmp_path / "c.yaml") in str(exc.value)
    assert reason in str(exc.value)


def test_missing_campaign_file(tmp_path):
    with pytest.raises(ConfigError, match="campaign file not found"):
        synth.load_campaign(tmp_path / "nope.yaml")


def test_campaign_schema_and_generator_name_the_same_deviations_and_truth():
    """The schema file and the generator's tables are written apart: they must agree."""
    from railtherm.yamlio import packaged_schema

    defs = packaged_schema("campaign")["$defs"]
    deviation = defs["deviation"]
    assert tuple(deviation["properties"]["type"]["enum"]) == synth.DEVIATION_TYPES
    assert set(deviation["$defs"]) == set(synth.DEVIATION_TYPES)
    assert set(synth.DEVIATION_EFFECT_ON_K) == set(synth.DEVIATION_TYPES)
    truth = defs["settings"]["properties"]["truth"]
    assert set(truth["required"]) == set(synth.TRUTH_UNITS)


@pytest.mark.parametrize(
    ("a", "gain", "before"), [(0.9, 0.1, 20.0), (0.999, 1.0, 0.0), (0.0, 1.0, 3.0)]
)
def test_the_tunnels_lag_is_the_recursion_it_names(a, gain, before):
    """physics.lagged (a banded triangular solve) is y[n] = a y[n-1] + gain x[n] from
    y[-1] = before, as a plain loop computes it, to rounding."""
    from railtherm.synth import physics

    x = np.random.default_rng(7).normal(size=5000)
    y, expected = before, []
    for v in x:
        y = a * y + gain * v
        expected.append(y)
    np.testing.assert_allclose(physics.lagged(x, a, gain, before), expected, rtol=1e-12, atol=1e-12)
