"""The Armadillo posterior by railtherm's sampler beside pySIP's ``Regressor.sample``, like
for like, one thread each, interleaved in one run.

    python benchmarks/pysip_posterior.py --pysip-python /path/to/pysip-venv/bin/python \
        [--pysip-source /path/to/pySIP] [--chains 4] [--draws 1000] [--tune 1000] [--rounds 1]

pySIP (github.com/locie/pySIP, 1.0.0) runs in its own environment (see
benchmarks/pysip_armadillo.py for one way to build it; its ``sample`` needs PyMC 5 and
PyTensor, with numpy < 2, pandas < 2, pydantic < 2, scipy < 1.13, matplotlib < 3.9).

Like for like:

- Model and data: TwTi_RoRi (pySIP) and ``interior_envelope`` (railtherm), the first 232
  rows of the record (pySIP's set-up drops the last), the first-order hold, diffusion on the
  wall state only, the indoor state's initial value from its first reading (pySIP: its
  regression test's 26.701 degC, sd 0.1 K).
- Priors: those of pySIP's regression test (tests/data/test_armadillo.py) as its ``fit``
  reads them: LogNormal(1, 1) on each scaled value, i.e. R_o, R_i, C_w, C_i, the wall's
  diffusion and the measurement sd lognormal with median e x their scale and log sd 1, and
  the wall's initial state normal with mean 25 degC and sd 5 K. pySIP's ``sample`` puts a
  prior on each parameter's value in pySIP's units (days), not on the scaled value, so it is
  given the same distributions in those units (LogNormal(1 + ln scale, 1), Normal(25, 5)).
  railtherm holds conductances and variances: a lognormal prior on R = 1/K is the lognormal
  prior on K with median 1/median(R) and the same log sd, one on the sd of the measurement
  noise the lognormal prior on its variance with median squared and twice the log sd.
- Sampler: NUTS on both sides, ``chains`` chains of ``tune`` tuning and ``draws`` draws,
  one chain after the other in one process, target acceptance 0.8. pySIP: PyMC's sampler
  (its ``sample``, cores=1; its gradient by finite differences of its likelihood). railtherm:
  nutpie on railtherm's Kalman-filter likelihood with its exact gradient
  (railtherm.estimation.sampling).
- Threads: OMP/OPENBLAS/MKL/NUMBA_NUM_THREADS = 1 for both workers.
- Time: the sampling alone (PyMC's ``sampling_time``, without compiling its model; nutpie's
  wall time, after railtherm's MAP fit that starts the chains), and each worker's whole call.

Printed per tool: posterior mean and 2.5-97.5 % quantiles of R_o, R_i, C_w and C_i, R-hat,
bulk ESS, and ESS per second of sampling (the smallest bulk ESS of the four over the
sampling time) and per CPU second of the whole call (each worker's process time); then the
ratio of the means and interval ends, and of the two rates.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DATA = REPO / "data" / "armadillo" / "armadillo_data_H2.csv"
ROWS = 232
THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")
PARAMETERS = ("R_o", "R_i", "C_w", "C_i")

# both workers' last lines: each parameter's mean, 2.5 % and 97.5 % quantiles, R-hat and bulk
# ESS (ArviZ's, in each tool's own environment), printed as one JSON line
SUMMARY = r"""
for name, v in values.items():
    a = v.values
    out[name] = {"mean": float(a.mean()), "lo": float(np.quantile(a, 0.025)),
                 "hi": float(np.quantile(a, 0.975)),
                 "rhat": float(az.rhat(v.to_dataset(name="x"))["x"]),
                 "ess_bulk": float(az.ess(v.to_dataset(name="x"), method="bulk")["x"])}
print("@" + json.dumps(out), flush=True)
"""

PYSIP_WORKER = (
    r"""
import json, math, sys, time, warnings
warnings.filterwarnings("ignore")
import numpy as np
import pandas as pd
data, chains, draws, tune, seed = sys.argv[1], *map(int, sys.argv[2:6])
if len(sys.argv) > 6:
    sys.path.insert(0, sys.argv[6])
