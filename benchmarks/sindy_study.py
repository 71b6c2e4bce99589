"""Derivative-treatment study for railtherm's SINDy cross-check (docs/sindy.md).

    python benchmarks/sindy_study.py [--seeds 20] [--jobs 2]

Which derivative treatment recovers the support and the coefficients of

    dx/dt = Xi [T, T_veh, T_o, Q_H],   x = [T, T_veh],  time in hours, Q_H in kW,

at the campaign's noise levels and logger steps? Two truths:

- Tram2: the grey box of eq. 14 (kA 979.2 W/K, C 1.8e7 J/K, K_veh 974 W/K, C_veh 1.0e7 J/K);
  right support = eq. 14, right verdict = "structure confirmed";
- Main2: eq. 14 plus a conductance K_o = 120 W/K from the body node to T_o (kA 546 W/K,
  C 2.6e6 J/K, K_veh 564 W/K, C_veh 2.4e7 J/K); right support = eq. 14 plus the T_o term in
  dT_veh/dt, right verdict = "structure contradicted" with a reason "dT_veh/dt needs a T_o
  term".

Experiment per seed (like the virtual campaign): 60 h; T_o steps between -10 and +10 degC
(whole degrees, at least 5 K apart) held 12-20 h; Q_H steps between 0 and n heater groups
(Tram2: 5 x 4 kW, Main2: 3 x 5 kW) held 3-8 h; every change on a multiple of 600 s (the
largest logger step), so that simulating exactly (ZOH,
``railtherm.estimation.models.discretize_zoh``) at
the logger step with the inputs held over each step makes the logged inputs (the value held
from each logged instant) exact. Start at equilibrium with the first inputs (even seeds) or
off it by uniform(-3, 3) K per state (odd seeds). Gaussian white noise of sd ``noise`` on T
and T_veh only. The programme depends on (vehicle, seed) only; the noise on (vehicle, seed,
noise, step); the treatments see the same data.

Treatments:

(a) ``finite_difference`` + mid inputs (railtherm's default), (b) ``finite_difference``
    without mid inputs, (c) ``smoothed_finite_difference`` + mid inputs: all by
    ``railtherm.study.sindy.cross_check`` with ``Settings(n_bootstrap=50, ...)``;
(d) discrete-time least squares x[k+1] = Phi x[k] + Gamma u[k], then A = logm(Phi)/h and
    B = A (Phi - I)^-1 Gamma (scipy.linalg.logm), then each equation's continuous
    coefficients below 0.1 x that equation's largest |coefficient| set to zero (no refit, no
    bootstrap, so no verdict).

Per cell: the fraction of seeds with exactly the right support, the median over seeds of the
largest relative error of the truly nonzero coefficients (thresholded fit; a dropped term
counts 100 %), and for (a)-(c) the fraction of right verdicts. Deterministic (fixed seeds via
numpy default_rng); prints Markdown to stdout.
"""

from __future__ import annotations

import argparse
import datetime
import platform
import time
import warnings
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pandas as pd
import pysindy as ps
import scipy
from scipy.linalg import logm

from railtherm.estimation import models
from railtherm.study import sindy

HOUR = 3600.0
KW = 1000.0
DURATION_H = 60.0
GRID_S = 600  # every input change on a multiple of this (the largest logger step)
T_O_RANGE = (-10, 10)  # degC, whole degrees
T_O_MIN_JUMP = 5.0  # K between successive T_o levels
T_O_HOLD_H = (12.0, 20.0)
Q_H_HOLD_H = (3.0, 8.0)
OFFSET_K = 3.0  # odd seeds start off equilibrium by uniform(-OFFSET_K, OFFSET_K) per state
NOISES = (0.0, 0.02, 0.07, 0.15)  # K, on T and T_veh
STEPS = (30, 60, 300, 600)  # s
TREATMENTS = {
    "a": ("finite_difference", True),
    "b": ("finite_difference", False),
    "c": ("smoothed_finite_difference", True),
    "d": None,  # discrete-time LS + matrix logarithm
}
TREATMENT_NAMES = {
    "a": "finite_difference + mid inputs (default)",
    "b": "finite_difference, inputs as logged",
    "c": "smoothed_finite_difference (pysindy defaults: Savitzky-Golay window {window_length}, "
    "polynomial order {polyorder}) + mid inputs",
    "d": "discrete-time LS + logm, threshold 0.1 x row max",
}
N_BOOTSTRAP = 50
THRESHOLD = 0.1
VEHICLES = {
    "Tram2": dict(kA=979.2, C=1.8e7, K_veh=974.0, C_veh=1.0e7, K_o=0.0, groups=5, group_W=4000.0),
    "Main2": dict(kA=546.0, C=2.6e6, K_veh=564.0, C_veh=2.4e7, K_o=120.0, groups=3, group_W=5000.0),
}


def truth(v: dict) -> tuple[np.ndarray, np.ndarray]:
    """Continuous (A, B) in SI units, with the body-to-outdoor path K_o if any."""
    A, B = models.second_order(v["kA"], v["C"], v["K_veh"], v["C_veh"])
    A = A.copy()
    B = B.copy()
    A[1, 1] -= v["K_o"] / v["C_veh"]
    B[1, 0] = v["K_o"] / v["C_veh"]
    return A, B


