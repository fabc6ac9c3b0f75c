"""Terminal view of the analysis record (a pure function of ``Analysis.to_dict()``)."""
from __future__ import annotations

import re
from typing import Any

from kfcrit.views.formatting import counted
from kfcrit.views.mesh.meshtext import mesh_lines
from kfcrit.views.text.looptext import loop_lines
from kfcrit.views.text.netmargin import (
    NETWORK_P_MEANING,
    bottleneck_margin_text,
    margin_text,
)
from kfcrit.views.text.tracefit import channel_fit_lines

_DECIMAL = re.compile(r"-?\d+(\.\d+)?(e[-+]?\d+)?")
_LONG_DECIMAL = re.compile(r"\d\.\d{9,}")


def _num(v: Any, digits: int = 6) -> str:
    if v is None:
        return "—"
    if isinstance(v, float):
        return f"{v:.{digits}g}"
    return str(v)


def safe_text(text: Any) -> str:
    """Text from a user's file with control characters (ESC, CR, …) shown as ``\\xNN``, so
    that a crafted name cannot rewrite the terminal."""
    return "".join(c if c.isprintable() or c == " " else f"\\x{ord(c):02x}" for c in str(text))


EXACT_TEXT_MAX = 100
"""Longest exact expression the terminal view prints in full (``--json`` always has it all)."""


def _exact(d: dict[str, Any]) -> str:
    """``  (= expression)`` for a quantity with an exact form; long forms point to ``--json``."""
    expr = (d.get("expression") or "").strip()
    if not expr or _DECIMAL.fullmatch(expr) or _LONG_DECIMAL.search(expr):
        return ""   # a decimal (or text holding one) is the value itself, not an exact form
    if "RootOf" in expr or len(expr) > EXACT_TEXT_MAX:
        return f"  (exact form of {len(expr)} characters: see --json)"
    return f"  (= {expr})"


REVIEW_MARK = {"pass": "PASS", "fail": "FAIL", "undetermined": "UNDETERMINED"}
STATUS_MARK = {"pass": "ok ", "fail": "FAIL", "undetermined": "?  ", "not applicable": "-  "}


def review_lines(rec: dict[str, Any]) -> list[str]:
    """The review decision and its reasons (the first thing a reader sees)."""
    review = rec.get("review") or {}
    decision = review.get("decision")
    lines = [f"  REVIEW: {REVIEW_MARK.get(decision, '—')}"]
    for r in review.get("reasons") or []:
        lines.append(f"    [{STATUS_MARK.get(r.get('status'), '?  ')}] {r.get('check')}: "
                     f"{r.get('detail')}")
    return lines


def _value_text(d: dict[str, Any] | None) -> str:
    """A value with its exact form, or its interval when only bracketed."""
    d = d or {}
    if d.get("value") is not None:
        expr = d.get("expression")
        return f"{d['value']:.6g}" + (f" (= {expr})" if d.get("exact") and expr and
                                       len(expr) <= 30 else "")
    iv = d.get("interval")
    if iv:
        return f"in [{_num(iv[0])}, {_num(iv[1])}]"
    return "—"


def design_lines(design: dict[str, Any] | None) -> list[str]:
    """The accuracy requirement as a required arrival probability, and what it asks of the
    radio (theory §11)."""
    if not design:
        return []
    req = design.get("required_arrival_probability") or {}
    lines = [f"  accuracy requirement  {design.get('requirement')}"]
    if req.get("status") == "interval":
        lo, hi = req["interval"]
        lines.append(f"  required arrival p    [{_num(lo)}, {_num(hi)}]  (p ≤ p_S fails, "
                     "p ≥ p_V meets it)")
    else:
        lines.append(f"  required arrival p    {req.get('status')}: {req.get('reason') or ''}")
    radio = design.get("radio") or {}
    for key in ("max_distance_m", "min_tx_power_dbm", "max_payload_bytes", "retries_needed"):
        bound = radio.get(key)
        if not isinstance(bound, dict):
            continue
        unit = bound.get("unit") or ""
        ends = []
        for end, what in (("sufficient", "meets it"), ("necessary", "beyond it fails")):
            b = bound.get(end) or {}
            status = b.get("status")
            text = {"unbounded": "no limit", "unreachable": "unreachable",
                    "phy-limit": f"{_num(b.get('value'))} {unit} (the PHY's limit)"}.get(
                status, f"{_num(b.get('value'))} {unit}")
            ends.append(f"{text} {what}")
        lines.append(f"    {bound.get('quantity') or key:<19} {bound.get('sense', '')}: "
                     + "; ".join(ends))
    return lines


