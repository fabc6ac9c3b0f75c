"""Mo–Sinopoli (58)–(61): the root test, the critical value 1 − λ^{−2q/(q−1)}, and the D_M form.

Source: Mo & Sinopoli, proof of Theorem 9, eqs. (58)–(61), and Theorem 5 / docs/theory.md §4:
p_c = max(1 − |λ_1|^{−2/(1 − D_M(φ/2π))}, 0), D_M(r/q) = 1/q, D_M(irrational) = 0. Steps:

1. Grouping (exact, symbolic p and λ): for i = kq + ρ (ρ = 1..q−1), |S_{q,i}| = k(q−1) + ρ − 1,
   so the second series of (58), T = Σ_{i ∈ S_q} p (1−p)^{|S_{q,i}|} λ^{2i}, truncated at
   i < Nq equals [Σ_ρ p(1−p)^{ρ−1} λ^{2ρ}] · Σ_{k<N} ((1−p)^{q−1} λ^{2q})^k. It converges iff
   (1−p)^{q−1} λ^{2q} < 1 ⇔ (1−p) λ^{2q/(q−1)} < 1 (60) ⇔ p > 1 − λ^{−2q/(q−1)} (61).
2. The first series Σ p(1−p)^{i−1} λ^{2i} needs p > 1 − λ^{−2}, a weaker condition since
   2q/(q−1) > 2; so p_c = 1 − λ^{−2q/(q−1)} (61). (Printed (58) has (1−p)^i for (1−p)^{i−1},
   which changes only a constant factor.)
3. D_M form: 1 − λ^{−2/(1 − 1/q)} = 1 − λ^{−2q/(q−1)} (symbolic), and 1 − λ^{−2} for D_M = 0.
4. Exact values: λ = 2: q = 2 → 15/16, q = 3 → 7/8, q = 4 → 1 − 2^{−8/3}; q → ∞ → 3/4.
5. Numeric: partial sums of T at p_c ± 0.01 (λ = 2, q = 3) converge / diverge.
"""
from __future__ import annotations

import math

import sympy as sp

from . import Check
from ._algebra import require

STEP = "Mo (58)–(61): root test ⇒ p_c = 1 − λ^(−2q/(q−1)) = D_M form"
SOURCE = "Mo–Sinopoli, Thm 9 proof (58)–(61); Thm 5"


def sq_count(q: int, i: int) -> int:
    """|S_{q,i}| = (i−1) − ⌊(i−1)/q⌋ (see check_mo_sqi_count)."""
    return (i - 1) - (i - 1) // q


def truncated_series(p, lam, q: int, N: int):
    """Σ_{i < Nq, q ∤ i} p (1−p)^{|S_{q,i}|} λ^{2i}."""
    return sum(p * (1 - p) ** sq_count(q, i) * lam ** (2 * i)
               for i in range(1, N * q) if i % q != 0)


def symbolic(max_q: int = 5, N: int = 4) -> str:
    """Steps 1 (grouping, threshold) and 3 (D_M form)."""
    p, lam = sp.symbols("p lambda", positive=True)
    for q in range(2, max_q + 1):
        head = sum(p * (1 - p) ** (rho - 1) * lam ** (2 * rho) for rho in range(1, q))
        ratio = (1 - p) ** (q - 1) * lam ** (2 * q)
        grouped = head * sum(ratio ** k for k in range(N))
        require(sp.expand(truncated_series(p, lam, q, N) - grouped) == 0, f"grouping q={q}")
        # boundary of convergence: ratio = 1 exactly at p = 1 − λ^{−2q/(q−1)}
        pc = 1 - lam ** sp.Rational(-2 * q, q - 1)
        require(sp.simplify(sp.powsimp(ratio.subs(p, pc), force=True) - 1) == 0,
                f"ratio ≠ 1 at p_c, q={q}")
        # (1−p)^{q−1} λ^{2q} = ((1−p) λ^{2q/(q−1)})^{q−1}: same side of 1 (positive bases)
        root_form = ((1 - p) * lam ** sp.Rational(2 * q, q - 1)) ** (q - 1)
        require(sp.simplify(sp.powsimp(root_form - ratio, force=True)) == 0, "root form")
    qs = sp.Symbol("q", positive=True)
    dm_form = 1 - lam ** (-2 / (1 - 1 / qs))
    require(sp.simplify(dm_form - (1 - lam ** (-2 * qs / (qs - 1)))) == 0, "D_M form")
    require(sp.simplify(sp.limit(dm_form, qs, sp.oo) - (1 - lam ** -2)) == 0, "q → ∞ limit")
    return (f"grouping exact (q ≤ {max_q}, N = {N}); ratio = 1 at p_c; "
            "D_M form = 1 − λ^(−2q/(q−1)); q → ∞ gives 1 − λ^(−2)")


def exact() -> str:
    """Step 2 and 4."""
    lam = sp.Integer(2)
    vals = {q: sp.nsimplify(1 - lam ** sp.Rational(-2 * q, q - 1)) for q in (2, 3, 4)}
    require(vals[2] == sp.Rational(15, 16) and vals[3] == sp.Rational(7, 8), f"{vals}")
    require(sp.simplify(vals[4] - (1 - 2 ** sp.Rational(-8, 3))) == 0, f"q=4: {vals[4]}")
    for q in range(2, 30):
        require(sp.Rational(2 * q, q - 1) > 2, "exponent not above 2")
        require(1 - lam ** sp.Rational(-2 * q, q - 1) > 1 - lam ** -2, "ordering")
    return "λ = 2: q=2 → 15/16, q=3 → 7/8, q=4 → 1 − 2^(−8/3); second series dominates (q < 30)"


def numeric() -> str:
    """Step 5: λ = 2, q = 3, p_c = 7/8: partial sums settle at p_c + 0.01, blow up at p_c − 0.01."""
    lam, q, pc = 2.0, 3, 7 / 8

    def partial(p: float, N: int) -> float:
        # each term evaluated in log space (λ^{2i} alone overflows a double)
        return math.fsum(math.exp(math.log(p) + sq_count(q, i) * math.log(1 - p)
                                  + 2 * i * math.log(lam))
                         for i in range(1, N * q) if i % q != 0)

    above = [partial(pc + 0.01, N) for N in (100, 200)]
    below = [partial(pc - 0.01, N) for N in (100, 200)]
    require(abs(above[1] - above[0]) < 1e-6 * above[1], f"no convergence above: {above}")
    require(below[1] > 1e3 * below[0], f"no divergence below: {below}")
    return (f"T(p_c+0.01): {above[0]:.4g} → {above[1]:.4g}; "
            f"T(p_c−0.01): {below[0]:.3g} → {below[1]:.3g}")


CHECKS = [
    Check(STEP, SOURCE, "sympy symbolic (q ≤ 5; q symbolic)", symbolic),
    Check(STEP, SOURCE, "sympy exact (λ = 2)", exact),
    Check(STEP, SOURCE, "numeric (partial sums)", numeric),
]


def test_symbolic() -> None:
    symbolic()


def test_exact() -> None:
    exact()


def test_numeric() -> None:
    numeric()
