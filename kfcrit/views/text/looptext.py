"""Text of a closed loop's record section (theory §12), shared by the terminal view and the
report: thresholds, verdict, cost and its bounds, the TCP-like/UDP-like comparison, the Monte
Carlo check and the actuation link. Pure functions of the typed ``loop`` section
(:class:`~kfcrit.analysis.loop.schema.LoopSection`)."""
from __future__ import annotations

import math
from typing import Any

from kfcrit.analysis.loop.schema import LoopCostSummary, LoopSection, LoopThreshold
from kfcrit.analysis.sections import AnalysisRecord
from kfcrit.io.typed import ABSENT


def number_text(v: Any, digits: int = 6) -> str:
    """A number to ``digits`` significant digits; ``∞`` for an infinite (null) cost."""
    if v is None:
        return "—"
    if isinstance(v, float) and not math.isfinite(v):
        return "∞"
    return f"{v:.{digits}g}" if isinstance(v, float) else str(v)


def threshold_text(th: LoopThreshold | None) -> str:
    """``9/25 = 0.36 (theorem)`` or ``in [lo, hi] (certified-interval)``."""
    if th is None:
        return "—"
    if th.value is None and not th.interval:
        return "none (an unstable mode is unobservable or unreachable)"
    iv = th.interval or [None, None]
    if th.exact and th.expression:
        head = f"{th.expression} = {number_text(th.value, 12)}"
    elif th.value is not None and iv[0] is not None and iv[1] - iv[0] < 1e-12:
        head = number_text(th.value, 12)
    else:
        head = f"in [{number_text(iv[0], 10)}, {number_text(iv[1], 10)}]"
    return f"{head} ({th.basis})"


def cost_text(cost: LoopCostSummary | None) -> str:
    """``J = 5.65894 in [3.54, 5.74]``, or ``J = ∞`` when proven infinite."""
    if cost is None:
        return "—"
    if cost.finite is False:
        return "J = ∞ (" + (cost.reason or "not mean-square stable") + ")"
    value = cost.value
    lo, hi = cost.lower, cost.upper
    text = f"J = {number_text(value)}" if value is not None else "J not computed"
    if cost.error:
        text += f" ± {cost.error:.2g}"
    if (lo, hi) != (value, value) and (lo is not None or hi is not None):
        text += f"  in [{number_text(lo)}, {number_text(hi) if hi is not None else '∞'}]"
    return text


def design_label(loop: LoopSection) -> str:
    """What the loop is: TCP-like/UDP-like, zero/hold, optimal or a fixed design."""
    kind = "TCP-like (acknowledged)" if loop.acknowledged else "UDP-like (no acks)"
    source = loop.gains.source if loop.gains is not None else "fixed gains"
    design = ("optimal: time-varying Kalman filter, L from the control MARE"
              if loop.design == "tcp-optimal" else f"fixed design: {source}")
    return f"{kind}, {loop.on_loss} on loss; {design}"


def comparison_lines(loop: LoopSection, indent: str = "      ") -> list[str]:
    """One line per design of the TCP-like/UDP-like comparison."""
    out = []
    for row in loop.comparison:
        rho = row.spectral_radius
        crit = row.critical_nu
        out.append(f"{indent}{row.design:<26} {cost_text(row.cost):<34}"
                   + (f" ρ = {rho:.4g}" if rho is not None else "")
                   + (f"  ν̄ needed > {crit:.4g}" if crit is not None else ""))
    return out


