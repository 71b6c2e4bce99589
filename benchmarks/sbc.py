"""Simulation-based calibration (Talts et al. 2018) of railtherm's posterior sampling, both
estimators, on records written by a generator of this file (not railtherm.synth, not
railtherm.estimation.models).

    python benchmarks/sbc.py [--records 200] [--jobs 2] [--estimators output_error,kalman]
        [--seed 2018] [--out ranks.csv] [--oe-x0 estimated]

For each record: the second-order model's parameters (kA, C, K_veh, C_veh) are drawn from
the prior the posterior uses (lognormal, medians 700 W/K, 1e7 J/K, 500 W/K, 1.5e7 J/K, log
sd 0.2, 0.3, 0.3, 0.3); a 24-hour programme (heater steps of 0-20 kW every 3 h, outdoor
steps in [-20, 0] degC every 8 h) at a 5-minute step is simulated from the steady state of
the first inputs by this file's own exact discretisation (scipy.linalg.expm of the augmented
system; the process noise's covariance by Van Loan's block exponential), and T and T_veh are
read with white noise of sd 0.1 K.

- output_error: the deterministic simulation plus the reading noise; the posterior of
  railtherm.estimation.sampling with the simulation error's likelihood (the noise variance
  integrated out, iid residuals), the initial states estimated (flat; ``--oe-x0 measured``:
  the first reading taken as the exact initial state instead).
- kalman: the stochastic model (diffusion 2e-3 K/sqrt(s) on both states) plus the reading
  noise; the posterior with the filter's likelihood, the noise parameters given (fixed at the
  generator's), the initial state from the first reading.

Each posterior: 2 chains x (300 tuning + 400 draws), seeded per record; the rank of the
truth among 99 draws taken evenly from the 800 (thinned against autocorrelation) is a number
0-99, uniform if the posterior is calibrated. Printed per estimator and parameter: the
chi-square test of the ranks in 10 bins (9 degrees of freedom) and its p-value, and the
records whose sampling did not converge (R-hat > 1.05 or divergences), which are kept: a
calibration is of the whole procedure.
"""

from __future__ import annotations

import argparse
import math
import os
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pandas as pd
from scipy import linalg, stats

PARAMETERS = ("kA", "C", "K_veh", "C_veh")
PRIOR = {"kA": (700.0, 0.2), "C": (1.0e7, 0.3), "K_veh": (500.0, 0.3), "C_veh": (1.5e7, 0.3)}
DT = 300.0
ROWS = 288
SIGMA = 2e-3  # K / sqrt(s), both states (kalman)
READ_SD = 0.1  # K
DRAWS, TUNE, CHAINS, RANKS = 400, 300, 2, 99


def matrices(theta):
    """dx/dt = A x + B u, x = (T, T_veh), u = (T_o, Q_H): eqs. 7-8."""
    kA, C, K, Cv = (theta[p] for p in PARAMETERS)
    A = np.array([[-(kA + K) / C, K / C], [K / Cv, -K / Cv]])
    B = np.array([[kA / C, 1.0 / C], [0.0, 0.0]])
    return A, B


def discretise(A, B, h):
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n], M[:n, n:] = A, B
    E = linalg.expm(M * h)
    return E[:n, :n], E[:n, n:]


def process_noise(A, q, h):
    """Van Loan: the covariance of the noise integrated over a step, for diffusion q I."""
    n = len(A)
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n], M[:n, n:], M[n:, n:] = -A, q * np.eye(n), A.T
    E = linalg.expm(M * h)
    Ad_T = E[n:, n:]
    return Ad_T.T @ E[:n, n:]


