"""Editing railtherm's code reruns exactly the jobs that run it: every rule whose script imports
railtherm carries a digest (param ``code``, railtherm.codedigest) of every railtherm module the
script reaches, derived from the imports rather than listed by hand."""

from __future__ import annotations

import ast
import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from snakemake_run import cores

from railtherm.codedigest import code_digest, code_files

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "railtherm"
RULES = sorted((REPO / "workflow" / "rules").glob("*.smk"))
SCRIPTS = REPO / "workflow" / "scripts"


def rules() -> list[tuple[str, str, str | None]]:
    """(rule, its script's file name, the script named in its ``code=script_code(...)`` param
    or None) of every rule with a script."""
    out = []
    for smk in RULES:
        text = smk.read_text(encoding="utf-8")
        for block in re.split(r"^(?=rule |for _rule)", text, flags=re.M)[1:]:
            name = re.search(r"^rule (\w+)|name: (\w+)", block, re.M)
            script = re.search(r'script:\s*\n\s*"\.\./scripts/([^"]+)"', block)
            if not script:
                continue
            code = re.search(r'code=script_code\("([^"]+)"\)', block)
            out.append((name.group(1) or name.group(2), script.group(1), code and code.group(1)))
    return out


_LOADED = """
import json, sys
out = {}
for name, code in json.loads(sys.argv[1]).items():
    for module in [m for m in sys.modules if m == "railtherm" or m.startswith("railtherm.")]:
        del sys.modules[module]
    exec(compile(code, name, "exec"), {"__name__": "__job__"})
    out[name] = sorted(m for m in sys.modules if m == "railtherm" or m.startswith("railtherm."))
print(json.dumps(out))
"""


@pytest.fixture(scope="module")
def imported_at_start() -> dict[str, set[str]]:
    """Per script, the railtherm modules loaded by running its top-level imports (what Python
    itself finds, independent of railtherm.codedigest's reading): one fresh interpreter runs
    every script's imports in turn, each time with no railtherm module loaded (the third-party
    packages stay loaded: they import no railtherm module)."""
    codes = {}
    for script in sorted(SCRIPTS.glob("*.py")):
        tree = ast.parse(script.read_text(encoding="utf-8"))
        imports = [ast.unparse(n) for n in tree.body if isinstance(n, ast.Import | ast.ImportFrom)]
        codes[script.name] = "\n".join(imports)
    run = subprocess.run(
        [sys.executable, "-c", _LOADED, json.dumps(codes)],
        capture_output=True,
        text=True,
        check=True,
    )
    return {name: set(modules) for name, modules in json.loads(run.stdout).items()}


@pytest.mark.parametrize(("rule", "script", "named"), rules(), ids=lambda x: str(x))
def test_every_rule_digests_the_code_its_own_script_reaches(rule, script, named, imported_at_start):
    path = SCRIPTS / script
    loaded = imported_at_start[script]
    if not loaded:
        assert named is None or named == script
        return
    assert named == script, f"rule {rule} runs {script} but its code param is {named}"
    files = {p.resolve() for p in code_files(path)}
    for module in loaded:
        source = importlib.util.find_spec(module).origin
        assert Path(source).resolve() in files, f"rule {rule}: editing {module} would not rerun it"


def test_a_module_imported_only_inside_a_function_is_covered(tmp_path):
    script = tmp_path / "job.py"
    script.write_text("def later():\n    from railtherm.data import timeaxis\n", encoding="utf-8")
    names = {p.relative_to(PACKAGE).as_posix() for p in code_files(script)}
    assert {"data/timeaxis.py", "data/__init__.py", "__init__.py"} <= names
    assert "report/plots.py" not in names  # only what is reached
    assert "data/ingest.py" not in names  # a package reached brings its __init__, not all


def test_the_structure_registry_brings_every_structure(tmp_path):
    """The registry imports its modules by discovery: a script that reaches it reruns when
    any structure's file changes, a new one included."""
    script = tmp_path / "job.py"
    script.write_text("from railtherm import structures\n", encoding="utf-8")
    names = {p.relative_to(PACKAGE).as_posix() for p in code_files(script)}
    found = {f"structures/{p.name}" for p in (PACKAGE / "structures").glob("*.py")}
    assert found <= names and "structures/second_order.py" in found


def test_the_digest_follows_the_bytes_of_the_code(tmp_path):
    script = tmp_path / "job.py"
    script.write_text("from railtherm import errors\n", encoding="utf-8")
    assert code_digest(script) == code_digest(script)
    other = tmp_path / "other.py"
    other.write_text("from railtherm.data import timeaxis\n", encoding="utf-8")
    assert code_digest(other) != code_digest(script)


def _snakemake(repo: Path, study: Path, *args: str) -> subprocess.CompletedProcess:
    """Snakemake in ``study`` with the Snakefile of ``repo``. Snakemake puts the Snakefile's
    directory first on ``sys.path``, so the workflow imports the railtherm beside it."""
    return subprocess.run(
        [sys.executable, "-m", "snakemake", "--snakefile", str(repo / "Snakefile")]
        + ["--directory", str(study), "--cores", str(cores()), *args],
        capture_output=True,
        text=True,
        check=False,
        env={**os.environ, "MPLBACKEND": "Agg"},
    )


@pytest.mark.slow
@pytest.mark.workflow
def test_editing_a_module_a_rule_reaches_reruns_that_rule(tmp_path):
    """A one-vehicle study fits its second-order model with a copy of the repository, and
    makes the campaign's ground truth; nothing is then to be done. After a comment is appended
    to metrics.py in the copy (reached by the identify script through railtherm.study.identify's
    imports, named by no rule), exactly the identify and check jobs are planned again, because
    their code changed: not the upstream synthesize, clean and kvalue jobs, nor the ground
    truth, whose scripts do not reach metrics.py."""
    repo = tmp_path / "repo"
    repo.mkdir()
    for part in ("Snakefile", "workflow", "railtherm", "profiles"):
        copy = shutil.copytree if (REPO / part).is_dir() else shutil.copy
        copy(REPO / part, repo / part)
    study = tmp_path / "study"
    shutil.copytree(REPO / "config", study / "config")
    config = yaml.safe_load((study / "config" / "config.yaml").read_text())
    config["vehicles"] = ["config/vehicles/Tram2.yaml"]
    config["sindy"]["enabled"] = False
    (study / "config" / "config.yaml").write_text(yaml.safe_dump(config, sort_keys=False))
    targets = ["results/vehicles/Tram2/fit_order2.yaml", "results/campaign/ground_truth.csv"]
    first = _snakemake(repo, study, *targets)
    assert first.returncode == 0, first.stderr[-3000:]
    same = _snakemake(repo, study, "-n", *targets)
    assert same.returncode == 0, same.stderr[-3000:]
    assert "Nothing to be done" in same.stdout + same.stderr
    for script in ("clean.py", "synthesize.py", "kvalue.py", "ground_truth.py"):
        assert "metrics.py" not in {p.name for p in code_files(SCRIPTS / script)}
    with open(repo / "railtherm" / "estimation" / "metrics.py", "a", encoding="utf-8") as stream:
        stream.write("\n# an edit\n")
    edited = _snakemake(repo, study, "-n", *targets)
    assert edited.returncode == 0, edited.stderr[-3000:]
    log = edited.stdout + edited.stderr
    assert set(re.findall(r"^rule (\w+):", log, re.M)) == {"identify", "check"}, log[-3000:]
    assert "params have changed" in log.lower()
