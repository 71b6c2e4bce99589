# Shared set-up: load and validate every vehicle before any job starts, and helpers for rules.
import functools
import inspect
import os
import re
from pathlib import Path

from snakemake.exceptions import WorkflowError

try:  # where Snakemake looks up an input or params function's parameters, job by job
    from snakemake.common import overwrite_function_params
except ImportError:  # another Snakemake: inspected at every job, as usual
    overwrite_function_params = None

from railtherm.study import identify as rt_identify
from railtherm.study import reference as rt_reference
from railtherm import codedigest, synth
from railtherm.data import ingest
from railtherm.config import load_study
from railtherm.data.datacheck import check_study_values
from railtherm.errors import RailthermError
from railtherm.data.rawfile import DigestCache
from railtherm.study.scenario import load_scenario

# where a conda job's post-deploy script finds the repository to install railtherm from
os.environ.setdefault("RAILTHERM_REPO", str(Path(workflow.basedir).resolve()))

# railtherm's parse caches: a study parsed again validates only what changed (railtherm.config
# VehicleCache, railtherm.data.rawfile DigestCache, railtherm.data.datacheck check_study_values)
CACHE_DIR = ".snakemake/railtherm"

try:
    STUDY = load_study(config, workdir=".", cache=f"{CACHE_DIR}/vehicles.pickle")
except RailthermError as err:
    raise WorkflowError(f"invalid configuration: {err}") from None

CAMPAIGN = STUDY.campaign_data
VEHICLES = list(STUDY.vehicles)
CAMPAIGN_VEHICLES = list(CAMPAIGN["vehicles"]) if CAMPAIGN else []
CAMPAIGN_ROOT = "resources/campaign"


# The chain from raw file to the study's tables (synthesize, clean, kvalue, identify, check,
# aggregate, the predictions) goes first among the jobs ready to run; figures and other leaves
# fill the cores around it. Left alone, Snakemake prefers the job with the largest input
# files, a vehicle's figures, and the study's last vehicle reaches its tables late.
CHAIN_PRIORITY = 1


VEHICLE_ID = "[A-Za-z][A-Za-z0-9_-]*"


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


def raw_files(vehicle):
    """The raw files of one vehicle, as paths relative to the working directory."""
    return list(STUDY.vehicles[vehicle].raw_files.values())


# The helpers below answer per vehicle and are memoised: input functions and params run once
# per job, and a fleet has thousands of jobs.


def per_job(func):
    """Mark an input or params function: its signature is read once, not by Snakemake at each
    of the thousands of jobs of a fleet (inspect.signature costs more than the function)."""
    if overwrite_function_params is not None:
        overwrite_function_params(func, inspect.signature(func).parameters)
    return func


@functools.cache
def tidy_tables(vehicle):
    """Tidy tables of a vehicle: its windows, plus the whole record for the k-window figure."""
    names = ingest.window_names(STUDY.vehicles[vehicle].data)
    return tuple(names + ["record"] if "kvalue" in names else names)


@functools.cache
def table_sources(vehicle):
    """{tidy table: the raw file it is cut from} of a vehicle (railtherm.data.ingest.window_spec)."""
    v = STUDY.vehicles[vehicle]
    return {w: v.raw_files[ingest.window_spec(v.data, w)[0]] for w in tidy_tables(vehicle)}


@per_job
def clean_input(wildcards):
    """The raw files a vehicle's tidy tables are cut from (each once)."""
    return list(dict.fromkeys(table_sources(wildcards.vehicle).values()))


def rule_groups(name, signature):
    """The study's vehicles grouped by ``signature(vehicle)``, which fixes the outputs of a
    per-vehicle rule (Snakemake takes no output function), in order of first appearance, as
    [(name of the group's rule, signature, wildcard constraint of its vehicles)]. The rule of
    the first group is named ``name``, those of further groups ``name_2``, ``name_3`` and so
    on; a fleet of alike vehicles has one."""
    groups = {}
    for vid in VEHICLES:
        groups.setdefault(signature(vid), []).append(vid)
    return [
        (name if i == 0 else f"{name}_{i + 1}", sig, group_constraint(list(groups.values()), vids))
        for i, (sig, vids) in enumerate(groups.items())
    ]


def group_constraint(groups, vehicles):
    """The wildcard constraint matching ``vehicles``, one of ``groups`` (lists of vehicles):
    any vehicle id when there is one group; else for the largest group any id but the others'
    (each followed by no id character), for the others their own ids. A fleet's constraints
    stay short: a regular expression of a thousand names takes long to compile."""
    if len(groups) == 1:
        return VEHICLE_ID
    largest = max(groups, key=len)
    if vehicles is largest:
        others = [vid for group in groups if group is not largest for vid in group]
        alternatives = "|".join(re.escape(vid) for vid in others)
        return f"(?!(?:{alternatives})(?![A-Za-z0-9_-])){VEHICLE_ID}"
    return "|".join(re.escape(vid) for vid in vehicles)


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


