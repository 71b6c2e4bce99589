"""The simulator's inner recursion z[n+1] = lam z[n] + w[n]: railtherm's compiled loop
(``railtherm.estimation.models.recursion``, numba) against ``scipy.signal.lfilter``, which it
reproduces to the bit, and against the one scipy routine that does the same recursion without
importing scipy.signal, LAPACK's triangular banded solve ``scipy.linalg.lapack.dtbtrs`` of the
bidiagonal system; then what each costs a job before it computes: the import, in a fresh
interpreter that has numpy, pandas and scipy.linalg already (as every simulating job has).

    python benchmarks/bench_recursion.py [--rounds 5]

Prints, per channel count C and length N, the CPU time per call of each, best of 7
interleaved rounds (lfilter, railtherm, dtbtrs, lfilter, ...; one thread each: none of them
threads), and the ratios to lfilter, after checking that the compiled loop gives lfilter's
numbers exactly and dtbtrs within 1e-12; then the best of ``--rounds`` start-up CPU times,
alternating between the two imports.
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from scipy.linalg.lapack import dtbtrs
from scipy.signal import lfilter

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from railtherm.estimation import models  # noqa: E402

LAM = 0.999  # a slow mode: exp(-dt/tau), dt = 60 s, tau ~ 17 h
START_UP = {
    "scipy.signal.lfilter": "from scipy.signal import lfilter",
    "railtherm recursion (numba)": (
        "import numpy as np; from railtherm.estimation.models import recursion; "
        "recursion(0.5, np.zeros((1, 2)), np.zeros(1))"
    ),
}
PRELOADED = "import numpy, pandas, scipy.linalg, time; t = time.process_time(); "
ROUNDS = 7


def by_lfilter(w: np.ndarray, z0: np.ndarray) -> np.ndarray:
    return lfilter([0.0, 1.0], [1.0, -LAM], w, axis=-1, zi=z0[:, None])[0]


def by_recursion(w: np.ndarray, z0: np.ndarray) -> np.ndarray:
    return models.recursion(LAM, w, z0)


def by_banded_solve(w: np.ndarray, z0: np.ndarray) -> np.ndarray:
    """L z = [z0, w[0], ..., w[N-2]] with L unit lower bidiagonal, -lam below the diagonal."""
    C, N = w.shape
    b = np.empty((N, C), order="F")
    b[0] = z0
    b[1:] = w[:, :-1].T
    ab = np.empty((2, N))
    ab[0] = 1.0
    ab[1] = -LAM
    z, info = dtbtrs(ab, b, uplo="L", diag="U", overwrite_b=1)
    assert info == 0
    return z.T


def interleaved(functions, w: np.ndarray, z0: np.ndarray, rounds: int) -> list[float]:
    """CPU seconds per call of each function, the best of ``rounds`` rounds in which every
    function runs once after the other (a load on the machine falls on all alike); each
    round repeats a call as often as fills ~0.2 ms of lfilter's time at this size."""
    n = max(1, 200_000 // w.shape[1])
    best = [math.inf] * len(functions)
    for _ in range(rounds):
        for i, f in enumerate(functions):
            start = time.process_time()
            for _ in range(n):
                f(w, z0)
            best[i] = min(best[i], (time.process_time() - start) / n)
    return best


def start_up(code: str) -> float:
    """CPU seconds of ``code`` in a fresh interpreter, after numpy, pandas and scipy.linalg."""
    statement = PRELOADED + code + "; print(time.process_time() - t)"
    run = subprocess.run(
        [sys.executable, "-c", statement],
        capture_output=True,
        text=True,
        check=True,
        cwd=Path(__file__).resolve().parents[1],
    )
    return float(run.stdout)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=5)
    rounds = parser.parse_args().rounds
    rng = np.random.default_rng(1)
    by_recursion(np.zeros((1, 2)), np.zeros(1))  # compiled (or loaded) before timing
    print("| C | N | lfilter | railtherm | dtbtrs | railtherm / lfilter | dtbtrs / lfilter |")
    print("|---|---|---|---|---|---|---|")
    for C in (1, 4):
        for N in (1_000, 10_000, 100_000):
            w, z0 = rng.normal(size=(C, N)), rng.normal(size=C)
            a = by_lfilter(w, z0)
            assert np.array_equal(by_recursion(w, z0), a)
            b = by_banded_solve(w, z0)
            assert np.allclose(a, b, rtol=1e-12, atol=1e-12 * np.abs(a).max())
            t = interleaved((by_lfilter, by_recursion, by_banded_solve), w, z0, ROUNDS)
            print(
                f"| {C} | {N:.0e} | {t[0] * 1e3:.3f} ms | {t[1] * 1e3:.3f} ms "
                f"| {t[2] * 1e3:.3f} ms | {t[1] / t[0]:.2f} | {t[2] / t[0]:.2f} |"
            )
    times: dict[str, list[float]] = {name: [] for name in START_UP}
    for _ in range(rounds):
        for name, code in START_UP.items():
            times[name].append(start_up(code))
    print()
    print(f"| start-up (best of {rounds}, after numpy, pandas, scipy.linalg) | CPU seconds |")
    print("|---|---|")
    for name, seconds in times.items():
        print(f"| {name} | {min(seconds):.2f} s |")


if __name__ == "__main__":
    main()
