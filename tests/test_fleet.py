"""A fleet parses fast: the validated vehicles are kept between parses (railtherm.config's
VehicleCache), the figures of each vehicle can be switched off (study.figures), and the jobs
per vehicle are few (one clean job, one figure job)."""

from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

import pytest
import yaml
from snakemake_run import job_counts, make_study, snakemake

from railtherm.config import VehicleCache, load_study, read_yaml
from railtherm.data import recordcheck
from railtherm.errors import ConfigError

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture
def validation(tmp_path):
    """The validation study (two vehicles reading one measured raw file) in a scratch copy:
    (working directory, study config, raw file)."""
    workdir = tmp_path / "validation"
    shutil.copytree(REPO / "validation" / "config", workdir / "config")
    shutil.copytree(REPO / "data", tmp_path / "data")
    raw = tmp_path / "data" / "armadillo" / "armadillo_data_H2.csv"
    return workdir, read_yaml(workdir / "config" / "config.yaml"), raw


@pytest.fixture
def reads(monkeypatch):
    """Raw files read by the validation of a vehicle config (header and time column)."""
    seen: list[str] = []
    for name in ("read_columns", "read_layout"):
        original = getattr(recordcheck, name)

        def counting(path, *args, _original=original, **kwargs):
            seen.append(os.path.basename(path))
            return _original(path, *args, **kwargs)

        monkeypatch.setattr(recordcheck, name, counting)
    return seen


def load(workdir: Path, config: dict, cache: Path):
    return load_study(config, workdir=workdir, cache=cache)


def test_a_second_parse_reads_no_raw_file_and_gives_the_same_vehicles(validation, reads):
    workdir, config, _ = validation
    cache = workdir / ".snakemake" / "railtherm" / "vehicles.pickle"
    first = load(workdir, config, cache)
    assert reads and cache.is_file()
    reads.clear()
    second = load(workdir, config, cache)
    assert reads == []
    assert second.vehicles == first.vehicles
    assert second.vehicles == load_study(config, workdir=workdir).vehicles  # as if uncached
    again = VehicleCache(cache)
    assert set(again.entries) == {
        str(workdir / "config" / "vehicles" / f"{vid}.yaml") for vid in first.vehicles
    }


@pytest.mark.parametrize("change", ["mtime", "size", "same bytes rewritten"])
def test_a_changed_raw_file_is_read_again(validation, reads, change):
    workdir, config, raw = validation
    cache = workdir / ".snakemake" / "railtherm" / "vehicles.pickle"
    load(workdir, config, cache)
    reads.clear()
    st = raw.stat()
    if change == "mtime":
        os.utime(raw, ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000_000))
    elif change == "size":
        raw.write_bytes(raw.read_bytes() + b"\n")  # a trailing blank line: the same data
        os.utime(raw, ns=(st.st_atime_ns, st.st_mtime_ns))  # even with the old mtime
    else:
        raw.write_bytes(raw.read_bytes())
        os.utime(raw, ns=(st.st_atime_ns, st.st_mtime_ns))  # the ctime tells
    load(workdir, config, cache)
    assert set(reads) == {raw.name}
    assert len(reads) >= len(config["vehicles"])  # each vehicle reading it checked again
    reads.clear()
    load(workdir, config, cache)
    assert reads == []


def test_an_edited_vehicle_file_alone_is_validated_again(validation, reads):
    workdir, config, _ = validation
    cache = workdir / ".snakemake" / "railtherm" / "vehicles.pickle"
    before = load(workdir, config, cache)
    path = workdir / "config" / "vehicles" / "Armadillo_solar.yaml"
    data = yaml.safe_load(path.read_text())
    data["volume_m3"] = 120
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    reads.clear()
    cached = VehicleCache(cache)
    after = load_study(config, workdir=workdir, cache=cache)
    assert after.vehicles["Armadillo_solar"].volume_m3 == 120
    assert after.vehicles["Armadillo"] == before.vehicles["Armadillo"]
    assert len(reads) == 2  # the edited vehicle's raw file: its header, its time column
    assert len(cached.entries) == len(before.vehicles)  # one per vehicle of the study


def test_an_invalid_vehicle_is_not_kept_and_fails_every_parse(validation):
    workdir, config, _ = validation
    cache = workdir / ".snakemake" / "railtherm" / "vehicles.pickle"
    path = workdir / "config" / "vehicles" / "Armadillo.yaml"
    data = yaml.safe_load(path.read_text())
    data["mass_kg"] = -1
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    for _ in range(2):
        with pytest.raises(ConfigError, match="mass_kg"):
            load(workdir, config, cache)


def test_a_broken_or_foreign_cache_file_is_only_a_cache(validation, reads):
    workdir, config, _ = validation
    cache = workdir / "vehicles.pickle"
    cache.write_bytes(b"not a pickle")
    assert load(workdir, config, cache).vehicles
    assert reads
    reads.clear()
    load(workdir, config, cache)
    assert reads == []


def small_study(tmp_path: Path, figures: bool | None) -> Path:
    study = make_study(tmp_path, ["Tram2", "Metro3"])
    if figures is not None:
        cfg_path = study / "config" / "config.yaml"
        cfg = yaml.safe_load(cfg_path.read_text())
        cfg["study"]["figures"] = figures
        cfg_path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    return study


@pytest.mark.workflow
def test_one_clean_job_and_one_figure_job_per_vehicle(tmp_path):
    """Tram2's tables are other than Metro3's (two identification windows): a clean rule each."""
    study = small_study(tmp_path, None)
    run = snakemake(study, "--dry-run")
    assert run.returncode == 0, run.stderr
    counts = job_counts(run.stdout + run.stderr)
    assert counts["clean"] == 1 and counts["clean_2"] == 1
    assert counts["vehicle_figures"] == 2
    assert counts["identify"] == 2 and counts["check"] == 2  # one each per vehicle
    planned = re.findall(r"^rule clean(?:_2)?:\n\s+input: .*\n\s+output: (.+)$", run.stdout, re.M)
    assert sorted(len(line.split(", ")) for line in planned) == [3, 4]
    assert (study / ".snakemake" / "railtherm" / "vehicles.pickle").is_file()


@pytest.mark.workflow
def test_switched_off_figures_plan_no_per_vehicle_figure_job(tmp_path):
    study = small_study(tmp_path, False)
    run = snakemake(study, "--dry-run")
    assert run.returncode == 0, run.stderr
    counts = job_counts(run.stdout + run.stderr)
    assert not any(rule.startswith("vehicle_figures") for rule in counts)
    for rule in ("figure3", "figure5", "aggregate", "simulate", "sindy_summary"):
        assert counts[rule] == 1  # the study's own figures and tables stay
    planned = re.findall(r"^\s+output: (.+)$", run.stdout, re.MULTILINE)
    files = [f for line in planned for f in line.split(", ")]
    assert files and not any(re.match(r"results/vehicles/.*\.(png|svg)$", f) for f in files)
