"""Shared fixtures: the virtual campaign synthesised once per test session."""

import os
import shutil
from pathlib import Path

import pytest

from railtherm import synth
from railtherm.config import load_study

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def campaign_study(tmp_path_factory):
    """(root, campaign, study): the shipped configs in a temporary working directory with every
    raw file of the 13-vehicle virtual campaign written by the synthesizer."""
    root = tmp_path_factory.mktemp("campaign")
    shutil.copytree(REPO / "config", root / "config")
    campaign = synth.load_campaign(root / "config" / "campaign" / "virtual_cwt.yaml")
    for vid in campaign["vehicles"]:
        spec = synth.vehicle_spec(campaign, vid)
        for name in synth.raw_file_names(spec):
            synth.write_raw_file(spec, name, root / "resources" / "campaign" / vid / name)
    config = {"campaign": "config/campaign/virtual_cwt.yaml"}
    config["vehicles"] = [f"config/vehicles/{vid}.yaml" for vid in campaign["vehicles"]]
    return root, campaign, load_study(config, workdir=root)


@pytest.fixture(scope="session")
def fit_files(campaign_study, tmp_path_factory):
    """``fit_files(vehicle, model) -> (fit yaml path, series csv path)``: a vehicle of the virtual
    campaign, or the Armadillo test cell of the validation study, fitted once per session by
    :func:`railtherm.study.run.fit_vehicle` into a temporary results directory (as the rules
    write it)."""
    from railtherm.config import add_vehicle, read_yaml, study_context
    from railtherm.study import run

    root, _, study = campaign_study
    out = tmp_path_factory.mktemp("fits")
    cache: dict[tuple[str, str], tuple[Path, Path]] = {}

    def fit(vehicle: str, model: str) -> tuple[Path, Path]:
        if (vehicle, model) not in cache:
            if vehicle in study.vehicles:
                v, workdir = study.vehicles[vehicle], root
            else:
                workdir = REPO / "validation"
                config = read_yaml(workdir / "config" / "config.yaml")
                context = study_context(config, workdir=workdir, config_file="config/config.yaml")
                add_vehicle(context, workdir / "config" / "vehicles" / f"{vehicle}.yaml", workdir)
                v = context.vehicles[vehicle]
            run.fit_vehicle(v, [model], out=out, workdir=workdir)
            base = out / "vehicles" / vehicle
            cache[vehicle, model] = (
                base / f"fit_{model}.yaml",
                base / "identify" / f"{model}_series.csv",
            )
        return cache[vehicle, model]

    return fit


# ---------------------------------------------------------------------------------------------
# Running the suite on every core (pytest-xdist: `pytest -n auto`, as the README runs it)


def pytest_xdist_auto_num_workers(config):
    """``-n auto``: one worker per CPU this process may run on (its affinity), where xdist would
    count physical cores only (one on a 2-vCPU machine with hyperthreads)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def pytest_configure(config):
    """The package's bytecode written once before any test (in the controller, not per
    xdist worker): each process a test starts (a Snakemake job, the command line) then reads
    it instead of compiling the package's source again, as it does where
    PYTHONDONTWRITEBYTECODE is set. An optimisation only: every test runs whatever it says."""
    if hasattr(config, "workerinput"):
        return
    import compileall

    compileall.compile_dir(str(REPO / "railtherm"), quiet=1)


# the files that take longest (`pytest --durations=30`: whole-study runs), handed out first and
# so to different workers; an order only, every test runs whatever it says
LONGEST_FILES = (
    "test_workflow_full_study.py",
    "test_workflow.py",
    "test_optional_metadata.py",
    "test_kalman.py",
    "test_validation.py",
)


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """Order the test files for ``--dist loadfile`` (pyproject's addopts: each file's tests on
    one worker, so a module-scoped fixture - a finished study run, a fit - is made once, not
    once per worker), whatever the file: files with long tests (marked ``slow`` or
    ``workflow``: statistical checks, whole studies) are handed out first, so that no worker
    starts one when the others have finished. Without -n only the order of the files changes;
    each test stays independent of the order."""
    long_files = {
        item.path
        for item in items
        if item.get_closest_marker("slow") or item.get_closest_marker("workflow")
    }
    first_index = {}
    for i, item in enumerate(items):
        first_index.setdefault(item.path, i)
    # the longest files (whole studies, measured by --durations) before the other long ones
    rank = {name: i for i, name in enumerate(LONGEST_FILES)}
    items.sort(
        key=lambda item: (
            rank.get(item.path.name, len(rank)),
            item.path not in long_files,
            first_index[item.path],
        )
    )
