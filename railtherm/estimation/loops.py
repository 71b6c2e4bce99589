"""Row recursions compiled with numba: the Kalman filter's with its forward sensitivities
(:func:`kalman_rows`), the simulation with its free response that ranks the output-error
start's grid inside a Kalman fit (:func:`output_error`), one mode's first-order recursion
that every modal simulation runs (:func:`first_order`), and the stationary filter's Riccati
equation by doubling (:func:`riccati`).

One pass of the predictor-form filter of :mod:`railtherm.estimation.kalman` over one
experiment: per row, the update with the measured outputs o (none: skipped),

    eps = y_o - C_o x,  R = C_o P C_o^T + S_o,  K = P C_o^T R^-1,
    x <- x + K eps,  P <- P - K R K^T,

then the prediction x <- Ad x + Bd u_k, P <- Ad P Ad^T + Qd, each differentiated along Q
directions (dAd, dBd, dQd, dS; dx0, dP0 for the initial state), which gives the negative
log-likelihood 1/2 sum_k (log det R_k + eps_k^T R_k^-1 eps_k + n_k log 2 pi) (eq. 17's
criterion with the innovations as eq. 18's prediction errors), its exact gradient and the
Fisher information

    dNLL_q = sum_k 1/2 tr(R^-1 dR_q) - 1/2 a^T dR_q a + deps_q^T a,   a = R^-1 eps,
    I_qr = sum_k deps_q^T R^-1 deps_r + 1/2 tr(R^-1 dR_q R^-1 dR_r).

Once a prediction leaves the predicted P and every dP_q unchanged from the row before
(relative ``freeze_tol``), the filter
has reached its stationary gain for the row's measurement pattern: K, R and their
derivatives are then held, and each further row of the same pattern costs only the state and
its sensitivities, until the pattern changes.

The loops are written out for the small matrices of a thermal network (a few states): that
is where a compiled loop beats a library call per 2 x 2 product. ``cache=True`` keeps the
machine code between processes.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

LOG_2PI = math.log(2.0 * math.pi)
RUNS_TOGETHER = 64  # heated_steps: runs advanced side by side (one vectorised loop each)


@njit(cache=True)
def riccati(Ad, C, Qd, S, tol, max_iter):
    """P of the filter's discrete algebraic Riccati equation

        P = Ad P Ad^T + Qd - Ad P C^T (C P C^T + diag(S))^-1 C P Ad^T

    (the predicted covariance of the stationary filter: ``scipy.linalg.solve_discrete_are(
    Ad.T, C.T, Qd, diag(S))``) by the structure-preserving doubling algorithm (Chu, Fan and
    Lin 2005): with A = Ad^T, G = C^T diag(S)^-1 C, H = Qd and W = I + G H,

        A <- A W^-1 A,  G <- G + A W^-1 G A^T,  H <- H + A^T H W^-1 A,

    H converges quadratically to P (the closed loop's spectral radius squared at each
    doubling). Returns (P, converged): converged is False when no doubling within
    ``max_iter`` moved H by less than ``tol`` relative, or a number went non-finite."""
    n = Ad.shape[0]
    A = Ad.T.copy()
    G = C.T @ np.diag(1.0 / S) @ C
    H = Qd.copy()
    eye = np.eye(n)
    for _ in range(max_iter):
        W = eye + G @ H
        WA = np.linalg.solve(W, A)
        WG = np.linalg.solve(W, G)
        H_next = H + A.T @ (H @ WA)
        H_next = (H_next + H_next.T) / 2.0
        G = G + A @ WG @ A.T
        G = (G + G.T) / 2.0
        A = A @ WA
        change = np.max(np.abs(H_next - H))
        H = H_next
        if not np.all(np.isfinite(H)):
            return H, False
        if change <= tol * np.max(np.abs(H)):
            return H, True
    return H, False


@njit(cache=True)
def first_order(lam, w, z0, z):
    """z[c, 0] = z0[c], z[c, n + 1] = lam z[c, n] + w[c, n] for every channel c (w[c, N - 1]
    is unused); real or complex, written into ``z`` (which may be ``w`` itself).

    The products and sums are those of ``scipy.signal.lfilter([0, 1], [1, -lam], w,
    zi=z0)`` (its direct form II transposed) in the same order, so the result is the same to
    the bit; a loop of one multiply-add per sample, without scipy.signal's second of import
    in every job that simulates."""
    C, N = w.shape
    for c in range(C):
        zn = z0[c]
        for n in range(N):
            wn = w[c, n]
            z[c, n] = zn
            zn = wn + lam * zn
    return z


@njit(cache=True)
def _predict(Ad, Bd, x, u, xn):
    """The state's one-step prediction in place, x <- Ad x + Bd u (xn a scratch vector)."""
    n = x.shape[0]
    for i in range(n):
        s = 0.0
        for t in range(n):
            s += Ad[i, t] * x[t]
        for t in range(Bd.shape[1]):
            s += Bd[i, t] * u[t]
        xn[i] = s
    for i in range(n):
        x[i] = xn[i]


