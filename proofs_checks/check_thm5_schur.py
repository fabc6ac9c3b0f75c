"""Sinopoli Theorem 5, (b) ⇔ (c): the Schur-complement chain from X ≻ φ(K, X) to the LMI Ψ ≻ 0.

Source: Sinopoli et al. 2004, Theorem 5 and its proof (Θ, Λ = diag(X^{-1}, I, I) Θ diag(...),
change of variables Y = X^{-1}, Z = X^{-1} K, homogeneity Ψ(αY, αZ) = αΨ(Y, Z)). Steps checked:

1. Schur complement of Θ = [[X, √p F, √(1−p) A], [√p F', X^{-1}, 0], [√(1−p) A', 0, X^{-1}]]
   with respect to diag(X^{-1}, X^{-1}) is X − p F X F' − (1−p) A X A' = X − φ_0(K, X), where
   φ_0 is φ with Q = R = 0 (symbolic).
2. diag(Y, I, I) Θ diag(Y, I, I) = Ψ(Y, Z) with Y = X^{-1}, Z = Y K (symbolic).
3. Hence Ψ(Y, Z) ≻ 0 ⇔ X ≻ φ_0(K, X) (exact instances on both sides of the threshold).
4. Noise: the proof's first "is equivalent to" drops Q + pKRK'. For a *fixed* X it is only an
   implication (an exact counterexample is exhibited); existence is equivalent by homogeneity:
   X ≻ φ_0(K, X) ⇒ tX ≻ φ(K, tX) for t > λ_max(Q + pKRK') / λ_min(X − φ_0(K, X)).
"""
from __future__ import annotations

import numpy as np
import sympy as sp

from kfcrit.theory.covariance import riccati

from . import Check
from ._algebra import general, is_zero_matrix, phi, require, symmetric

STEP = "Thm 5 (b)⇔(c): Schur chain to LMI Ψ"
SOURCE = "Sinopoli 2004, Thm 5 proof (Θ, Λ, Ψ)"


def phi0(A, C, K, X, p):
    """φ_0(K, X) = (1−p) A X A' + p F X F' (φ with Q = R = 0)."""
    F = A + K * C
    return (1 - p) * A * X * A.T + p * F * X * F.T


def psi(A, C, Y, Z, s, r):
    """Ψ(Y, Z) with s = √p, r = √(1−p) (Theorem 5(c))."""
    n = A.shape[0]
    O = sp.zeros(n, n)
    top = s * (Y * A + Z * C)
    return sp.BlockMatrix([[Y, top, r * Y * A], [top.T, Y, O], [r * A.T * Y, O, Y]]).as_explicit()


def symbolic(n: int = 2, m: int = 1) -> str:
    """Steps 1 and 2 with every entry symbolic (s = √p, r = √(1−p) kept as symbols, r² = 1−s²)."""
    A, C, K = general("a", n, n), general("c", m, n), general("k", n, m)
    X = symmetric("x", n)
    s, r = sp.symbols("s r", positive=True)
    Y = X.inv()
    F = A + K * C
    # step 1: Schur complement of Θ w.r.t. its lower-right block diag(X^{-1}, X^{-1})
    B = sp.Matrix.hstack(s * F, r * A)
    schur = X - B * sp.diag(X, X) * B.T  # (diag(Y, Y))^{-1} = diag(X, X)
    require(is_zero_matrix((schur - (X - phi0(A, C, K, X, s ** 2))).subs(r, sp.sqrt(1 - s ** 2))),
            "Schur complement of Θ ≠ X − φ_0(K, X)")
    # step 2: the congruence diag(Y, I, I) Θ diag(Y, I, I) equals Ψ(Y, YK)
    O = sp.zeros(n, n)
    Theta = sp.BlockMatrix([[X, s * F, r * A], [s * F.T, Y, O], [r * A.T, O, Y]]).as_explicit()
    D = sp.diag(Y, sp.eye(n), sp.eye(n))
    require(is_zero_matrix(D * Theta * D - psi(A, C, Y, Y * K, s, r)), "Λ ≠ Ψ(Y, YK)")
    return f"Schur complement and congruence identically, n={n}, m={m}"


def _instance(p: sp.Rational, s: sp.Rational, r: sp.Rational, X: sp.Matrix) -> tuple[bool, bool]:
    A = sp.Matrix([[sp.Rational(5, 4), 0], [1, sp.Rational(11, 10)]])
    C = sp.Matrix([[1, 1]])
    K = sp.Matrix([[-1], [-1]])
    Y = X.inv()
    lmi = psi(A, C, Y, Y * K, s, r).is_positive_definite
    direct = (X - phi0(A, C, K, X, p)).is_positive_definite
    return bool(lmi), bool(direct)


