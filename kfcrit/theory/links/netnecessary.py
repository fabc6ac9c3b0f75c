"""The necessary surface of a sensor network (docs/theory.md §9.2) and the modal one-step
observability that makes it the exact region (docs/theory.md §15.6; the proof is in
:mod:`kfcrit.theory.links.network`).

For every sensor set T, ρ_T = the largest |λ| among the eigenvalues of A not observable through
C_T (PBH); p ∈ 𝓢 requires Π_{i∉T}(1 − p_i)·ρ_T² < 1. Eigenvalues are exact where the structure
path is exact, and for an exact diagonal A at any size (the diagonal entries); otherwise floats.
"""
from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy as sp

from kfcrit.errors import KfcritError, NumericalError
from kfcrit.model.exprparse import compare
from kfcrit.model.network import Network
from kfcrit.theory.critical.section import structure_of
from kfcrit.theory.links import netkernels as nk

FLAT_BUDGET = 20000
"""Most sensor combinations tried per eigenvalue when enumerating hyperplanes (g ≥ 2)."""
RANK_TOL = 1e-9
"""Relative tolerance of the float rank decisions (σ ≤ RANK_TOL·max(‖C‖, 1) counts as 0)."""
# ---- the necessary surface

@dataclass(frozen=True)
class Constraint:
    """Necessary condition Π_{i∉T}(1 − p_i)·ρ_T² < 1 for a maximal unobservable set T."""

    blind: frozenset[int]
    mod2: float
    mod2_expr: sp.Expr | None
    eigenvalue: str
    decided: str

    def factor(self, p: np.ndarray) -> float:
        """ρ_T² Π_{i∉T}(1 − p_i) in floats."""
        out = self.mod2
        for i in range(p.size):
            if i not in self.blind:
                out *= 1.0 - float(p[i])
        return out

    def factor_expr(self, p_exact: Sequence[sp.Expr | None]) -> sp.Expr | None:
        """The same exactly (None when an ingredient is not exact)."""
        if self.mod2_expr is None:
            return None
        out = self.mod2_expr
        for i, pi in enumerate(p_exact):
            if i not in self.blind:
                if pi is None:
                    return None
                out = out * (1 - pi)
        return out


def _exact_eigvecs(A: sp.Matrix, lam: sp.Expr) -> list[sp.Matrix] | None:
    """Exact eigenvectors for a rational eigenvalue (None otherwise or on failure)."""
    if not (lam is not None and lam.is_Rational):
        return None
    try:
        return (A - lam * sp.eye(A.shape[0])).nullspace()
    except (ValueError, TypeError, ArithmeticError, NotImplementedError):
        return None


@dataclass(frozen=True)
class DiagonalMode:
    """An exact eigenvalue d of a diagonal A with |d| ≥ 1 and its eigenvectors e_k (A_kk = d)."""

    expr: sp.Expr
    columns: tuple[int, ...]

    @property
    def mod2_expr(self) -> sp.Expr:
        return self.expr ** 2

    @property
    def mod2(self) -> float:
        return float(sp.N(self.mod2_expr, 30))

    @property
    def text(self) -> str:
        return sp.sstr(self.expr)


def diagonal_modes(network: Network) -> list[DiagonalMode] | None:
    """The modes with |λ| ≥ 1 of an exact diagonal A with real entries, decided exactly (the
    eigenvalues are the diagonal entries, the eigenvectors unit vectors) — at any n, where the
    general structure path falls back to floats (None when A is not exact and diagonal)."""
    if not network.exact:
        return None
    A = sp.Matrix(network.A)
    if not A.is_diagonal() or not all(d.is_real for d in A.diagonal()):
        return None
    if any(isinstance(d, sp.Float) for d in A.diagonal()):
        return None
    cols: dict[sp.Expr, list[int]] = {}
    for k in range(A.shape[0]):
        cols.setdefault(A[k, k], []).append(k)
    try:
        out = [DiagonalMode(d, tuple(ks)) for d, ks in cols.items()
               if compare(d ** 2, 1, "A", "|λ|² - 1") >= 0]
    except KfcritError:
        return None
    return sorted(out, key=lambda m: -m.mod2)


