"""Certified-enclosure stage of the exact path: rigorous python-flint ball arithmetic.

Runs when the number-field algebra cannot (e.g. an eigenvalue of degree ≥ 3 over an irrational
entry field, such as 6×6 ``a + b*sqrt(2)`` matrices with a degree-12 eigenvalue). The entries
are enclosed in arb balls and ``acb_mat.eig`` certifies simple isolated eigenvalues with
eigenvector balls. Decisions are rigorous: exactly conjugate pairs have equal moduli, all other
moduli must be separated, ranks and C·v ≠ 0 by balls excluding 0; a root of unity z = λ̄/λ is
excluded up to the order bound of the degree of λ, or *proved* exactly in cyclotomic arithmetic
(:mod:`kfcrit.theory.structure.cyclotomic`) when the entries are rationals and cosines/sines of rational
multiples of π. Whatever the balls do not decide raises :class:`Fallback`.
"""
from __future__ import annotations

import dataclasses
import math
import time
from fractions import Fraction
from typing import Any

import numpy as np
import sympy as sp

from kfcrit.model.system import System
from kfcrit.records.structure import StandardForm, StandardFormBlock
from kfcrit.theory.structure.budget import field_degree_bound
from kfcrit.theory.structure.cyclotomic import MAX_FIELD_DEGREE as CYCLO_MAX_DEGREE
from kfcrit.theory.structure.cyclotomic import (
    CycloField,
    cyclotomic_order,
    poly_at,
    shifted_gcd,
    trig_form,
)
from kfcrit.theory.structure.cyclotomic import charpoly as cyclo_charpoly
from kfcrit.theory.structure.cyclotomic import element as cyclo_element
from kfcrit.theory.structure.cyclotomic import monic as cyclo_monic
from kfcrit.theory.structure.cyclotomic import real_expression as cyclo_real
from kfcrit.theory.structure.exact import controllability
from kfcrit.theory.structure.records import (
    EXACT_MAX_STATES,
    EXACT_TIME_BUDGET,
    Eigen,
    EquiBlock,
    Fallback,
    Pair,
    Structure,
    float_basis,
    observability_index,
    simplest_rational,
    turn_of,
)

_X = sp.Symbol("x")


# --------------------------------------------------------------------------- certified enclosures

CERTIFIED_PRECISIONS = (128, 256, 512)
"""Working precisions (bits) of the certified-enclosure stage, tried in turn."""


class _Undecided(Exception):
    """The enclosures at this precision do not decide a fact (retry higher, then hand over)."""


def arb_of(expr: sp.Expr) -> Any:
    """A rigorous arb ball containing the real number ``expr`` (sympy expression tree, at the
    current flint precision): rationals, +, ×, integer powers, positive-base rational powers,
    pi, E, cos/sin. Anything else: ``Fallback``."""
    from flint import arb, fmpq

    if expr.is_Rational:
        return arb(fmpq(int(expr.p), int(expr.q)))
    if expr is sp.pi:
        return arb.pi()
    if expr is sp.E:
        return arb(1).exp()
    if expr.is_Add:
        out = arb(0)
        for a in expr.args:
            out = out + arb_of(a)
        return out
    if expr.is_Mul:
        out = arb(1)
        for a in expr.args:
            out = out * arb_of(a)
        return out
    if expr.is_Pow:
        base, ex = expr.base, expr.exp
        if ex.is_Integer:
            b = arb_of(base)
            k = int(ex)
            r = arb(1)
            for _ in range(abs(k)):
                r = r * b
            return r if k >= 0 else 1 / r
        if ex.is_Rational:
            b = arb_of(base)
            if not b > 0:
                raise Fallback(f"cannot enclose {sp.sstr(expr)} (base not certainly positive)")
            if ex == sp.Rational(1, 2):
                return b.sqrt()
            return (b.log() * arb_of(ex)).exp()
    if isinstance(expr, (sp.cos, sp.sin)):
        arg = expr.args[0]
        c = arg / sp.pi
        if c.is_Rational:
            f = fmpq(int(c.p), int(c.q))
            return arb.cos_pi_fmpq(f) if isinstance(expr, sp.cos) else arb.sin_pi_fmpq(f)
        v = arb_of(arg)
        return v.cos() if isinstance(expr, sp.cos) else v.sin()
    raise Fallback(f"no certified enclosure for the entry {sp.sstr(expr)[:40]}")


def _arb_fraction(x: Any) -> tuple[Fraction, Fraction]:
    """Exact rational bounds [mid − rad, mid + rad] of an arb ball."""
    m, e = x.mid().man_exp()
    r, f = x.rad().man_exp()
    mid = Fraction(int(m)) * Fraction(2) ** int(e)
    rad = Fraction(int(r)) * Fraction(2) ** int(f)
    return mid - rad, mid + rad


