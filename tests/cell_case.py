"""A simulated test cell written as a lab would hand it over: one raw CSV file (elapsed
seconds, powers in W) and a vehicle config of class other fitting the interior-envelope
structure with its envelope state's start estimated. Shared by the tests of the model
structure options (irradiance node, surface sensors)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import yaml


def write_cell(
    root: Path,
    dt: float,
    columns: dict[str, np.ndarray],
    channels: dict[str, list[dict[str, Any]]],
    **extra: Any,
) -> Path:
    """``raw.csv`` (a column Time in seconds, then ``columns`` at full precision) and
    ``Cell.yaml`` under ``root``: the channels T_int (indoor air), T_ext (outdoor air) and
    P_hea (W) plus ``channels``, one identification window over the whole record, and the
    top-level keys ``extra``; returns the config's path."""
    names = list(columns)
    n = len(next(iter(columns.values())))
    lines = [",".join(["Time", *names])]
    lines += [
        ",".join([f"{i * dt:g}", *(f"{columns[c][i]:.17g}" for c in names)]) for i in range(n)
    ]
    (root / "raw.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
    vehicle = {
        "id": "Cell",
        "class": "other",
        "mass_kg": 20_000,
        "surface_m2": 162,
        "raw_files": {"run": "raw.csv"},
        "format": {
            "power_timing": "mean_following",
            "time": {"column": "Time", "format": "seconds"},
        },
        "channels": {
            "indoor_air": [{"column": "T_int"}],
            "outdoor_air": [{"column": "T_ext"}],
            "heater_power": [{"column": "P_hea", "unit": "W"}],
            **channels,
        },
        "windows": {"identification": [{"name": "run", "start": 0, "end": (n - 1) * dt}]},
        **extra,
        "model": {
            "orders": [2],
            "structures": ["interior_envelope"],
            "mode": "joint",
            "x0": "estimated",
        },
    }
    path = root / "Cell.yaml"
    path.write_text(yaml.safe_dump(vehicle, sort_keys=False), encoding="utf-8")
    return path
