"""Shared fixtures: the virtual campaign synthesised once per test session."""

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
