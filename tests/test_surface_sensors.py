"""Surface sensors as the measured envelope state of the interior-envelope structure
(``model.envelope_sensors: surface``, railtherm.study.fitsettings.envelope_tables): T_e compared in
eq. 17 like T_veh in eqs. 7-8, through the whole chain (raw file -> config -> cleaning -> PEM
fit), and the config's checks."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from cell_case import write_cell

from railtherm.config import load_vehicle
from railtherm.errors import ConfigError
from railtherm.estimation import models
from railtherm.study import fitsettings, identify
from railtherm.study.run import fit_vehicle, tidy_tables

TRUTH = {"C": 2.0e6, "K_i": 400.0, "C_e": 1.5e7, "K_o": 70.0}
DT = 1800.0
N = 240  # 5 days at 30 min
NOISE_K = 0.05


def write_case(root: Path, seed: int = 24) -> Path:
    """A raw file of the interior-envelope structure (T_o a daily sine, heating steps of
    0-2.2 kW held 4 h; the air and a wall surface sensor with 0.05 K noise) and a vehicle
    config that maps the wall sensor to channels.surface but leaves the envelope unmeasured;
    returns the config's path."""
    rng = np.random.default_rng(seed)
    t = np.arange(N) * DT
    T_o = 5.0 + 6.0 * np.sin(2.0 * np.pi * t / 86_400.0 - 2.0)
    Q_H = np.repeat(rng.choice([0.0, 800.0, 1600.0, 2200.0], size=N // 8 + 1), 8)[:N]
    T_o_step = np.concatenate([(T_o[:-1] + T_o[1:]) / 2.0, T_o[-1:]])  # as the fit holds it
    s = models.STRUCTURES["interior_envelope"]
    x = models.simulate(s, TRUTH, np.column_stack([T_o_step, Q_H]), DT, [20.0, 15.0])
    y = x + rng.normal(0.0, NOISE_K, x.shape)
    return write_cell(
        root,
        DT,
        {"T_ext": T_o, "P_hea": Q_H, "T_int": y[:, 0], "T_wall": y[:, 1]},
        {"surface": [{"column": "T_wall"}]},
        # no type-B uncertainty: the intervals are the data's own information
        instruments={"temperature_u_K": 0.0, "power_u_rel": 0.0},
    )


def variant(path: Path, name: str, change) -> Path:
    data = yaml.safe_load(path.read_text(encoding="utf-8"))
    change(data)
    out = path.with_name(f"Cell_{name}.yaml")
    out.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return out


def measured(data) -> None:
    data["model"]["envelope_sensors"] = "surface"


@pytest.fixture(scope="module")
def case(tmp_path_factory) -> Path:
    return write_case(tmp_path_factory.mktemp("surface"))


@pytest.fixture(scope="module")
def fits(case):
    """The interior-envelope fit without and with the surface sensors as T_e."""
    out = {}
    for name, path in (("unmeasured", case), ("measured", variant(case, "measured", measured))):
        vehicle = load_vehicle(path, workdir=path.parent)
        out[name] = fit_vehicle(vehicle, ["interior_envelope"], workdir=path.parent).fits[
            "interior_envelope"
        ]
    return out


def test_measured_envelope_is_compared_and_narrows_C_e(fits):
    plain, wall = fits["unmeasured"], fits["measured"]
    assert plain.content["outputs"] == ["T"] and wall.content["outputs"] == ["T", "T_e"]
    assert plain.series["T_e"].isna().all()
    # T_e's measurement is the surface sensor's cleaned mean (the tidy column T_veh)
    assert wall.series["T_e"].notna().all()
    residual = wall.content["measures"]["T_e"]["overall"]["rmse"]
    assert residual < 1.3 * NOISE_K, residual
    # its calibration offset is a source of the systematic budget, like T_veh's
    assert "offset_T_e" in wall.content["systematic"]["sources"]
    assert "offset_T_e" not in plain.content["systematic"]["sources"]
    widths = {}
    for name, fit in fits.items():
        for p, truth in TRUTH.items():
            assert abs(fit.parameters[p].value / truth - 1.0) < 0.05, (name, fit.parameters[p])
        lo, hi = fit.parameters["C_e"].ci95_combined
        assert lo < TRUTH["C_e"] < hi, (name, fit.parameters["C_e"])
        widths[name] = np.log(hi / lo)
    assert widths["measured"] < 0.85 * widths["unmeasured"], widths


def test_measured_initial_envelope_state_with_x0_measured(case):
    path = variant(case, "x0", lambda d: (measured(d), d["model"].update(x0="measured")))
    vehicle = load_vehicle(path, workdir=path.parent)
    tables = tidy_tables(vehicle, path.parent)
    windows = {"run": tables["run"]}
    estimate, series = identify.identify(windows, vehicle.data, None, "interior_envelope")
    assert estimate.content["fit"]["experiments"][0]["x0_estimated"] == []
    assert estimate.content["fit"]["experiments"][0]["x0"]["T_e"] == tables["run"]["T_veh"].iloc[0]
    assert series["T_e"].equals(tables["run"]["T_veh"].rename("T_e"))
    # without the key the same data leave T_e unmeasured: its initial state is estimated
    plain = variant(case, "x0_plain", lambda d: d["model"].update(x0="measured"))
    vehicle = load_vehicle(plain, workdir=plain.parent)
    estimate, _ = identify.identify(windows, vehicle.data, None, "interior_envelope")
    assert estimate.content["fit"]["experiments"][0]["x0_estimated"] == ["T_e"]


def test_second_order_and_unmeasured_tables_are_left_as_they_are():
    table = pd.DataFrame({"time": [0.0, 60.0], "T": 20.0, "T_veh": [18.0, 18.5]})
    data = {"model": {"envelope_sensors": "surface"}}
    second = fitsettings.envelope_tables(models.STRUCTURES["second_order"], data, {"w": table})
    assert second["w"] is table
    first = fitsettings.envelope_tables(models.STRUCTURES["first_order"], data, {"w": table})
    assert first["w"] is table
    ie = models.STRUCTURES["interior_envelope"]
    assert fitsettings.envelope_tables(ie, {"model": {}}, {"w": table})["w"] is table
    out = fitsettings.envelope_tables(ie, data, {"w": table})["w"]
    assert out["T_e"].tolist() == [18.0, 18.5] and "T_e" not in table.columns


def test_config_checks_name_file_key_and_value(case):
    def no_surface(d):
        measured(d)
        del d["channels"]["surface"]

    path = variant(case, "no_surface", no_surface)
    with pytest.raises(ConfigError) as error:
        load_vehicle(path, workdir=path.parent)
    message = str(error.value)
    assert "Cell_no_surface.yaml" in message and "model.envelope_sensors" in message
    assert "'surface'" in message and "channels.surface" in message

    path = variant(case, "outputs", lambda d: d["model"].update(outputs=["T", "T_e"]))
    with pytest.raises(ConfigError, match=r"model\.outputs.*T_e.*envelope_sensors: surface"):
        load_vehicle(path, workdir=path.parent)

    path = variant(case, "wrong", lambda d: d["model"].update(envelope_sensors="roof"))
    with pytest.raises(ConfigError, match="envelope_sensors"):
        load_vehicle(path, workdir=path.parent)

    ok = variant(case, "ok", lambda d: (measured(d), d["model"].update(outputs=["T", "T_e"])))
    assert load_vehicle(ok, workdir=ok.parent).model["envelope_sensors"] == "surface"
