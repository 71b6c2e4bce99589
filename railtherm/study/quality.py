"""The quality of a fit as the study records and judges it: the measures of each compared
output written to fit files (:func:`summary`: R² of eq. 21, NRMSE fit, RMSE, AIC, BIC and the
residuals' whiteness, from :mod:`railtherm.estimation.metrics`) and the plain verdict
(:func:`verdict`): "fit acceptable" or "assumptions in doubt", with its reasons."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any

from railtherm.estimation.metrics import Whiteness, aic, bic, ljung_box, nrmse_fit, paired, r2, rmse

__all__ = ["ACCEPTABLE", "DEFAULT_THRESHOLDS", "IN_DOUBT", "summary", "verdict"]

ACCEPTABLE = "fit acceptable"
IN_DOUBT = "assumptions in doubt"

#: Defaults of :func:`verdict`, named and valued as the keys of a vehicle's ``check`` section
#: (railtherm/schemas/vehicle.schema.yaml, where each value's reason is given): the
#: climatic-wind-tunnel values. ``r2_min``: R^2 (eq. 21) below this puts the assumptions in
#: doubt. ``min_effective_samples``: residuals whose autocorrelation time leaves fewer than this
#: many independent samples (m / tau) are *strongly coloured*: the error is a few slow
#: excursions, i.e. dynamics the model does not have. ``require_white``: also count a rejected
#: Ljung-Box test (Holm-adjusted p < ``whiteness_alpha`` over the series judged) as a reason;
#: off by default, since
#: simulation-error residuals of thermal data are practically never white.
DEFAULT_THRESHOLDS: dict[str, Any] = {
    "r2_min": 0.9,
    "min_effective_samples": 10.0,
    "require_white": False,
    "whiteness_alpha": 0.05,
}


def summary(y: Any, yhat: Any, p: int, lags: int | None = None) -> dict[str, float | int]:
    """All measures of one output series (y measured, yhat simulated, p estimated parameters
    including estimated initial states), as plain values in a stable order, for YAML."""
    yy, yh = paired(y, yhat)
    e = yy - yh
    m = int(yy.size)
    ssr = float(e @ e)
    out: dict[str, float | int] = {
        "m": m,
        "p": int(p),
        "r2": r2(yy, yh),
        "nrmse_fit": nrmse_fit(yy, yh),
        "rmse": rmse(yy, yh),
        "ssr": ssr,
        "aic": aic(ssr, m, p) if m and ssr > 0 else math.nan,
        "bic": bic(ssr, m, p) if m and ssr > 0 else math.nan,
    }
    w = ljung_box(e, lags)
    for key, value in w.to_dict().items():
        if key != "m":
            out[key] = value
    return out


def _message(flag: Any) -> str:
    """The plain sentence of an identifiability flag: a str, a mapping with 'message', an
    object with ``.message``, or a (code, message) pair."""
    if isinstance(flag, str):
        return flag
    if isinstance(flag, Mapping):
        return str(flag.get("message", flag.get("code", flag)))
    if hasattr(flag, "message"):
        return str(flag.message)
    if isinstance(flag, tuple) and len(flag) == 2:
        return str(flag[1])
    return str(flag)


def _named(value: Any) -> list[tuple[str, Any]]:
    """A single value as [("", value)], a mapping as its (name, value) items."""
    if value is None:
        return []
    if isinstance(value, Mapping) and not (value and "ljung_box_p" in value):
        return [(str(k), v) for k, v in value.items()]
    return [("", value)]


def _get(w: Any, attr: str, key: str) -> float:
    return float(w[key]) if isinstance(w, Mapping) else float(getattr(w, attr))


def verdict(
    r2: float | Mapping[str, float],
    flags: Iterable[Any] = (),
    whiteness: Whiteness | Mapping[str, Any] | None = None,
    thresholds: Mapping[str, Any] | None = None,
) -> tuple[str, list[str]]:
    """("fit acceptable" | "assumptions in doubt", reasons): a small pure function.

    r2: R^2 (eq. 21), or a mapping {name: R^2} (e.g. per experiment or per cross-validation
    fold); a NaN R^2 is a reason. flags: the fit's identifiability flags (sentences, or objects
    / mappings carrying a ``message``); each one is a reason. whiteness: a :class:`Whiteness`
    (or its ``to_dict()``), or a mapping {name: Whiteness}; with ``require_white`` their
    Ljung-Box tests are one family, judged by Holm's procedure at ``whiteness_alpha``
    (:func:`railtherm.estimation.diagnostics.holm`: white residuals put the fit in doubt with
    probability at most that level, however many series). thresholds: overrides of
    :data:`DEFAULT_THRESHOLDS` (an unknown name is a ValueError naming the known ones).
    Reasons are plain sentences with the numbers; the label is "fit acceptable" exactly when
    there are none."""
    t = {**DEFAULT_THRESHOLDS, **(thresholds or {})}
    unknown = set(t) - set(DEFAULT_THRESHOLDS)
    if unknown:
        raise ValueError(
            f"unknown verdict thresholds: {sorted(unknown)} (known: {sorted(DEFAULT_THRESHOLDS)})"
        )
    reasons: list[str] = []
    for name, value in _named(r2):
        where = f" ({name})" if name else ""
        value = float(value)
        if math.isnan(value):
            reasons.append(f"R^2{where} is undefined (no usable rows or a constant measurement).")
        elif value < t["r2_min"]:
            reasons.append(f"R^2{where} = {value:.4f} is below {t['r2_min']:g}.")
    reasons.extend(_message(f) for f in flags)
    named = _named(whiteness)
    if t["require_white"] and named:
        from railtherm.estimation.diagnostics import holm

        adjusted = holm([_get(w, "p_value", "ljung_box_p") for _, w in named])
    family = f"Holm over {len(named)} series, " if len(named) > 1 else ""
    for i, (name, w) in enumerate(named):
        where = f" ({name})" if name else ""
        n_eff = _get(w, "effective_samples", "effective_samples")
        tau = _get(w, "tau", "autocorrelation_time")
        if n_eff < t["min_effective_samples"]:
            reasons.append(
                f"The residuals{where} are strongly coloured: autocorrelation time {tau:.4g} "
                f"samples leaves {n_eff:.3g} independent samples (< "
                f"{t['min_effective_samples']:g}); the model misses a slow dynamic."
            )
        p = _get(w, "p_value", "ljung_box_p")
        if t["require_white"] and adjusted[i] < t["whiteness_alpha"]:
            shown = f"p = {p:.3g}, {family}adjusted {adjusted[i]:.3g}" if family else f"p = {p:.3g}"
            reasons.append(
                f"The residuals{where} are not white (Ljung-Box {shown} < "
                f"{t['whiteness_alpha']:g})."
            )
    return (IN_DOUBT if reasons else ACCEPTABLE), reasons
