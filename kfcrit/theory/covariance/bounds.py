"""Covariance bounds S̄ ⪯ lim E[P_t] ⪯ V̄, their phase transition in p, and static gains.

Sinopoli Thm 4 and 6 (docs/theory.md §3), for p above the relevant threshold:

* S̄ = (1−p) A S̄ A' + Q — a Lyapunov equation for √(1−p) A; exists iff (1−p) ρ(A)² < 1.
* V̄ = g_p(V̄) — the MARE fixed point, the limit of V_{t+1} = g_p(V_t) from V_0 = 0; exists
  (the iteration is bounded) iff p > p_up. We compute it by the iteration *and* by
  Newton–Kleinman, V_{k+1} = L_{K_k,p}(V_{k+1}) + Q + p K_k R K_k', K_{k+1} = K_{V_{k+1}}, which
  converges quadratically from any gain K_0 with ρ(L_{K_0,p}) < 1. A gain is accepted as
  stabilising when the solution of V = L_{K_0,p}(V) + Q + p K_0 R K_0' is positive definite: for
  a positive operator with Q ≻ 0 that holds iff ρ(L_{K_0,p}) < 1.

Static gains (Sinopoli journal Section V): a fixed gain K gives the jump-linear error system
e' = (A + γ K C) e + noise, mean-square stable iff ρ(L_{K,p}) < 1 with steady covariance
Σ = L_{K,p}(Σ) + Q + p K R K'. Its critical value p_K = inf{p : ρ(L_{K,p}) < 1} is never below
p_up, and the best static gain attains p_up (that is the definition of p_up in Thm 5).
"""
from __future__ import annotations

import os
import time
import warnings as _warnings
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np
import scipy.linalg as sla

from kfcrit.io.jsonio import native_number
from kfcrit.io.typed import ABSENT, to_json
from kfcrit.model.system import System
from kfcrit.records.covariance import (
    BestStaticGain,
    CovarianceBounds,
    CovarianceSummary,
    Limits,
    MareEnclosure,
    Markers,
    PhaseTransition,
    StaticGain,
    StaticGainEstimate,
)
from kfcrit.theory.covariance.mare import mare_enclosure
from kfcrit.theory.covariance.riccati import (
    g,
    optimal_gain,
    solve_generalized_stein,
    stein_matrix,
    symmetrize,
)
from kfcrit.theory.critical import plow
from kfcrit.theory.critical.compare import compare_probability
from kfcrit.theory.upper import bracket as upper_module

NEWTON_MAX_STATES = 60
"""Newton–Kleinman (a dense solve in n(n+1)/2 unknowns) is used up to this state dimension."""
PHASE_NEWTON_MAX_STATES = 24
"""The phase-transition curve uses Newton per grid point up to this n (each solve costs
O((n²/2)³)); above it, the MARE fixed-point iteration warm-started from the neighbouring grid
point (V̄ is non-increasing in p, so V̄(p') ⪯ V̄(p) for p' > p and the iteration from V̄(p')
increases monotonically to V̄(p))."""
PHASE_TIME_BUDGET = float(os.environ.get("KFCRIT_PHASE_TIME_BUDGET", "20"))
"""Seconds allowed for the V̄ curve of :func:`phase_transition` (environment variable
``KFCRIT_PHASE_TIME_BUDGET``); points left when it runs out are ``None`` and the record's
``warnings`` say where the curve stopped."""
PHASE_ITERATION_CAP = 5000
"""Fixed-point iterations per grid point above :data:`PHASE_NEWTON_MAX_STATES`."""
LARGE_STATES = 40
"""Above this n the V̄ computations have iteration budgets (each MARE step costs O(n³)):
:data:`LARGE_MARE_ITERATIONS` at the operating point, :data:`LARGE_PHASE_ITERATIONS` for the
whole V̄ curve (``quick``: :data:`LARGE_QUICK_PHASE_ITERATIONS` over
:data:`LARGE_QUICK_PHASE_POINTS` points); what they leave out is stated in the record."""
LARGE_MARE_ITERATIONS = 5000
LARGE_PHASE_ITERATIONS = 1200
LARGE_QUICK_PHASE_ITERATIONS = 300
LARGE_QUICK_PHASE_POINTS = 12


def _matrix(M: np.ndarray | None) -> list[list[float]] | None:
    return None if M is None else [[float(v) for v in row] for row in M]


def lower_exists_exactly(lower: CovarianceSummary, p: Any, p_low: Any) -> CovarianceSummary:
    r"""``lower`` with S̄'s existence decided on the exact ``p`` and ``p_low`` (Sinopoli Thm 3,
    4): a p that rounds onto p_low in float64 (p = 9/25 + 10⁻⁴⁰) finds no bounded S̄ there, yet
    S̄ exists, beyond float64. Unchanged when it exists in float64 or either side is unknown.

    .. math::  \exists\,\bar S \iff p > p_{low} = 1 - 1/\rho(A)^2
    """
    if lower.exists is not False or p is None or p_low is None:
        return lower
    try:
        above = compare_probability(p, p_low) > 0
    except ArithmeticError:   # undecidable: the float64 answer stands
        return lower
    return replace(lower, exists=True, beyond_float64=True) if above else lower


