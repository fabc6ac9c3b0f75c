"""Independent, rigorous checks of the certificates behind the upper bound p_up.

A numerical method proposes; this module decides. Nothing here calls a solver or trusts a
floating-point eigenvalue: every check is done in ball arithmetic (python-flint ``arb``) on the
*exact* system matrices (``System.A``, ``System.C`` are sympy numbers; rationals are entered
exactly, algebraic numbers as balls of radius 10^-60) and on the certificate as given (a float
matrix is a dyadic rational, entered exactly).

* Upper end (Sinopoli Thm 5): (X, K) with X ≻ 0 and X − L_{K,p}(X) ≻ 0, where
  L_{K,p}(X) = (1−p) A X A' + p F X F', F = A + K C, proves p_up ≤ p: a large multiple cX
  satisfies cX ≻ φ(K, cX) (the noise terms are fixed), and g_p' ⪯ g_p for p' ≥ p (Lemma 1(d)).
* Lower end: X ⪰ 0, X ≠ 0 with G_p(X) − X ⪰ 0 (noise-free MARE map, eigenvalue ≥ 1 of the
  cone-preserving map G_p) proves that no Y ≻ 0 has Y ≻ G_p(Y), i.e. p ≤ p_up. We can check it
  rigorously only when X ≻ 0 and G_p(X) − X ≻ 0 (strict, so balls can decide). With stable
  modes no such full-state X exists; the check is then done on an *exactly* A-invariant
  (unstable) subspace enclosed in balls (:func:`invariant_block`, :func:`verify_lower_block`):
  X = W X_u W' ⪰ 0 on that subspace has G_p(X) = W G^u_p(X_u) W', which the same argument uses.

Positive definiteness of a ball matrix M (after an exact diagonal equilibration): take
σ = λ_min(mid M)/2, a float Cholesky factor L of mid M − σI, and the ball E = M − L L' − σI;
if ‖E‖₂ ≤ max_i Σ_j |E_ij| < σ then M = L L' + σI + E ⪰ (σ − ‖E‖₂) I ≻ 0 —
a proof, whatever the rounding in L.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import flint
import numpy as np
import sympy as sp

from kfcrit.io.jsonio import native_number
from kfcrit.model.system import System
from kfcrit.records.bounds import CertificateCheck

PRECISION_BITS = 160
"""Working precision of the ball arithmetic."""


@dataclass(frozen=True)
class CheckResult:
    """Outcome of a rigorous check: ``ok`` and rigorous lower bounds on the two eigenvalues."""

    ok: bool
    kind: str
    p: float
    min_eig_x: float | None
    margin: float | None
    reason: str
    verified_by: str | None = None
    """How the check was done, when not by :func:`verify_upper`'s ball arithmetic."""

    def record(self) -> CertificateCheck:
        """The check as the record states it (``check`` of a certificate, of the lower-end
        evidence or of an end of the required arrival probability)."""
        return CertificateCheck(
            ok=bool(self.ok), kind=self.kind, p=native_number(self.p),
            min_eig_x_lower=native_number(self.min_eig_x),
            margin_lower=native_number(self.margin), reason=self.reason,
            margin_meaning=MARGIN_MEANING, verified_by=self.verified_by or BALL_CHECK)

    def to_dict(self) -> dict[str, Any]:
        return {"ok": self.ok, "kind": self.kind, "p": self.p, "min_eig_x_lower": self.min_eig_x,
                "margin_lower": self.margin, "reason": self.reason,
                "margin_meaning": MARGIN_MEANING,
                "verified_by": self.verified_by or BALL_CHECK}


MARGIN_MEANING = ("rigorous lower bound on the least eigenvalue of D M D, "
                  "D = diag(M)^(-1/2) (the equilibrated matrix)")
"""What a check's ``margin_lower`` bounds (the record's ``margin_meaning``)."""
BALL_CHECK = (f"python-flint arb ball arithmetic ({PRECISION_BITS} bits) on the exact "
              "system matrices and the float certificate taken exactly")
