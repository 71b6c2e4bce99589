"""A broken structure module stops only the vehicles that ask for it: in a copy of the package
with user modules that do not parse, repeat a key, declare no STRUCTURE or carry doubled
derivatives (and, separately, with a shipped module broken), ``railtherm validate``,
``railtherm fit`` and the workflow's parse refuse each vehicle that asks for a broken one,
naming the vehicle's key, the module's file and the fix, while another vehicle of the same
study validates and fits. The copy is made as tests/test_structure_registry.py makes it: a new
structure is one new file in railtherm/structures/."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
import yaml
from test_structure_registry import ARMADILLO, PACKAGE, REPO, run
from test_structures_refused import DOUBLED, ENVELOPE

# {module name: (its source, what the refusal must say)}
BROKEN = {
    "typo": (
        ENVELOPE.replace('    title="interior-envelope model",', '    title="interior-envelope,'),
        "syntax error",
    ),
    "twice": (
        ENVELOPE.replace('"K_o": 1000.0},', '"K_o": 1000.0, "K_i": 10.0},'),
        "keep one entry for it",
    ),
    "nameless": (
        ENVELOPE.replace("STRUCTURE = Structure(", "MODEL = Structure("),
        "add STRUCTURE = Structure(...)",
    ),
    "doubled": (ENVELOPE + DOUBLED, "correct dA[0, 0]/dC in the function given as jacobian"),
}


def package_copy(root: Path, modules: dict[str, str]) -> Path:
    """A copy of the package and the workflow under ``root`` with ``modules`` ({file name:
    source}) written into its railtherm/structures/ (added, or replacing a shipped one)."""
    shutil.copytree(PACKAGE, root / "railtherm", ignore=shutil.ignore_patterns("__pycache__"))
    for folder in ("workflow", "profiles"):
        shutil.copytree(REPO / folder, root / folder, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copyfile(REPO / "Snakefile", root / "Snakefile")
    for name, source in modules.items():
        (root / "railtherm" / "structures" / f"{name}.py").write_text(source)
    return root


def study(folder: Path, vehicles: dict[str, dict]) -> Path:
    """A study of Armadillo-box vehicles ({id: model settings}), output-error fits only."""
    (folder / "config" / "vehicles").mkdir(parents=True)
    (folder / "data").mkdir()
    shutil.copyfile(
        REPO / "data" / "armadillo" / "armadillo_data_H2.csv", folder / "data" / "h2.csv"
    )
    for vid, model in vehicles.items():
        vehicle = yaml.safe_load(ARMADILLO.read_text())
        vehicle["id"] = vid
        vehicle["raw_files"] = {"h2": "../../data/h2.csv"}
        vehicle["model"].update(estimator="output_error", **model)
        (folder / "config" / "vehicles" / f"{vid}.yaml").write_text(yaml.safe_dump(vehicle))
    write_config(folder, list(vehicles))
    return folder


def write_config(folder: Path, vehicles: list[str]) -> None:
    config = yaml.safe_load((REPO / "validation" / "config" / "config.yaml").read_text())
    config["vehicles"] = [f"config/vehicles/{vid}.yaml" for vid in vehicles]
    config["study"]["references"] = []
    (folder / "config" / "config.yaml").write_text(yaml.safe_dump(config, sort_keys=False))


# Runs railtherm's command line once per argv in one process (each as ``railtherm ...`` would
# run it: cli.main, its exit status and its two streams), to pay Python's start-up once.
COMMANDS = """
import contextlib, io, json, sys
from railtherm import cli
results = []
for argv in json.loads(sys.argv[1]):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = cli.main(argv)
        except SystemExit as exit:
            rc = exit.code
    results.append([rc, out.getvalue(), err.getvalue()])
