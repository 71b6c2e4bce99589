"""The annual-energy step loop as railtherm ran it before it was compiled: one vectorised numpy
step over every run at a time (the engine of ``railtherm.study.energy`` up to 95d3bf5), with the
signature of :func:`railtherm.estimation.loops.heated_steps` so that
``energy.annual_energy(..., kernel=numpy_heated_steps)`` runs the same year through it.

benchmarks/bench_energy.py times both kernels on the same vehicle-year in one process and
checks that they give the same year; this file is the baseline, not part of the package.
"""

from __future__ import annotations

import numpy as np


def numpy_heated_steps(
    k_from, k_to, x, Ad, BdT, BdQ, BdI, gain_Q, door, T_o, gains, ghi, noise, Qchol,
    variant, draw, set_point, pre, service, until, waiting, started, back, Am,
    x_per_T_o, x_per_W, limit, month, unmet_K, G_out, door_W, energy, pre_J, peak, unmet,
    losses, accumulate,
):  # fmt: skip
    """Steps k_from..k_to-1 of every run together (see loops.heated_steps for the model)."""
    R, n = x.shape
    rows = np.arange(R)
    noisy = draw > 0
    horizon = Am.shape[0] > 1
    for k in range(k_from, k_to):
        g = door[k]
        free = np.einsum("rij,rj->ri", Ad[g], x)
        free += BdT[g] * T_o[k] + BdQ[g] * gains[k] + BdI[g] * ghi[k]
        if noise.shape[0] > 0:
            w = noise[k - k_from, np.maximum(draw - 1, 0)]
            free[noisy] += np.einsum("rij,rj->ri", Qchol[g][noisy], w[noisy])
        sp = set_point[variant, k]
        if horizon:
            if service[k]:
                started[:] = False
            else:
                window = pre[variant, k] & waiting
                if window.any():
                    m = np.maximum(until[variant, k] - 1, 0)
                    x_full = x_per_T_o * T_o[k] + x_per_W * limit
                    end = x_full[:, 0] + np.einsum("rj,rj->r", Am[m, rows, 0], x - x_full)
                    started |= window & (end < sp)
                    sp = np.where(window & ~started, back[variant], sp)
        q = np.clip((sp - free[:, 0]) / gain_Q[g], 0.0, limit)
        q = np.where(np.isnan(sp), 0.0, q)
        mean = (x + free + BdQ[g] * q[:, None]) / 2.0
        x[:] = free + BdQ[g] * q[:, None]
        if accumulate:
            losses[:, 0] += np.einsum("ri,ri->r", G_out, mean - T_o[k])
            losses[:, 1] += door_W[k] * (mean[:, 0] - T_o[k])
            energy[:, month[k]] += q
            pre_J += np.where(pre[variant, k], q, 0.0)
            c = 0 if service[k] else 1
            peak[:, c] = np.maximum(peak[:, c], q)
            if service[k]:
                unmet += x[:, 0] < sp - unmet_K
