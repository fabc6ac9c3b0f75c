"""View model of the theory sections: the system, its structure, the classification and the
theorem that decides p_c, the bounds table, fixed-gain estimators, covariance bounds, the
almost-sure statements and the invariant distribution of scalar systems."""
from __future__ import annotations

from typing import Any

from markupsafe import Markup

from kfcrit.analysis.records.covariance import Invariant
from kfcrit.errors import ExpressionError
from kfcrit.model.exprparse import parse_with_float
from kfcrit.theory.critical.numtext import modulus_from_p_low
from kfcrit.views import formatting as filters
from kfcrit.views.figures import mathsvg
from kfcrit.views.figures.record import invariant_gaps
from kfcrit.views.report.network import is_network
from kfcrit.views.report.parts import (
    INPUT_DIGITS,
    as_dict,
    as_list,
    closed_form_text,
    complex_html,
    decimal_entry,
    exact_claim,
    exact_p_low,
    exact_plain,
    formula,
    input_exact,
    kv_rows,
    maybe_svg,
    missing,
    number,
    numerical_text,
    prose,
    row,
    safe_svg,
    sentence,
    typed_section,
)
from kfcrit.views.text.netmargin import NETWORK_P_MEANING

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

def matrix_cell(entry: Any, exact_input: bool) -> dict[str, Any]:
    """One matrix entry ``{text, svg}``: an exact input's entry as read (typeset unless plain),
    a floating-point input's entry as a decimal (never its binary expansion's fraction)."""
    text = str(entry)
    if not exact_input:
        return {"text": decimal_entry(text), "svg": None}
    return {"text": text,
            "svg": None if mathsvg.is_plain(text) else safe_svg(mathsvg.expression_svg(text))}


def matrices_view(system: dict[str, Any], exact_input: bool = True) -> list[dict[str, Any]]:
    """The matrices as rows of cells (:func:`matrix_cell`)."""
    out = []
    for name, rows in as_dict(system.get("matrices")).items():
        if not isinstance(rows, list):
            continue
        cells = [[matrix_cell(e, exact_input) for e in as_list(row)] for row in rows]
        label = {"Sigma0": "Σ₀"}.get(name, name)
        out.append({"name": label, "rows": cells})
    return out


def system_view(rec: dict[str, Any]) -> dict[str, Any]:
    """Sizes, exactness, exact matrices and channel."""
    sysd = rec.get("system")
    d = as_dict(sysd)
    return {"available": isinstance(sysd, dict), "missing": missing("system"),
            "n": d.get("n"), "m": d.get("m"), "exact_input": d.get("exact_input"),
            "input_digits": INPUT_DIGITS,
            "matrices": matrices_view(d, d.get("exact_input") is not False)}



STRUCTURE_KNOWN = {"eigenvalues", "equi_blocks", "diagonalizable", "detectable", "controllable_Q",
                   "path", "path_reason", "tolerances", "equal_modulus_pairs",
                   "observability_index", "observable", "standard_form", "unresolved"}


def eigenvalue_numerical(e: dict[str, Any]) -> str:
    """An eigenvalue without a short closed form: re ± im·j at 6 digits, marked numerical."""
    if number(e.get("re")) is None:
        return filters.DASH
    return f"{complex_html(e.get('re'), e.get('im'))} (numerical)"


def form_entry(entry: Any, exact: bool = True) -> str:
    """One entry of C·V: its short closed form (exact analysis of exact input), else its value
    at 6 digits marked numerical; a float pair ``[re, im]`` is a computed complex number."""
    pair = as_list(entry)
    if len(pair) == 2 and all(number(x) is not None for x in pair):
        return f"{complex_html(pair[0], pair[1])} (numerical)"
    short = exact_plain(entry) if exact else None
    if short:
        return filters.pretty_expr(short)
    try:
        return numerical_text(parse_with_float(str(entry))[1])
    except (ExpressionError, ValueError, TypeError, ArithmeticError):
        return "a number with no short closed form"


