"""Critical arrival probability p_c: which theorem applies, its exact value, and how robust it is.

The decision tree (docs/theory.md §3–§4, Mo–Sinopoli; the eigen-structure comes from
:mod:`kfcrit.theory.structure.eigen`):

1. some eigenvector with |λ| ≥ 1 is invisible to C  → ``not-detectable`` (no p_c: E[P_t]
   diverges for every p, even with no losses);
2. ρ(A) < 1                                            → ``stable``, p_c = 0;
3. A not diagonalizable                                → ``non-diagonalizable``: no closed form,
   except Sinopoli §IV (C invertible, or a single unstable eigenvalue), where p_c = p_low;
4. every equi-block with |λ| ≥ 1 one-step observable   → ``non-degenerate`` (Thm 4),
   p_c = max(1 − |λ_1|^{−2}, 0);
5. the |λ| ≥ 1 part is one degenerate equal-modulus pair → ``degenerate-second-order``
   (Thm 5, 9, 10; with Thm 3 and Thm 8 when stable eigenvalues are present),
   p_c = max(1 − |λ_1|^{−2/(1 − D_M(φ/2π))}, 0) = max(1 − |λ_1|^{−2q/(q−1)}, 0);
6. otherwise                                          → ``degenerate``: no closed form; the block
   lower bound (Thm 3 over single eigenvalues and equal-modulus pairs) is reported instead.

The robust value (issue item 3) looks at every decision a relative perturbation of size ``tol``
could flip *upwards*: moduli within ``tol`` of each other (a pair that could become an equi-block),
C-columns within ``tol``·‖C‖ of rank deficiency, an angle φ/2π within ``tol`` of a rational r/q with
a smaller q (q ≤ ``MAX_DENOMINATOR``; larger q change p_c by at most 0.37/(q − 1)), and eigenvectors
within ``tol``·‖C‖ of being unobservable. The continuous drift of p_c with |λ_1| (O(tol)) is not a
flip and is not reported.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

import numpy as np
import sympy as sp

from kfcrit.errors import InputError
from kfcrit.model.exprparse import MAX_DIGITS, exact_text
from kfcrit.model.system import System
from kfcrit.theory.critical.numtext import (
    approx_text,
    complex_text,
    is_short_expression,
    p_c_text,
    superscript,
    value_text,
)
from kfcrit.theory.structure.eigen import (
    MAX_DENOMINATOR,
    NUMERIC_FLOOR,
    NUMERIC_TOLERANCES,
    Structure,
    cmp_exact,
    simplest_rational,
    structure_at,
    structure_of,
)

_LONG_LITERAL = re.compile(rf"\d{{{MAX_DIGITS + 1},}}")
_LONG_NUMBER = re.compile(r"\d{13,}")

CLASSIFICATIONS = ("stable", "non-degenerate", "degenerate-second-order", "degenerate",
                   "non-diagonalizable", "not-detectable")

# --------------------------------------------------------------------------- numbers

@dataclass(frozen=True)
class Num:
    """A probability: float value and, when known exactly, the sympy expression."""

    value: float
    expr: sp.Expr | None = None
    text: str | None = None

    @property
    def expression(self) -> str:
        """Text readable by sympy and :func:`kfcrit.model.exprparse.parse_expression`."""
        if self.expr is None:
            return repr(self.value)
        full = sp.sstr(self.expr)
        out = self.text if self.text is not None and len(self.text) < len(full) else full
        # the safe parser caps literals at MAX_DIGITS digits: long integers in Horner form
        return exact_text(self.expr) if _LONG_LITERAL.search(out) else out

    @property
    def latex(self) -> str:
        """LaTeX of the exact expression (or of the float)."""
        return sp.latex(self.expr) if self.expr is not None else repr(self.value)

    def to_dict(self) -> dict[str, Any]:
        return {"value": self.value, "expression": self.expression}


def _num(expr: sp.Expr | None, value: float | None = None) -> Num:
    if expr is None:
        return Num(float(value))
    expr = sp.nsimplify(expr) if isinstance(expr, sp.Float) else expr
    return Num(float(sp.N(expr, 30)), expr)


def _above_one(mod2: float, mod2_expr: sp.Expr | None) -> bool:
    """|λ|² > 1, decided exactly when ``mod2_expr`` is given (then max(·, 0) needs no sympy Max)."""
    if mod2_expr is None:
        return mod2 > 1.0
    return cmp_exact(mod2_expr, 1) > 0


_ZERO = Num(0.0, sp.Integer(0))


def _mtol(st: Structure | None) -> float:
    """The numeric path's modulus tolerance (relative) of ``st``."""
    tol = st.tolerances.get("modulus_relative") if st is not None else None
    return tol if tol is not None else NUMERIC_TOLERANCES["modulus_relative"]


def _eig_above(e: Any, st: Structure | None = None) -> bool:
    """|λ| > 1 as decided by the structure (exactly on the exact path; on the numeric path
    |λ| within the modulus tolerance of 1 counts as critically stable)."""
    if e.unit_cmp is not None:
        return e.unit_cmp > 0
    return e.mod2 > 1 + 2 * _mtol(st)


def _on_circle(e: Any, st: Structure | None = None) -> bool:
    return e.unit_cmp == 0 if e.unit_cmp is not None else abs(e.mod2 - 1) <= 2 * _mtol(st)


def nondegenerate_value(mod2: float, mod2_expr: sp.Expr | None = None,
                        above: bool | None = None) -> Num:
    """Mo–Sinopoli Thm 4: p = max(1 − |λ|^{−2}, 0), with |λ|² = ``mod2``.

    ``above`` (|λ| > 1), when given, is the exact decision of the structure analysis.
    """
    if not (above if above is not None else _above_one(mod2, mod2_expr)):
        return _ZERO if mod2_expr is not None else Num(0.0)
    if mod2_expr is not None:
        return _num(1 - 1 / mod2_expr)
    return Num(1.0 - 1.0 / mod2)


