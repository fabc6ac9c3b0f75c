"""Exact path of the eigen-structure: the characteristic polynomial factored over the entry field.

Entries of A and C rational or real algebraic (radicals such as ``sqrt(3)``, ``cos(2*pi/5)``).

* Factors of degree ≤ 2 over K give explicit radical eigenvalues. Zero tests use high-precision
  numerics only to *exclude* zero and ``sympy.minimal_polynomial`` to *prove* it (an algebraic
  number is 0 iff its minimal polynomial is ``x``). Eigenvectors and ranks are computed in an
  algebraic number field (``DomainMatrix`` over ``QQ<...>``), never in floating point.
  z = λ_2/λ_1 is a root of unity iff its minimal polynomial is cyclotomic; q is its index.
* Irreducible factors of degree ≥ 3 (rational entries only) give eigenvalues ``CRootOf(P, i)``:
  each is the generator θ of Q[x]/(P), so its eigenvectors are exact polynomials in θ.
  |λ_a|² = |λ_b|² is decided exactly: both are real roots of the square-free part of
  Res_x(P(x), x^d P(y/x)) (all products of two roots), equal iff they fall in the same exact
  isolating interval. The rank of a block mixing several such eigenvalues is certified by a
  50-digit singular value above 1e-30 (full rank), else the path gives up. For a conjugate pair,
  z = λ̄/λ has degree ≤ d(d−1): if no r/q with φ(q) ≤ d(d−1) lies within 1e-40 of φ/2π, z is
  not a root of unity; otherwise z^q = 1 ⇔ λ^q is real, certified by exact real-root isolation
  of Res_x(P(x), y − x^q).
* Diagonalizable iff the square-free part of the characteristic polynomial annihilates A.

Whatever cannot be decided in the time budget raises :class:`Fallback`.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np
import sympy as sp
from sympy.polys.matrices import DomainMatrix

from kfcrit.model.system import System
from kfcrit.records.structure import StandardForm, StandardFormBlock
from kfcrit.theory.structure.budget import exact_refusal
from kfcrit.theory.structure.records import (
    EXACT_MAX_FIELD_DEGREE,
    EXACT_MAX_STATES,
    EXACT_TIME_BUDGET,
    Eigen,
    EquiBlock,
    Fallback,
    Pair,
    Structure,
    eigen_indices,
    float_basis,
    is_relevant,
    numeric_controllable,
    observability_index,
    simplest_rational,
    turn_of,
)

_X = sp.Symbol("x")
_Y = sp.Symbol("y")
_ZERO_PROBE_DIGITS = 40


# --------------------------------------------------------------------------- exact helpers

def is_zero(expr: sp.Expr) -> bool:
    """Exact zero test of an algebraic number: numerics exclude 0, the minimal polynomial proves it.

    A nonzero value is certified by a 40-digit evaluation whose magnitude clearly exceeds its
    error; otherwise ``minimal_polynomial(expr) == x`` decides (exact).
    """
    expr = sp.nsimplify(expr) if isinstance(expr, sp.Float) else expr
    if expr.is_Rational:
        return expr == 0
    v = sp.N(expr, _ZERO_PROBE_DIGITS)
    if abs(complex(v)) > 1e-25:
        return False
    return sp.minimal_polynomial(expr, _X) == _X


def cmp_exact(a: sp.Expr, b: sp.Expr | int) -> int:
    """Sign of a − b for real algebraic numbers (exact zero test, then a certified sign)."""
    d = sp.expand(a - b)
    if is_zero(d):
        return 0
    return 1 if float(sp.re(sp.N(d, _ZERO_PROBE_DIGITS))) > 0 else -1


def field_generators(entries: list[sp.Expr]) -> list[sp.Expr]:
    """Generators of the field of the entries: their radical atoms (``sqrt(5)``, nested
    ``sqrt(5/8 + sqrt(5)/8)``) when each entry is a rational expression in them, else the
    entry itself (if it is a real algebraic number)."""
    gens: dict[str, sp.Expr] = {}
    for e in entries:
        if e.is_Rational:
            continue
        if e.is_algebraic is not True or not e.is_real:
            raise Fallback(f"entry {sp.sstr(e)} is not a real algebraic number")
        pows = sorted((a for a in e.atoms(sp.Pow)
                       if a.exp.is_Rational and not a.exp.is_Integer), key=sp.default_sort_key)
        rest = e.subs({a: sp.Dummy() for a in pows})
        if pows and not (rest.atoms(sp.Function) or rest.has(sp.pi, sp.E, sp.I)):
            for a in pows:
                gens.setdefault(sp.srepr(a), a)
        elif not any(is_zero(e - g) or is_zero(e + g) for g in gens.values()):
            gens[sp.srepr(e)] = e
    return list(gens.values())


def _quadratic_roots(coeffs: list[sp.Expr]) -> tuple[list[sp.Expr], sp.Expr, bool]:
    """Roots of a x² + b x + c (real coefficients); returns roots, discriminant, complex?"""
    a, b, c = coeffs
    disc = sp.expand(b * b - 4 * a * c)
    neg = cmp_exact(disc, 0) < 0
    s = sp.I * sp.sqrt(-disc) if neg else sp.sqrt(disc)
    return [sp.expand((-b + s) / (2 * a)), sp.expand((-b - s) / (2 * a))], disc, neg


@dataclass
class _ExactEigen:
    expr: sp.Expr
    mult: int
    mod2: sp.Expr
    field_gens: tuple[sp.Expr, ...]   # extra generator (sqrt of discriminant or the root)
    factor: int
    poly: sp.Poly | None = None        # the irreducible factor over QQ (rational entries only)
    conj: int | None = None            # index (within the factor) of the complex conjugate
    index: int = 0                     # index of this root within its factor
    hp: Any = None                     # 60-digit mpmath value (degree ≥ 3 roots only)
    text: str | None = None            # exact label ``CRootOf(P, i)`` (degree ≥ 3 roots only)

    @property
    def algebraic(self) -> bool:
        """Root of an irreducible factor of degree ≥ 3 (a CRootOf, not a radical)."""
        return self.hp is not None


class ExactWork:
    """State of one exact computation (number fields cached per set of generators)."""

    def __init__(self, A: sp.Matrix, C: sp.Matrix, start: float) -> None:
        self.A, self.C, self.start = A, C, start
        self.n = A.shape[0]
        self.gens = field_generators(list(A) + list(C))
        self._fields: dict[tuple, Any] = {}
        self._null: dict[tuple, DomainMatrix] = {}
        self._conv: dict[tuple, Any] = {}
        self._prod: dict[str, sp.Poly] = {}
        self._tables: dict[str, dict[str, Any]] = {}

    def check_time(self, step: str) -> None:
        if time.monotonic() - self.start > EXACT_TIME_BUDGET:
            raise Fallback(f"exact path exceeded its {EXACT_TIME_BUDGET:g} s budget ({step})")

    def field(self, extra: tuple[sp.Expr, ...]) -> Any:
        key = tuple(sp.srepr(g) for g in extra)
        if key not in self._fields:
            gens = list(self.gens) + list(extra)
            K = sp.QQ.algebraic_field(*gens) if gens else sp.QQ
            self._fields[key] = K
            if K != sp.QQ and K.ext.minpoly.degree() > EXACT_MAX_FIELD_DEGREE:
                raise Fallback("number field degree above the exact-path limit")
            self._tables[str(K)] = self._generator_table(K, gens)
        return self._fields[key]

    def _generator_table(self, K: Any, gens: list[sp.Expr]) -> dict[str, Any]:
        """Each generator as an element of K (polynomial in the primitive element θ = Σ g_i),
        from ``primitive_element(..., ex=True)``: converting entries is then plain field
        arithmetic instead of sympy's general (slow) field-isomorphism search."""
        from sympy.polys.numberfields.subfield import primitive_element

        if K == sp.QQ:
            return {}
        minpoly, coeffs, reps = primitive_element(gens, _X, ex=True)
        if list(coeffs) != [1] * len(gens) or sp.Poly(minpoly, _X).monic().all_coeffs() != \
                sp.Poly(K.ext.minpoly.as_expr(), K.ext.minpoly.gen).monic().all_coeffs():
            return {}
        table = {}
        for g, rep in zip(gens, reps):
            elem = K.new([K.dom.convert(sp.Rational(c)) for c in rep])
            table[sp.srepr(g)] = elem
            coeff, rest = g.as_coeff_Mul()       # sympy may pull square factors out of roots
            if coeff != 1 and rest != 1:
                table.setdefault(sp.srepr(rest), K.quo(elem, K.convert(K.dom.convert(coeff))))
        return table

    def products_poly(self, P: sp.Poly) -> sp.Poly:
        key = sp.srepr(P.as_expr())
        if key not in self._prod:
            self._prod[key] = _products_poly(P)
        return self._prod[key]

    def same_mod2(self, a: _ExactEigen, b: _ExactEigen) -> bool:
        """|λ_a|² = |λ_b|² exactly: minimal polynomial for radicals; for CRootOf, both are real
        roots of sqf(g_a·g_b) (g: products polynomial) and equal iff in the same isolating
        interval."""
        if not (a.algebraic or b.algebraic):
            return is_zero(sp.expand(a.mod2 - b.mod2))
        if a.factor == b.factor and (a.index == b.conj or a.index == b.index):
            return True
        ga, gb = self.products_poly(a.poly), self.products_poly(b.poly)
        G = (ga * gb).sqf_part()
        return _isolated_index(G, self.mod2_hp(a)) == _isolated_index(G, self.mod2_hp(b))

    def mod2_hp(self, e: _ExactEigen) -> Any:
        """|λ|² to 50 digits (from the radical expression or the mpmath root)."""
        import mpmath

        if e.hp is not None:
            return _mod2_hp(e)
        with mpmath.workdps(50):
            return mpmath.mpf(str(sp.re(sp.N(e.mod2, 50))))

    def unit_cmp(self, e: _ExactEigen) -> int:
        """Sign of |λ|² − 1, exact."""
        if not e.algebraic:
            return cmp_exact(e.mod2, 1)
        g = self.products_poly(e.poly)
        hv = _mod2_hp(e)
        v = float(hv)
        if g.eval(1) != 0 or abs(v - 1) > 1e-30:
            return 1 if v > 1 else -1
        gs = g.sqf_part()
        return 0 if _isolated_index(gs, hv) == _isolated_index(gs, sp.Integer(1)) else (
            1 if v > 1 else -1)

    def block_rank(self, eigs: list[_ExactEigen], ids: list[int]) -> int:
        """Rank over ℂ of C·V_I: exact in a number field, or certified at 50 digits when the
        block mixes degree ≥ 3 eigenvalues (no compositum field is built)."""
        if len(ids) == 1 or not any(eigs[i].algebraic for i in ids):
            return self.images(eigs, ids)[1].rank()
        import mpmath
        cols: list[list[Any]] = []
        with mpmath.workdps(50):
            for i in ids:
                K, CV = self.images(eigs, [i])
                theta = self.theta_hp(K, eigs, i)
                rows = CV.to_list()
                for j in range(CV.shape[1]):
                    cols.append([_anp_value(K, r[j], theta) for r in rows])
            m, k = self.C.shape[0], len(cols)
            M = [[cols[j][i] for j in range(k)] for i in range(m)]
        return _cert_rank(M, m, k)

    def theta_hp(self, K: Any, eigs: list[_ExactEigen], i: int) -> Any:
        """50-digit value of the primitive element of K (the eigenvalue for a CRootOf field)."""
        e = eigs[i]
        if e.hp is not None:
            return e.hp
        if K == sp.QQ:
            return None
        return _mp(K.ext.as_expr())

    def to_field(self, K: Any, expr: sp.Expr) -> Any:
        """Element of K for an exact number (cached: conversions are the costly step)."""
        key = (str(K), sp.srepr(expr))
        if key not in self._conv:
            self._conv[key] = self._convert(K, self._tables.get(str(K), {}), expr)
        return self._conv[key]

    def _convert(self, K: Any, table: dict[str, Any], expr: sp.Expr) -> Any:
        """Field arithmetic on the expression tree over the generator table (fallback:
        sympy's ``from_sympy`` for anything else)."""
        if K == sp.QQ:
            return K.from_sympy(expr)
        key = sp.srepr(expr)
        if key in table:
            return table[key]
        if expr.is_Rational:
            return K.convert(K.dom.convert(expr))
        if expr.is_Add:
            out = K.zero
            for a in expr.args:
                out = out + self._convert(K, table, a)
            return out
        if expr.is_Mul:
            coeff, rest = expr.as_coeff_Mul()
            if coeff != 1 and sp.srepr(rest) in table:
                return K.convert(K.dom.convert(coeff)) * table[sp.srepr(rest)]
            out = K.one
            for a in expr.args:
                out = out * self._convert(K, table, a)
            return out
        if expr.is_Pow and expr.exp.is_Integer:
            b = self._convert(K, table, expr.base)
            n = int(expr.exp)
            r = K.one
            for _ in range(abs(n)):
                r = r * b
            return r if n >= 0 else K.quo(K.one, r)
        return K.from_sympy(expr)

    def matrix(self, K: Any, M: sp.Matrix) -> DomainMatrix:
        """``M`` as a DomainMatrix over K, entry by entry through the conversion cache."""
        rows = [[self.to_field(K, e) for e in M.row(i)] for i in range(M.shape[0])]
        return DomainMatrix(rows, M.shape, K)

    def images(self, eigs: list[_ExactEigen], ids: list[int]) -> tuple[Any, DomainMatrix]:
        """C·V for the eigenvalues ``ids`` (V: exact eigenspace bases) in one common field."""
        extra: list[sp.Expr] = []
        for i in ids:
            for g in eigs[i].field_gens:
                if g not in extra:
                    extra.append(g)
        K = self.field(tuple(extra))
        cols = []
        for i in ids:
            key = (i, tuple(sp.srepr(g) for g in extra))
            if key not in self._null:
                Ad = self.matrix(K, self.A)
                lam = (K.new([1, 0]) if eigs[i].algebraic   # θ: a root of the factor
                       else self.to_field(K, eigs[i].expr))
                M = Ad - DomainMatrix.eye(self.n, K).mul(lam)
                self._null[key] = M.nullspace().transpose()
            cols.append(self._null[key])
        V = cols[0].hstack(*cols[1:]) if len(cols) > 1 else cols[0]
        return K, self.matrix(K, self.C).matmul(V)


