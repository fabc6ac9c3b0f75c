"""The allow-list expression parser: exact values, and refusal of everything else."""
from __future__ import annotations

import pytest
import sympy as sp
from hypothesis import given
from hypothesis import strategies as st

from kfcrit.errors import ExpressionError
from kfcrit.model.exprparse import number_from_text, parse_expression


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("1.25", sp.Rational(5, 4)),
        ("1e-3", sp.Rational(1, 1000)),
        ("-0.1", sp.Rational(-1, 10)),
        ("2^-4", sp.Rational(1, 16)),
        ("2**(-4)", sp.Rational(1, 16)),
        ("sqrt(3)", sp.sqrt(3)),
        ("2*cos(pi/5)", (1 + sp.sqrt(5)) / 2),
        ("cos(2*pi/5)", (sp.sqrt(5) - 1) / 4),
        ("(1 + 2) * 3 / 4", sp.Rational(9, 4)),
        ("exp(0)", sp.Integer(1)),
        ("log(E)", sp.Integer(1)),
        ("sin(pi/6)", sp.Rational(1, 2)),
        ("tan(pi/4)", sp.Integer(1)),
        ("1.7320508075688772", sp.Rational(17320508075688772, 10**16)),
    ],
)
def test_exact_values(text: str, expected: sp.Expr) -> None:
    # expected values are the textbook exact values of each expression
    assert sp.simplify(parse_expression(text) - expected) == 0


@pytest.mark.parametrize(
    "text",
    [
        "__import__('os').system('id')",
        "().__class__",
        "().__class__.__bases__[0].__subclasses__()",
        "open('x')",
        "9**9**9**9",
        "x" * 100_000,
        "1" * 100_000,
        "lambda: 1",
        "[i for i in range(3)]",
        "{1: 2}",
        "a",
        "sqrt(2, 3)",
        "sqrt(x=2)",
        "1 if 1 else 2",
        "1e400",
        "1e-400",
        "sqrt(-1)",
        "log(0)",
        "1/0",
        "tan(pi/2)",
        "2**sqrt(2)",
        "3 < 4",
        "1j",
        "True",
        "'abc'",
        "",
        "   ",
        "(" * 200 + "1" + ")" * 200,
        "exp(1000)",
        "10**64**2",
        "pi.real",
        "e.__class__",
        "\x00",
        "1 @ 2",
        "2 // 3",
    ],
)
def test_hostile_expressions_are_refused(text: str) -> None:
    with pytest.raises(ExpressionError):
        parse_expression(text, field="A[0][0]")


def test_error_names_the_field() -> None:
    with pytest.raises(ExpressionError, match=r"^A\[0\]\[1\]: "):
        parse_expression("open('x')", field="A[0][1]")


@given(st.fractions(max_denominator=10**6).filter(lambda f: abs(f) < 10**9))
def test_decimal_text_round_trips_exactly(f) -> None:  # noqa: ANN001
    # a decimal written with enough digits is read back as exactly the rational it denotes
    text = f"{f.numerator}/{f.denominator}"
    assert parse_expression(text) == sp.Rational(f.numerator, f.denominator)


@given(st.integers(-10**12, 10**12), st.integers(0, 12))
def test_number_from_text_is_exact(mantissa: int, scale: int) -> None:
    text = f"{mantissa}e-{scale}"
    assert number_from_text(text) == sp.Rational(mantissa, 10**scale)


# ---- bounded decisions (audit "Hardening: hostile inputs") -----------------------------------

def test_sign_of_decides_without_bool_of_a_relational() -> None:
    from kfcrit.model.exprparse import compare, sign_of

    one = sp.cos(1) ** 2 + sp.sin(1) ** 2  # exactly 1, not syntactically
    assert compare(one, 1) == 0  # proven by the bounded exact test
    assert sign_of(one - 1 + sp.exp(-2000)) == 1  # certain digits at ~2000 digits of precision
    assert sign_of(sp.sqrt(2) - sp.Rational(14142135623730951, 10**16)) == -1
    assert sign_of(sp.Rational(-3, 7)) == -1 and sign_of(sp.Integer(0)) == 0
    with pytest.raises(ExpressionError, match=r"^p: cannot decide the sign"):
        compare(one**64, 1, "p")  # zero to 1100 digits, beyond the bounded exact test


@pytest.mark.parametrize("text", ["cos(1)**2+sin(1)**2-1", "sqrt(cos(1)**2+sin(1)**2-1)",
                                  "log(cos(1)**2+sin(1)**2)", "(1+sqrt(2))**2-3-2*sqrt(2)",
                                  "1/(sqrt(2)-1)-sqrt(2)-1", "tan(1)-sin(1)/cos(1)"])
