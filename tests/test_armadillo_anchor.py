"""The Armadillo anchor as published: the validation study fits pySIP's 232 rows (the record's
last row, a +0.84 K glitch that pySIP's analysis leaves out, ends outside the window) and
reproduces pySIP's published TwTi_RoRi fit; the all-rows fit beside it names the glitch among
its outlying samples; reference files carry a published uncertainty that the comparison uses.

pySIP's values are an anchor the project did not make: data/armadillo/README.md, as published
and as pySIP's own re-run printed them (benchmarks/pysip_armadillo_results.txt)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from chain import checked_fits

from railtherm import config
from railtherm.errors import ConfigError
from railtherm.estimation import outliers
from railtherm.records import FitRecord
from railtherm.study import reference

REPO = Path(__file__).resolve().parents[1]
VALIDATION = REPO / "validation"
VEHICLES = VALIDATION / "config" / "vehicles"
PUBLISHED = VALIDATION / "config" / "published"
RAW = REPO / "data" / "armadillo" / "armadillo_data_H2.csv"

# pySIP's TwTi_RoRi fit of the Armadillo record (first-order hold, 232 rows):
# data/armadillo/README.md as published, and its re-run's printed digits
PYSIP_PUBLISHED = {"R_o": 0.01759, "R_i": 0.001984, "C_w": 1.47e7, "C_i": 1.64e6}
PYSIP_RERUN = {"R_o": 0.017567, "R_i": 0.0019846, "C_w": 1.4638e7, "C_i": 1.6344e6}
PYSIP_SD = {"R_o": 9.3e-4, "R_i": 7.5e-5}
GLITCH_TIME = 417600.0


def pysip_terms(fit: dict) -> dict[str, float]:
    """A fit file's interior-envelope parameters in pySIP's names."""
    p = fit["parameters"]
    return {
        "R_o": 1.0 / p["K_o"]["value"],
        "R_i": 1.0 / p["K_i"]["value"],
        "C_w": p["C_e"]["value"],
        "C_i": p["C"]["value"],
    }


@pytest.fixture(scope="module")
def pysip_rows():
    """The validation study's Armadillo vehicle (pySIP's rows): its Kalman fit."""
    return checked_fits(VEHICLES / "Armadillo.yaml", ["interior_envelope_kalman"])


@pytest.fixture(scope="module")
def all_rows():
    """The validation study's Armadillo_all_rows vehicle: both estimators."""
    return checked_fits(
        VEHICLES / "Armadillo_all_rows.yaml", ["interior_envelope_kalman", "interior_envelope"]
    )


def test_the_study_fits_pysips_rows_without_touching_the_raw_file(pysip_rows, all_rows):
    """The window ends a step before the last row; the raw file keeps all 233 rows."""
    raw = pd.read_csv(RAW)
    assert len(raw) == 233 and raw["Time"].iloc[-1] == GLITCH_TIME
    fit = pysip_rows.fits["interior_envelope_kalman"].to_dict()
    assert fit["rows"] == {"h2": {"rows": 232, "used": {"T": 232}}}
    assert pysip_rows.tables["h2"]["time"].max() == GLITCH_TIME - 1800.0
    assert all_rows.fits["interior_envelope_kalman"].content["rows"]["h2"]["rows"] == 233
    # the glitch: the last sample 0.84 K above the one before, the heating off
    assert raw["T_int"].iloc[-1] - raw["T_int"].iloc[-2] == pytest.approx(0.84, abs=0.01)
    assert raw["P_hea"].iloc[-1] == 0.0


@pytest.mark.parametrize(
    ("anchor", "values"), [("published", PYSIP_PUBLISHED), ("re-run", PYSIP_RERUN)]
)
def test_kalman_fit_on_pysips_rows_is_within_half_a_percent_of_pysip(pysip_rows, anchor, values):
    """Armadillo.yaml's Kalman fit (first-order hold, 232 rows), as the validation study makes
    it: R_o, R_i, C_w and C_i each within 0.5 % of pySIP's."""
    fit = pysip_rows.fits["interior_envelope_kalman"].to_dict()
    assert fit["input_hold"] == "first_order" and fit["estimator"] == "kalman"
    got = pysip_terms(fit)
    for name, value in values.items():
        assert got[name] == pytest.approx(value, rel=0.005), (anchor, name, got[name])