"""How :func:`verify_upper` and its kin check (a check's ``verified_by`` unless it says
otherwise)."""


def _arb_number(x: sp.Expr) -> flint.arb:
    """A ball containing the exact sympy number ``x``."""
    x = sp.nsimplify(x) if isinstance(x, sp.Float) else x
    if x.is_Rational:
        return flint.arb(flint.fmpq(int(x.p), int(x.q)))
    value = sp.N(x, 70)
    if not value.is_real:
        raise ValueError("complex matrix entry")
    mag = max(1.0, abs(float(value)))
    return flint.arb(str(value)) + flint.arb(0, 10.0 ** -60 * mag)


def arb_from_sympy(M: sp.MatrixBase) -> flint.arb_mat:
    """Ball matrix enclosing the exact matrix ``M``."""
    return flint.arb_mat([[_arb_number(M[i, j]) for j in range(M.cols)] for i in range(M.rows)])


def arb_from_float(M: np.ndarray) -> flint.arb_mat:
    """Ball matrix equal to the float matrix ``M`` (every float is a dyadic rational)."""
    M = np.atleast_2d(np.asarray(M, dtype=float))
    if not np.all(np.isfinite(M)):
        raise ValueError("non-finite certificate entry")
    return flint.arb_mat([[flint.arb(float(v)) for v in row] for row in M])


def _arb_float_exact(x: float) -> flint.arb:
    return flint.arb(flint.fmpq(*Fraction(float(x)).as_integer_ratio()))


def _mid(M: flint.arb_mat) -> np.ndarray:
    return np.array([[float(e.mid()) for e in row] for row in M.tolist()])


def definite_margin(M: flint.arb_mat) -> float | None:
    """Rigorous lower bound on λ_min(D M D) > 0 (D a positive diagonal), or None if not proven.

    D = diag(1/√M_ii) (floats, so D M D is exact in balls) equilibrates matrices whose blocks
    live on different scales; a congruence by a positive diagonal preserves definiteness, so a
    positive result proves M ≻ 0. Only the symmetric part (M + M')/2 is tested.
    """
    n = M.nrows()
    M = (M + M.transpose()) * flint.arb(0.5)
    mid = _mid(M)
    d = np.diag(mid)
    if not (np.all(np.isfinite(mid)) and np.all(d > 0)):
        return None
    D = arb_from_float(np.diag(1.0 / np.sqrt(d)))
    M = D * M * D
    mid = _mid(M)
    mid = 0.5 * (mid + mid.T)
    lam = float(np.linalg.eigvalsh(mid).min())
    if not lam > 0:
        return None
    sigma = 0.5 * lam
    try:
        L = np.linalg.cholesky(mid - sigma * np.eye(n))
    except np.linalg.LinAlgError:
        return None
    La = arb_from_float(L)
    E = M - La * La.transpose() - flint.arb_mat(n, n, [sigma if i == j else 0
                                                        for i in range(n) for j in range(n)])
    bound = max(sum((e.abs_upper() for e in row), flint.arb(0)) for row in E.tolist())
    low = (flint.arb(sigma) - bound).lower()
    if not low > 0:
        return None
    return float(low)


def _with_precision(fn):
    def wrapper(*args, **kwargs):
        old = flint.ctx.prec
        flint.ctx.prec = PRECISION_BITS
        try:
            return fn(*args, **kwargs)
        finally:
            flint.ctx.prec = old
    wrapper.__doc__ = fn.__doc__
    wrapper.__name__ = fn.__name__
    return wrapper


