"""Matrix-free numerics for large unstable blocks (k > ``NEWTON_MAX_REDUCED``): Newton steps
whose linear systems are solved by GMRES, each operator application costing O(k³).

The dense Newton of :mod:`kfcrit.theory.upper.cone` stores the Jacobian on vech coordinates,
(k(k+1)/2)² entries (k = 151: 1.3·10⁸, an O(k⁶) factorisation). Here the same Jacobians are
applied as operators (docs/theory.md §3, "Large unstable blocks"):

.. math::

    J(dX, dp) = \\bigl(L_{K,p}(dX) - dX - dp\\,P,\\ \\operatorname{tr} dX\\bigr),
    \\qquad P = A X C'(C X C')^{-1} C X A',

(threshold Newton on G_p(X) = X, tr X = 1), the eigen-Newton at fixed p on G_p(X) = r X, and
the generalized Stein equation X − L_{K,p}(X) = W whose solution, when ρ(L_{K,p}) < 1, is the
upper certificate with margin W. Nothing here proves anything: the certificates are checked by
:mod:`kfcrit.theory.upper.floatcheck`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
from scipy.linalg import lapack

from kfcrit.theory.covariance.riccati import symmetrize

GMRES_RESTART = 300
"""Krylov subspace size before a restart."""
GMRES_CYCLES = 4
"""Restart cycles per linear solve."""
NEWTON_RESIDUAL = 1e-10
"""Stop when max |G_p(X) − X| (tr X = 1) is below this (the float64 floor is ~1e-11)."""
REG = 1e-15
"""Homogeneous regulariser (times tr X) added to C X C' (as ``cone.NEWTON_REG``)."""


@dataclass(frozen=True)
class KrylovResult:
    """A Newton solution: X (tr X = 1), the parameter (p or the eigenvalue r), the gain K."""

    X: np.ndarray
    value: float
    K: np.ndarray
    iterations: int
    converged: bool
    face: bool
    """The threshold iteration ran into the floor p_low with X turning singular (a face root)."""
    matvecs: int