def test_all_rows_kalman_fit_misses_pysip_by_the_glitch(all_rows, pysip_rows):
    """With the glitch row the outdoor resistance moves by more than 4 % (the difference the
    two fits' rows make, not a difference of the tools)."""
    got = pysip_terms(all_rows.fits["interior_envelope_kalman"].content)
    assert got["R_o"] / PYSIP_PUBLISHED["R_o"] - 1 > 0.04
    same = pysip_terms(pysip_rows.fits["interior_envelope_kalman"].content)
    assert abs(same["R_o"] / PYSIP_PUBLISHED["R_o"] - 1) < 0.005


@pytest.mark.parametrize(
    ("model", "statistic"),
    [
        ("interior_envelope_kalman", "standardized innovation"),
        ("interior_envelope", "standardized residual"),
    ],
)
def test_the_glitch_row_is_named_by_the_innovations(all_rows, model, statistic):
    """All 233 rows: the last sample's standardized innovation (Kalman) or residual (output
    error) lies beyond the Bonferroni threshold over the record, and the fit's notes name it."""
    fit = all_rows.fits[model].to_dict()
    found = fit["outliers"]["T"]
    assert found["statistic"] == statistic and found["n"] == 233
    assert found["threshold"] == pytest.approx(outliers.bonferroni_threshold(233, 0.05))
    glitch = [s for s in found["samples"] if s["time"] == GLITCH_TIME]
    assert len(glitch) == 1 and glitch[0]["z"] > found["threshold"]
    note = [n for n in fit["notes"] if "t = 417600 s" in n]
    assert len(note) == 1 and statistic in note[0] and "Bonferroni over 233 samples" in note[0]
    assert fit["verdict"]  # reported, the verdict judged as before


def test_railtherm_fit_prints_the_outlying_samples(capsys):
    """The fit's text (``railtherm fit``): the glitch row under the verdict's reasons."""
    from railtherm.cli import main

    args = ["fit", "config/vehicles/Armadillo_all_rows.yaml", "--model", "interior_envelope"]
    assert main([*args, "-d", str(VALIDATION)]) == 0
    out = capsys.readouterr().out
    line = [x for x in out.splitlines() if "t = 417600 s" in x]
    assert len(line) == 1 and line[0].startswith("  ! T sample at t = 417600 s (window h2)")
    assert "standardized residual +5.0" in line[0] and "Bonferroni over 233 samples" in line[0]


def test_the_glitch_is_the_kalman_fits_largest_innovation(all_rows):
    """An innovation of about 11 standard deviations: no other sample comes near it."""
    found = all_rows.fits["interior_envelope_kalman"].content["outliers"]["T"]
    z = sorted(found["samples"], key=lambda s: -abs(s["z"]))
    assert z[0]["time"] == GLITCH_TIME and z[0]["z"] > 8.0
    assert all(abs(s["z"]) < 0.6 * z[0]["z"] for s in z[1:])


def test_bonferroni_threshold_is_the_normal_quantile_at_alpha_over_n():
    """z* = Phi^-1(1 - alpha / (2 N)): 1.96 for one sample at 5 %, 3.70 for 232."""
    assert outliers.bonferroni_threshold(1, 0.05) == pytest.approx(1.959964, abs=1e-6)
    assert outliers.bonferroni_threshold(232, 0.05) == pytest.approx(3.7001, abs=1e-4)
    with pytest.raises(ValueError, match="not a probability"):
        outliers.bonferroni_threshold(10, 1.5)


