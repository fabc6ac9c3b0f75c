"""View model of the report's mesh section (theory §13): topology map, the per-sensor table,
routes, joint losses, the forwarding modes compared, the bottleneck hop and N − 1.

Reads the record's ``mesh`` section only; every number is the record's (formatted here, so the
template computes nothing).
"""
from __future__ import annotations

from typing import Any

from kfcrit.views.report.parts import as_dict, as_list, figure_entry, prose

VERDICT_CSS = {"mean-stable": "ok", "mean-unstable": "no", "undetermined": "none"}


def _num(v: Any, digits: int = 6) -> str:
    return "—" if not isinstance(v, (int, float)) or isinstance(v, bool) else f"{v:.{digits}g}"


def _with_exact(v: Any, expression: Any) -> str:
    return _num(v) + (f" = {expression}" if expression else "")


def mesh_sensor_table(mesh: dict[str, Any]) -> list[dict[str, Any]]:
    """One row per sensor: routes, arrival probability, smart-sensor test, what kills it."""
    arr, expr = as_dict(mesh.get("arrival_probability")), as_dict(mesh.get("arrival_expression"))
    smart = {s.get("sensor"): s for s in as_list(as_dict(mesh.get("smart_sensor")).get("sensors"))}
    cuts = {c.get("sensor"): c for c in as_list(as_dict(mesh.get("relaying")).get("sensors"))}
    rows = []
    for name, p in arr.items():
        routes = [" → ".join(as_list(r.get("nodes"))) for r in as_list(mesh.get("routes"))
                  if r.get("sensor") == name]
        killers = [f"{f.get('kind')} {f.get('element')}" for f in as_list(mesh.get("failures"))
                   if name in as_list(f.get("lost_sensors"))]
        cut = as_dict(cuts.get(name))
        rows.append({"name": name, "routes": routes, "arrival": _with_exact(p, expr.get(name)),
                     "p_cut": _with_exact(cut.get("p_cut"), cut.get("p_cut_expression")),
                     "cut_hops": ", ".join(as_list(cut.get("cut_hops"))),
                     "detectable": as_dict(smart.get(name)).get("detectable"),
                     "lost_with": ", ".join(killers) or "—"})
    return rows


def route_table(mesh: dict[str, Any]) -> list[dict[str, Any]]:
    """One row per route: hops with their success and the route's delivery probability."""
    return [{"sensor": r.get("sensor"), "path": " → ".join(as_list(r.get("nodes"))),
             "hops": ", ".join(f"{h} ({_num(s, 4)})" for h, s in
                               zip(as_list(r.get("hops")), as_list(r.get("hop_success")))),
             "arrival": _with_exact(r.get("arrival_probability"), r.get("arrival_expression")),
             "origin": r.get("origin")} for r in as_list(mesh.get("routes"))]


def hop_table(mesh: dict[str, Any]) -> list[dict[str, Any]]:
    """One row per hop: q_h, retries, s_h, link budget, critical success and headroom."""
    out = []
    for h in as_list(mesh.get("hops")):
        link = as_dict(h.get("link"))
        out.append({
            "name": h.get("name"), "bottleneck": h.get("name") == mesh.get("bottleneck"),
            "q": _with_exact(h.get("attempt_success"), h.get("attempt_success_expression")),
            "retries": "—" if h.get("retries") is None else h.get("retries"),
            "s": _with_exact(h.get("period_success"), h.get("period_success_expression")),
            "link": (f"{link.get('radio')}, {_num(link.get('distance_m'), 4)} m, SINR "
                     f"{_num(link.get('sinr_db'), 3)} dB" if link else "given"),
            "critical": _num(h.get("critical_attempt_success"), 4) if h.get("critical")
            else "— (not critical alone)",
            "headroom": _num(h.get("headroom"), 4) if h.get("critical") else "—"})
    return out


def mode_rows(mesh: dict[str, Any]) -> list[dict[str, Any]]:
    """The forwarding modes compared: verdict, badge class and condition."""
    return [{"mode": m.get("mode"), "verdict": m.get("verdict"),
             "css": VERDICT_CSS.get(str(m.get("verdict")), "none"),
             "condition": prose(m.get("condition"))} for m in as_list(mesh.get("modes"))]


