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
        if op.get("note"):
            lines.append(f"      note: {op['note']}")
    for w in rec.get("warnings") or []:
        lines.append(f"  warning: {w}")
    return "\n".join(lines)
