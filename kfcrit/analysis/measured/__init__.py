"""Measured links in the analysis: traces to verdicts with confidence (theory §13, §14).

:func:`measured_channel` builds the record's ``channel_fit`` section of a ``trace`` channel (or
of a network whose sensors all have trace channels) and the inputs of the verdict rules
:func:`kfcrit.analysis.verdict.measured_verdict` and
:func:`kfcrit.analysis.verdict.joint_law_verdict`.
"""
from __future__ import annotations

from typing import Any

from kfcrit.analysis import verdict as vd
from kfcrit.analysis.measured.joint import joint_fit, network_confidence, network_traces
from kfcrit.analysis.measured.single import MeasuredFit, trace_fit


def measured_channel(spec: Any, crit: vd.CriticalInputs, *, details: bool = True,
                     structure: Any = None) -> MeasuredFit | None:
    """The ``channel_fit`` section and verdict inputs of a measured channel; None when the
    operating point is not a trace (or a network of traces)."""
    if spec.network is not None and spec.network.size > 1:
        traces = network_traces(spec.network)
        if traces is None:
            return None
        return joint_fit(spec.network, traces, network_confidence(spec.network))
    ch = spec.channel
    if ch is None or ch.model != "trace":
        return None
    return trace_fit(spec.system, ch.arrivals, getattr(ch, "confidence", 0.95), crit,
                     details=details, structure=structure)


__all__ = ["MeasuredFit", "measured_channel"]