def pair_value(mod2: float, q: int | None, mod2_expr: sp.Expr | None = None,
               above: bool | None = None) -> Num:
    """Mo–Sinopoli Thm 5: p = max(1 − |λ|^{−2/(1 − D_M)}, 0), D_M = 1/q (0 if irrational).

    ``q = 1`` (z = 1: equal eigenvalues seen through one column) means not detectable: p = 1.
    """
    if q == 1:
        return Num(1.0, sp.Integer(1))
    if q is None:
        return nondegenerate_value(mod2, mod2_expr, above)
    if not (above if above is not None else _above_one(mod2, mod2_expr)):
        return _ZERO if mod2_expr is not None else Num(0.0)
    if mod2_expr is not None:
        v = _num(1 - mod2_expr ** sp.Rational(-q, q - 1))
        # compact unexpanded form, e.g. 1 - (m)**(-3/2), when it is shorter (long rationals)
        exp = f"-{q}" if q == 2 else f"-{q}/{q - 1}"
        base = sp.sstr(mod2_expr)
        base = base if mod2_expr.is_Integer and mod2_expr > 0 else f"({base})"
        return Num(v.value, v.expr, f"1 - {base}**({exp})")
    return Num(1.0 - mod2 ** (-q / (q - 1)))


# --------------------------------------------------------------------------- record

@dataclass(frozen=True)
class CriticalValue:
    """The critical value of one system and everything that decided it.

    ``to_dict()`` keys: classification, critical_value {value, exact, expression, latex, reason},
    robust_critical_value {value, tolerance, expression, nearby_case} | None,
    lower_bound {value, expression}, block_lower_bound {value, expression},
    structure {...}, theory {...}, warnings [str].
    """

    classification: str
    value: Num | None
    reason: str
    lower: Num
    block_lower: Num | None
    block_reason: str
    robust: dict[str, Any] | None
    structure: Structure
    theory: dict[str, Any]
    warnings: tuple[str, ...] = field(default=())
    basis: str | None = None
    """For a value from coinciding bounds: "theorem" or "claim" (a [beyond] identity)."""

    def to_dict(self) -> dict[str, Any]:
        exact = self.structure.path == "exact"
        if self.value is not None:
            reason = self.reason
            if exact and self.value.expr is None:
                reason += (" (every decision exact; |λ₁|² is an algebraic number of degree ≥ 3, "
                           "so the value is given in double precision)")
            cv = {"value": self.value.value, "exact": exact and self.value.expr is not None,
                  "expression": self.value.expression, "latex": self.value.latex,
                  "reason": reason}
            if self.basis is not None:
                cv["basis"] = self.basis
        else:
            cv = {"value": None, "exact": None, "expression": None, "latex": None,
                  "reason": self.reason}
        blb = ({**self.block_lower.to_dict(), "reason": self.block_reason}
               if self.block_lower is not None
               else {"value": None, "expression": None, "reason": self.block_reason})
        return {"classification": self.classification, "critical_value": cv,
                "robust_critical_value": dict(self.robust) if self.robust else None,
                "lower_bound": self.lower.to_dict(), "block_lower_bound": blb,
                "structure": self.structure.to_dict(), "theory": self.theory,
                "warnings": list(self.warnings)}


# --------------------------------------------------------------------------- bounds

def _eig_text(st: Structure, i: int) -> str:
    """λ_i: its short exact expression, else its float (``≈`` when it rounds an exact value)."""
    e = st.eigen[i]
    text = sp.sstr(e.expr) if e.expr is not None else None
    if text is not None and is_short_expression(text):
        return text
    return ("≈ " if text is not None else "") + complex_text(e.value)


def _mod_text(st: Structure, i: int) -> str:
    """|λ_i|: the exact expression when short, else the float marked "≈" (exact path: the
    float of the exact value) or as computed (numeric path), to 12 significant digits."""
    e = st.eigen[i]
    if e.mod2_expr is not None:
        return value_text(e.modulus, sp.sstr(sp.sqrt(e.mod2_expr)))
    if e.text is not None:   # exact path, an indexed root without a closed form
        return f"≈ {approx_text(e.modulus)}"
    return approx_text(e.modulus)


def _is_mod(st: Structure, i: int) -> str:
    """``= |λ_i|`` (exact or computed) or ``≈ |λ_i|`` (an exact value rounded), for prose."""
    text = _mod_text(st, i)
    return text if text.startswith("≈") else f"= {text}"


def _decided_text(system: System, st: Structure, what: str) -> str:
    """How a discrete decision (``what``) was made, for reason texts on float input."""
    if st.path == "numeric":
        tol = st.tolerances.get("modulus_relative", NUMERIC_TOLERANCES["modulus_relative"])
        return (f" ({what} decided in floating point: equal within relative tolerance "
                f"{tol:g}; the numbers shown are computed float64 values to 12 digits)")
    if not system.exact:
        return (f" ({what} decided exactly on the binary-float input taken as the rationals "
                "it represents; numbers marked ≈ are float64 roundings of exact values)")
    return ""


def _lower(st: Structure) -> Num:
    """Sinopoli Thm 3: p_low = max(1 − 1/ρ(A)², 0) (eigen is sorted by modulus)."""
    top = st.eigen[0]
    return nondegenerate_value(top.mod2, top.mod2_expr, _eig_above(top, st))


def lower_bound(system: System, structure: Structure | None = None) -> dict[str, Any]:
    """Sinopoli Thm 3 lower bound p_low = 1 − 1/ρ(A)², 0 when ρ(A) ≤ 1: {value, expression}.

    ``structure``: the eigen-structure of ``system`` if already computed
    (:func:`kfcrit.theory.structure.eigen.structure_of`), else it is computed here."""
    return _lower(structure if structure is not None else structure_of(system)).to_dict()


def _pair_num(st: Structure, pair: Any, q: int | None) -> Num:
    e = st.eigen[pair.a]
    return pair_value(e.mod2, q, e.mod2_expr, _eig_above(e, st))


def _block_lower(st: Structure, low: Num) -> tuple[Num, str]:
    """Thm 3: max over single eigenvalues (= p_low) and degenerate equal-modulus pairs."""
    best, why = low, "Sinopoli Thm 3 / Mo–Sinopoli Thm 3 over single eigenvalues (= p_low)"
    if not st.diagonalizable:
        return best, why + "; A is not diagonalizable, so Mo–Sinopoli blocks are not used"
    for p in st.pairs:
        if p.degenerate:
            v = _pair_num(st, p, p.q)
            if v.value > best.value:
                best = v
                why = (f"Mo–Sinopoli Thm 3 with Thm 5 on the degenerate pair "
                       f"{_eig_text(st, p.a)}, {_eig_text(st, p.b)} "
                       f"(φ/2π = {p.turn_text}, q = {p.q if p.q else '∞'})")
    return best, why


def _c_invertible(system: System, st: Structure) -> bool:
    if system.m != system.n:
        return False
    if st.path == "exact":
        return sp.Matrix(system.C).rank(simplify=True) == system.n
    return bool(np.linalg.matrix_rank(system.c) == system.n)


