"""The upper bound p_up of the critical arrival probability, with a checked certificate.

p_up = inf { p : ∃ K, X ≻ 0 with X ≻ L_{K,p}(X) },  L_{K,p}(X) = (1−p) A X A' + p F X F',
F = A + K C (Sinopoli Thm 5 with Q, R scaled away). Minimising over K for fixed X gives the
noise-free MARE map G_p(X) = A X A' − p A X C'(C X C')^{-1} C X A' = min_K L_{K,p}(X), which is
monotone, concave and positively homogeneous; p_up is where its cone spectral radius r(p)
crosses 1 (MATH.md §3).

The default method ("newton") works in four steps:

1. *Reduce.* Only the modes with |λ| ≥ 1 matter: with an ordered real Schur form
   A = Z [[T_uu, T_us], [0, T_ss]] Z', p_up(A, C) = p_up(T_uu, C Z_u) (a stable block driven by
   nothing decays; a gain that ignores it keeps mean-square stability — and the unstable
   subspace carries an invariant sub-cone of G_p, so the reduced radius is a lower bound).
2. *Bracket.* Bisection on p with r(p) estimated by normalised power iteration.
3. *Newton* on the eigen-system G_p(X) = X, tr X = 1 in the unknowns (X, p): the Jacobian in X
   is L_{K_X,p} − I (envelope theorem), in p it is −A X C'(C X C')^{-1} C X A'. Quadratic
   convergence to p* (the eigenvector X* ⪰ 0 shows r(p*) ≥ 1, hence p_up ≥ p*).
   The same Newton on the *regularised* map G^ε_p(X) = G_p with Q = R = ε·tr(X)·I gives
   p_ε ≥ p_up (a little above p*), with X_ε ≻ 0 and X_ε − L_{K,p_ε}(X_ε) ⪰ ε·tr(X_ε)·I.
4. *Certify.* Lift (X_ε, K_ε) to the full state and prove X ≻ 0, X − L_{K,hi}(X) ≻ 0 in ball
   arithmetic on the exact matrices (:mod:`kfcrit.theory.certify`). The lower end is p_low (Thm 3,
   proven) when hi − tol ≤ p_low, otherwise the Newton root p* (numerical), upgraded to a
   proof when a positive definite eigenvector X_u of G_lo on the unstable block with eigenvalue
   > 1 is verified in balls on an exactly A-invariant subspace (enclosed by Stewart's theorem,
   :func:`kfcrit.theory.certify.invariant_block`). That is valid with stable modes too: G_p maps the
   cone of PSD matrices supported on an A-invariant subspace into itself, so its cone radius
   bounds that of the full map from below (:func:`cone_lower_check`).

``method="lmi"`` runs Sinopoli's Ψ_p LMI (:mod:`kfcrit.theory.lmi`) instead; "auto" runs "newton" and
falls back to the LMI when Newton cannot produce a certified bracket.
"""
from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import scipy.linalg as sla
import sympy as sp

from kfcrit.theory import certify
from kfcrit.theory.riccati import noise_free_g, stein_matrix, symmetrize, unvech, vech
from kfcrit.model.system import System

UNSTABLE_TOL = 1e-9
"""Modes with |λ| ≥ 1 − UNSTABLE_TOL are kept in the reduced system."""
NEWTON_MAX_REDUCED = 60
"""Largest unstable block for the dense Newton (its Jacobian has (k(k+1)/2 + 1)² entries)."""
NEAR_P_LOW = 1e-6
"""A Newton root this close to p_low is first tried as p_up = p_low (certificate at p_low + tol)."""
SMALL_MATRIX = 6
"""Up to this many states the LMI's certificate matrices were included in older records (kept
for compatibility; now :data:`RECORD_MATRIX_MAX` applies to every method)."""
RECORD_MATRIX_MAX = 60
"""Certificates of systems with at most this many states are included in the record: the
matrices exactly as checked (``basis``, ``X_basis``, ``K_basis``, ``output_map``; JSON floats
round-trip exactly) and the rounded full-state copies ``X``, ``K``."""


@dataclass(frozen=True)
class UpperBound:
    """The upper bound p_up with its bracket, certificate and evidence (a plain record)."""

    value: float | None
    interval: tuple[float, float]
    certified: bool
    status: str
    method: str
    certificate: dict[str, Any] | None
    lower_evidence: dict[str, Any]
    solver: dict[str, Any]
    warnings: tuple[str, ...] = ()
    extras: dict[str, Any] = field(default_factory=dict, compare=False, repr=False)
    tolerance: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able data (no NaN/inf)."""
        return {"value": self.value, "interval": [float(self.interval[0]), float(self.interval[1])],
                "certified": self.certified, "status": self.status, "method": self.method,
                "certificate": self.certificate, "lower_evidence": self.lower_evidence,
                "solver": self.solver, "warnings": list(self.warnings),
                "tolerance": self.tolerance,
                "applicable": not self.extras.get("not_applicable"),
                "not_applicable_reason": self.extras.get("not_applicable")}


# ---------------------------------------------------------------------------------------------
# reduction, power iteration, Newton
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Reduced:
    """Ordered real Schur reduction: A = Z T Z', the first k modes have |λ| ≥ 1 − tol."""

    T: np.ndarray
    Z: np.ndarray
    k: int
    Au: np.ndarray
    Cu: np.ndarray
    Cw: np.ndarray | None = None
    """The output matrix the reduction was computed with (M C when compressed, else C)."""
    M: np.ndarray | None = None
    """Output compression: certificates carry gains K_w for M C; the gain for C is K_w M."""


def reduce_unstable(A: np.ndarray, C: np.ndarray, tol: float = UNSTABLE_TOL,
                    output_map: np.ndarray | None = None) -> Reduced:
    """Real Schur form with the modes |λ| ≥ 1 − tol first; (T_uu, C Z_u) is the reduced system.

    ``C`` is the output matrix to work with (already compressed when ``output_map`` is given).
    """
    T, Z, k = sla.schur(A, output="real",
                        sort=lambda re, im: re * re + im * im >= (1.0 - tol) ** 2)
    return Reduced(T, Z, int(k), T[:k, :k], C @ Z[:, :k], C, output_map)


OUTPUT_CONDITION_LIMIT = 1e4
"""Conditioning rule for the reduced output C Z_u: beyond this ratio σ_max/σ_min (or with
dependent rows) the methods work with the compressed output M C (see :func:`reduce_system`)."""


def reduce_system(system: System, tol: float = UNSTABLE_TOL) -> Reduced:
    """:func:`reduce_unstable` of (A, C), with the output compressed when C Z_u is
    ill-conditioned.

    p_up depends on the row space of the reduced output C Z_u only (K C = (K M⁻¹)(M C)), but
    the methods do not: a tiny singular value of C Z_u is swamped by their homogeneous
    regulariser (1e-15·tr X added to C X C') and by the LMI solver's tolerances, so an
    ill-conditioned output behaves as if it had fewer rows — the audit case A = [[0,−2],[2,0]],
    C = diag(1, 1e-12) gave a "determined" bracket around 0.9375 for p_up = 0.75.
    Conditioning rule: when σ_max/σ_min of C Z_u exceeds ``OUTPUT_CONDITION_LIMIT``, or its
    rows are dependent (numerical rank r < m by NumPy's rule σ_i > max(m, k)·eps·σ_max), the
    methods use M C with M = diag(1/σ_1..1/σ_r) U_r' (then M C Z_u has orthonormal rows).
    M C is formed exactly in balls from the exact C and rounded once, and every certificate
    is checked with the gain K_w M on the exact C (:func:`kfcrit.theory.certify.verify_upper`,
    ``output_map``), so the compression never enters a proof.
    """
    A, C = system.a, system.c
    red = reduce_unstable(A, C, tol)
    if red.k == 0 or not np.all(np.isfinite(red.Cu)):
        return red
    m, k = red.Cu.shape
    U, sv, _ = np.linalg.svd(red.Cu, full_matrices=False)
    if sv.size == 0 or sv[0] == 0:
        return red
    r = int(np.sum(sv > max(m, k) * np.finfo(float).eps * sv[0]))
    if r == m and sv[r - 1] * OUTPUT_CONDITION_LIMIT >= sv[0]:
        return red
    M = (U[:, :r] / sv[:r]).T
    Cw = certify.exact_product(M, system.C)
    return Reduced(red.T, red.Z, red.k, red.Au, Cw @ red.Z[:, :red.k], Cw, M)


POWER_REG = 1e-12
"""Homogeneous regulariser floor (times tr X, added to C X C') of the power iteration, whose
iterates drift toward singular X."""
NEWTON_REG = 1e-15
"""The same floor for the Newton solvers (:func:`threshold_newton`, :func:`perron_newton`): the
residual and the Jacobian must use one and the same map, or Newton converges to the root of a
different map than the one it is differentiating (with 1e-12 in the residual and 1e-15 in the
gain, ``random_system(12, 4, 0)`` had r(p*) = 1 + 2.3e-8 at the threshold root p*, and no
certificate within tol of p*)."""