def loop_lines(loop: LoopSection | None) -> list[str]:
    """The terminal block of a closed loop (empty without one)."""
    if loop is None or loop is ABSENT:
        return []
    lines = [f"  closed loop           {design_label(loop)}",
             f"      sensing γ̄ = {number_text(loop.sensing_arrival_probability)}, "
             f"γ_c {threshold_text(loop.sensing_critical)}",
             f"      actuation ν̄ = {number_text(loop.actuation_arrival_probability)} "
             f"({loop.actuation_model}), ν_c "
             f"{threshold_text(loop.actuation_critical)}",
             f"      loop verdict {loop.verdict.value.upper()}: {loop.basis}"]
    if loop.spectral_radius is not None:
        lines.append(f"      second-moment spectral radius ρ = {loop.spectral_radius:.6g}")
    lines.append(f"      cost {cost_text(loop.cost)}")
    if loop.comparison:
        lines.append("      TCP-like against UDP-like at the operating point:")
        lines.extend(comparison_lines(loop, "        "))
    sim = loop.simulation
    if sim is not None:
        lines.append(f"      Monte Carlo ({sim.paths} paths × {sim.steps} steps, seed "
                     f"{sim.seed}): {sim.status} — {sim.detail}")
    link = loop.actuation_link
    if link is not None:
        lines.append(f"      actuation link: margin {number_text(link.link_margin_db, 4)} dB "
                     f"(policy {number_text(link.required_margin_db, 4)} dB), outage "
                     f"{number_text(link.outage_probability, 3)} (max "
                     f"{number_text(link.max_outage, 3)}), needed ν̄ > "
                     f"{number_text(link.required_arrival_probability)}")
    for note in loop.notes:
        lines.append(f"      note: {note}")
    return lines


VERDICT_CSS = {"mean-square-stable": "ok", "mean-square-unstable": "no", "undetermined": "none"}


def loop_view(rec: AnalysisRecord) -> dict[str, Any]:
    """The report's closed-loop section: strings and rows only (``available`` False without a
    loop); the figures are added by the report's view model."""
    loop = rec.loop
    if loop is None or loop is ABSENT:
        return {"available": False}
    rows = [("design", design_label(loop)),
            ("sensing link γ̄", f"{number_text(loop.sensing_arrival_probability)} "
             f"({'i.i.d.' if loop.sensing_iid else 'bursty'})"),
            ("sensing threshold γ_c", threshold_text(loop.sensing_critical)),
            ("actuation link ν̄", f"{number_text(loop.actuation_arrival_probability)} "
             f"({loop.actuation_model}, "
             f"{'i.i.d.' if loop.actuation_iid else 'bursty'})"),
            ("actuation threshold ν_c", threshold_text(loop.actuation_critical)),
            ("second-moment spectral radius ρ", number_text(loop.spectral_radius)),
            ("average cost", cost_text(loop.cost))]
    sim = loop.simulation
    link = loop.actuation_link
    return {"available": True, "verdict": loop.verdict.value,
            "verdict_css": VERDICT_CSS.get(loop.verdict.value, "none"),
            "basis": loop.basis or "", "operating_verdict": loop.operating_verdict.value,
            "rows": [{"label": k, "value": v} for k, v in rows],
            "comparison": [{"design": r.design,
                            "acks": "yes" if r.acknowledged else "no",
                            "on_loss": r.on_loss, "stability": r.stability,
                            "rho": number_text(r.spectral_radius, 5),
                            "cost": cost_text(r.cost),
                            "critical_nu": number_text(r.critical_nu, 5)}
                           for r in loop.comparison],
            "simulation": (f"{sim.status}: {sim.detail} (seed {sim.seed}, "
                           f"{sim.design})") if sim is not None else "",
            "link": [{"label": k, "value": v} for k, v in (
                ("needed ν̄ (" + link.required_basis + ")",
                 number_text(link.required_arrival_probability)),
                ("link margin", f"{number_text(link.link_margin_db, 4)} dB (policy "
                 f"{number_text(link.required_margin_db, 4)} dB): "
                 f"{'met' if link.margin_policy_met else 'NOT met'}"),
                ("shadowing outage", f"{number_text(link.outage_probability, 3)} (max "
                 f"{number_text(link.max_outage, 3)})"),
                ("distance", f"{number_text(link.distance_m, 5)} m (max "
                 f"{number_text(link.max_distance_m, 5)} m)"))] if link is not None else [],
            "notes": list(loop.notes)}
