"""Predicted interval widths against the realised spread of repeated virtual tunnel runs.

    python benchmarks/design_replicates.py [--replicates 30] [--jobs 2] [--seed 4601]
        [--vehicles light,heavy,slow_body] [--setting output_error/static/without]
        [--out replicates.csv]
    python benchmarks/design_replicates.py --from-csv replicates.csv   # the table of a saved run

Three fixed vehicles of the independent generator of ``benchmarks/calibration.py`` (its own
simulation of eqs. 7-8, sensors with offsets and white noise, power meters with a common
scale error and white noise, a tunnel air that fluctuates; not ``railtherm.synth``) run the
same programme ``--replicates`` times, each with new noise and new instrument errors: the
thermostat's heating phase with the static k window at its end, a heating step up held, and
the step back. Every record is fitted as the study fits it (``run.fit_vehicle``).

Measured per vehicle and parameter (C, K_veh, C_veh):

- **realised**: the standard deviation of log(estimate) over the replicates (the spread a
  test programme really gives), with its 90 % interval by the chi-square law;
- **from the truth**: ``design.predict`` of the programme at the true parameters, with the
  programme's declared noise and systematic uncertainties; ratio = predicted sd / realised;
- **from each pilot**: the prediction made as an engineer makes it before a re-test, from
  one replicate's fit as the prior (``design.prior_from_fit``: its estimates and residual
  noise); median and 10-90 % range of predicted sd / realised over the replicates.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats

sys.path.insert(0, str(Path(__file__).resolve().parent))
import calibration as cb  # noqa: E402  (the independent generator)
import design_check as dc  # noqa: E402

from railtherm.study import design  # noqa: E402

CHECKED = ("C", "K_veh", "C_veh")
PILOT_DRAWS = 50  # draws of a pilot fit's own intervals
ERRORS = ("offset_T", "offset_T_o", "offset_T_veh", "power_scale")  # drawn per replicate
GENERATOR = cb.Generator()


def _truth(name: str, k: float, A: float, C: float, C_veh: float, K_veh: float) -> cb.Truth:
    return cb.Truth(
        vehicle=name,
        vehicle_class=cb.vehicle_class(A),
        k=k,
        A=A,
        C=C,
        C_veh=C_veh,
        K_veh=K_veh,
        mass_kg=round(A * 120.0),
        volume_m3=round(A * 0.38, 1),
        T_o=-10.0,
        T_set=21.0,
        dQ=k * A * 9.0,
        lag_drawn=0.2,
        lag=0.2,
    )


VEHICLES = {  # light; heavy; a slow body (C_veh / K_veh = 39 h)
    "light": _truth("light", 1.6, 260.0, 6e6, 4e6, 1200.0),
    "heavy": _truth("heavy", 1.5, 380.0, 2.4e7, 5.5e7, 900.0),
    "slow_body": _truth("slow_body", 1.8, 300.0, 1.2e7, 5.6e7, 400.0),
}


def true_theta(truth: cb.Truth) -> dict[str, float]:
    return {"kA": truth.kA, "C": truth.C, "K_veh": truth.K_veh, "C_veh": truth.C_veh}


def truth_prior(truth: cb.Truth, setting: str) -> design.Prior:
    """The prior at the truth, with the programme's declared sensor noise (white)."""
    from railtherm import structures

    structure = structures.STRUCTURES["second_order"]
    return design.Prior(structure, true_theta(truth), ("C", "K_veh", "C_veh"), "truth")


def plan(truth: cb.Truth) -> cb.Plan:
    """The bench's programme for ``truth``: after the thermostat's heating phase, the steady
    power at its set point plus the vehicle's step dQ, then the steady power again."""
    steady = truth.kA * (truth.T_set - truth.T_o)
    return cb.Plan(powers=(steady + truth.dQ, steady))


def programme(
    truth: cb.Truth, prior: design.Prior, setting: str, bench: cb.Plan | None = None
) -> design.Programme:
    """The bench's programme (``bench``, default :func:`plan`) as design reads it; T_veh
    compared only with surface sensors."""
    base = dc.calibration_programme(truth, prior, bench or plan(truth))
    if setting.endswith("/with"):
        return base
    noise = {s: v for s, v in base.noise_K.items() if s != "T_veh"}
    systematic = {s: v for s, v in base.systematic.items() if s != "T_veh"}
    return replace(base, noise_K=noise, systematic=systematic)