def _exact_eigenvalues(work: ExactWork) -> tuple[list[_ExactEigen], bool]:
    """Distinct eigenvalues as radicals, and diagonalizability (sqf part of χ annihilates A)."""
    A = work.A
    if work.gens:
        _norm_precheck(work)
    charpoly = A.charpoly(_X).as_expr()
    if work.gens:
        _, factors = sp.factor_list(sp.expand(charpoly), _X, extension=work.gens)
    else:
        _, factors = sp.factor_list(sp.Poly(charpoly, _X, domain=sp.QQ))
    work.check_time("factoring the characteristic polynomial")
    eigs: list[_ExactEigen] = []
    sqf = sp.Integer(1)
    for k, (f, mult) in enumerate(factors):
        P = sp.Poly(f, _X)
        coeffs = [sp.expand(c) for c in P.all_coeffs()]
        if P.degree() == 1:
            root = sp.expand(-coeffs[1] / coeffs[0])
            eigs.append(_ExactEigen(root, mult, sp.expand(root**2), (), k))
        elif P.degree() == 2:
            roots, disc, neg = _quadratic_roots(coeffs)
            s = sp.I * sp.sqrt(-disc) if neg else sp.sqrt(disc)
            for r in roots:
                mod2 = sp.expand(coeffs[2] / coeffs[0]) if neg else sp.expand(r**2)
                eigs.append(_ExactEigen(r, mult, mod2, (s,), k))
        elif not work.gens:
            eigs.extend(_rootof_eigenvalues(P, mult, k))
        else:
            raise Fallback(f"irreducible factor of degree {P.degree()} over the entry field "
                            "(eigenvalues are not explicit radicals and the entries are not "
                            "rational)")
        if P.degree() <= 2 and not work.gens:
            for e in eigs:
                if e.factor == k:
                    e.poly = P
        sqf = sqf * P.as_expr()
    # Diagonalizable iff the square-free part of the characteristic polynomial annihilates A.
    K = work.field(())
    Ad = DomainMatrix.from_Matrix(A).convert_to(K)
    S = sp.Poly(sp.expand(sqf), _X)
    acc = DomainMatrix.zeros((work.n, work.n), K)
    for c in S.all_coeffs():
        acc = acc.matmul(Ad) + DomainMatrix.eye(work.n, K).mul(K.from_sympy(c))
    diagonalizable = acc.is_zero_matrix
    work.check_time("diagonalizability")
    return eigs, diagonalizable


