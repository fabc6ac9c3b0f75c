r"""Terminal lines of a measured trace's fit (the record's ``channel_fit``, theory §14).

The fits with their exact intervals, the model the likelihood-ratio test chose, the burst-length
histogram against the geometric law (1 − r̂)^{j−1} r̂, the confidence region's corners and the
trace length that would decide; for a network of traces the joint law of the received set
against the product of the marginals,

.. math:: \hat\pi(\emptyset) \quad\text{vs}\quad \prod_i (1 - \hat p_i).

Every number is the record's (the typed :class:`~kfcrit.analysis.measured.section.ChannelFitSection`).
"""
from __future__ import annotations

from typing import Any

from kfcrit.analysis.measured.section import (
    BurstLengthHistogram,
    ChannelFitSection,
    ConfidenceRegion,
    JointLawFit,
)
from kfcrit.io.typed import ABSENT


def _safe(text: Any) -> str:  # noqa: D103 - the terminal's rule, kept local (no cycle)
    return "".join(c if c.isprintable() or c == " " else f"\\x{ord(c):02x}" for c in str(text))

MAX_BURST_BINS = 8
"""Burst lengths listed one by one; longer runs are summed into one bin."""


def _num(v: Any, digits: int = 6) -> str:
    return "—" if v is None else f"{float(v):.{digits}g}"


def _interval(iv: Any, digits: int = 6) -> str:
    if not isinstance(iv, (list, tuple)) or len(iv) != 2:
        return "—"
    return f"[{_num(iv[0], digits)}, {_num(iv[1], digits)}]"


def _bursts(b: BurstLengthHistogram) -> list[str]:
    lengths, counts, expected = b.lengths, b.counts, b.expected
    if not lengths:
        return [f"  loss bursts           no complete loss run ({b.censored} touching "
                "an end of the trace)"]
    cells = []
    for j, (length, count) in enumerate(zip(lengths, counts)):
        if j == MAX_BURST_BINS:
            rest = sum(counts[j:])
            rest_e = sum(expected[j:]) if len(expected) == len(lengths) else None
            cells.append(f"≥{length}: {rest}" + (f" ({rest_e:.3g})" if rest_e is not None
                                                  else ""))
            break
        e = expected[j] if len(expected) == len(lengths) else None
        cells.append(f"{length}: {count}" + (f" ({e:.3g})" if e is not None else ""))
    out = [f"  loss bursts           {b.runs} complete runs, mean length "
           f"{_num(b.mean_length, 4)}; length: observed (geometric law of r̂)",
           f"      {', '.join(cells)}"]
    if b.p_value is not None:
        out.append(f"      Pearson X² = {_num(b.statistic, 4)}, {b.dof} dof, "
                   f"p-value {_num(b.p_value, 3)}")
    return out


def _region(region: ConfidenceRegion | None) -> list[str]:
    if region is None:
        return []
    out = []
    for key, c in (("worst", region.worst), ("best", region.best)):
        where = (f"p = {_num(c.arrival_probability)}"
                 if c.arrival_probability is not None else
                 f"(f, r) = ({_num(c.failure_rate)}, {_num(c.recovery_rate)})")
        nec = {True: "holds", False: "FAILS", None: "undecided"}[c.necessary]
        out.append(f"      {key} corner {where}: necessary condition {nec}, sufficient "
                   f"{'proven' if c.sufficient else 'not proven'}")
    out.append(f"      on the whole region: stability {region.outcome}")
    return out


def _joint(j: JointLawFit | None) -> list[str]:
    if j is None:
        return []
    out = [f"  joint law             {len(j.sensors)} sensors, {j.n} "
           f"time-aligned periods: P(all lost) = {_num(j.p_all_lost)} "
           f"{_interval(j.p_all_lost_interval)}, product of marginals "
           f"{_num(j.p_all_lost_product)} (ratio {_num(j.all_lost_ratio, 4)})"]
    for c in j.constraints:
        members = [str(m) for m in c.unobservable]
        names = "{" + ", ".join(members) + "}" if members else "∅"
        out.append(f"      P(S ⊆ {names})·ρ_T² = {_num(c.value)} in "
                   f"[{_num(c.value_low)}, {_num(c.value_high)}]; independent "
                   f"links would give {_num(c.product_value)}")
    out.append(f"      {_safe(j.statement or '')}")
    return out


def channel_fit_lines(fit: ChannelFitSection | None) -> list[str]:
    """The terminal lines of ``channel_fit`` (empty without a measured trace)."""
    if fit is None or fit is ABSENT:
        return []
    out = [f"  measured trace        {fit.n} periods of "
           f"{_safe(fit.subject or 'the trace')}; model {fit.model} "
           f"(LRT p-value {_num(fit.lrt_p_value, 3)}, confidence "
           f"{_num(100 * float(fit.confidence or 0), 4)} %)",
           f"      p̂ = {_num(fit.p_hat)} in {_interval(fit.p_interval)}; "
           f"f̂ = {_num(fit.failure_rate_hat)} in "
           f"{_interval(fit.failure_rate_interval)}; r̂ = "
           f"{_num(fit.recovery_rate_hat)} in "
           f"{_interval(fit.recovery_rate_interval)}"]
    out += _region(fit.region)
    if fit.length_to_decide is not None:
        out.append(f"      a trace of about {fit.length_to_decide} periods would decide "
                   f"({_safe(fit.length_to_decide_basis or '')})")
    out += _bursts(fit.bursts)
    out += _joint(fit.joint_law)
    for note in fit.notes or []:
        out.append(f"      note: {_safe(note)}")
    return out


__all__ = ["channel_fit_lines"]
