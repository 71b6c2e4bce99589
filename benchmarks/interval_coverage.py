"""Coverage of the 95 % intervals of C, K_veh and C_veh over seeds of the virtual campaign.

    python benchmarks/interval_coverage.py [--seeds 30] [--first 1] [--jobs 2] [--out coverage.csv]

For each seed, the campaign generator (railtherm.synth) writes the raw files of the vehicles
that declare no deviation from the paper's assumptions (their truth is what the method should
recover), and the library runs what the workflow runs for each: clean, the static k test
(eq. 10) and its storage correction, the two-stage second-order fit (eqs. 7-8, 15-20) with
its combined statistical and systematic (GUM type B) intervals. A parameter counts as covered
when its combined 95 % interval is bounded (within the factor of 1000 that Table 2 prints as 0
or ∞) and holds the truth; an unbounded interval or a parameter at a bound counts as not
covered, so inflating an interval to infinity cannot pass.

Printed: coverage per parameter and per vehicle, with a 95 % Wilson interval of the coverage
itself; the static k's error against the truth beside its u(k), for eq. 10 and for the
storage-corrected k that stage two holds; and the mean and the rms of
z = log(estimate / truth) / sd_log_total: the mean is the bias in units of the claimed sd
(near 0 for an unbiased estimator), the rms the spread (close to 1 for honest intervals; well
below 1 means inflated intervals, well above 1 too narrow ones).
"""

from __future__ import annotations

import argparse
import math
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
from calibration import collect, wilson  # benchmarks/ is the script's folder, first on sys.path

from railtherm import synth
from railtherm.config import load_study
from railtherm.data import ingest
from railtherm.estimation import kvalue
from railtherm.study import identify
from railtherm.study.storage import storage_corrected_k

REPO = Path(__file__).resolve().parents[1]
PARAMETERS = ("C", "K_veh", "C_veh")
UNBOUNDED_FACTOR = 1e3


def deviation_free(campaign) -> list[str]:
    """The campaign's vehicles that declare no deviation from the paper's assumptions."""
    truth = synth.ground_truth_table(campaign)
    free = truth["deviations"].fillna("") == ""
    return truth.loc[free, "vehicle"].tolist()


def one_seed(seed: int) -> list[dict]:
    """Synthesise the deviation-free vehicles with ``seed`` and fit each; one row per
    vehicle and parameter."""
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        shutil.copytree(REPO / "config", root / "config")
        campaign = synth.load_campaign(root / "config" / "campaign" / "virtual_cwt.yaml")
        campaign["seed"] = seed
        vids = deviation_free(campaign)
        for vid in vids:
            spec = synth.vehicle_spec(campaign, vid)
            for name in synth.raw_file_names(spec):
                synth.write_raw_file(spec, name, root / "resources" / "campaign" / vid / name)
        config = {
            "campaign": "config/campaign/virtual_cwt.yaml",
            "vehicles": [f"config/vehicles/{vid}.yaml" for vid in vids],
        }
        study = load_study(config, workdir=root)
        truth = synth.ground_truth_table(campaign).set_index("vehicle")
        for vid in vids:
            vehicle = study.vehicles[vid]
            data = vehicle.data

            def clean(name, data=data, vehicle=vehicle):
                key, _, _ = ingest.window_spec(data, name)
                return ingest.clean_window(root / vehicle.raw_files[key], data, name)

            k_window = clean("kvalue")
            k = kvalue.for_vehicle(k_window, data, source=vid).to_dict()
            tables = {w["name"]: clean(w["name"]) for w in data["windows"]["identification"]}
            storage = storage_corrected_k(tables, k_window, data, k)
            estimate, _ = identify.identify(tables, data, k, 2, storage)
            estimate = estimate.content  # the estimate file as written
            k_true = float(truth.loc[vid, "k"])
            if estimate["kA_fixed"] is not None:
                # the storage-corrected k that stage two holds (eq. 10's where not made)
                k_held = estimate["kA_fixed"] / estimate["A"]
                u_held = (
                    estimate["u_k_corrected"] / estimate["k_corrected"]
                    if estimate["k_corrected"]
                    else k["u_k_rel"]
                )
            else:  # the records rejected the static kA: the joint fit's, sd from its interval
                entry = estimate["fit"]["parameters"]["kA"]
                k_held = entry["value"] / estimate["A"]
                u_held = entry["sd_log_total"]
            k_stage = {
                "k_source": estimate["k_source"],
                "k_rel_error": k["k"] / k_true - 1.0,
                "u_k_rel": k["u_k_rel"],
                "k_fixed_rel_error": k_held / k_true - 1.0,
                "u_k_fixed_rel": u_held,
            }
            flagged = {
                p
                for f in estimate["fit"]["flags"]
                if f["code"] == "at_bound"
                for p in f["parameters"]
            }
            for p in PARAMETERS:
                entry = estimate["fit"]["parameters"][p]
                x, (lo, hi), t = entry["value"], entry["ci95"], float(truth.loc[vid, p])
                bounded = (
                    math.isfinite(lo)
                    and math.isfinite(hi)
                    and lo > x / UNBOUNDED_FACTOR
                    and hi < x * UNBOUNDED_FACTOR
                    and p not in flagged
                )
                sd = entry["sd_log_total"]
                rows.append(
                    {
                        "seed": seed,
                        "vehicle": vid,
                        "parameter": p,
                        "estimate": x,
                        "truth": t,
                        "lo": lo,
                        "hi": hi,
                        "sd_log_total": sd,
                        "sd_log_statistical": entry["sd_log"],
                        "bounded": bounded,
                        "covered": bool(bounded and lo <= t <= hi),
                        "z": math.log(x / t) / sd if sd > 0 and math.isfinite(sd) else math.nan,
                        **k_stage,
                    }
                )
    return rows


