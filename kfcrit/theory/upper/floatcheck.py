"""A rigorous check of the upper certificate in float64 with a priori rounding-error bounds.

For large systems the ball-arithmetic check of :func:`kfcrit.theory.upper.certify.verify_upper`
costs O(n³) *ball* operations on 160-bit numbers (minutes at n = 400). This module proves the
same statement,

.. math::

    X \\succ 0, \\qquad X - (1-p) A X A' - p F X F' \\succ 0, \\qquad F = A + K C,

with ordinary float64 BLAS products and rigorous bounds on every rounding error, in
midpoint-radius form (docs/theory.md §3, "Verified float64 check"): a matrix is a pair
(M̃, R) with |M − M̃| ≤ R entrywise for the exact M. The bounds used are

* a product of floats computed in any order (BLAS, FMA or not): |fl(UV) − UV| ≤ γ_q |U||V|
  + q·η, γ_q = q u/(1 − q u), u = 2⁻⁵³, η = 2⁻¹⁰⁷⁴ (underflow), q the inner dimension
  (Higham, *Accuracy and Stability of Numerical Algorithms*, sections 3.1 and 3.5);
* products of intervals: ⟨M₁, R₁⟩⟨M₂, R₂⟩ ⊆ ⟨M₁M₂, |M₁|R₂ + R₁(|M₂| + R₂)⟩ (Rump 1999);
* every radius is a sum of non-negative terms computed in floats, hence at most
  (1 + γ_{q+8}) above its computed value: radii are multiplied by ``INFLATE`` = 1 + 1e-10
  (valid for q ≤ 10⁵) and receive q·η more.

The exact A and C differ from their float views a, c by at most one ulp per entry
(:func:`kfcrit.model.system.to_float` rounds each exact entry once, after at most a 20-digit
evaluation): |A − a| ≤ 2u|a| + η. Positive definiteness of a symmetric interval matrix is proven
as in :func:`kfcrit.theory.upper.certify.definite_margin`: D M D = L L' + σI + E with D a
power-of-two diagonal (exact scaling), L a float Cholesky factor, and ‖E‖₂ ≤ max row sum
|E| < σ, where |E| is bounded rigorously from the float residual.
"""
from __future__ import annotations

import math
from fractions import Fraction
from typing import Any

import numpy as np

from kfcrit.model.system import matrix_rows

U = 2.0 ** -53
"""Unit roundoff of float64 (round to nearest)."""
ETA = 2.0 ** -1074
"""Smallest positive subnormal: the absolute error of one underflowing operation."""
INFLATE = 1.0 + 1e-10
"""Factor covering the rounding of a computed radius (q ≤ 10⁵ terms: γ_{q+8} < 1e-10)."""


def gamma(q: int) -> float:
    """γ_q = q u / (1 − q u), the relative error bound of a length-q dot product."""
    return q * U / (1.0 - q * U)


Interval = tuple[np.ndarray, np.ndarray]
"""(midpoint, radius): the exact matrix M satisfies |M − midpoint| ≤ radius entrywise."""


def _up(rad: np.ndarray, q: int) -> np.ndarray:
    """A radius computed in floats from q-term sums, made an upper bound of the exact one."""
    return rad * INFLATE + (q + 8) * ETA


def mul(a: Interval, b: Interval) -> Interval:
    """Enclosure of the product of two interval matrices (midpoint-radius, Rump 1999).

    .. math::

        \\langle M_1, R_1\\rangle \\langle M_2, R_2\\rangle \\subseteq
        \\langle \\mathrm{fl}(M_1 M_2),\\ \\gamma_q |M_1||M_2| + |M_1| R_2 + R_1 (|M_2| + R_2)
        \\rangle
    """
    (m1, r1), (m2, r2) = a, b
    q = m1.shape[1]
    mid = m1 @ m2
    a1, a2 = np.abs(m1), np.abs(m2)
    rad = gamma(q + 2) * (a1 @ a2)
    if r2.any():
        rad += a1 @ r2
    if r1.any():
        rad += r1 @ (a2 + r2)
    return mid, _up(rad, q)


def add(a: Interval, b: Interval, sb: float = 1.0) -> Interval:
    """Enclosure of a + sb·b for a float scalar sb (exact power of two or ±1 keeps it tight)."""
    mid = a[0] + sb * b[0]
    rad = a[1] + abs(sb) * b[1] + 2 * U * (np.abs(a[0]) + abs(sb) * np.abs(b[0]) + np.abs(mid))
    return mid, _up(rad, 4)


