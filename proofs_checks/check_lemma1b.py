"""Sinopoli Lemma 1(b): K_X minimises φ(K, X), so g_p(X) = min_K φ(K, X) ⪯ φ(K, X).

Source: Sinopoli et al. 2004, Appendix A, Lemma 1(b): ∂ψ/∂K = 0 gives
2(A + KC) X C' + 2 K R = 0, i.e. K = K_X. Checked in the stronger completed-square form

    φ(K, X) − φ(K_X, X) = p (K − K_X) S (K − K_X)',   S = C X C' + R ≻ 0,

which gives both the minimum (the right side is PSD for p ≥ 0) and the stationarity.
"""
from __future__ import annotations

import numpy as np
import sympy as sp

from kfcrit.theory.covariance import riccati

from . import Check
from ._algebra import gain, general, is_zero_matrix, phi, require, symmetric

STEP = "Lemma 1(b): K_X minimises φ(K, X)"
SOURCE = "Sinopoli 2004, App. A Lemma 1(b), eq. (23)"


def symbolic(n: int = 2, m: int = 1) -> str:
    """Completed square and vanishing first variation with every entry symbolic."""
    A, C, K = general("a", n, n), general("c", m, n), general("k", n, m)
    X, Q, R = symmetric("x", n), symmetric("q", n), symmetric("r", m)
    p, t = sp.Symbol("p", real=True), sp.Symbol("t", real=True)
    KX = gain(A, C, R, X)
    S = C * X * C.T + R
    D = K - KX
    require(is_zero_matrix(phi(A, C, Q, R, K, X, p) - phi(A, C, Q, R, KX, X, p)
                           - p * D * S * D.T), "completed square fails")
    # first variation along any direction K: d/dt φ(K_X + tK, X) at t = 0 vanishes
    first = (phi(A, C, Q, R, KX + t * K, X, p)).diff(t).subs(t, 0)
    require(is_zero_matrix(first), "K_X is not a stationary point")
    return f"completed square and stationarity identically, n={n}, m={m}"


def numeric() -> str:
    """φ(K, X) − g_p(X) ⪰ 0 for many gains K (riccati module, the paper's general system)."""
    A = np.array([[1.25, 0.0], [1.0, 1.1]])
    C = np.array([[1.0, 1.0]])
    Q, R = 20 * np.eye(2), np.array([[2.5]])
    X = np.array([[3.0, 1.0], [1.0, 2.0]])
    rng = np.random.default_rng(1)
    G = riccati.g(A, C, Q, R, X, 0.7)
    low = min(float(np.linalg.eigvalsh(riccati.phi(A, C, Q, R, K, X, 0.7) - G)[0])
              for K in rng.normal(scale=3, size=(200, 2, 1)))
    require(low >= -1e-10, f"λ_min(φ(K,X) − g_p(X)) = {low:.2e}")
    return f"min over 200 gains of λ_min(φ − g_p) = {low:.1e} (tolerance −1e-10)"


CHECKS = [
    Check(STEP, SOURCE, "sympy symbolic (n=2, m=1)", symbolic),
    Check(STEP, SOURCE, "numeric (kfcrit.theory.covariance.riccati)", numeric),
]


def test_symbolic() -> None:
    symbolic()


def test_numeric() -> None:
    numeric()
