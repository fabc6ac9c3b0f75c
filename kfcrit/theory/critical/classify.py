"""Which theorem decides p_c: the structure class of (A, C), the lower bounds p_low and the
block lower bound, and the prose that states each decision (theory §3–§4, §11)."""
from __future__ import annotations

from typing import Any

import numpy as np
import sympy as sp

from kfcrit.model.system import System
from kfcrit.theory.critical.numtext import (
    approx_text,
    complex_text,
    is_short_expression,
    superscript,
    value_text,
)
from kfcrit.theory.critical.values import Num, eig_above, nondegenerate_value, on_circle, pair_value
from kfcrit.theory.structure.eigen import (
    NUMERIC_TOLERANCES,
    Structure,
    structure_of,
)

# --------------------------------------------------------------------------- bounds

def eig_text(st: Structure, i: int) -> str:
    """λ_i: its short exact expression, else its float (``≈`` when it rounds an exact value)."""
    e = st.eigen[i]
    text = sp.sstr(e.expr) if e.expr is not None else None
    if text is not None and is_short_expression(text):
        return text
    return ("≈ " if text is not None else "") + complex_text(e.value)


def mod_text(st: Structure, i: int) -> str:
    """|λ_i|: the exact expression when short, else the float marked "≈" (exact path: the
    float of the exact value) or as computed (numeric path), to 12 significant digits."""
    e = st.eigen[i]
    if e.mod2_expr is not None:
        return value_text(e.modulus, sp.sstr(sp.sqrt(e.mod2_expr)))
    if e.text is not None:   # exact path, an indexed root without a closed form
        return f"≈ {approx_text(e.modulus)}"
    return approx_text(e.modulus)


def is_mod(st: Structure, i: int) -> str:
    """``= |λ_i|`` (exact or computed) or ``≈ |λ_i|`` (an exact value rounded), for prose."""
    text = mod_text(st, i)
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


def lower_of(st: Structure) -> Num:
    """Sinopoli Thm 3: p_low = max(1 − 1/ρ(A)², 0) (eigen is sorted by modulus)."""
    top = st.eigen[0]
    return nondegenerate_value(top.mod2, top.mod2_expr, eig_above(top, st))


def lower_bound(system: System, structure: Structure | None = None) -> dict[str, Any]:
    """Sinopoli Thm 3 lower bound p_low = 1 − 1/ρ(A)², 0 when ρ(A) ≤ 1: {value, expression}.

    ``structure``: the eigen-structure of ``system`` if already computed
    (:func:`kfcrit.theory.structure.eigen.structure_of`), else it is computed here."""
    return lower_of(structure if structure is not None else structure_of(system)).to_dict()


def _pair_num(st: Structure, pair: Any, q: int | None) -> Num:
    e = st.eigen[pair.a]
    return pair_value(e.mod2, q, e.mod2_expr, eig_above(e, st))


def block_lower(st: Structure, low: Num) -> tuple[Num, str]:
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
                       f"{eig_text(st, p.a)}, {eig_text(st, p.b)} "
                       f"(φ/2π = {p.turn_text}, q = {p.q if p.q else '∞'})")
    return best, why


def c_full_rank(system: System, st: Structure) -> bool:
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
    return not on_circle(st.eigen[rel[0]], st)


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
    return max((e.multiplicity - e.geometric + 1 for e in st.eigen if on_circle(e, st)),
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
    return (f"marginal modes (docs/theory.md §11): ρ(A) {is_mod(st, 0)} (eigenvalues on the unit "
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



def classify_structure(system: System, st: Structure, low: Num) -> tuple[str, Num | None, str]:
    if not st.detectable:
        bad = ", ".join(eig_text(st, i) for i in st.undetectable)
        return ("not-detectable", None,
                f"(C, A) is not detectable: eigenvalue(s) {bad} with |λ| ≥ 1 have an eigenvector "
                "with C v = 0, so E[Pₜ] (indeed Pₜ itself) diverges for every arrival "
                "probability, even with no losses (PBH test)")
    if st.stable:
        return ("stable", Num(0.0, sp.Integer(0)),
                f"ρ(A) {is_mod(st, 0)} < 1: E[Pₜ] is bounded for every p, p_c = 0")
    if not any(eig_above(e, st) for e in st.eigen):
        return (_structural_class(st), Num(0.0, sp.Integer(0)), _marginal_reason(system, st))
    if not st.diagonalizable:
        if c_full_rank(system, st):
            return ("non-diagonalizable", low,
                    "A is not diagonalizable (outside Mo–Sinopoli), but C is invertible: "
                    "Sinopoli et al. Section IV, upper and lower bounds coincide, p_c = 1 − 1/ρ(A)²")
        if _single_unstable(st):
            return ("non-diagonalizable", low,
                    f"A is not diagonalizable (outside Mo–Sinopoli), but it has a single unstable "
                    f"eigenvalue {eig_text(st, 0)}: Sinopoli et al. Section IV, bounds coincide, "
                    "p_c = 1 − 1/|λ₁|²")
        return ("non-diagonalizable", None,
                "A is not diagonalizable: Mo–Sinopoli (H2) fails and the papers give no closed "
                "form; p_c lies in [block lower bound, LMI upper bound]")
    rel_blocks = [b for b in st.blocks if b.relevant]
    degenerate = [b for b in rel_blocks if not b.one_step_observable]
    if not degenerate:
        facts = "; ".join(
            f"|λ| {is_mod(st, b.members[0])}: rank C_I = {b.rank} = size {b.size}"
            for b in rel_blocks)
        return ("non-degenerate", low,
                f"Mo–Sinopoli Thm 4: every equi-block with |λ| ≥ 1 is one-step observable "
                f"({facts}); p_c = max(1 − |λ₁|⁻², 0) with |λ₁| {is_mod(st, 0)}"
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
                f"Mo–Sinopoli Thm 5{extra}: equal moduli |λ| {is_mod(st, a)} of "
                f"the eigenvalues {eig_text(st, a)} and {eig_text(st, b)}, rank C_I = {pair.rank} < 2, "
                f"{qtext}" + _decided_text(system, st, "equal moduli, rank and φ/2π"))
    return ("degenerate", None,
            f"degenerate equi-block of size {blk.size} with rank C_I = {blk.rank} at |λ| "
            f"{is_mod(st, blk.members[0])}"
            + ("" if len(rel_blocks) == 1 else f" among {len(rel_blocks)} equi-blocks with |λ| ≥ 1")
            + ": beyond second order the papers give no closed form; p_c lies in "
              "[block lower bound, LMI upper bound]")