def certified_structure(system: System, start: float, prior: str) -> Structure:
    """The eigen-structure decided by rigorous ball arithmetic (python-flint arb/acb).

    Used when the exact algebra falls back (e.g. an eigenvalue of degree ≥ 3 over a
    quadratic entry field). Every decision is a theorem about the exact input:

    * ``acb_mat.eig`` certifies that every eigenvalue is simple and lies in its own ball (so A
      is diagonalizable) and encloses an eigenvector for each.
    * A is real, so the conjugate of an eigenvalue is an eigenvalue; if the conjugate of ball i
      meets exactly one ball j, then λ_j = conj(λ_i) exactly (j = i: λ_i is real), and the pair
      has exactly equal moduli. Every other pair of moduli must be certified distinct (disjoint
      |λ| balls); and |λ| vs 1 must be certified (the ball of |λ| excludes 1).
    * C·v ≠ 0 when a component's ball excludes 0; a pair block has rank 2 when a 2×2 minor's
      ball excludes 0, rank 1 when C has one row.
    * For an equal-modulus pair, z = λ̄/λ has degree D ≤ d(d − 1) over Q, d ≤ n·[K:Q] the degree
      of λ; a root of unity of order q has φ(q) ≤ D, so q ≤ 2D² (φ(q) ≥ √(q/2)). If the ball of
      φ/2π holds no fraction with such a denominator, z is not a root of unity.

    Anything the balls do not decide (after ``CERTIFIED_PRECISIONS``) raises ``Fallback``.
    """
    import flint

    if system.n > EXACT_MAX_STATES:
        raise Fallback(f"n = {system.n} > {EXACT_MAX_STATES}")
    A, C = sp.Matrix(system.A), sp.Matrix(system.C)
    A_trig = A.applyfunc(trig_form)
    L = cyclotomic_order(list(A_trig))
    if L is not None:
        d_field: int | None = int(sp.totient(L))
    else:
        d_field = field_degree_bound(list(A))
        if d_field is None:
            raise Fallback("the entries of A are not all algebraic numbers (no degree bound for "
                           "the root-of-unity test)")
    d_lam = system.n * d_field
    q_max = 2 * (d_lam * (d_lam - 1)) ** 2 + 2
    old = flint.ctx.prec
    why = ""
    try:
        for prec in CERTIFIED_PRECISIONS:
            flint.ctx.prec = prec
            try:
                return _certified_at(system, A, C, prec, q_max, d_lam, start, prior,
                                     (A_trig, L) if L is not None else None)
            except _Undecided as exc:
                why = str(exc)
            except ValueError as exc:      # acb_mat.eig: eigenvalues not isolated
                why = f"eigenvalues not isolated ({exc})"
    finally:
        flint.ctx.prec = old
    raise Fallback(f"undecided at {CERTIFIED_PRECISIONS[-1]} bits: {why}")