def test_records_the_model_describes_show_an_outlier_at_most_alpha_of_the_time():
    """The family-wise false-alarm rate on white N(0, 1) records of the Armadillo's length and
    on strongly autocorrelated ones (an AR(1), phi 0.9, scaled to unit variance): at most
    alpha = 5 % (2000 records each, binomial sd 0.5 %); Bonferroni holds whatever the
    dependence, so the coloured residuals of an output-error fit are covered too."""
    rng = np.random.default_rng(43)
    n, records = 233, 2000
    white = rng.standard_normal((records, n))
    e = rng.standard_normal((records, n)) * np.sqrt(1 - 0.9**2)
    ar = np.empty_like(e)
    ar[:, 0] = rng.standard_normal(records)
    for t in range(1, n):
        ar[:, t] = 0.9 * ar[:, t - 1] + e[:, t]
    times, windows = np.arange(n) * 1800.0, ["w"] * n
    for z in (white, ar):
        alarms = [
            bool(outliers.outlying_samples("T", row, times, windows, "kalman").samples) for row in z
        ]
        assert np.mean(alarms) <= 0.05 + 2 * 0.005


def test_samples_not_measured_are_not_tested():
    z = np.array([0.1, np.nan, 9.0, -0.3])
    found = outliers.outlying_samples("T", z, [0, 1, 2, 3], ["a"] * 4, "output_error")
    assert found.n == 3
    assert [s["time"] for s in found.samples] == [2.0]
    assert "standardized residual +9.0" in found.texts()[0]


# --- published uncertainties ----------------------------------------------------------------


def test_published_uncertainty_is_parsed_and_carried_to_the_conductance():
    ref = reference.load_reference(PUBLISHED / "pysip_armadillo_kalman.yaml")
    assert reference.published_parameters(ref)["K_o"] == pytest.approx(1 / 0.01759)
    sd = reference.published_sd_log(ref)
    assert set(sd) == {"K_o", "K_i"}  # C_w and C_i are published without one
    assert sd["K_o"] == pytest.approx(PYSIP_SD["R_o"] / PYSIP_PUBLISHED["R_o"])
    assert sd["K_i"] == pytest.approx(PYSIP_SD["R_i"] / PYSIP_PUBLISHED["R_i"])


def test_comparison_uses_the_published_uncertainty(pysip_rows, all_rows):
    """z of the difference with both standard uncertainties (the logarithms, railtherm's
    statistical sd): within the uncertainties on pySIP's rows; the published sd is written
    in the row's unit."""
    ref = reference.load_reference(PUBLISHED / "pysip_armadillo_kalman.yaml")
    fit = pysip_rows.fits["interior_envelope_kalman"].to_dict()
    windows = {"h2": pysip_rows.tables["h2"]}
    table = reference.compare(ref, FitRecord.from_dict(fit), windows, pysip_rows.vehicle.data)
    table = table.set_index("quantity")
    K_o = fit["parameters"]["K_o"]
    sd_pub = PYSIP_SD["R_o"] / PYSIP_PUBLISHED["R_o"]
    expected = np.log(K_o["value"] * PYSIP_PUBLISHED["R_o"]) / np.hypot(K_o["sd_log"], sd_pub)
    assert table.loc["K_o", "z"] == pytest.approx(expected)
    assert table.loc["K_o", "published_sd"] == pytest.approx(sd_pub / PYSIP_PUBLISHED["R_o"])
    assert abs(table.loc["K_o", "z"]) < 0.1 and abs(table.loc["K_i", "z"]) < 0.1
    assert np.isnan(table.loc["C", "z"]) and np.isnan(table.loc["C", "published_sd"])
    assert table.loc["K_o", "rows"] == 232
    md = reference.markdown(table.reset_index(), [ref], "measured", [FitRecord.from_dict(fit)])
    assert f"| K_o | W/K | 56.85 ± {56.85 * sd_pub:.4g} |" in md
    assert "railtherm's fit used 232 rows" in md


