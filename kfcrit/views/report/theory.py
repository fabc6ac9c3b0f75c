"""View model of the theory sections: the system, its structure, the classification and the
theorem that decides p_c, the bounds table, fixed-gain estimators, covariance bounds, the
almost-sure statements and the invariant distribution of scalar systems."""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

from markupsafe import Markup

from kfcrit.errors import ExpressionError
from kfcrit.model.exprparse import parse_with_float
from kfcrit.records.covariance import BestStaticGain
from kfcrit.theory.critical.numtext import modulus_from_p_low
from kfcrit.views import formatting as filters
from kfcrit.views.figures import mathsvg
from kfcrit.views.figures.record import invariant_gaps
from kfcrit.views.report.network import is_network
from kfcrit.views.report.parts import (
    INPUT_DIGITS,
    closed_form_text,
    complex_html,
    decimal_entry,
    exact_claim,
    exact_p_low,
    exact_plain,
    formula,
    input_exact,
    maybe_svg,
    missing,
    number,
    numerical_text,
    prose,
    row,
    safe_svg,
    sentence,
    stated,
    stated_fields,
)
from kfcrit.views.text.netmargin import NETWORK_P_MEANING

if TYPE_CHECKING:
    from kfcrit.analysis.sections import (
        AnalysisRecord,
        CriticalValueRecord,
        SystemSection,
        UpperBoundRecord,
    )
    from kfcrit.records.contract import RobustCriticalValue
    from kfcrit.records.covariance import CovarianceSummary, ValueExpression
    from kfcrit.records.structure import Eigenvalue, StandardForm, StructureRecord

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

def matrix_cell(entry: str, exact_input: bool) -> dict[str, Any]:
    """One matrix entry ``{text, svg}``: an exact input's entry as read (typeset unless plain),
    a floating-point input's entry as a decimal (never its binary expansion's fraction)."""
    text = str(entry)
    if not exact_input:
        return {"text": decimal_entry(text), "svg": None}
    return {"text": text,
            "svg": None if mathsvg.is_plain(text) else safe_svg(mathsvg.expression_svg(text))}


def matrices_view(system: SystemSection, exact_input: bool = True) -> list[dict[str, Any]]:
    """The matrices as rows of cells (:func:`matrix_cell`)."""
    out = []
    for name, rows in stated_fields(system.matrices):
        cells = [[matrix_cell(e, exact_input) for e in row] for row in rows]
        label = {"Sigma0": "Σ₀"}.get(name, name)
        out.append({"name": label, "rows": cells})
    return out


def system_view(rec: AnalysisRecord) -> dict[str, Any]:
    """Sizes, exactness, exact matrices and channel."""
    system = rec.system
    return {"available": True, "missing": missing("system"),
            "n": system.n, "m": system.m, "exact_input": system.exact_input,
            "input_digits": INPUT_DIGITS,
            "matrices": matrices_view(system, system.exact_input is not False)}


def eigenvalue_numerical(e: Eigenvalue) -> str:
    """An eigenvalue without a short closed form: re ± im·j at 6 digits, marked numerical."""
    if number(e.re) is None:
        return filters.DASH
    return f"{complex_html(e.re, e.im)} (numerical)"


def form_entry(entry: str | list[float | None], exact: bool = True) -> str:
    """One entry of C·V: its short closed form (exact analysis of exact input), else its value
    at 6 digits marked numerical; a float pair ``[re, im]`` is a computed complex number."""
    if isinstance(entry, list):
        if len(entry) == 2 and all(number(x) is not None for x in entry):
            return f"{complex_html(entry[0], entry[1])} (numerical)"
    short = exact_plain(entry) if exact else None
    if short:
        return filters.pretty_expr(short)
    try:
        return numerical_text(parse_with_float(str(entry))[1])
    except (ExpressionError, ValueError, TypeError, ArithmeticError):
        return "a number with no short closed form"


def standard_form_note(form: StandardForm, exact: bool = True) -> str:
    """The standard form of (A, C) in words: the basis and C·V of each equi-block
    (``exact``: the analysis was exact on exact input, so short closed forms are shown)."""
    parts = [prose(form.basis)] if form.basis else []
    for b in form.equi_blocks:
        cols: list[Any] = list(b.C_columns)
        if cols:
            # one column of C·V per eigenvalue; a column of m > 1 entries reads (a; b)
            text = ", ".join(
                form_entry(c[0], exact) if len(c) == 1 else
                "(" + "; ".join(form_entry(e, exact) for e in c) + ")" for c in cols)
            parts.append(f"C·V on I = {filters.indices(b.indices)}: [{text}]")
    return "; ".join(parts)


