"""Reading big numeric matrices fast: the plain-decimal path of ``number_from_text``, the
direct construction of rational matrices and their float views give exactly what the general
paths give (values, types, flags, errors), on generated and hostile inputs."""
from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
import sympy as sp
from hypothesis import example, given, settings
from hypothesis import strategies as st

from kfcrit.errors import ExpressionError
from kfcrit.model import exprparse
from kfcrit.model.exprparse import number_from_text, plain_decimal
from kfcrit.model.system import (
    System,
    matrix_and_float,
    matrix_rows,
    rational_floats,
    rational_matrix,
)

HOSTILE = [
    "1e999", "-1e999", "1e-999", "1e400", "1e401", "1e-400", "1e300", "1e301", "1e-300",
    "1e-301", "9.99e299", "1.0000000000000001e300", "0.99999999999999e-300", "10e299",
    "0.1e301", "nan", "NaN", "-nan", "inf", "-inf", ".inf", "-.inf", "+.INF", "Infinity",
    ".nan", "1e" + "9" * 5000, "1e-" + "9" * 5000, "1e0000000000001", "1e" + "0" * 5000 + "1",
    "e5", "E5", ".e5", "1e", "1e+", ".", "", " ", "+", "-", "+-1", "1..2", "1.2.3", "--1",
    "1_000", "1__0", "_1", "1_", " 1.5 ", "\t2\n", "1/3", "sqrt(2)", "2**3", "0x1F", "0o17",
    "0b101", "1:30", "١٢", "٣.٥", "1e٣", "²", "1" * 60, "1" * 61, "0." + "0" * 59 + "1",
    "0." + "0" * 60 + "1", "-0", "-0.0", "+0", "0e0", "0e999", "0.0e-999", "000123",
    "1.5E+07", "1.5e-07", "+.5", "5.", "-5.e-1", "1e-0", "1e+0", "12345678901234567890.5",
]


def outcome(fn, text: str) -> tuple:
    """What a reader makes of ``text``: ("ok", value, type) or ("error", class, message,
    field)."""
    try:
        value = fn(text, "A[0][0]")
    except ExpressionError as exc:
        return ("error", type(exc), str(exc), exc.field)
    return ("ok", value, type(value))


def same_as_general(text: str) -> None:
    assert outcome(number_from_text, text) == outcome(exprparse.general_number_from_text, text), text


@pytest.mark.parametrize("text", HOSTILE)
def test_hostile_texts_read_as_by_the_general_path(text: str) -> None:
    same_as_general(text)


@pytest.mark.parametrize("text", ["1e" + "9" * 5000, "e5", ".e5"])
def test_texts_that_used_to_escape_as_tracebacks_are_one_line_errors(text: str) -> None:
    with pytest.raises(ExpressionError) as info:
        number_from_text(text, "Q[1][2]")
    assert info.value.field == "Q[1][2]" and "\n" not in str(info.value)


DIGITS = st.text(alphabet="0123456789", max_size=70)
EXPONENT = st.one_of(st.just(""), st.builds(
    lambda e, sign, digits: e + sign + digits, st.sampled_from("eE"),
    st.sampled_from(["", "+", "-"]), st.text(alphabet="0123456789", max_size=8)))
LITERAL = st.builds(lambda sign, whole, dot, frac, exp: sign + whole + dot + frac + exp,
                    st.sampled_from(["", "+", "-"]), DIGITS, st.sampled_from(["", "."]),
                    DIGITS, EXPONENT)


@settings(max_examples=600, deadline=None)
@given(LITERAL)
@example("0.010845690418329832")
@example("-0.20056088166815003")
def test_generated_literals_read_as_by_the_general_path(text: str) -> None:
    same_as_general(text)


@settings(max_examples=300, deadline=None)
@given(st.text(alphabet="0123456789.eE+-_ x/()", max_size=24))
def test_generated_noise_reads_as_by_the_general_path(text: str) -> None:
    same_as_general(text)


@settings(max_examples=300, deadline=None)
@given(st.floats(allow_nan=False, allow_infinity=False, min_value=-1e300, max_value=1e300)
       .filter(lambda x: x == 0 or abs(x) >= 1e-300))
def test_plain_decimal_is_the_exact_rational_of_the_text(x: float) -> None:
    # the reference is the standard library's exact reading of the same text
    text = repr(x)
    value = plain_decimal(text)
    assert value is not None
    assert (int(value.p), int(value.q)) == Fraction(text).as_integer_ratio()


def rationals() -> st.SearchStrategy[sp.Rational]:
    return st.one_of(
        st.integers(-10**6, 10**6).map(sp.Integer),
        st.builds(lambda p, q: sp.Rational(p, q), st.integers(-10**30, 10**30),
                  st.integers(1, 10**30)),
        st.floats(allow_nan=False, allow_infinity=False, min_value=-1e300, max_value=1e300)
        .filter(lambda x: x == 0 or abs(x) >= 1e-300).map(lambda x: sp.Rational(x)),
        # midpoints between neighbouring doubles: ties of round-to-nearest
        st.floats(min_value=1e-300, max_value=1e300).map(
            lambda x: sp.Rational((Fraction(x) + Fraction(np.nextafter(x, np.inf))) / 2)),
    )


@settings(max_examples=300, deadline=None)
@given(st.lists(rationals(), min_size=1, max_size=30))
def test_float_views_are_the_correctly_rounded_ones(values: list[sp.Rational]) -> None:
    expected = [float(v) for v in values]          # sympy/mpmath rounding to nearest
    assert rational_floats(values).tolist() == expected
    assert rational_floats(values).tolist() == [float(Fraction(int(v.p), int(v.q)))
                                                for v in values]


