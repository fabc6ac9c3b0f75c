"""Design-review reports: one Jinja template set, two outputs (self-contained HTML and PDF).

The analysis record (``Analysis.to_dict()``) plus its figures (:mod:`kfcrit.views.figures`) is the only
input. :func:`view_model` turns them into one plain dict holding every key the templates read
(missing sections become ``available: False`` with a "not computed" message, never a missing key:
the environment uses ``StrictUndefined``). Templates only lay the view model out; numbers are
formatted by the registered filters of :mod:`kfcrit.views.jinja_filters`; formulas are SVG from
:mod:`kfcrit.views.mathsvg`. The PDF is the same HTML printed by WeasyPrint with the print stylesheet
(``@media print`` / ``@page`` in ``report.css``), with a URL fetcher that refuses every external
URL. Files are written atomically and never over the input file.
"""
from __future__ import annotations

import functools
import os
import re
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import jinja2
from markupsafe import Markup

from kfcrit.version import __version__
from kfcrit.views import jinja_filters as filters
from kfcrit.views import mathsvg
from kfcrit.io.atomic import write_atomic
from kfcrit.errors import InputError

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
    package = Path(__file__).resolve().parents[1]
    for candidate in (package / "templates", package.parent / "templates"):
        if (candidate / TEMPLATE).is_file():
            return candidate
    raise FileNotFoundError(f"report templates not found next to {package} (looked for "
                            f"kfcrit/templates/{TEMPLATE} and templates/{TEMPLATE})")


def environment() -> jinja2.Environment:
    """The Jinja environment: autoescape for ``.html``/``.html.j2``, ``StrictUndefined``.

    One environment per template folder is kept, so compiled templates are reused across
    reports (Jinja still reloads a template whose file changed).
    """
    return _environment_for(str(template_dir()))


@functools.lru_cache(maxsize=4)
def _environment_for(folder: str) -> jinja2.Environment:
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(folder),
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


def _prose(value: Any) -> str:
    """Record prose with its ASCII mathematics in Unicode (``sqrt(3)`` → √3, ``<=`` → ≤ ...);
    ``None`` → empty string. See :func:`kfcrit.views.jinja_filters.pretty_text`."""
    return filters.pretty_text(value) if value is not None else ""


def _sentence(value: Any) -> str:
    """Record prose as a finished sentence: Unicode mathematics and a final full stop."""
    text = _prose(value).strip()
    if text and text[-1] not in ".!?":
        text += "."
    return text


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

def row(label: str, value: Any, kind: str = "text", note: str = "",
        status: bool | None = None, unit_title: str = "") -> dict[str, Any]:
    """One labelled row of a quantity table: the template prints ``value | quantity(kind)``.

    ``note`` is already formatted text (built with :mod:`kfcrit.views.jinja_filters`); ``status`` marks a
    pass/fail comparison (``None``: no comparison).
    """
    return {"label": label, "value": value, "kind": kind, "note": note, "status": status,
            "title": unit_title}


def _exact_text(expression: Any) -> str | None:
    """An exact expression worth printing beside its number (not a plain decimal like 0.96213…)."""
    if not isinstance(expression, str) or not expression.strip():
        return None
    return None if mathsvg.is_plain(expression) else expression


CHANNEL_NAMES = {"bernoulli": "Bernoulli (i.i.d. losses)",
                 "gilbert-elliott": "Gilbert–Elliott (bursty, two-state Markov losses)",
                 "trace": "measured arrival trace", "link-budget": "radio link budget"}


def channel_rows(channel: dict[str, Any]) -> list[dict[str, Any]]:
    """The configured channel as labelled rows with units (nested mappings flattened by hand)."""
    model = channel.get("model")
    p = row("arrival probability p", channel.get("arrival_probability"), "prob",
            note=f"= {filters.pretty_expr(_exact_text(channel['arrival_probability_expression']))}"
            if _exact_text(channel.get("arrival_probability_expression")) else "")
    rows = [row("model", None, note=str(CHANNEL_NAMES.get(str(model), model)))]
    if model == "gilbert-elliott":
        rows += [row("failure rate f = P(lost | received before)", channel.get("failure_rate"),
                     "prob"),
                 row("recovery rate r = P(received | lost before)",
                     channel.get("recovery_rate"), "prob"),
                 row("stationary arrival probability r / (f + r)",
                     channel.get("arrival_probability"), "prob", note=p["note"]),
                 row("mean loss-burst length 1 / r", channel.get("mean_burst_length"), "num",
                     note="packets")]
    elif model == "link-budget":
        radio = _dict(channel.get("radio"))
        pl = _dict(channel.get("path_loss"))
        # The numbers of the budget itself (powers, SINR, p) are in the budget table.
        rows += [row("radio", radio.get("model"), note=str(radio.get("source") or "")),
                 row("path-loss model", pl.get("model"), note=_prose(pl.get("formula"))),
                 row("shadowing σ", pl.get("shadowing_sigma_db"), "dB",
                     note=str(pl.get("shadowing") or "")),
                 row("arrival probability p", channel.get("arrival_probability"), "prob",
                     note=str(channel.get("arrival_probability_basis") or "")),
                 row("margin policy", channel.get("margin_db"), "dB",
                     note=f"at most {filters.pct(channel.get('max_outage'))} shadowing outage"
                     if _num(channel.get("max_outage")) is not None else "")]
    elif model == "trace":
        rows += [row("trace file", channel.get("path")),
                 row("length", channel.get("length"), "count", note="packets"), p]
    else:
        rows.append(p)
    return rows


def channel_summary(channel: dict[str, Any]) -> str:
    """One line for the verdict box: the channel's defining numbers with units."""
    model = channel.get("model")
    if model == "gilbert-elliott":
        return (f"Gilbert–Elliott: failure rate {filters.prob(channel.get('failure_rate'))}, "
                f"recovery rate {filters.prob(channel.get('recovery_rate'))}, mean loss burst "
                f"{filters.num(channel.get('mean_burst_length'), 4)} packets")
    if model == "link-budget":
        radio = _dict(channel.get("radio")).get("model") or "radio"
        return (f"{radio}: {filters.unit(channel.get('tx_power_dbm'), 'dBm')} at "
                f"{filters.unit(channel.get('distance_m'), 'm')}, "
                f"{filters.num(channel.get('packet_bytes'))}-byte packets, SINR "
                f"{filters.unit(channel.get('sinr_db'), 'dB')} "
                f"({channel.get('arrival_probability_basis') or 'median link'})")
    if model == "trace":
        return f"measured trace {channel.get('path')} ({filters.count(channel.get('length'))} " \
               "packets)"
    return CHANNEL_NAMES.get(str(model), str(model or "channel"))


def link_design_view(rec: dict[str, Any]) -> dict[str, Any] | None:
    """The link-budget design outcome for the verdict box (None for other channels)."""
    lb = _dict(rec.get("link_budget"))
    if not lb.get("applicable"):
        return None
    if "condition" in lb:   # Gilbert–Elliott
        cond = _dict(lb.get("condition"))
        return {"kind": "bursty", "status": cond.get("holds"),
                "text": f"recovery rate r = {filters.prob(lb.get('recovery_rate'))} must exceed "
                        f"1 − 1/a² = {filters.prob(lb.get('required_recovery_rate'))}, i.e. mean "
                        f"loss bursts of at most "
                        f"{filters.num(_num(lb.get('max_mean_burst_length')), 4)} packets "
                        f"({_prose(cond.get('status')) or 'status unknown'})"}
    dc = _dict(lb.get("design_check"))
    parts = [f"link margin {filters.unit(lb.get('link_margin_db'), 'dB')} at "
             f"{filters.unit(dc.get('distance_m'), 'm')}"]
    if dc.get("required_margin_db") is not None:
        parts[0] += f" (policy needs {filters.unit(dc.get('required_margin_db'), 'dB')})"
    if lb.get("max_distance_unbounded"):
        parts.append("no distance limit at the margin policy")
    elif lb.get("max_distance_m") is not None:
        parts.append(f"maximum distance at the margin policy "
                     f"{filters.unit(lb.get('max_distance_m'), 'm')}")
    if dc.get("outage_probability") is not None:
        parts.append(f"shadowing outage {filters.pct(dc.get('outage_probability'))}"
                     + (f" (policy allows {filters.pct(dc.get('max_outage'))})"
                        if dc.get("max_outage") is not None else ""))
    met = dc.get("margin_policy_met")
    if dc.get("outage_within_policy") is False:
        met = False
    return {"kind": "link", "status": met, "text": "; ".join(parts)}


