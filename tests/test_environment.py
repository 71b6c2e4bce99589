"""The software environments agree with pyproject.toml: the pip lock file (requirements.lock)
pins every package within pyproject's ranges, the conda environment of the rules
(workflow/envs/railtherm.yaml) lists pyproject's dependencies, and its post-deploy script
installs railtherm from the repository into a fresh environment."""

from __future__ import annotations

import importlib.metadata
import json
import os
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
import yaml
from packaging.requirements import Requirement
from packaging.specifiers import SpecifierSet
from packaging.utils import canonicalize_name
from packaging.version import Version

REPO = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["project"]
LOCK = REPO / "requirements.lock"
RULE_ENV = REPO / "workflow" / "envs" / "railtherm.yaml"
POST_DEPLOY = RULE_ENV.with_name("railtherm.post-deploy.sh")
# conda-forge's names of PyPI packages (the same software, without optional extras)
CONDA_NAME = {"snakemake": "snakemake-minimal", "matplotlib": "matplotlib-base"}


def requirements(extra: str | None = None) -> list[Requirement]:
    deps = PYPROJECT["dependencies"] if extra is None else PYPROJECT["optional-dependencies"][extra]
    return [Requirement(d) for d in deps]


def lock() -> dict[str, Version]:
    pins = {}
    for line in LOCK.read_text(encoding="utf-8").splitlines():
        if line.strip() and not line.startswith("#"):
            name, _, version = line.partition("==")
            assert version, f"requirements.lock: not an exact pin: {line!r}"
            pins[canonicalize_name(name)] = Version(version)
    return pins


def installed_extras() -> set[str]:
    """The extras the README's environment installs: those the test extra names."""
    return {
        extra
        for r in requirements("test")
        if canonicalize_name(r.name) == "railtherm"
        for extra in r.extras
    } | {"test"}


def test_lock_pins_every_dependency_within_pyproject_ranges():
    pins = lock()
    assert "railtherm" not in pins
    for req in requirements() + [r for e in installed_extras() for r in requirements(e)]:
        name = canonicalize_name(req.name)
        if name == "railtherm":
            continue  # an extra naming others
        assert name in pins, f"{req.name} is in pyproject.toml but not in requirements.lock"
        assert pins[name] in req.specifier, f"requirements.lock pins {name} {pins[name]}: {req}"


def test_an_extra_outside_the_lock_is_installed_by_its_doc_at_a_version_in_range():
    """The slurm extra (the submit host of a cluster) stays out of the default environment;
    docs/cluster.md installs it at an exact version, which pyproject's range must hold."""
    others = set(PYPROJECT["optional-dependencies"]) - installed_extras()
    assert others == {"slurm"}
    doc = (REPO / "docs" / "cluster.md").read_text(encoding="utf-8")
    for req in requirements("slurm"):
        pin = re.search(rf"pip install {re.escape(req.name)}==([\w.]+)", doc)
        assert pin, f"docs/cluster.md does not install {req.name} at an exact version"
        assert Version(pin.group(1)) in req.specifier, (req, pin.group(1))
        assert canonicalize_name(req.name) not in lock()


def test_lock_holds_everything_the_dependencies_pull_in():
    """Walk railtherm[test]'s requirements through the installed packages' metadata: every
    package reached is pinned (a new dependency, or a new one of a dependency, is noticed)
    and every pin is reached."""
    pins = lock()
    todo = [*requirements(), *requirements("test")]
    seen: set[tuple[str, frozenset[str]]] = set()
    walked_all = True
    while todo:
        req = todo.pop()
        name = canonicalize_name(req.name)
        if (name, frozenset(req.extras)) in seen:
            continue
        seen.add((name, frozenset(req.extras)))
        if name == "railtherm":  # an extra naming others (test -> workflow, sindy)
            todo += [r for extra in sorted(req.extras) for r in requirements(extra)]
            continue
        assert name in pins, f"{req.name} (needed as {req}) is not in requirements.lock"
        try:
            dist = importlib.metadata.distribution(req.name)
        except importlib.metadata.PackageNotFoundError:
            walked_all = False  # not installed here: its own requirements cannot be walked
            continue
        for r in map(Requirement, dist.requires or []):
            if r.marker is None or any(r.marker.evaluate({"extra": e}) for e in req.extras | {""}):
                todo.append(r)
    reached = {name for name, _ in seen} - {"railtherm"}
    if walked_all:
        assert not set(pins) - reached, f"pinned but not needed: {sorted(set(pins) - reached)}"


def conda_dependencies(path: Path) -> dict[str, SpecifierSet]:
    env = yaml.safe_load(path.read_text(encoding="utf-8"))
    deps = {}
    for dep in env["dependencies"]:
        if isinstance(dep, str):
            name, _, spec = dep.partition(" ")
            deps[name] = SpecifierSet(spec.replace(" ", ""))
    return deps