@_with_precision
def verify_upper(system: System, p: float, X: np.ndarray, K: np.ndarray,
                 basis: np.ndarray | None = None,
                 output_map: np.ndarray | None = None) -> CheckResult:
    """Prove p_up ≤ p from (X, K): X ≻ 0 and X − L_{K,p}(X) ≻ 0, in balls.

    L_{K,p}(X) = (1−p) A X A' + p (A + K C) X (A + K C)'   (Sinopoli Thm 5 with Q, R scaled
    away: X ≻ L_{K,p}(X) ⇔ Ψ_p(X^{-1}, X^{-1}K) ≻ 0).

    With ``basis`` Z the certificate is given in that basis: the matrices checked are Z X Z'
    and Z K, formed exactly in balls (no rounding), and X ≻ 0 is proven as Z'Z ≻ 0, X ≻ 0.

    With ``output_map`` M (r × m) the gain is given for the compressed output M C: the gain
    checked for C is K M, formed in balls (the float product K·M would be rounded, and with an
    ill-conditioned C that rounding, amplified by ‖C‖·‖M‖, can exceed the certificate's
    margin). ``K`` is then n × r. The system matrices A, C are always the exact ones: no
    tolerance, no rescaling of the system enters the decision.
    """
    kind = "upper: X > 0 and X - L_{K,p}(X) > 0"
    n, m = system.n, system.m
    try:
        A = arb_from_sympy(system.A)
        C = arb_from_sympy(system.C)
        Xa = arb_from_float(np.asarray(X, dtype=float))
        if output_map is None:
            Ka = arb_from_float(np.asarray(K, dtype=float).reshape(n, m))
        else:
            Mo = np.atleast_2d(np.asarray(output_map, dtype=float))
            if Mo.shape[1] != m:
                raise ValueError(f"output map has {Mo.shape[1]} columns, C has {m} rows")
            Ka = arb_from_float(np.asarray(K, dtype=float).reshape(n, Mo.shape[0])) \
                * arb_from_float(Mo)
        pa = _arb_float_exact(p)
        Za = None if basis is None else arb_from_float(np.asarray(basis, dtype=float))
    except (ValueError, TypeError) as exc:
        return CheckResult(False, kind, float(p), None, None, f"bad certificate: {exc}")
    if not (0 <= p <= 1) or Xa.nrows() != n or Xa.ncols() != n or (
            Za is not None and (Za.nrows() != n or Za.ncols() != n)):
        return CheckResult(False, kind, float(p), None, None, "bad shape or p outside [0, 1]")
    Xs = (Xa + Xa.transpose()) * flint.arb(0.5)
    mx = definite_margin(Xs)
    if mx is None:
        return CheckResult(False, kind, float(p), None, None, "X is not proven positive definite")
    if Za is not None:
        if definite_margin(Za.transpose() * Za) is None:
            return CheckResult(False, kind, float(p), mx, None, "basis not proven invertible")
        Xs = Za * Xs * Za.transpose()
        Ka = Za * Ka
    F = A + Ka * C
    LX = (1 - pa) * (A * Xs * A.transpose()) + pa * (F * Xs * F.transpose())
    mm = definite_margin(Xs - LX)
    if mm is None:
        return CheckResult(False, kind, float(p), mx, None,
                           "X - L_{K,p}(X) is not proven positive definite")
    return CheckResult(True, kind, float(p), mx, mm, "proven")


@_with_precision
def verify_lower(system: System, p: float, X: np.ndarray) -> CheckResult:
    """Prove p_up ≥ p from X ≻ 0 with G_p(X) − X ≻ 0, in balls.

    G_p(X) = A X A' − p A X C' (C X C')^{-1} C X A'. If some Y ≻ 0 had Y ≻ G_p(Y), then with
    t > 0 such that Y ⪰ tX, monotonicity and homogeneity give G_p^k(Y) ⪰ t X for all k, while
    Y ≻ G_p(Y) gives G_p^k(Y) → 0: a contradiction. So p is not above p_up.
    """
    kind = "lower: X > 0 and G_p(X) - X > 0"
    try:
        A = arb_from_sympy(system.A)
        C = arb_from_sympy(system.C)
    except (ValueError, TypeError) as exc:
        return CheckResult(False, kind, float(p), None, None, f"bad system: {exc}")
    return _lower_core(A, C, p, X, kind)


