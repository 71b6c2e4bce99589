"""railtherm.study.energy and railtherm.study.weather: the annual heating energy against
answers known without the engine."""

from __future__ import annotations

import math
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from railtherm.errors import ConfigError
from railtherm.estimation import models
from railtherm.study import energy, simulate, weather

REPO = Path(__file__).resolve().parents[1]
SAND_POINT = REPO / "config" / "weather" / "703165TY.csv"
GREENSBORO = REPO / "config" / "weather" / "723170TYA.csv"
SECOND = models.STRUCTURES["second_order"]
THETA = {"kA": 700.0, "C": 9.0e6, "K_veh": 450.0, "C_veh": 1.8e7}
ALWAYS = {"weekdays": [[0, 24]]}


def vehicle(theta=THETA) -> simulate.ParameterSet:
    return simulate.ParameterSet("test car", "declared", SECOND, dict(theta))


def profile(tmp_path, **changes) -> energy.Profile:
    data = {"service": ALWAYS, "set_point_C": 20, "heating_limit_W": 60000, **changes}
    path = tmp_path / "profile.yaml"
    path.write_text(yaml.safe_dump(data))
    return energy.load_profile(path)


def constant_year(T_o: float) -> weather.Weather:
    n = 8760
    time = pd.date_range("2001-01-01 01:00", periods=n, freq="h")
    return weather.Weather("flat", "constant", time, np.arange(n) * 3600.0, np.full(n, T_o), None)


def test_constant_weather_costs_kA_dT_for_8760_hours_less_the_gains(tmp_path):
    """T_o held at -5 degC, 20 degC held around the clock, 1.5 kW of auxiliaries: every
    step heats kA (T_set - T_o) less the gains, exactly."""
    prof = profile(tmp_path, auxiliaries_W=1500)
    result = energy.annual_energy(vehicle(), constant_year(-5.0), prof, dt_s=600.0, draws=0)
    expected = (THETA["kA"] * 25.0 - 1500.0) * 8760 / 1000.0
    assert result.energy_kWh[0, 0] == pytest.approx(expected, rel=1e-9)
    assert result.monthly_kWh[0, 0, 0] == pytest.approx(expected * 31 / 365, rel=1e-9)
    assert result.unmet_h[0, 0] == 0 and result.preheat_kWh[0, 0] == 0


@pytest.mark.parametrize("path", [SAND_POINT, GREENSBORO])
def test_a_real_year_in_service_around_the_clock_is_its_degree_hours(tmp_path, path):
    """In service around the clock at 20 degC without gains, a typical year costs kA times
    its degree-hours below 20 degC within 3 %: the difference is the heat the capacities
    store and give back across the hours the vehicle would float above its set point."""
    year = weather.read_weather(path)
    result = energy.annual_energy(vehicle(), year, profile(tmp_path), dt_s=600.0, draws=0)
    degree_hours = np.clip(20.0 - year.T_o, 0.0, None).sum()
    expected = THETA["kA"] * degree_hours / 1000.0
    assert result.energy_kWh[0, 0] == pytest.approx(expected, rel=0.03)


def test_a_what_if_is_paired_and_its_band_narrower_than_the_totals(tmp_path):
    """k -10 % on the same draws: a saving, and the difference's band narrower than either
    total's (the parameters' common uncertainty cancels)."""

    def draw(n, rng):
        return {p: v * np.exp(rng.normal(0.0, 0.05, n)) for p, v in THETA.items()}

    ps = simulate.ParameterSet("test car", "declared", SECOND, dict(THETA), draw=draw)
    prof = profile(tmp_path, service={"weekdays": [[6, 22]]}, set_back_C=8, preheat_h=1)
    result = energy.annual_energy(
        ps,
        weather.read_weather(SAND_POINT),
        prof,
        what_ifs=[energy.parse_what_if("k=-10%")],
        dt_s=1200.0,
        draws=30,
        seed=3,
    )
    base = result.band(result.energy_kWh[0])
    less = result.band(result.energy_kWh[1])
    diff = result.difference(1)
    assert diff[0] < 0 and diff[2] < 0
    assert diff[2] - diff[1] < min(base[2] - base[1], less[2] - less[1]) / 3
    assert result.preheat_kWh[0, 0] > 0


def test_typical_years_are_read_through_pvlib():
    sand = weather.read_weather(SAND_POINT)
    assert sand.hours == 8760 and sand.source.startswith("NREL TMY3 station 703165")
    assert sand.latitude == pytest.approx(55.317) and -11 < sand.T_o.min() < sand.T_o.max() < 20
    t, T_o, ghi = weather.on_grid(sand, 60.0)
    assert len(t) == 525600 and T_o[60] == sand.T_o[1] and ghi is not None
    assert T_o[30] == pytest.approx((sand.T_o[0] + sand.T_o[1]) / 2)


