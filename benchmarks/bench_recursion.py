"""The simulator's inner recursion z[n+1] = lam z[n] + w[n] by ``scipy.signal.lfilter`` (what
railtherm.estimation.models uses) against the one scipy alternative that does not import
scipy.signal (whose import, with scipy.stats, is 0.4-0.5 s of every job that simulates): LAPACK's
triangular banded solve ``scipy.linalg.lapack.dtbtrs`` of the bidiagonal system.

    python benchmarks/bench_recursion.py

Prints, per channel count C and length N, the best of 3 rounds of each (time per call) and
their ratio, and checks that both give the same z (relative 1e-12).
"""

from __future__ import annotations

import timeit

import numpy as np
from scipy.linalg.lapack import dtbtrs
from scipy.signal import lfilter

LAM = 0.999  # a slow mode: exp(-dt/tau), dt = 60 s, tau ~ 17 h


def by_lfilter(w: np.ndarray, z0: np.ndarray) -> np.ndarray:
    return lfilter([0.0, 1.0], [1.0, -LAM], w, axis=-1, zi=z0[:, None])[0]


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


def main() -> None:
    rng = np.random.default_rng(1)
    print("| C | N | lfilter | dtbtrs | dtbtrs / lfilter |")
    print("|---|---|---|---|---|")
    for C in (1, 4):
        for N in (1_000, 10_000, 100_000):
            w, z0 = rng.normal(size=(C, N)), rng.normal(size=C)
            a, b = by_lfilter(w, z0), by_banded_solve(w, z0)
            assert np.allclose(a, b, rtol=1e-12, atol=1e-12 * np.abs(a).max())
            n = max(1, 200_000 // N)
            t = [
                min(timeit.repeat(lambda f=f, w=w, z0=z0: f(w, z0), number=n, repeat=3)) / n
                for f in (by_lfilter, by_banded_solve)
            ]
            print(
                f"| {C} | {N:.0e} | {t[0] * 1e3:.3f} ms | {t[1] * 1e3:.3f} ms | {t[1] / t[0]:.2f} |"
            )


if __name__ == "__main__":
    main()
