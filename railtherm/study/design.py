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

from railtherm.errors import ConfigError
from railtherm.estimation import models
from railtherm.estimation.pem import Z95, identification
from railtherm.yamlio import check_finite, packaged_schema, read_yaml, validate_schema

__all__ = [
    "Assessment",
    "Phase",
    "Prediction",
    "Prior",
    "Programme",
    "assess",
    "best_of_length",
    "load_programme",
    "markdown",
    "parse_target",
    "predict",
    "prior_for_class",
    "prior_from_fit",
    "prior_from_reference",
    "programme_inputs",
    "residuals_of",
    "scaled",
    "shortest",
]

# an information matrix whose condition number exceeds this leaves some direction of the
# parameters undetermined by the record: those parameters are "not identifiable" by it
COND_MAX = 1e12


@dataclass(frozen=True)
class Phase:
    """One phase of a programme: ``hours`` long at tunnel temperature ``T_o_C``, heating
    ``power_W`` held, or ``steps``: [(hours from the phase's start, W), ...] with the first at
    0."""

    name: str
    hours: float
    T_o_C: float
    steps: tuple[tuple[float, float], ...]


@dataclass(frozen=True)
class Programme:
    """A planned tunnel programme: its phases in order, the logger step ``step_s``, and the
    measurement noise (K, one standard deviation) of each compared state ``noise_K``, and the
    standard uncertainties of its systematic errors ``systematic``: an offset (K) of a
    compared state's sensors or of T_o, and ``power_rel``, the relative scale error of Q_H;
    ``limits``: what the heaters and the tunnel can do (``max_power_W``, ``min_T_o_C``,
    ``max_T_o_C``)."""

    name: str
    phases: tuple[Phase, ...]
    step_s: float
    noise_K: Mapping[str, float] = field(default_factory=dict)
    systematic: Mapping[str, float] = field(default_factory=dict)
    limits: Mapping[str, float] = field(default_factory=dict)

    @property
    def hours(self) -> float:
        return sum(p.hours for p in self.phases)


def load_programme(path: str | Path) -> Programme:
    """Read and check a programme file (YAML, ``railtherm/schemas/programme.schema.yaml``):
    ``name``, ``step_s``, ``noise_K`` ({state: K}), ``systematic`` ({T or T_veh or T_o:
    offset K, power_rel: scale}, standard uncertainties), ``limits`` (``max_power_W``,
    ``min_T_o_C``, ``max_T_o_C``) and ``phases``, each with ``hours``, ``T_o_C`` and either
    ``power_W`` or ``steps`` (a list of [hours from the phase's start, W], the first at 0,
    rising within the phase). Any mistake, or a phase beyond the limits, is a
    :class:`ConfigError` naming the file, the key and the value."""
    file = str(path)
    data = read_yaml(path, display=file)
    validate_schema(file, data, packaged_schema("programme"))
    check_finite(file, data)
    limits = {k: float(v) for k, v in data["limits"].items()}
    phases = []
    for i, ph in enumerate(data["phases"]):
        key = f"phases[{i}]"
        steps = [(0.0, ph["power_W"])] if "power_W" in ph else ph["steps"]
        for j, (at, _) in enumerate(steps):
            if (j == 0 and at != 0) or (j and at <= steps[j - 1][0]) or at >= ph["hours"]:
                raise ConfigError(
                    file,
                    f"{key}.steps[{j}][0]",
                    at,
                    "steps start at 0 and rise strictly within the phase's hours",
                )
        top = max(w for _, w in steps)
        if top > limits.get("max_power_W", math.inf):
            raise ConfigError(
                file, key, top, f"more power than limits.max_power_W {limits['max_power_W']:g} W"
            )
        if (
            not limits.get("min_T_o_C", -math.inf)
            <= ph["T_o_C"]
            <= limits.get("max_T_o_C", math.inf)
        ):
            raise ConfigError(
                file, f"{key}.T_o_C", ph["T_o_C"], "outside the tunnel's limits.min/max_T_o_C"
            )
        steps = tuple((float(at), float(w)) for at, w in steps)
        phases.append(
            Phase(
                str(ph.get("name", f"phase {i + 1}")), float(ph["hours"]), float(ph["T_o_C"]), steps
            )
        )
    noise = {str(s): float(v) for s, v in data["noise_K"].items()}
    systematic = {str(k): float(v) for k, v in data["systematic"].items()}
    name = str(data.get("name", Path(file).stem))
    return Programme(name, tuple(phases), float(data["step_s"]), noise, systematic, limits)


