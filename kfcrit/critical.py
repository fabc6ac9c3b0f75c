"""Critical arrival probability p_c: which theorem applies, its exact value, and how robust it is.

The decision tree (MATH.md §3–§4, Mo–Sinopoli; the eigen-structure comes from
:mod:`kfcrit.structure`):

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
import weakref
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

import numpy as np
import sympy as sp

from .errors import InputError
from .exprparse import MAX_DIGITS, exact_text
from .structure import (
    MAX_DENOMINATOR,
    NUMERIC_TOLERANCES,
    Structure,
    _cmp_exact,
    eigen_structure,
    simplest_rational,
)
from .system import System

_LONG_LITERAL = re.compile(rf"\d{{{MAX_DIGITS + 1},}}")
_LONG_NUMBER = re.compile(r"\d{13,}")

CLASSIFICATIONS = ("stable", "non-degenerate", "degenerate-second-order", "degenerate",
                   "non-diagonalizable", "not-detectable")

_CACHE: weakref.WeakKeyDictionary[System, Structure] = weakref.WeakKeyDictionary()


def structure_of(system: System) -> Structure:
    """The (cached) eigen-structure of ``system``; see :func:`kfcrit.structure.eigen_structure`."""
    if system not in _CACHE:
        _CACHE[system] = eigen_structure(system)
    return _CACHE[system]


# --------------------------------------------------------------------------- numbers

@dataclass(frozen=True)
class Num:
    """A probability: float value and, when known exactly, the sympy expression."""

    value: float
    expr: sp.Expr | None = None
    text: str | None = None

    @property
    def expression(self) -> str:
        """Text readable by sympy and :func:`kfcrit.exprparse.parse_expression`."""
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
    return _cmp_exact(mod2_expr, 1) > 0


_ZERO = Num(0.0, sp.Integer(0))


def _eig_above(e: Any) -> bool:
    """|λ| > 1 as decided by the structure (exactly on the exact path; on the numeric path
    |λ| within the modulus tolerance of 1 counts as critically stable)."""
    if e.unit_cmp is not None:
        return e.unit_cmp > 0
    return e.mod2 > 1 + 2 * NUMERIC_TOLERANCES["modulus_relative"]


def _on_circle(e: Any) -> bool:
    return e.unit_cmp == 0 if e.unit_cmp is not None else abs(e.mod2 - 1) <= 1e-10


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
        return Num(v.value, v.expr, f"1 - ({sp.sstr(mod2_expr)})**(-{q}/{q - 1})")
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

_SUPERSCRIPT = str.maketrans("0123456789-−", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻⁻")


def _sup(k: int) -> str:
    """An integer as Unicode superscript digits (h² for the second iterate)."""
    return str(k).translate(_SUPERSCRIPT)


def _short(text: str | None, approx: str) -> str:
    """Exact text when it is short enough to read, else the float approximation."""
    return text if text is not None and len(text) <= 48 else approx


def _float_text(z: complex) -> str:
    """A computed complex number in full (shortest round-trip repr of each part): a float
    result is never shown rounded to a value it does not have (1.9999999999999998, not 2)."""
    if z.imag == 0:
        return repr(float(z.real))
    return f"{float(z.real)!r}{'+' if z.imag > 0 else '-'}{abs(float(z.imag))!r}j"


def _eig_text(st: Structure, i: int) -> str:
    e = st.eigen[i]
    text = sp.sstr(e.expr) if e.expr is not None else None
    if text is not None and _LONG_NUMBER.search(text):
        return "≈ " + _float_text(e.value)     # e.g. binary-float input: 2^51 denominators
    return _short(text, _float_text(e.value))


def _mod_text(st: Structure, i: int) -> str:
    """|λ_i|: the exact expression when short, else the computed float marked "≈" (exact
    path: the float of the exact value) or as computed (numeric path)."""
    e = st.eigen[i]
    if e.mod2_expr is not None:
        return _short(sp.sstr(sp.sqrt(e.mod2_expr)), f"≈ {e.modulus!r}")
    return repr(e.modulus)


def _decided_text(system: System, st: Structure, what: str) -> str:
    """How a discrete decision (``what``) was made, for reason texts on float input."""
    if st.path == "numeric":
        tol = st.tolerances.get("modulus_relative", NUMERIC_TOLERANCES["modulus_relative"])
        return (f" ({what} decided in floating point: equal within relative tolerance "
                f"{tol:g}; the numbers shown are the computed float64 values)")
    if not system.exact:
        return (f" ({what} decided exactly on the binary-float input taken as the rationals "
                "it represents; numbers marked ≈ are float64 roundings of exact values)")
    return ""


def _lower(st: Structure) -> Num:
    """Sinopoli Thm 3: p_low = max(1 − 1/ρ(A)², 0) (eigen is sorted by modulus)."""
    top = st.eigen[0]
    return nondegenerate_value(top.mod2, top.mod2_expr, _eig_above(top))


def lower_bound(system: System) -> dict[str, Any]:
    """Sinopoli Thm 3 lower bound p_low = 1 − 1/ρ(A)², 0 when ρ(A) ≤ 1: {value, expression}."""
    return _lower(structure_of(system)).to_dict()


def _pair_num(st: Structure, pair: Any, q: int | None) -> Num:
    e = st.eigen[pair.a]
    return pair_value(e.mod2, q, e.mod2_expr, _eig_above(e))


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
    return not _on_circle(st.eigen[rel[0]])


# --------------------------------------------------------------------------- decision tree

def _classify(system: System, st: Structure, low: Num) -> tuple[str, Num | None, str]:
    if not st.detectable:
        bad = ", ".join(_eig_text(st, i) for i in st.undetectable)
        return ("not-detectable", None,
                f"(C, A) is not detectable: eigenvalue(s) {bad} with |λ| ≥ 1 have an eigenvector "
                "with C v = 0, so E[Pₜ] (indeed Pₜ itself) diverges for every arrival "
                "probability, even with no losses (PBH test)")
    if st.stable:
        return ("stable", Num(0.0, sp.Integer(0)),
                f"ρ(A) = {_mod_text(st, 0)} < 1: E[Pₜ] is bounded for every p, p_c = 0")
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
            f"|λ| = {_mod_text(st, b.members[0])}: rank C_I = {b.rank} = size {b.size}"
            for b in rel_blocks)
        return ("non-degenerate", low,
                f"Mo–Sinopoli Thm 4: every equi-block with |λ| ≥ 1 is one-step observable "
                f"({facts}); p_c = max(1 − |λ₁|⁻², 0) with |λ₁| = {_mod_text(st, 0)}"
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
                f"Mo–Sinopoli Thm 5{extra}: equal moduli |{_eig_text(st, a)}| = "
                f"|{_eig_text(st, b)}| = {_mod_text(st, a)}, rank C_I = {pair.rank} < 2, "
                f"{qtext}" + _decided_text(system, st, "equal moduli, rank and φ/2π"))
    return ("degenerate", None,
            f"degenerate equi-block of size {blk.size} with rank C_I = {blk.rank} at |λ| = "
            f"{_mod_text(st, blk.members[0])}"
            + ("" if len(rel_blocks) == 1 else f" among {len(rel_blocks)} equi-blocks with |λ| ≥ 1")
            + ": beyond second order the papers give no closed form; p_c lies in "
              "[block lower bound, LMI upper bound]")


# --------------------------------------------------------------------------- robustness

def _sigma_min(st: Structure, c: np.ndarray, ids: list[int]) -> float:
    M = c @ np.hstack([st.eigen[i].basis for i in ids])
    if M.size == 0 or M.shape[0] < M.shape[1]:
        return 0.0          # fewer outputs than columns: rank deficient for every C
    return float(np.linalg.svd(M, compute_uv=False).min())


def _nearby_q(turn: float, tol: float, q: int | None) -> int | None:
    """Least denominator q' ≤ MAX_DENOMINATOR of a rational within ``tol`` of φ/2π (or q)."""
    frac = simplest_rational(Fraction(turn) - Fraction(tol), Fraction(turn) + Fraction(tol))
    cand = frac.denominator if frac.denominator <= MAX_DENOMINATOR else None
    if q is None:
        return cand
    return q if cand is None else min(q, cand)


