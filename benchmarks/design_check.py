"""Predicted against realised interval widths of designed programmes, on two virtual tunnels.

    python benchmarks/design_check.py [--runs 30] [--generator calibration,campaign]
        [--seed 3301] [--out runs.csv]
    python benchmarks/design_check.py --from-csv runs.csv   # the table of a saved run
    python benchmarks/design_check.py --shortest Tram1 [--target C_veh=10%] [--repeats 5]

Each run does what a test engineer planning a re-test does, then runs the test virtually:

1. **Prior**: a pilot fit of the vehicle (``design.prior_from_fit``): its estimates, its
   residual RMSE and autocorrelation time.
2. **Design**: ``design.best_of_length`` for C_veh, at a length drawn per run, within the
   heaters' limit: the programme's later phases' durations (and, where the heaters allow any
   level, their powers).
3. **Prediction**: the 95 % half-width of C, K_veh and C_veh that ``design.predict`` expects
   for that programme at the prior.
4. **Virtual run**: the designed programme simulated by the generator from the vehicle's
   truth (other noise and instrument errors than the pilot's), fitted as the study fits it
   (``railtherm.study.run.fit_vehicle``, output error, kA from the static test).
5. **Measured**: ratio = predicted sd of log(theta) / the fit's own (its combined 95 %
   interval's log half-width / 1.96), and z = log(estimate / truth) / predicted sd.

Generators:

- ``calibration``: the independent generator of ``benchmarks/calibration.py`` (its own
  vehicles, thermostat heating phase with the k window, then two held phases at any power up
  to 1.5 times the thermostat's steady power). The pilot is its default 70 h programme; the
  designed length is drawn between 30 and 70 h.
- ``campaign``: the package's campaign generator (``railtherm.synth``) for the campaign's
  vehicles that declare no deviation from the model, the study's fits of their campaign
  records as the pilots (where acceptable); the
  paper's special programme (steady start, step up, step reversed) whose heater groups stay
  as the campaign's (the levels are whole groups: durations are designed); the designed length
  is drawn between 36 h and the vehicle's campaign programme.

Printed per generator and parameter: the runs, the median ratio with its 90 % bootstrap
interval, the 10-90 % range of the ratio, and the rms of z (1 when the predicted sd is the
realised spread).
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
import calibration as cb  # noqa: E402  (the independent generator)

from railtherm.config import load_vehicle  # noqa: E402
from railtherm.study import design, run  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
CAMPAIGN = ROOT / "config" / "campaign" / "virtual_cwt.yaml"
CHECKED = ("C", "K_veh", "C_veh")
TARGET = "C_veh"


def fitted(yaml_path: Path):
    """The study's second-order fit of one vehicle file."""
    vehicle = load_vehicle(yaml_path, workdir=yaml_path.parent)
    return run.fit_vehicle(vehicle, ["order2"], workdir=yaml_path.parent).fits["order2"]


def realised_sd(fit, p: str) -> float:
    par = fit.parameters[p]
    if not par.identified or par.ci95_combined is None or par.ci95_combined[0] <= 0:
        return math.inf
    lo, hi = par.ci95_combined
    return (math.log(hi) - math.log(lo)) / (2 * design.Z95)


def rows_of(generator, vehicle, length_h, prediction, fit, truth, hours) -> list[dict]:
    rows = []
    for p in CHECKED:
        sd_pred, sd_real = prediction.sd_log[p], realised_sd(fit, p)
        rows.append(
            {
                "generator": generator,
                "vehicle": vehicle,
                "length_h": round(hours, 3),
                "drawn_h": round(length_h, 3),
                "parameter": p,
                "predicted_half_width": prediction.half_width[p],
                "realised_half_width": math.expm1(design.Z95 * sd_real),
                "ratio": sd_pred / sd_real,
                "z": math.log(fit.parameters[p].value / truth[p]) / sd_pred,
                "verdict": fit.verdict,
                "kA": "estimated" if "kA" in prediction.sd_log else "static test",
            }
        )
    return rows


