"""The class reference model: a second-order parameter set for a vehicle nobody measured.

The paper generalises its fits by vehicle class (section 6.3): the specific heat capacity of the
vehicle body ``c_veh = C_veh / m_veh`` (eq. 24) and the ratio of the two heat capacities
``delta = C_veh / C`` (eq. 25). Read backwards, a class's generalised parameters give the
second-order model (eqs. 7-8, 14) of an unmeasured vehicle of that class from its mass ``m`` and
outer surface ``A``:

- ``C_veh = c_veh * m`` (eq. 24),
- ``C = C_veh / delta`` (eq. 25),
- ``K_veh = kappa_veh * A``, and
- ``kA = k * A`` (eq. 5), with ``k`` the class's unless the caller gives it (a k-value test of
  the new vehicle, ``--k``).

``kappa_veh = K_veh / A`` (W/(m2 K)) is railtherm's generalisation of the coupling between the
air and the vehicle's heat capacity: the paper gives none for ``K_veh``. Scaling it with the
outer surface assumes that the inner surfaces exchanging heat with the air grow with the
vehicle as ``A`` does; it is an assumption of railtherm, not a result of the paper.

Each generalised parameter is summarised over the class's usable vehicles in log space (they
are positive and spread over a factor, not a difference): the centre is the geometric mean and
the interval is the 95 % **prediction** interval for one new vehicle of the class,
``mean_log +- t_{0.975, n-1} * sd_log * sqrt(1 + 1/n)``. A new vehicle is not the class mean:
it scatters about it as the fitted vehicles do (the ``1``), and the class mean itself is known
only from ``n`` vehicles (the ``1/n``); the t quantile accounts for ``sd_log`` being estimated
from ``n`` values. The intervals of the derived parameters (``kA``, ``C``, ``K_veh``,
``C_veh``) are the 2.5 % and 97.5 % quantiles of :data:`PARAMETER_DRAWS` draws with the fixed
seed :data:`PARAMETER_SEED`, the generalised parameters drawn independently of each other from
their predictive distributions (their correlation across vehicles is not modelled: with 2 to 5
vehicles per class it cannot be estimated). The intervals come from the spread between the
vehicles' fits; each fit's own 95 % interval is not added (it is mostly much narrower than the
spread between vehicles).

A vehicle is usable when its checked second-order fit is acceptable
(:data:`railtherm.study.quality.ACCEPTABLE`), every one of ``kA``, ``C``, ``K_veh`` and
``C_veh`` is
identified (no estimate at a bound of the search) and its config gives ``mass_kg`` and
``surface_m2``. The study's members (:func:`members_from_study`, ``railtherm reference``) come
from its committed Table 2 (``results/tables/table2.csv``: k, C, K_veh, C_veh with their
status and the verdict, 6 significant digits; ``kA = k A``), not from the per-vehicle fit
files, which are not committed; :func:`member_from_fit` applies the same rule to a fit.
:func:`build` refuses a class with fewer than ``min_vehicles`` (at least 2: a spread needs
two) usable vehicles, naming them and why the others were not used.
"""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import yaml

from railtherm import structures
from railtherm.errors import ConfigError
from railtherm.estimation import pem
from railtherm.estimation.priors import LinearT
from railtherm.study import identifiability, quality
from railtherm.study.fit import Fit, write_yaml
from railtherm.yamlio import packaged_schema, read_yaml, validate_schema

__all__ = [
    "GENERALISED",
    "PARAMETER_DRAWS",
    "PARAMETER_SEED",
    "POOLED",
    "RAIL_CLASSES",
    "ClassMember",
    "Generalised",
    "ReferenceModel",
    "build",
    "member_from_fit",
    "member_from_row",
    "members_from_table2",
    "members_from_study",
    "read_reference_model",
]

# the rail classes of the vehicle schema (tram, metro, regional, main-line); class other (a test
# cell, a building) is no class to generalise over
RAIL_CLASSES: tuple[str, ...] = tuple(
    packaged_schema("vehicle")["if"]["properties"]["class"]["enum"]
)
POOLED = "all"  # every rail class pooled: a comparator, not a class
KIND = "class_reference_model"
MODEL = "order2"
STRUCTURE = "second_order"
# the parameters of the second-order model (eqs. 7-8) and their units
FIT_PARAMETERS = ("kA", "C", "K_veh", "C_veh")
UNITS = {"kA": "W/K", "C": "J/K", "K_veh": "W/K", "C_veh": "J/K"}
# the kinds of a parameter the data do not determine
AT_BOUND = "at a bound"
UNBOUNDED = "interval unbounded"
COUPLED = "coupled to a parameter not identified"
TABLE2 = os.path.join("tables", "table2.csv")  # Table 2 under the study's results directory
# Table 2's column of each fit parameter: k = kA / A (eq. 5), the others as fitted
TABLE_COLUMNS = {"kA": "k", "C": "C", "K_veh": "K_veh", "C_veh": "C_veh"}
# the generalised parameters: c_veh (eq. 24), delta (eq. 25), kappa_veh = K_veh / A and k
GENERALISED = {
    "c_veh": "J/(kg K)",
    "delta": "1",
    "kappa_veh": "W/(m2 K)",
    "k": "W/(m2 K)",
}
PARAMETER_DRAWS = 20_000  # draws behind the derived parameters' intervals
PARAMETER_SEED = 0  # their seed: the intervals are the same on every run
NOTE = (
    "The intervals are 95 % prediction intervals for one new vehicle of the class, from the "
    "spread of the fits of the {n} vehicles in basis (log scale, t with {dof} degrees of "
    "freedom, sd_log * sqrt(1 + 1/n)); those of kA, C, K_veh and C_veh are the 2.5 and 97.5 % "
    "quantiles of {draws} draws (seed {seed}) that assume the generalised parameters "
    "independent. kappa_veh = K_veh / A is railtherm's generalisation of the coupling (the "
    "paper gives none). {k}{synthetic}"
)


