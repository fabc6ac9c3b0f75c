"""Bursty (Gilbert–Elliott) links for any system: a necessary condition, a checked sufficient
certificate (facts, not verdicts), and the critical curve in the (failure rate, recovery rate) plane.

The channel is a two-state Markov chain γ_t ∈ {0 (lost), 1 (received)} with failure rate
f = P(γ_{t+1} = 0 | γ_t = 1) and recovery rate r = P(γ_{t+1} = 1 | γ_t = 0); its transition
matrix is T = [[1 − r, r], [f, 1 − f]] (T_ij = P(next j | now i)), its stationary arrival
probability r/(f + r) (docs/theory.md §7, §10).

* Necessary (any system): a loss burst lasts j steps with probability (1 − r)^{j−1} r, during
  which the dominant mode grows like ρ(A)^{2j}, so bounded E[P_t] needs

  .. math::

      (1 - r)\\,\\rho(A)^2 < 1 .

* Sufficient (any system): the Kalman filter is no worse than any fixed gain K; with
  F_0 = A, F_1 = A + K C and Y_j = E[e_t e_t' 1{γ_t = j}] of the fixed-gain error e_t,

  .. math::

      Y_j \\leftarrow \\sum_i T_{ij} F_i Y_i F_i' + \\text{const},

  a positive linear recursion. If some K gives it spectral radius < 1 — equivalently X_0, X_1 ≻ 0
  with X_i ≻ F_i' (Σ_j T_ij X_j) F_i (coupled Lyapunov inequalities of the adjoint) — E[P_t] is
  bounded. The gain is found by the coupled Lyapunov LMI (cvxpy + Clarabel, the Schur form
  below with Z = S_1 K), the matrices X_i by a linear (Stein) solve X = M*(X) + I, and the
  inequalities are proven in ball arithmetic on the exact A, C, f, r
  (:func:`kfcrit.theory.upper.certify.verify_markov_jump`).

  .. math::

      X_0 - A' S_0 A \\succ 0,\\quad
      \\begin{bmatrix} X_1 & A' S_1 + C' Z' \\\\ S_1 A + Z C & S_1 \\end{bmatrix} \\succ 0,
      \\quad S_0 = (1-r) X_0 + r X_1,\\ S_1 = f X_0 + (1-f) X_1 .

* For non-degenerate systems the literature states that the necessary condition is also
  sufficient (You, Fu & Xie, Automatica 2011; Mo & Sinopoli, TAC 57(3) 2012). It is reported
  as a labelled claim only, never as the verdict.
"""
from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from fractions import Fraction
from typing import Any

import numpy as np
import scipy.linalg as sla
import sympy as sp

from kfcrit.model.system import System
from kfcrit.records.bounds import CertificateCheck
from kfcrit.records.bursty import (
    BurstCertificateRecord,
    BurstClaim,
    BurstCurveRecord,
    CoupledCertificate,
    CoupledCertificateMatrices,
    NecessaryBurstCondition,
    RatesPoint,
    facts_record,
)
from kfcrit.theory.covariance.riccati import congruence_matrix, symmetrize, unvech, vech
from kfcrit.theory.critical.compare import compare_probability
from kfcrit.theory.critical.plow import rational_rho2
from kfcrit.theory.facts import StabilityFacts
from kfcrit.theory.upper import certify

LMI_MAX_STATES = 30
"""Largest n for the coupled Lyapunov LMI (cvxpy + Clarabel); above it only candidate gains."""
CERTIFICATE_MAX_STATES = 40
"""Largest n for the coupled certificate (its Stein solve has n(n+1) unknowns, O(n⁶) time)."""
EXACT_DIGITS = 60
"""Digits used to decide the sign of (1 − r)|λ_1|² − 1 for an exact |λ_1|² (then exact zero
test)."""
LMI_FEASIBLE_MARGIN = 1e-9
"""An LMI optimum t* above this is read as feasible (numerically; the ball check decides)."""
CLARABEL_SETTINGS = {"tol_gap_abs": 1e-9, "tol_gap_rel": 1e-9, "tol_feas": 1e-9,
                     "max_iter": 400}

LITERATURE = ("You, Fu & Xie, 'Mean square stability for Kalman filtering with Markovian "
              "packet losses', Automatica 47(12) 2011; Mo & Sinopoli, 'Kalman filtering with "
              "intermittent observations: tail distribution and critical value', IEEE TAC 57(3) "
              "2012")


def exact_rate(x: Any, name: str = "rate") -> sp.Expr:
    """An exact probability: sympy numbers as they are, Fractions and ints exactly, Python
    floats by their shortest decimal form (0.1 → 1/10, as the user wrote it)."""
    if isinstance(x, bool):
        raise TypeError(f"{name} must be a number, got {x!r}")
    if isinstance(x, sp.Basic):
        v = x
    elif isinstance(x, Fraction | int):
        v = sp.Rational(Fraction(x).numerator, Fraction(x).denominator)
    elif isinstance(x, float):
        if not np.isfinite(x):
            raise ValueError(f"{name} must be finite, got {x!r}")
        fr = Fraction(repr(x))
        v = sp.Rational(fr.numerator, fr.denominator)
    else:
        raise TypeError(f"{name} must be a number, got {type(x).__name__}")
    if isinstance(v, sp.Float):
        fr = Fraction(str(v))
        v = sp.Rational(fr.numerator, fr.denominator)
    if not (sp.N(v, 30) >= 0 and sp.N(v, 30) <= 1):
        raise ValueError(f"{name} must lie in [0, 1], got {v}")
    return v


# ---------------------------------------------------------------------------------------------
# the necessary burst condition
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Rho2:
    """ρ(A)² enclosed: lo ≤ ρ² ≤ hi, with the exact number when known."""

    lo: Fraction
    hi: Fraction
    exact: sp.Expr | None
    how: str
    rigorous: bool


