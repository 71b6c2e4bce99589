"""Grey-box state-space structures of the paper (section 5.1), their exact zero-order-hold
discretisation, fast exact simulation and exact parameter sensitivities.

Inputs are u = [T_o, Q_H] (degC, W), optionally followed by irradiance channels I_i (W/m2,
:func:`with_irradiance`: solar gains a_i I_i into the air node, the envelope node or shared
between them, eq. 1); outputs y = x (C = I, D = 0, eqs. 11-12).

The structures themselves are data, one module each in :mod:`railtherm.structures`
(:class:`Structure`, :data:`STRUCTURES`): a name, the parameter and state names, and functions
giving the continuous (A, B) and their analytic derivatives with respect to each parameter.
Nothing here knows how many states a structure has.

Discrete model (eq. 15 with K = 0), input held over each step (zero-order hold, the paper's
choice)::

    x[n+1] = Ad x[n] + Bd u[n],   [[Ad, Bd], [0, I]] = expm([[A, B], [0, 0]] dt)

or, with the first-order hold (inputs linear between their samples, as pySIP and CTSM-R offer),
the exact discretisation of the system augmented by the input and its slope::

    x[n+1] = Ad x[n] + (G0 - G1) u[n] + G1 u[n+1],
    expm([[A, B, 0], [0, 0, I], [0, 0, 0]] dt) = [[Ad, G0, G1], [0, I, I], [0, 0, I]]

(G0 = int_0^dt e^{A s} ds B, G1 = int_0^dt e^{A (dt - s)} B s/dt ds). It is written as the
zero-order form with the doubled input [u[n]; u[n+1]] (:func:`forcing`) and Bd = [G0 - G1, G1],
so every recursion below serves both holds unchanged.

Simulation (:func:`simulate`) propagates the recursion without a Python loop over samples:
Ad = V diag(lambda) V^-1 (the thermal networks here have real, distinct, stable eigenvalues),
each modal coordinate z_i = (V^-1 x)_i obeys z_i[n+1] = lambda_i z_i[n] + w_i[n], which is
one first-order recursion per mode (:func:`recursion`). When Ad is not safely diagonalisable
(complex or repeated eigenvalues, ill-conditioned V) the complex Schur form Ad = Q T Q^H is used
instead: T is triangular, so the modes are solved from the last one up, each again by one
recursion, the coupling entering as an extra input. Both are exact up to rounding.

Sensitivities (:func:`sensitivities`) differentiate the discrete recursion, not the ODE::

    s_p[n+1] = Ad s_p[n] + dAd_p x[n] + dBd_p u[n],   s_p[0] = 0,

with dAd_p, dBd_p the exact Frechet derivative of the matrix exponential along
[[dA_p, dB_p], [0, 0]] dt, obtained for all parameters at once from the upper block row of
expm of the block matrix [[M, E_1, ..., E_P], [0, M, 0..], ..., [0, .., M]] (the block-triangular
identity that ``scipy.linalg.expm_frechet`` is built on; tests compare the two). The
sensitivity to the initial state is the free response dx[n]/dx0 = Ad^n, computed modally as
lambda^n and cut to zero once below 1e-30 (so the computation never walks into subnormal
floats, which are very slow).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from railtherm.structures import STRUCTURES, Structure

__all__ = [
    "HOLDS",
    "STRUCTURES",
    "Discretisation",
    "Structure",
    "discretize",
    "discretize_noise",
    "discretize_ramp",
    "discretize_zoh",
    "check_hold",
    "forcing",
    "first_order",
    "free_response",
    "free_response_head",
    "irradiance_spec",
    "modal_form",
    "parameter_sensitivities",
    "propagate",
    "second_order",
    "sensitivities",
    "simulate",
    "steady_state",
    "step_means",
    "steady_state_kA",
    "structure_for",
    "with_irradiance",
    "transition",
]

HOLDS = ("zero_order", "first_order")  # how an input varies between its samples
FREE_RESPONSE_CUT = 1e-30  # |lambda|^n below this (relative to 1) is taken as 0
_MODAL_COND_MAX = 1e8  # cond(V) above this: use the Schur form instead of eigenvectors


def expm(M: np.ndarray) -> np.ndarray:
    """``scipy.linalg.expm``, imported on first use: scipy.linalg's import is a tenth of a
    second of every job's start-up, and the jobs that only read results never discretise."""
    from scipy.linalg import expm as expm_

    return expm_(M)


