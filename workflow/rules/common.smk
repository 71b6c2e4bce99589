# Shared set-up: load and validate every vehicle before any job starts, and helpers for rules.
import functools
import hashlib
import os
import re
from pathlib import Path

from snakemake.exceptions import WorkflowError

import railtherm
from railtherm import identify as rt_identify
from railtherm import reference as rt_reference
from railtherm import ingest, synth
from railtherm.config import load_study
from railtherm.datacheck import check_study_values
from railtherm.errors import RailthermError
from railtherm.rawfile import DigestCache
from railtherm.scenario import load_scenario

RAILTHERM_DIR = Path(railtherm.__file__).parent
# where a conda job's post-deploy script finds the repository to install railtherm from
os.environ.setdefault("RAILTHERM_REPO", str(Path(workflow.basedir).resolve()))

try:
    STUDY = load_study(config, workdir=".")
except RailthermError as err:
    raise WorkflowError(f"invalid configuration: {err}") from None

CAMPAIGN = STUDY.campaign_data
VEHICLES = list(STUDY.vehicles)
CAMPAIGN_VEHICLES = list(CAMPAIGN["vehicles"]) if CAMPAIGN else []
CAMPAIGN_ROOT = "resources/campaign"


wildcard_constraints:
    vehicle="[A-Za-z][A-Za-z0-9_-]*",


_IMPORT = re.compile(
    r"^\s*(?:from railtherm((?:\.\w+)*) import ([\w, ]+)|import railtherm((?:\.\w+)+)"
    r"|from (\.+\w*) import)",
    re.M,
)


def _source_files(dotted):
    """Source files (relative to the package) of a railtherm module or subpackage."""
    path = RAILTHERM_DIR.joinpath(*dotted.split("."))
    if path.with_suffix(".py").is_file():
        return [path.with_suffix(".py").relative_to(RAILTHERM_DIR).as_posix()]
    if path.is_dir():
        return sorted(p.relative_to(RAILTHERM_DIR).as_posix() for p in path.rglob("*.py"))
    return []


@functools.cache
def railtherm_modules(*modules):
    """The railtherm source files ``modules`` (``ingest.py``; a subpackage ``synth.py`` stands
    for every file of ``synth/``) and every railtherm module they import, in turn."""
    seen, todo = [], [f for m in modules for f in _source_files(m.removesuffix(".py"))]
    while todo:
        name = todo.pop(0)
        if name in seen:
            continue
        seen.append(name)
        package = ".".join(Path(name).parent.parts)
        for sub, names, plain, relative in _IMPORT.findall((RAILTHERM_DIR / name).read_text()):
            if relative:  # from .x import ...: a sibling inside a subpackage, already included
                todo += _source_files(package) if package else []
            elif sub or plain:
                todo += _source_files((sub or plain).lstrip("."))
            else:
                todo += [
                    f for n in names.split(",") for f in _source_files(n.split(" as ")[0].strip())
                ]
    return sorted(seen)


def code_digest(*modules):
    """Digest of railtherm source files and of what they import from railtherm, passed as a
    param so that code edits rerun the jobs that run that code."""
    h = hashlib.sha256()
    for name in railtherm_modules(*modules):
        h.update(name.encode() + (RAILTHERM_DIR / name).read_bytes())
    return h.hexdigest()[:16]


def campaign_file_regex(field):
    """Wildcard constraint matching only what the campaign declares (never a real-data file)."""
    if not CAMPAIGN:
        return "(?!x)x"
    if field == "vehicle":
        names = CAMPAIGN_VEHICLES
    else:
        names = [
            name
            for vid in CAMPAIGN_VEHICLES
            for name in synth.raw_file_names(synth.vehicle_spec(CAMPAIGN, vid))
        ]
    return "|".join(re.escape(name) for name in sorted(set(names)))


def raw_files(vehicle):
    """The raw files of one vehicle, as paths relative to the working directory."""
    return list(STUDY.vehicles[vehicle].raw_files.values())


def tidy_tables(vehicle):
    """Tidy tables of a vehicle: its windows, plus the whole record for the k-window figure."""
    names = ingest.window_names(STUDY.vehicles[vehicle].data)
    return names + ["record"] if "kvalue" in names else names