def relevant_modes(network: Network) -> tuple[list[Any], list[DiagonalMode] | None]:
    """The eigenvalues with |λ| ≥ 1: exact diagonal modes where A is exact and diagonal and the
    structure is not exact, else the structure's (docs/theory.md §9.2)."""
    st = structure_of(network.stacked_system())
    rel = [e for i, e in enumerate(st.eigen) if st.relevant(i)]
    if all(e.mod2_expr is not None for e in rel) and (rel or not network.exact):
        return rel, None
    diag = diagonal_modes(network)
    return (rel, None) if diag is None else (list(diag), diag)


def _rank_fn(network: Network, e: Any, tol: float):
    """Rank of the stacked C_i V over a set of sensors: exact for rational eigenvalues of exact
    input, else float SVD with a relative tolerance. Returns (rank(sensors), g, how)."""
    sl = network.row_slices()
    A = sp.Matrix(network.A)
    if isinstance(e, DiagonalMode):
        vecs = [sp.Matrix([1 if r == k else 0 for r in range(A.shape[0])]) for k in e.columns]
    else:
        vecs = _exact_eigvecs(A, e.expr) if network.exact else None
    if vecs:
        V = sp.Matrix.hstack(*vecs)
        C = sp.Matrix(network.stacked_system().C)
        CV = C * V
        blocks = [CV[s.start:s.stop, :] for s in sl]

        def rank(idx: Sequence[int]) -> int:
            if not idx:
                return 0
            return sp.Matrix.vstack(*[blocks[i] for i in idx]).rank()
        return rank, V.shape[1], "exact (rational eigenvalue, sympy ranks)"
    V = e.basis
    c = network.stacked_system().c
    scale = max(float(np.linalg.norm(c, 2)), 1.0)
    CVf = c @ V
    fblocks = [CVf[s] for s in sl]

    def frank(idx: Sequence[int]) -> int:
        if not idx:
            return 0
        M = np.vstack([fblocks[i] for i in idx])
        sv = np.linalg.svd(M, compute_uv=False)
        return int(np.sum(sv > tol * scale))
    return frank, V.shape[1], f"float64 SVD, relative tolerance {tol:g}"


def _eig_text(e: Any) -> str:
    if e.expr is not None:
        return sp.sstr(e.expr)
    if e.text is not None:
        return e.text
    z = complex(e.value)
    return repr(z.real) if z.imag == 0 else f"{z.real:.12g}{z.imag:+.12g}j"


def necessary_constraints(network: Network, tol: float = RANK_TOL) -> tuple[Constraint, ...]:
    """The non-dominated necessary constraints (T, ρ_T²) (see the module docstring).

    For each eigenvalue λ with |λ| ≥ 1 (eigenspace V, dimension g): the blind sensors
    B = {i : C_i V = 0}; if all sensors together have rank < g on V, T = every sensor (the
    network cannot detect λ: no p works); else every hyperplane flat — the closure of ≤ g − 1
    sensors whose rows span rank g − 1 on V — united with B. A constraint (T, ρ²) is dropped
    when another has T' ⊇ T and ρ'² ≥ ρ².
    """
    modes, _ = relevant_modes(network)
    N = network.size
    out: list[Constraint] = []
    for e in modes:
        rank, g, how = _rank_fn(network, e, tol)
        blind = frozenset(i for i in range(N) if rank([i]) == 0)
        seen = [i for i in range(N) if i not in blind]
        flats: set[frozenset[int]] = set()
        if rank(seen) < g:
            flats.add(frozenset(range(N)))
        else:
            tried = 0
            reps = _distinct_row_spaces(rank, seen) if g > 1 else seen
            for size in range(0, g):
                for U in itertools.combinations(reps, size):
                    tried += 1
                    if tried > FLAT_BUDGET:
                        raise NumericalError(f"eigenvalue {_eig_text(e)} has a {g}-dimensional "
                                             f"eigenspace seen by {len(seen)} sensors: more than "
                                             f"{FLAT_BUDGET} sensor combinations (a size limit of "
                                             "kfcrit, not an error in the file)", field="sensors")
                    if rank(list(U)) != g - 1:
                        continue
                    closure = frozenset(i for i in seen if rank(list(U) + [i]) == g - 1)
                    flats.add(blind | closure)
        for T in flats:
            out.append(Constraint(T, float(e.mod2), e.mod2_expr, _eig_text(e), how))
    keep = []
    for c in out:
        if any(d is not c and c.blind <= d.blind and c.mod2 <= d.mod2
               and (c.blind != d.blind or c.mod2 < d.mod2 or id(d) < id(c)) for d in out):
            continue
        keep.append(c)
    keep.sort(key=lambda c: (-c.mod2, sorted(c.blind)))
    return tuple(keep)


