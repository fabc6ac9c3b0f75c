"""Exact comparison of probabilities: an arrival probability against p_c, p_up or a robust value.

A verdict ``p > p_c`` must not be decided in float64 when both are exact: p = 9/25 + 10⁻⁴⁰ is
above p_c = 9/25, though both round to the same double. :func:`compare_probability` returns the
sign of p − v: exactly for rationals, by rigorous ball arithmetic (python-flint arb) at rising
precision otherwise, and by an exact zero test (minimal polynomial) when the balls keep
containing 0. A float operand is the binary rational it represents (compared as given).
"""
from __future__ import annotations

from fractions import Fraction
from typing import Any

import sympy as sp

from kfcrit.model.exprparse import parse_expression
from kfcrit.theory.structure.certified import arb_of
from kfcrit.theory.structure.exact import is_zero
from kfcrit.theory.structure.records import Fallback

_PRECISIONS = (64, 256, 1024, 4096)
"""Ball precisions (bits) tried in turn before the exact zero test."""


def exact_number(x: Any) -> sp.Expr:
    """``x`` as an exact sympy number: sympy numbers as they are, int/Fraction as rationals, a
    float as the binary rational it holds, a string through the safe expression parser, and an
    object with ``expr``/``value`` (a :class:`~kfcrit.theory.critical.section.Num`) by its exact
    expression when it has one."""
    if hasattr(x, "expr") and hasattr(x, "value"):
        return exact_number(x.expr if x.expr is not None else x.value)
    if isinstance(x, bool):
        raise TypeError("a probability is not a bool")
    if isinstance(x, sp.Float):
        return sp.Rational(Fraction(float(x)))
    if isinstance(x, sp.Basic):
        return x
    if isinstance(x, int):
        return sp.Integer(x)
    if isinstance(x, Fraction):
        return sp.Rational(x.numerator, x.denominator)
    if isinstance(x, float):
        f = Fraction(x)
        return sp.Rational(f.numerator, f.denominator)
    if isinstance(x, str):
        return parse_expression(x, "probability")
    raise TypeError(f"cannot read {type(x).__name__} as an exact number")


def compare_probability(p: Any, value: Any) -> int:
    """Sign of p − value, decided exactly: −1 (p below), 0 (equal), +1 (p above).

    Parameters
    ----------
    p, value : sympy number, int, Fraction, float, str or Num
        Read by :func:`exact_number` (a float is the binary rational it represents).

    Notes
    -----
    With d = p − value: rationals compare exactly; otherwise an arb ball D ∋ d is computed at
    64, 256, 1024 and 4096 bits, and the sign is that of D once 0 ∉ D. If 0 stays in every ball,
    d is decided by its minimal polynomial (d = 0 iff minpoly(d) = x), and a nonzero d by a
    5000-bit ball.

    .. math:: \\operatorname{sign}(p - v) \\in \\{-1, 0, 1\\}
    """
    a, b = exact_number(p), exact_number(value)
    d = sp.expand(a - b)
    if d.is_Rational:
        return 1 if d > 0 else -1 if d < 0 else 0
    sign = _ball_sign(d, _PRECISIONS)
    if sign is not None:
        return sign
    if is_zero(d):
        return 0
    sign = _ball_sign(d, (16384,))
    if sign is None:
        raise ArithmeticError(f"cannot decide the sign of {sp.sstr(d)[:60]}")
    return sign


def _ball_sign(d: sp.Expr, precisions: tuple[int, ...]) -> int | None:
    """Sign of d from arb balls at the given precisions; None while 0 is in the ball."""
    import flint

    old = flint.ctx.prec
    try:
        for prec in precisions:
            flint.ctx.prec = prec
            try:
                ball = arb_of(d)
            except Fallback:
                return _mpmath_sign(d, prec)
            if ball > 0:
                return 1
            if ball < 0:
                return -1
    finally:
        flint.ctx.prec = old
    return None


def _mpmath_sign(d: sp.Expr, prec: int) -> int | None:
    """Sign from sympy's adaptive evaluation when arb has no enclosure for an atom: accepted
    only when the value is far above the requested accuracy."""
    digits = max(30, prec * 3 // 10)
    v = sp.N(d, digits)
    re = sp.re(v)
    if re != 0 and abs(re) > sp.Float(10, digits) ** (-(digits // 2)):
        return 1 if re > 0 else -1
    return None
