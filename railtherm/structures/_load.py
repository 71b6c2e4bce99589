"""Loading one structure module in isolation, and the checks a structure passes before the
registry (:mod:`railtherm.structures`) offers it.

A module is read, parsed, imported and checked on its own: one that fails to parse or import,
declares no ``STRUCTURE``, leaves a required entry out, writes a key twice in a dict literal
(Python keeps the last value silently), or whose analytic derivatives disagree with central
differences at its start values is a :class:`Refused` module. The registry keeps the reason,
and only a vehicle or command that asks for that structure is refused with it.
"""

from __future__ import annotations

import ast
import difflib
import importlib
import math
import re
from collections.abc import Callable
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from railtherm.errors import ConfigError
from railtherm.structures._structure import Structure

# Central differences at the start values: step h = STEP * |theta_p|, and an entry disagrees
# when |analytic - central| exceeds RTOL of the larger of the two, plus the difference's own
# rounding (a few ulps of the matrix entry over h) and ATOL of the largest entry of that
# parameter's derivative. A doubled or sign-flipped entry misses by 100 %; an exact one by
# about STEP**2 (truncation) and 1e-16 / STEP (rounding) relative.
# The suffix of a model key fitted by the Kalman filter (railtherm.study.fitsettings.KALMAN_SUFFIX):
# a module named with it could not be asked for by output error.
KALMAN_SUFFIX = "_kalman"

STEP = 1e-6
RTOL = 1e-5
ATOL = 1e-7
ROUNDING_ULPS = 64


@dataclass(frozen=True)
class Refused:
    """A structure module the registry refuses: its module name, file, the key (a line, or
    an entry of ``STRUCTURE``) and value that are wrong, and the reason with the fix.
    ``order`` is the paper's order the module's text declares (``order=<n>``), so that a
    vehicle asking for that order is told which module failed; None if it declares none."""

    name: str
    file: str
    key: str
    value: Any
    reason: str
    order: int | None = None

    @property
    def model_key(self) -> str:
        """The model key a vehicle asks for this structure by: order<n>, else its name."""
        return f"order{self.order}" if self.order else self.name

    def error(self) -> ConfigError:
        """The error a command that needs this structure stops with."""
        return ConfigError(self.file, self.key, self.value, self.reason)

    def __str__(self) -> str:
        return str(self.error())


class _Problem(Exception):
    """One thing wrong with a module: the key, the value and the reason with its fix."""

    def __init__(self, key: str, value: Any, reason: str):
        super().__init__(reason)
        self.key, self.value, self.reason = key, value, reason


def load(name: str, package: str, file: str) -> Structure | Refused:
    """The structure of module ``package.name`` (source ``file``) named after the module, or
    the reason it is refused. Never raises for anything the module holds."""
    try:
        source = Path(file).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        return Refused(name, file, "(file)", None, f"cannot be read ({err}): fix the file")
    order = declared_order(source)
    if name.endswith(KALMAN_SUFFIX):
        return Refused(
            name,
            file,
            "(file name)",
            Path(file).name,
            f"a structure's name may not end in {KALMAN_SUFFIX}, the suffix of a model key "
            f"that asks for the Kalman-filter estimator (the key {name} reads as "
            f"{name[: -len(KALMAN_SUFFIX)]} fitted by the filter): rename the file, e.g. "
            f"{name[: -len(KALMAN_SUFFIX)]}.py, and ask for the filter with "
            "model.estimator: kalman",
            order,
        )
    try:
        tree = _parse(source, file)
        _duplicate_keys(tree)
        module = _import(f"{package}.{name}")
        declared = getattr(module, "STRUCTURE", None)
        if declared is None:
            raise _Problem(
                "STRUCTURE",
                None,
                "the module declares no STRUCTURE: add STRUCTURE = Structure(...) at the "
                "end of the file (docs/structures.md), or prefix the file name with _ if it "
                "is a helper, not a structure",
            )
        if not isinstance(declared, Structure):
            raise _Problem(
                "STRUCTURE",
                type(declared).__name__,
                "is not a Structure: declare STRUCTURE = Structure(...) "
                "(from railtherm.structures._structure import Structure)",
            )
        order = declared.order
        structure = replace(declared, name=name)
        check(structure)
    except _Problem as problem:
        return Refused(name, file, problem.key, problem.value, problem.reason, order)
    return structure


def declared_order(source: str) -> int | None:
    """The ``order=<n>`` a module's text declares (read even when it does not parse)."""
    found = re.search(r"\border\s*=\s*(\d+)", source)
    return int(found.group(1)) if found else None


def _parse(source: str, file: str) -> ast.Module:
    try:
        return ast.parse(source, filename=file)
    except SyntaxError as err:
        line = (err.text or "").strip()
        raise _Problem(
            f"line {err.lineno}",
            line,
            f"syntax error ({err.msg}): correct this line of the module",
        ) from None


