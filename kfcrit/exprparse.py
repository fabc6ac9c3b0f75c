"""Safe, exact parsing of numbers and expression strings from system files.

Nothing from a system file ever reaches ``eval``, ``sympify`` or ``parse_expr``. A string is
parsed by Python's :mod:`ast` (which only parses, never executes) and the tree is walked with an
allow-list into sympy objects built directly:

* numbers: integer and decimal literals (read from their source text, so ``1.25`` is 5/4 and
  ``1e-3`` is 1/1000, never through a binary float);
* operators: ``+ - * / ** ^`` (``^`` means power) and parentheses;
* names: ``pi``, ``E`` (also ``e``);
* functions of one argument: ``sqrt, cos, sin, tan, exp, log``.

Limits (each violation is an :class:`~kfcrit.errors.ExpressionError`): ``MAX_LENGTH`` characters,
``MAX_DEPTH`` nesting levels, ``MAX_DIGITS`` digits in one literal, exponents that are rational
with ``|numerator| <= MAX_EXPONENT`` and small denominators, and results whose magnitude stays
within ``MAX_MAGNITUDE`` (so the float view of every entry is finite).
"""
from __future__ import annotations

import ast
import math
import re
from fractions import Fraction

import sympy as sp

from .errors import ExpressionError

MAX_LENGTH = 500
MAX_DEPTH = 30
MAX_DIGITS = 60
MAX_EXPONENT = 64
MAX_EXPONENT_DENOMINATOR = 64
MAX_MAGNITUDE = sp.Integer(10) ** 300
MAX_NODES = 200
_BOUND = 10**300

_FUNCTIONS = {
    "sqrt": sp.sqrt,
    "cos": sp.cos,
    "sin": sp.sin,
    "tan": sp.tan,
    "exp": sp.exp,
    "log": sp.log,
}
_NAMES = {"pi": sp.pi, "E": sp.E, "e": sp.E}
_DESCRIPTIONS = {"Attribute": "attribute access", "Subscript": "indexing", "Lambda": "lambda",
                 "ListComp": "a comprehension", "GeneratorExp": "a comprehension",
                 "Compare": "a comparison", "IfExp": "a conditional"}
_NUMBER_TEXT = re.compile(r"^[+-]?(\d[\d_]*)?(\.\d*)?([eE][+-]?\d+)?$")


def number_from_text(text: str, field: str | None = None) -> sp.Rational:
    """Exact rational of a decimal literal's text (``"1.25"`` → 5/4, ``"1e-3"`` → 1/1000).

    Parameters
    ----------
    text : str
        The literal exactly as written (YAML scalar or Python literal source).
    field : str, optional
        Name of the field, for the error message.
    """
    t = text.strip().replace("_", "")
    if t.lower().lstrip("+-") in (".inf", ".nan", "inf", "nan", "infinity"):
        raise ExpressionError(f"{text.strip()[:20]!r} is not a finite number", field=field)
    if not t or not _NUMBER_TEXT.match(t) or not any(ch.isdigit() for ch in t):
        raise ExpressionError(f"not a number: {text[:40]!r}", field=field)
    mantissa = re.split(r"[eE]", t)[0]
    if sum(ch.isdigit() for ch in mantissa) > MAX_DIGITS:
        raise ExpressionError(f"number has more than {MAX_DIGITS} digits", field=field)
    exp_part = re.split(r"[eE]", t)[1] if re.search(r"[eE]", t) else "0"
    if abs(int(exp_part)) > 400:
        raise ExpressionError(f"number {text[:40]!r} is out of range", field=field)
    if re.fullmatch(r"[+-]?\d+", t):
        r = sp.Integer(int(t))
    else:
        value = Fraction(t)
        r = sp.Rational(value.numerator, value.denominator)
    _check_magnitude(r, field, text)
    return r


def _check_magnitude(value: sp.Expr, field: str | None, text: str) -> None:
    if value.is_Rational:
        p, q = abs(int(value.p)), int(value.q)
        if p > _BOUND * q or (p != 0 and p * _BOUND < q):
            raise ExpressionError(f"{text[:40]!r} is out of range (|x| must be in [1e-300, 1e300])",
                                  field=field)


def parse_expression(text: str, field: str | None = None) -> sp.Expr:
    """Parse an expression string into an exact, finite, real sympy number.

    Parameters
    ----------
    text : str
        For example ``"sqrt(3)"``, ``"2*cos(pi/5)"``, ``"1/3"``, ``"2^-4"``.
    field : str, optional
        Name of the field (``"A[0][1]"``) used in error messages.

    Returns
    -------
    sympy.Expr
        An exact real number (Rational or algebraic/transcendental constant expression).
    """
    if not isinstance(text, str):
        raise ExpressionError(f"expected a number or expression string, got {type(text).__name__}",
                              field=field)
    if len(text) > MAX_LENGTH:
        raise ExpressionError(f"expression longer than {MAX_LENGTH} characters", field=field)
    if not text.strip():
        raise ExpressionError("empty expression", field=field)
    if any(ord(ch) < 32 or ord(ch) > 126 for ch in text):
        raise ExpressionError("expression contains characters outside printable ASCII",
                              field=field)
    depth = 0
    for ch in text:
        depth += (ch == "(") - (ch == ")")
        if depth > MAX_DEPTH:
            raise ExpressionError(f"parentheses nested deeper than {MAX_DEPTH}", field=field)
    source = text.strip().replace("^", "**")
    try:
        tree = ast.parse(source, mode="eval")
    except (SyntaxError, ValueError, MemoryError, RecursionError):
        raise ExpressionError(f"cannot parse expression {text[:40]!r}", field=field) from None
    count = sum(1 for _ in ast.walk(tree))
    if count > MAX_NODES:
        raise ExpressionError(f"expression has more than {MAX_NODES} terms", field=field)
    walker = _Walker(source, field, text)
    value = walker.visit(tree.body, 0)
    return _finish(value, field, text)


