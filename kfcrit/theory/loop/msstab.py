"""Mean-square stability of a jump-linear system, decided exactly where the data are rational.

For i.i.d. modes with probabilities π_m the second moment Z_t = E[z_t z_t'] follows the
positive map 𝓛(Z) = Σ_m π_m Φ_m Z Φ_m'; for a Markov chain of modes with transition matrix T
the tuple Z_j = E[z z' 1{θ = j}] follows 𝓛(Z)_j = Σ_i T_ij Φ_i Z_i Φ_i' (Costa, Fragoso &
Marques, *Discrete-time Markov jump linear systems*, 2005). Mean-square stability holds iff

.. math::

    \\rho\\Bigl(\\sum_m \\pi_m \\Phi_m \\otimes \\Phi_m\\Bigr) < 1
    \\quad\\text{resp.}\\quad
    \\rho\\bigl((T' \\otimes I)\\operatorname{diag}(\\Phi_i \\otimes \\Phi_i)\\bigr) < 1 .

**Exact decision.** 𝓛 preserves the cone of positive semidefinite matrices (tuples), so its
spectral radius ρ is itself an eigenvalue with a positive semidefinite eigenvector
(Krein–Rutman); it is an eigenvalue of the restriction to symmetric matrices (``vech``
coordinates, :func:`vech_operator`). Let χ be the characteristic polynomial of that matrix and
χ₁(y) = χ(1 + y). Then

.. math::

    \\rho < 1 \\iff \\text{every coefficient of } \\chi_1 \\text{ is } > 0 .

(⇒: every root z has |z| < 1, so every root y = z − 1 has Re y < 0 and the monic real
polynomial χ₁ is a product of factors y + α, y² + βy + δ with α, β, δ > 0. ⇐: by Descartes'
rule χ₁ has no root y > 0, and χ₁(0) = χ(1) ≠ 0, so no real eigenvalue is ≥ 1; since ρ is a
real eigenvalue, ρ < 1.) With rational data (floats are dyadic rationals) this is exact
integer arithmetic (python-flint ``fmpq_mat.charpoly``): "holds (certified)" or
"fails (certified)". Above :data:`EXACT_MAX_DIMENSION` a Lyapunov certificate — X ≻ 0 with
X − 𝓛(X) ≻ 0, found numerically and checked in ball arithmetic — can still prove stability;
otherwise the fact is "not decided" (with the float spectral radius).
"""
from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import flint
import numpy as np

from kfcrit.theory.upper import certify

__all__ = ["EXACT_MAX_DIMENSION", "StabilityFact", "mss_decision", "operator_matrix",
           "vech_operator"]

EXACT_MAX_DIMENSION = 160
"""Largest vech-operator dimension decided by the exact characteristic polynomial."""

HOLDS, FAILS, UNDECIDED = "holds (certified)", "fails (certified)", "not decided"


@dataclass(frozen=True)
class StabilityFact:
    """Mean-square stability of a jump-linear system, as a fact.

    Attributes
    ----------
    status : str
        ``"holds (certified)"``, ``"fails (certified)"`` or ``"not decided"``.
    holds : bool or None
        True / False when certified, None when not decided.
    rho : float
        Float64 spectral radius of the second-moment operator (an estimate).
    method : str
        How the status was decided.
    dimension : int
        Size of the operator matrix (vech coordinates).
    """

    status: str
    holds: bool | None
    rho: float
    method: str
    dimension: int


def vech_operator(Phi: np.ndarray) -> np.ndarray:
    """Matrix of X ↦ Φ X Φ' on ``vech`` coordinates (upper triangle, row-major).

    .. math::

        [\\,\\cdot\\,]_{(r,s),(i,j)} = \\Phi_{ri}\\Phi_{sj} + \\Phi_{rj}\\Phi_{si}
        \\quad (\\text{halved when } i = j)

    Works on float arrays and on exact object arrays of Fraction alike.
    """
    n = Phi.shape[0]
    iu, ju = np.triu_indices(n)
    Mr, Ms = Phi[iu], Phi[ju]
    T = Mr[:, iu] * Ms[:, ju] + Mr[:, ju] * Ms[:, iu]
    half = Fraction(1, 2) if Phi.dtype == object else 0.5
    T[:, iu == ju] = T[:, iu == ju] * half
    return T


