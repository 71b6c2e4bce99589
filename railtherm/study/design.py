"""The uncertainty a planned climatic-wind-tunnel programme will give, before the tunnel runs.

A programme is data (:class:`Programme`, :func:`load_programme`): phases of given duration,
tunnel temperature T_o and heating power Q_H (held, or steps within the phase), the logger
step, and the standard deviation of the measurement noise of each compared state. For a
structure and a prior parameter set theta, the expected covariance of the log parameters of
the simulation-error fit (eqs. 17-18) is the inverse of the Fisher information of the planned
record,

    F = sum_j (1 / sigma_j^2) S_j^T S_j,   S_j[n, :] = d y_j[n] / d(log theta, x0),

with the exact output sensitivities of :func:`railtherm.estimation.models.sensitivities` (the
initial states estimated, as the fits estimate them) and sigma_j the noise of output j. A
residual that is not white carries fewer independent samples: its integrated autocorrelation
time tau (in samples) scales the variance by tau (:func:`predict`, ``tau_samples``). The
prediction is the Cramér-Rao bound of an unbiased estimate under the model: it assumes the
structure right and the noise as declared; it says nothing of a heat path the model lacks.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from railtherm.errors import ConfigError
from railtherm.estimation import models
from railtherm.estimation.pem import Z95
from railtherm.yamlio import read_yaml

__all__ = ["Phase", "Prediction", "Programme", "load_programme", "predict", "programme_inputs"]

# an information matrix whose condition number exceeds this leaves some direction of the
# parameters undetermined by the record: those parameters are "not identifiable" by it
COND_MAX = 1e12
# a predicted 95 % interval wider than this factor in total (hi / lo) is no estimate either,
# as for a fitted one (railtherm.estimation.pem.identification)
UNBOUNDED_FACTOR = 1e3


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
    measurement noise (K, one standard deviation) of each compared state ``noise_K``."""

    name: str
    phases: tuple[Phase, ...]
    step_s: float
    noise_K: Mapping[str, float] = field(default_factory=dict)

    @property
    def hours(self) -> float:
        return sum(p.hours for p in self.phases)


def _number(file: str, key: str, value: Any, low: float = 0.0, strict: bool = True) -> float:
    ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
    if not ok or (value <= low if strict else value < low):
        bound = f"> {low:g}" if strict else f">= {low:g}"
        raise ConfigError(file, key, value, f"expected a number {bound}")
    return float(value)