def spectral_radius2(system: System, structure: Any | None = None) -> Rho2:
    """Enclose ρ(A)² = |λ_1|² (exact when possible).

    Sources, in order: the exact |λ_1|² of an exact-path ``structure``
    (:mod:`kfcrit.theory.structure.eigen`); sympy eigenvalues for n ≤ 2; the exact characteristic
    polynomial of a rational A (python-flint root isolation); ball eigenvalues of the exact A;
    float64 eigenvalues widened by 1e-12 relative (not rigorous).
    """
    eigen = getattr(structure, "eigen", None)
    if getattr(structure, "path", None) == "exact" and eigen and eigen[0].mod2_expr is not None:
        return _rho2_of_expr(eigen[0].mod2_expr, "exact (structure analysis)")
    n = system.n
    if n <= 2:
        try:
            eigs = list(sp.Matrix(system.A).eigenvals())
            mods = [sp.radsimp(sp.expand(sp.re(z) ** 2 + sp.im(z) ** 2)) for z in eigs]
            return _rho2_of_expr(max(mods, key=lambda v: float(sp.N(v, 30))),
                                 "exact (eigenvalues by sympy)")
        except (ValueError, TypeError, ArithmeticError):
            pass
    bounds, how = None, ""
    if n <= 60:
        if all(e.is_Rational for e in system.A):
            bounds, how = rational_rho2(system), "exact characteristic polynomial (python-flint)"
        if bounds is None:
            bounds, how = certify.spectral_radius2_bounds(system), "ball eigenvalues (python-flint)"
    if bounds is not None:
        return Rho2(bounds[0], bounds[1], None, how, True)
    rho = float(max(abs(np.linalg.eigvals(system.a)))) if system.n else 0.0
    v = Fraction(rho * rho)
    pad = v * Fraction(1, 10 ** 12)
    return Rho2(v - pad, v + pad, None, "float64 eigenvalues, widened by 1e-12 relative "
                "(not rigorous)", False)


def _rho2_of_expr(mod2: sp.Expr, how: str) -> Rho2:
    v = sp.N(mod2, EXACT_DIGITS)
    x = Fraction(str(v))
    pad = abs(x) * Fraction(1, 10 ** (EXACT_DIGITS - 10)) + Fraction(1, 10 ** 300)
    return Rho2(x - pad, x + pad, mod2, how, True)


NECESSARY_CONDITION = "(1 - r) * rho(A)^2 < 1"
"""The necessary burst condition in words (``condition`` of its record)."""


@dataclass(frozen=True)
class BurstNecessary:
    """The necessary burst condition (1 − r)·ρ(A)² < 1 at one recovery rate."""

    holds: bool | None
    value: float
    enclosure: tuple[float, float]
    rho2: float
    rho2_expression: str | None
    recovery_rate: float
    rigorous: bool
    how: str
    statement: str

    def record(self) -> NecessaryBurstCondition:
        """The record of the condition (``certificate.necessary`` of the bursty section)."""
        return NecessaryBurstCondition(
            holds=self.holds, value=_number(self.value),
            enclosure=[_number(v) for v in self.enclosure], rho2=_number(self.rho2),
            rho2_expression=self.rho2_expression, recovery_rate=_number(self.recovery_rate),
            rigorous=bool(self.rigorous), how=self.how, statement=self.statement,
            condition=NECESSARY_CONDITION)

    def to_dict(self) -> dict[str, Any]:
        return {"holds": self.holds, "value": self.value, "enclosure": list(self.enclosure),
                "rho2": self.rho2, "rho2_expression": self.rho2_expression,
                "recovery_rate": self.recovery_rate, "rigorous": self.rigorous,
                "how": self.how, "statement": self.statement,
                "condition": NECESSARY_CONDITION}


def burst_necessary(system: System, recovery_rate: Any,
                    structure: Any | None = None) -> BurstNecessary:
    """Decide the necessary condition (1 − r)·ρ(A)² < 1 for bounded E[P_t] (docs/theory.md §10).

    .. math::

        E[P_t] \\succeq \\sum_{j \\ge 1} (1-r)^{j-1} r\\, \\rho^{2j} c \\to \\infty
        \\quad\\text{when } (1-r)\\rho^2 \\ge 1 .

    Exact comparisons when ρ² is exact (structure, n ≤ 2) and r is exact: the sign of
    (1 − r)ρ² − 1 from 60 digits, equality by an exact zero test. With a ball enclosure of ρ²
    the decision is rigorous unless the enclosure straddles the boundary (then ``holds`` is
    None).
    """
    r = exact_rate(recovery_rate, "recovery_rate")
    rho = spectral_radius2(system, structure)
    one_minus = 1 - Fraction(str(sp.N(r, EXACT_DIGITS))) if not r.is_Rational else \
        1 - Fraction(int(r.p), int(r.q))
    lo, hi = one_minus * rho.lo, one_minus * rho.hi
    holds: bool | None = None
    how = rho.how
    excess: sp.Expr | None = None
    if rho.exact is not None:
        excess = sp.expand((1 - r) * rho.exact - 1)
        try:   # (1 - r) rho^2 < 1  <=>  r > 1 - 1/rho^2: the package's one exact comparison
            sign = compare_probability(r, 1 - 1 / rho.exact)
        except ArithmeticError:
            sign = None
        if sign is not None:
            holds = sign > 0
            if sign == 0:
                how += "; equality (1 - r) rho^2 = 1 proven exactly"
    elif r.is_Rational:
        if hi < 1:
            holds = True
        elif lo >= 1:
            holds = False
    if holds is not None and not rho.rigorous:
        how += " (decision not rigorous)"
    value = float((lo + hi) / 2)
    expr = None if rho.exact is None else sp.sstr(rho.exact)
    rs = float(r)
    shown = near_one_text(excess) if excess is not None else f"{value:.12g}"
    if holds is None:
        statement = (f"(1 - r) rho(A)^2 lies in [{float(lo):.12g}, {float(hi):.12g}] at "
                     f"r = {rs:.12g}: too close to 1 to decide")
    elif holds:
        statement = (f"(1 - r) rho(A)^2 = {shown} < 1 at r = {rs:.12g}: the necessary burst "
                     "condition holds (for n > 1 not sufficient on its own)")
    else:
        statement = (f"(1 - r) rho(A)^2 = {shown} >= 1 at r = {rs:.12g}: a loss burst of j "
                     "steps has probability (1 - r)^(j-1) r and lets the dominant mode grow like "
                     "rho^(2j), so E[P_t] diverges (docs/theory.md §7, §10)")
    return BurstNecessary(holds, value, (float(lo), float(hi)), float((rho.lo + rho.hi) / 2),
                          expr, rs, rho.rigorous and holds is not None, how, statement)


