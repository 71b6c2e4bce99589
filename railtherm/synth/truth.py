"""The campaign's declared ground truth as tables: one row per vehicle and one per value.

The truth is what the identified parameters are checked against: k, C, K_veh, C_veh and the
derived c_veh (eq. 24), delta (eq. 25) and time constants (eq. 14), with what each declared
deviation does to the static k test (eq. 10).
"""

from __future__ import annotations

import pandas as pd

from railtherm.synth.campaign import (
    DEVIATION_EFFECT_ON_K,
    TRUTH_UNITS,
    time_constants,
    vehicle_spec,
)
from railtherm.synth.physics import _instruments, _rngs


def ground_truth_table(campaign: dict) -> pd.DataFrame:
    """One row per vehicle (campaign order): the declared truth in SI units, the derived c_veh
    (eq. 24) and delta (eq. 25), time constants of eq. 14, programme and logger step, and the
    declared deviations (";"-joined types, "" if none) with what each does to the static k
    test (``k_effects``, "type: effect" joined by " | ", "" if none does anything)."""
    rows = []
    for vid in campaign["_merged"]:
        spec = vehicle_spec(campaign, vid)
        tr = spec["truth"]
        tf, ts = time_constants(spec)
        inst = _instruments(spec, _rngs(spec)[0])
        devs = spec["deviations"]
        rows.append(
            {
                "vehicle": vid,
                "class": spec["class"],
                "k": tr["k"],
                "A": tr["A"],
                "kA": tr["kA"],
                "C": tr["C"],
                "K_veh": tr["K_veh"],
                "C_veh": tr["C_veh"],
                "mass_kg": tr["mass_kg"],
                "volume_m3": tr["volume_m3"],
                "c_veh": tr["C_veh"] / tr["mass_kg"],
                "delta": tr["C_veh"] / tr["C"],
                "tau_fast_s": tf,
                "tau_slow_s": ts,
                "programme": spec["programme"]["type"],
                "step_s": spec["logger"]["step_s"],
                "duration_s": spec["programme"]["phases_s"]["end"],
                "hvac_airflow_bias": inst["hvac_bias"]
                if spec["programme"]["type"] == "existing"
                else 1.0,
                "deviations": ";".join(d["type"] for d in devs),
                "k_effects": " | ".join(
                    f"{d['type']}: {DEVIATION_EFFECT_ON_K[d['type']]}"
                    for d in devs
                    if DEVIATION_EFFECT_ON_K[d["type"]]
                ),
                "synthetic": True,
            }
        )
    return pd.DataFrame(rows)


def ground_truth_sources(campaign: dict) -> pd.DataFrame:
    """Every truth value with its unit and source (vehicle, quantity, value, unit, source)."""
    rows = []
    for vid, m in campaign["_merged"].items():
        for q in TRUTH_UNITS:
            e = m["truth"][q]
            rows.append(
                {
                    "vehicle": vid,
                    "quantity": q,
                    "value": float(e["value"]),
                    "unit": e["unit"],
                    "source": e["source"],
                }
            )
    return pd.DataFrame(rows)
