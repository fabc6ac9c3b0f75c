"""View model of the accuracy-requirement design (theory §11) and of the link curves.

Reads ``design`` ({requirement, required_arrival_probability, radio}), the requirement's
assessment in ``requirements.assessments``, ``tail.exponent`` and the figures drawn from
``phase_transition`` and ``link_budget.curves``. Every number is the record's.
"""
from __future__ import annotations

from typing import Any

from kfcrit.views import formatting as filters
from kfcrit.views.report.parts import (
    as_dict,
    as_list,
    figure_entry,
    number,
    prose,
    row,
    short_closed_form,
)

RADIO_ITEMS = (("max_distance_m", "maximum distance"),
               ("min_tx_power_dbm", "minimum transmit power"),
               ("max_payload_bytes", "maximum payload"),
               ("retries_needed", "MAC retries needed"))
UNITS = {"m": "m", "dBm": "dBm", "bytes": "bytes", "retries": ""}


def end_text(end: Any) -> str:
    """One end of [p_S, p_V]: its value and whether it is certified."""
    e = as_dict(end)
    v = number(e.get("value"))
    if v is None:
        return "not computed"
    return f"{filters.num(v, 6)} ({'certified' if e.get('certified') else 'numerical'})"


def end_value(end: dict[str, Any], unit: str) -> str:
    """One end of a radio quantity's interval with its unit, or its status (``unreachable``)."""
    v = number(end.get("value"))
    if v is None:
        return str(end.get("status") or "—")
    return filters.unit(v, unit) if UNITS.get(unit) else filters.num(v, 6)


FAILING_SIDE = {"at least": ("or more", "below"), "at most": ("or less", "above")}
"""For each sense of a radio bound: the side that keeps the requirement and the side that
fails it (a power must be at least its bound, so it fails below; a distance above)."""


def bound_text(item: dict[str, Any]) -> str:
    """A radio bound [sufficient, necessary] in words, by its sense and its ends' statuses.

    ``at least`` quantities (power, retries) fail below the necessary end, ``at most``
    quantities (distance, payload) above it; between the ends the requirement is not decided.
    """
    unit = str(item.get("unit") or "")
    quantity = str(item.get("quantity") or "value")
    suf_d, nec_d = as_dict(item.get("sufficient")), as_dict(item.get("necessary"))
    suf, nec = end_value(suf_d, unit), end_value(nec_d, unit)
    keep, fail = FAILING_SIDE.get(str(item.get("sense") or ""), ("", "beyond"))
    status = str(suf_d.get("status") or "")
    if status == "phy-limit":
        return f"every {quantity} the PHY allows meets it (up to {suf})"
    if status == "unbounded":
        return f"any {quantity} meets it"
    if status == "unreachable":
        if str(nec_d.get("status") or "") == "unreachable" or number(nec_d.get("value")) is None:
            return f"no {quantity} meets it"
        return f"no {quantity} guarantees it; it fails {fail} {nec}"
    if number(suf_d.get("value")) is None:
        return filters.DASH
    if unit == "retries" and suf == nec:
        v = number(suf_d.get("value"))
        return ("needed: 0 (the requirement holds without retries)" if v == 0 else
                f"needed: {suf} (with fewer it fails)")
    if suf == nec:
        return f"guaranteed at {suf} {keep}; fails {fail} it".replace("  ", " ")
    return (f"guaranteed at {suf} {keep}; fails {fail} {nec} (between them the requirement "
            f"is not decided)").replace("  ", " ")


def radio_rows(radio: dict[str, Any]) -> list[dict[str, Any]]:
    """What the accuracy requirement asks of the radio: each quantity as [guaranteed, limit]."""
    rows = []
    for key, label in RADIO_ITEMS:
        item = as_dict(radio.get(key))
        if not item:
            continue
        sense = str(item.get("sense") or "")
        rows.append(row(f"{label} ({sense})" if sense else label, None,
                        note=bound_text(item)
                        + (f" — {prose(item.get('method'))}" if item.get("method") else "")))
    if number(radio.get("margin_db")) is not None:
        rows.append(row("SINR kept in reserve", radio.get("margin_db"), "dB",
                        note="the link's margin policy, kept while each quantity is varied"))
    return rows