def scale(s: Interval, a: Interval) -> Interval:
    """Enclosure of s·a for a scalar interval s = (s̃, ρ), |s − s̃| ≤ ρ."""
    (sm, sr), (m, r) = s, a
    mid = sm * m
    rad = abs(sm) * r + sr * (np.abs(m) + r) + 2 * U * np.abs(mid)
    return mid, _up(rad, 4)


def point(M: np.ndarray) -> Interval:
    """A float matrix taken exactly."""
    M = np.asarray(M, dtype=float)
    return M, np.zeros_like(M)


def from_exact(view: np.ndarray) -> Interval:
    """Enclosure of an exact matrix from its float view, rounded once per entry:
    |M − view| ≤ 2u|view| + η (one ulp)."""
    view = np.asarray(view, dtype=float)
    return view, 2 * U * np.abs(view) + ETA


def pow2_diagonal(d: np.ndarray) -> np.ndarray:
    """Powers of two s_i ≈ 1/√d_i (exact scaling factors: no rounding in s_i M_ij s_j)."""
    return np.array([math.ldexp(1.0, -round(math.log2(x) / 2)) for x in d])


def verified_definite_margin(M: Interval) -> float | None:
    """Rigorous lower bound on λ_min(S M S) > 0 for the symmetric exact matrix M in the
    interval (S a power-of-two diagonal), or None if not proven.

    .. math::

        S M S = L L' + \\sigma I + E, \\quad \\|E\\|_2 \\le \\max_i \\sum_j |E_{ij}| < \\sigma
        \\;\\Rightarrow\\; \\lambda_{\\min}(S M S) \\ge \\sigma - \\|E\\|_2 > 0 .
    """
    mid, rad = M
    if not (np.all(np.isfinite(mid)) and np.all(np.isfinite(rad))):
        return None
    sym = 0.5 * (mid + mid.T)
    rad = _up(0.5 * (rad + rad.T) + 2 * U * np.abs(sym), 2)
    d = np.diag(sym)
    if not np.all(d > 0):
        return None
    s = pow2_diagonal(d)
    sym = s[:, None] * sym * s[None, :]
    rad = s[:, None] * rad * s[None, :] + ETA
    lam = float(np.linalg.eigvalsh(sym)[0])
    if not lam > 0:
        return None
    for frac in SHIFT_FRACTIONS:
        low = _shifted_cholesky_bound(sym, rad, frac * lam)
        if low is not None:
            return low
    return None


SHIFT_FRACTIONS = (0.5, 0.9)
"""Shifts σ = frac·λ_min(mid) tried in turn by :func:`verified_definite_margin` (a larger σ
leaves more room for the radius when the Cholesky factor of mid − σI stays accurate)."""


def _shifted_cholesky_bound(sym: np.ndarray, rad: np.ndarray, sigma: float) -> float | None:
    """σ − ‖E‖₂ for sym = L L' + σI + E (L a float Cholesky factor), if positive (rad: the
    radius of the interval around sym)."""
    n = sym.shape[0]
    shifted = sym - sigma * np.eye(n)
    try:
        L = np.linalg.cholesky(shifted)
    except np.linalg.LinAlgError:
        return None
    LL = L @ L.T
    resid = shifted - LL
    aL = np.abs(L)
    # |E| ≤ |fl(resid)| + rounding of the subtraction, of σI, of L L' + the radius of M
    err = (np.abs(resid) + gamma(n + 2) * (aL @ aL.T)
           + 2 * U * (np.abs(sym) + np.abs(LL) + np.abs(resid)) + 2 * U * sigma * np.eye(n)
           + rad)
    err = _up(err, n)
    # ‖E‖₂ ≤ √(‖E‖₁‖E‖_∞) ≤ the larger of the greatest row and column sums of |E|
    bound = max(float(np.max(err.sum(axis=0))), float(np.max(err.sum(axis=1)))) * INFLATE
    low = (sigma - bound) * (1 - 1e-12)
    return low if low > 0 else None


