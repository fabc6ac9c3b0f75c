"""Sinopoli Theorem 6(b), corrected: V̄ = argmax tr V s.t. [[AVA' + Q − V, √p AVC'],
[√p CVA', CVC' + R]] ⪰ 0, V ⪰ 0.

Source: Sinopoli et al. 2004, Theorem 6(b) and its proof ("Schur complement decomposition on
V ⪯ g_p(V)"); the printed SDP omits Q (docs/theory.md §3, see check_misprint_thm6b). Steps checked:

1. The Schur complement of the block matrix w.r.t. C V C' + R ≻ 0 is g_p(V) − V (symbolic), so
   the constraint is exactly V ⪯ g_p(V).
2. The feasible set is {V ⪰ 0 : V ⪯ g_p(V)} and its trace maximiser is the fixed point V̄: in
   the paper's scalar example (p = 1/2) the feasible set is exactly [0, V̄] (exact).
3. Numerically, the SDP (cvxpy + Clarabel) on the paper's general example matches the limit of
   the MARE iteration V_{t+1} = g_p(V_t) computed with kfcrit.theory.covariance.riccati.g.
"""
from __future__ import annotations

import numpy as np
import sympy as sp

from kfcrit.theory.covariance import riccati

from . import Check
from ._algebra import general, is_zero_matrix, mare, require, symmetric

STEP = "Thm 6(b): SDP constraint ⇔ V ⪯ g_p(V), max = V̄"
SOURCE = "Sinopoli 2004, Thm 6(b) (corrected, with Q)"

SCALAR = {"a": sp.Rational(-5, 4), "c": sp.Integer(1), "q": sp.Integer(1), "r": sp.Rational(5, 2)}


def sdp_block(A, C, Q, R, V, s, with_q: bool = True) -> sp.Matrix:
    """[[A V A' + Q − V, s A V C'], [s C V A', C V C' + R]] (s = √p); printed form: no Q."""
    top = A * V * A.T + (Q if with_q else sp.zeros(*Q.shape)) - V
    return sp.BlockMatrix([[top, s * A * V * C.T], [s * C * V * A.T, C * V * C.T + R]]) \
        .as_explicit()


def symbolic(n: int = 2, m: int = 1) -> str:
    """Step 1 with every entry symbolic."""
    A, C = general("a", n, n), general("c", m, n)
    V, Q, R = symmetric("v", n), symmetric("q", n), symmetric("r", m)
    s = sp.Symbol("s", positive=True)
    M = sdp_block(A, C, Q, R, V, s)
    schur = M[:n, :n] - M[:n, n:] * M[n:, n:].inv() * M[n:, :n]
    require(is_zero_matrix(schur - (mare(A, C, Q, R, V, s ** 2) - V)), "Schur ≠ g_p(V) − V")
    return f"Schur complement = g_p(V) − V identically, n={n}, m={m}"


def scalar_fixed_point(p: sp.Rational, with_q: bool = True) -> tuple[sp.Expr, sp.Expr]:
    """(h(V) numerator, largest root) for h(V) = g_p(V) − V (− Q if not with_q), scalar example."""
    a, c, q, r = SCALAR["a"], SCALAR["c"], SCALAR["q"], SCALAR["r"]
    v = sp.Symbol("v", real=True)
    h = a ** 2 * v + (q if with_q else 0) - p * a ** 2 * c ** 2 * v ** 2 / (c ** 2 * v + r) - v
    num = sp.expand(sp.numer(sp.together(h)))  # denominator c²v + r > 0 for v ≥ 0
    roots = sp.solve(num, v)
    return num, max(roots, key=lambda e: float(e))


def exact() -> str:
    """Step 2: feasible set of the corrected SDP is [0, V̄] for the scalar example at p = 1/2."""
    p = sp.Rational(1, 2)
    v = sp.Symbol("v", real=True)
    num, vbar = scalar_fixed_point(p)
    a, c, q, r = SCALAR["a"], SCALAR["c"], SCALAR["q"], SCALAR["r"]
    g = mare(*(sp.Matrix([[x]]) for x in (a, c, q, r, vbar)), p)[0]
    require(sp.simplify(g - vbar) == 0, "V̄ is not a fixed point")
    # num is a quadratic with negative leading coefficient: ≥ 0 exactly between its roots
    require(sp.Poly(num, v).LC() < 0 and all(rt < 0 or rt == vbar for rt in sp.solve(num, v)),
            "feasible set is not [0, V̄]")
    require(num.subs(v, 0) > 0, "V = 0 infeasible")
    return f"feasible set = [0, V̄], V̄ = {sp.nsimplify(vbar)} ≈ {float(vbar):.6f} (p = 1/2)"


def mare_limit(A, C, Q, R, p, steps: int = 2000) -> np.ndarray:
    """V̄ as the limit of V_{t+1} = g_p(V_t), V_0 = 0 (kfcrit.theory.covariance.riccati.g)."""
    V = np.zeros_like(Q)
    for _ in range(steps):
        V = riccati.g(A, C, Q, R, V, p)
    return V


def solve_sdp(A, C, Q, R, p, with_q: bool = True) -> np.ndarray:
    """max tr V s.t. the Theorem 6(b) block ⪰ 0, V ⪰ 0 (cvxpy + Clarabel)."""
    import cvxpy as cp

    n = A.shape[0]
    V = cp.Variable((n, n), symmetric=True)
    top = A @ V @ A.T + (Q if with_q else 0) - V
    off = np.sqrt(p) * A @ V @ C.T
    M = cp.bmat([[top, off], [off.T, C @ V @ C.T + R]])
    prob = cp.Problem(cp.Maximize(cp.trace(V)), [0.5 * (M + M.T) >> 0, V >> 0])
    prob.solve(solver="CLARABEL")
    require(prob.status == cp.OPTIMAL, f"SDP status {prob.status}")
    return V.value


def numeric() -> str:
    """Step 3 on the paper's general example (p_up ≈ 0.471) at p = 0.8."""
    A = np.array([[1.25, 0.0], [1.0, 1.1]])
    C = np.array([[1.0, 1.0]])
    Q, R = 20 * np.eye(2), np.array([[2.5]])
    V_iter = mare_limit(A, C, Q, R, 0.8)
    V_sdp = solve_sdp(A, C, Q, R, 0.8)
    rel = float(np.max(np.abs(V_sdp - V_iter)) / np.max(np.abs(V_iter)))
    require(rel < 1e-5, f"SDP vs MARE limit: relative difference {rel:.2e}")
    return f"tr V̄ = {np.trace(V_iter):.4f} (MARE), SDP differs by {rel:.1e} (relative)"


CHECKS = [
    Check(STEP, SOURCE, "sympy symbolic (n=2, m=1)", symbolic),
    Check(STEP, SOURCE, "sympy exact (scalar example)", exact),
    Check(STEP, SOURCE, "numeric (cvxpy SDP vs kfcrit MARE)", numeric),
]


def test_symbolic() -> None:
    symbolic()


def test_exact() -> None:
    exact()


def test_numeric() -> None:
    numeric()
