"""A certified lower end p_up ≥ lo for an interior root of a large unstable block, proven in
verified float64 (docs/theory.md §3, "Certified lower end for large blocks"; beyond the papers).

Principle: if some Y ⪰ 0, Y ≠ 0 has G_lo(Y) ⪰ Y for the noise-free MARE map G, no gain K and
X ≻ 0 have X ≻ L_{K,lo}(X) (L_{K,lo}(Y) ⪰ G_lo(Y) for every K, so L^j(Y) ⪰ Y could not decay),
hence p_up ≥ lo. Such a Y lives on the unstable invariant subspace of A, which is enclosed
without any large Sylvester inverse:

1. a real eigendecomposition A S ≈ S D (D block diagonal with normal 1 × 1 and 2 × 2 blocks
   [[α, β], [−β, α]], unstable modes first) and a verified approximate inverse R of S;
2. B = S⁻¹ A S = D + F with ‖F_ij‖ enclosed blockwise (the unstable columns of A S − S D by
   compensated products, F = (I − N)⁻¹ R (A S − S D), ‖N‖ = ‖I − R S‖ < 1);
3. one correction step Φ̃ (D_s Φ̃ − Φ̃ D_u = −mid F_su) and Stewart's theorem on
   B' = P⁻¹BP, P = [[I, 0], [Φ̃, I]]: the Sylvester operator Φ ↦ Φ D_u − D_s Φ is normal with
   separation min |λ_u − λ_s|, so the exact unstable subspace is span S [I; Φ̃ + Φ] with
   ‖Φ‖_F ≤ 2‖B'_su‖_F / δ, δ = min|λ_u − λ_s| − ‖B'_uu − D_u‖ − ‖B'_ss − D_s‖, when
   4‖B'_su‖‖F_us‖ < δ²; on it A acts as T = B'_uu + F_us Φ and C as C S_u + C S_s (Φ̃ + Φ):
   every quantity lies in a ball of verified radius around (T₀, C₀) = (D_u, C S_u + C S_s Φ̃);
4. Y solves Y − L_{K,lo}(Y) = −I on (T₀, C₀) (K the gain of the threshold eigenvector, so
   G_lo(Y) − Y ≈ I), and G^{(T,C)}_lo(Y) − Y ⪰ 0 is proven for every (T, C) in the balls:
   the midpoint matrix in midpoint-radius arithmetic minus a scalar perturbation bound
   (Weyl) is shown positive definite by the Cholesky residual bound of
   :func:`kfcrit.theory.upper.floatcheck.verified_definite_margin`.

Nothing numerical here proves anything by itself: the decision is :func:`verify_lower_ball`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg as sla

from kfcrit.theory.covariance.riccati import symmetrize
from kfcrit.theory.upper import floatcheck as fc
from kfcrit.theory.upper import krylov
from kfcrit.theory.upper.floatcheck import Interval

SAFE = 1.0 + 1e-12
"""Factor covering the rounding of a scalar bound computed from a few float operations."""
NEUMANN_MAX = 0.25
"""Largest proven ‖I − R S‖ accepted (the Neumann factor ν/(1 − ν) stays below 1/3)."""


@dataclass(frozen=True)
class PairBall:
    """The exact unstable pair (T, C) of A (an exactly A-invariant subspace S [I; Φ]):
    ‖T − T₀‖₂ ≤ ``tau``, ‖C − C₀‖₂ ≤ ``gamma``; the other fields describe the enclosure."""

    T0: np.ndarray
    C0: np.ndarray
    tau: float
    gamma: float
    k: int
    condition: float
    """Estimated 2-norm condition number of the eigenvector matrix S (informative)."""
    gap: float
    """Proven lower bound on min |λ_u − λ_s| over the eigenvalues of D."""
    neumann: float
    """Proven upper bound on ‖I − R S‖₂."""
    phi: float
    """Proven upper bound on ‖Φ‖_F."""


def _frob(M: np.ndarray) -> float:
    return fc._frob_up(M)


def _abs_up(a: Interval) -> np.ndarray:
    """Entrywise upper bound of |M| for M in the interval (float addition rounded up)."""
    return (np.abs(a[0]) + a[1]) * (1.0 + 2 * fc.U)


def spectral_norm_up(a: Interval) -> float:
    r"""Upper bound on ‖M‖₂ for every M in the interval: β with βI − M'M ⪰ 0 proven
    (:func:`kfcrit.theory.upper.floatcheck.verified_definite_margin`), else the bound
    √(‖M‖₁‖M‖_∞) of the entrywise upper bound |M|.

    .. math::  \|M\|_2^2 = \lambda_{\max}(M'M) \le \beta
    """
    absm = _abs_up(a)
    crude = math.sqrt(float(absm.sum(axis=0).max(initial=0.0))
                      * float(absm.sum(axis=1).max(initial=0.0))) * SAFE
    m, n = a[0].shape
    P = fc.mul(fc.transpose(a), a) if n <= m else fc.mul(a, fc.transpose(a))
    top = float(np.linalg.eigvalsh(0.5 * (P[0] + P[0].T))[-1]) if P[0].size else 0.0
    beta = top * (1.0 + 1e-8) + _frob(P[1]) * 2.0 + 1e-300
    N = P[0].shape[0]
    shifted = fc.add((beta * np.eye(N), np.zeros((N, N))), P, -1.0)
    if fc.verified_definite_margin(shifted) is not None:
        return min(math.sqrt(beta) * SAFE, crude)
    return crude


def real_eigenbasis(a: np.ndarray, unstable_tol: float
                    ) -> tuple[np.ndarray, np.ndarray, int] | None:
    """(S, D, k): A S ≈ S D with D real block diagonal (1 × 1 blocks for real eigenvalues,
    [[α, β], [−β, α]] for α ± iβ), the k modes with |λ| ≥ 1 − ``unstable_tol`` first.

    For a complex pair the eigenvector v of α + iβ (β > 0) is rotated so that Re v ⟂ Im v and
    scaled to ‖v‖ = √2; then A [Re v, Im v] = [Re v, Im v] [[α, β], [−β, α]]. None when NumPy
    does not return the conjugate pairs side by side.
    """
    w, V = np.linalg.eig(a)
    n = a.shape[0]
    cols: list[tuple[bool, np.ndarray, np.ndarray]] = []
    cut = (1.0 - unstable_tol) ** 2
    i = 0
    while i < n:
        lam = w[i]
        unstable = lam.real * lam.real + lam.imag * lam.imag >= cut
        if lam.imag == 0.0:
            v = V[:, i].real
            cols.append((unstable, (v / np.linalg.norm(v))[:, None], np.array([[lam.real]])))
            i += 1
            continue
        if i + 1 >= n or w[i + 1] != np.conj(lam) or lam.imag < 0:
            return None
        v = V[:, i]
        v = v * np.exp(-0.5j * np.angle(v @ v))
        v = v * (math.sqrt(2.0) / np.linalg.norm(v))
        al, be = lam.real, lam.imag
        cols.append((unstable, np.stack([v.real, v.imag], axis=1),
                     np.array([[al, be], [-be, al]])))
        i += 2
    ordered = [c for c in cols if c[0]] + [c for c in cols if not c[0]]
    S = np.hstack([c[1] for c in ordered])
    D = np.zeros((n, n))
    j = 0
    for _, _, blk in ordered:
        b = blk.shape[0]
        D[j:j + b, j:j + b] = blk
        j += b
    k = sum(c[1].shape[1] for c in ordered if c[0])
    return S, D, k


def block_eigenvalues(D: np.ndarray, lo: int, hi: int) -> np.ndarray:
    """The eigenvalues α + i|β| of the diagonal blocks of D in rows lo..hi (one per block)."""
    out = []
    j = lo
    while j < hi:
        if j + 1 < hi and D[j, j + 1] != 0.0:
            out.append(complex(D[j, j], abs(D[j, j + 1])))
            j += 2
        else:
            out.append(complex(D[j, j], 0.0))
            j += 1
    return np.array(out)


def separation_lower(D: np.ndarray, k: int) -> float:
    r"""Lower bound on min |λ_u − λ_s| over the eigenvalues of the diagonal blocks of D
    (unstable: the first k rows), each pair α ± iβ taken on both sides.

    .. math::  |\lambda_u - \lambda_s| \ge \sqrt{(\alpha_u - \alpha_s)^2
        + (|\beta_u| - |\beta_s|)^2}

    (the nearer of the two conjugates); the float evaluation is rounded down by 1e-13.
    """
    lu, ls = block_eigenvalues(D, 0, k), block_eigenvalues(D, k, D.shape[0])
    if lu.size == 0 or ls.size == 0:
        return math.inf
    da = lu.real[:, None] - ls.real[None, :]
    db = np.abs(lu.imag)[:, None] - np.abs(ls.imag)[None, :]
    return float(np.sqrt(da * da + db * db).min()) * (1.0 - 1e-13)


def enclose_unstable_pair(a: np.ndarray, c: np.ndarray, S: np.ndarray, D: np.ndarray, k: int,
                          a_off: fc.Offsets, c_off: fc.Offsets) -> tuple[PairBall | None, str]:
    r"""Balls around (D_u, C S_u) holding the exact pair (T, C_e) of A and C on its unstable
    invariant subspace (module docstring, steps 1–3), for the exact A = a + a_lo ± a_rad and
    C = c + c_lo ± c_rad (:func:`kfcrit.theory.upper.floatcheck.exact_offsets`). Returns
    (ball, "proven") or (None, reason).

    .. math::

        \|T - D_u\|_2 \le \|F_{uu}\|_F + \|F_{us}\|_F\,\varphi, \qquad
        \|C_e - C S_u\|_2 \le \|\mathrm{rad}(C S_u)\|_F + \|C S_s\|_F\,\varphi, \qquad
        \varphi = \frac{2\|F_{su}\|_F}{\delta}
    """
    n = a.shape[0]
    if not 0 < k < n:
        return None, "no stable block to separate" if k == n else "no unstable block"
    A, Cx = fc.offset_interval(a, a_off), fc.offset_interval(c, c_off)
    u, s = slice(0, k), slice(k, n)
    # unstable columns of A S − S D by compensated products: [a, a_lo, −S_u] [S_u; S_u; D_uu]
    a_ext = np.hstack([a, a_off[0]]) if np.any(a_off[0]) else a
    reps = 2 if np.any(a_off[0]) else 1
    Eu = fc.accurate_product(np.hstack([a_ext, -S[:, u]]),
                             np.vstack([S[:, u]] * reps + [D[u, u]]))
    if np.any(a_off[1]):
        Eu = (Eu[0], fc._up(Eu[1] + a_off[1] @ np.abs(S[:, u]) * (1 + fc.gamma(n + 2)), n))
    Es = fc.add(fc.mul(A, fc.point(S[:, s])), fc.mul(fc.point(S[:, s]), fc.point(D[s, s])),
                -1.0)
    R = np.linalg.inv(S)
    Nm = fc.add(fc.point(np.eye(n)), fc.mul(fc.point(R), fc.point(S)), -1.0)
    nu = spectral_norm_up(Nm)
    if not nu < NEUMANN_MAX:
        return None, f"eigenvector matrix not proven invertible (||I - RS|| <= {nu:.2g})"
    f = nu / (1.0 - nu) * SAFE
    Gu, Gs = fc.mul(fc.point(R), Eu), fc.mul(fc.point(R), Es)
    au, as_ = _abs_up(Gu), _abs_up(Gs)
    cu, cs = _frob(au), _frob(as_)
    # F[:, J] = G[:, J] + N (I − N)⁻¹ G[:, J]: each block within f‖G[:, J]‖_F of G's block
    Fuu, Fsu = (_frob(au[u]) + f * cu) * SAFE, (_frob(au[s]) + f * cu) * SAFE
    Fus, Fss = (_frob(as_[u]) + f * cs) * SAFE, (_frob(as_[s]) + f * cs) * SAFE
    # one Newton step on the subspace: Φ̃ with D_s Φ̃ − Φ̃ D_u = −mid(F_su), then Stewart on
    # B' = P⁻¹ B P, P = [[I, 0], [Φ̃, I]] (exact), whose lower-left block is second order
    Dss, Duu = D[s, s], D[u, u]
    Ft = Gu[0][s]
    Phit = sla.solve_sylvester(Dss, -Duu, -Ft)
    if not np.all(np.isfinite(Phit)):
        return None, "the subspace correction is not finite"
    Pt = fc.point(Phit)
    resid = fc.add(fc.add(fc.mul(fc.point(Dss), Pt), fc.mul(Pt, fc.point(Duu)), -1.0),
                   fc.point(Ft))
    pt = _frob(np.abs(Phit))
    unc = (_frob(Gu[1][s]) + f * cu) * SAFE              # ‖F_su − mid(F_su)‖_F
    b_su = (unc + _frob(_abs_up(resid)) + Fss * pt + pt * Fuu + pt * pt * Fus) * SAFE
    e_uu, e_ss = (Fuu + Fus * pt) * SAFE, (Fss + pt * Fus) * SAFE
    gap = separation_lower(D, k)
    delta = (gap - e_uu - e_ss) * (1.0 - 1e-15)
    if not (delta > 0 and 4.0 * b_su * Fus * SAFE < delta * delta):
        return None, (f"Stewart's condition fails: gap {gap:.3g}, ||F_uu|| {Fuu:.2g}, "
                      f"||F_ss|| {Fss:.2g}, ||F_su|| {Fsu:.2g}, ||F_us|| {Fus:.2g}")
    phi = 2.0 * b_su / delta * SAFE
    tau = (e_uu + Fus * phi) * SAFE
    CSu = fc.offset_product(c, c_off, S[:, u])
    CSs = fc.mul(Cx, fc.point(S[:, s]))
    C0 = fc.add(CSu, fc.mul(CSs, Pt))
    gamma = (_frob(C0[1]) + _frob(_abs_up(CSs)) * phi) * SAFE
    cond = float(np.linalg.norm(S, 2) * np.linalg.norm(R, 2))
    return PairBall(Duu.copy(), C0[0], tau, gamma, k, cond, gap, nu, phi), "proven"


@dataclass(frozen=True)
class LowerCheck:
    """The outcome of :func:`verify_lower_ball`: ``ok`` when G_p(Y) − Y ⪰ 0 is proven for
    every pair in the ball; ``margin`` is the proven least eigenvalue of the equilibrated
    midpoint matrix after the shift ``perturbation`` (the Weyl bound of the ball)."""

    ok: bool
    p: float
    min_eig_y: float | None
    """Proven lower bound on the least eigenvalue of the equilibrated Y."""
    margin: float | None
    perturbation: float | None
    reason: str


def verify_lower_ball(ball: PairBall, p: float, Y: np.ndarray) -> LowerCheck:
    r"""Prove Y ≻ 0 and G^{(T,C)}_p(Y) − Y ⪰ 0 for every (T, C) with ‖T − T₀‖ ≤ τ,
    ‖C − C₀‖ ≤ γ (Y float, exactly symmetric; p a float).

    With H(C) = Y − p Y C'(C Y C')⁻¹ C Y (0 ⪯ H ⪯ Y) and G = T H(C) T':

    .. math::

        \|G^{(T,C)} - T_0 H(C_0) T_0'\| \le (2t\tau + \tau^2) y
            + t^2 p\, y\, \|\Pi_C - \Pi_{C_0}\|, \qquad
        \|\Pi_C - \Pi_{C_0}\| \le \frac{\sqrt{y}\,\gamma}{\sigma - \sqrt{y}\,\gamma},

    t ≥ ‖T₀‖, y ≥ ‖Y‖, σ² ≤ λ_min(C₀ Y C₀'), Π_C the orthogonal projector onto the range of
    Y^{1/2} C' (so Y C'(C Y C')⁻¹ C Y = Y^{1/2} Π_C Y^{1/2}). T₀ H(C₀) T₀' is enclosed in
    midpoint-radius arithmetic with (C₀ Y C₀')⁻¹ = (I − Δ)⁻¹ Ŝ, Δ = I − Ŝ C₀ Y C₀', its error
    at most t² p v² ‖Ŝ‖ ε/(1 − ε) (v ≥ ‖Y C₀'‖, ε ≥ ‖Δ‖). The enclosure minus the sum of these
    bounds times I is proven positive definite.
    """
    if not (0.0 <= p <= 1.0) or not np.array_equal(Y, Y.T) or not np.all(np.isfinite(Y)):
        return LowerCheck(False, p, None, None, None, "bad p or Y not exactly symmetric")
    Yi = fc.point(Y)
    my = fc.verified_definite_margin(Yi)
    if my is None:
        return LowerCheck(False, p, None, None, None, "Y is not proven positive definite")
    T0 = fc.point(ball.T0)
    y, t = spectral_norm_up(Yi), spectral_norm_up(T0)
    # V = Y C₀' and C₀ Y C₀' by compensated products: the inverse multiplies their radii by
    # ‖(C₀ Y C₀')⁻¹‖, so a priori γ_k bounds would swamp the margin
    V = fc.accurate_product(Y, ball.C0.T)
    S0 = fc.accurate_product(ball.C0, V[0])
    S0 = (S0[0], fc._up(S0[1] + np.abs(ball.C0) @ V[1] * (1 + fc.gamma(Y.shape[0] + 2)),
                        Y.shape[0]))
    # the exact C₀ Y C₀' is symmetric: (M + M')/2 is within max(r, r') (+ its rounding)
    S0 = (0.5 * (S0[0] + S0[0].T),
          fc._up(np.maximum(S0[1], S0[1].T) + 2 * fc.U * np.abs(S0[0] + S0[0].T), 2))
    low = float(np.linalg.eigvalsh(S0[0])[0])
    sigma2 = None
    for frac in (0.9, 0.5):
        m = S0[0].shape[0]
        if low > 0 and fc.verified_definite_margin(
                fc.add(S0, (frac * low * np.eye(m), np.zeros((m, m))), -1.0)) is not None:
            sigma2 = frac * low
            break
    if sigma2 is None:
        return LowerCheck(False, p, my, None, None, "C0 Y C0' is not proven positive definite")
    Sh = np.linalg.inv(S0[0])
    Sh = np.triu(Sh) + np.triu(Sh, 1).T
    m = Sh.shape[0]
    P = fc.accurate_product(Sh, S0[0])
    P = (P[0], fc._up(P[1] + np.abs(Sh) @ S0[1] * (1 + fc.gamma(m + 2)), m))
    Delta = fc.add(fc.point(np.eye(m)), P, -1.0)
    eps = spectral_norm_up(Delta)
    if not eps < 0.5:
        return LowerCheck(False, p, my, None, None, "(C0 Y C0')^-1 not enclosed")
    v, sh = spectral_norm_up(V), spectral_norm_up(fc.point(Sh))
    Q = fc.mul(fc.mul(V, fc.point(Sh)), fc.transpose(V))
    H = fc.add(Yi, Q, -p)
    M = fc.add(fc.mul(fc.mul(T0, H), fc.transpose(T0)), Yi, -1.0)
    sy = math.sqrt(y) * SAFE
    sig = math.sqrt(sigma2) * (1.0 - 1e-15)
    if not sig > sy * ball.gamma:
        return LowerCheck(False, p, my, None, None,
                          "output ball too wide for the projector bound")
    dpi = min(1.0, sy * ball.gamma / (sig - sy * ball.gamma) * SAFE)
    pert = (t * t * p * v * v * sh * eps / (1.0 - eps)
            + (2.0 * t * ball.tau + ball.tau * ball.tau) * y
            + t * t * p * y * dpi) * SAFE * SAFE
    k = Y.shape[0]
    shifted = fc.add(M, (pert * np.eye(k), np.zeros((k, k))), -1.0)
    margin = fc.verified_definite_margin(shifted)
    if margin is None:
        return LowerCheck(False, p, my, None, pert,
                          "G_p(Y) - Y minus the ball perturbation is not proven positive "
                          "definite")
    return LowerCheck(True, p, my, margin, pert, "proven")


CANDIDATE_RTOL = 1e-2
"""Relative residual of the GMRES solve for the candidate Y: any positive definite Y is a
candidate (the ball check decides), and G_p(Y) − Y = I − E stays ⪰ 0 while ‖E‖₂ < 1,
‖E‖_F ≤ 10⁻²·‖I‖_F = 10⁻²√k; a loose solve is 2–5 times cheaper than 1e-7 near the root."""


def lower_candidate(ball: PairBall, K: np.ndarray, p: float) -> tuple[np.ndarray | None, int]:
    """Y with Y − L_{K,p}(Y) = −I on (T₀, C₀) (preconditioned GMRES), so that
    G_p(Y) − Y ≈ I when ρ(L_{K,p}) is just above 1; scaled to tr Y = 1 and made exactly
    symmetric. Returns (Y or None when the solve fails or Y is not positive definite, operator
    applications)."""
    Y, count = krylov.stein_solve_preconditioned(ball.T0, ball.C0, K, p, -np.eye(ball.k),
                                                 rtol=CANDIDATE_RTOL)
    if Y is None or not np.all(np.isfinite(Y)):
        return None, count
    Y = symmetrize(Y)
    tr = float(np.trace(Y))
    if not tr > 0:
        return None, count
    Y = Y / tr
    Y = np.triu(Y) + np.triu(Y, 1).T
    return (Y if krylov._positive_definite(Y) else None), count


def schur_to_eigen(Z_u: np.ndarray, S_u: np.ndarray, X: np.ndarray) -> np.ndarray:
    """X given on the Schur basis Z_u as the same subspace matrix on S_u: with V = Z_u' S_u
    (S_u ≈ Z_u V), Z_u X Z_u' = S_u Y S_u' for Y = V⁻¹ X V⁻ᵀ."""
    V = Z_u.T @ S_u
    Vi = np.linalg.inv(V)
    return symmetrize(Vi @ X @ Vi.T)


@dataclass(frozen=True)
class LowerProof:
    """The outcome of :func:`prove_lower_end`: ``check`` is the first passing check (or the
    last failing one), ``reason`` says why nothing was proven (or "proven")."""

    check: LowerCheck | None
    ball: PairBall | None
    reason: str
    operator_applications: int

    @property
    def ok(self) -> bool:
        return self.check is not None and self.check.ok


def prove_lower_end(a: np.ndarray, c: np.ndarray, Z_u: np.ndarray, X_star: np.ndarray,
                    points: list[float], a_off: fc.Offsets, c_off: fc.Offsets,
                    unstable_tol: float) -> LowerProof:
    """Try to prove p_up ≥ p at each of ``points`` in turn (module docstring): enclose the
    unstable pair once, take the gain K of the threshold eigenvector X* (given on the Schur
    basis Z_u, moved to the eigenbasis), and check the candidate Y of
    :func:`lower_candidate` at each p. Stops at the first proven point."""
    if Z_u.shape[1] == a.shape[0]:
        ball, Ys = whole_space_ball(a, c, a_off, c_off), symmetrize(Z_u @ X_star @ Z_u.T)
        return _prove_on(ball, Ys, points)
    basis = real_eigenbasis(a, unstable_tol)
    if basis is None:
        return LowerProof(None, None, "no real eigenbasis (unpaired complex eigenvalues)", 0)
    S, D, k = basis
    if k != Z_u.shape[1]:
        return LowerProof(None, None, f"the eigenvalues give {k} unstable modes, the Schur "
                                      f"form {Z_u.shape[1]}", 0)
    ball, why = enclose_unstable_pair(a, c, S, D, k, a_off, c_off)
    if ball is None:
        return LowerProof(None, None, "the unstable invariant subspace is not enclosed: " + why,
                          0)
    return _prove_on(ball, schur_to_eigen(Z_u, S[:, :k], X_star), points)


def whole_space_ball(a: np.ndarray, c: np.ndarray, a_off: fc.Offsets, c_off: fc.Offsets
                     ) -> PairBall:
    """Every mode unstable: the invariant subspace is the whole space, the pair is (A, C)
    itself, within ‖|lo| + rad‖_F of (a, c) (:func:`kfcrit.theory.upper.floatcheck.exact_offsets`)."""
    tau = _frob(fc.offset_interval(a, a_off)[1]) * SAFE
    gamma = _frob(fc.offset_interval(c, c_off)[1]) * SAFE
    return PairBall(np.array(a, dtype=float), np.array(c, dtype=float), tau, gamma,
                    a.shape[0], 1.0, math.inf, 0.0, 0.0)


def _prove_on(ball: PairBall, Ys: np.ndarray, points: list[float]) -> LowerProof:
    """The candidates of :func:`lower_candidate` (gain of the eigenvector Ys) checked at each
    point in turn."""
    K, _ = krylov.gain_and_correction(ball.T0, ball.C0, Ys / float(np.trace(Ys)))
    check, count, reason = None, 0, "no candidate point"
    for p in points:
        Y, used = lower_candidate(ball, K, p)
        count += used
        if Y is None:
            reason = f"no positive definite candidate Y at p = {p!r} (GMRES)"
            continue
        check = verify_lower_ball(ball, p, Y)
        if check.ok:
            return LowerProof(check, ball, "proven", count)
        reason = f"the ball check failed at p = {p!r}: {check.reason}"
    return LowerProof(check, ball, reason, count)


def stats_of(ball: PairBall | None, check: LowerCheck | None) -> dict[str, Any]:
    """The numbers of an attempt (for the record's solver statistics)."""
    out: dict[str, Any] = {}
    if ball is not None:
        out.update(eigenvector_condition=ball.condition, eigen_gap=ball.gap,
                   state_radius=ball.tau, output_radius=ball.gamma, neumann=ball.neumann,
                   subspace_tilt=ball.phi)
    if check is not None:
        out.update(perturbation=check.perturbation, margin=check.margin)
    # JSON has no infinity (the whole-space case has no gap to separate)
    return {key: (v if v is None or math.isfinite(v) else None) for key, v in out.items()}
