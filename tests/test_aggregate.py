"""railtherm.study.aggregate: tables over vehicles."""

import pandas as pd
import pytest

from railtherm.study.aggregate import kvalue_table
from railtherm.synth import DEVIATION_EFFECT_ON_K


def result(k, u_k, steady=True, forced=False, reasons=()):
    return {
        "k": k,
        "u_k": u_k,
        "steady": steady,
        "forced": forced,
        "usable": steady or forced,
        "reasons": list(reasons),
    }


TRUTH = pd.DataFrame(
    {
        "vehicle": ["A", "B", "C", "D"],
        "k": [2.0, 2.0, 2.0, 2.0],
        "deviations": ["", "", "unlogged_aux", "unsteady_start"],
        "k_effects": ["", "", f"unlogged_aux: {DEVIATION_EFFECT_ON_K['unlogged_aux']}", ""],
    }
)


def test_agreement_uses_the_wider_of_standard_uncertainty_and_three_percent():
    table = kvalue_table(
        {
            "A": result(2.05, 0.01),  # 2.5 % off, u = 0.01: inside the 3 % floor
            "B": result(2.15, 0.16),  # 7.5 % off, u = 0.16: inside u
            "D": result(2.15, 0.08),  # 7.5 % off, u = 0.08: outside (inside U = 2u only)
        },
        TRUTH,
    ).set_index("vehicle")
    assert table.loc["A", "agrees"] and table.loc["B", "agrees"]
    assert not table.loc["D", "agrees"]
    assert table.loc["A", "U_k"] == pytest.approx(0.02)
    assert table.loc["B", "rel_error"] == pytest.approx(0.075)
    assert table.loc["A", "note"] == ""


def test_disagreement_is_explained_by_a_declared_deviation_or_flagged():
    table = kvalue_table(
        {"C": result(1.8, 0.01), "D": result(2.3, 0.01), "A": result(2.2, 0.01)}, TRUTH
    ).set_index("vehicle")
    assert not table.loc["C", "agrees"]
    assert "unlogged_aux" in table.loc["C", "note"] and "biased low" in table.loc["C", "note"]
    assert table.loc["C", "note"].startswith("declared deviation affecting the static test")
    # unsteady_start does not bias the static test: nothing declared explains D
    assert "no declared deviation explains it" in table.loc["D", "note"]
    assert "no declared deviation explains it" in table.loc["A", "note"]


def test_unusable_window_is_noted_even_when_close():
    table = kvalue_table({"A": result(2.01, 0.5, steady=False, reasons=["T drifts"])}, TRUTH)
    assert table.iloc[0]["agrees"]
    assert "not usable" in table.iloc[0]["note"]


def test_verdict_and_reasons_travel_without_truth():
    table = kvalue_table({"X": result(1.5, 0.05, steady=False, forced=True, reasons=["T drifts"])})
    row = table.iloc[0]
    assert row["vehicle"] == "X" and not row["steady"] and row["forced"] and row["usable"]
    assert row["reasons"] == "T drifts" and "k_truth" not in table.columns
