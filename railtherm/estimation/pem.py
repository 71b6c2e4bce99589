"""Simulation-error prediction error method (paper section 5.3, eqs. 15-18 with K = 0).

The model (a :class:`railtherm.estimation.models.Structure`) is simulated exactly (zero-order hold,
eq. 15) from each experiment's initial state, and the criterion J(theta) = e^T e (eq. 17) over
the compared outputs (eq. 18; outputs in K, equal weights for every output and sample; rows
where the measurement is NaN are skipped) is minimised in log parameters, with bounds, fixed
parameters and the exact analytic Jacobian (discrete sensitivities, chain rule to log), by a
Levenberg-Marquardt on the p x p normal equations
(:func:`railtherm.estimation.solver.levenberg_marquardt`: p is small,
the data long, and scipy's general solver costs more per fit than the simulations do), with
``scipy.optimize.least_squares`` (trust-region reflective, bounded) as the fallback whenever
that fails or leaves the bounds.

* Two-stage (the paper, section 5.2): ``fixed={"kA": k A}`` from the static k stage; joint:
  kA free too.
* Several experiments share one parameter set; each has its own initial state, either
  measured (``x0="measured"``: the experiment's ``x0`` or the first row of ``y``; a state
  with no measurement there is estimated) or estimated (``x0="estimated"``: extra unknowns).
  An estimated initial state is bounded to the window's measured temperatures widened by
  X0_MARGIN_K; one that ends at that bound is flagged (``x0_at_bound``).
* Start (``start``): ``"initial"`` starts from ``initial`` (default: the paper's values);
  ``"auto"`` also computes an equation-error least-squares start (:func:`equation_error_start`,
  needs every state measured) or, failing that, a start scaled to the data
  (:func:`_scale_aware_start`: kA from the heat balance of the records, C_bar by equation
  error, a log grid of the capacities and conductances around them ranked on a
  block-averaged copy of the data), and starts from the candidate with the lowest
  simulation-error cost (``FitResult.start_used`` says which).
* Covariance in log parameters: ``"iid"``: s^2 (J^T J)^-1, s^2 = SSR / (m - p);
  ``"hac"``: Newey-West sandwich (J^T J)^-1 S (J^T J)^-1 with a Bartlett kernel per
  experiment and output (block), the bandwidth from the block's lag-1 residual
  autocorrelation (Andrews' AR(1) plug-in rule). 95 % intervals exp(log theta +- 1.96 sd).
* Identifiability flags (:class:`Flag`): wide interval (hi / lo > 10), parameter at a bound,
  |correlation| > 0.95, ill-conditioned Jacobian (cond > 1e8), non-convergence, an estimated
  initial state at its bound.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any, ClassVar

import numpy as np

from railtherm.estimation import hac, leastsquares_map, models, solver
from railtherm.estimation.common import (
    NULL_REL,
    Z95,
    Experiment,
    compared_outputs,
    fit_flags,
    heat_balance_kA,
    identification,
    lumped_capacity,
    measured_range,
    noise_levels,
    one_hold,
    single_threaded_blas,
    x0_flags,
)
from railtherm.estimation.estimate import Estimate, Flag
from railtherm.estimation.models import Structure
from railtherm.estimation.priors import LinearT, LogPrior, Prior, bounded

__all__ = [
    "Experiment",
    "FitResult",
    "Flag",
    "equation_error_start",
    "fit",
    "experiment_from_table",
    "heat_balance_kA",
    "identification",
    "lumped_capacity",
]

_LSMR_ABOVE = 300_000  # Jacobian entries above which the trust-region step uses LSMR
START_FACTORS = (0.1, 1.0, 10.0)  # the automatic start's grid around its centre
KA_FACTORS = (1.0 / 3.0, 1.0, 3.0)  # ... and around the heat balance's overall kA
START_KEEP = 3  # grid points refined
RANK_SAMPLES = 500  # samples per experiment of the block-averaged copy the grid is ranked on
COARSE_SAMPLES = 2000  # ... and of the copy the best grid points are refined on


def experiment_from_table(
    table,
    name: str,
    states=("T", "T_veh"),
    T_o_hold: str = "mean",
    inputs: Sequence[str] = ("T_o", "Q_H"),
    hold: str = "zero_order",
):
    """An :class:`Experiment` from a tidy table (railtherm.data.ingest.read_tidy).

    ``inputs``: the structure's inputs, "T_o" and "Q_H" first, then any further tidy columns
    (irradiance, e.g. "I_sol"). Zero-order ``hold`` (eq. 15): Q_H[n] is already the mean
    power over [t_n, t_n + step), and so is every further input (taken as it is). T_o is a
    point sample: with ``T_o_hold="mean"`` (default) the input over the step is
    (T_o[n] + T_o[n+1]) / 2 (the trapezoidal mean; the last row keeps T_o[N-1]), with
    ``"zoh"`` T_o[n] is held. First-order ``hold``: every input of the table is its value at
    t_n (the table was cleaned for that hold) and is taken as it is.
    """
    inputs = tuple(inputs)
    if inputs[:2] != ("T_o", "Q_H"):
        raise ValueError(f"inputs must start with ('T_o', 'Q_H'), got {inputs}")
    missing = [c for c in inputs if c not in table.columns]
    if missing:
        raise ValueError(f"experiment {name!r}: the table has no input columns {missing}")
    t = table["time"].to_numpy(float)
    dt = float(np.median(np.diff(t)))
    To = table["T_o"].to_numpy(float)
    if T_o_hold not in ("mean", "zoh"):
        raise ValueError(f"T_o_hold must be 'mean' or 'zoh', got {T_o_hold!r}")
    if models.check_hold(hold) == "zero_order" and T_o_hold == "mean":
        To = models.step_means(To, "first_order")  # the trapezoidal mean over each step
    u = np.column_stack([To] + [table[c].to_numpy(float) for c in inputs[1:]])
    y = np.column_stack(
        [
            table[s].to_numpy(float) if s in table.columns else np.full(len(t), np.nan)
            for s in states
        ]
    )
    return Experiment(name=name, dt=dt, u=u, y=y, x0=y[0].copy(), hold=hold)


@dataclass(kw_only=True)
class FitResult(Estimate):
    """The simulation-error estimate (eqs. 17-18 with K = 0), an :class:`Estimate` with
    ``estimator`` output_error: ``cost`` = e^T e (eq. 17, K^2), ``cond`` the condition number
    of the Jacobian of the log parameters, ``covariance`` "hac" or "iid", ``bandwidths`` the
    HAC bandwidth of each record and output, ``input_noise_sd`` the declared input noise;
    ``samples_weight`` the independent samples the residuals count as (m / tau,
    :func:`_tau`; not written)."""

    CONDITION: ClassVar[str] = "jacobian_condition"

    estimator: str = "output_error"
    samples_weight: float | None = None


# ----------------------------------------------------------------------------------------------
# the problem


class _Problem:
    """Residuals and Jacobian of eq. 18 in the unknowns v = [log theta_free, x0 unknowns]."""

    def __init__(self, structure, experiments, fixed, free, out_idx, x0_mode, compiled=False):
        self.s = structure
        self.compiled = compiled  # cost_x0_projected by the compiled simulation (loops)
        self.exps = list(experiments)
        self.fixed = dict(fixed)
        self.free = tuple(free)
        self.P = len(self.free)
        self.out_idx = tuple(out_idx)
        n = len(structure.states)
        self.n = n
        self.x0_base, self.x0_free, self.x0_guess, self.x0_range = [], [], [], []
        self.rows = []  # per experiment, per output: index array of compared samples or None
        for e in self.exps:
            if e.y.shape[1] != n:
                raise ValueError(
                    f"experiment {e.name!r}: y has {e.y.shape[1]} columns, structure "
                    f"{structure.name!r} has states {structure.states}"
                )
            first = e.y[0] if e.x0 is None else e.x0
            if len(first) != n:
                raise ValueError(f"experiment {e.name!r}: x0 needs {n} values, got {first}")
            base = np.array(first, dtype=float)
            free_states = (
                list(range(n))
                if x0_mode == "estimated"
                else list(np.flatnonzero(~np.isfinite(base)))
            )
            guess = base.copy()
            fallback = e.y[0][np.isfinite(e.y[0])]
            fill = float(fallback.mean()) if fallback.size else float(e.u[0, 0])
            guess[~np.isfinite(guess)] = fill
            lo, hi = measured_range(e)
            base[free_states] = 0.0
            self.x0_base.append(base)
            self.x0_free.append(free_states)
            self.x0_guess.append(np.clip(guess[free_states], lo, hi))
            self.x0_range.append((lo, hi))
            rows = []
            for i in self.out_idx:
                ok = np.isfinite(e.y[:, i])
                rows.append(None if ok.all() else np.flatnonzero(ok))
            self.rows.append(rows)
        self.n_x0 = sum(len(f) for f in self.x0_free)
        # bounds of the estimated initial states (K), in the order of the unknowns
        ranges = [r for r, f in zip(self.x0_range, self.x0_free, strict=True) for _ in f]
        self.x0_lo = np.array([r[0] for r in ranges])
        self.x0_hi = np.array([r[1] for r in ranges])
        self.m = sum(
            (len(e.y) if r is None else len(r))
            for e, rr in zip(self.exps, self.rows, strict=True)
            for r in rr
        )
        self._key = None
        self._jac_key = None
        self._pos = None
        self.uT = [np.ascontiguousarray(e.forcing.T) for e in self.exps]
        self.yT = [np.ascontiguousarray(e.y.T) for e in self.exps]

    def theta(self, v) -> dict:
        th = dict(self.fixed)
        th.update({p: float(np.exp(v[i])) for i, p in enumerate(self.free)})
        return th

    def x0s(self, v):
        out, k = [], self.P
        for base, fr in zip(self.x0_base, self.x0_free, strict=True):
            x0 = base.copy()
            x0[fr] = v[k : k + len(fr)]
            k += len(fr)
            out.append(x0)
        return out

    def _evaluate(self, v, derivatives: bool):
        key = (v.tobytes(), derivatives)
        if self._key is not None and (
            self._key == key or (self._key[0] == key[0] and not derivatives)
        ):
            return self._cache
        with np.errstate(over="ignore", invalid="ignore"):
            th = self.theta(v)
        params = self.free if derivatives else ()
        cache: dict[float, Any] = {}
        sims = []
        try:
            if not all(math.isfinite(x) and x > 0 for x in th.values()):
                raise FloatingPointError
            # extreme trial points may overflow: their residuals are then not finite, and
            # least_squares shrinks its step
            with np.errstate(over="ignore", invalid="ignore"):
                for e, uT, x0 in zip(self.exps, self.uT, self.x0s(v), strict=True):
                    if e.dt not in cache:
                        cache[e.dt] = models.discretize(self.s, th, e.dt, params, e.hold)
                    d = cache[e.dt]
                    sims.append((d, models._run_T(d, uT, x0)))
        except (ArithmeticError, np.linalg.LinAlgError, ValueError):
            sims = None  # parameters so extreme that the model cannot be evaluated
        self._key, self._cache = key, (th, sims)
        return self._cache

    def residuals(self, v) -> np.ndarray:
        """Simulated minus measured (the negative of eq. 18's e), compared samples only."""
        _, sims = self._evaluate(v, derivatives=True)
        if sims is None:
            return np.full(self.m, np.inf)  # least_squares shrinks its trust region
        out = np.empty(self.m)
        row = 0
        for yT, (_, xT), rows in zip(self.yT, sims, self.rows, strict=True):
            for i, r in zip(self.out_idx, rows, strict=True):
                if r is None:
                    N_i = xT.shape[1]
                    np.subtract(xT[i], yT[i], out=out[row : row + N_i])
                else:
                    N_i = len(r)
                    out[row : row + N_i] = xT[i, r] - yT[i, r]
                row += N_i
        return out

    def cost(self, v) -> float:
        """e^T e (eq. 17) at v, through :meth:`residuals`: the evaluation (with the
        derivatives of the discretisation) stays cached for a solve that starts at v."""
        with np.errstate(over="ignore", invalid="ignore"):
            r = self.residuals(v)
            c = float(r @ r)
        return c if math.isfinite(c) else math.inf

    def cost_only(self, v) -> float:
        """e^T e (eq. 17) at v from the simulation alone (no derivatives: cheapest)."""
        _, sims = self._evaluate(v, derivatives=False)
        if sims is None:
            return math.inf
        total = 0.0
        for yT, (_, xT), rows in zip(self.yT, sims, self.rows, strict=True):
            for i, r in zip(self.out_idx, rows, strict=True):
                diff = xT[i] - yT[i] if r is None else xT[i, r] - yT[i, r]
                total += float(diff @ diff)
        return total if np.isfinite(total) else math.inf

    def cost_x0_projected(self, v) -> tuple[float, np.ndarray]:
        """e^T e at the parameters of v with the estimated initial states at their best
        (within their bounds), and that v. The outputs are linear in x0 (x[n] depends on x0
        through Ad^n, :func:`railtherm.estimation.models.free_response_head`), so for fixed
        parameters the best initial states are one small linear least-squares problem per
        experiment:
        a start's cost is judged with the initial states the data give it, not a guess."""
        if self.compiled:
            return self._cost_x0_projected_compiled(v)
        _, sims = self._evaluate(v, derivatives=False)
        if sims is None:
            return math.inf, v
        v = v.copy()
        total, k = 0.0, 0
        for e, yT, (d, xT), rows, fr in zip(
            self.exps, self.yT, sims, self.rows, self.x0_free, strict=True
        ):
            res, cols = [], []
            F = models.free_response_head(d, len(e.u))[:, self.out_idx][:, :, fr] if fr else None
            for j, (i, r) in enumerate(zip(self.out_idx, rows, strict=True)):
                idx = np.arange(xT.shape[1]) if r is None else r
                res.append(xT[i, idx] - yT[i, idx])
                if fr:
                    G = np.zeros((len(idx), len(fr)))
                    keep = idx < len(F)
                    G[keep] = F[idx[keep], j]
                    cols.append(G)
            e_k = np.concatenate(res)
            if fr:
                with np.errstate(over="ignore", invalid="ignore"):
                    e_k = self._best_x0(v, k, len(fr), np.concatenate(cols), e_k)
                k += len(fr)
            total += float(e_k @ e_k)
        return (total if math.isfinite(total) else math.inf), v

    def _best_x0(self, v: np.ndarray, k: int, n: int, G: np.ndarray, e_k: np.ndarray):
        """One experiment's n estimated initial states (from the k-th) set in v to their
        least-squares best within their bounds, the outputs being linear in them (G = de/dx0);
        the residuals e_k at them. Non-finite states leave v and e_k as they were."""
        at = slice(self.P + k, self.P + k + n)
        step = np.linalg.lstsq(G, -e_k, rcond=None)[0]
        x0 = np.clip(v[at] + step, self.x0_lo[k : k + n], self.x0_hi[k : k + n])
        if np.all(np.isfinite(x0)):
            e_k = e_k + G @ (x0 - v[at])
            v[at] = x0
        return e_k

    def _cost_x0_projected_compiled(self, v) -> tuple[float, np.ndarray]:
        """:meth:`cost_x0_projected` with the simulation and its free response run by the
        compiled recursion :func:`railtherm.estimation.loops.output_error` from Ad, Bd alone
        (no modal form)."""
        from railtherm.estimation import loops

        with np.errstate(over="ignore", invalid="ignore"):
            th = self.theta(v)
        if not all(math.isfinite(x) and x > 0 for x in th.values()):
            return math.inf, v
        steps: dict[float, tuple[np.ndarray, np.ndarray]] = {}
        v = v.copy()
        total, k = 0.0, 0
        pos, counts = self._positions()
        try:
            with np.errstate(over="ignore", invalid="ignore"):
                for e, uT, yT, x0, fr, p, m in zip(
                    self.exps, self.uT, self.yT, self.x0s(v), self.x0_free, pos, counts,
                    strict=True,
                ):  # fmt: skip
                    if e.dt not in steps:
                        steps[e.dt] = models.transition(self.s, th, e.dt, e.hold)[:2]
                    Ad, Bd = steps[e.dt]
                    e_k, G = loops.output_error(
                        Ad, Bd, uT, x0, np.asarray(fr, dtype=np.int64), self._out, yT, p, m,
                        models.FREE_RESPONSE_CUT,
                    )  # fmt: skip
                    if fr:
                        e_k = self._best_x0(v, k, len(fr), G, e_k)
                        k += len(fr)
                    total += float(e_k @ e_k)
        except (ArithmeticError, np.linalg.LinAlgError, ValueError):
            return math.inf, v  # parameters so extreme that the model cannot be evaluated
        return (total if math.isfinite(total) else math.inf), v

    def _positions(self) -> tuple[list[np.ndarray], list[int]]:
        """Per experiment, each compared sample's place in its residual vector ((n_out, N),
        -1: not compared; the order of :meth:`residuals`) and the count of compared samples."""
        if self._pos is None:
            pos, counts = [], []
            for e, rows in zip(self.exps, self.rows, strict=True):
                p = np.full((len(self.out_idx), len(e.u)), -1, dtype=np.int64)
                row = 0
                for j, r in enumerate(rows):
                    idx = np.arange(len(e.u)) if r is None else r
                    p[j, idx] = row + np.arange(len(idx))
                    row += len(idx)
                pos.append(p)
                counts.append(row)
            self._pos = (pos, counts)
            self._out = np.asarray(self.out_idx, dtype=np.int64)
        return self._pos

    def jacobian(self, v) -> np.ndarray:
        """d(residuals)/dv (m x unknowns): the exact discrete sensitivities, times theta_p
        for the log parameters (chain rule), and the free response Ad^n for estimated
        initial states. Returned as the transpose of a C-ordered (unknowns x m) array."""
        key = v.tobytes()
        if self._jac_key == key:
            return self._jac
        th, sims = self._evaluate(v, derivatives=True)
        scale = np.array([th[p] for p in self.free])
        simple = self.n_x0 == 0 and len(self.exps) == 1 and all(r is None for r in self.rows[0])
        if simple and self.P:  # one record, every sample compared: no copy at all
            (d, xT), uT = sims[0], self.uT[0]
            S = models.parameter_sensitivities(d, xT, uT, self.free, scale, self.out_idx)
            JT = S.reshape(self.P, -1)
        else:
            JT = np.zeros((self.P + self.n_x0, self.m))
            row, col = 0, self.P
            for e, uT, (d, xT), rows, fr in zip(
                self.exps, self.uT, sims, self.rows, self.x0_free, strict=True
            ):
                S = (
                    models.parameter_sensitivities(d, xT, uT, self.free, scale, self.out_idx)
                    if self.P
                    else None
                )
                F = models.free_response_head(d, len(e.u)) if fr else None
                for k, (i, r) in enumerate(zip(self.out_idx, rows, strict=True)):
                    N_i = len(e.u) if r is None else len(r)
                    if S is not None:
                        JT[: self.P, row : row + N_i] = S[:, k] if r is None else S[:, k, r]
                    if fr:
                        head = F[:, i, :][:, fr].T  # (len(fr), n_cut)
                        if r is None:
                            JT[col : col + len(fr), row : row + head.shape[1]] = head
                        else:
                            keep = r[r < head.shape[1]]
                            JT[col : col + len(fr), row : row + len(keep)] = head[:, keep]
                    row += N_i
                col += len(fr)
        self._jac_key, self._jac = key, JT.T
        return self._jac


# ----------------------------------------------------------------------------------------------
# starts


def equation_error_start(
    structure: Structure,
    experiments: Sequence[Experiment],
    fixed: Mapping[str, float],
    initial: Mapping[str, float],
    log_bounds: tuple[np.ndarray, np.ndarray],
    free: tuple[str, ...],
) -> dict[str, float] | None:
    """Equation-error least-squares start (needs every state measured).

    Regress the continuous model on the data, dx/dt ~ (x[n+1] - x[n]) / dt, with the states
    at the step's midpoint (x[n] + x[n+1]) / 2 and the held input u[n] (consistent with the
    zero-order hold): first the unconstrained [A B] row by row (ordinary least squares through
    the sufficient statistics), then the structure's parameters closest to it in the metric of
    the regression (each row weighted by its residual variance). Returns None when a state is
    not measured or the regression is degenerate."""
    n = len(structure.states)
    k = n + len(structure.inputs)
    Szz, Szd, ss_dd, count = np.zeros((k, k)), np.zeros((k, n)), np.zeros(n), 0
    for e in experiments:
        yT = np.ascontiguousarray(e.y[:, :n].T)
        fin = np.isfinite(yT).all(axis=0)
        ok = fin[1:] & fin[:-1]
        n_ok = int(ok.sum())
        if n_ok == 0:
            continue
        # rows of ZD: Z = [step-midpoint states (x[n] + x[n+1]) / 2; held input u[n]] (k rows),
        # then D = (x[n+1] - x[n]) / dt (n rows): dx/dt over each step
        ZD = np.empty((k + n, len(ok)))
        np.add(yT[:, 1:], yT[:, :-1], out=ZD[:n])
        ZD[:n] *= 0.5
        ZD[n:k] = e.step_u[:-1].T
        np.subtract(yT[:, 1:], yT[:, :-1], out=ZD[k:])
        ZD[k:] *= 1.0 / e.dt
        if n_ok < len(ok):
            ZD = np.ascontiguousarray(ZD[:, ok])
        G = solver.gram(ZD)  # every sum of products at once
        Szz += G[:k, :k]
        Szd += G[:k, k:]
        ss_dd += np.diag(G[k:, k:])
        count += n_ok
    if count < 3 * k:
        return None
    s, U = np.linalg.eigh(Szz)
    keep = s > s.max() * 1e-12
    if not keep.any():
        return None
    sq = np.sqrt(s[keep])
    Ur = U[:, keep]
    # the unconstrained [A B]^T is Ur S^-1 Ur^T Szd; in the regression metric it is
    # ``target``, and each row's OLS residual sum of squares is ss_dd - |target column|^2
    target = (Ur.T @ Szd) / sq[:, None]  # (r, n)
    ss_res = ss_dd - (target * target).sum(axis=0)
    scale_dd = np.sqrt(ss_dd / count)
    sigma = np.sqrt(np.maximum(ss_res, 0.0) / count) + 1e-12 * scale_dd + 1e-300

    W = sq[:, None] * Ur.T  # (r, k): the regression metric
    inv_sigma = 1.0 / sigma
    target_w = target * inv_sigma
    names = structure.parameters

    def theta_of(w):
        th = dict(fixed)
        for i, p in enumerate(free):
            th[p] = math.exp(w[i])
        return th

    def fun(w):
        th = theta_of(w)
        A, B = structure.build(**{p: th[p] for p in names})
        return (W @ np.concatenate((A, B), axis=1).T * inv_sigma - target_w).ravel()

    def jac(w):
        th = theta_of(w)
        der = structure.jacobian(**{p: th[p] for p in names})
        dphi = np.stack([np.concatenate(der[p], axis=1).T * th[p] for p in free])  # (P, k, n)
        return ((W @ dphi) * inv_sigma).reshape(len(free), -1).T

    lo, hi = log_bounds
    w0 = np.clip([math.log(initial[p]) for p in free], lo, hi)
    # A small, smooth matching problem: the Levenberg-Marquardt of the main fit (no bounds;
    # the start is clipped into the bounds afterwards). When it fails (it can wander off in a
    # non-identifiable problem), the bounded trf solve.
    failures = (ValueError, ArithmeticError, np.linalg.LinAlgError)
    w = None
    if fun(w0).size >= len(free):
        try:
            with np.errstate(over="ignore", invalid="ignore"):
                sol = solver.levenberg_marquardt(fun, jac, w0)
            if sol.success and np.all(np.isfinite(sol.x)) and np.all(np.abs(sol.x - w0) < 50):
                w = np.clip(sol.x, lo, hi)
        except failures:
            w = None
    if w is None:
        try:
            from scipy.optimize import least_squares  # on first use: a job's start-up

            sol = least_squares(fun, w0, jac=jac, bounds=(lo, hi), method="trf")
        except failures:
            return None
        if not np.all(np.isfinite(sol.x)):
            return None
        w = sol.x
    return {p: float(np.exp(w[i])) for i, p in enumerate(free)}


def _block_average(e: Experiment, factor: int) -> Experiment:
    """A coarser copy for cheap cost ranking: inputs averaged over blocks of ``factor``
    samples, outputs sampled at the block starts."""
    N = (len(e.u) // factor) * factor
    u = e.step_u[:N].reshape(-1, factor, e.u.shape[1]).mean(axis=1)
    return Experiment(name=e.name, dt=e.dt * factor, u=u, y=e.y[:N:factor], x0=e.x0)


def _input_noise_meat(structure, prob, v, J, levels) -> np.ndarray:
    """The part of the scores' covariance that white noise on measured inputs causes.

    Output error simulates the model from the measured inputs, so noise e on input k at step
    j moves every later simulated sample: d x[t] = Ad^(t-1-j) Bd[:, k] e_j (t > j). The
    estimate moves by (J^T J)^+ J^T d r, and d r is slow (the model filters e), so the fit
    absorbs most of it into the parameters and the residuals, which the HAC meat reads, keep
    little: its share of the covariance must come from the model. With W_k = J^T H_k (H_k
    the map from e to the compared samples) the meat is sum_k sigma_k^2 W_k W_k^T per record
    (``levels``: per record, {input: sigma}). W_k is one backward recursion per record:
    Lambda[j] = G[j + 1] + Ad^T Lambda[j + 1], W_k[:, j] = Bd[:, k]^T Lambda[j], G[t] the
    rows of J at sample t placed on their states."""
    p_all = J.shape[1]
    meat = np.zeros((p_all, p_all))
    _, sims = prob._evaluate(v, derivatives=False)
    row = 0
    for e, (d, _), rows, sigma in zip(prob.exps, sims, prob.rows, levels, strict=True):
        N = len(e.u)
        G = np.zeros((N, prob.n, p_all))
        for i, rr in zip(prob.out_idx, rows, strict=True):
            idx = np.arange(N) if rr is None else rr
            G[idx, i, :] = J[row : row + len(idx)]
            row += len(idx)
        if not sigma:
            continue
        Lam = np.zeros((N, prob.n, p_all))
        AdT = d.Ad.T
        for j in range(N - 2, -1, -1):
            Lam[j] = G[j + 1] + AdT @ Lam[j + 1]
        for name, s_k in sigma.items():
            W = np.einsum("n,jnp->pj", d.Bd[:, structure.inputs.index(name)], Lam)
            meat += s_k**2 * (W @ W.T)
    return meat


def _noise_energy(structure, prob, theta, levels) -> float:
    """sum over records and noisy inputs k of sigma_k^2 ||H_k(theta)||_F^2: the summed
    squares, over the compared samples, of the simulated outputs' response to the white
    noise on input k (eq. 15's ZOH model), i.e. sum over outputs i and lags l of
    sigma_k^2 h_ik(l)^2 times the number of compared samples t > l, with the impulse
    response h(l) = Ad^l Bd (:func:`railtherm.estimation.models.free_response_head`, one
    discretisation per step length)."""
    total, impulse = 0.0, {}
    for e, rows, sigma in zip(prob.exps, prob.rows, levels, strict=True):
        if not sigma:
            continue
        N = len(e.u)
        if (e.dt, N) not in impulse:
            d = models.discretize(structure, theta, e.dt, hold=e.hold)
            impulse[e.dt, N] = models.free_response_head(d, N - 1) @ d.Bd  # (lags, n, m)
        H = impulse[e.dt, N]
        lags = np.arange(len(H))
        for i, rr in zip(prob.out_idx, rows, strict=True):
            later = N - 1 - lags if rr is None else len(rr) - np.searchsorted(rr, lags, "right")
            for name, s_k in sigma.items():
                total += s_k**2 * float(later @ H[:, i, structure.inputs.index(name)] ** 2)
    return total


def _input_noise_bias(structure, prob, v, Vt, inv_s, levels) -> np.ndarray:
    """The step that removes the bias white noise on the measured inputs gives the estimate.

    Output error minimises V = ||r||^2 with r simulated from the noisy inputs; noise e adds
    H_theta e to r, so E V = V_0 + sum_k sigma_k^2 ||H_k(theta)||_F^2 (the noise is
    independent of the true inputs and of the output noise), and the model that minimises V
    is biased towards small gains H (for the air node: a larger C). The compensated
    criterion V - sum_k sigma_k^2 ||H_k||^2 (bias-compensated least squares, as for
    errors-in-variables) is minimised from the estimate by one Gauss-Newton step:
    dv = (J^T J)^+ grad E / 2, E = :func:`_noise_energy`, its gradient in log theta by
    central differences (the initial states do not enter H)."""
    th = prob.theta(v)
    gradient = np.zeros(Vt.shape[1])
    h = 1e-4
    for j, p in enumerate(prob.free):
        up, down = (
            _noise_energy(structure, prob, {**th, p: th[p] * math.exp(sign * h)}, levels)
            for sign in (1.0, -1.0)
        )
        gradient[j] = (up - down) / (2.0 * h)
    return 0.5 * (Vt.T @ (inv_s**2 * (Vt @ gradient)))


# ----------------------------------------------------------------------------------------------
# fit


@single_threaded_blas
def fit(structure: Structure, experiments: Sequence[Experiment], **options: Any) -> FitResult:
    """Simulation-error PEM (eqs. 17-18, K = 0) of ``structure`` to ``experiments`` jointly:
    :func:`fit_with_density`'s estimate, whose options it takes."""
    return fit_with_density(structure, experiments, **options)[0]


def fit_with_density(
    structure: Structure,
    experiments: Sequence[Experiment],
    *,
    fixed: Mapping[str, float] | None = None,
    initial: Mapping[str, float] | None = None,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    outputs: Sequence[str] | None = None,
    x0: str = "measured",
    covariance: str = "hac",
    start: str = "auto",
    max_nfev: int | None = None,
    input_noise: Mapping[str, float | Sequence[float]] | None = None,
    compiled: bool = False,
    priors: Mapping[str, Prior] | None = None,
    prior_terms: Sequence[LinearT] = (),
) -> tuple[FitResult, leastsquares_map.Density]:
    """The fit and the posterior's density at it
    (:class:`railtherm.estimation.leastsquares_map.Density`): simulation-error PEM
    (eqs. 17-18, K = 0) of ``structure`` to ``experiments`` jointly.

    fixed: {param: value} held (two-stage: {"kA": k A}); initial: start values of free
    parameters (default: the paper's, ``structure.initial``); bounds: {param: (lo, hi)} in SI
    units (default ``structure.bounds``); outputs: state names compared (default: every state
    with a measurement); x0: "measured" | "estimated"; covariance: "hac" | "iid";
    start: "initial" | "auto"; input_noise: {input name (``structure.inputs``): the standard
    deviation of its white measurement noise, one number or one per experiment}, carried
    into the covariance (:func:`_input_noise_meat`) and removed from the estimate's bias
    (:func:`_input_noise_bias`). compiled: rank the automatic start's grid by the compiled
    simulation of :mod:`railtherm.estimation.loops` (numba, whose import a fit by output error
    alone need not pay; the Kalman fit, which loads it anyway, asks for it); the same costs.
    priors: {free parameter: :class:`railtherm.estimation.priors.Prior`}: the maximum a
    posteriori estimate (:mod:`railtherm.estimation.leastsquares_map`) from the
    least-squares optimum; without priors the least-squares (maximum-likelihood) estimate.
    prior_terms: joint prior terms on the log parameters (a class reference model's).
    """
    fixed = {p: float(v) for p, v in (fixed or {}).items()}
    experiments = list(experiments)
    _check_arguments(structure, experiments, fixed, x0, covariance, start)
    one_hold(experiments)
    noisy = noise_levels(structure, input_noise or {}, experiments)
    _check_input_columns(structure, experiments)
    free = tuple(p for p in structure.parameters if p not in fixed)
    init = dict(structure.initial)
    init.update({p: float(v) for p, v in (initial or {}).items() if p in structure.parameters})
    given = {p: (float(b[0]), float(b[1])) for p, b in (bounds or {}).items()}
    bnds = bounded({**structure.bounds, **given}, priors)  # a uniform prior is a bound
    lb = np.array([math.log(bnds[p][0]) if bnds[p][0] > 0 else -np.inf for p in free])
    ub = np.array([math.log(bnds[p][1]) if np.isfinite(bnds[p][1]) else np.inf for p in free])
    prior = LogPrior(free, priors or {}, prior_terms)
    outputs = compared_outputs(structure, experiments, outputs)
    out_idx = [structure.states.index(s) for s in outputs]
    prob = _Problem(structure, experiments, fixed, free, out_idx, x0, compiled)
    if prob.m <= len(free) + prob.n_x0:
        raise ValueError(f"{prob.m} compared samples cannot determine the unknowns")

    span = ub - lb
    margin = np.where(np.isfinite(span), 1e-6 * span, 0.0)

    def clip(v: np.ndarray) -> np.ndarray:
        """v moved into the bounds: the log parameters just inside, the initial states in."""
        w = np.clip(v[: len(free)], lb + margin, ub - margin)
        return np.concatenate([w, np.clip(v[len(free) :], prob.x0_lo, prob.x0_hi)])

    def pack(theta_free: Mapping[str, float]) -> np.ndarray:
        w = np.array([math.log(theta_free[p]) for p in free])
        return clip(np.concatenate([w, *prob.x0_guess]) if prob.n_x0 else w)

    candidates = {"initial": pack(init)}
    if start == "auto" and free:
        ee = equation_error_start(structure, experiments, fixed, init, (lb, ub), free)
        if ee is not None:
            candidates["equation_error"] = pack(ee)
        else:
            grid = _scale_aware_start(structure, experiments, fixed, free, init, pack, clip, prob)
            if grid is not None:
                candidates["grid"] = grid
    # the last candidate (the equation-error or grid start, when there is one) is the
    # likeliest winner: prob.cost keeps its evaluation for the solver's first step
    last = list(candidates)[-1]
    costs = {
        name: (prob.cost(v) if name == last else prob.cost_only(v))
        for name, v in candidates.items()
    }
    start_used = min(costs, key=lambda k: costs[k] if np.isfinite(costs[k]) else np.inf)
    v0 = candidates[start_used]
    if not math.isfinite(costs[start_used]):
        raise ValueError(
            f"the model cannot be simulated from any start ({', '.join(costs)}): check the "
            "initial values, bounds and inputs"
        )

    lo = np.concatenate([lb, prob.x0_lo])
    hi = np.concatenate([ub, prob.x0_hi])
    posterior = None
    if prob.P + prob.n_x0 == 0:  # every parameter and initial state given: evaluate only
        sol = SimpleNamespace(
            x=v0, fun=prob.residuals(v0), success=True, status=1, nfev=1, njev=0,
            active_mask=np.zeros(0, int),
            message="nothing to estimate: every parameter and initial state is given",
        )  # fmt: skip
    else:
        sol = _minimise(prob, v0, lo, hi, max_nfev)
    if prior and prob.P + prob.n_x0:
        posterior = (prior, _likelihood_weight(prob, sol, lo, hi, covariance))
        sol = leastsquares_map.search(prob.residuals, prob.jacobian, sol, *posterior, lo, hi)
    v = sol.x
    r = prob.residuals(v)
    J = prob.jacobian(v) if len(v) else np.zeros((prob.m, 0))  # cached: the solver's last
    result = _result(
        structure, prob, sol, v, r, J, covariance, start_used, costs, outputs, bnds, noisy,
        (lo, hi), posterior,
    )  # fmt: skip
    names = [*free, *(f"x0_{s}[{e.name}]" for e, f in zip(experiments, prob.x0_free, strict=True)
                      for s in (structure.states[i] for i in f))]  # fmt: skip
    return result, leastsquares_map.Density(
        prior, tuple(names), len(free), lo, hi, np.array(v, dtype=float),
        residuals=prob.residuals, jacobian=prob.jacobian, weight=result.samples_weight,
    )  # fmt: skip


def _likelihood_weight(prob, sol, lo, hi, covariance: str) -> float:
    """How many independent samples the simulation error's residuals count as for a MAP
    estimate (:func:`railtherm.estimation.leastsquares_map.search`): m / tau at the
    least-squares optimum (:func:`_tau`; m with the iid covariance), so that the records
    weigh against the prior as much as their intervals say they inform."""
    if covariance != "hac":
        return float(prob.m)
    v = np.clip(sol.x, lo, hi)
    r, J = prob.residuals(v), prob.jacobian(v)
    _, Vt, _, inv_s, _ = _singular(J, prob.P)
    cov_hac = hac.sandwich(Vt, inv_s, _hac_meat(prob, r, J)[0])
    cov_iid = float(r @ r) / max(prob.m - J.shape[1], 1) * ((Vt.T * inv_s**2) @ Vt)
    return prob.m / _tau(cov_hac, cov_iid)


def _tau(cov_hac: np.ndarray, cov_iid: np.ndarray) -> float:
    """The mean ratio of the HAC to the iid variance of the unknowns (at least 1): how many
    samples of coloured residuals count as one independent one."""
    var_hac, var_iid = np.diag(cov_hac), np.diag(cov_iid)
    ok = (var_iid > 0) & np.isfinite(var_hac) & (var_hac > 0)
    return max(1.0, float(np.mean(var_hac[ok] / var_iid[ok]))) if ok.any() else 1.0


def _check_arguments(structure, experiments, fixed, x0: str, covariance: str, start: str) -> None:
    """:func:`fit`'s arguments: fixed parameters of the structure, the options' values, at
    least one experiment."""
    unknown = [p for p in fixed if p not in structure.parameters]
    if unknown:
        raise ValueError(f"fixed parameters {unknown} not in {structure.parameters}")
    if x0 not in ("measured", "estimated"):
        raise ValueError(f"x0 must be 'measured' or 'estimated', got {x0!r}")
    if covariance not in ("hac", "iid"):
        raise ValueError(f"covariance must be 'hac' or 'iid', got {covariance!r}")
    if start not in ("initial", "auto"):
        raise ValueError(f"start must be 'initial' or 'auto', got {start!r}")
    if not experiments:
        raise ValueError("fit needs at least one experiment")


def _check_input_columns(structure, experiments) -> None:
    """Each experiment's u has a column per input of the structure (:func:`fit`)."""
    m_in = len(structure.inputs)
    wrong = [f"{e.name!r} ({e.u.shape[1]})" for e in experiments if e.u.shape[1] != m_in]
    if wrong:
        raise ValueError(
            f"structure {structure.name!r} has {m_in} inputs {structure.inputs}, but the u of "
            f"experiments {', '.join(wrong)} has a different number of columns"
        )


def _minimise(prob, v0: np.ndarray, lo: np.ndarray, hi: np.ndarray, max_nfev: int | None):
    """The least-squares solve of :func:`fit` from ``v0`` within [lo, hi]."""
    # Levenberg-Marquardt without bounds first: an optimum strictly inside the bounds (of the
    # parameters and of the estimated initial states) is a local optimum of the bounded
    # problem too. Otherwise (the search left the box or failed) scipy's bounded trust-region
    # reflective solve from the same start; its subproblem uses the SVD of J for small
    # problems and LSMR for large ones, where the SVD of the tall Jacobian dominates the cost.
    tr = {"tr_solver": "lsmr"} if prob.m * (prob.P + prob.n_x0) > _LSMR_ABOVE else {}
    sol = solver.levenberg_marquardt(prob.residuals, prob.jacobian, v0, max_nfev)
    inside = np.all(sol.x > lo) and np.all(sol.x < hi)
    if not (sol.success and inside and np.all(np.isfinite(sol.fun))):
        first = sol
        from scipy.optimize import least_squares  # on first use: a job's start-up

        sol = least_squares(
            prob.residuals,
            v0,
            jac=prob.jacobian,
            bounds=(lo, hi),
            method="trf",
            x_scale=1.0,
            max_nfev=max_nfev,
            **tr,
        )
        sol.nfev += first.nfev
        sol.njev = (sol.njev or 0) + (first.njev or 0)
    return sol


def _coarse_problem(prob: _Problem, samples: int) -> _Problem:
    """``prob`` on block-averaged copies of its experiments (at most about ``samples``
    samples each; :func:`_block_average`), with the same initial states and their bounds."""
    N = max(len(e.u) for e in prob.exps)
    factor = max(1, N // samples)
    if factor == 1:
        return prob
    coarse = [_block_average(e, factor) for e in prob.exps]
    cprob = _Problem(prob.s, coarse, prob.fixed, prob.free, prob.out_idx, "measured", prob.compiled)
    cprob.x0_base, cprob.x0_free, cprob.n_x0 = prob.x0_base, prob.x0_free, prob.n_x0
    cprob.x0_lo, cprob.x0_hi = prob.x0_lo, prob.x0_hi
    return cprob


def _scale_aware_start(
    structure: Structure,
    experiments: Sequence[Experiment],
    fixed: Mapping[str, float],
    free: tuple[str, ...],
    init: Mapping[str, float],
    pack,
    clip,
    prob: _Problem,
) -> np.ndarray | None:
    """The automatic start when not every state is measured (no equation-error start).

    Centre, from the data alone: every free conductance equal and every free capacity
    equal. The overall kA (:func:`railtherm.estimation.models.steady_state_kA`) is kA_ref, that of
    the heat balance (:func:`heat_balance_kA`) when the free conductances set it (doubling them
    doubles it), else that of the initial values with the fixed ones (the static kA of the
    two-stage method), which the free conductances then equal; the capacities share C_bar, the
    equation-error fit of eq. 9 with kA_ref (:func:`lumped_capacity`). Any other parameter
    (an aperture) keeps its initial value.

    Grid around the centre: every free capacity and every free conductance times each of
    START_FACTORS (decades both ways: the ratios of the capacities and of the conductances
    are not known at all); when the free conductances set the overall kA, one of them is not
    gridded (its ratio to the others is) and all are rescaled together to kA_ref times each
    of KA_FACTORS (the heat balance is right to a factor of a few). The grid is ranked by the
    simulation-error cost on a block-averaged copy of the data (at most RANK_SAMPLES samples
    per record), each point with its best initial states (:meth:`_Problem.cost_x0_projected`);
    the START_KEEP best that lie at least two grid steps apart are refined by
    Levenberg-Marquardt on a finer copy (COARSE_SAMPLES), and the refined point with the
    lowest cost on the full data is returned (None without a finite centre)."""
    conductances = [p for p in structure.conductances if p in free]
    capacities = [p for p in structure.capacities if p in free]
    if not (conductances or capacities):
        return None
    centre = {p: float(init[p]) for p in free if p not in conductances + capacities}
    unit = {**fixed, **centre, **dict.fromkeys(conductances + capacities, 1.0)}
    kA_unit = models.steady_state_kA(structure, unit)
    doubled = {**unit, **dict.fromkeys(conductances, 2.0)}
    movable = bool(conductances) and math.isclose(
        models.steady_state_kA(structure, doubled), 2.0 * kA_unit, rel_tol=1e-9
    )
    initial = {**init, **fixed}
    if movable:
        kA_ref = heat_balance_kA(experiments)
        if not math.isfinite(kA_ref):  # no heated record: the initial values' kA
            kA_ref = models.steady_state_kA(structure, initial)
        g = kA_ref / kA_unit
    else:  # the fixed parameters set it, or help to: two-stage, the static kA
        kA_ref = models.steady_state_kA(structure, initial)
        g = kA_ref
    C_bar = lumped_capacity(experiments, kA_ref)
    if not math.isfinite(C_bar):  # the initial values' time constant C_bar / kA
        C_initial = sum(initial[p] for p in structure.capacities)
        C_bar = kA_ref * C_initial / models.steady_state_kA(structure, initial)
    if not (math.isfinite(g) and g > 0 and math.isfinite(C_bar) and C_bar > 0):
        return None
    centre |= dict.fromkeys(conductances, g)
    centre |= dict.fromkeys(capacities, C_bar / len(structure.capacities))

    gridded = capacities + (conductances[1:] if movable else conductances)
    axes = [START_FACTORS] * len(gridded) + ([KA_FACTORS] if movable else [])
    combos = np.array(np.meshgrid(*axes, indexing="ij")).reshape(len(axes), -1).T
    rank = _coarse_problem(prob, RANK_SAMPLES)
    ranked, seen = [], set()
    for combo in combos:
        th = centre | {p: centre[p] * f for p, f in zip(gridded, combo, strict=False)}
        if movable:
            kA_th = models.steady_state_kA(structure, {**fixed, **th})
            if not math.isfinite(kA_th):
                continue
            th |= {p: th[p] * kA_ref * combo[-1] / kA_th for p in conductances}
        v = pack(th)
        key = tuple(np.round(v[: len(free)], 6))
        if key not in seen:
            seen.add(key)
            ranked.append(rank.cost_x0_projected(v))
    ranked = sorted(((c, v) for c, v in ranked if math.isfinite(c)), key=lambda cv: cv[0])
    kept: list[np.ndarray] = []
    apart = 1.5 * math.log(10.0)  # two grid steps in some parameter
    for _, v in ranked:
        if all(np.abs(v[: len(free)] - k[: len(free)]).max() > apart for k in kept):
            kept.append(v)
        if len(kept) == START_KEEP:
            break
    refine = _coarse_problem(prob, COARSE_SAMPLES)
    best, best_cost = None, math.inf
    for v in kept:
        with np.errstate(over="ignore", invalid="ignore"):
            sol = solver.levenberg_marquardt(refine.residuals, refine.jacobian, v, 30 * len(v))
        w = clip(sol.x) if np.all(np.isfinite(sol.x)) else v
        c = prob.cost_only(w)
        if c < best_cost:
            best, best_cost = w, c
    return best


def _result(
    structure,
    prob,
    sol,
    v,
    r,
    J,
    covariance,
    start_used,
    costs,
    outputs,
    bnds,
    noisy,
    box,
    posterior=None,
):
    """The :class:`FitResult` at ``v``. ``posterior``: (the log-prior, the likelihood's
    weight) of a MAP estimate (:func:`railtherm.estimation.leastsquares_map.search`), whose
    covariance is the
    estimator's (HAC or iid) with the prior's curvature added to its information (the
    Laplace approximation of the posterior); a direction neither the data nor a prior
    determine keeps an infinite variance."""
    P, m = prob.P, prob.m
    p_all = J.shape[1]
    ssr = float(r @ r)
    s, Vt, null, inv_s, cond = _singular(J, P)
    bandwidths, capped = [], []
    s2 = ssr / max(m - p_all, 1)
    cov_iid = s2 * ((Vt.T * inv_s**2) @ Vt)  # s^2 (J^T J)^+
    cov, tau = cov_iid, 1.0
    if covariance != "iid":
        meat, bandwidths, capped = _hac_meat(prob, r, J)
        cov = hac.sandwich(Vt, inv_s, meat)
        tau = _tau(cov, cov_iid)
    input_sd = [dict(level) for level in noisy] if any(noisy) else []
    if input_sd:
        cov = cov + hac.sandwich(Vt, inv_s, _input_noise_meat(structure, prob, v, J, noisy))
        step = _input_noise_bias(structure, prob, v, Vt, inv_s, noisy)
        moved = v + step
        if np.all(np.isfinite(step)) and np.all(moved > box[0]) and np.all(moved < box[1]):
            v = moved
            r = prob.residuals(v)
            ssr = float(r @ r)
    if posterior is not None:
        cov, null, Vt = leastsquares_map.laplace_covariance(cov, null, Vt, posterior[0], v)
    var = np.diag(cov)[:P].copy()
    # directions the data do not determine: infinite variance for the parameters on them
    if null.any():
        load = np.abs(Vt[null][:, :P]).max(axis=0)
        var[load > 1e-8] = np.inf
    th = prob.theta(v)
    free = prob.free
    # a zero or undefined variance where the residuals are not zero is no information about
    # the parameter but a breakdown of the estimator: the parameter is not identified
    degenerate = [
        p for i, p in enumerate(free) if ssr > 0 and not (var[i] > 0) and not np.isinf(var[i])
    ]
    var[[free.index(p) for p in degenerate]] = np.inf
    sd = np.sqrt(np.maximum(var, 0.0))
    corr, ci, sd_log = _intervals(cov, sd, th, free)
    flags = fit_flags(sol, v, th, free, ci, corr, cond, bnds)
    flags += x0_flags(prob, sol, v)
    flags += _covariance_flags(capped, degenerate, covariance, free)
    simulated, residuals = _simulated(prob, v)
    x0s = prob.x0s(v)
    return FitResult(
        structure=structure.name,
        theta={p: float(th[p]) for p in structure.parameters},
        free=free,
        fixed=dict(prob.fixed),
        ci95=ci,
        sd_log=sd_log,
        correlation=corr,
        cond=cond,
        flags=flags,
        cost=ssr,
        n_obs=m,
        n_unknowns=p_all,
        nfev=int(sol.nfev),
        njev=int(sol.njev or 0),
        success=bool(sol.success),
        message=str(sol.message),
        start_used=start_used,
        start_costs=costs,
        covariance=covariance,
        outputs=tuple(outputs),
        names=[e.name for e in prob.exps],
        x0=x0s,
        x0_estimated=[tuple(structure.states[j] for j in fr) for fr in prob.x0_free],
        simulated=simulated,
        residuals=residuals,
        dt=[float(e.dt) for e in prob.exps],
        states=tuple(structure.states),
        bandwidths=bandwidths,
        input_noise_sd=input_sd,
        samples_weight=m / tau,
        priors={} if posterior is None else posterior[0].to_dict(),
        log_prior=None if posterior is None else float(posterior[0].evaluate(v)[0]),
    )


def _singular(J: np.ndarray, P: int):
    """The singular values s and right vectors Vt of J, the null directions (s below
    NULL_REL of the largest), the pseudo-inverse's 1/s (0 on them) and the condition of the
    parameter block (its first P columns) (:func:`_result`)."""
    p_all = J.shape[1]
    if p_all:
        s, Vt = solver.svd_tall(J)
    else:  # nothing estimated
        s, Vt = np.zeros(0), np.zeros((0, 0))
    smax = float(s[0]) if s.size else 0.0
    null = s <= NULL_REL * smax if smax > 0 else np.ones_like(s, dtype=bool)
    # condition of the parameter block only (log-parameter columns)
    if P and p_all == P:
        cond = float(s[0] / s[-1]) if s[-1] > 0 else math.inf
    elif P:
        sp = solver.svd_tall(J[:, :P])[0]
        cond = float(sp[0] / sp[-1]) if sp[-1] > 0 else math.inf
    else:
        cond = 1.0
    with np.errstate(divide="ignore"):
        inv_s = np.where(null, 0.0, 1.0 / np.where(null, 1.0, s))
    return s, Vt, null, inv_s, cond


def _hac_meat(prob, r: np.ndarray, J: np.ndarray):
    """The HAC meat of the sandwich (Bartlett kernel, Andrews' bandwidth per record), the
    bandwidths and the records whose bandwidth reached half their rows (:func:`_result`)."""
    p_all = J.shape[1]
    bandwidths, capped = [], []
    meat = np.zeros((p_all, p_all))
    JT = np.ascontiguousarray(J.T)  # no copy: J is the transpose of a C-ordered array
    row = 0
    for e, rows in zip(prob.exps, prob.rows, strict=True):
        for rr in rows:
            N_i = len(e.u) if rr is None else len(rr)
            ri, JTi = r[row : row + N_i], JT[:, row : row + N_i]
            if rr is None:
                gT, res_full = JTi * ri, ri
            else:
                gT = np.zeros((p_all, len(e.u)))
                gT[:, rr] = JTi * ri
                res_full = np.zeros(len(e.u))
                res_full[rr] = ri
            L = hac.andrews_bandwidth(res_full)
            bandwidths.append(L)
            if len(res_full) >= 8 and L >= len(res_full) // 2:
                capped.append(f"{e.name} (L = {L} of {len(res_full)} rows)")
            meat += hac.bartlett(gT, L)
            row += N_i
    return meat, bandwidths, capped


def _intervals(cov: np.ndarray, sd: np.ndarray, th, free):
    """The correlation of the free log parameters (NaN where a variance is infinite), their
    95 % intervals and sd in log units (:func:`_result`)."""
    P = len(free)
    with np.errstate(invalid="ignore", divide="ignore"):
        d = np.sqrt(np.maximum(np.diag(cov)[:P], 0.0))
        corr = cov[:P, :P] / np.outer(d, d)
    corr[~np.isfinite(corr)] = np.nan
    for i in range(P):
        if np.isfinite(sd[i]) and sd[i] > 0:
            corr[i, i] = 1.0
        if not np.isfinite(sd[i]):
            corr[i, :] = np.nan
            corr[:, i] = np.nan
    ci = {}
    sd_log = {}
    for i, p in enumerate(free):
        lv = math.log(th[p])
        with np.errstate(over="ignore"):
            ci[p] = (float(np.exp(lv - Z95 * sd[i])), float(np.exp(lv + Z95 * sd[i])))
        sd_log[p] = float(sd[i])
    return corr, ci, sd_log


def _covariance_flags(capped, degenerate, covariance: str, free) -> list[Flag]:
    """The flags of a covariance that rests on a capped HAC bandwidth or gives no positive
    variance (:func:`_result`)."""
    flags = []
    if capped:
        flags.append(
            Flag(
                "hac_bandwidth_capped",
                tuple(free),
                "the residuals are so persistent that the HAC bandwidth reached half the "
                f"window in {', '.join(dict.fromkeys(capped))}: the intervals rest on a few "
                "effective samples and may understate the uncertainty (a slow dynamic the "
                "model lacks?)",
            )
        )
    if degenerate:
        flags.append(
            Flag(
                "degenerate_covariance",
                tuple(degenerate),
                f"the {covariance} covariance gives no positive variance for "
                f"{', '.join(degenerate)}: the estimator breaks down on these data, so the "
                "parameters are taken as not identified",
            )
        )
    return flags


def _simulated(prob, v: np.ndarray):
    """Each record's simulated states and residuals at ``v`` (:func:`_result`)."""
    sims = prob._evaluate(v, derivatives=True)[1]
    simulated, residuals = [], []
    for e, (_, xT) in zip(prob.exps, sims, strict=True):
        x = xT.T.copy()
        simulated.append(x)
        res = np.full_like(x, np.nan)
        for i in prob.out_idx:
            res[:, i] = e.y[:, i] - x[:, i]
        residuals.append(res)
    return simulated, residuals
