"""Rigorous ball arithmetic for the tests' own re-checks (python-flint ``arb``), written apart
from :mod:`kfcrit.theory.upper.certify` so that a certificate is re-checked by different code.

:func:`ball` evaluates a sympy expression built from rationals, π, sums, products, integer and
half-integer powers, sin and cos; :func:`certainly_positive_definite` applies Sylvester's
criterion to a symmetric matrix of such expressions: every leading principal minor's ball lies
strictly above zero. Both are exact decisions (balls contain the true value); an expression of
another form raises :class:`Unsupported` and the caller falls back to sympy's exact algebra.
"""
from __future__ import annotations

import flint
import sympy as sp

PRECISION_BITS = 256


class Unsupported(ValueError):
    """The expression has a form :func:`ball` does not evaluate."""


def ball(expr: sp.Expr) -> flint.arb:
    """A ball (python-flint ``arb``) that contains the real number ``expr``."""
    expr = sp.sympify(expr)
    if expr.is_Rational:
        return flint.arb(int(expr.p)) / int(expr.q)
    if expr is sp.pi:
        return flint.arb.pi()
    if expr.is_Add:
        out = flint.arb(0)
        for term in expr.args:
            out += ball(term)
        return out
    if expr.is_Mul:
        out = flint.arb(1)
        for factor in expr.args:
            out *= ball(factor)
        return out
    if expr.is_Pow and expr.exp.is_Integer:
        return ball(expr.base) ** int(expr.exp)
    if expr.is_Pow and expr.exp.is_Rational and expr.exp.q == 2:
        return ball(expr.base).sqrt() ** int(expr.exp.p)
    if isinstance(expr, sp.cos):
        return ball(expr.args[0]).cos()
    if isinstance(expr, sp.sin):
        return ball(expr.args[0]).sin()
    raise Unsupported(f"no ball evaluation for {type(expr).__name__}")


def certainly_positive_definite(M: sp.Matrix) -> bool:
    """True when every leading principal minor of the symmetric ``M`` is certainly > 0.

    False means "not proven" (a minor's ball touches or lies below zero).
    """
    old = flint.ctx.prec
    flint.ctx.prec = PRECISION_BITS
    try:
        n = M.shape[0]
        entries = [[ball(M[i, j]) for j in range(n)] for i in range(n)]
        return all(flint.arb_mat([row[:k] for row in entries[:k]]).det() > 0
                   for k in range(1, n + 1))
    finally:
        flint.ctx.prec = old