def _single_unstable(st: Structure) -> bool:
    """Exactly one eigenvalue (with multiplicity) has |λ| > 1 and all others |λ| < 1."""
    rel = [i for i in range(len(st.eigen)) if st.relevant(i)]
    if len(rel) != 1 or st.eigen[rel[0]].multiplicity != 1:
        return False
    return not _on_circle(st.eigen[rel[0]], st)


# --------------------------------------------------------------------------- decision tree

def _structural_class(st: Structure) -> str:
    """The Mo–Sinopoli class of a detectable, not stable (A, C), from the structure alone."""
    if not st.diagonalizable:
        return "non-diagonalizable"
    rel_blocks = [b for b in st.blocks if b.relevant]
    degenerate = [b for b in rel_blocks if not b.one_step_observable]
    if not degenerate:
        return "non-degenerate"
    blk = degenerate[0]
    if len(rel_blocks) == 1 and len(blk.members) == 2 and blk.size == 2:
        return "degenerate-second-order"
    return "degenerate"


def _jordan_size(st: Structure) -> int:
    """Largest possible Jordan block of a unit-modulus eigenvalue: algebraic − geometric + 1."""
    return max((e.multiplicity - e.geometric + 1 for e in st.eigen if _on_circle(e, st)),
               default=1)


def _marginal_reason(system: System, st: Structure) -> str:
    """docs/theory.md §11, marginal modes: ρ(A) ≤ 1 and (C, A) detectable ⇒ p_c = 0 (any Jordan form)."""
    k = _jordan_size(st)
    io = st.observability_index
    run = (f"Iₒ = {io}" if io is not None else
           "Iₒ = the observability index of the observable part (the unobservable modes have "
           "|λ| < 1 by detectability and stay bounded)")
    growth = ("A is diagonalizable on the unit circle, so ‖Aᵗ‖ is bounded" if k == 1 else
              f"the largest Jordan block on the unit circle has size ≤ {k}, so ‖Aᵗ‖ = "
              f"O(t{superscript(k - 1) if k > 2 else ''})")
    return (f"marginal modes (docs/theory.md §11): ρ(A) {_is_mod(st, 0)} (eigenvalues on the unit "
            "circle, none outside) and (C, A) detectable, so p_c = 0 whatever the Jordan "
            "structure. Argument: "
            f"(1) Pₜ₊₁ ⪯ A Pₜ A' + Q and {growth}, so Pₜ grows at most polynomially in the time "
            f"since the last useful data; (2) a run of {run} consecutive arrivals puts Pₜ ⪯ M "
            "whatever Pₜ was before it (the Iₒ-step observability of (C, A) bounds the error of "
            "the best estimate from those measurements, and the Kalman filter is optimal); "
            "(3) for every p > 0 the waiting time W for such a run has a geometric tail, "
            "P(W > w) ≤ θᵏ with θ = 1 − pᴵᵒ and k = ⌊w/Iₒ⌋, so E[Pₜ] ⪯ E[poly(W)]·(‖M‖ + ‖Q‖) "
            "< ∞. The steps are checked mechanically by kfcrit's proof checks "
            "(check_marginal_modes)"
            + _decided_text(system, st, "|λ| = 1"))



def _classify(system: System, st: Structure, low: Num) -> tuple[str, Num | None, str]:
    if not st.detectable:
        bad = ", ".join(_eig_text(st, i) for i in st.undetectable)
        return ("not-detectable", None,
                f"(C, A) is not detectable: eigenvalue(s) {bad} with |λ| ≥ 1 have an eigenvector "
                "with C v = 0, so E[Pₜ] (indeed Pₜ itself) diverges for every arrival "
                "probability, even with no losses (PBH test)")
    if st.stable:
        return ("stable", Num(0.0, sp.Integer(0)),
                f"ρ(A) {_is_mod(st, 0)} < 1: E[Pₜ] is bounded for every p, p_c = 0")
    if not any(_eig_above(e, st) for e in st.eigen):
        return (_structural_class(st), Num(0.0, sp.Integer(0)), _marginal_reason(system, st))
    if not st.diagonalizable:
        if _c_invertible(system, st):
            return ("non-diagonalizable", low,
                    "A is not diagonalizable (outside Mo–Sinopoli), but C is invertible: "
                    "Sinopoli et al. §IV, upper and lower bounds coincide, p_c = 1 − 1/ρ(A)²")
        if _single_unstable(st):
            return ("non-diagonalizable", low,
                    f"A is not diagonalizable (outside Mo–Sinopoli), but it has a single unstable "
                    f"eigenvalue {_eig_text(st, 0)}: Sinopoli et al. §IV, bounds coincide, "
                    "p_c = 1 − 1/|λ₁|²")
        return ("non-diagonalizable", None,
                "A is not diagonalizable: Mo–Sinopoli (H2) fails and the papers give no closed "
                "form; p_c lies in [block lower bound, LMI upper bound]")
    rel_blocks = [b for b in st.blocks if b.relevant]
    degenerate = [b for b in rel_blocks if not b.one_step_observable]
    if not degenerate:
        facts = "; ".join(
            f"|λ| {_is_mod(st, b.members[0])}: rank C_I = {b.rank} = size {b.size}"
            for b in rel_blocks)
        return ("non-degenerate", low,
                f"Mo–Sinopoli Thm 4: every equi-block with |λ| ≥ 1 is one-step observable "
                f"({facts}); p_c = max(1 − |λ₁|⁻², 0) with |λ₁| {_is_mod(st, 0)}"
                + _decided_text(system, st, "equi-blocks and ranks"))
    blk = degenerate[0]
    second_order = (len(rel_blocks) == 1 and len(blk.members) == 2 and blk.size == 2)
    if second_order:
        pair = next(p for p in st.pairs if {p.a, p.b} == set(blk.members))
        val = _pair_num(st, pair, pair.q)
        a, b = pair.a, pair.b
        extra = (" with Thm 3 and Thm 8 (the |λ| < 1 eigenvalues do not change p_c)"
                 if len(st.eigen) > 2 else "")
        qtext = (f"φ/2π = {pair.turn_text}, q = {pair.q} (Thm 9)" if pair.q is not None else
                 "φ/2π irrational, D_M = 0 (Thm 10)" if st.path == "exact" else
                 f"φ/2π ≈ {pair.turn:.12g}: {pair.turn_text}, treated as irrational (Thm 10)")
        return ("degenerate-second-order", val,
                f"Mo–Sinopoli Thm 5{extra}: equal moduli |λ| {_is_mod(st, a)} of "
                f"the eigenvalues {_eig_text(st, a)} and {_eig_text(st, b)}, rank C_I = {pair.rank} < 2, "
                f"{qtext}" + _decided_text(system, st, "equal moduli, rank and φ/2π"))
    return ("degenerate", None,
            f"degenerate equi-block of size {blk.size} with rank C_I = {blk.rank} at |λ| "
            f"{_is_mod(st, blk.members[0])}"
            + ("" if len(rel_blocks) == 1 else f" among {len(rel_blocks)} equi-blocks with |λ| ≥ 1")
            + ": beyond second order the papers give no closed form; p_c lies in "
              "[block lower bound, LMI upper bound]")


