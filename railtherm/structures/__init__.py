"""The model structures railtherm fits, one module per structure.

Every module of this package whose name does not start with an underscore declares one
grey-box thermal network as ``STRUCTURE``, a :class:`Structure`: its states, inputs,
parameters with start values, bounds, units and descriptions, how the overall kA follows,
which sensors measure which state, which smaller structure it nests, and the functions giving
its continuous (A, B) and their analytic derivatives. The module's file name is the
structure's name. Nothing else in railtherm names a structure: the config schema, the
command line, the fits, the figures and the tables all read this registry, so a new network is
one new file here (docs/structures.md).

- :data:`STRUCTURES`: {name: Structure}, the paper's orders first, then by name;
- :func:`by_key`: the structure of a model key (order1, order2, or a name);
- :func:`keys`, :func:`orders`, :func:`further`: the model keys, the paper's orders and the
  further structures' names, as config files and the command line take them.
"""

from __future__ import annotations

import importlib
import pkgutil
from dataclasses import replace

from railtherm.structures._structure import Structure

__all__ = [
    "STRUCTURES",
    "Structure",
    "by_key",
    "further",
    "keys",
    "measurable_states",
    "of_kind",
    "of_fit",
    "nesting",
    "orders",
    "parameters",
    "unit",
    "with_envelope",
]


def _discover() -> dict[str, Structure]:
    """Import every public module of this package and take its ``STRUCTURE``, named after the
    module; ordered by the paper's order, then by name. A module without a Structure, or two
    structures under one model key, is an error naming the file."""
    found = []
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{__name__}.{info.name}")
        declared = getattr(module, "STRUCTURE", None)
        if not isinstance(declared, Structure):
            raise TypeError(
                f"{module.__file__}: a structure module declares STRUCTURE = Structure(...)"
            )
        found.append(replace(declared, name=info.name))
    found.sort(key=lambda s: (s.order is None, s.order or 0, s.name))
    by_key: dict[str, Structure] = {}
    for s in found:
        if s.key in by_key:
            raise ValueError(
                f"structures {by_key[s.key].name!r} and {s.name!r} both declare the model key "
                f"{s.key!r} (order={s.order}): give one of them another order, or none"
            )
        by_key[s.key] = s
    return {s.name: s for s in found}


STRUCTURES: dict[str, Structure] = _discover()
_BY_KEY = {s.key: s for s in STRUCTURES.values()}


def by_key(key: str) -> Structure:
    """The structure of a model key: order1, order2 or a further structure's name."""
    if key not in _BY_KEY:
        raise KeyError(f"unknown model {key!r}; known: {', '.join(_BY_KEY)}")
    return _BY_KEY[key]


def keys() -> list[str]:
    """Every model key, the paper's orders first (order1, order2, then the others by name)."""
    return list(_BY_KEY)


def orders() -> list[int]:
    """The paper's model orders ``model.orders`` takes (1, 2)."""
    return [s.order for s in STRUCTURES.values() if s.order]


def further() -> list[str]:
    """The names ``model.structures`` takes: every structure that is not one of the orders."""
    return [s.name for s in STRUCTURES.values() if not s.order]


def nesting() -> tuple[tuple[str, str, int], ...]:
    """(smaller key, larger key, parameters on the boundary) for every nested pair the model
    selection tests: each structure's ``nests``."""
    return tuple(
        (small, s.key, int(boundary))
        for s in STRUCTURES.values()
        for small, boundary in s.nests.items()
        if small in _BY_KEY
    )


def parameters() -> list[str]:
    """Every structure's parameters, each once, in the registry's order (kA, C_bar, C, K_veh,
    C_veh, then the further structures'): the names ``model.initial`` and ``model.bounds``
    take besides the solar ones."""
    return of_kind("parameters")


def with_envelope() -> list[str]:
    """The model keys of the structures with an envelope node (where a solar gain declared on
    the envelope can enter)."""
    return [s.key for s in STRUCTURES.values() if s.envelope]


def of_kind(kind: str) -> list[str]:
    """Every structure's ``capacities`` or ``conductances`` (``kind``), each once, in the
    registry's order."""
    return list(dict.fromkeys(p for s in STRUCTURES.values() for p in getattr(s, kind)))


def measurable_states() -> list[str]:
    """The states a sensor can measure (``model.outputs``): every structure's ``sensors``, and
    its envelope state (measured where ``model.envelope_sensors`` says so)."""
    found = [x for s in STRUCTURES.values() for x in s.sensors]
    found += [s.states[1] for s in STRUCTURES.values() if s.envelope]
    return list(dict.fromkeys(found))


def unit(parameter: str) -> str:
    """The SI unit of a structure parameter: J/K for a capacity, W/K for a conductance, m² for
    an aperture a_<name>; '' for a dimensionless one (a share f_<name>)."""
    for s in STRUCTURES.values():
        if parameter in s.parameters:
            return s.unit(parameter)
    return "m²" if parameter.startswith("a_") else ""


def of_fit(name: str) -> Structure:
    """The registered structure of a fit's ``structure`` name, irradiance inputs dropped
    (``second_order+I_sol`` -> second_order)."""
    return STRUCTURES[name.split("+")[0]]
