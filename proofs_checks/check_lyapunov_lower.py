"""Existence condition of the lower bound S̄ = (1 − p) A S̄ A' + Q (and of p_low = 1 − 1/α²).

Source: Sinopoli et al. 2004, Theorem 3 (eq. 19: p_low = arginf{p : ∃ Ŝ = (1−p)AŜA' + Q}
= 1 − 1/α², α = max |λ_i(A)|) and Theorem 4 (S̄). Steps checked:

1. Necessity: for a left eigenvector v of A (v'A = λv') any solution satisfies
   (1 − (1−p)|λ|²) v'S v = v'Q v, so S ⪰ 0 with v'Qv > 0 forces (1−p)|λ|² < 1 (symbolic).
2. Scalar closed form S̄ = q / (1 − (1−p) a²): positive iff (1−p)a² < 1, i.e. p > 1 − 1/a².
3. The paper's general example (α = 5/4, Q = 20 I): the exact solution is PD for p = 1/2,
   exists but is not PSD for p = 1/4, and the equation is singular at p = 9/25 = p_low (exact).
4. Numeric: the series Σ (1−p)^k A^k Q A'^k converges to scipy's Lyapunov solution above p_low.
"""
from __future__ import annotations

import numpy as np
import sympy as sp

from . import Check
from ._algebra import require

STEP = "Thm 3/4: S̄ exists iff (1−p)α² < 1"
SOURCE = "Sinopoli 2004, Thm 3 eq. (19), Thm 4"


def symbolic() -> str:
    """Steps 1 and 2."""
    lam, p, vSv, a, q = sp.symbols("lambda p vSv a q", real=True)
    # v'(S − (1−p) A S A')v with v'A = λ v' equals (1 − (1−p)λ²) v'Sv
    lhs = vSv - (1 - p) * lam * vSv * lam
    require(sp.expand(lhs - (1 - (1 - p) * lam ** 2) * vSv) == 0, "eigenvector identity")
    s = sp.solve(sp.Symbol("s") - (1 - p) * a ** 2 * sp.Symbol("s") - q, sp.Symbol("s"))[0]
    require(sp.simplify(s - q / (1 - (1 - p) * a ** 2)) == 0, f"scalar solution {s}")
    threshold = sp.solve(sp.Eq(1 - (1 - p) * a ** 2, 0), p)[0]
    require(sp.simplify(threshold - (1 - 1 / a ** 2)) == 0, f"threshold {threshold}")
    return "(1 − (1−p)|λ|²) v'Sv = v'Qv; scalar S̄ = q/(1 − (1−p)a²), threshold p = 1 − 1/a²"


def lyapunov_exact(A: sp.Matrix, Q: sp.Matrix, p: sp.Rational) -> sp.Matrix | None:
    """Solve S = (1−p) A S A' + Q exactly via vec; None when the linear system is singular."""
    n = A.shape[0]
    M = sp.eye(n * n) - (1 - p) * sp.kronecker_product(A, A)
    if M.det() == 0:
        return None
    vecQ = sp.Matrix(n * n, 1, list(Q.T))  # column-major vec
    vecS = M.LUsolve(vecQ)
    return sp.Matrix(n, n, list(vecS)).T


def exact() -> str:
    """Step 3 on the paper's general example."""
    A = sp.Matrix([[sp.Rational(5, 4), 0], [1, sp.Rational(11, 10)]])
    Q = 20 * sp.eye(2)
    above = lyapunov_exact(A, Q, sp.Rational(1, 2))
    below = lyapunov_exact(A, Q, sp.Rational(1, 4))
    at = lyapunov_exact(A, Q, sp.Rational(9, 25))
    require(above is not None and above.is_positive_definite, "no PD solution at p = 1/2")
    require(below is not None and not below.is_positive_semidefinite, "PSD solution at p = 1/4")
    require(at is None, "equation not singular at p = p_low")
    return "p = 1/2: PD solution; p = 1/4: solution not PSD; p = 9/25: singular equation"


def numeric() -> str:
    """Step 4: truncated series vs scipy.linalg.solve_discrete_lyapunov, p = 0.5."""
    from scipy.linalg import solve_discrete_lyapunov

    A = np.array([[1.25, 0.0], [1.0, 1.1]])
    Q = 20 * np.eye(2)
    p = 0.5
    B = np.sqrt(1 - p) * A
    S = solve_discrete_lyapunov(B, Q)
    series, term = np.zeros((2, 2)), Q.copy()
    for _ in range(400):
        series += term
        term = B @ term @ B.T
    rel = float(np.max(np.abs(series - S)) / np.max(np.abs(S)))
    require(rel < 1e-9, f"series vs Lyapunov {rel:.2e}")
    # below p_low the partial sums grow without bound
    B2 = np.sqrt(1 - 0.3) * A
    grow, t2 = np.zeros((2, 2)), Q.copy()
    for _ in range(200):
        grow += t2
        t2 = B2 @ t2 @ B2.T
    require(np.trace(grow) > 1e6 * np.trace(S), "series does not diverge below p_low")
    return f"series = Lyapunov solution to {rel:.1e} at p = 0.5; diverges at p = 0.3"


CHECKS = [
    Check(STEP, SOURCE, "sympy symbolic", symbolic),
    Check(STEP, SOURCE, "sympy exact (general example)", exact),
    Check(STEP, SOURCE, "numeric (scipy Lyapunov, series)", numeric),
]


def test_symbolic() -> None:
    symbolic()


def test_exact() -> None:
    exact()


def test_numeric() -> None:
    numeric()
