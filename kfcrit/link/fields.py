"""Reading link-budget fields from a system file: exact numbers, ranges, integers, mappings.

Every reader names the offending field in a one-line :class:`~kfcrit.errors.InputError`. Text is
parsed by :mod:`kfcrit.model.exprparse` (never ``eval``), so ``"1/3"`` and ``"2e6"`` are read
exactly; the range checks are decided on the exact value before it becomes a float.
"""
from __future__ import annotations

import functools
import math
from typing import Any

import sympy as sp

from kfcrit.errors import InputError
from kfcrit.model.exprparse import number_from_text, parse_expression


def exact_field_number(value: Any, field: str) -> sp.Expr:
    """Exact real number of a system-file value (text, int, float or sympy); never ``eval``."""
    if isinstance(value, bool) or value is None:
        raise InputError("must be a number", field=field)
    if isinstance(value, sp.Basic):
        if not value.is_number:
            raise InputError("must be a number", field=field)
        return value
    if isinstance(value, int):
        return sp.Integer(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise InputError("must be a finite number", field=field)
        return number_from_text(repr(value), field)
    if isinstance(value, str):
        try:
            return parsed_text(value)
        except InputError:  # parse again so that the message names the caller's field
            return parse_expression(value, field)
    raise InputError(f"must be a number, got {type(value).__name__}", field=field)


@functools.lru_cache(maxsize=8192)
def parsed_text(text: str) -> sp.Expr:
    """:func:`~kfcrit.model.exprparse.parse_expression` of ``text``, memoised by text.

    Pure and bounded: sympy numbers are immutable and errors are not cached. A sweep re-reads the
    same channel texts at every grid point.
    """
    return parse_expression(text, "value")


def real_field(data: dict, key: str, prefix: str, *, low: float | None = None,
               high: float | None = None, low_open: bool = False) -> float:
    """Read ``data[key]`` exactly; check ``low ≤ x ≤ high`` (``low < x`` if ``low_open``)."""
    where = f"{prefix}.{key}"
    value = data[key]
    if isinstance(value, str):
        try:
            checked = _checked_text(value, low, high, low_open)
        except InputError:  # parse again so that the message names the caller's field
            parse_expression(value, where)
            raise
        if isinstance(checked, str):
            raise InputError(checked, field=where)
        return checked
    return _checked(exact_field_number(value, where), where, low, high, low_open)


def _range_error(x: sp.Expr, low: float | None, high: float | None,
                 low_open: bool) -> str | None:
    """Why ``x`` is outside ``[low, high]`` (``(low, high]`` if ``low_open``), or None."""
    if low is not None and (bool(x <= low) if low_open else bool(x < low)):
        return f"must be {'>' if low_open else '>='} {low:g}, got {sp.sstr(x)[:30]}"
    if high is not None and bool(x > high):
        return f"must be <= {high:g}, got {sp.sstr(x)[:30]}"
    return None


def _checked(x: sp.Expr, where: str, low: float | None, high: float | None,
             low_open: bool) -> float:
    """``x`` as a float after the range check (a one-line error naming ``where``)."""
    reason = _range_error(x, low, high, low_open)
    if reason is not None:
        raise InputError(reason, field=where)
    return float(sp.N(x, 20)) if not x.is_Rational else float(x)


@functools.lru_cache(maxsize=8192)
def _checked_text(text: str, low: float | None, high: float | None,
                  low_open: bool) -> float | str:
    """The float of a field text inside its range, or the reason it is not (memoised: a pure
    function of its arguments; a sweep re-reads the same texts at every point)."""
    x = parsed_text(text)
    reason = _range_error(x, low, high, low_open)
    if reason is not None:
        return reason
    return float(sp.N(x, 20)) if not x.is_Rational else float(x)


def integer_field(data: dict, key: str, prefix: str, *, low: int, high: int) -> int:
    """Read an integer exactly and check ``low ≤ x ≤ high``."""
    where = f"{prefix}.{key}"
    x = exact_field_number(data[key], where)
    if not x.is_Integer:
        raise InputError(f"must be an integer, got {sp.sstr(x)[:30]}", field=where)
    if not low <= int(x) <= high:
        raise InputError(f"must be between {low} and {high}, got {int(x)}", field=where)
    return int(x)


def mapping_field(value: Any, field: str) -> dict:
    """``value`` itself when it is a mapping, else a one-line error naming ``field``."""
    if not isinstance(value, dict):
        raise InputError("must be a mapping", field=field)
    return value


def choice_field(data: dict, key: str, prefix: str, choices: tuple[str, ...]) -> str:
    """Read ``data[key]`` as one of ``choices``."""
    value = data[key]
    if not isinstance(value, str) or value not in choices:
        raise InputError(f"must be one of: {', '.join(choices)}", field=f"{prefix}.{key}")
    return value