print(json.dumps(results))
"""


def commands(root: Path, folder: Path, *argvs: list[str]) -> list[tuple[int, str, str]]:
    """(exit status, stdout, stderr) of ``railtherm <argv>`` for each argv, in ``folder``
    with the package copy ``root`` first on the path."""
    result = run(["-c", COMMANDS, json.dumps(list(argvs))], folder, root)
    assert result.returncode == 0, result.stderr[-3000:]
    return [tuple(r) for r in json.loads(result.stdout.splitlines()[-1])]


def vehicle(vid: str) -> str:
    return f"config/vehicles/{vid}.yaml"


@pytest.fixture(scope="module")
def user_modules(tmp_path_factory):
    """(package copy, study, validated): the four broken user modules beside the shipped
    ones; a vehicle asking for each, and Healthy, asking for the first-order model and
    interior_envelope; ``validated`` {vehicle id: (exit status, stdout, stderr)} of
    ``railtherm validate`` on each."""
    tmp = tmp_path_factory.mktemp("broken_user_modules")
    root = package_copy(tmp / "pkg", {name: source for name, (source, _) in BROKEN.items()})
    vehicles = {"Healthy": {"orders": [1], "structures": ["interior_envelope"]}}
    vehicles |= {f"Uses_{name}": {"orders": [1], "structures": [name]} for name in BROKEN}
    folder = study(tmp / "study", vehicles)
    done = commands(root, folder, *(["validate", vehicle(vid)] for vid in vehicles))
    return root, folder, dict(zip(vehicles, done, strict=True))


@pytest.mark.bad_input
@pytest.mark.parametrize("name", list(BROKEN))
def test_validate_refuses_only_the_vehicle_asking_for_a_broken_module(user_modules, name):
    """``railtherm validate`` of the vehicle that asks for the broken module stops with the
    vehicle's file and key, the module's file and the fix; the study's other vehicle
    validates in the same package."""
    root, _, validated = user_modules
    rc, _, message = validated[f"Uses_{name}"]
    assert rc == 1 and "Traceback" not in message
    assert message.startswith(f"{vehicle(f'Uses_{name}')}: key 'model.structures[0]' = '{name}'")
    module = root / "railtherm" / "structures" / f"{name}.py"
    assert f"the structure module is refused: {module}: key " in message
    assert BROKEN[name][1] in message
    assert f"Fix the module, or drop {name} from model.structures" in message

    rc, out, err = validated["Healthy"]
    assert rc == 0 and out.startswith("ok: 1 vehicle"), err[-2000:]


@pytest.mark.bad_input
def test_a_vehicle_beside_broken_modules_fits_and_the_command_line_refuses_them(user_modules):
    """``railtherm fit`` fits the healthy vehicle's models with four broken modules in the
    package; asked for a broken one by --model, it names the module and the fix."""
    root, folder, _ = user_modules
    fit, refused = commands(
        root,
        folder,
        ["fit", vehicle("Healthy"), "--model", "order1"],
        ["fit", vehicle("Healthy"), "--model", "doubled"],
    )
    assert fit[0] == 0, fit[2][-3000:]
    assert "order1" in fit[1] and "kA" in fit[1]
    assert refused[0] == 1 and "Traceback" not in refused[2]
    assert "doubled.py: key 'STRUCTURE.jacobian[C]'" in refused[2]
    assert "disagrees with the central difference" in refused[2]


@pytest.mark.bad_input
@pytest.mark.workflow
def test_the_workflow_parse_refuses_the_same_vehicles(user_modules):
    """The workflow's parse runs the same check: with a vehicle asking for a broken module
    in the study, the dry run stops naming it and the module; without it, the dry run plans
    the healthy vehicle's jobs."""
    root, folder, _ = user_modules
    snakemake = ["-m", "snakemake", "--snakefile", str(root / "Snakefile"), "-n", "--cores", "1"]
    write_config(folder, ["Healthy", "Uses_twice"])
    refused = run(snakemake, folder, root)
    said = refused.stderr + refused.stdout
    assert refused.returncode != 0
    assert "invalid configuration: config/vehicles/Uses_twice.yaml: key 'model.structures[0]'" in (
        said
    )
    assert "twice.py: key 'line " in said and "keep one entry for it" in said

    write_config(folder, ["Healthy"])
    planned = run(snakemake, folder, root)
    assert planned.returncode == 0, planned.stderr[-3000:]
    assert "identify" in planned.stdout


# {shipped module: (text replaced, by, the order it is, the other order)}: first_order.py
# with a syntax error, second_order.py with a start value written twice
SHIPPED = {
    "first_order": ('    air="C_bar",', '    air="C_bar"\n    air=C_bar,', 1, 2),
    "second_order": ('"C": 120_480.0,', '"C": 120_480.0, "kA": 5.0,', 2, 1),
}


@pytest.mark.bad_input
@pytest.mark.parametrize("name", list(SHIPPED))
def test_a_broken_shipped_module_stops_only_the_vehicles_of_its_order(tmp_path, name):
    """A shipped module broken: the vehicle asking for its order is refused, naming the
    module's file and line; a study of a vehicle asking for the other order and
    interior_envelope validates (with the study's design and energy settings) and fits."""
    old, new, order, other = SHIPPED[name]
    source = (PACKAGE / "structures" / f"{name}.py").read_text()
    assert old in source
    root = package_copy(tmp_path / "pkg", {name: source.replace(old, new)})
    folder = study(
        tmp_path / "study",
        {
            "Uses": {"orders": [order], "structures": []},
            "Other": {"orders": [other], "structures": ["interior_envelope"]},
        },
    )
    write_config(folder, ["Other"])
    refused, fine, fit = commands(
        root,
        folder,
        ["validate", vehicle("Uses")],
        ["validate"],
        ["fit", vehicle("Other"), "--model", "interior_envelope"],
    )
    assert refused[0] == 1 and "Traceback" not in refused[2]
    assert refused[2].startswith(f"{vehicle('Uses')}: key 'model.orders[0]' = {order}")
    assert f"{root / 'railtherm' / 'structures' / f'{name}.py'}: key 'line " in refused[2]
    assert f"drop {order} from model.orders" in refused[2]
    assert fine[0] == 0 and fine[1].startswith("ok: 1 vehicle"), fine[2][-2000:]
    assert fit[0] == 0, fit[2][-3000:]
    assert "interior_envelope" in fit[1] and "K_o" in fit[1]