# ---------------------------------------------------------------------------------------------
# The members of a class: one vehicle's generalised parameters


@dataclass(frozen=True)
class ClassMember:
    """One vehicle's generalised parameters from its checked second-order fit.

    ``k = kA / A`` (W/(m2 K)), ``c_veh = C_veh / m`` (J/(kg K), eq. 24), ``delta = C_veh / C``
    (eq. 25), ``kappa_veh = K_veh / A`` (W/(m2 K), railtherm's; the paper gives none). A value
    is None where the fit does not identify a parameter it needs or the config does not give
    the mass or surface. ``usable``: the fit is acceptable, kA, C, K_veh and C_veh are all
    identified and mass and surface are given; ``why`` says why not ("" when usable).
    ``synthetic``: the vehicle's data come from the virtual climatic wind tunnel."""

    vehicle: str
    vehicle_class: str
    mass_kg: float | None
    surface_m2: float | None
    k: float | None
    c_veh: float | None
    delta: float | None
    kappa_veh: float | None
    usable: bool
    why: str
    synthetic: bool = False


def _metadata(vehicle: Mapping[str, Any], key: str) -> float | None:
    """A vehicle config's ``mass_kg`` or ``surface_m2``: a positive number, or None."""
    value = vehicle.get(key)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(f"vehicle {vehicle.get('id')}", key, value, "expected a positive number")
    if not (math.isfinite(value) and value > 0):
        raise ConfigError(f"vehicle {vehicle.get('id')}", key, value, "expected a positive number")
    return float(value)


def _kind(reason: str) -> str:
    """The kind of a "not identified" reason (:func:`railtherm.estimation.pem.identification`): an
    estimate at a bound of the search ("at its lower search bound 1e+04"), a 95 % interval
    unbounded or wider than a factor 1000 in total (also without a reason), or a parameter
    coupled to one of those (:func:`railtherm.study.identifiability.coupled_identification`)."""
    if "coupled to" in reason:
        return COUPLED
    if "unbounded" in reason or "spans a factor" in reason:
        return UNBOUNDED
    return AT_BOUND if "bound" in reason else UNBOUNDED


def _member(
    vehicle: Mapping[str, Any],
    estimates: Mapping[str, float | None],
    not_identified: Mapping[str, str],
    verdict: str,
    synthetic: bool,
) -> ClassMember:
    """The one usability rule of a :class:`ClassMember`, whatever its source.

    ``estimates``: kA, C, K_veh and C_veh (None where not identified or not known);
    ``not_identified``: parameter -> kind (:data:`AT_BOUND` or :data:`UNBOUNDED`); ``verdict``
    the fit's (:data:`railtherm.study.quality.ACCEPTABLE` to be usable). c_veh by eq. 24,
    delta by eq. 25. A parameter of the dynamic part (C, K_veh, C_veh: ``Structure.coupled``)
    coupled to
    one not identified is not identified either (:data:`COUPLED`). Usable: acceptable, every
    parameter identified and estimated, mass and surface given; ``why`` one phrase per kind of
    unidentified parameters ("C, K_veh not identified (at a bound)"), then the verdict, then the
    missing metadata."""
    mass, surface = _metadata(vehicle, "mass_kg"), _metadata(vehicle, "surface_m2")
    coupled = structures.named(STRUCTURE).coupled
    if any(p in not_identified for p in coupled):  # the others of the dynamic part neither
        not_identified = {**{p: COUPLED for p in coupled}, **not_identified}
    value = {p: None if p in not_identified else estimates.get(p) for p in FIT_PARAMETERS}

    def ratio(num: float | None, den: float | None) -> float | None:
        return None if num is None or den is None else float(num / den)

    by_kind: dict[str, list[str]] = {}
    for p in FIT_PARAMETERS:
        if p in not_identified:
            by_kind.setdefault(not_identified[p], []).append(p)
    kinds = sorted(by_kind, key=lambda kind: kind == COUPLED)  # the cause before its coupling
    why = [f"{', '.join(by_kind[kind])} not identified ({kind})" for kind in kinds]
    if verdict != quality.ACCEPTABLE:
        doubt = verdict == quality.IN_DOUBT
        why.append("fit assumptions in doubt" if doubt else f"fit verdict {verdict!r}")
    why += [f"no {key}" for key, v in (("mass_kg", mass), ("surface_m2", surface)) if v is None]
    unknown = [p for p in FIT_PARAMETERS if value[p] is None and p not in not_identified]
    if unknown and not why:  # a safety net: never usable without every estimate
        why.append(f"{', '.join(unknown)} not given")
    return ClassMember(
        vehicle=str(vehicle.get("id")),
        vehicle_class=str(vehicle.get("class")),
        mass_kg=mass,
        surface_m2=surface,
        k=ratio(value["kA"], surface),
        c_veh=ratio(value["C_veh"], mass),
        delta=ratio(value["C_veh"], value["C"]),
        kappa_veh=ratio(value["K_veh"], surface),
        usable=not why,
        why="; ".join(why),
        synthetic=synthetic,
    )


