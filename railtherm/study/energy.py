"""The annual heating energy of a vehicle: an identified model (a fit or a class reference
model) through a typical year of weather (:mod:`railtherm.study.weather`) and an operating
profile, with 95 % bands and paired what-ifs.

**Profile** (:func:`load_profile`, schema ``railtherm/schemas/profile.schema.yaml``): the hours
in service by weekday, the set point in service and the set-back when stabled (or heating
off), the depot pre-heating (the set point raised that many hours before each service
period; its energy apart), passengers by hour and their sensible heat, door openings as air
exchanged with the outside (a conductance rho c_p V' between T and T_o, eq. 1's E_sup -
E_exh), auxiliaries, and the heating limit of the vehicle's HVAC.

**Model.** Eqs. 7-8 (or 9, or any structure of the registry) with T_o from the weather, the
gains and the heating into the air node, the door conductance in service; each step's exact
discretisation, the inputs held over the step. The HVAC is an ideal controller: each step it
gives the power that brings T to the set point at the step's end, within 0 and its limit
(the heating a well-tuned HVAC delivers; no overshoot, no cycling). Where the limit is
reached T falls below the set point: the hours in service more than ``UNMET_K`` below it are
the unmet demand. The year runs after a warm-up over its own last ``WARMUP_DAYS`` days (a
typical year repeats), so the stored heat at its start is the year's own.

**Bands.** The 95 % bands are the 2.5 and 97.5 % quantiles over the parameter draws of the
identification (:func:`railtherm.study.simulate.parameter_draws`: a fit's covariance and
systematic sources, or a class model's spread), within the physical limits; a Kalman fit's
draws each carry its identified process noise too (the diffusion of the state equation,
discretised exactly), the same noise for the base and every what-if.

**What-ifs** (``k=-10%``, ``set_back=8``, ``set_back=off``, ``preheat_h=3``) run with the same
draws as the base, so their difference is paired: its band is that of the difference, per
draw, not the two totals' bands combined, and it is narrower than either.

Cooling is out of scope: the model has no cooling input, and a vehicle above its set point
floats.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from operator import attrgetter
from pathlib import Path
from typing import Any

import numpy as np

from railtherm.errors import ConfigError
from railtherm.study import simulate as sim
from railtherm.study.fit import Fit
from railtherm.study.weather import Weather, on_grid
from railtherm.yamlio import check_finite, packaged_schema, read_yaml, validate_schema

__all__ = [
    "AnnualResult",
    "Profile",
    "WhatIf",
    "annual_energy",
    "check_what_ifs",
    "contradiction",
    "heater_surface",
    "load_profile",
    "markdown",
    "parse_what_if",
    "profile_on_grid",
    "result_rows",
    "study_markdown",
    "study_rows",
    "study_table",
    "vehicle_energy",
    "write_result",
    "write_study_energy",
]

UNMET_K = 0.5  # a service hour more than this below the set point is unmet demand
WARMUP_DAYS = 14
NOISE_BLOCK = 4096  # steps of process noise drawn at once (draws x states each)
RHO_CP_AIR = 1.2 * 1005.0  # J/(m3 K), as the scenario engine's air exchange
DAYS_PER_MONTH = (31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31)
WEEKDAYS = ("monday", "tuesday", "wednesday", "thursday", "friday", "saturday", "sunday")


@dataclass(frozen=True)
class Profile:
    """An operating profile (:func:`load_profile`): service periods [(start h, end h)] by day
    kind (``weekdays``, ``saturday``, ``sunday``), set points, pre-heating hours, passengers
    per hour of a service day and their W, door exchange (m³/h in service), auxiliaries and
    the heating limit."""

    name: str
    service: Mapping[str, tuple[tuple[float, float], ...]]
    set_point_C: float
    set_back_C: float | None
    preheat_h: float
    passengers_by_hour: tuple[float, ...]
    W_per_passenger: float
    door_air_m3_h: float
    auxiliaries_W: float
    heating_limit_W: float
    year_starts_on: str = "monday"
    source: str = ""
    preheat_mode: str = "start"
    heating_limit_W_per_m2: float | None = None

    def for_surface(self, surface_m2: float | None, label: str) -> Profile:
        """The profile of a vehicle of ``surface_m2`` (m²): its heater sized by
        ``heating_limit_W_per_m2`` where the profile gives one (the surface is then needed,
        else a :class:`ConfigError` naming the vehicle ``label``), else as it is."""
        if self.heating_limit_W_per_m2 is None:
            return self
        if surface_m2 is None or not (math.isfinite(surface_m2) and surface_m2 > 0):
            raise ConfigError(
                label or "the vehicle",
                "surface_m2",
                surface_m2,
                f"profile {self.name} sizes the heater per m² of outer surface "
                f"({self.heating_limit_W_per_m2:g} W/m²): give the vehicle's surface_m2 "
                "(railtherm energy: --surface-m2)",
            )
        return replace(self, heating_limit_W=self.heating_limit_W_per_m2 * surface_m2)


def load_profile(path: str | Path) -> Profile:
    """Read and check an operating profile (YAML, ``profile.schema.yaml``). A mistake is a
    :class:`ConfigError` naming the file, the key and the value."""
    file = str(path)
    data = read_yaml(path, display=file)
    validate_schema(file, data, packaged_schema("profile"))
    check_finite(file, data)
    service = {}
    for kind in ("weekdays", "saturday", "sunday"):
        periods = data["service"].get(kind, data["service"]["weekdays"])
        end = 0.0
        for i, (a, b) in enumerate(periods):
            if not (end <= a < b <= 24):
                raise ConfigError(
                    file, f"service.{kind}[{i}]", [a, b], "periods start < end, in order, in 0-24 h"
                )
            end = b
        service[kind] = tuple((float(a), float(b)) for a, b in periods)
    by_hour = [float(v) for v in data["passengers"]["by_hour"]]
    if len(by_hour) not in (1, 24):
        raise ConfigError(file, "passengers.by_hour", len(by_hour), "expected 1 or 24 values")
    set_back = data["set_back_C"]
    if set_back is not None and set_back > data["set_point_C"]:
        raise ConfigError(
            file,
            "set_back_C",
            set_back,
            f"above set_point_C = {data['set_point_C']:g} degC: the set-back is the lower "
            "temperature held when stabled; give set_back_C at most set_point_C, or null "
            "(heating off when stabled)",
        )
    limits = [key for key in ("heating_limit_W", "heating_limit_W_per_m2") if key in data]
    if len(limits) != 1:
        raise ConfigError(
            file,
            "heating_limit_W",
            {key: data[key] for key in limits} or None,
            "give the heater's power as exactly one of heating_limit_W (W) and "
            "heating_limit_W_per_m2 (W per m² of the vehicle's outer surface)",
        )
    doors = data["doors"]
    return Profile(
        name=str(data.get("name", Path(file).stem)),
        service=service,
        set_point_C=float(data["set_point_C"]),
        set_back_C=None if data["set_back_C"] is None else float(data["set_back_C"]),
        preheat_h=float(data["preheat_h"]),
        passengers_by_hour=tuple(by_hour * 24 if len(by_hour) == 1 else by_hour),
        W_per_passenger=float(data["passengers"].get("W_each", 80.0)),
        door_air_m3_h=float(doors.get("openings_per_h", 0))
        * float(doors.get("air_m3_per_opening", 0)),
        auxiliaries_W=float(data["auxiliaries_W"]),
        heating_limit_W=float(data.get("heating_limit_W", math.nan)),
        heating_limit_W_per_m2=(
            float(data["heating_limit_W_per_m2"]) if "heating_limit_W_per_m2" in data else None
        ),
        year_starts_on=str(data["year_starts_on"]),
        source=str(data.get("source", "")),
        preheat_mode=str(data["preheat_mode"]),
    )


@dataclass(frozen=True)
class Grid:
    """A profile on the simulation grid (one value per step): in service, pre-heating, the
    set point (NaN: heating off), the gains (W) and the door conductance (W/K)."""

    in_service: np.ndarray
    preheat: np.ndarray
    set_point: np.ndarray
    gains_W: np.ndarray
    door_W_K: np.ndarray
    until_service: np.ndarray  # steps to the next service start (in the pre-heating window)


def profile_on_grid(profile: Profile, t_s: np.ndarray) -> Grid:
    """The profile at every grid time ``t_s`` (seconds from the typical year's start, whose
    first day is ``profile.year_starts_on``)."""
    day = (t_s // 86400.0).astype(int)
    hour = (t_s % 86400.0) / 3600.0
    weekday = (day + WEEKDAYS.index(profile.year_starts_on)) % 7
    kind = np.where(weekday < 5, 0, np.where(weekday == 5, 1, 2))
    in_service = np.zeros(len(t_s), dtype=bool)
    for k, name in enumerate(("weekdays", "saturday", "sunday")):
        for a, b in profile.service[name]:
            in_service |= (kind == k) & (hour >= a) & (hour < b)
    # pre-heating: not in service, and service within the next preheat_h (the year wraps)
    steps_ahead = int(round(profile.preheat_h * 3600.0 / (t_s[1] - t_s[0]))) if len(t_s) > 1 else 0
    preheat = np.zeros(len(t_s), dtype=bool)
    if steps_ahead > 0:
        wrapped = np.concatenate([in_service, in_service[:steps_ahead]]).astype(int)
        ahead = np.concatenate([[0], np.cumsum(wrapped)])
        idx = np.arange(len(t_s))
        preheat = (ahead[idx + 1 + steps_ahead] - ahead[idx + 1] > 0) & ~in_service
    until = np.zeros(len(t_s), dtype=int)
    starts = np.flatnonzero(in_service & ~np.roll(in_service, 1))
    if preheat.any() and len(starts):
        idx = np.flatnonzero(preheat)
        ahead = np.concatenate([starts, starts + len(t_s)])
        until[idx] = ahead[np.searchsorted(ahead, idx)] - idx
    heated = in_service | preheat
    set_back = math.nan if profile.set_back_C is None else profile.set_back_C
    set_point = np.where(heated, profile.set_point_C, set_back)
    people = np.asarray(profile.passengers_by_hour)[np.minimum(hour.astype(int), 23)]
    gains = np.where(in_service, people * profile.W_per_passenger + profile.auxiliaries_W, 0.0)
    door = np.where(in_service, RHO_CP_AIR * profile.door_air_m3_h / 3600.0, 0.0)
    return Grid(in_service, preheat, set_point, gains, door, until)


@dataclass(frozen=True)
class WhatIf:
    """A change to the base: ``k`` (relative change of the loss conductance kA), ``set_back``
    (degC, or None: heating off when stabled), ``preheat_h``."""

    label: str
    k_rel: float = 0.0
    profile: Mapping[str, Any] = field(default_factory=dict)


def parse_what_if(text: str) -> WhatIf:
    """``k=-10%``, ``set_back=8``, ``set_back=off`` or ``preheat_h=3``; another text, a value
    that is no finite number, a change of k of -100 % or less (a loss conductance kA not
    positive) or above +900 % (:data:`MAX_K_FACTOR`) or a negative pre-heating is a
    :class:`ConfigError` naming ``--what-if`` and the fix."""
    m = re.fullmatch(
        r"\s*(k|set_back|preheat_h)\s*=\s*([-+]?[\w.]+(?:[eE][-+]\d+)?)(%?)\s*", str(text)
    )
    if m:
        key, value, pct = m.groups()
        if key == "set_back" and not pct and value.lower() == "off":
            return WhatIf("set-back off", profile={"set_back_C": None})
        try:
            number = float(value)
        except ValueError:
            number = None
        if number is not None and (key == "k") == bool(pct):
            if not math.isfinite(number):
                raise ConfigError(
                    "--what-if",
                    "what_if",
                    text,
                    f"{key} = {value} is not a finite number: give one, e.g. {EXAMPLES[key]}",
                )
            if key == "k":
                if not number > -100.0:
                    raise ConfigError(
                        "--what-if",
                        "what_if",
                        text,
                        f"k {number:+g} % makes the loss conductance kA {1 + number / 100:+g} "
                        "times its identified value, not positive: give a change above "
                        "-100 %, e.g. k=-10%",
                    )
                if number > 100.0 * (MAX_K_FACTOR - 1.0):
                    raise ConfigError(
                        "--what-if",
                        "what_if",
                        text,
                        f"k {number:+g} % makes kA {1 + number / 100:g} times its identified "
                        f"value; a what-if stays within {MAX_K_FACTOR:g} times it: give at "
                        f"most k=+{100 * (MAX_K_FACTOR - 1):g}%",
                    )
                return WhatIf(f"k {number:+.12g} %", k_rel=number / 100.0)
            if key == "set_back":
                return WhatIf(f"set-back {number:g} °C", profile={"set_back_C": number})
            if number < 0:
                raise ConfigError(
                    "--what-if", "what_if", text, "pre-heating lasts 0 h or more, e.g. preheat_h=3"
                )
            return WhatIf(f"pre-heat {number:g} h", profile={"preheat_h": number})
    raise ConfigError(
        "--what-if", "what_if", text, "expected k=-10%, set_back=8, set_back=off or preheat_h=3"
    )


MAX_K_FACTOR = 10.0  # a what-if's kA at most this many times the identified one
EXAMPLES = {"k": "k=-10%", "set_back": "set_back=8 (or set_back=off)", "preheat_h": "preheat_h=3"}


def contradiction(profile: Profile, what_if: WhatIf) -> str | None:
    """Why ``what_if`` contradicts ``profile`` (a set-back above its set point, or outside the
    profile's own limits of set-back and pre-heating), or None. The CLI (``--what-if``) and
    the study config (``energy.what_if``) refuse it alike, each naming its own key."""
    limits = packaged_schema("profile")["properties"]
    changed = dict(what_if.profile)
    set_back = changed.get("set_back_C")
    if set_back is not None:
        lo, hi = limits["set_back_C"]["minimum"], limits["set_back_C"]["maximum"]
        if set_back > profile.set_point_C:
            return (
                f"the set-back {set_back:g} degC is above the profile's set point "
                f"{profile.set_point_C:g} degC (set_point_C of {profile.name}): the set-back is "
                f"the lower temperature held when stabled; give at most "
                f"set_back={profile.set_point_C:g}, or set_back=off"
            )
        if not lo <= set_back <= hi:
            return f"the set-back {set_back:g} degC lies outside {lo:g}..{hi:g} degC"
    preheat = changed.get("preheat_h")
    if preheat is not None and preheat > limits["preheat_h"]["maximum"]:
        return (
            f"pre-heating {preheat:g} h is more than the profile's limit of "
            f"{limits['preheat_h']['maximum']:g} h (preheat_h)"
        )
    return None


def check_what_ifs(
    profile: Profile,
    what_ifs: Sequence[WhatIf],
    texts: Sequence[str],
    file: str,
    keys: Sequence[str],
) -> None:
    """A :class:`ConfigError` naming ``file``, the what-if's key (``keys[i]``) and its text
    (``texts[i]``) for the first what-if that contradicts ``profile`` (:func:`contradiction`)."""
    for what_if, text, key in zip(what_ifs, texts, keys, strict=True):
        reason = contradiction(profile, what_if)
        if reason is not None:
            raise ConfigError(file, key, text, reason)


@dataclass
class AnnualResult:
    """Per run (the central parameters first, then the draws), per variant (the base, then
    each what-if): the annual heating energy (kWh), monthly (kWh, 12), pre-heating (kWh),
    the peak power in service and outside it (pre-heating and stabling; W), the unmet hours
    in service, and the design heat load (W): the steady heating that holds the service set
    point at the year's design temperature ``design_T_o_C`` (the 99.6 % dry-bulb: 0.4 % of
    the year's hours are colder), door closed, without gains or sun - what sizes an HVAC
    unit; the year's heat balance: the losses through the envelope and the open doors
    (kWh), which the heating, the internal gains (passengers and auxiliaries) and the sun
    through the apertures cover (:meth:`stored`: what is left, the heat stored over the
    year and the steps' rounding); and what the run rests on."""

    label: str
    weather: str
    profile: str
    variants: list[str]
    energy_kWh: np.ndarray  # (V, S)
    monthly_kWh: np.ndarray  # (V, S, 12)
    preheat_kWh: np.ndarray  # (V, S)
    peak_service_W: np.ndarray  # (V, S)
    peak_preheat_W: np.ndarray  # (V, S)
    unmet_h: np.ndarray  # (V, S)
    dt_s: float
    draws: int
    design_T_o_C: float = math.nan
    design_load_W: np.ndarray | None = None  # (V, S)
    envelope_kWh: np.ndarray | None = None  # (V, S): lost through the envelope
    doors_kWh: np.ndarray | None = None  # (V, S): lost through the open doors
    gains_kWh: np.ndarray | None = None  # (V, S): passengers and auxiliaries
    solar_kWh: np.ndarray | None = None  # (V, S): the sun through the apertures
    rejected: int = 0
    notes: list[str] = field(default_factory=list)
    source: str = ""  # what the central run rests on
    band_sources: tuple[str, ...] = ()  # what the draws carry

    def band(self, values: np.ndarray) -> tuple[float, float, float]:
        """(central, 2.5 %, 97.5 %) of a per-run array; NaN bounds without draws."""
        central = float(values[0])
        if len(values) < 3:
            return central, math.nan, math.nan
        lo, hi = np.quantile(values[1:], [0.025, 0.975])
        return central, float(lo), float(hi)

    def band_note(self) -> str:
        """What a figure's whiskers are."""
        if not self.draws:
            return f"{self.label}: central run only (no parameter draws)"
        return (
            f"{self.label}: bars central, whiskers the 95 % band over {self.draws} parameter draws"
        )

    def stored(self) -> np.ndarray:
        """(V, S): heating + gains + sun - envelope and door losses, kWh: the heat the
        vehicle stores over the year (about 0: the year starts where it ends) and the
        steps' rounding of the losses."""
        supplied = self.energy_kWh + self.gains_kWh + self.solar_kWh
        return supplied - self.envelope_kWh - self.doors_kWh

    def difference(self, variant: int) -> tuple[float, float, float]:
        """The what-if's paired difference in annual energy (kWh): per run, then banded."""
        return self.band(self.energy_kWh[variant] - self.energy_kWh[0])


def _loss_scaled(ps: sim.ParameterSet, theta: Mapping[str, float], k_rel: float) -> dict:
    """``theta`` with the loss conductance to the outside scaled by 1 + k_rel."""
    structure = ps.structure
    if k_rel == 0.0:
        return dict(theta)
    if "kA" not in structure.parameters:
        raise ConfigError(
            "--what-if", "k", k_rel, f"structure {structure.name} has no kA to change"
        )
    if not (math.isfinite(k_rel) and k_rel > -1.0):
        raise ConfigError(
            "--what-if",
            "k",
            f"{100 * k_rel:+g}%",
            "makes the loss conductance kA not positive: give a change above -100 %",
        )
    return {**theta, "kA": theta["kA"] * (1.0 + k_rel)}


def annual_energy(
    params: Any,
    weather: Weather,
    profile: Profile,
    *,
    what_ifs: Sequence[WhatIf] = (),
    dt_s: float = 60.0,
    draws: int = 200,
    seed: int = 0,
    volume_m3: float | None = None,
    hold: str = "first_order",
    surface_m2: float | None = None,
    kernel: Any = None,
    progress: Callable[[int, int], None] | None = None,
) -> AnnualResult:
    """The annual heating energy of ``params`` (a fit, a class reference model or a
    :class:`railtherm.study.simulate.ParameterSet`) in ``weather`` under ``profile``, with
    ``draws`` parameter draws (0: the central run only) and the ``what_ifs`` on the same
    draws; the hourly weather on the grid by ``hold``
    (:func:`railtherm.study.weather.on_grid`). Every run and variant advances together
    through one compiled loop: ``kernel``, by default
    :func:`railtherm.estimation.loops.heated_steps` (another with its signature runs the same
    year, e.g. a reference implementation to compare with). ``surface_m2``: the vehicle's
    outer surface, which sizes the heater of a profile that gives its limit per m².
    ``progress(done, total)`` is called as the steps advance (warm-up and year)."""
    if kernel is None:
        from railtherm.estimation import loops  # numba: imported only to simulate

        kernel = loops.heated_steps

    ps = _predictable(params, profile, what_ifs)
    profile = profile.for_surface(surface_m2, ps.label)
    structure = ps.structure
    thetas, rejected, notes = _parameter_draws(ps, draws, seed, volume_m3)
    t, T_o, ghi_grid = on_grid(weather, dt_s, hold)
    notes += _irradiance_notes(structure, ghi_grid)
    variants = [WhatIf("base"), *what_ifs]
    variant_profiles = [replace(profile, **w.profile) for w in variants]
    grids = [profile_on_grid(p, t) for p in variant_profiles]
    S = len(thetas)
    runs = [_loss_scaled(ps, th, w.k_rel) for w in variants for th in thetas]
    n = len(structure.states)
    # one discretisation per run and door state (closed: 0; open: the profile's conductance)
    G_open = float(grids[0].door_W_K.max())
    sigma = ps.sigma if (ps.sigma is not None and S > 1 and np.any(ps.sigma > 0)) else None
    steps = sim.prepare_steps(structure, runs, np.array([0.0, G_open]), dt_s, sigma)
    Ad, BdT, BdQ, BdI, gain_Q = _step_inputs(steps)
    irradiated = len(structure.inputs) > 2
    ghi = ghi_grid if irradiated and ghi_grid is not None else np.zeros_like(T_o)
    V = len(variants)
    variant = np.repeat(np.arange(V), S)
    set_point = np.stack([g.set_point for g in grids])  # (V, N)
    pre = np.stack([g.preheat for g in grids])
    service = grids[0].in_service
    door = (grids[0].door_W_K > 0).astype(int)
    gains = grids[0].gains_W
    limit = profile.heating_limit_W
    month = np.minimum(np.searchsorted(np.cumsum(DAYS_PER_MONTH) * 86400.0, t, "right"), 11)

    noise_rng = np.random.default_rng([seed, 1])
    R = V * S
    until = np.stack([g.until_service for g in grids])
    energy, pre_J, peak, unmet = np.zeros((R, 12)), np.zeros(R), np.zeros((R, 2)), np.zeros(R)
    G_out, solar_per_ghi = _balance_inputs(structure, runs, steps)
    door_W, losses = np.ascontiguousarray(grids[0].door_W_K, dtype=float), np.zeros((R, 2))
    fixed = tuple(
        np.ascontiguousarray(a) for a in (Ad, BdT, BdQ, BdI, gain_Q, door, T_o, gains, ghi)
    )
    per_run = (variant, np.tile(np.arange(S), V), set_point, pre, service, until)
    ready = _ready_inputs(variant_profiles, until, steps, variant, float(limit))
    Qchol = steps.Qchol if sigma is not None else np.zeros((2, R, n, n))

    N, warmup, done = len(t), int(WARMUP_DAYS * 86400 / dt_s), [0]

    def advance(k_from: int, k_to: int, accumulate: bool) -> None:
        """Steps k_from..k_to-1 (``kernel``), the process noise drawn in blocks in
        the order the steps use it."""
        for a in range(k_from, k_to, NOISE_BLOCK):
            b = min(a + NOISE_BLOCK, k_to)
            noise = (
                noise_rng.standard_normal((b - a, S - 1, n))
                if sigma is not None
                else np.zeros((0, 0, n))
            )
            kernel(
                a, b, x, *fixed, noise, Qchol, *per_run, *ready, month, UNMET_K, G_out,
                door_W, energy, pre_J, peak, unmet, losses, accumulate,
            )  # fmt: skip
            done[0] += b - a
            if progress is not None:
                progress(done[0], warmup + N)

    # warm-up over the year's last days, every state starting at the first set point (at T_o
    # where the heating is off)
    sp0 = set_point[variant, 0]
    x = np.repeat(np.where(np.isnan(sp0), T_o[0], sp0)[:, None], n, axis=1)
    advance(N - warmup, N, False)
    advance(0, N, True)
    scale = dt_s / 3.6e6
    return AnnualResult(
        ps.label,
        weather.source,
        profile.name,
        [w.label for w in variants],
        *_totals(energy, pre_J, peak, unmet, dt_s, V, S),
        dt_s=dt_s,
        draws=S - 1,
        **_design_loads(structure, runs, weather, profile, V, S),
        envelope_kWh=(losses[:, 0] * scale).reshape(V, S),
        doors_kWh=(losses[:, 1] * scale).reshape(V, S),
        gains_kWh=np.repeat(np.array([g.gains_W.sum() * scale for g in grids])[:, None], S, 1),
        solar_kWh=(solar_per_ghi * float(ghi.sum()) * scale).reshape(V, S),
        rejected=rejected,
        notes=notes,
        source=ps.source,
        band_sources=tuple(ps.band_sources) if S > 1 else (),
    )


def _parameter_draws(ps, draws: int, seed: int, volume_m3: float | None):
    """The central parameters of ``ps`` and ``draws`` parameter sets within the physical
    limits (none for a fit that carries no band), how many were replaced, and the notes on
    them: a central air node below the air's capacity, the share replaced, no band and why."""
    floor = sim.air_capacity(volume_m3, ps.label)
    withheld = ps.band_withheld
    rng = np.random.default_rng(seed)
    thetas, rejected, unbounded = sim.parameter_draws(ps, 0 if withheld else draws, rng, floor)
    notes = [sim.central_below_air(ps, floor, volume_m3), withheld, unbounded]
    notes.append(sim.replaced_note(rejected, draws))
    return thetas, rejected, [n for n in notes if n]


def _ready_inputs(variant_profiles, until, steps, variant, limit: float) -> tuple:
    """ "Ready by" (:func:`annual_energy`): in the pre-heating window each run waits, set
    back, until heating at full power from its state would just reach the set point at the
    service start (T_o held at its present value over the horizon: A^m of the stabled step
    and the full-power equilibrium), then heats. The kernel's arguments: which runs wait,
    which started, each variant's own set-back while waiting (none: heating off), A^m, the
    equilibria per kelvin and per watt, the limit."""
    ready_by = [p.preheat_mode == "ready_by" for p in variant_profiles]
    horizon = int(until.max()) if any(ready_by) else 0
    R = len(variant)
    n = steps.Ad.shape[-1]
    Am, x_per_T_o, x_per_W = _ready_by(steps, horizon, R, n)
    back = np.array([math.nan if p.set_back_C is None else p.set_back_C for p in variant_profiles])
    waiting = np.array(ready_by)[variant]
    return (waiting, np.zeros(R, dtype=bool), back, Am, x_per_T_o, x_per_W, limit)


def _balance_inputs(structure, runs, steps) -> tuple[np.ndarray, np.ndarray]:
    """The heat balance's coefficients per run (:func:`annual_energy`): each node's
    conductance to the outside (its capacity times its B[:, T_o], door closed; W/K, R x n)
    and the sun's watts per W/m² of irradiance through the apertures (R)."""
    capacity = np.array([[th[c] for c in structure.capacities] for th in runs])
    G_out = np.ascontiguousarray(capacity * steps.B[0][:, :, 0])
    return G_out, (capacity * steps.B[0][:, :, 2:].sum(axis=2)).sum(axis=1)


def _step_inputs(steps: Any) -> tuple:
    """The year's step coefficients per door state and run (:func:`annual_energy`): Ad, the
    columns of Bd for T_o, Q_H and (summed) the apertures' irradiance, and the air's
    response to a held watt over a step."""
    BdQ = steps.Bd[:, :, :, 1]
    # an aperture's irradiance: the weather's global horizontal irradiance for each channel
    return steps.Ad, steps.Bd[:, :, :, 0], BdQ, steps.Bd[:, :, :, 2:].sum(axis=3), BdQ[:, :, 0]


def _design_loads(structure, runs, weather: Weather, profile: Profile, V: int, S: int):
    """The design temperature of the year and each run's design heat load (W, (V, S))."""
    design_T_o = float(np.quantile(weather.T_o, DESIGN_QUANTILE))
    load = np.array([_design_load(structure, th, profile.set_point_C, design_T_o) for th in runs])
    return {"design_T_o_C": design_T_o, "design_load_W": load.reshape(V, S)}


def _totals(energy, pre_J, peak, unmet, dt_s: float, V: int, S: int) -> tuple:
    """The loop's sums per run as the result's arrays (V, S, ...): the year's energy and its
    months (kWh), the pre-heating (kWh), the peaks in and out of service (W), the unmet
    hours."""
    scale = dt_s / 3.6e6
    monthly = (energy * scale).reshape(V, S, 12)
    return (
        monthly.sum(axis=2),
        monthly,
        (pre_J * scale).reshape(V, S),
        peak[:, 0].reshape(V, S),
        peak[:, 1].reshape(V, S),
        (unmet * dt_s / 3600.0).reshape(V, S),
    )


# the heating design temperature of a year: the 99.6 % dry-bulb (ASHRAE Handbook -
# Fundamentals, ch. 14), exceeded by all but 0.4 % of its hours
DESIGN_QUANTILE = 0.004


def _design_load(structure: Any, theta: Mapping[str, float], T_set: float, T_o: float) -> float:
    """The steady heating (W) that holds the air at ``T_set`` with the outside at ``T_o``,
    every other input 0 (door closed, no gains, no sun): from the structure's steady state,
    T_air = a T_o + b Q_H, Q_H = (T_set - a T_o) / b (kA (T_set - T_o) for eqs. 7-8)."""
    from railtherm.estimation import models

    A, B = structure.matrices(theta)
    unit = np.zeros(len(structure.inputs))
    per_T_o, per_W = unit.copy(), unit.copy()
    per_T_o[0], per_W[1] = 1.0, 1.0
    a = float(models.steady_state(A, B, per_T_o).reshape(-1)[0])
    b = float(models.steady_state(A, B, per_W).reshape(-1)[0])
    return (T_set - a * T_o) / b if b > 0 else math.nan


def _predictable(params: Any, profile: Profile, what_ifs: Sequence[WhatIf]) -> Any:
    """The parameter set of ``params`` for :func:`annual_energy`, refused where a what-if
    contradicts the profile or a parameter is not identified."""
    for w in what_ifs:
        reason = contradiction(profile, w)
        if reason is not None:
            raise ConfigError("--what-if", "what_if", w.label, reason)
    ps = params if isinstance(params, sim.ParameterSet) else sim.parameter_set(params)
    if ps.not_identified:
        raise sim.NotPredictable(
            ps.label, "parameters", list(ps.not_identified), "not identified by the data"
        )
    return ps


def _irradiance_notes(structure: Any, ghi_grid: np.ndarray | None) -> list[str]:
    """What an energy year takes for a structure's irradiance inputs (:func:`annual_energy`)."""
    if len(structure.inputs) <= 2:
        return []
    names = list(structure.inputs[2:])
    if ghi_grid is not None:
        return [f"irradiance inputs {names}: the weather's global horizontal irradiance for each"]
    return [f"irradiance inputs {names} taken as 0 W/m² (the weather has none)"]


def _ready_by(steps: Any, horizon: int, R: int, n: int):
    """ "Ready by" pre-heating (:func:`annual_energy`): A^m of the stabled step for m = 0 ..
    ``horizon`` per run (R x n x n each), and the full-power equilibrium per kelvin of T_o and
    per watt (R x n); without a horizon, zeros in their place."""
    if not horizon:
        return np.zeros((1, R, n, n)), np.zeros((R, n)), np.zeros((R, n))
    Ad = steps.Ad
    powers = [np.broadcast_to(np.eye(n), (R, n, n))]
    for _ in range(horizon):
        powers.append(np.einsum("sij,sjk->sik", Ad[0], powers[-1]))
    Am = np.array(powers)  # (horizon + 1, runs, n, n)
    A_cont = steps.A[0]
    B_cont = steps.B[0]
    x_per_T_o = -np.linalg.solve(A_cont, B_cont[:, :, 0:1])[:, :, 0]
    x_per_W = -np.linalg.solve(A_cont, B_cont[:, :, 1:2])[:, :, 0]
    return Am, x_per_T_o, x_per_W


MONTHS = ("Jan", "Feb", "Mar", "Apr", "May", "Jun", "Jul", "Aug", "Sep", "Oct", "Nov", "Dec")


def _banded(c: float, lo: float, hi: float, scale: float = 1.0, sign: bool = False) -> str:
    """``c [lo, hi]`` in whole units of ``scale`` ("" for NaN; no band where lo is NaN)."""
    if math.isnan(c):
        return ""
    fmt = "{:+,.0f}" if sign else "{:,.0f}"
    band = "" if math.isnan(lo) else f" [{fmt.format(lo / scale)}, {fmt.format(hi / scale)}]"
    return fmt.format(c / scale) + band


def markdown(result: AnnualResult) -> str:
    """The annual result for readers: the year's heating energy, pre-heating, peak power and
    unmet hours with 95 % bands, the months, and each what-if's paired difference."""
    r = result
    carry = f" ({', '.join(r.band_sources)})" if r.band_sources else ""
    bands = "95 % bands over " + (
        f"{r.draws} parameter draws{carry}" if r.draws else "no draws (central only)"
    )
    source = f" ({r.source})" if r.source else ""
    lines = [
        f"Annual heating energy of {r.label}{source}: weather {r.weather}, profile {r.profile}, "
        f"{r.dt_s:g} s step; {bands}.",
        *(f"Note: {n}." for n in r.notes),
        "",
        "| variant | heating (kWh/a) | of it pre-heating (kWh/a) | peak in service (W) | "
        f"peak outside service (W) | design load at {r.design_T_o_C:.1f} °C (W) | unmet (h) |",
        "|---|---|---|---|---|---|---|",
    ]
    for v, name in enumerate(r.variants):
        design = "" if r.design_load_W is None else _banded(*r.band(r.design_load_W[v]))
        lines.append(
            f"| {name} | {_banded(*r.band(r.energy_kWh[v]))} | "
            f"{_banded(*r.band(r.preheat_kWh[v]))} | {_banded(*r.band(r.peak_service_W[v]))} | "
            f"{_banded(*r.band(r.peak_preheat_W[v]))} | {design} | "
            f"{_banded(*r.band(r.unmet_h[v]))} |"
        )
    lines += ["", *balance_markdown(r)]
    lines += ["", "| month | " + " | ".join(MONTHS) + " |", "|---" * 13 + "|"]
    cells = [f"{r.monthly_kWh[0, 0, m]:,.0f}" for m in range(12)]
    lines.append(f"| {r.variants[0]} (kWh) | " + " | ".join(cells) + " |")
    for v in range(1, len(r.variants)):
        c, lo, hi = r.difference(v)
        band = "" if math.isnan(lo) else f" [{lo:+,.0f}, {hi:+,.0f}]"
        lines.append("")
        lines.append(f"{r.variants[v]} against the base: {c:+,.0f} kWh/a{band} (paired).")
    lines += ["", "Cooling is not modelled: above its set point the vehicle floats."]
    return "\n".join(lines)


def balance_markdown(result: AnnualResult) -> list[str]:
    """The year's heat balance per variant (kWh/a, 95 % bands): the losses through the
    envelope and the open doors, and what covers them: the internal gains (passengers and
    auxiliaries, the profile's), the sun through the apertures and the heating; the rest is
    the heat stored over the year and the steps' rounding."""
    r = result
    lines = [
        "Heat balance of the year (kWh/a): losses = gains + sun + heating (+ stored).",
        "",
        "| variant | envelope loss | door loss | internal gains | sun | heating | stored |",
        "|---|---|---|---|---|---|---|",
    ]
    stored = r.stored()
    for v, name in enumerate(r.variants):
        cells = [
            _banded(*r.band(getattr(r, key)[v])) for key in (*BALANCE, "energy_kWh")
        ]  # fmt: skip
        lines.append(f"| {name} | " + " | ".join(cells) + f" | {round(stored[v, 0]) + 0.0:+,.0f} |")
    return lines


# ------------------------------------------------------------------------------------------
# the study's table (rule energy)


def step_problem(dt_s: float) -> str | None:
    """Why ``dt_s`` cannot be the simulation step of a year under a profile (None where it
    can): the profile's hours (service, passengers, pre-heating) and the weather's hourly
    records need a step of an hour or less; a longer one skips them (a step of a day, or of
    more than the year, gives a year of 0 kWh)."""
    if not (math.isfinite(dt_s) and dt_s > 0):
        return "expected a positive step (s), e.g. 60"
    if dt_s > 3600.0:
        return (
            "longer than an hour: the profile's hours and the weather's hourly records fall "
            "between the steps; give a step of at most 3600 s, e.g. 60 or 300"
        )
    return None


def heater_surface(params: Any, given: float | None) -> float | None:
    """The outer surface that sizes a per-m² heater: ``given`` (``--surface-m2``) or, for a
    class reference model (``params``, a :class:`railtherm.study.simulate.ParameterSet`),
    the surface it was built for; both, when they differ, contradict each other (the
    model's kA and capacities are those of its own surface)."""
    own = params.surface_m2
    if given is None or own is None:
        return own if given is None else given
    if not math.isclose(given, own, rel_tol=1e-9):
        raise ConfigError(
            "--surface-m2",
            "surface_m2",
            given,
            f"the class reference model was built for {own:g} m² (its kA and capacities are "
            "that surface's): leave --surface-m2 out, or build the model for this surface "
            "(railtherm reference --surface-m2)",
        )
    return given


def study_columns() -> list[str]:
    """The columns of the study's annual energy table (:func:`study_rows`), in order: an
    empty table (no vehicle with an acceptable fit) has them too."""
    columns = ["vehicle", "class", "model", "profile", "climate", "weather", "variant"]
    for key in (*TOTALS, "difference_kWh", *BALANCE):
        columns += [key, f"{key}_lo", f"{key}_hi"]
    columns.append("design_T_o_C")
    for name in MONTHS:
        columns += [f"{name}_kWh", f"{name}_lo", f"{name}_hi"]
    return [*columns, "draws"]


def no_acceptable_fit(verdicts: Mapping[str, str]) -> str:
    """The statement of an empty energy table: no vehicle has an acceptable fit (``verdicts``:
    {vehicle: its fit's verdict}), where to read why and what gives a row."""
    found = "; ".join(f"{vid}: {v}" for vid, v in verdicts.items()) or "no vehicle in the study"
    return (
        f"No vehicle has an acceptable fit ({found}), so there is no annual "
        "energy to compute. Each fit's verdict and its reasons are in "
        "results/vehicles/<id>/fit_<model>.yaml; a fit judged acceptable gives a row (or run "
        "railtherm energy on a class reference model)."
    )


def study_rows(
    fits: Mapping[str, Fit],
    vehicles: Mapping[str, Mapping[str, Any]],
    weathers: Sequence[Weather],
    profiles: Mapping[str, Profile],
    what_ifs: Sequence[WhatIf] = (),
    *,
    dt_s: float = 60.0,
    draws: int = 200,
    seed: int = 0,
    hold: str = "first_order",
    index: Mapping[str, int] | None = None,
) -> list[dict[str, Any]]:
    """One row per vehicle with an acceptable fit, climate and variant, each vehicle under
    its profile (``profiles``, {vehicle: profile}): the annual energy, pre-heating, peaks,
    design load and unmet hours with 95 % bands, the heat balance, the months (central and
    band) and, for a what-if, its paired difference from the base. A vehicle's draws are
    seeded by ``seed``, its place in the study (``index``, default the order of ``fits``)
    and the climate."""
    from railtherm.study.quality import ACCEPTABLE

    index = index if index is not None else {vid: i for i, vid in enumerate(fits)}
    rows = []
    for vid, fit in fits.items():
        if fit.verdict != ACCEPTABLE:
            continue
        for j, year in enumerate(weathers):
            result = annual_energy(
                fit,
                year,
                profiles[vid],
                what_ifs=what_ifs,
                dt_s=dt_s,
                draws=draws,
                seed=seed + 100 * index[vid] + j,
                volume_m3=vehicles[vid].get("volume_m3"),
                hold=hold,
                surface_m2=vehicles[vid].get("surface_m2"),
            )
            ids = {
                "vehicle": vid,
                "class": vehicles[vid].get("class", ""),
                "model": fit.model,
                "profile": profiles[vid].name,
                "climate": year.name,
            }
            rows += result_rows(result, ids)
    return rows


BALANCE = ("envelope_kWh", "doors_kWh", "gains_kWh", "solar_kWh")
# the per-run totals of a year a row gives with their 95 % bands, beside the balance
TOTALS = (
    "energy_kWh", "preheat_kWh", "peak_service_W", "peak_preheat_W", "design_load_W", "unmet_h",
)  # fmt: skip


def result_rows(result: AnnualResult, ids: Mapping[str, Any]) -> list[dict[str, Any]]:
    """One row per variant of ``result`` (:func:`study_columns`, after the identifying
    columns ``ids``): every total with its 95 % band, the heat balance, the months and, for
    a what-if, its paired difference from the base."""
    rows = []
    for v, variant in enumerate(result.variants):
        row: dict[str, Any] = {**ids, "weather": result.weather, "variant": variant}
        for key in (*TOTALS, *BALANCE):
            row[key], row[f"{key}_lo"], row[f"{key}_hi"] = result.band(getattr(result, key)[v])
        row["design_T_o_C"] = result.design_T_o_C
        diff = result.difference(v) if v else (math.nan,) * 3
        row["difference_kWh"], row["difference_kWh_lo"], row["difference_kWh_hi"] = diff
        for m, name in enumerate(MONTHS):
            c, lo, hi = result.band(result.monthly_kWh[v, :, m])
            row[f"{name}_kWh"], row[f"{name}_lo"], row[f"{name}_hi"] = c, lo, hi
        row["draws"] = result.draws
        rows.append(row)
    return rows


def study_markdown(table, profiles: Sequence[Profile], dt_s: float, source: str) -> str:
    """The study's annual energy table for readers: the totals per vehicle, climate and
    variant, then the heat balance of each base year; ``profiles`` the profiles the rows
    name (their heating limits are stated)."""
    limits = "; ".join(
        f"{p.name}: {p.heating_limit_W_per_m2:g} W/m² of the vehicle's outer surface"
        if p.heating_limit_W_per_m2 is not None
        else f"{p.name}: {p.heating_limit_W / 1000:,.0f} kW"
        for p in sorted(profiles, key=attrgetter("name"))
    )
    lines = [
        "# Annual heating energy in two typical years",
        "",
        f"Data: {source}. Each vehicle under its class's operating profile (column profile, "
        f"config/profiles/), {dt_s:g} s step, the vehicle's identified model (second order "
        "where its fit is acceptable, else first order: the column model) with an ideal HVAC "
        f"to the set point within the profile's heating limit ({limits or 'none'}); 95 % "
        "bands over parameter draws; a what-if's difference is paired (the same draws). "
        "Peaks in service and outside it (pre-heating from the set-back, stabling); the "
        "design load is the steady heating that holds the set point at the year's 99.6 % "
        "dry-bulb temperature (design T_o), door closed, without gains or sun. Cooling is "
        "not modelled. (railtherm.study.energy)",
        "",
        "| vehicle | model | profile | climate | variant | heating (kWh/a) | difference "
        "(kWh/a) | pre-heating (kWh/a) | peak in service (kW) | peak outside service (kW) | "
        "design load (kW) | design T_o (°C) | unmet (h) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]

    def band(r, key: str, scale: float = 1.0, sign: bool = False) -> str:
        return _banded(float(r[key]), float(r[f"{key}_lo"]), float(r[f"{key}_hi"]), scale, sign)

    if table.empty:
        lines[-2:] = [no_acceptable_fit(table.attrs.get("verdicts", {}))]
        return "\n".join(lines) + "\n"
    for _, r in table.iterrows():
        lines.append(
            f"| {r['vehicle']} | {r['model']} | {r['profile']} | {r['climate']} | "
            f"{r['variant']} | {band(r, 'energy_kWh')} | "
            f"{band(r, 'difference_kWh', sign=True)} | {band(r, 'preheat_kWh')} | "
            f"{band(r, 'peak_service_W', 1000.0)} | {band(r, 'peak_preheat_W', 1000.0)} | "
            f"{band(r, 'design_load_W', 1000.0)} | {r['design_T_o_C']:.1f} | "
            f"{band(r, 'unmet_h')} |"
        )
    lines += [
        "",
        "Heat balance of each base year (kWh/a): the losses through the envelope and the "
        "open doors are covered by the internal gains (passengers and auxiliaries, the "
        "profile's), the sun through the apertures and the heating.",
        "",
        "| vehicle | climate | envelope loss | door loss | internal gains | sun | heating |",
        "|---|---|---|---|---|---|---|",
    ]
    for _, r in table[table["variant"] == "base"].iterrows():
        cells = [band(r, key) for key in (*BALANCE, "energy_kWh")]
        lines.append(f"| {r['vehicle']} | {r['climate']} | " + " | ".join(cells) + " |")
    left_out = table.attrs.get("verdicts") or {}
    if left_out:
        named = "; ".join(f"{vid} ({verdict})" for vid, verdict in left_out.items())
        lines += ["", f"Not in the tables, without an acceptable fit of any order: {named}."]
    return "\n".join(lines) + "\n"


def _best_fits(
    fit_files: Sequence[str], owners: Sequence[str], posteriors: Sequence[str] = ()
) -> dict[str, Fit]:
    """{vehicle: fit}: per vehicle the first acceptable of its ``fit_files`` (each of the
    vehicle ``owners`` names; the second order listed first), else its first; read with
    their ``posteriors`` (one per fit file, in order) where given."""
    from railtherm.study.fit import read_fit
    from railtherm.study.quality import ACCEPTABLE

    fits: dict[str, Fit] = {}
    ncs = list(posteriors) or [None] * len(fit_files)
    for vid, path, nc in zip(owners, fit_files, ncs, strict=True):
        fit = read_fit(path, posterior=nc)
        if vid not in fits or (fits[vid].verdict != ACCEPTABLE and fit.verdict == ACCEPTABLE):
            fits[vid] = fit
    return fits


def vehicle_energy(
    vid: str,
    vehicle: Mapping[str, Any],
    fit_files: Sequence[str],
    weather_files: Sequence[str],
    profile_file: str,
    what_if: Sequence[str] = (),
    index: int = 0,
    posteriors: Sequence[str] = (),
    **options: Any,
):
    """The rows of one vehicle (rule energy, :func:`study_rows`): its best fit of
    ``fit_files`` (second order listed first; with its posterior of ``posteriors``, one per
    fit file, where given: the draws are then the posterior's), the typical years (files,
    or as read: :func:`railtherm.study.weather.load_year`), its class's profile and
    the what-ifs as the config writes them, seeded by its place ``index`` in the study;
    ``options`` go to :func:`study_rows` (dt_s, draws, seed, hold). Returns the table (no
    rows without an acceptable fit)."""
    import pandas as pd

    from railtherm.study.quality import ACCEPTABLE
    from railtherm.study.weather import load_year

    fits = _best_fits(fit_files, [vid] * len(fit_files), posteriors)
    if all(fit.verdict != ACCEPTABLE for fit in fits.values()):  # no row: no weather read
        return pd.DataFrame([], columns=study_columns())
    weathers = [load_year(path) for path in weather_files]
    profile = load_profile(profile_file)
    what_ifs = [parse_what_if(text) for text in what_if]
    rows = study_rows(
        fits, {vid: vehicle}, weathers, {vid: profile}, what_ifs, index={vid: index}, **options
    )
    return pd.DataFrame(rows, columns=study_columns())


def study_table(tables: Sequence[str], fit_files: Sequence[str], fit_vehicles: Sequence[str]):
    """The study's annual energy table (rule energy_table): the vehicles' tables (rule
    energy, in study order) one after the other; it carries (``attrs["verdicts"]``) the fit
    verdict of each vehicle without a row (``fit_files`` of the vehicles ``fit_vehicles``
    names), which its Markdown names."""
    import pandas as pd

    parts = [pd.read_csv(path) for path in tables]
    parts = [part for part in parts if not part.empty]
    columns = study_columns()
    table = pd.concat(parts, ignore_index=True)[columns] if parts else pd.DataFrame(columns=columns)
    # the vehicles without a row (no acceptable fit of any order), each with its verdict
    shown = set(table["vehicle"].astype(str))
    owners = [(v, f) for v, f in zip(fit_vehicles, fit_files, strict=True) if v not in shown]
    fits = _best_fits([f for _, f in owners], [v for v, _ in owners])
    table.attrs["verdicts"] = {vid: str(fit.verdict) for vid, fit in fits.items()}
    return table


def write_result(result: AnnualResult, ids: Mapping[str, Any], out: str | Path) -> list[Path]:
    """``railtherm energy --out``: ``result`` in the directory ``out`` as energy.csv (a row per
    variant, :func:`result_rows` after ``ids``, 4 significant digits), energy.md (as printed)
    and energy.png / energy.svg (the months with their bands). Returns the paths written."""
    import pandas as pd

    from railtherm.report import plots, tables

    out = Path(out)
    table = pd.DataFrame(result_rows(result, ids), columns=study_columns())
    figure = plots.annual_energy_figure(table, note=result.band_note())  # drawn before writing
    out.mkdir(parents=True, exist_ok=True)
    tables.write_csv(table, out / "energy.csv", digits=4)
    (out / "energy.md").write_text(markdown(result) + "\n", encoding="utf-8")
    png, svg = plots.save_figure(figure, out / "energy")
    return [out / "energy.csv", out / "energy.md", png, svg]


def write_study_energy(
    table, profiles: Sequence[Profile], dt_s: float, source: str, csv: str, md: str, figure: str
) -> None:
    """The study's annual energy ``table`` (:func:`study_table`) as CSV (4 significant
    digits) and Markdown, and its figure (``figure``: the path without suffix; PNG and
    SVG), whose footer says what its whiskers are."""
    from railtherm.report import plots, tables

    tables.write_csv(table, csv, digits=4)
    used = {p.name: p for p in profiles if p.name in set(table["profile"])}
    with open(md, "w", encoding="utf-8") as stream:
        stream.write(study_markdown(table, list(used.values()), dt_s, source))
    draws = int(table["draws"].max()) if not table.empty else 0
    bands = (
        f"bars central, whiskers the 95 % band over {draws} parameter draws"
        if draws
        else "central runs only"
    )
    plots.save_figure(plots.annual_energy_figure(table, note=f"{source}; {bands}"), figure)