def programme_inputs(programme: Programme) -> np.ndarray:
    """The inputs u = [T_o, Q_H] (N x 2) of the programme on its logger grid, each held over
    the step that follows its sample (the paper's zero-order hold, eq. 15)."""
    rows = []
    for phase in programme.phases:
        n = int(round(phase.hours * 3600.0 / programme.step_s))
        t_h = np.arange(n) * programme.step_s / 3600.0
        at = np.array([s[0] for s in phase.steps])
        watts = np.array([s[1] for s in phase.steps])
        power = watts[np.searchsorted(at, t_h, side="right") - 1]
        rows.append(np.column_stack([np.full(n, phase.T_o_C), power]))
    return np.concatenate(rows)


@dataclass(frozen=True)
class Prediction:
    """The expected uncertainty of a fit of ``structure`` to the programme: per estimated
    parameter its standard deviation of log(theta) ``sd_log`` and its relative 95 % half-width
    ``half_width`` (the interval exp(+-1.96 sd_log), half its log width as a fraction:
    exp(1.96 sd_log) - 1), and whether the record determines it (``identifiable``);
    ``condition`` the condition number of the information matrix; ``sd_log_systematic`` the
    share of ``sd_log`` the programme's systematic errors give."""

    structure: str
    sd_log: dict[str, float]
    half_width: dict[str, float]
    identifiable: dict[str, bool]
    condition: float
    sd_log_systematic: dict[str, float] = field(default_factory=dict)