def _norm_precheck(work: ExactWork) -> None:
    """Cheap test before factoring over K (slow in sympy): the characteristic polynomial of the
    rational (n·D)×(n·D) matrix replacing each entry by its multiplication matrix on K (D = [K:Q])
    is the norm N(χ_A). An eigenvalue of degree e over K has degree ≤ e·D over Q, so an
    irreducible Q-factor of N(χ_A) of degree > 2D proves an eigenvalue of degree ≥ 3 over K."""
    K = work.field(())
    D = K.ext.minpoly.degree()
    theta = K.new([1, 0])
    powers = [K.one]
    for _ in range(D - 1):
        powers.append(powers[-1] * theta)
    n = work.n
    big = [[sp.Integer(0)] * (n * D) for _ in range(n * D)]
    for i in range(n):
        for j in range(n):
            a = work.to_field(K, work.A[i, j])
            for c, pw in enumerate(powers):
                col = (a * pw).to_list()
                col = [sp.Integer(0)] * (D - len(col)) + [K.dom.to_sympy(v) for v in col]
                for r in range(D):               # coefficient of θ^r
                    big[i * D + r][j * D + c] = col[D - 1 - r]
    chi = DomainMatrix.from_Matrix(sp.Matrix(big)).convert_to(sp.QQ).charpoly()
    _, factors = sp.Poly(chi, _X, domain=sp.QQ).factor_list()
    worst = max(f.degree() for f, _ in factors)
    if worst > 2 * D:
        raise Fallback(f"an eigenvalue has degree ≥ 3 over the entry field (the norm of the "
                        f"characteristic polynomial has an irreducible factor of degree {worst} "
                        f"> 2·[K:Q] = {2 * D})")
    work.check_time("norm pre-check")


