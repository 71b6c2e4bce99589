"""The uncertainty a planned climatic-wind-tunnel programme will give, before the tunnel runs.

A programme is data (:class:`Programme`, :func:`load_programme`): phases of given duration,
tunnel temperature T_o and heating power Q_H (held, or steps within the phase), the logger
step, and the standard deviation of the measurement noise of each compared state. For a
structure and a prior parameter set theta, the expected covariance of the log parameters of
the simulation-error fit (eqs. 17-18) is the inverse of the Fisher information of the planned
record,

    F = sum_j (1 / sigma_j^2) S_j^T S_j,   S_j[n, :] = d y_j[n] / d(log theta, x0),

with the exact output sensitivities of :func:`railtherm.estimation.models.sensitivities` (the
initial states estimated, as the fits estimate them) and sigma_j the noise of output j. The
fit weighs every output alike (eq. 17), so the covariance is the sandwich A J^T W J A with
A = (J^T J)^-1 and W the noise variance of each sample; a residual that is not white carries
fewer independent samples: its integrated autocorrelation time tau (in samples) scales the
variance by tau (:func:`predict`, ``tau_samples``). A systematic error of the programme's
instruments (an offset of a sensor group or of T_o, a scale error of the power) shifts the
record by a computable dy, and the fit by A J^T dy (its linear response); a kA fixed by the
static test (eq. 10, on the first phase's end) moves with the same errors, and the record the
fit compares with it. The shifts add in quadrature to the statistical variance, as in the
fits' own budget. The prediction assumes the structure right and the noise as declared; it says
nothing of a heat path the model
lacks.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from railtherm import structures
from railtherm.errors import ConfigError
from railtherm.estimation import models
from railtherm.estimation.acf import autocorrelation_time
from railtherm.estimation.common import Z95, identification
from railtherm.study import kwindow, limits
from railtherm.study.programme import (
    Phase,
    Programme,
    check_out_path,
    compared_rows,
    fit_windows,
    initial_state,
    k_window_rows,
    load_programme,
    prbs_steps,
    programme_inputs,
    write_programme,
)

__all__ = [
    "Assessment",
    "check_out_path",
    "Phase",
    "Prediction",
    "Prior",
    "Programme",
    "Run",
    "assess",
    "best_of_length",
    "load_programme",
    "parse_target",
    "predict",
    "predict_runs",
    "prior_for_class",
    "fit_draws",
    "within_limits",
    "write_programme",
    "prior_from_fit",
    "prior_from_fit_file",
    "prbs_steps",
    "prior_from_reference",
    "record_runs",
    "compared_rows",
    "k_window_rows",
    "fit_windows",
    "initial_state",
    "programme_inputs",
    "residual_noise",
    "residuals_of",
    "scaled",
    "shortest",
    "spread",
]

# an information matrix whose condition number exceeds this leaves some direction of the
# parameters undetermined by the record: those parameters are "not identifiable" by it
COND_MAX = 1e12
# a loop gain g . S of static kA and fit beyond this is flagged (a k window that is not
# steady): the errors are amplified by 1 / (1 - g . S), 2 and more, with tails
LOOP_GAIN_FLAG = 0.5
# From g . S = 1 on, the alternation of balance and fit runs away (the fits settle them by the
# secant method) and the linear fixed point's errors fall again as g . S grows (a factor
# 1 / |1 - g . S|), a promise the virtual tunnel runs do not bear out: Metro2's spread is
# 1.45-1.55 times the prediction at g . S 1.25, C_veh's 1.88 times at 3.23 (docs/design.md).
# A search for a better programme keeps below it.
LOOP_GAIN_MAX = 1.0


@dataclass(frozen=True)
class Prediction:
    """The expected uncertainty of a fit of ``structure`` to the programme: per estimated
    parameter its standard deviation of log(theta) ``sd_log`` and its relative 95 % half-width
    ``half_width`` (the interval exp(+-1.96 sd_log), half its log width as a fraction:
    exp(1.96 sd_log) - 1), and whether the record determines it (``identifiable``);
    ``condition`` the condition number of the information matrix; ``sd_log_systematic`` the
    share of ``sd_log`` the programme's systematic errors give; ``loop_gain`` g . S of the
    storage-corrected static kA and the fit (:mod:`railtherm.study.kwindow`): near 1 the two
    amplify each other's errors by 1 / (1 - g . S), and the estimates' spread has tails
    beyond this linear prediction (a k window that is not steady)."""

    structure: str
    sd_log: dict[str, float]
    half_width: dict[str, float]
    identifiable: dict[str, bool]
    condition: float
    sd_log_systematic: dict[str, float] = field(default_factory=dict)
    loop_gain: float = 0.0


@dataclass(frozen=True)
class Run:
    """One simulated stretch of a programme or a record: its inputs ``u`` (N x inputs, held
    over each step), its state ``x0`` at the first sample, and the sample ranges [a, b) the
    fit compares, each a record whose initial states it estimates (``windows``)."""

    u: np.ndarray
    x0: np.ndarray
    windows: tuple[tuple[int, int], ...]


def _systematic_shifts(
    structure, theta, run, x, step_s, outputs, systematic, dT_k, sens, power_share=1.0
):
    """The shift dy (N x outputs) of the run's record relative to the model, one per
    systematic source: an offset b of a compared state's sensors (dy = b), of T_o or a scale
    error of Q_H (the model driven by the biased inputs departs from the record by dx: dy =
    -dx). With ``sens`` (the sensitivities, kA among them) kA is fixed by the static test on
    the same instruments, Q_H / (T - T_o) with T - T_o = ``dT_k``, and its move shifts the
    model too (a power scale error by ``power_share`` of itself: 1 for eq. 10, less for the
    storage-corrected balance, :attr:`railtherm.study.kwindow.StaticK.power_share`);
    ``kA_rel`` is a random error of that kA of its own (relative)."""
    idx = [structure.states.index(s) for s in outputs]
    for source, u_sys in systematic.items():
        dy = np.zeros((len(x), len(outputs)))
        if source in outputs:
            dy[:, outputs.index(source)] = u_sys
        elif source in ("T_o", "power_rel"):
            du = np.zeros_like(run.u)
            du[:, 0] = u_sys if source == "T_o" else 0.0
            du[:, 1] = u_sys * run.u[:, 1] if source == "power_rel" else 0.0
            dy = -(models.simulate(structure, theta, run.u + du, step_s, run.x0) - x)[:, idx]
        elif source != "kA_rel" or sens is None:
            yield None
            continue
        if sens is not None and dT_k:  # d log kA of eq. 10's Q_H / (T - T_o)
            dlog_kA = {
                "power_rel": u_sys * power_share,
                "T": -u_sys / dT_k,
                "T_o": u_sys / dT_k,
                "kA_rel": u_sys,
            }.get(source, 0.0)
            dy = dy - dlog_kA * theta["kA"] * sens["kA"][:, idx]
        yield dy


def _input_noise_covariance(
    structure: models.Structure,
    theta: Mapping[str, float],
    runs: Sequence[Run],
    step_s: float,
    idx: Sequence[int],
    R: np.ndarray,
    input_noise: Mapping[str, float],
) -> np.ndarray:
    """The covariance the logged inputs' white noise gives the fit: the fit simulates from
    the logged T_o and Q_H, so a sample's noise moves every later compared output of its
    window by the model's impulse response h, dy = G du, and the fit by R dy (``R``: its
    linear response, rows the unknowns, columns the compared samples output by output as
    :func:`predict_runs` stacks them). Cov = sum_inputs (R G s)(R G s)^T, s the noise of each
    sample (``T_o`` K; ``power_rel`` times Q_H)."""
    from scipy.signal import fftconvolve

    sizes = [b - a for run in runs for a, b in run.windows]
    per_output = sum(sizes)
    columns = []
    for i, name in enumerate(structure.inputs):
        level = float(input_noise.get("power_rel" if name == "Q_H" else name, 0.0))
        if level <= 0 or name not in ("T_o", "Q_H"):
            continue
        w = 0
        for run in runs:
            impulse = np.zeros_like(run.u)
            impulse[0, i] = 1.0
            zero = np.zeros(len(structure.states))
            h = models.simulate(structure, theta, impulse, step_s, zero)[:, list(idx)]
            for a, b in run.windows:
                L = b - a
                start = sum(sizes[:w])
                moved = np.zeros((R.shape[0], L))
                for k in range(len(idx)):  # sum_n>m R[:, n] h[n - m], per output
                    v = R[:, k * per_output + start : k * per_output + start + L]
                    moved += fftconvolve(v[:, ::-1], h[None, :L, k], axes=1)[:, :L][:, ::-1]
                sd = level * np.abs(run.u[a:b, i]) if name == "Q_H" else np.full(L, level)
                columns.append(moved * sd)
                w += 1
    if not columns:
        return np.zeros((R.shape[0], R.shape[0]))
    C = np.concatenate(columns, axis=1)
    return C @ C.T


def _static_columns(
    runs: Sequence[Run], outputs: Sequence[str], static_test: kwindow.StaticK
) -> np.ndarray:
    """The static test's weights d log kA / d y on the compared samples, each times its
    sensors' white noise variance, stacked as :func:`predict_runs` stacks the samples (output
    by output, window by window; the k window lies in the first run): the covariance of the
    fit's samples with the static kA. The balance shares the sensors' white noise with the
    fit, not the colour of the fit's residuals (a slow misfit its regression absorbs)."""
    a, b = static_test.rows
    stacked = []
    for state in outputs:
        weight = static_test.weights.get(state, np.zeros(b - a))
        weight = weight * static_test.noise_K.get(state, 0.0) ** 2
        for r, run in enumerate(runs):
            for lo, hi in run.windows:
                column = np.zeros(hi - lo)
                at, to = max(lo, a), min(hi, b)
                if r == 0 and to > at:
                    column[at - lo : to - lo] = weight[at - a : to - a]
                stacked.append(column)
    return np.concatenate(stacked)


