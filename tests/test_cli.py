"""`railtherm validate`: exit 0 with "ok: N vehicles", or exit 1 with the one-line error."""

from __future__ import annotations

import copy
import os
import subprocess
import sys

import pytest
import yaml
from test_config import RAW_FILE, VEHICLE, VEHICLE_FILE, csv_text, write_raw, write_vehicle

from railtherm.cli import main


def write_study(vehicles, path="config/config.yaml", **extra):
    os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
    with open(path, "w", encoding="utf-8") as stream:
        yaml.safe_dump({"vehicles": vehicles, **extra}, stream)


def setup_repo(root) -> None:
    os.chdir(root)
    write_raw(csv_text(), RAW_FILE)
    write_vehicle(VEHICLE)
    second = copy.deepcopy(VEHICLE)
    second["id"] = "V2"
    write_vehicle(second, "config/vehicles/V2.yaml")
    write_study([VEHICLE_FILE, "config/vehicles/V2.yaml"])


def test_validate_ok(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    setup_repo(tmp_path)
    assert main(["validate"]) == 0
    assert capsys.readouterr().out == "ok: 2 vehicles, values of 4 windows checked\n"
    assert main(["validate", "--headers-only"]) == 0
    assert capsys.readouterr().out == "ok: 2 vehicles\n"


def test_validate_single_vehicle_files(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    setup_repo(tmp_path)
    assert main(["validate", VEHICLE_FILE]) == 0
    assert capsys.readouterr().out == "ok: 1 vehicle, values of 2 windows checked\n"
    os.remove("config/config.yaml")  # loose vehicle files need no study config
    assert main(["validate", VEHICLE_FILE, "config/vehicles/V2.yaml"]) == 0
    assert capsys.readouterr().out == "ok: 2 vehicles, values of 4 windows checked\n"


def test_validate_bad_vehicle_exits_1_with_message(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    setup_repo(tmp_path)
    bad = copy.deepcopy(VEHICLE)
    bad["id"] = "V2"
    bad["mass_kg"] = -1
    write_vehicle(bad, "config/vehicles/V2.yaml")
    assert main(["validate"]) == 1
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err == "config/vehicles/V2.yaml: key 'mass_kg' = -1: must be > 0\n"


def test_validate_bad_study_config(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    setup_repo(tmp_path)
    write_study([VEHICLE_FILE, "config/vehicles/V3.yaml"], path="other.yaml")
    assert main(["validate", "--config", "other.yaml"]) == 1
    err = capsys.readouterr().err
    assert (
        err == "other.yaml: key 'vehicles[1]' = 'config/vehicles/V3.yaml': vehicle file not found\n"
    )
    assert main(["validate", "--config", "missing.yaml"]) == 1
    assert "missing.yaml: key '(file)' = 'missing.yaml': file not found" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("extra", "key", "hint"),
    [
        ({"default": {}}, "default", "did you mean 'defaults'?"),
        ({"defaults": {"modle": {}}}, "defaults.modle", "did you mean 'model'?"),
        ({"study": {"figure5": True}}, "study.figure5", "unknown key"),
        ({"posterior": {"target_accept": 1.0}}, "posterior.target_accept", "1.0"),
        ({"posterior": {"chains": 0}}, "posterior.chains", "0"),
    ],
)
def test_validate_refuses_an_unknown_study_key_as_snakemake_would(
    tmp_path, monkeypatch, capsys, extra, key, hint
):
    """Once these passed `railtherm validate` and failed in Snakemake's schema check."""
    monkeypatch.chdir(tmp_path)
    setup_repo(tmp_path)
    write_study([VEHICLE_FILE], **extra)
    assert main(["validate"]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"config/config.yaml: key '{key}'") and hint in err


def test_validate_directory_option(tmp_path, monkeypatch, capsys):
    setup_repo(tmp_path)
    monkeypatch.chdir(tmp_path.parent)
    assert main(["validate", "-d", str(tmp_path)]) == 0
    assert capsys.readouterr().out == "ok: 2 vehicles, values of 4 windows checked\n"


def test_console_script_prints_no_traceback(tmp_path):
    cwd = os.getcwd()
    try:
        setup_repo(tmp_path)
        with open(VEHICLE_FILE, "a", encoding="utf-8") as stream:
            stream.write("colour: red\n")
    finally:
        os.chdir(cwd)
    result = subprocess.run(
        [sys.executable, "-m", "railtherm.cli", "validate"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 1
    assert result.stdout == ""
    assert "Traceback" not in result.stderr
    assert result.stderr.startswith(
        "config/vehicles/V1.yaml: key 'colour' = 'red': unknown key (allowed: id, class,"
    )
    assert result.stderr.count("\n") == 1


def test_no_command_prints_usage(capsys):
    assert main([]) == 2
    assert "validate" in capsys.readouterr().err


def test_every_help_text_reads_as_written():
    """argparse %-formats help strings but not descriptions: a "%%" written into a
    description is printed as it stands. No command's help shows one, and the fit command
    names both estimators."""
    import argparse

    from railtherm.cli import build_parser

    parser = build_parser()
    (commands,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    texts = {"railtherm": parser.format_help()}
    texts.update({name: sub.format_help() for name, sub in commands.choices.items()})
    for name, text in texts.items():
        assert "%%" not in text, name
    fit = " ".join(texts["fit"].split())
    assert "simulation-error PEM" in fit and "Kalman filter" in fit
