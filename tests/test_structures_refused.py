"""The structure registry loads each module in isolation and refuses, with the reason and the
fix, a module that does not parse, does not import, declares no STRUCTURE, leaves out or
repeats an entry, or whose analytic derivatives disagree with central differences at its
start values. Here the registry's loader (railtherm.structures.discover) reads a package of
user modules written into a temporary directory, beside a healthy one it must keep."""

from __future__ import annotations

import itertools
import sys
from pathlib import Path

import numpy as np
import pytest

from railtherm import structures
from railtherm.errors import ConfigError
from railtherm.structures import _load

REPO = Path(__file__).resolve().parents[1]
SHIPPED = REPO / "railtherm" / "structures"
ENVELOPE = (SHIPPED / "interior_envelope.py").read_text()  # a structure without an order
_count = itertools.count()

# Appended to a copy of interior_envelope.py: every analytic derivative doubled.
DOUBLED = """
from dataclasses import replace as _replace

_exact = derivatives


def doubled(**theta):
    return {p: (2 * dA, 2 * dB) for p, (dA, dB) in _exact(**theta).items()}


STRUCTURE = _replace(STRUCTURE, jacobian=doubled)
"""


def registry(tmp_path: Path, monkeypatch, modules: dict[str, str]):
    """discover() over a new package in ``tmp_path`` holding ``modules`` ({name: source})
    and a healthy copy of interior_envelope.py named ``healthy``."""
    package = f"user_structures_{next(_count)}"
    folder = tmp_path / package
    folder.mkdir()
    (folder / "__init__.py").write_text("")
    for name, source in {"healthy": ENVELOPE, **modules}.items():
        (folder / f"{name}.py").write_text(source)
    monkeypatch.syspath_prepend(str(tmp_path))
    try:
        return structures.discover([str(folder)], package)
    finally:
        for name in [m for m in sys.modules if m.startswith(package)]:
            del sys.modules[name]


def refused_only(tmp_path, monkeypatch, name: str, source: str) -> str:
    """The module ``name`` holding ``source`` is refused, the healthy one beside it loaded;
    the reason as a command would print it."""
    found, refused = registry(tmp_path, monkeypatch, {name: source})
    assert list(found) == ["healthy"] and list(refused) == [name]
    message = str(refused[name])
    assert message.startswith(str(tmp_path)) and f"{name}.py" in message.split(":")[0]
    return message


def test_the_shipped_structures_pass_the_derivative_check():
    """Every shipped module loads and none is refused: their derivatives agree with central
    differences at their start values (the check the registry runs on each load)."""
    assert structures.REFUSED == {}
    assert list(structures.STRUCTURES) == [
        "first_order",
        "second_order",
        "interior_envelope",
        "interior_fittings",
    ]
    for s in structures.STRUCTURES.values():
        _load.check(s)  # raises on the first disagreeing entry


def test_the_derivative_check_sees_a_small_error():
    """The check is tight enough to see a 1 % error in one entry of one derivative, and
    loose enough to pass exact derivatives evaluated away from the start values."""
    s = structures.STRUCTURES["second_order"]
    exact = s.jacobian

    def off_by_one_percent(**theta):
        d = exact(**theta)
        dA, dB = d["C_veh"]
        dA = dA.copy()
        dA[1, 1] *= 1.01
        return {**d, "C_veh": (dA, dB)}

    from dataclasses import replace

    with pytest.raises(_load._Problem) as caught:
        _load.check_derivatives(replace(s, jacobian=off_by_one_percent))
    assert caught.value.key == "STRUCTURE.jacobian[C_veh]"
    assert "dA[1, 1]/dC_veh" in caught.value.value
    for scale in (1e-3, 1.0, 1e3):  # exact derivatives pass across the range of values
        initial = {p: v * scale for p, v in s.initial.items()}
        bounds = {p: (0.0, np.inf) for p in s.parameters}
        _load.check_derivatives(replace(s, initial=initial, bounds=bounds))


@pytest.mark.bad_input
def test_a_structure_with_doubled_derivatives_is_refused_by_name(tmp_path, monkeypatch):
    """Doubled analytic derivatives would halve every interval without a word: the module is
    refused, naming the structure's file, the parameter, the entry, both values and the
    fix."""
    message = refused_only(tmp_path, monkeypatch, "doubled", ENVELOPE + DOUBLED)
    assert "doubled.py: key 'STRUCTURE.jacobian[C]'" in message
    assert "dA[0, 0]/dC" in message and "disagrees with the central difference" in message
    assert "correct dA[0, 0]/dC in the function given as jacobian" in message