def test_a_published_kA_with_its_uncertainty(pysip_rows, tmp_path):
    """A publication that prints kA = 3.96 ± 0.14 W/K: the kA row's z uses that sd."""
    data = yaml.safe_load((PUBLISHED / "pysip_armadillo_kalman.yaml").read_text())
    data["parameters"] = {"kA": {"value": 51.0, "sd": 1.5}}
    path = tmp_path / "ref.yaml"
    path.write_text(yaml.safe_dump(data))
    ref = reference.load_reference(path)
    fit = pysip_rows.fits["interior_envelope_kalman"].to_dict()
    table = reference.compare(
        ref, FitRecord.from_dict(fit), {"h2": pysip_rows.tables["h2"]}, pysip_rows.vehicle.data
    )
    row = table.set_index("quantity").loc["kA"]
    kA = fit["parameters"]["kA"]
    expected = np.log(kA["value"] / 51.0) / np.hypot(kA["sd_log_total"], 1.5 / 51.0)
    assert row["published_sd"] == pytest.approx(1.5) and row["z"] == pytest.approx(expected)


def test_committed_reference_table_shows_both_fits_and_names_the_glitch():
    """The validation study's committed reference table: pySIP's rows and all rows, each
    beside pySIP, the all-rows section naming the last row."""
    table = pd.read_csv(VALIDATION / "results" / "tables" / "reference.csv")
    kalman = table[table["model"] == "interior_envelope_kalman"].set_index(["vehicle", "quantity"])
    assert kalman.loc[("Armadillo", "K_o"), "rows"] == 232
    assert kalman.loc[("Armadillo_all_rows", "K_o"), "rows"] == 233
    for q in ("K_o", "K_i", "C_e", "C"):
        assert abs(kalman.loc[("Armadillo", q), "ratio"] - 1) < 0.005, q
    assert np.isfinite(kalman.loc[("Armadillo", "K_o"), "z"])
    md = (VALIDATION / "results" / "tables" / "reference.md").read_text(encoding="utf-8")
    section = md.split("### Armadillo_all_rows, interior_envelope_kalman", 1)[1].split("###")[0]
    assert "t = 417600 s: +11" in section
    pysip = md.split("### Armadillo, interior_envelope_kalman", 1)[1].split("###")[0]
    assert "417600" not in pysip and "232 rows" in pysip


@pytest.mark.bad_input
@pytest.mark.parametrize(
    ("entry", "key", "why"),
    [
        ({"value": 0.01759, "sd": -9.3e-4}, "parameters.R_o.sd", "must be > 0"),
        ({"value": 0.01759, "sd": 0.0}, "parameters.R_o.sd", "must be > 0"),
        ({"value": 0.01759, "sd": "0.93e-3 K/W"}, "parameters.R_o.sd", "must be a number"),
        ({"value": 0.01759, "sd": float("nan")}, "parameters.R_o.sd", "not a finite number"),
        ({"value": 0.01759, "sd": float("inf")}, "parameters.R_o.sd", "not a finite number"),
        ({"value": 0.01759}, "parameters.R_o.sd", "missing required key"),
        ({"value": 0.01759, "sd": 9.3e-4, "sd95": 1e-3}, "parameters.R_o.sd95", "unknown key"),
    ],
)
def test_a_bad_published_uncertainty_is_refused_naming_file_and_key(tmp_path, entry, key, why):
    data = yaml.safe_load((PUBLISHED / "pysip_armadillo_kalman.yaml").read_text())
    data["parameters"]["R_o"] = entry
    path = tmp_path / "ref.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError) as err:
        reference.load_reference(path)
    message = str(err.value)
    assert str(path) in message and key in message and why in message, message


@pytest.mark.bad_input
def test_a_bad_outlier_level_is_refused_naming_the_key(tmp_path):
    data = yaml.safe_load((VEHICLES / "Armadillo.yaml").read_text())
    data["raw_files"] = {"h2": str(RAW)}
    data["check"] = {"outlier_alpha": 1.5}
    path = tmp_path / "Box.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError) as err:
        config.load_vehicle(path)
    assert "check.outlier_alpha" in str(err.value) and "must be < 1" in str(err.value)
