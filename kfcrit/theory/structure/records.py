"""Records and shared constants of the eigen-structure analysis (every path produces these).

:class:`Structure` holds the diagonal standard form of (A, C) that the Mo–Sinopoli theorems read:
distinct eigenvalues (:class:`Eigen`), equi-blocks (:class:`EquiBlock`), equal-modulus pairs
(:class:`Pair`) and the decided facts (diagonalizable, detectable, ...). The paths that fill it
live in :mod:`~kfcrit.theory.structure.exact` (number fields),
:mod:`~kfcrit.theory.structure.certified` (ball arithmetic) and
:mod:`~kfcrit.theory.structure.numeric` (float64 with tolerances); the entry point is
:func:`kfcrit.theory.structure.eigen.structure_of`.

Invariant: whichever path ran, every distinct eigenvalue carries a float64 value, its geometric
multiplicity and an orthonormal basis of its eigenspace (float), so that the robustness analysis
treats all paths alike.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

import numpy as np
import sympy as sp

from kfcrit.defaults import DEFAULT_TOLERANCE
from kfcrit.io.typed import ABSENT, to_json
from kfcrit.records.structure import (
    Eigenvalue,
    EqualModulusPair,
    EquiBlockRecord,
    StandardForm,
    StructureRecord,
    StructureTolerances,
)

EXACT_MAX_STATES = 6
"""Largest n for the exact path (beyond it the number-field arithmetic grows too fast)."""
EXACT_MAX_STATES_BINARY_FLOAT = 3
"""Largest n for the exact path when the input holds binary floats (NumPy arrays)."""
def _time_budget_from_environment(default: float = 8.0) -> float:
    """The exact-path time budget: ``KFCRIT_EXACT_TIME_BUDGET`` seconds if set and valid."""
    text = os.environ.get("KFCRIT_EXACT_TIME_BUDGET", "")
    try:
        value = float(text)
    except ValueError:
        return default
    return value if math.isfinite(value) and value > 0 else default


EXACT_TIME_BUDGET = _time_budget_from_environment()
"""Seconds the exact path may use (checked between steps, and enforced by killing the forked
child each exact stage runs in: :func:`kfcrit.theory.structure.budget.run_bounded`; beyond it
the next path runs).

Typical exact analyses of n ≤ 6 take 0.01–1.3 s (see ``kfcrit.bench.bench_critical``); the
default of 8 s is kept well above that so that results rarely depend on machine load. The
environment variable ``KFCRIT_EXACT_TIME_BUDGET`` overrides it (the test suite sets 120 s so
that assertions on exact results hold on a heavily loaded machine)."""
EXACT_MAX_FIELD_DEGREE = 16
"""Largest degree over Q of the entry field K for the exact path."""
MAX_DENOMINATOR = 1000
"""Largest q for which a floating-point angle φ/2π is matched to a rational r/q."""
NUMERIC_FLOOR = 64 * float(np.finfo(float).eps)
"""Least numeric decision tolerance: below ~64 ulp a float64 comparison decides nothing."""
NUMERIC_TOLERANCES = {
    "modulus_relative": DEFAULT_TOLERANCE,
    "rank_relative": DEFAULT_TOLERANCE,
    "turn_absolute": DEFAULT_TOLERANCE,
    "eigenvalue_cluster_relative": 1e-6,
    "geometric_multiplicity_relative": 1e-6,
    "max_denominator": MAX_DENOMINATOR,
}
"""Decision tolerances of the numeric path (relative to ‖A‖₂ or ‖C‖₂ where it applies) at the
default tolerance; :func:`numeric_tolerances` replaces the first three by the user's tolerance."""


