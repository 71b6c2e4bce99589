"""NUTS with nutpie's low-rank modified mass matrix against its diagonal one, on one
vehicle's second-order posterior in a finished study (its class prior as the workflow gives
it), like for like: the same posterior, chains, draws, tuning and seed, one thread, the two
settings alternated in one process.

    python benchmarks/mass_matrix.py --study DIR [--vehicle Regio1] [--chains 2]
        [--draws 150] [--tune 150] [--seed 3] [--rounds 2]

DIR holds a study `snakemake` has run (config/, results/). Printed per setting and round:
the mean leapfrog steps per draw, the mean tree depth, the smallest bulk ESS and largest
R-hat over the structure's parameters, the sampling's wall and CPU seconds, and the
smallest bulk ESS per CPU second.
"""

from __future__ import annotations

import argparse
import os
import time


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--study", required=True)
    parser.add_argument("--vehicle", default="Regio1")
    parser.add_argument("--chains", type=int, default=2)
    parser.add_argument("--draws", type=int, default=150)
    parser.add_argument("--tune", type=int, default=150)
    parser.add_argument("--seed", type=int, default=3)
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    os.chdir(args.study)
    import numpy as np

    from railtherm import io as rt_io
    from railtherm.config import load_study
    from railtherm.data import ingest
    from railtherm.estimation import sampling
    from railtherm.study import classmodel, identify, pooling
    from railtherm.study.fit import read_fit
    from railtherm.study.storage import storage_corrected_k
    from railtherm.yamlio import read_yaml

    study = load_study(read_yaml("config/config.yaml"), ".")
    vid = args.vehicle
    vehicle = study.vehicles[vid]
    base = f"results/vehicles/{vid}"
    names = [w["name"] for w in vehicle.windows["identification"]]
    windows = {n: ingest.read_tidy(f"{base}/clean/{n}.csv") for n in names}
    k_stage = rt_io.read_result(f"{base}/kvalue.yaml")
    k_window = ingest.read_tidy(f"{base}/clean/kvalue.csv")
    fit = read_fit(f"{base}/fit_order2.yaml")
    members = classmodel.members_from_table2(
        "results/tables/table2.csv", {k: v.data for k, v in study.vehicles.items()}
    )
    prior = pooling.class_prior(members, vid, vehicle.data, None)
    storage = storage_corrected_k(windows, k_window, vehicle.data, k_stage)
    setup = identify.fit_setup(windows, vehicle.data, k_stage, "order2", storage, prior.terms)
    options = dict(setup.options)
    estimator = options.pop("estimator", "output_error")
    params = [p for p in fit.free if p in fit.section("parameters")]
    print(
        f"{vid} order2 ({estimator}), class prior from {', '.join(prior.reference.basis)}; "
        f"{args.chains} chains x ({args.tune} tuning + {args.draws} draws), seed {args.seed}, "
        "one thread"
    )
    print("| round | mass matrix | steps per draw | tree depth | bulk ESS (min) | R-hat (max) "
          "| wall s | CPU s | ESS per CPU s |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|")
    for r in range(args.rounds):
        for mass in ("low_rank", "diagonal"):
            c0 = time.process_time()
            post = sampling.sample(
                setup.structure, setup.exps, chains=args.chains, draws=args.draws,
                tune=args.tune, seed=args.seed, estimator=estimator, mass_matrix=mass,
                **options,
            )  # fmt: skip
            cpu = time.process_time() - c0
            stats = post.idata.sample_stats
            summary = post.summary().loc[params]
            ess = float(summary["ess_bulk"].min())
            print(
                f"| {r + 1} | {mass} | {float(np.mean(stats['n_steps'].values)):.1f} "
                f"| {float(np.mean(stats['depth'].values)):.2f} | {ess:.0f} "
                f"| {float(summary['r_hat'].max()):.3f} | {post.seconds:.1f} | {cpu:.1f} "
                f"| {ess / cpu:.2f} |"
            )


if __name__ == "__main__":
    main()