def covariance_summary(M: np.ndarray | None) -> CovarianceSummary:
    """Trace, largest eigenvalue and entries of a covariance bound (``exists`` False for None).

    Parameters
    ----------
    M : numpy.ndarray or None
        The bound (S̄, V̄ or a fixed-gain covariance), None where it does not exist.

    Returns
    -------
    CovarianceSummary
        A value beyond the float64 range is None and ``beyond_float64`` is set; the matrix is
        None unless every entry is finite.
    """
    if M is None:
        return CovarianceSummary(exists=False, trace=None, max_eig=None, matrix=None)
    with np.errstate(all="ignore"):
        tr = float(np.trace(M))
        try:
            top = float(np.linalg.eigvalsh(M).max())
        except np.linalg.LinAlgError:
            top = float("nan")
    finite = bool(np.all(np.isfinite(M)))
    within = finite and bool(np.isfinite(tr)) and bool(np.isfinite(top))
    return CovarianceSummary(exists=True, trace=tr if np.isfinite(tr) else None,
                             max_eig=top if np.isfinite(top) else None,
                             matrix=_matrix(M) if finite else None,
                             beyond_float64=ABSENT if within else True)


def _enclosure(enc: dict[str, Any]) -> MareEnclosure:
    """The verified enclosure of :func:`kfcrit.theory.covariance.mare.mare_enclosure` as its
    record class."""
    return MareEnclosure(relative_width=float(enc["relative_width"]),
                         trace_interval=[float(v) for v in enc["trace_interval"]],
                         proves_p_above_p_up=bool(enc["proves_p_above_p_up"]),
                         margins=[native_number(v) for v in enc["margins"]],
                         method=str(enc["method"]))


def _scaled_norm_ratio(D: np.ndarray, V: np.ndarray) -> float | None:
    """‖D‖_F / ‖V‖_F without overflow (both scaled by max |entry| first); None if not finite.

    ``np.linalg.norm`` squares the entries: for V ~ 1e250 (e.g. R = 1e250) that overflows to
    inf and inf/inf gives NaN with a RuntimeWarning on stderr."""
    with np.errstate(all="ignore"):
        s = max(float(np.max(np.abs(V))) if V.size else 0.0,
                float(np.max(np.abs(D))) if D.size else 0.0)
        if not (np.isfinite(s) and s > 0):
            return 0.0 if s == 0 else None
        r = float(np.linalg.norm(D / s)) / max(float(np.linalg.norm(V / s)), 1e-300)
    return r if np.isfinite(r) else None


# ---------------------------------------------------------------------------------------------
# S̄ and V̄
# ---------------------------------------------------------------------------------------------


def lower_covariance(A: np.ndarray, Q: np.ndarray, p: float,
                     rho: float | None = None) -> np.ndarray | None:
    r"""S̄ = (1−p) A S̄ A' + Q, or None when (1−p) ρ(A)² ≥ 1 (no bounded solution).

    .. math::

        \bar S = (1-p)\, A \bar S A' + Q

    scipy's direct (Kronecker) solver is tried first; when it reports an ill-conditioned system
    (``LinAlgWarning``, e.g. a strongly non-normal A near the boundary) the bilinear
    (Bartels–Stewart) method is used instead. Nothing is printed.

    Parameters
    ----------
    A, Q : numpy.ndarray
        Plant matrix and process-noise covariance (float64).
    p : float
        Arrival probability.
    rho : float, optional
        ρ(A) when the caller has it (a curve over p computes it once: O(n³) per call).

    Returns
    -------
    numpy.ndarray or None
        The lower bound S̄ of lim E[P_t] (symmetric), or None when it does not exist.

    Raises
    ------
    numpy.linalg.LinAlgError
        A (numerically) singular Lyapunov system.

    References
    ----------
    Sinopoli et al. (2004), Theorem 3 (eq. (19)) and Theorem 4; docs/theory.md §3.

    Examples
    --------
    >>> import numpy as np
    >>> from kfcrit.theory.covariance.bounds import lower_covariance
    >>> lower_covariance(np.array([[1.25]]), np.array([[1.0]]), 0.5).round(6)  # 1/(1 - 25/32)
    array([[4.571429]])
    >>> lower_covariance(np.array([[2.0]]), np.array([[1.0]]), 0.5) is None
    True
    """
    if rho is None:
        rho = float(max(abs(np.linalg.eigvals(A)))) if A.size else 0.0
    if (1.0 - p) * rho**2 >= 1.0:
        return None
    M = np.sqrt(1.0 - p) * A
    # the equation is linear in Q: solve for Q/s with s = max |Q_ij| and scale back, so that
    # Q = 1e-250·I or 1e250·I reaches scipy at unit scale (no underflow inside its balancing)
    s = float(np.max(np.abs(Q))) if Q.size else 0.0
    if not (s > 0 and np.isfinite(s)):
        s = 1.0
    Qs = Q / s
    with _warnings.catch_warnings():
        _warnings.simplefilter("error", sla.LinAlgWarning)
        try:
            return s * symmetrize(sla.solve_discrete_lyapunov(M, Qs))
        except sla.LinAlgWarning:
            pass
    with _warnings.catch_warnings():
        _warnings.simplefilter("ignore", sla.LinAlgWarning)
        return s * symmetrize(sla.solve_discrete_lyapunov(M, Qs, method="bilinear"))


