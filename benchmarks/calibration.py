"""Calibration of the 95 % intervals of k, C, K_veh and C_veh on virtual vehicles written by an
independent generator.

    python benchmarks/calibration.py [--count 50] [--seed 20260] [--jobs 2]
        [--settings output_error/static/without,output_error/joint/with,...]
        [--x0 measured|estimated] [--no-offsets] [--no-meter-error] [--no-power-noise]
        [--steady-start]
        [--out fits.csv]
    python benchmarks/calibration.py --from-csv fits-*.csv   # the tables of saved runs

The generator here shares no code with the campaign generator of the package: it simulates
the second-order model (eqs. 7-8)

    C     dT/dt     = kA (T_o - T) + K_veh (T_veh - T) + Q_H
    C_veh dT_veh/dt = K_veh (T - T_veh)

with its own exact zero-order-hold discretisation (matrix exponential of the augmented
system) on a 10 s sub-step, and writes what a test bench would write: one logger CSV per
vehicle at a 60 s step (6 indoor-air, 2 tunnel-air and 4 surface sensors, 4 heater-power
channels in kW) and a vehicle YAML per setting, as a test engineer writes it. Each sensor
reads its state plus a calibration offset drawn with the declared standard uncertainty
(``instruments.temperature_u_K`` = 0.1 K) plus white noise; the power meters share one scale
error drawn with ``instruments.power_u_rel`` = 0.3 % and add white noise; the YAML declares
the noise as a data sheet would (``instruments.outdoor_noise_K`` = 0.05 K,
``instruments.power_noise_rel`` = 0.3 %). The tunnel holds T_o with small, smooth
fluctuations.

Truths per vehicle (log-uniform): k 1.2-3.2 W/(m^2 K), A 150-420 m^2, C 6e6-2.5e7 J/K,
C_veh 4e6-6e7 J/K, K_veh 250-1500 W/K; mass and volume from A as for a rail car.

Programme (70 h): a 10 h heating phase in which a thermostat holds T at its set point
(power computed each minute from the state, so near constant); its last 6 h are the k window
(eq. 10), and the body still takes up heat there: T_veh starts that window 0.05-0.4 K below T
(a fast body, C_veh / K_veh under about 1.5 h, cannot lag so long after 4 h of heating and
starts it closer; the realised lag is in the CSV). Then a heating-power step up held 30 h and
the step back held 30 h, the two identification windows.

Each vehicle is fitted as the study fits it (railtherm.config.load_vehicle, then
railtherm.study.run.tidy_tables -> kvalue.for_vehicle -> identify.identify) once per setting: the
estimator (output_error, kalman) x the mode (static: kA fixed from the static test, eq. 10;
joint: kA estimated with the capacities) x the surface sensors (without: the YAML does not
list them; with: it does, and T_veh is compared in eq. 17). ``--x0`` sets ``model.x0``.

Measured per fit and parameter: the estimate, the truth, the combined 95 % interval
(``ci95``), z = ln(estimate / truth) / sd_log with sd_log the interval's log half-width / 1.96,
and covered = the truth inside the interval and the parameter identified (not at a bound,
interval within a factor 1000). k is the static test's k with k +- 2 u(k) in static mode, as
Table 2 prints it, and kA / A with kA's interval in joint mode (or when the static window
failed its steady-state test and the fit fell back to joint). Printed per setting and
parameter: n, the coverage with its 95 % Wilson interval, mean z (bias in units of the
claimed sd), rms z (1 for honest intervals; above 1 too narrow, below 1 too wide) and the
number not identified; then the seconds per fit per setting.

``--no-offsets``, ``--no-meter-error`` (the meters' common scale error), ``--no-power-noise``
(their white noise) and ``--steady-start`` (no body lag: T_veh = T at the start) switch error
sources off in the generator, to find which one an interval misses; each vehicle keeps its
truth and its true states (drawn first).
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

STEP_S = 60.0  # logger step
SUBSTEP_S = 10.0  # simulation step (exact ZOH)
HEATING_H = 10.0  # heating phase at the set point
KWINDOW_H = 6.0  # its last hours: the static k window (eq. 10)
STEP_H = 30.0  # the heating step up, then the step back, each this long
START = pd.Timestamp("2026-01-05T00:00:00")

RANGES = {  # log-uniform truths
    "k": (1.2, 3.2),
    "A": (150.0, 420.0),
    "C": (6e6, 2.5e7),
    "C_veh": (4e6, 6e7),
    "K_veh": (250.0, 1500.0),
}
U_T_K = 0.1  # declared standard uncertainty of one temperature sensor (calibration offset)
U_POWER_REL = 0.003  # declared relative standard uncertainty of the power meters
NOISE_T_K = 0.05  # white noise of one temperature reading
NOISE_POWER_REL = 0.003  # white noise of one power reading, relative
N_INDOOR, N_OUTDOOR, N_SURFACE, N_HEATER = 6, 2, 4, 4

PARAMETERS = ("k", "C", "K_veh", "C_veh")
ESTIMATORS = ("output_error", "kalman")
MODES = ("static", "joint")
SURFACES = ("without", "with")
ALL_SETTINGS = tuple(f"{e}/{m}/{s}" for e in ESTIMATORS for m in MODES for s in SURFACES)
DEFAULT_SETTINGS = tuple(s for s in ALL_SETTINGS if s.startswith("output_error/"))
UNBOUNDED_FACTOR = 1e3
Z95 = 1.959963984540054
K_COVERAGE_FACTOR = 2.0  # k +- 2 u(k), as Table 2 prints the static k


@dataclass(frozen=True)
class Generator:
    """Which error sources the virtual test bench has."""

    offsets: bool = True
    meter_error: bool = True
    power_noise: bool = True
    steady_start: bool = False


@dataclass(frozen=True)
class Plan:
    """The programme the bench runs: the thermostat's heating phase (its last KWINDOW_H the k
    window), then two held phases compared by the fit. ``powers`` (W, absolute): the two held
    phases' heating; None: the heating phase's last half-hour mean plus the vehicle's dQ,
    then that mean again (the default programme)."""

    heating_h: float = HEATING_H
    up_h: float = STEP_H
    down_h: float = STEP_H
    powers: tuple[float, float] | None = None


PLAN = Plan()


@dataclass(frozen=True)
class Truth:
    """One virtual vehicle: its parameters (SI) and its programme."""

    vehicle: str
    vehicle_class: str
    k: float
    A: float
    C: float
    C_veh: float
    K_veh: float
    mass_kg: float
    volume_m3: float
    T_o: float  # tunnel set point, degC
    T_set: float  # thermostat set point of the heating phase, degC
    dQ: float  # heating step, W
    lag_drawn: float  # T - T_veh at the start of the k window, as drawn (K)
    lag: float  # ... as realised (K)

    @property
    def kA(self) -> float:
        return self.k * self.A


def log_uniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))


def vehicle_rng(seed: int, i: int) -> np.random.Generator:
    """The generator of vehicle ``i``: a stream derived from (seed, i), independent of the
    other vehicles and of the order they are made in."""
    return np.random.default_rng(np.random.SeedSequence([seed, i]))


def vehicle_class(A: float) -> str:
    """A rail class that fits a body of outer surface A (m^2)."""
    for limit, name in ((220.0, "tram"), (290.0, "metro"), (350.0, "regional")):
        if A < limit:
            return name
    return "main-line"


def draw_truth(rng: np.random.Generator, i: int, generator: Generator) -> Truth:
    p = {name: log_uniform(rng, *bounds) for name, bounds in RANGES.items()}
    A = p["A"]
    T_o = float(rng.uniform(-15.0, -5.0))
    T_set = float(rng.uniform(18.0, 24.0))
    dT_step = float(rng.uniform(6.0, 12.0))  # steady rise of T - T_o the step would give
    lag = 0.0 if generator.steady_start else float(rng.uniform(0.05, 0.4))
    return Truth(
        vehicle=f"V{i:03d}",
        vehicle_class=vehicle_class(A),
        k=p["k"],
        A=A,
        C=p["C"],
        C_veh=p["C_veh"],
        K_veh=p["K_veh"],
        mass_kg=float(round(A * rng.uniform(90.0, 150.0))),
        volume_m3=float(round(A * rng.uniform(0.33, 0.42), 1)),
        T_o=T_o,
        T_set=T_set,
        dQ=p["k"] * A * dT_step,
        lag_drawn=lag,
        lag=lag,
    )


def state_space(truth: Truth) -> tuple[np.ndarray, np.ndarray]:
    """Continuous (A, B) of eqs. 7-8, states [T, T_veh], inputs [T_o, Q_H]."""
    kA, C, K, Cv = truth.kA, truth.C, truth.K_veh, truth.C_veh
    A = np.array([[-(kA + K) / C, K / C], [K / Cv, -K / Cv]])
    B = np.array([[kA / C, 1.0 / C], [0.0, 0.0]])
    return A, B


def zoh(A: np.ndarray, B: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact discretisation for inputs held over h: expm of [[A, B], [0, 0]] h."""
    from scipy.linalg import expm

    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n], M[:n, n:] = A, B
    E = expm(M * h)
    return E[:n, :n], E[:n, n:]


