"""Reusable Hypothesis strategies for kfcrit's property tests.

Every matrix is generated *by construction* from bounded Hypothesis floats or integers, so every
example shrinks and no strategy touches NumPy's random generator:

* orthogonal matrices are products of Givens rotations whose angles Hypothesis draws;
* a matrix with condition number at most κ is U diag(s) W' with U, W orthogonal, s ∈ [1, κ];
* PD matrices are U diag(s) U' with s in a stated range; PSD matrices are L L' + δ I (L possibly
  with fewer columns than rows, δ ≥ 0, so rank-deficient PSD matrices occur);
* pairs X ⪯ Y are (X, X + D) with D PSD;
* a system matrix with a prescribed spectrum is A = V J V^{-1}, J the real block-diagonal form
  (real eigenvalues, and ρ [[cos θ, −sin θ], [sin θ, cos θ]] blocks for the pairs ρ e^{±jθ}),
  V with bounded condition number — so the eigenvalues of A are known independently of any
  eigenvalue solver (they are the reference in the spectral properties);
* exact systems (sympy rationals) are T D T^{-1} with T an integer unimodular matrix, for the
  properties decided in exact arithmetic (Mo–Sinopoli classification, critical values).

The papers' systems are exported as constants (``PAPER_CASES``) for ``@example``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import sympy as sp
from hypothesis import strategies as st

# --------------------------------------------------------------------------------------------
# scalars


TINY = 1e-100
"""Magnitudes below this are generated as 0 (System accepts |x| ≥ 1e-300 only, and such values
exercise no mathematics, only the exponent range)."""


def bounded_floats(lo: float, hi: float) -> st.SearchStrategy[float]:
    """Finite floats in [lo, hi] (no NaN, no infinity, no subnormals, |x| < TINY → 0)."""
    return st.floats(lo, hi, allow_nan=False, allow_infinity=False, allow_subnormal=False).map(
        lambda x: 0.0 if abs(x) < TINY and lo <= 0.0 <= hi else x)


def arrival_probabilities(lo: float = 0.0, hi: float = 1.0) -> st.SearchStrategy[float]:
    """Arrival probabilities p ∈ [lo, hi]; the end points are always among the examples tried."""
    return st.one_of(st.sampled_from([lo, hi]), bounded_floats(lo, hi))


def probability_pairs() -> st.SearchStrategy[tuple[float, float]]:
    """Pairs p1 ≤ p2 in [0, 1]."""
    return st.tuples(bounded_floats(0, 1), bounded_floats(0, 1)).map(lambda t: tuple(sorted(t)))


# --------------------------------------------------------------------------------------------
# orthogonal, conditioned, PD and PSD matrices


def givens_product(n: int, angles: list[float]) -> np.ndarray:
    """Orthogonal matrix Π_{i<j} G_{ij}(θ_ij) from n(n−1)/2 angles (identity for n = 1)."""
    U = np.eye(n)
    k = 0
    for i in range(n):
        for j in range(i + 1, n):
            c, s = math.cos(angles[k]), math.sin(angles[k])
            G = np.eye(n)
            G[i, i] = G[j, j] = c
            G[i, j], G[j, i] = -s, s
            U = U @ G
            k += 1
    return U


@st.composite
def orthogonal_matrices(draw: st.DrawFn, n: int) -> np.ndarray:
    """n×n orthogonal matrices (Givens products; angles in [−π, π])."""
    count = n * (n - 1) // 2
    angles = draw(st.lists(bounded_floats(-math.pi, math.pi), min_size=count, max_size=count))
    return givens_product(n, angles)


@st.composite
def conditioned_matrices(draw: st.DrawFn, n: int, max_condition: float = 10.0) -> np.ndarray:
    """n×n matrices U diag(s) W' with 1 = s_min ≤ s ≤ s_max ≤ max_condition (cond ≤ κ)."""
    U = draw(orthogonal_matrices(n))
    W = draw(orthogonal_matrices(n))
    s = draw(st.lists(bounded_floats(1.0, max_condition), min_size=n, max_size=n))
    s[0] = 1.0
    return U @ np.diag(s) @ W.T


