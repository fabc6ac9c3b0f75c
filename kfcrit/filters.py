"""Jinja filters of the report: all formatting of numbers, flags and expressions lives here.

Templates hold no computation; they print view-model values through these filters. Every filter
accepts ``None`` (a value the analysis did not compute) and prints an em dash or "not computed"
rather than failing, so a partial record still renders.
"""
from __future__ import annotations

import math
import re
from collections.abc import Callable
from typing import Any

import jinja2

DASH = "—"
_POW_RE = re.compile(r"\*\*\(?(-?[\w./]+)\)?")


def num(value: Any, digits: int = 6) -> str:
    """A number with ``digits`` significant digits (``None`` or non-finite → em dash).

    Integers print in full, floats with the ``g`` format, booleans as yes/no; anything else as
    its text.
    """
    if value is None:
        return DASH
    if isinstance(value, bool):
        return yesno(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            return DASH
        return f"{value:.{digits}g}"
    return str(value)


def signed(value: Any, digits: int = 4) -> str:
    """A difference with its sign, e.g. ``+0.04`` (``None`` → em dash)."""
    if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
        return DASH
    text = f"{value:+.{digits}g}"
    return text.replace("-", "−")


def interval(pair: Any, digits: int = 6) -> str:
    """``[a, b]`` for a two-element sequence (missing ends print as em dashes)."""
    if not isinstance(pair, (list, tuple)) or len(pair) != 2:
        return DASH
    return f"[{num(pair[0], digits)}, {num(pair[1], digits)}]"


def yesno(value: Any) -> str:
    """``yes`` / ``no`` / ``not computed``."""
    if value is None:
        return "not computed"
    return "yes" if value else "no"


def pretty_expr(text: Any) -> str:
    """Readable plain text of an expression in ``sympy.sstr`` form.

    ``sqrt`` → √, ``a**b`` → a^b, ``*`` → ·, ``-`` → the minus sign. The result is plain text
    (still autoescaped); the typeset form is the SVG from :mod:`kfcrit.mathsvg`.
    """
    if text is None or text == "":
        return DASH
    s = str(text)
    s = _POW_RE.sub(lambda m: "^" + m.group(1), s)
    s = s.replace("sqrt", "√").replace("*", "·")
    return s.replace("-", "−")


def verdict_label(value: Any) -> str:
    """The verdict in capitals for the verdict box (``None`` → ``NOT DETERMINED``)."""
    if not value:
        return "NOT DETERMINED"
    return str(value).replace("-", " ").upper()


def pct(value: Any, digits: int = 3) -> str:
    """A probability as a percentage (``0.0123`` → ``1.23 %``)."""
    if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
        return DASH
    return f"{100 * value:.{digits}g} %"


def indices(value: Any) -> str:
    """Eigenvalue indices of a block, 1-based as in the papers (``[0, 1]`` → ``{1, 2}``)."""
    if not isinstance(value, (list, tuple)):
        return DASH
    return "{" + ", ".join(str(int(i) + 1) if isinstance(i, int) else str(i)
                           for i in value) + "}"


def short_hash(value: Any, length: int = 16) -> str:
    """The first ``length`` hex digits of a digest, for tables (the full one is in a title)."""
    if not value:
        return DASH
    s = str(value)
    return s if len(s) <= length else s[:length] + "…"


def text(value: Any) -> str:
    """Any value as text for the generic key/value tables (lists joined, floats via :func:`num`)."""
    if isinstance(value, (list, tuple)):
        if len(value) > 12:
            return ", ".join(text(v) for v in value[:12]) + f", … ({len(value)} items)"
        return ", ".join(text(v) for v in value) if value else DASH
    if isinstance(value, dict):
        return "; ".join(f"{k}: {text(v)}" for k, v in value.items()) if value else DASH
    return num(value)


def key_label(value: Any) -> str:
    """A record key as a label (``max_error_trace`` → ``max error trace``)."""
    return str(value).replace("_", " ")


FILTERS: dict[str, Callable[..., str]] = {
    "num": num, "signed": signed, "interval": interval, "yesno": yesno,
    "pretty_expr": pretty_expr, "verdict_label": verdict_label, "pct": pct,
    "indices": indices, "short_hash": short_hash, "text": text, "key_label": key_label,
}


def register(env: jinja2.Environment) -> jinja2.Environment:
    """Register every report filter on ``env`` and return it."""
    env.filters.update(FILTERS)
    return env
