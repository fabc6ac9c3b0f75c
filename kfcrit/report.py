"""Design-review reports: one Jinja template set, two outputs (self-contained HTML and PDF).

The analysis record (``Analysis.to_dict()``) plus its figures (:mod:`kfcrit.figures`) is the only
input. :func:`view_model` turns them into one plain dict holding every key the templates read
(missing sections become ``available: False`` with a "not computed" message, never a missing key:
the environment uses ``StrictUndefined``). Templates only lay the view model out; numbers are
formatted by the registered filters of :mod:`kfcrit.filters`; formulas are SVG from
:mod:`kfcrit.mathsvg`. The PDF is the same HTML printed by WeasyPrint with the print stylesheet
(``@media print`` / ``@page`` in ``report.css``), with a URL fetcher that refuses every external
URL. Files are written atomically and never over the input file.
"""
from __future__ import annotations

import os
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import jinja2
from markupsafe import Markup

from . import __version__, filters, mathsvg
from .atomic import write_atomic
from .errors import InputError

FORMATS = {".html": "html", ".htm": "html", ".pdf": "pdf"}
TEMPLATE = "report.html.j2"
NOT_COMPUTED = "not computed"


# --------------------------------------------------------------------------- templates

def template_dir() -> Path:
    """Folder of the report templates.

    In an installed wheel they live in ``kfcrit/templates`` (hatchling ``force-include``); after
    ``pip install -e .`` or in a source checkout they are the repository's top-level
    ``templates/``.
    """
    here = Path(__file__).resolve().parent
    for candidate in (here / "templates", here.parent / "templates"):
        if (candidate / TEMPLATE).is_file():
            return candidate
    raise FileNotFoundError(f"report templates not found next to {here} (looked for "
                            f"kfcrit/templates/{TEMPLATE} and templates/{TEMPLATE})")


def environment() -> jinja2.Environment:
    """The Jinja environment: autoescape for ``.html``/``.html.j2``, ``StrictUndefined``."""
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(template_dir())),
        autoescape=jinja2.select_autoescape(("html", "html.j2")),
        undefined=jinja2.StrictUndefined,
        trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True)
    return filters.register(env)


# --------------------------------------------------------------------------- view model helpers

def _dict(value: Any) -> dict[str, Any]:
    return value if isinstance(value, dict) else {}


def _list(value: Any) -> list[Any]:
    return value if isinstance(value, list) else []


def _num(value: Any) -> float | None:
    """A real number or ``None`` (bools and text are not numbers here)."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return value
    return None


def _svg(svg: str | None) -> Markup | None:
    """Mark an SVG that *we* generated (matplotlib output, ids rewritten) as safe HTML."""
    return Markup(svg) if svg else None


def _missing(section: str, reason: str | None = None) -> str:
    return f"{section}: {NOT_COMPUTED}" + (f" ({reason})" if reason else "")


def kv_rows(data: Any, skip: Iterable[str] = ()) -> list[dict[str, Any]]:
    """Rows ``{key, value}`` of a mapping's entries, for generic tables (nothing disappears)."""
    skipped = set(skip)
    return [{"key": str(k), "value": v} for k, v in _dict(data).items() if k not in skipped]


def formula(latex: str | None, expression: str | None, *, fontsize: float = 11.0,
            label: str | None = None) -> Markup | None:
    """Typeset a record formula: its LaTeX if mathtext can set it, else its exact expression."""
    svg = mathsvg.latex_svg(latex, fontsize=fontsize, label=label) if latex else None
    if svg is None and expression:
        svg = mathsvg.expression_svg(expression, fontsize=fontsize)
    return _svg(svg)