def top_modulus_form(rec: AnalysisRecord) -> tuple[str, float] | None:
    """ρ(A) in closed form from the record's exact p_low (the upper bound's lower evidence,
    computed from exact eigenvalues) when the structure itself has only floats: exact input
    only (:func:`kfcrit.theory.critical.numtext.modulus_from_p_low`)."""
    if not input_exact(rec) or rec.upper_bound is None:
        return None
    ev = stated(rec.upper_bound.lower_evidence)
    expr = stated(ev.expression) if ev is not None else None
    if ev is None or not isinstance(expr, str) \
            or not str(stated(ev.p_low_how) or "").startswith("exact"):
        return None
    return modulus_from_p_low(expr)


def structure_flags(st: StructureRecord | None) -> list[dict[str, Any]]:
    """The structural yes/no flags of (A, C) and Q (unknown without a structure section)."""
    return [{"label": label, "value": value if st is not None else None} for label, value in (
        ("A diagonalizable", st and st.diagonalizable),
        ("(A, C) observable", st and st.observable),
        ("(A, C) detectable", st and st.detectable),
        (Markup("(A, Q<sup>1/2</sup>) controllable"), st and st.controllable_Q))]


def structure_view(rec: AnalysisRecord) -> dict[str, Any]:
    """Eigenvalues with moduli, equi-blocks, equal-modulus pairs and the structural flags."""
    st = rec.structure
    exact = st is not None and st.path == "exact" and input_exact(rec)
    top = top_modulus_form(rec)
    # the structure's own tolerance for equal moduli decides which |λ| equal ρ(A)
    tol = (number(stated(st.tolerances.modulus_relative)) if st is not None else None) or 1e-14
    eigs = []
    for e in st.eigenvalues if st is not None else []:
        expr = exact_plain(e.modulus_expression) if exact else None
        if expr is None and top and number(e.modulus) is not None \
                and abs(e.modulus - top[1]) <= tol * top[1]:
            expr = top[0]
        value = (exact_plain(e.value) if exact else None) or eigenvalue_numerical(e)
        if top and expr == top[0] and not number(e.im) and number(e.re):
            value = expr if e.re > 0 else f"-{expr}"   # a real λ is ±|λ|
        eigs.append({"value": value, "value_svg": maybe_svg(value),
                     "re": number(e.re), "im": number(e.im),
                     "modulus": number(e.modulus),
                     "modulus_expression": expr or (
                         "no short closed form" if exact else "— (numerical)"),
                     "modulus_svg": maybe_svg(expr)})
    blocks = [{"indices": b.indices, "modulus": number(b.modulus),
               "modulus_expression": b.modulus_expression, "size": b.size,
               "unstable": b.unstable_or_critical,
               "one_step_observable": b.one_step_observable, "rank": b.rank}
              for b in (st.equi_blocks if st is not None else [])]
    pairs = [{"indices": q.indices, "degenerate": q.degenerate, "q": q.q,
              "turn": number(q.turn), "turn_expression": q.turn_expression, "rank": q.rank}
             for q in (st.equal_modulus_pairs if st is not None else [])]
    flags = structure_flags(st)
    rows = [row("analysis path", st.path if st is not None else None,
                note=prose(st.path_reason) if st is not None else "")]
    if st is not None and st.observability_index is not None:
        rows.append(row("observability index I_o", st.observability_index, "num",
                        note="smallest k with rank [C; CA; …; CAᵏ⁻¹] = n"))
    if st is not None:
        rows.append(row("undecided structural questions", None,
                        note="; ".join(prose(str(u)) for u in st.unresolved)
                        or "none: every structural question was decided"))
        rows.append(row("standard form (eigenbasis V)", None,
                        note=standard_form_note(st.standard_form, exact) or filters.DASH))
    return {"available": st is not None, "missing": missing("structure analysis"),
            "eigenvalues": eigs, "equi_blocks": blocks, "pairs": pairs,
            "pairs_listed": st is not None,
            "flags": flags, "rows": rows, "path": st.path if st is not None else None}


def classification_name(rec: AnalysisRecord) -> str | None:
    """The record's classification as its word (``non-degenerate`` ...), ``None`` without."""
    return rec.classification.value if rec.classification is not None else None