def regularised_g(A: np.ndarray, C: np.ndarray, X: np.ndarray, p: float,
                  eps: float, floor: float = POWER_REG) -> np.ndarray:
    """G^ε_p(X) = A X A' + εt I − p A X C'(C X C' + max(ε, floor) t I)^{-1} C X A', t = tr X
    (ε = 0: G_p with the homogeneous regulariser ``floor``·t only)."""
    t = float(np.trace(X))
    Y = noise_free_g(A, C, X, p, reg=max(eps, floor) * t)
    return Y + eps * t * np.eye(A.shape[0]) if eps else Y


def cone_radius(A: np.ndarray, C: np.ndarray, p: float, X0: np.ndarray | None = None,
                iterations: int = 600, rtol: float = 1e-10,
                eps: float = 0.0) -> tuple[float, np.ndarray, int]:
    """Cone spectral radius r(p) of G^ε_p by averaged normalised power iteration
    X ← (X + G(X)/tr G(X))/2, tr X = 1 (a fixed point has G(X) = r X).

    With ε = 0 a homogeneous regulariser 1e-12·tr X keeps C X C' invertible.
    Returns (r, X, iterations).
    """
    n = A.shape[0]
    X = np.eye(n) / n if X0 is None else X0 / np.trace(X0)
    r = float("nan")
    for i in range(1, iterations + 1):
        Y = regularised_g(A, C, X, p, eps)
        r = float(np.trace(Y))
        if not np.isfinite(r) or r <= 0:
            return r, X, i
        Y = Y / r
        done = np.abs(Y - X).max() < rtol
        # Krasnoselskii averaging: breaks the periodic orbits of rotations (e.g. λ = ±jρ)
        X = 0.5 * (X + Y)
        if done:
            break
    return r, X, i


@dataclass(frozen=True)
class NewtonResult:
    X: np.ndarray
    p: float
    K: np.ndarray
    iterations: int
    converged: bool
    residual: float


def threshold_newton(A: np.ndarray, C: np.ndarray, X0: np.ndarray, p0: float, eps: float = 0.0,
                     max_iterations: int = 40, atol: float = 1e-14) -> NewtonResult:
    """Newton on G^ε_p(X) = X, tr X = 1 in (X, p) (see the module docstring).

    G^ε_p(X) = A X A' + εt I − p A X C'(C X C' + εt I)^{-1} C X A', t = tr X. Its Jacobian in X
    is L_{K,p}(dX) + ε tr(dX) (I + p K K') with K the optimal gain; in p, −A X C' S^{-1} C X A'.
    """
    n, m = A.shape[0], C.shape[0]
    N = n * (n + 1) // 2
    iu, ju = np.triu_indices(n)
    diag = (iu == ju).astype(float)
    X, p = symmetrize(X0) / np.trace(X0), float(p0)
    K = np.zeros((n, m))
    res = np.inf
    for it in range(max_iterations + 1):
        t = np.trace(X)
        S = C @ X @ C.T + max(eps, NEWTON_REG) * t * np.eye(m)   # keep S invertible
        AXC = A @ X @ C.T
        try:
            K = -np.linalg.solve(S.T, AXC.T).T
            P = symmetrize(AXC @ np.linalg.solve(S, AXC.T))
        except np.linalg.LinAlgError:
            return NewtonResult(X, p, K, it, False, np.inf)
        Fv = vech(symmetrize(A @ X @ A.T) + eps * t * np.eye(n) - p * P - X)
        r = np.concatenate([Fv, [t - 1.0]])
        res = float(np.abs(r).max())
        if not np.isfinite(res):
            return NewtonResult(X, p, K, it, False, res)
        if res < atol:
            return NewtonResult(X, p, K, it, True, res)
        if it == max_iterations:
            break
        J = np.zeros((N + 1, N + 1))
        J[:N, :N] = stein_matrix(A, C, K, p) - np.eye(N)
        if eps:
            J[:N, :N] += eps * np.outer(vech(np.eye(n) + p * K @ K.T), diag)
        J[:N, N] = -vech(P)
        J[N, :N] = diag
        try:
            d = np.linalg.solve(J, -r)
        except np.linalg.LinAlgError:
            return NewtonResult(X, p, K, it, False, res)
        X = X + unvech(d[:N], n)
        p = p + float(d[N])
    return NewtonResult(X, p, K, max_iterations, res < 1e3 * atol, res)


def perron_newton(A: np.ndarray, C: np.ndarray, X0: np.ndarray, p: float, eps: float = 0.0,
                  max_iterations: int = 40, atol: float = 1e-14
                  ) -> tuple[np.ndarray, float, np.ndarray, bool]:
    """Newton on G^ε_p(X) = r X, tr X = 1 in (X, r) at fixed p: the cone eigenpair of G^ε_p.

    Returns (X, r, K, converged) with K the optimal gain at X.
    """
    n, m = A.shape[0], C.shape[0]
    N = n * (n + 1) // 2
    iu, ju = np.triu_indices(n)
    diag = (iu == ju).astype(float)
    X = symmetrize(X0) / np.trace(X0)
    r = float(np.trace(regularised_g(A, C, X, p, eps, NEWTON_REG)))
    K = np.zeros((n, m))
    for _ in range(max_iterations + 1):
        t = float(np.trace(X))
        S = C @ X @ C.T + max(eps, NEWTON_REG) * t * np.eye(m)   # keep S invertible
        AXC = A @ X @ C.T
        try:
            K = -np.linalg.solve(S.T, AXC.T).T
            G = regularised_g(A, C, X, p, eps, NEWTON_REG)   # the map K and J belong to
        except np.linalg.LinAlgError:
            return X, r, K, False
        res_v = np.concatenate([vech(G - r * X), [t - 1.0]])
        if not np.all(np.isfinite(res_v)):
            return X, r, K, False
        if np.abs(res_v).max() < atol:
            return X, r, K, True
        J = np.zeros((N + 1, N + 1))
        J[:N, :N] = stein_matrix(A, C, K, p) - r * np.eye(N)
        if eps:
            J[:N, :N] += eps * np.outer(vech(np.eye(n) + p * K @ K.T), diag)
        J[:N, N] = -vech(X)
        J[N, :N] = diag
        try:
            d = np.linalg.solve(J, -res_v)
        except np.linalg.LinAlgError:
            return X, r, K, False
        X = X + unvech(d[:N], n)
        r = r + float(d[N])
    return X, r, K, False


# ---------------------------------------------------------------------------------------------
# lifting a reduced certificate to the full state
# ---------------------------------------------------------------------------------------------