def _unidentified(fit: Fit) -> dict[str, str]:
    """The parameters of the fit that are not identified and the kind of each. A parameter
    flagged ``at_bound`` counts even when marked identified: a fit whose estimate sits at a
    bound is never used."""
    params = fit.parameters
    pinned = {
        p for f in fit.flags if f.get("code") == "at_bound" for p in f.get("parameters") or ()
    }
    out = {}
    for p in FIT_PARAMETERS:
        if p in pinned:
            out[p] = AT_BOUND
        elif not params[p].identified:
            out[p] = _kind(str(params[p].identification.reason or ""))
    return out


def member_from_fit(fit: Fit, vehicle: Mapping[str, Any]) -> ClassMember:
    """The :class:`ClassMember` of one vehicle: its checked second-order fit (``fit_order2.yaml``
    or ``fit_order2_kalman.yaml``, :func:`railtherm.study.fit.read_fit`) and its vehicle config as a
    dict (``id``, ``class``, ``mass_kg``, ``surface_m2``). c_veh by eq. 24, delta by eq. 25."""
    vid = str(vehicle.get("id"))
    if fit.vehicle != vid:
        raise ConfigError(
            f"fit of {fit.vehicle}", "vehicle", fit.vehicle, f"is not the config's vehicle {vid!r}"
        )
    base = fit.structure_name.split("+")[0]
    if base != STRUCTURE:
        raise ConfigError(
            f"fit of {vid}",
            "structure",
            fit.structure_name or None,
            f"a class reference model needs the second-order fit ({STRUCTURE}, eqs. 7-8)",
        )
    params = fit.parameters
    missing = [p for p in FIT_PARAMETERS if p not in params]
    if missing:
        raise ConfigError(
            f"fit of {vid}", "parameters", sorted(params), f"lacks {', '.join(missing)}"
        )
    return _member(
        vehicle,
        {p: params[p].value for p in FIT_PARAMETERS},
        _unidentified(fit),
        fit.verdict,
        bool(vehicle.get("synthetic", False) or fit.synthetic),
    )


def _cell(row: Mapping[str, Any], column: str, table: str) -> Any:
    if column not in row:
        raise ConfigError(table, column, None, "column missing: not a Table 2 of railtherm")
    value = row[column]
    if isinstance(value, float) and math.isnan(value):
        return None  # an empty cell (pandas reads it as NaN)
    return None if value == "" else value


def member_from_row(
    row: Mapping[str, Any], vehicle: Mapping[str, Any], table: str = "table2.csv"
) -> ClassMember:
    """The :class:`ClassMember` of one vehicle from its row of Table 2 (``table2.csv`` of
    :func:`railtherm.study.aggregate.table2`, as a dict: column -> cell, an empty cell "" or NaN)
    and its vehicle config as a dict (``class``, ``mass_kg``, ``surface_m2``, ``synthetic``; the
    id, if given, must be the row's). ``kA = k * A`` (eq. 5); a status other than "estimated"
    ("not identified: <reason>") makes the parameter not identified; the row's verdict is the
    fit's. The same rule as :func:`member_from_fit`. ``table`` names the file in messages.

    Raises a one-line :class:`ConfigError` for a row that disagrees with the config (another
    vehicle or class, k "not given" though the config gives ``surface_m2``: a Table 2 older
    than the config) or an estimate that is not a positive number."""
    from railtherm.study.aggregate import ESTIMATED, NOT_GIVEN_PREFIX, SYNTHETIC_SOURCE

    vid = str(_cell(row, "vehicle", table))
    if vehicle.get("id") is not None and str(vehicle["id"]) != vid:
        raise ConfigError(table, "vehicle", vid, f"is not the config's vehicle {vehicle['id']!r}")
    vehicle = {**vehicle, "id": vid}
    if str(_cell(row, "class", table)) != str(vehicle.get("class")):
        raise ConfigError(
            table,
            "class",
            _cell(row, "class", table),
            f"{vid}'s config says {vehicle.get('class')!r}: the table is older than the config "
            "(rerun snakemake)",
        )
    surface = _metadata(vehicle, "surface_m2")
    estimates: dict[str, float | None] = {}
    not_identified: dict[str, str] = {}
    for p, column in TABLE_COLUMNS.items():
        status = str(_cell(row, f"{column}_status", table) or "")
        if status == ESTIMATED:
            value = _cell(row, column, table)
            try:
                number = float(value)
            except (TypeError, ValueError):
                number = math.nan
            if not (math.isfinite(number) and number > 0):
                raise ConfigError(
                    table, column, row[column], f"{vid}: estimated, but not a positive number"
                )
            if p == "kA":
                number = None if surface is None else number * surface  # eq. 5
            estimates[p] = number
        elif status.startswith(NOT_GIVEN_PREFIX):
            if p == "kA" and surface is not None:
                raise ConfigError(
                    table,
                    f"{column}_status",
                    status,
                    f"{vid}'s config gives surface_m2: the table is older than the config "
                    "(rerun snakemake)",
                )
            estimates[p] = None  # no surface_m2: the metadata rule says so
        else:
            not_identified[p] = _kind(status)
    verdict = str(_cell(row, "verdict", table))
    source = _cell(row, "source", table)
    return _member(
        vehicle,
        estimates,
        not_identified,
        verdict,
        bool(vehicle.get("synthetic", False) or source == SYNTHETIC_SOURCE),
    )


