"""The class as a prior: a short test borrowing strength from its class.

    python benchmarks/borrowing_strength.py [--study DIR] [--fraction 0.3333] [--jobs 2]

Needs a finished study in DIR (default: this checkout; ``snakemake --cores 2`` writes it):
the campaign's raw files, Table 2 of the full-record fits and the campaign's ground truth
(``results/campaign/ground_truth.csv``). For every campaign vehicle with a second-order
model, the identification record is cut to its first ``fraction`` (from the first window's
start; a window past the cut is dropped, the one across it truncated; the static k test is a
test of its own and keeps its window), and the second-order model is fitted to the cut
record twice by the study's output-error estimator, both with the same k stage:

- maximum likelihood, as the study fits it;
- MAP with the class as the prior: the class reference model of the vehicle's class, mass
  and surface built from the *other* vehicles' full-record fits (Table 2; the vehicle
  itself excluded), its generalised parameters' predictive distributions as joint prior
  terms (ReferenceModel.prior_terms). A class with fewer than two other usable vehicles
  takes every rail class pooled ("all") instead, as `railtherm reference --class all` does.

Printed per vehicle: the truth, both estimates with their 95 % intervals (statistical and
systematic combined, docs/identification.md; for the MAP fit the Laplace interval of
docs/bayes.md), and whether the fit determines the parameter. Then, for C_veh and K_veh,
the median |log(estimate / truth)| over the vehicles (a parameter the fit does not determine
counts as an infinite error: it gives no estimate), also over the determined ones only,
and the share of vehicles whose 95 % interval covers the truth.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd

REPO = Path(__file__).resolve().parents[1]
PARAMETERS = ("C_veh", "K_veh", "C")


def cut(tables: dict[str, pd.DataFrame], names: list[str], fraction: float):
    """The identification windows ``names`` cut to the first ``fraction`` of the record."""
    stamps = {n: pd.to_datetime(tables[n]["timestamp"]) for n in names}
    start = min(s.iloc[0] for s in stamps.values())
    end = max(s.iloc[-1] for s in stamps.values())
    limit = start + (end - start) * fraction
    out = {}
    for n in names:
        keep = (stamps[n] <= limit).to_numpy()
        if keep.sum() >= 10:
            out[n] = tables[n].loc[keep].reset_index(drop=True)
    return out


def one_vehicle(args) -> dict:
    """A vehicle's row, or {"vehicle", "skipped": why} where its cut record cannot be fitted
    (too few rows left, say): reported, not a crash after every other vehicle's fits."""
    try:
        return _one_vehicle(args)
    except Exception as err:  # noqa: BLE001 - the benchmark reports it and goes on
        return {"vehicle": args[1], "skipped": f"{type(err).__name__}: {err}"}