def lift_certificate(red: Reduced, C: np.ndarray, Xu: np.ndarray, Ku: np.ndarray,
                     p: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Full-state certificate (Z, X_z, K_z) from a reduced one X_u ≻ L_{K_u,p}(X_u).

    The full-state certificate is X = Z X_z Z', K = Z K_z (formed exactly by the checker).

    In Schur coordinates take K = [K_u; 0] and X = diag(c X_u, Y_s), Y_s = T_ss Y_s T_ss' + I.
    Then X − L(X) = [[c M_u − a, −b], [−b', I]] with M_u = X_u − L_u(X_u),
    a = (1−p) T_us Y_s T_us' + p B Y_s B', b = ((1−p) T_us + p B) Y_s T_ss', B = T_us + K_u C_s;
    it is ≻ 0 when c M_u ≻ a + b b', which holds for c = max(2‖a + b b'‖ / λ_min(M_u), 1).
    (Scaling the unstable block up, not the stable block down, keeps X well inside the cone.)
    """
    n, k = red.T.shape[0], red.k
    C = red.Cw if red.Cw is not None else C
    Fu = red.Au + Ku @ red.Cu
    Mu = symmetrize(Xu - (1 - p) * red.Au @ Xu @ red.Au.T - p * Fu @ Xu @ Fu.T)
    if k == n:
        Xz, Kz = Xu, Ku
    else:
        Tss, Tus = red.T[k:, k:], red.T[:k, k:]
        Cs = C @ red.Z[:, k:]
        Ys = sla.solve_discrete_lyapunov(Tss, np.eye(n - k))
        B = Tus + Ku @ Cs
        a = (1 - p) * Tus @ Ys @ Tus.T + p * B @ Ys @ B.T
        b = ((1 - p) * Tus + p * B) @ Ys @ Tss.T
        lam = float(np.linalg.eigvalsh(Mu).min())
        scale = float(np.linalg.norm(a + b @ b.T, 2))
        c = max(2.0 * scale / lam, 1.0) if lam > 0 else 1.0
        Xz = np.zeros((n, n))
        Xz[:k, :k] = c * Xu
        Xz[k:, k:] = Ys
        Kz = np.zeros((n, Ku.shape[1]))
        Kz[:k] = Ku
    return red.Z, symmetrize(Xz), Kz


MARGINAL_TOL = 1e-6
"""| |λ| − 1 | below this marks a mode of the unstable block as marginal (see
:func:`_lower_evidence`: numerical lower-end evidence is not accepted there)."""
PBH_TOL = 1e-10
"""Relative PBH threshold of :func:`undetected_modes` (σ_min against ‖A‖ + ‖C‖)."""


def undetected_modes(Au: np.ndarray, Cu: np.ndarray,
                     tol: float = PBH_TOL) -> list[tuple[complex, float]]:
    """Modes of the reduced block (|λ| ≥ 1 − tol) that C cannot see: PBH test in float64.

    (A, C) is detectable iff [A − λI; C] has full column rank for every |λ| ≥ 1. With a right
    eigenvector v, Cv = 0, then (A + KC) v = A v = λ v for every gain K, so
    (1 − p) A⊗A + p (A+KC)⊗(A+KC) keeps the eigenvalue |λ|² ≥ 1 on v⊗v̄: no p and no K give a
    mean-square stable error system and p_up does not exist. Returns (λ, σ_min) for each
    eigenvalue whose σ_min([A − λI; C]) ≤ tol·(‖A‖ + ‖C‖) (the exact structure analysis
    decides detectability exactly; this guard keeps the numerical methods from reporting a
    bracket for a threshold that does not exist).
    """
    k = Au.shape[0]
    if k == 0:
        return []
    scale = float(np.linalg.norm(Au, 2) + (np.linalg.norm(Cu, 2) if Cu.size else 0.0))
    out = []
    for lam in np.linalg.eigvals(Au):
        M = np.vstack([Au - lam * np.eye(k), Cu.astype(complex)])
        s = float(np.linalg.svd(M, compute_uv=False)[-1])
        if s <= tol * max(scale, 1.0):
            out.append((complex(lam), s))
    return out


def stable_certificate(A: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For ρ(A) < 1: K = 0 and X = A X A' + I certify p = 0."""
    X = sla.solve_discrete_lyapunov(A, np.eye(A.shape[0]))
    return symmetrize(X), np.zeros((A.shape[0], C.shape[0]))


# ---------------------------------------------------------------------------------------------
# the fast method
# ---------------------------------------------------------------------------------------------


def p_low_of(A: np.ndarray) -> float:
    """p_low = 1 − 1/ρ(A)² (0 when ρ(A) ≤ 1), Sinopoli Thm 3."""
    rho = float(max(abs(np.linalg.eigvals(A)))) if A.size else 0.0
    return max(0.0, 1.0 - 1.0 / rho**2) if rho > 1 else 0.0


@dataclass(frozen=True)
class PLow:
    """p_low = max(1 − 1/ρ(A)², 0) with directed float roundings down ≤ p_low ≤ up."""

    down: float
    up: float
    expression: str | None
    how: str
    rigorous: bool


def p_low_bounds(system: System) -> PLow:
    """Enclose the exact p_low of ``system`` between two floats (Sinopoli Thm 3).

    In order of preference: the exact |λ_1|² of the structure analysis when it has already run
    (exact path; e.g. A = √2 gives p_low = 1/2 exactly, where floats give 0.5000000000000001);
    exact eigenvalues for n ≤ 2 (sympy); the exact characteristic polynomial of a rational A
    (python-flint, rigorous root isolation, multiplicities handled); ball eigenvalues of the
    exact A (python-flint acb_mat.eig); float64 eigenvalues widened by 1e-12 relative (labelled
    not rigorous) when n > 60 or everything else fails.
    """
    key = id(system)
    hit = _PLOW_CACHE.get(key)
    if hit is not None and hit[0] is system:
        return hit[1]
    out = _p_low_bounds(system)
    _PLOW_CACHE[key] = (system, out)
    while len(_PLOW_CACHE) > 32:
        _PLOW_CACHE.pop(next(iter(_PLOW_CACHE)))
    return out


_PLOW_CACHE: dict[int, tuple[System, PLow]] = {}


def _p_low_from_mod2(mod2: sp.Expr, how: str) -> PLow:
    mod2 = sp.nsimplify(mod2) if isinstance(mod2, sp.Float) else mod2
    if not sp.N(mod2 - 1, 50) > 0:
        # |λ_1|² ≤ 1 to 50 digits; equality is decided exactly below when possible
        if mod2.is_Rational or sp.N(mod2 - 1, 50) < 0 or sp.simplify(mod2 - 1) == 0:
            return PLow(0.0, 0.0, "0", how, True)
        raise ValueError("|λ_1|² too close to 1 to decide")
    expr = sp.radsimp(1 - 1 / mod2)
    down, up = certify.round_expr(expr)
    return PLow(max(down, 0.0), up, sp.sstr(expr), how, True)


def _p_low_bounds(system: System) -> PLow:
    from kfcrit.theory import critical
    st = critical._CACHE.get(system)
    if st is not None and st.path == "exact" and st.eigen and st.eigen[0].mod2_expr is not None:
        top = st.eigen[0]
        if top.unit_cmp is not None and top.unit_cmp <= 0:
            return PLow(0.0, 0.0, "0", "exact (structure analysis: ρ(A) ≤ 1)", True)
        try:
            return _p_low_from_mod2(top.mod2_expr, "exact (structure analysis)")
        except (ValueError, TypeError):
            pass
    n = system.n
    if n <= 2:
        try:
            eigs = list(sp.Matrix(system.A).eigenvals())
            mods = [sp.radsimp(sp.expand(sp.re(z) ** 2 + sp.im(z) ** 2)) for z in eigs]
            mod2 = max(mods, key=lambda v: float(sp.N(v, 30)))
            return _p_low_from_mod2(mod2, "exact (eigenvalues by sympy)")
        except (ValueError, TypeError, ArithmeticError):
            pass
    bounds = None
    if n <= 60:
        if all(e.is_Rational for e in system.A):
            bounds = _rational_rho2(system)
        if bounds is None:
            bounds = certify.spectral_radius2_bounds(system)
    if bounds is not None:
        lo2, hi2 = bounds
        down = certify.float_down(1 - 1 / lo2) if lo2 > 1 else 0.0
        up = certify.float_up(1 - 1 / hi2) if hi2 > 1 else 0.0
        if up - down <= 1e-12:
            return PLow(max(down, 0.0), up, None, "ball enclosure of ρ(A)² (python-flint)", True)
    p = p_low_of(system.a)
    pad = 1e-12 * max(p, 1e-300)
    return PLow(max(0.0, p - pad), p + pad if p > 0 else 0.0, None,
                "float64 eigenvalues, widened by 1e-12 relative (not rigorous)", False)


def _rational_rho2(system: System):
    """Rigorous bounds on ρ(A)² from the exact characteristic polynomial of a rational A."""
    from fractions import Fraction as Fr

    import flint
    try:
        old = flint.ctx.prec
        flint.ctx.prec = 200
        try:
            rows = [[flint.fmpq(int(e.p), int(e.q)) for e in system.A.row(i)]
                    for i in range(system.n)]
            P = flint.fmpq_mat(rows).charpoly()
            num = flint.fmpz_poly([int(c * P.denom()) for c in P.coeffs()])
            lo, hi = Fr(0), Fr(0)
            for root, _mult in num.complex_roots():
                m2 = root.real * root.real + root.imag * root.imag
                a, b = certify._arb_exact(m2.lower()), certify._arb_exact(m2.upper())
                lo, hi = max(lo, max(a, Fr(0))), max(hi, b)
            return lo, hi
        finally:
            flint.ctx.prec = old
    except (ValueError, TypeError, ZeroDivisionError, AttributeError):
        return None


def c_invertible(system: System) -> tuple[bool | None, str]:
    """Is C square and invertible? (decision, how it was decided).

    Exact where the entries are exact numbers: rational C (every binary float is one) by the
    rank over Q (python-flint fmpq_mat); algebraic C by a ball determinant that excludes 0
    (proves invertible), else sympy's exact determinant (proves singular when it simplifies to
    0). Otherwise None (undecided; the general method runs).
    """
    n, m = system.n, system.m
    if m != n:
        return False, "C is not square"
    import flint
    if all(e.is_Rational for e in system.C):
        rows = [[flint.fmpq(int(e.p), int(e.q)) for e in system.C.row(i)] for i in range(n)]
        rank = flint.fmpq_mat(rows).rank()
        return rank == n, f"rank C = {rank} over Q, exact rational arithmetic (python-flint)"
    try:
        old = flint.ctx.prec
        flint.ctx.prec = certify.PRECISION_BITS
        try:
            det = certify.arb_from_sympy(system.C).det()
        finally:
            flint.ctx.prec = old
        if not det.contains(0):
            return True, f"det C ≠ 0 proven by ball arithmetic (det C ∈ {det.str(5)})"
    except (ValueError, TypeError, ZeroDivisionError):
        pass
    if n <= 6 and sp.simplify(sp.Matrix(system.C).det()) == 0:
        return False, "det C = 0, exact (sympy)"
    return None, "undecided"


def _c_invertible_bound(system: System, how: str) -> UpperBound:
    """p_up = p_c = p_low exactly when C is invertible (Sinopoli et al. 2004 §IV)."""
    t0 = time.perf_counter()
    pl = p_low_bounds(system)
    kappa = float(np.linalg.cond(system.c))
    statement = ("C is square and invertible (" + how + "): the gain K = −A C⁻¹ gives "
                 "F = A + K C = 0, so X ≻ L_{K,p}(X) = (1−p) A X A' has a solution X ≻ 0 iff "
                 "(1−p) ρ(A)² < 1, i.e. iff p > p_low; hence p_up = p_low = max(1 − 1/ρ(A)², 0) "
                 "exactly and p_c = p_up = p_low (Sinopoli et al. 2004 §IV). The infimum is "
                 "not attained: every p > p_low is certified by this K.")
    warn: list[str] = []
    if not system.exact and kappa > 1e8:
        warn.append(f"C is invertible as given (its binary floats taken exactly) but "
                    f"ill-conditioned: cond₂(C) ≈ {kappa:.3g}, so a relative change of about "
                    f"{1 / kappa:.1g} in C can make it singular and raise p_up")
    interval = (pl.down, pl.up)
    cert = {"kind": "theorem: C invertible, F = A + K C = 0 with K = −A C⁻¹",
            "origin": "exact decision, no numerical certificate needed", "ok": pl.rigorous,
            "p": pl.up, "statement": statement, "reason": "proven" if pl.rigorous else
            "p_low from float eigenvalues (not rigorous)",
            "verified_by": f"{how}; p_low by {pl.how}", "condition_number_C": kappa}
    lower = {"kind": "theorem", "value": pl.down, "certified": pl.rigorous,
             "expression": pl.expression,
             "statement": "p_up ≥ p_c ≥ p_low = 1 − 1/ρ(A)² (Sinopoli Thm 3); here "
                          "p_up = p_low exactly (C invertible)"}
    solver = {"seconds": time.perf_counter() - t0, "solves": 0, "special_case": "C invertible",
              "p_low": pl.how}
    return UpperBound(pl.up, interval, pl.rigorous, "determined" if pl.rigorous else
                      "undetermined", "exact", cert, lower, solver, tuple(warn),
                      {"p_low_expression": pl.expression})


def _evidence_p_low(p_low: float) -> dict[str, Any]:
    return {"kind": "theorem", "value": p_low, "certified": True,
            "statement": "p_up ≥ p_c ≥ p_low = 1 − 1/ρ(A)² (Sinopoli Thm 3)"}


def _newton_method(system: System, tol: float,
                   progress: dict[str, Any] | None = None) -> UpperBound:
    """The fast method (module docstring). ``progress`` receives the stage and the numerical
    bracket as they are reached (read by :func:`upper_bound` if a numerical failure stops it)."""
    progress = {} if progress is None else progress
    progress.update(stage="Schur reduction", method="newton")
    t0 = time.perf_counter()
    A, C = system.a, system.c
    stats: dict[str, Any] = {"power_iterations": 0, "newton_iterations": 0, "certificate_checks": 0}
    warnings: list[str] = []
    p_low = p_low_of(A)
    red = reduce_system(system)
    stats["reduced_states"] = red.k
    if red.M is not None:
        stats["output_compression"] = _compression_note(red)

    def done(value, interval, certified, status, cert, lower, extras=None):
        stats["seconds"] = time.perf_counter() - t0
        stats["solves"] = stats["newton_iterations"]      # dense Newton linear solves
        return UpperBound(value, (float(interval[0]), float(interval[1])), certified, status,
                          "newton", cert, lower, dict(stats), tuple(warnings), extras or {})

    if red.k == 0:
        X, K = stable_certificate(A, C)
        check = certify.verify_upper(system, 0.0, X, K)
        stats["certificate_checks"] += 1
        cert = _certificate_summary(system, check, X, K, "Lyapunov X = A X A' + I, K = 0")
        lower = {"kind": "trivial", "value": 0.0, "certified": True,
                 "statement": "p ≥ 0; ρ(A) < 1, so p = 0 is already mean-square stable"}
        return done(0.0, (0.0, 0.0), check.ok, "determined", cert, lower)

    Au, Cu = red.Au, red.Cu
    blind = undetected_modes(Au, Cu)
    if blind:
        warnings.append("upper bound not applicable: (A, C) is not detectable in float64 (PBH: "
                        + ", ".join(f"λ ≈ {z:.6g} with σ_min([A − λI; C]) ≈ {s:.1e}"
                                    for z, s in blind[:3])
                        + "); no gain makes the error system mean-square stable")
        return done(None, (p_low, 1.0), False, "undetermined", None, _evidence_p_low(p_low),
                    {"not_applicable": "(A, C) is not detectable: a mode with |λ| ≥ 1 is "
                                       "invisible to C, so (A + KC) keeps it for every K and no "
                                       "p makes E[P_t] bounded; p_up is not defined"})
    # 2. bracket by bisection on the power-iteration radius
    lo, hi = p_low, 1.0
    progress["stage"] = "power-iteration bracket"
    r1, X1, it = cone_radius(Au, Cu, 1.0)
    stats["power_iterations"] += it
    if not (r1 < 1.0):
        warnings.append("upper bound undetermined: in float64 the noise-free Riccati map has cone "
                        f"spectral radius {r1:.6g} >= 1 even at p = 1, so no p_up < 1 was found; "
                        "(A, C) is either not detectable or too ill-conditioned for this method "
                        "(the exact structure analysis decides detectability)")
        return done(None, (p_low, 1.0), False, "undetermined", None, _evidence_p_low(p_low),
                    {"not_applicable": "the noise-free Riccati map does not contract even at "
                                       "p = 1: (A, C) is not detectable (or numerically so); "
                                       "no p < 1 makes E[P_t] bounded, p_up is not defined"})
    Xh, Xl = X1, None
    while hi - lo > 1.0 / 64:
        mid = 0.5 * (lo + hi)
        r, Xm, it = cone_radius(Au, Cu, mid, Xh)
        stats["power_iterations"] += it
        if r < 1.0:
            hi, Xh = mid, Xm
        else:
            lo, Xl = mid, Xm
    progress.update(lo=lo, hi=hi, stage="threshold Newton and certificate")
    if red.k > NEWTON_MAX_REDUCED:
        progress["stage"] = "power-iteration bisection"
        return _power_bisection(system, red, lo, hi, Xh, tol, stats, warnings, done)
    # 3. Newton on the threshold (plain and regularised) and 4. certificates; if Newton lands
    #    on a face of the cone (a boundary eigenvector: a lower bound only) or nothing can be
    #    certified, the power-iteration bracket is refined and Newton restarted from inside it.
    best, plain, plain_ok, p_star = None, None, False, None
    lo_seen = p_low                  # the largest lower end with (numerical) evidence
    for _round in range(4):
        start = Xl if Xl is not None else Xh
        plain = threshold_newton(Au, Cu, start, 0.5 * (lo + hi))
        stats["newton_iterations"] += plain.iterations
        lam = float(np.linalg.eigvalsh(plain.X).min()) if plain.converged else -1.0
        plain_ok = plain.converged and lo - 0.05 <= plain.p <= hi + 0.05 and lam > -1e-8
        p_star = max(plain.p, p_low) if plain_ok else None
        if p_star is not None and p_star - p_low <= NEAR_P_LOW:
            # the root sits at p_low (a single critical mode): try p_up <= p_low + tol
            best = fixed_p_certificate(system, red, p_low, plain.X, tol, stats)
            if best is not None:
                p_star = p_low
                break
        if plain_ok and p_star - p_low > NEAR_P_LOW:
            # the certificate point hi = p* + tol/2 (so that [hi - tol, hi] has the root in its
            # middle): eigenvector of G_hi, else the Stein certificate of its gain or of K*
            best = fixed_p_certificate(system, red, p_star, plain.X, tol, stats,
                                       offsets=(0.5,), gains=(plain.K,))
        if best is None and plain_ok and lam > 1e-9 * np.trace(plain.X):
            best = _regularised_certificate(system, red, plain, start, 0.5 * (lo + hi), p_star,
                                            p_low, tol, stats)
        elif best is None and plain_ok:   # singular X*: a face root, or a degenerate one
            best = fixed_p_certificate(system, red, p_star, plain.X, tol, stats)
        if best is not None:
            break
        if plain_ok and lo < p_star < hi:
            lo = p_star          # an eigenvector X* ⪰ 0 with eigenvalue 1 shows p_up >= p*
            lo_seen = max(lo_seen, p_star)
        target = max((hi - lo) / 64, 1e-3 * (hi - lo), 4 * tol)
        lo_before = lo
        lo, hi, Xl, Xh = _refine_bracket(Au, Cu, lo, hi, Xl, Xh, target, stats)
        if lo > lo_before:       # raised only by a Collatz–Wielandt bound r(lo) >= 1
            lo_seen = max(lo_seen, lo)
        progress.update(lo=lo_seen, hi=hi)
        plain_ok = False
    if best is None:
        warnings.append("no certificate could be verified; the upper end is a numerical "
                        "power-iteration estimate")
        lower = _evidence_p_low(p_low) if lo_seen <= p_low else {
            "kind": "numerical", "value": lo_seen, "certified": False,
            "statement": "a cone eigenvector with eigenvalue >= 1 (Newton root or "
                         "Collatz-Wielandt bound of the power iterate)", "p_low_theorem": p_low}
        return done(None, (lo_seen, hi), False, "undetermined", None, lower)
    hi_p, (Z, Xz, Kz), check, eps_used = best
    progress.update(stage="lower-end evidence", hi=hi_p)
    X, K = symmetrize(Z @ Xz @ Z.T), _full_gain(red, Z @ Kz)
    stats["regularisation"] = eps_used
    origin = ("cone eigenvector of the regularised noise-free MARE map (epsilon = "
              f"{eps_used:.3g}), lifted from the unstable Schur block; checked as Z X_z Z', Z K_z "
              + ("M (M the output compression) " if red.M is not None else "")
              + "with the float Schur basis Z (X, K below are rounded copies)")
    cert = _certificate_summary(system, check, X, K, origin, (Z, Xz, Kz), red.M)
    lo_p = _lower_end(hi_p, tol, p_low)
    if p_star is None:
        warnings.append("plain Newton root not found; the lower end rests on p_low only")
        lo_p = p_low
    elif p_star - p_low <= NEAR_P_LOW:
        # a root this close to p_low is not numerical evidence of p_up > p_low: the
        # eigenvector there is (near) singular — e.g. one unstable mode plus modes with
        # |λ| = 1, A = diag(1, −1, 3), C = [1 1 1], whose Newton root 0.88888890690 lay above
        # p_up = p_low = 8/9. The lower end is the theorem p_low (rounded down below).
        lo_p = p_low
    elif p_star < lo_p:
        warnings.append(f"the certificate holds only at hi = {hi_p:.12g}, more than tol above "
                        f"the Newton root {p_star:.12g}: the bracket is wider than requested")
        lo_p = max(p_low, p_star)
    lower = _lower_evidence(system, red, plain, lo_p, p_low, stats, tol) if plain_ok else \
        _evidence_p_low(p_low)
    if lower.get("inconsistent"):
        warnings.append(lower["inconsistent"])
        lo_p = p_low
        lower = _evidence_p_low(p_low)
    status = "determined" if hi_p - lo_p <= tol else "undetermined"
    return done(hi_p, (lo_p, hi_p), check.ok, status, cert, lower,
                {"X": X, "K": K, "basis": Z, "X_basis": Xz, "K_basis": Kz, "p_star": p_star,
                 "output_map": red.M})


def collatz_wielandt(A: np.ndarray, C: np.ndarray, X: np.ndarray, p: float
                     ) -> tuple[float, float]:
    """Bounds c_lo ≤ r(p) ≤ c_hi from X ≻ 0: the extreme eigenvalues of X^{-1/2} G_p(X) X^{-1/2}.

    G_p(X) ⪯ c_hi X gives r ≤ c_hi (monotone, homogeneous map); G_p(X) ⪰ c_lo X gives
    r ≥ c_lo (a sub-eigenvector). Returns (0, inf) when X is not numerically positive definite.
    """
    try:
        L = np.linalg.cholesky(X)
        G = noise_free_g(A, C, X, p, reg=NEWTON_REG * np.trace(X))
        Li = np.linalg.solve(L, np.eye(L.shape[0]))
        ev = np.linalg.eigvalsh(symmetrize(Li @ G @ Li.T))
    except np.linalg.LinAlgError:
        return 0.0, float("inf")
    return float(ev[0]), float(ev[-1])


def _refine_bracket(A, C, lo, hi, Xl, Xh, width, stats):
    """Bisection on r(p) until hi − lo ≤ width, each step decided by Collatz–Wielandt bounds of
    the power iterate (r < 1 proven numerically: hi; r ≥ 1: lo); stops when neither holds."""
    while hi - lo > width:
        mid = 0.5 * (lo + hi)
        _, Xm, it = cone_radius(A, C, mid, Xh, iterations=3000, rtol=1e-12)
        stats["power_iterations"] += it
        c_lo, c_hi = collatz_wielandt(A, C, Xm, mid)
        if c_hi < 1.0:
            hi, Xh = mid, Xm
        elif c_lo >= 1.0:
            lo, Xl = mid, Xm
        else:
            break
    return lo, hi, Xl, Xh


def _power_bisection(system: System, red: Reduced, lo: float, hi: float, Xh: np.ndarray,
                     tol: float, stats: dict[str, Any], warnings: list[str], done) -> UpperBound:
    """Large unstable blocks: bisection on r(p) by power iteration to width max(tol, 1e-6),
    with a ball-checked certificate from the power-iteration eigenvector at each feasible p."""
    width = max(tol, 1e-6)
    best = None
    while hi - lo > width:
        mid = 0.5 * (lo + hi)
        r, X, it = cone_radius(red.Au, red.Cu, mid, Xh, iterations=2000, rtol=1e-11)
        stats["power_iterations"] += it
        found = None
        if r < 1.0:
            for eps in (0.0, 1e-3 * width, 1e-6 * width):   # regularised: X ⪰ ε tr(X) I
                _, Xe, it = cone_radius(red.Au, red.Cu, mid, X, iterations=2000, rtol=1e-11,
                                        eps=eps)
                stats["power_iterations"] += it
                if float(np.linalg.eigvalsh(Xe).min()) <= 0:
                    continue
                K = optimal_gain_noise_free(red.Au, red.Cu, Xe, eps)
                Z, Xz, Kz = lift_certificate(red, system.c, Xe, K, mid)
                check = certify.verify_upper(system, mid, Xz, Kz, basis=Z, output_map=red.M)
                stats["certificate_checks"] += 1
                if check.ok:
                    found = (mid, (Z, Xz, Kz), check)
                    break
        if found is not None:
            hi, Xh, best = mid, X, found
        elif r >= 1.0:
            lo = mid
        else:
            warnings.append(f"r({mid:.9g}) = {r:.12g} < 1 but no certificate verified there; "
                            "bisection stopped")
            break
    warnings.append(f"unstable block of {red.k} states: power-iteration bisection to width "
                    f"{width:g} (Newton is used up to {NEWTON_MAX_REDUCED}); the lower end is "
                    "numerical (power iteration r(lo) >= 1 or no certificate found)")
    lower = {"kind": "numerical", "value": lo, "certified": False,
             "statement": "power iteration: r(lo) >= 1, or no certificate could be verified"}
    if best is None:
        return done(None, (lo, 1.0), False, "undetermined", None, lower)
    hi_p, (Z, Xz, Kz), check = best
    cert = _certificate_summary(system, check, Z @ Xz @ Z.T, _full_gain(red, Z @ Kz),
                                "power-iteration cone eigenvector, lifted from the unstable block",
                                (Z, Xz, Kz), red.M)
    status = "determined" if hi_p - lo <= tol else "undetermined"
    return done(hi_p, (lo, hi_p), True, status, cert, lower,
                {"X": Z @ Xz @ Z.T, "K": _full_gain(red, Z @ Kz), "basis": Z, "X_basis": Xz,
                 "K_basis": Kz, "output_map": red.M})


def _compression_note(red: Reduced) -> str:
    return (f"output compressed: C replaced by M C (rank {red.M.shape[0]}; C Z_u has condition "
            f"number > {OUTPUT_CONDITION_LIMIT:g} or dependent rows); gains checked as K M on "
            "the exact C")


def _full_gain(red: Reduced, K: np.ndarray) -> np.ndarray:
    """The gain for the original C (a rounded copy K M when the output was compressed)."""
    return K if red.M is None else K @ red.M


def optimal_gain_noise_free(A: np.ndarray, C: np.ndarray, X: np.ndarray,
                            eps: float = 0.0) -> np.ndarray:
    """K_X = −A X C' (C X C' + ε tr(X) I)^{+} (the minimiser of G^ε_p; pseudo-inverse)."""
    S = C @ X @ C.T + eps * float(np.trace(X)) * np.eye(C.shape[0])
    return -(A @ X @ C.T) @ np.linalg.pinv(S)


def _lower_end(hi: float, tol: float, p_low: float) -> float:
    """The smallest float lo ≥ max(p_low, hi − tol) with hi − lo ≤ tol (in floating point)."""
    lo = max(p_low, hi - tol)
    while hi - lo > tol:
        lo = float(np.nextafter(lo, hi))
    return lo


def _regularised_certificate(system: System, red: Reduced, plain: NewtonResult | None,
                             start: np.ndarray, p_start: float, p_star: float | None,
                             p_low: float, tol: float, stats: dict[str, Any]):
    """Continuation in ε of the regularised Newton, then a ball-checked lifted certificate.

    From a starting ε (1e-6, else 1e-4, 1e-8, 1e-3), ε goes down (at most tenfold per step, each
    solve warm-started, each eigenvector checked to be positive definite) until
    p_ε − p* ≤ tol/4 (slope dp_ε/dε estimated on the way). The certificate is tried from the
    smallest ε back. Returns (hi, (Z, X_z, K_z), check, ε) or None.
    """
    p0 = plain.p if plain is not None else p_start
    X0 = plain.X if plain is not None else start
    base = max(p_star if p_star is not None else p_start, p_low)
    for eps0 in (1e-6, 1e-4, 1e-8, 1e-3):
        good = _continuation(red, X0, p0, eps0, p_star, tol, stats)
        for eps_used, reg in reversed(good[-3:]):
            hi = float(np.nextafter(max(reg.p, p_low), 2.0))
            Z, Xz, Kz = lift_certificate(red, system.c, reg.X, reg.K, hi)
            check = certify.verify_upper(system, hi, Xz, Kz, basis=Z, output_map=red.M)
            stats["certificate_checks"] += 1
            if check.ok:
                stats["regularisation"] = eps_used
                return hi, (Z, Xz, Kz), check, eps_used
    return fixed_p_certificate(system, red, base, X0, tol, stats)


def fixed_p_certificate(system: System, red: Reduced, base: float, X0: np.ndarray, tol: float,
                        stats: dict[str, Any],
                        offsets: tuple[float, ...] = (0.5, 1.0, 10.0, 100.0, 1e4),
                        gains: tuple[np.ndarray, ...] = ()):
    """Certificate at p = base + offset·tol (offsets 1/2 … 10^4) from the cone eigenvector of
    G^ε_p (ε = 0 first): r_ε(p) < 1 with X ≻ 0 gives X − L_{K,p}(X) ⪰ (1 − r) X ≻ 0.

    That margin is (1 − r)·λ_min(X): near the threshold it can sink below the rounding of X (a
    nearly singular eigenvector, r = 1 − O(tol)). When the eigenvector check fails, the gain K
    of the eigenvector (and then each of ``gains``) is tried in :func:`stein_certificate`,
    whose margin is the identity by construction."""
    for mult in offsets:
        offset = mult * tol
        hi = float(min(base + offset, 1.0))
        stein_tried = False
        for eps in (0.0, 1e-2 * offset, 1e-4 * offset):
            X, r, K, ok = perron_newton(red.Au, red.Cu, X0 + eps * np.eye(red.k), hi, eps=eps)
            stats["newton_iterations"] += 1
            if not (ok and r < 1 and float(np.linalg.eigvalsh(X).min()) > 0):
                _, Xs, its = cone_radius(red.Au, red.Cu, hi, X0, eps=eps, iterations=2000)
                stats["power_iterations"] += its
                X, r, K, ok = perron_newton(red.Au, red.Cu, Xs, hi, eps=eps)
                stats["newton_iterations"] += 1
            if ok and r < 1 and float(np.linalg.eigvalsh(X).min()) > 0:
                Z, Xz, Kz = lift_certificate(red, system.c, X, K, hi)
                check = certify.verify_upper(system, hi, Xz, Kz, basis=Z, output_map=red.M)
                stats["certificate_checks"] += 1
                if check.ok:
                    stats["regularisation"] = eps
                    return hi, (Z, Xz, Kz), check, eps
            if not stein_tried and np.all(np.isfinite(K)):
                stein_tried = True
                bal = X if (ok and np.all(np.isfinite(X))
                            and float(np.linalg.eigvalsh(X).min()) > 0) else None
                for Kc in (K, *gains):
                    found = stein_certificate(system, red, hi, Kc, stats, balance=bal)
                    if found is not None:
                        stats["regularisation"] = eps
                        return (hi, *found, eps)
    return None


STEIN_REFINE_STEPS = 2
"""Steps of iterative refinement of the Stein solution (residual in float64, LU reused)."""


def balanced_reduction(red: Reduced, X: np.ndarray) -> tuple[Reduced, np.ndarray] | None:
    """The reduction in the coordinates x_u = T y, T T' = X (Cholesky of a positive definite X,
    normally the cone eigenvector of G_p): A_u → T⁻¹ A_u T, C_u → C_u T, T_us → T⁻¹ T_us, and
    the basis Z_u → Z_u T (a float product, used exactly by the checker like any basis).

    In these coordinates the eigenvector is the identity, so a certificate built there is as
    well conditioned as if X* were: the ill-conditioning of the eigenvector (λ_min(X*) = 4e-7
    for ``random_system(12, 4, 0)``) moves into the basis, where the ball check takes it
    exactly, instead of into the float certificate, where it meets the rounding. Returns
    (reduction, T) or None."""
    k = red.k
    try:
        Xs = symmetrize(X) / float(np.trace(X))
        Tb = np.linalg.cholesky(Xs)
        Ti = sla.solve_triangular(Tb, np.eye(k), lower=True)
    except (np.linalg.LinAlgError, ValueError, ZeroDivisionError):
        return None
    if not (np.all(np.isfinite(Tb)) and np.all(np.isfinite(Ti))):
        return None
    Tn = red.T.copy()
    Tn[:k, :k] = Ti @ red.T[:k, :k] @ Tb
    Tn[:k, k:] = Ti @ red.T[:k, k:]
    Zn = red.Z.copy()
    Zn[:, :k] = red.Z[:, :k] @ Tb
    return Reduced(Tn, Zn, k, Tn[:k, :k], red.Cu @ Tb, red.Cw, red.M), Tb


def stein_certificate(system: System, red: Reduced, p: float, K: np.ndarray,
                      stats: dict[str, Any], balance: np.ndarray | None = None):
    """Certificate at p from the gain K alone: X_u solves X_u = L_{K,p}(X_u) + I on the unstable
    block, lifted (:func:`lift_certificate`) and ball-checked (:func:`certify.verify_upper`).

    Why this is well conditioned where the eigenvector is not: with ρ(L_{K,p}) = 1 − δ the
    eigenvector X of G_p has X − L_{K,p}(X) ⪰ δ X, a margin δ·λ_min(X) that near the threshold
    (δ ~ tol, λ_min(X) ≪ 1) is at the level of the rounding of X. The Stein solution has the
    margin X_u − L(X_u) = I by construction, and its size ‖X_u‖ ~ 1/δ only scales the float
    residual, ~ u·‖X_u‖·‖I − L‖: the check has room as long as δ ≫ u (≈ 1e-16). X_u ≻ 0 with
    X_u − L(X_u) ≻ 0 holds iff ρ(L_{K,p}) < 1 (L is a positive map). The linear solve is only a
    proposal: the decision is the ball check on the exact matrices, so no solver error can make
    it pass.

    ‖X_u‖ is 1/δ only when the eigenvector of L_{K,p} is well conditioned; otherwise
    X_u = Σ L^j(I) can be far larger (1e15 for δ = 5e-10 on ``random_system(12, 4, 0)``). With
    ``balance`` = that eigenvector X the equation is solved in the coordinates of
    :func:`balanced_reduction` (there L(I) ≈ r I and X̃_u ≈ I/δ), and the unbalanced solve is
    the fallback. Returns ((Z, X_z, K_z), check) or None.
    """
    if red.k > NEWTON_MAX_REDUCED or not np.all(np.isfinite(K)):
        return None
    if balance is not None:
        bal = balanced_reduction(red, balance)
        if bal is not None:
            red_b, Tb = bal
            Kb = sla.solve_triangular(Tb, K, lower=True)     # F → T⁻¹ F T: K → T⁻¹ K
            found = stein_certificate(system, red_b, p, Kb, stats)
            if found is not None:
                stats["certificate_from"] += " (balanced by the cone eigenvector)"
                return found
    k = red.k
    Au, Cu = red.Au, red.Cu
    iu = np.triu_indices(k)
    eye = np.eye(k)
    try:
        with np.errstate(all="raise"):
            Lm = stein_matrix(Au, Cu, K, p)
            lu = sla.lu_factor(np.eye(Lm.shape[0]) - Lm, check_finite=True)
            Xu = unvech(sla.lu_solve(lu, vech(eye)), k)
            F = Au + K @ Cu
            for _ in range(STEIN_REFINE_STEPS):
                W = symmetrize(Xu - (1 - p) * Au @ Xu @ Au.T - p * F @ Xu @ F.T)
                res = eye - W
                if float(np.abs(res).max()) <= 1e-8:
                    break
                Xu = symmetrize(Xu + unvech(sla.lu_solve(lu, res[iu]), k))
    except (np.linalg.LinAlgError, FloatingPointError, ValueError, ZeroDivisionError):
        return None
    stats["newton_iterations"] += 1          # one dense solve of the vech system
    if not np.all(np.isfinite(Xu)):
        return None
    try:
        if float(np.linalg.eigvalsh(Xu).min()) <= 0:     # ρ(L_{K,p}) ≥ 1: no certificate
            return None
    except np.linalg.LinAlgError:
        return None
    Xu = Xu / float(np.trace(Xu))            # scale: immaterial to the check, tidy in the record
    Z, Xz, Kz = lift_certificate(red, system.c, Xu, K, p)
    check = certify.verify_upper(system, p, Xz, Kz, basis=Z, output_map=red.M)
    stats["certificate_checks"] += 1
    if not check.ok:
        return None
    stats["certificate_from"] = "stein: X_u = L_{K,p}(X_u) + I"
    return (Z, Xz, Kz), check


def _continuation(red: Reduced, X0: np.ndarray, p0: float, eps: float, p_star: float | None,
                  tol: float, stats: dict[str, Any]) -> list[tuple[float, NewtonResult]]:
    """The regularised Newton solutions (ε, result) along a decreasing sequence of ε."""
    _, X, its = cone_radius(red.Au, red.Cu, p0, X0, eps=eps)
    stats["power_iterations"] += its
    p = p0
    good: list[tuple[float, NewtonResult]] = []
    for _ in range(30):
        reg = threshold_newton(red.Au, red.Cu, X, p, eps=eps)
        stats["newton_iterations"] += reg.iterations
        if not (reg.converged and float(np.linalg.eigvalsh(reg.X).min()) > 0
                and reg.p >= (p_star if p_star is not None else -1.0) - 1e-12
                and reg.p <= 1.0):
            break
        good.append((eps, reg))
        X, p = reg.X, reg.p
        if p_star is None:
            if eps <= 0.02 * tol:
                break
            eps = max(0.1 * eps, 0.02 * tol)
            continue
        gap = reg.p - p_star
        if gap <= 0.25 * tol:
            break
        eps = max(0.1 * eps, 0.2 * tol * eps / gap)
    return good


def invariant_block_of(system: System, red: Reduced) -> certify.InvariantBlock | None:
    """Ball enclosure of the exact unstable invariant block for ``red`` (memoised per system)."""
    key = (id(system), id(red))
    hit = _BLOCK_CACHE.get(key)
    if hit is not None and hit[0] is system and hit[1] is red:
        return hit[2]
    block = certify.invariant_block(system, red.Z, red.k)
    _BLOCK_CACHE[key] = (system, red, block)
    while len(_BLOCK_CACHE) > 8:
        _BLOCK_CACHE.pop(next(iter(_BLOCK_CACHE)))
    return block


_BLOCK_CACHE: dict[tuple[int, int], tuple[System, Reduced, Any]] = {}

CONE_CONFIRM_MARGIN = 1e-11
"""A cone eigenvalue r(p) ≥ 1 + this (Newton-converged, PSD eigenvector) confirms p ≤ p_up
numerically."""


def cone_lower_check(system: System, red: Reduced, p: float, X0: np.ndarray | None,
                     stats: dict[str, Any] | None = None) -> dict[str, Any]:
    """Independent evidence that p ≤ p_up: the cone eigenpair (X_u, r) of G_p on the unstable
    block (power iteration, then Newton), and a ball-checked proof when possible.

    Returns {"r", "X", "numerical": r ≥ 1 + CONE_CONFIRM_MARGIN with a converged PSD
    eigenvector, "certified": the proof passed, "check", "how"}.

    Why the unstable block suffices (and is valid for the full system): the first k Schur
    vectors span an A-invariant subspace V (exactly so for the enclosed W = Z[I; P] of
    :func:`kfcrit.theory.certify.invariant_block`); for X = W X_u W' the noise-free map satisfies
    G_p(X) = W G^u_p(X_u) W', so the cone {W X_u W' : X_u ⪰ 0} is invariant and the cone
    spectral radius of the full map is at least that of G^u_p. An X_u ≻ 0 with
    G^u_p(X_u) ≻ X_u therefore gives X ⪰ 0, X ≠ 0 with G_p(X) ⪰ X, and the cone argument
    (:func:`kfcrit.theory.certify.verify_lower_block`) shows that no Y ≻ 0 has Y ≻ G_p(Y): p ≤ p_up.
    (The converse direction — that p_up of the full system equals that of the block — is the
    reduction of the module docstring; the lower bound needs only the invariance.)
    """
    stats = stats if stats is not None else {}
    out: dict[str, Any] = {"r": None, "X": None, "numerical": False, "certified": False,
                           "check": None, "how": ""}
    start = X0 if X0 is not None and np.all(np.isfinite(X0)) else None
    r, Xp, its = cone_radius(red.Au, red.Cu, p, start, iterations=3000, rtol=1e-12)
    stats["power_iterations"] = stats.get("power_iterations", 0) + its
    X, r2, _K, ok = perron_newton(red.Au, red.Cu, Xp, p)
    stats["newton_iterations"] = stats.get("newton_iterations", 0) + 1
    if not (ok and np.isfinite(r2) and float(np.linalg.eigvalsh(X).min()) > -1e-10):
        c_lo, _ = collatz_wielandt(red.Au, red.Cu, Xp, p)
        out.update(r=c_lo, X=Xp, how="Collatz-Wielandt lower bound of the power iterate")
        X, r2 = Xp, c_lo
    else:
        out.update(r=r2, X=X, how="cone eigenpair of G_p by power iteration and Newton")
    out["numerical"] = bool(r2 >= 1.0 + CONE_CONFIRM_MARGIN)
    if not out["numerical"]:
        return out
    block = invariant_block_of(system, red)
    if block is None:
        out["how"] += ("; no ball proof: the invariant subspace could not be enclosed "
                       f"(k(n-k) = {red.k * (system.n - red.k)}, limit {certify.KRONECKER_MAX})")
        return out
    for X_try in (X, X + 1e-9 * np.trace(X) * np.eye(red.k)):
        check = certify.verify_lower_block(block, p, symmetrize(X_try))
        stats["certificate_checks"] = stats.get("certificate_checks", 0) + 1
        if check.ok:
            out.update(certified=True, check=check, X=X_try)
            break
        out["check"] = check
    return out


def _lower_evidence(system: System, red: Reduced, plain: NewtonResult, lo: float, p_low: float,
                    stats: dict[str, Any], tol: float | None = None) -> dict[str, Any]:
    """The strongest evidence for p_up ≥ lo that we can check, labelled.

    p_low (theorem) when lo ≤ p_low; else the cone eigenpair (X, r) of G_lo on the unstable
    block (:func:`cone_lower_check`): r ≥ 1 supports lo numerically, and is proven when
    X_u ≻ 0, G^u_lo(X_u) − X_u ≻ 0 pass in balls on an exactly A-invariant subspace enclosed
    by :func:`kfcrit.theory.certify.invariant_block` (valid for the full system, stable modes
    included: see :func:`cone_lower_check`). When the proof fails at lo itself (its margin
    (r − 1)·λ_min(X_u) is below the ball widths), the largest of a few points lo − δ where it
    passes is reported as ``proven_lower`` (a proven p_up ≥ lo − δ beside the numerical lo).
    An eigenvalue r < 1 contradicts lo: the evidence is then marked ``inconsistent``.
    """
    if lo <= p_low:
        return _evidence_p_low(p_low)
    conf = cone_lower_check(system, red, lo, plain.X, stats)
    r = conf["r"]
    evidence: dict[str, Any] = {
        "kind": "numerical", "value": lo, "certified": False,
        "statement": ("Newton root p* of the cone spectral radius r(p) = 1 of the noise-free "
                      f"MARE map (p* = {plain.p:.15g}, residual {plain.residual:.2g}); at lo "
                      f"the cone eigenvalue of the unstable block is r(lo) = {r:.15g} >= 1, so "
                      "no X > 0 has X > G_lo(X) (numerically; " + conf["how"] + ")"),
        "p_low_theorem": p_low}
    if r is None or not np.isfinite(r):
        evidence["statement"] = (f"Newton root p* = {plain.p:.15g} of r(p) = 1 (residual "
                                 f"{plain.residual:.2g}); the eigenpair at lo did not converge")
        return evidence
    if r < 1 - 1e-12:
        return {"inconsistent": f"cone eigenvalue r({lo:.12g}) = {r:.15g} < 1 contradicts the "
                                "Newton root; the lower end falls back to p_low"}
    marginal = np.abs(np.abs(np.linalg.eigvals(red.Au)) - 1.0) <= MARGINAL_TOL
    if not conf["certified"] and np.any(marginal):
        # a mode on the unit circle makes the cone eigenvector nearly singular, and the
        # homogeneous regulariser then biases r(p) upward by more than tol (seen: r(lo) =
        # 1 + 2e-8 at a lo 1.7e-8 above a p_up proven by a certificate of the similar system)
        return {"inconsistent": f"r({lo:.12g}) = {r:.15g} ≥ 1 is not evidence here: A has a "
                                "mode with |λ| ≈ 1 in the unstable block, where the "
                                "regularised cone eigenvalue is biased upward; the lower end "
                                "falls back to p_low"}
    if conf["certified"]:
        check = conf["check"]
        evidence.update({"kind": "certificate", "certified": True,
                         "statement": "X_u > 0 with G_lo(X_u) - X_u > 0 (cone eigenvalue "
                                      f"{r:.15g} > 1 of the noise-free MARE map) on the "
                                      f"{red.k}-dimensional unstable invariant subspace, proven "
                                      "in ball arithmetic; valid for the full system because "
                                      "G_p maps the cone of that subspace into itself",
                         "check": check.to_dict()})
        if system.n <= RECORD_MATRIX_MAX:
            evidence["X_u"] = _matrix_list(conf["X"])
            evidence["basis"] = _matrix_list(red.Z)
            evidence["reduced_states"] = red.k
    elif conf["numerical"] and conf["check"] is not None:
        step = max(tol if tol is not None else 1e-9, 1e-12)
        for mult in (1, 10, 100, 1000):
            p = lo - mult * step
            if p <= p_low:
                break
            c2 = cone_lower_check(system, red, p, conf["X"], stats)
            if c2["certified"]:
                evidence["proven_lower"] = {
                    "value": p, "check": c2["check"].to_dict(),
                    "statement": f"p_up >= {p!r} proven: X_u > 0 with G_p(X_u) - X_u > 0 on "
                                 "the unstable invariant subspace, ball arithmetic (at lo "
                                 "itself the margin was below the ball widths: "
                                 f"{conf['check'].reason})"}
                break
    return evidence


def _matrix_list(M: np.ndarray) -> list[list[float]]:
    """A float matrix as nested lists (JSON floats round-trip exactly)."""
    return [[float(v) for v in row] for row in np.atleast_2d(M)]


def _certificate_summary(system: System, check: certify.CheckResult, X: np.ndarray,
                         K: np.ndarray, origin: str, basis: tuple | None = None,
                         output_map: np.ndarray | None = None) -> dict[str, Any]:
    """The record's certificate: what was proven, how, and (n ≤ RECORD_MATRIX_MAX) the matrices.

    A certificate checked in a basis (X = Z X_z Z', K = Z K_z, times M with an output map) is
    included exactly as checked (``basis``, ``X_basis``, ``K_basis``, ``output_map``), so the
    record alone re-verifies; the rounded full-state copies ``X``, ``K`` are re-checked directly
    (``matrices_verified``) — they may fail on their own when the margin is below the rounding.
    """
    out = {"kind": "X > 0 and X - L_{K,hi}(X) > 0 (Sinopoli Thm 5, Psi_hi(X^-1, X^-1 K) > 0)",
           "origin": origin, **check.to_dict()}
    if system.n <= RECORD_MATRIX_MAX:
        out["X"] = _matrix_list(X)
        out["K"] = _matrix_list(K)
        direct = check if basis is None else certify.verify_upper(system, check.p, X, K)
        out["matrices_verified"] = direct.ok
        if basis is not None:
            for name, M in zip(("basis", "X_basis", "K_basis"), basis):
                out[name] = _matrix_list(M)
            if output_map is not None:
                out["output_map"] = _matrix_list(output_map)
        out["reverify"] = ("X = basis X_basis basis', K = basis K_basis (output_map): check "
                           "X > 0 and X - (1-p) A X A' - p F X F' > 0, F = A + K C, p = the "
                           "certificate's p, exactly" if basis is not None else
                           "check X > 0 and X - (1-p) A X A' - p F X F' > 0, F = A + K C, "
                           "p = the certificate's p, exactly")
    return out


# ---------------------------------------------------------------------------------------------
# public interface
# ---------------------------------------------------------------------------------------------


METHODS = ("auto", "newton", "lmi")


def upper_bound(system: System, tol: float = 1e-9, method: str = "auto") -> UpperBound:
    """Upper bound p_up on the critical arrival probability with a bracket [lo, hi], hi − lo ≤ tol.

    Parameters
    ----------
    system : System
    tol : float
        Requested width of the bracket.
    method : {"auto", "newton", "lmi"}
        "newton" — cone-spectral-radius Newton with a lifted, ball-checked certificate (fast);
        "lmi" — Sinopoli's Ψ_p LMI bisection (cvxpy + Clarabel); "auto" — "newton", falling
        back to "lmi" if Newton gives no certified bracket.

    Returns
    -------
    UpperBound
        ``certified`` is True only if the upper end ``hi`` passed :func:`certify.verify_upper`.
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    key = ((sp.srepr(system.A), sp.srepr(system.C)) if system.exact else
           (system.a.tobytes(), system.c.tobytes(), system.a.shape, system.c.shape),
           float(tol), method)
    if key in _CACHE:
        return _CACHE[key]
    progress: dict[str, Any] = {}
    t0 = time.perf_counter()
    try:
        result = replace(_upper_bound(system, tol, method, progress), tolerance=float(tol))
    except Exception as exc:              # noqa: BLE001 — re-raised unless numerical
        if not is_numerical_failure(exc):
            raise
        return _failure_record(system, tol, method, exc, progress, time.perf_counter() - t0)
    _CACHE[key] = result
    while len(_CACHE) > 16:
        _CACHE.pop(next(iter(_CACHE)))
    return result


def numerical_failure_types() -> tuple[type[BaseException], ...]:
    """The exceptions that mean "the numerics failed" (not a bug, not bad input): LinAlgError,
    FloatingPointError / ZeroDivisionError / OverflowError (ArithmeticError), ValueError (scipy
    solvers raise it for non-finite or ill-posed data) and, when cvxpy has been loaded,
    its SolverError."""
    types: list[type[BaseException]] = [np.linalg.LinAlgError, ArithmeticError, ValueError]
    cp_error = getattr(sys.modules.get("cvxpy.error"), "SolverError", None)
    if isinstance(cp_error, type):
        types.append(cp_error)
    return tuple(types)


def is_numerical_failure(exc: BaseException) -> bool:
    return isinstance(exc, numerical_failure_types())


def _failure_record(system: System, tol: float, method: str, exc: BaseException,
                    progress: dict[str, Any], seconds: float) -> UpperBound:
    """The ``undetermined`` record of a computation stopped by a numerical failure: the bracket
    reached so far (the lower end from p_low, or a numerical cone-radius bound; the upper end 1
    or a numerical power-iteration estimate — neither certified) and a warning naming the
    failure. Not memoised (the failure may be transient)."""
    try:
        p_low = p_low_bounds(system).down
    except Exception as exc2:             # noqa: BLE001
        if not is_numerical_failure(exc2):
            raise
        try:
            p_low = p_low_of(system.a)
        except Exception:                 # noqa: BLE001
            p_low = 0.0
    lo = float(progress.get("lo", p_low))
    hi = float(progress.get("hi", 1.0))
    if not (np.isfinite(lo) and np.isfinite(hi) and p_low <= lo <= hi <= 1.0):
        lo, hi = p_low, 1.0
    lower = _evidence_p_low(p_low) if lo <= p_low else {
        "kind": "numerical", "value": lo, "certified": False,
        "statement": "power-iteration bracket reached before the numerical failure (cone "
                     "spectral radius r(lo) >= 1 of the noise-free MARE map, numerically)",
        "p_low_theorem": p_low}
    name = type(exc).__name__
    text = str(exc).strip().splitlines()[0][:200] if str(exc).strip() else "(no message)"
    stage = progress.get("stage", "start")
    warning = (f"upper bound undetermined: numerical failure ({name}: {text}) in the "
               f"{method} method at stage '{stage}'; the bracket [{lo:.12g}, {hi:.12g}] is the "
               "one reached so far, not certified")
    solver = {"seconds": seconds, "solves": 0, "failure": name, "failure_message": text,
              "failure_stage": stage}
    return UpperBound(None, (lo, hi), False, "undetermined",
                      progress.get("method", "newton" if method != "lmi" else "lmi"), None,
                      lower, solver, (warning,), {}, float(tol))


_CACHE: dict[tuple, UpperBound] = {}
"""Memo of results (immutable records) by exact (A, C), tol and method: p_up depends on A and C
only, and the covariance-bound and static-gain sections ask for it again."""


def _upper_bound(system: System, tol: float, method: str,
                 progress: dict[str, Any] | None = None) -> UpperBound:
    result = _upper_bound_raw(system, tol, method, {} if progress is None else progress)
    # the LMI works to max(tol, 1e-7): judge its width by the tolerance it used
    used = max(tol, 1e-7) if result.method == "lmi" else tol
    return _exact_lower_end(system, result, used)


def _exact_lower_end(system: System, result: UpperBound, tol: float) -> UpperBound:
    """Invariant: a lower end that rests on Sinopoli's p_low (evidence kind "theorem") is the
    exact p_low rounded down, and the interval always contains p_up (the upper end, when it
    is p_low itself, is rounded up)."""
    if result.lower_evidence.get("kind") != "theorem" or result.method == "exact":
        return result
    pl = p_low_bounds(system)
    lo, hi = result.interval
    hi = max(hi, pl.up)
    lower = {**result.lower_evidence, "value": pl.down, "certified": pl.rigorous,
             "p_low_enclosure": [pl.down, pl.up], "p_low_how": pl.how}
    if pl.expression is not None:
        lower["expression"] = pl.expression
    status = result.status
    # the rounding moves the lower end by a few ulps at most: allowed beyond tol
    if status == "determined" and hi - pl.down > tol + 8 * math.ulp(max(hi, 1e-300)) \
            and hi - pl.down > hi - lo:
        status = "undetermined"
    return replace(result, interval=(pl.down, hi), lower_evidence=lower, status=status)


def _upper_bound_raw(system: System, tol: float, method: str,
                     progress: dict[str, Any]) -> UpperBound:
    if method != "lmi":
        progress["stage"] = "C invertible test"
        inv, how = c_invertible(system)
        if inv:
            return _c_invertible_bound(system, how)
    if method == "lmi":
        from kfcrit.theory.lmi import lmi_upper_bound
        progress.update(stage="LMI bisection", method="lmi")
        return lmi_upper_bound(system, tol=max(tol, 1e-7))
    result = _newton_method(system, tol, progress)
    if result.extras.get("not_applicable"):
        return result            # not detectable: no LMI fallback (it cannot succeed either)
    if method == "auto" and not result.certified and system.n <= 30:
        from kfcrit.theory.lmi import lmi_upper_bound
        progress.update(stage="LMI fallback", method="lmi")
        alt = lmi_upper_bound(system, tol=max(tol, 1e-7))
        if alt.certified:
            width_ok = alt.interval[1] - alt.interval[0] <= tol
            return replace(alt, status=alt.status if width_ok else "undetermined",
                           warnings=result.warnings
                           + ("newton method gave no certificate; LMI used ("
                              + alt.solver.get("ends", "ends not stated") + ")",)
                           + alt.warnings)
    return result


def upper_section(system: System, tol: float = 1e-9) -> dict[str, Any]:
    """``upper_bound(system, tol).to_dict()``; numerical trouble gives status "undetermined"."""
    try:
        return upper_bound(system, tol=tol).to_dict()
    except (np.linalg.LinAlgError, ValueError, ArithmeticError, RuntimeError) as exc:
        p_low = p_low_bounds(system).down
        return UpperBound(None, (p_low, 1.0), False, "undetermined", "newton", None,
                          _evidence_p_low(p_low), {}, (f"numerical failure: {exc}",)).to_dict()
