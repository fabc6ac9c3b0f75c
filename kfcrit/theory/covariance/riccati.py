"""Riccati maps of intermittent Kalman filtering (Sinopoli et al. 2004).

Notation (docs/theory.md §1–§3): arrival probability p, prediction covariance X.

* loss map        f_0(X) = A X A' + Q
* arrival map     f_1(X) = A X A' + Q − A X C' (C X C' + R)^{-1} C X A'
* MARE map        g_p(X) = A X A' + Q − p · A X C' (C X C' + R)^{-1} C X A'
* φ(K, X)        = (1−p)(A X A' + Q) + p (F X F' + V),  F = A + K C,  V = Q + K R K'
* optimal gain    K_X = −A X C' (C X C' + R)^{-1}, so g_p(X) = φ(K_X, X) (Lemma 1(a)).

Invariant: every map returns an exactly symmetric matrix (we symmetrise what we compute).
"""
from __future__ import annotations

import ctypes
import functools
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

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
    """MARE map g_p(X) = A X A' + Q − p A X C' (C X C' + R)^{-1} C X A' (Sinopoli eq. 16).

    A X is formed once (``A @ X @ M`` is ``(A @ X) @ M``: the same products, bit for bit).
    """
    AX = A @ X
    AXC = AX @ C.T
    S = C @ X @ C.T + R
    return symmetrize(AX @ A.T + Q - p * AXC @ np.linalg.solve(S, AXC.T))


def phi(A: np.ndarray, C: np.ndarray, Q: np.ndarray, R: np.ndarray, K: np.ndarray,
        X: np.ndarray, p: float) -> np.ndarray:
    """φ(K, X) = (1−p)(A X A' + Q) + p (F X F' + V), F = A + K C, V = Q + K R K' (eq. 23)."""
    F = A + K @ C
    V = Q + K @ R @ K.T
    return symmetrize((1 - p) * (A @ X @ A.T + Q) + p * (F @ X @ F.T + V))


# ---------------------------------------------------------------------------------------------
# Noise-free maps, the jump-linear second-moment operator and linear solvers (issue 9).
#
# * noise-free MARE  G_p(X) = A X A' − p A X C' (C X C')^{-1} C X A'   (g_p with Q = R = 0)
# * second moment    L_{K,p}(X) = (1−p) A X A' + p F X F',  F = A + K C
#   (the error covariance operator of the jump-linear system e' = (A + γ K C) e);
#   G_p(X) = min_K L_{K,p}(X), attained at K_X = −A X C' (C X C')^{-1}.
# Symmetric matrices are vectorised by their upper triangle (``vech``) in the basis
# E_ii, E_ij + E_ji (i < j): the coordinates of X are X[i, j], i ≤ j.
# ---------------------------------------------------------------------------------------------


def noise_free_g(A: np.ndarray, C: np.ndarray, X: np.ndarray, p: float,
                 reg: float = 0.0) -> np.ndarray:
    """G_p(X) = A X A' − p A X C' (C X C' + reg·I)^{-1} C X A' (noise-free MARE map).

    ``reg`` > 0 is a homogeneous regulariser (pass ε·tr X) for nearly singular C X C'.
    """
    AXC = A @ X @ C.T
    S = C @ X @ C.T + reg * np.eye(C.shape[0])
    return symmetrize(A @ X @ A.T - p * AXC @ np.linalg.solve(S, AXC.T))


def second_moment_map(A: np.ndarray, C: np.ndarray, K: np.ndarray, X: np.ndarray,
                      p: float) -> np.ndarray:
    """L_{K,p}(X) = (1−p) A X A' + p F X F' with F = A + K C."""
    F = A + K @ C
    return symmetrize((1 - p) * (A @ X @ A.T) + p * (F @ X @ F.T))


def vech(X: np.ndarray) -> np.ndarray:
    """Upper-triangle coordinates X[i, j], i ≤ j (row-major)."""
    iu = np.triu_indices(X.shape[-1])
    return X[..., iu[0], iu[1]]


