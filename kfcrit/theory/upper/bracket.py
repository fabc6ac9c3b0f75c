"""The upper bound p_up of the critical arrival probability, with a checked certificate.

p_up = inf { p : ∃ K, X ≻ 0 with X ≻ L_{K,p}(X) },  L_{K,p}(X) = (1−p) A X A' + p F X F',
F = A + K C (Sinopoli Thm 5 with Q, R scaled away). Minimising over K for fixed X gives the
noise-free MARE map G_p(X) = A X A' − p A X C'(C X C')^{-1} C X A' = min_K L_{K,p}(X), which is
monotone, concave and positively homogeneous; p_up is where its cone spectral radius r(p)
crosses 1 (docs/theory.md §3).

The default method ("newton") works in four steps:

1. *Reduce.* Only the modes with |λ| ≥ 1 matter: with an ordered real Schur form
   A = Z [[T_uu, T_us], [0, T_ss]] Z', p_up(A, C) = p_up(T_uu, C Z_u) (a stable block driven by
   nothing decays; a gain that ignores it keeps mean-square stability — and the unstable
   subspace carries an invariant sub-cone of G_p, so the reduced radius is a lower bound).
2. *Bracket.* Bisection on p with r(p) estimated by normalised power iteration.
3. *Newton* on the eigen-system G_p(X) = X, tr X = 1 in the unknowns (X, p): the Jacobian in X
   is L_{K_X,p} − I (envelope theorem), in p it is −A X C'(C X C')^{-1} C X A'. Quadratic
   convergence to p* (the eigenvector X* ⪰ 0 shows r(p*) ≥ 1, hence p_up ≥ p*).
   The same Newton on the *regularised* map G^ε_p(X) = G_p with Q = R = ε·tr(X)·I gives
   p_ε ≥ p_up (a little above p*), with X_ε ≻ 0 and X_ε − L_{K,p_ε}(X_ε) ⪰ ε·tr(X_ε)·I.
4. *Certify.* Lift (X_ε, K_ε) to the full state and prove X ≻ 0, X − L_{K,hi}(X) ≻ 0 in ball
   arithmetic on the exact matrices (:mod:`kfcrit.theory.upper.certify`). The lower end is p_low (Thm 3,
   proven) when hi − tol ≤ p_low, otherwise the Newton root p* (numerical; moved down, and
   the bracket then wider than tol, when its shift under a larger regulariser shows it less
   accurate than that: :func:`kfcrit.theory.upper.cone.root_error`), upgraded to a
   proof when a positive definite eigenvector X_u of G_lo on the unstable block with eigenvalue
   > 1 is verified in balls on an exactly A-invariant subspace (enclosed by Stewart's theorem,
   :func:`kfcrit.theory.upper.certify.invariant_block`). That is valid with stable modes too: G_p maps the
   cone of PSD matrices supported on an A-invariant subspace into itself, so its cone radius
   bounds that of the full map from below (:func:`cone_lower_check`).

``method="lmi"`` runs Sinopoli's Ψ_p LMI (:mod:`kfcrit.theory.upper.lmi`) instead; "auto" runs "newton"
and falls back to the LMI when Newton cannot produce a certified bracket.

Modules: :mod:`kfcrit.theory.upper.cone` (reduction, power iteration, Newton, lifting),
:mod:`kfcrit.theory.upper.certs` (the ball-checked certificates of both ends),
:mod:`kfcrit.theory.upper.newton` (the fast method), :mod:`kfcrit.theory.critical.plow` (p_low, C invertible),
:mod:`kfcrit.theory.upper.record` (the result type and its record entries); this module is the
public interface.
"""
from __future__ import annotations

import math
import sys
import time
import warnings
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import scipy.linalg as sla