def _lower_core(A: flint.arb_mat, C: flint.arb_mat, p: float, X: np.ndarray,
                kind: str, note: str = "") -> CheckResult:
    """X ≻ 0 and G_p(X) − X ≻ 0 for the ball matrices A, C (every matrix in the balls)."""
    try:
        Xa = arb_from_float(np.asarray(X, dtype=float))
        pa = _arb_float_exact(p)
    except (ValueError, TypeError) as exc:
        return CheckResult(False, kind, float(p), None, None, f"bad certificate: {exc}")
    if not (0 <= p <= 1) or Xa.nrows() != A.nrows() or Xa.ncols() != A.nrows():
        return CheckResult(False, kind, float(p), None, None, "bad shape or p outside [0, 1]")
    Xs = (Xa + Xa.transpose()) * flint.arb(0.5)
    mx = definite_margin(Xs)
    if mx is None:
        return CheckResult(False, kind, float(p), None, None, "X is not proven positive definite")
    AXC = A * Xs * C.transpose()
    S = C * Xs * C.transpose()
    try:
        G = A * Xs * A.transpose() - pa * (AXC * S.solve(AXC.transpose()))
    except (ZeroDivisionError, ValueError):
        return CheckResult(False, kind, float(p), mx, None, "C X C' is not proven invertible")
    mm = definite_margin(G - Xs)
    if mm is None:
        return CheckResult(False, kind, float(p), mx, None,
                           "G_p(X) - X is not proven positive definite")
    return CheckResult(True, kind, float(p), mx, mm, "proven" + note)


KRONECKER_MAX = 300
"""Largest k(n − k) for the ball Sylvester separation bound of :func:`invariant_block` (its
cost grows as (k(n − k))³: about 0.3 s at 96, 20 s at 561 on the 2-core test machine)."""


@dataclass(frozen=True)
class InvariantBlock:
    """Ball enclosure of the restriction of the exact A to an exactly A-invariant subspace.

    The subspace is spanned by the columns of W = Z [I; P] for the float basis Z and some P
    in the ball ``P`` (‖P‖_F ≤ ``radius``); A W = W A_u and C W = C_u with A_u, C_u in the balls.
    """

    A: flint.arb_mat
    C: flint.arb_mat
    k: int
    radius: float
    sep_lower: float | None
    statement: str


