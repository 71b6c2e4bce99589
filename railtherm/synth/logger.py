"""The lab logger: column names, the logged record and the raw files it writes.

Logger conventions: one sample every ``step_s``; temperatures are instantaneous values at the
sample time; powers are the mean over the preceding logging interval [t - step_s, t) as
integrating power meters report them. The logged record adds the instruments to the simulated
truth (sensor offsets and noise, heat-driven stratification, the biased HVAC heat from the air
flow, power-meter noise) and a few short dropouts; :func:`write_raw_file` formats it as the
logger would (naming scheme, separator, decimal mark, units, optional gzip).
"""

from __future__ import annotations

import gzip
import io
import math
import posixpath
from pathlib import Path

import numpy as np
import pandas as pd

from railtherm.data.rawfile import RawLayout
from railtherm.errors import ConfigError
from railtherm.synth.campaign import _deviation, vehicle_spec
from railtherm.synth.physics import _interval_mean, _rngs, _run_cached, lagged, meter_scale


# --------------------------------------------------------------------------------------------
# Files and columns
# --------------------------------------------------------------------------------------------
def raw_file_names(spec: dict) -> list[str]:
    """File names written for a vehicle (e.g. ``Tram1_cwt.csv.gz``), in file order."""
    return [f["name"] for f in spec["files"]]


_SCHEMES = {
    "tag": {
        "indoor": "TI{:02d}",
        "surface": "TW{:02d}",
        "outdoor": "TA{:02d}",
        "hvac": "QKL01",
        "heater": "PH{:02d}",
        "heater_total": "PH_SUM",
        "fan": "PV{:02d}",
        "fan_total": "PV_SUM",
        "humidity": "RF01",
        "wind": "VW01",
    },
    "german": {
        "indoor": "T_Innen_{}",
        "surface": "T_Wand_{}",
        "outdoor": "T_Aussen_{}",
        "hvac": "Q_Klima_Luftstrom",
        "heater": "P_Heizung_{}",
        "heater_total": "P_Heizung_ges",
        "fan": "P_Luefter_{}",
        "fan_total": "P_Luefter_ges",
        "humidity": "rF_Innen",
        "wind": "v_Wind",
    },
    "dotted": {
        "indoor": "air.T.{}",
        "surface": "wall.T.{}",
        "outdoor": "tunnel.T.{}",
        "hvac": "hvac.Q",
        "heater": "heater.P.{}",
        "heater_total": "heater.P.total",
        "fan": "fan.P.{}",
        "fan_total": "fan.P.total",
        "humidity": "air.RH",
        "wind": "tunnel.v",
    },
    "english": {
        "indoor": "indoor_air_{}",
        "surface": "surface_{}",
        "outdoor": "tunnel_air_{}",
        "hvac": "hvac_heat_airflow",
        "heater": "heater_group_{}",
        "heater_total": "heater_total",
        "fan": "fan_{}",
        "fan_total": "fans_total",
        "humidity": "rel_humidity",
        "wind": "wind_speed",
    },
}


def columns(spec: dict) -> list[tuple[str, str, int]]:
    """(column name, kind, index) of every column of the vehicle's raw files, in file order.

    kind is one of time, indoor, surface, outdoor, hvac, heater, heater_total, fan, fan_total,
    humidity, wind; index counts from 1 within the kind (0 for single columns).
    """
    lg, se = spec["logger"], spec["sensors"]
    items: list[tuple[str, int]] = []
    items += [("indoor", i + 1) for i in range(len(se["indoor"]["heights_m"]))]
    items += [("surface", i + 1) for i in range(se["surface"]["n"])]
    items += [("outdoor", i + 1) for i in range(se["outdoor"]["n"])]
    if spec["programme"]["type"] == "existing":
        items.append(("hvac", 0))
    if lg["heater_channels"] == "per_group":
        items += [("heater", i + 1) for i in range(spec["heaters"]["groups"])]
    else:
        items.append(("heater_total", 0))
    if spec["fans"]["n"] > 0:
        if lg["fan_channels"] == "per_fan":
            items += [("fan", i + 1) for i in range(spec["fans"]["n"])]
        else:
            items.append(("fan_total", 0))
    items += [(x, 0) for x in lg.get("extras", [])]
    out = [(lg["time_column"], "time", 0)]
    if lg["naming"] == "channel":
        out += [(f"CH{j + 1:02d}", kind, i) for j, (kind, i) in enumerate(items)]
    else:
        fmt = _SCHEMES[lg["naming"]]
        out += [(fmt[kind].format(i), kind, i) for kind, i in items]
    return out


def _time_values(spec: dict, t_s: np.ndarray):
    if spec["logger"]["time_format"] == "seconds":
        return t_s.astype(float)
    base = np.datetime64(spec["start"], "s")
    return base + t_s.astype(np.int64).astype("timedelta64[s]")


