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
- :data:`REFUSED`: {name: Refused}, the modules that fail to import, leave out or repeat an
  entry, or whose analytic derivatives disagree with central differences at their start
  values, each with the reason and the fix. Each module is loaded in isolation: a refused
  one stops only the vehicles and commands that ask for it (:func:`refused`);
- :func:`by_key`: the structure of a model key (order1, order2, or a name);
- :func:`keys`, :func:`orders`, :func:`further`: the model keys, the paper's orders and the
  further structures' names, as config files and the command line take them.
"""

from __future__ import annotations

import os
import pkgutil
from collections.abc import Iterable

from railtherm.structures._load import Refused, load
from railtherm.structures._structure import Structure

__all__ = [
    "REFUSED",
    "STRUCTURES",
    "Refused",
    "Structure",
    "by_key",
    "discover",
    "further",
    "keys",
    "measurable_states",
    "named",
    "of_kind",
    "of_fit",
    "nesting",
    "orders",
    "parameters",
    "refused",
    "unit",
    "with_envelope",
]


def discover(path: Iterable[str], package: str) -> tuple[dict[str, Structure], dict[str, Refused]]:
    """Load every public module of ``package`` (found on ``path``), each in isolation
    (:func:`railtherm.structures._load.load`): ({name: Structure}, ordered by the paper's
    order, then by name; {name: Refused}, the modules that fail to load or to pass the
    checks, with the reason). Two modules that claim one model key are both refused: which
    one a vehicle means cannot be told."""
    found, refused = [], {}
    for info in sorted(pkgutil.iter_modules(list(path)), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        file = os.path.join(info.module_finder.path, info.name)
        file = os.path.join(file, "__init__.py") if info.ispkg else f"{file}.py"
        loaded = load(info.name, package, file)
        if isinstance(loaded, Refused):
            refused[info.name] = loaded
        else:
            found.append((loaded, file))
    found.sort(key=lambda sf: (sf[0].order is None, sf[0].order or 0, sf[0].name))
    claims: dict[str, list[tuple[Structure, str]]] = {}
    for s, file in found:
        claims.setdefault(s.key, []).append((s, file))
    for key, claimants in claims.items():
        if len(claimants) > 1:
            names = " and ".join(repr(s.name) for s, _ in claimants)
            for s, file in claimants:
                refused[s.name] = Refused(
                    s.name,
                    file,
                    "STRUCTURE.order",
                    s.order,
                    f"structures {names} both declare the model key {key!r} (order="
                    f"{s.order}): give one of them another order, or none",
                    s.order,
                )
    healthy = {s.name: s for s, _ in found if s.name not in refused}
    return healthy, dict(sorted(refused.items()))


STRUCTURES, REFUSED = discover(__path__, __name__)
_BY_KEY = {s.key: s for s in STRUCTURES.values()}


def refused(key: str) -> list[Refused]:
    """The refused modules behind a model key (order<n> or a name) that no loaded structure
    serves: empty when none. (A refused module whose text declares order 2 beside a sound
    second_order.py does not stop the vehicles asking for order 2.)"""
    if key in _BY_KEY:
        return []
    return [r for r in REFUSED.values() if key in (r.model_key, r.name)]


def by_key(key: str) -> Structure:
    """The structure of a model key: order1, order2 or a further structure's name. A key
    whose module is refused raises its :class:`~railtherm.errors.ConfigError`, naming the
    module's file, the entry and the fix."""
    if key not in _BY_KEY:
        for r in refused(key):
            raise r.error()
        raise KeyError(f"unknown model {key!r}; known: {', '.join(_BY_KEY)}")
    return _BY_KEY[key]


def named(name: str) -> Structure:
    """The structure of a module name (second_order, interior_envelope). A refused module
    raises its :class:`~railtherm.errors.ConfigError`, naming the file, the entry and the
    fix."""
    if name not in STRUCTURES and name in REFUSED:
        raise REFUSED[name].error()
    if name not in STRUCTURES:
        raise KeyError(f"unknown structure {name!r}; known: {', '.join(STRUCTURES)}")
    return STRUCTURES[name]


def keys(include_refused: bool = False) -> list[str]:
    """Every model key, the paper's orders first (order1, order2, then the others by name);
    with ``include_refused``, the keys of refused modules too (the names a vehicle or the
    command line may ask for, to be told why the structure is refused)."""
    found = list(_BY_KEY)
    if include_refused:
        found += [r.model_key for r in REFUSED.values()]
    return list(dict.fromkeys(found))


def orders(include_refused: bool = False) -> list[int]:
    """The paper's model orders ``model.orders`` takes (1, 2); with ``include_refused``, the
    orders of refused modules too."""
    found = [s.order for s in STRUCTURES.values() if s.order]
    if include_refused:
        found = sorted({*found, *(r.order for r in REFUSED.values() if r.order)})
    return found


def further(include_refused: bool = False) -> list[str]:
    """The names ``model.structures`` takes: every structure that is not one of the orders;
    with ``include_refused``, the refused modules' that declare no order too."""
    found = [s.name for s in STRUCTURES.values() if not s.order]
    if include_refused:
        found += [r.name for r in REFUSED.values() if not r.order]
    return found


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


def search_bounds(parameter: str) -> tuple[float, float] | None:
    """The widest search bounds a registered structure gives ``parameter`` (None for a
    parameter no structure bounds)."""
    found = [s.bounds[parameter] for s in STRUCTURES.values() if parameter in s.bounds]
    if not found:
        return None
    return min(float(b[0]) for b in found), max(float(b[1]) for b in found)


def noise_parameters() -> list[str]:
    """The names a Kalman estimator's noise priors take: ``sigma_<state>`` (a state's
    diffusion) for every structure's states, ``s_<output>`` (an output's measurement
    variance) for every state a sensor can measure."""
    states = dict.fromkeys(x for s in STRUCTURES.values() for x in s.states)
    return [f"sigma_{x}" for x in states] + [f"s_{x}" for x in measurable_states()]


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
