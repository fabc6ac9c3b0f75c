"""Misprint: Sinopoli Theorem 1 prints V = Q + K K K'; Lemma 1 (eq. 23) has V = Q + K R K'.

Source: Sinopoli et al. 2004 (conference version), Theorem 1 and the proof of Theorem 5 print
``V = Q + KKK'``; Appendix A, eq. (23) defines V = Q + K R K'. docs/theory.md §2 flags it.
The printed form is (i) ill-formed unless m = n (K is n×m, so K K needs m = n), and (ii) where it
is defined it breaks Lemma 1(a) g_p(X) = φ(K_X, X), on which Theorems 1 and 5 rest. The
corrected form satisfies Lemma 1(a) (see check_lemma1a).
"""
from __future__ import annotations

import numpy as np
import sympy as sp

from kfcrit.theory.covariance import riccati

from . import Check
from ._algebra import gain, mare, require

STEP = "Misprint Thm 1: V = Q + KKK' → Q + KRK'"
SOURCE = "Sinopoli 2004, Thm 1 vs App. A eq. (23)"


def phi_printed(A, C, Q, R, K, X, p):
    """φ with the printed V = Q + K K K'."""
    F = A + K * C
    return (1 - p) * (A * X * A.T + Q) + p * (F * X * F.T + Q + K * K * K.T)


def phi_corrected(A, C, Q, R, K, X, p):
    """φ with V = Q + K R K' (eq. 23)."""
    F = A + K * C
    return (1 - p) * (A * X * A.T + Q) + p * (F * X * F.T + Q + K * R * K.T)


def symbolic() -> str:
    """Scalar case (the only one where K K K' is defined for every system with m = n = 1):
    φ_printed(K_X) − g_p = p K_X² (K_X − R), not identically zero; φ_corrected(K_X) − g_p ≡ 0."""
    a, c, x, q, r, p = sp.symbols("a c x q r p", real=True)
    A, C, X, Q, R = (sp.Matrix([[s]]) for s in (a, c, x, q, r))
    KX = gain(A, C, R, X)
    g = mare(A, C, Q, R, X, p)
    printed = sp.simplify((phi_printed(A, C, Q, R, KX, X, p) - g)[0])
    corrected = sp.simplify((phi_corrected(A, C, Q, R, KX, X, p) - g)[0])
    require(corrected == 0, f"corrected form leaves {corrected}")
    require(sp.simplify(printed - p * KX[0] ** 2 * (KX[0] - r)) == 0, f"printed gap {printed}")
    require(printed != 0, "printed form unexpectedly identical")
    return "printed: φ(K_X) − g_p = p K_X²(K_X − R) ≢ 0; corrected: ≡ 0"


def exact() -> str:
    """The paper's scalar example (A = −1.25, C = 1, Q = 1, R = 2.5), X = 1, p = 1/2, and the
    general example (n = 2, m = 1) where K K K' is not even defined."""
    A, C = sp.Matrix([[sp.Rational(-5, 4)]]), sp.Matrix([[1]])
    Q, R, X, p = sp.Matrix([[1]]), sp.Matrix([[sp.Rational(5, 2)]]), sp.Matrix([[1]]), \
        sp.Rational(1, 2)
    KX = gain(A, C, R, X)
    g = mare(A, C, Q, R, X, p)
    gap = (phi_printed(A, C, Q, R, KX, X, p) - g)[0]
    require(gap != 0, "printed form agrees on the scalar example")
    require(phi_corrected(A, C, Q, R, KX, X, p) - g == sp.zeros(1, 1), "corrected fails")
    A2 = sp.Matrix([[sp.Rational(5, 4), 0], [1, sp.Rational(11, 10)]])
    C2 = sp.Matrix([[1, 1]])
    K2 = gain(A2, C2, sp.Matrix([[sp.Rational(5, 2)]]), sp.eye(2))
    try:
        K2 * K2 * K2.T
    except sp.ShapeError:
        ill_formed = True
    else:
        ill_formed = False
    require(ill_formed, "K K K' unexpectedly defined for n=2, m=1")
    return f"scalar example: printed gap = {gap} ≠ 0; n=2, m=1: K K K' is ill-formed (2x1·2x1)"


def numeric() -> str:
    """kfcrit.theory.covariance.riccati.phi uses the corrected V: it matches g_p at K_X where R ≠ I."""
    A, C, Q, R = (np.array([[v]]) for v in (-1.25, 1.0, 1.0, 2.5))
    X = np.array([[1.0]])
    K = riccati.optimal_gain(A, C, R, X)
    g = riccati.g(A, C, Q, R, X, 0.5)
    ours = riccati.phi(A, C, Q, R, K, X, 0.5)
    printed = 0.5 * (A @ X @ A.T + Q) + 0.5 * ((A + K @ C) @ X @ (A + K @ C).T + Q + K @ K @ K.T)
    require(abs(float(ours[0, 0] - g[0, 0])) < 1e-12, "kfcrit.theory.covariance.riccati.phi ≠ g_p at K_X")
    require(abs(float(printed[0, 0] - g[0, 0])) > 1e-3, "printed form not distinguishable")
    return (f"g_p = {g[0, 0]:.6f}, kfcrit φ(K_X) = {ours[0, 0]:.6f}, "
            f"printed φ(K_X) = {printed[0, 0]:.6f}")


CHECKS = [
    Check(STEP, SOURCE, "sympy symbolic (scalar)", symbolic),
    Check(STEP, SOURCE, "sympy exact (paper examples)", exact),
    Check(STEP, SOURCE, "numeric (kfcrit.theory.covariance.riccati)", numeric),
]


def test_symbolic() -> None:
    symbolic()


def test_exact() -> None:
    exact()


def test_numeric() -> None:
    numeric()
