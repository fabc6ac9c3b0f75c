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


def _finite(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) \
        and math.isfinite(value)


def fixed(value: Any, decimals: int = 2) -> str:
    """A number with a fixed count of decimals (``1.77516`` → ``1.78``); minus sign as −."""
    if not _finite(value):
        return DASH
    return f"{value:.{decimals}f}".replace("-", "−")


def sci(value: Any, digits: int = 3) -> str:
    """A small or large number in readable scientific form (``4.26e-16`` → ``4.26 × 10⁻¹⁶``);
    numbers between 10⁻³ and 10⁶ print plainly."""
    if not _finite(value):
        return DASH
    if value == 0 or 1e-3 <= abs(value) < 1e6:
        return num(float(value), digits).replace("-", "−")
    mant, exp = f"{value:.{digits - 1}e}".split("e")
    mant = mant.rstrip("0").rstrip(".") if "." in mant else mant
    sup = str(int(exp)).translate(_SUPERSCRIPT)
    return f"{mant} × 10{sup}".replace("-", "−")


_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")

# Units of the link budget and how many decimals a reviewer needs for each.
UNITS: dict[str, tuple[str, int]] = {
    "dB": ("dB", 2), "dBm": ("dBm", 2), "m": ("m", 1), "Hz": ("Hz", 0), "K": ("K", 0),
    "bytes": ("bytes", 0), "s": ("s", 2),
}


def unit(value: Any, name: str, decimals: int | None = None) -> str:
    """A physical quantity with its unit: ``1.775 | unit("dB")`` → ``1.78 dB``.

    Decimals default per unit (dB and dBm 2, metres 1, kelvin 0); hertz print with an SI
    prefix (``2e6`` → ``2 MHz``). ``None`` or non-finite → em dash.
    """
    if not _finite(value):
        return DASH
    label, default = UNITS.get(name, (name, 3))
    if name == "Hz":
        for scale, prefix in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
            if abs(value) >= scale:
                return f"{num(value / scale, 6)} {prefix}Hz"
        return f"{num(float(value), 6)} Hz"
    places = default if decimals is None else decimals
    return f"{fixed(value, places)} {label}"


def prob(value: Any, digits: int = 4) -> str:
    """A probability: ``0.3286`` (4 significant digits) and, below 10⁻³, scientific."""
    if not _finite(value):
        return DASH
    if value != 0 and abs(value) < 1e-3:
        return sci(value, 3)
    return num(float(value), digits)


def count(value: Any) -> str:
    """An integer count with thin-space thousands separators (``50000`` → ``50 000``)."""
    if not _finite(value):
        return DASH
    return f"{int(value):,}".replace(",", "\u202f")


def vector(value: Any, digits: int = 4) -> str:
    """A vector or matrix of numbers as text: ``[−0.801, −0.997]`` (rows separated by ``;``)."""
    if not isinstance(value, (list, tuple)) or not value:
        return DASH
    if all(isinstance(v, (list, tuple)) and len(v) == 1 for v in value):
        value = [v[0] for v in value]
    if all(isinstance(v, (list, tuple)) for v in value):
        return "[" + "; ".join(", ".join(signed_plain(x, digits) for x in row)
                               for row in value) + "]"
    return "[" + ", ".join(signed_plain(x, digits) for x in value) + "]"


def signed_plain(value: Any, digits: int = 4) -> str:
    """A number with the typographic minus sign and ``digits`` significant digits."""
    if not _finite(value):
        return DASH
    return "0" if value == 0 else num(value, digits).replace("-", "−")


def quantity(value: Any, kind: str | None = None) -> str:
    """Format ``value`` by its kind, for the labelled tables of the view model.

    ``kind`` is a unit of :data:`UNITS` (``dB``, ``dBm``, ``m``, ``Hz``, ``K``, ``bytes``, ``s``)
    or one of ``prob``, ``pct``, ``count``, ``num``, ``sci``, ``yesno``, ``vector``, ``expr``,
    ``interval``, ``signed``, ``text`` (default: :func:`text`). ``None`` prints an em dash
    (``yesno``: "not computed").
    """
    if kind in UNITS:
        return unit(value, kind)
    simple: dict[str, Callable[[Any], str]] = {
        "prob": prob, "pct": pct, "count": count, "num": num, "sci": sci, "yesno": yesno,
        "vector": vector, "expr": pretty_expr, "interval": interval, "signed": signed,
        "text": text}
    return simple.get(kind or "text", text)(value)


FILTERS: dict[str, Callable[..., str]] = {
    "num": num, "signed": signed, "interval": interval, "yesno": yesno,
    "pretty_expr": pretty_expr, "verdict_label": verdict_label, "pct": pct,
    "indices": indices, "short_hash": short_hash, "text": text, "key_label": key_label,
    "fixed": fixed, "sci": sci, "unit": unit, "prob": prob, "count": count, "vector": vector,
    "signed_plain": signed_plain, "quantity": quantity,
}


def register(env: jinja2.Environment) -> jinja2.Environment:
    """Register every report filter on ``env`` and return it."""
    env.filters.update(FILTERS)
    return env