# --------------------------------------------------------------------------- robustness

@dataclass(frozen=True)
class _Sensitivity:
    """First-order sensitivity of the spectrum of A to a perturbation E with ‖E‖₂ ≤ tol·‖A‖₂.

    ``kappa[i]`` = ‖P_i‖₂, P_i the spectral projector of the i-th distinct eigenvalue (for a simple
    eigenvalue ‖P_i‖ = κ(λ_i) = ‖x‖‖y‖/|y^H x| from its right/left eigenvectors x, y); ``delta[i]``
    the radius of its neighbourhood (see :func:`_sensitivity`); ``eps`` = tol·‖A‖₂.
    """

    eps: float
    kappa: tuple[float, ...]
    delta: tuple[float, ...]

    def subspace(self, a: np.ndarray, st: Structure, ids: list[int]) -> float:
        """Bound on how far the invariant subspace span{V_I} turns under A + E (≤ 1).

        Stewart's theorem on invariant subspaces (Stewart–Sun, Thm V.2.7): in a Schur form
        A = Z [[T₁₁, T₁₂], [0, T₂₂]] Z^H with the eigenvalues of I in T₁₁, and ‖E‖₂ ≤ ε, put
        δ = sep(T₁₁, T₂₂) − 2ε, γ = ε, η = ‖T₁₂‖ + ε. If γη/δ² < 1/4, A + E has an invariant
        subspace span{Z(I; X)} with ‖X‖₂ ≤ 2γ/δ, so the subspace turns by at most that.

        .. math:: \\operatorname{sep}(T_{11}, T_{22}) = \\sigma_{\\min}(I \\otimes T_{22}
                  - T_{11}^T \\otimes I)

        Only the separation of the two spectral parts enters: a defective eigenvalue *outside*
        I does not make the subspace of I sensitive unless it is close to I's eigenvalues.
        Above :data:`STEWART_MAX_STATES` states the first-order estimate is used (each Stewart
        bound costs a Schur reordering and a Sylvester separation)."""
        if a.shape[0] > STEWART_MAX_STATES:
            return self._first_order_turn(st, ids)
        turn = subspace_turn(a, st, ids, self.eps)
        return turn if turn is not None else self._first_order_turn(st, ids)

    def _first_order_turn(self, st: Structure, ids: list[int]) -> float:
        """First-order estimate for large blocks: δv_i = Σ_{j∉I} v_j (y_j^H E v_i)/((λ_i − λ_j)
        y_j^H v_j), norm ≤ ε Σ_{j∉I} κ_j/|λ_i − λ_j| (1.0 when some κ_j is infinite)."""
        tot = 0.0
        for j, ej in enumerate(st.eigen):
            if j in ids:
                continue
            gap = min(abs(st.eigen[i].value - ej.value) for i in ids)
            if gap == 0 or not math.isfinite(self.kappa[j]):
                return 1.0
            tot += self.kappa[j] / gap
        return min(1.0, self.eps * tot)


_SEP_MAX_ORDER = 600
STEWART_MAX_STATES = 100
"""Largest n whose invariant-subspace turns use Stewart's bound (first order beyond)."""
"""Largest k·(n − k) for which sep(T₁₁, T₂₂) is computed from the Kronecker form."""


def subspace_turn(a: np.ndarray, st: Structure, ids: list[int], eps: float) -> float | None:
    """Stewart's bound 2ε/δ on the turn of span{V_I} (see :meth:`_Sensitivity.subspace`);
    1.0 when it does not apply (parts not separated), None when sep is too large to compute."""
    import scipy.linalg as sla

    n = a.shape[0]
    w = np.linalg.eigvals(a)
    chosen: list[int] = []
    for i in ids:
        e = st.eigen[i]
        free = sorted((k for k in range(n) if k not in chosen), key=lambda k: abs(w[k] - e.value))
        chosen.extend(free[:e.multiplicity])
    k = len(chosen)
    if k >= n:
        return 0.0
    inside, outside = w[chosen], np.delete(w, chosen)
    gap = float(np.min(np.abs(inside[:, None] - outside[None, :])))
    if gap == 0.0:
        return 1.0
    if k * (n - k) > _SEP_MAX_ORDER:
        return None
    T, _, sdim = sla.schur(a.astype(complex), output="complex",
                           sort=lambda x: bool(np.min(np.abs(inside - x)) < gap / 2))
    if sdim != k:
        return 1.0
    T11, T12, T22 = T[:k, :k], T[:k, k:], T[k:, k:]
    S = np.kron(np.eye(k), T22) - np.kron(T11.T, np.eye(n - k))
    sep = float(np.linalg.svd(S, compute_uv=False).min())
    delta = sep - 2 * eps
    eta = float(np.linalg.norm(T12, 2)) + eps
    if delta <= 0 or eps * eta / delta ** 2 >= 0.25:
        return 1.0
    return min(1.0, 2 * eps / delta)