def necessary_recovery_threshold(system: System, structure: Any | None = None
                                 ) -> tuple[float, str | None]:
    """The recovery rate where the necessary condition switches: r_nec = max(1 − 1/ρ², 0)
    (independent of f); returns (float value, exact expression or None). Below or at r_nec the
    link is mean-unstable; for ρ(A) ≤ 1 every r > 0 passes the condition."""
    rho = spectral_radius2(system, structure)
    if rho.exact is not None:
        if sp.N(rho.exact - 1, EXACT_DIGITS) <= 0:
            return 0.0, "0"
        e = sp.radsimp(1 - 1 / rho.exact)
        return float(sp.N(e, 30)), sp.sstr(e)
    mid = (rho.lo + rho.hi) / 2
    return (float(1 - 1 / mid) if mid > 1 else 0.0), None


def recovery_margin(recovery_rate: Any, r_nec: float | None, r_nec_exact: Any = None) -> float:
    r"""The margin of a bursty link against its own boundary (theory §10): r − r_nec, with
    r_nec = max(1 − 1/ρ(A)², 0) the necessary recovery threshold (positive iff the necessary
    burst condition holds).

    .. math::  \delta = r - r_{nec}, \qquad r_{nec} = \max(1 - \rho(A)^{-2}, 0)

    Rounded once to a double when r and ``r_nec_exact`` are both exact (so 9/25 + 10⁻⁴⁰ − 9/25
    is 1e-40, not 0.0); ``r_nec`` None reads as 0, and ``r_nec_exact`` counts only where
    r_nec > 0.
    """
    threshold = r_nec if r_nec is not None else 0.0
    fallback = float(recovery_rate) - threshold
    exact = r_nec_exact if r_nec is not None and r_nec > 0 else None
    if isinstance(recovery_rate, sp.Basic) and isinstance(exact, sp.Basic) and not (
            recovery_rate.has(sp.Float) or exact.has(sp.Float)):
        try:
            return float(sp.N(recovery_rate - exact, 30))
        except (TypeError, ValueError):
            return fallback
    return fallback


# ---------------------------------------------------------------------------------------------
# the sufficient coupled certificate
# ---------------------------------------------------------------------------------------------


def transition_matrix(f: float, r: float) -> np.ndarray:
    """T = [[1 − r, r], [f, 1 − f]], T_ij = P(γ_{t+1} = j | γ_t = i) (0 lost, 1 received)."""
    return np.array([[1.0 - r, r], [f, 1.0 - f]])


def coupled_operator(A: np.ndarray, C: np.ndarray, K: np.ndarray, f: float,
                     r: float) -> np.ndarray:
    """Matrix of the second-moment map (Y_0, Y_1) ↦ (Σ_i T_i0 F_i Y_i F_i', Σ_i T_i1 F_i Y_i F_i')
    on (vech Y_0, vech Y_1); F_0 = A, F_1 = A + K C."""
    T = transition_matrix(f, r)
    L = [congruence_matrix(A), congruence_matrix(A + K @ C)]
    return np.block([[T[0, 0] * L[0], T[1, 0] * L[1]], [T[0, 1] * L[0], T[1, 1] * L[1]]])


def coupled_radius(A: np.ndarray, C: np.ndarray, K: np.ndarray, f: float, r: float) -> float:
    """Spectral radius of :func:`coupled_operator` (< 1: the fixed-gain error system is
    mean-square stable over the chain)."""
    return float(max(abs(np.linalg.eigvals(coupled_operator(A, C, K, f, r)))))


def adjoint_stein(A: np.ndarray, C: np.ndarray, K: np.ndarray, f: float, r: float
                  ) -> tuple[np.ndarray, np.ndarray] | None:
    """Solve X_i = F_i' (Σ_j T_ij X_j) F_i + I (i = 0, 1): the coupled Lyapunov matrices with
    margin I by construction (positive definite iff the spectral radius is < 1)."""
    n = A.shape[0]
    T = transition_matrix(f, r)
    Lt = [congruence_matrix(A.T), congruence_matrix((A + K @ C).T)]
    M = np.block([[T[0, 0] * Lt[0], T[0, 1] * Lt[0]], [T[1, 0] * Lt[1], T[1, 1] * Lt[1]]])
    N = n * (n + 1) // 2
    rhs = np.concatenate([vech(np.eye(n)), vech(np.eye(n))])
    try:
        with np.errstate(all="raise"):
            x = sla.solve(np.eye(2 * N) - M, rhs)
    except (np.linalg.LinAlgError, FloatingPointError, ValueError):
        return None
    X0, X1 = unvech(x[:N], n), unvech(x[N:], n)
    if not (np.all(np.isfinite(X0)) and np.all(np.isfinite(X1))):
        return None
    if min(np.linalg.eigvalsh(X0).min(), np.linalg.eigvalsh(X1).min()) <= 0:
        return None
    s = float(np.trace(X0) + np.trace(X1))
    return symmetrize(X0) / s, symmetrize(X1) / s


