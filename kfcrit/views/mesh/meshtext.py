"""The mesh in the terminal summary (theory §13): routes, arrivals, joint losses, the forwarding
modes compared, the bottleneck hop and N − 1. Pure function of the record's ``mesh`` section."""
from __future__ import annotations

from typing import Any


def _num(v: Any, digits: int = 6) -> str:
    return "—" if not isinstance(v, (int, float)) or isinstance(v, bool) else f"{v:.{digits}g}"


def _exact(value: Any, expression: Any) -> str:
    return _num(value) + (f" (= {expression})" if expression else "")


def route_lines(mesh: dict[str, Any]) -> list[str]:
    """One line per route: nodes, per-hop success and delivery probability."""
    per = "per attempt" if mesh.get("slots_per_period") else "per period"
    out = [f"    routes ({mesh.get('routing')}); hop success {per}"]
    for r in mesh.get("routes") or []:
        hops = " ".join(_num(s, 4) for s in r.get("hop_success") or [])
        delivers = _exact(r.get("arrival_probability"), r.get("arrival_expression"))
        out.append(f"      {str(r.get('sensor'))[:12]:<12} {' → '.join(r.get('nodes') or [])}"
                   f"  [{hops}]  delivers {delivers}")
    return out


def mesh_lines(rec: dict[str, Any]) -> list[str]:
    """The mesh block of :func:`kfcrit.views.text.terminal.summary` (empty without a mesh)."""
    mesh = rec.get("mesh")
    if not isinstance(mesh, dict):
        return []
    slots = mesh.get("slots_per_period")
    lines = [f"  mesh                  {sum(n.get('role') == 'sensor' for n in mesh.get('nodes') or [])}"
             f" sensors, {sum(n.get('role') == 'relay' for n in mesh.get('nodes') or [])} relays "
             f"({mesh.get('relay_mode')}), {len(mesh.get('hops') or [])} hops"
             + (f", slot budget {slots} per route and period" if slots else "")]
    lines.extend(route_lines(mesh))
    expr = mesh.get("arrival_expression") or {}
    for name, p in (mesh.get("arrival_probability") or {}).items():
        lines.append(f"    arrival {str(name)[:12]:<12} {_exact(p, expr.get(name))}")
    al = mesh.get("all_lost") or {}
    product = _exact(al.get("product_of_marginals"), al.get("product_expression"))
    lines.append(f"    P(all lost)           {_exact(al.get('value'), al.get('expression'))} vs "
                 f"product of marginals {product} (ratio {_num(al.get('ratio'), 4)})")
    facts = mesh.get("facts") or {}
    lines.append(f"    facts                 necessary {facts.get('necessary')}, sufficient "
                 f"{facts.get('sufficient')} ({facts.get('reason')})")
    if mesh.get("bottleneck"):
        lines.append(f"    bottleneck hop        {mesh['bottleneck']} (headroom in per-attempt "
                     f"success {_num(mesh.get('bottleneck_headroom'), 4)})")
    lines.append("    forwarding modes")
    for m in mesh.get("modes") or []:
        lines.append(f"      {str(m.get('mode')):<44} {str(m.get('verdict')).upper():<14} "
                     f"{m.get('condition')}")
    lines.append(f"    needed: {mesh.get('recommendation')}")
    lines.append("    N − 1 (raw forwarding with the element dead)")
    for f in mesh.get("failures") or []:
        lost = ", ".join(f.get("lost_sensors") or []) or "none"
        lines.append(f"      {f.get('kind'):<5} {str(f.get('element'))[:20]:<20} loses {lost:<24} "
                     f"{f.get('verdict')}")
    sim = mesh.get("simulation")
    if isinstance(sim, dict):
        mean = (f"E[tr P] ≈ {_num(sim.get('mean_trace'))}; " if sim.get("mean_trace") is not None
                else "")
        agree = {True: "agrees with", None: "inconclusive against", False: "CONTRADICTS"}[
            sim.get("consistent")]
        lines.append(f"    Monte Carlo           {mean}{sim.get('statement')}; {agree} the verdict "
                     f"({sim.get('paths')} paths × {sim.get('steps')} periods)")
    return lines
