"""Bursty-link figure: the critical curve in the (failure rate, recovery rate) plane (theory §10).

Reads the typed ``link_budget.critical_curve``
(:class:`~kfcrit.records.bursty.BurstCurveRecord`):
on a grid of failure rates f, the necessary recovery rate r_nec(f) (at or below it E[P_t]
diverges, proven) and the sufficient one r_suf(f) (at or above it the coupled fixed-gain
certificate proves E[P_t] bounded),

.. math::

    r_{nec}(f) \\le r_{crit}(f) \\le r_{suf}(f),

and the operating point (f, r). Nothing is computed: the curves are drawn at the record's grid
points only (no extrapolation beyond them).
"""
from __future__ import annotations

import matplotlib
from matplotlib.figure import Figure

from kfcrit.analysis.sections import AnalysisRecord
from kfcrit.records.bursty import BurstCurveRecord, GilbertElliottSection
from kfcrit.records.link import LinkBudgetRecord
from kfcrit.views.figures.style import (
    COLORS,
    finite,
    floats,
    fmt,
    new_figure,
    present,
    readable_rc,
)

R_NEC = r"$r_{\mathrm{nec}}(f)$"
R_SUF = r"$r_{\mathrm{suf}}(f)$"


def critical_curve_of(rec: AnalysisRecord) -> BurstCurveRecord | None:
    """The critical curve of a Gilbert–Elliott link (single link or the link budget's bursty
    part), or ``None``."""
    lb = rec.link_budget
    bursty = lb.bursty if isinstance(lb, LinkBudgetRecord) else lb
    if not isinstance(bursty, GilbertElliottSection) or not present(bursty.critical_curve):
        return None
    return bursty.critical_curve


def draw_critical_curve(rec: AnalysisRecord) -> Figure | None:
    """Both bounding curves of the critical curve, the regions they decide, the operating
    point and the line f + r = 1 (i.i.d. losses)."""
    curve = critical_curve_of(rec)
    if curve is None:
        return None
    f = floats(curve.failure_rates)
    nec = floats(curve.necessary_recovery)
    suf = floats(curve.sufficient_recovery)
    if f is None or (nec is None and suf is None):
        return None
    nec = nec if nec is not None and len(nec) == len(f) else None
    suf = suf if suf is not None and len(suf) == len(f) else None
    if nec is None and suf is None:
        return None
    op = curve.operating_point
    of, orr = finite(op.failure_rate), finite(op.recovery_rate)
    gap = max_gap(nec, suf) if nec is not None and suf is not None else None
    with matplotlib.rc_context(readable_rc()):
        fig, ax = new_figure()
        level = nec[0] if nec is not None and max(nec) - min(nec) < 1e-12 else None
        if nec is not None:
            ax.fill_between(f, 0, nec, color="#fde2e2", linewidth=0,
                            label=rf"r ≤ {R_NEC}: mean-unstable (proven)")
        if suf is not None:
            ax.fill_between(f, suf, 1, color="#dcfce7", linewidth=0,
                            label=rf"r > {R_NEC} = {R_SUF}: mean-stable (exact)"
                            if is_exact_curve(curve) else
                            rf"r ≥ {R_SUF}: mean-stable (certificate)")
        # Coinciding curves stay distinguishable: r_nec wide and solid with dots at every grid
        # point, r_suf narrower and dashed with open squares at every other point, the closed
        # form thin and dotted on top of both.
        if nec is not None:
            ax.plot(f, nec, color=COLORS["p_c"], marker="o", markersize=4, linewidth=3.0,
                    alpha=0.85, label=rf"necessary recovery rate {R_NEC}")
        if suf is not None:
            ax.plot(f, suf, color=COLORS["operating"], marker="s", markersize=4.5,
                    markerfacecolor="none", markevery=(1, 2), linewidth=1.4,
                    linestyle=(0, (5, 2.5)),
                    label=rf"sufficient recovery rate {R_SUF}"
                          + coincidence_note(gap))
        if level is not None and curve.necessary_expression:
            ax.axhline(level, color=COLORS["sim"], linestyle=(0, (1, 1.5)), linewidth=0.9,
                       label=f"r = {curve.necessary_expression}: {R_NEC} in closed form "
                             "(every f)")
        ax.plot([0, 1], [1, 0], color=COLORS["p_low"], linestyle=":", linewidth=1,
                label="f + r = 1 (i.i.d. losses, p = r)")
        if of is not None and orr is not None:
            ax.plot([of], [orr], marker="*", markersize=11, color=COLORS["sim"],
                    linestyle="none", clip_on=False,
                    label=f"operating point f = {fmt(of)}, r = {fmt(orr)}")
        ax.set_xlim(0, 1)
        ax.set_ylim(0, 1)
        ax.set_xlabel("failure rate f = P(lost | received before)")
        ax.set_ylabel("recovery rate r")
        fig.legend(loc="outside right center", frameon=False)
        return fig


def is_exact_curve(curve: BurstCurveRecord) -> bool:
    """Whether the record's sufficient recovery rate equals its necessary one at every grid
    point (the scalar theorem of theory §7): then no band between them is undetermined."""
    nec, suf = floats(curve.necessary_recovery), floats(curve.sufficient_recovery)
    return (nec is not None and suf is not None and len(nec) == len(suf) > 0
            and all(a == b for a, b in zip(nec, suf)))


VISIBLE_GAP = 0.01
"""Gap between r_nec and r_suf (the axis spans 1) below which the two lines overlap in print."""


def max_gap(a: list[float], b: list[float]) -> float | None:
    """Largest |a − b| over the grid points where both are finite (``None``: no such point)."""
    gaps = [abs(x - y) for x, y in zip(a, b) if x == x and y == y]
    return max(gaps) if gaps else None


def coincidence_note(gap: float | None) -> str:
    """Legend note for r_suf when it lies on r_nec (gap below :data:`VISIBLE_GAP`)."""
    if gap is None or gap >= VISIBLE_GAP:
        return ""
    if gap <= 1e-12:
        return f" (coincides with {R_NEC}: the critical curve is exact)"
    return f" (on {R_NEC}: within {gap:.2g})".replace("-", "−")