def operator_matrix(Phi: list[np.ndarray], weights: list, transition: list | None = None
                    ) -> np.ndarray:
    """The second-moment operator on vech coordinates.

    i.i.d. (``transition`` None): Σ_m π_m vech(Φ_m ⊗ Φ_m). Markov: the block matrix with
    block (j, i) = T_ij vech(Φ_i ⊗ Φ_i) (the form (T' ⊗ I) diag(Φ_i ⊗ Φ_i)).
    """
    ops = [vech_operator(P) for P in Phi]
    if transition is None:
        out = weights[0] * ops[0]
        for w, O in zip(weights[1:], ops[1:]):
            out = out + w * O
        return out
    k = len(ops)
    rows = [np.hstack([transition[i][j] * ops[i] for i in range(k)]) for j in range(k)]
    return np.vstack(rows)


def _fmpq(x: Fraction) -> flint.fmpq:
    x = Fraction(x)
    return flint.fmpq(x.numerator, x.denominator)


def exact_decision(M: np.ndarray) -> bool:
    """ρ(M) < 1 for a rational matrix M of a cone-preserving operator (see module docstring)."""
    d = M.shape[0]
    rows = [[_fmpq(M[i, j]) for j in range(d)] for i in range(d)]
    chi = flint.fmpq_mat(rows).charpoly()
    num = flint.fmpz_poly([int(c * chi.denom()) for c in chi.coeffs()])
    shifted = num(flint.fmpz_poly([1, 1]))
    coeffs = shifted.coeffs()
    lead = coeffs[-1]
    return all(c * lead > 0 for c in coeffs) and len(coeffs) == d + 1


def _lyapunov_certificate(M_exact: np.ndarray, M: np.ndarray, n: int, blocks: int) -> bool:
    """X ≻ 0 and X − 𝓛(X) ≻ 0 (block-wise) proven in balls, X from (I − M) vech X = vech I."""
    d = n * (n + 1) // 2
    eye = np.eye(n)[np.triu_indices(n)]
    rhs = np.concatenate([eye] * blocks)
    try:
        x = np.linalg.solve(np.eye(M.shape[0]) - M, rhs)
    except np.linalg.LinAlgError:
        return False
    old = flint.ctx.prec
    flint.ctx.prec = certify.PRECISION_BITS
    try:
        Ma = flint.arb_mat([[flint.arb(_fmpq(v)) for v in row] for row in M_exact])
        xa = flint.arb_mat([[flint.arb(float(v))] for v in x])
        res = xa - Ma * xa
        for b in range(blocks):
            for vec in (xa, res):
                X = _unvech_arb([vec[b * d + i, 0] for i in range(d)], n)
                if certify.definite_margin(X) is None:
                    return False
        return True
    finally:
        flint.ctx.prec = old


def _unvech_arb(values: list, n: int) -> flint.arb_mat:
    iu, ju = np.triu_indices(n)
    X = flint.arb_mat(n, n)
    for k, (i, j) in enumerate(zip(iu, ju)):
        X[int(i), int(j)] = values[k]
        X[int(j), int(i)] = values[k]
    return X


def mss_decision(M_exact: np.ndarray | None, M: np.ndarray, n: int, blocks: int = 1
           ) -> StabilityFact:
    """Mean-square stability from the operator matrix (exact when ``M_exact`` is given).

    Parameters
    ----------
    M_exact : ndarray of Fraction or None
        The exact operator matrix (None: numerical only).
    M : ndarray
        Its float64 version.
    n : int
        Size of z (the vech blocks have n(n+1)/2 coordinates).
    blocks : int
        Number of Markov modes in the operator (1 for i.i.d.).
    """
    d = M.shape[0]
    with np.errstate(all="ignore"):
        ev = np.linalg.eigvals(M) if np.all(np.isfinite(M)) else np.array([np.inf])
    rho = float(np.max(np.abs(ev))) if ev.size else 0.0
    if M_exact is not None and d <= EXACT_MAX_DIMENSION:
        ok = exact_decision(M_exact)
        return StabilityFact(HOLDS if ok else FAILS, ok, rho,
                             "exact: signs of the Taylor-shifted characteristic polynomial "
                             "χ(1 + y) of the vech second-moment operator (python-flint)", d)
    if M_exact is not None and rho < 1 and _lyapunov_certificate(M_exact, M, n, blocks):
        return StabilityFact(HOLDS, True, rho, "Lyapunov certificate X ≻ 0, X − 𝓛(X) ≻ 0 "
                             "checked in ball arithmetic", d)
    return StabilityFact(UNDECIDED, None, rho, "float64 spectral radius only", d)