@_with_precision
def invariant_block(system: System, basis: np.ndarray, k: int) -> InvariantBlock | None:
    """Enclose an exactly invariant k-dimensional subspace of A near the first k columns of Z.

    With B = Z^{-1} A Z (balls, exact A) split as [[B11, B12], [B21, B22]], the subspace
    span Z [I; P] is A-invariant iff B21 + B22 P − P B11 − P B12 P = 0 (then
    A Z[I; P] = Z[I; P] (B11 + B12 P)). With s ≤ sep_F(B11, B22) = σ_min(I ⊗ B22 − B11ᵀ ⊗ I)
    proven in balls and 4‖B21‖_F‖B12‖_F < s², the map P ↦ S^{-1}(P B12 P − B21) (S the
    Sylvester operator) is a contraction of {‖P‖_F ≤ 2‖B21‖_F/s} into itself, so a solution P
    exists there (Stewart 1973, Thm 4.1; the argument is purely algebraic, Z need not be
    orthogonal). Returns None when the bound cannot be proven (or k(n − k) > KRONECKER_MAX).
    """
    n = system.n
    try:
        A = arb_from_sympy(system.A)
        C = arb_from_sympy(system.C)
        Za = arb_from_float(np.asarray(basis, dtype=float))
    except (ValueError, TypeError):
        return None
    if Za.nrows() != n or Za.ncols() != n or not 0 < k <= n:
        return None
    try:
        B = Za.solve(A * Za)
    except (ZeroDivisionError, ValueError):
        return None
    rows = B.tolist()
    Cz = (C * Za).tolist()
    B11 = flint.arb_mat([r[:k] for r in rows[:k]])
    Cu = flint.arb_mat([r[:k] for r in Cz])
    if k == n:
        return InvariantBlock(B11, Cu, k, 0.0, None,
                              "the whole state space in the basis Z (B = Z^-1 A Z in balls)")
    s = n - k
    if k * s > KRONECKER_MAX:
        return None
    B12 = flint.arb_mat([r[k:] for r in rows[:k]])
    B21 = flint.arb_mat([r[:k] for r in rows[k:]])
    B22 = flint.arb_mat([r[k:] for r in rows[k:]])
    # Kronecker matrix of S(P) = B22 P − P B11 on vec(P) (column-major), P of size s × k
    N = k * s
    Kr = [[flint.arb(0)] * N for _ in range(N)]
    b11, b22 = B11.tolist(), B22.tolist()
    for j in range(k):            # column j of P
        for i in range(s):
            row = j * s + i
            for l in range(s):    # (B22 P)_{ij} = Σ_l B22[i,l] P[l,j]
                Kr[row][j * s + l] += b22[i][l]
            for l in range(k):    # (P B11)_{ij} = Σ_l P[i,l] B11[l,j]
                Kr[row][l * s + i] -= b11[l][j]
    Km = flint.arb_mat(Kr)
    G = Km.transpose() * Km
    mid = _mid(G)
    lam = float(np.linalg.eigvalsh(0.5 * (mid + mid.T)).min())
    if not lam > 0:
        return None
    tau = 0.5 * lam
    shifted = G - flint.arb_mat(N, N, [tau if i == j else 0 for i in range(N) for j in range(N)])
    if definite_margin(shifted) is None:
        return None
    sep = flint.arb(tau).sqrt().lower()               # σ_min(K) ≥ √τ, proven

    def frob_upper(M):
        return sum((e.abs_upper() ** 2 for row in M.tolist() for e in row),
                   flint.arb(0)).sqrt().upper()

    b21n, b12n = frob_upper(B21), frob_upper(B12)
    if not (4 * b21n * b12n < sep * sep):
        return None
    rho = (2 * b21n / sep).upper()
    P = flint.arb_mat([[flint.arb(0, rho) for _ in range(k)] for _ in range(s)])
    Au = B11 + B12 * P
    Cs = flint.arb_mat([r[k:] for r in Cz])
    Cb = Cu + Cs * P
    return InvariantBlock(Au, Cb, k, float(rho), float(sep),
                          f"exactly A-invariant subspace span Z[I; P], ||P||_F <= {float(rho):.3g}"
                          f" (Sylvester separation >= {float(sep):.3g}, Stewart's theorem, "
                          "all in balls on the exact A)")


@_with_precision
def verify_lower_block(block: InvariantBlock, p: float, X: np.ndarray) -> CheckResult:
    """Prove p_up(A, C) ≥ p from X_u ≻ 0 with G^u_p(X_u) − X_u ≻ 0 on an invariant block.

    For W = Z[I; P] with A W = W A_u, C W = C_u (:func:`invariant_block`) the noise-free map
    satisfies G_p(W X_u W') = W G^u_p(X_u) W' (G_p(X) = min_K L_{K,p}(X), defined for X ⪰ 0),
    so X = W X_u W' ⪰ 0, X ≠ 0, has G_p(X) ⪰ X: the cone argument of :func:`verify_lower`
    (monotone, homogeneous G_p; Y ⪰ tX for any Y ≻ 0) then shows that no Y ≻ 0 has
    Y ≻ G_p(Y), i.e. p ≤ p_up of the full system. The check holds for every (A_u, C_u) in the
    balls, hence for the exact invariant block.
    """
    kind = "lower: X_u > 0 and G_p(X_u) - X_u > 0 on an A-invariant subspace"
    return _lower_core(block.A, block.C, p, X, kind, note=f" ({block.statement})")


# ---------------------------------------------------------------------------------------------
# directed rounding of exact values to floats
# ---------------------------------------------------------------------------------------------


