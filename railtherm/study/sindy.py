"""Optional SINDy cross-check of the grey-box structure (paper section 4, eqs. 7-8 and 14).

Told nothing of the structure, sparse identification fits the linear library

    dx/dt = Xi [T, T_veh, T_o, Q_H],   x = [T, T_veh],  time in hours, Q_H in kW,

and says which terms the data need. The grey box (eq. 14) has all four terms in dT/dt and
only T and T_veh in dT_veh/dt: no heat path from the body straight to the outdoor air (no T_o
term) and no heating of the body (no Q_H term). Its coefficients are implied by the PEM fit:

    dT/dt     = -(kA + K_veh)/C T + K_veh/C T_veh + kA/C T_o + 1/C Q_H
    dT_veh/dt =  K_veh/C_veh T - K_veh/C_veh T_veh

Method (the choice is justified by the study in docs/sindy.md, ``benchmarks/sindy_study.py``):

- derivatives by pysindy's ``FiniteDifference`` (second-order central differences) of the
  recorded states; each logged input averaged over the interval the difference spans,
  u_mid[k] = (u[k-1] + u[k]) / 2, which removes the half-sample bias of zero-order-held inputs;
- features by pysindy's ``PolynomialLibrary(degree=1, include_bias=False)`` (a bias would be
  collinear with sensor offsets);
- sequentially thresholded least squares (pysindy ``STLSQ``), one state equation at a time,
  with the threshold relative to that equation's largest coefficient: the two equations'
  scales differ by up to three decades (K_veh/C_veh against kA/C), so no single absolute
  threshold serves both;
- 95 % intervals of the unthresholded coefficients by a moving-block bootstrap over the
  samples (blocks long against the slow dynamics' correlation, fixed seed).

Verdict per vehicle: ``data too poor to say`` when the unthresholded fit is not a physical
two-node network (unstable, wrong signs, no significant coupling) or its fast time constant is
below two sample steps; otherwise ``structure contradicted`` naming each term SINDy keeps that
eq. 14 lacks (or drops that eq. 14 needs), with its interval excluding zero; otherwise
``structure confirmed``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from railtherm.records import FitRecord

STATES = ("T", "T_veh")
INPUTS = ("T_o", "Q_H")
FEATURES = STATES + INPUTS
EQUATIONS = ("dT/dt", "dT_veh/dt")
# eq. 14: which terms the grey box has (rows: equations, columns: FEATURES)
STRUCTURE = np.array([[True, True, True, True], [True, True, False, False]])
HOUR = 3600.0
KW = 1000.0


def _pysindy():
    """pysindy, imported when the cross-check runs (an optional extra of railtherm)."""
    try:
        import pysindy
    except ImportError:
        raise ImportError(
            "the SINDy cross-check needs pysindy: pip install 'railtherm[sindy]' "
            "(or switch it off with sindy: {enabled: false} in the study config)"
        ) from None
    return pysindy


DERIVATIVES = {
    "finite_difference": lambda: _pysindy().FiniteDifference(order=2),
    "smoothed_finite_difference": lambda: _pysindy().SmoothedFiniteDifference(),
}

CONFIRMED = "structure confirmed"
CONTRADICTED = "structure contradicted"
TOO_POOR = "data too poor to say"


@dataclass(frozen=True)
class Settings:
    """The knobs of the cross-check (config ``sindy:``)."""

    threshold: float = 0.1  # STLSQ threshold relative to the equation's largest coefficient
    n_bootstrap: int = 200
    block_h: float = 2.0  # moving-block length of the bootstrap (hours)
    seed: int = 0
    min_fast_steps: float = 2.0  # fast time constant below this many sample steps: too poor
    # derivative treatment (docs/sindy.md compares them): "finite_difference" (central,
    # second order) or "smoothed_finite_difference" (Savitzky-Golay, pysindy's defaults)
    derivative: str = "finite_difference"
    mid_inputs: bool = True  # inputs averaged over the interval the difference spans

    def __post_init__(self):
        if self.derivative not in DERIVATIVES:
            raise ValueError(f"derivative {self.derivative!r}: one of {sorted(DERIVATIVES)}")


@dataclass
class Result:
    """What :func:`cross_check` found for one vehicle."""

    coefficients: np.ndarray  # thresholded Xi (2 x 4), 1/h and K/(h kW)
    unthresholded: np.ndarray  # least squares, all terms
    lo: np.ndarray  # 95 % bootstrap interval of the unthresholded coefficients
    hi: np.ndarray
    verdict: str
    reasons: list[str]
    grey_box: np.ndarray | None = None  # the PEM-implied Xi, same units
    n_samples: int = 0
    step_s: float = 0.0
    tau_fast_h: float = float("nan")
    notes: list[str] = field(default_factory=list)

    def support(self) -> np.ndarray:
        return self.coefficients != 0

    def to_dict(self, settings: Settings) -> dict[str, Any]:
        terms = []
        for i, eq in enumerate(EQUATIONS):
            for j, feat in enumerate(FEATURES):
                entry = {
                    "equation": eq,
                    "term": feat,
                    "in_structure": bool(STRUCTURE[i, j]),
                    "kept": bool(self.coefficients[i, j] != 0),
                    "coefficient": float(self.coefficients[i, j]),
                    "least_squares": float(self.unthresholded[i, j]),
                    "ci95": [float(self.lo[i, j]), float(self.hi[i, j])],
                    "significant": bool(self.lo[i, j] > 0 or self.hi[i, j] < 0),
                }
                if self.grey_box is not None:
                    entry["grey_box"] = float(self.grey_box[i, j])
                terms.append(entry)
        return {
            "verdict": self.verdict,
            "reasons": list(self.reasons),
            "notes": list(self.notes),
            "units": "1/h for T, T_veh, T_o terms; K/(h kW) for Q_H terms",
            "method": {
                "library": "linear, no bias (pysindy PolynomialLibrary degree 1)",
                "derivative": "pysindy FiniteDifference (central, order 2); inputs averaged "
                "over the interval the difference spans",
                "optimizer": "pysindy STLSQ per equation, threshold relative to the "
                "equation's largest coefficient",
                "threshold": settings.threshold,
                "bootstrap": {
                    "resamples": settings.n_bootstrap,
                    "block_h": settings.block_h,
                    "seed": settings.seed,
                },
            },
            "samples": self.n_samples,
            "step_s": self.step_s,
            "tau_fast_h": None if not np.isfinite(self.tau_fast_h) else float(self.tau_fast_h),
            "terms": terms,
        }


def grey_box_coefficients(kA: float, C: float, K_veh: float, C_veh: float) -> np.ndarray:
    """Xi implied by the second-order model (eqs. 7-8), in 1/h and K/(h kW)."""
    return (
        np.array(
            [
                [-(kA + K_veh) / C, K_veh / C, kA / C, KW / C],
                [K_veh / C_veh, -K_veh / C_veh, 0.0, 0.0],
            ]
        )
        * HOUR
    )


def _regression(
    windows: Sequence[pd.DataFrame], settings: Settings
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Rows of the library Theta, the derivatives dx/dt and a block label per row (the
    window index), with the sample step (s). Edge rows of each window are dropped."""
    ps = _pysindy()
    library = ps.PolynomialLibrary(degree=1, include_bias=False)
    differentiate = DERIVATIVES[settings.derivative]()
    thetas, dxs, labels, steps = [], [], [], []
    for w_i, w in enumerate(windows):
        t = w["time"].to_numpy(float) / HOUR
        x = w[list(STATES)].to_numpy(float)
        u = np.column_stack([w["T_o"].to_numpy(float), w["Q_H"].to_numpy(float) / KW])
        u_mid = u.copy()
        if settings.mid_inputs:
            u_mid[1:] = 0.5 * (u[1:] + u[:-1])
        dx = differentiate(x, t)
        theta = library.fit_transform(np.column_stack([x, u_mid]))
        keep = np.zeros(len(t), bool)
        keep[1:-1] = True
        ok = np.isfinite(theta).all(axis=1) & np.isfinite(x).all(axis=1)
        keep[1:-1] &= ok[:-2] & ok[1:-1] & ok[2:]  # a difference needs both neighbours
        thetas.append(theta[keep])
        dxs.append(dx[keep])
        labels.append(np.full(int(keep.sum()), w_i))
        steps.append(float(np.median(np.diff(w["time"].to_numpy(float)))))
    return np.vstack(thetas), np.vstack(dxs), np.concatenate(labels), float(np.median(steps))