def _certified_at(system: System, A: sp.Matrix, C: sp.Matrix, prec: int, q_max: int,
                  d_lam: int, start: float, prior: str,
                  cyclo: tuple[sp.Matrix, int] | None = None) -> Structure:
    from flint import acb, acb_mat, arb

    n, m = A.shape[0], C.shape[0]
    Ab = acb_mat([[acb(arb_of(A[i, j])) for j in range(n)] for i in range(n)])
    Cb = acb_mat([[acb(arb_of(C[i, j])) for j in range(n)] for i in range(m)])
    if not all(x.is_finite() for x in Ab.entries() + Cb.entries()):
        raise _Undecided("an entry's enclosure is not finite")
    E, R = Ab.eig(right=True)
    E = list(E)
    CV = Cb * R
    # conjugate partners (exact: each ball holds exactly one eigenvalue, the spectrum of a real
    # matrix is closed under conjugation)
    conj = []
    for i in range(n):
        hits = [j for j in range(n) if E[j].overlaps(E[i].conjugate())]
        if len(hits) != 1:
            raise _Undecided(f"conjugate of eigenvalue {i} not isolated")
        conj.append(hits[0])
    mods = [abs(z) for z in E]
    groups: list[list[int]] = []
    seen: set[int] = set()
    for i in range(n):
        if i in seen:
            continue
        grp = [i] if conj[i] == i else [i, conj[i]]
        seen.update(grp)
        groups.append(grp)
    for a in range(len(groups)):
        for b in range(a + 1, len(groups)):
            if mods[groups[a][0]].overlaps(mods[groups[b][0]]):
                raise _Undecided("two moduli not separated (possibly equal, not conjugate)")
    groups.sort(key=lambda g: -float(mods[g[0]].mid()))
    for a in range(len(groups) - 1):
        if not mods[groups[a][0]] > mods[groups[a + 1][0]]:
            raise _Undecided("modulus order not certified")   # pragma: no cover - disjoint
    for g in groups:
        g.sort(key=lambda i: turn_of(complex(E[i].mid())))
    order = [i for g in groups for i in g]
    pos = {i: k for k, i in enumerate(order)}

    def unit_cmp(i: int) -> int:
        if mods[i] > 1:
            return 1
        if mods[i] < 1:
            return -1
        raise _Undecided("|λ| = 1 not excluded")

    def nonzero(i: int) -> bool:
        return any(not CV[r, i].contains(0) for r in range(m))

    eigen = []
    for i in order:
        v = complex(E[i].mid())
        if conj[i] == i:
            v = complex(v.real, 0.0)
        if not nonzero(i):
            raise _Undecided("C·v not certified nonzero")
        mod2 = mods[i] * mods[i]
        eigen.append(Eigen(value=v, multiplicity=1, geometric=1, mod2=float(mod2.mid()),
                           basis=float_basis(system.a, v, 1), expr=None, mod2_expr=None,
                           unit_cmp=unit_cmp(i), text=_ball_text(E[i], conj[i] == i)))
    blocks, pairs = [], []
    cyclotomic_proofs: list[tuple[Fraction, bool]] = []
    for g in groups:
        members = [pos[i] for i in g]
        relevant = eigen[members[0]].unit_cmp >= 0
        if len(g) == 1:
            rank = 1
        elif any(not (CV[r, g[0]] * CV[s, g[1]] - CV[s, g[0]] * CV[r, g[1]]).contains(0)
                 for r in range(m) for s in range(r + 1, m)):
            rank = 2
        elif m == 1:
            rank = 1
        else:
            raise _Undecided("rank of an equal-modulus pair not certified")
        blocks.append(EquiBlock(members=tuple(members), indices=tuple(members),
                                mod2=eigen[members[0]].mod2, mod2_expr=None, rank=rank,
                                size=len(g), relevant=relevant))
        if relevant and len(g) == 2:
            a, b = g
            # arg ∈ (−π, π]: a ball meeting 0 or ±1/2 turn decides nothing (z ≈ ±1)
            lo, hi = _arb_fraction((E[b] / E[a]).arg() / (2 * arb.pi()))
            if not (0 < lo or hi < 0) or hi - lo > Fraction(1, 4):
                raise _Undecided("φ/2π not separated from 0")
            frac = simplest_rational(lo + 1, hi + 1) if hi < 0 else simplest_rational(lo, hi)
            q, mod2_expr = None, None
            if frac.denominator <= q_max:
                if cyclo is None:
                    raise _Undecided(f"φ/2π near {frac} (a root of unity not excluded)")
                proved, mod2_expr = _rational_angle(cyclo[0], E, a, b, frac, cyclo[1])
                if proved is None:
                    raise _Undecided(f"φ/2π near {frac}: the cyclotomic test did not decide")
                proved_q = frac.denominator if proved else None
                q, cyclotomic_proofs = proved_q, cyclotomic_proofs + [(frac, proved)]
            if mod2_expr is not None:
                for k in members:
                    eigen[k] = dataclasses.replace(eigen[k], mod2_expr=mod2_expr)
                blocks[-1] = dataclasses.replace(blocks[-1], mod2_expr=mod2_expr)
            pairs.append(Pair(a=members[0], b=members[1], rank=rank, size=2,
                              degenerate=rank < 2, q=q,
                              turn=(float(frac) if q is not None else
                                    turn_of(eigen[members[1]].value / eigen[members[0]].value)),
                              turn_text=str(frac) if q is not None else "irrational"))
    if time_left(start) < 0:
        raise Fallback(f"exceeded the {EXACT_TIME_BUDGET:g} s budget")
    controllable, how = _certified_controllable(system)
    form = StandardForm(
        eigenvalues=[e.text for e in eigen],
        basis=(f"V: certified eigenvector enclosures (python-flint acb_mat.eig, {prec} "
               "bits); C·V entries as balls"),
        equi_blocks=[StandardFormBlock(
            indices=[int(pos[i]) for i in g],
            eigenvalues=[eigen[pos[i]].text for i in g],
            C_columns=[[CV[r, i].str(radius=True) for r in range(m)] for i in g])
            for g in groups])
    return Structure(
        path="exact",
        path_reason=(f"certified enclosures (python-flint arb, {prec} bits): {prior}; all "
                     "eigenvalues simple and isolated "
                     "(acb_mat.eig), moduli separated by disjoint balls or exactly equal for "
                     "conjugate pairs, |λ| vs 1 and ranks by balls excluding 0, roots of unity "
                     f"excluded for every order q ≤ {q_max} (degree of λ over Q ≤ {d_lam})"
                     + "".join(f"; φ/2π = {fr} {'proved' if ok else 'refuted'} exactly in "
                               f"Q(ζ_{math.lcm(cyclo[1] if cyclo else 1, fr.denominator)}) "
                               "(common roots of χ(x) and w⁻ⁿχ(wx), w = e^{2πi·φ/2π})"
                               for fr, ok in cyclotomic_proofs) + "; "
                     "every decision is rigorous, eigenvalues are given as certified balls"
                     + how),
        tolerances={"exact": True, "certified_enclosures": True, "precision_bits": prec,
                    "time_budget_seconds": EXACT_TIME_BUDGET, "max_states": EXACT_MAX_STATES},
        eigen=tuple(eigen), blocks=tuple(blocks), pairs=tuple(pairs),
        diagonalizable=True, detectable=True, undetectable=(), controllable_Q=controllable,
        observability_index=observability_index(system.a, system.c), observable=True,
        norm_A=float(np.linalg.norm(system.a, 2)), norm_C=float(np.linalg.norm(system.c, 2)),
        seconds=time.monotonic() - start, standard_form=form)