@njit(cache=True)
def _gain(P, C, S, o, no, PCt, R, Lc, Li, Rinv, K):
    """The update's gain for the outputs o[:no]: PCt = P C_o^T, R = C_o PCt + S_o, its
    Cholesky factor Lc, Li = Lc^-1, R^-1 = Li^T Li and K = PCt R^-1, all in place. Returns
    log det R, or NaN when R is not positive definite."""
    n = P.shape[0]
    for i in range(n):
        for jj in range(no):
            s = 0.0
            for t in range(n):
                s += P[i, t] * C[o[jj], t]
            PCt[i, jj] = s
    for ii in range(no):
        for jj in range(no):
            s = 0.0
            for t in range(n):
                s += C[o[ii], t] * PCt[t, jj]
            R[ii, jj] = s
        R[ii, ii] += S[o[ii]]
    logdet = 0.0
    for ii in range(no):
        for jj in range(ii + 1):
            s = R[ii, jj]
            for t in range(jj):
                s -= Lc[ii, t] * Lc[jj, t]
            if ii == jj:
                if not s > 0.0:
                    return math.nan
                Lc[ii, ii] = math.sqrt(s)
                logdet += 2.0 * math.log(Lc[ii, ii])
            else:
                Lc[ii, jj] = s / Lc[jj, jj]
    for ii in range(no):  # Li = Lc^-1 (lower triangular)
        for jj in range(no):
            Li[ii, jj] = 0.0
        Li[ii, ii] = 1.0 / Lc[ii, ii]
        for jj in range(ii):
            s = 0.0
            for t in range(jj, ii):
                s -= Lc[ii, t] * Li[t, jj]
            Li[ii, jj] = s / Lc[ii, ii]
    for ii in range(no):  # R^-1 = Li^T Li
        for jj in range(no):
            s = 0.0
            for t in range(max(ii, jj), no):
                s += Li[t, ii] * Li[t, jj]
            Rinv[ii, jj] = s
    for i in range(n):
        for jj in range(no):
            s = 0.0
            for t in range(no):
                s += PCt[i, t] * Rinv[t, jj]
            K[i, jj] = s
    return logdet