def standard_form_note(form: Any, exact: bool = True) -> str:
    """The standard form of (A, C) in words: the basis and C·V of each equi-block
    (``exact``: the analysis was exact on exact input, so short closed forms are shown)."""
    d = as_dict(form)
    parts = [prose(d["basis"])] if d.get("basis") else []
    for b in as_list(d.get("equi_blocks")):
        cols = as_list(as_dict(b).get("C_columns"))
        if cols:
            # one column of C·V per eigenvalue; a column of m > 1 entries reads (a; b)
            text = ", ".join(
                form_entry(as_list(c)[0], exact) if len(as_list(c)) == 1 else
                "(" + "; ".join(form_entry(e, exact) for e in as_list(c)) + ")" for c in cols)
            parts.append(f"C·V on I = {filters.indices(as_dict(b).get('indices'))}: [{text}]")
    return "; ".join(parts)


def top_modulus_form(rec: dict[str, Any]) -> tuple[str, float] | None:
    """ρ(A) in closed form from the record's exact p_low (the upper bound's lower evidence,
    computed from exact eigenvalues) when the structure itself has only floats: exact input
    only (:func:`kfcrit.theory.critical.numtext.modulus_from_p_low`)."""
    if not input_exact(rec):
        return None
    ev = as_dict(as_dict(rec.get("upper_bound")).get("lower_evidence"))
    expr = ev.get("expression")
    if not isinstance(expr, str) or not str(ev.get("p_low_how", "")).startswith("exact"):
        return None
    return modulus_from_p_low(expr)


def structure_view(rec: dict[str, Any]) -> dict[str, Any]:
    """Eigenvalues with moduli, equi-blocks, equal-modulus pairs and the structural flags."""
    st = rec.get("structure")
    d = as_dict(st)
    exact = d.get("path") == "exact" and input_exact(rec)
    top = top_modulus_form(rec)
    # the structure's own tolerance for equal moduli decides which |λ| equal ρ(A)
    tol = number(as_dict(d.get("tolerances")).get("modulus_relative")) or 1e-14
    eigs = []
    for e in as_list(d.get("eigenvalues")):
        e = as_dict(e)
        expr = exact_plain(e.get("modulus_expression")) if exact else None
        if expr is None and top and number(e.get("modulus")) is not None \
                and abs(e["modulus"] - top[1]) <= tol * top[1]:
            expr = top[0]
        value = (exact_plain(e.get("value")) if exact else None) or eigenvalue_numerical(e)
        if top and expr == top[0] and not number(e.get("im")) and number(e.get("re")):
            value = expr if e["re"] > 0 else f"-{expr}"   # a real λ is ±|λ|
        eigs.append({"value": value, "value_svg": maybe_svg(value),
                     "re": number(e.get("re")), "im": number(e.get("im")),
                     "modulus": number(e.get("modulus")),
                     "modulus_expression": expr or (
                         "no short closed form" if exact else "— (numerical)"),
                     "modulus_svg": maybe_svg(expr)})
    blocks = [{"indices": as_dict(b).get("indices"), "modulus": number(as_dict(b).get("modulus")),
               "modulus_expression": as_dict(b).get("modulus_expression"),
               "size": as_dict(b).get("size"),
               "unstable": as_dict(b).get("unstable_or_critical"),
               "one_step_observable": as_dict(b).get("one_step_observable"),
               "rank": as_dict(b).get("rank")} for b in as_list(d.get("equi_blocks"))]
    pairs = [{"indices": as_dict(q).get("indices"), "degenerate": as_dict(q).get("degenerate"),
              "q": as_dict(q).get("q"), "turn": number(as_dict(q).get("turn")),
              "turn_expression": as_dict(q).get("turn_expression"), "rank": as_dict(q).get("rank")}
             for q in as_list(d.get("equal_modulus_pairs"))]
    flags = [{"label": label, "value": d.get(key)} for key, label in (
        ("diagonalizable", "A diagonalizable"), ("observable", "(A, C) observable"),
        ("detectable", "(A, C) detectable"), ("controllable_Q", Markup("(A, Q<sup>1/2</sup>) controllable")))]
    rows = [row("analysis path", d.get("path"), note=prose(d.get("path_reason")))]
    if d.get("observability_index") is not None:
        rows.append(row("observability index I_o", d.get("observability_index"), "num",
                        note="smallest k with rank [C; CA; …; CAᵏ⁻¹] = n"))
    if isinstance(d.get("unresolved"), list):
        rows.append(row("undecided structural questions", None,
                        note="; ".join(prose(str(u)) for u in d["unresolved"])
                        or "none: every structural question was decided"))
    if isinstance(d.get("standard_form"), dict):
        rows.append(row("standard form (eigenbasis V)", None,
                        note=standard_form_note(d["standard_form"], exact) or filters.DASH))
    return {"available": isinstance(st, dict), "missing": missing("structure analysis"),
            "eigenvalues": eigs, "equi_blocks": blocks, "pairs": pairs,
            "pairs_listed": isinstance(d.get("equal_modulus_pairs"), list),
            "flags": flags, "rows": rows, "path": d.get("path"),
            "extra": kv_rows(d, skip=STRUCTURE_KNOWN)}


