"""Marginal modes: ρ(A) ≤ 1 and (C, A) detectable ⇒ p_c = 0, diagonalizable or not.

Source: theory §11 ("Marginal modes"). The argument has three steps, each checked here:

1. ‖Aᵗ‖ grows at most polynomially when ρ(A) ≤ 1: for a Jordan block J = λI + N of size k,
   Jᵗ has entries binomial(t, j)·λ^{t−j} (j < k), polynomials of degree ≤ k − 1 in t when |λ| = 1
   (checked symbolically by induction: F(0) = I and J·F(t) = F(t + 1) for symbolic t).
2. A run of Iₒ consecutive arrivals puts P below a matrix M whatever P was before: on the
   constant-velocity tracker (Iₒ = 2) with prior P₀ = s·I, the covariance after two arrivals has a
   finite limit M as s → ∞ and M − P₂(s) ⪰ 0 for every s > 0 (exact rational functions of s).
3. The waiting time W for a run of Iₒ arrivals has a geometric tail,
   P(W > w) ≤ (1 − p^Iₒ)^⌊w/Iₒ⌋ (checked exactly against the run-length recursion), and a
   polynomial times a geometric tail is summable (ratio test, symbolic).
"""
from __future__ import annotations

from fractions import Fraction

import sympy as sp

from . import Check
from ._algebra import require

STEP = "theory §11 marginal modes: ρ(A) ≤ 1, detectable ⇒ p_c = 0"
SOURCE = "theory §11 (marginal modes); Sinopoli 2004 eq. (15)"


def jordan_powers(k: int = 4) -> str:
    """Jᵗ = [binomial(t, j − i) λ^{t−j+i}] for a k×k Jordan block, by induction in symbolic t."""
    t = sp.Symbol("t", integer=True, nonnegative=True)
    lam = sp.Symbol("lambda")
    J = sp.Matrix(k, k, lambda i, j: lam if i == j else (1 if j == i + 1 else 0))

    def F(s: sp.Expr) -> sp.Matrix:
        return sp.Matrix(k, k, lambda i, j: sp.binomial(s, j - i) * lam ** (s - (j - i))
                         if j >= i else 0)
    require(F(sp.Integer(0)) == sp.eye(k), "F(0) ≠ I")
    D = (J * F(t) - F(t + 1)).applyfunc(lambda e: sp.simplify(sp.expand_func(e)))
    require(D == sp.zeros(k, k), f"J·F(t) − F(t+1) = {D}")
    degrees = [sp.Poly(sp.expand_func(F(t)[0, j].subs(lam, 1)), t).degree() for j in range(k)]
    require(max(degrees) == k - 1, f"degrees in t at |λ| = 1: {degrees}")
    return f"Jᵗ entries binomial(t, j)·λ^(t−j), degree ≤ {k - 1} in t at |λ| = 1 (k = {k})"


def _arrival(A: sp.Matrix, C: sp.Matrix, Q: sp.Matrix, R: sp.Matrix, P: sp.Matrix) -> sp.Matrix:
    """One step with an arrival (Sinopoli eq. 15 with γ = 1)."""
    S = C * P * C.T + R
    return (A * P * A.T + Q - A * P * C.T * S.inv() * C * P * A.T).applyfunc(sp.cancel)


def run_bound() -> str:
    """Tracker A = [[1, T], [0, 1]], C = [1, 0] (one axis of the planar tracker, Iₒ = 2)."""
    s = sp.Symbol("s", positive=True)
    T = sp.Rational(1, 10)
    A, C = sp.Matrix([[1, T], [0, 1]]), sp.Matrix([[1, 0]])
    Q, R = sp.eye(2) / 10, sp.Matrix([[2]])
    P = s * sp.eye(2)
    for _ in range(2):
        P = _arrival(A, C, Q, R, P)
    M = P.applyfunc(lambda e: sp.limit(e, s, sp.oo))
    require(all(e.is_finite for e in M), f"no finite limit after Iₒ arrivals: {M}")
    D = (M - P).applyfunc(sp.cancel)
    for what, expr in (("trace", D.trace()), ("determinant", D.det())):
        num, den = sp.fraction(sp.cancel(expr))
        coeffs = sp.Poly(num, s).all_coeffs() + sp.Poly(den, s).all_coeffs()
        signs = {sp.sign(c) for c in coeffs if c != 0}
        require(len(signs) == 1, f"{what} of M − P₂(s) not of one sign for s > 0: {expr}")
    return f"P after 2 arrivals ⪯ M = {sp.sstr(M.tolist())} for every prior s·I, s > 0"


def waiting_tail(io: int = 2, p: Fraction = Fraction(1, 3), horizon: int = 60) -> str:
    """P(W > w) from the exact run-length recursion against (1 − p^Iₒ)^⌊w/Iₒ⌋; ratio test."""
    # state j = length of the current run of arrivals (j < Iₒ); absorbed at j = Iₒ
    dist = [Fraction(1)] + [Fraction(0)] * (io - 1)
    for w in range(1, horizon + 1):
        new = [Fraction(0)] * io
        for j, mass in enumerate(dist):
            new[0] += mass * (1 - p)
            if j + 1 < io:
                new[j + 1] += mass * p
        dist = new
        survive = sum(dist)
        bound = (1 - p ** io) ** (w // io)
        require(survive <= bound, f"P(W > {w}) = {survive} > {bound}")
    d, r, w = sp.Symbol("d", positive=True), sp.Symbol("r", positive=True), sp.Symbol("w")
    ratio = sp.limit((w + 1) ** d * r ** (w + 1) / (w ** d * r ** w), w, sp.oo)
    require(sp.simplify(ratio - r) == 0, f"ratio test limit {ratio}")
    return (f"P(W > w) ≤ (1 − p^{io})^⌊w/{io}⌋ for w ≤ {horizon} at p = {p} (exact); "
            "Σ w^d r^w: ratio → r < 1, summable")


CHECKS = [
    Check(STEP, SOURCE, "sympy symbolic: ‖Aᵗ‖ polynomial (Jordan block)", jordan_powers),
    Check(STEP, SOURCE, "sympy exact: run of Iₒ arrivals bounds P", run_bound),
    Check(STEP, SOURCE, "exact: geometric waiting tail, summable", waiting_tail),
]


def test_jordan_powers() -> None:
    jordan_powers()


def test_run_bound() -> None:
    run_bound()


def test_waiting_tail() -> None:
    waiting_tail()
