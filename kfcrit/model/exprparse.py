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
within ``MAX_MAGNITUDE`` (so the float view of every entry is finite). The same range rule holds
for literals and for evaluated results: a non-zero value must lie in [1e-300, 1e300] in magnitude.

Decisions about non-rational numbers (is the argument of ``log`` positive? is a probability at
most 1? is a result zero?) never call ``bool`` on a sympy relational. :func:`sign_of` evaluates
the number with sympy's adaptive ``evalf`` (``strict``: the sign is certain once a digit is), up
to ``MAX_WORKING_DIGITS`` digits of working precision; a number that still shows no digit there
is zero only if a bounded exact test (expansion, with the ``exp`` form of trigonometric
functions, capped at ``MAX_EXPANSION_TERMS`` terms) proves it, and is refused otherwise.

Cost: alongside the exact value, the walk carries a rigorous real enclosure (a python-flint arb
ball at ``BALL_BITS`` bits) of every subexpression. A decision the ball settles (a divisor or
the argument of ``sqrt``/``log`` certainly non-zero or positive, a result certainly inside the
range) is taken from it; only what the ball leaves open goes to ``evalf`` and the exact zero
test. :func:`parse_with_float` also returns the float64 view, correctly rounded when both ends
of the ball round to the same double. The size guard counts tree nodes (capped walk), not
``count_ops``.
"""
from __future__ import annotations

import ast
import math
import re
from fractions import Fraction
from typing import Any

import flint
import sympy as sp
from sympy.core.evalf import PrecisionExhausted

from kfcrit.errors import ExpressionError

MAX_LENGTH = 500
MAX_DEPTH = 30
MAX_DIGITS = 60
MAX_EXPONENT = 64
MAX_EXPONENT_DENOMINATOR = 64
MAX_MAGNITUDE = sp.Integer(10) ** 300
MAX_NODES = 200
MAX_WORKING_DIGITS = 1200
"""Working precision (decimal digits) up to which :func:`sign_of` looks for a non-zero digit."""
MAX_EXPANSION_TERMS = 400
"""Size guard of the exact zero test: expansions that could exceed this many terms are skipped."""
MAX_TREE_NODES = 800
"""Largest sympy expression tree (nodes) an operation may produce while parsing."""
BALL_BITS = 128
"""Working precision of the ball enclosures that settle most decisions without ``evalf``."""
_BALL_EXP_LIMIT = 690
_BOUND = 10**300
_TINY = sp.Float(10, 40) ** -300
_HUGE = sp.Float(10, 40) ** 300

_FUNCTIONS = {
    "sqrt": sp.sqrt,
    "cos": sp.cos,
    "sin": sp.sin,
    "tan": sp.tan,
    "exp": sp.exp,
    "log": sp.log,
}
_NAMES = {"pi": sp.pi, "E": sp.E, "e": sp.E}
_DESCRIPTIONS = {
    "Attribute": "attribute access (x.y) is not allowed",
    "Subscript": "indexing (x[i]) is not allowed",
    "Slice": "slices are not allowed",
    "Lambda": "lambda functions are not allowed",
    "ListComp": "comprehensions are not allowed",
    "SetComp": "comprehensions are not allowed",
    "DictComp": "comprehensions are not allowed",
    "GeneratorExp": "comprehensions are not allowed",
    "Compare": "comparisons are not allowed",
    "BoolOp": "'and' and 'or' are not allowed",
    "IfExp": "conditional expressions (x if c else y) are not allowed",
    "JoinedStr": "f-strings are not allowed",
    "FormattedValue": "f-strings are not allowed",
    "NamedExpr": "assignment expressions (:=) are not allowed",
    "Starred": "starred arguments (*x) are not allowed",
    "List": "lists are not allowed",
    "Tuple": "tuples (commas) are not allowed",
    "Set": "sets are not allowed",
    "Dict": "dictionaries are not allowed",
    "Await": "'await' is not allowed",
    "Yield": "'yield' is not allowed",
    "YieldFrom": "'yield' is not allowed",
    "UnaryOp": "only the unary operators + and - are allowed",
}
"""Plain-words messages for syntax outside the grammar (never a Python AST class name)."""
_NOT_ALLOWED = ("this syntax is not allowed (only numbers, + - * / ** ^, parentheses, pi, E and "
                "sqrt, cos, sin, tan, exp, log)")
_OPERATORS = {"Mod": "%", "FloorDiv": "//", "MatMult": "@", "LShift": "<<", "RShift": ">>",
              "BitOr": "|", "BitAnd": "&", "BitXor": "^"}
_NUMBER_TEXT = re.compile(r"^[+-]?(\d[\d_]*)?(\.\d*)?([eE][+-]?\d+)?$")


_PLAIN_DECIMAL = re.compile(r"([+-]?)(\d*)(?:\.(\d*))?(?:[eE]([+-]?\d{1,6}))?")
"""A plain decimal literal (no spaces or underscores): sign, integer digits, fraction digits,
exponent. :func:`plain_decimal` reads the ones that are certainly valid."""
_MAX_LITERAL_EXPONENT = 400
"""Largest |exponent| written in a decimal literal (beyond it: out of range, before any work)."""
_from_coprime = getattr(sp.Rational, "from_coprime_ints", None)


def plain_decimal(text: str) -> sp.Rational | None:
    r"""The exact rational of a plain, valid decimal literal, or None for any other text.

    The fast path of :func:`number_from_text`: ``[+-]digits[.digits][e[+-]digits]`` with at
    least one mantissa digit, at most ``MAX_DIGITS`` of them, an exponent of at most 400 in
    magnitude and a value within the range rule. Everything else (spaces, underscores,
    ``inf``, too many digits, out of range, not a number) is None, and
    :func:`number_from_text` reads it on its general path (which also words the error).

    .. math::

        \pm d_1 \dots d_k . f_1 \dots f_l \mathrm{e}\,x
        = \pm \frac{\overline{d_1 \dots d_k f_1 \dots f_l}\cdot 10^{x}}{10^{l}}
        \quad (\text{reduced by their gcd})
    """
    match = _PLAIN_DECIMAL.fullmatch(text)
    if match is None:
        return None
    sign, whole, frac, exp = match.groups()
    frac = frac or ""
    digits = whole + frac
    if not digits or len(digits) > MAX_DIGITS:
        return None
    shift = int(exp) if exp else 0
    if abs(shift) > _MAX_LITERAL_EXPONENT:
        return None
    p, shift = int(digits), shift - len(frac)
    if sign == "-":
        p = -p
    if shift >= 0:
        p, q = p * 10**shift, 1
    else:
        q = 10**-shift
        g = math.gcd(p, q)
        p, q = p // g, q // g
    if abs(p) > _BOUND * q or (p != 0 and abs(p) * _BOUND < q):
        return None
    if q == 1:
        return sp.Integer(p)
    return _from_coprime(p, q) if _from_coprime is not None else sp.Rational(p, q)


def number_from_text(text: str, field: str | None = None) -> sp.Rational:
    """Exact rational of a decimal literal's text (``"1.25"`` → 5/4, ``"1e-3"`` → 1/1000).

    Plain literals take the fast path :func:`plain_decimal`; the rest (underscores, spaces,
    errors) the general one, with the same values.

    Parameters
    ----------
    text : str
        The literal exactly as written (YAML scalar or Python literal source).
    field : str, optional
        Name of the field, for the error message.
    """
    fast = plain_decimal(text) if isinstance(text, str) else None
    if fast is not None:
        return fast
    return general_number_from_text(text, field)


def general_number_from_text(text: str, field: str | None = None) -> sp.Rational:
    """:func:`number_from_text` without its fast path: every check, in its order, with its
    message (the reference the fast path :func:`plain_decimal` is tested against).

    Parameters
    ----------
    text : str
        The literal as written (spaces around it and underscores between digits allowed).
    field : str, optional
        Name of the field, for the error message.
    """
    t = text.strip().replace("_", "")
    if t.lower().lstrip("+-") in (".inf", ".nan", "inf", "nan", "infinity"):
        raise ExpressionError(f"{text.strip()[:20]!r} is not a finite number", field=field)
    mantissa = re.split(r"[eE]", t)[0]
    if not t or not _NUMBER_TEXT.match(t) or not any(ch.isdigit() for ch in mantissa):
        raise ExpressionError(f"not a number: {text[:40]!r}", field=field)
    if sum(ch.isdigit() for ch in mantissa) > MAX_DIGITS:
        raise ExpressionError(f"number has more than {MAX_DIGITS} digits", field=field)
    exp_part = re.split(r"[eE]", t)[1] if re.search(r"[eE]", t) else "0"
    # leading zeros dropped and the digits counted before int() reads them (int() refuses more
    # than 4300 digits)
    digits = exp_part.lstrip("+-")
    lead = 0
    while lead < len(digits) - 1 and int(digits[lead]) == 0:
        lead += 1
    if len(digits) - lead > 3 or int(digits[lead:]) > _MAX_LITERAL_EXPONENT:
        raise ExpressionError(f"number {text[:40]!r} is out of range", field=field)
    if re.fullmatch(r"[+-]?\d+", t):
        r = sp.Integer(int(t))
    else:  # Fraction(t), with the exponent read as above
        shift = int(digits[lead:]) * (-1 if exp_part.startswith("-") else 1)
        value = Fraction(mantissa) * Fraction(10) ** shift
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
    return _parse(text, field)[0]


def parse_with_float(text: str, field: str | None = None) -> tuple[sp.Expr, float]:
    """:func:`parse_expression` and the float64 view of the value (rounded to nearest).

    The float comes from the value's ball enclosure when both of its ends round to the same
    double (then it is the correctly rounded value), else from a 20-digit ``evalf``.
    """
    value, ball = _parse(text, field)
    if value.is_Rational:
        return value, float(value)
    if ball is not None:
        with flint.ctx.workprec(BALL_BITS):   # the ends, exact at the ball's precision
            lo, hi = float(ball.lower()), float(ball.upper())
        if lo == hi:
            return value, lo
    return value, float(sp.N(value, 20))


def _parse(text: str, field: str | None) -> tuple[sp.Expr, Any]:
    """The checked exact value of ``text`` and its ball enclosure (None when not available)."""
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
    with flint.ctx.workprec(BALL_BITS):
        value, ball = walker.visit(tree.body, 0)
        return finish_value(value, field, text, ball), ball


def _ball_decides_range(ball: Any) -> bool:
    """The ball is finite, excludes 0 and lies within [1e-300, 1e300] in magnitude."""
    if ball is None or not ball.is_finite() or ball.contains(0):
        return False
    mag = abs(ball)
    return bool(mag > flint.arb(10) ** -300 and mag < flint.arb(10) ** 300)


def finish_value(value: sp.Expr, field: str | None, text: str, ball: Any = None) -> sp.Expr:
    """Check that ``value`` is a finite real number within the range rule and return it.

    The range rule is the literal rule (:func:`_check_magnitude`) applied to the evaluated
    value, compared in arbitrary precision (never through a float, which would underflow to 0).
    A value that is zero but not syntactically so comes back as the exact ``0``. ``ball``, a
    real arb enclosure of ``value`` from the parser, settles the checks when it is conclusive
    (finite, excluding 0 and certainly within the range).
    """
    if value.has(sp.zoo, sp.oo, -sp.oo, sp.nan) or not value.is_number:
        raise ExpressionError(f"{text[:40]!r} is not a finite number", field=field)
    if value.is_Rational:
        _check_magnitude(value, field, text)
        return value
    if _ball_decides_range(ball):
        return value
    if value.is_real is False:
        raise ExpressionError(f"{text[:40]!r} is not a real number", field=field)
    re_part, im_part = _evaluate(value, field, text)
    if im_part is not None and im_part != 0 and (
            re_part is None or abs(im_part) > sp.Float(10, 40) ** -25 * max(1, abs(re_part))):
        raise ExpressionError(f"{text[:40]!r} is not a real number", field=field)
    if re_part is None or re_part == 0:  # no digit found: zero if provably so, else refused
        if _provably_zero(value):
            return sp.Integer(0)
        raise ExpressionError(f"cannot decide whether {text[:40]!r} is zero (it is below "
                              f"1e-{MAX_WORKING_DIGITS - 100} in magnitude but not provably 0); "
                              "write it as 0 or in a simpler form", field=field)
    if abs(re_part) > _HUGE or abs(re_part) < _TINY:
        raise ExpressionError(f"{text[:40]!r} is out of range (|x| must be in [1e-300, 1e300])",
                              field=field)
    return value


def _evaluate(value: sp.Expr, field: str | None,
              text: str) -> tuple[sp.Float | None, sp.Float | None]:
    """Real and imaginary parts of ``value`` to 30 certain digits (``None``: no digit found)."""
    try:
        approx = value.evalf(30, maxn=MAX_WORKING_DIGITS, strict=True)
    except PrecisionExhausted:
        return None, None
    except (TypeError, ValueError, OverflowError, ZeroDivisionError, RecursionError):
        raise ExpressionError(f"{text[:40]!r} is not a finite number", field=field) from None
    re_part, im_part = approx.as_real_imag()
    if not (re_part.is_Number and im_part.is_Number) or re_part.has(sp.nan, sp.zoo, sp.oo) \
            or im_part.has(sp.nan, sp.zoo, sp.oo):
        raise ExpressionError(f"{text[:40]!r} is not a finite number", field=field)
    return re_part, im_part


def _term_bound(e: sp.Basic) -> int:
    """An upper bound on the number of terms of ``sp.expand(e)`` (capped just above the limit)."""
    cap = MAX_EXPANSION_TERMS + 1
    if e.is_Add:
        return min(cap, sum(_term_bound(a) for a in e.args))
    if e.is_Mul:
        out = 1
        for a in e.args:
            out = min(cap, out * _term_bound(a))
        return out
    if e.is_Pow:
        t = _term_bound(e.base)
        k = abs(e.exp.p) if e.exp.is_Rational else 1
        if e.exp.is_Rational and e.exp.q == 1 and t > 1:
            return min(cap, math.comb(t + k - 1, k)) if k < 10 * cap else cap
        return t
    if e.args:
        return min(cap, max(_term_bound(a) for a in e.args) * 2)
    return 1


def _provably_zero(value: sp.Expr) -> bool:
    """Bounded exact zero test: expansion (trigonometric functions in their ``exp`` form).

    Returns True only when the value is proven to be exactly zero; False means "not proven"
    (including when the expansion could exceed ``MAX_EXPANSION_TERMS`` terms).
    """
    if value == 0:
        return True
    candidates = [value]
    if value.has(sp.cos, sp.sin, sp.tan):
        candidates.append(value.rewrite(sp.exp))
    for cand in candidates:
        if _term_bound(cand) > MAX_EXPANSION_TERMS:
            continue
        try:
            expanded = sp.expand(cand)
            if expanded == 0:
                return True
            if expanded.is_Add and len(expanded.args) <= 20 and sp.count_ops(expanded) <= 60 \
                    and sp.expand(sp.radsimp(sp.together(expanded))) == 0:
                return True
        except (TypeError, ValueError, RecursionError, PrecisionExhausted):
            continue
    return False


def sign_of(value: sp.Expr, field: str | None = None, what: str | None = None) -> int:
    """The sign (-1, 0 or 1) of a real sympy number, decided without ``bool`` on a relational.

    Rationals exactly; otherwise by ``evalf`` with certain digits at up to
    ``MAX_WORKING_DIGITS`` digits of working precision; a number showing no digit there is 0 when
    :func:`_provably_zero` proves it. Otherwise the sign is undecidable and an
    :class:`ExpressionError` naming ``field`` is raised (exit code 2).
    """
    value = _as_number(value)
    if value.is_Rational:
        return (int(value.p) > 0) - (int(value.p) < 0)
    if not value.is_number:
        raise ExpressionError("must be a number", field=field)
    label = what or sp.sstr(value)[:40]
    try:
        approx = value.evalf(30, maxn=MAX_WORKING_DIGITS, strict=True)
    except PrecisionExhausted:
        approx = None
    except (TypeError, ValueError, OverflowError, ZeroDivisionError, RecursionError):
        raise ExpressionError(f"cannot evaluate {label}", field=field) from None
    if approx is not None:
        re_part = approx.as_real_imag()[0]
        if re_part.is_Number and re_part.is_finite and re_part != 0:
            return 1 if re_part > 0 else -1
    if _provably_zero(value):
        return 0
    raise ExpressionError(f"cannot decide the sign of {label}: it is zero to "
                          f"{MAX_WORKING_DIGITS - 100} digits but not provably so; write the "
                          "value in a simpler form", field=field)


def _as_number(value: sp.Expr | int) -> sp.Expr:
    """A sympy number from a sympy number or a Python int (never from text)."""
    if isinstance(value, sp.Basic):
        return value
    if isinstance(value, int) and not isinstance(value, bool):
        return sp.Integer(value)
    raise TypeError(f"expected a sympy number or an int, got {type(value).__name__}")


def compare(value: sp.Expr, bound: sp.Expr | int, field: str | None = None,
            what: str | None = None) -> int:
    """Sign of ``value - bound`` (see :func:`sign_of`): -1, 0 or 1, or an ExpressionError."""
    return sign_of(_as_number(value) - _as_number(bound), field,
                   what or f"{sp.sstr(value)[:40]} - {sp.sstr(bound)[:20]}")


_LONG_DIGITS = re.compile(rf"\d{{{MAX_DIGITS + 1},}}")


def exact_text(expr: sp.Expr) -> str:
    """Exact text of a sympy number, readable by :func:`parse_expression` where the limits allow.

    ``sp.sstr`` of the number, with every integer literal longer than ``MAX_DIGITS`` digits
    written in Horner form ``((d0*10**60 + d1)*10**60 + d2)`` of at most 60-digit chunks: still
    exact, and within the literal limit. (The text may still exceed ``MAX_LENGTH``; it stays
    exact, never a float.)
    """
    out = sp.sstr(expr)

    def horner(match: re.Match[str]) -> str:
        digits = match.group(0)
        head = len(digits) % MAX_DIGITS or MAX_DIGITS
        text = str(int(digits[:head]))
        for i in range(head, len(digits), MAX_DIGITS):
            text = f"({text}*10**{MAX_DIGITS} + {int(digits[i:i + MAX_DIGITS])})"
        return text

    return _LONG_DIGITS.sub(horner, out)


Ball = Any
"""A python-flint ``arb`` (real ball) enclosing a subexpression's value, or None (not known)."""


