"""TCP-like closed loops (acknowledged actuation): thresholds, control MARE and the optimal cost.

theory §12 (Schenato, Sinopoli, Franceschetti, Poolla, Sastry, Proc. IEEE 95(1), 2007):

.. math::

    x_{t+1} = A x_t + \\nu_t B u_t + w_t, \\qquad y_t = C x_t + v_t
    \\ (\\text{received when } \\gamma_t = 1),

with γ_t ~ Bernoulli(γ̄), ν_t ~ Bernoulli(ν̄) independent, a lost control packet applying
u = 0, and the cost J = lim (1/T) E Σ (x_t'Wx_t + ν_t u_t'Uu_t). Separation holds: the Kalman
filter with the known applied input, and u_t = L x̂_{t|t} with

.. math::

    S = A'SA + W - \\bar\\nu A'SB(B'SB+U)^{-1}B'SA, \\qquad L = -(B'SB+U)^{-1}B'SA,

    J = \\operatorname{tr}(S Q) + \\bar\\nu \\operatorname{tr}\\bigl(L'(B'SB+U)L
        \\cdot \\lim E[P_{t|t}]\\bigr).

The cost is finite iff γ̄ > γ_c and ν̄ > ν_c (theory §12, under the standing controllability and
observability assumptions of the sources); its bounds come from those of lim E[P_{t|t}]
(:mod:`kfcrit.theory.loop.filter_mean`). Everything here is a *fact* (values, intervals,
exactness), never a verdict.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy as sp

from kfcrit.model.system import System, to_matrix
from kfcrit.theory.covariance.bounds import upper_covariance
from kfcrit.theory.covariance.riccati import symmetrize
from kfcrit.theory.loop.filter_mean import FilterMoments, filter_moments
from kfcrit.theory.loop.thresholds import (
    LoopThresholdFact,
    actuation_threshold,
    dual_system,
    sensing_threshold,
)

__all__ = ["LoopCost", "TCPLoop", "control_gain", "control_mare", "scalar_control_riccati", "tcp_cost",
           "tcp_loop"]


@dataclass(frozen=True)
class LoopCost:
    """The stationary average cost J of a loop, with bounds.

    Attributes
    ----------
    value : float
        J (``inf`` when proven infinite, ``nan`` when not computed).
    lower, upper : float
        lower ≤ J ≤ upper (``inf`` when no finite bound is available or J is infinite).
    finite : bool or None
        J < ∞ proven (True), J = ∞ proven (False), or undecided (None).
    method : str
        How ``value`` was obtained.
    error : float or None
        Accuracy of ``value`` (standard error of a Monte Carlo part, or a settling change).
    reason : str
    """

    value: float
    lower: float
    upper: float
    finite: bool | None
    method: str
    error: float | None
    reason: str


@dataclass(frozen=True)
class TCPLoop:
    """Facts about a TCP-like loop at (γ̄, ν̄): thresholds, control MARE solution, cost.

    Attributes
    ----------
    gamma_bar, nu_bar : float
        Arrival probabilities of the sensing and actuation links.
    nu_c, gamma_c : LoopThresholdFact
        Actuation threshold (MARE of (A', B')) and sensing threshold (p_c of (A, C)).
    S : ndarray or None
        Control MARE fixed point at ν̄ (None when ν̄ ≤ ν_c or not reached).
    L : ndarray or None
        Optimal gain −(B'SB+U)^{-1}B'SA.
    cost : LoopCost
    filter : FilterMoments or None
        lim E[P_{t|t}] and its bounds.
    notes : tuple of str
    """

    gamma_bar: float
    nu_bar: float
    nu_c: LoopThresholdFact
    gamma_c: LoopThresholdFact
    S: np.ndarray | None
    L: np.ndarray | None
    cost: LoopCost
    filter: FilterMoments | None
    notes: tuple[str, ...] = ()


def control_gain(A: np.ndarray, B: np.ndarray, U: np.ndarray, S: np.ndarray) -> np.ndarray:
    """L = −(B'SB + U)^{-1} B'SA.

    .. math::

        L = -(B' S B + U)^{-1} B' S A
    """
    return -np.linalg.solve(B.T @ S @ B + U, B.T @ S @ A)


def control_mare(A: Any, B: Any, W: Any, U: Any, nu: float) -> np.ndarray | None:
    """The control MARE fixed point S(ν̄), computed as V̄ of the dual estimation MARE.

    .. math::

        S = A'SA + W - \\bar\\nu A'SB(B'SB+U)^{-1}B'SA = g_{\\bar\\nu}(S)
        \\text{ for } (A', B', W, U)

    Returns None when the iteration does not reach a fixed point (ν̄ ≤ ν_c).
    """
    dual = dual_system(A, B, W, U)
    S = upper_covariance(dual, float(nu))["V"]
    if S is None or not np.all(np.isfinite(S)):
        return None
    return symmetrize(S)


def _finite(gamma_c: LoopThresholdFact, nu_c: LoopThresholdFact, g: float,
            nu: float) -> tuple[bool | None, str]:
    below = (gamma_c.below(g), nu_c.below(nu))
    if gamma_c.interval is None or nu_c.interval is None:
        return False, "no threshold: an unstable mode is undetectable or unstabilisable"
    if below[0] is False or below[1] is False:
        which = "γ̄ ≤ γ_c" if below[0] is False else "ν̄ ≤ ν_c"
        return False, f"{which}: the cost is infinite (theory §12)"
    if below == (True, True):
        return True, "γ̄ > γ_c and ν̄ > ν_c (proven by the thresholds' intervals)"
    return None, "γ̄ or ν̄ lies inside its threshold's interval: finiteness undecided"


def _trace(M: np.ndarray, X: np.ndarray | None) -> float:
    return math.inf if X is None else float(np.trace(M @ X))


def tcp_cost(system_a: np.ndarray, system_b: np.ndarray, Q: np.ndarray, W: np.ndarray,
             U: np.ndarray, S: np.ndarray, nu: float, moments: FilterMoments,
             finite: bool | None, why: str) -> LoopCost:
    """J = tr(SQ) + ν̄ tr(L'(B'SB+U)L · lim E[P_{t|t}]) and its bounds from ``moments``.

    .. math::

        J = \\operatorname{tr}(SQ) + \\bar\\nu\\,\\operatorname{tr}(M\\,\\lim E[P_{t|t}]),
        \\quad M = L'(B'SB+U)L
    """
    A, B = system_a, system_b
    L = control_gain(A, B, U, S)
    M = symmetrize(L.T @ (B.T @ S @ B + U) @ L)
    base = float(np.trace(S @ Q))
    lower = base + nu * _trace(M, moments.lower_filt)
    upper = base + nu * _trace(M, moments.upper_filt)
    if moments.mean_filt is None:
        return LoopCost(math.nan, lower, upper, finite, moments.method, None, why)
    value = base + nu * float(np.trace(M @ moments.mean_filt))
    err = None if moments.error is None else nu * float(moments.error) * (
        1.0 if moments.method.startswith("monte") else float(np.trace(M)))
    return LoopCost(value, lower, upper, finite, moments.method, err, why)


def tcp_loop(A: Any, B: Any, C: Any, W: Any, U: Any, Q: Any, R: Any, gamma_bar: float,
             nu_bar: float, tol: float = 1e-9, mc_paths: int = 1000, mc_steps: int = 3000,
             seed: int = 0) -> TCPLoop:
    """All facts about the TCP-like loop at (γ̄, ν̄).

    .. math::

        \\nu_c = p_{up}(A', B'), \\quad \\gamma_c = p_c(A, C), \\quad
        J = \\operatorname{tr}(SQ) + \\bar\\nu \\operatorname{tr}(L'(B'SB+U)L\\,
        \\lim E[P_{t|t}])

    Parameters
    ----------
    A, B, C : array_like
        Plant (n × n), input (n × m_u) and output (m × n) matrices; exact input stays exact.
    W, U : array_like
        State and input weights (U ≻ 0).
    Q, R : array_like
        Process and measurement noise covariances (R ≻ 0).
    gamma_bar, nu_bar : float
        Arrival probabilities of the sensing and actuation links.
    tol : float
        Width of certified brackets.
    mc_paths, mc_steps, seed : int
        Monte Carlo size of lim E[P_{t|t}] when n > 1.

    Returns
    -------
    TCPLoop

        The thresholds ν_c and γ_c, the control Riccati solution S and gain L, the cost J
        (value and bounds, ``finite``), the filter moments and notes.

    Raises
    ------
    ValueError
        An arrival probability outside [0, 1].
    kfcrit.errors.InputError
        Matrices of the wrong shape.

    References
    ----------
    Schenato, Sinopoli, Franceschetti, Poolla & Sastry (2007), "Foundations of control and
    estimation over lossy networks", Proc. IEEE 95(1); docs/theory.md §12
    (the cost formula and its check J = 5.65894 for a = 5/4, γ̄ = ν̄ = 0.8).

    Examples
    --------
    >>> from fractions import Fraction
    >>> from kfcrit.theory.loop.tcp import tcp_loop
    >>> loop = tcp_loop([[Fraction(5, 4)]], [[1]], [[1]], 1, 1, 1, 1, 0.8, 0.8)
    >>> round(loop.cost.value, 5), loop.cost.finite
    (5.65894, True)
    """
    nu_c = actuation_threshold(A, B, W, U, tol)
    gamma_c = sensing_threshold(A, C, Q, R, tol)
    A_, _ = to_matrix(A, "A")
    C_, _ = to_matrix(C, "C")
    sensing = System(A_, C_, Q, R, name="sensing link (A, C, Q, R)")
    dual = dual_system(A, B, W, U)
    a, b, w, u, q = sensing.a, dual.c.T, dual.q, dual.r, sensing.q
    finite, why = _finite(gamma_c, nu_c, float(gamma_bar), float(nu_bar))
    notes: list[str] = []
    if nu_c.basis == "claim":
        notes.append("ν_c rests on the single-input identity (theory §3 [beyond]): " + nu_c.reason)
    S = None if finite is False and nu_c.below(nu_bar) is False else control_mare(
        A, B, W, U, nu_bar)
    if S is None:
        inf = math.inf
        cost = LoopCost(inf, inf, inf, False if finite is not True else None,
                        "none: the control MARE has no fixed point", None,
                        why if finite is False else "control MARE iteration not bounded")
        return TCPLoop(float(gamma_bar), float(nu_bar), nu_c, gamma_c, None, None, cost, None,
                       tuple(notes))
    L = control_gain(a, b, u, S)
    M = symmetrize(L.T @ (b.T @ S @ b + u) @ L)
    moments = filter_moments(sensing, float(gamma_bar), mc_paths=mc_paths, mc_steps=mc_steps,
                             seed=seed, weight=M, value=finite is not False)
    if finite is False:
        inf = math.inf
        cost = LoopCost(inf, inf, inf, False, "none: a threshold is not exceeded", None, why)
    else:
        cost = tcp_cost(a, b, q, w, u, S, float(nu_bar), moments, finite, why)
    return TCPLoop(float(gamma_bar), float(nu_bar), nu_c, gamma_c, S, L, cost, moments,
                   tuple(notes))


def scalar_control_riccati(a: sp.Expr, b: sp.Expr, w: sp.Expr, u: sp.Expr,
                           nu: sp.Expr) -> sp.Expr:
    """The positive root S of the scalar control MARE, exactly.

    .. math::

        (1 - a^2 + \\bar\\nu a^2) b^2 S^2 + (u(1 - a^2) - w b^2) S - w u = 0
    """
    s = sp.Symbol("S", positive=True)
    eq = sp.expand((s - a**2 * s - w) * (b**2 * s + u) + nu * a**2 * b**2 * s**2)
    roots = [r for r in sp.solve(eq, s) if r.is_positive]
    return sp.radsimp(roots[0]) if roots else sp.nan