from kfcrit.defaults import DEFAULT_TOLERANCE
from kfcrit.model.system import System
from kfcrit.records.bounds import UpperCertificate, UpperLowerEvidence
from kfcrit.theory.covariance.riccati import symmetrize
from kfcrit.theory.critical.plow import PLow, c_invertible, p_low_bounds, p_low_from_structure, p_low_of
from kfcrit.theory.upper import lmi
from kfcrit.theory.upper.certs import invariant_block_of, lower_end, stein_certificate
from kfcrit.theory.upper.cone import NEWTON_MAX_REDUCED, full_gain, reduce_system
from kfcrit.theory.upper.large import P_LOW_VERIFIED, verified_p_low
from kfcrit.theory.upper.newton import newton_method
from kfcrit.theory.upper.record import (
    UpperBound,
    certificate_summary,
    evidence_p_low,
    native_number,
)

__all__ = ["METHODS", "PLow", "UpperBound", "c_invertible", "invariant_block_of",
           "is_numerical_failure", "marginal_certificate", "numerical_failure_types",
           "p_low_bounds", "p_low_of", "reduce_system", "slow_observer_gain", "upper_bound",
           "upper_section"]


def _c_invertible_bound(system: System, how: str, known: PLow | None) -> UpperBound:
    """p_up = p_c = p_low exactly when C is invertible (Sinopoli et al. 2004 Section IV)."""
    t0 = time.perf_counter()
    pl = known if known is not None else p_low_bounds(system)
    kappa = float(np.linalg.cond(system.c))
    statement = ("C is square and invertible (" + how + "): the gain K = −A C⁻¹ gives "
                 "F = A + K C = 0, so X ≻ L_{K,p}(X) = (1−p) A X A' has a solution X ≻ 0 iff "
                 "(1−p) ρ(A)² < 1, i.e. iff p > p_low; hence p_up = p_low = max(1 − 1/ρ(A)², 0) "
                 "exactly and p_c = p_up = p_low (Sinopoli et al. 2004 Section IV). The infimum is "
                 "not attained: every p > p_low is certified by this K.")
    warn: list[str] = []
    if not system.exact and kappa > 1e8:
        warn.append(f"C is invertible as given (its binary floats taken exactly) but "
                    f"ill-conditioned: cond₂(C) ≈ {kappa:.3g}, so a relative change of about "
                    f"{1 / kappa:.1g} in C can make it singular and raise p_up")
    interval = (pl.down, pl.up)
    cert = UpperCertificate(
        kind="theorem: C invertible, F = A + K C = 0 with K = −A C⁻¹",
        origin="exact decision, no numerical certificate needed", ok=bool(pl.rigorous),
        p=native_number(pl.up), statement=statement, reason="proven" if pl.rigorous else
        "p_low from float eigenvalues (not rigorous)",
        verified_by=f"{how}; p_low by {pl.how}", condition_number_C=kappa)
    lower = UpperLowerEvidence(
        kind="theorem", value=native_number(pl.down), certified=bool(pl.rigorous),
        expression=pl.expression,
        statement="p_up ≥ p_c ≥ p_low = 1 − 1/ρ(A)² (Sinopoli Thm 3); here "
                  "p_up = p_low exactly (C invertible)")
    solver = {"seconds": time.perf_counter() - t0, "solves": 0, "special_case": "C invertible",
              "p_low": pl.how}
    return UpperBound(pl.up, interval, pl.rigorous, "determined" if pl.rigorous else
                      "undetermined", "exact", cert, lower, solver, tuple(warn),
                      {"p_low_expression": pl.expression})


METHODS = ("auto", "newton", "lmi")