def planned_layouts(campaign: dict, root: str = "resources/campaign") -> dict[str, RawLayout]:
    """Columns and first/last time of every raw file the campaign writes, WITHOUT simulating.

    Keyed by the normalised relative path ``{root}/{vehicle}/{name}``. The first and the last row
    of a file are never dropped, so the span is exact.
    """
    out = {}
    for vid in campaign["_merged"]:
        spec = vehicle_spec(campaign, vid)
        cols = tuple(c for c, _, _ in columns(spec))
        lg = spec["logger"]
        for f in spec["files"]:
            path = posixpath.normpath(f"{root}/{vid}/{f['name']}")
            t = _time_values(spec, np.array([f["t0"], f["t1"]]))
            if lg["time_format"] == "iso":
                t0, t1 = pd.Timestamp(t[0]), pd.Timestamp(t[1])
            else:
                t0, t1 = float(t[0]), float(t[1])
            out[path] = RawLayout(
                path, cols, lg["time_column"], lg["time_format"], t0, t1, float(lg["step_s"])
            )
    return out


# --------------------------------------------------------------------------------------------
# The logged record
# --------------------------------------------------------------------------------------------
def simulate(spec: dict, ideal: bool = False) -> pd.DataFrame:
    """Simulate one vehicle on its logger grid.

    ideal=True: the TRUE states and inputs, no instruments: time_s, T, T_veh, T_o (at the sample
    time), Q_H (heaters + HVAC + fans, eq. 3, mean over the preceding interval), Q_aux (unlogged
    auxiliaries), n_groups_on-equivalent heater power Q_heaters, Q_hvac (true), and T_zone when
    ``poor_mixing`` is declared.
    ideal=False: the full logged record (all files' rows, before splitting into files) with the
    raw column names, numeric values in the logged units, NaN for empty cells, dropped rows
    removed; the time column holds seconds (float) or numpy datetimes.
    """
    r = _run_cached(spec)
    step = spec["logger"]["step_s"]
    m = int(round(step / r["dt"]))
    K = r["N"] // m + 1
    idx = np.arange(K) * m
    t_s = idx * r["dt"]
    heat = r["Q_heat"] + r["Q_hvac"]
    if ideal:
        out = pd.DataFrame(
            {
                "time_s": t_s,
                "T": r["T"][idx],
                "T_veh": r["T_veh"][idx],
                "T_o": r["T_o"][idx],
                "Q_H": _interval_mean(heat + r["Q_fan"], m, K),
                "Q_heaters": _interval_mean(r["Q_heat"], m, K),
                "Q_hvac": _interval_mean(r["Q_hvac"], m, K),
                "Q_aux": _interval_mean(r["Q_aux"], m, K),
            }
        )
        if r["T_zone"] is not None:
            out["T_zone"] = r["T_zone"][idx]
        return out
    return _logged(spec, r, idx, t_s, m, K)