def numeric_tolerances(tolerance: float | None = None) -> dict[str, Any]:
    """The numeric path's decision tolerances for a user ``tolerance`` (``--tolerance``):
    moduli equal within relative ``tolerance``, rank within ``tolerance``·‖C‖, φ/2π matched to
    r/q within ``tolerance`` (each at least ``NUMERIC_FLOOR``)."""
    tol = dict(NUMERIC_TOLERANCES)
    if tolerance is not None:
        t = max(float(tolerance), NUMERIC_FLOOR)
        tol.update(modulus_relative=t, rank_relative=t, turn_absolute=t)
    return tol

_X = sp.Symbol("x")
_Y = sp.Symbol("y")
_ZERO_PROBE_DIGITS = 40


class Fallback(Exception):
    """The exact path cannot (or may not, in the time budget) decide; use the numeric path."""



# --------------------------------------------------------------------------- records

@dataclass(frozen=True)
class Eigen:
    """One distinct eigenvalue λ with its multiplicities and eigenspace.

    ``expr`` and ``mod2_expr`` (= |λ|²) are exact sympy numbers on the exact path, None on the
    numeric path. ``basis`` is an orthonormal float basis of ker(A − λI) (n × geometric).
    """

    value: complex
    multiplicity: int
    geometric: int
    mod2: float
    basis: np.ndarray = field(repr=False)
    expr: sp.Expr | None = None
    mod2_expr: sp.Expr | None = None
    unit_cmp: int | None = None
    """Sign of |λ| − 1 decided exactly (exact path), None on the numeric path."""
    text: str | None = None
    """Exact label when ``expr`` is None on the exact path (``CRootOf(P, i)``)."""

    @property
    def modulus(self) -> float:
        """|λ| as a float."""
        return math.sqrt(self.mod2)


@dataclass(frozen=True)
class Pair:
    """Two distinct eigenvalues of equal modulus, λ_b = λ_a·z (a block of Mo–Sinopoli Thm 5).

    ``degenerate``: the pair's columns of C·V are rank deficient (rank < size). ``q``: order of
    z as a root of unity (None: not a root of unity, i.e. φ/2π irrational on the exact path, or
    no r/q with q ≤ ``MAX_DENOMINATOR`` within the turn tolerance on the numeric path).
    """

    a: int
    b: int
    rank: int
    size: int
    degenerate: bool
    q: int | None
    turn: float
    turn_text: str


@dataclass(frozen=True)
class EquiBlock:
    """Maximal set of distinct eigenvalues with equal modulus (Mo–Sinopoli Definition 2)."""

    members: tuple[int, ...]
    indices: tuple[int, ...]
    mod2: float
    mod2_expr: sp.Expr | None
    rank: int
    size: int
    relevant: bool

    @property
    def one_step_observable(self) -> bool:
        """Full column rank of the block's columns of C·V (Definition 4)."""
        return self.rank == self.size