def _static_feedback(
    cov: np.ndarray,
    moved: list[np.ndarray],
    S: np.ndarray,
    free: Sequence[str],
    static_test: kwindow.StaticK,
    shared: np.ndarray,
) -> tuple[np.ndarray, list[np.ndarray], float]:
    """The fit's statistical covariance ``cov`` and systematic shifts ``moved`` (of the log
    parameters ``free`` first, then the windows' states) with kA the static test's. Its
    random error b (sd ``static_test.sd_log_random``) moves the estimates by S b; where the k
    window's samples are compared too, b and the fit's error F share their sensors' noise
    (``shared``: cov(F, b), the fit's response to :func:`_static_columns`). Where the
    balance depends on the capacities (gradient g) the two settle at the fixed point
    d log theta = M (F + S b), M = I + S g^T / (1 - g . S) (:mod:`railtherm.study.kwindow`).
    Returns both transformed and the loop gain g . S."""
    g = np.zeros(len(S))
    for i, p in enumerate(free):
        g[i] = static_test.gradient.get(p, 0.0)
    loop = 1.0 - float(g @ S)
    if abs(loop) < 1e-6:  # balance and fit do not settle: kA is not determined this way
        loop = math.copysign(1e-6, loop) if loop else 1e-6
    M = np.eye(len(S)) + np.outer(S, g) / loop
    var_b = static_test.sd_log_random**2
    joint = cov + np.outer(S, shared) + np.outer(shared, S) + var_b * np.outer(S, S)
    return M @ joint @ M.T, [M @ m for m in moved], 1.0 - loop


def _undetermined(structure: models.Structure, free: Sequence[str]) -> Prediction:
    inf = dict.fromkeys(free, math.inf)
    return Prediction(structure.name, inf, dict(inf), dict.fromkeys(free, False), math.inf, inf)


def _record_rows(
    structure: models.Structure,
    theta: Mapping[str, float],
    runs: Sequence[Run],
    step_s: float,
    outputs: Sequence[str],
    free: Sequence[str],
    sources: Mapping[str, float],
    static_k: tuple[float, float],
    static: bool,
) -> tuple[list, list, list] | None:
    """The rows of :func:`predict_runs` per compared output, window by window: d y / d (log
    theta, window states) (J), d y / d log kA where ``static`` (the static test fixes kA;
    ``static_k``: its T - T_o and power share), and per systematic source its shift dy; None
    where the logger step cannot resolve the parameter set (a heavy-tailed draw with a time
    constant of 1e-20 s)."""
    idx = [structure.states.index(s) for s in outputs]
    n_x = len(structure.states)
    n_w = sum(len(run.windows) for run in runs)
    dT_k, power_share = static_k
    params = free + (("kA",) if static else ())
    blocks: list[list[np.ndarray]] = [[] for _ in outputs]  # J rows per output
    kA_rows: list[list[np.ndarray]] = [[] for _ in outputs]  # d y / d log kA per output
    shifts: list[list[np.ndarray]] = [[] for _ in sources]  # dy rows per source
    w = 0
    for run in runs:
        try:
            with np.errstate(over="ignore", invalid="ignore"):
                x, sens, free_resp = models.sensitivities(
                    structure, theta, run.u, step_s, run.x0, params=params
                )
        except FloatingPointError:  # a parameter set the logger step cannot resolve (a
            # heavy-tailed draw with a time constant of 1e-20 s) determines nothing
            return None
        dys = list(
            _systematic_shifts(
                structure,
                theta,
                run,
                x,
                step_s,
                outputs,
                sources,
                dT_k,
                sens if static else None,
                power_share,
            )
        )
        for a, b in run.windows:
            # the window's initial states: the response of its samples to a state at its
            # first sample (the free response, shifted), zero in every other window
            starts = np.zeros((b - a, n_w * n_x, n_x))
            starts[:, w * n_x : (w + 1) * n_x, :] = free_resp[: b - a].transpose(0, 2, 1)
            for k, j in enumerate(idx):
                blocks[k].append(
                    np.column_stack([theta[p] * sens[p][a:b, j] for p in free] + [starts[:, :, j]])
                )
                if static:
                    kA_rows[k].append(theta["kA"] * sens["kA"][a:b, j])
            for k, dy in enumerate(dys):
                if dy is not None:
                    shifts[k].append(dy[a:b])
            w += 1
    return blocks, kA_rows, shifts