def test_provable_zeros_become_exact_zero(text: str) -> None:
    assert parse_expression(text) == 0


@pytest.mark.parametrize(("text", "message"), [
    ("1/(cos(1)**2+sin(1)**2-1)", "division by zero"),
    ("(cos(1)**2+sin(1)**2-1)^-1", "zero to a non-positive power"),
    ("log(cos(1)**2+sin(1)**2-1)", "log of a non-positive number"),
    ("(cos(1)**2+sin(1)**2)^64-1", "cannot decide whether"),
    ("sqrt((cos(1)**2+sin(1)**2)^64-1)", "cannot decide the sign"),
    ("1e-200*1e-200", "out of range"),
    ("exp(-690)**2", "out of range"),
    ("exp(-690)*1e-10", "out of range"),
    ("1e200*1e200", "out of range"),
])
def test_bounded_refusals_name_the_field(text: str, message: str) -> None:
    with pytest.raises(ExpressionError, match=r"^A\[0\]\[0\]: ") as info:
        parse_expression(text, "A[0][0]")
    assert message in str(info.value)


def test_magnitude_rule_is_the_same_for_literals_and_results() -> None:
    # the boundary 1e-300 is inside for both; just below is outside for both
    assert parse_expression("1e-300") == sp.Rational(1, 10**300)
    assert parse_expression("1e-150*1e-150") == sp.Rational(1, 10**300)
    for text in ("1e-301", "1e-150*1e-151", "0.1*1e-300"):
        with pytest.raises(ExpressionError, match="out of range"):
            parse_expression(text)
    assert parse_expression("exp(-690)") == sp.exp(-690)  # 2.2e-300
    assert parse_expression("0*exp(-690)") == 0  # zero is allowed


def test_exact_text_keeps_long_numbers_exact_and_parseable() -> None:
    from kfcrit.model.exprparse import exact_text

    r = sp.Rational(10**70 + 3, 7 * 10**65 + 1)
    text = exact_text(r)
    assert "." not in text and "e" not in text.lower()  # never a float text
    assert all(len(run) <= 60 for run in __import__("re").findall(r"\d+", text))
    assert parse_expression(text) == r
    assert exact_text(sp.sqrt(2) / 3) == "sqrt(2)/3"
    long = sp.Integer(10) ** 200 + 1
    assert parse_expression(exact_text(long)) == long
    huge = sp.Rational(3**1000, 7)  # beyond the length limit: exact text all the same
    assert "." not in exact_text(huge) and len(exact_text(huge)) > 500


_AST_CLASS_NAMES = ("JoinedStr", "FormattedValue", "NamedExpr", "Starred", "BoolOp", "UnaryOp",
                    "IfExp", "Tuple", "List", "Dict", "Set", "Await", "Mod", "FloorDiv",
                    "MatMult", "BitOr", "BitAnd", "LShift", "Compare", "Attribute", "Subscript")


@pytest.mark.parametrize(("text", "words"), [
    ("f'{1}'", "f-strings are not allowed"),
    ("(x := 1)", "assignment expressions (:=) are not allowed"),
    ("sqrt(*[4])", "starred arguments (*x) are not allowed"),
    ("1 if 1 else 2", "conditional expressions"),
    ("1 and 2", "'and' and 'or' are not allowed"),
    ("not 1", "only the unary operators + and - are allowed"),
    ("~1", "only the unary operators + and - are allowed"),
    ("1 % 2", "the operator % is not allowed"),
    ("7 // 2", "the operator // is not allowed"),
    ("1 @ 2", "the operator @ is not allowed"),
    ("1 | 2", "the operator | is not allowed"),
    ("1 << 2", "the operator << is not allowed"),
    ("(1, 2)", "tuples (commas) are not allowed"),
    ("[1]", "lists are not allowed"),
    ("{1: 2}", "dictionaries are not allowed"),
    ("{1}", "sets are not allowed"),
    ("1 < 2", "comparisons are not allowed"),
    ("().__class__", "attribute access (x.y) is not allowed"),
    ("x[0]", "indexing (x[i]) is not allowed"),
    ("[x for x in y]", "comprehensions are not allowed"),
    ("lambda: 1", "lambda functions are not allowed"),
    ("await x", "'await' is not allowed"),
])
def test_syntax_errors_are_in_plain_words(text: str, words: str) -> None:
    with pytest.raises(ExpressionError) as info:
        parse_expression(text, "A[0][0]")
    message = str(info.value)
    assert message.startswith("A[0][0]: ") and words in message, message
    for name in _AST_CLASS_NAMES:
        assert name not in message.split(" in ")[0], message
