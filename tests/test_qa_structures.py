"""Structure modules a user may write that the registry must refuse by name, beside a healthy
module it keeps (the loader of tests/test_structures_refused.py)."""

from __future__ import annotations

import pytest
from test_structures_refused import ENVELOPE, refused_only


@pytest.mark.bad_input
@pytest.mark.parametrize(
    "old, new, key",
    [
        ('"K_i": (1.0e-1, 1.0e7)', '"K_i": (-1.0e3, 1.0e7)', "STRUCTURE.bounds[K_i]"),
        ('"C": (1.0e4, 1.0e10)', '"C": (0.0, 1.0e10)', "STRUCTURE.bounds[C]"),
    ],
)
def test_a_bound_at_or_below_zero_is_refused(tmp_path, monkeypatch, old, new, key):
    """Before: a lower bound of -1000 W/K (with a start value of 0, inside it) was accepted,
    though every parameter is a capacity or conductance estimated as its logarithm."""
    source = ENVELOPE.replace(old, new)
    assert source != ENVELOPE
    message = refused_only(tmp_path, monkeypatch, "my_network", source)
    assert f"key '{key}'" in message
    assert "must be > 0" in message and "give a small positive low" in message


@pytest.mark.bad_input
def test_a_module_that_exits_at_import_is_refused_not_obeyed(tmp_path, monkeypatch):
    """sys.exit() in a module's body must not end the command that loads the registry."""
    source = ENVELOPE.replace(
        "import numpy as np", "import sys\n\nimport numpy as np\n\nsys.exit(0)"
    )
    message = refused_only(tmp_path, monkeypatch, "my_network", source)
    assert "key '(import)' = 'SystemExit: 0'" in message and "fix it" in message


@pytest.mark.bad_input
def test_a_module_named_with_the_kalman_suffix_is_refused(tmp_path, monkeypatch):
    """Before: env_kalman.py loaded, `railtherm validate` said ok for a vehicle asking for
    it, and `railtherm fit` stopped with ValueError: unknown model 'env_kalman' (the key read
    as env by the Kalman filter)."""
    message = refused_only(tmp_path, monkeypatch, "env_kalman", ENVELOPE)
    assert "key '(file name)' = 'env_kalman.py'" in message
    assert "may not end in _kalman" in message and "rename the file, e.g. env.py" in message


def test_the_registry_and_the_model_keys_share_the_kalman_suffix():
    from railtherm.structures import _load
    from railtherm.study import fitsettings

    assert _load.KALMAN_SUFFIX == fitsettings.KALMAN_SUFFIX