def schur(a: np.ndarray, output: str = "real") -> tuple[np.ndarray, np.ndarray]:
    """``scipy.linalg.schur``, imported on first use (see :func:`expm`)."""
    from scipy.linalg import schur as schur_

    return schur_(a, output=output)


def recursion(lam: complex, w: np.ndarray, z0) -> np.ndarray:
    """z[..., 0] = z0, z[..., n + 1] = lam z[..., n] + w[..., n] along the last axis of ``w``
    (w[..., N - 1] is unused): one mode of a modal simulation, or any first-order lag
    (:func:`railtherm.estimation.loops.first_order`, bit for bit ``scipy.signal.lfilter([0,
    1], [1, -lam], w, zi=z0)``). Real when ``lam``, ``w`` and ``z0`` are real, else complex."""
    from railtherm.estimation.loops import first_order  # numba: only where a job simulates

    w = np.asarray(w)
    dtype = np.result_type(w.dtype, np.asarray(lam).dtype, np.asarray(z0).dtype, float)
    channels = np.ascontiguousarray(w.reshape(-1, w.shape[-1]), dtype=dtype)
    start = np.ascontiguousarray(np.broadcast_to(z0, w.shape[:-1]).reshape(-1), dtype=dtype)
    z = first_order(dtype.type(lam), channels, start, np.empty_like(channels))
    return z.reshape(w.shape)


# (A, B) of the paper's models by their usual names (eqs. 13, 14) and of the interior-envelope
# structure: each structure module's ``matrices``, looked up when called, so that a refused
# module stops only what uses it (railtherm.structures.REFUSED)
def _build(name: str):
    from railtherm.structures import named

    return named(name).build


def first_order(*args, **kwargs) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) of eq. 13: railtherm/structures/first_order.py's ``matrices``."""
    return _build("first_order")(*args, **kwargs)


def second_order(*args, **kwargs) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) of eq. 14: railtherm/structures/second_order.py's ``matrices``."""
    return _build("second_order")(*args, **kwargs)


def interior_envelope(*args, **kwargs) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) of railtherm/structures/interior_envelope.py's ``matrices``."""
    return _build("interior_envelope")(*args, **kwargs)


def steady_state_kA(structure: Structure, theta: Mapping[str, float]) -> float:
    """The overall heat-loss coefficient (W/K) of any structure at ``theta``, from its steady
    state (:meth:`Structure.kA_log_gradient`): eq. 10, Q_H = kA (T - T_o), holds at
    equilibrium. It equals kA itself for eqs. 13-14 and K_i K_o / (K_i + K_o) for the
    interior-envelope structure. NaN when the network has no steady state."""
    A, B = structure.matrices(theta)
    try:
        AiB = np.linalg.solve(A, B)  # the gain g = dT/dQ_H, as kA_log_gradient has it
    except np.linalg.LinAlgError:
        return math.nan
    g = -float(AiB[0, 1])
    return 1.0 / g if g > 0 and math.isfinite(g) else math.nan


APERTURE_INITIAL = 1.0  # m2: start value of an effective aperture a_i
APERTURE_BOUNDS = (1.0e-3, 1.0e3)  # m2
IRRADIANCE_NODES = ("air", "envelope", "both")  # where a solar gain a_i I_i enters (eq. 1)
SHARE_INITIAL = 0.5  # start value of the envelope's share f_i of a gain on both nodes
SHARE_BOUNDS = (1.0e-3, 1.0)  # f_i in (0, 1], estimated in log f_i like every parameter


def irradiance_spec(text: str) -> tuple[str, str]:
    """An irradiance input as a structure's name spells it, split into (input, node):
    ``"I_sol"`` -> ("I_sol", "air"), ``"I_sol@envelope"`` -> ("I_sol", "envelope")."""
    name, sep, node = str(text).partition("@")
    return name, (node if sep else "air")


