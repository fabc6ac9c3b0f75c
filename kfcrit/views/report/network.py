"""View model of the sensor-network section (theory §9): the table of nodes, the uniform margin,
the bottleneck, the necessary constraints and the two network figures.

Reads the typed ``network`` section (:class:`~kfcrit.records.network.NetworkSection`)
and ``system.sensors``; every number is the record's. Intervals stand where the necessary and
sufficient surfaces do not meet.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

from kfcrit.views import formatting as filters
from kfcrit.views.figures.network import margin_bounds, positions_of, sink_of, weakest_pair
from kfcrit.views.report.parts import closed_form_text, figure_entry, number, prose, stated
from kfcrit.views.text.netmargin import (
    NO_CRITICAL_VALUE,
    bottleneck_margin_text,
    burst_margin_of,
    has_no_critical_value,
    margin_text,
    margin_value_text,
)

if TYPE_CHECKING:
    from kfcrit.analysis.sections import AnalysisRecord
    from kfcrit.records.network import NetworkSection

VERDICT_CSS = {"mean-stable": "ok", "mean-unstable": "no", "undetermined": "none"}


def is_network(rec: AnalysisRecord) -> bool:
    """Whether the record is a sensor network of two or more sensors (theory §9)."""
    net = stated(rec.network)
    return net is not None and len(net.sensors) > 1


def node_rows(rec: AnalysisRecord, net: NetworkSection) -> list[dict[str, Any]]:
    """One row per sensor: p, critical value, margin, N−1 verdict, position, bottleneck flag."""
    positions = positions_of(rec)
    bottleneck = net.bottleneck.name
    rows = []
    for s in net.sensors:
        name = s.name or "?"
        cv = s.critical_value
        n1 = s.n_minus_1
        low, _ = margin_bounds(s)
        expr = closed_form_text(cv.expression)
        pos = positions.get(name)
        rows.append({
            "name": name, "bottleneck": name == bottleneck,
            "p": number(s.arrival_probability),
            "p_expression": closed_form_text(s.arrival_probability_expression),
            "critical": (NO_CRITICAL_VALUE if has_no_critical_value(s)
                         else margin_value_text(cv.value, cv.interval)),
            "critical_expression": expr if expr and expr != filters.num(number(cv.value))
            else None,
            # "exact" describes a value: with none (only a bracket, or nothing) it is not said
            "critical_exact": cv.exact if number(cv.value) is not None else None,
            "critical_basis": prose(cv.basis),
            "margin": margin_text(s), "margin_bad": low is not None and low <= 0,
            "n1_verdict": n1.verdict, "n1_css": VERDICT_CSS.get(n1.verdict, "none"),
            "n1_reason": prose(n1.reason),
            "position": f"({filters.num(pos[0], 4)}, {filters.num(pos[1], 4)}) m"
            if pos else "—"})
    return rows


def constraint_lines(net: NetworkSection, bursty: bool = False) -> list[str]:
    """The necessary constraints as inequalities: |λ|²·Π(1 − p_k) < 1 over the mode's sensors
    (with ``bursty``, a one-sensor network on a Markov link, the burst condition
    |λ|²·(1 − r) < 1 in the link's recovery rate r, theory §10)."""
    symbol = "r" if bursty else "p"
    out = []
    for c in net.necessary_constraints:
        members = [str(m) for m in c.unobservable_without]
        if not members:
            continue
        m2 = c.modulus2_expression or filters.num(number(c.modulus2))
        product = "·".join(f"(1 − {symbol}_{m})" for m in members)
        blind = [str(b) for b in c.blind_sensors]
        out.append(f"mode λ = {filters.pretty_expr(c.eigenvalue)}: {product}·{m2} < 1"
                   + (f" (blind to it: {', '.join(blind)})" if blind else "")
                   + (f"; {prose(c.decided)}" if c.decided else ""))
    return out


def region_caption(rec: AnalysisRecord, net: NetworkSection) -> str:
    """What the region figure draws: which links, which surfaces, and what is not in it."""
    sensors = net.sensors
    pair = weakest_pair(rec)
    if len(pair) < 2:
        return ""
    names = [sensors[i].name for i in pair]
    others = [s.name for k, s in enumerate(sensors) if k not in pair]
    exact = net.exact_region.holds is True
    text = (f"The plane of the arrival probabilities of {names[0]} and {names[1]} (the two "
            "weakest links: the bottleneck first, then the smallest certain margin)"
            + (f", with {', '.join(others)} at {'its' if len(others) == 1 else 'their'} "
               "operating value" + ("" if len(others) == 1 else "s") if others else "")
            + ". Shaded red: a necessary constraint |λ|²·Π(1 − p_k) < 1 (docs/theory.md §9) fails, so "
            "the filter is mean-unstable there (proven); the lines are those constraints' "
            "boundaries, drawn from their closed forms in the record. ")
    if exact:
        text += ("The record states that the necessary surface is the exact boundary here "
                 f"({prose(net.exact_region.reason)}): everything "
                 "outside the shaded area is mean-stable.")
    else:
        text += ("The sufficient surface is not in the record as a curve; only its points on "
                 "the lines through the operating point are drawn (the purple ends of the "
                 "critical intervals, certified). Between the two surfaces the analysis does "
                 "not decide.")
    return text


def map_caption(rec: AnalysisRecord) -> str:
    """What the map shows, and whether the record had the sink's position."""
    text = ("Each node at its position, coloured by its certain margin p_i − p_c,i (the "
            "conservative end when p_c,i is an interval; red: the link is at or below its "
            "critical value with the others at their operating values).")
    if sink_of(rec) is None:
        text += " The record gives no sink position, so the sink is not drawn."
    return text


def network_view(rec: AnalysisRecord, figures: dict[str, str | None]) -> dict[str, Any]:
    """The network section: verdict, table of nodes, uniform margin, bottleneck, constraints
    and figures (``available: False`` for a single-link record)."""
    net = stated(rec.network)
    if net is None or not net.sensors:
        return {"available": False}
    um = net.uniform_margin
    bn = net.bottleneck
    ex = net.exact_region
    has_positions = bool(positions_of(rec))
    bursty = burst_margin_of(rec, net)
    return {
        "available": True, "size": len(net.sensors),
        "verdict": net.verdict, "verdict_css": VERDICT_CSS.get(net.verdict, "none"),
        "reason": prose(net.reason), "basis": prose(net.basis),
        "nodes": node_rows(rec, net),
        "uniform_margin": margin_value_text(um.value, um.interval, 6)
        if not um.unbounded else "unbounded",
        "bursty": bursty,
        "uniform_label": "margin r − r_nec" if bursty else "uniform margin δ",
        "uniform_reason": prose(um.reason), "uniform_rule": prose(um.rule),
        "bottleneck": bn.name,
        "bottleneck_margin": bottleneck_margin_text(bn),
        "bottleneck_rule": prose(bn.rule),
        "constraints": constraint_lines(net, bursty),
        "exact_region": {"holds": ex.holds, "reason": prose(ex.reason),
                         "basis": prose(ex.basis)},
        "claims": [prose(c) for c in net.claims],
        "warnings": [prose(w) for w in net.warnings],
        "region": figure_entry(
            figures.get("network_region"), "Stability region of the two weakest links",
            region_caption(rec, net), "stability region: not computed (the network has fewer "
            "than two sensors, or the record lacks their operating arrival probabilities)"),
        "map": figure_entry(figures.get("network_map"), "Map of the nodes", map_caption(rec),
                            "") if has_positions else None,
        "positions_note": "" if has_positions else
        "No node positions in the record (the system file gives distances, not positions), "
        "so there is no map.",
    }