def predict_runs(
    structure: models.Structure,
    theta: Mapping[str, float],
    runs: Sequence[Run],
    step_s: float,
    noise_K: Mapping[str, float],
    *,
    tau_samples: Mapping[str, float] | None = None,
    free: Sequence[str] | None = None,
    outputs: Sequence[str] | None = None,
    systematic: Mapping[str, float] | None = None,
    dT_k: float = 0.0,
    static_test: kwindow.StaticK | None = None,
    input_noise: Mapping[str, float] | None = None,
) -> Prediction:
    """The Fisher-information prediction of the module docstring for the records of
    ``runs`` (:class:`Run`), logged every ``step_s``: the parameters ``free`` (default every
    parameter but kA, as the paper's two-stage fit estimates them), compared on ``outputs``
    (default the states ``noise_K`` names: the residual sd per output, ``tau_samples`` its
    autocorrelation time in samples), each window's initial states estimated (nuisance
    unknowns). ``systematic``: standard uncertainties of the sources of
    :func:`_systematic_shifts`; ``dT_k``: T - T_o of the static test that fixes kA; ``static_test``:
    the static test's random error and, for the storage-corrected balance, its dependence on
    the capacities (:func:`railtherm.study.kwindow.static_k`; its ``dT`` replaces ``dT_k``),
    carried to the parameters through the fixed point of the balance and the fit;
    ``input_noise``: the white noise of the logged inputs (``T_o`` K, ``power_rel``), which
    the fit's simulation follows (:func:`_input_noise_covariance`)."""
    tau = {s: float((tau_samples or {}).get(s, 1.0)) for s in noise_K}
    free = tuple(p for p in structure.parameters if p != "kA") if free is None else tuple(free)
    outputs = (
        tuple(s for s in structure.states if s in noise_K) if outputs is None else tuple(outputs)
    )
    unknown = [s for s in outputs if s not in noise_K or s not in structure.states]
    if unknown or not outputs:
        raise ValueError(f"outputs {list(outputs)}: each needs a state and a noise_K entry")
    # a kA held fixed comes from the static test (eq. 10) on the same instruments: it moves
    # with their systematic errors, and the fit with it
    static = "kA" in structure.parameters and "kA" not in free
    power_share = 1.0
    if static and static_test is not None:
        if not math.isfinite(static_test.sd_log_random):  # the static test gives no kA
            return _undetermined(structure, free)
        dT_k, power_share = static_test.dT, static_test.power_share
    idx = [structure.states.index(s) for s in outputs]
    sources = dict(systematic or {})
    rows = _record_rows(
        structure, theta, runs, step_s, outputs, free, sources, (dT_k, power_share), static
    )
    if rows is None:  # a parameter set the logger step cannot resolve determines nothing
        return _undetermined(structure, free)
    blocks, kA_rows, shifts = rows
    if not any(len(r) for rows in blocks for r in rows):  # no compared sample (a programme
        # scaled, or a phase shortened, below its logger step) determines nothing
        return _undetermined(structure, free)
    # J: d y / d (log theta, window states) of every compared sample, output by output (eq.
    # 17's e), its columns scaled to unit length for the inverse
    J = np.concatenate([np.concatenate(rows) for rows in blocks])
    if not np.all(np.isfinite(J)):
        return _undetermined(structure, free)
    n_rows = [sum(len(r) for r in rows) for rows in blocks]
    scale = np.sqrt(np.einsum("ij,ij->j", J, J))
    scale[scale == 0] = 1.0
    Jn = J / scale
    H = Jn.T @ Jn
    eig = np.linalg.eigvalsh(H)
    condition = float(eig[-1] / eig[0]) if eig[0] > 0 else math.inf
    loop_gain = 0.0
    if not math.isfinite(condition) or condition > COND_MAX:
        sd = sd_sys = dict.fromkeys(free, math.inf)
    else:
        # the unweighted least squares of eq. 17 with noise of variance sigma_j^2 tau_j per
        # output (tau samples carry the information of one): the sandwich A J^T W J A
        A = np.linalg.inv(H)
        weight = np.repeat([noise_K[s] ** 2 * max(tau[s], 1.0) for s in outputs], n_rows)
        cov = A @ (Jn.T @ (weight[:, None] * Jn)) @ A / np.outer(scale, scale)
        response = A @ Jn.T  # the fit's linear response to a shift of the record
        if input_noise:
            cov = cov + _input_noise_covariance(
                structure, theta, runs, step_s, idx, response / scale[:, None], input_noise
            )
        moved = [
            (response @ np.concatenate(parts).T.reshape(-1)) / scale for parts in shifts if parts
        ]
        if static and static_test is not None:
            # the static kA's own random error and, for the storage-corrected balance, the
            # fixed point of balance and fit (railtherm.study.kwindow)
            kA_col = np.concatenate([np.concatenate(rows) for rows in kA_rows])
            S = -(response @ kA_col) / scale  # d (log theta, x0) / d log kA of the fit
            shared = (response @ _static_columns(runs, outputs, static_test)) / scale
            cov, moved, loop_gain = _static_feedback(cov, moved, S, free, static_test, shared)
        systematic_var = np.sum(np.square(moved), axis=0) if moved else np.zeros(len(scale))
        sd = {
            p: float(math.sqrt(max(cov[i, i] + systematic_var[i], 0.0))) for i, p in enumerate(free)
        }
        sd_sys = {p: float(math.sqrt(systematic_var[i])) for i, p in enumerate(free)}
    # a record that does not move a parameter leaves its sd huge (or infinite): no width
    half = {p: (math.expm1(Z95 * v) if Z95 * v < 700.0 else math.inf) for p, v in sd.items()}
    # the fits' own rule on the predicted interval of theta * exp(+-1.96 sd)
    identifiable = {
        p: identification(1.0, (math.exp(-Z95 * v), math.inf if h == math.inf else 1.0 + h))[
            "identified"
        ]
        for (p, v), h in zip(sd.items(), half.values(), strict=True)
    }
    return Prediction(structure.name, sd, half, identifiable, condition, sd_sys, loop_gain)