def _read_table2(path: str, display: str) -> dict[str, dict[str, Any]]:
    """Table 2 by vehicle: each row as a dict of its cells (strings; "" for an empty cell)."""
    if not os.path.isfile(path):
        raise ConfigError(
            display,
            "(file)",
            display,
            "not found: the study's Table 2, which `snakemake` writes (run it first)",
        )
    try:
        with open(path, encoding="utf-8", newline="") as stream:
            rows = list(csv.DictReader(stream))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise ConfigError(display, "(file)", display, f"cannot read the table: {exc}") from None
    by_vehicle: dict[str, dict[str, Any]] = {}
    for row in rows:
        vid = _cell(row, "vehicle", display)
        if vid in by_vehicle:
            raise ConfigError(display, "vehicle", vid, "listed twice")
        by_vehicle[str(vid)] = row
    return by_vehicle


def members_from_table2(
    path: str | os.PathLike[str], vehicles: Mapping[str, Mapping[str, Any]]
) -> list[ClassMember]:
    """The vehicles of ``vehicles`` ({id: vehicle config}) that have a row in the study's
    Table 2 at ``path``, as :class:`ClassMember` (:func:`member_from_row`), in the table's
    order; rows of other vehicles are ignored."""
    display = str(path)
    rows = _read_table2(display, display)
    return [
        member_from_row(row, vehicles[vid], table=display)
        for vid, row in rows.items()
        if vid in vehicles
    ]


def members_from_study(
    config_path: str | os.PathLike[str],
    results_dir: str | os.PathLike[str] = "results",
    workdir: str | os.PathLike[str] = ".",
) -> list[ClassMember]:
    """Every vehicle of a study as a :class:`ClassMember` (:func:`member_from_row`), in the
    config's order.

    ``config_path`` (the study config) and ``results_dir`` are relative to ``workdir``, the
    vehicle files as the config lists them. Reads the study's Table 2,
    ``<results_dir>/tables/table2.csv`` (committed with the study; ``snakemake`` writes it),
    and each vehicle config (:func:`read_yaml` only: its raw files need not exist) for its
    class, mass, surface and whether its data are synthetic. A vehicle without a row is a
    member that is not usable ("not in table2.csv"); rows of vehicles the config does not
    list are ignored."""
    config_name = str(config_path)
    config = read_yaml(os.path.join(workdir, config_path), display=config_name)
    vehicles = config.get("vehicles") if isinstance(config, dict) else None
    if not isinstance(vehicles, list) or not all(isinstance(v, str) for v in vehicles):
        raise ConfigError(config_name, "vehicles", vehicles, "expected a list of vehicle files")
    table = os.path.join(str(results_dir), TABLE2)
    rows = _read_table2(os.path.join(workdir, table), table)
    members: list[ClassMember] = []
    seen: set[str] = set()
    for path in vehicles:
        data = read_yaml(os.path.join(workdir, path), display=path)
        if not isinstance(data, dict) or not isinstance(data.get("id"), str):
            raise ConfigError(path, "id", (data or {}).get("id"), "expected the vehicle's id")
        vid = data["id"]
        if data.get("class") not in (*RAIL_CLASSES, "other"):
            raise ConfigError(
                path, "class", data.get("class"), f"expected one of {', '.join(RAIL_CLASSES)}"
            )
        if vid in seen:
            raise ConfigError(config_name, "vehicles", path, f"vehicle id {vid!r} listed twice")
        seen.add(vid)
        if vid in rows:
            members.append(member_from_row(rows[vid], data, table=table))
            continue
        members.append(
            ClassMember(
                vehicle=vid,
                vehicle_class=str(data["class"]),
                mass_kg=_metadata(data, "mass_kg"),
                surface_m2=_metadata(data, "surface_m2"),
                k=None,
                c_veh=None,
                delta=None,
                kappa_veh=None,
                usable=False,
                why=f"not in {os.path.basename(TABLE2)}",
                synthetic=bool(data.get("synthetic", False)),
            )
        )
    return members


# ---------------------------------------------------------------------------------------------
# A class's generalised parameters


