"""Formulas as inline SVG, rendered by matplotlib's mathtext (WeasyPrint has no MathML or JS).

A formula is LaTeX in the subset mathtext understands (``\\frac``, ``\\sqrt``, sub- and
superscripts, Greek letters, ``\\max``, ``\\bar`` ...). Glyphs are written as SVG paths, so the
result needs no font and no network; every SVG gets a fresh id prefix so that several of them can
live in one HTML document without clashing ``id``s.

Exact expressions from the record (``sympy.sstr`` text such as ``1 - 2**(-3)`` or ``sqrt(3)``) are
read back with the safe parser :func:`kfcrit.model.exprparse.parse_expression` (never ``sympify``) and
converted with ``sympy.latex``.
"""
from __future__ import annotations

import functools
import html
import io
import itertools
import re

import matplotlib

matplotlib.use("Agg")

from matplotlib.figure import Figure  # noqa: E402 - after choosing the backend

_PREFIX = itertools.count()
_IMAG_RE = re.compile(r"\bI\b")
_EULER_RE = re.compile(r"\b[eE]\b")
_ID_RE = re.compile(r'\bid="([^"]+)"')
_STRIP_RE = re.compile(r"<\?xml.*?\?>|<!DOCTYPE.*?>|<metadata>.*?</metadata>|<!--.*?-->"
                       r"|<style[^>]*>.*?</style>", re.DOTALL)
MATH_RC = {"mathtext.fontset": "dejavuserif", "svg.fonttype": "path", "svg.hashsalt": "kfcrit"}


def clean_svg(svg: str, *, label: str | None = None, css_class: str = "") -> str:
    """Make matplotlib's SVG document embeddable in HTML.

    Drops the XML declaration, DOCTYPE, metadata, comments and the global ``<style>`` (its
    ``*{...}`` rule would leak into the page; ``report.css`` has the equivalent scoped rule);
    prefixes every ``id`` (and each reference to it) with a fresh ``kN-`` so ids are unique in
    the page; adds ``role="img"``, an ``aria-label`` and a ``<title>`` (escaped) when
    ``label`` is given.
    """
    svg = _STRIP_RE.sub("", svg).strip()
    prefix = f"k{next(_PREFIX)}-"
    ids = set(_ID_RE.findall(svg))
    for old in sorted(ids, key=len, reverse=True):
        svg = svg.replace(f'id="{old}"', f'id="{prefix}{old}"')
        svg = svg.replace(f'"#{old}"', f'"#{prefix}{old}"')
        svg = svg.replace(f"url(#{old})", f"url(#{prefix}{old})")
    attrs = ' role="img"'
    if css_class:
        attrs += f' class="{html.escape(css_class)}"'
    if label:
        attrs += f' aria-label="{html.escape(label)}"'
    svg = svg.replace("<svg ", f"<svg{attrs} ", 1)
    if label:
        head_end = svg.index(">") + 1
        svg = svg[:head_end] + f"<title>{html.escape(label)}</title>" + svg[head_end:]
    return svg


@functools.lru_cache(maxsize=512)
def _mathtext_svg(latex: str, fontsize: float) -> str:
    """Raw SVG of ``$latex$`` (cached; raises ``ValueError`` if mathtext cannot parse it)."""
    with matplotlib.rc_context(MATH_RC):
        fig = Figure(figsize=(0.01, 0.01))
        fig.text(0, 0, f"${latex}$", fontsize=fontsize)
        buf = io.BytesIO()
        fig.savefig(buf, format="svg", bbox_inches="tight", pad_inches=0.02, transparent=True,
                    metadata={"Date": None, "Creator": None, "Format": None, "Type": None})
    return buf.getvalue().decode("utf-8")


def latex_svg(latex: str, *, fontsize: float = 11.0, label: str | None = None) -> str | None:
    """Inline SVG of a LaTeX formula, or ``None`` when mathtext cannot typeset it.

    Parameters
    ----------
    latex : str
        Formula without the surrounding ``$``, e.g. ``p_c = 1 - |\\lambda_1|^{-2}``.
    fontsize : float
        Point size of the formula.
    label : str, optional
        Plain-text reading of the formula (``aria-label`` and ``<title>``); defaults to the LaTeX.
    """
    if not latex or not latex.strip():
        return None
    try:
        raw = _mathtext_svg(latex.strip(), float(fontsize))
    except (ValueError, RuntimeError):
        return None
    return clean_svg(raw, label=label or latex, css_class="math")


def expression_latex(text: str) -> str | None:
    """LaTeX of an exact expression given as text (``sympy.sstr`` form), or ``None``.

    The text is read with the safe parser :func:`kfcrit.model.exprparse.parse_expression`, then typeset
    with ``sympy.latex``; anything the parser refuses gives ``None`` (the caller shows plain text).
    """
    import sympy as sp

    from kfcrit.errors import KfcritError
    from kfcrit.model.exprparse import parse_expression

    if not text or not isinstance(text, str):
        return None
    # Eigenvalues come as sympy text with the imaginary unit ``I``, a name the safe parser does
    # not know. When the text uses neither Euler's number nor exp/log (sympy writes exp(x) as
    # E**x), read ``I`` as ``E`` and swap the constant back afterwards (the parser stays the only
    # reader of record text).
    imaginary = bool(_IMAG_RE.search(text)) and not _EULER_RE.search(text) \
        and "exp" not in text and "log" not in text
    source = _IMAG_RE.sub("E", text) if imaginary else text
    try:
        value = parse_expression(source, "report")
        if imaginary:
            value = sp.expand(value.subs(sp.E, sp.I))
    except (KfcritError, ValueError, TypeError, RecursionError):
        return None
    return _mathtext_safe(sp.latex(value, imaginary_unit="i"))


def _mathtext_safe(latex: str) -> str:
    """Map the few sympy LaTeX commands mathtext lacks onto ones it has."""
    return (latex.replace(r"\left(", "(").replace(r"\right)", ")")
            .replace(r"\left|", "|").replace(r"\right|", "|")
            .replace(r"\left[", "[").replace(r"\right]", "]")
            .replace(r"\operatorname{", r"\mathrm{").replace(r"\cdot", r"\cdot"))


def is_plain(text: str) -> bool:
    """True when an expression reads well as plain text (an integer or a decimal)."""
    return bool(re.fullmatch(r"-?\d+(\.\d+)?", text.strip())) if text else True


def expression_svg(text: str, *, fontsize: float = 10.5) -> str | None:
    """Inline SVG of an exact expression's text (e.g. a matrix entry ``sqrt(3)``), or ``None``."""
    latex = expression_latex(text)
    return latex_svg(latex, fontsize=fontsize, label=text) if latex else None
