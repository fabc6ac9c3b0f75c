"""A sensor network's margins decided with the exact data (docs/theory.md §9.5): the uniform
margin's necessary end enclosed in ball arithmetic, exact per-sensor margins, and the
bottleneck ranked by them.

Near the boundary (a product Π(1 − p_i)·ρ² within 10⁻⁴⁰ of 1, say) a float evaluation of the
necessary factors cannot tell which side p lies on: the boundary along the uniform path is
therefore bisected on float values of s whose factors are evaluated in balls around the exact
p_i and ρ², and the bisection stops when a ball straddles 1 — the bracket it returns always
contains the true crossing.
"""
from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from fractions import Fraction
from typing import Any, Protocol

import flint
import sympy as sp

from kfcrit.errors import KfcritError
from kfcrit.model.exprparse import compare
from kfcrit.theory.facts import StabilityFacts
from kfcrit.theory.upper.certify import arb_from_sympy

BALL_BITS = 320
"""Working precision of the ball evaluation of the necessary factors (bits)."""
FLOAT_MOD2_RADIUS = 1e-13
"""Relative radius given to a |λ|² known only in floats (no exact eigenvalue)."""


class NecessaryFactor(Protocol):
    """A necessary constraint Π_{i∉T}(1 − p_i)·ρ_T² < 1 (``blind`` = T)."""

    blind: frozenset[int]
    mod2: float
    mod2_expr: sp.Expr | None


class MarginRow(Protocol):
    """What the bottleneck reads of a sensor's row."""

    name: str
    margin: dict[str, Any]
    margin_exact: sp.Expr | None
    n_minus_1: StabilityFacts


def _ball(x: sp.Expr) -> flint.arb:
    return arb_from_sympy(sp.Matrix([[x]]))[0, 0]


def _float_ball(x: float) -> flint.arb:
    return flint.arb(flint.fmpq(*float(x).as_integer_ratio()))


def _order_key(x: float) -> int:
    """An integer increasing with the float ``x`` (consecutive floats: consecutive keys)."""
    (bits,) = struct.unpack("<q", struct.pack("<d", x))
    return bits if bits >= 0 else -(bits & 0x7FFFFFFFFFFFFFFF)


def _key_float(key: int) -> float:
    bits = key if key >= 0 else (-key) | (1 << 63)
    return struct.unpack("<d", struct.pack("<q", bits if bits < (1 << 63) else bits - (1 << 64)))[0]


def uniform_necessary_bracket(constraints: Sequence[NecessaryFactor],
                              p_exact: Sequence[sp.Expr], lo: float = -1.0, hi: float = 1.0
                              ) -> tuple[float, float] | None:
    r"""Floats [a, b] enclosing the least s in [lo, hi] at which every necessary constraint
    holds along the uniform path p(s) = clip(p + s·1, 0, 1) (docs/theory.md §9.2, §9.5).

    .. math:: f_T(s) = \rho_T^2 \prod_{i \notin T} \bigl(1 - \operatorname{clip}(p_i + s)\bigr)

    is non-increasing in s; the crossing s* = inf{s : max_T f_T(s) < 1} lies in [a, b]: every
    f_T(b) < 1 is proven in balls, and some f_T(a) ≥ 1 is proven unless a = lo. Returns (lo, lo)
    when they hold at lo, None when some constraint does not hold even at hi (the necessary
    surface is not crossed). Raises ArithmeticError when even the end of the path is undecided
    in balls (a |λ|² known only in floats at 1).
    """
    old = flint.ctx.prec
    flint.ctx.prec = BALL_BITS
    try:
        ps = [_ball(sp.sympify(v)) for v in p_exact]
        mods = []
        for c in constraints:
            if c.mod2_expr is not None:
                mods.append(_ball(c.mod2_expr))
            else:
                m = _float_ball(c.mod2)
                mods.append(m + flint.arb(0, FLOAT_MOD2_RADIUS * abs(c.mod2)))

        rational = _rationals(constraints, p_exact)

        def side(s: float) -> int:
            """1: every constraint holds at s; −1: one fails; 0: undecided (balls straddle 1
            and the data are not all rational)."""
            sb = _float_ball(s)
            undecided = False
            for k, (c, m) in enumerate(zip(constraints, mods)):
                f = m
                for i, p in enumerate(ps):
                    if i not in c.blind:
                        f = f * (1 - (p + sb).max(flint.arb(0)).min(flint.arb(1)))
                if f >= 1:
                    return -1
                if not f < 1:
                    if rational is None:
                        undecided = True
                    elif _exact_factor(rational, k, c.blind, s) >= 1:
                        return -1
            return 0 if undecided else 1

        if side(lo) == 1:
            return lo, lo
        at_hi = side(hi)
        if at_hi == -1:
            return None
        if at_hi == 0:
            raise ArithmeticError("the necessary constraints are undecided in balls at the end "
                                  "of the path")
        a, b = _order_key(lo), _order_key(hi)
        while b - a > 1:
            mid = (a + b) // 2
            s = side(_key_float(mid))
            if s == 1:
                b = mid
            elif s == -1:
                a = mid
            else:
                # the crossing is within this ball's resolution: [a, b] still encloses it
                break
        return _key_float(a), _key_float(b)
    finally:
        flint.ctx.prec = old


