"""View model of the sensor-network section (theory §9): the table of nodes, the uniform margin,
the bottleneck, the necessary constraints and the two network figures.

Reads ``network`` (:meth:`kfcrit.theory.links.network.NetworkResult.to_dict`) and ``system.sensors``;
every number is the record's. Intervals stand where the necessary and sufficient surfaces do
not meet.
"""
from __future__ import annotations

from typing import Any

from kfcrit.analysis.records.network import NetworkBottleneck, NetworkSensor
from kfcrit.views import formatting as filters
from kfcrit.views.figures.network import margin_bounds, positions_of, sink_of, weakest_pair
from kfcrit.views.report.parts import (
    as_dict,
    as_list,
    closed_form_text,
    figure_entry,
    number,
    prose,
    typed_record,
    typed_section,
)
from kfcrit.views.text.netmargin import bottleneck_margin_text, margin_text, margin_value_text

VERDICT_CSS = {"mean-stable": "ok", "mean-unstable": "no", "undetermined": "none"}


def is_network(rec: dict[str, Any]) -> bool:
    """Whether the record is a sensor network of two or more sensors (theory §9)."""
    return len(as_list(as_dict(as_dict(rec).get("network")).get("sensors"))) > 1


def node_rows(rec: dict[str, Any]) -> list[dict[str, Any]]:
    """One row per sensor: p, critical value, margin, N−1 verdict, position, bottleneck flag."""
    net = as_dict(rec.get("network"))
    positions = positions_of(typed_record(rec))
    bottleneck = as_dict(net.get("bottleneck")).get("name")
    rows = []
    for s in as_list(net.get("sensors")):
        s = as_dict(s)
        typed_row = typed_section(NetworkSensor, s)
        name = str(s.get("name") or "?")
        cv = as_dict(s.get("critical_value"))
        n1 = as_dict(s.get("n_minus_1"))
        low, _ = margin_bounds(typed_row) if typed_row else (None, None)
        expr = closed_form_text(cv.get("expression"))
        pos = positions.get(name)
        rows.append({
            "name": name, "bottleneck": name == bottleneck,
            "p": number(s.get("arrival_probability")),
            "p_expression": closed_form_text(s.get("arrival_probability_expression")),
            "critical": margin_value_text(cv.get("value"), cv.get("interval")),
            "critical_expression": expr if expr and expr != filters.num(number(cv.get("value")))
            else None,
            # "exact" describes a value: with none (only a bracket, or nothing) it is not said
            "critical_exact": cv.get("exact") if number(cv.get("value")) is not None else None,
            "critical_basis": prose(cv.get("basis")),
            "margin": margin_text(typed_row) if typed_row else "—",
            "margin_bad": low is not None and low <= 0,
            "n1_verdict": n1.get("verdict"), "n1_css": VERDICT_CSS.get(str(n1.get("verdict")),
                                                                       "none"),
            "n1_reason": prose(n1.get("reason")),
            "position": f"({filters.num(pos[0], 4)}, {filters.num(pos[1], 4)}) m"
            if pos else "—"})
    return rows


def constraint_lines(rec: dict[str, Any]) -> list[str]:
    """The necessary constraints as inequalities: |λ|²·Π(1 − p_k) < 1 over the mode's sensors."""
    out = []
    for c in as_list(as_dict(rec.get("network")).get("necessary_constraints")):
        c = as_dict(c)
        members = [str(m) for m in as_list(c.get("unobservable_without"))]
        if not members:
            continue
        m2 = c.get("modulus2_expression") or filters.num(number(c.get("modulus2")))
        product = "·".join(f"(1 − p_{m})" for m in members)
        blind = [str(b) for b in as_list(c.get("blind_sensors"))]
        out.append(f"mode λ = {filters.pretty_expr(c.get('eigenvalue'))}: {product}·{m2} < 1"
                   + (f" (blind to it: {', '.join(blind)})" if blind else "")
                   + (f"; {prose(c.get('decided'))}" if c.get("decided") else ""))
    return out