@njit(cache=True)
def _gain_derivatives(dP, C, dS, o, no, Rinv, K, order, dPCt, dR, RdR, dK, g_const, f_const):
    """Along every direction q: dPCt = dP C_o^T, dR = C_o dPCt + dS_o, R^-1 dR (its half
    trace: the constant part of the row's gradient, g_const), dK = (dPCt - K dR) R^-1; with
    order 2 also f_const = 1/2 tr(R^-1 dR_q R^-1 dR_r) of the Fisher information."""
    Q, n = dP.shape[0], dP.shape[1]
    for q in range(Q):
        for i in range(n):
            for jj in range(no):
                s = 0.0
                for t in range(n):
                    s += dP[q, i, t] * C[o[jj], t]
                dPCt[q, i, jj] = s
        for ii in range(no):
            for jj in range(no):
                s = 0.0
                for t in range(n):
                    s += C[o[ii], t] * dPCt[q, t, jj]
                dR[q, ii, jj] = s
            dR[q, ii, ii] += dS[q, o[ii]]
        g = 0.0
        for ii in range(no):
            for jj in range(no):
                s = 0.0
                for t in range(no):
                    s += Rinv[ii, t] * dR[q, t, jj]
                RdR[q, ii, jj] = s
            g += RdR[q, ii, ii]
        g_const[q] = 0.5 * g
        # dK = (dPCt - K dR) R^-1
        for i in range(n):
            for jj in range(no):
                s = 0.0
                for t in range(no):
                    w = dPCt[q, i, t]
                    for r in range(no):
                        w -= K[i, r] * dR[q, r, t]
                    s += w * Rinv[t, jj]
                dK[q, i, jj] = s
    if order >= 2:
        for q in range(Q):
            for r in range(q + 1):
                s = 0.0
                for ii in range(no):
                    for jj in range(no):
                        s += RdR[q, ii, jj] * RdR[r, jj, ii]
                f_const[q, r] = 0.5 * s
                f_const[r, q] = 0.5 * s


@njit(cache=True)
def _scores(C, dx, o, no, a, dR, Rinv, g_const, f_const, order, de, Rde, grad, fisher):
    """The row's gradient dNLL_q = g_const_q + deps_q^T a - 1/2 a^T dR_q a (deps = -C_o dx,
    written to de) added to grad, and with order 2 its Fisher information added to fisher."""
    Q, n = dx.shape
    for q in range(Q):
        g = g_const[q]
        for ii in range(no):
            s = 0.0
            for t in range(n):
                s -= C[o[ii], t] * dx[q, t]
            de[q, ii] = s
            g += s * a[ii]
            w = 0.0
            for jj in range(no):
                w += dR[q, ii, jj] * a[jj]
            g -= 0.5 * a[ii] * w
        grad[q] += g
    if order >= 2:
        for q in range(Q):
            for ii in range(no):
                s = 0.0
                for jj in range(no):
                    s += Rinv[ii, jj] * de[q, jj]
                Rde[q, ii] = s
        for q in range(Q):
            for r in range(q + 1):
                s = f_const[q, r]
                for ii in range(no):
                    s += de[q, ii] * Rde[r, ii]
                fisher[q, r] += s
                if r != q:
                    fisher[r, q] += s


@njit(cache=True)
def _update_derivatives(no, eps, de, K, dK, dR, PCt, frozen, dx, dP):
    """dx += dK eps + K deps and, unless the gain is held, dP -= dK (K R)^T + (K R) dK^T +
    K dR K^T (K R = PCt), in place."""
    Q, n = dx.shape
    for q in range(Q):
        for i in range(n):
            s = 0.0
            for jj in range(no):
                s += dK[q, i, jj] * eps[jj] + K[i, jj] * de[q, jj]
            dx[q, i] += s
        if not frozen:
            for i in range(n):
                for t in range(i + 1):
                    s = 0.0
                    for jj in range(no):
                        s += dK[q, i, jj] * PCt[t, jj] + PCt[i, jj] * dK[q, t, jj]
                        w = 0.0
                        for r in range(no):
                            w += dR[q, jj, r] * K[t, r]
                        s += K[i, jj] * w
                    dP[q, i, t] -= s
                    if t != i:
                        dP[q, t, i] -= s


@njit(cache=True)
def _update(no, eps, K, PCt, frozen, x, P):
    """x += K eps and, unless the gain is held, P -= K PCt^T, in place."""
    n = x.shape[0]
    for i in range(n):
        s = 0.0
        for jj in range(no):
            s += K[i, jj] * eps[jj]
        x[i] += s
    if not frozen:
        for i in range(n):
            for t in range(i + 1):
                s = 0.0
                for jj in range(no):
                    s += K[i, jj] * PCt[t, jj]
                P[i, t] -= s
                if t != i:
                    P[t, i] -= s