@st.composite
def pd_matrices(draw: st.DrawFn, n: int, min_eig: float = 0.1,
                max_eig: float = 10.0) -> np.ndarray:
    """Symmetric positive definite U diag(s) U', s ∈ [min_eig, max_eig] (exactly symmetric)."""
    U = draw(orthogonal_matrices(n))
    s = draw(st.lists(bounded_floats(min_eig, max_eig), min_size=n, max_size=n))
    M = U @ np.diag(s) @ U.T
    return 0.5 * (M + M.T)


@st.composite
def psd_matrices(draw: st.DrawFn, n: int, max_entry: float = 2.0,
                 max_delta: float = 1.0) -> np.ndarray:
    """Symmetric PSD L L' + δ I; L is n×k with k ∈ [0, n] (rank-deficient when k < n, δ = 0)."""
    k = draw(st.integers(0, n))
    L = np.array(draw(st.lists(bounded_floats(-max_entry, max_entry), min_size=n * k,
                               max_size=n * k))).reshape(n, k)
    delta = draw(st.one_of(st.just(0.0), bounded_floats(0.0, max_delta)))
    M = L @ L.T + delta * np.eye(n)
    return 0.5 * (M + M.T)


@st.composite
def psd_pairs(draw: st.DrawFn, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (X, Y) of PSD matrices with X ⪯ Y (Y = X + D, D PSD)."""
    X = draw(psd_matrices(n))
    D = draw(psd_matrices(n))
    return X, X + D


# --------------------------------------------------------------------------------------------
# spectra and systems


@dataclass(frozen=True)
class Spectrum:
    """Eigenvalues given by construction: real ones and complex pairs ρ e^{±jθ}, θ ∈ (0, π)."""

    real: tuple[float, ...]
    pairs: tuple[tuple[float, float], ...]

    @property
    def n(self) -> int:
        return len(self.real) + 2 * len(self.pairs)

    def eigenvalues(self) -> np.ndarray:
        """All eigenvalues (complex array, pairs listed as ρe^{jθ}, ρe^{−jθ})."""
        out = [complex(r) for r in self.real]
        for rho, theta in self.pairs:
            out += [rho * complex(math.cos(theta), math.sin(theta)),
                    rho * complex(math.cos(theta), -math.sin(theta))]
        return np.array(out, dtype=complex)

    @property
    def radius(self) -> float:
        """Spectral radius max |λ_i| (from the construction, not from an eigen-solver)."""
        mods = [abs(r) for r in self.real] + [rho for rho, _ in self.pairs]
        return max(mods)

    def real_form(self) -> np.ndarray:
        """Real block-diagonal J: diag(real) and ρ[[cos θ, −sin θ], [sin θ, cos θ]] blocks."""
        J = np.zeros((self.n, self.n))
        for i, r in enumerate(self.real):
            J[i, i] = r
        k = len(self.real)
        for rho, theta in self.pairs:
            c, s = rho * math.cos(theta), rho * math.sin(theta)
            J[k:k + 2, k:k + 2] = [[c, -s], [s, c]]
            k += 2
        return J


SPECTRUM_KINDS = ("stable", "critical", "unstable", "any")


@st.composite
def spectra(draw: st.DrawFn, n: int, kind: str = "any", top_count: int | None = None,
            max_modulus: float = 2.5) -> Spectrum:
    """Spectra of n×n real matrices with a controlled largest modulus.

    Parameters
    ----------
    kind : {"stable", "critical", "unstable", "any"}
        Largest modulus ρ: ≤ 0.95 (stable), exactly 1 (critically stable), in [1.05, max_modulus]
        (unstable), or anything in [0, max_modulus].
    top_count : int, optional
        Number of *units* (a real eigenvalue or a complex pair) sharing the largest modulus
        exactly (an equal-modulus structure). Others have modulus ≤ 0.9 ρ (a strict gap), so
        exactly ``top_count`` units attain ρ. Default: drawn.
    """
    if kind not in SPECTRUM_KINDS:
        raise ValueError(f"kind must be one of {SPECTRUM_KINDS}")
    n_pairs = draw(st.integers(0, n // 2))
    n_real = n - 2 * n_pairs
    units = n_real + n_pairs
    if top_count is None:
        top_count = draw(st.integers(1, units))
    top_count = max(1, min(top_count, units))
    if kind == "stable":
        rho = draw(bounded_floats(0.05, 0.95))
    elif kind == "critical":
        rho = 1.0
    elif kind == "unstable":
        rho = draw(bounded_floats(1.05, max_modulus))
    else:
        rho = draw(bounded_floats(0.05, max_modulus))
    mods = [rho] * top_count + draw(st.lists(bounded_floats(0.0, 0.9 * rho),
                                             min_size=units - top_count,
                                             max_size=units - top_count))
    order = draw(st.permutations(range(units)))
    mods = [mods[i] for i in order]
    real = tuple(m * draw(st.sampled_from([1.0, -1.0])) for m in mods[:n_real])
    pairs = tuple((m, draw(bounded_floats(0.05, math.pi - 0.05))) for m in mods[n_real:])
    return Spectrum(real, pairs)


@dataclass(frozen=True, eq=False)
class SystemCase:
    """A float system (A, C, Q, R) together with its spectrum known by construction."""

    A: np.ndarray
    C: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    spectrum: Spectrum | None = None

    @property
    def n(self) -> int:
        return self.A.shape[0]

    @property
    def m(self) -> int:
        return self.C.shape[0]


@st.composite
def output_matrices(draw: st.DrawFn, m: int, n: int, max_entry: float = 2.0) -> np.ndarray:
    """m×n output matrices with entries in [−max_entry, max_entry]."""
    values = draw(st.lists(bounded_floats(-max_entry, max_entry), min_size=m * n,
                           max_size=m * n))
    return np.array(values).reshape(m, n)


@st.composite
def systems(draw: st.DrawFn, n: int | None = None, m: int | None = None, kind: str = "any",
            top_count: int | None = None, max_condition: float = 10.0,
            max_n: int = 4) -> SystemCase:
    """Float systems A = V J V^{-1} with a chosen spectrum, cond(V) ≤ max_condition.

    C has bounded entries; Q and R are PD with eigenvalues in [0.1, 10].
    """
    n = draw(st.integers(1, max_n)) if n is None else n
    m = draw(st.integers(1, n)) if m is None else m
    spec = draw(spectra(n, kind=kind, top_count=top_count))
    V = draw(conditioned_matrices(n, max_condition))
    A = V @ spec.real_form() @ np.linalg.inv(V)
    C = draw(output_matrices(m, n))
    Q = draw(pd_matrices(n))
    R = draw(pd_matrices(m))
    return SystemCase(A, C, Q, R, spec)


# --------------------------------------------------------------------------------------------
# exact systems (sympy rationals)


def small_rationals(max_num: int = 9, max_den: int = 4) -> st.SearchStrategy[sp.Rational]:
    """Rationals a/b with |a| ≤ max_num, 1 ≤ b ≤ max_den."""
    return st.builds(sp.Rational, st.integers(-max_num, max_num), st.integers(1, max_den))


@st.composite
def unimodular_matrices(draw: st.DrawFn, n: int, shears: int = 3) -> sp.Matrix:
    """Integer matrices with determinant ±1: products of elementary shears and a permutation."""
    T = sp.eye(n)
    if n == 1:
        return T
    for _ in range(draw(st.integers(0, shears))):
        i, j = draw(st.sampled_from([(i, j) for i in range(n) for j in range(n) if i != j]))
        k = draw(st.integers(-2, 2))
        E = sp.eye(n)
        E[i, j] = k
        T = T * E
    perm = draw(st.permutations(range(n)))
    return T.extract(list(perm), list(range(n)))


@st.composite
def similarity_transforms(draw: st.DrawFn, n: int, max_condition: float = 60.0) -> sp.Matrix:
    """A non-trivial invertible integer T of size n (n ≥ 2): at least one shear, then a
    permutation, with cond₂(T) ≤ ``max_condition`` (well-conditioned, so that float views of
    T A T⁻¹ stay accurate). For n = 1, a nonzero integer scale 2 or −3 (a scalar similarity is
    trivial on A but still rescales C)."""
    if n == 1:
        return sp.Matrix([[draw(st.sampled_from([2, -3]))]])
    T = sp.eye(n)
    for _ in range(draw(st.integers(1, 3))):
        i, j = draw(st.sampled_from([(i, j) for i in range(n) for j in range(n) if i != j]))
        E = sp.eye(n)
        E[i, j] = draw(st.sampled_from([-2, -1, 1, 2]))
        T = T * E
    if T == sp.eye(n):             # the shears cancelled: keep T non-trivial
        T[0, 1] = 1
    perm = draw(st.permutations(range(n)))
    T = T.extract(list(perm), list(range(n)))
    cond = float(np.linalg.cond(np.array(T.tolist(), dtype=float)))
    if cond > max_condition:       # fall back to the permuted unit bidiagonal (cond ≤ 2n)
        B = sp.eye(n) + sp.Matrix(n, n, lambda i, j: 1 if j == i + 1 else 0)
        T = B.extract(list(perm), list(range(n)))
    return T


@dataclass(frozen=True, eq=False)
class ExactCase:
    """An exact system: A = T D T^{-1} with known real block form D and integer T (det ±1)."""

    A: sp.Matrix
    C: sp.Matrix
    Q: sp.Matrix
    R: sp.Matrix
    D: sp.Matrix
    T: sp.Matrix


def _same_modulus(block: sp.Matrix, variant: int) -> sp.Matrix:
    """A block with the same eigenvalue modulus as ``block`` (sign flip, conjugate, rotation)."""
    if block.shape == (1, 1):
        return -block if variant % 2 else block
    a, b = block[0, 0], block[1, 0]
    choices = [sp.Matrix([[a, b], [-b, a]]), sp.Matrix([[b, -a], [a, b]]),
               sp.Matrix([[-a, -b], [b, -a]])]
    out = choices[variant % 3]
    return out if out[1, 0] != 0 else block


@st.composite
def exact_real_form(draw: st.DrawFn, n: int, kind: str = "unstable",
                    equal_modulus: bool | None = None) -> sp.Matrix:
    """Block-diagonal D with rational real eigenvalues and [[a, −b], [b, a]] blocks (b ≠ 0).

    ``kind="unstable"`` forces the first block to have modulus > 1. ``equal_modulus`` (default:
    drawn) makes the second block, when it has the first block's shape, share its modulus
    (−λ for a real eigenvalue; a conjugate or rotated copy of a 2×2 block): an equi-block.
    """
    blocks: list[sp.Matrix] = []
    size = 0
    while size < n:
        two = size + 2 <= n and draw(st.booleans())
        if two:
            a = draw(small_rationals(4, 2))
            b = draw(small_rationals(4, 2).filter(lambda v: v != 0))
            blocks.append(sp.Matrix([[a, -b], [b, a]]))
            size += 2
        else:
            blocks.append(sp.Matrix([[draw(small_rationals(5, 2))]]))
            size += 1
    if kind == "unstable":
        first = blocks[0]
        if first.shape == (1, 1):
            blocks[0] = sp.Matrix([[draw(st.sampled_from([sp.Rational(3, 2), -2, 2, -3]))]])
        elif first[0, 0] ** 2 + first[1, 0] ** 2 <= 1:
            # scale so that max(|a|, |b|) = 2: the modulus is then ≥ 2 and stays rational
            blocks[0] = first * 2 / max(abs(first[0, 0]), abs(first[1, 0]))
    if equal_modulus is None:
        equal_modulus = draw(st.booleans())
    if equal_modulus and len(blocks) >= 2 and blocks[1].shape == blocks[0].shape:
        blocks[1] = _same_modulus(blocks[0], draw(st.integers(0, 5)))
    return sp.diag(*blocks)


@st.composite
def exact_systems(draw: st.DrawFn, n: int | None = None, m: int | None = None,
                  kind: str = "unstable", max_n: int = 4,
                  equal_modulus: bool | None = None) -> ExactCase:
    """Exact rational systems A = T D T^{-1}; C small integers; Q = R = I scaled by rationals."""
    n = draw(st.integers(1, max_n)) if n is None else n
    m = draw(st.integers(1, n)) if m is None else m
    D = draw(exact_real_form(n, kind, equal_modulus))
    T = draw(unimodular_matrices(n))
    A = T * D * T.inv()
    C = sp.Matrix(m, n, draw(st.lists(st.integers(-2, 2), min_size=m * n, max_size=m * n)))
    if all(v == 0 for v in C):
        C[0, 0] = 1
    q = draw(st.sampled_from([sp.Integer(1), sp.Rational(1, 2), sp.Integer(3)]))
    r = draw(st.sampled_from([sp.Integer(1), sp.Rational(5, 2)]))
    return ExactCase(A, C, q * sp.eye(n), r * sp.eye(m), D, T)


# --------------------------------------------------------------------------------------------
# the papers' systems, for @example (exact entries as sympy; float views via PAPER_FLOAT_CASES)


def _case(A, C, Q, R) -> dict[str, sp.Matrix]:
    return {"A": sp.Matrix(A), "C": sp.Matrix(C), "Q": sp.Matrix(Q), "R": sp.Matrix(R)}


_r = sp.Rational
PAPER_CASES: dict[str, dict[str, sp.Matrix]] = {
    # Sinopoli et al. 2004, scalar example: p_c = 9/25
    "sinopoli-scalar": _case([[_r(-5, 4)]], [[1]], [[1]], [[_r(5, 2)]]),
    # Sinopoli et al. 2004, one unstable eigenvalue: p_c = 9/25
    "sinopoli-single-unstable": _case([[_r(5, 4), 1, 0], [0, _r(9, 10), 7], [0, 0, _r(3, 5)]],
                                      [[1, 0, 2]], 20 * sp.eye(3), [[_r(5, 2)]]),
    # Sinopoli et al. 2004, general case: p_low = 9/25, p_up = 57/121; p_c = 9/25 (Mo–Sinopoli)
    "sinopoli-general": _case([[_r(5, 4), 0], [1, _r(11, 10)]], [[1, 1]], 20 * sp.eye(2),
                              [[_r(5, 2)]]),
    # Mo–Sinopoli degenerate pair: q = 2, p_c = 15/16
    "mo-degenerate-diagonal": _case([[2, 0], [0, -2]], [[1, 1]], sp.eye(2), [[1]]),
    # Mo–Sinopoli non-degenerate four states: p_c = 8/9
    "mo-nondegenerate-four": _case(sp.diag(2, -2, 3, -3), [[1, 0, 1, 0], [0, 1, 0, 1]],
                                   sp.eye(4), sp.eye(2)),
    # rotation by π/3 with modulus 2: q = 3, p_c = 1 − 2^{-3} = 7/8
    "rotation-third-turn": _case([[1, -sp.sqrt(3)], [sp.sqrt(3), 1]], [[1, 0]], sp.eye(2),
                                 [[1]]),
    # Kar–Sinopoli–Moura scalar fractal example: p_c = 1/2
    "kar-scalar-fractal": _case([[sp.sqrt(2)]], [[1]], [[1]], [[1]]),
}


def float_case(name: str) -> SystemCase:
    """Float64 view of one of ``PAPER_CASES``."""
    c = PAPER_CASES[name]
    f = {k: np.array(v.evalf(30).tolist(), dtype=float) for k, v in c.items()}
    return SystemCase(f["A"], f["C"], f["Q"], f["R"])


PAPER_FLOAT_CASES: dict[str, SystemCase] = {name: float_case(name) for name in PAPER_CASES}


# --------------------------------------------------------------------------------------------
# inputs of the Riccati-map properties


@dataclass(frozen=True, eq=False)
class RiccatiInput:
    """A system with two PSD points X ⪯ Y, a gain K, a weight α and probabilities p ≤ p2."""

    case: SystemCase
    X: np.ndarray
    Y: np.ndarray
    K: np.ndarray
    alpha: float
    p: float
    p2: float


@st.composite
def riccati_inputs(draw: st.DrawFn, kind: str = "any", max_n: int = 4) -> RiccatiInput:
    """Inputs for Sinopoli Lemma 1: systems of size ≤ max_n, X ⪯ Y PSD, any gain K."""
    case = draw(systems(kind=kind, max_n=max_n))
    X, Y = draw(psd_pairs(case.n))
    K = draw(output_matrices(case.n, case.m, max_entry=3.0))
    alpha = draw(bounded_floats(0.0, 1.0))
    p, p2 = draw(probability_pairs())
    return RiccatiInput(case, X, Y, K, alpha, p, p2)


def paper_riccati_input(name: str, p: float = 0.5) -> RiccatiInput:
    """A :class:`RiccatiInput` on one of the papers' systems (X = I ⪯ Y = 2I, K = 0)."""
    case = PAPER_FLOAT_CASES[name]
    n, m = case.n, case.m
    return RiccatiInput(case, np.eye(n), 2 * np.eye(n), np.zeros((n, m)), 0.5, p,
                        min(1.0, p + 0.25))


@st.composite
def exact_pd_matrices(draw: st.DrawFn, n: int) -> sp.Matrix:
    """Exact positive definite L L' + I with L a small integer matrix."""
    L = sp.Matrix(n, n, draw(st.lists(st.integers(-2, 2), min_size=n * n, max_size=n * n)))
    return L * L.T + sp.eye(n)


# --------------------------------------------------------------------------------------------
# degenerate second-order systems with a known critical value (Mo–Sinopoli Thm 9, 10)

_S2, _S3 = sp.sqrt(2), sp.sqrt(3)
ROTATIONS: tuple[tuple[sp.Expr, sp.Expr, int | None], ...] = (
    # (cos θ, sin θ, q): z = e^{∓2jθ}, q its order as a root of unity (None: not a root of unity)
    (sp.Integer(0), sp.Integer(1), 2),                  # θ = π/2
    (sp.Rational(1, 2), _S3 / 2, 3),                    # θ = π/3
    (-sp.Rational(1, 2), _S3 / 2, 3),                   # θ = 2π/3
    (_S2 / 2, _S2 / 2, 4),                              # θ = π/4
    (-_S2 / 2, _S2 / 2, 4),                             # θ = 3π/4
    (_S3 / 2, sp.Rational(1, 2), 6),                    # θ = π/6
    (1 / sp.sqrt(5), 2 / sp.sqrt(5), None),             # θ = atan 2: (−3+4j)/5 is no root of 1
    (sp.Rational(4, 5), sp.Rational(3, 5), None),       # θ = atan(3/4): (7+24j)/25 likewise
)


@dataclass(frozen=True, eq=False)
class DegenerateCase:
    """A degenerate equal-modulus pair (modulus ρ) hidden by a similarity, with its q."""

    A: sp.Matrix
    C: sp.Matrix
    rho: sp.Expr
    q: int | None

    def expected(self) -> sp.Expr:
        """p_c = max(1 − ρ^{−2q/(q−1)}, 0) (Thm 9) or max(1 − ρ^{−2}, 0) (Thm 10)."""
        if self.q is None:
            return sp.Max(1 - self.rho ** -2, 0)
        return sp.Max(1 - self.rho ** sp.Rational(-2 * self.q, self.q - 1), 0)


@st.composite
def degenerate_pairs(draw: st.DrawFn, with_stable: bool | None = None) -> DegenerateCase:
    """ρ·rotation(θ) or diag(ρ, −ρ) seen through one output, optionally with a stable mode."""
    rho = draw(st.sampled_from([sp.Integer(1), sp.Rational(3, 2), sp.Integer(2),
                                sp.Rational(5, 2), sp.Integer(3)]))
    if draw(st.booleans()):
        c, s, q = draw(st.sampled_from(ROTATIONS))
        block = rho * sp.Matrix([[c, -s], [s, c]])
        col = [draw(st.integers(-2, 2)), draw(st.integers(-2, 2))]
        if col == [0, 0]:
            col = [1, 0]
    else:
        block, q = sp.diag(rho, -rho), 2
        col = [draw(st.sampled_from([-2, -1, 1, 2])), draw(st.sampled_from([-2, -1, 1, 2]))]
    if with_stable is None:
        with_stable = draw(st.booleans())
    D, cols = block, col
    if with_stable:
        D = sp.diag(block, draw(st.sampled_from([sp.Rational(1, 2), -sp.Rational(2, 3),
                                                 sp.Integer(0)])))
        cols = col + [draw(st.integers(-2, 2))]
    T = draw(unimodular_matrices(D.shape[0]))
    CT = sp.Matrix([cols])
    return DegenerateCase(sp.simplify(T * D * T.inv()), sp.simplify(CT * T.inv()), rho, q)