def window_raw_file(wildcards):
    """The raw file a tidy table is cut from (see railtherm.ingest.window_spec)."""
    vehicle = STUDY.vehicles[wildcards.vehicle]
    key, _, _ = ingest.window_spec(vehicle.data, wildcards.window)
    return vehicle.raw_files[key]


RAW_DIGESTS = DigestCache(".snakemake/railtherm/raw-digests.json")

# every value of the study's own raw files, read as the jobs clean and kvalue will, so that a
# bad value stops the run before any job (cached by content: a parse again re-reads nothing)
try:
    check_study_values(
        STUDY,
        RAW_DIGESTS,
        ".snakemake/railtherm/value-checks.json",
        skip=lambda path: Path(path).is_relative_to(CAMPAIGN_ROOT),
    )
except RailthermError as err:
    raise WorkflowError(f"invalid raw data: {err}") from None


def raw_digest(wildcards):
    """Content digest of a window's raw file, passed as a param so that new content reruns
    its jobs whatever the file's mtime. Files the workflow writes itself (the virtual
    campaign's) follow their own rule and are not hashed."""
    path = window_raw_file(wildcards)
    if Path(path).is_relative_to(CAMPAIGN_ROOT):
        return "written by rule synthesize"
    return RAW_DIGESTS.digest(path)


def kvalue_vehicles():
    """Vehicles with a steady window for the standardized static k test."""
    return [vid for vid in VEHICLES if "kvalue" in STUDY.vehicles[vid].windows]


def identification_windows(vehicle):
    """Names of a vehicle's identification windows, in config order."""
    return [w["name"] for w in STUDY.vehicles[vehicle].windows["identification"]]


def kvalue_input(vehicle):
    """The static k result a two-stage fit needs (none without a k window)."""
    if vehicle in kvalue_vehicles():
        return f"results/vehicles/{vehicle}/kvalue.yaml"
    return []


# the fits of the study's tables: fit_order<n>.yaml, or fit_order<n>_kalman.yaml when the study
# chooses the Kalman-filter estimator (study.estimator)
TABLE_KEY_SUFFIX = (
    rt_identify.KALMAN_SUFFIX if config["study"].get("estimator") == "kalman" else ""
)


def fit_targets():
    """(vehicle, order) of every configured fit, in config order."""
    return [(vid, n) for vid in VEHICLES for n in STUDY.vehicles[vid].model["orders"]]


def model_targets():
    """(vehicle, model key) of every configured fit: order1, order2, then further structures
    (the key names the files: fit_<key>.yaml)."""
    return [
        (vid, key) for vid in VEHICLES for key in rt_identify.model_keys(STUDY.vehicles[vid].data)
    ]


def load_references():
    """The study's published analyses of the same data, validated once at parse time:
    [(file, reference)], each naming a fit the study makes."""
    try:
        return rt_reference.study_references(config["study"]["references"], model_targets())
    except RailthermError as err:
        raise WorkflowError(f"invalid configuration: {err}") from None


REFERENCES = load_references()


def second_order_vehicles():
    """Vehicles with a second-order fit: the rows of Tables 2 and 3."""
    return [vid for vid, n in fit_targets() if n == 2]


def figure3_vehicle():
    """The vehicle of Figure 3 when it is in the study with first- and second-order fits."""
    vid = config["study"]["figure3"]
    return vid if vid and {(vid, 1), (vid, 2)} <= set(fit_targets()) else None


def figure4_vehicles():
    """The configured Figure 4 vehicles that have a second-order fit."""
    return [vid for vid in config["study"]["figure4"] if vid in second_order_vehicles()]


def sindy_vehicles():
    """Vehicles the SINDy cross-check runs on: with it enabled, those with surface sensors."""
    if not config["sindy"]["enabled"]:
        return []
    return [vid for vid in VEHICLES if STUDY.vehicles[vid].channels.get("surface")]


STUDY_TABLES = ("table1", "table2", "table3", "class_summary", "class_test")