@functools.cache
def _raw_digests(vehicle):
    return {
        path: (
            "written by rule synthesize"
            if Path(path).is_relative_to(CAMPAIGN_ROOT)
            else RAW_DIGESTS.digest(path)
        )
        for path in dict.fromkeys(table_sources(vehicle).values())
    }


@per_job
def raw_digests(wildcards):
    """Content digests of a vehicle's raw files, passed as a param so that new content reruns
    its jobs whatever the file's mtime. Files the workflow writes itself (the virtual
    campaign's) follow their own rule and are not hashed."""
    return _raw_digests(wildcards.vehicle)


@functools.cache
def _kvalue_vehicles():
    return tuple(vid for vid in VEHICLES if has_kvalue(vid))


def kvalue_vehicles():
    """Vehicles with a steady window for the standardized static k test."""
    return list(_kvalue_vehicles())


def has_kvalue(vehicle):
    """Whether a vehicle of the study has a steady window for the static k test."""
    return "kvalue" in STUDY.vehicles[vehicle].windows


@functools.cache
def identification_windows(vehicle):
    """Names of a vehicle's identification windows, in config order."""
    return tuple(w["name"] for w in STUDY.vehicles[vehicle].windows["identification"])


@functools.cache
def _identification_tables(vehicle):
    windows = identification_windows(vehicle)
    return tuple(f"results/vehicles/{vehicle}/clean/{w}.csv" for w in windows)


@per_job
def identification_tables(wildcards):
    """The tidy tables of a vehicle's identification windows (input of identify, sindy)."""
    return list(_identification_tables(wildcards.vehicle))


@per_job
def kvalue_input(wildcards):
    """The static k result a two-stage fit needs (none without a k window)."""
    if has_kvalue(wildcards.vehicle):
        return f"results/vehicles/{wildcards.vehicle}/kvalue.yaml"
    return []


@per_job
def kvalue_window_input(wildcards):
    """The tidy k window, for the storage correction of the static k (none without one)."""
    if has_kvalue(wildcards.vehicle):
        return f"results/vehicles/{wildcards.vehicle}/clean/kvalue.csv"
    return []


@per_job
def vehicle_data(wildcards):
    """A vehicle's validated config (params of its jobs)."""
    return STUDY.vehicles[wildcards.vehicle].data


@per_job
def check_settings(wildcards):
    """The thresholds of a vehicle's verdicts (config `check`)."""
    return STUDY.vehicles[wildcards.vehicle].data["check"]


@per_job
def vehicle_synthetic(wildcards):
    """Whether a vehicle's data are synthetic (the figures say so)."""
    return STUDY.vehicles[wildcards.vehicle].data.get("synthetic", False)


@per_job
def clean_sources(wildcards):
    """{tidy table: raw file} of a vehicle (params of its clean job)."""
    return table_sources(wildcards.vehicle)


@per_job
def identification_names(wildcards):
    """The names of a vehicle's identification windows (params of identify)."""
    return list(identification_windows(wildcards.vehicle))


# the fits of the study's tables: fit_order<n>.yaml, or fit_order<n>_kalman.yaml when the study
# chooses the Kalman-filter estimator (study.estimator)
TABLE_KEY_SUFFIX = (
    rt_identify.KALMAN_SUFFIX if config["study"].get("estimator") == "kalman" else ""
)


@functools.cache
def _fit_targets():
    return tuple((vid, n) for vid in VEHICLES for n in STUDY.vehicles[vid].model["orders"])


def fit_targets():
    """(vehicle, order) of every configured fit, in config order."""
    return list(_fit_targets())


def table_key(vehicle, order):
    """The model key of a vehicle's order-``order`` fit in the study's tables and figures: by
    the study's estimator (study.estimator) where the vehicle fits with it, else by the
    vehicle's own (a vehicle declaring model.estimator: kalman alone)."""
    key = f"order{order}{TABLE_KEY_SUFFIX}"
    if key in model_keys(vehicle):
        return key
    return f"order{order}" if TABLE_KEY_SUFFIX else f"order{order}{rt_identify.KALMAN_SUFFIX}"


