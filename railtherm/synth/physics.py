"""The vehicle in the tunnel: system matrices, controllers and the exact simulation.

Physics: the generic balance eq. 1 around the two-capacity model, eqs. 7-8 / 14, states
x = [T, T_veh] (+ T_zone for ``poor_mixing``), inputs T_o and Q_H (eq. 3: heaters + fans (+ the
HVAC during pre-heating)) plus eq. 1's Q_aux when a deviation declares unlogged auxiliaries.
The linear part is simulated EXACTLY by zero-order hold (matrix exponential,
:func:`railtherm.estimation.models.discretize_zoh`) on the fine step ``fine_step_s`` with every
input held constant over a fine step; the controllers (tunnel temperature, HVAC pre-heating, heater
thermostat) act once per fine step. The one non-linear deviation (``temperature_dependent_k``)
freezes its extra loss per fine step.

Everything here lives on the fine grid; :mod:`railtherm.synth.logger` samples it on the logger
grid.
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

from railtherm.estimation.models import discretize_zoh, second_order
from railtherm.synth.campaign import _deviation


def _rngs(spec: dict):
    """Independent streams: instruments, tunnel, noise, dropouts."""
    return [np.random.default_rng(s) for s in np.random.SeedSequence(spec["seed"]).spawn(4)]


def meter_scale(spec: dict) -> float:
    """The calibration error common to a vehicle's power meters (heater groups and fans), a
    factor 1 + u N(0, 1) with u = ``power_meter.scale_u_rel``; drawn from a stream of its own
    (the fifth child of the vehicle's seed), so the other draws do not move with it."""
    u = float(spec["power_meter"].get("scale_u_rel", 0.0))
    rng = np.random.default_rng(np.random.SeedSequence(spec["seed"]).spawn(5)[4])
    return 1.0 + u * float(rng.normal())


def _instruments(spec: dict, rng) -> dict:
    """Per-vehicle realisation of the instruments (drawn in a fixed order)."""
    se = spec["sensors"]
    n_in = len(se["indoor"]["heights_m"])
    return {
        "indoor_offset": rng.normal(0, se["indoor"]["offset_sd_K"], n_in),
        "surface_offset": rng.normal(0, se["surface"]["offset_sd_K"], se["surface"]["n"]),
        "outdoor_offset": rng.normal(0, se["outdoor"]["offset_sd_K"], se["outdoor"]["n"]),
        "group_factor": 1 + rng.normal(0, spec["heaters"].get("tolerance_rel", 0.02), 64),
        "fan_factor": 1 + rng.normal(0, 0.03, 64),
        "hvac_bias": 1 + spec["hvac"].get("airflow_bias_sd", 0.08) * rng.normal(),
    }


def _system(spec: dict):
    """Continuous (A, B) with states [T, T_veh, T_zone] and inputs [T_o, Q into the air node].

    Without poor_mixing the zone state is absent (n = 2). body_to_outdoor adds K_o between
    T_veh and T_o; poor_mixing splits the air into a mixed part (1 - f) C and a zone f C coupled
    by K_zone, the zone losing a share g of kA.
    """
    tr = spec["truth"]
    kA, C, K, Cv = tr["kA"], tr["C"], tr["K_veh"], tr["C_veh"]
    A, B = second_order(kA, C, K, Cv)
    bo = _deviation(spec, "body_to_outdoor")
    if bo:
        A[1, 1] -= bo["K_o"] / Cv
        B[1, 0] += bo["K_o"] / Cv
    pm = _deviation(spec, "poor_mixing")
    if pm:
        f, g, Kz = pm["zone_fraction"], pm["zone_loss_fraction"], pm["K_zone"]
        Cm, Cz = (1 - f) * C, f * C
        A = np.array(
            [
                [-((1 - g) * kA + K + Kz) / Cm, K / Cm, Kz / Cm],
                [K / Cv, A[1, 1], 0.0],
                [Kz / Cz, 0.0, -(g * kA + Kz) / Cz],
            ]
        )
        B = np.array([[(1 - g) * kA / Cm, 1 / Cm], [B[1, 0], 0.0], [g * kA / Cz, 0.0]])
    return A, B


def _schedules(spec: dict, n_steps: int, dt: float):
    """Per fine step: mode (0 fixed, 1 HVAC pre-heating, 2 thermostat), fixed heater power,
    fan power, unlogged auxiliary power, tunnel setpoint."""
    p = spec["programme"]
    ph = p["phases_s"]
    t = np.arange(n_steps) * dt
    mode = np.zeros(n_steps, dtype=np.int8)
    q_fix = np.zeros(n_steps)
    fan_on = np.zeros(n_steps, dtype=bool)
    inst = spec["_inst"]
    groups = spec["heaters"]["power_W"] * inst["group_factor"][: spec["heaters"]["groups"]]
    if p["type"] == "existing":
        mode[(t >= ph["preheat"]) & (t < ph["kvalue"])] = 1
        mode[(t >= ph["kvalue"]) & (t < ph["cooldown"])] = 2
        fan_on[t >= ph["kvalue"]] = True
    else:
        base = groups[: p["base_groups"]].sum()
        up = groups[: p["base_groups"] + p["step_groups"]].sum()
        q_fix[:] = base
        q_fix[(t >= ph["step_up"]) & (t < ph["step_down"])] = up
        fan_on[:] = True
    fans = spec["fans"]["power_W"] * inst["fan_factor"][: spec["fans"]["n"]]
    q_fan = np.where(fan_on, fans.sum(), 0.0)
    q_aux = np.zeros(n_steps)
    ua = _deviation(spec, "unlogged_aux")
    if ua:
        for a, b in ua["on_h"]:
            q_aux[(t >= a * 3600) & (t < b * 3600)] += ua["power_W"]
    return mode, q_fix, q_fan, q_aux, groups, fans


def _tunnel(spec: dict, n: int, dt: float, rng) -> np.ndarray:
    """Tunnel air T_o per fine step: the tunnel controller's first-order lag to the setpoint
    plus an AR(1) fluctuation (the control loop's residual), starting settled."""
    tu = spec["tunnel"]
    sp = np.full(n, float(spec["programme"]["T_tunnel"]))
    a = math.exp(-dt / tu["lag_s"])
    lag = lagged(sp, a, 1 - a, before=sp[0])
    phi = math.exp(-dt / tu["correlation_s"])
    w = rng.normal(0, tu["fluctuation_sd_K"] * math.sqrt(1 - phi**2), n)
    w[0] = rng.normal(0, tu["fluctuation_sd_K"])
    ar = lagged(w, phi, 1.0)
    return lag + ar


def lagged(x: np.ndarray, a: float, gain: float, before: float = 0.0) -> np.ndarray:
    """y[n] = a y[n-1] + gain x[n] from y[-1] = ``before``: a first-order lag sampled at its
    step (a = exp(-dt / tau), gain 1 - a) or an AR(1) process (gain 1) driven by ``x``.

    Solved as the unit lower-bidiagonal system y[n] - a y[n-1] = gain x[n] by LAPACK's
    banded triangular solve (``dtbtrs``, forward substitution: the recursion itself), which
    needs no compiled loop of railtherm's: a job that synthesises a record loads neither
    numba nor scipy.signal for it."""
    from scipy.linalg.lapack import dtbtrs

    b = gain * np.asarray(x, dtype=float)
    b[0] += a * before
    bands = np.zeros((2, b.size))
    bands[1, :-1] = -a
    y, info = dtbtrs(bands, b, uplo="L", diag="U")
    if info != 0:
        raise ValueError(f"the lag's triangular solve failed (LAPACK info {info})")
    return y


def _run(spec: dict) -> dict:
    """Simulate on the fine grid; returns fine-step arrays (states at n dt, inputs over [n dt,
    (n+1) dt))."""
    dt = float(spec["fine_step_s"])
    t_end = spec["programme"]["phases_s"]["end"]
    N = int(round(t_end / dt))
    r_inst, r_tun, _, _ = _rngs(spec)
    spec = dict(spec, _inst=_instruments(spec, r_inst))
    A, B = _system(spec)
    ns = A.shape[0]
    Ad, Bd = discretize_zoh(A, B, dt)
    Ad3, Bd3 = np.zeros((3, 3)), np.zeros((3, 2))
    Ad3[:ns, :ns], Bd3[:ns] = Ad, Bd
    To = _tunnel(spec, N + 1, dt, r_tun)
    mode, q_fix, q_fan, q_aux, groups, _ = _schedules(spec, N + 1, dt)
    tr, p = spec["truth"], spec["programme"]
    tdk = _deviation(spec, "temperature_dependent_k")
    beta = tdk["beta_per_K"] if tdk else 0.0
    dT_ref = (p.get("T_setpoint", 0.0) - p["T_tunnel"]) if tdk else 0.0
    kA = tr["kA"]

    def q_nl(T, to):  # extra loss of k = k0 (1 + beta (T - T_o - dT_ref))
        return -kA * beta * (T - to - dT_ref) * (T - to)

    # initial state: steady at the initial inputs (fixed point for the non-linear loss)
    q0 = q_fix[0] + q_fan[0] + q_aux[0]
    x = np.linalg.solve(A, -B @ np.array([To[0], q0]))
    for _ in range(50 if beta else 0):
        x = np.linalg.solve(A, -B @ np.array([To[0], q0 + q_nl(x[0], To[0])]))
    us = _deviation(spec, "unsteady_start")
    if us:
        x[0] += us["dT_air_K"]
        x[1] += us["dT_body_K"]
        if ns == 3:
            x[2] += us["dT_air_K"]
    x0, x1, x2 = (float(v) for v in (*x, 0.0, 0.0)[:3])
    (a00, a01, a02), (a10, a11, a12), (a20, a21, a22) = Ad3.tolist()
    (b00, b01), (b10, b11), (b20, b21) = Bd3.tolist()
    cum = np.concatenate([[0.0], np.cumsum(groups)]).tolist()
    G = len(groups)
    he = spec["heaters"]
    Tset = p.get("T_setpoint", 0.0)
    lo, hi = Tset - he.get("hysteresis_K", 0.3), Tset + he.get("hysteresis_K", 0.3)
    dwell = he.get("dwell_s", 120.0)
    hv = spec["hvac"]
    hv_max, band, Tpre = hv.get("power_max_W", 0.0), hv.get("band_K", 2.0), p.get("T_preheat", 0)
    To_l, mode_l = To.tolist(), mode.tolist()
    qfix_l = q_fix.tolist()
    qext_l = (q_fan + q_aux).tolist()
    X0, X1, X2 = [x0] * (N + 1), [x1] * (N + 1), [x2] * (N + 1)
    QH, QV = [0.0] * (N + 1), [0.0] * (N + 1)
    n_on, since = 0, dwell
    for n in range(N):
        m = mode_l[n]
        if m == 2:  # staged thermostat: one group more/less per dwell time outside the band
            if since >= dwell:
                if x0 < lo and n_on < G:
                    n_on += 1
                    since = 0.0
                elif x0 > hi and n_on > 0:
                    n_on -= 1
                    since = 0.0
            since += dt
            qh, qv = cum[n_on], 0.0
        elif m == 1:  # HVAC pre-heating, proportional control towards T_preheat
            qv = hv_max * (Tpre - x0) / band
            qv = hv_max if qv > hv_max else (0.0 if qv < 0.0 else qv)
            qh = 0.0
        else:
            qh, qv = qfix_l[n], 0.0
        to = To_l[n]
        q = qh + qv + qext_l[n]
        if beta:
            q += q_nl(x0, to)
        x0, x1, x2 = (
            a00 * x0 + a01 * x1 + a02 * x2 + b00 * to + b01 * q,
            a10 * x0 + a11 * x1 + a12 * x2 + b10 * to + b11 * q,
            a20 * x0 + a21 * x1 + a22 * x2 + b20 * to + b21 * q,
        )
        X0[n + 1], X1[n + 1], X2[n + 1] = x0, x1, x2
        QH[n], QV[n] = qh, qv
    # inputs after the end (never used in the balance) repeat the last step
    QH[N], QV[N] = QH[N - 1], QV[N - 1]
    return {
        "spec": spec,
        "N": N,
        "dt": dt,
        "T": np.array(X0),
        "T_veh": np.array(X1),
        "T_zone": np.array(X2) if ns == 3 else None,
        "T_o": To,
        "Q_heat": np.array(QH),
        "Q_hvac": np.array(QV),
        "Q_fan": q_fan,
        "Q_aux": q_aux,
        "groups": groups,
    }


def _interval_mean(q: np.ndarray, m: int, n_samples: int) -> np.ndarray:
    """Mean over the logging interval [t - step, t) for each sample; before t = 0 the input is
    the initial one (the record starts in a held state)."""
    qp = np.concatenate([np.full(m, q[0]), q[: (n_samples - 1) * m]])
    return qp.reshape(n_samples, m).mean(axis=1)


_CACHE: dict[str, Any] = {}


def _run_cached(spec: dict) -> dict:
    """:func:`_run`, remembered for the last spec (a vehicle's files share one simulation)."""
    key = json.dumps(spec, sort_keys=True)
    if key not in _CACHE:
        _CACHE.clear()
        _CACHE[key] = _run(spec)
    return _CACHE[key]