def tunnel_air(rng: np.random.Generator, truth: Truth, n_fine: int) -> np.ndarray:
    """T_o on the sub-step grid: the set point plus a smooth fluctuation (an AR(1) process of
    20 min correlation time and 0.1 K sd, smoothed over 5 min)."""
    phi = math.exp(-SUBSTEP_S / 1200.0)
    e = rng.normal(0.0, 0.1 * math.sqrt(1.0 - phi**2), n_fine + 60)
    from scipy.signal import lfilter

    x = lfilter([1.0], [1.0, -phi], e)
    x = np.convolve(x, np.ones(30) / 30.0, mode="valid")[:n_fine]
    return truth.T_o + x


def simulate(
    truth: Truth, rng: np.random.Generator, plan: Plan = PLAN
) -> tuple[pd.DataFrame, Truth]:
    """The true states at the logger's instants and the heating power over each logger step.

    Heating phase (``plan.heating_h``): each minute a thermostat sets the power that brings T
    back to T_set at the minute's end (from the state and the tunnel air at the minute's
    start). Then the power of the phase's last half hour plus dQ for ``plan.up_h``, then that
    power again for ``plan.down_h`` (or the plan's two powers)."""
    A, B = state_space(truth)
    Ad, Bd = zoh(A, B, SUBSTEP_S)
    Am, Bm = zoh(A, B, STEP_S)
    per = int(round(STEP_S / SUBSTEP_S))
    n_steps = int(round((plan.heating_h + plan.up_h + plan.down_h) * 3600 / STEP_S))
    To = tunnel_air(rng, truth, n_steps * per + 1)
    tau_veh = truth.C_veh / truth.K_veh
    pre_s = (plan.heating_h - KWINDOW_H) * 3600.0
    lag0 = min(truth.lag_drawn * math.exp(pre_s / tau_veh), truth.T_set - truth.T_o)
    x = np.array([truth.T_set, truth.T_set - lag0])
    n_heat = int(round(plan.heating_h * 3600 / STEP_S))
    n_kstart = int(round((plan.heating_h - KWINDOW_H) * 3600 / STEP_S))
    n_step = int(round(plan.up_h * 3600 / STEP_S))
    X = np.empty((n_steps + 1, 2))
    Q = np.empty(n_steps + 1)
    lag = math.nan
    for n in range(n_steps):
        X[n] = x
        if n == n_kstart:
            lag = float(x[0] - x[1])
        if n < n_heat:  # the thermostat: T back to T_set at the minute's end
            free = Am[0] @ x + Bm[0, 0] * To[n * per]
            Q[n] = max((truth.T_set - free) / Bm[0, 1], 0.0)
        elif n == n_heat:
            Q_hold = float(np.mean(Q[n_heat - 30 : n_heat]))
            Q_up, Q_down = plan.powers or (Q_hold + truth.dQ, Q_hold)
            Q[n] = Q_up
        else:
            Q[n] = Q_up if n < n_heat + n_step else Q_down
        for j in range(per):
            x = Ad @ x + Bd @ np.array([To[n * per + j], Q[n]])
    X[n_steps] = x
    Q[n_steps] = Q[n_steps - 1]
    t = np.arange(n_steps + 1) * STEP_S
    states = pd.DataFrame({"time": t, "T": X[:, 0], "T_veh": X[:, 1], "T_o": To[::per], "Q_H": Q})
    truth = Truth(**{**asdict(truth), "lag": lag})
    return states, truth


