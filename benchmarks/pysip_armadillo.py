"""railtherm's Kalman-filter fit of the Armadillo record beside pySIP's own fit of it, like for
like, timed side by side on one machine, interleaved round by round.

    python benchmarks/pysip_armadillo.py --pysip-python /path/to/pysip-venv/bin/python \
        [--pysip-source /path/to/pySIP] [--rounds 20] [--threads single default]

pySIP (github.com/locie/pySIP, 1.0.0) runs in its own environment (the pins of its
poetry.lock: numpy 1.24.4, scipy 1.9.3, numba 0.57.1, pandas 1.5.3, pydantic 1.10.12). One
way to build it (Python 3.11): ``python3.11 -m venv V``, then ``V/bin/pip install`` of the
runtime dependencies of pySIP's pyproject.toml with its poetry.lock's versions as constraints
(``-c``), then ``V/bin/pip install --no-deps -e PYSIP_SOURCE``.

Like for like: the same estimator, rows, hold and threads on both sides.

- Mode: maximum likelihood on both sides. pySIP's regression test
  (``tests/data/test_armadillo.py``) puts a prior on every free parameter, which makes its
  fit a maximum a posteriori one; here its set-up is taken without the priors (pySIP's
  criterion is then its negative log-likelihood plus its bounds' 1e-4 penalty), and
  railtherm's Kalman fit is run without priors too. The posteriors with the test's priors
  are compared in benchmarks/pysip_posterior.py.
- Model and data: TwTi_RoRi (pySIP) and ``interior_envelope`` (railtherm), the same network;
  the first 232 rows of the record (pySIP's set-up drops the last); the first-order hold; the
  indoor state's initial value from its first reading; diffusion on the wall state only
  (railtherm: ``fixed={"sigma_T": 0}``); the wall state's initial value estimated.
- Work timed: one whole fit, estimates and their standard deviations included. pySIP:
  ``Regressor.fit`` (BFGS with 3-point differences, from its set-up's start values);
  railtherm: ``kalman.fit`` with ``x0="measured"`` (from its automatic start: the
  output-error fit it runs first is inside the time). Each side's first fit (numba's
  compilation, imports, caches) is not timed.
- Time: wall time per fit (``time.perf_counter``) in worker processes, one per tool, which
  the benchmark asks for a fit in turn (pySIP, railtherm, pySIP, ...): a load on the machine
  falls on both alike. CPU time is printed beside it.
- Threads: ``single``: both workers started with OMP_NUM_THREADS, OPENBLAS_NUM_THREADS,
  MKL_NUM_THREADS and NUMBA_NUM_THREADS set to 1; ``default``: both with none of them set
  (each library's own default). Each worker reports the threads it has.

The table gives, per threading setting, the median and the minimum wall time of each tool,
their ratios (pySIP / railtherm), the evaluations of each fit's optimiser (scipy's nfev:
pySIP's BFGS counts every value of its criterion, its 3-point gradients included; railtherm's
trust-region search counts evaluations of the likelihood with its exact gradient and Fisher
information, not those of its output-error start and of the observed information at the
optimum), each tool's negative log-likelihood at its optimum (NLL; the formulations differ in
the initial indoor state: pySIP's set-up gives it the prior mean 26.701 degC with a fixed
standard deviation of 0.1 K, railtherm takes the first reading with the measurement variance
and does not use that reading again) and both sets of estimates.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DATA = REPO / "data" / "armadillo" / "armadillo_data_H2.csv"
ROWS = 232  # pySIP's set-up drops the record's last row
THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")

PYSIP_WORKER = r"""
import json, sys, time, warnings
warnings.filterwarnings("ignore")
import pandas as pd
if len(sys.argv) > 2:
    sys.path.insert(0, sys.argv[2])
from pysip.regressors import Regressor
from pysip.statespace.thermal_network import TwTi_RoRi

sT = 3600.0 * 24.0
df = pd.read_csv(sys.argv[1]).set_index("Time")
df.drop(df.index[-1], axis=0, inplace=True)
df.index /= sT


