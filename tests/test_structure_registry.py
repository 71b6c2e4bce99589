"""A model structure is one file: the registry of railtherm.structures feeds the config schema,
the command line, the fits, the model table and the figures, so a network added as one new
module is fitted everywhere, with no other file changed."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from snakemake_run import cores

from railtherm import structures
from railtherm.yamlio import packaged_schema

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "railtherm"
ARMADILLO = REPO / "validation" / "config" / "vehicles" / "Armadillo_zoh.yaml"
NEW = "envelope_copy"  # the new structure's key: its module's file name
RENAMED = ("K_o", "K_w")  # a parameter of the copy renamed to a name no schema file contains


def package_with_new_structure(tmp_path: Path) -> Path:
    """A copy of the package (with the workflow beside it, as in the repository) with
    ``structures/interior_envelope.py`` copied to ``structures/envelope_copy.py``, its
    conductance K_o renamed K_w: no other file of the copy differs from the repository's."""
    root = tmp_path / "pkg"
    shutil.copytree(PACKAGE, root / "railtherm", ignore=shutil.ignore_patterns("__pycache__"))
    for folder in ("workflow", "profiles"):
        shutil.copytree(REPO / folder, root / folder, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copyfile(REPO / "Snakefile", root / "Snakefile")
    text = (PACKAGE / "structures" / "interior_envelope.py").read_text(encoding="utf-8")
    (root / "railtherm" / "structures" / f"{NEW}.py").write_text(
        text.replace(*RENAMED), encoding="utf-8"
    )
    return root


def study_asking_for(tmp_path: Path, key: str) -> Path:
    """A one-vehicle study (the validation study's config) whose vehicle, the Armadillo box
    under the zero-order hold, asks for the structure ``key`` alone, output-error fit."""
    study = tmp_path / "study"
    (study / "config" / "vehicles").mkdir(parents=True)
    (study / "data").mkdir()
    shutil.copyfile(
        REPO / "data" / "armadillo" / "armadillo_data_H2.csv", study / "data" / "h2.csv"
    )
    vehicle = yaml.safe_load(ARMADILLO.read_text())
    vehicle["id"] = "Box"
    vehicle["raw_files"] = {"h2": "../../data/h2.csv"}
    vehicle["model"].update(orders=[], structures=[key], estimator="output_error")
    (study / "config" / "vehicles" / "Box.yaml").write_text(yaml.safe_dump(vehicle))
    config = yaml.safe_load((REPO / "validation" / "config" / "config.yaml").read_text())
    config["vehicles"] = ["config/vehicles/Box.yaml"]
    config["study"]["references"] = []
    (study / "config" / "config.yaml").write_text(yaml.safe_dump(config, sort_keys=False))
    return study


def run(args: list[str], cwd: Path, package_root: Path | None) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    if package_root is not None:  # the copy first on the path, before the installed package
        env["PYTHONPATH"] = os.pathsep.join([str(package_root), env.get("PYTHONPATH", "")])
    return subprocess.run(
        [sys.executable, *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=900
    )


def test_registry_derives_the_schema_the_cli_and_the_nesting():
    """The enums of model.orders, model.structures and model.outputs, the reference files'
    model keys and the nested pairs of the model selection are those of the modules."""
    model = packaged_schema("vehicle")["properties"]["model"]["properties"]
    assert model["orders"]["items"]["enum"] == structures.orders() == [1, 2]
    assert model["structures"]["items"]["enum"] == structures.further()
    assert "interior_envelope" in structures.further()
    assert set(model["outputs"]["items"]["enum"]) == {"T", "T_veh", "T_e"}
    pattern = packaged_schema("reference")["properties"]["model"]["pattern"]
    assert all(k in pattern for k in structures.keys())
    assert ("order1", "order2", 1) in structures.nesting()
    assert structures.keys()[:2] == ["order1", "order2"]


@pytest.mark.parametrize("name", list(structures.STRUCTURES))
def test_every_structure_is_complete(name):
    """Each module declares the derivatives of its own (A, B) (checked against central
    differences), units for every parameter, a title, and an overall kA: a parameter kA or a
    loss path whose steady state gives it."""
    s = structures.STRUCTURES[name]
    theta = {p: float(v) for p, v in s.initial.items()}
    assert set(theta) == set(s.parameters) == set(s.bounds)
    assert s.title and all(s.unit(p) in ("J/K", "W/K") for p in s.parameters)
    A, B = s.matrices(theta)
    assert A.shape == (len(s.states), len(s.states)) and B.shape == (len(s.states), 2)
    for p, (dA, dB) in s.derivatives(theta).items():
        h = 1e-6 * theta[p]
        Ap, Bp = s.matrices({**theta, p: theta[p] + h})
        Am, Bm = s.matrices({**theta, p: theta[p] - h})
        np.testing.assert_allclose(dA, (Ap - Am) / (2 * h), rtol=1e-6, atol=1e-14)
        np.testing.assert_allclose(dB, (Bp - Bm) / (2 * h), rtol=1e-6, atol=1e-14)
    kA, gradient = s.kA_log_gradient(theta)
    assert kA > 0 and ("kA" in s.parameters or s.loss_path)
    for p in s.parameters:  # d log kA / d log p against a central difference
        up = s.kA_log_gradient({**theta, p: theta[p] * np.exp(1e-6)})[0]
        down = s.kA_log_gradient({**theta, p: theta[p] * np.exp(-1e-6)})[0]
        assert gradient[p] == pytest.approx(np.log(up / down) / 2e-6, abs=1e-6)


def test_two_structures_under_one_key_are_refused(tmp_path):
    """A copy of an order's module keeps its order: two structures claim one model key, and
    the registry refuses both, saying which; the other structures load."""
    root = tmp_path / "pkg"
    shutil.copytree(PACKAGE, root / "railtherm", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copyfile(
        PACKAGE / "structures" / "second_order.py", root / "railtherm" / "structures" / "twin.py"
    )
    code = "from railtherm import structures as s; print(list(s.STRUCTURES)); s.by_key('order2')"
    result = run(["-c", code], tmp_path, root)
    assert result.returncode != 0
    assert "['first_order', 'interior_envelope', 'interior_fittings']" in result.stdout
    assert "'second_order' and 'twin' both declare the model key 'order2'" in result.stderr


@pytest.mark.slow
@pytest.mark.workflow
def test_a_structure_added_as_one_file_is_fitted_by_the_cli_and_the_workflow(tmp_path):
    """The acceptance check of the registry: in a copy of the package with one module added
    (a copy of interior_envelope.py under the key envelope_copy, one parameter renamed to a
    name no schema file contains) and no other file changed, ``railtherm fit`` and
    ``snakemake`` fit it for a vehicle that asks for it and gives the renamed parameter a
    start value and bounds, models.md has its row and the vehicle its fit figure. The
    installed package does not know the key."""
    root = package_with_new_structure(tmp_path)
    schemas = " ".join(p.read_text() for p in (PACKAGE / "schemas").glob("*.yaml"))
    assert RENAMED[1] not in schemas
    changed = [
        p.relative_to(root / "railtherm")
        for p in (root / "railtherm").rglob("*")
        if p.is_file()
        and not (PACKAGE / p.relative_to(root / "railtherm")).is_file()
        and "__pycache__" not in p.parts
    ]
    assert changed == [Path("structures") / f"{NEW}.py"]
    study = study_asking_for(tmp_path, NEW)
    vehicle = "config/vehicles/Box.yaml"
    box = yaml.safe_load((study / vehicle).read_text())
    box["model"]["initial"] = {RENAMED[1]: 900.0}
    box["model"]["bounds"] = {RENAMED[1]: [0.5, 2.0e5]}
    (study / vehicle).write_text(yaml.safe_dump(box))

    refused = run(["-m", "railtherm", "validate", vehicle], study, None)
    said = refused.stderr + refused.stdout  # the installed package knows neither name
    assert refused.returncode != 0 and ("model.structures" in said or RENAMED[1] in said), said

    fit = run(["-m", "railtherm", "fit", vehicle], study, root)
    assert fit.returncode == 0, fit.stderr[-3000:]
    assert NEW in fit.stdout and "K_i" in fit.stdout and "C_e" in fit.stdout
    assert f"{RENAMED[1]} = " in fit.stdout, fit.stdout

    workflow = run(
        ["-m", "snakemake", "--snakefile", str(root / "Snakefile"), "--cores", str(cores())],
        study,
        root,
    )
    assert workflow.returncode == 0, workflow.stderr[-3000:]
    table = (study / "results" / "tables" / "models.md").read_text()
    rows = [line for line in table.splitlines() if line.startswith("|") and NEW in line]
    assert rows and "Box" in rows[0]
    assert (study / "results" / "vehicles" / "Box" / f"fit_{NEW}.png").is_file()
    fitted = yaml.safe_load(
        (study / "results" / "vehicles" / "Box" / f"fit_{NEW}.yaml").read_text()
    )
    assert fitted["structure"] == fitted["model"] == NEW
    assert RENAMED[1] in fitted["parameters"] and RENAMED[0] not in fitted["parameters"]


def test_the_interior_fittings_structure_recovers_its_truth():
    """The worked example of docs/structures.md: the second-order model with a third,
    unmeasured node for the interior fittings. Simulated from a declared truth with sensor
    noise on T and T_veh (T_f not measured) and fitted with kA fixed (the paper's two-stage
    fit): every parameter within its 95 % interval's reach of the truth, and the fit nests
    the second-order model."""
    from railtherm.estimation import models, pem

    s = structures.by_key("interior_fittings")
    assert s.states == ("T", "T_veh", "T_f") and ("order2", "interior_fittings", 1) in (
        structures.nesting()
    )
    truth = {"kA": 800.0, "C": 2.0e5, "K_veh": 400.0, "C_veh": 8.0e6, "K_f": 300.0, "C_f": 1.5e6}
    dt, n = 60.0, 2880  # 48 h at 1 min
    t = np.arange(n) * dt / 3600.0
    Q_H = np.select([t < 2, t < 20, t < 30], [0.0, 10_000.0, 3_000.0], 12_000.0)
    u = np.column_stack([np.full(n, -5.0), Q_H])
    x = models.simulate(s, truth, u, dt, x0=[-5.0, -5.0, -5.0])
    rng = np.random.default_rng(32)
    y = x.copy()
    y[:, :2] += rng.normal(0.0, 0.05, (n, 2))
    y[:, 2] = np.nan  # the fittings have no sensor
    exp = pem.Experiment("steps", dt, u, y, x0=y[0].copy())
    result = pem.fit(s, [exp], fixed={"kA": truth["kA"]}, x0="estimated", covariance="iid")
    assert result.success and result.outputs == ("T", "T_veh")
    for p in ("C", "K_veh", "C_veh", "K_f", "C_f"):
        lo, hi = result.ci95[p]
        assert lo < hi and abs(np.log(result.theta[p] / truth[p])) < 0.1, p
        assert lo / 1.5 < truth[p] < hi * 1.5, (p, lo, truth[p], hi)


def test_docs_list_every_structure():
    """docs/structures.md has a row per registered structure: its file, key and states."""
    text = (REPO / "docs" / "structures.md").read_text()
    for s in structures.STRUCTURES.values():
        row = f"| `{s.name}.py` | `{s.key}` | {', '.join(s.states)} | {', '.join(s.parameters)} |"
        assert row in text, row