class CoupledLmi:
    r"""The coupled Lyapunov LMI of (A, C) with the transition rates (f, r) as parameters.

    .. math::

        \max t \ \text{s.t.}\ X_0 - A^\top S_0 A \succeq tI,\
        \begin{bmatrix} X_1 & (S_1 A + Z C)^\top \\ S_1 A + Z C & S_1 \end{bmatrix}
        \succeq tI,\ X_i \preceq I,

    with :math:`S_0 = (1-r)X_0 + rX_1`, :math:`S_1 = fX_0 + (1-f)X_1` (affine in the parameters
    times the variables, so the problem is DPP: cvxpy compiles it once and each
    :meth:`solve` only re-fills the numbers — the critical curve solves it ~100 times).
    """

    def __init__(self, A: np.ndarray, C: np.ndarray) -> None:
        import cvxpy as cp

        n, m = A.shape[0], C.shape[0]
        self.f = cp.Parameter(nonneg=True)
        self.r = cp.Parameter(nonneg=True)
        self.X0 = cp.Variable((n, n), symmetric=True)
        self.X1 = cp.Variable((n, n), symmetric=True)
        self.Z = cp.Variable((n, m))
        self.t = cp.Variable()
        S0 = (1 - self.r) * self.X0 + self.r * self.X1
        S1 = self.f * self.X0 + (1 - self.f) * self.X1
        off = S1 @ A + self.Z @ C
        block = cp.bmat([[self.X1, off.T], [off, S1]])
        eye = np.eye(n)
        cons = [self.X0 - A.T @ S0 @ A - self.t * eye >> 0,
                0.5 * (block + block.T) - self.t * np.eye(2 * n) >> 0,
                eye - self.X0 >> 0, eye - self.X1 >> 0]
        self.problem = cp.Problem(cp.Maximize(self.t), cons)

    def solve(self, f: float, r: float) -> tuple[np.ndarray | None, float]:
        """(K = S_1⁻¹ Z or None, t*) at (f, r); t* > 0 means feasible (numerically)."""
        import cvxpy as cp

        self.f.value, self.r.value = float(f), float(r)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                self.problem.solve(solver=cp.CLARABEL, **CLARABEL_SETTINGS)
        except (cp.error.SolverError, ValueError, ArithmeticError):
            return None, float("nan")
        t = self.t.value
        if self.problem.status not in ("optimal", "optimal_inaccurate") or t is None:
            return None, float("nan")
        S1v = f * self.X0.value + (1 - f) * self.X1.value
        try:
            K = np.linalg.solve(S1v, self.Z.value)
        except np.linalg.LinAlgError:
            return None, float(t)
        return (K if np.all(np.isfinite(K)) else None), float(t)


def lmi_gain(A: np.ndarray, C: np.ndarray, f: float, r: float) -> tuple[np.ndarray | None, float]:
    """The gain of the coupled Lyapunov LMI (:class:`CoupledLmi`), maximising the margin t:
    returns (K = S_1⁻¹ Z or None, t*). t* > 0 means feasible (numerically)."""
    return CoupledLmi(A, C).solve(f, r)


def candidate_gains(A: np.ndarray, C: np.ndarray) -> list[tuple[str, np.ndarray]]:
    """Gains tried besides the LMI's: the output deadbeat −A C⁺ (F_1 = A (I − C⁺C)) and the
    steady Kalman gain of (A, C, I, I)."""
    out = [("deadbeat -A C^+", -A @ np.linalg.pinv(C))]
    try:
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            P = sla.solve_discrete_are(A.T, C.T, np.eye(A.shape[0]), np.eye(C.shape[0]))
        K = -A @ P @ C.T @ np.linalg.inv(C @ P @ C.T + np.eye(C.shape[0]))
        if np.all(np.isfinite(K)):
            out.append(("steady Kalman gain (Q = I, R = I)", K))
    except (np.linalg.LinAlgError, ValueError):
        pass
    return out


@dataclass(frozen=True)
class BurstCertificate:
    """The coupled fixed-gain certificate at (f, r): proven, or why not."""

    certified: bool
    failure_rate: float
    recovery_rate: float
    spectral_radius: float | None
    gain_origin: str | None
    check: dict[str, Any] | None
    reason: str
    seconds: float
    lmi_margin: float | None = None
    matrices: dict[str, Any] | None = field(default=None, compare=False)

    def record(self) -> CoupledCertificate:
        """The record of the certificate (``certificate.certificate`` of the bursty section;
        its wall-clock seconds are not part of it)."""
        m = self.matrices
        mats = None
        if m is not None:
            mats = CoupledCertificateMatrices(K=_rows(m["K"]), X0=_rows(m["X0"]),
                                              X1=_rows(m["X1"]))
            if "K1" in m:
                mats = replace(mats, K1=_rows(m["K1"]))
        return CoupledCertificate(
            certified=bool(self.certified), failure_rate=_number(self.failure_rate),
            recovery_rate=_number(self.recovery_rate),
            spectral_radius=_finite(self.spectral_radius), gain_origin=self.gain_origin,
            check=_check_record(self.check), reason=self.reason,
            lmi_margin=_finite(self.lmi_margin), matrices=mats, kind=COUPLED_KIND)

    def to_dict(self) -> dict[str, Any]:
        return {"certified": self.certified, "failure_rate": self.failure_rate,
                "recovery_rate": self.recovery_rate,
                "spectral_radius": _finite(self.spectral_radius),
                "gain_origin": self.gain_origin, "check": self.check, "reason": self.reason,
                "seconds": self.seconds, "lmi_margin": _finite(self.lmi_margin),
                "matrices": self.matrices, "kind": COUPLED_KIND}


COUPLED_KIND = ("coupled Lyapunov: X_i > 0, X_i - F_i' (sum_j T_ij X_j) F_i > 0, F_0 = A, "
                "F_1 = A + K C, T = [[1-r, r], [f, 1-f]]")
"""``kind`` of the coupled fixed-gain certificate."""


def _finite(x: float | None) -> float | None:
    return None if x is None or not np.isfinite(x) else float(x)


def _number(x: Any) -> float | int | None:
    """A number of the record: an int stays an int, a float (NumPy's too) becomes a Python
    float, None where it is not finite."""
    if x is None:
        return None
    if isinstance(x, (int, np.integer)) and not isinstance(x, (bool, np.bool_)):
        return int(x)
    f = float(x)
    return f if np.isfinite(f) else None