@dataclass(frozen=True)
class _WithApertures:
    """(A, B) or their derivatives of a base structure with irradiance inputs appended: the
    base (A, B), and for input i the column m0 + i of B (m0 the base's number of inputs),

        B[0, m0 + i] = (1 - f_i) a_i / C_air,   B[1, m0 + i] = f_i a_i / C_env,

    eq. 1's Q_solar of the air node and of the envelope node, with the envelope's share
    ``shares[i]`` f_i = 0 (node air), 1 (envelope) or the parameter named there (both). A
    frozen dataclass (not a closure) so that structures built alike compare equal and
    pickle."""

    base: Callable[..., Any]
    base_parameters: tuple[str, ...]
    air: str
    apertures: tuple[str, ...]
    derivatives: bool
    envelope: str = ""
    shares: tuple[str | float, ...] = ()

    def __call__(self, **theta: float):
        out = self.base(**{p: theta[p] for p in self.base_parameters})
        a = np.array([theta[p] for p in self.apertures], dtype=float)
        shares = self.shares or (0.0,) * len(a)
        f = np.array([theta[s] if isinstance(s, str) else s for s in shares], dtype=float)
        # the envelope row is written only when a gain reaches it (air alone: as the base)
        env = self.envelope if any(isinstance(s, str) or s != 0.0 for s in shares) else ""
        C = theta[self.air]
        C_env = theta[env] if env else math.nan
        to_air = (1.0 - f) * a  # W per W/m2 into the air node: (1 - f_i) a_i
        to_env = f * a  # ... and into the envelope node: f_i a_i
        k = len(a)
        if not self.derivatives:
            A, B = out
            extra = np.zeros((B.shape[0], k))
            extra[0] = to_air / C
            if env:
                extra[1] = to_env / C_env
            return A, np.concatenate([B, extra], axis=1)
        der = {}
        for p, (dA, dB) in out.items():
            extra = np.zeros((dB.shape[0], k))
            if p == self.air:
                extra[0] = -to_air / C**2
            if env and p == env:
                extra[1] = -to_env / C_env**2
            der[p] = (dA, np.concatenate([dB, extra], axis=1))
        dA0, dB0 = out[self.air]
        n, m0 = dB0.shape
        for i, p in enumerate(self.apertures):
            dB = np.zeros((n, m0 + k))
            dB[0, m0 + i] = (1.0 - f[i]) / C
            if env:
                dB[1, m0 + i] = f[i] / C_env
            der[p] = (np.zeros_like(dA0), dB)
        for i, s in enumerate(shares):
            if isinstance(s, str):
                dB = np.zeros((n, m0 + k))
                dB[0, m0 + i] = -a[i] / C
                dB[1, m0 + i] = a[i] / C_env
                der[s] = (np.zeros_like(dA0), dB)
        return der


def with_irradiance(
    structure: Structure, names: Sequence[str], nodes: Sequence[str] | None = None
) -> Structure:
    """``structure`` with irradiance inputs ``names`` (W/m2, e.g. "I_sol") appended to its
    inputs, each a solar gain a_<name> I (eq. 1's Q_solar, W) through an unknown effective
    aperture a_<name> (m2), heating the node ``nodes[i]`` (default "air"; a name may also
    carry it, "I_sol@envelope", as the structure's name spells it):

    - ``air``: the air node (state 0), B[0, m0 + i] = a_i / C_air;
    - ``envelope``: the envelope node (state 1, ``structure.envelope``: T_veh of eqs. 7-8,
      T_e of the interior-envelope structure), B[1, m0 + i] = a_i / C_env;
    - ``both``: the share f_<name> (estimated, in (0, 1]) to the envelope, the rest to the air,
      B[0, m0 + i] = (1 - f_i) a_i / C_air, B[1, m0 + i] = f_i a_i / C_env.

    The new parameters follow the base ones: the apertures a_<name> (start 1 m2, bounds 1e-3
    to 1e3 m2), then the shares f_<name> (start 0.5, bounds 1e-3 to 1); the Jacobian is exact.
    A one-node structure (first_order) has no envelope: ``envelope`` or ``both`` there is a
    ValueError. No names: ``structure`` itself."""
    specs = [irradiance_spec(n) if isinstance(n, str) else (n, "air") for n in names]
    if nodes is not None:
        nodes = tuple(nodes)
        if len(nodes) != len(specs):
            raise ValueError(f"nodes {nodes} must give one node per irradiance input {names}")
        for i, ((name, node), given) in enumerate(zip(specs, nodes, strict=True)):
            if "@" in str(names[i]) and node != given:
                raise ValueError(f"irradiance input {names[i]!r} is declared on node {given!r}")
            specs[i] = (name, given)
    names = tuple(name for name, _ in specs)
    if not names:
        return structure
    bad = [n for n in names if not isinstance(n, str) or not n]
    if bad:
        raise ValueError(f"irradiance names must be non-empty strings, got {bad}")
    unknown = [f"{n}@{node}" for n, node in specs if node not in IRRADIANCE_NODES]
    if unknown:
        raise ValueError(
            f"irradiance inputs {unknown}: the node must be one of {list(IRRADIANCE_NODES)}"
        )
    clash = sorted({n for n in names if names.count(n) > 1 or n in structure.inputs})
    if clash:
        raise ValueError(
            f"irradiance inputs {clash} repeat or clash with the inputs {structure.inputs} "
            f"of {structure.name!r}"
        )
    apertures = tuple(f"a_{n}" for n in names)
    shared = tuple(f"f_{n}" for n, node in specs if node == "both")
    taken = [p for p in apertures + shared if p in structure.parameters]
    if taken:
        raise ValueError(f"parameters {taken} already exist in {structure.name!r}")
    if structure.air not in structure.parameters:
        raise ValueError(f"structure {structure.name!r} has no air-node capacity {structure.air!r}")
    on_envelope = [n for n, node in specs if node != "air"]
    if on_envelope and structure.envelope not in structure.parameters:
        raise ValueError(
            f"structure {structure.name!r} has one node ({', '.join(structure.states)}), no "
            f"envelope: irradiance {on_envelope} can heat only the air node (node 'air')"
        )
    share_of = {"air": 0.0, "envelope": 1.0}
    shares = tuple(share_of.get(node, f"f_{n}") for n, node in specs)
    common = dict(
        base_parameters=structure.parameters,
        air=structure.air,
        apertures=apertures,
        envelope=structure.envelope if on_envelope else "",
        shares=shares,
    )
    if on_envelope:
        equations = "solar gains a_i I_i into the air node, the envelope node or both (eq. 1)"
    else:
        equations = "solar gains a_i I_i into the air node (eq. 1)"
    spelled = tuple(n if node == "air" else f"{n}@{node}" for n, node in specs)
    return replace(
        structure,
        name=f"{structure.name}+{'+'.join(spelled)}",
        parameters=structure.parameters + apertures + shared,
        build=_WithApertures(base=structure.build, derivatives=False, **common),
        jacobian=_WithApertures(base=structure.jacobian, derivatives=True, **common),
        inputs=tuple(structure.inputs) + names,
        initial={
            **structure.initial,
            **dict.fromkeys(apertures, APERTURE_INITIAL),
            **dict.fromkeys(shared, SHARE_INITIAL),
        },
        bounds={
            **structure.bounds,
            **dict.fromkeys(apertures, APERTURE_BOUNDS),
            **dict.fromkeys(shared, SHARE_BOUNDS),
        },
        equations=f"{structure.equations}; {equations}" if structure.equations else equations,
    )