def classification_view(rec: AnalysisRecord) -> dict[str, Any]:
    """The classification, the theorem that decides it and its formula (typeset)."""
    cls = classification_name(rec)
    cv = rec.critical_value
    reason = prose(cv.reason) if cv is not None else ""
    name, latex, why = theorem_for(cls)
    exact = exact_claim(rec, cv)
    return {"available": bool(cls),
            "missing": missing("classification", reason or None),
            "name": cls, "theorem": name, "why": why, "general_latex": latex,
            "general_svg": safe_svg(mathsvg.latex_svg(latex, fontsize=12)),
            "instance_svg": formula(cv.latex, cv.expression, fontsize=12,
                                    label=cv.expression) if exact and cv is not None else None,
            "instance_expression": closed_form_text(cv.expression)
            if exact and cv is not None else None,
            "value": number(cv.value) if cv is not None else None,
            "reason": reason or None, "exact": exact}


FLOAT_INPUT_DECIDED = ("not computed: the structure was decided on the rationals that the "
                       "floating-point input's binary floats represent")


def critical_detail(cv: CriticalValueRecord | None, exact_input: bool) -> str:
    """How p_c was obtained, for the bounds table: exact only for an exact value of an exact
    input; a floating-point input's value is numerical even when decided on its rationals."""
    exact = cv.exact if cv is not None else None
    if exact and exact_input:
        return "exact (decided symbolically)"
    if exact:
        return ("numerical: floating-point input (the structure decided on the rationals its "
                "binary floats represent)")
    if exact is False:
        return "numerical (bracket closed to the tolerance)"
    return ""


def bounds_view(rec: AnalysisRecord) -> dict[str, Any]:
    """Rows of the bounds table, the higher-moment thresholds and the fixed-gain comparison."""
    lb, blb = rec.lower_bound, rec.block_lower_bound
    cv, rob, ub = rec.critical_value, rec.robust_critical_value, rec.upper_bound
    cv_value = number(cv.value) if cv is not None else None
    cv_reason = cv.reason if cv is not None else None
    exact_in, cv_exact = input_exact(rec), exact_claim(rec, cv)
    rows = [
        {"symbol": "p_low", "name": "lower bound p_low", "available": lb is not None,
         "value": number(lb.value) if lb is not None else None,
         "expression": exact_p_low(rec) if lb is not None else None,
         "detail": "1 − 1/max|λᵢ|²: necessary for mean stability",
         "source": "Sinopoli et al., Theorem 3"},
        {"symbol": "p_block", "name": "block lower bound", "available": blb is not None,
         "value": number(blb.value) if blb is not None else None,
         "expression": closed_form_text(blb.expression) if exact_in and blb is not None
         else None,
         "detail": "largest critical value of an equi-block",
         "source": "Mo–Sinopoli, Theorem 3"},
        {"symbol": "p_c", "name": "critical value p_c",
         "available": cv_value is not None, "value": cv_value,
         "expression": closed_form_text(cv.expression) if cv_exact and cv is not None
         else None,
         "detail": critical_detail(cv, exact_in),
         "source": theorem_for(classification_name(rec))[0],
         "missing": "not computed: " + prose(cv_reason) if cv_reason else "not computed"},
        {"symbol": "p_c,robust", "name": "robust critical value",
         "available": rob is not None,
         "value": number(rob.value) if rob is not None else None,
         "expression": closed_form_text(stated(rob.expression)) if exact_in and rob is not None
         else None,
         "detail": _robust_detail(rob),
         "source": "largest p_c within the stated relative perturbation",
         "missing": "not needed: the decision is exact and robust to perturbations"
         if cv_exact else FLOAT_INPUT_DECIDED if cv is not None and cv.exact
         else "not computed"},
        {"symbol": "p_up", "name": "upper bound p_up", "available": ub is not None,
         "value": number(ub.value) if ub is not None else None,
         "expression": upper_expression(ub) if exact_in else None,
         "detail": _upper_detail(ub), "source": "Sinopoli et al., Theorem 5 (LMI)",
         "missing": "not computed"},
    ]
    for r in rows:
        r.setdefault("missing", "not computed")
    th = rec.theory
    moments = [{"q": m.q, "value": number(m.value),
                "expression": closed_form_text(m.expression) if exact_in else None,
                "applies": m.applies}
               for m in (th.moment_thresholds if th is not None else [])]
    note = th.moment_thresholds_note if th is not None else None
    return {"rows": rows, "moments": moments,
            "critical_reason": prose(cv_reason) or None
            if cv is not None and cv.value is not None else None,
            "moments_note": sentence(note) if note else
            "Mo–Sinopoli, Corollary 2: for non-degenerate systems whose eigenvalues are all "
            "unstable, the q-th moment is bounded iff p > 1 − |λ₁|^(−2q).",
            "static_gain": static_gain_view(rec),
            "moments_available": bool(moments),
            "moments_missing": missing("higher-moment thresholds")}


