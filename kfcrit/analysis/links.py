"""The link of the operating point as the analysis reads it: bursty chains behind a channel,
the link policy check, the curves the report draws."""
from __future__ import annotations

from typing import Any

from kfcrit.io.systemfile import SystemSpec
from kfcrit.io.typed import ABSENT
from kfcrit.records.link import LinkCurves


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
    usable = {k: v for k, v in marks.items() if 0 < v < 1}
    outage = curves.outage_vs_distance(
        channel, usable, curves.distance_grid(channel, points=60)).record() if usable else ABSENT
    return LinkCurves(
        arrival_vs_distance=curves.arrival_vs_distance(channel).record(),
        per_vs_sinr=curves.per_vs_sinr(
            channel.radio, sizes, include_db=[v for v in (channel.sinr_db, required_sinr_db)
                                              if v is not None],
            header_bytes=channel.per_bytes - channel.psdu_bytes).record(),
        marks=marks, outage_vs_distance=outage)