def summary(df: pd.DataFrame, by: str) -> pd.DataFrame:
    rows = []
    for key, part in df.groupby(by, sort=False):
        k, n = int(part["covered"].sum()), len(part)
        lo, hi = wilson(k, n)
        z = part["z"].to_numpy(dtype=float)
        z = z[np.isfinite(z)]
        rows.append(
            {
                by: key,
                "n": n,
                "covered": k,
                "coverage": k / n,
                "coverage_lo": lo,
                "coverage_hi": hi,
                "unbounded": int((~part["bounded"]).sum()),
                "mean_z": float(np.mean(z)) if z.size else math.nan,
                "rms_z": float(np.sqrt(np.mean(z**2))) if z.size else math.nan,
            }
        )
    return pd.DataFrame(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=30)
    parser.add_argument("--first", type=int, default=1)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--out", type=Path, default=None, help="per-interval CSV")
    args = parser.parse_args()
    seeds = range(args.first, args.first + args.seeds)
    df = pd.DataFrame(collect(one_seed, list(seeds), args.jobs, "seed"))
    if args.out:
        df.to_csv(args.out, index=False, float_format="%.6g")
    fmt = {"coverage": "{:.3f}".format, "coverage_lo": "{:.3f}".format}
    fmt |= {"coverage_hi": "{:.3f}".format, "mean_z": "{:+.2f}".format, "rms_z": "{:.2f}".format}
    print(f"seeds {seeds.start}-{seeds.stop - 1}, vehicles: {', '.join(df['vehicle'].unique())}")
    for by in ("parameter", "vehicle"):
        print()
        print(summary(df, by).to_string(index=False, formatters=fmt))
    k = df[df["parameter"] == PARAMETERS[0]].groupby("vehicle", sort=False)
    print()
    print("static k against the truth, per vehicle over the seeds: eq. 10, and the")
    print("storage-corrected k that stage two holds, or the joint fit's where the records")
    print("reject the static kA (z = error / u(k)):")
    print(
        pd.DataFrame(
            {
                "mean_error": k["k_rel_error"].mean(),
                "sd_error": k["k_rel_error"].std(),
                "mean_u_k_rel": k["u_k_rel"].mean(),
                "mean_z": (df["k_rel_error"] / df["u_k_rel"]).groupby(df["vehicle"]).mean(),
                "fixed_mean_error": k["k_fixed_rel_error"].mean(),
                "fixed_sd_error": k["k_fixed_rel_error"].std(),
                "fixed_mean_u_rel": k["u_k_fixed_rel"].mean(),
                "fixed_mean_z": (df["k_fixed_rel_error"] / df["u_k_fixed_rel"])
                .groupby(df["vehicle"])
                .mean(),
            }
        ).to_string(float_format="{:.4f}".format)
    )
    print()
    print("where stage two's kA came from (fits):")
    print(k["k_source"].value_counts().to_string())
    total = summary(df.assign(all="all"), "all")
    print()
    print(total.to_string(index=False, formatters=fmt))


if __name__ == "__main__":
    main()
