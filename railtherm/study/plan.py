"""The files of a study: which jobs its validated configs ask for, what each reads and writes.

A :class:`StudyPlan` answers, from a :class:`~railtherm.config.Study`, the study config and its
scenarios, every question the workflow's rules ask at parse time: a vehicle's tidy tables and
the raw files they are cut from, its fits (model keys), its figures, the study's tables and
figures, and the targets of the whole study. The paths are the output contract of the README
("Outputs"). Answers per vehicle are memoised: a fleet asks them thousands of times.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Callable, Hashable, Mapping, Sequence
from typing import Any

from railtherm.config import Study
from railtherm.data import ingest
from railtherm.errors import ConfigError
from railtherm.study import fitsettings

__all__ = ["STUDY_TABLES", "VEHICLE_ID", "StudyPlan", "figure_warnings"]

VEHICLE_ID = "[A-Za-z][A-Za-z0-9_-]*"  # a vehicle id, as the vehicle schema spells it
STUDY_TABLES = ("table1", "table2", "table3", "class_summary", "class_test")
FIGURE_FORMATS = ("png", "svg")


def figure_warnings(study: Study, config: Mapping[str, Any]) -> list[str]:
    """A sentence per study figure the config asks for but the study cannot draw: Figure 3's
    vehicle without model orders 1 and 2, a Figure 4 vehicle without order 2, and a name of
    no vehicle of the study where the config gives one other than the default (a misspelt
    id; the default's vehicles are often left out of a study on purpose). ``config``: the
    study config, defaults filled in or not (``railtherm validate`` and the workflow's parse
    warn alike)."""
    from railtherm.yamlio import packaged_schema

    defaults = {
        key: spec.get("default")
        for key, spec in packaged_schema("study")["properties"]["study"]["properties"].items()
    }
    section = config.get("study") or {}
    orders = {vid: set(v.model["orders"]) for vid, v in study.vehicles.items()}

    def unknown(key: str, vid: str, consequence: str) -> str:
        return (
            f"study.{key} names {vid!r}, no vehicle of the study ({', '.join(orders) or 'none'}): "
            f"{consequence}"
        )

    warnings = []
    fig3 = section.get("figure3", defaults["figure3"])
    if fig3 is not None and fig3 not in orders and fig3 != defaults["figure3"]:
        warnings.append(unknown("figure3", fig3, "no Figure 3"))
    elif fig3 in orders and not {1, 2} <= orders[fig3]:
        warnings.append(
            f"study.figure3 = {fig3!r}: its model.orders are {sorted(orders[fig3])}, and "
            "Figure 3 compares orders 1 and 2: no Figure 3 (add order 1 and 2 to the "
            "vehicle, or name another)"
        )
    fig4 = list(section.get("figure4", defaults["figure4"]) or [])
    for vid in fig4:
        if vid not in orders and fig4 != defaults["figure4"]:
            warnings.append(unknown("figure4", vid, "Figure 4 leaves it out"))
        elif vid in orders and 2 not in orders[vid]:
            warnings.append(
                f"study.figure4 names {vid!r}, whose model.orders {sorted(orders[vid])} have "
                "no second order: Figure 4 leaves it out"
            )
    return warnings


class StudyPlan:
    """The jobs' files of ``study`` under the study config ``config`` (defaults filled in),
    with the study's ``scenarios`` (:class:`railtherm.study.scenario.Scenario`)."""

    def __init__(self, study: Study, config: Mapping[str, Any], scenarios: Sequence = ()):
        self.study = study
        self.config = config
        self.scenarios = list(scenarios)
        self.vehicles = list(study.vehicles)
        campaign = study.campaign_data
        self.campaign_vehicles = list(campaign["vehicles"]) if campaign else []
        # the fits of the study's tables: fit_order<n>.yaml, or fit_order<n>_kalman.yaml
        # when the study chooses the Kalman-filter estimator (study.estimator)
        kalman = config["study"].get("estimator") == "kalman"
        self.table_key_suffix = fitsettings.KALMAN_SUFFIX if kalman else ""

    # -- one vehicle -----------------------------------------------------------------------

    def raw_files(self, vehicle: str) -> list[str]:
        """The raw files of one vehicle, as paths relative to the working directory."""
        return self.study.vehicles[vehicle].files()

    @functools.cache  # noqa: B019 (one plan per parse: the cache lives as long as the study)
    def tidy_tables(self, vehicle: str) -> tuple[str, ...]:
        """Tidy tables of a vehicle: its windows, plus the whole record for the k figure."""
        names = ingest.window_names(self.study.vehicles[vehicle].data)
        return tuple(names + ["record"] if "kvalue" in names else names)

    @functools.cache  # noqa: B019
    def table_sources(self, vehicle: str) -> dict[str, str | dict[str, str]]:
        """{tidy table: the raw file it is cut from, or with sources {source: file}}
        (railtherm.data.ingest.window_spec)."""
        v = self.study.vehicles[vehicle]
        return {w: v.record(ingest.window_spec(v.data, w)[0]) for w in self.tidy_tables(vehicle)}

    def clean_input(self, vehicle: str) -> list[str]:
        """The raw files a vehicle's tidy tables are cut from (each once)."""
        files = []
        for record in self.table_sources(vehicle).values():
            files += list(record.values()) if isinstance(record, dict) else [record]
        return list(dict.fromkeys(files))

    def has_kvalue(self, vehicle: str) -> bool:
        """Whether a vehicle has a steady window for the standardized static k test."""
        return "kvalue" in self.study.vehicles[vehicle].windows

    @functools.cache  # noqa: B019
    def kvalue_vehicles(self) -> tuple[str, ...]:
        """Vehicles with a steady window for the static k test."""
        return tuple(vid for vid in self.vehicles if self.has_kvalue(vid))

    @functools.cache  # noqa: B019
    def identification_windows(self, vehicle: str) -> tuple[str, ...]:
        """Names of a vehicle's identification windows, in config order."""
        return tuple(w["name"] for w in self.study.vehicles[vehicle].windows["identification"])

    @functools.cache  # noqa: B019
    def identification_tables(self, vehicle: str) -> tuple[str, ...]:
        """The tidy tables of a vehicle's identification windows (input of identify, sindy)."""
        windows = self.identification_windows(vehicle)
        return tuple(f"results/vehicles/{vehicle}/clean/{w}.csv" for w in windows)

    def kvalue_input(self, vehicle: str) -> str | list[str]:
        """The static k result a two-stage fit needs (none, [], without a k window)."""
        return f"results/vehicles/{vehicle}/kvalue.yaml" if self.has_kvalue(vehicle) else []

    def kvalue_window_input(self, vehicle: str) -> str | list[str]:
        """The tidy k window, for the storage correction of the static k (none without one)."""
        return f"results/vehicles/{vehicle}/clean/kvalue.csv" if self.has_kvalue(vehicle) else []

    @functools.cache  # noqa: B019
    def model_keys(self, vehicle: str) -> tuple[str, ...]:
        """The model keys of a vehicle's fits: order1, order2, then further structures, each
        per estimator (the key names the files: fit_<key>.yaml)."""
        return tuple(fitsettings.model_keys(self.study.vehicles[vehicle].data))

    def has_fit(self, vehicle: str, order: int) -> bool:
        """Whether a vehicle fits the paper's model of this order."""
        return order in self.study.vehicles[vehicle].model["orders"]

    def table_key(self, vehicle: str, order: int) -> str:
        """The model key of a vehicle's order-``order`` fit in the study's tables and figures:
        by the study's estimator (study.estimator) where the vehicle fits with it, else by the
        vehicle's own (a vehicle declaring model.estimator: kalman alone)."""
        key = f"order{order}{self.table_key_suffix}"
        if key in self.model_keys(vehicle):
            return key
        other = "" if self.table_key_suffix else fitsettings.KALMAN_SUFFIX
        return f"order{order}{other}"

    def table_series(self, vehicle: str | None, order: int) -> str:
        """The simulated series of the fit :meth:`table_key` names (a figure's input); any
        path when no vehicle is chosen (None: the figure is not made)."""
        key = self.table_key(vehicle, order) if vehicle else f"order{order}"
        return f"results/vehicles/{vehicle}/identify/{key}_series.csv"

    def figure_signature(self, vehicle: str) -> tuple[bool, tuple[str, ...]]:
        """What fixes the outputs of a vehicle's figure job: a k figure or not, its models."""
        return (self.has_kvalue(vehicle), self.model_keys(vehicle))

    def vehicle_figure_files(self, vehicle: str) -> list[str]:
        """Every figure the vehicle's figure job draws (the k figure, a figure per fit, the
        innovations of each Kalman-filter fit), as PNG and SVG."""
        has_k, keys = self.figure_signature(vehicle)
        stems = (["kvalue"] if has_k else []) + [f"fit_{key}" for key in keys]
        stems += [f"innovations_{key}" for key in keys if key.endswith(fitsettings.KALMAN_SUFFIX)]
        return [f"results/vehicles/{vehicle}/{s}.{ext}" for s in stems for ext in FIGURE_FORMATS]

    # -- the study -------------------------------------------------------------------------

    @functools.cache  # noqa: B019
    def fit_targets(self) -> tuple[tuple[str, int], ...]:
        """(vehicle, order) of every configured fit of the paper's orders, in config order."""
        vehicles = self.study.vehicles
        return tuple((vid, n) for vid in self.vehicles for n in vehicles[vid].model["orders"])

    def model_targets(self) -> list[tuple[str, str]]:
        """(vehicle, model key) of every configured fit, in config order."""
        return [(vid, key) for vid in self.vehicles for key in self.model_keys(vid)]

    @functools.cache  # noqa: B019
    def second_order_vehicles(self) -> tuple[str, ...]:
        """Vehicles with a second-order fit: the rows of Tables 2 and 3."""
        return tuple(vid for vid, n in self.fit_targets() if n == 2)

    def without_second_order(self) -> dict[str, list[int]]:
        """{vehicle: its model orders} of the vehicles the paper's tables leave out (no
        second-order fit), in study order: the tables name them."""
        second = set(self.second_order_vehicles())
        vehicles = self.study.vehicles
        return {
            vid: sorted(vehicles[vid].model["orders"]) for vid in self.vehicles if vid not in second
        }

    def energy_fits(self) -> tuple[tuple[str, int], ...]:
        """(vehicle, order) of the fits the annual energy chooses from, per vehicle the
        second order first: the study uses a vehicle's second-order fit where acceptable,
        else its first-order one."""
        return tuple(sorted(self.fit_targets(), key=lambda t: (self.vehicles.index(t[0]), -t[1])))

    def energy_vehicles(self) -> tuple[str, ...]:
        """The vehicles of the annual energy (rule energy, one job each): those with a fit,
        in study order."""
        return tuple(dict.fromkeys(vid for vid, _ in self.energy_fits()))

    def figure3_vehicle(self) -> str | None:
        """The vehicle of Figure 3 when it is in the study with first- and second-order fits."""
        vid = self.config["study"]["figure3"]
        return vid if vid and {(vid, 1), (vid, 2)} <= set(self.fit_targets()) else None

    def figure4_vehicles(self) -> list[str]:
        """The configured Figure 4 vehicles that have a second-order fit."""
        chosen = self.config["study"]["figure4"]
        return [vid for vid in chosen if vid in self.second_order_vehicles()]

    def paper_tables(self) -> bool:
        """Whether the study writes Tables 1-3 and Figure 5 (second-order fits, and asked)."""
        return bool(self.second_order_vehicles() and self.config["study"]["paper_tables"])

    @functools.cache  # noqa: B019
    def sindy_vehicles(self) -> tuple[str, ...]:
        """Vehicles the SINDy cross-check runs on: with it enabled, those with surface sensors."""
        if not self.config["sindy"]["enabled"]:
            return ()
        vehicles = self.study.vehicles
        return tuple(vid for vid in self.vehicles if vehicles[vid].channels.get("surface"))

    def sindy_batches(self) -> list[tuple[str, list[str]]]:
        """[(name of the rule, vehicles)]: the SINDy vehicles in study order,
        sindy.vehicles_per_job to a job; rules ``sindy``, ``sindy_2``, ..."""
        vids = list(self.sindy_vehicles())
        size = self.config["sindy"]["vehicles_per_job"]
        batches = [vids[i : i + size] for i in range(0, len(vids), size)]
        return [("sindy" if i == 0 else f"sindy_{i + 1}", b) for i, b in enumerate(batches)]

    def study_figures(self) -> list[str]:
        """Stems of the study figures this config can draw (results/figures/<stem>.png)."""
        stems = ["figure3"] if self.figure3_vehicle() else []
        stems += ["figure4"] if self.figure4_vehicles() else []
        stems += ["figure5a", "figure5b"] if self.paper_tables() else []
        return stems

    def scenario_files(self) -> list[str]:
        """Every scenario file and every profile file it reads (inputs of the predictions)."""
        return list(dict.fromkeys(f for sc in self.scenarios for f in (sc.file, *sc.files)))

    def figure_scenario(self):
        """The scenario of the scenario figure and of the leave-one-out heat-up comparison:
        scenarios.figure, else the first scenario with a heat-up threshold (None: none). A
        name of no scenario is a :class:`ConfigError`."""
        name = self.config["scenarios"]["figure"]
        if name is None:
            return next((sc for sc in self.scenarios if sc.heat_up_to_C is not None), None)
        chosen = [sc for sc in self.scenarios if sc.name == name]
        if not chosen:
            names = [sc.name for sc in self.scenarios]
            raise ConfigError(
                "config/config.yaml", "scenarios.figure", name, f"no such scenario; have {names}"
            )
        return chosen[0]

    def prediction_outputs(self) -> list[str]:
        """Targets of the rules simulate and reference_validation."""
        if not self.scenarios or not self.second_order_vehicles():
            return []
        targets = [f"results/tables/scenarios.{ext}" for ext in ("csv", "md")]
        if self.figure_scenario() is not None:
            targets += [f"results/figures/scenarios.{ext}" for ext in FIGURE_FORMATS]
            if self.config["reference_model"]["validation"] and self.paper_tables():
                targets += [f"results/tables/reference_validation.{e}" for e in ("csv", "md")]
                targets += [f"results/figures/reference_validation.{e}" for e in FIGURE_FORMATS]
        return targets

    def design_outputs(self) -> list[str]:
        """Targets of the rule design: with ``design.enabled``, second-order fits and the
        study's Table 2 (the class models)."""
        if not (
            self.config["design"]["enabled"]
            and self.second_order_vehicles()
            and self.paper_tables()
        ):
            return []
        targets = [f"results/tables/design.{ext}" for ext in ("csv", "md")]
        return targets + [f"results/figures/design.{ext}" for ext in FIGURE_FORMATS]

    def energy_outputs(self) -> list[str]:
        """Targets of the rule energy_table: with ``energy.enabled``, weather, a profile
        and fits (the settings are checked by load_study,
        :func:`railtherm.config.check_study_plans`)."""
        cfg = self.config["energy"]
        profiled = cfg["profile"] or cfg.get("profiles")
        if not (cfg["enabled"] and cfg["weather"] and profiled and self.energy_vehicles()):
            return []
        targets = [f"results/tables/annual_energy.{ext}" for ext in ("csv", "md")]
        return targets + [f"results/figures/annual_energy.{ext}" for ext in FIGURE_FORMATS]

    def posterior_targets(self) -> list[tuple[str, str]]:
        """(vehicle, model key) of every Table 1 and Table 2 fit sampled by NUTS, with
        ``inference: posterior`` (rule posterior)."""
        if self.config.get("inference", "ml") != "posterior":
            return []
        return [(vid, self.table_key(vid, n)) for vid, n in self.fit_targets()]

    def class_prior_input(self, vehicle: str, model: str) -> list[str]:
        """What rule posterior reads for a class prior: the study's Table 2, for a
        second-order model with ``posterior.prior: class`` (none otherwise)."""
        second = fitsettings.split_key(model)[0] == "order2"
        wanted = self.config["posterior"]["prior"] == "class" and second
        return ["results/tables/table2.csv"] if wanted and self.paper_tables() else []

    def posteriors_of(self, fit_files: Sequence[str]) -> list[str]:
        """With ``inference: posterior``, the posterior files of ``fit_files`` (the
        predictions then draw from them: rules simulate and energy); none otherwise."""
        if self.config.get("inference", "ml") != "posterior":
            return []
        return [f.removesuffix(".yaml") + ".posterior.nc" for f in fit_files]

    def posterior_outputs(self) -> list[str]:
        """Targets of the rules posterior and pooling."""
        targets = [
            f"results/vehicles/{vid}/{name}"
            for vid, key in self.posterior_targets()
            for name in (
                f"fit_{key}.posterior.nc",
                f"fit_{key}.posterior.png",
                f"posterior_{key}.yaml",
            )
        ]
        if targets:
            targets += [f"results/tables/pooling.{ext}" for ext in ("csv", "md")]
        return targets

    def all_outputs(self) -> list[str]:
        """Every target of the study (rule all), in a stable order."""
        cfg = self.config
        vehicles = self.vehicles
        targets = [path for vid in vehicles for path in self.raw_files(vid)]
        targets += [
            f"results/vehicles/{vid}/clean/{t}.csv"
            for vid in vehicles
            for t in self.tidy_tables(vid)
        ]
        targets += [f"results/vehicles/{vid}/kvalue.yaml" for vid in self.kvalue_vehicles()]
        targets += ["results/tables/kvalue.csv"] if self.kvalue_vehicles() else []
        targets += [f"results/vehicles/{vid}/fit_{key}.yaml" for vid, key in self.model_targets()]
        targets.append("results/tables/identification.csv")
        if cfg["study"]["figures"]:
            targets += [path for vid in vehicles for path in self.vehicle_figure_files(vid)]
        if cfg["study"]["models_table"]:
            targets += [f"results/tables/models.{ext}" for ext in ("csv", "md")]
        if cfg["study"]["references"]:
            targets += [f"results/tables/reference.{ext}" for ext in ("csv", "md")]
        if self.paper_tables():
            targets += [
                f"results/tables/{name}.{ext}"
                for name in STUDY_TABLES
                for ext in ("csv", "md", "tex")
            ]
        targets += [
            f"results/figures/{stem}.{ext}"
            for stem in self.study_figures()
            for ext in FIGURE_FORMATS
        ]
        if self.sindy_vehicles():
            targets += [f"results/vehicles/{vid}/sindy.yaml" for vid in self.sindy_vehicles()]
            targets += [f"results/tables/sindy.{ext}" for ext in ("csv", "md")]
            targets += [f"results/figures/sindy.{ext}" for ext in FIGURE_FORMATS]
        if cfg["audit"]["published"]:
            targets += ["results/audit/findings.csv", "results/audit/audit.md"]
        targets += self.prediction_outputs()
        targets += self.design_outputs()
        targets += self.energy_outputs()
        targets += self.posterior_outputs()
        if self.study.campaign_data:
            targets += [
                "results/campaign/ground_truth.csv",
                "results/campaign/ground_truth_sources.csv",
            ]
        return targets

    # -- rules whose outputs differ between vehicles ----------------------------------------

    def rule_groups(
        self, name: str, signature: Callable[[str], Hashable]
    ) -> list[tuple[str, Any, str]]:
        """The study's vehicles grouped by ``signature(vehicle)``, which fixes the outputs of a
        per-vehicle rule (a rule's outputs are fixed), in order of first appearance, as
        [(name of the group's rule, signature, wildcard constraint of its vehicles)]. The
        first group's rule is ``name``, further ones ``name_2``, ``name_3``, ...; a fleet of
        alike vehicles has one."""
        groups: dict[Hashable, list[str]] = {}
        for vid in self.vehicles:
            groups.setdefault(signature(vid), []).append(vid)
        listed = list(groups.values())
        return [
            (name if i == 0 else f"{name}_{i + 1}", sig, group_constraint(listed, vids))
            for i, (sig, vids) in enumerate(groups.items())
        ]


def group_constraint(groups: Sequence[list[str]], vehicles: list[str]) -> str:
    """The wildcard constraint matching ``vehicles``, one of ``groups``: any vehicle id when
    there is one group; else for the largest group any id but the others' (each followed by
    no id character), for the others their own ids. A fleet's constraints stay short: a
    regular expression of a thousand names takes long to compile."""
    if len(groups) == 1:
        return VEHICLE_ID
    largest = max(groups, key=len)
    if vehicles is largest:
        others = [vid for group in groups if group is not largest for vid in group]
        alternatives = "|".join(re.escape(vid) for vid in others)
        return f"(?!(?:{alternatives})(?![A-Za-z0-9_-])){VEHICLE_ID}"
    return "|".join(re.escape(vid) for vid in vehicles)