def network_lines(net: dict[str, Any] | None) -> list[str]:
    """The sensor network: one row per node (arrival probability, critical value, margin,
    verdict with that link dead), the uniform margin and the bottleneck link."""
    if not net:
        return []
    lines = ["  sensor network        " + f"{counted(len(net.get('sensors') or []), 'sensor')}, verdict "
             f"{(net.get('verdict') or '—').upper()}",
             f"    {'sensor':<12} {'p_i':>9}  {'critical p_i':<24} {'margin':>19}  N−1 (link dead)"]
    for s in net.get("sensors") or []:
        # the report's margin text (an interval when p_c,i is only bracketed): one rendering
        lines.append(f"    {safe_text(s.get('name'))[:12]:<12} "
                     f"{_num(s.get('arrival_probability')):>9}  "
                     f"{_value_text(s.get('critical_value')):<24} "
                     f"{margin_text(s):>19}  "
                     f"{(s.get('n_minus_1') or {}).get('verdict', '—')}")
    um = net.get("uniform_margin") or {}
    lines.append(f"    uniform margin δ      {_value_text(um)}  (every link degraded by δ "
                 "reaches the boundary)")
    bn = net.get("bottleneck") or {}
    if bn.get("name"):
        lines.append(f"    bottleneck link       {safe_text(bn['name'])}  (margin "
                     f"{bottleneck_margin_text(bn)})")
    return lines


def summary(rec: dict[str, Any]) -> str:
    """A readable multi-line summary of an analysis record."""
    lines = [f"kfcrit analysis: {safe_text(rec['name'])}"]
    lines.extend(review_lines(rec))
    sysd = rec.get("system") or {}
    lines.append(f"  states n = {sysd.get('n')}, outputs m = {sysd.get('m')}, "
                 f"input {'exact' if sysd.get('exact_input') else 'floating-point'}")
    lines.append(f"  classification        {rec.get('classification') or '—'}")
    cv = rec.get("critical_value") or {}
    # a floating-point input's values are numerical even where decided on its binary rationals
    exact_input = sysd.get("exact_input") is not False
    stacked = (rec.get("network") is not None
               and len((rec.get("network") or {}).get("sensors") or []) > 1)
    if stacked:
        lines.append("  stacked system (all sensors on one link): p_c, p_low and p_up below; "
                     "each sensor's own critical value is in the network table")
    elif rec.get("mesh") is not None:
        lines.append("  stacked system (all sensors on one link): p_c, p_low and p_up below; "
                     "the mesh is judged on its joint law of the received set (mesh section), "
                     "not by one p against this p_c")
    lines.append(f"  critical value p_c    {_num(cv.get('value'), 12)}"
                 f"{_exact(cv) if cv.get('exact') and exact_input else ''}")
    if cv.get("reason"):
        lines.append(f"      {cv['reason']}")
    rob = rec.get("robust_critical_value")
    if rob:
        lines.append(f"  robust critical value {_num(rob.get('value'), 12)}  "
                     f"(tolerance {rob.get('tolerance')})")
    lb = rec.get("lower_bound") or {}
    lines.append(f"  lower bound p_low     {_num(lb.get('value'), 12)}"
                 f"{_exact(lb) if exact_input else ''}")
    blb = rec.get("block_lower_bound")
    if blb:
        lines.append(f"  block lower bound     {_num(blb.get('value'), 12)}"
                     f"{_exact(blb) if exact_input else ''}")
    ub = rec.get("upper_bound")
    if ub and ub.get("status") == "not applicable":
        lines.append(f"  upper bound p_up      {ub.get('reason') or 'not applicable'}")
    elif ub:
        iv = ub.get("interval") or [None, None]
        lines.append(f"  upper bound p_up      {_num(ub.get('value'), 12)}  in "
                     f"[{_num(iv[0], 12)}, {_num(iv[1], 12)}]"
                     f"{'  certified' if ub.get('certified') else '  not certified'}")
    op = rec.get("operating_point")
    if op:
        network = rec.get("network") is not None and op.get("bottleneck") is not None
        if network:
            lines.append(f"  bottleneck link p     {_num(op.get('arrival_probability'), 12)}  "
                         f"({safe_text(op.get('bottleneck'))})")
        else:
            lines.append(f"  operating point p     {_num(op.get('arrival_probability'), 12)}")
        if op.get("margin") is not None:
            label = ("uniform margin δ" if network else "margin r - r_nec"
                     if op.get("recovery_threshold") is not None else "margin p - p_c")
            lines.append(f"  {label:<21} {op['margin']:+.6g}")
            if op.get("margin_to_sufficient") is not None:
                lines.append(f"  margin r - r_suf(f)   {op['margin_to_sufficient']:+.6g}")
            if op.get("recovery_threshold") is not None and op.get("iid_margin") is not None:
                lines.append(f"      (i.i.d. comparison p - p_c = {op['iid_margin']:+.6g}: not "
                             "a margin for this channel)")
        if op.get("bracket") and not (network and op.get("margin") is not None):
            b = op["bracket"]
            label = "uniform margin δ in" if network else "bracket"
            lines.append(f"  {label:<21} [{_num(b[0])}, {_num(b[1])}]")
        lines.append(f"  stability verdict     {op.get('verdict', '—').upper()}")
        if op.get("reason"):
            lines.append(f"      reason: {op['reason']}")
        if op.get("iid_comparison_verdict") and op["iid_comparison_verdict"] != op.get("verdict"):
            lines.append(f"      (the i.i.d. comparison p vs p_c alone would say "
                         f"{op['iid_comparison_verdict']})")
        if op.get("basis"):
            lines.append(f"      basis: {op['basis']}")
        if op.get("note"):
            lines.append(f"      note: {op['note']}")
    lines.extend(channel_fit_lines(rec.get("channel_fit")))
    lines.extend(network_lines(rec.get("network")))
    lines.extend(mesh_lines(rec))
    lines.extend(loop_lines(rec.get("loop")))
    lines.extend(design_lines(rec.get("design")))
    lines.extend(_bounds_lines(rec))
    lines.extend(_simulation_lines(rec))
    lines.extend(_link_lines(rec))
    checks = rec.get("verification") or []
    if checks:
        passed = sum(c.get("passed") is True for c in checks)
        failed = [c["check"] for c in checks if c.get("passed") is False]
        unsure = [c["check"] for c in checks if c.get("status") == "inconclusive"]
        idle = sum(c.get("status") == "not applicable" for c in checks)
        lines.append(f"  verification          {passed} of {len(checks) - idle} checks passed"
                     + (f" ({idle} not applicable)" if idle else "")
                     + (f"; inconclusive: {'; '.join(unsure)}" if unsure else "")
                     + (f"; FAILED: {'; '.join(failed)}" if failed else ""))
    for w in rec.get("warnings") or []:
        lines.append(f"  warning: {w}")
    return "\n".join(lines)


