"""The verdict's thresholds are settings: every threshold the verdict and its checks use is a
key of a vehicle's `check` section, with the climatic-wind-tunnel value as its default,
documented in the schema and docs/checks.md; the study's `defaults.check` is merged under each
vehicle's, the vehicle's own value wins, and an unknown key stops with a clear error."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from test_identify import TABLES, k_result, vehicle
from test_optional_metadata import armadillo_copy

from railtherm.cli import main
from railtherm.config import load_study, load_vehicle, section_defaults
from railtherm.errors import ConfigError, DataError
from railtherm.records import EstimateRecord
from railtherm.study import identify, quality
from railtherm.study.fit import read_fit
from railtherm.yamlio import packaged_schema

REPO = Path(__file__).resolve().parents[1]
CHECK = packaged_schema("vehicle")["properties"]["check"]["properties"]


# --- one list of thresholds, documented ---------------------------------------------------------


def test_the_verdicts_defaults_are_the_check_sections_defaults():
    for key, value in quality.DEFAULT_THRESHOLDS.items():
        assert key in CHECK, key
        assert CHECK[key]["default"] == value, key


def test_every_threshold_has_a_default_a_reason_and_a_line_in_the_docs():
    docs = (REPO / "docs" / "checks.md").read_text(encoding="utf-8")
    study = packaged_schema("study")["properties"]["defaults"]["properties"]["check"]
    for key, spec in CHECK.items():
        assert "default" in spec, key
        assert len(spec.get("description", "")) > 60, key  # a reason, not a label
        assert f"`{key}`" in docs, key
        assert key in study["description"], key


def test_every_threshold_the_code_reads_is_a_setting():
    """Whatever the verdict's code looks up in its thresholds is a key of the schema."""
    source = "".join(
        (REPO / "railtherm" / "study" / name).read_text(encoding="utf-8")
        for name in ("identify.py", "fitsettings.py", "quality.py")
    )
    read = set(re.findall(r'thresholds\["(\w+)"\]', source))
    read |= set(re.findall(r'get\("check"\) or \{\}\)\.get\("(\w+)"', source))
    assert read and read <= set(CHECK), read - set(CHECK)
    assert {"r2_min", "max_rmse_K", "k_range_W_m2K", "min_air_capacity_ratio"} <= read
    assert "min_used_share" in read


# --- study, vehicle, unknown keys ---------------------------------------------------------------


def study_with(tmp_path: Path, study_check: dict | None, vehicle_check: dict | None) -> Path:
    """A study config of the Armadillo copy with ``defaults.check`` and a vehicle ``check``."""
    path = armadillo_copy(tmp_path)
    if vehicle_check is not None:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
        data["check"] = vehicle_check
        path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    config = {"vehicles": ["config/vehicles/Armadillo.yaml"]}
    if study_check is not None:
        config["defaults"] = {"check": study_check}
    config_path = tmp_path / "config" / "config.yaml"
    config_path.write_text(yaml.safe_dump(config, sort_keys=False), encoding="utf-8")
    return config_path


def loaded_check(config_path: Path) -> dict:
    config = yaml.safe_load(config_path.read_text(encoding="utf-8"))
    study = load_study(config, workdir=config_path.parents[1])
    return study.vehicles["Armadillo"].data["check"]


def test_study_thresholds_apply_and_a_vehicles_own_value_wins(tmp_path):
    study = {"max_rmse_K": 1.0, "r2_min": 0.8, "require_white": True}
    check = loaded_check(study_with(tmp_path, study, {"r2_min": 0.95}))
    assert check["max_rmse_K"] == 1.0 and check["require_white"] is True  # the study's
    assert check["r2_min"] == 0.95  # the vehicle's own
    defaults = section_defaults("check")
    for key in set(CHECK) - {"max_rmse_K", "require_white", "r2_min"}:
        assert check[key] == defaults[key], key  # the wind-tunnel default
    assert loaded_check(study_with(tmp_path, None, None)) == defaults


