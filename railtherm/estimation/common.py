"""What the two estimators share (:mod:`railtherm.estimation.pem`, output error, and
:mod:`railtherm.estimation.kalman`, the Kalman filter's likelihood): the record they fit
(:class:`Experiment`), the bounds of an estimated initial state (:func:`measured_range`), the
input hold of a fit (:func:`one_hold`), the declared white noise on the measured inputs
(:func:`noise_levels`), the identifiability flags of an estimate (:func:`fit_flags`,
:func:`x0_flags`) with their thresholds, what the data determine of a parameter
(:func:`identification`), and the guard that keeps BLAS on one thread during a fit
(:func:`single_threaded_blas`)."""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from threadpoolctl import ThreadpoolController

from railtherm.estimation import models
from railtherm.estimation.estimate import Flag, Identification

__all__ = [
    "Experiment",
    "fit_flags",
    "identification",
    "measured_range",
    "noise_levels",
    "one_hold",
    "single_threaded_blas",
    "x0_flags",
]


Z95 = 1.959963984540054

WIDE_RATIO = 10.0

UNBOUNDED_FACTOR = 1e3  # an interval wider than this in total (hi / lo): not an estimate

CORR_MAX = 0.95

COND_MAX = 1e8

NULL_REL = 1e-13  # singular values below this (relative) span unidentifiable directions

# An estimated initial state lies within the window's measured temperatures (every measured
# state and T_o) widened by this margin: a start far outside them is a hidden heat source.
X0_MARGIN_K = 10.0

X0_AT_BOUND_K = 1e-3  # an estimated initial state this close to its bound sits at it


@dataclass
class Experiment:
    """One record: ``u`` N x m in the structure's input order, [T_o, Q_H] then any further
    inputs such as irradiance, ``y`` N x n_states in the structure's state order (NaN = not
    measured / not used), ``x0`` the measured initial state (NaN entries are estimated) or
    None (the first row of ``y``). ``hold``: how the inputs run between samples,
    "zero_order" (u[n] held over [t_n, t_n + dt), eq. 15) or "first_order" (u[n] the value
    at t_n, linear to u[n+1]; :mod:`railtherm.estimation.models`)."""

    name: str
    dt: float
    u: np.ndarray
    y: np.ndarray
    x0: np.ndarray | None = None
    hold: str = "zero_order"

    @property
    def forcing(self) -> np.ndarray:
        """The rows the discrete model multiplies by Bd
        (:func:`railtherm.estimation.models.forcing`)."""
        return models.forcing(self.u, self.hold)

    @property
    def step_u(self) -> np.ndarray:
        """Each input's mean over [t_n, t_n + dt)
        (:func:`railtherm.estimation.models.step_means`)."""
        return models.step_means(self.u, self.hold)

    def __post_init__(self):
        models.check_hold(self.hold)
        self.u = np.asarray(self.u, dtype=float)
        self.y = np.asarray(self.y, dtype=float)
        if self.y.ndim == 1:
            self.y = self.y[:, None]
        if self.x0 is not None:
            self.x0 = np.asarray(self.x0, dtype=float).reshape(-1)
        if self.u.ndim != 2 or self.u.shape[1] < 2 or len(self.u) != len(self.y):
            raise ValueError(
                f"experiment {self.name!r}: u must be N x m with m >= 2 (T_o, Q_H, then any "
                f"further inputs) and y N x n, got {self.u.shape}, {self.y.shape}"
            )
        if not (self.dt > 0):
            raise ValueError(f"experiment {self.name!r}: dt must be > 0, got {self.dt}")


def measured_range(e: Experiment) -> tuple[float, float]:
    """The bounds of an estimated initial state of ``e``: the lowest and highest measured
    temperature of the window (every measured state and T_o) widened by X0_MARGIN_K. A state
    far outside every temperature of the record is a hidden heat source or sink (a body
    starting at thousands of degC that heats the air for days), not a thermal state."""
    temperatures = np.concatenate([e.y[np.isfinite(e.y)], e.u[np.isfinite(e.u[:, 0]), 0]])
    if not temperatures.size:
        return -np.inf, np.inf
    return (
        float(temperatures.min()) - X0_MARGIN_K,
        float(temperatures.max()) + X0_MARGIN_K,
    )