def _logged(spec, r, idx, t_s, m, K) -> pd.DataFrame:
    _, _, rng, rng_drop = _rngs(spec)
    inst = r["spec"]["_inst"]
    lg, se = spec["logger"], spec["sensors"]
    dt = r["dt"]
    heat = r["Q_heat"] + r["Q_hvac"]
    # heat-driven stratification and plume respond within response_s (first-order lag)
    a = math.exp(-dt / se.get("response_s", 120.0))
    q_f = lagged(heat, a, 1 - a, before=heat[0])
    qf_kw = q_f[idx] / 1000.0
    T, Tv, To = r["T"][idx], r["T_veh"][idx], r["T_o"][idx]
    Tz = r["T_zone"][idx] if r["T_zone"] is not None else T
    pm = _deviation(spec, "poor_mixing") or {}
    zone, plume = set(pm.get("zone_sensors", [])), set(pm.get("plume_sensors", []))
    h_ref, s_str = se.get("reference_height_m", 1.1), se.get("stratification_K_per_m_kW", 0.0)
    kelvin = 273.15 if lg["temperature_unit"] == "K" else 0.0
    pn = spec["power_meter"]["noise_rel"]
    scale = meter_scale(spec)  # the meters' common calibration error
    hv = spec["hvac"]
    data: dict[str, np.ndarray] = {}
    for name, kind, i in columns(spec):
        if kind == "time":
            continue
        if kind == "indoor":
            h = se["indoor"]["heights_m"][i - 1]
            v = (Tz if i in zone else T) + inst["indoor_offset"][i - 1]
            v = v + s_str * (h - h_ref) * qf_kw
            if i in plume:
                v = v + pm["plume_K_per_kW"] * qf_kw
            v = v + rng.normal(0, se["indoor"]["noise_K"], K) + kelvin
        elif kind == "surface":
            v = Tv + inst["surface_offset"][i - 1]
            v = v + rng.normal(0, se["surface"]["noise_K"], K) + kelvin
        elif kind == "outdoor":
            v = To + inst["outdoor_offset"][i - 1]
            v = v + rng.normal(0, se["outdoor"]["noise_K"], K) + kelvin
        elif kind == "hvac":  # from the air flow: biased and noisier (section 3.3)
            q = _interval_mean(r["Q_hvac"], m, K) * inst["hvac_bias"]
            v = q * (1 + rng.normal(0, hv.get("airflow_noise_rel", 0.04), K))
        elif kind in ("heater", "heater_total"):
            if kind == "heater":  # the staged thermostat switches groups 1..n in order
                g = r["groups"][i - 1]
                on = np.clip(
                    r["Q_heat"] - np.concatenate([[0], np.cumsum(r["groups"])])[i - 1], 0, g
                )
                q = _interval_mean(on, m, K)
            else:
                q = _interval_mean(r["Q_heat"], m, K)
            v = q * scale * (1 + rng.normal(0, pn, K))
        elif kind in ("fan", "fan_total"):
            q = _interval_mean(r["Q_fan"], m, K)
            if kind == "fan":
                q = q * inst["fan_factor"][i - 1] / inst["fan_factor"][: spec["fans"]["n"]].sum()
            v = q * scale * (1 + rng.normal(0, pn, K))
        elif kind == "humidity":
            v = np.clip(40.0 - 0.8 * (T - To) + rng.normal(0, 1.0, K), 5, 95)
        else:  # wind
            v = np.abs(1.5 + rng.normal(0, 0.2, K))
        if (
            kind in ("hvac",)
            and lg["hvac_unit"] == "kW"
            or (kind in ("heater", "heater_total", "fan", "fan_total") and lg["power_unit"] == "kW")
        ):
            v = v / 1000.0
        data[name] = np.asarray(v, dtype=float)
    df = pd.DataFrame(data)
    # Short dropouts: a few missing rows and a few empty cells, each an isolated single sample
    # (never next to another gap of the same channel, never a file's first/last row), so no
    # channel ever misses more than one logger step.
    cols = list(df.columns)
    dr = spec["dropouts"]
    keep_ends = {0, K - 1}
    step = spec["logger"]["step_s"]
    for f in spec["files"]:
        keep_ends |= {int(f["t0"] // step), int(f["t1"] // step)}
    drop: set[int] = set()
    while len(drop) < dr["missing_rows"]:
        j = int(rng_drop.integers(1, K - 1))
        if j not in keep_ends and not drop & {j - 1, j, j + 1}:
            drop.add(j)
    empty: set[tuple[int, int]] = set()
    while len(empty) < dr["empty_cells"]:
        j, c = int(rng_drop.integers(1, K - 1)), int(rng_drop.integers(0, len(cols)))
        if not drop & {j - 1, j, j + 1} and not empty & {(j - 1, c), (j, c), (j + 1, c)}:
            empty.add((j, c))
            df.iat[j, c] = np.nan
    df.insert(0, lg["time_column"], _time_values(spec, t_s))
    df.insert(0, "_t_s", t_s)
    return df.drop(index=sorted(drop)).reset_index(drop=True)


def _fmt(values: np.ndarray, decimals: int, dec: str) -> list[str]:
    f = f"{{:.{decimals}f}}"
    out = ["" if v != v else f.format(v) for v in values.tolist()]
    if dec == ",":
        out = [s.replace(".", ",") for s in out]
    return out


def write_raw_file(spec: dict, name: str, out_path) -> None:
    """Simulate the vehicle and write the raw file ``name`` (one header row, no comments;
    byte-deterministic, gzip with mtime=0 for ``.gz``)."""
    files = {f["name"]: f for f in spec["files"]}
    if name not in files:
        raise ConfigError(spec["id"], "name", name, f"not one of {sorted(files)}")
    f = files[name]
    df = simulate(spec)
    df = df[(df["_t_s"] >= f["t0"]) & (df["_t_s"] <= f["t1"])]
    lg = spec["logger"]
    dec, sep = lg.get("decimal", "."), lg["separator"]
    cols_out = []
    for col, kind, _ in columns(spec):
        v = df[col].to_numpy()
        if kind == "time":
            if lg["time_format"] == "iso":
                s = list(np.datetime_as_string(v.astype("datetime64[s]"), unit="s"))
            else:
                s = [str(int(x)) for x in v]
        elif kind in ("indoor", "surface", "outdoor"):
            s = _fmt(v, lg.get("temperature_decimals", 2), dec)
        elif kind in ("humidity", "wind"):
            s = _fmt(v, 1, dec)
        else:
            unit = lg["hvac_unit"] if kind == "hvac" else lg["power_unit"]
            s = _fmt(v, 4 if unit == "kW" else 1, dec)
        cols_out.append(s)
    header = sep.join(c for c, _, _ in columns(spec))
    text = header + "\n" + "".join(sep.join(row) + "\n" for row in zip(*cols_out, strict=True))
    raw = text.encode("utf-8")
    out_path = Path(out_path)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    if name.endswith(".gz"):
        buf = io.BytesIO()
        with gzip.GzipFile(filename="", mode="wb", fileobj=buf, mtime=0, compresslevel=6) as gz:
            gz.write(raw)
        raw = buf.getvalue()
    out_path.write_bytes(raw)