def upper_bound(system: System, tol: float = DEFAULT_TOLERANCE, method: str = "auto",
                structure: Any | None = None) -> UpperBound:
    r"""Upper bound p_up on the critical arrival probability with a bracket [lo, hi], hi − lo ≤ tol.

    .. math::

        p_{up} = \inf\{p : \exists K, X \succ 0,\ X \succ (1-p) A X A' + p (A+KC) X (A+KC)'\}

    This is Sinopoli's Theorem 5 (the Ψ_p LMI) with Q and R scaled away; p_low ≤ p_c ≤ p_up
    (Theorem 3). For a single output (m = 1) the claim p_up = 1 − 1/Π|λ_u|² is a cross-check.

    Parameters
    ----------
    system : System
        The system; only A and C matter.
    tol : float
        Requested width of the bracket.
    method : {"auto", "newton", "lmi"}
        "newton" — cone-spectral-radius Newton with a lifted, ball-checked certificate (fast);
        "lmi" — Sinopoli's Ψ_p LMI bisection (cvxpy + Clarabel); "auto" — "newton", falling
        back to "lmi" if Newton gives no certified bracket.
    structure : kfcrit.theory.structure.eigen.Structure, optional
        The eigen-structure of ``system`` (``critical.structure_of(system, tolerance)``). On its
        exact path the lower end p_low is the exact 1 − 1/|λ_1|² rounded down; without it
        p_low is enclosed from the matrices (:func:`kfcrit.theory.critical.plow.p_low_bounds`). The
        result depends on the arguments only, never on what ran before.

    Returns
    -------
    UpperBound
        ``value`` (the upper end), ``interval`` (lo, hi), ``status`` ("determined" or
        "undetermined"), ``method`` and the certificate. ``certified`` is True only if the upper
        end ``hi`` passed :func:`certify.verify_upper`.

    Raises
    ------
    ValueError
        ``method`` not one of "auto", "newton", "lmi". Numerical failures do not raise: they
        give an "undetermined" record.

    References
    ----------
    Sinopoli et al. (2004), Theorems 3 and 5 and Corollary 1; docs/theory.md §3 (equivalent
    characterisations of p_up).

    Examples
    --------
    >>> from kfcrit import System, upper_bound
    >>> ub = upper_bound(System(A=[[1.25, 0], [1, 1.1]], C=[[1, 1]], Q=20, R=2.5))
    >>> round(ub.value, 6), ub.certified, ub.status      # 1 - 1/(1.25 * 1.1)**2 = 57/121
    (0.471074, True, 'determined')
    >>> upper_bound(System(A=[[2]], C=[[1]], Q=1, R=1)).interval   # C invertible: p_up = p_low
    (0.75, 0.75)
    >>> upper_bound(System(A=[[2]], C=[[1]], Q=1, R=1), method="sdp")
    Traceback (most recent call last):
        ...
    ValueError: method must be one of ('auto', 'newton', 'lmi'), got 'sdp'
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    known = p_low_from_structure(structure)
    progress: dict[str, Any] = {}
    t0 = time.perf_counter()
    try:
        if method != "lmi":
            progress["stage"] = "C invertible test"
            inv, how = c_invertible(system)
            if inv:
                return replace(_c_invertible_bound(system, how, known), tolerance=float(tol))
        raw = _solve(_Problem(problem_key(system, tol, method), system, float(tol), method,
                              progress))
        # the LMI works to max(tol, 1e-7): judge its width by the tolerance it used
        used = max(tol, 1e-7) if raw.method == "lmi" else tol
        return _exact_lower_end(system, raw, used, known)
    except Exception as exc:              # noqa: BLE001 — re-raised unless numerical
        if not is_numerical_failure(exc):
            raise
        return _failure_record(system, tol, method, exc, progress,
                               time.perf_counter() - t0, known)


def problem_key(system: System, tol: float, method: str) -> tuple:
    """What fixes the bracket: the exact A and C (their exact entry text, computed once per
    system by :meth:`kfcrit.model.system.System.matrices_text`; for float input the binary
    floats themselves), tol and method. Equal for equal matrices however they were built;
    costs a few tenths of a second at 400 states where ``sympy.srepr`` took seconds."""
    if system.exact:
        text = system.matrices_text()
        mats: tuple = tuple(tuple(tuple(row) for row in text[nm]) for nm in ("A", "C"))
    else:
        mats = (system.a.tobytes(), system.c.tobytes(), system.a.shape, system.c.shape)
    return mats, float(tol), method


@dataclass(frozen=True)
class _Problem:
    """One bracket computation (Newton or LMI): compared and hashed by ``key`` (the exact A
    and C, tol and method), which fixes its result — p_up depends on A and C only; the other
    fields are its inputs and a scratch record of progress."""

    key: tuple
    system: System = field(compare=False, hash=False)
    tol: float = field(compare=False, hash=False)
    method: str = field(compare=False, hash=False)
    progress: dict[str, Any] = field(compare=False, hash=False)


def _solve(problem: _Problem) -> UpperBound:
    """The bracket of ``problem`` (no memo: callers that need p_up again pass the result in,
    e.g. :func:`kfcrit.theory.covariance.bounds.phase_transition`'s ``upper``); what the
    caller's structure adds (the exact p_low) is applied after."""
    result = _upper_bound_raw(problem.system, problem.tol, problem.method, problem.progress)
    return replace(result, tolerance=problem.tol)


def numerical_failure_types() -> tuple[type[BaseException], ...]:
    """The exceptions that mean "the numerics failed" (not a bug, not bad input): LinAlgError,
    FloatingPointError / ZeroDivisionError / OverflowError (ArithmeticError), ValueError (scipy
    solvers raise it for non-finite or ill-posed data) and, when cvxpy has been loaded,
    its SolverError."""
    types: list[type[BaseException]] = [np.linalg.LinAlgError, ArithmeticError, ValueError]
    cp_error = getattr(sys.modules.get("cvxpy.error"), "SolverError", None)
    if isinstance(cp_error, type):
        types.append(cp_error)
    return tuple(types)


def is_numerical_failure(exc: BaseException) -> bool:
    return isinstance(exc, numerical_failure_types())


def _failure_record(system: System, tol: float, method: str, exc: BaseException,
                    progress: dict[str, Any], seconds: float,
                    known: PLow | None = None) -> UpperBound:
    """The ``undetermined`` record of a computation stopped by a numerical failure: the bracket
    reached so far (the lower end from p_low, or a numerical cone-radius bound; the upper end 1
    or a numerical power-iteration estimate — neither certified) and a warning naming the
    failure. Not memoised (the failure may be transient)."""
    try:
        p_low = (known if known is not None else p_low_bounds(system)).down
    except Exception as exc2:             # noqa: BLE001
        if not is_numerical_failure(exc2):
            raise
        try:
            p_low = p_low_of(system.a)
        except Exception:                 # noqa: BLE001
            p_low = 0.0
    lo = float(progress.get("lo", p_low))
    hi = float(progress.get("hi", 1.0))
    if not (np.isfinite(lo) and np.isfinite(hi) and p_low <= lo <= hi <= 1.0):
        lo, hi = p_low, 1.0
    lower = evidence_p_low(p_low) if lo <= p_low else UpperLowerEvidence(
        kind="numerical", value=lo, certified=False,
        statement="power-iteration bracket reached before the numerical failure (cone "
                  "spectral radius r(lo) >= 1 of the noise-free MARE map, numerically)",
        p_low_theorem=native_number(p_low))
    name = type(exc).__name__
    text = str(exc).strip().splitlines()[0][:200] if str(exc).strip() else "(no message)"
    stage = progress.get("stage", "start")
    warning = (f"upper bound undetermined: numerical failure ({name}: {text}) in the "
               f"{method} method at stage '{stage}'; the bracket [{lo:.12g}, {hi:.12g}] is the "
               "one reached so far, not certified")
    solver = {"seconds": seconds, "solves": 0, "failure": name, "failure_message": text,
              "failure_stage": stage}
    return UpperBound(None, (lo, hi), False, "undetermined",
                      progress.get("method", "newton" if method != "lmi" else "lmi"), None,
                      lower, solver, (warning,), {}, float(tol))


def _exact_lower_end(system: System, result: UpperBound, tol: float,
                     known: PLow | None) -> UpperBound:
    """Invariant: a lower end that rests on Sinopoli's p_low (evidence kind "theorem") is the
    exact p_low rounded down, and the interval always contains p_up (the upper end, when it
    is p_low itself, is rounded up)."""
    if result.lower_evidence.kind != "theorem" or result.method == "exact":
        return result
    pl = known if known is not None else p_low_bounds(system)
    verified = result.extras.get("p_low_verified")
    if not pl.rigorous and verified is None:
        verified = verified_p_low(system)
    if not pl.rigorous and verified is not None and verified <= pl.up:
        # the face-root path proved ρ(A)² from below (verified float64): a rigorous lower end
        pl = replace(pl, down=float(verified), rigorous=True,
                     how=P_LOW_VERIFIED + "; the upper value is " + pl.how)
    lo, hi = result.interval
    hi = max(hi, pl.up)
    lower = replace(result.lower_evidence, value=native_number(pl.down),
                    certified=bool(pl.rigorous),
                    p_low_enclosure=[native_number(pl.down), native_number(pl.up)],
                    p_low_how=pl.how)
    if pl.expression is not None:
        lower = replace(lower, expression=pl.expression)
    status = result.status
    # the rounding moves the lower end by a few ulps at most: allowed beyond tol
    if status == "determined" and hi - pl.down > tol + 8 * math.ulp(max(hi, 1e-300)) \
            and hi - pl.down > hi - lo:
        status = "undetermined"
    return replace(result, interval=(pl.down, hi), lower_evidence=lower, status=status)


def _upper_bound_raw(system: System, tol: float, method: str,
                     progress: dict[str, Any]) -> UpperBound:
    if method == "lmi":
        progress.update(stage="LMI bisection", method="lmi")
        return lmi.lmi_upper_bound(system, tol=max(tol, 1e-7))
    result = newton_method(system, tol, progress)
    if result.extras.get("not_applicable"):
        return result            # not detectable: no LMI fallback (it cannot succeed either)
    if result.status != "determined" and p_low_of(system.a) < tol:
        # ρ(A) ≤ 1 (in float64): the threshold sits at p = 0, where the cone eigenvector is
        # singular; a slow observer certifies p_up ≤ tol instead.
        progress.update(stage="slow-observer certificate (marginal modes)")
        marginal = marginal_certificate(system, tol)
        if marginal is not None:
            return marginal
    if method == "auto" and not result.certified and system.n <= 30:
        progress.update(stage="LMI fallback", method="lmi")
        alt = lmi.lmi_upper_bound(system, tol=max(tol, 1e-7))
        if alt.certified:
            width_ok = alt.interval[1] - alt.interval[0] <= tol
            return replace(alt, status=alt.status if width_ok else "undetermined",
                           warnings=result.warnings
                           + ("newton method gave no certificate; LMI used ("
                              + alt.solver.get("ends", "ends not stated") + ")",)
                           + alt.warnings)
    return result


MARGINAL_RATES = (0.1, 0.03, 0.3, 0.01)
"""Decay rates a = c·p of the slow observers tried by :func:`marginal_certificate` (c here)."""


def slow_observer_gain(Au: np.ndarray, Cu: np.ndarray, a: float) -> tuple[np.ndarray, np.ndarray]:
    r"""Gain G with A_u + G C_u stable at rate ≈ a, and its (balancing) covariance P⁺.

    The minimum-energy filter (Q = 0, R = I) of the expanded system Ã = A_u / (1 − a): with the
    observability Gramian Y of (Ã^{-1}, C_u Ã^{-1}),

    .. math::

        Y = Ã'^{-1} Y Ã^{-1} + Ã'^{-1} C_u' C_u Ã^{-1}, \quad P^+ = (Y + C_u' C_u)^{-1},
        \quad G = -A_u P^+ C_u',

    the poles of Ã + G̃ C_u are those of Ã reflected into the unit disc, so A_u + G C_u has
    its poles at radius (1 − a)² when every |λ(A_u)| = 1; G and P⁺ carry the Jordan scaling
    (entries of order a, a², …) that a fixed-shape gain lacks. Only a proposal: the
    certificate built from it is checked in ball arithmetic.
    """
    B = (1.0 - a) * np.linalg.inv(Au)
    CB = Cu @ B
    with warnings.catch_warnings():
        # Y is ill-conditioned by design (entries of order a^{-1}, a^{-3}, …)
        warnings.simplefilter("ignore", sla.LinAlgWarning)
        Y = symmetrize(sla.solve_discrete_lyapunov(B.T, CB.T @ CB))
        M = Y + Cu.T @ Cu
        d = 1.0 / np.sqrt(np.diag(M))
        P = symmetrize(d[:, None] * np.linalg.inv(d[:, None] * M * d[None, :]) * d[None, :])
    return -Au @ P @ Cu.T, P


def marginal_certificate(system: System, tol: float) -> UpperBound | None:
    r"""p_up ≤ tol certified by a slow observer, for A with every |λ| ≤ 1 (marginal modes).

    At p = tol the gain K = G / p of :func:`slow_observer_gain` (rate a = c·p) makes the jump
    system mean-square stable: with F = A + K C,

    .. math::

        L_{K,p}(X) = (A + G C) X (A + G C)' + \frac{1-p}{p} G C X C' G',

    a stable observer of bandwidth a plus a multiplicative noise of size a²/p = c² p. The
    Stein solution X_u = L_{K,p}(X_u) + I, balanced by P⁺, is lifted and proven
    (X ≻ 0, X − L_{K,p}(X) ≻ 0) in ball arithmetic by :func:`stein_certificate`. With the
    trivial lower end p_up ≥ p_low = 0 the bracket is [0, tol]. None when no rate certifies.
    """
    red = reduce_system(system)
    if red.k == 0 or red.k > NEWTON_MAX_REDUCED:
        return None
    p = float(tol)
    stats: dict[str, Any] = {"power_iterations": 0, "newton_iterations": 0,
                             "certificate_checks": 0, "reduced_states": red.k}
    t0 = time.perf_counter()
    for c in MARGINAL_RATES:
        try:
            G, P = slow_observer_gain(red.Au, red.Cu, c * p)
        except (np.linalg.LinAlgError, ValueError, ArithmeticError):
            continue
        if not (np.all(np.isfinite(G)) and np.all(np.isfinite(P))):
            continue
        found = stein_certificate(system, red, p, G / p, stats, balance=P)
        if found is None:
            continue
        (Z, Xz, Kz), check = found
        X, K = symmetrize(Z @ Xz @ Z.T), full_gain(red, Z @ Kz)
        origin = (f"slow observer (marginal modes): K = G/p with A_u + G C_u stable at rate "
                  f"a = {c:g}·p (minimum-energy filter of A_u/(1 − a)); Stein solution "
                  "X_u = L_{K,p}(X_u) + I balanced by its covariance, lifted from the Schur "
                  "block; checked as Z X_z Z', Z K_z with the float Schur basis Z")
        cert = certificate_summary(system, check, X, K, origin, (Z, Xz, Kz), red.M)
        p_low = p_low_of(system.a)
        lo = lower_end(p, tol, p_low)
        stats.update(seconds=time.perf_counter() - t0, solves=stats["newton_iterations"],
                     observer_rate=c * p)
        return UpperBound(p, (lo, p), check.ok, "determined" if p - lo <= tol else
                          "undetermined", "newton", cert, evidence_p_low(p_low), stats, (),
                          {"X": X, "K": K, "basis": Z, "X_basis": Xz, "K_basis": Kz,
                           "output_map": red.M})
    return None


def upper_result(system: System, tol: float = DEFAULT_TOLERANCE,
                 structure: Any | None = None) -> UpperBound:
    """``upper_bound(system, tol, structure=structure)``; numerical trouble gives status
    "undetermined" with the bracket [p_low, 1]."""
    try:
        return upper_bound(system, tol=tol, structure=structure)
    except (np.linalg.LinAlgError, ValueError, ArithmeticError, RuntimeError) as exc:
        p_low = p_low_bounds(system, structure).down
        return UpperBound(None, (p_low, 1.0), False, "undetermined", "newton", None,
                          evidence_p_low(p_low), {}, (f"numerical failure: {exc}",))


def upper_section(system: System, tol: float = DEFAULT_TOLERANCE,
                  structure: Any | None = None) -> dict[str, Any]:
    """The record's ``upper_bound`` section: :func:`upper_result` as JSON data (its
    :meth:`~kfcrit.theory.upper.record.UpperBound.to_dict`)."""
    return upper_result(system, tol, structure).to_dict()