def _systematic_shifts(structure, theta, programme, u, x0, x, outputs, sens_kA=None):
    """The shift dy (N x outputs) of the record relative to the model, one per systematic
    source of the programme: an offset b of a compared state's sensors (dy = b), of T_o or a
    scale error of Q_H (the model driven by the biased inputs departs from the record by dx:
    dy = -dx). With ``sens_kA`` (the sensitivities, kA among them) kA is fixed by the static
    test on the same instruments, Q_H / (T - T_o) at the first phase's end, and its move
    shifts the model too."""
    idx = [structure.states.index(s) for s in outputs]
    k_end = int(round(programme.phases[0].hours * 3600.0 / programme.step_s)) - 1
    dT_k = float(x[k_end, 0] - u[k_end, 0])  # T - T_o at the end of the first (steady) phase
    for source, u_sys in programme.systematic.items():
        if source in outputs:
            dy = np.zeros((len(x), len(outputs)))
            dy[:, outputs.index(source)] = u_sys
        elif source in ("T_o", "power_rel"):
            du = np.zeros_like(u)
            du[:, 0 if source == "T_o" else 1] = u_sys * (1.0 if source == "T_o" else u[:, 1])
            dy = -(models.simulate(structure, theta, u + du, programme.step_s, x0) - x)[:, idx]
        else:
            continue
        if sens_kA is not None and dT_k != 0.0:  # d log kA of eq. 10's Q_H / (T - T_o)
            dlog_kA = {"power_rel": u_sys, "T": -u_sys / dT_k, "T_o": u_sys / dT_k}.get(source, 0.0)
            dy = dy - dlog_kA * theta["kA"] * sens_kA["kA"][:, idx]
        yield dy


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
    """The Fisher-information prediction of the module docstring for the parameters ``free``
    (default: every parameter but kA, as the paper's two-stage fit estimates them), compared
    on ``outputs`` (default: the states the programme gives a noise for), the initial states
    estimated (nuisance unknowns), from ``x0`` (default: every state at the first T_o, the
    vehicle soaked). ``tau_samples``: the residuals' integrated autocorrelation time in
    samples (1 for white noise), one for all outputs or one per output; ``noise_K``: the
    residual standard deviation per output, in place of the programme's sensor noise (a
    prior fit's RMSE, :class:`Prior`)."""
    noise = {**programme.noise_K, **(noise_K or {})}
    tau = (
        {s: float(tau_samples.get(s, 1.0)) for s in noise}
        if isinstance(tau_samples, Mapping)
        else dict.fromkeys(noise, float(tau_samples))
    )
    free = tuple(p for p in structure.parameters if p != "kA") if free is None else tuple(free)
    outputs = (
        tuple(s for s in structure.states if s in programme.noise_K)
        if outputs is None
        else tuple(outputs)
    )
    unknown = [s for s in outputs if s not in programme.noise_K or s not in structure.states]
    if unknown or not outputs:
        raise ValueError(f"outputs {list(outputs)}: each needs a state and a noise_K entry")
    u = programme_inputs(programme)
    x0 = np.full(len(structure.states), u[0, 0]) if x0 is None else np.asarray(x0, float)
    # a kA held fixed comes from the static test (eq. 10) on the same instruments: it moves
    # with their systematic errors, and the fit with it
    static = "kA" in structure.parameters and "kA" not in free
    x, sens, free_resp = models.sensitivities(
        structure, theta, u, programme.step_s, x0, params=free + (("kA",) if static else ())
    )
    idx = [structure.states.index(s) for s in outputs]
    # J: d y / d (log theta, x0) of every compared sample, output by output (eq. 17's e),
    # its columns scaled to unit length for the inverse
    J = np.concatenate(
        [
            np.column_stack(
                [theta[p] * sens[p][:, j] for p in free]
                + [free_resp[:, j, k] for k in range(len(structure.states))]
            )
            for j in idx
        ]
    )
    scale = np.sqrt(np.einsum("ij,ij->j", J, J))
    scale[scale == 0] = 1.0
    Jn = J / scale
    H = Jn.T @ Jn
    eig = np.linalg.eigvalsh(H)
    condition = float(eig[-1] / eig[0]) if eig[0] > 0 else math.inf
    if not math.isfinite(condition) or condition > COND_MAX:
        sd = sd_sys = dict.fromkeys(free, math.inf)
    else:
        # the unweighted least squares of eq. 17 with noise of variance sigma_j^2 tau_j per
        # output (tau samples carry the information of one): the sandwich A J^T W J A
        A = np.linalg.inv(H)
        weight = np.repeat([noise[s] ** 2 * max(tau[s], 1.0) for s in outputs], len(x))
        cov = A @ (Jn.T @ (weight[:, None] * Jn)) @ A / np.outer(scale, scale)
        response = A @ Jn.T  # the fit's linear response to a shift of the record
        shifts = [
            (response @ dy.T.reshape(-1)) / scale
            for dy in _systematic_shifts(
                structure, theta, programme, u, x0, x, outputs, sens if static else None
            )
        ]
        systematic = np.sum(np.square(shifts), axis=0) if shifts else np.zeros(len(scale))
        sd = {p: float(math.sqrt(max(cov[i, i] + systematic[i], 0.0))) for i, p in enumerate(free)}
        sd_sys = {p: float(math.sqrt(systematic[i])) for i, p in enumerate(free)}
    # a record that does not move a parameter leaves its sd huge (or infinite): no width
    half = {p: (math.expm1(Z95 * v) if Z95 * v < 700.0 else math.inf) for p, v in sd.items()}
    # the fits' own rule on the predicted interval of theta * exp(+-1.96 sd)
    identifiable = {
        p: identification(1.0, (math.exp(-Z95 * v), math.inf if h == math.inf else 1.0 + h))[
            "identified"
        ]
        for (p, v), h in zip(sd.items(), half.values(), strict=True)
    }
    return Prediction(structure.name, sd, half, identifiable, condition, sd_sys)


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


def prior_from_fit(fit) -> Prior:
    """The prior of a vehicle measured before (:class:`railtherm.study.fit.Fit`): its
    estimates, the parameters it estimated (kA fixed by the static test stays fixed), and per
    compared output the residual RMSE and autocorrelation time its record showed (in samples
    of that record: the programme is taken at the same logger step)."""
    measures = fit.data.get("measures") or {}
    noise = {s: float(m["overall"]["rmse"]) for s, m in measures.items()}
    tau = {s: float(m["overall"].get("autocorrelation_time", 1.0)) for s, m in measures.items()}
    estimated = {p for p, q in fit.parameters.items() if q.estimated is True}
    structure = fit.structure
    free = tuple(p for p in structure.parameters if p in estimated)
    source = f"the fit {fit.model} of {fit.vehicle}"
    return Prior(structure, dict(fit.theta), free, source, None, noise, tau)


