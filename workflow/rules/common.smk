# Shared set-up: load and validate every vehicle before any job starts, and the helpers the
# rules take their files from (railtherm.study.plan answers them from the validated configs).
import functools
import os
import re
from pathlib import Path

from snakemake.exceptions import WorkflowError
from snakemake.logging import logger

from railtherm import codedigest, synth
from railtherm.config import energy_profile, load_study
from railtherm.data.datacheck import check_study_values, shared_records
from railtherm.data.rawfile import DigestCache
from railtherm.errors import RailthermError
from railtherm.study import fitsettings
from railtherm.study import reference as rt_reference
from railtherm.study.plan import STUDY_TABLES, VEHICLE_ID, StudyPlan, figure_warnings
from railtherm.study.scenario import load_scenario

# where a conda job's post-deploy script finds the repository to install railtherm from
os.environ.setdefault("RAILTHERM_REPO", str(Path(workflow.basedir).resolve()))

# railtherm's parse caches: a study parsed again validates only what changed (railtherm.config
# VehicleCache, railtherm.data.rawfile DigestCache, railtherm.data.datacheck check_study_values)
CACHE_DIR = ".snakemake/railtherm"

try:
    STUDY = load_study(config, workdir=".", cache=f"{CACHE_DIR}/vehicles.pickle")
    SCENARIOS = [load_scenario(path) for path in config["scenarios"]["files"]]
except RailthermError as err:
    raise WorkflowError(f"invalid configuration: {err}") from None

PLAN = StudyPlan(STUDY, config, SCENARIOS)
CAMPAIGN = STUDY.campaign_data
VEHICLES = PLAN.vehicles
CAMPAIGN_VEHICLES = PLAN.campaign_vehicles
CAMPAIGN_ROOT = "resources/campaign"


# The chain from raw file to the study's tables (synthesize, clean, kvalue, identify, check,
# aggregate, the predictions) goes first among the jobs ready to run; figures and other leaves
# fill the cores around it. Left alone, Snakemake prefers the job with the largest input
# files, a vehicle's figures, and the study's last vehicle reaches its tables late.
CHAIN_PRIORITY = 1



wildcard_constraints:
    vehicle=VEHICLE_ID,


def script_code(script):
    """Digest of the railtherm code that ``workflow/scripts/<script>`` can run (its imports,
    in turn: railtherm.codedigest), passed as a param so that an edit of that code reruns the
    rule's jobs and no others."""
    return codedigest.code_digest(Path(workflow.basedir) / "workflow" / "scripts" / script)


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


RAW_DIGESTS = DigestCache(f"{CACHE_DIR}/raw-digests.json")

# every value of the study's own raw files, read as the jobs clean and kvalue will, so that a
# bad value stops the run before any job (cached by content: a parse again re-reads nothing)
try:
    check_study_values(
        STUDY,
        RAW_DIGESTS,
        f"{CACHE_DIR}/value-checks.json",
        skip=lambda path: Path(path).is_relative_to(CAMPAIGN_ROOT),
    )
except RailthermError as err:
    raise WorkflowError(f"invalid raw data: {err}") from None
for _warning in shared_records(STUDY) + figure_warnings(STUDY, config):  # as validate warns
    logger.warning(f"warning: {_warning}")


@functools.cache
def _raw_digests(vehicle):
    return {
        path: (
            "written by rule synthesize"
            if Path(path).is_relative_to(CAMPAIGN_ROOT)
            else RAW_DIGESTS.digest(path)
        )
        for path in PLAN.clean_input(vehicle)
    }


def raw_digests(wildcards):
    """Content digests of a vehicle's raw files, passed as a param so that new content reruns
    its jobs whatever the file's mtime. Files the workflow writes itself (the virtual
    campaign's) follow their own rule and are not hashed."""
    return _raw_digests(wildcards.vehicle)


# Per job: the input and params functions of the per-vehicle rules (wildcards -> files or values)


def clean_input(wildcards):
    """The raw files a vehicle's tidy tables are cut from (each once)."""
    return PLAN.clean_input(wildcards.vehicle)


def clean_sources(wildcards):
    """{tidy table: raw file} of a vehicle (params of its clean job)."""
    return PLAN.table_sources(wildcards.vehicle)