def region_caption(rec: dict[str, Any]) -> str:
    """What the region figure draws: which links, which surfaces, and what is not in it."""
    net = as_dict(rec.get("network"))
    sensors = as_list(net.get("sensors"))
    pair = weakest_pair(typed_record(rec))
    if len(pair) < 2:
        return ""
    names = [str(as_dict(sensors[i]).get("name")) for i in pair]
    others = [str(as_dict(s).get("name")) for k, s in enumerate(sensors) if k not in pair]
    exact = as_dict(net.get("exact_region")).get("holds") is True
    text = (f"The plane of the arrival probabilities of {names[0]} and {names[1]} (the two "
            "weakest links: the bottleneck first, then the smallest certain margin)"
            + (f", with {', '.join(others)} at {'its' if len(others) == 1 else 'their'} "
               "operating value" + ("" if len(others) == 1 else "s") if others else "")
            + ". Shaded red: a necessary constraint |λ|²·Π(1 − p_k) < 1 (docs/theory.md §9) fails, so "
            "the filter is mean-unstable there (proven); the lines are those constraints' "
            "boundaries, drawn from their closed forms in the record. ")
    if exact:
        text += ("The record states that the necessary surface is the exact boundary here "
                 f"({prose(as_dict(net.get('exact_region')).get('reason'))}): everything "
                 "outside the shaded area is mean-stable.")
    else:
        text += ("The sufficient surface is not in the record as a curve; only its points on "
                 "the lines through the operating point are drawn (the purple ends of the "
                 "critical intervals, certified). Between the two surfaces the analysis does "
                 "not decide.")
    return text


def map_caption(rec: dict[str, Any]) -> str:
    """What the map shows, and whether the record had the sink's position."""
    text = ("Each node at its position, coloured by its certain margin p_i − p_c,i (the "
            "conservative end when p_c,i is an interval; red: the link is at or below its "
            "critical value with the others at their operating values).")
    if sink_of(typed_record(rec)) is None:
        text += " The record gives no sink position, so the sink is not drawn."
    return text


def network_view(rec: dict[str, Any], figures: dict[str, Any]) -> dict[str, Any]:
    """The network section: verdict, table of nodes, uniform margin, bottleneck, constraints
    and figures (``available: False`` for a single-link record)."""
    net = rec.get("network")
    netd = as_dict(net)
    if not netd or not as_list(netd.get("sensors")):
        return {"available": False}
    um = as_dict(netd.get("uniform_margin"))
    bn = as_dict(netd.get("bottleneck"))
    ex = as_dict(netd.get("exact_region"))
    figs = as_dict(figures)
    has_positions = bool(positions_of(typed_record(rec)))
    typed_bn = typed_section(NetworkBottleneck, bn)
    return {
        "available": True, "size": len(as_list(netd.get("sensors"))),
        "verdict": netd.get("verdict"), "verdict_css": VERDICT_CSS.get(str(netd.get("verdict")),
                                                                      "none"),
        "reason": prose(netd.get("reason")), "basis": prose(netd.get("basis")),
        "nodes": node_rows(rec),
        "uniform_margin": margin_value_text(um.get("value"), um.get("interval"), 6)
        if not um.get("unbounded") else "unbounded",
        "uniform_reason": prose(um.get("reason")), "uniform_rule": prose(um.get("rule")),
        "bottleneck": bn.get("name"),
        "bottleneck_margin": bottleneck_margin_text(typed_bn) if typed_bn else "—",
        "bottleneck_rule": prose(bn.get("rule")),
        "constraints": constraint_lines(rec),
        "exact_region": None if not ex else
        {"holds": ex.get("holds"), "reason": prose(ex.get("reason")),
         "basis": prose(ex.get("basis"))},
        "claims": [prose(c) if isinstance(c, str) else prose(as_dict(c).get("statement"))
                   for c in as_list(netd.get("claims"))],
        "warnings": [prose(w) for w in as_list(netd.get("warnings"))],
        "region": figure_entry(
            figs.get("network_region"), "Stability region of the two weakest links",
            region_caption(rec), "stability region: not computed (the network has fewer than "
            "two sensors, or the record lacks their operating arrival probabilities)"),
        "map": figure_entry(figs.get("network_map"), "Map of the nodes", map_caption(rec),
                            "") if has_positions else None,
        "positions_note": "" if has_positions else
        "No node positions in the record (the system file gives distances, not positions), "
        "so there is no map.",
    }