@njit(cache=True)
def _predict_derivatives(Ad, dAd, dBd, x, u, dx, dxn):
    """dx <- Ad dx + dAd x + dBd u along every direction, in place (x that of the update)."""
    Q, n = dx.shape
    m = dBd.shape[2]
    for q in range(Q):
        for i in range(n):
            s = 0.0
            for t in range(n):
                s += Ad[i, t] * dx[q, t] + dAd[q, i, t] * x[t]
            for t in range(m):
                s += dBd[q, i, t] * u[t]
            dxn[q, i] = s
    for q in range(Q):
        for i in range(n):
            dx[q, i] = dxn[q, i]


@njit(cache=True)
def _predict_covariance(Ad, Qd, dAd, dQd, order, P, dP, Pp, dPp, AP, Pn, dPn):
    """P <- Ad P Ad^T + Qd and (order >= 1) dP <- (dAd P + Ad dP) Ad^T + Ad P dAd^T + dQd, in
    place. Returns how far each moved from the row's predicted Pp, dPp and their sizes
    (pchange, psize, change, size: the largest absolute entries), which decide the hold."""
    Q, n = dP.shape[0], P.shape[0]
    for i in range(n):  # Ad P
        for t in range(n):
            s = 0.0
            for r in range(n):
                s += Ad[i, r] * P[r, t]
            AP[i, t] = s
    change = 0.0
    size = 0.0
    if order >= 1:
        for q in range(Q):
            for i in range(n):
                for t in range(n):
                    s = 0.0
                    for r in range(n):
                        s += dAd[q, i, r] * P[r, t] + Ad[i, r] * dP[q, r, t]
                    Pn[i, t] = s
            for i in range(n):
                for t in range(i + 1):
                    s = dQd[q, i, t]
                    for r in range(n):
                        s += Pn[i, r] * Ad[t, r] + AP[i, r] * dAd[q, t, r]
                    dPn[q, i, t] = s
            for i in range(n):
                for t in range(i):
                    dPn[q, t, i] = dPn[q, i, t]
        for q in range(Q):
            for i in range(n):
                for t in range(n):
                    change = max(change, abs(dPn[q, i, t] - dPp[q, i, t]))
                    size = max(size, abs(dPn[q, i, t]))
                    dP[q, i, t] = dPn[q, i, t]
    pchange = 0.0
    psize = 0.0
    for i in range(n):
        for t in range(i + 1):
            s = Qd[i, t]
            w = Qd[t, i]
            for r in range(n):
                s += AP[i, r] * Ad[t, r]
                w += AP[t, r] * Ad[i, r]
            Pn[i, t] = 0.5 * (s + w)
            Pn[t, i] = Pn[i, t]
    for i in range(n):
        for t in range(n):
            pchange = max(pchange, abs(Pn[i, t] - Pp[i, t]))
            psize = max(psize, abs(Pn[i, t]))
            P[i, t] = Pn[i, t]
    return pchange, psize, change, size


