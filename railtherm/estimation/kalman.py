"""Stochastic grey-box estimator: the prediction error method with a Kalman gain (paper
eqs. 15-18 with K estimated through a noise model, not fixed to 0), by maximum likelihood.

Model (continuous-discrete, any :class:`railtherm.estimation.models.Structure`)::

    dx = (A(theta) x + B(theta) u) dt + Sigma dw,   Sigma = diag(sigma_i)   (one per state)
    y_k = C x_k + v_k,                              v_k ~ N(0, S), S = diag(s_j)

C selects the compared outputs (states). The input is held over each step (zero-order hold,
as :mod:`railtherm.estimation.pem`) or linear between samples (first-order hold: u_k below is then
[u_k; u_{k+1}], :func:`railtherm.estimation.models.forcing`), so the exact discrete model is
x_{k+1} = Ad x_k + Bd u_k + w_k with (Ad, Bd) of :func:`railtherm.estimation.models.discretize` and
w_k ~ N(0, Qd), Qd by Van Loan's method (:func:`railtherm.estimation.models.discretize_noise`).

Likelihood: the Kalman filter's innovations eps_k = y_k - C x_{k|k-1} and their covariances
R_k = C P_{k|k-1} C^T + S give the exact negative log-likelihood

    NLL = 1/2 sum_k (log det R_k + eps_k^T R_k^-1 eps_k + n_k log 2 pi)

(eq. 17's criterion generalised: eq. 18's prediction errors are the innovations). Rows, or
single outputs of a row, without a measurement skip the update.

The fits run the filter row by row in compiled code (:mod:`railtherm.estimation.loops`, numba):
the time-varying recursion with its forward sensitivities, whose gain is held once a prediction
leaves P and its derivatives unchanged (relative FREEZE_TOL) until the measurement pattern
changes. ``COMPILED = False`` runs the numpy implementation instead, which the tests check the
compiled one against: there, once the predicted covariance P_k has reached the solution P of
the discrete algebraic Riccati equation of the row's measurement pattern
(``scipy.linalg.solve_discrete_are``; relative STEADY_TOL), the filter is the time-invariant
recursion x_{k+1} = F x_k + Bd u_k + L y_k (F = Ad - L C, L = Ad P C^T R^-1), run without a
Python loop by the modal ``lfilter`` machinery of :mod:`railtherm.estimation.models`.
An estimated initial state starts with the stationary prior covariance P_0 = P (no transient at
all); a measured one with the measurement variances. In the numpy implementation, a run that
starts off the stationary covariance (a measured initial state, the first rows after a gap) is
filtered with the stationary gain too, and its NLL corrected exactly for the difference Delta
of its prior by de Jong's augmentation of the initial state: the stationary innovations respond
to the first state's deviation as G_j = C F^j, so with X_N = sum_j G_j^T R^-1 G_j (a Lyapunov
equation) and s = sum_j G_j^T R^-1 eps_j,

    NLL = NLL_stationary + 1/2 log det(I + X_N Delta) - 1/2 s^T Delta (I + X_N Delta)^-1 s,

with its exact gradient from the same adjoint sums (:func:`_prior_correction`). This holds for
the record's last run whatever its length, and for an earlier run whose transient dies out
within it (the next run then starts as the time-varying filter's would).

Gradient: exact, by forward sensitivities of the filter recursions (the derivatives of Ad, Bd
from the block exponential of :func:`railtherm.estimation.models.discretize`, of Qd from Van Loan's
exponential, of the stationary P from the Lyapunov equation the differentiated Riccati
equation is, ``scipy.linalg.solve_discrete_lyapunov``), in log parameters. The same
sensitivities give the Fisher information, the Hessian of a trust-region scoring step
(``scipy.optimize.minimize``, trust-exact); L-BFGS-B finishes with bounds when the optimum
lies on one. Covariance: the inverse of the observed information (forward differences of the
analytic gradient) at the optimum; 95 % intervals in log parameters as in
:mod:`railtherm.estimation.pem`,
whose flags are reused.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from types import SimpleNamespace
from typing import Any, ClassVar

import numpy as np
from scipy.linalg import cho_factor, cho_solve, solve_discrete_are, solve_discrete_lyapunov
from scipy.optimize import minimize

from railtherm.estimation import common, models, pem
from railtherm.estimation.common import Experiment
from railtherm.estimation.estimate import Estimate, Identification
from railtherm.estimation.models import Structure

__all__ = [
    "KalmanResult",
    "LOG_2PI",
    "fit",
    "negative_log_likelihood",
    "noise_names",
]

LOG_2PI = math.log(2.0 * math.pi)
SIGMA_BOUNDS = (1e-9, 1.0)  # K / sqrt(s): diffusion of a state (1 K/sqrt(s): 60 K per hour)
MEAS_VAR_BOUNDS = (1e-10, 1e4)  # K^2: measurement variance of an output
STEADY_TOL = 1e-10  # |P_k - P| / |P| below which the filter switches to the stationary gain
# the compiled filter holds its gain once |P_k+1 - P_k| <= FREEZE_TOL |P_k+1| (and so for dP)
FREEZE_TOL = 1e-13
COMPILED = True  # False: the numpy filter (module docstring), the reference of the tests
# a run that starts off the stationary covariance is done by the stationary filter with the
# exact correction for its prior (:func:`_prior_correction`) instead of row by row when it is
# the record's last run, or when its transient |F|^rows decays below this before a later run
JUMP_DECAY = 1e-18
PRIOR_CORRECTION = True  # False: every transient row by row (the reference the tests compare)
OFFSET_STEP = 1e-4  # K: central-difference step along an output offset
OFFSET_BOUNDS = (-5.0, 5.0)  # K: an output's constant offset
HESSIAN_STEP = 1e-5  # forward-difference step of the observed information (log units, K)
SIGMA_START = 0.1  # default start: sigma_i^2 dt = SIGMA_START^2 x the output-error variance
# a noise parameter this close (log) to its bound is held there for the covariance
_AT_BOUND_LOG = 1e-3
KKT_TOL = 1e-3  # NLL per log unit: an unknown held at a bound with a smaller pull inside stays
SNAP_LOG = math.log(1e4)  # a noise parameter within this (log) of its lower bound may snap to it


def noise_names(structure: Structure, outputs: Sequence[str]) -> tuple[str, ...]:
    """The names of the noise parameters: ``sigma_<state>`` (diffusion, K/sqrt(s)) for every
    state, then ``s_<output>`` (measurement variance, K^2) for every compared output. They
    may be given in ``fixed``, ``initial`` and ``bounds`` of :func:`fit` like the structure's
    parameters (a diffusion may be fixed at 0)."""
    return tuple(f"sigma_{s}" for s in structure.states) + tuple(f"s_{o}" for o in outputs)


# ----------------------------------------------------------------------------------------------
# the discrete system and its stationary filters


class NotEvaluable(ValueError):
    """The likelihood cannot be evaluated at the output-error optimum the Kalman fit starts
    from: the message names the fastest time constant of the model there against the step,
    the parameters that make it, and what to do."""

    def __init__(self, structure: Structure, theta: Mapping[str, float], dt: float):
        A, _ = structure.matrices(theta)
        rates = np.abs(np.linalg.eigvals(A))
        tau = 1.0 / float(rates.max()) if np.all(np.isfinite(rates)) and rates.max() > 0 else 0.0
        at_bound = [
            p
            for p in structure.parameters
            if p in theta
            and any(
                abs(math.log(float(theta[p]) / b)) < 1e-3
                for b in structure.bounds[p]
                if b > 0 and math.isfinite(b)
            )
        ]
        self.tau, self.dt, self.at_bound = tau, dt, at_bound
        where = f" ({', '.join(at_bound)} at a bound of the search)" if at_bound else ""
        super().__init__(
            f"the Kalman filter's likelihood of {structure.name} cannot be evaluated at the "
            f"output-error optimum it starts from: there the model's fastest time constant is "
            f"{tau:.3g} s against the {dt:g} s step{where}, where the discretised process "
            "noise overflows"
        )


class _Modes:
    """The recursion x[l+1] = F x[l] + w[l] in modal coordinates, F = V diag(lam) V^-1, with
    each complex-conjugate pair of modes run once (for a real forcing the pair's coordinates
    are conjugate, so x = sum over the kept modes of weight Re(v_i z_i), weight 2 for a pair):
    one ``scipy.signal.lfilter`` per kept mode for all channels. A Kalman predictor's F =
    Ad - L C often has a complex pair where Ad has none. When V is ill-conditioned or the
    eigenvalues are repeated, the complex Schur form of
    :func:`railtherm.estimation.models.modal_form`
    is used instead (every mode, complex, weight 1: x = Re(sum of Q_i z_i))."""

    def __init__(self, F: np.ndarray):
        F = np.atleast_2d(F)
        n = len(F)
        self.schur: models.Discretisation | None = None
        lam, V = np.linalg.eig(F)
        gap = np.abs(lam[:, None] - lam[None, :])[~np.eye(n, dtype=bool)]
        distinct = n == 1 or float(gap.min()) > 1e-9 * max(1.0, float(np.abs(lam).max()))
        Vinv = None
        if distinct:
            try:
                Vinv = np.linalg.inv(V)
            except np.linalg.LinAlgError:
                Vinv = None
        if Vinv is None or np.abs(V).sum(0).max() * np.abs(Vinv).sum(0).max() >= 1e8:
            self.schur = models.modal_form(F)
            return
        keep = [i for i in range(n) if np.imag(lam[i]) >= 0.0]
        real = np.imag(lam[keep]) == 0.0
        self.modes = [
            (
                (float(np.real(lam[i])), np.real(V[:, i]), np.real(Vinv[i]), 1.0)
                if r
                else (complex(lam[i]), V[:, i], Vinv[i], 2.0)
            )
            for i, r in zip(keep, real, strict=True)
        ]

    def run(self, H: np.ndarray, Z: np.ndarray, x0: np.ndarray) -> list[tuple]:
        """The modal coordinates of x[0] = x0 (n, C), x[l+1] = F x[l] + w[:, c, l] with the
        forcing w[:, c, l] = H[:, c, :] @ Z[:, l] (H: n x C x k, Z: k x L; Z's last column
        is not used): a list of (z (C, L), v (n,), weight) with x = sum weight Re(v z).
        Channels without forcing (the initial states' directions) are free responses
        z0 lam^l, taken as 0 once |lam|^l < models.FREE_RESPONSE_CUT: nothing is computed in
        subnormal floats (very slow)."""
        n, C, k = H.shape
        L = Z.shape[1]
        if self.schur is not None:
            d = self.schur
            Qinv = d.Qinv.astype(complex)
            w = (Qinv @ H.reshape(n, -1)).reshape(n * C, k) @ Z
            z = models.propagate(d, w.reshape(n, C, L), (Qinv @ x0).astype(complex))
            return [(z[i], d.Q[:, i].astype(complex), 1.0) for i in range(n)]
        forced = np.any(H != 0.0, axis=(0, 2))
        one = np.array([0.0, 1.0])
        out = []
        for lam, v, vinv, weight in self.modes:
            dtype = float if isinstance(lam, float) else complex
            z = np.zeros((C, L), dtype=dtype)
            z0 = vinv @ x0
            if forced.any():
                h = np.tensordot(vinv, H[:, forced], axes=(0, 0))  # (C_forced, k)
                if dtype is float:
                    f = h @ Z
                else:  # two real products: no complex copy of Z
                    f = np.empty((len(h), L), dtype=complex)
                    f.real = h.real @ Z
                    f.imag = h.imag @ Z
                z[forced] = models.lfilter(
                    one.astype(dtype), [1.0, -lam], f, axis=-1, zi=z0[forced][:, None]
                )[0]
            if not forced.all():
                r = abs(lam)
                if r >= 1.0:
                    cut = L
                elif r > 0.0:
                    cut = min(L, int(math.log(models.FREE_RESPONSE_CUT) / math.log(r)) + 1)
                else:
                    cut = 1
                z[~forced, :cut] = z0[~forced][:, None] * lam ** np.arange(cut)[None, :]
            out.append((z, v, weight))
        return out


def _states(modes: list[tuple], M: np.ndarray) -> np.ndarray:
    """M x (r, C, L) from the modal coordinates of :meth:`_Modes.run`."""
    out = None
    for z, v, weight in modes:
        g = weight * (M @ v)
        if np.isrealobj(z) and np.isrealobj(g):
            term = np.multiply.outer(g, z)
        else:
            term = np.multiply.outer(g.real, z.real) - np.multiply.outer(g.imag, z.imag)
        out = term if out is None else out + term
    return out


def _column(modes: list[tuple], col: int) -> np.ndarray:
    """x[:, :, col] (n, C) from the modal coordinates."""
    return sum(weight * np.real(np.multiply.outer(v, z[:, col])) for z, v, weight in modes)


@dataclass
class _Steady:
    """The stationary filter of one measurement pattern (outputs ``o``): P of the Riccati
    equation (predicted covariance), R, K (filter gain), L = Ad K, F = Ad - L C_o, and their
    derivatives along the global directions (leading axis)."""

    o: np.ndarray
    C: np.ndarray
    P: np.ndarray
    dP: np.ndarray
    R: np.ndarray
    dR: np.ndarray
    chol: tuple
    Rinv: np.ndarray
    logdet: float
    K: np.ndarray
    dK: np.ndarray
    L: np.ndarray
    dL: np.ndarray
    F: np.ndarray
    dF: np.ndarray
    modes: _Modes
    _modes_T: _Modes | None = None

    @property
    def modes_T(self) -> _Modes:
        """The modes of F^T (the adjoint recursion)."""
        if self._modes_T is None:
            self._modes_T = _Modes(self.F.T)
        return self._modes_T


def _lyapunov_stack(F: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """X_q = F X_q F^T + rhs_q for every q of the stack rhs (Q, n, n): with vec (row-major)
    one linear system (I - F kron F) vec X = vec rhs for all q at once, the direct method of
    ``scipy.linalg.solve_discrete_lyapunov`` factored once instead of once per q (a thermal
    network's few states: n^2 unknowns)."""
    n = F.shape[0]
    lhs = np.eye(n * n) - np.kron(F, F)
    return np.linalg.solve(lhs, rhs.reshape(len(rhs), n * n).T).T.reshape(rhs.shape)


class _System:
    """Ad, Bd, Qd, C, S of one step length and their derivatives along the global directions
    (log theta_free, log sigma_free, log s_free), with the stationary filters per pattern."""

    def __init__(self, Ad, Bd, Qd, C, S, dAd, dBd, dQd, dS, order: int):
        self.Ad, self.Bd, self.Qd, self.C, self.S = Ad, Bd, Qd, C, S
        self.dAd, self.dBd, self.dQd, self.dS = dAd, dBd, dQd, dS
        self.order = order
        self._steady: dict[int, _Steady | None] = {}

    def steady(self, code: int, o: np.ndarray) -> _Steady | None:
        if code not in self._steady:
            self._steady[code] = self._solve(o) if len(o) else None
        return self._steady[code]

    def _solve(self, o: np.ndarray) -> _Steady | None:
        Ad, C, Qd = self.Ad, self.C[o], self.Qd
        So = np.diag(self.S[o])
        try:
            with np.errstate(all="ignore"):
                P = solve_discrete_are(Ad.T, C.T, Qd, So)
        except (np.linalg.LinAlgError, ValueError):
            return None
        P = (P + P.T) / 2.0
        if not np.all(np.isfinite(P)):
            return None
        R = C @ P @ C.T + So
        try:
            chol = cho_factor(R)
        except np.linalg.LinAlgError:
            return None
        Rinv = cho_solve(chol, np.eye(len(o)))
        K = P @ C.T @ Rinv
        L = Ad @ K
        F = Ad - L @ C
        if np.max(np.abs(np.linalg.eigvals(F))) >= 1.0:
            return None  # no stabilising solution
        M = P - K @ R @ K.T
        Qg = len(self.dAd)
        dP = np.zeros((Qg,) + P.shape)
        if self.order >= 1 and Qg:
            rhs = self.dAd @ M @ Ad.T
            rhs = rhs + rhs.transpose(0, 2, 1) + self.dQd
            rhs = rhs + (L * self.dS[:, None, o]) @ L.T
            dP = _lyapunov_stack(F, rhs)
            dP = (dP + dP.transpose(0, 2, 1)) / 2.0
        dR = C @ dP @ C.T + _diag_stack(self.dS[:, o])
        dK = (dP @ C.T - K @ dR) @ Rinv
        dL = self.dAd @ K + Ad @ dK
        dF = self.dAd - dL @ C
        return _Steady(
            o=o,
            C=C,
            P=P,
            dP=dP,
            R=R,
            dR=dR,
            chol=chol,
            Rinv=Rinv,
            logdet=2.0 * float(np.log(np.diag(chol[0])).sum()),
            K=K,
            dK=dK,
            L=L,
            dL=dL,
            F=F,
            dF=dF,
            modes=_Modes(F),
        )


def _diag_stack(d: np.ndarray) -> np.ndarray:
    """(Q, k) -> (Q, k, k) diagonal matrices."""
    out = np.zeros(d.shape + (d.shape[-1],))
    idx = np.arange(d.shape[-1])
    out[:, idx, idx] = d
    return out


def _pad(a: np.ndarray, Q: int) -> np.ndarray:
    """Derivative array a (Qg, ...) padded with zeros to Q directions (the x0 directions)."""
    if len(a) == Q:
        return a
    return np.concatenate([a, np.zeros((Q - len(a),) + a.shape[1:])])


# ----------------------------------------------------------------------------------------------
# one experiment's data


@dataclass
class _Data:
    """An experiment's compared outputs (N x n_out, NaN = skipped), the rows its inputs drive
    the model by (``u``: :attr:`Experiment.forcing`, the hold's), the measurement pattern per
    row (bit j: output j measured) and the runs of equal patterns."""

    e: Experiment
    u: np.ndarray
    y: np.ndarray
    codes: np.ndarray
    runs: list[tuple[int, int, int]]
    prior_code: int
    x0_base: np.ndarray
    x0_free: list[int]
    x0_prior: list[tuple[int, int]]  # (state, output): measured initial state, variance s_j
    x0_range: tuple[float, float]


def _outputs_of(code: int, n_out: int) -> np.ndarray:
    return np.array([j for j in range(n_out) if code >> j & 1], dtype=int)


def _data(structure: Structure, e: Experiment, out_idx: Sequence[int], x0_mode: str) -> _Data:
    n = len(structure.states)
    if e.y.shape[1] != n:
        raise ValueError(
            f"experiment {e.name!r}: y has {e.y.shape[1]} columns, structure "
            f"{structure.name!r} has states {structure.states}"
        )
    y = e.y[:, list(out_idx)].copy()
    x0_prior: list[tuple[int, int]] = []
    first = np.array(e.y[0] if e.x0 is None else e.x0, dtype=float)
    if len(first) != n:
        raise ValueError(f"experiment {e.name!r}: x0 needs {n} values, got {first}")
    if x0_mode == "estimated":
        x0_free = list(range(n))
        base = np.zeros(n)
    else:
        x0_free = [int(i) for i in np.flatnonzero(~np.isfinite(first))]
        base = np.where(np.isfinite(first), first, 0.0)
        for j, i in enumerate(out_idx):
            if np.isfinite(first[i]):
                x0_prior.append((int(i), j))
                y[0, j] = np.nan  # the first measurement is the prior, not also a datum
    mask = np.isfinite(y)
    codes = (mask * (1 << np.arange(y.shape[1]))).sum(axis=1)
    edges = np.flatnonzero(np.diff(codes)) + 1
    starts = np.concatenate([[0], edges])
    ends = np.concatenate([edges, [len(y)]])
    runs = [(int(a), int(b), int(codes[a])) for a, b in zip(starts, ends, strict=True)]
    used = codes[codes > 0]
    prior_code = int(np.bincount(used).argmax()) if used.size else 0
    return _Data(
        e=e,
        u=np.ascontiguousarray(e.forcing),
        y=y,
        codes=codes,
        runs=runs,
        prior_code=prior_code,
        x0_base=base,
        x0_free=x0_free,
        x0_prior=x0_prior,
        x0_range=common.measured_range(e),
    )


# ----------------------------------------------------------------------------------------------
# the filter


@dataclass
class _Pass:
    """One filter pass over one experiment: NLL, its gradient and Fisher information along the
    pass's directions, and (when asked) the series."""

    nll: float
    grad: np.ndarray
    fisher: np.ndarray | None
    xp: np.ndarray | None = None  # x_{k|k-1}, N x n
    eps: np.ndarray | None = None  # innovations, N x n_out (NaN: not measured)
    rvar: np.ndarray | None = None  # diagonal of R_k, N x n_out (NaN: not measured)
    steady_from: list[int] = field(default_factory=list)  # rows where a stationary run began


def _filter(
    sysm: _System,
    d: _Data,
    x0: np.ndarray,
    dx0: np.ndarray,
    P0: np.ndarray,
    dP0: np.ndarray,
    order: int,
    steady: bool = True,
    series: bool = False,
) -> _Pass:
    """The Kalman filter (predictor form) over one experiment, with forward sensitivities along
    Q directions (order >= 1: gradient; order 2: also the Fisher information). dx0 (Q, n) and
    dP0 (Q, n, n): derivatives of the prior mean and covariance of x_0. The system's derivatives
    are zero along the directions beyond its own (an experiment's initial states).

    Per row: update with the measured outputs o (skipped when none), then predict,

        eps = y_o - C_o x,  R = C_o P C_o^T + S_o,  K = P C_o^T R^-1,
        x <- Ad (x + K eps) + Bd u,  P <- Ad (P - K R K^T) Ad^T + Qd,

    differentiated term by term. Where P has reached the stationary P of the run's pattern
    (``steady``, relative STEADY_TOL), the rest of the run is :func:`_steady_run`; where it has
    not, but the run is the last or long enough to forget its prior, too, with the exact
    correction for the prior (module docstring)."""
    y, u = d.y, d.u
    N, n_out = y.shape
    n = len(x0)
    Q = len(dx0)
    Ad, Bd, Qd, S, C = sysm.Ad, sysm.Bd, sysm.Qd, sysm.S, sysm.C
    dAd = dBd = dQd = dS = None
    if order >= 1:
        dAd, dBd, dQd, dS = (_pad(a, Q) for a in (sysm.dAd, sysm.dBd, sysm.dQd, sysm.dS))
    x, P = np.array(x0, dtype=float), np.array(P0, dtype=float)
    dx, dP = np.array(dx0, dtype=float), np.array(dP0, dtype=float)
    out = _Pass(nll=0.0, grad=np.zeros(Q), fisher=np.zeros((Q, Q)) if order >= 2 else None)
    if series:
        out.xp = np.empty((N, n))
        out.eps = np.full((N, n_out), np.nan)
        out.rvar = np.full((N, n_out), np.nan)
    nll = 0.0
    for k0, k1, code in d.runs:
        o = _outputs_of(code, n_out)
        st = sysm.steady(code, o) if steady else None
        if len(o):  # the run's measurement model
            Co, So, CoT = C[o], np.diag(S[o]), C[o].T
            dSo = _diag_stack(dS[:, o]) if order >= 1 else None
        k = k0
        while k < k1:
            steady_now = st is not None and float(np.abs(P - st.P).max()) <= STEADY_TOL * float(
                np.abs(st.P).max()
            )
            jump = (  # decided at the run's first row: later rows only shorten what is left
                k == k0
                and PRIOR_CORRECTION
                and st is not None
                and not steady_now
                and not series
                and k1 - k >= 2
                and (k1 == N or _decays(st, k1 - k))  # the last run, or the prior forgotten
            )
            if steady_now or jump:
                out.steady_from.append(k)
                prior = None
                if jump:  # the prior P's difference from the stationary one, corrected exactly
                    prior = (P - st.P, dP - _pad(st.dP, Q) if order >= 1 else None)
                nll_run, x, dx = _steady_run(
                    sysm, st, d, k, k1, x, dx, dBd, order, out, prior=prior
                )
                nll += nll_run
                P = st.P.copy()
                if order >= 1:
                    dP = _pad(st.dP, Q).copy()
                break
            if series:
                out.xp[k] = x
            if len(o):
                eps = y[k, o] - Co @ x
                PCt = P @ CoT
                R = Co @ PCt + So
                lam, V = np.linalg.eigh(R)  # one call: R^-1, log det R and R > 0
                if not lam[0] > 0.0:
                    raise np.linalg.LinAlgError("the innovation covariance is not positive")
                Rinv = (V / lam) @ V.T
                a = Rinv @ eps
                nll += 0.5 * (float(np.log(lam).sum()) + float(eps @ a) + len(o) * LOG_2PI)
                K = PCt @ Rinv
                KR = K @ R
                if series:
                    out.eps[k, o] = eps
                    out.rvar[k, o] = R.diagonal()
                if order >= 1:
                    dPCt = dP @ CoT  # (Q, n, no)
                    dR = Co @ dPCt + dSo  # (Q, no, no)
                    de = -dx @ CoT  # (Q, no)
                    # 1/2 tr(R^-1 dR) - 1/2 a^T dR a + de^T a, a = R^-1 eps
                    M = 0.5 * (Rinv - np.outer(a, a))
                    out.grad += dR.reshape(Q, -1) @ M.ravel() + de @ a
                    if order >= 2:
                        RdR = Rinv @ dR
                        out.fisher += de @ Rinv @ de.T + 0.5 * (
                            RdR.reshape(Q, -1) @ RdR.transpose(0, 2, 1).reshape(Q, -1).T
                        )
                    dK = (dPCt - K @ dR) @ Rinv  # (Q, n, no)
                    dx = dx + dK @ eps + de @ K.T
                    dKRK = dK @ KR.T
                    dP = dP - dKRK - dKRK.transpose(0, 2, 1) - K @ dR @ K.T
                x = x + K @ eps
                P = P - KR @ K.T
            if order >= 1:  # prediction, differentiated
                dx = dx @ Ad.T + dAd @ x + dBd @ u[k]
                APA = dAd @ P @ Ad.T
                dP = APA + APA.transpose(0, 2, 1) + Ad @ dP @ Ad.T + dQd
            x = Ad @ x + Bd @ u[k]
            P = Ad @ P @ Ad.T + Qd
            P = (P + P.T) / 2.0
            k += 1
    out.nll = nll
    return out


def _filter_rows(
    sysm: _System,
    d: _Data,
    x0: np.ndarray,
    dx0: np.ndarray,
    P0: np.ndarray,
    dP0: np.ndarray,
    order: int,
    steady: bool = True,
    series: bool = False,
) -> _Pass:
    """:func:`_filter` by the compiled row recursion of :mod:`railtherm.estimation.loops`."""
    from railtherm.estimation import loops

    y, u = d.y, d.u
    N, n_out = y.shape
    n = len(x0)
    Q = len(dx0)
    f8 = np.float64
    if order >= 1:
        dAd, dBd, dQd, dS = (
            np.ascontiguousarray(_pad(a, Q), dtype=f8)
            for a in (sysm.dAd, sysm.dBd, sysm.dQd, sysm.dS)
        )
    else:
        Q = 0
        dAd, dQd = np.zeros((0, n, n)), np.zeros((0, n, n))
        dBd, dS = np.zeros((0,) + sysm.Bd.shape), np.zeros((0, n_out))
    rows = N if series else 0
    xp, eps, rvar = (
        np.empty((rows, n)),
        np.full((rows, n_out), np.nan),
        np.full((rows, n_out), np.nan),
    )
    steady_from = np.zeros(N, dtype=np.int64)
    status, nll, grad, fisher, count = loops.kalman_rows(
        np.ascontiguousarray(sysm.Ad, dtype=f8),
        np.ascontiguousarray(sysm.Bd, dtype=f8),
        np.ascontiguousarray(sysm.Qd, dtype=f8),
        np.ascontiguousarray(sysm.C, dtype=f8),
        np.ascontiguousarray(sysm.S, dtype=f8),
        dAd,
        dBd,
        dQd,
        dS,
        np.ascontiguousarray(y, dtype=f8),
        np.ascontiguousarray(u, dtype=f8),
        np.ascontiguousarray(x0, dtype=f8),
        np.ascontiguousarray(dx0[:Q], dtype=f8).reshape(Q, n),
        np.ascontiguousarray(P0, dtype=f8),
        np.ascontiguousarray(dP0[:Q], dtype=f8).reshape(Q, n, n),
        int(order),
        float(FREEZE_TOL if steady else -1.0),
        xp,
        eps,
        rvar,
        steady_from,
    )
    if status:
        raise np.linalg.LinAlgError("the innovation covariance is not positive")
    out = _Pass(
        nll=float(nll),
        grad=grad if order >= 1 else np.zeros(len(dx0)),
        fisher=fisher if order >= 2 else None,
        steady_from=[int(k) for k in steady_from[:count]],
    )
    if series:
        out.xp, out.eps, out.rvar = xp, eps, rvar
    return out


def _decays(st: _Steady, rows: int) -> bool:
    """Whether the stationary predictor's transient dies out within ``rows``: |F|^rows below
    JUMP_DECAY for the slowest mode (the prior's trace on the run's end state is then
    rounding, so a later run starts as the exact filter would)."""
    r = float(np.max(np.abs(np.linalg.eigvals(st.F))))
    return r <= 0.0 or rows * math.log(r) < math.log(JUMP_DECAY)


def _power_sum(modes: _Modes, w: np.ndarray) -> np.ndarray:
    """sum_i G^i w[..., i] for channels w (C, n, L), G the matrix of ``modes`` (F for
    ``st.modes``, F^T for ``st.modes_T``): one pass of the recursion nu_(i) = G nu_(i+1) + w_i
    backwards in i, read at i = 0. Returns (C, n)."""
    C, n, L = w.shape
    H = np.zeros((n, C, C * n))
    for c in range(C):
        H[:, c, c * n : (c + 1) * n] = np.eye(n)
    Z = np.zeros((C * n, L + 1))
    Z[:, :L] = w.reshape(C * n, L)[:, ::-1]
    return _column(modes.run(H, Z, np.zeros((n, C))), L).T


def _matrix_power(F: np.ndarray, dF: np.ndarray, N: int) -> tuple[np.ndarray, np.ndarray]:
    """F^N and its derivatives along dF (Q, n, n), by squaring the block matrices
    [[F, dF_q], [0, F]] (whose N-th power is [[F^N, d(F^N)_q], [0, F^N]])."""
    n, Q = len(F), len(dF)
    B = np.zeros((max(Q, 1), 2 * n, 2 * n))
    B[:, :n, :n] = F
    B[:, n:, n:] = F
    if Q:
        B[:, :n, n:] = dF
    out = np.broadcast_to(np.eye(2 * n), B.shape).copy()
    e = N
    while e:
        if e & 1:
            out = out @ B
        e >>= 1
        if e:
            B = B @ B
    return out[0, :n, :n], out[:Q, :n, n:]


@dataclass
class _PriorCorrection:
    """The exact change of a run's NLL when its first predicted covariance is P + Delta
    instead of the stationary P (:func:`_prior_correction`)."""

    nll: float
    N: int
    X: np.ndarray  # the infinite sum (the Lyapunov solution)
    XN: np.ndarray  # the run's sum, X - F^(N T) X F^N
    Delta: np.ndarray
    Minv: np.ndarray
    s: np.ndarray

    def gradient(self, st, Q, dDelta, dx0, mu, Hq, Z, a, Co) -> np.ndarray:
        """dNLL along the Q directions: dDelta (Q, n, n), dx0 (Q, n) the run's first state
        sensitivities, mu (n, N + 1) the innovations' adjoint, Hq (Q, n, k) and Z (k, N) the
        sensitivities' forcing f_i = Hq Z_i, a = R^-1 eps (n_o, N)."""
        n, N = len(self.s), self.N
        F, X = st.F, self.X
        dF, dR = _pad(st.dF, Q), _pad(st.dR, Q)
        RC = st.Rinv @ Co  # (n_o, n)
        # dX = F^T dX F + dF^T X F + F^T X dF - C^T R^-1 dR R^-1 C (Kronecker solve), then
        # the run's dX_N = d(X - F^(N T) X F^N)
        XF = X @ F
        rhs = dF.transpose(0, 2, 1) @ XF
        rhs = rhs + rhs.transpose(0, 2, 1) - RC.T @ dR @ RC
        kron = np.eye(n * n) - np.kron(F.T, F.T)
        dX = np.linalg.solve(kron, rhs.reshape(Q, -1).T).T.reshape(Q, n, n)
        FN, dFN = _matrix_power(F, dF, N)
        tail = dFN.transpose(0, 2, 1) @ (X @ FN)
        dXN = dX - tail - tail.transpose(0, 2, 1) - FN.T @ dX @ FN
        # ds = sum_i F^(i T) w_i - X_N dx_0 + F^(N T) X sum_i F^(N-1-i) f_i, with
        # w_i = dF^T mu_(i+1) - C^T R^-1 dR a_i - F^T X f_i (docs/identification.md)
        f = Hq @ Z  # (Q, n, N)
        w = np.einsum("qji,jl->qil", dF, mu[:, 1 : N + 1])
        w -= np.einsum("ij,qjk,kl->qil", Co.T @ st.Rinv, dR, a)
        w -= np.einsum("ij,qjl->qil", XF.T, f)
        ds = _power_sum(st.modes_T, w) - dx0 @ self.XN
        ds += _power_sum(st.modes, f[:, :, ::-1]) @ (X @ FN)
        # c = 1/2 log det M - 1/2 s^T W s, M = I + X_N Delta, W = Delta M^-1
        dM = dXN @ self.Delta + self.XN @ dDelta
        W = self.Delta @ self.Minv
        r = self.Minv @ self.s
        left = W.T @ self.s
        g = 0.5 * np.einsum("ij,qji->q", self.Minv, dM)
        g -= 0.5 * (ds @ (left + W @ self.s))
        g -= 0.5 * (
            np.einsum("i,qij,j->q", self.s, dDelta, r) - np.einsum("i,qij,j->q", left, dM, r)
        )
        return g


def _prior_correction(st: _Steady, Delta: np.ndarray, s: np.ndarray, N: int) -> _PriorCorrection:
    """A run of N rows filtered from the predicted covariance P + Delta has the stationary
    filter's innovations e_j plus the response G_j = C_o F^j to its first state's deviation
    (de Jong's augmentation of the initial state, exact for any Delta that keeps the joint
    covariance positive): with X_N = sum_(j<N) G_j^T R^-1 G_j = X - F^(N T) X F^N (X the
    Lyapunov solution of X = F^T X F + C_o^T R^-1 C_o) and s = sum_j G_j^T R^-1 e_j,

        NLL = NLL_stationary + 1/2 log det(I + X_N Delta) - 1/2 s^T Delta (I + X_N Delta)^-1 s.
    """
    n = len(s)
    H = st.C.T @ st.Rinv @ st.C
    X = solve_discrete_lyapunov(st.F.T, H)
    X = (X + X.T) / 2.0
    FN = np.linalg.matrix_power(st.F, N)
    XN = X - FN.T @ X @ FN
    XN = (XN + XN.T) / 2.0
    M = np.eye(n) + XN @ Delta
    sign, logdet = np.linalg.slogdet(M)
    if not sign > 0:
        raise np.linalg.LinAlgError("the prior's innovation covariance is not positive")
    Minv = np.linalg.inv(M)
    nll = 0.5 * (logdet - float(s @ (Delta @ Minv) @ s))
    return _PriorCorrection(nll=nll, N=N, X=X, XN=XN, Delta=Delta, Minv=Minv, s=s)


def _steady_run(
    sysm: _System,
    st: _Steady,
    d: _Data,
    k: int,
    k1: int,
    x: np.ndarray,
    dx: np.ndarray,
    dBd: np.ndarray | None,
    order: int,
    out: _Pass,
    prior: tuple[np.ndarray, np.ndarray | None] | None = None,
) -> tuple[float, np.ndarray, np.ndarray]:
    """Rows k..k1-1 with the stationary filter: x_{j+1} = F x_j + Bd u_j + L y_j and its
    sensitivities dx_{j+1} = F dx_j + dF x_j + dBd u_j + dL y_j, each one modal lfilter per
    mode for all channels (:func:`railtherm.estimation.models.propagate`); R is constant, so

        NLL = 1/2 (n_rows (log det R + n_o log 2 pi) + sum eps^T R^-1 eps),
        dNLL = 1/2 n_rows tr(R^-1 dR) - 1/2 tr(R^-1 dR R^-1 E) + sum (R^-1 eps)^T deps,

    E = sum eps eps^T, deps = -C_o dx. Returns the NLL of the rows and the prediction (x, dx)
    for row k1; adds to out's gradient, Fisher information and series.

    ``prior`` (Delta, dDelta): row k's predicted covariance is P + Delta, not the stationary
    P; the NLL and gradient then get the exact correction of :func:`_prior_correction` (the
    Fisher information stays the stationary filter's: the optimiser's curvature only)."""
    o, Co = st.o, st.C
    Lr = k1 - k
    n, no = len(x), len(o)
    u = d.u
    # Z = [x; u; y] of rows k..k1 (the forcing of row k1 is not used: any value)
    m_in = u.shape[1]
    Z = np.zeros((n + m_in + no, Lr + 1))
    Z[n : n + m_in] = np.vstack([u[k:k1], u[min(k1, len(u) - 1)]]).T
    Z[n + m_in :, :Lr] = d.y[k:k1][:, o].T
    # x_{j+1} = F x_j + Bd u_j + L y_j
    H = np.concatenate([sysm.Bd, st.L], axis=1)[:, None, :]
    xs = _states(st.modes.run(H, Z[n:], x[:, None]), np.eye(n))[:, 0, :]  # (n, Lr + 1)
    Z[:n] = xs
    eps = Z[n + m_in :, :Lr] - Co @ xs[:, :Lr]  # (no, Lr)
    a = st.Rinv @ eps
    nll = 0.5 * (Lr * (st.logdet + no * LOG_2PI) + float(np.einsum("ij,ij->", eps, a)))
    mu = None
    if prior is not None or (order == 1 and k1 == len(u)):
        # mu_l = sum_{j >= l} F^(j-l)T C_o^T a_j, mu_Lr = 0: the adjoint of the innovations
        b = np.zeros((n, Lr + 1))
        b[:, :Lr] = (Co.T @ a)[:, ::-1]
        rev = _states(st.modes_T.run(np.eye(n)[:, None, :], b, np.zeros((n, 1))), np.eye(n))
        mu = rev[:, 0, ::-1]  # mu_l, l = 0..Lr
    if prior is not None:
        correction = _prior_correction(st, prior[0], mu[:, 0], Lr)
        nll += correction.nll
    if out.xp is not None:
        out.xp[k:k1] = xs[:, :Lr].T
        rows = np.arange(k, k1)[:, None]
        out.eps[rows, o[None, :]] = eps.T
        out.rvar[rows, o[None, :]] = np.diag(st.R)[None, :]
    x_next = xs[:, Lr].copy()
    if order < 1:
        return nll, x_next, dx
    Q = len(dx)
    # sensitivities: dx_{j+1} = F dx_j + dF x_j + dBd u_j + dL y_j = F dx_j + H_q Z_j
    Hq = np.concatenate([_pad(st.dF, Q), dBd, _pad(st.dL, Q)], axis=2)  # (Q, n, k)
    dR = _pad(st.dR, Q)
    RdR = st.Rinv @ dR
    g = 0.5 * Lr * np.trace(RdR, axis1=1, axis2=2)
    g -= 0.5 * np.einsum("qij,ji->q", RdR, st.Rinv @ (eps @ eps.T))
    if prior is not None:
        g += correction.gradient(st, Q, prior[1], dx, mu, Hq, Z[:, :Lr], a, Co)
    if order == 1 and k1 == len(u):
        # the experiment's last run, gradient only: sum_l deps_l^T a_l = -sum_l b_l^T dx_l
        # (b_l = C_o^T a_l) by the adjoint mu_l = F^T mu_{l+1} + b_l, mu_Lr = 0:
        # = -(mu_0^T dx_0 + sum_l mu_{l+1}^T H_q Z_l), one recursion for every direction
        g -= dx @ mu[:, 0] + np.einsum("qij,ij->q", Hq, mu[:, 1:Lr] @ Z[:, : Lr - 1].T)
        out.grad += g
        return nll, x_next, dx  # no later row needs the sensitivities
    modes = st.modes.run(Hq.transpose(1, 0, 2), Z, dx.T)
    dx_next = _column(modes, Lr).T.copy()
    # sum_l deps_l^T a_l with deps = -C_o dx: per mode, -weight Re(z @ (a^T C_o v))
    for z, v, weight in modes:
        b = (Co @ v) @ a  # (Lr,)
        g -= weight * np.real(z[:, :Lr] @ b)
    out.grad += g
    if order >= 2:
        Lc = np.linalg.cholesky(st.Rinv)  # R^-1 = Lc Lc^T
        G = _states(modes, -Lc.T @ Co)[:, :, :Lr]  # (no, Q, Lr): Lc^T deps
        info = 0.5 * Lr * np.einsum("qij,rji->qr", RdR, RdR)
        for i in range(no):
            info += G[i] @ G[i].T
        out.fisher += info
    return nll, x_next, dx_next


# ----------------------------------------------------------------------------------------------
# the likelihood of all experiments in the unknowns


class _Likelihood:
    """NLL, gradient and Fisher information of all experiments in the unknowns
    v = [log theta_free, log sigma_free, log s_free, initial states (K) per experiment]."""

    def __init__(
        self,
        structure: Structure,
        experiments: Sequence[Experiment],
        fixed: Mapping[str, float],
        free: tuple[str, ...],
        sigma: np.ndarray,
        sigma_free: tuple[int, ...],
        meas_var: np.ndarray,
        meas_var_free: tuple[int, ...],
        out_idx: tuple[int, ...],
        x0_mode: str,
        offset_sd: Mapping[int, float] | None = None,
    ):
        self.s = structure
        self.fixed = dict(fixed)
        self.free = tuple(free)
        self.sigma0 = np.asarray(sigma, dtype=float)  # values of the fixed diffusions
        self.sigma_free = tuple(sigma_free)
        self.meas_var0 = np.asarray(meas_var, dtype=float)
        self.meas_var_free = tuple(meas_var_free)
        self.out_idx = tuple(out_idx)
        self.x0_mode = x0_mode
        self.n = len(structure.states)
        self.hold = pem.one_hold(experiments)
        self.data = [_data(structure, e, out_idx, x0_mode) for e in experiments]
        self.P = len(self.free)
        self.Qn = self.P + len(self.sigma_free) + len(self.meas_var_free)  # noise ends here
        # constant offsets of compared outputs (K), estimated with a Gaussian prior
        # N(0, sd^2): {output position j: sd}
        self.offset_out = tuple(sorted(offset_sd or {}))
        self.offset_sd = np.array([float((offset_sd or {})[j]) for j in self.offset_out])
        self.Qg = self.Qn + len(self.offset_out)
        self.offsets = []
        k = self.Qg
        for d in self.data:
            self.offsets.append(k)
            k += len(d.x0_free)
        self.n_unknowns = k
        self.n_obs = int(sum(np.isfinite(d.y).sum() for d in self.data))
        self._cache: dict[tuple, Any] = {}

    # -- unpacking
    def theta(self, v: np.ndarray) -> dict[str, float]:
        th = dict(self.fixed)
        th.update({p: float(np.exp(v[i])) for i, p in enumerate(self.free)})
        return th

    def sigma(self, v: np.ndarray) -> np.ndarray:
        out = self.sigma0.copy()
        out[list(self.sigma_free)] = np.exp(v[self.P : self.P + len(self.sigma_free)])
        return out

    def meas_var(self, v: np.ndarray) -> np.ndarray:
        out = self.meas_var0.copy()
        a = self.P + len(self.sigma_free)
        out[list(self.meas_var_free)] = np.exp(v[a : a + len(self.meas_var_free)])
        return out

    def x0s(self, v: np.ndarray, data: list[_Data] | None = None) -> list[np.ndarray]:
        """The experiments' initial states; ``data``: :meth:`shifted` at v, when the caller
        has it already."""
        out = []
        for d, off in zip(data or self.shifted(v), self.offsets, strict=True):
            x0 = d.x0_base.copy()
            x0[d.x0_free] = v[off : off + len(d.x0_free)]
            out.append(x0)
        return out

    # -- the discrete system
    def system(self, v: np.ndarray, dt: float, order: int) -> _System:
        th = self.theta(v)
        sigma, svar = self.sigma(v), self.meas_var(v)
        n, P = self.n, self.P
        A, _ = self.s.matrices(th)
        Ad, Bd, dAd_p, dBd_p = models.transition(
            self.s, th, dt, self.hold, self.free if order >= 1 else ()
        )
        W = np.diag(sigma**2)
        C = np.eye(n)[list(self.out_idx)]
        if order < 1:
            Qd, _ = models.discretize_noise(A, W, dt)
            e = np.zeros((0, n, n))
            return _System(
                Ad, Bd, Qd, C, svar, e, np.zeros((0,) + Bd.shape), e,
                np.zeros((0, len(svar))), order,
            )  # fmt: skip
        der = self.s.derivatives(th)
        directions = [(th[p] * der[p][0], np.zeros((n, n))) for p in self.free]
        for i in self.sigma_free:
            dW = np.zeros((n, n))
            dW[i, i] = 2.0 * sigma[i] ** 2  # d(sigma_i^2) / d log sigma_i
            directions.append((np.zeros((n, n)), dW))
        Qd, dQ = models.discretize_noise(A, W, dt, directions)
        Qg = self.Qg
        dAd = np.zeros((Qg, n, n))
        dBd = np.zeros((Qg,) + Bd.shape)
        dQd = np.zeros((Qg, n, n))
        dS = np.zeros((Qg, len(svar)))
        for i, p in enumerate(self.free):
            dAd[i] = th[p] * dAd_p[p]
            dBd[i] = th[p] * dBd_p[p]
        if dQ:
            dQd[: len(dQ)] = np.array(dQ)
        base = P + len(self.sigma_free)
        for t, j in enumerate(self.meas_var_free):
            dS[base + t, j] = svar[j]  # d s_j / d log s_j
        return _System(Ad, Bd, Qd, C, svar, dAd, dBd, dQd, dS, order)

    def _prior(self, sysm: _System, d: _Data, x0: np.ndarray, order: int, Q: int):
        """Prior mean and covariance of x_0 with their derivatives along Q directions."""
        n = self.n
        dx0 = np.zeros((Q, n))
        for t, i in enumerate(d.x0_free):
            dx0[self.Qg + t, i] = 1.0
        dP0 = np.zeros((Q, n, n))
        if self.x0_mode == "estimated":
            st = sysm.steady(d.prior_code, _outputs_of(d.prior_code, len(self.out_idx)))
            if st is not None:
                P0 = st.P.copy()
                if order >= 1:
                    dP0 = _pad(st.dP, Q).copy()
            else:  # no stationary filter: one step of process noise
                P0 = sysm.Qd.copy()
                if order >= 1:
                    dP0 = _pad(sysm.dQd, Q).copy()
            return x0, dx0, P0, dP0
        P0 = np.zeros((n, n))
        for i, j in d.x0_prior:
            P0[i, i] = sysm.S[j]
            if order >= 1:
                dP0[: len(sysm.dS), i, i] = sysm.dS[:, j]
        return x0, dx0, P0, dP0

    def offsets_of(self, v: np.ndarray) -> np.ndarray:
        """The compared outputs' offsets (K), zero where none is estimated."""
        b = np.zeros(len(self.out_idx))
        b[list(self.offset_out)] = v[self.Qn : self.Qg]
        return b

    def shifted(self, v: np.ndarray) -> list[_Data]:
        """The experiments' data with the estimated output offsets taken off the readings
        (and off a measured initial state)."""
        if not self.offset_out:
            return self.data
        b = self.offsets_of(v)
        out = []
        for d in self.data:
            x0_base = d.x0_base.copy()
            for i, j in d.x0_prior:
                x0_base[i] -= b[j]
            out.append(replace(d, y=d.y - b, x0_base=x0_base))
        return out

    def passes(self, v: np.ndarray, order: int, steady: bool = True, series: bool = False):
        """One filter pass per experiment (list of _Pass; the x0 directions of each are its
        own, after the Qg global ones)."""
        systems: dict[float, _System] = {}
        out = []
        data = self.shifted(v)
        for d, x0 in zip(data, self.x0s(v, data), strict=True):
            if d.e.dt not in systems:
                systems[d.e.dt] = self.system(v, d.e.dt, order)
            sysm = systems[d.e.dt]
            Q = self.Qg + len(d.x0_free)
            x0, dx0, P0, dP0 = self._prior(sysm, d, x0, order, Q)
            run = _filter_rows if COMPILED else _filter
            out.append(run(sysm, d, x0, dx0, P0, dP0, order, steady=steady, series=series))
        return out

    def evaluate(self, v: np.ndarray, order: int, steady: bool = True):
        """(NLL, gradient or None, Fisher information or None) at v; inf where the model
        cannot be evaluated. The last evaluation is cached.

        With output offsets: their prior 1/2 sum b_j^2 / sd_j^2 is added, and their entries
        of the gradient and of the information come from central differences (of the NLL in
        b, of the analytic gradient along b); the filter's own derivatives cover the rest."""
        key = (v.tobytes(), steady)
        hit = self._cache.get(key)
        if hit is not None and hit[0] >= order:
            return hit[1]
        res = self._raw(v, order, steady)
        if self.offset_out and math.isfinite(res[0]):
            res = self._with_offsets(v, order, steady, res)
        # a failed pass of the derivatives is not cached: their solves can fail where the
        # likelihood (a lower order) is finite, which a cached failure would hide
        if order == 0 or math.isfinite(res[0]):
            self._cache = {key: (order, res)}
        return res

    def _with_offsets(self, v, order, steady, res):
        nll, grad, fisher = res
        B = range(self.Qn, self.Qg)
        b = v[self.Qn : self.Qg]
        nll = nll + 0.5 * float(np.sum((b / self.offset_sd) ** 2))
        if order < 1:
            return nll, None, None
        h = OFFSET_STEP
        for t, q in enumerate(B):
            e = np.zeros(len(v))
            e[q] = h
            up, down = (
                self._raw(v + e, max(order - 1, 0), steady),
                self._raw(v - e, max(order - 1, 0), steady),
            )
            grad[q] = (up[0] - down[0]) / (2.0 * h) + b[t] / self.offset_sd[t] ** 2
            if order >= 2:
                column = (up[1] - down[1]) / (2.0 * h)
                column[q] = (up[0] - 2.0 * res[0] + down[0]) / h**2
                fisher[:, q] = column
                fisher[q, :] = column
                fisher[q, q] += 1.0 / self.offset_sd[t] ** 2
        return nll, grad, fisher

    def _raw(self, v: np.ndarray, order: int, steady: bool = True):
        """evaluate() of the filter alone, without the cache and the offsets' terms."""
        U = self.n_unknowns
        try:
            with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
                runs = self.passes(v, order, steady)
            nll = float(sum(r.nll for r in runs))
            if not math.isfinite(nll):
                raise FloatingPointError
        except (ArithmeticError, np.linalg.LinAlgError, ValueError):
            return (math.inf, np.zeros(U) if order >= 1 else None, None)
        grad = fisher = None
        if order >= 1:
            grad = np.zeros(U)
            if order >= 2:
                fisher = np.zeros((U, U))
            for d, off, r in zip(self.data, self.offsets, runs, strict=True):
                idx = np.concatenate([np.arange(self.Qg), off + np.arange(len(d.x0_free))])
                grad[idx] += r.grad
                if order >= 2:
                    fisher[np.ix_(idx, idx)] += r.fisher
        return nll, grad, fisher


def negative_log_likelihood(
    structure: Structure,
    experiments: Sequence[Experiment],
    theta: Mapping[str, float],
    sigma: Mapping[str, float],
    meas_var: Mapping[str, float],
    x0: Sequence[Sequence[float]],
    *,
    outputs: Sequence[str] | None = None,
    x0_mode: str = "estimated",
    steady: bool = True,
) -> float:
    """The exact NLL of ``experiments`` at given parameters: theta (every parameter of the
    structure), sigma {state: diffusion, K/sqrt(s)}, meas_var {output: variance, K^2}, x0 the
    prior mean of each experiment's initial state (with ``x0_mode="measured"`` only its
    unmeasured entries are read). ``steady=False`` runs the time-varying filter on every row
    (the reference the stationary switch is measured against)."""
    outputs = _default_outputs(structure, experiments) if outputs is None else tuple(outputs)
    out_idx = tuple(structure.states.index(o) for o in outputs)
    lik = _Likelihood(
        structure,
        experiments,
        {p: float(theta[p]) for p in structure.parameters},
        (),
        np.array([float(sigma[s]) for s in structure.states]),
        (),
        np.array([float(meas_var[o]) for o in outputs]),
        (),
        out_idx,
        x0_mode,
    )
    v = np.concatenate(
        [np.zeros(0)]
        + [np.asarray(x, dtype=float)[d.x0_free] for x, d in zip(x0, lik.data, strict=True)]
    )
    return lik.evaluate(v, 0, steady=steady)[0]


def _default_outputs(structure: Structure, experiments: Sequence[Experiment]) -> tuple[str, ...]:
    """Every state with a finite measurement in some experiment (as
    :func:`railtherm.estimation.pem.fit`)."""
    n = len(structure.states)
    return tuple(
        s
        for i, s in enumerate(structure.states)
        if any(np.isfinite(e.y[:, i]).any() for e in experiments if e.y.shape[1] == n)
    )


# ----------------------------------------------------------------------------------------------
# the estimate


@dataclass(kw_only=True)
class KalmanResult(Estimate):
    """The maximum-likelihood estimate of the stochastic grey-box model, an
    :class:`~railtherm.estimation.estimate.Estimate` with ``estimator`` kalman.

    As every estimate for the structure's parameters: ``theta`` (all, fixed
    ones too), ``free`` (estimated, in the order of ``correlation``), ``fixed``, ``ci95``,
    ``sd_log``, ``correlation``, ``cond`` (square root of the condition number of the observed
    information of the log parameters, the analogue of cond(J)), ``flags``, ``identified``
    ({param: :func:`railtherm.estimation.pem.identification`}). ``cost`` is the minimised negative
    log-likelihood and ``loglik`` = -cost; ``n_obs`` the scalar measurements used,
    ``n_unknowns`` = ``n_params`` every estimated quantity (parameters, noise parameters,
    initial states: the count of AIC = 2 cost + 2 n_params and BIC).

    Noise: ``sigma`` {state: sigma, K/sqrt(s)}, ``meas_var`` {output: s, K^2}, with
    ``noise_ci95`` and ``noise_sd_log`` for the estimated ones (a noise parameter at its bound
    is held there: no interval, listed in ``noise_at_bound``).

    Per experiment (lists in the order given): ``names``, ``dt``, ``x0`` (the initial state:
    the prior mean of the filter), ``x0_estimated`` (its estimated states), ``simulated`` (the
    deterministic simulation x[n+1] = Ad x[n] + Bd u[n] from x0 with the estimated theta,
    N x n_states), ``residuals`` (measured - simulated, NaN where not compared), ``one_step``
    (the filter's predictions x_{k|k-1}, N x n_states), ``innovations`` (y - C x_{k|k-1},
    N x n_outputs, NaN where not measured), ``innovation_var`` (the diagonal of R_k, N x
    n_outputs, NaN where not measured).

    ``unknowns`` names every estimated quantity in the order of ``covariance_log`` (the
    inverse observed information: log parameters, log noise parameters, initial states in K).
    """

    CONDITION: ClassVar[str] = "information_condition"

    estimator: str = "kalman"
    covariance: str = "observed information"
    start_used: str = "output_error"
    sigma: dict[str, float] = field(default_factory=dict)
    meas_var: dict[str, float] = field(default_factory=dict)
    noise_ci95: dict[str, tuple[float, float]] = field(default_factory=dict)
    noise_sd_log: dict[str, float] = field(default_factory=dict)
    noise_at_bound: tuple[str, ...] = ()
    loglik: float = math.nan
    n_params: int = 0
    innovations: list[np.ndarray] = field(default_factory=list, repr=False)
    innovation_var: list[np.ndarray] = field(default_factory=list, repr=False)
    one_step: list[np.ndarray] = field(default_factory=list, repr=False)
    identified: dict[str, Identification] = field(default_factory=dict)
    unknowns: tuple[str, ...] = ()
    covariance_log: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)), repr=False)
    x0_mode: str = "estimated"
    start_theta: dict[str, float] = field(default_factory=dict)
    start_cost: float = math.nan
    offsets: dict[str, dict[str, float]] = field(default_factory=dict)

    @property
    def aic(self) -> float:
        """Akaike's criterion 2 NLL + 2 n_params."""
        return 2.0 * self.cost + 2.0 * self.n_params

    @property
    def bic(self) -> float:
        """Schwarz's criterion 2 NLL + n_params log n_obs."""
        return 2.0 * self.cost + self.n_params * math.log(max(self.n_obs, 1))

    def extra(self) -> dict[str, Any]:
        """The noise parameters (sigma_<state>, s_<output>) with their intervals, the
        measurement offsets, the likelihood and its criteria, the count of AIC and BIC and
        how the initial states were taken."""

        def f(v):
            return float(v)

        noise = {}
        for name, v in [(f"sigma_{s}", x) for s, x in self.sigma.items()] + [
            (f"s_{o}", x) for o, x in self.meas_var.items()
        ]:
            entry = {"value": f(v), "estimated": name in self.noise_ci95}
            if name in self.noise_ci95:
                entry["ci95"] = [f(c) for c in self.noise_ci95[name]]
                entry["sd_log"] = f(self.noise_sd_log[name])
            noise[name] = entry
        return {
            "noise": noise,
            "noise_at_bound": list(self.noise_at_bound),
            "offsets": {
                o: {k: f(x) for k, x in entry.items()} for o, entry in self.offsets.items()
            },
            "negative_log_likelihood": f(self.cost),
            "loglik": f(self.loglik),
            "aic": f(self.aic),
            "bic": f(self.bic),
            "n_params": int(self.n_params),
            "x0_mode": self.x0_mode,
        }


