"""Programme entries that were read silently as something else: a phase compared over more
hours than it lasts (clamped to the phase) and a PRBS whose bit outlasts the phase (a held
power, no excitation). Each is refused naming the key, the value and the fix."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from railtherm.errors import ConfigError
from railtherm.study import design

REPO = Path(__file__).resolve().parents[1]
PAPER = REPO / "config" / "programmes" / "paper.yaml"


def _programme(tmp_path: Path, phase: int, **changes) -> Path:
    data = yaml.safe_load(PAPER.read_text())
    data["phases"][phase].update(changes)
    path = tmp_path / "programme.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


@pytest.mark.bad_input
def test_a_phase_compared_over_more_hours_than_it_lasts_is_refused(tmp_path):
    path = _programme(tmp_path, 0, identify=30)
    with pytest.raises(ConfigError) as err:
        design.load_programme(path)
    text = str(err.value)
    assert "key 'phases[0].identify' = 30" in text
    assert "give identify of at most 24, or true" in text


@pytest.mark.bad_input
def test_a_prbs_bit_longer_than_half_its_phase_is_refused(tmp_path):
    path = _programme(tmp_path, 2, prbs={"low_W": 5000, "high_W": 30000, "hold_h": 100})
    data = yaml.safe_load(path.read_text())
    del data["phases"][2]["power_W"]
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    with pytest.raises(ConfigError) as err:
        design.load_programme(path)
    text = str(err.value)
    assert "key 'phases[2].prbs.hold_h' = 100" in text
    assert "hold_h of at most 6 h" in text and "power_W / steps" in text


def test_the_limits_themselves_are_accepted(tmp_path):
    design.load_programme(_programme(tmp_path, 0, identify=24))
    path = _programme(tmp_path, 2, prbs={"low_W": 5000, "high_W": 30000, "hold_h": 6})
    data = yaml.safe_load(path.read_text())
    del data["phases"][2]["power_W"]
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    assert design.load_programme(path).phases[2].steps
