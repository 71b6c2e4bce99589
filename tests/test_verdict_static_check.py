"""The two-stage check's sentences hold together, and the joint fit replacing a two-stage fit
whose kA agrees with the static test is a note, not a reason of the verdict.

The case built here is the one where the two yardsticks of the check part: a static kA 1 %
off with 0.5 % claimed (within 3 times the static test's own uncertainty), which the records,
whose difference from it leaves out the errors both share, put more than 3 standard
uncertainties away."""

from __future__ import annotations

import re

import pytest
from test_kvalue_storage import WITHOUT_SURFACE, k_stage, k_window, vehicle

from railtherm.study import fitsettings, identify, quality


@pytest.fixture(scope="module")
def contradicted():
    data = vehicle()
    data["kvalue"] = {**data["kvalue"], "storage_correction": False}
    k = k_stage(k_window(0.0), data)
    k = {**k, "kA": k["kA"] * 1.01, "k": k["k"] * 1.01, "u_k_rel": 0.005}
    estimate, series = identify.identify(WITHOUT_SURFACE, data, k, 2, None)
    return estimate, series


def test_the_note_states_each_yardstick_with_its_own_number(contradicted):
    estimate, _ = contradicted
    check = estimate.content["fit"]["static_kA_check"]
    assert check["reason"] == identify.STATIC_CONTRADICTED and check["use_joint"]
    assert abs(check["z"]["kA"]) > fitsettings.CONTRADICTION_Z  # the case of the two yardsticks
    (note,) = [n for n in estimate.content["method_notes"] if "contradict the two-stage fit" in n]
    # no bare "within the static test's uncertainty" beside "more than 3 standard
    # uncertainties of the difference": each claim names its yardstick and its number
    assert "within the static test's uncertainty)" not in note
    off = float(re.search(r"([+-][\d.]+) % from the static", note).group(1))
    own = float(re.search(r"static test's own uncertainty \(([\d.]+) %\)", note).group(1))
    z = float(re.search(r"but z = ([+-][\d.]+) of their difference", note).group(1))
    sd = float(re.search(r"difference's standard uncertainty \(([\d.]+) %\)", note).group(1))
    assert own == pytest.approx(0.5)
    assert abs(off) <= fitsettings.CONTRADICTION_Z * own  # "within 3 times ... own" holds
    assert abs(z) > fitsettings.CONTRADICTION_Z  # "more than 3" holds
    assert sd < own and abs(off) / sd == pytest.approx(abs(z), rel=0.1)  # and both at once
    assert z == pytest.approx(check["z"]["kA"], abs=0.05)


def test_a_replacement_whose_kA_agrees_is_a_note_not_a_reason(contradicted):
    estimate, series = contradicted
    checked = quality.check(estimate, series, {})
    k_method = next(c for c in checked.content["criteria"] if c["criterion"] == "k_stage")
    assert k_method["applies"] and k_method["passed"]
    assert not any("contradict the two-stage fit" in r for r in checked.content["reasons"])
    assert any("contradict the two-stage fit" in n for n in checked.content["notes"])


def test_the_agreement_sentence_in_each_case():
    """kA's agreement in words: where z of the difference is within 3 it says so; where it
    is beyond, it says why both can hold; with no finite z, the static test's yardstick
    alone."""
    agree = identify._kA_agreement(1010.0, 1000.0, 0.00995, 0.005, 1.2)
    assert "within 3 times the static test's own uncertainty (0.5 %)" in agree
    assert agree.endswith("z = +1.2 of their difference")
    beyond = identify._kA_agreement(1010.0, 1000.0, 0.00995, 0.005, 4.0)
    assert "but z = +4.0 of their difference, more than 3" in beyond
    assert "standard uncertainty (0.25 %)" in beyond and "leaves out the errors" in beyond
    alone = identify._kA_agreement(1010.0, 1000.0, 0.00995, 0.005, float("nan"))
    assert "z =" not in alone and alone.endswith("(0.5 %)")