STATIC_GAIN_LABELS = {"kalman": "steady-state Kalman gain K∞ of the lossless filter",
                      "best": "best fixed gain K* (from the p_up certificate)"}


def static_gain_view(rec: AnalysisRecord) -> dict[str, Any]:
    """The fixed-gain (jump-linear) estimators of the record, one table row per gain."""
    sg = rec.static_gain
    gains = []
    for g, label in ((sg.kalman, STATIC_GAIN_LABELS["kalman"]),
                     (sg.best, STATIC_GAIN_LABELS["best"])) if sg is not None else ():
        notes = []
        if isinstance(g, BestStaticGain) and g.equals_p_up:
            notes.append("its critical value equals p_up")
        if g.available is False:
            notes.append(prose(stated(g.reason) or "not available"))
        gains.append({"label": label, "available": g.available is not False,
                      "critical_value": number(stated(g.critical_value)),
                      "gain": stated(g.gain), "covariance_exists": stated(g.covariance_exists),
                      "covariance_trace": number(stated(g.covariance_trace)),
                      "note": "; ".join(notes)})
    return {"available": sg is not None, "p": number(sg.p) if sg is not None else None,
            "gains": gains,
            "missing": missing("fixed-gain estimators", static_gain_reason(rec))}


def static_gain_reason(rec: AnalysisRecord) -> str:
    """Why the record has no fixed-gain section: a network (the analysis is made for one
    link), no operating point (no channel), or simply absent."""
    if is_network(rec):
        return ("the fixed-gain analysis is made for single-link systems only; a sensor "
                "network's arrivals are one per sensor, so one gain against one arrival "
                "probability does not describe it")
    if rec.operating_point is None:
        return "no operating point: the system file has no channel"
    return "the record has no fixed-gain section"


def upper_expression(ub: UpperBoundRecord | None) -> str | None:
    """The exact form of p_up when the record has one: its own ``expression``, or, when p_up is
    decided exactly (method ``exact``), the exact value of the theorem that pins it (the lower
    evidence, e.g. p_up = p_low = 9/25 for invertible C)."""
    if ub is None:
        return None
    ev = stated(ub.lower_evidence)
    if ev is None:
        return None
    value, ev_value = number(ub.value), number(ev.value)
    expr = stated(ev.expression)
    if ub.method == "exact" and expr and value is not None and \
            ev_value is not None and abs(value - ev_value) <= 1e-12 * max(1.0, abs(value)):
        return closed_form_text(expr)
    return None


def _robust_detail(rob: RobustCriticalValue | None) -> str:
    parts = []
    if rob is not None and number(rob.tolerance) is not None:
        parts.append(f"relative tolerance {filters.sci(rob.tolerance, 3)}")
    if rob is not None and stated(rob.nearby_case):
        parts.append(f"nearby case: {filters.text(rob.nearby_case)}")
    return "; ".join(parts)


def _upper_detail(ub: UpperBoundRecord | None) -> str:
    if ub is None:
        return ""
    parts = []
    if ub.certified is not None:
        parts.append("certified" if ub.certified else "not certified")
    iv = ub.interval
    ev = stated(ub.lower_evidence)
    if iv is not None and ub.method == "exact":
        parts.append("decided exactly" + (f": {prose(ev.statement)}"
                                          if ev is not None and ev.statement else ""))
    elif iv is not None:
        parts.append(f"p_up ∈ {filters.interval(iv, 10)}")
    if ub.method:
        parts.append(f"method: {ub.method}")
    if ub.status and ub.status not in ("determined", "certified"):
        parts.append(f"status: {ub.status}")
    return "; ".join(parts)


def covariance_side(x: CovarianceSummary) -> dict[str, Any]:
    """One side (S̄ or V̄) of the covariance bounds: exists, trace, largest eigenvalue."""
    method = stated(x.method)
    # ``computed: False`` (a network's V̄; older records say so only in ``method``):
    # "exists" is then unknown, never a red "no"
    computed = stated(x.computed) is not False and \
        not str(method or "").startswith("not computed")
    return {"exists": x.exists if computed else None, "computed": computed,
            "trace": number(x.trace),
            "max_eig": number(x.max_eig), "residual": number(stated(x.residual)),
            "method": prose(method) or None}


