"""What a vehicle-year costs: the annual heating energy (``railtherm.study.energy``) at a 1-minute
step with 200 parameter draws and the ideal HVAC controller, beside the scenario engine
(``railtherm.study.simulate``) on the study's 24 h pre-heating scenario, in the same run.

    python benchmarks/bench_energy.py [--draws 200] [--step-s 60]
    python benchmarks/bench_energy.py --degree-hours   # the check against degree-hours

The year's engine is one compiled loop (numba) over steps and draws, the scenario engine
advances every draw together one vectorised numpy step at a time (a (draws x n x n)
matrix-vector product and a few element-wise operations); the cost per step and draw is the
figure to compare. The vehicle is Metro2's
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


def degree_hours() -> int:
    """The known-answer check of docs/energy.md: the annual energy against kA times the
    year's degree-hours below the set point, Sum (20 - T_o)+ x 1 h."""
    import tempfile

    import numpy as np
    import yaml

    from railtherm.estimation import models

    theta = {"kA": 700.0, "C": 9.0e6, "K_veh": 450.0, "C_veh": 1.8e7}
    car = simulate.ParameterSet("700 W/K car", "declared", models.STRUCTURES["second_order"], theta)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "always.yaml"
        always = {"service": {"weekdays": [[0, 24]]}, "set_point_C": 20}
        path.write_text(yaml.safe_dump({**always, "heating_limit_W": 60000}))
        profile = energy.load_profile(path)
    print("| year | step | annual energy | degree-hour estimate | difference |")
    print("|---|---|---|---|---|")
    for name in ("703165TY.csv", "723170TYA.csv"):
        year = weather.read_weather(REPO / "config" / "weather" / name)
        estimate = theta["kA"] * np.clip(20.0 - year.T_o, 0.0, None).sum() / 1000.0
        for step in (600.0, 60.0):
            kwh = energy.annual_energy(car, year, profile, dt_s=step, draws=0).energy_kWh[0, 0]
            print(
                f"| {year.name} | {step:g} s | {kwh:,.0f} kWh | {estimate:,.0f} kWh | "
                f"{100 * (kwh / estimate - 1):+.2f} % |"
            )
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=200)
    ap.add_argument("--step-s", type=float, default=60.0)
    ap.add_argument(
        "--degree-hours",
        action="store_true",
        help="a 700 W/K car in service around the clock at 20 degC without gains, in both "
        "shipped years at 600 s and 60 s, against kA times the degree-hours below 20 degC",
    )
    args = ap.parse_args(argv)
    if args.degree_hours:
        return degree_hours()
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