def replicate_fit(name: str, r: int, seed: int, setting: str, generator, bench: cb.Plan):
    """Replicate ``r`` of vehicle ``name`` under ``bench``: its record from its own noise
    and instrument errors, fitted as the study fits it; (fit, the drawn errors)."""
    truth = VEHICLES[name]
    with tempfile.TemporaryDirectory() as tmp:
        rng = np.random.default_rng(np.random.SeedSequence([seed, list(VEHICLES).index(name), r]))
        states, realised = cb.simulate(truth, rng, bench)
        raw, errors = cb.logger_file(states, rng, generator)
        csv = Path(tmp) / f"{name}_{r}.csv"
        raw.to_csv(csv, index=False)
        path = cb.write_yaml_file(realised, csv, setting, "estimated", generator, bench)
        return dc.fitted(path), errors


def pilot_sd(fit, truth: cb.Truth, setting: str, bench: cb.Plan, seed: int) -> dict:
    """What a pilot fit predicts for ``bench``: the sd of log theta at its estimates, and the
    median over :data:`PILOT_DRAWS` draws of its own combined intervals."""
    pilot = design.prior_from_fit(fit, PILOT_DRAWS, seed)
    assessment = design.assess(pilot, programme(truth, pilot, setting, bench))
    out = {}
    for p in CHECKED:
        median = assessment.spread[p][1]
        out[p] = (assessment.central.sd_log[p], math.log1p(median) / design.Z95)
    return out


def one_replicate(job: tuple) -> list[dict]:
    name, r, seed, setting, generator, bench = job
    truth = VEHICLES[name]
    bench = bench or plan(truth)
    fit, errors = replicate_fit(name, r, seed, setting, generator, bench)
    rows = [
        {
            **errors,
            "vehicle": name,
            "replicate": r,
            "parameter": "kA",
            "estimate": fit.parameters["kA"].value,
            "truth": truth.kA,
            "identified": True,
            "verdict": fit.verdict,
            "fit_sd_log": math.nan,
            "pilot_sd_log": math.nan,
            "pilot_draws_sd_log": math.nan,
            "pilot_failure": "",
        }
    ]
    try:
        predicted = pilot_sd(fit, truth, setting, bench, r)
    except (ValueError, np.linalg.LinAlgError) as err:  # a pilot that predicts nothing
        predicted, failure = None, str(err)
    else:
        failure = ""
    for p in CHECKED:
        q = fit.parameters[p]
        rows.append(
            {
                **errors,
                "vehicle": name,
                "replicate": r,
                "parameter": p,
                "estimate": q.value,
                "truth": true_theta(truth)[p],
                "identified": q.identified,
                "verdict": fit.verdict,
                "fit_sd_log": dc.realised_sd(fit, p),
                "pilot_sd_log": math.nan if predicted is None else predicted[p][0],
                "pilot_draws_sd_log": math.nan if predicted is None else predicted[p][1],
                "pilot_failure": failure,
            }
        )
    return rows


def summary(df: pd.DataFrame, setting: str, bench: cb.Plan | None = None) -> pd.DataFrame:
    out = []
    for (name, p), g in df.groupby(["vehicle", "parameter"], sort=False):
        truth = VEHICLES[name]
        prior = truth_prior(truth, setting)
        prog = programme(truth, prior, setting, bench)
        predicted = prior.predict(prog).sd_log.get(p, math.nan)
        statistical = prior.predict(replace(prog, systematic={})).sd_log.get(p, math.nan)
        ok = g[g["identified"]]
        logs = np.log(ok["estimate"].to_numpy(float))
        n = len(logs)
        realised = float(np.std(logs, ddof=1))
        lo = realised * math.sqrt((n - 1) / stats.chi2.ppf(0.95, n - 1))
        hi = realised * math.sqrt((n - 1) / stats.chi2.ppf(0.05, n - 1))
        pilots = ok["pilot_draws_sd_log"].to_numpy(float) / realised
        pilots = pilots[np.isfinite(pilots)]
        central = ok["pilot_sd_log"].to_numpy(float) / realised
        central = central[np.isfinite(central)]
        bias = float(np.mean(logs - math.log(float(g["truth"].iloc[0]))))
        # the spread left once the drawn instrument errors are regressed out: the statistical
        # share, against the prediction without systematic errors
        drawn = [c for c in ERRORS if c in ok.columns]
        X = np.column_stack([ok[drawn].to_numpy(float), np.ones(n)])
        rest = logs - X @ np.linalg.lstsq(X, logs, rcond=None)[0]
        rest_sd = float(np.sqrt(np.sum(rest**2) / max(n - X.shape[1], 1)))
        out.append(
            {
                "vehicle": name,
                "parameter": p,
                "replicates": n,
                "realised_sd_log": realised,
                "realised_90": f"{lo:.4f}-{hi:.4f}",
                "truth_sd_log": predicted,
                "ratio_truth": predicted / realised,
                "pilot_median": float(np.median(pilots)) if len(pilots) else math.nan,
                "pilot_10": float(np.quantile(pilots, 0.1)) if len(pilots) else math.nan,
                "pilot_90": float(np.quantile(pilots, 0.9)) if len(pilots) else math.nan,
                "central_10": float(np.quantile(central, 0.1)) if len(central) else math.nan,
                "central_90": float(np.quantile(central, 0.9)) if len(central) else math.nan,
                "statistical_ratio": (statistical / rest_sd if p != "kA" else float("nan")),
                "bias_log": bias,
                "bias_se": realised / math.sqrt(n),
                "acceptable": int(g["verdict"].str.startswith("fit acceptable").sum()),
            }
        )
    return pd.DataFrame(out)


