"""View model of the verdict box: the review decision with its reasons, the operating point
against p_c, the link design and the requirement."""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

from kfcrit.records.channel import ChannelRecord
from kfcrit.views.figures.record import tail_of
from kfcrit.views.report.link import (
    CHANNEL_NAMES,
    channel_summary,
    link_design_view,
    record_channel,
)
from kfcrit.views.report.parts import (
    closed_form_text,
    exact_claim,
    exact_p_low,
    formula,
    input_exact,
    missing,
    number,
    prose,
    sentence,
    stated,
)

if TYPE_CHECKING:
    from kfcrit.analysis.sections import (
        AnalysisRecord,
        CriticalValueRecord,
        OperatingPoint,
        RequirementsRecord,
    )
    from kfcrit.views.report.link import AnyChannel

DECISIONS = ("pass", "fail", "undetermined")
REASON_STATUSES = {"pass": "pass", "fail": "fail", "undetermined": "undetermined",
                   "not applicable": "none"}


def review_view(rec: AnalysisRecord) -> dict[str, Any]:
    """The review decision of the record (``review``) and its reasons, for the verdict box.

    ``review = {"decision": "pass" | "fail" | "undetermined", "reasons": [{"check", "status",
    "detail"}]}`` is computed once by the analysis; the box shows it as it is (green pass, red
    fail, amber undetermined).
    """
    decision = rec.review.decision.value
    reasons = []
    for r in rec.review.reasons:
        status = r.status.value
        reasons.append({"check": prose(r.check) or "check",
                        "status": status or "not stated",
                        "css": REASON_STATUSES.get(status, "none"),
                        "detail": sentence(r.detail) if r.detail else ""})
    return {"available": True, "decision": decision, "word": decision.upper(),
            "css": decision, "reasons": reasons, "missing": ""}


def verdict_view(rec: AnalysisRecord) -> dict[str, Any]:
    """The verdict box: operating p against p_c, margins, robust value, bracket, verdict."""
    op = rec.operating_point
    cv = rec.critical_value
    rob = rec.robust_critical_value
    channel = record_channel(rec)
    verdict = op.verdict.value if op is not None else None
    css = {"mean-stable": "stable", "mean-unstable": "unstable",
           "undetermined": "undetermined"}.get(str(verdict), "unknown")
    review = review_view(rec)
    exact_in = input_exact(rec)
    form = critical_form(cv, exact_in)
    iid_verdict = stated(op.iid_comparison_verdict) if op is not None else None
    model = channel.model if channel is not None else None
    network = shows_network(rec, channel)
    return {
        "available": op is not None,
        "missing": missing("operating point", "the system file has no channel section, so "
                            "there is no arrival probability to compare with p_c")
        if op is None else "",
        "verdict": verdict, "css": css, "review": review, "box_css": review["css"],
        "p": number(op.arrival_probability) if op is not None else None,
        "p_expression": closed_form_text(channel.arrival_probability_expression)
        if isinstance(channel, ChannelRecord) else None,
        "channel_model": CHANNEL_NAMES.get(str(model), model),
        "channel_summary": channel_summary(channel) if channel is not None else "",
        "critical_value": number(cv.value) if cv is not None else None,
        "critical_expression": form,
        "critical_svg": formula(cv.latex, form, fontsize=13, label=form)
        if form and cv is not None else None,
        "critical_exact": exact_claim(rec, cv),
        "p_low_expression": exact_p_low(rec) if not exact_claim(rec, cv) else None,
        "critical_reason": (prose(cv.reason) or None) if cv is not None else None,
        "margin": number(op.margin) if op is not None else None,
        "margin_robust": number(op.margin_robust) if op is not None else None,
        "burst_margin": op is not None and stated(op.recovery_threshold) is not None,
        "iid_margin": number(stated(op.iid_margin)) if op is not None else None,
        "robust": {"available": rob is not None,
                   "value": number(rob.value) if rob is not None else None,
                   "tolerance": number(rob.tolerance) if rob is not None else None,
                   "expression": closed_form_text(stated(rob.expression))
                   if rob is not None else None,
                   "nearby_case": stated(rob.nearby_case) if rob is not None else None,
                   "missing": "not needed: the classification is decided exactly and no "
                              "perturbation within the tolerance changes it"
                   if exact_claim(rec, cv) else "not computed"},
        "bracket": op.bracket if op is not None else None,
        "margin_to_bracket": stated(op.margin_to_bracket) if op is not None else None,
        "reason": prose(stated(op.reason)) if op is not None and stated(op.reason) is not None
        else None,
        "basis": prose(op.basis) if op is not None else None,
        "iid_verdict": iid_verdict if iid_verdict and iid_verdict != verdict else None,
        "note": sentence(stated(op.note)) if op is not None and stated(op.note) else None,
        "legend": verdict_legend(op, network=network),
        "meaning": verdict_meaning(rec),
        "stacked": stated(rec.mesh) is not None,
        "link_design": link_design_view(rec),
        "requirement": requirement_view(rec),
        "network": network_cells(rec) if network else None,
    }