def logger_file(
    states: pd.DataFrame, rng: np.random.Generator, generator: Generator
) -> tuple[pd.DataFrame, dict]:
    """The raw logger CSV: every sensor reads its state + offset + white noise, every heater
    channel its share of Q_H (kW) times the meters' common scale + white noise. Power values
    are the mean over the logger step that starts at their timestamp."""
    n = len(states)
    raw = {
        "timestamp": (START + pd.to_timedelta(states["time"], unit="s")).dt.strftime(
            "%Y-%m-%dT%H:%M:%S"
        )
    }
    errors = {}
    for prefix, state, count in (
        ("indoor_air", "T", N_INDOOR),
        ("tunnel_air", "T_o", N_OUTDOOR),
        ("surface", "T_veh", N_SURFACE),
    ):
        offsets = rng.normal(0.0, U_T_K, count) if generator.offsets else np.zeros(count)
        errors[f"offset_{state}"] = float(offsets.mean())
        for j in range(count):
            noise = rng.normal(0.0, NOISE_T_K, n)
            raw[f"{prefix}_{j + 1}"] = np.round(states[state] + offsets[j] + noise, 3)
    scale = 1.0 + (rng.normal(0.0, U_POWER_REL) if generator.meter_error else 0.0)
    errors["power_scale"] = scale - 1.0
    share = rng.dirichlet(np.full(N_HEATER, 20.0))
    for j in range(N_HEATER):
        q = states["Q_H"].to_numpy() * share[j] * scale
        noise = rng.normal(0.0, NOISE_POWER_REL, n)  # drawn either way: the same later draws
        q = q * (1.0 + (noise if generator.power_noise else 0.0))
        raw[f"heater_{j + 1}"] = np.round(q / 1000.0, 4)
    return pd.DataFrame(raw), errors


