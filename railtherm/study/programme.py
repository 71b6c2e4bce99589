"""A planned climatic-wind-tunnel programme as data: its phases (tunnel temperature and heating
held, steps, a pseudo-random sequence or a thermostat), the logger step, the sensors' noise and
systematic uncertainties, the logged inputs' noise, the static k window and what the heaters
and the tunnel can do (``railtherm/schemas/programme.schema.yaml``); the inputs it gives on the
logger grid and the windows the fit compares. Read by :func:`load_programme`, written by
:func:`write_programme`; predicted by :mod:`railtherm.study.design`."""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from railtherm.errors import ConfigError
from railtherm.estimation import models
from railtherm.study import kwindow
from railtherm.yamlio import check_finite, packaged_schema, read_yaml, validate_schema

__all__ = [
    "Phase",
    "Programme",
    "check_out_path",
    "compared_rows",
    "fit_windows",
    "initial_state",
    "k_window_rows",
    "load_programme",
    "prbs_steps",
    "programme_dict",
    "programme_inputs",
    "schedule",
    "write_programme",
]


@dataclass(frozen=True)
class Phase:
    """One phase of a programme: ``hours`` long at tunnel temperature ``T_o_C``, heating
    ``power_W`` held, or ``steps``: [(hours from the phase's start, W), ...] with the first at
    0, or a thermostat holding the air at ``set_point_C`` (``steps`` empty). ``identify``:
    whether the fit compares the phase's records (a phase that only brings the vehicle to its
    state is left out), or a number of hours: its last hours compared; ``window``: the fit
    window (a record of its own, its initial states estimated anew) the phase belongs to."""

    name: str
    hours: float
    T_o_C: float
    steps: tuple[tuple[float, float], ...]
    set_point_C: float | None = None
    identify: bool | float = True
    window: str = "record"

    def describe(self) -> str:
        """The phase in a line: its duration, tunnel temperature and heating."""
        if self.set_point_C is not None:
            heating = f"thermostat at {self.set_point_C:g} degC"
        elif len(self.steps) == 1:
            heating = f"{self.steps[0][1]:,.0f} W"
        else:
            heating = ", ".join(f"{w:,.0f} W from {at:.3g} h" for at, w in self.steps)
        return f"{self.name}: {self.hours:.3g} h at {self.T_o_C:g} degC, {heating}"


@dataclass(frozen=True)
class Programme:
    """A planned tunnel programme: its phases in order, the logger step ``step_s``, and the
    measurement noise (K, one standard deviation) of each compared state ``noise_K``, and the
    standard uncertainties of its systematic errors ``systematic``: an offset (K) of a
    compared state's sensors or of T_o, and ``power_rel``, the relative scale error of Q_H;
    ``limits``: what the heaters and the tunnel can do (``max_power_W``, ``min_T_o_C``,
    ``max_T_o_C``); ``start``: the vehicle's state when the programme starts, ``soaked``
    (every state at the first T_o) or ``steady`` (the equilibrium of the first inputs);
    ``input_noise``: the white noise of the logged inputs (``T_o`` in K, ``power_rel``
    relative to Q_H); ``k_window_h``: the static k window, the first phase's last hours;
    ``storage_correction``: whether the fit's kA is eq. 10 corrected for the heat the body
    stores (the study's default, :mod:`railtherm.study.kwindow`)."""

    name: str
    phases: tuple[Phase, ...]
    step_s: float
    noise_K: Mapping[str, float] = field(default_factory=dict)
    systematic: Mapping[str, float] = field(default_factory=dict)
    limits: Mapping[str, float] = field(default_factory=dict)
    start: str = "soaked"
    input_noise: Mapping[str, float] = field(default_factory=dict)
    k_window_h: float = kwindow.K_WINDOW_H
    storage_correction: bool = True
    file: str = field(default="", compare=False)  # the file it was read from ("": in code)

    @property
    def where(self) -> str:
        """The file an error names: the programme file, else the programme's name."""
        return self.file or self.name

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
    given = set(data) if isinstance(data, dict) else set()
    validate_schema(file, data, packaged_schema("programme"))
    check_finite(file, data)
    limits = {k: float(v) for k, v in data["limits"].items()}
    phases = [_phase(file, i, ph, limits) for i, ph in enumerate(data["phases"])]
    if not any(ph.identify for ph in phases):
        raise ConfigError(file, "phases", "identify: false", "no phase is compared by the fit")
    _check_step(file, float(data["step_s"]), phases)
    _check_windows(file, phases)
    noise, systematic, inputs = _noise_and_offsets(file, data, given)
    name = str(data.get("name", Path(file).stem))
    start = str(data.get("start", "soaked"))
    k = data.get("kvalue") or {}
    hours = float(k.get("hours", min(kwindow.K_WINDOW_H, phases[0].hours)))
    if hours > phases[0].hours:
        raise ConfigError(
            file,
            "kvalue.hours",
            hours,
            f"longer than the first phase ({phases[0].name}, {phases[0].hours:g} h), whose "
            f"last hours are the static k window: give at most {phases[0].hours:g}",
        )
    return Programme(
        name,
        tuple(phases),
        float(data["step_s"]),
        noise,
        systematic,
        limits,
        start,
        inputs,
        hours,
        bool(k.get("storage_correction", True)),
        file,
    )


