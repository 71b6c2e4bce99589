"""Package-level promises: the library stands without the workflow engine."""

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def test_library_does_not_import_snakemake():
    modules = ["railtherm", "railtherm.config", "railtherm.synth", "railtherm.cli"]
    code = (
        "import sys\n"
        + "".join(f"import {m}\n" for m in modules)
        + "print('snakemake' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def _imports() -> dict[str, set[str]]:
    """railtherm module -> railtherm modules it imports (anywhere in the file).

    A subpackage's ``__init__.py`` is the node ``synth``, each of its modules a node of its own
    (``synth.physics``). Importing a submodule from outside its package runs the package's
    ``__init__.py`` first, so there that import is one of the package too.
    """
    import ast
    from pathlib import Path

    root = Path(__file__).resolve().parents[1] / "railtherm"
    files = {p.stem: p for p in root.glob("*.py")}
    for package in sorted(p.parent for p in root.glob("*/__init__.py")):
        for path in package.glob("*.py"):
            name = package.name if path.stem == "__init__" else f"{package.name}.{path.stem}"
            files[name] = path
    modules = set(files)
    graph = {}
    for name, path in files.items():
        package = name.split(".")[0] if path.parent != root else None
        found = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.level == 1 and package:
                base = f"{package}.{node.module}" if node.module else package
                found.add(base)
                found |= {f"{package}.{a.name}" for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.module:
                parts = node.module.split(".")
                if parts[0] != "railtherm":
                    continue
                if len(parts) > 1:
                    found.add(".".join(parts[1:3]))
                    found |= {f"{parts[1]}.{a.name}" for a in node.names}
                else:
                    found |= {a.name for a in node.names}
            elif isinstance(node, ast.Import):
                found |= {
                    ".".join(a.name.split(".")[1:3])
                    for a in node.names
                    if a.name.startswith("railtherm.")
                }
        found |= {m.split(".")[0] for m in found if m.split(".")[0] != package}
        graph[name] = found & modules - {name}
    return graph


def test_no_import_cycle_among_railtherm_modules():
    graph = _imports()
    done: set[str] = set()

    def visit(module: str, trail: tuple[str, ...]) -> None:
        assert module not in trail, "import cycle: " + " -> ".join([*trail, module])
        if module in done:
            return
        for other in sorted(graph[module]):
            visit(other, (*trail, module))
        done.add(module)

    for module in sorted(graph):
        visit(module, ())


def test_table_building_does_not_depend_on_the_campaign_generator():
    graph = _imports()
    assert "synth" not in graph["study.aggregate"] and "synth" not in graph["report.plots"]


def test_entry_points_are_importable_from_the_package():
    import railtherm

    for name in ("load_vehicle", "load_study", "fit_vehicle", "Fit", "read_fit", "KValue"):
        assert callable(getattr(railtherm, name)), name


def test_the_estimation_layer_passes_no_bare_dicts_of_results():
    """Every public function of railtherm.estimation returns a typed result (an Estimate, a
    KValue, an Identification, test results), never a bare dict or mapping, and takes no
    results as one; a mapping it takes is a config section (settings, instruments, channels,
    thresholds) or parameter values."""
    import importlib
    import inspect
    import pkgutil

    import railtherm.estimation as estimation

    untyped = ("dict[str, Any]", "Mapping[str, Any]", "dict[str, float | int]")
    results = {"fit", "fitted", "estimate", "estimates", "result", "results", "judged", "entry"}
    offending = []
    for info in pkgutil.iter_modules(estimation.__path__):
        module = importlib.import_module(f"railtherm.estimation.{info.name}")
        for name, obj in vars(module).items():
            if name.startswith("_") or not inspect.isfunction(obj):
                continue
            if obj.__module__ != module.__name__:
                continue
            sig = inspect.signature(obj)
            returned = str(sig.return_annotation)
            if returned in ("dict", "Mapping") or any(t == returned for t in untyped):
                offending.append(f"{module.__name__}.{name} returns {returned}")
            for p, param in sig.parameters.items():
                text = str(param.annotation)
                if p in results and ("dict" in text or "Mapping" in text):
                    offending.append(f"{module.__name__}.{name}({p}: {text})")
    assert not offending, offending


def test_the_layers_of_the_architecture_hold_and_the_doc_lists_the_contracts_exceptions():
    """import-linter's contract (pyproject.toml) is kept, imports inside functions included,
    and docs/architecture.md names exactly the imports the contract lets a layer make upwards."""
    import re
    import shutil
    import tomllib
    from pathlib import Path

    repo = Path(__file__).resolve().parents[1]
    lint = shutil.which("lint-imports", path=str(Path(sys.executable).parent))
    assert lint, "import-linter is in the test extra (pyproject.toml)"
    run = subprocess.run([lint], cwd=repo, capture_output=True, text=True)
    assert run.returncode == 0, run.stdout[-3000:]
    config = tomllib.loads((repo / "pyproject.toml").read_text(encoding="utf-8"))
    contracts = config["tool"]["importlinter"]["contracts"]
    ignored = {i for c in contracts for i in c.get("ignore_imports", [])}
    shown = {
        f"railtherm.{a} -> railtherm.{b}"
        for a, b in re.findall(
            r"`([a-z.]+) -> ([a-z.*]+)`", (repo / "docs" / "architecture.md").read_text()
        )
    }
    assert shown == ignored


MODULE_LINES_MAX = 1200  # lines of one module of the package


def test_no_module_of_the_package_is_longer_than_one_concern_needs():
    """Every module of railtherm/ holds at most MODULE_LINES_MAX lines: one that grows past
    it has taken on a second concern (docs/architecture.md lists each module's)."""
    long = {
        str(path.relative_to(REPO)): n
        for path in sorted((REPO / "railtherm").rglob("*.py"))
        if (n := len(path.read_text(encoding="utf-8").splitlines())) > MODULE_LINES_MAX
    }
    assert not long, long


def test_every_module_of_the_package_is_in_the_architecture_doc():
    doc = (REPO / "docs" / "architecture.md").read_text(encoding="utf-8")
    missing = [
        str(path.relative_to(REPO))
        for path in sorted((REPO / "railtherm").rglob("*.py"))
        if path.name != "__init__.py" and path.parent.name != "structures" and path.name not in doc
    ]
    assert not missing, missing


FUNCTION_LINES_MAX = 120  # lines of one function, its docstring included
# a function kept longer, with the reason: (module, function) -> why
LONG_FUNCTIONS: dict[tuple[str, str], str] = {}


def test_no_function_of_the_package_is_longer_than_one_step_needs():
    """Every function of railtherm/ holds at most FUNCTION_LINES_MAX lines, but those of
    LONG_FUNCTIONS (each with its reason, and each still too long: an entry no longer needed
    goes)."""
    import ast

    long = {}
    for path in sorted((REPO / "railtherm").rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                n = node.end_lineno - node.lineno + 1
                if n > FUNCTION_LINES_MAX:
                    long[(str(path.relative_to(REPO)), node.name)] = n
    assert set(long) == set(LONG_FUNCTIONS), long


# A fit travels above the estimators as its record (railtherm.records.FitRecord, or the Fit
# built on it; the identify stage's EstimateRecord before the verdict, and the JudgedEstimate
# of the estimator's result while its parameters are judged).
FIT_NAMES = {"fit", "fits", "fitted", "first_order", "estimate"}


def test_no_fit_travels_as_a_dict_above_the_estimators():
    """study/, report/ and cli.py take a fit as its record: no parameter named for a fit is
    annotated as a mapping or dict (a mapping of records, {vehicle: FitRecord}, is one); and
    no module reads a fit file but by railtherm.io.read_fit."""
    import ast

    found = set()
    paths = [*sorted((REPO / "railtherm" / "study").glob("*.py"))]
    paths += [*sorted((REPO / "railtherm" / "report").glob("*.py")), REPO / "railtherm" / "cli.py"]
    for path in paths:
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                continue
            for arg in [*node.args.posonlyargs, *node.args.args, *node.args.kwonlyargs]:
                text = "" if arg.annotation is None else ast.unparse(arg.annotation)
                untyped = ("Mapping" in text or "dict" in text) and not (
                    "FitRecord" in text or "Fit]" in text
                )
                if arg.arg in FIT_NAMES and untyped:
                    where = str(path.relative_to(REPO / "railtherm"))
                    found.add((where, node.name, arg.arg))
    assert not found, sorted(found)
    readers = [
        f"{path.relative_to(REPO)}:{n}"
        for path in [
            *sorted((REPO / "railtherm").rglob("*.py")),
            *(REPO / "workflow").rglob("*.py"),
        ]
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
        if ("read_result(" in line or "read_yaml(" in line) and "fit" in line.lower()
    ]
    assert not readers, readers


def test_the_public_api_documents_its_parameters_and_returns():
    """Every public function of railtherm's API (``railtherm.__all__``, their classes' public
    methods, inherited ones included, and the command line's ``build_parser`` and ``main``)
    has numpydoc sections: Parameters where it takes arguments, Returns where it returns."""
    import inspect

    import railtherm
    import railtherm.cli as cli

    def public(obj):
        if inspect.isfunction(obj):
            yield obj.__qualname__, obj
        elif inspect.isclass(obj) and not issubclass(obj, BaseException):
            for name, member in inspect.getmembers(obj):
                function = getattr(member, "__func__", member)
                if name.startswith("_") or not inspect.isfunction(function):
                    continue
                if (function.__module__ or "").startswith("railtherm"):
                    yield f"{obj.__name__}.{name}", function

    functions = dict(p for n in railtherm.__all__ for p in public(getattr(railtherm, n)))
    functions |= {f"cli.{n}": getattr(cli, n) for n in ("build_parser", "main")}
    missing = []
    for name, function in sorted(functions.items()):
        doc = inspect.getdoc(function) or ""
        signature = inspect.signature(function)
        takes = [p for p in signature.parameters if p not in ("self", "cls")]
        if takes and "Parameters\n----------" not in doc:
            missing.append(f"{name}: Parameters")
        returns = signature.return_annotation
        if returns not in (None, "None", inspect.Signature.empty) and "Returns\n-------" not in doc:
            missing.append(f"{name}: Returns")
    assert len(functions) > 20 and not missing, missing
