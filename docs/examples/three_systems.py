"""A tunnel's record from three data-acquisition systems, as the systems write it: the cabin's
thermocouples every 30 s with ISO times at UTC+01:00; the heater's power analyser every second
in kW, tab-separated under `#` comment lines, its time counted from its own start 137 s before
the loggers; the tunnel controller every 60 s, `;`-separated with decimal commas, in UTC, its
clock 40 s fast. The record itself is eqs. 7-8 integrated exactly over 1 s steps, written
without railtherm (the example of docs/adding-a-vehicle.md, section 8, and the reference of
tests/test_sources.py).

    python docs/examples/three_systems.py my/tunnel

writes my/tunnel/cabin.csv, power_meter.txt and tunnel.csv.
"""

from __future__ import annotations

import datetime as dt
import math
import sys
from pathlib import Path

import numpy as np
from scipy.linalg import expm

# the truth (eqs. 7-8): a metro car in the tunnel
TRUTH = {"kA": 1200.0, "C": 4.0e6, "K_veh": 2500.0, "C_veh": 2.4e7}
MASS_KG, SURFACE_M2 = 30_000.0, 700.0
HOURS = 30
CABIN_START = dt.datetime(2026, 3, 2, 9, 0, 0, tzinfo=dt.timezone(dt.timedelta(hours=1)))
METER_EARLY_S = 137.0  # the power analyser was started 137 s before the loggers
TUNNEL_FAST_S = 40.0  # the tunnel controller's clock runs 40 s ahead
# heater programme (kW) by the hour it starts: 7 h steady at 30 kW (the static k test's
# window), then steps; the tunnel air ramps from -10 to 0 degC over half an hour from 18 h
HEATER_KW = [(-1, 30.0), (7, 12.0), (10, 36.0), (14, 0.0), (17, 24.0), (22, 8.0), (26, 30.0)]
TUNNEL_STEP_H, T_O_BEFORE, T_O_AFTER = 18.0, -10.0, 0.0


def true_record(seed: int = 5) -> dict[str, np.ndarray]:
    """Eqs. 7-8 integrated exactly over 1 s steps (zero-order hold on 1 s power and tunnel
    air), from the steady state of the first heater power: true time t (s from the cabin
    start)."""
    rng = np.random.default_rng(seed)
    kA, C, K, Cv = (TRUTH[p] for p in ("kA", "C", "K_veh", "C_veh"))
    A = np.array([[-(kA + K) / C, K / C], [K / Cv, -K / Cv]])
    B = np.array([[kA / C, 1.0 / C], [0.0, 0.0]])
    M = np.zeros((4, 4))
    M[:2, :2], M[:2, 2:] = A, B
    E = expm(M)  # one second
    Ad, Bd = E[:2, :2], E[:2, 2:]
    t = np.arange(-200.0, HOURS * 3600.0 + 200.0)  # covers the early meter and the late clock
    hour = t / 3600.0
    q = np.zeros_like(t)
    for start, kw in HEATER_KW:
        q[hour >= start] = kw * 1000.0
    q *= 1.0 + 0.01 * rng.standard_normal(t.size)  # the heater's ripple, measured as it is
    ramp = np.clip((hour - TUNNEL_STEP_H) / 0.5, 0.0, 1.0)
    T_o = T_O_BEFORE + (T_O_AFTER - T_O_BEFORE) * ramp
    T_o = T_o + 0.03 * np.cumsum(rng.standard_normal(t.size)) / math.sqrt(t.size)
    steady = T_O_BEFORE + HEATER_KW[0][1] * 1000.0 / kA  # eqs. 7-8 at rest: T = T_veh
    x = np.array([steady, steady])
    T = np.empty(t.size)
    T_veh = np.empty(t.size)
    a00, a01, a10, a11 = Ad.ravel()
    b00, b01, b10, b11 = Bd.ravel()
    x0, x1 = x
    for n in range(t.size):
        T[n], T_veh[n] = x0, x1
        u0, u1 = T_o[n], q[n]
        x0, x1 = (
            a00 * x0 + a01 * x1 + b00 * u0 + b01 * u1,
            a10 * x0 + a11 * x1 + b10 * u0 + b11 * u1,
        )
    return {"t": t, "T": T, "T_veh": T_veh, "T_o": T_o, "Q": q}


def write_three_systems(folder: Path, seed: int = 5) -> dict[str, Path]:
    """The three systems' files of one record (the module docstring)."""
    r = true_record(seed)
    rng = np.random.default_rng(seed + 1)
    t = r["t"]
    folder.mkdir(parents=True, exist_ok=True)
    # cabin loggers: every 30 s from the cabin start, ISO at +01:00, four air and two surface
    # thermocouples with small offsets and noise
    rows = ["time,TC01,TC02,TC03,TC04,T_Wand_1,T_Wand_2"]
    offsets = [0.05, -0.04, 0.02, -0.03, 0.04, -0.04]
    for s in np.arange(0.0, HOURS * 3600.0 + 1.0, 30.0):
        i = int(s - t[0])
        stamp = (CABIN_START + dt.timedelta(seconds=float(s))).isoformat()
        air = [r["T"][i] + o + 0.03 * rng.standard_normal() for o in offsets[:4]]
        body = [r["T_veh"][i] + o + 0.03 * rng.standard_normal() for o in offsets[4:]]
        rows.append(stamp + "," + ",".join(f"{v:.3f}" for v in air + body))
    cabin = folder / "cabin.csv"
    cabin.write_text("\n".join(rows) + "\n", encoding="utf-8")
    # power analyser: every second, its own elapsed seconds, kW, tab-separated, comment lines
    lines = [
        "# Power analyser PA-3000, serial 0417",
        "# channel 1: cabin heater (3~400 V)",
        "# integration 1 s",
        "# started by hand",
        "t_s\tP_heater_kW",
    ]
    for s in np.arange(-METER_EARLY_S, HOURS * 3600.0 + 60.0, 1.0):
        i = int(s - t[0])
        lines.append(f"{s + METER_EARLY_S:.0f}\t{r['Q'][i] / 1000.0:.4f}")
    power = folder / "power_meter.txt"
    power.write_text("\n".join(lines) + "\n", encoding="utf-8")
    # tunnel controller: every 60 s in UTC without an offset, its clock 40 s fast, ';' and
    # decimal commas, two air sensors
    rows = ["Zeit;T_Luft_1;T_Luft_2"]
    utc0 = CABIN_START.astimezone(dt.UTC).replace(tzinfo=None)
    for s in np.arange(0.0, HOURS * 3600.0 + 1.0, 60.0):
        i = int(s - t[0])
        shown = utc0 + dt.timedelta(seconds=float(s) + TUNNEL_FAST_S)
        a = r["T_o"][i] + 0.02 * rng.standard_normal()
        b = r["T_o"][i] + 0.02 * rng.standard_normal()
        rows.append(f"{shown:%Y-%m-%d %H:%M:%S};{a:.3f};{b:.3f}".replace(".", ","))
    tunnel = folder / "tunnel.csv"
    tunnel.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return {"cabin": cabin, "power": power, "tunnel": tunnel}


if __name__ == "__main__":
    folder = Path(sys.argv[1] if len(sys.argv) > 1 else "my/tunnel")
    for name, path in write_three_systems(folder).items():
        print(f"{name}: {path}")
