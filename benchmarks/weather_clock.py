"""What placing each weather value on the hour it describes changes in the annual energy.

    python benchmarks/weather_clock.py [--results results] [--draws 0]

For every vehicle with an acceptable second-order fit in the study's results and every
typical year of config/config.yaml (NREL TMY3 files, stamped at the end of each hour), the
annual heating and pre-heating energy of the central run (``--draws 0``) under the study's
profile, with the weather as read (each value at its stamp) and with every value an hour
early (the record stamped 01:00 at 00:00, as a reader that counts hours from the first
record places it). Prints each change relative to the year as read.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np
import yaml

from railtherm.study import energy, weather
from railtherm.study.fit import read_fit
from railtherm.study.quality import ACCEPTABLE

ROOT = Path(__file__).resolve().parents[1]


def hour_early(year: weather.Weather) -> weather.Weather:
    """The same values, each an hour before the instant it describes."""
    period = len(year.t_s) * year.step_s
    return replace(year, t_s=np.mod(year.t_s - 3600.0, period))


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--results", default="results")
    ap.add_argument("--draws", type=int, default=0)
    args = ap.parse_args(argv)
    config = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())["energy"]
    profile = energy.load_profile(ROOT / config["profile"])
    years = [weather.read_weather(ROOT / w) for w in config["weather"]]
    print("| vehicle | climate | annual heating, an hour early vs as read | pre-heating |")
    print("|---|---|---|---|")
    changes = {"energy": [], "preheat": []}
    for path in sorted((ROOT / args.results / "vehicles").glob("*/fit_order2.yaml")):
        fit = read_fit(path)
        if fit.verdict != ACCEPTABLE:
            continue
        for year in years:
            kw = {"dt_s": float(config["step_s"]), "draws": args.draws}
            read = energy.annual_energy(fit, year, profile, **kw)
            early = energy.annual_energy(fit, hour_early(year), profile, **kw)
            e = 100 * (early.energy_kWh[0, 0] / read.energy_kWh[0, 0] - 1)
            p = 100 * (early.preheat_kWh[0, 0] / read.preheat_kWh[0, 0] - 1)
            changes["energy"].append(e)
            changes["preheat"].append(p)
            print(f"| {fit.vehicle} | {year.name} | {e:+.2f} % | {p:+.2f} % |")
    for what, values in changes.items():
        print(f"{what}: {min(values):+.2f} % to {max(values):+.2f} %")


if __name__ == "__main__":
    main()