def _sensitivity(system: System, st: Structure, tol: float) -> _Sensitivity:
    """Neighbourhood radii δ_i of the eigenvalues of A + E, ‖E‖₂ ≤ tol·‖A‖₂ (Bauer–Fike /
    first-order perturbation theory, e.g. Stewart–Sun, Matrix Perturbation Theory, Ch. IV–V).

    * semisimple λ_i (geometric = algebraic multiplicity): the eigenvalues of A + E near λ_i lie
      within δ_i = κ_i·tol·‖A‖₂ + O(tol²), κ_i = ‖P_i‖₂ (spectral projector; κ(λ) for a simple
      eigenvalue, = 1 for normal A);
    * defective λ_i (largest possible Jordan block k = algebraic − geometric + 1): the first-order
      bound does not exist, the eigenvalues move like ‖E‖^{1/k} (Lidskii); we use
      δ_i = ‖A‖₂·tol^{1/k} (the leading-order scale with unit constant — an estimate, not a bound).

    Moduli |λ| can move by δ_i, arguments arg λ by about δ_i/|λ_i|; δ_i is capped at ‖A‖₂ + 1.
    """
    a = np.asarray(system.a, dtype=float)
    n = a.shape[0]
    norm = max(st.norm_A, np.finfo(float).tiny)
    eps = tol * norm
    big = 1.0 / NUMERIC_FLOOR
    try:
        w, V = np.linalg.eig(a)
        Vinv = np.linalg.inv(V)
        ok = bool(np.all(np.isfinite(Vinv)))
    except np.linalg.LinAlgError:
        w, V, Vinv, ok = np.zeros(n), None, None, False
    used: set[int] = set()
    kappa, delta = [], []
    for e in st.eigen:
        order = sorted((k for k in range(n) if k not in used),
                       key=lambda k: abs(w[k] - e.value))[:e.multiplicity]
        used.update(order)
        if e.geometric < e.multiplicity:
            kappa.append(math.inf)
            k = e.multiplicity - e.geometric + 1
            delta.append(min(norm * tol ** (1.0 / k), norm + 1.0))
            continue
        if not ok:
            kap = big
        elif len(order) == 1:
            kap = float(np.linalg.norm(V[:, order[0]]) * np.linalg.norm(Vinv[order[0], :]))
        else:
            kap = float(np.linalg.norm(V[:, order] @ Vinv[order, :], 2))
        kap = min(max(kap, 1.0), big)
        kappa.append(kap)
        delta.append(min(eps * kap, norm + 1.0))
    return _Sensitivity(eps, tuple(kappa), tuple(delta))


def _sigma_min(st: Structure, c: np.ndarray, ids: list[int]) -> float:
    """Least singular value of C·Q, Q an orthonormal basis of span{V_I} (the distance of C
    restricted to the invariant subspace from rank deficiency)."""
    B = np.hstack([st.eigen[i].basis for i in ids])
    if B.size == 0 or c.shape[0] < B.shape[1]:
        return 0.0          # fewer outputs than columns: rank deficient for every C
    Q, _ = np.linalg.qr(B)
    return float(np.linalg.svd(c @ Q, compute_uv=False).min())


def _nearby_q(turn: float, width: float, q: int | None) -> int | None:
    """Least denominator q' ≤ MAX_DENOMINATOR of a rational within ``width`` of φ/2π (or q)."""
    width = min(width, 0.5)
    frac = simplest_rational(Fraction(turn) - Fraction(width), Fraction(turn) + Fraction(width))
    cand = frac.denominator if frac.denominator <= MAX_DENOMINATOR else None
    if q is None:
        return cand
    return q if cand is None else min(q, cand)


def _nearby_mod2(e: Any, tol: float) -> tuple[float, sp.Expr | None]:
    """|λ|² of the nearby case, exactly: the simplest rational within relative 4·tol of |λ|²
    (a point of the neighbourhood: e.g. |λ|² = 1 + 1.7320508075688772² → 4), else the exact
    |λ|² when it is short, else the float."""
    if tol > 0 and e.mod2 > 0:
        m2, w = Fraction(e.mod2), Fraction(4 * tol)
        lo, hi = m2 * (1 - w), m2 * (1 + w)
        frac = simplest_rational(lo, hi)
        if frac.denominator <= MAX_DENOMINATOR and abs(frac.numerator) <= 10**9:
            x = sp.Rational(frac.numerator, frac.denominator)
            return float(x), x
    if e.mod2_expr is not None and not _LONG_NUMBER.search(sp.sstr(e.mod2_expr)):
        return e.mod2, e.mod2_expr
    return e.mod2, None


def _nearby_pair_value(e: Any, q: int | None, tol: float) -> Num:
    mod2, expr = _nearby_mod2(e, tol)
    above = cmp_exact(expr, 1) > 0 if expr is not None else mod2 > 1
    return pair_value(mod2, q, expr, above)


def _nearby_cases(system: System, st: Structure, tol: float) -> tuple[list[tuple[Num, str]],
                                                                     list[str]]:
    """Worse cases for some A + E, C + F with ‖E‖ ≤ tol·‖A‖, ‖F‖ ≤ tol·‖C‖: (value, description)
    and plain warnings. Neighbourhoods from :func:`_sensitivity`: |λ_i| moves by δ_i, arg λ_i by
    δ_i/|λ_i|, and σ_min of C on an invariant subspace by ‖C‖·(tol + η_I), η_I the first-order
    turn of that subspace (:meth:`_Sensitivity.subspace`)."""
    c = system.c
    a = np.asarray(system.a, dtype=float)
    sens = _sensitivity(system, st, tol)
    dl = sens.delta
    normc = max(st.norm_C, np.finfo(float).tiny)

    def ctol(ids: list[int]) -> float:
        return normc * (tol + sens.subspace(a, st, ids))

    cases: list[tuple[Num, str]] = []
    notes: list[str] = []
    near = [i for i, e in enumerate(st.eigen) if e.modulus + dl[i] >= 1]

    def rad(i: int) -> str:
        return (f"δ = {dl[i]:.3g}" + (f", κ = {sens.kappa[i]:.3g}"
                                      if math.isfinite(sens.kappa[i]) else ", defective"))
    for i in near:
        if i not in st.undetectable and _sigma_min(st, c, [i]) <= ctol([i]):
            where = ("|λ| ≥ 1" if st.relevant(i) else
                     f"|λ| {_is_mod(st, i)} < 1 but within {rad(i)} of the unit circle")
            cases.append((Num(1.0, sp.Integer(1)),
                          f"eigenvalue {_eig_text(st, i)} ({where}) is within relative {tol:g} of "
                          "being unobservable: a nearby system is not detectable"))
        elif not st.relevant(i):
            notes.append(f"eigenvalue {_eig_text(st, i)} (|λ| {_is_mod(st, i)} < 1) is within "
                         f"{rad(i)} of the unit circle: a system within relative {tol:g} is "
                         "critically stable or unstable (p_c moves continuously from 0)")
    pairs = {(p.a, p.b): p for p in st.pairs}
    for ia, i in enumerate(near):
        for j in near[ia + 1:]:
            ei, ej = st.eigen[i], st.eigen[j]
            pair = pairs.get((i, j))
            if pair is None and abs(ei.modulus - ej.modulus) > dl[i] + dl[j]:
                continue
            exact_def = pair is not None and pair.degenerate
            smin = 0.0 if exact_def else _sigma_min(st, c, [i, j])
            if not (exact_def or smin <= ctol([i, j])):
                continue
            turn = pair.turn if pair is not None else _turn_of(ej.value / ei.value)
            width = (dl[i] / max(ei.modulus, 1e-300) + dl[j] / max(ej.modulus, 1e-300)) \
                / (2 * math.pi)
            q_now = pair.q if (pair is not None and pair.degenerate) else None
            qn = _nearby_q(turn, width, pair.q if pair is not None else None)
            if exact_def and qn == q_now:
                continue
            hi = i if ei.mod2 >= ej.mod2 else j
            val = _nearby_pair_value(st.eigen[hi], qn, tol)
            why = []
            if pair is None:
                why.append(f"moduli {_mod_text(st, i)} and {_mod_text(st, j)} differ by at most "
                           f"δ_i + δ_j ({rad(i)}; {rad(j)}) for perturbations of relative size "
                           f"{tol:g} (a nearby system has an equal-modulus pair)")
            if not exact_def:
                why.append("the pair's columns of C·V have rank 1" if smin == 0.0 else
                           f"the pair's columns of C·V are within relative {tol:g} of rank 1")
            if qn is not None and qn != q_now:
                why.append(f"φ/2π ≈ {turn:.12g} is within {width:.3g} of a rational with q = {qn}")
            desc = (f"eigenvalues {_eig_text(st, i)}, {_eig_text(st, j)}: "
                    + "; ".join(w for w in why if w)
                    + (f" → degenerate pair with q = {qn}, p_c = {val.expression}" if qn != 1
                       else " → equal eigenvalues seen through one column: not detectable"))
            cases.append((val, desc))
    for b in st.blocks:
        if b.relevant and b.one_step_observable and b.size >= 3 \
                and _sigma_min(st, c, list(b.members)) <= ctol(list(b.members)):
            notes.append(f"equi-block at |λ| {_is_mod(st, b.members[0])} is within relative "
                         f"{tol:g} of a degenerate block of order {b.size}, for which the papers "
                         "give no closed form")
    return cases, notes


