"""Building blocks of the report's view model: safe readers of record values and table rows.

A record section may be missing, ``None`` or malformed; these readers turn any of that into an
empty mapping, an empty list or ``None`` so that the section views never raise and the templates
(``StrictUndefined``) always find every key.
"""
from __future__ import annotations

import dataclasses
import re
import typing
from collections.abc import Iterable
from typing import Any

from markupsafe import Markup

from kfcrit.analysis.sections import AnalysisRecord, record_from_json
from kfcrit.errors import ExpressionError
from kfcrit.io.typed import ABSENT, RecordError, from_json
from kfcrit.model.exprparse import parse_with_float
from kfcrit.views import formatting as filters
from kfcrit.views.figures import mathsvg

NOT_COMPUTED = "not computed"


def typed_section(cls: type, value: Any) -> Any:
    """``value`` (a section's JSON form) read as ``cls``, or ``None`` when it is missing or does
    not fit (the report renders what it can of a malformed record)."""
    if value is None:
        return None
    try:
        return from_json(cls, value, cls.__name__)
    except RecordError:
        return None


def typed_record(data: Any) -> AnalysisRecord:
    """The typed record of a report's JSON-form input, for the views that take the typed
    record: read strictly, else section by section, a missing or misfit section being left out
    (``None``, an absent optional key, or an empty list)."""
    try:
        return record_from_json(data)
    except RecordError:
        pass
    d = as_dict(data)
    hints = typing.get_type_hints(AnalysisRecord)
    values: dict[str, Any] = {}
    for f in dataclasses.fields(AnalysisRecord):
        if f.metadata.get("internal"):
            continue
        empty = ABSENT if f.default is ABSENT else [] if f.name in ("warnings",
                                                                    "verification") else None
        try:
            values[f.name] = from_json(hints[f.name], d[f.name], f.name) if f.name in d else empty
        except RecordError:
            values[f.name] = empty
    return AnalysisRecord(**values)


def as_dict(value: Any) -> dict[str, Any]:
    return value if isinstance(value, dict) else {}


def as_list(value: Any) -> list[Any]:
    return value if isinstance(value, list) else []


def number(value: Any) -> float | None:
    """A real number or ``None`` (bools and text are not numbers here)."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return value
    return None


def safe_svg(svg: str | None) -> Markup | None:
    """Mark an SVG that *we* generated (matplotlib output, ids rewritten) as safe HTML."""
    return Markup(svg) if svg else None


def prose(value: Any) -> str:
    """Record prose with its ASCII mathematics in Unicode (``sqrt(3)`` → √3, ``<=`` → ≤ ...);
    ``None`` → empty string. See :func:`kfcrit.views.formatting.pretty_text`."""
    return filters.pretty_text(value) if value is not None else ""


def sentence(value: Any) -> str:
    """Record prose as a finished sentence: Unicode mathematics and a final full stop."""
    text = prose(value).strip()
    if text and text[-1] not in ".!?":
        text += "."
    return text


def missing(section: str, reason: str | None = None) -> str:
    return f"{section}: {NOT_COMPUTED}" + (f" ({reason})" if reason else "")


def kv_rows(data: Any, skip: Iterable[str] = ()) -> list[dict[str, Any]]:
    """Rows ``{key, value}`` of a mapping's entries, for generic tables (nothing disappears)."""
    skipped = set(skip)
    return [{"key": str(k), "value": v} for k, v in as_dict(data).items() if k not in skipped]


def formula(latex: str | None, expression: str | None, *, fontsize: float = 11.0,
            label: str | None = None) -> Markup | None:
    """Typeset a record formula: its LaTeX if mathtext can set it, else its exact expression."""
    svg = mathsvg.latex_svg(latex, fontsize=fontsize, label=label) if latex else None
    if svg is None and expression:
        svg = mathsvg.expression_svg(expression, fontsize=fontsize)
    return safe_svg(svg)


def row(label: str, value: Any, kind: str = "text", note: str = "",
        status: bool | None = None, unit_title: str = "") -> dict[str, Any]:
    """One labelled row of a quantity table: the template prints ``value | quantity(kind)``.

    ``note`` is already formatted text (built with :mod:`kfcrit.views.formatting`); ``status`` marks a
    pass/fail comparison (``None``: no comparison).
    """
    return {"label": label, "value": value, "kind": kind, "note": note, "status": status,
            "title": unit_title}


SHORT_FORM_CHARS = 40
"""Longest exact expression the report prints (longer ones read as a dump, not a form)."""

_LONG_DECIMAL_RE = re.compile(r"\d\.\d{7,}|\d[eE][+-]?\d")