# ------------------------------------------------------------------------------------------
# the independent generator (benchmarks/calibration.py)

SETTING = "output_error/static/with"


def calibration_record(truth, stream: int, seed: int, i: int, directory: Path, plan) -> Path:
    """The record of ``plan`` for vehicle ``i``'s truth, its noise and instrument errors from
    their own stream: the vehicle YAML as a test engineer writes it."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, i, stream]))
    states, truth = cb.simulate(truth, rng, plan)
    raw, _ = cb.logger_file(states, rng, cb.Generator())
    csv = directory / f"{truth.vehicle}_{stream}.csv"
    raw.to_csv(csv, index=False)
    path = cb.write_yaml_file(truth, csv, SETTING, "estimated", cb.Generator(), plan)
    return path.rename(directory / f"{truth.vehicle}_{stream}.yaml")


def calibration_programme(truth, prior, plan) -> design.Programme:
    """The bench's programme as the design module reads it: the thermostat phase (not
    compared; its end is the k window), then the two held phases; sensors as declared."""
    steady = prior.theta["kA"] * (truth.T_set - truth.T_o)
    top = 1.5 * steady
    powers = plan.powers or (top, steady)
    phases = (
        design.Phase("heating", plan.heating_h, truth.T_o, (), truth.T_set, identify=False),
        design.Phase("step up", plan.up_h, truth.T_o, ((0.0, powers[0]),), window="step_up"),
        design.Phase("down", plan.down_h, truth.T_o, ((0.0, powers[1]),), window="step_down"),
    )
    noise = {
        "T": cb.NOISE_T_K / math.sqrt(cb.N_INDOOR),
        "T_veh": cb.NOISE_T_K / math.sqrt(cb.N_SURFACE),
    }
    systematic = {
        "T": cb.U_T_K / math.sqrt(cb.N_INDOOR),
        "T_veh": cb.U_T_K / math.sqrt(cb.N_SURFACE),
        "T_o": cb.U_T_K / math.sqrt(cb.N_OUTDOOR),
        "power_rel": cb.U_POWER_REL,
    }
    limits = {"max_power_W": top}
    inputs = {
        "T_o": cb.NOISE_T_K / math.sqrt(cb.N_OUTDOOR),
        # four meters, each of its share of Q_H: the sum's noise is the shares' quadrature
        "power_rel": cb.NOISE_POWER_REL / math.sqrt(cb.N_HEATER),
    }
    return design.Programme(
        f"bench {truth.vehicle}",
        phases,
        cb.STEP_S,
        noise,
        systematic,
        limits,
        "steady",
        inputs,
        cb.KWINDOW_H,
    )


def bench_plan(best: design.Programme) -> cb.Plan:
    """A designed programme (the thermostat's heating, then two held phases) as the bench's
    plan, its durations to the minute."""
    up, down = best.phases[1:]
    return cb.Plan(
        cb.HEATING_H,
        round(up.hours * 60) / 60,
        round(down.hours * 60) / 60,
        (up.steps[0][1], down.steps[0][1]),
    )


def calibration_run(seed: int, i: int, rng: np.random.Generator) -> list[dict]:
    truth = cb.draw_truth(cb.vehicle_rng(seed, i), i, cb.Generator())
    true = {"C": truth.C, "K_veh": truth.K_veh, "C_veh": truth.C_veh}
    length = float(rng.uniform(30.0, 70.0))
    with tempfile.TemporaryDirectory() as tmp:
        pilot = fitted(calibration_record(truth, 1, seed, i, Path(tmp), cb.PLAN))
        prior = design.prior_from_fit(pilot)
        base = calibration_programme(truth, prior, cb.PLAN)
        best, _ = design.best_of_length(prior, base, TARGET, hours=length)
        plan = bench_plan(best)
        designed = calibration_programme(truth, prior, plan)
        fit = fitted(calibration_record(truth, 2, seed, i, Path(tmp), plan))
        prediction = predict(prior, designed, fit)
    return rows_of("calibration", truth.vehicle, length, prediction, fit, true, designed.hours)


def predict(prior, programme, fit=None) -> design.Prediction:
    """The prediction at the prior, for the parameters ``fit`` estimated (its mode: a fit
    whose static k the records refused estimates kA too) or else the prior's."""
    free = prior.free
    if fit is not None:
        free = tuple(p for p, q in fit.parameters.items() if q.estimated is True)
    return prior.predict(programme, free=free)


# ------------------------------------------------------------------------------------------
# the campaign generator (railtherm.synth)


def campaign_pilots(campaign: dict) -> dict:
    """The study's own fit of each campaign vehicle that declares no deviation, from the
    campaign's programme and seed (what ``snakemake`` fits), where it is acceptable."""
    from railtherm.study.quality import ACCEPTABLE

    pilots = {}
    for vid, m in sorted(campaign["_merged"].items()):
        if m.get("deviations"):
            continue
        with tempfile.TemporaryDirectory() as tmp:
            fit = fitted(
                campaign_record(campaign, vid, m["programme"], campaign["seed"], Path(tmp))
            )
        if fit.verdict == ACCEPTABLE:
            pilots[vid] = fit
    return pilots


def campaign_length_h(campaign: dict, vid: str) -> float:
    from railtherm import synth

    return synth.vehicle_spec(campaign, vid)["programme"]["phases_s"]["end"] / 3600.0


def special(campaign: dict, vid: str, prior, base_h: float = 10.0) -> dict:
    """The paper's special programme for ``vid`` with the campaign's heaters: the base groups
    that hold the air near 20 K above the tunnel at the prior's kA, the step the rest."""
    m = campaign["_merged"][vid]
    groups, watts = int(m["heaters"]["groups"]), float(m["heaters"]["power_W"])
    T_tunnel = float(m["programme"]["T_tunnel"])
    base = int(min(max(round(prior.theta["kA"] * 20.0 / watts), 1), groups - 1))
    return {
        "type": "special",
        "T_tunnel": T_tunnel,
        "base_h": base_h,
        "base_groups": base,
        "step_groups": groups - base,
        "up_h": 24,
        "down_h": 24,
        "kvalue_window_h": 6,
        "overlap_h": 1,
    }


def campaign_programme(campaign: dict, vid: str, p: dict) -> design.Programme:
    """The special programme as the design module reads it: the steady start (compared in
    its last hour only, as the study's windows do), the step up and the step reversed (two
    records, as the study fits them); powers of the nominal heater groups and the fans; sensors as
    the campaign declares them."""
    m = campaign["_merged"][vid]
    watts, sensors = float(m["heaters"]["power_W"]), m["sensors"]
    fans = float(m["fans"]["n"]) * float(m["fans"]["power_W"])
    base = p["base_groups"] * watts + fans
    up = (p["base_groups"] + p["step_groups"]) * watts + fans
    T_o = p["T_tunnel"]
    phases = (
        design.Phase("steady", p["base_h"], T_o, ((0.0, base),), None, 1.0, "step_up"),
        design.Phase("step up", p["up_h"], T_o, ((0.0, up),), window="step_up"),
        design.Phase("step down", p["down_h"], T_o, ((0.0, base),), window="step_down"),
    )
    n_in, n_surface = len(sensors["indoor"]["heights_m"]), sensors["surface"]["n"]
    noise = {
        "T": float(sensors["indoor"]["noise_K"]) / math.sqrt(n_in),
        "T_veh": float(sensors["surface"]["noise_K"]) / math.sqrt(n_surface),
    }
    systematic = {
        "T": float(sensors["indoor"]["offset_sd_K"]) / math.sqrt(n_in),
        "T_veh": float(sensors["surface"]["offset_sd_K"]) / math.sqrt(n_surface),
        "T_o": float(sensors["outdoor"]["offset_sd_K"]) / math.sqrt(sensors["outdoor"]["n"]),
        "power_rel": float(m["power_meter"]["scale_u_rel"]),
    }
    step_s = float(m["logger"]["step_s"])
    return design.Programme(f"special {vid}", phases, step_s, noise, systematic, {}, "steady")


def campaign_record(campaign: dict, vid: str, p: dict, seed: int, directory: Path) -> Path:
    """The raw files and vehicle YAML of ``vid`` under the special programme ``p``, the
    campaign's noise and instrument errors drawn from ``seed``."""
    from railtherm import synth

    campaign = {**campaign, "seed": seed, "_merged": dict(campaign["_merged"])}
    campaign["_merged"][vid] = {**campaign["_merged"][vid], "programme": p}
    spec = synth.vehicle_spec(campaign, vid)
    (directory / vid).mkdir(exist_ok=True)
    for f in spec["files"]:
        synth.write_raw_file(spec, f["name"], directory / vid / f["name"])
    content = synth.vehicle_config(campaign, vid, raw_dir=".")
    path = directory / f"{vid}.yaml"
    path.write_text(yaml.safe_dump(content, sort_keys=False))
    return path


def campaign_run(
    campaign: dict, vid: str, pilot, seed: int, rng: np.random.Generator
) -> list[dict]:
    from railtherm import synth

    truth = synth.vehicle_spec(campaign, vid)["truth"]
    prior = design.prior_from_fit(pilot)
    p = special(campaign, vid, prior)
    length = float(rng.uniform(36.0, campaign_length_h(campaign, vid)))
    base = campaign_programme(campaign, vid, p)
    best, _ = design.best_of_length(
        prior, base, TARGET, hours=length, vary_power=False, min_phase_h=2.0
    )
    up, down = best.phases[1:]
    p = {**p, "up_h": round(up.hours, 2), "down_h": round(down.hours, 2)}
    designed = campaign_programme(campaign, vid, p)
    with tempfile.TemporaryDirectory() as tmp:
        fit = fitted(campaign_record(campaign, vid, p, seed, Path(tmp)))
    prediction = predict(prior, designed, fit)
    return rows_of("campaign", vid, length, prediction, fit, truth, designed.hours)


def campaign_shortest(
    campaign: dict, vid: str, target: tuple[str, float], repeats: int, seed: int
) -> None:
    """The shortest special programme (steady start kept, the two steps scaled together) that
    the prediction says reaches ``target`` for ``vid``, from the study's fit of its campaign
    record; then ``repeats`` virtual runs of it (seeds ``seed``, ``seed`` + 1, ...)."""
    from railtherm import synth

    m = campaign["_merged"][vid]
    with tempfile.TemporaryDirectory() as tmp:
        pilot = fitted(campaign_record(campaign, vid, m["programme"], campaign["seed"], Path(tmp)))
    prior = design.prior_from_fit(pilot)
    name, goal = target
    own = math.expm1(design.Z95 * realised_sd(pilot, name))
    length = campaign_length_h(campaign, vid)
    print(
        f"{vid}: the campaign's programme ({m['programme']['type']}, {length:g} h) gave "
        f"{name} = {pilot.parameters[name].value:.4g}, ±{100 * own:.2g} %"
    )
    p = special(campaign, vid, prior)
    factors = tuple(np.round(np.geomspace(0.05, 4.0, 65), 4))
    found = design.shortest(prior, campaign_programme(campaign, vid, p), target, 0.5, factors, True)
    if found is None:
        print(f"no special programme up to 4 times as long reaches {name} ±{100 * goal:g} %")
        return
    factor = found[0]
    p = {**p, "up_h": round(p["up_h"] * factor, 2), "down_h": round(p["down_h"] * factor, 2)}
    designed = campaign_programme(campaign, vid, p)
    prediction = predict(prior, designed)
    print(
        f"shortest special programme to {name} ±{100 * goal:g} %: {designed.hours:g} h "
        f"(steady {p['base_h']:g} h with {p['base_groups']} heater groups, step up "
        f"{p['step_groups']} groups for {p['up_h']:g} h, reversed for {p['down_h']:g} h); "
        f"predicted ±{100 * prediction.half_width[name]:.3g} %"
    )
    truth = synth.vehicle_spec(campaign, vid)["truth"][name]
    print("| seed | estimate | realised ± (95 %) | error | within the target |")
    print("|---|---|---|---|---|")
    for r in range(repeats):
        with tempfile.TemporaryDirectory() as tmp:
            fit = fitted(campaign_record(campaign, vid, p, seed + r, Path(tmp)))
        value = fit.parameters[name].value
        width = math.expm1(design.Z95 * realised_sd(fit, name))
        print(
            f"| {seed + r} | {value:.4g} | {100 * width:.3g} % | "
            f"{100 * (value / truth - 1):+.2g} % | {'yes' if width <= goal else 'no'} |"
        )


# ------------------------------------------------------------------------------------------


def bootstrap_median(x: np.ndarray, rng: np.random.Generator, n: int = 2000) -> tuple:
    draws = rng.choice(x, size=(n, len(x)), replace=True)
    return tuple(np.quantile(np.median(draws, axis=1), [0.05, 0.95]))


def summary(df: pd.DataFrame) -> pd.DataFrame:
    rng = np.random.default_rng(0)
    out = []
    for (generator, p), g in df.groupby(["generator", "parameter"], sort=True):
        ratio = g["ratio"].to_numpy()
        finite = ratio[np.isfinite(ratio)]
        lo, hi = bootstrap_median(finite, rng)
        z = g["z"].to_numpy()
        out.append(
            {
                "generator": generator,
                "parameter": p,
                "runs": len(g),
                "median_ratio": np.median(finite),
                "median_90_lo": lo,
                "median_90_hi": hi,
                "ratio_10": np.quantile(finite, 0.1),
                "ratio_90": np.quantile(finite, 0.9),
                "rms_z": math.sqrt(np.mean(z[np.isfinite(z)] ** 2)),
                "median_predicted_pct": 100 * g["predicted_half_width"].median(),
                "median_realised_pct": 100 * g["realised_half_width"].median(),
            }
        )
    return pd.DataFrame(out)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=30, help="runs per generator")
    parser.add_argument("--generator", default="calibration,campaign")
    parser.add_argument("--seed", type=int, default=3301)
    parser.add_argument("--out", help="write every run's rows to this CSV")
    parser.add_argument("--from-csv", help="print the table of a saved run")
    parser.add_argument(
        "--shortest",
        metavar="VEHICLE",
        help="the shortest special programme for a campaign vehicle to --target, run virtually",
    )
    parser.add_argument("--target", default="C_veh=10%")
    parser.add_argument("--repeats", type=int, default=5, help="virtual runs of --shortest")
    args = parser.parse_args(argv)
    if args.shortest:
        from railtherm import synth

        target = design.parse_target(args.target)
        campaign = synth.load_campaign(CAMPAIGN)
        campaign_shortest(campaign, args.shortest, target, args.repeats, args.seed)
        return
    if args.from_csv:
        df = pd.read_csv(args.from_csv)
    else:
        rows = []
        for generator in args.generator.split(","):
            rng = np.random.default_rng([args.seed, len(generator)])
            if generator == "calibration":
                for i in range(args.runs):
                    rows += calibration_run(args.seed, i, rng)
                    print(f"calibration run {i + 1}/{args.runs} done", file=sys.stderr)
            elif generator == "campaign":
                from railtherm import synth

                campaign = synth.load_campaign(CAMPAIGN)
                pilots = campaign_pilots(campaign)
                vehicles = sorted(pilots)
                for j in range(args.runs):
                    vid = vehicles[j % len(vehicles)]
                    rows += campaign_run(campaign, vid, pilots[vid], args.seed + j, rng)
                    print(f"campaign run {j + 1}/{args.runs} ({vid}) done", file=sys.stderr)
            else:
                parser.error(f"--generator: unknown {generator!r}")
        df = pd.DataFrame(rows)
        if args.out:
            df.to_csv(args.out, index=False)
    with pd.option_context("display.width", 200, "display.precision", 2):
        print(summary(df).to_string(index=False, float_format=lambda v: f"{v:.2f}"))


if __name__ == "__main__":
    main()
