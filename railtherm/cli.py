"""The ``railtherm`` command line.

``railtherm validate [--config config/config.yaml] [--headers-only] [VEHICLE.yaml ...]`` checks
the study config and every vehicle it lists (or only the vehicle files given, with the study's
defaults and campaign layouts when the study config exists), then reads every value of their
raw files as the jobs ``clean`` and ``kvalue`` will (:mod:`railtherm.datacheck`). It prints
``ok: N vehicles, ...`` and exits 0, or prints the one-line error on stderr and exits 1.

``railtherm fit VEHICLE.yaml [--model order2] [--out DIR]`` runs one vehicle through the
rules' chain (clean -> static k -> PEM fit -> check, :mod:`railtherm.run`), prints each fit's
parameters and verdict and, with ``--out``, writes the rules' files. A raw file that the study's
virtual wind tunnel plans but has not written is written first.

``railtherm audit PUBLISHED.yaml [--ranges config/audit.yaml] [--estimates results/tables]
[--out results/audit] [--fail-on never|error|warning]`` runs the audit of published values
(:mod:`railtherm.audit`) without the rest of the pipeline.

``railtherm new-vehicle RAW.csv [--out VEHICLE.yaml] [--id ID]`` writes a starter vehicle YAML
for a raw logger file (:mod:`railtherm.starter`): the detected separator, decimal mark and time
format, a guess of the channel map from the column names, one identification window over the
whole file, and TODOs for what the file cannot tell, which ``railtherm validate`` refuses until
they are filled. It never overwrites a file; without ``--out`` it prints the YAML.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from railtherm import __version__, starter
from railtherm.config import Study, add_vehicle, load_study, read_yaml, study_context
from railtherm.errors import ConfigError, RailthermError


def _study(args: argparse.Namespace, vehicles: Sequence[str]) -> Study:
    """The study config's vehicles, or only ``vehicles`` under its defaults and campaign
    layouts (loose vehicle files need no study config)."""
    workdir = args.directory
    config_local = os.path.normpath(os.path.join(workdir, args.config))
    if vehicles and not os.path.isfile(config_local):
        study = Study(vehicles={}, campaign=None)
    else:
        config = read_yaml(config_local, display=args.config)
        if not vehicles:
            study = load_study(config, workdir=workdir, config_file=args.config)
        else:
            study = study_context(config, workdir=workdir, config_file=args.config)
    for path in vehicles:
        add_vehicle(study, os.path.join(workdir, path), workdir=workdir)
    return study


def _references(args: argparse.Namespace, study: Study) -> int:
    """Check the study's reference files (``study.references``) against its fits; how many."""
    config = read_yaml(os.path.join(args.directory, args.config), display=args.config)
    paths = ((config or {}).get("study") or {}).get("references") or []
    if paths:
        from railtherm import identify, reference

        fits = [
            (vid, key) for vid, v in study.vehicles.items() for key in identify.model_keys(v.data)
        ]
        reference.study_references(paths, fits, workdir=args.directory)
    return len(paths)


def _validate(args: argparse.Namespace) -> int:
    workdir = args.directory
    study = _study(args, args.vehicles)
    references = 0 if args.vehicles else _references(args, study)
    count = len(study.vehicles)
    summary = f"ok: {count} vehicle{'' if count == 1 else 's'}"
    if references:
        summary += f", {references} reference file{'' if references == 1 else 's'}"
    if not args.headers_only:
        from railtherm.datacheck import check_values  # pandas only when reading values

        windows, not_written = 0, []
        for vehicle in study.vehicles.values():
            checked = check_values(vehicle, workdir=workdir)
            windows += len(checked.windows)
            not_written += checked.not_written
            for warning in checked.warnings:
                print(f"warning: {warning}", file=sys.stderr)
        summary += f", values of {windows} window{'' if windows == 1 else 's'} checked"
        if not_written:
            summary += (
                f" ({len(not_written)} raw file{'' if len(not_written) == 1 else 's'} not "
                "written yet: the clean job checks them)"
            )
    print(summary)
    return 0


def _audit(args: argparse.Namespace) -> int:
    from railtherm import audit  # pandas only when auditing

    estimates = args.estimates
    if estimates is not None and not os.path.isfile(os.path.join(estimates, "table2.csv")):
        raise ConfigError(
            "--estimates", "(directory)", estimates, "holds no table2.csv of re-estimates"
        )
    findings = audit.audit(args.published, args.ranges, estimates, args.out)
    counts = findings["severity"].value_counts()
    summary = ", ".join(f"{counts.get(s, 0)} {s}" for s in audit.SEVERITIES)
    print(f"{args.out}/findings.csv, {args.out}/audit.md: {summary}")
    fail = {"never": (), "error": ("error",), "warning": ("error", "warning")}[args.fail_on]
    return 1 if any(counts.get(s, 0) for s in fail) else 0


def _campaign_files(study: Study, workdir: str) -> list[str]:
    """Write the raw files of the study's vehicles that the virtual wind tunnel plans but has
    not written yet (what rule ``synthesize`` does); the paths written."""
    if not study.campaign_data:
        return []
    from railtherm import synth  # only studies with a campaign need the generator

    written = []
    for vid in study.campaign_data["vehicles"]:
        spec = synth.vehicle_spec(study.campaign_data, vid)
        for name in synth.raw_file_names(spec):
            path = os.path.normpath(f"resources/campaign/{vid}/{name}")
            local = os.path.join(workdir, path)
            wanted = any(path in v.raw_files.values() for v in study.vehicles.values())
            if wanted and not os.path.isfile(local):
                synth.write_raw_file(spec, name, local)
                written.append(path)
    return written


