"""The typed records of a fit: what ``fit_<model>.yaml`` holds, as :class:`FitRecord` with
one :class:`ParameterEstimate` per parameter and per total, and what the identify stage hands
the verdict (``identify/<model>.yaml``), as :class:`EstimateRecord`.

These files are read and written by :mod:`railtherm.io` only (:func:`railtherm.io.read_fit`,
:func:`railtherm.io.write_fit`, :func:`railtherm.io.read_estimate`,
:func:`railtherm.io.write_estimate`); every layer above takes and returns these records,
never a dict of a fit. A record keeps the file's content as written (``to_dict``), so a fit
read and written again is the same file, and gives it typed names: the combined 95 %
interval a reader sees (``ci95_combined``, the file's ``ci95``: statistical and systematic)
apart from the fit's statistical one (``ci95_statistical``), and whether the data determine
the value (:class:`~railtherm.estimation.estimate.Identification`).
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Self

import numpy as np

from railtherm.estimation.common import identification
from railtherm.estimation.estimate import Identification

__all__ = ["EstimateRecord", "FitRecord", "JudgedEstimate", "ParameterEstimate"]


def _interval(value: Any) -> tuple[float, float] | None:
    return None if value is None else (float(value[0]), float(value[1]))


def _number(value: Any) -> float | None:
    return None if value is None else float(value)


@dataclass(frozen=True)
class ParameterEstimate:
    """One parameter of a fit, or one total of its parameters (C_total = C + C_veh), in SI
    units.

    ``estimated``: True (by the fit), False (held fixed, e.g. kA from the static test, eq. 10)
    or "derived" (kA of losses in series, from the structure's steady state).
    ``ci95_combined``: the 95 % interval of the statistical and the systematic uncertainty
    together (the file's ``ci95``), None for a fixed parameter; ``ci95_statistical`` and
    ``sd_log`` the fit's statistical interval and log standard deviation alone;
    ``sd_log_total`` the combined one. ``identification``: whether the data determine the
    value, and where they do not, the limit they give. A total names its ``parts`` and those
    held at a bound of the search (``held_at_bound``: the interval is conditional on them).
    ``coupled_to``: the parameters whose not being identified makes this one not an
    estimate either."""

    name: str
    value: float
    estimated: bool | str = True
    ci95_combined: tuple[float, float] | None = None
    ci95_statistical: tuple[float, float] | None = None
    sd_log: float | None = None
    sd_log_total: float | None = None
    identification: Identification = field(default_factory=lambda: Identification(True))
    at_bound: str | None = None
    coupled_to: tuple[str, ...] = ()
    derived_from: str | None = None
    parts: tuple[str, ...] = ()
    held_at_bound: tuple[str, ...] = ()
    note: str = ""

    @classmethod
    def from_entry(cls, name: str, entry: Mapping[str, Any]) -> ParameterEstimate:
        """The estimate of an entry ``parameters.<name>`` (or ``totals.<name>``) of a fit
        file. An entry written without its identification is judged from its interval
        (:func:`railtherm.estimation.common.identification`); a fixed one is identified.

        Parameters
        ----------
        name : str
            The parameter's (or total's) name.
        entry : mapping
            Its entry in the fit file.

        Returns
        -------
        ParameterEstimate
        """
        ci = _interval(entry.get("ci95"))
        if "identified" in entry:
            ident = Identification(
                bool(entry["identified"]),
                entry.get("limit"),
                _number(entry.get("limit_value")),
                entry.get("at_bound"),
                entry.get("reason"),
            )
        elif ci is None:
            ident = Identification(True)
        else:
            ident = identification(float(entry["value"]), ci)
        return cls(
            name=name,
            value=float(entry["value"]),
            estimated=entry.get("estimated", True),
            ci95_combined=ci,
            ci95_statistical=_interval(entry.get("ci95_statistical")),
            sd_log=_number(entry.get("sd_log")),
            sd_log_total=_number(entry.get("sd_log_total")),
            identification=ident,
            at_bound=entry.get("at_bound"),
            coupled_to=tuple(entry.get("coupled_to") or ()),
            derived_from=entry.get("derived_from"),
            parts=tuple(entry.get("parts") or ()),
            held_at_bound=tuple(entry.get("held_at_bound") or ()),
            note=str(entry.get("note") or ""),
        )

    @property
    def identified(self) -> bool:
        return bool(self.identification.identified)

    @property
    def fixed(self) -> bool:
        """Held at a value from outside the fit (e.g. kA from the static test)."""
        return self.estimated is False

    def __str__(self) -> str:
        ident = self.identification
        if not ident.identified:
            if ident.limit in ("upper", "lower") and ident.limit_value is not None:
                side = {"upper": "at most", "lower": "at least"}[ident.limit]
                return f"{self.name}: not identified ({side} {ident.limit_value:.3g})"
            return f"{self.name}: not identified ({ident.reason or 'no limit the data give'})"
        if self.ci95_combined is None:
            return f"{self.name} = {self.value:.4g} (fixed)"
        lo, hi = self.ci95_combined
        return f"{self.name} = {self.value:.4g} [{lo:.4g}, {hi:.4g}]"


def _section(content: Mapping[str, Any], key: str) -> Mapping[str, Any]:
    return MappingProxyType(dict(content.get(key) or {}))


@dataclass(frozen=True, eq=False)
class _Content:
    """A file's content as written (read-only), made from a mapping by a deep copy."""

    content: Mapping[str, Any] = field(repr=False)

    @classmethod
    def from_dict(cls, content: Mapping[str, Any]) -> Self:
        """The record of a file's content (a deep copy: the record does not change with the
        mapping it was made from).

        Parameters
        ----------
        content : mapping
            The file's content.

        Returns
        -------
        the record
        """
        return cls(MappingProxyType(copy.deepcopy(dict(content))))

    def to_dict(self) -> dict[str, Any]:
        """The file's content, as written (a deep copy).

        Returns
        -------
        dict
        """
        return copy.deepcopy(dict(self.content))

    def section(self, key: str) -> Mapping[str, Any]:
        """A section of the file as a read-only mapping (empty where it is absent).

        Parameters
        ----------
        key : str
            The section's key (``measures``, ``systematic``, ``innovations``, ...).

        Returns
        -------
        mapping
        """
        return _section(self.content, key)

    def has(self, key: str) -> bool:
        """Whether the file holds ``key`` with a value.

        Parameters
        ----------
        key : str

        Returns
        -------
        bool
        """
        return self.content.get(key) is not None


@dataclass(frozen=True, eq=False)
class _Record(_Content):
    """What the identify stage's estimate and the checked fit share: the content of the file
    as written (read-only), and typed names for the vehicle, the model, how k was obtained
    and the records fitted."""

    # --- who and what
    @property
    def vehicle(self) -> str:
        return str(self.content["vehicle"])

    @property
    def synthetic(self) -> bool:
        return bool(self.content.get("synthetic", False))

    @property
    def order(self) -> int:
        return int(self.content["order"])

    @property
    def model(self) -> str:
        return str(self.content["model"])

    @property
    def estimator(self) -> str:
        return str(self.content.get("estimator", "output_error"))

    @property
    def structure_name(self) -> str:
        """The structure's name (``second_order``, or with irradiance inputs
        ``second_order+I_sol``); empty for a file that does not say."""
        return str(self.content.get("structure") or "")

    @property
    def input_hold(self) -> str:
        return str(self.content.get("input_hold", "zero_order"))

    # --- the k stage
    @property
    def k_source(self) -> str:
        return str(self.content.get("k_source", ""))

    @property
    def kA_fixed(self) -> float | None:
        return _number(self.content.get("kA_fixed"))

    @property
    def k_eq10(self) -> float | None:
        return _number(self.content.get("k_eq10"))

    @property
    def u_k_eq10(self) -> float | None:
        return _number(self.content.get("u_k_eq10"))

    @property
    def k_corrected(self) -> float | None:
        return _number(self.content.get("k_corrected"))

    @property
    def u_k_corrected(self) -> float | None:
        return _number(self.content.get("u_k_corrected"))

    @property
    def notes(self) -> tuple[str, ...]:
        return tuple(self.content.get("notes") or ())

    @property
    def outputs(self) -> tuple[str, ...]:
        return tuple(self.content.get("outputs") or ())

    @property
    def windows(self) -> tuple[str, ...]:
        return tuple(self.content.get("windows") or ())


class _Estimates:
    """The estimates a fit gives, read from its content: each parameter and total as a
    :class:`ParameterEstimate`, the values (``theta``), the ``free`` log parameters with
    their statistical ``correlation``, and the estimator's ``flags``."""

    content: Mapping[str, Any]

    # --- the estimates
    @property
    def parameters(self) -> dict[str, ParameterEstimate]:
        """Every parameter of the structure (and a derived kA), by name, in the file's order."""
        return {
            p: ParameterEstimate.from_entry(p, e)
            for p, e in (self.content.get("parameters") or {}).items()
        }

    @property
    def totals(self) -> dict[str, ParameterEstimate]:
        """The sums the data determine however the capacity splits (C_total = C + C_veh), as
        written."""
        return {
            p: ParameterEstimate.from_entry(p, e)
            for p, e in (self.content.get("totals") or {}).items()
        }

    @property
    def theta(self) -> dict[str, float]:
        """Every parameter's value by name (identified or not: the model as fitted)."""
        return {p: float(e["value"]) for p, e in (self.content.get("parameters") or {}).items()}

    @property
    def free(self) -> tuple[str, ...]:
        return tuple(self.content.get("free") or ())

    @property
    def correlation(self) -> np.ndarray:
        """The statistical correlation of the free log parameters (order of :attr:`free`)."""
        corr = self.content.get("correlation")
        n = len(self.free)
        return np.asarray(corr, dtype=float) if corr is not None else np.eye(n)

    @property
    def flags(self) -> tuple[Mapping[str, Any], ...]:
        return tuple(MappingProxyType(dict(f)) for f in self.content.get("flags") or ())


@dataclass(frozen=True, eq=False)
class FitRecord(_Record, _Estimates):
    """A checked fit of one grey-box model to one vehicle: the content of
    ``fit_<model>.yaml`` (the workflow's rule ``check``), typed.

    The vehicle, the model key and its ``estimator`` and ``structure``; how k was obtained
    (``k_source``, ``kA_fixed`` and the static test's ``k_eq10`` / ``k_corrected`` with their
    standard uncertainties); the ``verdict`` with its ``reasons`` and ``notes``; each
    parameter and total as a :class:`ParameterEstimate`; the statistical ``correlation`` of the
    ``free`` log parameters; R^2 of eq. 21 (``R2``) and the NRMSE fit. The sections a reader
    rarely needs whole (``measures``, ``systematic``, ``cross_validation``, ``innovations``,
    ``storage_correction``, ...) are read-only mappings of the file's text
    (:meth:`section`)."""

    # --- the verdict
    @property
    def verdict(self) -> str:
        return str(self.content["verdict"])

    @property
    def reasons(self) -> tuple[str, ...]:
        return tuple(self.content.get("reasons") or ())

    @property
    def judged_by(self) -> str:
        """The criteria that judged the fit, as the tables print them."""
        return str(self.content.get("judged_by", ""))

    @property
    def criteria(self) -> tuple[Mapping[str, Any], ...]:
        return tuple(MappingProxyType(dict(c)) for c in self.content.get("criteria") or ())

    # --- the fit measures
    @property
    def R2(self) -> float:
        """R^2 of the simulated T over every window (eq. 21)."""
        return float(self.content["R2"])

    @property
    def nrmse_fit(self) -> float | None:
        return _number(self.content.get("nrmse_fit"))

    @property
    def loglik(self) -> float | None:
        """The Kalman filter's log-likelihood (None for an output-error fit)."""
        return _number(self.content.get("loglik"))

    @property
    def n_params(self) -> int | None:
        """The Kalman fit's count of estimated quantities (None for an output-error fit)."""
        n = self.content.get("n_params")
        return None if n is None else int(n)

    @property
    def n_obs(self) -> int | None:
        """The Kalman fit's count of scalar measurements (None for an output-error fit)."""
        n = self.content.get("n_obs")
        return None if n is None else int(n)


@dataclass(frozen=True, eq=False)
class JudgedEstimate(_Content, _Estimates):
    """The estimator's result as the identify stage judges it (an estimate file's ``fit``
    section, :attr:`EstimateRecord.fit`): each parameter with its combined (statistical and
    systematic) 95 % interval and whether the data determine it, a kA derived from the
    structure's steady state where it has no parameter kA, the totals (C_total = C + C_veh),
    the ``free`` log parameters with their ``correlation``, and the estimator's ``flags``."""


@dataclass(frozen=True, eq=False)
class EstimateRecord(_Record):
    """The identify stage's estimate of one model of one vehicle, before its verdict: the
    content of ``identify/<model>.yaml``, typed (the rule ``check`` judges it into a
    :class:`FitRecord`).

    Besides what every record gives: the vehicle's surface ``A``, ``mass_kg`` and
    ``volume_m3`` (None where the config gives none); the estimator's result with its
    judged parameters (:meth:`section` ``"fit"``, :attr:`parameters`); the systematic budget
    (``"systematic"``), the cross-validation, the unit checks and, for a Kalman fit, the
    whiteness tests of its innovations (``"innovations"``, and ``innovations_of`` where they
    are another fit's than the one reported); ``method_notes`` and the ``notes`` the k stage
    left."""

    @property
    def A(self) -> float | None:
        """The outer surface (m^2); None for an object without one."""
        return _number(self.content.get("A"))

    @property
    def mass_kg(self) -> float | None:
        return _number(self.content.get("mass_kg"))

    @property
    def volume_m3(self) -> float | None:
        return _number(self.content.get("volume_m3"))

    @property
    def fit(self) -> JudgedEstimate:
        """The estimator's result, judged (the ``fit`` section)."""
        return JudgedEstimate(self.section("fit"))

    @property
    def parameters(self) -> dict[str, ParameterEstimate]:
        """Every parameter of the estimate, judged (the ``fit`` section's ``parameters``)."""
        return self.fit.parameters

    @property
    def method_notes(self) -> tuple[str, ...]:
        return tuple(self.content.get("method_notes") or ())

    @property
    def unit_checks(self) -> tuple[str, ...]:
        return tuple(self.content.get("unit_checks") or ())

    @property
    def cross_validation(self) -> tuple[Mapping[str, Any], ...]:
        return tuple(self.content.get("cross_validation") or ())

    @property
    def innovations_of(self) -> str | None:
        """Whose innovations the whiteness tests judged where not the reported fit's."""
        of = self.content.get("innovations_of")
        return None if of is None else str(of)