@pytest.mark.bad_input
def test_a_bad_weather_file_or_profile_names_what_is_wrong(tmp_path):
    short = tmp_path / "short.csv"
    short.write_text("time,T_o\n2001-01-01T00:00:00,1\n2001-01-01T01:00:00,2\n")
    with pytest.raises(ConfigError, match="8760"):
        weather.read_weather(short, kind="csv")
    with pytest.raises(ConfigError, match=r"'service\.weekdays\[0\]'"):
        profile(tmp_path, service={"weekdays": [[22, 6]]})
    with pytest.raises(ConfigError, match="what_if"):
        energy.parse_what_if("k=ten")
    assert math.isnan(
        energy.profile_on_grid(
            profile(tmp_path, service={"weekdays": [[6, 7]]}), np.array([0.0, 600.0])
        ).set_point[0]
    )


def test_the_command_prints_the_year_its_months_and_a_paired_what_if(fit_files, capsys):
    """``railtherm energy`` on a campaign fit: the year with its band, the months, the
    pre-heating apart and the what-if's paired difference; a bad what-if is refused before
    anything runs."""
    from railtherm.cli import main

    fit, _ = fit_files("Metro2", "order2")
    args = [
        "energy",
        str(fit),
        "--weather",
        str(SAND_POINT),
        "--profile",
        str(REPO / "config" / "profiles" / "metro_service.yaml"),
        "--step-s",
        "1800",
        "--draws",
        "40",
    ]
    assert main([*args, "--what-if", "k=-10%"]) == 0
    out = capsys.readouterr().out
    assert "weather NREL TMY3 station 703165 (Sand Point, AK)" in out
    assert "| base | " in out and "| k -10 % | " in out and "| month | Jan |" in out
    assert "k -10 % against the base: -" in out and "(paired)" in out
    assert main([*args, "--what-if", "k=lots"]) != 0
    assert "--what-if" in capsys.readouterr().err