def verdict_view(rec: dict[str, Any]) -> dict[str, Any]:
    """The verdict box: operating p against p_c, margins, robust value, bracket, verdict."""
    op = rec.get("operating_point")
    opd = _dict(op)
    cv = _dict(rec.get("critical_value"))
    rob = rec.get("robust_critical_value")
    robd = _dict(rob)
    channel = _dict(opd.get("channel")) or _dict(_dict(rec.get("system")).get("channel"))
    verdict = opd.get("verdict") if isinstance(op, dict) else None
    css = {"mean-stable": "stable", "mean-unstable": "unstable",
           "undetermined": "undetermined"}.get(str(verdict), "unknown")
    iid_verdict = opd.get("iid_comparison_verdict")
    return {
        "available": isinstance(op, dict),
        "missing": _missing("operating point", "the system file has no channel section, so "
                            "there is no arrival probability to compare with p_c")
        if op is None else "",
        "verdict": verdict, "css": css,
        "p": _num(opd.get("arrival_probability")),
        "p_expression": _exact_text(channel.get("arrival_probability_expression")),
        "channel_model": CHANNEL_NAMES.get(str(channel.get("model")), channel.get("model")),
        "channel_summary": channel_summary(channel) if channel else "",
        "critical_value": _num(cv.get("value")),
        "critical_expression": cv.get("expression"),
        "critical_svg": formula(cv.get("latex"), cv.get("expression"), fontsize=13,
                                label=cv.get("expression")),
        "critical_exact": cv.get("exact"),
        "critical_reason": _prose(cv.get("reason")) or None,
        "margin": _num(opd.get("margin")),
        "margin_robust": _num(opd.get("margin_robust")),
        "robust": {"available": isinstance(rob, dict),
                   "value": _num(robd.get("value")), "tolerance": _num(robd.get("tolerance")),
                   "expression": robd.get("expression"),
                   "nearby_case": robd.get("nearby_case"),
                   "missing": "not needed: the classification is decided exactly and no "
                              "perturbation within the tolerance changes it"
                   if cv.get("exact") else "not computed"},
        "bracket": opd.get("bracket") if isinstance(opd.get("bracket"), list) else None,
        "margin_to_bracket": opd.get("margin_to_bracket")
        if isinstance(opd.get("margin_to_bracket"), list) else None,
        "reason": _prose(opd.get("reason")) if isinstance(opd.get("reason"), str) else None,
        "basis": _prose(opd.get("basis")) if isinstance(opd.get("basis"), str) else None,
        "iid_verdict": iid_verdict if iid_verdict and iid_verdict != verdict else None,
        "note": _sentence(opd.get("note")) if opd.get("note") else None,
        "legend": verdict_legend(op, verdict, opd),
        "link_design": link_design_view(rec),
        "requirement": requirement_view(rec),
    }


def verdict_legend(op: Any, verdict: Any, opd: dict[str, Any]) -> str:
    """The last sentence of the legend under the verdict box (after the two verdicts' meaning):
    why this verdict is not determined, when it is not (no operating point, p inside the bracket
    of p_c, or the record's reason); empty for a determined verdict."""
    if not isinstance(op, dict):
        why = ("Not determined: no operating point is configured (the system file has no "
               "channel section), so there is no arrival probability p to compare with p_c.")
    elif verdict == "undetermined":
        if isinstance(opd.get("bracket"), list):
            why = "Undetermined: p lies inside the bracket of p_c, so the comparison is open."
        else:
            why = "Undetermined: " + (_sentence(opd.get("reason")) or
                                      "the comparison of p with p_c is not decided.")
    elif not verdict:
        why = "Not determined: " + (_sentence(opd.get("reason")) or "the analysis gave no verdict.")
    else:
        why = ""
    return why