def _split(mapping: Mapping[str, Any] | None, structure: Structure, noise: tuple[str, ...]):
    """(structure's entries, noise entries) of a fixed / initial / bounds mapping."""
    mapping = dict(mapping or {})
    unknown = [k for k in mapping if k not in structure.parameters and k not in noise]
    if unknown:
        raise ValueError(
            f"unknown parameters {unknown}: {structure.name!r} has {structure.parameters} and "
            f"the noise parameters {noise}"
        )
    return (
        {k: v for k, v in mapping.items() if k in structure.parameters},
        {k: v for k, v in mapping.items() if k in noise},
    )


def _hessian(
    lik: _Likelihood, v: np.ndarray, g0: np.ndarray, h: float = HESSIAN_STEP
) -> np.ndarray:
    """The observed information: forward differences of the analytic gradient (g0 at v),
    symmetrised. With h = 1e-5 the standard deviations it gives agree with central differences
    to about 1e-5 (relative), at half their cost."""
    U = len(v)
    H = np.zeros((U, U))
    for i in range(U):
        step = np.zeros(U)
        step[i] = h
        H[:, i] = (_gradient(lik, v + step) - g0) / h
    return (H + H.T) / 2.0


def _gradient(lik: _Likelihood, v: np.ndarray) -> np.ndarray:
    """The NLL's gradient at v; NaN where it cannot be evaluated (the information built from
    it then leaves the unknowns it touches unresolved, :func:`_finite_information`)."""
    nll, g, _ = lik.evaluate(v, 1)
    if g is None or not math.isfinite(nll):
        return np.full(len(v), np.nan)
    return np.asarray(g, dtype=float)


