"""What a vehicle-year costs: the annual heating energy (``railtherm.study.energy``) at a 1-minute
step with 200 parameter draws and one what-if on the same draws, through the compiled step loop
(``railtherm.estimation.loops.heated_steps``, numba) and, in the same run, through the numpy
step it replaced (benchmarks/energy_numpy_steps.py: every run advanced together one vectorised
step at a time), interleaved, both on one thread.

    python benchmarks/bench_energy.py [--draws 200] [--step-s 60] [--rounds 3] [--what-if k=-10%]
    python benchmarks/bench_energy.py --scenario       # per step and run, beside simulate
    python benchmarks/bench_energy.py --degree-hours   # the check against degree-hours

The vehicle is Metro2's second-order fit (results/vehicles/Metro2/fit_order2.yaml, written by
``snakemake``; ``--fit`` another), the weather Sand Point's TMY3 year, the profile
config/profiles/metro_service.yaml (``--profile``). Each kernel is timed as the best of
``--rounds`` CPU times of this process for the whole call (draws, discretisation, the
year's steps and the totals); the two years must agree (printed).
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")  # one thread for numpy's side, as numba's
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from bench_pem import machine  # noqa: E402  (the machine line of bench_pem)

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


def kernels(args) -> int:
    """The compiled step loop beside the numpy one it replaced (benchmarks/energy_numpy_steps.py),
    on the same vehicle-year with one what-if, interleaved, best of ``--rounds`` each."""
    import numpy as np
    from energy_numpy_steps import numpy_heated_steps

    fit = read_fit(Path(args.fit))
    year = weather.read_weather(REPO / "config" / "weather" / "703165TY.csv")
    profile = energy.load_profile(Path(args.profile))
    what_ifs = [energy.parse_what_if(args.what_if)]

    def year_with(kernel):
        return energy.annual_energy(
            fit, year, profile, what_ifs=what_ifs, dt_s=args.step_s, draws=args.draws,
            kernel=kernel,
        )  # fmt: skip

    energy.annual_energy(fit, year, profile, dt_s=3600.0, draws=2)  # compiled code loaded
    best = {"compiled (loops.heated_steps, numba)": math.inf, "numpy step (before)": math.inf}
    results = {}
    for _ in range(args.rounds):
        for name, kernel in zip(best, (None, numpy_heated_steps), strict=True):
            t0 = time.process_time()
            results[name] = year_with(kernel)
            best[name] = min(best[name], time.process_time() - t0)
    compiled, numpy_year = results.values()
    differences = [
        float(np.max(np.abs(getattr(compiled, a) / getattr(numpy_year, a) - 1.0)))
        for a in ("energy_kWh", "preheat_kWh", "peak_service_W", "peak_preheat_W")
    ]
    print(machine())
    print(
        f"{compiled.label}: {len(year.T_o)} h of {year.name}, profile {profile.name}, "
        f"{args.step_s:g} s step, {args.draws} draws, what-if {args.what_if!r} on the same "
        f"draws ({2 * (args.draws + 1)} runs); one thread each (numba: one core; numpy: "
        f"OMP/MKL/OpenBLAS threads {os.environ.get('OMP_NUM_THREADS')}); CPU time of this "
        f"process, best of {args.rounds} interleaved rounds\n"
    )
    print("| kernel | CPU time for the vehicle-year | ratio to the numpy step |")
    print("|---|---|---|")
    base = best["numpy step (before)"]
    for name, t in best.items():
        print(f"| {name} | {t:.2f} s | {t / base:.3f} |")
    print(
        f"\nspeed-up {base / best['compiled (loops.heated_steps, numba)']:.1f}x; the two "
        f"years agree to {max(differences):.1e} relative (annual, pre-heating and peak "
        "powers of every run and variant)"
    )
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=200)
    ap.add_argument("--step-s", type=float, default=60.0)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--what-if", default="k=-10%")
    ap.add_argument("--fit", default=str(REPO / "results/vehicles/Metro2/fit_order2.yaml"))
    ap.add_argument("--profile", default=str(REPO / "config/profiles/metro_service.yaml"))
    ap.add_argument(
        "--scenario",
        action="store_true",
        help="per step and run, the year's engine beside the scenario engine (simulate)",
    )
    ap.add_argument(
        "--degree-hours",
        action="store_true",
        help="a 700 W/K car in service around the clock at 20 degC without gains, in both "
        "shipped years at 600 s and 60 s, against kA times the degree-hours below 20 degC",
    )
    args = ap.parse_args(argv)
    if args.degree_hours:
        return degree_hours()
    if not args.scenario:
        return kernels(args)
    fit = read_fit(Path(args.fit))
    year = weather.read_weather(REPO / "config" / "weather" / "703165TY.csv")
    profile = energy.load_profile(Path(args.profile))
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
    print(
        f"{fit.vehicle} {fit.structure_name}, {args.draws} draws, {year.name}, "
        f"{args.step_s:g} s step\n"
    )
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