def _one_vehicle(args) -> dict:
    study, vid, fraction = args
    os.chdir(study)
    from railtherm.config import load_study
    from railtherm.data import ingest
    from railtherm.estimation import kvalue
    from railtherm.study import classmodel, identify
    from railtherm.study.run import tidy_tables
    from railtherm.study.storage import storage_corrected_k
    from railtherm.yamlio import read_yaml

    config = read_yaml("config/config.yaml")
    vehicle = load_study(config, ".").vehicles[vid]
    tables = tidy_tables(vehicle, ".")
    names = [w["name"] for w in vehicle.windows["identification"]]
    windows = cut(tables, names, fraction)
    k_stage = None
    if "kvalue" in tables:
        raw_name, _, key = ingest.window_spec(vehicle.data, "kvalue")
        source = f"{vehicle.raw_files[raw_name]} ({key})"
        k_stage = kvalue.for_vehicle(tables["kvalue"], vehicle.data, source=source).to_dict()
    storage = storage_corrected_k(windows, tables.get("kvalue"), vehicle.data, k_stage)
    ml, _ = identify.identify(windows, vehicle.data, k_stage, "order2", storage)

    members = classmodel.members_from_study("config/config.yaml", "results", ".")
    mass, surface = vehicle.data.get("mass_kg"), vehicle.data.get("surface_m2")
    k_given = None
    fixed_kA = ml.content["fit"]["parameters"]["kA"]
    if not fixed_kA.get("estimated", True):
        k_given = float(fixed_kA["value"]) / float(surface)
    basis = "class"
    try:
        reference = classmodel.build(
            members, vehicle.vehicle_class, mass, surface, k=k_given, exclude=[vid]
        )
    except Exception:  # fewer than two other usable vehicles in the class
        basis = "all"
        reference = classmodel.build(
            members, classmodel.POOLED, mass, surface, k=k_given, exclude=[vid]
        )
    post, _ = identify.identify(
        windows, vehicle.data, k_stage, "order2", storage, prior_terms=reference.prior_terms()
    )
    out = {
        "vehicle": vid,
        "class": vehicle.vehicle_class,
        "prior": basis,
        "prior_n": len(reference.basis),
        "rows": sum(len(w) for w in windows.values()),
    }
    for label, record in (("ml", ml), ("map", post)):
        for p in PARAMETERS:
            entry = record.content["fit"]["parameters"][p]
            out[f"{p}_{label}"] = float(entry["value"])
            out[f"{p}_{label}_lo"], out[f"{p}_{label}_hi"] = map(float, entry["ci95"])
            out[f"{p}_{label}_identified"] = bool(entry.get("identified", True))
    for p in PARAMETERS:
        centre = reference.theta[p]
        out[f"{p}_prior"] = float(centre)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--study", type=Path, default=REPO)
    parser.add_argument("--fraction", type=float, default=1.0 / 3.0)
    parser.add_argument("--jobs", type=int, default=2)
    args = parser.parse_args()
    study = args.study.resolve()
    truth = pd.read_csv(study / "results" / "campaign" / "ground_truth.csv").set_index("vehicle")
    if not (study / "results" / "tables" / "table2.csv").exists():
        sys.exit(f"{study}: no results/tables/table2.csv; run snakemake there first")
    jobs = [(str(study), vid, args.fraction) for vid in truth.index]
    with ProcessPoolExecutor(args.jobs) as pool:
        rows = list(pool.map(one_vehicle, jobs))
    skipped = [r for r in rows if "skipped" in r]
    rows = [r for r in rows if "skipped" not in r]
    for r in skipped:
        print(f"{r['vehicle']}: skipped ({r['skipped']})")
    table = pd.DataFrame(rows).set_index("vehicle")
    print(
        f"Record cut to its first {args.fraction:.4g}; second-order model by output error; "
        "95 % intervals statistical + systematic (MAP: Laplace)."
    )
    print()
    for p in ("C_veh", "K_veh"):
        print(f"| vehicle | prior from | {p} truth | class prior centre | ML [95 %] | MAP [95 %] |")
        print("|---|---|---|---|---|---|")
        for vid, r in table.iterrows():

            def cell(label, r=r, p=p):
                mark = "" if r[f"{p}_{label}_identified"] else " (not identified)"
                return (
                    f"{r[f'{p}_{label}']:.4g} [{r[f'{p}_{label}_lo']:.3g}, "
                    f"{r[f'{p}_{label}_hi']:.3g}]{mark}"
                )

            print(
                f"| {vid} | {r['prior']} ({r['prior_n']}) | {truth.loc[vid, p]:.4g} "
                f"| {r[f'{p}_prior']:.4g} | {cell('ml')} | {cell('map')} |"
            )
        print()
    print("| parameter | estimate | median abs log error (not identified = inf) "
          "| median abs log error (determined only, n) | 95 % interval covers truth |")  # fmt: skip
    print("|---|---|---|---|---|")
    for p in ("C_veh", "K_veh"):
        medians = {}
        for label in ("ml", "map"):
            err = np.abs(np.log(table[f"{p}_{label}"] / truth.loc[table.index, p]))
            ident = table[f"{p}_{label}_identified"]
            med_inf = float(np.median(np.where(ident, err, np.inf)))
            med_det = float(np.median(err[ident])) if ident.any() else math.nan
            covers = (table[f"{p}_{label}_lo"] <= truth.loc[table.index, p]) & (
                truth.loc[table.index, p] <= table[f"{p}_{label}_hi"]
            )
            medians[label] = med_inf
            print(
                f"| {p} | {'ML' if label == 'ml' else 'MAP, class prior'} | {med_inf:.4f} "
                f"| {med_det:.4f} ({int(ident.sum())}) | {int(covers.sum())}/{len(covers)} |"
            )
        if math.isfinite(medians["ml"]) and medians["ml"] > 0:
            print(f"|  | MAP / ML | {medians['map'] / medians['ml']:.3f} | | |")


if __name__ == "__main__":
    main()
