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

import functools
import hashlib
import os
import re
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
        if "pkgutil" in _text(init):  # structure registry), every module
            return sorted(path.rglob("*.py"))
        return [init]
    return []


# an import statement at the start of a line, at any indentation (also inside a function):
# ``import a.b [as c], d`` or ``from [.]a.b import x [as y], z`` with the names on one line or
# in parentheses over several; read from the text, which is ten times faster than parsing
# every module. A line of a docstring that reads like an import only adds a file: the digest
# then covers more code, never less.
_IMPORT = re.compile(
    r"^[ \t]*(?:from[ \t]+(?P<module>\.*[\w.]*)[ \t]+import[ \t]+(?P<names>\([^)]*\)|[^\n#;]*)"
    r"|import[ \t]+(?P<modules>[^\n#;]*))",
    re.MULTILINE,
)


@functools.cache
def _text(path: Path) -> str:
    return path.read_text(encoding="utf-8")


def _names(clause: str) -> list[str]:
    """The imported names of ``a as b, c`` or ``(a as b,\n c)`` (comments dropped)."""
    clause = re.sub(r"#[^\n]*", "", clause).strip("() \t\n")
    return [part.split()[0] for part in clause.split(",") if part.split()]


@functools.cache
def _imported(path: Path) -> frozenset[str]:
    """The railtherm modules (dotted names; also names that may be attributes) that a source
    file imports anywhere in it."""
    source = _text(path)
    if "railtherm" not in source and not path.is_relative_to(PACKAGE):
        return frozenset()
    names: set[str] = set()
    for m in _IMPORT.finditer(source):
        if m["modules"] is not None:  # import railtherm.a.b: railtherm, .a and .a.b run
            for name in _names(m["modules"]):
                parts = name.split(".")
                if parts[0] == "railtherm":
                    names |= {".".join(parts[: i + 1]) for i in range(len(parts))}
            continue
        module = m["module"]
        if module.startswith("."):  # a relative import inside a subpackage: its own modules
            if not path.is_relative_to(PACKAGE):
                continue
            level = len(module) - len(module.lstrip("."))
            package = path.parent.relative_to(PACKAGE.parent).as_posix().split("/")
            package = package[: len(package) - (level - 1)]
            module = ".".join(package + ([module[level:]] if module[level:] else []))
        elif module.split(".")[0] != "railtherm":
            continue
        parts = module.split(".")
        names |= {".".join(parts[: i + 1]) for i in range(len(parts))}
        names |= {f"{module}.{name}" for name in _names(m["names"])}
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
    if any("schemas" in _text(p) for p in files):
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
