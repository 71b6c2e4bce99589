"""The assessment of a planned programme for readers (``railtherm design``): the predicted
95 % widths at the prior's centre and over its draws, the target's probability, the highest
temperatures, and what the loop of static kA and fit, the k window's steadiness and a
search's binding limits mean for them (:mod:`railtherm.study.design` computes them)."""

from __future__ import annotations

import math

from railtherm.study import limits
from railtherm.study.design import LOOP_GAIN_FLAG, LOOP_GAIN_MAX, Assessment

__all__ = ["markdown"]


def _quantity(key: str, value: float) -> str:
    """An uncertainty of a programme with its unit: K for a temperature, % for a ratio."""
    if key.endswith("_rel"):
        return f"{key} {100 * value:.3g} %"
    return f"{key} {value:.3g} K"


def markdown(assessment: Assessment) -> str:
    """The assessment for readers: per estimated parameter its predicted ± (95 %) at the
    central parameters, over the prior's draws the median and 90 % range, and the share of
    draws that identify it; then the target's probability."""
    a = assessment
    if a.prior.noise_K:
        tau = a.prior.tau_at(a.programme.step_s)
        level = ", ".join(
            f"{s} {a.prior.noise_K[s]:.3g} K (autocorrelation time "
            f"{tau.get(s, 1.0):.3g} samples of {a.programme.step_s:g} s)"
            for s in a.prior.noise_K
        )
        residuals = f"residuals as the prior's fits show them: {level}"
    else:
        noise = ", ".join(f"{s} {v:.3g} K" for s, v in a.programme.noise_K.items())
        residuals = f"residuals white at the programme's sensor noise: {noise}"
    systematic = ", ".join(_quantity(k, v) for k, v in a.programme.systematic.items()) or "none"
    inputs = ", ".join(_quantity(k, v) for k, v in a.programme.input_noise.items()) or "none"
    method = "eq. 10 corrected for the heat stored" if a.programme.storage_correction else "eq. 10"
    lines = [
        f"Programme {a.programme.name} ({a.programme.hours:.4g} h, logger step "
        f"{a.programme.step_s:g} s) for {a.prior.source}; {residuals}; systematic "
        f"uncertainties (1 sd): {systematic}; logged inputs' noise (1 sd): {inputs}; static "
        f"k window: the first phase's last {a.programme.k_window_h:.3g} h, {method}.",
        "",
        "| parameter | predicted ± (95 %) | over the prior: median [5 %, 95 %] | identifiable |",
        "|---|---|---|---|",
    ]

    def pct(x: float) -> str:
        return "not identifiable" if not math.isfinite(x) else f"{100 * x:.3g} %"

    for p in a.prior.free:
        central = pct(a.central.half_width[p]) if a.central.identifiable[p] else "not identifiable"
        q05, q50, q95 = a.spread[p]
        over = f"{pct(q50)} [{pct(q05)}, {pct(q95)}]" if a.prior.draws else "no draws"
        share = (
            f"{100 * a.identifiable[p]:.0f} % of draws"
            if a.prior.draws
            else ("yes" if a.central.identifiable[p] else "no")
        )
        lines.append(f"| {p} | {central} | {over} | {share} |")
    if a.target is not None:
        name, goal = a.target
        lines += ["", f"{name} within ±{100 * goal:g} % with probability {a.probability:.2f}."]
    highest = ", ".join(
        f"{limits.WHAT.get(s, s)} {v:.1f} degC" for s, v in a.peaks.items() if math.isfinite(v)
    )
    if highest:
        band = f"{100 * limits.UPPER_BAND:g} %" if a.prior.draws else "the central parameters"
        lines += ["", f"Highest temperatures (at {band} of the prior): {highest}."]
    for v in a.violations:
        lines.append(f"Beyond a limit: {v}.")
    gS = a.central.loop_gain
    if gS >= LOOP_GAIN_MAX:
        lines.append(
            f"The storage-corrected static kA and the fit pull each other away (g·S = "
            f"{gS:.2f}, at least {LOOP_GAIN_MAX:g}): their alternation runs away, the widths "
            "above are a linear prediction that is too narrow there (--replicates runs the "
            "virtual tunnel), and a search for a better programme keeps out of it (lengthen "
            "the first phase, its steady state)."
        )
    elif gS > LOOP_GAIN_FLAG:
        lines.append(
            f"The storage-corrected static kA and the fit amplify each other's errors "
            f"(g·S = {gS:.2f}, a factor {1 / (1 - gS):.2g}): the estimates' spread has tails "
            "beyond this prediction."
        )
    if a.k_storage_share > limits.NOT_STEADY_SHARE:
        lines.append(
            f"The static k window is not steady: {100 * a.k_storage_share:.3g} % of its heat "
            "goes into storage, which eq. 10 books as loss (start the programme steady, or "
            "lengthen the first phase)."
        )
    lines += [f"{n}." for n in a.notes]
    return "\n".join(lines)