def _strict_tolerance(system: System, st: Structure) -> float:
    """Float64 resolution of the numeric decisions: 64 ulp · max κ (the rounding error of the
    computed eigenvalues relative to ‖A‖), at most 1e-3."""
    sens = _sensitivity(system, st, NUMERIC_FLOOR)
    kmax = max([k for k in sens.kappa if math.isfinite(k)] or [1.0])
    return min(NUMERIC_FLOOR * kmax, 1e-3)


def _headline_structure(system: System, st: Structure) -> tuple[Structure, Structure | None]:
    """The structure behind the headline p_c and, on the numeric path, the one decided at the
    user's tolerance when that is looser than float64 resolution.

    The headline is the system as entered: on the numeric path its decisions are made at float64
    resolution (:func:`_strict_tolerance`), so that moduli, ranks and angles which only *agree
    within the tolerance* are kept apart. What the tolerance merges is a nearby system — it
    enters the robust value (:func:`_tolerance_alternative`), never the headline."""
    if st.path != "numeric":
        return st, None
    strict = _strict_tolerance(system, st)
    if strict >= _mtol(st):
        return st, None
    return structure_at(st, system, strict), st


def _tolerance_alternative(system: System, st_tol: Structure | None, value: Num | None,
                           blow: Num | None, classification: str) -> dict[str, Any] | None:
    """Numeric path: the case decided with the user's tolerance, when it differs from the
    headline (decided at float64 resolution): {value, expression, classification, case}."""
    if st_tol is None:
        return None
    low2 = _lower(st_tol)
    cls2, val2, reason2 = _classify(system, st_tol, low2)
    if cls2 == "not-detectable":
        alt: Num | None = Num(1.0, sp.Integer(1))
    else:
        alt = val2 if val2 is not None else _block_lower(st_tol, low2)[0]
    mine = value if value is not None else blow
    if cls2 == classification and alt is not None and mine is not None \
            and abs(alt.value - mine.value) <= 1e-12:
        return None
    return {"value": alt.value if alt is not None else None,
            "expression": alt.expression if alt is not None else None,
            "classification": cls2,
            "case": (f"decisions at the tolerance {_mtol(st_tol):g} (moduli, ranks and angles "
                     f"equal within it are merged): {cls2}"
                     + ("" if val2 is not None or cls2 == "not-detectable"
                        else " (block lower bound)") + f"; {reason2}")}


def _turn_of(z: complex) -> float:
    t = math.atan2(z.imag, z.real) / (2 * math.pi)
    return t + 1.0 if t < 0 else t


# --------------------------------------------------------------------------- theory

def _theory(system: System, st: Structure, classification: str, pc: Num | None,
            channel: Any) -> dict[str, Any]:
    top = st.eigen[0]
    all_unstable = all(st.relevant(i) for i in range(len(st.eigen))) and not any(
        _on_circle(e, st) for e in st.eigen)
    applies = classification == "non-degenerate" and all_unstable
    moments = []
    for q in (1, 2):
        if not nondegenerate_value(top.mod2, top.mod2_expr, _eig_above(top, st)).value > 0:
            v = Num(0.0, sp.Integer(0) if top.mod2_expr is not None else None)
        elif top.mod2_expr is not None:
            v = _num(1 - top.mod2_expr ** (-q))
        else:
            v = Num(1 - top.mod2 ** (-q))
        moments.append({"q": q, "value": v.value, "expression": v.expression,
                        "applies": applies})
    pc_text = "p_c (not known in closed form)" if pc is None else p_c_text(
        pc.value, pc.expression if pc.expr is not None else None, system.exact)
    if st.detectable:
        sb = ("Kar–Sinopoli–Moura Thm 9: for every arrival probability p > 0 the random Riccati "
              "sequence Pₜ is stochastically bounded and converges weakly to a unique invariant "
              f"distribution from every P_0; that distribution has a finite mean iff p > "
              f"{pc_text}.")
        if not st.controllable_Q:
            sb += (" (Their hypothesis (A, Q^(1/2)) stabilizable is assumed here: kfcrit checked "
                   "controllability, which failed.)")
    else:
        sb = ("Kar–Sinopoli–Moura Thm 9 needs (C, A) detectable, which fails: no statement.")
    return {"moment_thresholds": moments,
            "moment_thresholds_note": ("Mo–Sinopoli Cor. 2: supₖ E[Pₖ^q] < ∞ iff "
                                       "p > 1 − |λ₁|^(−2q); applies to non-degenerate systems "
                                       "whose eigenvalues are all unstable"),
            "stochastic_boundedness": sb,
            "almost_sure": _almost_sure(st, channel),
            "observability_index": st.observability_index}