# Which theorem decides the critical value, by classification (first match wins, in order).
THEOREMS: tuple[tuple[str, str, str, str], ...] = (
    ("non-degenerate", "Mo–Sinopoli, Theorem 4",
     r"p_c = \max\,(1 - |\lambda_1|^{-2},\ 0)",
     "Every unstable or critically stable equi-block is one-step observable, so the critical "
     "value is the Sinopoli lower bound of the largest eigenvalue modulus."),
    ("second-order", "Mo–Sinopoli, Theorem 5 (Theorems 9 and 10)",
     r"p_c = \max\,(1 - |\lambda_1|^{-2/(1 - D_M(\varphi/2\pi))},\ 0)",
     "A degenerate second-order equi-block with λ₂ = λ₁·exp(jφ); D_M(x) = 1/q when x = r/q in "
     "lowest terms and 0 when x is irrational."),
    ("degenerate", "Mo–Sinopoli, Theorem 3, with Sinopoli et al., Theorem 5",
     r"\max_I\ p_c(A_I, C_I)\ \leq\ p_c\ \leq\ p_{up}",
     "A degenerate equi-block beyond second order has no closed form in the papers: the "
     "critical value is bracketed by the known block values and the LMI upper bound."),
    ("single", "Sinopoli et al., Theorem 3 (one unstable eigenvalue)",
     r"p_c = p_{low} = 1 - |\lambda_1|^{-2}",
     "With a single unstable eigenvalue the lower and upper bounds coincide."),
    ("stable", "Sinopoli et al., Theorem 3",
     r"p_c = 0 \quad \mathrm{when}\ \max_i |\lambda_i| \leq 1",
     "No unstable eigenvalue: the expected error covariance is bounded for every p > 0."),
)
FALLBACK_THEOREM = ("Sinopoli et al., Theorems 3 and 5",
                    r"1 - \max_i|\lambda_i|^{-2}\ \leq\ p_c\ \leq\ p_{up}",
                    "The general bounds: the closed-form lower bound and the LMI upper bound.")


def theorem_for(classification: str | None) -> tuple[str, str, str]:
    """(theorem, LaTeX of its formula, one-sentence explanation) deciding ``classification``."""
    key = (classification or "").lower()
    for needle, name, latex, why in THEOREMS:
        if needle in key:
            return name, latex, why
    return FALLBACK_THEOREM


# --------------------------------------------------------------------------- view model sections

def verdict_view(rec: dict[str, Any]) -> dict[str, Any]:
    """The verdict box: operating p against p_c, margins, robust value, bracket, verdict."""
    op = rec.get("operating_point")
    cv = _dict(rec.get("critical_value"))
    rob = rec.get("robust_critical_value")
    robd = _dict(rob)
    channel = _dict(_dict(op).get("channel")) or _dict(_dict(rec.get("system")).get("channel"))
    verdict = _dict(op).get("verdict") if isinstance(op, dict) else None
    css = {"mean-stable": "stable", "mean-unstable": "unstable",
           "undetermined": "undetermined"}.get(str(verdict), "unknown")
    return {
        "available": isinstance(op, dict),
        "missing": _missing("operating point", "the system file has no channel section")
        if op is None else "",
        "verdict": verdict, "css": css,
        "p": _num(_dict(op).get("arrival_probability")),
        "p_expression": channel.get("arrival_probability_expression"),
        "channel_model": channel.get("model"),
        "channel_rows": kv_rows({k: v for k, v in channel.items()
                                 if not isinstance(v, (dict, list))},
                                skip=("model", "arrival_probability",
                                      "arrival_probability_expression")),
        "critical_value": _num(cv.get("value")),
        "critical_expression": cv.get("expression"),
        "critical_svg": formula(cv.get("latex"), cv.get("expression"), fontsize=13,
                                label=cv.get("expression")),
        "critical_exact": cv.get("exact"),
        "critical_reason": cv.get("reason"),
        "margin": _num(_dict(op).get("margin")),
        "margin_robust": _num(_dict(op).get("margin_robust")),
        "robust": {"available": isinstance(rob, dict),
                   "value": _num(robd.get("value")), "tolerance": _num(robd.get("tolerance")),
                   "expression": robd.get("expression"),
                   "nearby_case": robd.get("nearby_case")},
        "bracket": _dict(op).get("bracket") if isinstance(_dict(op).get("bracket"), list)
        else None,
        "margin_to_bracket": _dict(op).get("margin_to_bracket")
        if isinstance(_dict(op).get("margin_to_bracket"), list) else None,
        "note": _dict(op).get("note"),
        "requirement": requirement_view(rec),
    }


