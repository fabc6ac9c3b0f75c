"""Mo–Sinopoli, proof of Theorem 8: g(X, αA, p) − g(X, βA, p) = (α² − β²)[A X A' − p A X C'(C X C'
+ R)^{-1} C X A'], and the bracket is PSD for p ≤ 1, so g is non-decreasing in α > 0.

Source: Mo & Sinopoli, proof of Theorem 8 (the displayed difference before (47)); the printed
formula writes A X C (C X C^H + R)^{-1} C X A^H, i.e. C for C^H in the first factor (a harmless
misprint). Steps: the identity (symbolic, n = 2, m = 1); the bracket equals
A (X − p X C' S^{-1} C X) A' ⪰ A (X − X C' S^{-1} C X) A' ⪰ 0 (the last because
[[X, XC'], [CX, S]] ⪰ 0 — checked exactly on instances); numerically with kfcrit.theory.covariance.riccati.g.
"""
from __future__ import annotations

import numpy as np
import sympy as sp

from kfcrit.theory.covariance import riccati

from . import Check
from ._algebra import general, is_zero_matrix, mare, require, symmetric

STEP = "Mo Thm 8: g monotone in a scaling α of A"
SOURCE = "Mo–Sinopoli, proof of Thm 8, before (47)"


def symbolic(n: int = 2, m: int = 1) -> str:
    A, C = general("a", n, n), general("c", m, n)
    X, Q, R = symmetric("x", n), symmetric("q", n), symmetric("r", m)
    p, al, be = sp.symbols("p alpha beta", real=True)
    S = C * X * C.T + R
    bracket = A * X * A.T - p * A * X * C.T * S.inv() * C * X * A.T
    diff = mare(al * A, C, Q, R, X, p) - mare(be * A, C, Q, R, X, p)
    require(is_zero_matrix(diff - (al ** 2 - be ** 2) * bracket), "scaling identity fails")
    return f"identity holds with all entries symbolic (n={n}, m={m})"


def exact() -> str:
    """Bracket ⪰ 0 on exact instances, p ∈ {0, 1/2, 1}."""
    A = sp.Matrix([[2, 0, 1], [0, -2, 1], [1, 1, sp.Rational(1, 2)]])
    C = sp.Matrix([[1, 1, 0]])
    R = sp.Matrix([[sp.Rational(1, 10)]])
    cases = 0
    for X in (sp.eye(3), sp.Matrix([[5, 2, 0], [2, 1, 0], [0, 0, 0]]),
              sp.Matrix([[9, -3, 1], [-3, 2, 0], [1, 0, 1]])):
        S = C * X * C.T + R
        require(sp.BlockMatrix([[X, X * C.T], [C * X, S]]).as_explicit()
                .is_positive_semidefinite, "[[X, XC'], [CX, S]] not PSD")
        for p in (0, sp.Rational(1, 2), 1):
            bracket = A * X * A.T - p * A * X * C.T * S.inv() * C * X * A.T
            require(bracket.is_positive_semidefinite, f"bracket not PSD at p = {p}")
            cases += 1
    return f"bracket PSD in {cases} exact cases (including singular X)"


def numeric() -> str:
    """kfcrit.theory.covariance.riccati.g(αA) − g(βA) matches (α² − β²)·bracket and is PSD for α > β > 0."""
    rng = np.random.default_rng(8)
    worst = 0.0
    for _ in range(50):
        A, C = rng.normal(size=(3, 3)), rng.normal(size=(2, 3))
        L = rng.normal(size=(3, 3))
        X, Q, R = L @ L.T, np.eye(3), np.eye(2)
        p = rng.random()
        al, be = sorted(rng.random(2) * 2)[::-1]
        d = riccati.g(al * A, C, Q, R, X, p) - riccati.g(be * A, C, Q, R, X, p)
        S = C @ X @ C.T + R
        br = A @ X @ A.T - p * A @ X @ C.T @ np.linalg.solve(S, C @ X @ A.T)
        worst = max(worst, float(np.max(np.abs(d - (al ** 2 - be ** 2) * br)))
                    / max(1.0, float(np.linalg.norm(d))))
        require(np.linalg.eigvalsh(d)[0] >= -1e-9 * np.linalg.norm(d), "difference not PSD")
    require(worst < 1e-10, f"identity error {worst:.2e}")
    return f"50 random cases: PSD, identity to {worst:.1e} (relative)"


CHECKS = [
    Check(STEP, SOURCE, "sympy symbolic (n=2, m=1)", symbolic),
    Check(STEP, SOURCE, "sympy exact (n=3)", exact),
    Check(STEP, SOURCE, "numeric (kfcrit.theory.covariance.riccati)", numeric),
]


def test_symbolic() -> None:
    symbolic()


def test_exact() -> None:
    exact()


def test_numeric() -> None:
    numeric()