def one_hold(experiments: Sequence[Experiment]) -> str:
    """The input hold every experiment of a fit shares (one discretisation per step length)."""
    holds = sorted({e.hold for e in experiments})
    if len(holds) > 1:
        raise ValueError(
            "the experiments of one fit must share one input hold, got "
            + ", ".join(f"{e.name!r}: {e.hold}" for e in experiments)
        )
    return holds[0] if holds else "zero_order"


def compared_outputs(structure, experiments: Sequence[Experiment], outputs=None) -> tuple[str, ...]:
    """The states an estimator compares: ``outputs``, or every state with a finite
    measurement in some experiment; each a state of the structure (else ValueError)."""
    n = len(structure.states)
    if outputs is None:
        outputs = tuple(
            s
            for i, s in enumerate(structure.states)
            if any(np.isfinite(e.y[:, i]).any() for e in experiments if e.y.shape[1] == n)
        )
    outputs = tuple(outputs)
    bad = [s for s in outputs if s not in structure.states]
    if bad or not outputs:
        raise ValueError(f"outputs {outputs} must be states of {structure.name}")
    return outputs


def noise_levels(structure, input_noise, experiments) -> list[dict[str, float]]:
    """Per experiment, {input name: sd} of the declared white input noise (those > 0)."""
    n_experiments = len(experiments)
    unknown = [n for n in input_noise if n not in structure.inputs]
    if unknown:
        raise ValueError(f"input_noise {unknown} not in the inputs {structure.inputs}")
    levels: list[dict[str, float]] = [{} for _ in range(n_experiments)]
    for name, sd in input_noise.items():
        values = [sd] * n_experiments if np.ndim(sd) == 0 else list(sd)
        if len(values) != n_experiments:
            raise ValueError(
                f"input_noise {name!r}: {len(values)} values for {n_experiments} experiments"
            )
        for level, value in zip(levels, values, strict=True):
            if not (math.isfinite(float(value)) and float(value) >= 0):
                raise ValueError(f"input_noise {name!r}: an sd must be >= 0, got {value}")
            if float(value) > 0:
                level[name] = float(value)
    held = [e.name for e, level in zip(experiments, levels, strict=True) if level]
    if held and one_hold(experiments) != "zero_order":
        raise ValueError(
            f"input_noise is modelled for the zero-order hold (white noise on each held step "
            f"input); experiments {held} use the first-order hold, where a noisy sample enters "
            f"two steps: fit them with hold zero_order, or without input_noise"
        )
    return levels


@functools.cache
def _blas_controller() -> ThreadpoolController:
    return ThreadpoolController()  # inspects the loaded BLAS libraries once per process


def single_threaded_blas(function):
    """Run ``function`` with BLAS limited to one thread: the matrices of a fit are tiny (4x4
    exponentials) or tall and thin, and idle BLAS threads spinning on a loaded 2-core machine
    cost 10x (an N = 1e4 fit: 230 ms with them, 15 ms without)."""

    @functools.wraps(function)
    def limited(*args, **kwargs):
        with _blas_controller().limit(limits=1, user_api="blas"):
            return function(*args, **kwargs)

    return limited