def _stlsq(theta: np.ndarray, dx: np.ndarray, threshold: float) -> np.ndarray:
    """STLSQ per equation, threshold relative to the equation's largest LS coefficient."""
    ps = _pysindy()
    xi = np.zeros((dx.shape[1], theta.shape[1]))
    for i in range(dx.shape[1]):
        full = np.linalg.lstsq(theta, dx[:, i], rcond=None)[0]
        scale = np.max(np.abs(full))
        opt = ps.STLSQ(threshold=threshold * scale, alpha=0.0)
        opt.fit(theta, dx[:, i])
        xi[i] = np.ravel(opt.coef_)
    return xi


def _block_bootstrap(
    theta: np.ndarray, dx: np.ndarray, block: int, settings: Settings
) -> tuple[np.ndarray, np.ndarray]:
    """95 % percentile intervals of the LS coefficients, moving blocks of ``block`` rows."""
    rng = np.random.default_rng(settings.seed)
    n = len(dx)
    block = max(1, min(block, n))
    starts = np.arange(n - block + 1)
    n_blocks = int(np.ceil(n / block))
    draws = np.empty((settings.n_bootstrap, dx.shape[1], theta.shape[1]))
    offsets = np.arange(block)
    for b in range(settings.n_bootstrap):
        rows = (rng.choice(starts, n_blocks)[:, None] + offsets).ravel()[:n]
        draws[b] = np.linalg.lstsq(theta[rows], dx[rows], rcond=None)[0].T
    lo, hi = np.percentile(draws, [2.5, 97.5], axis=0)
    return lo, hi