@dataclass(frozen=True)
class Structure:
    """The eigen-structure of (A, C) and the facts the critical-value theorems need."""

    path: str
    path_reason: str
    tolerances: dict[str, Any]
    eigen: tuple[Eigen, ...]
    blocks: tuple[EquiBlock, ...]
    pairs: tuple[Pair, ...]
    diagonalizable: bool
    detectable: bool
    undetectable: tuple[int, ...]
    controllable_Q: bool
    observability_index: int | None
    observable: bool
    norm_A: float
    norm_C: float
    seconds: float
    standard_form: StandardForm | None = None
    """Diagonal standard form (Mo–Sinopoli): eigenvalues and the columns of C·V per equi-block
    (exact strings on the exact path, [re, im] float pairs on the numeric path)."""
    unresolved: tuple[str, ...] = ()
    """Numeric path: eigenvalue groups float64 could not resolve (one sentence each)."""

    def relevant(self, i: int) -> bool:
        """Eigenvalue i is unstable or critically stable (|λ| ≥ 1)."""
        return is_relevant(self.eigen[i], self.tolerances)

    @property
    def stable(self) -> bool:
        """ρ(A) < 1."""
        return not any(self.relevant(i) for i in range(len(self.eigen)))

    def record(self) -> StructureRecord:
        """The record's ``structure`` section: eigenvalues in modulus order (each repeated by
        its multiplicity), equi-blocks, equal-modulus pairs and the decided facts."""
        eigs = [Eigenvalue(
            value=(sp.sstr(e.expr) if e.expr is not None else
                   e.text if e.text is not None else complex_sympy_text(e.value)),
            re=float(e.value.real), im=float(e.value.imag), modulus=float(e.modulus),
            modulus_expression=(sp.sstr(_modulus_expr(e.mod2_expr))
                                if e.mod2_expr is not None else repr(e.modulus)))
            for e in self.eigen for _ in range(e.multiplicity)]
        blocks = [EquiBlockRecord(
            indices=[int(i) for i in b.indices], modulus=math.sqrt(b.mod2),
            modulus_expression=(sp.sstr(_modulus_expr(b.mod2_expr))
                                if b.mod2_expr is not None else repr(math.sqrt(b.mod2))),
            one_step_observable=bool(b.one_step_observable), rank=int(b.rank),
            size=int(b.size), unstable_or_critical=bool(b.relevant)) for b in self.blocks]
        pairs = [EqualModulusPair(
            indices=[self._first_index(p.a), self._first_index(p.b)], rank=int(p.rank),
            size=int(p.size), degenerate=bool(p.degenerate),
            q=int(p.q) if p.q is not None else None, turn=float(p.turn),
            turn_expression=p.turn_text) for p in self.pairs]
        return StructureRecord(
            path=self.path, path_reason=self.path_reason,
            tolerances=_tolerances_record(self.tolerances), eigenvalues=eigs,
            equi_blocks=blocks, equal_modulus_pairs=pairs,
            diagonalizable=bool(self.diagonalizable), detectable=bool(self.detectable),
            controllable_Q=bool(self.controllable_Q),
            observability_index=(int(self.observability_index)
                                 if self.observability_index is not None else None),
            observable=bool(self.observable), standard_form=self.standard_form,
            unresolved=list(self.unresolved))

    def to_dict(self, record: StructureRecord | None = None) -> dict[str, Any]:
        """Plain JSON data: :meth:`record` (``record`` when already built) with the wall-clock
        ``seconds`` the analysis took (before ``standard_form``)."""
        d = to_json(record if record is not None else self.record())
        tail = {k: d.pop(k) for k in ("standard_form", "unresolved")}
        return {**d, "seconds": round(self.seconds, 4), **tail}

    def _first_index(self, i: int) -> int:
        return sum(e.multiplicity for e in self.eigen[:i])


def _tolerances_record(tol: dict[str, Any]) -> StructureTolerances:
    """The decision tolerances a path states (each key only when that path uses it)."""
    def get(key: str, kind: type) -> Any:
        if key not in tol:
            return ABSENT
        return None if tol[key] is None else kind(tol[key])

    return StructureTolerances(
        exact=get("exact", bool), time_budget_seconds=get("time_budget_seconds", float),
        max_states=get("max_states", int), modulus_relative=get("modulus_relative", float),
        rank_relative=get("rank_relative", float), turn_absolute=get("turn_absolute", float),
        eigenvalue_cluster_relative=get("eigenvalue_cluster_relative", float),
        geometric_multiplicity_relative=get("geometric_multiplicity_relative", float),
        max_denominator=get("max_denominator", int),
        certified_enclosures=get("certified_enclosures", bool),
        precision_bits=get("precision_bits", int))


def _modulus_expr(mod2: sp.Expr) -> sp.Expr:
    return sp.sqrt(mod2)


def complex_sympy_text(z: complex) -> str:
    if z.imag == 0:
        return repr(float(z.real))
    sign = "+" if z.imag >= 0 else "-"
    return f"{z.real!r} {sign} {abs(z.imag)!r}*I"