def mare_residual(A, C, Q, R, V: np.ndarray, p: float) -> float | None:
    """Relative residual ‖g_p(V) − V‖_F / ‖V‖_F of the MARE (computed with scaling, so huge V
    do not overflow); None when it cannot be evaluated in float64 (non-finite g_p(V))."""
    with np.errstate(all="ignore"):
        try:
            D = g(A, C, Q, R, V, p) - V
        except (np.linalg.LinAlgError, ValueError):
            return None
    return _scaled_norm_ratio(D, V)


def mare_iteration(A, C, Q, R, p: float, V0: np.ndarray | None = None,
                   max_iterations: int = 200_000, rtol: float = 1e-13,
                   blowup: float = 1e14) -> tuple[np.ndarray | None, int]:
    r"""V_{t+1} = g_p(V_t) from V_0 (0 by default) until ‖ΔV‖ ≤ rtol ‖V‖.

    .. math::

        V_{t+1} = g_p(V_t) = A V_t A' + Q - p\, A V_t C'(C V_t C' + R)^{-1} C V_t A'

    With Q ≻ 0 the orbit from 0 is bounded iff p > p_up; the iteration slows down near p_up.

    Parameters
    ----------
    A, C, Q, R : numpy.ndarray
        System matrices (float64).
    p : float
        Arrival probability.
    V0 : numpy.ndarray, optional
        Starting point (default 0).
    max_iterations : int
        Iteration budget.
    rtol : float
        Relative step size at which the iteration stops.
    blowup : float
        The orbit is declared unbounded above ``blowup``·(1 + ‖V_1‖).

    Returns
    -------
    V : numpy.ndarray or None
        The fixed point V̄, or None when the iterates blow up or the budget ends first.
    iterations : int
        Iterations used.

    Raises
    ------
    ValueError
        Matrices of inconsistent shapes.

    References
    ----------
    Sinopoli et al. (2004), Theorem 1 and Theorem 6(a); docs/theory.md §3 (characterisation 3
    of p_up).

    Examples
    --------
    >>> import numpy as np
    >>> from kfcrit.theory.covariance.bounds import mare_iteration
    >>> one = np.eye(1)
    >>> V, its = mare_iteration(1.25 * one, one, one, one, 0.5)
    >>> V.round(6)
    array([[7.733944]])
    >>> mare_iteration(1.25 * one, one, one, one, 0.3, max_iterations=1000)[0] is None  # p < 9/25
    True
    """
    V = np.zeros_like(Q, dtype=float) if V0 is None else np.array(V0, dtype=float)
    # overflow and NaN are detected below (non-finite norm): no RuntimeWarning on stderr
    with np.errstate(all="ignore"):
        scale = 1.0 + float(np.linalg.norm(g(A, C, Q, R, V, p)))
        for t in range(1, max_iterations + 1):
            Vn = g(A, C, Q, R, V, p)
            nv = float(np.linalg.norm(Vn))
            if not np.isfinite(nv) or nv > blowup * scale:
                return None, t
            if float(np.linalg.norm(Vn - V)) <= rtol * nv:
                return Vn, t
            V = Vn
    return None, max_iterations


def stabilising_solution(A, C, Q, R, K: np.ndarray, p: float) -> np.ndarray | None:
    """Σ = L_{K,p}(Σ) + Q + p K R K' if ρ(L_{K,p}) < 1 (Σ ≻ 0 is the test), else None."""
    W = symmetrize(Q + p * K @ R @ K.T)
    try:
        S = solve_generalized_stein(A, C, K, p, W)
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(S)) or float(np.linalg.eigvalsh(S).min()) <= 0:
        return None
    return symmetrize(S)


def mare_newton(A, C, Q, R, p: float, K0: np.ndarray, max_iterations: int = 60,
                rtol: float = 1e-14) -> tuple[np.ndarray | None, int]:
    """Newton–Kleinman for V̄ = g_p(V̄) from a stabilising gain K0 (None if K0 is not)."""
    V = stabilising_solution(A, C, Q, R, K0, p)
    if V is None:
        return None, 0
    prev = np.inf
    for k in range(1, max_iterations + 1):
        K = optimal_gain(A, C, R, V)
        Vn = stabilising_solution(A, C, Q, R, K, p)
        if Vn is None:
            return None, k
        change = _scaled_norm_ratio(Vn - V, Vn)
        if change is None:
            return None, k
        V = Vn
        # converged, or stagnating at rounding level (quadratic convergence has stopped)
        if change <= rtol or (change <= 1e-10 and change >= 0.5 * prev):
            break
        prev = change
    return V, k