def residuals_of(fits) -> tuple[dict[str, float], dict[str, float]]:
    """The residual level a class's fits show: per compared output the median RMSE and the
    median autocorrelation time (samples) over ``fits`` (:class:`railtherm.study.fit.Fit`)
    whose verdict is acceptable; ({}, {}) without one."""
    from railtherm.study.quality import ACCEPTABLE

    rmse: dict[str, list[float]] = {}
    tau: dict[str, list[float]] = {}
    for fit in fits:
        if fit.verdict != ACCEPTABLE:
            continue
        for state, m in (fit.data.get("measures") or {}).items():
            rmse.setdefault(state, []).append(float(m["overall"]["rmse"]))
            tau.setdefault(state, []).append(float(m["overall"].get("autocorrelation_time", 1)))
    return (
        {s: float(np.median(v)) for s, v in rmse.items()},
        {s: float(np.median(v)) for s, v in tau.items()},
    )


def prior_from_reference(model, n: int = 200, seed: int = 0, fits=()) -> Prior:
    """The prior of an unmeasured vehicle from its class reference model
    (:class:`railtherm.study.classmodel.ReferenceModel`): its central parameters and ``n``
    draws of a new vehicle of the class (deterministic with ``seed``); kA fixed, as the
    two-stage fit fixes it from the static test. ``fits``: the class's fits, whose residual
    level (:func:`residuals_of`) replaces the programme's sensor noise."""
    structure = models.STRUCTURES[model.structure]
    draws = model.draws(n, seed)
    keep = np.all([np.isfinite(v) & (v > 0) for v in draws.values()], axis=0)
    draws = {p: v[keep] for p, v in draws.items()}
    free = tuple(p for p in structure.parameters if p != "kA")
    source = (
        f"the {model.vehicle_class} reference model ({model.mass_kg:g} kg, "
        f"{model.surface_m2:g} m², {len(model.basis)} vehicles)"
    )
    noise, tau = residuals_of(fits)
    return Prior(structure, dict(model.theta), free, source, draws, noise, tau)


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
    from railtherm.study.fit import read_fit

    members = classmodel.members_from_study(config, results, workdir=workdir)
    model = classmodel.build(members, vehicle_class, mass_kg, surface_m2)
    paths = [Path(workdir, results, "vehicles", vid, "fit_order2.yaml") for vid in model.basis]
    fits = [read_fit(path) for path in paths if path.is_file()]
    return prior_from_reference(model, n, seed, fits)


# ------------------------------------------------------------------------------------------
# assessment and design


def parse_target(text: str) -> tuple[str, float]:
    """``"C_veh=5%"`` -> ("C_veh", 0.05): a parameter and its target relative 95 % half-width.
    A text of another form is a :class:`ConfigError` naming ``--target``."""
    name, sep, value = str(text).partition("=")
    number = value.strip().removesuffix("%")
    try:
        fraction = float(number) / 100.0
    except ValueError:
        fraction = math.nan
    if not sep or not name.strip() or not (math.isfinite(fraction) and fraction > 0):
        raise ConfigError("--target", "target", text, "expected PARAMETER=PERCENT, e.g. C_veh=5%")
    return name.strip(), fraction


@dataclass(frozen=True)
class Assessment:
    """A programme judged for a prior: the prediction at the central parameters
    (``central``), and over the prior's draws each parameter's median and 5 / 95 % quantiles
    of the relative 95 % half-width (``spread``: {param: (q05, median, q95)}), the share of
    draws in which it is identifiable (``identifiable``) and, for a ``target`` (param,
    half-width), the probability to reach it (``probability``)."""

    programme: Programme
    prior: Prior
    central: Prediction
    spread: dict[str, tuple[float, float, float]]
    identifiable: dict[str, float]
    target: tuple[str, float] | None = None
    probability: float | None = None