def failure_table(mesh: dict[str, Any]) -> list[dict[str, Any]]:
    """N − 1 rows: element, the sensors it cuts off and the verdict with it dead."""
    return [{"kind": f.get("kind"), "element": f.get("element"),
             "lost": ", ".join(as_list(f.get("lost_sensors"))) or "none",
             "verdict": f.get("verdict"), "css": VERDICT_CSS.get(str(f.get("verdict")), "none"),
             "basis": prose(f.get("basis"))} for f in as_list(mesh.get("failures"))]


def mesh_view(rec: dict[str, Any], figures: dict[str, Any]) -> dict[str, Any]:
    """The report's mesh section (``available: False`` for a record without a mesh)."""
    mesh = as_dict(as_dict(rec).get("mesh"))
    if not mesh:
        return {"available": False}
    al, facts, sim = (as_dict(mesh.get("all_lost")), as_dict(mesh.get("facts")),
                      as_dict(mesh.get("simulation")))
    nodes = as_list(mesh.get("nodes"))
    slots = mesh.get("slots_per_period")
    law = as_dict(mesh.get("law"))
    return {
        "available": True,
        "summary": (f"{sum(n.get('role') == 'sensor' for n in nodes)} sensors, "
                    f"{sum(n.get('role') == 'relay' for n in nodes)} relays "
                    f"({mesh.get('relay_mode')} by default), {len(as_list(mesh.get('hops')))} hops"
                    + (f", a slot budget of {slots} slots per route and period" if slots else
                       ", no slot budget (retries within the period)")),
        "routing": ("most reliable path per sensor: Dijkstra on −log s_h, s_h the per-period "
                    "hop success" if "Dijkstra" in str(mesh.get("routing"))
                    else prose(mesh.get("routing"))),
        "verdict": mesh.get("verdict"), "verdict_css": VERDICT_CSS.get(str(mesh.get("verdict")),
                                                                       "none"),
        "basis": prose(mesh.get("basis")), "recommendation": prose(mesh.get("recommendation")),
        "sensors": mesh_sensor_table(mesh), "routes": route_table(mesh), "hops": hop_table(mesh),
        "hop_success_kind": "per attempt (the slot schedule decides the rest)" if slots
        else "per period",
        "all_lost": _with_exact(al.get("value"), al.get("expression")),
        "product": _with_exact(al.get("product_of_marginals"), al.get("product_expression")),
        "ratio": _num(al.get("ratio"), 4), "law_method": prose(law.get("method")),
        "law_cells": [{"set": "{" + ", ".join(as_list(c.get("received"))) + "}",
                       "p": _num(c.get("probability"))} for c in as_list(law.get("largest"))],
        "facts": {"necessary": facts.get("necessary"), "sufficient": facts.get("sufficient"),
                  "reason": prose(facts.get("reason")),
                  "binding": prose(facts.get("necessary_basis"))},
        "bottleneck": mesh.get("bottleneck") or "none (no hop's loss alone breaks the "
                                                "necessary condition)",
        "bottleneck_headroom": _num(mesh.get("bottleneck_headroom"), 4),
        "modes": mode_rows(mesh), "failures": failure_table(mesh),
        "relaying_basis": prose(as_dict(mesh.get("relaying")).get("basis")),
        "simulation": None if not sim else {
            "statement": prose(sim.get("statement")),
            "mean": _num(sim.get("mean_trace")) if sim.get("mean_trace") is not None else None,
            "consistent": sim.get("consistent"),
            "size": f"{sim.get('paths')} paths × {sim.get('steps')} periods, seed {sim.get('seed')}",
            "empirical_all_lost": _num(sim.get("empirical_all_lost"), 4)},
        "map": figure_entry(as_dict(figures).get("mesh_topology"), "Mesh topology",
                            "Nodes at their positions (a layered layout by hops to the gateway "
                            "when the file gives none); arrows are hops, coloured by their "
                            "success, dotted when no route uses them; the bottleneck hop is "
                            "thick; a relay whose death alone makes raw forwarding mean-unstable "
                            "is ringed in red; a = each sensor's arrival probability.",
                            "topology map: not drawn"),
    }
