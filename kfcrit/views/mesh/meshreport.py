"""View model of the report's mesh section (theory §13): topology map, the per-sensor table,
routes, joint losses, the forwarding modes compared, the bottleneck hop and N − 1.

Reads the typed record's ``mesh`` section (:class:`~kfcrit.analysis.mesh.section.MeshSection`)
only; every number is the record's (formatted here, so the template computes nothing).
"""
from __future__ import annotations

from typing import Any

from kfcrit.analysis.mesh.section import MeshSection
from kfcrit.analysis.sections import AnalysisRecord
from kfcrit.io.typed import ABSENT
from kfcrit.views.report.parts import figure_entry, prose

VERDICT_CSS = {"mean-stable": "ok", "mean-unstable": "no", "undetermined": "none"}


def _num(v: Any, digits: int = 6) -> str:
    return "—" if not isinstance(v, (int, float)) or isinstance(v, bool) else f"{v:.{digits}g}"


def _with_exact(v: Any, expression: Any) -> str:
    return _num(v) + (f" = {expression}" if expression else "")


def mesh_sensor_table(mesh: MeshSection) -> list[dict[str, Any]]:
    """One row per sensor: routes, arrival probability, smart-sensor test, what kills it."""
    # arrival_probability / arrival_expression are plain dict[str, X] fields of the schema
    arr, expr = mesh.arrival_probability, mesh.arrival_expression
    smart = {s.sensor: s for s in mesh.smart_sensor.sensors}
    cuts = {c.sensor: c for c in mesh.relaying.sensors}
    rows = []
    for name, p in arr.items():
        routes = [" → ".join(r.nodes) for r in mesh.routes if r.sensor == name]
        killers = [f"{f.kind} {f.element}" for f in mesh.failures if name in f.lost_sensors]
        cut = cuts.get(name)
        row_smart = smart.get(name)
        rows.append({"name": name, "routes": routes, "arrival": _with_exact(p, expr.get(name)),
                     "p_cut": _with_exact(cut.p_cut, cut.p_cut_expression) if cut else
                     _with_exact(None, None),
                     "cut_hops": ", ".join(cut.cut_hops) if cut else "",
                     "detectable": row_smart.detectable if row_smart else None,
                     "lost_with": ", ".join(killers) or "—"})
    return rows


def route_table(mesh: MeshSection) -> list[dict[str, Any]]:
    """One row per route: hops with their success and the route's delivery probability."""
    return [{"sensor": r.sensor, "path": " → ".join(r.nodes),
             "hops": ", ".join(f"{h} ({_num(s, 4)})" for h, s in zip(r.hops, r.hop_success)),
             "arrival": _with_exact(r.arrival_probability, r.arrival_expression),
             "origin": r.origin} for r in mesh.routes]


def hop_table(mesh: MeshSection) -> list[dict[str, Any]]:
    """One row per hop: q_h, retries, s_h, link budget, critical success and headroom."""
    out = []
    for h in mesh.hops:
        link = h.link
        out.append({
            "name": h.name, "bottleneck": h.name == mesh.bottleneck,
            "q": _with_exact(h.attempt_success, h.attempt_success_expression),
            "retries": "—" if h.retries is None else h.retries,
            "s": _with_exact(h.period_success, h.period_success_expression),
            "link": (f"{link.radio}, {_num(link.distance_m, 4)} m, SINR "
                     f"{_num(link.sinr_db, 3)} dB" if link is not None else "given"),
            "critical": _num(h.critical_attempt_success, 4) if h.critical
            else "— (not critical alone)",
            "headroom": _num(h.headroom, 4) if h.critical else "—"})
    return out


def mode_rows(mesh: MeshSection) -> list[dict[str, Any]]:
    """The forwarding modes compared: verdict, badge class and condition."""
    return [{"mode": m.mode, "verdict": m.verdict.value,
             "css": VERDICT_CSS.get(m.verdict.value, "none"),
             "condition": prose(m.condition)} for m in mesh.modes]


def failure_table(mesh: MeshSection) -> list[dict[str, Any]]:
    """N − 1 rows: element, the sensors it cuts off and the verdict with it dead."""
    return [{"kind": f.kind, "element": f.element,
             "lost": ", ".join(f.lost_sensors) or "none",
             "verdict": f.verdict.value, "css": VERDICT_CSS.get(f.verdict.value, "none"),
             "basis": prose(f.basis)} for f in mesh.failures]


def mesh_view(rec: AnalysisRecord, figures: dict[str, Any]) -> dict[str, Any]:
    """The report's mesh section (``available: False`` for a record without a mesh)."""
    mesh = rec.mesh
    if mesh is None or mesh is ABSENT:
        return {"available": False}
    al, facts, sim = mesh.all_lost, mesh.facts, mesh.simulation
    nodes = mesh.nodes
    slots = mesh.slots_per_period
    law = mesh.law
    return {
        "available": True,
        "summary": (f"{sum(n.role == 'sensor' for n in nodes)} sensors, "
                    f"{sum(n.role == 'relay' for n in nodes)} relays "
                    f"({mesh.relay_mode} by default), {len(mesh.hops)} hops"
                    + (f", a slot budget of {slots} slots per route and period" if slots else
                       ", no slot budget (retries within the period)")),
        "routing": ("most reliable path per sensor: Dijkstra on −log s_h, s_h the per-period "
                    "hop success" if "Dijkstra" in mesh.routing
                    else prose(mesh.routing)),
        "verdict": mesh.verdict.value, "verdict_css": VERDICT_CSS.get(mesh.verdict.value, "none"),
        "basis": prose(mesh.basis), "recommendation": prose(mesh.recommendation),
        "sensors": mesh_sensor_table(mesh), "routes": route_table(mesh), "hops": hop_table(mesh),
        "hop_success_kind": "per attempt (the slot schedule decides the rest)" if slots
        else "per period",
        "all_lost": _with_exact(al.value, al.expression),
        "product": _with_exact(al.product_of_marginals, al.product_expression),
        "ratio": _num(al.ratio, 4), "law_method": prose(law.method),
        "law_cells": [{"set": "{" + ", ".join(c.received) + "}",
                       "p": _num(c.probability)} for c in law.largest],
        "facts": {"necessary": facts.necessary, "sufficient": facts.sufficient,
                  "reason": prose(facts.reason),
                  "binding": prose(facts.necessary_basis)},
        "bottleneck": mesh.bottleneck or "none (no hop's loss alone breaks the "
                                         "necessary condition)",
        "bottleneck_headroom": _num(mesh.bottleneck_headroom, 4),
        "modes": mode_rows(mesh), "failures": failure_table(mesh),
        "relaying_basis": prose(mesh.relaying.basis),
        "simulation": None if sim is None else {
            "statement": prose(sim.statement),
            "mean": _num(sim.mean_trace) if sim.mean_trace is not None else None,
            "consistent": sim.consistent,
            "size": f"{sim.paths} paths × {sim.steps} periods, seed {sim.seed}",
            "empirical_all_lost": _num(sim.empirical_all_lost, 4)},
        "map": figure_entry(figures.get("mesh_topology"), "Mesh topology",
                            "Nodes at their positions (a layered layout by hops to the gateway "
                            "when the file gives none); arrows are hops, coloured by their "
                            "success, dotted when no route uses them; the bottleneck hop is "
                            "thick; a relay whose death alone makes raw forwarding mean-unstable "
                            "is ringed in red; a = each sensor's arrival probability.",
                            "topology map: not drawn"),
    }
