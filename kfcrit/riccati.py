"""Riccati maps of intermittent Kalman filtering (Sinopoli et al. 2004).

Notation (MATH.md §1–§3): arrival probability p, prediction covariance X.

* loss map        f_0(X) = A X A' + Q
* arrival map     f_1(X) = A X A' + Q − A X C' (C X C' + R)^{-1} C X A'
* MARE map        g_p(X) = A X A' + Q − p · A X C' (C X C' + R)^{-1} C X A'
* φ(K, X)        = (1−p)(A X A' + Q) + p (F X F' + V),  F = A + K C,  V = Q + K R K'
* optimal gain    K_X = −A X C' (C X C' + R)^{-1}, so g_p(X) = φ(K_X, X) (Lemma 1(a)).

Invariant: every map returns an exactly symmetric matrix (we symmetrise what we compute).
"""
from __future__ import annotations

import numpy as np


def symmetrize(X: np.ndarray) -> np.ndarray:
    """Return (X + X')/2 (batched over leading axes)."""
    return 0.5 * (X + np.swapaxes(X, -1, -2))


def optimal_gain(A: np.ndarray, C: np.ndarray, R: np.ndarray, X: np.ndarray) -> np.ndarray:
    """K_X = −A X C' (C X C' + R)^{-1}."""
    S = C @ X @ C.T + R
    return -np.linalg.solve(S.T, (A @ X @ C.T).T).T


def f_loss(A: np.ndarray, Q: np.ndarray, X: np.ndarray) -> np.ndarray:
    """f_0(X) = A X A' + Q."""
    return symmetrize(A @ X @ A.T + Q)


def f_arrival(A: np.ndarray, C: np.ndarray, Q: np.ndarray, R: np.ndarray,
              X: np.ndarray) -> np.ndarray:
    """f_1(X) = A X A' + Q − A X C' (C X C' + R)^{-1} C X A'."""
    return g(A, C, Q, R, X, 1.0)


def g(A: np.ndarray, C: np.ndarray, Q: np.ndarray, R: np.ndarray, X: np.ndarray,
      p: float) -> np.ndarray:
    """MARE map g_p(X) = A X A' + Q − p A X C' (C X C' + R)^{-1} C X A' (Sinopoli eq. 16)."""
    AXC = A @ X @ C.T
    S = C @ X @ C.T + R
    return symmetrize(A @ X @ A.T + Q - p * AXC @ np.linalg.solve(S, AXC.T))


def phi(A: np.ndarray, C: np.ndarray, Q: np.ndarray, R: np.ndarray, K: np.ndarray,
        X: np.ndarray, p: float) -> np.ndarray:
    """φ(K, X) = (1−p)(A X A' + Q) + p (F X F' + V), F = A + K C, V = Q + K R K' (eq. 23)."""
    F = A + K @ C
    V = Q + K @ R @ K.T
    return symmetrize((1 - p) * (A @ X @ A.T + Q) + p * (F @ X @ F.T + V))