def _duplicate_keys(tree: ast.Module) -> None:
    """A dict literal that writes one key twice: Python keeps the last value without a word,
    so the first one written is silently ignored."""
    for node in ast.walk(tree):
        if not isinstance(node, ast.Dict):
            continue
        seen: dict[Any, int] = {}
        for key in node.keys:
            if not isinstance(key, ast.Constant):
                continue
            if key.value in seen:
                first = seen[key.value]
                where = (
                    f"lines {first} and {key.lineno}" if first != key.lineno else f"line {first}"
                )
                raise _Problem(
                    f"line {key.lineno}",
                    key.value,
                    f"this key is written twice in one dict ({where}); Python keeps the "
                    "last value and drops the first without a word: keep one entry for it",
                )
            seen[key.value] = key.lineno


def _import(module_name: str):
    try:
        return importlib.import_module(module_name)
    except TypeError as err:
        if "Structure.__init__()" in str(err):
            raise _entry_problem(str(err)) from None
        raise _Problem(
            "(import)",
            f"{type(err).__name__}: {err}",
            "the module fails when imported: run it with python to see where, and fix it",
        ) from None
    except (Exception, SystemExit) as err:  # a user's module may raise anything
        raise _Problem(
            "(import)",
            f"{type(err).__name__}: {err}",
            "the module fails when imported: run it with python to see where, and fix it",
        ) from None


def _entry_problem(text: str) -> _Problem:
    """``Structure(...)`` called without a required entry or with one it does not have (a
    misspelt name): the entry and the fix."""
    entries = [f.name for f in fields(Structure) if f.name != "name"]
    named = re.findall(r"'(\w+)'", text)
    if "unexpected keyword" in text and named:
        close = difflib.get_close_matches(named[0], entries, n=1)
        hint = f"did you mean {close[0]}? " if close else ""
        return _Problem(
            f"STRUCTURE.{named[0]}",
            None,
            f"Structure has no entry {named[0]!r}: {hint}the entries are {', '.join(entries)}",
        )
    if "missing" in text and named:
        return _Problem(
            f"STRUCTURE.{named[0]}",
            None,
            f"a required entry is missing: give {named[0]}=... in STRUCTURE = Structure(...) "
            "(parameters, states, build and jacobian are required; docs/structures.md)",
        )
    return _Problem("STRUCTURE", text, "Structure(...) is called wrongly: fix the call")


def check(s: Structure) -> None:
    """The entries every structure needs, consistent with each other, and its analytic
    derivatives against central differences at its start values (:func:`check_derivatives`).
    Raises :class:`_Problem` naming the first entry that is wrong."""
    parameters = tuple(s.parameters)
    if not parameters or len(set(parameters)) != len(parameters):
        raise _Problem(
            "STRUCTURE.parameters",
            list(parameters),
            "must name each parameter once, at least one",
        )
    if not s.states:
        raise _Problem("STRUCTURE.states", list(s.states), "must name the states, air first")
    for field in ("initial", "bounds"):
        given = getattr(s, field)
        missing = [p for p in parameters if p not in given]
        if missing:
            what = "a start value" if field == "initial" else "bounds (low, high)"
            raise _Problem(
                f"STRUCTURE.{field}",
                missing[0],
                f"no entry for parameter {missing[0]!r}: give {what} for every parameter "
                f"({', '.join(parameters)}), SI units",
            )
        extra = [p for p in given if p not in parameters]
        if extra:
            raise _Problem(
                f"STRUCTURE.{field}",
                extra[0],
                f"{extra[0]!r} is not a parameter ({', '.join(parameters)}): remove it or "
                "add it to parameters",
            )
    for p in parameters:
        value = s.initial[p]
        try:
            lo, hi = (float(b) for b in s.bounds[p])
            value = float(value)
        except (TypeError, ValueError):
            raise _Problem(
                f"STRUCTURE.bounds[{p}]",
                s.bounds[p],
                "must be (low, high), numbers, with a number as initial",
            ) from None
        if not lo > 0:
            raise _Problem(
                f"STRUCTURE.bounds[{p}]",
                s.bounds[p],
                f"the lower bound of {p} must be > 0: capacities and conductances are "
                "positive and are estimated as their logarithms; give a small positive "
                "low (e.g. 1e-1 W/K, 1e4 J/K)",
            )
        if not (math.isfinite(value) and lo < hi and lo <= value <= hi):
            raise _Problem(
                f"STRUCTURE.initial[{p}]",
                value,
                f"must be a finite number inside the bounds {s.bounds[p]} (low < high)",
            )
    for field in ("capacities", "conductances", "coupled", "loss_path"):
        _subset(field, getattr(s, field), parameters)
    for total, summed in s.totals.items():
        _subset(f"totals[{total}]", summed, parameters)
    for field in ("air", "envelope"):
        value = getattr(s, field)
        if (value or field == "air") and value not in parameters:
            raise _Problem(
                f"STRUCTURE.{field}",
                value,
                f"must name the capacity of the {field} node, one of {', '.join(parameters)}",
            )
    strange = [x for x in s.sensors if x not in s.states]
    if strange:
        raise _Problem(
            "STRUCTURE.sensors", strange[0], f"not a state ({', '.join(s.states)}): fix the key"
        )
    if "kA" not in parameters and not s.loss_path:
        raise _Problem(
            "STRUCTURE.loss_path",
            list(s.loss_path),
            "without a parameter kA the overall kA needs the loss path: name the "
            "conductances in series from the air to the outdoors",
        )
    check_derivatives(s)