@njit(cache=True)
def kalman_rows(
    Ad, Bd, Qd, C, S, dAd, dBd, dQd, dS, y, u, x0, dx0, P0, dP0,
    order, freeze_tol, xp, eps_out, rvar_out, steady_from,
):  # fmt: skip
    """The filter over the rows of y (N x n_out, NaN: not measured) driven by u (N x m).

    order 0: the NLL only; 1: and its gradient; 2: and the Fisher information. freeze_tol
    < 0: the time-varying filter on every row. xp (N x n), eps_out and rvar_out (N x n_out):
    filled with x_{k|k-1}, the innovations and the diagonal of R_k when they have rows (pass
    (0, .) arrays otherwise). steady_from (N,): the rows where a held gain began.

    Returns (status, nll, grad (Q,), fisher (Q, Q), count of steady_from); status 1: an
    innovation covariance that is not positive definite."""
    N, n_out = y.shape
    n = Ad.shape[0]
    Q = dAd.shape[0]
    series = xp.shape[0] > 0
    x, P, dx, dP = x0.copy(), P0.copy(), dx0.copy(), dP0.copy()
    xn, Pn, AP = np.empty(n), np.empty((n, n)), np.empty((n, n))
    dxn, dPn = np.empty((Q, n)), np.empty((Q, n, n))
    Pp, dPp = np.empty((n, n)), np.empty((Q, n, n))  # the row's predicted P, dP
    o = np.empty(n_out, np.int64)
    eps, a = np.empty(n_out), np.empty(n_out)
    PCt, K = np.empty((n, n_out)), np.empty((n, n_out))
    R, Lc = np.empty((n_out, n_out)), np.empty((n_out, n_out))
    Li, Rinv = np.empty((n_out, n_out)), np.empty((n_out, n_out))
    dPCt, dK = np.empty((Q, n, n_out)), np.empty((Q, n, n_out))
    dR, RdR = np.empty((Q, n_out, n_out)), np.empty((Q, n_out, n_out))
    de, Rde = np.empty((Q, n_out)), np.empty((Q, n_out))
    g_const, f_const = np.zeros(Q), np.zeros((Q, Q))
    grad, fisher = np.zeros(Q), np.zeros((Q, Q))
    nll = 0.0
    logdet = 0.0
    frozen = False
    prev_code = -1
    n_steady = 0
    for k in range(N):
        no = 0  # the row's measurement pattern
        code = 0
        for j in range(n_out):
            if not math.isnan(y[k, j]):
                o[no] = j
                no += 1
                code += 1 << j
        if code != prev_code:
            frozen = False
        prev_code = code
        if series:
            for i in range(n):
                xp[k, i] = x[i]
        if not frozen:
            Pp[:, :] = P
            dPp[:, :, :] = dP
        if no > 0:
            for jj in range(no):
                j = o[jj]
                s = y[k, j]
                for i in range(n):
                    s -= C[j, i] * x[i]
                eps[jj] = s
            if not frozen:
                logdet = _gain(P, C, S, o, no, PCt, R, Lc, Li, Rinv, K)
                if math.isnan(logdet):
                    return 1, math.inf, grad, fisher, n_steady
                if order >= 1:
                    _gain_derivatives(
                        dP, C, dS, o, no, Rinv, K, order, dPCt, dR, RdR, dK, g_const, f_const
                    )
            quad = 0.0
            for ii in range(no):
                s = 0.0
                for jj in range(no):
                    s += Rinv[ii, jj] * eps[jj]
                a[ii] = s
                quad += eps[ii] * s
            nll += 0.5 * (logdet + quad + no * LOG_2PI)
            if series:
                for jj in range(no):
                    eps_out[k, o[jj]] = eps[jj]
                    rvar_out[k, o[jj]] = R[jj, jj]
            if order >= 1:
                _scores(C, dx, o, no, a, dR, Rinv, g_const, f_const, order, de, Rde, grad, fisher)
                _update_derivatives(no, eps, de, K, dK, dR, PCt, frozen, dx, dP)
            _update(no, eps, K, PCt, frozen, x, P)
        # the prediction, differentiated (with x and P of the update)
        if order >= 1:
            _predict_derivatives(Ad, dAd, dBd, x, u[k], dx, dxn)
        _predict(Ad, Bd, x, u[k], xn)
        if frozen:
            continue
        pchange, psize, change, size = _predict_covariance(
            Ad, Qd, dAd, dQd, order, P, dP, Pp, dPp, AP, Pn, dPn
        )
        if (
            freeze_tol >= 0.0
            and k + 1 < N
            and pchange <= freeze_tol * psize
            and change <= freeze_tol * size
        ):
            frozen = True
            steady_from[n_steady] = k + 1
            n_steady += 1
    return 0, nll, grad, fisher, n_steady


