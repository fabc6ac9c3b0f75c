"""Block-triangular Stein solves for large certificates, and the face-root certificate
(docs/theory.md §3, "Large unstable blocks").

In a real Schur basis with the gain zero on the stable block, A and F = A + K C are both block
upper triangular with the same stable diagonal block, so

.. math::

    X - (1-p) A X A' - p F X F' = W

splits into one small equation per block pair, solved from the bottom right: a Lyapunov
equation on the stable block, one-term Stein–Sylvester equations X − M X T_ss' = R for the
coupling to it (column recursion on the quasi-triangular T_ss), and small Kronecker systems.
The solution has exactly the margin W; no norm-bound scaling inflates it (the cruder lift of
:func:`kfcrit.theory.upper.cone.lift_certificate` scales the unstable block by ~10⁷ at n = 200,
which the verified float64 check cannot afford next to a margin of order tol).

*Face root* (p_up = p_low): order the unstable block as [[T₁₁, T₁₂], [0, T₂₂]] with T₁₁ the
modes of modulus ρ(A). The gain K₁ = −T₁₁ C₁⁺, K₂ = K̃₂ Π (Π the projector off range C₁)
kills the dominant modes (F's first block column is 0), so L_{K,p} is block triangular with
diagonal parts (1−p) T₁₁ ⊗ T₁₁ (radius (1−p)ρ² < 1 for p > p_low) and the jump operator of
(T₂₂, Π C₂) with gain K̃₂. When the MARE of (T₂₂, Π C₂) (Q = I, R = I) converges at p, its
gain makes that operator stable (P − L₂₂(P) = I + p K̃₂K̃₂'), so p_up ≤ p for every p > p_low
at which it converges: a certificate at p_low + tol/2 with the lower end p_low (Thm 3).
Nothing here proves anything: the certificate is checked by
:func:`kfcrit.theory.upper.floatcheck.verify_upper_float_basis`.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from kfcrit.theory.covariance.riccati import symmetrize
from kfcrit.theory.upper import krylov
from kfcrit.theory.upper.cone import Reduced

KRONECKER_LIMIT = 1600
"""Largest block (rows × columns) solved by a dense Kronecker system."""
FACE_MARE_STEPS = 4000
"""Fixed-point steps of the MARE on the non-dominant block before giving up (not a face root,
or too close to it)."""
DOMINANT_TOL = 1e-9
"""Modes with |λ| ≥ ρ(A)(1 − this) form the dominant block of a face root."""


def _schur_blocks(N: np.ndarray) -> list[tuple[int, int]]:
    """(start, size) of the 1×1 and 2×2 diagonal blocks of a real quasi-triangular matrix."""
    out, j, s = [], 0, N.shape[0]
    while j < s:
        b = 2 if j + 1 < s and N[j + 1, j] != 0.0 else 1
        out.append((j, b))
        j += b
    return out


def stein_sylvester(M: np.ndarray, N: np.ndarray, R: np.ndarray) -> np.ndarray:
    """X with X − M X N' = R, N real upper quasi-triangular (column recursion from the right).

    .. math::

        X_J - M X_J N_{JJ}' = R_J + M \\textstyle\\sum_{l > J} X_l N_{J l}'
    """
    r = M.shape[0]
    X = np.zeros_like(R, dtype=float)
    I = np.eye(r)
    for j0, b in reversed(_schur_blocks(N)):
        J = slice(j0, j0 + b)
        rhs = R[:, J] + M @ (X[:, j0 + b:] @ N[J, j0 + b:].T)
        if b == 1:
            X[:, j0] = np.linalg.solve(I - N[j0, j0] * M, rhs[:, 0])
        else:
            S = np.eye(2 * r) - np.kron(N[J, J], M)
            X[:, J] = np.linalg.solve(S, rhs.reshape(-1, order="F")).reshape(r, 2, order="F")
    return X


def _kronecker_pair(Ti, Tj, Fi, Fj, p, R) -> np.ndarray:
    """X with X − (1−p) T_i X T_j' − p F_i X F_j' = R, by a dense Kronecker system."""
    S = np.eye(R.size) - (1 - p) * np.kron(Tj, Ti) - p * np.kron(Fj, Fi)
    return np.linalg.solve(S, R.reshape(-1, order="F")).reshape(R.shape, order="F")


def jump_second_moment(T: np.ndarray, F: np.ndarray, X: np.ndarray, p: float) -> np.ndarray:
    """L_{K,p}(X) = (1−p) T X T' + p F X F' (any basis)."""
    return (1 - p) * (T @ X @ T.T) + p * (F @ X @ F.T)


def mare_fixed_point(A: np.ndarray, C: np.ndarray, p: float, steps: int = FACE_MARE_STEPS,
                     rtol: float = 1e-12) -> np.ndarray | None:
    """The MARE solution with Q = I, R = I by the fixed-point iteration from 0, or None when it
    does not converge (trace past 10¹⁰ k, or ``steps`` run out).

    .. math::

        P_{t+1} = A P_t A' + I - p A P_t C' (C P_t C' + I)^{-1} C P_t A'
    """
    X, converged = krylov.mare_start(A, C, p, iterations=steps, rtol=rtol,
                                     trace_limit=1e10 * A.shape[0])
    return X if converged else None


def dominant_split(red: Reduced) -> tuple[Reduced, int] | None:
    """The reduction with its unstable block reordered so that the modes of modulus ρ(A_u) come
    first: (reduction in the basis [Z_u Q, Z_s], number d of dominant states), or None."""
    k = red.k
    if k == 0:
        return None
    rho = float(np.max(np.abs(np.linalg.eigvals(red.Au))))
    cut = (rho * (1.0 - DOMINANT_TOL)) ** 2
    T, Q, d = sla.schur(red.Au, output="real", sort=lambda re, im: re * re + im * im >= cut)
    d = int(d)
    if d == 0 or d == k:
        return None
    Tn = red.T.copy()
    Tn[:k, :k] = T
    Tn[:k, k:] = Q.T @ red.T[:k, k:]
    Zn = red.Z.copy()
    Zn[:, :k] = red.Z[:, :k] @ Q
    return Reduced(Tn, Zn, k, T, red.Cu @ Q, red.Cw, red.M), d


def face_gain(red: Reduced, d: int, p: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The face-root gain on the (reordered) unstable block and the MARE solution P₂ of the
    non-dominant block (module docstring), or None when C₁ has rank < d or that MARE does not
    converge at p."""
    k, Cu, T = red.k, red.Cu, red.Au
    m = Cu.shape[0]
    C1, C2 = Cu[:, :d], Cu[:, d:]
    if m < d or np.linalg.matrix_rank(C1) < d:
        return None
    C1p = np.linalg.pinv(C1)
    Pi = np.eye(m) - C1 @ C1p
    Ct = Pi @ C2
    P2 = mare_fixed_point(T[d:, d:], Ct, p)
    if P2 is None:
        return None
    APC = T[d:, d:] @ P2 @ Ct.T
    K2 = -np.linalg.solve((Ct @ P2 @ Ct.T + np.eye(m)).T, APC.T).T @ Pi
    K = np.zeros((k, m))
    K[:d] = -T[:d, :d] @ C1p
    K[d:] = K2
    return K, P2


def face_certificate_matrices(red: Reduced, d: int, p: float
                              ) -> tuple[np.ndarray, np.ndarray] | None:
    """(X_z, K_z) in the basis ``red.Z`` with X_z − L_{K,p}(X_z) = W ≻ 0 block diagonal, for the
    face-root gain (blocks: dominant, rest of the unstable block, stable block; solved from the
    bottom right, :func:`stein_sylvester` / Kronecker; the middle block is β P₂ with β such
    that its margin β(I + p K̃₂K̃₂') − (coupling) stays ⪰ I; the dominant block's margin is
    ‖c₁₁‖ I, c₁₁ its coupling term, which balances X₁₁ ~ (margin + c₁₁)/δ against the margin
    in the equilibrated check, δ = 1 − (1−p)ρ²)."""
    found = face_gain(red, d, p)
    if found is None:
        return None
    Ku, P2 = found
    n, k = red.T.shape[0], red.k
    Cz = red.Cw @ red.Z
    Kz = np.zeros((n, Ku.shape[1]))
    Kz[:k] = Ku
    T = red.T
    F = T + Kz @ Cz
    X = np.zeros((n, n))
    u, s = slice(0, k), slice(k, n)
    if k < n:
        X[s, s] = symmetrize(sla.solve_discrete_lyapunov(T[s, s], np.eye(n - k)))
        Mu = (1 - p) * T[u, u] + p * F[u, u]
        R = jump_second_moment(T, F, X, p)[u, s]
        X[u, s] = stein_sylvester(Mu, T[s, s], R)
        X[s, u] = X[u, s].T
    x2 = slice(d, k)
    c22 = symmetrize(jump_second_moment(T, F, X, p)[x2, x2])
    M22 = np.eye(k - d) + p * Ku[d:] @ Ku[d:].T          # = P₂ − L₂₂(P₂)
    ev = np.linalg.eigvalsh(symmetrize(M22))
    beta = 1.0 + 2.0 * max(float(np.linalg.eigvalsh(c22).max()), 0.0) / float(ev.min())
    X[x2, x2] = beta * P2
    x1 = slice(0, d)
    R12 = jump_second_moment(T, F, X, p)[x1, x2]
    X[x1, x2] = _kronecker_pair(T[x1, x1], T[x2, x2], F[x1, x1], F[x2, x2], p, R12)
    X[x2, x1] = X[x1, x2].T
    c11 = symmetrize(jump_second_moment(T, F, X, p)[x1, x1])
    # margin w·I with w = ‖c₁₁‖: X₁₁ ≈ (w + c₁₁)/δ against √w in the equilibrated check
    w = max(1.0, float(np.linalg.norm(c11, 2)))
    R11 = w * np.eye(d) + c11
    X[x1, x1] = symmetrize(_kronecker_pair(T[x1, x1], T[x1, x1], F[x1, x1], F[x1, x1], p, R11))
    X = np.triu(X) + np.triu(X, 1).T
    if not np.all(np.isfinite(X)):
        return None
    return X, Kz



def block_lift(red: Reduced, Ku: np.ndarray, Xu: np.ndarray, Mu: np.ndarray, p: float
               ) -> tuple[np.ndarray, np.ndarray] | None:
    """Full-state (X_z, K_z) in the basis ``red.Z`` from an unstable-block certificate
    X_u − L_u(X_u) = M_u ≻ 0 with gain K_u (K zero on the stable block).

    Block back-substitution as in :func:`face_certificate_matrices`: X_ss − T_ss X_ss T_ss' = I,
    the coupling X_us − M X_us T_ss' = R_us exactly (:func:`stein_sylvester`,
    M = (1−p) T_uu + p F_uu), and X_uu = β X_u with β M_u ⪰ 1.5 (c_uu + I), c_uu the coupling
    term; then X_z − L(X_z) = diag(β M_u − c_uu, I) ≻ 0 without a Schur-complement scaling.
    """
    n, k = red.T.shape[0], red.k
    Kz = np.zeros((n, Ku.shape[1]))
    Kz[:k] = Ku
    T = red.T
    F = T + Kz @ (red.Cw @ red.Z)
    X = np.zeros((n, n))
    u, s = slice(0, k), slice(k, n)
    if k < n:
        X[s, s] = symmetrize(stein_sylvester(T[s, s], T[s, s], np.eye(n - k)))
        Mt = (1 - p) * T[u, u] + p * F[u, u]
        X[u, s] = stein_sylvester(Mt, T[s, s], jump_second_moment(T, F, X, p)[u, s])
        X[s, u] = X[u, s].T
    cuu = symmetrize(jump_second_moment(T, F, X, p)[u, u])
    try:
        Lc = np.linalg.cholesky(symmetrize(Mu))
        Li = sla.solve_triangular(Lc, np.eye(k), lower=True)
        top = float(np.linalg.eigvalsh(symmetrize(Li @ (cuu + np.eye(k)) @ Li.T)).max())
    except np.linalg.LinAlgError:
        return None
    X[u, u] = max(1.0, 1.5 * top) * Xu
    X = np.triu(X) + np.triu(X, 1).T
    if not np.all(np.isfinite(X)):
        return None
    return X, Kz
