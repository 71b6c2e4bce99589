"""Tables over all vehicles (the study's Tables 1-3 come here in a later stage)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import pandas as pd

from railtherm.synth import DEVIATION_EFFECT_ON_K

COVERAGE_FACTOR = 2.0  # expanded uncertainty U = 2 u: about 95 % for a normal distribution
K_TOLERANCE_REL = 0.03  # agreement floor: within 3 % of the truth counts as agreeing


def kvalue_table(results: Mapping[str, Mapping[str, Any]], truth: pd.DataFrame | None = None):
    """One row per vehicle: the static k (eq. 10), u(k), the verdict, and the truth if known.

    ``results`` maps vehicle id -> the dict of its kvalue.yaml (railtherm.kvalue); ``truth`` is
    the campaign's ground_truth.csv (synthetic vehicles only). A vehicle agrees with its truth
    when |k - k_truth| <= max(u_k, 3 % k_truth) (u_k the standard uncertainty; U_k = 2 u_k, the
    expanded one, is listed too). ``note`` names the declared deviations that bias k, says when
    the window is not usable, and flags a disagreement that nothing declared explains.
    """
    truth_by_id = truth.set_index("vehicle") if truth is not None else None
    rows = []
    for vid, r in results.items():
        row = {
            "vehicle": vid,
            "method": "static (eq. 10)",
            "k": r["k"],
            "u_k": r["u_k"],
            "U_k": COVERAGE_FACTOR * r["u_k"],
            "steady": r["steady"],
            "forced": r["forced"],
            "usable": r["usable"],
            "reasons": "; ".join(r["reasons"]),
        }
        if truth_by_id is not None and vid in truth_by_id.index:
            t = truth_by_id.loc[vid]
            declared = [d for d in str(t["deviations"] or "").split(";") if d and d != "nan"]
            effects = [
                f"{d}: {DEVIATION_EFFECT_ON_K[d]}" for d in declared if DEVIATION_EFFECT_ON_K.get(d)
            ]
            error = r["k"] - t["k"]
            agrees = bool(abs(error) <= max(r["u_k"], K_TOLERANCE_REL * t["k"]))
            notes = []
            if not r["usable"]:
                notes.append("window not steady: k not usable")
            if effects:
                notes.append("declared deviation affecting the static test: " + " | ".join(effects))
            elif not agrees:
                notes.append("disagrees with the truth and no declared deviation explains it")
            note = "; ".join(notes)
            row |= {
                "k_truth": float(t["k"]),
                "rel_error": float(error / t["k"]),
                "agrees": agrees,
                "deviations": ";".join(declared),
                "note": note,
            }
        rows.append(row)
    return pd.DataFrame(rows)


PARAMETERS = ("kA", "C_bar", "C", "K_veh", "C_veh")
# Recovery tolerance of the second-order estimates against the campaign's truth (issue 4).
RECOVERY_TOLERANCE = {"C": 0.05, "K_veh": 0.10, "C_veh": 0.05}


def fit_table(fits: list[Mapping[str, Any]], truth: pd.DataFrame | None = None) -> pd.DataFrame:
    """One row per vehicle and model order: verdict, R^2 (eq. 21), NRMSE fit, how k was
    obtained, every parameter with its 95 % interval, the flags; and, for second-order fits of
    campaign vehicles, the truth, the relative error and whether the estimate is recovered
    (within 5 % for C and C_veh, 10 % for K_veh, or the truth inside the 95 % interval)."""
    truth_by_id = truth.set_index("vehicle") if truth is not None else None
    rows = []
    for fit in fits:
        row: dict[str, Any] = {
            "vehicle": fit["vehicle"],
            "order": fit["order"],
            "verdict": fit["verdict"],
            "R2": fit["R2"],
            "nrmse_fit": fit["nrmse_fit"],
            "k_source": fit["k_source"],
        }
        for p in PARAMETERS:
            entry = fit["parameters"].get(p, {})
            lo, hi = entry.get("ci95", (None, None))
            row |= {p: entry.get("value"), f"{p}_lo": lo, f"{p}_hi": hi}
        row["flags"] = ";".join(sorted({f["code"] for f in fit["flags"]}))
        known = truth_by_id is not None and fit["vehicle"] in truth_by_id.index
        if known and fit["order"] == 2:
            t = truth_by_id.loc[fit["vehicle"]]
            row["deviations"] = "" if pd.isna(t["deviations"]) else t["deviations"]
            for p, tol in RECOVERY_TOLERANCE.items():
                error = row[p] / t[p] - 1.0
                inside = row[f"{p}_lo"] is not None and row[f"{p}_lo"] <= t[p] <= row[f"{p}_hi"]
                row |= {
                    f"{p}_truth": float(t[p]),
                    f"{p}_rel_error": float(error),
                    f"{p}_recovered": bool(abs(error) <= tol or inside),
                }
        rows.append(row)
    return pd.DataFrame(rows)