def _nearby_cases(system: System, st: Structure, tol: float) -> tuple[list[tuple[Num, str]],
                                                                     list[str]]:
    """Worse cases within relative ``tol``: (value, description) and plain warnings."""
    c = system.c
    ctol = tol * max(st.norm_C, np.finfo(float).tiny)
    cases: list[tuple[Num, str]] = []
    notes: list[str] = []
    near = [i for i, e in enumerate(st.eigen) if e.modulus >= 1 - tol]
    for i in near:
        if i not in st.undetectable and _sigma_min(st, c, [i]) <= ctol:
            cases.append((Num(1.0, sp.Integer(1)),
                          f"eigenvalue {_eig_text(st, i)} (|λ| ≥ 1) is within relative {tol:g} of "
                          "being unobservable: a nearby system is not detectable"))
    pairs = {(p.a, p.b): p for p in st.pairs}
    for ia, i in enumerate(near):
        for j in near[ia + 1:]:
            ei, ej = st.eigen[i], st.eigen[j]
            pair = pairs.get((i, j))
            if pair is None and abs(ei.modulus - ej.modulus) > tol * max(ei.modulus, ej.modulus):
                continue
            exact_def = pair is not None and pair.degenerate
            smin = 0.0 if exact_def else _sigma_min(st, c, [i, j])
            if not (exact_def or smin <= ctol):
                continue
            turn = pair.turn if pair is not None else _turn_of(ej.value / ei.value)
            q_now = pair.q if (pair is not None and pair.degenerate) else None
            qn = _nearby_q(turn, tol, pair.q if pair is not None else None)
            hi = i if ei.mod2 >= ej.mod2 else j
            val = pair_value(st.eigen[hi].mod2, qn, st.eigen[hi].mod2_expr,
                             _eig_above(st.eigen[hi]))
            now = (pair_value(ei.mod2, q_now, ei.mod2_expr, _eig_above(ei))
                   if pair is not None and pair.degenerate else None)
            if now is not None and qn == q_now:
                continue
            why = []
            if pair is None:
                why.append(f"moduli {_mod_text(st, i)} and {_mod_text(st, j)} are within "
                           f"relative {tol:g} (a nearby system has an equal-modulus pair)")
            if not exact_def:
                why.append("the pair's columns of C·V have rank 1" if smin == 0.0 else
                           f"the pair's columns of C·V are within relative {tol:g} of rank 1")
            if qn is not None and qn != q_now:
                why.append(f"φ/2π ≈ {turn:.12g} is within {tol:g} of a rational with q = {qn}")
            desc = (f"eigenvalues {_eig_text(st, i)}, {_eig_text(st, j)}: "
                    + "; ".join(w for w in why if w)
                    + (f" → degenerate pair with q = {qn}, p_c = {val.expression}" if qn != 1
                       else " → equal eigenvalues seen through one column: not detectable"))
            cases.append((val, desc))
    for b in st.blocks:
        if b.relevant and b.one_step_observable and b.size >= 3 \
                and _sigma_min(st, c, list(b.members)) <= ctol:
            notes.append(f"equi-block at |λ| = {_mod_text(st, b.members[0])} is within relative "
                         f"{tol:g} of a degenerate block of order {b.size}, for which the papers "
                         "give no closed form")
    return cases, notes


