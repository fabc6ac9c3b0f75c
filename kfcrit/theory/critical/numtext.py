"""Numbers in the prose of theory records (reason texts, statements): one short style.

A computed float is written to at most :data:`PROSE_DIGITS` significant digits, unless that
rounding would show a short value it does not have (``1.9999999999999998`` stays as computed,
never "2"); a complex number reads ``0.888697045118 + 0.485317094819j``; an exact value is
written as its expression only when the expression is short and the input was exact (a
rational of a binary float's expansion, such as ``986919187616889/1125899906842624``, is not a
closed form a reader can use, so it is written as a decimal marked ``≈``).
"""
from __future__ import annotations

import re

import sympy as sp

from kfcrit.errors import ExpressionError
from kfcrit.model.exprparse import parse_with_float

PROSE_DIGITS = 12
"""Most significant digits of a number in prose (the record's values keep full precision)."""

SHORT_EXPRESSION_CHARS = 48
"""Longest exact expression written in prose (a longer one reads as a dump, not a form)."""

_LONG_INTEGER = re.compile(r"\d{13,}")
_LONG_DECIMAL = re.compile(r"\d\.\d{13,}|\d{13,}")


def approx_text(x: float, digits: int = PROSE_DIGITS) -> str:
    """``x`` to ``digits`` significant digits, unless rounding would show a short value that
    ``x`` does not have (then the shortest round-trip text of ``x``).

    .. math:: \\mathrm{text}(x) = \\mathrm{round}_{d}(x)\\ \\text{if}\\
              \\mathrm{round}_{d}(x) = x \\lor |\\mathrm{round}_{d}(x)| \\ge 8\\ \\text{chars}
    """
    text = f"{x:.{digits}g}"
    return repr(float(x)) if float(text) != x and len(text) < 8 else text


def complex_text(z: complex, digits: int = PROSE_DIGITS) -> str:
    """A computed complex number as ``a + bj`` (``a − bj``), each part by :func:`approx_text`;
    a real number as its real part."""
    re_, im = float(z.real), float(z.imag)
    if im == 0:
        return approx_text(re_, digits)
    sign = "−" if im < 0 else "+"
    return f"{approx_text(re_, digits)} {sign} {approx_text(abs(im), digits)}j"


def is_short_expression(text: str | None) -> bool:
    """True when ``text`` is an exact expression short enough to read in prose (no integer or
    decimal of 13 or more digits, at most :data:`SHORT_EXPRESSION_CHARS` characters)."""
    return (text is not None and len(text) <= SHORT_EXPRESSION_CHARS
            and not _LONG_DECIMAL.search(text) and "RootOf" not in text)


def value_text(value: float, expression: str | None, exact_input: bool = True) -> str:
    """A probability or modulus in prose: its short exact expression (exact input only), else
    its float: marked ``≈`` when it rounds an exact value, as computed when there is none.

    Parameters
    ----------
    value : float
        The float value (the exact value rounded, or the computed float).
    expression : str or None
        The exact expression, ``None`` when the value was computed in floating point.
    exact_input : bool
        Whether the system was read as exact numbers (not binary floats).
    """
    if expression is None:
        return approx_text(value)
    if exact_input and is_short_expression(expression):
        return expression
    return f"≈ {approx_text(value)}"


def p_c_text(value: float, expression: str | None, exact_input: bool = True) -> str:
    """``p_c = expression`` for a short exact form on exact input, else ``p_c ≈ decimal``
    (:func:`value_text`)."""
    text = value_text(value, expression, exact_input)
    if expression is not None and not text.startswith("≈"):
        return f"p_c = {text}"
    return f"p_c ≈ {text.removeprefix('≈ ')}"


_SUPERSCRIPT = str.maketrans("0123456789-−", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻⁻")


def superscript(k: int) -> str:
    """An integer as Unicode superscript digits (h² for the second iterate)."""
    return str(k).translate(_SUPERSCRIPT)


def modulus_from_p_low(expression: str) -> tuple[str, float] | None:
    """ρ(A) in closed form from an exact ``p_low = 1 − ρ(A)⁻²`` (Sinopoli Thm 3), or ``None``
    when ``p_low`` is 0 (no information on ρ(A) ≤ 1) or ρ(A) has no short form.

    .. math:: \\rho(A) = (1 - p_{low})^{-1/2}

    The expression text is read with :func:`kfcrit.model.exprparse.parse_with_float` (never
    with sympify), so it may come from a record file.
    """
    try:
        p_low, value = parse_with_float(expression)
    except (ExpressionError, ValueError, TypeError, ArithmeticError):
        return None
    if not 0 < value < 1:
        return None
    rho = sp.sqrt(1 / (1 - p_low))
    text = sp.sstr(rho)
    if not is_short_expression(text):
        return None
    return text, float(sp.N(rho, 20))
