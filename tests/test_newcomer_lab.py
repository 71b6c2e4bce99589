"""A newcomer's lab, unmodified: a workbook with a sheet of run information first and a title
row above the table, US dates on a Chicago clock through the end of summer time, °F
temperatures and W power. `railtherm new-vehicle` writes the config that reads it as it is
(only what no file can tell is filled in), and the fit recovers the truth within its
intervals; the same data declared in °C are refused."""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
import pytest
import yaml

from railtherm import fit_vehicle, load_vehicle
from railtherm.data.starter import starter_vehicle
from railtherm.errors import ConfigError
from railtherm.estimation import models

pytest.importorskip("python_calamine")
pytest.importorskip("xlsxwriter")

TRUTH = {"kA": 979.2, "C": 1.8e7, "K_veh": 974.0, "C_veh": 1.0e7}
STEP_S = 60.0


def record() -> pd.DataFrame:
    """48 h from 2024-11-02 06:00 CDT, heater steps every 6 h, the tunnel at -5 °C; the
    second-order model's response (eqs. 7-8) with 0.05 K sensor noise, written as the lab's
    logger writes it: local wall-clock time (01:00-02:00 on 3 November twice), °F, W."""
    rng = np.random.default_rng(7)
    n = int(48 * 3600 / STEP_S) + 1
    t = np.arange(n) * STEP_S
    q = np.where((t // 21_600) % 2 == 0, 30_000.0, 8_000.0)
    u = np.column_stack([np.full(n, -5.0), q])
    s = models.STRUCTURES["second_order"]
    A, B = s.matrices(TRUTH)
    x = models.simulate(s, TRUTH, u, STEP_S, models.steady_state(A, B, [-5.0, 8_000.0]))
    utc = pd.Timestamp("2024-11-02 11:00:00", tz="UTC") + pd.to_timedelta(t, unit="s")
    local = utc.tz_convert("America/Chicago").tz_localize(None)
    f = lambda c: c * 9.0 / 5.0 + 32.0  # noqa: E731
    return pd.DataFrame(
        {
            "Date/Time (CST/CDT)": local.strftime("%m/%d/%Y %I:%M:%S %p"),
            "Cabin Air [°F]": f(x[:, 0] + rng.normal(0, 0.05, n)),
            "Tunnel Air [°F]": f(u[:, 0] + rng.normal(0, 0.05, n)),
            "Body Surface [°F]": f(x[:, 1] + rng.normal(0, 0.05, n)),
            "Heater Power [W]": q,
        }
    )


@pytest.fixture(scope="module")
def workbook(tmp_path_factory):
    folder = tmp_path_factory.mktemp("lab")
    path = folder / "run_0412.xlsx"
    with pd.ExcelWriter(path, engine="xlsxwriter") as book:
        info = pd.DataFrame({"Item": ["Vehicle", "Operator"], "Value": ["Tram 7", "J. Doe"]})
        info.to_excel(book, sheet_name="Run Info", index=False)
        record().to_excel(book, sheet_name="Log", index=False, startrow=1)
        book.sheets["Log"].write(0, 0, "Climatic wind tunnel, run 0412")
    return path


def starter(workbook, folder) -> str:
    text, todos = starter_vehicle(workbook, "Tram7", folder)
    assert [t.split(":")[0] for t in todos] == ["class", "mass_kg", "surface_m2"]
    for key, value in (("class", "tram"), ("mass_kg", "38000"), ("surface_m2", "306")):
        text = re.sub(rf"^{key}: +TODO", f"{key}: {value}", text, flags=re.M)
    return text  # only what no file can tell is filled in; the model as new-vehicle leaves it


def test_new_vehicle_reads_the_workbook_as_it_is_and_the_fit_finds_the_truth(workbook):
    folder = workbook.parent
    text = starter(workbook, folder)
    assert "sheet: Log" in text and "header_row: 1" in text
    assert "timezone: America/Chicago" in text and "dst: infer" in text
    assert text.count("unit: degF") == 3 and "unit: W}" in text
    path = folder / "Tram7.yaml"
    path.write_text(text, encoding="utf-8")
    result = fit_vehicle(load_vehicle(path, workdir=folder), models=["order2"], workdir=folder)
    fit = result.fits["order2"]
    # no steady window for the static k test: kA is estimated with the capacities, and the
    # verdict says so (the config's default mode asks for the static test); nothing else
    assert fit.content["k_source"].startswith("joint estimation"), fit.content["k_source"]
    failed = [c["criterion"] for c in fit.content["criteria"] if c["applies"] and not c["passed"]]
    assert failed in ([], ["k_stage"]), (failed, fit.reasons)
    for p, value in TRUTH.items():
        entry = fit.parameters[p]
        assert entry.identified, p
        assert entry.ci95_combined[0] <= value <= entry.ci95_combined[1], (p, entry)
        assert entry.value == pytest.approx(value, rel=0.05), p


@pytest.mark.bad_input
def test_the_same_workbook_declared_celsius_is_refused(workbook):
    folder = workbook.parent
    data = yaml.safe_load(starter(workbook, folder))
    data["channels"]["indoor_air"][0]["unit"] = "degC"
    path = folder / "Tram7_celsius.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False, allow_unicode=True), encoding="utf-8")
    with pytest.raises(ConfigError, match=r"says °F: declare unit: degF"):
        load_vehicle(path, workdir=folder)