@njit(cache=True)
def output_error(Ad, Bd, uT, x0, free, out_idx, yT, pos, m, cut):
    """The simulation x[k+1] = Ad x[k] + Bd u[k] from x0 (uT: m_u x N) and its free response
    to the initial states ``free`` (Ad^k e_i, entries below ``cut`` taken as 0: never computed
    into subnormal floats), read at the compared samples: pos (n_out, N) is each sample's
    place in the residual vector (-1: not compared) for the outputs out_idx.

    Returns e (m,) = x - y and G (m, len(free)) = d e / d x0[free]."""
    n = Ad.shape[0]
    N = uT.shape[1]
    nf = free.shape[0]
    no = out_idx.shape[0]
    x = x0.copy()
    xn = np.empty(n)
    z = np.zeros((nf, n))
    zn = np.empty((nf, n))
    for c in range(nf):
        z[c, free[c]] = 1.0
    e = np.empty(m)
    G = np.empty((m, nf))
    for k in range(N):
        for j in range(no):
            p = pos[j, k]
            if p >= 0:
                i = out_idx[j]
                e[p] = x[i] - yT[i, k]
                for c in range(nf):
                    G[p, c] = z[c, i]
        _predict(Ad, Bd, x, uT[:, k], xn)
        for c in range(nf):
            for i in range(n):
                s = 0.0
                for t in range(n):
                    s += Ad[i, t] * z[c, t]
                zn[c, i] = s if abs(s) >= cut else 0.0
            for i in range(n):
                z[c, i] = zn[c, i]
    return e, G