def _rational_angle(A: sp.Matrix, E: list[Any], a: int, b: int, frac: Fraction,
                    L: int) -> tuple[bool | None, sp.Expr | None]:
    """Is λ_b = w·λ_a exactly, w = e^{2πi·frac}? Entries of A in Q(ζ_L) (``L`` from
    :func:`~kfcrit.theory.structure.cyclotomic.cyclotomic_order`); E: certified, disjoint eigenvalue balls.

    g = gcd(χ(x), w⁻ⁿχ(wx)) over Q(ζ_M), M = lcm(L, q), has as roots exactly the eigenvalues μ
    with w·μ an eigenvalue (all simple). The balls E_j with 0 ∈ g(E_j) contain every root; if
    there are exactly deg g of them, they are the roots. λ_a is then a root or not — and if it is,
    w·λ_a is the eigenvalue in the only ball it meets, E_b. Returns (True/False, or None when
    undecided) and |λ_a|² as an exact real expression when g pins it: deg g = 1 (λ_a = −g₀,
    |λ_a|² = λ_a·λ_b = w·λ_a²) or g = (x − λ_a)(x − λ_b) (|λ_a|² = g₀)."""
    q = frac.denominator
    F0 = CycloField.of(L)
    M = math.lcm(L, q)
    if int(sp.totient(M)) > CYCLO_MAX_DEGREE:
        return None, None
    F = CycloField.of(M)
    n = A.shape[0]
    try:
        rows = [[F0.embed(cyclo_element(F0, A[i, j]), F) for j in range(n)] for i in range(n)]
    except (ValueError, ZeroDivisionError):
        return None, None
    chi = cyclo_charpoly(F, rows)
    w_power = frac.numerator * (M // q)
    g = shifted_gcd(F, chi, w_power)
    deg = len(g) - 1
    if deg == 0:
        return False, None
    roots = [j for j in range(len(E)) if poly_at(F, g, E[j]).contains(0)]
    if len(roots) != deg:
        return None, None
    if a not in roots:
        return False, None
    image = E[a] * F.value(F.zeta(w_power))
    hits = [j for j in range(len(E)) if image.overlaps(E[j])]
    if hits != [b]:
        return None, None
    mod2 = None
    m2 = None
    if deg in (1, 2):
        g = cyclo_monic(F, g)
    if deg == 1:
        lam = F.reduce(-g[1])
        m2 = F.mul(F.zeta(w_power), F.mul(lam, lam))
    elif deg == 2 and sorted(roots) == sorted((a, b)):
        m2 = g[2]                               # g = (x − λ_a)(x − λ̄_a): constant |λ_a|²
    if m2 is not None:
        mod2 = cyclo_real(F, m2)
        if not F.value(m2).imag.contains(0):       # |λ|² is real: a failed check is a bug
            return None, None
    return True, mod2


def _ball_text(z: Any, real: bool) -> str:
    """A certified eigenvalue ball as text: ``[mid +/- rad]`` (real, certified) or
    ``[re +/- r] + [im +/- r]*I``."""
    if real:
        return f"real eigenvalue in {z.real.str(radius=True)}"
    return f"eigenvalue in {z.str(radius=True).replace('j', '*I')}"


def time_left(start: float) -> float:
    return EXACT_TIME_BUDGET - (time.monotonic() - start)


def _certified_controllable(system: System) -> tuple[bool, str]:
    """(A, Q^{1/2}) controllable: trivially when Q ≻ 0 (exact Cholesky test), else the exact
    Krylov rank over the entry field (float64 PBH test when that is refused: see
    :func:`~kfcrit.theory.structure.exact.controllability`)."""
    Q = sp.Matrix(system.Q)
    if all(v.is_Rational for v in Q) and Q.is_positive_definite:
        return True, ""
    return controllability(system)