def float_down(x: Fraction) -> float:
    """The largest float ≤ the exact rational ``x``."""
    f = float(x)
    return f if Fraction(f) <= x else math.nextafter(f, -math.inf)


def float_up(x: Fraction) -> float:
    """The smallest float ≥ the exact rational ``x``."""
    f = float(x)
    return f if Fraction(f) >= x else math.nextafter(f, math.inf)


def arb_exact(x: flint.arb) -> Fraction:
    """The exact value of an exact (zero-radius) arb as a Fraction."""
    man, exp = x.mid().man_exp()
    man, exp = int(man), int(exp)
    return Fraction(man) * (Fraction(2) ** exp)


def round_expr(expr: sp.Expr) -> tuple[float, float]:
    """(down, up): floats with down ≤ expr ≤ up for the exact real sympy number ``expr``.

    Rationals are rounded exactly (1/2 gives (0.5, 0.5)); other numbers are evaluated to 60
    significant digits (mpmath evalf, which tracks its accuracy) and widened by 1e-50 relative
    before the directed rounding.
    """
    expr = sp.nsimplify(expr) if isinstance(expr, sp.Float) else expr
    if expr.is_Rational:
        x = Fraction(int(expr.p), int(expr.q))
        return float_down(x), float_up(x)
    v = sp.N(expr, 60)
    if not v.is_real:
        raise ValueError("not a real number")
    x = Fraction(str(v))
    pad = abs(x) * Fraction(1, 10 ** 50) + Fraction(1, 10 ** 300)
    return float_down(x - pad), float_up(x + pad)


@_with_precision
def spectral_radius2_bounds(system: System) -> tuple[Fraction, Fraction] | None:
    """Rigorous bounds lo ≤ ρ(A)² ≤ hi from ball eigenvalues of the exact A (None if the
    enclosure fails; multiple eigenvalues are enclosed as clusters, python-flint acb_mat.eig
    with ``multiple=True``)."""
    try:
        A = flint.acb_mat(arb_from_sympy(system.A))
        eigs = A.eig(multiple=True)
    except (ValueError, ZeroDivisionError, TypeError):
        return None
    lo, hi = Fraction(0), Fraction(0)
    for z in eigs:
        m2 = z.real * z.real + z.imag * z.imag
        if not m2.is_finite():
            return None
        a, b = arb_exact(m2.lower()), arb_exact(m2.upper())
        lo, hi = max(lo, max(a, Fraction(0))), max(hi, b)
    return lo, hi


@_with_precision
def exact_product(M: np.ndarray, B: sp.MatrixBase) -> np.ndarray:
    """M·B for a float matrix M and an exact matrix B, formed in balls and rounded once to
    float64 (no cancellation error from the float product)."""
    P = arb_from_float(M) * arb_from_sympy(B)
    return np.array([[float(e.mid()) for e in row] for row in P.tolist()])


def arb_exact_number(x: sp.Expr | Fraction | int) -> flint.arb:
    """A ball containing the exact number ``x`` (a point ball when ``x`` is rational)."""
    if isinstance(x, Fraction | int):
        return flint.arb(flint.fmpq(Fraction(x).numerator, Fraction(x).denominator))
    return _arb_number(x)