def test_float_views_out_of_the_range_rule_are_sympys() -> None:
    values = [sp.Rational(1, 10**400), sp.Integer(10**400), -sp.Integer(10**400),
              sp.Rational(7, 10**310), sp.Integer(0)]
    assert rational_floats(values).tolist() == [float(v) for v in values]


@settings(max_examples=150, deadline=None)
@given(st.integers(1, 6), st.integers(1, 6), st.data())
def test_rational_matrix_is_sympys_matrix(rows: int, cols: int, data: st.DataObject) -> None:
    kind = data.draw(st.sampled_from(["mixed", "integer", "zero"]))
    entry = {"mixed": rationals(), "integer": st.integers(-50, 50).map(sp.Integer),
             "zero": st.just(sp.Integer(0))}[kind]
    flat = data.draw(st.lists(entry, min_size=rows * cols, max_size=rows * cols))
    reference = sp.ImmutableMatrix(rows, cols, flat)
    built = rational_matrix(rows, cols, flat)
    assert type(built) is type(reference)
    assert built == reference and hash(built) == hash(reference)
    assert built.args == reference.args
    assert built._rep == reference._rep and built._rep.domain == reference._rep.domain
    assert built.tolist() == reference.tolist()
    assert matrix_rows(built) == reference.tolist()
    if rows == cols:
        assert built * built == reference * reference
        assert built.det() == reference.det()


def test_matrix_rows_of_other_matrices_is_tolist() -> None:
    for M in (sp.Matrix([[1, sp.sqrt(2)], [sp.pi, 0]]), sp.ImmutableMatrix([[sp.sqrt(3)]]),
              sp.ImmutableMatrix(sp.eye(3) * sp.Rational(1, 3)), sp.zeros(2, 3)):
        assert matrix_rows(M) == M.tolist()


def general_matrix(rows: list[list]) -> tuple[sp.ImmutableMatrix, np.ndarray]:
    """The general construction (sympy's constructor, entry-wise float views)."""
    return sp.ImmutableMatrix(rows), np.array([[float(v) for v in r] for r in rows])


@settings(max_examples=100, deadline=None)
@given(st.integers(1, 5), st.integers(1, 5), st.data())
def test_matrix_and_float_of_rationals_is_the_general_result(rows: int, cols: int,
                                                           data: st.DataObject) -> None:
    flat = data.draw(st.lists(rationals(), min_size=rows * cols, max_size=rows * cols))
    nested = [flat[i * cols:(i + 1) * cols] for i in range(rows)]
    M, exact, F = matrix_and_float(nested, "A")
    ref_M, ref_F = general_matrix(nested)
    assert exact is True and M == ref_M and M._rep == ref_M._rep
    assert F.tolist() == ref_F.tolist()


def test_mixed_rows_take_the_general_path_with_its_errors() -> None:
    with pytest.raises(Exception) as info:
        matrix_and_float([[sp.Rational(1, 2), "sqrt(-1)"]], "A")
    assert "A[0][1]" in str(info.value)
    M, exact, F = matrix_and_float([[sp.Rational(1, 2), 0.25]], "A")
    assert exact is False and M == sp.ImmutableMatrix([[sp.Rational(1, 2), sp.Rational(1, 4)]])
    with pytest.raises(Exception) as info:
        matrix_and_float([[sp.Rational(1, 2)], [sp.Rational(1, 3), 1]], "C")
    assert "row 1 has 2 entries" in str(info.value)


def test_a_system_of_rationals_is_the_system_of_the_same_texts() -> None:
    # one system from exact rationals (fast path), one from strings (the expression path)
    texts = [["0.5", "-1.25"], ["1e-3", "2"]]
    fast = System(A=[[number_from_text(t) for t in row] for row in texts], C=[[1, 0]],
                  Q=[[number_from_text("0.5"), 0], [0, 1]], R=1)
    slow = System(A=texts, C=[["1", "0"]], Q=[["0.5", "0"], ["0", "1"]], R="1")
    for name in ("A", "C", "Q", "R", "Sigma0"):
        assert getattr(fast, name) == getattr(slow, name)
    for name in ("a", "c", "q", "r", "sigma0"):
        assert getattr(fast, name).tolist() == getattr(slow, name).tolist()
    assert fast.exact and slow.exact
    assert fast.matrices_text() == slow.matrices_text()
    with pytest.raises(Exception, match="must be symmetric"):
        System(A=[[1]], C=[[1], [2]], Q=1,
               R=[[number_from_text("1"), number_from_text("0.5")],
                  [number_from_text("0.25"), number_from_text("1")]])


def test_the_parsing_deadline_never_refuses_plain_numbers(monkeypatch: pytest.MonkeyPatch) -> None:
    # the deadline bounds expression evaluation; here every check of it counts as expired
    from kfcrit.model import system as system_module

    calls: list[str] = []

    def expired(self, where: str) -> None:
        calls.append(where)
        raise system_module.InputError("deadline", field=where)

    monkeypatch.setattr(system_module.ParseBudget, "check", expired)
    half = number_from_text("0.5")
    s = System(A=[[half, 0], [0, half]], C=[[1, 0]], Q=[[1, half], [half, 1]], R=1)
    assert s.exact and calls == []
    with pytest.raises(system_module.InputError, match="deadline"):
        System(A=[[half, 0], [0, half]], C=[[1, 0]], Q=[[1, "sqrt(2)/4"], ["sqrt(2)/4", 1]],
               R=1)
    assert calls