def _rationals(constraints: Sequence[NecessaryFactor], p_exact: Sequence[sp.Expr]
               ) -> tuple[list[Fraction], list[Fraction]] | None:
    """(ρ_T² per constraint, p_i) as fractions when every one is rational, else None."""
    values = [c.mod2_expr for c in constraints] + [sp.sympify(p) for p in p_exact]
    if not all(v is not None and v.is_Rational for v in values):
        return None
    fr = [Fraction(int(v.p), int(v.q)) for v in values]
    return fr[:len(constraints)], fr[len(constraints):]


def _exact_factor(rational: tuple[list[Fraction], list[Fraction]], k: int,
                  blind: frozenset[int], s: float) -> Fraction:
    """ρ_T² Π_{i∉T}(1 − clip(p_i + s, 0, 1)) in exact rationals (s a float, hence dyadic)."""
    mods, ps = rational
    sf = Fraction(s)
    out = mods[k]
    for i, p in enumerate(ps):
        if i not in blind:
            out *= 1 - min(max(p + sf, Fraction(0)), Fraction(1))
    return out


def exact_margin(p: sp.Expr | None, crit: sp.Expr | None) -> sp.Expr | None:
    """p_i − p_i* exactly (None unless both are exact)."""
    if p is None or crit is None:
        return None
    return p - crit


def dead_is_stable(facts: StabilityFacts) -> bool:
    """Whether the facts with a link dead prove mean stability (the rule of theory §16)."""
    return facts.necessary is not False and (
        facts.sufficient or (facts.exact_region and facts.necessary is True))


def network_bottleneck(rows: Sequence[MarginRow]) -> dict[str, Any]:
    """The sensor with the smallest margin p_i − critical_i, named only when the bounds rank it.

    Candidates are the sensors whose loss alone can break mean stability (their N − 1 facts do
    not prove stability). Each margin is an interval [lo, hi] (a point where the critical value
    is exact). Sensor a is the bottleneck when hi_a < lo_b for every other candidate b; where
    every candidate's margin is exact the margins are compared exactly (a tie names none).
    Otherwise the bounds cannot rank them: no name is given and ``candidates`` lists the
    sensors whose intervals overlap the least one (or tie with it).
    """
    rule = ("smallest p_i − critical_i among sensors whose loss alone can break mean stability; "
            "named only when its margin interval lies below every other candidate's (exact "
            "margins compare exactly; a tie names none)")
    cands = []
    for k, r in enumerate(rows):
        iv = r.margin.get("interval")
        if iv is None or dead_is_stable(r.n_minus_1):
            continue
        lo = iv[0] if iv[0] is not None else -math.inf
        hi = iv[1] if iv[1] is not None else math.inf
        cands.append((lo, hi, k, r))
    if not cands:
        return {"name": None, "margin": None, "rule": rule,
                "reason": "no single link's degradation reaches the boundary"}
    exact = _exact_order(cands)
    if exact is not None:
        cands, above = exact
    else:
        cands.sort(key=lambda c: (c[1], c[0], c[2]))
        above = [cands[0][1] < c[0] for c in cands[1:]]
    best = cands[0][3]
    rivals = [c for c, b in zip(cands[1:], above) if not b]
    if rivals:
        names = [best.name] + [c[3].name for c in rivals]
        why = (" are equal (compared exactly)" if exact is not None else
               " overlap: the bounds cannot rank these links")
        return {"name": None, "margin": None, "rule": rule, "candidates": names,
                "reason": "the margins of " + ", ".join(names) + why}
    return {"name": best.name, "margin": best.margin.get("value"),
            "margin_interval": best.margin.get("interval"), "rule": rule}


def _exact_order(cands: list[tuple[float, float, int, Any]]
                 ) -> tuple[list[tuple[float, float, int, Any]], list[bool]] | None:
    """Candidates with the least exact margin first, and whether each other one lies strictly
    above it (None unless every margin is exact and every comparison is decided)."""
    if any(c[3].margin_exact is None for c in cands):
        return None
    try:
        least = cands[0]
        for c in cands[1:]:
            if compare(c[3].margin_exact, least[3].margin_exact, "network", "margin") < 0:
                least = c
        rest = [c for c in cands if c is not least]
        above = [compare(c[3].margin_exact, least[3].margin_exact, "network", "margin") > 0
                 for c in rest]
    except KfcritError:
        return None
    return [least] + rest, above