def _rootof_eigenvalues(P: sp.Poly, mult: int, k: int) -> list[_ExactEigen]:
    """Roots of an irreducible rational factor P of degree ≥ 3, |λ|² = λ·λ̄.

    Each root is the generator θ of the same number field Q[x]/(P) (its eigenvectors are
    polynomials in θ, identical for all roots), evaluated at that root's 60-digit value from
    ``mpmath.polyroots``; the number of real roots is exact (Sturm). Roots are labelled
    ``CRootOf(P, i)`` in sympy's order (real ascending, then complex by real and imaginary part).
    """
    import mpmath

    n_real = int(P.count_roots())
    with mpmath.workdps(60):
        coeffs = [mpmath.mpf(sp.Rational(c).p) / sp.Rational(c).q for c in P.all_coeffs()]
        hps = list(mpmath.polyroots(coeffs, maxsteps=400, extraprec=300))
        by_imag = sorted(range(len(hps)), key=lambda t: abs(mpmath.im(hps[t])))
        real = set(by_imag[:n_real])
        hps = [mpmath.mpc(mpmath.re(h), 0) if t in real else h for t, h in enumerate(hps)]
        order = sorted(range(len(hps)), key=lambda t: (t not in real, float(mpmath.re(hps[t])),
                                                      float(mpmath.im(hps[t]))))
    gen = sp.CRootOf(P.as_expr(), 0)
    poly_text = sp.sstr(P.as_expr())
    out = []
    for idx, t in enumerate(order):
        out.append(_ExactEigen(None, mult, None, (gen,), k, P, idx, idx, hp=hps[t],
                               text=f"CRootOf({poly_text}, {idx})"))
    for e in out:
        if mpmath.im(e.hp) != 0:
            e.conj = min((t for t in range(len(out)) if t != e.index),
                         key=lambda t: abs(complex(out[t].hp) - complex(e.hp).conjugate()))
    return out


