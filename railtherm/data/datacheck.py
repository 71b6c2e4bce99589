"""The values of a vehicle's raw files, checked as the jobs will read them.

:mod:`railtherm.config` checks a vehicle config against its raw files' headers and time
columns; the jobs then read every value. What a job would stop on and the config and raw
files alone decide - a cell that is no number or infinite, a temperature outside the physical
range, a gap longer than ``cleaning.max_gap_s``, a k window without a positive T - T_o or
Q_H (eq. 10) - is checked here, by the same code the rules ``clean`` and ``kvalue`` run, so
that ``railtherm validate`` stops on it before any job does.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import pandas as pd

from railtherm import codedigest
from railtherm.config import Study, Vehicle
from railtherm.data import ingest, timeaxis
from railtherm.data.rawfile import DigestCache, RawLayout
from railtherm.errors import ConfigError
from railtherm.estimation import kvalue


@dataclass
class DataCheck:
    """What :func:`check_values` read: the windows checked (``vehicle/window``) and the raw
    files not there to read yet (a campaign's files before the virtual wind tunnel ran)."""

    windows: list[str] = field(default_factory=list)
    not_written: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)


# A thermal record of a vehicle or a building is logged every few seconds to an hour; a step
# outside this range is more likely a time unit read wrongly (hours declared seconds) than a
# logger setting.
PLAUSIBLE_STEP_S = (1.0, 3 * 3600.0)


def shared_records(study: Study) -> list[str]:
    """A sentence per group of vehicles that read the same raw files over the same
    identification windows: one record, which every class statistic would count as many
    vehicles (copies of one test, a vehicle added twice under two ids)."""
    groups: dict[tuple, list[str]] = {}
    for vid, vehicle in study.vehicles.items():
        windows = json.dumps(vehicle.windows.get("identification"), sort_keys=True, default=str)
        groups.setdefault((tuple(sorted(vehicle.raw_files.values())), windows), []).append(vid)
    return [
        f"vehicles {', '.join(ids)} read the same raw files ({', '.join(files)}) over the same "
        f"identification windows: one record under {len(ids)} ids (a statistic over vehicles "
        f"would count it {len(ids)} times)"
        for (files, _), ids in groups.items()
        if len(ids) > 1
    ]


def step_warnings(vehicle: Vehicle) -> list[str]:
    """A sentence per raw file whose logger step is implausible for a thermal record, naming
    the declared time unit and the steps the same numbers would give in the other units (with
    sources: each source's files, naming its key)."""
    if vehicle.source_files:
        files = [
            (layout, name, vehicle.data["sources"][source]["format"]["time"], f"sources.{source}.")
            for source, parts in vehicle.source_layouts.items()
            for name, layout in parts.items()
        ]
    else:
        files = [
            (layout, name, vehicle.format["time"], "") for name, layout in vehicle.layouts.items()
        ]
    warnings = []
    for layout, name, time, prefix in files:
        text = _step_warning(vehicle, layout, name, timeaxis.time_format(time), prefix)
        if text:
            warnings.append(text)
    return warnings


def _step_warning(
    vehicle: Vehicle, layout: RawLayout, name: str, tf: timeaxis.TimeFormat, prefix: str
) -> str | None:
    lo, hi = PLAUSIBLE_STEP_S
    step = layout.step_s
    if not step or lo <= step <= hi:
        return None
    if tf.absolute:
        advice = f"is {prefix}format.time.format right?"
    else:
        number = step / timeaxis.ELAPSED_UNITS_S[tf.format]  # as the file writes it
        others = [
            f"{number * factor:g} s in {unit}"
            for unit, factor in timeaxis.ELAPSED_UNITS_S.items()
            if unit != tf.format and lo <= number * factor <= hi
        ]
        advice = "is the time unit right?"
        if others:
            advice += f" (a step of {number:g} is {', '.join(others)})"
    return (
        f"{vehicle.path}: raw file {layout.path} ({name}) is logged every {step:g} s by "
        f"its time column read as {prefix}format.time.format '{tf.format}': implausible for a "
        f"thermal record ({lo:g} s to {hi / 3600:g} h); {advice}"
    )


def k_window_warning(vehicle: Vehicle, display: str, k: kvalue.KValue) -> str:
    """The sentence for a k window that fails the standardized steady-state test (eq. 10):
    each failed criterion with its numbers, what the fit then does and the keys to change."""
    then = (
        "the fit uses it anyway (kvalue.force), flagged"
        if k.forced
        else "the fit will not fix kA from it but estimate kA jointly with the capacities"
    )
    return (
        f"{vehicle.path}: the k window (windows.kvalue, {display}) is not steady by the "
        f"standardized test (eq. 10): {'; '.join(k.reasons) or 'a criterion failed'}; "
        f"{then}. Extend or move the "
        "window, or change the criterion under kvalue (e.g. kvalue.min_duration_h)"
    )