def _bounds_lines(rec: dict[str, Any]) -> list[str]:
    cb = rec.get("covariance_bounds")
    if not cb:
        return []
    lo, up = cb.get("lower") or {}, cb.get("upper") or {}
    if up.get("computed") is False or str(up.get("method") or "").startswith("not computed"):
        return _uncomputed_upper_lines(cb)
    out = [f"  lim E[P] bounds at p   tr S̄ = {_num(lo.get('trace')) if lo.get('exists') else '∞'}"
           f" ≤ tr lim E[P] ≤ tr V̄ = {_num(up.get('trace')) if up.get('exists') else '∞'}"]
    if (rec.get("operating_point") or {}).get("iid") is False:
        out.append("      (i.i.d. bounds at the stationary arrival probability: they do not "
                   "bound E[P] for this channel)")
    mj = cb.get("markov_jump")
    if isinstance(mj, dict):
        mlo, mup = mj.get("lower") or {}, mj.get("upper") or {}
        out.append(f"  lim E[P] bursty link   {_num(mlo.get('trace')) if mlo.get('exists') else '∞'}"
                   f" ≤ tr lim E[P] ≤ {_num(mup.get('trace')) if mup.get('exists') else '∞'}"
                   "  (Markov-jump bounds valid for this Gilbert–Elliott channel, theory §10)")
    if cb.get("applicable") is False and cb.get("reason"):
        out.append(f"      V̄ {cb['reason']}")
    return out


def _uncomputed_upper_lines(cb: dict[str, Any]) -> list[str]:
    """Bounds of lim E[P] when V̄ was not computed (a sensor network): S̄ only, at the p the
    record states with its meaning (``p_meaning``), and V̄ "not computed", never ∞."""
    lo, up = cb.get("lower") or {}, cb.get("upper") or {}
    s_text = _num(lo.get("trace")) if lo.get("exists") else "∞"
    out = [f"  lim E[P] bounds       tr S̄ = {s_text} ≤ tr lim E[P]  at p = {_num(cb.get('p'))}; "
           f"tr V̄ {safe_text(up.get('method') or 'not computed')}"]
    meaning = cb.get("p_meaning") or (NETWORK_P_MEANING if up.get("method") ==
                                      "not computed for a network" else None)
    if meaning:
        out.append(f"      p = {_num(cb.get('p'))} is {safe_text(meaning)}")
    return out