def _mod2_hp(e: _ExactEigen) -> Any:
    import mpmath

    with mpmath.workdps(50):
        return abs(e.hp) ** 2


def _products_poly(P: sp.Poly) -> sp.Poly:
    """g(y) = Res_x(P(x), x^d P(y/x)): its roots are all products λ_i λ_j of roots of P."""
    d = P.degree()
    rev = sp.expand(_X**d * P.as_expr().subs(_X, _Y / _X))
    return sp.Poly(sp.resultant(P.as_expr(), rev, _X), _Y)


def _isolated_index(G: sp.Poly, value: Any) -> int:
    """Index of the isolating interval (width < 1e-40) of a real root of G containing ``value``
    (a 50-digit mpmath real, or an exact rational)."""
    import mpmath

    if isinstance(value, sp.Rational):
        v = value
    else:
        with mpmath.workdps(50):
            v = sp.Rational(mpmath.nstr(mpmath.re(value), 50, min_fixed=-1, max_fixed=2))
    slack = sp.Rational(1, 10**45)
    hits = [i for i, ((lo, hi), _) in enumerate(G.intervals(eps=sp.Rational(1, 10**40)))
            if lo - slack <= v <= hi + slack]
    if len(hits) != 1:
        raise Fallback("could not isolate |λ|² among the roots of its resultant polynomial")
    return hits[0]