def is_relevant(e: Eigen, tolerances: dict[str, Any] | None = None) -> bool:
    """|λ| ≥ 1: exact sign on the exact path; within the modulus tolerance on the numeric path."""
    if e.unit_cmp is not None:
        return e.unit_cmp >= 0
    tol = (tolerances or {}).get("modulus_relative", NUMERIC_TOLERANCES["modulus_relative"])
    return e.mod2 >= 1 - tol



def turn_of(z: complex) -> float:
    """φ/2π ∈ [0, 1) for z = e^{jφ}·|z|."""
    t = math.atan2(z.imag, z.real) / (2 * math.pi)
    return t + 1.0 if t < 0 else t



def eigen_indices(eigen: list[Eigen], members: list[int]) -> tuple[int, ...]:
    out = []
    for i in members:
        start = sum(e.multiplicity for e in eigen[:i])
        out.extend(range(start, start + eigen[i].multiplicity))
    return tuple(out)


def float_basis(a: np.ndarray, lam: complex, g: int) -> np.ndarray:
    """Orthonormal float basis of ker(a − λI) of known dimension g (last right singular vectors)."""
    n = a.shape[0]
    _, _, vh = np.linalg.svd(a.astype(complex) - lam * np.eye(n))
    return vh[n - g:].conj().T if g > 0 else np.zeros((n, 0), complex)



def numeric_controllable(a: np.ndarray, q: np.ndarray) -> bool:
    """PBH: (A, Q^{1/2}) controllable iff no left eigenvector w of A has w^H Q w = 0."""
    nq = float(np.linalg.norm(q, 2))
    if nq == 0:
        return False
    if np.linalg.eigvalsh(0.5 * (q + q.T)).min() > NUMERIC_TOLERANCES["rank_relative"] * nq:
        return True
    _, W = np.linalg.eig(a.T)
    W = W / np.linalg.norm(W, axis=0)
    vals = np.real(np.einsum("ij,ik,kj->j", W.conj(), q, W))
    return bool(np.all(vals > NUMERIC_TOLERANCES["rank_relative"] * nq))


def observability_index(a: np.ndarray, c: np.ndarray) -> int | None:
    """Least k with [C; CA; …; CA^{k−1}] of full column rank (None: not observable), float64.

    Incremental: an orthonormal basis of the row space grows by the part of C·A^{k−1} (rows
    normalised) orthogonal to it (projected twice for stability); relative tolerance 1e-9.
    """
    n = a.shape[0]
    basis = np.zeros((0, n))
    block = c.astype(float)
    for k in range(1, n + 1):
        norms = np.linalg.norm(block, axis=1, keepdims=True)
        rows = block / np.where(norms > 0, norms, 1.0)
        for _ in range(2):
            if basis.shape[0]:
                rows = rows - (rows @ basis.T) @ basis
        _, s, vh = np.linalg.svd(rows, full_matrices=False)
        new = vh[s > 1e-9]
        if new.shape[0]:
            if basis.shape[0]:
                new = new - (new @ basis.T) @ basis
                new = new / np.linalg.norm(new, axis=1, keepdims=True)
            basis = np.vstack([basis, new])
        if basis.shape[0] >= n:
            return k
        block = block @ a
    return None


# --------------------------------------------------------------------------- rationals

def simplest_rational(lo: float | Fraction, hi: float | Fraction) -> Fraction:
    """The rational with the least denominator in [lo, hi] (Stern–Brocot / continued fractions).

    Parameters
    ----------
    lo, hi : float or Fraction
        Interval ends, lo ≤ hi (floats are read exactly).
    """
    lo, hi = Fraction(lo), Fraction(hi)
    if lo > hi:
        lo, hi = hi, lo
    fl = math.floor(lo)
    if fl + 1 <= hi or lo == fl:
        return Fraction(math.ceil(lo))
    # lo, hi in (fl, fl+1): recurse on the reciprocals of the fractional parts.
    inner = simplest_rational(1 / (hi - fl), 1 / (lo - fl))
    return fl + 1 / inner