def _information(lik: _Likelihood, v: np.ndarray) -> np.ndarray:
    """The Fisher information at v; where the filter's second-order pass cannot give it
    (evaluate returns None), the observed information from the gradient (:func:`_hessian`)."""
    nll, _, F = lik.evaluate(v, 2)
    if F is not None and math.isfinite(nll):
        return F
    return _hessian(lik, v, _gradient(lik, v))


def _finite_information(Hk: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``Hk`` with the rows and columns of unknowns whose information is not finite set to
    zero, and a mask of those unknowns (their variance is then unbounded: not identified)."""
    bad = ~np.all(np.isfinite(Hk), axis=0) | ~np.all(np.isfinite(Hk), axis=1)
    if not bad.any():
        return Hk, bad
    Hk = np.array(Hk, dtype=float)
    Hk[bad, :] = 0.0
    Hk[:, bad] = 0.0
    return Hk, bad


@common.single_threaded_blas
def fit(
    structure: Structure,
    experiments: Sequence[Experiment],
    *,
    fixed: Mapping[str, float] | None = None,
    initial: Mapping[str, float] | None = None,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    outputs: Sequence[str] | None = None,
    x0: str = "estimated",
    start: str = "auto",
    sigma_initial: float | Mapping[str, float] | None = None,
    input_noise: Mapping[str, float | Sequence[float]] | None = None,
    offsets: Mapping[str, float] | None = None,
) -> KalmanResult:
    """Maximum-likelihood fit of the stochastic model of ``structure`` to ``experiments``
    jointly (shared parameters, each experiment its own initial state).

    fixed / initial / bounds: as :func:`railtherm.estimation.pem.fit` for the structure's
    parameters, and may also name the noise parameters of :func:`noise_names` (``sigma_<state>`` in
    K/sqrt(s), ``s_<output>`` in K^2; ``fixed={"sigma_T": 0.0}`` removes the diffusion of T).
    outputs: the compared states (default: every state with a measurement). x0:
    ``"estimated"`` (every initial state estimated, prior covariance the stationary P of the
    filter) or ``"measured"`` (the first measurement with its variance s_j as prior; a state
    without one is estimated). start: passed to the output-error fit
    (:func:`railtherm.estimation.pem.fit`, ``"auto"`` or ``"initial"``) whose optimum starts theta
    and the initial states; the measurement variances start at the output-error residual variance,
    the diffusions at sigma_initial (K/sqrt(s), one value or {state: value}), by default
    sigma_i^2 dt = SIGMA_START^2 times the mean of those variances. input_noise: {input name:
    the standard deviation of its white measurement noise, one value or one per experiment},
    as :func:`railtherm.estimation.pem.fit` takes it: compensated in the estimate and added to the
    covariance (:func:`_input_noise_terms`). offsets: {compared output: sd (K)} - a constant
    offset of that output's readings (y = x + b + v, one output at most), estimated with the
    Gaussian prior b ~ N(0, sd^2): the calibration offset of a sensor group relative to the
    others, which the filter would otherwise explain by diffusions (``b_<output>``).
    """
    if x0 not in ("estimated", "measured"):
        raise ValueError(f"x0 must be 'estimated' or 'measured', got {x0!r}")
    if start not in ("auto", "initial"):
        raise ValueError(f"start must be 'auto' or 'initial', got {start!r}")
    experiments = list(experiments)
    if not experiments:
        raise ValueError("fit needs at least one experiment")
    outputs = _default_outputs(structure, experiments) if outputs is None else tuple(outputs)
    bad = [s for s in outputs if s not in structure.states]
    if bad or not outputs:
        raise ValueError(f"outputs {outputs} must be states of {structure.name}")
    out_idx = tuple(structure.states.index(s) for s in outputs)
    noise = noise_names(structure, outputs)
    offsets = dict(offsets or {})
    if len(offsets) > 1 or any(o not in outputs for o in offsets):
        raise ValueError(f"offsets: at most one of the compared outputs {outputs}, got {offsets}")
    if any(not (float(sd) > 0) for sd in offsets.values()):
        raise ValueError(f"offsets: the prior sd must be > 0, got {offsets}")
    fixed_p, fixed_n = _split(fixed, structure, noise)
    initial_p, initial_n = _split(initial, structure, noise)
    bounds_p, bounds_n = _split(bounds, structure, noise)
    if any(v < 0 or not math.isfinite(v) for v in fixed_n.values()):
        raise ValueError(f"fixed noise parameters must be finite and >= 0, got {fixed_n}")

    # the start: the output-error fit of the same structure, data and initial states
    oe = pem.fit(
        structure,
        experiments,
        fixed=fixed_p,
        initial=initial_p,
        bounds=bounds_p,
        outputs=outputs,
        x0=x0,
        covariance="iid",
        start=start,
        compiled=COMPILED,
    )
    free = oe.free
    bnds = dict(structure.bounds)
    bnds.update({p: (float(b[0]), float(b[1])) for p, b in bounds_p.items()})
    n, n_out = len(structure.states), len(outputs)
    resid = np.concatenate([r[:, out_idx] for r in oe.residuals])
    s_start = np.array([float(np.nanmean(resid[:, j] ** 2)) for j in range(n_out)])
    s_start = np.where(np.isfinite(s_start) & (s_start > 0), s_start, 1e-2)
    dt = float(np.median([e.dt for e in experiments]))
    if sigma_initial is None:
        sig_start = np.full(n, SIGMA_START * math.sqrt(float(s_start.mean()) / dt))
    elif isinstance(sigma_initial, Mapping):
        default = SIGMA_START * math.sqrt(float(s_start.mean()) / dt)
        sig_start = np.array([float(sigma_initial.get(s, default)) for s in structure.states])
    else:
        sig_start = np.full(n, float(sigma_initial))
    sigma = np.array(
        [
            float(fixed_n.get(f"sigma_{s}", initial_n.get(f"sigma_{s}", sig_start[i])))
            for i, s in enumerate(structure.states)
        ]
    )
    meas_var = np.array(
        [
            float(fixed_n.get(f"s_{o}", initial_n.get(f"s_{o}", s_start[j])))
            for j, o in enumerate(outputs)
        ]
    )
    sigma_free = tuple(i for i, s in enumerate(structure.states) if f"sigma_{s}" not in fixed_n)
    meas_var_free = tuple(j for j, o in enumerate(outputs) if f"s_{o}" not in fixed_n)
    lik = _Likelihood(
        structure,
        experiments,
        oe.fixed,
        free,
        sigma,
        sigma_free,
        meas_var,
        meas_var_free,
        out_idx,
        x0,
        {outputs.index(o): float(sd) for o, sd in offsets.items()},
    )
    names = (
        list(free)
        + [f"sigma_{structure.states[i]}" for i in sigma_free]
        + [f"s_{outputs[j]}" for j in meas_var_free]
        + [f"b_{outputs[j]}" for j in lik.offset_out]
    )
    for d, e in zip(lik.data, experiments, strict=True):
        names += [f"x0_{structure.states[i]}[{e.name}]" for i in d.x0_free]
    # bounds of the unknowns (log parameters, log noise, initial states in K)
    noise_bounds = {f"sigma_{s}": SIGMA_BOUNDS for s in structure.states}
    noise_bounds |= {f"s_{o}": MEAS_VAR_BOUNDS for o in outputs}
    noise_bounds |= {k: (float(b[0]), float(b[1])) for k, b in bounds_n.items()}
    lo, hi = [], []
    for name in names[: lik.Qn]:
        b = bnds[name] if name in bnds else noise_bounds[name]
        lo.append(math.log(b[0]) if b[0] > 0 else -np.inf)
        hi.append(math.log(b[1]) if np.isfinite(b[1]) else np.inf)
    lo += [OFFSET_BOUNDS[0]] * len(lik.offset_out)
    hi += [OFFSET_BOUNDS[1]] * len(lik.offset_out)
    for d in lik.data:
        lo += [d.x0_range[0]] * len(d.x0_free)
        hi += [d.x0_range[1]] * len(d.x0_free)
    lo, hi = np.array(lo), np.array(hi)
    span = hi - lo
    margin = np.where(np.isfinite(span), 1e-6 * span, 0.0)

    def clip(v: np.ndarray) -> np.ndarray:
        return np.clip(v, lo + margin, hi - margin)

    v0 = np.concatenate(
        [
            np.log([oe.theta[p] for p in free]),
            np.log(sigma[list(sigma_free)]),
            np.log(meas_var[list(meas_var_free)]),
            np.zeros(len(lik.offset_out)),
        ]
        + [x[d.x0_free] for x, d in zip(oe.x0, lik.data, strict=True)]
    )
    v0 = clip(v0)
    start_cost = lik.evaluate(v0, 0)[0]
    if not math.isfinite(start_cost):
        raise NotEvaluable(structure, oe.theta, dt)
    sol = _optimise(lik, v0, lo, hi, clip)
    v = sol.x
    H = _hessian(lik, v, _gradient(lik, v))
    levels = common.noise_levels(structure, input_noise or {}, experiments)
    meat = None
    if any(levels):
        v = _input_noise_terms(lik, v, levels, lo, hi)
        sol = SimpleNamespace(
            **{
                **vars(sol),
                "x": v,
                "fun": float(lik.evaluate(v, 0)[0]),
                "active_mask": _active_mask(v, lo, hi),
            }
        )
        # the Fisher information: the compensated point is no stationary point of the NLL, so
        # its observed information holds the residuals' second-order terms
        H = _information(lik, v)
        meat = _input_noise_meat(lik, v, _kept(lik, sol, v, lo, hi), levels)
    result = _result(structure, lik, sol, v, H, names, lo, hi, bnds, outputs, oe, start_cost, meat)
    result.input_noise_sd = [dict(level) for level in levels] if any(levels) else []
    return result


def _optimise(lik: _Likelihood, v0: np.ndarray, lo, hi, clip) -> SimpleNamespace:
    """Fisher scoring in a trust region (scipy trust-exact, the Fisher information as its
    Hessian) with an active set for the bounds: an unknown that leaves its bounds is held at
    the bound and the rest re-solved; a held one is released when the gradient points inside
    (the KKT condition fails by more than KKT_TOL). A diffusion the data do not show runs to
    its lower bound this way in a few steps, where a bounded quasi-Newton method crawls along
    the flat likelihood. When the scoring fails, L-BFGS-B with the bounds from the best point.
    """
    counts = {"nfev": 0}
    U = len(v0)
    scale = max(1.0, abs(lik.evaluate(v0, 0)[0]))
    v = v0.copy()
    held: dict[int, float] = {}
    message, success = "", False
    for _ in range(2 * U + 2):
        idx = np.array([i for i in range(U) if i not in held], dtype=int)
        base = v.copy()

        def full(w, base=base, idx=idx):
            x = base.copy()
            x[idx] = w
            return x

        def fun(w, full=full, idx=idx):
            counts["nfev"] += 1
            nll, g, _ = lik.evaluate(full(w), 2)
            return nll, g[idx]

        def hess(w, full=full, idx=idx):
            F = lik.evaluate(full(w), 2)[2]
            if F is None:  # a point the model cannot be evaluated at: a stiff stand-in
                return np.eye(len(idx)) * scale
            return F[np.ix_(idx, idx)]

        def leave(w, idx=idx):
            if np.any(w < lo[idx]) or np.any(w > hi[idx]):
                raise StopIteration

        if len(idx):
            res = minimize(
                fun,
                v[idx],
                jac=True,
                hess=hess,
                method="trust-exact",
                callback=leave,
                options={"gtol": 1e-7 * scale, "maxiter": 200},
            )
            w = full(res.x)
            if lik.evaluate(w, 0)[0] <= lik.evaluate(v, 0)[0]:
                v = w
            message = str(res.message)
        outside = [i for i in idx if v[i] < lo[i] or v[i] > hi[i]]
        if outside:
            for i in outside:
                held[i] = lo[i] if v[i] < lo[i] else hi[i]
                v[i] = held[i]
            continue
        nll, g, F = lik.evaluate(v, 2)
        if g is None or F is None or not math.isfinite(nll):
            # the information cannot be evaluated at the point reached (a derivative's
            # Lyapunov or discretisation solve fails where the likelihood itself does not):
            # no scoring step to judge convergence by; the quasi-Newton solve below goes on
            message = f"the Fisher information cannot be evaluated at the point reached ({message})"
            break
        release = [i for i, b in held.items() if _pull(lik, i, b, v, v0, g, lo, hi) > KKT_TOL]
        if release:
            for i in release:
                del held[i]
                v[i] = float(
                    np.clip(v0[i] if lik.P <= i < lik.Qn else v[i], lo[i] + 1e-3, hi[i] - 1e-3)
                )
            continue
        # a noise parameter left in the flat region near zero (its effect below the solver's
        # resolution) is taken at its bound when that changes the NLL by nothing
        snapped = False
        for i in idx:
            if lik.P <= i < lik.Qn and v[i] - lo[i] < SNAP_LOG:
                w = v.copy()
                w[i] = lo[i]
                nll_w, g_w, _ = lik.evaluate(w, 1)
                if (
                    nll_w <= nll + 1e-8 * scale
                    and _pull(lik, i, lo[i], w, v0, g_w, lo, hi) <= KKT_TOL
                ):
                    v, nll, held[i], snapped = w, nll_w, lo[i], True
        if snapped:
            continue
        # converged when the scoring step left is negligible: the Newton decrement
        # g^T F^-1 g (on the unknowns not held) below 1e-8 per unknown
        gi, Fi = g[idx], F[np.ix_(idx, idx)]
        try:
            decrement = float(gi @ np.linalg.lstsq(Fi, gi, rcond=1e-12)[0]) if len(idx) else 0.0
        except np.linalg.LinAlgError:
            decrement = math.inf
        success = decrement <= 1e-8 * max(len(idx), 1)
        # scipy's own exit message may read as a failure ("A bad approximation caused
        # failure to predict improvement") at a point whose scoring step is negligible: the
        # message says what decided
        message = (
            f"{'converged' if success else 'not converged'}: Newton decrement "
            f"{decrement:.3g} (tolerance {1e-8 * max(len(idx), 1):.3g}; trust-exact: {message})"
            + (f"; {len(held)} unknowns at a bound" if held else "")
        )
        break
    if not success:  # the bounded quasi-Newton solve from the best point reached

        def fun1(w):
            counts["nfev"] += 1
            nll, g, _ = lik.evaluate(w, 1)
            return nll, g

        res = minimize(
            fun1,
            clip(v) if not held else np.clip(v, lo, hi),
            jac=True,
            method="L-BFGS-B",
            bounds=list(zip(lo, hi, strict=True)),
            options={"maxiter": 2000, "ftol": 1e-14, "gtol": 1e-9 * scale},
        )
        if res.fun <= lik.evaluate(v, 0)[0]:
            v = res.x
        success = bool(res.success)
        message = f"trust-exact did not converge, then L-BFGS-B: {res.message}"
    return SimpleNamespace(
        x=v,
        fun=float(lik.evaluate(v, 0)[0]),
        success=success,
        status=1 if success else 0,
        message=message,
        active_mask=_active_mask(v, lo, hi),
        nfev=counts["nfev"],
        njev=counts["nfev"],
    )


def _active_mask(v: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """-1 / +1 for the unknowns at their lower / upper bound, 0 elsewhere."""
    active = np.zeros(len(v), int)
    active[v <= lo + 1e-9] = -1
    active[v >= hi - 1e-9] = 1
    return active


def _pull(lik: _Likelihood, i: int, b: float, v, v0, g, lo, hi) -> float:
    """How much the NLL falls per unit step from the bound b of unknown i into the inside
    (the KKT condition holds when it is not positive). For a noise parameter at its lower
    bound the log scale is blind (dNLL/dlog s = s dNLL/ds vanishes as s -> 0 whether or not
    the likelihood wants s > 0): the step is measured in the natural variable instead, s_j
    or sigma_i^2, in units of its start value."""
    inward = 1.0 if b == lo[i] else -1.0
    if lik.P <= i < lik.Qn and b == lo[i]:
        power = 2.0 if i < lik.P + len(lik.sigma_free) else 1.0
        return -g[i] * math.exp(power * (v0[i] - v[i])) / power
    return -inward * g[i]


def _kept(lik: _Likelihood, sol, v: np.ndarray, lo, hi) -> np.ndarray:
    """The unknowns the covariance is computed for: every one but the noise parameters at a
    bound, which are held there (the likelihood is flat beyond: a diffusion the data do not
    show), so they carry no curvature to invert."""
    held = {
        i
        for i in range(lik.P, lik.Qn)
        if v[i] - lo[i] < _AT_BOUND_LOG or hi[i] - v[i] < _AT_BOUND_LOG or sol.active_mask[i]
    }
    return np.array([i for i in range(len(v)) if i not in held], dtype=int)


def _pinv_sym(Hk: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pseudo-inverse of a symmetric information matrix (directions below common.NULL_REL of
    the largest eigenvalue dropped) and a mask of the unknowns loading on a dropped one."""
    lam, V = np.linalg.eigh(Hk)
    top = float(np.max(np.abs(lam))) if lam.size else 0.0
    null = lam <= common.NULL_REL * top if top > 0 else np.ones_like(lam, dtype=bool)
    inv = np.where(null, 0.0, 1.0 / np.where(null, 1.0, lam))
    unresolved = np.abs(V[:, null]).max(axis=1) > 1e-8 if null.any() else np.zeros(len(lam), bool)
    return (V * inv) @ V.T, unresolved


def _lag_sums(z: np.ndarray, N: int) -> np.ndarray:
    """S(z) = sum_{l=0}^{N-2} (N - 1 - l) z^l elementwise (complex z, |z| <= 1): the number of
    row pairs at lag l of a record of N rows, weighting z^l."""
    z = np.asarray(z, dtype=complex)
    one = np.abs(1.0 - z) < 1e-9
    zz = np.where(one, 0.5, z)
    with np.errstate(over="ignore", invalid="ignore"):
        out = ((N - 1) - zz * (1.0 - zz ** (N - 1)) / (1.0 - zz)) / (1.0 - zz)
    return np.where(one, N * (N - 1) / 2.0, out)


def _record_noise_terms(lik: _Likelihood, v: np.ndarray, i: int, level: Mapping[str, float]):
    """Experiment i's stationary predictor (F, C_o, R^-1, Bd) and the compensation
    1/2 sum_j sd_j^2 sum_l (N - 1 - l) g_l^T R^-1 g_l, g_l = C_o F^l Bd[:, j]
    (:func:`_input_noise_terms`), in closed form over F's modes. None where the record has no
    stationary filter for all its outputs."""
    d = lik.data[i]
    sysm = lik.system(v, d.e.dt, 0)
    n_out = len(lik.out_idx)
    st = sysm.steady((1 << n_out) - 1, np.arange(n_out))
    if st is None:
        return None
    N = len(d.y)
    lam, V = np.linalg.eig(st.F)
    CV = st.C @ V
    G = CV.T @ st.Rinv @ CV  # (modes, modes): alpha_a^T R^-1 alpha_b per unit amplitudes
    S = _lag_sums(np.outer(lam, lam), N)
    comp = 0.0
    for name, sd in level.items():
        beta = np.linalg.solve(V, sysm.Bd[:, lik.s.inputs.index(name)])
        comp += 0.5 * sd**2 * float(np.real(np.sum(G * np.outer(beta, beta) * S)))
    return SimpleNamespace(F=st.F, C=st.C, Rinv=st.Rinv, Bd=sysm.Bd, comp=comp)


def _compensation(lik: _Likelihood, v: np.ndarray, levels) -> float:
    total = 0.0
    for i, level in enumerate(levels):
        if level:
            terms = _record_noise_terms(lik, v, i, level)
            if terms is None:
                raise ValueError("no stationary filter")
            total += terms.comp
    return total


def _input_noise_terms(lik: _Likelihood, v, levels, lo, hi):
    """The declared white noise of measured inputs in a Kalman fit: its bias removed from the
    estimate, and its share of the covariance.

    The filter conditions on the measured inputs u = u0 + e. Noise e_t on input j moves the
    one-step predictions of the later rows by g_l e_t (g_l = C F^l Bd[:, j], F the stationary
    predictor's transition), so the innovations are the clean ones minus sum_l g_l e_{t-1-l}.
    That is not process noise - it is correlated with the input the filter is given (errors
    in variables) - but the likelihood takes it for some: its expectation adds to the NLL

        c(v) = 1/2 sum_j sd_j^2 sum_l (N - 1 - l) g_l^T R^-1 g_l

    (per record, summed), which prefers diffusions that let the filter follow the record and
    a small gain from the noisy input (for the air node, a larger C). The estimate is the
    minimiser of the compensated criterion NLL - c from the maximum-likelihood point, with the
    measurement variances held at their maximum-likelihood values: first over the
    structure's parameters, the diffusions and the initial states where a diffusion lies
    above its bound (L-BFGS-B within the bounds), then by Gauss-Newton steps with the Fisher
    information in the parameters and initial states (grad c by forward differences, c in
    closed form over F's modes). Where the declared noise accounts for the apparent process
    noise, the diffusions go to their lower bound and the estimate to the compensated
    output-error one. Returns the compensated v (or v unchanged where c cannot be evaluated)."""
    U = len(v)
    P, a = lik.P, lik.P + len(lik.sigma_free)
    diffusions = range(P, a)
    h = 1e-6

    def criterion(w: np.ndarray, order: int, along: Sequence[int]):
        """NLL - c, its gradient along ``along`` (forward differences of c) and, with
        order 2, the Fisher information; (inf, ...) where either cannot be evaluated."""
        nll, g, F = lik.evaluate(w, order)
        if not math.isfinite(nll):
            return math.inf, None, None
        try:
            c = _compensation(lik, w, levels)
            gc = np.zeros(U)
            for q in along:
                if q < a:
                    e = np.zeros(U)
                    e[q] = h
                    gc[q] = (_compensation(lik, w + e, levels) - c) / h
        except (ValueError, np.linalg.LinAlgError, ArithmeticError):
            return math.inf, None, None
        return nll - c, (None if g is None else g - gc), F

    start = criterion(v, 0, ())[0]
    if not math.isfinite(start):
        return v
    # 1. a diffusion above its bound may have taken up the input noise: the compensated
    # criterion over the parameters, the diffusions and the initial states (the measurement
    # variances held at their maximum-likelihood values: c grows as 1 / s, so NLL - c has no
    # minimum in them)
    if any(v[i] > lo[i] + _AT_BOUND_LOG for i in diffusions):
        free = [i for i in range(U) if not a <= i < lik.Qn]
        res = minimize(
            lambda w: criterion(w, 1, free)[:2],
            v,
            jac=True,
            method="L-BFGS-B",
            bounds=[(v[i], v[i]) if a <= i < lik.Qn else (lo[i], hi[i]) for i in range(U)],
            options={"maxiter": 300},
        )
        if math.isfinite(res.fun) and res.fun <= start:
            v, start = res.x.copy(), float(res.fun)
        # a diffusion left in the flat region near zero is taken at its bound when that
        # costs nothing (as the maximum-likelihood search does)
        for i in diffusions:
            if v[i] > lo[i]:
                w = v.copy()
                w[i] = lo[i]
                value = criterion(w, 0, ())[0]
                if value <= start + 1e-8 * max(1.0, abs(start)):
                    v, start = w, value
    # 2. Gauss-Newton steps with the Fisher information in the parameters and initial states,
    # the noise parameters held, each step halved until the criterion falls
    moved = [i for i in range(U) if i < P or i >= lik.Qn]
    for _ in range(20):
        value, g, F = criterion(v, 2, moved)
        if g is None or F is None:  # the information cannot be evaluated here: no step
            break
        Fm, gm = F[np.ix_(moved, moved)], g[moved]
        step = np.zeros(U)
        step[moved] = -np.linalg.lstsq(Fm, gm, rcond=1e-12)[0]
        if float(-gm @ step[moved]) <= 1e-10 * max(len(moved), 1):
            break
        for _ in range(30):
            w = np.clip(v + step, lo, hi)
            if criterion(w, 0, ())[0] < value:
                v = w
                break
            step = step / 2.0
        else:
            break
    return v


def _input_noise_meat(lik: _Likelihood, v: np.ndarray, keep: np.ndarray, levels) -> np.ndarray:
    """The covariance's share of the input noise (:func:`_input_noise_terms`): H^-1 M H^-1
    with M = sum_j sd_j^2 sum_t w_t w_t^T, w_t = -sum_l D_{t+1+l}^T R^-1 g_l the score's
    response to the noise at row t (D_k = d eps_k / d v by forward differences), in the
    order of v. With g_l = C F^l b, w_t = -b^T lambda_{t+1} by the backward recursion
    lambda_k = F^T lambda_{k+1} + C^T R^-1 D_k (one pass per record for every input)."""
    U = len(v)
    h = 1e-6
    base = lik.passes(v, 0, series=True)
    D = [np.zeros((len(r.eps), U, r.eps.shape[1])) for r in base]
    for q in keep:
        e = np.zeros(U)
        e[q] = h
        for k, r in enumerate(lik.passes(v + e, 0, series=True)):
            D[k][:, q, :] = np.nan_to_num((r.eps - base[k].eps) / h)
    M = np.zeros((U, U))
    for i, level in enumerate(levels):
        terms = _record_noise_terms(lik, v, i, level) if level else None
        if terms is None:
            continue
        forcing = (D[i] @ terms.Rinv) @ terms.C  # (N, U, n): (C^T R^-1 D_k)^T
        N = len(forcing)
        lam = np.zeros((N + 1, U, terms.F.shape[0]))  # lambda_k^T, lambda_N = 0
        for k in range(N - 1, 0, -1):
            lam[k] = lam[k + 1] @ terms.F + forcing[k]
        for name, sd in level.items():
            wt = -lam[1:N] @ terms.Bd[:, lik.s.inputs.index(name)]  # (N - 1, U)
            M += sd**2 * (wt.T @ wt)
    return M


def _result(structure, lik, sol, v, H, names, lo, hi, bnds, outputs, oe, start_cost, meat=None):
    P, Qg = lik.P, lik.Qg
    U = len(v)
    keep = _kept(lik, sol, v, lo, hi)
    held = [i for i in range(U) if i not in set(keep.tolist())]
    cov = np.full((U, U), np.nan)
    var = np.full(U, np.inf)
    if len(keep):
        Hk, bad = _finite_information(H[np.ix_(keep, keep)])
        ck, unresolved = _pinv_sym(Hk)
        if meat is not None:
            # an unknown whose input-noise term cannot be evaluated is not resolved either
            Mk = meat[np.ix_(keep, keep)]
            bad = bad | ~np.isfinite(Mk).all(axis=0)
            ck = ck + ck @ np.nan_to_num(Mk) @ ck
        unresolved = unresolved | bad
        vk = np.diag(ck).copy()
        vk[unresolved] = np.inf
        cov[np.ix_(keep, keep)] = ck
        var[keep] = vk
    sd = np.sqrt(np.maximum(var, 0.0))
    th = lik.theta(v)
    free = lik.free
    with np.errstate(invalid="ignore", divide="ignore"):
        dd = np.sqrt(np.maximum(np.diag(cov)[:P], 0.0))
        corr = cov[:P, :P] / np.outer(dd, dd)
    corr = np.where(np.isfinite(corr), corr, np.nan)
    for i in range(P):
        if np.isfinite(sd[i]) and sd[i] > 0:
            corr[i, i] = 1.0
        else:
            corr[i, :] = corr[:, i] = np.nan
    ci, sd_log = {}, {}
    for i, p in enumerate(free):
        lv = math.log(th[p])
        with np.errstate(over="ignore"):
            ci[p] = (float(np.exp(lv - pem.Z95 * sd[i])), float(np.exp(lv + pem.Z95 * sd[i])))
        sd_log[p] = float(sd[i])
    HP = H[:P, :P]
    if P and np.all(np.isfinite(HP)):
        ev = np.linalg.eigvalsh(HP)
        cond = float(math.sqrt(ev[-1] / ev[0])) if ev[0] > 0 else math.inf
    elif P:  # an information that cannot be evaluated conditions nothing
        cond = math.inf
    else:
        cond = 1.0
    noise_ci, noise_sd = {}, {}
    for i in range(P, lik.Qn):
        if i in held:
            continue
        with np.errstate(over="ignore"):
            noise_ci[names[i]] = (
                float(np.exp(v[i] - pem.Z95 * sd[i])),
                float(np.exp(v[i] + pem.Z95 * sd[i])),
            )
        noise_sd[names[i]] = float(sd[i])
    flags = common.fit_flags(sol, v, th, free, ci, corr, cond, bnds)
    prob = SimpleNamespace(
        P=Qg,
        exps=[d.e for d in lik.data],
        x0_free=[d.x0_free for d in lik.data],
        x0_range=[d.x0_range for d in lik.data],
        s=structure,
    )
    flags += common.x0_flags(prob, sol, v)
    bound_of = {fl.parameters[0]: fl for fl in flags if fl.code == "at_bound"}
    identified = {}
    for i, p in enumerate(free):
        at = None
        if p in bound_of:
            side = "lower" if abs(v[i] - lo[i]) <= abs(hi[i] - v[i]) else "upper"
            at = (side, bnds[p][0] if side == "lower" else bnds[p][1])
        identified[p] = pem.identification(th[p], ci[p], at)
    # the series at the optimum
    runs = lik.passes(v, 0, series=True)
    x0s = lik.x0s(v)
    simulated, residuals = [], []
    b = lik.offsets_of(v)
    for d, x0 in zip(lik.data, x0s, strict=True):
        sim = models.simulate(structure, th, d.e.u, d.e.dt, x0, lik.hold)
        res = np.full_like(sim, np.nan)
        for j, i in enumerate(lik.out_idx):
            res[:, i] = d.e.y[:, i] - b[j] - sim[:, i]
        simulated.append(sim)
        residuals.append(res)
    sigma, svar = lik.sigma(v), lik.meas_var(v)
    nll = float(sol.fun)
    offsets = {
        outputs[j]: {
            "value": float(v[lik.Qn + t]),
            "sd": float(sd[lik.Qn + t]),
            "prior_sd": float(lik.offset_sd[t]),
        }
        for t, j in enumerate(lik.offset_out)
    }
    return KalmanResult(
        structure=structure.name,
        theta={p: float(th[p]) for p in structure.parameters},
        free=free,
        fixed=dict(lik.fixed),
        ci95=ci,
        sd_log=sd_log,
        correlation=corr,
        cond=cond,
        flags=flags,
        cost=nll,
        n_obs=lik.n_obs,
        n_unknowns=U,
        success=bool(sol.success),
        message=str(sol.message),
        outputs=tuple(outputs),
        names=[d.e.name for d in lik.data],
        x0=x0s,
        simulated=simulated,
        residuals=residuals,
        sigma={s: float(sigma[i]) for i, s in enumerate(structure.states)},
        meas_var={o: float(svar[j]) for j, o in enumerate(outputs)},
        noise_ci95=noise_ci,
        noise_sd_log=noise_sd,
        noise_at_bound=tuple(names[i] for i in held),
        offsets=offsets,
        loglik=-nll,
        n_params=U,
        innovations=[r.eps for r in runs],
        innovation_var=[r.rvar for r in runs],
        one_step=[r.xp for r in runs],
        x0_estimated=[tuple(structure.states[i] for i in d.x0_free) for d in lik.data],
        dt=[float(d.e.dt) for d in lik.data],
        states=tuple(structure.states),
        identified=identified,
        unknowns=tuple(names),
        covariance_log=cov,
        x0_mode=lik.x0_mode,
        start_theta={p: float(oe.theta[p]) for p in structure.parameters},
        start_cost=float(start_cost),
        start_costs={"output_error": float(start_cost)},
        nfev=int(sol.nfev),
        njev=int(sol.njev),
    )