def record(i: int, seed: int, estimator: str):
    rng = np.random.default_rng([seed, i])
    theta = {p: float(m * math.exp(s * rng.standard_normal())) for p, (m, s) in PRIOR.items()}
    t = np.arange(ROWS) * DT
    q = rng.uniform(0.0, 20_000.0, size=ROWS // 36 + 1)[(t // 10_800).astype(int)]
    to = rng.uniform(-20.0, 0.0, size=ROWS // 96 + 1)[(t // 28_800).astype(int)]
    u = np.column_stack([to, q])
    A, B = matrices(theta)
    Ad, Bd = discretise(A, B, DT)
    x = np.empty((ROWS, 2))
    x[0] = np.linalg.solve(A, -B @ u[0])
    root = None
    if estimator == "kalman":
        root = np.linalg.cholesky(process_noise(A, SIGMA**2, DT))
    for k in range(ROWS - 1):
        x[k + 1] = Ad @ x[k] + Bd @ u[k]
        if root is not None:
            x[k + 1] += root @ rng.standard_normal(2)
    y = x + READ_SD * rng.standard_normal(x.shape)
    return theta, u, y


def one(job) -> dict:
    i, seed, estimator, oe_x0 = job
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    from railtherm.estimation import models, pem, sampling
    from railtherm.estimation.priors import Prior

    theta, u, y = record(i, seed, estimator)
    e = pem.Experiment(f"r{i}", DT, u, y, x0=y[0].copy())
    priors = {p: Prior("lognormal", PRIOR[p]) for p in PARAMETERS}
    options = {"priors": priors}
    if estimator == "kalman":
        noise = {"sigma_T": SIGMA, "sigma_T_veh": SIGMA, "s_T": READ_SD**2, "s_T_veh": READ_SD**2}
        options.update(fixed=noise, x0="measured")
    else:  # the first reading is no exact initial state of a simulation: estimated
        options.update(covariance="iid", x0=oe_x0)
    row = {"record": i, "estimator": estimator}
    try:
        post = sampling.sample(
            models.STRUCTURES["second_order"], [e], estimator=estimator, chains=CHAINS,
            draws=DRAWS, tune=TUNE, seed=seed + i, **options,
        )  # fmt: skip
    except Exception as err:  # noqa: BLE001 - a failed record is reported, not hidden
        row["error"] = f"{type(err).__name__}: {err}"
        return row
    summary = post.summary()
    row["rhat_max"] = float(summary["r_hat"].max())
    row["divergences"] = post.divergences()
    take = np.linspace(0, CHAINS * DRAWS - 1, RANKS).round().astype(int)
    for p in PARAMETERS:
        draws = post.idata.posterior[p].values.ravel()[take]
        row[p] = int(np.sum(draws < theta[p]))
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--records", type=int, default=200)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--seed", type=int, default=2018)
    parser.add_argument("--estimators", default="output_error,kalman")
    parser.add_argument("--out", help="write the ranks (CSV)")
    parser.add_argument(
        "--oe-x0",
        default="estimated",
        choices=("estimated", "measured"),
        help="output error's initial states: estimated, or the first reading taken as exact",
    )
    args = parser.parse_args()
    jobs = [
        (i, args.seed, estimator, args.oe_x0)
        for estimator in args.estimators.split(",")
        for i in range(args.records)
    ]
    rows = []
    with ProcessPoolExecutor(args.jobs) as pool:
        for row in pool.map(one, jobs, chunksize=4):  # each record's ranks as they come
            rows.append(row)
            if args.out:
                pd.DataFrame(rows).to_csv(args.out, index=False)
    df = pd.DataFrame(rows)
    print(
        f"SBC: {args.records} records per estimator (seed {args.seed}); ranks of the truth "
        f"among {RANKS} of {CHAINS} x {DRAWS} draws ({TUNE} tuning), 10 bins, chi-square 9 dof"
    )
    print("| estimator | parameter | records | chi-square | p | not converged |")
    print("|---|---|---|---|---|---|")
    for estimator, part in df.groupby("estimator", sort=False):
        ok = part.dropna(subset=list(PARAMETERS))
        bad = int(((ok["rhat_max"] > 1.05) | (ok["divergences"] > 0)).sum())
        failed = len(part) - len(ok)
        for p in PARAMETERS:
            counts = np.histogram(ok[p], bins=10, range=(0, RANKS + 1))[0]
            chi2, pval = stats.chisquare(counts)
            print(
                f"| {estimator} | {p} | {len(ok)} (failed {failed}) | {chi2:.2f} | {pval:.3f} "
                f"| {bad} |"
            )


if __name__ == "__main__":
    main()