def check_values(vehicle: Vehicle, workdir: str | os.PathLike[str] = ".") -> DataCheck:
    """Clean every window of ``vehicle`` in memory (rule ``clean``) and compute its static k
    (rule ``kvalue``); the first error propagates, naming file, column or key, line and
    value. Nothing is written."""
    out = DataCheck(warnings=step_warnings(vehicle))
    raws: dict[str, object] = {}
    identification = {w["name"] for w in vehicle.windows.get("identification", [])}
    spans: dict[str, list[tuple[str, object, object]]] = {}  # record: (window, first, last)
    for name in ingest.window_names(vehicle.data):
        raw_name, window, key = ingest.window_spec(vehicle.data, name)
        display = vehicle.raw_files[raw_name]
        record = vehicle.record(raw_name)
        paths = list(record.values()) if isinstance(record, dict) else [record]
        missing = [p for p in paths if not os.path.isfile(os.path.join(str(workdir), p))]
        if missing:
            if display not in out.not_written:
                out.not_written.append(display)
            continue
        if display not in raws:
            raws[display] = ingest.read_record_part(record, vehicle.data, workdir)
        table = ingest.tidy(raws[display], vehicle.data, window, display, window_key=key)
        stamps = _instants(table["timestamp"]) if name in identification else []
        if stamps:
            spans.setdefault(display, []).append((name, stamps[0], stamps[-1]))
        if name == "kvalue":
            k = kvalue.for_vehicle(table, vehicle.data, source=f"{display} ({key})")
            if not k.steady:
                out.warnings.append(k_window_warning(vehicle, display, k))
        out.windows.append(f"{vehicle.id}/{name}")
    _refuse_overlaps(vehicle, spans)
    return out


def _instants(stamps: pd.Series) -> list:
    """A tidy table's ``timestamp`` column as comparable instants: seconds of an elapsed
    time axis, or dates ([] where it holds neither: nothing to compare)."""
    numbers = pd.to_numeric(stamps, errors="coerce")
    if numbers.notna().all():
        return list(numbers)
    dates = pd.to_datetime(stamps, errors="coerce", utc=True)
    return list(dates) if dates.notna().all() else []


def _refuse_overlaps(vehicle: Vehicle, spans: Mapping[str, list[tuple[str, object, object]]]):
    """A :class:`ConfigError` where two identification windows of one record share more than
    an instant: the fit would count their common samples twice, as if the tunnel had
    measured them twice, and its intervals would be too narrow."""
    for display, windows in spans.items():
        ordered = sorted(windows, key=lambda w: w[1])
        for (a, _, a_end), (b, b_start, _) in zip(ordered, ordered[1:], strict=False):
            if b_start < a_end:
                raise ConfigError(
                    vehicle.path,
                    "windows.identification",
                    f"{a}, {b}",
                    f"the windows overlap on {display} from {b_start} to {a_end}: the fit "
                    "would count those samples twice (its intervals too narrow); cut them "
                    "apart or join them into one window",
                )


def _code_version() -> str:
    """Digest of the code that reads and judges the values, this module's imports in turn
    (:func:`railtherm.codedigest.code_digest`): a change re-checks them."""
    return codedigest.code_digest(__file__)


def check_study_values(
    study: Study,
    digests: DigestCache,
    cache: str | os.PathLike[str],
    workdir: str | os.PathLike[str] = ".",
    skip: Callable[[str], bool] = lambda path: False,
) -> list[str]:
    """:func:`check_values` for every vehicle of ``study`` whose raw files exist and are not
    ``skip``-ped (files a workflow writes itself), remembered in the JSON file ``cache`` by a
    digest of the vehicle's validated config, its raw files' contents and this code: a study
    parsed again re-reads nothing that passed before. Returns the ids checked now."""
    code = _code_version()
    try:
        with open(cache, encoding="utf-8") as stream:
            passed = set(json.load(stream))
    except (OSError, ValueError, TypeError):
        passed = set()  # a missing or broken cache is only a cache
    checked = []
    for vehicle in study.vehicles.values():
        files = [os.path.join(str(workdir), f) for f in vehicle.files()]
        if any(skip(f) or not os.path.isfile(f) for f in vehicle.files()):
            continue
        h = hashlib.sha256(code.encode())
        h.update(json.dumps(vehicle.data, sort_keys=True, default=str).encode())
        for f in files:
            h.update(digests.digest(f).encode())
        key = h.hexdigest()
        if key in passed:
            continue
        check_values(vehicle, workdir)
        passed.add(key)
        checked.append(vehicle.id)
    if checked:
        try:
            os.makedirs(os.path.dirname(os.path.abspath(cache)), exist_ok=True)
            tmp = f"{cache}.{os.getpid()}.tmp"
            with open(tmp, "w", encoding="utf-8") as stream:
                json.dump(sorted(passed), stream)
            os.replace(tmp, cache)
        except OSError:
            pass  # an unwritable cache costs time, not correctness
    return checked
