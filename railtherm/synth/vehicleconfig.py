"""Vehicle configs for the campaign: the windows and channel map of each vehicle's raw files.

The shipped ``config/vehicles/*.yaml`` of a campaign vehicle must agree with
:func:`vehicle_config` (tests/test_campaign.py checks it): it declares the columns, format and
time stamps the logger (:mod:`railtherm.synth.logger`) writes and the windows of the programme.
"""

from __future__ import annotations

import numpy as np

from railtherm.synth.campaign import vehicle_spec
from railtherm.synth.logger import columns


def _stamp(spec: dict, t_s: float):
    if spec["logger"]["time_format"] == "seconds":
        return int(t_s) if float(t_s).is_integer() else float(t_s)
    return str(np.datetime_as_string(np.datetime64(spec["start"], "s") + int(t_s), unit="s"))


def windows(spec: dict) -> dict:
    """The vehicle-config ``windows`` for the programme (times in the file's time format).

    existing: kvalue = the last ``kvalue_window_h`` (>= 8 h) of the k-test hold; one
    identification window ``sequence`` from the start of the k-test hold to the end of the
    cool-down. The pre-heating is left out: its heat is only known from the air flow (biased and
    noisy, paper section 3.3), and a test engineer would not identify on it.
    special: kvalue = the last ``kvalue_window_h`` of the steady start; ``step_up``
    from 1 h before the step to the reversal (file step_up) and ``step_down`` over the second
    file.
    """
    p, ph = spec["programme"], spec["programme"]["phases_s"]
    w = p["kvalue_window_h"] * 3600.0
    if p["type"] == "existing":
        return {
            "kvalue": {
                "start": _stamp(spec, ph["cooldown"] - w),
                "end": _stamp(spec, ph["cooldown"]),
            },
            "identification": [
                {
                    "name": "sequence",
                    "start": _stamp(spec, ph["kvalue"]),
                    "end": _stamp(spec, spec["files"][0]["t1"]),
                }
            ],
        }
    f_up, f_down = spec["files"]
    return {
        "kvalue": {
            "file": "step_up",
            "start": _stamp(spec, ph["step_up"] - w),
            "end": _stamp(spec, ph["step_up"]),
        },
        "identification": [
            {
                "name": "step_up",
                "file": "step_up",
                "start": _stamp(spec, max(0.0, ph["step_up"] - 3600.0)),
                "end": _stamp(spec, f_up["t1"]),
            },
            {
                "name": "step_down",
                "file": "step_down",
                "start": _stamp(spec, f_down["t0"]),
                "end": _stamp(spec, f_down["t1"]),
            },
        ],
    }


def vehicle_config(campaign: dict, vehicle_id: str, raw_dir: str = "../../resources/campaign"):
    """The vehicle-config content (schema keys) matching what the campaign writes for a vehicle;
    raw file paths are ``{raw_dir}/{id}/{name}`` (relative to the vehicle YAML's directory)."""
    spec = vehicle_spec(campaign, vehicle_id)
    m = campaign["_merged"][vehicle_id]
    lg = spec["logger"]
    cols = columns(spec)
    tunit = lg["temperature_unit"]
    weights = m["sensors"]["indoor"].get("weights")

    def temp(kind):
        out = []
        for c, k, i in cols:
            if k == kind:
                d = {"column": c}
                if kind == "indoor" and weights is not None:
                    d["weight"] = weights[i - 1]
                if tunit != "degC":
                    d["unit"] = tunit
                out.append(d)
        return out

    heater = [
        {"column": c, "unit": lg["hvac_unit"] if k == "hvac" else lg["power_unit"]}
        for c, k, _ in cols
        if k in ("hvac", "heater", "heater_total")
    ]
    fan = [{"column": c, "unit": lg["power_unit"]} for c, k, _ in cols if k in ("fan", "fan_total")]
    channels = {"indoor_air": temp("indoor"), "surface": temp("surface")}
    channels["outdoor_air"] = temp("outdoor")
    channels["heater_power"] = heater
    if fan:
        channels["fan_power"] = fan
    return {
        "id": vehicle_id,
        "class": spec["class"],
        "synthetic": True,
        "mass_kg": m["truth"]["mass_kg"]["value"],
        "surface_m2": m["truth"]["surface_m2"]["value"],
        "volume_m3": m["truth"]["volume_m3"]["value"],
        "raw_files": {f["key"]: f"{raw_dir}/{vehicle_id}/{f['name']}" for f in spec["files"]},
        "format": {
            "separator": lg["separator"],
            "decimal": lg.get("decimal", "."),
            # the logger's power meters report the mean over the interval ending at each stamp
            "power_timing": "mean_preceding",
            "time": {"column": lg["time_column"], "format": lg["time_format"]},
        },
        "channels": channels,
        # the campaign's sensors, as a lab declares its calibration: one sensor's offset sd
        "instruments": {
            f"{group}_temperature_u_K": float(m["sensors"][group]["offset_sd_K"])
            for group in ("indoor", "surface", "outdoor")
        },
        "windows": windows(spec),
    }