def classification_view(rec: dict[str, Any]) -> dict[str, Any]:
    """The classification, the theorem that decides it and its formula (typeset)."""
    cls = rec.get("classification")
    cv = as_dict(rec.get("critical_value"))
    name, latex, why = theorem_for(cls if isinstance(cls, str) else None)
    exact = exact_claim(rec, cv)
    return {"available": isinstance(cls, str) and bool(cls),
            "missing": missing("classification", prose(cv.get("reason")) or None),
            "name": cls, "theorem": name, "why": why, "general_latex": latex,
            "general_svg": safe_svg(mathsvg.latex_svg(latex, fontsize=12)),
            "instance_svg": formula(cv.get("latex"), cv.get("expression"), fontsize=12,
                                    label=cv.get("expression")) if exact else None,
            "instance_expression": closed_form_text(cv.get("expression")) if exact else None,
            "value": number(cv.get("value")),
            "reason": prose(cv.get("reason")) or None, "exact": exact}


FLOAT_INPUT_DECIDED = ("not computed: the structure was decided on the rationals that the "
                       "floating-point input's binary floats represent")


def critical_detail(cv: dict[str, Any], exact_input: bool) -> str:
    """How p_c was obtained, for the bounds table: exact only for an exact value of an exact
    input; a floating-point input's value is numerical even when decided on its rationals."""
    if cv.get("exact") and exact_input:
        return "exact (decided symbolically)"
    if cv.get("exact"):
        return ("numerical: floating-point input (the structure decided on the rationals its "
                "binary floats represent)")
    if cv.get("exact") is False:
        return "numerical (bracket closed to the tolerance)"
    return ""