def _phase(file: str, i: int, ph: Mapping[str, Any], limits: Mapping[str, float]) -> Phase:
    """Phase ``i`` of a programme file checked against the tunnel's ``limits``: a held power,
    steps or a pseudo-random sequence (``prbs``, turned into steps), or a thermostat."""
    key = f"phases[{i}]"
    if "prbs" in ph:
        prbs = ph["prbs"]
        if prbs["low_W"] >= prbs["high_W"]:
            raise ConfigError(file, f"{key}.prbs.low_W", prbs["low_W"], "below high_W")
        if 2 * prbs["hold_h"] > ph["hours"]:
            # one bit fills the phase: a held power, not a sequence that excites
            raise ConfigError(
                file,
                f"{key}.prbs.hold_h",
                prbs["hold_h"],
                f"a bit held this long leaves the {ph['hours']:g} h phase at most one "
                f"switch, no pseudo-random sequence: give hold_h of at most "
                f"{ph['hours'] / 2:g} h (e.g. 1), or power_W / steps for a held power",
            )
        ph = {**ph, "steps": prbs_steps(ph["hours"], **prbs)}
    identify = ph.get("identify", True)
    if not isinstance(identify, bool) and identify > ph["hours"]:
        raise ConfigError(
            file,
            f"{key}.identify",
            identify,
            f"more hours than the phase's {ph['hours']:g}: the fit compares at most the "
            f"whole phase; give identify of at most {ph['hours']:g}, or true",
        )
    steps = (
        [(0.0, ph["power_W"])]
        if "power_W" in ph
        else ph.get("steps", [(0.0, limits.get("max_power_W", 0.0))])
    )
    if "set_point_C" in ph and "max_power_W" not in limits:
        raise ConfigError(
            file,
            f"{key}.set_point_C",
            ph["set_point_C"],
            "a thermostat needs limits.max_power_W",
        )
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
    if not limits.get("min_T_o_C", -math.inf) <= ph["T_o_C"] <= limits.get("max_T_o_C", math.inf):
        raise ConfigError(
            file, f"{key}.T_o_C", ph["T_o_C"], "outside the tunnel's limits.min/max_T_o_C"
        )
    thermostat = "set_point_C" in ph
    steps = () if thermostat else tuple((float(at), float(w)) for at, w in steps)
    return Phase(
        str(ph.get("name", f"phase {i + 1}")),
        float(ph["hours"]),
        float(ph["T_o_C"]),
        steps,
        float(ph["set_point_C"]) if thermostat else None,
        ph.get("identify", True),
        str(ph.get("window", "record")),
    )


def _check_windows(file: str, phases: Sequence[Phase]) -> None:
    """The compared phases of one window follow each other."""
    seen: list[str] = []
    for i, ph in enumerate(phases):
        if ph.identify and seen and ph.window != seen[-1] and ph.window in seen:
            raise ConfigError(
                file, f"phases[{i}].window", ph.window, "a window's phases follow each other"
            )
        if ph.identify and (not seen or ph.window != seen[-1]):
            seen.append(ph.window)