def _finish(value: sp.Expr, field: str | None, text: str) -> sp.Expr:
    """Check that ``value`` is a finite real number and return it."""
    if value.has(sp.zoo, sp.oo, -sp.oo, sp.nan) or not value.is_number:
        raise ExpressionError(f"{text[:40]!r} is not a finite number", field=field)
    try:
        approx = complex(sp.N(value, 30))
    except (TypeError, ValueError, OverflowError):
        raise ExpressionError(f"{text[:40]!r} is not a finite number", field=field) from None
    if not (math.isfinite(approx.real) and math.isfinite(approx.imag)):
        raise ExpressionError(f"{text[:40]!r} is not a finite number", field=field)
    if value.is_real is False or (abs(approx.imag) > 1e-25 * max(1.0, abs(approx.real))):
        raise ExpressionError(f"{text[:40]!r} is not a real number", field=field)
    if abs(approx.real) > 1e300 or (approx.real != 0 and abs(approx.real) < 1e-300):
        raise ExpressionError(f"{text[:40]!r} is out of range (|x| must be in [1e-300, 1e300])",
                              field=field)
    return value


class _Walker:
    """Allow-list walk of an ``ast`` expression tree into sympy objects."""

    def __init__(self, source: str, field: str | None, text: str) -> None:
        self.source = source
        self.field = field
        self.text = text

    def fail(self, why: str) -> ExpressionError:
        return ExpressionError(f"{why} in {self.text[:40]!r}", field=self.field)

    def visit(self, node: ast.AST, depth: int) -> sp.Expr:
        if depth > MAX_DEPTH:
            raise self.fail(f"nesting deeper than {MAX_DEPTH}")
        if isinstance(node, ast.Constant):
            return self.constant(node)
        if isinstance(node, ast.Name):
            if node.id in _NAMES:
                return _NAMES[node.id]
            raise self.fail(f"unknown name {node.id[:20]!r}")
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.UAdd, ast.USub)):
            operand = self.visit(node.operand, depth + 1)
            return -operand if isinstance(node.op, ast.USub) else operand
        if isinstance(node, ast.BinOp):
            return self.binop(node, depth)
        if isinstance(node, ast.Call):
            return self.call(node, depth)
        kind = type(node).__name__
        raise self.fail(f"{_DESCRIPTIONS.get(kind, kind)} is not allowed")

    def constant(self, node: ast.Constant) -> sp.Expr:
        if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
            raise self.fail("only real numeric literals are allowed")
        segment = ast.get_source_segment(self.source, node)
        if segment is None:
            raise self.fail("unreadable literal")
        return number_from_text(segment, self.field)

    def binop(self, node: ast.BinOp, depth: int) -> sp.Expr:
        left = self.visit(node.left, depth + 1)
        right = self.visit(node.right, depth + 1)
        op = node.op
        if isinstance(op, ast.Add):
            out = left + right
        elif isinstance(op, ast.Sub):
            out = left - right
        elif isinstance(op, ast.Mult):
            out = left * right
        elif isinstance(op, ast.Div):
            if right == 0:
                raise self.fail("division by zero")
            out = left / right
        elif isinstance(op, ast.Pow):
            out = self.power(left, right)
        else:
            raise self.fail(f"operator {type(op).__name__} is not allowed")
        self.check_size(out)
        return out

    def power(self, base: sp.Expr, exponent: sp.Expr) -> sp.Expr:
        if not exponent.is_Rational:
            raise self.fail("exponents must be rational numbers")
        if abs(exponent.p) > MAX_EXPONENT or exponent.q > MAX_EXPONENT_DENOMINATOR:
            raise self.fail(f"exponent {exponent} exceeds the limit {MAX_EXPONENT}")
        if base == 0 and exponent <= 0:
            raise self.fail("zero to a non-positive power")
        return base**exponent

    def call(self, node: ast.Call, depth: int) -> sp.Expr:
        if not isinstance(node.func, ast.Name):
            raise self.fail("only calls of sqrt, cos, sin, tan, exp, log are allowed")
        if node.func.id not in _FUNCTIONS:
            raise self.fail(f"function {node.func.id[:20]!r} is not allowed")
        if len(node.args) != 1 or node.keywords:
            raise self.fail(f"{node.func.id} takes exactly one argument")
        arg = self.visit(node.args[0], depth + 1)
        if node.func.id == "log" and arg.is_number and bool(arg <= 0):
            raise self.fail("log of a non-positive number")
        if node.func.id == "sqrt" and arg.is_number and bool(arg < 0):
            raise self.fail("square root of a negative number")
        if node.func.id == "exp" and arg.is_number and bool(abs(arg) > 690):
            raise self.fail("exp argument out of range")
        out = _FUNCTIONS[node.func.id](arg)
        self.check_size(out)
        return out

    def check_size(self, value: sp.Expr) -> None:
        if value.is_Rational:
            if value.p.bit_length() > 2000 or value.q.bit_length() > 2000:
                raise self.fail("intermediate value out of range")
        elif value.count_ops() > 400:
            raise self.fail("expression too complex")