def _rows(M: Any) -> list[list[float | int | None]]:
    """A matrix of the record, row by row (:func:`_number` of each entry)."""
    return [[_number(v) for v in row] for row in M]


def _check_record(check: dict[str, Any] | None) -> CertificateCheck | None:
    """The record of a ball-arithmetic check
    (:meth:`kfcrit.theory.upper.certify.CheckResult.to_dict`)."""
    if check is None:
        return None
    return CertificateCheck(ok=bool(check["ok"]), kind=check["kind"], p=_number(check["p"]),
                            min_eig_x_lower=_number(check["min_eig_x_lower"]),
                            margin_lower=_number(check["margin_lower"]), reason=check["reason"],
                            margin_meaning=check["margin_meaning"],
                            verified_by=check["verified_by"])


def _mat(M: np.ndarray) -> list[list[float]]:
    return [[float(v) for v in row] for row in np.atleast_2d(M)]


def burst_certificate(system: System, failure_rate: Any, recovery_rate: Any,
                      use_lmi: bool = True) -> BurstCertificate:
    """Find and prove the coupled fixed-gain certificate at (f, r) (module docstring).

    Gains tried: the coupled LMI's (n ≤ :data:`LMI_MAX_STATES`, cvxpy + Clarabel), then
    :func:`candidate_gains`; for each, :func:`adjoint_stein` proposes X_0, X_1 and
    :func:`kfcrit.theory.upper.certify.verify_markov_jump` decides on the exact matrices.
    """
    t0 = time.perf_counter()
    fe, re_ = exact_rate(failure_rate, "failure_rate"), exact_rate(recovery_rate, "recovery_rate")
    f, r = float(fe), float(re_)
    A, C = system.a, system.c
    n = system.n

    def done(ok, rho, origin, check, reason, margin=None, mats=None):
        return BurstCertificate(ok, f, r, rho, origin, check, reason,
                                time.perf_counter() - t0, margin, mats)

    if n > CERTIFICATE_MAX_STATES:
        return done(False, None, None, None,
                    f"not attempted for n = {n} > {CERTIFICATE_MAX_STATES} states (the coupled "
                    f"Stein system has n(n+1) = {n * (n + 1)} unknowns)")
    gains: list[tuple[str, np.ndarray]] = []
    margin = None
    if use_lmi and n <= LMI_MAX_STATES:
        K, margin = lmi_gain(A, C, f, r)
        if K is not None:
            gains.append(("coupled Lyapunov LMI (cvxpy + Clarabel), K = S_1^-1 Z", K))
    gains.extend(candidate_gains(A, C))
    best_rho, last_reason = None, "no gain gave a positive definite coupled Stein solution"
    for origin, K in gains:
        try:
            rho = coupled_radius(A, C, K, f, r)
        except (np.linalg.LinAlgError, ValueError):
            continue
        best_rho = rho if best_rho is None else min(best_rho, rho)
        if not rho < 1:
            continue
        sol = adjoint_stein(A, C, K, f, r)
        if sol is None:
            continue
        check = certify.verify_markov_jump(system, fe, re_, sol[0], sol[1], K)
        if check.ok:
            mats = ({"K": _mat(K), "X0": _mat(sol[0]), "X1": _mat(sol[1])} if n <= 60 else None)
            return done(True, rho, origin, check.to_dict(), "proven", margin, mats)
        last_reason = f"ball check failed for the gain '{origin}': {check.reason}"
    pair = _previous_arrival_certificate(system, fe, re_)
    if pair is not None and pair[0].ok:
        check, rho, gains, Y = pair
        mats = ({"K": _mat(gains[0]), "K1": _mat(gains[1]), "X0": _mat(Y[0]),
                 "X1": _mat(Y[1])} if n <= 60 else None)
        return done(True, rho, PREVIOUS_ARRIVAL_ORIGIN, check.to_dict(), "proven", margin, mats)
    if pair is not None:
        last_reason += f"; previous-arrival gains: {pair[0].reason}"
    if best_rho is not None and best_rho >= 1:
        last_reason = (f"no gain tried gives a mean-square stable fixed-gain error system "
                       f"(least spectral radius {best_rho:.6g} >= 1)")
    return done(False, best_rho, None, None, last_reason, margin)


PREVIOUS_ARRIVAL_ORIGIN = ("gains chosen by the previous arrival (coupled Riccati iteration): "
                           "K = K_0 after a loss, K1 after a reception")
"""``gain_origin`` of a certificate whose gain depends on the previous arrival (theory §10)."""


CURVE_RICCATI_ITERATIONS = 300
"""Riccati steps for the previous-arrival gains tried at each point of the sufficient curve
(the curve tests hundreds of points; the certificate at the operating point runs to the fixed
point)."""


def previous_arrival_radius(A: np.ndarray, C: np.ndarray, Q: np.ndarray, R: np.ndarray,
                            f: float, r: float, max_iterations: int | None = None
                            ) -> tuple[float, list[np.ndarray]] | None:
    """Spectral radius of the second-moment map with gains chosen by the previous arrival
    (the coupled Riccati gains of :func:`kfcrit.theory.links.burstcov.previous_arrival_gains`),
    and those gains; None when the Riccati iteration diverges.

    .. math:: \\mathcal M(X)_j = \\sum_i T_{ij}\\, G_{ij} X_i G_{ij}',\\quad
              G_{i0} = A,\\; G_{i1} = A + K_i C
    """
    from kfcrit.theory.links import burstcov, pairgain

    T = np.array([[1.0 - r, r], [f, 1.0 - f]])
    pi = np.array([f, r]) / (f + r)
    gains = burstcov.previous_arrival_gains(
        A, C, Q, R, T, pi, **({} if max_iterations is None else
                              {"max_iterations": max_iterations}))
    if gains is None:
        return None
    G = pairgain.transition_maps(A, C, gains)
    M = np.block([[T[i, j] * np.kron(G[i][j], G[i][j]) for i in range(2)] for j in range(2)])
    with np.errstate(all="ignore"):
        vals = np.linalg.eigvals(M) if np.all(np.isfinite(M)) else None
    if vals is None:
        return None
    return float(max(abs(vals))), gains


