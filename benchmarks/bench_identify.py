"""Where an identify job's time goes: the main fit with its covariance, the systematic
(type-B) budget's refits and the cross-validation, against the bare fit, at N = 1e3, 1e4, 1e5.

The data: the Tram2 vehicle of the virtual campaign (two step windows, written by the virtual
wind tunnel into a scratch directory) and the Armadillo test cell of the validation study (real
data, one window, kA estimated jointly, initial states estimated), each window resampled onto
N / (number of windows) points over the same programme (linear interpolation of every tidy
column: the same experiment logged finer). Every phase is timed inside one call of
:func:`railtherm.study.identify.identify` by wrapping the functions it calls; the bare fit is the
same estimator alone (:func:`railtherm.study.fitsettings.estimate_parameters`) with iid
covariance (no HAC, no budget, no cross-validation). Best of ``--rounds`` (default 3).

    python benchmarks/bench_identify.py [--rounds 3] [--sizes 1000 10000 100000]

prints a Markdown table; docs/performance.md quotes it.
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np
import pandas as pd

from railtherm import cli
from railtherm.config import load_vehicle
from railtherm.study import fitsettings, identify, run

REPO = Path(__file__).resolve().parents[1]


def tram2(scratch: Path):
    """Tram2's vehicle config, tidy windows and static k from the virtual campaign."""
    shutil.copytree(REPO / "config", scratch / "config")
    assert (
        cli.main(["fit", "config/vehicles/Tram2.yaml", "--model", "order1", "-d", str(scratch)])
        == 0
    )
    cwd = os.getcwd()
    try:
        os.chdir(scratch)
        vehicle = load_vehicle("config/vehicles/Tram2.yaml")
        tables = run.tidy_tables(vehicle, ".")
        result = run.fit_vehicle(vehicle, ["order1"], workdir=".")
    finally:
        os.chdir(cwd)
    windows = {w["name"]: tables[w["name"]] for w in vehicle.windows["identification"]}
    return vehicle.data, windows, result.kvalue.to_dict()


def armadillo():
    """The Armadillo test cell of the validation study (real data, 30-min steps, no static k)."""
    from railtherm.config import add_vehicle, read_yaml, study_context

    workdir = REPO / "validation"
    config = read_yaml(workdir / "config" / "config.yaml")
    context = study_context(config, workdir=workdir, config_file="config/config.yaml")
    add_vehicle(context, workdir / "config" / "vehicles" / "Armadillo.yaml", workdir)
    vehicle = context.vehicles["Armadillo"]
    tables = run.tidy_tables(vehicle, workdir)
    windows = {w["name"]: tables[w["name"]] for w in vehicle.windows["identification"]}
    return vehicle.data, windows, None


def resampled(table: pd.DataFrame, n: int) -> pd.DataFrame:
    """The window on n points over its own span (numeric columns interpolated)."""
    t = table["time"].to_numpy(float)
    grid = np.linspace(t[0], t[-1], n)
    out = {"time": grid}
    for column in table.columns:
        if column in ("time", "timestamp") or not pd.api.types.is_numeric_dtype(table[column]):
            continue
        out[column] = np.interp(grid, t, table[column].to_numpy(float))
    frame = pd.DataFrame(out)
    if "filled" in frame:
        frame["filled"] = 0
    if "timestamp" in table:
        start = pd.Timestamp(table["timestamp"].iloc[0])
        frame.insert(1, "timestamp", (start + pd.to_timedelta(grid, unit="s")).astype(str))
    return frame


def timed_identify(data, windows, kvalue, model) -> dict[str, float]:
    """One identify call with each phase's time (s)."""
    spent: dict[str, float] = defaultdict(float)
    originals = {}

    def wrap(module, name, label):
        original = getattr(module, name)
        originals[(module, name)] = original

        def timed(*args, **kwargs):
            t0 = time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                spent[label] += time.perf_counter() - t0

        setattr(module, name, timed)

    wrap(identify, "systematic_budget", "budget")
    wrap(identify, "_cross_validate", "cross-validation")
    try:
        t0 = time.perf_counter()
        identify.identify(windows, data, kvalue, model)
        spent["total"] = time.perf_counter() - t0
    finally:
        for (module, name), original in originals.items():
            setattr(module, name, original)
    spent["main fit and the rest"] = spent["total"] - spent["budget"] - spent["cross-validation"]
    return dict(spent)


def bare_fit(data, windows, kvalue, model) -> float:
    structure = fitsettings.model_structure(model, data)
    exps = fitsettings.experiments(structure, windows)
    fixed, initial, bounds, _, _ = fitsettings._settings(structure, data, kvalue, windows)
    options = {
        "fixed": fixed,
        "initial": initial,
        "bounds": bounds,
        "outputs": identify._outputs(structure, data, windows),
        "x0": data["model"].get("x0", "measured"),
        "covariance": "iid",
        "start": data["model"].get("start", "auto"),
        **({"estimator": "kalman"} if model.endswith("_kalman") else {}),
    }
    t0 = time.perf_counter()
    fitsettings.estimate_parameters(structure, exps, options)
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000, 100000])
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        cases = [("Tram2", "order2", tram2(Path(tmp)))]
    cell = armadillo()
    cases += [("Armadillo", "interior_envelope", cell), ("Armadillo", "order2_kalman", cell)]
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs")
    print()
    print(
        "| vehicle | model | N | identify job | main fit + rest | budget refits "
        "| cross-validation | bare fit | job / bare |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for vid, model, (data, windows, kvalue) in cases:
        for n in args.sizes:
            if model.endswith("_kalman") and n > 10_000:
                continue  # the filter's likelihood at 1e5 takes minutes per fit
            win = {name: resampled(t, n // len(windows)) for name, t in windows.items()}
            bare = min(bare_fit(data, win, kvalue, model) for _ in range(args.rounds))
            best: dict[str, float] = {}
            for _ in range(args.rounds):
                spent = timed_identify(data, win, kvalue, model)
                if not best or spent["total"] < best["total"]:
                    best = spent
            print(
                f"| {vid} | {model} | {n:.0e} | {best['total']:.2f} s | "
                f"{best['main fit and the rest']:.2f} s | {best['budget']:.2f} s | "
                f"{best['cross-validation']:.2f} s | {bare:.3f} s | {best['total'] / bare:.1f}× |",
                flush=True,
            )


if __name__ == "__main__":
    main()