def covariance_view(rec: AnalysisRecord) -> dict[str, Any]:
    """S̄ and V̄ at the operating point (Sinopoli Theorems 4 and 6)."""
    cb = rec.covariance_bounds
    why = "no operating point: the system file has no channel section" \
        if rec.operating_point is None else None
    absent = {"exists": None, "computed": True, "trace": None, "max_eig": None,
              "residual": None, "method": None}
    return {"available": cb is not None, "missing": missing("covariance bounds", why),
            "p": number(cb.p) if cb is not None else None,
            "p_meaning": covariance_p_meaning(rec),
            "lower": covariance_side(cb.lower) if cb is not None else absent,
            "upper": covariance_side(cb.upper) if cb is not None else dict(absent)}


def covariance_p_meaning(rec: AnalysisRecord) -> str | None:
    r"""What the ``p`` of ``covariance_bounds`` is, when it is not the operating point's p.

    For a sensor network the record's S̄ solves :math:`\bar S = \prod_i (1 - p_i) A \bar S A'
    + Q` (its ``reason`` says so), so :math:`p = 1 - \prod_i (1 - p_i)`. ``None`` for a
    single link.
    """
    return NETWORK_P_MEANING if is_network(rec) else None


def statements_view(rec: AnalysisRecord) -> dict[str, Any]:
    """Almost-sure and distributional statements (theory §5–§6) in plain words."""
    th = rec.theory
    sb = th.stochastic_boundedness if th is not None else ""
    sentences = [prose(s) for s in th.almost_sure] if th is not None else []
    return {"available": bool(sb) or bool(sentences),
            "missing": missing("almost-sure and distributional statements"),
            "stochastic_boundedness": [prose(sb)] if sb else [],
            "almost_sure": sentences}


def _value_expr(x: ValueExpression) -> tuple[float | None, str | None]:
    """(value, exact expression) of a record number given as ``{value, expression}``."""
    return number(x.value), closed_form_text(x.expression)


def invariant_view(rec: AnalysisRecord, figure: str | None) -> dict[str, Any]:
    """Support of the invariant distribution (scalar systems only)."""
    inv = rec.invariant
    exact = [{"n": g.n, "lower": number(g.lower), "upper": number(g.upper),
              "lower_expression": g.lower_expression, "upper_expression": g.upper_expression}
             for g in (inv.gap_levels if inv is not None else [])]
    exact = [{**g, "pair": [g["lower"], g["upper"]]} for g in exact
             if g["lower"] is not None and g["upper"] is not None]
    known = {(round(g["lower"], 9), round(g["upper"], 9)) for g in exact}
    gaps = [g for g in (invariant_gaps(inv) if inv is not None else [])
            if (round(g[0], 9), round(g[1], 9)) not in known]
    rows = []
    if inv is not None:
        pstar, pstar_expr = _value_expr(inv.fixed_point)
        if pstar is not None:
            rows.append(row("Riccati fixed point P* (left end of the support)", pstar, "num",
                            note=f"= {filters.pretty_expr(pstar_expr)}" if pstar_expr else ""))
        rows.append(row("Riccati maps", None, note="; ".join(
            f"{filters.key_label(k)}: {prose(v)}" for k, v in stated_fields(inv.maps))))
        lim, lim_expr = _value_expr(inv.arrival_limit)
        if lim is not None:
            rows.append(row("limit f₁(∞) of the arrival map", lim, "num",
                            note=f"= {filters.pretty_expr(lim_expr)}" if lim_expr else ""))
        ss = inv.self_similarity
        if ss.statement:
            rows.append(row("self-similarity", prose(ss.statement), note=prose(ss.pieces)))
        sp = inv.support_points
        rows.append(row("support points computed", sp.count, "count",
                        note=f"compositions of depth {filters.num(sp.depth)} in "
                        f"{filters.interval(sp.window, 6)}"))
    return {"applies": rec.system.n == 1 and not is_network(rec),
            "available": inv is not None,
            "scope": ("The support of the invariant distribution is characterised for one link "
                      "(Kar–Sinopoli–Moura, Theorem 10); a sensor network has one arrival per "
                      "sensor, so it is not computed here.") if is_network(rec) else "",
            "missing": missing("invariant distribution support"),
            "exact_gaps": exact[:10], "gaps": gaps[:10], "more_gaps": max(0, len(gaps) - 10),
            "rows": rows, "note": sentence(inv.note if inv is not None else None)}
