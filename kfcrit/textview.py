"""Terminal view of the analysis record (a pure function of ``Analysis.to_dict()``)."""
from __future__ import annotations

from typing import Any


def _num(v: Any, digits: int = 6) -> str:
    if v is None:
        return "—"
    if isinstance(v, float):
        return f"{v:.{digits}g}"
    return str(v)


def summary(rec: dict[str, Any]) -> str:
    """A readable multi-line summary of an analysis record."""
    lines = [f"kfcrit analysis: {rec['name']}"]
    sysd = rec.get("system") or {}
    lines.append(f"  states n = {sysd.get('n')}, outputs m = {sysd.get('m')}, "
                 f"input {'exact' if sysd.get('exact_input') else 'floating-point'}")
    lines.append(f"  classification        {rec.get('classification') or '—'}")
    cv = rec.get("critical_value") or {}
    expr = cv.get("expression")
    lines.append(f"  critical value p_c    {_num(cv.get('value'), 12)}"
                 + (f"  (= {expr})" if expr else ""))
    if cv.get("reason"):
        lines.append(f"      {cv['reason']}")
    rob = rec.get("robust_critical_value")
    if rob:
        lines.append(f"  robust critical value {_num(rob.get('value'), 12)}  "
                     f"(tolerance {rob.get('tolerance')})")
    lb = rec.get("lower_bound") or {}
    lines.append(f"  lower bound p_low     {_num(lb.get('value'), 12)}  (= {lb.get('expression')})")
    blb = rec.get("block_lower_bound")
    if blb:
        lines.append(f"  block lower bound     {_num(blb.get('value'), 12)}  "
                     f"(= {blb.get('expression')})")
    ub = rec.get("upper_bound")
    if ub:
        iv = ub.get("interval") or [None, None]
        lines.append(f"  upper bound p_up      {_num(ub.get('value'), 12)}  in "
                     f"[{_num(iv[0], 12)}, {_num(iv[1], 12)}]"
                     f"{'  certified' if ub.get('certified') else '  not certified'}")
    op = rec.get("operating_point")
    if op:
        lines.append(f"  operating point p     {_num(op.get('arrival_probability'), 12)}")
        if op.get("margin") is not None:
            lines.append(f"  margin p - p_c        {op['margin']:+.6g}")
        if op.get("bracket"):
            b = op["bracket"]
            lines.append(f"  bracket               [{_num(b[0])}, {_num(b[1])}]")
        lines.append(f"  verdict               {op.get('verdict', '—').upper()}")
        if op.get("basis"):
            lines.append(f"      basis: {op['basis']}")
        if op.get("note"):
            lines.append(f"      note: {op['note']}")
    lines.extend(_bounds_lines(rec))
    lines.extend(_simulation_lines(rec))
    lines.extend(_link_lines(rec))
    checks = rec.get("verification") or []
    if checks:
        passed = sum(c.get("passed") is True for c in checks)
        failed = [c["check"] for c in checks if c.get("passed") is False]
        lines.append(f"  verification          {passed} of {len(checks)} checks passed"
                     + (f"; FAILED: {'; '.join(failed)}" if failed else ""))
    for w in rec.get("warnings") or []:
        lines.append(f"  warning: {w}")
    return "\n".join(lines)


def _bounds_lines(rec: dict[str, Any]) -> list[str]:
    cb = rec.get("covariance_bounds")
    if not cb:
        return []
    lo, up = cb.get("lower") or {}, cb.get("upper") or {}
    return [f"  lim E[P] bounds at p   tr S̄ = {_num(lo.get('trace')) if lo.get('exists') else '∞'}"
            f" ≤ tr lim E[P] ≤ tr V̄ = {_num(up.get('trace')) if up.get('exists') else '∞'}"]


def _simulation_lines(rec: dict[str, Any]) -> list[str]:
    sim = (rec.get("simulation") or {}).get("operating_point")
    if not sim:
        return []
    mt = sim.get("mean_trace") or {}
    out = []
    if mt.get("mean"):
        out.append(f"  simulated E[tr P_t]   {_num(mt['mean'][-1])} at t = {sim.get('steps')} "
                   f"({sim.get('paths')} paths, seed {sim.get('seed')})")
    ex = sim.get("exceedance")
    if ex:
        out.append(f"  P(tr P > {_num(ex.get('level'))})      {_num(ex.get('probability'))}")
    div = sim.get("divergence") or {}
    if div.get("diverged_paths"):
        out.append(f"  diverged paths        {div['diverged_paths']} of {sim.get('paths')}")
    return out


def _link_lines(rec: dict[str, Any]) -> list[str]:
    lb = rec.get("link_budget")
    if not lb or not lb.get("applicable", True):
        return []
    out = []
    for key, label, unit in (("required_sinr_db", "required SINR", " dB"),
                             ("required_rx_power_dbm", "required rx power", " dBm"),
                             ("link_margin_db", "link margin", " dB"),
                             ("max_distance_m", "max distance", " m")):
        if lb.get(key) is not None:
            out.append(f"  {label:<21} {_num(lb[key])}{unit}")
    cond = lb.get("condition")
    if isinstance(cond, dict) and cond.get("expression"):
        out.append(f"  bursty link           {cond['expression']}: {_num(cond.get('value'))} "
                   f"({'holds' if cond.get('holds') else 'fails'}; {cond.get('status')})")
    return out
