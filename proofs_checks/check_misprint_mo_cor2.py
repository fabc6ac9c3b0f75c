"""Misprint: Mo–Sinopoli Corollary 2 (higher moments).

Source: Mo & Sinopoli, Corollary 2, printed as
    "sup_k E P_k^q ≤ ∞ ⇔ p_c > 1 − |λ_1|^{−2q}".
Read (docs/theory.md §4): sup_k E[P_k^q] < ∞ ⇔ p > 1 − |λ_1|^{−2q}. The printed form is wrong twice:
its left side "≤ ∞" is always true, and its right side does not involve p and is false for every
unstable non-degenerate system (p_c = 1 − |λ_1|^{−2} ≤ 1 − |λ_1|^{−2q} for q ≥ 1), so it reads
"true ⇔ false". The corrected form is checked in the scalar case (n = 1, C = 1), where the
proof is short: f_1 maps [0, ∞) into [Q, a²R + Q), so after τ losses following an arrival
f_0^τ(Q) ≤ P ≤ f_0^τ(a²R + Q), both ~ a^{2τ}; with P(τ = t) = p(1−p)^t,
sup_k E[P_k^q] < ∞ ⇔ Σ_t p(1−p)^t a^{2qt} < ∞ ⇔ (1−p) a^{2q} < 1.
"""
from __future__ import annotations

import numpy as np
import sympy as sp

from kfcrit.theory.covariance import riccati

from . import Check
from ._algebra import require

STEP = "Misprint Mo Cor. 2: q-th moment threshold"
SOURCE = "Mo–Sinopoli, Corollary 2 as printed"


def symbolic() -> str:
    """The printed right side is false for λ > 1, q ≥ 1; the scalar moment series' condition."""
    lam, q = sp.symbols("lambda q", positive=True)
    gap = (1 - lam ** -2) - (1 - lam ** (-2 * q))  # p_c − (1 − λ^{−2q})
    # gap = λ^{−2} (λ^{−2(q−1)} − 1), and λ^{−2(q−1)} ≤ 1 for λ ≥ 1, q ≥ 1: gap ≤ 0
    require(sp.simplify(gap - lam ** -2 * (lam ** (-2 * (q - 1)) - 1)) == 0, "gap factorisation")
    for lv in (sp.Rational(5, 4), 2, 3):
        for qv in (1, 2, 3, 5):
            require(gap.subs({lam: lv, q: qv}) <= 0, f"printed right side true at {lv}, {qv}")
    # f_1 range for the scalar system: f_1(X) = a²XR/(X+R) + Q ∈ [Q, a²R + Q)
    a, x, Q, R = sp.symbols("a x Q R", positive=True)
    f1 = a ** 2 * x + Q - a ** 2 * x ** 2 / (x + R)
    require(sp.simplify(f1 - (a ** 2 * x * R / (x + R) + Q)) == 0, "f_1 form")
    require(sp.simplify(sp.limit(f1, x, sp.oo) - (a ** 2 * R + Q)) == 0, "f_1 sup")
    # the moment series: geometric with ratio (1−p) a^{2q}
    p, t = sp.symbols("p t", positive=True)
    s = sp.summation(p * ((1 - p) * a ** (2 * q)) ** t, (t, 0, sp.oo))
    pieces = list(s.atoms(sp.Piecewise))
    require(len(pieces) == 1, f"unexpected summation result {s}")
    cond = pieces[0].args[0].cond  # convergence condition found by sympy
    lhs = cond.lhs.subs(sp.Abs(p - 1), 1 - p)  # 0 < p < 1
    require(cond.rhs == 1 and sp.simplify(lhs - (1 - p) * a ** (2 * q)) == 0,
            f"convergence condition {cond}")
    return "printed: right side false for all λ > 1, q ≥ 1; corrected: ratio (1−p)a^(2q) < 1"


def exact() -> str:
    """a = 2, q = 2: threshold 15/16; the series is 19/4 at p = 19/20 and diverges at p = 9/10."""
    t = sp.Symbol("t", integer=True, nonnegative=True)
    a, q = 2, 2
    above = sp.summation(sp.Rational(19, 20) * (sp.Rational(1, 20) * a ** (2 * q)) ** t,
                         (t, 0, sp.oo))
    below = sp.summation(sp.Rational(9, 10) * (sp.Rational(1, 10) * a ** (2 * q)) ** t,
                         (t, 0, sp.oo))
    require(above == sp.Rational(19, 4), f"above: {above}")
    require(below == sp.oo, f"below: {below}")
    pc = 1 - sp.Integer(a) ** -2
    require(not pc > 1 - sp.Integer(a) ** (-2 * q), "printed right side unexpectedly true")
    return "a=2, q=2: Σ = 19/4 at p = 19/20 > 15/16, Σ = ∞ at p = 9/10; printed: 3/4 > 15/16 false"


def moment_bounds(p: float, k: int, a: float = 2.0, q: int = 2) -> tuple[float, float]:
    """Lower/upper bounds on E[P_k^q] from the τ-sandwich, maps from kfcrit.theory.covariance.riccati.

    τ_k = steps since the last arrival (≤ k); P ∈ [f_0^τ(Q), f_0^τ(a²R + Q)] with Q = R = 1 and
    P_0 ≤ a²R + Q. Probabilities: p(1−p)^t for t < k and (1−p)^k for t = k.
    """
    A, Q = np.array([[a]]), np.array([[1.0]])
    lo, hi = np.array([[1.0]]), np.array([[a * a + 1.0]])
    low = high = 0.0
    for t in range(k + 1):
        prob = p * (1 - p) ** t if t < k else (1 - p) ** k
        low += prob * float(lo[0, 0]) ** q
        high += prob * float(hi[0, 0]) ** q
        lo, hi = riccati.f_loss(A, Q, lo), riccati.f_loss(A, Q, hi)
    return low, high


def numeric() -> str:
    """E[P_k²] bounds for a = 2 (threshold 15/16): bounded at p = 0.95, growing at p = 0.92."""
    A, C, Q, R = (np.array([[v]]) for v in (2.0, 1.0, 1.0, 1.0))
    vals = [float(riccati.f_arrival(A, C, Q, R, np.array([[x]]))[0, 0])
            for x in np.linspace(0, 1e4, 101)]
    require(min(vals) >= 1.0 - 1e-12 and max(vals) < 5.0, "f_1 range")
    hi = [moment_bounds(0.95, k)[1] for k in (50, 100, 200)]
    lo = [moment_bounds(0.92, k)[0] for k in (50, 100, 200)]
    require(abs(hi[2] - hi[1]) < 1e-9 * hi[2], f"upper bound not settled at p = 0.95: {hi}")
    require(lo[2] > 1e3 * lo[1] > 1e6 * lo[0], f"lower bound not growing at p = 0.92: {lo}")
    return f"p=0.95: E[P²] ≤ {hi[2]:.4g} for all k; p=0.92: E[P_k²] ≥ {lo[2]:.3g} at k = 200"


CHECKS = [
    Check(STEP, SOURCE, "sympy symbolic", symbolic),
    Check(STEP, SOURCE, "sympy exact (a = 2, q = 2)", exact),
    Check(STEP, SOURCE, "numeric (kfcrit.theory.covariance.riccati maps)", numeric),
]


def test_symbolic() -> None:
    symbolic()


def test_exact() -> None:
    exact()


def test_numeric() -> None:
    numeric()
