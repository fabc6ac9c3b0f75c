"""View model of the accuracy-requirement design (theory §11) and of the link curves.

Reads ``design`` ({requirement, required_arrival_probability, radio}), the requirement's
assessment in ``requirements.assessments``, ``tail.exponent`` and the figures drawn from
``phase_transition`` and ``link_budget.curves``. Every number is the record's.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

from kfcrit.views import formatting as filters
from kfcrit.views.report.parts import (
    figure_entry,
    number,
    prose,
    row,
    short_closed_form,
    stated,
)

if TYPE_CHECKING:
    from kfcrit.analysis.sections import AnalysisRecord
    from kfcrit.records.covariance import RequiredArrivalEnd
    from kfcrit.records.link import (
        LinkDesignBound,
        LinkDesignDistance,
        LinkDesignPayload,
        LinkDesignPayloadBound,
        LinkDesignRecord,
    )

UNITS = {"m": "m", "dBm": "dBm", "bytes": "bytes", "retries": ""}


def end_text(end: RequiredArrivalEnd) -> str:
    """One end of [p_S, p_V]: its value and whether it is certified."""
    v = number(end.value)
    if v is None:
        return "not computed"
    return f"{filters.num(v, 6)} ({'certified' if end.certified else 'numerical'})"


def end_value(end: LinkDesignBound | LinkDesignPayloadBound, unit: str) -> str:
    """One end of a radio quantity's interval with its unit, or its status (``unreachable``)."""
    v = number(end.value)
    if v is None:
        return end.status or "—"
    return filters.unit(v, unit) if UNITS.get(unit) else filters.num(v, 6)


FAILING_SIDE = {"at least": ("or more", "below"), "at most": ("or less", "above")}
"""For each sense of a radio bound: the side that keeps the requirement and the side that
fails it (a power must be at least its bound, so it fails below; a distance above)."""


def bound_text(item: LinkDesignDistance | LinkDesignPayload) -> str:
    """A radio bound [sufficient, necessary] in words, by its sense and its ends' statuses.

    ``at least`` quantities (power, retries) fail below the necessary end, ``at most``
    quantities (distance, payload) above it; between the ends the requirement is not decided.
    """
    unit = item.unit
    quantity = item.quantity or "value"
    suf, nec = end_value(item.sufficient, unit), end_value(item.necessary, unit)
    keep, fail = FAILING_SIDE.get(item.sense, ("", "beyond"))
    status = item.sufficient.status
    if status == "phy-limit":
        return f"every {quantity} the PHY allows meets it (up to {suf})"
    if status == "unbounded":
        return f"any {quantity} meets it"
    if status == "unreachable":
        if item.necessary.status == "unreachable" or number(item.necessary.value) is None:
            return f"no {quantity} meets it"
        return f"no {quantity} guarantees it; it fails {fail} {nec}"
    if number(item.sufficient.value) is None:
        return filters.DASH
    if unit == "retries" and suf == nec:
        v = number(item.sufficient.value)
        return ("needed: 0 (the requirement holds without retries)" if v == 0 else
                f"needed: {suf} (with fewer it fails)")
    if suf == nec:
        return f"guaranteed at {suf} {keep}; fails {fail} it".replace("  ", " ")
    return (f"guaranteed at {suf} {keep}; fails {fail} {nec} (between them the requirement "
            f"is not decided)").replace("  ", " ")


def radio_rows(radio: LinkDesignRecord) -> list[dict[str, Any]]:
    """What the accuracy requirement asks of the radio: each quantity as [guaranteed, limit]."""
    rows = []
    for item, label in ((radio.max_distance_m, "maximum distance"),
                        (radio.min_tx_power_dbm, "minimum transmit power"),
                        (radio.max_payload_bytes, "maximum payload"),
                        (radio.retries_needed, "MAC retries needed")):
        sense = item.sense
        rows.append(row(f"{label} ({sense})" if sense else label, None,
                        note=bound_text(item)
                        + (f" — {prose(item.method)}" if item.method else "")))
    if number(radio.margin_db) is not None:
        rows.append(row("SINR kept in reserve", radio.margin_db, "dB",
                        note="the link's margin policy, kept while each quantity is varied"))
    return rows


def mean_assessment_rows(rec: AnalysisRecord) -> dict[str, Any] | None:
    """The assessment of lim E[tr P] ≤ L in ``requirements.assessments`` (``None``: absent)."""
    for a in rec.requirements.assessments if rec.requirements is not None else []:
        if "E[tr P]" in a.requirement:
            status = a.status or ""
            return {"requirement": prose(a.requirement), "status": status,
                    "met": {"met": True, "not met": False}.get(status),
                    "basis": prose(a.basis),
                    "interval": stated(a.interval)}
    return None


