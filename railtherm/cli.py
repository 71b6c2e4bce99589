"""The ``railtherm`` command line.

``railtherm validate [--config config/config.yaml] [--headers-only] [VEHICLE.yaml ...]`` checks
the study config and every vehicle it lists (or only the vehicle files given, with the study's
defaults and campaign layouts when the study config exists), then reads every value of their
raw files as the jobs ``clean`` and ``kvalue`` will (:mod:`railtherm.data.datacheck`). It prints
``ok: N vehicles, ...`` and exits 0, or prints the one-line error on stderr and exits 1.

``railtherm fit VEHICLE.yaml [--model order2] [--out DIR]`` runs one vehicle through the
rules' chain (clean -> static k -> PEM fit -> check, :mod:`railtherm.study.run`), prints each fit's
parameters and verdict and, with ``--out``, writes the rules' files. A raw file that the study's
virtual wind tunnel plans but has not written is written first.

``railtherm audit PUBLISHED.yaml [--ranges config/audit.yaml] [--estimates results/tables]
[--out results/audit] [--fail-on never|error|warning]`` runs the audit of published values
(:mod:`railtherm.report.audit`) without the rest of the pipeline.

``railtherm new-vehicle RAW.csv [--out VEHICLE.yaml] [--id ID]`` writes a starter vehicle YAML
for a raw logger file (:mod:`railtherm.data.starter`): the detected separator, decimal mark and time
format, a guess of the channel map from the column names, one identification window over the
whole file, and TODOs for what the file cannot tell, which ``railtherm validate`` refuses until
they are filled. It never overwrites a file; without ``--out`` it prints the YAML.

``railtherm reference --class CLASS --mass-kg M --surface-m2 A [--k K] [--min-vehicles 2]
[--exclude ID ...] [--config config/config.yaml] [--results results] [--out FILE]`` builds the
second-order model of an unmeasured vehicle from its class's generalised parameters
(:mod:`railtherm.study.classmodel`: c_veh, delta, kappa_veh and k over the class's usable vehicles
of the committed ``results/tables/table2.csv``), with 95 % prediction intervals; it prints a
summary and writes the YAML to ``--out`` (without ``--out``, prints the YAML).

``railtherm simulate PARAMS.yaml --scenario S.yaml [--scenario S2.yaml ...] [--draws 200]
[--seed 0] [--out DIR] [--allow-unreachable]`` runs each scenario (:mod:`railtherm.study.scenario`)
through a checked fit (``fit_<model>.yaml``) or a class reference model
(:mod:`railtherm.study.simulate`) and prints its heat-up and cool-down times, energy, peak power and
final temperature with 95 % bands from ``--draws`` parameter draws. With ``--out``, writes
``DIR/<scenario name>.csv`` (the series) and ``DIR/<scenario name>.yaml`` (the outcomes), and
nothing if any scenario fails. A set point the heating cannot hold is an error unless
``--allow-unreachable``.

Every subcommand's paths are relative to its ``-d`` working directory; a user mistake is one
line on stderr and exit status 1.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import sys
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

from railtherm import __version__, structures
from railtherm.config import Study, add_vehicle, load_study, read_yaml, study_context
from railtherm.data import starter
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


def _study_config(args: argparse.Namespace) -> dict:
    """The study config ``validate`` checks (read by railtherm's own loader)."""
    return read_yaml(os.path.join(args.directory, args.config), display=args.config) or {}


def _references(args: argparse.Namespace, study: Study, config: dict) -> int:
    """Check the study's reference files (``study.references``) against its fits; how many."""
    paths = ((config or {}).get("study") or {}).get("references") or []
    if paths:
        from railtherm.study import fitsettings, reference

        fits = [
            (vid, key)
            for vid, v in study.vehicles.items()
            for key in fitsettings.model_keys(v.data)
        ]
        reference.study_references(paths, fits, workdir=args.directory)
    return len(paths)


def _weather_years(args: argparse.Namespace, config: dict) -> int:
    """Read the study's typical years (``energy.weather``, when enabled) as the rule energy
    will, so that a year in degF or K, cut short or of another kind stops here, not after
    the fits; how many."""
    energy = (config or {}).get("energy") or {}
    if not energy.get("enabled", False):
        return 0
    from railtherm.study.weather import read_weather

    paths = energy.get("weather") or []
    for path in paths:
        read_weather(os.path.join(args.directory, path))
    return len(paths)


def _validate(args: argparse.Namespace) -> int:
    workdir = args.directory
    study = _study(args, args.vehicles)
    config = {} if args.vehicles else _study_config(args)
    references = 0 if args.vehicles else _references(args, study, config)
    count = len(study.vehicles)
    summary = f"ok: {count} vehicle{'' if count == 1 else 's'}"
    if references:
        summary += f", {references} reference file{'' if references == 1 else 's'}"
    if not args.vehicles:
        from railtherm.study.plan import figure_warnings

        for warning in figure_warnings(study, config):
            print(f"warning: {warning}", file=sys.stderr)
    if not args.headers_only:
        from railtherm.data.datacheck import check_values  # pandas only when reading values

        windows, not_written = 0, []
        for vehicle in study.vehicles.values():
            checked = check_values(vehicle, workdir=workdir)
            windows += len(checked.windows)
            not_written += checked.not_written
            for warning in checked.warnings:
                print(f"warning: {warning}", file=sys.stderr)
        from railtherm.data.datacheck import shared_records

        for warning in shared_records(study):
            print(f"warning: {warning}", file=sys.stderr)
        summary += f", values of {windows} window{'' if windows == 1 else 's'} checked"
        years = 0 if args.vehicles else _weather_years(args, config)
        if years:
            summary += f", {years} weather year{'' if years == 1 else 's'} read"
        if not_written:
            summary += (
                f" ({len(not_written)} raw file{'' if len(not_written) == 1 else 's'} not "
                "written yet: the clean job checks them)"
            )
    print(summary)
    return 0


def _audit(args: argparse.Namespace) -> int:
    from railtherm.report import audit  # pandas only when auditing

    estimates = args.estimates
    if estimates is not None and not os.path.isfile(os.path.join(estimates, "table2.csv")):
        raise ConfigError(
            "--estimates", "(directory)", estimates, "holds no table2.csv of re-estimates"
        )
    if os.path.exists(args.out) and not os.path.isdir(args.out):
        raise ConfigError("--out", "out", args.out, "a file is there: give a directory")
    findings = audit.audit(args.published, args.ranges, estimates, args.out)
    # the findings about the published values; the re-estimation's are never counted with them
    paper = findings["family"].isin(audit.PAPER_FAMILIES)
    counts = findings.loc[paper, "severity"].value_counts()
    summary = ", ".join(f"{counts.get(s, 0)} {s}" for s in audit.SEVERITIES)
    if not paper.all():
        rest = findings.loc[~paper, "severity"].value_counts()
        summary += "; the re-estimation: " + ", ".join(
            f"{rest.get(s, 0)} {s}" for s in audit.SEVERITIES
        )
    print(f"{args.out}/findings.csv, {args.out}/audit.md: the published values {summary}")
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
    from railtherm.study.run import fit_vehicle  # numpy, scipy and pandas only when fitting

    if args.posterior:  # the sampler's settings before any work
        _check_sampler_args(args)
    study = _study(args, [args.vehicle])
    for path in _campaign_files(study, args.directory):
        print(f"{path}: written by the virtual climatic wind tunnel (synthetic)")
    (vehicle,) = study.vehicles.values()
    out = None if args.out is None else os.path.join(args.directory, args.out)
    terms = _class_prior_terms(args, vehicle) if args.class_prior else ()
    result = fit_vehicle(vehicle, args.model, out=out, workdir=args.directory, prior_terms=terms)
    if result.kvalue is not None:
        k = result.kvalue
        value = (
            f"kA = {k.kA:.4g} ± {k.u_kA:.2g} W/K (± one standard uncertainty u; eq. 10; k not "
            "given: no surface_m2)"
            if k.k is None
            else f"k = {k.k:.4g} ± {k.u_k:.2g} W/(m2 K) (± one standard uncertainty u; 95 %: "
            f"± {2 * k.u_k:.2g}; eq. 10)"
        )
        print(
            f"{vehicle.id}: {value}, "
            f"{'steady' if k.steady else 'not steady'}{', forced' if k.forced else ''}"
        )
        for reason in k.reasons:  # why the window failed the steady-state test
            print(f"  - {reason}")
    for fit in result.fits.values():
        print(fit.summary())
    if out:
        print(f"written to {os.path.join(out, 'vehicles', vehicle.id)}")
    if args.posterior:
        _posterior(args, vehicle, result, out, terms)
    return 0


def _check_sampler_args(args: argparse.Namespace) -> None:
    """``railtherm fit --posterior``'s sampler settings, refused with the option's name."""
    for key, value in (("chains", args.chains), ("draws", args.draws)):
        if value < 1:
            raise ConfigError(f"--{key}", key, value, "expected 1 or more")
    if args.tune < 0:
        raise ConfigError("--tune", "tune", args.tune, "expected 0 or more")
    if not 0.0 < args.target_accept < 1.0:
        raise ConfigError(
            "--target-accept", "target_accept", args.target_accept, "expected between 0 and 1"
        )
    if not 0 <= args.seed < 2**64:  # the sampler's seed is an unsigned 64-bit integer
        raise ConfigError("--seed", "seed", args.seed, "expected 0 to 2^64 - 1")


def _class_prior_terms(args: argparse.Namespace, vehicle) -> list:
    """``railtherm fit --class-prior``: the class reference model of the study's Table 2
    without the vehicle, as joint prior terms of its second-order fits (docs/bayes.md)."""
    from railtherm.study import classmodel, pooling

    members = classmodel.members_from_study(args.config, args.results, args.directory)
    prior = pooling.class_prior(members, vehicle.id, vehicle.data, None)
    if prior.reference is None:
        raise ConfigError(
            vehicle.path, "class", vehicle.data.get("class"), f"no class prior: {prior.reason}"
        )
    where = "its class" if prior.basis == "class" else "every rail class pooled"
    table = os.path.join(args.results, "tables", "table2.csv")
    basis = ", ".join(prior.reference.basis)
    print(f"{vehicle.id}: class prior from {where} without it ({basis}; {table})")
    return prior.terms


def loo_line(loo: dict) -> str:
    """PSIS-LOO's figures as one line (docs/bayes.md); where a Pareto k exceeds 0.7 the
    estimate of that observation's term is unreliable, and the line says so first."""
    bad = int(loo["pareto_k_above_0.7"])
    trust = (
        f"unreliable: {bad} of {loo['observations']} observations with Pareto k above 0.7 "
        "(more draws, or exact leave-one-out for them); "
        if bad
        else ""
    )
    return (
        f"PSIS-LOO: {trust}elpd_loo {loo['elpd_loo']:.6g} ± {loo['se']:.3g}, p_loo "
        f"{loo['p_loo']:.3g} ({loo['observations']} observations, {loo['draws']} draws); "
        f"Pareto k max {loo['pareto_k_max']:.2f}, {bad} above 0.7; "
        f"comparable with: {loo['compare']}"
    )


def _posterior(args: argparse.Namespace, vehicle, result, out: str | None, prior_terms=()) -> None:
    """``railtherm fit --posterior``: each fitted model's posterior by NUTS, its summary
    printed and its InferenceData written beside the fit file (under --out), else in the
    working directory."""
    from railtherm.study import fitsettings, posterior

    for model in result.fits:
        second = fitsettings.split_key(model)[0] == "order2"  # the class model's structure
        post = posterior.vehicle_posterior(
            vehicle, model, result, chains=args.chains, draws=args.draws, tune=args.tune,
            seed=args.seed, prior_terms=prior_terms if second else (),
            target_accept=args.target_accept,
        )  # fmt: skip
        table = post.summary()[["mean", "sd", "hdi_2.5%", "hdi_97.5%", "r_hat", "ess_bulk"]]
        print(
            f"{vehicle.id} {model}: posterior by NUTS ({post.settings['chains']} chains x "
            f"{post.settings['draws']} draws after {post.settings['tune']} tuning, seed "
            f"{post.settings['seed']}, target acceptance {post.settings['target_accept']}; "
            f"{post.divergences()} divergences; "
            f"{post.seconds:.1f} s); trust it only with R-hat <= 1.01, bulk ESS >= 400 and no "
            "divergences (docs/bayes.md)"
        )
        print(table.to_string(float_format=lambda x: f"{x:.5g}"))
        undetermined = [p for p, q in result.fits[model].parameters.items() if not q.identified]
        if undetermined:
            print(
                f"Not identified by the record (its fit): {', '.join(undetermined)}: their "
                "posterior is what the prior and the search bounds allow, not an estimate "
                "from the data."
            )
        intervals = post.intervals()
        if "with_systematic_lo" in intervals:
            print(
                "95 % intervals (equal-tailed): the data's (statistical) and with the "
                "systematic budget (type B) mixed in by draws"
            )
            print(intervals.dropna().to_string(float_format=lambda x: f"{x:.5g}"))
        if args.loo:
            print(loo_line(post.loo()))
        if out:  # beside the fit file
            path = os.path.join(out, "vehicles", vehicle.id, f"fit_{model}.posterior.nc")
        else:
            path = os.path.join(args.directory, f"{vehicle.id}.fit_{model}.posterior.nc")
        print(f"written to {posterior.write(post, path)}")
        figure = posterior.pair_plot(post, path.removesuffix(".nc") + ".png")
        print(f"pair plot: {figure}")


def _reference_model(args: argparse.Namespace) -> int:
    """``railtherm reference``: the class reference model of an unmeasured vehicle
    (:mod:`railtherm.study.classmodel`) from the study's Table 2 (``<results>/tables/table2.csv``,
    committed; the per-vehicle fit files need not exist). With ``--out``,
    the summary on stdout and the YAML to the file; without, the YAML on stdout and the
    summary on stderr (so that ``> FILE`` keeps only the YAML)."""
    from railtherm.study import classmodel  # numpy and scipy only when building one

    members = classmodel.members_from_study(args.config, args.results, workdir=args.directory)
    model = classmodel.build(
        members,
        args.vehicle_class,
        args.mass_kg,
        args.surface_m2,
        k=args.k,
        min_vehicles=args.min_vehicles,
        exclude=args.exclude or (),
        exclude_in_class=True,
    )
    quantities = {"m_veh": args.mass_kg, "surface": args.surface_m2}
    notes = _class_range_notes(args.vehicle_class, quantities, args.directory)
    for note in notes:
        print(note, file=sys.stderr)
    if args.out is None:
        sys.stdout.write(model.to_yaml())
        print(model.summary(), file=sys.stderr)
        return 0
    model.write(os.path.join(args.directory, args.out))
    print(model.summary())
    print(f"written to {args.out}")
    return 0


def _class_range_notes(vehicle_class: str, quantities: dict[str, float], workdir: str) -> list[str]:
    """A note per quantity (``m_veh``, ``surface``) outside its class's range in the audit's
    ranges (config/audit.yaml, where the working directory has it): the class model then
    extrapolates beyond the vehicles its ranges describe."""
    from railtherm.report.auditbase import class_range, load_ranges

    path = os.path.join(workdir, "config", "audit.yaml")
    if not os.path.isfile(path):
        return []
    ranges = load_ranges(path, "config/audit.yaml")
    notes = []
    for quantity, value in quantities.items():
        found = class_range(ranges, quantity, vehicle_class)
        if found is None:
            continue
        interval, entry = found
        lo, hi = interval.lo, interval.hi
        if not lo <= value <= hi:
            notes.append(
                f"Note: {quantity} = {value:g} {entry['unit']} lies outside the {vehicle_class} "
                f"range {lo:g}-{hi:g} {entry['unit']} (config/audit.yaml ranges.{quantity}): "
                "the class model extrapolates beyond the vehicles it describes."
            )
    return notes


def _design_prior(args: argparse.Namespace, workdir: str):
    """The prior ``railtherm design`` predicts for: a measured vehicle's fit (--vehicle
    FIT.yaml), or the class reference model of a vehicle config (--vehicle CONFIG.yaml) or
    of --class, --mass-kg and --surface-m2."""
    from railtherm.study import design

    if args.vehicle:
        ignored = [
            option
            for option, value in (("--mass-kg", args.mass_kg), ("--surface-m2", args.surface_m2))
            if value is not None
        ]
        if ignored:  # they were ignored beside a fit, overwritten by a vehicle config's
            raise ConfigError(
                ignored[0],
                ignored[0][2:].replace("-", "_"),
                getattr(args, ignored[0][2:].replace("-", "_")),
                "--vehicle brings its own mass and surface: give --class, --mass-kg and "
                "--surface-m2 without --vehicle for a vehicle described by them",
            )
        path = os.path.join(workdir, args.vehicle)
        data = read_yaml(path, display=args.vehicle)
        if isinstance(data, dict) and "parameters" not in data:
            # a vehicle config, before its test: its class, mass and surface
            for key in ("class", "mass_kg", "surface_m2"):
                if key not in data:
                    raise ConfigError(args.vehicle, key, None, "a vehicle config needs it here")
            args.vehicle_class = data["class"]
            args.mass_kg, args.surface_m2 = data["mass_kg"], data["surface_m2"]
            args.vehicle = None
    if args.vehicle:
        prior = design.prior_from_fit_file(path, args.draws, args.seed)
    else:
        given = (("--mass-kg", args.mass_kg), ("--surface-m2", args.surface_m2))
        missing = [option for option, value in given if value is None]
        if missing:
            raise ConfigError(
                missing[0], missing[0][2:], None, "--class needs --mass-kg and --surface-m2"
            )
        for note in _class_range_notes(
            args.vehicle_class, {"m_veh": args.mass_kg, "surface": args.surface_m2}, workdir
        ):
            print(note)
        prior = design.prior_for_class(
            args.vehicle_class,
            args.mass_kg,
            args.surface_m2,
            args.config,
            args.results,
            workdir,
            args.draws,
            args.seed,
        )
    return prior


def _design(args: argparse.Namespace) -> int:
    """``railtherm design``: the predicted 95 % intervals a planned programme gives a vehicle
    (:mod:`railtherm.study.design`), from a measured vehicle's fit or from the class
    reference model of an unmeasured one; with --optimise, the shortest programme of the same
    shape that reaches --target with the probability asked."""
    from railtherm.study import design, designtext, replicates

    workdir = args.directory
    programme = design.load_programme(os.path.join(workdir, args.programme))
    target = design.parse_target(args.target) if args.target else None
    if args.optimise and target is None:
        raise ConfigError("--optimise", "target", None, "--optimise needs --target")
    if args.length_h is not None and target is None:
        raise ConfigError("--length-h", "target", None, "--length-h needs --target")
    if not 0.0 < args.probability <= 1.0:
        raise ConfigError("--probability", "probability", args.probability, "expected 0 < p <= 1")
    if args.draws < 1:
        raise ConfigError("--draws", "draws", args.draws, "expected 1 or more")
    if args.replicates < 0 or args.replicates == 1:
        raise ConfigError("--replicates", "replicates", args.replicates, "expected 0, or 2 or more")
    if args.out and args.optimise == (args.length_h is not None):
        raise ConfigError(
            "--out", "out", args.out, "writes the programme of --optimise or --length-h: give one"
        )
    _nonnegative(args, "seed")
    if args.out:
        design.check_out_path(args.out, os.path.join(workdir, args.out))
    prior = _design_prior(args, workdir)
    assessment = design.assess(prior, programme, target)
    found = None
    if args.optimise:  # the first phase as given: its end is the static k window
        found = design.shortest(prior, programme, target, args.probability, keep_first=True)
    best = None
    if args.length_h is not None:
        best = design.best_of_length(
            prior, programme, target[0], args.length_h, args.max_power_w, args.min_phase_h
        )
    print(designtext.markdown(assessment))
    if args.replicates:
        print("\n" + replicates.markdown(replicates.run_for(prior, programme, assessment, args)))
    proposed = None
    if best is not None and best[1].central.loop_gain >= design.LOOP_GAIN_MAX:
        print(
            f"\nNo programme of {best[0].hours:g} h was found where the storage-corrected kA "
            f"and the fit settle as the linear prediction assumes (g·S below "
            f"{design.LOOP_GAIN_MAX:g} at the prior's central parameters): the programme as "
            "given stays; lengthen the first phase, its steady state, to lower g·S."
        )
    elif best is not None:
        chosen, assessed = best
        proposed = chosen
        print(f"\nBest programme of {chosen.hours:g} h for {target[0]} (the first phase kept):")
        for ph in chosen.phases:
            print(f"  {ph.describe()}")
        print()
        chosen_assessed = replace(design.assess(prior, chosen, target), notes=assessed.notes)
        print(designtext.markdown(chosen_assessed))
        name = target[0]
        before, after = assessment.central.half_width[name], assessed.central.half_width[name]
        if assessment.central.loop_gain >= design.LOOP_GAIN_MAX:
            print(
                f"\nNo comparison of {name}'s width with the programme as given: there the "
                "storage-corrected kA and the fit pull each other away (g·S at least "
                f"{design.LOOP_GAIN_MAX:g}), where the linear prediction does not hold."
            )
        else:
            print(
                f"\nAgainst the programme as given, at the prior's central parameters: {name} "
                f"±{100 * before:.3g} % -> ±{100 * after:.3g} %."
            )
    if args.optimise:
        name, goal = target
        if found is None:
            longest = design.assess(prior, design.scaled(programme, 4.0), target)
            why = "".join(f"; at 4 times, {v}" for v in longest.violations)
            print(
                f"\nNo programme of this shape up to 4 times as long reaches {name} within "
                f"±{100 * goal:g} % with probability {args.probability:g} within the "
                f"programme's limits{why}."
            )
        else:
            factor, best = found
            proposed = best.programme
            hours = best.programme.hours
            print(
                f"\nShortest programme of this shape (the first phase kept): {hours:.4g} h "
                f"(the later phases {factor:g} times as long), {name} within "
                f"±{100 * goal:g} % with probability {best.probability:.2f}:"
            )
            for ph in best.programme.phases:
                print(f"  {ph.describe()}")
            print()
            print(designtext.markdown(best))
    if args.replicates and proposed is not None:
        print("\nThe proposed programme in the virtual tunnel:")
        checked = design.assess(prior, proposed, target, with_peaks=False)
        print("\n" + replicates.markdown(replicates.run_for(prior, proposed, checked, args)))
    if args.out:
        if proposed is None:
            raise ConfigError("--out", "out", args.out, "no programme was found to write")
        try:
            written = design.write_programme(proposed, os.path.join(workdir, args.out))
        except OSError as err:
            raise ConfigError("--out", "out", args.out, f"cannot write there: {err}") from err
        print(f"\nWrote {written[0]} and its set-point schedule {written[1]}.")
    return 0


def _band_draws(draws: int) -> None:
    """``--draws`` 0 or enough for a 95 % band, else a :class:`ConfigError` naming it."""
    from railtherm.study import simulate as sim

    problem = sim.band_draws_problem(draws)
    if problem:
        raise ConfigError("--draws", "draws", draws, problem)


def _nonnegative(args: argparse.Namespace, *names: str) -> None:
    """Each option ``--<name>`` 0 or more, else a :class:`ConfigError` naming it."""
    for name in names:
        value = getattr(args, name)
        if value < 0:
            raise ConfigError(f"--{name.replace('_', '-')}", name, value, "expected 0 or more")


def _energy(args: argparse.Namespace) -> int:
    """``railtherm energy``: a fit's or a class reference model's annual heating energy in a
    typical year of weather under an operating profile, with 95 % bands and what-ifs."""
    from railtherm.study import energy
    from railtherm.study import simulate as sim
    from railtherm.study.weather import read_weather

    _nonnegative(args, "draws", "seed")
    _band_draws(args.draws)
    problem = energy.step_problem(args.step_s)
    if problem:
        raise ConfigError("--step-s", "step_s", args.step_s, problem)
    volume = args.volume_m3
    if volume is not None and not (math.isfinite(volume) and volume > 0):
        raise ConfigError(
            "--volume-m3", "volume_m3", volume, "expected the interior volume in m³, above 0"
        )
    texts = list(args.what_if or ())
    what_ifs = [energy.parse_what_if(w) for w in texts]
    workdir = args.directory
    out = os.path.join(workdir, args.out) if args.out else None
    if out is not None and os.path.exists(out) and not os.path.isdir(out):
        raise ConfigError(
            "--out", "out", args.out, "a file is there: give a directory for the results"
        )
    # the settings first (they contradict each other or not whatever the parameters), then
    # the weather, then the parameters
    profile = energy.load_profile(os.path.join(workdir, args.profile))
    energy.check_what_ifs(profile, what_ifs, texts, "--what-if", ["what_if"] * len(texts))
    if args.surface_m2 is not None and profile.heating_limit_W_per_m2 is None:
        print(
            f"Note: --surface-m2 is not used: profile {profile.name} gives its heating limit "
            f"in W ({profile.heating_limit_W:g} W), not per m².",
            file=sys.stderr,
        )
    year = read_weather(os.path.join(workdir, args.weather), kind=args.kind)
    params = sim.load_parameters(os.path.join(workdir, args.params))
    surface = energy.heater_surface(params, args.surface_m2)
    with _progress_bar(f"annual energy of {os.path.basename(args.params)}") as progress:
        result = energy.annual_energy(
            params,
            year,
            profile,
            what_ifs=what_ifs,
            dt_s=args.step_s,
            draws=args.draws,
            seed=args.seed,
            volume_m3=args.volume_m3,
            hold=args.hold,
            surface_m2=surface,
            progress=progress,
        )
    print(energy.markdown(result))
    if out is not None:
        ids = {
            "vehicle": result.label,
            "class": params.vehicle_class,
            "model": params.structure.name,
            "profile": profile.name,
            "climate": year.name,
        }
        try:
            written = energy.write_result(result, ids, out)
        except OSError as err:
            raise ConfigError("--out", "out", args.out, f"cannot write there: {err}") from err
        for path in written:
            print(f"wrote {path}", file=sys.stderr)
    return 0


@contextlib.contextmanager
def _progress_bar(title: str):
    """A progress bar on the terminal's stderr (rich), none where stderr is not a terminal;
    yields the callback progress(done, total)."""
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    console = Console(stderr=True)
    columns = (TextColumn("{task.description}"), BarColumn(), TimeRemainingColumn())
    with Progress(
        *columns, console=console, transient=True, disable=not console.is_terminal
    ) as bar:
        task = bar.add_task(title, total=None)

        def progress(done: int, total: int) -> None:
            bar.update(task, completed=done, total=total)

        yield progress


def _relocated(exc: ConfigError, local: str, given: str) -> ConfigError:
    """``exc`` naming the path ``given`` (as the user gave it) where it names ``local`` (the
    path under the working directory), of the same class."""
    file = given if exc.file == local else exc.file
    value = given if exc.value == local else exc.value
    return type(exc)(file, exc.key, value, exc.reason.replace(local, given))


def _simulate(args: argparse.Namespace) -> int:
    """``railtherm simulate``: every scenario through one parameter set; the summaries on
    stdout and, with ``--out``, each scenario's series (CSV) and outcomes (YAML). Every
    scenario runs before anything is printed or written: a failing one leaves no output."""
    from railtherm.report.tables import write_csv
    from railtherm.study import simulate as sim  # numpy and pandas only when simulating
    from railtherm.study.fit import write_yaml
    from railtherm.study.scenario import load_scenario

    _nonnegative(args, "draws", "seed")
    _band_draws(args.draws)
    sim.air_capacity(args.volume_m3, "--volume-m3")
    workdir = args.directory
    local = os.path.join(workdir, args.params)
    try:
        params = sim.load_parameters(local)
    except ConfigError as exc:
        raise _relocated(exc, local, args.params) from None
    scenarios = []
    for path in args.scenario:
        local = os.path.join(workdir, path)
        try:
            scenarios.append(load_scenario(local, display=path))
        except ConfigError as exc:
            raise _relocated(exc, local, path) from None
    if args.out is not None:
        names = [sc.name for sc in scenarios]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise ConfigError(
                "--scenario",
                "name",
                twice[0],
                "given by two scenarios: their files in --out would overwrite each other",
            )
    results = []
    for scenario in scenarios:
        try:
            result = sim.simulate(
                params,
                scenario,
                draws=args.draws,
                seed=args.seed,
                allow_unreachable=args.allow_unreachable,
                volume_m3=args.volume_m3,
            )
        except sim.NotPredictable as exc:
            raise type(exc)(f"{args.params} ({exc.file})", exc.key, exc.value, exc.reason) from None
        results.append(result)
    print("\n\n".join(result.summary() for result in results))
    if args.out is None:
        return 0
    out = os.path.join(workdir, args.out)
    try:
        for result in results:
            name = result.scenario.name
            write_csv(result.series, os.path.join(out, f"{name}.csv"), digits=6)
            write_yaml(result.to_dict(), os.path.join(out, f"{name}.yaml"))
    except OSError as exc:
        raise ConfigError("--out", "out", args.out, f"cannot write: {exc}") from None
    for result in results:
        base = os.path.join(args.out, result.scenario.name)
        print(f"written to {base}.csv, {base}.yaml")
    return 0


def _directory_option(parser: argparse.ArgumentParser) -> None:
    """``-d/--directory``: the working directory every path of the command is relative to."""
    parser.add_argument(
        "-d",
        "--directory",
        default=".",
        help="working directory all paths are relative to (default: %(default)s)",
    )


def _study_options(parser: argparse.ArgumentParser, results: str) -> None:
    """``--config`` and ``--results`` of a command that reads the study's class members, and
    ``-d/--directory``; ``results`` says what it reads there."""
    parser.add_argument(
        "--config",
        default="config/config.yaml",
        help="study config listing the vehicle files (default: %(default)s)",
    )
    parser.add_argument("--results", default="results", help=f"{results} (default: %(default)s)")
    _directory_option(parser)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with one subparser per command.

    Returns
    -------
    argparse.ArgumentParser
    """
    parser = argparse.ArgumentParser(
        prog="railtherm",
        description="Thermal parameters of rail vehicles from climatic-wind-tunnel data.",
    )
    parser.add_argument("--version", action="version", version=f"railtherm {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")
    _add_validate(commands)
    starter.register(commands)
    _add_audit(commands)
    _add_fit(commands)
    _add_reference(commands)
    _add_design(commands)
    _add_energy(commands)
    _add_simulate(commands)
    return parser


def _add_validate(commands: Any) -> None:
    """The ``validate`` command's subparser."""
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


def _add_audit(commands: Any) -> None:
    """The ``audit`` command's subparser."""
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


def _add_fit(commands: Any) -> None:
    """The ``fit`` command's subparser."""
    fit = commands.add_parser(
        "fit",
        help="one vehicle through clean, static k, fit and check, without the workflow",
        description=(
            "Clean the windows of VEHICLE.yaml, compute the static k (eq. 10), fit each model "
            "(by simulation-error PEM, or a _kalman model by the Kalman filter's likelihood) "
            "and judge it, as the workflow's rules do; print the parameters with their 95 % "
            "intervals and the verdict. With --out, write the "
            "rules' files under DIR/vehicles/<id>/."
        ),
    )
    fit.add_argument("vehicle", metavar="VEHICLE.yaml", help="vehicle file")
    fit.add_argument(
        "--model",
        action="append",
        choices=[
            key + suffix
            for key in structures.keys(include_refused=True)
            for suffix in ("", "_kalman")
        ],
        help=(
            "model to fit (repeatable; default: the models the vehicle file asks for); the "
            "suffix _kalman fits it by the Kalman-filter estimator"
        ),
    )
    fit.add_argument("--out", metavar="DIR", help="results directory to write into")
    fit.add_argument(
        "--posterior",
        action="store_true",
        help=(
            "also sample each model's posterior by NUTS (the extra railtherm[bayes]); print "
            "its summary and write fit_<model>.posterior.nc (docs/bayes.md)"
        ),
    )
    fit.add_argument("--chains", type=int, default=4, help="posterior chains (default: 4)")
    fit.add_argument(
        "--class-prior",
        action="store_true",
        help="give the second-order fit the class reference model of the study's Table 2 "
        "(RESULTS/tables/table2.csv) without this vehicle as its prior: a MAP fit, and "
        "the posterior's prior with --posterior (docs/bayes.md)",
    )
    fit.add_argument(
        "--results",
        default="results",
        help="the study's results directory --class-prior reads (default: results)",
    )
    fit.add_argument(
        "--loo",
        action="store_true",
        help="with --posterior, also PSIS-LOO by ArviZ (each observation's likelihood at up "
        "to 400 draws; a Kalman model's by the filter's row loop, slow on long records)",
    )
    fit.add_argument("--draws", type=int, default=1000, help="draws per chain (default: 1000)")
    fit.add_argument("--tune", type=int, default=1000, help="tuning steps (default: 1000)")
    fit.add_argument("--seed", type=int, default=0, help="the sampler's seed (default: 0)")
    fit.add_argument(
        "--target-accept",
        type=float,
        default=0.8,
        help="the acceptance rate NUTS adapts its step to (default: 0.8); 0.9-0.95 for divergences",
    )
    fit.add_argument(
        "--config",
        default="config/config.yaml",
        help="study config whose defaults apply, if it exists (default: %(default)s)",
    )
    _directory_option(fit)
    fit.set_defaults(run=_fit)


def _add_reference(commands: Any) -> None:
    """The ``reference`` command's subparser."""
    reference = commands.add_parser(
        "reference",
        help="class reference model of an unmeasured vehicle from the study's fits",
        description=(
            "Build the second-order model of a vehicle nobody measured from its class, mass "
            "and outer surface: C_veh = c_veh m (eq. 24), C = C_veh / delta (eq. 25), "
            "K_veh = kappa_veh A, kA = k A, each generalised parameter from the class's usable "
            "second-order fits (acceptable, every parameter identified), with 95 % "
            "prediction intervals for one new vehicle of the class. Prints a summary and "
            "writes the YAML to --out (without --out, prints the YAML)."
        ),
    )
    reference.add_argument(
        "--class",
        dest="vehicle_class",
        required=True,
        metavar="CLASS",
        help="tram, metro, regional, main-line, or all (every rail class pooled)",
    )
    reference.add_argument(
        "--mass-kg", type=float, required=True, help="the vehicle's mass m_veh (kg)"
    )
    reference.add_argument(
        "--surface-m2", type=float, required=True, help="its outer surface A (m2, eq. 5)"
    )
    reference.add_argument(
        "--k", type=float, help="its k (W/(m2 K)), e.g. from a k-value test (default: the class's)"
    )
    reference.add_argument(
        "--min-vehicles",
        type=int,
        default=2,
        help="refuse a class with fewer usable vehicles (at least 2; default: %(default)s)",
    )
    reference.add_argument(
        "--exclude",
        action="append",
        metavar="ID",
        help="leave this vehicle out of the class (repeatable)",
    )
    _study_options(reference, "the study's results directory with tables/table2.csv")
    reference.add_argument(
        "--out", metavar="FILE", help="YAML file to write (default: print the YAML)"
    )
    reference.set_defaults(run=_reference_model)


def _add_design(commands: Any) -> None:
    """The ``design`` command's subparser."""
    design = commands.add_parser(
        "design",
        help="the predicted uncertainty of a planned tunnel programme, before it runs",
        description=(
            "Predict the 95 % intervals of the parameters that PROGRAMME (phases of tunnel "
            "temperature and heating, logger step, sensor noise and systematic errors; "
            "config/programmes/) will give: from the Fisher information of the planned record "
            "for a measured vehicle's fit (--vehicle), or, over draws of a new vehicle of its "
            "class (--class, --mass-kg, --surface-m2), with the probability to reach --target. "
            "--optimise finds the shortest programme of the same shape that does."
        ),
    )
    design.add_argument("programme", metavar="PROGRAMME.yaml", help="the planned programme")
    prior = design.add_mutually_exclusive_group(required=True)
    prior.add_argument(
        "--vehicle",
        metavar="FIT_OR_CONFIG.yaml",
        help="a measured vehicle's checked fit, or a vehicle config (its class, mass, surface)",
    )
    prior.add_argument(
        "--class", dest="vehicle_class", metavar="CLASS", help="the class of an unmeasured vehicle"
    )
    design.add_argument("--mass-kg", type=float, help="its mass m_veh (kg), with --class")
    design.add_argument("--surface-m2", type=float, help="its outer surface A (m2), with --class")
    design.add_argument("--target", metavar="PARAM=PCT", help="e.g. C_veh=5%% (95 %% half-width)")
    design.add_argument(
        "--probability",
        type=float,
        default=0.9,
        help="the probability --optimise asks for (default: %(default)s)",
    )
    design.add_argument("--optimise", action="store_true", help="shortest programme to --target")
    design.add_argument(
        "--length-h",
        type=float,
        help="the best programme of this many hours for --target (its first phase kept)",
    )
    design.add_argument(
        "--max-power-w",
        type=float,
        help="the heating power limit of --length-h (default: the programme's largest)",
    )
    design.add_argument(
        "--min-phase-h",
        type=float,
        default=1.0,
        help="the shortest phase of --length-h (default: %(default)s)",
    )
    design.add_argument(
        "--draws",
        type=int,
        default=200,
        help="draws of the prior: the class model's, or the fit's own intervals (default: "
        "%(default)s)",
    )
    design.add_argument("--seed", type=int, default=0, help="seed of the draws (default: 0)")
    design.add_argument(
        "--replicates",
        type=int,
        default=0,
        metavar="N",
        help="simulate N virtual tunnel runs of the programme (every declared error drawn "
        "anew), fit each as the study does and print realised against predicted widths",
    )
    design.add_argument(
        "--out",
        metavar="PROGRAMME.yaml",
        help="write the programme --optimise or --length-h proposes (YAML, which design "
        "reads back) and its set-point schedule beside it (.csv)",
    )
    _study_options(design, "the study's results: tables/table2.csv and the class's fits")
    design.set_defaults(run=_design)


def _add_energy(commands: Any) -> None:
    """The ``energy`` command's subparser."""
    energy = commands.add_parser(
        "energy",
        help="annual heating energy in a typical year under an operating profile",
        description=(
            "The annual heating energy of PARAMS (a checked fit or a class reference model) "
            "in a typical year of weather (TMY3, EPW, PVGIS or CSV) under an operating profile "
            "(config/profiles/): the year's kWh, its months, pre-heating, peak power and unmet "
            "hours, with 95 % bands from parameter draws; each --what-if on the same draws, "
            "its difference paired (docs/energy.md)."
        ),
    )
    energy.add_argument(
        "params", metavar="PARAMS", help="fit_<model>.yaml or a class reference model (YAML)"
    )
    energy.add_argument("--weather", required=True, metavar="FILE", help="a typical year")
    energy.add_argument(
        "--kind", choices=("tmy3", "epw", "pvgis", "csv"), help="the weather file's kind"
    )
    energy.add_argument("--profile", required=True, metavar="P.yaml", help="operating profile")
    energy.add_argument(
        "--what-if",
        action="append",
        metavar="CHANGE",
        help="k=-10%%, set_back=8, set_back=off or preheat_h=3 (repeatable)",
    )
    energy.add_argument("--draws", type=int, default=200, help="parameter draws (default: 200)")
    energy.add_argument("--seed", type=int, default=0, help="seed of the draws (default: 0)")
    energy.add_argument(
        "--step-s", type=float, default=60.0, help="simulation step (s; default: 60)"
    )
    energy.add_argument(
        "--volume-m3", type=float, metavar="V", help="interior volume: the draws' air capacity"
    )
    energy.add_argument(
        "--surface-m2",
        type=float,
        metavar="A",
        help="the vehicle's outer surface (m²): sizes the heater of a profile that gives "
        "heating_limit_W_per_m2",
    )
    energy.add_argument(
        "--hold",
        choices=("first_order", "zero_order"),
        default="first_order",
        help="the hourly weather between its hours: linear (default) or held",
    )
    energy.add_argument(
        "--out",
        metavar="DIR",
        help="also write energy.csv, energy.md and the monthly figure energy.png/.svg in DIR",
    )
    _directory_option(energy)
    energy.set_defaults(run=_energy)


def _add_simulate(commands: Any) -> None:
    """The ``simulate`` command's subparser."""
    simulate = commands.add_parser(
        "simulate",
        help="scenarios through a fit or a class reference model, with 95 %% bands",
        description=(
            "Run each scenario (outdoor temperature, heating or its controller, gains, initial "
            "state; config/scenarios/) through PARAMS: a checked fit (fit_<model>.yaml) or a "
            "class reference model (railtherm reference). Prints the heat-up and cool-down "
            "times, energy, peak power and final temperature with 95 % bands from parameter "
            "draws. With --out, writes DIR/<scenario name>.csv (the series) and "
            "DIR/<scenario name>.yaml (the outcomes), nothing if any scenario fails."
        ),
    )
    simulate.add_argument(
        "params", metavar="PARAMS", help="fit_<model>.yaml or a class reference model (YAML)"
    )
    simulate.add_argument(
        "--scenario",
        action="append",
        required=True,
        metavar="S.yaml",
        help="scenario file (repeatable)",
    )
    simulate.add_argument(
        "--draws",
        type=int,
        default=200,
        help="parameter draws behind the 95 %% bands (0: no bands; default: %(default)s)",
    )
    simulate.add_argument(
        "--seed", type=int, default=0, help="seed of the draws (default: %(default)s)"
    )
    simulate.add_argument(
        "--volume-m3",
        type=float,
        metavar="V",
        help=(
            "the vehicle's interior volume (m³): the draws' air capacity C is held at or above "
            "that of its air, rho c_p V (without it, only positivity)"
        ),
    )
    simulate.add_argument(
        "--out", metavar="DIR", help="directory to write <scenario name>.csv and .yaml into"
    )
    simulate.add_argument(
        "--allow-unreachable",
        action="store_true",
        help=(
            "simulate a set point the heating cannot hold (the heat-up time is reported as "
            "unreachable) instead of refusing it"
        ),
    )
    _directory_option(simulate)
    simulate.set_defaults(run=_simulate)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 ok, 1 user mistake, 2 usage).

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit status.
    """
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