def identification_tables(wildcards):
    """The tidy tables of a vehicle's identification windows (input of identify, sindy)."""
    return list(PLAN.identification_tables(wildcards.vehicle))


def identification_names(wildcards):
    """The names of a vehicle's identification windows (params of identify)."""
    return list(PLAN.identification_windows(wildcards.vehicle))


def kvalue_input(wildcards):
    """The static k result a two-stage fit needs (none without a k window)."""
    return PLAN.kvalue_input(wildcards.vehicle)


def kvalue_window_input(wildcards):
    """The tidy k window, for the storage correction of the static k (none without one)."""
    return PLAN.kvalue_window_input(wildcards.vehicle)


def vehicle_data(wildcards):
    """A vehicle's validated config (params of its jobs)."""
    return STUDY.vehicles[wildcards.vehicle].data


def check_settings(wildcards):
    """The thresholds of a vehicle's verdicts (config `check`)."""
    return STUDY.vehicles[wildcards.vehicle].data["check"]


def vehicle_synthetic(wildcards):
    """Whether a vehicle's data are synthetic (the figures say so)."""
    return STUDY.vehicles[wildcards.vehicle].data.get("synthetic", False)


# At parse time: what the rules and the target rule ask of the whole study
raw_files = PLAN.raw_files
tidy_tables = PLAN.tidy_tables
has_kvalue = PLAN.has_kvalue
has_fit = PLAN.has_fit
model_keys = PLAN.model_keys
table_key = PLAN.table_key
table_series = PLAN.table_series
rule_groups = PLAN.rule_groups
figure_signature = PLAN.figure_signature
vehicle_figure_files = PLAN.vehicle_figure_files
figure3_vehicle = PLAN.figure3_vehicle
figure4_vehicles = PLAN.figure4_vehicles
sindy_batches = PLAN.sindy_batches
study_figures = PLAN.study_figures
scenario_files = PLAN.scenario_files
prediction_outputs = PLAN.prediction_outputs
all_outputs = PLAN.all_outputs


def kvalue_vehicles():
    return list(PLAN.kvalue_vehicles())


def fit_targets():
    return list(PLAN.fit_targets())


def second_order_vehicles():
    return list(PLAN.second_order_vehicles())


def sindy_vehicles():
    return list(PLAN.sindy_vehicles())


def model_targets():
    return PLAN.model_targets()


def identify_files(keys):
    """{estimate_<key>: the fit's estimate, series_<key>: its series} of a vehicle's models
    ``keys``, with the {vehicle} wildcard: the outputs of identify, the inputs of check."""
    files = {f"estimate_{key}": f"results/vehicles/{{vehicle}}/identify/{key}.yaml" for key in keys}
    files |= {
        f"series_{key}": f"results/vehicles/{{vehicle}}/identify/{key}_series.csv" for key in keys
    }
    return files


def load_references():
    """The study's published analyses of the same data, validated once at parse time:
    [(file, reference)], each naming a fit the study makes."""
    try:
        return rt_reference.study_references(config["study"]["references"], model_targets())
    except RailthermError as err:
        raise WorkflowError(f"invalid configuration: {err}") from None


REFERENCES = load_references()
SINDY_SETTINGS = {
    k: v for k, v in config["sindy"].items() if k not in ("enabled", "vehicles_per_job")
}


def figure_scenario():
    """The scenario of the scenario figure (railtherm.study.plan.StudyPlan.figure_scenario)."""
    try:
        return PLAN.figure_scenario()
    except RailthermError as err:
        raise WorkflowError(f"invalid configuration: {err}") from None


def energy_profiles(cfg):
    """The operating profiles the annual energy uses: each class's, then the default."""
    energy = cfg["energy"]
    paths = list((energy.get("profiles") or {}).values())
    if energy.get("profile"):
        paths.append(energy["profile"])
    return list(dict.fromkeys(paths))


def weather_years(cfg):
    """The names of the study's typical years (their files' stems; rule weather_year)."""
    return [Path(path).name.split(".")[0] for path in cfg["energy"]["weather"]]


def weather_file(year):
    """The weather file of the typical year ``year`` (:func:`weather_years`)."""
    files = {Path(path).name.split(".")[0]: path for path in config["energy"]["weather"]}
    return files[year]