def _almost_sure(st: Structure, channel: Any) -> list[str]:
    """Plain sentences from docs/theory.md §6 (Wu–Shi–Anderson–Johansson) for the configured channel."""
    label = ("Consequence (Borel–Cantelli argument on Wu–Shi–Anderson–Johansson Lemma 4, "
             "docs/theory.md §6), not a theorem of the papers: ")
    if not st.detectable:
        return ["(C, A) is not detectable: tr Pₖ diverges almost surely on every channel."]
    if st.stable:
        return ["A is stable: tr Pₖ stays bounded by a deterministic constant for every arrival "
                "sequence (absolutely upper and lower almost-surely stable)."]
    io = st.observability_index
    critical = not any(_eig_above(e, st) for e in st.eigen)
    if io is not None:
        m_text = f"liminf tr Pₖ ≤ tr M with M = h{superscript(io)}(M₀) (Iₒ = {io})"
    elif st.observable:
        m_text = ("liminf tr Pₖ ≤ tr M with M = h^(Iₒ)(M₀) ((C, A) is observable by the PBH "
                  "test; Iₒ itself is not determined in floating point at this size)")
    else:
        m_text = "a liminf bound (Lemma 4 needs (C, A) observable, which fails here)"
    if critical:
        general = (label + "A is critically stable (ρ(A) = 1, no |λ| > 1), not unstable: the "
                   "upper a.s. instability consequence of docs/theory.md §6 is stated for unstable A and is "
                   "not claimed here. For an arrival process in which every run of Iₒ arrivals "
                   f"recurs infinitely often, {m_text} (absolutely lower a.s. stable). Mean "
                   "stability is a different, stronger notion.")
    else:
        general = (label + "for unstable A and an arrival process in which every finite loss "
                   "burst and every run of Iₒ arrivals recur infinitely often, limsup tr Pₖ = ∞ "
                   f"almost surely (upper a.s. unstable) while {m_text} (absolutely lower a.s. "
                   "stable). Mean stability is a different, stronger notion.")
    if channel is None:
        return [general]
    model = getattr(channel, "model", None)
    if model == "bernoulli":
        p = channel.arrival_probability
        if p == 1:
            return ["Every packet arrives (p = 1): the standard Kalman filter; Pₖ converges "
                    "to the Riccati fixed point (detectable system), so tr Pₖ is bounded."]
        if p == 0 and not critical:
            return ["No packet arrives (p = 0): open-loop prediction of an unstable system; "
                    "tr Pₖ → ∞ surely."]
        if p == 0:
            return ["No packet arrives (p = 0): open-loop prediction of a critically stable "
                    "system (ρ(A) = 1); no almost-sure statement of docs/theory.md §6 applies."]
        return [f"i.i.d. losses with 0 < p = {sp.sstr(p)} < 1 satisfy the recurrence condition. "
                + general]
    if model == "gilbert-elliott":
        f, r = channel.failure_rate, channel.recovery_rate
        if 0 < f < 1 and 0 < r < 1:
            return [f"Gilbert–Elliott losses with both rates in (0, 1) (failure {sp.sstr(f)}, "
                    f"recovery {sp.sstr(r)}) are a *-mixing Markov chain satisfying the "
                    "recurrence condition. " + general]
        return ["Gilbert–Elliott losses with a rate equal to 1: some loss bursts or arrival runs "
                "never occur, so the recurrence condition of docs/theory.md §6 does not hold; no "
                "statement."]
    if model == "trace":
        return ["A recorded trace is finite: the almost-sure statements concern infinite "
                "arrival sequences and are not evaluated for it."]
    return [f"Channel model {model!r}: the recurrence condition of docs/theory.md §6 is not checked "
            "for it. " + general]


# --------------------------------------------------------------------------- entry points

def _hypothesis_warnings(system: System, st: Structure) -> list[str]:
    out = []
    if st.path == "numeric":
        out.append(f"eigen-structure decided in floating point ({st.path_reason})")
    out.extend(f"float64 could not resolve the spectrum: {u}" for u in st.unresolved)
    if not st.controllable_Q:
        out.append("(A, Q^(1/2)) is not controllable: Sinopoli's existence theorem for p_c "
                   "assumes it")
    # exact for exact input, scale-aware for floats: Q = 1e-250·I is positive definite
    if not system.is_positive_definite("Q"):
        out.append("Q is not positive definite: Mo–Sinopoli (H3) assumes Q ≻ 0 (Thm 2, "
                   "independence of Q, R, Σ0)")
    if not system.is_positive_definite("Sigma0"):
        out.append("Σ0 is not positive definite: Mo–Sinopoli (H3) assumes Σ0 ≻ 0")
    return out


def _exact_p_up(system: System, st: Structure, low: Num) -> list[tuple[Num, str, bool]]:
    """Cases where the upper bound p_up is known exactly: (value, why, theorem?).

    * C invertible: p_up = p_low (Sinopoli et al. 2004 §IV, a theorem);
    * a single output (m = 1, exact path, every |λ|² of the unstable eigenvalues an explicit
      algebraic number): p_up = 1 − 1/Π_{|λ_i| > 1} |λ_i|² (with multiplicity) — docs/theory.md §3
      **[beyond]**: the dual of Elia's rank-one result, checked numerically on the paper
      examples and random single-output systems, *not* a theorem of the papers.
    """
    out: list[tuple[Num, str, bool]] = []
    if _c_invertible(system, st):
        out.append((low, "C invertible: p_up = p_low (Sinopoli et al. 2004 §IV, theorem)", True))
    if system.m == 1 and st.path == "exact":
        unstable = [e for e in st.eigen if e.unit_cmp is not None and e.unit_cmp > 0]
        if all(e.mod2_expr is not None for e in unstable):
            prod = sp.Integer(1)
            for e in unstable:
                prod = prod * e.mod2_expr ** e.multiplicity
            up = _num(sp.expand(1 - 1 / prod)) if unstable else Num(0.0, sp.Integer(0))
            out.append((up, (f"single output: p_up = 1 − 1/Π|λ_u|² = {up.expression} over the "
                             "eigenvalues with |λ| > 1 — a claim (docs/theory.md §3 [beyond]: the dual of "
                             "Elia's rank-one result, checked numerically, not a theorem of the "
                             "papers)"), False))
    return out