def predict(
    structure: models.Structure,
    theta: Mapping[str, float],
    programme: Programme,
    *,
    free: Sequence[str] | None = None,
    outputs: Sequence[str] | None = None,
    x0: Sequence[float] | None = None,
    tau_samples: float | Mapping[str, float] = 1.0,
    noise_K: Mapping[str, float] | None = None,
) -> Prediction:
    """The prediction of :func:`predict_runs` for a planned programme, simulated from ``x0``
    (default: the programme's ``start``, :func:`initial_state`) with its fit windows: the
    parameters ``free``, compared on ``outputs`` (default: the states the programme gives a
    noise for); ``tau_samples``: the residuals' integrated autocorrelation time in samples (1
    for white noise), one for all outputs or one per output; ``noise_K``: the residual
    standard deviation per output, in place of the programme's sensor noise (a prior fit's,
    :class:`Prior`). The static test that fixes kA is read at the first phase's end."""
    unknown = sorted(set(programme.noise_K) - set(structure.states))
    if unknown:
        raise ConfigError(
            programme.where,
            f"noise_K.{unknown[0]}",
            programme.noise_K[unknown[0]],
            f"no state of the model {structure.name} (its states: {', '.join(structure.states)}); "
            "the tunnel air's noise is input_noise.T_o or sensors.T_o",
        )
    noise = {**programme.noise_K, **(noise_K or {})}
    if outputs is None:
        outputs = tuple(s for s in structure.states if s in programme.noise_K)
    tau = (
        {s: float(tau_samples.get(s, 1.0)) for s in noise}
        if isinstance(tau_samples, Mapping)
        else dict.fromkeys(noise, float(tau_samples))
    )
    free = tuple(p for p in structure.parameters if p != "kA") if free is None else tuple(free)
    windows = tuple((a, b) for _, a, b in fit_windows(programme))
    if not windows:  # phases scaled below the logger step: no compared sample
        return _undetermined(structure, free)
    # a parameter set whose model the logger step cannot discretise (a heavy-tailed class
    # draw: K_veh of 1e157 W/K, exp(A dt) overflows) determines nothing
    try:
        u = programme_inputs(programme, structure, theta)
        if x0 is None:
            x0 = initial_state(programme, structure, theta, u[0])
        x0 = np.asarray(x0, float)
        run = Run(u, x0, windows)
        static_test = None
        if "kA" in structure.parameters and "kA" not in free:
            x = models.simulate(structure, theta, u, programme.step_s, x0)
            sensors = {s: programme.noise_K.get(s, v) for s, v in noise.items() if s in outputs}
            static_test = kwindow.static_k(
                structure,
                theta,
                u,
                x,
                programme.step_s,
                k_window_rows(programme),
                sensors,
                programme.input_noise,
                storage_correction=programme.storage_correction,
                free=free,
            )
        return predict_runs(
            structure,
            theta,
            [run],
            programme.step_s,
            noise,
            tau_samples=tau,
            free=free,
            outputs=outputs,
            systematic=programme.systematic,
            static_test=static_test,
            input_noise=programme.input_noise,
        )
    except FloatingPointError:
        return _undetermined(structure, free)


# ------------------------------------------------------------------------------------------
# priors: what is known of the vehicle before the tunnel


@dataclass(frozen=True)
class Prior:
    """What is known of a vehicle before its programme runs: the ``structure``, a central
    parameter set ``theta``, optionally ``draws`` ({param: array}) of parameter sets spanning
    the uncertainty (a class reference model's prediction), the ``free`` parameters the fit
    will estimate, and, where a fit gives them, the residual ``noise_K`` and autocorrelation
    time ``tau_samples`` per output. ``source`` says where it comes from."""

    structure: models.Structure
    theta: dict[str, float]
    free: tuple[str, ...]
    source: str
    draws: dict[str, np.ndarray] | None = None
    noise_K: dict[str, float] = field(default_factory=dict)
    tau_samples: dict[str, float] = field(default_factory=dict)
    tau_step_s: float | None = None  # the logger step of the samples tau_samples counts

    def tau_at(self, step_s: float) -> dict[str, float]:
        """The residuals' autocorrelation time in samples of a programme logged every
        ``step_s``: the same time, at least one sample (a faster logger adds correlated
        samples, not independent ones; a slower one samples white noise). As measured where
        the prior does not say at which step."""
        if self.tau_step_s is None:
            return dict(self.tau_samples)
        return {s: max(1.0, t * self.tau_step_s / step_s) for s, t in self.tau_samples.items()}

    def thetas(self) -> list[dict[str, float]]:
        """The prior's draws as parameter sets ([] without draws)."""
        if not self.draws:
            return []
        n = len(next(iter(self.draws.values())))
        return [{p: float(v[i]) for p, v in self.draws.items()} for i in range(n)]

    def predict(
        self,
        programme: Programme,
        theta: Mapping[str, float] | None = None,
        free: Sequence[str] | None = None,
    ) -> Prediction:
        """:func:`predict` of ``programme`` at ``theta`` (default the prior's centre) for
        ``free`` (default the prior's), with the prior's residual level."""
        return predict(
            self.structure,
            self.theta if theta is None else theta,
            programme,
            free=self.free if free is None else free,
            tau_samples=self.tau_at(programme.step_s) or 1.0,
            noise_K=self.noise_K,
        )

    def predict_runs(
        self,
        runs: Sequence[Run],
        step_s: float,
        systematic: Mapping[str, float],
        dT_k: float = 0.0,
        theta: Mapping[str, float] | None = None,
    ) -> Prediction:
        """:func:`predict_runs` of recorded ``runs`` at ``theta`` (default the centre) with
        the prior's residual level and free parameters."""
        return predict_runs(
            self.structure,
            self.theta if theta is None else theta,
            runs,
            step_s,
            self.noise_K,
            tau_samples=self.tau_at(step_s),
            free=self.free,
            systematic=systematic,
            dT_k=dT_k,
        )


