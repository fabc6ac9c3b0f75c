"""Mo–Sinopoli, proof of Theorem 9: |S_{q,i}| = ⌈(i−1)(q−1)/q⌉ and i/|S_{q,i}| → q/(q−1).

Source: Mo & Sinopoli, text between (59) and (60): S_{q,∞} = {l ∈ ℕ : q ∤ l},
S_{q,i} = {l ∈ S_{q,∞} : l < i}. Steps checked:

1. Symbolic in k: write i − 1 = kq + ρ, 0 ≤ ρ < q. Then |S_{q,i}| = (i−1) − ⌊(i−1)/q⌋
   = k(q−1) + ρ, and ⌈(kq + ρ)(q−1)/q⌉ = k(q−1) + ρ for every integer k (sympy, each ρ, q ≤ 16).
2. Exact enumeration for q ≤ 16, i ≤ 400.
3. The limit: (i−1)(q−1)/q ≤ |S_{q,i}| < (i−1)(q−1)/q + 1, and both i/((i−1)(q−1)/q) and
   i/((i−1)(q−1)/q + 1) tend to q/(q−1) (sympy limit with q symbolic), so i/|S_{q,i}| → q/(q−1).
"""
from __future__ import annotations

import sympy as sp

from . import Check
from ._algebra import require

STEP = "Mo Thm 9: |S_q,i| = ⌈(i−1)(q−1)/q⌉, limit q/(q−1)"
SOURCE = "Mo–Sinopoli, proof of Thm 9, before (60)"


def count(q: int, i: int) -> int:
    """|S_{q,i}| by enumeration."""
    return sum(1 for l in range(1, i) if l % q != 0)


def symbolic(max_q: int = 16) -> str:
    """Steps 1 and 3."""
    k = sp.Symbol("k", integer=True, nonnegative=True)
    for q in range(2, max_q + 1):
        for rho in range(q):
            closed = sp.ceiling((k * q + rho) * sp.Rational(q - 1, q))
            require(sp.simplify(closed - (k * (q - 1) + rho)) == 0, f"q={q}, ρ={rho}: {closed}")
            floor_form = (k * q + rho) - sp.floor((k * q + rho) / sp.Integer(q))
            require(sp.simplify(floor_form - (k * (q - 1) + rho)) == 0, f"floor form q={q}")
    i, qs = sp.symbols("i q", positive=True)
    lower = (i - 1) * (qs - 1) / qs
    for bound in (lower, lower + 1):
        lim = sp.limit(i / bound, i, sp.oo)
        require(sp.simplify(lim - qs / (qs - 1)) == 0, f"limit {lim}")
    return f"closed form for all k (q ≤ {max_q}); squeeze limits = q/(q−1) for symbolic q"


def exact(max_q: int = 16, max_i: int = 400) -> str:
    """Step 2."""
    for q in range(2, max_q + 1):
        for i in range(1, max_i + 1):
            expected = -((-(i - 1) * (q - 1)) // q)  # integer ceiling
            require(count(q, i) == expected, f"q={q}, i={i}: {count(q, i)} ≠ {expected}")
    return f"enumeration = ⌈(i−1)(q−1)/q⌉ for q ≤ {max_q}, i ≤ {max_i}"


def numeric() -> str:
    """i/|S_{q,i}| at i = 10⁶ is within 1e-5 of q/(q−1) for q = 2..10."""
    worst = max(abs(10 ** 6 / (10 ** 6 - 1 - (10 ** 6 - 1) // q) - q / (q - 1))
                for q in range(2, 11))
    require(worst < 1e-5, f"worst deviation {worst:.2e}")
    return f"max |i/|S_q,i| − q/(q−1)| at i = 10⁶: {worst:.1e}"


CHECKS = [
    Check(STEP, SOURCE, "sympy symbolic (k, q symbolic)", symbolic),
    Check(STEP, SOURCE, "exact enumeration", exact),
    Check(STEP, SOURCE, "numeric (i = 10⁶)", numeric),
]


def test_symbolic() -> None:
    symbolic()


def test_exact() -> None:
    exact()


def test_numeric() -> None:
    numeric()
