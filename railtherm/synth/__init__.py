"""The virtual climatic wind tunnel (CWT): synthetic raw files from declared ground truth.

The paper's measurements are proprietary, so the study ships a SYNTHETIC campaign: a YAML file
(config/campaign/virtual_cwt.yaml) declares, per vehicle, the true parameters (k, C, K_veh,
C_veh from Table 2, masses implied by Table 3 or assumed), the experiment programme (paper
section 3), the instruments and logger, and any declared deviation from the paper's
assumptions (section 4). This package simulates each vehicle and writes the raw CSV files a lab
logger would have written. See docs/virtual-cwt.md.

- :mod:`~railtherm.synth.campaign`: the campaign file (schema ``campaign.schema.yaml``), its
  semantic checks and the resolved per-vehicle spec;
- :mod:`~railtherm.synth.physics`: eq. 1 around the two-capacity model (eqs. 7-8 / 14), the
  declared deviations, the tunnel, HVAC and thermostat controllers, simulated exactly by
  zero-order hold on the fine step;
- :mod:`~railtherm.synth.logger`: the instruments and the logger: columns, the logged record,
  the raw files;
- :mod:`~railtherm.synth.vehicleconfig`: the vehicle configs (channels, format, windows) that
  match the raw files;
- :mod:`~railtherm.synth.truth`: the declared truth as tables.
"""

from __future__ import annotations

from railtherm.synth.campaign import (
    DEVIATION_EFFECT_ON_K as DEVIATION_EFFECT_ON_K,
)
from railtherm.synth.campaign import (
    DEVIATION_TYPES,
    SOURCE_PREFIXES,
    TRUTH_UNITS,
    load_campaign,
    time_constants,
    vehicle_spec,
)
from railtherm.synth.logger import (
    columns,
    planned_layouts,
    raw_file_names,
    simulate,
    write_raw_file,
)
from railtherm.synth.truth import ground_truth_sources, ground_truth_table
from railtherm.synth.vehicleconfig import vehicle_config, windows

__all__ = [
    "DEVIATION_TYPES",
    "SOURCE_PREFIXES",
    "TRUTH_UNITS",
    "columns",
    "ground_truth_sources",
    "ground_truth_table",
    "load_campaign",
    "planned_layouts",
    "raw_file_names",
    "simulate",
    "time_constants",
    "vehicle_config",
    "vehicle_spec",
    "windows",
    "write_raw_file",
]