def requirement_view(rec: dict[str, Any]) -> dict[str, Any]:
    """The system file's requirements against the simulated tail probability at p."""
    req = _dict(rec.get("requirements"))
    limit = _num(req.get("max_error_trace"))
    max_tail = _num(req.get("max_tail_probability"))
    from kfcrit.views.figures import tail_of

    tail = tail_of(rec)
    exc = _dict(_dict(_dict(rec.get("simulation")).get("operating_point")).get("exceedance"))
    lo, hi = _num(exc.get("lower")), _num(exc.get("upper"))
    status = _dict(req.get("assessment")).get("status")
    met = {"met": True, "not met": False}.get(status) if isinstance(status, str) else None
    return {"available": limit is not None, "limit": limit, "max_tail": max_tail,
            "tail": tail, "met": met, "status": status,
            "interval": [lo, hi] if None not in (lo, hi) else None,
            "count": exc.get("count"), "total": exc.get("total"),
            "caution": "not demonstrated: the 95 % interval contains the allowed tail "
                       "probability; run more paths (full mode) before relying on this"
                       if status == "not demonstrated" else "",
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


def _maybe_svg(expr: Any) -> Markup | None:
    """SVG of an exact expression that does not read well as plain text (else ``None``)."""
    if isinstance(expr, str) and expr and not mathsvg.is_plain(expr):
        return _svg(mathsvg.expression_svg(expr))
    return None


STRUCTURE_KNOWN = {"eigenvalues", "equi_blocks", "diagonalizable", "detectable", "controllable_Q",
                   "path", "path_reason", "tolerances", "equal_modulus_pairs",
                   "observability_index", "observable", "standard_form"}


def standard_form_note(form: Any) -> str:
    """The standard form of (A, C) in words: the basis and C·V of each equi-block."""
    d = _dict(form)
    parts = [_prose(d["basis"])] if d.get("basis") else []
    for b in _list(d.get("equi_blocks")):
        cols = _list(_dict(b).get("C_columns"))
        if cols:
            # one column of C·V per eigenvalue; a column of m > 1 entries reads (a; b)
            text = ", ".join(
                filters.pretty_expr(_list(c)[0]) if len(_list(c)) == 1 else
                "(" + "; ".join(filters.pretty_expr(e) for e in _list(c)) + ")" for c in cols)
            parts.append(f"C·V on I = {filters.indices(_dict(b).get('indices'))}: [{text}]")
    return "; ".join(parts)


def structure_view(rec: dict[str, Any]) -> dict[str, Any]:
    """Eigenvalues with moduli, equi-blocks, equal-modulus pairs and the structural flags."""
    st = rec.get("structure")
    d = _dict(st)
    eigs = []
    for e in _list(d.get("eigenvalues")):
        e = _dict(e)
        expr = e.get("modulus_expression")
        value = e.get("value")
        eigs.append({"value": value, "value_svg": _maybe_svg(value),
                     "re": _num(e.get("re")), "im": _num(e.get("im")),
                     "modulus": _num(e.get("modulus")), "modulus_expression": expr,
                     "modulus_svg": _maybe_svg(expr)})
    blocks = [{"indices": _dict(b).get("indices"), "modulus": _num(_dict(b).get("modulus")),
               "modulus_expression": _dict(b).get("modulus_expression"),
               "size": _dict(b).get("size"),
               "unstable": _dict(b).get("unstable_or_critical"),
               "one_step_observable": _dict(b).get("one_step_observable"),
               "rank": _dict(b).get("rank")} for b in _list(d.get("equi_blocks"))]
    pairs = [{"indices": _dict(q).get("indices"), "degenerate": _dict(q).get("degenerate"),
              "q": _dict(q).get("q"), "turn": _num(_dict(q).get("turn")),
              "turn_expression": _dict(q).get("turn_expression"), "rank": _dict(q).get("rank")}
             for q in _list(d.get("equal_modulus_pairs"))]
    flags = [{"label": label, "value": d.get(key)} for key, label in (
        ("diagonalizable", "A diagonalizable"), ("observable", "(A, C) observable"),
        ("detectable", "(A, C) detectable"), ("controllable_Q", "(A, Q^½) controllable"))]
    rows = [row("analysis path", d.get("path"), note=_prose(d.get("path_reason")))]
    if d.get("observability_index") is not None:
        rows.append(row("observability index I_o", d.get("observability_index"), "num",
                        note="smallest k with rank [C; CA; …; CAᵏ⁻¹] = n"))
    if isinstance(d.get("standard_form"), dict):
        rows.append(row("standard form (eigenbasis V)", None,
                        note=standard_form_note(d["standard_form"]) or filters.DASH))
    return {"available": isinstance(st, dict), "missing": _missing("structure analysis"),
            "eigenvalues": eigs, "equi_blocks": blocks, "pairs": pairs,
            "pairs_listed": isinstance(d.get("equal_modulus_pairs"), list),
            "flags": flags, "rows": rows, "path": d.get("path"),
            "extra": kv_rows(d, skip=STRUCTURE_KNOWN)}


def classification_view(rec: dict[str, Any]) -> dict[str, Any]:
    """The classification, the theorem that decides it and its formula (typeset)."""
    cls = rec.get("classification")
    cv = _dict(rec.get("critical_value"))
    name, latex, why = theorem_for(cls if isinstance(cls, str) else None)
    return {"available": isinstance(cls, str) and bool(cls),
            "missing": _missing("classification", _prose(cv.get("reason")) or None),
            "name": cls, "theorem": name, "why": why, "general_latex": latex,
            "general_svg": _svg(mathsvg.latex_svg(latex, fontsize=12)),
            "instance_svg": formula(cv.get("latex"), cv.get("expression"), fontsize=12,
                                    label=cv.get("expression")),
            "instance_expression": cv.get("expression"), "value": _num(cv.get("value")),
            "reason": _prose(cv.get("reason")) or None, "exact": cv.get("exact")}


def bounds_view(rec: dict[str, Any]) -> dict[str, Any]:
    """Rows of the bounds table, the higher-moment thresholds and the fixed-gain comparison."""
    lb, blb = rec.get("lower_bound"), rec.get("block_lower_bound")
    cv, rob, ub = rec.get("critical_value"), rec.get("robust_critical_value"), \
        rec.get("upper_bound")
    cvd, ubd = _dict(cv), _dict(ub)
    cls = rec.get("classification") if isinstance(rec.get("classification"), str) else None
    rows = [
        {"symbol": "p_low", "name": "lower bound p_low", "available": isinstance(lb, dict),
         "value": _num(_dict(lb).get("value")), "expression": _dict(lb).get("expression"),
         "detail": "1 − 1/max|λᵢ|²: necessary for mean stability",
         "source": "Sinopoli et al., Theorem 3"},
        {"symbol": "p_block", "name": "block lower bound", "available": isinstance(blb, dict),
         "value": _num(_dict(blb).get("value")), "expression": _dict(blb).get("expression"),
         "detail": "largest critical value of an equi-block",
         "source": "Mo–Sinopoli, Theorem 3"},
        {"symbol": "p_c", "name": "critical value p_c",
         "available": _num(cvd.get("value")) is not None,
         "value": _num(cvd.get("value")), "expression": cvd.get("expression"),
         "detail": "exact (decided symbolically)" if cvd.get("exact") else
         "numerical (bracket closed to the tolerance)" if cvd.get("exact") is False else "",
         "source": theorem_for(cls)[0],
         "missing": "not computed: " + _prose(cvd.get("reason")) if cvd.get("reason")
         else "not computed"},
        {"symbol": "p_c,robust", "name": "robust critical value",
         "available": isinstance(rob, dict),
         "value": _num(_dict(rob).get("value")), "expression": _dict(rob).get("expression"),
         "detail": _robust_detail(_dict(rob)),
         "source": "largest p_c within the stated relative perturbation",
         "missing": "not needed: the decision is exact and robust to perturbations"
         if cvd.get("exact") else "not computed"},
        {"symbol": "p_up", "name": "upper bound p_up", "available": isinstance(ub, dict),
         "value": _num(ubd.get("value")), "expression": upper_expression(ubd),
         "detail": _upper_detail(ubd), "source": "Sinopoli et al., Theorem 5 (LMI)",
         "missing": "not computed"},
    ]
    for r in rows:
        r.setdefault("missing", "not computed")
    th = _dict(rec.get("theory"))
    moments = [{"q": _dict(m).get("q"), "value": _num(_dict(m).get("value")),
                "expression": _dict(m).get("expression"), "applies": _dict(m).get("applies")}
               for m in _list(th.get("moment_thresholds"))]
    note = th.get("moment_thresholds_note")
    return {"rows": rows, "moments": moments,
            "critical_reason": _prose(cvd.get("reason")) or None
            if cvd.get("value") is not None else None,
            "moments_note": _sentence(note) if note else
            "Mo–Sinopoli, Corollary 2: for non-degenerate systems whose eigenvalues are all "
            "unstable, the q-th moment is bounded iff p > 1 − |λ₁|^(−2q).",
            "static_gain": static_gain_view(rec),
            "moments_available": bool(moments),
            "moments_missing": _missing("higher-moment thresholds")}


STATIC_GAIN_LABELS = {"kalman": "steady-state Kalman gain K∞ of the lossless filter",
                      "best": "best fixed gain K* (from the p_up certificate)"}


def static_gain_view(rec: dict[str, Any]) -> dict[str, Any]:
    """The fixed-gain (jump-linear) estimators of the record, one table row per gain."""
    sg = rec.get("static_gain")
    d = _dict(sg)
    gains = []
    for key, label in STATIC_GAIN_LABELS.items():
        g = _dict(d.get(key))
        if not g:
            continue
        notes = []
        if g.get("equals_p_up"):
            notes.append("its critical value equals p_up")
        if g.get("available") is False:
            notes.append(str(g.get("reason") or "not available"))
        gains.append({"label": label, "available": g.get("available") is not False,
                      "critical_value": _num(g.get("critical_value")),
                      "gain": g.get("gain"), "covariance_exists": g.get("covariance_exists"),
                      "covariance_trace": _num(g.get("covariance_trace")),
                      "note": "; ".join(notes)})
    return {"available": isinstance(sg, dict), "p": _num(d.get("p")), "gains": gains,
            "missing": _missing("fixed-gain estimators",
                                "no operating point: the system file has no channel")}


def upper_expression(ub: dict[str, Any]) -> str | None:
    """The exact form of p_up when the record has one: its own ``expression``, or, when p_up is
    decided exactly (method ``exact``), the exact value of the theorem that pins it (the lower
    evidence, e.g. p_up = p_low = 9/25 for invertible C)."""
    own = _exact_text(ub.get("expression"))
    if own:
        return own
    ev = _dict(ub.get("lower_evidence"))
    value, ev_value = _num(ub.get("value")), _num(ev.get("value"))
    if ub.get("method") == "exact" and ev.get("expression") and value is not None and \
            ev_value is not None and abs(value - ev_value) <= 1e-12 * max(1.0, abs(value)):
        return str(ev["expression"])
    return None


def _robust_detail(rob: dict[str, Any]) -> str:
    parts = []
    if _num(rob.get("tolerance")) is not None:
        parts.append(f"relative tolerance {filters.sci(rob['tolerance'], 3)}")
    if rob.get("nearby_case"):
        parts.append(f"nearby case: {filters.text(rob['nearby_case'])}")
    return "; ".join(parts)


def _upper_detail(ub: dict[str, Any]) -> str:
    parts = []
    if ub.get("certified") is not None:
        parts.append("certified" if ub["certified"] else "not certified")
    iv = ub.get("interval")
    if isinstance(iv, list) and ub.get("method") == "exact":
        ev = _dict(ub.get("lower_evidence"))
        parts.append("decided exactly" + (f": {_prose(ev['statement'])}"
                                          if ev.get("statement") else ""))
    elif isinstance(iv, list):
        parts.append(f"p_up ∈ {filters.interval(iv, 10)}")
    if ub.get("method"):
        parts.append(f"method: {ub['method']}")
    if ub.get("status") and ub.get("status") not in ("determined", "certified"):
        parts.append(f"status: {ub['status']}")
    return "; ".join(parts)


def covariance_view(rec: dict[str, Any]) -> dict[str, Any]:
    """S̄ and V̄ at the operating point (Sinopoli Theorems 4 and 6)."""
    cb = rec.get("covariance_bounds")
    d = _dict(cb)

    def side(x: Any) -> dict[str, Any]:
        x = _dict(x)
        return {"exists": x.get("exists"), "trace": _num(x.get("trace")),
                "max_eig": _num(x.get("max_eig")), "residual": _num(x.get("residual")),
                "method": _prose(x.get("method")) or None}

    why = "no operating point: the system file has no channel section" \
        if rec.get("operating_point") is None else None
    return {"available": isinstance(cb, dict), "missing": _missing("covariance bounds", why),
            "p": _num(d.get("p")), "lower": side(d.get("lower")), "upper": side(d.get("upper"))}


FIGURE_CAPTIONS = {
    "phase_transition": ("Phase transition",
                         "Trace of the lower bound S̄ and the upper bound V̄ of lim E[P_t] "
                         "against the arrival probability p (log scale), with p_low, p_c, p_up "
                         "and the operating point marked. Below p_c the expected error "
                         "covariance diverges."),
    "traces": ("Simulated error traces around the critical value",
               "Mean trace of P_t over simulated loss sequences for p just below and just above "
               "the critical value (log scale). Below p_c the expected covariance diverges; a "
               "mean over finitely many paths shows it as growth or as ever larger spikes from "
               "long loss bursts (it underestimates the expectation). Above p_c it settles."),
    "operating": ("Simulated mean covariance at the operating point",
                  "Mean trace of P_t over simulated paths at the operating p, with its 95 % "
                  "confidence band, against tr S̄ and tr V̄ (Sinopoli et al., Theorems 4 and 6: "
                  "S̄ ⪯ lim E[P_t] ⪯ V̄)."),
    "cdf": ("Distribution of tr P at the operating point",
            "Empirical CDF of the error covariance trace over the simulated paths at the "
            "simulation horizon (the law of P_t converges weakly to the invariant distribution, "
            "Kar–Sinopoli–Moura, Theorem 9)."),
    "almost_sure": ("Almost-sure behaviour along one path",
                    "Largest and smallest tr P_t over the dyadic blocks t ∈ [2ᵏ, 2ᵏ⁺¹) of "
                    "one long simulated path at the operating p. Growing maxima show "
                    "limsup tr P_t = ∞ (upper a.s. unstable); bounded minima show "
                    "liminf tr P_t < ∞ (lower a.s. stable)."),
    "invariant": ("Support of the invariant distribution",
                  "Support of the invariant distribution of P_t (Kar–Sinopoli–Moura, Theorem "
                  "10): it starts at the Riccati fixed point P* and has empty intervals that "
                  "carry no mass for every 0 < p < 1 (log scale). Blue: no empty interval found "
                  "at the computed resolution, so the support lies there (it is self-similar: "
                  "each blue piece holds smaller gaps)."),
}


def figure_reasons(rec: dict[str, Any]) -> dict[str, str]:
    """Why a figure may be missing, from what the record lacks (shown instead of the figure)."""
    no_channel = rec.get("operating_point") is None
    sim = _dict(rec.get("simulation"))
    if rec.get("simulation") is None:
        sim_why = "no simulation in the record"
    elif sim.get("skipped"):
        sim_why = str(sim.get("reason") or "simulation skipped")
    else:
        sim_why = ""
    op_why = ("the system file has no channel section, so there is no operating point"
              if no_channel else sim_why or "the simulation produced no data at the operating p")
    return {"phase_transition": "no phase-transition data in the record",
            "traces": sim_why or "the simulation produced no runs around p_c",
            "operating": op_why, "cdf": op_why, "almost_sure": op_why,
            "invariant": "the invariant-distribution analysis did not run"}


def figures_view(figures: dict[str, str | None],
                 rec: dict[str, Any] | None = None) -> dict[str, dict[str, Any]]:
    """Each figure with its title, caption and "not computed" message (with the reason)."""
    reasons = figure_reasons(_dict(rec))
    out = {}
    for key, (title, caption) in FIGURE_CAPTIONS.items():
        svg = figures.get(key) if isinstance(figures, dict) else None
        out[key] = {"svg": _svg(svg), "title": title, "caption": caption,
                    "missing": _missing(title[:1].lower() + title[1:], reasons.get(key))}
    return out


def _last(values: Any) -> float | None:
    """The last finite entry of a list (the horizon of a simulated series)."""
    if isinstance(values, list):
        for v in reversed(values):
            if _num(v) is not None:
                return v
    return None


def simulation_view(rec: dict[str, Any]) -> dict[str, Any]:
    """Settings and summary numbers of the simulation as labelled rows (arrays are drawn)."""
    sim = rec.get("simulation")
    d = _dict(sim)
    from kfcrit.views.figures import series_of, tail_of

    op = _dict(d.get("operating_point"))
    budget = _dict(d.get("budget"))
    rows: list[dict[str, Any]] = []
    if d.get("skipped"):
        return {"available": False, "tail_probability": None, "rows": [],
                "missing": _missing("simulation", str(d.get("reason") or "skipped"))}
    seed = d.get("seed") if d.get("seed") is not None else op.get("seed")
    paths = op.get("paths") if op.get("paths") is not None else \
        budget.get("paths", d.get("paths"))
    steps = op.get("steps") if op.get("steps") is not None else \
        budget.get("steps", d.get("steps"))
    if not op:
        rows.append(row("operating-point runs", None, note="none: the record has no operating "
                        "point (no channel in the system file)"
                        if rec.get("operating_point") is None else
                        "none: the simulation produced no data at the operating point"))
    elif paths is not None or steps is not None:
        p_op = filters.num(_num(op.get("arrival_probability")), 6)
        rows.append(row("operating-point runs", None, note=f"{filters.count(paths)} paths × "
                        f"{filters.count(steps)} steps at p = {p_op}"
                        + (f", seed {seed}" if seed is not None else "")))
    if "iid" in op:
        rows.append(row("i.i.d. losses", op.get("iid"), "yesno"))
    _, mean, lo, hi = series_of(op) if op else (None, None, None, None)
    cb = _dict(rec.get("covariance_bounds"))
    s_tr = _num(_dict(cb.get("lower")).get("trace"))
    v_tr = _num(_dict(cb.get("upper")).get("trace"))
    horizon = _dict(op.get("horizon"))
    if _last(mean) is not None:
        band = (f"95 % band {filters.span(_last(lo), _last(hi), 5)}"
                if _last(lo) is not None and _last(hi) is not None else "")
        bounds = (f"tr S̄ = {filters.num(s_tr, 5)}" if s_tr is not None else "") + \
            (f", tr V̄ = {filters.num(v_tr, 5)}" if v_tr is not None else
             (", V̄ does not exist at this p" if s_tr is not None else ""))
        rows.append(row("mean tr P_t at the horizon"
                        + (f" t = {horizon['time']}" if horizon.get("time") else ""),
                        _last(mean), "num", note="; ".join(x for x in (band, bounds) if x)))
    levels, quants = _list(horizon.get("levels")), _list(horizon.get("quantiles"))
    if levels and len(levels) == len(quants):
        wanted = [(lv, qv) for lv, qv in zip(levels, quants) if lv in (0.5, 0.9, 0.99)]
        if wanted:
            rows.append(row("quantiles of tr P at the horizon", None, note=", ".join(
                f"{filters.pct(lv, 3)}: {filters.num(_num(qv), 5)}" for lv, qv in wanted)))
    erg = _dict(op.get("ergodic"))
    pooled = _dict(_dict(erg.get("time_averages")).get("pooled_mean_trace"))
    if _num(pooled.get("mean")) is not None:
        rows.append(row("time average of tr P_t (one long path per replica)", pooled.get("mean"),
                        "num", note=ergodic_note(erg, pooled)))
    div = _dict(op.get("divergence"))
    if div.get("diverged_paths") is not None:
        rows.append(row("diverged paths", div.get("diverged_paths"), "count",
                        note=f"of {filters.count(paths)} (tr P above "
                        f"{filters.sci(_num(div.get('threshold')), 3)}; "
                        f"{divergence_text(div)})"))
    bursts = _dict(op.get("bursts"))
    if _num(bursts.get("mean_length")) is not None:
        rows.append(row("loss bursts", bursts.get("mean_length"), "num",
                        note=f"mean length (channel: "
                        f"{filters.num(_num(bursts.get('expected_mean_length')), 4)}); "
                        f"{filters.count(bursts.get('bursts'))} bursts, longest "
                        f"{filters.num(bursts.get('longest'))}, loss fraction "
                        f"{filters.pct(_num(bursts.get('loss_fraction')))}"))
    demo = d.get("phase_demo")
    curves = _list(_dict(demo).get("curves")) if isinstance(demo, dict) else _list(demo)
    if curves:
        ps = [_num(_dict(c).get("arrival_probability", _dict(c).get("p"))) for c in curves]
        ref = _dict(demo).get("reference_value") if isinstance(demo, dict) else None
        rows.append(row("runs around p_c", None, note=(
            f"p = {', '.join(filters.num(x, 4) for x in ps)}"
            + (f" (reference {filters.num(_num(ref), 6)})" if _num(ref) is not None else "")
            + (f"; {filters.count(_dict(demo).get('paths'))} paths × "
               f"{filters.count(_dict(demo).get('steps'))} steps each"
               if isinstance(demo, dict) and _dict(demo).get("paths") else ""))))
    seeds = d.get("seeds")
    if seeds is not None:
        rows.append(row("random seeds", None, note=seeds_text(seeds)))
    if d.get("quick") is not None:
        rows.append(row("draft (--quick)", d.get("quick"), "yesno"))
    return {"available": isinstance(sim, dict), "missing": _missing("simulation"),
            "tail_probability": tail_of(rec), "rows": rows}


def divergence_text(div: dict[str, Any]) -> str:
    """What happened to the paths that crossed the divergence threshold, as the record says.

    Paths continued in scaled form (``continued``) keep true values; censored paths (held at
    the threshold, the older rule) enter the means as the threshold, so the means are lower
    bounds; ``mean_is_lower_bound`` (censoring or a path frozen after a numerical failure)
    says so either way.
    """
    lower = bool(div.get("mean_is_lower_bound"))
    if div.get("continued"):
        text = "such paths are continued in scaled form, so the statistics are true values"
        return text + ("; some paths were frozen after a numerical failure, so means are "
                       "lower bounds" if lower else "")
    if div.get("diverged_paths") or lower:
        return "censored at the threshold; means are lower bounds"
    return ("a diverged path would be censored at the threshold, making the means lower "
            "bounds; none did")


ERGODIC_MIN_REPLICAS = 10
ERGODIC_MAX_SPREAD = 3.0


def ergodic_unreliable(erg: dict[str, Any], pooled: dict[str, Any]) -> str:
    """Why the time-average interval cannot be trusted ("" when nothing is wrong with it).

    tr P_t ≥ 0, so a 95 % interval reaching below zero, or replica means that differ by more
    than a factor :data:`ERGODIC_MAX_SPREAD` with fewer than :data:`ERGODIC_MIN_REPLICAS`
    replicas, mean the normal approximation behind it does not hold (few replicas, heavy tail).
    """
    reasons = []
    lower = _num(pooled.get("lower"))
    if lower is not None and lower < 0:
        reasons.append("its normal approximation reached below 0 (clamped there: tr P ≥ 0)")
    means = [v for v in _list(_dict(erg.get("time_averages")).get("replica_mean_trace"))
             if _num(v) is not None and v > 0]
    replicas = _num(erg.get("replicas"))
    spread = max(means) / min(means) if len(means) >= 2 else None
    if spread is not None and spread > ERGODIC_MAX_SPREAD and \
            (replicas is None or replicas < ERGODIC_MIN_REPLICAS):
        reasons.append(f"the {filters.count(replicas) if replicas else len(means)} replica means "
                       f"range over {filters.num(min(means), 4)} – {filters.num(max(means), 4)} "
                       "(a heavy tail)")
    return "; ".join(reasons)


def ergodic_note(erg: dict[str, Any], pooled: dict[str, Any]) -> str:
    """The time-average row's note: its 95 % interval clamped at 0, the replicas, and a caution
    when the interval is unreliable (:func:`ergodic_unreliable`)."""
    lower, upper = _num(pooled.get("lower")), _num(pooled.get("upper"))
    if lower is not None:
        lower = max(lower, 0.0)
    note = (f"95 % interval {filters.span(lower, upper, 5)}; "
            f"{filters.count(erg.get('replicas'))} replicas × "
            f"{filters.count(erg.get('steps'))} steps, burn-in "
            f"{filters.count(erg.get('burn_in'))}")
    why = ergodic_unreliable(erg, pooled)
    if why:
        note += f". Interval unreliable: {why}; run more replicas (full mode) before using it"
    return note


def seeds_text(seeds: Any) -> str:
    """The simulation's seeds in words (a mapping of stream names to seeds or seed rules)."""
    if isinstance(seeds, dict):
        parts = []
        for k, v in seeds.items():
            label = filters.key_label(k)
            if isinstance(v, dict):
                inner = ", ".join(f"{filters.key_label(a)} {filters.text(b)}"
                                  for a, b in v.items())
                parts.append(f"{label}: {inner}")
            else:
                parts.append(f"{label}: {filters.text(v)}")
        return "; ".join(parts) if parts else filters.DASH
    return filters.text(seeds)


def _is_series(value: Any) -> bool:
    return isinstance(value, list) and len(value) > 12


def statements_view(rec: dict[str, Any]) -> dict[str, Any]:
    """Almost-sure and distributional statements (MATH §5–6) in plain words."""
    th = rec.get("theory")
    d = _dict(th)
    sb = d.get("stochastic_boundedness")
    asure = d.get("almost_sure")
    sentences = [_prose(s) for s in asure] if isinstance(asure, list) else \
        ([_prose(asure)] if isinstance(asure, str) and asure else [])
    known = ("stochastic_boundedness", "almost_sure", "moment_thresholds",
             "moment_thresholds_note", "observability_index")
    return {"available": bool(sb) or bool(sentences),
            "missing": _missing("almost-sure and distributional statements"),
            "stochastic_boundedness": [_prose(s) for s in sb] if isinstance(sb, list) else
            ([_prose(sb)] if sb else []),
            "almost_sure": sentences,
            "extra": kv_rows(d, skip=known)}


def _value_expr(x: Any) -> tuple[float | None, str | None]:
    """(value, exact expression) of a record number given either as ``{value, expression}``
    or as a bare number."""
    if isinstance(x, dict):
        return _num(x.get("value")), _exact_text(x.get("expression"))
    return _num(x), None


def invariant_view(rec: dict[str, Any], figure: str | None) -> dict[str, Any]:
    """Support of the invariant distribution (scalar systems only)."""
    n = _dict(rec.get("system")).get("n")
    inv = rec.get("invariant")
    d = _dict(inv)
    from kfcrit.views.figures import invariant_gaps

    exact = [{"n": _dict(g).get("n"), "lower": _num(_dict(g).get("lower")),
              "upper": _num(_dict(g).get("upper")),
              "lower_expression": _dict(g).get("lower_expression"),
              "upper_expression": _dict(g).get("upper_expression")}
             for g in _list(d.get("gap_levels"))]
    exact = [{**g, "pair": [g["lower"], g["upper"]]} for g in exact
             if g["lower"] is not None and g["upper"] is not None]
    known = {(round(g["lower"], 9), round(g["upper"], 9)) for g in exact}
    gaps = [g for g in invariant_gaps(d) if (round(g[0], 9), round(g[1], 9)) not in known]
    rows = []
    pstar, pstar_expr = _value_expr(d.get("fixed_point"))
    if pstar is not None:
        rows.append(row("Riccati fixed point P* (left end of the support)", pstar, "num",
                        note=f"= {filters.pretty_expr(pstar_expr)}" if pstar_expr else ""))
    maps = _dict(d.get("maps"))
    if maps:
        rows.append(row("Riccati maps", None, note="; ".join(
            f"{filters.key_label(k)}: {_prose(v)}" for k, v in maps.items())))
    lim, lim_expr = _value_expr(d.get("arrival_limit"))
    if lim is not None:
        rows.append(row("limit f₁(∞) of the arrival map", lim, "num",
                        note=f"= {filters.pretty_expr(lim_expr)}" if lim_expr else ""))
    ss = _dict(d.get("self_similarity"))
    if ss.get("statement"):
        rows.append(row("self-similarity", _prose(ss.get("statement")),
                        note=_prose(ss.get("pieces"))))
    sp = d.get("support_points")
    if isinstance(sp, dict) and sp.get("count") is not None:
        rows.append(row("support points computed", sp.get("count"), "count",
                        note=f"compositions of depth {filters.num(sp.get('depth'))} in "
                        f"{filters.interval(sp.get('window'), 6)}"))
    elif isinstance(sp, list):
        rows.append(row("support points computed", len(sp), "count"))
    skip = {"gaps", "support_points", "gap_levels", "holes", "fixed_point", "maps",
            "arrival_limit", "self_similarity", "first_gap", "note", "warnings"}
    return {"applies": n == 1, "available": isinstance(inv, dict),
            "missing": _missing("invariant distribution support"),
            "exact_gaps": exact[:10], "gaps": gaps[:10], "more_gaps": max(0, len(gaps) - 10),
            "rows": rows, "note": _sentence(d.get("note")),
            "extra": kv_rows({k: v for k, v in d.items() if not _is_series(v)}, skip=skip)}


LINK_CHAIN = (("transmit power", "tx_power_dbm", "dBm"), ("antenna gains", "antenna_gain_db", "dB"),
              ("distance", "distance_m", "m"), ("path loss (median)", "path_loss_db", "dB"),
              ("received power (median)", "rx_power_dbm", "dBm"),
              ("noise bandwidth", "bandwidth_hz", "Hz"),
              ("receiver noise figure", "noise_figure_db", "dB"),
              ("noise temperature", "temperature_k", "K"),
              ("thermal noise floor", "noise_floor_dbm", "dBm"),
              ("interference", "interference_dbm", "dBm"),
              ("noise + interference", "noise_plus_interference_dbm", "dBm"),
              ("SINR (median link)", "sinr_db", "dB"),
              ("bit error rate", "bit_error_rate", "prob"),
              ("packet size", "packet_bytes", "bytes"),
              ("packet error rate", "packet_error_rate", "prob"),
              ("arrival probability, median link", "arrival_probability_nominal", "prob"),
              ("arrival probability, averaged over shadowing", "arrival_probability_mean",
               "prob"),
              ("arrival probability used (operating p)", "arrival_probability", "prob"))
THRESHOLD_LABELS = {"critical_value": "critical value p_c",
                    "robust_critical_value": "robust critical value",
                    "bracket_low": "lower end of the p_c bracket",
                    "bracket_high": "upper end of the p_c bracket",
                    "upper_bound": "upper bound p_up", "design": "design requirement"}


def link_budget_view(lb: dict[str, Any]) -> dict[str, Any]:
    """A link-budget section: the budget chain, the design outputs and the threshold table."""
    link = _dict(lb.get("link"))
    policy = _dict(lb.get("margin_policy"))
    req = _dict(lb.get("required_arrival_probability"))
    shadow = _dict(lb.get("shadowing"))
    dc = _dict(lb.get("design_check"))
    chain = [row(label, "none", "text") if key == "interference_dbm" and link.get(key) is None
             else row(label, link.get(key), kind)
             for label, key, kind in LINK_CHAIN if key in link]
    distance = link.get("distance_m")
    design = [
        row("required arrival probability", req.get("design_value"), "prob",
            note=str(req.get("basis") or "")),
        row("required SINR", lb.get("required_sinr_db"), "dB",
            note="smallest SINR whose packet arrival probability exceeds the requirement"),
        row("required received power", lb.get("required_rx_power_dbm"), "dBm"),
        row("link margin at the configured distance", lb.get("link_margin_db"), "dB",
            note=(f"policy needs ≥ {filters.unit(dc.get('required_margin_db'), 'dB')}"
                  if dc.get("required_margin_db") is not None else ""),
            status=dc.get("margin_policy_met")),
        row("effective margin of the policy", policy.get("effective_margin_db"), "dB",
            note=f"max({filters.unit(policy.get('margin_db'), 'dB')}, σ·Φ⁻¹(1 − "
                 f"{filters.pct(policy.get('max_outage'))}))"
            if policy.get("max_outage") is not None else
            f"margin {filters.unit(policy.get('margin_db'), 'dB')}"),
        row("maximum distance at the margin policy",
            "unbounded" if lb.get("max_distance_unbounded") else lb.get("max_distance_m"),
            "text" if lb.get("max_distance_unbounded") else "m",
            note=f"configured distance {filters.unit(distance, 'm')}"
            if distance is not None else "",
            status=dc.get("margin_policy_met")),
        row("mean-stable at the configured distance (median link)",
            lb.get("mean_stable_at_distance"), "yesno", status=lb.get("mean_stable_at_distance")),
        row("shadowing", shadow.get("sigma_db"), "dB", note=f"σ, {shadow.get('mode')} "
            "(per-link: drawn once per deployed link; per-packet: i.i.d. per packet)"
            if shadow.get("mode") else "σ"),
        row("shadowing outage P(p_link ≤ design requirement)", dc.get("outage_probability",
            shadow.get("outage_below_critical")), "pct",
            note=f"policy allows {filters.pct(dc.get('max_outage'))}"
            if dc.get("max_outage") is not None else "",
            status=dc.get("outage_within_policy")),
        row("shadowing outage P(p_link ≤ p_up)", shadow.get("outage_below_upper"), "pct"),
        row("mean arrival probability over shadowing", shadow.get("mean_arrival_probability"),
            "prob"),
    ]
    thresholds = [{"label": THRESHOLD_LABELS.get(str(_dict(t).get("label")),
                                                 filters.key_label(_dict(t).get("label"))),
                   **{k: _dict(t).get(k) for k in (
                       "arrival_probability", "required_sinr_db", "required_rx_power_dbm",
                       "link_margin_db", "max_distance_m", "max_distance_unbounded",
                       "outage_probability", "reachable")}}
                  for t in _list(lb.get("thresholds"))]
    radio = _dict(lb.get("radio"))
    return {"chain": chain, "design": design, "thresholds": thresholds,
            "radio": radio.get("model"), "radio_formula": _prose(radio.get("formula")) or None,
            "radio_svg": radio_formula_svg(radio),
            "radio_source": radio.get("source"), "policy_rule": _prose(policy.get("rule")),
            "notes": [_prose(n) for n in _list(lb.get("notes"))],
            "warnings": [_prose(w) for w in _list(lb.get("warnings"))]}


# Typeset forms of the radio models' BER formulas (the record carries them as ASCII text).
RADIO_LATEX = {
    "ieee802154-oqpsk-2450": (r"\mathrm{BER} = \frac{8}{15}\cdot\frac{1}{16}\sum_{k=2}^{16}"
                              r"(-1)^k \binom{16}{k}\,"
                              r"\exp\left(20\,\mathrm{SINR}\,\left(\frac{1}{k} - 1\right)\right)"),
    "bpsk": (r"\mathrm{BER} = Q\left(\sqrt{2E_b/N_0}\right) = "
             r"\frac{1}{2}\,\mathrm{erfc}\left(\sqrt{E_b/N_0}\right),\quad "
             r"E_b/N_0 = \mathrm{SINR}\cdot 10^{G/10}"),
}


def radio_formula_svg(radio: dict[str, Any]) -> Markup | None:
    """The radio model's BER formula typeset as SVG (``None``: shown as text instead)."""
    latex = RADIO_LATEX.get(str(radio.get("model")))
    return _svg(mathsvg.latex_svg(latex, fontsize=10.5, label=str(radio.get("formula") or "")
                                  or None)) if latex and radio.get("formula") else None


def bursty_view(lb: dict[str, Any]) -> dict[str, Any]:
    """A Gilbert–Elliott section: the burst condition (MATH §7), its status and the claims."""
    cond = _dict(lb.get("condition"))
    sim = _dict(lb.get("simulation"))
    rows = [
        row("failure rate f", lb.get("failure_rate"), "prob", note="P(lost | received before)"),
        row("recovery rate r", lb.get("recovery_rate"), "prob", note="P(received | lost before)"),
        row("stationary arrival probability r/(f + r)", lb.get("stationary_arrival_probability"),
            "prob"),
        row("mean loss-burst length 1/r", lb.get("mean_burst_length"), "num", note="packets"),
        row("spectral radius ρ(A) = a", lb.get("spectral_radius"), "num"),
        row(f"burst condition {filters.pretty_text(cond.get('expression'))}", cond.get("value"),
            "num", note=("holds" if cond.get("holds") else "fails" if cond.get("holds") is False
                         else "not decided") + (f"; {_prose(cond.get('status'))}"
                                                if cond.get("status") else ""),
            status=cond.get("holds")),
        row("required recovery rate 1 − 1/a²", lb.get("required_recovery_rate"), "prob",
            note="r must exceed this (f does not enter)"),
        row("longest admissible mean loss burst", lb.get("max_mean_burst_length"), "num",
            note="packets"),
    ]
    if sim:
        rows.append(row("simulated growth of mean P (last / second quarter)",
                        sim.get("growth_ratio"), "num",
                        note=f"{filters.count(sim.get('paths'))} paths × "
                             f"{filters.count(sim.get('steps'))} steps, seed "
                             f"{filters.num(sim.get('seed'))}; < 2 reads as bounded"
                             + ("; capped" if sim.get("capped") else ""),
                        status=lb.get("simulation_consistent")))
    else:
        rows.append(row("simulation of the bursty channel", None,
                        note="not run: the dedicated simulation covers scalar systems only"))
    claims = [{"statement": _prose(_dict(c).get("statement")),
               "source": str(_dict(c).get("source") or ""),
               "status": str(_dict(c).get("status") or "")} for c in _list(lb.get("claims"))]
    return {"rows": rows, "claims": claims}


def channel_view(rec: dict[str, Any]) -> dict[str, Any]:
    """The channel section: the configured channel, and its link budget or bursty analysis."""
    op = _dict(rec.get("operating_point"))
    channel = _dict(op.get("channel")) or _dict(_dict(rec.get("system")).get("channel"))
    lb = rec.get("link_budget")
    lbd = _dict(lb)
    model = channel.get("model")
    view: dict[str, Any] = {
        "available": bool(channel), "model": model,
        "title": CHANNEL_NAMES.get(str(model), str(model or "")),
        "missing": _missing("channel", "the system file has no channel section; add one "
                            "(bernoulli, gilbert-elliott, trace or link-budget) to get an "
                            "operating point and a verdict"),
        "rows": channel_rows(channel) if channel else [],
        "link": None, "bursty": None, "explanation": ""}
    if model == "link-budget":
        if lbd.get("applicable"):
            view["link"] = link_budget_view(lbd)
        else:
            view["explanation"] = _missing("link budget", str(lbd.get("reason") or
                                                             "no link-budget section"))
    elif model == "gilbert-elliott":
        if lbd.get("applicable"):
            view["bursty"] = bursty_view(lbd)
            view["rows"] = view["rows"][:1]   # the bursty table below has the rates
        else:
            view["explanation"] = _missing("bursty-link analysis", str(lbd.get("reason") or
                                                                       "no section"))
    elif channel:
        view["explanation"] = ("The arrival probability is given directly, so there is no link "
                               "budget to design; use channel model link-budget to derive p "
                               "from a radio link, or gilbert-elliott for bursty losses.")
    return view


OPTION_LABELS = {"tolerance": ("decision tolerance (floating-point input)", "sci"),
                 "upper_tol": ("upper-bound tolerance", "sci"),
                 "simulate": ("simulation run", "yesno"),
                 "quick": ("draft mode (--quick)", "yesno"),
                 "seed": ("base random seed", "num"), "paths": ("simulated paths", "count"),
                 "steps": ("simulated steps", "count")}


def _solver_text(solver: Any) -> str:
    """Upper-bound solver statistics in words (a mapping of counters), or its name."""
    if not isinstance(solver, dict):
        return filters.text(solver)
    parts = []
    for k, v in solver.items():
        label = filters.key_label(k)
        parts.append(f"{label} {filters.sci(v, 3) if isinstance(v, float) else filters.text(v)}")
    return ", ".join(parts) if parts else filters.DASH


_EXP_FLOAT = re.compile(r"-?\d+\.\d+e[-+]?\d+")
_ZERO_FLOAT = re.compile(r"(?<![\w.])-?0\.0+(?![\w.])")
# Check names of the record reworded where their words mislead (diverged paths are censored at
# the threshold and enter the means, which are then lower bounds: nothing is left out).
CHECK_WORDING = {"divergence flagged, not propagated":
                 "diverged paths censored at the threshold, means then lower bounds"}


def check_name(name: Any) -> str:
    """A verification check's name for the appendix (Unicode mathematics, truthful wording)."""
    text = str(name or "")
    for old, new in CHECK_WORDING.items():
        text = text.replace(old, new)
    return _prose(text)


def _detail_text(detail: Any) -> str:
    """A check's detail as text; a literal ``None`` left by the record reads as an em dash and
    full-precision exponent floats (``4.261669270870999e-16``) read as ``4.26 × 10⁻¹⁶``."""
    if detail is None:
        return ""
    out = filters.text(detail).replace("None", filters.DASH)
    out = _EXP_FLOAT.sub(lambda m: filters.sci(float(m.group(0)), 3), out)
    return _prose(_ZERO_FLOAT.sub("0", out))


def appendix_view(rec: dict[str, Any]) -> dict[str, Any]:
    """Verification appendix: certificates and cross-checks, tolerances, versions, seeds, hash."""
    ub = _dict(rec.get("upper_bound"))
    cv = _dict(rec.get("critical_value"))
    rob = _dict(rec.get("robust_critical_value"))
    cb = _dict(rec.get("covariance_bounds"))
    prov = _dict(rec.get("provenance"))
    sim = _dict(rec.get("simulation"))
    st = _dict(rec.get("structure"))
    recorded = [{"name": check_name(_dict(c).get("check")), "status": _dict(c).get("passed"),
                 "none_means": "not applicable",
                 "detail": _detail_text(_dict(c).get("detail"))}
                for c in _list(rec.get("verification"))]
    derived = [
        {"name": "critical value decided exactly", "status": cv.get("exact"),
         "none_means": "not computed", "detail": _prose(cv.get("reason"))},
        {"name": "upper bound certificate re-checked", "status": ub.get("certified"),
         "none_means": "not computed",
         "detail": _detail_text(_dict(ub.get("certificate")).get("verified_by")
                                or ub.get("certificate")) if ub.get("certificate") else ""},
        {"name": "upper bound bracket (lower evidence)", "none_means": "not computed",
         "status": None if ub.get("lower_evidence") is None else bool(ub.get("lower_evidence")),
         "detail": _detail_text(_dict(ub.get("lower_evidence")).get("statement")
                                or ub.get("lower_evidence")) if ub.get("lower_evidence")
         else ""},
        {"name": "upper covariance bound V̄ solves the MARE", "none_means": "not computed",
         "status": _dict(cb.get("upper")).get("exists"),
         "detail": f"residual {filters.sci(_dict(cb.get('upper')).get('residual'), 3)}"
         if _num(_dict(cb.get("upper")).get("residual")) is not None else ""},
        {"name": "lower covariance bound S̄ exists (Lyapunov)", "none_means": "not computed",
         "status": _dict(cb.get("lower")).get("exists"), "detail": ""},
    ]
    # The record's own verification list when the analysis provides one; else what the
    # sections' flags say (read, not recomputed).
    checks = recorded + derived[:1] if recorded else derived
    opts = _dict(prov.get("options"))
    stol = _dict(st.get("tolerances"))
    tolerances = [
        row("robust-value tolerance (relative)", rob.get("tolerance", opts.get("tolerance")),
            "sci"),
        row("upper-bound tolerance", ub.get("tolerance", opts.get("upper_tol")), "sci"),
        row("upper-bound method", ub.get("method")),
        row("upper-bound solver", None, note=_solver_text(ub.get("solver"))),
    ]
    if stol:
        tolerances.append(row("structure analysis", None, note=", ".join(
            x for x in (("exact arithmetic" if stol.get("exact") else "floating point")
                        if "exact" in stol else "",
                        f"time budget {filters.num(stol.get('time_budget_seconds'))} s"
                        if stol.get("time_budget_seconds") is not None else "",
                        f"at most {filters.num(stol.get('max_states'))} states for exact work"
                        if stol.get("max_states") is not None else "") if x)))
    seeds = sim.get("seeds") if sim.get("seeds") is not None else prov.get("seed")
    versions = dict(_dict(prov.get("versions")))
    if versions.get("kfcrit") != __version__:
        versions["kfcrit (report)"] = __version__
    versions.update({name: v for name, v in report_versions().items()
                     if name not in versions and name.lower() not in versions})
    options = [row(OPTION_LABELS.get(k, (filters.key_label(k), "text"))[0], v,
                   OPTION_LABELS.get(k, ("", "text"))[1],
                   note="default for the mode" if v is None and k in ("paths", "steps") else "")
               for k, v in opts.items()]
    return {"checks": checks, "tolerances": tolerances,
            "upper_warnings": [_prose(w) for w in _list(ub.get("warnings"))],
            "versions": [row(str(k), v if v is not None else "not installed")
                         for k, v in versions.items()],
            "seeds": seeds_text(seeds),
            "sha256": prov.get("input_sha256"), "input_path": prov.get("input_path"),
            "options": options}


REPORT_PACKAGES = ("weasyprint", "PyYAML", "numba", "mpmath")


def report_versions() -> dict[str, str | None]:
    """Versions of the packages behind the report and the analysis that the record's
    provenance may not list (``None``: not installed), read from the installed metadata."""
    from importlib import metadata

    out: dict[str, str | None] = {}
    for name in REPORT_PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


def view_model(record: dict[str, Any], figures: dict[str, str | None]) -> dict[str, Any]:
    """Every value the templates read, from the record and the figures (no computation left).

    Parameters
    ----------
    record : dict
        ``Analysis.to_dict()`` (any section may be ``None`` or absent).
    figures : dict
        Inline SVG strings from :func:`kfcrit.views.figures.build_figures` (``None`` where missing).
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
        "warnings": [_prose(w) for w in _list(rec.get("warnings"))],
        "system": system_view(rec),
        "structure": structure_view(rec),
        "classification": classification_view(rec),
        "bounds": bounds_view(rec),
        "covariance": covariance_view(rec),
        "figures": figures_view(figures, rec),
        "simulation": simulation_view(rec),
        "requirement": requirement_view(rec),
        "statements": statements_view(rec),
        "invariant": invariant_view(rec, _dict(figures).get("invariant")),
        "channel": channel_view(rec),
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
                   max_states: int, tolerance: float = 1e-9) -> int:
    """``kfcrit report``: analyse ``system_file`` and write the HTML or PDF report to ``output``.

    Returns the exit code (:func:`kfcrit.cli.main.exit_code_of` of the record: 3 when the upper bound
    was inconclusive, else 0). Bad paths or formats raise :class:`~kfcrit.errors.InputError`.
    """
    from kfcrit.analysis.record import AnalysisOptions, analyze
    from kfcrit.cli.main import exit_code_of
    from kfcrit.views.figures import build_figures
    from kfcrit.io.systemfile import load_spec

    kind = output_format(output, fmt)
    out = check_output_path(system_file, output)
    _progress(f"reading {system_file}")
    spec = load_spec(system_file, max_states=max_states)
    _progress("analysing" + (" (quick draft)" if quick else ""))
    record = analyze(spec, AnalysisOptions(quick=quick, seed=seed,
                                           tolerance=tolerance)).to_dict()
    _progress("drawing figures")
    figures = build_figures(record)
    _progress(f"rendering {kind.upper()}")
    html = render_html(record, figures)
    data = render_pdf(html) if kind == "pdf" else html.encode("utf-8")
    write_atomic(out, data)
    _progress(f"wrote {out} ({len(data)} bytes)")
    return exit_code_of(record)