def identification(
    value: float,
    ci95: tuple[float, float],
    at_bound: tuple[str, float] | tuple[str, float, str] | None = None,
) -> Identification:
    """Whether the data determine a parameter, and what they do say when they do not.

    Not identified: the estimate sits at a bound of the search (``at_bound`` = (side, bound)
    or (side, bound, what the bound is): the optimum may lie beyond it), or its combined
    95 % interval spans more than a factor ``UNBOUNDED_FACTOR`` in total (hi / lo > 1000, or
    an end that is 0 or infinite). A search bound is no information from the data, so an
    estimate at one has no limit (``limit: none``). Only an interval open on one side leaves
    a one-sided limit the data give: open above, its lower end ("at least", ``limit:
    lower``); open below, its upper end ("at most", ``limit: upper``). An interval finite on
    both sides but too wide, or open on both, gives none. Returns the :class:`Identification`,
    read as ``{"identified": True}`` or ``{"identified": False, "limit": "upper" | "lower" |
    "none", "limit_value": float | None, "reason": str}`` (and ``at_bound``)."""
    if at_bound is not None:
        side, bound = at_bound[0], float(at_bound[1])
        what = at_bound[2] if len(at_bound) > 2 else ""
        where = (
            f"its physical {side} bound ({what} = {bound:.3g})"
            if what
            else (f"its {side} search bound {bound:.3g}, not a limit the data give")
        )
        return Identification(False, "none", None, side, f"at {where}")
    lo, hi = (float(c) for c in ci95)
    factor = UNBOUNDED_FACTOR
    open_lo = not (math.isfinite(lo) and lo > 0)
    open_hi = not math.isfinite(hi)
    if not (open_lo or open_hi) and hi / lo <= factor:
        return Identification(True)
    if open_lo and open_hi:
        limit, limit_value, why = "none", None, "unbounded both ways"
    elif open_hi:
        limit, limit_value, why = "lower", lo, "unbounded above"
    elif open_lo:
        limit, limit_value, why = "upper", hi, "unbounded below"
    else:
        limit, limit_value = "none", None
        why = f"spans a factor {hi / lo:.4g} ({lo:.3g} to {hi:.3g})"
    reason = f"95 % interval {why}, more than a factor {factor:g} in total"
    return Identification(False, limit, limit_value, None, reason)


def x0_flags(prob: Any, sol, v: np.ndarray) -> list[Flag]:
    """``x0_at_bound``: an estimated initial state at the bound of its window's measured
    temperatures widened by X0_MARGIN_K (within X0_AT_BOUND_K, or active in the bounded
    solve). The data then ask for a state beyond any measured temperature - a hidden heat
    source or sink that the model lacks - and the parameters fitted with it are in doubt."""
    flags = []
    k = prob.P
    for e, fr, (lo, hi) in zip(prob.exps, prob.x0_free, prob.x0_range, strict=True):
        for j in fr:
            x, active = float(v[k]), int(sol.active_mask[k]) if len(sol.active_mask) > k else 0
            at_lo = x - lo <= X0_AT_BOUND_K or active < 0
            at_hi = hi - x <= X0_AT_BOUND_K or active > 0
            if at_lo or at_hi:
                state = prob.s.states[j]
                side = "lower" if at_lo else "upper"
                flags.append(
                    Flag(
                        "x0_at_bound",
                        (state,),
                        f"the estimated initial {state} of {e.name!r}, {x:.4g} degC, sits at "
                        f"its {side} bound: the window's measured temperatures "
                        f"({lo + X0_MARGIN_K:.4g} to {hi - X0_MARGIN_K:.4g} degC) widened by "
                        f"{X0_MARGIN_K:g} K. The data ask for a start beyond any measured "
                        "temperature, a hidden heat source or sink the model lacks, and the "
                        "parameters fitted with it are in doubt",
                    )
                )
            k += 1
    return flags


def fit_flags(sol, v, th, free, ci, corr, cond, bnds) -> list[Flag]:
    flags = []
    for p in free:
        lo, hi = ci[p]
        ratio = hi / lo if lo > 0 else math.inf
        if not ratio <= WIDE_RATIO:
            flags.append(
                Flag(
                    "wide_interval",
                    (p,),
                    f"the 95 % interval of {p} spans more than a decade "
                    f"({lo:.3g} to {hi:.3g}): the data hardly determine it",
                )
            )
    for i, p in enumerate(free):
        lo_b, hi_b = bnds[p]
        at_lo = lo_b > 0 and abs(v[i] - math.log(lo_b)) < 1e-4
        at_hi = np.isfinite(hi_b) and abs(math.log(hi_b) - v[i]) < 1e-4
        if at_lo or at_hi or (sol.active_mask[i] != 0):
            which = "lower" if (at_lo or sol.active_mask[i] < 0) else "upper"
            flags.append(
                Flag(
                    "at_bound",
                    (p,),
                    f"{p} = {th[p]:.4g} sits at its {which} bound "
                    f"({bnds[p][0]:.3g}, {bnds[p][1]:.3g}): the optimum may lie beyond it",
                )
            )
    for i in range(len(free)):
        for j in range(i + 1, len(free)):
            c = corr[i, j]
            if np.isfinite(c) and abs(c) > CORR_MAX:
                flags.append(
                    Flag(
                        "high_correlation",
                        (free[i], free[j]),
                        f"{free[i]} and {free[j]} are correlated ({c:+.3f}): the data "
                        "determine a combination of them rather than each",
                    )
                )
    if not cond <= COND_MAX:
        flags.append(
            Flag(
                "ill_conditioned",
                tuple(free),
                f"the Jacobian is ill-conditioned (condition number {cond:.3g} > {COND_MAX:.0e}): "
                "some parameter combination barely changes the simulated outputs, so the data "
                "cannot determine it",
            )
        )
    if not sol.success or sol.status == 0:
        flags.append(
            Flag(
                "not_converged",
                tuple(free),
                f"the optimiser did not converge ({sol.message}); the estimate is not an optimum",
            )
        )
    return flags