def _previous_arrival_certificate(system: System, fe: sp.Expr, re_: sp.Expr
                                  ) -> tuple[certify.CheckResult, float, list[np.ndarray],
                                             tuple[np.ndarray, np.ndarray]] | None:
    """The certificate of :mod:`kfcrit.theory.links.pairgain` with the coupled Riccati gains:
    (check, spectral radius, gains, Y), or None when no candidate exists (the Riccati
    iteration diverges, the map's radius is ≥ 1, or the adjoint solution is not definite)."""
    from kfcrit.theory.links import pairgain

    f, r = float(fe), float(re_)
    A, C = system.a, system.c
    found = previous_arrival_radius(A, C, system.q, system.r, f, r)
    if found is None or not found[0] < 1:
        return None
    rho, gains = found
    Y = pairgain.adjoint_solution(A, C, gains, f, r)
    if Y is None:
        return None
    return pairgain.verify_previous_arrival_gains(system, fe, re_, Y, gains), rho, gains, Y


# ---------------------------------------------------------------------------------------------
# facts and critical curve
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BurstFacts:
    """What is proven about E[P_t] over a Gilbert–Elliott link (f, r): the necessary burst
    condition, the coupled fixed-gain certificate, and the literature's claim (never a fact).
    The verdict is read from ``facts`` by :mod:`kfcrit.analysis.verdict`."""

    facts: StabilityFacts
    basis: str
    failure_rate: float
    recovery_rate: float
    stationary_arrival: float
    necessary: BurstNecessary
    certificate: BurstCertificate | None
    claim: dict[str, Any] | None

    def record(self, verdict: str, claim_verdict: str | None = None) -> BurstCertificateRecord:
        """The ``certificate`` of the bursty section, judged ``verdict`` (read from
        :attr:`facts` by the analysis); the literature's claim, when there is one, would give
        ``claim_verdict`` were it true."""
        c = self.claim
        claim = None if c is None else BurstClaim(
            label=c["label"], source=c["source"], statement=c["statement"],
            verdict_if_true=str(claim_verdict), stable_if_true=bool(c["stable_if_true"]))
        return BurstCertificateRecord(
            verdict=verdict, basis=self.basis, failure_rate=_number(self.failure_rate),
            recovery_rate=_number(self.recovery_rate),
            stationary_arrival=_number(self.stationary_arrival),
            necessary=self.necessary.record(),
            certificate=None if self.certificate is None else self.certificate.record(),
            claim=claim, facts=facts_record(self.facts))

    def to_dict(self) -> dict[str, Any]:
        return {"facts": self.facts.to_dict(), "basis": self.basis,
                "failure_rate": self.failure_rate,
                "recovery_rate": self.recovery_rate,
                "stationary_arrival": self.stationary_arrival,
                "necessary": self.necessary.to_dict(),
                "certificate": None if self.certificate is None else self.certificate.to_dict(),
                "claim": self.claim}


def burst_facts(system: System, failure_rate: Any, recovery_rate: Any,
                structure: Any | None = None, classification: str | None = None,
                use_lmi: bool = True) -> BurstFacts:
    r"""What is proven about E[P_t] over the link (f, r), from proofs only (theory §10).

    * the necessary condition (1 − r)ρ(A)² < 1 holds or fails (decided exactly where r and
      ρ(A) are exact);
    * the sufficient condition: the coupled fixed-gain certificate, proven in balls;
    * for "non-degenerate" systems (``classification`` from
      :mod:`kfcrit.theory.critical.section`), the literature's exact condition as a labelled
      ``claim`` (never a fact).

    .. math::

        (1 - r)\,\rho(A)^2 < 1 \quad\text{(necessary)},\qquad
        \rho\Bigl(Y_j \mapsto \sum_i T_{ij} F_i Y_i F_i'\Bigr) < 1 \quad\text{(sufficient)}.

    Parameters
    ----------
    system : System
        The system.
    failure_rate, recovery_rate : number
        f and r of the Gilbert–Elliott link (ints, fractions, sympy numbers or floats).
    structure : Structure, optional
        The eigen-structure of ``system`` (for an exact ρ(A)²).
    classification : str, optional
        The classification of :func:`kfcrit.critical_value`.
    use_lmi : bool
        Search the certificate's gain with the coupled Lyapunov LMI.

    Returns
    -------
    BurstFacts
        ``facts`` (``necessary``, ``sufficient``), ``basis``, the stationary arrival probability,
        the necessary condition and the certificate.

    Raises
    ------
    TypeError
        A rate that is not a number (a string, for instance).

    References
    ----------
    docs/theory.md §7 (scalar theorem) and §10 (necessary condition, coupled fixed-gain
    certificate); You, Fu & Xie (2011) and Mo & Sinopoli (2012) for the labelled claim.

    Examples
    --------
    >>> from fractions import Fraction
    >>> from kfcrit import System
    >>> from kfcrit.theory.links.markov import burst_facts
    >>> system = System(A=[["5/4"]], C=[[1]], Q=1, R=1)
    >>> bf = burst_facts(system, Fraction(1, 10), Fraction(1, 2))
    >>> bf.facts.necessary, bf.facts.sufficient, round(bf.stationary_arrival, 6)
    (True, True, 0.833333)
    >>> bf = burst_facts(system, Fraction(1, 20), Fraction(1, 10))   # (9/10)·(25/16) ≥ 1
    >>> bf.facts.necessary, bf.necessary.value
    (False, 1.40625)
    """
    fe, re_ = exact_rate(failure_rate, "failure_rate"), exact_rate(recovery_rate, "recovery_rate")
    f, r = float(fe), float(re_)
    stationary = float(re_ / (fe + re_)) if (fe + re_) != 0 else 0.0
    nec = burst_necessary(system, re_, structure)
    claim = None
    if classification == "non-degenerate" and nec.holds is not None:
        claim = {"label": "claim (literature, not proven here)", "source": LITERATURE,
                 "statement": "for non-degenerate systems with one sensor, (1 - r) rho(A)^2 < 1 "
                              "is necessary and sufficient for bounded E[P_t]",
                 "stable_if_true": bool(nec.holds)}
    nec_basis = "necessary burst condition: " + nec.statement
    if nec.holds is False:
        facts = StabilityFacts(False, False, False, "necessary burst condition fails: "
                               + nec.statement, "")
        return BurstFacts(facts, facts.necessary_basis, f, r, stationary, nec, None, claim)
    cert = burst_certificate(system, fe, re_, use_lmi=use_lmi)
    if cert.certified:
        basis = ("coupled fixed-gain certificate proven in ball arithmetic (gain: "
                 f"{cert.gain_origin}; spectral radius of the second-moment recursion "
                 f"{cert.spectral_radius:.6g} < 1): the Kalman filter is no worse than this "
                 "fixed gain, so E[P_t] is bounded (theory §10)")
        return BurstFacts(StabilityFacts(nec.holds, True, False, nec_basis, basis), basis,
                          f, r, stationary, nec, cert, claim)
    if nec.holds and scalar_theorem_applies(system):
        basis = ("scalar theorem (docs/theory.md §7): for n = 1 and c != 0, (1 - r) a^2 < 1 is "
                 "necessary and sufficient for bounded E[P_t]; " + nec.statement)
        return BurstFacts(StabilityFacts(True, True, True, nec_basis, basis), basis,
                          f, r, stationary, nec, cert, claim)
    basis = ("neither condition decides: " + nec.statement + "; sufficient certificate not "
             "proven (" + cert.reason + ")")
    return BurstFacts(StabilityFacts(nec.holds, False, False, nec_basis, ""), basis,
                      f, r, stationary, nec, cert, claim)


