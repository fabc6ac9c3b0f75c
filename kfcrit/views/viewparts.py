"""Building blocks of the report's view model: safe readers of record values and table rows.

A record section may be missing, ``None`` or malformed; these readers turn any of that into an
empty mapping, an empty list or ``None`` so that the section views never raise and the templates
(``StrictUndefined``) always find every key.
"""
from __future__ import annotations

import re
from collections.abc import Iterable
from typing import Any

from markupsafe import Markup

from kfcrit.views import jinja_filters as filters
from kfcrit.views import mathsvg

NOT_COMPUTED = "not computed"


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
    ``None`` → empty string. See :func:`kfcrit.views.jinja_filters.pretty_text`."""
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

    ``note`` is already formatted text (built with :mod:`kfcrit.views.jinja_filters`); ``status`` marks a
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


def exact_text(expression: Any) -> str | None:
    """An exact expression worth printing beside its number (:func:`short_closed_form`)."""
    return short_closed_form(expression)


def numerical_text(value: Any, digits: int = 6) -> str:
    """A value that has no short closed form: ``digits`` significant digits, marked numerical."""
    v = number(value)
    return f"{filters.num(v, digits)} (numerical)" if v is not None else filters.DASH


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