def exact() -> str:
    """Step 3 on exact instances (p with rational √p, √(1−p)) on both sides; step 4's
    counterexample and the scaling that repairs it."""
    outcomes = []
    X = sp.Matrix([[18, 3], [3, 11]]) / 5
    for p, s, r in ((sp.Rational(9, 25), sp.Rational(3, 5), sp.Rational(4, 5)),
                    (sp.Rational(16, 25), sp.Rational(4, 5), sp.Rational(3, 5)),
                    (sp.Rational(144, 169), sp.Rational(12, 13), sp.Rational(5, 13)),
                    (sp.Rational(1, 4), sp.Rational(1, 2), sp.sqrt(3) / 2)):
        lmi, direct = _instance(p, s, r, X)
        require(lmi == direct, f"p={p}: Ψ ≻ 0 is {lmi} but X ≻ φ_0 is {direct}")
        outcomes.append(direct)
    require(any(outcomes) and not all(outcomes), f"instances do not straddle: {outcomes}")
    # step 4: scalar a = 5/4, c = 1, K = −5/4 (F = 0), p = 1/2, Q = 1, R = 5/2
    a, c, k, p = sp.Rational(5, 4), sp.Integer(1), sp.Rational(-5, 4), sp.Rational(1, 2)
    A, C, K = sp.Matrix([[a]]), sp.Matrix([[c]]), sp.Matrix([[k]])
    Q, R = sp.Matrix([[1]]), sp.Matrix([[sp.Rational(5, 2)]])
    X1 = sp.Matrix([[1]])
    require((X1 - phi0(A, C, K, X1, p))[0] > 0, "X ≻ φ_0 fails")
    require(not (X1 - phi(A, C, Q, R, K, X1, p))[0] > 0, "no counterexample at X = 1")
    t = (Q + p * K * R * K.T)[0] / (X1 - phi0(A, C, K, X1, p))[0]
    tX = (t + 1) * X1
    require((tX - phi(A, C, Q, R, K, tX, p))[0] > 0, "scaling does not repair")
    return (f"Ψ ≻ 0 ⇔ X ≻ φ_0 on 4 instances (both outcomes); fixed-X gap: X = 1 has "
            f"X ≻ φ_0 but not X ≻ φ; tX works for t > {t}")


def numeric() -> str:
    """Float check with kfcrit.theory.covariance.riccati.phi (Q = R = 0) over a grid of p: Ψ ≻ 0 ⇔ X ≻ φ_0."""
    A = np.array([[1.25, 0.0], [1.0, 1.1]])
    C = np.array([[1.0, 1.0]])
    K = np.array([[-1.0], [-1.0]])
    X = np.array([[3.6, 0.6], [0.6, 2.2]])
    Y = np.linalg.inv(X)
    agree = 0
    changes = set()
    for p in np.linspace(0.0, 1.0, 101):
        s, r = np.sqrt(p), np.sqrt(1 - p)
        top = s * (Y @ A + Y @ K @ C)
        O = np.zeros((2, 2))
        P = np.block([[Y, top, r * Y @ A], [top.T, Y, O], [r * A.T @ Y, O, Y]])
        lmi = np.linalg.eigvalsh(P)[0] > 1e-12
        D = X - riccati.phi(A, C, np.zeros((2, 2)), np.zeros((1, 1)), K, X, p)
        direct = np.linalg.eigvalsh(D)[0] > 1e-12
        agree += lmi == direct
        changes.add(direct)
    require(agree == 101 and len(changes) == 2, f"agreement {agree}/101, outcomes {changes}")
    return "Ψ ≻ 0 ⇔ X ≻ φ_0(K, X) at 101 values of p (kfcrit.theory.covariance.riccati.phi, both outcomes)"


CHECKS = [
    Check(STEP, SOURCE, "sympy symbolic (n=2, m=1)", symbolic),
    Check(STEP, SOURCE, "sympy exact (instances, homogeneity)", exact),
    Check(STEP, SOURCE, "numeric (kfcrit.theory.covariance.riccati)", numeric),
]


def test_symbolic() -> None:
    symbolic()


def test_exact() -> None:
    exact()


def test_numeric() -> None:
    numeric()