def requirement_view(rec: dict[str, Any]) -> dict[str, Any]:
    """The system file's requirements against the simulated tail probability at p."""
    req = _dict(rec.get("requirements"))
    limit = _num(req.get("max_error_trace"))
    max_tail = _num(req.get("max_tail_probability"))
    from .figures import tail_of

    tail = tail_of(rec)
    met = None
    if limit is not None and max_tail is not None and tail is not None:
        met = tail <= max_tail
    return {"available": limit is not None, "limit": limit, "max_tail": max_tail,
            "tail": tail, "met": met,
            "missing": "" if limit is not None else
            "no requirement in the system file (add requirements: max_error_trace, "
            "max_tail_probability)"}


def matrices_view(system: dict[str, Any]) -> list[dict[str, Any]]:
    """Exact matrices as rows of cells ``{text, svg}`` (svg for entries that are not plain)."""
    out = []
    for name, rows in _dict(system.get("matrices")).items():
        if not isinstance(rows, list):
            continue
        cells = [[{"text": str(e),
                   "svg": None if mathsvg.is_plain(str(e))
                   else _svg(mathsvg.expression_svg(str(e)))} for e in _list(row)]
                 for row in rows]
        label = {"Sigma0": "Σ₀"}.get(name, name)
        out.append({"name": label, "rows": cells})
    return out


def system_view(rec: dict[str, Any]) -> dict[str, Any]:
    """Sizes, exactness, exact matrices and channel."""
    sysd = rec.get("system")
    d = _dict(sysd)
    return {"available": isinstance(sysd, dict), "missing": _missing("system"),
            "n": d.get("n"), "m": d.get("m"), "exact_input": d.get("exact_input"),
            "matrices": matrices_view(d)}


def structure_view(rec: dict[str, Any]) -> dict[str, Any]:
    """Eigenvalues with moduli, equi-blocks, and the structural flags."""
    st = rec.get("structure")
    d = _dict(st)
    eigs = []
    for e in _list(d.get("eigenvalues")):
        e = _dict(e)
        expr = e.get("modulus_expression")
        eigs.append({"value": e.get("value"), "re": _num(e.get("re")), "im": _num(e.get("im")),
                     "modulus": _num(e.get("modulus")), "modulus_expression": expr,
                     "modulus_svg": _svg(mathsvg.expression_svg(expr))
                     if isinstance(expr, str) and not mathsvg.is_plain(expr) else None})
    blocks = [{"indices": _dict(b).get("indices"), "modulus": _num(_dict(b).get("modulus")),
               "one_step_observable": _dict(b).get("one_step_observable"),
               "rank": _dict(b).get("rank")} for b in _list(d.get("equi_blocks"))]
    flags = [{"label": label, "value": d.get(key)} for key, label in (
        ("diagonalizable", "A diagonalizable"), ("detectable", "(A, C) detectable"),
        ("controllable_Q", "(A, Q^½) controllable"))]
    known = {"eigenvalues", "equi_blocks", "diagonalizable", "detectable", "controllable_Q"}
    return {"available": isinstance(st, dict), "missing": _missing("structure analysis"),
            "eigenvalues": eigs, "equi_blocks": blocks, "flags": flags,
            "path": d.get("path"), "extra": kv_rows(d, skip=known | {"path"})}


def classification_view(rec: dict[str, Any]) -> dict[str, Any]:
    """The classification, the theorem that decides it and its formula (typeset)."""
    cls = rec.get("classification")
    cv = _dict(rec.get("critical_value"))
    name, latex, why = theorem_for(cls if isinstance(cls, str) else None)
    return {"available": isinstance(cls, str) and bool(cls),
            "missing": _missing("classification", cv.get("reason")),
            "name": cls, "theorem": name, "why": why, "general_latex": latex,
            "general_svg": _svg(mathsvg.latex_svg(latex, fontsize=12)),
            "instance_svg": formula(cv.get("latex"), cv.get("expression"), fontsize=12,
                                    label=cv.get("expression")),
            "instance_expression": cv.get("expression"), "value": _num(cv.get("value")),
            "reason": cv.get("reason"), "exact": cv.get("exact")}