def _noise_and_offsets(
    file: str, data: Mapping[str, Any], given: set[str]
) -> tuple[dict[str, float], dict[str, float], dict[str, float]]:
    """``noise_K``, ``systematic`` and ``input_noise`` of a programme file, with each
    ``sensors`` group's noise and offset per sensor divided by the square root of its count
    (one reading averages them; the tunnel air's noise is an input's); a state given both
    ways is refused."""
    noise = {str(s): float(v) for s, v in data["noise_K"].items()}
    systematic = {str(k): float(v) for k, v in data["systematic"].items()}
    inputs = {str(k): float(v) for k, v in (data.get("input_noise") or {}).items()}
    if "T_o" in (data.get("sensors") or {}) and "noise_K" in data["sensors"]["T_o"]:
        if "T_o" in inputs:
            raise ConfigError(file, "input_noise.T_o", inputs["T_o"], "given by sensors.T_o too")
        group = data["sensors"]["T_o"]
        inputs["T_o"] = float(group["noise_K"]) / math.sqrt(float(group["count"]))
    if "sensors" in data:
        if "noise_K" not in given:
            noise = {}
        for state, group in data["sensors"].items():
            n = float(group["count"])
            for found, entry, value in (
                (noise, "noise_K", None if state == "T_o" else group.get("noise_K")),
                (systematic, "systematic", group.get("offset_K")),
            ):
                if value is None:
                    continue
                if state in found and entry in given:
                    raise ConfigError(
                        file, f"{entry}.{state}", found[state], f"given by sensors.{state} too"
                    )
                found[state] = float(value) / math.sqrt(n)
        if not noise:
            raise ConfigError(file, "sensors", data["sensors"], "no group with a noise_K")
    return noise, systematic, inputs


# a programme's record is simulated and differentiated whole: 10 million samples (a year at
# 3 s) is far beyond a tunnel test and still within memory; 1e9 h at 60 s asked for 447 GiB
MAX_SAMPLES = 10_000_000


def _check_step(file: str, step_s: float, phases: Sequence[Phase]) -> None:
    """Every phase, and every compared part of one, holds at least one logger sample of
    ``step_s``: a step longer than a phase (a logger step of a day against phases of hours)
    leaves it no sample, and a fit without samples determines nothing."""
    samples = [int(round(ph.hours * 3600.0 / step_s)) for ph in phases]
    if sum(samples) > MAX_SAMPLES:
        raise ConfigError(
            file,
            "step_s",
            step_s,
            f"{sum(samples):,} logger samples over the programme's "
            f"{sum(ph.hours for ph in phases):g} h, more than {MAX_SAMPLES:,} (a record a "
            "prediction holds in memory): give a longer step_s or shorter phases",
        )
    for i, (ph, n) in enumerate(zip(phases, samples, strict=True)):
        if n < 1:
            raise ConfigError(
                file,
                "step_s",
                step_s,
                f"longer than phases[{i}] ({ph.name}, {ph.hours:g} h = {ph.hours * 3600:g} s), "
                f"which gets no logger sample: give a step_s of at most "
                f"{min(p.hours for p in phases) * 3600 / 10:g} s (ten samples in the shortest "
                "phase), e.g. 60",
            )
    for i, (ph, n) in enumerate(zip(phases, samples, strict=True)):
        if not isinstance(ph.identify, bool) and _compared(ph, n, step_s) < 1:
            raise ConfigError(
                file,
                f"phases[{i}].identify",
                ph.identify,
                f"the compared {ph.identify:g} h hold no logger sample of step_s {step_s:g} s: "
                f"compare at least {step_s / 3600:g} h or give a shorter step_s",
            )


def prbs_steps(hours: float, low_W: float, high_W: float, hold_h: float) -> list:
    """A pseudo-random binary sequence of heating for a phase of ``hours``: a maximum-length
    sequence (``scipy.signal.max_len_seq``, the shortest whose period covers the phase) with
    each bit held ``hold_h``, high or low; as steps [hours from the phase's start, W], equal
    neighbours merged."""
    from scipy.signal import max_len_seq

    bits = max(2, math.ceil(math.log2(hours / hold_h + 1.0)))
    sequence = max_len_seq(bits)[0]
    steps: list[tuple[float, float]] = []
    for k in range(math.ceil(hours / hold_h)):
        level = float(high_W if sequence[k % len(sequence)] else low_W)
        if not steps or steps[-1][1] != level:
            steps.append((k * hold_h, level))
    return steps


def _phase_samples(programme: Programme) -> list[int]:
    return [int(round(ph.hours * 3600.0 / programme.step_s)) for ph in programme.phases]


def _compared(phase: Phase, n: int, step_s: float) -> int:
    """How many of the phase's ``n`` samples, at its end, the fit compares."""
    if isinstance(phase.identify, bool):
        return n if phase.identify else 0
    return min(n, int(round(float(phase.identify) * 3600.0 / step_s)))


def compared_rows(programme: Programme) -> np.ndarray:
    """Boolean (N,): the logger samples the fit compares (each phase's ``identify``)."""
    rows = []
    for ph, n in zip(programme.phases, _phase_samples(programme), strict=True):
        c = _compared(ph, n, programme.step_s)
        rows.append(np.arange(n) >= n - c)
    return np.concatenate(rows)