def short_closed_form(expression: Any) -> str | None:
    """``expression`` if it is a short closed form worth printing beside its number, else None.

    Not a closed form here: a plain decimal (``0.96213``), text holding a long float or a float
    in e-notation (``1.4198034786194746e-5``), a ``CRootOf``/``RootOf`` (an indexed root of a
    polynomial: exact, but not readable) and anything over :data:`SHORT_FORM_CHARS` characters.
    """
    if not isinstance(expression, str):
        return None
    text = expression.strip()
    if not text or "\n" in text or mathsvg.is_plain(text) or "RootOf" in text:
        return None
    if len(text) > SHORT_FORM_CHARS or _LONG_DECIMAL_RE.search(text):
        return None
    return text


def closed_form_text(expression: Any) -> str | None:
    """An exact expression worth printing beside its number (:func:`short_closed_form`)."""
    return short_closed_form(expression)


def exact_plain(text: Any) -> str | None:
    """An exact expression that reads as itself: a short closed form or an integer/short
    decimal such as ``1`` (a long decimal is a float's digits, not an exact form)."""
    if short_closed_form(text):
        return str(text).strip()
    if isinstance(text, str) and text.strip() and mathsvg.is_plain(text) \
            and len(text.strip()) <= 8:
        return text.strip()
    return None


def exact_p_low(rec: dict[str, Any]) -> str | None:
    """The short exact form of p_low: the lower bound's own expression (exact input, exact
    structure), else the upper bound's exact lower evidence (eigenvalues by exact arithmetic)."""
    if not input_exact(rec):
        return None
    if as_dict(rec.get("structure")).get("path") == "exact":
        own = closed_form_text(as_dict(rec.get("lower_bound")).get("expression"))
        if own:
            return own
    ev = as_dict(as_dict(rec.get("upper_bound")).get("lower_evidence"))
    if str(ev.get("p_low_how", "")).startswith("exact"):
        return closed_form_text(ev.get("expression"))
    return None


def numerical_text(value: Any, digits: int = 6) -> str:
    """A computed value: ``digits`` significant digits (:func:`~kfcrit.views.formatting.sig`),
    marked numerical."""
    v = number(value)
    if v is None:
        return filters.DASH
    return f"{filters.sig(float(v), digits).replace('-', '−')} (numerical)"


def complex_html(re_: Any, im: Any, digits: int = 6) -> str:
    """A computed complex number as ``a + bj`` (``a − bj``) at ``digits`` significant digits;
    a real one as its real part."""
    a, b = number(re_), number(im)
    if a is None:
        return filters.DASH
    real = filters.sig(float(a), digits).replace("-", "−")
    if not b:
        return real
    sign = "−" if b < 0 else "+"
    return f"{real} {sign} {filters.sig(abs(float(b)), digits)}j"


def input_exact(rec: dict[str, Any]) -> bool:
    """Whether the record's input was read as exact numbers (``system.exact_input``); a
    floating-point input's values are numerical even where they were decided exactly on the
    rationals its binary floats represent."""
    return as_dict(rec.get("system")).get("exact_input") is not False


def exact_claim(rec: dict[str, Any], quantity: Any) -> bool | None:
    """Whether the report may call ``quantity`` exact: its own ``exact`` flag and an exact
    input (``None`` when the quantity carries no flag)."""
    flag = as_dict(quantity).get("exact")
    if flag is None:
        return None
    return bool(flag) and input_exact(rec)


INPUT_DIGITS = 10
"""Significant digits of the entries of a floating-point input's matrices in the report."""


def decimal_entry(text: Any, digits: int = INPUT_DIGITS) -> str:
    """An entry of a floating-point input (the rational of its binary float, such as
    ``986919187616889/1125899906842624``) as a decimal to ``digits`` significant digits."""
    try:
        return filters.pretty_expr(filters.sig(float(parse_with_float(str(text))[1]), digits))
    except (ExpressionError, ValueError, TypeError, ArithmeticError):
        return str(text)


def maybe_svg(expr: Any) -> Markup | None:
    """SVG of an exact expression that does not read well as plain text (else ``None``)."""
    if short_closed_form(expr):
        return safe_svg(mathsvg.expression_svg(expr))
    return None




def figure_entry(svg: str | None, title: str, caption: str, missing_text: str
                 ) -> dict[str, Any]:
    """A figure for the ``figure`` macro: markup, title, caption and the "not computed" text."""
    return {"svg": safe_svg(svg), "title": title, "caption": caption,
            "missing": missing_text or f"{title[:1].lower() + title[1:]}: {NOT_COMPUTED}"}