def iso(seconds: float) -> str:
    return (START + pd.Timedelta(seconds=seconds)).strftime("%Y-%m-%dT%H:%M:%S")


def vehicle_yaml(
    truth: Truth,
    csv_name: str,
    setting: str,
    x0: str,
    generator: Generator = Generator(),
    plan: Plan = PLAN,
) -> dict:
    """The vehicle file a test engineer writes for this record and setting: the instruments'
    declared accuracies and, where the bench has it, their white noise (a data sheet's
    figures; 0 where the generator has none)."""
    estimator, mode, surface = setting.split("/")
    channels = {
        "indoor_air": [{"column": f"indoor_air_{j + 1}"} for j in range(N_INDOOR)],
        "outdoor_air": [{"column": f"tunnel_air_{j + 1}"} for j in range(N_OUTDOOR)],
        "heater_power": [{"column": f"heater_{j + 1}", "unit": "kW"} for j in range(N_HEATER)],
    }
    if surface == "with":
        channels["surface"] = [{"column": f"surface_{j + 1}"} for j in range(N_SURFACE)]
    heat_end = plan.heating_h * 3600.0
    reversal = heat_end + plan.up_h * 3600.0
    end = reversal + plan.down_h * 3600.0
    return {
        "id": truth.vehicle,
        "class": truth.vehicle_class,
        "description": "Virtual vehicle of the calibration benchmark (benchmarks/calibration.py).",
        "synthetic": True,
        "mass_kg": truth.mass_kg,
        "surface_m2": round(truth.A, 2),
        "volume_m3": truth.volume_m3,
        "raw_files": {"run": csv_name},
        "format": {
            "separator": ",",
            "power_timing": "mean_following",
            "time": {"column": "timestamp", "format": "iso"},
        },
        "channels": channels,
        "instruments": {
            "temperature_u_K": U_T_K,
            "power_u_rel": U_POWER_REL,
            "outdoor_noise_K": NOISE_T_K,
            "power_noise_rel": NOISE_POWER_REL if generator.power_noise else 0.0,
        },
        "windows": {
            "kvalue": {
                "file": "run",
                "start": iso(heat_end - KWINDOW_H * 3600),
                "end": iso(heat_end),
            },
            "identification": [
                {
                    "name": "step_up",
                    "file": "run",
                    "start": iso(heat_end),
                    "end": iso(reversal),
                },
                {
                    "name": "step_down",
                    "file": "run",
                    "start": iso(reversal),
                    "end": iso(end),
                },
            ],
        },
        "model": {"orders": [2], "estimator": estimator, "mode": mode, "x0": x0},
    }