def bounds_view(rec: dict[str, Any]) -> dict[str, Any]:
    """Rows of the bounds table and the higher-moment thresholds."""
    lb, blb = rec.get("lower_bound"), rec.get("block_lower_bound")
    cv, rob, ub = rec.get("critical_value"), rec.get("robust_critical_value"), \
        rec.get("upper_bound")
    ubd = _dict(ub)
    rows = [
        {"symbol": "p_low", "name": "lower bound", "available": isinstance(lb, dict),
         "value": _num(_dict(lb).get("value")), "expression": _dict(lb).get("expression"),
         "detail": "1 − 1/max|λᵢ|²", "source": "Sinopoli et al., Theorem 3"},
        {"symbol": "p_block", "name": "block lower bound", "available": isinstance(blb, dict),
         "value": _num(_dict(blb).get("value")), "expression": _dict(blb).get("expression"),
         "detail": "largest critical value of a block", "source": "Mo–Sinopoli, Theorem 3"},
        {"symbol": "p_c", "name": "critical value",
         "available": _num(_dict(cv).get("value")) is not None,
         "value": _num(_dict(cv).get("value")), "expression": _dict(cv).get("expression"),
         "detail": ("exact" if _dict(cv).get("exact") else
                    "numerical" if _dict(cv).get("exact") is False else "")
         + (f"; {_dict(cv).get('reason')}" if _dict(cv).get("reason") else ""),
         "source": theorem_for(rec.get("classification")
                               if isinstance(rec.get("classification"), str) else None)[0]},
        {"symbol": "p_c,robust", "name": "robust critical value",
         "available": isinstance(rob, dict),
         "value": _num(_dict(rob).get("value")), "expression": _dict(rob).get("expression"),
         "detail": _robust_detail(_dict(rob)),
         "source": "largest p_c within the stated relative perturbation"},
        {"symbol": "p_up", "name": "upper bound", "available": isinstance(ub, dict),
         "value": _num(ubd.get("value")), "expression": None,
         "detail": _upper_detail(ubd), "source": "Sinopoli et al., Theorem 5 (LMI)"},
    ]
    th = _dict(rec.get("theory"))
    moments = [{"q": _dict(m).get("q"), "value": _num(_dict(m).get("value")),
                "expression": _dict(m).get("expression"), "applies": _dict(m).get("applies")}
               for m in _list(th.get("moment_thresholds"))]
    sg = rec.get("static_gain")
    return {"rows": rows, "moments": moments,
            "static_gain": {"available": isinstance(sg, dict),
                            "rows": kv_rows({k: v for k, v in _dict(sg).items()
                                             if not _is_series(v)})},
            "moments_available": bool(moments),
            "moments_missing": _missing("higher-moment thresholds")}


def _robust_detail(rob: dict[str, Any]) -> str:
    parts = []
    if _num(rob.get("tolerance")) is not None:
        parts.append(f"relative tolerance {filters.num(rob['tolerance'], 3)}")
    if rob.get("nearby_case"):
        parts.append(f"nearby case: {filters.text(rob['nearby_case'])}")
    return "; ".join(parts)


def _upper_detail(ub: dict[str, Any]) -> str:
    parts = []
    if isinstance(ub.get("interval"), list):
        parts.append(f"in {filters.interval(ub['interval'], 8)}")
    if ub.get("certified") is not None:
        parts.append("certified" if ub["certified"] else "not certified")
    for key in ("status", "method"):
        if ub.get(key):
            parts.append(f"{key} {ub[key]}")
    return "; ".join(parts)


def covariance_view(rec: dict[str, Any]) -> dict[str, Any]:
    """S̄ and V̄ at the operating point (Sinopoli Theorems 4 and 6)."""
    cb = rec.get("covariance_bounds")
    d = _dict(cb)

    def side(x: Any) -> dict[str, Any]:
        x = _dict(x)
        return {"exists": x.get("exists"), "trace": _num(x.get("trace")),
                "max_eig": _num(x.get("max_eig")), "residual": _num(x.get("residual")),
                "method": x.get("method")}

    return {"available": isinstance(cb, dict), "missing": _missing("covariance bounds"),
            "p": _num(d.get("p")), "lower": side(d.get("lower")), "upper": side(d.get("upper"))}


