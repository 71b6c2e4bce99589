"""Noise on a measured input (errors in variables): the bias it gives each estimator and how
well each estimator's interval claims the spread, over independent realisations.

    python benchmarks/input_noise.py [--count 40] [--sd 1000] [--jobs 2]

Data: the second-order model with the Tram2 truth (kA 979.2 W/K fixed, C 1.8e7 J/K, K_veh 974
W/K, C_veh 1e7 J/K) without process noise, simulated from its steady state on a 30 h record
at 60 s (T_o -10 degC; Q_H 20 kW for 2 h, then 29 kW); T measured with 0.02 K white noise,
T_veh not; the measured Q_H carries white noise of ``--sd`` W (seed = the realisation's
number). Fits, with the truth as start (two-stage, x0 estimated): output error plain and with
``input_noise`` (the compensated criterion and the input-noise share of the covariance), the
Kalman filter plain and with ``input_noise``. Printed per fit and parameter: the mean log
error with its standard error, the realised sd of the log estimates and the claimed one (the
rms of ``sd_log``; equal to the realised sd for honest intervals).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from calibration import collect  # noqa: E402
from records import S2, noisy_power_record  # noqa: E402
from records import TRAM2 as TRUTH  # noqa: E402

from railtherm.estimation import kalman, pem  # noqa: E402

NAMES = ("C", "K_veh", "C_veh")
N = 1800


def one(job: tuple) -> list[dict]:
    seed, sd = job
    _, u, y = noisy_power_record(seed, sd, N)
    e = pem.Experiment(name="step", dt=60.0, u=u, y=y)
    options = {
        "fixed": {"kA": TRUTH["kA"]},
        "x0": "estimated",
        "start": "initial",
        "initial": TRUTH,
    }
    noise = {"input_noise": {"Q_H": sd}}
    fits = {
        "output error": pem.fit(S2, [e], **options),
        "output error, input_noise": pem.fit(S2, [e], **options, **noise),
        "Kalman": kalman.fit(S2, [e], **options),
        "Kalman, input_noise": kalman.fit(S2, [e], **options, **noise),
    }
    return [
        {
            "seed": seed,
            "fit": name,
            "parameter": p,
            "log_error": math.log(r.theta[p] / TRUTH[p]),
            "sd_log": r.sd_log[p],
        }
        for name, r in fits.items()
        for p in NAMES
    ]


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=40)
    parser.add_argument("--sd", type=float, default=1000.0, help="noise on Q_H, W")
    parser.add_argument("--jobs", type=int, default=2)
    args = parser.parse_args(argv)
    rows = collect(one, [(seed, args.sd) for seed in range(args.count)], args.jobs, "record")
    df = pd.DataFrame(rows)
    table = df.groupby(["fit", "parameter"], sort=False).agg(
        mean_log_error=("log_error", "mean"),
        se=("log_error", lambda v: v.std(ddof=1) / math.sqrt(len(v))),
        realised_sd=("log_error", lambda v: v.std(ddof=1)),
        claimed_sd=("sd_log", lambda v: math.sqrt(float(np.mean(np.square(v))))),
    )
    print(f"{args.count} realisations, {args.sd:g} W of white noise on Q_H")
    print(table.to_string(float_format="{:+.4f}".format))


if __name__ == "__main__":
    main()
