"""Virtual tunnel runs of a planned programme: a check of the design's prediction that does not
trust its linearisation.

Each run simulates the programme at the prior's central parameters (eqs. 7-8 driven by the
planned inputs, from the programme's start) and records it as the tunnel's instruments would,
with every error the programme declares drawn anew: each compared state's sensor noise (white,
or with the prior's residual autocorrelation time, as an AR(1) process of the same integrated
time), each sensor group's offset and the tunnel air's, the power meters' scale, the logged
inputs' white noise and an error of the static kA of its own (``systematic.kA_rel``). The
record is then fitted as the study's two-stage fit fits it: kA from the static k window (eq.
10, or the storage-corrected balance solved together with the fit by the study's own solver,
:func:`railtherm.study.storage.solve_storage_kA`, eq. 10's where it finds none), the
capacities by simulation-error PEM (eqs. 15-20) with each fit window's initial states
estimated. The spread of log theta over the runs is the
realised width; where it differs from the prediction by more than a quarter, the linear
prediction does not describe this programme (a parameter barely determined, a loop of kA and
capacities near 1).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from railtherm.estimation import models, pem
from railtherm.study import kwindow
from railtherm.study.programme import (
    Programme,
    fit_windows,
    initial_state,
    k_window_rows,
    programme_inputs,
)

__all__ = ["DIFFER", "Replicates", "markdown", "run", "run_for"]

DIFFER = 0.25  # realised and predicted widths differing by more than this share are flagged
# the fits start at the parameters the runs are simulated with; only their estimates are used
FAST = {"start": "initial", "covariance": "iid"}


@dataclass(frozen=True)
class Replicates:
    """``n`` virtual runs of a programme: per estimated parameter the predicted sd of log
    theta (``predicted``), the sd of log(estimate) over the runs (``realised``) and the
    mean of log(estimate / truth) (``bias``; printed as the geometric mean's change,
    exp(bias) - 1, above -100 % for a positive parameter); ``failed`` the runs whose fit
    failed."""

    n: int
    predicted: dict[str, float]
    realised: dict[str, float]
    bias: dict[str, float]
    failed: int = 0

    def ratio(self, p: str) -> float:
        """Realised / predicted sd of log theta."""
        return self.realised[p] / self.predicted[p] if self.predicted[p] > 0 else math.inf

    def ratio_interval(self, p: str) -> tuple[float, float]:
        """The 90 % interval of realised / predicted that ``n`` runs give (the realised sd's
        chi-square law with n - 1 degrees of freedom)."""
        from scipy.special import chdtri

        dof = self.n - 1
        if dof < 1:
            return (0.0, math.inf)
        r = self.ratio(p)
        return (r * math.sqrt(dof / chdtri(dof, 0.05)), r * math.sqrt(dof / chdtri(dof, 0.95)))

    def outside(self, p: str) -> bool:
        """Whether realised / predicted lies more than :data:`DIFFER` from 1."""
        r = self.ratio(p)
        return not (1.0 / (1.0 + DIFFER) <= r <= 1.0 + DIFFER)

    def differs(self, p: str) -> bool:
        """Whether realised and predicted differ by more than :data:`DIFFER`, beyond what the
        runs can tell: the ratio outside the band and its 90 % interval away from 1 (two
        runs said "differ" on a ratio of 0.38 whose interval reaches 6)."""
        lo, hi = self.ratio_interval(p)
        return self.outside(p) and not lo <= 1.0 <= hi


def _noise(rng: np.random.Generator, n: int, sd: float, tau: float) -> np.ndarray:
    """White noise of ``sd``, or an AR(1) process of that sd whose integrated
    autocorrelation time is ``tau`` samples: (1 + phi) / (1 - phi) = tau."""
    if sd <= 0:
        return np.zeros(n)
    phi = (tau - 1.0) / (tau + 1.0) if tau > 1.0 else 0.0
    e = rng.normal(0.0, sd * math.sqrt(1.0 - phi**2), n)
    out = np.empty(n)
    out[0] = rng.normal(0.0, sd)
    for i in range(1, n):
        out[i] = phi * out[i - 1] + e[i]
    return out


def _static_kA(structure, programme, logged, y, outputs, theta, records, free) -> float:
    """The two-stage fit's kA from the record: eq. 10 over the k window, or the storage-
    corrected balance solved with the fit as the study solves it
    (:func:`railtherm.study.storage.solve_storage_kA`), eq. 10's where that finds none (a
    capacity at a search bound, a balance that does not settle), as the study falls back."""
    a, b = k_window_rows(programme)
    T = y[a:b, outputs.index("T")]
    excess = T - logged[a:b, 0]
    eq10 = float(np.sum(logged[a:b, 1]) / np.sum(excess))
    if not (programme.storage_correction and kwindow.storage_parameters(structure)):
        return eq10
    import pandas as pd

    from railtherm.study.storage import solve_storage_kA

    window = pd.DataFrame(
        {"time": np.arange(b - a) * programme.step_s, "T": T}
        | {"T_o": logged[a:b, 0], "Q_H": logged[a:b, 1]}
        | ({"T_veh": y[a:b, outputs.index("T_veh")]} if "T_veh" in outputs else {})
    )
    options = {
        "fixed": {"kA": eq10},
        "initial": {p: theta[p] for p in free},
        "bounds": {},
        "x0": "estimated",
        **FAST,
    }
    try:
        step, _, _ = solve_storage_kA(structure, records, options, eq10, window)
    except (ValueError, np.linalg.LinAlgError, FloatingPointError):
        return eq10
    return step.kA_balance


def _one(structure, programme, theta, free, outputs, noise, tau, rng) -> dict[str, float]:
    u = programme_inputs(programme, structure, theta)
    x0 = initial_state(programme, structure, theta, u[0])
    x = models.simulate(structure, theta, u, programme.step_s, x0)
    idx = [structure.states.index(s) for s in outputs]
    sys_ = programme.systematic
    y = x[:, idx].copy()
    for j, s in enumerate(outputs):
        y[:, j] += rng.normal(0.0, sys_.get(s, 0.0)) + _noise(rng, len(y), noise[s], tau[s])
    logged = u[:, :2].copy()
    inputs = programme.input_noise
    logged[:, 0] += rng.normal(0.0, sys_.get("T_o", 0.0))
    logged[:, 0] += rng.normal(0.0, inputs.get("T_o", 0.0), len(u)) if inputs.get("T_o") else 0.0
    scale = 1.0 + rng.normal(0.0, sys_.get("power_rel", 0.0))
    jitter = (
        rng.normal(0.0, inputs.get("power_rel", 0.0), len(u)) if inputs.get("power_rel") else 0.0
    )
    logged[:, 1] *= scale * (1.0 + jitter)
    records = []
    for name, a, b in fit_windows(programme):
        series = np.full((b - a, len(structure.states)), math.nan)
        series[:, idx] = y[a:b]
        start = np.where(np.isfinite(series[0]), series[0], x[a])
        records.append(pem.Experiment(name, programme.step_s, logged[a:b], series, x0=start))
    if "kA" in free:
        start = {p: theta[p] for p in free}
        fit = pem.fit(structure, records, x0="estimated", initial=start, **FAST)
    else:  # stage two at the record's kA, as the study's identify fits it
        kA = _static_kA(structure, programme, logged, y, list(outputs), theta, records, free)
        kA *= math.exp(rng.normal(0.0, sys_.get("kA_rel", 0.0)))
        start = {p: theta[p] for p in free}
        fit = pem.fit(structure, records, fixed={"kA": kA}, x0="estimated", initial=start, **FAST)
    return {p: math.log(fit.theta[p] / theta[p]) for p in free}


def run(
    structure: models.Structure,
    theta: Mapping[str, float],
    programme: Programme,
    predicted: Mapping[str, float],
    n: int,
    seed: int = 0,
    *,
    free: tuple[str, ...] | None = None,
    noise_K: Mapping[str, float] | None = None,
    tau_samples: Mapping[str, float] | None = None,
) -> Replicates:
    """``n`` virtual tunnel runs of ``programme`` at ``theta`` (the module docstring),
    deterministic with ``seed``, against the ``predicted`` sd of log theta per parameter.

    Parameters
    ----------
    structure : Structure
        The model (its states compared where the programme gives them a noise).
    theta : mapping
        The parameters the runs are simulated with (the prior's centre).
    programme : Programme
        The planned programme with its declared errors.
    predicted : mapping
        The prediction's sd of log theta per estimated parameter.
    n : int
        The runs.
    seed : int
        Their seed.
    free : tuple of str, optional
        The parameters the fit estimates (default every one but kA).
    noise_K, tau_samples : mapping, optional
        The residual sd and autocorrelation time per output (a prior fit's), in place of the
        programme's white sensor noise.

    Returns
    -------
    Replicates
    """
    free = tuple(p for p in structure.parameters if p != "kA") if free is None else free
    noise = {**programme.noise_K, **(noise_K or {})}
    outputs = tuple(s for s in structure.states if s in programme.noise_K)
    tau = {s: float((tau_samples or {}).get(s, 1.0)) for s in outputs}
    logs, failed = [], 0
    for i in range(n):
        rng = np.random.default_rng(np.random.SeedSequence([seed, i]))
        try:
            logs.append(_one(structure, programme, theta, free, outputs, noise, tau, rng))
        except (ValueError, np.linalg.LinAlgError, FloatingPointError, RuntimeError):
            failed += 1
    realised = {
        p: float(np.std([r[p] for r in logs], ddof=1)) if len(logs) > 1 else math.nan for p in free
    }
    bias = {p: float(np.mean([r[p] for r in logs])) if logs else math.nan for p in free}
    return Replicates(len(logs), {p: float(predicted[p]) for p in free}, realised, bias, failed)


def run_for(prior, programme: Programme, assessment, options) -> Replicates:
    """:func:`run` of ``programme`` for a design prior (:class:`railtherm.study.design.Prior`)
    against its ``assessment``'s central prediction, ``options.replicates`` runs with seed
    ``options.seed`` (``railtherm design --replicates``)."""
    return run(
        prior.structure,
        prior.theta,
        programme,
        assessment.central.sd_log,
        options.replicates,
        options.seed,
        free=prior.free,
        noise_K=prior.noise_K,
        tau_samples=prior.tau_at(programme.step_s),
    )


def markdown(replicates: Replicates) -> str:
    """The runs against the prediction: per parameter the predicted and realised 95 %
    half-widths, their ratio and the bias of the mean, and where they differ by more than a
    quarter, a line that says so."""
    r = replicates

    def half(sd: float) -> str:
        return f"{100 * math.expm1(1.959964 * sd):.3g} %" if math.isfinite(sd) else "none"

    lines = [
        f"Virtual tunnel runs: {r.n} runs of the programme at the prior's central parameters, "
        "every declared error drawn anew, each fitted as the study's two-stage fit"
        + (f" ({r.failed} fits failed)" if r.failed else "")
        + ".",
        "",
        "| parameter | predicted ± (95 %) | realised ± (95 %) | realised / predicted | bias |",
        "|---|---|---|---|---|",
    ]
    for p in r.predicted:
        ratio = r.ratio(p)
        # the bias as the geometric mean's change, exp(mean log(estimate / truth)) - 1
        bias = f"{100 * math.expm1(r.bias[p]):+.3g} %" if math.isfinite(r.bias[p]) else "none"
        lines.append(
            f"| {p} | {half(r.predicted[p])} | {half(r.realised[p])} | "
            f"{f'{ratio:.2f}' if math.isfinite(ratio) else 'none'} | {bias} |"
        )
    if r.n < 2:
        lines += ["", f"{r.n} run{'s' if r.n != 1 else ''} fitted: no realised spread to compare."]
        return "\n".join(lines)
    differ = [p for p in r.predicted if r.differs(p)]
    if differ:
        lines += [
            "",
            f"Realised and predicted differ by more than {100 * DIFFER:g} % for "
            f"{', '.join(differ)}: the linear prediction does not describe this programme there.",
        ]
    unsure = [p for p in r.predicted if r.outside(p) and not r.differs(p)]
    if unsure:
        spans = ", ".join(
            f"{p} [{r.ratio_interval(p)[0]:.2g}, {r.ratio_interval(p)[1]:.2g}]" for p in unsure
        )
        lines += [
            "",
            f"{r.n} runs cannot tell a ratio of 1 from the one found for {', '.join(unsure)} "
            f"(90 % intervals of realised / predicted: {spans}): run more.",
        ]
    return "\n".join(lines)