def parameters():  # pySIP's regression-test set-up without its priors: maximum likelihood
    return [
        dict(name="Ro", scale=1e-2, bounds=(0, None)),
        dict(name="Ri", scale=1e-3, bounds=(0, None)),
        dict(name="Cw", scale=1e7 / sT, bounds=(0, None)),
        dict(name="Ci", scale=1e6 / sT, bounds=(0, None)),
        dict(name="sigw_w", scale=1e-2 * sT**0.5, bounds=(0, None)),
        dict(name="sigw_i", value=0, transform="fixed"),
        dict(name="sigv", scale=1e-2, bounds=(0, None)),
        dict(name="x0_w", loc=25, scale=5),
        dict(name="x0_i", value=26.701, transform="fixed"),
        dict(name="sigx0_w", value=1, transform="fixed"),
        dict(name="sigx0_i", value=0.1, transform="fixed"),
    ]


def one():
    reg = Regressor(ss=TwTi_RoRi(parameters(), hold_order=1), outputs="T_int",
                    inputs=["T_ext", "P_hea"])
    assert all(p.prior is None for p in reg.ss.parameters.parameters_free)
    w0, c0 = time.perf_counter(), time.process_time()
    summary, _, res = reg.fit(df=df, options={"disp": False})
    return time.perf_counter() - w0, time.process_time() - c0, summary, res, reg


one()  # numba's first compilation
import numba
try:
    import threadpoolctl
    blas = [i["num_threads"] for i in threadpoolctl.threadpool_info()]
except ImportError:  # not among pySIP's dependencies
    blas = ["?"]
info = {"rows": len(df), "numba_threads": numba.get_num_threads(), "blas_threads": blas}
print("ready " + json.dumps(info), flush=True)
for line in sys.stdin:
    wall, cpu, summary, res, reg = one()
    th = summary.iloc[:, 0]
    out = {"wall": wall, "cpu": cpu, "nfev": int(res.nfev), "R_o": th["Ro"], "R_i": th["Ri"],
           "C_w": th["Cw"] * sT, "C_i": th["Ci"] * sT, "nll": float(reg.log_likelihood(df))}
    print("@" + json.dumps(out), flush=True)
"""

RAILTHERM_WORKER = r"""
import json, sys, time
import numpy as np
import pandas as pd
from railtherm.estimation import kalman, models, pem

raw = pd.read_csv(sys.argv[1]).iloc[: int(sys.argv[2])]
u = raw[["T_ext", "P_hea"]].to_numpy(float)
y = np.column_stack([raw["T_int"].to_numpy(float), np.full(len(raw), np.nan)])
e = pem.Experiment("h2", 1800.0, u, y, hold="first_order")
s = models.structure_for("interior_envelope")


def one():
    w0, c0 = time.perf_counter(), time.process_time()
    r = kalman.fit(s, [e], x0="measured", fixed={"sigma_T": 0.0})
    return time.perf_counter() - w0, time.process_time() - c0, r


one()  # imports, numba's cache, scipy's first calls
import threadpoolctl
blas = [i["num_threads"] for i in threadpoolctl.threadpool_info()]
try:
    import numba
    numba_threads = numba.get_num_threads()
except ImportError:
    numba_threads = None
info = {"rows": len(raw), "numba_threads": numba_threads, "blas_threads": blas}
print("ready " + json.dumps(info), flush=True)
for line in sys.stdin:
    wall, cpu, r = one()
    th = r.theta
    out = {"wall": wall, "cpu": cpu, "nfev": int(r.nfev), "R_o": 1 / th["K_o"],
           "R_i": 1 / th["K_i"], "C_w": th["C_e"], "C_i": th["C"], "nll": r.cost}
    print("@" + json.dumps(out), flush=True)