import arviz as az
from pysip.params.prior import LogNormal, Normal
from pysip.regressors import Regressor
from pysip.statespace.thermal_network import TwTi_RoRi

sT = 3600.0 * 24.0
df = pd.read_csv(data).set_index("Time")
df.drop(df.index[-1], axis=0, inplace=True)
df.index /= sT


def L(scale):  # LogNormal(1, 1) on value = theta / scale, as a prior on theta
    return LogNormal(1.0 + math.log(scale), 1.0)


params = [
    dict(name="Ro", scale=1e-2, bounds=(0, None), prior=L(1e-2)),
    dict(name="Ri", scale=1e-3, bounds=(0, None), prior=L(1e-3)),
    dict(name="Cw", scale=1e7 / sT, bounds=(0, None), prior=L(1e7 / sT)),
    dict(name="Ci", scale=1e6 / sT, bounds=(0, None), prior=L(1e6 / sT)),
    dict(name="sigw_w", scale=1e-2 * sT**0.5, bounds=(0, None), prior=L(1e-2 * sT**0.5)),
    dict(name="sigw_i", value=0, transform="fixed"),
    dict(name="sigv", scale=1e-2, bounds=(0, None), prior=L(1e-2)),
    dict(name="x0_w", loc=25, scale=5, prior=Normal(25.0, 5.0)),
    dict(name="x0_i", value=26.701, transform="fixed"),
    dict(name="sigx0_w", value=1, transform="fixed"),
    dict(name="sigx0_i", value=0.1, transform="fixed"),
]
reg = Regressor(ss=TwTi_RoRi(params, hold_order=1), outputs="T_int", inputs=["T_ext", "P_hea"])
w0, c0 = time.perf_counter(), time.process_time()
tr = reg.sample(df, draws=draws, tune=tune, chains=chains, cores=1, random_seed=seed,
                progressbar=False, target_accept=0.8)
whole, cpu = time.perf_counter() - w0, time.process_time() - c0
post = tr.posterior
values = {"R_o": post["Ro"], "R_i": post["Ri"], "C_w": post["Cw"] * sT, "C_i": post["Ci"] * sT}
out = {"tool": "pySIP", "rows": len(df), "whole": whole, "cpu": cpu,
       "sampling": float(tr.sample_stats.attrs.get("sampling_time", whole)),
       "divergences": int(tr.sample_stats["diverging"].values.sum())}
"""
    + SUMMARY
)

RAILTHERM_WORKER = (
    r"""
import json, math, sys, time
import numpy as np
import pandas as pd
import arviz as az
from railtherm.estimation import models, pem, sampling
from railtherm.estimation.priors import Prior

data, rows, chains, draws, tune, seed = sys.argv[1], *map(int, sys.argv[2:7])
raw = pd.read_csv(data).iloc[:rows]
u = raw[["T_ext", "P_hea"]].to_numpy(float)
y = np.column_stack([raw["T_int"].to_numpy(float), np.full(len(raw), np.nan)])
e = pem.Experiment("h2", 1800.0, u, y, hold="first_order")
s = models.structure_for("interior_envelope")
E = math.e
priors = {  # pySIP's LogNormal(1, 1) on value = theta / scale, in railtherm's parameters
    "K_o": Prior("lognormal", (1.0 / (E * 1e-2), 1.0)),
    "K_i": Prior("lognormal", (1.0 / (E * 1e-3), 1.0)),
    "C_e": Prior("lognormal", (E * 1e7, 1.0)),
    "C": Prior("lognormal", (E * 1e6, 1.0)),
    "sigma_T_e": Prior("lognormal", (E * 1e-2, 1.0)),
    "s_T": Prior("lognormal", ((E * 1e-2) ** 2, 2.0)),
    "x0_T_e": Prior("normal", (25.0, 5.0)),
}
w0, c0 = time.perf_counter(), time.process_time()
post = sampling.sample(s, [e], x0="measured", fixed={"sigma_T": 0.0}, priors=priors,
                       chains=chains, draws=draws, tune=tune, seed=seed)