def _oscillating(eig: np.ndarray) -> bool:
    """Whether the eigenvalues are a complex pair: a mode that oscillates, which no network
    of capacities and conductances has."""
    return bool(np.any(np.abs(eig.imag) > 1e-9 * np.abs(eig).max()))


def _eigenvalues_text(eig: np.ndarray) -> str:
    """The eigenvalues for people: real ones in ascending order, a complex pair as
    "a ± bi" (printing its real parts alone showed two equal, real, stable modes)."""
    if _oscillating(eig):
        e = eig[np.argmax(eig.imag)]
        return f"a complex pair {e.real:.3g} ± {abs(e.imag):.3g}i"
    return ", ".join(f"{v:.3g}" for v in np.sort(eig.real))


def _physical(xi: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> list[str]:
    """Why the unthresholded fit is not a two-node thermal network (empty if it is)."""
    reasons = []
    A = xi[:, :2]
    eig = np.linalg.eigvals(A)
    if np.any(eig.real >= 0) or _oscillating(eig):
        reasons.append(
            "the identified state matrix is not that of a cooling two-node network "
            f"(eigenvalues {_eigenvalues_text(eig)} 1/h)"
        )
    if lo[0, 1] <= 0 or lo[1, 0] <= 0:
        reasons.append(
            "no significant coupling between air and body (the 95 % interval of "
            "K_veh/C or K_veh/C_veh reaches zero or below)"
        )
    if lo[0, 3] <= 0:
        reasons.append("no significant heating term 1/C in dT/dt")
    return reasons


def cross_check(
    windows: Sequence[pd.DataFrame],
    settings: Settings = Settings(),
    grey_box: np.ndarray | None = None,
) -> Result:
    """SINDy on the tidy identification windows (columns time [s], T, T_veh, T_o [degC],
    Q_H [W]) and the verdict against eq. 14."""
    theta, dx, labels, step = _regression(windows, settings)
    full = np.linalg.lstsq(theta, dx, rcond=None)[0].T
    block = int(round(settings.block_h * HOUR / step))
    lo, hi = _block_bootstrap(theta, dx, block, settings)
    xi = _stlsq(theta, dx, settings.threshold)
    eig = np.linalg.eigvals(full[:, :2])
    # the fast time constant of two real, stable modes (none for a pair that oscillates)
    stable = np.all(eig.real < 0) and not _oscillating(eig)
    tau_fast = float(1 / np.max(-eig.real)) if stable else float("nan")
    reasons = _physical(full, lo, hi)
    if not reasons and tau_fast * HOUR < settings.min_fast_steps * step:
        reasons.append(
            f"the fast time constant {tau_fast * 60:.3g} min is below "
            f"{settings.min_fast_steps:g} sample steps ({step:g} s): air and body cannot be "
            "told apart"
        )
    result = Result(
        coefficients=xi,
        unthresholded=full,
        lo=lo,
        hi=hi,
        verdict=TOO_POOR,
        reasons=reasons,
        grey_box=grey_box,
        n_samples=len(dx),
        step_s=step,
        tau_fast_h=tau_fast,
    )
    if reasons:
        return result
    support = xi != 0
    significant = (lo > 0) | (hi < 0)
    extra = [
        (i, j) for i, j in zip(*np.nonzero(support & ~STRUCTURE), strict=True) if significant[i, j]
    ]
    missing = list(zip(*np.nonzero(~support & STRUCTURE), strict=True))
    for i, j in extra:
        sign = "+" if full[i, j] > 0 else "-"
        result.reasons.append(
            f"{EQUATIONS[i]} needs a {FEATURES[j]} term that eq. 14 lacks (STLSQ "
            f"{sign}{abs(xi[i, j]):.3g}; least squares {full[i, j]:.3g}, 95 % interval "
            f"[{lo[i, j]:.3g}, {hi[i, j]:.3g}])"
        )
    for i, j in missing:
        result.reasons.append(
            f"{EQUATIONS[i]} does without the {FEATURES[j]} term of eq. 14 "
            f"(least squares {full[i, j]:.3g}, 95 % interval [{lo[i, j]:.3g}, {hi[i, j]:.3g}])"
        )
    for i, j in zip(*np.nonzero(support & ~STRUCTURE & ~significant), strict=True):
        result.notes.append(
            f"{EQUATIONS[i]} keeps a {FEATURES[j]} term above the threshold whose 95 % "
            "interval includes zero: not counted against the structure"
        )
    result.verdict = CONTRADICTED if result.reasons else CONFIRMED
    return result


def _param(fit: FitRecord, name: str) -> tuple[float, float, float]:
    """(value, lo, hi) of a fit parameter (its combined interval; a fixed one's value at
    both ends); NaN throughout for one the data do not determine
    (railtherm.estimation.pem.identification), so no coefficient is implied from it."""
    entry = fit.parameters[name]
    if not entry.identified:
        return math.nan, math.nan, math.nan
    lo, hi = entry.ci95_combined or (entry.value, entry.value)
    return entry.value, lo, hi


def grey_box_from_fit(fit: FitRecord) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Xi implied by a second-order PEM fit (fit_order2.yaml) with 95 % bounds by interval
    arithmetic over the parameters' 95 % intervals (conservative: ignores their correlation)."""
    kA, C, K, Cv = (np.array(_param(fit, p)) for p in ("kA", "C", "K_veh", "C_veh"))
    xi = grey_box_coefficients(kA[0], C[0], K[0], Cv[0])
    with np.errstate(divide="ignore", invalid="ignore"):  # a bound at 0 or infinity
        corners = np.array(
            [
                grey_box_coefficients(a, c, k, cv)
                for a in kA[1:]
                for c in C[1:]
                for k in K[1:]
                for cv in Cv[1:]
            ]
        )
    unbounded = np.isnan(corners).any(axis=0)  # 0 x inf, or not identified: says nothing
    filled = np.where(np.isnan(corners), 0.0, corners)
    lo, hi = filled.min(axis=0), filled.max(axis=0)
    return xi, np.where(unbounded, -np.inf, lo), np.where(unbounded, np.inf, hi)


def for_vehicle(
    vehicle: Mapping[str, Any],
    windows: Sequence[pd.DataFrame],
    fit: FitRecord | None,
    settings: Settings = Settings(),
) -> dict[str, Any]:
    """sindy.yaml of one vehicle: the cross-check and, with a second-order fit, the grey box's
    coefficients beside SINDy's."""
    grey = grey_box_from_fit(fit) if fit is not None else None
    result = cross_check(windows, settings, grey[0] if grey else None)
    out = {
        "vehicle": vehicle["id"],
        "synthetic": bool(vehicle.get("synthetic", False)),
        **result.to_dict(settings),
    }
    if grey is not None:
        _, g_lo, g_hi = grey
        for term, (i, j) in zip(out["terms"], np.ndindex(2, 4), strict=True):
            term["grey_box_ci95"] = [float(g_lo[i, j]), float(g_hi[i, j])]
            lo, hi = term["ci95"]
            # an unbounded grey-box interval agrees with anything: no comparison then
            bounded = np.isfinite(g_lo[i, j]) and np.isfinite(g_hi[i, j])
            agrees = bool(lo <= g_hi[i, j] and g_lo[i, j] <= hi) if bounded else None
            term["agrees_with_grey_box"] = agrees
    return out


_SHORT = {"dT/dt": "T", "dT_veh/dt": "T_veh"}


def summary_table(
    results: Mapping[str, Mapping[str, Any]], source: str | Mapping[str, str]
) -> pd.DataFrame:
    """One row per vehicle (from its sindy.yaml): verdict, the terms kept against eq. 14,
    SINDy's coefficient of each term (``<eq>:<term>``, 0 where dropped) and the PEM-implied
    one (``pem_<eq>:<term>``), the reasons and the data source (``source``: one for every
    row, or each vehicle's)."""
    rows = []
    for vid, data in results.items():
        row: dict[str, Any] = {"vehicle": vid, "verdict": data["verdict"]}
        row["extra_terms"] = ";".join(
            f"{t['equation']} {t['term']}" + ("" if t["significant"] else " (interval holds 0)")
            for t in data["terms"]
            if t["kept"] and not t["in_structure"]
        )
        row["dropped_terms"] = ";".join(
            f"{t['equation']} {t['term']}"
            for t in data["terms"]
            if t["in_structure"] and not t["kept"]
        )
        for t in data["terms"]:
            row[f"{_SHORT[t['equation']]}:{t['term']}"] = t["coefficient"]
        for t in data["terms"]:
            if t["in_structure"]:
                row[f"pem_{_SHORT[t['equation']]}:{t['term']}"] = t.get("grey_box", float("nan"))
        row["tau_fast_h"] = data.get("tau_fast_h")
        row["reasons"] = " | ".join(data["reasons"])
        row["source"] = source if isinstance(source, str) else source[vid]
        rows.append(row)
    return pd.DataFrame(rows)


def summary_markdown(table: pd.DataFrame, source: str) -> str:
    """The summary table for readers: verdict, extra terms and the key coefficients."""

    def pair(r: pd.Series, key: str) -> str:
        pem = r.get(f"pem_{key}", float("nan"))
        return f"{r[key]:.3g} ({pem:.3g})" if np.isfinite(pem) else f"{r[key]:.3g}"

    view = pd.DataFrame(
        {
            "vehicle": table["vehicle"],
            "verdict": table["verdict"],
            "terms eq. 14 lacks, kept": table["extra_terms"].replace("", "–"),
            "dT_veh/dt: T_o (1/h)": [f"{x:.3g}" for x in table["T_veh:T_o"]],
            "K_veh/C_veh: SINDy (PEM) (1/h)": [pair(r, "T_veh:T") for _, r in table.iterrows()],
            "kA/C: SINDy (PEM) (1/h)": [pair(r, "T:T_o") for _, r in table.iterrows()],
            "1/C: SINDy (PEM) (K/(h kW))": [pair(r, "T:Q_H") for _, r in table.iterrows()],
        }
    )
    lines = [
        f"**SINDy cross-check of the grey-box structure (eq. 14).** Data: {source}.",
        "",
        view.to_markdown(index=False, disable_numparse=True),
        "",
        "- Coefficients: SINDy's (STLSQ, 0 where dropped), in brackets those implied by the "
        "second-order PEM fit. Reasons per vehicle: results/tables/sindy.csv and "
        "results/vehicles/<id>/sindy.yaml. Method: docs/sindy.md.",
        "",
    ]
    return "\n".join(lines)