def _distinct_row_spaces(rank, seen: Sequence[int]) -> list[int]:
    """One sensor per distinct row space C_i V among ``seen`` (first in sensor order).

    Two sensors have the same row space on V iff rank([i, j]) = rank([i]) = rank([j]). A flat
    spanned by some sensors is spanned by their representatives, and the closure is taken over
    every sensor, so the flats (and the constraints) are unchanged; the enumeration then grows
    with the number of distinct row spaces, not with N (many sensors seeing the same modes).
    """
    reps: list[int] = []
    for i in seen:
        ri = rank([i])
        if not any(rank([r]) == ri and rank([r, i]) == ri for r in reps):
            reps.append(i)
    return reps


EQUALITY_GUARD = 1e-12
"""Float factors within this of 1 leave a necessary condition undecided (no exact value)."""


def factor_sign(value: float, expr: sp.Expr | None) -> int | None:
    """Sign of (value − 1): exact from ``expr`` when given, else float with a guard
    (:data:`EQUALITY_GUARD`: within it of 1 the sign is left undecided)."""
    if expr is not None:
        try:
            return compare(expr, 1, "network", "necessary factor - 1")
        except KfcritError:
            pass
    if abs(value - 1.0) <= EQUALITY_GUARD:
        return None
    return 1 if value > 1 else -1


def necessary_holds(constraints: Sequence[Constraint], p: np.ndarray,
                    p_exact: Sequence[sp.Expr | None]) -> bool | None:
    """Whether every necessary constraint holds at p (None: undecided at float precision)."""
    undecided = False
    for c in constraints:
        s = factor_sign(c.factor(p), c.factor_expr(p_exact))
        if s is None:
            undecided = True
        elif s >= 0:
            return False
    return None if undecided else True


def necessary_coordinate(constraints: Sequence[Constraint], i: int, p: np.ndarray,
                         p_exact: Sequence[sp.Expr | None]
                         ) -> tuple[bool | None, float, sp.Expr | None]:
    """Least p_i allowed by the necessary surface, others at p: (possible, value, exact).

    A constraint with i ∈ T caps nothing in p_i: if it fails, no p_i works (possible False;
    None when it is at equality to float precision, undecided). Otherwise
    c = ρ_T² Π_{j∉T, j≠i}(1 − p_j) and p_i > 1 − 1/c is needed (nothing if c ≤ 1). The value
    is called exact only when every constraint was decided exactly.
    """
    best, best_expr = 0.0, sp.Integer(0)
    exact_ok = True
    for c in constraints:
        if i in c.blind:
            fe = c.factor_expr(p_exact)
            s = factor_sign(c.factor(p), fe)
            if s is None:
                return None, math.nan, None
            if s >= 0:
                return False, math.nan, None
            exact_ok = exact_ok and fe is not None
            continue
        q = p.copy()
        q[i] = 0.0
        val = c.factor(q)
        qe = list(p_exact)
        qe[i] = sp.Integer(0)
        expr = c.factor_expr(qe)
        if expr is None:
            # a float decision: never called exact
            exact_ok = False
        if val <= 1.0 and (expr is None or factor_sign(val, expr) in (-1, 0)):
            continue
        cand = 1.0 - 1.0 / val
        cand_expr = sp.radsimp(1 - 1 / expr) if expr is not None else None
        if cand > best + 1e-15 or (cand_expr is not None and best_expr is not None
                                   and abs(cand - best) <= 1e-15
                                   and float(sp.N(cand_expr - best_expr, 30)) > 0):
            best, best_expr = cand, cand_expr
        elif abs(cand - best) <= 1e-15 and cand_expr is None:
            exact_ok = False
    if best_expr is not None:
        best = float(sp.N(best_expr, 30))
    return True, best, best_expr if exact_ok else None