def heat_balance_kA(experiments: Sequence[Experiment]) -> float:
    """The overall heat-loss coefficient from the heat balance of the records (the idea of
    eq. 10 applied to the identification windows, which need not be steady): the heat
    supplied up to each time t against the losses and the air node's storage,

        integral_0^t Q_H dt = kA integral_0^t (T - T_o) dt + C_bar (T(t) - T(0)),

    by least squares over every t of every window (T interpolated over missing rows). On a
    steady window the storage term vanishes and this is eq. 10: kA = mean Q_H / mean
    (T - T_o). Heat going into an unmeasured body and unmodelled gains still bias it; as
    the centre of a start grid it need only be right to a factor of a few. NaN when the
    records give no positive kA (no heated record)."""
    rows = []
    for e in experiments:
        T = e.y[:, 0].copy()
        ok = np.isfinite(T)
        if ok.sum() < 3:
            continue
        T = np.interp(np.arange(len(T)), np.flatnonzero(ok), T[ok])
        u = e.step_u
        losses = (T[1:] + T[:-1]) / 2.0 - u[:-1, 0]  # over each step, as the model holds u
        heat = np.concatenate([[0.0], np.cumsum(u[:-1, 1] * e.dt)])
        loss = np.concatenate([[0.0], np.cumsum(losses * e.dt)])
        rows.append(np.column_stack([loss, T - T[0], heat]))
    if not rows:
        return math.nan
    X = np.concatenate(rows)
    if np.isfinite(X).all():
        kA = float(np.linalg.lstsq(X[:, :2], X[:, 2], rcond=None)[0][0])
        if kA > 0 and math.isfinite(kA):
            return kA
    # the storage term taken as zero: eq. 10 over the whole records
    q, loss = sum(float(r[-1, 2]) for r in rows), sum(float(r[-1, 0]) for r in rows)
    return q / loss if q > 0 and loss > 0 and math.isfinite(q / loss) else math.nan


def lumped_capacity(experiments: Sequence[Experiment], kA: float) -> float:
    """C_bar of eq. 9 by equation error, kA given: C_bar dT/dt = Q_H - kA (T - T_o), with
    dT/dt ~ (T[n+1] - T[n]) / dt and T at the step midpoint, the discretisation of
    :func:`equation_error_start` (its noise is uncorrelated with the regressor). The slope of
    dT/dt on the net heat z = Q_H - kA (T - T_o) through the origin is 1 / C_bar. With an
    unmeasured body the one capacity lies between the air node's and the sum of all; it
    sets the time constant C_bar / kA of a start. NaN when the regression gives none."""
    szz = szd = 0.0
    for e in experiments:
        T = e.y[:, 0]
        d = (T[1:] - T[:-1]) / e.dt
        u = e.step_u
        z = u[:-1, 1] - kA * ((T[1:] + T[:-1]) / 2.0 - u[:-1, 0])
        ok = np.isfinite(d) & np.isfinite(z)
        szz += float(z[ok] @ z[ok])
        szd += float(z[ok] @ d[ok])
    return szz / szd if szd > 0 and szz > 0 else math.nan