def unvech(x: np.ndarray, n: int) -> np.ndarray:
    """Inverse of :func:`vech`: the symmetric matrix with upper triangle ``x``."""
    X = np.zeros((n, n))
    iu = np.triu_indices(n)
    X[iu] = x
    return X + np.triu(X, 1).T


def congruence_matrix(M: np.ndarray) -> np.ndarray:
    """Matrix of X ↦ M X M' on ``vech`` coordinates (size n(n+1)/2).

    The image of the basis element E_ij + E_ji is m_i m_j' + m_j m_i' (m_i the columns of M);
    of E_ii it is m_i m_i'.
    """
    n = M.shape[0]
    iu, ju = np.triu_indices(n)
    # row (r, s), column (i, j): M[r, i] M[s, j] + M[r, j] M[s, i] (halved when i = j)
    Mr, Ms = M[iu], M[ju]
    T = Mr[:, iu] * Ms[:, ju] + Mr[:, ju] * Ms[:, iu]
    T[:, iu == ju] *= 0.5
    return T


def stein_matrix(A: np.ndarray, C: np.ndarray, K: np.ndarray, p: float) -> np.ndarray:
    """Matrix of L_{K,p} on ``vech`` coordinates."""
    return (1 - p) * congruence_matrix(A) + p * congruence_matrix(A + K @ C)


def solve_generalized_stein(A: np.ndarray, C: np.ndarray, K: np.ndarray, p: float,
                            W: np.ndarray) -> np.ndarray:
    """Solve X = L_{K,p}(X) + W, i.e. X = (1−p) A X A' + p F X F' + W, directly (vech + LU).

    The solution is unique when ρ(L_{K,p}) ≠ 1; it is ⪰ W ⪰ 0 when ρ(L_{K,p}) < 1.
    Cost O(n^6) in time and O(n^4) in memory: meant for n ≲ 60.
    """
    n = A.shape[0]
    L = stein_matrix(A, C, K, p)
    x = np.linalg.solve(np.eye(L.shape[0]) - L, vech(symmetrize(W)))
    return unvech(x, n)


# ---------------------------------------------------------------------------------------------
# BLAS threads
# ---------------------------------------------------------------------------------------------


def openblas_thread_controls() -> tuple[tuple[Any, Any], ...]:
    """(get, set) of the thread count of every OpenBLAS mapped into this process (NumPy's and
    SciPy's each bring one); empty when none is found."""
    try:
        with open("/proc/self/maps") as fh:
            paths = sorted({line.split()[-1] for line in fh if "openblas" in line.lower()
                            and line.split()[-1].startswith("/")})
    except OSError:
        return ()
    return tuple(fns for fns in map(_thread_functions, paths) if fns is not None)


@functools.lru_cache(maxsize=8)
def _thread_functions(path: str) -> tuple[Any, Any] | None:
    """(get, set) of the OpenBLAS thread count in the shared object ``path`` (None: not one)."""
    try:
        lib = ctypes.CDLL(path)
    except OSError:
        return None
    for get, put in (("scipy_openblas_get_num_threads64_", "scipy_openblas_set_num_threads64_"),
                     ("scipy_openblas_get_num_threads", "scipy_openblas_set_num_threads"),
                     ("openblas_get_num_threads64_", "openblas_set_num_threads64_"),
                     ("openblas_get_num_threads", "openblas_set_num_threads")):
        if hasattr(lib, get) and hasattr(lib, put):
            return getattr(lib, get), getattr(lib, put)
    return None


@contextmanager
def single_blas_thread() -> Iterator[None]:
    """NumPy's and SciPy's OpenBLAS on one thread inside the block (restored after; a no-op
    when none is found). For products of a few hundred rows (large-system Riccati steps, Stein solves):
    OpenBLAS threads waiting for a busy core (a loaded machine) cost more CPU time than they
    save there; parallel work is shared between worker threads instead."""
    fns = openblas_thread_controls()
    before = [int(get()) for get, _ in fns]
    for _, put in fns:
        put(1)
    try:
        yield
    finally:
        for (_, put), k in zip(fns, before):
            put(k)