def bounds_view(rec: dict[str, Any]) -> dict[str, Any]:
    """Rows of the bounds table, the higher-moment thresholds and the fixed-gain comparison."""
    lb, blb = rec.get("lower_bound"), rec.get("block_lower_bound")
    cv, rob, ub = rec.get("critical_value"), rec.get("robust_critical_value"), \
        rec.get("upper_bound")
    cvd, ubd = as_dict(cv), as_dict(ub)
    cls = rec.get("classification") if isinstance(rec.get("classification"), str) else None
    exact_in, cv_exact = input_exact(rec), exact_claim(rec, cvd)
    rows = [
        {"symbol": "p_low", "name": "lower bound p_low", "available": isinstance(lb, dict),
         "value": number(as_dict(lb).get("value")),
         "expression": exact_p_low(rec) if isinstance(lb, dict) else None,
         "detail": "1 − 1/max|λᵢ|²: necessary for mean stability",
         "source": "Sinopoli et al., Theorem 3"},
        {"symbol": "p_block", "name": "block lower bound", "available": isinstance(blb, dict),
         "value": number(as_dict(blb).get("value")),
         "expression": closed_form_text(as_dict(blb).get("expression")) if exact_in else None,
         "detail": "largest critical value of an equi-block",
         "source": "Mo–Sinopoli, Theorem 3"},
        {"symbol": "p_c", "name": "critical value p_c",
         "available": number(cvd.get("value")) is not None,
         "value": number(cvd.get("value")),
         "expression": closed_form_text(cvd.get("expression")) if cv_exact else None,
         "detail": critical_detail(cvd, exact_in),
         "source": theorem_for(cls)[0],
         "missing": "not computed: " + prose(cvd.get("reason")) if cvd.get("reason")
         else "not computed"},
        {"symbol": "p_c,robust", "name": "robust critical value",
         "available": isinstance(rob, dict),
         "value": number(as_dict(rob).get("value")),
         "expression": closed_form_text(as_dict(rob).get("expression")) if exact_in else None,
         "detail": _robust_detail(as_dict(rob)),
         "source": "largest p_c within the stated relative perturbation",
         "missing": "not needed: the decision is exact and robust to perturbations"
         if cv_exact else FLOAT_INPUT_DECIDED if cvd.get("exact") else "not computed"},
        {"symbol": "p_up", "name": "upper bound p_up", "available": isinstance(ub, dict),
         "value": number(ubd.get("value")),
         "expression": upper_expression(ubd) if exact_in else None,
         "detail": _upper_detail(ubd), "source": "Sinopoli et al., Theorem 5 (LMI)",
         "missing": "not computed"},
    ]
    for r in rows:
        r.setdefault("missing", "not computed")
    th = as_dict(rec.get("theory"))
    moments = [{"q": as_dict(m).get("q"), "value": number(as_dict(m).get("value")),
                "expression": closed_form_text(as_dict(m).get("expression")) if exact_in else None,
                "applies": as_dict(m).get("applies")}
               for m in as_list(th.get("moment_thresholds"))]
    note = th.get("moment_thresholds_note")
    return {"rows": rows, "moments": moments,
            "critical_reason": prose(cvd.get("reason")) or None
            if cvd.get("value") is not None else None,
            "moments_note": sentence(note) if note else
            "Mo–Sinopoli, Corollary 2: for non-degenerate systems whose eigenvalues are all "
            "unstable, the q-th moment is bounded iff p > 1 − |λ₁|^(−2q).",
            "static_gain": static_gain_view(rec),
            "moments_available": bool(moments),
            "moments_missing": missing("higher-moment thresholds")}


STATIC_GAIN_LABELS = {"kalman": "steady-state Kalman gain K∞ of the lossless filter",
                      "best": "best fixed gain K* (from the p_up certificate)"}


def static_gain_view(rec: dict[str, Any]) -> dict[str, Any]:
    """The fixed-gain (jump-linear) estimators of the record, one table row per gain."""
    sg = rec.get("static_gain")
    d = as_dict(sg)
    gains = []
    for key, label in STATIC_GAIN_LABELS.items():
        g = as_dict(d.get(key))
        if not g:
            continue
        notes = []
        if g.get("equals_p_up"):
            notes.append("its critical value equals p_up")
        if g.get("available") is False:
            notes.append(prose(g.get("reason") or "not available"))
        gains.append({"label": label, "available": g.get("available") is not False,
                      "critical_value": number(g.get("critical_value")),
                      "gain": g.get("gain"), "covariance_exists": g.get("covariance_exists"),
                      "covariance_trace": number(g.get("covariance_trace")),
                      "note": "; ".join(notes)})
    return {"available": isinstance(sg, dict), "p": number(d.get("p")), "gains": gains,
            "missing": missing("fixed-gain estimators", static_gain_reason(rec))}