def near_one_text(excess: sp.Expr) -> str:
    r"""The number 1 + ``excess`` in words a reader can compare with 1: ``1 - 1.5625e-40``
    where a float would print ``1``.

    .. math::  x = 1 + \varepsilon,\quad |\varepsilon| < 10^{-9} \Rightarrow
               \text{"}1 \pm |\varepsilon|\text{"}
    """
    eps = sp.N(excess, 20)
    if eps != 0 and abs(eps) < sp.Float("1e-9"):
        return f"1 {'-' if eps < 0 else '+'} {float(abs(eps)):.6g}"
    return f"{float(sp.N(1 + excess, 20)):.12g}"


def scalar_theorem_applies(system: System) -> bool:
    r"""Whether the scalar theorem of docs/theory.md §7 decides mean stability: n = 1, c ≠ 0.

    .. math::  \sup_t E[P_t] < \infty \iff (1 - r)\,a^2 < 1 \qquad (n = 1,\ c \ne 0)
    """
    return system.n == 1 and any(e != 0 for e in system.C)


CURVE_MEANING = ("r <= necessary_recovery(f): mean-unstable (proven); r >= "
                 "sufficient_recovery(f): mean-stable by the coupled fixed-gain certificate "
                 "(curve found numerically); between: undetermined")
"""``meaning`` of a critical curve whose sufficient end is the coupled certificate's."""
SCALAR_CURVE_MEANING = ("r <= necessary_recovery(f): mean-unstable (proven); r > "
                        "necessary_recovery(f) = sufficient_recovery(f): mean-stable (scalar "
                        "theorem, docs/theory.md §7: for n = 1 the necessary threshold is also "
                        "sufficient); no undetermined band")
"""``meaning`` of the critical curve of a scalar plant seen by its sensor (theory §7)."""
SCALAR_CURVE_METHOD = ("scalar theorem (docs/theory.md §7): for n = 1 and c != 0, (1 - r) a^2 < 1 "
                       "is necessary and sufficient, so r_suf(f) = r_nec = max(1 - 1/a^2, 0) "
                       "for every f (exact; no search)")
"""``method`` of the critical curve of a scalar plant seen by its sensor (theory §7)."""


@dataclass(frozen=True)
class BurstCriticalCurve:
    """Both bounding curves of the critical curve in the (failure rate, recovery rate) plane:
    below ``necessary_recovery`` mean-unstable (proven), above ``sufficient_recovery``
    mean-stable (numerical bisection of the certificate's feasibility; the operating point is
    decided from :func:`burst_facts`)."""

    failure_rates: tuple[float, ...]
    necessary_recovery: tuple[float, ...]
    necessary_expression: str | None
    sufficient_recovery: tuple[float | None, ...]
    tolerance: float
    method: str
    operating_point: dict[str, float] | None
    notes: tuple[str, ...]
    seconds: float
    meaning: str = CURVE_MEANING

    def record(self) -> BurstCurveRecord:
        """The ``critical_curve`` of the bursty section (its wall-clock seconds are not part
        of it)."""
        op = self.operating_point or {}
        return BurstCurveRecord(
            failure_rates=[_number(v) for v in self.failure_rates],
            necessary_recovery=[_number(v) for v in self.necessary_recovery],
            necessary_expression=self.necessary_expression,
            sufficient_recovery=[_number(v) for v in self.sufficient_recovery],
            tolerance=_number(self.tolerance), method=self.method,
            operating_point=RatesPoint(failure_rate=_number(op.get("failure_rate")),
                                       recovery_rate=_number(op.get("recovery_rate"))),
            notes=list(self.notes), meaning=self.meaning)

    def to_dict(self) -> dict[str, Any]:
        return {"failure_rates": list(self.failure_rates),
                "necessary_recovery": list(self.necessary_recovery),
                "necessary_expression": self.necessary_expression,
                "sufficient_recovery": list(self.sufficient_recovery),
                "tolerance": self.tolerance, "method": self.method,
                "operating_point": self.operating_point, "notes": list(self.notes),
                "seconds": self.seconds, "meaning": self.meaning}


CURVE_MAX_STATES = 12
"""Largest n for the sufficient curve (one LMI per bisection step and grid point)."""