def write_vehicle(
    seed: int, i: int, directory: Path, generator: Generator, plan: Plan = PLAN
) -> tuple[Truth, dict, Path]:
    """Draw vehicle ``i`` of ``seed``, simulate it under ``plan`` and write its raw CSV into
    ``directory``; returns the truth, the drawn instrument errors and the CSV's path."""
    rng = vehicle_rng(seed, i)
    truth = draw_truth(rng, i, generator)
    states, truth = simulate(truth, rng, plan)
    raw, errors = logger_file(states, rng, generator)
    csv = directory / f"{truth.vehicle}_run.csv"
    raw.to_csv(csv, index=False)
    return truth, errors, csv


def write_yaml_file(
    truth: Truth,
    csv: Path,
    setting: str,
    x0: str,
    generator: Generator = Generator(),
    plan: Plan = PLAN,
) -> Path:
    path = csv.parent / f"{truth.vehicle}_{setting.replace('/', '_')}.yaml"
    content = vehicle_yaml(truth, csv.name, setting, x0, generator, plan)
    with open(path, "w", encoding="utf-8") as f:
        yaml.safe_dump(content, f, sort_keys=False)
    return path


def _interval_row(x: float, lo: float, hi: float, truth: float, identified: bool) -> dict:
    sd = (math.log(hi) - math.log(lo)) / (2 * Z95) if lo > 0 and math.isfinite(hi) else math.inf
    bounded = (
        identified
        and math.isfinite(lo)
        and math.isfinite(hi)
        and lo > x / UNBOUNDED_FACTOR
        and hi < x * UNBOUNDED_FACTOR
    )
    z = math.log(x / truth) / sd if 0 < sd < math.inf else math.nan
    return {
        "estimate": x,
        "truth": truth,
        "lo": lo,
        "hi": hi,
        "sd_log": sd,
        "identified": bool(bounded),
        "covered": bool(bounded and lo <= truth <= hi),
        "z": z,
    }


def fit_rows(truth: Truth, yaml_path: Path, setting: str) -> list[dict]:
    """Fit one vehicle file as the study does and compare k, C, K_veh, C_veh with the truth."""
    from railtherm.config import load_vehicle
    from railtherm.estimation import kvalue
    from railtherm.study import fitsettings, identify, run
    from railtherm.study.storage import storage_corrected_k

    vehicle = load_vehicle(yaml_path, workdir=yaml_path.parent)
    started = time.process_time()
    tables = run.tidy_tables(vehicle, workdir=yaml_path.parent)
    k = kvalue.for_vehicle(tables["kvalue"], vehicle.data, source=vehicle.id).to_dict()
    windows = {w["name"]: tables[w["name"]] for w in vehicle.windows["identification"]}
    estimator = setting.split("/")[0]
    model = "order2" if estimator == "output_error" else f"order2{fitsettings.KALMAN_SUFFIX}"
    storage = storage_corrected_k(windows, tables.get("kvalue"), vehicle.data, k)
    estimate, _ = identify.identify(windows, vehicle.data, k, model, storage)
    estimate = estimate.content  # the estimate file as written
    seconds = time.process_time() - started
    parameters = estimate["fit"]["parameters"]
    common = {
        "setting": setting,
        "vehicle": truth.vehicle,
        "k_source": estimate["k_source"],
        "k_usable": bool(k["usable"]),
        "seconds": seconds,
        "lag": truth.lag,
    }
    rows = []

    def static_row(value: float, u: float) -> dict:
        U = K_COVERAGE_FACTOR * u
        row = _interval_row(value, value - U, value + U, truth.k, True)
        row["sd_log"] = u / value  # the claimed sd of k (its interval is k +- 2 u(k))
        row["z"] = math.log(value / truth.k) / row["sd_log"]
        row["sd_log_statistical"] = math.nan
        return row

    if "/static/" in setting and estimate["k_eq10"] is not None:
        # eq. 10 as the standard gives it, wherever the static mode ran it (also where the
        # joint fit replaced the two-stage one)
        rows.append({**common, "parameter": "k_eq10", **static_row(k["k"], k["u_k"])})
    if estimate["k_source"].startswith("static test"):
        # the k that stage two holds (storage-corrected where the correction is made, else
        # eq. 10's)
        if estimate.get("k_corrected") is not None:
            row = static_row(estimate["k_corrected"], estimate["u_k_corrected"])
        else:
            row = static_row(k["k"], k["u_k"])
    else:
        entry = parameters["kA"]
        lo, hi = (c / truth.A for c in entry["ci95"])
        row = _interval_row(
            entry["value"] / truth.A, lo, hi, truth.k, entry.get("identified", True)
        )
        row["sd_log_statistical"] = entry.get("sd_log", math.nan)
    rows.append({**common, "parameter": "k", **row})
    for p in PARAMETERS[1:]:
        entry = parameters[p]
        lo, hi = entry["ci95"]
        row = _interval_row(
            entry["value"], lo, hi, getattr(truth, p), entry.get("identified", False)
        )
        row["sd_log_statistical"] = entry["sd_log"]
        rows.append({**common, "parameter": p, **row})
    return rows