def spread(
    predictions: Sequence[Prediction], params: Sequence[str]
) -> tuple[dict[str, tuple[float, float, float]], dict[str, float]]:
    """Over ``predictions`` (one per parameter set), each parameter's 5 %, median and 95 %
    relative 95 % half-width and the share of them that identify it."""
    widths, shares = {}, {}
    for p in params:
        values = np.array([r.half_width[p] for r in predictions])
        q05, q50, q95 = np.quantile(values, [0.05, 0.5, 0.95], method="inverted_cdf")
        widths[p] = (float(q05), float(q50), float(q95))
        shares[p] = float(np.mean([r.identifiable[p] for r in predictions]))
    return widths, shares


def record_runs(fit) -> tuple[list[Run], float] | None:
    """A fit's identification windows as :class:`Run` (their measured inputs, the fit's
    simulated state at each window's start, the whole window compared) and the logger step;
    None without a series that simulates every state."""
    series, structure = fit.series, fit.structure
    if series is None:
        return None
    sims = [f"{s}_sim" for s in structure.states]
    if any(c not in series.columns for c in [*sims, "window", "time", *structure.inputs]):
        return None
    runs, steps = [], []
    for _, w in series.groupby("window", sort=False):
        steps.append(float(np.median(np.diff(w["time"].to_numpy(float)))))
        u = w[list(structure.inputs)].to_numpy(float)
        runs.append(Run(u, w[sims].to_numpy(float)[0], ((0, len(w)),)))
    return runs, float(np.median(steps))


def residual_noise(fit) -> tuple[dict[str, float], dict[str, float], float] | None:
    """The noise of a fit's records, per compared output its standard deviation and
    integrated autocorrelation time (samples of the record's logger step, the third item),
    after the slow shapes its own systematic
    errors leave in the residual are taken out: an offset of each output's sensors, a T_o
    offset and a power scale error (the model's response to each), and an error of each
    parameter the fit held fixed (kA from the static test: its sensitivity). Those errors
    are the programme's systematic budget; left in, a drift they cause would count again, as
    coloured noise. None without the fit's series (time, inputs, measured and simulated
    states per window), or when a state is not simulated in it."""
    records = record_runs(fit)
    if records is None:
        return None
    structure = fit.structure
    outputs = [s for s in fit.outputs if f"{s}_residual" in fit.series]
    if not outputs:
        return None
    runs, step_s = records
    theta = fit.theta
    fixed = tuple(p for p, q in fit.parameters.items() if q.estimated is False and p in theta)
    idx = [structure.states.index(s) for s in outputs]
    unit = {**dict.fromkeys(outputs, 1.0), "T_o": 1.0, "power_rel": 1.0}  # 1 K, 100 %
    shapes, residuals, spans = [], [], []
    windows = fit.series.groupby("window", sort=False)
    for run, (_, w) in zip(runs, windows, strict=True):
        x, sens, _ = models.sensitivities(structure, theta, run.u, step_s, run.x0, params=fixed)
        cols = list(_systematic_shifts(structure, theta, run, x, step_s, outputs, unit, 0.0, None))
        cols += [theta[p] * sens[p][:, idx] for p in fixed]
        shapes.append(np.stack(cols, axis=-1))  # (n, outputs, sources)
        residuals.append(w[[f"{s}_residual" for s in outputs]].to_numpy(float))
        spans.append(len(w))
    X = np.concatenate(shapes).reshape(-1, shapes[0].shape[-1])
    r = np.concatenate(residuals).reshape(-1)
    ok = np.isfinite(r)
    coef = np.linalg.lstsq(X[ok], r[ok], rcond=None)[0]
    rest = (np.concatenate(residuals) - np.concatenate(shapes) @ coef).T  # (outputs, n)
    noise, tau = {}, {}
    for j, s in enumerate(outputs):
        values = rest[j]
        noise[s] = float(np.sqrt(np.nanmean(values**2)))
        bounds = np.cumsum([0, *spans])
        per = [
            (autocorrelation_time(values[a:b][np.isfinite(values[a:b])]), b - a)
            for a, b in zip(bounds[:-1], bounds[1:], strict=True)
        ]
        tau[s] = float(sum(t * n for t, n in per) / sum(n for _, n in per))
    return noise, tau, float(step_s)


def fit_draws(fit, n: int, seed: int = 0) -> dict[str, np.ndarray] | None:
    """``n`` parameter sets a fit's own uncertainty allows: its estimated parameters drawn
    log-normal about the estimates with their combined standard deviations of log theta
    (``sd_log_total``, statistical and systematic) and the fit's correlation of the free log
    parameters; the parameters it held (kA from the static test) at their values.
    Deterministic with ``seed``; None where ``n`` is 0 or a parameter is not identified (its
    interval gives no spread to draw from). A fit read with its posterior
    (:attr:`railtherm.study.fit.Fit.posterior`) gives ``n`` of the posterior's own draws,
    the systematic budget mixed in."""
    if n >= 1 and getattr(fit, "posterior", None) is not None:
        return fit.posterior_sample(n, np.random.default_rng(seed))
    params = fit.parameters
    estimated = [p for p in fit.structure.parameters if params[p].estimated is True]
    if n < 1 or not estimated or not all(params[p].identified for p in estimated):
        return None
    sd = np.array([params[p].sd_log_total or params[p].sd_log or 0.0 for p in estimated])
    if not np.all(np.isfinite(sd)):
        return None
    free = list(fit.free)
    corr = np.eye(len(estimated))
    if all(p in free for p in estimated) and fit.correlation.shape == (len(free), len(free)):
        at = [free.index(p) for p in estimated]
        corr = np.nan_to_num(fit.correlation[np.ix_(at, at)], nan=0.0)
        np.fill_diagonal(corr, 1.0)
    rng = np.random.default_rng(seed)
    z = rng.multivariate_normal(np.zeros(len(sd)), corr * np.outer(sd, sd), n, method="eigh")
    draws = {p: np.full(n, float(params[p].value)) for p in fit.structure.parameters}
    for i, p in enumerate(estimated):
        draws[p] = float(params[p].value) * np.exp(z[:, i])
    return draws


def prior_from_fit(fit, n: int = 0, seed: int = 0) -> Prior:
    """The prior of a vehicle measured before (:class:`railtherm.study.fit.Fit`): its
    estimates, the parameters it estimated (kA fixed by the static test stays fixed), and per
    compared output the residual noise and autocorrelation time its record showed (in
    samples of that record: the programme is taken at the same logger step), with the slow
    shapes of its systematic errors taken out where the fit's series is at hand
    (:func:`residual_noise`), else as its measures give them. With ``n`` the prior carries
    ``n`` draws of the fit's own uncertainty (:func:`fit_draws`, seed ``seed``): a
    prediction over them is not one pilot's chance."""
    measures = fit.section("measures")
    noise = {s: float(m["overall"]["rmse"]) for s, m in measures.items()}
    tau = {s: float(m["overall"].get("autocorrelation_time", 1.0)) for s, m in measures.items()}
    step = None  # the measures' autocorrelation times are of an unknown step
    separated = residual_noise(fit)
    if separated is not None:
        noise, tau, step = separated
    estimated = {p for p, q in fit.parameters.items() if q.estimated is True}
    structure = fit.structure
    free = tuple(p for p in structure.parameters if p in estimated)
    source = f"the fit {fit.model} of {fit.vehicle}"
    draws = fit_draws(fit, n, seed)
    if draws is not None:
        drawn = (
            "combined intervals" if fit.posterior is None else f"posterior ({fit.posterior_file})"
        )
        source += f", {n} draws of its {drawn}"
    return Prior(structure, dict(fit.central), free, source, draws, noise, tau, step)


