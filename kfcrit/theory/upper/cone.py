"""Numerics of the noise-free MARE map on the unstable block: reduction, cone spectral radius,
Newton on the threshold, lifting a reduced certificate to the full state.

The noise-free MARE map is

.. math::

    G_p(X) = A X A' - p\\, A X C' (C X C')^{-1} C X A' = \\min_K L_{K,p}(X),
    \\qquad L_{K,p}(X) = (1-p) A X A' + p (A+KC) X (A+KC)',

monotone, concave and positively homogeneous on the PSD cone; p_up is where its cone spectral
radius r(p) crosses 1 (docs/theory.md §3). Nothing here proves anything: the proofs are the ball
checks of :mod:`kfcrit.theory.upper.certify`, driven by :mod:`kfcrit.theory.upper.certs`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from kfcrit.model.system import System
from kfcrit.theory.covariance.riccati import noise_free_g, stein_matrix, symmetrize, unvech, vech
from kfcrit.theory.upper import certify

UNSTABLE_TOL = 1e-9
"""Modes with |λ| ≥ 1 − UNSTABLE_TOL are kept in the reduced system."""
NEWTON_MAX_REDUCED = 60
"""Largest unstable block for the dense Newton (its Jacobian has (k(k+1)/2 + 1)² entries)."""


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


OUTPUT_SCALE_FLOOR = 1e-2
"""Scale rule for the reduced output: a least singular value of C Z_u below this is compressed
too. The regulariser 1e-15·tr X added to C X C' is relative to tr X, so against C X C' ~ σ² tr X
it biases the map by ~1e-15/σ² (seen: C = [[0, 6.1e-5]] moved the Newton root 3.6e-7 above
p_up = 15/16 for A = 2·rotation(1))."""


def reduce_system(system: System, tol: float = UNSTABLE_TOL) -> Reduced:
    """:func:`reduce_unstable` of (A, C), with the output compressed when C Z_u is
    ill-conditioned.

    p_up depends on the row space of the reduced output C Z_u only (K C = (K M⁻¹)(M C)), but
    the methods do not: a tiny singular value of C Z_u is swamped by their homogeneous
    regulariser (1e-15·tr X added to C X C') and by the LMI solver's tolerances, so an
    ill-conditioned output behaves as if it had fewer rows — the audit case A = [[0,−2],[2,0]],
    C = diag(1, 1e-12) gave a "determined" bracket around 0.9375 for p_up = 0.75.
    Conditioning rule: when σ_max/σ_min of C Z_u exceeds ``OUTPUT_CONDITION_LIMIT``, or σ_min
    is below ``OUTPUT_SCALE_FLOOR``, or its rows are dependent (numerical rank r < m by NumPy's
    rule σ_i > max(m, k)·eps·σ_max), the methods use M C with M = diag(1/σ_1..1/σ_r) U_r'
    (then M C Z_u has orthonormal rows).
    M C is formed exactly in balls from the exact C and rounded once, and every certificate
    is checked with the gain K_w M on the exact C (:func:`kfcrit.theory.upper.certify.verify_upper`,
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
    well_scaled = sv[r - 1] >= OUTPUT_SCALE_FLOOR
    if r == m and sv[r - 1] * OUTPUT_CONDITION_LIMIT >= sv[0] and well_scaled:
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
                     max_iterations: int = 40, atol: float = 1e-14,
                     floor: float = NEWTON_REG) -> NewtonResult:
    """Newton on G^ε_p(X) = X, tr X = 1 in (X, p) (see the module docstring).

    G^ε_p(X) = A X A' + εt I − p A X C'(C X C' + εt I)^{-1} C X A', t = tr X. Its Jacobian in X
    is L_{K,p}(dX) + ε tr(dX) (I + p K K') with K the optimal gain; in p, −A X C' S^{-1} C X A'.
    ``floor`` (times t) is the least regulariser of C X C' (:data:`NEWTON_REG`; varied by
    :func:`root_error`).
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
        S = C @ X @ C.T + max(eps, floor) * t * np.eye(m)   # keep S invertible
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


ROOT_CHECK_FACTOR = 10.0
"""The regulariser floors of the two extra threshold Newtons of :func:`root_error` are this
and its square times :data:`NEWTON_REG`."""
ROOT_CHECK_LEAST_EXPONENT = 0.25
"""The least exponent α of the regulariser bias a δ^α that :func:`root_error` assumes (a
defective cone eigenvalue of multiplicity k gives α = 1/k)."""


def root_error(A: np.ndarray, C: np.ndarray, root: NewtonResult, slack: float,
               factor: float = ROOT_CHECK_FACTOR) -> tuple[float, int]:
    r"""Estimated error of the threshold root p* from its shifts d_1, d_2 when the
    regulariser floor δ = :data:`NEWTON_REG` of C X C' is multiplied by f and f²
    (f = ``factor``; Newton warm-started at the root).

    The floor biases p* by b(δ) = a δ^α: α = 1 for a well-conditioned eigenvector, α < 1 where
    the eigenvector sits on a face of the cone or the cone eigenvalue is defective (several
    blocks crossing 1 together; rounding of size u then moves p* by ~u^α as well). The shifts
    give g = f^α and b(δ):

    .. math::

        d_k = b(f^k δ) - b(δ), \qquad rac{d_2}{d_1} = g + 1, \qquad
        |b(δ)| = rac{|d_2|}{g^2 - 1},

    with g at most f. The returned error is twice |b(δ)| (the bias plus a rounding error of
    the same order). Shifts that fit no such bias (g < f^{1/4},
    :data:`ROOT_CHECK_LEAST_EXPONENT`, or of opposite signs) come from elsewhere — Newton
    stopped early at a singular root, where it converges linearly, or rounding: the error is
    then 2 max |d_k| if that is within ``slack``, else unknown (inf). Seen: A with the
    eigenvalues 2 ± i, −2 ± i and one block seen through one output (p_up = 24/25 exactly)
    gave p* = 24/25 + 1.5e-8 with d_1 = 3.1e-8, d_2 = 1.3e-7 (α ≈ 1/2);
    ``random_system(12, 4, 0)`` has α = 1 and |b(δ)| = 2.3e-11; A = 2·rotation ⊕ 1 with one
    output (p_up = 15/16) had p* = 15/16 + 8.3e-9 and d_1 = d_2 = −4.2e-9 (a singular root).
    Returns (error, Newton iterations); the error is inf also when a Newton does not converge.
    """
    shifts: list[float] = []
    iterations = 0
    X, p = root.X, root.p
    for k in (1, 2):
        alt = threshold_newton(A, C, X, p, floor=factor ** k * NEWTON_REG)
        iterations += alt.iterations
        if not (alt.converged and np.isfinite(alt.p)):
            return float("inf"), iterations
        shifts.append(alt.p - root.p)
        X, p = alt.X, alt.p
    d1, d2 = shifts
    if d2 == 0.0:
        return 0.0, iterations
    g = factor if d1 == 0.0 else d2 / d1 - 1.0
    if g < factor ** ROOT_CHECK_LEAST_EXPONENT:
        spread = 2.0 * max(abs(d1), abs(d2))
        return (spread if spread <= slack else float("inf")), iterations
    g = min(g, factor)
    return 2.0 * abs(d2) / (g * g - 1.0), iterations


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




def lift_certificate(red: Reduced, C: np.ndarray, Xu: np.ndarray, Ku: np.ndarray,
                     p: float, Ys: np.ndarray | None = None
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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
        Ys = stable_gramian(red) if Ys is None else Ys
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


def stable_gramian(red: Reduced) -> np.ndarray:
    """Y_s = T_ss Y_s T_ss' + I of the stable Schur block (the same for every lift of one
    reduction: pass it to :func:`lift_certificate` when lifting many times)."""
    k, n = red.k, red.T.shape[0]
    return sla.solve_discrete_lyapunov(red.T[k:, k:], np.eye(n - k))


MARGINAL_TOL = 1e-6
"""| |λ| − 1 | below this marks a mode of the unstable block as marginal (see
:func:`lower_evidence`: numerical lower-end evidence is not accepted there)."""
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


def refine_bracket(A, C, lo, hi, Xl, Xh, width, stats):
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




def full_gain(red: Reduced, K: np.ndarray) -> np.ndarray:
    """The gain for the original C (a rounded copy K M when the output was compressed)."""
    return K if red.M is None else K @ red.M


def optimal_gain_noise_free(A: np.ndarray, C: np.ndarray, X: np.ndarray,
                            eps: float = 0.0) -> np.ndarray:
    """K_X = −A X C' (C X C' + ε tr(X) I)^{+} (the minimiser of G^ε_p; pseudo-inverse)."""
    S = C @ X @ C.T + eps * float(np.trace(X)) * np.eye(C.shape[0])
    return -(A @ X @ C.T) @ np.linalg.pinv(S)




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




FLOAT_SCREEN_MARGIN = 1e-10
"""Least equilibrated float64 margin of X − L_{K,p}(X) for a certificate to go to the ball check."""


def float_upper_margin(system: System, p: float, Z: np.ndarray, Xz: np.ndarray,
                       Kz: np.ndarray, output_map: np.ndarray | None = None) -> float:
    r"""λ_min(D (X − L_{K,p}(X)) D) in float64, X = Z X_z Z', K = Z K_z (M), D = diag^{-1/2}:
    a cheap screen before the ball check (−inf when X is not positive definite).

    .. math::

        X - (1-p) A X A' - p F X F', \qquad F = A + K C
    """
    A, C = system.a, system.c
    X = symmetrize(Z @ Xz @ Z.T)
    K = Z @ Kz if output_map is None else Z @ Kz @ output_map
    F = A + K @ C
    D = symmetrize(X - (1 - p) * A @ X @ A.T - p * F @ X @ F.T)
    for M in (X, D):
        d = np.diag(M)
        if not (np.all(np.isfinite(M)) and np.all(d > 0)):
            return float("-inf")
    s = 1.0 / np.sqrt(np.diag(D))
    sx = 1.0 / np.sqrt(np.diag(X))
    if float(np.linalg.eigvalsh(sx[:, None] * X * sx[None, :]).min()) <= 0:
        return float("-inf")
    return float(np.linalg.eigvalsh(s[:, None] * D * s[None, :]).min())