def _turn_of(z: complex) -> float:
    t = math.atan2(z.imag, z.real) / (2 * math.pi)
    return t + 1.0 if t < 0 else t


# --------------------------------------------------------------------------- theory

def _theory(system: System, st: Structure, classification: str, pc: Num | None,
            channel: Any) -> dict[str, Any]:
    top = st.eigen[0]
    all_unstable = all(st.relevant(i) for i in range(len(st.eigen))) and not any(
        _on_circle(e) for e in st.eigen)
    applies = classification == "non-degenerate" and all_unstable
    moments = []
    for q in (1, 2):
        if not nondegenerate_value(top.mod2, top.mod2_expr, _eig_above(top)).value > 0:
            v = Num(0.0, sp.Integer(0) if top.mod2_expr is not None else None)
        elif top.mod2_expr is not None:
            v = _num(1 - top.mod2_expr ** (-q))
        else:
            v = Num(1 - top.mod2 ** (-q))
        moments.append({"q": q, "value": v.value, "expression": v.expression,
                        "applies": applies})
    pc_text = pc.expression if pc is not None else "p_c (not known in closed form)"
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
    """Plain sentences from MATH §6 (Wu–Shi–Anderson–Johansson) for the configured channel."""
    label = ("Consequence (Borel–Cantelli argument on Wu–Shi–Anderson–Johansson Lemma 4, "
             "MATH §6), not a theorem of the papers: ")
    if not st.detectable:
        return ["(C, A) is not detectable: tr Pₖ diverges almost surely on every channel."]
    if st.stable:
        return ["A is stable: tr Pₖ stays bounded by a deterministic constant for every arrival "
                "sequence (absolutely upper and lower almost-surely stable)."]
    io = st.observability_index
    if io is not None:
        m_text = f"liminf tr Pₖ ≤ tr M with M = h{_sup(io)}(M₀) (Iₒ = {io})"
    elif st.observable:
        m_text = ("liminf tr Pₖ ≤ tr M with M = h^(Iₒ)(M₀) ((C, A) is observable by the PBH "
                  "test; Iₒ itself is not determined in floating point at this size)")
    else:
        m_text = "a liminf bound (Lemma 4 needs (C, A) observable, which fails here)"
    general = (label + "for unstable A and an arrival process in which every finite loss burst "
               "and every run of Iₒ arrivals recur infinitely often, limsup tr Pₖ = ∞ almost "
               f"surely (upper a.s. unstable) while {m_text} (absolutely lower a.s. stable). "
               "Mean stability is a different, stronger notion.")
    if channel is None:
        return [general]
    model = getattr(channel, "model", None)
    if model == "bernoulli":
        p = channel.arrival_probability
        if p == 1:
            return ["Every packet arrives (p = 1): the standard Kalman filter; Pₖ converges "
                    "to the Riccati fixed point (detectable system), so tr Pₖ is bounded."]
        if p == 0:
            return ["No packet arrives (p = 0): open-loop prediction of an unstable system; "
                    "tr Pₖ → ∞ surely."]
        return [f"i.i.d. losses with 0 < p = {sp.sstr(p)} < 1 satisfy the recurrence condition. "
                + general]
    if model == "gilbert-elliott":
        f, r = channel.failure_rate, channel.recovery_rate
        if 0 < f < 1 and 0 < r < 1:
            return [f"Gilbert–Elliott losses with both rates in (0, 1) (failure {sp.sstr(f)}, "
                    f"recovery {sp.sstr(r)}) are a *-mixing Markov chain satisfying the "
                    "recurrence condition. " + general]
        return ["Gilbert–Elliott losses with a rate equal to 1: some loss bursts or arrival runs "
                "never occur, so the recurrence condition of MATH §6 does not hold; no "
                "statement."]
    if model == "trace":
        return ["A recorded trace is finite: the almost-sure statements concern infinite "
                "arrival sequences and are not evaluated for it."]
    return [f"Channel model {model!r}: the recurrence condition of MATH §6 is not checked "
            "for it. " + general]