def upper_covariance(system: System, p: float, gains: list[np.ndarray] | None = None,
                     rtol: float = 1e-14) -> dict[str, Any]:
    r"""V̄(p) by Newton–Kleinman, falling back to the plain MARE iteration.

    Gains tried: ``gains``, then K = −A C⁻¹ when C is square, then the gain of the MARE iterate.
    V̄ is the fixed point of the MARE

    .. math::

        \bar V = A \bar V A' + Q - p\, A \bar V C'(C \bar V C' + R)^{-1} C \bar V A' .

    Parameters
    ----------
    system : System
        The system.
    p : float
        Arrival probability (above p_up for V̄ to exist).
    gains : list of numpy.ndarray, optional
        Stabilising gains to warm-start Newton–Kleinman.
    rtol : float
        Relative convergence tolerance of Newton–Kleinman.

    Returns
    -------
    dict
        Keys ``V`` (the matrix, or None when not reached), ``method``, ``iterations`` and
        ``residual`` (relative MARE residual).

    Raises
    ------
    numpy.linalg.LinAlgError
        Only from a singular linear solve that the fallbacks cannot avoid.

    References
    ----------
    Sinopoli et al. (2004), Theorem 6(a) and Lemma 1; docs/theory.md §3.

    Examples
    --------
    >>> from kfcrit import System
    >>> from kfcrit.theory.covariance.bounds import upper_covariance
    >>> res = upper_covariance(System(A=[[1.25]], C=[[1]], Q=1, R=1), 0.5)
    >>> res["V"].round(6), res["method"]
    (array([[7.733944]]), 'newton-kleinman (warm gain)')
    """
    A, C, Q, R = system.a, system.c, system.q, system.r
    n = system.n
    candidates = list(gains or [])
    if C.shape[0] == n:
        # C invertible: K = −A C⁻¹ gives F = A + K C = 0, stabilising for every p > p_low
        # (no MARE iteration needed — whose blow-up test misfires when V̄ is huge, R = 1e250)
        with np.errstate(all="ignore"):
            try:
                K_inv = -np.linalg.solve(C.T, A.T).T
                if np.all(np.isfinite(K_inv)):
                    candidates.append(K_inv)
            except np.linalg.LinAlgError:
                pass
    if n <= NEWTON_MAX_STATES:
        for K0 in candidates:
            V, its = mare_newton(A, C, Q, R, p, K0, rtol=rtol)
            if V is not None:
                return {"V": V, "method": "newton-kleinman (warm gain)", "iterations": its,
                        "residual": mare_residual(A, C, Q, R, V, p)}
        Vi, its_i = mare_iteration(A, C, Q, R, p, rtol=1e-6, max_iterations=20_000)
        if Vi is not None:
            V, its = mare_newton(A, C, Q, R, p, optimal_gain(A, C, R, Vi), rtol=rtol)
            if V is not None:
                return {"V": V, "method": "newton-kleinman (gain from the MARE iteration)",
                        "iterations": its_i + its, "residual": mare_residual(A, C, Q, R, V, p)}
    cap = LARGE_MARE_ITERATIONS if n > LARGE_STATES else 200_000
    V, its = mare_iteration(A, C, Q, R, p, max_iterations=cap)
    return {"V": V, "method": "mare-iteration" if V is not None or n <= LARGE_STATES else
            f"mare-iteration (at most {cap} iterations for n = {n} > {LARGE_STATES})",
            "iterations": its,
            "residual": None if V is None else mare_residual(A, C, Q, R, V, p)}


def upper_of(system: System, upper: Any = None) -> Any:
    """The p_up bracket (:class:`kfcrit.theory.upper.record.UpperBound`) the caller computed,
    else computed here: pass it in (``upper``) so that p_up is computed once per record."""
    if upper is not None and not isinstance(upper, dict):
        return upper
    return upper_module.upper_bound(system)


def covariance_bounds(system: System, p: float, upper: Any = None) -> dict[str, Any]:
    r"""S̄ and V̄ at arrival probability p (Sinopoli Thm 4, 6), as plain JSON data.

    The JSON form of :func:`covariance_bounds_record` (the record's ``covariance_bounds``):

    .. math::

        \bar S \preceq \lim_t E[P_t] \preceq \bar V

    Parameters
    ----------
    system : System
        The system.
    p : float
        Arrival probability.
    upper : optional
        The p_up bracket if already computed (see :func:`covariance_bounds_record`).

    Returns
    -------
    dict
        ``{"p", "lower": {exists, trace, max_eig, matrix}, "upper": {exists, trace, max_eig,
        matrix, residual, method, iterations, ...}, "ordered", "warnings"}``.

    Raises
    ------
    TypeError, ValueError
        ``p`` not convertible to float.

    References
    ----------
    Sinopoli et al. (2004), Theorems 4 and 6; docs/theory.md §3.

    Examples
    --------
    >>> from kfcrit import System, covariance_bounds
    >>> b = covariance_bounds(System(A=[[1.25]], C=[[1]], Q=1, R=1), 0.5)
    >>> round(b["lower"]["trace"], 6), round(b["upper"]["trace"], 6), b["ordered"]
    (4.571429, 7.733944, True)
    >>> covariance_bounds(System(A=[[1.25]], C=[[1]], Q=1, R=1), 0.3)["upper"]["exists"]
    False
    """
    return to_json(covariance_bounds_record(system, p, upper))