def structure_for(name: str, irradiance: Sequence[str] = ()) -> Structure:
    """The structure ``name`` of :data:`STRUCTURES` with irradiance inputs ``irradiance``
    (:func:`with_irradiance`; "I_sol" heats the air node, "I_sol@envelope" or "I_sol@both"
    as declared)."""
    from railtherm.structures import named

    return with_irradiance(named(name), irradiance)


def discretize_zoh(A: np.ndarray, B: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretisation: expm([[A, B], [0, 0]] dt) = [[Ad, Bd], [0, I]]."""
    Ad, G0, _ = discretize_ramp(A, B, dt, ramp=False)
    return Ad, G0


def discretize_ramp(
    A: np.ndarray, B: np.ndarray, dt: float, ramp: bool = True
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(Ad, G0, G1) of the module docstring from continuous (A, B): a held input u adds G0 u
    over a step, a ramp from 0 to v over the step adds G1 v (so inputs linear between samples
    add G0 u[n] + G1 (u[n+1] - u[n])). G1 is None when ``ramp`` is False."""
    A = np.atleast_2d(np.asarray(A, dtype=float))
    B = np.atleast_2d(np.asarray(B, dtype=float))
    n, m = B.shape
    E = expm(_augmented(A, B, dt, ramp))
    return E[:n, :n], E[:n, n : n + m], (E[:n, n + m :] if ramp else None)


def _augmented(A: np.ndarray, B: np.ndarray, dt: float, ramp: bool) -> np.ndarray:
    """[[A, B], [0, 0]] dt, or with the ramp [[A, B, 0], [0, 0, I/dt], [0, 0, 0]] dt (the
    input and its slope as extra states): the exponent of the module docstring."""
    n, m = B.shape
    k = n + (2 * m if ramp else m)
    M = np.zeros((k, k))
    M[:n, :n] = A * dt
    M[:n, n : n + m] = B * dt
    if ramp:
        M[n : n + m, n + m :] = np.eye(m)  # d(input)/dt = slope, over dt: the ramp s/dt
    return M


def discretize_noise(
    A: np.ndarray,
    W: np.ndarray,
    dt: float,
    directions: Sequence[tuple[np.ndarray, np.ndarray]] = (),
) -> tuple[np.ndarray, list[np.ndarray]]:
    """The covariance Qd = integral_0^dt exp(A s) W exp(A^T s) ds of the noise a diffusion
    dx = ... dt + Sigma dw (W = Sigma Sigma^T) adds over one step, by Van Loan's method:

        expm([[-A, W], [0, A^T]] dt) = [[F11, F12], [0, F22]],   Qd = F22^T F12

    (F22 = exp(A^T dt)). ``directions`` [(dA, dW), ...]: the exact derivative of Qd along
    each, dQd = dF22^T F12 + F22^T dF12, from the Frechet derivative of the same exponential
    along [[-dA, dW], [0, dA^T]] dt; all of them from one expm of the block-triangular matrix
    that :func:`discretize` uses. Returns (Qd, [dQd, ...]), each symmetric."""
    A = np.atleast_2d(np.asarray(A, dtype=float))
    W = np.atleast_2d(np.asarray(W, dtype=float))
    n = A.shape[0]
    k = 2 * n

    def block(a: np.ndarray, w: np.ndarray) -> np.ndarray:
        out = np.zeros((k, k))
        out[:n, :n] = -a
        out[:n, n:] = w
        out[n:, n:] = a.T
        return out * dt

    M = block(A, W)
    P = len(directions)
    if P:
        big = np.zeros((k * (P + 1), k * (P + 1)))
        for i in range(P + 1):
            big[i * k : (i + 1) * k, i * k : (i + 1) * k] = M
        for i, (dA, dW) in enumerate(directions):
            big[:k, (i + 1) * k : (i + 2) * k] = block(np.asarray(dA, float), np.asarray(dW, float))
        E = expm(big)[:k]
    else:
        E = expm(M)
    if not np.all(np.isfinite(E)):
        raise FloatingPointError("the Van Loan exponential is not finite")
    F12, F22 = E[:n, n:k], E[n:k, n:k]
    Qd = F22.T @ F12
    Qd = (Qd + Qd.T) / 2.0
    out = []
    for i in range(P):
        D = E[:, (i + 1) * k : (i + 2) * k]
        dQ = D[n:k, n:k].T @ F12 + F22.T @ D[:n, n:k]
        out.append((dQ + dQ.T) / 2.0)
    return Qd, out


def steady_state(A: np.ndarray, B: np.ndarray, u: np.ndarray) -> np.ndarray:
    """The equilibrium x* = -A^-1 B u for a constant input u."""
    return -np.linalg.solve(np.atleast_2d(A), np.atleast_2d(B) @ np.asarray(u, dtype=float))


@dataclass(frozen=True)
class Discretisation:
    """Ad, Bd of eq. 15, their derivatives along ``params``, and a modal form of Ad.

    ``hold``: "zero_order" (Bd is n x m, acting on u[n]) or "first_order" (Bd is n x 2m,
    acting on [u[n]; u[n+1]], :func:`forcing`). ``Q``, ``Qinv``, ``T``: Ad = Q T Qinv with T
    diagonal (eigenvectors) or upper triangular (complex Schur, Qinv = Q^H); ``lam`` the
    diagonal of T.
    """

    Ad: np.ndarray
    Bd: np.ndarray
    dAd: dict
    dBd: dict
    Q: np.ndarray
    Qinv: np.ndarray
    T: np.ndarray
    lam: np.ndarray
    diagonal: bool
    hold: str = "zero_order"


def check_hold(hold: str) -> str:
    if hold not in HOLDS:
        raise ValueError(f"hold must be one of {', '.join(HOLDS)}, got {hold!r}")
    return hold


def forcing(u: np.ndarray, hold: str = "zero_order") -> np.ndarray:
    """The rows the discrete recursion multiplies by Bd: u itself (N x m) for the zero-order
    hold; [u[n], u[n+1]] (N x 2m, the last row repeating u[N-1]; it drives no later sample)
    for the first-order hold."""
    u = np.asarray(u, dtype=float)
    if check_hold(hold) == "zero_order":
        return u
    nxt = np.concatenate([u[1:], u[-1:]], axis=0)
    return np.concatenate([u, nxt], axis=1)


def step_means(u: np.ndarray, hold: str = "zero_order") -> np.ndarray:
    """The mean of each input over [t_n, t_n+1): u[n] (zero-order hold), (u[n] + u[n+1]) / 2
    (first-order hold; the last row keeps u[N-1])."""
    u = np.asarray(u, dtype=float)
    if check_hold(hold) == "zero_order":
        return u
    return np.concatenate([(u[:-1] + u[1:]) / 2.0, u[-1:]], axis=0)


def _modal(Ad: np.ndarray):
    n = Ad.shape[0]
    if n == 1:
        one = np.ones((1, 1))
        return one, one, Ad.copy(), Ad[0].copy(), True
    lam, V = np.linalg.eig(Ad)
    if lam.dtype.kind == "f":  # numpy returns real eigenvalues when every one is real
        order = np.argsort(lam)
        lam, V = lam[order], V[:, order]
        if float(np.min(np.diff(lam))) > 1e-9 * max(1.0, float(np.abs(lam).max())):  # distinct
            try:
                Vinv = np.linalg.inv(V)
            except np.linalg.LinAlgError:
                Vinv = None
            # 1-norm condition number (cheap; within a factor n of the 2-norm one)
            if Vinv is not None and np.abs(V).sum(0).max() * np.abs(Vinv).sum(0).max() < (
                _MODAL_COND_MAX
            ):
                return V, Vinv, np.diag(lam), lam, True
    T, Q = schur(Ad.astype(complex), output="complex")
    return Q, Q.conj().T, T, np.diag(T).copy(), False


def transition(
    structure: Structure,
    theta: Mapping[str, float],
    dt: float,
    hold: str = "zero_order",
    params: tuple[str, ...] = (),
) -> tuple[np.ndarray, np.ndarray, dict, dict]:
    """Ad, Bd (exact for the ``hold``, module docstring) and, for each name in ``params``, the
    exact dAd, dBd (Frechet derivative of the same exponential along [[dA, dB, ..], 0] dt;
    one block expm for all of them): (Ad, Bd, {p: dAd}, {p: dBd}), without the modal form
    of :func:`discretize`."""
    first = check_hold(hold) == "first_order"
    A, B = structure.matrices(theta)
    n, m = B.shape
    M = _augmented(A, B, dt, first)
    k = len(M)
    P = len(params)
    if P:
        der = structure.derivatives(theta)
        big = np.zeros((k * (P + 1), k * (P + 1)))
        for i in range(P + 1):
            big[i * k : (i + 1) * k, i * k : (i + 1) * k] = M
        for i, p in enumerate(params):
            dA, dB = der[p]
            big[:n, (i + 1) * k : (i + 1) * k + n] = dA * dt
            big[:n, (i + 1) * k + n : (i + 1) * k + n + m] = dB * dt
        E = expm(big)[:k]
    else:
        E = expm(M)
    if not np.all(np.isfinite(E)):
        raise FloatingPointError(f"exp(A dt) is not finite for {dict(theta)}")

    def inputs(G: np.ndarray) -> np.ndarray:  # the columns acting on u (and u[n+1])
        if not first:
            return G.copy()
        G0, G1 = G[:, :m], G[:, m:]
        return np.concatenate([G0 - G1, G1], axis=1)

    Ad, Bd = E[:n, :n].copy(), inputs(E[:n, n:k])
    dAd = {p: E[:n, (i + 1) * k : (i + 1) * k + n].copy() for i, p in enumerate(params)}
    dBd = {p: inputs(E[:n, (i + 1) * k + n : (i + 2) * k]) for i, p in enumerate(params)}
    return Ad, Bd, dAd, dBd


def discretize(
    structure: Structure,
    theta: Mapping[str, float],
    dt: float,
    params: tuple[str, ...] = (),
    hold: str = "zero_order",
) -> Discretisation:
    """:func:`transition` (Ad, Bd and their derivatives along ``params``) with the modal form
    of Ad that the simulations run in."""
    Ad, Bd, dAd, dBd = transition(structure, theta, dt, hold, params)
    Q, Qinv, T, lam, diagonal = _modal(Ad)
    return Discretisation(Ad, Bd, dAd, dBd, Q, Qinv, T, lam, diagonal, hold)


def modal_form(F: np.ndarray) -> Discretisation:
    """The modal form F = Q T Qinv (eigenvectors, or the complex Schur form when F is not
    safely diagonalisable) of any recursion matrix F, as a :class:`Discretisation` with
    Ad = F and no input matrix, for :func:`propagate` (e.g. a Kalman predictor, whose F =
    Ad - L C)."""
    F = np.atleast_2d(np.asarray(F, dtype=float))
    Q, Qinv, T, lam, diagonal = _modal(F)
    return Discretisation(F, np.zeros((F.shape[0], 0)), {}, {}, Q, Qinv, T, lam, diagonal)


def propagate(d: Discretisation, w: np.ndarray, z0: np.ndarray) -> np.ndarray:
    """Modal recursion z[n+1] = T z[n] + w[n], z[0] = z0, for channels stacked in w (n_modes,
    C, N), z0 (n_modes, C), in the modal coordinates of ``d`` (w and z0 already multiplied by
    d.Qinv; complex when ``d.diagonal`` is False). One :func:`recursion` per mode for all
    channels; w is overwritten by the result."""
    return _propagate(d, w, z0)


def _propagate(d: Discretisation, w: np.ndarray, z0: np.ndarray) -> np.ndarray:
    """Modal recursion z[n+1] = T z[n] + w[n], z[0] = z0, for channels stacked in w.

    w: (n_modes, C, N) forcing (w[..., N-1] is unused), z0: (n_modes, C). Returns z in w's
    place: w is overwritten (callers pass a temporary; no second array of that size).
    """
    n = w.shape[0]
    for i in range(n - 1, -1, -1):
        wi = w[i]
        if not d.diagonal:
            for j in range(i + 1, n):
                if d.T[i, j] != 0:
                    wi = wi + d.T[i, j] * w[j]  # w[j] holds z_j already
        w[i] = recursion(w.dtype.type(d.lam[i]), wi, z0[i].astype(w.dtype))
    return w


def _input_array(u: np.ndarray, n_in: int) -> np.ndarray:
    u = np.asarray(u, dtype=float)
    if u.ndim != 2 or u.shape[1] != n_in:
        raise ValueError(
            f"u must be N x {n_in} (T_o, Q_H, then any further inputs), got shape {u.shape}"
        )
    if not np.all(np.isfinite(u)):
        raise ValueError("u contains NaN or inf: the simulation needs every input sample")
    return u


def _initial_array(x0, structure: Structure) -> np.ndarray:
    if isinstance(x0, Mapping):
        x0 = [x0[s] for s in structure.states]
    x0 = np.asarray(x0, dtype=float).reshape(-1)
    if x0.shape != (len(structure.states),) or not np.all(np.isfinite(x0)):
        raise ValueError(f"x0 must be {len(structure.states)} finite values, got {x0}")
    return x0


def _run_T(d: Discretisation, uT: np.ndarray, x0: np.ndarray) -> np.ndarray:
    """States as an (n, N) array (state-major) from inputs uT (m, N), x[0] = x0."""
    dtype = float if d.diagonal else complex
    w = (d.Qinv @ d.Bd).astype(dtype) @ uT  # (n, N)
    z0 = (d.Qinv @ x0).astype(dtype)
    z = _propagate(d, w[:, None, :], z0[:, None])[:, 0, :]
    x = d.Q @ z if len(z) > 1 else z * d.Q[0, 0]
    x = x.real.copy() if dtype is complex else x
    x[:, 0] = x0  # exactly (Q Qinv x0 may differ by rounding)
    return x


def _run(d: Discretisation, u: np.ndarray, x0: np.ndarray) -> np.ndarray:
    """x (N x n)."""
    return _run_T(d, np.ascontiguousarray(u.T), x0).T.copy()


def simulate(
    structure: Structure,
    theta: Mapping[str, float],
    u: np.ndarray,
    dt: float,
    x0,
    hold: str = "zero_order",
) -> np.ndarray:
    """Exact simulation (eq. 15, K = 0) under the input ``hold``: x (N x n) with x[0] = x0 and
    x[n+1] = Ad x[n] + Bd u[n] (zero-order: the last row of u is not used) or
    x[n+1] = Ad x[n] + Bd [u[n]; u[n+1]] (first-order); u is N x m in the order of
    ``structure.inputs`` ([T_o, Q_H], then any irradiance)."""
    u = _input_array(u, len(structure.inputs))
    d = discretize(structure, theta, dt, hold=hold)
    return _run(d, forcing(u, hold), _initial_array(x0, structure))


def free_response(d: Discretisation, N: int) -> np.ndarray:
    """Ad^n for n = 0..N-1 as an (N, n, n) array: dx[n]/dx0. Powers of the modes below
    FREE_RESPONSE_CUT are set to zero (never computed into subnormal floats)."""
    head = free_response_head(d, N)
    out = np.zeros((N,) + head.shape[1:])
    out[: len(head)] = head
    return out


def free_response_head(d: Discretisation, N: int) -> np.ndarray:
    """The rows of :func:`free_response` up to where every mode has decayed below
    FREE_RESPONSE_CUT (all later rows are zero)."""
    n = d.Ad.shape[0]
    r = float(np.max(np.abs(d.lam))) if n else 0.0
    if r <= 0.0:
        n_cut = 1
    elif r < 1.0:
        n_cut = min(N, int(math.ceil(math.log(FREE_RESPONSE_CUT) / math.log(r))) * 2 + 2)
    else:
        n_cut = N
    if d.diagonal:
        with np.errstate(under="ignore"):  # lam^t, exact in sign and at lam = 0 (0^0 = 1)
            pw = np.power(d.lam.real[None, :], np.arange(n_cut)[:, None])
        pw[np.abs(pw) < FREE_RESPONSE_CUT] = 0.0
        # Ad^t = sum_j pw[t, j] Q[:, j] Qinv[j, :]: one (n_cut x n) (n x n^2) product
        outer = (d.Q.T[:, :, None] * d.Qinv[:, None, :]).reshape(n, n * n)
        return (pw @ outer).reshape(n_cut, n, n)
    w = np.zeros((n, n, n_cut), dtype=complex)
    z = _propagate(d, w, d.Qinv.astype(complex))  # (modes, columns of x0, N)
    x = np.einsum("ij,jkn->nik", d.Q, z).real
    x[np.abs(x) < FREE_RESPONSE_CUT] = 0.0
    return x


def sensitivities(
    structure: Structure,
    theta: Mapping[str, float],
    u: np.ndarray,
    dt: float,
    x0,
    params: tuple[str, ...] | None = None,
    hold: str = "zero_order",
) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray]:
    """x (N x n), {param: dx/dparam (N x n)} and dx/dx0 (N x n x n), all exact for the
    discrete recursion under the input ``hold`` (see the module docstring)."""
    params = structure.parameters if params is None else tuple(params)
    u = _input_array(u, len(structure.inputs))
    x0 = _initial_array(x0, structure)
    d = discretize(structure, theta, dt, params, hold)
    uT = np.ascontiguousarray(forcing(u, hold).T)
    xT = _run_T(d, uT, x0)
    S = parameter_sensitivities(d, xT, uT, params)  # (P, n, N)
    sens = {p: S[i].T.copy() for i, p in enumerate(params)}
    return xT.T.copy(), sens, free_response(d, len(u))