def designed(name: str, hours: float, target: str, args) -> tuple[cb.Plan, dict]:
    """The programme an engineer designs for ``name`` from a pilot run of the bench's default
    programme (its own noise stream): ``design.best_of_length`` for ``target`` at ``hours``,
    within the heaters' limit; as the bench's plan (durations to the minute), and the
    pilot's promise per parameter (sd of log theta at its estimates, median over its draws)."""
    truth = VEHICLES[name]
    fit, _ = replicate_fit(name, 10_000, args.seed, args.setting, GENERATOR, plan(truth))
    pilot = design.prior_from_fit(fit, PILOT_DRAWS, args.seed)
    best, assessed = design.best_of_length(
        pilot, programme(truth, pilot, args.setting), target, hours
    )
    bench = dc.bench_plan(best)
    final = design.assess(pilot, programme(truth, pilot, args.setting, bench))
    binds = "; ".join(assessed.notes) or "no limit binds"
    print(
        f"designed for {name}, {target} at {hours:g} h from a pilot fit: heating "
        f"{cb.HEATING_H:g} h at the thermostat, {bench.up_h:.4g} h at {bench.powers[0]:,.0f} W, "
        f"{bench.down_h:.4g} h at {bench.powers[1]:,.0f} W; {binds}"
    )
    promised = {
        p: (final.central.sd_log[p], math.log1p(final.spread[p][1]) / design.Z95) for p in CHECKED
    }
    return bench, promised


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--replicates", type=int, default=30)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--seed", type=int, default=4601)
    parser.add_argument("--vehicles", default=",".join(VEHICLES))
    parser.add_argument("--setting", default="output_error/static/with")
    parser.add_argument("--out", type=Path)
    parser.add_argument("--from-csv", type=Path)
    parser.add_argument(
        "--designed",
        metavar="VEHICLE",
        help="design the best programme of --length-h for --target from a pilot fit of the "
        "vehicle (design.best_of_length), then run it --replicates times",
    )
    parser.add_argument("--length-h", type=float, default=40.0)
    parser.add_argument("--target", default="C_veh")
    args = parser.parse_args(argv)
    bench, promised = None, None
    if args.designed:
        bench, promised = designed(args.designed, args.length_h, args.target, args)
        args.vehicles = args.designed
    if args.from_csv:
        df = pd.read_csv(args.from_csv, keep_default_na=False, na_values=[""])
    else:
        jobs = [
            (name, r, args.seed, args.setting, GENERATOR, bench)
            for name in args.vehicles.split(",")
            for r in range(args.replicates)
        ]
        with ProcessPoolExecutor(args.jobs) as pool:
            df = pd.DataFrame([row for rows in pool.map(one_replicate, jobs) for row in rows])
        if args.out:
            df.to_csv(args.out, index=False)
    table = summary(df, args.setting, bench)
    print(f"setting {args.setting}, seed {args.seed}")
    with pd.option_context("display.width", 200, "display.max_columns", 30):
        print(table.round(4).to_string(index=False))
    if promised is not None:
        print("\nthe designed programme against its promise (the pilot's prediction):")
        for p in CHECKED:
            row = table[table["parameter"] == p].iloc[0]
            central, over_draws = promised[p]
            print(
                f"  {p}: realised sd {row['realised_sd_log']:.4f}; promised {central:.4f} at the "
                f"pilot's estimates (realised / promised {row['realised_sd_log'] / central:.3f}), "
                f"{over_draws:.4f} over its draws ({row['realised_sd_log'] / over_draws:.3f}); "
                f"bias {row['bias_log']:+.4f} = {row['bias_log'] / row['bias_se']:+.2f} SE"
            )


if __name__ == "__main__":
    main()