@_with_precision
def verify_markov_jump(system: System, failure_rate: sp.Expr, recovery_rate: sp.Expr,
                       X0: np.ndarray, X1: np.ndarray, K: np.ndarray) -> CheckResult:
    r"""Prove mean-square stability of the Gilbert–Elliott fixed-gain error system, in balls.

    With the chain state γ ∈ {0 (lost), 1 (received)}, T = [[1−r, r], [f, 1−f]]
    (T_ij = P(next j | now i)), F_0 = A, F_1 = A + K C, the checked inequalities are

    .. math::

        X_i \succ 0,\qquad X_i - F_i' \Bigl(\sum_j T_{ij} X_j\Bigr) F_i \succ 0 \quad (i = 0, 1),

    the coupled Lyapunov inequalities of the adjoint of the positive map
    (Y_0, Y_1) ↦ (Σ_i T_i0 F_i Y_i F_i', Σ_i T_i1 F_i Y_i F_i'); they hold iff its spectral
    radius is < 1 (a positive linear map on a cone with an interior point X ≻ M*(X)).
    A, C, f, r are the exact numbers (rationals as point balls), X_0, X_1, K the floats as
    given. The result's ``p`` is the stationary arrival probability r/(f + r).
    """
    kind = "markov: X_i > 0 and X_i - F_i' (sum_j T_ij X_j) F_i > 0, i = 0, 1"
    # the check's p is the chain's stationary arrival probability r/(f + r) (for the record)
    fr = sp.sympify(failure_rate) + sp.sympify(recovery_rate)
    p_stat = float(sp.sympify(recovery_rate) / fr) if fr != 0 else 0.0
    n, m = system.n, system.m
    try:
        A = arb_from_sympy(system.A)
        C = arb_from_sympy(system.C)
        f = arb_exact_number(failure_rate)
        r = arb_exact_number(recovery_rate)
        Xa = [arb_from_float(np.asarray(X, dtype=float)) for X in (X0, X1)]
        Ka = arb_from_float(np.asarray(K, dtype=float).reshape(n, m))
    except (ValueError, TypeError) as exc:
        return CheckResult(False, kind, p_stat, None, None, f"bad certificate: {exc}")
    if any(X.nrows() != n or X.ncols() != n for X in Xa):
        return CheckResult(False, kind, p_stat, None, None, "bad shape")
    one = flint.arb(1)
    Xs = [(X + X.transpose()) * flint.arb(0.5) for X in Xa]
    margins_x = [definite_margin(X) for X in Xs]
    if any(mx is None for mx in margins_x):
        return CheckResult(False, kind, p_stat, None, None,
                           "X_0 or X_1 is not proven positive definite")
    F = [A, A + Ka * C]
    S = [(one - r) * Xs[0] + r * Xs[1], f * Xs[0] + (one - f) * Xs[1]]
    margins = []
    for i in (0, 1):
        mm = definite_margin(Xs[i] - F[i].transpose() * S[i] * F[i])
        if mm is None:
            return CheckResult(False, kind, p_stat, min(margins_x), None,
                               f"X_{i} - F_{i}' S_{i} F_{i} is not proven positive definite")
        margins.append(mm)
    return CheckResult(True, kind, p_stat, min(margins_x), min(margins), "proven")


def _arb_trace(M: flint.arb_mat) -> flint.arb:
    return sum((M[i, i] for i in range(M.nrows())), flint.arb(0))


@_with_precision
def verify_lyapunov_below(system: System, p: Fraction, S: np.ndarray,
                          level: Fraction) -> CheckResult:
    r"""Prove tr S̄(p) ≥ ``level`` from S with (1−p) A S A' + Q − S ≻ 0 and tr S ≥ level.

    .. math::

        \bar S - S = \sum_{k \ge 0} \mathcal L^k\bigl(Q + \mathcal L(S) - S\bigr) \succeq 0,
        \qquad \mathcal L(X) = (1-p) A X A',

    whenever S̄ exists (ρ(𝓛) < 1); otherwise E[P_t] is unbounded, which is stronger. A, Q, p
    and ``level`` are exact, S the floats as given.
    """
    kind = "lyapunov: (1-p) A S A' + Q - S > 0 and tr S >= L, so tr S_bar(p) >= L"
    try:
        A, Q = arb_from_sympy(system.A), arb_from_sympy(system.Q)
        Sa = arb_from_float(np.asarray(S, dtype=float))
    except (ValueError, TypeError) as exc:
        return CheckResult(False, kind, float(p), None, None, f"bad certificate: {exc}")
    pa = arb_exact_number(Fraction(p))
    Sa = (Sa + Sa.transpose()) * flint.arb(0.5)
    mm = definite_margin((1 - pa) * (A * Sa * A.transpose()) + Q - Sa)
    if mm is None:
        return CheckResult(False, kind, float(p), None, None,
                           "(1-p) A S A' + Q - S is not proven positive definite")
    if not (_arb_trace(Sa) - arb_exact_number(Fraction(level))) >= 0:
        return CheckResult(False, kind, float(p), None, mm, "tr S >= L not proven")
    return CheckResult(True, kind, float(p), None, mm, "proven")


