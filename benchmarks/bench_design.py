"""What planning a tunnel programme costs: ``railtherm design``'s assessment and optimisation,
against one output-error fit of the same planned record, in the same run.

    python benchmarks/bench_design.py [--draws 200]

(a) the paper's programme (config/programmes/paper.yaml, 48 h at a 60 s step) for a 40 t
    metro of 330 m2 from the class reference model of the committed Table 2: the prediction
    at ``--draws`` parameter sets (``railtherm.study.design.assess``);
(b) a 60 h programme of the same shape (every phase scaled by 1.25): the shortest programme
    of its shape reaching C_veh within +-5 % with probability 0.9 (``design.shortest``,
    bisection over 17 factors, each assessed over the draws);
(c) the best programme of 60 h for C_veh (``design.best_of_length``: the steady start kept,
    the later phases' durations and powers within the heaters' 40 kW by Nelder-Mead on the
    central prediction, then assessed over the draws);
(0) the baseline: one two-stage output-error fit (``railtherm.estimation.pem.fit``, kA
    fixed, initial states estimated) of the 48 h record simulated from the class model's
    central parameters with the programme's sensor noise.

Each is timed as the best of three runs (wall clock, single process); the table gives the
times and their ratios to (0).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from bench_pem import best_of, machine  # the timing and machine line of bench_pem

from railtherm.estimation import models, pem
from railtherm.study import design

REPO = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=200, help="class draws (default: 200)")
    args = ap.parse_args(argv)
    prior = design.prior_for_class(
        "metro", 40000.0, 330.0, "config/config.yaml", "results", REPO, args.draws, 0
    )
    paper = design.load_programme(REPO / "config" / "programmes" / "paper.yaml")
    longer = design.scaled(paper, 1.25)
    target = ("C_veh", 0.05)

    structure = models.STRUCTURES["second_order"]
    u = design.programme_inputs(paper)
    x = models.simulate(structure, prior.theta, u, paper.step_s, np.full(2, u[0, 0]))
    y = x + np.random.default_rng(0).normal(0.0, 0.05, x.shape)
    record = pem.Experiment("paper", paper.step_s, u, y, x0=y[0].copy())

    def baseline():
        pem.fit(structure, [record], fixed={"kA": prior.theta["kA"]}, x0="estimated")

    t0 = best_of(baseline, 3)
    ta = best_of(lambda: design.assess(prior, paper, target), 3)
    tb = best_of(lambda: design.shortest(prior, longer, target, 0.9), 3)
    tc = best_of(lambda: design.best_of_length(prior, paper, "C_veh", 60.0), 3)
    print(machine())
    print(f"prior: {prior.source}, {len(next(iter(prior.draws.values())))} draws\n")
    print("| task | time | / one fit |")
    print("|---|---|---|")
    print(f"| (0) one output-error fit of the 48 h record | {t0:.3g} s | 1 |")
    print(f"| (a) assess the 48 h paper programme | {ta:.3g} s | {ta / t0:.3g} |")
    print(f"| (b) shortest of a 60 h programme's shape | {tb:.3g} s | {tb / t0:.3g} |")
    print(f"| (c) best programme of 60 h for C_veh | {tc:.3g} s | {tc / t0:.3g} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
