"""Kar–Sinopoli–Moura scalar example: A = √2, C = Q = R = 1 — fixed point, images, holes.

Source: Kar, Sinopoli & Moura, Section VII-A, eqs. (128)–(130) and Proposition 24:
f_0(X) = 2X + 1, f_1(X) = 3 − 2/(X + 1), P* = 1 + √2; the intervals
(2^n·3 + 2^n − 1, 2^{n+1}(1+√2) + 2^{n+1} − 1), of length 2^{n+1}√2, carry no mass. Steps:

1. (128)–(130) from the general maps (symbolic): f_0 = g_0, f_1 = g_1 for this system; P* is
   the positive root of f_1(X) = X.
2. Images (symbolic): f_1 is increasing with f_1(P*) = P* and sup f_1 = 3, so f_1([P*, ∞)) =
   [P*, 3); f_0([P*, ∞)) = [3 + 2√2, ∞). Hence every point of the support is in
   [P*, 3] ∪ [3 + 2√2, ∞): the first hole (3, 3 + 2√2).
3. Holes, all n (symbolic in n): f_0^n(x) = 2^n x + 2^n − 1 maps the first hole onto the n-th;
   a point of the n-th hole (n ≥ 1) is not in f_1's range (< 3), so it would be f_0 of a point
   of the (n−1)-th hole; by induction no hole meets the support. Length 2^{n+1}√2.
4. Numeric: 20 000 steps of the random Riccati iteration from P* with the maps f_0, f_1 (riccati module)
   (p = 0.7): every iterate is ≥ P*, every image of f_1 is ≤ 3, none is in the first four holes.
"""
from __future__ import annotations

import numpy as np
import sympy as sp

from kfcrit.theory.covariance import riccati

from . import Check
from ._algebra import require

STEP = "Kar scalar example: P* = 1+√2, holes"
SOURCE = "Kar–Sinopoli–Moura §VII-A (128)–(130), Prop. 24"


def hole(n: sp.Expr) -> tuple[sp.Expr, sp.Expr]:
    """The n-th hole as printed in Proposition 24."""
    return 2 ** n * 3 + 2 ** n - 1, 2 ** (n + 1) * (1 + sp.sqrt(2)) + 2 ** (n + 1) - 1


def symbolic() -> str:
    x = sp.Symbol("x", nonnegative=True)
    n = sp.Symbol("n", integer=True, nonnegative=True)
    a2 = sp.sqrt(2) ** 2

    def g(p):
        return a2 * x + 1 - p * a2 * x ** 2 / (x + 1)

    f0, f1 = g(0), g(1)
    require(sp.simplify(f0 - (2 * x + 1)) == 0, "(128)")
    require(sp.simplify(f1 - (3 - 2 / (x + 1))) == 0, "(129)")
    roots = sp.solve(sp.Eq(f1, x), x)
    require(roots == [1 + sp.sqrt(2)], f"(130): roots {roots}")
    ps = roots[0]
    require(sp.simplify(sp.diff(f1, x) - 2 / (x + 1) ** 2) == 0, "f_1 increasing")
    require(sp.limit(f1, x, sp.oo) == 3, "sup f_1 = 3")
    require(sp.simplify(f0.subs(x, ps) - (3 + 2 * sp.sqrt(2))) == 0, "f_0(P*)")
    lo0, hi0 = hole(sp.Integer(0))
    require(sp.simplify(lo0 - 3) == 0 and sp.simplify(hi0 - (3 + 2 * sp.sqrt(2))) == 0,
            "first hole ≠ (3, 3 + 2√2)")
    f0n = 2 ** n * x + 2 ** n - 1  # f_0^n, verified by induction: f_0(f0n) = f0n at n+1
    require(sp.simplify((2 * f0n + 1) - f0n.subs(n, n + 1)) == 0, "f_0^n closed form")
    lo, hi = hole(n)
    require(sp.simplify(f0n.subs(x, lo0) - lo) == 0 and sp.simplify(f0n.subs(x, hi0) - hi) == 0,
            "f_0^n(first hole) ≠ n-th hole")
    require(sp.simplify(hi - lo - 2 ** (n + 1) * sp.sqrt(2)) == 0, "hole length")
    # the (n+1)-th hole starts at 3 + 4(2^{n+1} − 1) ≥ 7 > 3 = sup f_1
    require(sp.simplify(lo.subs(n, n + 1) - 3 - 4 * (2 ** (n + 1) - 1)) == 0, "hole start")
    return "(128)–(130); f_1([P*,∞)) = [P*,3); f_0(P*) = 3+2√2; f_0^n maps hole 0 to hole n"


def numeric() -> str:
    A, C, Q, R = (np.array([[v]]) for v in (np.sqrt(2), 1.0, 1.0, 1.0))
    ps = 1 + np.sqrt(2)
    rng = np.random.default_rng(24)
    arrivals = rng.random(20000) < 0.7
    X = np.array([[ps]])
    values = np.empty(arrivals.size)
    for t, arrived in enumerate(arrivals):
        X = riccati.f_arrival(A, C, Q, R, X) if arrived else riccati.f_loss(A, Q, X)
        values[t] = X[0, 0]
    tol = 1e-9
    require(values.min() >= ps - tol, f"iterate below P*: {values.min()}")
    after_arrival = values[arrivals]
    require(after_arrival.max() <= 3 + tol, f"f_1 image above 3: {after_arrival.max()}")
    hits = 0
    for k in range(4):
        lo, hi = (float(v) for v in hole(sp.Integer(k)))
        hits += int(np.sum((values > lo + tol * hi) & (values < hi - tol * hi)))
    require(hits == 0, f"{hits} iterates inside the holes")
    in_first_band = np.mean(values <= 3 + tol)
    return (f"20000 iterates ≥ P*, none in the first 4 holes; "
            f"{100 * in_first_band:.1f}% in [P*, 3]")


CHECKS = [
    Check(STEP, SOURCE, "sympy symbolic (n symbolic)", symbolic),
    Check(STEP, SOURCE, "numeric (kfcrit.theory.covariance.riccati orbit)", numeric),
]


def test_symbolic() -> None:
    symbolic()


def test_numeric() -> None:
    numeric()
