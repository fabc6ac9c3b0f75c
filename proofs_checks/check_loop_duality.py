"""Closed loops (theory §12): the control MARE is the estimation MARE of the dual pair, and the
TCP-like cost formula J = tr(SQ) + ν̄ tr(L'(B'SB+U)L · lim E[P_{t|t}]).

Source: Schenato, Sinopoli, Franceschetti, Poolla, Sastry, Proc. IEEE 95(1) 2007 (TCP-like
LQG); theory §12 [beyond]. The duality is the transpose identity: the estimation MARE
g_p(X) = A X A' + Q − p A X C'(C X C' + R)^{-1} C X A' with (A, C, Q, R) := (A', B', W, U) is
A' X A + W − p A' X B (B' X B + U)^{-1} B' X A, the control MARE with ν̄ = p; the dual
estimation gain K_X = −A' X B (B' X B + U)^{-1} is the transpose of the control gain L. The
cost: with x = x̂_{t|t} + e, E[e e'] = P_{t|t}, e ⊥ x̂, the one-step identity

    E[x'Wx + ν u'Uu + x_{t+1}'S x_{t+1}] − E[x'Sx] = tr(SQ) + ν̄ tr(L'(B'SB+U)L P_{t|t})

holds for u = L x̂ when S solves the control MARE (the x̂ terms cancel); the stationary average
of both sides gives the formula.
"""
from __future__ import annotations

import numpy as np
import sympy as sp

from . import Check
from ._algebra import gain, general, is_zero_matrix, mare, require, symmetric

STEP = "Loop duality: control MARE(A, B, W, U, ν̄) = estimation MARE(A', B', W, U, p = ν̄)"
STEP_COST = "TCP-like cost J = tr(SQ) + ν̄ tr(L'(B'SB+U)L E[P_{t|t}])"
SOURCE = "Schenato et al. 2007 (Proc. IEEE 95(1)), theory §12"


def control_mare(A, B, W, U, S, nu) -> sp.Matrix:
    """A'SA + W − ν A'SB(B'SB + U)^{-1}B'SA, written in control form."""
    M = B.T * S * B + U
    return A.T * S * A + W - nu * A.T * S * B * M.inv() * B.T * S * A


def symbolic(n: int = 2, mu: int = 1) -> str:
    """The transpose identity and the gain duality with every entry a symbol."""
    A, B = general("a", n, n), general("b", n, mu)
    S, W, U = symmetric("s", n), symmetric("w", n), symmetric("u", mu)
    nu = sp.Symbol("nu", real=True)
    require(is_zero_matrix(control_mare(A, B, W, U, S, nu) - mare(A.T, B.T, W, U, S, nu)),
            "control MARE ≠ estimation MARE of (A', B')")
    L = -(B.T * S * B + U).inv() * B.T * S * A
    require(is_zero_matrix(gain(A.T, B.T, U, S).T - L), "K_S(A', B')' ≠ L")
    # at any S: A'SA + W − (control MARE) = ν L'(B'SB + U)L
    lhs = A.T * S * A + W - control_mare(A, B, W, U, S, nu)
    require(is_zero_matrix(lhs - nu * L.T * (B.T * S * B + U) * L),
            "ν A'SB(B'SB+U)^{-1}B'SA ≠ ν L'(B'SB+U)L")
    return f"identically zero for n={n}, m_u={mu} (all entries symbolic)"


def scalar_cost_identity() -> str:
    """The one-step cost identity for a scalar loop, with S eliminated through its MARE."""
    a, b, q, s, u, nu, xh, p = sp.symbols("a b q S U nu xhat P", real=True)
    w = s - a**2 * s + nu * a**2 * b**2 * s**2 / (b**2 * s + u)      # W from the MARE
    L = -a * b * s / (b**2 * s + u)
    # E over x = xhat + e (E e² = P), ν ~ Bernoulli(nu) independent, w_t with variance q
    stage = w * (xh**2 + p) + nu * u * L**2 * xh**2
    nxt = s * (a**2 * (xh**2 + p) + 2 * nu * a * b * L * xh**2 + nu * b**2 * L**2 * xh**2 + q)
    diff = sp.cancel(stage + nxt - s * (xh**2 + p) - (s * q + nu * L**2 * (b**2 * s + u) * p))
    require(sp.simplify(diff) == 0, f"scalar cost identity fails: {diff}")
    return "x̂ terms cancel; remainder tr(SQ) + ν̄ L²(b²S+U) P exactly"


def _tree_mean(a: float, q: float, r: float, g: float, depth: int) -> tuple[float, float]:
    """E[P_d] and E[P_{d|d}] from P_0 = 0 over all 2^depth arrival histories (scalar, c = 1)."""
    P, w = np.array([0.0]), np.array([1.0])
    for _ in range(depth):
        P = np.concatenate([a * a * P + q, a * a * P * r / (P + r) + q])
        w = np.concatenate([(1 - g) * w, g * w])
    return float(w @ P), float((1 - g) * (w @ P) + g * (w @ (P * r / (P + r))))


def scalar_example() -> str:
    """a = 5/4, b = c = 1, unit noises and weights, γ̄ = ν̄ = 4/5: J from the formula."""
    nu = sp.Rational(4, 5)
    a2 = sp.Rational(25, 16)
    S = (25 + sp.sqrt(1329)) / 22                      # 11 S² − 25 S − 16 = 0
    require(sp.simplify(11 * S**2 - 25 * S - 16) == 0, "S is not the MARE root")
    require(sp.simplify(a2 * S + 1 - nu * a2 * S**2 / (S + 1) - S) == 0, "S ≠ MARE(S)")
    coef = float(nu * a2 * S**2 / (S + 1))             # ν̄ L²(b²S + U)
    _, Ptt = _tree_mean(1.25, 1.0, 1.0, 0.8, 20)
    J = float(S) + coef * Ptt
    from kfcrit.theory.loop.tcp import tcp_loop

    J_code = tcp_loop([[sp.Rational(5, 4)]], [[1]], [[1]], 1, 1, 1, 1, 0.8, 0.8).cost.value
    require(abs(J - J_code) < 2e-4 * J, f"J = {J:.6f} (tree, depth 20) vs {J_code:.6f} (code)")
    return f"S = (25 + √1329)/22 = {float(S):.6f}; J = {J:.5f} (tree) vs {J_code:.5f} (kfcrit)"


CHECKS = [
    Check(STEP, SOURCE, "sympy symbolic (n=2, m_u=1)", symbolic),
    Check(STEP_COST, SOURCE, "sympy symbolic (scalar one-step identity)", scalar_cost_identity),
    Check(STEP_COST, SOURCE, "sympy exact + numeric (scalar example)", scalar_example),
]


def test_symbolic() -> None:
    symbolic()


def test_scalar_cost_identity() -> None:
    scalar_cost_identity()


def test_scalar_example() -> None:
    scalar_example()