def covariance_bounds_record(system: System, p: float, upper: Any = None) -> CovarianceBounds:
    r"""S̄ and V̄ at arrival probability p (Sinopoli Thm 4, 6).

    For p > p_up the limit of the mean error covariance is bracketed:

    .. math::

        \bar S \preceq \lim_t E[P_t] \preceq \bar V,\qquad
        \bar S = (1-p) A \bar S A' + Q,\qquad \bar V = g_p(\bar V),

    with g_p(X) = A X A' + Q − p A X C'(C X C' + R)^{-1} C X A' (the MARE).

    Parameters
    ----------
    system : System
        The system.
    p : float
        Arrival probability.
    upper : kfcrit.theory.upper.record.UpperBound, optional
        ``upper.upper_bound(system)`` if already computed (its interval decides where V̄
        cannot exist, and its certificate gain warm-starts Newton).

    Returns
    -------
    CovarianceBounds
        ``lower`` (S̄) and ``upper`` (V̄ with ``residual``, ``method``, ``iterations`` and, when
        reached, its verified enclosure), ``ordered`` (S̄ ⪯ V̄ checked: λ_min(V̄ − S̄) ≥ −1e-9
        ‖V̄‖; None unless both exist) and ``warnings``. ``residual`` is the relative MARE
        residual ‖g_p(V̄) − V̄‖_F / ‖V̄‖_F.

    Raises
    ------
    TypeError, ValueError
        ``p`` not convertible to float. Bounds that do not exist are reported with
        ``exists`` False, never raised.

    References
    ----------
    Sinopoli et al. (2004), Theorems 4 and 6 (with the corrected Theorem 6(b) SDP); Lemma 1;
    docs/theory.md §2 and §3.

    Examples
    --------
    >>> from kfcrit import System
    >>> from kfcrit.theory.covariance.bounds import covariance_bounds_record
    >>> b = covariance_bounds_record(System(A=[[1.25]], C=[[1]], Q=1, R=1), 0.5)
    >>> round(b.upper.trace, 6), b.upper.certified
    (7.733944, True)
    """
    p = float(p)
    S = lower_covariance(system.a, system.q, p)
    if upper is None or not isinstance(upper, dict):
        ub = upper_of(system, upper)
        lo_up, gains = ub.interval[0], ([ub.extras["K"]] if "K" in ub.extras else [])
    else:
        lo_up, gains = float(upper["interval"][0]), []
    if p <= lo_up:
        out_up = replace(covariance_summary(None), residual=None,
                         method="none: p <= p_up (Thm 3)", iterations=0)
        V = None
    else:
        res = upper_covariance(system, p, gains)
        V = res["V"]
        out_up = replace(covariance_summary(V), residual=native_number(res["residual"]),
                         method=res["method"], iterations=int(res["iterations"]))
        if V is None:
            out_up = replace(out_up, not_reached=True)
        else:
            enc = mare_enclosure(system.a, system.c, system.q, system.r, p, V)
            out_up = replace(out_up, certified=enc is not None,
                             certificate=None if enc is None else _enclosure(enc))
    ordered = None
    warnings: list[str] = []
    if S is not None and V is not None:
        with np.errstate(all="ignore"):
            scale = float(np.max(np.abs(V)))
            if np.isfinite(scale) and scale > 0:
                ordered = bool(np.linalg.eigvalsh((V - S) / scale).min()
                               >= -1e-9 * np.linalg.norm(V / scale))
    low = covariance_summary(S)
    for name, summ in (("S̄ (lower bound)", low), ("V̄ (upper bound)", out_up)):
        if summ.beyond_float64:
            warnings.append(f"covariance bound {name} at p = {p:.6g}: its trace or largest "
                            "eigenvalue (or an entry) is beyond the float64 range (about "
                            "1.8e308) and is given as null")
    if V is not None and out_up.residual is None:
        warnings.append(f"covariance bound V̄ at p = {p:.6g}: the MARE residual could not be "
                        "evaluated in float64 (entries of V̄ or g_p(V̄) beyond its range); "
                        "V̄ is unverified and its residual is given as null")
    if out_up.not_reached:
        warnings.append(f"covariance bound V̄ at p = {p:.6g} not computed: p is above the "
                        f"lower end {lo_up:.12g} of the p_up bracket, but {out_up.method} "
                        f"did not reach the MARE fixed point ({out_up.iterations} "
                        "iterations; overflow, a blow-up or the iteration budget); V̄ is "
                        "given as null")
    if S is None and V is None and not np.all(np.isfinite(system.a)):
        warnings.append("covariance bounds not computed: the system matrices are not finite "
                        "in float64")
    return CovarianceBounds(p=p, lower=low, upper=out_up, ordered=ordered, warnings=warnings)