def xi_from(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Xi in railtherm's units: 1/h for T, T_veh, T_o; K/(h kW) for Q_H."""
    return np.column_stack([A * HOUR, B[:, :1] * HOUR, B[:, 1:] * HOUR * KW])


def programme(v: dict, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Inputs [T_o, Q_H] on the 600 s grid (one row per grid interval) and the offset of the
    initial state from equilibrium."""
    n = int(DURATION_H * HOUR / GRID_S)
    u = np.empty((n, 2))

    def fill(col: int, lo_h: float, hi_h: float, level) -> None:
        k, prev = 0, None
        while k < n:
            length = int(round(rng.uniform(lo_h, hi_h) * HOUR / GRID_S))
            value = level(prev)
            u[k : k + length, col] = value
            k, prev = k + length, value

    def t_o(prev):
        while True:
            value = float(rng.integers(T_O_RANGE[0], T_O_RANGE[1] + 1))
            if prev is None or abs(value - prev) >= T_O_MIN_JUMP:
                return value

    def q_h(prev):
        while True:
            value = float(rng.integers(0, v["groups"] + 1)) * v["group_W"]
            if value != prev:
                return value

    fill(0, *T_O_HOLD_H, t_o)
    fill(1, *Q_H_HOLD_H, q_h)
    return u, rng.uniform(-OFFSET_K, OFFSET_K, 2)


def simulate(A, B, u_grid, offset, step, equilibrium: bool) -> pd.DataFrame:
    """Exact ZOH simulation at the logger step; inputs logged as held from each instant."""
    u = np.repeat(u_grid, GRID_S // step, axis=0)
    Ad, Bd = models.discretize_zoh(A, B, step)
    x = np.empty((len(u), 2))
    x[0] = models.steady_state(A, B, u[0]) + (0.0 if equilibrium else offset)
    for k in range(len(u) - 1):
        x[k + 1] = Ad @ x[k] + Bd @ u[k]
    return pd.DataFrame(
        {
            "time": np.arange(len(u)) * float(step),
            "T": x[:, 0],
            "T_veh": x[:, 1],
            "T_o": u[:, 0],
            "Q_H": u[:, 1],
        }
    )


def discrete_logm(w: pd.DataFrame) -> np.ndarray | None:
    """(d): x[k+1] = Phi x[k] + Gamma u[k] by least squares, then A = logm(Phi)/h,
    B = A (Phi - I)^-1 Gamma, thresholded per equation. None if logm has no real value."""
    h = float(np.median(np.diff(w["time"].to_numpy(float)))) / HOUR
    x = w[list(sindy.STATES)].to_numpy(float)
    u = np.column_stack([w["T_o"].to_numpy(float), w["Q_H"].to_numpy(float) / KW])
    reg = np.column_stack([x[:-1], u[:-1]])
    coef = np.linalg.lstsq(reg, x[1:], rcond=None)[0].T
    phi, gamma = coef[:, :2], coef[:, 2:]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        log = logm(phi)
    if np.iscomplexobj(log):
        if np.max(np.abs(log.imag)) > 1e-9 * max(np.max(np.abs(log.real)), 1e-300):
            return None
        log = log.real
    A = log / h
    B = A @ np.linalg.solve(phi - np.eye(2), gamma)
    xi = np.column_stack([A, B])
    scale = np.max(np.abs(xi), axis=1, keepdims=True)
    return np.where(np.abs(xi) >= THRESHOLD * scale, xi, 0.0)


def score(xi: np.ndarray | None, true_xi: np.ndarray) -> tuple[bool, float]:
    """(exact support, largest relative error of the truly nonzero coefficients)."""
    if xi is None or not np.all(np.isfinite(xi)):
        return False, np.inf
    nz = true_xi != 0
    return bool(np.array_equal(xi != 0, nz)), float(np.max(np.abs(xi[nz] / true_xi[nz] - 1)))


def verdict_right(result: sindy.Result, name: str) -> bool:
    if name == "Tram2":
        return result.verdict == sindy.CONFIRMED
    return result.verdict == sindy.CONTRADICTED and any(
        r.startswith("dT_veh/dt needs a T_o term") for r in result.reasons
    )


def run_seed(job: tuple[str, int]) -> list[dict]:
    """All cells of one (vehicle, seed)."""
    warnings.simplefilter("ignore")
    name, seed = job
    v = VEHICLES[name]
    v_index = list(VEHICLES).index(name)
    A, B = truth(v)
    true_xi = xi_from(A, B)
    u_grid, offset = programme(v, np.random.default_rng([v_index, seed]))
    rows = []
    for s_i, step in enumerate(STEPS):
        clean = simulate(A, B, u_grid, offset, step, equilibrium=seed % 2 == 0)
        for n_i, noise in enumerate(NOISES):
            rng = np.random.default_rng([v_index, seed, n_i, s_i, 1])
            w = clean.copy()
            w[["T", "T_veh"]] += rng.normal(0.0, noise, (len(w), 2))
            for key, treatment in TREATMENTS.items():
                if treatment is None:
                    support, err = score(discrete_logm(w), true_xi)
                    right = np.nan
                else:
                    derivative, mid = treatment
                    settings = sindy.Settings(
                        n_bootstrap=N_BOOTSTRAP,
                        threshold=THRESHOLD,
                        derivative=derivative,
                        mid_inputs=mid,
                    )
                    result = sindy.cross_check([w], settings)
                    support, err = score(result.coefficients, true_xi)
                    right = float(verdict_right(result, name))
                rows.append(
                    dict(
                        vehicle=name,
                        seed=seed,
                        noise=noise,
                        step=step,
                        treatment=key,
                        support=float(support),
                        error=err,
                        verdict=right,
                    )
                )
    return rows


def cell(g: pd.DataFrame) -> str:
    err = np.median(g["error"])
    text = f"{g['support'].mean():.2f} / " + (f"{100 * err:.2g} %" if np.isfinite(err) else "inf")
    if g["verdict"].notna().all():
        text += f" / {g['verdict'].mean():.2f}"
    return text


def setup_lines() -> list[str]:
    lines = []
    for name, v in VEHICLES.items():
        lines.append(
            f"- {name}: kA {v['kA']:g} W/K, C {v['C']:.3g} J/K, K_veh {v['K_veh']:g} W/K, "
            f"C_veh {v['C_veh']:.3g} J/K, body-to-outdoor K_o {v['K_o']:g} W/K; Q_H in 0-"
            f"{v['groups']} groups of {v['group_W'] / KW:g} kW"
        )
    lines.append(
        f"- per seed: {DURATION_H:g} h; T_o whole degrees in [{T_O_RANGE[0]}, {T_O_RANGE[1]}] "
        f"degC, >= {T_O_MIN_JUMP:g} K apart, held {T_O_HOLD_H[0]:g}-{T_O_HOLD_H[1]:g} h; Q_H "
        f"held {Q_H_HOLD_H[0]:g}-{Q_H_HOLD_H[1]:g} h; changes on multiples of {GRID_S} s; even "
        f"seeds start at equilibrium, odd ones off it by uniform(-{OFFSET_K:g}, {OFFSET_K:g}) K "
        "per state; white noise on T and T_veh only; exact ZOH simulation at the logger step"
    )
    return lines


def truth_lines() -> list[str]:
    lines = [
        "| vehicle | eq. | T | T_veh | T_o | Q_H | fast, slow time constant (h) |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for name, v in VEHICLES.items():
        A, B = truth(v)
        xi = xi_from(A, B)
        tau = np.sort(-1 / np.linalg.eigvals(A).real) / HOUR
        for i, eq in enumerate(sindy.EQUATIONS):
            coefs = " | ".join(f"{c:.3g}" for c in xi[i])
            taus = f"{tau[0]:.3g}, {tau[1]:.3g}" if i == 0 else ""
            lines.append(f"| {name} | {eq} | {coefs} | {taus} |")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=20, help="seeds per cell (default 20)")
    parser.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    args = parser.parse_args()

    start = time.perf_counter()
    jobs = [(name, seed) for name in VEHICLES for seed in range(args.seeds)]
    if args.jobs > 1:
        with ProcessPoolExecutor(args.jobs) as pool:
            rows = [r for rs in pool.map(run_seed, jobs) for r in rs]
    else:
        rows = [r for job in jobs for r in run_seed(job)]
    data = pd.DataFrame(rows)
    elapsed = time.perf_counter() - start

    table = []
    for (name, noise, step), g in data.groupby(["vehicle", "noise", "step"], sort=False):
        row = {"vehicle": name, "noise sd (K)": f"{noise:g}", "step (s)": str(step)}
        for key in TREATMENTS:
            row[f"({key})"] = cell(g[g["treatment"] == key])
        table.append(row)

    print("\n".join(setup_lines()))
    print("\nTruth, Xi in 1/h (T, T_veh, T_o) and K/(h kW) (Q_H):\n")
    print("\n".join(truth_lines()))
    print()
    print(
        f"Cells: fraction of {args.seeds} seeds with the exact support / median over seeds of "
        "the largest relative error of the true nonzero coefficients / fraction of right "
        f"verdicts ((a)-(c), bootstrap {N_BOOTSTRAP} resamples). Relative threshold "
        f"{THRESHOLD:g}. Treatments: "
        + "; ".join(
            f"({k}) " + v.format(**ps.SmoothedFiniteDifference().smoother_kws)
            for k, v in TREATMENT_NAMES.items()
        )
        + ".\n"
    )
    print(pd.DataFrame(table).to_markdown(index=False, disable_numparse=True))
    print()
    print(
        f"Run {datetime.date.today().isoformat()}: {len(data)} fits, {args.seeds} seeds, "
        f"{args.jobs} worker processes, {elapsed:.1f} s wall; Python {platform.python_version()}, "
        f"numpy {np.__version__}, scipy {scipy.__version__}, pysindy {ps.__version__}."
    )


if __name__ == "__main__":
    main()