def assess(
    prior: Prior, programme: Programme, target: tuple[str, float] | None = None
) -> Assessment:
    """The :class:`Assessment` of ``programme`` for ``prior`` (every draw predicted; a prior
    without draws is its central parameters alone)."""
    if target is not None and target[0] not in prior.free:
        raise ConfigError(
            "--target", "target", target[0], f"not a parameter the fit estimates: {prior.free}"
        )

    def one(theta: Mapping[str, float]) -> Prediction:
        return predict(
            prior.structure,
            theta,
            programme,
            free=prior.free,
            tau_samples=prior.tau_samples or 1.0,
            noise_K=prior.noise_K,
        )

    central = one(prior.theta)
    if prior.draws:
        n = len(next(iter(prior.draws.values())))
        runs = [one({p: float(v[i]) for p, v in prior.draws.items()}) for i in range(n)]
    else:
        runs = [central]
    spread, identifiable = {}, {}
    for p in prior.free:
        widths = np.array([r.half_width[p] for r in runs])
        q05, q50, q95 = np.quantile(widths, [0.05, 0.5, 0.95], method="inverted_cdf")
        spread[p] = (float(q05), float(q50), float(q95))
        identifiable[p] = float(np.mean([r.identifiable[p] for r in runs]))
    probability = None
    if target is not None:
        name, goal = target
        probability = float(
            np.mean([r.identifiable[name] and r.half_width[name] <= goal for r in runs])
        )
    return Assessment(programme, prior, central, spread, identifiable, target, probability)


def scaled(programme: Programme, factor: float) -> Programme:
    """The programme with every phase (and every step within it) ``factor`` times as long."""
    phases = tuple(
        Phase(
            ph.name,
            ph.hours * factor,
            ph.T_o_C,
            tuple((at * factor, watts) for at, watts in ph.steps),
        )
        for ph in programme.phases
    )
    name = f"{programme.name} x{factor:.3g}"
    return replace(programme, name=name, phases=phases)


def shortest(
    prior: Prior,
    programme: Programme,
    target: tuple[str, float],
    probability: float = 0.9,
    factors: Sequence[float] = tuple(np.round(np.geomspace(0.25, 4.0, 17), 4)),
) -> tuple[float, Assessment] | None:
    """The shortest version of ``programme``'s shape (its phases in proportion, each scaled by
    one of ``factors``) whose :func:`assess` reaches ``target`` with at least
    ``probability``; (factor, its assessment), or None when even the longest does not. The
    factors are bisected: a longer programme of the same shape is taken to inform no less."""
    ordered = sorted(float(f) for f in factors)
    found: dict[float, Assessment] = {}

    def reaches(factor: float) -> bool:  # each factor assessed once
        if factor not in found:
            found[factor] = assess(prior, scaled(programme, factor), target)
        return (found[factor].probability or 0.0) >= probability

    if not reaches(ordered[-1]):
        return None
    lo, hi = -1, len(ordered) - 1  # a longer programme of the same shape informs more:
    while hi - lo > 1:  # bisect for the first factor that reaches the target
        mid = (lo + hi) // 2
        if reaches(ordered[mid]):
            hi = mid
        else:
            lo = mid
    return ordered[hi], found[ordered[hi]]