@njit(cache=True)
def heated_steps(
    k_from, k_to, x, Ad, BdT, BdQ, BdI, gain_Q, door, T_o, gains, ghi, noise, Qchol,
    variant, draw, set_point, pre, service, until, waiting, started, back, Am,
    x_per_T_o, x_per_W, limit, month, unmet_K, G_out, door_W, energy, pre_J, peak, unmet,
    losses, accumulate,
):  # fmt: skip
    """Steps k_from..k_to-1 of runs heated to a set point, every run r (its variant
    variant[r], its parameter draw draw[r]) advanced in place in x (R x n): per step k the
    free response free = Ad[g] x + BdT[g] T_o[k] + BdQ[g] gains[k] + BdI[g] ghi[k] (+ the
    draw's process noise Qchol[g] w, w = noise[k - k_from, draw - 1]; the central run, draw
    0, none) with g = door[k], then the heating q = clip((sp - free_air) / gain_Q[g], 0,
    limit) that brings the air (state 0) to the set point sp over the step (0 W where sp is
    NaN: heating off), and x = free + BdQ[g] q.

    "Ready by" (Am with more than one power, waiting[r]): in a run's pre-heating window it
    holds its set-back back[variant] until heating at the limit from the present state
    would just reach the set point at the service start (Am[m] = Ad^m of the closed step
    over the m steps left, T_o held: x_per_T_o, x_per_W the full-power equilibrium per
    kelvin and per watt), then heats (started[r]); a service step resets every run.

    With ``accumulate``: the heat per month (energy, summed q), in the pre-heating window
    (pre_J), its peak in service (peak[r, 0]) and outside service (peak[r, 1]: pre-heating
    and stabling; NaN once a q is NaN, as numpy.maximum), the service steps more than
    unmet_K below the set point (unmet), and the losses to the outside (W summed over the
    steps, each at the mean of the step's first and last state): through the envelope
    (losses[r, 0], sum_i G_out[r, i] (x_i - T_o)) and through the open door (losses[r, 1],
    door_W[k] (x_0 - T_o)).

    The runs are independent: RUNS_TOGETHER of them at a time are taken through the steps,
    their coefficients, states and sums copied side by side (the run the last index), so
    that each operation of a step is one loop over the block that the compiler vectorises;
    per run the same arithmetic in the same order as one run at a time (the same bits)."""
    R, n = x.shape
    with_noise = noise.shape[0] > 0
    horizon = Am.shape[0] > 1
    free = np.empty((n, RUNS_TOGETHER))
    w = np.empty(RUNS_TOGETHER)
    sp = np.empty(RUNS_TOGETHER)
    q = np.empty(RUNS_TOGETHER)
    for r0 in range(0, R, RUNS_TOGETHER):
        r1 = min(r0 + RUNS_TOGETHER, R)
        nb = r1 - r0
        # the block's runs side by side: the run the last (contiguous) index
        A = np.ascontiguousarray(Ad[:, r0:r1].transpose(0, 2, 3, 1))
        Qc = np.ascontiguousarray(Qchol[:, r0:r1].transpose(0, 2, 3, 1))
        for b in range(nb):
            if draw[r0 + b] == 0:  # the central run: no process noise
                Qc[:, :, :, b] = 0.0
        bT = np.ascontiguousarray(BdT[:, r0:r1].transpose(0, 2, 1))
        bQ = np.ascontiguousarray(BdQ[:, r0:r1].transpose(0, 2, 1))
        bI = np.ascontiguousarray(BdI[:, r0:r1].transpose(0, 2, 1))
        gQ = np.ascontiguousarray(gain_Q[:, r0:r1])
        xs = np.ascontiguousarray(x[r0:r1].T)
        months = np.ascontiguousarray(energy[r0:r1].T)
        # pre-heating, peak in service, peak outside it, unmet, envelope and door losses
        sums = np.empty((6, nb))
        sums[0] = pre_J[r0:r1]
        sums[1] = peak[r0:r1, 0]
        sums[2] = peak[r0:r1, 1]
        sums[3] = unmet[r0:r1]
        sums[4] = losses[r0:r1, 0]
        sums[5] = losses[r0:r1, 1]
        G = np.ascontiguousarray(G_out[r0:r1].T)
        ready = started[r0:r1].copy()
        v0 = variant[r0]
        one_variant = variant[r1 - 1] == v0
        for k in range(k_from, k_to):
            g = door[k]
            in_service = service[k]
            T_o_k = T_o[k]
            _free_response(free, xs, A, bT, bQ, bI, g, T_o_k, gains[k], ghi[k], nb)
            if with_noise:
                _add_noise(free, Qc, g, noise, k - k_from, draw, r0, nb, w)
            if one_variant:
                sp[:nb] = set_point[v0, k]
            else:
                for b in range(nb):
                    sp[b] = set_point[variant[r0 + b], k]
            if horizon and in_service:
                ready[:] = False
            elif horizon:
                _wait_or_heat(
                    k, r0, nb, xs, sp, ready, T_o_k, variant, pre, waiting, until, back, Am,
                    x_per_T_o, x_per_W, limit,
                )  # fmt: skip
            for b in range(nb):
                h = (sp[b] - free[0, b]) / gQ[g, b]
                h = 0.0 if h < 0.0 else h
                h = limit if h > limit else h
                q[b] = 0.0 if sp[b] != sp[b] else h  # heating off
            if accumulate:  # the losses at the step's first state, halved
                _losses(sums, G, xs, door_W[k], 0.0, nb)
            for i in range(n):
                for b in range(nb):
                    xs[i, b] = free[i, b] + bQ[g, i, b] * q[b]
            if accumulate:
                _losses(sums, G, xs, door_W[k], T_o_k, nb)
                for b in range(nb):
                    months[month[k], b] += q[b]
                _sums(
                    sums, q, xs, sp, k, r0, nb, in_service, one_variant, v0, variant, pre, unmet_K
                )
        x[r0:r1] = xs.T
        energy[r0:r1] = months.T
        started[r0:r1] = ready
        pre_J[r0:r1] = sums[0]
        peak[r0:r1, 0] = sums[1]
        peak[r0:r1, 1] = sums[2]
        unmet[r0:r1] = sums[3]
        losses[r0:r1, 0] = sums[4]
        losses[r0:r1, 1] = sums[5]