@_with_precision
def verify_mare_above(system: System, p: Fraction, V: np.ndarray, K: np.ndarray,
                      level: Fraction) -> CheckResult:
    r"""Prove tr V̄(p) ≤ ``level`` from (V, K) with V − φ(K, V) ≻ 0 and tr V ≤ level.

    .. math::

        \varphi(K, V) = (1-p)(A V A' + Q) + p\,(F V F' + Q + K R K') \succeq g_p(V),
        \quad F = A + K C \quad\text{(Sinopoli Lemma 1(b))},

    so the MARE iterates from 0 stay below V (g_p monotone): V̄(p) ⪯ V.
    """
    kind = "mare: V - phi(K, V) > 0 and tr V <= L, so tr V_bar(p) <= L"
    n, m = system.n, system.m
    try:
        A, C = arb_from_sympy(system.A), arb_from_sympy(system.C)
        Q, R = arb_from_sympy(system.Q), arb_from_sympy(system.R)
        Va = arb_from_float(np.asarray(V, dtype=float))
        Ka = arb_from_float(np.asarray(K, dtype=float).reshape(n, m))
    except (ValueError, TypeError) as exc:
        return CheckResult(False, kind, float(p), None, None, f"bad certificate: {exc}")
    pa = arb_exact_number(Fraction(p))
    Va = (Va + Va.transpose()) * flint.arb(0.5)
    F = A + Ka * C
    phi = (1 - pa) * (A * Va * A.transpose() + Q) + pa * (F * Va * F.transpose() + Q
                                                         + Ka * R * Ka.transpose())
    mm = definite_margin(Va - phi)
    if mm is None:
        return CheckResult(False, kind, float(p), None, None,
                           "V - phi(K, V) is not proven positive definite")
    if not (arb_exact_number(Fraction(level)) - _arb_trace(Va)) >= 0:
        return CheckResult(False, kind, float(p), None, mm, "tr V <= L not proven")
    return CheckResult(True, kind, float(p), None, mm, "proven")


@_with_precision
def riccati_floor_exceeds(system: System, level: Fraction,
                          max_steps: int = 400) -> tuple[bool, int]:
    r"""Prove tr P_∞ > ``level`` for the stabilising DARE solution P_∞ (the error with every
    packet delivered) by the Riccati iterates from 0 in balls, which increase to P_∞:

    .. math::

        P_{k+1} = A P_k A' + Q - A P_k C' (C P_k C' + R)^{-1} C P_k A', \quad P_0 = 0 .

    Returns (proven, steps). Since lim E[P_t] ⪰ P_∞ for every arrival probability, a proof
    means the requirement lim E[tr P] ≤ level is out of reach.
    """
    A, C = arb_from_sympy(system.A), arb_from_sympy(system.C)
    Q, R = arb_from_sympy(system.Q), arb_from_sympy(system.R)
    L = arb_exact_number(Fraction(level))
    P = flint.arb_mat(system.n, system.n)
    for k in range(1, max_steps + 1):
        AP = A * P
        S = C * P * C.transpose() + R
        try:
            G = AP * C.transpose() * S.inv()
        except (ZeroDivisionError, ValueError):
            return False, k
        P = AP * A.transpose() + Q - G * C * P * A.transpose()
        P = (P + P.transpose()) * flint.arb(0.5)
        tr = _arb_trace(P)
        if not tr.is_finite():
            return False, k
        if tr > L:
            return True, k
    return False, max_steps