def upper_operands(a: np.ndarray, c: np.ndarray, X: np.ndarray, K: np.ndarray,
                   p: float) -> tuple[Interval, Interval]:
    """Enclosures of X and of X − (1−p) A X A' − p F X F' (F = A + K C) for the exact A, C
    (views a, c) and the float certificate X (exactly symmetric), K and p (floats, exact)."""
    A, C = from_exact(a), from_exact(c)
    Xi, Ki = point(X), point(K)
    F = add(A, mul(Ki, C))
    AXA = mul(mul(A, Xi), (A[0].T, A[1].T))
    FXF = mul(mul(F, Xi), (F[0].T, F[1].T))
    q = (1.0 - p, 2 * U)                  # |fl(1 − p) − (1 − p)| ≤ u
    LX = add(scale(q, AXA), scale((p, 0.0), FXF))
    return Xi, add(Xi, LX, -1.0)


def verify_upper_float(a: np.ndarray, c: np.ndarray, p: float, X: np.ndarray,
                       K: np.ndarray) -> tuple[bool, float | None, float | None, str]:
    """Prove p_up ≤ p from (X, K) by the verified float64 check (module docstring).

    Returns (ok, margin of X, margin of X − L_{K,p}(X), reason); the margins are rigorous
    lower bounds on the least eigenvalues of the power-of-two-equilibrated matrices.
    """
    X = np.asarray(X, dtype=float)
    if not (0 <= p <= 1) or X.shape != (a.shape[0],) * 2 or K.shape != (a.shape[0], c.shape[0]):
        return False, None, None, "bad shape or p outside [0, 1]"
    if not np.array_equal(X, X.T):
        return False, None, None, "X is not exactly symmetric"
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(K))):
        return False, None, None, "non-finite certificate entry"
    Xi, M = upper_operands(np.asarray(a, float), np.asarray(c, float), X, K, float(p))
    mx = verified_definite_margin(Xi)
    if mx is None:
        return False, None, None, "X is not proven positive definite"
    mm = verified_definite_margin(M)
    if mm is None:
        return False, mx, None, "X - L_{K,p}(X) is not proven positive definite"
    return True, mx, mm, "proven"


def transpose(a: Interval) -> Interval:
    return a[0].T, a[1].T


SPLITTER = 134217729.0
"""2²⁷ + 1: Dekker's splitting constant for float64."""