def _finite(ball: Ball) -> Ball:
    """``ball`` when it is a finite enclosure, else None."""
    return ball if ball is not None and ball.is_finite() else None


def _positive(ball: Ball) -> bool:
    return ball is not None and bool(ball > 0)


def _negative(ball: Ball) -> bool:
    return ball is not None and bool(ball < 0)


def _nonzero(ball: Ball) -> bool:
    return ball is not None and not ball.contains(0)


def _ball_power(base: Ball, exponent: sp.Rational) -> Ball:
    """Enclosure of base**exponent with sympy's (real) meaning, or None where that could be
    complex or undefined (a non-integer power of a base not certainly positive)."""
    if base is None:
        return None
    if exponent.is_Integer:
        k = int(exponent)
        if k >= 0:
            return _finite(base ** k)
        return _finite(1 / base ** (-k)) if _nonzero(base) else None
    if not _positive(base):
        return None
    return _finite(base ** flint.arb(flint.fmpq(int(exponent.p), int(exponent.q))))


_BALL_FUNCTIONS = {"cos": "cos", "sin": "sin", "tan": "tan", "exp": "exp"}


class _Walker:
    """Allow-list walk of an ``ast`` expression tree into sympy objects, each paired with a
    ball enclosure that settles the walk's decisions when it can."""

    def __init__(self, source: str, field: str | None, text: str) -> None:
        self.source = source
        self.field = field
        self.text = text

    def fail(self, why: str) -> ExpressionError:
        return ExpressionError(f"{why} in {self.text[:40]!r}", field=self.field)

    def visit(self, node: ast.AST, depth: int) -> tuple[sp.Expr, Ball]:
        if depth > MAX_DEPTH:
            raise self.fail(f"nesting deeper than {MAX_DEPTH}")
        if isinstance(node, ast.Constant):
            value = self.constant(node)
            return value, flint.arb(flint.fmpq(int(value.p), int(value.q)))
        if isinstance(node, ast.Name):
            if node.id in _NAMES:
                return _NAMES[node.id], (flint.arb.pi() if node.id == "pi" else
                                         flint.arb(1).exp())
            raise self.fail(f"unknown name {node.id[:20]!r}")
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.UAdd, ast.USub)):
            operand, ball = self.visit(node.operand, depth + 1)
            if isinstance(node.op, ast.UAdd):
                return operand, ball
            return -operand, (-ball if ball is not None else None)
        if isinstance(node, ast.BinOp):
            return self.binop(node, depth)
        if isinstance(node, ast.Call):
            return self.call(node, depth)
        raise self.fail(_DESCRIPTIONS.get(type(node).__name__, _NOT_ALLOWED))

    def constant(self, node: ast.Constant) -> sp.Rational:
        if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
            raise self.fail("only real numeric literals are allowed")
        # the source is one line of printable ASCII (checked), so columns are character offsets
        segment = self.source[node.col_offset:node.end_col_offset]
        if not segment:
            raise self.fail("unreadable literal")
        if segment.isdigit() and len(segment) <= MAX_DIGITS:
            return sp.Integer(int(segment))
        return number_from_text(segment, self.field)

    def binop(self, node: ast.BinOp, depth: int) -> tuple[sp.Expr, Ball]:
        left, lb = self.visit(node.left, depth + 1)
        right, rb = self.visit(node.right, depth + 1)
        both = lb is not None and rb is not None
        op = node.op
        if isinstance(op, ast.Add):
            out, ball = left + right, (lb + rb if both else None)
        elif isinstance(op, ast.Sub):
            out, ball = left - right, (lb - rb if both else None)
        elif isinstance(op, ast.Mult):
            out, ball = left * right, (lb * rb if both else None)
        elif isinstance(op, ast.Div):
            if right == 0 or not _nonzero(rb) and sign_of(
                    right, self.field, f"the divisor in {self.text[:40]!r}") == 0:
                raise self.fail("division by zero")
            # a rational divisor: multiplying by its reciprocal builds the same value faster
            out = left * (1 / right) if right.is_Rational else left / right
            ball = lb / rb if both and _nonzero(rb) else None
        elif isinstance(op, ast.Pow):
            out = self.power(left, right, lb)
            ball = _ball_power(lb, right)
        else:
            symbol = _OPERATORS.get(type(op).__name__)
            raise self.fail(f"the operator {symbol} is not allowed" if symbol else
                            "only the operators + - * / ** ^ are allowed")
        self.check_size(out)
        return out, _finite(ball)

    def power(self, base: sp.Expr, exponent: sp.Expr, ball: Ball) -> sp.Expr:
        if not exponent.is_Rational:
            raise self.fail("exponents must be rational numbers")
        if abs(exponent.p) > MAX_EXPONENT or exponent.q > MAX_EXPONENT_DENOMINATOR:
            raise self.fail(f"exponent {exponent} exceeds the limit {MAX_EXPONENT}")
        if exponent <= 0 and (base == 0 or (
                not base.is_Rational and not _nonzero(ball)
                and sign_of(base, self.field, f"a power's base in {self.text[:40]!r}") == 0)):
            raise self.fail("zero to a non-positive power")
        return base**exponent

    def _sign(self, arg: sp.Expr, ball: Ball, what: str) -> int:
        """Sign of a function's argument: from its ball when decisive, else :func:`sign_of`."""
        if _positive(ball):
            return 1
        if _negative(ball):
            return -1
        return sign_of(arg, self.field, what)

    def call(self, node: ast.Call, depth: int) -> tuple[sp.Expr, Ball]:
        if not isinstance(node.func, ast.Name):
            raise self.fail("only calls of sqrt, cos, sin, tan, exp, log are allowed")
        if node.func.id not in _FUNCTIONS:
            raise self.fail(f"function {node.func.id[:20]!r} is not allowed")
        if len(node.args) != 1 or node.keywords:
            raise self.fail(f"{node.func.id} takes exactly one argument")
        arg, ball = self.visit(node.args[0], depth + 1)
        name = node.func.id
        what = f"the argument of {name} in {self.text[:40]!r}"
        out_ball: Ball = None
        if name in ("log", "sqrt") and arg.is_number:
            sign = self._sign(arg, ball, what)
            if name == "log" and sign <= 0:
                raise self.fail("log of a non-positive number")
            if name == "sqrt" and sign < 0:
                raise self.fail("square root of a negative number")
            if sign == 0:
                arg, ball = sp.Integer(0), flint.arb(0)
            if sign > 0 and ball is not None:
                out_ball = ball.log() if name == "log" else ball.sqrt()
            elif name == "sqrt" and sign == 0:
                out_ball = flint.arb(0)
        if name == "exp" and arg.is_number and not arg.is_Rational:
            # a range guard, not a fine decision: the ball or 30 digits settle it (the result's
            # magnitude is checked exactly afterwards in any case)
            limit = _BALL_EXP_LIMIT
            if ball is not None and bool(abs(ball) < limit):
                pass
            elif ball is not None and bool(abs(ball) > limit):
                raise self.fail("exp argument out of range")
            else:
                re_part, _ = _evaluate(arg, self.field, self.text)
                if re_part is not None and abs(re_part) > limit:
                    raise self.fail("exp argument out of range")
        elif name == "exp" and arg.is_Rational and abs(arg) > _BALL_EXP_LIMIT:
            raise self.fail("exp argument out of range")
        if name in _BALL_FUNCTIONS and ball is not None:
            out_ball = getattr(ball, _BALL_FUNCTIONS[name])()
        out = _FUNCTIONS[name](arg)
        self.check_size(out)
        return out, _finite(out_ball)

    def check_size(self, value: sp.Expr) -> None:
        if value.is_Rational:
            if value.p.bit_length() > 2000 or value.q.bit_length() > 2000:
                raise self.fail("intermediate value out of range")
            return
        nodes = 0
        for _ in sp.preorder_traversal(value):
            nodes += 1
            if nodes > MAX_TREE_NODES:
                raise self.fail("expression too complex")