def test_rule_environment_lists_pyproject_dependencies_with_their_ranges():
    deps = conda_dependencies(RULE_ENV)
    assert deps.pop("python") == SpecifierSet(PYPROJECT["requires-python"])
    assert deps.pop("pip") == SpecifierSet()
    # a rule's environment runs the whole study: the library, the workflow and the SINDy extras
    needed = requirements() + requirements("workflow") + requirements("sindy")
    expected = {CONDA_NAME.get(r.name, r.name): r.specifier for r in needed}
    assert deps == expected
    text = RULE_ENV.read_text(encoding="utf-8")
    assert "pip:" not in text  # railtherm comes from the post-deploy script, not a pip path


def test_conda_development_environment_installs_the_lock():
    env = yaml.safe_load((REPO / "environment.yml").read_text(encoding="utf-8"))
    pip = next(d["pip"] for d in env["dependencies"] if isinstance(d, dict))
    assert pip == ["-r requirements.lock", "-e .[test]"]
    python = next(d for d in env["dependencies"] if isinstance(d, str) and d.startswith("python"))
    assert python == "python =3.11"  # the Python the lock was made with
    assert "CPython 3.11" in LOCK.read_text(encoding="utf-8")


def test_readme_installs_with_the_lock():
    readme = (REPO / "README.md").read_text(encoding="utf-8").splitlines()
    commands = [line for line in readme if line.startswith("python3 -m venv .venv && ")]
    assert len(commands) == 2 and any("-m pytest" in c for c in commands)
    for command in commands:
        assert '-m pip install -r requirements.lock -e ".[test]"' in command
    # the study's command compiles the editable package's bytecode before any job imports it
    # (docs/environment.md); the suite does so itself (tests/conftest.py)
    study = next(c for c in commands if "snakemake --cores all" in c)
    assert ' -e ".[test]" && .venv/bin/python -m compileall -q railtherm && ' in study


def run_post_deploy(env_dir: Path, cwd: Path, **environ: str) -> subprocess.CompletedProcess:
    """The post-deploy script as Snakemake runs it: a copy named after the environment's hash
    beside the environment, with the interpreter of its shebang, the new environment
    activated, in the run's working directory."""
    copy = env_dir.with_name("0123456789abcdef.post-deploy.sh")
    shutil.copy2(POST_DEPLOY, copy)
    interpreter = POST_DEPLOY.read_text(encoding="utf-8").splitlines()[0][2:].strip()
    env = {k: v for k, v in os.environ.items() if k not in ("RAILTHERM_REPO", "PYTHONPATH")}
    env |= {"PATH": f"{env_dir / 'bin'}{os.pathsep}{env['PATH']}", "VIRTUAL_ENV": str(env_dir)}
    return subprocess.run(
        f"{interpreter} '{copy}'",
        shell=True,
        cwd=cwd,
        env=env | environ,
        capture_output=True,
        text=True,
        timeout=300,
    )


def railtherm_in(env_dir: Path, cwd: Path) -> subprocess.CompletedProcess:
    code = (
        "import importlib.metadata, json, pathlib, railtherm\n"
        "url = json.loads(importlib.metadata.distribution('railtherm')"
        ".read_text('direct_url.json'))\n"
        "print(pathlib.Path(railtherm.__file__).resolve(), json.dumps(url))\n"
    )
    return subprocess.run(
        [str(env_dir / "bin" / "python"), "-c", code], cwd=cwd, capture_output=True, text=True
    )


@pytest.mark.slow
def test_post_deploy_script_installs_railtherm_from_the_repository(tmp_path):
    """`snakemake --sdm conda` from the repository (here: --directory validation) and from a
    scratch directory with RAILTHERM_REPO: a fresh environment without railtherm (conda is not
    available here; a virtual environment stands in for it) imports it from the repository
    afterwards. Outside a repository and without RAILTHERM_REPO, the script says so."""
    env_dir = tmp_path / "env"
    subprocess.run([sys.executable, "-m", "venv", str(env_dir)], check=True)
    assert railtherm_in(env_dir, tmp_path).returncode != 0  # a fresh environment

    scratch = tmp_path / "study"
    scratch.mkdir()
    lost = run_post_deploy(env_dir, scratch)
    assert lost.returncode == 1
    assert "no railtherm repository at or above" in lost.stderr and "RAILTHERM_REPO" in lost.stderr

    for cwd, environ in ((REPO / "validation", {}), (scratch, {"RAILTHERM_REPO": str(REPO)})):
        deployed = run_post_deploy(env_dir, cwd, **environ)
        assert deployed.returncode == 0, deployed.stderr
        assert f"installing railtherm from {REPO}" in deployed.stdout
        found = railtherm_in(env_dir, tmp_path)
        assert found.returncode == 0, found.stderr
        path, url = found.stdout.split(" ", 1)
        assert Path(path) == REPO / "railtherm" / "__init__.py"
        assert json.loads(url)["dir_info"] == {"editable": True}
        assert json.loads(url)["url"] == REPO.as_uri()