def _two_product(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """x = fl(a b) and y with x + y = a b exactly (Dekker; barring underflow, handled by the
    caller's η terms, and overflow, excluded by the caller)."""
    x = a * b
    c = SPLITTER * a
    ah = c - (c - a)
    al = a - ah
    c = SPLITTER * b
    bh = c - (c - b)
    bl = b - bh
    return x, al * bl - (((x - ah * bh) - al * bh) - ah * bl)


def accurate_product(Lm: np.ndarray, Rm: np.ndarray) -> Interval:
    """Enclosure of Lm Rm for float Lm (q × n) and a few float columns Rm (n × d) by compensated
    dot products (Dot2 of Ogita, Rump and Oishi 2005, Prop. 5.5), vectorised over the outputs.

    .. math::

        |\\mathrm{res} - L_m R_m| \\le \\frac{u |\\mathrm{res}| + \\gamma_n^2 |L_m||R_m|}{1 - u}
        + \\text{underflow}

    Radius about u·|L_m R_m| instead of γ_n·|L_m||R_m|: needed for the basis columns that carry the
    huge dominant block of a face-root certificate (each of their rounding errors is multiplied
    by that block).
    """
    q, n = Lm.shape
    d = Rm.shape[1]
    big = max(float(np.abs(Lm).max(initial=0.0)), float(np.abs(Rm).max(initial=0.0)))
    if not big < 1e150:
        raise ValueError("accurate_product: entries too large for error-free splitting")
    s = np.zeros((q, d))
    err = np.zeros((q, d))
    for j in range(n):
        h, r = _two_product(Lm[:, j:j + 1], Rm[j:j + 1, :])
        t = s + h
        z = t - s
        err += ((s - (t - z)) + (h - z)) + r          # TwoSum error plus the product's error
        s = t
    res = s + err
    bound = (np.abs(Lm) @ np.abs(Rm)) * (1.0 + gamma(n + 2))   # ≥ the exact |Lm||Rm|
    rad = (U_ROUND_SAFE * np.abs(res) + gamma(n + 2) ** 2 * bound) / (1.0 - U)
    return res, _up(rad, n) + 8 * (n + 2) * ETA


U_ROUND_SAFE = 2.0 * U
"""u|res| of the Dot2 bound taken twice (covers the final rounding of res itself)."""


def sharpen_columns(a_int: Interval, Z: np.ndarray, d: int,
                    B: Interval, G: Interval,
                    a_lo: np.ndarray | None = None) -> tuple[Interval, Interval]:
    """B = Z'AZ and G = Z'Z with their first d columns (and G's first d rows) recomputed by
    :func:`accurate_product`: (Z'(A Z₁), Z'Z₁) with Z₁ = Z[:, :d]. With ``a_lo`` the exact A
    is a + a_lo ± rad(a_int) (:func:`exact_offsets`) and A Z₁ = [a, a_lo][Z₁; Z₁] ± rad|Z₁|."""
    a, ra = a_int
    Z1 = Z[:, :d]
    if a_lo is not None and np.any(a_lo):
        y, ry = accurate_product(np.hstack([a, a_lo]), np.vstack([Z1, Z1]))
    else:
        y, ry = accurate_product(a, Z1)
    # the exact A is within ra of a: add |ra||Z₁| (a float product, made an upper bound)
    ry = ry + _up((ra @ np.abs(Z1)) * (1.0 + gamma(Z.shape[0] + 2)), Z.shape[0])
    b1, rb1 = accurate_product(Z.T, y)
    rb1 = rb1 + _up((np.abs(Z.T) @ ry) * (1.0 + gamma(Z.shape[0] + 2)), Z.shape[0])
    g1, rg1 = accurate_product(Z.T, Z1)
    Bm, Br = B[0].copy(), B[1].copy()
    Bm[:, :d], Br[:, :d] = b1, rb1
    Gm, Gr = G[0].copy(), G[1].copy()
    Gm[:, :d], Gr[:, :d] = g1, rg1
    Gm[:d, :], Gr[:d, :] = g1.T, rg1.T
    return (Bm, Br), (Gm, Gr)


def _columns(a: Interval, cols: slice) -> Interval:
    return a[0][:, cols], a[1][:, cols]


def congruence(P: Interval, X: np.ndarray, sharp: int = 0) -> Interval:
    """Enclosure of P X P' for the float matrix X (exact).

    With ``sharp`` = d > 0 the leading d × d block of X (the huge dominant block of a face-root
    certificate) is taken apart: P X P' = P₁ X₁₁ P₁' + P X_r P' with X_r = X minus that block,
    so its products have inner dimension d and rounding γ_{d+2}, not γ_n, times X₁₁.
    """
    if sharp <= 0:
        return mul(mul(P, point(X)), transpose(P))
    d = sharp
    rest = X.copy()
    rest[:d, :d] = 0.0
    P1m, P1r = _columns(P, slice(0, d))
    X11 = X[:d, :d]
    q = P1m.shape[0]
    # Y = P₁ X₁₁ by compensated products, plus the radius of P₁ times |X₁₁|
    Ym, Yr = accurate_product(P1m, X11)
    Yr = Yr + _up((P1r @ np.abs(X11)) * (1.0 + gamma(d + 2)), d)
    # top = Y P₁' likewise, plus |Y| rad(P₁)' + rad(Y)(|P₁| + rad(P₁))'
    Tm, Tr = accurate_product(Ym, P1m.T)
    Tr = Tr + _up((np.abs(Ym) @ P1r.T + Yr @ (np.abs(P1m) + P1r).T) * (1.0 + gamma(d + 2)), d)
    top = (Tm, Tr) if Tm.shape == (q, q) else mul(mul((P1m, P1r), point(X11)),
                                                   transpose((P1m, P1r)))
    return add(top, mul(mul(P, point(rest)), transpose(P)))


def _sharp_gain_columns(A: Interval, C: Interval, Z: np.ndarray, G: Interval, B: Interval,
                        Kz: np.ndarray, output_map: np.ndarray | None, d: int,
                        F: Interval, c_off: Offsets | None = None) -> Interval:
    """F̂ = B + G K_z (M C Z) with its first d columns recomputed sharply: C Z₁ by compensated
    products, G K_z as K_z + (G − I) K_z (G − I is tiny; the diagonal subtraction is exact by
    Sterbenz's lemma when G_ii ∈ [1/2, 2]), the product with inner dimension m."""
    n = Z.shape[0]
    gd = np.diag(G[0])
    if not (np.all(gd >= 0.5) and np.all(gd <= 2.0)):
        return F
    Z1 = Z[:, :d]
    if c_off is not None:
        cz, rcz = offset_product(C[0], c_off, Z1)
    else:
        cz, rcz = accurate_product(C[0], Z1)
        rcz = rcz + _up((C[1] @ np.abs(Z1)) * (1.0 + gamma(n + 2)), n)
    CZ1 = (cz, rcz)
    if output_map is not None:
        CZ1 = mul(point(output_map), CZ1)
    GmI = (G[0] - np.eye(n), G[1])
    GK = add(point(Kz), mul(GmI, point(Kz)))
    F1 = add(_columns(B, slice(0, d)), mul(GK, CZ1))
    Fm, Fr = F[0].copy(), F[1].copy()
    Fm[:, :d], Fr[:, :d] = F1
    return Fm, Fr


def basis_operands(a: np.ndarray, c: np.ndarray, p: float, Z: np.ndarray, Xz: np.ndarray,
                   Kz: np.ndarray, output_map: np.ndarray | None = None, sharp: int = 0,
                   exact_views: bool = False,
                   offsets: tuple[Offsets, Offsets] | None = None
                   ) -> tuple[Interval, Interval, Interval]:
    r"""Enclosures of G = Z'Z, Z'XZ and Z'(X − L_{K,p}(X))Z for X = Z X_z Z', K = Z K_z (M).

    .. math::

        Z'XZ = G X_z G, \quad Z'(X - L_{K,p}(X))Z = G X_z G - (1-p) B X_z B' - p \hat F X_z
        \hat F', \quad B = Z'AZ, \ \hat F = B + G K_z (M C Z)

    (exact identities; X and K are never rounded). For invertible Z (G ≻ 0) the congruence
    preserves definiteness, so G X_z G ≻ 0 and the last matrix ≻ 0 prove X ≻ 0 and
    X ≻ L_{K,p}(X). With ``sharp`` = d > 0 the first d columns of B and G are enclosed by
    compensated products (:func:`sharpen_columns`). ``exact_views``: a and c are the exact
    matrices themselves (every entry a binary float, checked by the caller), radius 0.
    ``offsets``: the exact A and C as a + a_lo ± a_rad, c + c_lo ± c_rad
    (:func:`exact_offsets`, decimal input); the sharpened columns then carry radii of order u²
    from them instead of one ulp.
    """
    A, C = (point(a), point(c)) if exact_views else (from_exact(a), from_exact(c))
    if offsets is not None and not exact_views:
        A, C = offset_interval(a, offsets[0]), offset_interval(c, offsets[1])
    Zi = point(Z)
    Zt = transpose(Zi)
    G = mul(Zt, Zi)
    B = mul(Zt, mul(A, Zi))
    if sharp > 0:
        if offsets is not None and not exact_views:
            B, G = sharpen_columns((a, offsets[0][1]), Z, sharp, B, G, a_lo=offsets[0][0])
        else:
            B, G = sharpen_columns(A, Z, sharp, B, G)
    CZ = mul(C, Zi)
    if output_map is not None:
        CZ = mul(point(output_map), CZ)
    F = add(B, mul(mul(G, point(Kz)), CZ))
    if sharp > 0:
        F = _sharp_gain_columns(A, C, Z, G, B, Kz, output_map, sharp, F,
                                offsets[1] if offsets is not None and not exact_views else None)
    GXG = congruence(G, Xz, sharp)
    BXB = congruence(B, Xz, sharp)
    FXF = congruence(F, Xz, sharp)
    LX = add(scale((1.0 - p, 2 * U), BXB), scale((p, 0.0), FXF))
    return G, GXG, add(GXG, LX, -1.0)


def verify_upper_float_basis(a: np.ndarray, c: np.ndarray, p: float, Z: np.ndarray,
                             Xz: np.ndarray, Kz: np.ndarray,
                             output_map: np.ndarray | None = None, sharp: int = 0,
                             exact_views: bool = False,
                             offsets: tuple[Offsets, Offsets] | None = None
                             ) -> tuple[bool, float | None, float | None, str]:
    """:func:`verify_upper_float` for the certificate X = Z X_z Z', K = Z K_z (M) given in the
    basis Z (:func:`basis_operands`, ``sharp`` leading columns by compensated products); X_z
    must be exactly symmetric."""
    n = a.shape[0]
    Xz = np.asarray(Xz, dtype=float)
    if not (0 <= p <= 1) or Z.shape != (n, n) or Xz.shape != (n, n):
        return False, None, None, "bad shape or p outside [0, 1]"
    if not np.array_equal(Xz, Xz.T):
        return False, None, None, "X_z is not exactly symmetric"
    if not all(np.all(np.isfinite(M)) for M in (Z, Xz, Kz)):
        return False, None, None, "non-finite certificate entry"
    if not 0 <= sharp <= n:
        return False, None, None, "bad number of sharpened columns"
    G, GXG, M = basis_operands(np.asarray(a, float), np.asarray(c, float), float(p),
                               np.asarray(Z, float), Xz, np.asarray(Kz, float), output_map,
                               int(sharp), bool(exact_views), offsets)
    if verified_definite_margin(G) is None:
        return False, None, None, "the basis Z is not proven invertible (Z'Z > 0)"
    mx = verified_definite_margin(GXG)
    if mx is None:
        return False, None, None, "X is not proven positive definite"
    mm = verified_definite_margin(M)
    if mm is None:
        return False, mx, None, "X - L_{K,p}(X) is not proven positive definite"
    return True, mx, mm, "proven"


def _frob_up(M: np.ndarray) -> float:
    """An upper bound on the Frobenius norm of the float matrix M (relative error ≤ γ_{N+2})."""
    return float(np.sqrt(np.sum(M * M))) * (1.0 + 1e-9) + 1e-300


def dominant_radius_lower(a: np.ndarray, Z: np.ndarray, d: int) -> float | None:
    r"""Rigorous lower bound on ρ(A)² from an exactly A-invariant subspace near the first d
    (1 or 2) columns of the float basis Z, for the exact A within one ulp of ``a``.

    With B = Z⁻¹AZ = G⁻¹ B̃ (B̃ ∋ Z'AZ, G ∋ Z'Z enclosed as in :func:`basis_operands`, the
    first d columns by compensated products) split after d rows and columns, every block of B
    is within δ_B of the midpoint of B̃ in the Frobenius norm, δ_B = ‖rad B̃‖_F
    + ‖G⁻¹ − I‖₂ (‖mid B̃‖_F + ‖rad B̃‖_F). With s ≤ σ_min(I ⊗ B₂₂ − B₁₁' ⊗ I) (proven: a
    Cholesky definiteness check of S'S − τI for the midpoint Kronecker matrix S, less 2δ_B)
    and 4‖B₂₁‖_F‖B₁₂‖_F < s², Stewart's theorem gives an exactly invariant subspace
    span Z[I; P], ‖P‖_F ≤ 2‖B₂₁‖_F/s, on which A acts as M = B₁₁ + B₁₂P. Its eigenvalues are
    eigenvalues of A, so

    .. math::

        \rho(A)^2 \ge \rho(M)^2 \ge |\det M| \ (d = 2), \qquad \rho(A)^2 \ge M^2 \ (d = 1),

    with |det M − det M₀| ≤ ‖M₀‖_F η + η²/2 for ‖M − M₀‖_F ≤ η (2 × 2: adj M₀ has the norm of
    M₀). Returns None when a step cannot be proven.
    """
    n = a.shape[0]
    if d not in (1, 2) or Z.shape != (n, n) or n <= d:
        return None
    A, Zi = from_exact(a), point(Z)
    Zt = transpose(Zi)
    G = mul(Zt, Zi)
    B = mul(Zt, mul(A, Zi))
    B, G = sharpen_columns(A, Z, d, B, G)
    gdev = _frob_up(np.abs(G[0] - np.eye(n)) + G[1])          # ≥ ‖G − I‖₂
    if not gdev < 0.5:
        return None
    e_inv = gdev / (1.0 - gdev) * (1.0 + 1e-12)                # ≥ ‖G⁻¹ − I‖₂
    Bm, Br = B
    delta = _frob_up(Br) + e_inv * (_frob_up(Bm) + _frob_up(Br))
    B11, B12, B21, B22 = Bm[:d, :d], Bm[:d, d:], Bm[d:, :d], Bm[d:, d:]
    b21 = _frob_up(B21) + delta
    b12 = _frob_up(B12) + delta
    # S = I ⊗ B22 − B11' ⊗ I (vec of P, column-major): entries are differences of floats
    s_mid = np.kron(np.eye(d), B22) - np.kron(B11.T, np.eye(n - d))
    s_rad = _up(2 * U * np.abs(s_mid), 2)
    S = (s_mid, s_rad)
    StS = mul(transpose(S), S)
    lam = float(np.linalg.eigvalsh(0.5 * (StS[0] + StS[0].T))[0])
    if not lam > 0:
        return None
    tau = 0.5 * lam
    N = StS[0].shape[0]
    shifted = add(StS, (tau * np.eye(N), np.zeros((N, N))), -1.0)
    if verified_definite_margin(shifted) is None:
        return None
    sep = math.sqrt(tau) * (1.0 - 1e-12) - 2.0 * delta
    if not (sep > 0 and 4.0 * b21 * b12 * (1.0 + 1e-12) < sep * sep):
        return None
    rho_p = 2.0 * b21 / sep * (1.0 + 1e-12)
    eta = (delta + b12 * rho_p) * (1.0 + 1e-12)
    if d == 1:
        m0 = abs(Fraction(float(B11[0, 0])))
        low = m0 - Fraction(eta)
        return float(low * low) * (1.0 - 1e-15) if low > 0 else None
    det0 = Fraction(float(B11[0, 0])) * Fraction(float(B11[1, 1])) \
        - Fraction(float(B11[0, 1])) * Fraction(float(B11[1, 0]))
    m0f = Fraction(_frob_up(B11))
    e = Fraction(eta)
    low = abs(det0) - m0f * e - e * e / 2
    return float(low) * (1.0 - 1e-15) if low > 0 else None


Offsets = tuple[np.ndarray, np.ndarray]
"""(lo, rad): the exact matrix is view + lo + e with |e| ≤ rad entrywise."""


def exact_offsets(M: Any, view: np.ndarray) -> Offsets:
    r"""The exact matrix M (sympy) as its float view plus a float offset: for a rational entry
    lo = fl(M_ij − view_ij) (the exact difference rounded once, so |e| ≤ u|lo| + η), for any
    other entry lo = 0 and the one-ulp radius 2u|view_ij| + η of the view.

    .. math::  M = \mathrm{view} + \mathrm{lo} + e, \qquad |e| \le \mathrm{rad}

    Decimal input (a file's 0.1) is not a binary float: the one-ulp radius alone would make
    the enclosure of the invariant subspace as uncertain as u·cond(S)/gap, while the offset
    form leaves only u²-sized radii."""
    view = np.asarray(view, dtype=float)
    lo = np.zeros_like(view)
    rad = np.zeros_like(view)
    for i, row in enumerate(matrix_rows(M)):
        for j, e in enumerate(row):
            if e.is_Rational:
                lo[i, j] = float(Fraction(int(e.p), int(e.q)) - Fraction(float(view[i, j])))
            else:
                rad[i, j] = 2 * U * abs(view[i, j]) + ETA
    return lo, rad + 2 * U * np.abs(lo) + ETA


def no_offsets(view: np.ndarray) -> Offsets:
    """The offsets of a matrix whose entries are its float view exactly (binary input)."""
    return np.zeros_like(view, dtype=float), np.zeros_like(view, dtype=float)


def offset_interval(view: np.ndarray, off: Offsets) -> Interval:
    """The exact matrix as an interval around its view (the offset folded into the radius)."""
    return np.asarray(view, dtype=float), _up(np.abs(off[0]) + off[1], 2)


def offset_product(view: np.ndarray, off: Offsets, cols: np.ndarray) -> Interval:
    """(view + lo + e)·cols by compensated products: [view, lo]·[cols; cols] plus rad·|cols|."""
    n = view.shape[1]
    if np.any(off[0]):
        prod = accurate_product(np.hstack([view, off[0]]), np.vstack([cols, cols]))
    else:
        prod = accurate_product(view, cols)
    if np.any(off[1]):
        prod = (prod[0], _up(prod[1] + off[1] @ np.abs(cols) * (1 + gamma(n + 2)), n))
    return prod