@dataclass
class Generalised:
    """One generalised parameter over a class's usable vehicles, in log space.

    ``values`` by vehicle; ``centre`` the geometric mean; ``sd_log`` the sample standard
    deviation of the logs (ddof = 1); ``dof = n - 1``; ``pi95`` the 95 % prediction interval
    for ONE NEW vehicle of the class, ``exp(mean_log +- t_{0.975, dof} * sd_log *
    sqrt(1 + 1/n))``. It is a prediction interval, not a confidence interval of the class
    mean, because a new vehicle scatters about the mean as the fitted ones do (the 1 under the
    root) besides the mean being known from n vehicles only (the 1/n)."""

    name: str
    unit: str
    values: dict[str, float]
    n: int
    centre: float
    sd_log: float
    dof: int
    pi95: tuple[float, float]

    @classmethod
    def from_values(cls, name: str, unit: str, values: Mapping[str, float]) -> Generalised:
        """The summary of ``values`` (by vehicle; at least two, each positive)."""
        # the Student t quantile: scipy.special.stdtrit is what scipy.stats.t.ppf evaluates,
        # without the second of scipy.stats's import
        from scipy.special import stdtrit

        for vid, v in values.items():
            if v is None or not (math.isfinite(v) and v > 0):
                raise ConfigError(f"vehicle {vid}", name, v, "a usable member needs a value > 0")
        if len(values) < 2:
            raise ConfigError(
                "--min-vehicles", name, len(values), "a spread needs at least two vehicles"
            )
        logs = np.log(np.array([float(v) for v in values.values()]))
        n = len(logs)
        mean, sd = float(logs.mean()), float(logs.std(ddof=1))
        half = float(stdtrit(n - 1, 0.975)) * sd * math.sqrt(1.0 + 1.0 / n)
        return cls(
            name=name,
            unit=unit,
            values={str(vid): float(v) for vid, v in values.items()},
            n=n,
            centre=math.exp(mean),
            sd_log=sd,
            dof=n - 1,
            pi95=(math.exp(mean - half), math.exp(mean + half)),
        )

    @property
    def scale(self) -> float:
        """The scale of the predictive t distribution of the log: sd_log * sqrt(1 + 1/n)."""
        return self.sd_log * math.sqrt(1.0 + 1.0 / self.n)

    def draw_log(self, rng: np.random.Generator, size: int) -> np.ndarray:
        """``size`` draws of the log for a new vehicle: log centre + scale * T_dof."""
        return math.log(self.centre) + self.scale * rng.standard_t(self.dof, size)

    def to_dict(self) -> dict[str, Any]:
        return {
            "unit": self.unit,
            "n": self.n,
            "centre": self.centre,
            "sd_log": self.sd_log,
            "dof": self.dof,
            "pi95": list(self.pi95),
            "values": dict(self.values),
        }


# ---------------------------------------------------------------------------------------------
# The reference model