def certificate_feasible(A: np.ndarray, C: np.ndarray, f: float, r: float,
                         use_lmi: bool = True, lmi: CoupledLmi | None = None,
                         candidates: list[tuple[str, np.ndarray]] | None = None,
                         noise: tuple[np.ndarray, np.ndarray] | None = None) -> bool:
    """Numerical test: some gain (LMI or candidates) gives spectral radius < 1 of the coupled
    second-moment recursion (no ball check: used for the curve, not for verdicts).

    ``lmi`` (the compiled LMI of (A, C)) and ``candidates`` (:func:`candidate_gains`) may be
    passed in when the test is repeated for many (f, r). With ``noise`` = (Q, R) the gains
    chosen by the previous arrival (:func:`previous_arrival_radius`) are tried last, as
    :func:`burst_certificate` does."""
    gains = []
    if use_lmi:
        K, t = (lmi or CoupledLmi(A, C)).solve(f, r)
        if K is not None and t > LMI_FEASIBLE_MARGIN:
            gains.append(K)
    gains.extend(K for _, K in (candidate_gains(A, C) if candidates is None else candidates))
    for K in gains:
        try:
            if coupled_radius(A, C, K, f, r) < 1:
                return True
        except (np.linalg.LinAlgError, ValueError):
            continue
    if noise is not None:
        found = previous_arrival_radius(A, C, noise[0], noise[1], f, r,
                                        max_iterations=CURVE_RICCATI_ITERATIONS)
        return found is not None and found[0] < 1
    return False


def burst_critical_curve(system: System, failure_rates: Any = None, points: int = 9,
                   tol: float = 1e-3, operating: tuple[Any, Any] | None = None,
                   structure: Any | None = None) -> BurstCriticalCurve:
    """The two bounding curves r_nec(f) ≤ r_crit(f) ≤ r_suf(f) on a grid of failure rates.

    .. math::

        r_{nec} = \\max(1 - 1/\\rho(A)^2, 0), \\qquad
        r_{suf}(f) = \\min\\{r : \\exists K,\\ \\rho(\\mathcal{M}_{K,f,r}) < 1\\}

    r_nec does not depend on f; r_suf(f) is the smallest certified r found by a grid scan of
    (r_nec, 1] and a bisection inside the first bracket where the grid changes from not
    certified to certified, to width ``tol`` (:func:`smallest_certified`: the certificate's
    feasibility is not assumed monotone in r, although stability is, Wu–Shi–Anderson–Johansson
    TAC 2018). For a scalar plant seen by its sensor (n = 1, c ≠ 0) the scalar theorem of
    theory §7 makes the necessary threshold sufficient: r_suf(f) = r_nec, no search. Grid:
    ``points`` values f = k/points (k = 1..points) unless ``failure_rates`` is given.
    """
    t0 = time.perf_counter()
    fs = (tuple(float(v) for v in failure_rates) if failure_rates is not None else
          tuple((k + 1) / points for k in range(points)))
    r_nec, expr = necessary_recovery_threshold(system, structure)
    notes: list[str] = []
    A, C = system.a, system.c
    suff: list[float | None] = []
    scalar = scalar_theorem_applies(system)
    if scalar:
        suff = [r_nec] * len(fs)
    elif system.n > CURVE_MAX_STATES:
        notes.append(f"sufficient curve not computed for n = {system.n} > {CURVE_MAX_STATES}")
        suff = [None] * len(fs)
    else:
        lmi, candidates = CoupledLmi(A, C), candidate_gains(A, C)
        for f in fs:
            suff.append(_sufficient_threshold(A, C, f, r_nec, tol, lmi, candidates,
                                              (system.q, system.r)))
        if any(v is None for v in suff):
            notes.append("no certificate even at r = 1 for some f (None): the fixed-gain bound "
                         "does not decide there")
    op = None
    if operating is not None:
        op = {"failure_rate": float(exact_rate(operating[0], "failure_rate")),
              "recovery_rate": float(exact_rate(operating[1], "recovery_rate"))}
    method = SCALAR_CURVE_METHOD if scalar else (
        "grid scan on r, then bisection inside the first not-certified → certified bracket, "
        "of the coupled LMI / candidate-gain / previous-arrival-gain spectral radius "
        "(numerical)")
    return BurstCriticalCurve(fs, tuple(r_nec for _ in fs), expr, tuple(suff), float(tol),
                              method, op, tuple(notes), time.perf_counter() - t0,
                              SCALAR_CURVE_MEANING if scalar else CURVE_MEANING)


CURVE_GRID_POINTS = 12
"""Grid points in r ∈ (r_nec, 1] scanned before bisecting (the certificate's feasibility is not
proven monotone in r, so a plain bisection on [r_nec, 1] can miss a certified stretch)."""


def smallest_certified(feasible: Callable[[float], bool], lo: float, hi: float, tol: float,
                       points: int = CURVE_GRID_POINTS) -> float | None:
    """The smallest r in (lo, hi] found with ``feasible(r)`` True, or None.

    Scans the grid lo + k (hi − lo)/points (k = 1..points); at the first certified grid point
    it bisects only inside the bracket [previous grid point (not certified), that point],
    where the grid shows the change from not certified to certified, down to width ``tol``;
    the smallest certified r found is kept (never a point that was not checked).
    """
    step = (hi - lo) / points
    prev = lo
    for k in range(1, points + 1):
        r = hi if k == points else lo + k * step
        if feasible(r):
            a, b = prev, r
            while b - a > tol:
                mid = 0.5 * (a + b)
                if feasible(mid):
                    b = mid
                else:
                    a = mid
            return b
        prev = r
    return None


def _sufficient_threshold(A: np.ndarray, C: np.ndarray, f: float, r_nec: float,
                          tol: float, lmi: CoupledLmi,
                          candidates: list[tuple[str, np.ndarray]],
                          noise: tuple[np.ndarray, np.ndarray] | None = None) -> float | None:
    return smallest_certified(
        lambda r: certificate_feasible(A, C, f, r, lmi=lmi, candidates=candidates, noise=noise),
        r_nec, 1.0, tol)