def fit_windows(programme: Programme) -> list[tuple[str, int, int]]:
    """The fit's windows as (name, first sample, end sample): consecutive compared samples of
    one ``window`` name form one record."""
    out: list[tuple[str, int, int]] = []
    start = 0
    for ph, n in zip(programme.phases, _phase_samples(programme), strict=True):
        c = _compared(ph, n, programme.step_s)
        if c:
            a = start + n - c
            if out and out[-1][0] == ph.window and out[-1][2] == a:
                out[-1] = (ph.window, out[-1][1], start + n)
            else:
                out.append((ph.window, a, start + n))
        start += n
    return out


def initial_state(
    programme: Programme,
    structure: models.Structure,
    theta: Mapping[str, float],
    u0: Sequence[float],
) -> np.ndarray:
    """The state at the programme's start: every state at the first T_o (``soaked``), or the
    equilibrium of the first inputs ``u0`` (``steady``; under a thermostat, the equilibrium at
    its set point)."""
    if programme.start != "steady":
        return np.full(len(structure.states), float(u0[0]))
    A, B = structure.matrices(theta)
    T_o, Q_H = float(u0[0]), float(u0[1])
    first = programme.phases[0]
    if first.set_point_C is not None:  # the thermostat's equilibrium at its set point
        cold = models.steady_state(A, B, np.array([T_o, 0.0])).reshape(-1)
        per_watt = models.steady_state(A, B, np.array([0.0, 1.0])).reshape(-1)
        Q_H = (first.set_point_C - cold[0]) / per_watt[0]
    return models.steady_state(A, B, np.array([T_o, Q_H])).reshape(-1)


def programme_inputs(
    programme: Programme,
    structure: models.Structure | None = None,
    theta: Mapping[str, float] | None = None,
) -> np.ndarray:
    """The inputs u = [T_o, Q_H] (N x 2) of the programme on its logger grid, each held over
    the step that follows its sample (the paper's zero-order hold, eq. 15). A thermostat
    phase sets, each step, the power that brings T to its set point at the step's end, within
    0 and ``limits.max_power_W``: that power follows the vehicle, so ``structure`` and
    ``theta`` (the model it is predicted with) are needed; the fit takes the power as logged,
    an input like any other."""
    rows = []
    rate = programme.limits.get("max_T_o_rate_K_per_h", math.inf)
    T_o = programme.phases[0].T_o_C  # the tunnel air at the phase's start
    for phase, n in zip(programme.phases, _phase_samples(programme), strict=True):
        t_h = np.arange(n) * programme.step_s / 3600.0
        if phase.set_point_C is not None:
            power = np.full(n, math.nan)  # set below, once the state is known
        else:
            at = np.array([s[0] for s in phase.steps])
            watts = np.array([s[1] for s in phase.steps])
            power = watts[np.searchsorted(at, t_h, side="right") - 1]
        # the tunnel ramps to the phase's temperature at its rate limit at most
        change = phase.T_o_C - T_o
        if math.isinf(rate):
            air, T_o = np.full(n, phase.T_o_C), phase.T_o_C
        else:
            air = T_o + np.sign(change) * np.minimum(rate * t_h, abs(change))
            T_o = T_o + math.copysign(min(rate * phase.hours, abs(change)), change)
        rows.append(np.column_stack([air, power]))
    u = np.concatenate(rows)
    if not np.isnan(u[:, 1]).any():
        return u
    if structure is None or theta is None:
        raise ValueError("a thermostat phase needs the structure and theta to set its power")
    A, B = structure.matrices(theta)
    Ad, Bd = models.discretize_zoh(A, B, programme.step_s)
    top = float(programme.limits["max_power_W"])
    x = initial_state(programme, structure, theta, u[0])
    ends = np.cumsum(_phase_samples(programme))
    for n in range(len(u)):
        if math.isnan(u[n, 1]):
            phase = programme.phases[int(np.searchsorted(ends, n, side="right"))]
            free = Ad[0] @ x + Bd[0, 0] * u[n, 0]
            u[n, 1] = min(max((phase.set_point_C - free) / Bd[0, 1], 0.0), top)
        x = Ad @ x + Bd @ u[n, :2]
    return u


def k_window_rows(programme: Programme) -> tuple[int, int]:
    """The static k window's samples [a, b): the first phase's last ``k_window_h``."""
    end = _phase_samples(programme)[0]
    n = int(round(programme.k_window_h * 3600.0 / programme.step_s))
    return max(end - max(n, 2), 0), end