def necessary_along(constraints: Sequence[Constraint], path: nk.Path, lo: float,
                    hi: float) -> float | None:
    """Least s in [lo, hi] where every necessary constraint holds (bisection on the monotone
    float factors to 1e-15); ``lo`` if they hold there, None if not even at ``hi``."""
    def ok(s: float) -> bool:
        p, _ = path(s)
        return all(c.factor(p) < 1.0 for c in constraints)
    if ok(lo):
        return lo
    if not ok(hi):
        return None
    a, b = lo, hi
    for _ in range(200):
        mid = 0.5 * (a + b)
        if mid in (a, b):
            break
        a, b = (a, mid) if ok(mid) else (mid, b)
        if b - a < 1e-15:
            break
    return b


# ---- the exact case: modal one-step observability

def modal_one_step(network: Network, tol: float = RANK_TOL) -> tuple[bool | None, str]:
    """Whether the proof in the module docstring applies (True) or fails (False), with why.

    The condition is checked sensor by sensor (O(N) rank tests): the nonzero C_S w_j are
    linearly independent for every received set S iff they are for every single sensor
    (docs/theory.md §15.6).
    """
    rel, diag = relevant_modes(network)
    if not rel:
        return True, "ρ(A) < 1: every arrival probability works"
    if diag is not None:
        return _diagonal_one_step(network, diag)
    if any(e.geometric != e.multiplicity for e in rel):
        return False, "a mode with |λ| ≥ 1 is not diagonalizable"
    W = np.hstack([e.basis for e in rel])
    k = W.shape[1]
    sys = network.stacked_system()
    CW = sys.c @ W
    scale = max(float(np.linalg.norm(sys.c, 2)), 1.0)
    if k == 1:
        return True, "one unstable mode"
    # the condition for every received set S is equivalent to the one for every single
    # sensor (docs/theory.md §15.6): O(N) rank tests instead of 2^N
    for i, sl in enumerate(network.row_slices()):
        M = CW[sl]
        seen = np.linalg.norm(M, axis=0) > tol * scale
        if not seen.any():
            continue
        rank = int(np.sum(np.linalg.svd(M[:, seen], compute_uv=False) > tol * scale))
        if rank != int(seen.sum()):
            return False, (f"sensor {network.names[i]} sees unstable modes through dependent "
                           "outputs (not one-step observable)")
    return True, ("every sensor sees its observable unstable modes through linearly "
                  "independent outputs, hence so does every received set (docs/theory.md "
                  f"§15.6; float64 ranks, relative tolerance {tol:g})")


def _diagonal_one_step(network: Network, modes: Sequence[DiagonalMode]) -> tuple[bool, str]:
    """Modal one-step observability of an exact diagonal A with the unit eigenvectors, in exact
    ranks: each sensor's nonzero columns C_i e_k (k over the modes with |λ| ≥ 1) independent."""
    cols = [k for m in modes for k in m.columns]
    if len(cols) == 1:
        return True, "one unstable mode"
    C = sp.Matrix(network.stacked_system().C)
    for i, sl in enumerate(network.row_slices()):
        M = C[sl.start:sl.stop, cols]
        seen = [j for j in range(M.cols) if any(x != 0 for x in M[:, j])]
        if seen and M[:, seen].rank() != len(seen):
            return False, (f"sensor {network.names[i]} sees unstable modes through dependent "
                           "outputs (not one-step observable)")
    return True, ("every sensor sees its observable unstable modes through linearly "
                  "independent outputs, hence so does every received set (docs/theory.md "
                  "§15.6; A diagonal and exact: exact eigenvalues, eigenvectors and ranks)")
