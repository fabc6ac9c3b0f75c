"""View model of the verdict box: the review decision with its reasons, the operating point
against p_c, the link design and the requirement."""
from __future__ import annotations

from typing import Any

from kfcrit.views.figures.record import tail_of
from kfcrit.views.report.link import CHANNEL_NAMES, channel_summary, link_design_view
from kfcrit.views.report.parts import (
    as_dict,
    as_list,
    closed_form_text,
    exact_claim,
    exact_p_low,
    formula,
    input_exact,
    missing,
    number,
    prose,
    sentence,
    typed_record,
)

DECISIONS = ("pass", "fail", "undetermined")
REASON_STATUSES = {"pass": "pass", "fail": "fail", "undetermined": "undetermined",
                   "not applicable": "none"}


def review_view(rec: dict[str, Any]) -> dict[str, Any]:
    """The review decision of the record (``review``) and its reasons, for the verdict box.

    ``review = {"decision": "pass" | "fail" | "undetermined", "reasons": [{"check", "status",
    "detail"}]}`` is computed once by the analysis; the box shows it as it is (green pass, red
    fail, amber undetermined). A record without a ``review`` (written before reviews existed)
    gets a neutral box that says so: the view does not decide.
    """
    rv = as_dict(rec.get("review"))
    decision = rv.get("decision") if rv.get("decision") in DECISIONS else None
    reasons = []
    for r in as_list(rv.get("reasons")):
        r = as_dict(r)
        status = str(r.get("status") or "")
        reasons.append({"check": prose(r.get("check")) or "check",
                        "status": status or "not stated",
                        "css": REASON_STATUSES.get(status, "none"),
                        "detail": sentence(r.get("detail")) if r.get("detail") else ""})
    return {"available": decision is not None, "decision": decision,
            "word": decision.upper() if decision else "NO REVIEW DECISION",
            "css": decision or "neutral", "reasons": reasons,
            "missing": "" if decision else
            "This record has no review decision (it predates reviews, or the analysis did not "
            "produce one): the stability verdict below is not combined with the requirements "
            "and the link policy."}


def verdict_view(rec: dict[str, Any]) -> dict[str, Any]:
    """The verdict box: operating p against p_c, margins, robust value, bracket, verdict."""
    op = rec.get("operating_point")
    opd = as_dict(op)
    cv = as_dict(rec.get("critical_value"))
    rob = rec.get("robust_critical_value")
    robd = as_dict(rob)
    channel = as_dict(opd.get("channel")) or as_dict(as_dict(rec.get("system")).get("channel"))
    verdict = opd.get("verdict") if isinstance(op, dict) else None
    css = {"mean-stable": "stable", "mean-unstable": "unstable",
           "undetermined": "undetermined"}.get(str(verdict), "unknown")
    review = review_view(rec)
    exact_in = input_exact(rec)
    iid_verdict = opd.get("iid_comparison_verdict")
    return {
        "available": isinstance(op, dict),
        "missing": missing("operating point", "the system file has no channel section, so "
                            "there is no arrival probability to compare with p_c")
        if op is None else "",
        "verdict": verdict, "css": css, "review": review, "box_css": review["css"],
        "p": number(opd.get("arrival_probability")),
        "p_expression": closed_form_text(channel.get("arrival_probability_expression")),
        "channel_model": CHANNEL_NAMES.get(str(channel.get("model")), channel.get("model")),
        "channel_summary": channel_summary(channel) if channel else "",
        "critical_value": number(cv.get("value")),
        "critical_expression": critical_form(cv, exact_in),
        "critical_svg": formula(cv.get("latex"), critical_form(cv, exact_in), fontsize=13,
                                label=critical_form(cv, exact_in))
        if critical_form(cv, exact_in) else None,
        "critical_exact": exact_claim(rec, cv),
        "p_low_expression": exact_p_low(rec) if not exact_claim(rec, cv) else None,
        "critical_reason": prose(cv.get("reason")) or None,
        "margin": number(opd.get("margin")),
        "margin_robust": number(opd.get("margin_robust")),
        "burst_margin": opd.get("recovery_threshold") is not None,
        "iid_margin": number(opd.get("iid_margin")),
        "robust": {"available": isinstance(rob, dict),
                   "value": number(robd.get("value")), "tolerance": number(robd.get("tolerance")),
                   "expression": closed_form_text(robd.get("expression")),
                   "nearby_case": robd.get("nearby_case"),
                   "missing": "not needed: the classification is decided exactly and no "
                              "perturbation within the tolerance changes it"
                   if exact_claim(rec, cv) else "not computed"},
        "bracket": opd.get("bracket") if isinstance(opd.get("bracket"), list) else None,
        "margin_to_bracket": opd.get("margin_to_bracket")
        if isinstance(opd.get("margin_to_bracket"), list) else None,
        "reason": prose(opd.get("reason")) if isinstance(opd.get("reason"), str) else None,
        "basis": prose(opd.get("basis")) if isinstance(opd.get("basis"), str) else None,
        "iid_verdict": iid_verdict if iid_verdict and iid_verdict != verdict else None,
        "note": sentence(opd.get("note")) if opd.get("note") else None,
        "legend": verdict_legend(op, verdict, opd, network=shows_network(rec, channel)),
        "meaning": verdict_meaning(rec, opd),
        "stacked": isinstance(rec.get("mesh"), dict),
        "link_design": link_design_view(rec),
        "requirement": requirement_view(rec),
        "network": network_cells(rec) if shows_network(rec, channel) else None,
    }


