"""Clocks checked against the physics: the offset of each data-acquisition system's clock
(a vehicle's ``sources``, :mod:`railtherm.data.sources`) estimated from the record itself.

The air temperature T answers the heater power Q_H at once (eq. 7: dT/dt jumps by dQ_H / C
when the heater steps) and the tunnel air T_o through kA. A source whose clock is off by d
seconds moves its columns by d against the others, and the model fits worse the further it
is moved. So for each source other than the one that logs the indoor air (the reference),
the fit is repeated with that source's columns of the tidy tables moved by a few tidy steps
either way, each time from the fitted values (a profile of the fit's criterion over the
shift), and the shift that fits best is the source's offset:

- the criterion: the Kalman fit's negative log-likelihood (-2 log L difference); for output
  error the sum of squared simulation errors, as N_eff ln(SSE(d) / SSE_min), with N_eff the
  effective number of independent residuals (n / tau, tau their integrated autocorrelation
  time), so that coloured residuals do not make the profile over-confident;
- the estimate: the parabola through the best shift and its two neighbours; its 95 %
  interval: where the profile rises by 3.84 (chi-square, one degree of freedom), from the
  parabola, widened in quadrature by the resolution of moving tidy means (what a power
  switching within a step looks like moved by part of a step: taken as uniform over a step,
  1.96 step / sqrt(12));
- moving a column by d: temperatures (tidy means) interpolated linearly, powers (means over
  each step) from their cumulative energy, exact for a power constant over each step.

An offset whose interval excludes 0 and that exceeds a tidy step is a reason of the verdict
(:func:`reasons`): a fit on clocks that disagree is not acceptable until the offset is
declared (``sources.<name>.clock_offset_s``). Output-error and Kalman fits alike. A profile
whose best shift lies at the reach's end is a reason only where the clocks as declared fit
significantly worse (a rise above 3.84 at 0); one that never rises that far cannot judge the
clock (a source whose channels hardly move). A source that shares a channel group with
another is moved by the groups it logs alone.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from railtherm.data.ingest import IRRADIANCE, irradiance_names
from railtherm.estimation.acf import autocorrelation_time

# the tidy columns each channel group becomes, and how a shift moves them
TEMPERATURE_COLUMNS = {
    "indoor_air": ("T", "T_spread"),
    "surface": ("T_veh",),
    "outdoor_air": ("T_o",),
}
POWER_COLUMNS = {"heater_power": "Q_heater", "fan_power": "Q_fan", "heat_flows": "Q_known"}
CHI2_95 = 3.841458820694124  # the 95 % quantile of chi-square with one degree of freedom
STEPS = 5  # the profile's reach, in tidy steps either way


def _group_sources(vehicle_data: Mapping[str, Any]) -> dict[str, set[str]]:
    channels = vehicle_data["channels"]
    groups = (*TEMPERATURE_COLUMNS, *POWER_COLUMNS, IRRADIANCE)
    return {g: {c.get("source") for c in channels.get(g) or []} for g in groups}


def reference_source(vehicle_data: Mapping[str, Any]) -> str:
    """The source that logs the indoor air T (its first channel's): the clock the others are
    measured against."""
    return vehicle_data["channels"]["indoor_air"][0]["source"]


def movable(vehicle_data: Mapping[str, Any]) -> dict[str, list[str] | str]:
    """Each source but the reference: the channel groups it alone logs (which a shift moves;
    a group it shares with another source is averaged across clocks and stays), or the
    reason it cannot be moved on its own (every group it logs is shared)."""
    groups = _group_sources(vehicle_data)
    ref = reference_source(vehicle_data)
    out: dict[str, list[str] | str] = {}
    for name in vehicle_data["sources"]:
        if name == ref:
            continue
        mine = [g for g, s in groups.items() if name in s]
        alone = [g for g in mine if len(groups[g]) == 1]
        if alone:
            out[name] = alone
        else:
            out[name] = f"its channels share channels.{mine[0]} with another source"
    return out


def shared(vehicle_data: Mapping[str, Any], name: str) -> list[str]:
    """The channel groups source ``name`` logs together with another source."""
    return [g for g, s in _group_sources(vehicle_data).items() if name in s and len(s) > 1]


def shifted(
    table: pd.DataFrame, groups: Sequence[str], shift_s: float, vehicle_data: Mapping[str, Any]
) -> pd.DataFrame:
    """``table`` with the columns of ``groups`` moved ``shift_s`` seconds later (what was
    logged at t happened at t + shift_s); Q_H summed again from its parts."""
    t = table["time"].to_numpy(dtype=float)
    step = float(np.median(np.diff(t)))
    out = table.copy()
    columns = [c for g in groups for c in TEMPERATURE_COLUMNS.get(g, ())]
    for column in columns:
        if column in out:
            out[column] = np.interp(t - shift_s, t, table[column].to_numpy(dtype=float))
    power = [POWER_COLUMNS[g] for g in groups if g in POWER_COLUMNS]
    if IRRADIANCE in groups:
        power += irradiance_names(vehicle_data)
    edges = np.append(t, t[-1] + step)
    for column in power:
        if column not in out:
            continue
        q = table[column].to_numpy(dtype=float)
        energy = np.concatenate([[0.0], np.cumsum(q * step)])

        def cumulative(s: np.ndarray, q=q, energy=energy) -> np.ndarray:
            inside = np.interp(s, edges, energy)
            before = q[0] * (s - edges[0])
            after = energy[-1] + q[-1] * (s - edges[-1])
            return np.where(s < edges[0], before, np.where(s > edges[-1], after, inside))

        a = t - shift_s
        out[column] = (cumulative(a + step) - cumulative(a)) / step
    if power:
        parts = [c for c in ("Q_heater", "Q_fan", "Q_known") if c in out]
        out["Q_H"] = sum(out[c] for c in parts)
    return out


def _criterion(result: Any) -> float:
    return float(result.cost)


def _effective(result: Any) -> float:
    """The effective number of independent residuals of an output-error fit: each record's
    residuals of each output counted as n / tau, tau their integrated autocorrelation time
    (:func:`railtherm.estimation.acf.autocorrelation_time`, as the verdict's whiteness counts
    effective samples)."""
    total = 0.0
    for r in result.residuals:
        r = np.asarray(r, dtype=float)
        for col in (r.reshape(len(r), -1) if r.ndim > 1 else r[:, None]).T:
            col = col[np.isfinite(col)]
            total += col.size / autocorrelation_time(col)
    return max(total, 1.0)


def profile(
    fit: Any,
    nominal: Any,
    tables: Mapping[str, pd.DataFrame],
    groups: Sequence[str],
    vehicle_data: Mapping[str, Any],
    step: float,
) -> dict[str, Any]:
    """The profile of the fit's criterion over shifts of ``groups`` (-STEPS..STEPS tidy steps):
    ``fit(tables) -> result`` refits from the nominal values. Returns the offset (the shift
    that fits best, s), its 95 % interval (None where the profile does not rise by 3.84
    within the reach), and the rise of the criterion at each shift."""
    kalman = getattr(nominal, "estimator", "") == "kalman"
    shifts = np.arange(-STEPS, STEPS + 1) * step
    costs = []
    for d in shifts:
        if d == 0:
            costs.append(_criterion(nominal))
            continue
        moved = {name: shifted(t, groups, float(d), vehicle_data) for name, t in tables.items()}
        try:
            costs.append(_criterion(fit(moved)))
        except (ValueError, ArithmeticError, np.linalg.LinAlgError):
            # a record moved so far that the model cannot be fitted (the Kalman filter's
            # NotEvaluable is a ValueError): no support at this shift
            costs.append(math.inf)
    costs = np.asarray(costs)
    best = int(np.argmin(costs))
    if kalman:
        rise = 2.0 * (costs - costs[best])
    else:
        rise = _effective(nominal) * np.log(costs / costs[best])
    estimate = float(shifts[best])
    lo = hi = None
    if 0 < best < shifts.size - 1 and np.isfinite(rise[best - 1 : best + 2]).all():
        y0, y1, y2 = rise[best - 1], rise[best], rise[best + 1]
        curvature = (y0 - 2.0 * y1 + y2) / step**2
        if curvature > 0:
            vertex = float(shifts[best] + 0.5 * step * (y0 - y2) / (y0 - 2.0 * y1 + y2))
            estimate = vertex
            # the profile's own half-width, and the resolution of a shift of the tidy
            # means (uniform over a step: sd step / sqrt(12)) in quadrature
            half = math.hypot(math.sqrt(CHI2_95 / (0.5 * curvature)), 1.96 * step / math.sqrt(12.0))
            lo, hi = vertex - half, vertex + half
    return {
        "shift_s": estimate,
        "ci95": None if lo is None else [lo, hi],
        "rise": {f"{d:g}": float(r) for d, r in zip(shifts, rise, strict=True)},
        "at_edge": best in (0, shifts.size - 1),
    }


def clock_offsets(
    fit: Any,
    nominal: Any,
    tables: Mapping[str, pd.DataFrame],
    vehicle_data: Mapping[str, Any],
) -> dict[str, dict[str, Any]]:
    """Each source's clock against the reference's (module docstring): ``{source: {offset_s:
    the clock_offset_s to add (its clock runs that far ahead), ci95, significant,
    reference, at_edge} or {reason}}``. ``fit(tables) -> result`` refits the model from the
    nominal fit ``nominal``.

    One source off moves the others' profiles too (the fit compensates one shifted input with
    another), so the sources are judged in turn: every source is profiled, the one whose
    alignment as declared costs the fit most is taken, its offset applied where it is
    significant, and the others are profiled again on the corrected tables."""
    step = float(np.median(np.diff(next(iter(tables.values()))["time"].to_numpy(dtype=float))))
    ref = reference_source(vehicle_data)
    out: dict[str, dict[str, Any]] = {}
    remaining: dict[str, list[str]] = {}
    for name, groups in movable(vehicle_data).items():
        if isinstance(groups, str):
            out[name] = {"reference": ref, "reason": groups}
        else:
            remaining[name] = groups
    current, base = dict(tables), nominal
    while remaining:
        found = {
            name: profile(fit, base, current, groups, vehicle_data, step)
            for name, groups in remaining.items()
        }
        worst = max(found, key=lambda n: (found[n]["rise"]["0"], n))
        for name, p in found.items():
            out[name] = _entry(name, p, remaining[name], ref, step, vehicle_data)
        if not out[worst]["significant"]:
            break  # the worst agrees: so do the others, as profiled
        current = {
            w: shifted(t, remaining[worst], found[worst]["shift_s"], vehicle_data)
            for w, t in current.items()
        }
        base = fit(current)
        del remaining[worst]
    return {name: out[name] for name in vehicle_data["sources"] if name in out}


def _entry(name, p, groups, ref, step, vehicle_data) -> dict[str, Any]:
    # data logged at t happened at t + shift: the clock runs -shift ahead
    offset = -p["shift_s"]
    ci = None if p["ci95"] is None else sorted(-v for v in p["ci95"])
    significant = ci is not None and not ci[0] <= 0.0 <= ci[1]
    if p["at_edge"]:
        # beyond the reach: at least that far off where the clocks as declared fit
        # significantly worse; a profile that hardly rises (a source whose signal stays flat
        # over the record) cannot judge the clock at all
        significant = p["rise"]["0"] > CHI2_95
    return {
        "reference": ref,
        "declared_s": float(vehicle_data["sources"][name].get("clock_offset_s", 0.0)),
        "groups": list(groups),
        "offset_s": offset,
        "ci95": ci,
        "significant": bool(significant),
        "at_edge": bool(p["at_edge"]),
        "step_s": step,
        "rise": p["rise"],
        "shared": shared(vehicle_data, name),
    }


def reasons(clocks: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """The verdict's reasons: each source whose clock offset is significant and larger than a
    tidy step, with the key to declare."""
    out = []
    for name, c in clocks.items():
        if "offset_s" not in c or not c["significant"] or abs(c["offset_s"]) <= c["step_s"]:
            continue
        declared = float(c.get("declared_s", 0.0))
        side = "ahead of" if c["offset_s"] > 0 else "behind"
        where = (
            f"beyond the {STEPS} tidy steps searched"
            if c["at_edge"]
            else f"95 % {c['ci95'][0]:.0f} to {c['ci95'][1]:.0f} s"
        )
        out.append(
            f"The clock of sources.{name} looks {abs(c['offset_s']):.0f} s {side} that of "
            f"sources.{c['reference']} ({where}), judged by the fit: declare "
            f"sources.{name}.clock_offset_s: {declared + c['offset_s']:.0f} (or correct its "
            "format.time), and fit again."
        )
    return out


def notes(clocks: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """A note per source whose clock is not a reason of the verdict: it agrees with the
    reference's, differs by less than a tidy step, or cannot be judged."""
    out = []
    for name, c in clocks.items():
        if "reason" in c:
            out.append(f"The clock of sources.{name} is not checked: {c['reason']}.")
            continue
        ci = c["ci95"]
        span = f"95 % {ci[0]:.0f} to {ci[1]:.0f} s" if ci else "the profile is flat"
        held = c.get("shared") or []
        if held:
            out.append(
                f"The clock of sources.{name} is checked on channels."
                f"{', channels.'.join(c['groups'])} alone: channels.{', channels.'.join(held)} "
                "it shares with another source, and their mean stays as logged."
            )
        if not c["significant"] and ci is None:
            rises = [r for r in c["rise"].values() if math.isfinite(r)]
            top = max(rises, default=0.0)
            how = (
                f"rises by at most {top:.2g}, below the 95 % threshold {CHI2_95:.2f}: its "
                "channels hardly move over the record"
                if top < CHI2_95
                else "has no clear minimum"
            )
            out.append(
                f"The clock of sources.{name} cannot be judged against that of "
                f"sources.{c['reference']}: over ±{STEPS} tidy steps "
                f"({STEPS * c['step_s']:g} s) the fit's profile {how}."
            )
        elif not c["significant"]:
            out.append(
                f"The clock of sources.{name} agrees with that of sources.{c['reference']} as "
                f"far as the fit resolves it at a tidy step of {c['step_s']:g} s: offset "
                f"{c['offset_s']:+.0f} s ({span}; a finer cleaning.step_s narrows it)."
            )
        elif abs(c["offset_s"]) <= c["step_s"]:
            out.append(
                f"The clock of sources.{name} differs from that of sources.{c['reference']} "
                f"by less than a tidy step ({c['step_s']:g} s): offset {c['offset_s']:+.0f} s "
                f"({span})."
            )
    return out