@njit(cache=True)
def _wait_or_heat(
    k, r0, nb, xs, sp, ready, T_o_k, variant, pre, waiting, until, back, Am, x_per_T_o,
    x_per_W, limit,
):  # fmt: skip
    """ "Ready by" for the block of runs r0..r0+nb-1 at step k (:func:`heated_steps`): a run in
    its pre-heating window that has not started keeps its set-back (sp[b] = back[variant])
    until heating at the limit from its state xs[:, b] would just reach the set point at
    the service start."""
    n = xs.shape[0]
    for b in range(nb):
        r = r0 + b
        v = variant[r]
        if not (pre[v, k] and waiting[r]):
            continue
        m = max(until[v, k] - 1, 0)  # heating from the next step on
        end = x_per_T_o[r, 0] * T_o_k + x_per_W[r, 0] * limit
        for j in range(n):
            xd = xs[j, b] - (x_per_T_o[r, j] * T_o_k + x_per_W[r, j] * limit)
            end += Am[m, r, 0, j] * xd
        if end < sp[b]:
            ready[b] = True
        if not ready[b]:
            sp[b] = back[v]


@njit(cache=True)
def _free_response(free, xs, A, bT, bQ, bI, g, T_o_k, gains_k, ghi_k, nb):
    """free = A[g] x + bT[g] T_o + bQ[g] gains + bI[g] ghi for runs 0..nb-1 of a block (the run
    the last index, :func:`heated_steps`), summed in that order."""
    n = xs.shape[0]
    for i in range(n):
        for b in range(nb):
            free[i, b] = 0.0
        for j in range(n):
            for b in range(nb):
                free[i, b] += A[g, i, j, b] * xs[j, b]
        for b in range(nb):
            free[i, b] += bT[g, i, b] * T_o_k
        for b in range(nb):
            free[i, b] += bQ[g, i, b] * gains_k
        for b in range(nb):
            free[i, b] += bI[g, i, b] * ghi_k


@njit(cache=True)
def _add_noise(free, Qc, g, noise, k, draw, r0, nb, w):
    """free += Qc[g] w, w the standard normals of block step k of each run's draw
    (noise[k, draw - 1];
    Qc is 0 for the central run, draw 0), for a block of runs (:func:`heated_steps`)."""
    n = free.shape[0]
    for i in range(n):
        for b in range(nb):
            w[b] = 0.0
        for j in range(n):
            for b in range(nb):
                w[b] += Qc[g, i, j, b] * noise[k, max(draw[r0 + b] - 1, 0), j]
        for b in range(nb):
            free[i, b] += w[b]


@njit(cache=True)
def _losses(sums, G, xs, door_W_k, T_o_k, nb):
    """Half of a step's losses at the state xs (:func:`heated_steps`): sums[4] += sum_i G[i]
    (xs_i / 2 - T_o_k), sums[5] += door_W_k (xs_0 / 2 - T_o_k); called with the step's first
    state and T_o_k = 0, then with its last state and the step's T_o, it adds the losses at
    the step's mean state."""
    n = xs.shape[0]
    for i in range(n):
        for b in range(nb):
            sums[4, b] += G[i, b] * (0.5 * xs[i, b] - T_o_k)
    for b in range(nb):
        sums[5, b] += door_W_k * (0.5 * xs[0, b] - T_o_k)


@njit(cache=True)
def _sums(sums, q, xs, sp, k, r0, nb, in_service, one_variant, v0, variant, pre, unmet_K):
    """A step's heating q into a block's sums (:func:`heated_steps`): pre-heating (row 0),
    the peak in service (1) or outside it (2; NaN once a q is NaN), the unmet steps (3)."""
    if one_variant and pre[v0, k]:
        for b in range(nb):
            sums[0, b] += q[b]
    elif not one_variant:
        for b in range(nb):
            if pre[variant[r0 + b], k]:
                sums[0, b] += q[b]
    c = 1 if in_service else 2
    for b in range(nb):
        p = sums[c, b]
        sums[c, b] = q[b] if (q[b] > p or q[b] != q[b]) else p
    if in_service:
        for b in range(nb):
            sums[3, b] += 1.0 if xs[0, b] < sp[b] - unmet_K else 0.0