# --------------------------------------------------------------------------- entry points

def _hypothesis_warnings(system: System, st: Structure) -> list[str]:
    out = []
    if st.path == "numeric":
        out.append(f"eigen-structure decided in floating point ({st.path_reason})")
    if not st.controllable_Q:
        out.append("(A, Q^(1/2)) is not controllable: Sinopoli's existence theorem for p_c "
                   "assumes it")
    qf = np.linalg.eigvalsh(0.5 * (system.q + system.q.T))
    if qf.min() <= 1e-12 * max(1.0, float(np.abs(qf).max())):
        out.append("Q is not positive definite: Mo–Sinopoli (H3) assumes Q ≻ 0 (Thm 2, "
                   "independence of Q, R, Σ0)")
    sf = np.linalg.eigvalsh(0.5 * (system.sigma0 + system.sigma0.T))
    if sf.min() <= 1e-12 * max(1.0, float(np.abs(sf).max())):
        out.append("Σ0 is not positive definite: Mo–Sinopoli (H3) assumes Σ0 ≻ 0")
    return out


def critical_value(system: System, tolerance: float = 1e-9, channel: Any = None) -> CriticalValue:
    """Classify (A, C), give p_c exactly where a theorem applies, and its robust value.

    Parameters
    ----------
    system : System
        The system (Q, R, Σ0 only enter the hypothesis checks: Mo–Sinopoli Thm 2).
    tolerance : float
        Relative perturbation size for the robust critical value (default 1e-9).
    channel : Channel, optional
        The configured channel, for the almost-sure statements in ``theory``.

    Returns
    -------
    CriticalValue
        Record; ``.to_dict()`` gives plain JSON data (see :class:`CriticalValue`).
    """
    if not (isinstance(tolerance, (int, float)) and 0 <= tolerance <= 0.1):
        raise InputError(f"must be a number in [0, 0.1], got {tolerance!r}", field="tolerance")
    st = structure_of(system)
    low = _lower(st)
    classification, value, reason = _classify(system, st, low)
    reason = reason.replace("= ≈", "≈").replace("|≈ ", "|")
    warnings = _hypothesis_warnings(system, st)
    if classification == "not-detectable":
        blow, bwhy = None, "not detectable: no finite critical value"
    else:
        blow, bwhy = _block_lower(st, low)
        if value is not None and value.value > blow.value:
            blow, bwhy = value, "equals p_c"
    robust = None
    if classification not in ("not-detectable", "stable"):
        base = value if value is not None else blow
        cases, notes = _nearby_cases(system, st, tolerance)
        warnings.extend(notes)
        worse = [(v, d) for v, d in cases if v.value > base.value + 1e-15]
        for _v, d in worse:
            warnings.append(f"within tolerance {tolerance:g} of a different case: {d}")
        if worse:
            v, d = max(worse, key=lambda vd: vd[0].value)
            robust = {"value": v.value, "tolerance": tolerance, "expression": v.expression,
                      "nearby_case": d}
    theory = _theory(system, st, classification, value, channel)
    return CriticalValue(classification=classification, value=value, reason=reason, lower=low,
                         block_lower=blow, block_reason=bwhy, robust=robust, structure=st,
                         theory=theory, warnings=tuple(warnings))


def critical_section(system: System, tolerance: float = 1e-9,
                     channel: Any = None) -> dict[str, Any]:
    """``critical_value(system, tolerance, channel).to_dict()``."""
    return critical_value(system, tolerance, channel).to_dict()
