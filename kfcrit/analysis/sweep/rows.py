"""A sweep point's row: the result columns read from its analysis record (nothing recomputed:
the verdict and the review decision are the record's)."""
from __future__ import annotations

import math
from typing import Any

RESULT_COLUMNS = ("status", "error", "classification", "lower_bound", "critical_value",
                  "critical_expression", "robust_critical_value", "upper_bound", "requirement",
                  "requirement_basis", "arrival_probability", "iid", "margin", "verdict",
                  "decision",
                  "sinr_db", "required_sinr_db", "link_margin_db", "required_margin_db",
                  "max_distance_m", "outage_probability", "mean_arrival_probability",
                  "loop_verdict", "actuation_arrival_probability", "actuation_critical",
                  "loop_spectral_radius", "loop_cost")
"""Columns of every row after ``index``, ``key`` and the parameters (fixed: a tidy table)."""


def _value(obj: Any) -> float | None:
    """``x`` or ``x["value"]`` as a finite float; None when absent."""
    if isinstance(obj, dict):
        obj = obj.get("value")
    if obj is None or isinstance(obj, bool):
        return None
    try:
        v = float(obj)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def requirement_of(record: dict[str, Any]) -> tuple[float | None, str | None]:
    """The arrival probability a point must exceed, and the basis of that number: the record's
    p_c, robust value and bracket read by the one rule of
    :func:`kfcrit.analysis.verdict.probability_to_beat`."""
    from kfcrit.analysis.verdict import CriticalInputs, probability_to_beat

    low = _value(record.get("block_lower_bound"))
    return probability_to_beat(CriticalInputs(
        classification=record.get("classification"),
        critical=_value(record.get("critical_value")),
        robust=_value(record.get("robust_critical_value")),
        lower=low if low is not None else _value(record.get("lower_bound")),
        upper=_value(record.get("upper_bound"))))


def binding_requirement_of(record: dict[str, Any]) -> tuple[float | None, str | None]:
    """The requirement column of a point: the link design's binding requirement when an
    accuracy requirement binds it (p_V, or none when no arrival probability meets it; the
    value is the record's ``link_budget.required_arrival_probability.design_value``, computed
    once by :func:`kfcrit.link.requirement.binding_requirement`), else
    :func:`requirement_of`."""
    lb = record.get("link_budget") or {}
    req = lb.get("required_arrival_probability") if lb.get("applicable") else None
    if isinstance(req, dict) and req.get("binding") == "accuracy":
        return _value(req.get("design_value")), req.get("short_basis")
    return requirement_of(record)


def row_of(record: dict[str, Any]) -> dict[str, Any]:
    """The result columns of one point, read from its analysis record (nothing recomputed:
    the verdict and the decision are the record's)."""
    op = record.get("operating_point") or {}
    lb = record.get("link_budget") or {}
    req, basis = binding_requirement_of(record)
    low = _value(record.get("block_lower_bound"))
    p_low = _value(record.get("lower_bound"))
    row: dict[str, Any] = dict.fromkeys(RESULT_COLUMNS)
    row.update(status="ok", classification=record.get("classification"),
               lower_bound=max(v for v in (low, p_low, -1.0) if v is not None)
               if (low, p_low) != (None, None) else None,
               critical_value=_value(record.get("critical_value")),
               critical_expression=(record.get("critical_value") or {}).get("expression")
               if _value(record.get("critical_value")) is not None else None,
               robust_critical_value=_value(record.get("robust_critical_value")),
               upper_bound=_value(record.get("upper_bound")), requirement=req,
               requirement_basis=basis, decision=(record.get("review") or {}).get("decision"))
    if op and record.get("network"):
        # a network: the margin is the uniform margin δ, p the bottleneck sensor's
        bracket = op.get("bracket") or [None]
        margin = op.get("margin") if op.get("margin") is not None else bracket[0]
        row.update(arrival_probability=op.get("arrival_probability"), iid=op.get("iid"),
                   margin=margin, verdict=op.get("verdict"), requirement=None,
                   requirement_basis="uniform margin of the sensor network (the conservative "
                                     "end of its interval when not exact)")
    elif op and not op.get("iid") and op.get("margin_basis") and op.get("margin") is not None:
        # a channel with memory: the record's margin (r − r_nec of a bursty link), not p − p_c
        row.update(arrival_probability=op.get("arrival_probability"), iid=False,
                   margin=op.get("margin"), verdict=op.get("verdict"),
                   requirement=op.get("recovery_threshold"),
                   requirement_basis=op.get("margin_basis"))
    elif op:
        p = op.get("arrival_probability")
        # against p_c or its robust value the record's own margin (an exact difference, so
        # p_c + 10^-40 keeps its sign); against other requirements p − requirement
        own = {"critical value": op.get("margin"),
               "robust critical value": op.get("margin_robust")}.get(basis or "")
        row.update(arrival_probability=p, iid=op.get("iid"),
                   margin=own if own is not None and op.get("iid") else
                   (p - req) if None not in (p, req) else None,
                   verdict=op.get("verdict"))
    row.update(loop_columns(record.get("loop")))
    if lb.get("applicable") and "link" in lb:
        link = lb.get("link") or {}
        row.update(sinr_db=link.get("sinr_db"), required_sinr_db=lb.get("required_sinr_db"),
                   link_margin_db=lb.get("link_margin_db"),
                   required_margin_db=(lb.get("design_check") or {}).get("required_margin_db"),
                   max_distance_m=lb.get("max_distance_m"),
                   outage_probability=(lb.get("design_check") or {}).get("outage_probability"),
                   mean_arrival_probability=(lb.get("shadowing") or {}).get(
                       "mean_arrival_probability"))
    return row


def loop_columns(loop: dict[str, Any] | None) -> dict[str, Any]:
    """The closed loop's columns (theory §12): its verdict, the actuation link's arrival
    probability and threshold (ν_c, or the upper end of its bracket), ρ and the cost J."""
    if not loop:
        return {}
    act = loop.get("actuation_critical") or {}
    iv = act.get("interval") or [None, None]
    return {"loop_verdict": loop.get("verdict"),
            "actuation_arrival_probability": _value(loop.get("actuation_arrival_probability")),
            "actuation_critical": _value(act.get("value")) if act.get("exact") else _value(iv[1]),
            "loop_spectral_radius": _value(loop.get("spectral_radius")),
            "loop_cost": _value(loop.get("cost"))}
