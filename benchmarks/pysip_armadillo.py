"""railtherm's Kalman-filter fit of the Armadillo record beside pySIP's own fit of it, timed
side by side on one machine, interleaved round by round.

    python benchmarks/pysip_armadillo.py --pysip-python /path/to/pysip-venv/bin/python \
        [--pysip-source /path/to/pySIP] [--rounds 10]

pySIP (github.com/locie/pySIP, 1.0.0) runs in its own environment (the pins of its
poetry.lock: numpy 1.24.4, scipy 1.9.3, numba 0.57.1, pandas 1.5.3, pydantic 1.10.12), so it
is driven as a worker process that fits on request and reports its CPU time. One way to build
that environment (Python 3.11): ``python3.11 -m venv V``, then ``V/bin/pip install`` of the
runtime dependencies of pySIP's pyproject.toml with its poetry.lock's versions as constraints
(``-c``), then ``V/bin/pip install --no-deps -e PYSIP_SOURCE``. The set-up is its
regression test ``tests/data/test_armadillo.py``: TwTi_RoRi with the first-order hold, the 232
rows of the record (the last dropped), the indoor state fixed at its first reading, diffusion
on the wall state only; its warm fit (after numba's first compilation) is ``Regressor.fit``,
estimates and their standard deviations included. railtherm: ``kalman.fit`` of
``interior_envelope`` on the same rows, ``hold="first_order"``, ``x0="measured"``,
``fixed={"sigma_T": 0}``, intervals included. Both single-threaded (BLAS, OpenMP and numba
threads 1). The table gives the median and the minimum CPU time of each over the rounds, their
ratio, and both sets of estimates.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from railtherm.estimation import kalman, models, pem

REPO = Path(__file__).resolve().parents[1]
DATA = REPO / "data" / "armadillo" / "armadillo_data_H2.csv"
SINGLE = {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}

WORKER = r"""
import json, sys, time, warnings
warnings.filterwarnings("ignore")
import pandas as pd
if len(sys.argv) > 2:
    sys.path.insert(0, sys.argv[2])
from pysip.params.prior import LogNormal, Normal
from pysip.regressors import Regressor
from pysip.statespace.thermal_network import TwTi_RoRi

sT = 3600.0 * 24.0
df = pd.read_csv(sys.argv[1]).set_index("Time")
df.drop(df.index[-1], axis=0, inplace=True)
df.index /= sT


def parameters():
    return [
        dict(name="Ro", scale=1e-2, bounds=(0, None), prior=LogNormal(1, 1)),
        dict(name="Ri", scale=1e-3, bounds=(0, None), prior=LogNormal(1, 1)),
        dict(name="Cw", scale=1e7 / sT, bounds=(0, None), prior=LogNormal(1, 1)),
        dict(name="Ci", scale=1e6 / sT, bounds=(0, None), prior=LogNormal(1, 1)),
        dict(name="sigw_w", scale=1e-2 * sT**0.5, bounds=(0, None), prior=LogNormal(1, 1)),
        dict(name="sigw_i", value=0, transform="fixed"),
        dict(name="sigv", scale=1e-2, bounds=(0, None), prior=LogNormal(1, 1)),
        dict(name="x0_w", loc=25, scale=5, prior=Normal(0, 1)),
        dict(name="x0_i", value=26.701, transform="fixed"),
        dict(name="sigx0_w", value=1, transform="fixed"),
        dict(name="sigx0_i", value=0.1, transform="fixed"),
    ]


def one():
    reg = Regressor(ss=TwTi_RoRi(parameters(), hold_order=1), outputs="T_int",
                    inputs=["T_ext", "P_hea"])
    t0 = time.process_time()
    summary = reg.fit(df=df)[0]
    return time.process_time() - t0, summary


one()  # numba's first compilation
print("ready", flush=True)
for line in sys.stdin:
    cpu, summary = one()
    th = summary.iloc[:, 0]
    out = {"cpu": cpu, "R_o": th["Ro"], "R_i": th["Ri"], "C_w": th["Cw"] * sT,
           "C_i": th["Ci"] * sT}
    print("@" + json.dumps(out), flush=True)
"""


def railtherm_fit() -> tuple[float, dict[str, float]]:
    raw = pd.read_csv(DATA).iloc[:232]
    u = raw[["T_ext", "P_hea"]].to_numpy(float)
    y = np.column_stack([raw["T_int"].to_numpy(float), np.full(len(raw), np.nan)])
    e = pem.Experiment("h2", 1800.0, u, y, hold="first_order")
    s = models.structure_for("interior_envelope")
    t0 = time.process_time()
    r = kalman.fit(s, [e], x0="measured", fixed={"sigma_T": 0.0})
    cpu = time.process_time() - t0
    th = r.theta
    return cpu, {"R_o": 1 / th["K_o"], "R_i": 1 / th["K_i"], "C_w": th["C_e"], "C_i": th["C"]}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pysip-python", required=True, help="python of an environment with pySIP")
    ap.add_argument("--pysip-source", help="pySIP's source folder, when it is not installed")
    ap.add_argument("--rounds", type=int, default=10)
    args = ap.parse_args(argv)
    os.environ.update(SINGLE)
    env = {**os.environ, **SINGLE, "NUMBA_NUM_THREADS": "1"}
    cmd = [args.pysip_python, "-c", WORKER, str(DATA)]
    if args.pysip_source:
        cmd.append(args.pysip_source)
    worker = subprocess.Popen(
        cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
        env=env,
    )  # fmt: skip
    while worker.stdout.readline().strip() != "ready":
        if worker.poll() is not None:
            raise SystemExit(f"the pySIP worker stopped (exit {worker.returncode}): {cmd[0]}")
    railtherm_fit()  # the first call imports and builds caches, as pySIP's first compiles
    times: dict[str, list[float]] = {"pySIP": [], "railtherm": []}
    estimates: dict[str, dict[str, float]] = {}
    for _ in range(args.rounds):
        worker.stdin.write("fit\n")
        worker.stdin.flush()
        line = worker.stdout.readline()
        while not line.startswith("@"):  # pySIP prints its optimiser's report
            if not line:
                raise SystemExit("the pySIP worker stopped")
            line = worker.stdout.readline()
        got = json.loads(line[1:])
        times["pySIP"].append(got.pop("cpu"))
        estimates["pySIP"] = got
        cpu, estimates["railtherm"] = railtherm_fit()
        times["railtherm"].append(cpu)
    worker.stdin.close()
    worker.wait()
    print(f"# pysip_armadillo: {args.rounds} interleaved rounds, single-threaded, CPU seconds")
    print("| tool | median | min | R_o [K/W] | R_i [K/W] | C_w [J/K] | C_i [J/K] |")
    print("|---|---|---|---|---|---|---|")
    for tool in ("pySIP", "railtherm"):
        e = estimates[tool]
        print(
            f"| {tool} | {statistics.median(times[tool]):.3f} | {min(times[tool]):.3f} "
            f"| {e['R_o']:.5g} | {e['R_i']:.5g} | {e['C_w']:.5g} | {e['C_i']:.5g} |"
        )
    ratio = statistics.median(times["pySIP"]) / statistics.median(times["railtherm"])
    print(f"# pySIP / railtherm (medians): {ratio:.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