@pytest.mark.bad_input
@pytest.mark.parametrize(
    ("study", "vehicle_", "file", "key", "hint"),
    [
        ({"max_rmse": 1.0}, None, "config/config.yaml", "defaults.check.max_rmse", "max_rmse_K"),
        (None, {"r2min": 0.8}, "config/vehicles/Armadillo.yaml", "check.r2min", "r2_min"),
        (None, {"alpha": 0.01}, "config/vehicles/Armadillo.yaml", "check.alpha", None),
    ],
)
def test_an_unknown_threshold_stops_with_the_file_the_key_and_the_known_ones(
    tmp_path, study, vehicle_, file, key, hint
):
    with pytest.raises(ConfigError) as info:
        loaded_check(study_with(tmp_path, study, vehicle_))
    message = str(info.value)
    assert message.startswith(f"{file}: key '{key}'") and "unknown key" in message
    assert "whiteness_alpha" in message  # the allowed keys are listed
    if hint:
        assert f"did you mean '{hint}'" in message


@pytest.mark.bad_input
@pytest.mark.parametrize(
    ("check", "key", "reason"),
    [
        ({"whiteness_alpha": 1.5}, "check.whiteness_alpha", "must be < 1"),
        ({"require_white": "yes"}, "check.require_white", "true or false"),
        ({"min_air_capacity_ratio": 0}, "check.min_air_capacity_ratio", "must be > 0"),
        (
            {"min_capacity_per_kg_J_kgK": 500, "max_capacity_per_kg_J_kgK": 400},
            "check.max_capacity_per_kg_J_kgK",
            "must be above check.min_capacity_per_kg_J_kgK = 500",
        ),
    ],
)
def test_a_bad_threshold_value_is_a_one_line_error(tmp_path, check, key, reason):
    path = armadillo_copy(tmp_path)
    data = yaml.safe_load(path.read_text(encoding="utf-8"))
    data["check"] = check
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        load_vehicle(path, workdir=tmp_path)
    assert info.value.key == key and reason in str(info.value)


def test_library_callers_get_the_defaults_and_the_same_unknown_key_error():
    assert quality.check_thresholds({}) == section_defaults("check")
    assert quality.check_thresholds({"r2_min": 0.5})["r2_min"] == 0.5
    with pytest.raises(ConfigError, match=r"key 'check.r2min' .*did you mean 'r2_min'"):
        quality.check_thresholds({"r2min": 0.5})
    with pytest.raises(ValueError, match=r"unknown verdict thresholds: \['alpha'\] \(known:"):
        quality.verdict(0.99, thresholds={"alpha": 0.05})


# --- each threshold moves the verdict -----------------------------------------------------------


@pytest.fixture(scope="module")
def exact():
    """A second-order fit of noise-free data (test_identify's vehicle, static k)."""
    return identify.identify(TABLES, vehicle(), k_result(), 2)


def with_residuals(estimate, series, e: np.ndarray):
    """The fit's series with ``e`` added to the measured T (the residuals then are ``e``)."""
    series = series.assign(T=series["T"] + e, T_residual=series["T_residual"] + e)
    return estimate, series


def reasons(estimate, series, **check) -> list[str]:
    return quality.check(estimate, series, check).content["reasons"]


def test_rmse_limit_and_r2_min(exact):
    estimate, series = exact
    e = np.random.default_rng(1).normal(0.0, 0.3, len(series))  # white, 0.3 K
    noisy = with_residuals(estimate, series, e)
    assert any("RMSE 0.3" in r and "twice a sensor's accuracy" in r for r in reasons(*noisy))
    field = reasons(*noisy, max_rmse_K=1.0)  # a field record's limit
    assert not any("RMSE" in r for r in field)
    tight = reasons(*noisy, max_rmse_K=0.25)
    assert any("more than 0.25 K, check.max_rmse_K" in r for r in tight)
    r2 = quality.check(*noisy, {}).content["R2"]
    assert not any("R^2" in r for r in field)
    assert any(
        f"below {r2 + 1e-4:g}" in r for r in reasons(*noisy, max_rmse_K=1.0, r2_min=r2 + 1e-4)
    )


def test_whiteness_is_judged_only_when_required_and_at_its_level(exact):
    estimate, series = exact
    # T_veh's residuals are round-off here
    estimate = EstimateRecord.from_dict({**estimate.content, "outputs": ["T"]})
    e = np.random.default_rng(3).normal(0.0, 0.05, len(series))  # white, within the limit
    white = with_residuals(estimate, series, e)
    p = quality.check(*white, {}).content["measures"]["T"]["overall"]["ljung_box_p"]
    assert 0.01 < p < 0.99
    assert reasons(*white) == []
    assert reasons(*white, require_white=True, whiteness_alpha=p / 2) == []
    judged = reasons(*white, require_white=True, whiteness_alpha=min(2 * p, 0.999))
    assert len(judged) == 1 and "(T) are not white" in judged[0]
    slow = 0.05 * np.sin(2 * np.pi * np.arange(len(series)) / 200.0)  # coloured, still small
    coloured = with_residuals(estimate, series, slow)
    assert reasons(*coloured) == []  # within the sensors' accuracy: not judged by colour
    assert any("not white" in r for r in reasons(*coloured, require_white=True))


