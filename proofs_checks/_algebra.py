"""Small exact-algebra helpers shared by the check modules (not a check module itself)."""
from __future__ import annotations

import numpy as np
import sympy as sp


def general(name: str, rows: int, cols: int) -> sp.Matrix:
    """A matrix of independent real symbols name_ij."""
    return sp.Matrix(rows, cols, lambda i, j: sp.Symbol(f"{name}{i + 1}{j + 1}", real=True))


def symmetric(name: str, n: int) -> sp.Matrix:
    """A symmetric matrix of independent real symbols name_ij, i ≤ j."""
    return sp.Matrix(n, n, lambda i, j: sp.Symbol(f"{name}{min(i, j) + 1}{max(i, j) + 1}",
                                                   real=True))


def is_zero_matrix(M: sp.Matrix) -> bool:
    """Every entry is identically zero as a rational function (cancel, then expand)."""
    return all(sp.expand(sp.numer(sp.together(sp.cancel(e)))) == 0 for e in M)


def mare(A, C, Q, R, X, p) -> sp.Matrix:
    """g_p(X) = A X A' + Q − p A X C' (C X C' + R)^{-1} C X A' (Sinopoli eq. 16), exact."""
    S = C * X * C.T + R
    return A * X * A.T + Q - p * A * X * C.T * S.inv() * C * X * A.T


def phi(A, C, Q, R, K, X, p) -> sp.Matrix:
    """φ(K, X) = (1−p)(AXA' + Q) + p(FXF' + Q + KRK'), F = A + KC (Sinopoli eq. 23), exact."""
    F = A + K * C
    return (1 - p) * (A * X * A.T + Q) + p * (F * X * F.T + Q + K * R * K.T)


def gain(A, C, R, X) -> sp.Matrix:
    """K_X = −A X C' (C X C' + R)^{-1}, exact."""
    return -A * X * C.T * (C * X * C.T + R).inv()


def to_float(M: sp.Matrix) -> np.ndarray:
    """Float64 array of an exact matrix."""
    return np.array(M.evalf(30).tolist(), dtype=float)


def require(condition: bool, message: str) -> None:
    """``assert`` that survives ``python -O``."""
    if not condition:
        raise AssertionError(message)