def _read_with_series(path: str | Path):
    """A fit file with its series where the study wrote it (``identify/<model>_series.csv``
    beside ``fit_<model>.yaml``)."""
    from railtherm.study.fit import check_fit_file, read_fit

    fit = read_fit(path)
    check_fit_file(path, fit)
    series = Path(path).parent / "identify" / f"{fit.model}_series.csv"
    return read_fit(path, series if series.is_file() else None, posterior="auto")


def prior_from_fit_file(path: str | Path, n: int = 0, seed: int = 0) -> Prior:
    """:func:`prior_from_fit` of a fit file, with its series where the study wrote it, and
    ``n`` draws of its uncertainty (seed ``seed``)."""
    from railtherm.study.quality import ACCEPTABLE

    fit = _read_with_series(path)
    undetermined = [p for p, q in fit.parameters.items() if not q.identified]
    if undetermined:
        raise ConfigError(
            str(path),
            "parameters",
            undetermined,
            "not identified by its record (an estimate at a bound of the search or with an "
            "unbounded interval): no programme's prediction rests on it; plan with the class "
            "reference model (--class, --mass-kg, --surface-m2) as the prior",
        )
    prior = prior_from_fit(fit, n, seed)
    if fit.verdict != ACCEPTABLE:
        prior = replace(prior, source=f"{prior.source} (its verdict: {fit.verdict})")
    return prior


def residuals_of(fits) -> tuple[dict[str, float], dict[str, float], float | None]:
    """The residual level a class's fits show: per compared output the median noise and the
    median autocorrelation time over ``fits`` (:class:`railtherm.study.fit.Fit`) whose
    verdict is acceptable (each as :func:`residual_noise` separates it where the fit's
    series is at hand, else its RMSE and autocorrelation time), and the logger step that
    time is in samples of: 1 s (the times in seconds) where every fit's record gives its
    step, else None (the samples of each fit's own step); ({}, {}, None) without one."""
    from railtherm.study.quality import ACCEPTABLE

    rmse: dict[str, list[float]] = {}
    tau: dict[str, list[tuple[float, float | None]]] = {}
    for fit in fits:
        if fit.verdict != ACCEPTABLE:
            continue
        measures = fit.section("measures")
        levels = residual_noise(fit) or (
            {s: float(m["overall"]["rmse"]) for s, m in measures.items()},
            {s: float(m["overall"].get("autocorrelation_time", 1)) for s, m in measures.items()},
            None,
        )
        for state in levels[0]:
            rmse.setdefault(state, []).append(levels[0][state])
            tau.setdefault(state, []).append((levels[1][state], levels[2]))
    seconds = all(step is not None for v in tau.values() for _, step in v)

    def median_tau(v: list[tuple[float, float | None]]) -> float:
        return float(np.median([t * (step if seconds else 1.0) for t, step in v]))

    return (
        {s: float(np.median(v)) for s, v in rmse.items()},
        {s: median_tau(v) for s, v in tau.items()},
        1.0 if seconds and tau else None,
    )


def prior_from_reference(model, n: int = 200, seed: int = 0, fits=()) -> Prior:
    """The prior of an unmeasured vehicle from its class reference model
    (:class:`railtherm.study.classmodel.ReferenceModel`): its central parameters and ``n``
    draws of a new vehicle of the class (deterministic with ``seed``); kA fixed, as the
    two-stage fit fixes it from the static test. ``fits``: the class's fits, whose residual
    level (:func:`residuals_of`) replaces the programme's sensor noise."""
    structure = structures.named(model.structure)
    draws = model.draws(n, seed)
    keep = np.all([np.isfinite(v) & (v > 0) for v in draws.values()], axis=0)
    draws = {p: v[keep] for p, v in draws.items()}
    free = tuple(p for p in structure.parameters if p != "kA")
    source = (
        f"the {model.vehicle_class} reference model ({model.mass_kg:g} kg, "
        f"{model.surface_m2:g} m², {len(model.basis)} vehicles)"
    )
    noise, tau, step = residuals_of(fits)
    return Prior(structure, dict(model.theta), free, source, draws, noise, tau, step)


def prior_for_class(
    vehicle_class: str,
    mass_kg: float,
    surface_m2: float,
    config: str = "config/config.yaml",
    results: str = "results",
    workdir: str | Path = ".",
    n: int = 200,
    seed: int = 0,
) -> Prior:
    """The prior of an unmeasured vehicle of ``vehicle_class``, ``mass_kg`` and ``surface_m2``
    from the study's committed Table 2 (:func:`railtherm.study.classmodel.build`), with the
    residual level of its basis vehicles' second-order fits where ``results`` holds them
    (:func:`prior_from_reference`)."""
    from railtherm.study import classmodel

    members = classmodel.members_from_study(config, results, workdir=workdir)
    model = classmodel.build(members, vehicle_class, mass_kg, surface_m2)
    paths = [Path(workdir, results, "vehicles", vid, "fit_order2.yaml") for vid in model.basis]
    fits = [_read_with_series(path) for path in paths if path.is_file()]
    return prior_from_reference(model, n, seed, fits)


# ------------------------------------------------------------------------------------------
# assessment and design


def parse_target(text: str) -> tuple[str, float]:
    """``"C_veh=5%"`` -> ("C_veh", 0.05): a parameter and its target relative 95 % half-width.
    A text of another form is a :class:`ConfigError` naming ``--target``."""
    name, sep, value = str(text).partition("=")
    number = value.strip()
    try:
        fraction = float(number.removesuffix("%")) / 100.0
    except ValueError:
        fraction = math.nan
    if not sep or not name.strip() or not math.isfinite(fraction):
        raise ConfigError("--target", "target", text, "expected PARAMETER=PERCENT, e.g. C_veh=5%")
    if not number.endswith("%"):  # 0.05 read as 0.05 % where 5 % was meant
        raise ConfigError(
            "--target", "target", text, f"give the percent sign: {name.strip()}={number}%"
        )
    if not fraction > 0:
        raise ConfigError(
            "--target", "target", text, "a target half-width is above 0 %, e.g. C_veh=5%"
        )
    return name.strip(), fraction


