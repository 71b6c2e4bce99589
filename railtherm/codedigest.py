"""Which railtherm code a workflow script runs, and a digest of it.

A job of the workflow reruns when a value in its ``params`` changes. Passing the digest of every
railtherm source file a rule's script can reach makes an edit of that code rerun exactly the
jobs that run it. The files are derived from the imports, never listed by hand: the script's
``import railtherm...`` and ``from railtherm... import ...`` statements (at the top or inside a
function), then those of each module reached, in turn. A package reached brings its
``__init__.py`` (and a package that imports its modules by discovery, the structure registry,
every module of it); a module that reads the package's JSON schemas (it names ``schemas``) brings
those files.
"""

from __future__ import annotations

import ast
import functools
import hashlib
import os
from pathlib import Path

__all__ = ["code_digest", "code_files"]

PACKAGE = Path(__file__).resolve().parent


def _module_files(dotted: str) -> list[Path]:
    """The source files of ``railtherm[.x[.y]]``: a module's file, a subpackage's files, the
    package's ``__init__.py``; none for a name that is no module (a function, a class)."""
    parts = dotted.split(".")[1:]
    if not parts:
        return [PACKAGE / "__init__.py"]
    path = PACKAGE.joinpath(*parts)
    if path.with_suffix(".py").is_file():
        return [path.with_suffix(".py")]
    if path.is_dir():  # a package: its __init__.py (whose own imports are followed), or,
        init = path / "__init__.py"  # for one that imports its modules by discovery (the
        if "pkgutil" in init.read_text(encoding="utf-8"):  # structure registry), every module
            return sorted(path.rglob("*.py"))
        return [init]
    return []


def _statements(body: list[ast.stmt]):
    """Every statement of ``body`` and of the blocks nested in it (function and class bodies,
    branches, loops, ``try`` and ``with`` blocks): where an import can stand. Expressions are
    not visited."""
    todo = list(body)
    while todo:
        node = todo.pop()
        yield node
        for name in ("body", "orelse", "finalbody", "handlers", "cases"):
            block = getattr(node, name, None)
            if isinstance(block, list):
                todo += block


@functools.cache
def _imported(path: Path) -> frozenset[str]:
    """The railtherm modules (dotted names; also names that may be attributes) that a source
    file imports anywhere in it."""
    source = path.read_text(encoding="utf-8")
    if "railtherm" not in source and not path.is_relative_to(PACKAGE):
        return frozenset()
    try:
        tree = ast.parse(source, filename=str(path))
    except SyntaxError:  # a structure module that does not parse: its bytes still count, and
        return frozenset()  # the registry refuses it (railtherm.structures.REFUSED)
    names: set[str] = set()
    for node in _statements(tree.body):
        if isinstance(node, ast.Import):
            for alias in node.names:
                parts = alias.name.split(".")
                if parts[0] == "railtherm":  # import railtherm.a.b: railtherm, .a and .a.b run
                    names |= {".".join(parts[: i + 1]) for i in range(len(parts))}
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # a relative import inside a subpackage: its own modules
                package = path.parent.relative_to(PACKAGE.parent).as_posix().replace("/", ".")
                module = package + (f".{node.module}" if node.module else "")
            elif node.module and node.module.split(".")[0] == "railtherm":
                module = node.module
            else:
                continue
            parts = module.split(".")
            names |= {".".join(parts[: i + 1]) for i in range(len(parts))}
            names |= {f"{module}.{alias.name}" for alias in node.names}
    return frozenset(names)


@functools.cache
def _reached(script: Path) -> tuple[Path, ...]:
    seen: set[Path] = set()
    todo = [script]
    while todo:
        path = todo.pop()
        if path in seen:
            continue
        seen.add(path)
        for name in _imported(path):
            todo += _module_files(name)
    files = {p for p in seen if p.is_relative_to(PACKAGE)}
    if any("schemas" in p.read_text(encoding="utf-8") for p in files):
        files |= set((PACKAGE / "schemas").glob("*.yaml"))
    return tuple(sorted(files))


def code_files(script: str | os.PathLike[str]) -> list[Path]:
    """Every railtherm file that ``script`` (a Python file) can run or read, sorted."""
    return list(_reached(Path(script).resolve()))


def code_digest(script: str | os.PathLike[str]) -> str:
    """Digest (16 hex digits) of the names and bytes of :func:`code_files` of ``script``."""
    h = hashlib.sha256()
    for path in code_files(script):
        h.update(path.relative_to(PACKAGE).as_posix().encode() + b"\0" + path.read_bytes())
    return h.hexdigest()[:16]