def _simulation_lines(rec: dict[str, Any]) -> list[str]:
    net = (rec.get("simulation") or {}).get("network")
    if net:
        if net.get("mean_exists") is False:
            return [f"  simulated E[tr P_t]   diverges (network mean-unstable); sample mean "
                    f"{_num(net.get('sample_mean_trace'))} is not an estimate"]
        mt = net.get("mean_trace") or {}
        return [f"  simulated E[tr P_t]   {_num(mt.get('mean'))} at t = {net.get('steps')} "
                f"(95% CI {_num(mt.get('lower'))} .. {_num(mt.get('upper'))}; "
                f"{net.get('paths')} paths, each sensor over its own link)"]
    sim = (rec.get("simulation") or {}).get("operating_point")
    if not sim:
        return []
    mt = sim.get("mean_trace") or {}
    out = []
    if mt.get("diverges"):
        sample = ((sim.get("sample_mean_trace") or {}).get("mean") or [None])[-1]
        out.append(f"  simulated E[tr P_t]   diverges (the mean does not exist here); the sample "
                   f"mean {_num(sample)} at t = {sim.get('steps')} is not an estimate")
    elif mt.get("mean"):
        out.append(f"  simulated E[tr P_t]   {_num(mt['mean'][-1])} at t = {sim.get('steps')} "
                   f"({sim.get('paths')} paths, seed {sim.get('seed')})")
    ex = sim.get("exceedance")
    if ex:
        label = f"P(tr P > {_num(ex.get('level'))})"
        band = (f" (95% CI {_num(ex.get('lower'), 4)} .. {_num(ex.get('upper'), 4)})"
                if ex.get("lower") is not None else "")
        out.append(f"  {label:<21} {_num(ex.get('estimate'), 4)} at t = {sim.get('steps')}"
                   + band)
    ass = (rec.get("requirements") or {}).get("assessment") or {}
    if ass.get("status"):
        out.append(f"  requirement           {str(ass['status']).upper()}: {ass.get('basis')}")
    div = sim.get("divergence") or {}
    if div.get("diverged_paths"):
        out.append(f"  diverged paths        {div['diverged_paths']} of {sim.get('paths')}")
    return out


def _yes_no(v: Any, yes: str = "met", no: str = "NOT met") -> str:
    return "—" if v is None else (yes if v else no)


def _link_lines(rec: dict[str, Any]) -> list[str]:
    """Link-budget design outputs and the bursty-link condition, as the record states them."""
    lb = rec.get("link_budget")
    if not lb or not lb.get("applicable", True):
        return []
    out = []
    req = lb.get("required_arrival_probability") or {}
    if req.get("design_value") is not None:
        out.append(f"  required arrival p    {_num(req['design_value'])}"
                   + (f"  ({req['basis']})" if req.get("basis") else ""))
    for key, label, unit in (("required_sinr_db", "required SINR", " dB"),
                             ("required_rx_power_dbm", "required rx power", " dBm"),
                             ("link_margin_db", "link margin", " dB")):
        if lb.get(key) is not None:
            out.append(f"  {label:<21} {_num(lb[key])}{unit}")
    if lb.get("max_distance_unbounded"):
        out.append(f"  {'max distance':<21} unbounded at the margin policy")
    elif lb.get("max_distance_m") is not None:
        out.append(f"  {'max distance':<21} {_num(lb['max_distance_m'])} m")
    shadow = lb.get("shadowing") or {}
    if shadow.get("mean_arrival_probability") is not None:
        out.append(f"  shadowing-averaged p  {_num(shadow['mean_arrival_probability'])}"
                   f" (σ = {_num(shadow.get('sigma_db'))} dB, {shadow.get('mode') or '—'})")
    dc = lb.get("design_check") or {}
    if dc:
        out.append(f"  margin policy         {_yes_no(dc.get('margin_policy_met'))}: link margin "
                   f"{_num(dc.get('link_margin_db'), 4)} dB, policy needs "
                   f"{_num(dc.get('required_margin_db'), 4)} dB = max(margin_db, "
                   "σ·Φ⁻¹(1 − max_outage))")
        if dc.get("outage_probability") is not None:
            out.append(f"  outage probability    {_num(dc['outage_probability'], 4)}"
                       + (f" (policy allows {_num(dc.get('max_outage'), 4)}: "
                          f"{_yes_no(dc.get('outage_within_policy'), 'within', 'EXCEEDED')})"
                          if dc.get("max_outage") is not None else ""))
    cond = lb.get("condition")
    if isinstance(cond, dict) and cond.get("expression"):
        out.append(f"  bursty link           {cond['expression']}: {_num(cond.get('value'))} "
                   f"({'holds' if cond.get('holds') else 'fails'}; {cond.get('status')})")
    return out