def _fit(args: argparse.Namespace) -> int:
    from railtherm.run import fit_vehicle  # numpy, scipy and pandas only when fitting

    study = _study(args, [args.vehicle])
    for path in _campaign_files(study, args.directory):
        print(f"{path}: written by the virtual climatic wind tunnel (synthetic)")
    (vehicle,) = study.vehicles.values()
    out = None if args.out is None else os.path.join(args.directory, args.out)
    result = fit_vehicle(vehicle, args.model, out=out, workdir=args.directory)
    if result.kvalue is not None:
        k = result.kvalue
        value = (
            f"kA = {k.kA:.4g} +- {k.u_kA:.2g} W/K (eq. 10; k not given: no surface_m2)"
            if k.k is None
            else f"k = {k.k:.4g} +- {k.u_k:.2g} W/(m2 K) (eq. 10)"
        )
        print(
            f"{vehicle.id}: {value}, "
            f"{'steady' if k.steady else 'not steady'}{', forced' if k.forced else ''}"
        )
    for fit in result.fits.values():
        print(fit.summary())
    if out:
        print(f"written to {os.path.join(out, 'vehicles', vehicle.id)}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with one subparser per command."""
    parser = argparse.ArgumentParser(
        prog="railtherm",
        description="Thermal parameters of rail vehicles from climatic-wind-tunnel data.",
    )
    parser.add_argument("--version", action="version", version=f"railtherm {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")

    validate = commands.add_parser(
        "validate",
        help="check the study config and vehicle configs against their raw files",
        description=(
            "Check the study config and every vehicle it lists (or only the VEHICLE files "
            "given). Prints 'ok: N vehicles' or one line naming the file, key and value."
        ),
    )
    validate.add_argument(
        "--config",
        default="config/config.yaml",
        help="study config, relative to the working directory (default: %(default)s)",
    )
    validate.add_argument(
        "-d",
        "--directory",
        default=".",
        help="working directory the config's paths are relative to (default: %(default)s)",
    )
    validate.add_argument(
        "--headers-only",
        action="store_true",
        help=(
            "check configs against the raw files' headers and time columns only, as "
            "Snakemake's parse does (default: also read every value as the jobs will)"
        ),
    )
    validate.add_argument("vehicles", nargs="*", metavar="VEHICLE.yaml", help="vehicle files")
    validate.set_defaults(run=_validate)
    starter.register(commands)

    audit = commands.add_parser(
        "audit",
        help="audit a set of published values (consistency, plausibility, fitness, units)",
        description=(
            "Run the audit checks on PUBLISHED.yaml (the format of config/published/paper.yaml) "
            "and write findings.csv and audit.md to --out. Without the rest of the pipeline; "
            "with --estimates, also the published values beside railtherm's re-estimates."
        ),
    )
    audit.add_argument("published", metavar="PUBLISHED.yaml", help="published values")
    audit.add_argument(
        "--ranges",
        default="config/audit.yaml",
        help="class-typical ranges and thresholds (default: %(default)s)",
    )
    audit.add_argument(
        "--estimates",
        metavar="DIR",
        help="directory with table2.csv (and table3.csv) of re-estimates, e.g. results/tables",
    )
    audit.add_argument(
        "--out", default="results/audit", help="output directory (default: %(default)s)"
    )
    audit.add_argument(
        "--fail-on",
        choices=["never", "error", "warning"],
        default="never",
        help="exit 1 if there are findings of this severity or worse (default: %(default)s)",
    )
    audit.set_defaults(run=_audit)

    fit = commands.add_parser(
        "fit",
        help="one vehicle through clean, static k, fit and check, without the workflow",
        description=(
            "Clean the windows of VEHICLE.yaml, compute the static k (eq. 10), fit each model "
            "by simulation-error PEM and judge it, as the workflow's rules do; print the "
            "parameters with their 95 %% intervals and the verdict. With --out, write the "
            "rules' files under DIR/vehicles/<id>/."
        ),
    )
    fit.add_argument("vehicle", metavar="VEHICLE.yaml", help="vehicle file")
    fit.add_argument(
        "--model",
        action="append",
        choices=[
            key + suffix
            for key in ("order1", "order2", "interior_envelope")
            for suffix in ("", "_kalman")
        ],
        help=(
            "model to fit (repeatable; default: the models the vehicle file asks for); the "
            "suffix _kalman fits it by the Kalman-filter estimator"
        ),
    )
    fit.add_argument("--out", metavar="DIR", help="results directory to write into")
    fit.add_argument(
        "--config",
        default="config/config.yaml",
        help="study config whose defaults apply, if it exists (default: %(default)s)",
    )
    fit.add_argument(
        "-d",
        "--directory",
        default=".",
        help="working directory all paths are relative to (default: %(default)s)",
    )
    fit.set_defaults(run=_fit)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 ok, 1 user mistake, 2 usage)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help(sys.stderr)
        return 2
    try:
        return args.run(args)
    except RailthermError as exc:
        print(exc, file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