def _subset(field: str, values, parameters: tuple[str, ...]) -> None:
    strange = [v for v in values if v not in parameters]
    if strange:
        raise _Problem(
            f"STRUCTURE.{field}",
            strange[0],
            f"not a parameter ({', '.join(parameters)}): fix the name or add it to parameters",
        )


def _matrices(s: Structure, theta: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) from ``build`` at ``theta`` as float arrays."""

    def evaluate():
        A, B = s.matrices(theta)
        return np.asarray(A, dtype=float), np.asarray(B, dtype=float)

    return _call(s, "build", evaluate)


def _call(s: Structure, what: str, function: Callable[[], Any]) -> Any:
    try:
        return function()
    except Exception as err:  # a user's function may raise anything
        raise _Problem(
            f"STRUCTURE.{what}",
            f"{type(err).__name__}: {err}",
            f"the function given as {what} fails at the start values (initial): fix it",
        ) from None


def check_derivatives(s: Structure) -> None:
    """The analytic derivatives of (A, B) (``jacobian``) against central differences of
    ``build`` at the start values, entry by entry: 2 evaluations of (A, B) per parameter and
    one of the derivatives. The first entry that disagrees names the parameter, the matrix
    entry and both values."""
    theta = {p: float(s.initial[p]) for p in s.parameters}
    A, B = _matrices(s, theta)
    n, m = len(s.states), len(s.inputs)
    if (
        A.shape != (n, n)
        or B.shape != (n, m)
        or not (np.isfinite(A).all() and np.isfinite(B).all())
    ):
        raise _Problem(
            "STRUCTURE.build",
            f"A {A.shape}, B {B.shape}",
            f"must give finite A ({n} x {n}: the states) and B ({n} x {m}: the inputs "
            f"{', '.join(s.inputs)}) at the start values",
        )
    derivatives = _call(s, "jacobian", lambda: s.derivatives(theta))
    if not isinstance(derivatives, dict) or set(derivatives) != set(s.parameters):
        given = sorted(derivatives) if isinstance(derivatives, dict) else derivatives
        raise _Problem(
            "STRUCTURE.jacobian",
            given,
            "must give {parameter: (dA/dparameter, dB/dparameter)} for exactly the "
            f"parameters {', '.join(s.parameters)}",
        )
    for p in s.parameters:
        h = STEP * (abs(theta[p]) or 1.0)
        up = _matrices(s, {**theta, p: theta[p] + h})
        down = _matrices(s, {**theta, p: theta[p] - h})
        pair = derivatives[p]
        if not (isinstance(pair, tuple | list) and len(pair) == 2):
            raise _Problem(
                f"STRUCTURE.jacobian[{p}]", type(pair).__name__, "must be a pair (dA, dB)"
            )
        central = [(u - d) / (2 * h) for u, d in zip(up, down, strict=True)]
        try:
            analytic = [np.asarray(x, dtype=float) for x in pair]
        except (TypeError, ValueError):
            raise _Problem(
                f"STRUCTURE.jacobian[{p}]", repr(pair)[:80], "must be a pair of arrays (dA, dB)"
            ) from None
        scale = max(float(np.max(np.abs(c), initial=0.0)) for c in central)
        for label, exact, numeric, value in zip("AB", analytic, central, (A, B), strict=True):
            if exact.shape != numeric.shape or not np.isfinite(exact).all():
                raise _Problem(
                    f"STRUCTURE.jacobian[{p}]",
                    f"d{label} {exact.shape}",
                    f"d{label}/d{p} must be finite and of {label}'s shape {numeric.shape}",
                )
            rounding = ROUNDING_ULPS * np.finfo(float).eps * np.abs(value) / h
            tolerance = RTOL * np.maximum(np.abs(exact), np.abs(numeric)) + rounding
            tolerance += ATOL * scale
            wrong = np.argwhere(np.abs(exact - numeric) > tolerance)
            if len(wrong):
                i, j = (int(k) for k in wrong[0])
                raise _Problem(
                    f"STRUCTURE.jacobian[{p}]",
                    f"d{label}[{i}, {j}]/d{p} = {exact[i, j]:.6g}",
                    f"disagrees with the central difference of build, {numeric[i, j]:.6g}, "
                    f"at the start values (initial): correct d{label}[{i}, {j}]/d{p} in the "
                    f"function given as jacobian (or {label}[{i}, {j}] in the one given as "
                    "build); wrong derivatives give wrong intervals",
                )
