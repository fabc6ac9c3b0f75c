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
import markupsafe
from markupsafe import Markup

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
        if value != 0 and not SCI_LOW <= abs(value) < SCI_HIGH:
            return _sci_form(value, digits)
        return f"{value:.{digits}g}"
    return str(value)


def sig(value: Any, digits: int = 6) -> str:
    """A computed number to ``digits`` significant digits, trailing zeros kept (1.22140, so a
    rounding never reads as a shorter exact value); a float equal to a shorter decimal prints
    short (1, 0.5). Integers print in full; ``None`` or non-finite → em dash.

    .. math:: \\mathrm{sig}_d(x) = x \\text{ rounded to } d \\text{ significant digits}
    """
    if not isinstance(value, float) or not math.isfinite(value) or value == 0:
        return num(value, digits)
    short = num(value, digits)
    if value != 0 and not SCI_LOW <= abs(value) < SCI_HIGH:
        return short
    if float(f"{value:.{digits}g}") == value:
        return short
    return f"{value:#.{digits}g}".rstrip(".")


def span(low: Any, high: Any, digits: int = 6) -> str:
    """``a – b`` for a range; both ends in one style (scientific when either end needs it)."""
    ends = [v for v in (low, high) if _finite(v) and v != 0]
    if any(not SCI_LOW <= abs(v) < SCI_HIGH for v in ends):
        return " – ".join(_sci_form(v, digits) if _finite(v) and v != 0 else num(v, digits)
                          for v in (low, high))
    return f"{num(low, digits)} – {num(high, digits)}"


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
    (still autoescaped); the typeset form is the SVG from :mod:`kfcrit.views.figures.mathsvg`.
    """
    if text is None or text == "":
        return DASH
    s = str(text)
    s = _POW_RE.sub(lambda m: "^" + m.group(1), s)
    for _ in range(3):   # innermost square roots first: sqrt(3) → √3, sqrt(x + 1) → √(x + 1)
        s = _SQRT_RE.sub(_sqrt, s)
    s = s.replace("sqrt", "√").replace("*", "·")
    return s.replace("-", "−")


_SUP_MAP = str.maketrans("0123456789+-−()nijk", "⁰¹²³⁴⁵⁶⁷⁸⁹⁺⁻⁻⁽⁾ⁿⁱʲᵏ")
_SUB_MAP = str.maketrans("0123456789+-−()aehijklmnoprstuvx",
                         "₀₁₂₃₄₅₆₇₈₉₊₋₋₍₎ₐₑₕᵢⱼₖₗₘₙₒₚᵣₛₜᵤᵥₓ")
_SUP_OK = set("0123456789+-−()nijk")
_SUB_OK = set("0123456789+-−()aehijklmnoprstuvx")
_GREEK = {"lambda": "λ", "mu": "μ", "sigma": "σ", "Phi": "Φ", "phi": "φ", "pi": "π",
          "rho": "ρ", "Sigma": "Σ", "alpha": "α", "beta": "β", "gamma": "γ", "delta": "δ",
          "epsilon": "ε", "theta": "θ", "tau": "τ", "omega": "ω"}
_GREEK_RE = re.compile(r"\b(" + "|".join(_GREEK) + r")(?![A-Za-z0-9])")
_SQRT_RE = re.compile(r"\bsqrt\(([^()]*)\)")
_SIMPLE_RE = re.compile(r"[\w.]+")
_STAR_RE = re.compile(r"(?<=[\w)])\s?\*\s?(?=[\w(√])")
_POW_TEXT_RE = re.compile(r"\^\(([^()]+)\)|\^(-?\w+)")
_SUB_TEXT_RE = re.compile(r"(?<=[A-Za-zλμσ])_\(([^()]+)\)|(?<=[A-Za-zλμσ])_(\w)(?!\w)")


def _sup(m: re.Match) -> str:
    body = m.group(1) if m.group(1) is not None else m.group(2)
    if all(c in _SUP_OK for c in body.replace(" ", "")):
        return body.replace(" ", "").translate(_SUP_MAP)
    return m.group(0)


def _sub(m: re.Match) -> str:
    body = m.group(1) if m.group(1) is not None else m.group(2)
    if all(c in _SUB_OK for c in body.replace(" ", "")):
        return body.replace(" ", "").translate(_SUB_MAP)
    return m.group(0)


def _sqrt(m: re.Match) -> str:
    inner = m.group(1).strip()
    return "√" + inner if _SIMPLE_RE.fullmatch(inner) else f"√({inner})"


_EXP_TEXT_RE = re.compile(r"(?<![\w.])-?\d+(?:\.(\d+))?e[-+]?\d+(?![\w.])")


def _exp_number(m: re.Match) -> str:
    digits = min(len(m.group(1) or "") + 1, 3)
    return sci(float(m.group(0)), digits)


_BAR_RE = re.compile(r"\b([SVPX])_bar\b")
_MODULE_RE = re.compile(r"\bkfcrit(?:\.[a-z_]+)+\b")
_ERROR_NAMES = {"LinAlgError": "a linear-algebra failure",
                "FloatingPointError": "a floating-point failure",
                "ZeroDivisionError": "a division by zero", "OverflowError": "an overflow"}
_ERROR_RE = re.compile(r"\b(" + "|".join(_ERROR_NAMES) + r")\b(?::\s*)?")


def plain_names(text: str) -> str:
    """Record prose without program names: ``S_bar`` → S̄, a module path
    (``proof in kfcrit.theory.links.network``) → kfcrit's own proof, an exception class name
    (``LinAlgError``) → what failed, a record key in backticks (``in `network` ``) → the section
    of that name."""
    s = _BAR_RE.sub(lambda m: m.group(1) + "\u0304", text)
    s = re.sub(r"\bproof in kfcrit(?:\.[a-z_]+)+\b", "kfcrit's own proof", s)
    s = _MODULE_RE.sub("kfcrit", s)
    s = _ERROR_RE.sub(lambda m: _ERROR_NAMES[m.group(1)] + (": " if ":" in m.group(0) else ""),
                      s)
    s = re.sub(r"\bin `(\w+)`", lambda m: f"in the {m.group(1).replace('_', ' ')} section", s)
    return re.sub(r"`([^`\n]{1,60})`", r"\1", s)


def pretty_text(text: Any) -> str:
    """Prose of the record with its ASCII mathematics in Unicode notation.

    For sentences that embed formulas in ``sympy`` or plain-ASCII spelling (``|1 + sqrt(3)*I|``,
    ``QQ(sqrt(3))``, ``f0(X) = 2*X + 1``, ``S_(n-1)``, ``p <= p_up``, ``(1 - r) a^2``): √, the
    imaginary unit i, ℚ, f₀ / f₁, sub- and superscripts (where Unicode has the glyphs), ≤ ≥ ≠,
    Greek letter names, ∞ for ``inf``, · for products and − for a binary minus. Words joined by
    hyphens (Kar-Sinopoli-Moura) and identifiers such as ``p_up`` or ``max_outage`` are kept.
    ``None`` prints as an empty string.
    """
    if text is None:
        return ""
    s = plain_names(str(text))
    s = _EXP_TEXT_RE.sub(_exp_number, s)                    # 3.19e+10 → 3.19 × 10¹⁰
    s = s.replace("**", "^")
    for _ in range(3):   # innermost square roots first
        s = _SQRT_RE.sub(_sqrt, s)
    # sympy's imaginary unit: sqrt(3)*I → i√3, 2*I → 2i
    s = re.sub(r"(√\(?[\w./]+\)?)\*I\b", r"i\1", s)
    s = re.sub(r"(?<=[\w)])\*I\b", "i", s)
    s = re.sub(r"\bQQ\b", "ℚ", s)
    s = re.sub(r"\bf([01])(?=[(^\s])", lambda m: "f" + m.group(1).translate(_SUB_MAP), s)
    s = re.sub(r"(?<=[(\s=])inf(?=[)\s,;]|$)", "∞", s)
    s = _GREEK_RE.sub(lambda m: _GREEK[m.group(1)], s)
    s = s.replace("<=", "≤").replace(">=", "≥").replace("!=", "≠")
    s = re.sub(r"(?<=[\s(\[=≤≥<>])-(?=[\w(√.])", "−", s)     # unary minus
    s = re.sub(r"(?<=\s)-(?=\s)", "−", s)                      # binary minus
    s = _SUB_TEXT_RE.sub(_sub, s)
    s = _POW_TEXT_RE.sub(_sup, s)
    s = re.sub(r"(?<![/\d.])(\d+)\*(?=[A-Za-z(√])", r"\1", s)   # 2*X → 2X
    s = _STAR_RE.sub("·", s)
    return s


_CARET_RE = re.compile(r"\^(\([^()]{1,40}\)|[\w\u2080-\u209c\u2212+\-]{1,12})")


def supmath(text: Any) -> Markup:
    """Record prose (:func:`pretty_text`) as HTML, with each exponent Unicode has no glyph for
    (``E[Pₖ^q]``, ``|λ₁|^(−2q)``) set as ``<sup>`` instead of a literal caret; everything else
    is escaped."""
    escaped = str(markupsafe.escape(pretty_text(text)))

    def sup(m: re.Match[str]) -> str:
        body = m.group(1)
        if body.startswith("(") and body.endswith(")"):
            body = body[1:-1]
        return f"<sup>{body}</sup>"

    return Markup(_SYMBOL_RE.sub(_symbol, _CARET_RE.sub(sup, escaped)))


# The theory's named symbols, set with a real subscript in HTML prose (p_c → p<sub>c</sub>).
# Other identifiers with underscores (file keys such as max_outage) are kept as written.
_SYMBOL_RE = re.compile(r"\b([pPrCI])_(c|up|low|S|V|t|k|I|o|link|nec|suf|stab)\b")


def _symbol(m: re.Match[str]) -> str:
    return f"{m.group(1)}<sub>{m.group(2)}</sub>"


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
    numbers with 10⁻⁴ ≤ |x| < 10⁵ (and exact zero) print plainly, as in :func:`num`."""
    if not _finite(value):
        return DASH
    if value == 0:
        return "0"
    if SCI_LOW <= abs(value) < SCI_HIGH:
        return num(float(value), digits).replace("-", "−")
    return _sci_form(value, digits)


# The range printed plainly by num and sci; outside it both use "m × 10ⁿ".
SCI_LOW, SCI_HIGH = 1e-4, 1e5


def _sci_form(value: float, digits: int) -> str:
    """``m × 10ⁿ`` with ``digits`` significant digits in the mantissa (trailing zeros dropped)."""
    mant, exp = f"{value:.{max(digits, 1) - 1}e}".split("e")
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
        return _sci_form(value, 3)
    return num(float(value), digits)


def count(value: Any) -> str:
    """An integer count with thin-space thousands separators (``50000`` → ``50 000``)."""
    if not _finite(value):
        return DASH
    return f"{int(value):,}".replace(",", "\u202f")


def counted(n: int, noun: str) -> str:
    """``n`` and the noun, plural unless n is 1 (``1 sensor``, ``3 sensors``, ``0 errors``)."""
    return f"{n} {noun}" + ("" if n == 1 else "s")


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
    "signed_plain": signed_plain, "quantity": quantity, "pretty_text": pretty_text,
    "span": span, "supmath": supmath, "sig": sig,
}


def register(env: jinja2.Environment) -> jinja2.Environment:
    """Register every report filter on ``env`` and return it."""
    env.filters.update(FILTERS)
    return env