def _mp(expr: sp.Expr) -> Any:
    """50-digit mpmath complex value of an exact algebraic number."""
    import mpmath

    v = sp.N(expr, 50)
    return mpmath.mpc(mpmath.mpf(str(sp.re(v))), mpmath.mpf(str(sp.im(v))))


def _anp_value(K: Any, a: Any, theta: Any) -> Any:
    """Value of a field element (polynomial in the primitive element θ) at 50 digits."""
    import mpmath

    if K == sp.QQ:
        r = sp.Rational(a)
        return mpmath.mpc(mpmath.mpf(r.p) / r.q)
    coeffs = [mpmath.mpf(sp.Rational(c).p) / sp.Rational(c).q for c in K.to_list(a)] \
        if hasattr(K, "to_list") else [mpmath.mpf(sp.Rational(c).p) / sp.Rational(c).q
                                       for c in a.to_list()]
    return mpmath.polyval(coeffs, theta) if coeffs else mpmath.mpc(0)


def _cert_rank(M: list[list[Any]], m: int, k: int) -> int:
    """Rank of an m×k complex matrix given to 50 digits: full rank min(m, k) is certified by
    its least singular value exceeding 1e-30 (entries are exact algebraic numbers evaluated to
    50 digits); anything else falls back to the numeric path."""
    import mpmath

    if k == 0:
        return 0
    with mpmath.workdps(50):
        s = mpmath.svd_c(mpmath.matrix(M), compute_uv=False)
        r = min(m, k)
        if min(abs(s[i]) for i in range(r)) > mpmath.mpf("1e-30"):
            return r
    raise Fallback("rank of a block with degree ≥ 3 eigenvalues is not certified")


def _real_power_certified(P: sp.Poly, lam: Any, q: int) -> bool:
    """Is λ^q real?  β = λ^q is a root of p_β(y) = Res_x(P(x), y − x^q). β is real iff it is
    the root of sqf(p_β) inside an exact isolating interval of a real root, and no other root of
    sqf(p_β) lies within 1e-20 of β (roots of p_β computed to 50 digits)."""
    import mpmath

    pb = sp.Poly(sp.resultant(P.as_expr(), _Y - _X**q, _X), _Y).sqf_part()
    with mpmath.workdps(50):
        beta = lam**q
        scale = max(mpmath.mpf(1), abs(beta))
        if abs(mpmath.im(beta)) > mpmath.mpf("1e-25") * scale:
            return False
        coeffs = [mpmath.mpf(sp.Rational(c).p) / sp.Rational(c).q for c in pb.all_coeffs()]
        roots = mpmath.polyroots(coeffs, maxsteps=400, extraprec=300)
        near = [r for r in roots if abs(r - beta) < mpmath.mpf("1e-20") * scale]
        if len(near) != 1:
            raise Fallback("roots too close to certify a root of unity")
        v = sp.Rational(mpmath.nstr(mpmath.re(beta), 45, min_fixed=-1, max_fixed=2))
    slack = sp.Rational(1, 10**30)
    return any(lo - slack <= v <= hi + slack
               for (lo, hi), _ in pb.intervals(eps=sp.Rational(1, 10**35)))


