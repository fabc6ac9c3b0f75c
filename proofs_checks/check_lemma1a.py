"""Sinopoli Lemma 1(a): with K_X = −A X C'(C X C' + R)^{-1}, g_p(X) = φ(K_X, X).

Source: Sinopoli et al. 2004, Appendix A, Lemma 1(a) with φ of eq. (23) (V = Q + K R K') and
g_p of eq. (16). The proof uses F_X X C' + K_X R = 0, i.e. K_X (C X C' + R) = −A X C'.
"""
from __future__ import annotations

import numpy as np
import sympy as sp

from kfcrit.theory.covariance import riccati

from . import Check
from ._algebra import gain, general, is_zero_matrix, mare, phi, require, symmetric

STEP = "Lemma 1(a): g_p(X) = φ(K_X, X)"
SOURCE = "Sinopoli 2004, App. A Lemma 1(a), eqs. (16), (23)"


def symbolic(n: int = 2, m: int = 1) -> str:
    """The identity with every entry of A, C, X, Q, R and p a symbol."""
    A, C = general("a", n, n), general("c", m, n)
    X, Q, R = symmetric("x", n), symmetric("q", n), symmetric("r", m)
    p = sp.Symbol("p", real=True)
    KX = gain(A, C, R, X)
    require(is_zero_matrix(mare(A, C, Q, R, X, p) - phi(A, C, Q, R, KX, X, p)),
            "g_p(X) − φ(K_X, X) is not identically zero")
    require(is_zero_matrix((A + KX * C) * X * C.T + KX * R), "F_X X C' + K_X R ≠ 0")
    return f"identically zero for n={n}, m={m} (all entries symbolic)"


def exact() -> str:
    """A 3-state, 2-output exact rational instance."""
    A = sp.Matrix([[sp.Rational(5, 4), 1, 0], [0, sp.Rational(9, 10), 7], [0, 0, -2]])
    C = sp.Matrix([[1, 0, 2], [0, 1, -1]])
    Q = sp.Matrix([[20, 1, 0], [1, 3, 0], [0, 0, 1]])
    R = sp.Matrix([[sp.Rational(5, 2), 1], [1, 2]])
    X = sp.Matrix([[2, 1, 0], [1, 2, 1], [0, 1, 3]])
    p = sp.Rational(3, 7)
    D = mare(A, C, Q, R, X, p) - phi(A, C, Q, R, gain(A, C, R, X), X, p)
    require(D == sp.zeros(3, 3), f"difference {D}")
    return "exactly zero on a rational 3x3, m=2 instance"


def numeric() -> str:
    """kfcrit.theory.covariance.riccati.g against riccati.phi at riccati.optimal_gain."""
    rng = np.random.default_rng(5)
    worst = 0.0
    for n, m in ((1, 1), (3, 2), (5, 2)):
        A, C = rng.normal(size=(n, n)), rng.normal(size=(m, n))
        L = rng.normal(size=(n, n))
        X, Q = L @ L.T, np.eye(n)
        R = np.eye(m) * 2.5
        K = riccati.optimal_gain(A, C, R, X)
        d = riccati.g(A, C, Q, R, X, 0.6) - riccati.phi(A, C, Q, R, K, X, 0.6)
        worst = max(worst, float(np.max(np.abs(d))) / max(1.0, float(np.linalg.norm(X))))
    require(worst < 1e-12, f"relative difference {worst:.2e}")
    return f"kfcrit.theory.covariance.riccati: max relative difference {worst:.1e}"


CHECKS = [
    Check(STEP, SOURCE, "sympy symbolic (n=2, m=1)", symbolic),
    Check(STEP, SOURCE, "sympy exact (n=3, m=2)", exact),
    Check(STEP, SOURCE, "numeric (kfcrit.theory.covariance.riccati)", numeric),
]


def test_symbolic() -> None:
    symbolic()


def test_exact() -> None:
    exact()


def test_numeric() -> None:
    numeric()
