"""Shared fixtures: the virtual campaign synthesised once per test session."""

import os
import shutil
from pathlib import Path

# One BLAS thread per process: the suite already runs a worker per CPU (`-n auto`), and the
# processes its tests start (the command line, Snakemake) run beside them. OpenBLAS's own
# threads on top only wait for each other: on 2 cores they cost the kalman, plots, design,
# pem and simulate tests a third more CPU and wall time. Set before numpy is first imported
# (below); a value in the environment wins.
for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

import pytest  # noqa: E402

from railtherm import synth  # noqa: E402
from railtherm.config import load_study  # noqa: E402

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
    _compile_loops()


def _compile_loops() -> None:
    """The compiled loops' machine code cached once, before the workers start: a small Kalman
    fit (the filter, its gradient and Fisher information, the output-error start) and a
    short annual-energy run with process noise. In a fresh clone every worker and Snakemake
    job would otherwise compile them itself (about 12 s each) until one had written the
    cache. An optimisation only: any failure here leaves the tests to compile as they go."""
    try:
        from dataclasses import replace

        import numpy as np
        import pandas as pd

        from railtherm.estimation import kalman, models, pem
        from railtherm.study import energy, simulate, weather

        second = models.STRUCTURES["second_order"]
        theta = {"kA": 700.0, "C": 9.0e6, "K_veh": 450.0, "C_veh": 1.8e7}
        rng = np.random.default_rng(0)
        n, dt = 300, 60.0
        u = np.column_stack([np.full(n, -10.0), np.where(np.arange(n) % 100 < 50, 2e4, 5e3)])
        A, B = second.matrices(theta)
        Ad, Bd = models.discretize_zoh(A, B, dt)
        x = np.empty((n, 2))
        x[0] = models.steady_state(A, B, u[0])
        for k in range(n - 1):
            x[k + 1] = Ad @ x[k] + Bd @ u[k] + rng.normal(0.0, 0.01, 2)
        y = x + rng.normal(0.0, 0.05, x.shape)
        kalman.fit(second, [pem.Experiment(name="warm", dt=dt, u=u, y=y)])
        hours = 8760
        year = weather.Weather(
            "flat",
            "constant",
            pd.date_range("2001-01-01 01:00", periods=hours, freq="h"),
            np.arange(hours) * 3600.0,
            np.full(hours, 0.0),
            None,
        )
        profile = replace(
            energy.load_profile(REPO / "config" / "profiles" / "metro_service.yaml"),
            preheat_mode="ready_by",
        )

        def draw(count, generator):
            return {p: v * np.exp(generator.normal(0.0, 0.01, count)) for p, v in theta.items()}

        vehicle = simulate.ParameterSet(
            "warm", "declared", second, dict(theta), draw=draw, sigma=np.array([1e-3, 1e-3])
        )
        energy.annual_energy(vehicle, year, profile, dt_s=3600.0, draws=2)
    except Exception:  # noqa: BLE001 - a warm-up only
        pass


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
