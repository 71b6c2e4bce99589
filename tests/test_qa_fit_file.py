"""A fit file given to ``railtherm energy``, ``simulate`` or ``design`` that was edited by hand,
cut short or written for another structure: refused naming the file, the key, the value and
the fix (write it again), never a traceback from deep in the draws or the simulation."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from railtherm.cli import main
from railtherm.errors import ConfigError
from railtherm.study import design, simulate

REPO = Path(__file__).resolve().parents[1]
SAND_POINT = REPO / "config" / "weather" / "703165TY.csv"
PROFILE = REPO / "config" / "profiles" / "metro_service.yaml"


def _edited(fit: Path, tmp_path: Path, change) -> Path:
    data = yaml.safe_load(fit.read_text())
    change(data)
    path = tmp_path / "fit_order2.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _set_C(value):
    def change(data):
        data["parameters"]["C"]["value"] = value

    return change


def _rename_K_veh(data):
    data["parameters"]["K_x"] = data["parameters"].pop("K_veh")


def _structure(data):
    data["structure"] = "my_network"


def _correlation(data):
    data["correlation"] = [[1.0]]


CASES = [
    (_set_C(-1.0), "parameters.C.value", "-1.0", "finite number > 0"),
    (_set_C("abc"), "parameters.C.value", "'abc'", "finite number > 0"),
    (_set_C(float("nan")), "parameters.C.value", "nan", "finite number > 0"),
    (_set_C(0.0), "parameters.C.value", "0.0", "finite number > 0"),
    (_rename_K_veh, "parameters", "K_x", "missing K_veh"),
    (_structure, "structure", "'my_network'", "not a structure of the registry"),
    (_correlation, "correlation", "shape (1, 1)", "correlation of the free parameters"),
]


@pytest.mark.bad_input
@pytest.mark.parametrize("change, key, value, reason", CASES)
def test_an_edited_fit_file_is_refused_by_energy_naming_the_key_and_the_fix(
    fit_files, tmp_path, capsys, change, key, value, reason
):
    """Before: a negative, zero or text value raised ValueError (math domain error), NaN a
    LinAlgError, an unknown structure a KeyError, a renamed parameter a broadcast error."""
    fit, _ = fit_files("Metro2", "order2")
    path = _edited(fit, tmp_path, change)
    args = ["energy", str(path), "--weather", str(SAND_POINT), "--profile", str(PROFILE)]
    assert main([*args, "--draws", "0", "--step-s", "3600"]) != 0
    err = capsys.readouterr().err
    assert "Traceback" not in err
    for fragment in (str(path), f"'{key}'", value, reason, "railtherm fit --out"):
        assert fragment in err, (fragment, err)


@pytest.mark.bad_input
def test_an_edited_fit_file_is_refused_by_design_and_simulate(fit_files, tmp_path):
    fit, _ = fit_files("Metro2", "order2")
    path = _edited(fit, tmp_path, _set_C(-1.0))
    for read in (design.prior_from_fit_file, simulate.load_parameters):
        with pytest.raises(ConfigError) as err:
            read(path)
        assert "'parameters.C.value' = -1.0" in str(err.value)


def test_the_fit_file_as_written_still_loads(fit_files):
    fit, _ = fit_files("Metro2", "order2")
    ps = simulate.load_parameters(fit)
    assert set(ps.theta) == {"kA", "C", "K_veh", "C_veh"}
    assert all(v > 0 for v in ps.theta.values())
