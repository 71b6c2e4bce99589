"""Simulation scenarios as data: the inputs of one forward simulation, read from YAML.

A scenario file (``railtherm/schemas/scenario.schema.yaml``; the shipped ones are in
``config/scenarios/``) gives

- ``name`` (default: the file's stem), ``description`` and ``source``, where the numbers come
  from or why they were chosen (required);
- the time grid: ``duration_h`` and ``step_s`` (default 60 s); the duration must be a whole
  number of steps;
- ``outdoor``: the outdoor temperature T_o, exactly one of ``constant_C``, ``steps``
  (``[{at_h: 0, C: -20}, {at_h: 6, C: -10}]``) or ``file`` (a column of a CSV, Excel, MATLAB
  or R file, read by :mod:`railtherm.data.readers` and :mod:`railtherm.data.timeaxis` like a raw
  measurement file);
- ``heating``: exactly one of ``power_W``, ``steps`` (value key ``W``), ``file`` or
  ``controller`` (``type`` thermostat or pi, ``setpoint_C``, ``power_max_W``,
  ``power_min_W``; ``hysteresis_K`` for a thermostat, ``kp_W_K``/``ti_s`` for a PI);
- ``gains`` (optional), heat flows into the air node of eq. 1: ``passengers`` (``count`` or
  ``steps`` of counts, times ``sensible_W``), ``auxiliaries_W``, ``doors`` (``every_min``,
  ``open_s`` and either ``air_exchange_m3_h`` or ``heat_W``) and ``ventilation_m3_h``;
- ``irradiance`` (optional): channel -> W/m2, a number or ``steps`` (value key ``W_m2``) or
  ``file``;
- ``initial``: ``soaked`` (default), ``steady`` or ``{T_C: 20, T_veh_C: 18}``;
- ``report`` (optional): ``heat_up_to_C`` and ``cool_down_to_C``.

Time convention (zero-order hold, as in eq. 15 of the paper): every array has one value per
grid point t_n = n * step_s, n = 0..N (N = duration / step_s), and the value at t_n is held
over [t_n, t_n+1). A ``steps`` profile holds each value from its ``at_h`` (on the grid) to
the next. A ``file`` profile is interpolated linearly onto the grid points (it must cover
the whole duration; time 0 is time 0 of an elapsed-time column and the first row of a column
of instants). Door openings, which may be shorter than a step, enter as their mean over each
step: the share of the step the doors are open times the flow while open (exact in energy).
With ``input_hold: first_order`` every array runs linear between grid points instead (its
values are then point values, a ``steps`` change a ramp over one step); only the power of a
controller, decided at each grid point, stays held over the step.
Air exchanged with the outside (doors, ventilation) enters ``air_exchange_W_K`` as
rho c_p Vdot (:data:`RHO_AIR_KG_M3`, :data:`CP_AIR_J_KG_K`).

Every mistake stops :func:`load_scenario` with one :class:`~railtherm.errors.ConfigError`
naming the file, the dotted key and the value. Whether the heating power can hold the set
point depends on the vehicle and is checked by the simulation, not here.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from railtherm.data import ingest, timeaxis
from railtherm.data.rawfile import read_columns
from railtherm.errors import ConfigError, DataError
from railtherm.yamlio import check_finite, packaged_schema, read_yaml, validate_schema

__all__ = [
    "CP_AIR_J_KG_K",
    "RHO_AIR_KG_M3",
    "Controller",
    "Initial",
    "Scenario",
    "door_open_fraction",
    "exchange_W_K",
    "load_scenario",
]

RHO_AIR_KG_M3 = 1.2  # density of air (kg/m3), as for the air mass m_i of the paper
CP_AIR_J_KG_K = 1005.0  # specific heat capacity of air at constant pressure (J/(kg K))
MAX_STEPS = 5_000_000  # grid points beyond which a scenario is taken for a mistake
_EPS = 1e-9  # relative tolerance of "a whole number of steps"


@dataclass(frozen=True)
class Controller:
    """A heating controller on the indoor air temperature T."""

    kind: str  # "thermostat" | "pi"
    setpoint_C: float  # the indoor-air set point (degC)
    power_max_W: float  # heating power limit (W), > 0
    power_min_W: float = 0.0  # >= 0, < power_max_W
    # thermostat: full power below setpoint - h/2, off above setpoint + h/2, keeps its state
    # in between
    hysteresis_K: float = 1.0
    kp_W_K: float | None = None  # PI proportional gain (W/K); None: engine default
    ti_s: float | None = None  # PI integral time (s); None: engine default 1800


@dataclass(frozen=True)
class Initial:
    """The initial state of a simulation.

    ``kind`` is "soaked" (every state at T_o(0)), "steady" (the steady state of the first
    input row; with a controller at the set point if reachable) or "given" (``states_C``,
    e.g. ``{"T": 20.0, "T_veh": 18.0}``; a state left out starts at T's value).
    """

    kind: str
    states_C: dict = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class Scenario:
    """A loaded scenario: its arrays have one value per grid point t = 0, dt, ..., duration
    (N + 1 points), each held over the step that follows it (zero-order hold). The arrays
    are read-only. Compared by identity (arrays have no single truth value)."""

    name: str  # the file's stem unless the YAML gives `name`
    file: str  # the path as given (for messages)
    description: str
    source: str  # source or rationale of the numbers
    dt_s: float
    duration_s: float
    t_s: np.ndarray  # (N+1,)
    T_o: np.ndarray  # (N+1,) degC
    heating_W: np.ndarray | None  # (N+1,) fixed heating power; None when a controller drives it
    controller: Controller | None
    gains: dict  # name -> (N+1,) W: "passengers", "auxiliaries", "doors" (heat); declared ones
    air_exchange_W_K: np.ndarray  # (N+1,) rho c_p Vdot (W/K) with the outside; zeros if none
    irradiance: dict  # channel -> (N+1,) W/m2 (only the channels the scenario declares)
    initial: Initial
    heat_up_to_C: float | None  # report: first time T reaches this (rising)
    cool_down_to_C: float | None  # report: first time T falls to this
    files: tuple[str, ...] = ()  # the profile files read (paths as resolved from the scenario's)
    # T_o and irradiance between grid points: held (zero_order) or linear (first_order)
    input_hold: str = "zero_order"

    @property
    def gains_W(self) -> np.ndarray:
        """The sum of :attr:`gains` (W per grid point; zeros if none)."""
        total = np.zeros_like(self.t_s)
        for values in self.gains.values():
            total = total + values
        return total

    @property
    def n_steps(self) -> int:
        """N, the number of steps (the arrays have N + 1 points)."""
        return len(self.t_s) - 1


# ---------------------------------------------------------------------------------------------
# Loading


def load_scenario(path: str | os.PathLike[str], display: str | None = None) -> Scenario:
    """Read, validate and expand a scenario file onto its time grid.

    ``display`` is the file name used in messages (default: ``path`` as given); a profile
    file's path is relative to the scenario file's directory. Raises one
    :class:`~railtherm.errors.ConfigError` naming the file, the dotted key and the value for
    any mistake: a malformed file, an unknown key, a value of the wrong type or range (the
    schema), or an inconsistent one (the checks here).
    """
    name = display or str(path)
    data = read_yaml(path, display=name)
    validate_schema(name, data, packaged_schema("scenario"))
    check_finite(name, data)
    ctx = _Context(file=name, directory=os.path.dirname(os.fspath(path)))

    dt_s = float(data["step_s"])
    duration_s = _duration_s(name, data, dt_s)
    n = round(duration_s / dt_s)
    t_s = np.arange(n + 1, dtype=float) * dt_s
    ctx.dt_s, ctx.duration_s, ctx.t_s = dt_s, duration_s, t_s

    T_o = _profile(ctx, "outdoor", data["outdoor"], {"constant_C": "C"}, "C")
    heating = data["heating"]
    kind = _one_of(ctx, "heating", heating, ("power_W", "steps", "file", "controller"))
    if kind == "controller":
        controller = _controller(ctx, heating["controller"])
        heating_W = None
    else:
        controller = None
        heating_W = _profile(
            ctx, "heating", heating, {"power_W": "W"}, "W", nonnegative="a heating power"
        )

    gains, air_exchange = _gains(ctx, data["gains"])
    irradiance = {
        channel: _irradiance(ctx, f"irradiance.{channel}", spec)
        for channel, spec in data["irradiance"].items()
    }
    report = data["report"]
    scenario = Scenario(
        name=data.get("name") or Path(path).stem,
        file=name,
        description=str(data["description"]).strip(),
        source=str(data["source"]).strip(),
        dt_s=dt_s,
        duration_s=duration_s,
        t_s=t_s,
        T_o=T_o,
        heating_W=heating_W,
        controller=controller,
        gains=gains,
        air_exchange_W_K=air_exchange,
        irradiance=irradiance,
        initial=_initial(data["initial"]),
        heat_up_to_C=_float_or_none(report.get("heat_up_to_C")),
        cool_down_to_C=_float_or_none(report.get("cool_down_to_C")),
        files=tuple(dict.fromkeys(ctx.files)),
        input_hold=str(data.get("input_hold", "zero_order")),
    )
    for array in (t_s, T_o, heating_W, air_exchange, *gains.values(), *irradiance.values()):
        if array is not None:
            array.setflags(write=False)
    return scenario


@dataclass
class _Context:
    """What the expansion of one scenario file needs: names for messages and the grid."""

    file: str
    directory: str  # of the scenario file ("" for the working directory)
    dt_s: float = 0.0
    duration_s: float = 0.0
    t_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    files: list[str] = field(default_factory=list)  # profile files read, in order


def _float_or_none(value: Any) -> float | None:
    return None if value is None else float(value)


def _g(value: float) -> str:
    return f"{value:g}"


def _duration_s(file: str, data: Mapping[str, Any], dt_s: float) -> float:
    """The duration in seconds, a whole number of steps (to whole microseconds, so that
    0.1 h is 360 s and not the float product)."""
    hours = data["duration_h"]
    duration_s = round(float(hours) * 3600.0, 6)
    steps = duration_s / dt_s
    if abs(steps - round(steps)) > _EPS * max(1.0, steps) or round(steps) < 1:
        raise ConfigError(
            file,
            "duration_h",
            hours,
            f"not a whole number of steps: duration_h {_g(hours)} h = {_g(duration_s)} s is "
            f"{steps:.6g} times step_s {_g(dt_s)} s; make the duration a multiple of step_s",
        )
    if round(steps) + 1 > MAX_STEPS:
        raise ConfigError(
            file,
            "duration_h",
            hours,
            f"{round(steps):,} steps of step_s {_g(dt_s)} s exceed {MAX_STEPS:,}: a longer "
            "step_s, or is duration_h in hours?",
        )
    return duration_s


def _one_of(ctx: _Context, key: str, spec: Mapping[str, Any], kinds: Sequence[str]) -> str:
    """The one key of ``kinds`` that ``spec`` gives (other keys of it are ignored here);
    :class:`ConfigError` naming the keys given for two or more, ``spec`` for none."""
    given = [k for k in kinds if k in spec]
    if len(given) != 1:
        what = "none" if not given else ", ".join(given)
        raise ConfigError(
            ctx.file,
            key,
            given or dict(spec),
            f"give exactly one of {', '.join(kinds)} (given: {what})",
        )
    return given[0]


# ---------------------------------------------------------------------------------------------
# Profiles


def _profile(
    ctx: _Context,
    key: str,
    spec: Mapping[str, Any],
    constants: Mapping[str, str],
    value_key: str,
    nonnegative: str = "",
) -> np.ndarray:
    """A profile on the grid from ``spec``: one of its ``constants`` keys (a number), ``steps``
    (items ``{at_h, <value_key>}``) or ``file``; keys of ``spec`` beyond these are left to
    the caller (heating's controller). ``nonnegative`` names the quantity a file must not
    give negative (the schema bounds the other kinds)."""
    kinds = [*constants, "steps", "file"]
    kind = _one_of(ctx, key, spec, kinds)
    if kind == "steps":
        return _steps(ctx, f"{key}.steps", spec["steps"], value_key)
    if kind == "file":
        return _file(ctx, f"{key}.file", spec["file"], nonnegative)
    return np.full(ctx.t_s.shape, float(spec[kind]))


def _grid_index(ctx: _Context, key: str, at_h: float) -> int:
    """The grid point of a time given in hours; :class:`ConfigError` off the grid or past the
    end."""
    at_s = round(float(at_h) * 3600.0, 6)
    steps = at_s / ctx.dt_s
    if at_s >= ctx.duration_s:
        raise ConfigError(
            ctx.file,
            key,
            at_h,
            f"at or after the end of the scenario (duration_h {_g(ctx.duration_s / 3600)}): "
            "the step would hold over nothing",
        )
    if abs(steps - round(steps)) > _EPS * max(1.0, steps):
        raise ConfigError(
            ctx.file,
            key,
            at_h,
            f"not on the time grid: {_g(at_s)} s is no multiple of step_s {_g(ctx.dt_s)} s",
        )
    return round(steps)


def _steps(ctx: _Context, key: str, steps: Sequence[Mapping[str, Any]], value_key: str):
    """A piecewise-constant profile: each value holds from its ``at_h`` to the next."""
    starts = []
    for i, step in enumerate(steps):
        at_key = f"{key}[{i}].at_h"
        at_h = step["at_h"]
        if i == 0 and at_h != 0:
            raise ConfigError(
                ctx.file, at_key, at_h, "the first step must be at 0 h (the start of the scenario)"
            )
        if i > 0 and at_h <= steps[i - 1]["at_h"]:
            raise ConfigError(
                ctx.file,
                at_key,
                at_h,
                f"steps must be in time order: not after the step before (at_h "
                f"{_g(steps[i - 1]['at_h'])})",
            )
        starts.append(_grid_index(ctx, at_key, at_h))
    values = np.array([float(step[value_key]) for step in steps])
    which = np.searchsorted(np.array(starts), np.arange(len(ctx.t_s)), side="right") - 1
    return values[which]


def _file(ctx: _Context, key: str, spec: Mapping[str, Any], nonnegative: str) -> np.ndarray:
    """A column of a profile file, read as a raw measurement file is
    (:func:`railtherm.data.ingest.read_raw`) and interpolated linearly onto the grid points."""
    given = spec["path"]
    path = os.path.join(ctx.directory, given)
    if not os.path.isfile(path):
        raise ConfigError(ctx.file, f"{key}.path", given, f"file not found: {path}")
    ctx.files.append(os.path.normpath(path))
    time = dict(spec["time"])
    fmt = {**spec.get("format", {}), "time": time}
    try:
        tf = timeaxis.declared(ctx.file, time)
    except ConfigError as exc:  # its key is a vehicle's format.time.<x>
        raise ConfigError(
            ctx.file, exc.key.replace("format.time", f"{key}.time", 1), exc.value, exc.reason
        ) from None
    column, time_column = spec["column"], time["column"]
    try:
        columns = read_columns(path, fmt=fmt)
        if time_column not in columns:
            raise ConfigError(
                ctx.file,
                f"{key}.time.column",
                time_column,
                f"no such column in {path} (columns: {', '.join(columns)})",
            )
        if column not in columns or column == time_column:
            raise ConfigError(
                ctx.file,
                f"{key}.column",
                column,
                f"no such column in {path} (columns: "
                f"{', '.join(c for c in columns if c != time_column)})",
            )
        raw = ingest.read_raw(path, fmt, label=path)
        values = ingest._numeric(path, raw, column)
    except DataError as exc:  # the file as a whole (key ""), its time column or its values
        if not exc.key:
            which, value, where = f"{key}.path", given, exc.file
        else:
            which = f"{key}.time.column" if exc.key == time_column else f"{key}.column"
            value, where = exc.value, f"{exc.file}, column '{exc.key}'"
        raise ConfigError(ctx.file, which, value, f"{where}: {exc.reason}") from None
    empty = np.isnan(values)
    if empty.any():
        i = int(empty.argmax())
        raise ConfigError(
            ctx.file,
            f"{key}.column",
            column,
            f"{path}, line {i + 2}: an empty cell; a profile needs a value in every row",
        )
    if nonnegative and (values < 0).any():
        i = int((values < 0).argmax())
        raise ConfigError(
            ctx.file,
            f"{key}.column",
            column,
            f"{path}, line {i + 2}: {values[i]:g} is negative; {nonnegative} is >= 0",
        )
    t = raw.index.to_numpy(dtype=float)
    if t[0] > 0 or t[-1] < ctx.duration_s:
        origin = "the first row" if tf.absolute else f"{time_column} = 0 {tf.format}"
        raise ConfigError(
            ctx.file,
            f"{key}.path",
            given,
            f"{path} covers {_g(t[0] / 3600)} h to {_g(t[-1] / 3600)} h (time 0 at {origin}), "
            f"short of the scenario's 0 h to {_g(ctx.duration_s / 3600)} h (duration_h); a "
            "profile must cover the whole duration",
        )
    return np.interp(ctx.t_s, t, values)


# ---------------------------------------------------------------------------------------------
# Heating, gains, irradiance, initial state


def _controller(ctx: _Context, spec: Mapping[str, Any]) -> Controller:
    key = "heating.controller"
    kind = spec["type"]
    other = {"thermostat": ("kp_W_K", "ti_s"), "pi": ("hysteresis_K",)}[kind]
    for name in other:
        if name in spec:
            owner = "a pi controller" if kind == "thermostat" else "a thermostat"
            raise ConfigError(
                ctx.file,
                f"{key}.{name}",
                spec[name],
                f"is a setting of {owner}, not of type {kind}; remove it",
            )
    power_max = float(spec["power_max_W"])
    power_min = float(spec.get("power_min_W", 0.0))
    if power_min >= power_max:
        raise ConfigError(
            ctx.file,
            f"{key}.power_min_W",
            spec.get("power_min_W"),
            f"must be < power_max_W ({_g(power_max)} W)",
        )
    return Controller(
        kind=kind,
        setpoint_C=float(spec["setpoint_C"]),
        power_max_W=power_max,
        power_min_W=power_min,
        hysteresis_K=float(spec.get("hysteresis_K", 1.0)),
        kp_W_K=_float_or_none(spec.get("kp_W_K")),
        ti_s=_float_or_none(spec.get("ti_s")),
    )


def _open_time(t: np.ndarray, every_s: float, open_s: float) -> np.ndarray:
    """Time the doors have been open in [0, t): openings at 0, every_s, 2 every_s, ..."""
    periods = np.floor(t / every_s)
    return periods * open_s + np.minimum(t - periods * every_s, open_s)


def door_open_fraction(t_s: np.ndarray, dt_s: float, every_s: float, open_s: float):
    """The share of each step [t_n, t_n + dt) the doors are open (openings of ``open_s``
    seconds every ``every_s`` seconds, the first at time 0), rounded to 1e-9: the same share
    computed at different times is the same number (the simulation discretises once per
    distinct air exchange)."""
    share = (_open_time(t_s + dt_s, every_s, open_s) - _open_time(t_s, every_s, open_s)) / dt_s
    return np.round(share, 9)


def exchange_W_K(volume_flow_m3_h: float) -> float:
    """rho c_p Vdot (W/K) of a volume flow of outside air (m3/h)."""
    return RHO_AIR_KG_M3 * CP_AIR_J_KG_K * volume_flow_m3_h / 3600.0


def _gains(ctx: _Context, spec: Mapping[str, Any]) -> tuple[dict[str, np.ndarray], np.ndarray]:
    gains: dict[str, np.ndarray] = {}
    air = np.zeros(ctx.t_s.shape)
    if "passengers" in spec:
        key = "gains.passengers"
        passengers = spec["passengers"]
        kind = _one_of(ctx, key, passengers, ("count", "steps"))
        if kind == "steps":
            count = _steps(ctx, f"{key}.steps", passengers["steps"], "count")
        else:
            count = np.full(ctx.t_s.shape, float(passengers["count"]))
        gains["passengers"] = count * float(passengers["sensible_W"])
    if "auxiliaries_W" in spec:
        gains["auxiliaries"] = np.full(ctx.t_s.shape, float(spec["auxiliaries_W"]))
    if "doors" in spec:
        key = "gains.doors"
        doors = spec["doors"]
        every_s = float(doors["every_min"]) * 60.0
        open_s = float(doors["open_s"])
        if open_s >= every_s:
            raise ConfigError(
                ctx.file,
                f"{key}.open_s",
                doors["open_s"],
                f"must be shorter than the interval between openings (every_min "
                f"{_g(doors['every_min'])} = {_g(every_s)} s)",
            )
        kind = _one_of(ctx, key, doors, ("air_exchange_m3_h", "heat_W"))
        share = door_open_fraction(ctx.t_s, ctx.dt_s, every_s, open_s)
        if kind == "heat_W":
            gains["doors"] = share * float(doors["heat_W"])
        else:
            air = air + share * exchange_W_K(float(doors["air_exchange_m3_h"]))
    if "ventilation_m3_h" in spec:
        air = air + exchange_W_K(float(spec["ventilation_m3_h"]))
    return gains, air


def _irradiance(ctx: _Context, key: str, spec: Any) -> np.ndarray:
    if isinstance(spec, Mapping):
        return _profile(ctx, key, spec, {}, "W_m2", nonnegative="an irradiance")
    return np.full(ctx.t_s.shape, float(spec))


def _initial(spec: str | Mapping[str, Any]) -> Initial:
    if isinstance(spec, str):
        return Initial(kind=spec)
    return Initial(kind="given", states_C={k.removesuffix("_C"): float(v) for k, v in spec.items()})