def parameter_sensitivities(
    d: Discretisation,
    xT: np.ndarray,
    uT: np.ndarray,
    params: tuple[str, ...],
    scale: np.ndarray | None = None,
    outputs: tuple[int, ...] | None = None,
) -> np.ndarray:
    """(P, n_out, N): scale_p * dx_k/dparam_p for the states k in ``outputs`` (default all),
    from ds[n+1] = Ad ds[n] + dAd x[n] + dBd u[n], ds[0] = 0 (xT (n, N), uT (m, N) the
    simulated states and inputs, state-major).

    In modal coordinates every parameter of a mode shares the mode's filter: one recursion per
    mode for all parameters. ``scale`` (e.g. the parameters themselves, for derivatives with
    respect to log parameters) is folded into the forcing, and the return to states is one
    (P n_out) x (n P) matrix product, so the result is written once, in the layout a
    Jacobian needs: ``out.reshape(P, -1)`` has the outputs' blocks side by side."""
    n, N = xT.shape
    P = len(params)
    outputs = tuple(range(n)) if outputs is None else tuple(outputs)
    if P == 0:
        return np.zeros((0, len(outputs), N))
    dtype = float if d.diagonal else complex
    Qinv = d.Qinv.astype(dtype)
    # forcing in modal coordinates: w[i, p] = (Qinv dAd_p)[i] x + (Qinv dBd_p)[i] u
    HA = np.stack([Qinv @ d.dAd[p] for p in params], axis=1)  # (n, P, n)
    HB = np.stack([Qinv @ d.dBd[p] for p in params], axis=1)  # (n, P, m)
    if scale is not None:
        scale = np.asarray(scale, dtype=float)[None, :, None]
        HA, HB = HA * scale, HB * scale
    w = HA.reshape(n * P, n) @ xT
    w += HB.reshape(n * P, -1) @ uT
    s = _propagate(d, w.reshape(n, P, N), np.zeros((n, P), dtype=dtype))  # (n, P, N)
    # back to states: out[p, k] = sum_j Q[outputs[k], j] s[j, p]
    Qo = d.Q[list(outputs)].astype(dtype)  # (n_out, n)
    mix = np.einsum("kj,pq->pkjq", Qo, np.eye(P)).reshape(P * len(outputs), n * P)
    out = mix @ s.reshape(n * P, N)
    if dtype is complex:
        out = out.real.copy()
    return out.reshape(P, len(outputs), N)