# ---------------------------------------------------------------------------------------------
# phase transition
# ---------------------------------------------------------------------------------------------


def _warm_fixed_point(A, C, Q, R, p: float, V0: np.ndarray | None, deadline: float,
                      rtol: float = 1e-9, blowup: float = 1e14,
                      clock: Callable[[], float] = time.perf_counter,
                      cap: int = PHASE_ITERATION_CAP) -> tuple[np.ndarray | None, int]:
    """(V̄(p), iterations) by V_{t+1} = g_p(V_t) from V0 (0 if None), at most ``cap``
    iterations and never past ``deadline`` on ``clock``; V̄ None if not reached.

    From V0 = V̄(p') with p' > p the iterates increase monotonically to V̄(p) (Lemma 1(c), (d)).
    """
    V = np.zeros_like(Q, dtype=float) if V0 is None else np.array(V0, dtype=float)
    with np.errstate(all="ignore"):
        scale = 1.0 + float(np.linalg.norm(g(A, C, Q, R, V, p)))
        for t in range(cap):
            Vn = g(A, C, Q, R, V, p)
            nv = float(np.linalg.norm(Vn))
            if not np.isfinite(nv) or nv > blowup * scale:
                return None, t + 1
            if float(np.linalg.norm(Vn - V)) <= rtol * nv:
                return Vn, t + 1
            V = Vn
            if t % 25 == 24 and clock() > deadline:
                return None, t + 1
    return None, cap


def phase_points(n: int, points: int = 120) -> int:
    """Grid size of the phase-transition curve for n states: ``points`` up to n = 20, then
    shrinking like 20/n (at least 30): each point of V̄ costs O(n³) per iteration."""
    return points if n <= 20 else max(30, int(points * 20 / n))


