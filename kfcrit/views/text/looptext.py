"""Text of a closed loop's record section (theory §12), shared by the terminal view and the
report: thresholds, verdict, cost and its bounds, the TCP-like/UDP-like comparison, the Monte
Carlo check and the actuation link. Pure functions of ``record["loop"]``."""
from __future__ import annotations

import math
from typing import Any


def number_text(v: Any, digits: int = 6) -> str:
    """A number to ``digits`` significant digits; ``∞`` for an infinite (null) cost."""
    if v is None:
        return "—"
    if isinstance(v, float) and not math.isfinite(v):
        return "∞"
    return f"{v:.{digits}g}" if isinstance(v, float) else str(v)


def threshold_text(th: dict[str, Any] | None) -> str:
    """``9/25 = 0.36 (theorem)`` or ``in [lo, hi] (certified-interval)``."""
    if not th:
        return "—"
    if th.get("value") is None and not th.get("interval"):
        return "none (an unstable mode is unobservable or unreachable)"
    iv = th.get("interval") or [None, None]
    if th.get("exact") and th.get("expression"):
        head = f"{th['expression']} = {number_text(th.get('value'), 12)}"
    elif th.get("value") is not None and iv[0] is not None and iv[1] - iv[0] < 1e-12:
        head = number_text(th["value"], 12)
    else:
        head = f"in [{number_text(iv[0], 10)}, {number_text(iv[1], 10)}]"
    return f"{head} ({th.get('basis')})"


def cost_text(cost: dict[str, Any] | None) -> str:
    """``J = 5.65894 in [3.54, 5.74]``, or ``J = ∞`` when proven infinite."""
    if not cost:
        return "—"
    if cost.get("finite") is False:
        return "J = ∞ (" + (cost.get("reason") or "not mean-square stable") + ")"
    value = cost.get("value")
    lo, hi = cost.get("lower"), cost.get("upper")
    text = f"J = {number_text(value)}" if value is not None else "J not computed"
    if cost.get("error"):
        text += f" ± {cost['error']:.2g}"
    if (lo, hi) != (value, value) and (lo is not None or hi is not None):
        text += f"  in [{number_text(lo)}, {number_text(hi) if hi is not None else '∞'}]"
    return text


def design_label(loop: dict[str, Any]) -> str:
    """What the loop is: TCP-like/UDP-like, zero/hold, optimal or a fixed design."""
    kind = "TCP-like (acknowledged)" if loop.get("acknowledged") else "UDP-like (no acks)"
    design = ("optimal: time-varying Kalman filter, L from the control MARE"
              if loop.get("design") == "tcp-optimal" else
              f"fixed design: {(loop.get('gains') or {}).get('source', 'fixed gains')}")
    return f"{kind}, {loop.get('on_loss')} on loss; {design}"


def comparison_lines(loop: dict[str, Any], indent: str = "      ") -> list[str]:
    """One line per design of the TCP-like/UDP-like comparison."""
    out = []
    for row in loop.get("comparison") or []:
        rho = row.get("spectral_radius")
        crit = row.get("critical_nu")
        out.append(f"{indent}{row['design']:<26} {cost_text(row.get('cost')):<34}"
                   + (f" ρ = {rho:.4g}" if rho is not None else "")
                   + (f"  ν̄ needed > {crit:.4g}" if crit is not None else ""))
    return out


