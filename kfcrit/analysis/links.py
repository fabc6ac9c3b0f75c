"""The link of the operating point as the analysis reads it: bursty chains behind a channel,
the link policy check, the curves the report draws."""
from __future__ import annotations

from typing import Any

from kfcrit.io.jsonio import jsonable
from kfcrit.io.systemfile import SystemSpec
from kfcrit.io.typed import ABSENT
from kfcrit.records.link import (
    ArrivalVsDistance,
    DesignCheck,
    LinkCurves,
    OutageVsDistance,
    PerVsSinr,
)
from kfcrit.records.read import read_plain


def bursty_channel(channel: Any) -> Any:
    """The Gilbert–Elliott chain of a bursty channel: the channel itself, or the two-state
    approximation of a link budget's time-correlated shadowing; None for memoryless channels."""
    if channel is None:
        return None
    if channel.model == "gilbert-elliott":
        return channel
    if channel.model == "link-budget" and not channel.iid:
        return channel.gilbert_elliott()
    return None


def design_check(lb: dict[str, Any]) -> DesignCheck | None:
    """The configured link against its own margin policy (read from the link-budget section).

    ``lb`` is the link layer's plain result (:func:`kfcrit.link.linkbudget.design_section`).
    ``margin_policy_met``: the link margin at the configured distance is at least the policy's
    effective margin max(margin_db, σ·Φ⁻¹(1 − max_outage)) (equivalently, the distance is within
    ``max_distance_m``); ``outage_within_policy``: the per-link shadowing outage below the design
    requirement is at most ``max_outage``. Either is ``None`` when its inputs are missing.

    The design requirement is the binding one of the section
    (:func:`kfcrit.link.requirement.binding_requirement`). With an accuracy requirement the
    check also states ``design_value`` and ``basis`` and ``requirement_reachable``: False when
    no arrival probability, or none the radio reaches at any SINR, meets the binding
    requirement (the policy then fails: no margin exists). When the requirement is p = 0
    (p_c = 0: every arrival probability above 0 keeps the filter mean-stable) the margin is
    unbounded: ``margin_unbounded`` True and the policy met.
    """
    if not lb.get("applicable"):
        return None
    policy = lb.get("margin_policy") or {}
    link = lb.get("link") or {}
    shadow = lb.get("shadowing") or {}
    margin, needed = lb.get("link_margin_db"), policy.get("effective_margin_db")
    req = lb.get("required_arrival_probability") or {}
    design = req.get("design_value")
    rows = [r for r in lb.get("thresholds") or []
            if r.get("arrival_probability") == design and r.get("outage_probability") is not None]
    outage = rows[0]["outage_probability"] if rows else shadow.get("outage_below_critical")
    max_outage = policy.get("max_outage")
    out = {"link_margin_db": margin, "required_margin_db": needed,
           "margin_policy_met": (margin >= needed) if None not in (margin, needed) else None,
           "distance_m": link.get("distance_m"), "max_distance_m": lb.get("max_distance_m"),
           "outage_probability": outage, "max_outage": max_outage,
           "outage_within_policy": (outage <= max_outage)
           if None not in (outage, max_outage) else None}
    if margin is None and needed is not None and lb.get("max_distance_unbounded") \
            and design is not None and design <= 0:
        # p_c = 0: every SINR gives p > 0, so the margin over the requirement is unbounded
        out.update(margin_policy_met=True, margin_unbounded=True)
    if req.get("accuracy") is None:
        return DesignCheck(**jsonable(out))
    reachable = not (design is None and req.get("binding") == "accuracy") and not (
        design is not None and margin is None and not lb.get("max_distance_unbounded"))
    if not reachable:
        out.update(margin_policy_met=False, outage_probability=1.0,
                   outage_within_policy=False if max_outage is not None else None)
    out.update(design_value=design, basis=req.get("basis"), requirement_reachable=reachable)
    return DesignCheck(**jsonable(out))


def link_curves(channel: Any, sec: dict[str, Any], spec: SystemSpec,
                required_sinr_db: float | None = None) -> LinkCurves:
    """The link's curves for the report: arrival probability and outage against distance, PER
    against SINR (:mod:`kfcrit.link.curves`), with the arrival probabilities they are read
    against (p_c or the bracket's upper end, and the accuracy requirement's [p_S, p_V]).
    ``required_sinr_db`` is the link section's SINR at the design value (marked on PER)."""
    from kfcrit.link import curves

    marks: dict[str, float] = {}
    pc = sec["critical_value"].value if sec.get("critical_value") is not None else None
    up = sec["upper_bound"].value if sec.get("upper_bound") is not None else None
    if pc is not None:
        marks["p_c"] = float(pc)
    elif up is not None:
        marks["p_up"] = float(up)
    design = sec.get("design")
    interval = design.required_arrival_probability.interval if design else None
    if interval:
        marks["p_S"], marks["p_V"] = (float(v) for v in interval)
    sizes = tuple(sorted({20, int(channel.psdu_bytes), 127}))
    path = "link_budget.curves"
    usable = {k: v for k, v in marks.items() if 0 < v < 1}
    outage = read_plain(OutageVsDistance, curves.outage_vs_distance(
        channel, usable, curves.distance_grid(channel, points=60)).to_dict(),
        f"{path}.outage_vs_distance") if usable else ABSENT
    return LinkCurves(
        arrival_vs_distance=read_plain(ArrivalVsDistance,
                                       curves.arrival_vs_distance(channel).to_dict(),
                                       f"{path}.arrival_vs_distance"),
        per_vs_sinr=read_plain(PerVsSinr, curves.per_vs_sinr(
            channel.radio, sizes, include_db=[v for v in (channel.sinr_db, required_sinr_db)
                                              if v is not None],
            header_bytes=channel.per_bytes - channel.psdu_bytes).to_dict(),
            f"{path}.per_vs_sinr"),
        marks=marks, outage_vs_distance=outage)