def describe(generator: Generator) -> str:
    """The generator's error sources that are switched off, or that all are on."""
    off = [
        name.replace("_", "-")
        for name, on in asdict(generator).items()
        if (on if name == "steady_start" else not on)
    ]
    return ", ".join(f"--{'' if n == 'steady-start' else 'no-'}{n}" for n in off) or "all on"


def one_vehicle(job: tuple) -> list[dict]:
    seed, i, settings, x0, generator = job
    run = {"seed": seed, "x0": x0, "generator": describe(generator)}
    with tempfile.TemporaryDirectory() as tmp:
        truth, errors, csv = write_vehicle(seed, i, Path(tmp), generator)
        rows = []
        for setting in settings:
            path = write_yaml_file(truth, csv, setting, x0, generator)
            try:
                fitted = fit_rows(truth, path, setting)
            except Exception as err:  # a fit that stops is a miss, reported, not the run's end
                fitted = failed_rows(truth, setting, f"{type(err).__name__}: {err}")
            rows += [{**run, **r, **{f"true_{k}": v for k, v in errors.items()}} for r in fitted]
    return rows


def failed_rows(truth: Truth, setting: str, error: str) -> list[dict]:
    """The rows of a fit that raised: every parameter not identified and not covered."""
    print(f"{truth.vehicle} {setting}: {error}", file=sys.stderr, flush=True)
    common = {"setting": setting, "vehicle": truth.vehicle, "k_source": "failed", "lag": truth.lag}
    return [
        {
            **common,
            "parameter": p,
            "estimate": math.nan,
            "truth": truth.k if p == "k" else getattr(truth, p),
            "identified": False,
            "covered": False,
            "z": math.nan,
            "error": error,
        }
        for p in PARAMETERS
    ]


def proportion_ci(k: int, n: int, method: str = "wilson") -> tuple[float, float]:
    """95 % interval of a proportion k / n by scipy's binomtest ("wilson": Wilson score;
    "exact": Clopper-Pearson); NaN for no trials."""
    if n == 0:
        return math.nan, math.nan
    from scipy.stats import binomtest

    ci = binomtest(k, n).proportion_ci(0.95, method=method)
    return float(ci.low), float(ci.high)


def wilson(k: int, n: int) -> tuple[float, float]:
    """95 % Wilson score interval of a proportion k / n."""
    return proportion_ci(k, n, "wilson")


def summary(df: pd.DataFrame) -> pd.DataFrame:
    """Per setting and parameter: n, coverage with its Wilson interval, mean z, rms z and the
    number not identified."""
    rows = []
    for (setting, p), part in df.groupby(["setting", "parameter"], sort=False):
        n, k = len(part), int(part["covered"].sum())
        lo, hi = wilson(k, n)
        z = part["z"].to_numpy(dtype=float)
        z = z[np.isfinite(z)]
        rows.append(
            {
                "setting": setting,
                "parameter": p,
                "n": n,
                "coverage": k / n,
                "wilson_lo": lo,
                "wilson_hi": hi,
                "mean_z": float(np.mean(z)) if z.size else math.nan,
                "rms_z": float(np.sqrt(np.mean(z**2))) if z.size else math.nan,
                "not_identified": int((~part["identified"]).sum()),
            }
        )
    return pd.DataFrame(rows)