def shows_network(rec: dict[str, Any], channel: dict[str, Any]) -> bool:
    """Whether the record is a sensor network's: then ``operating_point.margin`` is the uniform
    margin δ and ``operating_point.bracket`` its interval (not p − p_c and p_c's bracket)."""
    return isinstance(rec.get("network"), dict) or channel.get("model") == "network"


def critical_form(cv: dict[str, Any], exact_input: bool = True) -> str | None:
    """The exact form of p_c for the verdict card: only an exact value's short closed form on
    exact input (a numerical value is printed as a number, never as its 17-digit expression,
    and a floating-point input's value never as the fraction of its binary expansion)."""
    return closed_form_text(cv.get("expression")) if cv.get("exact") and exact_input else None


def network_cells(rec: dict[str, Any]) -> dict[str, Any]:
    """For a sensor network, what the verdict box's cells stand for: p is the bottleneck link's,
    the margin is the uniform margin δ (its bracket when not exact), and p_c above is the
    stacked system's (every sensor on one link), not a per-link value."""
    net = as_dict(rec.get("network"))
    bn = as_dict(net.get("bottleneck"))
    crit = None
    for s in as_list(net.get("sensors")):
        if as_dict(s).get("name") == bn.get("name"):
            crit = as_dict(as_dict(s).get("critical_value"))
    return {"bottleneck": bn.get("name"),
            "bottleneck_critical": number(crit.get("value")) if crit else None,
            "bottleneck_interval": crit.get("interval") if crit else None}


def verdict_meaning(rec: dict[str, Any], opd: dict[str, Any]) -> str:
    """What the two verdicts mean for this channel (the first sentences of the legend): p
    against p_c for i.i.d. links; the channel's own boundary for a bursty link, a trace fitted
    as bursty, or a mesh."""
    base = "Mean-stable: E[P_t] stays bounded for every initial covariance"
    if isinstance(rec.get("mesh"), dict):
        return (base + ", here judged on the mesh's joint law of the received set "
                "(theory §13), not by one p against p_c. Mean-unstable: it diverges for some.")
    basis = opd.get("margin_basis")
    if isinstance(basis, str) and basis.startswith("recovery rate"):
        return (base + ", here judged on the bursty link's own boundary (recovery rate r "
                "against the burst conditions of theory §10), not by the average p against "
                "p_c. Mean-unstable: it diverges for some.")
    return base + " (p > p_c). Mean-unstable: it diverges for some (p ≤ p_c)."


def verdict_legend(op: Any, verdict: Any, opd: dict[str, Any], network: bool = False) -> str:
    """The last sentence of the legend under the verdict box (after the two verdicts' meaning):
    why this verdict is not determined, when it is not (no operating point, p inside the bracket
    of p_c, or the record's reason); empty for a determined verdict."""
    if not isinstance(op, dict):
        why = ("Not determined: no operating point is configured (the system file has no "
               "channel section), so there is no arrival probability p to compare with p_c.")
    elif verdict == "undetermined":
        if isinstance(opd.get("bracket"), list):
            why = ("Undetermined: the uniform margin δ is bracketed by an interval that "
                   "contains 0, so the comparison is open." if network else
                   "Undetermined: p lies inside the bracket of p_c, so the comparison is open.")
        else:
            why = "Undetermined: " + (sentence(opd.get("reason")) or
                                      "the comparison of p with p_c is not decided.")
    elif not verdict:
        why = "Not determined: " + (sentence(opd.get("reason")) or "the analysis gave no verdict.")
    else:
        why = ""
    return why


def requirement_view(rec: dict[str, Any]) -> dict[str, Any]:
    """The system file's requirements against the simulated tail probability at p."""
    req = as_dict(rec.get("requirements"))
    limit = number(req.get("max_error_trace"))
    max_tail = number(req.get("max_tail_probability"))

    tail = tail_of(typed_record(rec))
    exc = as_dict(as_dict(as_dict(rec.get("simulation")).get("operating_point")).get("exceedance"))
    lo, hi = number(exc.get("lower")), number(exc.get("upper"))
    status = as_dict(req.get("assessment")).get("status")
    met = {"met": True, "not met": False}.get(status) if isinstance(status, str) else None
    return {"available": limit is not None, "limit": limit, "max_tail": max_tail,
            "tail": tail, "met": met, "status": status,
            "interval": [lo, hi] if None not in (lo, hi) else None,
            "count": exc.get("count"), "total": exc.get("total"),
            "caution": "not demonstrated: the 95 % interval contains the allowed tail "
                       "probability; run more paths (full mode) before relying on this"
                       if status == "not demonstrated" else "",
            "missing": "" if limit is not None else mean_requirement_text(req),
            "box_text": "" if limit is not None else mean_requirement_text(req, short=True)}


def mean_requirement_text(req: dict[str, Any], short: bool = False) -> str:
    """The requirement line without a tail requirement: the mean requirement's assessment
    (``requirements.assessments``), or how to add a requirement (``short``: the verdict box's
    pointer to section 2, which says how)."""
    for a in as_list(req.get("assessments")):
        a = as_dict(a)
        if a.get("requirement"):
            return (f"{prose(a.get('requirement'))}: {a.get('status') or 'not assessed'} "
                    "(section 2)")
    if short:
        return "none in the system file (section 2 says how to add one)"
    return ("no requirement in the system file (add requirements: max_error_trace, "
            "max_tail_probability, or max_mean_error_trace)")