"""


class Worker:
    """A tool's fit in its own process: started with the threading setting's environment,
    asked for one fit per line."""

    def __init__(self, name: str, cmd: list[str], env: dict[str, str]):
        self.name = name
        self.proc = subprocess.Popen(
            cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
            text=True, env=env,
        )  # fmt: skip
        while True:
            line = self.proc.stdout.readline()
            if line.startswith("ready "):
                self.info = json.loads(line[6:])
                return
            if not line and self.proc.poll() is not None:
                raise SystemExit(f"the {name} worker stopped (exit {self.proc.returncode})")

    def fit(self) -> dict:
        self.proc.stdin.write("fit\n")
        self.proc.stdin.flush()
        line = self.proc.stdout.readline()
        while not line.startswith("@"):  # pySIP may print its optimiser's report
            if not line:
                raise SystemExit(f"the {self.name} worker stopped")
            line = self.proc.stdout.readline()
        return json.loads(line[1:])

    def close(self) -> None:
        self.proc.stdin.close()
        self.proc.wait()


def environment(threads: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in THREAD_VARS}
    if threads == "single":
        env.update(dict.fromkeys(THREAD_VARS, "1"))
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), *filter(None, [env.get("PYTHONPATH")])])
    return env


def run(threads: str, args) -> dict:
    env = environment(threads)
    cmd = [args.pysip_python, "-c", PYSIP_WORKER, str(DATA)]
    if args.pysip_source:
        cmd.append(args.pysip_source)
    workers = {
        "pySIP": Worker("pySIP", cmd, env),
        "railtherm": Worker(
            "railtherm", [sys.executable, "-c", RAILTHERM_WORKER, str(DATA), str(ROWS)], env
        ),
    }
    runs: dict[str, list[dict]] = {name: [] for name in workers}
    for _ in range(args.rounds):
        for name, worker in workers.items():
            runs[name].append(worker.fit())
    for worker in workers.values():
        worker.close()
    return {"workers": workers, "runs": runs}


def report(threads: str, got: dict, rounds: int) -> None:
    workers, runs = got["workers"], got["runs"]
    setting = (
        "OMP/OPENBLAS/MKL/NUMBA_NUM_THREADS = 1 for both"
        if threads == "single"
        else "none of OMP/OPENBLAS/MKL/NUMBA_NUM_THREADS set: each library's default"
    )
    print(f"\n## threads: {threads} ({setting}); {rounds} interleaved rounds, wall seconds per fit")
    mode = {
        "pySIP": "maximum likelihood (regression-test set-up without its priors)",
        "railtherm": "maximum likelihood (no priors given)",
    }
    print(
        "| tool | mode | rows | hold | threads (numba; BLAS) | median wall | min wall "
        "| median CPU | optimiser evaluations | NLL "
        "| R_o [K/W] | R_i [K/W] | C_w [J/K] | C_i [J/K] |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    med, low = {}, {}
    for name in ("pySIP", "railtherm"):
        rs, info = runs[name], workers[name].info
        wall = [r["wall"] for r in rs]
        med[name], low[name] = statistics.median(wall), min(wall)
        last = rs[-1]
        blas = ",".join(str(b) for b in info["blas_threads"]) or "-"
        print(
            f"| {name} | {mode[name]} | {info['rows']} | first order "
            f"| {info['numba_threads']}; {blas} | {med[name]:.4f} | {low[name]:.4f} "
            f"| {statistics.median(r['cpu'] for r in rs):.4f} "
            f"| {statistics.median(r['nfev'] for r in rs):.0f} | {last['nll']:.3f} "
            f"| {last['R_o']:.5g} | {last['R_i']:.5g} | {last['C_w']:.5g} | {last['C_i']:.5g} |"
        )
    ratio_med, ratio_min = med["pySIP"] / med["railtherm"], low["pySIP"] / low["railtherm"]
    print(
        f"# pySIP / railtherm, wall time per fit, threads {threads}: medians {ratio_med:.1f}, "
        f"minima {ratio_min:.1f}"
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pysip-python", required=True, help="python of an environment with pySIP")
    ap.add_argument("--pysip-source", help="pySIP's source folder, when it is not installed")
    ap.add_argument("--rounds", type=int, default=20)
    ap.add_argument(
        "--threads", nargs="+", choices=("single", "default"), default=["single", "default"]
    )
    args = ap.parse_args(argv)
    given = sys.argv[1:] if argv is None else argv
    print(f"# command: python benchmarks/pysip_armadillo.py {' '.join(given)}")
    print(
        "# pysip_armadillo: pySIP 1.0.0 (TwTi_RoRi) and railtherm (kalman.fit of "
        f"interior_envelope) on the Armadillo record, {ROWS} rows, first-order hold, maximum "
        "likelihood on both sides (no priors on either: the posteriors with pySIP's priors are "
        "compared in benchmarks/pysip_posterior.py)"
    )
    for threads in args.threads:
        report(threads, run(threads, args), args.rounds)
    return 0


if __name__ == "__main__":
    sys.exit(main())