def gain_and_correction(A: np.ndarray, C: np.ndarray,
                        X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """K = −A X C' S⁻¹ and P = A X C' S⁻¹ C X A', S = C X C' + 10⁻¹⁵ tr(X) I.

    .. math::

        G_p(X) = A X A' - p P = \\min_K L_{K,p}(X)
    """
    S = C @ X @ C.T + REG * float(np.trace(X)) * np.eye(C.shape[0])
    AXC = A @ X @ C.T
    K = -np.linalg.solve(S.T, AXC.T).T
    return K, symmetrize(-K @ AXC.T)


def second_moment_operator(A: np.ndarray, F: np.ndarray, X: np.ndarray, p: float) -> np.ndarray:
    """L_{K,p}(X) = (1−p) A X A' + p F X F' for F = A + K C."""
    return (1 - p) * (A @ X @ A.T) + p * (F @ X @ F.T)


def hopeless(history: list[float], target: float, remaining: int) -> bool:
    r"""Whether restarted GMRES will not reach ``target`` within ``remaining`` cycles, judged
    from the residual norms at the starts of its cycles: stagnation (rate ≥ 0.999 over the
    last two cycles), or, from the fifth cycle on (restarted GMRES often speeds up after a
    slow start), a geometric extrapolation needing more than twice the cycles left.

    .. math::  q = (r_c / r_{c-2})^{1/2}, \quad \frac{\log(\mathrm{target}/r_c)}{\log q}
        > 2\,(\text{cycles left})
    """
    if len(history) < 3 or not history[-3] > 0:
        return False
    rate = (history[-1] / history[-3]) ** 0.5
    if rate >= 0.999:
        return True
    if len(history) < 5:
        return False
    return math.log(target / history[-1]) / math.log(rate) > 2 * remaining


def gmres_solve(apply, rhs: np.ndarray, rtol: float, restart: int = 120,
                max_cycles: int = 10, give_up: bool = False) -> tuple[np.ndarray, int, bool]:
    """Restarted GMRES for apply(x) = rhs (classical Gram–Schmidt twice, BLAS-2).

    With ``give_up`` the solve stops early when :func:`hopeless` says the budget will not be
    enough (near the threshold the Stein operators of too narrow a bracket stall: 2 400
    operator applications, 13 s at 151 states, for nothing).
    Returns (x, operator applications, converged to ‖rhs − apply(x)‖ ≤ rtol‖rhs‖).
    """
    N = rhs.size
    x = np.zeros(N)
    bnorm = float(np.linalg.norm(rhs))
    count = 0
    if bnorm == 0.0:
        return x, 0, True
    m = min(restart, N)
    history: list[float] = []
    for cycle in range(max_cycles):
        if cycle:
            r = rhs - apply(x)
            count += 1
        else:
            r = rhs.copy()
        beta = float(np.linalg.norm(r))
        if beta <= rtol * bnorm:
            return x, count, True
        history.append(beta)
        if give_up and hopeless(history, rtol * bnorm, max_cycles - cycle):
            return x, count, False
        V = np.empty((m + 1, N))
        V[0] = r / beta
        H = np.zeros((m + 1, m))
        cs, sn = np.zeros(m), np.zeros(m)
        g = np.zeros(m + 1)
        g[0] = beta
        j = 0
        for j in range(m):
            w = apply(V[j])
            count += 1
            h = V[:j + 1] @ w
            w -= V[:j + 1].T @ h
            h2 = V[:j + 1] @ w
            w -= V[:j + 1].T @ h2
            h += h2
            hn = float(np.linalg.norm(w))
            col = np.concatenate([h, [hn]])
            for i in range(j):
                a, b = col[i], col[i + 1]
                col[i], col[i + 1] = cs[i] * a + sn[i] * b, -sn[i] * a + cs[i] * b
            den = float(np.hypot(col[j], col[j + 1]))
            cs[j], sn[j] = (col[j] / den, col[j + 1] / den) if den > 0 else (1.0, 0.0)
            col[j], col[j + 1] = den, 0.0
            g[j + 1] = -sn[j] * g[j]
            g[j] = cs[j] * g[j]
            H[:j + 2, j] = col
            if hn > 0:
                V[j + 1] = w / hn
            if abs(g[j + 1]) <= rtol * bnorm or hn == 0:
                break
        y = sla.solve_triangular(H[:j + 1, :j + 1], g[:j + 1])
        x = x + V[:j + 1].T @ y
        if abs(g[j + 1]) <= rtol * bnorm:
            count += 1
            if float(np.linalg.norm(rhs - apply(x))) <= rtol * bnorm:
                return x, count, True
    return x, count, False


def _gmres(apply, rhs: np.ndarray, rtol: float, counter: list[int]) -> np.ndarray:
    """Solve apply(x) = rhs by restarted GMRES; ``counter[0]`` counts operator applications."""
    x, count, _ok = gmres_solve(apply, rhs, rtol, GMRES_RESTART, GMRES_CYCLES)
    counter[0] += count
    return x


def threshold_newton_krylov(A: np.ndarray, C: np.ndarray, X0: np.ndarray, p0: float,
                            p_floor: float, max_iterations: int = 30) -> KrylovResult:
    """Damped Newton on G_p(X) = X, tr X = 1 in (X, p), steps by GMRES.

    A step is halved until p stays ≥ ``p_floor`` (= p_low: p_up ≥ p_low, Sinopoli Thm 3) and X
    stays positive definite. Two steps in a row cut by the floor mark a face root (the
    eigenvector turns singular as p → p_low): ``face`` is set and the iteration stops.
    """
    k = A.shape[0]
    X, p = symmetrize(X0) / float(np.trace(X0)), float(p0)
    counter, floor_hits = [0], 0
    K = np.zeros((k, C.shape[0]))
    for it in range(max_iterations + 1):
        K, P = gain_and_correction(A, C, X)
        res = np.concatenate([(symmetrize(A @ X @ A.T) - p * P - X).ravel(),
                              [np.trace(X) - 1.0]])
        err = float(np.abs(res).max())
        if not np.isfinite(err):
            return KrylovResult(X, p, K, it, False, False, counter[0])
        if err < NEWTON_RESIDUAL:
            return KrylovResult(X, p, K, it, True, False, counter[0])
        if it == max_iterations:
            break
        F = A + K @ C

        def apply(v, F=F, P=P, p=p):
            dX = v[:-1].reshape(k, k)
            return np.concatenate([(second_moment_operator(A, F, dX, p) - dX - v[-1] * P).ravel(),
                                   [np.trace(dX)]])

        d = _gmres(apply, -res, 1e-11, counter)
        dX, dp = symmetrize(d[:-1].reshape(k, k)), float(d[-1])
        step, cut_by_floor = 1.0, False
        while step > 1e-6:
            Xn, pn = X + step * dX, p + step * dp
            if pn < p_floor:
                cut_by_floor = True
            elif _positive_definite(Xn):
                break
            step *= 0.5
        else:
            return KrylovResult(X, p, K, it, False, False, counter[0])
        floor_hits = floor_hits + 1 if cut_by_floor else 0
        X, p = Xn, pn
        if floor_hits >= 2:
            return KrylovResult(X, p, K, it + 1, False, True, counter[0])
    return KrylovResult(X, p, K, max_iterations, False, False, counter[0])


def eigen_newton_krylov(A: np.ndarray, C: np.ndarray, X0: np.ndarray, p: float,
                        max_iterations: int = 30) -> KrylovResult:
    """Newton on G_p(X) = r X, tr X = 1 in (X, r) at fixed p (the cone eigenpair of G_p),
    steps by GMRES, damped to keep X positive definite.

    .. math::

        J(dX, dr) = \\bigl(L_{K,p}(dX) - r\\,dX - dr\\,X,\\ \\operatorname{tr} dX\\bigr)
    """
    k = A.shape[0]
    X = symmetrize(X0) / float(np.trace(X0))
    counter = [0]
    K, P = gain_and_correction(A, C, X)
    r = float(np.trace(symmetrize(A @ X @ A.T) - p * P))
    for it in range(max_iterations + 1):
        K, P = gain_and_correction(A, C, X)
        G = symmetrize(A @ X @ A.T) - p * P
        res = np.concatenate([(G - r * X).ravel(), [np.trace(X) - 1.0]])
        err = float(np.abs(res).max())
        if not np.isfinite(err):
            break
        if err < NEWTON_RESIDUAL:
            return KrylovResult(X, r, K, it, True, False, counter[0])
        if it == max_iterations:
            break
        F = A + K @ C

        def apply(v, F=F, X=X, r=r):
            dX = v[:-1].reshape(k, k)
            return np.concatenate([(second_moment_operator(A, F, dX, p) - r * dX - v[-1] * X).ravel(),
                                   [np.trace(dX)]])

        d = _gmres(apply, -res, 1e-11, counter)
        dX, dr = symmetrize(d[:-1].reshape(k, k)), float(d[-1])
        step = 1.0
        while step > 1e-6 and not _positive_definite(X + step * dX):
            step *= 0.5
        X, r = X + step * dX, r + step * dr
    return KrylovResult(X, r, K, max_iterations, False, False, counter[0])


def stein_solve_krylov(A: np.ndarray, C: np.ndarray, K: np.ndarray, p: float, W: np.ndarray,
                       refinements: int = 2) -> tuple[np.ndarray, int]:
    """X with X − L_{K,p}(X) = W by GMRES and iterative refinement; returns (X, matvecs).

    .. math::

        X - (1-p) A X A' - p F X F' = W, \\qquad F = A + K C
    """
    k = A.shape[0]
    F = A + K @ C
    counter = [0]

    def apply(v):
        Y = v.reshape(k, k)
        return (Y - second_moment_operator(A, F, Y, p)).ravel()

    X = np.zeros((k, k))
    for _ in range(refinements + 1):
        R = W - (X - second_moment_operator(A, F, X, p))
        X = symmetrize(X + _gmres(apply, symmetrize(R).ravel(), 1e-12, counter).reshape(k, k))
    return X, counter[0]


def mare_start(A: np.ndarray, C: np.ndarray, p: float, iterations: int = 3000,
               rtol: float = 1e-8, trace_limit: float = 1e14) -> tuple[np.ndarray, bool]:
    """The MARE solution with Q = I, R = I at p by the fixed-point iteration from 0 (a start for
    Newton: normalised, it approximates the cone eigenvector as p ↓ p_up).

    .. math::

        X_{t+1} = A X_t A' + I - p A X_t C' (C X_t C' + I)^{-1} C X_t A'

    Returns (X, converged); the iteration is abandoned as divergent once tr X passes
    ``trace_limit``.
    """
    k, m = A.shape[0], C.shape[0]
    X = np.zeros((k, k))
    for _ in range(iterations):
        AXC = A @ X @ C.T
        Xn = symmetrize(A @ X @ A.T + np.eye(k)
                        - p * AXC @ np.linalg.solve(C @ X @ C.T + np.eye(m), AXC.T))
        if not np.all(np.isfinite(Xn)) or np.trace(Xn) > trace_limit:
            return X, False
        if np.abs(Xn - X).max() <= rtol * np.abs(Xn).max():
            return Xn, True
        X = Xn
    return X, False


def _positive_definite(X: np.ndarray) -> bool:
    try:
        np.linalg.cholesky(X)
    except np.linalg.LinAlgError:
        return False
    return True


def stein_solve_preconditioned(A: np.ndarray, C: np.ndarray, K: np.ndarray, p: float,
                               W: np.ndarray, rtol: float = 1e-7
                               ) -> tuple[np.ndarray | None, int]:
    """X with X − L_{K,p}(X) = W by GMRES right-preconditioned with the one-term Stein solve
    S(X) = X − (1−p) A X A' (Bartels–Stewart on the Cayley transform, its real Schur form
    computed once); None when √(1−p) ρ(A) ≥ 1 or GMRES fails. Returns (X, matvecs).

    .. math::

        (I - p\\,F \\cdot F' \\circ S^{-1})(Y) = W, \\qquad X = S^{-1}(Y)
    """
    k = A.shape[0]
    M = np.sqrt(1.0 - p) * A
    if not float(np.max(np.abs(np.linalg.eigvals(M)))) < 1.0:
        return None, 0
    eye = np.eye(k)
    Ac = np.linalg.solve(M + eye, M - eye)      # Cayley: M = (I + Ac)(I − Ac)⁻¹
    S, U = sla.schur(Ac, output="real")
    ImA = eye - Ac
    F = A + K @ C

    def s_inv(Y):
        # X − M X M' = Y  ⇔  Ac X + X Ac' = −½ (I − Ac) Y (I − Ac)'
        R = -0.5 * U.T @ (ImA @ Y @ ImA.T) @ U
        Z, scale, info = lapack.dtrsyl(S, S, R, trana="N", tranb="T", isgn=1)
        if info < 0:
            raise np.linalg.LinAlgError("trsyl failed")
        return U @ (Z / scale) @ U.T

    def apply(v):
        Y = v.reshape(k, k)
        return (Y - p * F @ s_inv(Y) @ F.T).ravel()

    y, count, ok = gmres_solve(apply, W.ravel(), rtol, 120, 20, give_up=True)
    if not ok:
        return None, count
    return symmetrize(s_inv(y.reshape(k, k))), count
