"""The storage-corrected k where its iteration has nothing to report: the joint fit's
capacities give no positive balance (so the alternation starts from eq. 10's kA) and the first
stage-two fit cannot be used (a capacity at a search bound, as a long 1 Hz record cleaned to a
300 s step leaves it). The correction's message once read the last kA of an empty history
(IndexError), so the fallback to eq. 10's kA never ran; it now runs and says why."""

from __future__ import annotations

import dataclasses
import math

import pytest
from test_kvalue_storage import IDENTIFICATION, k_stage, k_window, vehicle

from railtherm.estimation import pem
from railtherm.study import identify
from railtherm.study import storage as storage_module
from railtherm.study.storage import storage_corrected_k


def no_usable_step(monkeypatch, joint_kA: float = -250.0):
    """The joint fit's balance gives ``joint_kA`` (not a positive kA) and every stage-two fit
    (kA fixed) leaves C_veh at its search bound."""
    real_balance = storage_module.storage_corrected_kA
    calls = {"n": 0}

    def balance(window, C, K_veh, C_veh, **kw):
        calls["n"] += 1
        result = real_balance(window, C, K_veh, C_veh, **kw)
        return dataclasses.replace(result, kA=joint_kA) if calls["n"] == 1 else result

    real_fit = identify.pem.fit

    def bounded(structure, exps, **options):
        result = real_fit(structure, exps, **options)
        if "kA" in options.get("fixed", {}):  # stage two
            result.flags.append(pem.Flag("at_bound", ("C_veh",), "C_veh at its upper bound"))
        return result

    monkeypatch.setattr(storage_module, "storage_corrected_kA", balance)
    monkeypatch.setattr(identify.pem, "fit", bounded)


@pytest.mark.bad_input
@pytest.mark.parametrize("joint_kA", [-250.0, math.nan])
def test_no_usable_first_step_falls_back_to_eq10_and_says_why(monkeypatch, joint_kA):
    no_usable_step(monkeypatch, joint_kA)
    data, window = vehicle(), k_window(0.3)
    k = k_stage(window, data)
    storage = storage_corrected_k(IDENTIFICATION, window, data, k)
    assert storage["applied"] is False
    reason = storage["reason"]
    assert f"no usable stage-two fit from kA = {k['kA']:.4g} W/K" in reason
    assert "leaves C_veh at a search bound" in reason and "eq. 10's kA is fixed" in reason


@pytest.mark.bad_input
def test_the_fit_after_the_fallback_holds_eq10s_kA_and_gives_numbers(monkeypatch):
    no_usable_step(monkeypatch)
    data, window = vehicle(), k_window(0.3)
    k = k_stage(window, data)
    storage = storage_corrected_k(IDENTIFICATION, window, data, k)
    monkeypatch.undo()
    data["model"] = {**data["model"], "two_stage_check": False}
    estimate, _ = identify.identify(IDENTIFICATION, data, k, 2, storage)
    assert estimate.content["kA_fixed"] == pytest.approx(k["kA"])
    assert estimate.content["k_corrected"] is None
    assert estimate.content["storage_correction"]["reason"] == storage["reason"]
    for p in ("C", "K_veh", "C_veh"):
        value = estimate.content["fit"]["parameters"][p]["value"]
        assert math.isfinite(value) and value > 0


@pytest.mark.bad_input
def test_the_unsettled_message_names_the_last_kA_or_its_absence():
    """Both ways the message is built from what there is: the last kA and the count of fits,
    or the start where no fit could be used, with the step's own reason."""
    assert "last kA 612 W/K after 3 fits" in storage_module._unsettled(
        [600.0, 605.0, 612.0], 580.0, None
    )
    text = storage_module._unsettled([], 580.0, ValueError("C at a search bound"))
    assert "no usable stage-two fit from kA = 580 W/K; C at a search bound" in text