def test_min_effective_samples(exact):
    estimate, series = exact
    slow = 0.5 * np.sin(2 * np.pi * np.arange(len(series)) / 400.0)  # a missed slow dynamic
    coloured = with_residuals(estimate, series, slow)
    assert any("strongly coloured" in r for r in reasons(*coloured))
    assert not any("strongly coloured" in r for r in reasons(*coloured, min_effective_samples=0.01))


def test_plausibility_thresholds(exact):
    estimate, series = exact  # k = 979.2 / 306 = 3.2; (1.8e7 + 1e7) / 30030 kg = 932 J/(kg K)
    assert reasons(estimate, series) == []
    assert any(
        "outside the physical range 0.1-1 W/(m² K)" in r
        for r in reasons(estimate, series, k_range_W_m2K=[0.1, 1.0])
    )
    assert any(
        "below 1000 J/(kg K)" in r
        for r in reasons(estimate, series, min_capacity_per_kg_J_kgK=1000)
    )
    assert any(
        "more than 900 J/(kg K) (check.max_capacity_per_kg_J_kgK)" in r
        for r in reasons(estimate, series, max_capacity_per_kg_J_kgK=900)
    )
    assert any(
        "below 200 times (check.min_air_capacity_ratio)" in r
        for r in reasons(estimate, series, min_air_capacity_ratio=200)
    )
    # K_veh = 974 W/K on 306 m2: 3.2 W/(m2 K), far below the default ceiling of 200
    assert any(
        "the conductance K_veh = 974 W/K is 3.183 W/(m² K)" in r and "more than 3 W/(m² K)" in r
        for r in reasons(estimate, series, max_conductance_per_area_W_m2K=3.0)
    )


def test_min_used_share():
    name = next(iter(TABLES))
    holes = {n: t.copy() for n, t in TABLES.items()}
    holes[name].loc[holes[name].index[:30], "T"] = np.nan  # 30 of 901 rows: 96.7 % measured
    identify.identify(holes, vehicle(), k_result(), 2)  # the default 0.95 lets it through
    strict = vehicle()
    strict["check"] = {"min_used_share": 0.99}
    with pytest.raises(DataError, match=r"less than check.min_used_share = 0.99"):
        identify.identify(holes, strict, k_result(), 2)


# --- end to end: a building record's limit for the whole study ---------------------------------


def test_railtherm_fit_takes_the_studys_limit_and_the_vehicles_own(tmp_path, capsys):
    """The Armadillo Box's interior-envelope model misses T by RMSE 0.21 K on all 233 rows
    (0.200 K on pySIP's 232, too near the limit to tell), only that: in doubt under the wind
    tunnel's 0.2 K, acceptable under a field record's 0.5 K set once for the study, in doubt
    again where the vehicle sets its own 0.2 K."""

    def verdict(study_check, vehicle_check) -> str:
        root = tmp_path / f"run{len(list(tmp_path.iterdir()))}"
        study_with(root, study_check, vehicle_check)
        vehicle = root / "config" / "vehicles" / "Armadillo.yaml"
        data = yaml.safe_load(vehicle.read_text(encoding="utf-8"))
        data["windows"]["identification"][0]["end"] = 417_600  # every row of the file
        vehicle.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
        args = ["fit", "config/vehicles/Armadillo.yaml", "--model", "interior_envelope"]
        assert main([*args, "--out", "out", "-d", str(root)]) == 0
        return read_fit(root / "out/vehicles/Armadillo/fit_interior_envelope.yaml").verdict

    assert verdict(None, None) == "assumptions in doubt"
    assert verdict({"max_rmse_K": 0.5}, None) == "fit acceptable"
    assert verdict({"max_rmse_K": 0.5}, {"max_rmse_K": 0.2}) == "assumptions in doubt"