FIGURE_CAPTIONS = {
    "phase_transition": ("Phase transition",
                         "Trace of the lower bound S̄ and the upper bound V̄ of lim E[P_t] "
                         "against the arrival probability p (log scale), with p_low, p_c, p_up "
                         "and the operating point marked. Below p_c the expected error "
                         "covariance diverges."),
    "traces": ("Simulated error traces around the critical value",
               "Mean trace of P_t over simulated loss sequences for p just below and just above "
               "the critical value."),
    "operating": ("Simulated mean covariance at the operating point",
                  "Mean trace of P_t over simulated paths at the operating p, with its band, "
                  "against tr S̄ and tr V̄."),
    "cdf": ("Distribution of tr P at the operating point",
            "Empirical CDF of the error covariance trace at the operating p (time averages along "
            "paths; ergodic by Kar–Sinopoli–Moura, Prop. 25)."),
    "invariant": ("Support of the invariant distribution",
                  "Support of the invariant distribution of P_t (Kar–Sinopoli–Moura, Theorem "
                  "10): points reached from P* by finite compositions of f₀ and f₁, and the "
                  "empty intervals that carry no mass."),
}


def figures_view(figures: dict[str, str | None]) -> dict[str, dict[str, Any]]:
    """Each figure with its title, caption and "not computed" message."""
    out = {}
    for key, (title, caption) in FIGURE_CAPTIONS.items():
        svg = figures.get(key) if isinstance(figures, dict) else None
        out[key] = {"svg": _svg(svg), "title": title, "caption": caption,
                    "missing": _missing(title.lower())}
    return out


def simulation_view(rec: dict[str, Any]) -> dict[str, Any]:
    """Summary numbers of the simulation (arrays are drawn, not tabulated)."""
    sim = rec.get("simulation")
    d = _dict(sim)
    from .figures import tail_of

    op = _dict(d.get("operating_point"))
    scalars = {k: v for k, v in op.items()
               if not isinstance(v, (list, dict)) and k != "tail_probability"}
    top = {k: v for k, v in d.items()
           if k not in ("operating_point", "phase_demo", "checks", "warnings")
           and not _is_series(v)}
    return {"available": isinstance(sim, dict), "missing": _missing("simulation"),
            "tail_probability": tail_of(rec),
            "rows": kv_rows(top) + kv_rows(scalars)}


def _is_series(value: Any) -> bool:
    return isinstance(value, list) and len(value) > 12


def statements_view(rec: dict[str, Any]) -> dict[str, Any]:
    """Almost-sure and distributional statements (MATH §5–6) in plain words."""
    th = rec.get("theory")
    d = _dict(th)
    sb = d.get("stochastic_boundedness")
    asure = d.get("almost_sure")
    sentences = [str(s) for s in asure] if isinstance(asure, list) else \
        ([str(asure)] if isinstance(asure, str) and asure else [])
    return {"available": bool(sb) or bool(sentences),
            "missing": _missing("almost-sure and distributional statements"),
            "stochastic_boundedness": [str(s) for s in sb] if isinstance(sb, list) else
            ([str(sb)] if sb else []),
            "almost_sure": sentences,
            "extra": kv_rows(d, skip=("stochastic_boundedness", "almost_sure",
                                      "moment_thresholds"))}


def invariant_view(rec: dict[str, Any], figure: str | None) -> dict[str, Any]:
    """Support of the invariant distribution (scalar systems only)."""
    n = _dict(rec.get("system")).get("n")
    inv = rec.get("invariant")
    d = _dict(inv)
    from .figures import invariant_gaps

    gaps = invariant_gaps(d)
    return {"applies": n == 1, "available": isinstance(inv, dict),
            "missing": _missing("invariant distribution support"),
            "gaps": gaps[:8], "more_gaps": max(0, len(gaps) - 8),
            "rows": kv_rows({k: v for k, v in d.items() if not _is_series(v)},
                            skip=("gaps", "support_points", "gap_levels", "holes"))}


