"""The least-squares solver of the simulation-error PEM (:func:`railtherm.estimation.pem.fit`):
Levenberg-Marquardt on the p x p normal equations of a tall problem (few parameters, long
records), and the Gram matrix and singular values of a tall Jacobian it and the covariance
use."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

__all__ = ["gram", "levenberg_marquardt", "solution", "svd_tall"]


def levenberg_marquardt(residuals, jacobian, v0, max_nfev=None, tol=1e-8, reuse=1e-2):
    """Levenberg-Marquardt on the p x p normal equations of a tall least-squares problem.

    Minimises 0.5 r(v)^T r(v) for few unknowns p and many residuals m. Each iteration forms
    H = J^T J and g = J^T r once (O(m p^2)) and solves (H + mu diag(H)) step = -g (Marquardt's
    scaling); mu follows Nielsen's update (shrunk after a good step, doubled and doubling
    after a rejected one). It exists because ``scipy.optimize.least_squares`` costs 2-3 ms
    of its own work per fit at m = 2e4, p = 3 (an SVD or QR of the whole m x p Jacobian every
    iteration, Fortran-order copies): more than the simulations themselves
    (docs/performance.md). ``fit`` falls back to least_squares (trf, with bounds) whenever
    this one fails or leaves the bounds.

    After an accepted step smaller than ``reuse`` in every unknown (1 % in a log parameter),
    the Jacobian is kept for the next step (a chord step: J changes by O(step), the step's
    accuracy by O(step^2)); it is recomputed before any conclusion is drawn from it and after
    a rejected step. Near the optimum this saves one sensitivity computation per fit.

    Stops when the nearly undamped Gauss-Newton step predicts a relative reduction of the
    cost below ``tol`` (status 2), when an accepted step's actual and predicted relative
    reductions are both below ``tol`` (status 2, as MINPACK), when the step is below ``tol``
    relative to |v| (status 3), when the gradient is orthogonal to the residuals to within
    ``tol`` (status 1), or after ``max_nfev`` residual evaluations (default 100 p; status 0,
    not converged); every stop but the last with the Jacobian evaluated at the returned v.
    Returns an object with the fields of least_squares' result that :func:`fit` reads.
    """
    v = np.array(v0, dtype=float)
    p = len(v)
    max_nfev = 100 * max(p, 1) if max_nfev is None else int(max_nfev)
    r = residuals(v)
    nfev, njev = 1, 0
    cost = 0.5 * float(r @ r)
    if not math.isfinite(cost):
        return solution(v, r, 0, nfev, njev, "the residuals are not finite at the start", False)
    J, fresh = jacobian(v), True
    njev += 1
    mu, nu = 1e-3, 2.0
    status, message = 0, "the maximum number of function evaluations is exceeded"
    while nfev < max_nfev:
        JT = J.T
        H = gram(JT)
        g = JT @ r
        if not (math.isfinite(H.sum()) and math.isfinite(g.sum())):
            if fresh:
                message = "the Jacobian is not finite"
                break
            J, fresh = jacobian(v), True
            njev += 1
            continue
        d = H.diagonal().copy()
        # gradient test: the largest cosine between a column of J and r is
        # max |g_i| / (|J_i| |r|) (a zero column has g_i = 0)
        converged = float((g * g / np.maximum(d, 1e-300)).max()) <= tol * tol * 2.0 * cost
        if converged and fresh:
            status, message = 1, "the gradient is orthogonal to the residuals (gtol)"
            break
        d = np.maximum(d, 1e-12 * float(d.max()) + 1e-300)
        try:
            step = np.linalg.solve(H + np.diag(mu * d), -g)
        except np.linalg.LinAlgError:  # H singular and mu tiny: damp harder
            mu = max(mu * nu, 1e-12)
            nu *= 2.0
            continue
        predicted = -float(g @ step) - 0.5 * float(step @ H @ step)
        converged = converged or (0 <= predicted <= tol * cost and mu <= 1e-2)
        if converged:
            if fresh:  # the Gauss-Newton step promises a relative reduction below tol
                status, message = 2, "the predicted relative reduction of the cost is below ftol"
                break
            J, fresh = jacobian(v), True  # check with the Jacobian at v itself
            njev += 1
            continue
        trial = v + step
        r_trial = residuals(trial)
        nfev += 1
        with np.errstate(over="ignore", invalid="ignore"):  # a wild trial: rejected below
            cost_trial = 0.5 * float(r_trial @ r_trial)
        actual = cost - cost_trial if math.isfinite(cost_trial) else -math.inf
        small_step = math.sqrt(float(step @ step)) <= tol * (math.sqrt(float(v @ v)) + tol)
        if predicted > 0 and actual > 0:
            rho = actual / predicted
            mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
            nu = 2.0
            v, r, cost_old, cost = trial, r_trial, cost, cost_trial
            stop = small_step or (actual <= tol * cost_old and predicted <= tol * cost_old)
            if stop or float(np.abs(step).max()) >= reuse:
                J, fresh = jacobian(v), True
                njev += 1
            else:
                fresh = False
            if stop:
                status, message = (
                    (3, "the step is below xtol")
                    if small_step
                    else (2, "the relative reduction of the cost is below ftol")
                )
                break
        elif not fresh:  # the stale Jacobian misled the step: renew it before damping
            J, fresh = jacobian(v), True
            njev += 1
        else:
            if small_step or 0 <= predicted <= 1e-2 * tol * cost:
                # no descent left at rounding level: v is the optimum
                status, message = 3, "the step is below xtol"
                break
            mu *= nu
            nu *= 2.0
    return solution(v, r, status, nfev, njev, message, status > 0)


def gram(JT: np.ndarray) -> np.ndarray:
    """J^T J from JT (p x m, p small): one dot product per entry. For p <= ~10 and m ~ 1e4
    this is 2-5x faster than ``JT @ JT.T`` (OpenBLAS' gemm/syrk, single-threaded, on a 3 x
    2e4 by 2e4 x 3 product: 45 us against 115 us), and a fit forms it every iteration."""
    p, m = JT.shape
    if m < 2048:  # small: one BLAS call is cheaper than p(p+1)/2 Python-level dots
        return JT @ JT.T
    H = np.empty((p, p))
    for i in range(p):
        for j in range(i, p):
            H[i, j] = H[j, i] = JT[i] @ JT[j]
    return H


_EIGH_COND_MAX = 1e5  # cond(J) up to which its SVD is taken from the eigenproblem of J^T J


def svd_tall(J: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Singular values (descending) and right singular vectors (rows of Vt) of a tall J.

    From the eigendecomposition of J^T J when J is well conditioned (cond <= 1e5, where
    squaring the condition costs at most ~1e-6 relative accuracy in the smallest singular
    value), else exactly from the QR factor R of J (J = Q R, SVD of R): the QR of a 2e4 x 3 J
    costs as much as three simulations of the data, the small eigenproblem nothing."""
    if J.shape[0] > J.shape[1]:
        lam, V = np.linalg.eigh(gram(np.ascontiguousarray(J.T)))
        lam, V = lam[::-1], V[:, ::-1]
        if lam[-1] > 0 and lam[0] > 0 and lam[-1] >= lam[0] / _EIGH_COND_MAX**2:
            return np.sqrt(lam), V.T.copy()
        R = np.linalg.qr(J, mode="r")
    else:
        R = J
    _, s, Vt = np.linalg.svd(R, full_matrices=False)
    return s, Vt


def solution(v, r, status, nfev, njev, message, success):
    return SimpleNamespace(
        x=v,
        fun=r,
        status=status,
        success=success,
        nfev=nfev,
        njev=njev,
        message=message,
        active_mask=np.zeros(len(v), int),
    )