def loop_lines(loop: dict[str, Any] | None) -> list[str]:
    """The terminal block of a closed loop."""
    if not loop:
        return []
    lines = [f"  closed loop           {design_label(loop)}",
             f"      sensing γ̄ = {number_text(loop['sensing_arrival_probability'])}, "
             f"γ_c {threshold_text(loop.get('sensing_critical'))}",
             f"      actuation ν̄ = {number_text(loop['actuation_arrival_probability'])} "
             f"({loop.get('actuation_model')}), ν_c "
             f"{threshold_text(loop.get('actuation_critical'))}",
             f"      loop verdict {str(loop.get('verdict')).upper()}: {loop.get('basis')}"]
    if loop.get("spectral_radius") is not None:
        lines.append(f"      second-moment spectral radius ρ = {loop['spectral_radius']:.6g}")
    lines.append(f"      cost {cost_text(loop.get('cost'))}")
    if loop.get("comparison"):
        lines.append("      TCP-like against UDP-like at the operating point:")
        lines.extend(comparison_lines(loop, "        "))
    sim = loop.get("simulation")
    if sim:
        lines.append(f"      Monte Carlo ({sim['paths']} paths × {sim['steps']} steps, seed "
                     f"{sim['seed']}): {sim['status']} — {sim['detail']}")
    link = loop.get("actuation_link")
    if link:
        lines.append(f"      actuation link: margin {number_text(link.get('link_margin_db'), 4)} dB "
                     f"(policy {number_text(link.get('required_margin_db'), 4)} dB), outage "
                     f"{number_text(link.get('outage_probability'), 3)} (max "
                     f"{number_text(link.get('max_outage'), 3)}), needed ν̄ > "
                     f"{number_text(link.get('required_arrival_probability'))}")
    for note in loop.get("notes") or []:
        lines.append(f"      note: {note}")
    return lines


VERDICT_CSS = {"mean-square-stable": "ok", "mean-square-unstable": "no", "undetermined": "none"}


def loop_view(rec: dict[str, Any]) -> dict[str, Any]:
    """The report's closed-loop section: strings and rows only (``available`` False without a
    loop); the figures are added by the report's view model."""
    loop = rec.get("loop") if isinstance(rec, dict) else None
    if not isinstance(loop, dict):
        return {"available": False}
    rows = [("design", design_label(loop)),
            ("sensing link γ̄", f"{number_text(loop['sensing_arrival_probability'])} "
             f"({'i.i.d.' if loop.get('sensing_iid') else 'bursty'})"),
            ("sensing threshold γ_c", threshold_text(loop.get("sensing_critical"))),
            ("actuation link ν̄", f"{number_text(loop['actuation_arrival_probability'])} "
             f"({loop.get('actuation_model')}, "
             f"{'i.i.d.' if loop.get('actuation_iid') else 'bursty'})"),
            ("actuation threshold ν_c", threshold_text(loop.get("actuation_critical"))),
            ("second-moment spectral radius ρ", number_text(loop.get("spectral_radius"))),
            ("average cost", cost_text(loop.get("cost")))]
    sim = loop.get("simulation") or {}
    link = loop.get("actuation_link") or {}
    return {"available": True, "verdict": loop.get("verdict"),
            "verdict_css": VERDICT_CSS.get(str(loop.get("verdict")), "none"),
            "basis": loop.get("basis") or "", "operating_verdict": loop.get("operating_verdict"),
            "rows": [{"label": k, "value": v} for k, v in rows],
            "comparison": [{"design": r.get("design"),
                            "acks": "yes" if r.get("acknowledged") else "no",
                            "on_loss": r.get("on_loss"), "stability": r.get("stability"),
                            "rho": number_text(r.get("spectral_radius"), 5),
                            "cost": cost_text(r.get("cost")),
                            "critical_nu": number_text(r.get("critical_nu"), 5)}
                           for r in loop.get("comparison") or []],
            "simulation": (f"{sim.get('status')}: {sim.get('detail')} (seed {sim.get('seed')}, "
                           f"{sim.get('design')})") if sim else "",
            "link": [{"label": k, "value": v} for k, v in (
                ("needed ν̄ (" + str(link.get("required_basis")) + ")",
                 number_text(link.get("required_arrival_probability"))),
                ("link margin", f"{number_text(link.get('link_margin_db'), 4)} dB (policy "
                 f"{number_text(link.get('required_margin_db'), 4)} dB): "
                 f"{'met' if link.get('margin_policy_met') else 'NOT met'}"),
                ("shadowing outage", f"{number_text(link.get('outage_probability'), 3)} (max "
                 f"{number_text(link.get('max_outage'), 3)})"),
                ("distance", f"{number_text(link.get('distance_m'), 5)} m (max "
                 f"{number_text(link.get('max_distance_m'), 5)} m)"))] if link else [],
            "notes": list(loop.get("notes") or [])}