@dataclass(frozen=True)
class Assessment:
    """A programme judged for a prior: the prediction at the central parameters
    (``central``), and over the prior's draws each parameter's median and 5 / 95 % quantiles
    of the relative 95 % half-width (``spread``: {param: (q05, median, q95)}), the share of
    draws in which it is identifiable (``identifiable``) and, for a ``target`` (param,
    half-width), the probability to reach it (``probability``); what the programme does to
    the vehicle: each state's highest temperature at the prior's upper band (``peaks``,
    degC, :func:`railtherm.study.limits.peaks`), the limits they exceed (``violations``),
    the share of the k window's heat that goes into storage (``k_storage_share``) and the
    ``notes`` of a search (which limit binds)."""

    programme: Programme
    prior: Prior
    central: Prediction
    spread: dict[str, tuple[float, float, float]]
    identifiable: dict[str, float]
    target: tuple[str, float] | None = None
    probability: float | None = None
    peaks: dict[str, float] = field(default_factory=dict)
    violations: tuple[str, ...] = ()
    k_storage_share: float = math.nan
    notes: tuple[str, ...] = ()


def assess(
    prior: Prior,
    programme: Programme,
    target: tuple[str, float] | None = None,
    with_peaks: bool = True,
) -> Assessment:
    """The :class:`Assessment` of ``programme`` for ``prior`` (every draw predicted; a prior
    without draws is its central parameters alone); ``with_peaks`` False leaves out the
    simulation of its temperatures (a search judges its limits apart)."""
    if target is not None and target[0] not in prior.free:
        raise ConfigError(
            "--target", "target", target[0], f"not a parameter the fit estimates: {prior.free}"
        )

    central = prior.predict(programme)
    runs = [prior.predict(programme, theta) for theta in prior.thetas()] or [central]
    widths, identifiable = spread(runs, prior.free)
    probability = None
    if target is not None:
        name, goal = target
        probability = float(
            np.mean([r.identifiable[name] and r.half_width[name] <= goal for r in runs])
        )
    highest = (
        limits.peaks(prior.structure, prior.thetas() or [prior.theta], programme)
        if with_peaks
        else {}
    )
    share = limits.k_window_storage_share(prior.structure, prior.theta, programme)
    return Assessment(
        programme,
        prior,
        central,
        widths,
        identifiable,
        target,
        probability,
        highest,
        tuple(limits.violations(highest, programme)),
        share,
    )


def scaled(programme: Programme, factor: float, keep_first: bool = False) -> Programme:
    """The programme with every phase (and every step within it) ``factor`` times as long;
    the first phase (the static k window's steady state) as it is with ``keep_first``, or
    where scaling would leave it shorter than the k window (``k_window_h``)."""
    phases = tuple(
        ph
        if (keep_first or ph.hours * factor < programme.k_window_h) and i == 0
        else replace(
            ph, hours=ph.hours * factor, steps=tuple((at * factor, w) for at, w in ph.steps)
        )
        for i, ph in enumerate(programme.phases)
    )
    name = f"{programme.name} x{factor:.3g}"
    return replace(programme, name=name, phases=phases)


def shortest(
    prior: Prior,
    programme: Programme,
    target: tuple[str, float],
    probability: float = 0.9,
    factors: Sequence[float] = tuple(np.round(np.geomspace(0.25, 4.0, 17), 4)),
    keep_first: bool = False,
) -> tuple[float, Assessment] | None:
    """The shortest version of ``programme``'s shape (its phases in proportion, each scaled by
    one of ``factors``; the first kept as it is with ``keep_first``) whose :func:`assess`
    reaches ``target`` with at least ``probability`` within the programme's temperature
    limits (:mod:`railtherm.study.limits`); (factor, its assessment), or None when none
    within them does. The factors within the limits are tried from the shortest up: a longer
    programme of the same shape need not give a narrower interval (the systematic errors'
    share grows with the holds: Metro2's fit with a 36 h first phase predicts C ±2.73 %
    with later phases of 3 h, ±4.07 % with 12 h), but it heats the vehicle no less, so the
    longest within the limits is found by bisection first."""
    ordered = sorted(float(f) for f in factors)
    found: dict[float, Assessment] = {}
    caps = limits.temperature_limits(programme)
    thetas = prior.thetas() or [prior.theta]

    def within(factor: float) -> bool:
        if not caps:
            return True
        highest = limits.peaks(prior.structure, thetas, scaled(programme, factor, keep_first))
        return not limits.violations(highest, programme)

    def reaches(factor: float) -> bool:  # each factor assessed once
        if factor not in found:  # the limits are judged apart (within)
            candidate = scaled(programme, factor, keep_first)
            found[factor] = assess(prior, candidate, target, with_peaks=False)
        return (found[factor].probability or 0.0) >= probability

    def first_true(test, lo: int, hi: int) -> int:  # test(ordered[hi]) holds, lo's does not
        while hi - lo > 1:
            mid = (lo + hi) // 2
            lo, hi = (lo, mid) if test(ordered[mid]) else (mid, hi)
        return hi

    top = len(ordered) - 1
    if not within(ordered[top]):  # the longest within the limits
        if not within(ordered[0]):
            return None
        top = first_true(lambda f: not within(f), 0, top) - 1
    best = next((i for i in range(top + 1) if reaches(ordered[i])), None)
    if best is None:
        return None
    chosen = scaled(programme, ordered[best], keep_first)
    highest = limits.peaks(prior.structure, thetas, chosen)
    found_best = replace(
        found[ordered[best]], peaks=highest, violations=tuple(limits.violations(highest, chosen))
    )
    return ordered[best], found_best