whole, cpu = time.perf_counter() - w0, time.process_time() - c0
p = post.idata.posterior
values = {"R_o": 1.0 / p["K_o"], "R_i": 1.0 / p["K_i"], "C_w": p["C_e"], "C_i": p["C"]}
out = {"tool": "railtherm", "rows": len(raw), "whole": whole, "cpu": cpu,
       "sampling": post.seconds,
       "divergences": post.divergences()}
"""
    + SUMMARY
)


def run(cmd: list[str], env: dict[str, str]) -> dict:
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
    lines = [line for line in proc.stdout.splitlines() if line.startswith("@")]
    if proc.returncode != 0 or not lines:
        raise SystemExit(f"{cmd[0]} failed:\n{proc.stderr[-3000:]}")
    return json.loads(lines[-1][1:])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pysip-python", required=True)
    parser.add_argument("--pysip-source")
    parser.add_argument("--chains", type=int, default=4)
    parser.add_argument("--draws", type=int, default=1000)
    parser.add_argument("--tune", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--rounds", type=int, default=1)
    args = parser.parse_args()
    env = {k: v for k, v in os.environ.items() if k not in THREAD_VARS}
    env.update(dict.fromkeys(THREAD_VARS, "1"))
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), *filter(None, [env.get("PYTHONPATH")])])
    settings = [str(args.chains), str(args.draws), str(args.tune), str(args.seed)]
    pysip = [args.pysip_python, "-c", PYSIP_WORKER, str(DATA), *settings]
    if args.pysip_source:
        pysip.append(args.pysip_source)
    ours = [sys.executable, "-c", RAILTHERM_WORKER, str(DATA), str(ROWS), *settings]
    print(
        f"Armadillo, {ROWS} rows, first-order hold; NUTS, {args.chains} chains x "
        f"({args.tune} tuning + {args.draws} draws), one after the other, target acceptance "
        f"0.8, seed {args.seed}; OMP/OPENBLAS/MKL/NUMBA_NUM_THREADS = 1 for both."
    )
    for r in range(args.rounds):
        got = {"pySIP": run(pysip, env), "railtherm": run(ours, env)}
        print(f"\n## round {r + 1}\n")
        print(
            "| tool | parameter | mean | 2.5 % | 97.5 % | R-hat | bulk ESS "
            "| sampling s | whole call s | whole call CPU s | divergences "
            "| ESS/s (smallest of the four) | ESS per CPU s |"
        )
        print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
        rate, cpu_rate = {}, {}
        for tool, out in got.items():
            rate[tool] = min(out[p]["ess_bulk"] for p in PARAMETERS) / out["sampling"]
            cpu_rate[tool] = min(out[p]["ess_bulk"] for p in PARAMETERS) / out["cpu"]
            for p in PARAMETERS:
                q = out[p]
                print(
                    f"| {tool} | {p} | {q['mean']:.5g} | {q['lo']:.5g} | {q['hi']:.5g} "
                    f"| {q['rhat']:.4f} | {q['ess_bulk']:.0f} | {out['sampling']:.1f} "
                    f"| {out['whole']:.1f} | {out['cpu']:.1f} | {out['divergences']} "
                    f"| {rate[tool]:.2f} | {cpu_rate[tool]:.2f} |"
                )
        print("\n| parameter | mean railtherm / pySIP | 2.5 % | 97.5 % |")
        print("|---|---|---|---|")
        for p in PARAMETERS:
            a, b = got["railtherm"][p], got["pySIP"][p]
            print(
                f"| {p} | {a['mean'] / b['mean']:.4f} | {a['lo'] / b['lo']:.4f} "
                f"| {a['hi'] / b['hi']:.4f} |"
            )
        print(f"\nESS per second, railtherm / pySIP: {rate['railtherm'] / rate['pySIP']:.1f}")
        print(
            "ESS per CPU second of the whole call, railtherm / pySIP: "
            f"{cpu_rate['railtherm'] / cpu_rate['pySIP']:.1f}"
        )


if __name__ == "__main__":
    main()