def test_the_command_writes_its_table_text_and_figure_with_the_gains(fit_files, tmp_path, capsys):
    """``railtherm energy --out DIR``: energy.csv (a row per variant, the heat balance among
    its columns), energy.md (what was printed, the gains listed) and the monthly figure as
    PNG and SVG; the balance's what-if effect reads off it: the saving is the envelope loss
    saved, the gains the same."""
    from railtherm.cli import main

    fit, _ = fit_files("Metro2", "order2")
    out = tmp_path / "out"
    args = ["energy", str(fit), "--weather", str(SAND_POINT), "--profile"]
    args += [str(REPO / "config" / "profiles" / "metro_service.yaml"), "--step-s", "1800"]
    assert main([*args, "--draws", "40", "--what-if", "k=-10%", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert sorted(p.name for p in out.iterdir()) == [
        "energy.csv", "energy.md", "energy.png", "energy.svg",
    ]  # fmt: skip
    assert "| internal gains |" in printed and printed in out.joinpath("energy.md").read_text()
    table = pd.read_csv(out / "energy.csv")
    assert list(table.columns) == energy.study_columns() and len(table) == 2
    base, cut = table.iloc[0], table.iloc[1]
    assert base["gains_kWh"] == cut["gains_kWh"] > 0
    saved = cut["envelope_kWh"] + cut["doors_kWh"] - base["envelope_kWh"] - base["doors_kWh"]
    assert cut["difference_kWh"] == pytest.approx(saved, rel=2e-3)
    assert out.joinpath("energy.png").stat().st_size > 0


def test_the_heat_balance_closes_and_its_envelope_loss_is_kA_times_the_degree_hours(tmp_path):
    """A constant -5 degC year held at 20 degC with 1.5 kW of auxiliaries and a door: the
    envelope loss is kA x 25 K x 8760 h, the gains 1.5 kW x 8760 h, and the heating covers
    the losses less the gains (nothing is stored over a steady year)."""
    prof = profile(
        tmp_path, auxiliaries_W=1500, doors={"openings_per_h": 10, "air_m3_per_opening": 5}
    )
    r = energy.annual_energy(vehicle(), constant_year(-5.0), prof, dt_s=600.0, draws=0)
    assert r.envelope_kWh[0, 0] == pytest.approx(THETA["kA"] * 25.0 * 8.76, rel=1e-6)
    assert r.gains_kWh[0, 0] == pytest.approx(1.5 * 8760.0, rel=1e-12)
    door_W_K = 10 * 5 * 1.2 * 1005.0 / 3600.0  # m3/h x rho c_p
    assert r.doors_kWh[0, 0] == pytest.approx(door_W_K * 25.0 * 8.76, rel=1e-6)
    assert abs(r.stored()[0, 0]) < 1e-6 * r.envelope_kWh[0, 0]


def test_a_year_read_once_loads_as_it_was_read(tmp_path):
    """The study reads each typical year once (rule weather_year) and its energy jobs load
    it: the same instants, temperatures and irradiance; a file of another kind is read as a
    weather file, a stored object that is no year is refused."""
    import pickle

    year = weather.read_weather(SAND_POINT)
    path = tmp_path / "sand.year.pickle"
    weather.write_year(year, path)
    again = weather.load_year(path)
    assert again.source == year.source and again.ghi_shift_s == year.ghi_shift_s
    np.testing.assert_array_equal(again.t_s, year.t_s)
    np.testing.assert_array_equal(again.T_o, year.T_o)
    np.testing.assert_array_equal(again.ghi, year.ghi)
    assert weather.load_year(SAND_POINT).source == year.source
    (tmp_path / "odd.year.pickle").write_bytes(pickle.dumps({"T_o": [1.0]}))
    with pytest.raises(ConfigError, match="not a typical year"):
        weather.load_year(tmp_path / "odd.year.pickle")


def test_each_class_has_a_profile_whose_figures_name_their_source():
    """The study runs every vehicle class of config/audit.yaml under a profile of its own
    (config/config.yaml energy.profiles); each figure in a class profile's ``source`` names
    its kind as config/audit.yaml does (standard, handbook, datasheet, published, physics,
    definition or assumption), and the heater is sized by the vehicle's surface."""
    import re

    config = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
    audit = yaml.safe_load((REPO / "config" / "audit.yaml").read_text())
    classes = set(audit["ranges"]["m_veh"])
    profiles = config["energy"]["profiles"]
    assert classes <= set(profiles), classes - set(profiles)
    kinds = "standard|handbook|datasheet|published|physics|definition|assumption"
    for cls in classes:
        path = REPO / profiles[cls]
        data = yaml.safe_load(path.read_text())
        parts = [p.strip() for p in data["source"].split(";") if p.strip()]
        unsourced = [p for p in parts if not re.search(rf" - ({kinds}):", p)]
        assert len(parts) >= 6 and not unsourced, (path.name, unsourced)
        prof = energy.load_profile(path)
        assert prof.name == cls and prof.heating_limit_W_per_m2 is not None


def test_progress_is_reported_up_to_the_last_step(tmp_path):
    """annual_energy's progress callback (the command's progress bar) sees the steps done
    rise to the total: the warm-up and the year."""
    seen = []
    energy.annual_energy(
        vehicle(), constant_year(0.0), profile(tmp_path), dt_s=600.0, draws=0,
        progress=lambda done, total: seen.append((done, total)),
    )  # fmt: skip
    done = [d for d, _ in seen]
    total = 8760 * 6 + energy.WARMUP_DAYS * 144
    assert done == sorted(done) and seen[-1] == (total, total) and len(seen) > 1


def test_a_heater_sized_per_square_metre_takes_the_vehicles_surface(tmp_path):
    """heating_limit_W_per_m2 sizes each vehicle's heater by its outer surface: a heater of
    20 W/m2 on 500 m2 (10 kW) cannot hold 20 degC at -5 degC against 17.5 kW of loss, one of
    50 W/m2 can; without the surface the year is refused, naming the key."""
    path = tmp_path / "per_m2.yaml"
    data = {"service": ALWAYS, "set_point_C": 20, "heating_limit_W_per_m2": 20}
    path.write_text(yaml.safe_dump(data))
    weak = energy.load_profile(path)
    year = constant_year(-5.0)
    r = energy.annual_energy(vehicle(), year, weak, dt_s=3600.0, draws=0, surface_m2=500.0)
    assert r.peak_service_W[0, 0] == pytest.approx(10000.0) and r.unmet_h[0, 0] > 8000
    strong = replace(weak, heating_limit_W_per_m2=50.0)
    r = energy.annual_energy(vehicle(), year, strong, dt_s=3600.0, draws=0, surface_m2=500.0)
    assert r.peak_service_W[0, 0] == pytest.approx(17500.0) and r.unmet_h[0, 0] == 0
    with pytest.raises(ConfigError, match="surface_m2"):
        energy.annual_energy(vehicle(), year, weak, dt_s=3600.0, draws=0)


def test_a_kalman_fits_process_noise_widens_the_draws_not_the_central_year(tmp_path):
    """The same parameter draws with and without a diffusion on the states: the central year
    (no noise) is the same, the draws spread more, and a what-if stays paired (its
    difference's band narrower than the base's)."""

    def draw(n, rng):
        return {p: v * np.exp(rng.normal(0.0, 0.03, n)) for p, v in THETA.items()}

    plain = simulate.ParameterSet("car", "declared", SECOND, dict(THETA), draw=draw)
    noisy = simulate.ParameterSet(
        "car", "declared", SECOND, dict(THETA), draw=draw, sigma=np.array([2e-3, 1e-3])
    )
    year = weather.read_weather(GREENSBORO)
    prof = profile(tmp_path)
    what_if = [energy.parse_what_if("k=-10%")]
    kw = {"dt_s": 3600.0, "draws": 20, "seed": 5, "what_ifs": what_if}
    a = energy.annual_energy(plain, year, prof, **kw)
    b = energy.annual_energy(noisy, year, prof, **kw)
    assert b.energy_kWh[0, 0] == pytest.approx(a.energy_kWh[0, 0], rel=1e-12)
    assert np.std(b.energy_kWh[0, 1:]) > np.std(a.energy_kWh[0, 1:])
    lo, hi = b.difference(1)[1:]
    assert hi - lo < np.ptp(b.energy_kWh[0, 1:])


@pytest.mark.parametrize("mode", ["start", "ready_by"])
def test_the_compiled_year_is_the_year_stepped_run_by_run_in_numpy(tmp_path, mode):
    """The compiled loop (runs in blocks, vectorised over each block) gives every run and
    variant the same year, to rounding, as every run advanced together one numpy step at a
    time (benchmarks/energy_numpy_steps.py, which sums in another order): 142 runs, so
    blocks that end mid-variant, with process noise, a what-if, set-back and pre-heating."""
    import sys

    sys.path.insert(0, str(REPO / "benchmarks"))
    from energy_numpy_steps import numpy_heated_steps

    def draw(n, rng):
        return {p: v * np.exp(rng.normal(0.0, 0.05, n)) for p, v in THETA.items()}

    car = simulate.ParameterSet(
        "car", "declared", SECOND, dict(THETA), draw=draw, sigma=np.array([2e-3, 1e-3])
    )
    service = {"weekdays": [[6, 22]], "saturday": [[8, 20]]}
    prof = profile(
        tmp_path, service=service, set_back_C=8, preheat_h=2, preheat_mode=mode,
        heating_limit_W=24000,
    )  # fmt: skip
    kw = {"dt_s": 1800.0, "draws": 70, "seed": 3, "what_ifs": [energy.parse_what_if("k=-20%")]}
    year = weather.read_weather(SAND_POINT)
    a = energy.annual_energy(car, year, prof, **kw)
    b = energy.annual_energy(car, year, prof, **kw, kernel=numpy_heated_steps)
    names = ("monthly_kWh", "preheat_kWh", "peak_service_W", "peak_preheat_W", "unmet_h")
    for name in (*names, "envelope_kWh", "doors_kWh"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=1e-11, err_msg=name)
    assert a.energy_kWh.shape == (2, 71) and np.all(a.peak_preheat_W > 0)
    assert np.ptp(a.unmet_h) > 0  # a heater that some draws outgrow: the sums differ by run


def _write_year(kind: str, path: Path, T_o, ghi) -> weather.Weather:
    """A year written as an EPW or a PVGIS TMY CSV at Sand Point (the layouts those services
    publish: EPW's hour N ending at N:00 local standard time, PVGIS's stamps in UTC), the
    value of each record ``T_o(h)`` and ``ghi(h)`` of the local instant it describes (hours
    from 00:00 of 1 January, local standard time), then read back."""
    stamps = pd.date_range("2005-01-01 00:00", periods=8760, freq="h")
    # EPW's hour ts.hour + 1 ends an hour after ts; PVGIS's UTC stamp is 11 h ahead of Sand
    # Point's zone (longitude -160.5: UTC - 11 h)
    offset = 1 if kind == "epw" else -11
    at = [int((ts - stamps[0]) / pd.Timedelta(hours=1) + offset) % 8760 for ts in stamps]
    if kind == "epw":
        lines = [
            "LOCATION,Sand Point,AK,USA,TMY3,703165,55.32,-160.52,-9.0,7.0",
            "DESIGN CONDITIONS,0",
            "TYPICAL/EXTREME PERIODS,0",
            "GROUND TEMPERATURES,0",
            "HOLIDAYS/DAYLIGHT SAVINGS,No,0,0,0",
            "COMMENTS 1,test",
            "COMMENTS 2,test",
            "DATA PERIODS,1,1,Data,Sunday, 1/ 1,12/31",
        ]
        flags = "?9?9?9?9E0?9?9?9?9?9?9?9?9?9?9?9?9?9?9?9*9*9?9?9?9"
        for i, ts in enumerate(stamps):
            rest = "0,0,0,0,0,0,180,2.0,10,10,9999,77777,9,999999999,0,0.0,0,88,0.0,0.0,0.0"
            lines.append(
                f"2005,{ts.month},{ts.day},{ts.hour + 1},60,{flags},{T_o(at[i]):.1f},0.0,80,"
                f"101000,0,1415,300,{ghi(at[i]):.0f},{rest}"
            )
    else:
        lines = [
            "Latitude (decimal degrees): 55.317",
            "Longitude (decimal degrees): -160.517",
            "Elevation (m): 7.0",
            "month,year",
            *(f"{m},2005" for m in range(1, 13)),
            "time(UTC),T2m,RH,G(h),Gb(n),Gd(h),IR(h),WS10m,WD10m,SP",
            *(
                f"{ts:%Y%m%d:%H%M},{T_o(at[i]):.2f},80,{ghi(at[i]):.0f},0,0,300,2,180,101000"
                for i, ts in enumerate(stamps)
            ),
            "T2m: 2-m air temperature (degree Celsius)",
        ]
    path.write_text("\n".join(lines) + "\n")
    return weather.read_weather(path)


def _sand_point_as(kind: str, path: Path) -> weather.Weather:
    """Sand Point's TMY3 year written as an EPW or a PVGIS TMY, each value at its instant."""
    year = weather.read_weather(SAND_POINT)

    def at(values):
        return lambda h: values[np.searchsorted(year.t_s, h * 3600.0)]

    return _write_year(kind, path, at(year.T_o), at(year.ghi))


WARM_HOUR = (165 * 24 + 13) * 3600.0  # 15 June, 13:00 local standard time


@pytest.mark.parametrize("kind", ["tmy3", "epw", "pvgis"])
def test_one_warm_hour_lands_on_the_hour_it_describes(tmp_path, kind):
    """A year at -5 degC but for the value describing 15 June 13:00 (local standard time),
    at 20 degC: written as each service stamps it (TMY3 at the end of the hour, local; EPW
    hour 13 of the day; PVGIS at 00:00 UTC of 16 June for Sand Point's UTC - 11 h), the
    warmth is at 13:00 on the simulation grid, and an hour either side it is gone."""
    if kind == "tmy3":
        lines = SAND_POINT.read_text().splitlines()
        header = lines[1].split(",")
        column = header.index("Dry-bulb (C)")
        for i in range(2, len(lines)):
            fields = lines[i].split(",")
            warm = fields[0].startswith("06/15/") and fields[1] == "13:00"
            fields[column] = "20.0" if warm else "-5.0"
            lines[i] = ",".join(fields)
        path = tmp_path / "warm.csv"
        path.write_text("\n".join(lines) + "\n")
        year = weather.read_weather(path)
    else:
        warm = round(WARM_HOUR / 3600.0)
        name = "warm.epw" if kind == "epw" else "warm_pvgis.csv"
        year = _write_year(
            kind, tmp_path / name, lambda h: 20.0 if h == warm else -5.0, lambda h: 0.0
        )
    t, T_o, _ = weather.on_grid(year, 60.0)
    at = int(WARM_HOUR / 60.0)
    assert T_o[at] == pytest.approx(20.0) and float(t[np.argmax(T_o)]) == WARM_HOUR
    assert T_o[at - 60] == pytest.approx(-5.0) and T_o[at + 60] == pytest.approx(-5.0)


@pytest.mark.parametrize(("kind", "name"), [("epw", "sand.epw"), ("pvgis", "sand_pvgis.csv")])
def test_epw_and_pvgis_years_are_read_as_published(tmp_path, kind, name):
    year = _sand_point_as(kind, tmp_path / name)
    reference = weather.read_weather(SAND_POINT)
    assert year.hours == 8760 and year.latitude == pytest.approx(55.3, abs=0.05)
    assert year.T_o == pytest.approx(np.round(reference.T_o, 1), abs=0.01)
    assert year.ghi == pytest.approx(reference.ghi, abs=0.5)


def test_ready_by_preheating_starts_late_enough_and_no_later(tmp_path):
    """Pre-heating 'ready by' the service start costs less than starting 4 h before and
    still has the air at the set point when service starts (no unmet hour); with too weak a
    heater for the lead it cannot, and the unmet hours say so."""
    year = weather.read_weather(SAND_POINT)
    common = {"service": {"weekdays": [[6, 22]]}, "set_back_C": 8, "preheat_h": 4}
    early = profile(tmp_path, **common, heating_limit_W=30000)
    late = profile(tmp_path, **common, heating_limit_W=30000, preheat_mode="ready_by")
    a = energy.annual_energy(vehicle(), year, early, dt_s=300.0, draws=0)
    b = energy.annual_energy(vehicle(), year, late, dt_s=300.0, draws=0)
    assert b.preheat_kWh[0, 0] < 0.8 * a.preheat_kWh[0, 0]
    assert b.energy_kWh[0, 0] < a.energy_kWh[0, 0]
    assert a.unmet_h[0, 0] == 0 and b.unmet_h[0, 0] == 0
    weak = profile(tmp_path, **common, heating_limit_W=16000, preheat_mode="ready_by")
    assert energy.annual_energy(vehicle(), year, weak, dt_s=300.0, draws=0).unmet_h[0, 0] > 0


@pytest.mark.parametrize("change", ["set_back=12", "set_back=off", "preheat_h=2"])
def test_a_what_if_is_the_year_of_the_profile_it_describes(tmp_path, change):
    """A what-if on the operating profile (set-back, pre-heating) gives, on the same draws,
    the very year of a base profile written with that change - also while a 'ready by' run
    waits set back for its start."""
    year = weather.read_weather(SAND_POINT)
    common = {"service": {"weekdays": [[6, 22]]}, "preheat_h": 4, "preheat_mode": "ready_by"}
    base = profile(tmp_path, **common, set_back_C=8, heating_limit_W=30000)
    what_if = energy.parse_what_if(change)
    as_written = profile(tmp_path, **{**common, "set_back_C": 8, "heating_limit_W": 30000,
                                      **what_if.profile})  # fmt: skip
    kw = {"dt_s": 600.0, "draws": 3, "seed": 2}
    paired = energy.annual_energy(vehicle(), year, base, what_ifs=[what_if], **kw)
    alone = energy.annual_energy(vehicle(), year, as_written, **kw)
    names = ("energy_kWh", "preheat_kWh", "peak_service_W", "peak_preheat_W", "design_load_W")
    for name in (*names, "unmet_h"):
        np.testing.assert_allclose(getattr(paired, name)[1], getattr(alone, name)[0], rtol=1e-12)
    assert not np.allclose(paired.preheat_kWh[1], paired.preheat_kWh[0])


def test_the_peaks_in_and_out_of_service_and_the_design_load(tmp_path):
    """Set back at night and pre-heated at the heater's limit, a 700 W/K car peaks at the
    limit outside service and below it in service; its design load is kA (T_set - T_d) at the
    year's 99.6 % dry-bulb T_d (0.4 % of the hours colder), exactly."""
    year = weather.read_weather(SAND_POINT)
    common = {"service": {"weekdays": [[6, 22]]}, "preheat_h": 2, "set_back_C": 5}
    result = energy.annual_energy(
        vehicle(), year, profile(tmp_path, **common, heating_limit_W=60000), dt_s=600.0, draws=20
    )
    colder = np.mean(year.T_o < result.design_T_o_C)
    assert colder <= 0.004 < np.mean(year.T_o <= result.design_T_o_C)
    assert result.peak_preheat_W[0, 0] == pytest.approx(60000.0)
    assert 0 < result.peak_service_W[0, 0] < 60000.0
    kA = THETA["kA"]
    T_set = profile(tmp_path, **common).set_point_C
    assert result.design_load_W[0, 0] == pytest.approx(kA * (T_set - result.design_T_o_C))


def test_a_csv_year_at_ten_minutes_is_read_and_one_off_the_year_refused(tmp_path):
    """A plain CSV at a 10-minute step over a year is read (hourly or finer); the same
    missing its last record is refused naming the records."""
    stamps = pd.date_range("2001-01-01 00:00", periods=8760 * 6, freq="10min")
    T_o = 5.0 + 10.0 * np.sin(2 * np.pi * np.arange(len(stamps)) / (8760 * 6))
    table = pd.DataFrame({"time": stamps.strftime("%Y-%m-%dT%H:%M:%S"), "T_o": T_o})
    path = tmp_path / "year.csv"
    table.to_csv(path, index=False)
    year = weather.read_weather(path)
    assert year.step_s == 600 and year.hours == 8760
    t, grid, _ = weather.on_grid(year, 300.0)
    assert len(t) == 8760 * 12 and grid[1] == pytest.approx((T_o[0] + T_o[1]) / 2)
    table.iloc[:-1].to_csv(path, index=False)
    with pytest.raises(ConfigError, match="'records'"):
        weather.read_weather(path)


def test_the_study_files_give_a_row_per_vehicle_climate_and_variant(
    campaign_study, fit_files, tmp_path
):
    """vehicle_energy and study_table read what rules energy and energy_table give them: an
    acceptable fit in both shipped years, the base and the what-if each a row under the
    vehicle's profile, the what-if's paired difference beside it; a fit in doubt (Metro3's
    second order) gives none."""
    _, _, study = campaign_study
    vids = ["Metro2", "Metro3"]
    fits = [str(fit_files(vid, "order2")[0]) for vid in vids]
    profile_file = str(REPO / "config" / "profiles" / "metro_service.yaml")
    tables = []
    for i, vid in enumerate(vids):
        part = energy.vehicle_energy(
            vid,
            study.vehicles[vid].data,
            [fits[i]],
            [str(SAND_POINT), str(GREENSBORO)],
            profile_file,
            ["k=-10%"],
            index=i,
            dt_s=3600.0,
            draws=4,
            seed=1,
        )
        part.to_csv(tmp_path / f"{vid}.csv", index=False)
        tables.append(str(tmp_path / f"{vid}.csv"))
    table = energy.study_table(tables, fits, vids)
    assert set(table["profile"]) == {"metro_service"}
    assert list(table["vehicle"].unique()) == ["Metro2"]
    # the vehicle left out is named with its verdict (before: absent without a word)
    assert list(table.attrs["verdicts"]) == ["Metro3"]
    csv, md = tmp_path / "energy.csv", tmp_path / "energy.md"
    profile = energy.load_profile(profile_file)
    energy.write_study_energy(table, [profile], 3600.0, "test", csv, md, str(tmp_path / "f"))
    left = f"without an acceptable fit of any order: Metro3 ({table.attrs['verdicts']['Metro3']})"
    assert left in md.read_text(encoding="utf-8")
    assert list(zip(table["climate"], table["variant"], strict=True)) == [
        ("Sand Point", "base"),
        ("Sand Point", "k -10 %"),
        ("Greensboro Piedmont Triad Int", "base"),
        ("Greensboro Piedmont Triad Int", "k -10 %"),
    ]
    saving = table.iloc[1]["difference_kWh"]
    assert saving == pytest.approx(table.iloc[1]["energy_kWh"] - table.iloc[0]["energy_kWh"])
    assert saving < 0 and table["energy_kWh"].iloc[0] > table["energy_kWh"].iloc[2]
    # the design load with a band from the fit's draws; Metro2's service never saturates the
    # 40 kW heater, the pre-heat from the set-back does
    base = table.iloc[0]
    assert 0 < base["design_load_W_lo"] < base["design_load_W_hi"] < 40000.0
    assert base["peak_service_W"] < base["peak_preheat_W"] == pytest.approx(40000.0)


def test_a_vehicle_whose_first_order_fit_alone_is_acceptable_gets_its_row(fit_files):
    """Metro3's second-order fit is in doubt, its first-order fit acceptable: given both,
    the second order listed first, the study's table has Metro3's rows from the first-order
    model and says so."""
    from railtherm.study.fit import read_fit
    from railtherm.study.quality import ACCEPTABLE

    second, first = (str(fit_files("Metro3", key)[0]) for key in ("order2", "order1"))
    assert read_fit(second).verdict != ACCEPTABLE == read_fit(first).verdict
    table = energy.vehicle_energy(
        "Metro3",
        {"class": "metro"},
        [second, first],
        [str(SAND_POINT)],
        str(REPO / "config" / "profiles" / "metro_service.yaml"),
        dt_s=3600.0,
        draws=0,
    )
    assert list(table["vehicle"]) == ["Metro3"] and list(table["model"]) == ["order1"]
    assert table["energy_kWh"].iloc[0] > 0


@pytest.mark.parametrize("command", ["energy", "simulate"])
@pytest.mark.parametrize("draws", [1, 5, 39])
@pytest.mark.bad_input
def test_too_few_draws_for_a_95_percent_band_are_refused(fit_files, capsys, command, draws):
    """The range of n draws holds a further draw with probability (n - 1)/(n + 1): under 40
    draws a "95 % band" is none (before: 5 draws printed 50,690 [50,842, 52,015] kWh, the
    central value outside its band). 0 (the central run alone) and 40 run."""
    from railtherm.cli import main

    fit, _ = fit_files("Metro2", "order2")
    args = [command, str(fit), "--draws", str(draws)]
    if command == "energy":
        args += [
            "--weather",
            str(SAND_POINT),
            "--profile",
            str(REPO / "config/profiles/metro_service.yaml"),
        ]
    else:
        args += ["--scenario", str(REPO / "config/scenarios/preheat_cold_soak.yaml")]
    assert main(args) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err and f"'draws' = {draws}" in err and "at least 40" in err, err


def test_the_monthly_figure_draws_a_band_wherever_its_central_bar_ends():
    """A band that does not hold its central value (a posterior whose medians lie off its
    draws' outcomes) is drawn as it is; before, matplotlib refused negative error bars and
    `railtherm energy --out` stopped after writing the table."""
    from railtherm.report import plots

    row = dict.fromkeys(energy.study_columns(), 0.0)
    row.update(vehicle="V", climate="C", variant="base", source="synthetic")
    for m in energy.MONTHS:
        row.update({f"{m}_kWh": 1000.0, f"{m}_lo": 1100.0, f"{m}_hi": 1300.0})
    figure = plots.annual_energy_figure(pd.DataFrame([row]))
    ax = figure.axes[0]
    (lines,) = ax.collections
    spans = np.array([seg[:, 1] for seg in lines.get_segments()])
    np.testing.assert_allclose(spans, [[1.1, 1.3]] * 12)  # MWh, the band, not the bar


def test_the_year_says_what_its_centre_rests_on_and_which_draws_it_replaced(fit_files):
    """A volume whose air holds more than the fit's central C: the note says so, and the
    share of draws replaced at the air's capacity is counted (before: bands silently all
    above the centre); the first line names what the draws carry."""
    fit, _ = fit_files("Metro2", "order2")
    params = simulate.load_parameters(fit)
    year = weather.read_weather(SAND_POINT)
    profile = energy.load_profile(REPO / "config/profiles/metro_service.yaml")
    C = params.theta["C"]
    volume = 1.001 * C / simulate.air_capacity(1.0)  # the air alone just above the fit's C
    result = energy.annual_energy(params, year, profile, dt_s=3600.0, draws=40, volume_m3=volume)
    text = energy.markdown(result)
    assert f"the central C = {C:.4g} J/K is below the capacity of the air" in text
    assert re.search(r"of the parameter draws \(\d+ of \d+\) lay beyond the physical limits", text)
    assert result.rejected > 0 and "parameter covariance (statistical)" in text.splitlines()[0]


@pytest.mark.bad_input
def test_an_epw_year_with_its_missing_marker_names_the_record(tmp_path):
    """EPW writes 99.9 for a dry-bulb temperature it lacks: the year stops at that record as
    missing, not as a year in degF (before: "read as degF they are mean -15.3 ... check the
    unit")."""
    with pytest.raises(ConfigError) as caught:
        _write_year("epw", tmp_path / "gap.epw", lambda h: 99.9 if h == 100 else -5.0, lambda h: 0)
    text = str(caught.value)
    assert "gap.epw" in text and "= 99.9" in text and "EPW's marker 99.9" in text, text
    assert "degF" not in text


def test_a_surface_the_profile_does_not_use_is_said_to_be_unused(fit_files, capsys):
    """metro_service gives its heater in W: --surface-m2 changes nothing, and the command
    says so (before, it was silently ignored)."""
    from railtherm.cli import main

    fit, _ = fit_files("Metro2", "order2")
    args = ["energy", str(fit), "--weather", str(SAND_POINT), "--draws", "0", "--step-s", "3600"]
    args += ["--profile", str(REPO / "config/profiles/metro_service.yaml")]
    assert main([*args, "--surface-m2", "1"]) == 0
    err = capsys.readouterr().err
    assert "--surface-m2 is not used: profile metro_service gives its heating limit in W" in err


def test_a_class_reference_models_table_names_its_class(tmp_path, capsys):
    """``railtherm energy REF --out DIR`` on a class reference model: a profile's heater per m²
    is sized by the surface the model was built for (it asked for --surface-m2 again), a
    different --surface-m2 is refused, and the table's class column says the class (it was
    left empty)."""
    from railtherm.cli import main

    ref = tmp_path / "regional.yaml"
    argv = ["reference", "--class", "regional", "--mass-kg", "45000", "--surface-m2", "400"]
    assert main([*argv, "-d", str(REPO), "--out", str(ref)]) == 0
    out = tmp_path / "out"
    args = ["energy", str(ref), "--weather", str(SAND_POINT), "--profile"]
    args += [str(REPO / "config" / "profiles" / "classes" / "regional.yaml")]
    args += ["--step-s", "3600", "--draws", "0"]
    assert main([*args, "--surface-m2", "250"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("--surface-m2: key 'surface_m2' = 250") and "built for 400 m²" in err
    assert main([*args, "--surface-m2", "400"]) == 0
    explicit = capsys.readouterr().out
    assert main([*args, "--out", str(out)]) == 0
    assert capsys.readouterr().out == explicit
    table = pd.read_csv(out / "energy.csv", keep_default_na=False)
    assert list(table["class"]) == ["regional"]