@dataclass
class ReferenceModel:
    """The second-order model (eqs. 7-8) of an unmeasured vehicle of ``vehicle_class`` with
    mass ``mass_kg`` and surface ``surface_m2``, from its class's generalised parameters.

    ``basis``: the vehicles it rests on; ``excluded``: the class's vehicles left out by the
    caller; ``not_used``: the class's other vehicles and why they are not usable;
    ``generalised``: c_veh (eq. 24), delta (eq. 25), kappa_veh and k (present even when
    ``k_given`` is, then unused); ``synthetic``: the basis holds synthetic fits."""

    vehicle_class: str
    mass_kg: float
    surface_m2: float
    k_given: float | None
    basis: list[str]
    excluded: list[str]
    min_vehicles: int
    generalised: dict[str, Generalised]
    not_used: dict[str, str] = field(default_factory=dict)
    synthetic: bool = False

    @property
    def structure(self) -> str:
        """The grey-box structure: the paper's second-order model."""
        return STRUCTURE

    @property
    def model(self) -> str:
        return MODEL

    @property
    def k(self) -> float:
        """k used: the given one, else the class's centre (W/(m2 K))."""
        return self.k_given if self.k_given is not None else self.generalised["k"].centre

    @property
    def theta(self) -> dict[str, float]:
        """Point values from the centres: kA = k A, C = C_veh / delta (eq. 25),
        K_veh = kappa_veh A, C_veh = c_veh m (eq. 24)."""
        g = self.generalised
        C_veh = g["c_veh"].centre * self.mass_kg
        return {
            "kA": self.k * self.surface_m2,
            "C": C_veh / g["delta"].centre,
            "K_veh": g["kappa_veh"].centre * self.surface_m2,
            "C_veh": C_veh,
        }

    def prior_terms(self) -> list[LinearT]:
        """The class as a prior of a vehicle's second-order fit: each generalised parameter's
        predictive distribution for one new vehicle of the class (log centre + sd_log
        sqrt(1 + 1/n) T_{n-1}, as :meth:`draws` samples it) as a term on the fit's log
        parameters - c_veh: log C_veh - log m (eq. 24); delta: log C_veh - log C (eq. 25);
        kappa_veh: log K_veh - log A; k: log kA - log A (none when k is given). The four
        map (kA, C, K_veh, C_veh) one to one, so together they are the joint density of the
        vehicle's parameters that :meth:`draws` samples
        (:class:`railtherm.estimation.priors.LogPrior`)."""
        g = self.generalised
        log_m, log_A = math.log(self.mass_kg), math.log(self.surface_m2)
        combos = {
            "c_veh": ((("C_veh", 1.0),), -log_m),
            "delta": ((("C_veh", 1.0), ("C", -1.0)), 0.0),
            "kappa_veh": ((("K_veh", 1.0),), -log_A),
            "k": ((("kA", 1.0),), -log_A),
        }
        return [
            LinearT(
                name=f"class:{name}",
                weights=weights,
                offset=offset,
                centre_log=math.log(g[name].centre),
                scale=g[name].scale,
                dof=float(g[name].dof),
            )
            for name, (weights, offset) in combos.items()
            if not (name == "k" and self.k_given is not None)
        ]

    def _log_draws(self, n: int, seed: int) -> dict[str, np.ndarray]:
        """The logs of :meth:`draws` (sums of logs: no overflow however heavy the tails)."""
        if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
            raise ValueError(f"n must be a positive number of draws, got {n!r}")
        rng = np.random.default_rng(seed)
        g = self.generalised
        c_veh = g["c_veh"].draw_log(rng, n)
        delta = g["delta"].draw_log(rng, n)
        kappa = g["kappa_veh"].draw_log(rng, n)
        k = (
            np.full(n, math.log(self.k_given))
            if self.k_given is not None
            else g["k"].draw_log(rng, n)
        )
        log_m, log_A = math.log(self.mass_kg), math.log(self.surface_m2)
        return {
            "kA": k + log_A,
            "C": c_veh + log_m - delta,
            "K_veh": kappa + log_A,
            "C_veh": c_veh + log_m,
        }

    def draws(self, n: int, seed: int = 0) -> dict[str, np.ndarray]:
        """``n`` draws of kA, C, K_veh and C_veh for one new vehicle of the class: each
        generalised parameter drawn independently from its scaled-t predictive distribution
        (log centre + sd_log sqrt(1 + 1/n_class) T_{n_class - 1}), in the order c_veh, delta,
        kappa_veh, k (k fixed when given); then C_veh = c_veh m (eq. 24), C = C_veh / delta
        (eq. 25), K_veh = kappa_veh A, kA = k A. Deterministic:
        ``numpy.random.default_rng(seed)``. With 2 vehicles (t with 1 degree of freedom, a
        Cauchy) a draw may overflow to inf."""
        with np.errstate(over="ignore"):
            return {p: np.exp(v) for p, v in self._log_draws(n, seed).items()}

    @property
    def parameters(self) -> dict[str, dict[str, Any]]:
        """Each parameter's ``{value, ci95, unit}``: kA, C, K_veh and C_veh with the 2.5/97.5 %
        quantiles of :data:`PARAMETER_DRAWS` draws with the fixed seed
        :data:`PARAMETER_SEED` (taken on the log scale); c_veh, delta, kappa_veh and k with
        their analytic 95 % prediction intervals. A given k is taken as exact: its interval
        (and kA's) is the point."""
        theta = self.theta
        sample = self._log_draws(PARAMETER_DRAWS, PARAMETER_SEED)
        out: dict[str, dict[str, Any]] = {}
        for p in FIT_PARAMETERS:
            lo, hi = np.exp(np.quantile(sample[p], [0.025, 0.975]))
            out[p] = {"value": float(theta[p]), "ci95": [float(lo), float(hi)], "unit": UNITS[p]}
        if self.k_given is not None:  # exactly the point, whatever exp(log) rounds to
            out["kA"]["ci95"] = [out["kA"]["value"]] * 2
        for name, unit in GENERALISED.items():
            g = self.generalised[name]
            if name == "k" and self.k_given is not None:
                entry = {"value": self.k_given, "ci95": [self.k_given, self.k_given]}
                out[name] = {**entry, "unit": unit, "given": True}
            else:
                out[name] = {"value": g.centre, "ci95": list(g.pi95), "unit": unit}
        # the vehicles' rule applied to the class: an interval wider than a factor 1000 in
        # total is no estimate, nor a parameter of the dynamic part coupled to one
        judged = {
            p: {"identified": True} if e.get("given") else pem.identification(e["value"], e["ci95"])
            for p, e in out.items()
        }
        coupled = structures.named(STRUCTURE).coupled
        judged |= identifiability.coupled_identification(judged, coupled)
        for p, j in judged.items():
            out[p]["identified"] = bool(j["identified"])
            if not j["identified"]:
                out[p]["reason"] = str(j["reason"])
        return out

    @property
    def note(self) -> str:
        n = len(self.basis)
        k = (
            f"k = {self.k_given:g} W/(m2 K) was given and is taken as exact. "
            if self.k_given is not None
            else ""
        )
        synthetic = (
            "The basis fits come from synthetic data (virtual climatic wind tunnel), not "
            "measurements."
            if self.synthetic
            else ""
        )
        text = NOTE.format(
            n=n, dof=n - 1, draws=PARAMETER_DRAWS, seed=PARAMETER_SEED, k=k, synthetic=synthetic
        )
        return text.strip()

    def to_dict(self) -> dict[str, Any]:
        """The content of the reference-model file (plain floats, lists and strings)."""
        return {
            "kind": KIND,
            "model": MODEL,
            "structure": STRUCTURE,
            "class": self.vehicle_class,
            "mass_kg": float(self.mass_kg),
            "surface_m2": float(self.surface_m2),
            "k_given": None if self.k_given is None else float(self.k_given),
            "basis": list(self.basis),
            "excluded": list(self.excluded),
            "not_used": dict(self.not_used),
            "min_vehicles": int(self.min_vehicles),
            "synthetic": bool(self.synthetic),
            "generalised": {name: g.to_dict() for name, g in self.generalised.items()},
            "parameters": self.parameters,
            "intervals": {"draws": PARAMETER_DRAWS, "seed": PARAMETER_SEED},
            "note": self.note,
        }

    def to_yaml(self) -> str:
        """:meth:`to_dict` as YAML text (keys in order)."""
        return yaml.safe_dump(self.to_dict(), sort_keys=False)

    def write(self, path: str | os.PathLike[str]) -> None:
        """Write the reference-model file (YAML; read it with :func:`read_reference_model`)."""
        write_yaml(self.to_dict(), path)

    def summary(self) -> str:
        """A few lines for people: the class, the vehicles it rests on, each parameter with
        its 95 % prediction interval, and where k comes from."""
        what = (
            "every rail class pooled (a comparator, not a class)"
            if self.vehicle_class == POOLED
            else f"class {self.vehicle_class}"
        )
        lines = [
            f"class reference model (second order, eqs. 7-8): {what}, "
            f"m = {self.mass_kg:,.0f} kg, A = {self.surface_m2:g} m2",
            f"rests on {len(self.basis)} vehicles: {', '.join(self.basis)}"
            + (" (synthetic fits)" if self.synthetic else ""),
        ]
        if self.not_used:
            lines.append(
                "not used: " + ", ".join(f"{vid} ({why})" for vid, why in self.not_used.items())
            )
        if self.excluded:
            lines.append(f"excluded: {', '.join(self.excluded)}")
        params = self.parameters
        label = {
            "c_veh": "c_veh (eq. 24)",
            "delta": "delta (eq. 25)",
            "kappa_veh": "kappa_veh = K_veh/A",
            "k": "k",
        }
        for name in (*FIT_PARAMETERS, *GENERALISED):
            p = params[name]
            lo, hi = p["ci95"]
            unit = "" if p["unit"] == "1" else f" {p['unit']}"
            if not p.get("identified", True):  # no value: the class does not determine it
                lines.append(f"  {label.get(name, name):<20}   not identified ({p['reason']})")
                continue
            if p.get("given"):
                interval = " (given)"
            elif name == "kA" and self.k_given is not None:
                interval = " (k given)"
            else:
                interval = f" [{_number(lo)}, {_number(hi)}]"
            lines.append(f"  {label.get(name, name):<20} = {_number(p['value'])}{unit}{interval}")
        k = self.generalised["k"]
        lines.append(
            f"k given ({self.k_given:g} W/(m2 K)); the class's would be {k.centre:.3g}"
            if self.k_given is not None
            else f"k from class ({k.n} vehicles)"
        )
        lines.append(
            f"95 % prediction intervals for one new vehicle (t, {len(self.basis) - 1} dof; "
            f"kA, C, K_veh, C_veh from {PARAMETER_DRAWS} draws, seed {PARAMETER_SEED}, the "
            "generalised parameters taken as independent)"
        )
        return "\n".join(lines)