def beta_text(value: float, finite_mean: bool | None, finite_variance: bool | None) -> str:
    """β as text, never contradicting the exact comparisons: β > 1 iff E[tr P] is finite and
    β > 2 iff its variance is (theory §5); a β that rounds onto 1 or 2 in float64 while the
    exact comparison decides the side is written with that side."""
    for edge, finite in ((1.0, finite_mean), (2.0, finite_variance)):
        if finite is True and value <= edge:
            return f"{edge:g}⁺ (above {edge:g} exactly; {edge:g} to float64 precision)"
        if finite is False and value > edge:
            return f"≤ {edge:g} (exactly; {value:.6g} in float64)"
    return filters.num(value, 6)


def tail_view(rec: AnalysisRecord) -> dict[str, Any] | None:
    """The power-law tail exponent of tr P (a labelled claim), or ``None``."""
    tail = stated(rec.tail)
    ex = tail.exponent if tail is not None else None
    if ex is None or not ex.applicable or number(ex.value) is None:
        return None
    return {"value": ex.value, "value_text": beta_text(ex.value, ex.finite_mean, ex.finite_variance),
            "expression": short_closed_form(ex.expression),
            "formula": prose(ex.formula), "statement": prose(ex.statement),
            "label": prose(ex.label), "source": ex.source}


LINK_FIGURES = {
    "arrival_distance": ("Arrival probability against distance",
                         "Arrival probability of the median link (and its average over the "
                         "shadowing) against distance, with the critical arrival probability "
                         "p_c, the configured distance and the largest distance of the margin "
                         "policy; when the system file states an accuracy requirement, its "
                         "required interval [p_S, p_V] is shaded as well."),
    "per_sinr": ("Packet error rate against SINR",
                 "Packet error rate of one attempt against SINR for several PSDU lengths, with "
                 "the configured SINR and the SINR the stability requirement needs."),
    "outage_distance": ("Shadowing outage against distance",
                        "Probability that a deployed link (per-link log-normal shadowing) "
                        "falls below the arrival probability it needs (one curve per value "
                        "named in the legend: p_c, and p_S and p_V when an accuracy "
                        "requirement is stated), against distance, with the policy's allowed "
                        "outage and the configured distance."),
}


def link_figures(rec: AnalysisRecord, figures: dict[str, str | None]) -> list[dict[str, Any]]:
    """The link-curve figures the record has data for (``link_budget.curves``)."""
    return [figure_entry(figures.get(key), title, caption, "")
            for key, (title, caption) in LINK_FIGURES.items() if figures.get(key)]


def design_view(rec: AnalysisRecord, figures: dict[str, str | None]) -> dict[str, Any]:
    """The accuracy-requirement design: [p_S, p_V], what it means for the radio, the figure."""
    design = stated(rec.design)
    if design is None:
        return {"available": False, "tail": tail_view(rec)}
    req = design.required_arrival_probability
    radio = stated(design.radio)
    rows = [row("requirement", None, note=prose(design.requirement)),
            row("status", req.status),
            row("required arrival probability [p_S, p_V]", filters.interval(
                req.interval, 6) if req.interval else "—",
                note=prose(req.meaning)),
            row("p_S: below it the requirement fails", None, note=end_text(req.p_S)
                + " — tr S̄(p_S) = L"),
            row("p_V: from it on the requirement is met", None, note=end_text(req.p_V)
                + " — tr V̄(p_V) = L"),
            row("floor tr P∞ (every packet arrives)", number(req.floor_trace), "num",
                note="certified" if req.floor_certified else "numerical"),
            row("reason", None, note=prose(req.reason))]
    return {
        "available": True, "level": number(req.level), "rows": rows,
        "assessment": mean_assessment_rows(rec),
        "radio": radio_rows(radio) if radio is not None else [],
        "radio_notes": [prose(n) for n in radio.notes] if radio is not None else [],
        "accuracy": figure_entry(
            figures.get("accuracy"), "Accuracy requirement against the covariance bounds",
            "tr S̄(p) and tr V̄(p) against the arrival probability (log scale), with the "
            "requirement lim E[tr P] ≤ L and the interval [p_S, p_V] shaded: below p_S "
            "the lower bound already exceeds L (fails), from p_V on the upper bound meets it; "
            "between, the bounds do not decide. These bounds assume i.i.d. losses.",
            "accuracy figure: not computed (no phase-transition curves in the record)"),
        "tail": tail_view(rec),
    }