@pytest.mark.bad_input
def test_one_wrong_derivative_entry_is_named(tmp_path, monkeypatch):
    """One sign flipped in dB/dK_o (the outdoor air's entry into the envelope): the message
    names that parameter and that entry."""
    source = ENVELOPE.replace(
        '"K_o": (np.array([[0.0, 0.0], [0.0, -1 / C_e]]), np.array([[0.0, 0.0], [1 / C_e, 0.0]]))',
        '"K_o": (np.array([[0.0, 0.0], [0.0, -1 / C_e]]), np.array([[0.0, 0.0], [-1 / C_e, 0.0]]))',
    )
    assert source != ENVELOPE
    message = refused_only(tmp_path, monkeypatch, "flipped", source)
    assert "STRUCTURE.jacobian[K_o]" in message and "dB[1, 0]/dK_o" in message


@pytest.mark.bad_input
def test_a_module_with_a_syntax_error_is_refused_naming_the_line(tmp_path, monkeypatch):
    source = ENVELOPE.replace(
        '    title="interior-envelope model",', '    title="interior-envelope,'
    )
    message = refused_only(tmp_path, monkeypatch, "typo", source)
    line = 1 + ENVELOPE.splitlines().index('    title="interior-envelope model",')
    assert f"key 'line {line}'" in message
    assert "syntax error" in message and "correct this line of the module" in message


@pytest.mark.bad_input
def test_a_key_written_twice_is_refused_though_python_keeps_the_last(tmp_path, monkeypatch):
    """initial={"C": ..., "K_i": ..., "C_e": ..., "K_o": ..., "C": 1.0}: Python keeps 1.0 and
    drops the first value without a word; the registry names the key and both lines."""
    source = ENVELOPE.replace('"K_o": 1000.0},', '"K_o": 1000.0,\n        "C": 120_480.0,\n    },')
    assert source != ENVELOPE
    message = refused_only(tmp_path, monkeypatch, "twice", source)
    first = 1 + next(i for i, t in enumerate(source.splitlines()) if "initial={" in t)
    assert "= 'C'" in message and f"(lines {first} and {first + 1})" in message
    assert "keep one entry for it" in message


@pytest.mark.bad_input
def test_a_module_without_structure_is_refused(tmp_path, monkeypatch):
    source = ENVELOPE.replace("STRUCTURE = Structure(", "MODEL = Structure(")
    message = refused_only(tmp_path, monkeypatch, "nameless", source)
    assert "key 'STRUCTURE' = None" in message and "add STRUCTURE = Structure(...)" in message


@pytest.mark.bad_input
def test_a_structure_that_is_no_structure_is_refused(tmp_path, monkeypatch):
    message = refused_only(tmp_path, monkeypatch, "plain", ENVELOPE + "\nSTRUCTURE = dict()\n")
    assert "= 'dict'" in message and "is not a Structure" in message


@pytest.mark.bad_input
def test_a_module_that_fails_on_import_is_refused(tmp_path, monkeypatch):
    source = ENVELOPE.replace("import numpy as np", "import numpy as np\nimport no_such_module")
    message = refused_only(tmp_path, monkeypatch, "missing_import", source)
    assert "key '(import)'" in message and "No module named 'no_such_module'" in message
    assert "run it with python to see where, and fix it" in message


@pytest.mark.bad_input
def test_a_parameter_without_a_start_value_is_refused(tmp_path, monkeypatch):
    source = ENVELOPE.replace(', "K_o": 1000.0},', "},")
    assert source != ENVELOPE
    message = refused_only(tmp_path, monkeypatch, "no_start", source)
    assert "key 'STRUCTURE.initial' = 'K_o'" in message
    assert "give a start value for every parameter (C, K_i, C_e, K_o)" in message


@pytest.mark.bad_input
def test_derivatives_missing_a_parameter_are_refused(tmp_path, monkeypatch):
    source = ENVELOPE + (
        "\nfrom dataclasses import replace as _replace\n"
        "_all = derivatives\n"
        "STRUCTURE = _replace(STRUCTURE, jacobian=lambda **t: "
        "{p: d for p, d in _all(**t).items() if p != 'C_e'})\n"
    )
    message = refused_only(tmp_path, monkeypatch, "partial", source)
    assert "key 'STRUCTURE.jacobian' = ['C', 'K_i', 'K_o']" in message
    assert "for exactly the parameters C, K_i, C_e, K_o" in message


@pytest.mark.bad_input
def test_a_start_value_outside_its_bounds_is_refused(tmp_path, monkeypatch):
    source = ENVELOPE.replace('"C_e": 500_000.0, "K_o"', '"C_e": 1.0, "K_o"')
    assert source != ENVELOPE
    message = refused_only(tmp_path, monkeypatch, "tiny", source)
    assert "key 'STRUCTURE.initial[C_e]' = 1.0" in message and "inside the bounds" in message


