"""What the clock check resolves at a coarse tidy step: the three-system record of
docs/examples/three_systems.py (eqs. 7-8 integrated without railtherm) with the power
analyser's start written 120 s late, fitted (second order) at `cleaning.step_s` 60 and 300 s.
Prints per step the power source's clock offset with its 95 % interval, whether it is a
reason of the verdict, the verdict, and C against the generator's truth.

    python benchmarks/clock_step.py [--late-s 120] [--steps 60 300]

docs/adding-a-vehicle.md quotes its output.
"""

from __future__ import annotations

import argparse
import datetime as dt
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))

from test_sources import (  # noqa: E402  (the record and its vehicle file, as the tests write them)
    CABIN_START,
    METER_EARLY_S,
    TRUTH,
    load,
    vehicle_yaml,
    write_three_systems,
)

from railtherm.study import run  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--late-s", type=float, default=120.0)
    parser.add_argument("--steps", type=float, nargs="+", default=[60.0, 300.0])
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        write_three_systems(folder)
        true_start = CABIN_START - dt.timedelta(seconds=METER_EARLY_S)
        late = (true_start + dt.timedelta(seconds=args.late_s)).isoformat()
        print(
            f"power analyser's start written {args.late_s:g} s late; truth C = {TRUTH['C']:g} J/K"
        )
        print("| step_s | offset (s) | 95 % (s) | reason | verdict | C (J/K) | C / truth |")
        print("|---|---|---|---|---|---|---|")
        for step in args.steps:
            changes = {"sources.power.format.time.start": late, "cleaning": {"step_s": step}}
            vehicle_yaml(folder, **changes)
            fit = run.fit_vehicle(load(folder), ["order2"], workdir=folder).fits["order2"]
            clock = fit.content["clocks"]["power"]
            ci = clock["ci95"]
            span = "none" if ci is None else f"{ci[0]:.0f} to {ci[1]:.0f}"
            reason = any("sources.power" in r for r in fit.reasons)
            print(
                f"| {step:g} | {clock['offset_s']:+.0f} | {span} | {'yes' if reason else 'no'} "
                f"| {fit.verdict} | {fit.theta['C']:.4g} | {fit.theta['C'] / TRUTH['C']:.3f} |"
            )


if __name__ == "__main__":
    main()