def shows_network(rec: AnalysisRecord, channel: AnyChannel | None) -> bool:
    """Whether the record is a sensor network's: then ``operating_point.margin`` is the uniform
    margin δ and ``operating_point.bracket`` its interval (not p − p_c and p_c's bracket)."""
    return stated(rec.network) is not None or (channel is not None and channel.model == "network")


def critical_form(cv: CriticalValueRecord | None, exact_input: bool = True) -> str | None:
    """The exact form of p_c for the verdict card: only an exact value's short closed form on
    exact input (a numerical value is printed as a number, never as its 17-digit expression,
    and a floating-point input's value never as the fraction of its binary expansion)."""
    return closed_form_text(cv.expression) if cv is not None and cv.exact and exact_input \
        else None


def network_cells(rec: AnalysisRecord) -> dict[str, Any]:
    """For a sensor network, what the verdict box's cells stand for: p is the bottleneck link's,
    the margin is the uniform margin δ (its bracket when not exact), and p_c above is the
    stacked system's (every sensor on one link), not a per-link value."""
    net = stated(rec.network)
    name = net.bottleneck.name if net is not None else None
    crit = None
    for s in net.sensors if net is not None else []:
        if s.name == name:
            crit = s.critical_value
    return {"bottleneck": name,
            "bottleneck_critical": number(crit.value) if crit is not None else None,
            "bottleneck_interval": crit.interval if crit is not None else None}


def verdict_meaning(rec: AnalysisRecord) -> str:
    """What the two verdicts mean for this channel (the first sentences of the legend): p
    against p_c for i.i.d. links; the channel's own boundary for a bursty link, a trace fitted
    as bursty, or a mesh."""
    base = "Mean-stable: E[P_t] stays bounded for every initial covariance"
    if stated(rec.mesh) is not None:
        return (base + ", here judged on the mesh's joint law of the received set "
                "(theory §13), not by one p against p_c. Mean-unstable: it diverges for some.")
    op = rec.operating_point
    basis = stated(op.margin_basis) if op is not None else None
    if isinstance(basis, str) and basis.startswith("recovery rate"):
        return (base + ", here judged on the bursty link's own boundary (recovery rate r "
                "against the burst conditions of theory §10), not by the average p against "
                "p_c. Mean-unstable: it diverges for some.")
    return base + " (p > p_c). Mean-unstable: it diverges for some (p ≤ p_c)."


def verdict_legend(op: OperatingPoint | None, network: bool = False) -> str:
    """The last sentence of the legend under the verdict box (after the two verdicts' meaning):
    why this verdict is not determined, when it is not (no operating point, p inside the bracket
    of p_c, or the record's reason); empty for a determined verdict."""
    if op is None:
        return ("Not determined: no operating point is configured (the system file has no "
                "channel section), so there is no arrival probability p to compare with p_c.")
    if op.verdict.value == "undetermined":
        if op.bracket is not None:
            return ("Undetermined: the uniform margin δ is bracketed by an interval that "
                    "contains 0, so the comparison is open." if network else
                    "Undetermined: p lies inside the bracket of p_c, so the comparison is open.")
        return "Undetermined: " + (sentence(stated(op.reason)) or
                                   "the comparison of p with p_c is not decided.")
    return ""


def requirement_view(rec: AnalysisRecord) -> dict[str, Any]:
    """The system file's requirements against the simulated tail probability at p."""
    req = rec.requirements
    limit = number(req.max_error_trace) if req is not None else None
    max_tail = number(req.max_tail_probability) if req is not None else None

    tail = tail_of(rec)
    run = stated(rec.simulation.operating_point) if rec.simulation is not None else None
    exc = run.exceedance if run is not None else None
    lo, hi = (number(exc.lower), number(exc.upper)) if exc is not None else (None, None)
    assessment = stated(req.assessment) if req is not None else None
    status = assessment.status if assessment is not None else None
    met = {"met": True, "not met": False}.get(status) if isinstance(status, str) else None
    return {"available": limit is not None, "limit": limit, "max_tail": max_tail,
            "tail": tail, "met": met, "status": status,
            "interval": [lo, hi] if None not in (lo, hi) else None,
            "count": exc.count if exc is not None else None,
            "total": exc.total if exc is not None else None,
            "caution": "not demonstrated: the 95 % interval contains the allowed tail "
                       "probability; run more paths (full mode) before relying on this"
                       if status == "not demonstrated" else "",
            "missing": "" if limit is not None else mean_requirement_text(req),
            "box_text": "" if limit is not None else mean_requirement_text(req, short=True)}


def mean_requirement_text(req: RequirementsRecord | None, short: bool = False) -> str:
    """The requirement line without a tail requirement: the mean requirement's assessment
    (``requirements.assessments``), or how to add a requirement (``short``: the verdict box's
    pointer to section 2, which says how)."""
    for a in req.assessments if req is not None else []:
        if a.requirement:
            return (f"{prose(a.requirement)}: {a.status or 'not assessed'} "
                    "(section 2)")
    if short:
        return "none in the system file (section 2 says how to add one)"
    return ("no requirement in the system file (add requirements: max_error_trace, "
            "max_tail_probability, or max_mean_error_trace)")
