"""The Kalman filter of the stochastic grey-box model (:mod:`railtherm.estimation.kalman`):
its exact negative log-likelihood and gradient, in log parameters.

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
(:func:`stationary_covariance`; relative STEADY_TOL), the filter is the time-invariant
recursion x_{k+1} = F x_k + Bd u_k + L y_k (F = Ad - L C, L = Ad P C^T R^-1), run without a
Python loop by the modal recursions of :mod:`railtherm.estimation.models`.
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
lies on one.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy.linalg import cho_factor, cho_solve, solve_discrete_are, solve_discrete_lyapunov

from railtherm.estimation import common, models
from railtherm.estimation.common import Experiment
from railtherm.estimation.models import Structure

__all__ = [
    "COMPILED",
    "LOG_2PI",
    "Likelihood",
    "NotEvaluable",
    "negative_log_likelihood",
]

LOG_2PI = math.log(2.0 * math.pi)
STEADY_TOL = 1e-10  # |P_k - P| / |P| below which the filter switches to the stationary gain
# the compiled filter holds its gain once |P_k+1 - P_k| <= FREEZE_TOL |P_k+1| (and so for dP)
FREEZE_TOL = 1e-13
COMPILED = True  # False: the numpy filter (module docstring), the reference of the tests
# the stationary filter's Riccati equation by doubling: converged once a doubling moves P by at
# most RICCATI_TOL relative (the error then is of the order of its square); 100 doublings
# suffice for any closed-loop spectral radius below 1 - 1e-28, and QZ takes over otherwise
RICCATI_TOL = 1e-12
RICCATI_DOUBLINGS = 100
# a run that starts off the stationary covariance is done by the stationary filter with the
# exact correction for its prior (:func:`_prior_correction`) instead of row by row when it is
# the record's last run, or when its transient |F|^rows decays below this before a later run
JUMP_DECAY = 1e-18
PRIOR_CORRECTION = True  # False: every transient row by row (the reference the tests compare)
OFFSET_STEP = 1e-4  # K: central-difference step along an output offset

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
    one first-order recursion (:func:`railtherm.estimation.models.recursion`) per kept mode
    for all channels. A Kalman predictor's F = Ad - L C often has a complex pair where Ad has
    none. When V is ill-conditioned or the eigenvalues are repeated, the complex Schur form of
    :func:`railtherm.estimation.models.modal_form` is used instead (every mode, complex,
    weight 1: x = Re(sum of Q_i z_i))."""

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
                z[forced] = models.recursion(dtype(lam), f, z0[forced])
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
    _modes: _Modes | None = None
    _modes_T: _Modes | None = None

    @property
    def modes(self) -> _Modes:
        """The modes of F (the stationary recursion of the numpy implementation; the compiled
        filter, which only takes P from here as the prior, never builds them)."""
        if self._modes is None:
            self._modes = _Modes(self.F)
        return self._modes

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
                P = stationary_covariance(Ad, C, Qd, self.S[o])
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
        )


def stationary_covariance(Ad: np.ndarray, C: np.ndarray, Qd: np.ndarray, S: np.ndarray):
    """P of the stationary filter's Riccati equation P = Ad P Ad^T + Qd - Ad P C^T (C P C^T +
    diag(S))^-1 C P Ad^T: by doubling (:func:`railtherm.estimation.loops.riccati`, compiled,
    a few microseconds for a thermal network's states), or by
    ``scipy.linalg.solve_discrete_are`` (the QZ method) where doubling does not converge
    within ``RICCATI_DOUBLINGS``, meets a singular step, or a measurement variance is not
    positive."""
    S = np.asarray(S, dtype=float)
    if np.all(S > 0.0):
        from railtherm.estimation import loops  # numba: compiled on first use

        try:
            P, converged = loops.riccati(
                np.ascontiguousarray(Ad, dtype=float),
                np.ascontiguousarray(C, dtype=float),
                np.ascontiguousarray(Qd, dtype=float),
                np.ascontiguousarray(S),
                RICCATI_TOL,
                RICCATI_DOUBLINGS,
            )
        except np.linalg.LinAlgError:  # a singular doubling step: QZ below
            converged = False
        if converged:
            return P
    return solve_discrete_are(Ad.T, C.T, Qd, np.diag(S))


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
    ll: np.ndarray | None = None  # each row's log-likelihood term, N (NaN: none measured)
    steady_from: list[int] = field(default_factory=list)  # rows where a stationary run began


def _series_arrays(out: _Pass, N: int, n: int, n_out: int) -> None:
    """A pass's series, to be filled row by row (NaN where a row has no such value)."""
    out.xp = np.empty((N, n))
    out.eps = np.full((N, n_out), np.nan)
    out.rvar = np.full((N, n_out), np.nan)
    out.ll = np.full(N, np.nan)


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
        _series_arrays(out, N, n, n_out)
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
                term = 0.5 * (float(np.log(lam).sum()) + float(eps @ a) + len(o) * LOG_2PI)
                nll += term
                K = PCt @ Rinv
                KR = K @ R
                if series:
                    out.eps[k, o] = eps
                    out.rvar[k, o] = R.diagonal()
                    out.ll[k] = -term
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
    sensitivities dx_{j+1} = F dx_j + dF x_j + dBd u_j + dL y_j, each one modal recursion per
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


class Likelihood:
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
        self.hold = common.one_hold(experiments)
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

    def passes(
        self,
        v: np.ndarray,
        order: int,
        steady: bool = True,
        series: bool = False,
        compiled: bool | None = None,
    ):
        """One filter pass per experiment (list of _Pass; the x0 directions of each are its
        own, after the Qg global ones); ``compiled=False``: by the row loop of
        :func:`_filter` whatever :data:`COMPILED` says (its series hold each row's
        log-likelihood term, ``ll``, with ``steady=False``)."""
        systems: dict[float, _System] = {}
        out = []
        data = self.shifted(v)
        for d, x0 in zip(data, self.x0s(v, data), strict=True):
            if d.e.dt not in systems:
                systems[d.e.dt] = self.system(v, d.e.dt, order)
            sysm = systems[d.e.dt]
            Q = self.Qg + len(d.x0_free)
            x0, dx0, P0, dP0 = self._prior(sysm, d, x0, order, Q)
            run = _filter_rows if (COMPILED if compiled is None else compiled) else _filter
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
    outputs = common.compared_outputs(structure, experiments, outputs)
    out_idx = tuple(structure.states.index(o) for o in outputs)
    lik = Likelihood(
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
