"""The mesh in the terminal summary (theory §13): routes, arrivals, joint losses, the forwarding
modes compared, the bottleneck hop and N − 1. Pure function of the typed record's ``mesh``
section (:class:`~kfcrit.analysis.mesh.section.MeshSection`)."""
from __future__ import annotations

from typing import Any

from kfcrit.analysis.mesh.section import MeshSection
from kfcrit.analysis.sections import AnalysisRecord
from kfcrit.io.typed import ABSENT


def _num(v: Any, digits: int = 6) -> str:
    return "—" if not isinstance(v, (int, float)) or isinstance(v, bool) else f"{v:.{digits}g}"


def _exact(value: Any, expression: Any) -> str:
    return _num(value) + (f" (= {expression})" if expression else "")


def route_lines(mesh: MeshSection) -> list[str]:
    """One line per route: nodes, per-hop success and delivery probability."""
    per = "per attempt" if mesh.slots_per_period else "per period"
    out = [f"    routes ({mesh.routing}); hop success {per}"]
    for r in mesh.routes:
        hops = " ".join(_num(s, 4) for s in r.hop_success)
        delivers = _exact(r.arrival_probability, r.arrival_expression)
        out.append(f"      {r.sensor[:12]:<12} {' → '.join(r.nodes)}"
                   f"  [{hops}]  delivers {delivers}")
    return out


def mesh_lines(rec: AnalysisRecord) -> list[str]:
    """The mesh block of :func:`kfcrit.views.text.terminal.summary` (empty without a mesh)."""
    mesh = rec.mesh
    if mesh is None or mesh is ABSENT:
        return []
    slots = mesh.slots_per_period
    lines = [f"  mesh                  {sum(n.role == 'sensor' for n in mesh.nodes)}"
             f" sensors, {sum(n.role == 'relay' for n in mesh.nodes)} relays "
             f"({mesh.relay_mode}), {len(mesh.hops)} hops"
             + (f", slot budget {slots} per route and period" if slots else "")]
    lines.extend(route_lines(mesh))
    # arrival_expression is a plain dict[str, str] field of the schema: its keys are sensors
    expr = mesh.arrival_expression
    for name, p in mesh.arrival_probability.items():
        lines.append(f"    arrival {name[:12]:<12} {_exact(p, expr.get(name))}")
    al = mesh.all_lost
    product = _exact(al.product_of_marginals, al.product_expression)
    lines.append(f"    P(all lost)           {_exact(al.value, al.expression)} vs "
                 f"product of marginals {product} (ratio {_num(al.ratio, 4)})")
    facts = mesh.facts
    lines.append(f"    facts                 necessary {facts.necessary}, sufficient "
                 f"{facts.sufficient} ({facts.reason})")
    if mesh.bottleneck:
        lines.append(f"    bottleneck hop        {mesh.bottleneck} (headroom in per-attempt "
                     f"success {_num(mesh.bottleneck_headroom, 4)})")
    lines.append("    forwarding modes")
    for m in mesh.modes:
        lines.append(f"      {m.mode:<44} {m.verdict.value.upper():<14} "
                     f"{m.condition}")
    lines.append(f"    needed: {mesh.recommendation}")
    lines.append("    N − 1 (raw forwarding with the element dead)")
    for f in mesh.failures:
        lost = ", ".join(f.lost_sensors) or "none"
        lines.append(f"      {f.kind:<5} {f.element[:20]:<20} loses {lost:<24} "
                     f"{f.verdict.value}")
    sim = mesh.simulation
    if sim is not None:
        mean = f"E[tr P] ≈ {_num(sim.mean_trace)}; " if sim.mean_trace is not None else ""
        agree = {True: "agrees with", None: "inconclusive against", False: "CONTRADICTS"}[
            sim.consistent]
        lines.append(f"    Monte Carlo           {mean}{sim.statement}; {agree} the verdict "
                     f"({sim.paths} paths × {sim.steps} periods)")
    return lines