def study_figures():
    """Stems of the study figures this config can draw (results/figures/<stem>.png/.svg)."""
    stems = []
    if figure3_vehicle():
        stems.append("figure3")
    if figure4_vehicles():
        stems.append("figure4")
    if second_order_vehicles() and config["study"]["paper_tables"]:
        stems += ["figure5a", "figure5b"]
    return stems


try:
    SCENARIOS = [load_scenario(path) for path in config["scenarios"]["files"]]
except RailthermError as err:
    raise WorkflowError(f"invalid scenario: {err}") from None


def scenario_files():
    """Every scenario file and every profile file it reads (inputs of the prediction rules)."""
    return list(dict.fromkeys(f for sc in SCENARIOS for f in (sc.file, *sc.files)))


def figure_scenario():
    """The scenario of the scenario figure and of the leave-one-out heat-up comparison:
    scenarios.figure, else the first scenario with a heat-up threshold (None: none)."""
    name = config["scenarios"]["figure"]
    if name is not None:
        chosen = [sc for sc in SCENARIOS if sc.name == name]
        if not chosen:
            raise WorkflowError(
                f"config/config.yaml: key 'scenarios.figure' = {name!r}: no such scenario; "
                f"the scenarios are {[sc.name for sc in SCENARIOS]}"
            )
        return chosen[0]
    return next((sc for sc in SCENARIOS if sc.heat_up_to_C is not None), None)


def prediction_outputs():
    """Targets of the rules simulate and reference_validation."""
    if not SCENARIOS or not second_order_vehicles():
        return []
    targets = [f"results/tables/scenarios.{ext}" for ext in ("csv", "md")]
    if figure_scenario() is not None:
        targets += [f"results/figures/scenarios.{ext}" for ext in ("png", "svg")]
        if config["reference_model"]["validation"] and config["study"]["paper_tables"]:
            targets += [f"results/tables/reference_validation.{ext}" for ext in ("csv", "md")]
            targets += [f"results/figures/reference_validation.{ext}" for ext in ("png", "svg")]
    return targets


def all_outputs():
    """The targets of `rule all`."""
    targets = [path for vid in VEHICLES for path in raw_files(vid)]
    targets += [
        f"results/vehicles/{vid}/clean/{window}.csv"
        for vid in VEHICLES
        for window in tidy_tables(vid)
    ]
    targets += [
        f"results/vehicles/{vid}/kvalue.{ext}"
        for vid in kvalue_vehicles()
        for ext in ("yaml", "png", "svg")
    ]
    if kvalue_vehicles():
        targets.append("results/tables/kvalue.csv")
    targets += [f"results/vehicles/{vid}/fit_{key}.yaml" for vid, key in model_targets()]
    targets.append("results/tables/identification.csv")
    targets += [
        f"results/vehicles/{vid}/fit_{key}.{ext}"
        for vid, key in model_targets()
        for ext in ("png", "svg")
    ]
    targets += [
        f"results/vehicles/{vid}/innovations_{key}.png"
        for vid, key in model_targets()
        if key.endswith(rt_identify.KALMAN_SUFFIX)
    ]
    if config["study"]["models_table"]:
        targets += [f"results/tables/models.{ext}" for ext in ("csv", "md")]
    if config["study"]["references"]:
        targets += [f"results/tables/reference.{ext}" for ext in ("csv", "md")]
    if second_order_vehicles() and config["study"]["paper_tables"]:
        targets += [
            f"results/tables/{name}.{ext}"
            for name in STUDY_TABLES
            for ext in ("csv", "md", "tex")
        ]
    targets += [f"results/figures/{stem}.{ext}" for stem in study_figures() for ext in ("png", "svg")]
    if sindy_vehicles():
        targets += [f"results/vehicles/{vid}/sindy.yaml" for vid in sindy_vehicles()]
        targets += [f"results/tables/sindy.{ext}" for ext in ("csv", "md")]
        targets += [f"results/figures/sindy.{ext}" for ext in ("png", "svg")]
    if config["audit"]["published"]:
        targets += ["results/audit/findings.csv", "results/audit/audit.md"]
    targets += prediction_outputs()
    if CAMPAIGN:
        targets += [
            "results/campaign/ground_truth.csv",
            "results/campaign/ground_truth_sources.csv",
        ]
    return targets