def programme_dict(programme: Programme) -> dict[str, Any]:
    """The programme as its file holds it (:func:`load_programme` reads it back to the same
    :class:`Programme`): every phase with its heating (``power_W``, ``steps`` or
    ``set_point_C``), ``identify`` and ``window``; the noise, systematic uncertainties,
    inputs' noise, limits, start and static k window."""
    phases = []
    for ph in programme.phases:
        entry: dict[str, Any] = {"name": ph.name, "hours": float(ph.hours), "T_o_C": ph.T_o_C}
        if ph.set_point_C is not None:
            entry["set_point_C"] = float(ph.set_point_C)
        elif len(ph.steps) == 1:
            entry["power_W"] = float(ph.steps[0][1])
        else:
            entry["steps"] = [[float(at), float(w)] for at, w in ph.steps]
        entry["identify"] = ph.identify if isinstance(ph.identify, bool) else float(ph.identify)
        entry["window"] = ph.window
        phases.append(entry)
    return {
        "name": programme.name,
        "step_s": float(programme.step_s),
        "noise_K": {s: float(v) for s, v in programme.noise_K.items()},
        "systematic": {s: float(v) for s, v in programme.systematic.items()},
        "input_noise": {s: float(v) for s, v in programme.input_noise.items()},
        "limits": {s: float(v) for s, v in programme.limits.items()},
        "start": programme.start,
        "kvalue": {
            "hours": float(programme.k_window_h),
            "storage_correction": bool(programme.storage_correction),
        },
        "phases": phases,
    }


def schedule(programme: Programme) -> list[dict[str, Any]]:
    """The set points a tunnel controller takes: one row per held stretch (a phase, or a
    step within it), with its start and end (h from the programme's start), the tunnel air
    set point (degC) and the heating (W), or the cabin's thermostat set point (degC)."""
    rows, t0 = [], 0.0
    for ph in programme.phases:
        if ph.set_point_C is not None:
            stretches = [(0.0, ph.hours, None)]
        else:
            ends = [at for at, _ in ph.steps[1:]] + [ph.hours]
            stretches = [(at, end, w) for (at, w), end in zip(ph.steps, ends, strict=True)]
        for at, end, watts in stretches:
            rows.append(
                {
                    "start_h": round(t0 + at, 6),
                    "end_h": round(t0 + end, 6),
                    "phase": ph.name,
                    "T_o_set_C": ph.T_o_C,
                    "power_W": None if watts is None else round(float(watts), 3),
                    "T_set_C": ph.set_point_C,
                }
            )
        t0 += ph.hours
    return rows


def check_out_path(given: str, path: str | Path) -> None:
    """Where :func:`write_programme` is to write (``railtherm design --out``), checked before
    any search: a programme file (.yaml) in a directory that exists, its set-point schedule
    (.csv) beside it; else a :class:`ConfigError` naming ``--out`` and ``given``."""
    target = Path(path)
    problem = None
    if target.suffix.lower() not in (".yaml", ".yml"):
        problem = "expected a programme file ending in .yaml (its schedule goes beside it, .csv)"
    elif not target.parent.is_dir():
        problem = f"no directory {target.parent} to write into"
    elif target.is_dir() or target.with_suffix(".csv").is_dir():
        problem = f"a directory is there ({target} or {target.with_suffix('.csv')})"
    if problem:
        raise ConfigError("--out", "out", given, problem)


def write_programme(programme: Programme, path: str | Path) -> tuple[Path, Path]:
    """Write ``programme`` to ``path`` (YAML, :func:`programme_dict`) and its set-point
    :func:`schedule` beside it (the same name, ``.csv``; hours at 6 decimals, watts at 3).
    Returns both paths."""
    import csv

    import yaml

    path = Path(path)
    table = path.with_suffix(".csv")
    for target in (path, table):
        if target.is_dir():
            raise IsADirectoryError(f"{target} is a directory")
    text = yaml.safe_dump(programme_dict(programme), sort_keys=False, allow_unicode=True)
    rows = schedule(programme)
    # both written beside their places first, then moved there: no file is left half written
    # or alone where the second cannot be written
    parts = [path.with_name(f".{path.name}.part"), table.with_name(f".{table.name}.part")]
    try:
        parts[0].write_text(text, encoding="utf-8")
        with open(parts[1], "w", newline="", encoding="utf-8") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]), lineterminator="\n")
            writer.writeheader()
            writer.writerows({k: "" if v is None else v for k, v in r.items()} for r in rows)
        os.replace(parts[0], path)
        os.replace(parts[1], table)
    finally:
        for part in parts:
            part.unlink(missing_ok=True)
    return path, table