def timings(df: pd.DataFrame) -> pd.DataFrame:
    per_fit = df.drop_duplicates(["setting", "vehicle"]).groupby("setting", sort=False)["seconds"]
    return pd.DataFrame(
        {"fits": per_fit.size(), "median_s": per_fit.median(), "max_s": per_fit.max()}
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=50, help="virtual vehicles")
    parser.add_argument("--first", type=int, default=0, help="index of the first vehicle")
    parser.add_argument("--seed", type=int, default=20260)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument(
        "--settings",
        default=",".join(DEFAULT_SETTINGS),
        help=f"comma-separated estimator/mode/surface; 'all' for {len(ALL_SETTINGS)}",
    )
    parser.add_argument(
        "--x0",
        choices=("measured", "estimated"),
        default="estimated",
        help="model.x0 of every vehicle file (default: estimated, railtherm's default)",
    )
    parser.add_argument("--no-offsets", action="store_true")
    parser.add_argument("--no-meter-error", action="store_true")
    parser.add_argument("--no-power-noise", action="store_true")
    parser.add_argument("--steady-start", action="store_true")
    parser.add_argument("--out", type=Path, default=None, help="per-fit CSV")
    parser.add_argument(
        "--from-csv",
        type=Path,
        nargs="+",
        default=None,
        help="print the tables of per-fit CSV files written with --out (e.g. runs in chunks)",
    )
    args = parser.parse_args(argv)
    settings = ALL_SETTINGS if args.settings == "all" else tuple(args.settings.split(","))
    unknown = [s for s in settings if s not in ALL_SETTINGS]
    if unknown:
        parser.error(f"unknown setting {unknown[0]!r}; known: {', '.join(ALL_SETTINGS)}")
    generator = Generator(
        offsets=not args.no_offsets,
        meter_error=not args.no_meter_error,
        power_noise=not args.no_power_noise,
        steady_start=args.steady_start,
    )
    if args.from_csv:
        df = pd.concat([pd.read_csv(f) for f in args.from_csv], ignore_index=True)
        df = df.drop_duplicates(["seed", "x0", "generator", "setting", "vehicle", "parameter"])
    else:
        jobs = [
            (args.seed, i, settings, args.x0, generator)
            for i in range(args.first, args.first + args.count)
        ]
        df = pd.DataFrame(collect(one_vehicle, jobs, args.jobs, "vehicle"))
    if args.out:
        df.to_csv(args.out, index=False, float_format="%.6g")
    report(df)


def collect(function, jobs: list, workers: int, label: str) -> list[dict]:
    """The rows of ``function`` over ``jobs`` in ``workers`` processes, in the jobs' order,
    with a progress line per finished job on stderr."""
    rows: list[dict] = []
    with ProcessPoolExecutor(max_workers=workers) as pool:
        for done, part in enumerate(pool.map(function, jobs), start=1):
            rows += part
            print(f"{label} {done}/{len(jobs)} done", file=sys.stderr, flush=True)
    return rows


def vehicle_ranges(numbers: list[int]) -> str:
    """Sorted vehicle numbers as runs: [0, 1, 2, 25] -> "V000-V002, V025"."""
    runs = np.split(np.asarray(numbers), np.flatnonzero(np.diff(numbers) != 1) + 1)
    return ", ".join(f"V{r[0]:03d}" if len(r) == 1 else f"V{r[0]:03d}-V{r[-1]:03d}" for r in runs)


def report(df: pd.DataFrame) -> None:
    """Print the run's description, the summary per setting and parameter, and the timings."""
    numbers = sorted(int(v[1:]) for v in df["vehicle"].unique())
    runs = df[["seed", "x0", "generator"]].drop_duplicates().astype(str)
    print(
        "; ".join(
            f"seed {r.seed}, x0 {r.x0}, generator error sources: {r.generator}"
            for r in runs.itertuples()
        )
        + f"; {len(numbers)} vehicles ({vehicle_ranges(numbers)})"
    )
    print()
    fmt = {c: "{:.3f}".format for c in ("coverage", "wilson_lo", "wilson_hi")}
    fmt |= {"mean_z": "{:+.2f}".format, "rms_z": "{:.2f}".format}
    print(summary(df).to_string(index=False, formatters=fmt))
    if "error" in df.columns:
        failed = df.loc[df["error"].notna(), ["setting", "vehicle", "error"]].drop_duplicates()
        print()
        print(f"fits that stopped with an error ({len(failed)}; counted as not identified):")
        print(failed.to_string(index=False))
    print()
    print("CPU seconds per fit (k test + identification):")
    print(timings(df).to_string(float_format="{:.1f}".format))


if __name__ == "__main__":
    main()
