"""Package-level promises: the library stands without the workflow engine."""

import subprocess
import sys


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
    """railtherm module -> railtherm modules it imports (anywhere in the file)."""
    import ast
    from pathlib import Path

    root = Path(__file__).resolve().parents[1] / "railtherm"
    modules = {p.stem for p in root.glob("*.py")}
    graph = {}
    for path in root.glob("*.py"):
        found = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module:
                parts = node.module.split(".")
                if parts[0] != "railtherm":
                    continue
                if len(parts) > 1:
                    found.add(parts[1])
                else:
                    found |= {a.name for a in node.names if a.name in modules}
            elif isinstance(node, ast.Import):
                found |= {
                    a.name.split(".")[1] for a in node.names if a.name.startswith("railtherm.")
                }
        graph[path.stem] = found & modules - {path.stem}
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
    assert "synth" not in graph["aggregate"] and "synth" not in graph["plots"]


def test_entry_points_are_importable_from_the_package():
    import railtherm

    for name in ("load_vehicle", "load_study", "fit_vehicle", "Fit", "read_fit", "KValue"):
        assert callable(getattr(railtherm, name)), name