def _rootof_pair_order(a: _ExactEigen, b: _ExactEigen) -> int | None:
    """Order of z = λ_b/λ_a for a conjugate pair of CRootOf eigenvalues, certified.

    z has degree D ≤ d(d − 1) over Q, so its order q, if finite, has φ(q) ≤ D and q ≤ 2D² + 2.
    If no r/q with such q lies within 1e-40 of φ/2π (50-digit value), z is not a root of
    unity. Otherwise z^q = 1 ⇔ λ^q = λ̄^q ⇔ λ^q is real, which is certified exactly.
    """
    import mpmath

    if not (a.factor == b.factor and a.conj == b.index):
        raise Fallback("equal moduli between non-conjugate eigenvalues of degree ≥ 3")
    d = a.poly.degree()
    bound = 2 * (d * (d - 1)) ** 2 + 2
    with mpmath.workdps(50):
        za, zb = a.hp, b.hp
        t = mpmath.arg(zb / za) / (2 * mpmath.pi)
        t = t + 1 if t < 0 else t
        eps = mpmath.mpf("1e-40")
        lo = Fraction(str(mpmath.nstr(t - eps, 48, min_fixed=-1, max_fixed=2)))
        hi = Fraction(str(mpmath.nstr(t + eps, 48, min_fixed=-1, max_fixed=2)))
    frac = simplest_rational(lo, hi)
    if frac.denominator > bound:
        return None
    q = frac.denominator
    if q > 64:
        raise Fallback(f"candidate root of unity of order {q} too large to certify")
    return q if _real_power_certified(a.poly, a.hp, q) else None


def _exact_root_of_unity_order(z: sp.Expr) -> int | None:
    """Order q of z as a root of unity (minimal polynomial = q-th cyclotomic), else None."""
    mp = sp.Poly(sp.minimal_polynomial(z, _X), _X)
    if not mp.is_cyclotomic:
        return None
    d = mp.degree()
    for q in range(1, 2 * d * d + 3):
        if sp.totient(q) == d and sp.Poly(sp.cyclotomic_poly(q, _X), _X) == mp:
            return q
    raise Fallback("cyclotomic index not found")  # pragma: no cover - unreachable


def exact_structure(system: System, start: float) -> Structure:
    if system.n > EXACT_MAX_STATES:
        raise Fallback(f"n = {system.n} > {EXACT_MAX_STATES}")
    A, C = sp.Matrix(system.A), sp.Matrix(system.C)
    work = ExactWork(A, C, start)
    xeigs, diagonalizable = _exact_eigenvalues(work)
    # Order by modulus (descending), then by argument, numerically; ties are decided exactly.
    vals = [complex(e.hp) if e.algebraic else complex(sp.N(e.expr, 30)) for e in xeigs]
    order = sorted(range(len(xeigs)), key=lambda i: (-abs(vals[i]), turn_of(vals[i])))
    xeigs = [xeigs[i] for i in order]
    vals = [vals[i] for i in order]
    eigen = []
    for e, v in zip(xeigs, vals):
        _, CV = work.images(xeigs, [xeigs.index(e)])
        g = CV.shape[1]
        eigen.append(Eigen(value=v, multiplicity=e.mult, geometric=g,
                           mod2=float(work.mod2_hp(e)),
                           basis=float_basis(system.a, v, g), expr=e.expr, text=e.text,
                           mod2_expr=None if e.algebraic else e.mod2,
                           unit_cmp=work.unit_cmp(e)))
    work.check_time("eigenvectors")
    # Equi-blocks: group equal |λ|² exactly (numerically distant moduli are certainly unequal).
    groups: list[list[int]] = []
    for i, e in enumerate(xeigs):
        for grp in groups:
            j = grp[0]
            if abs(eigen[i].mod2 - eigen[j].mod2) <= 1e-12 * max(1.0, eigen[j].mod2) \
                    and work.same_mod2(e, xeigs[j]):
                grp.append(i)
                break
        else:
            groups.append([i])
    work.check_time("equal moduli")
    blocks, pairs = [], []
    undetectable = []
    for i, e in enumerate(eigen):
        if is_relevant(e) and work.block_rank(xeigs, [i]) < e.geometric:
            undetectable.append(i)
    for grp in groups:
        relevant = is_relevant(eigen[grp[0]])
        size = sum(eigen[i].geometric for i in grp)
        blocks.append(EquiBlock(members=tuple(grp), indices=eigen_indices(eigen, grp),
                                mod2=eigen[grp[0]].mod2, mod2_expr=eigen[grp[0]].mod2_expr,
                                rank=work.block_rank(xeigs, grp), size=size, relevant=relevant))
        if not relevant:
            continue
        for ia in range(len(grp)):
            for ib in range(ia + 1, len(grp)):
                a, b = grp[ia], grp[ib]
                psize = eigen[a].geometric + eigen[b].geometric
                prank = work.block_rank(xeigs, [a, b])
                turn = turn_of(vals[b] / vals[a])
                if xeigs[a].algebraic or xeigs[b].algebraic:
                    q = _rootof_pair_order(xeigs[a], xeigs[b])
                else:
                    q = _exact_root_of_unity_order(sp.expand(xeigs[b].expr / xeigs[a].expr))
                if q is not None:
                    r = round(turn * q) % q
                    text = sp.sstr(sp.Rational(r, q))
                    turn = r / q
                else:
                    text = "irrational"
                pairs.append(Pair(a=a, b=b, rank=prank, size=psize, degenerate=prank < psize,
                                  q=q, turn=turn, turn_text=text))
                work.check_time("equal-modulus pairs")
    controllable, how = controllability(system, work)
    labels = [sp.sstr(e.expr) if e.expr is not None else e.text for e in eigen]
    form_blocks = []
    for grp in groups:
        _, CV = work.images(xeigs, grp)
        M = CV.to_Matrix()
        form_blocks.append(StandardFormBlock(
            indices=[int(i) for i in eigen_indices(eigen, grp)],
            eigenvalues=[labels[i] for i in grp],
            C_columns=[[sp.sstr(M[r, k]) for r in range(M.shape[0])]
                       for k in range(M.shape[1])]))
    form = StandardForm(eigenvalues=labels,
                        basis="V: exact bases of ker(A − λI) (exact linear algebra), C·V over ℂ",
                        equi_blocks=form_blocks)
    work.check_time("standard form")
    return Structure(
        path="exact",
        path_reason=("exact algebraic arithmetic: entries in " +
                     (f"QQ({', '.join(sp.sstr(g) for g in work.gens)})" if work.gens else "QQ") +
                     (", eigenvalues as radicals" if not any(e.algebraic for e in xeigs) else
                      ", eigenvalues as radicals and CRootOf (moduli by resultant root "
                      "isolation, ranks of mixed blocks certified at 50 digits)") +
                     ", zero tests by minimal polynomials" + how),
        tolerances={"exact": True, "time_budget_seconds": EXACT_TIME_BUDGET,
                    "max_states": EXACT_MAX_STATES},
        eigen=tuple(eigen), blocks=tuple(blocks), pairs=tuple(pairs),
        diagonalizable=bool(diagonalizable), detectable=not undetectable,
        undetectable=tuple(undetectable), controllable_Q=controllable,
        observability_index=observability_index(system.a, system.c),
        observable=all(work.block_rank(xeigs, [i]) == e.geometric for i, e in enumerate(eigen)),
        norm_A=float(np.linalg.norm(system.a, 2)), norm_C=float(np.linalg.norm(system.c, 2)),
        seconds=time.monotonic() - start, standard_form=form)


