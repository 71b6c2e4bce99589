"""The verdict's false-alarm rate per criterion on correctly specified records of the
independent generator.

    python benchmarks/false_alarms.py [--records 100] [--seed 20260] [--first 0] [--jobs 2]
        [--settings output_error/static/without,kalman/static/without,...] [--out fits.csv]
    python benchmarks/false_alarms.py --from-csv fits-*.csv   # the table of saved runs

The records are those of benchmarks/calibration.py (its generator shares no code with the
package's railtherm.synth): the second-order model (eqs. 7-8) simulated exactly, the sensors'
calibration offsets and white noise and the power meters' scale error and noise drawn as
the vehicle file declares them. The model the study fits is the one that made the data, and
every error source is declared: a verdict "assumptions in doubt" on such a record is a false
alarm.

Each record is fitted as the study fits it (railtherm.study.run.tidy_tables ->
kvalue.for_vehicle -> storage.storage_corrected_k -> identify.identify) and judged as the
rule ``check`` judges it (quality.check with the vehicle's ``check`` section, here the
defaults), once per setting (estimator/mode/surface sensors, as in calibration.py). Printed
per setting and criterion family (quality.CRITERIA): the fits the criterion applies to,
those it put in doubt, the share with its exact (Clopper-Pearson) binomial 95 % interval,
and the same for the verdict as a whole (any criterion); then every reason given, for
reading. A criterion family that runs several tests (whiteness over outputs and tests) is
judged at its stated level as a family (Holm), so its share should lie at or below that
level (0.05); beside it, the share the same fits would have had with each test judged
alone at that level (from the p-values kept per fit), and the share the k method would have
had with the joint fit's replacing a two-stage fit a reason (from the fit's k_source).
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))

import calibration  # noqa: E402  (the independent generator, beside this file)

# output error in the study's default mode (static: kA from eq. 10, checked against the joint
# fit) without surface sensors (one compared output) and with them (two); the Kalman fit with
# them (its innovations face four whiteness tests), in joint mode, where a fit costs half
DEFAULT_SETTINGS = (
    "output_error/static/without",
    "output_error/static/with",
    "kalman/joint/with",
)
LEVEL = 0.05  # the family-wise level the verdict's tests are judged at (whiteness_alpha)


def fitted(yaml_path: Path, setting: str, kA: float | None = None):
    """Fit one record as the study does: its estimate, series and judged fit (``kA``: the
    static kA replaced by this value, to see what its error does)."""
    from railtherm.config import load_vehicle
    from railtherm.estimation import kvalue
    from railtherm.study import fitsettings, identify, quality, run
    from railtherm.study.storage import storage_corrected_k

    vehicle = load_vehicle(yaml_path, workdir=yaml_path.parent)
    tables = run.tidy_tables(vehicle, workdir=yaml_path.parent)
    k = kvalue.for_vehicle(tables["kvalue"], vehicle.data, source=vehicle.id).to_dict()
    windows = {w["name"]: tables[w["name"]] for w in vehicle.windows["identification"]}
    estimator = setting.split("/")[0]
    model = "order2" if estimator == "output_error" else f"order2{fitsettings.KALMAN_SUFFIX}"
    storage = storage_corrected_k(windows, tables.get("kvalue"), vehicle.data, k)
    if kA is not None:
        storage = {**storage, "kA_corrected": float(kA)}
    estimate, series = identify.identify(windows, vehicle.data, k, model, storage)
    return estimate, series, quality.check(estimate, series, vehicle.data.get("check"))


def judge(truth, yaml_path: Path, setting: str) -> dict:
    """Fit one record as the study does and judge it: the verdict, per criterion whether it
    applied and passed, and the reasons."""
    estimate, _, checked = fitted(yaml_path, setting)
    row = {
        "setting": setting,
        "vehicle": truth.vehicle,
        "k_source": estimate.k_source,
        "verdict": checked.verdict,
        "reasons": " | ".join(checked.reasons),
    }
    for c in checked.criteria:
        row[f"applies_{c['criterion']}"] = bool(c["applies"])
        row[f"failed_{c['criterion']}"] = bool(c["applies"] and not c["passed"])
    for state, t in checked.section("innovations").items():
        row[f"ljung_box_p_{state}"] = t["ljung_box_p"]
        row[f"cpg_p_{state}"] = t["cpg_p"]
    return row


def one_record(job: tuple) -> list[dict]:
    seed, i, settings = job
    generator = calibration.Generator()
    with tempfile.TemporaryDirectory() as tmp:
        truth, _, csv = calibration.write_vehicle(seed, i, Path(tmp), generator)
        rows = []
        for setting in settings:
            path = calibration.write_yaml_file(truth, csv, setting, "estimated", generator)
            try:
                row = judge(truth, path, setting)
            except Exception as err:  # a fit that stops is reported, not the run's end
                print(f"{truth.vehicle} {setting}: {err}", file=sys.stderr, flush=True)
                row = {
                    "setting": setting,
                    "vehicle": truth.vehicle,
                    "verdict": "stopped",
                    "error": f"{type(err).__name__}: {err}",
                }
            rows.append({"seed": seed, **row})
    return rows


def interval(k: int, n: int) -> tuple[float, float]:
    """Exact (Clopper-Pearson) binomial 95 % interval of k / n."""
    return calibration.proportion_ci(k, n, "exact")


def table(df: pd.DataFrame) -> pd.DataFrame:
    """Per setting and criterion family (and the verdict as a whole): fits judged, fits in
    doubt, their share and its 95 % interval."""
    from railtherm.study.identify import STATIC_CONTRADICTED, STATIC_UNDETERMINED
    from railtherm.study.quality import CRITERIA

    rows = []
    for setting, part in df.groupby("setting", sort=False):
        judged = part[part["verdict"] != "stopped"]
        families = [(c, CRITERIA[c]) for c in CRITERIA if f"applies_{c}" in judged]
        for criterion, label in [*families, ("any", "verdict (any criterion)")]:
            if criterion == "any":
                n = len(judged)
                k = int((judged["verdict"] != "fit acceptable").sum())
            else:
                applies = judged[f"applies_{criterion}"].astype(bool)
                n = int(applies.sum())
                k = int(judged.loc[applies, f"failed_{criterion}"].astype(bool).sum())
            rows.append(row(setting, label, k, n))
            if criterion == "k_stage" and n:
                # the same fits with the joint fit's replacing the two-stage one a reason
                replaced = (
                    judged["k_source"]
                    .astype(str)
                    .str.contains(f"{STATIC_UNDETERMINED}|{STATIC_CONTRADICTED}")
                )
                k_old = int((replaced | judged["failed_k_stage"].astype(bool)).sum())
                rows.append(
                    row(setting, f"({label}: a replacement by the joint fit too)", k_old, n)
                )
            tests = [c for c in judged if c.startswith(("ljung_box_p_", "cpg_p_"))]
            if criterion == "innovations_white" and n and tests:
                # the same fits judged test by test at the level, as before the family
                p = judged.loc[judged[f"applies_{criterion}"].astype(bool), tests]
                single = int((p.astype(float) < LEVEL).any(axis=1).sum())
                rows.append(row(setting, f"({label}: each test alone at {LEVEL:g})", single, n))
    return pd.DataFrame(rows)


def row(setting: str, criterion: str, k: int, n: int) -> dict:
    lo, hi = interval(k, n)
    return {
        "setting": setting,
        "criterion": criterion,
        "fits": n,
        "in_doubt": k,
        "share": k / n if n else math.nan,
        "ci95_lo": lo,
        "ci95_hi": hi,
    }


def report(df: pd.DataFrame) -> None:
    records = sorted(int(v[1:]) for v in df["vehicle"].unique())
    seeds = ", ".join(str(s) for s in sorted(df["seed"].unique()))
    print(
        f"seed {seeds}; {len(records)} records ({calibration.vehicle_ranges(records)}) of "
        "benchmarks/calibration.py, every error source on, model.x0 estimated, the default "
        "check thresholds"
    )
    print()
    fmt = {c: "{:.3f}".format for c in ("share", "ci95_lo", "ci95_hi")}
    print(table(df).to_string(index=False, formatters=fmt))
    stopped = df[df["verdict"] == "stopped"]
    if len(stopped):
        print()
        print(f"fits that stopped with an error ({len(stopped)}; not counted above):")
        print(stopped[["setting", "vehicle", "error"]].to_string(index=False))
    doubted = df[(df["verdict"] != "fit acceptable") & (df["verdict"] != "stopped")]
    print()
    print(f"reasons of the fits in doubt ({len(doubted)}):")
    for r in doubted.itertuples():
        print(f"- {r.setting} {r.vehicle}: {r.reasons}")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--records", type=int, default=100, help="virtual vehicles")
    parser.add_argument("--first", type=int, default=0, help="index of the first vehicle")
    parser.add_argument("--seed", type=int, default=20260)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument(
        "--settings",
        default=",".join(DEFAULT_SETTINGS),
        help="comma-separated estimator/mode/surface (benchmarks/calibration.py's settings)",
    )
    parser.add_argument("--out", type=Path, default=None, help="per-fit CSV")
    parser.add_argument("--from-csv", type=Path, nargs="+", default=None)
    args = parser.parse_args(argv)
    settings = tuple(args.settings.split(","))
    unknown = [s for s in settings if s not in calibration.ALL_SETTINGS]
    if unknown:
        parser.error(
            f"unknown setting {unknown[0]!r}; known: {', '.join(calibration.ALL_SETTINGS)}"
        )
    if args.from_csv:
        df = pd.concat([pd.read_csv(f) for f in args.from_csv], ignore_index=True)
        df = df.drop_duplicates(["seed", "setting", "vehicle"])
    else:
        jobs = [(args.seed, i, settings) for i in range(args.first, args.first + args.records)]
        df = pd.DataFrame(calibration.collect(one_record, jobs, args.jobs, "record"))
    if args.out:
        df.to_csv(args.out, index=False, float_format="%.6g")
    report(df)


if __name__ == "__main__":
    main()