@pytest.mark.bad_input
def test_two_modules_claiming_one_model_key_are_both_refused(tmp_path, monkeypatch):
    """Which of two modules declaring order 2 a vehicle means cannot be told: both are
    refused by name, and a vehicle asking for order2 is told so."""
    second = (SHIPPED / "second_order.py").read_text()
    found, refused = registry(tmp_path, monkeypatch, {"second": second, "twin": second})
    assert list(found) == ["healthy"] and list(refused) == ["second", "twin"]
    for name in ("second", "twin"):
        assert refused[name].model_key == "order2"
        assert "'second' and 'twin' both declare the model key 'order2'" in str(refused[name])
        assert "give one of them another order, or none" in str(refused[name])


@pytest.mark.bad_input
def test_asking_the_registry_for_a_refused_key_names_the_module(monkeypatch):
    """by_key and the vehicle check stop only where the refused key is asked for."""
    from railtherm import config

    broken = _load.Refused("broken", "/x/broken.py", "line 3", "(", "syntax error: fix it")
    monkeypatch.setitem(structures.REFUSED, "broken", broken)
    with pytest.raises(ConfigError, match=r"/x/broken.py: key 'line 3'"):
        structures.by_key("broken")
    assert structures.by_key("order2").name == "second_order"
    assert "broken" in structures.further(include_refused=True)
    assert "broken" not in structures.further()
    model = {"orders": [1], "structures": ["interior_envelope", "broken"]}
    with pytest.raises(ConfigError) as caught:
        config._check_structures("v.yaml", model)
    assert str(caught.value).startswith("v.yaml: key 'model.structures[1]' = 'broken'")
    assert "/x/broken.py" in str(caught.value) and "drop broken from model.structures" in str(
        caught.value
    )
    config._check_structures("v.yaml", {"orders": [1, 2], "structures": ["interior_envelope"]})


@pytest.mark.bad_input
def test_a_broken_copy_declaring_an_order_leaves_the_sound_module_of_that_order(monkeypatch):
    """A refused module whose text says order=2 beside a sound second_order.py: a vehicle
    asking for order 2 is fitted by second_order.py; asked for by its name, the refused
    module is named."""
    from railtherm import config

    copy = _load.Refused("my_copy", "/x/my_copy.py", "line 9", "", "syntax error: fix it", 2)
    monkeypatch.setitem(structures.REFUSED, "my_copy", copy)
    assert copy.model_key == "order2" and structures.refused("order2") == []
    assert structures.by_key("order2").name == "second_order"
    config._check_structures("v.yaml", {"orders": [1, 2], "structures": []})
    assert structures.refused("my_copy") == [copy]


@pytest.mark.bad_input
def test_the_storage_correction_asks_for_order_2(monkeypatch):
    """A vehicle fitting only order 1 but with a k window corrects eq. 10's kA for storage
    with the second-order model: with second_order.py refused it is refused at
    kvalue.storage_correction, naming the module and both ways out; without the correction
    (switched off, joint mode, or no k window) it passes."""
    from railtherm import config

    broken = _load.Refused(
        "second_order", "/x/second_order.py", "line 52", "kA", "written twice: fix it", 2
    )
    monkeypatch.setitem(structures.REFUSED, "second_order", broken)
    loaded = {k: s for k, s in structures._BY_KEY.items() if k != "order2"}
    monkeypatch.setattr(structures, "_BY_KEY", loaded)  # the registry's own dict untouched
    model = {"orders": [1], "structures": []}
    k_window = {"windows": {"kvalue": {"start": 0, "end": 1}}, "kvalue": {}}
    with pytest.raises(ConfigError) as caught:
        config._check_structures("v.yaml", model, k_window)
    message = str(caught.value)
    assert message.startswith("v.yaml: key 'kvalue.storage_correction' = True")
    assert "/x/second_order.py: key 'line 52'" in message
    assert "set kvalue.storage_correction: false (or model.mode: joint)" in message
    off = {**k_window, "kvalue": {"storage_correction": False}}
    config._check_structures("v.yaml", model, off)
    config._check_structures("v.yaml", {**model, "mode": "joint"}, k_window)
    config._check_structures("v.yaml", model, {"windows": {}, "kvalue": {}})
    with pytest.raises(ConfigError, match="key 'model.orders\\[1\\]' = 2"):
        config._check_structures("v.yaml", {"orders": [1, 2]}, k_window)


@pytest.mark.bad_input
@pytest.mark.parametrize(
    "entry, message",
    [
        ("", "key 'STRUCTURE.jacobian' = None: a required entry is missing: give jacobian=..."),
        (
            "    jacobain=derivatives,\n",
            "key 'STRUCTURE.jacobain' = None: Structure has no entry 'jacobain': did you mean "
            "jacobian?",
        ),
    ],
)
def test_a_required_entry_left_out_or_misspelt_is_named(tmp_path, monkeypatch, entry, message):
    source = ENVELOPE.replace("    jacobian=derivatives,\n", entry)
    assert source != ENVELOPE
    assert message in refused_only(tmp_path, monkeypatch, "incomplete", source)