def static_gain_reason(rec: dict[str, Any]) -> str:
    """Why the record has no fixed-gain section: a network (the analysis is made for one
    link), no operating point (no channel), or simply absent."""
    if is_network(rec):
        return ("the fixed-gain analysis is made for single-link systems only; a sensor "
                "network's arrivals are one per sensor, so one gain against one arrival "
                "probability does not describe it")
    if rec.get("operating_point") is None:
        return "no operating point: the system file has no channel"
    return "the record has no fixed-gain section"


def upper_expression(ub: dict[str, Any]) -> str | None:
    """The exact form of p_up when the record has one: its own ``expression``, or, when p_up is
    decided exactly (method ``exact``), the exact value of the theorem that pins it (the lower
    evidence, e.g. p_up = p_low = 9/25 for invertible C)."""
    own = closed_form_text(ub.get("expression"))
    if own:
        return own
    ev = as_dict(ub.get("lower_evidence"))
    value, ev_value = number(ub.get("value")), number(ev.get("value"))
    if ub.get("method") == "exact" and ev.get("expression") and value is not None and \
            ev_value is not None and abs(value - ev_value) <= 1e-12 * max(1.0, abs(value)):
        return closed_form_text(ev["expression"])
    return None


def _robust_detail(rob: dict[str, Any]) -> str:
    parts = []
    if number(rob.get("tolerance")) is not None:
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
        ev = as_dict(ub.get("lower_evidence"))
        parts.append("decided exactly" + (f": {prose(ev['statement'])}"
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
    d = as_dict(cb)

    def side(x: Any) -> dict[str, Any]:
        x = as_dict(x)
        # ``computed: False`` (a network's V̄; older records say so only in ``method``):
        # "exists" is then unknown, never a red "no"
        computed = x.get("computed") is not False and \
            not str(x.get("method") or "").startswith("not computed")
        return {"exists": x.get("exists") if computed else None, "computed": computed,
                "trace": number(x.get("trace")),
                "max_eig": number(x.get("max_eig")), "residual": number(x.get("residual")),
                "method": prose(x.get("method")) or None}

    why = "no operating point: the system file has no channel section" \
        if rec.get("operating_point") is None else None
    return {"available": isinstance(cb, dict), "missing": missing("covariance bounds", why),
            "p": number(d.get("p")), "p_meaning": covariance_p_meaning(rec),
            "lower": side(d.get("lower")), "upper": side(d.get("upper"))}


def covariance_p_meaning(rec: dict[str, Any]) -> str | None:
    r"""What the ``p`` of ``covariance_bounds`` is, when it is not the operating point's p.

    For a sensor network the record's S̄ solves :math:`\bar S = \prod_i (1 - p_i) A \bar S A'
    + Q` (its ``reason`` says so), so :math:`p = 1 - \prod_i (1 - p_i)`; a ``p_meaning`` in
    the record, when present, is used as written. ``None`` for a single link.
    """
    cb = as_dict(rec.get("covariance_bounds"))
    if cb.get("p_meaning"):
        return prose(cb.get("p_meaning"))
    return NETWORK_P_MEANING if is_network(rec) else None


def _is_series(value: Any) -> bool:
    return isinstance(value, list) and len(value) > 12


def statements_view(rec: dict[str, Any]) -> dict[str, Any]:
    """Almost-sure and distributional statements (theory §5–§6) in plain words."""
    th = rec.get("theory")
    d = as_dict(th)
    sb = d.get("stochastic_boundedness")
    asure = d.get("almost_sure")
    sentences = [prose(s) for s in asure] if isinstance(asure, list) else \
        ([prose(asure)] if isinstance(asure, str) and asure else [])
    known = ("stochastic_boundedness", "almost_sure", "moment_thresholds",
             "moment_thresholds_note", "observability_index")
    return {"available": bool(sb) or bool(sentences),
            "missing": missing("almost-sure and distributional statements"),
            "stochastic_boundedness": [prose(s) for s in sb] if isinstance(sb, list) else
            ([prose(sb)] if sb else []),
            "almost_sure": sentences,
            "extra": kv_rows(d, skip=known)}


def _value_expr(x: Any) -> tuple[float | None, str | None]:
    """(value, exact expression) of a record number given either as ``{value, expression}``
    or as a bare number."""
    if isinstance(x, dict):
        return number(x.get("value")), closed_form_text(x.get("expression"))
    return number(x), None


def invariant_view(rec: dict[str, Any], figure: str | None) -> dict[str, Any]:
    """Support of the invariant distribution (scalar systems only)."""
    n = as_dict(rec.get("system")).get("n")
    inv = rec.get("invariant")
    d = as_dict(inv)

    exact = [{"n": as_dict(g).get("n"), "lower": number(as_dict(g).get("lower")),
              "upper": number(as_dict(g).get("upper")),
              "lower_expression": as_dict(g).get("lower_expression"),
              "upper_expression": as_dict(g).get("upper_expression")}
             for g in as_list(d.get("gap_levels"))]
    exact = [{**g, "pair": [g["lower"], g["upper"]]} for g in exact
             if g["lower"] is not None and g["upper"] is not None]
    known = {(round(g["lower"], 9), round(g["upper"], 9)) for g in exact}
    typed_inv = typed_section(Invariant, d)
    found = invariant_gaps(typed_inv) if typed_inv else []
    gaps = [g for g in found if (round(g[0], 9), round(g[1], 9)) not in known]
    rows = []
    pstar, pstar_expr = _value_expr(d.get("fixed_point"))
    if pstar is not None:
        rows.append(row("Riccati fixed point P* (left end of the support)", pstar, "num",
                        note=f"= {filters.pretty_expr(pstar_expr)}" if pstar_expr else ""))
    maps = as_dict(d.get("maps"))
    if maps:
        rows.append(row("Riccati maps", None, note="; ".join(
            f"{filters.key_label(k)}: {prose(v)}" for k, v in maps.items())))
    lim, lim_expr = _value_expr(d.get("arrival_limit"))
    if lim is not None:
        rows.append(row("limit f₁(∞) of the arrival map", lim, "num",
                        note=f"= {filters.pretty_expr(lim_expr)}" if lim_expr else ""))
    ss = as_dict(d.get("self_similarity"))
    if ss.get("statement"):
        rows.append(row("self-similarity", prose(ss.get("statement")),
                        note=prose(ss.get("pieces"))))
    sp = d.get("support_points")
    if isinstance(sp, dict) and sp.get("count") is not None:
        rows.append(row("support points computed", sp.get("count"), "count",
                        note=f"compositions of depth {filters.num(sp.get('depth'))} in "
                        f"{filters.interval(sp.get('window'), 6)}"))
    elif isinstance(sp, list):
        rows.append(row("support points computed", len(sp), "count"))
    skip = {"gaps", "support_points", "gap_levels", "holes", "fixed_point", "maps",
            "arrival_limit", "self_similarity", "first_gap", "note", "warnings"}
    network = len(as_list(as_dict(rec.get("network")).get("sensors"))) > 1
    return {"applies": n == 1 and not network, "available": isinstance(inv, dict),
            "scope": ("The support of the invariant distribution is characterised for one link "
                      "(Kar–Sinopoli–Moura, Theorem 10); a sensor network has one arrival per "
                      "sensor, so it is not computed here.") if network else "",
            "missing": missing("invariant distribution support"),
            "exact_gaps": exact[:10], "gaps": gaps[:10], "more_gaps": max(0, len(gaps) - 10),
            "rows": rows, "note": sentence(d.get("note")),
            "extra": kv_rows({k: v for k, v in d.items() if not _is_series(v)}, skip=skip)}