def controllability(system: System, work: ExactWork | None = None) -> tuple[bool, str]:
    """(A, Q^{1/2}) controllable: exactly (:func:`exact_controllable`), or by the float64 PBH
    test when the exact test is refused; the second item is "" or the note for the record."""
    try:
        return exact_controllable(system, work), ""
    except Fallback as exc:
        return (numeric_controllable(system.a, system.q),
                f"; controllability of (A, Q^(1/2)) by the float64 PBH test ({exc})")


def exact_controllable(system: System, work: ExactWork | None = None) -> bool:
    """(A, Q^{1/2}) controllable iff rank [Q, AQ, …, A^{n−1}Q] = n (range Q = range Q^{1/2}).

    Refused (``Fallback``) before any field is built when the entries of A, C and Q may generate
    a field above ``EXACT_MAX_FIELD_DEGREE`` (:func:`~kfcrit.theory.structure.budget.exact_refusal`).
    """
    refusal = exact_refusal(list(system.A) + list(system.C) + list(system.Q), "A, C and Q")
    if refusal is not None:
        raise Fallback(f"controllability: {refusal}")
    gens = work.gens if work is not None else field_generators(list(system.A) + list(system.C))
    qgens = field_generators(list(system.Q))
    K = sp.QQ.algebraic_field(*(gens + qgens)) if (gens or qgens) else sp.QQ
    A = DomainMatrix.from_Matrix(sp.Matrix(system.A)).convert_to(K)
    blk = DomainMatrix.from_Matrix(sp.Matrix(system.Q)).convert_to(K)
    cols = [blk]
    n = system.n
    for _ in range(n - 1):
        blk = A.matmul(blk)
        cols.append(blk)
    return cols[0].hstack(*cols[1:]).rank() == n if len(cols) > 1 else cols[0].rank() == 1


