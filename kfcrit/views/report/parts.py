"""Building blocks of the report's view model: readers of typed record values and table rows.

The section views read the typed record (:class:`~kfcrit.analysis.sections.AnalysisRecord`) by
attribute; an optional section is ``None`` and a key that some records lack
(:func:`~kfcrit.io.typed.opt_key`) is :data:`~kfcrit.io.typed.ABSENT`, which :func:`stated`
reads as ``None``, so that the templates (``StrictUndefined``) always find every key.
"""
from __future__ import annotations

import dataclasses
import re
from typing import TYPE_CHECKING, Any, TypeVar

from markupsafe import Markup

from kfcrit.errors import ExpressionError
from kfcrit.io.typed import ABSENT
from kfcrit.model.exprparse import parse_with_float
from kfcrit.views import formatting as filters
from kfcrit.views.figures import mathsvg

if TYPE_CHECKING:
    from kfcrit.analysis.sections import AnalysisRecord, CriticalValueRecord

NOT_COMPUTED = "not computed"
T = TypeVar("T")


def stated(value: T) -> T | None:
    """The value of a key that some records lack (:func:`~kfcrit.io.typed.opt_key`), ``None``
    when this record lacks it (:data:`~kfcrit.io.typed.ABSENT`)."""
    return None if value is ABSENT else value


def stated_fields(obj: Any) -> list[tuple[str, Any]]:
    """``(name, value)`` of the fields of a typed record value that it states, in declaration
    order (the keys of its JSON form: absent keys and fields kept out of the JSON are skipped)."""
    return [(f.name, getattr(obj, f.name)) for f in dataclasses.fields(obj)
            if not f.metadata.get("internal") and getattr(obj, f.name) is not ABSENT]


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
    ``None`` or an absent key → empty string. See :func:`kfcrit.views.formatting.pretty_text`."""
    return filters.pretty_text(value) if stated(value) is not None else ""


def sentence(value: Any) -> str:
    """Record prose as a finished sentence: Unicode mathematics and a final full stop."""
    text = prose(value).strip()
    if text and text[-1] not in ".!?":
        text += "."
    return text


def missing(section: str, reason: str | None = None) -> str:
    return f"{section}: {NOT_COMPUTED}" + (f" ({reason})" if reason else "")


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


def exact_p_low(rec: AnalysisRecord) -> str | None:
    """The short exact form of p_low: the lower bound's own expression (exact input, exact
    structure), else the upper bound's exact lower evidence (eigenvalues by exact arithmetic)."""
    if not input_exact(rec):
        return None
    if rec.structure is not None and rec.structure.path == "exact" \
            and rec.lower_bound is not None:
        own = closed_form_text(rec.lower_bound.expression)
        if own:
            return own
    ev = stated(rec.upper_bound.lower_evidence) if rec.upper_bound is not None else None
    if ev is not None and str(stated(ev.p_low_how) or "").startswith("exact"):
        return closed_form_text(stated(ev.expression))
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


def input_exact(rec: AnalysisRecord) -> bool:
    """Whether the record's input was read as exact numbers (``system.exact_input``); a
    floating-point input's values are numerical even where they were decided exactly on the
    rationals its binary floats represent."""
    return rec.system.exact_input is not False


def exact_claim(rec: AnalysisRecord, cv: CriticalValueRecord | None) -> bool | None:
    """Whether the report may call the critical value ``cv`` exact: its own ``exact`` flag and
    an exact input (``None`` when there is no value or it carries no flag)."""
    flag = cv.exact if cv is not None else None
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
