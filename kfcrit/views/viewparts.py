"""Building blocks of the report's view model: safe readers of record values and table rows.

A record section may be missing, ``None`` or malformed; these readers turn any of that into an
empty mapping, an empty list or ``None`` so that the section views never raise and the templates
(``StrictUndefined``) always find every key.
"""
from __future__ import annotations

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


def exact_text(expression: Any) -> str | None:
    """An exact expression worth printing beside its number (not a plain decimal like 0.96213…)."""
    if not isinstance(expression, str) or not expression.strip():
        return None
    return None if mathsvg.is_plain(expression) else expression


def maybe_svg(expr: Any) -> Markup | None:
    """SVG of an exact expression that does not read well as plain text (else ``None``)."""
    if isinstance(expr, str) and expr and not mathsvg.is_plain(expr):
        return safe_svg(mathsvg.expression_svg(expr))
    return None




def figure_entry(svg: str | None, title: str, caption: str, missing_text: str
                 ) -> dict[str, Any]:
    """A figure for the ``figure`` macro: markup, title, caption and the "not computed" text."""
    return {"svg": safe_svg(svg), "title": title, "caption": caption,
            "missing": missing_text or f"{title[:1].lower() + title[1:]}: {NOT_COMPUTED}"}