def best_of_length(
    prior: Prior,
    programme: Programme,
    target: str,
    hours: float | None = None,
    max_power_W: float | None = None,
    min_phase_h: float = 1.0,
) -> tuple[Programme, Assessment]:
    """The programme of ``hours`` (default: ``programme``'s own length) that gives the
    narrowest predicted interval of ``target`` at the prior's central parameters. The first
    phase stays as given: it ends with the static k window (eq. 10), which needs its steady
    state. The later phases keep their order and tunnel temperatures; each one's duration (at
    least ``min_phase_h``) and held power (0 to ``max_power_W``, default the programme's
    ``limits.max_power_W``, else its largest power) are chosen by Nelder-Mead, started from
    ``programme`` scaled to ``hours``. The result is then assessed over the prior's draws. A
    later phase with steps, or a length that leaves the later phases less than ``min_phase_h`` each,
    is a :class:`ConfigError`."""
    from scipy.optimize import minimize

    first, rest = programme.phases[0], programme.phases[1:]
    for i, ph in enumerate(rest, start=1):
        if len(ph.steps) != 1:
            raise ConfigError(
                programme.name, f"phases[{i}].steps", ph.steps, "optimised phases hold power_W"
            )
    if target not in prior.free:
        raise ConfigError("--target", "target", target, f"not estimated: {prior.free}")
    total = programme.hours if hours is None else float(hours)
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
    power_max = float(max_power_W) if max_power_W is not None else power_max

    def build(z: np.ndarray) -> Programme:
        share = np.exp(z[:n] - z[:n].max())
        share /= share.sum()
        power = power_max / (1.0 + np.exp(-z[n:]))  # within (0, power_max)
        later = tuple(
            Phase(
                ph.name, min_phase_h + spare * float(share[i]), ph.T_o_C, ((0.0, float(power[i])),)
            )
            for i, ph in enumerate(rest)
        )
        name = f"{programme.name}, best of {total:g} h"
        return replace(programme, name=name, phases=(first, *later))

    def width(z: np.ndarray) -> float:
        prediction = predict(
            prior.structure,
            prior.theta,
            build(z),
            free=prior.free,
            tau_samples=prior.tau_samples or 1.0,
            noise_K=prior.noise_K,
        )
        sd = prediction.sd_log[target]
        return float(np.log(sd)) if math.isfinite(sd) and sd > 0 else 1e6

    scale = (total - first.hours) / max(sum(ph.hours for ph in rest), 1e-9)
    hours0 = np.array([max(ph.hours * scale - min_phase_h, 1e-3) for ph in rest])
    p0 = np.clip([ph.steps[0][1] / power_max for ph in rest], 1e-3, 1 - 1e-3)
    z0 = np.concatenate([np.log(hours0), np.log(p0 / (1.0 - p0))])
    options = {"maxfev": 400, "xatol": 1e-3, "fatol": 1e-4}
    found = minimize(width, z0, method="Nelder-Mead", options=options)
    best = build(found.x if found.fun < width(z0) else z0)
    return best, assess(prior, best, (target, math.inf))


def markdown(assessment: Assessment) -> str:
    """The assessment for readers: per estimated parameter its predicted ± (95 %) at the
    central parameters, over the prior's draws the median and 90 % range, and the share of
    draws that identify it; then the target's probability."""
    a = assessment
    if a.prior.noise_K:
        level = ", ".join(
            f"{s} {a.prior.noise_K[s]:.3g} K (autocorrelation time "
            f"{a.prior.tau_samples.get(s, 1.0):.3g} samples)"
            for s in a.prior.noise_K
        )
        residuals = f"residuals as the prior's fits show them: {level}"
    else:
        noise = ", ".join(f"{s} {v:g} K" for s, v in a.programme.noise_K.items())
        residuals = f"residuals white at the programme's sensor noise: {noise}"
    systematic = ", ".join(f"{k} {v:g}" for k, v in a.programme.systematic.items()) or "none"
    lines = [
        f"Programme {a.programme.name} ({a.programme.hours:g} h, logger step "
        f"{a.programme.step_s:g} s) for {a.prior.source}; {residuals}; systematic "
        f"uncertainties: {systematic}.",
        "",
        "| parameter | predicted ± (95 %) | over the prior: median [5 %, 95 %] | identifiable |",
        "|---|---|---|---|",
    ]

    def pct(x: float) -> str:
        return "not identifiable" if not math.isfinite(x) else f"{100 * x:.3g} %"

    for p in a.prior.free:
        central = pct(a.central.half_width[p]) if a.central.identifiable[p] else "not identifiable"
        q05, q50, q95 = a.spread[p]
        lines.append(
            f"| {p} | {central} | {pct(q50)} [{pct(q05)}, {pct(q95)}] | "
            f"{100 * a.identifiable[p]:.0f} % of draws |"
        )
    if a.target is not None:
        name, goal = a.target
        lines += ["", f"{name} within ±{100 * goal:g} % with probability {a.probability:.2f}."]
    return "\n".join(lines)