def table_series(vehicle, order):
    """The simulated series of the fit :func:`table_key` names (the figures' input); any
    path when no vehicle is chosen (``vehicle`` None: the figure is not made)."""
    key = table_key(vehicle, order) if vehicle else f"order{order}"
    return f"results/vehicles/{vehicle}/identify/{key}_series.csv"


def has_fit(vehicle, order):
    """Whether a vehicle of the study fits the model of this order."""
    return order in STUDY.vehicles[vehicle].model["orders"]


@functools.cache
def model_keys(vehicle):
    """The model keys of a vehicle's fits: order1, order2, then further structures, each per
    estimator (the key names the files: fit_<key>.yaml)."""
    return tuple(rt_identify.model_keys(STUDY.vehicles[vehicle].data))


def identify_files(keys):
    """{estimate_<key>: the fit's estimate, series_<key>: its series} of a vehicle's models
    ``keys``, with the {vehicle} wildcard: the outputs of identify, the inputs of check."""
    files = {f"estimate_{key}": f"results/vehicles/{{vehicle}}/identify/{key}.yaml" for key in keys}
    files |= {
        f"series_{key}": f"results/vehicles/{{vehicle}}/identify/{key}_series.csv" for key in keys
    }
    return files


def model_targets():
    """(vehicle, model key) of every configured fit, in config order."""
    return [(vid, key) for vid in VEHICLES for key in model_keys(vid)]


def load_references():
    """The study's published analyses of the same data, validated once at parse time:
    [(file, reference)], each naming a fit the study makes."""
    try:
        return rt_reference.study_references(config["study"]["references"], model_targets())
    except RailthermError as err:
        raise WorkflowError(f"invalid configuration: {err}") from None


REFERENCES = load_references()


@functools.cache
def _second_order_vehicles():
    return tuple(vid for vid, n in _fit_targets() if n == 2)


def second_order_vehicles():
    """Vehicles with a second-order fit: the rows of Tables 2 and 3."""
    return list(_second_order_vehicles())


def figure3_vehicle():
    """The vehicle of Figure 3 when it is in the study with first- and second-order fits."""
    vid = config["study"]["figure3"]
    return vid if vid and {(vid, 1), (vid, 2)} <= set(fit_targets()) else None


def figure4_vehicles():
    """The configured Figure 4 vehicles that have a second-order fit."""
    return [vid for vid in config["study"]["figure4"] if vid in second_order_vehicles()]


@functools.cache
def _sindy_vehicles():
    if not config["sindy"]["enabled"]:
        return ()
    return tuple(vid for vid in VEHICLES if STUDY.vehicles[vid].channels.get("surface"))


def sindy_vehicles():
    """Vehicles the SINDy cross-check runs on: with it enabled, those with surface sensors."""
    return list(_sindy_vehicles())


SINDY_SETTINGS = {
    k: v for k, v in config["sindy"].items() if k not in ("enabled", "vehicles_per_job")
}


def sindy_batches():
    """[(name of the rule, vehicles)]: the SINDy vehicles in study order, sindy.vehicles_per_job
    to a job; the first batch's rule is ``sindy``, further ones ``sindy_2``, ``sindy_3``, ..."""
    vids = sindy_vehicles()
    size = config["sindy"]["vehicles_per_job"]
    batches = [vids[i : i + size] for i in range(0, len(vids), size)]
    return [("sindy" if i == 0 else f"sindy_{i + 1}", batch) for i, batch in enumerate(batches)]


def figure_signature(vehicle):
    """What fixes the outputs of a vehicle's figure job: a k figure or not, its model keys."""
    return (has_kvalue(vehicle), model_keys(vehicle))


def vehicle_figure_files(vehicle):
    """Every figure of ``vehicle`` that its vehicle_figures job draws (the k figure, a figure
    per fit, the innovations of each Kalman-filter fit), as PNG and SVG."""
    has_k, keys = figure_signature(vehicle)
    stems = (["kvalue"] if has_k else []) + [f"fit_{key}" for key in keys]
    stems += [f"innovations_{key}" for key in keys if key.endswith(rt_identify.KALMAN_SUFFIX)]
    return [f"results/vehicles/{vehicle}/{stem}.{ext}" for stem in stems for ext in ("png", "svg")]


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
    targets += [f"results/vehicles/{vid}/kvalue.yaml" for vid in kvalue_vehicles()]
    if kvalue_vehicles():
        targets.append("results/tables/kvalue.csv")
    targets += [f"results/vehicles/{vid}/fit_{key}.yaml" for vid, key in model_targets()]
    targets.append("results/tables/identification.csv")
    if config["study"]["figures"]:
        targets += [path for vid in VEHICLES for path in vehicle_figure_files(vid)]
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