def appendix_view(rec: dict[str, Any]) -> dict[str, Any]:
    """Verification appendix: certificates and cross-checks, tolerances, versions, seeds, hash."""
    ub = _dict(rec.get("upper_bound"))
    cv = _dict(rec.get("critical_value"))
    rob = _dict(rec.get("robust_critical_value"))
    cb = _dict(rec.get("covariance_bounds"))
    prov = _dict(rec.get("provenance"))
    sim = _dict(rec.get("simulation"))
    recorded = [{"name": str(_dict(c).get("check") or ""), "status": _dict(c).get("passed"),
                 "detail": filters.text(_dict(c).get("detail"))
                 if _dict(c).get("detail") is not None else ""}
                for c in _list(rec.get("verification"))]
    derived = [
        {"name": "critical value decided exactly", "status": cv.get("exact"),
         "detail": cv.get("reason") or ""},
        {"name": "upper bound certificate re-checked", "status": ub.get("certified"),
         "detail": filters.text(ub.get("certificate")) if ub.get("certificate") else ""},
        {"name": "upper bound bracket (lower evidence)",
         "status": None if ub.get("lower_evidence") is None else bool(ub.get("lower_evidence")),
         "detail": filters.text(ub.get("lower_evidence")) if ub.get("lower_evidence") else ""},
        {"name": "upper covariance bound V̄ solves the MARE",
         "status": _dict(cb.get("upper")).get("exists"),
         "detail": f"residual {filters.num(_dict(cb.get('upper')).get('residual'), 3)}"
         if _num(_dict(cb.get("upper")).get("residual")) is not None else ""},
        {"name": "lower covariance bound S̄ exists (Lyapunov)",
         "status": _dict(cb.get("lower")).get("exists"), "detail": ""},
    ]
    # The record's own verification list when the analysis provides one; else what the
    # sections' flags say (read, not recomputed).
    checks = recorded + derived[:1] if recorded else derived
    opts = _dict(prov.get("options"))
    tolerances = {"robust tolerance": rob.get("tolerance", opts.get("tolerance")),
                  "upper-bound tolerance": opts.get("upper_tol"),
                  "upper-bound solver": ub.get("solver"), "upper-bound method": ub.get("method")}
    seeds = sim.get("seeds") if sim.get("seeds") is not None else prov.get("seed")
    versions = dict(_dict(prov.get("versions")))
    versions.setdefault("kfcrit (report)", __version__)
    return {"checks": checks,
            "tolerances": [{"key": k, "value": v} for k, v in tolerances.items()],
            "upper_warnings": [str(w) for w in _list(ub.get("warnings"))],
            "versions": kv_rows(versions), "seeds": seeds,
            "sha256": prov.get("input_sha256"), "input_path": prov.get("input_path"),
            "options": kv_rows(opts)}


def view_model(record: dict[str, Any], figures: dict[str, str | None]) -> dict[str, Any]:
    """Every value the templates read, from the record and the figures (no computation left).

    Parameters
    ----------
    record : dict
        ``Analysis.to_dict()`` (any section may be ``None`` or absent).
    figures : dict
        Inline SVG strings from :func:`kfcrit.figures.build_figures` (``None`` where missing).
    """
    rec = _dict(record)
    prov = _dict(rec.get("provenance"))
    name = rec.get("name") or "unnamed system"
    return {
        "meta": {"title": f"Design review: {name}", "name": name,
                 "description": rec.get("description") or "",
                 "quick": bool(_dict(prov.get("options")).get("quick")),
                 "input_path": prov.get("input_path"), "version": __version__},
        "verdict": verdict_view(rec),
        "warnings": [str(w) for w in _list(rec.get("warnings"))],
        "system": system_view(rec),
        "structure": structure_view(rec),
        "classification": classification_view(rec),
        "bounds": bounds_view(rec),
        "covariance": covariance_view(rec),
        "figures": figures_view(figures),
        "simulation": simulation_view(rec),
        "requirement": requirement_view(rec),
        "statements": statements_view(rec),
        "invariant": invariant_view(rec, _dict(figures).get("invariant")),
        "link_budget": {"available": isinstance(rec.get("link_budget"), dict),
                        "missing": _missing("link budget"),
                        "rows": kv_rows(rec.get("link_budget"))},
        "appendix": appendix_view(rec),
    }


