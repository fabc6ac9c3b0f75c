"""Sinopoli's lower bound p_low = max(1 − 1/ρ(A)², 0) enclosed between two floats, and the exact
test whether C is square and invertible (then p_up = p_c = p_low).

.. math::

    p_{low} = \\max\\bigl(1 - 1/\\rho(A)^2,\\ 0\\bigr)   \\qquad \\text{(Sinopoli Thm 3)}

The eigen-structure of :mod:`kfcrit.theory.structure.eigen` (exact |λ_1|²), when the caller has it,
is passed in as an argument; nothing is read from another module's memo, so the enclosure is
a function of its arguments only.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

import flint
import numpy as np
import sympy as sp

from kfcrit.model.system import System
from kfcrit.theory.upper import certify

ENCLOSURE_MAX_STATES = 60
"""Largest n whose p_low is enclosed rigorously (exact characteristic polynomial or balls);
above it float64 eigenvalues widened by 1e-12 relative, labelled not rigorous."""


def p_low_of(A: np.ndarray) -> float:
    """p_low = 1 − 1/ρ(A)² (0 when ρ(A) ≤ 1), Sinopoli Thm 3."""
    rho = float(max(abs(np.linalg.eigvals(A)))) if A.size else 0.0
    return max(0.0, 1.0 - 1.0 / rho**2) if rho > 1 else 0.0


@dataclass(frozen=True)
class PLow:
    """p_low = max(1 − 1/ρ(A)², 0) with directed float roundings down ≤ p_low ≤ up."""

    down: float
    up: float
    expression: str | None
    how: str
    rigorous: bool


def p_low_bounds(system: System, structure: Any | None = None) -> PLow:
    """Enclose the exact p_low of ``system`` between two floats (Sinopoli Thm 3).

    .. math::

        \\text{down} \\le p_{low} = \\max(1 - 1/|\\lambda_1|^2, 0) \\le \\text{up}

    Parameters
    ----------
    system : System
    structure : kfcrit.theory.structure.eigen.Structure, optional
        The eigen-structure of ``system`` (as from ``critical.structure_of(system,
        tolerance)``). On its exact path its |λ_1|² is used first (e.g. A = √2 gives p_low = 1/2
        exactly, where floats give 0.5000000000000001).

    Notes
    -----
    Then, in order of preference: exact eigenvalues for n ≤ 2 (sympy); the exact
    characteristic polynomial of a rational A (python-flint, rigorous root isolation,
    multiplicities handled); ball eigenvalues of the exact A (python-flint acb_mat.eig);
    float64 eigenvalues widened by 1e-12 relative (labelled not rigorous) when n > 60 or
    everything else fails. The result depends on the arguments only.
    """
    from_structure = p_low_from_structure(structure)
    if from_structure is not None:
        return from_structure
    # above ENCLOSURE_MAX_STATES only the float view of A is read: key by it (no O(n²) srepr)
    key = (sp.srepr(system.A) if system.exact and system.n <= ENCLOSURE_MAX_STATES
           else (system.a.tobytes(), system.a.shape))
    return _enclosure_memo(_AKey(key, system))


@dataclass(frozen=True)
class _AKey:
    """A system compared and hashed by the content of its A (p_low depends on A only)."""

    key: Any
    system: System = field(compare=False, hash=False)


@functools.lru_cache(maxsize=32)
def _enclosure_memo(akey: _AKey) -> PLow:
    """:func:`_p_low_enclosure` as a pure function of the exact A (bounded memo)."""
    return _p_low_enclosure(akey.system)


def p_low_from_structure(st: Any | None) -> PLow | None:
    """p_low from the exact |λ_1|² of an exact-path structure (None when it has none)."""
    eigen = getattr(st, "eigen", None)
    if getattr(st, "path", None) != "exact" or not eigen or eigen[0].mod2_expr is None:
        return None
    top = eigen[0]
    if top.unit_cmp is not None and top.unit_cmp <= 0:
        return PLow(0.0, 0.0, "0", "exact (structure analysis: ρ(A) ≤ 1)", True)
    try:
        return p_low_from_mod2(top.mod2_expr, "exact (structure analysis)")
    except (ValueError, TypeError):
        return None


def p_low_from_mod2(mod2: sp.Expr, how: str) -> PLow:
    mod2 = sp.nsimplify(mod2) if isinstance(mod2, sp.Float) else mod2
    if not sp.N(mod2 - 1, 50) > 0:
        # |λ_1|² ≤ 1 to 50 digits; equality is decided exactly below when possible
        if mod2.is_Rational or sp.N(mod2 - 1, 50) < 0 or sp.simplify(mod2 - 1) == 0:
            return PLow(0.0, 0.0, "0", how, True)
        raise ValueError("|λ_1|² too close to 1 to decide")
    expr = sp.radsimp(1 - 1 / mod2)
    down, up = certify.round_expr(expr)
    return PLow(max(down, 0.0), up, sp.sstr(expr), how, True)


def _p_low_enclosure(system: System) -> PLow:
    """p_low of ``system`` from its own matrices (see :func:`p_low_bounds`)."""
    n = system.n
    if n <= 2:
        try:
            eigs = list(sp.Matrix(system.A).eigenvals())
            mods = [sp.radsimp(sp.expand(sp.re(z) ** 2 + sp.im(z) ** 2)) for z in eigs]
            mod2 = max(mods, key=lambda v: float(sp.N(v, 30)))
            return p_low_from_mod2(mod2, "exact (eigenvalues by sympy)")
        except (ValueError, TypeError, ArithmeticError):
            pass
    bounds = None
    if n <= ENCLOSURE_MAX_STATES:
        if all(e.is_Rational for e in system.A):
            bounds = rational_rho2(system)
        if bounds is None:
            bounds = certify.spectral_radius2_bounds(system)
    if bounds is not None:
        lo2, hi2 = bounds
        down = certify.float_down(1 - 1 / lo2) if lo2 > 1 else 0.0
        up = certify.float_up(1 - 1 / hi2) if hi2 > 1 else 0.0
        if up - down <= 1e-12:
            return PLow(max(down, 0.0), up, None, "ball enclosure of ρ(A)² (python-flint)", True)
    p = p_low_of(system.a)
    pad = 1e-12 * max(p, 1e-300)
    return PLow(max(0.0, p - pad), p + pad if p > 0 else 0.0, None,
                "float64 eigenvalues, widened by 1e-12 relative (not rigorous)", False)


def rational_rho2(system: System):
    """Rigorous bounds on ρ(A)² from the exact characteristic polynomial of a rational A."""
    Fr = Fraction
    try:
        old = flint.ctx.prec
        flint.ctx.prec = 200
        try:
            rows = [[flint.fmpq(int(e.p), int(e.q)) for e in system.A.row(i)]
                    for i in range(system.n)]
            P = flint.fmpq_mat(rows).charpoly()
            num = flint.fmpz_poly([int(c * P.denom()) for c in P.coeffs()])
            lo, hi = Fr(0), Fr(0)
            for root, _mult in num.complex_roots():
                m2 = root.real * root.real + root.imag * root.imag
                a, b = certify.arb_exact(m2.lower()), certify.arb_exact(m2.upper())
                lo, hi = max(lo, max(a, Fr(0))), max(hi, b)
            return lo, hi
        finally:
            flint.ctx.prec = old
    except (ValueError, TypeError, ZeroDivisionError, AttributeError):
        return None


def c_invertible(system: System) -> tuple[bool | None, str]:
    """Is C square and invertible? (decision, how it was decided).

    Exact where the entries are exact numbers: rational C (every binary float is one) by the
    rank over Q (python-flint fmpq_mat); algebraic C by a ball determinant that excludes 0
    (proves invertible), else sympy's exact determinant (proves singular when it simplifies to
    0). Otherwise None (undecided; the general method runs).
    """
    n, m = system.n, system.m
    if m != n:
        return False, "C is not square"
    if all(e.is_Rational for e in system.C):
        rows = [[flint.fmpq(int(e.p), int(e.q)) for e in system.C.row(i)] for i in range(n)]
        rank = flint.fmpq_mat(rows).rank()
        return rank == n, f"rank C = {rank} over Q, exact rational arithmetic (python-flint)"
    try:
        old = flint.ctx.prec
        flint.ctx.prec = certify.PRECISION_BITS
        try:
            det = certify.arb_from_sympy(system.C).det()
        finally:
            flint.ctx.prec = old
        if not det.contains(0):
            return True, f"det C ≠ 0 proven by ball arithmetic (det C ∈ {det.str(5)})"
    except (ValueError, TypeError, ZeroDivisionError):
        pass
    if n <= 6 and sp.simplify(sp.Matrix(system.C).det()) == 0:
        return False, "det C = 0, exact (sympy)"
    return None, "undecided"