def _coinciding(system: System, st: Structure, low: Num, blow: Num, bwhy: str
                ) -> tuple[Num, str, bool] | None:
    """The value when the block lower bound equals an exactly known p_up (exact comparison)."""
    if blow is None or blow.expr is None:
        return None
    for up, why, theorem in _exact_p_up(system, st, low):
        if up.expr is not None and cmp_exact(sp.expand(blow.expr - up.expr), 0) == 0:
            return (blow, f"the bounds coincide: block lower bound {blow.expression} ({bwhy}) = "
                          f"upper bound p_up = {up.expression} ({why}), so p_c = "
                          f"{blow.expression}", theorem)
    return None


def _robust(system: System, st: Structure, st_tol: Structure | None, tolerance: float,
            value: Num | None, blow: Num, classification: str,
            warnings: list[str]) -> dict[str, Any] | None:
    """The robust critical value: the worst case within ``tolerance`` (``value``, ≥ the
    headline) and, when some case within it is lower, the least one (``low``); every differing
    case decided at the user's tolerance in ``alternatives``. ``warnings`` is extended."""
    base = value if value is not None else blow
    cases, notes = _nearby_cases(system, st, tolerance)
    warnings.extend(notes)
    worse = [(v, d) for v, d in cases if v.value > base.value + 1e-15]
    lower = [(v, d) for v, d in cases if v.value < base.value - 1e-15]
    for _v, d in worse + lower:
        warnings.append(f"within tolerance {tolerance:g} of a different case: {d}")
    alt = _tolerance_alternative(system, st_tol, value, blow, classification)
    if alt is not None:
        warnings.append(f"numeric decision at float64 resolution {_mtol(st):.3g}: "
                        f"{classification} with "
                        f"{'p_c' if value is not None else 'block lower bound'} = "
                        f"{base.expression}; on the other side of the tolerance decisions, "
                        f"{alt['case']} gives {alt['expression']}")
        if alt["value"] is not None:
            num = Num(alt["value"]) if alt["expression"] is None else Num(
                alt["value"], None, alt["expression"])
            (worse if alt["value"] > base.value + 1e-15 else
             lower if alt["value"] < base.value - 1e-15 else []).append((num, alt["case"]))
    if not (worse or lower or alt):
        return None
    top, top_case = max(worse, key=lambda vd: vd[0].value) if worse else (base, "the headline "
                                                                          "case")
    robust: dict[str, Any] = {"value": top.value, "tolerance": tolerance,
                              "expression": _num_text(top), "nearby_case": top_case}
    if lower:
        v, d = min(lower, key=lambda vd: vd[0].value)
        robust["low"] = {"value": v.value, "expression": _num_text(v), "case": d}
    if alt is not None:
        robust["alternatives"] = [alt]
    return robust


def _num_text(v: Num) -> str:
    """The expression of a value that may carry only its text (an alternative's expression)."""
    return v.text if v.expr is None and v.text is not None else v.expression


def critical_value(system: System, tolerance: float = 1e-9, channel: Any = None,
                   structure: Structure | None = None, robust: bool = True) -> CriticalValue:
    """Classify (A, C), give p_c exactly where a theorem applies, and its robust value.

    Parameters
    ----------
    system : System
        The system (Q, R, Σ0 only enter the hypothesis checks: Mo–Sinopoli Thm 2).
    tolerance : float
        Relative perturbation size for the robust critical value (default 1e-9); on the numeric
        path also the decision tolerance of the eigen-structure.
    channel : Channel, optional
        The configured channel, for the almost-sure statements in ``theory``.
    structure : Structure, optional
        The eigen-structure of ``system`` from
        :func:`kfcrit.theory.structure.eigen.structure_of` (computed here when omitted). A numeric-path
        structure decided at another tolerance is re-decided at ``tolerance``.
    robust : bool
        Compute the robust critical value (the systems within ``tolerance``); when False the
        record says it was not computed (a draft of a large system: each eigenvalue group
        costs a Sylvester separation of order k(n − k)).

    Returns
    -------
    CriticalValue
        Record; ``.to_dict()`` gives plain JSON data (see :class:`CriticalValue`).
    """
    if not (isinstance(tolerance, (int, float)) and 0 <= tolerance <= 0.1):
        raise InputError(f"must be a number in [0, 0.1], got {tolerance!r}", field="tolerance")
    st_in = (structure_at(structure, system, tolerance) if structure is not None
             else structure_of(system, tolerance))
    st, st_tol = _headline_structure(system, st_in)
    low = _lower(st)
    classification, value, reason = _classify(system, st, low)
    reason = reason.replace("= ≈", "≈").replace("|≈ ", "|")
    if st.unresolved:
        reason += ("; RESOLUTION FAILED: float64 cannot resolve some eigenvalues of A (their "
                   "error bounds 64·ε·‖A‖·κ overlap), so this rests on the computed values: "
                   + "; ".join(st.unresolved))
    warnings = _hypothesis_warnings(system, st)
    if classification == "not-detectable":
        blow, bwhy = None, "not detectable: no finite critical value"
    else:
        blow, bwhy = _block_lower(st, low)
        if value is not None and value.value > blow.value:
            blow, bwhy = value, "equals p_c"
    basis = None
    if value is None and classification in ("degenerate", "non-diagonalizable"):
        hit = _coinciding(system, st, low, blow, bwhy)
        if hit is not None:
            value, why, theorem = hit
            reason += "; " + why
            basis = "theorem" if theorem else "claim"
            if not theorem:
                warnings.append("p_c rests on the single-output identity p_up = 1 − 1/Π|λ_u|², "
                                "a claim checked numerically (docs/theory.md §3 [beyond]), not a theorem")
    robust_value = None
    if classification != "not-detectable" and robust:
        robust_value = _robust(system, st, st_tol, tolerance, value, blow, classification,
                               warnings)
    elif classification != "not-detectable":
        warnings.append(f"robust critical value not computed (a --quick draft of n = "
                        f"{system.n} states): the verdict does not consider systems within the "
                        f"tolerance {tolerance:g}; run without --quick for it")
    theory = _theory(system, st, classification, value, channel)
    return CriticalValue(classification=classification, value=value, reason=reason, lower=low,
                         block_lower=blow, block_reason=bwhy, robust=robust_value, structure=st,
                         theory=theory, warnings=tuple(warnings), basis=basis)


def critical_section(system: System, tolerance: float = 1e-9, channel: Any = None,
                     structure: Structure | None = None) -> dict[str, Any]:
    """``critical_value(system, tolerance, channel, structure).to_dict()``."""
    return critical_value(system, tolerance, channel, structure).to_dict()
