"""What a vehicle-year costs: the annual heating energy (``railtherm.study.energy``) at a 1-minute
step with 200 parameter draws and the ideal HVAC controller, beside the scenario engine
(``railtherm.study.simulate``) on the study's 24 h pre-heating scenario, in the same run.

    python benchmarks/bench_energy.py [--draws 200] [--step-s 60]

Both advance every draw together, one vectorised step at a time (numpy arrays over the draws;
the per-step work is a (draws x n x n) matrix-vector product and a few element-wise
operations), so the cost per step and draw is the figure to compare. The vehicle is Metro2's
second-order fit (results/vehicles/Metro2/fit_order2.yaml, written by ``snakemake``), the
weather Sand Point's TMY3 year, the profile config/profiles/metro_service.yaml. Each is timed
as the best of three runs of CPU time of this process (one core).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from bench_pem import machine  # the machine line of bench_pem

from railtherm.study import energy, simulate, weather
from railtherm.study.fit import read_fit
from railtherm.study.scenario import load_scenario

REPO = Path(__file__).resolve().parents[1]


def cpu(fn, repeats: int = 3) -> float:
    best = float("inf")
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=200)
    ap.add_argument("--step-s", type=float, default=60.0)
    args = ap.parse_args(argv)
    fit = read_fit(REPO / "results" / "vehicles" / "Metro2" / "fit_order2.yaml")
    year = weather.read_weather(REPO / "config" / "weather" / "703165TY.csv")
    profile = energy.load_profile(REPO / "config" / "profiles" / "metro_service.yaml")
    scenario = load_scenario(REPO / "config" / "scenarios" / "preheat_cold_soak.yaml")

    def annual():
        energy.annual_energy(fit, year, profile, dt_s=args.step_s, draws=args.draws)

    def day():
        simulate.simulate(fit, scenario, draws=args.draws, allow_unreachable=True)

    t_year = cpu(annual, 1)
    t_day = cpu(day)
    steps_year = year.hours * 3600.0 / args.step_s
    steps_day = scenario.n_steps
    runs = args.draws + 1
    print(machine())
    print(f"Metro2 order2, {args.draws} draws, Sand Point TMY3, {args.step_s:g} s step\n")
    print("| task | steps | CPU time | µs per step and run |")
    print("|---|---|---|---|")
    per_year = 1e6 * t_year / steps_year / runs
    per_day = 1e6 * t_day / steps_day / runs
    print(f"| one vehicle-year (energy) | {steps_year:,.0f} | {t_year:.3g} s | {per_year:.3g} |")
    print(
        f"| the 24 h pre-heating scenario (simulate) | {steps_day:,} | {t_day:.3g} s | "
        f"{per_day:.3g} |"
    )
    print(
        f"\nper step and run, the year's engine costs {per_year / per_day:.2g} times the scenario's"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