def best_of_length(
    prior: Prior,
    programme: Programme,
    target: str,
    hours: float | None = None,
    max_power_W: float | None = None,
    min_phase_h: float = 1.0,
    vary_power: bool = True,
) -> tuple[Programme, Assessment]:
    """The programme of ``hours`` (default: ``programme``'s own length) that gives the
    narrowest predicted interval of ``target`` at the prior's central parameters. The first
    phase stays as given: it ends with the static k window (eq. 10), which needs its steady
    state. The later phases keep their order and tunnel temperatures; each one's duration (at
    least ``min_phase_h``) and held power (0 to ``max_power_W``, default the programme's
    ``limits.max_power_W``, else its largest power; kept as given with ``vary_power`` False,
    for heaters of fixed levels) are chosen by Nelder-Mead, started from ``programme`` scaled
    to ``hours``. The result is then assessed over the prior's draws. A
    later phase with steps, or a length that leaves the later phases less than ``min_phase_h`` each,
    is a :class:`ConfigError`."""
    from scipy.optimize import minimize

    first, rest = programme.phases[0], programme.phases[1:]
    for i, ph in enumerate(rest, start=1):
        if len(ph.steps) != 1:
            raise ConfigError(
                programme.where, f"phases[{i}].steps", ph.steps, "optimised phases hold power_W"
            )
    if target not in prior.free:
        raise ConfigError("--target", "target", target, f"not estimated: {prior.free}")
    total = programme.hours if hours is None else float(hours)
    if not (math.isfinite(total) and total > 0):
        raise ConfigError("--length-h", "length_h", total, "expected a length in hours above 0")
    shortest_h = 10.0 * programme.step_s / 3600.0  # ten samples, as a programme file needs
    if not (math.isfinite(min_phase_h) and min_phase_h >= shortest_h):
        raise ConfigError(
            "--min-phase-h",
            "min_phase_h",
            min_phase_h,
            f"expected at least {shortest_h:.3g} h: ten samples of the logger step "
            f"({programme.step_s:g} s), as a programme file needs in every phase",
        )
    n = len(rest)
    spare = total - first.hours - n * min_phase_h
    if n == 0 or spare < 0:
        raise ConfigError(
            "--length-h",
            "length_h",
            total,
            f"the first phase ({first.hours:g} h) and {n} later phases of at least "
            f"{min_phase_h:g} h do not fit",
        )
    power_max = max(s[1] for ph in programme.phases for s in ph.steps)
    power_max = programme.limits.get("max_power_W", power_max)
    if max_power_W is not None:
        limit = programme.limits.get("max_power_W")
        if not (math.isfinite(max_power_W) and max_power_W > 0):
            raise ConfigError(
                "--max-power-w", "max_power_w", max_power_W, "expected a power in W above 0"
            )
        if limit is not None and max_power_W > limit:
            raise ConfigError(
                "--max-power-w",
                "max_power_w",
                max_power_W,
                f"above the programme's limits.max_power_W ({limit:g} W), which a proposed "
                "programme keeps to (raise the limit in the file where the heaters can)",
            )
        power_max = float(max_power_W)

    def build(z: np.ndarray) -> Programme:
        share = np.exp(z[:n] - z[:n].max())
        share /= share.sum()
        given = [ph.steps[0][1] for ph in rest]
        power = power_max / (1.0 + np.exp(-z[n:])) if vary_power else given  # in (0, max)
        later = tuple(
            replace(
                ph, hours=min_phase_h + spare * float(share[i]), steps=((0.0, float(power[i])),)
            )
            for i, ph in enumerate(rest)
        )
        name = f"{programme.name}, best of {total:g} h"
        return replace(programme, name=name, phases=(first, *later))

    def width(z: np.ndarray) -> float:
        predicted = prior.predict(build(z))
        if predicted.loop_gain >= LOOP_GAIN_MAX:  # the linear prediction does not hold there
            return 1e6
        sd = predicted.sd_log[target]
        return float(np.log(sd)) if math.isfinite(sd) and sd > 0 else 1e6

    scale = (total - first.hours) / max(sum(ph.hours for ph in rest), 1e-9)
    hours0 = np.array([max(ph.hours * scale - min_phase_h, 1e-3) for ph in rest])
    p0 = np.clip([ph.steps[0][1] / power_max for ph in rest], 1e-3, 1 - 1e-3)
    z0 = np.concatenate([np.log(hours0), np.log(p0 / (1.0 - p0)) if vary_power else []])
    options = {"maxfev": 400, "xatol": 1e-3, "fatol": 1e-4}
    found = minimize(width, z0, method="Nelder-Mead", options=options)
    best = build(found.x if found.fun < width(z0) else z0)
    best, notes = within_limits(prior, best)
    return best, replace(assess(prior, best, (target, math.inf)), notes=notes)


def _powers_scaled(programme: Programme, factor: float) -> Programme:
    """The programme with the heating of every phase after the first ``factor`` times."""
    later = tuple(
        replace(ph, steps=tuple((at, w * factor) for at, w in ph.steps))
        for ph in programme.phases[1:]
    )
    return replace(programme, phases=(programme.phases[0], *later))


def within_limits(prior: Prior, programme: Programme) -> tuple[Programme, tuple[str, ...]]:
    """``programme`` kept within its temperature limits at the prior's upper band
    (:mod:`railtherm.study.limits`): where the cabin air or the body would get hotter than
    ``limits.max_T_C`` / ``max_T_veh_C``, the heating of every phase after the first is
    scaled down (bisection) until the hottest is at its limit. Returns the programme and
    notes saying which limit binds (the heaters' ``max_power_W`` too, where a phase holds
    it). A first phase that exceeds a limit alone is a :class:`ConfigError`."""
    notes = []
    top = programme.limits.get("max_power_W")
    at_top = [
        ph.name
        for ph in programme.phases[1:]
        if top is not None and ph.steps and max(w for _, w in ph.steps) >= top * (1 - 1e-6)
    ]
    if at_top:
        notes.append(f"limits.max_power_W binds: {top:g} W in {', '.join(at_top)}")
    caps = limits.temperature_limits(programme)
    if not caps:
        return programme, tuple(notes)
    thetas = prior.thetas() or [prior.theta]

    def excess(factor: float) -> tuple[float, str]:
        highest = limits.peaks(prior.structure, thetas, _powers_scaled(programme, factor))
        over = {s: highest[s] - cap for s, cap in caps.items()}
        state = max(over, key=lambda s: over[s] if math.isfinite(over[s]) else math.inf)
        return over[state], state

    first, state = excess(1.0)
    if first <= 0:
        return programme, tuple(notes)
    key = limits.LIMIT_KEYS[state]
    if excess(0.0)[0] > 0:
        raise ConfigError(
            programme.where,
            f"limits.{key}",
            caps[state],
            f"{limits.WHAT[state]} exceeds it without any heating after the first phase: "
            "the first phase or the tunnel's temperatures are beyond it; lower the first "
            "phase's heating or tunnel temperature, or raise the limit",
        )
    lo, hi = 0.0, 1.0
    for _ in range(20):  # the largest factor within the limit
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if excess(mid)[0] > 0 else (mid, hi)
    notes = [n for n in notes if not n.startswith("limits.max_power_W")]
    notes.append(
        f"limits.{key} binds: the heating after the first phase scaled by {lo:.3g} keeps "
        f"{limits.WHAT[state]} at most {caps[state]:g} degC at the prior's upper band"
    )
    return _powers_scaled(programme, lo), tuple(notes)
