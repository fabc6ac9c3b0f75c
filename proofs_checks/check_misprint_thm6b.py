"""Misprint: Sinopoli Theorem 6(b) prints the SDP without Q.

Source: Sinopoli et al. 2004, Theorem 6(b): the printed constraint is
[[A V A' − V, √p A V C'], [√p C V A', C V C' + R]] ⪰ 0. Its Schur complement is
g_p(V) − Q − V, so the printed problem maximises tr V over {V : V ⪯ g_p(V) − Q}: V̄ itself is
infeasible there (g_p(V̄) − Q − V̄ = −Q ≺ 0) and the optimum is a different matrix. In the
scalar example (A = −1.25, C = 1, Q = 1, R = 2.5, p = 1/2) the printed optimum is
(a² − 1) r / (1 − (1 − p) a²) = 45/7, while V̄ is the positive root of the corrected equation.
"""
from __future__ import annotations

import numpy as np
import sympy as sp

from . import Check
from ._algebra import require
from .check_thm6b_sdp import SCALAR, mare_limit, scalar_fixed_point, solve_sdp

STEP = "Misprint Thm 6(b): SDP without Q"
SOURCE = "Sinopoli 2004, Thm 6(b) as printed"


def exact() -> str:
    """Printed optimum 45/7 ≠ V̄; V̄ infeasible for the printed constraint."""
    p = sp.Rational(1, 2)
    _, vbar = scalar_fixed_point(p, with_q=True)
    num0, vprinted = scalar_fixed_point(p, with_q=False)
    a, r = SCALAR["a"], SCALAR["r"]
    require(sp.simplify(vprinted - (a ** 2 - 1) * r / (1 - (1 - p) * a ** 2)) == 0,
            f"printed optimum {vprinted}")
    require(sp.simplify(vprinted - vbar) != 0, "printed optimum equals V̄")
    v = sp.Symbol("v", real=True)
    require(num0.subs(v, vbar) < 0, "V̄ feasible for the printed SDP")
    return (f"printed optimum = {vprinted} ≈ {float(vprinted):.4f}, corrected V̄ ≈ "
            f"{float(vbar):.4f}; V̄ violates the printed constraint")


def numeric() -> str:
    """cvxpy: the printed SDP misses the MARE limit, the corrected one hits it (scalar case)."""
    A, C, Q, R = (np.array([[x]]) for x in (-1.25, 1.0, 1.0, 2.5))
    V_iter = mare_limit(A, C, Q, R, 0.5)[0, 0]
    V_printed = solve_sdp(A, C, Q, R, 0.5, with_q=False)[0, 0]
    V_fixed = solve_sdp(A, C, Q, R, 0.5, with_q=True)[0, 0]
    require(abs(V_fixed - V_iter) < 1e-5 * V_iter, f"corrected SDP {V_fixed} vs {V_iter}")
    require(abs(V_printed - V_iter) > 1e-2 * V_iter, "printed SDP not distinguishable")
    require(abs(V_printed - 45 / 7) < 1e-5 * 45 / 7, f"printed SDP {V_printed} vs 45/7")
    return f"MARE limit {V_iter:.5f}; corrected SDP {V_fixed:.5f}; printed SDP {V_printed:.5f}"


CHECKS = [
    Check(STEP, SOURCE, "sympy exact (scalar example)", exact),
    Check(STEP, SOURCE, "numeric (cvxpy, both SDPs)", numeric),
]


def test_exact() -> None:
    exact()


def test_numeric() -> None:
    numeric()