def mean_assessment_rows(rec: dict[str, Any]) -> dict[str, Any] | None:
    """The assessment of lim E[tr P] ≤ L in ``requirements.assessments`` (``None``: absent)."""
    for a in as_list(as_dict(rec.get("requirements")).get("assessments")):
        a = as_dict(a)
        if "E[tr P]" in str(a.get("requirement") or ""):
            status = str(a.get("status") or "")
            return {"requirement": prose(a.get("requirement")), "status": status,
                    "met": {"met": True, "not met": False}.get(status),
                    "basis": prose(a.get("basis")),
                    "interval": a.get("interval")}
    return None


def tail_view(rec: dict[str, Any]) -> dict[str, Any] | None:
    """The power-law tail exponent of tr P (a labelled claim), or ``None``."""
    ex = as_dict(as_dict(rec.get("tail")).get("exponent"))
    if not ex or not ex.get("applicable", True) or number(ex.get("value")) is None:
        return None
    return {"value": ex.get("value"), "expression": short_closed_form(ex.get("expression")),
            "formula": prose(ex.get("formula")), "statement": prose(ex.get("statement")),
            "label": prose(ex.get("label")), "source": str(ex.get("source") or "")}


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


def link_figures(rec: dict[str, Any], figures: dict[str, Any]) -> list[dict[str, Any]]:
    """The link-curve figures the record has data for (``link_budget.curves``)."""
    figs = as_dict(figures)
    return [figure_entry(figs.get(key), title, caption, "")
            for key, (title, caption) in LINK_FIGURES.items() if figs.get(key)]


def design_view(rec: dict[str, Any], figures: dict[str, Any]) -> dict[str, Any]:
    """The accuracy-requirement design: [p_S, p_V], what it means for the radio, the figure."""
    design = as_dict(rec.get("design"))
    req = as_dict(design.get("required_arrival_probability"))
    figs = as_dict(figures)
    if not design:
        return {"available": False, "tail": tail_view(rec)}
    level = number(req.get("level"))
    floor = number(req.get("floor_trace"))
    rows = [row("requirement", None, note=prose(design.get("requirement"))),
            row("status", req.get("status")),
            row("required arrival probability [p_S, p_V]", filters.interval(
                req.get("interval"), 6) if as_list(req.get("interval")) else "—",
                note=prose(req.get("meaning"))),
            row("p_S: below it the requirement fails", None, note=end_text(req.get("p_S"))
                + " — tr S̄(p_S) = L"),
            row("p_V: from it on the requirement is met", None, note=end_text(req.get("p_V"))
                + " — tr V̄(p_V) = L"),
            row("floor tr P∞ (every packet arrives)", floor, "num",
                note="certified" if req.get("floor_certified") else "numerical"),
            row("reason", None, note=prose(req.get("reason")))]
    return {
        "available": True, "level": level, "rows": rows,
        "assessment": mean_assessment_rows(rec),
        "radio": radio_rows(as_dict(design.get("radio"))) if design.get("radio") else [],
        "radio_notes": [prose(n) for n in as_list(as_dict(design.get("radio")).get("notes"))],
        "accuracy": figure_entry(
            figs.get("accuracy"), "Accuracy requirement against the covariance bounds",
            "tr S̄(p) and tr V̄(p) against the arrival probability (log scale), with the "
            "requirement lim E[tr P] ≤ L and the interval [p_S, p_V] shaded: below p_S "
            "the lower bound already exceeds L (fails), from p_V on the upper bound meets it; "
            "between, the bounds do not decide. These bounds assume i.i.d. losses.",
            "accuracy figure: not computed (no phase-transition curves in the record)"),
        "tail": tail_view(rec),
    }