# --------------------------------------------------------------------------- rendering

def render_html(record: dict[str, Any], figures: dict[str, str | None]) -> str:
    """The self-contained HTML report (inline CSS and SVG, no scripts, no external URLs)."""
    template = environment().get_template(TEMPLATE)
    return template.render(**view_model(record, figures))


def _refusing_fetcher() -> Any:
    """A WeasyPrint URL fetcher that serves ``data:`` URLs only and refuses everything else."""
    import weasyprint

    if hasattr(weasyprint, "URLFetcher"):  # WeasyPrint >= 68
        return weasyprint.URLFetcher(allowed_protocols={"data"})

    def fetch(url: str, *args: Any, **kwargs: Any) -> Any:  # pragma: no cover - old WeasyPrint
        if not url.startswith("data:"):
            raise ValueError(f"external URL refused: {url[:80]}")
        return weasyprint.default_url_fetcher(url, *args, **kwargs)

    return fetch


def render_pdf(html: str) -> bytes:
    """Print the HTML report to PDF with WeasyPrint (print stylesheet; no external fetches)."""
    try:
        import weasyprint
    except ImportError:  # pragma: no cover - optional dependency
        raise InputError("PDF output needs WeasyPrint (pip install 'kfcrit[pdf]')",
                         field="format") from None
    doc = weasyprint.HTML(string=html, base_url=None, url_fetcher=_refusing_fetcher())
    return doc.write_pdf()


def output_format(output: str | Path, fmt: str | None) -> str:
    """``html`` or ``pdf``: ``fmt`` if given, else from the extension (InputError otherwise)."""
    if fmt is not None:
        if fmt not in ("html", "pdf"):
            raise InputError("must be html or pdf", field="format")
        return fmt
    ext = Path(output).suffix.lower()
    if ext not in FORMATS:
        raise InputError(f"cannot tell the format from the extension {ext or '(none)'!r}; use "
                         ".html or .pdf, or give --format", field="output")
    return FORMATS[ext]


def check_output_path(system_file: str | Path, output: str | Path) -> Path:
    """The output path, refused if it is the input file, a folder, or in a missing folder."""
    out = Path(output)
    if out.exists() and out.is_dir():
        raise InputError(f"{str(out)[:80]!r} is a directory", field="output")
    src = Path(system_file)
    same = out.resolve() == src.resolve()
    if not same and out.exists() and src.exists():
        same = os.path.samefile(out, src)
    if same:
        raise InputError("refusing to overwrite the input file", field="output")
    if not out.resolve().parent.is_dir():
        raise InputError(f"folder {str(out.parent)[:80]!r} does not exist", field="output")
    return out


def _progress(message: str) -> None:
    print(f"kfcrit: {message}", file=sys.stderr, flush=True)


def report_command(system_file: str, output: str, *, fmt: str | None, quick: bool, seed: int,
                   max_states: int) -> int:
    """``kfcrit report``: analyse ``system_file`` and write the HTML or PDF report to ``output``.

    Returns the exit code (:func:`kfcrit.cli.exit_code_of` of the record: 3 when the upper bound
    was inconclusive, else 0). Bad paths or formats raise :class:`~kfcrit.errors.InputError`.
    """
    from .analysis import AnalysisOptions, analyze
    from .cli import exit_code_of
    from .figures import build_figures
    from .systemfile import load_spec

    kind = output_format(output, fmt)
    out = check_output_path(system_file, output)
    _progress(f"reading {system_file}")
    spec = load_spec(system_file, max_states=max_states)
    _progress("analysing" + (" (quick draft)" if quick else ""))
    record = analyze(spec, AnalysisOptions(quick=quick, seed=seed)).to_dict()
    _progress("drawing figures")
    figures = build_figures(record)
    _progress(f"rendering {kind.upper()}")
    html = render_html(record, figures)
    data = render_pdf(html) if kind == "pdf" else html.encode("utf-8")
    write_atomic(out, data)
    _progress(f"wrote {out} ({len(data)} bytes)")
    return exit_code_of(record)