def _number(x: float) -> str:
    """Three significant digits, plain between 0.001 and 10^5, else in exponent form."""
    rounded = float(f"{x:.3g}")
    if not (math.isfinite(rounded) and 1e-3 <= abs(rounded) < 1e5):
        return f"{x:.3g}"
    places = 2 - math.floor(math.log10(abs(rounded)))
    return f"{rounded:,.{max(0, places)}f}"


# ---------------------------------------------------------------------------------------------
# Building one


def _positive(option: str, key: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.number):
        raise ConfigError(option, key, value, "expected a positive number")
    if not (math.isfinite(value) and value > 0):
        raise ConfigError(option, key, value, "expected a positive number")
    return float(value)


def _check_class(vehicle_class: Any) -> str:
    if vehicle_class in RAIL_CLASSES or vehicle_class == POOLED:
        return str(vehicle_class)
    if vehicle_class == "other":
        reason = (
            "class other holds objects that are not rail vehicles (test cells, buildings): "
            f"no class to generalise over; one of {', '.join(RAIL_CLASSES)} or {POOLED}"
        )
    else:
        reason = (
            f"unknown vehicle class; one of {', '.join(RAIL_CLASSES)} or {POOLED} "
            "(every rail class pooled)"
        )
    raise ConfigError("--class", "class", vehicle_class, reason)


def _refusal(
    vehicle_class: str,
    basis: Sequence[ClassMember],
    not_used: Mapping[str, str],
    excluded: Sequence[str],
    min_vehicles: int,
) -> str:
    """The one-line reason a class has too few usable vehicles."""
    what = (
        "the pooled rail classes have" if vehicle_class == POOLED else f"class {vehicle_class} has"
    )
    if not (basis or not_used or excluded):
        return f"{what} no vehicle among the study's fits; at least {min_vehicles} are needed"
    ids = f" ({', '.join(m.vehicle for m in basis)})" if basis else ""
    text = f"{what} {len(basis)} usable vehicle{'' if len(basis) == 1 else 's'}{ids}"
    if not_used:
        text += "; not used: " + ", ".join(f"{vid} ({why})" for vid, why in not_used.items())
    if excluded:
        text += f"; excluded: {', '.join(excluded)}"
    return (
        f"{text}; a class reference model needs at least {min_vehicles} "
        f"(min_vehicles; a spread needs two)"
    )