def phase_grid(p_low: float, p_up: float | None, points: int = 120) -> np.ndarray:
    """A grid on [0, 1] dense near the blow-ups: uniform, plus geometric offsets above
    p_low and p_up (10^-6 … 10^-0.5 of the distance to 1)."""
    third = max(points // 3, 4)
    grids = [np.linspace(0.0, 1.0, third)]
    for mark in (p_low, p_up):
        if mark is not None and 0 <= mark < 1:
            grids.append(mark + (1 - mark) * np.logspace(-6, -0.5, third))
    grid = np.unique(np.clip(np.concatenate(grids), 0.0, 1.0))
    return grid


def phase_transition(system: System, markers: Markers | None = None,
                     points: int = 120, time_budget: float | None = None,
                     clock: Callable[[], float] = time.perf_counter,
                     upper: Any = None, iteration_budget: int | None = None) -> PhaseTransition:
    """tr S̄(p) and tr V̄(p) on a grid resolving the blow-ups at p_low and p_up.

    ``iteration_budget`` bounds the fixed-point iterations of the whole V̄ curve (n above
    :data:`PHASE_NEWTON_MAX_STATES`; default :data:`LARGE_PHASE_ITERATIONS` for n >
    :data:`LARGE_STATES`, else unbounded): a count, so the curve does not depend on the
    machine's speed; the points it leaves out are stated in ``warnings`` and ``limits``.

    ``clock`` measures the time budget (injectable, so that tests count work instead of
    reading the wall clock).

    ``markers`` (p_low, p_c, p_up, operating point) are echoed; p_low and p_up are computed
    where None. Entries are None where the bound does not exist (or V̄ was not reached).

    Cost control (large n): the grid has :func:`phase_points` points; V̄ is computed from p = 1
    downwards, by Newton warm-started with the previous gain for n ≤
    :data:`PHASE_NEWTON_MAX_STATES`, else by the fixed-point iteration warm-started from the
    previous V̄ (at most :data:`PHASE_ITERATION_CAP` iterations, relative tolerance 1e-9). Once
    a point is not reached, the points closer to p_up (slower still) are skipped, and the whole
    V̄ curve stops after ``time_budget`` seconds (:data:`PHASE_TIME_BUDGET`); both are stated
    in ``warnings`` and ``limits``.
    """
    budget = PHASE_TIME_BUDGET if time_budget is None else float(time_budget)
    if markers is None:
        markers = Markers(p_low=None, p_c=None, p_up=None, operating=None)
    p_low = plow.p_low_of(system.a) if markers.p_low is None else float(markers.p_low)
    ub = upper_of(system, upper)
    p_up = native_number(ub.value) if markers.p_up is None else float(markers.p_up)
    lo_up = ub.interval[0] if ub.value is not None else 1.0
    n_points = phase_points(system.n, points)
    grid = phase_grid(p_low, p_up, n_points)
    trace_lower = []
    rho = float(max(abs(np.linalg.eigvals(system.a)))) if system.n else 0.0
    for p in grid:
        S = lower_covariance(system.a, system.q, float(p), rho)
        trace_lower.append(None if S is None else float(np.trace(S)))
    trace_upper: list[float | None] = [None] * len(grid)
    gains = [ub.extras["K"]] if "K" in ub.extras else []
    warnings: list[str] = []
    A, C, Q, R = system.a, system.c, system.q, system.r
    newton = system.n <= PHASE_NEWTON_MAX_STATES
    if iteration_budget is None and system.n > LARGE_STATES:
        iteration_budget = LARGE_PHASE_ITERATIONS
    left = iteration_budget
    t0 = clock()
    V_prev: np.ndarray | None = None
    stopped = None
    for i in range(len(grid) - 1, -1, -1):          # from p = 1 down, warm-starting
        p = float(grid[i])
        if p <= lo_up:
            continue
        if left is not None and left <= 0 and not newton:
            stopped = (f"the V̄ curve stopped at p = {p:.6g} after its budget of "
                       f"{iteration_budget} fixed-point iterations (n = {system.n} > "
                       f"{LARGE_STATES}: each costs O(n³)); "
                       f"{sum(1 for v in grid[:i + 1] if v > lo_up)} points closer to p_up "
                       "were not computed")
            break
        if clock() - t0 > budget:
            stopped = (f"the V̄ curve stopped at p = {p:.6g} after the time budget of "
                       f"{budget:g} s (KFCRIT_PHASE_TIME_BUDGET); "
                       f"{sum(1 for v in grid[:i + 1] if v > lo_up)} points closer to p_up "
                       "were not computed")
            break
        if newton:
            res = upper_covariance(system, p, gains[-1:], rtol=1e-10)   # curves: 1e-10
            V = res["V"]
        else:
            cap = PHASE_ITERATION_CAP if left is None else min(PHASE_ITERATION_CAP, left)
            V, used = _warm_fixed_point(A, C, Q, R, p, V_prev, t0 + budget, clock=clock, cap=cap)
            if left is not None:
                left -= used
            res = {"method": f"fixed-point iteration, cap {cap} iterations "
                             "or the time budget"}
        if V is None:
            warnings.append(f"V at p = {p:.6g} not reached ({res['method']})")
            if not newton and left is not None and left <= 0:
                stopped = (f"the V̄ curve stopped at p = {p:.6g} after its budget of "
                           f"{iteration_budget} fixed-point iterations (n = {system.n} > "
                           f"{LARGE_STATES}: each costs O(n³)); points closer to p_up were "
                           "not computed")
                break
            if not newton:
                stopped = (f"the V̄ curve stops at p = {p:.6g}: the warm-started fixed-point "
                           "iteration slows down towards p_up; points closer to p_up were "
                           "not computed")
                break
            continue
        trace_upper[i] = float(np.trace(V))
        V_prev = V
        if newton:
            gains.append(optimal_gain(A, C, R, V))
    if stopped:
        warnings.append(stopped)
    if ub.value is None:
        warnings.append("V̄ curve not computed: p_up has no value (its bracket "
                        f"[{ub.interval[0]:.12g}, {ub.interval[1]:.12g}] was not narrowed), so "
                        "where V̄ exists is not known")
    return PhaseTransition(
        p=[float(v) for v in grid], trace_lower=trace_lower, trace_upper=trace_upper,
        markers=replace(markers, p_low=p_low, p_up=p_up), warnings=warnings,
        limits=Limits(points=int(len(grid)), requested_points=int(points),
                      method="newton-kleinman" if newton else "warm-started fixed point",
                      time_budget_seconds=budget, stopped=stopped))


# ---------------------------------------------------------------------------------------------
# static gains
# ---------------------------------------------------------------------------------------------


def ms_stable(A, C, K, p: float) -> bool:
    """ρ(L_{K,p}) < 1, tested by positive definiteness of the solution of X = L_{K,p}(X) + I."""
    n = A.shape[0]
    try:
        X = solve_generalized_stein(A, C, K, p, np.eye(n))
    except np.linalg.LinAlgError:
        return False
    return bool(np.all(np.isfinite(X)) and np.linalg.eigvalsh(X).min() > 0)


def ms_critical_value(A: np.ndarray, C: np.ndarray, K: np.ndarray) -> dict[str, Any]:
    """p_K = inf{p ∈ [0, 1] : ρ(L_{K,p}) < 1} for the fixed gain K.

    ρ(L_{K,p}) = 1 only where 1 is an eigenvalue of L_{K,p} = 𝒜 + p(𝓕 − 𝒜), i.e. at the real
    eigenvalues p of the pencil (I − 𝒜, 𝓕 − 𝒜) (on vech coordinates). They cut [0, 1] into
    pieces on which mean-square stability is constant; each piece is tested at its midpoint.
    Returns {critical_value (None: unstable for every p), stable_up_to_one, crossings}.
    """
    n = A.shape[0]
    LA = stein_matrix(A, C, K, 0.0)
    LF = stein_matrix(A, C, K, 1.0)
    N = LA.shape[0]
    ev = sla.eigvals(np.eye(N) - LA, LF - LA)
    real = sorted({float(e.real) for e in ev
                   if np.isfinite(e) and abs(e.imag) <= 1e-9 * max(1.0, abs(e))
                   and -1e-12 <= e.real <= 1 + 1e-12})
    cuts = [0.0] + [min(max(r, 0.0), 1.0) for r in real] + [1.0]
    crit = None
    stable_pieces = []
    for a, b in zip(cuts[:-1], cuts[1:]):
        if b - a <= 1e-15:
            continue
        if ms_stable(A, C, K, 0.5 * (a + b)):
            stable_pieces.append((a, b))
            if crit is None:
                crit = a
    up_to_one = bool(stable_pieces) and stable_pieces[-1][1] >= 1.0 and all(
        stable_pieces[i][1] == stable_pieces[i + 1][0] for i in range(len(stable_pieces) - 1))
    del n
    return {"critical_value": crit, "stable_up_to_one": up_to_one,
            "crossings": [float(c) for c in real]}


STATIC_GAIN_MAX_STATES = 30
"""Largest n for the fixed-gain section (its vech eigenproblems cost O(n⁶); n = 60 took 46 s)."""


def static_gain(system: System, p: float, upper: Any = None) -> StaticGain:
    """Steady Kalman gain and best static gain: mean-square critical values and covariances.

    * steady Kalman gain K_∞ = −A P C'(C P C' + R)^{-1}, P the stabilising DARE solution (the
      filter with no losses); its critical value p_{K_∞} ≥ p_up, covariance Σ_∞(p) if p > p_{K_∞}.
    * best static gain: the gain K* of the p_up certificate (:mod:`kfcrit.theory.upper.bracket`); its
      critical value equals p_up to within the certificate's width — shown by ``difference``.

    Parameters
    ----------
    system : System
        The system.
    p : float
        Arrival probability at which the fixed-gain covariances are computed.
    upper : optional
        The p_up bracket if already computed (its certificate gain is the best static gain).

    Returns
    -------
    StaticGain
        Both gains (``available`` False where there is none), with p_up and its bracket;
        ``skipped`` says why nothing was computed above :data:`STATIC_GAIN_MAX_STATES` states.
    """
    A, C, Q, R = system.a, system.c, system.q, system.r
    p = float(p)
    if system.n > STATIC_GAIN_MAX_STATES:
        reason = (f"not computed for n = {system.n} > {STATIC_GAIN_MAX_STATES} states: the "
                  f"mean-square critical value of a fixed gain needs an eigenproblem of size "
                  f"n(n+1)/2 = {system.n * (system.n + 1) // 2} (O(n⁶) time, O(n⁴) memory)")
        return StaticGain(p=p, kalman=StaticGainEstimate(available=False, reason=reason),
                          best=BestStaticGain(available=False, reason=reason), p_up=None,
                          p_up_interval=None, skipped=reason)
    try:
        # scipy's balancing warns (and may fail) on extreme scales such as Q = 1e-250·I: the
        # result is checked for finiteness instead of letting a RuntimeWarning reach stderr
        with np.errstate(all="ignore"), _warnings.catch_warnings():
            _warnings.simplefilter("ignore", RuntimeWarning)
            P = symmetrize(sla.solve_discrete_are(A.T, C.T, Q, R))
        K_kf = optimal_gain(A, C, R, P) if np.all(np.isfinite(P)) else None
    except (np.linalg.LinAlgError, ValueError):
        K_kf = None
    ub = upper_of(system, upper)
    kalman = StaticGainEstimate(available=False) if K_kf is None else \
        _fixed_gain(StaticGainEstimate, system, K_kf, p)
    K_best = ub.extras.get("K")
    best = BestStaticGain(available=False) if K_best is None else \
        _fixed_gain(BestStaticGain, system, K_best, p)
    if best.available and best.critical_value is not None and ub.value is not None:
        best = replace(best, difference=float(best.critical_value - ub.value),
                       equals_p_up=bool(ub.interval[0] - 1e-9 <= best.critical_value
                                        <= ub.interval[1] + 1e-9))
    return StaticGain(p=p, kalman=kalman, best=best, p_up=native_number(ub.value),
                      p_up_interval=[native_number(v) for v in ub.interval])


def _fixed_gain(cls: type, system: System, K: np.ndarray, p: float) -> Any:
    """The fixed gain ``K`` as ``cls`` (:class:`StaticGainEstimate` or
    :class:`BestStaticGain`): its mean-square critical value (:func:`ms_critical_value`) and
    its steady covariance at ``p`` (:func:`stabilising_solution`); the gain itself for n ≤ 6."""
    A, C, Q, R = system.a, system.c, system.q, system.r
    crit = ms_critical_value(A, C, K)
    cov = covariance_summary(stabilising_solution(A, C, Q, R, K, p))
    return cls(available=True, critical_value=native_number(crit["critical_value"]),
               stable_up_to_one=bool(crit["stable_up_to_one"]),
               crossings=[float(c) for c in crit["crossings"]],
               covariance_exists=cov.exists, covariance_trace=cov.trace,
               covariance_max_eig=cov.max_eig, covariance_matrix=cov.matrix,
               gain=_matrix(K) if system.n <= 6 else ABSENT)