def load_programme(path: str | Path) -> Programme:
    """Read and check a programme file (YAML): ``name``, ``step_s``, ``noise_K`` ({state: K})
    and ``phases``, each with ``hours``, ``T_o_C`` and either ``power_W`` or ``steps`` (a list
    of [hours from the phase's start, W], the first at 0). Any mistake is a
    :class:`ConfigError` naming the file, the key and the value."""
    file = str(path)
    data = read_yaml(path, display=file)
    if not isinstance(data, Mapping):
        raise ConfigError(file, "(root)", data, "expected a mapping (name, step_s, phases)")
    known = {"name", "step_s", "noise_K", "phases", "description"}
    for key in data:
        if key not in known:
            raise ConfigError(file, key, data[key], f"unknown key; known: {sorted(known)}")
    step = _number(file, "step_s", data.get("step_s"))
    noise = data.get("noise_K", {"T": 0.05})
    if not isinstance(noise, Mapping) or not noise:
        raise ConfigError(file, "noise_K", noise, "expected {state: standard deviation in K}")
    noise_K = {str(s): _number(file, f"noise_K.{s}", v) for s, v in noise.items()}
    raw_phases = data.get("phases")
    if not isinstance(raw_phases, list) or not raw_phases:
        raise ConfigError(file, "phases", raw_phases, "expected a list of phases")
    phases = []
    for i, ph in enumerate(raw_phases):
        key = f"phases[{i}]"
        if not isinstance(ph, Mapping):
            raise ConfigError(file, key, ph, "expected a mapping (hours, T_o_C, power_W)")
        hours = _number(file, f"{key}.hours", ph.get("hours"))
        T_o = ph.get("T_o_C")
        if not (isinstance(T_o, int | float) and not isinstance(T_o, bool) and -60 <= T_o <= 60):
            raise ConfigError(file, f"{key}.T_o_C", T_o, "expected a temperature -60..60 degC")
        if ("power_W" in ph) == ("steps" in ph):
            raise ConfigError(file, key, dict(ph), "give power_W or steps, one of them")
        if "power_W" in ph:
            steps = ((0.0, _number(file, f"{key}.power_W", ph["power_W"], strict=False)),)
        else:
            raw = ph["steps"]
            if not isinstance(raw, list) or not raw:
                raise ConfigError(file, f"{key}.steps", raw, "expected [[hours, W], ...]")
            steps = []
            for j, st in enumerate(raw):
                if not (isinstance(st, list | tuple) and len(st) == 2):
                    raise ConfigError(file, f"{key}.steps[{j}]", st, "expected [hours, W]")
                at = _number(file, f"{key}.steps[{j}][0]", st[0], strict=False)
                watts = _number(file, f"{key}.steps[{j}][1]", st[1], strict=False)
                if (j == 0 and at != 0) or (j and at <= steps[-1][0]) or at >= hours:
                    raise ConfigError(
                        file,
                        f"{key}.steps[{j}][0]",
                        st[0],
                        "steps start at 0 and rise strictly within the phase's hours",
                    )
                steps.append((at, watts))
            steps = tuple(steps)
        phases.append(Phase(str(ph.get("name", f"phase {i + 1}")), hours, float(T_o), steps))
    return Programme(str(data.get("name", Path(file).stem)), tuple(phases), step, noise_K)


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
    ``condition`` the condition number of the information matrix."""

    structure: str
    sd_log: dict[str, float]
    half_width: dict[str, float]
    identifiable: dict[str, bool]
    condition: float


def predict(
    structure: models.Structure,
    theta: Mapping[str, float],
    programme: Programme,
    *,
    free: Sequence[str] | None = None,
    outputs: Sequence[str] | None = None,
    x0: Sequence[float] | None = None,
    tau_samples: float = 1.0,
) -> Prediction:
    """The Fisher-information prediction of the module docstring for the parameters ``free``
    (default: every parameter but kA, as the paper's two-stage fit estimates them), compared
    on ``outputs`` (default: the states the programme gives a noise for), the initial states
    estimated (nuisance unknowns), from ``x0`` (default: every state at the first T_o, the
    vehicle soaked). ``tau_samples``: the residuals' integrated autocorrelation time in
    samples (1 for white noise)."""
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
    _, sens, free_resp = models.sensitivities(
        structure, theta, u, programme.step_s, x0, params=free
    )
    blocks = []
    for s in outputs:
        j = structure.states.index(s)
        cols = [theta[p] * sens[p][:, j] for p in free]  # d y / d log theta
        cols += [free_resp[:, j, k] for k in range(len(structure.states))]  # d y / d x0
        blocks.append(np.column_stack(cols) / programme.noise_K[s])
    S = np.concatenate(blocks)
    F = S.T @ S
    scale = np.sqrt(np.diag(F))
    scale[scale == 0] = 1.0
    Fn = F / np.outer(scale, scale)
    eig = np.linalg.eigvalsh(Fn)
    condition = float(eig[-1] / eig[0]) if eig[0] > 0 else math.inf
    P = len(free)
    if not math.isfinite(condition) or condition > COND_MAX:
        sd = {p: math.inf for p in free}
    else:
        cov = np.linalg.inv(Fn) / np.outer(scale, scale) * float(tau_samples)
        sd = {p: float(math.sqrt(max(cov[i, i], 0.0))) for i, p in enumerate(free[:P])}
    # a record that does not move a parameter leaves its sd huge (or infinite): no width
    half = {p: (math.expm1(Z95 * v) if Z95 * v < 700.0 else math.inf) for p, v in sd.items()}
    limit = math.log(UNBOUNDED_FACTOR)
    identifiable = {p: 2.0 * Z95 * v <= limit for p, v in sd.items()}
    return Prediction(structure.name, sd, half, identifiable, condition)