def build(
    members: Iterable[ClassMember],
    vehicle_class: str,
    mass_kg: float,
    surface_m2: float,
    k: float | None = None,
    min_vehicles: int = 2,
    exclude: Iterable[str] = (),
    exclude_in_class: bool = False,
) -> ReferenceModel:
    """The :class:`ReferenceModel` of a vehicle of ``vehicle_class`` (or ``"all"``: every rail
    class pooled, a comparator) with mass ``mass_kg`` and outer surface ``surface_m2``, from
    the class's usable ``members`` less ``exclude``. ``k`` (W/(m2 K)) replaces the class's k.
    With ``exclude_in_class`` (``railtherm reference --exclude``) an excluded vehicle of
    another class is refused: leaving it out would change nothing.

    Raises a one-line :class:`ConfigError` for an unknown class, a non-positive mass, surface
    or k, ``min_vehicles`` below 2, an excluded id that is no member, and a class with fewer
    than ``min_vehicles`` usable vehicles (the message names them, why the others were not
    used and the minimum)."""
    vehicle_class = _check_class(vehicle_class)
    mass = _positive("--mass-kg", "mass_kg", mass_kg)
    surface = _positive("--surface-m2", "surface_m2", surface_m2)
    k_given = None if k is None else _positive("--k", "k", k)
    if isinstance(min_vehicles, bool) or not isinstance(min_vehicles, int) or min_vehicles < 2:
        raise ConfigError(
            "--min-vehicles",
            "min_vehicles",
            min_vehicles,
            "must be an integer of at least 2: a spread needs two vehicles",
        )
    members = list(members)
    ids = [m.vehicle for m in members]
    twice = sorted({vid for vid in ids if ids.count(vid) > 1})
    if twice:
        raise ConfigError("--class", "members", twice, "vehicle given twice")
    exclude = list(exclude)
    for vid in exclude:
        if vid not in ids:
            raise ConfigError("--exclude", "exclude", vid, "no vehicle of that id in the study")
    in_class = [
        m
        for m in members
        if m.vehicle_class == vehicle_class
        or (vehicle_class == POOLED and m.vehicle_class in RAIL_CLASSES)
    ]
    excluded = [m.vehicle for m in in_class if m.vehicle in exclude]
    outside = [vid for vid in exclude if vid not in excluded]
    if outside and exclude_in_class:  # excluding it changes nothing: a misplaced id
        cls = next(m.vehicle_class for m in members if m.vehicle == outside[0])
        raise ConfigError(
            "--exclude",
            "exclude",
            outside[0],
            f"a vehicle of class {cls}, not of {vehicle_class}: leaving it out changes nothing",
        )
    candidates = [m for m in in_class if m.vehicle not in exclude]
    basis = [m for m in candidates if m.usable]
    not_used = {m.vehicle: m.why for m in candidates if not m.usable}
    if len(basis) < min_vehicles:
        raise ConfigError(
            "--class",
            "class",
            vehicle_class,
            _refusal(vehicle_class, basis, not_used, excluded, min_vehicles),
        )
    generalised = {
        name: Generalised.from_values(name, unit, {m.vehicle: getattr(m, name) for m in basis})
        for name, unit in GENERALISED.items()
    }
    return ReferenceModel(
        vehicle_class=vehicle_class,
        mass_kg=mass,
        surface_m2=surface,
        k_given=k_given,
        basis=[m.vehicle for m in basis],
        excluded=excluded,
        min_vehicles=min_vehicles,
        generalised=generalised,
        not_used=not_used,
        synthetic=any(m.synthetic for m in basis),
    )


# ---------------------------------------------------------------------------------------------
# Reading one back


def read_reference_model(path: str | os.PathLike[str]) -> ReferenceModel:
    """The :class:`ReferenceModel` of a file written by :meth:`ReferenceModel.write`.

    The generalised parameters are recomputed from their ``values`` (so the object is the one
    written); a file whose summaries disagree with its values (edited by hand) is refused
    with a one-line :class:`ConfigError`, as is one that does not match the schema
    ``railtherm/schemas/class_reference.schema.yaml``."""
    name = str(path)
    data = read_yaml(path, display=name)
    validate_schema(name, data, packaged_schema("class_reference"))
    generalised = {}
    for gname, unit in GENERALISED.items():
        entry = data["generalised"][gname]
        g = Generalised.from_values(gname, unit, entry["values"])
        for key in ("centre", "sd_log"):
            stored, computed = float(entry[key]), float(getattr(g, key))
            if not math.isclose(stored, computed, rel_tol=1e-9, abs_tol=1e-12):
                raise ConfigError(
                    name,
                    f"generalised.{gname}.{key}",
                    stored,
                    f"disagrees with its values ({computed:.6g}): edited by hand?",
                )
        if list(g.values) != list(data["basis"]):
            raise ConfigError(
                name, f"generalised.{gname}.values", list(g.values), "are not the basis vehicles"
            )
        generalised[gname] = g
    return ReferenceModel(
        vehicle_class=data["class"],
        mass_kg=float(data["mass_kg"]),
        surface_m2=float(data["surface_m2"]),
        k_given=None if data["k_given"] is None else float(data["k_given"]),
        basis=list(data["basis"]),
        excluded=list(data.get("excluded") or []),
        min_vehicles=int(data["min_vehicles"]),
        generalised=generalised,
        not_used=dict(data.get("not_used") or {}),
        synthetic=bool(data.get("synthetic", False)),
    )
